/* SPDX-License-Identifier: MIT */
/* Subdivision: midpoint (1-to-4) splitting and Loop's smooth scheme.
 *
 * Each iteration splits every triangle into four. The new ("odd") vertex of
 * edge e gets index vertex_count + e, with edges numbered by
 * lk_edge_adjacency_build; old ("even") vertices keep their indices. A
 * triangle (v0, v1, v2) with edge midpoints m0 (v0-v1), m1 (v1-v2) and
 * m2 (v2-v0) becomes (v0, m0, m2), (v1, m1, m0), (v2, m2, m1) and
 * (m0, m1, m2): all four keep the parent's winding.
 *
 * Loop (C. Loop, "Smooth subdivision surfaces based on triangles", 1987):
 *   - odd vertex of an edge with two triangles: 3/8 of each endpoint plus
 *     1/8 of each opposite vertex; of a border or non-manifold edge (one, or
 *     three and more triangles): the midpoint;
 *   - even vertex with only two-triangle edges (interior) and valence n:
 *     (1 - n beta) v + beta * (sum of neighbours), with Loop's original
 *     beta = (5/8 - (3/8 + cos(2 pi / n) / 4)^2) / n (Warren's simpler
 *     3/(8n) is not used: Loop's weights give the standard limit surface);
 *   - even vertex with exactly two border edges (a crease): 3/4 v plus 1/8
 *     of each border neighbour, so the border follows a cubic B-spline of
 *     the input border polyline and does not depend on the triangles inside
 *     (seams split for texture coordinates stay closed);
 *   - corner vertices keep their position: vertices on a non-manifold edge,
 *     vertices with a number of border edges other than 0 or 2 (bowties on
 *     the border), and border vertices where the border turns sharply (the
 *     angle between its two border edges is below 130 degrees, so that the
 *     corners of a square grid stay put and its border stays on the square).
 * Every Loop weight is non-negative, so new positions are convex
 * combinations of old ones and stay within the input's bounding box.
 *
 * Attributes (normals, texture coordinates, colours) are interpolated
 * linearly under both schemes: odd vertices get the average of the edge's
 * endpoints (normals renormalised), even vertices keep theirs. Loop moves
 * positions but not attributes, so callers who need accurate normals of the
 * smoothed surface should recompute them.
 *
 * Degenerate triangles (a repeated vertex index) are refused with
 * LK_ERR_INVALID naming the triangle (lk_mesh_remove_degenerate drops
 * them). Duplicate triangles are subdivided like any other.
 *
 * `out` is overwritten without being freed (as lk_mesh_copy does) and is
 * left untouched on failure. Sizes are checked before the output is
 * allocated: T * 4^iterations first, then the vertex count predicted from
 * the input's edges (exact without duplicate triangles, an upper bound with
 * them).
 *
 * Cost per iteration: O(T) time plus the edge adjacency build (O(T) for
 * bounded valence); memory: the output, the adjacency (9T words) and about 40V
 * bytes of accumulators for Loop. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Border vertices whose two border edges meet at a smaller angle than this
 * are corners and keep their position (cos 130 degrees). */
#define CORNER_COSINE (-0.64278760968653925)

/* Loop's original weight of each neighbour of an interior vertex of
 * valence n. */
static double loop_beta(uint32_t valence)
{
    double n = (double)valence;
    double c = 0.375 + 0.25 * cos(2.0 * 3.14159265358979323846 / n);
    return (0.625 - c * c) / n;
}

static uint32_t edge_triangle_count(const lk_edge_adjacency *edges, size_t e)
{
    return edges->offsets[e + 1] - edges->offsets[e];
}

/* Loop's rules for the even (old) vertices, written to positions[0 .. V). */
static lk_status loop_even_positions(const lk_mesh *src, const lk_edge_adjacency *edges, float *positions,
                                     lk_error *error)
{
    size_t vertex_count = src->vertex_count;
    const float *old = src->positions;
    /* Per vertex: valence, border edge count (saturating), a non-manifold
     * flag, the first two border neighbours and the sum of all neighbours. */
    uint32_t *valence = lk__calloc_array(vertex_count, sizeof(uint32_t));
    uint8_t *border_count = lk__calloc_array(vertex_count, 1);
    uint8_t *nonmanifold = lk__calloc_array(vertex_count, 1);
    uint32_t *border_neighbor = lk__malloc_array(vertex_count, 2 * sizeof(uint32_t));
    double *sum = lk__calloc_array(vertex_count, 3 * sizeof(double));
    if (!valence || !border_count || !nonmanifold || !border_neighbor || !sum) {
        free(valence), free(border_count), free(nonmanifold), free(border_neighbor), free(sum);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate Loop tables for %zu vertices", vertex_count);
    }
    for (size_t e = 0; e < edges->edge_count; e++) {
        uint32_t a = edges->vertices[2 * e], b = edges->vertices[2 * e + 1];
        uint32_t faces = edge_triangle_count(edges, e);
        valence[a]++, valence[b]++;
        const float *pa = old + 3 * (size_t)a, *pb = old + 3 * (size_t)b;
        for (int k = 0; k < 3; k++) {
            sum[3 * (size_t)a + k] += pb[k];
            sum[3 * (size_t)b + k] += pa[k];
        }
        if (faces >= 3) {
            nonmanifold[a] = nonmanifold[b] = 1;
        } else if (faces == 1) {
            if (border_count[a] < 2) border_neighbor[2 * (size_t)a + border_count[a]] = b;
            if (border_count[b] < 2) border_neighbor[2 * (size_t)b + border_count[b]] = a;
            if (border_count[a] < 255) border_count[a]++;
            if (border_count[b] < 255) border_count[b]++;
        }
    }
    for (size_t v = 0; v < vertex_count; v++) {
        const float *p = old + 3 * v;
        float *q = positions + 3 * v;
        memcpy(q, p, 3 * sizeof(float)); /* corners and unused vertices */
        if (nonmanifold[v] || valence[v] == 0) continue;
        if (border_count[v] == 0) {
            double beta = loop_beta(valence[v]), self = 1.0 - valence[v] * beta;
            for (int k = 0; k < 3; k++) q[k] = (float)(self * p[k] + beta * sum[3 * v + k]);
        } else if (border_count[v] == 2) {
            const float *a = old + 3 * (size_t)border_neighbor[2 * v],
                        *b = old + 3 * (size_t)border_neighbor[2 * v + 1];
            double to_a[3], to_b[3], dot = 0, length_a = 0, length_b = 0;
            for (int k = 0; k < 3; k++) {
                to_a[k] = (double)a[k] - p[k], to_b[k] = (double)b[k] - p[k];
                dot += to_a[k] * to_b[k], length_a += to_a[k] * to_a[k], length_b += to_b[k] * to_b[k];
            }
            /* A border that doubles back (angle below 130 degrees) is a corner. */
            if (dot > CORNER_COSINE * sqrt(length_a * length_b)) continue;
            for (int k = 0; k < 3; k++) q[k] = (float)(0.75 * p[k] + 0.125 * ((double)a[k] + b[k]));
        }
    }
    free(valence), free(border_count), free(nonmanifold), free(border_neighbor), free(sum);
    return LK_OK;
}

/* Odd vertex positions: midpoints, or Loop's edge rule on two-triangle edges. */
static void odd_positions(const lk_mesh *src, const lk_edge_adjacency *edges, lk_subdivide_scheme scheme,
                          float *positions)
{
    const float *old = src->positions;
    const uint32_t *indices = src->indices;
    for (size_t e = 0; e < edges->edge_count; e++) {
        uint32_t a = edges->vertices[2 * e], b = edges->vertices[2 * e + 1];
        const float *pa = old + 3 * (size_t)a, *pb = old + 3 * (size_t)b;
        float *q = positions + 3 * e;
        if (scheme == LK_SUBDIVIDE_LOOP && edge_triangle_count(edges, e) == 2) {
            /* The opposite corner of a non-degenerate triangle is the one
             * that is neither a nor b: the sum of its indices minus a + b. */
            uint32_t t1 = edges->triangles[edges->offsets[e]], t2 = edges->triangles[edges->offsets[e] + 1];
            uint64_t ends = (uint64_t)a + b;
            uint32_t c = (uint32_t)((uint64_t)indices[3 * (size_t)t1] + indices[3 * (size_t)t1 + 1] +
                                    indices[3 * (size_t)t1 + 2] - ends);
            uint32_t d = (uint32_t)((uint64_t)indices[3 * (size_t)t2] + indices[3 * (size_t)t2 + 1] +
                                    indices[3 * (size_t)t2 + 2] - ends);
            const float *pc = old + 3 * (size_t)c, *pd = old + 3 * (size_t)d;
            for (int k = 0; k < 3; k++)
                q[k] = (float)(0.375 * ((double)pa[k] + pb[k]) + 0.125 * ((double)pc[k] + pd[k]));
        } else {
            for (int k = 0; k < 3; k++) q[k] = (float)(0.5 * ((double)pa[k] + pb[k]));
        }
    }
}

/* Attributes: even vertices keep theirs, odd ones get the edge average. */
static void interpolate_attribute(const float *old, size_t vertex_count, const lk_edge_adjacency *edges, size_t width,
                                  int renormalise, float *values)
{
    if (!old) return;
    memcpy(values, old, vertex_count * width * sizeof(float));
    float *odd = values + vertex_count * width;
    for (size_t e = 0; e < edges->edge_count; e++) {
        const float *a = old + width * edges->vertices[2 * e], *b = old + width * edges->vertices[2 * e + 1];
        float *q = odd + width * e;
        double average[4], length = 0;
        for (size_t k = 0; k < width; k++) {
            average[k] = 0.5 * ((double)a[k] + b[k]);
            length += average[k] * average[k];
        }
        /* Opposite normals average to zero: keep the first endpoint's then. */
        if (renormalise && !(length > 1e-30)) {
            memcpy(q, a, width * sizeof(float));
            continue;
        }
        double scale = renormalise ? 1.0 / sqrt(length) : 1.0;
        for (size_t k = 0; k < width; k++) q[k] = (float)(average[k] * scale);
    }
}

/* One iteration of `src` (with its edge adjacency) into a new mesh `dst`. */
static lk_status subdivide_once(const lk_mesh *src, const lk_edge_adjacency *edges, lk_subdivide_scheme scheme,
                                lk_mesh *dst, lk_error *error)
{
    size_t vertex_count = src->vertex_count, triangle_count = src->triangle_count;
    unsigned flags = (src->normals ? LK_ATTR_NORMALS : 0) | (src->texcoords ? LK_ATTR_TEXCOORDS : 0) |
                     (src->colors ? LK_ATTR_COLORS : 0);
    lk_status status = lk_mesh_alloc(dst, vertex_count + edges->edge_count, 4 * triangle_count, flags, error);
    if (status != LK_OK) return status;
    const uint32_t *indices = src->indices;
    uint32_t *out = dst->indices;
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *v = indices + 3 * t;
        const uint32_t *e = edges->triangle_edges + 3 * t;
        uint32_t m0 = (uint32_t)(vertex_count + e[0]), m1 = (uint32_t)(vertex_count + e[1]),
                 m2 = (uint32_t)(vertex_count + e[2]);
        uint32_t *children = out + 12 * t;
        children[0] = v[0], children[1] = m0, children[2] = m2;
        children[3] = v[1], children[4] = m1, children[5] = m0;
        children[6] = v[2], children[7] = m2, children[8] = m1;
        children[9] = m0, children[10] = m1, children[11] = m2;
    }
    if (scheme == LK_SUBDIVIDE_LOOP) {
        status = loop_even_positions(src, edges, dst->positions, error);
        if (status != LK_OK) {
            lk_mesh_free(dst);
            return status;
        }
    } else if (vertex_count) {
        memcpy(dst->positions, src->positions, vertex_count * 3 * sizeof(float));
    }
    odd_positions(src, edges, scheme, dst->positions + 3 * vertex_count);
    interpolate_attribute(src->normals, vertex_count, edges, 3, 1, dst->normals);
    interpolate_attribute(src->texcoords, vertex_count, edges, 2, 0, dst->texcoords);
    interpolate_attribute(src->colors, vertex_count, edges, 4, 0, dst->colors);
    return LK_OK;
}

lk_status lk_subdivide(const lk_mesh *mesh, lk_subdivide_scheme scheme, unsigned iterations, lk_mesh *out,
                       lk_error *error)
{
    if (!mesh || !out) return lk_error_set(error, LK_ERR_INVALID, "mesh and output must not be NULL");
    if (scheme != LK_SUBDIVIDE_LOOP && scheme != LK_SUBDIVIDE_MIDPOINT)
        return lk_error_set(error, LK_ERR_INVALID, "unknown subdivision scheme %d", (int)scheme);
    lk_status status = lk_mesh_validate(mesh, error);
    if (status != LK_OK) return status;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *v = mesh->indices + 3 * t;
        if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0])
            return lk_error_set(error, LK_ERR_INVALID,
                                "triangle %zu is degenerate (vertices %u %u %u): remove it first "
                                "(lk_mesh_remove_degenerate)",
                                t, v[0], v[1], v[2]);
    }
    /* Refuse before allocating anything if the triangles would not fit. */
    uint64_t final_triangles = mesh->triangle_count;
    for (unsigned i = 0; i < iterations && final_triangles; i++) {
        if (final_triangles > LK_MAX_ELEMENTS / 4)
            return lk_error_set(error, LK_ERR_LIMIT, "%u iterations of %zu triangles would exceed %zu triangles",
                                iterations, mesh->triangle_count, LK_MAX_ELEMENTS);
        final_triangles *= 4;
    }
    if (iterations == 0 || mesh->triangle_count == 0) return lk_mesh_copy(out, mesh, error);

    lk_edge_adjacency edges;
    status = lk_edge_adjacency_build(mesh, &edges, error);
    if (status != LK_OK) return status;
    /* Each iteration adds one vertex per edge; an edge becomes two and each
     * triangle adds three (exact without duplicate triangles, an upper bound
     * with them), so the final vertex count is known before allocating. */
    uint64_t vertices = mesh->vertex_count, edge_count = edges.edge_count, triangles = mesh->triangle_count;
    for (unsigned i = 0; i < iterations; i++) {
        vertices += edge_count;
        if (vertices > LK_MAX_ELEMENTS) {
            lk_edge_adjacency_free(&edges);
            return lk_error_set(error, LK_ERR_LIMIT, "%u iterations of %zu vertices would exceed %zu vertices",
                                iterations, mesh->vertex_count, LK_MAX_ELEMENTS);
        }
        edge_count = 2 * edge_count + 3 * triangles;
        triangles *= 4;
    }

    const lk_mesh *current = mesh;
    lk_mesh level;
    lk_mesh_init(&level);
    for (unsigned i = 0; i < iterations; i++) {
        lk_mesh next;
        status = subdivide_once(current, &edges, scheme, &next, error);
        lk_edge_adjacency_free(&edges);
        lk_mesh_free(&level); /* the previous level (empty on the first pass) */
        if (status != LK_OK) return status;
        level = next;
        current = &level;
        if (i + 1 < iterations) {
            status = lk_edge_adjacency_build(&level, &edges, error);
            if (status != LK_OK) {
                lk_mesh_free(&level);
                return status;
            }
        }
    }
    *out = level;
    return LK_OK;
}
