/* SPDX-License-Identifier: MIT */
/* Quadric error metric simplification: Garland & Heckbert, "Surface
 * simplification using quadric error metrics" (SIGGRAPH 1997), with the
 * attribute quadrics of Hoppe, "New quadric metric for simplifying meshes
 * with appearance attributes" (1999).
 *
 * Quadrics. Every vertex carries the sum of the area-weighted squared-
 * distance quadrics of the planes of its triangles, plus constraint
 * quadrics for border, non-manifold and crease edges (the plane through
 * the edge perpendicular to each of its faces, weighted by
 * feature_weight * |edge|^2 so that units match the area-weighted face
 * quadrics, a crease's more as its fold sharpens: qem_build.c) and a point
 * quadric at corners (three or more such edges).
 * Contracting a pair (p, q) costs v^T (Qp + Qq) v at the v minimising it;
 * when the 3x3 system is ill-conditioned, or its optimum lies far from the
 * pair, v is the best point of the segment pq (its minimum, ends or
 * midpoint). The reported error sqrt(cost / area) is an RMS plane distance.
 * With LK_SIMPLIFY_ATTRIBUTES, Hoppe's quadric adds, per face and channel,
 * (g.v + d - s)^2 where s(v) = g.v + d interpolates the channel on the
 * face; minimising over s first leaves a 3x3 system in v again.
 *
 * Pairs are the mesh edges plus, with pair_distance > 0, the nearest
 * non-edge vertex pairs closer than that (found with a hashed grid).
 *
 * Queue. Entries (a, b, time, key) sit in a bucket queue keyed by the bits
 * of the float cost: positive floats order like their bit patterns, so
 * key >> bucket_shift gives ordered buckets 1/256 of an octave (0.27% of
 * the cost; 1/64 with collapses in rounds) wide. A bucket is a stack of small chunks and a two-level bitmap
 * finds the lowest non-empty one, so push and pop are O(1) on contiguous
 * memory. Keys are cheap lower bounds: the unconstrained minimum of the
 * summed quadric, which no placement can beat; the popped pair gets the
 * full evaluation and goes back if its true cost falls in a higher bucket.
 * A contraction pushes fresh entries for every edge around the kept vertex
 * p; older entries naming p or the removed vertex are recognised as
 * obsolete when popped (an end's quadric changed after their time). Entries
 * of non-edge pairs (PERSISTENT) instead follow their ends through the
 * contractions: quadrics only grow, so a stale cost is still a lower bound.
 *
 * A pair is refused, and parked until a triangle around it changes, when
 * the contraction would
 *   - break the link condition: for an edge, the vertices adjacent to both
 *     ends must be exactly the opposite vertices of the triangles on the
 *     edge; an interior edge may not join two border vertices; no edge may
 *     end up with more than two triangles (this also governs non-edge pairs,
 *     which may join components but not create non-manifold edges);
 *   - create a duplicate triangle (e.g. flatten a tetrahedron), or leave the
 *     kept vertex without triangles (a component would vanish);
 *   - turn a surviving triangle's normal by more than acos(FLIP_COSINE) or
 *     make it zero-area;
 *   - exceed options->max_error.
 * Parked pairs are rescanned every few hundred contractions and when the
 * queue runs dry; they return once a stamp of an endpoint's neighbourhood
 * is newer than the refusal.
 *
 * Connectivity. Each vertex owns a block of a pool listing its live
 * triangles (initially compressed rows); a contraction writes the merged
 * list of p and q into p's block, q's block, or a new block at the end of
 * the pool. Removed vertices point to their survivor (union-find).
 *
 * Memory. Cache misses, not arithmetic, bound the speed: contractions jump
 * around the mesh in cost order. So vertices and triangles are renumbered
 * internally in Morton order (a neighbourhood then shares cache lines and
 * pages), the data a pair evaluation reads (quadric, position, parent,
 * triangle count) share one 128-byte record, per-vertex arrays scanned at
 * random are kept small (stamps, 8-byte link counters), and a contraction
 * requests its whole neighbourhood (and the next queued pair) before using
 * it, so that the misses overlap. Input ids are restored on output and in
 * the history.
 *
 * Geometry is translated and scaled so that the bounding-box diagonal is 1;
 * quadrics are accumulated in double.
 *
 * Files. qem_state.h holds the state, split by concern (the static engine's,
 * the per-frame extension, the lost-surface term), and the inline helpers
 * the three files share; qem_build.c sets the state up; qem_frames.c holds
 * several frames (lk_animation_simplify: Cho & Chen's deformation-sensitive
 * simplification, driven by anim_simplify.c) and the lost-surface term;
 * this file is the engine: queue, pair evaluation, checks, contraction,
 * main loop, output and the entry points. */
#include "qem_state.h"

#include <stdlib.h>

/* Contractions between rescans of parked pairs (at least). */
#define RESCAN_INTERVAL 256
/* Contractions between progress reports. */
#define PROGRESS_INTERVAL 4096

struct queue_item {
    uint32_t a, b;
    uint32_t time; /* contraction number when evaluated or parked, | PERSISTENT */
    uint32_t key;  /* bits of the float cost: ordered like the cost */
};
#define PERSISTENT 0x80000000u

/* Bucket queue: keys are the bits of the float cost, which order like the
 * cost; bucket = key >> s->bucket_shift spans 1/2^(23 - bucket_shift) of
 * an octave. A bucket is a stack of chunks; a two-level bitmap finds the
 * lowest non-empty bucket. Push and pop are O(1) and touch contiguous
 * memory; within a bucket the order is last in, first out, hence 1/256 of
 * an octave (1/64 with rounds: docs/benchmarks.md, "QEM queue
 * resolution"). BUCKET_COUNT: the finer shift's (no sign bit). */
#define FINE_BUCKET_SHIFT 15
#define ROUNDS_BUCKET_SHIFT 17
#define BUCKET_COUNT (1u << (31 - FINE_BUCKET_SHIFT))
#define BUCKET_WORDS ((BUCKET_COUNT + 63) / 64)
#define SUMMARY_WORDS ((BUCKET_WORDS + 63) / 64)
/* An item as a chunk holds it: without the key, which only chose the
 * bucket (a popped item is evaluated afresh), so that the queue, the
 * largest part of the peak memory after the vertex records, is 12 bytes
 * an item rather than 16. */
typedef struct queued_item {
    uint32_t a, b, time;
} queued_item;
/* 256 bytes: a chunk is fetched whole, ahead of its pops (queue_pop) */
#define CHUNK_ITEMS 20
struct queue_chunk {
    uint32_t next; /* next chunk of the bucket (full), or of the free list */
    uint32_t unused[3];
    queued_item items[CHUNK_ITEMS];
};
_Static_assert(sizeof(struct queue_chunk) == 256, "a chunk must fill four cache lines");

/* A bucket's first chunk and how many of its items are used (the other
 * chunks are full). The fill lives here, in a small array, so that a push
 * only writes to the chunk: a store miss does not stall. */
struct queue_bucket {
    uint32_t chunk; /* NONE when empty */
    uint32_t fill;
};

/* With allow_folds, when every remaining pair is refused, the number of
 * frames a contraction may fold (turn a triangle by more than
 * acos(FLIP_COSINE)) grows through these fractions of the frame count;
 * the reference frame never folds. The last stage checks the reference
 * frame alone, like the static simplifier. Intermediate stages (0.01,
 * 0.02, 0.05, 0.1, 0.2, 0.5) were measured worse: on faerie.md2 at 20% the
 * max scheme's worst-frame RMS grew from 0.75% to 1.05% of the diagonal
 * (pairs that fold a few frames are not better than pairs that fold many,
 * and they go first). */
static const double FOLD_STAGES[] = {0, 1.0};
#define FOLD_STAGE_COUNT (sizeof FOLD_STAGES / sizeof FOLD_STAGES[0])

/* ------------------------------------------------------------------------ */
/* Cache prefetch                                                           */
/* ------------------------------------------------------------------------ */

/* Cache misses dominate a contraction: its vertices and triangles are
 * scattered. Requesting a whole neighbourhood up front lets the misses
 * overlap instead of queueing one behind the other. */
#if defined(__GNUC__)
#define prefetch(address) __builtin_prefetch(address)
/* GCC counts a function whose only effects are prefetches as pure and
 * drops calls to it (it dropped the previous next-pair prefetch) unless
 * inlined first. */
#define ALWAYS_INLINE __attribute__((always_inline))
#else
#define prefetch(address) ((void)(address))
#define ALWAYS_INLINE
#endif

/* ------------------------------------------------------------------------ */
/* Bucket queue                                                             */
/* ------------------------------------------------------------------------ */

static inline uint32_t cost_key(double cost)
{
    float value = (float)cost; /* cost >= 0 */
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    return bits;
}

static inline uint32_t lowest_bit(uint64_t bits)
{
#if defined(__GNUC__)
    return (uint32_t)__builtin_ctzll(bits);
#else
    uint32_t i = 0;
    while (!(bits & 1)) bits >>= 1, i++;
    return i;
#endif
}

static bool make_room(qem *s);

static inline bool queue_push(qem *s, queue_item item)
{
    if (s->free_chunks == NONE && s->chunk_count == s->chunk_capacity && !make_room(s)) return false;
    uint32_t index = item.key >> s->bucket_shift;
    queue_bucket *bucket = &s->buckets[index];
    if (bucket->chunk == NONE || bucket->fill == CHUNK_ITEMS) {
        uint32_t chunk = s->free_chunks;
        if (chunk != NONE) {
            s->free_chunks = s->chunks[chunk].next;
        } else {
            if (s->chunk_count == s->chunk_capacity) {
                size_t capacity = s->chunk_capacity + s->chunk_capacity / 2 + 64;
                if (capacity >= NONE) return false;
                queue_chunk *grown = lk__realloc_array(s->chunks, capacity, sizeof *grown);
                if (!grown) return false;
                s->chunks = grown;
                s->chunk_capacity = capacity;
            }
            chunk = (uint32_t)s->chunk_count++;
        }
        if (bucket->chunk == NONE) {
            s->bucket_bits[index >> 6] |= 1ull << (index & 63);
            s->summary_bits[index >> 12] |= 1ull << ((index >> 6) & 63);
        }
        s->chunks[chunk].next = bucket->chunk;
        bucket->chunk = chunk;
        bucket->fill = 0;
    }
    s->chunks[bucket->chunk].items[bucket->fill++] = (queued_item){item.a, item.b, item.time};
    if (index < s->current_bucket) s->current_bucket = index;
    s->queued++;
    return true;
}

/* First non-empty bucket at or after `from` (the queue must not be empty). */
static uint32_t next_bucket(const qem *s, uint32_t from)
{
    uint32_t word = from >> 6;
    uint64_t bits = s->bucket_bits[word] & (~0ull << (from & 63));
    if (bits) return (word << 6) + lowest_bit(bits);
    word++;
    uint32_t summary = word >> 6;
    uint64_t words = summary < SUMMARY_WORDS ? s->summary_bits[summary] & (~0ull << (word & 63)) : 0;
    while (!words) words = s->summary_bits[++summary];
    word = (summary << 6) + lowest_bit(words);
    return (word << 6) + lowest_bit(s->bucket_bits[word]);
}

/* Drops the obsolete items of a full chunk about to become a bucket's
 * head, keeping the order of the others, and returns how many remain. An
 * item is obsolete once an end's stamp passes its time (item_ends), and
 * stays so: stamps only grow. Most queued items end that way, and one
 * unpredictable branch per pop, each behind a stamp's cache miss, cost
 * more than these loads, which are independent and overlap. Non-edge
 * (PERSISTENT) items are left to item_ends. */
static inline uint32_t drop_obsolete(const qem *s, queue_chunk *chunk)
{
    uint32_t kept = 0;
    for (int i = 0; i < CHUNK_ITEMS; i++) {
        queued_item item = chunk->items[i];
        bool live = (item.time & PERSISTENT) || (s->stamp[item.a] <= item.time && s->stamp[item.b] <= item.time);
        chunk->items[kept] = item;
        kept += live;
    }
    return kept;
}

/* The bucket's head chunk is empty: the next chunk (full, less its
 * obsolete items) becomes the head, or the bucket empties. */
static void advance_head(qem *s, queue_bucket *bucket, uint32_t index)
{
    do {
        uint32_t empty = bucket->chunk;
        queue_chunk *chunk = &s->chunks[empty];
        bucket->chunk = chunk->next;
        chunk->next = s->free_chunks;
        s->free_chunks = empty;
        if (bucket->chunk == NONE) {
            bucket->fill = 0;
            s->bucket_bits[index >> 6] &= ~(1ull << (index & 63));
            if (!s->bucket_bits[index >> 6]) s->summary_bits[index >> 12] &= ~(1ull << ((index >> 6) & 63));
            return;
        }
        /* Items wait long in the queue: their chunk has left the cache by
         * the time they are popped. The new head was requested when it
         * became next; request its successor now, a chunk's worth of pops
         * before its use. */
        queue_chunk *head = &s->chunks[bucket->chunk];
        if (head->next != NONE) {
            const char *lines = (const char *)&s->chunks[head->next];
            for (size_t offset = 0; offset < sizeof(queue_chunk); offset += 64) prefetch(lines + offset);
            prefetch(lines + sizeof(queue_chunk) - 1); /* a grown array need not start a line */
        }
        bucket->fill = drop_obsolete(s, head);
        s->queued -= CHUNK_ITEMS - bucket->fill;
    } while (bucket->fill == 0);
}

/* Drops the obsolete items of every bucket (drop_obsolete's rule),
 * keeping the order of the others, and returns the chunks freed. Obsolete
 * items pile up in the buckets above the current one, which the pops
 * reach late or never: on a 20M-triangle mesh the queue grew to 2.4 times
 * its initial size, the largest growth of the run. A bucket's items, in
 * pop order, sit at positions 20 - fill .. 20 M - 1 of its chain of M
 * chunks (position g: chunk g / CHUNK_ITEMS, slot CHUNK_ITEMS - 1 - g %
 * CHUNK_ITEMS); the live ones move to the end, the chunks left empty at
 * the front are freed. */
static size_t purge_queue(qem *s)
{
    size_t freed = 0, chain_capacity = 0;
    uint32_t *chain = NULL;
    for (uint32_t index = 0; index < BUCKET_COUNT; index++) {
        queue_bucket *bucket = &s->buckets[index];
        if (bucket->chunk == NONE) continue;
        size_t length = 0;
        for (uint32_t c = bucket->chunk; c != NONE; c = s->chunks[c].next) {
            if (length == chain_capacity) {
                size_t capacity = chain_capacity ? 2 * chain_capacity : 256;
                uint32_t *grown = lk__realloc_array(chain, capacity, sizeof *grown);
                if (!grown) {
                    free(chain);
                    return freed; /* nothing half done: this bucket is untouched */
                }
                chain = grown, chain_capacity = capacity;
            }
            chain[length++] = c;
        }
        size_t end = length * CHUNK_ITEMS, first = CHUNK_ITEMS - bucket->fill, write = end;
        for (size_t g = end; g-- > first;) {
            queued_item item = s->chunks[chain[g / CHUNK_ITEMS]].items[CHUNK_ITEMS - 1 - g % CHUNK_ITEMS];
            if (!(item.time & PERSISTENT) && (s->stamp[item.a] > item.time || s->stamp[item.b] > item.time)) continue;
            write--;
            s->chunks[chain[write / CHUNK_ITEMS]].items[CHUNK_ITEMS - 1 - write % CHUNK_ITEMS] = item;
        }
        s->queued -= write - first;
        size_t head = write / CHUNK_ITEMS;
        for (size_t k = 0; k < head; k++) {
            s->chunks[chain[k]].next = s->free_chunks;
            s->free_chunks = chain[k];
            freed++;
        }
        if (head == length) {
            bucket->chunk = NONE;
            bucket->fill = 0;
            s->bucket_bits[index >> 6] &= ~(1ull << (index & 63));
            if (!s->bucket_bits[index >> 6]) s->summary_bits[index >> 12] &= ~(1ull << ((index >> 6) & 63));
        } else {
            bucket->chunk = chain[head];
            bucket->fill = (uint32_t)((head + 1) * CHUNK_ITEMS - write);
        }
    }
    free(chain);
    return freed;
}

/* Every chunk is in use: purge the queue, and grow it too unless that
 * freed a quarter of it (so that purges stay rare). False when out of
 * memory. */
static bool make_room(qem *s)
{
    if (purge_queue(s) >= s->chunk_capacity / 4) return true;
    size_t capacity = s->chunk_capacity + s->chunk_capacity / 2 + 64;
    if (capacity >= NONE) return s->free_chunks != NONE;
    queue_chunk *grown = lk__realloc_array(s->chunks, capacity, sizeof *grown);
    if (!grown) return s->free_chunks != NONE;
    s->chunks = grown;
    s->chunk_capacity = capacity;
    return true;
}

/* Removes an item of the lowest bucket; false when the queue is empty. */
static inline bool queue_pop(qem *s, queue_item *out)
{
    if (s->queued == 0) return false;
    uint32_t index = next_bucket(s, s->current_bucket);
    s->current_bucket = index;
    queue_bucket *bucket = &s->buckets[index];
    queue_chunk *chunk = &s->chunks[bucket->chunk];
    const queued_item *top = &chunk->items[--bucket->fill];
    *out = (queue_item){top->a, top->b, top->time, 0}; /* the key is the caller's to compute */
    s->queued--;
    if (bucket->fill == 0) advance_head(s, bucket, index);
    return true;
}

/* Pops run ahead of the data they need: most popped items are obsolete
 * (an end contracted after they were queued), found so by one random load
 * of a stamp, and a live one needs two vertex records. Items keep their
 * order; these only request memory for the items the next pops will
 * return: the stamps of the one STAMP_AHEAD places down the current bucket,
 * and, when its stamps (requested earlier) show it live, the records of
 * the one RECORD_AHEAD places down. */
#define STAMP_AHEAD 20
#define RECORD_AHEAD 2

/* The item `depth` places below the top of the current bucket, or NULL
 * when that is past the bucket's first two chunks. */
static inline const queued_item *item_below_top(const qem *s, uint32_t depth)
{
    const queue_bucket *bucket = &s->buckets[s->current_bucket];
    if (bucket->chunk == NONE) return NULL;
    const queue_chunk *chunk = &s->chunks[bucket->chunk];
    if (depth < bucket->fill) return &chunk->items[bucket->fill - 1 - depth];
    depth -= bucket->fill;
    if (chunk->next == NONE || depth >= CHUNK_ITEMS) return NULL;
    return &s->chunks[chunk->next].items[CHUNK_ITEMS - 1 - depth];
}

ALWAYS_INLINE static inline void prefetch_ahead(const qem *s)
{
    if (s->queued <= RECORD_AHEAD) return;
    const queued_item *far = item_below_top(s, STAMP_AHEAD);
    if (far) prefetch(&s->stamp[far->a]), prefetch(&s->stamp[far->b]);
    const queued_item *near = item_below_top(s, RECORD_AHEAD);
    if (!near) return;
    if (!(near->time & PERSISTENT) && (s->stamp[near->a] > near->time || s->stamp[near->b] > near->time)) return;
    const vertex *a = &s->vertices[near->a], *b = &s->vertices[near->b];
    prefetch(a), prefetch(a->position), prefetch(b), prefetch(b->position);
}

/* ------------------------------------------------------------------------ */
/* Pair evaluation                                                          */
/* ------------------------------------------------------------------------ */

static inline uint32_t representative(vertex *vertices, uint32_t v)
{
    while (vertices[v].parent != v) {
        vertices[v].parent = vertices[vertices[v].parent].parent; /* path halving */
        v = vertices[v].parent;
    }
    return v;
}

/* Adds the attribute terms of a + b, reduced to the position: minimising
 * over the attribute values s_j = -(g_j.x + bs_j) / w leaves a quadric in x
 * alone (Schur complement of the diagonal attribute block). */
static void add_reduced_attributes(const qem *s, uint32_t va, uint32_t vb, double weight, double a[6], double b[3],
                                   double *c)
{
    const double *qa = s->attribute_quadrics + va * s->attribute_stride;
    const double *qb = s->attribute_quadrics + vb * s->attribute_stride;
    unsigned m = s->attribute_count;
    for (int k = 0; k < 6; k++) a[k] += qa[k] + qb[k];
    for (int k = 0; k < 3; k++) b[k] += qa[6 + k] + qb[6 + k];
    *c += qa[9] + qb[9];
    if (!(weight > 0)) return;
    double inverse = 1.0 / weight;
    for (unsigned j = 0; j < m; j++) {
        const double *ga = qa + 10 + 3 * j, *gb = qb + 10 + 3 * j;
        double g[3] = {ga[0] + gb[0], ga[1] + gb[1], ga[2] + gb[2]};
        double bs = qa[10 + 3 * m + j] + qb[10 + 3 * m + j];
        a[0] -= g[0] * g[0] * inverse, a[1] -= g[0] * g[1] * inverse, a[2] -= g[0] * g[2] * inverse;
        a[3] -= g[1] * g[1] * inverse, a[4] -= g[1] * g[2] * inverse, a[5] -= g[2] * g[2] * inverse;
        b[0] -= g[0] * bs * inverse, b[1] -= g[1] * bs * inverse, b[2] -= g[2] * bs * inverse;
        *c -= bs * bs * inverse;
    }
}

/* Places the merged vertex of pair (va, vb) for the quadric q = (A, b, c)
 * (q: a00 a01 a02 a11 a12 a22 b0 b1 b2 c) and records its cost. Scalar
 * locals, written out only at the end, let the compiler keep everything in
 * registers. Always inlined: on smooth meshes most queue keys come from the
 * full evaluation (cost_lower_bound's fallback), and a call passes q and
 * the placement through memory (1.10-1.16x on the 1.1M-triangle bunny). */
ALWAYS_INLINE static inline void place(const qem *s, uint32_t va, uint32_t vb, const double *q, placement *out)
{
    const double *pa = s->vertices[va].position, *pb = s->vertices[vb].position;
    double a00 = q[0], a01 = q[1], a02 = q[2], a11 = q[3], a12 = q[4], a22 = q[5];
    double b0 = q[6], b1 = q[7], b2 = q[8], c = q[9];
    double x0, x1, x2;
    uint32_t kept;
    if (((s->flags[va] | s->flags[vb]) & FLAG_LOCKED) || ((s->flags[va] ^ s->flags[vb]) & FLAG_SEAM)) {
        kept = (s->flags[va] & (FLAG_LOCKED | FLAG_SEAM)) ? va : vb;
        if ((s->flags[va] | s->flags[vb]) & FLAG_LOCKED) kept = (s->flags[va] & FLAG_LOCKED) ? va : vb;
        const double *fixed = kept == va ? pa : pb;
        x0 = fixed[0], x1 = fixed[1], x2 = fixed[2];
    } else if (s->endpoints) {
        /* Half-edge collapse: the cheaper endpoint stays where it is, so a
         * progressive mesh need not store where it was before. */
        double cost_a = quadric_value(q, q + 6, c, pa), cost_b = quadric_value(q, q + 6, c, pb);
        kept = cost_a <= cost_b ? va : vb;
        const double *fixed = kept == va ? pa : pb;
        x0 = fixed[0], x1 = fixed[1], x2 = fixed[2];
    } else {
        double x[3];
        /* keep the end nearer to the new position */
        kept = optimal_point(q, pa, pb, x) <= 0 ? va : vb;
        x0 = x[0], x1 = x[1], x2 = x[2];
    }
    double cost = x0 * (a00 * x0 + a01 * x1 + a02 * x2 + 2 * b0) + x1 * (a01 * x0 + a11 * x1 + a12 * x2 + 2 * b1) +
                  x2 * (a02 * x0 + a12 * x1 + a22 * x2 + 2 * b2) + c;
    out->position[0] = x0, out->position[1] = x1, out->position[2] = x2;
    out->kept = kept;
    out->removed = kept == va ? vb : va;
    out->cost = cost > 0 ? cost : 0;
}

static void evaluate_with_attributes(const qem *s, uint32_t va, uint32_t vb, placement *out)
{
    const quadric *qa = &s->vertices[va].q, *qb = &s->vertices[vb].q;
    double geometric_q[10], total[10], weight = qa->weight + qb->weight;
    for (int k = 0; k < 10; k++) total[k] = geometric_q[k] = qa->m[k] + qb->m[k];
    add_reduced_attributes(s, va, vb, weight, total, total + 6, total + 9);
    place(s, va, vb, total, out);
    double geometric = quadric_value(geometric_q, geometric_q + 6, geometric_q[9], out->position);
    out->error_sq = weight > 0 && geometric > 0 ? geometric / weight : 0;
}

/* Cost and placement of contracting va and vb. */
static inline void evaluate(const qem *s, uint32_t va, uint32_t vb, placement *out)
{
    if (s->frames.count) {
        lk__qem_evaluate_frames(s, va, vb, out);
        return;
    }
    if (s->attribute_quadrics_on) {
        evaluate_with_attributes(s, va, vb, out);
        return;
    }
    const double *qa = s->vertices[va].q.m, *qb = s->vertices[vb].q.m;
    double q[10];
    for (int k = 0; k < 10; k++) q[k] = qa[k] + qb[k];
    place(s, va, vb, q, out);
    double weight = s->vertices[va].q.weight + s->vertices[vb].q.weight;
    out->error_sq = weight > 0 ? out->cost / weight : 0;
}

/* A lower bound of the cost of contracting va and vb, cheap enough for the
 * queue keys: the unconstrained minimum b.x + c of the summed quadric at
 * A x = -b. Whatever placement evaluate() then picks (the same point, or
 * the segment, or a locked end) costs at least that, so a popped pair
 * whose true cost lands in a higher bucket just goes back. Nearly singular
 * systems (flat or cylindrical parts) and attribute quadrics take the full
 * evaluation: a bound of 0 there would send back nearly every flat pair,
 * whose true cost is tiny but not 0. */
static inline double cost_lower_bound(const qem *s, uint32_t va, uint32_t vb)
{
    if (!s->attribute_quadrics_on && !s->frames.count) {
        const double *qa = s->vertices[va].q.m, *qb = s->vertices[vb].q.m;
        double a00 = qa[0] + qb[0], a01 = qa[1] + qb[1], a02 = qa[2] + qb[2];
        double a11 = qa[3] + qb[3], a12 = qa[4] + qb[4], a22 = qa[5] + qb[5];
        double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11;
        double det = a00 * c00 + a01 * c01 + a02 * c02, trace = a00 + a11 + a22;
        if (fabs(det) > DET_EPSILON * trace * trace * trace) {
            double b0 = qa[6] + qb[6], b1 = qa[7] + qb[7], b2 = qa[8] + qb[8];
            double c11 = a00 * a22 - a02 * a02, c12 = a01 * a02 - a00 * a12, c22 = a00 * a11 - a01 * a01;
            double x0 = c00 * b0 + c01 * b1 + c02 * b2;
            double x1 = c01 * b0 + c11 * b1 + c12 * b2;
            double x2 = c02 * b0 + c12 * b1 + c22 * b2;
            double cost = qa[9] + qb[9] - (b0 * x0 + b1 * x1 + b2 * x2) / det;
            return cost > 0 ? cost : 0; /* NaN too */
        }
    }
    placement pl;
    pl.frames = NULL;
    evaluate(s, va, vb, &pl);
    return pl.cost;
}

/* ------------------------------------------------------------------------ */
/* Topology and geometry checks                                             */
/* ------------------------------------------------------------------------ */

static void next_token(qem *s)
{
    if (++s->token == 0) {
        for (size_t v = 0; v < s->vertex_count; v++) s->link[v].mark = 0;
        s->token = 1;
    }
}

static inline link_counts *touch(qem *s, uint32_t v)
{
    link_counts *counts = &s->link[v];
    if (counts->mark != s->token) {
        counts->mark = s->token;
        counts->around_p = counts->around_q = counts->shared = 0;
    }
    return counts;
}

/* True when p has a triangle using both r and w. */
static bool has_triangle_with(const qem *s, uint32_t p, uint32_t r, uint32_t w)
{
    const uint32_t *list = list_of(s, p);
    for (uint32_t i = 0; i < s->vertices[p].list_count; i++) {
        const uint32_t *t = s->indices + 3 * (size_t)list[i];
        if (triangle_has(t, r) && triangle_has(t, w)) return true;
    }
    return false;
}

/* False when moving corner `moved` of triangle t to x turns the triangle's
 * normal by more than acos(FLIP_COSINE) or makes it zero-area. */
static inline bool keeps_orientation(const qem *s, const uint32_t *t, uint32_t moved, const double x[3])
{
    int k = t[0] == moved ? 0 : t[1] == moved ? 1 : 2;
    const double *p0 = s->vertices[t[k]].position;
    const double *p1 = s->vertices[t[k == 2 ? 0 : k + 1]].position;
    const double *p2 = s->vertices[t[k == 0 ? 2 : k - 1]].position;
    return corner_move_keeps_orientation(p0, p1, p2, x);
}

/* The same test in every frame, with each frame's new position (frames
 * other than the reference: qem_frames.c). */
static bool keeps_orientation_everywhere(qem *s, const uint32_t *t, uint32_t moved, const placement *pl)
{
    if (!s->frames.count) return keeps_orientation(s, t, moved, pl->position);
    if (!keeps_orientation(s, t, moved, pl->position)) return false; /* the reference frame */
    return lk__qem_frames_keep_orientation(s, t, moved, pl);         /* the other frames */
}

/* Decides whether contracting pl->removed (q) into pl->kept (p) at
 * pl->position is allowed (link condition, no new non-manifold edge, no
 * duplicate triangle, no vanishing component, no flipped triangle: see the
 * top comment) and, if so, leaves p's merged triangle list in
 * scratch[0 .. *merged) and the triangles on pq in scratch[*merged ..
 * *merged + *vanishing). One pass over the triangles of p and of q serves
 * all the tests, which read the same corners. scratch must hold
 * count_p + count_q entries. */
static bool check_contraction(qem *s, const placement *pl, uint32_t *merged, uint32_t *vanishing)
{
    uint32_t p = pl->kept, q = pl->removed;
    const uint32_t *list_p = list_of(s, p), *list_q = list_of(s, q);
    uint32_t count_p = s->vertices[p].list_count, count_q = s->vertices[q].list_count;
    if (count_p > MAX_LINK_DEGREE || count_q > MAX_LINK_DEGREE) return false;
    for (uint32_t i = 0; i < count_p; i++) prefetch(s->indices + 3 * (size_t)list_p[i]);
    for (uint32_t i = 0; i < count_q; i++) prefetch(s->indices + 3 * (size_t)list_q[i]);
    for (int side = 0; side < 2; side++) {
        const uint32_t *list = side ? list_q : list_p;
        uint32_t count = side ? count_q : count_p;
        for (uint32_t i = 0; i < count; i++) {
            const uint32_t *t = s->indices + 3 * (size_t)list[i];
            for (int k = 0; k < 3; k++) {
                const vertex *corner = &s->vertices[t[k]];
                prefetch(corner), prefetch(corner->position), prefetch(&s->link[t[k]]);
            }
        }
    }
    next_token(s);
    if (s->frames.count && s->frames.folded_count) {
        memset(s->frames.folded, 0, s->frames.count);
        s->frames.folded_count = 0;
    }
    uint32_t *survivors = s->scratch, *on_pq = s->scratch + count_p + count_q; /* on_pq grows down */
    uint32_t survivor_count = 0, shared = 0;
    for (uint32_t i = 0; i < count_p; i++) {
        const uint32_t *t = s->indices + 3 * (size_t)list_p[i];
        bool with_q = triangle_has(t, q);
        for (int k = 0; k < 3; k++) {
            uint32_t r = t[k];
            if (r == p || r == q) continue;
            link_counts *counts = touch(s, r);
            counts->around_p++;
            counts->shared += with_q;
        }
        if (with_q) {
            *--on_pq = list_p[i];
            shared++;
            /* The opposite vertex will lose t (contract): its record was
             * requested above, so its list can be now. */
            for (int k = 0; k < 3; k++)
                if (t[k] != p && t[k] != q) prefetch(list_of(s, t[k]));
        } else {
            if (!keeps_orientation_everywhere(s, t, p, pl)) return false;
            survivors[survivor_count++] = list_p[i];
        }
    }
    /* The kept vertex must keep a triangle, or a component would vanish. */
    if (count_p + count_q <= 2 * shared) return false;
    /* An interior edge joining two border vertices would pinch the surface. */
    if (shared >= 2 && (s->flags[p] & (FLAG_BORDER | FLAG_NONMANIFOLD)) &&
        (s->flags[q] & (FLAG_BORDER | FLAG_NONMANIFOLD)))
        return false;
    /* Counts only grow, so each test can run as soon as its count moves. */
    for (uint32_t i = 0; i < count_q; i++) {
        const uint32_t *t = s->indices + 3 * (size_t)list_q[i];
        if (triangle_has(t, p)) continue;
        uint32_t others[2], other_count = 0;
        for (int k = 0; k < 3; k++)
            if (t[k] != q) others[other_count++] = t[k];
        for (int k = 0; k < 2; k++) {
            link_counts *counts = touch(s, others[k]);
            counts->around_q++;
            if (counts->around_p == 0) continue;
            /* For an edge, a common neighbour must be an opposite vertex. */
            if (shared > 0 && counts->shared == 0) return false;
            /* The merged edge p-r: n(p,r) + n(q,r) - 2 n(p,q,r) triangles. */
            if (counts->around_p + counts->around_q - counts->shared > 2) return false;
        }
        /* q's triangle (q, r, w) becomes (p, r, w): must not duplicate one of p's. */
        if (s->link[others[0]].around_p && s->link[others[1]].around_p && has_triangle_with(s, p, others[0], others[1]))
            return false;
        if (!keeps_orientation_everywhere(s, t, q, pl)) return false;
        survivors[survivor_count++] = list_q[i];
    }
    /* the triangles on pq follow the survivors */
    memmove(survivors + survivor_count, on_pq, shared * sizeof *on_pq);
    *merged = survivor_count;
    *vanishing = shared;
    return true;
}

/* ------------------------------------------------------------------------ */
/* Contraction                                                              */
/* ------------------------------------------------------------------------ */

static bool ensure_scratch(qem *s, size_t needed)
{
    if (needed <= s->scratch_capacity) return true;
    size_t capacity = needed * 2;
    uint32_t *grown = lk__realloc_array(s->scratch, capacity, sizeof *grown);
    if (!grown) return false;
    s->scratch = grown;
    s->scratch_capacity = capacity;
    return true;
}

/* Pool offsets are 32-bit: when a new block would end past pool_limit
 * (POOL_LIMIT), the live lists are first copied, without their spare room,
 * into a fresh pool. False when even that leaves no room. */
static bool compact_pool(qem *s, size_t needed)
{
    size_t live = 0;
    for (size_t v = 0; v < s->vertex_count; v++) live += s->vertices[v].list_count;
    if (needed > s->pool_limit || live > s->pool_limit - needed) return false;
    size_t capacity = live + needed;
    capacity = capacity < s->pool_limit - capacity / 2 ? capacity + capacity / 2 : s->pool_limit;
    uint32_t *fresh = lk__alloc_random_access(capacity, sizeof(uint32_t), false);
    if (!fresh) return false;
    size_t start = 0;
    for (size_t v = 0; v < s->vertex_count; v++) {
        vertex *vv = &s->vertices[v];
        memcpy(fresh + start, s->pool + vv->list_start, vv->list_count * sizeof(uint32_t));
        vv->list_start = (uint32_t)start;
        vv->list_capacity = vv->list_count;
        start += vv->list_count;
    }
    free(s->pool);
    s->pool = fresh;
    s->pool_size = start;
    s->pool_capacity = capacity;
    return true;
}

/* Places p's new list (held in scratch) into p's block, q's block or a new
 * block at the end of the pool. */
static bool store_list(qem *s, uint32_t p, uint32_t q, uint32_t count)
{
    vertex *vp = &s->vertices[p], *vq = &s->vertices[q];
    if (count > vp->list_capacity) {
        if (count <= vq->list_capacity) {
            vp->list_start = vq->list_start;
            vp->list_capacity = vq->list_capacity;
        } else {
            size_t capacity = (size_t)count + count / 2;
            if (s->pool_size + capacity > s->pool_capacity) {
                if (s->pool_size + capacity > s->pool_limit && !compact_pool(s, capacity)) return false;
                if (s->pool_size + capacity > s->pool_capacity) {
                    size_t grown_capacity = (s->pool_size + capacity) * 3 / 2;
                    if (grown_capacity > s->pool_limit) grown_capacity = s->pool_limit;
                    uint32_t *grown = lk__realloc_array(s->pool, grown_capacity, sizeof *grown);
                    if (!grown) return false;
                    s->pool = grown;
                    s->pool_capacity = grown_capacity;
                }
            }
            vp->list_start = (uint32_t)s->pool_size;
            vp->list_capacity = (uint32_t)capacity;
            s->pool_size += capacity;
        }
    }
    vq->list_capacity = 0;
    vq->list_count = 0;
    memcpy(s->pool + vp->list_start, s->scratch, count * sizeof(uint32_t));
    vp->list_count = count;
    return true;
}

static void remove_from_list(qem *s, uint32_t v, uint32_t triangle)
{
    uint32_t *list = s->pool + s->vertices[v].list_start;
    uint32_t count = s->vertices[v].list_count;
    for (uint32_t i = 0; i < count; i++)
        if (list[i] == triangle) {
            list[i] = list[count - 1];
            s->vertices[v].list_count = count - 1;
            return;
        }
}

/* New attribute values of the kept vertex (before the quadrics merge). */
static void contract_attributes(qem *s, const placement *pl)
{
    unsigned m = s->attribute_count;
    float *kept = s->attributes + (size_t)pl->kept * m;
    const float *removed = s->attributes + (size_t)pl->removed * m;
    if (s->attribute_quadrics_on) {
        const double *qa = s->attribute_quadrics + (size_t)pl->kept * s->attribute_stride;
        const double *qb = s->attribute_quadrics + (size_t)pl->removed * s->attribute_stride;
        double weight = s->vertices[pl->kept].q.weight + s->vertices[pl->removed].q.weight;
        if (weight > 0) {
            const double *x = pl->position;
            for (unsigned j = 0; j < m; j++) {
                const double *ga = qa + 10 + 3 * j, *gb = qb + 10 + 3 * j;
                double gx = (ga[0] + gb[0]) * x[0] + (ga[1] + gb[1]) * x[1] + (ga[2] + gb[2]) * x[2];
                double bs = qa[10 + 3 * m + j] + qb[10 + 3 * m + j];
                kept[j] = (float)(-(gx + bs) / weight / s->attribute_scale);
            }
        }
    } else {
        /* Interpolate along the pair at the projection of the new position. */
        const double *pk = s->vertices[pl->kept].position, *pr = s->vertices[pl->removed].position;
        double d[3], e[3];
        sub3(d, pr, pk);
        sub3(e, pl->position, pk);
        double length_sq = dot3(d, d), t = length_sq > 0 ? dot3(d, e) / length_sq : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        for (unsigned j = 0; j < m; j++) kept[j] = (float)(kept[j] + t * (removed[j] - kept[j]));
    }
    if (s->normal_channel != NONE) {
        float *n = kept + s->normal_channel;
        double length = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (length > 0) n[0] = (float)(n[0] / length), n[1] = (float)(n[1] / length), n[2] = (float)(n[2] / length);
    }
    if (s->color_channel != NONE)
        for (int k = 0; k < 4; k++) {
            float *value = kept + s->color_channel + k;
            *value = *value < 0 ? 0 : *value > 1 ? 1 : *value;
        }
}

/* Performs a contraction prepared by check_contraction. */
static bool contract(qem *s, const placement *pl, uint32_t merged, uint32_t vanishing)
{
    uint32_t p = pl->kept, q = pl->removed;
    vertex *vp = &s->vertices[p], *vq = &s->vertices[q];
    uint32_t now = ++s->now;
    lk_collapse *record = NULL;
    if (s->record) {
        record = &s->collapses[s->collapse_count++];
        record->kept = s->vertex_input[p];
        record->removed = s->vertex_input[q];
        record->first_vanished = (uint32_t)s->vanished_count;
    }
    /* q's surviving triangles now use p (p's own have no q: no-op) */
    for (uint32_t i = 0; i < merged; i++) {
        uint32_t *corners = s->indices + 3 * (size_t)s->scratch[i];
        for (int k = 0; k < 3; k++) corners[k] = corners[k] == q ? p : corners[k];
    }
    for (uint32_t i = 0; i < vanishing; i++) {
        const uint32_t *corners = s->indices + 3 * (size_t)s->scratch[merged + i];
        for (int k = 0; k < 3; k++) prefetch(list_of(s, corners[k]));
    }
    /* The triangles on pq vanish; their opposite vertices lose them. */
    uint32_t vanished_here = vanishing;
    for (uint32_t i = 0; i < vanishing; i++) {
        uint32_t t = s->scratch[merged + i];
        s->triangle_alive[t] = 0;
        if (record) s->vanished[s->vanished_count++] = s->triangle_input[t];
        const uint32_t *corners = s->indices + 3 * (size_t)t;
        for (int k = 0; k < 3; k++) {
            uint32_t o = corners[k];
            if (o == p || o == q) continue;
            remove_from_list(s, o, t);
            if (s->vertices[o].list_count == 0) {
                s->live_vertices--;
                s->stamp[o] = DEAD;
            }
        }
    }
    if (record) record->vanished_count = vanished_here;
    s->live_triangles -= vanished_here;
    s->live_vertices--;
    if (!store_list(s, p, q, merged)) return false;

    /* Merge q into p. */
    if (s->attribute_count) contract_attributes(s, pl);
    for (int k = 0; k < 10; k++) vp->q.m[k] += vq->q.m[k];
    vp->q.weight += vq->q.weight;
    if (s->attribute_quadrics_on) {
        double *ap = s->attribute_quadrics + (size_t)p * s->attribute_stride;
        const double *aq = s->attribute_quadrics + (size_t)q * s->attribute_stride;
        for (size_t k = 0; k < s->attribute_stride; k++) ap[k] += aq[k];
    }
    if (s->frames.count) lk__qem_contract_frames(s, p, q, pl);
    if (s->lost.member_next) {
        s->lost.member_next[s->lost.member_last[p]] = q;
        s->lost.member_last[p] = s->lost.member_last[q];
    }
    s->flags[p] |= s->flags[q] & (FLAG_BORDER | FLAG_NONMANIFOLD);
    vq->parent = p;
    /* A vertex that stays put (locked, or an endpoint placement) keeps its
     * exact float position. */
    if (vp->position[0] != pl->position[0] || vp->position[1] != pl->position[1] ||
        vp->position[2] != pl->position[2]) {
        for (int k = 0; k < 3; k++) vp->position[k] = pl->position[k];
        s->flags[p] |= FLAG_MOVED;
    }
    if (record) {
        output_position(s, p, record->position);
        record->error = (float)(sqrt(pl->error_sq) * s->extent);
    }
    if (pl->error_sq > s->reached_error_sq) s->reached_error_sq = pl->error_sq;

    /* p's quadric changed (queue_edges_around stamps its ring) */
    s->stamp[p] = now;
    s->stamp[q] = DEAD;
    return true;
}

/* After a contraction: fresh entries for every edge around p, and ring
 * stamps for p and its neighbours (their triangles changed). */
static bool queue_edges_around(qem *s, uint32_t p)
{
    next_token(s);
    s->link[p].mark = s->token;
    s->ring_stamp[p] = s->now;
    const uint32_t *list = list_of(s, p);
    uint32_t count = s->vertices[p].list_count;
    bool locked = (s->flags[p] & FLAG_LOCKED) != 0;
    for (uint32_t i = 0; i < count; i++) {
        const uint32_t *corners = s->indices + 3 * (size_t)list[i];
        for (int k = 0; k < 3; k++) {
            uint32_t r = corners[k];
            if (s->link[r].mark == s->token) continue;
            s->link[r].mark = s->token;
            s->ring_stamp[r] = s->now;
            if (locked && (s->flags[r] & FLAG_LOCKED)) continue;
            queue_item item = {p, r, s->now, cost_key(cost_lower_bound(s, p, r))};
            if (!queue_push(s, item)) return false;
        }
    }
    return true;
}

/* ------------------------------------------------------------------------ */
/* Queue set-up (the rest of the set-up: qem_build.c)                       */
/* ------------------------------------------------------------------------ */

/* Evaluates every pair and loads the queue; the initial pair list is
 * freed. A counting sort by bucket lays each bucket's chunks out
 * contiguously, so both the loading and the first pops run through memory
 * in order. */
static lk_status build_queue(qem *s, lk_error *error)
{
    size_t pair_count = s->pair_count;
    s->buckets = lk__malloc_array(BUCKET_COUNT, sizeof(queue_bucket));
    s->bucket_bits = lk__calloc_array(BUCKET_WORDS, sizeof(uint64_t));
    s->summary_bits = lk__calloc_array(SUMMARY_WORDS, sizeof(uint64_t));
    s->parked_capacity = 256;
    s->parked = lk__malloc_array(s->parked_capacity, sizeof(queue_item));
    uint32_t *keys = lk__malloc_array(pair_count, sizeof(uint32_t));
    uint32_t *first_chunk = lk__calloc_array(BUCKET_COUNT, sizeof(uint32_t));
    if (!s->buckets || !s->bucket_bits || !s->summary_bits || !s->parked || !keys || !first_chunk) {
        free(keys), free(first_chunk);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the pair queue (%zu pairs)", pair_count);
    }
    for (uint32_t b = 0; b < BUCKET_COUNT; b++) s->buckets[b].chunk = NONE, s->buckets[b].fill = 0;
    /* keys, and the item count of each bucket in buckets[].fill */
    for (size_t i = 0; i < pair_count; i++) {
        uint32_t a = s->pairs[2 * i], b = s->pairs[2 * i + 1];
        keys[i] = NONE; /* both ends locked: never a candidate */
        if ((s->flags[a] & FLAG_LOCKED) && (s->flags[b] & FLAG_LOCKED)) continue;
        keys[i] = cost_key(cost_lower_bound(s, a, b));
        s->buckets[keys[i] >> s->bucket_shift].fill++;
    }
    /* chunk ranges: a bucket of n items owns ceil(n / CHUNK_ITEMS) chunks;
     * the last is its head (partly filled), each links to the one before */
    size_t chunk_count = 0;
    s->current_bucket = BUCKET_COUNT - 1;
    for (uint32_t b = BUCKET_COUNT; b-- > 0;) {
        queue_bucket *bucket = &s->buckets[b];
        if (bucket->fill == 0) continue;
        first_chunk[b] = (uint32_t)chunk_count;
        chunk_count += (bucket->fill + CHUNK_ITEMS - 1) / CHUNK_ITEMS;
        s->current_bucket = b;
        s->bucket_bits[b >> 6] |= 1ull << (b & 63);
        s->summary_bits[b >> 12] |= 1ull << ((b >> 6) & 63);
        s->queued += bucket->fill;
    }
    s->chunk_capacity = chunk_count + chunk_count / 2 + 64;
    s->chunks = lk__alloc_random_access(s->chunk_capacity, sizeof(queue_chunk), false);
    if (!s->chunks) {
        free(keys), free(first_chunk);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the pair queue (%zu pairs)", pair_count);
    }
    s->chunk_count = chunk_count;
    s->free_chunks = NONE;
    for (uint32_t b = 0; b < BUCKET_COUNT; b++) {
        queue_bucket *bucket = &s->buckets[b];
        if (bucket->fill == 0) continue;
        uint32_t chunks = (bucket->fill + CHUNK_ITEMS - 1) / CHUNK_ITEMS;
        for (uint32_t k = 0; k < chunks; k++) s->chunks[first_chunk[b] + k].next = k ? first_chunk[b] + k - 1 : NONE;
        bucket->chunk = first_chunk[b] + chunks - 1;
        bucket->fill -= (chunks - 1) * CHUNK_ITEMS;
        first_chunk[b] *= CHUNK_ITEMS; /* now the next free item slot */
    }
    for (size_t i = 0; i < pair_count; i++) {
        if (keys[i] == NONE) continue;
        uint32_t slot = first_chunk[keys[i] >> s->bucket_shift]++;
        queued_item item = {s->pairs[2 * i], s->pairs[2 * i + 1], i < s->edge_count ? 0 : PERSISTENT};
        s->chunks[slot / CHUNK_ITEMS].items[slot % CHUNK_ITEMS] = item;
    }
    free(keys);
    free(first_chunk);
    free(s->pairs);
    s->pairs = NULL;
    return LK_OK;
}

/* ------------------------------------------------------------------------ */
/* Main loop                                                                */
/* ------------------------------------------------------------------------ */

/* Appends to a growing list of items (the parked pairs, the pairs waiting
 * for the next round); false when out of memory. */
static bool append_item(queue_item **items, size_t *count, size_t *capacity, queue_item item)
{
    if (*count == *capacity) {
        size_t grown_capacity = *capacity ? 2 * *capacity : 256;
        queue_item *grown = lk__realloc_array(*items, grown_capacity, sizeof *grown);
        if (!grown) return false;
        *items = grown;
        *capacity = grown_capacity;
    }
    (*items)[(*count)++] = item;
    return true;
}

static bool park(qem *s, queue_item item)
{
    item.time = s->now | (item.time & PERSISTENT);
    return append_item(&s->parked, &s->parked_count, &s->parked_capacity, item);
}

/* LK_SIMPLIFY_ROUNDS: a round ends when the cheapest waiting pair's bucket
 * is more than 2 octaves (a cost ratio of 4) below the next pair's; why 4:
 * docs/stream-format.md, "Version 2 rationale". A pair is touched when a
 * contraction of this round re-linked or moved one of its ends. */
#define ROUND_SPAN(s) (2u << (23 - (s)->bucket_shift))
static inline bool touched_this_round(const qem *s, uint32_t v) { return s->ring_stamp[v] > s->round_start; }

static bool wait_for_next_round(qem *s, queue_item item)
{
    uint32_t bucket = item.key >> s->bucket_shift;
    if (s->waiting_count == 0 || bucket < s->waiting_lowest) s->waiting_lowest = bucket;
    return append_item(&s->waiting, &s->waiting_count, &s->waiting_capacity, item);
}

/* Starts the next round: the waiting pairs go back to the queue. */
static bool next_round(qem *s)
{
    for (size_t i = 0; i < s->waiting_count; i++)
        if (!queue_push(s, s->waiting[i])) return false;
    s->waiting_count = 0;
    s->round_start = s->now;
    return true;
}

/* Resolves the live ends of an item; false when the item is obsolete. */
static inline bool item_ends(qem *s, queue_item *item)
{
    if (item->time & PERSISTENT) {
        item->a = representative(s->vertices, item->a);
        item->b = representative(s->vertices, item->b);
        if (item->a == item->b || s->stamp[item->a] == DEAD || s->stamp[item->b] == DEAD) return false;
    } else if (s->stamp[item->a] > item->time || s->stamp[item->b] > item->time) {
        return false; /* a fresher entry exists if the pair is still an edge */
    }
    return !((s->flags[item->a] & FLAG_LOCKED) && (s->flags[item->b] & FLAG_LOCKED));
}

/* Returns parked pairs whose neighbourhood changed to the queue (counted in
 * *released) and drops obsolete ones; false when out of memory. */
static bool release_parked(qem *s, size_t *released)
{
    size_t kept = 0;
    *released = 0;
    for (size_t i = 0; i < s->parked_count; i++) {
        queue_item item = s->parked[i];
        if (!item_ends(s, &item)) continue;
        uint32_t time = item.time & ~PERSISTENT;
        if (s->ring_stamp[item.a] > time || s->ring_stamp[item.b] > time) {
            if (!queue_push(s, item)) return false;
            (*released)++;
        } else {
            s->parked[kept++] = item;
        }
    }
    s->parked_count = kept;
    return true;
}

/* Returns every live parked pair to the queue. */
static bool release_all_parked(qem *s, size_t *released)
{
    *released = 0;
    for (size_t i = 0; i < s->parked_count; i++) {
        queue_item item = s->parked[i];
        if (!item_ends(s, &item)) continue;
        if (!queue_push(s, item)) return false;
        (*released)++;
    }
    s->parked_count = 0;
    return true;
}

lk_status lk__qem_run(qem *s, size_t target_triangles, size_t target_vertices, lk_progress_fn progress,
                      void *progress_user, lk_error *error)
{
    size_t start_triangles = s->live_triangles;
    size_t since_rescan = 0, since_progress = 0, released = 0;
    while (s->live_triangles > target_triangles && s->live_vertices > target_vertices) {
        queue_item item;
        if (s->waiting_count && s->queued == 0) { /* only pairs of the next round are left */
            if (!next_round(s)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            continue;
        }
        if (!queue_pop(s, &item)) {
            if (s->parked_count == 0) break;
            if (!release_parked(s, &released)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            while (released == 0 && s->frames.count && s->frames.allow_folds &&
                   s->frames.fold_stage + 1 < FOLD_STAGE_COUNT) {
                /* Every remaining pair is refused. With several frames that
                 * is mostly the orientation test of some frame: let a few
                 * more frames fold and give every parked pair another
                 * chance. */
                s->frames.fold_stage++;
                s->frames.allowed_folds = (size_t)ceil(FOLD_STAGES[s->frames.fold_stage] * (double)s->frames.count);
                if (!s->frames.folds_from) s->frames.folds_from = s->live_triangles;
                if (!release_all_parked(s, &released)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            }
            if (released == 0) break;
            since_rescan = 0;
            continue;
        }
        prefetch_ahead(s);
        if (!item_ends(s, &item)) continue;
        /* the triangle lists check_contraction reads first, fetched while
         * evaluate computes */
        prefetch(list_of(s, item.a)), prefetch(list_of(s, item.b));
        placement pl;
        pl.frames = s->frames.scratch;
        evaluate(s, item.a, item.b, &pl);
        item.key = cost_key(pl.cost);
        item.time = s->now | (item.time & PERSISTENT);
        if (item.key >> s->bucket_shift > s->current_bucket) {
            /* the key was a lower bound (or, for a non-edge pair, stale) */
            if (!queue_push(s, item)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            continue;
        }
        if (s->rounds && s->waiting_count && (item.key >> s->bucket_shift) > s->waiting_lowest + ROUND_SPAN(s)) {
            if (!queue_push(s, item) || !next_round(s)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            continue;
        }
        if (s->rounds && (touched_this_round(s, item.a) || touched_this_round(s, item.b))) {
            if (!wait_for_next_round(s, item)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            continue;
        }
        bool refused;
        uint32_t merged = 0, vanishing = 0;
        if (pl.error_sq > s->max_error_sq) {
            s->parked_for_error = true;
            refused = true;
        } else {
            if (!ensure_scratch(s, (size_t)s->vertices[pl.kept].list_count + s->vertices[pl.removed].list_count))
                return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            refused = !check_contraction(s, &pl, &merged, &vanishing);
        }
        if (refused) {
            if (!park(s, item)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            continue;
        }
        if (!contract(s, &pl, merged, vanishing) || !queue_edges_around(s, pl.kept))
            return lk_error_set(error, LK_ERR_NOMEM, "cannot grow the QEM working arrays");
        if (++since_rescan >= RESCAN_INTERVAL && since_rescan >= s->parked_count / 8) {
            if (!release_parked(s, &released)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            since_rescan = 0;
        }
        if (progress && ++since_progress >= PROGRESS_INTERVAL) {
            since_progress = 0;
            double span = (double)start_triangles - (double)target_triangles;
            double fraction = span > 0 ? ((double)start_triangles - (double)s->live_triangles) / span : 0;
            if (fraction > 1) fraction = 1;
            if (progress(progress_user, fraction, "simplify")) return lk_error_set(error, LK_ERR_INVALID, "cancelled");
        }
    }
    return LK_OK;
}

/* Compacts the survivors into result->mesh and fills the vertex map. */
static lk_status build_output(qem *s, const lk_mesh *mesh, lk_simplify_result *result, lk_error *error)
{
    size_t v_count = s->vertex_count, t_count = s->triangle_count;
    result->vertex_map = lk__malloc_array(v_count, sizeof(uint32_t));
    uint32_t *internal = lk__malloc_array(v_count, sizeof(uint32_t));  /* input vertex -> internal */
    uint32_t *output_of = lk__malloc_array(v_count, sizeof(uint32_t)); /* internal vertex -> output */
    uint32_t *internal_triangle = lk__malloc_array(t_count, sizeof(uint32_t));
    lk_status status = LK_OK;
    if (!result->vertex_map || !internal || !output_of || !internal_triangle)
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the vertex map");
    size_t out_vertices = 0;
    if (status == LK_OK) {
        for (size_t v = 0; v < v_count; v++) internal[s->vertex_input[v]] = (uint32_t)v;
        for (size_t t = 0; t < t_count; t++) internal_triangle[s->triangle_input[t]] = (uint32_t)t;
        /* survivors numbered in input order */
        for (size_t input = 0; input < v_count; input++) {
            uint32_t v = internal[input];
            const vertex *vv = &s->vertices[v];
            output_of[v] = vv->parent == v && vv->list_count > 0 ? (uint32_t)out_vertices++ : NONE;
        }
        /* merged vertices map to their survivor's output vertex */
        for (size_t input = 0; input < v_count; input++)
            result->vertex_map[input] = output_of[representative(s->vertices, internal[input])];
        unsigned flags = (mesh->normals ? LK_ATTR_NORMALS : 0) | (mesh->texcoords ? LK_ATTR_TEXCOORDS : 0) |
                         (mesh->colors ? LK_ATTR_COLORS : 0);
        status = lk_mesh_alloc(&result->mesh, out_vertices, s->live_triangles, flags, error);
    }
    if (status == LK_OK) {
        lk_mesh *out = &result->mesh;
        unsigned m = s->attribute_count;
        for (size_t v = 0; v < v_count; v++) {
            if (s->vertices[v].parent != v || output_of[v] == NONE) continue;
            size_t o = output_of[v];
            output_position(s, (uint32_t)v, out->positions + 3 * o);
            if (m == 0) continue;
            const float *values = s->attributes + v * m;
            if (out->normals) memcpy(out->normals + 3 * o, values + s->normal_channel, 3 * sizeof(float));
            if (out->texcoords) memcpy(out->texcoords + 2 * o, values + s->texcoord_channel, 2 * sizeof(float));
            if (out->colors) memcpy(out->colors + 4 * o, values + s->color_channel, 4 * sizeof(float));
        }
        /* survivors in input order */
        size_t out_triangles = 0;
        for (size_t input = 0; input < t_count; input++) {
            uint32_t t = internal_triangle[input];
            if (!s->triangle_alive[t]) continue;
            for (int k = 0; k < 3; k++) out->indices[3 * out_triangles + k] = output_of[s->indices[3 * (size_t)t + k]];
            out_triangles++;
        }
    }
    free(internal), free(output_of), free(internal_triangle);
    if (status != LK_OK) return status;
    if (s->record) {
        result->collapse_count = s->collapse_count;
        result->vanished_count = s->vanished_count;
        result->collapses = s->collapses;
        result->vanished = s->vanished;
        s->collapses = NULL;
        s->vanished = NULL;
        /* give back the unused tail of the upper-bound allocations */
        lk_collapse *collapses = lk__realloc_array(result->collapses, result->collapse_count, sizeof(lk_collapse));
        if (collapses) result->collapses = collapses;
        uint32_t *vanished = lk__realloc_array(result->vanished, result->vanished_count, sizeof(uint32_t));
        if (vanished) result->vanished = vanished;
    }
    return LK_OK;
}

lk_status lk__simplify_qem(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                           lk_progress_fn progress, void *progress_user, lk_error *error)
{
    return lk__simplify_qem_pool_limit(mesh, options, POOL_LIMIT, result, progress, progress_user, error);
}

static lk_status simplify_qem(const lk_mesh *mesh, const lk_simplify_options *options, size_t pool_limit,
                              const lk__qem_part *part, lk_simplify_result *result, lk_progress_fn progress,
                              void *progress_user, lk_error *error);

lk_status lk__simplify_qem_pool_limit(const lk_mesh *mesh, const lk_simplify_options *options, size_t pool_limit,
                                      lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                      lk_error *error)
{
    return simplify_qem(mesh, options, pool_limit, NULL, result, progress, progress_user, error);
}

lk_status lk__simplify_qem_part(const lk_mesh *mesh, const lk_simplify_options *options, const lk__qem_part *part,
                                lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                lk_error *error)
{
    return simplify_qem(mesh, options, POOL_LIMIT, part, result, progress, progress_user, error);
}

static lk_status simplify_qem(const lk_mesh *mesh, const lk_simplify_options *options, size_t pool_limit,
                              const lk__qem_part *part, lk_simplify_result *result, lk_progress_fn progress,
                              void *progress_user, lk_error *error)
{
    /* contraction numbers share 32 bits with the PERSISTENT flag */
    if (mesh->vertex_count >= PERSISTENT || mesh->triangle_count > LK_MAX_ELEMENTS / 3)
        return lk_error_set(error, LK_ERR_LIMIT, "mesh too large for QEM simplification (%zu vertices)",
                            mesh->vertex_count);
    qem s;
    memset(&s, 0, sizeof s);
    s.options = options;
    s.part = part;
    s.vertex_count = mesh->vertex_count;
    s.triangle_count = mesh->triangle_count;
    s.pool_limit = pool_limit < POOL_LIMIT ? pool_limit : POOL_LIMIT;
    s.record = (options->flags & LK_SIMPLIFY_RECORD) != 0;
    s.lock_border = (options->flags & LK_SIMPLIFY_LOCK_BORDER) != 0;
    s.endpoints = (options->flags & LK_SIMPLIFY_ENDPOINTS) != 0;
    s.rounds = (options->flags & LK_SIMPLIFY_ROUNDS) != 0;
    s.bucket_shift = s.rounds ? ROUNDS_BUCKET_SHIFT : FINE_BUCKET_SHIFT;
    s.max_error_sq = options->max_error > 0 ? options->max_error * options->max_error : INFINITY;
    float *face_normals = NULL;
    lk__memory_trace("qem: start");
    lk_status status = lk__qem_allocate(&s, error);
    if (status == LK_OK) status = lk__qem_build_lists(&s, mesh, error);
    lk__memory_trace("qem: triangle lists");
    if (status == LK_OK) status = lk__qem_setup_attributes(&s, mesh, error);
    if (status == LK_OK) {
        face_normals = lk__malloc_array(3 * s.triangle_count, sizeof(float));
        if (!face_normals) status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate face normals");
    }
    if (status == LK_OK) {
        lk__qem_add_face_quadrics(&s, face_normals);
        status = lk__qem_build_edges(&s, face_normals, error);
    }
    lk__memory_trace("qem: quadrics and edges");
    free(face_normals);
    if (status == LK_OK && options->pair_distance > 0) status = lk__qem_add_close_pairs(&s, error);
    if (status == LK_OK) status = build_queue(&s, error);
    lk__memory_trace("qem: queue");

    /* Stopping rules: the first one reached wins. */
    size_t target_triangles = 0, target_vertices = options->target_vertices;
    if (options->target_ratio > 0) target_triangles = (size_t)floor(options->target_ratio * (double)s.triangle_count);
    if (options->target_triangles > target_triangles) target_triangles = options->target_triangles;
    bool count_target = options->target_ratio > 0 || options->target_triangles > 0 || options->target_vertices > 0;
    if (status == LK_OK) status = lk__qem_run(&s, target_triangles, target_vertices, progress, progress_user, error);
    lk__memory_trace("qem: contractions");
    /* The output needs the records, triangles and flags only: the queue,
     * the lists and the scratch go first, so that the output's arrays do
     * not add to the peak. */
    free(s.chunks), free(s.pool), free(s.link), free(s.stamp), free(s.ring_stamp);
    s.chunks = NULL, s.pool = NULL, s.link = NULL, s.stamp = NULL, s.ring_stamp = NULL;
    if (status == LK_OK) status = build_output(&s, mesh, result, error);
    lk__memory_trace("qem: output");
    if (status == LK_OK) {
        bool count_reached = s.live_triangles <= target_triangles || s.live_vertices <= target_vertices;
        result->target_reached = count_target ? count_reached || s.parked_for_error : 1;
        result->error = sqrt(s.reached_error_sq) * s.extent;
    }
    lk__qem_free_arrays(&s);
    return status;
}

/* ------------------------------------------------------------------------ */
/* Several frames (lk_animation_simplify, run by src/anim_simplify.c)       */
/* ------------------------------------------------------------------------ */

lk_status lk__qem_frames_start(const lk_mesh *clean, const lk_animation *animation,
                               const lk_anim_simplify_options *options, lk__qem **out, lk_error *error)
{
    *out = NULL;
    /* contraction numbers share 32 bits with the PERSISTENT flag */
    if (clean->vertex_count >= PERSISTENT || clean->triangle_count > LK_MAX_ELEMENTS / 3)
        return lk_error_set(error, LK_ERR_LIMIT, "mesh too large for QEM simplification (%zu vertices)",
                            clean->vertex_count);
    const lk_simplify_options *o = &options->simplify;
    size_t reference = options->scheme == LK_ANIM_SCHEME_FRAME ? options->frame : 0;
    size_t v_count = animation->mesh.vertex_count, frames = animation->frame_count;
    qem *s = calloc(1, sizeof *s);
    if (!s) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the QEM state");
    s->options = o;
    s->vertex_count = clean->vertex_count;
    s->triangle_count = clean->triangle_count;
    s->lock_border = (o->flags & LK_SIMPLIFY_LOCK_BORDER) != 0;
    s->endpoints = (o->flags & LK_SIMPLIFY_ENDPOINTS) != 0;
    s->bucket_shift = FINE_BUCKET_SHIFT;
    s->max_error_sq = o->max_error > 0 ? o->max_error * o->max_error : INFINITY;
    s->frames.count = frames;
    s->frames.scheme = options->scheme;
    s->frames.scheme_frame = options->frame;
    s->frames.reference = reference;
    s->frames.input = animation->frame_positions;
    s->frames.allow_folds = options->allow_folds != 0;
    s->lost.weight = options->lost_surface;
    float *face_normals = NULL;
    lk_status status = lk__qem_allocate(s, error);
    if (status == LK_OK) {
        s->frames.quadrics = lk__calloc_array(v_count * frames, sizeof(quadric));
        s->frames.positions = lk__malloc_array(v_count * frames, 3 * sizeof(double));
        s->frames.output = lk__malloc_array(v_count * frames, 3 * sizeof(float));
        s->frames.scratch = lk__malloc_array(frames, 3 * sizeof(double));
        s->frames.folded = lk__calloc_array(frames, 1);
        face_normals = lk__malloc_array(3 * s->triangle_count, sizeof(float));
        if (!s->frames.quadrics || !s->frames.positions || !s->frames.output || !s->frames.scratch ||
            !s->frames.folded || !face_normals)
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu bytes of per-frame quadrics",
                                  lk__qem_frame_bytes(v_count, frames, s->lost.weight > 0));
    }
    if (status == LK_OK) status = lk__qem_build_lists(s, clean, error);
    if (status == LK_OK) status = lk__qem_setup_attributes(s, clean, error);
    if (status == LK_OK) {
        lk__qem_add_face_quadrics(s, face_normals);
        status = lk__qem_build_edges(s, face_normals, error);
    }
    if (status == LK_OK) status = lk__qem_build_frame_quadrics(s, face_normals, error);
    free(face_normals);
    if (status == LK_OK && s->lost.weight > 0) {
        s->lost.member_next = lk__malloc_array(v_count, sizeof(uint32_t));
        s->lost.member_last = lk__malloc_array(v_count, sizeof(uint32_t));
        s->lost.origin_positions = lk__malloc_array(v_count * frames, 3 * sizeof(double));
        s->lost.origin_weights = lk__malloc_array(v_count * frames, sizeof(double));
        if (!s->lost.member_next || !s->lost.member_last || !s->lost.origin_positions || !s->lost.origin_weights) {
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the lost-surface records");
        } else {
            for (size_t v = 0; v < v_count; v++) s->lost.member_next[v] = NONE, s->lost.member_last[v] = (uint32_t)v;
            memcpy(s->lost.origin_positions, s->frames.positions, v_count * frames * 3 * sizeof(double));
            for (size_t slot = 0; slot < v_count * frames; slot++)
                s->lost.origin_weights[slot] = s->frames.quadrics[slot].weight;
        }
    }
    if (status == LK_OK && o->pair_distance > 0) status = lk__qem_add_close_pairs(s, error);
    if (status == LK_OK) status = build_queue(s, error);
    if (status != LK_OK) {
        lk__qem_free(s);
        return status;
    }
    *out = s;
    return LK_OK;
}

/* The current state as an animation: build_output's mesh and vertex map,
 * plus every frame's positions. */
lk_status lk__qem_animation_output(qem *s, const lk_mesh *mesh, const lk_animation *animation,
                                   lk_anim_simplify_result *result, lk_error *error)
{
    lk_simplify_result flat;
    memset(&flat, 0, sizeof flat);
    lk_status status = build_output(s, mesh, &flat, error);
    if (status != LK_OK) {
        lk_mesh_free(&flat.mesh);
        free(flat.vertex_map);
        return status;
    }
    lk_animation *out = &result->animation;
    out->mesh = flat.mesh;
    result->vertex_map = flat.vertex_map;
    size_t frames = s->frames.count, out_vertices = out->mesh.vertex_count;
    out->frame_count = frames;
    out->frames_per_second = animation->frames_per_second;
    out->frame_positions = lk__malloc_array(frames * out_vertices, 3 * sizeof(float));
    if (!out->frame_positions && frames * out_vertices > 0)
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu frames of %zu vertices", frames, out_vertices);
    for (size_t v = 0; v < s->vertex_count; v++) {
        const vertex *vv = &s->vertices[v];
        if (vv->parent != v || vv->list_count == 0) continue;
        size_t o = result->vertex_map[s->vertex_input[v]];
        for (size_t f = 0; f < frames; f++)
            memcpy(out->frame_positions + 3 * (f * out_vertices + o), s->frames.output + 3 * (v * frames + f),
                   3 * sizeof(float));
    }
    if (out_vertices) memcpy(out->mesh.positions, out->frame_positions, 3 * out_vertices * sizeof(float));
    if (animation->frame_names) {
        out->frame_names = lk__calloc_array(frames, sizeof(char *));
        if (!out->frame_names) return lk_error_set(error, LK_ERR_NOMEM, "cannot copy the frame names");
        for (size_t f = 0; f < frames; f++) {
            const char *name = animation->frame_names[f] ? animation->frame_names[f] : "";
            size_t length = strlen(name);
            out->frame_names[f] = malloc(length + 1);
            if (!out->frame_names[f]) return lk_error_set(error, LK_ERR_NOMEM, "cannot copy the frame names");
            memcpy(out->frame_names[f], name, length + 1);
        }
    }
    return LK_OK;
}

/* For splitting seams after lk__qem_animation_output, whose vertex map is
 * vertex_map: survivor[o] = the input id of the vertex kept as output
 * vertex o, and source_triangle[t] = the input triangle of output triangle t
 * (the output triangles are the live input triangles in input order, as
 * build_output writes them). */
lk_status lk__qem_output_sources(const qem *s, const uint32_t *vertex_map, uint32_t *survivor,
                                 uint32_t *source_triangle, lk_error *error)
{
    uint32_t *internal_triangle = lk__malloc_array(s->triangle_count, sizeof(uint32_t));
    if (!internal_triangle) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam split");
    for (size_t v = 0; v < s->vertex_count; v++) {
        const vertex *vv = &s->vertices[v];
        if (vv->parent == v && vv->list_count > 0) survivor[vertex_map[s->vertex_input[v]]] = s->vertex_input[v];
    }
    for (size_t t = 0; t < s->triangle_count; t++) internal_triangle[s->triangle_input[t]] = (uint32_t)t;
    size_t out_triangles = 0;
    for (size_t input = 0; input < s->triangle_count; input++)
        if (s->triangle_alive[internal_triangle[input]]) source_triangle[out_triangles++] = (uint32_t)input;
    free(internal_triangle);
    return LK_OK;
}

void lk__qem_mark_seams(qem *s, const unsigned char *seam)
{
    for (size_t v = 0; v < s->vertex_count; v++)
        if (seam[s->vertex_input[v]]) s->flags[v] |= FLAG_SEAM;
}

void lk__qem_outcome_of(const qem *s, lk__qem_outcome *out)
{
    out->live_triangles = s->live_triangles;
    out->live_vertices = s->live_vertices;
    out->parked_for_error = s->parked_for_error;
    out->error = sqrt(s->reached_error_sq) * s->extent;
    out->diagonal = s->extent;
    out->folds_from = s->frames.folds_from;
}

void lk__qem_free(qem *s)
{
    if (!s) return;
    lk__qem_free_arrays(s);
    free(s);
}
