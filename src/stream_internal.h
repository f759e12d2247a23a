/* SPDX-License-Identifier: MIT */
/* What the files of the progressive stream format (.lks) share, private to
 * them: the format's constants and integer coding (stream_format.c holds
 * the header, the chunk table and the CRC), and the decoding core of
 * stream_decode.c, which the encoder (stream_encode.c) runs on what it has
 * just written. docs/stream-format.md specifies every byte. Not installed. */
#ifndef LODKIT_STREAM_INTERNAL_H
#define LODKIT_STREAM_INTERNAL_H

#include "internal.h"

#define LKS_VERSION 1u
#define LKS_FIXED_HEADER_SIZE 96u
#define LKS_TABLE_ENTRY_SIZE 32u
#define LKS_TABLE_CRC_SIZE 4u
#define LKS_CHUNK_HEADER_SIZE 8u
/* deflate cannot expand data more than ~1032:1, so a stored payload of n
 * bytes never stands for more than this many raw bytes per byte. */
#define LKS_MAX_DEFLATE_RATIO 1032u
/* A split costs at least its p varint and three position varints. */
#define LKS_MIN_SPLIT_BYTES 4u
#define LKS_NONE UINT32_MAX

extern const unsigned char lk__lks_magic[8];

/* CRC-32 (zlib's) of any number of bytes. */
uint32_t lk__lks_crc32(const unsigned char *bytes, size_t size);

/* ---- variable-length integers ----------------------------------------- */

static inline uint64_t lks_zigzag(int64_t value) { return ((uint64_t)value << 1) ^ (uint64_t)(value >> 63); }
static inline int64_t lks_unzigzag(uint64_t value) { return (int64_t)(value >> 1) ^ -(int64_t)(value & 1); }

/* Appends to a growable buffer and remembers an allocation failure, so
 * the encoder checks once per section instead of once per integer. */
typedef struct lks_writer {
    lk__buffer buffer;
    bool failed;
    /* Where the sections of a chunk payload start: the encoder ends a
     * deflate block there, so each section gets its own Huffman codes. */
    size_t section_start[3];
    int section_count;
} lks_writer;

static inline void lks_write_bytes(lks_writer *writer, const void *bytes, size_t size)
{
    if (!writer->failed && !lk__buffer_append(&writer->buffer, bytes, size)) writer->failed = true;
}
static inline void lks_write_varint(lks_writer *writer, uint64_t value)
{
    unsigned char bytes[10];
    size_t length = 0;
    while (value >= 0x80) {
        bytes[length++] = (unsigned char)(value | 0x80);
        value >>= 7;
    }
    bytes[length++] = (unsigned char)value;
    lks_write_bytes(writer, bytes, length);
}
typedef struct lks_reader {
    const unsigned char *data;
    size_t size;
    size_t position;
} lks_reader;

enum { LKS_VARINT_OK = 0, LKS_VARINT_END, LKS_VARINT_OVERFLOW };

static inline int lks_read_varint(lks_reader *reader, uint64_t *out)
{
    uint64_t value = 0;
    for (unsigned shift = 0;; shift += 7) {
        if (reader->position >= reader->size) return LKS_VARINT_END;
        unsigned byte = reader->data[reader->position++];
        /* The tenth byte may only carry bit 63. */
        if (shift == 63 && byte > 1) return LKS_VARINT_OVERFLOW;
        value |= (uint64_t)(byte & 0x7f) << shift;
        if (!(byte & 0x80)) break;
    }
    *out = value;
    return LKS_VARINT_OK;
}

/* ---- error messages ----------------------------------------------------- */

/* Where a chunk lives, for messages such as "chunk 3 at byte 1234: ...". */
typedef struct lks_where {
    size_t chunk;
    uint64_t offset;
} lks_where;

/* Sets "chunk N at byte OFFSET: message" (LK_ERR_PARSE). */
lk_status lk__lks_chunk_error(lk_error *error, const lks_where *where, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* How a varint failed: LKS_VARINT_END or LKS_VARINT_OVERFLOW. */
const char *lk__lks_varint_problem(int code);

/* ---- header and chunk table (stream_format.c) ---------------------------- */

typedef struct lks_header {
    lk_stream_info info;
    size_t splits_per_chunk;
    int32_t quantised_max; /* 2^bits - 1 */
    unsigned flags;        /* version 2: the attributes each vertex carries (LKS2_FLAG_*) */
} lks_header;

/* Largest distance between a position and its dequantised float. */
double lk__lks_quantisation_error(const float min[3], const float step[3], unsigned bits);

static inline float lks_dequantise(float min, float step, int32_t quantised)
{
    /* Evaluated in double and rounded once, so any client (JavaScript
     * included) reproduces the same float. */
    return (float)((double)min + (double)quantised * (double)step);
}

/* Quantisation box over every position a progressive mesh carries, and the
 * bit count: the fewest bits whose error bound stays within 0.01% of the
 * diagonal, unless requested_bits (4..24) is given (stream_encode.c). */
lk_status lk__lks_choose_quantisation(const lk_progressive_mesh *pm, unsigned requested_bits, float min[3],
                                      float step[3], unsigned *bits, lk_error *error);
/* Per-axis steps for `bits` over [min, max] (stream_format.c). */
void lk__lks_steps(const float min[3], const float max[3], unsigned bits, float step[3]);
/* The code of value on the grid min + i * step, clamped to 0..top. */
int32_t lk__lks_quantise(float value, float min, float step, int32_t top);
/* Writes the fixed header (from header->info; version, counts, box), the
 * chunk table (offsets, sizes and CRCs computed here from the stored
 * payloads; raw_size, first_split, split_count and triangle_count as
 * given) and the chunks. Sets info->header_size and total_size. */
lk_status lk__lks_assemble(lks_header *header, lk_stream_chunk_info *chunks, unsigned char *const *stored,
                           const size_t *stored_sizes, unsigned char **bytes, size_t *size, lk_error *error);

/* Parses and checks the fixed header (LKS_FIXED_HEADER_SIZE bytes). */
lk_status lk__lks_parse_header(const unsigned char *bytes, lks_header *header, lk_error *error);
/* Parses and checks the chunk table that follows the fixed header (chunk_count
 * entries and the table's CRC) into `chunks`. */
lk_status lk__lks_parse_table(const unsigned char *table, const lks_header *header, lk_stream_chunk_info *chunks,
                              lk_error *error);

/* ---- decoding core (stream_decode.c; the encoder's self-check runs it) --- */

typedef struct lks_state {
    size_t base_vertex_count;
    size_t present;     /* n = base + level */
    size_t capacity;    /* vertex slots allocated */
    int32_t *quantised; /* 3 * capacity: quantised positions of present vertices */
    uint32_t *head;     /* capacity: first strip position resolving to v, LKS_NONE if none */
    uint32_t *count;    /* capacity: how many strip positions resolve to v */
    size_t strip_length;
    uint32_t *resolved;    /* r: strip_length */
    uint32_t *next;        /* next position with the same resolved vertex, increasing */
    size_t triangles;      /* non-degenerate triangles of r */
    int32_t quantised_max; /* 2^bits - 1 */
    bool has_base;
} lks_state;

/* What a chunk changed, so a chunk that turns out to be corrupt half-way
 * can be taken back and the decoder keeps the level of the chunk before. */
typedef struct lks_undo {
    uint32_t *kept;        /* p of each applied split */
    int32_t *old_position; /* 3 per split: p's position before the split */
    size_t capacity;
} lks_undo;

/* Base strip tokens: 0 and 1 repeat r[j-1] and r[j-2] (collapsed regions
 * repeat vertices), 2..33 name an entry of a move-to-front list of the 32
 * vertices most recently named by a list or literal token, and 34 + zigzag
 * delta from the previous literal names any base vertex. */
#define LKS_TOKEN_RECENT 2u
#define LKS_RECENT_SIZE 32u
#define LKS_TOKEN_LITERAL (LKS_TOKEN_RECENT + LKS_RECENT_SIZE)

typedef struct lks_recent {
    uint32_t vertices[LKS_RECENT_SIZE];
    unsigned size;
} lks_recent;

void lk__lks_state_free(lks_state *state);
void lk__lks_undo_free(lks_undo *undo);
/* Makes room for vertex_count vertices (the state keeps what it holds). */
lk_status lk__lks_state_reserve(lks_state *state, size_t vertex_count, lk_error *error);
/* Moves v to the front of the recent list; returns v's index before the
 * move, or LKS_RECENT_SIZE if it was absent. */
unsigned lk__lks_recent_use(lks_recent *recent, uint32_t v);
/* Decodes the base chunk's payload into a fresh state (replacing *state). */
lk_status lk__lks_decode_base(lks_state *state, const lks_header *header, const unsigned char *payload, size_t size,
                              const lks_where *where, lk_error *error);
/* Moves the entries of p picked by `mask` to the new vertex q = present. */
void lk__lks_split_entries(lks_state *state, uint32_t kept, const unsigned char *mask);
/* Predicted positions of the new vertex q and of the kept vertex p. */
void lk__lks_predict_split(const lks_state *state, uint32_t q, uint32_t kept, int64_t out[3]);
void lk__lks_predict_kept(const lks_state *state, uint32_t kept, int64_t out[3]);
/* Applies the first `limit` splits of a split chunk, or leaves the state as
 * it was; check_triangles compares the count with the table's. */
lk_status lk__lks_apply_chunk(lks_state *state, lks_undo *undo, const unsigned char *payload, size_t size,
                              const lk_stream_chunk_info *chunk, size_t limit, bool check_triangles,
                              const lks_where *where, lk_error *error);

#endif
