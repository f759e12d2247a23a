/* SPDX-License-Identifier: MIT */
/* The version-2 stream decoder (stream2_decode.c, stream2_mesh.c) as a
 * WebAssembly module for the browser's worker (web/stream2_wasm.js): the
 * same C that lodkit decodes with, compiled by clang for wasm32-wasi
 * (CMakeLists.txt: the stream2.wasm command), not into the library.
 *
 * The page's JavaScript keeps the container (web/stream.js: header, chunk
 * table, CRCs, buffering) and hands each chunk's payload here; this module
 * decodes it into its mesh, takes a bad chunk back whole, and gives any
 * decoded level's quantised positions and triangles (it keeps every split's
 * undo record for that, lks2_state.keep_log). Every export takes and gives
 * plain numbers and pointers into the module's memory. */
#include "../stream2_internal.h"

#include <stdlib.h>
#include <string.h>

/* Natively (fuzz/fuzz_stream.c links this file to fuzz it) the exports are
 * plain functions and the library's CRC is zlib's. */
#ifdef __wasm__
#define WASM_EXPORT(name) __attribute__((export_name(#name)))
#else
#define WASM_EXPORT(name)
#endif

#ifdef __wasm__
/* CRC-32 (IEEE 802.3, reflected, as zlib's) for lk__lks_parse_header: zlib
 * is not built for wasm32. Bitwise: the header is checked once. */
uint32_t lk__lks_crc32(const unsigned char *bytes, size_t size)
{
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = 0; i < size; i++) {
        crc ^= bytes[i];
        for (int bit = 0; bit < 8; bit++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xFFFFFFFFu;
}
#endif

typedef struct wasm_decoder {
    lks_header header;
    lks2_state state;
    lk_error error;
    int32_t *level_quantised; /* the last level asked for */
    uint32_t *level_corners;
} wasm_decoder;

WASM_EXPORT(lkw_alloc) void *lkw_alloc(size_t size) { return malloc(size ? size : 1); }
WASM_EXPORT(lkw_free) void lkw_free(void *pointer) { free(pointer); }

/* A decoder for the stream whose 96-byte fixed header is at `header`; NULL
 * when it is refused (lkw_create_error tells why). */
static lk_error create_error;
WASM_EXPORT(lkw_create) wasm_decoder *lkw_create(const unsigned char *header)
{
    wasm_decoder *decoder = calloc(1, sizeof *decoder);
    if (!decoder) {
        lk_error_set(&create_error, LK_ERR_NOMEM, "out of memory for the decoder");
        return NULL;
    }
    if (lk__lks_parse_header(header, &decoder->header, &create_error) != LK_OK ||
        (decoder->header.info.version != LKS2_VERSION &&
         lk_error_set(&create_error, LK_ERR_PARSE, "version %u, not 2", decoder->header.info.version)) ||
        lk__lks2_state_begin(&decoder->state, &decoder->header, &create_error) != LK_OK) {
        lk__lks2_state_free(&decoder->state);
        free(decoder);
        return NULL;
    }
    decoder->state.keep_log = true;
    return decoder;
}
WASM_EXPORT(lkw_create_error) const char *lkw_create_error(void) { return create_error.message; }

WASM_EXPORT(lkw_destroy) void lkw_destroy(wasm_decoder *decoder)
{
    if (!decoder) return;
    lk__lks2_state_free(&decoder->state);
    free(decoder->level_quantised);
    free(decoder->level_corners);
    free(decoder);
}

/* Decodes chunk `index` (table entry: is_base, split_count, the triangle
 * count after it; offset for messages) from its payload. 0 when it is
 * applied; otherwise the chunk is taken back and lkw_error tells why. */
WASM_EXPORT(lkw_chunk)
int lkw_chunk(wasm_decoder *decoder, uint32_t index, double offset, int is_base, uint32_t split_count,
              uint32_t triangle_count, const unsigned char *payload, size_t size)
{
    lk_stream_chunk_info chunk = {0};
    chunk.offset = (uint64_t)offset;
    chunk.is_base = is_base;
    chunk.split_count = is_base ? 0 : split_count;
    chunk.triangle_count = triangle_count;
    chunk.first_split = (uint32_t)(decoder->state.mesh.vertex_count - decoder->state.base_vertex_count);
    lks_where where = {index, chunk.offset};
    lk_error_clear(&decoder->error);
    return (int)lk__lks2_decode_chunk(&decoder->state, &decoder->header, &chunk, payload, size, SIZE_MAX, &where,
                                      &decoder->error);
}
WASM_EXPORT(lkw_error) const char *lkw_error(const wasm_decoder *decoder) { return decoder->error.message; }

/* Splits applied (0 before the base chunk too). */
WASM_EXPORT(lkw_level) uint32_t lkw_level(const wasm_decoder *decoder)
{
    const lks2_state *state = &decoder->state;
    return state->has_base ? (uint32_t)(state->mesh.vertex_count - state->base_vertex_count) : 0;
}

/* Builds level `level` (at most the decoded one): its base + level vertices'
 * quantised positions (lkw_level_quantised, 3 each) and its triangles
 * (lkw_level_corners, 3 each), the later splits undone from the log as
 * web/stream2.js's levelGeometry does. Returns the triangle count, or -1
 * when out of memory. */
WASM_EXPORT(lkw_build_level) int lkw_build_level(wasm_decoder *decoder, uint32_t level)
{
    const lks2_state *state = &decoder->state;
    const lks2_mesh *mesh = &state->mesh;
    uint32_t current = lkw_level(decoder);
    if (level > current) level = current;
    size_t triangles = level < current ? state->splits[level].triangles_before : mesh->triangle_count;
    int32_t *quantised = realloc(decoder->level_quantised, (mesh->vertex_count ? mesh->vertex_count : 1) * 12);
    if (quantised) decoder->level_quantised = quantised;
    uint32_t *corners = realloc(decoder->level_corners, (triangles ? triangles : 1) * 12);
    if (corners) decoder->level_corners = corners;
    if (!quantised || !corners) return -1;
    memcpy(quantised, mesh->quantised, mesh->vertex_count * 12);
    memcpy(corners, mesh->corners, triangles * 12);
    for (uint32_t split = current; split-- > level;) {
        const lks2_undo_split *undo = &state->splits[split];
        uint32_t q = (uint32_t)(state->base_vertex_count + split);
        memcpy(quantised + 3 * (size_t)undo->p, undo->old_position, sizeof undo->old_position);
        uint32_t moved_end = split + 1 < current ? state->splits[split + 1].moved_start : (uint32_t)state->moved_count;
        for (uint32_t m = undo->moved_start; m < moved_end; m++) {
            uint32_t t = state->moved[m];
            if (t >= triangles) continue; /* restored after this level: dropped */
            uint32_t *c = corners + 3 * (size_t)t;
            if (c[0] == q)
                c[0] = undo->p;
            else if (c[1] == q)
                c[1] = undo->p;
            else
                c[2] = undo->p;
        }
    }
    return (int)triangles;
}
WASM_EXPORT(lkw_level_quantised) const int32_t *lkw_level_quantised(const wasm_decoder *d)
{
    return d->level_quantised;
}
WASM_EXPORT(lkw_level_corners) const uint32_t *lkw_level_corners(const wasm_decoder *d) { return d->level_corners; }
