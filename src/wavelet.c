/* CDF 9/7 wavelets on periodic sequences and the wavelet simplification of
 * planar contours (Jang, Lee, Han & Park 2004, section 3.2-3.4), plus the
 * LK_SIMPLIFY_WAVELET pipeline: slice (slice.c) -> simplify contours (here)
 * -> tile (tile.c). docs/wavelet.md explains the choices.
 *
 * Transform. Lifting (Daubechies & Sweldens) with the four classic steps
 * alpha..delta, then the approximations divided and the details multiplied by
 * K = 1.2301741...: that makes one level equal to the convolution with the
 * paper's Table 1 filters, the analysis low-pass summing to 1 (so coarse
 * samples are weighted averages of positions, in model units) and the
 * 7-tap high-pass summing to 0, centred on the odd samples. Lifting is
 * exactly invertible step by step, so synthesis needs no filter table.
 *
 * Contours. A contour of n >= 4 points is padded to N = 2^m samples with
 * equally spaced points on its longest segments (midpoints when a segment
 * gets one), so the samples lie on the sampled polygon itself. Level L
 * (1 <= L <= m - 2, leaving >= 4 coarse samples) is represented by the
 * synthesis of its coarse coefficients alone (details of levels 1..L set to
 * zero) taken at the coarse sample positions i * 2^L: points of the smooth
 * approximating curve, not the (shrunken) raw averages. A contour takes
 * the coarsest level whose dropped details are small: by the paper's
 * measure (eq. 7, the energy sum c^2 of the detail coefficients of levels
 * 1..L, both coordinates; the default) or by the largest distance from a
 * padded sample to the polygon segment spanning it (LK_WAVELET_DISTANCE).
 * docs/wavelet.md compares the two on the Table 4 models.
 *
 * Pipeline. With a count target, a share of the vertex budget is kept for
 * the refinement between the planes (see below): the tiled surface has all
 * its vertices on the slice planes, and its worst errors lie between them. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- the transform ------------------------------------------------------ */

#define LIFT_ALPHA (-1.586134342059924)
#define LIFT_BETA (-0.052980118572961)
#define LIFT_GAMMA 0.882911075530934
#define LIFT_DELTA 0.443506852043971
#define LIFT_SCALE 1.230174104914001

const double lk_cdf97_analysis_low[9] = {0.02674875741080976,  -0.01686411844287495, -0.07822326652898785,
                                         0.2668641184428723,   0.6029490182363579,   0.2668641184428723,
                                         -0.07822326652898785, -0.01686411844287495, 0.02674875741080976};
const double lk_cdf97_analysis_high[7] = {0.09127176311424948, -0.05754352622849957, -0.5912717631142470,
                                          1.115087052456994,   -0.5912717631142470, -0.05754352622849957,
                                          0.09127176311424948};

/* One level on x[0..n) (n even, >= 2): approximations to x[0..n/2),
 * details to x[n/2..n). scratch holds n doubles. */
static void forward_level(double *x, size_t n, double *scratch)
{
    size_t half = n / 2;
    double *s = scratch, *d = scratch + half;
    for (size_t i = 0; i < half; i++) {
        s[i] = x[2 * i];
        d[i] = x[2 * i + 1];
    }
    for (size_t i = 0; i < half; i++) d[i] += LIFT_ALPHA * (s[i] + s[(i + 1) % half]);
    for (size_t i = 0; i < half; i++) s[i] += LIFT_BETA * (d[(i + half - 1) % half] + d[i]);
    for (size_t i = 0; i < half; i++) d[i] += LIFT_GAMMA * (s[i] + s[(i + 1) % half]);
    for (size_t i = 0; i < half; i++) s[i] += LIFT_DELTA * (d[(i + half - 1) % half] + d[i]);
    for (size_t i = 0; i < half; i++) {
        x[i] = s[i] / LIFT_SCALE;
        x[half + i] = d[i] * LIFT_SCALE;
    }
}

static void inverse_level(double *x, size_t n, double *scratch)
{
    size_t half = n / 2;
    double *s = scratch, *d = scratch + half;
    for (size_t i = 0; i < half; i++) {
        s[i] = x[i] * LIFT_SCALE;
        d[i] = x[half + i] / LIFT_SCALE;
    }
    for (size_t i = 0; i < half; i++) s[i] -= LIFT_DELTA * (d[(i + half - 1) % half] + d[i]);
    for (size_t i = 0; i < half; i++) d[i] -= LIFT_GAMMA * (s[i] + s[(i + 1) % half]);
    for (size_t i = 0; i < half; i++) s[i] -= LIFT_BETA * (d[(i + half - 1) % half] + d[i]);
    for (size_t i = 0; i < half; i++) d[i] -= LIFT_ALPHA * (s[i] + s[(i + 1) % half]);
    for (size_t i = 0; i < half; i++) {
        x[2 * i] = s[i];
        x[2 * i + 1] = d[i];
    }
}

static void forward_levels(double *data, size_t count, unsigned levels, double *scratch)
{
    for (unsigned level = 0; level < levels; level++) forward_level(data, count >> level, scratch);
}

static void inverse_levels(double *data, size_t count, unsigned levels, double *scratch)
{
    for (unsigned level = levels; level > 0; level--) inverse_level(data, count >> (level - 1), scratch);
}

static lk_status check_transform(const double *data, size_t count, unsigned levels, lk_error *error)
{
    if (!data && count) return lk_error_set(error, LK_ERR_INVALID, "wavelet transform: NULL data");
    if (levels == 0) return LK_OK;
    if (levels >= 8 * sizeof(size_t) || (count >> levels) < 2 || (count & (((size_t)1 << levels) - 1)) != 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "wavelet transform: %zu samples cannot go through %u levels (need a multiple of 2^%u "
                            "with at least 2 coarse samples)",
                            count, levels, levels);
    return LK_OK;
}

lk_status lk_wavelet_forward(double *data, size_t count, unsigned levels, lk_error *error)
{
    lk_status status = check_transform(data, count, levels, error);
    if (status != LK_OK || levels == 0) return status;
    double *scratch = lk__malloc_array(count, sizeof(double));
    if (!scratch) return lk_error_set(error, LK_ERR_NOMEM, "wavelet transform: cannot allocate %zu samples", count);
    forward_levels(data, count, levels, scratch);
    free(scratch);
    return LK_OK;
}

lk_status lk_wavelet_inverse(double *data, size_t count, unsigned levels, lk_error *error)
{
    lk_status status = check_transform(data, count, levels, error);
    if (status != LK_OK || levels == 0) return status;
    double *scratch = lk__malloc_array(count, sizeof(double));
    if (!scratch) return lk_error_set(error, LK_ERR_NOMEM, "wavelet transform: cannot allocate %zu samples", count);
    inverse_levels(data, count, levels, scratch);
    free(scratch);
    return LK_OK;
}

/* ---- contour simplification -------------------------------------------- */

/* Below this many points a contour is kept as it is (the paper's polygons
 * need a few samples for the 9-tap filter to mean anything). */
#define MIN_TRANSFORM_POINTS 4
/* Coarsest level keeps this many samples. */
#define MIN_COARSE_SAMPLES 4
#define MAX_LEVELS 15
#define BISECTION_STEPS 60
/* A count target is met when the count is within 1/COUNT_TOLERANCE of it. */
#define COUNT_TOLERANCE 500

/* One contour's candidates: level 0 = its own points, level L = the coarse
 * synthesis at samples i * 2^L of the padded sequence. */
typedef struct contour_levels {
    size_t padded_count;  /* N (0 for an untransformed contour) */
    unsigned level_count; /* levels available, 0..level_count-1 */
    size_t first_sample;  /* into work.samples (N points) */
    size_t first_candidate[MAX_LEVELS + 1]; /* into work.candidates, per level */
    size_t candidate_count[MAX_LEVELS + 1];
    double level_error[MAX_LEVELS + 1];
    double level_energy[MAX_LEVELS + 1]; /* sqrt of the energy of the details of levels 1..L */
} contour_levels;

typedef struct simplify_work {
    const lk_slices *in;
    contour_levels *contours;
    double *samples;        /* 2 per padded sample: the padded polygon */
    size_t sample_total;
    double *candidates;     /* 2 per candidate vertex */
    uint32_t *positions;    /* padded index of each candidate vertex */
    size_t candidate_total;
    unsigned char *keep;    /* scratch: per candidate of one level */
    size_t keep_capacity;
    size_t midpoints;
    size_t untransformed;
    lk_wavelet_criterion criterion;
} simplify_work;

static double segment_distance(const double *p, const double *a, const double *b)
{
    double ex = b[0] - a[0], ey = b[1] - a[1];
    double px = p[0] - a[0], py = p[1] - a[1];
    double length2 = ex * ex + ey * ey;
    double t = length2 > 0 ? (px * ex + py * ey) / length2 : 0;
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    double dx = px - t * ex, dy = py - t * ey;
    return sqrt(dx * dx + dy * dy);
}

/* Largest distance from padded samples first..last (cyclic, inclusive) to
 * segment a-b; stops early once it exceeds `limit`. */
static double range_distance(const double *samples, size_t sample_count, size_t first, size_t last, const double *a,
                             const double *b, double limit)
{
    double worst = 0;
    size_t s = first;
    for (;;) {
        double distance = segment_distance(samples + 2 * s, a, b);
        if (distance > worst) {
            worst = distance;
            if (worst > limit) return worst;
        }
        if (s == last) break;
        s = (s + 1) % sample_count;
    }
    return worst;
}

/* Max-heap of segments by the length of their pieces, for padding. */
typedef struct pad_segment {
    double length;
    uint32_t pieces;
    uint32_t index;
} pad_segment;

static int heap_less(const pad_segment *a, const pad_segment *b)
{
    double la = a->length / a->pieces, lb = b->length / b->pieces;
    if (la != lb) return la < lb;
    return a->index > b->index; /* ties: the earlier segment first, for determinism */
}

static void heap_sift_down(pad_segment *heap, size_t count, size_t i)
{
    for (;;) {
        size_t largest = i, l = 2 * i + 1, r = l + 1;
        if (l < count && heap_less(&heap[largest], &heap[l])) largest = l;
        if (r < count && heap_less(&heap[largest], &heap[r])) largest = r;
        if (largest == i) return;
        pad_segment t = heap[i];
        heap[i] = heap[largest];
        heap[largest] = t;
        i = largest;
    }
}

static size_t next_power_of_two(size_t n)
{
    size_t p = 1;
    while (p < n) p <<= 1;
    return p;
}

static unsigned log2_exact(size_t n)
{
    unsigned m = 0;
    while (((size_t)1 << m) < n) m++;
    return m;
}

/* Builds every contour's padded samples and level candidates. */
static lk_status build_levels(simplify_work *work, lk_progress_fn progress, void *progress_user, lk_error *error)
{
    const lk_slices *in = work->in;
    work->contours = lk__calloc_array(in->contour_count, sizeof(contour_levels));
    if (!work->contours) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate contour levels");
    /* Sizes first. */
    size_t sample_total = 0, candidate_total = 0, largest = 4;
    for (size_t c = 0; c < in->contour_count; c++) {
        const lk_contour *contour = &in->contours[c];
        contour_levels *levels = &work->contours[c];
        size_t n = contour->count;
        levels->first_sample = sample_total;
        if (n < MIN_TRANSFORM_POINTS) {
            levels->padded_count = 0;
            levels->level_count = 1;
            levels->first_candidate[0] = candidate_total;
            levels->candidate_count[0] = n;
            candidate_total += n;
            work->untransformed++;
            continue;
        }
        size_t padded = next_power_of_two(n);
        unsigned m = log2_exact(padded);
        /* m - log2(MIN_COARSE_SAMPLES) levels leave MIN_COARSE_SAMPLES */
        unsigned coarsest = m >= 2 ? m - 2 : 0;
        if (coarsest > MAX_LEVELS) coarsest = MAX_LEVELS;
        levels->padded_count = padded;
        levels->level_count = coarsest + 1;
        sample_total += padded;
        if (padded > largest) largest = padded;
        levels->first_candidate[0] = candidate_total;
        levels->candidate_count[0] = n;
        candidate_total += n;
        for (unsigned level = 1; level <= coarsest; level++) {
            levels->first_candidate[level] = candidate_total;
            levels->candidate_count[level] = padded >> level;
            candidate_total += padded >> level;
        }
        work->midpoints += padded - n;
    }
    _Static_assert(MIN_COARSE_SAMPLES == 4, "the level count above assumes 4 coarse samples");
    work->sample_total = sample_total;
    work->candidate_total = candidate_total;
    work->samples = lk__malloc_array(2 * sample_total, sizeof(double));
    work->candidates = lk__malloc_array(2 * candidate_total, sizeof(double));
    work->positions = lk__malloc_array(candidate_total, sizeof(uint32_t));
    work->keep = lk__malloc_array(largest, 1);
    work->keep_capacity = largest;
    double *scratch = lk__malloc_array(8 * largest, sizeof(double));
    pad_segment *heap = lk__malloc_array(largest, sizeof(pad_segment));
    uint32_t *pieces = lk__malloc_array(largest, sizeof(uint32_t));
    if (!work->samples || !work->candidates || !work->positions || !work->keep || !scratch || !heap || !pieces) {
        free(scratch);
        free(heap);
        free(pieces);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu contour samples", sample_total);
    }
    double *u = scratch, *v = scratch + largest, *ru = scratch + 2 * largest, *rv = scratch + 3 * largest;
    double *lift = scratch + 4 * largest; /* 2 * largest for the lifting scratch */
    lk_status status = LK_OK;
    for (size_t c = 0; c < in->contour_count && status == LK_OK; c++) {
        if (progress && (c & 63) == 0 && progress(progress_user, 0.25 + 0.25 * (double)c / (double)in->contour_count,
                                                  "wavelet analysis"))
            status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
        const lk_contour *contour = &in->contours[c];
        contour_levels *levels = &work->contours[c];
        const double *points = in->points + 2 * (size_t)contour->first;
        size_t n = contour->count;
        /* level 0: the points themselves */
        memcpy(work->candidates + 2 * levels->first_candidate[0], points, 2 * n * sizeof(double));
        levels->level_error[0] = 0;
        levels->level_energy[0] = 0;
        if (levels->padded_count == 0) {
            for (size_t i = 0; i < n; i++) work->positions[levels->first_candidate[0] + i] = (uint32_t)i;
            continue;
        }
        size_t padded = levels->padded_count;
        /* Padding: each segment gets `pieces` equal parts; the extra samples
         * go one at a time to the segment whose parts are longest. */
        for (size_t i = 0; i < n; i++) {
            const double *a = points + 2 * i, *b = points + 2 * ((i + 1) % n);
            heap[i].length = hypot(b[0] - a[0], b[1] - a[1]);
            heap[i].pieces = 1;
            heap[i].index = (uint32_t)i;
        }
        for (size_t i = n / 2; i-- > 0;) heap_sift_down(heap, n, i);
        for (size_t extra = padded - n; extra > 0; extra--) {
            heap[0].pieces++;
            heap_sift_down(heap, n, 0);
        }
        for (size_t i = 0; i < n; i++) pieces[heap[i].index] = heap[i].pieces;
        double *samples = work->samples + 2 * levels->first_sample;
        size_t s = 0;
        for (size_t i = 0; i < n; i++) {
            const double *a = points + 2 * i, *b = points + 2 * ((i + 1) % n);
            work->positions[levels->first_candidate[0] + i] = (uint32_t)s;
            for (uint32_t k = 0; k < pieces[i]; k++) {
                double t = (double)k / pieces[i];
                samples[2 * s] = a[0] + t * (b[0] - a[0]);
                samples[2 * s + 1] = a[1] + t * (b[1] - a[1]);
                u[s] = samples[2 * s];
                v[s] = samples[2 * s + 1];
                s++;
            }
        }
        unsigned coarsest = levels->level_count - 1;
        forward_levels(u, padded, coarsest, lift);
        forward_levels(v, padded, coarsest, lift);
        /* The paper's measure (eq. 7): the energy of the details dropped
         * with levels 1..L, both coordinates (Mallat layout: d_L at
         * [N >> L, N >> (L - 1))). */
        double energy = 0;
        for (unsigned level = 1; level <= coarsest; level++) {
            for (size_t i = padded >> level; i < padded >> (level - 1); i++) energy += u[i] * u[i] + v[i] * v[i];
            levels->level_energy[level] = sqrt(energy);
        }
        for (unsigned level = 1; level <= coarsest; level++) {
            /* Synthesis with the details of levels 1..level dropped. */
            size_t kept = padded >> level;
            memcpy(ru, u, padded * sizeof(double));
            memcpy(rv, v, padded * sizeof(double));
            memset(ru + kept, 0, (padded - kept) * sizeof(double));
            memset(rv + kept, 0, (padded - kept) * sizeof(double));
            inverse_levels(ru, padded, coarsest, lift);
            inverse_levels(rv, padded, coarsest, lift);
            size_t step = (size_t)1 << level;
            double *candidates = work->candidates + 2 * levels->first_candidate[level];
            uint32_t *positions = work->positions + levels->first_candidate[level];
            double worst = 0;
            for (size_t i = 0; i < kept; i++) {
                candidates[2 * i] = ru[i * step];
                candidates[2 * i + 1] = rv[i * step];
                positions[i] = (uint32_t)(i * step);
                double offset = hypot(ru[i * step] - samples[2 * i * step], rv[i * step] - samples[2 * i * step + 1]);
                if (offset > worst) worst = offset;
            }
            for (size_t i = 0; i < kept; i++) {
                const double *a = candidates + 2 * i, *b = candidates + 2 * ((i + 1) % kept);
                size_t last = ((i + 1) * step) % padded;
                double distance = range_distance(samples, padded, i * step, last, a, b, INFINITY);
                if (distance > worst) worst = distance;
            }
            levels->level_error[level] = worst;
        }
    }
    free(scratch);
    free(heap);
    free(pieces);
    return status;
}

/* Distance bound check for the sampled polygon of a contour between the
 * candidates a (at padded index first) and b (at last). Untransformed
 * contours have no samples: their candidates are the points, always kept. */
static double span_error(const simplify_work *work, const contour_levels *levels, uint32_t first, uint32_t last,
                         const double *a, const double *b, double limit)
{
    const double *samples = work->samples + 2 * levels->first_sample;
    return range_distance(samples, levels->padded_count, first, last, a, b, limit);
}

/* Chooses the level of a contour for threshold E: the coarsest whose error
 * (distance criterion) or square root of dropped detail energy (energy
 * criterion) is within E. */
static unsigned choose_level(const simplify_work *work, const contour_levels *levels, double threshold)
{
    const double *measure = work->criterion == LK_WAVELET_ENERGY ? levels->level_energy : levels->level_error;
    for (unsigned level = levels->level_count; level-- > 1;)
        if (measure[level] <= threshold) return level;
    return 0;
}

/* Greedy removal of redundant vertices of one level: a vertex goes when
 * the segment joining its kept neighbours stays within E of every sampled
 * point between them. Fills work->keep; returns the kept count (>= 3). */
static size_t prune(const simplify_work *work, const contour_levels *levels, unsigned level, double threshold,
                    unsigned char *keep)
{
    size_t count = levels->candidate_count[level];
    memset(keep, 1, count);
    if (levels->padded_count == 0 || count <= 3 || threshold <= 0) return count;
    const double *candidates = work->candidates + 2 * levels->first_candidate[level];
    const uint32_t *positions = work->positions + levels->first_candidate[level];
    size_t kept = count;
    size_t previous = 0; /* last kept vertex before i */
    /* Visit 1..count-1 then 0; `previous` tracks the last kept one. */
    for (size_t step = 1; step <= count && kept > 3; step++) {
        size_t i = step % count;
        size_t next = (i + 1) % count;
        while (!keep[next]) next = (next + 1) % count;
        if (next == previous) break;
        double distance = span_error(work, levels, positions[previous], positions[next], candidates + 2 * previous,
                                     candidates + 2 * next, threshold);
        if (distance <= threshold) {
            keep[i] = 0;
            kept--;
        } else {
            previous = i;
        }
    }
    return kept;
}

static size_t count_at(const simplify_work *work, double threshold)
{
    size_t total = 0;
    for (size_t c = 0; c < work->in->contour_count; c++) {
        const contour_levels *levels = &work->contours[c];
        unsigned level = choose_level(work, levels, threshold);
        total += prune(work, levels, level, threshold, work->keep);
    }
    return total;
}

void lk_slices_init(lk_slices *slices)
{
    memset(slices, 0, sizeof *slices);
}

void lk_slices_free(lk_slices *slices)
{
    if (!slices) return;
    free(slices->contours);
    free(slices->points);
    lk_slices_init(slices);
}

double lk_slices_plane(const lk_slices *slices, size_t k)
{
    return slices->origin + ((double)k + 0.5) * slices->spacing;
}

static void free_work(simplify_work *work)
{
    free(work->contours);
    free(work->samples);
    free(work->candidates);
    free(work->positions);
    free(work->keep);
}

lk_status lk_slices_simplify(const lk_slices *in, const lk_contour_simplify_options *options, lk_slices *out,
                             lk_contour_simplify_info *info, lk_progress_fn progress, void *progress_user,
                             lk_error *error)
{
    lk_contour_simplify_info local_info;
    if (!info) info = &local_info;
    memset(info, 0, sizeof *info);
    if (!in || !options || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_slices_simplify: NULL argument");
    if (!(options->max_error >= 0) || !isfinite(options->max_error))
        return lk_error_set(error, LK_ERR_INVALID, "contour max error must be a finite number >= 0");
    lk_slices_init(out);
    simplify_work work;
    memset(&work, 0, sizeof work);
    work.in = in;
    if (options->criterion != LK_WAVELET_DISTANCE && options->criterion != LK_WAVELET_ENERGY)
        return lk_error_set(error, LK_ERR_INVALID, "unknown contour criterion %d", (int)options->criterion);
    work.criterion = options->criterion;
    lk_status status = build_levels(&work, progress, progress_user, error);
    if (status != LK_OK) {
        free_work(&work);
        return status;
    }
    /* The threshold: max_error, or the smallest reaching the count. */
    double threshold = options->max_error > 0 ? options->max_error : INFINITY;
    info->target_reached = 1;
    if (options->target_vertices > 0) {
        double low = 0, high = in->diagonal > 0 ? in->diagonal : 1;
        if (count_at(&work, 0) <= options->target_vertices) {
            high = 0;
        } else if (count_at(&work, high) > options->target_vertices) {
            info->target_reached = 0; /* three points per contour is the floor */
        } else {
            /* Close enough: within COUNT_TOLERANCE of the target (each
             * step costs a pass over every contour). */
            size_t good_enough = options->target_vertices - options->target_vertices / COUNT_TOLERANCE;
            for (int step = 0; step < BISECTION_STEPS && high - low > 1e-12 * high; step++) {
                if (progress && progress(progress_user, 0.5 + 0.2 * step / BISECTION_STEPS, "wavelet threshold")) {
                    free_work(&work);
                    return lk_error_set(error, LK_ERR_INVALID, "cancelled");
                }
                double middle = 0.5 * (low + high);
                size_t count = count_at(&work, middle);
                if (count <= options->target_vertices) {
                    high = middle;
                    if (count >= good_enough) break;
                } else {
                    low = middle;
                }
            }
        }
        if (high < threshold) threshold = high;
    }
    if (!isfinite(threshold)) threshold = 0; /* no target at all: keep every point */
    info->threshold = threshold;
    info->midpoints = work.midpoints;
    info->untransformed = work.untransformed;

    /* Output. */
    size_t total = count_at(&work, threshold);
    out->axis = in->axis;
    out->u_axis = in->u_axis;
    out->v_axis = in->v_axis;
    out->slice_count = in->slice_count;
    out->origin = in->origin;
    out->spacing = in->spacing;
    out->sampling_error = in->sampling_error;
    out->diagonal = in->diagonal;
    out->contours = lk__malloc_array(in->contour_count, sizeof(lk_contour));
    out->points = lk__malloc_array(2 * total, sizeof(double));
    if (!out->contours || !out->points) {
        free_work(&work);
        lk_slices_free(out);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu simplified contour points", total);
    }
    /* Points closer than this are one point (they would make zero-area
     * triangles). */
    double merge = 1e-9 * (in->diagonal > 0 ? in->diagonal : 1);
    size_t point_count = 0, contour_count = 0;
    double worst = 0;
    for (size_t c = 0; c < in->contour_count; c++) {
        const contour_levels *levels = &work.contours[c];
        unsigned level = choose_level(&work, levels, threshold);
        size_t count = levels->candidate_count[level];
        size_t kept = prune(&work, levels, level, threshold, work.keep);
        info->pruned += count - kept;
        info->level_histogram[level < 16 ? level : 15]++;
        const double *candidates = work.candidates + 2 * levels->first_candidate[level];
        const uint32_t *positions = work.positions + levels->first_candidate[level];
        lk_contour *contour = &out->contours[contour_count];
        contour->slice = in->contours[c].slice;
        contour->first = (uint32_t)point_count;
        contour->level = level;
        size_t start = point_count;
        size_t first_kept = SIZE_MAX, last_kept = SIZE_MAX;
        for (size_t i = 0; i < count; i++) {
            if (!work.keep[i]) continue;
            const double *p = candidates + 2 * i;
            if (point_count > start) {
                const double *q = out->points + 2 * (point_count - 1);
                if (hypot(p[0] - q[0], p[1] - q[1]) <= merge) continue;
            }
            /* Error actually reached along the span from the last kept vertex. */
            if (levels->padded_count && last_kept != SIZE_MAX) {
                double d = span_error(&work, levels, positions[last_kept], positions[i], candidates + 2 * last_kept, p,
                                      INFINITY);
                if (d > worst) worst = d;
            }
            if (first_kept == SIZE_MAX) first_kept = i;
            last_kept = i;
            out->points[2 * point_count] = p[0];
            out->points[2 * point_count + 1] = p[1];
            point_count++;
        }
        if (levels->padded_count && first_kept != SIZE_MAX && last_kept != first_kept) {
            double d = span_error(&work, levels, positions[last_kept], positions[first_kept],
                                  candidates + 2 * last_kept, candidates + 2 * first_kept, INFINITY);
            if (d > worst) worst = d;
        }
        while (point_count - start >= 2) {
            const double *p = out->points + 2 * start, *q = out->points + 2 * (point_count - 1);
            if (hypot(p[0] - q[0], p[1] - q[1]) > merge) break;
            point_count--;
        }
        if (point_count - start < 3) { /* collapsed to a point or a segment: drop it */
            point_count = start;
            continue;
        }
        contour->count = (uint32_t)(point_count - start);
        double area = 0;
        const double *origin = out->points + 2 * start;
        for (size_t i = 1; i + 1 < contour->count; i++) {
            const double *a = origin + 2 * i, *b = origin + 2 * (i + 1);
            area += (a[0] - origin[0]) * (b[1] - origin[1]) - (a[1] - origin[1]) * (b[0] - origin[0]);
        }
        contour->area = 0.5 * area;
        contour_count++;
    }
    out->contour_count = contour_count;
    out->point_count = point_count;
    info->error = worst;
    if (options->target_vertices > 0 && point_count > options->target_vertices) info->target_reached = 0;
    free_work(&work);
    return LK_OK;
}

/* ---- the LK_SIMPLIFY_WAVELET pipeline ----------------------------------- */

/* The paper's slice count. */
#define PAPER_SLICES 150

typedef struct wavelet_run {
    lk_slices slices;
    lk_slices simplified;
    lk_contour_simplify_info info;
} wavelet_run;

static void wavelet_run_free(wavelet_run *run)
{
    lk_slices_free(&run->slices);
    lk_slices_free(&run->simplified);
}

static lk_status run_slices(const lk_mesh *mesh, lk_axis axis, size_t slice_count,
                            const lk_contour_simplify_options *contour_options, wavelet_run *run,
                            lk_progress_fn progress, void *progress_user, lk_error *error)
{
    memset(run, 0, sizeof *run);
    lk_status status = lk_mesh_slice(mesh, axis, slice_count, &run->slices, progress, progress_user, error);
    if (status == LK_OK)
        status = lk_slices_simplify(&run->slices, contour_options, &run->simplified, &run->info, progress,
                                    progress_user, error);
    if (status != LK_OK) wavelet_run_free(run);
    return status;
}

/* ---- refinement between the planes -------------------------------------- */

/* Every tiled vertex lies on a slice plane, so whatever the surface does
 * between two planes (a feature tip that starts and ends between them, the
 * saddle under a branching, a belly a bridge spans) is invisible to the
 * contours: it is where the largest (Hausdorff) errors sit. The
 * refinement spends a small reserve of the vertex budget there: in rounds,
 * it measures both ways (input vertices and triangle centres to the
 * output; points of every output triangle to the input), and at the worst
 * places inserts a vertex lying on the input surface: the input point
 * itself, or the input point nearest to the output point. The vertex splits
 * the output triangle (or its edge, when the place is near one), which keeps
 * the mesh a closed, consistently oriented 2-manifold. */

/* Share of a vertex target kept for the refinement. */
#define REFINE_SHARE 0.08
/* Rounds the reserve is spread over (the measure is redone each round). */
#define REFINE_ROUNDS 6
/* Barycentric coordinate below which a place counts as on the edge. */
#define REFINE_EDGE 0.2
/* Places nearer than this share of the largest distance wait for a later
 * round. */
#define REFINE_FAR 0.25
/* Input triangles whose longest edge is shorter than this share of the
 * output's mean edge are represented by their corners alone (a point of
 * the triangle is within its edge length of a corner). */
#define REFINE_SMALL_TRIANGLE 0.25
/* A new triangle may lie at most this many times the error it fixes from
 * the input. */
#define REFINE_SPIKE 1.5

typedef struct refine_place {
    double distance;
    double position[3];   /* the new vertex: a point of the input surface */
    double bary[3];       /* where in the output triangle */
    uint32_t triangle;
} refine_place;

static int refine_place_order(const void *a, const void *b)
{
    const refine_place *p = a, *q = b;
    if (p->distance != q->distance) return p->distance < q->distance ? 1 : -1;
    if (p->triangle != q->triangle) return p->triangle < q->triangle ? -1 : 1;
    return 0;
}

/* Barycentric coordinates of the projection of p onto triangle abc. */
static void barycentric(const float *a, const float *b, const float *c, const double *p, double *out)
{
    double e0[3], e1[3], d[3];
    for (int k = 0; k < 3; k++) {
        e0[k] = (double)b[k] - a[k];
        e1[k] = (double)c[k] - a[k];
        d[k] = p[k] - a[k];
    }
    double d00 = e0[0] * e0[0] + e0[1] * e0[1] + e0[2] * e0[2], d01 = e0[0] * e1[0] + e0[1] * e1[1] + e0[2] * e1[2];
    double d11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
    double d20 = d[0] * e0[0] + d[1] * e0[1] + d[2] * e0[2], d21 = d[0] * e1[0] + d[1] * e1[1] + d[2] * e1[2];
    double det = d00 * d11 - d01 * d01;
    if (!(det > 0)) {
        out[0] = out[1] = out[2] = 1.0 / 3;
        return;
    }
    double v = (d11 * d20 - d01 * d21) / det, w = (d00 * d21 - d01 * d20) / det;
    out[0] = 1 - v - w;
    out[1] = v;
    out[2] = w;
}

/* The triangle other than t that holds the edge b -> a (t holds a -> b). */
static size_t opposite_triangle(const lk_mesh *mesh, size_t t, uint32_t a, uint32_t b)
{
    for (size_t s = 0; s < mesh->triangle_count; s++) {
        if (s == t) continue;
        const uint32_t *i = mesh->indices + 3 * s;
        for (int e = 0; e < 3; e++)
            if (i[e] == b && i[(e + 1) % 3] == a) return s;
    }
    return SIZE_MAX;
}

/* Barycentric sample points of an output triangle: edge midpoints and
 * quarter points (a band's long edges span the gap between planes), centre
 * and the points between the centre and the corners. */
#define REFINE_SAMPLES 13
static const double refine_samples[REFINE_SAMPLES][3] = {
    {0.5, 0.5, 0},        {0, 0.5, 0.5},        {0.5, 0, 0.5},        {0.75, 0.25, 0},      {0.25, 0.75, 0},
    {0, 0.75, 0.25},      {0, 0.25, 0.75},      {0.25, 0, 0.75},      {0.75, 0, 0.25},      {1.0 / 3, 1.0 / 3, 1.0 / 3},
    {2.0 / 3, 1.0 / 6, 1.0 / 6}, {1.0 / 6, 2.0 / 3, 1.0 / 6}, {1.0 / 6, 1.0 / 6, 2.0 / 3}};

/* Largest distance from the sample points of triangle t to the input. */
static double triangle_distance(const lk_mesh *mesh, size_t t, const lk_surface_index *input_index, double *closest,
                                const double **bary)
{
    const uint32_t *tri = mesh->indices + 3 * t;
    double worst = -1;
    for (int s = 0; s < REFINE_SAMPLES; s++) {
        double p[3], q[3];
        for (int k = 0; k < 3; k++)
            p[k] = refine_samples[s][0] * mesh->positions[3 * (size_t)tri[0] + k] +
                   refine_samples[s][1] * mesh->positions[3 * (size_t)tri[1] + k] +
                   refine_samples[s][2] * mesh->positions[3 * (size_t)tri[2] + k];
        double d = lk_surface_index_nearest(input_index, p, INFINITY, q, NULL);
        if (d > worst) {
            worst = d;
            if (closest) memcpy(closest, q, sizeof q);
            if (bary) *bary = refine_samples[s];
        }
    }
    return worst;
}

/* Inserts one vertex; `touched` marks triangles changed in this round.
 * Returns 1 when inserted, 0 when skipped: the place touches a triangle
 * already changed, the vertex would coincide with a corner, or a new
 * triangle would lie farther from the input than `spike` times the error
 * being fixed (a spike across empty space; the change is undone). The mesh arrays have
 * room for it. */
static int refine_insert(lk_mesh *mesh, const refine_place *place, unsigned char *touched, double merge,
                         double spike, const lk_surface_index *input_index)
{
    size_t t = place->triangle;
    if (touched[t]) return 0;
    uint32_t *tri = mesh->indices + 3 * t;
    for (int k = 0; k < 3; k++) {
        const float *corner = mesh->positions + 3 * (size_t)tri[k];
        double dx = place->position[0] - corner[0], dy = place->position[1] - corner[1],
               dz = place->position[2] - corner[2];
        if (dx * dx + dy * dy + dz * dz <= merge * merge) return 0;
    }
    uint32_t m = (uint32_t)mesh->vertex_count;
    int smallest = 0;
    for (int k = 1; k < 3; k++)
        if (place->bary[k] < place->bary[smallest]) smallest = k;
    size_t added = mesh->triangle_count, s = SIZE_MAX;
    uint32_t saved_t[3], saved_s[3];
    memcpy(saved_t, tri, sizeof saved_t);
    if (place->bary[smallest] < REFINE_EDGE) {
        /* Split the edge opposite the corner with the smallest weight:
         * t = (a, b, c) with edge a -> b, s = (b, a, d). */
        uint32_t a = tri[(smallest + 1) % 3], b = tri[(smallest + 2) % 3], c = tri[smallest];
        s = opposite_triangle(mesh, t, a, b);
        if (s == SIZE_MAX || touched[s]) return 0;
        uint32_t *other = mesh->indices + 3 * s;
        memcpy(saved_s, other, sizeof saved_s);
        uint32_t d = other[0] != a && other[0] != b ? other[0] : other[1] != a && other[1] != b ? other[1] : other[2];
        const float *pd = mesh->positions + 3 * (size_t)d;
        double dx = place->position[0] - pd[0], dy = place->position[1] - pd[1], dz = place->position[2] - pd[2];
        if (dx * dx + dy * dy + dz * dz <= merge * merge) return 0;
        tri[0] = a, tri[1] = m, tri[2] = c;
        other[0] = m, other[1] = a, other[2] = d;
        uint32_t *n = mesh->indices + 3 * added;
        n[0] = m, n[1] = b, n[2] = c;
        n[3] = b, n[4] = m, n[5] = d;
    } else {
        uint32_t a = tri[0], b = tri[1], c = tri[2];
        tri[2] = m;
        uint32_t *n = mesh->indices + 3 * added;
        n[0] = b, n[1] = c, n[2] = m;
        n[3] = c, n[4] = a, n[5] = m;
    }
    mesh->triangle_count += 2;
    for (int k = 0; k < 3; k++) {
        /* Near FLT_MAX a refined position may round past the float range. */
        double value = place->position[k];
        mesh->positions[3 * (size_t)m + k] = value > FLT_MAX ? FLT_MAX : value < -FLT_MAX ? -FLT_MAX : (float)value;
    }
    mesh->vertex_count++;
    size_t changed[4] = {t, added, added + 1, s};
    for (int i = 0; i < (s == SIZE_MAX ? 3 : 4); i++)
        if (triangle_distance(mesh, changed[i], input_index, NULL, NULL) > spike * place->distance) {
            memcpy(tri, saved_t, sizeof saved_t);
            if (s != SIZE_MAX) memcpy(mesh->indices + 3 * s, saved_s, sizeof saved_s);
            mesh->triangle_count -= 2;
            mesh->vertex_count--;
            return 0;
        }
    for (int i = 0; i < (s == SIZE_MAX ? 3 : 4); i++) touched[changed[i]] = 1;
    return 1;
}

/* Measures the output against the input both ways; fills places (the
 * worst first) and returns how many, or SIZE_MAX on allocation failure.
 * *worst gets the largest distance seen. */
static size_t refine_measure(const double *input_samples, size_t input_sample_count, double *sample_distance,
                             uint32_t *sample_triangle, const lk_surface_index *input_index, const lk_mesh *output,
                             refine_place *triangle_cache, unsigned char *dirty, refine_place **places,
                             size_t *capacity, double *worst, lk_status *status, lk_error *error)
{
    lk_surface_index *output_index = NULL;
    *status = lk_surface_index_build(output, &output_index, error);
    if (*status != LK_OK) return SIZE_MAX;
    size_t needed = input_sample_count + output->triangle_count;
    if (needed > *capacity) {
        refine_place *grown = lk__realloc_array(*places, needed, sizeof(refine_place));
        if (!grown) {
            lk_surface_index_free(output_index);
            *status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu refinement places", needed);
            return SIZE_MAX;
        }
        *places = grown;
        *capacity = needed;
    }
    size_t count = 0;
    *worst = 0;
    /* Input to output: the input point becomes the vertex. */
    for (size_t i = 0; i < input_sample_count; i++) {
        double p[3], closest[3];
        memcpy(p, input_samples + 3 * i, sizeof p);
        uint32_t triangle = 0;
        /* When the nearest triangle of the last measure is still there, the
         * distance can only have shrunk: that bounds the search. */
        double bound = sample_triangle[i] != UINT32_MAX && !dirty[sample_triangle[i]]
                           ? sample_distance[i] * (1 + 1e-9) + 1e-30
                           : INFINITY;
        double d = lk_surface_index_nearest(output_index, p, bound, closest, &triangle);
        if (!isfinite(d) && isfinite(bound)) d = lk_surface_index_nearest(output_index, p, INFINITY, closest, &triangle);
        if (!isfinite(d)) continue;
        sample_distance[i] = d;
        sample_triangle[i] = triangle;
        refine_place *place = &(*places)[count++];
        place->distance = d;
        memcpy(place->position, p, sizeof p);
        place->triangle = triangle;
        const uint32_t *t = output->indices + 3 * (size_t)triangle;
        barycentric(output->positions + 3 * (size_t)t[0], output->positions + 3 * (size_t)t[1],
                    output->positions + 3 * (size_t)t[2], closest, place->bary);
        if (d > *worst) *worst = d;
    }
    /* Output to input: the nearest input point becomes the vertex. Only
     * triangles changed since the last measure are measured again. */
    for (size_t t = 0; t < output->triangle_count; t++) {
        refine_place *best = &triangle_cache[t];
        if (dirty[t]) {
            const double *bary = NULL;
            best->triangle = (uint32_t)t;
            best->distance = triangle_distance(output, t, input_index, best->position, &bary);
            if (bary) memcpy(best->bary, bary, sizeof best->bary);
            else best->distance = -1;
            dirty[t] = 0;
        }
        if (best->distance < 0) continue;
        (*places)[count++] = *best;
        if (best->distance > *worst) *worst = best->distance;
    }
    lk_surface_index_free(output_index);
    /* Only the far places can be used this round: sort those. */
    size_t kept = 0;
    for (size_t i = 0; i < count; i++)
        if ((*places)[i].distance >= REFINE_FAR * *worst) (*places)[kept++] = (*places)[i];
    qsort(*places, kept, sizeof(refine_place), refine_place_order);
    return kept;
}

/* Adds up to `budget` vertices to `output` where it is farthest from
 * `input` (see above), in REFINE_ROUNDS rounds. */
static lk_status refine_between_planes(const lk_mesh *input, const lk_surface_index *input_index, lk_mesh *output,
                                       size_t budget, double diagonal, lk_error *error)
{
    if (budget == 0 || output->triangle_count == 0) return LK_OK;
    size_t vertex_room = output->vertex_count + budget, triangle_room = output->triangle_count + 2 * budget;
    float *positions = lk__realloc_array(output->positions, 3 * vertex_room, sizeof(float));
    if (!positions) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement vertices");
    output->positions = positions;
    uint32_t *indices = lk__realloc_array(output->indices, 3 * triangle_room, sizeof(uint32_t));
    if (!indices) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement triangles");
    output->indices = indices;
    /* Input samples: every vertex, and the centres of the triangles that
     * are not small next to the output's. */
    double mean_edge = 0;
    for (size_t i = 0; i < 3 * output->triangle_count; i++) {
        const float *a = output->positions + 3 * (size_t)output->indices[i];
        const float *b = output->positions + 3 * (size_t)output->indices[i - i % 3 + (i + 1) % 3];
        mean_edge += sqrt(((double)a[0] - b[0]) * (a[0] - b[0]) + ((double)a[1] - b[1]) * (a[1] - b[1]) +
                          ((double)a[2] - b[2]) * (a[2] - b[2]));
    }
    mean_edge /= (double)(3 * output->triangle_count);
    double *input_samples = lk__malloc_array(4 * (input->vertex_count + input->triangle_count), sizeof(double));
    uint32_t *sample_triangle = lk__malloc_array(input->vertex_count + input->triangle_count, sizeof(uint32_t));
    unsigned char *touched = lk__malloc_array(triangle_room, 1);
    unsigned char *dirty = lk__malloc_array(triangle_room, 1);
    refine_place *triangle_cache = lk__malloc_array(triangle_room, sizeof(refine_place));
    if (!touched || !input_samples || !dirty || !triangle_cache || !sample_triangle) {
        free(touched);
        free(input_samples);
        free(sample_triangle);
        free(dirty);
        free(triangle_cache);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement samples");
    }
    memset(dirty, 1, triangle_room);
    size_t input_sample_count = 0;
    for (size_t v = 0; v < input->vertex_count; v++, input_sample_count++)
        for (int k = 0; k < 3; k++) input_samples[3 * input_sample_count + k] = input->positions[3 * v + k];
    for (size_t t = 0; t < input->triangle_count; t++) {
        const float *corner[3];
        for (int c = 0; c < 3; c++) corner[c] = input->positions + 3 * (size_t)input->indices[3 * t + c];
        double longest = 0;
        for (int c = 0; c < 3; c++) {
            const float *a = corner[c], *b = corner[(c + 1) % 3];
            longest = fmax(longest, sqrt(((double)a[0] - b[0]) * (a[0] - b[0]) + ((double)a[1] - b[1]) * (a[1] - b[1]) +
                                         ((double)a[2] - b[2]) * (a[2] - b[2])));
        }
        if (longest < REFINE_SMALL_TRIANGLE * mean_edge) continue;
        for (int k = 0; k < 3; k++)
            input_samples[3 * input_sample_count + k] = ((double)corner[0][k] + corner[1][k] + corner[2][k]) / 3;
        input_sample_count++;
    }
    /* Distances of the last measure, after the 3 coordinates per sample. */
    double *sample_distance = input_samples + 3 * input_sample_count;
    for (size_t i = 0; i < input_sample_count; i++) sample_triangle[i] = UINT32_MAX;
    refine_place *places = NULL;
    size_t capacity = 0;
    size_t per_round = (budget + REFINE_ROUNDS - 1) / REFINE_ROUNDS;
    double merge = 1e-6 * diagonal;
    lk_status status = LK_OK;
    /* The best mesh measured so far (insertions can make things worse
     * elsewhere): its counts and a copy of its arrays. */
    float *best_positions = lk__malloc_array(3 * vertex_room, sizeof(float));
    uint32_t *best_indices = lk__malloc_array(3 * triangle_room, sizeof(uint32_t));
    size_t best_vertices = output->vertex_count, best_triangles = output->triangle_count;
    double best_worst = INFINITY;
    if (!best_positions || !best_indices) {
        free(best_positions);
        free(best_indices);
        free(touched);
        free(input_samples);
        free(sample_triangle);
        free(dirty);
        free(triangle_cache);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate refinement copies");
    }
    double spike = REFINE_SPIKE;
    for (;;) {
        double worst = 0;
        size_t count = refine_measure(input_samples, input_sample_count, sample_distance, sample_triangle, input_index,
                                      output, triangle_cache, dirty, &places, &capacity, &worst, &status, error);
        if (count == SIZE_MAX) break;
        if (worst <= best_worst) {
            best_worst = worst;
            best_vertices = output->vertex_count;
            best_triangles = output->triangle_count;
            memcpy(best_positions, output->positions, 3 * best_vertices * sizeof(float));
            memcpy(best_indices, output->indices, 3 * best_triangles * sizeof(uint32_t));
        } else {
            /* The last round made the largest error worse (its new
             * triangles were allowed up to REFINE_SPIKE times the error they
             * fixed): back to the best mesh, and go on with new triangles no
             * farther from the input than the error they fix. */
            output->vertex_count = best_vertices;
            output->triangle_count = best_triangles;
            memcpy(output->positions, best_positions, 3 * best_vertices * sizeof(float));
            memcpy(output->indices, best_indices, 3 * best_triangles * sizeof(uint32_t));
            memset(dirty, 1, triangle_room);
            if (spike <= 1) break;
            spike = 1;
            continue;
        }
        if (output->vertex_count >= vertex_room) break;
        size_t budget_left = vertex_room - output->vertex_count;
        memset(touched, 0, triangle_room);
        size_t inserted = 0, round_budget = per_round < budget_left ? per_round : budget_left;
        for (size_t i = 0; i < count && inserted < round_budget; i++) {
            if (places[i].distance <= 0) break;
            inserted += (size_t)refine_insert(output, &places[i], touched, merge, spike, input_index);
        }
        if (inserted == 0) break;
        for (size_t t = 0; t < output->triangle_count; t++) dirty[t] |= touched[t];
    }
    if (status == LK_OK && (output->vertex_count != best_vertices || output->triangle_count != best_triangles)) {
        output->vertex_count = best_vertices;
        output->triangle_count = best_triangles;
        memcpy(output->positions, best_positions, 3 * best_vertices * sizeof(float));
        memcpy(output->indices, best_indices, 3 * best_triangles * sizeof(uint32_t));
    }
    free(best_positions);
    free(best_indices);
    free(places);
    free(touched);
    free(input_samples);
    free(sample_triangle);
    free(dirty);
    free(triangle_cache);
    return status;
}

static lk_status simplify_wavelet(const lk_mesh *mesh, const lk_simplify_options *options,
                                  lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                  lk_error *error)
{
    lk_wavelet_criterion criterion = (lk_wavelet_criterion)options->wavelet_criterion;
    if (criterion != LK_WAVELET_DISTANCE && criterion != LK_WAVELET_ENERGY)
        return lk_error_set(error, LK_ERR_INVALID, "unknown contour criterion %d", options->wavelet_criterion);
    int refine = !(options->flags & LK_SIMPLIFY_NO_REFINE);
    if (options->slice_axis < LK_AXIS_AUTO || options->slice_axis > LK_AXIS_Z)
        return lk_error_set(error, LK_ERR_INVALID, "unknown slicing axis %d", options->slice_axis);
    lk_axis axis = (lk_axis)options->slice_axis;
    /* Count targets become a vertex count: the first one reached while
     * coarsening is the largest. A closed surface of genus 0 has
     * 2V - 4 triangles. */
    size_t target = 0;
    if (options->target_vertices) target = options->target_vertices;
    if (options->target_triangles) {
        size_t v = options->target_triangles / 2 + 2;
        if (v > target) target = v;
    }
    if (options->target_ratio > 0) {
        size_t v = (size_t)(options->target_ratio * (double)mesh->triangle_count / 2) + 2;
        if (v > target) target = v;
    }
    /* A count target keeps a reserve for the refinement between planes. */
    size_t contour_target = target;
    if (target > 0 && refine) contour_target = target - (size_t)ceil(REFINE_SHARE * (double)target);
    if (target > 0 && contour_target < 3) contour_target = target;
    lk_contour_simplify_options contour_options = {0, contour_target, criterion};
    wavelet_run run;
    lk_status status;
    size_t slice_count = options->slice_count;
    if (slice_count == 0) slice_count = PAPER_SLICES;
    if (options->max_error > 0) {
        /* The error bound is in-plane; it needs the diagonal first. */
        float low[3], high[3];
        contour_options.max_error = options->max_error * lk_mesh_bounds(mesh, low, high);
    }
    if (options->slice_count == 0 && target > 0) {
        /* Automatic count for a vertex budget: fewer slices leave more
         * points per contour. Score each candidate by the larger of its
         * in-plane error and its spacing (the tiling error between planes
         * grows like the spacing) and keep the best. */
        static const size_t candidates[] = {PAPER_SLICES, 100, 70, 50, 35, 25, 16};
        double best_score = INFINITY;
        memset(&run, 0, sizeof run);
        for (size_t c = 0; c < sizeof candidates / sizeof candidates[0]; c++) {
            wavelet_run trial;
            status = run_slices(mesh, axis, candidates[c], &contour_options, &trial, NULL, NULL, error);
            if (status != LK_OK) {
                wavelet_run_free(&run);
                return status;
            }
            double score = fmax(trial.info.error, trial.slices.spacing);
            if (!trial.info.target_reached) score = INFINITY;
            if (score < best_score || (c == 0 && !isfinite(score))) {
                if (c > 0) wavelet_run_free(&run);
                run = trial;
                best_score = score;
            } else {
                wavelet_run_free(&trial);
            }
            if (progress && progress(progress_user, 0.1 * (double)(c + 1), "choosing the slice count")) {
                wavelet_run_free(&run);
                return lk_error_set(error, LK_ERR_INVALID, "cancelled");
            }
        }
    } else {
        status = run_slices(mesh, axis, slice_count, &contour_options, &run, progress, progress_user, error);
        if (status != LK_OK) return status;
    }
    if (progress && progress(progress_user, 0.8, "tiling")) {
        wavelet_run_free(&run);
        return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    }
    status = lk_slices_tile(&run.simplified, &result->mesh, NULL, error);
    /* Tiling leaves out contours that pair with nothing on either side, so
     * a count target can end a little short: ask the contours for more
     * points (0.5 to 4 times the shortfall), keeping the closest result
     * that is not above the target. */
    static const double extra_factors[] = {0.5, 1, 1.5, 2, 3, 4};
    size_t shortfall =
        status == LK_OK && contour_target > result->mesh.vertex_count ? contour_target - result->mesh.vertex_count : 0;
    for (size_t retry = 0; retry < sizeof extra_factors / sizeof extra_factors[0] && status == LK_OK && target > 0 &&
                           run.info.target_reached && result->mesh.vertex_count < contour_target - contour_target / 100;
         retry++) {
        lk_contour_simplify_options more = contour_options;
        more.target_vertices = contour_target + (size_t)ceil(extra_factors[retry] * (double)shortfall);
        lk_slices simplified;
        lk_contour_simplify_info info;
        lk_mesh retiled;
        lk_mesh_init(&retiled);
        status = lk_slices_simplify(&run.slices, &more, &simplified, &info, NULL, NULL, error);
        if (status != LK_OK) break;
        status = lk_slices_tile(&simplified, &retiled, NULL, error);
        if (status == LK_OK && retiled.vertex_count <= contour_target && retiled.vertex_count > result->mesh.vertex_count &&
            retiled.triangle_count > 0) {
            lk_mesh_free(&result->mesh);
            result->mesh = retiled;
            lk_slices_free(&run.simplified);
            run.simplified = simplified;
            info.target_reached = 1;
            run.info = info;
        } else {
            lk_mesh_free(&retiled);
            lk_slices_free(&simplified);
        }
    }
    if (status == LK_OK && result->mesh.triangle_count == 0)
        status = lk_error_set(error, LK_ERR_INVALID,
                              "no contour spans two neighbouring slices (%zu slices along %c): use more slices",
                              run.slices.slice_count, "xyz"[run.slices.axis - 1]);
    if (status == LK_OK && refine && target > result->mesh.vertex_count) {
        lk_surface_index *input_index = NULL;
        status = lk_surface_index_build(mesh, &input_index, error);
        if (status == LK_OK)
            status = refine_between_planes(mesh, input_index, &result->mesh, target - result->mesh.vertex_count,
                                           run.slices.diagonal, error);
        lk_surface_index_free(input_index);
    }
    if (status == LK_OK) {
        result->vertex_map = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
        if (!result->vertex_map) status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the vertex map");
        else
            for (size_t v = 0; v < mesh->vertex_count; v++) result->vertex_map[v] = UINT32_MAX;
    }
    if (status == LK_OK) {
        double in_plane = run.info.error, sampling = run.slices.sampling_error;
        result->error = sqrt(in_plane * in_plane + sampling * sampling);
        result->target_reached = run.info.target_reached;
        if (progress) progress(progress_user, 1.0, "done");
    } else {
        lk_mesh_free(&result->mesh);
    }
    wavelet_run_free(&run);
    return status;
}

lk_status lk__simplify_wavelet(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                               lk_progress_fn progress, void *progress_user, lk_error *error)
{
    return simplify_wavelet(mesh, options, result, progress, progress_user, error);
}
