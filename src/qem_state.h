/* SPDX-License-Identifier: MIT */
/* Internal interface of the QEM simplifier, shared by its three files:
 * qem.c (the engine: queue, pair evaluation, checks, contraction, main loop,
 * output, entry points), qem_build.c (the set-up: internal order, quadrics,
 * constraints, pairs) and qem_frames.c (several frames and the lost-surface
 * term). The state is split by concern: struct lk__qem holds the static
 * engine's, qem_frames the per-frame extension and qem_lost the
 * lost-surface term. The small vector and quadric helpers are inline here
 * so that each file compiles them into its own hot loops. A header of its
 * own (no .c): the set-up and the frames include it and qem.c calls them.
 * qem.c's top comment explains the method. Not installed. */
#ifndef LODKIT_QEM_STATE_H
#define LODKIT_QEM_STATE_H

#include "internal.h"

#include <float.h>
#include <math.h>
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

/* FLAG_SEAM: welded copies with different attributes (a texture seam, a
 * hard normal): such a vertex may merge with another seam vertex, but a
 * pair of a seam vertex and another keeps the seam vertex where it is, so
 * seams are never cut across (lk__qem_mark_seams). */
/* FLAG_MOVED: the vertex left its input position (output_position). */
enum { FLAG_BORDER = 1, FLAG_NONMANIFOLD = 2, FLAG_LOCKED = 4, FLAG_SEAM = 8, FLAG_MOVED = 16 };

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
    uint32_t list_start;    /* the list of the live triangles: pool[list_start ..] */
    uint32_t list_capacity; /* entries of that block */
} vertex;
_Static_assert(sizeof(vertex) == 128, "a vertex record must fill two cache lines");

/* Pool offsets are 32-bit (vertex.list_start): qem.pool_limit's default. */
#define POOL_LIMIT ((size_t)UINT32_MAX)

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

/* The bucket queue's types (qem.c). */
typedef struct queue_item queue_item;
typedef struct queue_chunk queue_chunk;
typedef struct queue_bucket queue_bucket;

typedef struct placement {
    double position[3];
    double cost;     /* total quadric cost: the priority */
    double error_sq; /* geometric cost / area weight (normalised units^2) */
    uint32_t kept, removed;
    double *frames; /* several frames: 3 * frames.count positions (one per frame) are
                        written here when not NULL; position is the reference frame's */
} placement;

typedef struct lk__qem qem;

/* Several frames (lk_animation_simplify): one quadric and one position per
 * vertex and frame, and the orientation test's fold allowance; count == 0
 * when static (qem_frames.c). */
typedef struct qem_frames {
    size_t count; /* frames; 0 when static */
    lk_anim_scheme scheme;
    size_t scheme_frame;   /* LK_ANIM_SCHEME_FRAME: the frame whose cost counts */
    size_t reference;      /* the frame held in the vertex records */
    const float *input;    /* count * V * 3, input vertex order */
    quadric *quadrics;     /* V * F, vertex-major: [v * F + f] */
    double *positions;     /* V * F * 3, normalised */
    float *output;         /* V * F * 3, model units (exact input floats until moved) */
    double *scratch;       /* F * 3: per-frame positions of the pair being contracted */
    bool allow_folds;      /* lk_anim_simplify_options.allow_folds */
    unsigned fold_stage;   /* index into FOLD_STAGES: 0 = no frame may fold */
    size_t allowed_folds;  /* frames (never the reference) a contraction may fold */
    size_t folded_count;   /* frames folded by the contraction being checked */
    unsigned char *folded; /* F: marks of those frames */
    size_t folds_from;     /* live triangles when folds were first allowed (0: never) */
} qem_frames;

/* The lost-surface term of several frames (lost_surface_cost in
 * qem_frames.c); weight == 0 when off. */
typedef struct qem_lost {
    double weight;            /* lk_anim_simplify_options.lost_surface (0: off) */
    uint32_t *member_next;    /* V: next input vertex merged into the same vertex (NONE ends) */
    uint32_t *member_last;    /* V: last member of a surviving vertex's list */
    double *origin_positions; /* V * F * 3: every vertex's normalised input positions */
    double *origin_weights;   /* V * F: area around each input vertex in each frame */
} qem_lost;

/* The state of one simplification: the static engine's, with the two
 * extensions of several frames. */
struct lk__qem {
    const lk_simplify_options *options;
    size_t vertex_count, triangle_count;
    /* Internal ids follow a spatial (Morton) order, so that a neighbourhood
     * sits in a few cache lines and pages; *_input map them back. */
    uint32_t *vertex_input;        /* V: input id of internal vertex */
    uint32_t *triangle_input;      /* T: input id of internal triangle */
    uint32_t *indices;             /* 3T, rewritten as vertices merge */
    unsigned char *triangle_alive; /* T */
    vertex *vertices;              /* V */
    const float *input_positions;  /* 3V, the input mesh's, input order (output_position) */
    double center[3], extent;      /* model = normalised * extent + center */
    const lk__qem_part *part;      /* NULL, or the whole mesh's normalisation and locks */
    unsigned char *flags;          /* V */
    bool lock_border;
    bool endpoints;        /* LK_SIMPLIFY_ENDPOINTS: half-edge collapses */
    bool rounds;           /* LK_SIMPLIFY_ROUNDS: independent contractions in rounds */
    uint32_t bucket_shift; /* queue buckets: key >> bucket_shift (qem.c) */

    /* attributes: attribute_count channels per vertex */
    unsigned attribute_count;
    unsigned normal_channel, texcoord_channel, color_channel; /* NONE when absent */
    float *attributes;                                        /* V * attribute_count, unscaled values */
    bool attribute_quadrics_on;
    double attribute_scale;     /* attribute_weight * ATTRIBUTE_UNIT */
    size_t attribute_stride;    /* doubles per vertex: 10 + 4m */
    double *attribute_quadrics; /* V * stride: gg[6] bx[3] c g[3m] bs[m] */

    /* per-vertex triangle lists (blocks of the pool named by the vertex
     * records: a contraction finds them with the records it reads anyway) */
    uint32_t *pool;
    size_t pool_size, pool_capacity;
    size_t pool_limit; /* POOL_LIMIT (lower in tests): pool_capacity never exceeds it */

    link_counts *link; /* V */
    uint16_t token;
    uint32_t *stamp;      /* V: contraction that last changed the quadric, or DEAD */
    uint32_t *ring_stamp; /* V: contraction that last changed a triangle around it */
    uint32_t *scratch;    /* merged triangle list */
    size_t scratch_capacity;
    uint32_t now; /* contractions done */

    /* initial pairs */
    size_t pair_count, edge_count;
    uint32_t *pairs; /* 2 * pair_count */

    /* queue */
    queue_chunk *chunks;
    size_t chunk_count, chunk_capacity;
    uint32_t free_chunks;
    queue_bucket *buckets;   /* BUCKET_COUNT */
    uint64_t *bucket_bits;   /* non-empty buckets */
    uint64_t *summary_bits;  /* non-zero bucket_bits words */
    uint32_t current_bucket; /* no non-empty bucket below it */
    size_t queued;
    queue_item *parked;
    size_t parked_count, parked_capacity;
    bool parked_for_error;
    /* LK_SIMPLIFY_ROUNDS: pairs popped in this round but next to one of its
     * contractions wait here for the next round (their keys are true costs). */
    queue_item *waiting;
    size_t waiting_count, waiting_capacity;
    uint32_t waiting_lowest; /* lowest bucket among them */
    uint32_t round_start;    /* s->now when the round began: ring_stamp[v] > it = touched */

    size_t live_triangles, live_vertices;

    /* history */
    bool record;
    lk_collapse *collapses;
    size_t collapse_count;
    uint32_t *vanished;
    size_t vanished_count;
    double max_error_sq; /* normalised units^2 (INFINITY if none) */
    double reached_error_sq;

    qem_frames frames; /* several frames (count == 0 when static) */
    qem_lost lost;     /* the lost-surface term (weight == 0 when off) */
};

/* ---- small vector and quadric helpers ---------------------------------- */

static inline void sub3(double out[3], const double a[3], const double b[3])
{
    out[0] = a[0] - b[0], out[1] = a[1] - b[1], out[2] = a[2] - b[2];
}
static inline double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
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

/* v^T A v + 2 b.v + c */
static inline double quadric_value(const double a[6], const double b[3], double c, const double v[3])
{
    double av0 = a[0] * v[0] + a[1] * v[1] + a[2] * v[2];
    double av1 = a[1] * v[0] + a[3] * v[1] + a[4] * v[2];
    double av2 = a[2] * v[0] + a[4] * v[1] + a[5] * v[2];
    return v[0] * (av0 + 2 * b[0]) + v[1] * (av1 + 2 * b[1]) + v[2] * (av2 + 2 * b[2]) + c;
}

/* Best point of segment pa-pb for the quadric among its minimum, its ends
 * and its midpoint (which wins ties: better-shaped triangles on flat
 * ground). Along the segment, E(pa + t d) = E0 + 2 t g.d + t^2 d.A d with
 * g = A pa + b, so one evaluation of the quadric serves every candidate. */
static inline void segment_minimum(const double a[6], const double b[3], const double pa[3], const double pb[3],
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

/* Output positions go back to float. A model near FLT_MAX (3.4e38) can
 * have its optimum a little outside the float range (a sphere's optimum
 * lies outside the sphere): clamp rather than write inf. */
static inline float output_float(double value)
{
    if (value > FLT_MAX) return FLT_MAX;
    if (value < -FLT_MAX) return -FLT_MAX;
    return (float)value;
}

/* The merged vertex's position x for the quadric q (a00 a01 a02 a11 a12
 * a22 b0 b1 b2 c) of pair pa-pb: A x = -b by cofactors, unless A is (nearly)
 * singular relative to its trace (an isotropic A has det = trace^3 / 27) or
 * the optimum lies far away; then the best point of the segment. Returns
 * (x - midpoint).(pb - pa): <= 0 when x is nearer to pa. */
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

/* A vertex's position in model units: its exact input floats until it
 * moves, then its normalised position scaled back (no array of output
 * positions: 12 bytes per vertex less at the peak). */
static inline void output_position(const qem *s, uint32_t v, float out[3])
{
    if (s->flags[v] & FLAG_MOVED) {
        for (int k = 0; k < 3; k++) out[k] = output_float(s->vertices[v].position[k] * s->extent + s->center[k]);
    } else {
        memcpy(out, s->input_positions + 3 * (size_t)s->vertex_input[v], 3 * sizeof(float));
    }
}

static inline bool triangle_has(const uint32_t *t, uint32_t v) { return t[0] == v || t[1] == v || t[2] == v; }

static inline const uint32_t *list_of(const qem *s, uint32_t v) { return s->pool + s->vertices[v].list_start; }

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

/* ---- set-up (qem_build.c) ------------------------------------------------
 * In the order lk__simplify_qem and lk__qem_frames_start call them. */
/* Allocates the per-vertex and per-triangle arrays (vertex_count,
 * triangle_count and record set). */
lk_status lk__qem_allocate(qem *s, lk_error *error);
/* Frees every array of the state (not the state itself). */
void lk__qem_free_arrays(qem *s);
/* Internal order, normalised positions (the bounds of every frame with
 * several), vertex triangle lists, live counts. */
lk_status lk__qem_build_lists(qem *s, const lk_mesh *mesh, lk_error *error);
/* The attribute channels present in the mesh (and their quadrics with
 * LK_SIMPLIFY_ATTRIBUTES). */
lk_status lk__qem_setup_attributes(qem *s, const lk_mesh *mesh, lk_error *error);
/* Face quadrics (and attribute quadrics); fills unit face normals (3T). */
void lk__qem_add_face_quadrics(qem *s, float *face_normals);
/* The edges (the first pairs), border and non-manifold flags, border and
 * crease constraints and corner quadrics. */
lk_status lk__qem_build_edges(qem *s, const float *face_normals, lk_error *error);
/* Several frames: every frame's quadrics by the same rules; the vertex
 * records end up holding the reference frame. */
lk_status lk__qem_build_frame_quadrics(qem *s, float *face_normals, lk_error *error);
/* Non-edge pairs closer than pair_distance. */
lk_status lk__qem_add_close_pairs(qem *s, lk_error *error);

/* ---- several frames (qem_frames.c) -------------------------------------- */
/* evaluate() of qem.c for several frames: each frame's placement, the
 * scheme's cost (with the lost-surface term) and error. */
void lk__qem_evaluate_frames(const qem *s, uint32_t va, uint32_t vb, placement *out);
/* The orientation test in every frame but the reference. */
bool lk__qem_frames_keep_orientation(qem *s, const uint32_t *t, uint32_t moved, const placement *pl);
/* p takes q's per-frame quadrics and each frame's new position. */
void lk__qem_contract_frames(qem *s, uint32_t p, uint32_t q, const placement *pl);

#endif
