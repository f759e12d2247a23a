/* SPDX-License-Identifier: MIT */
/* Vertex clustering's weights (src/cluster.c's file comment says which and
 * why): the mean-direction weight of uniform cells and Low & Tan's
 * largest-angle weight of floating cells, each from one pass over the
 * triangles. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Added to the angle term: flat vertices stay ordered by their longest
 * edge (see src/cluster.c). */
#define IMPORTANCE_FLOOR 0.05
/* Above this many incident edge directions, the largest angle is sought
 * against this many evenly spaced directions only (keeps O(degree)). */
#define ANGLE_PAIRS_LIMIT 64
/* Triangles ahead whose corners' positions and sums the importance pass
 * prefetches. */
#define PREFETCH_DISTANCE 32
/* Vertices ahead whose edge ends' positions the largest-angle pass
 * prefetches. */
#define ENDS_AHEAD 4

static bool degenerate(const uint32_t *corners)
{
    return corners[0] == corners[1] || corners[1] == corners[2] || corners[0] == corners[2];
}

/* Uniform cells: the mean-direction weight (see src/cluster.c). One
 * pass over the triangles (degenerate ones ignored) gives used[],
 * importance[], the non-degenerate triangle count and the surface area.
 * Edges are measured in units of `scale` (the bounding-box diagonal), so
 * single precision neither overflows nor underflows; the weights only
 * compare with each other. */
lk_status lk__cluster_mean_direction_weights(lk__cluster_weights *w, double scale, lk_error *error)
{
    (void)error; /* the caller's memory: nothing to fail (the signature is the floating pass's) */
    const lk_mesh *mesh = w->mesh;
    size_t vertex_count = mesh->vertex_count, triangle_count = mesh->triangle_count;
    /* Per vertex: the sum of the unit vectors along its incident edges and
     * its longest incident edge (16 bytes: one cache line holds four), in
     * the caller's block, and the number of incident edges of non-zero
     * length, once per triangle (a vertex in fewer than 2^31 triangles
     * cannot overflow it). */
    float(*stars)[4] = w->vertex_block;
    uint32_t *counts = w->directions;
    /* A longest edge of -1: the vertex is in no non-degenerate triangle
     * (any such triangle raises it to a length >= 0). */
    for (size_t v = 0; v < vertex_count; v++) {
        stars[v][0] = stars[v][1] = stars[v][2] = 0;
        stars[v][3] = -1;
    }
    memset(counts, 0, vertex_count * sizeof *counts);
    const uint32_t *indices = mesh->indices;
    const float *positions = mesh->positions;
    double inverse_scale = scale > 0 && isfinite(scale) ? 1 / scale : 1;
    /* A difference of two floats overflows only near FLT_MAX, where the
     * diagonal is as large: then the differences are taken in double. */
    bool single_precision = scale < 1e37 && isfinite((float)inverse_scale) && (float)inverse_scale > 0;
    float inverse_scale_float = (float)inverse_scale;
    size_t solid_count = 0;
    double area = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *corners = indices + 3 * t;
#ifdef __GNUC__
        /* The corners are scattered over the vertex arrays: ask early for
         * those of a triangle ahead. */
        if (t + PREFETCH_DISTANCE < triangle_count)
            for (int k = 0; k < 3; k++) {
                uint32_t ahead = corners[3 * PREFETCH_DISTANCE + k];
                __builtin_prefetch(positions + 3 * (size_t)ahead);
                __builtin_prefetch(stars + ahead, 1);
                __builtin_prefetch(counts + ahead, 1);
            }
#endif
        if (degenerate(corners)) continue;
        solid_count++;
        float edge[3][3], length[3]; /* edge k: corner k to k + 1 */
        for (int k = 0; k < 3; k++) {
            const float *from = positions + 3 * (size_t)corners[k], *to = positions + 3 * (size_t)corners[(k + 1) % 3];
            for (int a = 0; a < 3; a++)
                edge[k][a] = single_precision ? (to[a] - from[a]) * inverse_scale_float
                                              : (float)(((double)to[a] - from[a]) * inverse_scale);
            length[k] = sqrtf(edge[k][0] * edge[k][0] + edge[k][1] * edge[k][1] + edge[k][2] * edge[k][2]);
        }
        /* The area only seeds the cell-size search: every 8th triangle's. */
        if (solid_count % 8 == 1) {
            double x = (double)edge[0][1] * edge[2][2] - (double)edge[0][2] * edge[2][1];
            double y = (double)edge[0][2] * edge[2][0] - (double)edge[0][0] * edge[2][2];
            double z = (double)edge[0][0] * edge[2][1] - (double)edge[0][1] * edge[2][0];
            area += 4.0 * sqrt(x * x + y * y + z * z); /* half the cross product, times 8 */
        }
        for (int k = 0; k < 3; k++) {
            float inverse = length[k] > 0 ? 1 / length[k] : 0;
            for (int a = 0; a < 3; a++) edge[k][a] *= inverse; /* now unit vectors */
        }
        /* Corner k: edge k leaves it, edge k - 1 arrives (reversed). */
        for (int k = 0; k < 3; k++) {
            int previous = (k + 2) % 3;
            float *star = stars[corners[k]];
            for (int a = 0; a < 3; a++) star[a] += edge[k][a] - edge[previous][a];
            float longest = length[k] > length[previous] ? length[k] : length[previous];
            star[3] = !(longest <= star[3]) ? longest : star[3]; /* a select, not a branch; NaN marks it used */
            counts[corners[k]] += (uint32_t)(length[k] > 0) + (uint32_t)(length[previous] > 0);
        }
    }
    w->solid_count = solid_count;
    w->area = area * (1 / (inverse_scale * inverse_scale));
    /* The importances overwrite the block's second half: importance[v]'s
     * 8 bytes lie in star (vertex_count + v) / 2, never below v, so a
     * descending pass reads every star before its bytes are reused. */
    double *importance = (double *)w->vertex_block + vertex_count;
    w->used_count = 0;
    for (size_t v = vertex_count; v-- > 0;) {
        const float *star = stars[v];
        float sum[3] = {star[0], star[1], star[2]}, longest = star[3];
        uint32_t directions = counts[v];
        w->used[v] = !(longest < 0);
        if (!w->used[v]) {
            importance[v] = 0;
            continue;
        }
        w->used_count++;
        float mean_length = 0; /* of the mean edge direction: cos(theta / 2), see src/cluster.c */
        if (directions) {
            mean_length = sqrtf(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]) / (float)directions;
            if (mean_length > 1) mean_length = 1;
        }
        importance[v] = (double)longest * (mean_length + IMPORTANCE_FLOOR) * scale;
    }
    return LK_OK;
}

/* Largest angle's weight at one vertex from its incident edges' far ends
 * (two per incident triangle, in triangle order): see src/cluster.c.
 * *edge_sum and *edge_count accumulate the lengths of its distinct edges. */
static double vertex_importance(const float *positions, uint32_t v, const uint32_t *ends, size_t end_count,
                                double *directions, double *edge_sum, size_t *edge_count)
{
    const float *p = positions + 3 * (size_t)v;
    double longest = 0;
    size_t direction_count = 0;
    /* Up to ANGLE_PAIRS_LIMIT directions every pair is tried, so repeated
     * ends (each interior edge appears twice) are dropped first: same
     * largest angle, half the work. */
    bool all_pairs = end_count <= ANGLE_PAIRS_LIMIT;
    for (size_t i = 0; i < end_count; i++) {
        uint32_t u = ends[i];
        bool repeated = false;
        if (all_pairs) /* no early exit: a loop without branches to mispredict */
            for (size_t j = 0; j < i; j++) repeated |= ends[j] == u;
        if (repeated) continue;
        const float *q = positions + 3 * (size_t)u;
        double d[3] = {(double)q[0] - p[0], (double)q[1] - p[1], (double)q[2] - p[2]};
        double length = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        longest = length > longest ? length : longest; /* selects, not branches (the data decide them) */
        if (length <= 0) continue;
        *edge_sum += length;
        ++*edge_count;
        double *unit = directions + 3 * direction_count++;
        for (int a = 0; a < 3; a++) unit[a] = d[a] / length;
    }
    double min_dot = 1;
    size_t stride = direction_count > ANGLE_PAIRS_LIMIT ? direction_count / ANGLE_PAIRS_LIMIT : 1;
    for (size_t i = 0; i < direction_count; i++) {
        const double *a = directions + 3 * i;
        for (size_t j = stride > 1 ? 0 : i + 1; j < direction_count; j += stride) {
            const double *b = directions + 3 * j;
            double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            min_dot = dot < min_dot ? dot : min_dot;
        }
    }
    if (min_dot < -1) min_dot = -1;
    double half_angle_cosine = sqrt((1 + min_dot) / 2); /* cos(theta / 2) */
    return longest * (half_angle_cosine + IMPORTANCE_FLOOR);
}

/* Floating cells: Low & Tan's weight (see src/cluster.c). One pass over
 * the triangles lists, for every vertex, the far ends of its incident
 * edges; from them come used[], importance[], the non-degenerate triangle
 * count and an area estimate (from the mean edge length). Degenerate
 * triangles are ignored. */
lk_status lk__cluster_largest_angle_weights(lk__cluster_weights *w, lk_error *error)
{
    const lk_mesh *mesh = w->mesh;
    size_t vertex_count = mesh->vertex_count, triangle_count = mesh->triangle_count;
    if (triangle_count > UINT32_MAX / 6)
        return lk_error_set(error, LK_ERR_INVALID, "too many triangles for floating cells (%zu)", triangle_count);
    uint32_t *offsets = lk__alloc_random_access(vertex_count + 1, sizeof(uint32_t), true);
    if (!offsets) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering weights");
    const uint32_t *indices = mesh->indices;
    size_t solid_count = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *corners = indices + 3 * t;
        if (degenerate(corners)) continue;
        solid_count++;
        for (int k = 0; k < 3; k++) offsets[corners[k] + 1] += 2;
    }
    size_t max_ends = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        if (offsets[v + 1] > max_ends) max_ends = offsets[v + 1];
        offsets[v + 1] += offsets[v];
    }
    uint32_t *ends = lk__alloc_random_access(6 * solid_count + 1, sizeof(uint32_t), false);
    double *directions = lk__malloc_array(max_ends + 1, 3 * sizeof(double));
    if (!ends || !directions) {
        free(offsets);
        free(ends);
        free(directions);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering weights");
    }
    /* Fill with offsets[v] as a cursor, then shift back: triangle order kept. */
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *corners = indices + 3 * t;
        if (degenerate(corners)) continue;
        uint32_t a = corners[0], b = corners[1], d = corners[2];
        uint32_t *slot = ends + offsets[a];
        slot[0] = b, slot[1] = d;
        offsets[a] += 2;
        slot = ends + offsets[b];
        slot[0] = a, slot[1] = d;
        offsets[b] += 2;
        slot = ends + offsets[d];
        slot[0] = a, slot[1] = b;
        offsets[d] += 2;
    }
    for (size_t v = vertex_count; v > 0; v--) offsets[v] = offsets[v - 1];
    offsets[0] = 0;

    const float *positions = mesh->positions;
    double edge_sum = 0;
    size_t edge_count = 0;
    double *importance = (double *)w->vertex_block + vertex_count;
    w->used_count = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        uint32_t begin = offsets[v], end = offsets[v + 1];
#ifdef __GNUC__
        /* The far ends are scattered over the positions: ask early for
         * those of a vertex ahead (its every other end: each edge of a
         * closed surface is listed twice). */
        if (v + ENDS_AHEAD < vertex_count)
            for (uint32_t i = offsets[v + ENDS_AHEAD]; i < offsets[v + ENDS_AHEAD + 1]; i += 2)
                __builtin_prefetch(positions + 3 * (size_t)ends[i]);
#endif
        w->used[v] = begin < end;
        importance[v] = 0;
        if (begin == end) continue;
        w->used_count++;
        importance[v] =
            vertex_importance(positions, (uint32_t)v, ends + begin, end - begin, directions, &edge_sum, &edge_count);
    }
    w->solid_count = solid_count;
    /* Edges seen from both ends; an equilateral triangle of side e has area
     * e^2 sqrt(3) / 4. */
    double mean_edge = edge_count ? edge_sum / (double)edge_count : 0;
    w->area = (double)solid_count * mean_edge * mean_edge * 0.4330127018922193;
    free(offsets);
    free(ends);
    free(directions);
    return LK_OK;
}
