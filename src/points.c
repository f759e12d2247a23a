/* SPDX-License-Identifier: MIT */
/* Point sets: sampling a triangle mesh into an oriented point set, splat
 * radii from the k-nearest-neighbour spacing, and normals by local PCA with
 * a consistent orientation.
 *
 * k-nearest-neighbour queries go through a k-d tree over float positions
 * (flat arrays, built breadth-first without recursion, median splits so its
 * depth is about log2(N / 4) whatever the input); the Poisson-disk
 * elimination, which asks many fixed-radius questions, uses a hashed
 * uniform grid. Per-point work (k-NN queries, PCA, sample weights, samples)
 * runs on a few POSIX threads; every result is written to the slot of its
 * own point, so the output does not depend on the number of threads or on
 * their timing.
 *
 * Choices the header leaves open:
 * - radii: with k or more points at the very same position, the k-th
 *   neighbour is at distance 0; the radius then comes from the nearest
 *   point at a positive distance (a duplicate adds no coverage, so the
 *   spacing is what lies beyond it). If all points coincide (or there is
 *   one) there is no spacing at all: radius = scale * 1e-6 * max(1, largest
 *   |coordinate|). k larger than N - 1 is clamped to N - 1. Radii are
 *   clamped to [FLT_TRUE_MIN, FLT_MAX] (denormals kept) so that they are
 *   always valid floats > 0.
 * - radii, robust to outliers (issue 23): a stray point's k-th neighbour is
 *   far, so its raw spacing would make a large disc. Two clamps follow the
 *   spacing. (1) Global: no radius above 4x the 99th percentile of all the
 *   spacings (rank round(0.99 (N - 1))). (2) Local: no radius above 4x the
 *   lower median (rank (k - 1) / 2) of the radii of its k neighbours (the
 *   ones the spacing came from, the point itself excluded), repeated over
 *   all points until no radius changes, each pass reading the previous
 *   pass's radii, so the rule holds for the final radii. A lone stray's
 *   neighbours are ordinary surface points, so (2) shrinks it to 4x their
 *   spacing; a sparse group of k / 2 or more strays vouches for itself in
 *   (2), and (1) bounds it. The factors come from bench/bench_radii.c: on
 *   the clean samples no radius is above 3.2x its neighbourhood median, and
 *   only one stereo scan's far rows are above 4x the 99th percentile.
 *   Cost: O(N k) per pass on the stored neighbour lists (O(N k) memory);
 *   one pass on clean data, three on pcd/bun0.pcd (radii only shrink, and
 *   each clamped one is 4x a radius of the pass before, so the passes end;
 *   64 passes is a safety stop, never reached on the samples).
 * - normals: the seed of each connected part of the k-NN graph is its
 *   highest point (largest z), turned to +z.
 * - lk_mesh_sample_points leaves `points` empty on failure and refuses
 *   points == mesh. */
#include "points_kd.h"

#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* Largest k accepted: the per-query candidate list lives on the stack, and a
 * splat radius or a tangent plane from more than a few dozen neighbours is
 * no longer local anyway. */
#define MAX_NEIGHBOURS 256u
/* Clip lines (lk_points_estimate_clips): a point is on a border when its
 * neighbours leave one empty wedge at least this wide around it in its
 * tangent plane. 180 degrees (the point outside its neighbours' hull)
 * missed most of a real border, which is jagged: 70 of the 326 rim
 * vertices of the bunny cut open (tests/unit/test_points.c), 220 at 150,
 * 283 at 120. bench_radii, splat pixels off the sample scans' surfaces
 * (coverage): Haystack_Rock from above 10.4% (99.99%) at 180, 8.3%
 * (99.97%) at 150, 7.0% (99.96%) at 120; the hippo 22.7% (99.09%), 19.8%
 * (98.54%), 18.7% (98.49%); the bunny's random sample keeps 99.98% at 150,
 * 99.82% at 120. */
#define CLIP_OPEN_DEGREES 150.0
#define CLIP_PI 3.14159265358979323846

void lk_sample_options_default(lk_sample_options *options)
{
    memset(options, 0, sizeof *options);
    options->point_count = 100000;
    options->poisson = 0;
    options->seed = 1;
    options->neighbours = 8;
    options->radius_scale = 1.0;
}

/* Receives the points found by a fixed-radius search. */
typedef void (*kd_visit_fn)(void *context, uint32_t id, double distance2);

/* ---- shared checks -------------------------------------------------------- */

static lk_status check_positions(const lk_mesh *points, lk_error *error)
{
    if (points->vertex_count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "point set of %zu points is too large", points->vertex_count);
    if (points->vertex_count && !points->positions)
        return lk_error_set(error, LK_ERR_INVALID, "point set has no positions");
    for (size_t i = 0; i < 3 * points->vertex_count; i++)
        if (!isfinite(points->positions[i]))
            return lk_error_set(error, LK_ERR_RANGE, "point %zu: position is not finite (%g)", i / 3,
                                (double)points->positions[i]);
    return LK_OK;
}

static lk_status check_neighbours(unsigned neighbours, lk_error *error)
{
    if (neighbours == 0 || neighbours > MAX_NEIGHBOURS)
        return lk_error_set(error, LK_ERR_INVALID, "neighbours must be between 1 and %u, got %u", MAX_NEIGHBOURS,
                            neighbours);
    return LK_OK;
}

/* The lower median (rank (count - 1) / 2) of radii[id[0 .. count)). */
static float neighbour_median(const float *radii, const uint32_t *id, unsigned count)
{
    float values[MAX_NEIGHBOURS];
    for (unsigned j = 0; j < count; j++) values[j] = radii[id[j]];
    lk__select_float(values, count, (count - 1) / 2);
    return values[(count - 1) / 2];
}

/* ---- radii ----------------------------------------------------------------- */

/* The clamps against outliers (top of file). Chosen with
 * bench/bench_radii.c on the samples: clean data (meshes' vertices, uniform
 * samples, the PCD/LAS scans) has no radius above 3.2x the median of its
 * neighbourhood, so 4x (the bound) leaves it alone and catches the
 * strays of pcd/bun0.pcd; the largest radius of clean data is 1.1-3.3x the
 * 99th percentile but for the far rows of a stereo scan (5.3x, clamped to
 * 4x), so the global cap only meets groups of strays that vouch for each
 * other. */
#define LOCAL_FACTOR 4.0f
#define GLOBAL_FACTOR 4.0f
#define GLOBAL_QUANTILE 0.99
/* Clamping passes before giving up on a fixed point (measured: 1 to 3). */
#define MOST_CLAMP_PASSES 64
/* With normals a radius is at most this many times the farthest corner of
 * the point's cell among its neighbours (cell_radius), a margin for the
 * neighbours the k nearest miss and for curvature. Measured with
 * bench_radii (512x512, silhouette coverage, splat pixels outside): 1.0
 * left fandisk's vertices covering 98.96%; 1.15 99.54%, 1.3 99.81%; the
 * kitten scan's spill 1.41%, 1.64%, 1.91% (6.05% with the k-th neighbour's
 * distance alone). */
#define CELL_MARGIN 1.25

typedef struct radii_job {
    const kd_tree *tree;
    unsigned neighbours; /* already clamped to count - 1 */
    double scale;
    float fallback;          /* radius when no other point has a different position */
    float *radii;            /* scale * k-th-neighbour spacing, then clamped */
    uint32_t *neighbour_ids; /* neighbours per point: the neighbourhood of the clamp */
    const float *positions, *normals;
} radii_job;

static float clamp_radius(double radius)
{
    /* Denormal radii are kept: between denormal positions (a model 1e-40
     * across) FLT_MIN would be a splat ~1000 times the model. Only what
     * rounds to 0 in float becomes the smallest float > 0. */
    if (radius > FLT_MAX) return FLT_MAX;
    float value = (float)radius;
    return value > 0 ? value : FLT_TRUE_MIN;
}

/* An orthonormal basis (e1, e2) of the plane across normal n; false when
 * n is zero or not finite. */
static bool tangent_basis(const float *n, double e1[3], double e2[3])
{
    double normal[3] = {n[0], n[1], n[2]};
    double length = sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    if (!(length > 0) || !isfinite(length)) return false;
    for (int k = 0; k < 3; k++) normal[k] /= length;
    double helper[3] = {0, 0, 0};
    helper[fabs(normal[0]) < 0.6 ? 0 : fabs(normal[1]) < 0.6 ? 1 : 2] = 1;
    e1[0] = helper[1] * normal[2] - helper[2] * normal[1];
    e1[1] = helper[2] * normal[0] - helper[0] * normal[2];
    e1[2] = helper[0] * normal[1] - helper[1] * normal[0];
    double e1_length = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
    for (int k = 0; k < 3; k++) e1[k] /= e1_length;
    e2[0] = normal[1] * e1[2] - normal[2] * e1[1];
    e2[1] = normal[2] * e1[0] - normal[0] * e1[2];
    e2[2] = normal[0] * e1[1] - normal[1] * e1[0];
    return true;
}

/* The farthest corner from p of p's Voronoi cell among its neighbours, in
 * the plane through p across its normal n, the cell cut to the square of
 * half-side `bound` around p; `bound` if the normal is zero. Discs of
 * these radii in the points' tangent planes cover every cell, so they
 * leave no hole wherever the neighbours surround the point. */
static double cell_radius(const float *positions, const float *p, const float *n, const uint32_t *ids, unsigned count,
                          double bound)
{
    double e1[3], e2[3];
    if (!tangent_basis(n, e1, e2)) return bound;
    /* the cell, a convex polygon clipped by one bisector per neighbour */
    double polygon[2][2 * (MAX_NEIGHBOURS + 4)], *cell = polygon[0], *next = polygon[1];
    unsigned corners = 4;
    double square[8] = {-bound, -bound, bound, -bound, bound, bound, -bound, bound};
    memcpy(cell, square, sizeof square);
    for (unsigned j = 0; j < count && corners > 0; j++) {
        const float *q = positions + 3 * (size_t)ids[j];
        double d[3] = {(double)q[0] - p[0], (double)q[1] - p[1], (double)q[2] - p[2]};
        double u = d[0] * e1[0] + d[1] * e1[1] + d[2] * e1[2], v = d[0] * e2[0] + d[1] * e2[1] + d[2] * e2[2];
        double limit = 0.5 * (u * u + v * v); /* keep x.(u, v) <= |(u, v)|^2 / 2 */
        if (!(limit > 0)) continue;
        unsigned kept = 0;
        for (unsigned c = 0; c < corners; c++) {
            const double *a = cell + 2 * c, *b = cell + 2 * ((c + 1) % corners);
            double fa = a[0] * u + a[1] * v - limit, fb = b[0] * u + b[1] * v - limit;
            if (fa <= 0) next[2 * kept] = a[0], next[2 * kept + 1] = a[1], kept++;
            if ((fa < 0 && fb > 0) || (fa > 0 && fb < 0)) {
                double t = fa / (fa - fb);
                next[2 * kept] = a[0] + t * (b[0] - a[0]), next[2 * kept + 1] = a[1] + t * (b[1] - a[1]), kept++;
            }
        }
        double *swap = cell;
        cell = next, next = swap;
        corners = kept;
    }
    double farthest = 0;
    for (unsigned c = 0; c < corners; c++)
        farthest = fmax(farthest, cell[2 * c] * cell[2 * c] + cell[2 * c + 1] * cell[2 * c + 1]);
    return sqrt(farthest);
}

static void radii_range(void *context, size_t begin, size_t end)
{
    const radii_job *job = context;
    double distance2[MAX_NEIGHBOURS];
    /* Queries in tree order: consecutive queries touch the same nodes. */
    for (size_t t = begin; t < end; t++) {
        const kd_entry *entry = &job->tree->entries[t];
        uint32_t *ids = job->neighbour_ids + (size_t)entry->id * job->neighbours;
        unsigned found = lk__kd_nearest(job->tree, entry->p, entry->id, job->neighbours, false, distance2, ids);
        for (unsigned j = found; j < job->neighbours; j++) ids[j] = entry->id; /* cannot happen: k <= N - 1 */
        double spacing = found ? sqrt(distance2[found - 1]) : 0;
        if (spacing == 0 && found) {
            /* k or more points coincide with this one: its spacing is the
             * distance to the nearest point elsewhere, not 0. */
            uint32_t elsewhere;
            found = lk__kd_nearest(job->tree, entry->p, entry->id, 1, true, distance2, &elsewhere);
            spacing = found ? sqrt(distance2[0]) : 0;
        }
        if (spacing > 0 && job->normals)
            spacing =
                fmin(spacing, CELL_MARGIN * cell_radius(job->positions, entry->p, job->normals + 3 * (size_t)entry->id,
                                                        ids, found, spacing));
        job->radii[entry->id] = spacing > 0 ? clamp_radius(job->scale * spacing) : job->fallback;
    }
}

typedef struct clamp_job {
    const uint32_t *neighbour_ids;
    unsigned neighbours;
    const float *radii; /* this pass reads these... */
    float *clamped;     /* ...and writes these, so the order of points does not matter */
    atomic_size_t changed;
} clamp_job;

static void clamp_range(void *context, size_t begin, size_t end)
{
    clamp_job *job = context;
    size_t changed = 0;
    for (size_t i = begin; i < end; i++) {
        float bound =
            LOCAL_FACTOR * neighbour_median(job->radii, job->neighbour_ids + i * job->neighbours, job->neighbours);
        float radius = job->radii[i];
        if (radius > bound && bound > 0) {
            radius = bound;
            changed++;
        }
        job->clamped[i] = radius;
    }
    atomic_fetch_add_explicit(&job->changed, changed, memory_order_relaxed);
}

/* Clamps radii[] in place against the global cap, then against the
 * neighbourhood medians until no radius changes: each pass reads the radii
 * of the previous one (Jacobi order), so the result depends neither on the
 * thread count nor on timing. Radii only shrink, and a clamped radius is
 * LOCAL_FACTOR times a radius of the previous pass, so a fixed point is
 * reached; the pass limit is a safety stop. scratch: count floats. */
static void clamp_radii(float *radii, size_t count, const uint32_t *neighbour_ids, unsigned neighbours, float *scratch)
{
    memcpy(scratch, radii, count * sizeof(float));
    size_t rank = (size_t)llround(GLOBAL_QUANTILE * (double)(count - 1));
    lk__select_float(scratch, count, rank);
    float cap = clamp_radius(GLOBAL_FACTOR * (double)scratch[rank]);
    for (size_t i = 0; i < count; i++)
        if (radii[i] > cap) radii[i] = cap;
    clamp_job job = {neighbour_ids, neighbours, radii, scratch, 0};
    for (int pass = 0; pass < MOST_CLAMP_PASSES; pass++) {
        atomic_store_explicit(&job.changed, 0, memory_order_relaxed);
        lk__points_parallel_for(count, 8192, clamp_range, &job);
        float *swap = (float *)job.radii;
        job.radii = job.clamped;
        job.clamped = swap;
        if (atomic_load_explicit(&job.changed, memory_order_relaxed) == 0) break;
    }
    if (job.radii != radii) memcpy(radii, job.radii, count * sizeof(float));
}

static lk_status estimate_radii_with_tree(lk_mesh *points, const kd_tree *tree, unsigned neighbours, double scale,
                                          lk_error *error)
{
    size_t count = points->vertex_count;
    float lo[3], hi[3];
    (void)lk_mesh_bounds(points, lo, hi);
    /* The fallback is only used when every point sits at one position (or
     * there is only one point): there is no spacing to measure, and the
     * bounding box is a point too. A splat must still be > 0, so use a
     * millionth of the coordinates' magnitude, or of 1. */
    double magnitude = 1;
    for (int k = 0; k < 3; k++) magnitude = fmax(magnitude, fmax(fabs((double)lo[k]), fabs((double)hi[k])));
    radii_job job = {.tree = tree,
                     .neighbours = neighbours < count ? neighbours : (unsigned)(count - 1),
                     .scale = scale,
                     .fallback = clamp_radius(scale * 1e-6 * magnitude),
                     .radii = points->radii,
                     .positions = points->positions,
                     .normals = points->normals};
    if (job.neighbours == 0) {
        for (size_t i = 0; i < count; i++) points->radii[i] = job.fallback;
        return LK_OK;
    }
    /* Both buffers before any radius is written: on failure the radii are
     * left as they were. */
    job.neighbour_ids = lk__malloc_array(count * job.neighbours, sizeof(uint32_t));
    float *scratch = lk__malloc_array(count, sizeof(float));
    if (!job.neighbour_ids || !scratch) {
        free(job.neighbour_ids);
        free(scratch);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %u neighbours for %zu points", job.neighbours, count);
    }
    lk__points_parallel_for(count, 8192, radii_range, &job);
    clamp_radii(points->radii, count, job.neighbour_ids, job.neighbours, scratch);
    free(job.neighbour_ids);
    free(scratch);
    return LK_OK;
}

lk_status lk_points_estimate_radii(lk_mesh *points, unsigned neighbours, double scale, lk_error *error)
{
    lk_status status = check_neighbours(neighbours, error);
    if (status != LK_OK) return status;
    if (!(scale > 0) || !isfinite(scale))
        return lk_error_set(error, LK_ERR_INVALID, "radius scale must be a finite number > 0, got %g", scale);
    status = check_positions(points, error);
    if (status != LK_OK) return status;
    size_t count = points->vertex_count;
    if (!points->radii) {
        points->radii = lk__malloc_array(count, sizeof(float));
        if (!points->radii) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate radii for %zu points", count);
    }
    if (count == 0) return LK_OK;
    kd_tree tree;
    status = lk__kd_build(&tree, points->positions, count, error);
    if (status != LK_OK) return status;
    status = estimate_radii_with_tree(points, &tree, neighbours, scale, error);
    lk__kd_free(&tree);
    return status;
}

/* ---- clip lines ---------------------------------------------------------- */

typedef struct clips_job {
    const kd_tree *tree;
    unsigned neighbours; /* already clamped to count - 1 */
    const float *positions, *normals;
    float *clips;
} clips_job;

static void sort_angles(double *angles, unsigned count)
{
    for (unsigned i = 1; i < count; i++) {
        double value = angles[i];
        unsigned j = i;
        for (; j > 0 && angles[j - 1] > value; j--) angles[j] = angles[j - 1];
        angles[j] = value;
    }
}

/* The clip line of the point `id` at p (lk_points_estimate_clips' rule)
 * into clip[4]; *reach (when not NULL) gets the distance of the farthest
 * neighbour asked, the radius within which the neighbourhood was seen. */
static void clip_line(const kd_tree *tree, const float *positions, const float *normals, uint32_t id, const float p[3],
                      unsigned neighbours, float clip[4], float *reach)
{
    double distance2[MAX_NEIGHBOURS], angles[MAX_NEIGHBOURS], plane[2 * MAX_NEIGHBOURS];
    uint32_t ids[MAX_NEIGHBOURS];
    clip[0] = clip[1] = clip[2] = clip[3] = 0;
    if (reach) *reach = 0;
    double e1[3], e2[3];
    if (!tangent_basis(normals + 3 * (size_t)id, e1, e2)) return;
    unsigned found = lk__kd_nearest(tree, p, id, neighbours, false, distance2, ids);
    if (reach && found) *reach = (float)sqrt(distance2[found - 1]);
    unsigned directions = 0;
    for (unsigned j = 0; j < found; j++) {
        const float *q = positions + 3 * (size_t)ids[j];
        double d[3] = {(double)q[0] - p[0], (double)q[1] - p[1], (double)q[2] - p[2]};
        double u = d[0] * e1[0] + d[1] * e1[1] + d[2] * e1[2], v = d[0] * e2[0] + d[1] * e2[1] + d[2] * e2[2];
        double length = sqrt(u * u + v * v);
        if (!(length > 0)) continue; /* a duplicate, or straight above: no direction */
        plane[2 * directions] = u, plane[2 * directions + 1] = v;
        angles[directions++] = atan2(v, u);
    }
    if (directions < 2) return;
    sort_angles(angles, directions);
    /* the widest empty wedge around the point, the wrap-around one first */
    double widest = angles[0] + 2 * CLIP_PI - angles[directions - 1], from = angles[directions - 1], second = 0;
    for (unsigned j = 1; j < directions; j++) {
        double gap = angles[j] - angles[j - 1];
        if (gap > widest)
            second = widest, widest = gap, from = angles[j - 1];
        else if (gap > second)
            second = gap;
    }
    /* open on two sides: a row of points (a scan line), not a border */
    if (second >= CLIP_OPEN_DEGREES * CLIP_PI / 180) return;
    if (widest < CLIP_OPEN_DEGREES * CLIP_PI / 180) return;
    double middle = from + 0.5 * widest, c = cos(middle), s = sin(middle);
    for (int k = 0; k < 3; k++) clip[k] = (float)(c * e1[k] + s * e2[k]);
    /* the neighbours' hull's supporting line across that direction, or
     * the point itself when they all lie behind it: a wedge under 180
     * degrees is also what uneven sampling leaves inside a surface, and
     * there the cut stays outside the neighbours (the bunny's random
     * sample: coverage 87.8% with every cut through its point at 90
     * degrees, 99.64% with this) */
    double support = 0;
    for (unsigned j = 0; j < directions; j++) support = fmax(support, plane[2 * j] * c + plane[2 * j + 1] * s);
    clip[3] = (float)support;
}

static void clips_range(void *context, size_t begin, size_t end)
{
    const clips_job *job = context;
    for (size_t t = begin; t < end; t++) {
        const kd_entry *entry = &job->tree->entries[t];
        clip_line(job->tree, job->positions, job->normals, entry->id, entry->p, job->neighbours,
                  job->clips + 4 * (size_t)entry->id, NULL);
    }
}

/* The clip lines of some of the points (lk__points_estimate_clips_of). */
typedef struct clips_of_job {
    const kd_tree *tree;
    unsigned neighbours;
    const float *positions, *normals;
    const uint32_t *queries;
    float *clips, *reach;
} clips_of_job;

static void clips_of_range(void *context, size_t begin, size_t end)
{
    const clips_of_job *job = context;
    for (size_t i = begin; i < end; i++) {
        uint32_t id = job->queries[i];
        clip_line(job->tree, job->positions, job->normals, id, job->positions + 3 * (size_t)id, job->neighbours,
                  job->clips + 4 * i, job->reach + i);
    }
}

lk_status lk__points_estimate_clips_of(const float *positions, const float *normals, size_t count,
                                       const uint32_t *queries, size_t query_count, unsigned neighbours, float *clips,
                                       float *reach, lk_error *error)
{
    lk_status status = check_neighbours(neighbours, error);
    if (status != LK_OK) return status;
    if (count < 2) {
        memset(clips, 0, 4 * query_count * sizeof *clips);
        memset(reach, 0, query_count * sizeof *reach);
        return LK_OK;
    }
    kd_tree tree;
    status = lk__kd_build(&tree, positions, count, error);
    if (status != LK_OK) return status;
    clips_of_job job = {
        &tree, neighbours < count ? neighbours : (unsigned)(count - 1), positions, normals, queries, clips, reach};
    lk__points_parallel_for(query_count, 8192, clips_of_range, &job);
    lk__kd_free(&tree);
    return LK_OK;
}

lk_status lk_points_estimate_clips(const lk_mesh *points, unsigned neighbours, float *clips, lk_error *error)
{
    lk_status status = check_neighbours(neighbours, error);
    if (status == LK_OK) status = check_positions(points, error);
    if (status != LK_OK) return status;
    if (!clips) return lk_error_set(error, LK_ERR_INVALID, "no array for the clip lines");
    size_t count = points->vertex_count;
    if (count && !points->normals)
        return lk_error_set(error, LK_ERR_INVALID,
                            "the points have no normals, which clip lines need (lk_points_estimate_normals)");
    if (count < 2) {
        memset(clips, 0, 4 * count * sizeof *clips);
        return LK_OK;
    }
    kd_tree tree;
    status = lk__kd_build(&tree, points->positions, count, error);
    if (status != LK_OK) return status;
    clips_job job = {&tree, neighbours < count ? neighbours : (unsigned)(count - 1), points->positions, points->normals,
                     clips};
    lk__points_parallel_for(count, 8192, clips_range, &job);
    lk__kd_free(&tree);
    return LK_OK;
}

typedef struct medians_job {
    const kd_tree *tree;
    unsigned neighbours;
    const float *radii;
    float *medians;
} medians_job;

static void medians_range(void *context, size_t begin, size_t end)
{
    const medians_job *job = context;
    double distance2[MAX_NEIGHBOURS];
    uint32_t id[MAX_NEIGHBOURS];
    for (size_t t = begin; t < end; t++) {
        const kd_entry *entry = &job->tree->entries[t];
        unsigned found = lk__kd_nearest(job->tree, entry->p, entry->id, job->neighbours, false, distance2, id);
        job->medians[entry->id] = found ? neighbour_median(job->radii, id, found) : job->radii[entry->id];
    }
}

lk_status lk__points_neighbour_medians(const lk_mesh *points, unsigned neighbours, float *medians, lk_error *error)
{
    lk_status status = check_neighbours(neighbours, error);
    if (status == LK_OK) status = check_positions(points, error);
    if (status != LK_OK) return status;
    if (!points->radii) return lk_error_set(error, LK_ERR_INVALID, "point set has no radii");
    size_t count = points->vertex_count;
    if (count == 0) return LK_OK;
    kd_tree tree;
    status = lk__kd_build(&tree, points->positions, count, error);
    if (status != LK_OK) return status;
    medians_job job = {&tree, neighbours < count ? neighbours : (unsigned)(count - 1), points->radii, medians};
    lk__points_parallel_for(count, 8192, medians_range, &job);
    lk__kd_free(&tree);
    return LK_OK;
}

/* ---- normals ----------------------------------------------------------------- */

/* Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations:
 * each rotation zeroes one off-diagonal entry; a few sweeps bring them all
 * below rounding. Unconditionally stable, exact for diagonal input (zero
 * rotations), and fine with repeated or zero eigenvalues, which closed-form
 * cubic solutions handle badly. vectors[r][c]: column c is the eigenvector
 * of values[c]. */
static void symmetric_eigen3(const double matrix[3][3], double values[3], double vectors[3][3])
{
    double a[3][3];
    memcpy(a, matrix, sizeof a);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) vectors[r][c] = r == c;
    static const int pairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
    for (int sweep = 0; sweep < 32; sweep++) {
        double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        double diagonal = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if (off <= 1e-30 * diagonal || off == 0) break;
        for (int pair = 0; pair < 3; pair++) {
            int p = pairs[pair][0], q = pairs[pair][1];
            double apq = a[p][q];
            if (apq == 0) continue;
            /* tan of the rotation angle, the smaller root, written so that
             * it neither overflows nor cancels. */
            double theta = (a[q][q] - a[p][p]) / (2 * apq);
            double t =
                fabs(theta) > 1e150 ? 0.5 / theta : (theta >= 0 ? 1 : -1) / (fabs(theta) + sqrt(theta * theta + 1));
            double c = 1 / sqrt(t * t + 1), s = t * c, tau = s / (1 + c);
            a[p][p] -= t * apq;
            a[q][q] += t * apq;
            a[p][q] = a[q][p] = 0;
            int r = 3 - p - q; /* the third index */
            double g = a[r][p], h = a[r][q];
            a[r][p] = a[p][r] = g - s * (h + g * tau);
            a[r][q] = a[q][r] = h + s * (g - h * tau);
            for (int row = 0; row < 3; row++) {
                g = vectors[row][p];
                h = vectors[row][q];
                vectors[row][p] = g - s * (h + g * tau);
                vectors[row][q] = h + s * (g - h * tau);
            }
        }
    }
    for (int k = 0; k < 3; k++) values[k] = a[k][k];
}

typedef struct normals_job {
    const kd_tree *tree;
    const float *positions;
    unsigned neighbours;
    uint32_t *neighbour_ids; /* neighbours per point */
    float *normals;
    unsigned char *flat; /* 1 where the neighbourhood has no spread: no plane */
} normals_job;

/* Normal of the least-squares plane through a point and its neighbours:
 * the eigenvector of the smallest eigenvalue of their covariance. */
static void normals_range(void *context, size_t begin, size_t end)
{
    const normals_job *job = context;
    unsigned k = job->neighbours;
    double distance2[MAX_NEIGHBOURS];
    for (size_t t = begin; t < end; t++) {
        const kd_entry *entry = &job->tree->entries[t];
        uint32_t i = entry->id, *ids = job->neighbour_ids + (size_t)i * k;
        unsigned found = lk__kd_nearest(job->tree, entry->p, i, k, false, distance2, ids);
        for (unsigned j = found; j < k; j++) ids[j] = i; /* only when the set is tiny */
        /* Centred on the point itself first (exact in float differences),
         * then on the mean, all in double. */
        double mean[3] = {0, 0, 0}, d[MAX_NEIGHBOURS + 1][3];
        for (unsigned j = 0; j <= found; j++) {
            const float *p = j == found ? entry->p : job->positions + 3 * (size_t)ids[j];
            for (int c = 0; c < 3; c++) {
                d[j][c] = (double)p[c] - entry->p[c];
                mean[c] += d[j][c];
            }
        }
        for (int c = 0; c < 3; c++) mean[c] /= (double)(found + 1);
        double covariance[3][3] = {{0}};
        for (unsigned j = 0; j <= found; j++)
            for (int r = 0; r < 3; r++)
                for (int c = r; c < 3; c++) covariance[r][c] += (d[j][r] - mean[r]) * (d[j][c] - mean[c]);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < r; c++) covariance[r][c] = covariance[c][r];
        double values[3], vectors[3][3];
        symmetric_eigen3(covariance, values, vectors);
        int smallest = 0;
        for (int c = 1; c < 3; c++)
            if (values[c] < values[smallest]) smallest = c;
        double trace = covariance[0][0] + covariance[1][1] + covariance[2][2];
        float *n = job->normals + 3 * (size_t)i;
        double length = sqrt(vectors[0][smallest] * vectors[0][smallest] + vectors[1][smallest] * vectors[1][smallest] +
                             vectors[2][smallest] * vectors[2][smallest]);
        for (int c = 0; c < 3; c++) n[c] = (float)(vectors[c][smallest] / length);
        job->flat[i] = !(trace > 0);
        if (job->flat[i]) n[0] = 0, n[1] = 0, n[2] = 1;
    }
}

/* Indexed binary min-heap of point ids keyed by a float cost (ties by id,
 * so the order is fully determined). position[id] = slot or UINT32_MAX. */
typedef struct cost_heap {
    uint32_t *items;
    uint32_t *position;
    float *key;
    size_t size;
} cost_heap;

static bool heap_less(const cost_heap *heap, uint32_t a, uint32_t b)
{
    return heap->key[a] < heap->key[b] || (heap->key[a] == heap->key[b] && a < b);
}

static void heap_place(cost_heap *heap, size_t slot, uint32_t id)
{
    heap->items[slot] = id;
    heap->position[id] = (uint32_t)slot;
}

static void heap_up(cost_heap *heap, size_t slot)
{
    uint32_t id = heap->items[slot];
    while (slot > 0) {
        size_t parent = (slot - 1) / 2;
        if (!heap_less(heap, id, heap->items[parent])) break;
        heap_place(heap, slot, heap->items[parent]);
        slot = parent;
    }
    heap_place(heap, slot, id);
}

static void heap_down(cost_heap *heap, size_t slot)
{
    uint32_t id = heap->items[slot];
    for (;;) {
        size_t child = 2 * slot + 1;
        if (child >= heap->size) break;
        if (child + 1 < heap->size && heap_less(heap, heap->items[child + 1], heap->items[child])) child++;
        if (!heap_less(heap, heap->items[child], id)) break;
        heap_place(heap, slot, heap->items[child]);
        slot = child;
    }
    heap_place(heap, slot, id);
}

static uint32_t heap_pop(cost_heap *heap)
{
    uint32_t top = heap->items[0];
    heap->position[top] = UINT32_MAX;
    heap->size--;
    if (heap->size) {
        heap_place(heap, 0, heap->items[heap->size]);
        heap_down(heap, 0);
    }
    return top;
}

/* Cost of propagating the orientation along the edge i-j: Hoppe's
 * 1 - |n_i . n_j| (near 0 between parallel tangent planes), plus how much
 * the edge runs along the normals. The second term is what keeps the
 * orientation from jumping across a thin sheet (an ear, a fin): there the
 * two sides' planes are parallel too, so |n_i . n_j| alone cannot tell them
 * apart, but the edge between them is perpendicular to both, while edges
 * within one side lie in the plane. */
static float edge_cost(const float *positions, const float *normals, const unsigned char *flat, uint32_t i, uint32_t j)
{
    if (flat[i] || flat[j]) return 2.0f; /* no plane: attach these last */
    const float *a = normals + 3 * (size_t)i, *b = normals + 3 * (size_t)j;
    double dot = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2];
    double e[3], length2 = 0;
    for (int c = 0; c < 3; c++) {
        e[c] = (double)positions[3 * (size_t)j + c] - positions[3 * (size_t)i + c];
        length2 += e[c] * e[c];
    }
    double along = 0;
    if (length2 > 0) {
        double ea = (e[0] * a[0] + e[1] * a[1] + e[2] * a[2]), eb = (e[0] * b[0] + e[1] * b[1] + e[2] * b[2]);
        along = 0.5 * (fabs(ea) + fabs(eb)) / sqrt(length2);
    }
    return (float)(1 - fabs(dot) + along);
}

typedef struct z_order {
    float z;
    uint32_t id;
} z_order;

static int compare_z_descending(const void *a, const void *b)
{
    const z_order *x = a, *y = b;
    if (x->z != y->z) return x->z > y->z ? -1 : 1;
    return x->id < y->id ? -1 : x->id > y->id;
}

/* Orients the normals consistently: a minimum spanning tree (Prim) of the
 * symmetric k-NN graph under edge_cost, grown from the highest point of
 * each connected part, whose normal is turned to +z (at a surface's
 * highest point the outward normal points up); every point then takes the
 * side of the tree neighbour it was reached from. */
static lk_status orient_normals(const float *positions, size_t count, unsigned k, const uint32_t *neighbour_ids,
                                float *normals, const unsigned char *flat, lk_error *error)
{
    /* Symmetric adjacency in compressed rows: every k-NN edge both ways. */
    size_t edge_total = 2 * count * (size_t)k;
    size_t *offsets = lk__calloc_array(count + 1, sizeof(size_t));
    uint32_t *adjacent = lk__malloc_array(edge_total, sizeof(uint32_t));
    uint32_t *parent = lk__malloc_array(count, sizeof(uint32_t));
    unsigned char *done = lk__calloc_array(count, 1);
    z_order *order = lk__malloc_array(count, sizeof(z_order));
    cost_heap heap = {lk__malloc_array(count, sizeof(uint32_t)), lk__malloc_array(count, sizeof(uint32_t)),
                      lk__malloc_array(count, sizeof(float)), 0};
    lk_status status = LK_OK;
    if (!offsets || !adjacent || !parent || !done || !order || !heap.items || !heap.position || !heap.key) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the neighbour graph of %zu points", count);
        goto done;
    }
    for (size_t i = 0; i < count; i++)
        for (unsigned j = 0; j < k; j++) {
            offsets[i + 1]++;
            offsets[neighbour_ids[i * k + j] + 1]++;
        }
    for (size_t i = 0; i < count; i++) offsets[i + 1] += offsets[i];
    for (size_t i = 0; i < count; i++)
        for (unsigned j = 0; j < k; j++) {
            uint32_t other = neighbour_ids[i * k + j];
            adjacent[offsets[i]++] = other;
            adjacent[offsets[other]++] = (uint32_t)i;
        }
    for (size_t i = count; i > 0; i--) offsets[i] = offsets[i - 1];
    offsets[0] = 0;

    for (size_t i = 0; i < count; i++) {
        order[i] = (z_order){positions[3 * i + 2], (uint32_t)i};
        heap.position[i] = UINT32_MAX;
        heap.key[i] = INFINITY;
        parent[i] = UINT32_MAX;
    }
    qsort(order, count, sizeof *order, compare_z_descending);
    for (size_t o = 0; o < count; o++) {
        uint32_t seed = order[o].id;
        if (done[seed]) continue;
        /* The highest point of a part not reached yet: a new part. */
        float *n = normals + 3 * (size_t)seed;
        if (n[2] < 0) n[0] = -n[0], n[1] = -n[1], n[2] = -n[2];
        heap.key[seed] = 0;
        heap_place(&heap, heap.size++, seed);
        heap_up(&heap, heap.size - 1);
        while (heap.size) {
            uint32_t v = heap_pop(&heap);
            done[v] = 1;
            float *nv = normals + 3 * (size_t)v;
            if (parent[v] != UINT32_MAX) {
                const float *np = normals + 3 * (size_t)parent[v];
                if (flat[v]) {
                    memcpy(nv, np, 3 * sizeof(float)); /* no plane of its own: borrow one */
                } else if ((double)nv[0] * np[0] + (double)nv[1] * np[1] + (double)nv[2] * np[2] < 0) {
                    nv[0] = -nv[0], nv[1] = -nv[1], nv[2] = -nv[2];
                }
            }
            for (size_t e = offsets[v]; e < offsets[v + 1]; e++) {
                uint32_t u = adjacent[e];
                if (done[u] || u == v) continue;
                float cost = edge_cost(positions, normals, flat, v, u);
                if (!(cost < heap.key[u])) continue;
                heap.key[u] = cost;
                parent[u] = v;
                if (heap.position[u] == UINT32_MAX) heap_place(&heap, heap.size++, u);
                heap_up(&heap, heap.position[u]);
            }
        }
    }
done:
    free(offsets);
    free(adjacent);
    free(parent);
    free(done);
    free(order);
    free(heap.items);
    free(heap.position);
    free(heap.key);
    return status;
}

lk_status lk_points_estimate_normals(lk_mesh *points, unsigned neighbours, lk_error *error)
{
    lk_status status = check_neighbours(neighbours, error);
    if (status != LK_OK) return status;
    status = check_positions(points, error);
    if (status != LK_OK) return status;
    size_t count = points->vertex_count;
    float *normals = lk__malloc_array(count, 3 * sizeof(float));
    if (!normals) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate normals for %zu points", count);
    if (count < 2) {
        /* No neighbourhood at all: any direction is as good; pick +z. */
        for (size_t i = 0; i < count; i++) normals[3 * i] = 0, normals[3 * i + 1] = 0, normals[3 * i + 2] = 1;
        free(points->normals);
        points->normals = normals;
        return LK_OK;
    }
    unsigned k = neighbours < count ? neighbours : (unsigned)(count - 1);
    uint32_t *neighbour_ids = lk__malloc_array(count, (size_t)k * sizeof(uint32_t));
    unsigned char *flat = lk__malloc_array(count, 1);
    kd_tree tree = {0};
    if (!neighbour_ids || !flat) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate neighbour lists for %zu points", count);
        goto done;
    }
    status = lk__kd_build(&tree, points->positions, count, error);
    if (status != LK_OK) goto done;
    normals_job job = {&tree, points->positions, k, neighbour_ids, normals, flat};
    lk__points_parallel_for(count, 4096, normals_range, &job);
    lk__kd_free(&tree);
    status = orient_normals(points->positions, count, k, neighbour_ids, normals, flat, error);
done:
    lk__kd_free(&tree);
    free(neighbour_ids);
    free(flat);
    if (status != LK_OK) {
        free(normals);
        return status;
    }
    free(points->normals);
    points->normals = normals;
    return LK_OK;
}

/* ---- sampling ---------------------------------------------------------------- */

static lk_status cancelled(lk_error *error) { return lk_error_set(error, LK_ERR_INVALID, "cancelled"); }

typedef struct sample_job {
    const lk_mesh *mesh;
    const double *cumulative; /* cumulative[t]: area of triangles 0..t */
    size_t last_triangle;     /* last triangle of positive area */
    uint64_t key;             /* from the seed */
    float *positions, *normals;
} sample_job;

/* Sample i depends only on (seed, i): three counter-based random numbers
 * pick a triangle in proportion to its area (binary search in the
 * cumulative areas) and a uniform point in it (barycentric coordinates
 * (1 - sqrt(u), sqrt(u)(1 - v), sqrt(u) v) are uniform over the triangle). */
static void sample_range(void *context, size_t begin, size_t end)
{
    const sample_job *job = context;
    const lk_mesh *mesh = job->mesh;
    double total = job->cumulative[mesh->triangle_count - 1];
    for (size_t i = begin; i < end; i++) {
        uint64_t counter = job->key + 3 * (uint64_t)i;
        double target = lk__unit_double(lk__mix64(counter)) * total;
        double u = lk__unit_double(lk__mix64(counter + 1)), v = lk__unit_double(lk__mix64(counter + 2));
        /* First triangle whose cumulative area exceeds the target; those of
         * zero area never do. */
        size_t lo = 0, hi = job->last_triangle;
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (job->cumulative[mid] > target)
                hi = mid;
            else
                lo = mid + 1;
        }
        const uint32_t *triangle = mesh->indices + 3 * lo;
        double s = sqrt(u), w[3] = {1 - s, s * (1 - v), s * v};
        const float *a = mesh->positions + 3 * (size_t)triangle[0], *b = mesh->positions + 3 * (size_t)triangle[1],
                    *c = mesh->positions + 3 * (size_t)triangle[2];
        for (int k = 0; k < 3; k++) job->positions[3 * i + k] = (float)(w[0] * a[k] + w[1] * b[k] + w[2] * c[k]);
        double n[3] = {0, 0, 0}, length = 0;
        if (mesh->normals) {
            for (int k = 0; k < 3; k++)
                for (int corner = 0; corner < 3; corner++)
                    n[k] += w[corner] * mesh->normals[3 * (size_t)triangle[corner] + k];
            length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        }
        if (!(length > 1e-12)) {
            /* No vertex normals, or they cancel out here: the triangle's. */
            double e1[3], e2[3];
            for (int k = 0; k < 3; k++) e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
            n[0] = e1[1] * e2[2] - e1[2] * e2[1];
            n[1] = e1[2] * e2[0] - e1[0] * e2[2];
            n[2] = e1[0] * e2[1] - e1[1] * e2[0];
            length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        }
        for (int k = 0; k < 3; k++) job->normals[3 * i + k] = (float)(n[k] / length);
    }
}

/* ---- Poisson-disk subset by weighted sample elimination --------------------
 * (Yuksel, "Sample Elimination for Generating Poisson Disk Sample Sets",
 * 2015.) From a uniform pool several times larger than wanted, repeatedly
 * drop the sample that is most crowded: each sample's weight is the sum of
 * (1 - d / (2 r_max))^8 over the other samples within 2 r_max, where r_max
 * is the disk radius of the densest packing of N disks on the area
 * (hexagonal: A / N = 2 sqrt(3) r_max^2). Dropping a sample lowers its
 * neighbours' weights. Distances below 2 r_min, r_min a fraction of r_max
 * that grows as the pool gets denser than the target, count as 2 r_min,
 * which keeps the elimination from fussing over pairs that will be broken
 * up anyway. The result has exactly point_count points with blue-noise
 * spacing; distances are straight-line (3-D), so the sides of a thin part
 * keep their distance too. */

/* Fixed-radius neighbours through a uniform grid: points sorted by cell
 * and a hash table from each non-empty cell to its run. For this many
 * queries of one radius it beat the k-d tree here; cells of twice the
 * radius measured fastest (fewer hash look-ups outweigh the extra
 * candidates). */
typedef struct grid_run {
    uint64_t key; /* packed cell coordinates + 1; 0 marks an empty slot */
    uint32_t begin, end;
} grid_run;

typedef struct point_grid {
    double origin[3], inverse_cell;
    int64_t cells[3];  /* cells per axis */
    kd_entry *entries; /* sorted by cell */
    grid_run *table;
    size_t mask;
} point_grid;

static void grid_free(point_grid *grid)
{
    free(grid->entries);
    free(grid->table);
    memset(grid, 0, sizeof *grid);
}

static int64_t grid_coordinate(const point_grid *grid, const float *p, int axis)
{
    int64_t c = (int64_t)floor(((double)p[axis] - grid->origin[axis]) * grid->inverse_cell);
    return c < 0 ? 0 : c >= grid->cells[axis] ? grid->cells[axis] - 1 : c;
}

static uint64_t grid_pack(int64_t x, int64_t y, int64_t z)
{
    return ((uint64_t)x | (uint64_t)y << 21 | (uint64_t)z << 42) + 1;
}

static int compare_entry_key(const void *a, const void *b)
{
    const uint64_t *x = a, *y = b; /* (key, index) pairs */
    if (x[0] != y[0]) return x[0] < y[0] ? -1 : 1;
    return x[1] < y[1] ? -1 : x[1] > y[1];
}

static lk_status grid_build(point_grid *grid, const float *positions, size_t count, double cell, lk_error *error)
{
    memset(grid, 0, sizeof *grid);
    float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    lk_mesh view = {.vertex_count = count, .positions = (float *)positions};
    (void)lk_mesh_bounds(&view, lo, hi);
    /* 21 bits per axis in the packed key: widen the cells of a very
     * elongated set (more candidates per query, same answers). */
    for (int k = 0; k < 3; k++) cell = fmax(cell, ((double)hi[k] - lo[k]) / 2000000.0);
    if (!(cell > 0)) cell = 1;
    grid->inverse_cell = 1 / cell;
    for (int k = 0; k < 3; k++) {
        grid->origin[k] = lo[k];
        grid->cells[k] = (int64_t)(((double)hi[k] - lo[k]) * grid->inverse_cell) + 1;
        if (grid->cells[k] > (1 << 21) - 1) grid->cells[k] = (1 << 21) - 1;
    }
    size_t table_size = 16;
    while (table_size < 2 * count) table_size *= 2;
    uint64_t *order = lk__malloc_array(count, 2 * sizeof(uint64_t));
    grid->entries = lk__malloc_array(count, sizeof(kd_entry));
    grid->table = lk__calloc_array(table_size, sizeof(grid_run));
    if (!order || !grid->entries || !grid->table) {
        free(order);
        grid_free(grid);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate a grid of %zu points", count);
    }
    grid->mask = table_size - 1;
    for (size_t i = 0; i < count; i++) {
        const float *p = positions + 3 * i;
        order[2 * i] = grid_pack(grid_coordinate(grid, p, 0), grid_coordinate(grid, p, 1), grid_coordinate(grid, p, 2));
        order[2 * i + 1] = i;
    }
    qsort(order, count, 2 * sizeof(uint64_t), compare_entry_key);
    for (size_t i = 0; i < count; i++) {
        size_t id = (size_t)order[2 * i + 1];
        memcpy(grid->entries[i].p, positions + 3 * id, 3 * sizeof(float));
        grid->entries[i].id = (uint32_t)id;
        if (i > 0 && order[2 * i] == order[2 * i - 2]) continue;
        size_t slot = lk__mix64(order[2 * i]) & grid->mask;
        while (grid->table[slot].key) slot = (slot + 1) & grid->mask;
        size_t end = i + 1;
        while (end < count && order[2 * end] == order[2 * i]) end++;
        grid->table[slot] = (grid_run){order[2 * i], (uint32_t)i, (uint32_t)end};
    }
    free(order);
    return LK_OK;
}

/* Calls visit(context, id, distance2) for every point strictly within
 * `radius` of q (radius2 = radius^2): scans the cells that the ball's
 * bounding box meets. */
static void grid_within(const point_grid *grid, const float q[3], double radius, double radius2, kd_visit_fn visit,
                        void *context)
{
    int64_t first[3], last[3];
    for (int k = 0; k < 3; k++) {
        double t = ((double)q[k] - grid->origin[k]) * grid->inverse_cell, reach = radius * grid->inverse_cell;
        first[k] = (int64_t)floor(t - reach);
        last[k] = (int64_t)floor(t + reach);
        if (first[k] < 0) first[k] = 0;
        if (last[k] > grid->cells[k] - 1) last[k] = grid->cells[k] - 1;
    }
    for (int64_t z = first[2]; z <= last[2]; z++)
        for (int64_t y = first[1]; y <= last[1]; y++)
            for (int64_t x = first[0]; x <= last[0]; x++) {
                uint64_t key = grid_pack(x, y, z);
                size_t slot = lk__mix64(key) & grid->mask;
                while (grid->table[slot].key && grid->table[slot].key != key) slot = (slot + 1) & grid->mask;
                const grid_run *run = &grid->table[slot];
                for (uint32_t i = run->begin; i < run->end; i++) {
                    double d = lk__point_distance2(grid->entries[i].p, q);
                    if (d < radius2) visit(context, grid->entries[i].id, d);
                }
            }
}

typedef struct elimination {
    const point_grid *grid;
    double range, range2, floor_distance; /* 2 r_max, its square, 2 r_min */
    double *weight;
    const unsigned char *alive;
    /* the visitor's current target */
    uint32_t self;
    double sum;
} elimination;

static double crowding(const elimination *e, double distance2)
{
    double d = sqrt(distance2);
    if (d < e->floor_distance) d = e->floor_distance;
    double x = 1 - d / e->range;
    double x2 = x * x, x4 = x2 * x2;
    return x4 * x4;
}

static void add_weight(void *context, uint32_t id, double distance2)
{
    elimination *e = context;
    if (id != e->self) e->sum += crowding(e, distance2);
}

static void weights_range(void *context, size_t begin, size_t end)
{
    elimination local = *(const elimination *)context; /* private visitor state per thread */
    for (size_t i = begin; i < end; i++) {
        local.self = (uint32_t)i;
        local.sum = 0;
        grid_within(local.grid, local.grid->entries[i].p, local.range, local.range2, add_weight, &local);
        local.weight[i] = local.sum;
    }
}

static void remove_weight(void *context, uint32_t id, double distance2)
{
    elimination *e = context;
    if (id != e->self && e->alive[id]) e->weight[id] -= crowding(e, distance2);
}

/* Max-heap of (weight, id), heaviest first, ties by the smaller id. Lazy:
 * weights only fall, so an entry may hold an outdated, larger weight; the
 * top is checked against the current weight when it is taken and pushed
 * back down if it was stale. That spares a heap update per neighbour of
 * every removed sample. */
typedef struct weight_entry {
    double weight;
    uint32_t id;
} weight_entry;

static bool entry_before(const weight_entry *a, const weight_entry *b)
{
    return a->weight > b->weight || (a->weight == b->weight && a->id < b->id);
}

static void entry_down(weight_entry *heap, size_t size, size_t slot)
{
    weight_entry item = heap[slot];
    for (;;) {
        size_t child = 2 * slot + 1;
        if (child >= size) break;
        if (child + 1 < size && entry_before(&heap[child + 1], &heap[child])) child++;
        if (!entry_before(&heap[child], &item)) break;
        heap[slot] = heap[child];
        slot = child;
    }
    heap[slot] = item;
}

/* fn over [offset + begin, offset + end): a parallel_for over part of a range. */
typedef struct offset_job {
    range_fn fn;
    void *context;
    size_t offset;
} offset_job;

static void offset_range(void *context, size_t begin, size_t end)
{
    const offset_job *job = context;
    job->fn(job->context, job->offset + begin, job->offset + end);
}

static lk_status poisson_subset(const float *positions, const float *normals, size_t pool_count, size_t target,
                                double area, float *out_positions, float *out_normals, lk_progress_fn progress,
                                void *progress_user, lk_error *error)
{
    double r_max = sqrt(area / (2 * sqrt(3.0) * (double)target));
    point_grid grid;
    lk_status status = grid_build(&grid, positions, pool_count, 4 * r_max, error);
    if (status != LK_OK) return status;
    if (progress && progress(progress_user, 0.2, "poisson")) {
        grid_free(&grid);
        return cancelled(error);
    }
    double *weight = lk__malloc_array(pool_count, sizeof(double));
    unsigned char *alive = lk__malloc_array(pool_count, 1);
    weight_entry *heap = lk__malloc_array(pool_count, sizeof(weight_entry));
    uint32_t *pool_index = lk__malloc_array(pool_count, sizeof(uint32_t));
    if (!weight || !alive || !heap || !pool_index) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate Poisson-disk tables for %zu samples", pool_count);
        goto done;
    }
    /* Work in the grid's order, not the pool's (random) one: the weights
     * and flags of a sample's neighbours then sit next to each other in
     * memory, which makes the elimination several times faster. */
    for (size_t i = 0; i < pool_count; i++) {
        pool_index[i] = grid.entries[i].id;
        grid.entries[i].id = (uint32_t)i;
    }
    double ratio = (double)target / (double)pool_count;
    elimination e = {&grid, 2 * r_max, 4 * r_max * r_max, 2 * r_max * 0.65 * (1 - pow(ratio, 1.5)), weight, alive,
                     0,     0};
    /* The weights in pieces, with progress between them (each sample's
     * weight is its own, so the pieces change nothing). */
    enum { WEIGHT_PIECES = 16 };
    for (size_t piece = 0; piece < WEIGHT_PIECES; piece++) {
        size_t begin = pool_count * piece / WEIGHT_PIECES, end = pool_count * (piece + 1) / WEIGHT_PIECES;
        offset_job job = {weights_range, &e, begin};
        lk__points_parallel_for(end - begin, 4096, offset_range, &job);
        if (progress && progress(progress_user, 0.2 + 0.3 * (double)(piece + 1) / WEIGHT_PIECES, "poisson")) {
            status = cancelled(error);
            goto done;
        }
    }
    memset(alive, 1, pool_count);
    size_t heap_size = pool_count;
    for (size_t i = 0; i < pool_count; i++) heap[i] = (weight_entry){weight[i], (uint32_t)i};
    for (size_t i = pool_count / 2; i-- > 0;) entry_down(heap, heap_size, i);
    size_t to_remove = pool_count - target;
    for (size_t removed = 0, next_report = 0; removed < to_remove;) {
        if (progress && removed == next_report) {
            next_report += 65536;
            if (progress(progress_user, 0.5 + 0.4 * (double)removed / (double)to_remove, "poisson")) {
                status = cancelled(error);
                goto done;
            }
        }
        weight_entry top = heap[0];
        if (top.weight != weight[top.id]) { /* stale: re-rank with its current weight */
            heap[0].weight = weight[top.id];
            entry_down(heap, heap_size, 0);
            continue;
        }
        alive[top.id] = 0;
        heap[0] = heap[--heap_size];
        entry_down(heap, heap_size, 0);
        e.self = top.id;
        grid_within(&grid, grid.entries[top.id].p, e.range, e.range2, remove_weight, &e);
        removed++;
    }
    size_t next = 0;
    for (size_t i = 0; i < pool_count; i++) {
        if (!alive[i]) continue;
        memcpy(out_positions + 3 * next, grid.entries[i].p, 3 * sizeof(float));
        memcpy(out_normals + 3 * next, normals + 3 * (size_t)pool_index[i], 3 * sizeof(float));
        next++;
    }
done:
    grid_free(&grid);
    free(weight);
    free(alive);
    free(heap);
    free(pool_index);
    return status;
}

/* Uniform pool size for the Poisson-disk subset, as a multiple of the
 * points wanted: more gives a slightly better spacing for more time. */
enum { POISSON_POOL_FACTOR = 5 };

lk_status lk_mesh_sample_points(const lk_mesh *mesh, const lk_sample_options *options, lk_mesh *points,
                                lk_progress_fn progress, void *progress_user, lk_error *error)
{
    lk_sample_options defaults;
    lk_sample_options_default(&defaults);
    if (!options) options = &defaults;
    if (points == mesh) return lk_error_set(error, LK_ERR_INVALID, "the output point set must not be the input mesh");
    lk_mesh_init(points);
    if (options->point_count == 0 || options->point_count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_INVALID, "point count must be between 1 and %zu, got %zu", LK_MAX_ELEMENTS,
                            options->point_count);
    lk_status status = check_neighbours(options->neighbours, error);
    if (status != LK_OK) return status;
    if (!(options->radius_scale > 0) || !isfinite(options->radius_scale))
        return lk_error_set(error, LK_ERR_INVALID, "radius scale must be a finite number > 0, got %g",
                            options->radius_scale);
    if (mesh->triangle_count == 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "the mesh has no triangles to sample (%zu points: a point set already)",
                            mesh->vertex_count);
    status = lk_mesh_validate(mesh, error);
    if (status != LK_OK) return status;

    size_t triangle_count = mesh->triangle_count;
    double *cumulative = lk__malloc_array(triangle_count, sizeof(double));
    if (!cumulative)
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate an area table of %zu triangles", triangle_count);
    double total = 0;
    size_t last_triangle = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *tri = mesh->indices + 3 * t;
        const float *a = mesh->positions + 3 * (size_t)tri[0], *b = mesh->positions + 3 * (size_t)tri[1],
                    *c = mesh->positions + 3 * (size_t)tri[2];
        double e1[3], e2[3];
        for (int k = 0; k < 3; k++) e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
        double n0 = e1[1] * e2[2] - e1[2] * e2[1], n1 = e1[2] * e2[0] - e1[0] * e2[2],
               n2 = e1[0] * e2[1] - e1[1] * e2[0];
        double area = 0.5 * sqrt(n0 * n0 + n1 * n1 + n2 * n2);
        if (area > 0) last_triangle = t;
        total += area;
        cumulative[t] = total;
    }
    if (!(total > 0) || !isfinite(total)) {
        free(cumulative);
        return lk_error_set(error, LK_ERR_INVALID, "the mesh's surface area is %g: nothing to sample", total);
    }

    size_t target = options->point_count;
    size_t pool_count = target;
    if (options->poisson)
        pool_count = target > LK_MAX_ELEMENTS / POISSON_POOL_FACTOR ? LK_MAX_ELEMENTS : target * POISSON_POOL_FACTOR;
    float *pool_positions = lk__malloc_array(pool_count, 3 * sizeof(float));
    float *pool_normals = lk__malloc_array(pool_count, 3 * sizeof(float));
    if (!pool_positions || !pool_normals) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu samples", pool_count);
        goto fail;
    }
    if (progress && progress(progress_user, 0.0, "sampling")) {
        status = cancelled(error);
        goto fail;
    }
    sample_job job = {mesh,           cumulative,  last_triangle, lk__mix64(options->seed ^ 0x5A3D1E0F7C6B4829ull),
                      pool_positions, pool_normals};
    lk__points_parallel_for(pool_count, 16384, sample_range, &job);
    free(cumulative);
    cumulative = NULL;
    if (progress && progress(progress_user, options->poisson ? 0.1 : 0.6, "sampling")) {
        status = cancelled(error);
        goto fail;
    }

    status = lk_mesh_alloc(points, target, 0, LK_ATTR_NORMALS, error);
    if (status != LK_OK) goto fail;
    if (options->poisson) {
        status = poisson_subset(pool_positions, pool_normals, pool_count, target, total, points->positions,
                                points->normals, progress, progress_user, error);
        if (status != LK_OK) goto fail;
        free(pool_positions);
        free(pool_normals);
    } else {
        free(points->positions);
        free(points->normals);
        points->positions = pool_positions;
        points->normals = pool_normals;
    }
    pool_positions = pool_normals = NULL;
    if (progress && progress(progress_user, 0.9, "radii")) {
        status = cancelled(error);
        goto fail;
    }
    status = lk_points_estimate_radii(points, options->neighbours, options->radius_scale, error);
    if (status != LK_OK) goto fail;
    if (progress) (void)progress(progress_user, 1.0, "radii"); /* done: too late to cancel */
    return LK_OK;
fail:
    free(cumulative);
    free(pool_positions);
    free(pool_normals);
    lk_mesh_free(points);
    return status;
}
