/* SPDX-License-Identifier: MIT */
/* Indexed triangle mesh: allocation, validation, bounds, adjacency, welding,
 * clean-up, components and topology statistics. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void lk_mesh_init(lk_mesh *mesh) { memset(mesh, 0, sizeof *mesh); }

void lk_mesh_free(lk_mesh *mesh)
{
    if (!mesh) return;
    free(mesh->positions);
    free(mesh->normals);
    free(mesh->texcoords);
    free(mesh->colors);
    free(mesh->radii);
    free(mesh->indices);
    lk_mesh_init(mesh);
}

lk_status lk_mesh_alloc(lk_mesh *mesh, size_t vertex_count, size_t triangle_count, unsigned attribute_flags,
                        lk_error *error)
{
    lk_mesh_init(mesh);
    if (vertex_count > LK_MAX_ELEMENTS || triangle_count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "mesh of %zu vertices and %zu triangles is too large", vertex_count,
                            triangle_count);
    mesh->vertex_count = vertex_count;
    mesh->triangle_count = triangle_count;
    /* Huge pages for big arrays: filling them (a reader, a subdivision) faults far less. */
    mesh->positions = lk__alloc_random_access(vertex_count, 3 * sizeof(float), false);
    mesh->indices = lk__alloc_random_access(triangle_count, 3 * sizeof(uint32_t), false);
    bool ok = mesh->positions && mesh->indices;
    if (attribute_flags & LK_ATTR_NORMALS)
        ok = ok && (mesh->normals = lk__alloc_random_access(vertex_count, 3 * sizeof(float), false));
    if (attribute_flags & LK_ATTR_TEXCOORDS)
        ok = ok && (mesh->texcoords = lk__alloc_random_access(vertex_count, 2 * sizeof(float), false));
    if (attribute_flags & LK_ATTR_COLORS)
        ok = ok && (mesh->colors = lk__alloc_random_access(vertex_count, 4 * sizeof(float), false));
    if (attribute_flags & LK_ATTR_RADII)
        ok = ok && (mesh->radii = lk__alloc_random_access(vertex_count, sizeof(float), false));
    if (!ok) {
        lk_mesh_free(mesh);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate a mesh of %zu vertices and %zu triangles",
                            vertex_count, triangle_count);
    }
    return LK_OK;
}

static float *copy_floats(const float *src, size_t count, bool *ok)
{
    if (!src) return NULL;
    float *dst = lk__malloc_array(count, sizeof(float));
    if (!dst) {
        *ok = false;
        return NULL;
    }
    memcpy(dst, src, count * sizeof(float));
    return dst;
}

lk_status lk_mesh_copy(lk_mesh *dst, const lk_mesh *src, lk_error *error)
{
    lk_mesh copy;
    lk_mesh_init(&copy);
    bool ok = true;
    copy.vertex_count = src->vertex_count;
    copy.triangle_count = src->triangle_count;
    copy.positions = lk__malloc_array(src->vertex_count, 3 * sizeof(float));
    copy.indices = lk__malloc_array(src->triangle_count, 3 * sizeof(uint32_t));
    if (!copy.positions || !copy.indices) ok = false;
    if (ok) {
        if (src->vertex_count) memcpy(copy.positions, src->positions, src->vertex_count * 3 * sizeof(float));
        if (src->triangle_count) memcpy(copy.indices, src->indices, src->triangle_count * 3 * sizeof(uint32_t));
    }
    copy.normals = copy_floats(src->normals, src->vertex_count * 3, &ok);
    copy.texcoords = copy_floats(src->texcoords, src->vertex_count * 2, &ok);
    copy.colors = copy_floats(src->colors, src->vertex_count * 4, &ok);
    copy.radii = copy_floats(src->radii, src->vertex_count, &ok);
    if (!ok) {
        lk_mesh_free(&copy);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot copy a mesh of %zu vertices", src->vertex_count);
    }
    *dst = copy;
    return LK_OK;
}

static lk_status check_finite(const float *values, size_t vertex_count, size_t width, const char *what, lk_error *error)
{
    if (!values) return LK_OK;
    for (size_t i = 0; i < vertex_count * width; i++) {
        if (!isfinite(values[i]))
            return lk_error_set(error, LK_ERR_RANGE, "vertex %zu: %s is not finite (%g)", i / width, what,
                                (double)values[i]);
    }
    return LK_OK;
}

lk_status lk_mesh_validate(const lk_mesh *mesh, lk_error *error)
{
    if (mesh->vertex_count > LK_MAX_ELEMENTS || mesh->triangle_count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "mesh too large");
    if ((mesh->vertex_count && !mesh->positions) || (mesh->triangle_count && !mesh->indices))
        return lk_error_set(error, LK_ERR_INVALID, "mesh arrays missing");
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        for (int k = 0; k < 3; k++) {
            uint32_t v = mesh->indices[3 * t + k];
            if (v >= mesh->vertex_count)
                return lk_error_set(error, LK_ERR_RANGE, "triangle %zu: vertex index %u out of range (%zu vertices)", t,
                                    v, mesh->vertex_count);
        }
    }
    lk_status status = check_finite(mesh->positions, mesh->vertex_count, 3, "position", error);
    if (status == LK_OK) status = check_finite(mesh->normals, mesh->vertex_count, 3, "normal", error);
    if (status == LK_OK) status = check_finite(mesh->texcoords, mesh->vertex_count, 2, "texture coordinate", error);
    if (status == LK_OK) status = check_finite(mesh->colors, mesh->vertex_count, 4, "colour", error);
    if (status == LK_OK && mesh->radii) {
        /* A splat of radius 0 covers nothing and a negative one is
         * meaningless, so radii must be strictly positive, not only finite. */
        for (size_t i = 0; i < mesh->vertex_count; i++)
            if (!(mesh->radii[i] > 0) || !isfinite(mesh->radii[i]))
                return lk_error_set(error, LK_ERR_RANGE, "vertex %zu: radius %g is not a finite number > 0", i,
                                    (double)mesh->radii[i]);
    }
    return status;
}

double lk_mesh_bounds(const lk_mesh *mesh, float min[3], float max[3])
{
    float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    if (mesh->vertex_count) {
        for (int k = 0; k < 3; k++) lo[k] = hi[k] = mesh->positions[k];
        for (size_t i = 1; i < mesh->vertex_count; i++) {
            const float *p = mesh->positions + 3 * i;
            for (int k = 0; k < 3; k++) {
                if (p[k] < lo[k]) lo[k] = p[k];
                if (p[k] > hi[k]) hi[k] = p[k];
            }
        }
    }
    if (min) memcpy(min, lo, sizeof lo);
    if (max) memcpy(max, hi, sizeof hi);
    double dx = (double)hi[0] - lo[0], dy = (double)hi[1] - lo[1], dz = (double)hi[2] - lo[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

static double triangle_area(const float *a, const float *b, const float *c)
{
    double u[3], v[3];
    for (int k = 0; k < 3; k++) {
        u[k] = (double)b[k] - a[k];
        v[k] = (double)c[k] - a[k];
    }
    double n0 = u[1] * v[2] - u[2] * v[1], n1 = u[2] * v[0] - u[0] * v[2], n2 = u[0] * v[1] - u[1] * v[0];
    return 0.5 * sqrt(n0 * n0 + n1 * n1 + n2 * n2);
}

double lk_mesh_area(const lk_mesh *mesh)
{
    double area = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *tri = mesh->indices + 3 * t;
        area += triangle_area(mesh->positions + 3 * tri[0], mesh->positions + 3 * tri[1], mesh->positions + 3 * tri[2]);
    }
    return area;
}

void lk_mesh_translate(lk_mesh *mesh, double dx, double dy, double dz)
{
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        float *p = mesh->positions + 3 * i;
        p[0] = (float)(p[0] + dx);
        p[1] = (float)(p[1] + dy);
        p[2] = (float)(p[2] + dz);
    }
}

/* ---- adjacency ---------------------------------------------------------- */

lk_status lk_vertex_adjacency_build(const lk_mesh *mesh, lk_vertex_adjacency *adjacency, lk_error *error)
{
    memset(adjacency, 0, sizeof *adjacency);
    size_t vertex_count = mesh->vertex_count, corner_count = 3 * mesh->triangle_count;
    uint32_t *offsets = lk__calloc_array(vertex_count + 1, sizeof(uint32_t));
    uint32_t *triangles = lk__malloc_array(corner_count, sizeof(uint32_t));
    if (!offsets || !triangles) {
        free(offsets);
        free(triangles);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate vertex adjacency");
    }
    for (size_t c = 0; c < corner_count; c++) offsets[mesh->indices[c] + 1]++;
    for (size_t v = 0; v < vertex_count; v++) offsets[v + 1] += offsets[v];
    /* Fill using offsets[v] as a cursor, then shift back: keeps triangles in order. */
    for (size_t c = 0; c < corner_count; c++) triangles[offsets[mesh->indices[c]]++] = (uint32_t)(c / 3);
    for (size_t v = vertex_count; v > 0; v--) offsets[v] = offsets[v - 1];
    offsets[0] = 0;
    adjacency->vertex_count = vertex_count;
    adjacency->offsets = offsets;
    adjacency->triangles = triangles;
    return LK_OK;
}

void lk_vertex_adjacency_free(lk_vertex_adjacency *adjacency)
{
    if (!adjacency) return;
    free(adjacency->offsets);
    free(adjacency->triangles);
    memset(adjacency, 0, sizeof *adjacency);
}

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

lk_status lk_edge_adjacency_build(const lk_mesh *mesh, lk_edge_adjacency *adjacency, lk_error *error)
{
    memset(adjacency, 0, sizeof *adjacency);
    size_t vertex_count = mesh->vertex_count, corner_count = 3 * mesh->triangle_count;
    /* Bucket every half-edge by its smaller vertex (counting sort), then sort
     * each bucket by (larger vertex, corner): O(T) overall for meshes of
     * bounded valence, O(T log T) at worst. */
    uint32_t *bucket_start = lk__calloc_array(vertex_count + 1, sizeof(uint32_t));
    uint64_t *entries = lk__malloc_array(corner_count, sizeof(uint64_t)); /* (other << 32) | corner */
    uint32_t *vertices = lk__malloc_array(corner_count, 2 * sizeof(uint32_t));
    uint32_t *offsets = lk__malloc_array(corner_count + 1, sizeof(uint32_t));
    uint32_t *triangles = lk__malloc_array(corner_count, sizeof(uint32_t));
    uint32_t *triangle_edges = lk__malloc_array(corner_count, sizeof(uint32_t));
    if (!bucket_start || !entries || !vertices || !offsets || !triangles || !triangle_edges) {
        free(bucket_start), free(entries), free(vertices), free(offsets), free(triangles), free(triangle_edges);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate edge adjacency");
    }
    const uint32_t *indices = mesh->indices;
    for (size_t c = 0; c < corner_count; c++) {
        uint32_t a = indices[c], b = indices[c - c % 3 + (c % 3 + 1) % 3];
        bucket_start[(a < b ? a : b) + 1]++;
    }
    for (size_t v = 0; v < vertex_count; v++) bucket_start[v + 1] += bucket_start[v];
    for (size_t c = 0; c < corner_count; c++) {
        uint32_t a = indices[c], b = indices[c - c % 3 + (c % 3 + 1) % 3];
        uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
        entries[bucket_start[lo]++] = ((uint64_t)hi << 32) | (uint64_t)c;
    }
    for (size_t v = vertex_count; v > 0; v--) bucket_start[v] = bucket_start[v - 1];
    bucket_start[0] = 0;
    size_t edge_count = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        uint64_t *bucket = entries + bucket_start[v];
        size_t length = bucket_start[v + 1] - bucket_start[v];
        if (length > 32) {
            /* A vertex of huge valence (a fan of many triangles, or a hostile
             * file repeating one vertex in a polygon of 100k corners) would
             * make the insertion sort quadratic. */
            qsort(bucket, length, sizeof *bucket, compare_u64);
        } else {
            for (size_t i = 1; i < length; i++) { /* insertion sort: buckets are tiny */
                uint64_t key = bucket[i];
                size_t j = i;
                while (j > 0 && bucket[j - 1] > key) {
                    bucket[j] = bucket[j - 1];
                    j--;
                }
                bucket[j] = key;
            }
        }
        for (size_t i = 0; i < length; i++) {
            uint32_t other = (uint32_t)(bucket[i] >> 32), corner = (uint32_t)bucket[i];
            if (i == 0 || (uint32_t)(bucket[i - 1] >> 32) != other) {
                vertices[2 * edge_count] = (uint32_t)v;
                vertices[2 * edge_count + 1] = other;
                offsets[edge_count] = bucket_start[v] + (uint32_t)i;
                edge_count++;
            }
            triangles[bucket_start[v] + i] = corner / 3;
            triangle_edges[corner] = (uint32_t)(edge_count - 1);
        }
    }
    offsets[edge_count] = (uint32_t)corner_count;
    free(bucket_start);
    free(entries);
    adjacency->edge_count = edge_count;
    adjacency->vertices = vertices;
    adjacency->offsets = offsets;
    adjacency->triangles = triangles;
    adjacency->triangle_edges = triangle_edges;
    return LK_OK;
}

void lk_edge_adjacency_free(lk_edge_adjacency *adjacency)
{
    if (!adjacency) return;
    free(adjacency->vertices);
    free(adjacency->offsets);
    free(adjacency->triangles);
    free(adjacency->triangle_edges);
    memset(adjacency, 0, sizeof *adjacency);
}

/* ---- union-find over uint32 ids ------------------------------------------ */

static uint32_t uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]]; /* path halving */
        x = parent[x];
    }
    return x;
}

static void uf_union(uint32_t *parent, uint32_t a, uint32_t b)
{
    a = uf_find(parent, a);
    b = uf_find(parent, b);
    if (a == b) return;
    if (a < b)
        parent[b] = a; /* smaller id is the root: deterministic */
    else
        parent[a] = b;
}

static uint32_t *uf_new(size_t count)
{
    uint32_t *parent = lk__malloc_array(count, sizeof(uint32_t));
    if (parent)
        for (size_t i = 0; i < count; i++) parent[i] = (uint32_t)i;
    return parent;
}

/* Copies vertex `from` (all attributes) over vertex `to`; used when
 * compacting arrays in place (to <= from). */
static void move_vertex(lk_mesh *mesh, size_t to, size_t from)
{
    memmove(mesh->positions + 3 * to, mesh->positions + 3 * from, 3 * sizeof(float));
    if (mesh->normals) memmove(mesh->normals + 3 * to, mesh->normals + 3 * from, 3 * sizeof(float));
    if (mesh->texcoords) memmove(mesh->texcoords + 2 * to, mesh->texcoords + 2 * from, 2 * sizeof(float));
    if (mesh->colors) memmove(mesh->colors + 4 * to, mesh->colors + 4 * from, 4 * sizeof(float));
    if (mesh->radii) mesh->radii[to] = mesh->radii[from];
}

/* ---- welding ----------------------------------------------------------- */

/* Hash of an integer grid cell. */
static uint64_t cell_hash(int64_t x, int64_t y, int64_t z)
{
    return lk__mix64((uint64_t)x * 0x9E3779B1ull ^ lk__mix64((uint64_t)y * 0x85EBCA77ull ^ lk__mix64((uint64_t)z)));
}

static uint32_t float_bits(float value)
{
    if (value == 0.0f) value = 0.0f; /* -0 and +0 weld */
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    return bits;
}

lk_status lk_mesh_weld(lk_mesh *mesh, double tolerance, size_t *merged_count, lk_error *error)
{
    if (merged_count) *merged_count = 0;
    if (!(tolerance >= 0) || !isfinite(tolerance))
        return lk_error_set(error, LK_ERR_INVALID, "weld tolerance must be a finite number >= 0");
    size_t vertex_count = mesh->vertex_count;
    if (vertex_count == 0) return LK_OK;
    size_t table_size = 16;
    while (table_size < 2 * vertex_count) table_size *= 2;
    /* Open-addressed table of cell -> first representative in that cell;
     * representatives of one cell are chained through next_in_cell. */
    uint32_t *table = lk__malloc_array(table_size, sizeof(uint32_t));
    uint64_t *table_key = lk__malloc_array(table_size, sizeof(uint64_t));
    uint32_t *next_in_cell = lk__malloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *remap = lk__malloc_array(vertex_count, sizeof(uint32_t));
    int64_t *cell = lk__malloc_array(vertex_count, 3 * sizeof(int64_t));
    if (!table || !table_key || !next_in_cell || !remap || !cell) {
        free(table), free(table_key), free(next_in_cell), free(remap), free(cell);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate weld tables");
    }
    const uint32_t empty = UINT32_MAX;
    for (size_t i = 0; i < table_size; i++) table[i] = empty;
    double inverse_cell = tolerance > 0 ? 1.0 / tolerance : 0.0;
    double tolerance_squared = tolerance * tolerance;
    const float *positions = mesh->positions;
    size_t representative_count = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        const float *p = positions + 3 * v;
        if (tolerance > 0) {
            for (int k = 0; k < 3; k++) cell[3 * v + k] = (int64_t)floor((double)p[k] * inverse_cell);
        } else {
            for (int k = 0; k < 3; k++) cell[3 * v + k] = (int64_t)float_bits(p[k]);
        }
        uint32_t found = empty;
        int reach = tolerance > 0 ? 1 : 0;
        for (int dx = -reach; dx <= reach && found == empty; dx++)
            for (int dy = -reach; dy <= reach && found == empty; dy++)
                for (int dz = -reach; dz <= reach && found == empty; dz++) {
                    int64_t cx = cell[3 * v] + dx, cy = cell[3 * v + 1] + dy, cz = cell[3 * v + 2] + dz;
                    uint64_t key = cell_hash(cx, cy, cz);
                    for (size_t slot = key & (table_size - 1); table[slot] != empty;
                         slot = (slot + 1) & (table_size - 1)) {
                        if (table_key[slot] != key) continue;
                        for (uint32_t r = table[slot]; r != empty; r = next_in_cell[r]) {
                            if (cell[3 * r] != cx || cell[3 * r + 1] != cy || cell[3 * r + 2] != cz) continue;
                            const float *q = positions + 3 * r;
                            double d0 = (double)p[0] - q[0], d1 = (double)p[1] - q[1], d2 = (double)p[2] - q[2];
                            if (d0 * d0 + d1 * d1 + d2 * d2 <= tolerance_squared) {
                                found = r;
                                break;
                            }
                        }
                        if (found != empty) break;
                    }
                }
        if (found != empty) {
            remap[v] = found;
            continue;
        }
        /* New representative: link it into its cell's chain. */
        remap[v] = (uint32_t)v;
        representative_count++;
        uint64_t key = cell_hash(cell[3 * v], cell[3 * v + 1], cell[3 * v + 2]);
        size_t slot = key & (table_size - 1);
        while (table[slot] != empty && table_key[slot] != key) slot = (slot + 1) & (table_size - 1);
        next_in_cell[v] = table[slot];
        table[slot] = (uint32_t)v;
        table_key[slot] = key;
    }
    free(table);
    free(table_key);
    free(next_in_cell);
    free(cell);
    /* Compact representatives in order; remap to new indices. */
    uint32_t *new_index = lk__malloc_array(vertex_count, sizeof(uint32_t));
    if (!new_index) {
        free(remap);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate weld tables");
    }
    size_t next = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        if (remap[v] != v) continue;
        new_index[v] = (uint32_t)next;
        move_vertex(mesh, next, v);
        next++;
    }
    for (size_t c = 0; c < 3 * mesh->triangle_count; c++) mesh->indices[c] = new_index[remap[mesh->indices[c]]];
    free(new_index);
    free(remap);
    if (merged_count) *merged_count = vertex_count - representative_count;
    mesh->vertex_count = representative_count;
    return LK_OK;
}

/* ---- clean-up ----------------------------------------------------------- */

static void sort3(uint32_t v[3])
{
    uint32_t s;
    if (v[0] > v[1]) s = v[0], v[0] = v[1], v[1] = s;
    if (v[1] > v[2]) s = v[1], v[1] = v[2], v[2] = s;
    if (v[0] > v[1]) s = v[0], v[0] = v[1], v[1] = s;
}

/* Marks keep[t] = 0 for degenerate triangles (a repeated index) and for
 * later copies of a vertex set already seen (any order or orientation).
 * Uses an open-addressed hash set of sorted triples: O(T) expected.
 * Returns false on allocation failure. */
static bool classify_triangles(const lk_mesh *mesh, unsigned char *keep, size_t *degenerate, size_t *duplicate)
{
    size_t triangle_count = mesh->triangle_count;
    size_t table_size = 16;
    while (table_size < 2 * triangle_count) table_size *= 2;
    uint32_t *table = lk__malloc_array(table_size, sizeof(uint32_t));
    if (!table) return false;
    memset(table, 0xFF, table_size * sizeof(uint32_t));
    *degenerate = *duplicate = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        uint32_t v[3] = {mesh->indices[3 * t], mesh->indices[3 * t + 1], mesh->indices[3 * t + 2]};
        keep[t] = 1;
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
            keep[t] = 0;
            (*degenerate)++;
            continue;
        }
        sort3(v);
        uint64_t hash = lk__mix64(((uint64_t)v[0] << 32 | v[1]) ^ lk__mix64(v[2]));
        for (size_t slot = hash & (table_size - 1);; slot = (slot + 1) & (table_size - 1)) {
            if (table[slot] == UINT32_MAX) {
                table[slot] = (uint32_t)t;
                break;
            }
            uint32_t w[3] = {mesh->indices[3 * table[slot]], mesh->indices[3 * table[slot] + 1],
                             mesh->indices[3 * table[slot] + 2]};
            sort3(w);
            if (w[0] == v[0] && w[1] == v[1] && w[2] == v[2]) {
                keep[t] = 0;
                (*duplicate)++;
                break;
            }
        }
    }
    free(table);
    return true;
}

lk_status lk_mesh_remove_degenerate(lk_mesh *mesh, size_t *degenerate_removed, size_t *duplicate_removed,
                                    lk_error *error)
{
    unsigned char *keep = lk__malloc_array(mesh->triangle_count, 1);
    size_t degenerate = 0, duplicate = 0;
    if (!keep || !classify_triangles(mesh, keep, &degenerate, &duplicate)) {
        free(keep);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate triangle table");
    }
    size_t next = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        if (!keep[t]) continue;
        memmove(mesh->indices + 3 * next, mesh->indices + 3 * t, 3 * sizeof(uint32_t));
        next++;
    }
    free(keep);
    mesh->triangle_count = next;
    if (degenerate_removed) *degenerate_removed = degenerate;
    if (duplicate_removed) *duplicate_removed = duplicate;
    return LK_OK;
}

lk_status lk__mesh_clean_view(const lk_mesh *mesh, lk_mesh *clean, uint32_t **owned_indices, lk_error *error)
{
    *clean = *mesh;
    *owned_indices = NULL;
    unsigned char *keep = lk__malloc_array(mesh->triangle_count, 1);
    size_t degenerate = 0, duplicate = 0;
    if (!keep || !classify_triangles(mesh, keep, &degenerate, &duplicate)) {
        free(keep);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate triangle table");
    }
    size_t kept = mesh->triangle_count - degenerate - duplicate;
    if (kept < mesh->triangle_count) {
        uint32_t *indices = lk__malloc_array(3 * kept + 1, sizeof(uint32_t));
        if (!indices) {
            free(keep);
            return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the cleaned triangles");
        }
        size_t next = 0;
        for (size_t t = 0; t < mesh->triangle_count; t++)
            if (keep[t]) memcpy(indices + 3 * next++, mesh->indices + 3 * t, 3 * sizeof(uint32_t));
        clean->indices = *owned_indices = indices;
        clean->triangle_count = kept;
    }
    free(keep);
    return LK_OK;
}

lk_status lk_mesh_remove_unused_vertices(lk_mesh *mesh, size_t *removed_count, lk_error *error)
{
    if (removed_count) *removed_count = 0;
    if (mesh->triangle_count == 0) return LK_OK;
    uint32_t *new_index = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
    if (!new_index) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate vertex table");
    for (size_t v = 0; v < mesh->vertex_count; v++) new_index[v] = UINT32_MAX;
    for (size_t c = 0; c < 3 * mesh->triangle_count; c++) new_index[mesh->indices[c]] = 0;
    size_t next = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        if (new_index[v] == UINT32_MAX) continue;
        new_index[v] = (uint32_t)next;
        move_vertex(mesh, next, v);
        next++;
    }
    for (size_t c = 0; c < 3 * mesh->triangle_count; c++) mesh->indices[c] = new_index[mesh->indices[c]];
    free(new_index);
    if (removed_count) *removed_count = mesh->vertex_count - next;
    mesh->vertex_count = next;
    return LK_OK;
}

/* ---- components and statistics ----------------------------------------- */

lk_status lk_mesh_components(const lk_mesh *mesh, uint32_t *component, size_t *component_count, lk_error *error)
{
    *component_count = 0;
    uint32_t *parent = uf_new(mesh->vertex_count);
    uint32_t *label = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
    if (!parent || !label) {
        free(parent);
        free(label);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate component table");
    }
    const uint32_t *indices = mesh->indices;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        uf_union(parent, indices[3 * t], indices[3 * t + 1]);
        uf_union(parent, indices[3 * t], indices[3 * t + 2]);
    }
    for (size_t v = 0; v < mesh->vertex_count; v++) label[v] = UINT32_MAX;
    size_t count = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        uint32_t root = uf_find(parent, indices[3 * t]);
        if (label[root] == UINT32_MAX) label[root] = (uint32_t)count++;
        if (component) component[t] = label[root];
    }
    free(parent);
    free(label);
    *component_count = count;
    return LK_OK;
}

lk_status lk_mesh_compute_stats(const lk_mesh *mesh, lk_mesh_stats *stats, lk_error *error)
{
    memset(stats, 0, sizeof *stats);
    lk_status status = lk_mesh_validate(mesh, error);
    if (status != LK_OK) return status;
    stats->vertex_count = mesh->vertex_count;
    stats->triangle_count = mesh->triangle_count;
    stats->diagonal = lk_mesh_bounds(mesh, stats->min, stats->max);
    stats->area = lk_mesh_area(mesh);

    size_t triangle_count = mesh->triangle_count, corner_count = 3 * triangle_count;
    unsigned char *keep = lk__malloc_array(triangle_count, 1);
    unsigned char *used = lk__calloc_array(mesh->vertex_count, 1);
    unsigned char *vertex_flags = lk__calloc_array(mesh->vertex_count, 1); /* 1: on non-manifold edge, 2: on boundary */
    uint32_t *corner_parent = uf_new(corner_count);
    uint32_t *boundary_parent = uf_new(mesh->vertex_count);
    uint32_t *fans = lk__calloc_array(mesh->vertex_count, sizeof(uint32_t));
    lk_edge_adjacency edges = {0};
    bool ok = keep && used && vertex_flags && corner_parent && boundary_parent && fans &&
              classify_triangles(mesh, keep, &stats->degenerate_triangle_count, &stats->duplicate_triangle_count);
    if (ok) ok = lk_edge_adjacency_build(mesh, &edges, NULL) == LK_OK;
    if (ok) ok = lk_mesh_components(mesh, NULL, &stats->component_count, NULL) == LK_OK;
    if (!ok) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate topology tables");
        goto done;
    }
    for (size_t c = 0; c < corner_count; c++) used[mesh->indices[c]] = 1;
    for (size_t v = 0; v < mesh->vertex_count; v++) stats->used_vertex_count += used[v];
    stats->edge_count = edges.edge_count;
    /* Corners of a vertex are joined across every manifold edge through it;
     * a vertex whose corners form more than one group (fan) is a bowtie. */
    for (size_t e = 0; e < edges.edge_count; e++) {
        uint32_t begin = edges.offsets[e], end = edges.offsets[e + 1];
        uint32_t a = edges.vertices[2 * e], b = edges.vertices[2 * e + 1];
        size_t face_count = end - begin;
        if (face_count == 1) {
            stats->boundary_edge_count++;
            vertex_flags[a] |= 2;
            vertex_flags[b] |= 2;
            uf_union(boundary_parent, a, b);
        } else if (face_count > 2) {
            stats->nonmanifold_edge_count++;
            vertex_flags[a] |= 1;
            vertex_flags[b] |= 1;
        } else {
            uint32_t t1 = edges.triangles[begin], t2 = edges.triangles[begin + 1];
            for (int side = 0; side < 2; side++) {
                uint32_t v = side ? b : a, c1 = UINT32_MAX, c2 = UINT32_MAX;
                for (uint32_t k = 0; k < 3; k++) {
                    if (mesh->indices[3 * t1 + k] == v) c1 = 3 * t1 + k;
                    if (mesh->indices[3 * t2 + k] == v) c2 = 3 * t2 + k;
                }
                if (c1 != UINT32_MAX && c2 != UINT32_MAX) uf_union(corner_parent, c1, c2);
            }
        }
    }
    for (size_t c = 0; c < corner_count; c++)
        if (uf_find(corner_parent, (uint32_t)c) == c) fans[mesh->indices[c]]++;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        if (!used[v]) continue;
        if (fans[v] > 1 || (vertex_flags[v] & 1)) stats->nonmanifold_vertex_count++;
        if ((vertex_flags[v] & 2) && uf_find(boundary_parent, (uint32_t)v) == v) stats->boundary_loop_count++;
    }
    stats->euler_characteristic =
        (long long)stats->used_vertex_count - (long long)stats->edge_count + (long long)triangle_count;
    if (stats->nonmanifold_edge_count || stats->nonmanifold_vertex_count || triangle_count == 0) {
        stats->genus = -1;
    } else {
        long long twice =
            2 * (long long)stats->component_count - stats->euler_characteristic - (long long)stats->boundary_loop_count;
        stats->genus = twice >= 0 && twice % 2 == 0 ? twice / 2 : -1;
    }
done:
    free(keep);
    free(used);
    free(vertex_flags);
    free(corner_parent);
    free(boundary_parent);
    free(fans);
    lk_edge_adjacency_free(&edges);
    return status;
}

/* A triangle with its corners sorted, to find repeats by sorting. */
typedef struct triangle_key {
    uint32_t sorted[3];
    uint32_t triangle;
} triangle_key;

static int compare_triangle_keys(const void *a, const void *b)
{
    const triangle_key *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x->sorted[k] != y->sorted[k]) return x->sorted[k] < y->sorted[k] ? -1 : 1;
    return x->triangle < y->triangle ? -1 : x->triangle > y->triangle;
}

size_t lk__unique_triangles(const lk_mesh *mesh, bool skip_degenerate, uint32_t *out)
{
    size_t triangle_count = mesh->triangle_count;
    triangle_key *keys = lk__malloc_array(triangle_count, sizeof *keys);
    unsigned char *keep = lk__calloc_array(triangle_count ? triangle_count : 1, 1);
    if (!keys || !keep) {
        free(keys), free(keep);
        return SIZE_MAX;
    }
    size_t key_count = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *c = mesh->indices + 3 * t;
        if (skip_degenerate && (c[0] == c[1] || c[1] == c[2] || c[0] == c[2])) continue;
        uint32_t a = c[0], b = c[1], d = c[2], swap;
        if (a > b) swap = a, a = b, b = swap;
        if (b > d) swap = b, b = d, d = swap;
        if (a > b) swap = a, a = b, b = swap;
        keys[key_count++] = (triangle_key){{a, b, d}, (uint32_t)t};
    }
    qsort(keys, key_count, sizeof *keys, compare_triangle_keys);
    for (size_t i = 0; i < key_count; i++)
        if (i == 0 || memcmp(keys[i].sorted, keys[i - 1].sorted, sizeof keys[i].sorted) != 0)
            keep[keys[i].triangle] = 1;
    size_t count = 0;
    for (size_t t = 0; t < triangle_count; t++)
        if (keep[t]) out[count++] = (uint32_t)t;
    free(keys);
    free(keep);
    return count;
}
