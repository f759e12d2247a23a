/* SPDX-License-Identifier: MIT */
/* Progressive stream format (.lks): lk_stream_inspect, which reads the
 * header and the chunk table and checks every chunk's header and CRC
 * without decoding anything, and lk_stream_bits_by_part, which decodes a
 * version-2 stream to say where its bits go. */
#include "bytes.h"
#include "stream2_internal.h"

#include <stdlib.h>
#include <string.h>

/* ---- inspection ------------------------------------------------------------ */

lk_status lk_stream_inspect(const unsigned char *bytes, size_t size, lk_stream_info *info,
                            lk_stream_chunk_info **chunks, lk_error *error)
{
    if (chunks) *chunks = NULL;
    if (info) memset(info, 0, sizeof *info);
    if (!bytes && size) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_inspect: NULL bytes");
    if (size < LKS_FIXED_HEADER_SIZE) {
        size_t known = size < sizeof lk__lks_magic ? size : sizeof lk__lks_magic;
        if (known && memcmp(bytes, lk__lks_magic, known) != 0)
            return lk_error_set(error, LK_ERR_PARSE, "header at byte 0: not a lodkit stream (bad magic)");
        return lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated: stopped at byte %zu in the header (%u bytes)",
                            size, LKS_FIXED_HEADER_SIZE);
    }
    lks_header header;
    lk_status status = lk__lks_parse_header(bytes, &header, error);
    if (status != LK_OK) return status;
    if (info) *info = header.info;
    if (size < header.info.header_size)
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "stream truncated: stopped at byte %zu in the chunk table (%zu chunk%s, header ends at "
                            "byte %zu)",
                            size, header.info.chunk_count, header.info.chunk_count == 1 ? "" : "s",
                            header.info.header_size);
    lk_stream_chunk_info *table = lk__malloc_array(header.info.chunk_count, sizeof *table);
    if (!table) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu chunks", header.info.chunk_count);
    status = lk__lks_parse_table(bytes + LKS_FIXED_HEADER_SIZE, &header, table, error);
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
            status =
                lk__lks_chunk_error(error, &where,
                                    "chunk header (payload %u bytes, CRC %08x) disagrees with the table (%zu bytes, "
                                    "CRC %08x)",
                                    (unsigned)header_stored, (unsigned)header_crc, stored, (unsigned)chunk->crc32);
            break;
        }
        uint32_t crc = lk__lks_crc32(chunk_bytes + LKS_CHUNK_HEADER_SIZE, stored);
        if (crc != chunk->crc32)
            status = lk__lks_chunk_error(error, &where, "CRC-32 mismatch (stored %08x, computed %08x)",
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

/* ---- bits by part (version 2) ---------------------------------------------- */

lk_status lk_stream_bits_by_part(const unsigned char *bytes, size_t size, lk_stream_bits *bits, lk_error *error)
{
    memset(bits, 0, sizeof *bits);
    lk_stream_info info;
    lk_status status = lk_stream_inspect(bytes, size, &info, NULL, error);
    if (status != LK_OK) return status;
    if (info.version != LKS2_VERSION)
        return lk_error_set(error, LK_ERR_INVALID,
                            "a version %u stream has no bits by part (its chunks are deflated; version 2 only)",
                            info.version);
    double account[LKS2_PART_COUNT] = {0};
    lks_header header;
    lks2_mesh mesh = {0};
    status = lk__lks2_decode(bytes, size, SIZE_MAX, account, &header, &mesh, error);
    lk__lks2_mesh_free(&mesh);
    if (status != LK_OK) return status;
    double per_vertex = info.vertex_count ? 1.0 / (double)info.vertex_count : 0;
    double counted = 0;
    for (int part = 0; part < LKS2_PART_COUNT; part++) counted += account[part];
    bits->base = account[LKS2_PART_BASE] * per_vertex;
    bits->split_vertices = account[LKS2_PART_SPLIT_VERTICES] * per_vertex;
    bits->moves = account[LKS2_PART_MOVES] * per_vertex;
    bits->restored = account[LKS2_PART_RESTORED] * per_vertex;
    bits->positions = account[LKS2_PART_POSITIONS] * per_vertex;
    bits->normals = account[LKS2_PART_NORMALS] * per_vertex;
    bits->texcoords = account[LKS2_PART_TEXCOORDS] * per_vertex;
    bits->colors = account[LKS2_PART_COLORS] * per_vertex;
    bits->total = 8.0 * (double)info.total_size * per_vertex;
    bits->framing = bits->total - counted * per_vertex;
    return LK_OK;
}
