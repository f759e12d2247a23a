/* SPDX-License-Identifier: MIT */
/* What the files of the version-2 progressive stream share, private to them:
 * the adaptive binary range coder every v2 payload is written with, and the
 * decoder's mesh (stream2_mesh.c), which the encoder (stream2_encode.c) keeps
 * in step with so that both see the same vertex and triangle numbers, rings
 * and predictions. docs/stream-format.md specifies every bit. Not installed. */
#ifndef LODKIT_STREAM2_INTERNAL_H
#define LODKIT_STREAM2_INTERNAL_H

#include "stream_internal.h"

#include <math.h>
#include <string.h>

#define LKS2_VERSION 2u

/* ---- adaptive binary range coder ----------------------------------------- */

/* A probability is P(bit = 0) in units of 1/4096; after each coded bit it
 * moves 1/32 of the way towards what was seen (LZMA's adaptation rule). */
#define LKS2_PROB_BITS 12u
#define LKS2_PROB_ONE (1u << LKS2_PROB_BITS)
#define LKS2_PROB_INIT (LKS2_PROB_ONE / 2u)
#define LKS2_ADAPT_SHIFT 5u
#define LKS2_TOP (1u << 24)

typedef uint16_t lks2_prob;

typedef struct lks2_encoder {
    lk__buffer out;
    uint64_t low;
    uint32_t range;
    unsigned char cache;
    uint64_t pending; /* bytes held back while a carry may still reach them */
    bool started;     /* the first byte held back is always 0 and is not written */
    bool failed;
} lks2_encoder;

static inline void lks2_encoder_init(lks2_encoder *coder)
{
    memset(coder, 0, sizeof *coder);
    coder->range = UINT32_MAX;
    coder->pending = 1;
}

static inline void lks2_put(lks2_encoder *coder, unsigned char byte)
{
    if (!coder->started) {
        coder->started = true; /* the leading zero: implied by the decoder */
        return;
    }
    if (!coder->failed && !lk__buffer_append(&coder->out, &byte, 1)) coder->failed = true;
}

static inline void lks2_shift_low(lks2_encoder *coder)
{
    if ((uint32_t)coder->low < 0xFF000000u || (coder->low >> 32) != 0) {
        unsigned char carry = (unsigned char)(coder->low >> 32);
        unsigned char held = coder->cache;
        do {
            lks2_put(coder, (unsigned char)(held + carry));
            held = 0xFF;
        } while (--coder->pending != 0);
        coder->cache = (unsigned char)(coder->low >> 24);
    }
    coder->pending++;
    coder->low = (coder->low & 0x00FFFFFFu) << 8;
}

static inline void lks2_encode_bit(lks2_encoder *coder, lks2_prob *prob, unsigned bit)
{
    uint32_t bound = (coder->range >> LKS2_PROB_BITS) * *prob;
    if (!bit) {
        coder->range = bound;
        *prob = (lks2_prob)(*prob + ((LKS2_PROB_ONE - *prob) >> LKS2_ADAPT_SHIFT));
    } else {
        coder->low += bound;
        coder->range -= bound;
        *prob = (lks2_prob)(*prob - (*prob >> LKS2_ADAPT_SHIFT));
    }
    while (coder->range < LKS2_TOP) {
        coder->range <<= 8;
        lks2_shift_low(coder);
    }
}

/* Bits of even odds (no model): half the range each. */
static inline void lks2_encode_direct(lks2_encoder *coder, uint32_t value, unsigned bits)
{
    while (bits-- > 0) {
        coder->range >>= 1;
        if ((value >> bits) & 1u) coder->low += coder->range;
        while (coder->range < LKS2_TOP) {
            coder->range <<= 8;
            lks2_shift_low(coder);
        }
    }
}

/* Ends the payload: the decoder reads exactly the bytes written. */
static inline void lks2_encoder_flush(lks2_encoder *coder)
{
    for (int i = 0; i < 5; i++) lks2_shift_low(coder);
}

typedef struct lks2_decoder {
    const unsigned char *data;
    size_t size, position;
    uint32_t range, code;
    bool overrun; /* read past the end: the payload is corrupt or cut */
} lks2_decoder;

/* Bits of information the decoder has taken so far: each byte read adds 8,
 * each symbol narrows the range by its probability. Differences between
 * two calls are the exact cost of the symbols decoded between them. */
static inline double lks2_decoder_bits(const lks2_decoder *coder)
{
    return 8.0 * (double)coder->position - log2((double)coder->range);
}

static inline unsigned char lks2_get(lks2_decoder *coder)
{
    if (coder->position < coder->size) return coder->data[coder->position++];
    coder->overrun = true;
    return 0;
}

static inline void lks2_decoder_init(lks2_decoder *coder, const unsigned char *data, size_t size)
{
    coder->data = data;
    coder->size = size;
    coder->position = 0;
    coder->overrun = false;
    coder->range = UINT32_MAX;
    coder->code = 0;
    for (int i = 0; i < 4; i++) coder->code = (coder->code << 8) | lks2_get(coder);
}

static inline unsigned lks2_decode_bit(lks2_decoder *coder, lks2_prob *prob)
{
    uint32_t bound = (coder->range >> LKS2_PROB_BITS) * *prob;
    unsigned bit;
    if (coder->code < bound) {
        coder->range = bound;
        *prob = (lks2_prob)(*prob + ((LKS2_PROB_ONE - *prob) >> LKS2_ADAPT_SHIFT));
        bit = 0;
    } else {
        coder->code -= bound;
        coder->range -= bound;
        *prob = (lks2_prob)(*prob - (*prob >> LKS2_ADAPT_SHIFT));
        bit = 1;
    }
    while (coder->range < LKS2_TOP) {
        coder->range <<= 8;
        coder->code = (coder->code << 8) | lks2_get(coder);
    }
    return bit;
}

static inline uint32_t lks2_decode_direct(lks2_decoder *coder, unsigned bits)
{
    uint32_t value = 0;
    while (bits-- > 0) {
        coder->range >>= 1;
        unsigned bit = coder->code >= coder->range;
        if (bit) coder->code -= coder->range;
        value = (value << 1) | bit;
        while (coder->range < LKS2_TOP) {
            coder->range <<= 8;
            coder->code = (coder->code << 8) | lks2_get(coder);
        }
    }
    return value;
}

static inline void lks2_probs_init(lks2_prob *probs, size_t count)
{
    for (size_t i = 0; i < count; i++) probs[i] = LKS2_PROB_INIT;
}

/* Symbols of `bits` bits through a binary tree of 2^bits models (most
 * significant bit first, each bit's model chosen by the bits above it). */
static inline void lks2_encode_tree(lks2_encoder *coder, lks2_prob *tree, unsigned bits, uint32_t symbol)
{
    uint32_t node = 1;
    while (bits-- > 0) {
        unsigned bit = (symbol >> bits) & 1u;
        lks2_encode_bit(coder, &tree[node], bit);
        node = 2 * node + bit;
    }
}
static inline uint32_t lks2_decode_tree(lks2_decoder *coder, lks2_prob *tree, unsigned bits)
{
    uint32_t node = 1;
    for (unsigned i = 0; i < bits; i++) node = 2 * node + lks2_decode_bit(coder, &tree[node]);
    return node - (1u << bits);
}

/* Unsigned integers up to 2^32 - 1: the bit length (0 for zero, else
 * 1..32) through a 6-bit tree, then the bits under the leading one: the
 * highest LKS2_MODELLED_BITS of them through models chosen by the length,
 * the rest direct. */
#define LKS2_LENGTH_BITS 6u
#define LKS2_MODELLED_BITS 2u
typedef struct lks2_uint_model {
    lks2_prob length[1u << LKS2_LENGTH_BITS];
    lks2_prob high[33][1u << LKS2_MODELLED_BITS];
} lks2_uint_model;

static inline void lks2_uint_model_init(lks2_uint_model *model)
{
    lks2_probs_init(model->length, sizeof model->length / sizeof model->length[0]);
    lks2_probs_init(&model->high[0][0], sizeof model->high / sizeof model->high[0][0]);
}

static inline unsigned lks2_bit_length(uint32_t value)
{
    unsigned length = 0;
    while (value) {
        length++;
        value >>= 1;
    }
    return length;
}

static inline void lks2_encode_uint(lks2_encoder *coder, lks2_uint_model *model, uint32_t value)
{
    unsigned length = lks2_bit_length(value);
    lks2_encode_tree(coder, model->length, LKS2_LENGTH_BITS, length);
    if (length <= 1) return;
    unsigned below = length - 1; /* bits under the leading one */
    unsigned modelled = below < LKS2_MODELLED_BITS ? below : LKS2_MODELLED_BITS;
    lks2_encode_tree(coder, model->high[length], modelled, (value >> (below - modelled)) & ((1u << modelled) - 1u));
    if (below > modelled) lks2_encode_direct(coder, value & ((1u << (below - modelled)) - 1u), below - modelled);
}

/* Returns false for a length above 32 (a corrupt payload). */
static inline bool lks2_decode_uint(lks2_decoder *coder, lks2_uint_model *model, uint32_t *out)
{
    unsigned length = lks2_decode_tree(coder, model->length, LKS2_LENGTH_BITS);
    if (length > 32) return false;
    if (length <= 1) {
        *out = length;
        return true;
    }
    unsigned below = length - 1;
    unsigned modelled = below < LKS2_MODELLED_BITS ? below : LKS2_MODELLED_BITS;
    uint64_t value = 1;
    value = (value << modelled) | lks2_decode_tree(coder, model->high[length], modelled);
    if (below > modelled) value = (value << (below - modelled)) | lks2_decode_direct(coder, below - modelled);
    *out = (uint32_t)value;
    return true;
}

static inline uint32_t lks2_zigzag32(int32_t value) { return ((uint32_t)value << 1) ^ (uint32_t)(value >> 31); }
static inline int32_t lks2_unzigzag32(uint32_t value) { return (int32_t)(value >> 1) ^ -(int32_t)(value & 1u); }

/* ---- vertex attributes ------------------------------------------------------ */

/* Header flags of a version-2 stream: the attributes each vertex carries,
 * in this order after its position. */
#define LKS2_FLAG_NORMALS 1u   /* 2 components: octahedral, normal_bits each */
#define LKS2_FLAG_TEXCOORDS 2u /* 2 components: texcoord_bits each, on their own box */
#define LKS2_FLAG_COLORS 4u    /* 4 components: RGBA, 8 bits each */
#define LKS2_FLAGS (LKS2_FLAG_NORMALS | LKS2_FLAG_TEXCOORDS | LKS2_FLAG_COLORS)
/* Not an attribute: split positions are coded in their ring's frame
 * (lk__lks2_predict_frame). lodkit writes it; streams without it still
 * decode. */
#define LKS2_FLAG_RING_FRAME 8u
#define LKS2_HEADER_FLAGS (LKS2_FLAGS | LKS2_FLAG_RING_FRAME)
#define LKS2_MAX_ATTRIBUTES 8u

/* How the attributes are quantised (the base chunk carries it). */
typedef struct lks2_attributes {
    unsigned flags;
    unsigned count;         /* components per vertex */
    unsigned normal_bits;   /* 4..16 */
    unsigned texcoord_bits; /* 4..24 */
    float texcoord_min[2], texcoord_step[2];
    int32_t top[LKS2_MAX_ATTRIBUTES]; /* largest value of each component */
} lks2_attributes;

/* Fills count and top from flags and bits. */
void lk__lks2_attributes_layout(lks2_attributes *attributes);
/* Octahedral code of a unit normal on `bits` bits per component, and back. */
void lk__lks2_encode_normal(const float normal[3], unsigned bits, int32_t out[2]);
void lk__lks2_decode_normal(const int32_t code[2], unsigned bits, float out[3]);

/* ---- the decoder's mesh (stream2_mesh.c) ---------------------------------- */

/* Vertices are numbered in the order they appear (base vertices in the
 * base chunk's order, then one per split in decoding order), triangles
 * likewise. Each vertex keeps a singly linked list of its corners. */
typedef struct lks2_mesh {
    size_t vertex_count, vertex_capacity;
    size_t triangle_count, triangle_capacity;
    int32_t *quantised;       /* 3 per vertex */
    uint32_t *head;           /* per vertex: a corner of it, LKS_NONE if none */
    uint32_t *valence;        /* per vertex: its triangle count (the length of its corner list) */
    uint32_t *corners;        /* 3 per triangle: its vertices */
    uint32_t *next_corner;    /* 3 per triangle: the next corner of the same vertex */
    unsigned hint_shift;      /* position bits above 12: dropped before the hint's dot products */
    bool ring_frame;          /* LKS2_FLAG_RING_FRAME: split positions in their ring's frame */
    unsigned attribute_count; /* quantised attribute components per vertex (0..LKS2_MAX_ATTRIBUTES) */
    int32_t *attributes;      /* attribute_count per vertex */
} lks2_mesh;

void lk__lks2_mesh_free(lks2_mesh *mesh);
/* Room for vertex_count vertices and triangle_count triangles. */
lk_status lk__lks2_mesh_reserve(lks2_mesh *mesh, size_t vertex_count, size_t triangle_count, lk_error *error);
/* Appends a vertex (room reserved); returns its number. Its attributes are
 * copied from vertex `like` (LKS_NONE: zero). */
uint32_t lk__lks2_add_vertex(lks2_mesh *mesh, const int32_t position[3], uint32_t like);
/* Appends a triangle (room reserved). */
void lk__lks2_add_triangle(lks2_mesh *mesh, uint32_t a, uint32_t b, uint32_t c);
/* The triangles around v, in the order of v's corner list (at most
 * `capacity`); returns how many there are (which may be more). */
size_t lk__lks2_vertex_triangles(const lks2_mesh *mesh, uint32_t v, uint32_t *out, size_t capacity);
/* Gives triangle t's corner at v to vertex `to`. */
void lk__lks2_move_corner(lks2_mesh *mesh, uint32_t t, uint32_t v, uint32_t to);
/* Predicted position of v: the mean of the vertices of its triangles other
 * than v (each as often as it appears), rounded half up; `fallback` when v
 * has no triangle. */
void lk__lks2_predict(const lks2_mesh *mesh, uint32_t v, const int32_t fallback[3], int32_t out[3]);
/* The frame a split position is coded in when mesh->ring_frame is set
 * (docs/stream-format.md, "One split at vertex p", step 6): the residual's
 * components along axis[0] and axis[1] as they are, then the one along
 * axis[2], the axis closest to the ring's normal, less the offset that puts
 * the vertex in the plane through the prediction across that normal
 * (lk__lks2_frame_offset). On a smooth surface the new vertex lies near
 * that plane, so the third component is small. */
typedef struct lks2_frame {
    int axis[3];
    int64_t normal[3]; /* scaled: |normal[axis[2]]| < 2^15, the others no larger */
} lks2_frame;
/* lk__lks2_predict's prediction and, around it, the frame. */
void lk__lks2_predict_frame(const lks2_mesh *mesh, uint32_t v, const int32_t fallback[3], int32_t predicted[3],
                            lks2_frame *frame);
int64_t lk__lks2_frame_offset(const lks2_frame *frame, int32_t first, int32_t second);
/* The same mean over v's ring for its attribute components (`fallback`
 * when v has no triangle). */
void lk__lks2_predict_attributes(const lks2_mesh *mesh, uint32_t v, const int32_t *fallback, int32_t *out);

/* The shapes of a fan (the triangles around a vertex). */
enum { LKS2_FAN_UNORDERED = 0, LKS2_FAN_OPEN = 1, LKS2_FAN_CLOSED = 2 };
/* Orders the fan of v (count triangles; `fan` has room for 2 * count,
 * `scratch` for 3 * count): when its triangles form one chain, each sharing
 * the edge (v, w) with the next, in chain order from the chain's start
 * (open: the triangle no other leads into; closed: the lowest numbered),
 * else by increasing number. Returns the shape. */
unsigned lk__lks2_order_fan(const lks2_mesh *mesh, uint32_t v, uint32_t *fan, size_t count, uint32_t *scratch);

/* The fan of the vertex being split, ordered, with the decisions taken
 * for it and the restored triangles predicted from them. */
typedef struct lks2_fan {
    uint32_t *triangles;  /* 2 * capacity (lk__lks2_order_fan's room) */
    unsigned char *moved; /* capacity: 1 when the triangle goes to q */
    unsigned char *hint;  /* capacity: 1 when the triangle lies on the side of v's ring centroid,
                             + 2 when its spokes are longer than the fan's mean */
    int64_t *spoke;       /* capacity: squared spokes (hint's positions) */
    int64_t *offset;      /* 3 * capacity: the sum of the other corners' offsets from v (hint's positions) */
    uint32_t *scratch;    /* 3 * capacity */
    uint32_t *restored;   /* 3 per predicted triangle */
    size_t capacity, restored_capacity;
    size_t count;
    unsigned shape;
} lks2_fan;

void lk__lks2_fan_free(lks2_fan *fan);
/* Loads and orders v's fan; false when out of memory. */
bool lk__lks2_fan_load(lks2_fan *fan, const lks2_mesh *mesh, uint32_t v);
/* Predicts the restored triangles from fan->moved into fan->restored;
 * returns their count, SIZE_MAX when out of memory. */
size_t lk__lks2_fan_restore(lks2_fan *fan, const lks2_mesh *mesh, uint32_t p, uint32_t q);

/* How one split is coded, shared by encoder and decoder. */
#define LKS2_MOVE_CONTEXTS 96u

/* The split kinds: which of the two vertices after the split gets a coded
 * position (the other keeps the position p had). */
enum { LKS2_NEW_Q = 0, LKS2_NEW_P = 1, LKS2_NEW_BOTH = 2 };

/* Models of a chunk (reset at the start of every chunk). */
/* Models of "is this vertex a split vertex of the batch": one per count of
 * triangles around it, the last for that count or more. */
#define LKS2_SPLIT_CONTEXTS 11u

typedef struct lks2_models {
    lks2_prob split[LKS2_SPLIT_CONTEXTS];
    lks2_prob move[LKS2_MOVE_CONTEXTS];
    lks2_prob predicted_ok[2];
    lks2_prob kind[4];
    lks2_uint_model escape_count;
    lks2_prob orientation;
    lks2_uint_model residual[3];
    lks2_uint_model batch_size;
    lks2_uint_model corner[3]; /* base triangles */
    lks2_uint_model attribute[LKS2_MAX_ATTRIBUTES];
} lks2_models;

void lk__lks2_models_init(lks2_models *models);
/* Context of "is v a split vertex of the batch": its triangle count, up to
 * LKS2_SPLIT_CONTEXTS - 1 (a split raises the kept vertex's count, so the
 * vertices around which many triangles meet are the likely ones). */
unsigned lk__lks2_split_context(const lks2_mesh *mesh, uint32_t v);
/* Context of "does triangle i of the ordered fan move to q": the decisions
 * already taken for the fan's earlier triangles (along the chain: the
 * previous one and how often they changed; unordered: the neighbouring
 * triangles' decisions), and whether the triangle lies towards the ring's
 * centroid (fan->hint). */
unsigned lk__lks2_move_context(const lks2_mesh *mesh, uint32_t v, const lks2_fan *fan, size_t index);
/* The triangles a split should restore, predicted from the moved set: one
 * per edge (v, w) between a moved and a staying triangle of the fan,
 * oriented against the staying one. Writes 3 corners per triangle (p, q
 * and w in drawing order) and returns their number (at most `capacity`). */
size_t lk__lks2_predict_restored(const lks2_mesh *mesh, uint32_t p, uint32_t q, const uint32_t *fan,
                                 const unsigned char *moved, size_t fan_size, unsigned shape, uint32_t *out,
                                 size_t capacity);

/* Marks v and its neighbours with `serial`: vertices that cannot split in
 * the same batch as v. */
void lk__lks2_exclude(const lks2_mesh *mesh, uint32_t v, uint32_t *stamp, uint32_t serial);

/* ---- decoding core (stream2_decode.c; the encoder checks its output with it) */

/* What a chunk changed, so a chunk found corrupt half-way is taken back
 * and the decoder keeps the level of the chunk before. */
typedef struct lks2_undo_split {
    uint32_t p;
    uint32_t triangles_before; /* triangle count before the split */
    uint32_t moved_start;      /* into lks2_state.moved */
    int32_t old_position[3];   /* p's position before the split */
} lks2_undo_split;

typedef struct lks2_state {
    lks2_mesh mesh;
    lks2_attributes attributes; /* known once the base chunk is decoded */
    size_t base_vertex_count;
    bool has_base;
    uint32_t *stamp; /* per vertex: serial of the batch that excluded it */
    uint32_t serial;
    lks2_undo_split *splits; /* of the chunk being applied (keep_log: of every split chunk so far) */
    size_t split_capacity, split_count;
    /* Keep every split in splits / moved / old_attributes, not only the
     * chunk's: a client that shows lower levels rebuilds them from it
     * (src/wasm/stream2_wasm.c). chunk_split_start and chunk_moved_start:
     * where the chunk being applied began in them. */
    bool keep_log;
    size_t chunk_split_start, chunk_moved_start;
    uint32_t *moved; /* triangles given to q, split after split */
    size_t moved_capacity, moved_count;
    int32_t *old_attributes; /* attributes.count per logged split: p's before it */
    size_t old_attributes_capacity;
    lks2_models models; /* of the split chunks, carried from one to the next */
    bool models_started;
    /* lk_stream_bits: bits per part (LKS2_PART_*) are added to account
     * (NULL: not counted), from account_mark, the coder's bits at the last
     * part boundary */
    double *account;
    double account_mark;
} lks2_state;

/* What lk_stream_bits splits a version-2 stream into. */
enum {
    LKS2_PART_BASE,
    LKS2_PART_SPLIT_VERTICES,
    LKS2_PART_MOVES,
    LKS2_PART_RESTORED,
    LKS2_PART_POSITIONS,
    LKS2_PART_NORMALS,
    LKS2_PART_TEXCOORDS,
    LKS2_PART_COLORS,
    LKS2_PART_COUNT
};

/* Adds the bits since the last boundary to `part`. */
static inline void lks2_account(lks2_state *state, const lks2_decoder *coder, unsigned part)
{
    if (!state->account) return;
    double bits = lks2_decoder_bits(coder);
    state->account[part] += bits - state->account_mark;
    state->account_mark = bits;
}

void lk__lks2_state_free(lks2_state *state);
/* Room for the header's counts (vertices, triangles). */
lk_status lk__lks2_state_begin(lks2_state *state, const lks_header *header, lk_error *error);
/* Decodes the base chunk (or a split chunk, applying at most `limit` of its
 * splits) and checks the table's triangle count when the whole chunk was
 * applied. On failure the state is as before the chunk. */
lk_status lk__lks2_decode_chunk(lks2_state *state, const lks_header *header, const lk_stream_chunk_info *chunk,
                                const unsigned char *payload, size_t size, size_t limit, const lks_where *where,
                                lk_error *error);

/* Encodes a progressive mesh as a version-2 stream (*bytes: free()), with
 * the normals, texture coordinates and colours `input` has (the mesh the
 * progressive mesh was built from; NULL: positions only). vertex_map
 * (optional, free()): decoder vertex -> input vertex. */
lk_status lk__lks2_encode(const lk_progressive_mesh *pm, const lk_mesh *input, const lk_stream_options *options,
                          unsigned char **bytes, size_t *size, uint32_t **vertex_map, lk_error *error);
/* The same, with split positions in their ring's frame (LKS2_FLAG_RING_FRAME,
 * what lk__lks2_encode writes) or, ring_frame false, axis by axis as streams
 * without the flag (kept for tests: such streams must still decode). */
lk_status lk__lks2_encode_framed(const lk_progressive_mesh *pm, const lk_mesh *input, const lk_stream_options *options,
                                 bool ring_frame, unsigned char **bytes, size_t *size, uint32_t **vertex_map,
                                 lk_error *error);
/* Decodes a whole version-2 stream and compares it with the mesh the
 * encoder ended with (vertex positions and triangles, in order). */
lk_status lk__lks2_check(const unsigned char *bytes, size_t size, const lks2_mesh *expected, lk_error *error);
/* Decodes a whole version-2 stream held in memory into *mesh (empty on
 * entry), stopping after max_chunks chunks (base included). */
lk_status lk__lks2_decode(const unsigned char *bytes, size_t size, size_t max_chunks, double *account,
                          lks_header *header, lks2_mesh *mesh, lk_error *error);

#endif
