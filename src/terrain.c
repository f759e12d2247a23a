/* SPDX-License-Identifier: MIT */
/* Terrain continuous LOD: Röttger's quadtree over a (2^n + 1)^2 grid, the
 * d2 roughness with an upward propagation that bounds the level difference
 * of neighbours, triangle fans, view-frustum culling, geomorphing and the
 * crack elimination of Ju & Kim (see include/lodkit.h, "Terrain continuous
 * LOD", for the rules of each crack mode).
 *
 * Storage. Nodes live in per-level arrays: level k holds 2^k x 2^k nodes,
 * node (a, b) has half size r = 2^(levels-1-k) and its centre at grid
 * index ((2a+1) r, (2b+1) r). Per-frame state (f of every evaluated node, the
 * morphed height of every grid vertex, the mesh vertex of every grid point)
 * is tagged with a frame number instead of being cleared, so an update only
 * touches what it visits. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TERRAIN_MAX_LEVELS 24
#define TERRAIN_PI 3.14159265358979323846

/* Everything an update reads or writes about one node or one grid point
 * sits together: one cache miss each instead of one per array. */
typedef struct terrain_node {
    float d2; /* propagated roughness */
    float f;  /* this frame's f when stamp == frame */
    uint32_t stamp;
    float centre_height; /* true height of the centre sample (for l) */
} terrain_node;

/* stamp == frame: the point has a record this frame: its FULL-mode height
 * z (computed before the point is emitted) and its mesh vertex (UINT32_MAX
 * until emitted). */
typedef struct terrain_vertex {
    float height; /* true height */
    float z;
    uint32_t stamp;
    uint32_t mesh_index;
} terrain_vertex;

typedef struct terrain_leaf {
    uint32_t a, b;
    uint32_t level;
} terrain_leaf;

struct lk_terrain {
    lk_terrain_options options;
    size_t size;          /* samples per side */
    unsigned levels;      /* node levels */
    terrain_vertex *grid; /* size * size, row-major */
    double spacing_x, spacing_y, origin_x, origin_y;
    double node_spacing; /* metres per sample used for the node size d */
    double min_height, max_height;
    size_t node_count;
    size_t level_offset[TERRAIN_MAX_LEVELS + 1];
    terrain_node *nodes;
    float *ranges; /* zmin, zmax per node, for culling */

    /* per frame */
    uint32_t frame;

    terrain_leaf *leaves;
    size_t leaf_count, leaf_capacity;
    lk_terrain_leaf *public_leaves;
    size_t public_leaf_capacity;

    float *positions; /* output being built */
    uint32_t *indices;
    size_t position_capacity, index_capacity; /* in vertices, in triangles */
    size_t vertex_count, triangle_count;

    double planes[4][4]; /* frustum: inside when n . p + w >= 0 */
    double eye[3];
    size_t culled, visited, morphing, evaluated;
    int failed;
};

/* ---- options ----------------------------------------------------------- */

void lk_terrain_options_default(lk_terrain_options *options)
{
    if (!options) return;
    memset(options, 0, sizeof *options);
    options->resolution = 8.0;
    options->error_scale = 50.0;
    options->morph = 1;
    options->cracks = LK_TERRAIN_CRACKS_FULL;
    options->culling = 1;
    options->blend_override = -1.0;
    options->max_samples = (size_t)1 << 26;
}

const char *lk_terrain_cracks_name(lk_terrain_cracks mode)
{
    switch (mode) {
    case LK_TERRAIN_CRACKS_NONE: return "none";
    case LK_TERRAIN_CRACKS_MIDPOINT: return "midpoint";
    case LK_TERRAIN_CRACKS_PAPER: return "paper";
    case LK_TERRAIN_CRACKS_FULL: return "full";
    }
    return "unknown";
}

static lk_status check_options(const lk_terrain_options *options, lk_error *error)
{
    if (!(options->resolution > 0) || !isfinite(options->resolution))
        return lk_error_set(error, LK_ERR_INVALID, "terrain: resolution C must be a positive number (got %g)",
                            options->resolution);
    if (!(options->error_scale > 0) || !isfinite(options->error_scale))
        return lk_error_set(error, LK_ERR_INVALID, "terrain: error scale c must be a positive number (got %g)",
                            options->error_scale);
    if ((int)options->cracks < LK_TERRAIN_CRACKS_NONE || (int)options->cracks > LK_TERRAIN_CRACKS_FULL)
        return lk_error_set(error, LK_ERR_INVALID, "terrain: unknown crack mode %d", (int)options->cracks);
    if (isnan(options->blend_override) || options->blend_override > 1)
        return lk_error_set(error, LK_ERR_INVALID, "terrain: blend_override must be in [0,1] or negative (got %g)",
                            options->blend_override);
    if (options->max_samples == 0) return lk_error_set(error, LK_ERR_INVALID, "terrain: max_samples must be > 0");
    return LK_OK;
}

/* ---- node addressing ---------------------------------------------------- */

static inline uint32_t half_size(const lk_terrain *t, unsigned level) { return 1u << (t->levels - 1 - level); }

/* Spreads the bits of x apart (bit k goes to bit 2k). */
static inline uint64_t spread_bits(uint32_t x)
{
    uint64_t v = x;
    v = (v | (v << 16)) & 0x0000FFFF0000FFFFull;
    v = (v | (v << 8)) & 0x00FF00FF00FF00FFull;
    v = (v | (v << 4)) & 0x0F0F0F0F0F0F0F0Full;
    v = (v | (v << 2)) & 0x3333333333333333ull;
    v = (v | (v << 1)) & 0x5555555555555555ull;
    return v;
}

/* Nodes of a level are stored in Morton (Z) order, so that a node's
 * neighbours and its parent's neighbours, which the fans and the morphing
 * look up, are mostly close in memory. */
static inline size_t node_id(const lk_terrain *t, unsigned level, uint32_t a, uint32_t b)
{
    return t->level_offset[level] + (size_t)(spread_bits(a) | (spread_bits(b) << 1));
}

static inline float height_at(const lk_terrain *t, uint32_t i, uint32_t j)
{
    return t->grid[(size_t)j * t->size + i].height;
}

static inline double grid_x(const lk_terrain *t, uint32_t i) { return t->origin_x + (double)i * t->spacing_x; }
static inline double grid_y(const lk_terrain *t, uint32_t j) { return t->origin_y + (double)j * t->spacing_y; }

/* Euclidean distance between the centre samples of two nodes (3-D). */
static double centre_distance(const lk_terrain *t, unsigned level_a, uint32_t a0, uint32_t b0, unsigned level_b,
                              uint32_t a1, uint32_t b1)
{
    uint32_t r0 = half_size(t, level_a), r1 = half_size(t, level_b);
    uint32_t i0 = (2 * a0 + 1) * r0, j0 = (2 * b0 + 1) * r0;
    uint32_t i1 = (2 * a1 + 1) * r1, j1 = (2 * b1 + 1) * r1;
    double dx = ((double)i1 - (double)i0) * t->spacing_x;
    double dy = ((double)j1 - (double)j0) * t->spacing_y;
    double dz = (double)height_at(t, i1, j1) - (double)height_at(t, i0, j0);
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* ---- creation: d2, height ranges, propagation ---------------------------- */

static void compute_local_d2(lk_terrain *t)
{
    for (unsigned level = 0; level < t->levels; level++) {
        uint32_t r = half_size(t, level), count = 1u << level;
        double d = 2.0 * r * t->node_spacing;
        for (uint32_t b = 0; b < count; b++)
            for (uint32_t a = 0; a < count; a++) {
                uint32_t i = (2 * a + 1) * r, j = (2 * b + 1) * r;
                double sw = height_at(t, i - r, j - r), se = height_at(t, i + r, j - r);
                double nw = height_at(t, i - r, j + r), ne = height_at(t, i + r, j + r);
                double centre = height_at(t, i, j);
                double e = fabs(height_at(t, i, j - r) - 0.5 * (sw + se));
                e = fmax(e, fabs(height_at(t, i, j + r) - 0.5 * (nw + ne)));
                e = fmax(e, fabs(height_at(t, i - r, j) - 0.5 * (sw + nw)));
                e = fmax(e, fabs(height_at(t, i + r, j) - 0.5 * (se + ne)));
                e = fmax(e, fabs(centre - 0.5 * (sw + ne)));
                e = fmax(e, fabs(centre - 0.5 * (se + nw)));
                t->nodes[node_id(t, level, a, b)].d2 = (float)(e / d);
                t->nodes[node_id(t, level, a, b)].centre_height = (float)centre;
            }
    }
}

static void compute_ranges(lk_terrain *t)
{
    unsigned finest = t->levels - 1;
    uint32_t count = 1u << finest;
    for (uint32_t b = 0; b < count; b++)
        for (uint32_t a = 0; a < count; a++) {
            uint32_t i = 2 * a + 1, j = 2 * b + 1;
            float lo = INFINITY, hi = -INFINITY;
            for (uint32_t y = j - 1; y <= j + 1; y++)
                for (uint32_t x = i - 1; x <= i + 1; x++) {
                    float h = height_at(t, x, y);
                    lo = h < lo ? h : lo;
                    hi = h > hi ? h : hi;
                }
            size_t id = node_id(t, finest, a, b);
            t->ranges[2 * id] = lo;
            t->ranges[2 * id + 1] = hi;
        }
    for (unsigned level = finest; level-- > 0;) {
        count = 1u << level;
        for (uint32_t b = 0; b < count; b++)
            for (uint32_t a = 0; a < count; a++) {
                float lo = INFINITY, hi = -INFINITY;
                for (uint32_t q = 0; q < 4; q++) {
                    size_t child = node_id(t, level + 1, 2 * a + (q & 1), 2 * b + (q >> 1));
                    lo = t->ranges[2 * child] < lo ? t->ranges[2 * child] : lo;
                    hi = t->ranges[2 * child + 1] > hi ? t->ranges[2 * child + 1] : hi;
                }
                t->ranges[2 * node_id(t, level, a, b)] = lo;
                t->ranges[2 * node_id(t, level, a, b) + 1] = hi;
            }
    }
}

/* Raises d2 of Y (level - 1) so that f_X < 1 implies f_Y < 1 for node X. */
static void propagate_to(lk_terrain *t, unsigned level, uint32_t a, uint32_t b, double need_base, double d, uint32_t ya,
                         uint32_t yb)
{
    double delta = centre_distance(t, level, a, b, level - 1, ya, yb);
    double need = (need_base + delta / (2.0 * d * t->options.resolution)) / t->options.error_scale;
    need *= 1.0 + 1e-6; /* margin for float storage and rounding of l */
    size_t id = node_id(t, level - 1, ya, yb);
    if (need > t->nodes[id].d2) t->nodes[id].d2 = (float)need;
}

/* Bottom-up: l_Y <= l_X + |c_X - c_Y| and f_X < 1 give
 * l_Y < d C m_X + delta <= 2 d C m_Y as soon as m_Y >= m_X / 2 + delta / (2 d C),
 * with m = max(c d2, 1). Targets: the parent and the two parent-level
 * nodes sharing an edge with X. Nodes of the finest level never subdivide,
 * so they constrain nothing. */
static void propagate_d2(lk_terrain *t)
{
    if (t->levels < 3) return;
    for (unsigned level = t->levels - 2; level >= 1; level--) {
        uint32_t count = 1u << level, parent_count = count >> 1;
        double d = 2.0 * half_size(t, level) * t->node_spacing;
        for (uint32_t b = 0; b < count; b++)
            for (uint32_t a = 0; a < count; a++) {
                double m = fmax(t->options.error_scale * (double)t->nodes[node_id(t, level, a, b)].d2, 1.0);
                double base = 0.5 * m;
                uint32_t pa = a >> 1, pb = b >> 1;
                propagate_to(t, level, a, b, base, d, pa, pb);
                if ((a & 1) == 0 && pa > 0) propagate_to(t, level, a, b, base, d, pa - 1, pb);
                if ((a & 1) == 1 && pa + 1 < parent_count) propagate_to(t, level, a, b, base, d, pa + 1, pb);
                if ((b & 1) == 0 && pb > 0) propagate_to(t, level, a, b, base, d, pa, pb - 1);
                if ((b & 1) == 1 && pb + 1 < parent_count) propagate_to(t, level, a, b, base, d, pa, pb + 1);
            }
    }
}

lk_status lk_terrain_create(const lk_heightfield *field, const lk_terrain_options *options, lk_terrain **out,
                            lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_create: out is NULL");
    *out = NULL;
    if (!field || !field->heights) return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_create: no heightfield");
    lk_terrain_options settings;
    lk_terrain_options_default(&settings);
    if (options) settings = *options;
    lk_status status = check_options(&settings, error);
    if (status != LK_OK) return status;
    size_t size = field->width;
    if (field->width != field->height)
        return lk_error_set(error, LK_ERR_INVALID,
                            "terrain: the grid must be square with 2^n+1 samples a side (got %zux%zu; resample it)",
                            field->width, field->height);
    unsigned levels = 0;
    while (levels <= TERRAIN_MAX_LEVELS && ((size_t)1 << levels) + 1 < size) levels++;
    if (levels > TERRAIN_MAX_LEVELS || ((size_t)1 << levels) + 1 != size)
        return lk_error_set(error, LK_ERR_INVALID,
                            "terrain: %zux%zu is not (2^n+1)x(2^n+1) samples (resample it, e.g. to %zu)", size, size,
                            levels <= TERRAIN_MAX_LEVELS ? ((size_t)1 << levels) + 1 : (size_t)0);
    if (levels < 2)
        return lk_error_set(error, LK_ERR_RANGE, "terrain: a %zux%zu grid is too small (need at least 5x5)", size,
                            size);
    if (size > settings.max_samples / size)
        return lk_error_set(error, LK_ERR_LIMIT, "terrain: %zux%zu grid exceeds the budget of %zu samples", size, size,
                            settings.max_samples);
    if (!(field->spacing_x > 0) || !(field->spacing_y > 0) || !isfinite(field->spacing_x) ||
        !isfinite(field->spacing_y) || !isfinite(field->origin_x) || !isfinite(field->origin_y))
        return lk_error_set(error, LK_ERR_RANGE, "terrain: spacing must be positive and finite, origin finite");
    size_t samples = size * size;
    double lo = INFINITY, hi = -INFINITY;
    for (size_t s = 0; s < samples; s++) {
        float h = field->heights[s];
        if (!isfinite(h))
            return lk_error_set(error, LK_ERR_RANGE, "terrain: height at column %zu, row %zu is not finite", s % size,
                                s / size);
        lo = h < lo ? h : lo;
        hi = h > hi ? h : hi;
    }

    lk_terrain *t = calloc(1, sizeof *t);
    if (!t) return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory");
    t->options = settings;
    t->size = size;
    t->levels = levels;
    t->spacing_x = field->spacing_x;
    t->spacing_y = field->spacing_y;
    t->origin_x = field->origin_x;
    t->origin_y = field->origin_y;
    t->node_spacing = fmax(field->spacing_x, field->spacing_y);
    t->min_height = lo;
    t->max_height = hi;
    size_t total = 0;
    for (unsigned level = 0; level <= levels; level++) {
        t->level_offset[level] = total;
        if (level < levels) total += (size_t)1 << (2 * level);
    }
    t->node_count = total;
    t->grid = lk__calloc_array(samples, sizeof *t->grid);
    t->nodes = lk__calloc_array(total, sizeof *t->nodes);
    t->ranges = lk__malloc_array(total, 2 * sizeof *t->ranges);
    if (!t->grid || !t->nodes || !t->ranges) {
        lk_terrain_free(t);
        return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory for a %zux%zu grid", size, size);
    }
    for (size_t k = 0; k < samples; k++) t->grid[k].height = field->heights[k];
    compute_local_d2(t);
    compute_ranges(t);
    propagate_d2(t);
    *out = t;
    return LK_OK;
}

void lk_terrain_free(lk_terrain *t)
{
    if (!t) return;
    free(t->grid);
    free(t->nodes);
    free(t->ranges);
    free(t->leaves);
    free(t->public_leaves);
    free(t->positions);
    free(t->indices);
    free(t);
}

void lk_terrain_get_info(const lk_terrain *t, lk_terrain_info *info)
{
    if (!info) return;
    memset(info, 0, sizeof *info);
    if (!t) return;
    info->size = t->size;
    info->levels = t->levels;
    info->node_count = t->node_count;
    info->spacing_x = t->spacing_x;
    info->spacing_y = t->spacing_y;
    info->origin_x = t->origin_x;
    info->origin_y = t->origin_y;
    info->min_height = t->min_height;
    info->max_height = t->max_height;
    size_t samples = t->size * t->size;
    info->memory_bytes = sizeof *t + samples * sizeof(terrain_vertex) +
                         t->node_count * (sizeof(terrain_node) + 2 * sizeof(float)) +
                         t->leaf_capacity * sizeof(terrain_leaf) + t->public_leaf_capacity * sizeof(lk_terrain_leaf) +
                         t->position_capacity * 3 * sizeof(float) + t->index_capacity * 3 * sizeof(uint32_t);
}

void lk_terrain_get_options(const lk_terrain *t, lk_terrain_options *options)
{
    if (!options) return;
    if (!t) {
        lk_terrain_options_default(options);
        return;
    }
    *options = t->options;
}

/* ---- per-frame state ------------------------------------------------------ */

/* f of a node for this frame's eye, computed on first use. Nodes outside
 * the frustum are evaluated too when a visible neighbour asks, so culling
 * never changes what is drawn inside the view. */
static float node_f(lk_terrain *t, unsigned level, uint32_t a, uint32_t b)
{
    terrain_node *node = &t->nodes[node_id(t, level, a, b)];
    if (node->stamp == t->frame) return node->f;
    float f = INFINITY;
    if (level + 2 <= t->levels) {
        uint32_t r = half_size(t, level);
        uint32_t i = (2 * a + 1) * r, j = (2 * b + 1) * r;
        double dx = grid_x(t, i) - t->eye[0], dy = grid_y(t, j) - t->eye[1];
        double dz = (double)node->centre_height - t->eye[2];
        double l = sqrt(dx * dx + dy * dy + dz * dz);
        double d = 2.0 * r * t->node_spacing;
        double m = fmax(t->options.error_scale * (double)node->d2, 1.0);
        f = (float)(l / (d * t->options.resolution * m));
    }
    node->stamp = t->frame;
    node->f = f;
    t->evaluated++;
    return f;
}

/* Subdivided: f < 1. The propagation of d2 to the parent makes f < 1 imply
 * the parent's f < 1, so this local test describes a proper tree. */
static inline int node_subdivided(lk_terrain *t, unsigned level, uint32_t a, uint32_t b)
{
    return node_f(t, level, a, b) < 1.0f;
}

/* A node exists in this frame's tree when its parent is subdivided. */
static inline int node_exists(lk_terrain *t, unsigned level, uint32_t a, uint32_t b)
{
    return level == 0 || node_subdivided(t, level - 1, a >> 1, b >> 1);
}

/* Blend of the points created by subdividing node P: 0 when P is not
 * subdivided, 1 without morphing. */
static inline double subdivision_blend(lk_terrain *t, unsigned level, uint32_t a, uint32_t b)
{
    if (!node_subdivided(t, level, a, b)) return 0.0;
    if (!t->options.morph) return 1.0;
    if (t->options.blend_override >= 0) return t->options.blend_override;
    double blend = 2.0 * (1.0 - (double)node_f(t, level, a, b));
    return blend < 0 ? 0 : blend > 1 ? 1 : blend;
}

/* Blend of a node's own centre and midpoints (those of its parent's
 * subdivision); the root's are always at their true heights. */
static inline double node_blend(lk_terrain *t, unsigned level, uint32_t a, uint32_t b)
{
    return level == 0 ? 1.0 : subdivision_blend(t, level - 1, a >> 1, b >> 1);
}

/* Röttger's rule for an edge midpoint shared by two nodes of `level`: the
 * smaller of their blends (nodes outside the grid or not drawn do not
 * count; 0 when neither exists). (qi, qj) is the midpoint in units of half
 * a node side: one of them is odd, and it says along which axis the edge
 * runs. */
static double shared_edge_blend(lk_terrain *t, unsigned level, uint32_t qi, uint32_t qj)
{
    uint32_t count = 1u << level;
    int horizontal = (qi & 1) != 0; /* the edge runs along x */
    double blend = 2.0;
    for (int side = 0; side < 2; side++) {
        uint32_t a, b;
        if (horizontal) {
            a = qi >> 1;
            if (side == 0 && qj == 0) continue;
            b = side == 0 ? qj / 2 - 1 : qj / 2;
            if (b >= count) continue;
        } else {
            b = qj >> 1;
            if (side == 0 && qi == 0) continue;
            a = side == 0 ? qi / 2 - 1 : qi / 2;
            if (a >= count) continue;
        }
        if (!node_exists(t, level, a, b)) continue;
        double side_blend = node_blend(t, level, a, b);
        blend = side_blend < blend ? side_blend : blend;
    }
    return blend > 1 ? 0 : blend;
}

static void setup_frustum(lk_terrain *t, const lk_terrain_view *view)
{
    double forward[3], right[3], up[3];
    for (int k = 0; k < 3; k++) forward[k] = view->target[k] - view->eye[k];
    double length = sqrt(forward[0] * forward[0] + forward[1] * forward[1] + forward[2] * forward[2]);
    for (int k = 0; k < 3; k++) forward[k] /= length;
    /* right = forward x z (or x y when looking straight down) */
    double world_up[3] = {0, 0, 1};
    if (fabs(forward[2]) > 0.999) world_up[1] = 1, world_up[2] = 0;
    right[0] = forward[1] * world_up[2] - forward[2] * world_up[1];
    right[1] = forward[2] * world_up[0] - forward[0] * world_up[2];
    right[2] = forward[0] * world_up[1] - forward[1] * world_up[0];
    length = sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
    for (int k = 0; k < 3; k++) right[k] /= length;
    up[0] = right[1] * forward[2] - right[2] * forward[1];
    up[1] = right[2] * forward[0] - right[0] * forward[2];
    up[2] = right[0] * forward[1] - right[1] * forward[0];
    double tan_v = tan(0.5 * view->fov_y * TERRAIN_PI / 180.0), tan_h = tan_v * view->aspect;
    /* Inside: |x| <= z tan_h, |y| <= z tan_v in camera coordinates. */
    for (int k = 0; k < 3; k++) {
        t->planes[0][k] = forward[k] * tan_h - right[k];
        t->planes[1][k] = forward[k] * tan_h + right[k];
        t->planes[2][k] = forward[k] * tan_v - up[k];
        t->planes[3][k] = forward[k] * tan_v + up[k];
    }
    for (int p = 0; p < 4; p++)
        t->planes[p][3] =
            -(t->planes[p][0] * view->eye[0] + t->planes[p][1] * view->eye[1] + t->planes[p][2] * view->eye[2]);
}

/* 0: outside, 1: intersecting, 2: inside. */
static int box_in_frustum(const lk_terrain *t, const double lo[3], const double hi[3])
{
    int inside = 1;
    for (int p = 0; p < 4; p++) {
        const double *n = t->planes[p];
        double far_point = n[3], near_point = n[3];
        for (int k = 0; k < 3; k++) {
            far_point += n[k] * (n[k] > 0 ? hi[k] : lo[k]);
            near_point += n[k] * (n[k] > 0 ? lo[k] : hi[k]);
        }
        if (far_point < 0) return 0;
        if (near_point < 0) inside = 0;
    }
    return inside ? 2 : 1;
}

static int point_in_frustum(const double planes[4][4], double x, double y, double z)
{
    for (int p = 0; p < 4; p++)
        if (planes[p][0] * x + planes[p][1] * y + planes[p][2] * z + planes[p][3] < 0) return 0;
    return 1;
}

static int push_leaf(lk_terrain *t, unsigned level, uint32_t a, uint32_t b)
{
    if (t->leaf_count == t->leaf_capacity) {
        size_t capacity = t->leaf_capacity ? 2 * t->leaf_capacity : 1024;
        terrain_leaf *grown = lk__realloc_array(t->leaves, capacity, sizeof *grown);
        if (!grown) return 0;
        t->leaves = grown;
        t->leaf_capacity = capacity;
    }
    t->leaves[t->leaf_count++] = (terrain_leaf){a, b, level};
    return 1;
}

static void visit(lk_terrain *t, unsigned level, uint32_t a, uint32_t b, int inside)
{
    if (t->failed) return;
    t->visited++;
    if (t->options.culling && inside != 2) {
        size_t id = node_id(t, level, a, b);
        uint32_t r = half_size(t, level);
        uint32_t i = (2 * a + 1) * r, j = (2 * b + 1) * r;
        double lo[3] = {grid_x(t, i - r), grid_y(t, j - r), t->ranges[2 * id]};
        double hi[3] = {grid_x(t, i + r), grid_y(t, j + r), t->ranges[2 * id + 1]};
        inside = box_in_frustum(t, lo, hi);
        if (inside == 0) {
            t->culled++;
            return;
        }
    }
    float f = node_f(t, level, a, b);
    if (f < 1.0f) {
        if (t->options.morph && 2.0 * (1.0 - f) < 1.0) t->morphing++;
        for (uint32_t q = 0; q < 4; q++) visit(t, level + 1, 2 * a + (q & 1), 2 * b + (q >> 1), inside);
    } else if (!push_leaf(t, level, a, b)) {
        t->failed = 1;
    }
}

/* ---- heights of the drawn points ----------------------------------------- */

static inline uint32_t lowest_bit(uint32_t value) { return value & (~value + 1u); }

static inline unsigned level_of_half_size(const lk_terrain *t, uint32_t r)
{
    return t->levels - 1 - (unsigned)__builtin_ctz(r);
}

/* LK_TERRAIN_CRACKS_FULL: one height per grid vertex and frame, top-down.
 * The recursion goes to strictly coarser vertices, so its depth is at most
 * the number of levels. */
static float full_height(lk_terrain *t, uint32_t i, uint32_t j)
{
    terrain_vertex *vertex = &t->grid[(size_t)j * t->size + i];
    if (vertex->stamp == t->frame) return vertex->z;
    double h = vertex->height;
    double z = h;
    uint32_t bits = i | j;
    uint32_t r = bits ? lowest_bit(bits) : (1u << t->levels);
    if (r < half_size(t, 0)) {
        unsigned level = level_of_half_size(t, r);
        uint32_t qi = i / r, qj = j / r;
        double vp, blend;
        if ((qi & 1) && (qj & 1)) {
            /* centre of a node: the parent's fan diagonal through it runs
             * from the parent's centre to the opposite corner */
            uint32_t a = qi >> 1, b = qj >> 1;
            uint32_t pi = (2 * (a >> 1) + 1) * 2 * r, pj = (2 * (b >> 1) + 1) * 2 * r;
            vp = 0.5 * ((double)full_height(t, pi, pj) + (double)full_height(t, 2 * i - pi, 2 * j - pj));
            blend = subdivision_blend(t, level - 1, a >> 1, b >> 1);
        } else {
            /* midpoint of an edge of length 2r between two nodes (one on the border) */
            int horizontal = (qi & 1) != 0; /* the edge runs along x */
            uint32_t e0i = horizontal ? i - r : i, e0j = horizontal ? j : j - r;
            uint32_t e1i = horizontal ? i + r : i, e1j = horizontal ? j : j + r;
            vp = 0.5 * ((double)full_height(t, e0i, e0j) + (double)full_height(t, e1i, e1j));
            blend = shared_edge_blend(t, level, qi, qj);
        }
        z = vp + blend * (h - vp);
    }
    vertex->stamp = t->frame;
    vertex->z = (float)z;
    vertex->mesh_index = UINT32_MAX;
    return (float)z;
}

/* The neighbour of node (level, a, b) across edge `edge` (0 S, 1 E, 2 N, 3 W);
 * 0 when it is outside the grid. */
static int neighbour(uint32_t count, uint32_t a, uint32_t b, int edge, uint32_t *na, uint32_t *nb)
{
    *na = a;
    *nb = b;
    switch (edge) {
    case 0:
        if (b == 0) return 0;
        *nb = b - 1;
        return 1;
    case 1:
        if (a + 1 >= count) return 0;
        *na = a + 1;
        return 1;
    case 2:
        if (b + 1 >= count) return 0;
        *nb = b + 1;
        return 1;
    default:
        if (a == 0) return 0;
        *na = a - 1;
        return 1;
    }
}

/* Blend of an edge midpoint of node (level, a, b) across `edge` under the
 * midpoint rule: the minimum over both nodes sharing the edge. */
static double shared_midpoint_blend(lk_terrain *t, unsigned level, uint32_t a, uint32_t b, int edge)
{
    double blend = node_blend(t, level, a, b);
    uint32_t na, nb;
    if (neighbour(1u << level, a, b, edge, &na, &nb) && node_exists(t, level, na, nb)) {
        double other = node_blend(t, level, na, nb);
        blend = other < blend ? other : blend;
    }
    return blend;
}

/* The paper's corner rules (LK_TERRAIN_CRACKS_PAPER) for corner (i, j) of a
 * leaf at `level`, using true heights for v_p. */
static double paper_corner_height(lk_terrain *t, unsigned level, uint32_t i, uint32_t j)
{
    double h = height_at(t, i, j);
    uint32_t bits = i | j;
    uint32_t r = bits ? lowest_bit(bits) : (1u << t->levels);
    if (r >= half_size(t, 0)) return h; /* root points: the root's blend is 1 */
    unsigned point_level = level_of_half_size(t, r);
    uint32_t qi = i / r, qj = j / r;
    if ((qi & 1) && (qj & 1)) {
        /* (b/c) an ancestor's centre: v_p = the smaller of the midpoints of
         * its two diagonals, b = the ancestor's blend */
        uint32_t a = qi >> 1, b = qj >> 1;
        double sw = height_at(t, i - r, j - r), ne = height_at(t, i + r, j + r);
        double se = height_at(t, i + r, j - r), nw = height_at(t, i - r, j + r);
        double vp = fmin(0.5 * (sw + ne), 0.5 * (se + nw));
        double blend = node_blend(t, point_level, a, b);
        return vp + blend * (h - vp);
    }
    if (point_level + 1 != level) return h; /* a grandparent's (or older) edge midpoint: no rule */
    /* (a/d) the parent's edge midpoint */
    int horizontal = (qi & 1) != 0;
    double e0 = horizontal ? height_at(t, i - r, j) : height_at(t, i, j - r);
    double e1 = horizontal ? height_at(t, i + r, j) : height_at(t, i, j + r);
    double vp = 0.5 * (e0 + e1);
    double blend = shared_edge_blend(t, point_level, qi, qj);
    return vp + blend * (h - vp);
}

/* ---- mesh generation ------------------------------------------------------ */

static int reserve_output(lk_terrain *t, size_t vertices, size_t triangles)
{
    if (vertices > t->position_capacity) {
        float *grown = lk__realloc_array(t->positions, vertices, 3 * sizeof *grown);
        if (!grown) return 0;
        t->positions = grown;
        t->position_capacity = vertices;
    }
    if (triangles > t->index_capacity) {
        uint32_t *grown = lk__realloc_array(t->indices, triangles, 3 * sizeof *grown);
        if (!grown) return 0;
        t->indices = grown;
        t->index_capacity = triangles;
    }
    return 1;
}

/* Mesh vertex for grid point (i, j) at height z: shared with an earlier
 * triangle when that one gave the point the same height. */
static uint32_t emit_vertex(lk_terrain *t, uint32_t i, uint32_t j, float z)
{
    terrain_vertex *g = &t->grid[(size_t)j * t->size + i];
    int known = g->stamp == t->frame && g->mesh_index != UINT32_MAX;
    if (known && t->positions[3 * (size_t)g->mesh_index + 2] == z) return g->mesh_index;
    uint32_t v = (uint32_t)t->vertex_count++;
    float *p = t->positions + 3 * (size_t)v;
    p[0] = (float)grid_x(t, i);
    p[1] = (float)grid_y(t, j);
    p[2] = z;
    if (!known) {
        g->stamp = t->frame;
        g->mesh_index = v;
    }
    return v;
}

static void emit_leaf(lk_terrain *t, const terrain_leaf *leaf, size_t *violations)
{
    unsigned level = leaf->level;
    uint32_t a = leaf->a, b = leaf->b, r = half_size(t, level), count = 1u << level;
    uint32_t i = (2 * a + 1) * r, j = (2 * b + 1) * r;
    /* ring: SW, S, SE, E, NE, N, NW, W (counter-clockwise seen from +z) */
    static const int offsets[8][2] = {{-1, -1}, {0, -1}, {1, -1}, {1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}};
    int include[8];
    for (int k = 0; k < 8; k += 2) include[k] = 1;
    for (int edge = 0; edge < 4; edge++) {
        uint32_t na, nb;
        int inside = neighbour(count, a, b, edge, &na, &nb);
        int exists = !inside || node_exists(t, level, na, nb);
        include[2 * edge + 1] = exists;
        /* The parent-level neighbour must exist then (restricted quadtree). */
        if (!exists && level >= 2 && !node_exists(t, level - 1, na >> 1, nb >> 1)) (*violations)++;
    }
    lk_terrain_cracks mode = t->options.cracks;
    double own_blend = node_blend(t, level, a, b);
    uint32_t ring[8];
    int ring_count = 0;
    for (int k = 0; k < 8; k++) {
        if (!include[k]) continue;
        uint32_t pi = (uint32_t)((int64_t)i + offsets[k][0] * (int64_t)r);
        uint32_t pj = (uint32_t)((int64_t)j + offsets[k][1] * (int64_t)r);
        float z;
        if (mode == LK_TERRAIN_CRACKS_FULL) {
            z = full_height(t, pi, pj);
        } else if (k % 2 == 0) {
            z = mode == LK_TERRAIN_CRACKS_PAPER ? (float)paper_corner_height(t, level, pi, pj) : height_at(t, pi, pj);
        } else {
            int edge = k / 2;
            double e0 = height_at(t, (uint32_t)((int64_t)i + offsets[k - 1][0] * (int64_t)r),
                                  (uint32_t)((int64_t)j + offsets[k - 1][1] * (int64_t)r));
            double e1 = height_at(t, (uint32_t)((int64_t)i + offsets[(k + 1) % 8][0] * (int64_t)r),
                                  (uint32_t)((int64_t)j + offsets[(k + 1) % 8][1] * (int64_t)r));
            double vp = 0.5 * (e0 + e1);
            double blend = mode == LK_TERRAIN_CRACKS_NONE ? own_blend : shared_midpoint_blend(t, level, a, b, edge);
            z = (float)(vp + blend * (height_at(t, pi, pj) - vp));
        }
        ring[ring_count++] = emit_vertex(t, pi, pj, z);
    }
    float centre_z;
    if (mode == LK_TERRAIN_CRACKS_FULL) {
        centre_z = full_height(t, i, j);
    } else if (level == 0) {
        centre_z = height_at(t, i, j);
    } else {
        /* the parent's fan diagonal through this centre */
        uint32_t pi = (2 * (a >> 1) + 1) * 2 * r, pj = (2 * (b >> 1) + 1) * 2 * r;
        double vp = 0.5 * ((double)height_at(t, pi, pj) + (double)height_at(t, 2 * i - pi, 2 * j - pj));
        centre_z = (float)(vp + own_blend * (height_at(t, i, j) - vp));
    }
    uint32_t centre = emit_vertex(t, i, j, centre_z);
    for (int k = 0; k < ring_count; k++) {
        uint32_t *tri = t->indices + 3 * t->triangle_count++;
        tri[0] = centre;
        tri[1] = ring[k];
        tri[2] = ring[(k + 1) % ring_count];
    }
}

static lk_status check_view(const lk_terrain_view *view, lk_error *error)
{
    if (!view) return lk_error_set(error, LK_ERR_INVALID, "terrain: no view");
    for (int k = 0; k < 3; k++)
        if (!isfinite(view->eye[k]) || !isfinite(view->target[k]))
            return lk_error_set(error, LK_ERR_INVALID, "terrain: view eye and target must be finite");
    double dx = view->target[0] - view->eye[0], dy = view->target[1] - view->eye[1],
           dz = view->target[2] - view->eye[2];
    if (!(dx * dx + dy * dy + dz * dz > 0))
        return lk_error_set(error, LK_ERR_INVALID, "terrain: view eye and target coincide");
    if (!(view->fov_y > 0 && view->fov_y < 180))
        return lk_error_set(error, LK_ERR_INVALID, "terrain: fov_y must be in (0, 180) degrees (got %g)", view->fov_y);
    if (!(view->aspect > 0) || !isfinite(view->aspect))
        return lk_error_set(error, LK_ERR_INVALID, "terrain: aspect must be positive (got %g)", view->aspect);
    if (!(view->viewport_height > 0) || !isfinite(view->viewport_height))
        return lk_error_set(error, LK_ERR_INVALID, "terrain: viewport_height must be positive (got %g)",
                            view->viewport_height);
    return LK_OK;
}

lk_status lk_terrain_update(lk_terrain *t, const lk_terrain_view *view, lk_mesh *out, lk_terrain_stats *stats,
                            lk_error *error)
{
    if (!t || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_update: terrain or out is NULL");
    lk_status status = check_view(view, error);
    if (status != LK_OK) return status;
    double start = lk__now();
    if (++t->frame == 0) {
        /* after 2^32 frames the stamps would alias: start over */
        for (size_t k = 0; k < t->node_count; k++) t->nodes[k].stamp = 0;
        for (size_t k = 0; k < t->size * t->size; k++) t->grid[k].stamp = 0;
        t->frame = 1;
    }
    setup_frustum(t, view);
    t->leaf_count = 0;
    t->culled = t->visited = t->morphing = t->evaluated = 0;
    t->failed = 0;
    for (int k = 0; k < 3; k++) t->eye[k] = view->eye[k];
    visit(t, 0, 0, 0, 0);
    if (t->failed) return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory for the leaf list");
    if (!reserve_output(t, 9 * t->leaf_count, 8 * t->leaf_count))
        return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory for %zu leaves", t->leaf_count);
    t->vertex_count = t->triangle_count = 0;
    size_t violations = 0;
    unsigned max_level = 0;
    for (size_t k = 0; k < t->leaf_count; k++) {
        emit_leaf(t, &t->leaves[k], &violations);
        if (t->leaves[k].level > max_level) max_level = t->leaves[k].level;
    }
    /* hand over to the caller's mesh (arrays reused when possible) */
    size_t vertices = t->vertex_count ? t->vertex_count : 1, triangles = t->triangle_count ? t->triangle_count : 1;
    float *positions = lk__realloc_array(out->positions, vertices, 3 * sizeof *positions);
    if (!positions) return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory for the mesh");
    out->positions = positions;
    uint32_t *indices = lk__realloc_array(out->indices, triangles, 3 * sizeof *indices);
    if (!indices) return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory for the mesh");
    out->indices = indices;
    free(out->normals);
    free(out->texcoords);
    free(out->colors);
    free(out->radii);
    out->normals = out->texcoords = out->colors = out->radii = NULL;
    if (t->vertex_count) memcpy(out->positions, t->positions, t->vertex_count * 3 * sizeof *positions);
    if (t->triangle_count) memcpy(out->indices, t->indices, t->triangle_count * 3 * sizeof *indices);
    out->vertex_count = t->vertex_count;
    out->triangle_count = t->triangle_count;
    double elapsed = lk__now() - start;
    if (stats) {
        memset(stats, 0, sizeof *stats);
        stats->triangles = t->triangle_count;
        stats->vertices = t->vertex_count;
        stats->leaves = t->leaf_count;
        stats->nodes_visited = t->visited;
        stats->nodes_evaluated = t->evaluated;
        stats->nodes_culled = t->culled;
        stats->morphing_nodes = t->morphing;
        stats->restriction_violations = violations;
        stats->max_level = max_level;
        stats->milliseconds = elapsed * 1000.0;
    }
    return LK_OK;
}

const lk_terrain_leaf *lk_terrain_leaves(const lk_terrain *t, size_t *count)
{
    if (count) *count = 0;
    if (!t || t->leaf_count == 0) return NULL;
    /* The public form is filled lazily; the cast keeps the getter const for
     * callers (the cache is not part of the observable state). */
    lk_terrain *mutable_terrain = (lk_terrain *)t;
    if (t->public_leaf_capacity < t->leaf_count) {
        lk_terrain_leaf *grown = lk__realloc_array(mutable_terrain->public_leaves, t->leaf_count, sizeof *grown);
        if (!grown) return NULL;
        mutable_terrain->public_leaves = grown;
        mutable_terrain->public_leaf_capacity = t->leaf_count;
    }
    for (size_t k = 0; k < t->leaf_count; k++) {
        const terrain_leaf *leaf = &t->leaves[k];
        uint32_t r = half_size(t, leaf->level);
        mutable_terrain->public_leaves[k] = (lk_terrain_leaf){2 * leaf->a * r, 2 * leaf->b * r, 2 * r, leaf->level};
    }
    if (count) *count = t->leaf_count;
    return t->public_leaves;
}

lk_status lk_terrain_outline(const lk_terrain *t, float **segments, size_t *segment_count, lk_error *error)
{
    if (!t || !segments || !segment_count)
        return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_outline: NULL argument");
    *segments = NULL;
    *segment_count = 0;
    size_t count = t->leaf_count;
    float *lines = lk__malloc_array(count * 4, 6 * sizeof *lines);
    if (!lines) return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory for the outline");
    for (size_t k = 0; k < count; k++) {
        const terrain_leaf *leaf = &t->leaves[k];
        uint32_t r = half_size(t, leaf->level);
        uint32_t x0 = 2 * leaf->a * r, y0 = 2 * leaf->b * r, x1 = x0 + 2 * r, y1 = y0 + 2 * r;
        uint32_t corners[5][2] = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0}};
        for (int e = 0; e < 4; e++) {
            float *s = lines + 24 * k + 6 * e;
            s[0] = (float)grid_x(t, corners[e][0]);
            s[1] = (float)grid_y(t, corners[e][1]);
            s[2] = height_at(t, corners[e][0], corners[e][1]);
            s[3] = (float)grid_x(t, corners[e + 1][0]);
            s[4] = (float)grid_y(t, corners[e + 1][1]);
            s[5] = height_at(t, corners[e + 1][0], corners[e + 1][1]);
        }
    }
    *segments = lines;
    *segment_count = 4 * count;
    return LK_OK;
}

/* ---- measurement: cracks ---------------------------------------------------- */

typedef struct grid_vertex {
    uint64_t key; /* j * size + i */
    uint32_t vertex;
} grid_vertex;

static int compare_grid_vertex(const void *x, const void *y)
{
    const grid_vertex *p = x, *q = y;
    if (p->key != q->key) return p->key < q->key ? -1 : 1;
    return p->vertex < q->vertex ? -1 : p->vertex > q->vertex;
}

static int compare_u64(const void *x, const void *y)
{
    uint64_t p = *(const uint64_t *)x, q = *(const uint64_t *)y;
    return p < q ? -1 : p > q;
}

/* Grid index of a mesh vertex, or 0 when it is not on a grid point. */
static int vertex_on_grid(const lk_terrain *t, const float *p, int64_t *i, int64_t *j)
{
    double u = ((double)p[0] - t->origin_x) / t->spacing_x, v = ((double)p[1] - t->origin_y) / t->spacing_y;
    double ru = floor(u + 0.5), rv = floor(v + 0.5);
    if (!(fabs(u - ru) < 0.25 && fabs(v - rv) < 0.25)) return 0;
    if (ru < 0 || rv < 0 || ru > (double)(t->size - 1) || rv > (double)(t->size - 1)) return 0;
    *i = (int64_t)ru;
    *j = (int64_t)rv;
    return 1;
}

static int64_t gcd64(int64_t x, int64_t y)
{
    if (x < 0) x = -x;
    if (y < 0) y = -y;
    while (y) {
        int64_t r = x % y;
        x = y;
        y = r;
    }
    return x;
}

/* The crack count, and the grid keys (j * size + i) of the cracked places
 * (sorted, distinct, malloc'ed) when `places` is not NULL. */
static lk_status find_cracks(const lk_terrain *t, const lk_mesh *mesh, double tolerance, lk_terrain_crack_stats *out,
                             uint64_t **places, lk_error *error)
{
    memset(out, 0, sizeof *out);
    if (places) *places = NULL;
    if (!(tolerance > 0)) tolerance = 1e-3;
    size_t vertex_count = mesh->vertex_count;
    if (mesh->triangle_count == 0) return LK_OK;
    grid_vertex *sorted = lk__malloc_array(vertex_count, sizeof *sorted);
    int64_t *lattice = lk__malloc_array(vertex_count, 2 * sizeof *lattice);
    lk__buffer cracked = {0};
    if (!sorted || !lattice) {
        free(sorted);
        free(lattice);
        return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory counting cracks");
    }
    for (size_t v = 0; v < vertex_count; v++) {
        int64_t i, j;
        if (!vertex_on_grid(t, mesh->positions + 3 * v, &i, &j)) {
            free(sorted);
            free(lattice);
            return lk_error_set(error, LK_ERR_INVALID, "terrain: mesh vertex %zu is not on a grid point", v);
        }
        lattice[2 * v] = i;
        lattice[2 * v + 1] = j;
        sorted[v] = (grid_vertex){(uint64_t)j * t->size + (uint64_t)i, (uint32_t)v};
    }
    qsort(sorted, vertex_count, sizeof *sorted, compare_grid_vertex);
    lk_status status = LK_OK;
    for (size_t tri = 0; tri < mesh->triangle_count && status == LK_OK; tri++) {
        for (int e = 0; e < 3; e++) {
            uint32_t u = mesh->indices[3 * tri + e], w = mesh->indices[3 * tri + (e + 1) % 3];
            if (u >= vertex_count || w >= vertex_count) {
                status = lk_error_set(error, LK_ERR_RANGE, "terrain: triangle %zu has an index out of range", tri);
                break;
            }
            int64_t di = lattice[2 * w] - lattice[2 * u], dj = lattice[2 * w + 1] - lattice[2 * u + 1];
            int64_t steps = gcd64(di, dj);
            if (steps == 0) continue;
            double zu = mesh->positions[3 * (size_t)u + 2], zw = mesh->positions[3 * (size_t)w + 2];
            for (int64_t s = 0; s <= steps; s++) {
                int64_t pi = lattice[2 * u] + di / steps * s, pj = lattice[2 * u + 1] + dj / steps * s;
                uint64_t key = (uint64_t)pj * t->size + (uint64_t)pi;
                size_t lo = 0, hi = vertex_count;
                while (lo < hi) {
                    size_t mid = (lo + hi) / 2;
                    if (sorted[mid].key < key)
                        lo = mid + 1;
                    else
                        hi = mid;
                }
                double expected = zu + (zw - zu) * ((double)s / (double)steps);
                int off = 0;
                for (size_t k = lo; k < vertex_count && sorted[k].key == key; k++) {
                    uint32_t q = sorted[k].vertex;
                    if (q == u || q == w) continue;
                    out->checks++;
                    double gap = fabs((double)mesh->positions[3 * (size_t)q + 2] - expected);
                    if (gap > out->max_gap) out->max_gap = gap;
                    if (gap > tolerance) off = 1;
                }
                if (off && !lk__buffer_append(&cracked, &key, sizeof key)) {
                    status = lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory counting cracks");
                    break;
                }
            }
        }
    }
    if (status == LK_OK) {
        size_t count = cracked.size / sizeof(uint64_t);
        uint64_t *keys = (uint64_t *)cracked.data;
        if (count) qsort(keys, count, sizeof *keys, compare_u64);
        size_t distinct = 0;
        for (size_t k = 0; k < count; k++)
            if (k == 0 || keys[k] != keys[k - 1]) keys[distinct++] = keys[k];
        out->cracks = distinct;
        if (places) {
            *places = (uint64_t *)lk__buffer_take(&cracked);
            if (distinct && !*places) status = lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory");
        }
    }
    lk__buffer_free(&cracked);
    free(sorted);
    free(lattice);
    return status;
}

lk_status lk_terrain_count_cracks(const lk_terrain *t, const lk_mesh *mesh, double tolerance,
                                  lk_terrain_crack_stats *out, lk_error *error)
{
    if (!t || !mesh || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_count_cracks: NULL argument");
    return find_cracks(t, mesh, tolerance, out, NULL, error);
}

/* ---- measurement: surface and popping ----------------------------------------- */

lk_status lk_terrain_sample_surface(const lk_terrain *t, const lk_mesh *mesh, size_t probes_per_side, float *heights,
                                    lk_error *error)
{
    if (!t || !mesh || !heights) return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_sample_surface: NULL argument");
    if (probes_per_side < 2) return lk_error_set(error, LK_ERR_INVALID, "terrain: need at least 2 probes a side");
    size_t probes = probes_per_side;
    for (size_t k = 0; k < probes * probes; k++) heights[k] = NAN;
    /* probe p stands at grid coordinate p * (size - 1) / (probes - 1) */
    double scale = (double)(probes - 1) / (double)(t->size - 1);
    for (size_t tri = 0; tri < mesh->triangle_count; tri++) {
        double u[3], v[3], z[3];
        for (int c = 0; c < 3; c++) {
            uint32_t index = mesh->indices[3 * tri + c];
            if (index >= mesh->vertex_count)
                return lk_error_set(error, LK_ERR_RANGE, "terrain: triangle %zu has an index out of range", tri);
            const float *p = mesh->positions + 3 * (size_t)index;
            u[c] = ((double)p[0] - t->origin_x) / t->spacing_x * scale;
            v[c] = ((double)p[1] - t->origin_y) / t->spacing_y * scale;
            z[c] = p[2];
        }
        double area = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
        if (fabs(area) < 1e-12) continue;
        double umin = fmin(u[0], fmin(u[1], u[2])), umax = fmax(u[0], fmax(u[1], u[2]));
        double vmin = fmin(v[0], fmin(v[1], v[2])), vmax = fmax(v[0], fmax(v[1], v[2]));
        double eps = 1e-9;
        long x0 = (long)ceil(umin - eps), x1 = (long)floor(umax + eps);
        long y0 = (long)ceil(vmin - eps), y1 = (long)floor(vmax + eps);
        if (x0 < 0) x0 = 0;
        if (y0 < 0) y0 = 0;
        if (x1 > (long)probes - 1) x1 = (long)probes - 1;
        if (y1 > (long)probes - 1) y1 = (long)probes - 1;
        for (long py = y0; py <= y1; py++)
            for (long px = x0; px <= x1; px++) {
                double w0 = ((u[1] - px) * (v[2] - py) - (u[2] - px) * (v[1] - py)) / area;
                double w1 = ((u[2] - px) * (v[0] - py) - (u[0] - px) * (v[2] - py)) / area;
                double w2 = 1.0 - w0 - w1;
                if (w0 < -eps || w1 < -eps || w2 < -eps) continue;
                heights[(size_t)py * probes + (size_t)px] = (float)(w0 * z[0] + w1 * z[1] + w2 * z[2]);
            }
    }
    return LK_OK;
}

void lk_terrain_measure_popping(const lk_terrain *t, const lk_terrain_view *view, const float *before, const float *now,
                                size_t probes_per_side, lk_terrain_popping *out)
{
    if (!out) return;
    memset(out, 0, sizeof *out);
    if (!t || !view || !before || !now || probes_per_side < 2) return;
    lk_terrain scratch; /* only the frustum planes are used */
    setup_frustum(&scratch, view);
    double tan_half = tan(0.5 * view->fov_y * TERRAIN_PI / 180.0);
    double step = (double)(t->size - 1) / (double)(probes_per_side - 1);
    for (size_t py = 0; py < probes_per_side; py++)
        for (size_t px = 0; px < probes_per_side; px++) {
            size_t k = py * probes_per_side + px;
            if (!isfinite(before[k]) || !isfinite(now[k])) continue;
            double x = t->origin_x + (double)px * step * t->spacing_x;
            double y = t->origin_y + (double)py * step * t->spacing_y;
            double z = now[k];
            if (!point_in_frustum((const double(*)[4])scratch.planes, x, y, z)) continue;
            out->probes++;
            double change = fabs((double)now[k] - (double)before[k]);
            double dx = x - view->eye[0], dy = y - view->eye[1], dz = z - view->eye[2];
            double distance = sqrt(dx * dx + dy * dy + dz * dz);
            double pixels = distance > 0 ? change * view->viewport_height / (2.0 * distance * tan_half) : 0;
            if (change > out->max_metres) out->max_metres = change;
            if (pixels > out->max_pixels) out->max_pixels = pixels;
        }
}

void lk_terrain_flight(const lk_terrain *t, size_t frame, double speed, lk_terrain_view *view)
{
    if (!t || !view) return;
    if (!(speed > 0)) speed = 0.5;
    double width = (double)(t->size - 1) * t->spacing_x, height = (double)(t->size - 1) * t->spacing_y;
    double cx = t->origin_x + 0.5 * width, cy = t->origin_y + 0.5 * height;
    double radius = 0.3 * fmin(width, height);
    double angle = (double)frame * speed * t->node_spacing / radius;
    /* Ten samples above the highest point, but on a grid only a few dozen
     * samples wide that is too high: looking 30 degrees down (60 degrees
     * at the bottom of the view) from there, the camera sees past the grid
     * and every frame is empty. A quarter of the grid's width keeps it in
     * view; from 41 samples on, nothing changes. */
    double altitude = t->max_height + fmin(10.0 * t->node_spacing, 0.25 * fmin(width, height));
    view->eye[0] = cx + radius * cos(angle);
    view->eye[1] = cy + radius * sin(angle);
    view->eye[2] = altitude;
    double pitch = 30.0 * TERRAIN_PI / 180.0;
    double fx = -sin(angle), fy = cos(angle); /* counter-clockwise tangent */
    view->target[0] = view->eye[0] + fx * cos(pitch);
    view->target[1] = view->eye[1] + fy * cos(pitch);
    view->target[2] = view->eye[2] - sin(pitch);
    view->fov_y = 60.0;
    view->aspect = 4.0 / 3.0;
    view->viewport_height = 768.0;
}

/* ---- colours ----------------------------------------------------------------- */

static void ramp(double height, double top, float rgb[3])
{
    /* stops: deep water, shallow water | lowland green, hills yellow-brown, mountains brown, peaks white */
    static const double land[4][4] = {
        {0.00, 0.20, 0.55, 0.20}, {0.35, 0.80, 0.75, 0.40}, {0.70, 0.55, 0.38, 0.22}, {1.00, 0.97, 0.97, 0.97}};
    if (height < 0) {
        double s = fmin(1.0, -height / 6000.0);
        rgb[0] = (float)(0.35 - 0.30 * s);
        rgb[1] = (float)(0.60 - 0.45 * s);
        rgb[2] = (float)(0.90 - 0.45 * s);
        return;
    }
    double s = top > 0 ? fmin(1.0, height / top) : 0;
    int k = 0;
    while (k < 2 && s > land[k + 1][0]) k++;
    double w = (s - land[k][0]) / (land[k + 1][0] - land[k][0]);
    for (int c = 0; c < 3; c++) rgb[c] = (float)(land[k][c + 1] + w * (land[k + 1][c + 1] - land[k][c + 1]));
}

lk_status lk_terrain_color_mesh(const lk_terrain *t, lk_mesh *mesh, lk_error *error)
{
    if (!t || !mesh) return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_color_mesh: NULL argument");
    if (!mesh->colors) {
        mesh->colors = lk__malloc_array(mesh->vertex_count ? mesh->vertex_count : 1, 4 * sizeof *mesh->colors);
        if (!mesh->colors) return lk_error_set(error, LK_ERR_NOMEM, "terrain: out of memory for colours");
    }
    double light[3] = {-0.5, 0.5, 0.70710678};
    size_t last = t->size - 1;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        const float *p = mesh->positions + 3 * v;
        int64_t i = 0, j = 0;
        float rgb[3];
        ramp(p[2], t->max_height, rgb);
        double shade = 1.0;
        if (vertex_on_grid(t, p, &i, &j)) {
            size_t i0 = i > 0 ? (size_t)i - 1 : 0, i1 = (size_t)i < last ? (size_t)i + 1 : last;
            size_t j0 = j > 0 ? (size_t)j - 1 : 0, j1 = (size_t)j < last ? (size_t)j + 1 : last;
            double gx = ((double)height_at(t, (uint32_t)i1, (uint32_t)j) - height_at(t, (uint32_t)i0, (uint32_t)j)) /
                        ((double)(i1 - i0) * t->spacing_x);
            double gy = ((double)height_at(t, (uint32_t)i, (uint32_t)j1) - height_at(t, (uint32_t)i, (uint32_t)j0)) /
                        ((double)(j1 - j0) * t->spacing_y);
            double n[3] = {-gx, -gy, 1.0};
            double length = sqrt(n[0] * n[0] + n[1] * n[1] + 1.0);
            double lit = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / length;
            shade = 0.35 + 0.65 * fmax(0.0, lit);
        }
        float *c = mesh->colors + 4 * v;
        for (int k = 0; k < 3; k++) c[k] = (float)fmin(1.0, rgb[k] * shade);
        c[3] = 1.0f;
    }
    return LK_OK;
}

/* ---- top-down map ---------------------------------------------------------------- */

static void blend_pixel(unsigned char *rgba, unsigned width, unsigned height, long x, long y, const float colour[3],
                        float alpha)
{
    if (x < 0 || y < 0 || x >= (long)width || y >= (long)height) return;
    unsigned char *p = rgba + 4 * ((size_t)y * width + (size_t)x);
    for (int c = 0; c < 3; c++) p[c] = (unsigned char)lrintf((float)p[c] * (1 - alpha) + 255.0f * colour[c] * alpha);
    p[3] = 255;
}

static void draw_line(unsigned char *rgba, unsigned width, unsigned height, double x0, double y0, double x1, double y1,
                      const float colour[3], float alpha)
{
    double length = fmax(fabs(x1 - x0), fabs(y1 - y0));
    long steps = (long)ceil(length);
    if (steps > 100000) steps = 100000;
    for (long s = 0; s <= steps; s++) {
        double u = steps ? (double)s / (double)steps : 0;
        blend_pixel(rgba, width, height, lrint(x0 + u * (x1 - x0)), lrint(y0 + u * (y1 - y0)), colour, alpha);
    }
}

void lk_terrain_map_size(const lk_terrain *t, unsigned width, unsigned *height)
{
    if (!height) return;
    *height = 0;
    if (!t || width == 0) return;
    double extent_x = (double)(t->size - 1) * t->spacing_x, extent_y = (double)(t->size - 1) * t->spacing_y;
    double h = ceil((double)width * extent_y / extent_x);
    *height = h < 1 ? 1 : h > 16384 ? 16384 : (unsigned)h;
}

lk_status lk_terrain_draw_map(const lk_terrain *t, const lk_terrain_view *view, const lk_mesh *mesh, double tolerance,
                              unsigned width, unsigned char *rgba, lk_terrain_crack_stats *cracks, lk_error *error)
{
    if (!t || !rgba || width == 0) return lk_error_set(error, LK_ERR_INVALID, "lk_terrain_draw_map: bad argument");
    unsigned height;
    lk_terrain_map_size(t, width, &height);
    double last = (double)(t->size - 1);
    double light[3] = {-0.5, 0.5, 0.70710678};
    /* shaded relief, north up */
    for (unsigned y = 0; y < height; y++)
        for (unsigned x = 0; x < width; x++) {
            size_t i = (size_t)lrint(((double)x + 0.5) / width * last);
            size_t j = (size_t)lrint((1.0 - ((double)y + 0.5) / height) * last);
            if (i > t->size - 1) i = t->size - 1;
            if (j > t->size - 1) j = t->size - 1;
            size_t i0 = i ? i - 1 : 0, i1 = i + 1 < t->size ? i + 1 : i, j0 = j ? j - 1 : 0,
                   j1 = j + 1 < t->size ? j + 1 : j;
            double gx = ((double)height_at(t, (uint32_t)i1, (uint32_t)j) - height_at(t, (uint32_t)i0, (uint32_t)j)) /
                        ((double)(i1 - i0) * t->spacing_x);
            double gy = ((double)height_at(t, (uint32_t)i, (uint32_t)j1) - height_at(t, (uint32_t)i, (uint32_t)j0)) /
                        ((double)(j1 - j0) * t->spacing_y);
            /* slopes exaggerated so that gentle relief still shows */
            double exaggeration = 20.0;
            double n[3] = {-gx * exaggeration, -gy * exaggeration, 1.0};
            double lit = (n[0] * light[0] + n[1] * light[1] + n[2]) / sqrt(n[0] * n[0] + n[1] * n[1] + 1.0);
            double shade = 0.45 + 0.55 * fmax(0.0, lit);
            float rgb[3];
            ramp(height_at(t, (uint32_t)i, (uint32_t)j), t->max_height, rgb);
            unsigned char *p = rgba + 4 * ((size_t)y * width + x);
            for (int c = 0; c < 3; c++) p[c] = (unsigned char)lrint(255.0 * fmin(1.0, rgb[c] * shade));
            p[3] = 255;
        }
    double sx = (double)width / last, sy = (double)height / last;
    /* the quadtree: every leaf's square */
    const float ink[3] = {0.05f, 0.05f, 0.08f};
    for (size_t k = 0; k < t->leaf_count; k++) {
        const terrain_leaf *leaf = &t->leaves[k];
        uint32_t r = half_size(t, leaf->level);
        double x0 = 2.0 * leaf->a * r * sx, x1 = (2.0 * leaf->a + 2) * r * sx;
        double y0 = height - 2.0 * leaf->b * r * sy, y1 = height - (2.0 * leaf->b + 2) * r * sy;
        draw_line(rgba, width, height, x0, y0, x1, y0, ink, 0.55f);
        draw_line(rgba, width, height, x1, y0, x1, y1, ink, 0.55f);
        draw_line(rgba, width, height, x1, y1, x0, y1, ink, 0.55f);
        draw_line(rgba, width, height, x0, y1, x0, y0, ink, 0.55f);
    }
    /* the eye and its view direction */
    if (view) {
        const float white[3] = {1, 1, 1};
        double ex = (view->eye[0] - t->origin_x) / t->spacing_x * sx;
        double ey = height - (view->eye[1] - t->origin_y) / t->spacing_y * sy;
        /* direction in pixels (the map may scale x and y differently) */
        double dx = (view->target[0] - view->eye[0]) / t->spacing_x * sx;
        double dy = -(view->target[1] - view->eye[1]) / t->spacing_y * sy;
        double length = sqrt(dx * dx + dy * dy);
        if (length > 0) {
            double reach = 0.08 * width;
            draw_line(rgba, width, height, ex, ey, ex + dx / length * reach, ey + dy / length * reach, white, 1.0f);
        }
        for (long oy = -3; oy <= 3; oy++)
            for (long ox = -3; ox <= 3; ox++)
                if (ox * ox + oy * oy <= 9)
                    blend_pixel(rgba, width, height, lrint(ex) + ox, lrint(ey) + oy, white, 1.0f);
    }
    /* cracks: red rings */
    if (mesh) {
        lk_terrain_crack_stats found;
        uint64_t *places = NULL;
        lk_status status = find_cracks(t, mesh, tolerance, &found, &places, error);
        if (status != LK_OK) return status;
        const float red[3] = {1.0f, 0.0f, 0.0f};
        for (size_t k = 0; k < found.cracks; k++) {
            double px = (double)(places[k] % t->size) * sx, py = height - (double)(places[k] / t->size) * sy;
            for (long oy = -3; oy <= 3; oy++)
                for (long ox = -3; ox <= 3; ox++) {
                    long d2 = ox * ox + oy * oy;
                    if (d2 <= 10 && d2 >= 4)
                        blend_pixel(rgba, width, height, lrint(px) + ox, lrint(py) + oy, red, 1.0f);
                }
        }
        free(places);
        if (cracks) *cracks = found;
    }
    return LK_OK;
}
