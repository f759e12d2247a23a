/* SPDX-License-Identifier: MIT */
/* Metro-style surface distance.
 *
 * Three parts:
 *   1. lk_surface_index: a bounding-volume hierarchy (binned SAH, flat array
 *      of 32-byte nodes, up to 4 primitives per leaf) over a mesh's
 *      triangles, or over its vertices when it has no triangles, answering
 *      exact nearest-point queries: point-triangle distance in double
 *      (Ericson's region method on triangles prepared once), degenerate
 *      triangles measured as their three sides.
 *   2. Sampling of a source surface, deterministic whatever order the
 *      samples are taken in:
 *        - S face samples (sample_count, or round(samples_per_face * T), at
 *          least 1), stratified by cumulative area: triangle t receives
 *          round(S*cumA(t)/A) - round(S*cumA(t-1)/A) samples, each uniform in
 *          the triangle from a counter-based random number
 *          (seed, triangle, sample);
 *        - every vertex used by a triangle (unless sample_vertices < 0);
 *        - L * sqrt(S / A) edge samples in all (L the total length of the
 *          unique edges, A the area: Metro's rule, the linear density that
 *          matches the face samples' area density; none if sample_edges < 0)
 *          over the unique edges, stratified by cumulative edge length the
 *          same way; an edge with n samples gets one jittered
 *          sample in each of n equal parts of its length (short edges may
 *          get none: their ends are sampled as vertices).
 *      The maximum is over all samples; mean and RMS are over the face
 *      samples only, which makes them area-weighted estimates of the mean
 *      and RMS distance over the surface. A point set (no triangles) as the
 *      source is sampled at its vertices, and mean/RMS are over them.
 *   3. A driver that splits the samples into fixed-size chunks, measures
 *      them on any number of threads, and combines per-chunk sums in chunk
 *      order, so the result is bit-identical whatever the thread count.
 *
 * Speed comes from coherence: all samples of a source triangle (its face
 * samples, and the vertices and edge samples it owns) are consecutive and
 * are measured against a short list of candidate leaves gathered once for
 * the triangle (see measure_triangle); each query starts from the distance
 * to the previous sample's nearest primitive, and triangles whose plane is
 * already too far are skipped before the full test. Chunks restart this
 * state, so results do not depend on how chunks are spread over threads. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ------------------------------------------------------------------------ */
/* Point-primitive distances                                                */
/* ------------------------------------------------------------------------ */

static inline double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static inline double distance_sq3(const double a[3], const double b[3])
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

/* Closest point to p on segment [a, b] (a point when a == b). */
static double segment_closest(const double a[3], const double b[3], const double p[3], double closest[3])
{
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    double length_sq = dot3(ab, ab);
    double t = length_sq > 0 ? dot3(ap, ab) / length_sq : 0;
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    for (int k = 0; k < 3; k++) closest[k] = a[k] + t * ab[k];
    return distance_sq3(p, closest);
}

/* A triangle whose squared sine of the angle at its first corner is below
 * this is treated as the union of its edges: Ericson's region tests assume
 * a proper triangle, and the true surface of such a sliver lies within
 * 1e-8 * (edge length) of its edges anyway. */
#define LK_DEGENERATE_SINE_SQ 1e-16

/* A triangle prepared for distance queries: what every query would
 * otherwise recompute (128 bytes). */
typedef struct prepared_triangle {
    double a[3], ab[3], ac[3];
    double normal[3]; /* ab x ac */
    double ab_ab, ac_ac, ab_ac;
    double inverse_normal_sq; /* 1 / |normal|^2; 0 marks a degenerate triangle */
} prepared_triangle;

static void prepare_triangle(const float *a, const float *b, const float *c, prepared_triangle *t)
{
    for (int k = 0; k < 3; k++) {
        t->a[k] = a[k];
        t->ab[k] = (double)b[k] - a[k];
        t->ac[k] = (double)c[k] - a[k];
    }
    const double *ab = t->ab, *ac = t->ac;
    t->normal[0] = ab[1] * ac[2] - ab[2] * ac[1];
    t->normal[1] = ab[2] * ac[0] - ab[0] * ac[2];
    t->normal[2] = ab[0] * ac[1] - ab[1] * ac[0];
    t->ab_ab = dot3(ab, ab);
    t->ac_ac = dot3(ac, ac);
    t->ab_ac = dot3(ab, ac);
    double normal_sq = dot3(t->normal, t->normal);
    bool degenerate = !(normal_sq > LK_DEGENERATE_SINE_SQ * t->ab_ab * t->ac_ac);
    t->inverse_normal_sq = degenerate ? 0 : 1 / normal_sq;
}

/* Squared distance from p to the triangle and the closest point, after
 * Ericson, "Real-Time Collision Detection", 5.1.5, with the products that
 * do not depend on p precomputed. In the face region the distance is
 * measured along the normal, which stays accurate for thin triangles. */
static inline double triangle_closest(const prepared_triangle *t, const double p[3], double closest[3])
{
    const double *a = t->a, *ab = t->ab, *ac = t->ac;
    double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    if (t->inverse_normal_sq == 0) { /* degenerate: nearest of its three sides */
        double b[3], c[3], q[3];
        for (int k = 0; k < 3; k++) {
            b[k] = a[k] + ab[k];
            c[k] = a[k] + ac[k];
        }
        double best = segment_closest(a, b, p, closest);
        double d = segment_closest(b, c, p, q);
        if (d < best) {
            best = d;
            memcpy(closest, q, sizeof q);
        }
        d = segment_closest(c, a, p, q);
        if (d < best) {
            best = d;
            memcpy(closest, q, sizeof q);
        }
        return best;
    }
    /* d1 = ab.ap, d2 = ac.ap, d3 = ab.bp, d4 = ac.bp, d5 = ab.cp, d6 = ac.cp */
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) { /* vertex region a */
        memcpy(closest, a, 3 * sizeof(double));
        return dot3(ap, ap);
    }
    double d3 = d1 - t->ab_ab, d4 = d2 - t->ab_ac;
    if (d3 >= 0 && d4 <= d3) { /* vertex region b */
        for (int k = 0; k < 3; k++) closest[k] = a[k] + ab[k];
        return distance_sq3(p, closest);
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) { /* edge region ab */
        double v = d1 / t->ab_ab;
        for (int k = 0; k < 3; k++) closest[k] = a[k] + v * ab[k];
        return distance_sq3(p, closest);
    }
    double d5 = d1 - t->ab_ac, d6 = d2 - t->ac_ac;
    if (d6 >= 0 && d5 <= d6) { /* vertex region c */
        for (int k = 0; k < 3; k++) closest[k] = a[k] + ac[k];
        return distance_sq3(p, closest);
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) { /* edge region ac */
        double w = d2 / t->ac_ac;
        for (int k = 0; k < 3; k++) closest[k] = a[k] + w * ac[k];
        return distance_sq3(p, closest);
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) { /* edge region bc */
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) closest[k] = a[k] + ab[k] + w * (ac[k] - ab[k]);
        return distance_sq3(p, closest);
    }
    /* face region: project p onto the plane */
    double height = dot3(ap, t->normal);
    double s = height * t->inverse_normal_sq;
    for (int k = 0; k < 3; k++) closest[k] = p[k] - s * t->normal[k];
    return height * s;
}

/* Exposed for the unit tests (declared there, not in a header). */
double lk__triangle_closest_point(const float tri[9], const double point[3], double closest[3]);
double lk__triangle_closest_point(const float tri[9], const double point[3], double closest[3])
{
    prepared_triangle t;
    prepare_triangle(tri, tri + 3, tri + 6, &t);
    return triangle_closest(&t, point, closest);
}

/* ------------------------------------------------------------------------ */
/* Bounding-volume hierarchy                                                */
/* ------------------------------------------------------------------------ */

/* 32 bytes. Nodes are stored depth-first: an inner node's left child is the
 * next node, its right child is at `offset`. */
typedef struct bvh_node {
    float lo[3];
    uint32_t offset; /* leaf: first slot; inner: index of the right child */
    float hi[3];
    uint32_t count; /* leaf: primitives in it (> 0); inner: 0 */
} bvh_node;

struct lk_surface_index {
    bool point_set; /* primitives are points, not triangles */
    size_t primitive_count;
    size_t node_count;
    bvh_node *nodes;
    prepared_triangle *triangles; /* per slot, in leaf order (NULL for a point set) */
    float *points;                /* per slot, 3 floats (point sets only) */
    uint32_t *primitive;          /* per slot: original triangle or vertex index */
};

enum {
    LK_LEAF_SIZE = 4,   /* split nodes with more primitives than this */
    LK_BIN_COUNT = 16,  /* SAH bins per axis */
    LK_SAH_DEPTH = 64,  /* below this depth, split in halves (bounds the depth) */
    LK_STACK_SIZE = 128 /* > LK_SAH_DEPTH + 32 */
};

#define LK_NO_SLOT UINT32_MAX

typedef struct box3 {
    float lo[3], hi[3];
} box3;

static const box3 empty_box = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};

/* Branch-free min/max: the comparisons are unpredictable while building. */
static inline void box_grow(box3 *box, const float *lo, const float *hi)
{
    for (int k = 0; k < 3; k++) {
        box->lo[k] = lo[k] < box->lo[k] ? lo[k] : box->lo[k];
        box->hi[k] = hi[k] > box->hi[k] ? hi[k] : box->hi[k];
    }
}

static double box_half_area(const box3 *box)
{
    double dx = (double)box->hi[0] - box->lo[0], dy = (double)box->hi[1] - box->lo[1],
           dz = (double)box->hi[2] - box->lo[2];
    return dx * dy + dy * dz + dz * dx;
}

typedef struct build_state {
    const float *lo, *hi, *centroid; /* 3 per primitive */
    uint32_t *order;                 /* primitive ids, permuted into leaf order */
} build_state;

/* A range of `order` waiting to become a node. */
typedef struct build_item {
    uint32_t begin, end, depth;
    uint32_t parent; /* parent node, or LK_NO_SLOT for the root */
    bool right;      /* the parent's right child (its offset points here) */
    box3 bounds;     /* of the primitives */
    box3 centroids;  /* of their centroids */
} build_item;

/* In double: a float extent of +-3.4e38 centroids overflows to inf, its
 * scale to 0, and (inf * 0) NaN does not convert to int. */
static inline int bin_of(float value, double origin, double scale)
{
    double position = ((double)value - origin) * scale;
    if (!(position > 0)) return 0;
    return position < LK_BIN_COUNT - 1 ? (int)position : LK_BIN_COUNT - 1;
}

/* Splits `item` into two non-empty halves with a binned surface-area
 * heuristic along the axis where the centroids spread most (so one pass
 * over the primitives per level), filling the halves' boxes. Falls back to
 * cutting the range in the middle when the centroids coincide or the tree
 * gets deep. */
static void split_range(const build_state *state, const build_item *item, build_item halves[2])
{
    uint32_t *order = state->order;
    uint32_t begin = item->begin, end = item->end, middle = begin + (end - begin) / 2;
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if ((double)item->centroids.hi[k] - item->centroids.lo[k] >
            (double)item->centroids.hi[axis] - item->centroids.lo[axis])
            axis = k;
    double origin = item->centroids.lo[axis], extent = (double)item->centroids.hi[axis] - origin;
    int best_split = -1;
    box3 bin_box[LK_BIN_COUNT];
    double scale = 0;
    if (item->depth < LK_SAH_DEPTH && extent > 0) {
        scale = LK_BIN_COUNT / extent;
        uint32_t bin_count[LK_BIN_COUNT] = {0};
        for (int b = 0; b < LK_BIN_COUNT; b++) bin_box[b] = empty_box;
        for (uint32_t i = begin; i < end; i++) {
            size_t id = order[i];
            int b = bin_of(state->centroid[3 * id + axis], origin, scale);
            bin_count[b]++;
            box_grow(&bin_box[b], state->lo + 3 * id, state->hi + 3 * id);
        }
        double right_cost[LK_BIN_COUNT]; /* bins split.. as one box */
        box3 right = empty_box;
        uint32_t right_count = 0;
        for (int b = LK_BIN_COUNT - 1; b > 0; b--) {
            box_grow(&right, bin_box[b].lo, bin_box[b].hi);
            right_count += bin_count[b];
            right_cost[b] = right_count ? box_half_area(&right) * right_count : 0;
        }
        box3 left = empty_box;
        uint32_t left_count = 0;
        double best_cost = INFINITY;
        for (int split = 1; split < LK_BIN_COUNT; split++) {
            box_grow(&left, bin_box[split - 1].lo, bin_box[split - 1].hi);
            left_count += bin_count[split - 1];
            if (left_count == 0 || left_count == end - begin) continue;
            double cost = box_half_area(&left) * left_count + right_cost[split];
            if (cost < best_cost) {
                best_cost = cost;
                best_split = split;
            }
        }
    }
    halves[0] = (build_item){begin, middle, item->depth + 1, LK_NO_SLOT, false, empty_box, empty_box};
    halves[1] = (build_item){middle, end, item->depth + 1, LK_NO_SLOT, true, empty_box, empty_box};
    if (best_split < 0) { /* halve, and measure the halves */
        for (int h = 0; h < 2; h++)
            for (uint32_t i = halves[h].begin; i < halves[h].end; i++) {
                size_t id = order[i];
                box_grow(&halves[h].bounds, state->lo + 3 * id, state->hi + 3 * id);
                box_grow(&halves[h].centroids, state->centroid + 3 * id, state->centroid + 3 * id);
            }
        return;
    }
    for (int b = 0; b < LK_BIN_COUNT; b++) {
        box3 *bounds = &halves[b < best_split ? 0 : 1].bounds;
        box_grow(bounds, bin_box[b].lo, bin_box[b].hi);
    }
    /* Partition: bins below best_split go left. */
    uint32_t i = begin, j = end;
    while (i < j) {
        uint32_t id = order[i];
        const float *c = state->centroid + 3 * (size_t)id;
        if (bin_of(c[axis], origin, scale) < best_split) {
            box_grow(&halves[0].centroids, c, c);
            i++;
        } else {
            box_grow(&halves[1].centroids, c, c);
            j--;
            order[i] = order[j];
            order[j] = id;
        }
    }
    halves[0].end = halves[1].begin = i;
}

/* Builds index->nodes depth-first over the primitives; leaves the leaf
 * order in state->order. */
static lk_status build_tree(lk_surface_index *index, build_state *state, lk_error *error)
{
    size_t count = index->primitive_count;
    size_t capacity = 2 * count; /* a binary tree with >= 1 primitive per leaf */
    index->nodes = lk__malloc_array(capacity, sizeof(bvh_node));
    build_item *stack = lk__malloc_array(LK_STACK_SIZE + 2, sizeof(build_item));
    if (!index->nodes || !stack) {
        free(stack);
        return lk_error_set(error, LK_ERR_NOMEM, "surface index: cannot allocate %zu nodes", capacity);
    }
    build_item root = {0, (uint32_t)count, 0, LK_NO_SLOT, false, empty_box, empty_box};
    for (size_t id = 0; id < count; id++) {
        box_grow(&root.bounds, state->lo + 3 * id, state->hi + 3 * id);
        box_grow(&root.centroids, state->centroid + 3 * id, state->centroid + 3 * id);
    }
    size_t node_count = 0, top = 0;
    stack[top++] = root;
    while (top > 0) {
        build_item item = stack[--top];
        uint32_t node_id = (uint32_t)node_count++;
        bvh_node *node = &index->nodes[node_id];
        if (item.right) index->nodes[item.parent].offset = node_id;
        memcpy(node->lo, item.bounds.lo, sizeof node->lo);
        memcpy(node->hi, item.bounds.hi, sizeof node->hi);
        if (item.end - item.begin <= LK_LEAF_SIZE) {
            node->offset = item.begin;
            node->count = item.end - item.begin;
            continue;
        }
        build_item halves[2];
        split_range(state, &item, halves);
        node->count = 0;
        node->offset = 0; /* patched when the right child is created */
        /* Depth-first order: push right, then left, so left comes next. The
         * depth is bounded (halving below LK_SAH_DEPTH), and so is the stack:
         * it holds at most one pending right child per level. */
        halves[0].parent = halves[1].parent = node_id;
        stack[top++] = halves[1];
        stack[top++] = halves[0];
        if (top > LK_STACK_SIZE) { /* cannot happen with the depth bound */
            free(stack);
            return lk_error_set(error, LK_ERR_LIMIT, "surface index: tree too deep");
        }
    }
    free(stack);
    index->node_count = node_count;
    bvh_node *fitted = lk__realloc_array(index->nodes, node_count, sizeof(bvh_node));
    if (fitted) index->nodes = fitted; /* else keep the larger block */
    return LK_OK;
}

void lk_surface_index_free(lk_surface_index *index)
{
    if (!index) return;
    free(index->nodes);
    free(index->triangles);
    free(index->points);
    free(index->primitive);
    free(index);
}

/* The first of every set of triangles with the same three vertices, in
 * mesh order, into source; returns how many. Falls back to every triangle
 * when out of memory (the index is then only slower). */
static size_t unique_triangles(const lk_mesh *mesh, uint32_t *source)
{
    size_t unique = lk__unique_triangles(mesh, false, source);
    if (unique != SIZE_MAX) return unique;
    for (size_t i = 0; i < mesh->triangle_count; i++) source[i] = (uint32_t)i;
    return mesh->triangle_count;
}

lk_status lk_surface_index_build(const lk_mesh *mesh, lk_surface_index **out, lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "surface index: no output pointer");
    *out = NULL;
    if (!mesh) return lk_error_set(error, LK_ERR_INVALID, "surface index: no mesh");
    if (mesh->vertex_count == 0) return lk_error_set(error, LK_ERR_INVALID, "surface index: the mesh has no vertices");
    lk_error inner = {0};
    lk_status status = lk_mesh_validate(mesh, &inner);
    if (status != LK_OK) return lk_error_set(error, status, "surface index: invalid mesh: %s", inner.message);

    bool point_set = mesh->triangle_count == 0;
    size_t count = point_set ? mesh->vertex_count : mesh->triangle_count;
    if (count > 0x7FFFFFFFu)
        return lk_error_set(error, LK_ERR_LIMIT, "surface index: %zu primitives is more than supported (2^31 - 1)",
                            count);
    lk_surface_index *index = calloc(1, sizeof *index);
    float *lo = lk__malloc_array(count, 3 * sizeof(float));
    float *hi = lk__malloc_array(count, 3 * sizeof(float));
    float *centroid = lk__malloc_array(count, 3 * sizeof(float));
    uint32_t *order = lk__malloc_array(count, sizeof(uint32_t));
    uint32_t *source = lk__malloc_array(count, sizeof(uint32_t)); /* index entry -> mesh primitive */
    if (index) {
        index->point_set = point_set;
        index->primitive_count = count;
        if (point_set)
            index->points = lk__malloc_array(count, 3 * sizeof(float));
        else
            index->triangles = lk__malloc_array(count, sizeof(prepared_triangle));
        index->primitive = lk__malloc_array(count, sizeof(uint32_t));
    }
    if (!index || !lo || !hi || !centroid || !order || !source || !(index->points || index->triangles) ||
        !index->primitive) {
        free(lo);
        free(hi);
        free(centroid);
        free(order);
        free(source);
        lk_surface_index_free(index);
        return lk_error_set(error, LK_ERR_NOMEM, "surface index: cannot allocate for %zu primitives", count);
    }
    const float *positions = mesh->positions;
    /* Repeated triangles (same three vertices, any order) are indexed once:
     * they cannot change a distance, and thousands of copies over one spot
     * (a hostile polygon repeating its corners) would make every query
     * near them visit all the copies. */
    count = point_set ? count : unique_triangles(mesh, source);
    if (point_set)
        for (size_t i = 0; i < count; i++) source[i] = (uint32_t)i;
    index->primitive_count = count;
    for (size_t i = 0; i < count; i++) {
        order[i] = (uint32_t)i;
        if (point_set) {
            for (int k = 0; k < 3; k++) lo[3 * i + k] = hi[3 * i + k] = centroid[3 * i + k] = positions[3 * i + k];
            continue;
        }
        const uint32_t *tri = mesh->indices + 3 * (size_t)source[i];
        const float *a = positions + 3 * (size_t)tri[0], *b = positions + 3 * (size_t)tri[1],
                    *c = positions + 3 * (size_t)tri[2];
        for (int k = 0; k < 3; k++) {
            float l = a[k], h = a[k];
            if (b[k] < l) l = b[k];
            if (b[k] > h) h = b[k];
            if (c[k] < l) l = c[k];
            if (c[k] > h) h = c[k];
            lo[3 * i + k] = l;
            hi[3 * i + k] = h;
            centroid[3 * i + k] = (float)(((double)a[k] + b[k] + c[k]) / 3.0);
        }
    }
    build_state state = {lo, hi, centroid, order};
    status = build_tree(index, &state, error);
    free(lo);
    free(hi);
    free(centroid);
    if (status != LK_OK) {
        free(order);
        free(source);
        lk_surface_index_free(index);
        return status;
    }
    /* Gather the geometry into leaf order so that a leaf reads one run. */
    for (size_t slot = 0; slot < count; slot++) {
        uint32_t id = source[order[slot]];
        index->primitive[slot] = id;
        if (point_set) {
            memcpy(index->points + 3 * slot, positions + 3 * (size_t)id, 3 * sizeof(float));
        } else {
            const uint32_t *tri = mesh->indices + 3 * (size_t)id;
            prepare_triangle(positions + 3 * (size_t)tri[0], positions + 3 * (size_t)tri[1],
                             positions + 3 * (size_t)tri[2], &index->triangles[slot]);
        }
    }
    free(order);
    free(source);
    *out = index;
    return LK_OK;
}

static inline double box_distance_sq(const bvh_node *node, const double p[3])
{
    /* Clamp p into the box (compiles to min/max, no branches). */
    double sum = 0;
    for (int k = 0; k < 3; k++) {
        double lo = node->lo[k], hi = node->hi[k];
        double inside = p[k] > lo ? p[k] : lo;
        inside = inside < hi ? inside : hi;
        double outside = p[k] - inside;
        sum += outside * outside;
    }
    return sum;
}

static inline double slot_distance_sq(const lk_surface_index *index, uint32_t slot, const double p[3],
                                      double closest[3])
{
    if (index->point_set) {
        const float *q = index->points + 3 * (size_t)slot;
        for (int k = 0; k < 3; k++) closest[k] = q[k];
        return distance_sq3(p, closest);
    }
    return triangle_closest(&index->triangles[slot], p, closest);
}

/* Like slot_distance_sq, but returns INFINITY without the full test when
 * the distance to the triangle's plane (a lower bound) already reaches
 * `bound_sq`. Cheap, and decisive for points near a smooth surface. */
static inline double slot_distance_sq_below(const lk_surface_index *index, uint32_t slot, const double p[3],
                                            double bound_sq)
{
    double scratch[3];
    if (!index->point_set) {
        const prepared_triangle *t = &index->triangles[slot];
        double height =
            (p[0] - t->a[0]) * t->normal[0] + (p[1] - t->a[1]) * t->normal[1] + (p[2] - t->a[2]) * t->normal[2];
        if (height * height * t->inverse_normal_sq >= bound_sq) return INFINITY;
    }
    return slot_distance_sq(index, slot, p, scratch);
}

/* Nearest slot to p among those strictly closer than sqrt(*best_sq).
 * `known` is a slot whose squared distance is already *best_sq (the
 * previous sample's answer), or LK_NO_SLOT; it is not measured again.
 * Returns the best slot (`known` when nothing is closer) and updates
 * *best_sq. Boxes at or beyond the bound are pruned, and the nearer child
 * is visited first. */
static uint32_t nearest_slot(const lk_surface_index *index, const double p[3], double *best_sq, uint32_t known)
{
    const bvh_node *nodes = index->nodes;
    struct {
        uint32_t node;
        double distance_sq;
    } stack[LK_STACK_SIZE];
    unsigned top = 0;
    double best = *best_sq;
    uint32_t best_slot = known;
    if (!(box_distance_sq(nodes, p) < best)) return best_slot;
    uint32_t node_id = 0;
    for (;;) {
        const bvh_node *node = &nodes[node_id];
        if (node->count) {
            uint32_t end = node->offset + node->count;
            for (uint32_t slot = node->offset; slot < end; slot++) {
                if (slot == known) continue;
                double d = slot_distance_sq_below(index, slot, p, best);
                if (d < best) {
                    best = d;
                    best_slot = slot;
                }
            }
        } else {
            uint32_t near_id = node_id + 1, far_id = node->offset;
            double near_d = box_distance_sq(&nodes[near_id], p), far_d = box_distance_sq(&nodes[far_id], p);
            if (far_d < near_d) {
                uint32_t swap_id = near_id;
                near_id = far_id;
                far_id = swap_id;
                double swap_d = near_d;
                near_d = far_d;
                far_d = swap_d;
            }
            if (near_d < best) {
                if (far_d < best) {
                    stack[top].node = far_id;
                    stack[top].distance_sq = far_d;
                    top++;
                }
                node_id = near_id;
                continue;
            }
        }
        for (;;) { /* pop the next box that can still hold something closer */
            if (top == 0) {
                *best_sq = best;
                return best_slot;
            }
            top--;
            if (stack[top].distance_sq < best) {
                node_id = stack[top].node;
                break;
            }
        }
    }
}

double lk_surface_index_nearest(const lk_surface_index *index, const double point[3], double max_distance,
                                double closest[3], uint32_t *primitive)
{
    if (!index || !point || !(max_distance >= 0)) return INFINITY;
    /* Inclusive bound: anything at distance <= max_distance is accepted. */
    double bound = max_distance * max_distance;
    bound = isinf(bound) ? INFINITY : nextafter(bound, INFINITY);
    uint32_t slot = nearest_slot(index, point, &bound, LK_NO_SLOT);
    if (slot == LK_NO_SLOT) return INFINITY;
    double q[3];
    double distance_sq = slot_distance_sq(index, slot, point, q);
    if (closest) memcpy(closest, q, sizeof q);
    if (primitive) *primitive = index->primitive[slot];
    return sqrt(distance_sq);
}

/* ------------------------------------------------------------------------ */
/* Sampling                                                                 */
/* ------------------------------------------------------------------------ */

/* Samples are numbered triangle by triangle, so that all samples of one
 * triangle are consecutive (and share the candidate list when measured):
 * triangle t takes [first[t], first[t+1]): its face samples, then the
 * vertices it owns, then the samples of the edges it owns. A triangle owns
 * a vertex or an edge when it is the first triangle to use it. */
typedef struct sampler {
    const float *positions;
    const uint32_t *indices;
    size_t triangle_count;
    uint64_t seed;
    uint64_t *first;               /* triangle_count + 1 */
    uint64_t *face_first;          /* triangle_count + 1: face samples, stratified by area */
    uint64_t *side_first;          /* 3 * triangle_count + 1: edge samples by side (t, corner k -> k+1) */
    unsigned char *owned_vertices; /* per triangle: bit k set when it owns corner k's vertex */
    uint64_t face_count;
    uint64_t total;
    bool point_set; /* no triangles: the vertices are the samples */
} sampler;

static void sampler_free(sampler *s)
{
    free(s->first);
    free(s->face_first);
    free(s->side_first);
    free(s->owned_vertices);
    memset(s, 0, sizeof *s);
}

/* first[i] = round(total * cumulative[i] / sum) for a weight list, where
 * first[0] = 0 and first[count] = total; monotone by construction. */
static void stratify(const double *weights, size_t count, uint64_t total, uint64_t *first)
{
    double sum = 0;
    for (size_t i = 0; i < count; i++) sum += weights[i];
    double running = 0;
    first[0] = 0;
    for (size_t i = 0; i < count; i++) {
        running += weights[i];
        uint64_t value = sum > 0 ? (uint64_t)llround((double)total * (running / sum)) : total;
        if (value > total) value = total;
        if (value < first[i]) value = first[i];
        first[i + 1] = value;
    }
    first[count] = total;
}

#define LK_MAX_FACE_SAMPLES 1e10 /* about an hour of work; refuse more */

/* Marks the sides (3t+k) that own their edge: the first side, in triangle
 * order, joining the same two vertices. Sides are bucketed under their
 * smaller vertex in side order, so the owner is the first in its bucket. */
static bool mark_edge_owners(const lk_mesh *mesh, unsigned char *owner)
{
    size_t vertex_count = mesh->vertex_count, side_count = 3 * mesh->triangle_count;
    size_t *bucket_first = lk__calloc_array(vertex_count + 1, sizeof(size_t));
    uint32_t *bucket = lk__malloc_array(side_count, sizeof(uint32_t));
    uint32_t *last_low = lk__calloc_array(vertex_count, sizeof(uint32_t));
    bool ok = bucket_first && bucket && last_low;
    if (ok) {
        const uint32_t *indices = mesh->indices;
        for (size_t side = 0; side < side_count; side++) {
            uint32_t u = indices[side], v = indices[side - side % 3 + (side % 3 + 1) % 3];
            bucket_first[(u < v ? u : v) + 1]++;
        }
        for (size_t v = 0; v < vertex_count; v++) bucket_first[v + 1] += bucket_first[v];
        for (size_t side = 0; side < side_count; side++) {
            uint32_t u = indices[side], v = indices[side - side % 3 + (side % 3 + 1) % 3];
            bucket[bucket_first[u < v ? u : v]++] = (uint32_t)side;
        }
        /* bucket_first[v] now ends bucket v */
        size_t begin = 0;
        for (size_t low = 0; low < vertex_count; low++) {
            size_t end = bucket_first[low];
            for (size_t i = begin; i < end; i++) {
                size_t side = bucket[i];
                uint32_t u = indices[side], v = indices[side - side % 3 + (side % 3 + 1) % 3];
                uint32_t high = u < v ? v : u;
                owner[side] = high != low && last_low[high] != low + 1;
                last_low[high] = (uint32_t)(low + 1);
            }
            begin = end;
        }
    }
    free(bucket_first);
    free(bucket);
    free(last_low);
    return ok;
}

static lk_status sampler_init(sampler *s, const lk_mesh *mesh, const lk_metro_options *options, const char *what,
                              lk_error *error)
{
    memset(s, 0, sizeof *s);
    s->positions = mesh->positions;
    s->indices = mesh->indices;
    s->triangle_count = mesh->triangle_count;
    s->seed = options->seed;
    size_t triangle_count = mesh->triangle_count, side_count = 3 * triangle_count;
    if (triangle_count == 0) {
        s->point_set = true;
        s->total = mesh->vertex_count;
        return LK_OK;
    }
    double wanted = options->sample_count > 0 ? (double)options->sample_count
                                              : round(options->samples_per_face * (double)triangle_count);
    if (wanted > LK_MAX_FACE_SAMPLES)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: %.0f face samples is more than the limit of %.0f", what, wanted,
                            LK_MAX_FACE_SAMPLES);
    s->face_count = wanted < 1 ? 1 : (uint64_t)wanted;

    double *weights = lk__malloc_array(side_count, sizeof(double)); /* per triangle, then per side */
    unsigned char *edge_owner = lk__calloc_array(side_count, 1);
    s->first = lk__malloc_array(triangle_count + 1, sizeof(uint64_t));
    s->face_first = lk__malloc_array(triangle_count + 1, sizeof(uint64_t));
    s->side_first = lk__malloc_array(side_count + 1, sizeof(uint64_t));
    s->owned_vertices = lk__calloc_array(triangle_count, 1);
    if (!weights || !edge_owner || !s->first || !s->face_first || !s->side_first || !s->owned_vertices) goto nomem;

    /* Face samples: by area; all-degenerate meshes share them equally. */
    const float *positions = mesh->positions;
    const uint32_t *indices = mesh->indices;
    double area = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const float *a = positions + 3 * (size_t)indices[3 * t], *b = positions + 3 * (size_t)indices[3 * t + 1],
                    *c = positions + 3 * (size_t)indices[3 * t + 2];
        double u[3], v[3];
        for (int k = 0; k < 3; k++) {
            u[k] = (double)b[k] - a[k];
            v[k] = (double)c[k] - a[k];
        }
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        weights[t] = 0.5 * sqrt(dot3(n, n));
        area += weights[t];
    }
    if (!(area > 0))
        for (size_t t = 0; t < triangle_count; t++) weights[t] = 1;
    stratify(weights, triangle_count, s->face_count, s->face_first);

    /* Vertex samples: each used vertex once, with its first triangle. */
    if (options->sample_vertices >= 0) {
        unsigned char *seen = lk__calloc_array(mesh->vertex_count, 1);
        if (!seen) goto nomem;
        for (size_t side = 0; side < side_count; side++) {
            uint32_t v = indices[side];
            if (seen[v]) continue;
            seen[v] = 1;
            s->owned_vertices[side / 3] |= (unsigned char)(1u << (side % 3));
        }
        free(seen);
    }

    /* Edge samples: one per triangle on average, over the unique edges by
     * length, each edge's samples with the triangle that owns it. */
    uint64_t edge_samples = 0;
    if (options->sample_edges >= 0) {
        if (!mark_edge_owners(mesh, edge_owner)) goto nomem;
        double length = 0;
        for (size_t side = 0; side < side_count; side++) {
            weights[side] = 0;
            if (!edge_owner[side]) continue;
            const float *a = positions + 3 * (size_t)indices[side],
                        *b = positions + 3 * (size_t)indices[side - side % 3 + (side % 3 + 1) % 3];
            double d[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
            weights[side] = sqrt(dot3(d, d));
            length += weights[side];
        }
        /* Metro's rule: edges get the linear density that matches the face
         * samples' area density (spacing ~ sqrt(area / face samples)), so a
         * maximum that lies along an edge is found as reliably as one
         * inside a face. */
        if (length > 0) {
            double linear_density = area > 0 && s->face_count > 0 ? sqrt((double)s->face_count / area) : 0;
            /* Long edges of almost no area (a vertex pulled out to 1e38)
             * would ask for ~1e21 samples: cap them at a few times the face
             * samples (a well-shaped mesh asks for about 0.7 times as many,
             * so the cap only bites on slivers), and convert to an integer
             * only below the cap (llround of 1e21 is undefined). */
            double cap = 4.0 * ((double)s->face_count + (double)triangle_count);
            double density_samples = linear_density > 0 ? length * linear_density : (double)triangle_count;
            edge_samples = density_samples < cap ? (uint64_t)llround(density_samples) : (uint64_t)cap;
        }
    }
    stratify(weights, side_count, edge_samples, s->side_first);
    if (edge_samples == 0) memset(s->side_first, 0, (side_count + 1) * sizeof(uint64_t));

    s->first[0] = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        unsigned owned = s->owned_vertices[t];
        uint64_t count = (s->face_first[t + 1] - s->face_first[t]) + (owned & 1) + (owned >> 1 & 1) + (owned >> 2 & 1) +
                         (s->side_first[3 * t + 3] - s->side_first[3 * t]);
        s->first[t + 1] = s->first[t] + count;
    }
    s->total = s->first[triangle_count];
    free(weights);
    free(edge_owner);
    return LK_OK;
nomem:
    free(weights);
    free(edge_owner);
    sampler_free(s);
    return lk_error_set(error, LK_ERR_NOMEM, "%s: cannot allocate the sampling tables for %zu triangles", what,
                        triangle_count);
}

/* What to do with samples: `triangle` is called before the samples of each
 * triangle (corners as floats) and with NULLs after the last; `sample` on
 * every sample, with is_face telling whether it counts towards the mean
 * and RMS (face samples, or every sample of a point set). */
typedef struct sample_visitor {
    void (*triangle)(void *user, const float *a, const float *b, const float *c);
    void (*sample)(void *user, const double point[3], bool is_face);
    void *user;
} sample_visitor;

static inline uint64_t stream_key(uint64_t seed, uint64_t stream, uint64_t item)
{
    return lk__mix64(lk__mix64(seed ^ stream) + item);
}

static size_t find_stratum(const uint64_t *first, size_t count, uint64_t sample)
{
    /* last i < count with first[i] <= sample */
    size_t lo = 0, hi = count;
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (first[mid] <= sample)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

#define LK_FACE_STREAM 0x46414345ull /* "FACE" */
#define LK_EDGE_STREAM 0x45444745ull /* "EDGE" */

/* Walks samples [begin, end) in order. A sample's position depends only on
 * its number, the mesh and the seed, never on the range it is taken in. */
static void visit_samples(const sampler *s, uint64_t begin, uint64_t end, const sample_visitor *visitor)
{
    double p[3];
    if (s->point_set) {
        for (uint64_t j = begin; j < end; j++) {
            for (int k = 0; k < 3; k++) p[k] = s->positions[3 * j + k];
            visitor->sample(visitor->user, p, true);
        }
        return;
    }
    size_t t = find_stratum(s->first, s->triangle_count, begin);
    for (uint64_t j = begin; j < end; t++) {
        if (s->first[t + 1] <= j) continue; /* a triangle without samples */
        const uint32_t *tri = s->indices + 3 * t;
        const float *corner[3] = {s->positions + 3 * (size_t)tri[0], s->positions + 3 * (size_t)tri[1],
                                  s->positions + 3 * (size_t)tri[2]};
        const float *a = corner[0];
        double ab[3], ac[3];
        for (int k = 0; k < 3; k++) {
            ab[k] = (double)corner[1][k] - a[k];
            ac[k] = (double)corner[2][k] - a[k];
        }
        if (visitor->triangle) visitor->triangle(visitor->user, corner[0], corner[1], corner[2]);
        uint64_t local = j - s->first[t];
        uint64_t stop = (end < s->first[t + 1] ? end : s->first[t + 1]) - s->first[t];
        uint64_t faces = s->face_first[t + 1] - s->face_first[t];
        if (local < faces) {
            uint64_t key = stream_key(s->seed, LK_FACE_STREAM, t);
            for (; local < stop && local < faces; local++) {
                double r1 = lk__unit_double(lk__mix64(key + 2 * local));
                double r2 = lk__unit_double(lk__mix64(key + 2 * local + 1));
                if (r1 + r2 > 1) { /* fold the parallelogram onto the triangle */
                    r1 = 1 - r1;
                    r2 = 1 - r2;
                }
                for (int k = 0; k < 3; k++) p[k] = a[k] + r1 * ab[k] + r2 * ac[k];
                visitor->sample(visitor->user, p, true);
            }
        }
        uint64_t next = faces; /* number of the next owned vertex */
        for (int corner_k = 0; corner_k < 3; corner_k++) {
            if (!(s->owned_vertices[t] >> corner_k & 1)) continue;
            if (local == next && local < stop) {
                for (int k = 0; k < 3; k++) p[k] = corner[corner_k][k];
                visitor->sample(visitor->user, p, false);
                local++;
            }
            next++;
        }
        const uint64_t *side_first = s->side_first + 3 * t;
        for (int side = 0; local < stop; local++) {
            uint64_t edge_sample = side_first[0] + (local - next);
            while (side_first[side + 1] <= edge_sample) side++;
            uint64_t part = edge_sample - side_first[side], parts = side_first[side + 1] - side_first[side];
            /* one jittered sample in each of `parts` equal pieces of the edge */
            double r = lk__unit_double(lk__mix64(stream_key(s->seed, LK_EDGE_STREAM, 3 * t + (uint64_t)side) + part));
            double along = ((double)part + r) / (double)parts;
            const float *from = corner[side], *to = corner[(side + 1) % 3];
            for (int k = 0; k < 3; k++) p[k] = from[k] + along * ((double)to[k] - from[k]);
            visitor->sample(visitor->user, p, false);
        }
        j = s->first[t] + stop;
    }
    if (visitor->triangle) visitor->triangle(visitor->user, NULL, NULL, NULL);
}

/* ------------------------------------------------------------------------ */
/* Measuring                                                                */
/* ------------------------------------------------------------------------ */

enum { LK_CHUNK_SAMPLES = 4096 }; /* fixed: results must not depend on threads */

typedef struct chunk_stats {
    double max, sum, sum_sq;
} chunk_stats;

/* The samples of one source triangle are measured against a short list of
 * candidate leaves instead of the whole tree. If T0 is the target primitive
 * nearest to the triangle's centroid, the distance from p to T0 is a convex
 * function of p, so it is at most U = max over the corners of their
 * distance to T0 on the whole triangle. The nearest primitive to any point
 * of the triangle is thus within U of the triangle, and its leaf's box is
 * within U of the triangle's box: those leaves are the candidates. When
 * there are too many (a far-away or large triangle), samples walk the tree
 * as usual. */
enum { LK_MAX_CANDIDATES = 48 };
#define LK_NO_CANDIDATES ((size_t)-1)

typedef struct measure_state {
    const lk_surface_index *target;
    uint32_t hint; /* nearest slot of the previous sample */
    chunk_stats stats;
    size_t candidate_count; /* LK_NO_CANDIDATES: walk the tree */
    bvh_node candidates[LK_MAX_CANDIDATES];
} measure_state;

static inline double box_box_distance_sq(const bvh_node *node, const double lo[3], const double hi[3])
{
    double sum = 0;
    for (int k = 0; k < 3; k++) {
        double below = (double)node->lo[k] - hi[k], above = lo[k] - (double)node->hi[k];
        double gap = below > above ? below : above;
        gap = gap > 0 ? gap : 0;
        sum += gap * gap;
    }
    return sum;
}

/* Fills m->candidates with the leaves whose boxes are within sqrt(bound_sq)
 * of the box [lo, hi]; false when there are more than LK_MAX_CANDIDATES. */
static bool gather_candidates(measure_state *m, const double lo[3], const double hi[3], double bound_sq)
{
    const bvh_node *nodes = m->target->nodes;
    uint32_t stack[LK_STACK_SIZE];
    unsigned top = 0;
    m->candidate_count = 0;
    if (box_box_distance_sq(nodes, lo, hi) <= bound_sq) stack[top++] = 0;
    while (top > 0) {
        const bvh_node *node = &nodes[stack[--top]];
        if (node->count) {
            if (m->candidate_count == LK_MAX_CANDIDATES) return false;
            m->candidates[m->candidate_count++] = *node;
            continue;
        }
        uint32_t right = node->offset, left = (uint32_t)(node - nodes) + 1;
        if (box_box_distance_sq(&nodes[right], lo, hi) <= bound_sq) stack[top++] = right;
        if (box_box_distance_sq(&nodes[left], lo, hi) <= bound_sq) stack[top++] = left;
    }
    return true;
}

/* Nearest slot to p among the candidate leaves (or LK_NO_SLOT), starting
 * from the bound *best_sq given by slot `known`. */
static uint32_t nearest_candidate(const measure_state *m, const double p[3], double *best_sq, uint32_t known)
{
    double best = *best_sq;
    uint32_t best_slot = known;
    for (size_t i = 0; i < m->candidate_count; i++) {
        const bvh_node *leaf = &m->candidates[i];
        if (!(box_distance_sq(leaf, p) < best)) continue;
        for (uint32_t slot = leaf->offset; slot < leaf->offset + leaf->count; slot++) {
            if (slot == known) continue;
            double d = slot_distance_sq_below(m->target, slot, p, best);
            if (d < best) {
                best = d;
                best_slot = slot;
            }
        }
    }
    *best_sq = best;
    return best_slot;
}

static void measure_triangle(void *user, const float *a, const float *b, const float *c)
{
    measure_state *m = user;
    m->candidate_count = LK_NO_CANDIDATES;
    if (!a) return;
    const float *corner[3] = {a, b, c};
    double lo[3], hi[3], centroid[3], scratch[3];
    for (int k = 0; k < 3; k++) {
        lo[k] = hi[k] = a[k];
        for (int i = 1; i < 3; i++) {
            lo[k] = corner[i][k] < lo[k] ? corner[i][k] : lo[k];
            hi[k] = corner[i][k] > hi[k] ? corner[i][k] : hi[k];
        }
        centroid[k] = ((double)a[k] + b[k] + c[k]) / 3;
    }
    double best = INFINITY;
    if (m->hint != LK_NO_SLOT) best = slot_distance_sq(m->target, m->hint, centroid, scratch);
    uint32_t nearest = nearest_slot(m->target, centroid, &best, m->hint);
    m->hint = nearest;
    /* A triangle flagged degenerate is measured as its sides; for a sliver
     * (not exactly flat) their union is not convex, so no bound from it. */
    if (!m->target->point_set && m->target->triangles[nearest].inverse_normal_sq == 0) return;
    double bound_sq = 0, magnitude = 0;
    for (int i = 0; i < 3; i++) {
        double corner_p[3] = {corner[i][0], corner[i][1], corner[i][2]};
        double d = slot_distance_sq(m->target, nearest, corner_p, scratch);
        bound_sq = d > bound_sq ? d : bound_sq;
        for (int k = 0; k < 3; k++) magnitude = fabs(corner_p[k]) > magnitude ? fabs(corner_p[k]) : magnitude;
    }
    /* Widen the bound against rounding: relatively for the distances, and
     * absolutely for samples computed a few ulps outside the triangle. */
    double bound = sqrt(bound_sq) * (1 + 1e-9) + 16 * DBL_EPSILON * magnitude;
    if (!gather_candidates(m, lo, hi, bound * bound)) m->candidate_count = LK_NO_CANDIDATES;
}

static void measure_sample(void *user, const double p[3], bool is_face)
{
    measure_state *m = user;
    const lk_surface_index *index = m->target;
    double best = INFINITY, scratch[3];
    if (m->hint != LK_NO_SLOT) best = slot_distance_sq(index, m->hint, p, scratch);
    m->hint = m->candidate_count == LK_NO_CANDIDATES ? nearest_slot(index, p, &best, m->hint)
                                                     : nearest_candidate(m, p, &best, m->hint);
    double distance = sqrt(best);
    if (distance > m->stats.max) m->stats.max = distance;
    if (is_face) {
        m->stats.sum += distance;
        m->stats.sum_sq += best;
    }
}

typedef struct metro_job {
    const sampler *source;
    const lk_surface_index *target;
    size_t first_chunk, chunk_count;
} metro_job;

typedef struct metro_run {
    const metro_job *jobs;
    int job_count;
    size_t chunk_total;
    chunk_stats *chunks;
    atomic_size_t next_chunk;
    atomic_size_t done_chunks;
    atomic_int cancelled;
} metro_run;

static void run_chunk(const metro_run *run, size_t chunk)
{
    const metro_job *job = &run->jobs[0];
    for (int i = 1; i < run->job_count; i++)
        if (chunk >= run->jobs[i].first_chunk) job = &run->jobs[i];
    uint64_t begin = (uint64_t)(chunk - job->first_chunk) * LK_CHUNK_SAMPLES;
    uint64_t end = begin + LK_CHUNK_SAMPLES < job->source->total ? begin + LK_CHUNK_SAMPLES : job->source->total;
    measure_state m;
    m.target = job->target;
    m.hint = LK_NO_SLOT;
    m.stats = (chunk_stats){0, 0, 0};
    m.candidate_count = LK_NO_CANDIDATES;
    sample_visitor visitor = {measure_triangle, measure_sample, &m};
    visit_samples(job->source, begin, end, &visitor);
    run->chunks[chunk] = m.stats;
}

/* Measures the next chunk; false when none is left or the run was cancelled. */
static bool take_chunk(metro_run *run)
{
    if (atomic_load(&run->cancelled)) return false;
    size_t chunk = atomic_fetch_add(&run->next_chunk, 1);
    if (chunk >= run->chunk_total) return false;
    run_chunk(run, chunk);
    atomic_fetch_add(&run->done_chunks, 1);
    return true;
}

static void *metro_worker(void *arg)
{
    metro_run *run = arg;
    while (take_chunk(run)) {
    }
    return NULL;
}

static int thread_count_for(const lk_metro_options *options)
{
    long count = options->thread_count;
    if (count == 0) count = sysconf(_SC_NPROCESSORS_ONLN);
    if (count < 1) count = 1;
    if (count > 256) count = 256;
    return (int)count;
}

/* Measures every job on `threads` threads (the caller's included) and
 * fills stats[i] for job i. Progress is reported from this thread only. */
static lk_status measure_jobs(metro_job *jobs, int job_count, int threads, lk_distance_stats *stats,
                              lk_progress_fn progress, void *progress_user, lk_error *error)
{
    size_t chunk_total = 0;
    for (int i = 0; i < job_count; i++) {
        jobs[i].first_chunk = chunk_total;
        jobs[i].chunk_count = (size_t)((jobs[i].source->total + LK_CHUNK_SAMPLES - 1) / LK_CHUNK_SAMPLES);
        chunk_total += jobs[i].chunk_count;
    }
    metro_run run;
    run.jobs = jobs;
    run.job_count = job_count;
    run.chunk_total = chunk_total;
    run.chunks = lk__malloc_array(chunk_total, sizeof(chunk_stats));
    if (!run.chunks) return lk_error_set(error, LK_ERR_NOMEM, "metro: cannot allocate %zu chunks", chunk_total);
    atomic_init(&run.next_chunk, 0);
    atomic_init(&run.done_chunks, 0);
    atomic_init(&run.cancelled, 0);

    if ((size_t)threads > chunk_total) threads = chunk_total ? (int)chunk_total : 1;
    pthread_t workers[256];
    int started = 0;
    for (int i = 1; i < threads; i++) {
        if (pthread_create(&workers[started], NULL, metro_worker, &run) != 0) break; /* fewer threads, same result */
        started++;
    }
    int last_percent = -1;
    while (take_chunk(&run)) {
        if (!progress) continue;
        size_t done = atomic_load(&run.done_chunks);
        int percent = (int)(100.0 * (double)done / (double)chunk_total);
        if (percent == last_percent) continue;
        last_percent = percent;
        if (progress(progress_user, (double)done / (double)chunk_total, "measuring")) atomic_store(&run.cancelled, 1);
    }
    for (int i = 0; i < started; i++) pthread_join(workers[i], NULL);
    if (atomic_load(&run.cancelled)) {
        free(run.chunks);
        return lk_error_set(error, LK_ERR_INVALID, "metro: cancelled");
    }
    for (int i = 0; i < job_count; i++) {
        double max = 0, sum = 0, sum_sq = 0;
        for (size_t c = jobs[i].first_chunk; c < jobs[i].first_chunk + jobs[i].chunk_count; c++) {
            if (run.chunks[c].max > max) max = run.chunks[c].max;
            sum += run.chunks[c].sum;
            sum_sq += run.chunks[c].sum_sq;
        }
        const sampler *s = jobs[i].source;
        double averaged = (double)(s->point_set ? s->total : s->face_count);
        stats[i].max = max;
        stats[i].mean = averaged > 0 ? sum / averaged : 0;
        stats[i].rms = averaged > 0 ? sqrt(sum_sq / averaged) : 0;
        stats[i].sample_count = (size_t)s->total;
    }
    free(run.chunks);
    if (progress) (void)progress(progress_user, 1.0, "measuring"); /* done: too late to cancel */
    return LK_OK;
}

void lk_metro_options_default(lk_metro_options *options)
{
    if (!options) return;
    memset(options, 0, sizeof *options);
    options->samples_per_face = 10;
    options->sample_count = 0;
    options->sample_vertices = 1;
    options->sample_edges = 1;
    options->seed = 1;
    options->thread_count = 0;
}

static lk_status check_options(const lk_metro_options *options, lk_error *error)
{
    if (options->sample_count == 0 && !(options->samples_per_face > 0 && isfinite(options->samples_per_face)))
        return lk_error_set(error, LK_ERR_INVALID,
                            "metro: samples_per_face must be a positive number (got %g; use lk_metro_options_default)",
                            options->samples_per_face);
    if (options->thread_count < 0)
        return lk_error_set(error, LK_ERR_INVALID, "metro: thread_count must be >= 0 (got %d)", options->thread_count);
    return LK_OK;
}

static lk_status check_mesh(const lk_mesh *mesh, const char *what, lk_error *error)
{
    if (!mesh) return lk_error_set(error, LK_ERR_INVALID, "metro: %s is NULL", what);
    if (mesh->vertex_count == 0) return lk_error_set(error, LK_ERR_INVALID, "metro: %s is empty (no vertices)", what);
    lk_error inner = {0};
    lk_status status = lk_mesh_validate(mesh, &inner);
    if (status != LK_OK) return lk_error_set(error, status, "metro: %s is invalid: %s", what, inner.message);
    return LK_OK;
}

/* Exposed for the unit tests (declared there): the sample points that
 * lk_metro_one_sided measures, 3 doubles each, and whether each one counts
 * towards the mean and RMS. Free both with free(). */
lk_status lk__metro_samples(const lk_mesh *mesh, const lk_metro_options *options, double **points,
                            unsigned char **averaged, size_t *count, lk_error *error);

typedef struct collect_state {
    double *points;
    unsigned char *averaged;
    size_t count;
} collect_state;

static void collect_sample(void *user, const double p[3], bool is_face)
{
    collect_state *c = user;
    memcpy(c->points + 3 * c->count, p, 3 * sizeof(double));
    c->averaged[c->count++] = is_face;
}

lk_status lk__metro_samples(const lk_mesh *mesh, const lk_metro_options *options, double **points,
                            unsigned char **averaged, size_t *count, lk_error *error)
{
    lk_metro_options defaults;
    lk_metro_options_default(&defaults);
    if (!options) options = &defaults;
    *points = NULL;
    *averaged = NULL;
    *count = 0;
    lk_status status = check_mesh(mesh, "source mesh", error);
    if (status == LK_OK) status = check_options(options, error);
    sampler s;
    if (status == LK_OK) status = sampler_init(&s, mesh, options, "source mesh", error);
    if (status != LK_OK) return status;
    collect_state c = {lk__malloc_array((size_t)s.total, 3 * sizeof(double)), lk__malloc_array((size_t)s.total, 1), 0};
    if (!c.points || !c.averaged) {
        free(c.points);
        free(c.averaged);
        sampler_free(&s);
        return lk_error_set(error, LK_ERR_NOMEM, "metro: cannot allocate samples");
    }
    sample_visitor visitor = {NULL, collect_sample, &c};
    visit_samples(&s, 0, s.total, &visitor);
    sampler_free(&s);
    *points = c.points;
    *averaged = c.averaged;
    *count = c.count;
    return LK_OK;
}

lk_status lk_metro_one_sided(const lk_mesh *source, const lk_surface_index *target_index,
                             const lk_metro_options *options, lk_distance_stats *stats, lk_error *error)
{
    lk_metro_options defaults;
    lk_metro_options_default(&defaults);
    if (!options) options = &defaults;
    if (!stats) return lk_error_set(error, LK_ERR_INVALID, "metro: no output statistics");
    memset(stats, 0, sizeof *stats);
    if (!target_index) return lk_error_set(error, LK_ERR_INVALID, "metro: target index is NULL");
    lk_status status = check_mesh(source, "source mesh", error);
    if (status == LK_OK) status = check_options(options, error);
    if (status != LK_OK) return status;
    sampler s;
    status = sampler_init(&s, source, options, "source mesh", error);
    if (status != LK_OK) return status;
    metro_job job = {&s, target_index, 0, 0};
    status = measure_jobs(&job, 1, thread_count_for(options), stats, NULL, NULL, error);
    sampler_free(&s);
    return status;
}

/* Everything one side of lk_metro needs: its index and its samples. */
typedef struct metro_side {
    const lk_mesh *mesh;
    const lk_metro_options *options;
    const char *what;
    lk_surface_index *index;
    sampler samples;
    lk_status status;
    lk_error error;
} metro_side;

static void *prepare_side(void *arg)
{
    metro_side *side = arg;
    lk_error inner = {0};
    side->status = lk_surface_index_build(side->mesh, &side->index, &inner);
    if (side->status != LK_OK) {
        lk_error_set(&side->error, side->status, "metro: %s: %s", side->what, inner.message);
        return NULL;
    }
    side->status = sampler_init(&side->samples, side->mesh, side->options, side->what, &side->error);
    return NULL;
}

lk_status lk_metro(const lk_mesh *a, const lk_mesh *b, const lk_metro_options *options, lk_metro_result *result,
                   lk_progress_fn progress, void *progress_user, lk_error *error)
{
    double start = lk__now();
    lk_metro_options defaults;
    lk_metro_options_default(&defaults);
    if (!options) options = &defaults;
    if (!result) return lk_error_set(error, LK_ERR_INVALID, "metro: no output result");
    memset(result, 0, sizeof *result);
    lk_status status = check_mesh(a, "mesh A", error);
    if (status == LK_OK) status = check_mesh(b, "mesh B", error);
    if (status == LK_OK) status = check_options(options, error);
    if (status != LK_OK) return status;
    if (progress && progress(progress_user, 0.0, "indexing"))
        return lk_error_set(error, LK_ERR_INVALID, "metro: cancelled");

    int threads = thread_count_for(options);
    metro_side sides[2] = {{a, options, "mesh A", NULL, {0}, LK_OK, {0}},
                           {b, options, "mesh B", NULL, {0}, LK_OK, {0}}};
    /* Build B's side on a second thread while this one builds A's. */
    pthread_t helper;
    bool helped = threads > 1 && pthread_create(&helper, NULL, prepare_side, &sides[1]) == 0;
    prepare_side(&sides[0]);
    if (helped)
        pthread_join(helper, NULL);
    else
        prepare_side(&sides[1]);
    for (int i = 0; i < 2 && status == LK_OK; i++) {
        if (sides[i].status != LK_OK) {
            status = sides[i].status;
            if (error) *error = sides[i].error;
        }
    }
    if (status == LK_OK) {
        metro_job jobs[2] = {{&sides[0].samples, sides[1].index, 0, 0}, {&sides[1].samples, sides[0].index, 0, 0}};
        lk_distance_stats stats[2];
        status = measure_jobs(jobs, 2, threads, stats, progress, progress_user, error);
        if (status == LK_OK) {
            result->diagonal = lk_mesh_bounds(a, NULL, NULL);
            result->forward = stats[0];
            result->backward = stats[1];
            result->hausdorff = stats[0].max > stats[1].max ? stats[0].max : stats[1].max;
            result->sample_count = stats[0].sample_count + stats[1].sample_count;
        }
    }
    for (int i = 0; i < 2; i++) {
        lk_surface_index_free(sides[i].index);
        sampler_free(&sides[i].samples);
    }
    result->seconds = lk__now() - start;
    return status;
}
