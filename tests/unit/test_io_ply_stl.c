/* SPDX-License-Identifier: MIT */
/* PLY and STL readers and writers: real models, hand-made files (including
 * big-endian bytes), round trips, and every kind of bad input. */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* ---- helpers ---------------------------------------------------------------- */

/* A growable byte string for building binary files by hand. */
typedef struct bytes {
    unsigned char data[4096];
    size_t size;
    int big_endian;
} bytes;

static void put_text(bytes *b, const char *text)
{
    size_t length = strlen(text);
    assert_true(b->size + length <= sizeof b->data);
    memcpy(b->data + b->size, text, length);
    b->size += length;
}

static void put_uint(bytes *b, uint64_t value, int width)
{
    assert_true(b->size + (size_t)width <= sizeof b->data);
    for (int i = 0; i < width; i++) {
        int shift = b->big_endian ? 8 * (width - 1 - i) : 8 * i;
        b->data[b->size++] = (unsigned char)(value >> shift);
    }
}

static void put_float(bytes *b, float value)
{
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    put_uint(b, bits, 4);
}

static void put_double(bytes *b, double value)
{
    uint64_t bits;
    memcpy(&bits, &value, sizeof bits);
    put_uint(b, bits, 8);
}

static lk_status read_bytes(const bytes *b, const char *name, lk_mesh *mesh, lk_error *error)
{
    lk_error_clear(error);
    lk_mesh_init(mesh);
    return lk_mesh_read_memory(b->data, b->size, name, LK_FORMAT_AUTO, NULL, mesh, error);
}

static void assert_failure(lk_status status, lk_status expected, const lk_error *error, const lk_mesh *mesh)
{
    if (status != expected)
        fail_msg("expected status %s, got %s: %s", lk_status_string(expected), lk_status_string(status),
                 error->message);
    assert_int_equal(mesh->vertex_count, 0);
    assert_null(mesh->positions);
}

static void assert_same_floats(const float *a, const float *b, size_t count)
{
    if (!a || !b) {
        assert_ptr_equal(a, b);
        return;
    }
    for (size_t i = 0; i < count; i++) {
        uint32_t x, y;
        memcpy(&x, &a[i], 4);
        memcpy(&y, &b[i], 4);
        if (x != y) fail_msg("value %zu differs: %.9g (0x%08x) vs %.9g (0x%08x)", i, (double)a[i], x, (double)b[i], y);
    }
}

static void assert_same_mesh(const lk_mesh *a, const lk_mesh *b)
{
    assert_int_equal(a->vertex_count, b->vertex_count);
    assert_int_equal(a->triangle_count, b->triangle_count);
    assert_same_floats(a->positions, b->positions, 3 * a->vertex_count);
    assert_same_floats(a->normals, b->normals, 3 * a->vertex_count);
    assert_same_floats(a->texcoords, b->texcoords, 2 * a->vertex_count);
    if (a->triangle_count) assert_memory_equal(a->indices, b->indices, 3 * a->triangle_count * sizeof(uint32_t));
}

static size_t file_size(const char *path)
{
    FILE *file = fopen(path, "rb");
    assert_non_null(file);
    fseek(file, 0, SEEK_END);
    long size = ftell(file);
    fclose(file);
    return (size_t)size;
}

/* ---- PLY: real models --------------------------------------------------------- */

static void test_ply_hippo_points_with_normals(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("hippo1.ply"), &mesh);
    assert_int_equal(mesh.vertex_count, 6104);
    assert_int_equal(mesh.triangle_count, 0);
    assert_non_null(mesh.normals);
    assert_null(mesh.texcoords);
    assert_null(mesh.colors);
    /* First and last records of the file (binary little-endian doubles). */
    assert_true(mesh.positions[0] == (float)0.326401 && mesh.positions[1] == (float)0.19364 &&
                mesh.positions[2] == (float)0.056274);
    assert_true(mesh.normals[0] == (float)0.6063846815528339 && mesh.normals[2] == (float)0.7013668534349683);
    const float *last = mesh.positions + 3 * 6103;
    assert_true(last[0] == (float)0.027667 && last[1] == (float)0.22138 && last[2] == (float)0.064697);
    assert_true(mesh.normals[3 * 6103 + 1] == (float)0.7102228524069657);
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        const float *n = mesh.normals + 3 * v;
        assert_float_equal(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-5);
    }
    lk_mesh_free(&mesh);
}

static void roundtrip_ply(const lk_mesh *mesh, const char *file_name)
{
    static const lk_ply_encoding encodings[] = {LK_PLY_BINARY_LE, LK_PLY_BINARY_BE, LK_PLY_ASCII};
    static const char *const headers[] = {"format binary_little_endian 1.0", "format binary_big_endian 1.0",
                                          "format ascii 1.0"};
    for (int e = 0; e < 3; e++) {
        lk_write_options options = {0};
        options.ply_encoding = encodings[e];
        lk_error error = {0};
        const char *path = lk_test_tmpfile(file_name);
        if (lk_mesh_write(path, LK_FORMAT_PLY, mesh, &options, &error) != LK_OK)
            fail_msg("writing %s failed: %s", path, error.message);
        /* The header says what was asked for, with conventional names. */
        FILE *file = fopen(path, "rb");
        assert_non_null(file);
        char head[512] = {0};
        size_t got = fread(head, 1, sizeof head - 1, file);
        fclose(file);
        assert_true(got > 0);
        assert_non_null(strstr(head, headers[e]));
        assert_non_null(strstr(head, "property float x\nproperty float y\nproperty float z\n"));
        if (mesh->triangle_count) assert_non_null(strstr(head, "property list uchar int vertex_indices\n"));
        lk_mesh back;
        lk_test_load(path, &back);
        assert_same_mesh(mesh, &back);
        lk_mesh_free(&back);
    }
}

static void test_ply_roundtrip_cow_all_encodings(void **state)
{
    (void)state;
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    assert_int_equal(cow.vertex_count, 2904);
    assert_int_equal(cow.triangle_count, 5804);
    roundtrip_ply(&cow, "cow.ply");
    lk_mesh_free(&cow);
}

static void test_ply_roundtrip_hippo_points(void **state)
{
    (void)state;
    lk_mesh hippo;
    lk_test_load(lk_test_sample("hippo1.ply"), &hippo);
    roundtrip_ply(&hippo, "hippo.ply");
    lk_mesh_free(&hippo);
}

/* Attributes and awkward float values survive all three encodings. */
static void test_ply_roundtrip_attributes_and_odd_floats(void **state)
{
    (void)state;
    static const float odd[] = {0.1f,
                                -0.0f,
                                1e-45f /* smallest denormal */,
                                3.4028235e38f,
                                -1.17549435e-38f,
                                3.14159274f,
                                1e10f,
                                -123456.789f,
                                0.3333333f,
                                16777216.0f,
                                1.0f / 3.0f,
                                7e-39f};
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&mesh, 4, 2, LK_ATTR_NORMALS | LK_ATTR_TEXCOORDS | LK_ATTR_COLORS, &error), LK_OK);
    for (size_t i = 0; i < 12; i++) mesh.positions[i] = odd[i];
    for (size_t i = 0; i < 12; i++) mesh.normals[i] = odd[11 - i] * 0.5f;
    for (size_t i = 0; i < 8; i++) mesh.texcoords[i] = odd[i] / 7.0f;
    for (size_t i = 0; i < 16; i++) mesh.colors[i] = (float)(i * 17) / 255.0f;
    static const uint32_t indices[] = {0, 1, 2, 0, 2, 3};
    memcpy(mesh.indices, indices, sizeof indices);
    static const lk_ply_encoding encodings[] = {LK_PLY_BINARY_LE, LK_PLY_BINARY_BE, LK_PLY_ASCII};
    for (int e = 0; e < 3; e++) {
        lk_write_options options = {0};
        options.ply_encoding = encodings[e];
        const char *path = lk_test_tmpfile("odd.ply");
        assert_int_equal(lk_mesh_write(path, LK_FORMAT_PLY, &mesh, &options, &error), LK_OK);
        lk_mesh back;
        lk_test_load(path, &back);
        assert_same_mesh(&mesh, &back);
        assert_non_null(back.colors);
        for (size_t i = 0; i < 16; i++) assert_float_equal(back.colors[i], mesh.colors[i], 1e-6);
        lk_mesh_free(&back);
        /* Skipped attributes are not written. */
        options.skip_normals = options.skip_texcoords = options.skip_colors = 1;
        assert_int_equal(lk_mesh_write(path, LK_FORMAT_PLY, &mesh, &options, &error), LK_OK);
        lk_test_load(path, &back);
        assert_null(back.normals);
        assert_null(back.texcoords);
        assert_null(back.colors);
        assert_same_floats(mesh.positions, back.positions, 12);
        lk_mesh_free(&back);
    }
    lk_mesh_free(&mesh);
}

/* ---- PLY: hand-made files ----------------------------------------------------- */

/* Every kind of property and element the reader must skip, CRLF line ends,
 * a quad, integer colours with alpha, texture_u/texture_v. */
static void test_ply_ascii_crlf_with_unknown_elements(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_data("ply/quad_crlf.ply"), &mesh);
    assert_int_equal(mesh.vertex_count, 4);
    assert_int_equal(mesh.triangle_count, 3);
    static const uint32_t triangles[] = {0, 1, 2, 0, 2, 3, 0, 2, 1};
    assert_memory_equal(mesh.indices, triangles, sizeof triangles);
    static const float positions[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    assert_same_floats(mesh.positions, positions, 12);
    static const float texcoords[] = {0, 1, 1, 1, 1, 0, 0, 0};
    assert_same_floats(mesh.texcoords, texcoords, 8);
    assert_null(mesh.normals);
    assert_non_null(mesh.colors);
    static const float colours[] = {1, 0, 0, 1, 0, 1, 0, 128 / 255.0f, 0, 0, 1, 0, 0.2f, 0.4f, 0.6f, 0.8f};
    for (int i = 0; i < 16; i++) assert_float_equal(mesh.colors[i], colours[i], 1e-6);
    lk_mesh_free(&mesh);
}

/* The same binary file in both byte orders, with skipped scalars and lists
 * in the vertex, face and an unknown element. */
static void build_binary_ply(bytes *b, int big_endian)
{
    memset(b, 0, sizeof *b);
    b->big_endian = big_endian;
    put_text(b, big_endian ? "ply\nformat binary_big_endian 1.0\n" : "ply\nformat binary_little_endian 1.0\n");
    put_text(b, "comment made by hand\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                "property ushort quality\nproperty list uchar short extra\nproperty double nx\nproperty double ny\n"
                "property double nz\nelement face 2\nproperty uchar flags\nproperty list uchar int vertex_indices\n"
                "property list uchar float texcoord\nelement edge 1\nproperty int a\nproperty list ushort short b\n"
                "property double length\nend_header\n");
    static const float positions[4][3] = {{1.5f, -2.0f, 3.25f}, {0.1f, 0.2f, 0.3f}, {-1e-3f, 5e6f, -0.0f}, {7, 8, 9}};
    for (int v = 0; v < 4; v++) {
        for (int k = 0; k < 3; k++) put_float(b, positions[v][k]);
        put_uint(b, 0x1234 + (unsigned)v, 2);
        put_uint(b, (unsigned)v % 3, 1); /* list of 0..2 shorts */
        for (int i = 0; i < v % 3; i++) put_uint(b, 0xFFFF, 2);
        put_double(b, 0.0);
        put_double(b, v == 1 ? -1.0 : 1.0);
        put_double(b, 0.0);
    }
    put_uint(b, 7, 1);
    put_uint(b, 3, 1);
    put_uint(b, 0, 4);
    put_uint(b, 1, 4);
    put_uint(b, 2, 4);
    put_uint(b, 2, 1);
    put_float(b, 0.5f);
    put_float(b, 0.25f);
    put_uint(b, 0, 1);
    put_uint(b, 4, 1);
    put_uint(b, 0, 4);
    put_uint(b, 2, 4);
    put_uint(b, 3, 4);
    put_uint(b, 1, 4);
    put_uint(b, 0, 1);
    put_uint(b, (uint32_t)-5, 4);
    put_uint(b, 1, 2);
    put_uint(b, 42, 2);
    put_double(b, 2.5);
}

static void test_ply_binary_big_and_little_endian_by_hand(void **state)
{
    (void)state;
    lk_mesh meshes[2];
    for (int big = 0; big < 2; big++) {
        bytes b;
        build_binary_ply(&b, big);
        lk_error error;
        lk_mesh *mesh = &meshes[big];
        if (read_bytes(&b, big ? "big.ply" : "little.ply", mesh, &error) != LK_OK)
            fail_msg("reading failed: %s", error.message);
        assert_int_equal(mesh->vertex_count, 4);
        assert_int_equal(mesh->triangle_count, 3);
        static const uint32_t triangles[] = {0, 1, 2, 0, 2, 3, 0, 3, 1};
        assert_memory_equal(mesh->indices, triangles, sizeof triangles);
        static const float positions[] = {1.5f, -2.0f, 3.25f, 0.1f, 0.2f, 0.3f, -1e-3f, 5e6f, -0.0f, 7, 8, 9};
        assert_same_floats(mesh->positions, positions, 12);
        assert_non_null(mesh->normals);
        static const float normals[] = {0, 1, 0, 0, -1, 0, 0, 1, 0, 0, 1, 0};
        assert_same_floats(mesh->normals, normals, 12);
    }
    assert_same_mesh(&meshes[0], &meshes[1]);
    lk_mesh_free(&meshes[0]);
    lk_mesh_free(&meshes[1]);
}

/* ---- PLY: bad input ------------------------------------------------------------ */

static void expect_ply_text_error(const char *text, lk_status expected, const char *needle)
{
    lk_mesh mesh;
    lk_error error;
    lk_status status = lk_test_read_string(text, "bad.ply", LK_FORMAT_AUTO, &mesh, &error);
    assert_failure(status, expected, &error, &mesh);
    lk_assert_message_contains(error, needle);
}

#define PLY_XYZ_HEADER(count)                                                                                          \
    "ply\nformat ascii 1.0\nelement vertex " count "\nproperty float x\nproperty float y\nproperty float z\n"

static void test_ply_header_errors(void **state)
{
    (void)state;
    expect_ply_text_error("plx\nformat ascii 1.0\nend_header\n", LK_ERR_PARSE, "bad.ply:1: not a PLY file");
    expect_ply_text_error("ply\nformat ascii 1.0\nelement vertex 1\n", LK_ERR_PARSE,
                          "bad.ply:3: header ends without 'end_header'");
    expect_ply_text_error("ply\n", LK_ERR_PARSE, "bad.ply:1: header ends without 'end_header'");
    expect_ply_text_error("ply\nelement vertex 1\nproperty float x\nend_header\n1\n", LK_ERR_PARSE,
                          "bad.ply:4: header has no 'format' line");
    expect_ply_text_error("ply\nformat utf8 1.0\nend_header\n", LK_ERR_PARSE, "bad.ply:2: unknown format 'utf8'");
    expect_ply_text_error("ply\nformat ascii 2.0\nend_header\n", LK_ERR_UNSUPPORTED,
                          "bad.ply:2: unsupported PLY version");
    expect_ply_text_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float16 x\nend_header\n", LK_ERR_PARSE,
                          "bad.ply:4: unknown property type 'float16'");
    expect_ply_text_error("ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\nend_header\n",
                          LK_ERR_PARSE, "bad.ply:4: list count type must be an integer type");
    expect_ply_text_error("ply\nformat ascii 1.0\nproperty float x\nend_header\n", LK_ERR_PARSE,
                          "bad.ply:3: 'property' before any 'element'");
    expect_ply_text_error("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", LK_ERR_PARSE,
                          "bad.ply:3: element count must be a non-negative integer, got '-3'");
    expect_ply_text_error("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nend_header\n"
                          "1 2\n3 4\n",
                          LK_ERR_PARSE, "bad.ply:3: element vertex has no property 'z'");
    expect_ply_text_error("ply\nformat ascii 1.0\nelement face 0\nend_header\n", LK_ERR_PARSE,
                          "bad.ply:4: the header declares no 'vertex' element");
    expect_ply_text_error(PLY_XYZ_HEADER("1") "element face 1\nproperty int vertex_indices\nend_header\n0 0 0\n1\n",
                          LK_ERR_PARSE, "bad.ply:7: face property 'vertex_indices' must be a list");
}

static void test_ply_body_errors_ascii(void **state)
{
    (void)state;
    /* Truncated body: the message says how many records there were. */
    expect_ply_text_error(PLY_XYZ_HEADER("5") "end_header\n0 0 0\n1 0 0\n", LK_ERR_PARSE,
                          "bad.ply:9: expected 5 vertices, data ends after 2");
    expect_ply_text_error(PLY_XYZ_HEADER("2") "end_header\n0 0 0\n1 0\n", LK_ERR_PARSE,
                          "bad.ply:9: vertex 1: line ends before property 'z'");
    expect_ply_text_error(PLY_XYZ_HEADER("2") "end_header\n0 0 0\n1 0 0 4\n", LK_ERR_PARSE,
                          "bad.ply:9: vertex 1: unexpected extra value '4'");
    expect_ply_text_error(PLY_XYZ_HEADER("2") "end_header\n0 0 0\n1 abc 0\n", LK_ERR_PARSE,
                          "bad.ply:9: vertex 1: property 'y': expected a number, got 'abc'");
    expect_ply_text_error(PLY_XYZ_HEADER("2") "end_header\n0 0 0\n1 nan 0\n", LK_ERR_RANGE,
                          "bad.ply:9: vertex 1: y = nan is not a finite float");
    expect_ply_text_error(PLY_XYZ_HEADER("1") "end_header\n1e39 0 0\n", LK_ERR_RANGE,
                          "bad.ply:8: vertex 0: x = 1e+39 is not a finite float");
#define TRIANGLE_FILE(face)                                                                                            \
    PLY_XYZ_HEADER("3")                                                                                                \
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 "                           \
    "0\n" face
    expect_ply_text_error(TRIANGLE_FILE("3 0 1 -1\n"), LK_ERR_RANGE, "bad.ply:13: face 0: vertex index -1 is negative");
    expect_ply_text_error(TRIANGLE_FILE("3 0 1 3\n"), LK_ERR_RANGE,
                          "bad.ply:13: face 0: vertex index 3 is out of range (3 vertices)");
    expect_ply_text_error(TRIANGLE_FILE("2 0 1\n"), LK_ERR_PARSE,
                          "bad.ply:13: face 0 has 2 vertex indices (a face needs at least 3)");
    expect_ply_text_error(TRIANGLE_FILE("0\n"), LK_ERR_PARSE, "bad.ply:13: face 0 has 0 vertex indices");
    expect_ply_text_error(TRIANGLE_FILE("3 0 1.5 2\n"), LK_ERR_PARSE,
                          "bad.ply:13: face 0: vertex index 1.5 is not an integer");
    expect_ply_text_error(TRIANGLE_FILE("4 0 1 2\n"), LK_ERR_PARSE,
                          "bad.ply:13: face 0: line ends before property 'vertex_indices'");
    expect_ply_text_error(TRIANGLE_FILE(""), LK_ERR_PARSE, "expected 1 faces, data ends after 0");
    /* The same file with a good face loads, so the cases above are real. */
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(lk_test_read_string(TRIANGLE_FILE("3 0 1 2\n"), "good.ply", LK_FORMAT_AUTO, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 1);
    lk_mesh_free(&mesh);
    /* And a file on disk. */
    lk_status status = lk_mesh_read(lk_test_data("ply/bad_index.ply"), LK_FORMAT_AUTO, NULL, &mesh, &error);
    assert_failure(status, LK_ERR_RANGE, &error, &mesh);
    lk_assert_message_contains(error, "bad_index.ply:13: face 0: vertex index 9 is out of range (3 vertices)");
}

/* A binary header with three float vertices and `face_header` after it. */
static size_t binary_triangle_header(bytes *b, const char *face_header)
{
    memset(b, 0, sizeof *b);
    put_text(b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\n");
    put_text(b, face_header);
    put_text(b, "end_header\n");
    return b->size;
}

static void expect_bytes_error(const bytes *b, lk_status expected, const char *needle)
{
    lk_mesh mesh;
    lk_error error;
    lk_status status = read_bytes(b, "bad.ply", &mesh, &error);
    assert_failure(status, expected, &error, &mesh);
    lk_assert_message_contains(error, needle);
}

static void test_ply_body_errors_binary(void **state)
{
    (void)state;
    bytes b;
    char needle[128];
    const char *faces = "element face 2\nproperty list uchar uint vertex_indices\n";

    /* A good file first, so that each corruption below is what fails. */
    size_t body = binary_triangle_header(&b, faces);
    for (int i = 0; i < 9; i++) put_float(&b, (float)(i % 4 == 0));
    for (int f = 0; f < 2; f++) {
        put_uint(&b, 3, 1);
        for (uint32_t k = 0; k < 3; k++) put_uint(&b, (k + (uint32_t)f) % 3, 4);
    }
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_bytes(&b, "good.ply", &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 2);
    lk_mesh_free(&mesh);
    const bytes good = b;
    const size_t good_body = body;

    /* Faces cut short, between records and inside one. */
    b = good;
    b.size -= 13;
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: expected 2 faces, data ends after 1", body + 36 + 13);
    expect_bytes_error(&b, LK_ERR_PARSE, needle);
    b = good;
    b.size -= 5;
    snprintf(needle, sizeof needle,
             "bad.ply: byte %zu: face 1: list 'vertex_indices' of 3 items needs 12 bytes but only 7 are left",
             body + 36 + 13);
    expect_bytes_error(&b, LK_ERR_PARSE, needle);

    /* A list count of 2^31 is refused without allocating anything. */
    b = good;
    b.data[body + 36] = 0xFF; /* uchar count 255 needs 1020 bytes */
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: face 0: list 'vertex_indices' of 255 items needs 1020 bytes",
             body + 36);
    expect_bytes_error(&b, LK_ERR_PARSE, needle);
    body = binary_triangle_header(&b, "element face 1\nproperty list uint uint vertex_indices\n");
    for (int i = 0; i < 9; i++) put_float(&b, 0);
    put_uint(&b, 0x80000000u, 4);
    put_uint(&b, 0, 4);
    snprintf(needle, sizeof needle,
             "bad.ply: byte %zu: face 0: list 'vertex_indices' of 2147483648 items needs 8589934592 bytes", body + 36);
    expect_bytes_error(&b, LK_ERR_PARSE, needle);

    /* Index out of range, with the byte offset of the index. */
    b = good;
    b.data[good_body + 36 + 1 + 8] = 3;
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: face 0: vertex index 3 is out of range (3 vertices)",
             good_body + 36 + 9);
    expect_bytes_error(&b, LK_ERR_RANGE, needle);

    /* Count below three. */
    b = good;
    b.data[good_body + 36 + 13] = 2;
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: face 1 has 2 vertex indices", good_body + 36 + 13);
    expect_bytes_error(&b, LK_ERR_PARSE, needle);

    /* NaN coordinate: the offset of the vertex record. */
    b = good;
    static const unsigned char quiet_nan[4] = {0x00, 0x00, 0xC0, 0x7F}; /* little-endian +NaN */
    memcpy(b.data + good_body + 12 + 4, quiet_nan, 4);
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: vertex 1: y = nan is not a finite float", good_body + 12);
    expect_bytes_error(&b, LK_ERR_RANGE, needle);

    /* Negative index from a signed list. */
    body = binary_triangle_header(&b, "element face 1\nproperty list char int vertex_indices\n");
    for (int i = 0; i < 9; i++) put_float(&b, 0);
    put_uint(&b, 3, 1);
    put_uint(&b, 0, 4);
    put_uint(&b, 0xFFFFFFFFu, 4);
    put_uint(&b, 1, 4);
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: face 0: vertex index -1 is negative", body + 36 + 5);
    expect_bytes_error(&b, LK_ERR_RANGE, needle);

    /* Negative list count (signed count type). */
    b.data[body + 36] = 0xFE;
    expect_bytes_error(&b, LK_ERR_PARSE, "face 0: list 'vertex_indices' has an invalid length -2");
}

static void test_ply_absurd_claims(void **state)
{
    (void)state;
    /* 2^40 vertices: beyond what lodkit supports, refused before allocating. */
    expect_ply_text_error(PLY_XYZ_HEADER("1099511627776") "end_header\n0 0 0\n", LK_ERR_LIMIT,
                          "bad.ply:3: 1099511627776 vertices");
    /* Below the element limit but more than the bytes can hold. */
    expect_ply_text_error(PLY_XYZ_HEADER("2147483648") "end_header\n0 0 0\n", LK_ERR_LIMIT,
                          "bad.ply:3: header claims 2147483648 vertices but only 6 bytes follow");
    expect_ply_text_error(PLY_XYZ_HEADER("1") "element face 1000000\nproperty list uchar int vertex_indices\n"
                                              "end_header\n0 0 0\n3 0 0 0\n",
                          LK_ERR_LIMIT, "bad.ply:7: header claims 1000000 faces");
    bytes b;
    binary_triangle_header(&b, "element face 1000\nproperty list uchar int vertex_indices\n");
    for (int i = 0; i < 9; i++) put_float(&b, 0);
    put_uint(&b, 3, 1);
    for (int k = 0; k < 3; k++) put_uint(&b, 0, 4);
    expect_bytes_error(&b, LK_ERR_LIMIT, "bad.ply:7: header claims 1000 faces but only 13 bytes follow");

    /* A truncated real file: the binary vertex records cannot fit. */
    size_t size = file_size(lk_test_sample("hippo1.ply"));
    char *data = malloc(size);
    assert_non_null(data);
    FILE *file = fopen(lk_test_sample("hippo1.ply"), "rb");
    assert_non_null(file);
    assert_int_equal(fread(data, 1, size, file), size);
    fclose(file);
    lk_error error = {0};
    lk_mesh mesh;
    lk_status status = lk_mesh_read_memory(data, size - 48 * 6000, "hippo1.ply", LK_FORMAT_AUTO, NULL, &mesh, &error);
    assert_failure(status, LK_ERR_LIMIT, &error, &mesh);
    lk_assert_message_contains(error, "hippo1.ply:4: header claims 6104 vertices but only 4992 bytes follow");
    /* The memory budget is honoured too: it holds the input, the header's
     * tables (a few KiB) and the arrays. */
    lk_read_options options = {.max_bytes = size + 6104 * 24 - 1};
    status = lk_mesh_read_memory(data, size, "hippo1.ply", LK_FORMAT_AUTO, &options, &mesh, &error);
    assert_failure(status, LK_ERR_LIMIT, &error, &mesh);
    lk_assert_message_contains(error, "hippo1.ply:4: 6104 vertices would need more than the memory budget");
    options.max_bytes = size + 6104 * 24 + 4096;
    assert_int_equal(lk_mesh_read_memory(data, size, "hippo1.ply", LK_FORMAT_AUTO, &options, &mesh, &error), LK_OK);
    lk_mesh_free(&mesh);
    free(data);
}

static void test_ply_empty_file(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error;
    lk_status status = lk_test_read_string("", "empty.ply", LK_FORMAT_PLY, &mesh, &error);
    assert_failure(status, LK_ERR_PARSE, &error, &mesh);
    lk_assert_message_contains(error, "empty.ply");
    /* An empty mesh declared as such is fine. */
    assert_int_equal(lk_test_read_string(PLY_XYZ_HEADER("0") "end_header\n", "zero.ply", LK_FORMAT_AUTO, &mesh, &error),
                     LK_OK);
    assert_int_equal(mesh.vertex_count, 0);
    lk_mesh_free(&mesh);
}

/* Every PLY in Assimp's test set loads, or is refused with a message that
 * names the file. */
static void test_ply_assimp_samples(void **state)
{
    (void)state;
    static const struct {
        const char *name;
        size_t vertices, triangles; /* 0,0: expected to be refused */
        const char *refusal;
    } expected[] = {
        {"Wuson.ply", 11184, 3732, NULL},
        {"cube.ply", 8, 12, NULL},
        {"cube_binary.ply", 8, 12, NULL},
        {"cube_uv.ply", 24, 12, NULL},
        {"float-color.ply", 3, 1, NULL},
        {"points.ply", 4, 0, NULL},
        /* a vertex_indices list declared on the vertices, but not in the data */
        {"issue623.ply", 0, 0, "issue623.ply:13: vertex 0: line ends before property 'vertex_indices'"},
        /* 70051 vertices of 31 bytes declared, 2171512 bytes present */
        {"pond.0.ply", 0, 0, "pond.0.ply:3: header claims 70051 vertices but only 2171512 bytes follow"},
    };
    DIR *dir = opendir(lk_test_sample("assimp/PLY"));
    assert_non_null(dir);
    int seen = 0;
    for (struct dirent *entry; (entry = readdir(dir));) {
        if (entry->d_name[0] == '.') continue;
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", lk_test_sample("assimp/PLY"), entry->d_name);
        lk_mesh mesh;
        lk_error error = {0};
        lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &mesh, &error);
        if (status == LK_OK) {
            print_message("  %-16s %zu vertices, %zu triangles\n", entry->d_name, mesh.vertex_count,
                          mesh.triangle_count);
            assert_true(mesh.vertex_count > 0);
        } else {
            print_message("  %-16s refused: %s\n", entry->d_name, error.message);
            lk_assert_message_contains(error, entry->d_name);
        }
        for (size_t i = 0; i < sizeof expected / sizeof expected[0]; i++) {
            if (strcmp(expected[i].name, entry->d_name) != 0) continue;
            seen++;
            if (expected[i].refusal) {
                assert_int_not_equal(status, LK_OK);
                lk_assert_message_contains(error, expected[i].refusal);
            } else {
                if (status != LK_OK) fail_msg("%s", error.message);
                assert_int_equal(mesh.vertex_count, expected[i].vertices);
                assert_int_equal(mesh.triangle_count, expected[i].triangles);
            }
        }
        if (strcmp(entry->d_name, "cube_uv.ply") == 0 || strcmp(entry->d_name, "Wuson.ply") == 0) {
            assert_non_null(mesh.normals);
            assert_non_null(mesh.texcoords);
        }
        if (strcmp(entry->d_name, "float-color.ply") == 0) {
            assert_non_null(mesh.colors);
            assert_true(mesh.colors[0] == 0 && mesh.colors[2] == 1 && mesh.colors[3] == 1);
        }
        if (strcmp(entry->d_name, "points.ply") == 0) {
            assert_non_null(mesh.normals);
            assert_non_null(mesh.colors);
            assert_true(mesh.colors[4] == 1 && mesh.colors[5] == 0 && mesh.colors[6] == 1);
        }
        lk_mesh_free(&mesh);
    }
    closedir(dir);
    assert_int_equal(seen, (int)(sizeof expected / sizeof expected[0]));
}

/* ---- PLY: splat radii --------------------------------------------------------- */

/* Radii (the "radius" vertex property) of a real point set survive all three
 * encodings bit for bit, next to normals and colours. */
static void test_ply_radii_roundtrip_hippo(void **state)
{
    (void)state;
    lk_mesh hippo, mesh;
    lk_error error = {0};
    lk_test_load(lk_test_sample("hippo1.ply"), &hippo);
    assert_null(hippo.radii);
    assert_int_equal(
        lk_mesh_alloc(&mesh, hippo.vertex_count, 0, LK_ATTR_NORMALS | LK_ATTR_COLORS | LK_ATTR_RADII, &error), LK_OK);
    memcpy(mesh.positions, hippo.positions, 3 * hippo.vertex_count * sizeof(float));
    memcpy(mesh.normals, hippo.normals, 3 * hippo.vertex_count * sizeof(float));
    static const float odd[] = {1e-45f, 3.4028235e38f, 0.1f, 1.0f / 3.0f, 7e-39f, 16777216.0f};
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        /* A plausible spacing-sized radius, with awkward floats mixed in. */
        mesh.radii[v] = v % 97 < 6 ? odd[v % 97] : 0.001f * (float)(1 + v % 13) + hippo.positions[3 * v] * 1e-3f;
        assert_true(mesh.radii[v] > 0);
        for (int k = 0; k < 4; k++) mesh.colors[4 * v + k] = (float)((v + (size_t)k * 50) % 256) / 255.0f;
    }
    lk_mesh_free(&hippo);
    static const lk_ply_encoding encodings[] = {LK_PLY_BINARY_LE, LK_PLY_BINARY_BE, LK_PLY_ASCII};
    for (int e = 0; e < 3; e++) {
        lk_write_options options = {0};
        options.ply_encoding = encodings[e];
        const char *path = lk_test_tmpfile("radii.ply");
        if (lk_mesh_write(path, LK_FORMAT_PLY, &mesh, &options, &error) != LK_OK) fail_msg("%s", error.message);
        FILE *file = fopen(path, "rb");
        assert_non_null(file);
        char head[512] = {0};
        assert_true(fread(head, 1, sizeof head - 1, file) > 0);
        fclose(file);
        assert_non_null(strstr(head, "property float radius\n"));
        lk_mesh back;
        lk_test_load(path, &back);
        assert_same_mesh(&mesh, &back);
        assert_non_null(back.radii);
        assert_same_floats(mesh.radii, back.radii, mesh.vertex_count);
        for (size_t i = 0; i < 4 * mesh.vertex_count; i++) assert_float_equal(back.colors[i], mesh.colors[i], 1e-6);
        lk_mesh_free(&back);
    }
    /* A mesh without radii writes no radius property. */
    free(mesh.radii);
    mesh.radii = NULL;
    const char *path = lk_test_tmpfile("noradii.ply");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_PLY, &mesh, NULL, &error), LK_OK);
    lk_mesh back;
    lk_test_load(path, &back);
    assert_null(back.radii);
    lk_mesh_free(&back);
    lk_mesh_free(&mesh);
}

/* Radii as doubles, in a file where "radius" comes first and in big-endian
 * bytes; and in ascii after unrelated properties. */
static void test_ply_radii_double_and_ascii_by_hand(void **state)
{
    (void)state;
    bytes b;
    memset(&b, 0, sizeof b);
    b.big_endian = 1;
    put_text(&b, "ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double radius\nproperty float x\n"
                 "property float y\nproperty float z\nend_header\n");
    size_t second = b.size + 20; /* offset of the second record */
    put_double(&b, 0.125);
    put_float(&b, 1), put_float(&b, 2), put_float(&b, 3);
    put_double(&b, 1e-300); /* underflows float: refused as not > 0 */
    put_float(&b, 4), put_float(&b, 5), put_float(&b, 6);
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_bytes(&b, "r.ply", &mesh, &error), LK_ERR_RANGE);
    char needle[128];
    snprintf(needle, sizeof needle, "r.ply: byte %zu: vertex 1: radius = 1e-300 must be > 0", second);
    lk_assert_message_contains(error, needle);
    /* Replace the bad radius by 2.5 and the file loads. */
    b.size = second;
    put_double(&b, 2.5);
    put_float(&b, 4), put_float(&b, 5), put_float(&b, 6);
    if (read_bytes(&b, "r.ply", &mesh, &error) != LK_OK) fail_msg("%s", error.message);
    assert_non_null(mesh.radii);
    assert_true(mesh.radii[0] == 0.125f && mesh.radii[1] == 2.5f);
    assert_true(mesh.positions[3] == 4.0f && mesh.positions[5] == 6.0f);
    lk_mesh_free(&mesh);

    const char *text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                       "property uchar quality\nproperty float radius\nend_header\n0 0 0 7 0.5\n1 1 1 9 1e-3\n";
    if (lk_test_read_string(text, "r.ply", LK_FORMAT_AUTO, &mesh, &error) != LK_OK) fail_msg("%s", error.message);
    assert_true(mesh.radii[0] == 0.5f && mesh.radii[1] == 1e-3f);
    lk_mesh_free(&mesh);
}

#define PLY_RADIUS_HEADER(count) PLY_XYZ_HEADER(count) "property float radius\nend_header\n"

/* NaN, infinite, negative and zero radii are refused with the line or the
 * byte offset of the record; lk_mesh_validate names the vertex. */
static void test_ply_radii_errors(void **state)
{
    (void)state;
    expect_ply_text_error(PLY_RADIUS_HEADER("2") "0 0 0 1\n1 0 0 nan\n", LK_ERR_RANGE,
                          "bad.ply:10: vertex 1: radius = nan is not a finite float");
    expect_ply_text_error(PLY_RADIUS_HEADER("2") "0 0 0 1\n1 0 0 -inf\n", LK_ERR_RANGE,
                          "bad.ply:10: vertex 1: radius = -inf is not a finite float");
    expect_ply_text_error(PLY_RADIUS_HEADER("3") "0 0 0 1\n\n1 0 0 2\n2 0 0 -0.5\n", LK_ERR_RANGE,
                          "bad.ply:12: vertex 2: radius = -0.5 must be > 0");
    expect_ply_text_error(PLY_RADIUS_HEADER("1") "0 0 0 0\n", LK_ERR_RANGE,
                          "bad.ply:9: vertex 0: radius = 0 must be > 0");
    expect_ply_text_error(PLY_RADIUS_HEADER("1") "0 0 0 -0\n", LK_ERR_RANGE,
                          "bad.ply:9: vertex 0: radius = -0 must be > 0");
    expect_ply_text_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                          "property float z\nproperty list uchar float radius\nend_header\n0 0 0 1 1\n",
                          LK_ERR_PARSE, "bad.ply:3: vertex property 'radius' is a list");

    /* Binary: the offset of the bad record (16 bytes per vertex). */
    bytes b;
    memset(&b, 0, sizeof b);
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                 "property float z\nproperty float radius\nend_header\n");
    size_t header = b.size;
    static const float good[3][4] = {{0, 0, 0, 0.5f}, {1, 0, 0, 0.25f}, {0, 1, 0, 1}};
    for (int v = 0; v < 3; v++)
        for (int k = 0; k < 4; k++) put_float(&b, good[v][k]);
    lk_mesh mesh;
    lk_error error;
    if (read_bytes(&b, "good.ply", &mesh, &error) != LK_OK) fail_msg("%s", error.message);
    assert_true(mesh.radii[2] == 1.0f);
    lk_mesh_free(&mesh);
    char needle[128];
    size_t full = b.size;
    b.size = header + 2 * 16 + 12; /* overwrite the third radius in place */
    put_float(&b, NAN);
    b.size = full;
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: vertex 2: radius = nan is not a finite float", header + 32);
    expect_bytes_error(&b, LK_ERR_RANGE, needle);
    b.size = header + 16 + 12;
    put_float(&b, -2.0f);
    b.size = full;
    snprintf(needle, sizeof needle, "bad.ply: byte %zu: vertex 1: radius = -2 must be > 0", header + 16);
    expect_bytes_error(&b, LK_ERR_RANGE, needle);

    /* In memory: validate refuses what the reader refuses, and the writer
     * refuses to write it. */
    assert_int_equal(lk_mesh_alloc(&mesh, 3, 0, LK_ATTR_RADII, &error), LK_OK);
    for (int v = 0; v < 3; v++) {
        for (int k = 0; k < 3; k++) mesh.positions[3 * v + k] = good[v][k];
        mesh.radii[v] = good[v][3];
    }
    assert_int_equal(lk_mesh_validate(&mesh, &error), LK_OK);
    static const float bad_radii[] = {0.0f, -1.0f, NAN, INFINITY};
    for (int i = 0; i < 4; i++) {
        mesh.radii[1] = bad_radii[i];
        assert_int_equal(lk_mesh_validate(&mesh, &error), LK_ERR_RANGE);
        lk_assert_message_contains(error, "vertex 1: radius");
        assert_int_equal(lk_mesh_write(lk_test_tmpfile("badradius.ply"), LK_FORMAT_PLY, &mesh, NULL, &error),
                         LK_ERR_RANGE);
        lk_assert_message_contains(error, "refusing to write an invalid mesh: vertex 1: radius");
    }
    lk_mesh_free(&mesh);
}

/* ---- STL ------------------------------------------------------------------------ */

static int compare_positions(const void *a, const void *b)
{
    const float *p = a, *q = b;
    for (int k = 0; k < 3; k++) {
        if (p[k] < q[k]) return -1;
        if (p[k] > q[k]) return 1;
    }
    return 0;
}

/* Distinct positions (-0.0 == 0.0) among the vertices that triangles use. */
static size_t distinct_used_positions(const lk_mesh *mesh)
{
    float *corners = malloc(mesh->triangle_count * 9 * sizeof(float));
    assert_non_null(corners);
    for (size_t c = 0; c < 3 * mesh->triangle_count; c++)
        for (int k = 0; k < 3; k++)
            corners[3 * c + k] = mesh->positions[3 * (size_t)mesh->indices[c] + (size_t)k] + 0.0f;
    qsort(corners, 3 * mesh->triangle_count, 3 * sizeof(float), compare_positions);
    size_t distinct = 0;
    for (size_t c = 0; c < 3 * mesh->triangle_count; c++)
        if (c == 0 || compare_positions(corners + 3 * c, corners + 3 * (c - 1)) != 0) distinct++;
    free(corners);
    return distinct;
}

static void test_stl_roundtrip_cow_binary_and_ascii(void **state)
{
    (void)state;
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    size_t distinct = distinct_used_positions(&cow);
    assert_true(distinct > 2800 && distinct <= cow.vertex_count);
    for (int ascii = 0; ascii < 2; ascii++) {
        lk_write_options options = {0};
        options.stl_ascii = ascii;
        lk_error error = {0};
        const char *path = lk_test_tmpfile(ascii ? "cow_ascii.stl" : "cow_binary.stl");
        if (lk_mesh_write(path, LK_FORMAT_STL, &cow, &options, &error) != LK_OK) fail_msg("%s", error.message);
        if (!ascii) assert_int_equal(file_size(path), 84 + 50 * cow.triangle_count);
        lk_mesh back;
        lk_test_load(path, &back);
        assert_int_equal(back.triangle_count, cow.triangle_count);
        assert_int_equal(back.vertex_count, distinct);
        for (size_t c = 0; c < 3 * cow.triangle_count; c++) {
            const float *a = cow.positions + 3 * (size_t)cow.indices[c];
            const float *b = back.positions + 3 * (size_t)back.indices[c];
            if (a[0] != b[0] || a[1] != b[1] || a[2] != b[2]) fail_msg("corner %zu moved", c);
        }
        assert_null(back.normals);
        lk_mesh_free(&back);
    }
    lk_mesh_free(&cow);
}

static void test_stl_welds_signed_zero(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_data("stl/signed_zero.stl"), &mesh);
    assert_int_equal(mesh.triangle_count, 2);
    assert_int_equal(mesh.vertex_count, 4); /* (-0,1,-0) is (0,1,0); (1,0,0) shared */
    static const uint32_t triangles[] = {0, 1, 2, 2, 1, 3};
    assert_memory_equal(mesh.indices, triangles, sizeof triangles);
    lk_mesh_free(&mesh);
}

/* A binary file whose header starts with "solid" (and is all text) is
 * still binary when the size matches the count. */
static void test_stl_binary_with_solid_header(void **state)
{
    (void)state;
    bytes b;
    memset(&b, 0, sizeof b);
    put_text(&b, "solid but actually binary");
    while (b.size < 80) put_text(&b, " ");
    put_uint(&b, 2, 4);
    static const float corners[2][3][3] = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {0, 1, 0}}};
    for (int t = 0; t < 2; t++) {
        for (int k = 0; k < 3; k++) put_float(&b, 0); /* normal: ignored */
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) put_float(&b, corners[t][c][k]);
        put_uint(&b, 0, 2);
    }
    lk_mesh mesh;
    lk_error error;
    if (read_bytes(&b, "solid.stl", &mesh, &error) != LK_OK) fail_msg("%s", error.message);
    assert_int_equal(mesh.triangle_count, 2);
    assert_int_equal(mesh.vertex_count, 4);
    static const uint32_t triangles[] = {0, 1, 2, 1, 3, 2};
    assert_memory_equal(mesh.indices, triangles, sizeof triangles);
    lk_mesh_free(&mesh);

    /* NaN coordinate: the byte of the value. */
    bytes bad = b;
    memset(bad.data + 84 + 50 + 12 + 12 + 4, 0xFF, 4);
    lk_status status = read_bytes(&bad, "nan.stl", &mesh, &error);
    assert_failure(status, LK_ERR_RANGE, &error, &mesh);
    lk_assert_message_contains(error, "nan.stl: byte 162: triangle 1: vertex coordinate is not finite");

    /* Truncated: 12 triangles claimed, 300 bytes present. */
    bad = b;
    bad.data[80] = 12;
    memset(bad.data + 134, 0, 300 - 134);
    bad.size = 300;
    status = read_bytes(&bad, "short.stl", &mesh, &error);
    assert_failure(status, LK_ERR_LIMIT, &error, &mesh);
    lk_assert_message_contains(error, "short.stl: byte 84: expected 12 triangles (684 bytes), file has 300");

    /* Absurd count. */
    bad = b;
    memset(bad.data + 80, 0xFF, 4);
    status = read_bytes(&bad, "absurd.stl", &mesh, &error);
    assert_failure(status, LK_ERR_LIMIT, &error, &mesh);
    lk_assert_message_contains(error,
                               "absurd.stl: byte 84: expected 4294967295 triangles (214748364834 bytes), file has 184");

    /* Bytes after the last triangle. */
    bad = b;
    bad.data[80] = 1;
    status = read_bytes(&bad, "long.stl", &mesh, &error);
    assert_failure(status, LK_ERR_PARSE, &error, &mesh);
    lk_assert_message_contains(error, "long.stl: byte 84: expected 1 triangles (134 bytes), file has 184");

    /* Too short for anything. */
    bad = b;
    bad.data[0] = 'X';
    bad.size = 40;
    status = read_bytes(&bad, "tiny.stl", &mesh, &error);
    assert_failure(status, LK_ERR_PARSE, &error, &mesh);
    lk_assert_message_contains(error, "tiny.stl: byte 40: not an STL file");
}

static void expect_stl_text_error(const char *text, lk_status expected, const char *needle)
{
    lk_mesh mesh;
    lk_error error;
    lk_status status = lk_test_read_string(text, "bad.stl", LK_FORMAT_AUTO, &mesh, &error);
    assert_failure(status, expected, &error, &mesh);
    lk_assert_message_contains(error, needle);
}

static void test_stl_ascii_errors(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error;
    lk_status status = lk_mesh_read(lk_test_data("stl/bad_vertex.stl"), LK_FORMAT_AUTO, NULL, &mesh, &error);
    assert_failure(status, LK_ERR_PARSE, &error, &mesh);
    lk_assert_message_contains(error, "bad_vertex.stl:5: expected 3 coordinates after 'vertex', line ends");
#define FACET(v1)                                                                                                      \
    "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n" v1 "\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n"
    expect_stl_text_error(FACET("vertex 1 nan 0"), LK_ERR_RANGE,
                          "bad.stl:5: vertex coordinate 'nan' is not a finite float");
    expect_stl_text_error(FACET("vertex 1 x 0"), LK_ERR_PARSE,
                          "bad.stl:5: expected 3 coordinates after 'vertex', got 'x'");
    expect_stl_text_error(FACET("vortex 1 0 0"), LK_ERR_PARSE,
                          "bad.stl:5: expected 'vertex' or 'endloop', got 'vortex'");
    expect_stl_text_error("solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\n",
                          LK_ERR_PARSE, "bad.stl:2: facet has 2 vertices, expected 3");
    expect_stl_text_error("solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n", LK_ERR_PARSE,
                          "bad.stl:5: expected 'vertex' or 'endloop', file ends");
    expect_stl_text_error("solid s\nfacet normal 0 0 1\nloop\n", LK_ERR_PARSE,
                          "bad.stl:3: expected 'outer', got 'loop'");
    expect_stl_text_error("solid s\nendsolid s\ngarbage\n", LK_ERR_PARSE, "bad.stl:3: expected 'solid', got 'garbage'");
    expect_stl_text_error("solid s\n  triangle\n", LK_ERR_PARSE,
                          "bad.stl:2: expected 'facet' or 'endsolid', got 'triangle'");
    /* The good version of the facet loads; a quad is fanned. */
    assert_int_equal(lk_test_read_string(FACET("vertex 1 0 0"), "good.stl", LK_FORMAT_AUTO, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 1);
    lk_mesh_free(&mesh);
    assert_int_equal(
        lk_test_read_string(FACET("vertex 1 0 0\nvertex 1 1 0"), "quad.stl", LK_FORMAT_AUTO, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 2);
    assert_int_equal(mesh.vertex_count, 4);
    lk_mesh_free(&mesh);
    /* Empty solid: a valid, empty mesh. */
    assert_int_equal(lk_test_read_string("solid empty\nendsolid empty\n", "empty.stl", LK_FORMAT_AUTO, &mesh, &error),
                     LK_OK);
    assert_int_equal(mesh.vertex_count, 0);
    assert_int_equal(mesh.triangle_count, 0);
    lk_mesh_free(&mesh);
    /* Empty file. */
    status = lk_test_read_string("", "nothing.stl", LK_FORMAT_STL, &mesh, &error);
    assert_failure(status, LK_ERR_PARSE, &error, &mesh);
    lk_assert_message_contains(error, "nothing.stl");
}

static void test_stl_writer_refuses_point_set(void **state)
{
    (void)state;
    lk_mesh hippo;
    lk_test_load(lk_test_sample("hippo1.ply"), &hippo);
    lk_error error = {0};
    assert_int_equal(lk_mesh_write(lk_test_tmpfile("points.stl"), LK_FORMAT_STL, &hippo, NULL, &error),
                     LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "point set");
    lk_mesh_free(&hippo);
}

static void test_stl_assimp_samples(void **state)
{
    (void)state;
    static const struct {
        const char *name;
        size_t vertices, triangles;
    } expected[] = {
        {"3DSMaxExport.STL", 1042, 2000},
        {"Spider_ascii.stl", 722, 1368},
        {"Spider_binary.stl", 722, 1368},
        {"Wuson.stl", 2117, 3732},
        {"formatDetection", 3, 1},
        {"sphereWithHole.stl", 146, 285},
        {"triangle.stl", 3, 1},
        {"triangle_with_empty_solid.stl", 3, 1},
        {"triangle_with_two_solids.stl", 6, 2},
    };
    DIR *dir = opendir(lk_test_sample("assimp/STL"));
    assert_non_null(dir);
    int seen = 0;
    for (struct dirent *entry; (entry = readdir(dir));) {
        if (entry->d_name[0] == '.') continue;
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", lk_test_sample("assimp/STL"), entry->d_name);
        lk_mesh mesh;
        lk_error error = {0};
        /* formatDetection has no extension: read it as STL explicitly. */
        lk_status status = lk_mesh_read(path, LK_FORMAT_STL, NULL, &mesh, &error);
        if (status == LK_OK) {
            print_message("  %-30s %zu vertices, %zu triangles\n", entry->d_name, mesh.vertex_count,
                          mesh.triangle_count);
            assert_true(mesh.vertex_count > 0);
        } else {
            print_message("  %-30s refused: %s\n", entry->d_name, error.message);
            lk_assert_message_contains(error, entry->d_name);
        }
        for (size_t i = 0; i < sizeof expected / sizeof expected[0]; i++) {
            if (strcmp(expected[i].name, entry->d_name) != 0) continue;
            seen++;
            if (status != LK_OK) fail_msg("%s", error.message);
            assert_int_equal(mesh.vertex_count, expected[i].vertices);
            assert_int_equal(mesh.triangle_count, expected[i].triangles);
        }
        lk_mesh_free(&mesh);
    }
    closedir(dir);
    assert_int_equal(seen, (int)(sizeof expected / sizeof expected[0]));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ply_hippo_points_with_normals),
        cmocka_unit_test(test_ply_roundtrip_cow_all_encodings),
        cmocka_unit_test(test_ply_roundtrip_hippo_points),
        cmocka_unit_test(test_ply_roundtrip_attributes_and_odd_floats),
        cmocka_unit_test(test_ply_ascii_crlf_with_unknown_elements),
        cmocka_unit_test(test_ply_binary_big_and_little_endian_by_hand),
        cmocka_unit_test(test_ply_header_errors),
        cmocka_unit_test(test_ply_body_errors_ascii),
        cmocka_unit_test(test_ply_body_errors_binary),
        cmocka_unit_test(test_ply_absurd_claims),
        cmocka_unit_test(test_ply_empty_file),
        cmocka_unit_test(test_ply_assimp_samples),
        cmocka_unit_test(test_ply_radii_roundtrip_hippo),
        cmocka_unit_test(test_ply_radii_double_and_ascii_by_hand),
        cmocka_unit_test(test_ply_radii_errors),
        cmocka_unit_test(test_stl_roundtrip_cow_binary_and_ascii),
        cmocka_unit_test(test_stl_welds_signed_zero),
        cmocka_unit_test(test_stl_binary_with_solid_header),
        cmocka_unit_test(test_stl_ascii_errors),
        cmocka_unit_test(test_stl_writer_refuses_point_set),
        cmocka_unit_test(test_stl_assimp_samples),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
