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
 * Importance. Floating cells follow Low & Tan's refinement of Rossignac &
 * Borrel's weight: longest incident edge length L times cos(theta/2), theta
 * being the largest angle between two incident edges. cos(theta/2) is 0 on
 * a flat vertex (opposite edges) and near 1 at a spike, so silhouette-prone
 * vertices win the floating centres. Uniform cells weigh their average with
 * L times the length of the mean of the unit vectors along the incident
 * edges (each edge once per incident triangle): also 0 on a flat vertex and
 * near 1 at a spike, but above 0 on creases and borders too, and it comes
 * from one pass over the triangles where theta needs every vertex's edges
 * gathered first. (Over the bunny, triceratops, cow, fandisk and a dragon at
 * 0.5% to 50% it gave 4% lower RMS and the same Hausdorff distance as L&T's
 * weight for uniform cells, 12% lower RMS for floating cells but up to 2.7
 * times the Hausdorff distance on the triceratops' horns, so floating cells
 * keep L&T's.) A floor of 0.05 keeps flat vertices ordered by L instead of
 * tied at zero (it also gave slightly lower Hausdorff errors than 0 or
 * R-B's L/theta on the bunny and the triceratops).
 *
 * Triangles whose corners land in fewer than three clusters vanish, as do
 * repeats of a cluster triple in any order (the first one's orientation is
 * kept); clusters used by no surviving triangle are dropped, and vertices no
 * triangle used never join a cluster. Degenerate input triangles (a vertex
 * twice) are ignored throughout, and repeated input triangles vanish like
 * any repeat, so the input needs no cleaning copy. The result is generally
 * not a manifold: that is inherent in clustering.
 *
 * Targets: options->max_error gives the cell size s directly (fraction of the
 * bounding-box diagonal), so a vertex moves at most s*sqrt(3) (uniform) or
 * s/2 (floating). Cells finer than the model's largest extent / 2^20 are not
 * used (sizes are raised to that). Vertex or triangle targets (a ratio
 * counts the non-degenerate input triangles) are met by searching s,
 * stopping at the first exact count within 0.5% under the target. Most
 * sizes are first tried on an estimate, one pass over the triangles: those
 * whose corners fall in three distinct uniform cells of side s (s / 1.43
 * for floating cells: a ball of diameter s holds about as much surface as
 * that cube), and half as many vertices, times the ratio of the exact
 * counts to the estimate at the last exact trials (a power law in s
 * through the last two). When the targets ask for at most 1/8 of the
 * triangles, the estimate drops repeated cell triples like a trial (cheap
 * then), so uniform searches are exact throughout. An estimated search
 * starts from sqrt(area / target) (rounded to a power of 2^(1/16)) and
 * takes power-law steps (count ~ s^-k, k from the last two trials, 2 at
 * first) until the target is bracketed, then at most 3 secant steps on log
 * count over log s; the size it ends on gets an exact trial, and once two
 * exact trials bracket the target the secant runs between them
 * (Illinois-safeguarded). At most 40 trials, exact or estimated. A
 * uniform trial computes every vertex's packed cell coordinates, keeps the
 * triangles with three distinct ones and drops repeated key sets with a
 * hash table sized to those triangles; a floating trial buckets the
 * vertices in a grid of twice the ball's diameter (a dense array when
 * the box holds at most 4 of its cells a vertex, else a hash table) and
 * takes the balls in importance order, each scanning the 1 to 8 buckets
 * its box meets. Both cost O(V + T), and hash tables keyed by cell mean
 * sparse models never allocate a large dense grid. The count is not
 * monotonic in s, so the best exact trial is kept: the closest count not
 * above the target when within 2%, else the closest non-empty count, with
 * target_reached = 0. When a count and
 * max_error are both set, the finer of the two cell sizes wins (the first
 * rule reached while coarsening). result->error is the largest distance
 * from a kept vertex to its representative. If every triangle vanishes the
 * result is an empty mesh (no vertices, no triangles, every vertex_map entry
 * UINT32_MAX) with target_reached = 0. */
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
/* Trials of the cell-size search, and the count tolerance for target_reached. */
#define MAX_TRIALS 40
#define TARGET_TOLERANCE 0.02
/* The search stops at the first count this close under the target: every
 * trial costs a pass over the mesh, and the last few tenths of a percent
 * change the error by less than the grid's placement does. */
#define STOP_TOLERANCE 0.005
/* Secant steps of an estimated search (unless its counts are exact): the
 * estimates are too coarse for more; and its estimates in all. */
#define MAX_ESTIMATES 3
#define MAX_SEARCH_ESTIMATES 8
/* Estimated searches before the search goes on with exact trials only. */
#define ESTIMATED_ROUNDS 2
/* Smallest step of the bracketing search (a scale factor); it doubles (in
 * log) while the count does not change, as small counts move in jumps. */
#define MIN_STEP 1.002
/* The search's uniform counts are exact when the targets ask for at most
 * 1 / EXACT_FRACTION of the triangles (see count_proxy). */
#define EXACT_FRACTION 8
/* Bound on the fitted drift of the estimate's ratios (see search_state). */
#define MAX_RATIO_SLOPE 2.0
/* Floating cells estimate their counts from uniform cells this many times
 * smaller: a ball of diameter s holds about as much surface as a cube of
 * side s / 1.4 (measured 1.39 to 1.46 on the bunny at 1% to 50%). */
#define FLOATING_SIZE_RATIO 1.43
/* Candidates whose place in the repeat table is fetched ahead. */
#define DEDUP_AHEAD 8
/* Vertices whose cell's place in the cell table is fetched ahead. */
#define CELL_AHEAD 8
/* Floating cells bucket the vertices in a grid this many ball diameters
 * wide: a ball then meets 1 to 8 cells, 3.4 on average, and a bucket's
 * vertices are read in one sweep (on the 1.1M-triangle bunny, 2 took 40%
 * less time than 1). */
#define FLOATING_BUCKET_SIDE 2.0

typedef enum cluster_method { CLUSTER_UNIFORM, CLUSTER_FLOATING } cluster_method;

typedef struct cell_entry {
    uint64_t key;
    uint32_t value; /* NO_CLUSTER = empty slot */
} cell_entry;

/* A vertex in a floating trial's bucket: position and place in order[]
 * side by side, one fetch for both. */
typedef struct bucket_member {
    float position[3];
    uint32_t rank;
} bucket_member;

typedef struct clusterer {
    const lk_mesh *mesh;
    cluster_method method;
    size_t used_count;   /* vertices referenced by a non-degenerate triangle */
    size_t solid_count;  /* triangles with three distinct corners */
    double area;         /* of those */
    unsigned char *used; /* per vertex */
    double *importance;  /* per vertex, 0 when unused (in vertex_key's block) */
    uint32_t *order;     /* floating: used vertices by decreasing importance */
    double origin[3];    /* bounding-box minimum of the used vertices */
    double extent[3];    /* sides of that box (0 when no vertex is used) */
    double extent_max;   /* largest side of that box */
    /* Per-trial workspace, allocated once. */
    uint64_t *vertex_key; /* per vertex: cell key (uniform search) or cluster id; the block holds importance[] */
    uint32_t *kept;       /* triangles a trial keeps, in input order */
    /* dedup and cells share one block (`tables`, of table_bytes): a trial
     * is done with the one before it fills the other, so the pages the
     * search wrote serve the final run and the averages (build_output)
     * instead of fresh ones. */
    void *tables;
    size_t table_bytes;
    uint64_t *dedup;       /* kept triangles by the hash of their key set */
    size_t dedup_capacity; /* power of two >= 1.5 * triangle_count: keep_listed_triangles' largest table */
    uint64_t *key_set;     /* distinct keys of the kept triangles (key + 1, 0 = empty) */
    size_t key_set_capacity;
    cell_entry *cells;           /* hash table of grid cells */
    size_t cell_capacity;        /* power of two >= 2 * used_count */
    size_t cell_mask;            /* the part in use: a power of two minus 1 */
    size_t bucket_estimate;      /* floating: buckets of the last trial, at... */
    double bucket_estimate_size; /* ...this cell size */
    double counted_size;         /* the last count_trial's cell size, -1 = none */
    double kept_clusters_size;   /* floating: the cell size whose clusters' triangles kept[] holds, -1 = none */
    size_t candidate_count;      /* the last keep_triangles' triangles with three distinct keys */
    uint64_t *candidate_hash;    /* their key sets' hashes, when candidates_hashed */
    bool candidates_hashed;      /* (list_candidates computed them) */
    uint32_t *vertex_slot;       /* floating: a used vertex's bucket while bucketing */
    uint32_t *rank;              /* floating: a used vertex's place in order[] */
    float *ranked_position;      /* floating: positions in order[] */
    unsigned char *taken;        /* floating: per rank, clustered yet */
    uint32_t *bucket_offsets;    /* floating: used_count + 1 */
    uint32_t *bucket_first;      /* floating: a bucket's first unclustered place (clustered ones go first) */
    bucket_member *bucketed;     /* floating: the used vertices bucket by bucket */
    uint32_t *member_cluster;    /* floating: the cluster of bucketed[i]'s vertex */
    uint32_t *dense_buckets;     /* floating: bucket of every grid cell when the box holds few cells */
    size_t dense_capacity;       /* its length */
    uint32_t *cluster_of;        /* per vertex: its cluster in a trial, its output vertex after run_trial */
    uint32_t *centre;            /* per cluster (output vertex after run_trial): floating centre / most
                             important member */
    size_t cluster_count;
    uint32_t *triangles; /* cluster triples of the surviving triangles */
    size_t triangle_count;
    uint32_t *cluster_index; /* per cluster: output vertex or NO_CLUSTER */
    size_t vertex_count;     /* clusters used by a surviving triangle */
} clusterer;

static void clusterer_free(clusterer *c)
{
    free(c->used);
    free(c->order);
    free(c->vertex_key);
    free(c->kept);
    free(c->candidate_hash);
    free(c->tables);
    free(c->key_set);
    free(c->vertex_slot);
    free(c->bucket_offsets);
    free(c->bucket_first);
    free(c->bucketed);
    free(c->dense_buckets);
    free(c->member_cluster);
    free(c->rank);
    free(c->ranked_position);
    free(c->taken);
    free(c->cluster_of);
    free(c->centre);
    free(c->triangles);
    free(c->cluster_index);
}

/* Decreasing importance, then increasing index (a total, deterministic
 * order): a stable radix sort of the importances' bit patterns, which order
 * like the values as these are never negative. Its keys and the indices'
 * second copy live in the tables' block (20 bytes per used vertex of its
 * 32 or more), whose pages the trials then reuse; digits are 16 bits wide
 * from 2^20 vertices (4 passes), else 11 (6 passes): a 16-bit histogram
 * is a megabyte of fresh pages, 256 page faults, more than a small mesh's
 * two extra passes cost. */
#define WIDE_DIGITS_FROM ((size_t)1 << 20)
static lk_status sort_by_importance(clusterer *c, lk_error *error)
{
    size_t count = c->used_count;
    unsigned digit_bits = count >= WIDE_DIGITS_FROM ? 16 : 11;
    unsigned passes = (64 + digit_bits - 1) / digit_bits;
    size_t radix = (size_t)1 << digit_bits;
    uint64_t digit_mask = radix - 1;
    uint32_t *histogram = lk__calloc_array(passes * radix, sizeof(uint32_t));
    if (!histogram) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering order");
    uint64_t *keys = c->tables, *key_swap = keys + count; /* table_bytes >= 32 * used_count */
    uint32_t *swap = (uint32_t *)(key_swap + count);
    size_t next = 0;
    for (size_t v = 0; v < c->mesh->vertex_count; v++) {
        if (!c->used[v]) continue;
        uint64_t bits;
        memcpy(&bits, &c->importance[v], sizeof bits);
        keys[next] = ~bits; /* descending */
        c->order[next++] = (uint32_t)v;
        for (unsigned pass = 0; pass < passes; pass++)
            histogram[radix * pass + ((~bits >> (digit_bits * pass)) & digit_mask)]++;
    }
    uint64_t *from_keys = keys, *to_keys = key_swap;
    uint32_t *from = c->order, *to = swap;
    for (unsigned pass = 0; pass < passes; pass++) {
        uint32_t *counts = histogram + radix * pass;
        unsigned shift = digit_bits * pass;
        if (count && counts[(from_keys[0] >> shift) & digit_mask] == count) continue; /* one digit: nothing moves */
        uint32_t total = 0;
        for (size_t d = 0; d < radix; d++) {
            uint32_t n = counts[d];
            counts[d] = total;
            total += n;
        }
        for (size_t i = 0; i < count; i++) {
            uint32_t place = counts[(from_keys[i] >> shift) & digit_mask]++;
            to_keys[place] = from_keys[i];
            to[place] = from[i];
        }
        uint64_t *k = from_keys;
        from_keys = to_keys, to_keys = k;
        uint32_t *o = from;
        from = to, to = o;
    }
    if (from != c->order) memcpy(c->order, from, count * sizeof(uint32_t));
    for (size_t i = 0; i < count; i++) {
        c->rank[c->order[i]] = (uint32_t)i;
        memcpy(c->ranked_position + 3 * i, c->mesh->positions + 3 * (size_t)c->order[i], 3 * sizeof(float));
    }
    free(histogram);
    return LK_OK;
}

/* The box of the used vertices: the grid's origin and largest extent. */
static void compute_box(clusterer *c)
{
    double low[3] = {INFINITY, INFINITY, INFINITY}, high[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < c->mesh->vertex_count; v++) {
        if (!c->used[v]) continue;
        for (int k = 0; k < 3; k++) {
            double x = c->mesh->positions[3 * v + k];
            if (x < low[k]) low[k] = x;
            if (x > high[k]) high[k] = x;
        }
    }
    c->extent_max = 0;
    for (int k = 0; k < 3; k++) {
        c->origin[k] = low[k];
        c->extent[k] = high[k] - low[k] >= 0 ? high[k] - low[k] : 0;
        if (c->extent[k] > c->extent_max) c->extent_max = c->extent[k];
    }
}

/* ---- one clustering trial ----------------------------------------------- */

/* Grid coordinate of x (model units, already scaled): floor, clamped to the
 * packed range (NaN-safe; truncation is floor once non-negative). */
static uint64_t grid_coordinate(double x)
{
    /* Without branches: every vertex takes this path once per trial. */
    double clamped = x >= 0 ? x : 0; /* rounding at the box minimum */
    clamped = clamped < (double)(CELL_LIMIT - 2) ? clamped : (double)(CELL_LIMIT - 2);
    return (uint64_t)(int64_t)clamped;
}

/* Grid coordinates of position p in cells of side 1 / inverse_size. */
static void grid_cell(const clusterer *c, const float *p, double inverse_size, uint64_t cell[3])
{
    for (int k = 0; k < 3; k++) cell[k] = grid_coordinate(((double)p[k] - c->origin[k]) * inverse_size);
}

static uint64_t cell_key(const clusterer *c, const float *p, double inverse_size)
{
    uint64_t cell[3];
    grid_cell(c, p, inverse_size, cell);
    return cell[0] | cell[1] << CELL_BITS | cell[2] << (2 * CELL_BITS);
}

/* Entry of `key` in the cell table: its own, or the empty one to fill. */
static cell_entry *cell_find(const clusterer *c, uint64_t key)
{
    size_t slot = lk__mix64(key) & c->cell_mask;
    while (c->cells[slot].value != NO_CLUSTER && c->cells[slot].key != key) slot = (slot + 1) & c->cell_mask;
    return c->cells + slot;
}

/* Cell id of `key`, numbering new cells from *count. */
static uint32_t cell_insert(clusterer *c, uint64_t key, size_t *count)
{
    cell_entry *entry = cell_find(c, key);
    if (entry->value == NO_CLUSTER) {
        entry->key = key;
        entry->value = (uint32_t)(*count)++;
    }
    return entry->value;
}

/* Empties the cell table, sized for about `expected` cells: a small table
 * stays in cache. */
static void reset_cells(clusterer *c, size_t expected)
{
    size_t size = 16;
    while (size < expected + expected / 2 && size < c->cell_capacity) size *= 2;
    c->cell_mask = size - 1;
    for (size_t i = 0; i < size; i++) c->cells[i].value = NO_CLUSTER;
}

/* Whether the cell table holding `count` cells is too full for quick
 * probes and could grow. */
static bool cells_crowded(const clusterer *c, size_t count)
{
    return 10 * count > 7 * (c->cell_mask + 1) && c->cell_mask + 1 < c->cell_capacity;
}

static inline void prefetch(const void *address)
{
#ifdef __GNUC__
    __builtin_prefetch(address);
#else
    (void)address;
#endif
}

static void sort3_u64(uint64_t v[3])
{
    uint64_t s;
    if (v[0] > v[1]) s = v[0], v[0] = v[1], v[1] = s;
    if (v[1] > v[2]) s = v[1], v[1] = v[2], v[2] = s;
    if (v[0] > v[1]) s = v[0], v[0] = v[1], v[1] = s;
}

static void sorted_keys(const clusterer *c, uint32_t t, uint64_t out[3])
{
    const uint32_t *corners = c->mesh->indices + 3 * (size_t)t;
    for (int k = 0; k < 3; k++) out[k] = c->vertex_key[corners[k]];
    sort3_u64(out);
}

/* Hash of a key set in any order: the sum of the keys' mixes. Sorting the
 * keys first (three compare-and-swaps whose branches the data decide) and
 * mixing them in a chain took a sixth of a uniform trial's time on the
 * bunny; the three mixes here are independent and the sum commutes. Only
 * the dedup table's probing depends on the hash (a matching fingerprint is
 * confirmed on the keys), so the triangles kept do not. */
static uint64_t key_set_hash(uint64_t a, uint64_t b, uint64_t d) { return lk__mix64(a) + lk__mix64(b) + lk__mix64(d); }

/* The triangles a trial keeps, from vertex_key[] (a cluster's key per used
 * vertex): those whose corners have three distinct keys, the first of each
 * key set in input order. list_candidates lists those with three distinct
 * keys in kept[] (with `hashed`, their key sets' hashes in
 * candidate_hash[], for keep_listed_triangles: the keys are at hand here,
 * and read again there only to confirm a repeat), keep_listed_triangles
 * drops the repeats and sets triangle_count; with count_vertices,
 * vertex_count gets the number of keys they use. Degenerate input
 * triangles repeat a vertex, hence a key: never kept. */
static size_t list_candidates(clusterer *c, bool hashed)
{
    const uint32_t *indices = c->mesh->indices;
    const uint64_t *key = c->vertex_key;
    size_t triangle_count = c->mesh->triangle_count, candidate_count = 0;
    /* When many triangles are candidates (a large target), without a
     * branch: hashing every triangle costs less than mispredicting which
     * ones to hash; when few are (the last listing's share, under an
     * eighth), the branch is predictable and the hashes are skipped. */
    if (hashed && 8 * c->candidate_count > triangle_count) {
        for (size_t t = 0; t < triangle_count; t++) {
            uint64_t a = key[indices[3 * t]], b = key[indices[3 * t + 1]], d = key[indices[3 * t + 2]];
            c->candidate_hash[candidate_count] = key_set_hash(a, b, d);
            c->kept[candidate_count] = (uint32_t)t;
            candidate_count += (a != b) & (b != d) & (a != d);
        }
    } else if (hashed) {
        for (size_t t = 0; t < triangle_count; t++) {
            uint64_t a = key[indices[3 * t]], b = key[indices[3 * t + 1]], d = key[indices[3 * t + 2]];
            if (a == b || b == d || a == d) continue;
            c->candidate_hash[candidate_count] = key_set_hash(a, b, d);
            c->kept[candidate_count++] = (uint32_t)t;
        }
    } else {
        /* Without a branch: about every other triangle is one when the
         * targets ask for many. */
        for (size_t t = 0; t < triangle_count; t++) {
            uint64_t a = key[indices[3 * t]], b = key[indices[3 * t + 1]], d = key[indices[3 * t + 2]];
            c->kept[candidate_count] = (uint32_t)t;
            candidate_count += (a != b) & (b != d) & (a != d);
        }
    }
    c->candidate_count = candidate_count;
    c->candidates_hashed = hashed;
    c->kept_clusters_size = -1;
    return candidate_count;
}

/* keep_triangles once list_candidates has run. */
static void keep_listed_triangles(clusterer *c, bool count_vertices)
{
    const uint32_t *indices = c->mesh->indices;
    const uint64_t *key = c->vertex_key;
    size_t candidate_count = c->candidate_count;
    size_t size = 16;
    while (size < candidate_count + candidate_count / 2) size *= 2;
    size_t mask = size - 1;
    memset(c->dedup, 0, size * sizeof(uint64_t));
    if (!c->candidates_hashed) { /* listed for an estimate only */
        for (size_t i = 0; i < candidate_count; i++) {
            const uint32_t *corners = indices + 3 * (size_t)c->kept[i];
            c->candidate_hash[i] = key_set_hash(key[corners[0]], key[corners[1]], key[corners[2]]);
        }
        c->candidates_hashed = true;
    }
    size_t kept = 0;
    /* The table is far larger than the caches: the slots of the next
     * DEDUP_AHEAD candidates are fetched while this one is probed. */
    const uint64_t *hashes = c->candidate_hash;
    for (size_t i = 0; i < DEDUP_AHEAD && i < candidate_count; i++) prefetch(c->dedup + (hashes[i] & mask));
    for (size_t i = 0; i < candidate_count; i++) {
        uint32_t t = c->kept[i];
        uint64_t hash = hashes[i];
        if (i + DEDUP_AHEAD < candidate_count) prefetch(c->dedup + (hashes[i + DEDUP_AHEAD] & mask));
        /* An entry: the hash's high half, then the triangle + 1 (0 = empty). */
        uint64_t fingerprint = hash & 0xFFFFFFFF00000000u;
        size_t slot = hash & mask;
        bool repeat = false;
        for (; c->dedup[slot] != 0; slot = (slot + 1) & mask) {
            if ((c->dedup[slot] & 0xFFFFFFFF00000000u) != fingerprint) continue;
            uint64_t mine[3], other[3];
            sorted_keys(c, t, mine);
            sorted_keys(c, (uint32_t)(c->dedup[slot] & 0xFFFFFFFFu) - 1, other);
            if (other[0] == mine[0] && other[1] == mine[1] && other[2] == mine[2]) {
                repeat = true;
                break;
            }
        }
        if (repeat) continue;
        c->dedup[slot] = fingerprint | ((uint64_t)t + 1);
        c->kept[kept++] = t;
    }
    c->triangle_count = kept;
    if (!count_vertices) return;
    size = 16;
    while (size < 2 * 3 * kept && size < c->key_set_capacity) size *= 2;
    mask = size - 1;
    memset(c->key_set, 0, size * sizeof(uint64_t));
    size_t vertices = 0;
    for (size_t i = 0; i < 3 * kept; i++) {
        uint64_t stored = key[indices[3 * (size_t)c->kept[i / 3] + i % 3]] + 1;
        size_t slot = lk__mix64(stored) & mask;
        while (c->key_set[slot] != 0 && c->key_set[slot] != stored) slot = (slot + 1) & mask;
        if (c->key_set[slot] == 0) {
            c->key_set[slot] = stored;
            vertices++;
        }
    }
    c->vertex_count = vertices;
}

static void keep_triangles(clusterer *c, bool count_vertices)
{
    list_candidates(c, true);
    keep_listed_triangles(c, count_vertices);
}

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

/* Counts only (the search): a uniform cell's key is its packed coordinates,
 * so no table is needed to tell cells apart. */
static void count_uniform(clusterer *c, double cell_size, bool count_vertices)
{
    double inverse_size = 1.0 / cell_size;
    const float *positions = c->mesh->positions;
    for (size_t v = 0; v < c->mesh->vertex_count; v++)
        if (c->used[v]) c->vertex_key[v] = cell_key(c, positions + 3 * v, inverse_size);
    keep_triangles(c, count_vertices);
}

/* Estimated counts (the search): the triangles whose corners fall in
 * three distinct uniform cells of `cell_size`, repeats included, listed in
 * kept[]; every vertex's key is overwritten (unused ones are in no counted
 * triangle). */
static size_t count_candidates(clusterer *c, double cell_size, bool hashed)
{
    double inverse_size = 1.0 / cell_size;
    const float *positions = c->mesh->positions;
    uint64_t *key = c->vertex_key;
    for (size_t v = 0; v < c->mesh->vertex_count; v++) key[v] = cell_key(c, positions + 3 * v, inverse_size);
    return list_candidates(c, hashed);
}

/* Floating buckets of side 1 / inverse_size numbered through a dense grid
 * (dims[] cells per axis) when the box holds at most dense_capacity cells:
 * a ball's lookups are then reads of a small array, where the hash table's
 * probes missed the cache (a fifth of the balls' time on the 1.1M-triangle
 * bunny). Every vertex's cell coordinate is at most the box side times
 * inverse_size, the same product: below dims[]. */
static bool dense_grid(const clusterer *c, double inverse_size, size_t dims[3])
{
    double cells = 1;
    for (int k = 0; k < 3; k++) {
        dims[k] = (size_t)grid_coordinate(c->extent[k] * inverse_size) + 1;
        cells *= (double)dims[k];
    }
    if (!(cells <= (double)c->dense_capacity)) return false;
    for (size_t i = 0; i < dims[0] * dims[1] * dims[2]; i++) c->dense_buckets[i] = NO_CLUSTER;
    return true;
}

/* Low & Tan's greedy balls. The used vertices are bucketed in a grid of
 * side = the ball's diameter (stored bucket by bucket, positions copied,
 * vertex order kept within a bucket), so a ball meets at most 2 cells per
 * axis: the cells its bounding box touches. */
static void assign_floating(clusterer *c, double cell_size)
{
    const float *positions = c->mesh->positions;
    size_t vertex_count = c->mesh->vertex_count;
    double radius = cell_size / 2, radius_squared = radius * radius;
    double bucket_side = FLOATING_BUCKET_SIDE * cell_size, inverse_size = 1.0 / bucket_side;
    /* About as many buckets as the last trial's, scaled by the cell area
     * (first trial: a few per cell-sized patch of surface). */
    double expected = c->bucket_estimate
                          ? (double)c->bucket_estimate * pow(c->bucket_estimate_size / cell_size, 2) * 1.25
                          : 3 * c->area / (bucket_side * bucket_side);
    size_t bucket_count, dims[3];
    bool dense = dense_grid(c, inverse_size, dims);
    for (;;) {
        if (dense) {
            bucket_count = 0;
            for (size_t v = 0; v < vertex_count; v++) {
                if (!c->used[v]) continue;
                uint64_t coordinates[3];
                grid_cell(c, positions + 3 * v, inverse_size, coordinates);
                size_t cell = (size_t)(coordinates[0] + dims[0] * (coordinates[1] + dims[1] * coordinates[2]));
                uint32_t bucket = c->dense_buckets[cell];
                if (bucket == NO_CLUSTER) {
                    bucket = c->dense_buckets[cell] = (uint32_t)bucket_count++;
                    c->bucket_offsets[bucket + 1] = 0;
                }
                c->vertex_slot[v] = bucket;
                c->bucket_offsets[bucket + 1]++;
            }
            break;
        }
        reset_cells(c, expected < (double)c->used_count ? (size_t)expected + 16 : c->used_count);
        bucket_count = 0;
        uint64_t last_key = UINT64_MAX;
        uint32_t last_bucket = 0;
        size_t v;
        for (v = 0; v < vertex_count; v++) {
            if (!c->used[v]) continue;
            uint64_t key = cell_key(c, positions + 3 * v, inverse_size);
            if (key != last_key) { /* neighbouring vertices often share a cell */
                size_t before = bucket_count;
                last_bucket = cell_insert(c, key, &bucket_count);
                last_key = key;
                if (bucket_count != before) {
                    c->bucket_offsets[last_bucket + 1] = 0;
                    if (cells_crowded(c, bucket_count)) break;
                }
            }
            c->vertex_slot[v] = last_bucket; /* the bucket for now */
            c->bucket_offsets[last_bucket + 1]++;
        }
        if (v == vertex_count) break;
        expected = 2.0 * (double)(c->cell_mask + 1); /* start over in a table 4 times larger */
    }
    c->bucket_estimate = bucket_count, c->bucket_estimate_size = cell_size;
    c->bucket_offsets[0] = 0;
    for (size_t b = 0; b < bucket_count; b++) c->bucket_offsets[b + 1] += c->bucket_offsets[b];
    memcpy(c->bucket_first, c->bucket_offsets, bucket_count * sizeof(uint32_t));
    for (size_t v = 0; v < vertex_count; v++) {
        if (!c->used[v]) continue;
        uint32_t place = c->bucket_first[c->vertex_slot[v]]++;
        c->bucketed[place].rank = c->rank[v];
        memcpy(c->bucketed[place].position, positions + 3 * v, 3 * sizeof(float));
    }
    memcpy(c->bucket_first, c->bucket_offsets, bucket_count * sizeof(uint32_t));

    memset(c->taken, 0, c->used_count);
    for (size_t v = 0; v < vertex_count; v++) c->cluster_of[v] = NO_CLUSTER;
    uint32_t *member_cluster = c->member_cluster;
    size_t count = 0;
    for (size_t i = 0; i < c->used_count; i++) {
        uint32_t centre = c->order[i];
        if (c->taken[i]) continue; /* read in order: no cache miss */
        uint32_t id = (uint32_t)count++;
        c->centre[id] = centre; /* taken below with the rest of its ball */
        const float *p = c->ranked_position + 3 * i;
        /* In locals: the stores below could alias p for all the compiler
         * knows, so it would reload and convert it for every member. */
        const double px = p[0], py = p[1], pz = p[2];
        uint64_t low[3], high[3];
        for (int k = 0; k < 3; k++) {
            /* A little wider than the ball, against rounding. */
            low[k] = grid_coordinate(((double)p[k] - radius - c->origin[k]) * inverse_size - 1e-9);
            high[k] = grid_coordinate(((double)p[k] + radius - c->origin[k]) * inverse_size + 1e-9);
        }
        if (dense)
            for (int k = 0; k < 3; k++) high[k] = high[k] < dims[k] - 1 ? high[k] : dims[k] - 1;
        for (uint64_t z = low[2]; z <= high[2]; z++)
            for (uint64_t y = low[1]; y <= high[1]; y++)
                for (uint64_t x = low[0]; x <= high[0]; x++) {
                    uint32_t bucket = dense ? c->dense_buckets[x + dims[0] * (y + dims[1] * z)]
                                            : cell_find(c, x | y << CELL_BITS | z << (2 * CELL_BITS))->value;
                    if (bucket == NO_CLUSTER) continue;
                    /* A bucket keeps its clustered vertices first: a vertex
                     * taken swaps places with the first free one. */
                    uint32_t first = c->bucket_first[bucket], end = c->bucket_offsets[bucket + 1];
                    bucket_member *members = c->bucketed;
                    for (uint32_t j = first; j < end; j++) {
                        const float *q = members[j].position;
                        double d0 = (double)q[0] - px, d1 = (double)q[1] - py, d2 = (double)q[2] - pz;
                        if (d0 * d0 + d1 * d1 + d2 * d2 > radius_squared) continue;
                        uint32_t taken = members[j].rank;
                        c->taken[taken] = 1;
                        bucket_member swap = members[j];
                        members[j] = members[first];
                        member_cluster[first] = id;
                        members[first++] = swap;
                    }
                    c->bucket_first[bucket] = first;
                }
    }
    c->cluster_count = count;
    /* Every used vertex is in a ball now. Its cluster went beside its place
     * in the buckets: setting cluster_of[] there, in the order of the balls,
     * was a cache miss per vertex in a dependent chain (a tenth of the
     * balls' time on the 1.1M-triangle bunny); here the misses overlap. */
    for (size_t place = 0; place < c->used_count; place++)
        c->cluster_of[c->order[c->bucketed[place].rank]] = member_cluster[place];
}

/* Cluster ids (cluster_of, < cluster_count, with centre[]) to the result:
 * the clusters the kept triangles use numbered in id order. */
static void number_clusters(clusterer *c, double cell_size)
{
    size_t vertex_count = c->mesh->vertex_count;
    /* The search's last exact trial is usually the size chosen: its kept
     * triangles are still listed, and listing them again is a pass over
     * the triangles. */
    if (!(cell_size > 0 && cell_size == c->kept_clusters_size)) {
        for (size_t v = 0; v < vertex_count; v++)
            if (c->used[v]) c->vertex_key[v] = c->cluster_of[v];
        keep_triangles(c, false);
    }
    const uint32_t *indices = c->mesh->indices;
    for (size_t k = 0; k < c->cluster_count; k++) c->cluster_index[k] = NO_CLUSTER;
    for (size_t i = 0; i < c->triangle_count; i++)
        for (int k = 0; k < 3; k++) c->cluster_index[c->cluster_of[indices[3 * (size_t)c->kept[i] + k]]] = 0;
    size_t count = 0;
    for (size_t k = 0; k < c->cluster_count; k++)
        if (c->cluster_index[k] != NO_CLUSTER) {
            c->centre[count] = c->centre[k]; /* count <= k */
            c->cluster_index[k] = (uint32_t)count++;
        }
    c->vertex_count = count;
    for (size_t v = 0; v < vertex_count; v++)
        if (c->cluster_of[v] != NO_CLUSTER) c->cluster_of[v] = c->cluster_index[c->cluster_of[v]];
    for (size_t i = 0; i < c->triangle_count; i++)
        for (int k = 0; k < 3; k++) c->triangles[3 * i + k] = c->cluster_of[indices[3 * (size_t)c->kept[i] + k]];
}

/* Uniform cells to the result: the cells the kept triangles use,
 * numbered in order of their first used vertex. */
static void number_cells(clusterer *c, double cell_size)
{
    if (cell_size != c->counted_size) count_uniform(c, cell_size, false);
    const uint32_t *indices = c->mesh->indices;
    const uint64_t *key = c->vertex_key;
    size_t vertex_count = c->mesh->vertex_count;
    /* Every used vertex's cell, numbered in order of first member
     * (cluster_of, for now); build_output finds each cell's most important
     * member (centre[]) as it averages, where the cell's sums are in cache
     * already. A surface has about half as many vertices as triangles: the
     * table starts at the size for that and grows if crowded. */
    size_t expected = c->triangle_count / 2 + 16, count;
    for (;;) {
        reset_cells(c, expected);
        count = 0;
        uint64_t last_key = UINT64_MAX;
        uint32_t last_cell = NO_CLUSTER;
        size_t v;
        for (v = 0; v < vertex_count; v++) {
            c->cluster_of[v] = NO_CLUSTER;
            /* The table is larger than the caches: fetch a later vertex's slot. */
            if (v + CELL_AHEAD < vertex_count) prefetch(c->cells + (lk__mix64(key[v + CELL_AHEAD]) & c->cell_mask));
            if (!c->used[v]) continue;
            if (key[v] != last_key) { /* neighbouring vertices often share a cell */
                size_t before = count;
                last_key = key[v];
                last_cell = cell_insert(c, key[v], &count);
                if (count != before && cells_crowded(c, count)) break;
            }
            c->cluster_of[v] = last_cell;
        }
        if (v == vertex_count) break;
        expected = 2 * (c->cell_mask + 1); /* start over in a table 4 times larger */
    }
    /* The cells the kept triangles use, numbered in the same order. */
    uint32_t *numbered = c->cluster_index;
    for (size_t o = 0; o < count; o++) numbered[o] = NO_CLUSTER;
    for (size_t i = 0; i < c->triangle_count; i++) {
        const uint32_t *corners = indices + 3 * (size_t)c->kept[i];
        for (int k = 0; k < 3; k++) numbered[c->cluster_of[corners[k]]] = 0;
    }
    size_t next = 0;
    for (size_t o = 0; o < count; o++)
        if (numbered[o] != NO_CLUSTER) numbered[o] = (uint32_t)next++;
    c->vertex_count = next;
    for (size_t v = 0; v < vertex_count; v++)
        if (c->cluster_of[v] != NO_CLUSTER) c->cluster_of[v] = numbered[c->cluster_of[v]];
    for (size_t i = 0; i < c->triangle_count; i++) {
        const uint32_t *corners = indices + 3 * (size_t)c->kept[i];
        for (int k = 0; k < 3; k++) c->triangles[3 * i + k] = c->cluster_of[corners[k]];
    }
}

/* The result of a cell size in model units (0 = no clustering):
 * cluster_of[v] = output vertex or NO_CLUSTER, centre[] per output vertex,
 * triangles[] in output vertices. */
static void run_trial(clusterer *c, double cell_size)
{
    if (cell_size > 0 && c->method == CLUSTER_UNIFORM) {
        number_cells(c, cell_size);
        return;
    }
    if (cell_size <= 0)
        assign_identity(c);
    else if (cell_size != c->counted_size) /* else its clusters are still there */
        assign_floating(c, cell_size);
    number_clusters(c, cell_size);
}

/* The counts of a cell size, for the search: triangle_count and, when
 * count_vertices, vertex_count. */
static void count_trial(clusterer *c, double cell_size, bool count_vertices)
{
    c->counted_size = cell_size;
    if (c->method == CLUSTER_UNIFORM) {
        count_uniform(c, cell_size, count_vertices);
        return;
    }
    assign_floating(c, cell_size);
    for (size_t v = 0; v < c->mesh->vertex_count; v++)
        if (c->used[v]) c->vertex_key[v] = c->cluster_of[v];
    keep_triangles(c, count_vertices);
    c->kept_clusters_size = cell_size;
}

/* ---- output ------------------------------------------------------------- */

static void normalize3(float *n)
{
    double length = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    if (length > 0)
        for (int k = 0; k < 3; k++) n[k] = (float)(n[k] / length);
}

/* Builds result->mesh, vertex_map and error from the last trial. The
 * trial's cluster_of[] becomes the vertex map and its triangles[] the
 * output's indices (shrunk to fit), and a uniform trial's averages are
 * summed in memory the search wrote (its cell keys, else its tables) when
 * they fit there: such pages cost no fault, and on this machine a fresh
 * 4 KiB page costs about as much as clustering 100 triangles (the bunny at
 * 10%: 421 page faults a call, 103 of them for these three). */
static lk_status build_output(clusterer *c, lk_simplify_result *result, lk_error *error)
{
    const lk_mesh *mesh = c->mesh;
    unsigned flags = (mesh->normals ? LK_ATTR_NORMALS : 0) | (mesh->texcoords ? LK_ATTR_TEXCOORDS : 0) |
                     (mesh->colors ? LK_ATTR_COLORS : 0);
    lk_status status = lk_mesh_alloc(&result->mesh, c->vertex_count, 0, flags, error);
    if (status != LK_OK) return status;
    lk_mesh *out = &result->mesh;
    /* realloc may move the block (and lose its alignment, which only
     * mattered while clustering); if it fails the block stays as it is. */
    uint32_t *indices = realloc(c->triangles, 3 * (c->triangle_count ? c->triangle_count : 1) * sizeof(uint32_t));
    free(out->indices);
    out->indices = indices ? indices : c->triangles;
    out->triangle_count = c->triangle_count;
    c->triangles = NULL;
    result->vertex_map = c->cluster_of;
    c->cluster_of = NULL;

    /* Uniform cells: weighted averages of every attribute: 1 weight, 1
     * member count, the most important member's importance and index (the
     * first one on ties: the centre), 3 position sums per output vertex,
     * then 3 normal, 2 texcoord and 4 colour sums for the attributes there
     * are. */
    enum { W = 0, COUNT = 1, BEST = 2, CENTRE = 3, P = 4 };
    const size_t N = 7, UV = N + (mesh->normals ? 3 : 0), RGBA = UV + (mesh->texcoords ? 2 : 0),
                 STRIDE = RGBA + (mesh->colors ? 4 : 0);
    double *sums = NULL, *allocated_sums = NULL;
    if (c->method == CLUSTER_UNIFORM && c->vertex_count > 0) {
        /* The keys' half of vertex_key's block (the importances are in the
         * other half): every trial wrote it, and the keys are done with;
         * else the tables' block, which the trials wrote in part. */
        size_t sum_bytes = STRIDE * c->vertex_count * sizeof(double);
        if (sum_bytes <= mesh->vertex_count * sizeof(uint64_t))
            sums = (double *)c->vertex_key;
        else if (sum_bytes <= c->table_bytes)
            sums = c->tables;
        if (sums)
            memset(sums, 0, sum_bytes);
        else if (!(sums = allocated_sums = lk__alloc_random_access(c->vertex_count, STRIDE * sizeof(double), true)))
            return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate cluster averages");
        /* A cluster of zero total weight (coincident points) averages
         * evenly: a second pass, with weight 1, for those only. */
        bool any_weightless = false;
        for (int pass = 0; pass < 2; pass++) {
            for (size_t v = 0; v < mesh->vertex_count; v++) {
                uint32_t o = result->vertex_map[v];
                if (o == NO_CLUSTER) continue;
                double *sum = sums + STRIDE * (size_t)o;
                double weight = c->importance[v];
                if (pass == 1) {
                    if (sum[W] > 0) continue;
                    weight = 1;
                } else {
                    /* Selects, not a branch the data would decide. */
                    bool better = sum[COUNT] == 0 || weight > sum[BEST];
                    sum[BEST] = better ? weight : sum[BEST];
                    sum[CENTRE] = better ? (double)v : sum[CENTRE];
                }
                sum[W] += weight;
                sum[COUNT] += 1;
                for (int k = 0; k < 3; k++) sum[P + k] += weight * mesh->positions[3 * v + k];
                if (mesh->normals)
                    for (int k = 0; k < 3; k++) sum[N + k] += weight * mesh->normals[3 * v + k];
                if (mesh->texcoords)
                    for (int k = 0; k < 2; k++) sum[UV + k] += weight * mesh->texcoords[2 * v + k];
                if (mesh->colors)
                    for (int k = 0; k < 4; k++) sum[RGBA + k] += weight * mesh->colors[4 * v + k];
            }
            if (pass == 1) break;
            for (size_t o = 0; o < c->vertex_count; o++) {
                double *sum = sums + STRIDE * o;
                c->centre[o] = (uint32_t)sum[CENTRE];
                if (sum[W] > 0) continue;
                any_weightless = true;
                memset(sum, 0, STRIDE * sizeof(double));
            }
            if (!any_weightless) break;
        }
    }

    /* Start every output vertex as a copy of its cluster's centre: final for
     * floating cells, and the fall-back for degenerate averages. */
    for (size_t o = 0; o < c->vertex_count; o++) {
        uint32_t centre = c->centre[o];
        memcpy(out->positions + 3 * o, mesh->positions + 3 * (size_t)centre, 3 * sizeof(float));
        if (out->normals) memcpy(out->normals + 3 * o, mesh->normals + 3 * (size_t)centre, 3 * sizeof(float));
        if (out->texcoords) memcpy(out->texcoords + 2 * o, mesh->texcoords + 2 * (size_t)centre, 2 * sizeof(float));
        if (out->colors) memcpy(out->colors + 4 * o, mesh->colors + 4 * (size_t)centre, 4 * sizeof(float));
    }
    if (sums) {
        for (size_t o = 0; o < c->vertex_count; o++) {
            const double *sum = sums + STRIDE * o;
            if (sum[COUNT] < 2) continue; /* single member: exact copy already */
            double total = sum[W];
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
        free(allocated_sums);
    }
    double largest = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        uint32_t o = result->vertex_map[v];
        if (o == NO_CLUSTER) continue;
        const float *p = mesh->positions + 3 * v, *q = out->positions + 3 * (size_t)o;
        double d0 = (double)p[0] - q[0], d1 = (double)p[1] - q[1], d2 = (double)p[2] - q[2];
        double distance_squared = d0 * d0 + d1 * d1 + d2 * d2;
        if (distance_squared > largest) largest = distance_squared;
    }
    result->error = sqrt(largest);
    return LK_OK;
}

/* ---- setup -------------------------------------------------------------- */

/* `scale`: the model's size (any positive length will do). */
static lk_status clusterer_init(clusterer *c, const lk_mesh *mesh, cluster_method method, double scale, lk_error *error)
{
    memset(c, 0, sizeof *c);
    c->counted_size = -1;
    c->kept_clusters_size = -1;
    c->mesh = mesh;
    c->method = method;
    size_t vertex_count = mesh->vertex_count, triangle_count = mesh->triangle_count;
    if (triangle_count >= UINT32_MAX) /* triangles are numbered in 32 bits, with one value to spare */
        return lk_error_set(error, LK_ERR_INVALID, "too many triangles to cluster (%zu)", triangle_count);
    c->used = lk__alloc_random_access(vertex_count, 1, false);
    c->cluster_of = lk__alloc_random_access(vertex_count, sizeof(uint32_t), false);
    /* One block: the keys, then the importances (see lk__cluster_weights). */
    c->vertex_key = lk__alloc_random_access(vertex_count, 2 * sizeof(uint64_t), false);
    c->kept = lk__alloc_random_access(triangle_count, sizeof(uint32_t), false);
    c->candidate_hash = lk__alloc_random_access(triangle_count, sizeof(uint64_t), false);
    c->triangles = lk__alloc_random_access(triangle_count, 3 * sizeof(uint32_t), false);
    if (!c->used || !c->cluster_of || !c->vertex_key || !c->kept || !c->candidate_hash || !c->triangles)
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering tables");
    c->importance = (double *)(c->vertex_key + vertex_count);
    lk__cluster_weights weights = {
        .mesh = mesh, .used = c->used, .vertex_block = c->vertex_key, .directions = c->cluster_of};
    lk_status status = method == CLUSTER_UNIFORM ? lk__cluster_mean_direction_weights(&weights, scale, error)
                                                 : lk__cluster_largest_angle_weights(&weights, error);
    if (status != LK_OK) return status;
    c->used_count = weights.used_count;
    c->solid_count = weights.solid_count;
    c->area = weights.area;
    compute_box(c);

    size_t used_count = c->used_count;
    c->cell_capacity = 16;
    while (c->cell_capacity < 2 * used_count) c->cell_capacity *= 2;
    c->key_set_capacity = c->cell_capacity;
    c->dedup_capacity = 16;
    while (c->dedup_capacity < triangle_count + triangle_count / 2) c->dedup_capacity *= 2;
    c->table_bytes = c->dedup_capacity * sizeof(uint64_t);
    if (c->table_bytes < c->cell_capacity * sizeof(cell_entry)) c->table_bytes = c->cell_capacity * sizeof(cell_entry);
    c->tables = lk__alloc_random_access(c->table_bytes, 1, false);
    c->dedup = c->tables;
    c->cells = c->tables;
    c->key_set = lk__alloc_random_access(c->key_set_capacity, sizeof(uint64_t), false);
    c->centre = lk__alloc_random_access(used_count, sizeof(uint32_t), false);
    c->cluster_index = lk__alloc_random_access(used_count, sizeof(uint32_t), false);
    bool ok = c->tables && c->key_set && c->centre && c->cluster_index;
    if (ok && method == CLUSTER_FLOATING) {
        c->order = lk__alloc_random_access(used_count, sizeof(uint32_t), false);
        c->vertex_slot = lk__alloc_random_access(vertex_count, sizeof(uint32_t), false);
        c->bucket_offsets = lk__alloc_random_access(used_count + 1, sizeof(uint32_t), false);
        c->bucket_first = lk__alloc_random_access(used_count, sizeof(uint32_t), false);
        c->bucketed = lk__alloc_random_access(used_count, sizeof(bucket_member), false);
        c->rank = lk__alloc_random_access(vertex_count, sizeof(uint32_t), false);
        c->ranked_position = lk__alloc_random_access(used_count, 3 * sizeof(float), false);
        c->taken = lk__alloc_random_access(used_count, 1, false);
        /* Four cells a vertex (of a surface's box: most are empty), 16 bytes
         * a vertex: the 1.1M-triangle bunny's buckets at 50% need 2.3 a vertex. */
        c->dense_capacity = 4 * used_count + 4096;
        c->dense_buckets = lk__alloc_random_access(c->dense_capacity, sizeof(uint32_t), false);
        c->member_cluster = lk__alloc_random_access(used_count, sizeof(uint32_t), false);
        ok = c->order && c->vertex_slot && c->bucket_offsets && c->bucket_first && c->bucketed && c->rank &&
             c->ranked_position && c->taken && c->dense_buckets && c->member_cluster;
    }
    if (!ok) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate clustering tables");
    if (method == CLUSTER_FLOATING) {
        status = sort_by_importance(c, error);
        if (status != LK_OK) return status;
    }

    return LK_OK;
}

/* ---- cell-size search ---------------------------------------------------- */

/* Smallest cell size the packed grid keys can hold. */
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
    int exact_trials;
    int estimates;
    double last_exact_size, last_exact_score;
    /* Estimated counts: candidates (triangles with corners in three
     * distinct uniform cells of the size times proxy_scale) times these
     * ratios, taken from the last exact trial. */
    double proxy_scale;
    bool exact_proxy;
    double triangle_ratio, vertex_ratio; /* at ratio_size, */
    double triangle_slope, vertex_slope; /* and d log(ratio) / d log(size) */
    double ratio_size;
    /* Best exact trial at or under the target (largest score <= 0), and
     * best non-empty exact trial overall (smallest |score|). */
    double under_size, under_score;
    double closest_size, closest_score;
    bool have_under, have_closest;
} search_state;

/* Whether the search may try another size (exact or estimated). */
static bool trials_left(const search_state *s) { return s->trials + s->estimates < MAX_TRIALS; }

/* Whether the estimated search's trials are the exact ones (uniform cells
 * with exact proxy counts). */
static bool exact_search(const search_state *s) { return s->exact_proxy && s->c->method == CLUSTER_UNIFORM; }

/* Whether an estimated search that began after `used` trials may try
 * another size: one trial is left for the exact check of its result. */
static bool estimates_left(const search_state *s, int used)
{
    int total = s->trials + s->estimates;
    return total + 1 < MAX_TRIALS && (exact_search(s) || total - used < MAX_SEARCH_ESTIMATES);
}

static lk_status report_trial(search_state *s, bool exact, lk_error *error)
{
    if (exact)
        s->trials++;
    else
        s->estimates++;
    if (s->progress && s->progress(s->progress_user, (double)(s->trials + s->estimates) / MAX_TRIALS, "clustering"))
        return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    return LK_OK;
}

/* Records the counts now in s->c as the exact trial of `cell_size`, reports
 * progress; *score gets its target score. */
static lk_status record_trial(search_state *s, double cell_size, double *score, lk_error *error)
{
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
    return report_trial(s, true, error);
}

/* The counts the estimates scale: uniform cells of the size times
 * proxy_scale, exact (repeats dropped) when the targets ask for at most
 * 1 / EXACT_FRACTION of the triangles (or half as many vertices: dropping
 * repeats then costs little), else the triangles with corners in three
 * distinct cells and half as many vertices. Repeated input triangles thus
 * steer small targets' searches no more than their results. */
typedef struct proxy_counts {
    double triangles, vertices;
    bool exact;
} proxy_counts;

/* `exact`: an exact trial of uniform cells follows, which drops the
 * repeats from the candidates listed here. */
static proxy_counts count_proxy(search_state *s, double cell_size, bool exact)
{
    clusterer *c = s->c;
    proxy_counts proxy;
    bool kept_next = s->exact_proxy || (exact && c->method == CLUSTER_UNIFORM);
    size_t candidates = count_candidates(c, cell_size * s->proxy_scale, kept_next);
    proxy.exact = s->exact_proxy;
    if (proxy.exact) {
        keep_listed_triangles(c, s->targets->vertices != 0);
        proxy.triangles = (double)c->triangle_count;
        proxy.vertices = (double)c->vertex_count;
    } else {
        /* A closed surface has about half as many vertices as triangles. */
        proxy.triangles = (double)candidates;
        proxy.vertices = (double)candidates / 2;
    }
    /* Uniform: the keys and kept triangles of this size now, if exact. */
    if (c->method == CLUSTER_UNIFORM) c->counted_size = proxy.exact ? cell_size : -1;
    return proxy;
}

/* Records the exact counts now in s->c for `cell_size`, whose proxy
 * counts were `proxy`. */
static lk_status exact_counts(search_state *s, double cell_size, const proxy_counts *proxy, double *score,
                              lk_error *error)
{
    clusterer *c = s->c;
    if (proxy->triangles > 0 && c->triangle_count > 0) {
        /* The ratios drift with the size (floating cells' counts fall
         * faster than uniform ones): a power law through the last two
         * exact trials. */
        double triangle_ratio = (double)c->triangle_count / proxy->triangles;
        double vertex_ratio = (double)c->vertex_count / proxy->vertices;
        double span = s->ratio_size > 0 ? log(cell_size / s->ratio_size) : 0;
        if (fabs(span) > 1e-4) {
            s->triangle_slope =
                fmin(fmax(log(triangle_ratio / s->triangle_ratio) / span, -MAX_RATIO_SLOPE), MAX_RATIO_SLOPE);
            if (s->targets->vertices)
                s->vertex_slope =
                    fmin(fmax(log(vertex_ratio / s->vertex_ratio) / span, -MAX_RATIO_SLOPE), MAX_RATIO_SLOPE);
        }
        s->triangle_ratio = triangle_ratio;
        if (s->targets->vertices) s->vertex_ratio = vertex_ratio;
        s->ratio_size = cell_size;
    }
    s->exact_trials++;
    s->last_exact_size = cell_size;
    lk_status status = record_trial(s, cell_size, score, error);
    s->last_exact_score = *score;
    return status;
}

/* The exact counts of a cell size (a full trial); with `calibrate`, they
 * also correct the ratios of the estimated counts. */
static lk_status exact_trial(search_state *s, double cell_size, bool calibrate, double *score, lk_error *error)
{
    clusterer *c = s->c;
    if (c->method == CLUSTER_FLOATING) {
        /* Once two exact trials bracket the target no estimate follows, so
         * the uniform pass that calibrates them (a pass over the triangles)
         * would be wasted. */
        proxy_counts proxy = {0, 0, false};
        if (calibrate) proxy = count_proxy(s, cell_size, true);
        count_trial(c, cell_size, s->targets->vertices != 0);
        return exact_counts(s, cell_size, &proxy, score, error);
    }
    proxy_counts proxy = count_proxy(s, cell_size, true);
    if (!proxy.exact) {
        keep_listed_triangles(c, s->targets->vertices != 0);
        c->counted_size = cell_size;
    }
    return exact_counts(s, cell_size, &proxy, score, error);
}

/* Estimated counts of a cell size (one cheap pass): see search_state. */
static lk_status estimated_trial(search_state *s, double cell_size, double *score, lk_error *error)
{
    clusterer *c = s->c;
    proxy_counts proxy = count_proxy(s, cell_size, false);
    if (c->method == CLUSTER_UNIFORM && proxy.exact) return exact_counts(s, cell_size, &proxy, score, error);
    double score_value = INFINITY;
    const count_targets *targets = s->targets;
    double span = s->ratio_size > 0 ? log(cell_size / s->ratio_size) : 0;
    if (targets->vertices) {
        double vertices = proxy.vertices * s->vertex_ratio * exp(s->vertex_slope * span);
        score_value = fmin(score_value, (vertices - (double)targets->vertices) / (double)targets->vertices);
    }
    if (targets->triangles) {
        double triangles = proxy.triangles * s->triangle_ratio * exp(s->triangle_slope * span);
        score_value = fmin(score_value, (triangles - (double)targets->triangles) / (double)targets->triangles);
    }
    *score = score_value;
    return report_trial(s, false, error);
}

/* Next size to try between fine (count above the target) and coarse
 * (count at or under it): the count goes roughly as size^-2, so the
 * secant on log(count) over log(size), aimed a little under the target and
 * kept inside the bracket; a coarse count of 0 has no logarithm: bisect. */
static double interpolate(double fine, double fine_score, double coarse, double coarse_score)
{
    double aim = 1 - STOP_TOLERANCE / 2;
    double fraction = 0.5;
    if (1 + coarse_score > 0) {
        double y_fine = log((1 + fine_score) / aim), y_coarse = log((1 + coarse_score) / aim);
        if (y_fine > y_coarse) fraction = y_fine / (y_fine - y_coarse);
        if (!(fraction >= 0.02)) fraction = 0.02;
        if (fraction > 0.98) fraction = 0.98;
    }
    return exp(log(fine) + fraction * (log(coarse) - log(fine)));
}

/* Scale factor that moves a count of target * (1 + score) onto the target
 * (count ~ size^-exponent), at least `least` away from 1 and at most 2. */
static double step_factor(double score, double least, double exponent)
{
    double factor = pow(fmax(1 + score, 1e-12) / (1 - STOP_TOLERANCE / 2), 1 / exponent);
    if (factor >= 1) return fmin(fmax(factor, least), 2.0);
    return fmax(fmin(factor, 1 / least), 0.5);
}

/* The cell size whose estimated counts are within STOP_TOLERANCE under
 * the targets, searched from `size`, never coarser than max_size: power-law
 * steps until bracketed, then the secant (Illinois: a side kept twice has
 * its score halved so the secant cannot stall on it). */
static double count_exponent(double size, double score, double previous_size, double previous_score)
{
    /* -d log(count) / d log(size) between two trials: about 2 for a
     * surface; 2 when unknown or of the wrong sign, at most 4. */
    if (!(previous_size > 0) || size == previous_size || !(1 + score > 0) || !(1 + previous_score > 0)) return 2;
    double exponent = -log((1 + score) / (1 + previous_score)) / log(size / previous_size);
    return exponent > 0 ? fmin(fmax(exponent, 0.25), 4) : 2;
}

static lk_status estimated_search(search_state *s, double size, double max_size, double known_score, double *found,
                                  lk_error *error)
{
    clusterer *c = s->c;
    double finest = finest_size(c);
    if (size > 4 * c->extent_max && c->extent_max > 0) size = 4 * c->extent_max;
    if (size > max_size) size = max_size;
    if (!(size >= finest)) size = finest;
    double score = known_score, fine = 0, fine_score = 0, coarse, coarse_score;
    double previous_size = 0, previous_score = 0;
    double least = MIN_STEP;
    int used = s->trials + s->estimates;
    lk_status status = LK_OK;
    if (isnan(score)) status = estimated_trial(s, size, &score, error);
    if (status != LK_OK) return status;
    /* Grow until reached: beyond the model's size every vertex shares one
     * cell and no triangle is left, which meets any count. */
    while (score > 0) {
        fine = size, fine_score = score;
        if (!estimates_left(s, used) || size >= max_size) { /* the error bound stops first */
            *found = size;
            return LK_OK;
        }
        double exponent = count_exponent(size, score, previous_size, previous_score);
        least = previous_size > 0 && score == previous_score ? fmin(least * least, 2.0) : MIN_STEP;
        previous_size = size, previous_score = score;
        size = fmin(size * step_factor(score, least, exponent), max_size);
        status = estimated_trial(s, size, &score, error);
        if (status != LK_OK) return status;
    }
    coarse = size, coarse_score = score;
    if (fine == 0) {
        /* Shrink until not reached (or the finest grid). */
        while (estimates_left(s, used) && size > finest && coarse_score < -STOP_TOLERANCE) {
            double exponent = count_exponent(size, coarse_score, previous_size, previous_score);
            least = previous_size > 0 && coarse_score == previous_score ? fmin(least * least, 2.0) : MIN_STEP;
            previous_size = size, previous_score = coarse_score;
            size = fmax(size * step_factor(coarse_score, least, exponent), finest);
            status = estimated_trial(s, size, &score, error);
            if (status != LK_OK) return status;
            if (score > 0) {
                fine = size, fine_score = score;
                break;
            }
            coarse = size, coarse_score = score;
        }
    }
    int kept_side = 0; /* +1: fine kept last, -1: coarse kept last */
    double fine_weight = 1, coarse_weight = 1;
    int estimates = 0;
    while (fine > 0 && estimates_left(s, used) && coarse > fine * (1 + 1e-7) && coarse_score < -STOP_TOLERANCE &&
           (exact_search(s) || ++estimates <= MAX_ESTIMATES)) {
        double middle = interpolate(fine, fine_weight * fine_score, coarse, coarse_weight * coarse_score);
        status = estimated_trial(s, middle, &score, error);
        if (status != LK_OK) return status;
        if (score > 0) {
            fine = middle, fine_score = score, fine_weight = 1;
            if (kept_side == -1) coarse_weight /= 2;
            kept_side = -1;
        } else {
            coarse = middle, coarse_score = score, coarse_weight = 1;
            if (kept_side == 1) fine_weight /= 2;
            kept_side = 1;
        }
    }
    *found = coarse;
    return LK_OK;
}

/* Finds the cell size for the count targets, never coarser than
 * max_size (INFINITY when unset). Sets *cell_size and *reached. */
static lk_status search_cell_size(search_state *s, double max_size, double *cell_size, int *reached, lk_error *error)
{
    clusterer *c = s->c;
    double finest = finest_size(c);
    double score;
    s->proxy_scale = c->method == CLUSTER_FLOATING ? 1 / FLOATING_SIZE_RATIO : 1;
    s->triangle_ratio = 1;
    s->vertex_ratio = 1;
    double wanted_triangles = fmax((double)s->targets->triangles, 2.0 * (double)s->targets->vertices);
    s->exact_proxy = wanted_triangles * EXACT_FRACTION <= (double)c->solid_count;
    /* The input itself (cell size 0): its counts are known without a trial. */
    c->triangle_count = c->solid_count;
    c->vertex_count = c->used_count;
    lk_status status = record_trial(s, 0, &score, error);
    if (status != LK_OK) return status;
    if (score <= 0) {
        *cell_size = 0, *reached = 1;
        return LK_OK;
    }
    double size;
    if (isfinite(max_size)) {
        if (max_size < finest) max_size = finest;
        status = exact_trial(s, max_size, true, &score, error);
        if (status != LK_OK) return status;
        if (score > 0) { /* the error bound stops first */
            *cell_size = max_size;
            *reached = c->triangle_count > 0;
            return LK_OK;
        }
        size = max_size;
    } else {
        /* A surface of area A in cells of side s occupies about A / s^2
         * cells; a ball of diameter s holds as much as a cube of side
         * s / FLOATING_SIZE_RATIO. */
        double wanted = s->targets->vertices ? (double)s->targets->vertices : (double)s->targets->triangles / 2;
        size = sqrt(c->area / fmax(wanted, 1)) / s->proxy_scale;
        /* Rounded to a power of 2^(1/16), so that a repeated input triangle
         * (which adds to the area) rarely changes the search's path. */
        if (size > 0 && isfinite(size)) size = exp2(round(16 * log2(size)) / 16);
    }
    /* Exact trials until one is close enough under the target: each at the
     * size an estimated search finds, until two exact trials bracket the
     * target, then between them (the secant, Illinois-safeguarded: a side
     * kept twice has its score halved so the secant cannot stall on it). */
    double fine = 0, fine_score = 0, coarse = INFINITY, coarse_score = 0;
    if (isfinite(max_size)) coarse = max_size, coarse_score = s->last_exact_score;
    int kept_side = 0; /* +1: fine kept last, -1: coarse kept last */
    double fine_weight = 1, coarse_weight = 1;
    double previous_size = 0, previous_score = 0, least = MIN_STEP;
    for (int round = 0; trials_left(s); round++) {
        double next;
        bool interpolated = fine > 0 && isfinite(coarse);
        if (interpolated) {
            if (!(coarse > fine * (1 + 1e-7))) break;
            next = interpolate(fine, fine_weight * fine_score, coarse, coarse_weight * coarse_score);
        } else if (round < ESTIMATED_ROUNDS || exact_search(s)) {
            status = estimated_search(s, size, max_size, s->exact_trials ? s->last_exact_score : NAN, &next, error);
            if (status != LK_OK) return status;
            if (exact_search(s)) break;                                   /* every trial was exact */
            if (s->exact_trials > 0 && next == s->last_exact_size) break; /* no progress */
        } else {
            /* The estimates did not help: power-law steps on exact counts
             * until bracketed. */
            double exponent = count_exponent(size, score, previous_size, previous_score);
            least = previous_size > 0 && score == previous_score ? fmin(least * least, 2.0) : MIN_STEP;
            next = fmin(fmax(size * step_factor(score, least, exponent), finest), max_size);
            if (next == size) break;
        }
        if (!trials_left(s)) break;
        if (s->exact_trials > 0) previous_size = s->last_exact_size, previous_score = s->last_exact_score;
        status = exact_trial(s, next, !interpolated, &score, error);
        if (status != LK_OK) return status;
        if (score <= 0 && score >= -STOP_TOLERANCE) break;
        size = next;
        /* The count is not monotonic in the size: a trial outside the
         * bracket does not replace a side. */
        if (!(next > fine && next < coarse)) continue;
        if (score > 0) {
            fine = next, fine_score = score, fine_weight = 1;
            if (interpolated && kept_side == -1) coarse_weight /= 2;
            kept_side = -1;
        } else {
            coarse = next, coarse_score = score, coarse_weight = 1;
            if (interpolated && kept_side == 1) fine_weight /= 2;
            kept_side = 1;
        }
    }
    /* Closest without exceeding when within tolerance, else closest at all. */
    if (s->have_under && (-s->under_score <= TARGET_TOLERANCE || !s->have_closest)) {
        *cell_size = s->under_size;
        *reached = -s->under_score <= TARGET_TOLERANCE;
    } else if (s->have_closest) {
        *cell_size = s->closest_size;
        *reached = fabs(s->closest_score) <= TARGET_TOLERANCE;
    } else {
        *cell_size = isfinite(max_size) ? max_size : 4 * c->extent_max;
        *reached = 0;
    }
    return LK_OK;
}

static lk_status simplify_clustering(const lk_mesh *mesh, cluster_method method, const lk_simplify_options *options,
                                     lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                     lk_error *error)
{
    clusterer c;
    lk_status status = clusterer_init(&c, mesh, method, result->diagonal, error);
    if (status != LK_OK) {
        clusterer_free(&c);
        return status;
    }
    count_targets targets = {options->target_vertices, options->target_triangles};
    if (options->target_ratio > 0) {
        /* Of the triangles that carry surface (degenerate and repeated ones
         * do not count). */
        double ratio_triangles = options->target_ratio * (double)c.solid_count;
        size_t from_ratio = ratio_triangles < 1 ? 1 : (size_t)llround(ratio_triangles);
        /* Two triangle rules: the larger count is reached first. */
        if (from_ratio > targets.triangles) targets.triangles = from_ratio;
    }
    double max_size = options->max_error > 0 ? options->max_error * result->diagonal : INFINITY;
    double cell_size;
    int reached = 0;
    if (targets.vertices == 0 && targets.triangles == 0) {
        cell_size = max_size > 0 && max_size < finest_size(&c) ? finest_size(&c) : max_size;
        run_trial(&c, cell_size);
        reached = c.triangle_count > 0;
        if (progress && progress(progress_user, 1.0, "clustering"))
            status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
    } else {
        search_state search = {.c = &c, .targets = &targets, .progress = progress, .progress_user = progress_user};
        status = search_cell_size(&search, max_size, &cell_size, &reached, error);
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
