/* Progressive stream format (.lks): encoder, inspector and incremental
 * decoder. docs/stream-format.md specifies every byte; this file follows it.
 *
 * The decoder keeps the progressive strip fully resolved: r[j] is the
 * vertex present at the current level that strip entry j stands for. A
 * vertex split k (new vertex q = base + k next to p) rewrites some entries
 * from p to q; which ones is a bitmask over "the entries equal to p, in
 * strip order". To walk those entries without scanning the strip, every
 * present vertex has a list of its entries (head/next arrays threaded
 * through the strip positions, kept in increasing position), so a split
 * costs O(entries of p), the size of its mask.
 *
 * The same decoding core runs inside the encoder on the payloads it has just
 * written: that yields the triangle counts of the chunk table and proves,
 * before any byte leaves the encoder, that the stream decodes back to the
 * progressive strip it was given. */
#include "bytes.h"
#include "internal.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

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
/* Decoder memory budget unless lk_stream_decoder_set_max_bytes says otherwise
 * (the readers' default). */
#define LKS_DEFAULT_MAX_BYTES ((size_t)8 << 30)

static const unsigned char lks_magic[8] = {0x89, 'L', 'K', 'S', '\r', '\n', 0x1a, '\n'};

static uint32_t lks_crc32(const unsigned char *bytes, size_t size)
{
    /* zlib's crc32 takes uInt lengths: feed large buffers in pieces. */
    uLong crc = crc32(0L, Z_NULL, 0);
    while (size > 0) {
        uInt piece = size > (size_t)1 << 30 ? (uInt)1 << 30 : (uInt)size;
        crc = crc32(crc, bytes, piece);
        bytes += piece;
        size -= piece;
    }
    return (uint32_t)crc;
}

/* ---- variable-length integers ----------------------------------------- */

static uint64_t lks_zigzag(int64_t value) { return ((uint64_t)value << 1) ^ (uint64_t)(value >> 63); }
static int64_t lks_unzigzag(uint64_t value) { return (int64_t)(value >> 1) ^ -(int64_t)(value & 1); }

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

static void lks_write_bytes(lks_writer *writer, const void *bytes, size_t size)
{
    if (!writer->failed && !lk__buffer_append(&writer->buffer, bytes, size)) writer->failed = true;
}
static void lks_write_varint(lks_writer *writer, uint64_t value)
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

static int lks_read_varint(lks_reader *reader, uint64_t *out)
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

static lk_status lks_chunk_error(lk_error *error, const lks_where *where, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static lk_status lks_chunk_error(lk_error *error, const lks_where *where, const char *format, ...)
{
    char detail[400];
    va_list args;
    va_start(args, format);
    vsnprintf(detail, sizeof detail, format, args);
    va_end(args);
    return lk_error_set(error, LK_ERR_PARSE, "chunk %zu at byte %llu: %s", where->chunk,
                        (unsigned long long)where->offset, detail);
}

static const char *lks_varint_problem(int code)
{
    return code == LKS_VARINT_END ? "runs past the end of its section" : "is longer than 64 bits";
}

/* ---- header and chunk table ------------------------------------------- */

typedef struct lks_header {
    lk_stream_info info;
    size_t splits_per_chunk;
    int32_t quantised_max; /* 2^bits - 1 */
} lks_header;

/* Largest distance between a position and its dequantised float: half a
 * step per axis, plus half a float ulp from rounding min + q * step to
 * float (bounded by the box's largest magnitude times 2^-24; negligible at
 * the default bits, visible at 24). */
static double lks_quantisation_error(const float min[3], const float step[3], unsigned bits)
{
    double sum = 0, top = (double)((1u << bits) - 1);
    for (int axis = 0; axis < 3; axis++) {
        double magnitude = fmax(fabs((double)min[axis]), fabs((double)min[axis] + top * (double)step[axis]));
        double error = 0.5 * (double)step[axis] + ldexp(magnitude, -24);
        sum += error * error;
    }
    return sqrt(sum);
}

static float lks_dequantise(float min, float step, int32_t quantised)
{
    /* Evaluated in double and rounded once, so any client (JavaScript
     * included) reproduces the same float. */
    return (float)((double)min + (double)quantised * (double)step);
}

/* Parses and checks the fixed header (LKS_FIXED_HEADER_SIZE bytes). */
static lk_status lks_parse_header(const unsigned char *bytes, lks_header *header, lk_error *error)
{
    memset(header, 0, sizeof *header);
    lk_stream_info *info = &header->info;
    if (memcmp(bytes, lks_magic, sizeof lks_magic) != 0)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 0: not a lodkit stream (bad magic)");
    uint32_t stored_crc = lk__load_u32le(bytes + 92);
    uint32_t crc = lks_crc32(bytes, 92);
    info->version = lk__load_u16le(bytes + 8);
    if (info->version != LKS_VERSION)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 8: unsupported version %u (this decoder reads %u)",
                            info->version, LKS_VERSION);
    if (crc != stored_crc)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 92: CRC-32 mismatch (stored %08x, computed %08x)",
                            (unsigned)stored_crc, (unsigned)crc);
    uint32_t flags = lk__load_u16le(bytes + 10);
    if (flags != 0)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 10: unknown flags 0x%04x", (unsigned)flags);
    uint64_t header_size = lk__load_u32le(bytes + 12);
    uint64_t total_size = lk__load_u64le(bytes + 16);
    uint64_t vertex_count = lk__load_u32le(bytes + 24);
    uint64_t triangle_count = lk__load_u32le(bytes + 28);
    uint64_t base_vertex_count = lk__load_u32le(bytes + 32);
    uint64_t base_triangle_count = lk__load_u32le(bytes + 36);
    uint64_t split_count = lk__load_u32le(bytes + 40);
    uint64_t strip_length = lk__load_u32le(bytes + 44);
    uint64_t chunk_count = lk__load_u32le(bytes + 48);
    uint64_t splits_per_chunk = lk__load_u32le(bytes + 52);
    unsigned bits = bytes[56];
    if (bytes[57] || bytes[58] || bytes[59])
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 57: reserved bytes are not zero");

    const struct {
        uint64_t value;
        unsigned offset;
        const char *name;
    } counts[] = {{vertex_count, 24, "vertex count"},       {triangle_count, 28, "triangle count"},
                  {base_vertex_count, 32, "base vertex count"}, {base_triangle_count, 36, "base triangle count"},
                  {split_count, 40, "split count"},         {strip_length, 44, "strip length"}};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++)
        if (counts[i].value > LK_MAX_ELEMENTS)
            return lk_error_set(error, LK_ERR_PARSE, "header at byte %u: %s %llu is more than lodkit supports (%zu)",
                                counts[i].offset, counts[i].name, (unsigned long long)counts[i].value,
                                (size_t)LK_MAX_ELEMENTS);
    if (vertex_count != base_vertex_count + split_count)
        return lk_error_set(error, LK_ERR_PARSE,
                            "header at byte 24: vertex count %llu is not base %llu + splits %llu",
                            (unsigned long long)vertex_count, (unsigned long long)base_vertex_count,
                            (unsigned long long)split_count);
    uint64_t most_triangles = strip_length >= 2 ? strip_length - 2 : 0;
    if (triangle_count > most_triangles)
        return lk_error_set(error, LK_ERR_PARSE,
                            "header at byte 28: %llu triangles cannot come from a strip of %llu entries",
                            (unsigned long long)triangle_count, (unsigned long long)strip_length);
    if (base_triangle_count > triangle_count)
        return lk_error_set(error, LK_ERR_PARSE,
                            "header at byte 36: base triangle count %llu exceeds the full count %llu",
                            (unsigned long long)base_triangle_count, (unsigned long long)triangle_count);
    if (bits < 4 || bits > 24)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 56: position bits %u outside 4..24", bits);
    if (chunk_count < 1)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 48: no chunks (the base chunk is required)");
    uint64_t expected_header_size =
        LKS_FIXED_HEADER_SIZE + chunk_count * LKS_TABLE_ENTRY_SIZE + LKS_TABLE_CRC_SIZE;
    if (header_size != expected_header_size)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 12: header size %llu, expected %llu for %llu chunks",
                            (unsigned long long)header_size, (unsigned long long)expected_header_size,
                            (unsigned long long)chunk_count);
    if (total_size < header_size + chunk_count * (LKS_CHUNK_HEADER_SIZE + 1))
        return lk_error_set(error, LK_ERR_PARSE,
                            "header at byte 16: total size %llu cannot hold the header and %llu chunks",
                            (unsigned long long)total_size, (unsigned long long)chunk_count);
    if (total_size > SIZE_MAX)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 16: total size %llu does not fit in memory",
                            (unsigned long long)total_size);
    /* Every split needs LKS_MIN_SPLIT_BYTES raw bytes and every strip entry
     * one, and no payload inflates more than LKS_MAX_DEFLATE_RATIO times. */
    uint64_t raw_capacity =
        total_size > UINT64_MAX / LKS_MAX_DEFLATE_RATIO ? UINT64_MAX : total_size * LKS_MAX_DEFLATE_RATIO;
    if (split_count * LKS_MIN_SPLIT_BYTES > raw_capacity || strip_length > raw_capacity ||
        base_vertex_count * 3 > raw_capacity)
        return lk_error_set(error, LK_ERR_PARSE,
                            "header at byte 32: %llu base vertices, %llu splits and a strip of %llu entries "
                            "cannot fit in a stream of %llu bytes",
                            (unsigned long long)base_vertex_count, (unsigned long long)split_count,
                            (unsigned long long)strip_length, (unsigned long long)total_size);

    for (int axis = 0; axis < 3; axis++) {
        info->quantisation_min[axis] = lk__load_f32le(bytes + 60 + 4 * axis);
        info->quantisation_step[axis] = lk__load_f32le(bytes + 72 + 4 * axis);
        float min = info->quantisation_min[axis], step = info->quantisation_step[axis];
        double top = (double)min + (double)((1u << bits) - 1) * (double)step;
        if (!isfinite(min) || !isfinite(step) || step < 0 || !(fabs(top) <= FLT_MAX))
            return lk_error_set(error, LK_ERR_PARSE,
                                "header at byte %d: quantisation box of axis %d (min %g, step %g) is not finite",
                                60 + 4 * axis, axis, (double)min, (double)step);
    }
    info->diagonal = lk__load_f64le(bytes + 84);
    if (!isfinite(info->diagonal) || info->diagonal < 0)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 84: diagonal %g is not a finite length",
                            info->diagonal);

    info->vertex_count = (size_t)vertex_count;
    info->triangle_count = (size_t)triangle_count;
    info->base_vertex_count = (size_t)base_vertex_count;
    info->base_triangle_count = (size_t)base_triangle_count;
    info->split_count = (size_t)split_count;
    info->strip_length = (size_t)strip_length;
    info->position_bits = bits;
    info->quantisation_error = lks_quantisation_error(info->quantisation_min, info->quantisation_step, bits);
    info->chunk_count = (size_t)chunk_count;
    info->header_size = (size_t)header_size;
    info->total_size = (size_t)total_size;
    header->splits_per_chunk = (size_t)splits_per_chunk;
    header->quantised_max = (int32_t)((1u << bits) - 1);
    return LK_OK;
}

/* Parses and checks the chunk table (the bytes after the fixed header,
 * CRC included) into chunks[chunk_count]. */
static lk_status lks_parse_table(const unsigned char *table, const lks_header *header, lk_stream_chunk_info *chunks,
                                 lk_error *error)
{
    const lk_stream_info *info = &header->info;
    size_t table_size = info->chunk_count * LKS_TABLE_ENTRY_SIZE;
    uint32_t stored_crc = lk__load_u32le(table + table_size);
    uint32_t crc = lks_crc32(table, table_size);
    if (crc != stored_crc)
        return lk_error_set(error, LK_ERR_PARSE,
                            "chunk table at byte %zu: CRC-32 mismatch (stored %08x, computed %08x)",
                            (size_t)LKS_FIXED_HEADER_SIZE + table_size, (unsigned)stored_crc, (unsigned)crc);
    uint64_t expected_offset = info->header_size;
    uint64_t splits_so_far = 0;
    uint64_t triangles_before = 0;
    for (size_t i = 0; i < info->chunk_count; i++) {
        const unsigned char *entry = table + i * LKS_TABLE_ENTRY_SIZE;
        size_t where = LKS_FIXED_HEADER_SIZE + i * LKS_TABLE_ENTRY_SIZE;
        lk_stream_chunk_info *chunk = &chunks[i];
        memset(chunk, 0, sizeof *chunk);
        chunk->offset = lk__load_u64le(entry);
        chunk->size = lk__load_u32le(entry + 8);
        chunk->raw_size = lk__load_u32le(entry + 12);
        chunk->first_split = lk__load_u32le(entry + 16);
        chunk->split_count = lk__load_u32le(entry + 20);
        chunk->triangle_count = lk__load_u32le(entry + 24);
        chunk->crc32 = lk__load_u32le(entry + 28);
        chunk->is_base = i == 0;
        if (chunk->offset != expected_offset)
            return lk_error_set(error, LK_ERR_PARSE,
                                "chunk table entry %zu at byte %zu: offset %llu, expected %llu (chunks must follow "
                                "each other without gaps or overlaps)",
                                i, where, (unsigned long long)chunk->offset, (unsigned long long)expected_offset);
        if (chunk->size <= LKS_CHUNK_HEADER_SIZE || chunk->size > info->total_size - chunk->offset)
            return lk_error_set(error, LK_ERR_PARSE,
                                "chunk table entry %zu at byte %zu: size %u at offset %llu does not fit in the "
                                "stream of %zu bytes",
                                i, where + 8, (unsigned)chunk->size, (unsigned long long)chunk->offset,
                                info->total_size);
        uint64_t stored = chunk->size - LKS_CHUNK_HEADER_SIZE;
        if (chunk->raw_size < stored || chunk->raw_size > stored * LKS_MAX_DEFLATE_RATIO)
            return lk_error_set(error, LK_ERR_PARSE,
                                "chunk table entry %zu at byte %zu: raw size %u is impossible for %llu stored bytes",
                                i, where + 12, (unsigned)chunk->raw_size, (unsigned long long)stored);
        chunk->compressed = chunk->raw_size > stored;
        if (i == 0) {
            if (chunk->first_split != 0 || chunk->split_count != 0)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry 0 at byte %zu: the base chunk claims splits", where + 16);
            if (chunk->triangle_count != info->base_triangle_count)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry 0 at byte %zu: %u triangles, the header says %zu", where + 24,
                                    (unsigned)chunk->triangle_count, info->base_triangle_count);
            if ((uint64_t)info->strip_length + 3 * (uint64_t)info->base_vertex_count > chunk->raw_size)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry 0 at byte %zu: raw size %u cannot hold %zu base vertices and a "
                                    "strip of %zu entries",
                                    where + 12, (unsigned)chunk->raw_size, info->base_vertex_count,
                                    info->strip_length);
        } else {
            if (chunk->first_split != splits_so_far)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry %zu at byte %zu: first split %u, expected %llu", i, where + 16,
                                    (unsigned)chunk->first_split, (unsigned long long)splits_so_far);
            if (chunk->split_count == 0 || chunk->split_count > info->split_count - splits_so_far)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry %zu at byte %zu: %u splits, but %llu of %zu remain", i,
                                    where + 20, (unsigned)chunk->split_count,
                                    (unsigned long long)(info->split_count - splits_so_far), info->split_count);
            if ((uint64_t)chunk->split_count * LKS_MIN_SPLIT_BYTES > chunk->raw_size)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry %zu at byte %zu: raw size %u cannot hold %u splits", i,
                                    where + 12, (unsigned)chunk->raw_size, (unsigned)chunk->split_count);
            if (chunk->triangle_count < triangles_before || chunk->triangle_count > info->triangle_count)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry %zu at byte %zu: %u triangles is outside %llu..%zu (splits never "
                                    "remove triangles)",
                                    i, where + 24, (unsigned)chunk->triangle_count,
                                    (unsigned long long)triangles_before, info->triangle_count);
        }
        splits_so_far += chunk->split_count;
        triangles_before = chunk->triangle_count;
        expected_offset = chunk->offset + chunk->size;
    }
    size_t last_where = LKS_FIXED_HEADER_SIZE + (info->chunk_count - 1) * LKS_TABLE_ENTRY_SIZE;
    if (expected_offset != info->total_size)
        return lk_error_set(error, LK_ERR_PARSE,
                            "chunk table entry %zu at byte %zu: chunks end at byte %llu but the stream has %zu",
                            info->chunk_count - 1, last_where, (unsigned long long)expected_offset, info->total_size);
    if (splits_so_far != info->split_count)
        return lk_error_set(error, LK_ERR_PARSE, "chunk table entry %zu at byte %zu: chunks hold %llu splits, not %zu",
                            info->chunk_count - 1, last_where + 20, (unsigned long long)splits_so_far,
                            info->split_count);
    if (triangles_before != info->triangle_count)
        return lk_error_set(error, LK_ERR_PARSE,
                            "chunk table entry %zu at byte %zu: the last chunk ends with %llu triangles, not %zu",
                            info->chunk_count - 1, last_where + 24, (unsigned long long)triangles_before,
                            info->triangle_count);
    return LK_OK;
}

/* ---- decoding core (shared by the decoder and the encoder's self-check) -- */

typedef struct lks_state {
    size_t base_vertex_count;
    size_t present;        /* n = base + level */
    size_t capacity;       /* vertex slots allocated */
    int32_t *quantised;    /* 3 * capacity: quantised positions of present vertices */
    uint32_t *head;        /* capacity: first strip position resolving to v, LKS_NONE if none */
    uint32_t *count;       /* capacity: how many strip positions resolve to v */
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

static void lks_state_free(lks_state *state)
{
    free(state->quantised);
    free(state->head);
    free(state->count);
    free(state->resolved);
    free(state->next);
    memset(state, 0, sizeof *state);
}

static void lks_undo_free(lks_undo *undo)
{
    free(undo->kept);
    free(undo->old_position);
    memset(undo, 0, sizeof *undo);
}

static lk_status lks_state_reserve(lks_state *state, size_t vertex_count, lk_error *error)
{
    if (vertex_count <= state->capacity) return LK_OK;
    int32_t *quantised = lk__realloc_array(state->quantised, vertex_count, 3 * sizeof(int32_t));
    if (quantised) state->quantised = quantised;
    uint32_t *head = lk__realloc_array(state->head, vertex_count, sizeof(uint32_t));
    if (head) state->head = head;
    uint32_t *count = lk__realloc_array(state->count, vertex_count, sizeof(uint32_t));
    if (count) state->count = count;
    /* A failed realloc leaves the old (still valid, smaller) array. */
    if (!quantised || !head || !count)
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu stream vertices", vertex_count);
    state->capacity = vertex_count;
    return LK_OK;
}

static lk_status lks_undo_reserve(lks_undo *undo, size_t split_count, lk_error *error)
{
    if (split_count <= undo->capacity) return LK_OK;
    uint32_t *kept = lk__realloc_array(undo->kept, split_count, sizeof(uint32_t));
    if (kept) undo->kept = kept;
    int32_t *old_position = lk__realloc_array(undo->old_position, split_count, 3 * sizeof(int32_t));
    if (old_position) undo->old_position = old_position;
    if (!kept || !old_position)
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu splits", split_count);
    undo->capacity = split_count;
    return LK_OK;
}

static inline bool lks_triangle_drawn(const uint32_t *r, size_t t)
{
    return r[t] != r[t + 1] && r[t + 1] != r[t + 2] && r[t] != r[t + 2];
}

/* Sets r[j] = value and keeps the non-degenerate triangle count exact by
 * re-evaluating the (up to three) triangles that use entry j. */
static inline void lks_set_entry(lks_state *state, size_t j, uint32_t value)
{
    uint32_t *r = state->resolved;
    if (state->strip_length < 3) {
        r[j] = value;
        return;
    }
    size_t first = j >= 2 ? j - 2 : 0;
    size_t last = j < state->strip_length - 3 ? j : state->strip_length - 3;
    size_t before = 0, after = 0;
    for (size_t t = first; t <= last; t++) before += lks_triangle_drawn(r, t);
    r[j] = value;
    for (size_t t = first; t <= last; t++) after += lks_triangle_drawn(r, t);
    state->triangles = state->triangles - before + after;
}

static size_t lks_count_triangles(const uint32_t *r, size_t length)
{
    size_t triangles = 0;
    for (size_t t = 0; t + 2 < length; t++) triangles += lks_triangle_drawn(r, t);
    return triangles;
}

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

/* Moves v to the front (inserting it, and dropping the oldest entry when
 * full); returns v's index before the move, or LKS_RECENT_SIZE if absent. */
static unsigned lks_recent_use(lks_recent *recent, uint32_t v)
{
    unsigned index = 0;
    while (index < recent->size && recent->vertices[index] != v) index++;
    unsigned found = index < recent->size ? index : LKS_RECENT_SIZE;
    if (index == recent->size) {
        if (recent->size < LKS_RECENT_SIZE) recent->size++;
        index = recent->size - 1;
    }
    memmove(&recent->vertices[1], &recent->vertices[0], index * sizeof(uint32_t));
    recent->vertices[0] = v;
    return found;
}

/* Base chunk payload: varint position_bytes, positions (3 zigzag deltas per
 * base vertex from the previous one), strip tokens (the rest). */
static lk_status lks_decode_base(lks_state *state, const lks_header *header, const unsigned char *payload,
                                 size_t size, const lks_where *where, lk_error *error)
{
    const lk_stream_info *info = &header->info;
    size_t base = info->base_vertex_count, length = info->strip_length;
    lks_reader reader = {payload, size, 0};
    uint64_t position_bytes;
    int code = lks_read_varint(&reader, &position_bytes);
    if (code != LKS_VARINT_OK)
        return lks_chunk_error(error, where, "position section length %s", lks_varint_problem(code));
    if (position_bytes > size - reader.position)
        return lks_chunk_error(error, where, "position section of %llu bytes overruns the payload of %zu",
                               (unsigned long long)position_bytes, size);
    lks_reader positions = {payload, reader.position + (size_t)position_bytes, reader.position};
    lks_reader tokens = {payload, size, positions.size};
    if (3 * (uint64_t)base > position_bytes)
        return lks_chunk_error(error, where, "%zu base vertices cannot fit in %llu position bytes", base,
                               (unsigned long long)position_bytes);
    if (length > size - tokens.position)
        return lks_chunk_error(error, where, "a strip of %zu entries cannot fit in %zu token bytes", length,
                               size - tokens.position);

    lks_state fresh = {0};
    fresh.base_vertex_count = base;
    fresh.quantised_max = header->quantised_max;
    fresh.strip_length = length;
    lk_status status = lks_state_reserve(&fresh, base, error);
    if (status != LK_OK) {
        lks_state_free(&fresh);
        return status;
    }
    fresh.resolved = lk__malloc_array(length, sizeof(uint32_t));
    fresh.next = lk__malloc_array(length, sizeof(uint32_t));
    if (!fresh.resolved || !fresh.next) {
        lks_state_free(&fresh);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a strip of %zu entries", length);
    }

    int64_t previous[3] = {0, 0, 0};
    for (size_t v = 0; v < base; v++) {
        for (int axis = 0; axis < 3; axis++) {
            uint64_t raw;
            size_t at = positions.position;
            code = lks_read_varint(&positions, &raw);
            if (code != LKS_VARINT_OK) {
                lks_state_free(&fresh);
                return lks_chunk_error(error, where, "base vertex %zu: position varint at payload byte %zu %s", v, at,
                                       lks_varint_problem(code));
            }
            int64_t delta = lks_unzigzag(raw);
            if (delta < -(int64_t)header->quantised_max || delta > (int64_t)header->quantised_max ||
                previous[axis] + delta < 0 || previous[axis] + delta > header->quantised_max) {
                lks_state_free(&fresh);
                return lks_chunk_error(error, where,
                                       "base vertex %zu: delta %lld at payload byte %zu leaves the quantisation "
                                       "range 0..%d",
                                       v, (long long)delta, at, (int)header->quantised_max);
            }
            previous[axis] += delta;
            fresh.quantised[3 * v + axis] = (int32_t)previous[axis];
        }
    }
    if (positions.position != positions.size) {
        lks_state_free(&fresh);
        return lks_chunk_error(error, where, "%zu unused bytes at the end of the base position section",
                               positions.size - positions.position);
    }

    int64_t literal = 0;
    lks_recent recent = {{0}, 0};
    for (size_t j = 0; j < length; j++) {
        uint64_t token;
        size_t at = tokens.position;
        code = lks_read_varint(&tokens, &token);
        if (code != LKS_VARINT_OK) {
            lks_state_free(&fresh);
            return lks_chunk_error(error, where, "strip entry %zu: token at payload byte %zu %s", j, at,
                                   lks_varint_problem(code));
        }
        uint32_t value;
        if (token < LKS_TOKEN_RECENT) {
            if (j < token + 1) {
                lks_state_free(&fresh);
                return lks_chunk_error(error, where,
                                       "strip entry %zu: token at payload byte %zu repeats an entry before the strip",
                                       j, at);
            }
            value = fresh.resolved[j - 1 - token];
        } else if (token < LKS_TOKEN_LITERAL) {
            if (token - LKS_TOKEN_RECENT >= recent.size) {
                lks_state_free(&fresh);
                return lks_chunk_error(error, where,
                                       "strip entry %zu: token at payload byte %zu names recent vertex %u of %u", j, at,
                                       (unsigned)(token - LKS_TOKEN_RECENT), recent.size);
            }
            value = recent.vertices[token - LKS_TOKEN_RECENT];
            lks_recent_use(&recent, value);
        } else {
            int64_t delta = lks_unzigzag(token - LKS_TOKEN_LITERAL);
            if (delta < -(int64_t)base || delta > (int64_t)base || literal + delta < 0 ||
                literal + delta >= (int64_t)base) {
                lks_state_free(&fresh);
                return lks_chunk_error(error, where,
                                       "strip entry %zu: vertex %lld at payload byte %zu is not a base vertex (%zu)",
                                       j, (long long)(literal + delta), at, base);
            }
            literal += delta;
            value = (uint32_t)literal;
            lks_recent_use(&recent, value);
        }
        fresh.resolved[j] = value;
    }
    if (tokens.position != tokens.size) {
        lks_state_free(&fresh);
        return lks_chunk_error(error, where, "%zu unused bytes after the base strip", tokens.size - tokens.position);
    }

    for (size_t v = 0; v < base; v++) {
        fresh.head[v] = LKS_NONE;
        fresh.count[v] = 0;
    }
    for (size_t j = length; j-- > 0;) {
        uint32_t v = fresh.resolved[j];
        fresh.next[j] = fresh.head[v];
        fresh.head[v] = (uint32_t)j;
        fresh.count[v]++;
    }
    fresh.triangles = lks_count_triangles(fresh.resolved, length);
    fresh.present = base;
    fresh.has_base = true;
    lks_state_free(state);
    *state = fresh;
    return LK_OK;
}

/* Takes back the last applied split (q = present - 1): its entries return
 * to p's list, merged by strip position, and p gets its old position. */
static void lks_undo_split(lks_state *state, uint32_t kept, const int32_t old_position[3])
{
    uint32_t q = (uint32_t)(state->present - 1);
    uint32_t a = state->head[kept], b = state->head[q];
    uint32_t *tail = &state->head[kept];
    while (a != LKS_NONE || b != LKS_NONE) {
        if (b == LKS_NONE || (a != LKS_NONE && a < b)) {
            *tail = a;
            tail = &state->next[a];
            a = state->next[a];
        } else {
            *tail = b;
            tail = &state->next[b];
            uint32_t following = state->next[b];
            lks_set_entry(state, b, kept);
            b = following;
        }
    }
    *tail = LKS_NONE;
    state->count[kept] += state->count[q];
    state->count[q] = 0;
    state->head[q] = LKS_NONE;
    memcpy(&state->quantised[3 * (size_t)kept], old_position, 3 * sizeof(int32_t));
    state->present--;
}

static void lks_rollback(lks_state *state, const lks_undo *undo, size_t applied)
{
    for (size_t i = applied; i-- > 0;) lks_undo_split(state, undo->kept[i], &undo->old_position[3 * i]);
}

/* Moves the entries of p picked by `mask` (bit i, least significant first,
 * stands for the i-th entry of p's list) to the new vertex q = present, and
 * makes q present. Both lists stay in increasing strip position. */
static void lks_split_entries(lks_state *state, uint32_t kept, const unsigned char *mask)
{
    uint32_t q = (uint32_t)state->present;
    size_t candidates = state->count[kept];
    uint32_t *p_tail = &state->head[kept];
    uint32_t *q_tail = &state->head[q];
    uint32_t entry = state->head[kept];
    size_t moved_entries = 0;
    for (size_t bit = 0; bit < candidates; bit++) {
        uint32_t following = state->next[entry];
        if ((mask[bit >> 3] >> (bit & 7)) & 1) {
            *q_tail = entry;
            q_tail = &state->next[entry];
            lks_set_entry(state, entry, q);
            moved_entries++;
        } else {
            *p_tail = entry;
            p_tail = &state->next[entry];
        }
        entry = following;
    }
    *p_tail = LKS_NONE;
    *q_tail = LKS_NONE;
    state->count[kept] = (uint32_t)(candidates - moved_entries);
    state->count[q] = (uint32_t)moved_entries;
    state->present++;
}

/* Mean of the other two corners of every triangle the strip draws around
 * v (so each neighbour counts once per shared triangle), rounded half up;
 * `fallback` when v draws no triangle. Positions are never negative, so
 * integer division is floor division here and in any other decoder. */
static void lks_ring_centroid(const lks_state *state, uint32_t v, const int32_t fallback[3], int64_t out[3])
{
    int64_t sum[3] = {0, 0, 0};
    int64_t corners = 0;
    size_t length = state->strip_length;
    const uint32_t *r = state->resolved;
    if (length >= 3) {
        for (uint32_t j = state->head[v]; j != LKS_NONE; j = state->next[j]) {
            size_t first = j >= 2 ? j - 2 : 0;
            size_t last = j < length - 3 ? j : length - 3;
            for (size_t t = first; t <= last; t++) {
                if (!lks_triangle_drawn(r, t)) continue;
                for (size_t corner = t; corner < t + 3; corner++) {
                    if (r[corner] == v) continue;
                    const int32_t *position = &state->quantised[3 * (size_t)r[corner]];
                    for (int axis = 0; axis < 3; axis++) sum[axis] += position[axis];
                    corners++;
                }
            }
        }
    }
    for (int axis = 0; axis < 3; axis++)
        out[axis] = corners ? (2 * sum[axis] + corners) / (2 * corners) : fallback[axis];
}

/* Predictions of the two positions a split carries (docs/stream-format.md
 * has the measurements behind them). q: (3 ring(q) + p) / 4, with p still
 * at its position before the split; p: (3 p + ring(p)) / 4, once q has its
 * position. The ring centroid predicts a vertex of a smooth surface well;
 * leaning towards p helps on coarse, irregular meshes. */
static void lks_predict_split(const lks_state *state, uint32_t q, uint32_t kept, int64_t out[3])
{
    const int32_t *current = &state->quantised[3 * (size_t)kept];
    int64_t ring[3];
    lks_ring_centroid(state, q, current, ring);
    for (int axis = 0; axis < 3; axis++) out[axis] = (3 * ring[axis] + current[axis] + 2) / 4;
}

static void lks_predict_kept(const lks_state *state, uint32_t kept, int64_t out[3])
{
    const int32_t *current = &state->quantised[3 * (size_t)kept];
    int64_t ring[3];
    lks_ring_centroid(state, kept, current, ring);
    for (int axis = 0; axis < 3; axis++) out[axis] = (3 * (int64_t)current[axis] + ring[axis] + 2) / 4;
}

/* Reads three zigzag deltas against `predicted` into `position`, refusing
 * anything outside the quantisation range. */
static lk_status lks_read_position(lks_reader *reader, const int64_t predicted[3], int32_t top, int32_t position[3],
                                   size_t split, const char *what, const lks_where *where, lk_error *error)
{
    for (int axis = 0; axis < 3; axis++) {
        uint64_t raw;
        size_t at = reader->position;
        int code = lks_read_varint(reader, &raw);
        if (code != LKS_VARINT_OK)
            return lks_chunk_error(error, where, "split %zu: %s position varint at payload byte %zu %s", split, what, at,
                                   lks_varint_problem(code));
        int64_t delta = lks_unzigzag(raw);
        if (delta < -(int64_t)top || delta > (int64_t)top || predicted[axis] + delta < 0 ||
            predicted[axis] + delta > top)
            return lks_chunk_error(error, where,
                                   "split %zu: %s position delta %lld at payload byte %zu leaves the quantisation range "
                                   "0..%d",
                                   split, what, (long long)delta, at, (int)top);
        position[axis] = (int32_t)(predicted[axis] + delta);
    }
    return LK_OK;
}

/* Split chunk payload: varint p_bytes, varint mask_bytes, then the p
 * section, the mask section and the position section (the rest). Applies
 * up to `limit` of the chunk's split_count splits, recording each in undo
 * (reserved by the caller for `limit` splits; state reserved for
 * present + limit vertices). On failure the caller rolls back *applied
 * splits (the last one possibly without its positions). */
static lk_status lks_apply_splits(lks_state *state, const unsigned char *payload, size_t size, size_t split_count,
                                  size_t limit, lks_undo *undo, size_t *applied, const lks_where *where,
                                  lk_error *error)
{
    *applied = 0;
    lks_reader reader = {payload, size, 0};
    uint64_t p_bytes, mask_bytes;
    int code = lks_read_varint(&reader, &p_bytes);
    if (code == LKS_VARINT_OK) code = lks_read_varint(&reader, &mask_bytes);
    if (code != LKS_VARINT_OK)
        return lks_chunk_error(error, where, "section length %s", lks_varint_problem(code));
    size_t rest = size - reader.position;
    if (p_bytes > rest || mask_bytes > rest - p_bytes)
        return lks_chunk_error(error, where, "sections of %llu + %llu bytes overrun the payload of %zu bytes",
                               (unsigned long long)p_bytes, (unsigned long long)mask_bytes, size);
    lks_reader kept_reader = {payload, reader.position + (size_t)p_bytes, reader.position};
    lks_reader mask_reader = {payload, kept_reader.size + (size_t)mask_bytes, kept_reader.size};
    lks_reader position_reader = {payload, size, mask_reader.size};
    size_t level_before = state->present - state->base_vertex_count;

    for (size_t i = 0; i < limit; i++) {
        size_t split = level_before + i;
        size_t at = kept_reader.position;
        uint64_t kept_code;
        code = lks_read_varint(&kept_reader, &kept_code);
        if (code != LKS_VARINT_OK)
            return lks_chunk_error(error, where, "split %zu: p varint at payload byte %zu %s", split, at,
                                   lks_varint_problem(code));
        uint64_t kept64 = kept_code >> 1;
        bool moved = kept_code & 1;
        if (kept64 >= state->present)
            return lks_chunk_error(error, where,
                                   "split %zu: p = %llu at payload byte %zu is not a present vertex (%zu present)",
                                   split, (unsigned long long)kept64, at, state->present);
        uint32_t kept = (uint32_t)kept64;
        size_t candidates = state->count[kept];
        size_t mask_length = (candidates + 7) / 8;
        const unsigned char *mask = payload + mask_reader.position;
        if (mask_length > mask_reader.size - mask_reader.position)
            return lks_chunk_error(error, where,
                                   "split %zu: a mask of %zu bits at payload byte %zu runs past the mask section", split,
                                   candidates, mask_reader.position);
        if ((candidates & 7) && (mask[mask_length - 1] >> (candidates & 7)))
            return lks_chunk_error(error, where, "split %zu: padding bits of the mask at payload byte %zu are not zero",
                                   split, mask_reader.position + mask_length - 1);
        mask_reader.position += mask_length;

        /* The entries move first: q's predicted position needs its triangles.
         * From here on the split is in the undo log. */
        uint32_t q = (uint32_t)state->present;
        undo->kept[i] = kept;
        memcpy(&undo->old_position[3 * i], &state->quantised[3 * (size_t)kept], 3 * sizeof(int32_t));
        lks_split_entries(state, kept, mask);
        *applied = i + 1;

        int64_t predicted[3];
        int32_t position[3];
        lks_predict_split(state, q, kept, predicted);
        lk_status status = lks_read_position(&position_reader, predicted, state->quantised_max, position, split, "q",
                                             where, error);
        if (status != LK_OK) return status;
        memcpy(&state->quantised[3 * (size_t)q], position, sizeof position);
        if (moved) {
            lks_predict_kept(state, kept, predicted);
            status = lks_read_position(&position_reader, predicted, state->quantised_max, position, split, "p", where,
                                       error);
            if (status != LK_OK) return status;
            memcpy(&state->quantised[3 * (size_t)kept], position, sizeof position);
        }
    }
    if (limit == split_count) {
        if (kept_reader.position != kept_reader.size || mask_reader.position != mask_reader.size ||
            position_reader.position != position_reader.size)
            return lks_chunk_error(error, where,
                                   "unused bytes after the last split (p section %zu, mask section %zu, position "
                                   "section %zu)",
                                   kept_reader.size - kept_reader.position, mask_reader.size - mask_reader.position,
                                   position_reader.size - position_reader.position);
    }
    return LK_OK;
}

/* Applies one split chunk whole, or leaves the state as it was. `limit`
 * (<= split_count) stops early for max_level; the triangle count is
 * checked against the table when asked and the chunk was applied to its
 * end (the encoder asks the other way round: it fills the table). */
static lk_status lks_apply_chunk(lks_state *state, lks_undo *undo, const unsigned char *payload, size_t size,
                                 const lk_stream_chunk_info *chunk, size_t limit, bool check_triangles,
                                 const lks_where *where, lk_error *error)
{
    if (state->present - state->base_vertex_count != chunk->first_split)
        return lks_chunk_error(error, where, "starts at split %u but the decoder is at level %zu",
                               (unsigned)chunk->first_split, state->present - state->base_vertex_count);
    lk_status status = lks_state_reserve(state, state->present + limit, error);
    if (status == LK_OK) status = lks_undo_reserve(undo, limit, error);
    if (status != LK_OK) return status;
    size_t triangles_before = state->triangles;
    size_t applied = 0;
    status = lks_apply_splits(state, payload, size, chunk->split_count, limit, undo, &applied, where, error);
    if (status == LK_OK && check_triangles && limit == chunk->split_count &&
        state->triangles != chunk->triangle_count)
        status = lks_chunk_error(error, where, "the strip draws %zu triangles after the chunk, the table says %u",
                                 state->triangles, (unsigned)chunk->triangle_count);
    if (status != LK_OK) {
        lks_rollback(state, undo, applied);
        state->triangles = triangles_before;
    }
    return status;
}

/* Checks a chunk's header and CRC and hands back its raw payload: either a
 * pointer into `bytes` or, for a deflated one, *inflated (malloc'ed). */
static lk_status lks_open_chunk(const unsigned char *bytes, const lk_stream_chunk_info *chunk, const lks_where *where,
                                const unsigned char **payload, unsigned char **inflated, lk_error *error)
{
    *inflated = NULL;
    size_t stored = chunk->size - LKS_CHUNK_HEADER_SIZE;
    uint32_t header_stored = lk__load_u32le(bytes), header_crc = lk__load_u32le(bytes + 4);
    if (header_stored != stored || header_crc != chunk->crc32)
        return lks_chunk_error(error, where,
                               "chunk header (payload %u bytes, CRC %08x) disagrees with the table (%zu bytes, CRC "
                               "%08x)",
                               (unsigned)header_stored, (unsigned)header_crc, stored, (unsigned)chunk->crc32);
    const unsigned char *data = bytes + LKS_CHUNK_HEADER_SIZE;
    uint32_t crc = lks_crc32(data, stored);
    if (crc != chunk->crc32)
        return lks_chunk_error(error, where, "CRC-32 mismatch (stored %08x, computed %08x)", (unsigned)chunk->crc32,
                               (unsigned)crc);
    if (!chunk->compressed) {
        *payload = data;
        return LK_OK;
    }
    unsigned char *raw = malloc(chunk->raw_size ? chunk->raw_size : 1);
    if (!raw) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a chunk of %u bytes", (unsigned)chunk->raw_size);
    uLongf raw_length = chunk->raw_size;
    uLong source_length = (uLong)stored;
    int result = uncompress2(raw, &raw_length, data, &source_length);
    if (result != Z_OK || raw_length != chunk->raw_size || source_length != stored) {
        free(raw);
        return lks_chunk_error(error, where,
                               "deflated payload is corrupt (zlib: %s; inflated %lu of %u bytes from %lu of %zu)",
                               result == Z_OK ? "ok" : zError(result), (unsigned long)raw_length,
                               (unsigned)chunk->raw_size, (unsigned long)source_length, stored);
    }
    *payload = raw;
    *inflated = raw;
    return LK_OK;
}

/* ---- encoder -------------------------------------------------------------- */

void lk_stream_options_default(lk_stream_options *options)
{
    memset(options, 0, sizeof *options);
    options->position_bits = 0;
    options->splits_per_chunk = 1024;
    options->compress = 1;
}

/* Per-axis steps for `bits` over [min, max]: extent / (2^bits - 1), rounded
 * up as floats until the top code reaches max, so every position quantises
 * without clamping and stays within half a step per axis. */
static void lks_steps(const float min[3], const float max[3], unsigned bits, float step[3])
{
    double top = (double)((1u << bits) - 1);
    for (int axis = 0; axis < 3; axis++) {
        double extent = (double)max[axis] - (double)min[axis];
        float value = (float)(extent / top);
        /* Round up until the top code reaches max, but never past FLT_MAX:
         * a box that ends at (or within a step of) the float limit keeps
         * the last step whose top code is still a float (decoders refuse
         * boxes that are not); lks_quantise clamps codes to top, so such a
         * box's extreme points move by less than one step. */
        while (value > 0 && !((double)min[axis] + top * (double)value <= FLT_MAX))
            value = nextafterf(value, 0);  /* extent / top rounded up past the limit */
        while ((double)min[axis] + top * (double)value < (double)max[axis]) {
            float next = nextafterf(value, INFINITY);
            if (!((double)min[axis] + top * (double)next <= FLT_MAX)) break;
            value = next;
        }
        step[axis] = value;
    }
}

static int32_t lks_quantise(float value, float min, float step, int32_t top)
{
    if (!(step > 0)) return 0;
    double code = nearbyint(((double)value - (double)min) / (double)step);
    if (code < 0) code = 0;
    if (code > top) code = top;
    return (int32_t)code;
}

typedef struct lks_encoding {
    size_t base, splits, vertex_count, length;
    int32_t top;
    int32_t *base_quantised;   /* 3 * base */
    int32_t *split_quantised;  /* 3 * splits: q's position */
    int32_t *kept_quantised;   /* 3 * splits: p's position after the split */
    uint32_t *resolved;        /* the base-level strip r_0 */
    lk__buffer masks;          /* mask bytes, collapse order */
    size_t *mask_offset;       /* splits: where split k's mask starts in masks */
    uint32_t *mask_bits;       /* splits: candidates of split k */
} lks_encoding;

static void lks_encoding_free(lks_encoding *encoding)
{
    free(encoding->base_quantised);
    free(encoding->split_quantised);
    free(encoding->kept_quantised);
    free(encoding->resolved);
    lk__buffer_free(&encoding->masks);
    free(encoding->mask_offset);
    free(encoding->mask_bits);
}

/* Computes every split's mask by collapsing the full strip back to the base
 * level (split k from the last to the first: q's entries merge into p's
 * list, and the mask marks which merged entries came from q), and leaves
 * the base-level strip in encoding->resolved. */
static lk_status lks_compute_masks(const lk_progressive_mesh *pm, const lk_progressive_strips *ps,
                                   lks_encoding *encoding, lk_error *error)
{
    size_t vertex_count = encoding->vertex_count, length = encoding->length;
    uint32_t *head = lk__malloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *next = lk__malloc_array(length, sizeof(uint32_t));
    encoding->resolved = lk__malloc_array(length, sizeof(uint32_t));
    encoding->mask_offset = lk__malloc_array(encoding->splits, sizeof(size_t));
    encoding->mask_bits = lk__malloc_array(encoding->splits, sizeof(uint32_t));
    if (!head || !next || !encoding->resolved || !encoding->mask_offset || !encoding->mask_bits) {
        free(head);
        free(next);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a strip of %zu entries", length);
    }
    for (size_t v = 0; v < vertex_count; v++) head[v] = LKS_NONE;
    for (size_t j = length; j-- > 0;) {
        uint32_t v = ps->strip[j];
        next[j] = head[v];
        head[v] = (uint32_t)j;
    }
    for (size_t k = encoding->splits; k-- > 0;) {
        uint32_t q = (uint32_t)(encoding->base + k), kept = pm->splits[k].kept;
        /* First pass counts the merged list so its mask can be reserved. */
        size_t candidates = 0;
        for (uint32_t j = head[kept]; j != LKS_NONE; j = next[j]) candidates++;
        for (uint32_t j = head[q]; j != LKS_NONE; j = next[j]) candidates++;
        if (candidates > UINT32_MAX) {
            free(head);
            free(next);
            return lk_error_set(error, LK_ERR_LIMIT, "split %zu: %zu candidate strip entries", k, candidates);
        }
        size_t bytes = (candidates + 7) / 8;
        encoding->mask_offset[k] = encoding->masks.size;
        encoding->mask_bits[k] = (uint32_t)candidates;
        if (!lk__buffer_reserve(&encoding->masks, bytes)) {
            free(head);
            free(next);
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for split masks");
        }
        unsigned char *mask = encoding->masks.data + encoding->masks.size;
        memset(mask, 0, bytes);
        encoding->masks.size += bytes;
        uint32_t a = head[kept], b = head[q];
        uint32_t *tail = &head[kept];
        size_t bit = 0;
        while (a != LKS_NONE || b != LKS_NONE) {
            if (b == LKS_NONE || (a != LKS_NONE && a < b)) {
                *tail = a;
                tail = &next[a];
                a = next[a];
            } else {
                *tail = b;
                tail = &next[b];
                b = next[b];
                mask[bit >> 3] |= (unsigned char)(1u << (bit & 7));
            }
            bit++;
        }
        *tail = LKS_NONE;
        head[q] = LKS_NONE;
    }
    for (size_t v = 0; v < encoding->base; v++)
        for (uint32_t j = head[v]; j != LKS_NONE; j = next[j]) encoding->resolved[j] = (uint32_t)v;
    free(head);
    free(next);
    return LK_OK;
}

/* Raw payload of the base chunk. */
static void lks_write_base(const lks_encoding *encoding, lks_writer *payload)
{
    lks_writer positions = {0};
    int64_t previous[3] = {0, 0, 0};
    for (size_t v = 0; v < encoding->base; v++)
        for (int axis = 0; axis < 3; axis++) {
            int64_t value = encoding->base_quantised[3 * v + axis];
            lks_write_varint(&positions, lks_zigzag(value - previous[axis]));
            previous[axis] = value;
        }
    lks_write_varint(payload, positions.buffer.size);
    payload->section_start[0] = payload->buffer.size;
    lks_write_bytes(payload, positions.buffer.data, positions.buffer.size);
    payload->section_start[1] = payload->buffer.size;
    payload->section_count = 2;
    if (positions.failed) payload->failed = true;
    lk__buffer_free(&positions.buffer);

    const uint32_t *r = encoding->resolved;
    int64_t literal = 0;
    lks_recent recent = {{0}, 0};
    for (size_t j = 0; j < encoding->length; j++) {
        if (j >= 1 && r[j] == r[j - 1]) {
            lks_write_varint(payload, 0);
        } else if (j >= 2 && r[j] == r[j - 2]) {
            lks_write_varint(payload, 1);
        } else {
            unsigned index = lks_recent_use(&recent, r[j]);
            if (index < LKS_RECENT_SIZE) {
                lks_write_varint(payload, LKS_TOKEN_RECENT + index);
            } else {
                lks_write_varint(payload, LKS_TOKEN_LITERAL + lks_zigzag((int64_t)r[j] - literal));
                literal = r[j];
            }
        }
    }
}

/* Raw payload of the split chunk [first, first + count). `state` is the
 * decoder's view at level `first` and is advanced exactly as a decoder
 * would, so the predictions made here are the ones the decoder makes. */
static void lks_write_splits(const lk_progressive_mesh *pm, const lks_encoding *encoding, size_t first, size_t count,
                             lks_state *state, lks_writer *payload)
{
    lks_writer kept_section = {0}, mask_section = {0}, position_section = {0};
    for (size_t k = first; k < first + count; k++) {
        uint32_t kept = pm->splits[k].kept;
        uint32_t q = (uint32_t)state->present;
        const int32_t *split_position = &encoding->split_quantised[3 * k];
        const int32_t *kept_position = &encoding->kept_quantised[3 * k];
        const unsigned char *mask = encoding->masks.data + encoding->mask_offset[k];
        bool moved = memcmp(kept_position, &state->quantised[3 * (size_t)kept], 3 * sizeof(int32_t)) != 0;
        lks_write_varint(&kept_section, (uint64_t)kept << 1 | (moved ? 1u : 0u));
        lks_write_bytes(&mask_section, mask, ((size_t)encoding->mask_bits[k] + 7) / 8);
        lks_split_entries(state, kept, mask);
        int64_t predicted[3];
        lks_predict_split(state, q, kept, predicted);
        for (int axis = 0; axis < 3; axis++)
            lks_write_varint(&position_section, lks_zigzag(split_position[axis] - predicted[axis]));
        memcpy(&state->quantised[3 * (size_t)q], split_position, 3 * sizeof(int32_t));
        if (moved) {
            lks_predict_kept(state, kept, predicted);
            for (int axis = 0; axis < 3; axis++)
                lks_write_varint(&position_section, lks_zigzag(kept_position[axis] - predicted[axis]));
            memcpy(&state->quantised[3 * (size_t)kept], kept_position, 3 * sizeof(int32_t));
        }
    }
    lks_write_varint(payload, kept_section.buffer.size);
    lks_write_varint(payload, mask_section.buffer.size);
    payload->section_start[0] = payload->buffer.size;
    lks_write_bytes(payload, kept_section.buffer.data, kept_section.buffer.size);
    payload->section_start[1] = payload->buffer.size;
    lks_write_bytes(payload, mask_section.buffer.data, mask_section.buffer.size);
    payload->section_start[2] = payload->buffer.size;
    lks_write_bytes(payload, position_section.buffer.data, position_section.buffer.size);
    payload->section_count = 3;
    if (kept_section.failed || mask_section.failed || position_section.failed) payload->failed = true;
    lk__buffer_free(&kept_section.buffer);
    lk__buffer_free(&mask_section.buffer);
    lk__buffer_free(&position_section.buffer);
}

/* Deflates a chunk payload (zlib format, level 9), ending a deflate block
 * at each section start so every section gets Huffman codes of its own
 * (3.6% smaller on the bunny than one run over the whole payload; any
 * inflater reads it). Returns NULL, and the caller stores the payload raw,
 * when that is not smaller or zlib fails. */
static unsigned char *lks_deflate(const lks_writer *payload, size_t *stored_size)
{
    size_t raw_size = payload->buffer.size;
    if (raw_size > UINT32_MAX) return NULL;
    z_stream stream;
    memset(&stream, 0, sizeof stream);
    if (deflateInit2(&stream, 9, Z_DEFLATED, 15, 9, Z_DEFAULT_STRATEGY) != Z_OK) return NULL;
    /* Each block boundary costs at most a few bytes beyond deflateBound. */
    size_t capacity = deflateBound(&stream, (uLong)raw_size) + 64;
    unsigned char *out = malloc(capacity);
    if (!out) {
        deflateEnd(&stream);
        return NULL;
    }
    stream.next_out = out;
    stream.avail_out = (uInt)capacity;
    size_t start = 0;
    int result = Z_OK;
    for (int section = 0; section <= payload->section_count && result != Z_STREAM_END; section++) {
        bool last = section == payload->section_count;
        size_t end = last ? raw_size : payload->section_start[section];
        stream.next_in = payload->buffer.data + start;
        stream.avail_in = (uInt)(end - start);
        result = deflate(&stream, last ? Z_FINISH : Z_BLOCK);
        if (result != Z_OK && result != Z_STREAM_END && result != Z_BUF_ERROR) break;
        start = end;
    }
    size_t total = stream.total_out;
    deflateEnd(&stream);
    if (result != Z_STREAM_END || total >= raw_size) {
        free(out);
        return NULL;
    }
    *stored_size = total;
    return out;
}

static lk_status lks_check_inputs(const lk_progressive_mesh *pm, const lk_progressive_strips *ps,
                                  const lk_stream_options *options, lk_error *error)
{
    if (options->position_bits != 0 && (options->position_bits < 4 || options->position_bits > 24))
        return lk_error_set(error, LK_ERR_INVALID, "position_bits %u: use 0 (automatic) or 4..24",
                            options->position_bits);
    if (options->splits_per_chunk < 1 || options->splits_per_chunk > UINT32_MAX)
        return lk_error_set(error, LK_ERR_INVALID, "splits_per_chunk %zu: use 1..%u", options->splits_per_chunk,
                            (unsigned)UINT32_MAX);
    if (pm->vertex_count > LK_MAX_ELEMENTS || pm->triangle_count > LK_MAX_ELEMENTS ||
        ps->strip_length > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "progressive mesh too large for a stream");
    if (pm->base_vertex_count > pm->vertex_count || pm->split_count != pm->vertex_count - pm->base_vertex_count)
        return lk_error_set(error, LK_ERR_INVALID, "progressive mesh: %zu vertices is not base %zu + %zu splits",
                            pm->vertex_count, pm->base_vertex_count, pm->split_count);
    if ((pm->base_vertex_count && !pm->base_positions) || (pm->split_count && !pm->splits) ||
        (ps->strip_length && !ps->strip))
        return lk_error_set(error, LK_ERR_INVALID, "progressive mesh or strips without their arrays");
    for (size_t k = 0; k < pm->split_count; k++)
        if (pm->splits[k].kept >= pm->base_vertex_count + k)
            return lk_error_set(error, LK_ERR_INVALID, "split %zu: kept vertex %u is not present before the split", k,
                                (unsigned)pm->splits[k].kept);
    for (size_t j = 0; j < ps->strip_length; j++)
        if (ps->strip[j] >= pm->vertex_count)
            return lk_error_set(error, LK_ERR_INVALID, "strip entry %zu: vertex %u is not a vertex of the mesh (%zu)",
                                j, (unsigned)ps->strip[j], pm->vertex_count);
    return LK_OK;
}

/* Quantisation box over every position the stream carries, and the bit
 * count: the fewest bits whose error bound 0.5 * |step| stays within 0.01%
 * of the input diagonal, unless the caller chose one. */
static lk_status lks_choose_quantisation(const lk_progressive_mesh *pm, unsigned requested_bits, float min[3],
                                         float step[3], unsigned *bits, lk_error *error)
{
    float max[3];
    bool any = false;
    for (int axis = 0; axis < 3; axis++) min[axis] = max[axis] = 0;
    size_t total = pm->base_vertex_count + 2 * pm->split_count;
    for (size_t i = 0; i < total; i++) {
        const float *p = i < pm->base_vertex_count ? &pm->base_positions[3 * i]
                         : (i - pm->base_vertex_count) % 2 == 0
                             ? pm->splits[(i - pm->base_vertex_count) / 2].position
                             : pm->splits[(i - pm->base_vertex_count) / 2].kept_position;
        for (int axis = 0; axis < 3; axis++) {
            if (!isfinite(p[axis]))
                return lk_error_set(error, LK_ERR_RANGE, "progressive mesh has a non-finite position (%s %zu)",
                                    i < pm->base_vertex_count ? "base vertex" : "split",
                                    i < pm->base_vertex_count ? i : (i - pm->base_vertex_count) / 2);
            if (!any || p[axis] < min[axis]) min[axis] = p[axis];
            if (!any || p[axis] > max[axis]) max[axis] = p[axis];
        }
        any = true;
    }
    if (requested_bits) {
        *bits = requested_bits;
        lks_steps(min, max, requested_bits, step);
        return LK_OK;
    }
    double diagonal = pm->diagonal;
    if (!(diagonal > 0) || !isfinite(diagonal)) {
        double sum = 0;
        for (int axis = 0; axis < 3; axis++) sum += ((double)max[axis] - min[axis]) * ((double)max[axis] - min[axis]);
        diagonal = sqrt(sum);
    }
    for (unsigned candidate = 4; candidate <= 24; candidate++) {
        *bits = candidate;
        lks_steps(min, max, candidate, step);
        if (lks_quantisation_error(min, step, candidate) <= 1e-4 * diagonal) break;
    }
    return LK_OK;
}

lk_status lk_stream_encode(const lk_progressive_mesh *pm, const lk_progressive_strips *ps,
                           const lk_stream_options *options, unsigned char **bytes, size_t *size, lk_error *error)
{
    if (!pm || !ps || !bytes || !size) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_encode: NULL argument");
    *bytes = NULL;
    *size = 0;
    lk_stream_options defaults;
    lk_stream_options_default(&defaults);
    if (!options) options = &defaults;
    lk_status status = lks_check_inputs(pm, ps, options, error);
    if (status != LK_OK) return status;

    lks_header header;
    memset(&header, 0, sizeof header);
    lk_stream_info *info = &header.info;
    status = lks_choose_quantisation(pm, options->position_bits, info->quantisation_min, info->quantisation_step,
                                     &info->position_bits, error);
    if (status != LK_OK) return status;
    header.quantised_max = (int32_t)((1u << info->position_bits) - 1);
    info->version = LKS_VERSION;
    info->vertex_count = pm->vertex_count;
    info->base_vertex_count = pm->base_vertex_count;
    info->split_count = pm->split_count;
    info->strip_length = ps->strip_length;
    info->quantisation_error =
        lks_quantisation_error(info->quantisation_min, info->quantisation_step, info->position_bits);
    info->diagonal = isfinite(pm->diagonal) && pm->diagonal >= 0 ? pm->diagonal : 0;
    size_t splits_per_chunk = options->splits_per_chunk;
    size_t split_chunks = (pm->split_count + splits_per_chunk - 1) / splits_per_chunk;
    info->chunk_count = 1 + split_chunks;
    header.splits_per_chunk = splits_per_chunk;
    if (info->chunk_count > (UINT32_MAX - LKS_FIXED_HEADER_SIZE - LKS_TABLE_CRC_SIZE) / LKS_TABLE_ENTRY_SIZE)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu chunks do not fit in a chunk table", info->chunk_count);
    info->header_size = LKS_FIXED_HEADER_SIZE + info->chunk_count * LKS_TABLE_ENTRY_SIZE + LKS_TABLE_CRC_SIZE;

    lks_encoding encoding;
    memset(&encoding, 0, sizeof encoding);
    encoding.base = pm->base_vertex_count;
    encoding.splits = pm->split_count;
    encoding.vertex_count = pm->vertex_count;
    encoding.length = ps->strip_length;
    encoding.top = header.quantised_max;
    lks_writer *payloads = lk__calloc_array(info->chunk_count, sizeof(lks_writer));
    lk_stream_chunk_info *chunks = lk__calloc_array(info->chunk_count, sizeof(lk_stream_chunk_info));
    unsigned char **stored = lk__calloc_array(info->chunk_count, sizeof(unsigned char *));
    int32_t *current = lk__malloc_array(pm->vertex_count, 3 * sizeof(int32_t));
    encoding.base_quantised = lk__malloc_array(encoding.base, 3 * sizeof(int32_t));
    encoding.split_quantised = lk__malloc_array(encoding.splits, 3 * sizeof(int32_t));
    encoding.kept_quantised = lk__malloc_array(encoding.splits, 3 * sizeof(int32_t));
    lks_state state = {0}, writer_state = {0};
    lks_undo undo = {0};
    lk__buffer out = {0};
    if (!payloads || !chunks || !stored || !current || !encoding.base_quantised || !encoding.split_quantised ||
        !encoding.kept_quantised) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory encoding a stream");
        goto done;
    }

    const float *min = info->quantisation_min, *step = info->quantisation_step;
    for (size_t v = 0; v < encoding.base; v++)
        for (int axis = 0; axis < 3; axis++)
            encoding.base_quantised[3 * v + axis] =
                lks_quantise(pm->base_positions[3 * v + axis], min[axis], step[axis], encoding.top);
    for (size_t k = 0; k < encoding.splits; k++)
        for (int axis = 0; axis < 3; axis++) {
            encoding.split_quantised[3 * k + axis] =
                lks_quantise(pm->splits[k].position[axis], min[axis], step[axis], encoding.top);
            encoding.kept_quantised[3 * k + axis] =
                lks_quantise(pm->splits[k].kept_position[axis], min[axis], step[axis], encoding.top);
        }
    status = lks_compute_masks(pm, ps, &encoding, error);
    if (status != LK_OK) goto done;

    /* The positions every vertex ends with, replayed independently of the
     * decoding core for the self-check below. */
    memcpy(current, encoding.base_quantised, encoding.base * 3 * sizeof(int32_t));
    for (size_t k = 0; k < encoding.splits; k++) {
        memcpy(&current[3 * (encoding.base + k)], &encoding.split_quantised[3 * k], 3 * sizeof(int32_t));
        memcpy(&current[3 * (size_t)pm->splits[k].kept], &encoding.kept_quantised[3 * k], 3 * sizeof(int32_t));
    }

    /* Raw payloads. The split writer follows the decoder's state (base
     * level first), since predictions depend on it. */
    lks_write_base(&encoding, &payloads[0]);
    if (payloads[0].failed) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory writing the base chunk");
        goto done;
    }
    {
        lk_error check = {0};
        lks_where where = {0, 0};
        status = lks_decode_base(&writer_state, &header, payloads[0].buffer.data, payloads[0].buffer.size, &where,
                                 &check);
        if (status == LK_OK) status = lks_state_reserve(&writer_state, encoding.vertex_count, &check);
        if (status != LK_OK) {
            status = lk_error_set(error, status == LK_ERR_NOMEM ? LK_ERR_NOMEM : LK_ERR_INVALID,
                                  "stream self-check failed: %s", check.message);
            goto done;
        }
    }
    for (size_t c = 1; c < info->chunk_count; c++) {
        size_t first = (c - 1) * splits_per_chunk;
        size_t count = first + splits_per_chunk <= encoding.splits ? splits_per_chunk : encoding.splits - first;
        chunks[c].first_split = (uint32_t)first;
        chunks[c].split_count = (uint32_t)count;
        lks_write_splits(pm, &encoding, first, count, &writer_state, &payloads[c]);
    }
    for (size_t c = 0; c < info->chunk_count; c++) {
        if (payloads[c].failed) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory writing chunk %zu", c);
            goto done;
        }
        if (payloads[c].buffer.size > UINT32_MAX - LKS_CHUNK_HEADER_SIZE) {
            status = lk_error_set(error, LK_ERR_LIMIT, "chunk %zu: payload of %zu bytes exceeds 4 GiB (use fewer "
                                  "splits per chunk)", c, payloads[c].buffer.size);
            goto done;
        }
    }

    /* Decode what was written: triangle counts for the table, and proof that
     * the stream gives back the progressive strip and the positions. */
    for (size_t c = 0; c < info->chunk_count; c++) {
        lks_where where = {c, 0};
        const unsigned char *payload = payloads[c].buffer.data;
        size_t payload_size = payloads[c].buffer.size;
        lk_error check = {0};
        if (c == 0) {
            status = lks_decode_base(&state, &header, payload, payload_size, &where, &check);
        } else {
            status = lks_apply_chunk(&state, &undo, payload, payload_size, &chunks[c], chunks[c].split_count, false,
                                     &where, &check);
        }
        if (status != LK_OK) {
            /* The encoder wrote something its decoder refuses: a bug here, or
             * inputs this format cannot carry. */
            status = lk_error_set(error, status == LK_ERR_NOMEM ? LK_ERR_NOMEM : LK_ERR_INVALID,
                                  "stream self-check failed: %s", check.message);
            goto done;
        }
        chunks[c].triangle_count = (uint32_t)state.triangles;
        if (c == 0) info->base_triangle_count = state.triangles;
    }
    info->triangle_count = state.triangles;
    if ((encoding.length && memcmp(state.resolved, ps->strip, encoding.length * sizeof(uint32_t)) != 0) ||
        (encoding.vertex_count &&
         memcmp(state.quantised, current, encoding.vertex_count * 3 * sizeof(int32_t)) != 0)) {
        status = lk_error_set(error, LK_ERR_INVALID, "stream self-check failed: the decoded full level differs");
        goto done;
    }
    if (info->triangle_count != pm->triangle_count) {
        status = lk_error_set(error, LK_ERR_INVALID,
                              "the progressive strip draws %zu triangles but the progressive mesh has %zu (strips "
                              "built from another mesh?)",
                              info->triangle_count, pm->triangle_count);
        goto done;
    }

    /* Stored payloads and the table. */
    uint64_t offset = info->header_size;
    for (size_t c = 0; c < info->chunk_count; c++) {
        size_t raw_size = payloads[c].buffer.size;
        const unsigned char *raw = payloads[c].buffer.data;
        size_t stored_size = raw_size;
        if (options->compress && raw_size > 0) {
            stored[c] = lks_deflate(&payloads[c], &stored_size);
            if (!stored[c]) stored_size = raw_size;
        }
        const unsigned char *data = stored[c] ? stored[c] : raw;
        chunks[c].offset = offset;
        chunks[c].size = (uint32_t)(LKS_CHUNK_HEADER_SIZE + stored_size);
        chunks[c].raw_size = (uint32_t)raw_size;
        chunks[c].crc32 = lks_crc32(data, stored_size);
        offset += chunks[c].size;
    }
    info->total_size = (size_t)offset;

    unsigned char fixed[LKS_FIXED_HEADER_SIZE];
    memset(fixed, 0, sizeof fixed);
    memcpy(fixed, lks_magic, sizeof lks_magic);
    lk__store_u16le(fixed + 8, LKS_VERSION);
    lk__store_u16le(fixed + 10, 0);
    lk__store_u32le(fixed + 12, (uint32_t)info->header_size);
    lk__store_u64le(fixed + 16, offset);
    lk__store_u32le(fixed + 24, (uint32_t)info->vertex_count);
    lk__store_u32le(fixed + 28, (uint32_t)info->triangle_count);
    lk__store_u32le(fixed + 32, (uint32_t)info->base_vertex_count);
    lk__store_u32le(fixed + 36, (uint32_t)info->base_triangle_count);
    lk__store_u32le(fixed + 40, (uint32_t)info->split_count);
    lk__store_u32le(fixed + 44, (uint32_t)info->strip_length);
    lk__store_u32le(fixed + 48, (uint32_t)info->chunk_count);
    lk__store_u32le(fixed + 52, (uint32_t)splits_per_chunk);
    fixed[56] = (unsigned char)info->position_bits;
    for (int axis = 0; axis < 3; axis++) {
        lk__store_f32le(fixed + 60 + 4 * axis, info->quantisation_min[axis]);
        lk__store_f32le(fixed + 72 + 4 * axis, info->quantisation_step[axis]);
    }
    lk__store_f64le(fixed + 84, info->diagonal);
    lk__store_u32le(fixed + 92, lks_crc32(fixed, 92));

    if (!lk__buffer_reserve(&out, (size_t)offset)) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for a stream of %llu bytes",
                              (unsigned long long)offset);
        goto done;
    }
    lk__buffer_append(&out, fixed, sizeof fixed);
    for (size_t c = 0; c < info->chunk_count; c++) {
        unsigned char entry[LKS_TABLE_ENTRY_SIZE];
        lk__store_u64le(entry, chunks[c].offset);
        lk__store_u32le(entry + 8, chunks[c].size);
        lk__store_u32le(entry + 12, chunks[c].raw_size);
        lk__store_u32le(entry + 16, chunks[c].first_split);
        lk__store_u32le(entry + 20, chunks[c].split_count);
        lk__store_u32le(entry + 24, chunks[c].triangle_count);
        lk__store_u32le(entry + 28, chunks[c].crc32);
        lk__buffer_append(&out, entry, sizeof entry);
    }
    unsigned char table_crc[4];
    lk__store_u32le(table_crc, lks_crc32(out.data + LKS_FIXED_HEADER_SIZE, info->chunk_count * LKS_TABLE_ENTRY_SIZE));
    lk__buffer_append(&out, table_crc, 4);
    for (size_t c = 0; c < info->chunk_count; c++) {
        unsigned char chunk_header[LKS_CHUNK_HEADER_SIZE];
        size_t stored_size = chunks[c].size - LKS_CHUNK_HEADER_SIZE;
        lk__store_u32le(chunk_header, (uint32_t)stored_size);
        lk__store_u32le(chunk_header + 4, chunks[c].crc32);
        lk__buffer_append(&out, chunk_header, sizeof chunk_header);
        lk__buffer_append(&out, stored[c] ? stored[c] : payloads[c].buffer.data, stored_size);
    }
    *size = out.size;
    *bytes = lk__buffer_take(&out);
    status = LK_OK;

done:
    if (payloads)
        for (size_t c = 0; c < info->chunk_count; c++) lk__buffer_free(&payloads[c].buffer);
    if (stored)
        for (size_t c = 0; c < info->chunk_count; c++) free(stored[c]);
    free(payloads);
    free(stored);
    free(chunks);
    free(current);
    lks_encoding_free(&encoding);
    lks_state_free(&state);
    lks_state_free(&writer_state);
    lks_undo_free(&undo);
    lk__buffer_free(&out);
    return status;
}

lk_status lk_stream_write_file(const char *path, const unsigned char *bytes, size_t size, lk_error *error)
{
    if (!path || (!bytes && size)) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_write_file: NULL argument");
    lk__atomic_file file;
    lk_status status = lk__atomic_open(&file, path, error);
    if (status != LK_OK) return status;
    if (size && fwrite(bytes, 1, size, file.file) != size) {
        lk_error_set(error, LK_ERR_IO, "%s: write error", path);
        return lk__atomic_fail(&file, error);
    }
    return lk__atomic_commit(&file, error);
}

/* ---- inspection ------------------------------------------------------------ */

lk_status lk_stream_inspect(const unsigned char *bytes, size_t size, lk_stream_info *info,
                            lk_stream_chunk_info **chunks, lk_error *error)
{
    if (chunks) *chunks = NULL;
    if (info) memset(info, 0, sizeof *info);
    if (!bytes && size) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_inspect: NULL bytes");
    if (size < LKS_FIXED_HEADER_SIZE) {
        size_t known = size < sizeof lks_magic ? size : sizeof lks_magic;
        if (known && memcmp(bytes, lks_magic, known) != 0)
            return lk_error_set(error, LK_ERR_PARSE, "header at byte 0: not a lodkit stream (bad magic)");
        return lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated: stopped at byte %zu in the header (%u bytes)",
                            size, LKS_FIXED_HEADER_SIZE);
    }
    lks_header header;
    lk_status status = lks_parse_header(bytes, &header, error);
    if (status != LK_OK) return status;
    if (info) *info = header.info;
    if (size < header.info.header_size)
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "stream truncated: stopped at byte %zu in the chunk table (%zu chunks, header ends at "
                            "byte %zu)",
                            size, header.info.chunk_count, header.info.header_size);
    lk_stream_chunk_info *table = lk__malloc_array(header.info.chunk_count, sizeof *table);
    if (!table) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu chunks", header.info.chunk_count);
    status = lks_parse_table(bytes + LKS_FIXED_HEADER_SIZE, &header, table, error);
    if (status != LK_OK) {
        free(table);
        return status;
    }
    for (size_t c = 0; c < header.info.chunk_count && status == LK_OK; c++) {
        const lk_stream_chunk_info *chunk = &table[c];
        lks_where where = {c, chunk->offset};
        if (chunk->offset + chunk->size > size) {
            status = lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated: stopped at byte %zu in chunk %zu of %zu",
                                  size, c, header.info.chunk_count);
            break;
        }
        const unsigned char *chunk_bytes = bytes + chunk->offset;
        uint32_t header_stored = lk__load_u32le(chunk_bytes), header_crc = lk__load_u32le(chunk_bytes + 4);
        size_t stored = chunk->size - LKS_CHUNK_HEADER_SIZE;
        if (header_stored != stored || header_crc != chunk->crc32) {
            status = lks_chunk_error(error, &where,
                                     "chunk header (payload %u bytes, CRC %08x) disagrees with the table (%zu bytes, "
                                     "CRC %08x)",
                                     (unsigned)header_stored, (unsigned)header_crc, stored, (unsigned)chunk->crc32);
            break;
        }
        uint32_t crc = lks_crc32(chunk_bytes + LKS_CHUNK_HEADER_SIZE, stored);
        if (crc != chunk->crc32)
            status = lks_chunk_error(error, &where, "CRC-32 mismatch (stored %08x, computed %08x)",
                                     (unsigned)chunk->crc32, (unsigned)crc);
    }
    if (status == LK_OK && size > header.info.total_size)
        status = lk_error_set(error, LK_ERR_PARSE, "byte %zu: %zu bytes after the end of the stream",
                              header.info.total_size, size - header.info.total_size);
    if (chunks)
        *chunks = table;
    else
        free(table);
    return status;
}

/* ---- incremental decoder ------------------------------------------------------ */

enum { LKS_PHASE_HEADER, LKS_PHASE_TABLE, LKS_PHASE_CHUNKS, LKS_PHASE_DONE, LKS_PHASE_FAILED };

struct lk_stream_decoder {
    size_t max_level;
    size_t max_bytes;        /* memory budget for the decoder's own arrays and buffers */
    uint64_t state_bytes;    /* what the header's counts need (state + table), checked against it */
    int phase;
    bool stopped;            /* max_level reached: later bytes are ignored */
    lk__buffer pending;      /* bytes of the unit (header, table, chunk) being received */
    size_t received;         /* bytes fed so far */
    size_t consumed;         /* bytes of the header and the decoded chunks */
    bool has_info;
    lks_header header;
    lk_stream_chunk_info *chunks;
    size_t next_chunk;       /* chunk being received */
    size_t chunks_decoded;
    lks_state state;
    lks_undo undo;
    lk_error failure;        /* replayed once the decoder has failed */
};

lk_status lk_stream_decoder_create(size_t max_level, lk_stream_decoder **out, lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_create: NULL out");
    *out = calloc(1, sizeof **out);
    if (!*out) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a stream decoder");
    (*out)->max_level = max_level;
    (*out)->max_bytes = LKS_DEFAULT_MAX_BYTES;
    (*out)->phase = LKS_PHASE_HEADER;
    return LK_OK;
}

lk_status lk_stream_decoder_set_max_bytes(lk_stream_decoder *decoder, size_t max_bytes, lk_error *error)
{
    if (!decoder) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_set_max_bytes: NULL decoder");
    if (decoder->phase != LKS_PHASE_HEADER || decoder->received != 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "lk_stream_decoder_set_max_bytes: the budget must be set before the first byte is fed");
    decoder->max_bytes = max_bytes ? max_bytes : LKS_DEFAULT_MAX_BYTES;
    return LK_OK;
}

/* What decoding needs for the counts of a checked header: per vertex its
 * quantised position, list head and count (20 bytes), per strip entry the
 * resolved vertex and the next link (8 bytes), per chunk its table entry
 * as received and as parsed. Refused before anything of that size is
 * allocated, so a 100-byte header cannot make the decoder ask for
 * gigabytes. */
static lk_status lks_check_header_budget(lk_stream_decoder *decoder, lk_error *error)
{
    const lk_stream_info *info = &decoder->header.info;
    uint64_t state = (uint64_t)info->vertex_count * 20u + (uint64_t)info->strip_length * 8u;
    uint64_t table = (uint64_t)info->chunk_count * (LKS_TABLE_ENTRY_SIZE + sizeof(lk_stream_chunk_info));
    if (table > decoder->max_bytes)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "header at byte 48: a table of %zu chunks needs %llu bytes, more than the memory budget "
                            "of %zu bytes",
                            info->chunk_count, (unsigned long long)table, decoder->max_bytes);
    if (state > decoder->max_bytes - table)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "header at byte 24: %zu vertices and a strip of %zu entries need %llu bytes to decode, "
                            "more than the memory budget of %zu bytes",
                            info->vertex_count, info->strip_length, (unsigned long long)(state + table),
                            decoder->max_bytes);
    decoder->state_bytes = state + table;
    return LK_OK;
}

/* Each chunk is buffered whole (when it arrives in pieces), inflated into
 * raw_size bytes when compressed, and its splits are logged for undo (16
 * bytes each): refuse a table whose chunks would not fit next to the
 * state, before any chunk arrives. */
static lk_status lks_check_table_budget(const lk_stream_decoder *decoder, lk_error *error)
{
    const lk_stream_info *info = &decoder->header.info;
    uint64_t room = decoder->max_bytes - decoder->state_bytes;
    for (size_t i = 0; i < info->chunk_count; i++) {
        const lk_stream_chunk_info *chunk = &decoder->chunks[i];
        uint64_t working = (uint64_t)chunk->size + (chunk->compressed ? (uint64_t)chunk->raw_size : 0) +
                           (uint64_t)chunk->split_count * 16u;
        if (working > room)
            return lk_error_set(error, LK_ERR_LIMIT,
                                "chunk table entry %zu at byte %zu: a chunk of %u bytes (%u raw) at offset %llu needs "
                                "%llu bytes next to the %llu of the decoder state, more than the memory budget of %zu "
                                "bytes",
                                i, (size_t)LKS_FIXED_HEADER_SIZE + i * LKS_TABLE_ENTRY_SIZE + 8, (unsigned)chunk->size,
                                (unsigned)chunk->raw_size, (unsigned long long)chunk->offset,
                                (unsigned long long)working, (unsigned long long)decoder->state_bytes,
                                decoder->max_bytes);
    }
    return LK_OK;
}

void lk_stream_decoder_free(lk_stream_decoder *decoder)
{
    if (!decoder) return;
    lk__buffer_free(&decoder->pending);
    free(decoder->chunks);
    lks_state_free(&decoder->state);
    lks_undo_free(&decoder->undo);
    free(decoder);
}

/* Bytes of the unit the decoder waits for. */
static size_t lks_unit_size(const lk_stream_decoder *decoder)
{
    switch (decoder->phase) {
    case LKS_PHASE_HEADER: return LKS_FIXED_HEADER_SIZE;
    case LKS_PHASE_TABLE: return decoder->header.info.header_size - LKS_FIXED_HEADER_SIZE;
    case LKS_PHASE_CHUNKS: return decoder->chunks[decoder->next_chunk].size;
    default: return 0;
    }
}

static lk_status lks_decode_chunk(lk_stream_decoder *decoder, const unsigned char *bytes, lk_error *error)
{
    size_t index = decoder->next_chunk;
    const lk_stream_chunk_info *chunk = &decoder->chunks[index];
    lks_where where = {index, chunk->offset};
    const unsigned char *payload = NULL;
    unsigned char *inflated;
    lk_status status = lks_open_chunk(bytes, chunk, &where, &payload, &inflated, error);
    if (status != LK_OK) return status;
    size_t level = decoder->state.present - decoder->state.base_vertex_count;
    if (chunk->is_base) {
        status = lks_decode_base(&decoder->state, &decoder->header, payload, chunk->raw_size, &where, error);
        if (status == LK_OK && decoder->state.triangles != chunk->triangle_count) {
            status = lks_chunk_error(error, &where, "the base strip draws %zu triangles, the table says %u",
                                     decoder->state.triangles, (unsigned)chunk->triangle_count);
            lks_state_free(&decoder->state);
        }
        if (status == LK_OK && decoder->max_level == 0 && decoder->header.info.split_count > 0)
            decoder->stopped = true;
    } else {
        size_t limit = chunk->split_count;
        if (decoder->max_level - level < limit) limit = decoder->max_level - level;
        status = lks_apply_chunk(&decoder->state, &decoder->undo, payload, chunk->raw_size, chunk, limit, true,
                                 &where, error);
        if (status == LK_OK && level + limit == decoder->max_level && decoder->max_level < decoder->header.info.split_count)
            decoder->stopped = true;
    }
    free(inflated);
    if (status != LK_OK) return status;
    decoder->chunks_decoded++;
    decoder->consumed += chunk->size;
    decoder->next_chunk++;
    if (decoder->stopped || decoder->next_chunk == decoder->header.info.chunk_count) decoder->phase = LKS_PHASE_DONE;
    return LK_OK;
}

static lk_status lks_process_unit(lk_stream_decoder *decoder, const unsigned char *bytes, lk_error *error)
{
    switch (decoder->phase) {
    case LKS_PHASE_HEADER: {
        lk_status status = lks_parse_header(bytes, &decoder->header, error);
        if (status == LK_OK) status = lks_check_header_budget(decoder, error);
        if (status != LK_OK) return status;
        decoder->phase = LKS_PHASE_TABLE;
        return LK_OK;
    }
    case LKS_PHASE_TABLE: {
        size_t chunk_count = decoder->header.info.chunk_count;
        decoder->chunks = lk__malloc_array(chunk_count, sizeof(lk_stream_chunk_info));
        if (!decoder->chunks) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu chunks", chunk_count);
        lk_status status = lks_parse_table(bytes, &decoder->header, decoder->chunks, error);
        if (status == LK_OK) status = lks_check_table_budget(decoder, error);
        if (status != LK_OK) return status;
        decoder->has_info = true;
        decoder->consumed = decoder->header.info.header_size;
        decoder->phase = LKS_PHASE_CHUNKS;
        return LK_OK;
    }
    case LKS_PHASE_CHUNKS: return lks_decode_chunk(decoder, bytes, error);
    default: return LK_OK;
    }
}

static lk_status lks_replay_failure(const lk_stream_decoder *decoder, lk_error *error)
{
    return lk_error_set(error, decoder->failure.status, "%s", decoder->failure.message);
}

lk_status lk_stream_decoder_feed(lk_stream_decoder *decoder, const void *bytes, size_t size, lk_error *error)
{
    if (!decoder || (!bytes && size)) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_feed: NULL argument");
    if (decoder->phase == LKS_PHASE_FAILED) return lks_replay_failure(decoder, error);
    const unsigned char *input = bytes;
    while (size > 0) {
        if (decoder->phase == LKS_PHASE_DONE) {
            if (decoder->stopped) {
                /* max_level reached: the rest of a download is welcome and unused. */
                decoder->received += size;
                return LK_OK;
            }
            return lk_error_set(error, LK_ERR_PARSE, "byte %zu: data after the end of the stream (%zu bytes)",
                                decoder->received, decoder->header.info.total_size);
        }
        size_t unit = lks_unit_size(decoder);
        size_t have = decoder->pending.size;
        size_t take = unit - have < size ? unit - have : size;
        const unsigned char *unit_bytes = NULL;
        if (have == 0 && take == unit) {
            unit_bytes = input; /* the whole unit is here: no copy */
        } else {
            if (!lk__buffer_append(&decoder->pending, input, take))
                return lk_error_set(error, LK_ERR_NOMEM, "out of memory buffering %zu stream bytes", have + take);
            unit_bytes = decoder->pending.data;
        }
        decoder->received += take;
        input += take;
        size -= take;
        /* Say "not a stream" as soon as the magic is wrong, not after 96 bytes. */
        if (decoder->phase == LKS_PHASE_HEADER) {
            size_t known = have + take < sizeof lks_magic ? have + take : sizeof lks_magic;
            if (memcmp(unit_bytes, lks_magic, known) != 0) {
                lk_error_set(&decoder->failure, LK_ERR_PARSE, "header at byte 0: not a lodkit stream (bad magic)");
                decoder->phase = LKS_PHASE_FAILED;
                lk__buffer_free(&decoder->pending);
                return lks_replay_failure(decoder, error);
            }
        }
        if (have + take < unit) break;
        lk_error local = {0};
        lk_status status = lks_process_unit(decoder, unit_bytes, &local);
        decoder->pending.size = 0;
        if (status != LK_OK) {
            decoder->failure = local;
            decoder->phase = LKS_PHASE_FAILED;
            lk__buffer_free(&decoder->pending);
            return lks_replay_failure(decoder, error);
        }
    }
    /* A finished decoder keeps no buffered bytes around. */
    if (decoder->phase == LKS_PHASE_DONE) lk__buffer_free(&decoder->pending);
    return LK_OK;
}

lk_status lk_stream_decoder_finish(lk_stream_decoder *decoder, lk_error *error)
{
    if (!decoder) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_finish: NULL decoder");
    switch (decoder->phase) {
    case LKS_PHASE_DONE: return LK_OK;
    case LKS_PHASE_FAILED: return lks_replay_failure(decoder, error);
    case LKS_PHASE_HEADER:
        return lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated: stopped at byte %zu in the header (%u bytes)",
                            decoder->received, LKS_FIXED_HEADER_SIZE);
    case LKS_PHASE_TABLE:
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "stream truncated: stopped at byte %zu in the chunk table (%zu chunks, header ends at "
                            "byte %zu)",
                            decoder->received, decoder->header.info.chunk_count, decoder->header.info.header_size);
    default:
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "stream truncated: stopped at byte %zu in chunk %zu of %zu (bytes %llu..%llu); level %zu "
                            "of %zu decoded",
                            decoder->received, decoder->next_chunk, decoder->header.info.chunk_count,
                            (unsigned long long)decoder->chunks[decoder->next_chunk].offset,
                            (unsigned long long)(decoder->chunks[decoder->next_chunk].offset +
                                                 decoder->chunks[decoder->next_chunk].size),
                            lk_stream_decoder_level(decoder), decoder->header.info.split_count);
    }
}

const lk_stream_info *lk_stream_decoder_info(const lk_stream_decoder *decoder)
{
    return decoder && decoder->has_info ? &decoder->header.info : NULL;
}

size_t lk_stream_decoder_level(const lk_stream_decoder *decoder)
{
    if (!decoder || !decoder->state.has_base) return 0;
    return decoder->state.present - decoder->state.base_vertex_count;
}

size_t lk_stream_decoder_chunks(const lk_stream_decoder *decoder) { return decoder ? decoder->chunks_decoded : 0; }

size_t lk_stream_decoder_bytes(const lk_stream_decoder *decoder) { return decoder ? decoder->consumed : 0; }

lk_status lk_stream_decoder_mesh(const lk_stream_decoder *decoder, lk_mesh *out, lk_error *error)
{
    if (!decoder || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_mesh: NULL argument");
    const lks_state *state = &decoder->state;
    if (!state->has_base)
        return lk_error_set(error, LK_ERR_INVALID, "no mesh yet: the base chunk has not been decoded");
    size_t length = state->strip_length;
    uint32_t *triangles = lk__malloc_array(length >= 2 ? 3 * (length - 2) : 0, sizeof(uint32_t));
    if (!triangles) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu triangles", state->triangles);
    size_t triangle_count = length >= 3 ? lk_strip_triangles(state->resolved, length, triangles) : 0;
    lk_mesh mesh;
    lk_status status = lk_mesh_alloc(&mesh, state->present, triangle_count, 0, error);
    if (status != LK_OK) {
        free(triangles);
        return status;
    }
    const lk_stream_info *info = &decoder->header.info;
    for (size_t v = 0; v < state->present; v++)
        for (int axis = 0; axis < 3; axis++)
            mesh.positions[3 * v + axis] = lks_dequantise(info->quantisation_min[axis], info->quantisation_step[axis],
                                                          state->quantised[3 * v + axis]);
    memcpy(mesh.indices, triangles, 3 * triangle_count * sizeof(uint32_t));
    free(triangles);
    *out = mesh;
    return LK_OK;
}

lk_status lk_stream_decoder_strip(const lk_stream_decoder *decoder, int filtered, uint32_t **strip, size_t *length,
                                  lk_error *error)
{
    if (!decoder || !strip || !length)
        return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_strip: NULL argument");
    *strip = NULL;
    *length = 0;
    const lks_state *state = &decoder->state;
    if (!state->has_base)
        return lk_error_set(error, LK_ERR_INVALID, "no strip yet: the base chunk has not been decoded");
    size_t capacity = filtered ? lk_strip_filter_bound(state->strip_length) : state->strip_length;
    uint32_t *out = lk__malloc_array(capacity, sizeof(uint32_t));
    if (!out) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a strip of %zu entries", capacity);
    size_t out_length = state->strip_length;
    if (filtered)
        out_length = lk_strip_filter(state->resolved, state->strip_length, out);
    else
        memcpy(out, state->resolved, state->strip_length * sizeof(uint32_t));
    *strip = out;
    *length = out_length;
    return LK_OK;
}
