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
 * crash, a leak, or a level beyond the header's split count. */
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
    free(stream);
    return 0;
}
