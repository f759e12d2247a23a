/* SPDX-License-Identifier: MIT */
/* The progressive stream format (.lks) itself: the magic, the CRC-32, the
 * fixed header and the chunk table, read and checked (docs/stream-format.md
 * specifies every byte; the encoder writes them in stream_encode.c), and
 * the error messages that locate a chunk. What both sides share is declared
 * in stream_internal.h. */
#include "bytes.h"
#include "stream2_internal.h" /* LKS2_HEADER_FLAGS */
#include "stream_internal.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <string.h>

const unsigned char lk__lks_magic[8] = {0x89, 'L', 'K', 'S', '\r', '\n', 0x1a, '\n'};

/* ---- error messages ----------------------------------------------------- */

lk_status lk__lks_chunk_error(lk_error *error, const lks_where *where, const char *format, ...)
{
    char detail[400];
    va_list args;
    va_start(args, format);
    vsnprintf(detail, sizeof detail, format, args);
    va_end(args);
    return lk_error_set(error, LK_ERR_PARSE, "chunk %zu at byte %llu: %s", where->chunk,
                        (unsigned long long)where->offset, detail);
}

const char *lk__lks_varint_problem(int code)
{
    return code == LKS_VARINT_END ? "runs past the end of its section" : "is longer than 64 bits";
}

/* ---- header and chunk table ------------------------------------------- */

/* Largest distance between a position and its dequantised float: half a
 * step per axis, plus half a float ulp from rounding min + q * step to
 * float (bounded by the box's largest magnitude times 2^-24; negligible at
 * the default bits, visible at 24). */
double lk__lks_quantisation_error(const float min[3], const float step[3], unsigned bits)
{
    double sum = 0, top = (double)((1u << bits) - 1);
    for (int axis = 0; axis < 3; axis++) {
        double magnitude = fmax(fabs((double)min[axis]), fabs((double)min[axis] + top * (double)step[axis]));
        double error = 0.5 * (double)step[axis] + ldexp(magnitude, -24);
        sum += error * error;
    }
    return sqrt(sum);
}

/* Parses and checks the fixed header (LKS_FIXED_HEADER_SIZE bytes). */
lk_status lk__lks_parse_header(const unsigned char *bytes, lks_header *header, lk_error *error)
{
    memset(header, 0, sizeof *header);
    lk_stream_info *info = &header->info;
    if (memcmp(bytes, lk__lks_magic, sizeof lk__lks_magic) != 0)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 0: not a lodkit stream (bad magic)");
    uint32_t stored_crc = lk__load_u32le(bytes + 92);
    uint32_t crc = lk__lks_crc32(bytes, 92);
    info->version = lk__load_u16le(bytes + 8);
    if (info->version != LKS_VERSION && info->version != 2)
        return lk_error_set(error, LK_ERR_PARSE,
                            "header at byte 8: unsupported version %u (this decoder reads 1 and 2)", info->version);
    bool v2 = info->version == 2;
    if (crc != stored_crc)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 92: CRC-32 mismatch (stored %08x, computed %08x)",
                            (unsigned)stored_crc, (unsigned)crc);
    uint32_t flags = lk__load_u16le(bytes + 10);
    /* Version 2: bits 0..2 name the attributes each vertex carries, bit 3
     * says split positions are coded in their ring's frame. */
    if (v2) flags &= ~(uint32_t)LKS2_HEADER_FLAGS;
    header->flags = v2 ? lk__load_u16le(bytes + 10) & LKS2_HEADER_FLAGS : 0;
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
    } counts[] = {{vertex_count, 24, "vertex count"},
                  {triangle_count, 28, "triangle count"},
                  {base_vertex_count, 32, "base vertex count"},
                  {base_triangle_count, 36, "base triangle count"},
                  {split_count, 40, "split count"},
                  {strip_length, 44, "strip length"}};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++)
        if (counts[i].value > LK_MAX_ELEMENTS)
            return lk_error_set(error, LK_ERR_PARSE, "header at byte %u: %s %llu is more than lodkit supports (%zu)",
                                counts[i].offset, counts[i].name, (unsigned long long)counts[i].value,
                                (size_t)LK_MAX_ELEMENTS);
    if (vertex_count != base_vertex_count + split_count)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 24: vertex count %llu is not base %llu + splits %llu",
                            (unsigned long long)vertex_count, (unsigned long long)base_vertex_count,
                            (unsigned long long)split_count);
    /* Version 2 has no strip; a split restores at most 8 triangles. */
    uint64_t most_triangles = v2 ? base_triangle_count + 8 * split_count : strip_length >= 2 ? strip_length - 2 : 0;
    if (v2 && strip_length != 0)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 44: a version-2 stream has no strip (length %llu)",
                            (unsigned long long)strip_length);
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
    uint64_t expected_header_size = LKS_FIXED_HEADER_SIZE + chunk_count * LKS_TABLE_ENTRY_SIZE + LKS_TABLE_CRC_SIZE;
    if (header_size != expected_header_size)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 12: header size %llu, expected %llu for %llu chunk%s",
                            (unsigned long long)header_size, (unsigned long long)expected_header_size,
                            (unsigned long long)chunk_count, chunk_count == 1 ? "" : "s");
    if (total_size < header_size + chunk_count * (LKS_CHUNK_HEADER_SIZE + 1))
        return lk_error_set(
            error, LK_ERR_PARSE, "header at byte 16: total size %llu cannot hold the header and %llu chunk%s",
            (unsigned long long)total_size, (unsigned long long)chunk_count, chunk_count == 1 ? "" : "s");
    if (total_size > SIZE_MAX)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 16: total size %llu does not fit in memory",
                            (unsigned long long)total_size);
    /* Every split needs LKS_MIN_SPLIT_BYTES raw bytes and every strip entry
     * one, and no payload inflates more than LKS_MAX_DEFLATE_RATIO times. */
    uint64_t raw_capacity =
        total_size > UINT64_MAX / LKS_MAX_DEFLATE_RATIO ? UINT64_MAX : total_size * LKS_MAX_DEFLATE_RATIO;
    /* Version 2: a split makes at least 21 binary decisions, each costing
     * at least 0.011 bits with the coder's most skewed probability, so a
     * byte holds fewer than 64 splits (or base vertices: 18 decisions). */
    if (v2) raw_capacity = total_size > UINT64_MAX / 64 ? UINT64_MAX : total_size * 64;
    if (split_count * (v2 ? 1 : LKS_MIN_SPLIT_BYTES) > raw_capacity || strip_length > raw_capacity ||
        base_vertex_count * (v2 ? 1 : 3) > raw_capacity)
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
    info->quantisation_error = lk__lks_quantisation_error(info->quantisation_min, info->quantisation_step, bits);
    info->chunk_count = (size_t)chunk_count;
    info->header_size = (size_t)header_size;
    info->total_size = (size_t)total_size;
    header->splits_per_chunk = (size_t)splits_per_chunk;
    header->quantised_max = (int32_t)((1u << bits) - 1);
    return LK_OK;
}

/* Parses and checks the chunk table (the bytes after the fixed header,
 * CRC included) into chunks[chunk_count]. */
lk_status lk__lks_parse_table(const unsigned char *table, const lks_header *header, lk_stream_chunk_info *chunks,
                              lk_error *error)
{
    const lk_stream_info *info = &header->info;
    size_t table_size = info->chunk_count * LKS_TABLE_ENTRY_SIZE;
    uint32_t stored_crc = lk__load_u32le(table + table_size);
    uint32_t crc = lk__lks_crc32(table, table_size);
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
                                "chunk table entry %zu at byte %zu: raw size %u is impossible for %llu stored bytes", i,
                                where + 12, (unsigned)chunk->raw_size, (unsigned long long)stored);
        if (info->version == 2 && chunk->raw_size != stored)
            return lk_error_set(error, LK_ERR_PARSE,
                                "chunk table entry %zu at byte %zu: raw size %u, but version-2 chunks are stored as "
                                "they are (%llu bytes)",
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
            if (info->version == 1 &&
                (uint64_t)info->strip_length + 3 * (uint64_t)info->base_vertex_count > chunk->raw_size)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry 0 at byte %zu: raw size %u cannot hold %zu base vertices and a "
                                    "strip of %zu entries",
                                    where + 12, (unsigned)chunk->raw_size, info->base_vertex_count, info->strip_length);
        } else {
            if (chunk->first_split != splits_so_far)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry %zu at byte %zu: first split %u, expected %llu", i, where + 16,
                                    (unsigned)chunk->first_split, (unsigned long long)splits_so_far);
            if (chunk->split_count == 0 || chunk->split_count > info->split_count - splits_so_far)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry %zu at byte %zu: %u split%s, but %llu of %zu remain", i,
                                    where + 20, (unsigned)chunk->split_count, chunk->split_count == 1 ? "" : "s",
                                    (unsigned long long)(info->split_count - splits_so_far), info->split_count);
            if ((uint64_t)chunk->split_count * (info->version == 1 ? LKS_MIN_SPLIT_BYTES : 1) >
                (info->version == 1 ? 1u : 64u) * (uint64_t)chunk->raw_size)
                return lk_error_set(error, LK_ERR_PARSE,
                                    "chunk table entry %zu at byte %zu: raw size %u cannot hold %u split%s", i,
                                    where + 12, (unsigned)chunk->raw_size, (unsigned)chunk->split_count,
                                    chunk->split_count == 1 ? "" : "s");
            if (chunk->triangle_count < triangles_before || chunk->triangle_count > info->triangle_count)
                return lk_error_set(
                    error, LK_ERR_PARSE,
                    "chunk table entry %zu at byte %zu: %u triangles is outside %llu..%zu (splits never "
                    "remove triangles)",
                    i, where + 24, (unsigned)chunk->triangle_count, (unsigned long long)triangles_before,
                    info->triangle_count);
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
        return lk_error_set(
            error, LK_ERR_PARSE, "chunk table entry %zu at byte %zu: the last chunk ends with %llu triangles, not %zu",
            info->chunk_count - 1, last_where + 24, (unsigned long long)triangles_before, info->triangle_count);
    return LK_OK;
}

lk_status lk__lks_assemble(lks_header *header, lk_stream_chunk_info *chunks, unsigned char *const *stored,
                           const size_t *stored_sizes, unsigned char **bytes, size_t *size, lk_error *error)
{
    lk_stream_info *info = &header->info;
    if (info->chunk_count > (UINT32_MAX - LKS_FIXED_HEADER_SIZE - LKS_TABLE_CRC_SIZE) / LKS_TABLE_ENTRY_SIZE)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu chunks do not fit in a chunk table", info->chunk_count);
    info->header_size = LKS_FIXED_HEADER_SIZE + info->chunk_count * LKS_TABLE_ENTRY_SIZE + LKS_TABLE_CRC_SIZE;
    uint64_t offset = info->header_size;
    for (size_t c = 0; c < info->chunk_count; c++) {
        if (stored_sizes[c] > UINT32_MAX - LKS_CHUNK_HEADER_SIZE)
            return lk_error_set(error, LK_ERR_LIMIT, "chunk %zu: payload of %zu bytes exceeds 4 GiB", c,
                                stored_sizes[c]);
        chunks[c].offset = offset;
        chunks[c].size = (uint32_t)(LKS_CHUNK_HEADER_SIZE + stored_sizes[c]);
        chunks[c].crc32 = lk__lks_crc32(stored[c], stored_sizes[c]);
        offset += chunks[c].size;
    }
    info->total_size = (size_t)offset;

    unsigned char fixed[LKS_FIXED_HEADER_SIZE];
    memset(fixed, 0, sizeof fixed);
    memcpy(fixed, lk__lks_magic, sizeof lk__lks_magic);
    lk__store_u16le(fixed + 8, (uint16_t)info->version);
    lk__store_u16le(fixed + 10, (uint16_t)header->flags);
    lk__store_u32le(fixed + 12, (uint32_t)info->header_size);
    lk__store_u64le(fixed + 16, offset);
    lk__store_u32le(fixed + 24, (uint32_t)info->vertex_count);
    lk__store_u32le(fixed + 28, (uint32_t)info->triangle_count);
    lk__store_u32le(fixed + 32, (uint32_t)info->base_vertex_count);
    lk__store_u32le(fixed + 36, (uint32_t)info->base_triangle_count);
    lk__store_u32le(fixed + 40, (uint32_t)info->split_count);
    lk__store_u32le(fixed + 44, (uint32_t)info->strip_length);
    lk__store_u32le(fixed + 48, (uint32_t)info->chunk_count);
    lk__store_u32le(fixed + 52, (uint32_t)header->splits_per_chunk);
    fixed[56] = (unsigned char)info->position_bits;
    for (int axis = 0; axis < 3; axis++) {
        lk__store_f32le(fixed + 60 + 4 * axis, info->quantisation_min[axis]);
        lk__store_f32le(fixed + 72 + 4 * axis, info->quantisation_step[axis]);
    }
    lk__store_f64le(fixed + 84, info->diagonal);
    lk__store_u32le(fixed + 92, lk__lks_crc32(fixed, 92));

    lk__buffer out = {0};
    if (!lk__buffer_reserve(&out, (size_t)offset))
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a stream of %llu bytes",
                            (unsigned long long)offset);
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
    lk__store_u32le(table_crc,
                    lk__lks_crc32(out.data + LKS_FIXED_HEADER_SIZE, info->chunk_count * LKS_TABLE_ENTRY_SIZE));
    lk__buffer_append(&out, table_crc, 4);
    for (size_t c = 0; c < info->chunk_count; c++) {
        unsigned char chunk_header[LKS_CHUNK_HEADER_SIZE];
        lk__store_u32le(chunk_header, (uint32_t)stored_sizes[c]);
        lk__store_u32le(chunk_header + 4, chunks[c].crc32);
        lk__buffer_append(&out, chunk_header, sizeof chunk_header);
        lk__buffer_append(&out, stored[c], stored_sizes[c]);
    }
    *size = out.size;
    *bytes = lk__buffer_take(&out);
    return LK_OK;
}

/* ---- quantisation (both versions) ------------------------------------------ */

/* Per-axis steps for `bits` over [min, max]: extent / (2^bits - 1), rounded
 * up as floats until the top code reaches max, so every position quantises
 * without clamping and stays within half a step per axis. */
void lk__lks_steps(const float min[3], const float max[3], unsigned bits, float step[3])
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
            value = nextafterf(value, 0); /* extent / top rounded up past the limit */
        while ((double)min[axis] + top * (double)value < (double)max[axis]) {
            float next = nextafterf(value, INFINITY);
            if (!((double)min[axis] + top * (double)next <= FLT_MAX)) break;
            value = next;
        }
        step[axis] = value;
    }
}

int32_t lk__lks_quantise(float value, float min, float step, int32_t top)
{
    if (!(step > 0)) return 0;
    double code = nearbyint(((double)value - (double)min) / (double)step);
    if (code < 0) code = 0;
    if (code > top) code = top;
    return (int32_t)code;
}

/* Quantisation box over every position the stream carries, and the bit
 * count: the fewest bits whose error bound 0.5 * |step| stays within 0.01%
 * of the input diagonal, unless the caller chose one. */
lk_status lk__lks_choose_quantisation(const lk_progressive_mesh *pm, unsigned requested_bits, float min[3],
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
        lk__lks_steps(min, max, requested_bits, step);
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
        lk__lks_steps(min, max, candidate, step);
        if (lk__lks_quantisation_error(min, step, candidate) <= 1e-4 * diagonal) break;
    }
    return LK_OK;
}
