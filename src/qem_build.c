/* SPDX-License-Identifier: MIT */
/* Set-up of the QEM state (qem_state.h; the method is explained at the top of
 * qem.c): the working arrays, the internal (Morton) order, normalised
 * positions and triangle lists, the face and attribute quadrics, border,
 * non-manifold and crease constraints and corner points (for one frame, or
 * for each of several frames), and the non-edge pairs. Everything here runs
 * once, before the first contraction. */
#include "qem_state.h"

#include <stdlib.h>

/* Constraint weights, times feature_weight. A border (or non-manifold) plane
 * weighs BORDER_SCALE * |edge|^2, a crease plane CREASE_SCALE * |edge|^2 *
 * min(1, (1 - cos angle)^2) and a corner's point quadric CORNER_WEIGHT times
 * the vertex's area: a face quadric weighs its area (about |edge|^2 / 2),
 * so at 1 a border plane weighs about as much as the faces on its edge, a
 * right-angle crease (fandisk's) 4 times that, and a crease that folds the
 * surface by 60 degrees as much as its faces, one of 40 degrees a fifth.
 * Heavier constraints cost the maximum error (issue 22): the cost of every
 * contraction near a crease is then mostly the constraints', so crease-rich
 * ground keeps the vertices and the smooth ground between runs out of them.
 * With 4, 4 and 40 (before), 91% of the Chinese dragon's 103 vertices left
 * at 1% were crease vertices of its scales (30% of its input vertices; 66%
 * of meshopt_simplify's) and its Hausdorff distance was 1.36x meshopt's; over
 * the five sample models at 16 ratios from 0.8% to 50%, these weights gain
 * 5% in Hausdorff distance and 12% in RMS (geometric means) and keep
 * fandisk's creases sharper than its smooth parts. The mild folds of a
 * scan are held by their own face planes; a crease constraint is only
 * needed where the fold is sharp. Several frames keep the weights of
 * before (LEGACY_*): with the static ones, faerie.md2's max scheme stops at
 * 68 triangles at 10% with a worst frame of 5.0% instead of 4.6% (its
 * figures and tests were measured with them); one frame is the static case. */
#define BORDER_SCALE 1.0
#define CREASE_SCALE 4.0
#define CORNER_WEIGHT 2.5
#define LEGACY_SCALE 4.0
#define LEGACY_CORNER_WEIGHT 40.0
/* With LK_SIMPLIFY_ATTRIBUTES, attribute values are multiplied by
 * attribute_weight * ATTRIBUTE_UNIT before entering the quadrics, in which
 * positions are scaled to a unit diagonal: at weight 1 a unit of attribute
 * difference (a normal turned by a radian, a full colour step) weighs like
 * a distance of 0.3% of the diagonal. Normals vary fast on curved surfaces,
 * and a heavier unit pulls vertices off the surface. Measured on the bunny
 * at 2% with normals and a smooth colour: interpolated colours err by
 * 0.0136, solved ones by 0.0060 / 0.0058 / 0.0060 at units 0.001 / 0.003 /
 * 0.01, while the Hausdorff distance grows from 0.61% to 0.62% / 0.69% /
 * 0.93%. */
#define ATTRIBUTE_UNIT 0.003
/* Non-edge pairs kept per vertex (the nearest ones). */
#define CLOSE_PAIRS_PER_VERTEX 8

/* Largest number of attribute channels (normals 3 + texcoords 2 + colours 4). */
#define MAX_ATTRIBUTES 9

/* Adds weight * (n.v + d)^2. */
static void quadric_add_plane(quadric *q, const double n[3], double d, double weight)
{
    double *m = q->m;
    m[0] += weight * n[0] * n[0];
    m[1] += weight * n[0] * n[1];
    m[2] += weight * n[0] * n[2];
    m[3] += weight * n[1] * n[1];
    m[4] += weight * n[1] * n[2];
    m[5] += weight * n[2] * n[2];
    m[6] += weight * d * n[0];
    m[7] += weight * d * n[1];
    m[8] += weight * d * n[2];
    m[9] += weight * d * d;
}

/* Adds weight * |v - point|^2. */
static void quadric_add_point(quadric *q, const double point[3], double weight)
{
    double *m = q->m;
    m[0] += weight, m[3] += weight, m[5] += weight;
    m[6] -= weight * point[0];
    m[7] -= weight * point[1];
    m[8] -= weight * point[2];
    m[9] += weight * dot3(point, point);
}

lk_status lk__qem_allocate(qem *s, lk_error *error)
{
    size_t v = s->vertex_count, t = s->triangle_count;
    /* The arrays a contraction reads at random get huge pages (where the
     * system gives them on request). */
    s->indices = lk__alloc_random_access(3 * t, sizeof(uint32_t), false);
    s->vertex_input = lk__malloc_array(v, sizeof(uint32_t));
    s->triangle_input = lk__malloc_array(t, sizeof(uint32_t));
    s->triangle_alive = lk__malloc_array(t, 1);
    /* records aligned to cache lines: one record, two lines */
    if (v < SIZE_MAX / sizeof(vertex) - 1) s->vertices = lk__alloc_random_access(v + 1, sizeof(vertex), true);
    s->flags = lk__calloc_array(v, 1);
    /* 3T entries fill the pool at first, the rest is room to grow (3T <=
     * LK_MAX_ELEMENTS < POOL_LIMIT: the entry points refuse larger meshes) */
    if (s->pool_limit == 0) s->pool_limit = POOL_LIMIT;
    if (s->pool_limit < 3 * t) return lk_error_set(error, LK_ERR_LIMIT, "QEM pool limit below 3 * %zu triangles", t);
    /* Grown lists move to the end of the pool, which reaches about 5T
     * entries (1.1M- and 5M-triangle meshes, any ratio). Only the entries
     * written take memory (the allocation is a mapping that the system
     * fills page by page), so reserving 6T costs nothing, and it spares
     * the realloc to 1.5 times that, whose copy briefly held both pools
     * at the peak of the run. */
    s->pool_capacity = 6 * t + 16;
    if (s->pool_capacity > s->pool_limit) s->pool_capacity = s->pool_limit;
    s->pool = lk__alloc_random_access(s->pool_capacity, sizeof(uint32_t), false);
    s->link = lk__alloc_random_access(v, sizeof(link_counts), true);
    s->stamp = lk__alloc_random_access(v, sizeof(uint32_t), true);
    s->ring_stamp = lk__alloc_random_access(v, sizeof(uint32_t), true);
    if (!s->indices || !s->vertex_input || !s->triangle_input || !s->triangle_alive || !s->vertices || !s->flags ||
        !s->pool || !s->link || !s->stamp || !s->ring_stamp)
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate QEM working arrays for %zu vertices", v);
    if (s->record) {
        s->collapses = lk__malloc_array(v, sizeof(lk_collapse));
        s->vanished = lk__malloc_array(t, sizeof(uint32_t));
        if (!s->collapses || !s->vanished)
            return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the contraction history");
    }
    return LK_OK;
}

void lk__qem_free_arrays(qem *s)
{
    free(s->vertex_input);
    free(s->triangle_input);
    free(s->indices);
    free(s->triangle_alive);
    free(s->vertices);
    free(s->flags);
    free(s->attributes);
    free(s->attribute_quadrics);
    free(s->pool);
    free(s->link);
    free(s->stamp);
    free(s->ring_stamp);
    free(s->scratch);
    free(s->pairs);
    free(s->chunks);
    free(s->buckets);
    free(s->bucket_bits);
    free(s->summary_bits);
    free(s->parked);
    free(s->waiting);
    free(s->collapses);
    free(s->vanished);
    free(s->frames.quadrics);
    free(s->frames.positions);
    free(s->frames.output);
    free(s->frames.scratch);
    free(s->frames.folded);
    free(s->lost.member_next);
    free(s->lost.member_last);
    free(s->lost.origin_positions);
    free(s->lost.origin_weights);
}

/* Spreads the low 10 bits of x to every third bit. */
static inline uint32_t spread_bits(uint32_t x)
{
    x &= 0x3FF;
    x = (x | (x << 16)) & 0x030000FF;
    x = (x | (x << 8)) & 0x0300F00F;
    x = (x | (x << 4)) & 0x030C30C3;
    x = (x | (x << 2)) & 0x09249249;
    return x;
}

/* Internal order: vertices by Morton code of their position on a 1024^3
 * grid (three radix passes), triangles by their first internal vertex
 * (a counting sort). Fills vertex_input, triangle_input and returns the
 * inverse vertex map in `internal` (V entries). */
static void spatial_order(qem *s, const lk_mesh *mesh, uint32_t *internal, uint32_t *scratch)
{
    size_t v_count = s->vertex_count, t_count = s->triangle_count;
    uint32_t *codes = internal; /* the codes live there until the inverse is built */
    for (size_t v = 0; v < v_count; v++) {
        uint32_t cell[3];
        for (int k = 0; k < 3; k++) {
            double unit = ((double)mesh->positions[3 * v + k] - s->center[k]) / s->extent + 0.5; /* in [0, 1] */
            double scaled = unit * 1023.0 + 0.5;
            cell[k] = scaled > 0 ? (scaled < 1023 ? (uint32_t)scaled : 1023) : 0;
        }
        codes[v] = spread_bits(cell[0]) | spread_bits(cell[1]) << 1 | spread_bits(cell[2]) << 2;
        s->vertex_input[v] = (uint32_t)v;
    }
    /* least significant digit first, 10 bits at a time: stable */
    uint32_t counts[1025];
    uint32_t *from = s->vertex_input, *to = scratch;
    for (int shift = 0; shift < 30; shift += 10) {
        memset(counts, 0, sizeof counts);
        for (size_t i = 0; i < v_count; i++) counts[((codes[from[i]] >> shift) & 1023) + 1]++;
        for (int b = 0; b < 1024; b++) counts[b + 1] += counts[b];
        for (size_t i = 0; i < v_count; i++) to[counts[(codes[from[i]] >> shift) & 1023]++] = from[i];
        uint32_t *swap = from;
        from = to, to = swap;
    }
    /* three passes: the sorted order ended in scratch */
    memcpy(s->vertex_input, from, v_count * sizeof(uint32_t));
    for (size_t v = 0; v < v_count; v++) internal[s->vertex_input[v]] = (uint32_t)v;
    /* triangles by their smallest internal vertex */
    uint32_t *first = scratch; /* V + 1 counters */
    memset(first, 0, (v_count + 1) * sizeof(uint32_t));
    for (size_t t = 0; t < t_count; t++) {
        const uint32_t *c = mesh->indices + 3 * t;
        uint32_t a = internal[c[0]], b = internal[c[1]], d = internal[c[2]];
        uint32_t low = a < b ? (a < d ? a : d) : (b < d ? b : d);
        first[low + 1]++;
    }
    for (size_t v = 0; v < v_count; v++) first[v + 1] += first[v];
    for (size_t t = 0; t < t_count; t++) {
        const uint32_t *c = mesh->indices + 3 * t;
        uint32_t a = internal[c[0]], b = internal[c[1]], d = internal[c[2]];
        uint32_t low = a < b ? (a < d ? a : d) : (b < d ? b : d);
        uint32_t slot = first[low]++;
        s->triangle_input[slot] = (uint32_t)t;
        uint32_t *out = s->indices + 3 * (size_t)slot;
        out[0] = a, out[1] = b, out[2] = d;
    }
}

/* Several frames: min/max grow to hold every frame's vertices (like
 * lk_mesh_bounds; one normalisation for all frames keeps their costs
 * comparable). */
static void frame_bounds(const qem *s, float min[3], float max[3])
{
    size_t count = s->frames.count * s->vertex_count;
    for (size_t i = 0; i < count; i++) {
        const float *p = s->frames.input + 3 * i;
        for (int k = 0; k < 3; k++) {
            if (p[k] < min[k]) min[k] = p[k];
            if (p[k] > max[k]) max[k] = p[k];
        }
    }
}

/* Normalised positions in internal order, vertex triangle lists, live
 * counts. */
lk_status lk__qem_build_lists(qem *s, const lk_mesh *mesh, lk_error *error)
{
    size_t v_count = s->vertex_count, t_count = s->triangle_count;
    float min[3], max[3];
    lk_mesh_bounds(mesh, min, max);
    if (s->frames.count) frame_bounds(s, min, max);
    for (int k = 0; k < 3; k++) s->center[k] = 0.5 * ((double)min[k] + (double)max[k]);
    double dx = (double)max[0] - min[0], dy = (double)max[1] - min[1], dz = (double)max[2] - min[2];
    double diagonal = sqrt(dx * dx + dy * dy + dz * dz);
    s->extent = diagonal > 0 ? diagonal : 1;
    if (s->part) { /* a part: the whole mesh's units */
        memcpy(s->center, s->part->center, sizeof s->center);
        s->extent = s->part->extent;
    }
    uint32_t *internal = lk__malloc_array(v_count, sizeof(uint32_t));
    uint32_t *scratch = lk__malloc_array(v_count + 1, sizeof(uint32_t));
    if (!internal || !scratch) {
        free(internal), free(scratch);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the vertex order");
    }
    spatial_order(s, mesh, internal, scratch);
    free(internal);
    free(scratch);
    double inverse = 1.0 / s->extent;
    s->input_positions = mesh->positions;
    for (size_t v = 0; v < v_count; v++) {
        vertex *vv = &s->vertices[v];
        const float *input = mesh->positions + 3 * (size_t)s->vertex_input[v];
        for (int k = 0; k < 3; k++) vv->position[k] = ((double)input[k] - s->center[k]) * inverse;
        vv->parent = (uint32_t)v;
    }
    memset(s->triangle_alive, 1, t_count);
    /* degrees, then fill cursors in the small array ring_stamp (zero
     * until the contractions start) */
    for (size_t c = 0; c < 3 * t_count; c++) s->ring_stamp[s->indices[c]]++;
    size_t start = 0;
    s->live_vertices = 0;
    for (size_t v = 0; v < v_count; v++) {
        uint32_t degree = s->ring_stamp[v];
        s->ring_stamp[v] = 0;
        s->vertices[v].list_start = (uint32_t)start; /* start <= 3T <= pool_limit */
        s->vertices[v].list_capacity = degree;
        s->vertices[v].list_count = degree;
        start += degree;
        s->live_vertices += degree > 0;
        s->stamp[v] = degree > 0 ? 0 : DEAD;
    }
    s->pool_size = start;
    for (size_t t = 0; t < t_count; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t v = s->indices[3 * t + k];
            s->pool[s->vertices[v].list_start + s->ring_stamp[v]++] = (uint32_t)t;
        }
    memset(s->ring_stamp, 0, v_count * sizeof(uint32_t));
    s->live_triangles = t_count;
    return LK_OK;
}

/* Sets up the attribute channels present in the mesh. */
lk_status lk__qem_setup_attributes(qem *s, const lk_mesh *mesh, lk_error *error)
{
    unsigned m = 0;
    s->normal_channel = s->texcoord_channel = s->color_channel = NONE;
    if (mesh->normals) s->normal_channel = m, m += 3;
    if (mesh->texcoords) s->texcoord_channel = m, m += 2;
    if (mesh->colors) s->color_channel = m, m += 4;
    s->attribute_count = m;
    if (m == 0) return LK_OK;
    size_t v_count = mesh->vertex_count;
    s->attributes = lk__malloc_array(v_count * m, sizeof(float));
    if (!s->attributes) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate vertex attributes");
    for (size_t v = 0; v < v_count; v++) {
        float *out = s->attributes + v * m;
        size_t input = s->vertex_input[v];
        if (mesh->normals) memcpy(out + s->normal_channel, mesh->normals + 3 * input, 3 * sizeof(float));
        if (mesh->texcoords) memcpy(out + s->texcoord_channel, mesh->texcoords + 2 * input, 2 * sizeof(float));
        if (mesh->colors) memcpy(out + s->color_channel, mesh->colors + 4 * input, 4 * sizeof(float));
    }
    s->attribute_quadrics_on = (s->options->flags & LK_SIMPLIFY_ATTRIBUTES) && s->options->attribute_weight > 0;
    if (s->attribute_quadrics_on) {
        s->attribute_scale = s->options->attribute_weight * ATTRIBUTE_UNIT;
        s->attribute_stride = 10 + 4 * (size_t)m;
        s->attribute_quadrics = lk__calloc_array(v_count * s->attribute_stride, sizeof(double));
        if (!s->attribute_quadrics) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate attribute quadrics");
    }
    return LK_OK;
}

/* Face quadrics (and attribute quadrics); fills unit face normals. */
void lk__qem_add_face_quadrics(qem *s, float *face_normals)
{
    unsigned m = s->attribute_count;
    for (size_t t = 0; t < s->triangle_count; t++) {
        const uint32_t *corners = s->indices + 3 * t;
        const double *p0 = s->vertices[corners[0]].position;
        const double *p1 = s->vertices[corners[1]].position;
        const double *p2 = s->vertices[corners[2]].position;
        double e1[3], e2[3], n[3];
        sub3(e1, p1, p0);
        sub3(e2, p2, p0);
        cross3(n, e1, e2);
        double length = sqrt(dot3(n, n));
        if (length > 0) {
            double inverse = 1.0 / length;
            n[0] *= inverse, n[1] *= inverse, n[2] *= inverse;
        }
        for (int k = 0; k < 3; k++) face_normals[3 * t + k] = (float)n[k];
        /* area * (n.v + d)^2 */
        double area = 0.5 * length, d = -dot3(n, p0);
        double an[3] = {area * n[0], area * n[1], area * n[2]};
        double face[10] = {an[0] * n[0], an[0] * n[1], an[0] * n[2], an[1] * n[1], an[1] * n[2],
                           an[2] * n[2], an[0] * d,    an[1] * d,    an[2] * d,    area * d * d};
        for (int k = 0; k < 3; k++) {
            quadric *q = &s->vertices[corners[k]].q;
            for (int j = 0; j < 10; j++) q->m[j] += face[j];
            q->weight += area;
        }
        if (!s->attribute_quadrics_on || !(length > 0)) continue;
        /* Hoppe: each channel s(x) = g.x + d on the face with g.n = 0. */
        double term[10 + 4 * MAX_ATTRIBUTES];
        memset(term, 0, sizeof term);
        double e2n[3], ne1[3];
        cross3(e2n, e2, n);
        cross3(ne1, n, e1);
        for (unsigned j = 0; j < m; j++) {
            double s0 = s->attributes[corners[0] * (size_t)m + j] * s->attribute_scale;
            double s1 = s->attributes[corners[1] * (size_t)m + j] * s->attribute_scale;
            double s2 = s->attributes[corners[2] * (size_t)m + j] * s->attribute_scale;
            double g[3];
            for (int k = 0; k < 3; k++) g[k] = ((s1 - s0) * e2n[k] + (s2 - s0) * ne1[k]) / length;
            double dj = s0 - dot3(g, p0);
            term[0] += area * g[0] * g[0], term[1] += area * g[0] * g[1], term[2] += area * g[0] * g[2];
            term[3] += area * g[1] * g[1], term[4] += area * g[1] * g[2], term[5] += area * g[2] * g[2];
            for (int k = 0; k < 3; k++) term[6 + k] += area * dj * g[k];
            term[9] += area * dj * dj;
            for (int k = 0; k < 3; k++) term[10 + 3 * j + k] = -area * g[k];
            term[10 + 3 * m + j] = -area * dj;
        }
        for (int k = 0; k < 3; k++) {
            double *q = s->attribute_quadrics + corners[k] * s->attribute_stride;
            for (size_t j = 0; j < s->attribute_stride; j++) q[j] += term[j];
        }
    }
}

/* Adds to both ends of edge a-b the plane through the edge perpendicular to
 * a face of normal n. */
static void add_edge_constraint(qem *s, uint32_t a, uint32_t b, const float *face_normal, double weight)
{
    const double *pa = s->vertices[a].position, *pb = s->vertices[b].position;
    double e[3], n[3] = {face_normal[0], face_normal[1], face_normal[2]}, m[3];
    sub3(e, pb, pa);
    cross3(m, e, n);
    double length_sq = dot3(e, e), m_length = sqrt(dot3(m, m));
    if (!(m_length > 0)) return;
    m[0] /= m_length, m[1] /= m_length, m[2] /= m_length;
    double d = -dot3(m, pa);
    quadric_add_plane(&s->vertices[a].q, m, d, weight * length_sq);
    quadric_add_plane(&s->vertices[b].q, m, d, weight * length_sq);
}

/* The weights of the constraints (times feature_weight), and whether a
 * crease plane's weight grows with the fold (see CREASE_SCALE). */
typedef struct constraint_weights {
    double border, crease, corner;
    bool graded;
} constraint_weights;

static constraint_weights constraint_weights_of(const qem *s, bool legacy)
{
    double unit = s->options->feature_weight;
    if (legacy)
        return (constraint_weights){unit * LEGACY_SCALE, unit * LEGACY_SCALE, unit * LEGACY_CORNER_WEIGHT, false};
    return (constraint_weights){unit * BORDER_SCALE, unit * CREASE_SCALE, unit * CORNER_WEIGHT, true};
}

/* Border, non-manifold and crease constraints of one edge (a, b) used by
 * `uses` triangles, the first two of which are `faces`; counts the feature
 * edges at each end (for corners). Shared by the one-frame and the
 * per-frame quadrics so both apply the same rules. */
static void add_edge_constraints(qem *s, uint32_t a, uint32_t b, uint32_t uses, const uint32_t *faces,
                                 const float *face_normals, bool features, double crease_cosine,
                                 const constraint_weights *weights, unsigned char *feature_edges)
{
    bool feature = false;
    if (uses == 1) {
        add_edge_constraint(s, a, b, face_normals + 3 * (size_t)faces[0], weights->border);
        feature = true;
    } else if (uses >= 3) {
        add_edge_constraint(s, a, b, face_normals + 3 * (size_t)faces[0], weights->border);
        add_edge_constraint(s, a, b, face_normals + 3 * (size_t)faces[1], weights->border);
        feature = true;
    } else if (features) {
        const float *n0 = face_normals + 3 * (size_t)faces[0], *n1 = face_normals + 3 * (size_t)faces[1];
        double cosine = (double)n0[0] * n1[0] + (double)n0[1] * n1[1] + (double)n0[2] * n1[2];
        if (cosine < crease_cosine) {
            double fold = 1 - cosine, weight = weights->crease;
            if (weights->graded && fold < 1) weight *= fold * fold;
            add_edge_constraint(s, a, b, n0, weight);
            add_edge_constraint(s, a, b, n1, weight);
            feature = true;
        }
    }
    if (feature) {
        if (feature_edges[a] < 255) feature_edges[a]++;
        if (feature_edges[b] < 255) feature_edges[b]++;
    }
}

/* Finds the edges (they become the first pairs), flags border and
 * non-manifold vertices, adds border/crease constraints and corner quadrics. */
lk_status lk__qem_build_edges(qem *s, const float *face_normals, lk_error *error)
{
    size_t v_count = s->vertex_count;
    bool features = !(s->options->flags & LK_SIMPLIFY_NO_FEATURES);
    constraint_weights weights = constraint_weights_of(s, false);
    double crease_cosine = cos(s->options->feature_angle * (3.14159265358979323846 / 180.0));
    uint32_t max_degree = 0;
    for (size_t v = 0; v < v_count; v++)
        if (s->vertices[v].list_count > max_degree) max_degree = s->vertices[v].list_count;
    s->pairs = lk__malloc_array(3 * s->triangle_count, 2 * sizeof(uint32_t));
    uint32_t *slot = lk__malloc_array(v_count, sizeof(uint32_t));
    uint32_t *slot_owner = lk__calloc_array(v_count, sizeof(uint32_t)); /* slot[w] is valid while == v + 1 */
    uint32_t *edge_faces = lk__malloc_array(2 * (size_t)max_degree + 2, 2 * sizeof(uint32_t));
    uint32_t *edge_uses = lk__malloc_array(2 * (size_t)max_degree + 2, sizeof(uint32_t));
    unsigned char *feature_edges = lk__calloc_array(v_count, 1);
    if (!s->pairs || !slot || !slot_owner || !edge_faces || !edge_uses || !feature_edges) {
        free(slot), free(slot_owner), free(edge_faces), free(edge_uses), free(feature_edges);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the edge list");
    }
    size_t edge_count = 0;
    for (size_t v = 0; v < v_count; v++) {
        const uint32_t *list = list_of(s, (uint32_t)v);
        size_t first = edge_count;
        for (uint32_t i = 0; i < s->vertices[v].list_count; i++) {
            const uint32_t *corners = s->indices + 3 * (size_t)list[i];
            for (int k = 0; k < 3; k++) {
                uint32_t w = corners[k];
                if (w <= v) continue;
                if (slot_owner[w] != v + 1) {
                    slot_owner[w] = (uint32_t)(v + 1);
                    slot[w] = (uint32_t)(edge_count - first);
                    s->pairs[2 * edge_count] = (uint32_t)v;
                    s->pairs[2 * edge_count + 1] = w;
                    edge_uses[edge_count - first] = 0;
                    edge_count++;
                }
                uint32_t local = slot[w];
                if (edge_uses[local] < 2) edge_faces[2 * local + edge_uses[local]] = list[i];
                edge_uses[local]++;
            }
        }
        for (size_t e = first; e < edge_count; e++) {
            uint32_t a = (uint32_t)v, b = s->pairs[2 * e + 1];
            uint32_t uses = edge_uses[e - first];
            const uint32_t *faces = edge_faces + 2 * (e - first);
            if (uses == 1)
                s->flags[a] |= FLAG_BORDER, s->flags[b] |= FLAG_BORDER;
            else if (uses >= 3)
                s->flags[a] |= FLAG_NONMANIFOLD, s->flags[b] |= FLAG_NONMANIFOLD;
            add_edge_constraints(s, a, b, uses, faces, face_normals, features, crease_cosine, &weights, feature_edges);
        }
    }
    for (size_t v = 0; v < v_count; v++) {
        if (s->lock_border && (s->flags[v] & FLAG_BORDER)) s->flags[v] |= FLAG_LOCKED;
        if (s->part && s->part->locked[s->vertex_input[v]]) s->flags[v] |= FLAG_LOCKED;
        if (features && feature_edges[v] >= 3) {
            vertex *corner = &s->vertices[v];
            quadric_add_point(&corner->q, corner->position, weights.corner * corner->q.weight);
        }
    }
    s->pair_count = s->edge_count = edge_count;
    free(slot), free(slot_owner), free(edge_faces), free(edge_uses), free(feature_edges);
    return LK_OK;
}

/* Several frames: every frame's quadrics, by the rules of add_face_quadrics
 * and build_edges applied to that frame's positions. Borders, non-manifold
 * edges and locks come from the topology (the same in every frame); creases
 * and corners are found per frame. The vertex records are borrowed frame
 * after frame and end up holding the reference frame again. */
lk_status lk__qem_build_frame_quadrics(qem *s, float *face_normals, lk_error *error)
{
    size_t v_count = s->vertex_count, frames = s->frames.count, edge_count = s->edge_count;
    bool features = !(s->options->flags & LK_SIMPLIFY_NO_FEATURES);
    constraint_weights weights = constraint_weights_of(s, frames > 1);
    double crease_cosine = cos(s->options->feature_angle * (3.14159265358979323846 / 180.0));
    uint32_t *edge_faces = lk__malloc_array(edge_count + 1, 2 * sizeof(uint32_t));
    uint32_t *edge_uses = lk__malloc_array(edge_count + 1, sizeof(uint32_t));
    unsigned char *feature_edges = lk__malloc_array(v_count, 1);
    if (!edge_faces || !edge_uses || !feature_edges) {
        free(edge_faces), free(edge_uses), free(feature_edges);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the edge faces");
    }
    /* the first two triangles of each edge, in the order build_edges met them */
    for (size_t e = 0; e < edge_count; e++) {
        uint32_t a = s->pairs[2 * e], b = s->pairs[2 * e + 1], uses = 0;
        const uint32_t *list = list_of(s, a);
        for (uint32_t i = 0; i < s->vertices[a].list_count; i++)
            if (triangle_has(s->indices + 3 * (size_t)list[i], b)) {
                if (uses < 2) edge_faces[2 * e + uses] = list[i];
                uses++;
            }
        edge_uses[e] = uses;
    }
    double inverse = 1.0 / s->extent;
    for (size_t f = 0; f < frames; f++) {
        for (size_t v = 0; v < v_count; v++) {
            vertex *vv = &s->vertices[v];
            const float *input = s->frames.input + 3 * (f * v_count + s->vertex_input[v]);
            for (int k = 0; k < 3; k++) vv->position[k] = ((double)input[k] - s->center[k]) * inverse;
            memset(&vv->q, 0, sizeof vv->q);
        }
        lk__qem_add_face_quadrics(s, face_normals);
        memset(feature_edges, 0, v_count);
        for (size_t e = 0; e < edge_count; e++) {
            uint32_t a = s->pairs[2 * e], b = s->pairs[2 * e + 1], uses = edge_uses[e];
            const uint32_t *faces = edge_faces + 2 * e;
            add_edge_constraints(s, a, b, uses, faces, face_normals, features, crease_cosine, &weights, feature_edges);
        }
        for (size_t v = 0; v < v_count; v++) {
            vertex *vv = &s->vertices[v];
            if (features && feature_edges[v] >= 3)
                quadric_add_point(&vv->q, vv->position, weights.corner * vv->q.weight);
            size_t slot = v * frames + f;
            s->frames.quadrics[slot] = vv->q;
            memcpy(s->frames.positions + 3 * slot, vv->position, sizeof vv->position);
            memcpy(s->frames.output + 3 * slot, s->frames.input + 3 * (f * v_count + s->vertex_input[v]),
                   3 * sizeof(float));
        }
    }
    size_t reference = s->frames.reference;
    for (size_t v = 0; v < v_count; v++) {
        size_t slot = v * frames + reference;
        s->vertices[v].q = s->frames.quadrics[slot];
        memcpy(s->vertices[v].position, s->frames.positions + 3 * slot, sizeof s->vertices[v].position);
    }
    free(edge_faces), free(edge_uses), free(feature_edges);
    return LK_OK;
}

/* ---- non-edge pairs ----------------------------------------------------- */

typedef struct close_candidate {
    double distance_sq;
    uint32_t vertex;
} close_candidate;

static inline uint64_t cell_hash(int64_t x, int64_t y, int64_t z)
{
    return lk__mix64((uint64_t)x * 0x9E3779B97F4A7C15ull ^ (uint64_t)y * 0xC2B2AE3D27D4EB4Full ^
                     (uint64_t)z * 0x165667B19E3779F9ull);
}

/* Appends, for every used vertex, its nearest (up to CLOSE_PAIRS_PER_VERTEX)
 * non-adjacent vertices closer than pair_distance, each pair once. A hashed
 * grid of cell size pair_distance keeps the search local. */
lk_status lk__qem_add_close_pairs(qem *s, lk_error *error)
{
    size_t v_count = s->vertex_count;
    double limit = s->options->pair_distance; /* normalised units: fraction of the diagonal */
    double cell = limit > 1e-9 ? limit : 1e-9;
    size_t bucket_count = 1;
    while (bucket_count < 2 * v_count) bucket_count *= 2;
    int64_t *cells = lk__malloc_array(v_count, 3 * sizeof(int64_t));
    uint32_t *bucket_start = lk__calloc_array(bucket_count + 1, sizeof(uint32_t));
    uint32_t *cursor = lk__malloc_array(bucket_count, sizeof(uint32_t));
    uint32_t *members = lk__malloc_array(v_count, sizeof(uint32_t));
    uint32_t *bucket_of_vertex = lk__malloc_array(v_count, sizeof(uint32_t));
    uint32_t *neighbour_of = lk__calloc_array(v_count, sizeof(uint32_t)); /* == v + 1: adjacent to v */
    lk__buffer found = {0};
    if (!cells || !bucket_start || !cursor || !members || !bucket_of_vertex || !neighbour_of) {
        free(cells), free(bucket_start), free(cursor), free(members), free(bucket_of_vertex), free(neighbour_of);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the pair grid");
    }
    for (size_t v = 0; v < v_count; v++) {
        bucket_of_vertex[v] = NONE;
        if (s->vertices[v].list_count == 0) continue;
        int64_t *c = cells + 3 * v;
        for (int k = 0; k < 3; k++) c[k] = (int64_t)floor(s->vertices[v].position[k] / cell);
        bucket_of_vertex[v] = (uint32_t)(cell_hash(c[0], c[1], c[2]) & (bucket_count - 1));
        bucket_start[bucket_of_vertex[v] + 1]++;
    }
    for (size_t b = 0; b < bucket_count; b++) bucket_start[b + 1] += bucket_start[b];
    memcpy(cursor, bucket_start, bucket_count * sizeof(uint32_t));
    for (size_t v = 0; v < v_count; v++)
        if (bucket_of_vertex[v] != NONE) members[cursor[bucket_of_vertex[v]]++] = (uint32_t)v;
    free(cursor);

    lk_status status = LK_OK;
    close_candidate nearest[CLOSE_PAIRS_PER_VERTEX];
    for (size_t v = 0; v < v_count && status == LK_OK; v++) {
        if (bucket_of_vertex[v] == NONE) continue;
        /* mark v's neighbours: edges are pairs already */
        uint32_t token = (uint32_t)(v + 1);
        const uint32_t *list = list_of(s, (uint32_t)v);
        for (uint32_t i = 0; i < s->vertices[v].list_count; i++)
            for (int k = 0; k < 3; k++) neighbour_of[s->indices[3 * (size_t)list[i] + k]] = token;
        int found_count = 0;
        const double *pv = s->vertices[v].position;
        for (int dz = -1; dz <= 1; dz++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int64_t cx = cells[3 * v] + dx, cy = cells[3 * v + 1] + dy, cz = cells[3 * v + 2] + dz;
                    size_t b = cell_hash(cx, cy, cz) & (bucket_count - 1);
                    for (uint32_t i = bucket_start[b]; i < bucket_start[b + 1]; i++) {
                        uint32_t w = members[i];
                        if (w <= v || neighbour_of[w] == token) continue;
                        const int64_t *cw = cells + 3 * (size_t)w;
                        if (cw[0] != cx || cw[1] != cy || cw[2] != cz) continue;
                        double d = distance_sq3(pv, s->vertices[w].position);
                        if (!(d < limit * limit)) continue;
                        /* insertion into the short sorted list of the nearest */
                        int at = found_count;
                        if (found_count == CLOSE_PAIRS_PER_VERTEX) {
                            if (!(d < nearest[found_count - 1].distance_sq)) continue;
                            at--;
                        } else {
                            found_count++;
                        }
                        while (at > 0 && (nearest[at - 1].distance_sq > d ||
                                          (nearest[at - 1].distance_sq == d && nearest[at - 1].vertex > w))) {
                            nearest[at] = nearest[at - 1];
                            at--;
                        }
                        nearest[at].distance_sq = d;
                        nearest[at].vertex = w;
                    }
                }
        for (int i = 0; i < found_count; i++) {
            uint32_t pair[2] = {(uint32_t)v, nearest[i].vertex};
            if (!lk__buffer_append(&found, pair, sizeof pair)) {
                status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the close pairs");
                break;
            }
        }
    }
    free(cells), free(bucket_start), free(members), free(bucket_of_vertex), free(neighbour_of);
    if (status == LK_OK && found.size > 0) {
        size_t extra = found.size / (2 * sizeof(uint32_t));
        uint32_t *grown = lk__realloc_array(s->pairs, s->pair_count + extra, 2 * sizeof(uint32_t));
        if (!grown) {
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the close pairs");
        } else {
            s->pairs = grown;
            memcpy(s->pairs + 2 * s->pair_count, found.data, found.size);
            s->pair_count += extra;
        }
    }
    lk__buffer_free(&found);
    return status;
}
