/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the progressive stream decoder (src/stream_decode.c).
 *
 * Input: byte 0 picks where the stream is cut into two feeds (so the
 * decoder's buffering across calls is exercised), byte 1 holds flags, the
 * rest is the stream. Flag bit 0 re-seals the CRCs (header, chunk table,
 * every chunk whose bytes are present) before decoding: without it nearly
 * every mutation dies at a CRC check and the payload decoders are never
 * reached. Bits 1..7, when non-zero, set max_level = (flags >> 1) * 23, to
 * stop in the middle of chunks.
 *
 * Any input must give an error with a message or a valid mesh; never a
 * crash, a leak, or a level beyond the header's split count.
 *
 * The same stream then goes through the browser's build of the version-2
 * decoder (src/wasm/stream2_wasm.c, compiled natively here): chunk by chunk
 * as web/stream2_wasm.js hands them over, every split kept in the log, and
 * after each chunk a lower level rebuilt from that log. */
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "lodkit.h"

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

/* Recomputes the CRCs the format carries (docs/stream-format.md), wherever
 * the structure is present, leaving every other field as mutated. */
static void reseal(uint8_t *bytes, size_t size)
{
    if (size < 96) return;
    put32(bytes + 92, (uint32_t)crc32(0L, bytes, 92));
    size_t chunk_count = get32(bytes + 48);
    if (chunk_count > (size - 96) / 32) return;
    size_t table_end = 96 + 32 * chunk_count;
    if (table_end + 4 > size) return;
    for (size_t c = 0; c < chunk_count; c++) {
        uint8_t *entry = bytes + 96 + 32 * c;
        uint64_t offset = (uint64_t)get32(entry) | (uint64_t)get32(entry + 4) << 32;
        uint32_t chunk_size = get32(entry + 8);
        if (chunk_size < 8 || offset > size || chunk_size > size - offset) continue;
        uint32_t crc = (uint32_t)crc32(0L, bytes + offset + 8, chunk_size - 8);
        put32(entry + 28, crc);
        put32(bytes + offset + 4, crc);
    }
    put32(bytes + table_end, (uint32_t)crc32(0L, bytes + 96, (uInt)(32 * chunk_count)));
}

/* src/wasm/stream2_wasm.c's exports (it has no header: JavaScript calls them). */
typedef struct wasm_decoder wasm_decoder;
wasm_decoder *lkw_create(const unsigned char *header);
const char *lkw_create_error(void);
void lkw_destroy(wasm_decoder *decoder);
int lkw_chunk(wasm_decoder *decoder, uint32_t index, double offset, int is_base, uint32_t split_count,
              uint32_t triangle_count, const unsigned char *payload, size_t size);
const char *lkw_error(const wasm_decoder *decoder);
uint32_t lkw_level(const wasm_decoder *decoder);
int lkw_build_level(wasm_decoder *decoder, uint32_t level);
const int32_t *lkw_level_quantised(const wasm_decoder *decoder);
const uint32_t *lkw_level_corners(const wasm_decoder *decoder);

/* Every whole chunk of a version-2 stream, in order, until one is refused
 * (with a message, its splits taken back: the level stays); after each, the
 * level `pick` selects rebuilt: corners within its vertices, positions on
 * the grid, and the decoded level rebuilt twice alike. */
static void check_browser_decoder(const uint8_t *stream, size_t length, unsigned pick)
{
    lk_stream_info info;
    lk_stream_chunk_info *chunks = NULL;
    lk_status status = lk_stream_inspect(stream, length, &info, &chunks, NULL);
    if ((status != LK_OK && status != LK_ERR_TRUNCATED) || !chunks || info.version != 2) {
        lk_free(chunks);
        return;
    }
    wasm_decoder *decoder = lkw_create(stream);
    if (!decoder) {
        if (lkw_create_error()[0] == '\0') abort();
        lk_free(chunks);
        return;
    }
    int32_t top = (int32_t)((1u << info.position_bits) - 1u);
    for (size_t c = 0; c < info.chunk_count; c++) {
        const lk_stream_chunk_info *chunk = &chunks[c];
        if (chunk->offset + chunk->size > length || chunk->size < 8) break;
        uint32_t before = lkw_level(decoder);
        if (lkw_chunk(decoder, (uint32_t)c, (double)chunk->offset, chunk->is_base, chunk->split_count,
                      chunk->triangle_count, stream + chunk->offset + 8, chunk->size - 8) != 0) {
            if (lkw_error(decoder)[0] == '\0' || lkw_level(decoder) != before) abort();
            break;
        }
        uint32_t level = lkw_level(decoder);
        if (level > info.split_count || level != before + chunk->split_count) abort();
        pick = pick * 1103515245u + 12345u;
        uint32_t lower = (pick >> 8) % (level + 1);
        for (int pass = 0; pass < 2; pass++) {
            uint32_t at = pass ? level : lower;
            int triangles = lkw_build_level(decoder, at);
            if (triangles < 0) abort();
            size_t vertices = info.base_vertex_count + at;
            const uint32_t *corners = lkw_level_corners(decoder);
            for (size_t i = 0; i < 3 * (size_t)triangles; i++)
                if (corners[i] >= vertices) abort();
            const int32_t *quantised = lkw_level_quantised(decoder);
            for (size_t i = 0; i < 3 * vertices; i++)
                if (quantised[i] < 0 || quantised[i] > top) abort();
            if (pass && (size_t)triangles != chunk->triangle_count) abort();
        }
    }
    lkw_destroy(decoder);
    lk_free(chunks);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2) return 0;
    size_t length = size - 2;
    uint8_t *stream = malloc(length ? length : 1);
    if (!stream) return 0;
    memcpy(stream, data + 2, length);
    if (data[1] & 1) reseal(stream, length);
    size_t cut = (size_t)data[0] * length / 255;
    size_t max_level = (data[1] >> 1) ? (size_t)(data[1] >> 1) * 23 : SIZE_MAX;

    lk_stream_decoder *decoder = NULL;
    lk_error error = {0};
    if (lk_stream_decoder_create(max_level, &decoder, &error) != LK_OK) abort();
    /* Like the reader targets: a small budget keeps every input fast, and
     * claims over it must be refused with a message. */
    if (lk_stream_decoder_set_max_bytes(decoder, (size_t)64 << 20, &error) != LK_OK) abort();
    lk_status status = lk_stream_decoder_feed(decoder, stream, cut, &error);
    if (status == LK_OK) status = lk_stream_decoder_feed(decoder, stream + cut, length - cut, &error);
    if (status == LK_OK) status = lk_stream_decoder_finish(decoder, &error);
    if (status != LK_OK && error.message[0] == '\0') abort();

    const lk_stream_info *info = lk_stream_decoder_info(decoder);
    if (lk_stream_decoder_level(decoder) > 0 && !info) abort();
    if (info && lk_stream_decoder_level(decoder) > info->split_count) abort();
    if (lk_stream_decoder_level(decoder) > max_level) abort();

    lk_mesh mesh;
    if (lk_stream_decoder_mesh(decoder, &mesh, NULL) == LK_OK) {
        if (lk_mesh_validate(&mesh, NULL) != LK_OK) abort();
        if (mesh.vertex_count != info->base_vertex_count + lk_stream_decoder_level(decoder)) abort();
        lk_mesh_free(&mesh);
        for (int filtered = 0; filtered < 2; filtered++) {
            uint32_t *strip = NULL;
            size_t strip_length = 0;
            if (lk_stream_decoder_strip(decoder, filtered, &strip, &strip_length, NULL) != LK_OK) abort();
            for (size_t j = 0; j < strip_length; j++)
                if (strip[j] >= info->base_vertex_count + lk_stream_decoder_level(decoder)) abort();
            lk_free(strip);
        }
    }
    lk_stream_decoder_free(decoder);

    lk_stream_info inspected;
    lk_stream_chunk_info *chunks = NULL;
    lk_error inspect_error = {0};
    if (lk_stream_inspect(stream, length, &inspected, &chunks, &inspect_error) != LK_OK &&
        inspect_error.message[0] == '\0')
        abort();
    lk_free(chunks);
    /* bits by part decode the whole stream once more: a message or parts
     * that add up to the stream's size */
    lk_stream_bits bits;
    lk_error bits_error = {0};
    if (lk_stream_bits_by_part(stream, length, &bits, &bits_error) == LK_OK) {
        double parts = bits.base + bits.split_vertices + bits.moves + bits.restored + bits.positions + bits.normals +
                       bits.texcoords + bits.colors + bits.framing;
        if (!(fabs(parts - bits.total) <= 1e-6 * (bits.total + 1))) abort();
    } else if (bits_error.message[0] == '\0') {
        abort();
    }
    check_browser_decoder(stream, length, data[0] ^ (unsigned)data[1] << 8);
    free(stream);
    return 0;
}
