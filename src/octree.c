/* SPDX-License-Identifier: MIT */
/* Out-of-core point octrees (Potree-like level of detail; lodkit.h,
 * "Point octrees"; docs/formats.md, "Point octree").
 *
 * Building, with memory bounded by the chunk size whatever the input size:
 *  1. bounds: one streamed pass over the inputs gives the tight bounds,
 *     which attributes they have and (LAS) whether colours are 8 or 16 bit.
 *     Positions are then quantised once, to uint32 steps of `scale` from
 *     the root cube's corner; the cube's side is a power of two of steps, so
 *     every node's cube has exact integer bounds and a point's child is a
 *     bit of its coordinates.
 *  2. counts: a second pass counts the points per cell of a 128^3 grid
 *     (the cube's level-7 nodes); going down from the root, a node holding
 *     at most chunk_points points (or a level-7 cell) becomes a chunk, the
 *     nodes above the chunks are the "top" nodes.
 *  3. spill: a third pass appends each point to its chunk's temporary file.
 *  4. chunks: each chunk is read back and built into its subtree in memory,
 *     on several threads: a node takes the candidates that are at least its
 *     spacing from every point it took before (Poisson-disk in input order,
 *     a grid of spacing-sized cells: dense when the node spans at most 157
 *     a side, as with the default spacing, else hashed), the rest go to the
 *     children; a
 *     node with at most max_node_points candidates is a leaf and keeps them
 *     all. Nodes below a chunk's root are written to the chunk's own output
 *     file, the root stays in memory.
 *  5. top: from the deepest top node up, each top node takes its share of
 *     its children's points by the same rule, at its own spacing (points
 *     move up; a child keeps the others).
 *  6. output: octree.bin gets the top nodes and chunk roots, then every
 *     chunk's output file in chunk order; octree.json the index. Neither
 *     depends on the thread count: chunks are independent and the input
 *     order within a chunk is the spill order.
 * The inputs are read by src/octree_input.c, octrees by src/octree_read.c. */
#include "internal.h"
#include "bytes.h"
#include "octree_internal.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>
#include <time.h>
#include <zlib.h>

enum {
    OT_GRID_BITS = 7, /* the counting grid: 128^3 cells */
    OT_NAME_SIZE = OT_MAX_BITS + 2,
    OT_MAX_SPILL_BUFFER = 1 << 16,
    OT_DEFAULT_NODE_POINTS = 20000, /* leaf size of large clouds */
};


static double now_seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + t.tv_nsec * 1e-9;
}

void lk_octree_options_default(lk_octree_options *options)
{
    memset(options, 0, sizeof *options);
    options->max_node_points = 0; /* from the point count: adapt_to_cloud */
    options->chunk_points = 2000000;
    options->neighbours = 8;
}

/* ---- octahedral normals ---------------------------------------------------- */

static uint16_t oct_unorm16(float v)
{
    float t = (v * 0.5f + 0.5f) * 65535.0f + 0.5f;
    return (uint16_t)(t < 0.0f ? 0.0f : t > 65535.0f ? 65535.0f : t);
}

static void oct_encode(const float n[3], uint16_t out[2])
{
    float sum = fabsf(n[0]) + fabsf(n[1]) + fabsf(n[2]);
    if (!(sum > 0.0f) || !isfinite(sum)) {
        out[0] = out[1] = oct_unorm16(0.0f);
        return;
    }
    float x = n[0] / sum, y = n[1] / sum;
    if (n[2] < 0.0f) {
        float fx = (1.0f - fabsf(y)) * (x >= 0.0f ? 1.0f : -1.0f);
        float fy = (1.0f - fabsf(x)) * (y >= 0.0f ? 1.0f : -1.0f);
        x = fx;
        y = fy;
    }
    out[0] = oct_unorm16(x);
    out[1] = oct_unorm16(y);
}

/* ---- the build ---------------------------------------------------------------- */


/* A node written (or to be written): where its bytes are. */
typedef struct ot_record {
    char name[OT_NAME_SIZE];
    unsigned level;
    uint64_t points, offset, length;
    uint32_t crc;
} ot_record;

/* A chunk: one node of the octree whose subtree is built in memory. */
typedef struct ot_chunk {
    unsigned level;
    uint32_t cell[3]; /* the node's coordinates at its level */
    char name[OT_NAME_SIZE];
    uint64_t count; /* points spilled to it */
    size_t top;     /* its entry in the top list (its root) */
    /* spill buffer */
    ot_point *buffer;
    size_t buffered;
    /* results */
    ot_record *records; /* nodes below the root, in its output file */
    size_t record_count, record_capacity;
    uint64_t out_bytes;
} ot_chunk;

/* A node of the top of the tree: a top node or a chunk root, in memory. */
typedef struct ot_top {
    unsigned level;
    uint32_t cell[3];
    char name[OT_NAME_SIZE];
    long chunk;    /* its chunk, or -1 for a node above the chunks */
    long child[8]; /* top list entries, -1: none (or inside a chunk) */
    int leaf;      /* a chunk root without children */
    ot_point *points;
    size_t count;
} ot_top;

typedef struct ot_build {
    lk_octree_options options;
    const char *const *paths;
    size_t path_count;
    int *colors_16bit; /* per input, from pass 1 */
    lk_progress_fn progress;
    void *progress_user;
    pthread_mutex_t lock; /* progress calls, the next chunk, the first error */
    int cancelled;
    /* pass 1 */
    uint64_t total;
    double lo[3], hi[3];
    int has_colors, has_normals, keep_normals, estimate_normals;
    /* the frame */
    double offset[3], scale, cube_size, spacing;
    unsigned bits; /* the cube's side is 2^bits steps */
    unsigned grid_bits;
    /* pass 2 */
    uint64_t *grid_counts; /* (2^grid_bits)^3 */
    uint32_t *cell_chunk;  /* chunk of each grid cell */
    ot_chunk *chunks;
    size_t chunk_count, chunk_capacity;
    ot_top *tops;
    size_t top_count, top_capacity;
    size_t spill_buffer_points;
    /* files */
    char *spill_dir;
    /* chunk workers */
    size_t next_chunk, chunks_done;
    lk_status first_status;
    lk_error first_error;
    lk_octree_stats stats;
} ot_build;

static int report(ot_build *b, double fraction, const char *stage)
{
    if (!b->progress) return 0;
    pthread_mutex_lock(&b->lock);
    if (!b->cancelled && b->progress(b->progress_user, fraction, stage)) b->cancelled = 1;
    int cancelled = b->cancelled;
    pthread_mutex_unlock(&b->lock);
    return cancelled;
}

static lk_status cancelled_error(lk_error *error) { return lk_error_set(error, LK_ERR_INVALID, "cancelled"); }

/* Calls fn on every batch of every input, in order. */
typedef lk_status (*batch_fn)(ot_build *b, size_t input, const ot_source *source, const ot_batch *batch,
                              lk_error *error);

static lk_status for_each_batch(ot_build *b, ot_batch *batch, batch_fn fn, const char *stage, double from, double to,
                                lk_error *error)
{
    uint64_t done = 0;
    for (size_t input = 0; input < b->path_count; input++) {
        ot_source source;
        memset(&source, 0, sizeof source);
        source.colors_16bit = b->colors_16bit[input];
        source.max_read_bytes = b->options.max_read_bytes > SIZE_MAX ? SIZE_MAX : (size_t)b->options.max_read_bytes;
        lk_status status = lk__octree_source_open(&source, b->paths[input], error);
        while (status == LK_OK && source.next < source.count) {
            status = lk__octree_source_next(&source, batch, error);
            if (status == LK_OK) status = fn(b, input, &source, batch, error);
            done += batch->count;
            if (status == LK_OK &&
                report(b, from + (to - from) * (b->total ? (double)done / (double)b->total : 0.0), stage))
                status = cancelled_error(error);
        }
        if (status == LK_OK && source.is_las) b->colors_16bit[input] = source.color_max > 255;
        lk__octree_source_close(&source);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

static lk_status bounds_batch(ot_build *b, size_t input, const ot_source *source, const ot_batch *batch,
                              lk_error *error)
{
    (void)error;
    if (source->next == batch->count) { /* the source's first batch */
        if (source->has_colors) b->has_colors = 1;
        if (!source->has_normals) b->has_normals = 0;
        (void)input;
    }
    for (size_t i = 0; i < batch->count; i++)
        for (int k = 0; k < 3; k++) {
            double v = batch->xyz[3 * i + (size_t)k];
            if (v < b->lo[k]) b->lo[k] = v;
            if (v > b->hi[k]) b->hi[k] = v;
        }
    b->total += batch->count;
    return LK_OK;
}

static void quantise(const ot_build *b, const double xyz[3], uint32_t q[3])
{
    double top = (double)((1u << b->bits) - 1u);
    for (int k = 0; k < 3; k++) {
        double steps = floor((xyz[k] - b->offset[k]) / b->scale + 0.5);
        q[k] = (uint32_t)(steps < 0.0 ? 0.0 : steps > top ? top : steps);
    }
}

static size_t grid_index(const ot_build *b, const uint32_t q[3])
{
    unsigned shift = b->bits - b->grid_bits;
    size_t side = (size_t)1 << b->grid_bits;
    return ((size_t)(q[0] >> shift) * side + (q[1] >> shift)) * side + (q[2] >> shift);
}

static lk_status count_batch(ot_build *b, size_t input, const ot_source *source, const ot_batch *batch, lk_error *error)
{
    (void)input, (void)source, (void)error;
    for (size_t i = 0; i < batch->count; i++) {
        uint32_t q[3];
        quantise(b, batch->xyz + 3 * i, q);
        b->grid_counts[grid_index(b, q)]++;
    }
    return LK_OK;
}

static void node_name(char *name, const char *parent, int child)
{
    size_t length = strlen(parent);
    memcpy(name, parent, length);
    name[length] = (char)('0' + child);
    name[length + 1] = '\0';
}

static int child_of(const uint32_t q[3], unsigned bits, unsigned level)
{
    unsigned shift = bits - level - 1;
    return (int)(((q[0] >> shift) & 1u) << 2 | ((q[1] >> shift) & 1u) << 1 | ((q[2] >> shift) & 1u));
}

static long add_top(ot_build *b, unsigned level, const uint32_t cell[3], const char *name)
{
    if (b->top_count == b->top_capacity) {
        size_t capacity = b->top_capacity ? 2 * b->top_capacity : 64;
        ot_top *grown = lk__realloc_array(b->tops, capacity, sizeof *grown);
        if (!grown) return -1;
        b->tops = grown;
        b->top_capacity = capacity;
    }
    ot_top *top = &b->tops[b->top_count];
    memset(top, 0, sizeof *top);
    top->level = level;
    memcpy(top->cell, cell, sizeof top->cell);
    snprintf(top->name, sizeof top->name, "%s", name);
    top->chunk = -1;
    for (int c = 0; c < 8; c++) top->child[c] = -1;
    return (long)b->top_count++;
}

/* Sum of the grid counts inside a node (level <= grid_bits). */
static uint64_t node_count(const ot_build *b, unsigned level, const uint32_t cell[3])
{
    unsigned shift = b->grid_bits - level;
    size_t side = (size_t)1 << b->grid_bits, span = (size_t)1 << shift;
    uint64_t sum = 0;
    for (size_t x = 0; x < span; x++)
        for (size_t y = 0; y < span; y++) {
            const uint64_t *row = b->grid_counts +
                                  ((((size_t)cell[0] << shift) + x) * side + ((size_t)cell[1] << shift) + y) * side +
                                  ((size_t)cell[2] << shift);
            for (size_t z = 0; z < span; z++) sum += row[z];
        }
    return sum;
}

/* Splits the node into chunks (depth first, children in order 0..7). */
static lk_status plan_chunks(ot_build *b, unsigned level, const uint32_t cell[3], const char *name, uint64_t count,
                             long *top_out, lk_error *error)
{
    long top = add_top(b, level, cell, name);
    if (top < 0) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    *top_out = top;
    if (count <= b->options.chunk_points || level == b->grid_bits) {
        if (b->chunk_count == b->chunk_capacity) {
            size_t capacity = b->chunk_capacity ? 2 * b->chunk_capacity : 16;
            ot_chunk *grown = lk__realloc_array(b->chunks, capacity, sizeof *grown);
            if (!grown) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            b->chunks = grown;
            b->chunk_capacity = capacity;
        }
        ot_chunk *chunk = &b->chunks[b->chunk_count];
        memset(chunk, 0, sizeof *chunk);
        chunk->level = level;
        memcpy(chunk->cell, cell, sizeof chunk->cell);
        snprintf(chunk->name, sizeof chunk->name, "%s", name);
        chunk->top = (size_t)top;
        b->tops[top].chunk = (long)b->chunk_count;
        /* mark its grid cells */
        unsigned shift = b->grid_bits - level;
        size_t side = (size_t)1 << b->grid_bits, span = (size_t)1 << shift;
        for (size_t x = 0; x < span; x++)
            for (size_t y = 0; y < span; y++)
                for (size_t z = 0; z < span; z++)
                    b->cell_chunk[((((size_t)cell[0] << shift) + x) * side + ((size_t)cell[1] << shift) + y) * side +
                                  ((size_t)cell[2] << shift) + z] = (uint32_t)b->chunk_count;
        b->chunk_count++;
        return LK_OK;
    }
    for (int c = 0; c < 8; c++) {
        uint32_t child[3] = {cell[0] * 2 + (uint32_t)(c >> 2 & 1), cell[1] * 2 + (uint32_t)(c >> 1 & 1),
                             cell[2] * 2 + (uint32_t)(c & 1)};
        uint64_t child_count = node_count(b, level + 1, child);
        if (child_count == 0) continue;
        char child_name[OT_NAME_SIZE];
        node_name(child_name, name, c);
        long child_top;
        lk_status status = plan_chunks(b, level + 1, child, child_name, child_count, &child_top, error);
        if (status != LK_OK) return status;
        b->tops[top].child[c] = child_top;
    }
    return LK_OK;
}

static void chunk_path(const ot_build *b, size_t chunk, const char *what, char *path, size_t size)
{
    snprintf(path, size, "%s/%s%zu.bin", b->spill_dir, what, chunk);
}

static lk_status flush_spill(ot_build *b, size_t index, lk_error *error)
{
    ot_chunk *chunk = &b->chunks[index];
    if (chunk->buffered == 0) return LK_OK;
    char path[4200];
    chunk_path(b, index, "spill", path, sizeof path);
    FILE *file = fopen(path, "ab");
    if (!file) return lk_error_set(error, LK_ERR_IO, "%s: %s", path, strerror(errno));
    size_t written = fwrite(chunk->buffer, sizeof(ot_point), chunk->buffered, file);
    int failed = written != chunk->buffered || ferror(file);
    int saved = errno;
    if (fclose(file) != 0 && !failed) {
        failed = 1;
        saved = errno;
    }
    if (failed) return lk_error_set(error, LK_ERR_IO, "%s: write error: %s", path, strerror(saved));
    b->stats.temp_bytes += chunk->buffered * sizeof(ot_point);
    chunk->buffered = 0;
    return LK_OK;
}

static lk_status spill_batch(ot_build *b, size_t input, const ot_source *source, const ot_batch *batch, lk_error *error)
{
    (void)input;
    for (size_t i = 0; i < batch->count; i++) {
        ot_point point;
        memset(&point, 0, sizeof point);
        quantise(b, batch->xyz + 3 * i, point.q);
        if (b->has_colors) {
            if (source->has_colors)
                memcpy(point.rgb, batch->rgb + 3 * i, 3);
            else
                memset(point.rgb, 255, 3);
        }
        if (b->keep_normals) oct_encode(batch->normals + 3 * i, point.oct);
        size_t index = b->cell_chunk[grid_index(b, point.q)];
        ot_chunk *chunk = &b->chunks[index];
        chunk->buffer[chunk->buffered++] = point;
        chunk->count++;
        if (chunk->buffered == b->spill_buffer_points) {
            lk_status status = flush_spill(b, index, error);
            if (status != LK_OK) return status;
        }
    }
    return LK_OK;
}

/* ---- Poisson-disk subsampling ------------------------------------------------ */

/* A hash grid of cells `cell` steps wide holding the points taken so far
 * (chained through `next`). */
typedef struct ot_grid {
    uint64_t *keys; /* UINT64_MAX: empty */
    uint32_t *heads;
    size_t capacity, used;
} ot_grid;

static inline size_t grid_slot(uint64_t key, size_t mask)
{
    key ^= key >> 31;
    key *= 0x9E3779B97F4A7C15ull;
    key ^= key >> 29;
    return (size_t)key & mask;
}

static bool grid_reset(ot_grid *grid, size_t expected)
{
    size_t capacity = 1024;
    while (capacity < 2 * expected) capacity *= 2;
    if (capacity > grid->capacity) {
        free(grid->keys);
        free(grid->heads);
        grid->keys = lk__malloc_array(capacity, sizeof *grid->keys);
        grid->heads = lk__malloc_array(capacity, sizeof *grid->heads);
        if (!grid->keys || !grid->heads) {
            grid->capacity = 0;
            return false;
        }
        grid->capacity = capacity;
    }
    memset(grid->keys, 0xff, grid->capacity * sizeof *grid->keys);
    grid->used = 0;
    return true;
}

static bool grid_grow(ot_grid *grid)
{
    size_t capacity = grid->capacity * 2, mask = capacity - 1;
    uint64_t *keys = lk__malloc_array(capacity, sizeof *keys);
    uint32_t *heads = lk__malloc_array(capacity, sizeof *heads);
    if (!keys || !heads) {
        free(keys);
        free(heads);
        return false;
    }
    memset(keys, 0xff, capacity * sizeof *keys);
    for (size_t i = 0; i < grid->capacity; i++) {
        if (grid->keys[i] == UINT64_MAX) continue;
        size_t slot = grid_slot(grid->keys[i], mask);
        while (keys[slot] != UINT64_MAX) slot = (slot + 1) & mask;
        keys[slot] = grid->keys[i];
        heads[slot] = grid->heads[i];
    }
    free(grid->keys);
    free(grid->heads);
    grid->keys = keys;
    grid->heads = heads;
    grid->capacity = capacity;
    return true;
}

/* UINT32_MAX when the cell is empty. */
static inline uint32_t grid_find(const ot_grid *grid, uint64_t key)
{
    size_t mask = grid->capacity - 1, slot = grid_slot(key, mask);
    while (grid->keys[slot] != UINT64_MAX) {
        if (grid->keys[slot] == key) return grid->heads[slot];
        slot = (slot + 1) & mask;
    }
    return UINT32_MAX;
}

static inline uint64_t cell_key(uint64_t x, uint64_t y, uint64_t z) { return x << 42 | y << 21 | z; }

/* Scratch of one thread. */
typedef struct ot_scratch {
    ot_grid grid;
    uint32_t *next; /* chain of taken points, by candidate position */
    size_t next_capacity;
    float *radii; /* for medians */
    size_t radii_capacity;
    unsigned char *bytes; /* one encoded node */
    size_t bytes_capacity;
    uint32_t *dense;   /* a dense grid when the node has few cells a side (UINT32_MAX: empty) */
    uint32_t *touched; /* its cells set, to empty it again */
    size_t touched_capacity;
} ot_scratch;

/* Cells a side of the dense grid (with a border cell each side): the
 * default spacing gives 128 + 2. */
enum { OT_DENSE_SIDE = 160 };

static void scratch_free(ot_scratch *s)
{
    free(s->grid.keys);
    free(s->grid.heads);
    free(s->next);
    free(s->radii);
    free(s->bytes);
    free(s->dense);
    free(s->touched);
    memset(s, 0, sizeof *s);
}

static bool scratch_room(void **array, size_t *capacity, size_t count, size_t size)
{
    if (count <= *capacity) return true;
    void *grown = lk__realloc_array(*array, count, size);
    if (!grown) return false;
    *array = grown;
    *capacity = count;
    return true;
}

/* The 27 cells around a cell, its own first (the likeliest to hold a
 * close point). */
static const int8_t around[27][3] = {
    {0, 0, 0},  {-1, 0, 0},   {1, 0, 0},   {0, -1, 0},  {0, 1, 0},  {0, 0, -1},  {0, 0, 1},   {-1, -1, 0}, {-1, 1, 0},
    {1, -1, 0}, {1, 1, 0},    {-1, 0, -1}, {-1, 0, 1},  {1, 0, -1}, {1, 0, 1},   {0, -1, -1}, {0, -1, 1},  {0, 1, -1},
    {0, 1, 1},  {-1, -1, -1}, {-1, -1, 1}, {-1, 1, -1}, {-1, 1, 1}, {1, -1, -1}, {1, -1, 1},  {1, 1, -1},  {1, 1, 1}};

/* poisson_take on a dense grid of OT_DENSE_SIDE^3 cells (the node's cube
 * spans fewer cells than that a side): no hashing. */
static size_t poisson_take_dense(ot_scratch *s, const ot_point *const *points, size_t count, double spacing,
                                 const uint32_t origin[3], uint8_t *taken)
{
    const size_t side = OT_DENSE_SIDE, cells = side * side * side;
    if (!s->dense) {
        s->dense = lk__malloc_array(cells, sizeof *s->dense);
        if (!s->dense) return SIZE_MAX;
        memset(s->dense, 0xff, cells * sizeof *s->dense);
    }
    if (!scratch_room((void **)&s->next, &s->next_capacity, count, sizeof *s->next) ||
        !scratch_room((void **)&s->touched, &s->touched_capacity, count, sizeof *s->touched))
        return SIZE_MAX;
    double cell = spacing >= 1.0 ? spacing : 1.0, inverse = 1.0 / cell, limit = spacing * spacing;
    ptrdiff_t offsets[27];
    for (int a = 0; a < 27; a++)
        offsets[a] = ((ptrdiff_t)around[a][0] * (ptrdiff_t)side + around[a][1]) * (ptrdiff_t)side + around[a][2];
    size_t taken_count = 0;
    for (size_t i = 0; i < count; i++) {
        const uint32_t *q = points[i]->q;
        size_t c[3];
        for (int k = 0; k < 3; k++) c[k] = (size_t)((double)(q[k] - origin[k]) * inverse) + 1; /* +1: room for -1 */
        size_t home = (c[0] * side + c[1]) * side + c[2];
        bool near = false;
        for (int a = 0; a < 27 && !near; a++)
            for (uint32_t at = s->dense[(size_t)((ptrdiff_t)home + offsets[a])]; at != UINT32_MAX && !near;
                 at = s->next[at]) {
                const uint32_t *o = points[at]->q;
                double ex = (double)q[0] - o[0], ey = (double)q[1] - o[1], ez = (double)q[2] - o[2];
                if (ex * ex + ey * ey + ez * ez < limit) near = true;
            }
        taken[i] = !near;
        if (near) continue;
        if (s->dense[home] == UINT32_MAX)
            s->touched[taken_count] = (uint32_t)home;
        else
            s->touched[taken_count] = UINT32_MAX;
        taken_count++;
        s->next[i] = s->dense[home];
        s->dense[home] = (uint32_t)i;
    }
    for (size_t t = 0; t < taken_count; t++)
        if (s->touched[t] != UINT32_MAX) s->dense[s->touched[t]] = UINT32_MAX;
    return taken_count;
}

/* Takes, in order, the points of `points` (count of them) that lie at
 * least `spacing` steps from every point taken before; taken[i] says which.
 * Cells are `spacing` steps wide (clamped to at least 1), so a point closer
 * than that lies in one of the 27 cells around. Returns how many were taken,
 * or SIZE_MAX when out of memory. */
static size_t poisson_take(ot_scratch *s, const ot_point *const *points, size_t count, double spacing, unsigned shift,
                           uint8_t *taken)
{
    if (count == 0) return 0;
    uint32_t origin[3];
    for (int k = 0; k < 3; k++) origin[k] = shift >= 32 ? 0 : points[0]->q[k] >> shift << shift;
    double side_cells = (double)(1u << shift) / (spacing >= 1.0 ? spacing : 1.0);
    if (side_cells + 3 <= OT_DENSE_SIDE) return poisson_take_dense(s, points, count, spacing, origin, taken);
    if (!grid_reset(&s->grid, count < 65536 ? count : 65536)) return SIZE_MAX;
    if (!scratch_room((void **)&s->next, &s->next_capacity, count, sizeof *s->next)) return SIZE_MAX;
    double cell = spacing >= 1.0 ? spacing : 1.0, inverse = 1.0 / cell, limit = spacing * spacing;
    size_t taken_count = 0;
    for (size_t i = 0; i < count; i++) {
        const uint32_t *q = points[i]->q;
        uint64_t c[3];
        for (int k = 0; k < 3; k++) c[k] = (uint64_t)((double)(q[k] - origin[k]) * inverse) + 1; /* +1: room for -1 */
        bool near = false;
        for (int dx = -1; dx <= 1 && !near; dx++)
            for (int dy = -1; dy <= 1 && !near; dy++)
                for (int dz = -1; dz <= 1 && !near; dz++) {
                    uint32_t at =
                        grid_find(&s->grid, cell_key(c[0] + (uint64_t)dx, c[1] + (uint64_t)dy, c[2] + (uint64_t)dz));
                    for (; at != UINT32_MAX && !near; at = s->next[at]) {
                        const uint32_t *o = points[at]->q;
                        double ex = (double)q[0] - o[0], ey = (double)q[1] - o[1], ez = (double)q[2] - o[2];
                        if (ex * ex + ey * ey + ez * ez < limit) near = true;
                    }
                }
        taken[i] = !near;
        if (near) continue;
        taken_count++;
        uint64_t key = cell_key(c[0], c[1], c[2]);
        size_t mask = s->grid.capacity - 1, slot = grid_slot(key, mask);
        while (s->grid.keys[slot] != UINT64_MAX && s->grid.keys[slot] != key) slot = (slot + 1) & mask;
        if (s->grid.keys[slot] == key) {
            s->next[i] = s->grid.heads[slot];
        } else {
            s->next[i] = UINT32_MAX;
            s->grid.keys[slot] = key;
            s->grid.used++;
        }
        s->grid.heads[slot] = (uint32_t)i;
        if (2 * s->grid.used > s->grid.capacity && !grid_grow(&s->grid)) return SIZE_MAX;
    }
    return taken_count;
}

/* ---- encoding nodes ------------------------------------------------------------ */

/* Clip lines need normals: they lie in the tangent plane. */
static int with_clips(const ot_build *b) { return (b->keep_normals || b->estimate_normals) && !b->options.no_clips; }

static size_t point_stride(const ot_build *b)
{
    return 12 + (b->has_colors ? 3 : 0) + (b->keep_normals || b->estimate_normals ? 4 : 0) + 4 +
           (with_clips(b) ? 4 : 0);
}

static int compare_floats(const void *a, const void *c)
{
    float x = *(const float *)a, y = *(const float *)c;
    return (x > y) - (x < y);
}

/* The largest radius a node's points get: 4x the median of their local
 * densities' (outliers); INFINITY without radii. s->radii holds count. */
static float radius_limit(const ot_build *b, ot_scratch *s, const ot_point *const *points, size_t count)
{
    if (count == 0 || b->options.no_radii) return INFINITY;
    for (size_t i = 0; i < count; i++) s->radii[i] = points[i]->radius;
    qsort(s->radii, count, sizeof(float), compare_floats);
    return 4.0f * s->radii[count / 2];
}

/* A point's splat radius in its node: the local density's, clamped to the
 * node's limit, at least the node's spacing unless it is a leaf (a leaf's
 * points may be closer). */
static float drawn_radius(const ot_build *b, const ot_point *point, float limit, double spacing, int leaf)
{
    double radius = point->radius < limit ? point->radius : limit;
    if (b->options.no_radii || !(radius > 0.0))
        radius = spacing;
    else if (!leaf && radius < spacing)
        radius = spacing;
    return (float)radius;
}

/* Encodes the node's points into s->bytes. Radii as drawn_radius but not
 * floored at the spacing (format version 2): a reader floors them when it
 * draws the node without its children, and floors less where it draws the
 * children too (lk_octree_load_selection). */
static lk_status encode_node(const ot_build *b, ot_scratch *s, const ot_point *const *points, size_t count,
                             unsigned level, size_t *size, lk_error *error)
{
    size_t stride = point_stride(b);
    if (!scratch_room((void **)&s->bytes, &s->bytes_capacity, count ? count : 1, stride) ||
        !scratch_room((void **)&s->radii, &s->radii_capacity, count ? count : 1, sizeof(float)))
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    double spacing = b->spacing / (double)(1ull << level);
    float limit = radius_limit(b, s, points, count);
    int clips = with_clips(b);
    unsigned char *p = s->bytes;
    int with_normals = b->keep_normals || b->estimate_normals;
    for (size_t i = 0; i < count; i++) {
        const ot_point *point = points[i];
        for (int k = 0; k < 3; k++) lk__store_u32le(p + 4 * k, point->q[k]);
        p += 12;
        if (b->has_colors) {
            memcpy(p, point->rgb, 3);
            p += 3;
        }
        if (with_normals) {
            lk__store_u16le(p, point->oct[0]);
            lk__store_u16le(p + 2, point->oct[1]);
            p += 4;
        }
        float r = drawn_radius(b, point, limit, spacing, 1);
        uint32_t bits;
        memcpy(&bits, &r, 4);
        lk__store_u32le(p, bits);
        p += 4;
        if (clips) {
            memcpy(p, point->clip, 4);
            p += 4;
        }
    }
    *size = count * stride;
    return LK_OK;
}

/* ---- building one chunk ---------------------------------------------------------- */

/* A node of a chunk, decided but not yet written: its points are
 * order[first .. first + count). */
typedef struct ot_pending {
    size_t first, count;
    unsigned level;
    int leaf, is_root;
    char name[OT_NAME_SIZE];
} ot_pending;

typedef struct ot_chunk_work {
    ot_build *b;
    ot_chunk *chunk;
    ot_scratch *s;
    ot_point *points;
    const ot_point **order; /* candidates by node */
    const ot_point **rejected;
    uint8_t *taken;
    ot_pending *pending; /* the chunk's nodes, in preorder */
    size_t pending_count, pending_capacity;
    FILE *out;
    char out_path[4200];
    lk_error *error;
} ot_chunk_work;

static lk_status add_record(ot_chunk *chunk, const char *name, unsigned level, uint64_t points, uint64_t offset,
                            uint64_t length, uint32_t crc, lk_error *error)
{
    if (chunk->record_count == chunk->record_capacity) {
        size_t capacity = chunk->record_capacity ? 2 * chunk->record_capacity : 64;
        ot_record *grown = lk__realloc_array(chunk->records, capacity, sizeof *grown);
        if (!grown) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        chunk->records = grown;
        chunk->record_capacity = capacity;
    }
    ot_record *record = &chunk->records[chunk->record_count++];
    snprintf(record->name, sizeof record->name, "%s", name);
    record->level = level;
    record->points = points;
    record->offset = offset;
    record->length = length;
    record->crc = crc;
    return LK_OK;
}

/* Decides the node whose candidates are w->order[first .. first + count)
 * and its subtree: which points each node keeps, listed in w->pending in
 * preorder (written by write_pending once the clip lines, which depend on
 * every level's points, are known). */
static lk_status build_node(ot_chunk_work *w, size_t first, size_t count, unsigned level, const char *name, int is_root)
{
    ot_build *b = w->b;
    const ot_point **candidates = w->order + first;
    double spacing = b->spacing / b->scale / (double)(1ull << level);
    int leaf = count <= b->options.max_node_points || level >= b->bits;
    size_t kept = count;
    size_t child_first[9] = {0};
    if (!leaf) {
        size_t taken = poisson_take(w->s, candidates, count, spacing, b->bits - level, w->taken + first);
        if (taken == SIZE_MAX) return lk_error_set(w->error, LK_ERR_NOMEM, "out of memory");
        /* taken first (in order), then the others by child (in order) */
        size_t child_count[8] = {0};
        const ot_point **rejected = w->rejected + first;
        size_t r = 0, t = 0;
        for (size_t i = 0; i < count; i++) {
            if (w->taken[first + i])
                candidates[t++] = candidates[i];
            else {
                rejected[r++] = candidates[i];
                child_count[child_of(candidates[i]->q, b->bits, level)]++;
            }
        }
        kept = taken;
        child_first[0] = first + taken;
        for (int c = 0; c < 8; c++) child_first[c + 1] = child_first[c] + child_count[c];
        size_t cursor[8];
        memcpy(cursor, child_first, sizeof cursor);
        for (size_t i = 0; i < r; i++) w->order[cursor[child_of(rejected[i]->q, b->bits, level)]++] = rejected[i];
    }
    if (w->pending_count == w->pending_capacity) {
        size_t capacity = w->pending_capacity ? 2 * w->pending_capacity : 64;
        ot_pending *grown = lk__realloc_array(w->pending, capacity, sizeof *grown);
        if (!grown) return lk_error_set(w->error, LK_ERR_NOMEM, "out of memory");
        w->pending = grown;
        w->pending_capacity = capacity;
    }
    ot_pending *node = &w->pending[w->pending_count++];
    node->first = first;
    node->count = kept;
    node->level = level;
    node->leaf = leaf;
    node->is_root = is_root;
    snprintf(node->name, sizeof node->name, "%s", name);
    if (leaf) return LK_OK;
    for (int c = 0; c < 8; c++) {
        size_t n = child_first[c + 1] - child_first[c];
        if (n == 0) continue;
        char child_name[OT_NAME_SIZE];
        node_name(child_name, name, c);
        lk_status status = build_node(w, child_first[c], n, level + 1, child_name, 0);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

/* Local density (k-th neighbour distance) and estimated normals over the
 * chunk's own points, queried in Morton order (neighbouring queries touch
 * the same parts of the k-d tree: 2-3x faster than input order). Normals
 * (estimated, or the input's) come first: with them a radius is also
 * bounded by the point's cell among its neighbours (lk_points_estimate_radii). */
static lk_status chunk_estimates(ot_build *b, ot_point *points, size_t count, lk_error *error)
{
    int radii = !b->options.no_radii, normals = b->estimate_normals;
    if (!radii && !normals) return LK_OK;
    if (count < 2) return LK_OK;
    uint32_t *order = lk__octree_morton_order(points, count, b->bits);
    if (!order) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    lk_mesh mesh;
    int given_normals = radii && !normals && b->keep_normals;
    lk_status status = lk_mesh_alloc(&mesh, count, 0, given_normals ? LK_ATTR_NORMALS : 0, error);
    if (status != LK_OK) {
        free(order);
        return status;
    }
    for (size_t i = 0; i < count; i++) {
        for (int k = 0; k < 3; k++) mesh.positions[3 * i + (size_t)k] = (float)(points[order[i]].q[k] * b->scale);
        if (given_normals) lk__octree_oct_decode(points[order[i]].oct, mesh.normals + 3 * i);
    }
    unsigned k = b->options.neighbours;
    if (k >= count) k = (unsigned)(count - 1);
    if (normals) status = lk_points_estimate_normals(&mesh, k, error);
    if (status == LK_OK && radii) status = lk_points_estimate_radii(&mesh, k, 1.0, error);
    if (status == LK_OK)
        for (size_t i = 0; i < count; i++) {
            if (radii) points[order[i]].radius = mesh.radii[i];
            if (normals) oct_encode(mesh.normals + 3 * i, points[order[i]].oct);
        }
    lk_mesh_free(&mesh);
    free(order);
    return status;
}

/* Writes the chunk's nodes decided by build_node: the root is kept in
 * memory as its top entry, the others go to the chunk's output file. */
static lk_status write_pending(ot_chunk_work *w)
{
    ot_build *b = w->b;
    for (size_t n = 0; n < w->pending_count; n++) {
        const ot_pending *node = &w->pending[n];
        const ot_point **points = w->order + node->first;
        if (node->is_root) {
            ot_top *top = &b->tops[w->chunk->top];
            top->leaf = node->leaf;
            top->count = node->count;
            top->points = lk__malloc_array(node->count ? node->count : 1, sizeof(ot_point));
            if (!top->points) return lk_error_set(w->error, LK_ERR_NOMEM, "out of memory");
            for (size_t i = 0; i < node->count; i++) top->points[i] = *points[i];
            continue;
        }
        size_t size;
        lk_status status = encode_node(b, w->s, points, node->count, node->level, &size, w->error);
        if (status != LK_OK) return status;
        uint32_t crc = lk__octree_crc32(w->s->bytes, size);
        if (size && fwrite(w->s->bytes, 1, size, w->out) != size)
            return lk_error_set(w->error, LK_ERR_IO, "%s: write error: %s", w->out_path, strerror(errno));
        status = add_record(w->chunk, node->name, node->level, node->count, w->chunk->out_bytes, size, crc, w->error);
        if (status != LK_OK) return status;
        w->chunk->out_bytes += size;
    }
    return LK_OK;
}

/* The clip lines of the chunk's points (lk_points_estimate_clips' rule),
 * each among the points drawn with it: a point of a node at level l is
 * tested against the chunk's points of levels <= l (the nodes a view shows
 * when it shows that one and none deeper), so an inner node's large discs
 * are cut where its level's sample ends, not where the full cloud does.
 * Stored in point->clip as four signed bytes (direction, offset in the
 * point's drawn radii; docs/formats.md). Borders at the chunk's own faces
 * are dropped (OT_CLIP_FACE_COSINE). */
static lk_status chunk_clips(ot_chunk_work *w)
{
    ot_build *b = w->b;
    size_t count = (size_t)w->chunk->count;
    if (count == 0) return LK_OK;
    ot_clip_chunk clip;
    memset(&clip, 0, sizeof clip);
    unsigned char *depth = lk__malloc_array(count, 1);
    float *radius = lk__malloc_array(count, sizeof *radius);
    uint32_t *order = lk__octree_morton_order(w->points, count, b->bits);
    lk_status status = LK_OK;
    if (!depth || !radius || !order)
        status = lk_error_set(w->error, LK_ERR_NOMEM, "out of memory for the clip lines of chunk %s", w->chunk->name);
    clip.first_level = clip.last_level = w->chunk->level;
    for (size_t n = 0; status == LK_OK && n < w->pending_count; n++) {
        const ot_pending *node = &w->pending[n];
        const ot_point **points = w->order + node->first;
        if (!scratch_room((void **)&w->s->radii, &w->s->radii_capacity, node->count ? node->count : 1, sizeof(float))) {
            status = lk_error_set(w->error, LK_ERR_NOMEM, "out of memory");
            break;
        }
        float limit = radius_limit(b, w->s, points, node->count);
        double spacing = b->spacing / (double)(1ull << node->level);
        for (size_t i = 0; i < node->count; i++) {
            size_t at = (size_t)(points[i] - w->points);
            depth[at] = (unsigned char)node->level;
            radius[at] = drawn_radius(b, points[i], limit, spacing, node->leaf);
        }
        if (node->level > clip.last_level) clip.last_level = node->level;
    }
    /* the chunk's cube; faces on the root cube's are the cloud's own */
    unsigned side_bits = b->bits - w->chunk->level;
    for (int k = 0; k < 3; k++) {
        uint64_t first = (uint64_t)w->chunk->cell[k] << side_bits, end = first + (1ull << side_bits);
        clip.lo[k] = (double)first * b->scale;
        clip.hi[k] = (double)end * b->scale;
        clip.lo_open[k] = first > 0;
        clip.hi_open[k] = end < (1ull << b->bits);
    }
    clip.points = w->points;
    clip.count = count;
    clip.order = order;
    clip.depth = depth;
    clip.radius = radius;
    clip.scale = b->scale;
    clip.name = w->chunk->name;
    if (status == LK_OK) status = lk__octree_chunk_clips(&clip, w->error);
    free(depth);
    free(radius);
    free(order);
    return status;
}

static lk_status build_chunk(ot_build *b, size_t index, ot_scratch *s, lk_error *error)
{
    ot_chunk *chunk = &b->chunks[index];
    ot_chunk_work w;
    memset(&w, 0, sizeof w);
    w.b = b;
    w.chunk = chunk;
    w.s = s;
    w.error = error;
    if (chunk->count > UINT32_MAX - 1)
        return lk_error_set(error, LK_ERR_LIMIT, "chunk %s holds %llu points, more than 2^32 - 1", chunk->name,
                            (unsigned long long)chunk->count);
    size_t count = (size_t)chunk->count;
    char path[4200];
    chunk_path(b, index, "spill", path, sizeof path);
    lk_status status = LK_OK;
    w.points = lk__malloc_array(count, sizeof *w.points);
    w.order = lk__malloc_array(count, sizeof *w.order);
    w.rejected = lk__malloc_array(count, sizeof *w.rejected);
    w.taken = lk__malloc_array(count, 1);
    if (!w.points || !w.order || !w.rejected || !w.taken) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    if (status == LK_OK) {
        FILE *file = fopen(path, "rb");
        if (!file)
            status = lk_error_set(error, LK_ERR_IO, "%s: %s", path, strerror(errno));
        else {
            if (fread(w.points, sizeof *w.points, count, file) != count)
                status = lk_error_set(error, LK_ERR_IO, "%s: read error: the spill file is shorter than written", path);
            fclose(file);
            remove(path);
        }
    }
    if (status == LK_OK) status = chunk_estimates(b, w.points, count, error);
    if (status == LK_OK) {
        chunk_path(b, index, "nodes", w.out_path, sizeof w.out_path);
        w.out = fopen(w.out_path, "wb");
        if (!w.out) status = lk_error_set(error, LK_ERR_IO, "%s: %s", w.out_path, strerror(errno));
    }
    if (status == LK_OK) {
        for (size_t i = 0; i < count; i++) w.order[i] = &w.points[i];
        status = build_node(&w, 0, count, chunk->level, chunk->name, 1);
    }
    if (status == LK_OK && with_clips(b)) status = chunk_clips(&w);
    if (status == LK_OK) status = write_pending(&w);
    if (w.out && fclose(w.out) != 0 && status == LK_OK)
        status = lk_error_set(error, LK_ERR_IO, "%s: write error: %s", w.out_path, strerror(errno));
    free(w.points);
    free(w.order);
    free(w.rejected);
    free(w.taken);
    free(w.pending);
    return status;
}

static void *chunk_worker(void *argument)
{
    ot_build *b = argument;
    ot_scratch scratch;
    memset(&scratch, 0, sizeof scratch);
    for (;;) {
        pthread_mutex_lock(&b->lock);
        size_t index = b->next_chunk++;
        int stop = b->first_status != LK_OK || b->cancelled;
        pthread_mutex_unlock(&b->lock);
        if (stop || index >= b->chunk_count) break;
        lk_error error = {0};
        lk_status status = build_chunk(b, index, &scratch, &error);
        pthread_mutex_lock(&b->lock);
        b->chunks_done++;
        double fraction = 0.3 + 0.6 * (double)b->chunks_done / (double)b->chunk_count;
        if (status != LK_OK && b->first_status == LK_OK) {
            b->first_status = status;
            b->first_error = error;
        }
        pthread_mutex_unlock(&b->lock);
        if (report(b, fraction, "chunks")) break;
    }
    scratch_free(&scratch);
    return NULL;
}

/* ---- the top of the tree ---------------------------------------------------------- */

/* Each top node above the chunks takes its share of its children's points,
 * deepest first (the list is in depth-first preorder). */
static lk_status build_top(ot_build *b, lk_error *error)
{
    ot_scratch s;
    memset(&s, 0, sizeof s);
    lk_status status = LK_OK;
    for (size_t t = b->top_count; t-- > 0 && status == LK_OK;) {
        ot_top *top = &b->tops[t];
        if (top->chunk >= 0) continue;
        size_t count = 0;
        for (int c = 0; c < 8; c++)
            if (top->child[c] >= 0) count += b->tops[top->child[c]].count;
        const ot_point **candidates = lk__malloc_array(count ? count : 1, sizeof *candidates);
        uint8_t *taken = lk__malloc_array(count ? count : 1, 1);
        if (!candidates || !taken) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        size_t n = 0;
        for (int c = 0; c < 8 && status == LK_OK; c++)
            if (top->child[c] >= 0) {
                const ot_top *child = &b->tops[top->child[c]];
                for (size_t i = 0; i < child->count; i++) candidates[n++] = &child->points[i];
            }
        size_t kept = 0;
        if (status == LK_OK) {
            kept = poisson_take(&s, candidates, count, b->spacing / b->scale / (double)(1ull << top->level),
                                b->bits - top->level, taken);
            if (kept == SIZE_MAX) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        }
        if (status == LK_OK) {
            top->points = lk__malloc_array(kept ? kept : 1, sizeof(ot_point));
            if (!top->points) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        }
        if (status == LK_OK) {
            size_t at = 0;
            for (size_t i = 0; i < count; i++)
                if (taken[i]) top->points[top->count++] = *candidates[i];
            /* the children keep the others, in order */
            for (int c = 0; c < 8; c++) {
                if (top->child[c] < 0) continue;
                ot_top *child = &b->tops[top->child[c]];
                size_t left = 0;
                for (size_t i = 0; i < child->count; i++, at++)
                    if (!taken[at]) child->points[left++] = child->points[i];
                child->count = left;
            }
        }
        free(candidates);
        free(taken);
    }
    scratch_free(&s);
    return status;
}

/* ---- output ---------------------------------------------------------------------- */

static int compare_records(const void *a, const void *c)
{
    const ot_record *x = a, *y = c;
    if (x->level != y->level) return x->level < y->level ? -1 : 1;
    return strcmp(x->name, y->name);
}

static lk_status copy_file_into(const char *path, FILE *out, lk_error *error)
{
    FILE *in = fopen(path, "rb");
    if (!in) return lk_error_set(error, LK_ERR_IO, "%s: %s", path, strerror(errno));
    static const size_t size = 1 << 20;
    unsigned char *buffer = malloc(size);
    lk_status status = buffer ? LK_OK : lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    size_t got;
    while (status == LK_OK && (got = fread(buffer, 1, size, in)) > 0)
        if (fwrite(buffer, 1, got, out) != got) status = lk_error_set(error, LK_ERR_IO, "write error");
    if (status == LK_OK && ferror(in)) status = lk_error_set(error, LK_ERR_IO, "%s: read error", path);
    free(buffer);
    fclose(in);
    return status;
}

static cJSON *json_vector(const double v[3]) { return cJSON_CreateDoubleArray(v, 3); }

static lk_status write_output(ot_build *b, const char *out_dir, lk_error *error)
{
    size_t record_count = 0;
    for (size_t c = 0; c < b->chunk_count; c++) record_count += b->chunks[c].record_count;
    record_count += b->top_count;
    ot_record *records = lk__malloc_array(record_count, sizeof *records);
    char *data_path = lk__octree_join_path(out_dir, OT_DATA_NAME),
         *index_path = lk__octree_join_path(out_dir, OT_INDEX_NAME);
    ot_scratch s;
    memset(&s, 0, sizeof s);
    lk__atomic_file data;
    memset(&data, 0, sizeof data);
    lk_status status = records && data_path && index_path ? LK_OK : lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    if (status == LK_OK) status = lk__atomic_open(&data, data_path, error);
    int data_open = status == LK_OK;
    uint64_t offset = 0;
    size_t n = 0;
    /* the top nodes and chunk roots, by level then name */
    for (size_t t = 0; t < b->top_count && status == LK_OK; t++) {
        ot_top *top = &b->tops[t];
        ot_record *record = &records[n++];
        snprintf(record->name, sizeof record->name, "%s", top->name);
        record->level = top->level;
    }
    qsort(records, n, sizeof *records, compare_records);
    for (size_t i = 0; i < n && status == LK_OK; i++) {
        const ot_top *top = NULL;
        for (size_t t = 0; t < b->top_count; t++)
            if (strcmp(b->tops[t].name, records[i].name) == 0) top = &b->tops[t];
        const ot_point **points = lk__malloc_array(top->count ? top->count : 1, sizeof *points);
        if (!points) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            break;
        }
        for (size_t k = 0; k < top->count; k++) points[k] = &top->points[k];
        size_t size = 0;
        status = encode_node(b, &s, points, top->count, top->level, &size, error);
        free(points);
        if (status != LK_OK) break;
        records[i].points = top->count;
        records[i].offset = offset;
        records[i].length = size;
        records[i].crc = lk__octree_crc32(s.bytes, size);
        if (size && fwrite(s.bytes, 1, size, data.file) != size) status = lk_error_set(error, LK_ERR_IO, "write error");
        offset += size;
    }
    for (size_t c = 0; c < b->chunk_count && status == LK_OK; c++) {
        ot_chunk *chunk = &b->chunks[c];
        char path[4200];
        chunk_path(b, c, "nodes", path, sizeof path);
        status = copy_file_into(path, data.file, error);
        remove(path);
        for (size_t r = 0; r < chunk->record_count && status == LK_OK; r++) {
            records[n] = chunk->records[r];
            records[n++].offset += offset;
        }
        offset += chunk->out_bytes;
        if (report(b, 0.9 + 0.08 * (double)(c + 1) / (double)b->chunk_count, "writing"))
            status = cancelled_error(error);
    }
    if (status == LK_OK)
        status = lk__atomic_commit(&data, error);
    else if (data_open) {
        if (error->status == LK_ERR_IO)
            lk__atomic_fail(&data, error);
        else
            lk__atomic_abort(&data);
    }
    if (status == LK_OK) {
        qsort(records, n, sizeof *records, compare_records);
        unsigned levels = 0;
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "format", OT_FORMAT_NAME);
        cJSON_AddNumberToObject(root, "version", OT_VERSION);
        cJSON_AddStringToObject(root, "data", OT_DATA_NAME);
        cJSON_AddNumberToObject(root, "points", (double)b->total);
        cJSON_AddNumberToObject(root, "spacing", b->spacing);
        double scale[3] = {b->scale, b->scale, b->scale};
        cJSON_AddItemToObject(root, "scale", json_vector(scale));
        cJSON_AddItemToObject(root, "offset", json_vector(b->offset));
        cJSON_AddNumberToObject(root, "cube_size", b->cube_size);
        cJSON *bounds = cJSON_AddObjectToObject(root, "bounds");
        cJSON_AddItemToObject(bounds, "min", json_vector(b->lo));
        cJSON_AddItemToObject(bounds, "max", json_vector(b->hi));
        cJSON_AddNumberToObject(root, "stride", (double)point_stride(b));
        cJSON *attributes = cJSON_AddArrayToObject(root, "attributes");
        struct {
            const char *name, *encoding;
            int bytes, present;
        } list[] = {{"position", "int32x3", 12, 1},
                    {"rgb", "uint8x3", 3, b->has_colors},
                    {"normal", "oct16", 4, b->keep_normals || b->estimate_normals},
                    {"radius", "float32", 4, 1},
                    {"clip", "snorm8x4", 4, with_clips(b)}};
        for (int a = 0; a < 5; a++) {
            if (!list[a].present) continue;
            cJSON *attribute = cJSON_CreateObject();
            cJSON_AddStringToObject(attribute, "name", list[a].name);
            cJSON_AddStringToObject(attribute, "encoding", list[a].encoding);
            cJSON_AddNumberToObject(attribute, "bytes", list[a].bytes);
            cJSON_AddItemToArray(attributes, attribute);
        }
        cJSON *nodes = cJSON_AddArrayToObject(root, "nodes");
        for (size_t i = 0; i < n; i++) {
            cJSON *node = cJSON_CreateObject();
            cJSON_AddStringToObject(node, "name", records[i].name);
            cJSON_AddNumberToObject(node, "level", records[i].level);
            cJSON_AddNumberToObject(node, "points", (double)records[i].points);
            cJSON_AddNumberToObject(node, "offset", (double)records[i].offset);
            cJSON_AddNumberToObject(node, "length", (double)records[i].length);
            cJSON_AddNumberToObject(node, "crc32", records[i].crc);
            cJSON_AddItemToArray(nodes, node);
            if (records[i].level + 1 > levels) levels = records[i].level + 1;
        }
        char *text = cJSON_Print(root);
        cJSON_Delete(root);
        lk__atomic_file index;
        status = text ? lk__atomic_open(&index, index_path, error) : lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        if (status == LK_OK) {
            fputs(text, index.file);
            fputc('\n', index.file);
            status = lk__atomic_commit(&index, error);
        }
        free(text);
        b->stats.nodes = n;
        b->stats.levels = levels;
    }
    scratch_free(&s);
    free(records);
    free(data_path);
    free(index_path);
    return status;
}

/* ---- lk_octree_build --------------------------------------------------------------- */

static void remove_spill_dir(ot_build *b)
{
    if (!b->spill_dir) return;
    for (size_t c = 0; c < b->chunk_count; c++) {
        char path[4200];
        chunk_path(b, c, "spill", path, sizeof path);
        remove(path);
        chunk_path(b, c, "nodes", path, sizeof path);
        remove(path);
    }
    rmdir(b->spill_dir);
    free(b->spill_dir);
    b->spill_dir = NULL;
}

/* *created: whether it had to be made (and so may be removed on failure). */
static lk_status make_folder(const char *path, int *created, lk_error *error)
{
    *created = 0;
    struct stat info;
    if (stat(path, &info) == 0) {
        if (!S_ISDIR(info.st_mode)) return lk_error_set(error, LK_ERR_IO, "%s: not a folder", path);
        return LK_OK;
    }
    if (mkdir(path, 0777) != 0)
        return lk_error_set(error, LK_ERR_IO, "%s: cannot create the folder: %s", path, strerror(errno));
    *created = 1;
    return LK_OK;
}

/* The quantisation and the root cube, from the bounds. */
static lk_status choose_frame(ot_build *b, lk_error *error)
{
    double extent = 0.0;
    for (int k = 0; k < 3; k++)
        if (b->hi[k] - b->lo[k] > extent) extent = b->hi[k] - b->lo[k];
    double scale = b->options.scale;
    if (scale <= 0.0) {
        /* a power of ten near extent / 2^30, so that positions keep 30 bits */
        scale = extent > 0.0 ? pow(10.0, ceil(log10(extent / (double)(1u << OT_MAX_BITS)))) : 1e-3;
        if (!(scale > 0.0) || !isfinite(scale)) scale = 1e-3;
    }
    if (!(extent / scale + 1.0 < (double)(1u << OT_MAX_BITS)))
        return lk_error_set(error, LK_ERR_INVALID,
                            "scale %g is too fine for an extent of %g: positions need at most 2^30 steps", scale,
                            extent);
    unsigned bits = 1;
    while ((double)(1u << bits) <= extent / scale + 1.0) bits++;
    if (bits < OT_GRID_BITS) bits = OT_GRID_BITS;
    b->bits = bits;
    b->grid_bits = OT_GRID_BITS;
    b->scale = scale;
    for (int k = 0; k < 3; k++) b->offset[k] = b->lo[k];
    b->cube_size = scale * (double)(1u << bits);
    b->spacing = b->options.spacing; /* 0: adapt_to_cloud, after the counts */
    /* cell keys hold 21 bits a coordinate */
    if (b->spacing > 0.0 && b->cube_size / b->spacing > (double)(1u << 20))
        b->spacing = b->cube_size / (double)(1u << 20);
    return LK_OK;
}

/* Grid cells of level `level` (side cube_size / 2^level, level <= grid_bits)
 * holding at least one point, from the counting grid. */
static uint64_t occupied_cells(const ot_build *b, unsigned level, unsigned char *marks)
{
    size_t side = (size_t)1 << b->grid_bits, level_side = (size_t)1 << level;
    unsigned shift = b->grid_bits - level;
    memset(marks, 0, level_side * level_side * level_side);
    uint64_t occupied = 0;
    for (size_t x = 0; x < side; x++)
        for (size_t y = 0; y < side; y++)
            for (size_t z = 0; z < side; z++) {
                if (!b->grid_counts[(x * side + y) * side + z]) continue;
                size_t cell = ((x >> shift) * level_side + (y >> shift)) * level_side + (z >> shift);
                occupied += !marks[cell];
                marks[cell] = 1;
            }
    return occupied;
}

/* Defaults that depend on the cloud (the options left at 0), once the
 * points are counted. Leaf size: OT_DEFAULT_NODE_POINTS, or an eighth of
 * the cloud when that is less, so that a cloud of a few thousand points
 * still gets a root and children. Root spacing: the cube's side / 2^L for
 * the largest L <= 7 whose grid has at most an eighth of the cloud's count
 * of occupied cells (a Poisson-disk subsample at a cell's side keeps about
 * one point per occupied cell, so the root keeps about an eighth of the
 * points or fewer): side / 128, Potree's default, for large clouds, whose
 * root then holds tens of thousands of points at most (a surface crosses
 * some 128^2 cells); coarser for small clouds, whose points are further
 * apart than side / 128 and would all stay in the root. Deterministic: from
 * the counts alone. */
static lk_status adapt_to_cloud(ot_build *b, lk_error *error)
{
    uint64_t eighth = (b->total + 7) / 8;
    if (b->options.max_node_points == 0)
        b->options.max_node_points =
            eighth < OT_DEFAULT_NODE_POINTS ? (size_t)(eighth ? eighth : 1) : OT_DEFAULT_NODE_POINTS;
    if (b->spacing > 0.0) return LK_OK;
    unsigned char *marks = malloc((size_t)1 << (3 * b->grid_bits));
    if (!marks) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    unsigned level = b->grid_bits;
    while (level > 0 && occupied_cells(b, level, marks) > eighth) level--;
    free(marks);
    b->spacing = b->cube_size / (double)(1u << level);
    return LK_OK;
}

lk_status lk_octree_build(const char *const *paths, size_t path_count, const char *out_dir,
                          const lk_octree_options *options, lk_octree_stats *stats, lk_progress_fn progress,
                          void *progress_user, lk_error *error)
{
    double start = now_seconds();
    if (stats) memset(stats, 0, sizeof *stats);
    if (!paths || path_count == 0 || !out_dir)
        return lk_error_set(error, LK_ERR_INVALID, "lk_octree_build: no input or no output folder");
    ot_build *b = calloc(1, sizeof *b);
    ot_batch *batch = malloc(sizeof *batch);
    if (!b || !batch) {
        free(b);
        free(batch);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    if (options)
        b->options = *options;
    else
        lk_octree_options_default(&b->options);
    if (b->options.chunk_points == 0) b->options.chunk_points = 2000000;
    if (b->options.neighbours == 0) b->options.neighbours = 8;
    if (b->options.neighbours > 256) b->options.neighbours = 256;
    b->paths = paths;
    b->path_count = path_count;
    b->progress = progress;
    b->progress_user = progress_user;
    pthread_mutex_init(&b->lock, NULL);
    b->colors_16bit = calloc(path_count, sizeof *b->colors_16bit);
    for (int k = 0; k < 3; k++) {
        b->lo[k] = INFINITY;
        b->hi[k] = -INFINITY;
    }
    b->has_normals = 1;
    lk_status status = b->colors_16bit ? LK_OK : lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    if (status == LK_OK && report(b, 0.0, "bounds")) status = cancelled_error(error);
    int created = 0;
    if (status == LK_OK) status = for_each_batch(b, batch, bounds_batch, "bounds", 0.0, 0.0, error);
    if (status == LK_OK) status = make_folder(out_dir, &created, error);
    if (status == LK_OK) {
        b->keep_normals = b->has_normals && b->options.normals == LK_OCTREE_NORMALS_AUTO;
        b->estimate_normals = b->options.normals == LK_OCTREE_NORMALS_ESTIMATE;
        status = choose_frame(b, error);
    }
    size_t grid_cells = (size_t)1 << (3 * OT_GRID_BITS);
    if (status == LK_OK) {
        b->grid_counts = calloc(grid_cells, sizeof *b->grid_counts);
        b->cell_chunk = calloc(grid_cells, sizeof *b->cell_chunk);
        if (!b->grid_counts || !b->cell_chunk) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    if (status == LK_OK) status = for_each_batch(b, batch, count_batch, "counting", 0.0, 0.1, error);
    if (status == LK_OK) status = adapt_to_cloud(b, error);
    if (status == LK_OK) {
        uint32_t root[3] = {0, 0, 0};
        long top;
        status = plan_chunks(b, 0, root, "r", b->total, &top, error);
    }
    free(b->grid_counts);
    b->grid_counts = NULL;
    if (status == LK_OK) {
        const char *folder = b->options.temp_dir ? b->options.temp_dir : out_dir;
        char *base = lk__octree_join_path(folder, "octree");
        status = base ? lk__temp_dir_create(base, "spill", &b->spill_dir, error)
                      : lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        free(base);
    }
    if (status == LK_OK) {
        /* 64 KiB buffers, smaller when there are many chunks (64 MiB in all) */
        size_t per_chunk = ((size_t)64 << 20) / b->chunk_count;
        if (per_chunk > OT_MAX_SPILL_BUFFER) per_chunk = OT_MAX_SPILL_BUFFER;
        b->spill_buffer_points = per_chunk / sizeof(ot_point);
        if (b->spill_buffer_points < 16) b->spill_buffer_points = 16;
        for (size_t c = 0; c < b->chunk_count && status == LK_OK; c++) {
            b->chunks[c].buffer = lk__malloc_array(b->spill_buffer_points, sizeof(ot_point));
            if (!b->chunks[c].buffer) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        }
    }
    if (status == LK_OK) status = for_each_batch(b, batch, spill_batch, "spilling", 0.1, 0.3, error);
    for (size_t c = 0; c < b->chunk_count && status == LK_OK; c++) status = flush_spill(b, c, error);
    for (size_t c = 0; c < b->chunk_count; c++) {
        free(b->chunks[c].buffer);
        b->chunks[c].buffer = NULL;
    }
    free(b->cell_chunk);
    b->cell_chunk = NULL;
    if (status == LK_OK) {
        unsigned threads = b->options.threads;
        if (threads == 0) {
            long online = sysconf(_SC_NPROCESSORS_ONLN);
            threads = online > 0 ? (unsigned)online : 1;
        }
        if (threads > 64) threads = 64;
        if (threads > b->chunk_count) threads = (unsigned)b->chunk_count;
        pthread_t workers[64];
        unsigned started = 0;
        for (unsigned t = 1; t < threads; t++)
            if (pthread_create(&workers[started], NULL, chunk_worker, b) == 0) started++;
        chunk_worker(b);
        for (unsigned t = 0; t < started; t++) pthread_join(workers[t], NULL);
        if (b->first_status != LK_OK) {
            status = b->first_status;
            if (error) *error = b->first_error;
        } else if (b->cancelled)
            status = cancelled_error(error);
    }
    if (status == LK_OK) status = build_top(b, error);
    if (status == LK_OK) status = write_output(b, out_dir, error);
    if (status == LK_OK) report(b, 1.0, "done");
    remove_spill_dir(b);
    if (status != LK_OK && created) rmdir(out_dir); /* only when still empty */
    b->stats.points = b->total;
    b->stats.chunks = b->chunk_count;
    b->stats.seconds = now_seconds() - start;
    if (stats && status == LK_OK) *stats = b->stats;
    for (size_t c = 0; c < b->chunk_count; c++) free(b->chunks[c].records);
    for (size_t t = 0; t < b->top_count; t++) free(b->tops[t].points);
    free(b->chunks);
    free(b->tops);
    free(b->colors_16bit);
    free(b->grid_counts);
    free(b->cell_chunk);
    pthread_mutex_destroy(&b->lock);
    free(b);
    free(batch);
    return status;
}
