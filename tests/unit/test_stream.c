/* SPDX-License-Identifier: MIT */
/* Progressive stream format (src/stream_*.c, docs/stream-format.md): round
 * trips on the bunny, cow, triceratops and fandisk (full level equal to the
 * input, every chunk boundary equal to the progressive mesh's level), the
 * quantisation bound, the size in bits per vertex, byte-by-byte and
 * random-piece feeding, truncation, corruption with and without a valid
 * CRC (the decoder rolls back to the last good chunk), malformed headers
 * and tables, max_level, options, determinism and writing files. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zlib.h>

#include "testutil.h"

/* ---- models (built once, shared by the tests) ------------------------- */

typedef struct model {
    const char *name;
    bool built;
    lk_mesh input;   /* as read */
    lk_mesh cleaned; /* degenerate and duplicate triangles removed */
    lk_progressive_mesh pm;
    lk_progressive_strips ps;
    unsigned char *bytes; /* default options */
    size_t size;
    double encode_seconds;
} model;

static model models[] = {
    {.name = "bunny.obj"}, {.name = "cow.off"}, {.name = "triceratops.off"}, {.name = "fandisk.off"}};
enum { BUNNY, COW, TRICERATOPS, FANDISK, MODEL_COUNT };

static double now_seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static void encode_ok(const model *m, const lk_stream_options *options, unsigned char **bytes, size_t *size)
{
    lk_error error = {0};
    if (lk_stream_encode(&m->pm, &m->ps, options, bytes, size, &error) != LK_OK)
        fail_msg("%s: encode: %s", m->name, error.message);
}

static model *get_model(int which)
{
    model *m = &models[which];
    if (m->built) return m;
    lk_error error = {0};
    lk_test_load(lk_test_sample(m->name), &m->input);
    if (lk_mesh_copy(&m->cleaned, &m->input, &error) != LK_OK) fail_msg("copy: %s", error.message);
    if (lk_mesh_remove_degenerate(&m->cleaned, NULL, NULL, &error) != LK_OK) fail_msg("clean: %s", error.message);
    lk_progressive_options options;
    lk_progressive_options_default(&options);
    if (lk_progressive_mesh_build(&m->input, &options, &m->pm, NULL, NULL, &error) != LK_OK)
        fail_msg("%s: progressive mesh: %s", m->name, error.message);
    if (lk_progressive_strips_build(&m->pm, LK_STRIPIFY_BEST, &m->ps, &error) != LK_OK)
        fail_msg("%s: progressive strips: %s", m->name, error.message);
    double start = now_seconds();
    encode_ok(m, NULL, &m->bytes, &m->size);
    m->encode_seconds = now_seconds() - start;
    m->built = true;
    return m;
}

static int teardown_models(void **state)
{
    (void)state;
    for (int i = 0; i < MODEL_COUNT; i++) {
        model *m = &models[i];
        if (!m->built) continue;
        lk_mesh_free(&m->input);
        lk_mesh_free(&m->cleaned);
        lk_progressive_mesh_free(&m->pm);
        lk_progressive_strips_free(&m->ps);
        lk_free(m->bytes);
        m->built = false;
    }
    return 0;
}

/* ---- helpers ---------------------------------------------------------------- */

static void inspect_ok(const unsigned char *bytes, size_t size, lk_stream_info *info, lk_stream_chunk_info **chunks)
{
    lk_error error = {0};
    if (lk_stream_inspect(bytes, size, info, chunks, &error) != LK_OK) fail_msg("inspect: %s", error.message);
}

static void feed_ok(lk_stream_decoder *decoder, const unsigned char *bytes, size_t size)
{
    lk_error error = {0};
    if (lk_stream_decoder_feed(decoder, bytes, size, &error) != LK_OK) fail_msg("feed: %s", error.message);
}

static void assert_same_triangles(const uint32_t *a, size_t a_count, const uint32_t *a_map, const uint32_t *b,
                                  size_t b_count, const uint32_t *b_map, const char *what)
{
    if (a_count != b_count) fail_msg("%s: %zu triangles vs %zu", what, a_count, b_count);
    uint32_t *x = lk_test_canonical_triangles(a, a_count, a_map);
    uint32_t *y = lk_test_canonical_triangles(b, b_count, b_map);
    for (size_t t = 0; t < a_count; t++)
        if (memcmp(&x[3 * t], &y[3 * t], 3 * sizeof(uint32_t)) != 0)
            fail_msg("%s: oriented triangle %zu differs: (%u %u %u) vs (%u %u %u)", what, t, x[3 * t], x[3 * t + 1],
                     x[3 * t + 2], y[3 * t], y[3 * t + 1], y[3 * t + 2]);
    free(x);
    free(y);
}

static double distance3(const float *a, const float *b)
{
    double sum = 0;
    for (int k = 0; k < 3; k++) sum += ((double)a[k] - b[k]) * ((double)a[k] - b[k]);
    return sqrt(sum);
}

/* Every decoded position within the quantisation bound (+ float rounding)
 * of the reference (reference vertex = map[v], or v). Returns the largest
 * error seen. */
static double assert_positions_close(const lk_mesh *decoded, const float *reference, const uint32_t *map,
                                     const lk_stream_info *info, const char *what)
{
    /* The bound includes float rounding; leave room for double arithmetic only. */
    double slack = 1e-9 * info->diagonal + 1e-30;
    double worst = 0;
    for (size_t v = 0; v < decoded->vertex_count; v++) {
        double d = distance3(&decoded->positions[3 * v], &reference[3 * (map ? map[v] : v)]);
        if (d > worst) worst = d;
        if (d > info->quantisation_error + slack)
            fail_msg("%s: vertex %zu is %g away (bound %g)", what, v, d, info->quantisation_error);
    }
    return worst;
}

/* The decoder at a level must equal the progressive mesh at that level:
 * same triangles (PM numbering, oriented) and positions within the bound;
 * the filtered strip draws the same triangles. */
static void assert_decoder_matches_pm(const lk_stream_decoder *decoder, const model *m, const char *what)
{
    size_t level = lk_stream_decoder_level(decoder);
    const lk_stream_info *info = lk_stream_decoder_info(decoder);
    assert_non_null(info);
    lk_mesh decoded, reference;
    lk_error error = {0};
    lk_test_stream_mesh(decoder, &decoded);
    if (lk_progressive_mesh_level(&m->pm, level, &reference, &error) != LK_OK) fail_msg("pm level: %s", error.message);
    assert_int_equal(decoded.vertex_count, m->pm.base_vertex_count + level);
    assert_int_equal(decoded.vertex_count, reference.vertex_count);
    assert_int_equal(decoded.triangle_count, lk_progressive_mesh_level_triangles(&m->pm, level));
    char label[128];
    snprintf(label, sizeof label, "%s %s level %zu", m->name, what, level);
    assert_same_triangles(decoded.indices, decoded.triangle_count, NULL, reference.indices, reference.triangle_count,
                          NULL, label);
    assert_positions_close(&decoded, reference.positions, NULL, info, label);

    uint32_t *filtered, *unfiltered;
    size_t filtered_length, unfiltered_length;
    assert_int_equal(lk_stream_decoder_strip(decoder, 1, &filtered, &filtered_length, &error), LK_OK);
    assert_int_equal(lk_stream_decoder_strip(decoder, 0, &unfiltered, &unfiltered_length, &error), LK_OK);
    assert_int_equal(unfiltered_length, info->strip_length);
    assert_true(filtered_length <= unfiltered_length + 1);
    uint32_t *triangles = malloc(3 * (filtered_length + 1) * sizeof(uint32_t));
    size_t drawn = lk_strip_triangles(filtered, filtered_length, triangles);
    assert_same_triangles(triangles, drawn, NULL, decoded.indices, decoded.triangle_count, NULL, label);
    free(triangles);
    lk_free(filtered);
    lk_free(unfiltered);
    lk_mesh_free(&decoded);
    lk_mesh_free(&reference);
}

/* Whole stream at once: the full level is the input mesh. */
static void assert_full_round_trip(const lk_stream_decoder *decoder, const model *m)
{
    const lk_stream_info *info = lk_stream_decoder_info(decoder);
    lk_mesh decoded;
    lk_test_stream_mesh(decoder, &decoded);
    assert_int_equal(lk_stream_decoder_level(decoder), m->pm.split_count);
    assert_int_equal(decoded.vertex_count, m->pm.vertex_count);
    assert_same_triangles(decoded.indices, decoded.triangle_count, m->pm.vertex_order, m->cleaned.indices,
                          m->cleaned.triangle_count, NULL, m->name);
    double worst = assert_positions_close(&decoded, m->input.positions, m->pm.vertex_order, info, m->name);
    print_message("%-16s %5zu v  %u bits  largest position error %.3g%% of the diagonal (bound %.3g%%)\n", m->name,
                  decoded.vertex_count, info->position_bits, 100 * worst / info->diagonal,
                  100 * info->quantisation_error / info->diagonal);
    lk_mesh_free(&decoded);
}

static uint32_t crc_of(const unsigned char *bytes, size_t size) { return (uint32_t)crc32(0L, bytes, (uInt)size); }
static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static uint32_t get32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
/* Re-seals an edited stream: header CRC, chunk CRCs (table and chunk
 * headers) and the table CRC, as documented. */
static void fix_header_crc(unsigned char *bytes) { put32(bytes + 92, crc_of(bytes, 92)); }
static void fix_table_crc(unsigned char *bytes)
{
    size_t chunk_count = get32(bytes + 48);
    put32(bytes + 96 + 32 * chunk_count, crc_of(bytes + 96, 32 * chunk_count));
}
static void fix_chunk_crc(unsigned char *bytes, const lk_stream_chunk_info *chunk, size_t index)
{
    uint32_t crc = crc_of(bytes + chunk->offset + 8, chunk->size - 8);
    put32(bytes + chunk->offset + 4, crc);
    put32(bytes + 96 + 32 * index + 28, crc);
    fix_table_crc(bytes);
}

static unsigned char *copy_bytes(const unsigned char *bytes, size_t size)
{
    unsigned char *copy = malloc(size + 16);
    assert_non_null(copy);
    memcpy(copy, bytes, size);
    return copy;
}

/* Feeds a whole (edited) stream to a fresh decoder and to inspect and
 * expects LK_ERR_PARSE from both, with `needle` in the decoder's message. */
static void assert_refused(const unsigned char *bytes, size_t size, const char *needle)
{
    lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
    lk_error error = {0};
    lk_status status = lk_stream_decoder_feed(decoder, bytes, size, &error);
    if (status != LK_ERR_PARSE)
        fail_msg("expected a parse error with \"%s\", got %d: %s", needle, status, error.message);
    lk_assert_message_contains(error, needle);
    lk_error again = {0};
    assert_int_equal(lk_stream_decoder_finish(decoder, &again), LK_ERR_PARSE);
    assert_string_equal(again.message, error.message);
    lk_stream_decoder_free(decoder);
    lk_stream_info info;
    lk_stream_chunk_info *chunks = NULL;
    lk_error inspect_error = {0};
    status = lk_stream_inspect(bytes, size, &info, &chunks, &inspect_error);
    lk_free(chunks);
    /* inspect does not decode payloads: it sees header, table and CRCs. */
    if (status == LK_OK && strncmp(needle, "chunk", 5) == 0) return;
    if (status != LK_ERR_PARSE) fail_msg("inspect: expected a parse error, got %d: %s", status, inspect_error.message);
}

/* ---- tests -------------------------------------------------------------------- */

/* Encode, then decode chunk by chunk: at every chunk boundary the decoder
 * equals the PM level and the table's triangle count; at the end the input
 * mesh comes back (through vertex_order) within the quantisation bound. */
static void check_round_trip(int which)
{
    model *m = get_model(which);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    inspect_ok(m->bytes, m->size, &info, &chunks);
    assert_int_equal(info.version, 1);
    assert_int_equal(info.vertex_count, m->pm.vertex_count);
    assert_int_equal(info.triangle_count, m->pm.triangle_count);
    assert_int_equal(info.base_vertex_count, m->pm.base_vertex_count);
    assert_int_equal(info.base_triangle_count, m->pm.base_triangle_count);
    assert_int_equal(info.split_count, m->pm.split_count);
    assert_int_equal(info.strip_length, m->ps.strip_length);
    assert_int_equal(info.total_size, m->size);
    assert_int_equal(info.chunk_count, 1 + (m->pm.split_count + 1023) / 1024);
    assert_int_equal(info.header_size, 96 + 32 * info.chunk_count + 4);
    assert_true(info.quantisation_error <= 1e-4 * info.diagonal);
    assert_true(fabs(info.diagonal - m->pm.diagonal) <= 1e-12 * m->pm.diagonal);
    /* Default bits are the fewest that meet the bound. */
    assert_true(info.position_bits >= 4 && info.position_bits <= 24);
    assert_true(chunks[0].is_base && chunks[0].split_count == 0);

    lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(decoder, m->bytes, info.header_size);
    const lk_stream_info *decoder_info = lk_stream_decoder_info(decoder);
    assert_non_null(decoder_info);
    assert_memory_equal(decoder_info, &info, sizeof info);
    assert_int_equal(lk_stream_decoder_chunks(decoder), 0);
    size_t middle = info.chunk_count / 2;
    for (size_t c = 0; c < info.chunk_count; c++) {
        feed_ok(decoder, m->bytes + chunks[c].offset, chunks[c].size);
        size_t level = chunks[c].first_split + chunks[c].split_count;
        assert_int_equal(lk_stream_decoder_level(decoder), level);
        assert_int_equal(lk_stream_decoder_chunks(decoder), c + 1);
        assert_int_equal(lk_stream_decoder_bytes(decoder), chunks[c].offset + chunks[c].size);
        assert_int_equal(chunks[c].triangle_count, lk_progressive_mesh_level_triangles(&m->pm, level));
        if (c <= 1 || c == middle || c + 1 == info.chunk_count) assert_decoder_matches_pm(decoder, m, "chunk");
    }
    lk_error error = {0};
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_OK);
    assert_full_round_trip(decoder, m);
    lk_stream_decoder_free(decoder);
    lk_free(chunks);
}

static void test_round_trip_bunny(void **state)
{
    (void)state;
    check_round_trip(BUNNY);
}
static void test_round_trip_cow(void **state)
{
    (void)state;
    check_round_trip(COW);
}
static void test_round_trip_triceratops(void **state)
{
    (void)state;
    check_round_trip(TRICERATOPS);
}
static void test_round_trip_fandisk(void **state)
{
    (void)state;
    check_round_trip(FANDISK);
}

/* Size in bits per vertex at the default bits and at 11 bits (Draco's
 * 10.8 bits/vertex on the bunny is at 11-bit quantisation, single
 * resolution). The bounds are the sizes measured when the format was
 * fixed, plus ~4%: a regression in the coder fails here. */
static void test_size_bits_per_vertex(void **state)
{
    (void)state;
    const struct {
        int which;
        double max_default, max_11;
    } rows[] = {{BUNNY, 75.0, 65.5}, {COW, 87.0, 72.0}};
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        model *m = get_model(rows[i].which);
        lk_stream_options options;
        lk_stream_options_default(&options);
        options.position_bits = 11;
        unsigned char *bytes11;
        size_t size11;
        encode_ok(m, &options, &bytes11, &size11);
        lk_stream_info info, info11;
        lk_stream_chunk_info *chunks;
        inspect_ok(m->bytes, m->size, &info, &chunks);
        lk_free(chunks);
        inspect_ok(bytes11, size11, &info11, &chunks);
        lk_free(chunks);
        assert_int_equal(info11.position_bits, 11);
        double bits = 8.0 * (double)m->size / (double)m->pm.vertex_count;
        double bits11 = 8.0 * (double)size11 / (double)m->pm.vertex_count;

        lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
        double start = now_seconds();
        feed_ok(decoder, m->bytes, m->size);
        lk_mesh decoded;
        lk_test_stream_mesh(decoder, &decoded);
        double decode_seconds = now_seconds() - start;
        lk_mesh_free(&decoded);
        lk_stream_decoder_free(decoder);
        print_message("%-10s %zu bytes = %.2f bits/vertex at %u bits (error <= %.4f%% of the diagonal); %zu bytes = "
                      "%.2f bits/vertex at 11 bits (error <= %.4f%%); encode %.3f s, decode %.3f s\n",
                      m->name, m->size, bits, info.position_bits, 100 * info.quantisation_error / info.diagonal, size11,
                      bits11, 100 * info11.quantisation_error / info11.diagonal, m->encode_seconds, decode_seconds);
        assert_true(bits <= rows[i].max_default);
        assert_true(bits11 <= rows[i].max_11);
        assert_true(bits11 < bits);
        lk_free(bytes11);
    }
}

/* Same result whatever the pieces the bytes arrive in. */
static void assert_same_final_state(const lk_stream_decoder *a, const lk_stream_decoder *b, bool same_layout)
{
    assert_int_equal(lk_stream_decoder_level(a), lk_stream_decoder_level(b));
    if (same_layout) {
        assert_int_equal(lk_stream_decoder_chunks(a), lk_stream_decoder_chunks(b));
        assert_int_equal(lk_stream_decoder_bytes(a), lk_stream_decoder_bytes(b));
    }
    lk_mesh x, y;
    lk_test_stream_mesh(a, &x);
    lk_test_stream_mesh(b, &y);
    assert_int_equal(x.vertex_count, y.vertex_count);
    assert_int_equal(x.triangle_count, y.triangle_count);
    assert_memory_equal(x.positions, y.positions, 3 * x.vertex_count * sizeof(float));
    assert_memory_equal(x.indices, y.indices, 3 * x.triangle_count * sizeof(uint32_t));
    lk_mesh_free(&x);
    lk_mesh_free(&y);
    uint32_t *s, *t;
    size_t s_length, t_length;
    assert_int_equal(lk_stream_decoder_strip(a, 1, &s, &s_length, NULL), LK_OK);
    assert_int_equal(lk_stream_decoder_strip(b, 1, &t, &t_length, NULL), LK_OK);
    assert_int_equal(s_length, t_length);
    assert_memory_equal(s, t, s_length * sizeof(uint32_t));
    lk_free(s);
    lk_free(t);
}

static void test_incremental_feeding(void **state)
{
    (void)state;
    /* Byte by byte (cow), random pieces of 1..8192 bytes (bunny). */
    for (int pass = 0; pass < 2; pass++) {
        model *m = get_model(pass == 0 ? COW : BUNNY);
        lk_stream_info info;
        lk_stream_chunk_info *chunks;
        inspect_ok(m->bytes, m->size, &info, &chunks);
        lk_stream_decoder *whole = lk_test_stream_decoder(SIZE_MAX);
        feed_ok(whole, m->bytes, m->size);
        lk_stream_decoder *pieces = lk_test_stream_decoder(SIZE_MAX);
        uint64_t seed = 12345;
        size_t offset = 0, last_level = 0, chunk = 0;
        while (offset < m->size) {
            size_t piece = 1;
            if (pass == 1) {
                seed = seed * 6364136223846793005ull + 1442695040888963407ull;
                piece = 1 + (size_t)((seed >> 33) % 8192);
            }
            if (piece > m->size - offset) piece = m->size - offset;
            feed_ok(pieces, m->bytes + offset, piece);
            offset += piece;
            /* The level only moves at chunk ends, to the table's levels. */
            size_t level = lk_stream_decoder_level(pieces);
            assert_true(level >= last_level);
            while (chunk < info.chunk_count && chunks[chunk].offset + chunks[chunk].size <= offset) chunk++;
            if (chunk > 0) assert_int_equal(level, chunks[chunk - 1].first_split + chunks[chunk - 1].split_count);
            assert_int_equal(lk_stream_decoder_chunks(pieces), chunk);
            assert_int_equal(lk_stream_decoder_info(pieces) != NULL, offset >= info.header_size);
            last_level = level;
        }
        lk_error error = {0};
        assert_int_equal(lk_stream_decoder_finish(pieces, &error), LK_OK);
        assert_same_final_state(whole, pieces, true);
        lk_stream_decoder_free(whole);
        lk_stream_decoder_free(pieces);
        lk_free(chunks);
    }
}

/* A stream cut short: everything before the cut is decoded and usable,
 * finish names the byte and the chunk. */
static void test_truncated(void **state)
{
    (void)state;
    model *m = get_model(COW);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    inspect_ok(m->bytes, m->size, &info, &chunks);
    assert_true(info.chunk_count >= 4);
    char needle[128];

    /* Inside chunk 3. */
    size_t cut = (size_t)chunks[3].offset + chunks[3].size / 2;
    lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(decoder, m->bytes, cut);
    lk_error error = {0};
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_ERR_TRUNCATED);
    snprintf(needle, sizeof needle, "stopped at byte %zu in chunk 3 of %zu", cut, info.chunk_count);
    lk_assert_message_contains(error, needle);
    assert_int_equal(lk_stream_decoder_level(decoder), chunks[2].first_split + chunks[2].split_count);
    assert_int_equal(lk_stream_decoder_chunks(decoder), 3);
    assert_int_equal(lk_stream_decoder_bytes(decoder), chunks[3].offset);
    assert_decoder_matches_pm(decoder, m, "truncated");
    /* The rest arrives later: the decoder carries on. */
    feed_ok(decoder, m->bytes + cut, m->size - cut);
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_OK);
    assert_int_equal(lk_stream_decoder_level(decoder), m->pm.split_count);
    lk_stream_decoder_free(decoder);

    /* inspect says the same about the cut stream and still fills info. */
    lk_stream_info cut_info;
    lk_stream_chunk_info *cut_chunks = NULL;
    lk_error inspect_error = {0};
    assert_int_equal(lk_stream_inspect(m->bytes, cut, &cut_info, &cut_chunks, &inspect_error), LK_ERR_TRUNCATED);
    lk_assert_message_contains(inspect_error, needle);
    assert_non_null(cut_chunks);
    assert_int_equal(cut_info.chunk_count, info.chunk_count);
    lk_free(cut_chunks);

    /* Inside the header: nothing to show. */
    decoder = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(decoder, m->bytes, 50);
    assert_null(lk_stream_decoder_info(decoder));
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_ERR_TRUNCATED);
    lk_assert_message_contains(error, "stopped at byte 50 in the header");
    lk_mesh mesh;
    assert_int_equal(lk_stream_decoder_mesh(decoder, &mesh, &error), LK_ERR_INVALID);
    uint32_t *strip;
    size_t length;
    assert_int_equal(lk_stream_decoder_strip(decoder, 1, &strip, &length, &error), LK_ERR_INVALID);
    lk_stream_decoder_free(decoder);
    assert_int_equal(lk_stream_inspect(m->bytes, 50, &cut_info, NULL, &inspect_error), LK_ERR_TRUNCATED);

    /* Inside the table. */
    cut = 96 + 40;
    decoder = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(decoder, m->bytes, cut);
    assert_null(lk_stream_decoder_info(decoder));
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_ERR_TRUNCATED);
    snprintf(needle, sizeof needle, "stopped at byte %zu in the chunk table", cut);
    lk_assert_message_contains(error, needle);
    assert_int_equal(lk_stream_decoder_level(decoder), 0);
    lk_stream_decoder_free(decoder);

    /* Header and table only: the base chunk (chunk 0) is missing. */
    decoder = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(decoder, m->bytes, info.header_size);
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_ERR_TRUNCATED);
    snprintf(needle, sizeof needle, "stopped at byte %zu in chunk 0 of %zu", info.header_size, info.chunk_count);
    lk_assert_message_contains(error, needle);
    lk_stream_decoder_free(decoder);
    lk_free(chunks);
}

/* A flipped byte in chunk 2's payload: LK_ERR_PARSE naming chunk 2 and its
 * offset; the level of chunk 1 stays usable and further input is refused. */
static void test_corrupt_chunk(void **state)
{
    (void)state;
    model *m = get_model(COW);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    inspect_ok(m->bytes, m->size, &info, &chunks);
    unsigned char *bytes = copy_bytes(m->bytes, m->size);
    bytes[chunks[2].offset + 8 + (chunks[2].size - 8) / 2] ^= 0x10;

    lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
    lk_error error = {0};
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, m->size, &error), LK_ERR_PARSE);
    char needle[96];
    snprintf(needle, sizeof needle, "chunk 2 at byte %llu: CRC-32 mismatch", (unsigned long long)chunks[2].offset);
    lk_assert_message_contains(error, needle);
    assert_int_equal(lk_stream_decoder_level(decoder), chunks[1].first_split + chunks[1].split_count);
    assert_int_equal(lk_stream_decoder_chunks(decoder), 2);
    assert_decoder_matches_pm(decoder, m, "after corrupt chunk 2");
    lk_error again = {0};
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, 1, &again), LK_ERR_PARSE);
    assert_string_equal(again.message, error.message);
    assert_int_equal(lk_stream_decoder_finish(decoder, &again), LK_ERR_PARSE);
    lk_stream_decoder_free(decoder);

    lk_stream_chunk_info *inspected = NULL;
    assert_int_equal(lk_stream_inspect(bytes, m->size, &info, &inspected, &error), LK_ERR_PARSE);
    lk_assert_message_contains(error, needle);
    lk_free(inspected);
    free(bytes);
    lk_free(chunks);
}

/* Corruption that passes the CRC (payload and CRCs rewritten): the decoder
 * detects it while applying chunk 2, takes back the splits of chunk 2 it
 * had applied and keeps the level of chunk 1. */
static void test_corrupt_payload_rolls_back(void **state)
{
    (void)state;
    model *m = get_model(COW);
    lk_stream_options options;
    lk_stream_options_default(&options);
    options.compress = 0; /* payload bytes are the raw sections */
    unsigned char *clean;
    size_t size;
    encode_ok(m, &options, &clean, &size);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    inspect_ok(clean, size, &info, &chunks);
    for (size_t c = 0; c < info.chunk_count; c++) assert_false(chunks[c].compressed);
    size_t level_1 = chunks[1].first_split + chunks[1].split_count;

    /* (a) The last p of chunk 2 names a vertex that does not exist yet. */
    unsigned char *bytes = copy_bytes(clean, size);
    unsigned char *payload = bytes + chunks[2].offset + 8;
    size_t position = 0;
    uint64_t p_bytes = 0;
    for (int shift = 0;; shift += 7) {
        unsigned char b = payload[position++];
        p_bytes |= (uint64_t)(b & 0x7f) << shift;
        if (!(b & 0x80)) break;
    }
    while (payload[position++] & 0x80) {
    }
    size_t p_start = position, last = p_start;
    for (size_t at = p_start; at < p_start + p_bytes; at++)
        if (at == p_start || !(payload[at - 1] & 0x80)) last = at;
    size_t last_length = p_start + p_bytes - last;
    assert_true(last_length >= 2); /* the cow's 2757 splits need two-byte p codes */
    for (size_t k = 0; k + 1 < last_length; k++) payload[last + k] = 0xff;
    payload[last + last_length - 1] = 0x7f;
    fix_chunk_crc(bytes, &chunks[2], 2);
    lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
    lk_error error = {0};
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, size, &error), LK_ERR_PARSE);
    char needle[128];
    snprintf(needle, sizeof needle, "chunk 2 at byte %llu: split %u: p = ", (unsigned long long)chunks[2].offset,
             (unsigned)(chunks[2].first_split + chunks[2].split_count - 1));
    lk_assert_message_contains(error, needle);
    lk_assert_message_contains(error, "is not a present vertex");
    assert_int_equal(lk_stream_decoder_level(decoder), level_1);
    assert_decoder_matches_pm(decoder, m, "rolled back (a)");
    lk_stream_decoder_free(decoder);
    free(bytes);

    /* (b) The table claims one triangle more after chunk 2 than the strip
     * draws: found after the whole chunk was applied. */
    bytes = copy_bytes(clean, size);
    put32(bytes + 96 + 32 * 2 + 24, chunks[2].triangle_count + 1);
    fix_table_crc(bytes);
    decoder = lk_test_stream_decoder(SIZE_MAX);
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, size, &error), LK_ERR_PARSE);
    snprintf(needle, sizeof needle,
             "chunk 2 at byte %llu: the strip draws %u triangles after the chunk, the table says %u",
             (unsigned long long)chunks[2].offset, (unsigned)chunks[2].triangle_count,
             (unsigned)chunks[2].triangle_count + 1);
    lk_assert_message_contains(error, needle);
    assert_int_equal(lk_stream_decoder_level(decoder), level_1);
    assert_decoder_matches_pm(decoder, m, "rolled back (b)");
    lk_stream_decoder_free(decoder);
    free(bytes);

    /* (c) A byte too many in chunk 1's position section (size fields,
     * offsets and CRCs rewritten): trailing bytes are refused. */
    bytes = malloc(size + 1);
    size_t end1 = chunks[1].offset + chunks[1].size;
    memcpy(bytes, clean, end1);
    bytes[end1] = 0;
    memcpy(bytes + end1 + 1, clean + end1, size - end1);
    lk_stream_chunk_info grown = chunks[1];
    grown.size++;
    put32(bytes + chunks[1].offset, grown.size - 8);
    put32(bytes + 96 + 32 + 8, grown.size);
    put32(bytes + 96 + 32 + 12, grown.size - 8);
    for (size_t c = 2; c < info.chunk_count; c++) put32(bytes + 96 + 32 * c, (uint32_t)chunks[c].offset + 1);
    uint64_t total = size + 1;
    for (int i = 0; i < 8; i++) bytes[16 + i] = (unsigned char)(total >> (8 * i));
    fix_header_crc(bytes);
    fix_chunk_crc(bytes, &grown, 1);
    lk_stream_chunk_info *edited;
    inspect_ok(bytes, size + 1, &info, &edited); /* header, table and CRCs are consistent again */
    lk_free(edited);
    decoder = lk_test_stream_decoder(SIZE_MAX);
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, size + 1, &error), LK_ERR_PARSE);
    lk_assert_message_contains(error, "chunk 1 at byte");
    lk_assert_message_contains(error,
                               "unused bytes after the last split (p section 0, mask section 0, position section 1)");
    assert_int_equal(lk_stream_decoder_level(decoder), 0);
    assert_decoder_matches_pm(decoder, m, "rolled back (c)");
    lk_stream_decoder_free(decoder);
    free(bytes);
    lk_free(chunks);
    lk_free(clean);
}

/* Headers and tables that lie are refused before anything big is
 * allocated, with the offending byte named. */
static void test_malformed_headers(void **state)
{
    (void)state;
    model *m = get_model(COW);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    inspect_ok(m->bytes, m->size, &info, &chunks);
    size_t size = m->size;
    unsigned char *bytes;

#define EDIT(code, needle)                                                                                             \
    do {                                                                                                               \
        bytes = copy_bytes(m->bytes, size);                                                                            \
        code;                                                                                                          \
        assert_refused(bytes, size, needle);                                                                           \
        free(bytes);                                                                                                   \
    } while (0)

    EDIT(bytes[1] = 'X', "header at byte 0: not a lodkit stream (bad magic)");
    EDIT(bytes[8] = 3, "header at byte 8: unsupported version 3");
    EDIT(bytes[84] ^= 1, "header at byte 92: CRC-32 mismatch");
    EDIT((bytes[10] = 1, fix_header_crc(bytes)), "header at byte 10: unknown flags");
    EDIT((put32(bytes + 24, 0xFFFFFFFFu), fix_header_crc(bytes)), "header at byte 24: vertex count 4294967295 is more");
    EDIT((put32(bytes + 24, get32(bytes + 24) + 1), fix_header_crc(bytes)), "is not base");
    /* Two billion splits cannot fit in 30 KB. */
    EDIT((put32(bytes + 40, 2000000000u), put32(bytes + 24, 2000000000u + (uint32_t)info.base_vertex_count),
          fix_header_crc(bytes)),
         "cannot fit in a stream of");
    EDIT((put32(bytes + 44, 0x7FFFFFFFu), fix_header_crc(bytes)), "cannot fit in a stream of");
    EDIT((put32(bytes + 28, (uint32_t)info.strip_length), fix_header_crc(bytes)), "cannot come from a strip");
    EDIT((bytes[56] = 30, fix_header_crc(bytes)), "header at byte 56: position bits 30");
    EDIT((put32(bytes + 48, 0), fix_header_crc(bytes)), "no chunks");
    EDIT((put32(bytes + 48, 100000), fix_header_crc(bytes)), "header at byte 12: header size");
    EDIT((put32(bytes + 72, 0x7f800000u), fix_header_crc(bytes)), "quantisation box of axis 0");
    EDIT((bytes[16] ^= 0x40, fix_header_crc(bytes)), "chunk table entry 3");
    EDIT(bytes[96 + 32 + 5] ^= 1, "CRC-32 mismatch (stored");
    /* Table entries out of range, overlapping or out of order. */
    EDIT((put32(bytes + 96 + 32, (uint32_t)chunks[1].offset + 1), fix_table_crc(bytes)),
         "chunk table entry 1 at byte 128: offset");
    EDIT((put32(bytes + 96 + 64, (uint32_t)chunks[1].offset), fix_table_crc(bytes)),
         "chunk table entry 2 at byte 160: offset");
    EDIT((put32(bytes + 96 + 32 + 8, 0x7FFFFFFFu), fix_table_crc(bytes)), "does not fit in the stream");
    EDIT((put32(bytes + 96 + 32 + 12, 0xFFFFFFFFu), fix_table_crc(bytes)), "raw size 4294967295 is impossible");
    EDIT((put32(bytes + 96 + 32 + 16, 5), fix_table_crc(bytes)), "first split 5, expected 0");
    EDIT((put32(bytes + 96 + 32 + 20, 0), fix_table_crc(bytes)), "0 splits");
    EDIT((put32(bytes + 96 + 20, 7), fix_table_crc(bytes)), "the base chunk claims splits");
    EDIT((put32(bytes + 96 + 32 + 24, 1), fix_table_crc(bytes)), "splits never remove triangles");
    /* The chunk header disagrees with the table. */
    EDIT(put32(bytes + chunks[1].offset, chunks[1].size), "chunk 1 at byte");
    /* A strip length that does not match the base chunk. */
    EDIT((put32(bytes + 44, (uint32_t)info.strip_length - 1), fix_header_crc(bytes)), "chunk 0 at byte");
    EDIT((put32(bytes + 44, (uint32_t)info.strip_length + 1), fix_header_crc(bytes)), "chunk 0 at byte");
#undef EDIT

    /* Bytes after the end of a complete stream. */
    bytes = copy_bytes(m->bytes, size);
    bytes[size] = 0;
    lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
    lk_error error = {0};
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, size + 1, &error), LK_ERR_PARSE);
    lk_assert_message_contains(error, "data after the end of the stream");
    assert_int_equal(lk_stream_decoder_level(decoder), m->pm.split_count);
    lk_stream_decoder_free(decoder);
    lk_stream_chunk_info *inspected = NULL;
    assert_int_equal(lk_stream_inspect(bytes, size + 1, &info, &inspected, &error), LK_ERR_PARSE);
    lk_assert_message_contains(error, "after the end of the stream");
    lk_free(inspected);
    free(bytes);

    /* Not a stream at all, and empty input. */
    const char text[] = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    assert_refused((const unsigned char *)text, sizeof text - 1, "bad magic");
    decoder = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(decoder, NULL, 0);
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_ERR_TRUNCATED);
    lk_stream_decoder_free(decoder);
    lk_free(chunks);
}

/* max_level stops in the middle of a chunk; finish is then OK. */
static void test_max_level(void **state)
{
    (void)state;
    model *m = get_model(COW);
    const size_t levels[] = {0, 1, 1024, 1500, m->pm.split_count - 1, m->pm.split_count, SIZE_MAX - 1};
    for (size_t i = 0; i < sizeof levels / sizeof levels[0]; i++) {
        lk_stream_decoder *decoder = lk_test_stream_decoder(levels[i]);
        feed_ok(decoder, m->bytes, m->size);
        size_t expected = levels[i] < m->pm.split_count ? levels[i] : m->pm.split_count;
        assert_int_equal(lk_stream_decoder_level(decoder), expected);
        lk_error error = {0};
        assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_OK);
        assert_decoder_matches_pm(decoder, m, "max_level");
        /* Bytes after max_level are accepted and ignored; after a complete
         * stream they are an error. */
        if (levels[i] < m->pm.split_count) {
            feed_ok(decoder, m->bytes, 10);
            assert_int_equal(lk_stream_decoder_level(decoder), expected);
        } else {
            assert_int_equal(lk_stream_decoder_feed(decoder, m->bytes, 10, &error), LK_ERR_PARSE);
        }
        lk_stream_decoder_free(decoder);
    }
    /* Stopping early also works when the bytes trickle in. */
    lk_stream_decoder *decoder = lk_test_stream_decoder(1500);
    for (size_t offset = 0; offset < m->size; offset += 333)
        feed_ok(decoder, m->bytes + offset, m->size - offset < 333 ? m->size - offset : 333);
    assert_int_equal(lk_stream_decoder_level(decoder), 1500);
    lk_stream_decoder_free(decoder);
}

/* Options: explicit bits (error bound follows), chunk size, no
 * compression; bad values refused; the same mesh whatever the layout. */
static void test_options(void **state)
{
    (void)state;
    model *m = get_model(TRICERATOPS);
    lk_stream_options defaults;
    lk_stream_options_default(&defaults);
    assert_int_equal(defaults.position_bits, 0);
    assert_int_equal(defaults.splits_per_chunk, 1024);
    assert_int_equal(defaults.compress, 1);

    lk_stream_info base_info;
    lk_stream_chunk_info *chunks;
    inspect_ok(m->bytes, m->size, &base_info, &chunks);
    lk_free(chunks);
    /* The default is the fewest bits meeting 0.01% of the diagonal. */
    lk_stream_options options = defaults;
    options.position_bits = base_info.position_bits - 1;
    unsigned char *bytes;
    size_t size;
    encode_ok(m, &options, &bytes, &size);
    lk_stream_info info;
    inspect_ok(bytes, size, &info, &chunks);
    assert_true(info.quantisation_error > 1e-4 * info.diagonal);
    assert_true(info.quantisation_error < 2.1 * base_info.quantisation_error);
    lk_free(chunks);
    lk_free(bytes);

    const unsigned bits[] = {4, 11, 16, 24};
    for (size_t i = 0; i < 4; i++) {
        options = defaults;
        options.position_bits = bits[i];
        encode_ok(m, &options, &bytes, &size);
        inspect_ok(bytes, size, &info, &chunks);
        lk_free(chunks);
        assert_int_equal(info.position_bits, bits[i]);
        lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
        feed_ok(decoder, bytes, size);
        assert_full_round_trip(decoder, m);
        lk_stream_decoder_free(decoder);
        lk_free(bytes);
    }

    /* 100 splits per chunk, no compression: same decoded mesh. */
    options = defaults;
    options.splits_per_chunk = 100;
    options.compress = 0;
    encode_ok(m, &options, &bytes, &size);
    inspect_ok(bytes, size, &info, &chunks);
    assert_int_equal(info.chunk_count, 1 + (m->pm.split_count + 99) / 100);
    for (size_t c = 0; c < info.chunk_count; c++) {
        assert_false(chunks[c].compressed);
        assert_int_equal(chunks[c].raw_size + 8, chunks[c].size);
        assert_int_equal(chunks[c].is_base, c == 0);
        assert_int_equal(chunks[c].split_count,
                         c == 0 ? 0 : (c + 1 < info.chunk_count ? 100 : m->pm.split_count - 100 * (c - 1)));
    }
    assert_true(size > m->size);
    lk_stream_decoder *plain = lk_test_stream_decoder(SIZE_MAX), *packed = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(plain, bytes, size);
    feed_ok(packed, m->bytes, m->size);
    assert_same_final_state(plain, packed, false);
    lk_stream_decoder_free(plain);
    lk_stream_decoder_free(packed);
    lk_free(chunks);
    lk_free(bytes);

    /* Refused options. */
    lk_error error = {0};
    options = defaults;
    options.position_bits = 3;
    assert_int_equal(lk_stream_encode(&m->pm, &m->ps, &options, &bytes, &size, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "position_bits 3");
    options.position_bits = 25;
    assert_int_equal(lk_stream_encode(&m->pm, &m->ps, &options, &bytes, &size, &error), LK_ERR_INVALID);
    options = defaults;
    options.splits_per_chunk = 0;
    assert_int_equal(lk_stream_encode(&m->pm, &m->ps, &options, &bytes, &size, &error), LK_ERR_INVALID);
    assert_int_equal(lk_stream_encode(NULL, &m->ps, NULL, &bytes, &size, &error), LK_ERR_INVALID);
}

/* Encoding is deterministic; strips that do not belong to the progressive
 * mesh are refused. */
static void test_determinism_and_mismatch(void **state)
{
    (void)state;
    for (int which = 0; which < MODEL_COUNT; which++) {
        model *m = get_model(which);
        unsigned char *again;
        size_t size;
        encode_ok(m, NULL, &again, &size);
        assert_int_equal(size, m->size);
        assert_memory_equal(again, m->bytes, size);
        lk_free(again);
    }
    model *cow = get_model(COW), *triceratops = get_model(TRICERATOPS);
    lk_error error = {0};
    unsigned char *bytes;
    size_t size;
    /* The triceratops' strip names vertices the cow has, but is not its strip. */
    assert_int_not_equal(lk_stream_encode(&cow->pm, &triceratops->ps, NULL, &bytes, &size, &error), LK_OK);
    lk_progressive_strips broken = cow->ps;
    broken.strip = malloc(cow->ps.strip_length * sizeof(uint32_t));
    memcpy(broken.strip, cow->ps.strip, cow->ps.strip_length * sizeof(uint32_t));
    broken.strip[5] = (uint32_t)cow->pm.vertex_count;
    assert_int_equal(lk_stream_encode(&cow->pm, &broken, NULL, &bytes, &size, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "strip entry 5");
    free(broken.strip);
}

static void test_write_file(void **state)
{
    (void)state;
    model *m = get_model(COW);
    const char *path = lk_test_tmpfile("cow.lks");
    lk_error error = {0};
    assert_int_equal(lk_stream_write_file(path, m->bytes, m->size, &error), LK_OK);
    FILE *file = fopen(path, "rb");
    assert_non_null(file);
    unsigned char *back = malloc(m->size + 1);
    assert_int_equal(fread(back, 1, m->size + 1, file), m->size);
    fclose(file);
    assert_memory_equal(back, m->bytes, m->size);
    free(back);
    assert_int_equal(lk_stream_write_file(lk_test_tmpfile("missing/dir/cow.lks"), m->bytes, m->size, &error),
                     LK_ERR_IO);
}

/* A small open grid (border vertices, few splits) and a closed cube. */
static void test_small_meshes(void **state)
{
    (void)state;
    for (int shape = 0; shape < 2; shape++) {
        lk_mesh mesh;
        if (shape == 0)
            lk_test_make_grid(&mesh, 6);
        else
            lk_test_make_cube(&mesh);
        lk_progressive_options options;
        lk_progressive_options_default(&options);
        lk_progressive_mesh pm;
        lk_progressive_strips ps;
        lk_error error = {0};
        if (lk_progressive_mesh_build(&mesh, &options, &pm, NULL, NULL, &error) != LK_OK)
            fail_msg("pm: %s", error.message);
        if (lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &ps, &error) != LK_OK) fail_msg("ps: %s", error.message);
        lk_stream_options stream_options;
        lk_stream_options_default(&stream_options);
        stream_options.splits_per_chunk = 3;
        unsigned char *bytes;
        size_t size;
        if (lk_stream_encode(&pm, &ps, &stream_options, &bytes, &size, &error) != LK_OK)
            fail_msg("encode: %s", error.message);
        lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
        for (size_t offset = 0; offset < size; offset += 7)
            feed_ok(decoder, bytes + offset, size - offset < 7 ? size - offset : 7);
        assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_OK);
        lk_mesh decoded;
        lk_test_stream_mesh(decoder, &decoded);
        assert_int_equal(decoded.vertex_count, mesh.vertex_count);
        assert_same_triangles(decoded.indices, decoded.triangle_count, pm.vertex_order, mesh.indices,
                              mesh.triangle_count, NULL, shape == 0 ? "grid" : "cube");
        lk_mesh_free(&decoded);
        lk_stream_decoder_free(decoder);
        lk_free(bytes);
        lk_progressive_strips_free(&ps);
        lk_progressive_mesh_free(&pm);
        lk_mesh_free(&mesh);
    }
}

/* A stream of one chunk (the base is the whole mesh: no splits) cut inside
 * its chunk table: the messages count "1 chunk", not "1 chunks". */
static void test_single_chunk_messages(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_make_cube(&mesh);
    lk_progressive_options options;
    lk_progressive_options_default(&options);
    options.base_ratio = 1.0;
    lk_progressive_mesh pm;
    lk_progressive_strips ps;
    lk_error error = {0};
    if (lk_progressive_mesh_build(&mesh, &options, &pm, NULL, NULL, &error) != LK_OK) fail_msg("pm: %s", error.message);
    if (lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &ps, &error) != LK_OK) fail_msg("ps: %s", error.message);
    unsigned char *bytes;
    size_t size;
    if (lk_stream_encode(&pm, &ps, NULL, &bytes, &size, &error) != LK_OK) fail_msg("encode: %s", error.message);
    lk_stream_info info;
    inspect_ok(bytes, size, &info, NULL);
    assert_int_equal(info.chunk_count, 1);
    size_t cut = 100; /* 96-byte fixed header, then the table */
    assert_true(cut < info.header_size);
    char needle[120];
    snprintf(needle, sizeof needle, "stopped at byte %zu in the chunk table (1 chunk, header ends at byte %zu)", cut,
             info.header_size);
    lk_stream_decoder *decoder = lk_test_stream_decoder(SIZE_MAX);
    feed_ok(decoder, bytes, cut);
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_ERR_TRUNCATED);
    lk_assert_message_contains(error, needle);
    lk_stream_decoder_free(decoder);
    lk_error inspect_error = {0};
    assert_int_equal(lk_stream_inspect(bytes, cut, &info, NULL, &inspect_error), LK_ERR_TRUNCATED);
    lk_assert_message_contains(inspect_error, needle);
    lk_free(bytes);
    lk_progressive_strips_free(&ps);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_bunny),
        cmocka_unit_test(test_round_trip_cow),
        cmocka_unit_test(test_round_trip_triceratops),
        cmocka_unit_test(test_round_trip_fandisk),
        cmocka_unit_test(test_size_bits_per_vertex),
        cmocka_unit_test(test_incremental_feeding),
        cmocka_unit_test(test_truncated),
        cmocka_unit_test(test_corrupt_chunk),
        cmocka_unit_test(test_corrupt_payload_rolls_back),
        cmocka_unit_test(test_malformed_headers),
        cmocka_unit_test(test_max_level),
        cmocka_unit_test(test_options),
        cmocka_unit_test(test_determinism_and_mismatch),
        cmocka_unit_test(test_write_file),
        cmocka_unit_test(test_small_meshes),
        cmocka_unit_test(test_single_chunk_messages),
    };
    return cmocka_run_group_tests(tests, NULL, teardown_models);
}
