/* SPDX-License-Identifier: MIT */
/* PCD reader (src/io_pcd.c) on small files written here: each DATA kind
 * (ascii, binary, binary_compressed through a tiny LZF encoder below)
 * read back bit for bit, skipped fields of every SIZE/TYPE/COUNT, NaN
 * points dropped, and every malformed header or body refused with its
 * message. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* ---- writing PCD files ------------------------------------------------------ */

typedef struct bytes {
    unsigned char data[8192];
    size_t size;
} bytes;

static void put(bytes *out, const void *data, size_t size)
{
    assert_true(out->size + size <= sizeof out->data);
    memcpy(out->data + out->size, data, size);
    out->size += size;
}

static void put_text(bytes *out, const char *text) { put(out, text, strlen(text)); }

/* The header every test file shares but for FIELDS..COUNT and DATA. */
static void put_header(bytes *out, const char *fields, const char *sizes, const char *types, const char *counts,
                       unsigned width, unsigned height, unsigned points, const char *data)
{
    char text[1024];
    snprintf(text, sizeof text,
             "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\n"
             "WIDTH %u\nHEIGHT %u\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %u\nDATA %s\n",
             fields, sizes, types, counts, width, height, points, data);
    put_text(out, text);
}

/* Greedy LZF (liblzf's format, as the reader's comment says): back-
 * references of 3 to 264 bytes up to 8192 back, else literal runs of at
 * most 32 bytes. Brute-force search: the inputs are tiny. */
static size_t lzf_encode(const unsigned char *in, size_t size, unsigned char *out)
{
    size_t ip = 0, op = 0, literal_start = 0;
    while (ip <= size) {
        size_t best_length = 0, best_distance = 0;
        for (size_t distance = 1; ip < size && distance <= ip && distance <= 8192; distance++) {
            size_t length = 0;
            while (ip + length < size && length < 264 && in[ip + length] == in[ip + length - distance]) length++;
            if (length > best_length) best_length = length, best_distance = distance;
        }
        bool flush = ip == size || best_length >= 3 || ip - literal_start == 32;
        if (flush && ip > literal_start) {
            out[op++] = (unsigned char)(ip - literal_start - 1);
            memcpy(out + op, in + literal_start, ip - literal_start);
            op += ip - literal_start;
            literal_start = ip;
        }
        if (ip == size) break;
        if (best_length >= 3) {
            size_t length = best_length - 2, offset = best_distance - 1;
            if (length < 7) {
                out[op++] = (unsigned char)(length << 5 | offset >> 8);
            } else {
                out[op++] = (unsigned char)(7 << 5 | offset >> 8);
                out[op++] = (unsigned char)(length - 7);
            }
            out[op++] = (unsigned char)(offset & 0xff);
            ip += best_length;
            literal_start = ip;
        } else {
            ip++;
        }
    }
    return op;
}

static void put_u32(bytes *out, uint32_t value)
{
    unsigned char le[4] = {(unsigned char)value, (unsigned char)(value >> 8), (unsigned char)(value >> 16),
                           (unsigned char)(value >> 24)};
    put(out, le, 4);
}

static float bits_float(uint32_t bits)
{
    float value;
    memcpy(&value, &bits, 4);
    return value;
}

/* ---- the cloud every DATA kind holds ----------------------------------------- */

/* Fields: x y z (F4), intensity (U2, COUNT 3, skipped), normal_x normal_y
 * normal_z (F4), rgba (U4), t (F8, skipped), k (I1, skipped). Point 1 has a
 * NaN y and is dropped. */
#define CLOUD_FIELDS "x y z intensity normal_x normal_y normal_z rgba t k"
#define CLOUD_SIZES "4 4 4 2 4 4 4 4 8 1"
#define CLOUD_TYPES "F F F U F F F U F I"
#define CLOUD_COUNTS "1 1 1 3 1 1 1 1 1 1"
enum { CLOUD_POINTS = 3, CLOUD_POINT_SIZE = 12 + 6 + 12 + 4 + 8 + 1 };
static const float cloud_xyz[CLOUD_POINTS][3] = {{0.1f, -2.5f, 1e-7f}, {1, NAN, 3}, {-1e20f, 3.25f, 7}};
static const float cloud_normal[CLOUD_POINTS][3] = {{0, 0.6f, 0.8f}, {1, 0, 0}, {-1, 0, 0}};
static const uint32_t cloud_rgba[CLOUD_POINTS] = {0x80ff4020u, 0xffffffffu, 0x00010203u};

/* The fields of point i, in order, little-endian. */
static void cloud_field(size_t i, int field, bytes *out)
{
    const uint16_t intensity[3] = {1, 65535, 7};
    const double t = -1.5;
    const signed char k = -3;
    switch (field) {
    case 0:
    case 1:
    case 2: put(out, &cloud_xyz[i][field], 4); break;
    case 3: put(out, intensity, sizeof intensity); break;
    case 4:
    case 5:
    case 6: put(out, &cloud_normal[i][field - 4], 4); break;
    case 7: put_u32(out, cloud_rgba[i]); break;
    case 8: put(out, &t, 8); break;
    default: put(out, &k, 1); break;
    }
}

static void check_cloud(const lk_mesh *mesh)
{
    assert_int_equal(mesh->vertex_count, 2);
    assert_int_equal(mesh->triangle_count, 0);
    assert_non_null(mesh->normals);
    assert_non_null(mesh->colors);
    assert_null(mesh->texcoords);
    static const size_t kept[2] = {0, 2};
    for (size_t i = 0; i < 2; i++) {
        size_t source = kept[i];
        assert_memory_equal(mesh->positions + 3 * i, cloud_xyz[source], 12);
        assert_memory_equal(mesh->normals + 3 * i, cloud_normal[source], 12);
        uint32_t rgba = cloud_rgba[source];
        const float color[4] = {(float)(rgba >> 16 & 0xff) / 255.0f, (float)(rgba >> 8 & 0xff) / 255.0f,
                                (float)(rgba & 0xff) / 255.0f, (float)(rgba >> 24) / 255.0f};
        assert_memory_equal(mesh->colors + 4 * i, color, 16);
    }
}

static lk_status read_bytes(const bytes *file, lk_mesh *mesh, lk_error *error)
{
    return lk_mesh_read_memory(file->data, file->size, "t.pcd", LK_FORMAT_AUTO, NULL, mesh, error);
}

static void read_ok(const bytes *file, lk_mesh *mesh)
{
    lk_error error = {0};
    lk_status status = read_bytes(file, mesh, &error);
    if (status != LK_OK) fprintf(stderr, "%s\n", error.message);
    assert_int_equal(status, LK_OK);
}

static void test_binary(void **state)
{
    (void)state;
    bytes file = {0};
    put_header(&file, CLOUD_FIELDS, CLOUD_SIZES, CLOUD_TYPES, CLOUD_COUNTS, CLOUD_POINTS, 1, CLOUD_POINTS, "binary");
    for (size_t i = 0; i < CLOUD_POINTS; i++)
        for (int f = 0; f < 10; f++) cloud_field(i, f, &file);
    lk_mesh mesh;
    read_ok(&file, &mesh);
    check_cloud(&mesh);
    lk_mesh_free(&mesh);
    /* detected by content too */
    assert_int_equal(lk_format_sniff(file.data, file.size), LK_FORMAT_PCD);
}

/* The body of a binary_compressed file: field after field. */
static void compressed_body(bytes *raw)
{
    for (int f = 0; f < 10; f++)
        for (size_t i = 0; i < CLOUD_POINTS; i++) cloud_field(i, f, raw);
}

static void put_compressed(bytes *file, const bytes *raw)
{
    unsigned char packed[8192];
    size_t packed_size = lzf_encode(raw->data, raw->size, packed);
    put_u32(file, (uint32_t)packed_size);
    put_u32(file, (uint32_t)raw->size);
    put(file, packed, packed_size);
}

static void test_compressed(void **state)
{
    (void)state;
    bytes raw = {0}, file = {0};
    compressed_body(&raw);
    assert_int_equal(raw.size, CLOUD_POINTS * CLOUD_POINT_SIZE);
    put_header(&file, CLOUD_FIELDS, CLOUD_SIZES, CLOUD_TYPES, CLOUD_COUNTS, CLOUD_POINTS, 1, CLOUD_POINTS,
               "binary_compressed");
    put_compressed(&file, &raw);
    lk_mesh mesh;
    read_ok(&file, &mesh);
    check_cloud(&mesh);
    lk_mesh_free(&mesh);
}

/* Long runs: back-references of every length class (short, 7 + extra byte,
 * overlapping copies) through a 300-point cloud of few distinct values. */
static void test_compressed_runs(void **state)
{
    (void)state;
    enum { N = 300 };
    bytes raw = {0}, file = {0};
    for (int axis = 0; axis < 3; axis++)
        for (int i = 0; i < N; i++) {
            float value = (float)((i / 7) % 5) + (float)axis;
            put(&raw, &value, 4);
        }
    put_header(&file, "x y z", "4 4 4", "F F F", "1 1 1", N, 1, N, "binary_compressed");
    size_t header_size = file.size;
    put_compressed(&file, &raw);
    assert_true(file.size - header_size < raw.size / 4); /* the encoder did use back-references */
    lk_mesh mesh;
    read_ok(&file, &mesh);
    assert_int_equal(mesh.vertex_count, N);
    assert_memory_equal(mesh.positions + 0, &(float){0}, 4);
    for (int i = 0; i < N; i++)
        for (int axis = 0; axis < 3; axis++)
            assert_true(mesh.positions[3 * i + axis] == (float)((i / 7) % 5) + (float)axis);
    lk_mesh_free(&mesh);
}

static void test_ascii(void **state)
{
    (void)state;
    bytes file = {0};
    /* rgb typed F (its bits are the colour), a COUNT 2 field, an organised 2x2 grid with a NaN point. */
    put_header(&file, "x y z rgb normal_x normal_y normal_z curvature", "4 4 4 4 4 4 4 4", "F F F F F F F F",
               "1 1 1 1 1 1 1 2", 2, 2, 4, "ascii");
    char text[1024];
    float rgb = bits_float(0x00ff8001u);
    snprintf(text, sizeof text,
             "0.5 -1 2 %.9g 0 0 1 0.1 0.2\n"
             "nan nan nan %.9g 0 0 1 0 0\n"
             "\n"
             "1e3 2e-3 -0 %.9g nan nan nan 0 0\n"
             "3 4 5 %.9g 1 0 0 0 0",
             (double)rgb, (double)rgb, (double)rgb, (double)rgb);
    put_text(&file, text);
    lk_mesh mesh;
    read_ok(&file, &mesh);
    assert_int_equal(mesh.vertex_count, 3);
    const float positions[9] = {0.5f, -1, 2, 1e3f, 2e-3f, -0.0f, 3, 4, 5};
    assert_memory_equal(mesh.positions, positions, sizeof positions);
    /* a NaN normal ("could not be estimated") becomes 0 0 0 */
    const float normals[9] = {0, 0, 1, 0, 0, 0, 1, 0, 0};
    assert_memory_equal(mesh.normals, normals, sizeof normals);
    const float color[4] = {1, 128 / 255.0f, 1 / 255.0f, 1};
    assert_memory_equal(mesh.colors, color, sizeof color);
    assert_memory_equal(mesh.colors + 8, color, sizeof color);
    lk_mesh_free(&mesh);
}

/* A header of version 0.5 style: no TYPE or COUNT (floats, one each), no HEIGHT, POINTS only. */
static void test_old_header(void **state)
{
    (void)state;
    const char text[] = "VERSION .5\nFIELDS x y z\nSIZE 4 4 4\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read_memory(text, sizeof text - 1, "old.pcd", LK_FORMAT_AUTO, NULL, &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 2);
    assert_null(mesh.normals);
    assert_null(mesh.colors);
    assert_true(mesh.positions[5] == 6.0f);
    lk_mesh_free(&mesh);
    /* one point, without a final newline: the shortest file there is */
    const char shortest[] = "FIELDS x y z\nSIZE 4 4 4\nPOINTS 1\nDATA ascii\n1 2 3";
    assert_int_equal(
        lk_mesh_read_memory(shortest, sizeof shortest - 1, "short.pcd", LK_FORMAT_AUTO, NULL, &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 1);
    lk_mesh_free(&mesh);
    /* content detection without the extension */
    assert_int_equal(lk_format_sniff(text, sizeof text - 1), LK_FORMAT_PCD);
}

/* ---- malformed files ----------------------------------------------------------- */

static void expect_error(const bytes *file, lk_status expected_status, const char *expected_message)
{
    lk_mesh mesh;
    lk_error error = {0};
    lk_status status = read_bytes(file, &mesh, &error);
    if (status == LK_OK || !strstr(error.message, expected_message))
        fprintf(stderr, "got: %s\nexpected: %s\n", error.message, expected_message);
    assert_int_equal(status, expected_status);
    assert_non_null(strstr(error.message, expected_message));
    assert_int_equal(mesh.vertex_count, 0);
    assert_null(mesh.positions);
}

static void expect_text_error(const char *text, const char *expected_message)
{
    bytes file = {0};
    put_text(&file, text);
    expect_error(&file, LK_ERR_PARSE, expected_message);
}

static void test_bad_headers(void **state)
{
    (void)state;
    const char *xyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
    char text[512];
    snprintf(text, sizeof text, "%sWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA zip\n", xyz);
    expect_text_error(text, "t.pcd:8: unknown DATA 'zip' (expected ascii, binary or binary_compressed)");
    expect_text_error("FIELDS x y z\nSIZE 4 4\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:4: SIZE has 2 entries but FIELDS has 3");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F F\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:5: TYPE has 4 entries but FIELDS has 3");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nCOUNT 1 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:5: COUNT has 2 entries but FIELDS has 3");
    snprintf(text, sizeof text, "%sWIDTH 2\nHEIGHT 3\nPOINTS 5\nDATA ascii\n", xyz);
    expect_text_error(text, "t.pcd:8: POINTS 5 is not WIDTH 2 x HEIGHT 3");
    expect_text_error("FIELDS x y w\nSIZE 4 4 4\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:4: FIELDS has no z (x, y and z are needed)");
    expect_text_error("FIELDS x y z\nSIZE 4 3 4\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:2: SIZE of field 2 is '3' (expected 1, 2, 4 or 8)");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F X F\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:3: TYPE of field 2 is 'X' (expected I, U or F)");
    expect_text_error("FIELDS x y z\nSIZE 4 2 4\nTYPE F F F\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:5: field 2 has TYPE F and SIZE 2 (expected 4 or 8)");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nCOUNT 1 0 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:3: COUNT of field 2 is '0' (expected 1 to 1000000)");
    expect_text_error("FIELDS x y z rgb\nSIZE 4 4 4 2\nTYPE F F F U\nPOINTS 1\nDATA ascii\n1 2 3 4\n",
                      "t.pcd:5: field rgb has SIZE 2 (PCL packs a colour in 4 bytes)");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nPOINTS -1\nDATA ascii\n",
                      "t.pcd:3: POINTS needs a count of 0 or more");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nPOINTS 0\nDATA ascii\n", "t.pcd:4: no points (POINTS 0)");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nPOINTS 1\n", "t.pcd: no DATA line (not a PCD header?)");
    expect_text_error("SIZE 4 4 4\nPOINTS 1\nDATA ascii\n", "t.pcd:3: no FIELDS line before DATA");
    /* Found by the fuzzer: x of a first, longer FIELDS line pointed past the
     * second one's fields (a field of SIZE 0, read as 64-bit shift). */
    expect_text_error("FIELDS a b c d e x\nFIELDS x y z\nSIZE 4 4 4\nPOINTS 1\nDATA binary\n123456789012",
                      "t.pcd:2: a second FIELDS line");
    expect_text_error("FIELDS x y z\nSIZE 4 4 4\nSIZE 4 4 4\nPOINTS 1\nDATA ascii\n1 2 3\n",
                      "t.pcd:3: a second SIZE line");
}

static void test_bad_ascii(void **state)
{
    (void)state;
    const char *header = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 3\nDATA ascii\n";
    char text[512];
    snprintf(text, sizeof text, "%s10.5 20.5 30.5\n40.5 50.5 60.5\n", header);
    expect_text_error(text, "t.pcd:8: the file ends after 2 of 3 points");
    /* fewer bytes than 3 points can fill: refused by the claim check */
    snprintf(text, sizeof text, "%s1 2 3\n4 5 6\n", header);
    bytes file = {0};
    put_text(&file, text);
    expect_error(&file, LK_ERR_LIMIT, "t.pcd:6: header claims 3 points but only 12 bytes follow");
    snprintf(text, sizeof text, "%s1 2 3\n4 five 6\n7 8 9\n", header);
    expect_text_error(text, "t.pcd:8: expected a number, got 'five'");
    snprintf(text, sizeof text, "%s1.0 2.0 3.0\n4.0 5.0\n7.0 8.0 9.0\n", header);
    expect_text_error(text, "t.pcd:8: expected 3 values per point, got 2");
    snprintf(text, sizeof text, "%s1 2 3 4\n4 5 6\n7 8 9\n", header);
    expect_text_error(text, "t.pcd:7: more than 3 values per point");
    snprintf(text, sizeof text, "%snan 2 3\n1 nan 3\n1 2 nan\n", header);
    expect_text_error(text, "t.pcd: no points left: all 3 have NaN coordinates");
    /* a claim far beyond the file is refused before anything is allocated */
    memset(&file, 0, sizeof file);
    put_text(&file, "FIELDS x y z\nSIZE 4 4 4\nPOINTS 4000000000\nDATA ascii\n1 2 3\n");
    expect_error(&file, LK_ERR_LIMIT, "t.pcd:4: header claims 4000000000 points but only 6 bytes follow");
}

static void test_bad_binary(void **state)
{
    (void)state;
    bytes file = {0};
    put_header(&file, "x y z", "4 4 4", "F F F", "1 1 1", 2, 1, 2, "binary");
    size_t body = file.size;
    const float point[3] = {1, 2, 3};
    put(&file, point, 12);
    put(&file, point, 11);
    char message[200];
    snprintf(message, sizeof message, "t.pcd: byte %zu: truncated: 2 points of 12 bytes need 24 bytes, only 23 follow",
             body);
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(read_bytes(&file, &mesh, &error), LK_ERR_PARSE);
    assert_string_equal(error.message, message);
}

/* A binary_compressed file of 2 points (x y z) with the given sizes and LZF bytes. */
static void compressed_file(bytes *file, uint32_t compressed_size, uint32_t uncompressed_size, const unsigned char *lzf,
                            size_t lzf_size)
{
    memset(file, 0, sizeof *file);
    put_header(file, "x y z", "4 4 4", "F F F", "1 1 1", 2, 1, 2, "binary_compressed");
    put_u32(file, compressed_size);
    put_u32(file, uncompressed_size);
    put(file, lzf, lzf_size);
}

static void test_bad_compressed(void **state)
{
    (void)state;
    bytes file;
    unsigned char lzf[64];
    /* a literal run of 24 bytes: a valid body */
    lzf[0] = 23;
    memset(lzf + 1, 0, 24);
    compressed_file(&file, 25, 24, lzf, 25);
    size_t body = file.size - 25 - 8;
    lk_mesh mesh;
    read_ok(&file, &mesh);
    assert_int_equal(mesh.vertex_count, 2);
    lk_mesh_free(&mesh);
    char message[200];

    compressed_file(&file, 26, 24, lzf, 25);
    snprintf(message, sizeof message, "t.pcd: byte %zu: compressed size 26 is more than the 25 bytes that follow",
             body);
    expect_error(&file, LK_ERR_PARSE, message);

    compressed_file(&file, 25, 36, lzf, 25);
    snprintf(message, sizeof message, "t.pcd: byte %zu: uncompressed size 36 is not POINTS 2 x 12 bytes per point",
             body + 4);
    expect_error(&file, LK_ERR_PARSE, message);

    /* literal 1 byte, then a back-reference 3 bytes back from output byte 1 */
    const unsigned char before_start[] = {0, 7, 1 << 5, 2};
    compressed_file(&file, 4, 24, before_start, 4);
    snprintf(message, sizeof message,
             "t.pcd: byte %zu: LZF back-reference 3 bytes back from output byte 1 (before the start)", body + 10);
    expect_error(&file, LK_ERR_PARSE, message);

    /* a literal run of 24 announced, 10 present */
    compressed_file(&file, 11, 24, lzf, 11);
    snprintf(message, sizeof message, "t.pcd: byte %zu: LZF literal run of 24 bytes past the data's end", body + 8);
    expect_error(&file, LK_ERR_PARSE, message);

    /* 12 bytes, then an overlapping back-reference of 20: more than 24 */
    const unsigned char too_long[] = {11, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 7 << 5, 20 - 9, 0};
    compressed_file(&file, sizeof too_long, 24, too_long, sizeof too_long);
    snprintf(message, sizeof message, "t.pcd: byte %zu: LZF data decompresses to more than the 24 bytes announced",
             body + 8 + 13);
    expect_error(&file, LK_ERR_PARSE, message);

    /* 12 bytes only */
    compressed_file(&file, 13, 24, too_long, 13);
    snprintf(message, sizeof message, "t.pcd: byte %zu: LZF data decompresses to 12 bytes, the header announced 24",
             body + 8 + 13);
    expect_error(&file, LK_ERR_PARSE, message);

    /* a back-reference whose offset byte is missing */
    compressed_file(&file, 14, 24, too_long, 14);
    snprintf(message, sizeof message, "t.pcd: byte %zu: LZF back-reference cut short", body + 8 + 13);
    expect_error(&file, LK_ERR_PARSE, message);

    /* the sizes themselves cut off */
    memset(&file, 0, sizeof file);
    put_header(&file, "x y z", "4 4 4", "F F F", "1 1 1", 2, 1, 2, "binary_compressed");
    put_u32(&file, 25);
    snprintf(message, sizeof message,
             "t.pcd: byte %zu: truncated: the compressed and uncompressed sizes need 8 bytes, only 4 follow", body);
    expect_error(&file, LK_ERR_PARSE, message);

    /* 4 GB claimed from 1 byte of LZF: refused before allocating */
    memset(&file, 0, sizeof file);
    put_header(&file, "x y z", "4 4 4", "F F F", "1 1 1", 350000000, 1, 350000000, "binary_compressed");
    put_u32(&file, 1);
    put_u32(&file, 4200000000u);
    put(&file, lzf, 1);
    expect_error(&file, LK_ERR_PARSE, "uncompressed size 4200000000 cannot come from 1 bytes of LZF data");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_binary),    cmocka_unit_test(test_compressed), cmocka_unit_test(test_compressed_runs),
        cmocka_unit_test(test_ascii),     cmocka_unit_test(test_old_header), cmocka_unit_test(test_bad_headers),
        cmocka_unit_test(test_bad_ascii), cmocka_unit_test(test_bad_binary), cmocka_unit_test(test_bad_compressed),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
