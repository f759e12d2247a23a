/* SPDX-License-Identifier: MIT */
/* CDF 9/7 wavelets on periodic sequences and the wavelet simplification of
 * planar contours (Jang, Lee, Han & Park 2004, section 3.2-3.4): the middle
 * step of the LK_SIMPLIFY_WAVELET pipeline (wavelet_simplify.c), between
 * slicing (slice.c) and tiling (tile.c). docs/wavelet.md explains the
 * choices.
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
 */
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
                                          1.115087052456994,   -0.5912717631142470,  -0.05754352622849957,
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
    size_t padded_count;                    /* N (0 for an untransformed contour) */
    unsigned level_count;                   /* levels available, 0..level_count-1 */
    size_t first_sample;                    /* into work.samples (N points) */
    size_t first_candidate[MAX_LEVELS + 1]; /* into work.candidates, per level */
    size_t candidate_count[MAX_LEVELS + 1];
    double level_error[MAX_LEVELS + 1];
    double level_energy[MAX_LEVELS + 1]; /* sqrt of the energy of the details of levels 1..L */
} contour_levels;

typedef struct simplify_work {
    const lk_slices *in;
    contour_levels *contours;
    double *samples; /* 2 per padded sample: the padded polygon */
    size_t sample_total;
    double *candidates;  /* 2 per candidate vertex */
    uint32_t *positions; /* padded index of each candidate vertex */
    size_t candidate_total;
    unsigned char *keep; /* scratch: per candidate of one level */
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
        if (progress && (c & 63) == 0 &&
            progress(progress_user, 0.25 + 0.25 * (double)c / (double)in->contour_count, "wavelet analysis"))
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
        contour->below = in->contours[c].below;
        contour->above = in->contours[c].above;
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
