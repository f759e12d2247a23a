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
 * quadrics) and a point quadric at corners (three or more such edges).
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
 * key >> BUCKET_SHIFT gives ordered buckets 1/64 of an octave (1.1% of the
 * cost) wide. A bucket is a stack of small chunks and a two-level bitmap
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
 * Several frames (lk_animation_simplify; Cho & Chen, "Constructing scalable
 * 3D animated model by deformation sensitive simplification", 2004). One
 * connectivity, F frames of positions. Every vertex carries one quadric per
 * frame, built from that frame's positions by the same rules (area-weighted
 * face planes, border/non-manifold/crease constraints, corner points); a
 * pair gets one optimal position per frame, solved from that frame's summed
 * quadric exactly as above, and its cost combines the per-frame costs
 * v_i^T (Q_i,a + Q_i,b) v_i: their maximum (the paper's scheme), their mean,
 * or one frame's. A contraction sums every frame's quadrics and moves the
 * kept vertex to each frame's optimum; the orientation test runs in every
 * frame (with allow_folds, once every remaining pair is refused, in the
 * reference frame only: a connectivity that suits all poses runs out near
 * 30% of the triangles on faerie.md2). Vertices that coincide in every
 * frame (texture seams) are merged first unless keep_seams is set, or
 * every seam would be a border. The per-frame data live in separate
 * vertex-major arrays (frame after frame for one vertex, so a pair
 * evaluation reads two contiguous runs); the vertex records hold the
 * reference frame (frame 0, or the chosen frame of the single-frame
 * scheme), which orders vertices in space and finds non-edge pairs. All
 * frames share one normalisation (the bounds of every frame), so per-frame
 * costs are comparable. Queue keys are full evaluations (no cheap bound).
 * Not in the paper, on by default (lost_surface): each frame's cost also
 * counts how far the input vertices merged into the pair end up from the
 * triangles around the merged vertex (lost_surface_cost), which quadrics
 * miss on thin parts; every input vertex keeps its per-frame positions and
 * areas, and each surviving vertex the list of input vertices merged into
 * it.
 * lk_simplify never sets frame_count: its code paths and results are those
 * of the static simplifier, bit for bit. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX

/* A surviving triangle's normal may turn by at most acos(FLIP_COSINE). */
#define FLIP_COSINE 0.2
/* Relative determinant below which A is treated as singular: det(A) <
 * DET_EPSILON * trace(A)^3 (an isotropic A gives 1/27). */
#define DET_EPSILON 1e-6
/* An optimal point farther than this many pair lengths from the pair's
 * midpoint is distrusted in favour of the segment. */
#define FAR_FACTOR 2.0
/* Border and crease constraint planes weigh feature_weight * CONSTRAINT_SCALE
 * * |edge|^2: a face quadric weighs its area (about |edge|^2 / 2), so at 1
 * a constraint would barely outweigh one face; 4 keeps fandisk's creases
 * sharper than its smooth parts at little cost elsewhere. */
#define CONSTRAINT_SCALE 4.0
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
/* Corner point quadric weight, relative to the vertex's area weight. */
#define CORNER_WEIGHT 10.0
/* Non-edge pairs kept per vertex (the nearest ones). */
#define CLOSE_PAIRS_PER_VERTEX 8
/* Contractions between rescans of parked pairs (at least). */
#define RESCAN_INTERVAL 256
/* Contractions between progress reports. */
#define PROGRESS_INTERVAL 4096
/* Largest number of attribute channels (normals 3 + texcoords 2 + colours 4). */
#define MAX_ATTRIBUTES 9

enum { FLAG_BORDER = 1, FLAG_NONMANIFOLD = 2, FLAG_LOCKED = 4 };

/* Symmetric 3x3 A, vector b and constant c of v^T A v + 2 b.v + c, and the
 * face area accumulated into it (to turn costs into RMS distances). */
typedef struct quadric {
    double m[10]; /* A: a00 a01 a02 a11 a12 a22, then b0 b1 b2, then c */
    double weight;
} quadric;

typedef struct vertex {
    quadric q;
    double position[3];     /* normalised coordinates */
    uint32_t parent;        /* itself, or the vertex it was merged into */
    uint32_t list_count;    /* live triangles */
    uint32_t unused[2];     /* pads the record to two cache lines */
} vertex;
_Static_assert(sizeof(vertex) == 128, "a vertex record must fill two cache lines");

/* stamp[v] for vertices without triangles (merged away or isolated). */
#define DEAD UINT32_MAX

/* Scratch of the link-condition test, per vertex (valid when mark == token).
 * 16-bit fields keep the array small enough to stay in cache; contractions
 * of vertices with more than MAX_LINK_DEGREE triangles are refused. */
typedef struct link_counts {
    uint16_t mark;
    uint16_t around_p, around_q, shared; /* triangles with p / with q only / with p and q */
} link_counts;
#define MAX_LINK_DEGREE 30000

typedef struct queue_item {
    uint32_t a, b;
    uint32_t time; /* contraction number when evaluated or parked, | PERSISTENT */
    uint32_t key;  /* bits of the float cost: ordered like the cost */
} queue_item;
#define PERSISTENT 0x80000000u

/* Bucket queue: keys are the bits of the float cost, which order like the
 * cost; bucket = key >> BUCKET_SHIFT spans 1/2^(23 - BUCKET_SHIFT) of an
 * octave. A bucket is a stack of chunks; a two-level bitmap finds the
 * lowest non-empty bucket. Push and pop are O(1) and touch contiguous
 * memory; within a bucket the order is last in, first out. */
#define BUCKET_SHIFT 17
#define BUCKET_COUNT (1u << (31 - BUCKET_SHIFT)) /* the sign bit is never set */
#define BUCKET_WORDS ((BUCKET_COUNT + 63) / 64)
#define SUMMARY_WORDS ((BUCKET_WORDS + 63) / 64)
#define CHUNK_ITEMS 7
typedef struct queue_chunk {
    uint32_t next; /* next chunk of the bucket (full), or of the free list */
    uint32_t unused[3];
    queue_item items[CHUNK_ITEMS];
} queue_chunk;

/* A bucket's first chunk and how many of its items are used (the other
 * chunks are full). The fill lives here, in a small array, so that a push
 * only writes to the chunk: a store miss does not stall. */
typedef struct queue_bucket {
    uint32_t chunk; /* NONE when empty */
    uint32_t fill;
} queue_bucket;

typedef struct placement {
    double position[3];
    double cost;     /* total quadric cost: the priority */
    double error_sq; /* geometric cost / area weight (normalised units^2) */
    uint32_t kept, removed;
    double *frames;  /* several frames: 3 * frame_count positions (one per frame) are
                        written here when not NULL; position is the reference frame's */
} placement;

typedef struct qem {
    const lk_simplify_options *options;
    size_t vertex_count, triangle_count;
    /* Internal ids follow a spatial (Morton) order, so that a neighbourhood
     * sits in a few cache lines and pages; *_input map them back. */
    uint32_t *vertex_input;        /* V: input id of internal vertex */
    uint32_t *triangle_input;      /* T: input id of internal triangle */
    uint32_t *indices;             /* 3T, rewritten as vertices merge */
    unsigned char *triangle_alive; /* T */
    vertex *vertices;              /* V */
    float *output_position;        /* 3V, model units */
    double center[3], extent;      /* model = normalised * extent + center */
    unsigned char *flags;          /* V */
    bool lock_border;
    bool endpoints; /* LK_SIMPLIFY_ENDPOINTS: half-edge collapses */

    /* attributes: attribute_count channels per vertex */
    unsigned attribute_count;
    unsigned normal_channel, texcoord_channel, color_channel; /* NONE when absent */
    float *attributes;             /* V * attribute_count, unscaled values */
    bool attribute_quadrics_on;
    double attribute_scale;        /* attribute_weight * ATTRIBUTE_UNIT */
    size_t attribute_stride;       /* doubles per vertex: 10 + 4m */
    double *attribute_quadrics;    /* V * stride: gg[6] bx[3] c g[3m] bs[m] */

    /* per-vertex triangle lists */
    size_t *list_start;            /* V */
    uint32_t *list_capacity;       /* V */
    uint32_t *pool;
    size_t pool_size, pool_capacity;

    link_counts *link;             /* V */
    uint16_t token;
    uint32_t *stamp;               /* V: contraction that last changed the quadric, or DEAD */
    uint32_t *ring_stamp;          /* V: contraction that last changed a triangle around it */
    uint32_t *scratch;             /* merged triangle list */
    size_t scratch_capacity;
    uint32_t now;                  /* contractions done */

    /* initial pairs */
    size_t pair_count, edge_count;
    uint32_t *pairs;               /* 2 * pair_count */

    /* queue */
    queue_chunk *chunks;
    size_t chunk_count, chunk_capacity;
    uint32_t free_chunks;
    queue_bucket *buckets;         /* BUCKET_COUNT */
    uint64_t *bucket_bits;         /* non-empty buckets */
    uint64_t *summary_bits;        /* non-zero bucket_bits words */
    uint32_t current_bucket;       /* no non-empty bucket below it */
    size_t queued;
    queue_item *parked;
    size_t parked_count, parked_capacity;
    bool parked_for_error;

    size_t live_triangles, live_vertices;

    /* history */
    bool record;
    lk_collapse *collapses;
    size_t collapse_count;
    uint32_t *vanished;
    size_t vanished_count;
    double max_error_sq;           /* normalised units^2 (INFINITY if none) */
    double reached_error_sq;

    /* several frames (lk_animation_simplify); frame_count == 0 when static */
    size_t frame_count;
    lk_anim_scheme scheme;
    size_t scheme_frame;           /* LK_ANIM_SCHEME_FRAME: the frame whose cost counts */
    size_t reference_frame;        /* held in the vertex records */
    const float *input_frames;     /* frame_count * V * 3, input vertex order */
    quadric *frame_quadrics;       /* V * F, vertex-major: [v * F + f] */
    double *frame_positions;       /* V * F * 3, normalised */
    float *frame_output;           /* V * F * 3, model units (exact input floats until moved) */
    double *frame_scratch;         /* F * 3: per-frame positions of the pair being contracted */
    bool allow_folds;              /* lk_anim_simplify_options.allow_folds */
    unsigned fold_stage;           /* index into FOLD_STAGES: 0 = no frame may fold */
    size_t allowed_folds;          /* frames (never the reference) a contraction may fold */
    size_t folded_count;           /* frames folded by the contraction being checked */
    unsigned char *folded;         /* F: marks of those frames */
    size_t folds_from;             /* live triangles when folds were first allowed (0: never) */
    double lost_weight;            /* lost-surface term (0: off), see lost_surface_cost */
    uint32_t *member_next;         /* V: next input vertex merged into the same vertex (NONE ends) */
    uint32_t *member_last;         /* V: last member of a surviving vertex's list */
    double *origin_positions;      /* V * F * 3: every vertex's normalised input positions */
    double *origin_weights;        /* V * F: area around each input vertex in each frame */
} qem;

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
/* Small vector and quadric helpers                                         */
/* ------------------------------------------------------------------------ */

/* Cache misses dominate a contraction: its vertices and triangles are
 * scattered. Requesting a whole neighbourhood up front lets the misses
 * overlap instead of queueing one behind the other. */
static inline void prefetch(const void *address)
{
#if defined(__GNUC__)
    __builtin_prefetch(address);
#else
    (void)address;
#endif
}

static inline void sub3(double out[3], const double a[3], const double b[3])
{
    out[0] = a[0] - b[0], out[1] = a[1] - b[1], out[2] = a[2] - b[2];
}
static inline double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void cross3(double out[3], const double a[3], const double b[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}
static inline double distance_sq3(const double a[3], const double b[3])
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

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

/* v^T A v + 2 b.v + c */
static inline double quadric_value(const double a[6], const double b[3], double c, const double v[3])
{
    double av0 = a[0] * v[0] + a[1] * v[1] + a[2] * v[2];
    double av1 = a[1] * v[0] + a[3] * v[1] + a[4] * v[2];
    double av2 = a[2] * v[0] + a[4] * v[1] + a[5] * v[2];
    return v[0] * (av0 + 2 * b[0]) + v[1] * (av1 + 2 * b[1]) + v[2] * (av2 + 2 * b[2]) + c;
}

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

static inline bool queue_push(qem *s, queue_item item)
{
    uint32_t index = item.key >> BUCKET_SHIFT;
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
    s->chunks[bucket->chunk].items[bucket->fill++] = item;
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

/* Removes an item of the lowest bucket; false when the queue is empty. */
static inline bool queue_pop(qem *s, queue_item *out)
{
    if (s->queued == 0) return false;
    uint32_t index = next_bucket(s, s->current_bucket);
    s->current_bucket = index;
    queue_bucket *bucket = &s->buckets[index];
    queue_chunk *chunk = &s->chunks[bucket->chunk];
    *out = chunk->items[--bucket->fill];
    if (bucket->fill == 1 && chunk->next != NONE) prefetch(&s->chunks[chunk->next].items[CHUNK_ITEMS - 1]);
    if (bucket->fill == 0) {
        uint32_t empty = bucket->chunk;
        bucket->chunk = chunk->next;
        bucket->fill = CHUNK_ITEMS;
        chunk->next = s->free_chunks;
        s->free_chunks = empty;
        if (bucket->chunk == NONE) {
            s->bucket_bits[index >> 6] &= ~(1ull << (index & 63));
            if (!s->bucket_bits[index >> 6]) s->summary_bits[index >> 12] &= ~(1ull << ((index >> 6) & 63));
        }
    }
    s->queued--;
    return true;
}

/* Starts fetching the vertex records of the item the next pop will return,
 * unless it is already visibly obsolete: a contraction takes long enough
 * for them to arrive. */
static inline void prefetch_next(const qem *s)
{
    if (s->queued == 0) return;
    const queue_bucket *bucket = &s->buckets[s->current_bucket];
    if (bucket->chunk == NONE || bucket->fill == 0) return;
    const queue_item *next = &s->chunks[bucket->chunk].items[bucket->fill - 1];
    if (!(next->time & PERSISTENT) && (s->stamp[next->a] > next->time || s->stamp[next->b] > next->time)) return;
    const vertex *a = &s->vertices[next->a], *b = &s->vertices[next->b];
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
static void add_reduced_attributes(const qem *s, uint32_t va, uint32_t vb, double weight, double a[6],
                                   double b[3], double *c)
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

/* Best point of segment pa-pb for the quadric among its minimum, its ends
 * and its midpoint (which wins ties: better-shaped triangles on flat
 * ground). Along the segment, E(pa + t d) = E0 + 2 t g.d + t^2 d.A d with
 * g = A pa + b, so one evaluation of the quadric serves every candidate. */
static void segment_minimum(const double a[6], const double b[3], const double pa[3], const double pb[3],
                            double x[3])
{
    double d[3];
    sub3(d, pb, pa);
    double ad[3] = {a[0] * d[0] + a[1] * d[1] + a[2] * d[2], a[1] * d[0] + a[3] * d[1] + a[4] * d[2],
                    a[2] * d[0] + a[4] * d[1] + a[5] * d[2]};
    double gradient[3] = {a[0] * pa[0] + a[1] * pa[1] + a[2] * pa[2] + b[0],
                          a[1] * pa[0] + a[3] * pa[1] + a[4] * pa[2] + b[1],
                          a[2] * pa[0] + a[4] * pa[1] + a[5] * pa[2] + b[2]};
    double slope = 2 * dot3(gradient, d), curvature = dot3(d, ad);
    double best_t = 0.5, best = 0.5 * slope + 0.25 * curvature;
    if (0 < best) best_t = 0, best = 0;
    if (slope + curvature < best) best_t = 1, best = slope + curvature;
    if (curvature > 0) {
        double t = -0.5 * slope / curvature;
        if (t > 0 && t < 1 && t * slope + t * t * curvature < best) best_t = t;
    }
    x[0] = pa[0] + best_t * d[0];
    x[1] = pa[1] + best_t * d[1];
    x[2] = pa[2] + best_t * d[2];
}

/* The merged vertex's position x for the quadric q (a00 a01 a02 a11 a12
 * a22 b0 b1 b2 c) of pair pa-pb: A x = -b by cofactors, unless A is (nearly)
 * singular relative to its trace (an isotropic A has det = trace^3 / 27) or
 * the optimum lies far away; then the best point of the segment. Returns
 * (x - midpoint).(pb - pa): <= 0 when x is nearer to pa. */
/* Output positions go back to float. A model near FLT_MAX (3.4e38) can
 * have its optimum a little outside the float range (a sphere's optimum
 * lies outside the sphere): clamp rather than write inf. */
static inline float output_float(double value)
{
    if (value > FLT_MAX) return FLT_MAX;
    if (value < -FLT_MAX) return -FLT_MAX;
    return (float)value;
}

static inline double optimal_point(const double *q, const double pa[3], const double pb[3], double x[3])
{
    double a00 = q[0], a01 = q[1], a02 = q[2], a11 = q[3], a12 = q[4], a22 = q[5];
    double b0 = q[6], b1 = q[7], b2 = q[8];
    double ax = pa[0], ay = pa[1], az = pa[2];
    double dx = pb[0] - ax, dy = pb[1] - ay, dz = pb[2] - az;
    double x0 = 0, x1 = 0, x2 = 0;
    double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11;
    double det = a00 * c00 + a01 * c01 + a02 * c02, trace = a00 + a11 + a22;
    bool solved = fabs(det) > DET_EPSILON * trace * trace * trace;
    double mx = ax + 0.5 * dx, my = ay + 0.5 * dy, mz = az + 0.5 * dz;
    double ox = 0, oy = 0, oz = 0;
    if (solved) {
        double c11 = a00 * a22 - a02 * a02, c12 = a01 * a02 - a00 * a12, c22 = a00 * a11 - a01 * a01;
        double scale = -1.0 / det;
        x0 = (c00 * b0 + c01 * b1 + c02 * b2) * scale;
        x1 = (c01 * b0 + c11 * b1 + c12 * b2) * scale;
        x2 = (c02 * b0 + c12 * b1 + c22 * b2) * scale;
        ox = x0 - mx, oy = x1 - my, oz = x2 - mz;
        /* A well-conditioned but far-away optimum (near-parallel planes)
         * drags the surface: the segment is safer then. NaN fails the test
         * too. */
        solved = ox * ox + oy * oy + oz * oz <= FAR_FACTOR * FAR_FACTOR * (dx * dx + dy * dy + dz * dz);
    }
    if (!solved) {
        double segment[3];
        segment_minimum(q, q + 6, pa, pb, segment);
        x0 = segment[0], x1 = segment[1], x2 = segment[2];
        ox = x0 - mx, oy = x1 - my, oz = x2 - mz;
    }
    x[0] = x0, x[1] = x1, x[2] = x2;
    return ox * dx + oy * dy + oz * dz;
}

/* Places the merged vertex of pair (va, vb) for the quadric q = (A, b, c)
 * (q: a00 a01 a02 a11 a12 a22 b0 b1 b2 c) and records its cost. Scalar
 * locals, written out only at the end, let the compiler keep everything in
 * registers. */
static inline void place(const qem *s, uint32_t va, uint32_t vb, const double *q, placement *out)
{
    const double *pa = s->vertices[va].position, *pb = s->vertices[vb].position;
    double a00 = q[0], a01 = q[1], a02 = q[2], a11 = q[3], a12 = q[4], a22 = q[5];
    double b0 = q[6], b1 = q[7], b2 = q[8], c = q[9];
    double x0, x1, x2;
    uint32_t kept;
    if (s->lock_border && ((s->flags[va] | s->flags[vb]) & FLAG_LOCKED)) {
        kept = (s->flags[va] & FLAG_LOCKED) ? va : vb;
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

static inline bool triangle_has(const uint32_t *t, uint32_t v)
{
    return t[0] == v || t[1] == v || t[2] == v;
}

static inline const uint32_t *list_of(const qem *s, uint32_t v)
{
    return s->pool + s->list_start[v];
}

/* Squared distance from point x to triangle (a, b, c). */
static double point_triangle_distance_sq(const double x[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ax[3];
    sub3(ab, b, a), sub3(ac, c, a), sub3(ax, x, a);
    double d1 = dot3(ab, ax), d2 = dot3(ac, ax);
    if (d1 <= 0 && d2 <= 0) return dot3(ax, ax); /* nearest to a */
    double bx[3];
    sub3(bx, x, b);
    double d3 = dot3(ab, bx), d4 = dot3(ac, bx);
    if (d3 >= 0 && d4 <= d3) return dot3(bx, bx); /* nearest to b */
    double cx[3];
    sub3(cx, x, c);
    double d5 = dot3(ab, cx), d6 = dot3(ac, cx);
    if (d6 >= 0 && d5 <= d6) return dot3(cx, cx); /* nearest to c */
    double point[3], u, v;
    double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) { /* on edge ab */
        u = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++) point[k] = a[k] + u * ab[k];
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) { /* on edge ac */
        v = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++) point[k] = a[k] + v * ac[k];
    } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) { /* on edge bc */
        u = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) point[k] = b[k] + u * (c[k] - b[k]);
    } else { /* inside */
        double sum = va + vb + vc;
        if (!(sum > 0)) return dot3(ax, ax); /* degenerate */
        u = vb / sum, v = vc / sum;
        for (int k = 0; k < 3; k++) point[k] = a[k] + u * ab[k] + v * ac[k];
    }
    double d[3];
    sub3(d, x, point);
    return dot3(d, d);
}

#define LOST_FAN_MAX 96

/* The triangles that survive contracting va and vb (those of either end
 * without both), for the lost-surface term; 0 when more than LOST_FAN_MAX
 * (the term then takes the distances to the merged vertex itself, an upper
 * bound). */
static size_t lost_surface_fan(const qem *s, uint32_t va, uint32_t vb, uint32_t fan[LOST_FAN_MAX])
{
    size_t count = 0;
    for (int side = 0; side < 2; side++) {
        uint32_t v = side ? vb : va, other = side ? va : vb;
        const uint32_t *list = list_of(s, v);
        for (uint32_t i = 0; i < s->vertices[v].list_count; i++) {
            const uint32_t *t = s->indices + 3 * (size_t)list[i];
            if (triangle_has(t, other)) continue;
            if (count == LOST_FAN_MAX) return 0;
            fan[count++] = list[i];
        }
    }
    return count;
}

/* Lost surface in frame f: the input vertices merged into va and vb so far,
 * each weighted by its area, times the squared distance from its input
 * position to the triangles around the merged vertex at x. Quadrics measure
 * the merged vertex against the input's planes; this measures the input
 * against the new surface, which quadrics miss on thin parts: once a leg is
 * a few triangles its face planes contain its axis, and moving the foot up
 * into the hip is nearly free for the quadrics while the leg vanishes. */
static double lost_surface_cost(const qem *s, uint32_t va, uint32_t vb, const uint32_t *fan, size_t fan_count,
                                size_t f, const double x[3])
{
    size_t frames = s->frame_count;
    double total = 0;
    for (int side = 0; side < 2; side++) {
        for (uint32_t o = side ? vb : va; o != NONE; o = s->member_next[o]) {
            const double *point = s->origin_positions + 3 * (o * frames + f);
            /* x is a corner of every fan triangle: no farther than it */
            double best = distance_sq3(point, x);
            for (size_t i = 0; i < fan_count && best > 0; i++) {
                const uint32_t *t = s->indices + 3 * (size_t)fan[i];
                const double *corner[3];
                for (int k = 0; k < 3; k++)
                    corner[k] = t[k] == va || t[k] == vb ? x : s->frame_positions + 3 * (t[k] * frames + f);
                double d = point_triangle_distance_sq(point, corner[0], corner[1], corner[2]);
                best = d < best ? d : best;
            }
            total += s->origin_weights[o * frames + f] * best;
        }
    }
    return s->lost_weight * total;
}

/* Several frames: each frame places the merged vertex by its own summed
 * quadric (locked and half-edge placements choose one end for all frames),
 * and the scheme combines the per-frame costs. With out->frames NULL (queue
 * keys) the single-frame scheme looks at its frame only. */
static void evaluate_frames(const qem *s, uint32_t va, uint32_t vb, placement *out)
{
    size_t frames = s->frame_count;
    const quadric *qa = s->frame_quadrics + frames * va, *qb = s->frame_quadrics + frames * vb;
    const double *pa = s->frame_positions + 3 * frames * va, *pb = s->frame_positions + 3 * frames * vb;
    bool one_frame = s->scheme == LK_ANIM_SCHEME_FRAME;
    size_t first = 0, last = frames;
    if (one_frame && !out->frames) first = s->scheme_frame, last = first + 1;
    /* fixed: 0 = every frame keeps va where it is, 1 = vb, -1 = free */
    int fixed = -1;
    if (s->lock_border && ((s->flags[va] | s->flags[vb]) & FLAG_LOCKED)) {
        fixed = (s->flags[va] & FLAG_LOCKED) ? 0 : 1;
    } else if (s->endpoints) {
        double cost_a = 0, cost_b = 0;
        for (size_t f = first; f < last; f++) {
            if (one_frame && f != s->scheme_frame) continue;
            double q[10];
            for (int k = 0; k < 10; k++) q[k] = qa[f].m[k] + qb[f].m[k];
            double ca = quadric_value(q, q + 6, q[9], pa + 3 * f), cb = quadric_value(q, q + 6, q[9], pb + 3 * f);
            if (s->scheme == LK_ANIM_SCHEME_AVG) {
                cost_a += ca, cost_b += cb;
            } else {
                cost_a = ca > cost_a ? ca : cost_a, cost_b = cb > cost_b ? cb : cost_b;
            }
        }
        fixed = cost_a <= cost_b ? 0 : 1;
    }
    uint32_t fan[LOST_FAN_MAX];
    bool lost = s->lost_weight > 0;
    size_t fan_count = lost ? lost_surface_fan(s, va, vb, fan) : 0;
    double cost = 0, error_sq = 0, side = 0;
    for (size_t f = first; f < last; f++) {
        double q[10], x[3];
        for (int k = 0; k < 10; k++) q[k] = qa[f].m[k] + qb[f].m[k];
        if (fixed == 0) {
            memcpy(x, pa + 3 * f, sizeof x);
        } else if (fixed == 1) {
            memcpy(x, pb + 3 * f, sizeof x);
        } else {
            double nearer = optimal_point(q, pa + 3 * f, pb + 3 * f, x);
            if (!one_frame || f == s->scheme_frame) side += nearer;
        }
        if (out->frames) memcpy(out->frames + 3 * f, x, sizeof x);
        if (f == s->reference_frame) memcpy(out->position, x, sizeof x);
        if (one_frame && f != s->scheme_frame) continue;
        double quadric_cost = quadric_value(q, q + 6, q[9], x);
        quadric_cost = quadric_cost > 0 ? quadric_cost : 0; /* NaN too */
        double frame_cost = quadric_cost;
        if (lost) frame_cost += lost_surface_cost(s, va, vb, fan, fan_count, f, x);
        /* the error (max_error, the result's error) stays the quadrics' distance */
        double weight = qa[f].weight + qb[f].weight;
        double frame_error_sq = weight > 0 ? quadric_cost / weight : 0;
        if (s->scheme == LK_ANIM_SCHEME_MAX) {
            cost = frame_cost > cost ? frame_cost : cost;
            error_sq = frame_error_sq > error_sq ? frame_error_sq : error_sq;
        } else {
            cost += frame_cost, error_sq += frame_error_sq;
        }
    }
    if (s->scheme == LK_ANIM_SCHEME_AVG) cost /= (double)frames, error_sq /= (double)frames;
    out->kept = fixed == 0 ? va : fixed == 1 ? vb : side <= 0 ? va : vb;
    out->removed = out->kept == va ? vb : va;
    out->cost = cost;
    out->error_sq = error_sq;
}

/* Cost and placement of contracting va and vb. */
static inline void evaluate(const qem *s, uint32_t va, uint32_t vb, placement *out)
{
    if (s->frame_count) {
        evaluate_frames(s, va, vb, out);
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
    if (!s->attribute_quadrics_on && !s->frame_count) {
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

/* False when moving corner p0 of triangle (p0, p1, p2) to x turns its normal
 * by more than acos(FLIP_COSINE) or makes it zero-area. */
static inline bool corner_move_keeps_orientation(const double p0[3], const double p1[3], const double p2[3],
                                                 const double x[3])
{
    double e1[3], e2[3], f1[3], f2[3], before[3], after[3];
    sub3(e1, p1, p0);
    sub3(e2, p2, p0);
    sub3(f1, p1, x);
    sub3(f2, p2, x);
    cross3(before, e1, e2);
    cross3(after, f1, f2);
    double before_sq = dot3(before, before);
    if (before_sq == 0) return true; /* already flat: any shape is no worse */
    double d = dot3(before, after);
    return d > 0 && d * d >= FLIP_COSINE * FLIP_COSINE * before_sq * dot3(after, after);
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

/* The same test in every frame, with each frame's new position; frames
 * other than the reference may fold while the contraction's count of
 * folded frames stays within allowed_folds. */
static bool keeps_orientation_everywhere(qem *s, const uint32_t *t, uint32_t moved, const placement *pl)
{
    if (!s->frame_count) return keeps_orientation(s, t, moved, pl->position);
    if (!keeps_orientation(s, t, moved, pl->position)) return false; /* the reference frame */
    size_t frames = s->frame_count;
    if (s->allowed_folds >= frames - 1) return true;
    int k = t[0] == moved ? 0 : t[1] == moved ? 1 : 2;
    const double *r0 = s->frame_positions + 3 * frames * t[k];
    const double *r1 = s->frame_positions + 3 * frames * t[k == 2 ? 0 : k + 1];
    const double *r2 = s->frame_positions + 3 * frames * t[k == 0 ? 2 : k - 1];
    for (size_t f = 0; f < frames; f++) {
        if (f == s->reference_frame || s->folded[f]) continue;
        if (corner_move_keeps_orientation(r0 + 3 * f, r1 + 3 * f, r2 + 3 * f, pl->frames + 3 * f)) continue;
        if (s->folded_count == s->allowed_folds) return false;
        s->folded[f] = 1;
        s->folded_count++;
    }
    return true;
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
    if (s->frame_count && s->folded_count) {
        memset(s->folded, 0, s->frame_count);
        s->folded_count = 0;
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
            for (int k = 0; k < 3; k++) prefetch(&s->list_start[t[k]]); /* the opposite vertex loses t */
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
        if (s->link[others[0]].around_p && s->link[others[1]].around_p &&
            has_triangle_with(s, p, others[0], others[1]))
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

/* Places p's new list (held in scratch) into p's block, q's block or a new
 * block at the end of the pool. */
static bool store_list(qem *s, uint32_t p, uint32_t q, uint32_t count)
{
    if (count > s->list_capacity[p]) {
        if (count <= s->list_capacity[q]) {
            s->list_start[p] = s->list_start[q];
            s->list_capacity[p] = s->list_capacity[q];
        } else {
            uint32_t capacity = count + count / 2;
            if (s->pool_size + capacity > s->pool_capacity) {
                size_t grown_capacity = (s->pool_size + capacity) * 3 / 2;
                uint32_t *grown = lk__realloc_array(s->pool, grown_capacity, sizeof *grown);
                if (!grown) return false;
                s->pool = grown;
                s->pool_capacity = grown_capacity;
            }
            s->list_start[p] = s->pool_size;
            s->list_capacity[p] = capacity;
            s->pool_size += capacity;
        }
    }
    s->list_capacity[q] = 0;
    s->vertices[q].list_count = 0;
    memcpy(s->pool + s->list_start[p], s->scratch, count * sizeof(uint32_t));
    s->vertices[p].list_count = count;
    return true;
}

static void remove_from_list(qem *s, uint32_t v, uint32_t triangle)
{
    uint32_t *list = s->pool + s->list_start[v];
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

/* Several frames: p takes q's quadrics and each frame's position. A frame
 * where p stays put keeps its exact float position. */
static void contract_frames(qem *s, uint32_t p, uint32_t q, const placement *pl)
{
    size_t frames = s->frame_count;
    quadric *qp = s->frame_quadrics + frames * p;
    const quadric *qq = s->frame_quadrics + frames * q;
    double *position = s->frame_positions + 3 * frames * p;
    float *output = s->frame_output + 3 * frames * p;
    for (size_t f = 0; f < frames; f++) {
        for (int k = 0; k < 10; k++) qp[f].m[k] += qq[f].m[k];
        qp[f].weight += qq[f].weight;
        const double *x = pl->frames + 3 * f;
        double *old = position + 3 * f;
        if (old[0] == x[0] && old[1] == x[1] && old[2] == x[2]) continue;
        for (int k = 0; k < 3; k++) {
            old[k] = x[k];
            output[3 * f + k] = output_float(x[k] * s->extent + s->center[k]);
        }
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
        for (int k = 0; k < 3; k++) prefetch(s->pool + s->list_start[corners[k]]);
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
    if (s->frame_count) contract_frames(s, p, q, pl);
    if (s->member_next) {
        s->member_next[s->member_last[p]] = q;
        s->member_last[p] = s->member_last[q];
    }
    s->flags[p] |= s->flags[q] & (FLAG_BORDER | FLAG_NONMANIFOLD);
    vq->parent = p;
    float *output = s->output_position + 3 * (size_t)p;
    /* A vertex that stays put (locked, or an endpoint placement) keeps its
     * exact float position. */
    if (vp->position[0] != pl->position[0] || vp->position[1] != pl->position[1] ||
        vp->position[2] != pl->position[2])
        for (int k = 0; k < 3; k++) {
            vp->position[k] = pl->position[k];
            output[k] = output_float(pl->position[k] * s->extent + s->center[k]);
        }
    if (record) {
        memcpy(record->position, output, sizeof record->position);
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
    bool locked = s->lock_border && (s->flags[p] & FLAG_LOCKED);
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
/* Set-up                                                                   */
/* ------------------------------------------------------------------------ */

static void qem_free(qem *s)
{
    free(s->vertex_input);
    free(s->triangle_input);
    free(s->indices);
    free(s->triangle_alive);
    free(s->vertices);
    free(s->output_position);
    free(s->flags);
    free(s->attributes);
    free(s->attribute_quadrics);
    free(s->list_start);
    free(s->list_capacity);
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
    free(s->collapses);
    free(s->vanished);
    free(s->frame_quadrics);
    free(s->frame_positions);
    free(s->frame_output);
    free(s->frame_scratch);
    free(s->folded);
    free(s->member_next);
    free(s->member_last);
    free(s->origin_positions);
    free(s->origin_weights);
}

static lk_status allocate(qem *s, lk_error *error)
{
    size_t v = s->vertex_count, t = s->triangle_count;
    s->indices = lk__malloc_array(3 * t, sizeof(uint32_t));
    s->vertex_input = lk__malloc_array(v, sizeof(uint32_t));
    s->triangle_input = lk__malloc_array(t, sizeof(uint32_t));
    s->triangle_alive = lk__malloc_array(t, 1);
    /* records aligned to cache lines: one record, two lines */
    if (v < SIZE_MAX / sizeof(vertex) - 1) {
        s->vertices = aligned_alloc(64, (v + 1) * sizeof(vertex));
        if (s->vertices) memset(s->vertices, 0, (v + 1) * sizeof(vertex));
    }
    s->output_position = lk__malloc_array(3 * v, sizeof(float));
    s->flags = lk__calloc_array(v, 1);
    s->list_start = lk__malloc_array(v, sizeof(size_t));
    s->list_capacity = lk__malloc_array(v, sizeof(uint32_t));
    s->pool_capacity = 3 * t + 3 * t / 2 + 16;
    s->pool = lk__malloc_array(s->pool_capacity, sizeof(uint32_t));
    s->link = lk__calloc_array(v, sizeof(link_counts));
    s->stamp = lk__calloc_array(v, sizeof(uint32_t));
    s->ring_stamp = lk__calloc_array(v, sizeof(uint32_t));
    if (!s->indices || !s->vertex_input || !s->triangle_input || !s->triangle_alive || !s->vertices || !s->output_position || !s->flags || !s->list_start ||
        !s->list_capacity || !s->pool || !s->link || !s->stamp || !s->ring_stamp)
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate QEM working arrays for %zu vertices", v);
    if (s->record) {
        s->collapses = lk__malloc_array(v, sizeof(lk_collapse));
        s->vanished = lk__malloc_array(t, sizeof(uint32_t));
        if (!s->collapses || !s->vanished)
            return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the contraction history");
    }
    return LK_OK;
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
    size_t count = s->frame_count * s->vertex_count;
    for (size_t i = 0; i < count; i++) {
        const float *p = s->input_frames + 3 * i;
        for (int k = 0; k < 3; k++) {
            if (p[k] < min[k]) min[k] = p[k];
            if (p[k] > max[k]) max[k] = p[k];
        }
    }
}

/* Normalised positions in internal order, vertex triangle lists, live
 * counts. */
static lk_status build_lists(qem *s, const lk_mesh *mesh, lk_error *error)
{
    size_t v_count = s->vertex_count, t_count = s->triangle_count;
    float min[3], max[3];
    lk_mesh_bounds(mesh, min, max);
    if (s->frame_count) frame_bounds(s, min, max);
    for (int k = 0; k < 3; k++) s->center[k] = 0.5 * ((double)min[k] + (double)max[k]);
    double dx = (double)max[0] - min[0], dy = (double)max[1] - min[1], dz = (double)max[2] - min[2];
    double diagonal = sqrt(dx * dx + dy * dy + dz * dz);
    s->extent = diagonal > 0 ? diagonal : 1;
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
    for (size_t v = 0; v < v_count; v++) {
        vertex *vv = &s->vertices[v];
        const float *input = mesh->positions + 3 * (size_t)s->vertex_input[v];
        for (int k = 0; k < 3; k++) vv->position[k] = ((double)input[k] - s->center[k]) * inverse;
        memcpy(s->output_position + 3 * v, input, 3 * sizeof(float));
        vv->parent = (uint32_t)v;
    }
    memset(s->triangle_alive, 1, t_count);
    /* degrees and fill cursors in the small arrays list_capacity and
     * ring_stamp (zero until the contractions start) */
    memset(s->list_capacity, 0, v_count * sizeof(uint32_t));
    for (size_t c = 0; c < 3 * t_count; c++) s->list_capacity[s->indices[c]]++;
    size_t start = 0;
    s->live_vertices = 0;
    for (size_t v = 0; v < v_count; v++) {
        uint32_t degree = s->list_capacity[v];
        s->list_start[v] = start;
        s->vertices[v].list_count = degree;
        start += degree;
        s->live_vertices += degree > 0;
        s->stamp[v] = degree > 0 ? 0 : DEAD;
    }
    s->pool_size = start;
    for (size_t t = 0; t < t_count; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t v = s->indices[3 * t + k];
            s->pool[s->list_start[v] + s->ring_stamp[v]++] = (uint32_t)t;
        }
    memset(s->ring_stamp, 0, v_count * sizeof(uint32_t));
    s->live_triangles = t_count;
    return LK_OK;
}

/* Face quadrics (and attribute quadrics); fills unit face normals. */
static void add_face_quadrics(qem *s, float *face_normals)
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
        double face[10] = {an[0] * n[0], an[0] * n[1], an[0] * n[2], an[1] * n[1], an[1] * n[2], an[2] * n[2],
                           an[0] * d,    an[1] * d,    an[2] * d,    area * d * d};
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

/* Border, non-manifold and crease constraints of one edge (a, b) used by
 * `uses` triangles, the first two of which are `faces`; counts the feature
 * edges at each end (for corners). Shared by the one-frame and the
 * per-frame quadrics so both apply the same rules. */
static void add_edge_constraints(qem *s, uint32_t a, uint32_t b, uint32_t uses, const uint32_t *faces,
                                 const float *face_normals, bool features, double crease_cosine, double weight,
                                 unsigned char *feature_edges)
{
    bool feature = false;
    if (uses == 1) {
        add_edge_constraint(s, a, b, face_normals + 3 * (size_t)faces[0], weight);
        feature = true;
    } else if (uses >= 3) {
        add_edge_constraint(s, a, b, face_normals + 3 * (size_t)faces[0], weight);
        add_edge_constraint(s, a, b, face_normals + 3 * (size_t)faces[1], weight);
        feature = true;
    } else if (features) {
        const float *n0 = face_normals + 3 * (size_t)faces[0], *n1 = face_normals + 3 * (size_t)faces[1];
        double cosine = (double)n0[0] * n1[0] + (double)n0[1] * n1[1] + (double)n0[2] * n1[2];
        if (cosine < crease_cosine) {
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
static lk_status build_edges(qem *s, const float *face_normals, lk_error *error)
{
    size_t v_count = s->vertex_count;
    bool features = !(s->options->flags & LK_SIMPLIFY_NO_FEATURES);
    double weight = s->options->feature_weight * CONSTRAINT_SCALE;
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
            if (uses == 1) s->flags[a] |= FLAG_BORDER, s->flags[b] |= FLAG_BORDER;
            else if (uses >= 3) s->flags[a] |= FLAG_NONMANIFOLD, s->flags[b] |= FLAG_NONMANIFOLD;
            add_edge_constraints(s, a, b, uses, faces, face_normals, features, crease_cosine, weight, feature_edges);
        }
    }
    for (size_t v = 0; v < v_count; v++) {
        if (s->lock_border && (s->flags[v] & FLAG_BORDER)) s->flags[v] |= FLAG_LOCKED;
        if (features && feature_edges[v] >= 3) {
            vertex *corner = &s->vertices[v];
            quadric_add_point(&corner->q, corner->position, CORNER_WEIGHT * weight * corner->q.weight);
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
static lk_status build_frame_quadrics(qem *s, float *face_normals, lk_error *error)
{
    size_t v_count = s->vertex_count, frames = s->frame_count, edge_count = s->edge_count;
    bool features = !(s->options->flags & LK_SIMPLIFY_NO_FEATURES);
    double weight = s->options->feature_weight * CONSTRAINT_SCALE;
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
            const float *input = s->input_frames + 3 * (f * v_count + s->vertex_input[v]);
            for (int k = 0; k < 3; k++) vv->position[k] = ((double)input[k] - s->center[k]) * inverse;
            memset(&vv->q, 0, sizeof vv->q);
        }
        add_face_quadrics(s, face_normals);
        memset(feature_edges, 0, v_count);
        for (size_t e = 0; e < edge_count; e++) {
            uint32_t a = s->pairs[2 * e], b = s->pairs[2 * e + 1], uses = edge_uses[e];
            const uint32_t *faces = edge_faces + 2 * e;
            add_edge_constraints(s, a, b, uses, faces, face_normals, features, crease_cosine, weight, feature_edges);
        }
        for (size_t v = 0; v < v_count; v++) {
            vertex *vv = &s->vertices[v];
            if (features && feature_edges[v] >= 3)
                quadric_add_point(&vv->q, vv->position, CORNER_WEIGHT * weight * vv->q.weight);
            size_t slot = v * frames + f;
            s->frame_quadrics[slot] = vv->q;
            memcpy(s->frame_positions + 3 * slot, vv->position, sizeof vv->position);
            memcpy(s->frame_output + 3 * slot, s->input_frames + 3 * (f * v_count + s->vertex_input[v]),
                   3 * sizeof(float));
        }
    }
    size_t reference = s->reference_frame;
    for (size_t v = 0; v < v_count; v++) {
        size_t slot = v * frames + reference;
        s->vertices[v].q = s->frame_quadrics[slot];
        memcpy(s->vertices[v].position, s->frame_positions + 3 * slot, sizeof s->vertices[v].position);
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
static lk_status add_close_pairs(qem *s, lk_error *error)
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

/* Sets up the attribute channels present in the mesh. */
static lk_status setup_attributes(qem *s, const lk_mesh *mesh, lk_error *error)
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
        if (s->lock_border && (s->flags[a] & FLAG_LOCKED) && (s->flags[b] & FLAG_LOCKED)) continue;
        keys[i] = cost_key(cost_lower_bound(s, a, b));
        s->buckets[keys[i] >> BUCKET_SHIFT].fill++;
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
    s->chunks = lk__malloc_array(s->chunk_capacity, sizeof(queue_chunk));
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
        uint32_t slot = first_chunk[keys[i] >> BUCKET_SHIFT]++;
        queue_item item = {s->pairs[2 * i], s->pairs[2 * i + 1], i < s->edge_count ? 0 : PERSISTENT, keys[i]};
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

static bool park(qem *s, queue_item item)
{
    if (s->parked_count == s->parked_capacity) {
        size_t capacity = s->parked_capacity * 2;
        queue_item *grown = lk__realloc_array(s->parked, capacity, sizeof *grown);
        if (!grown) return false;
        s->parked = grown;
        s->parked_capacity = capacity;
    }
    item.time = s->now | (item.time & PERSISTENT);
    s->parked[s->parked_count++] = item;
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
    return !(s->lock_border && (s->flags[item->a] & FLAG_LOCKED) && (s->flags[item->b] & FLAG_LOCKED));
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

static lk_status run(qem *s, size_t target_triangles, size_t target_vertices, lk_progress_fn progress,
                     void *progress_user, lk_error *error)
{
    size_t start_triangles = s->live_triangles;
    size_t since_rescan = 0, since_progress = 0, released = 0;
    while (s->live_triangles > target_triangles && s->live_vertices > target_vertices) {
        queue_item item;
        if (!queue_pop(s, &item)) {
            if (s->parked_count == 0) break;
            if (!release_parked(s, &released)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            while (released == 0 && s->frame_count && s->allow_folds && s->fold_stage + 1 < FOLD_STAGE_COUNT) {
                /* Every remaining pair is refused. With several frames that
                 * is mostly the orientation test of some frame: let a few
                 * more frames fold and give every parked pair another
                 * chance. */
                s->fold_stage++;
                s->allowed_folds = (size_t)ceil(FOLD_STAGES[s->fold_stage] * (double)s->frame_count);
                if (!s->folds_from) s->folds_from = s->live_triangles;
                if (!release_all_parked(s, &released)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
            }
            if (released == 0) break;
            since_rescan = 0;
            continue;
        }
        if (!item_ends(s, &item)) continue;
        prefetch_next(s);
        placement pl;
        pl.frames = s->frame_scratch;
        evaluate(s, item.a, item.b, &pl);
        item.key = cost_key(pl.cost);
        item.time = s->now | (item.time & PERSISTENT);
        if (item.key >> BUCKET_SHIFT > s->current_bucket) {
            /* the key was a lower bound (or, for a non-edge pair, stale) */
            if (!queue_push(s, item)) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
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
            if (progress(progress_user, fraction, "simplify"))
                return lk_error_set(error, LK_ERR_INVALID, "cancelled");
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
            memcpy(out->positions + 3 * o, s->output_position + 3 * v, 3 * sizeof(float));
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
    /* contraction numbers share 32 bits with the PERSISTENT flag */
    if (mesh->vertex_count >= PERSISTENT || mesh->triangle_count > LK_MAX_ELEMENTS / 3)
        return lk_error_set(error, LK_ERR_LIMIT, "mesh too large for QEM simplification (%zu vertices)",
                            mesh->vertex_count);
    qem s;
    memset(&s, 0, sizeof s);
    s.options = options;
    s.vertex_count = mesh->vertex_count;
    s.triangle_count = mesh->triangle_count;
    s.record = (options->flags & LK_SIMPLIFY_RECORD) != 0;
    s.lock_border = (options->flags & LK_SIMPLIFY_LOCK_BORDER) != 0;
    s.endpoints = (options->flags & LK_SIMPLIFY_ENDPOINTS) != 0;
    s.max_error_sq = options->max_error > 0 ? options->max_error * options->max_error : INFINITY;
    float *face_normals = NULL;
    lk_status status = allocate(&s, error);
    if (status == LK_OK) status = build_lists(&s, mesh, error);
    if (status == LK_OK) status = setup_attributes(&s, mesh, error);
    if (status == LK_OK) {
        face_normals = lk__malloc_array(3 * s.triangle_count, sizeof(float));
        if (!face_normals) status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate face normals");
    }
    if (status == LK_OK) {
        add_face_quadrics(&s, face_normals);
        status = build_edges(&s, face_normals, error);
    }
    free(face_normals);
    if (status == LK_OK && options->pair_distance > 0) status = add_close_pairs(&s, error);
    if (status == LK_OK) status = build_queue(&s, error);

    /* Stopping rules: the first one reached wins. */
    size_t target_triangles = 0, target_vertices = options->target_vertices;
    if (options->target_ratio > 0) target_triangles = (size_t)floor(options->target_ratio * (double)s.triangle_count);
    if (options->target_triangles > target_triangles) target_triangles = options->target_triangles;
    bool count_target = options->target_ratio > 0 || options->target_triangles > 0 || options->target_vertices > 0;
    if (status == LK_OK) status = run(&s, target_triangles, target_vertices, progress, progress_user, error);
    if (status == LK_OK) status = build_output(&s, mesh, result, error);
    if (status == LK_OK) {
        bool count_reached = s.live_triangles <= target_triangles || s.live_vertices <= target_vertices;
        result->target_reached = count_target ? count_reached || s.parked_for_error : 1;
        result->error = sqrt(s.reached_error_sq) * s.extent;
    }
    qem_free(&s);
    return status;
}

/* ------------------------------------------------------------------------ */
/* Several frames (lk_animation_simplify)                                   */
/* ------------------------------------------------------------------------ */

/* Bytes of per-frame data for V vertices and F frames (SIZE_MAX on overflow);
 * the lost-surface term adds every input position and area per frame and
 * the member lists. */
static size_t frame_bytes(size_t vertex_count, size_t frame_count, bool lost_surface)
{
    size_t per_slot = sizeof(quadric) + 3 * sizeof(double) + 3 * sizeof(float);
    if (lost_surface) per_slot += 4 * sizeof(double);
    if (frame_count && vertex_count > SIZE_MAX / frame_count) return SIZE_MAX;
    size_t slots = vertex_count * frame_count;
    size_t fixed = 3 * sizeof(double) * frame_count + (lost_surface ? 2 * sizeof(uint32_t) * vertex_count : 0);
    if (slots > (SIZE_MAX - fixed) / per_slot) return SIZE_MAX;
    return slots * per_slot + fixed;
}

static lk_status check_animation(const lk_animation *animation, const lk_anim_simplify_options *options,
                                 lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "no animation given");
    if (animation->frame_count == 0 || !animation->frame_positions)
        return lk_error_set(error, LK_ERR_INVALID, "the animation has no frames");
    lk_status status = lk_mesh_validate(&animation->mesh, error);
    if (status != LK_OK) return status;
    if (animation->mesh.triangle_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "cannot simplify an animation without triangles");
    size_t v_count = animation->mesh.vertex_count;
    if (v_count > SIZE_MAX / 3 / animation->frame_count)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu frames of %zu vertices are too many", animation->frame_count,
                            v_count);
    size_t floats = 3 * v_count * animation->frame_count;
    for (size_t i = 0; i < floats; i++)
        if (!isfinite(animation->frame_positions[i]))
            return lk_error_set(error, LK_ERR_RANGE, "frame %zu, vertex %zu: position is not finite", i / 3 / v_count,
                                i / 3 % v_count);
    const lk_simplify_options *o = &options->simplify;
    if (options->scheme != LK_ANIM_SCHEME_MAX && options->scheme != LK_ANIM_SCHEME_AVG &&
        options->scheme != LK_ANIM_SCHEME_FRAME)
        return lk_error_set(error, LK_ERR_INVALID, "unknown scheme %d", (int)options->scheme);
    if (options->scheme == LK_ANIM_SCHEME_FRAME && options->frame >= animation->frame_count)
        return lk_error_set(error, LK_ERR_RANGE, "frame %zu does not exist (the animation has %zu frames)",
                            options->frame, animation->frame_count);
    if (o->flags & (LK_SIMPLIFY_ATTRIBUTES | LK_SIMPLIFY_RECORD))
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "attribute quadrics and contraction histories are not available for animations");
    if (!(o->target_ratio >= 0 && o->target_ratio <= 1))
        return lk_error_set(error, LK_ERR_INVALID, "target ratio must be in (0, 1], got %g", o->target_ratio);
    if (!(o->max_error >= 0) || !isfinite(o->max_error))
        return lk_error_set(error, LK_ERR_INVALID, "max error must be a finite number >= 0");
    if (!(o->pair_distance >= 0) || !isfinite(o->pair_distance))
        return lk_error_set(error, LK_ERR_INVALID, "pair distance must be a finite number >= 0");
    if (!(o->feature_angle >= 0 && o->feature_angle <= 180))
        return lk_error_set(error, LK_ERR_INVALID, "feature angle must be in [0, 180] degrees");
    if (!(o->feature_weight >= 0) || !isfinite(o->feature_weight))
        return lk_error_set(error, LK_ERR_INVALID, "weights must be finite numbers >= 0");
    if (!(options->lost_surface >= 0) || !isfinite(options->lost_surface))
        return lk_error_set(error, LK_ERR_INVALID, "the lost-surface weight must be a finite number >= 0, got %g",
                            options->lost_surface);
    size_t limit = options->max_bytes ? options->max_bytes : (size_t)2 << 30;
    size_t needed = frame_bytes(v_count, animation->frame_count, options->lost_surface > 0);
    if (needed > limit)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%zu frames of %zu vertices need %zu bytes of per-frame quadrics, more than the limit %zu",
                            animation->frame_count, v_count, needed, limit);
    return LK_OK;
}

typedef struct weld_key {
    uint64_t hash;
    uint32_t vertex;
} weld_key;

static int compare_weld_keys(const void *a, const void *b)
{
    const weld_key *x = a, *y = b;
    if (x->hash != y->hash) return x->hash < y->hash ? -1 : 1;
    return x->vertex < y->vertex ? -1 : x->vertex > y->vertex;
}

/* representative[v]: the first vertex whose positions equal v's in every
 * frame (texture seams split such vertices; the QEM must see them as one,
 * or every seam becomes a border that pins the simplification). Returns
 * the number of vertices merged, or SIZE_MAX when out of memory. */
static size_t weld_frames(const lk_animation *animation, uint32_t *representative)
{
    size_t v_count = animation->mesh.vertex_count, frames = animation->frame_count;
    weld_key *keys = lk__malloc_array(v_count, sizeof(weld_key));
    if (!keys) return SIZE_MAX;
    for (size_t v = 0; v < v_count; v++) {
        uint64_t hash = 0x9E3779B97F4A7C15ull;
        for (size_t f = 0; f < frames; f++) {
            const float *p = animation->frame_positions + 3 * (f * v_count + v);
            for (int k = 0; k < 3; k++) {
                float value = p[k] == 0 ? 0.0f : p[k]; /* -0 equals 0 */
                uint32_t bits;
                memcpy(&bits, &value, sizeof bits);
                hash = lk__mix64(hash ^ bits);
            }
        }
        keys[v].hash = hash, keys[v].vertex = (uint32_t)v;
        representative[v] = (uint32_t)v;
    }
    qsort(keys, v_count, sizeof *keys, compare_weld_keys);
    size_t merged = 0;
    for (size_t i = 0; i < v_count;) {
        size_t end = i + 1;
        while (end < v_count && keys[end].hash == keys[i].hash) end++;
        /* within a run of equal hashes (sorted by vertex), compare for real */
        for (size_t j = i + 1; j < end; j++) {
            uint32_t v = keys[j].vertex;
            for (size_t k = i; k < j; k++) {
                uint32_t u = keys[k].vertex;
                if (representative[u] != u) continue;
                bool same = true;
                for (size_t f = 0; f < frames && same; f++) {
                    const float *pu = animation->frame_positions + 3 * (f * v_count + u);
                    const float *pv = animation->frame_positions + 3 * (f * v_count + v);
                    same = pu[0] == pv[0] && pu[1] == pv[1] && pu[2] == pv[2];
                }
                if (same) {
                    representative[v] = u;
                    merged++;
                    break;
                }
            }
        }
        i = end;
    }
    free(keys);
    return merged;
}

/* Texture seams, for splitting welded vertices again on output. */
typedef struct seam_table {
    uint32_t *chart;        /* V: connected component of the input (split) mesh using each vertex */
    uint32_t *copy_start;   /* V + 1: the vertices welded into r are copies[copy_start[r] ..
                               copy_start[r + 1]) */
    uint32_t *copies;       /* V */
    uint32_t *clean_source; /* clean triangle -> input triangle */
} seam_table;

static void seam_table_free(seam_table *table)
{
    free(table->chart), free(table->copy_start), free(table->copies), free(table->clean_source);
    memset(table, 0, sizeof *table);
}

/* Charts, copies and the input triangle of every clean triangle. The
 * clean mesh keeps the input's triangle order and drops only degenerate
 * and duplicate triangles, so a single merge walk pairs them: a dropped
 * triangle never equals the next kept one (it would be a duplicate of an
 * earlier kept triangle, and so would that one). */
static lk_status build_seam_table(const lk_animation *animation, const uint32_t *representative,
                                  const lk_mesh *clean, seam_table *table, lk_error *error)
{
    const lk_mesh *mesh = &animation->mesh;
    size_t v_count = mesh->vertex_count, t_count = mesh->triangle_count;
    memset(table, 0, sizeof *table);
    table->chart = lk__malloc_array(v_count, sizeof(uint32_t));
    table->copy_start = lk__calloc_array(v_count + 1, sizeof(uint32_t));
    table->copies = lk__malloc_array(v_count, sizeof(uint32_t));
    table->clean_source = lk__malloc_array(clean->triangle_count, sizeof(uint32_t));
    uint32_t *component = lk__malloc_array(t_count, sizeof(uint32_t));
    if (!table->chart || !table->copy_start || !table->copies || !table->clean_source || !component) {
        free(component);
        seam_table_free(table);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam table");
    }
    size_t component_count = 0;
    lk_status status = lk_mesh_components(mesh, component, &component_count, error);
    if (status != LK_OK) {
        free(component);
        seam_table_free(table);
        return status;
    }
    for (size_t v = 0; v < v_count; v++) table->chart[v] = NONE;
    for (size_t c = 0; c < 3 * t_count; c++) table->chart[mesh->indices[c]] = component[c / 3];
    free(component);
    for (size_t v = 0; v < v_count; v++) table->copy_start[representative[v] + 1]++;
    for (size_t v = 0; v < v_count; v++) table->copy_start[v + 1] += table->copy_start[v];
    uint32_t *fill = lk__malloc_array(v_count, sizeof(uint32_t));
    if (!fill) {
        seam_table_free(table);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam table");
    }
    memcpy(fill, table->copy_start, v_count * sizeof(uint32_t));
    for (size_t v = 0; v < v_count; v++) table->copies[fill[representative[v]]++] = (uint32_t)v;
    free(fill);
    size_t next = 0;
    for (size_t t = 0; t < t_count && next < clean->triangle_count; t++) {
        const uint32_t *c = mesh->indices + 3 * t, *kept = clean->indices + 3 * next;
        if (representative[c[0]] == kept[0] && representative[c[1]] == kept[1] && representative[c[2]] == kept[2])
            table->clean_source[next++] = (uint32_t)t;
    }
    if (next != clean->triangle_count) {
        seam_table_free(table);
        return lk_error_set(error, LK_ERR_INVALID, "internal error: %zu of %zu triangles matched the input", next,
                            clean->triangle_count);
    }
    return LK_OK;
}

/* Splits the welded vertices of a result again where their copies carry
 * different attributes: each triangle corner takes the copy (of the vertex
 * it now uses) that lies in the chart of its input triangle, or, when that
 * vertex has no copy there, the attributes of its own input corner. Every
 * split vertex follows its welded vertex in every frame. */
static lk_status split_seams(const qem *s, const lk_animation *animation, const uint32_t *representative,
                             const seam_table *table, lk_anim_simplify_result *result, lk_error *error)
{
    lk_animation *out = &result->animation;
    const lk_mesh *in = &animation->mesh;
    size_t welded_count = out->mesh.vertex_count, out_triangles = out->mesh.triangle_count;
    size_t frames = out->frame_count, v_count = in->vertex_count;
    uint32_t *survivor = lk__malloc_array(welded_count + 1, sizeof(uint32_t));  /* welded output -> input id */
    uint32_t *internal_triangle = lk__malloc_array(s->triangle_count, sizeof(uint32_t));
    uint32_t *source = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t)); /* corner -> input vertex */
    uint32_t *first_pair = lk__malloc_array(welded_count + 1, sizeof(uint32_t));
    uint32_t *pair_next = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    uint32_t *pair_source = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    uint32_t *pair_welded = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    uint32_t *corner_vertex = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    float *positions = NULL;
    lk_status status = LK_OK;
    if (!survivor || !internal_triangle || !source || !first_pair || !pair_next || !pair_source || !pair_welded ||
        !corner_vertex) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam split");
        goto done;
    }
    for (size_t v = 0; v < s->vertex_count; v++) {
        const vertex *vv = &s->vertices[v];
        if (vv->parent == v && vv->list_count > 0) survivor[result->vertex_map[s->vertex_input[v]]] = s->vertex_input[v];
    }
    for (size_t t = 0; t < s->triangle_count; t++) internal_triangle[s->triangle_input[t]] = (uint32_t)t;
    /* output triangles are the live clean triangles in clean order (build_output) */
    size_t corner = 0;
    for (size_t clean_id = 0; clean_id < s->triangle_count; clean_id++) {
        if (!s->triangle_alive[internal_triangle[clean_id]]) continue;
        const uint32_t *original = in->indices + 3 * (size_t)table->clean_source[clean_id];
        for (int k = 0; k < 3; k++, corner++) {
            uint32_t u = original[k], kept = survivor[out->mesh.indices[corner]], chosen = u;
            if (representative[u] != kept)
                for (uint32_t i = table->copy_start[kept]; i < table->copy_start[kept + 1]; i++)
                    if (table->chart[table->copies[i]] == table->chart[u]) {
                        chosen = table->copies[i];
                        break;
                    }
            source[corner] = chosen;
        }
    }
    /* one output vertex per (welded vertex, source) */
    for (size_t w = 0; w < welded_count; w++) first_pair[w] = NONE;
    size_t pair_count = 0;
    for (size_t c = 0; c < 3 * out_triangles; c++) {
        uint32_t w = out->mesh.indices[c], found = NONE;
        for (uint32_t p = first_pair[w]; p != NONE; p = pair_next[p])
            if (pair_source[p] == source[c]) {
                found = p;
                break;
            }
        if (found == NONE) {
            found = (uint32_t)pair_count++;
            pair_source[found] = source[c];
            pair_welded[found] = w;
            pair_next[found] = first_pair[w];
            first_pair[w] = found;
        }
        corner_vertex[c] = found;
    }
    unsigned flags = (out->mesh.normals ? LK_ATTR_NORMALS : 0) | (out->mesh.texcoords ? LK_ATTR_TEXCOORDS : 0) |
                     (out->mesh.colors ? LK_ATTR_COLORS : 0);
    status = lk_mesh_alloc(&mesh, pair_count, out_triangles, flags, error);
    if (status != LK_OK) goto done;
    positions = lk__malloc_array(frames * pair_count, 3 * sizeof(float));
    if (!positions && pair_count > 0) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu frames of %zu vertices", frames, pair_count);
        goto done;
    }
    for (size_t p = 0; p < pair_count; p++) {
        size_t w = pair_welded[p], u = pair_source[p];
        for (size_t f = 0; f < frames; f++)
            memcpy(positions + 3 * (f * pair_count + p), out->frame_positions + 3 * (f * welded_count + w),
                   3 * sizeof(float));
        if (mesh.normals) memcpy(mesh.normals + 3 * p, in->normals + 3 * u, 3 * sizeof(float));
        if (mesh.texcoords) memcpy(mesh.texcoords + 2 * p, in->texcoords + 2 * u, 2 * sizeof(float));
        if (mesh.colors) memcpy(mesh.colors + 4 * p, in->colors + 4 * u, 4 * sizeof(float));
    }
    if (pair_count) memcpy(mesh.positions, positions, 3 * pair_count * sizeof(float));
    memcpy(mesh.indices, corner_vertex, 3 * out_triangles * sizeof(uint32_t));
    /* an input vertex maps to its own pair when it is a source, else to any
     * pair of its welded vertex */
    for (size_t v = 0; v < v_count; v++) {
        uint32_t w = result->vertex_map[v];
        if (w == NONE) continue;
        uint32_t chosen = first_pair[w];
        for (uint32_t p = first_pair[w]; p != NONE; p = pair_next[p])
            if (pair_source[p] == v) chosen = p;
        result->vertex_map[v] = chosen;
    }
    lk_mesh_free(&out->mesh);
    free(out->frame_positions);
    out->mesh = mesh;
    out->frame_positions = positions;
    lk_mesh_init(&mesh);
    positions = NULL;
done:
    lk_mesh_free(&mesh);
    free(positions);
    free(survivor), free(internal_triangle), free(source), free(first_pair), free(pair_next), free(pair_source);
    free(pair_welded), free(corner_vertex);
    return status;
}

/* The current state as an animation: build_output's mesh and vertex map,
 * plus every frame's positions. */
static lk_status animation_output(qem *s, const lk_mesh *mesh, const lk_animation *animation,
                                  lk_anim_simplify_result *result, lk_error *error)
{
    lk_simplify_result flat;
    memset(&flat, 0, sizeof flat);
    lk_status status = build_output(s, mesh, &flat, error);
    if (status != LK_OK) {
        lk_simplify_result_free(&flat);
        return status;
    }
    lk_animation *out = &result->animation;
    out->mesh = flat.mesh;
    result->vertex_map = flat.vertex_map;
    size_t frames = s->frame_count, out_vertices = out->mesh.vertex_count;
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
            memcpy(out->frame_positions + 3 * (f * out_vertices + o), s->frame_output + 3 * (v * frames + f),
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

/* Simplifies down through the levels of `order` (targets descending),
 * taking a snapshot at each. */
static lk_status simplify_animation(const lk_animation *animation, const lk_anim_simplify_options *options,
                                    const double *ratios, size_t level_count, const size_t *order,
                                    lk_anim_simplify_result *results, lk_progress_fn progress, void *progress_user,
                                    lk_error *error)
{
    double start = lk__now();
    const lk_simplify_options *o = &options->simplify;
    size_t reference = options->scheme == LK_ANIM_SCHEME_FRAME ? options->frame : 0;
    size_t v_count = animation->mesh.vertex_count, frames = animation->frame_count;
    /* the reference frame's positions, without degenerate or duplicate
     * triangles (which carry no surface in any frame) */
    lk_mesh clean;
    lk_status status = lk_mesh_copy(&clean, &animation->mesh, error);
    if (status != LK_OK) return status;
    memcpy(clean.positions, animation->frame_positions + 3 * reference * v_count, 3 * v_count * sizeof(float));
    uint32_t *representative = NULL;
    if (!options->keep_seams) {
        representative = lk__malloc_array(v_count, sizeof(uint32_t));
        if (!representative || weld_frames(animation, representative) == SIZE_MAX) {
            free(representative);
            lk_mesh_free(&clean);
            return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam table of %zu vertices", v_count);
        }
        for (size_t c = 0; c < 3 * clean.triangle_count; c++) clean.indices[c] = representative[clean.indices[c]];
    }
    status = lk_mesh_remove_degenerate(&clean, NULL, NULL, error);
    /* attributes differ between welded copies: remember where they came from */
    seam_table seams;
    memset(&seams, 0, sizeof seams);
    bool split = representative && (clean.normals || clean.texcoords || clean.colors);
    if (status == LK_OK && split) status = build_seam_table(animation, representative, &clean, &seams, error);
    if (status == LK_OK && clean.triangle_count == 0)
        status = lk_error_set(error, LK_ERR_INVALID, "every triangle is degenerate: nothing to simplify");
    if (status == LK_OK && (clean.vertex_count >= PERSISTENT || clean.triangle_count > LK_MAX_ELEMENTS / 3))
        status = lk_error_set(error, LK_ERR_LIMIT, "mesh too large for QEM simplification (%zu vertices)",
                              clean.vertex_count);
    if (status != LK_OK) {
        free(representative);
        seam_table_free(&seams);
        lk_mesh_free(&clean);
        return status;
    }
    qem s;
    memset(&s, 0, sizeof s);
    s.options = o;
    s.vertex_count = clean.vertex_count;
    s.triangle_count = clean.triangle_count;
    s.lock_border = (o->flags & LK_SIMPLIFY_LOCK_BORDER) != 0;
    s.endpoints = (o->flags & LK_SIMPLIFY_ENDPOINTS) != 0;
    s.max_error_sq = o->max_error > 0 ? o->max_error * o->max_error : INFINITY;
    s.frame_count = frames;
    s.scheme = options->scheme;
    s.scheme_frame = options->frame;
    s.reference_frame = reference;
    s.input_frames = animation->frame_positions;
    s.allow_folds = options->allow_folds != 0;
    s.lost_weight = options->lost_surface;
    float *face_normals = NULL;
    status = allocate(&s, error);
    if (status == LK_OK) {
        s.frame_quadrics = lk__calloc_array(v_count * frames, sizeof(quadric));
        s.frame_positions = lk__malloc_array(v_count * frames, 3 * sizeof(double));
        s.frame_output = lk__malloc_array(v_count * frames, 3 * sizeof(float));
        s.frame_scratch = lk__malloc_array(frames, 3 * sizeof(double));
        s.folded = lk__calloc_array(frames, 1);
        face_normals = lk__malloc_array(3 * s.triangle_count, sizeof(float));
        if (!s.frame_quadrics || !s.frame_positions || !s.frame_output || !s.frame_scratch || !s.folded ||
            !face_normals)
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu bytes of per-frame quadrics",
                                  frame_bytes(v_count, frames, s.lost_weight > 0));
    }
    if (status == LK_OK) status = build_lists(&s, &clean, error);
    if (status == LK_OK) status = setup_attributes(&s, &clean, error);
    if (status == LK_OK) {
        add_face_quadrics(&s, face_normals);
        status = build_edges(&s, face_normals, error);
    }
    if (status == LK_OK) status = build_frame_quadrics(&s, face_normals, error);
    free(face_normals);
    if (status == LK_OK && s.lost_weight > 0) {
        s.member_next = lk__malloc_array(v_count, sizeof(uint32_t));
        s.member_last = lk__malloc_array(v_count, sizeof(uint32_t));
        s.origin_positions = lk__malloc_array(v_count * frames, 3 * sizeof(double));
        s.origin_weights = lk__malloc_array(v_count * frames, sizeof(double));
        if (!s.member_next || !s.member_last || !s.origin_positions || !s.origin_weights) {
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the lost-surface records");
        } else {
            for (size_t v = 0; v < v_count; v++) s.member_next[v] = NONE, s.member_last[v] = (uint32_t)v;
            memcpy(s.origin_positions, s.frame_positions, v_count * frames * 3 * sizeof(double));
            for (size_t slot = 0; slot < v_count * frames; slot++)
                s.origin_weights[slot] = s.frame_quadrics[slot].weight;
        }
    }
    if (status == LK_OK && o->pair_distance > 0) status = add_close_pairs(&s, error);
    if (status == LK_OK) status = build_queue(&s, error);
    double diagonal = s.extent;
    for (size_t level = 0; level < level_count && status == LK_OK; level++) {
        size_t k = order[level];
        size_t target_triangles = 0, target_vertices = o->target_vertices;
        if (ratios[k] > 0) target_triangles = (size_t)floor(ratios[k] * (double)s.triangle_count);
        if (o->target_triangles > target_triangles) target_triangles = o->target_triangles;
        bool count_target = ratios[k] > 0 || o->target_triangles > 0 || o->target_vertices > 0;
        status = run(&s, target_triangles, target_vertices, progress, progress_user, error);
        lk_anim_simplify_result *result = &results[k];
        if (status == LK_OK) status = animation_output(&s, &clean, animation, result, error);
        if (status != LK_OK) break;
        /* welded copies follow their representative */
        if (representative)
            for (size_t v = 0; v < v_count; v++) result->vertex_map[v] = result->vertex_map[representative[v]];
        if (split) status = split_seams(&s, animation, representative, &seams, result, error);
        if (status != LK_OK) break;
        bool count_reached = s.live_triangles <= target_triangles || s.live_vertices <= target_vertices;
        result->target_reached = count_target ? count_reached || s.parked_for_error : 1;
        result->error = sqrt(s.reached_error_sq) * s.extent;
        result->diagonal = diagonal;
        result->working_bytes = frame_bytes(v_count, frames, s.lost_weight > 0);
        result->folds_from_triangles = s.folds_from;
        result->seconds = lk__now() - start;
    }
    qem_free(&s);
    lk_mesh_free(&clean);
    free(representative);
    seam_table_free(&seams);
    return status;
}

lk_status lk_animation_simplify(const lk_animation *animation, const lk_anim_simplify_options *options,
                                lk_anim_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                lk_error *error)
{
    if (!result) return lk_error_set(error, LK_ERR_INVALID, "no result given");
    memset(result, 0, sizeof *result);
    if (!options) return lk_error_set(error, LK_ERR_INVALID, "no options given: set a target");
    lk_status status = check_animation(animation, options, error);
    if (status != LK_OK) return status;
    const lk_simplify_options *o = &options->simplify;
    if (o->target_ratio == 0 && o->target_triangles == 0 && o->target_vertices == 0 && o->max_error == 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "no target: set a ratio, a triangle or vertex count, or a maximum error");
    size_t order = 0;
    status = simplify_animation(animation, options, &o->target_ratio, 1, &order, result, progress, progress_user,
                                error);
    if (status != LK_OK) lk_anim_simplify_result_free(result);
    return status;
}

lk_status lk_animation_simplify_levels(const lk_animation *animation, const lk_anim_simplify_options *options,
                                       const double *ratios, size_t level_count, lk_anim_simplify_result *results,
                                       lk_progress_fn progress, void *progress_user, lk_error *error)
{
    if (!results || !ratios || level_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "no levels given");
    memset(results, 0, level_count * sizeof *results);
    if (!options) return lk_error_set(error, LK_ERR_INVALID, "no options given");
    for (size_t k = 0; k < level_count; k++)
        if (!(ratios[k] > 0 && ratios[k] <= 1))
            return lk_error_set(error, LK_ERR_INVALID, "level %zu: ratio must be in (0, 1], got %g", k, ratios[k]);
    lk_anim_simplify_options level_options = *options;
    level_options.simplify.target_ratio = 0;
    level_options.simplify.target_triangles = 0;
    level_options.simplify.target_vertices = 0;
    lk_status status = check_animation(animation, &level_options, error);
    if (status != LK_OK) return status;
    size_t *order = lk__malloc_array(level_count, sizeof(size_t));
    if (!order) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu levels", level_count);
    /* largest ratio first (insertion sort: a handful of levels; stable) */
    for (size_t k = 0; k < level_count; k++) {
        size_t at = k;
        while (at > 0 && ratios[order[at - 1]] < ratios[k]) {
            order[at] = order[at - 1];
            at--;
        }
        order[at] = k;
    }
    status = simplify_animation(animation, &level_options, ratios, level_count, order, results, progress,
                                progress_user, error);
    free(order);
    if (status != LK_OK)
        for (size_t k = 0; k < level_count; k++) lk_anim_simplify_result_free(&results[k]);
    return status;
}
