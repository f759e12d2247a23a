/* SPDX-License-Identifier: MIT */
/* Vertex clustering simplification.
 *
 * Uniform subdivision (Rossignac & Borrel 1993): cubic cells of side s over
 * the bounding box of the used vertices (origin at its minimum); every
 * occupied cell becomes one vertex placed at the importance-weighted average
 * of its members (attributes are averaged alike, normals renormalised). The
 * quadric-optimal placement is not implemented: the weighted average is
 * Rossignac & Borrel's own choice and never leaves the cell.
 *
 * Floating cells (Low & Tan 1997): vertices are visited by decreasing
 * importance; an unclustered vertex becomes the centre of a ball of
 * diameter s (as wide as the cube of side s) and takes every unclustered
 * vertex inside it; the centre itself, the most important member, is the
 * representative (position and attributes copied).
 *
 * Importance (both methods) follows Low & Tan's refinement of Rossignac &
 * Borrel's weight: longest incident edge length L times cos(theta/2), theta
 * being the largest angle between two incident edges. cos(theta/2) is 0 on
 * a flat vertex (opposite edges) and near 1 at a spike, so silhouette-prone
 * vertices pull the average and win the floating centres. A floor of 0.05
 * keeps flat vertices ordered by L instead of tied at zero (it also gave
 * slightly lower Hausdorff errors than 0 or R-B's L/theta on the bunny and
 * the triceratops).
 *
 * Triangles whose corners land in fewer than three clusters vanish, as do
 * repeats of a cluster triple in any order (the first one's orientation is
 * kept); clusters used by no surviving triangle are dropped, and vertices no
 * triangle used never join a cluster. The result is generally not a
 * manifold: that is inherent in clustering.
 *
 * Targets: options->max_error gives the cell size s directly (fraction of the
 * bounding-box diagonal), so a vertex moves at most s*sqrt(3) (uniform) or
 * s/2 (floating). Cells finer than the model's largest extent / 2^20 are not
 * used (sizes are raised to that). Vertex or triangle targets are met by
 * searching s: bracketing by doubling from sqrt(area / target), then
 * bisection on log s, at most 40 trials; each trial costs O(V + T) with hash
 * tables keyed by cell, so thin models never allocate a dense grid. The
 * count is not monotonic in s, so the best trial is kept: the closest count
 * not above the target when within 2%, else the closest non-empty count,
 * with target_reached = 0. When a count and max_error are both set, the
 * finer of the two cell sizes wins (the first rule reached while
 * coarsening). result->error is the largest distance from a kept vertex to
 * its representative. If every triangle vanishes the result is an empty mesh
 * (no vertices, no triangles, every vertex_map entry UINT32_MAX) with
 * target_reached = 0. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NO_CLUSTER UINT32_MAX
/* Cell coordinates are packed 21 bits per axis in a 64-bit key. */
#define CELL_BITS 21
#define CELL_LIMIT ((int64_t)1 << CELL_BITS)
/* Grid cells are never finer than the largest extent / 2^20 (a millionth of
 * the model is finer than any useful clustering), so coordinates and their
 * +1 neighbours stay below CELL_LIMIT. */
#define FINEST_DIVISIONS 1048576.0
#define IMPORTANCE_FLOOR 0.05
/* Above this many incident edge directions, the largest angle is sought
 * against this many evenly spaced directions only (keeps O(degree)). */
#define ANGLE_PAIRS_LIMIT 64
/* Trials of the cell-size search, and the count tolerance for target_reached. */
#define MAX_TRIALS 40
#define TARGET_TOLERANCE 0.02

typedef enum cluster_method { CLUSTER_UNIFORM, CLUSTER_FLOATING } cluster_method;

typedef struct clusterer {
    const lk_mesh *mesh;
    cluster_method method;
    size_t used_count;   /* vertices referenced by a triangle */
    unsigned char *used; /* per vertex */
    double *importance;  /* per vertex, 0 when unused */
    uint32_t *order;     /* floating: used vertices by decreasing importance */
    double origin[3];    /* bounding-box minimum of the used vertices */
    double extent_max;   /* largest side of that box */
    /* Per-trial workspace, allocated once. */
    size_t cell_table_size; /* power of two >= 2 * used_count */
    uint64_t *cell_keys;
    uint32_t *cell_values;    /* NO_CLUSTER = empty slot */
    uint32_t *vertex_bucket;  /* floating: grid bucket of each used vertex */
    uint64_t *bucket_key;     /* floating: cell key of each bucket */
    uint32_t *bucket_offsets; /* floating: used_count + 1 */
    uint32_t *bucket_vertices;
    uint32_t *cluster_of; /* per vertex */
    uint32_t *centre;     /* per cluster: floating centre / most important member */
    size_t cluster_count;
    size_t triangle_table_size;
    uint32_t *triangle_table;
    uint32_t *triangles; /* cluster triples of the surviving triangles */
    size_t triangle_count;
    uint32_t *cluster_index; /* per cluster: output vertex or NO_CLUSTER */
    size_t vertex_count;     /* clusters used by a surviving triangle */
} clusterer;

static void clusterer_free(clusterer *c)
{
    free(c->used);
    free(c->importance);
    free(c->order);
    free(c->cell_keys);
    free(c->cell_values);
    free(c->vertex_bucket);
    free(c->bucket_key);
    free(c->bucket_offsets);
    free(c->bucket_vertices);
    free(c->cluster_of);
    free(c->centre);
    free(c->triangle_table);
    free(c->triangles);
    free(c->cluster_index);
}

/* ---- importance --------------------------------------------------------- */

/* Fills used[] and importance[] (see the file comment). */
static lk_status compute_importance(clusterer *c, lk_error *error)
{
    const lk_mesh *mesh = c->mesh;
    lk_vertex_adjacency adjacency;
    lk_status status = lk_vertex_adjacency_build(mesh, &adjacency, error);
    if (status != LK_OK) return status;
    size_t max_degree = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        size_t degree = adjacency.offsets[v + 1] - adjacency.offsets[v];
        if (degree > max_degree) max_degree = degree;
    }
    /* Two incident edges per incident triangle (interior edges appear twice,
     * which does not change the largest angle). */
    double *directions = lk__malloc_array(2 * max_degree, 3 * sizeof(double));
    if (!directions) {
        lk_vertex_adjacency_free(&adjacency);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering weights");
    }
    const float *positions = mesh->positions;
    c->used_count = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        uint32_t begin = adjacency.offsets[v], end = adjacency.offsets[v + 1];
        c->used[v] = begin < end;
        c->importance[v] = 0;
        if (begin == end) continue;
        c->used_count++;
        const float *p = positions + 3 * v;
        double longest = 0;
        size_t direction_count = 0;
        for (uint32_t i = begin; i < end; i++) {
            const uint32_t *corners = mesh->indices + 3 * (size_t)adjacency.triangles[i];
            for (int k = 0; k < 3; k++) {
                if (corners[k] == v) continue;
                const float *q = positions + 3 * (size_t)corners[k];
                double d[3] = {(double)q[0] - p[0], (double)q[1] - p[1], (double)q[2] - p[2]};
                double length = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                if (length > longest) longest = length;
                if (length <= 0) continue;
                double *unit = directions + 3 * direction_count++;
                for (int a = 0; a < 3; a++) unit[a] = d[a] / length;
            }
        }
        double min_dot = 1;
        size_t stride = direction_count > ANGLE_PAIRS_LIMIT ? direction_count / ANGLE_PAIRS_LIMIT : 1;
        for (size_t i = 0; i < direction_count; i++) {
            const double *a = directions + 3 * i;
            for (size_t j = stride > 1 ? 0 : i + 1; j < direction_count; j += stride) {
                const double *b = directions + 3 * j;
                double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
                if (dot < min_dot) min_dot = dot;
            }
        }
        if (min_dot < -1) min_dot = -1;
        double half_angle_cosine = sqrt((1 + min_dot) / 2); /* cos(theta / 2) */
        c->importance[v] = longest * (half_angle_cosine + IMPORTANCE_FLOOR);
    }
    free(directions);
    lk_vertex_adjacency_free(&adjacency);
    return LK_OK;
}

typedef struct ranked_vertex {
    double importance;
    uint32_t vertex;
} ranked_vertex;

/* Decreasing importance, then increasing index: a total, deterministic order. */
static int compare_ranked(const void *pa, const void *pb)
{
    const ranked_vertex *a = pa, *b = pb;
    if (a->importance != b->importance) return a->importance > b->importance ? -1 : 1;
    return (a->vertex > b->vertex) - (a->vertex < b->vertex);
}

static lk_status sort_by_importance(clusterer *c, lk_error *error)
{
    ranked_vertex *ranked = lk__malloc_array(c->used_count, sizeof *ranked);
    if (!ranked) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering order");
    size_t next = 0;
    for (size_t v = 0; v < c->mesh->vertex_count; v++)
        if (c->used[v]) ranked[next++] = (ranked_vertex){c->importance[v], (uint32_t)v};
    qsort(ranked, c->used_count, sizeof *ranked, compare_ranked);
    for (size_t i = 0; i < c->used_count; i++) c->order[i] = ranked[i].vertex;
    free(ranked);
    return LK_OK;
}

/* ---- one clustering trial ----------------------------------------------- */

static uint64_t cell_key(const clusterer *c, const float *p, double inverse_size)
{
    uint64_t key = 0;
    for (int k = 0; k < 3; k++) {
        double coordinate = floor(((double)p[k] - c->origin[k]) * inverse_size);
        if (coordinate < 0) coordinate = 0; /* rounding at the box minimum */
        if (coordinate > CELL_LIMIT - 2) coordinate = CELL_LIMIT - 2;
        key |= (uint64_t)coordinate << (CELL_BITS * k);
    }
    return key;
}

/* Slot of `key` in the cell table: its own, or the empty one to fill. */
static size_t cell_slot(const clusterer *c, uint64_t key)
{
    size_t mask = c->cell_table_size - 1;
    size_t slot = lk__mix64(key) & mask;
    while (c->cell_values[slot] != NO_CLUSTER && c->cell_keys[slot] != key) slot = (slot + 1) & mask;
    return slot;
}

/* Cell id of `key`, numbering new cells from *count. */
static uint32_t cell_insert(clusterer *c, uint64_t key, size_t *count)
{
    size_t slot = cell_slot(c, key);
    if (c->cell_values[slot] == NO_CLUSTER) {
        c->cell_keys[slot] = key;
        c->cell_values[slot] = (uint32_t)(*count)++;
    }
    return c->cell_values[slot];
}

static void reset_cells(clusterer *c) { memset(c->cell_values, 0xFF, c->cell_table_size * sizeof(uint32_t)); }

/* Cell size 0: every used vertex is its own cluster (the input itself). */
static void assign_identity(clusterer *c)
{
    c->cluster_count = 0;
    for (size_t v = 0; v < c->mesh->vertex_count; v++) {
        c->cluster_of[v] = NO_CLUSTER;
        if (!c->used[v]) continue;
        c->centre[c->cluster_count] = (uint32_t)v;
        c->cluster_of[v] = (uint32_t)c->cluster_count++;
    }
}

static void assign_uniform(clusterer *c, double cell_size)
{
    reset_cells(c);
    double inverse_size = 1.0 / cell_size;
    size_t count = 0;
    for (size_t v = 0; v < c->mesh->vertex_count; v++) {
        c->cluster_of[v] = NO_CLUSTER;
        if (!c->used[v]) continue;
        size_t before = count;
        uint32_t id = cell_insert(c, cell_key(c, c->mesh->positions + 3 * v, inverse_size), &count);
        c->cluster_of[v] = id;
        if (count != before || c->importance[v] > c->importance[c->centre[id]]) c->centre[id] = (uint32_t)v;
    }
    c->cluster_count = count;
}

static void assign_floating(clusterer *c, double cell_size)
{
    const float *positions = c->mesh->positions;
    double radius = cell_size / 2, radius_squared = radius * radius;
    double inverse_size = 1.0 / radius; /* grid of side = radius: neighbours lie in the 27 cells around */
    /* Bucket the used vertices by grid cell (counting sort, vertex order kept). */
    reset_cells(c);
    size_t bucket_count = 0;
    for (size_t v = 0; v < c->mesh->vertex_count; v++) {
        c->cluster_of[v] = NO_CLUSTER;
        if (!c->used[v]) continue;
        uint64_t key = cell_key(c, positions + 3 * v, inverse_size);
        size_t before = bucket_count;
        uint32_t bucket = cell_insert(c, key, &bucket_count);
        if (bucket_count != before) {
            c->bucket_key[bucket] = key;
            c->bucket_offsets[bucket + 1] = 0;
        }
        c->vertex_bucket[v] = bucket;
        c->bucket_offsets[bucket + 1]++;
    }
    c->bucket_offsets[0] = 0;
    for (size_t b = 0; b < bucket_count; b++) c->bucket_offsets[b + 1] += c->bucket_offsets[b];
    for (size_t v = 0; v < c->mesh->vertex_count; v++)
        if (c->used[v]) c->bucket_vertices[c->bucket_offsets[c->vertex_bucket[v]]++] = (uint32_t)v;
    for (size_t b = bucket_count; b > 0; b--) c->bucket_offsets[b] = c->bucket_offsets[b - 1];
    c->bucket_offsets[0] = 0;

    size_t count = 0;
    for (size_t i = 0; i < c->used_count; i++) {
        uint32_t centre = c->order[i];
        if (c->cluster_of[centre] != NO_CLUSTER) continue;
        uint32_t id = (uint32_t)count++;
        c->centre[id] = centre;
        c->cluster_of[centre] = id;
        const float *p = positions + 3 * (size_t)centre;
        uint64_t key = c->bucket_key[c->vertex_bucket[centre]];
        int64_t cx = (int64_t)(key & (CELL_LIMIT - 1)), cy = (int64_t)((key >> CELL_BITS) & (CELL_LIMIT - 1)),
                cz = (int64_t)(key >> (2 * CELL_BITS));
        for (int64_t x = cx - 1; x <= cx + 1; x++)
            for (int64_t y = cy - 1; y <= cy + 1; y++)
                for (int64_t z = cz - 1; z <= cz + 1; z++) {
                    if (x < 0 || y < 0 || z < 0) continue;
                    uint64_t neighbour = (uint64_t)x | (uint64_t)y << CELL_BITS | (uint64_t)z << (2 * CELL_BITS);
                    size_t slot = cell_slot(c, neighbour);
                    if (c->cell_values[slot] == NO_CLUSTER) continue;
                    uint32_t bucket = c->cell_values[slot];
                    for (uint32_t j = c->bucket_offsets[bucket]; j < c->bucket_offsets[bucket + 1]; j++) {
                        uint32_t u = c->bucket_vertices[j];
                        if (c->cluster_of[u] != NO_CLUSTER) continue;
                        const float *q = positions + 3 * (size_t)u;
                        double d0 = (double)q[0] - p[0], d1 = (double)q[1] - p[1], d2 = (double)q[2] - p[2];
                        if (d0 * d0 + d1 * d1 + d2 * d2 <= radius_squared) c->cluster_of[u] = id;
                    }
                }
    }
    c->cluster_count = count;
}

static void sort3(uint32_t v[3])
{
    uint32_t s;
    if (v[0] > v[1]) s = v[0], v[0] = v[1], v[1] = s;
    if (v[1] > v[2]) s = v[1], v[1] = v[2], v[2] = s;
    if (v[0] > v[1]) s = v[0], v[0] = v[1], v[1] = s;
}

/* Maps the triangles to clusters, keeping the first of each cluster triple
 * that has three distinct clusters, and numbers the clusters they use. */
static void collect_triangles(clusterer *c)
{
    const lk_mesh *mesh = c->mesh;
    size_t mask = c->triangle_table_size - 1;
    memset(c->triangle_table, 0xFF, c->triangle_table_size * sizeof(uint32_t));
    size_t count = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        uint32_t triple[3];
        for (int k = 0; k < 3; k++) triple[k] = c->cluster_of[mesh->indices[3 * t + k]];
        if (triple[0] == triple[1] || triple[1] == triple[2] || triple[0] == triple[2]) continue;
        uint32_t sorted[3] = {triple[0], triple[1], triple[2]};
        sort3(sorted);
        uint64_t hash = lk__mix64(((uint64_t)sorted[0] << 32 | sorted[1]) ^ lk__mix64(sorted[2]));
        bool duplicate = false;
        size_t slot = hash & mask;
        for (; c->triangle_table[slot] != NO_CLUSTER; slot = (slot + 1) & mask) {
            const uint32_t *kept = c->triangles + 3 * (size_t)c->triangle_table[slot];
            uint32_t other[3] = {kept[0], kept[1], kept[2]};
            sort3(other);
            if (other[0] == sorted[0] && other[1] == sorted[1] && other[2] == sorted[2]) {
                duplicate = true;
                break;
            }
        }
        if (duplicate) continue;
        c->triangle_table[slot] = (uint32_t)count;
        memcpy(c->triangles + 3 * count, triple, sizeof triple);
        count++;
    }
    c->triangle_count = count;
    for (size_t k = 0; k < c->cluster_count; k++) c->cluster_index[k] = NO_CLUSTER;
    for (size_t i = 0; i < 3 * count; i++) c->cluster_index[c->triangles[i]] = 0;
    c->vertex_count = 0;
    for (size_t k = 0; k < c->cluster_count; k++)
        if (c->cluster_index[k] != NO_CLUSTER) c->cluster_index[k] = (uint32_t)c->vertex_count++;
}

/* One trial: clusters, surviving triangles and output counts for a cell size
 * in model units (0 = no clustering). */
static void run_trial(clusterer *c, double cell_size)
{
    if (cell_size <= 0)
        assign_identity(c);
    else if (c->method == CLUSTER_UNIFORM)
        assign_uniform(c, cell_size);
    else
        assign_floating(c, cell_size);
    collect_triangles(c);
}

/* ---- output ------------------------------------------------------------- */

static void normalize3(float *n)
{
    double length = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    if (length > 0)
        for (int k = 0; k < 3; k++) n[k] = (float)(n[k] / length);
}

/* Builds result->mesh, vertex_map and error from the last trial. */
static lk_status build_output(const clusterer *c, lk_simplify_result *result, lk_error *error)
{
    const lk_mesh *mesh = c->mesh;
    unsigned flags = (mesh->normals ? LK_ATTR_NORMALS : 0) | (mesh->texcoords ? LK_ATTR_TEXCOORDS : 0) |
                     (mesh->colors ? LK_ATTR_COLORS : 0);
    lk_status status = lk_mesh_alloc(&result->mesh, c->vertex_count, c->triangle_count, flags, error);
    if (status != LK_OK) return status;
    result->vertex_map = lk__malloc_array(mesh->vertex_count, sizeof(uint32_t));
    if (!result->vertex_map) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the vertex map");
    lk_mesh *out = &result->mesh;
    for (size_t v = 0; v < mesh->vertex_count; v++)
        result->vertex_map[v] = c->cluster_of[v] == NO_CLUSTER ? NO_CLUSTER : c->cluster_index[c->cluster_of[v]];
    for (size_t i = 0; i < 3 * c->triangle_count; i++) out->indices[i] = c->cluster_index[c->triangles[i]];

    /* Start every output vertex as a copy of its cluster's centre: final for
     * floating cells, and the fall-back for degenerate averages. */
    for (size_t k = 0; k < c->cluster_count; k++) {
        uint32_t o = c->cluster_index[k], centre = c->centre[k];
        if (o == NO_CLUSTER) continue;
        memcpy(out->positions + 3 * (size_t)o, mesh->positions + 3 * (size_t)centre, 3 * sizeof(float));
        if (out->normals) memcpy(out->normals + 3 * (size_t)o, mesh->normals + 3 * (size_t)centre, 3 * sizeof(float));
        if (out->texcoords)
            memcpy(out->texcoords + 2 * (size_t)o, mesh->texcoords + 2 * (size_t)centre, 2 * sizeof(float));
        if (out->colors) memcpy(out->colors + 4 * (size_t)o, mesh->colors + 4 * (size_t)centre, 4 * sizeof(float));
    }
    if (c->method == CLUSTER_UNIFORM && c->vertex_count > 0) {
        /* Weighted averages of every attribute: 1 weight, 3 position,
         * 3 normal, 2 texcoord, 4 colour sums per output vertex. */
        enum { W = 0, P = 1, N = 4, UV = 7, RGBA = 9, STRIDE = 13 };
        double *sums = lk__calloc_array(c->vertex_count, STRIDE * sizeof(double));
        size_t *member_counts = lk__calloc_array(c->vertex_count, sizeof(size_t));
        if (!sums || !member_counts) {
            free(sums);
            free(member_counts);
            return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate cluster averages");
        }
        for (size_t v = 0; v < mesh->vertex_count; v++) {
            uint32_t o = result->vertex_map[v];
            if (o == NO_CLUSTER) continue;
            sums[STRIDE * o + W] += c->importance[v];
            member_counts[o]++;
        }
        for (size_t v = 0; v < mesh->vertex_count; v++) {
            uint32_t o = result->vertex_map[v];
            if (o == NO_CLUSTER || member_counts[o] < 2) continue;
            /* A cluster of zero total weight (coincident points) averages evenly. */
            double weight = sums[STRIDE * o + W] > 0 ? c->importance[v] : 1.0;
            double *sum = sums + STRIDE * o;
            for (int k = 0; k < 3; k++) sum[P + k] += weight * mesh->positions[3 * v + k];
            if (mesh->normals)
                for (int k = 0; k < 3; k++) sum[N + k] += weight * mesh->normals[3 * v + k];
            if (mesh->texcoords)
                for (int k = 0; k < 2; k++) sum[UV + k] += weight * mesh->texcoords[2 * v + k];
            if (mesh->colors)
                for (int k = 0; k < 4; k++) sum[RGBA + k] += weight * mesh->colors[4 * v + k];
        }
        for (size_t o = 0; o < c->vertex_count; o++) {
            if (member_counts[o] < 2) continue; /* single member: exact copy already */
            const double *sum = sums + STRIDE * o;
            double total = sum[W] > 0 ? sum[W] : (double)member_counts[o];
            for (int k = 0; k < 3; k++) out->positions[3 * o + k] = (float)(sum[P + k] / total);
            if (out->normals) {
                float averaged[3];
                for (int k = 0; k < 3; k++) averaged[k] = (float)(sum[N + k] / total);
                /* Opposite normals can cancel: keep the centre's then. */
                if (averaged[0] != 0 || averaged[1] != 0 || averaged[2] != 0) {
                    normalize3(averaged);
                    memcpy(out->normals + 3 * o, averaged, sizeof averaged);
                }
            }
            if (out->texcoords)
                for (int k = 0; k < 2; k++) out->texcoords[2 * o + k] = (float)(sum[UV + k] / total);
            if (out->colors)
                for (int k = 0; k < 4; k++) out->colors[4 * o + k] = (float)(sum[RGBA + k] / total);
        }
        free(sums);
        free(member_counts);
    }
    double largest = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        uint32_t o = result->vertex_map[v];
        if (o == NO_CLUSTER) continue;
        const float *p = mesh->positions + 3 * v, *q = out->positions + 3 * (size_t)o;
        double d0 = (double)p[0] - q[0], d1 = (double)p[1] - q[1], d2 = (double)p[2] - q[2];
        double distance = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
        if (distance > largest) largest = distance;
    }
    result->error = largest;
    return LK_OK;
}

/* ---- setup -------------------------------------------------------------- */

static lk_status clusterer_init(clusterer *c, const lk_mesh *mesh, cluster_method method, lk_error *error)
{
    memset(c, 0, sizeof *c);
    c->mesh = mesh;
    c->method = method;
    size_t vertex_count = mesh->vertex_count, triangle_count = mesh->triangle_count;
    c->used = lk__malloc_array(vertex_count, 1);
    c->importance = lk__malloc_array(vertex_count, sizeof(double));
    c->cluster_of = lk__malloc_array(vertex_count, sizeof(uint32_t));
    c->triangles = lk__malloc_array(triangle_count, 3 * sizeof(uint32_t));
    c->triangle_table_size = 16;
    while (c->triangle_table_size < 2 * triangle_count) c->triangle_table_size *= 2;
    c->triangle_table = lk__malloc_array(c->triangle_table_size, sizeof(uint32_t));
    if (!c->used || !c->importance || !c->cluster_of || !c->triangles || !c->triangle_table)
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering tables");
    lk_status status = compute_importance(c, error);
    if (status != LK_OK) return status;

    size_t used_count = c->used_count;
    c->cell_table_size = 16;
    while (c->cell_table_size < 2 * used_count) c->cell_table_size *= 2;
    c->cell_keys = lk__malloc_array(c->cell_table_size, sizeof(uint64_t));
    c->cell_values = lk__malloc_array(c->cell_table_size, sizeof(uint32_t));
    c->centre = lk__malloc_array(used_count, sizeof(uint32_t));
    c->cluster_index = lk__malloc_array(used_count, sizeof(uint32_t));
    bool ok = c->cell_keys && c->cell_values && c->centre && c->cluster_index;
    if (ok && method == CLUSTER_FLOATING) {
        c->order = lk__malloc_array(used_count, sizeof(uint32_t));
        c->vertex_bucket = lk__malloc_array(vertex_count, sizeof(uint32_t));
        c->bucket_key = lk__malloc_array(used_count, sizeof(uint64_t));
        c->bucket_offsets = lk__malloc_array(used_count + 1, sizeof(uint32_t));
        c->bucket_vertices = lk__malloc_array(used_count, sizeof(uint32_t));
        ok = c->order && c->vertex_bucket && c->bucket_key && c->bucket_offsets && c->bucket_vertices;
    }
    if (!ok) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering tables");
    if (method == CLUSTER_FLOATING) {
        status = sort_by_importance(c, error);
        if (status != LK_OK) return status;
    }

    double low[3] = {INFINITY, INFINITY, INFINITY}, high[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < vertex_count; v++) {
        if (!c->used[v]) continue;
        for (int k = 0; k < 3; k++) {
            double x = mesh->positions[3 * v + k];
            if (x < low[k]) low[k] = x;
            if (x > high[k]) high[k] = x;
        }
    }
    c->extent_max = 0;
    for (int k = 0; k < 3; k++) {
        c->origin[k] = low[k];
        if (high[k] - low[k] > c->extent_max) c->extent_max = high[k] - low[k];
    }
    return LK_OK;
}

/* ---- cell-size search ---------------------------------------------------- */

/* Smallest cell size the packed grid keys can hold (floating cells search a
 * grid of half the cell size). */
static double finest_size(const clusterer *c)
{
    if (!(c->extent_max > 0)) return 1.0; /* all points coincide: any size is one cell */
    return (c->method == CLUSTER_FLOATING ? 2 : 1) * c->extent_max / FINEST_DIVISIONS;
}

typedef struct count_targets {
    size_t vertices;  /* 0 = unset */
    size_t triangles; /* 0 = unset */
} count_targets;

/* Relative excess of the nearest count target: <= 0 once one is reached. */
static double target_score(const clusterer *c, const count_targets *targets)
{
    double score = INFINITY;
    if (targets->vertices)
        score = fmin(score, ((double)c->vertex_count - (double)targets->vertices) / (double)targets->vertices);
    if (targets->triangles)
        score = fmin(score, ((double)c->triangle_count - (double)targets->triangles) / (double)targets->triangles);
    return score;
}

typedef struct search_state {
    clusterer *c;
    const count_targets *targets;
    lk_progress_fn progress;
    void *progress_user;
    int trials;
    /* Best trial at or under the target (largest score <= 0), and best
     * non-empty trial overall (smallest |score|). */
    double under_size, under_score;
    double closest_size, closest_score;
    bool have_under, have_closest;
} search_state;

/* Runs a trial at `cell_size`, records it, reports progress; *score gets
 * its target score. */
static lk_status try_size(search_state *s, double cell_size, double *score, lk_error *error)
{
    run_trial(s->c, cell_size);
    s->trials++;
    *score = target_score(s->c, s->targets);
    if (*score <= 0 && (!s->have_under || *score > s->under_score)) {
        s->under_size = cell_size, s->under_score = *score;
        s->have_under = true;
    }
    if (s->c->triangle_count > 0 && (!s->have_closest || fabs(*score) < fabs(s->closest_score) ||
                                     (fabs(*score) == fabs(s->closest_score) && *score <= 0))) {
        s->closest_size = cell_size, s->closest_score = *score;
        s->have_closest = true;
    }
    if (s->progress && s->progress(s->progress_user, (double)s->trials / MAX_TRIALS, "clustering"))
        return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    return LK_OK;
}

/* Finds the cell size for the count targets, never coarser than
 * max_size (INFINITY when unset). Sets *cell_size and *reached. */
static lk_status search_cell_size(search_state *s, double area, double max_size, double *cell_size, int *reached,
                                  lk_error *error)
{
    clusterer *c = s->c;
    double finest = finest_size(c);
    double score;
    /* The input may already meet the target. */
    lk_status status = try_size(s, 0, &score, error);
    if (status != LK_OK) return status;
    if (score <= 0) {
        *cell_size = 0, *reached = 1;
        return LK_OK;
    }
    double fine = 0, coarse; /* fine: target not reached; coarse: reached */
    if (isfinite(max_size)) {
        if (max_size < finest) max_size = finest;
        status = try_size(s, max_size, &score, error);
        if (status != LK_OK) return status;
        if (score > 0) { /* the error bound stops first */
            *cell_size = max_size;
            *reached = c->triangle_count > 0;
            return LK_OK;
        }
        coarse = max_size;
    } else {
        /* A surface of area A in cells of side s occupies about A / s^2 cells. */
        double wanted = s->targets->vertices ? (double)s->targets->vertices : (double)s->targets->triangles / 2;
        double size = sqrt(area / fmax(wanted, 1));
        if (!(size >= finest)) size = finest;
        if (size > 4 * c->extent_max && c->extent_max > 0) size = 4 * c->extent_max;
        status = try_size(s, size, &score, error);
        if (status != LK_OK) return status;
        /* Grow until reached: beyond the model's size every vertex shares
         * one cell and no triangle is left, which meets any count. */
        while (score > 0 && s->trials < MAX_TRIALS) {
            fine = size;
            size *= 2;
            status = try_size(s, size, &score, error);
            if (status != LK_OK) return status;
        }
        coarse = size;
    }
    if (fine == 0) {
        /* Shrink until not reached (or the finest grid). */
        double size = coarse;
        while (s->trials < MAX_TRIALS && size > finest) {
            size = fmax(size / 2, finest);
            status = try_size(s, size, &score, error);
            if (status != LK_OK) return status;
            if (score > 0) {
                fine = size;
                break;
            }
            coarse = size;
        }
    }
    /* Bisect on log(size) between a not-reached and a reached size. */
    while (fine > 0 && s->trials < MAX_TRIALS && coarse > fine * (1 + 1e-7) &&
           !(s->have_under && s->under_score == 0)) {
        double middle = sqrt(fine * coarse);
        status = try_size(s, middle, &score, error);
        if (status != LK_OK) return status;
        if (score > 0)
            fine = middle;
        else
            coarse = middle;
    }
    /* Closest without exceeding when within tolerance, else closest at all. */
    if (s->have_under && (-s->under_score <= TARGET_TOLERANCE || !s->have_closest)) {
        *cell_size = s->under_size;
        *reached = -s->under_score <= TARGET_TOLERANCE;
    } else if (s->have_closest) {
        *cell_size = s->closest_size;
        *reached = fabs(s->closest_score) <= TARGET_TOLERANCE;
    } else {
        *cell_size = coarse;
        *reached = 0;
    }
    return LK_OK;
}

static lk_status simplify_clustering(const lk_mesh *mesh, cluster_method method, const lk_simplify_options *options,
                                     lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                     lk_error *error)
{
    clusterer c;
    lk_status status = clusterer_init(&c, mesh, method, error);
    if (status != LK_OK) {
        clusterer_free(&c);
        return status;
    }
    count_targets targets = {options->target_vertices, options->target_triangles};
    if (options->target_ratio > 0) {
        double ratio_triangles = options->target_ratio * (double)mesh->triangle_count;
        size_t from_ratio = ratio_triangles < 1 ? 1 : (size_t)llround(ratio_triangles);
        /* Two triangle rules: the larger count is reached first. */
        if (from_ratio > targets.triangles) targets.triangles = from_ratio;
    }
    double max_size = options->max_error > 0 ? options->max_error * result->diagonal : INFINITY;
    double cell_size;
    int reached;
    if (targets.vertices == 0 && targets.triangles == 0) {
        cell_size = max_size > 0 && max_size < finest_size(&c) ? finest_size(&c) : max_size;
        run_trial(&c, cell_size);
        reached = c.triangle_count > 0;
        if (progress && progress(progress_user, 1.0, "clustering"))
            status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
    } else {
        search_state search = {.c = &c, .targets = &targets, .progress = progress, .progress_user = progress_user};
        status = search_cell_size(&search, lk_mesh_area(mesh), max_size, &cell_size, &reached, error);
        if (status == LK_OK) run_trial(&c, cell_size);
    }
    if (status == LK_OK) status = build_output(&c, result, error);
    if (status == LK_OK) result->target_reached = reached && c.triangle_count > 0;
    clusterer_free(&c);
    return status;
}

lk_status lk__simplify_uniform(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                               lk_progress_fn progress, void *progress_user, lk_error *error)
{
    return simplify_clustering(mesh, CLUSTER_UNIFORM, options, result, progress, progress_user, error);
}

lk_status lk__simplify_floating(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                                lk_progress_fn progress, void *progress_user, lk_error *error)
{
    return simplify_clustering(mesh, CLUSTER_FLOATING, options, result, progress, progress_user, error);
}
