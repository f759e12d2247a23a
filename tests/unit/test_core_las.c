/* SPDX-License-Identifier: MIT */
/* LAS reader and writer (src/io_las.c) on small files written here by a
 * builder of its own (not the library's writer): every point data record
 * format 0 to 10 in LAS 1.2, 1.3 and 1.4 headers, with variable length
 * records before the points and extra bytes after each record; 16-bit and
 * 8-bit colours; write -> read round trips within the written scale; every
 * malformed header refused with the byte offset of the field at fault. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* ---- writing LAS files ------------------------------------------------------ */

typedef struct bytes {
    unsigned char data[16384];
    size_t size;
} bytes;

static void store_le(unsigned char *at, uint64_t value, int size)
{
    for (int i = 0; i < size; i++) at[i] = (unsigned char)(value >> (8 * i));
}

static void store_double(unsigned char *at, double value)
{
    uint64_t bits;
    memcpy(&bits, &value, sizeof bits);
    store_le(at, bits, 8);
}

/* Point data record formats: record size, where RGB starts (0: none). */
static const size_t format_sizes[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static const size_t format_rgb_at[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

typedef struct las_point {
    int32_t xyz[3];
    uint16_t rgb[3];
} las_point;

typedef struct las_spec {
    unsigned minor; /* LAS 1.minor */
    unsigned format;
    size_t extra_bytes; /* after each record */
    size_t vlr_payload; /* one variable length record of this many bytes (0: none) */
    double scale[3], offset[3];
    bool count_64_only; /* 1.4: legacy count 0, only the 64-bit count */
} las_spec;

static const las_spec plain_spec = {2, 0, 0, 0, {0.01, 0.01, 0.01}, {0, 0, 0}, false};

/* A LAS file of these points, as the specification lays it out. */
static void build_las(bytes *out, const las_spec *spec, const las_point *points, size_t count)
{
    size_t header_size = spec->minor <= 2 ? 227 : spec->minor == 3 ? 235 : 375;
    size_t vlr_size = spec->vlr_payload ? 54 + spec->vlr_payload : 0;
    size_t record = format_sizes[spec->format] + spec->extra_bytes;
    size_t point_offset = header_size + vlr_size;
    out->size = point_offset + count * record;
    assert_true(out->size <= sizeof out->data);
    unsigned char *h = out->data;
    memset(h, 0, point_offset);
    memcpy(h, "LASF", 4);
    h[24] = 1;
    h[25] = (unsigned char)spec->minor;
    memcpy(h + 26, "test_core_las", 13);
    store_le(h + 94, header_size, 2);
    store_le(h + 96, point_offset, 4);
    store_le(h + 100, spec->vlr_payload ? 1 : 0, 4);
    h[104] = (unsigned char)spec->format;
    store_le(h + 105, record, 2);
    store_le(h + 107, spec->count_64_only ? 0 : count, 4);
    for (int k = 0; k < 3; k++) {
        store_double(h + 131 + 8 * k, spec->scale[k]);
        store_double(h + 155 + 8 * k, spec->offset[k]);
    }
    if (spec->minor >= 4) store_le(h + 247, count, 8);
    if (vlr_size) {
        unsigned char *vlr = h + header_size;
        memcpy(vlr + 2, "test", 4); /* user id */
        store_le(vlr + 20, 1, 2);   /* record id */
        store_le(vlr + 22, spec->vlr_payload, 2);
        memset(vlr + 54, 0x5a, spec->vlr_payload);
    }
    for (size_t i = 0; i < count; i++) {
        unsigned char *r = out->data + point_offset + i * record;
        /* Intensity, returns, classification, GPS time, NIR, wave packets
         * and extra bytes: anything, the reader steps over them. */
        memset(r, 0xa5, record);
        for (int k = 0; k < 3; k++) store_le(r + 4 * k, (uint32_t)points[i].xyz[k], 4);
        if (format_rgb_at[spec->format])
            for (int k = 0; k < 3; k++) store_le(r + format_rgb_at[spec->format] + 2 * k, points[i].rgb[k], 2);
    }
}

static const las_point three_points[3] = {
    {{0, 0, 0}, {0, 0, 0}},
    {{123456, -98765, 4321}, {65535, 32768, 1}},
    {{-2147483647 - 1, 2147483647, -7}, {1000, 20000, 65535}},
};

static lk_status read_las(const bytes *file, const char *name, lk_mesh *mesh, lk_error *error)
{
    return lk_mesh_read_memory(file->data, file->size, name, LK_FORMAT_AUTO, NULL, mesh, error);
}

static void check_points(const lk_mesh *mesh, const las_spec *spec, const las_point *points, size_t count,
                         float color_full)
{
    assert_int_equal(mesh->vertex_count, count);
    assert_int_equal(mesh->triangle_count, 0);
    assert_null(mesh->normals);
    assert_int_equal(mesh->colors != NULL, format_rgb_at[spec->format] != 0);
    for (size_t i = 0; i < count; i++) {
        for (int k = 0; k < 3; k++) {
            float expected = (float)(points[i].xyz[k] * spec->scale[k] + spec->offset[k]);
            assert_true(mesh->positions[3 * i + (size_t)k] == expected);
        }
        if (!mesh->colors) continue;
        for (int k = 0; k < 3; k++) assert_true(mesh->colors[4 * i + (size_t)k] == points[i].rgb[k] / color_full);
        assert_true(mesh->colors[4 * i + 3] == 1.0f);
    }
}

/* ---- reading ------------------------------------------------------------------ */

/* Formats 0 to 10, each in the versions that define it, with and without
 * VLRs and extra bytes, legacy and 64-bit counts. */
static void test_every_format(void **state)
{
    (void)state;
    static bytes file;
    for (unsigned format = 0; format <= 10; format++) {
        unsigned first_minor = format <= 1 ? 0 : format <= 3 ? 2 : format <= 5 ? 3 : 4;
        for (unsigned minor = first_minor; minor <= 4; minor++) {
            for (int variant = 0; variant < 2; variant++) {
                las_spec spec = {minor,
                                 format,
                                 variant ? 5 : 0,
                                 variant ? 17 : 0,
                                 {0.001, 0.01, 0.25},
                                 {-10.5, 1000.0, 0.0},
                                 minor == 4 && (format >= 6 || variant)};
                build_las(&file, &spec, three_points, 3);
                lk_mesh mesh;
                lk_error error = {0};
                lk_status status = read_las(&file, "every.las", &mesh, &error);
                if (status != LK_OK) fprintf(stderr, "format %u, 1.%u: %s\n", format, minor, error.message);
                assert_int_equal(status, LK_OK);
                check_points(&mesh, &spec, three_points, 3, 65535.0f);
                lk_mesh_free(&mesh);
            }
        }
    }
}

/* Colours that never exceed 255 are 8-bit values in 16-bit fields (as
 * many writers store them): read against 255, not 65535. One channel of
 * one point at 256 makes the whole file 16-bit again. */
static void test_8bit_colors(void **state)
{
    (void)state;
    static bytes file;
    las_point points[2] = {{{1, 2, 3}, {255, 128, 0}}, {{4, 5, 6}, {10, 20, 30}}};
    las_spec spec = plain_spec;
    spec.format = 3;
    build_las(&file, &spec, points, 2);
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(read_las(&file, "rgb8.las", &mesh, &error), LK_OK);
    check_points(&mesh, &spec, points, 2, 255.0f);
    lk_mesh_free(&mesh);
    points[1].rgb[2] = 256;
    build_las(&file, &spec, points, 2);
    assert_int_equal(read_las(&file, "rgb16.las", &mesh, &error), LK_OK);
    check_points(&mesh, &spec, points, 2, 65535.0f);
    lk_mesh_free(&mesh);
}

/* A georeferenced tile: the coordinate is computed in double and rounded
 * once to float (no translation; docs/formats.md says what a float keeps). */
static void test_georeferenced(void **state)
{
    (void)state;
    static bytes file;
    las_point points[2] = {{{3084, 10093, 1196}, {0}}, {{36568, 33932, 80815}, {0}}};
    las_spec spec = {2, 1, 0, 0, {0.01, 0.01, 0.001}, {2230708.0, 251970.0, 0.0}, false};
    build_las(&file, &spec, points, 2);
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(read_las(&file, "geo.las", &mesh, &error), LK_OK);
    check_points(&mesh, &spec, points, 2, 65535.0f);
    /* x = 2230738.84: floats are 0.25 apart there; y = 252070.93: 1/64 apart. */
    assert_true(mesh.positions[0] == 2230738.75f);
    assert_true(mesh.positions[1] == 252070.9375f);
    assert_true(mesh.positions[2] == 1.196f);
    lk_mesh_free(&mesh);
}

/* Found by its signature under any name; the format by extension too. */
static void test_detection(void **state)
{
    (void)state;
    static bytes file;
    build_las(&file, &plain_spec, three_points, 3);
    assert_int_equal(lk_format_sniff(file.data, file.size), LK_FORMAT_LAS);
    assert_int_equal(lk_format_from_path("tile.LAS"), LK_FORMAT_LAS);
    assert_string_equal(lk_format_name(LK_FORMAT_LAS), "las");
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(read_las(&file, "tile.bin", &mesh, &error), LK_OK);
    check_points(&mesh, &plain_spec, three_points, 3, 65535.0f);
    lk_mesh_free(&mesh);
}

/* ---- malformed files ---------------------------------------------------------- */

static void expect_error(const bytes *file, const char *name, lk_status expected_status, const char *expected_message)
{
    lk_mesh mesh;
    lk_error error = {0};
    lk_status status = read_las(file, name, &mesh, &error);
    if (status == LK_OK || strcmp(error.message, expected_message) != 0)
        fprintf(stderr, "got %d '%s'\nexpected '%s'\n", status, error.message, expected_message);
    assert_int_equal(status, expected_status);
    assert_string_equal(error.message, expected_message);
    assert_int_equal(mesh.vertex_count, 0);
    assert_null(mesh.positions);
}

static void test_bad_headers(void **state)
{
    (void)state;
    static bytes file;
    build_las(&file, &plain_spec, three_points, 3);
    size_t size = file.size; /* 227 + 3 * 20 */

    memcpy(file.data, "LASG", 4);
    expect_error(&file, "bad.las", LK_ERR_PARSE, "bad.las: byte 0: not a LAS file (it does not start with LASF)");
    memcpy(file.data, "LASF", 4);

    file.size = 100;
    expect_error(&file, "cut.las", LK_ERR_PARSE,
                 "cut.las: byte 100: the header is cut short: a LAS header has at least 227 bytes, the file 100");
    file.size = size;

    file.data[24] = 2;
    expect_error(&file, "v2.las", LK_ERR_UNSUPPORTED, "v2.las: byte 24: LAS version 2.2 (expected 1.0 to 1.4)");
    file.data[24] = 1;
    file.data[25] = 5;
    expect_error(&file, "v15.las", LK_ERR_UNSUPPORTED, "v15.las: byte 24: LAS version 1.5 (expected 1.0 to 1.4)");
    file.data[25] = 2;

    store_le(file.data + 94, 200, 2);
    expect_error(&file, "hs.las", LK_ERR_PARSE,
                 "hs.las: byte 94: header size 200 is less than the 227 bytes of a LAS header (the file has 287 "
                 "bytes)");
    store_le(file.data + 94, 300, 2);
    expect_error(&file, "hs.las", LK_ERR_PARSE,
                 "hs.las: byte 94: header size 300 is past the end of the file (the file has 287 bytes)");
    store_le(file.data + 94, 227, 2);

    store_le(file.data + 96, 288, 4);
    expect_error(&file, "off.las", LK_ERR_PARSE,
                 "off.las: byte 96: offset to point data 288 is past the end of the file (header 227 bytes, file "
                 "287 bytes)");
    store_le(file.data + 96, 0xffffffffu, 4);
    expect_error(&file, "off.las", LK_ERR_PARSE,
                 "off.las: byte 96: offset to point data 4294967295 is past the end of the file (header 227 bytes, "
                 "file 287 bytes)");
    store_le(file.data + 96, 100, 4);
    expect_error(&file, "off.las", LK_ERR_PARSE,
                 "off.las: byte 96: offset to point data 100 is inside the header (header 227 bytes, file 287 "
                 "bytes)");
    store_le(file.data + 96, 227, 4);

    file.data[104] = 11;
    expect_error(&file, "fmt.las", LK_ERR_UNSUPPORTED,
                 "fmt.las: byte 104: point data record format 11 (expected 0 to 10)");
    file.data[104] = 0x83; /* LASzip: format 3, compressed */
    expect_error(&file, "x.laz", LK_ERR_UNSUPPORTED,
                 "x.laz: byte 104: the points are LAZ-compressed (point format byte 0x83); lodkit reads "
                 "uncompressed LAS only: decompress it first, e.g. 'laszip -i IN.laz -o OUT.las' or 'pdal "
                 "translate IN.laz OUT.las'");
    file.data[104] = 0;

    store_le(file.data + 105, 19, 2);
    expect_error(&file, "rl.las", LK_ERR_PARSE,
                 "rl.las: byte 105: point record length 19 is less than the 20 bytes of point format 0");
    file.data[104] = 10;
    store_le(file.data + 105, 66, 2);
    expect_error(&file, "rl.las", LK_ERR_PARSE,
                 "rl.las: byte 105: point record length 66 is less than the 67 bytes of point format 10");
    file.data[104] = 0;
    store_le(file.data + 105, 20, 2);

    store_double(file.data + 131 + 8, 0.0);
    expect_error(&file, "sc.las", LK_ERR_PARSE,
                 "sc.las: byte 139: y scale factor 0 (expected a finite number other than 0)");
    store_double(file.data + 131 + 8, INFINITY);
    expect_error(&file, "sc.las", LK_ERR_PARSE,
                 "sc.las: byte 139: y scale factor inf (expected a finite number other than 0)");
    store_double(file.data + 131 + 8, 0.01);
    store_double(file.data + 155 + 16, NAN);
    expect_error(&file, "of.las", LK_ERR_PARSE, "of.las: byte 171: z offset nan is not a finite number");
    store_double(file.data + 155 + 16, 0.0);

    /* A scale that makes a coordinate larger than any float: the record's X is named. */
    store_double(file.data + 131, 1e300);
    expect_error(&file, "big.las", LK_ERR_PARSE,
                 "big.las: byte 247: point 1: x = 1.23456e+305 does not fit in a float");
    store_double(file.data + 131, 0.01);

    /* The untouched file reads. */
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(read_las(&file, "ok.las", &mesh, &error), LK_OK);
    lk_mesh_free(&mesh);
}

static void test_bad_counts(void **state)
{
    (void)state;
    static bytes file;
    build_las(&file, &plain_spec, three_points, 3);

    store_le(file.data + 107, 4, 4);
    expect_error(&file, "more.las", LK_ERR_PARSE,
                 "more.las: byte 227: the header claims 4 points of 20 bytes but only 60 bytes (3 points) follow "
                 "(truncated or corrupt file)");
    file.size -= 1; /* a cut last record */
    store_le(file.data + 107, 3, 4);
    expect_error(&file, "cut.las", LK_ERR_PARSE,
                 "cut.las: byte 227: the header claims 3 points of 20 bytes but only 59 bytes (2 points) follow "
                 "(truncated or corrupt file)");
    file.size += 1;
    store_le(file.data + 107, 0, 4);
    expect_error(&file, "none.las", LK_ERR_PARSE, "none.las: byte 107: no points (the point count is 0)");

    /* LAS 1.4: the 64-bit count (byte 247) wins over the legacy one. */
    las_spec spec = plain_spec;
    spec.minor = 4;
    spec.format = 6;
    spec.count_64_only = true;
    build_las(&file, &spec, three_points, 3);
    store_le(file.data + 247, 0xffffffffffull, 8);
    expect_error(&file, "c64.las", LK_ERR_PARSE,
                 "c64.las: byte 375: the header claims 1099511627775 points of 30 bytes but only 90 bytes (3 points) "
                 "follow (truncated or corrupt file)");
    store_le(file.data + 107, 3, 4);
    store_le(file.data + 247, 0, 8); /* 64-bit count 0: the legacy one is read */
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(read_las(&file, "legacy.las", &mesh, &error), LK_OK);
    check_points(&mesh, &spec, three_points, 3, 65535.0f);
    lk_mesh_free(&mesh);

    /* Points that fit the file but not the memory budget. */
    build_las(&file, &plain_spec, three_points, 3);
    lk_read_options options = {.max_bytes = file.size + 30}; /* 3 points need 36 bytes */
    assert_int_equal(lk_mesh_read_memory(file.data, file.size, "budget.las", LK_FORMAT_AUTO, &options, &mesh, &error),
                     LK_ERR_LIMIT);
    assert_string_equal(error.message,
                        "budget.las: byte 107: 3 points would need more than the memory budget of 317 bytes");
    assert_null(mesh.positions);
}

/* ---- writing -------------------------------------------------------------------- */

static double header_double(const unsigned char *file, size_t at)
{
    uint64_t bits = 0;
    for (int i = 0; i < 8; i++) bits |= (uint64_t)file[at + (size_t)i] << (8 * i);
    double value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

/* Written as LAS 1.2 (format 2 with colours, 0 without) and read back:
 * every coordinate within half the scale the writer chose, which is at
 * most 0.001 and at most half a float's spacing at the bounds. */
static void round_trip(const lk_mesh *mesh, bool with_colors)
{
    lk_error error = {0};
    const char *path = lk_test_tmpfile("round.las");
    lk_write_options options = {0};
    options.skip_colors = !with_colors;
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, mesh, &options, &error), LK_OK);
    size_t size;
    unsigned char *file = lk_test_read_file(path, &size);
    size_t record = with_colors ? 26 : 20;
    assert_int_equal(size, 227 + record * mesh->vertex_count);
    assert_memory_equal(file, "LASF", 4);
    assert_int_equal(file[24], 1);
    assert_int_equal(file[25], 2);
    assert_int_equal(file[104], with_colors ? 2 : 0);
    assert_int_equal(file[105], record);
    lk_mesh back;
    assert_int_equal(lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &back, &error), LK_OK);
    assert_int_equal(back.vertex_count, mesh->vertex_count);
    assert_int_equal(back.colors != NULL, with_colors);
    for (int k = 0; k < 3; k++) {
        double scale = header_double(file, 131 + 8 * (size_t)k);
        float lowest = INFINITY, highest = -INFINITY;
        for (size_t i = 0; i < mesh->vertex_count; i++) {
            float value = mesh->positions[3 * i + (size_t)k];
            lowest = fminf(lowest, value);
            highest = fmaxf(highest, value);
        }
        double magnitude = fmax(fabs(lowest), fabs(highest));
        assert_true(scale <= 0.001);
        assert_true(scale <= magnitude * 0x1p-24 || magnitude == 0);
        for (size_t i = 0; i < mesh->vertex_count; i++) {
            double written = mesh->positions[3 * i + (size_t)k], read = back.positions[3 * i + (size_t)k];
            /* half a step of the scale, then the float rounding of the result */
            assert_true(fabs(read - written) <= scale / 2 + fabs(written) * 0x1p-24);
        }
        /* The header's bounds hold every point. */
        assert_true(header_double(file, 179 + 16 * (size_t)k) >= highest - scale);
        assert_true(header_double(file, 179 + 16 * (size_t)k + 8) <= lowest + scale);
    }
    for (size_t i = 0; with_colors && i < 4 * mesh->vertex_count; i++)
        assert_float_equal(back.colors[i], mesh->colors[i], 0.6 / 65535);
    lk_mesh_free(&back);
    free(file);
}

static void test_round_trip(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error = {0};
    const size_t count = 500;
    assert_int_equal(lk_mesh_alloc(&mesh, count, 0, LK_ATTR_COLORS, &error), LK_OK);
    /* Small, large, negative and georeferenced-size coordinates. */
    const float centres[3] = {0.0f, -1234.5f, 2230738.8f};
    for (size_t i = 0; i < count; i++) {
        for (int k = 0; k < 3; k++) {
            float t = (float)((i * (size_t)(7 + 3 * k)) % 101) / 101.0f;
            mesh.positions[3 * i + (size_t)k] = centres[k] + (t - 0.5f) * (k == 0 ? 1e-3f : 250.0f);
        }
        for (int k = 0; k < 3; k++) mesh.colors[4 * i + (size_t)k] = (float)((i + (size_t)k * 40) % 256) / 255.0f;
        mesh.colors[4 * i + 3] = 1.0f;
    }
    round_trip(&mesh, true);
    round_trip(&mesh, false);
    /* All points at one place: nothing to divide by. */
    for (size_t i = 0; i < 3 * count; i++) mesh.positions[i] = 0.0f;
    round_trip(&mesh, false);
    lk_mesh_free(&mesh);
}

/* A mesh's vertices are written; its triangles are dropped. */
static void test_write_mesh_vertices(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&mesh, 3, 1, 0, &error), LK_OK);
    const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t indices[3] = {0, 1, 2};
    memcpy(mesh.positions, positions, sizeof positions);
    memcpy(mesh.indices, indices, sizeof indices);
    const char *path = lk_test_tmpfile("triangle.las");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, &mesh, NULL, &error), LK_OK);
    lk_mesh back;
    assert_int_equal(lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &back, &error), LK_OK);
    assert_int_equal(back.vertex_count, 3);
    assert_int_equal(back.triangle_count, 0);
    for (int i = 0; i < 9; i++) assert_true(back.positions[i] == positions[i]);
    lk_mesh_free(&back);
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_format),  cmocka_unit_test(test_8bit_colors),
        cmocka_unit_test(test_georeferenced), cmocka_unit_test(test_detection),
        cmocka_unit_test(test_bad_headers),   cmocka_unit_test(test_bad_counts),
        cmocka_unit_test(test_round_trip),    cmocka_unit_test(test_write_mesh_vertices),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
