/* SPDX-License-Identifier: MIT */
/* The readers' fast paths (issue 22) give what the general code gives:
 * lk__parse_double against strtod (plain decimals, which take the fast
 * path, and everything around them: exponents, long mantissas, signs,
 * '.5', '5.', inf/nan, denormals), lk__parse_int64 at the overflow edge,
 * OBJ coordinates against (float)strtod, lk__format_float (the OBJ, PLY
 * ascii and other text writers) against its printf-only version, and binary PLY files whose layout
 * takes the fast loops against the same mesh in layouts that cannot
 * (double coordinates, a face property after the list, ascii), including
 * files where the loops stop midway (a quad, a NaN, an index out of range)
 * and the general code must go on with the same result or message. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#include "internal.h"

/* ---- numbers --------------------------------------------------------------- */

/* lk__parse_double and strtod agree on the value (bit for bit; NaN with
 * NaN) and on where the number ends. */
static void expect_like_strtod(const char *text)
{
    const char *cursor = text;
    double value = 0;
    bool parsed = lk__parse_double(&cursor, text + strlen(text), &value);
    char *strtod_end;
    double expected = strtod(text, &strtod_end);
    if (!parsed) {
        if (strtod_end != text) fail_msg("'%s': refused, strtod reads %g", text, expected);
        return;
    }
    if (cursor != strtod_end)
        fail_msg("'%s': ends after %d characters, strtod after %d", text, (int)(cursor - text),
                 (int)(strtod_end - text));
    if (isnan(expected)) {
        if (!isnan(value)) fail_msg("'%s': %.17g, strtod: nan", text, value);
        return;
    }
    if (memcmp(&value, &expected, sizeof value) != 0) fail_msg("'%s': %.17g, strtod: %.17g", text, value, expected);
}

static void test_parse_double_edge_cases(void **state)
{
    (void)state;
    static const char *const cases[] = {
        "0", "-0", "+0", "0.0", "-0.0", "1", "-1", "+1", "5.", "-5.", ".5", "+.5", "-.5", "0.296502", "-0.907931",
        "0.1", "0.3", "123456.789", "1e5", "1E5", "1e-5", "1.5e+3", "-2.5E-3", "1e22", "1e23", "1e-22", "1e-23", "1.5e",
        "1.5e+", "2E-", "3.25ex", "3.1+e2", "1.7976931348623157e308", "1e309", "-1e309", "4.9e-324",
        "2.2250738585072014e-308", "1.17549435e-38", "1.4e-45", "1e-400",
        /* 19 digits (the fast path's most), 20 and more (the general one's) */
        "1234567890123456789", "12345678901234567890", "123456789012345678901234567890", "0.1234567890123456789",
        "0.12345678901234567890", "1234567890.123456789", "9007199254740992", "9007199254740993", "900719925474099.3",
        "0.0000000000000000000001", "0.00000000000000000000001", "00000000000000000001.5",
        "3.14159265358979323846264338327950288", "0.30000000000000004441", "inf", "-inf", "+inf", "Infinity",
        "-INFINITY", "nan", "-nan", "NaN", "nan(123)", ".", "-", "+", "e5", "-.e1", "", "  7.25", "\t-3"};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) expect_like_strtod(cases[i]);
}

/* Random plain decimals up to 19 digits (the fast path) and some longer or
 * with an exponent (the general path), against strtod. */
static void test_parse_double_random(void **state)
{
    (void)state;
    uint64_t seed = 0x243F6A8885A308D3ull;
    char text[64];
    for (int n = 0; n < 200000; n++) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        uint64_t bits = seed >> 11;
        int digits = 1 + (int)(bits % 24), point = (int)((bits >> 5) % (uint64_t)(digits + 1));
        size_t at = 0;
        if (bits >> 10 & 1) text[at++] = (bits >> 11 & 1) ? '-' : '+';
        for (int d = 0; d < digits; d++) {
            if (d == point && (bits >> 12 & 1)) text[at++] = '.';
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            text[at++] = (char)('0' + (seed >> 33) % 10);
        }
        if ((bits >> 13) % 8 == 0) at += (size_t)sprintf(text + at, "e%d", (int)((bits >> 16) % 90) - 45);
        text[at] = '\0';
        expect_like_strtod(text);
    }
}

static void expect_int64(const char *text, bool parsed, long long expected, size_t length)
{
    const char *cursor = text;
    long long value = -12345;
    bool ok = lk__parse_int64(&cursor, text + strlen(text), &value);
    if (ok != parsed) fail_msg("'%s': %s", text, ok ? "parsed" : "refused");
    if (!ok) return;
    if (value != expected) fail_msg("'%s': %lld, expected %lld", text, value, expected);
    if ((size_t)(cursor - text) != length) fail_msg("'%s': ends after %d", text, (int)(cursor - text));
}

static void test_parse_int64(void **state)
{
    (void)state;
    expect_int64("0", true, 0, 1);
    expect_int64("-5", true, -5, 2);
    expect_int64("+7/", true, 7, 2);
    expect_int64(" 12a", true, 12, 3);
    expect_int64("123456789012345678", true, 123456789012345678ll, 18);
    expect_int64("1234567890123456789", true, 1234567890123456789ll, 19);
    expect_int64("9223372036854775807", true, 9223372036854775807ll, 19);
    expect_int64("-9223372036854775807", true, -9223372036854775807ll, 20);
    expect_int64("000000000000000000000000042", true, 42, 27);
    expect_int64("9223372036854775808", false, 0, 0);
    expect_int64("99999999999999999999", false, 0, 0);
    expect_int64("-", false, 0, 0);
    expect_int64("x1", false, 0, 0);
}

/* An OBJ of random coordinates reads as (float)strtod of each. */
static void test_obj_coordinates_like_strtod(void **state)
{
    (void)state;
    enum { VERTICES = 3000 };
    size_t capacity = VERTICES * 100 + 64, used = 0;
    char *text = malloc(capacity);
    float *expected = malloc(3 * VERTICES * sizeof *expected);
    assert_non_null(text);
    assert_non_null(expected);
    uint64_t seed = 7;
    static const char *const formats[] = {"%.6f", "%.9g", "%.17g", "%.3e", "%.12f", "%g"};
    for (int i = 0; i < VERTICES; i++) {
        used += (size_t)snprintf(text + used, capacity - used, "v");
        for (int k = 0; k < 3; k++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            double value = ((double)(seed >> 11) / 9007199254740992.0 - 0.5) * pow(10.0, (double)((seed >> 3) % 9) - 4);
            char number[64];
            snprintf(number, sizeof number, formats[(seed >> 7) % 6], value);
            expected[3 * i + k] = (float)strtod(number, NULL);
            used += (size_t)snprintf(text + used, capacity - used, " %s", number);
        }
        used += (size_t)snprintf(text + used, capacity - used, "\n");
    }
    used += (size_t)snprintf(text + used, capacity - used, "f 1 2 3\n");
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read_memory(text, used, "random.obj", LK_FORMAT_OBJ, NULL, &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, VERTICES);
    assert_memory_equal(mesh.positions, expected, 3 * VERTICES * sizeof *expected);
    lk_mesh_free(&mesh);
    free(text);
    free(expected);
}

/* lk__format_float before its fast path: the shortest of %.6g .. %.9g that
 * strtof reads back as the value. */
static int format_float_reference(char *buffer, size_t size, float value)
{
    for (int precision = 6; precision <= 9; precision++) {
        int length = snprintf(buffer, size, "%.*g", precision, (double)value);
        if (strtof(buffer, NULL) == value) return length;
    }
    return snprintf(buffer, size, "%.9g", (double)value);
}

static void expect_formatted_like_reference(float value)
{
    char got[64], expected[64];
    int length = lk__format_float(got, sizeof got, value);
    int expected_length = format_float_reference(expected, sizeof expected, value);
    if (strcmp(got, expected) != 0 || length != expected_length)
        fail_msg("%a: '%s' (%d), expected '%s' (%d)", (double)value, got, length, expected, expected_length);
}

/* The writers' float formatting (its single-printf fast path) gives the
 * reference's text for random bit patterns, random mesh-like coordinates,
 * and values around ties, powers of ten and the fast path's limits. */
static void test_format_float_like_reference(void **state)
{
    (void)state;
    uint64_t seed = 0x9E3779B97F4A7C15ull;
    for (int n = 0; n < 300000; n++) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        uint32_t bits = (uint32_t)(seed >> 32);
        float value;
        memcpy(&value, &bits, sizeof value);
        expect_formatted_like_reference(value);
        float coordinate = (float)(((double)(seed >> 11) / 9007199254740992.0 - 0.5) * 4.0);
        expect_formatted_like_reference(coordinate);
    }
    static const float special[] = {
        0.0f,  -0.0f,     1.0f,          -1.0f,           0.1f,     0.5f,      1e-30f,     -1e-30f,     9.99e-31f,
        1e30f, 1.001e30f, 1e-5f,         1e-4f,           99999.5f, 999999.5f, 1048576.5f, 16777216.0f, 1e6f,
        1e7f,  123456.5f, 3.4028235e38f, 1.17549435e-38f, 1e-45f,   0.296502f, -0.907931f};
    for (size_t i = 0; i < sizeof special / sizeof special[0]; i++) expect_formatted_like_reference(special[i]);
    /* Every float in a few ranges where %g changes layout or digits carry. */
    static const float starts[] = {9.9999e-5f, 0.99999f, 9.99999f, 99999.9f, 999999.0f, 9999999.0f};
    for (size_t i = 0; i < sizeof starts / sizeof starts[0]; i++) {
        float value = starts[i];
        for (int k = 0; k < 20000; k++, value = nextafterf(value, INFINITY)) expect_formatted_like_reference(value);
    }
}

/* ---- binary PLY -------------------------------------------------------------- */

enum { PLY_VERTICES = 6, PLY_FACES = 5 };
static const float ply_positions[3 * PLY_VERTICES] = {0, 0, 0, 1,    0,    0, 1,     1, 0,
                                                      0, 1, 0, 0.5f, 0.5f, 1, -2.5f, 3, 1e-3f};
static const float ply_normals[3 * PLY_VERTICES] = {0, 0, 1, 0, 0, -1, 1, 0, 0, 0, 1, 0, 0.6f, 0.8f, 0, 0, 0, 1};
/* The faces as polygons: count, then indices (the fourth face is a quad). */
static const uint32_t ply_faces[] = {3, 0, 1, 2, 3, 0, 2, 3, 3, 0, 1, 4, 4, 1, 2, 4, 5, 3, 3, 4, 5};

typedef struct ply_layout {
    bool big_endian;
    bool double_positions; /* x y z as double: no vertex fast path */
    bool face_flags;       /* a uchar after the list: no face fast path */
    bool uint_indices;     /* uint rather than int */
    int nan_vertex;        /* >= 0: that vertex's y is NaN */
    uint32_t bad_index;    /* != 0: the last index of face 1 (which the face loop reads) */
} ply_layout;

typedef struct byte_buffer {
    unsigned char bytes[4096];
    size_t size;
} byte_buffer;

static void put(byte_buffer *out, const void *bytes, size_t size, bool big_endian)
{
    assert_true(out->size + size <= sizeof out->bytes);
    for (size_t i = 0; i < size; i++)
        out->bytes[out->size + i] = ((const unsigned char *)bytes)[big_endian ? size - 1 - i : i];
    out->size += size;
}

static void make_ply(const ply_layout *layout, byte_buffer *out)
{
    out->size = 0;
    char header[512];
    const char *coordinate = layout->double_positions ? "double" : "float";
    int length =
        snprintf(header, sizeof header,
                 "ply\nformat binary_%s_endian 1.0\ncomment fast path test\nelement vertex %d\n"
                 "property %s x\nproperty %s y\nproperty %s z\nproperty float nx\nproperty float ny\n"
                 "property float nz\nelement face %d\nproperty list uchar %s vertex_indices\n%s"
                 "end_header\n",
                 layout->big_endian ? "big" : "little", PLY_VERTICES, coordinate, coordinate, coordinate, PLY_FACES,
                 layout->uint_indices ? "uint" : "int", layout->face_flags ? "property uchar flags\n" : "");
    put(out, header, (size_t)length, false);
    for (int i = 0; i < PLY_VERTICES; i++) {
        for (int k = 0; k < 3; k++) {
            float value = i == layout->nan_vertex && k == 1 ? NAN : ply_positions[3 * i + k];
            double wide = value;
            if (layout->double_positions)
                put(out, &wide, 8, layout->big_endian);
            else
                put(out, &value, 4, layout->big_endian);
        }
        for (int k = 0; k < 3; k++) put(out, &ply_normals[3 * i + k], 4, layout->big_endian);
    }
    size_t at = 0;
    for (int f = 0; f < PLY_FACES; f++) {
        unsigned char count = (unsigned char)ply_faces[at++];
        put(out, &count, 1, false);
        for (unsigned k = 0; k < count; k++) {
            uint32_t index = ply_faces[at++];
            if (f == 1 && k == count - 1u && layout->bad_index) index = layout->bad_index;
            put(out, &index, 4, layout->big_endian);
        }
        if (layout->face_flags) put(out, "\x7", 1, false);
    }
}

static lk_status read_ply(const ply_layout *layout, lk_mesh *mesh, lk_error *error)
{
    byte_buffer file;
    make_ply(layout, &file);
    return lk_mesh_read_memory(file.bytes, file.size, "fast.ply", LK_FORMAT_PLY, NULL, mesh, error);
}

static void expect_same_mesh(const lk_mesh *a, const lk_mesh *b)
{
    assert_int_equal(a->vertex_count, b->vertex_count);
    assert_int_equal(a->triangle_count, b->triangle_count);
    assert_memory_equal(a->positions, b->positions, 3 * a->vertex_count * sizeof(float));
    assert_non_null(a->normals);
    assert_non_null(b->normals);
    assert_memory_equal(a->normals, b->normals, 3 * a->vertex_count * sizeof(float));
    assert_memory_equal(a->indices, b->indices, 3 * a->triangle_count * sizeof(uint32_t));
}

/* Every layout, fast or not, gives the mesh of the ascii file. */
static void test_ply_layouts_agree(void **state)
{
    (void)state;
    char ascii[2048];
    int used = snprintf(ascii, sizeof ascii,
                        "ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float "
                        "z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face %d\nproperty list "
                        "uchar int vertex_indices\nend_header\n",
                        PLY_VERTICES, PLY_FACES);
    for (int i = 0; i < PLY_VERTICES; i++) {
        for (int k = 0; k < 3; k++)
            used += snprintf(ascii + used, sizeof ascii - (size_t)used, "%.9g ", (double)ply_positions[3 * i + k]);
        for (int k = 0; k < 3; k++)
            used += snprintf(ascii + used, sizeof ascii - (size_t)used, "%.9g ", (double)ply_normals[3 * i + k]);
        used += snprintf(ascii + used, sizeof ascii - (size_t)used, "\n");
    }
    for (size_t at = 0; at < sizeof ply_faces / sizeof ply_faces[0];) {
        uint32_t count = ply_faces[at++];
        used += snprintf(ascii + used, sizeof ascii - (size_t)used, "%u", count);
        for (uint32_t k = 0; k < count; k++)
            used += snprintf(ascii + used, sizeof ascii - (size_t)used, " %u", ply_faces[at++]);
        used += snprintf(ascii + used, sizeof ascii - (size_t)used, "\n");
    }
    lk_mesh reference;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read_memory(ascii, (size_t)used, "ascii.ply", LK_FORMAT_PLY, NULL, &reference, &error),
                     LK_OK);
    assert_int_equal(reference.triangle_count, 6); /* the quad is two */
    assert_memory_equal(reference.positions, ply_positions, sizeof ply_positions);
    for (int big_endian = 0; big_endian < 2; big_endian++)
        for (int double_positions = 0; double_positions < 2; double_positions++)
            for (int face_flags = 0; face_flags < 2; face_flags++)
                for (int uint_indices = 0; uint_indices < 2; uint_indices++) {
                    ply_layout layout = {big_endian, double_positions, face_flags, uint_indices, -1, 0};
                    lk_mesh mesh;
                    assert_int_equal(read_ply(&layout, &mesh, &error), LK_OK);
                    expect_same_mesh(&mesh, &reference);
                    lk_mesh_free(&mesh);
                }
    lk_mesh_free(&reference);
}

/* Where a fast loop stops at a bad record, the message is the general
 * code's, with the same byte offset for every layout of that record. */
static void test_ply_fast_path_errors(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error = {0};
    /* Vertex 3 starts at header + 3 * 24 bytes (float layout). */
    ply_layout nan_layout = {false, false, false, false, 3, 0};
    byte_buffer file;
    make_ply(&nan_layout, &file);
    size_t header_size = file.size - PLY_VERTICES * 24 - (PLY_FACES * 13 + 4);
    char expected[256];
    snprintf(expected, sizeof expected, "fast.ply: byte %zu: vertex 3: y = nan is not a finite float",
             header_size + 3 * 24);
    assert_int_equal(read_ply(&nan_layout, &mesh, &error), LK_ERR_RANGE);
    assert_string_equal(error.message, expected);
    nan_layout.big_endian = true; /* "big" is 3 bytes shorter than "little" */
    snprintf(expected, sizeof expected, "fast.ply: byte %zu: vertex 3: y = nan is not a finite float",
             header_size - 3 + 3 * 24);
    assert_int_equal(read_ply(&nan_layout, &mesh, &error), LK_ERR_RANGE);
    assert_string_equal(error.message, expected);

    /* Face 1's last index: out of range, then negative (int), then large (uint). */
    size_t faces_start = header_size + PLY_VERTICES * 24, last_index = faces_start + 13 + 1 + 2 * 4;
    snprintf(expected, sizeof expected, "fast.ply: byte %zu: face 1: vertex index 6 is out of range (6 vertices)",
             last_index);
    ply_layout range_layout = {false, false, false, false, -1, 6};
    assert_int_equal(read_ply(&range_layout, &mesh, &error), LK_ERR_RANGE);
    assert_string_equal(error.message, expected);
    snprintf(expected, sizeof expected, "fast.ply: byte %zu: face 1: vertex index -1 is negative", last_index);
    range_layout.bad_index = 0xFFFFFFFFu;
    assert_int_equal(read_ply(&range_layout, &mesh, &error), LK_ERR_RANGE);
    assert_string_equal(error.message, expected);
    range_layout.uint_indices = true;
    snprintf(expected, sizeof expected,
             "fast.ply: byte %zu: face 1: vertex index 4294967295 is out of range (6 vertices)",
             last_index + 1); /* "uint" is a byte longer than "int" */
    assert_int_equal(read_ply(&range_layout, &mesh, &error), LK_ERR_RANGE);
    assert_string_equal(error.message, expected);

    /* Truncated in face 1, after its count and one index: the loop stops
     * after face 0, the general code reports face 1. */
    ply_layout plain = {false, false, false, false, -1, 0};
    make_ply(&plain, &file);
    snprintf(expected, sizeof expected,
             "fast.ply: byte %zu: face 1: list 'vertex_indices' of 3 items needs 12 bytes but only 4 are left",
             faces_start + 13);
    assert_int_equal(
        lk_mesh_read_memory(file.bytes, faces_start + 13 + 5, "fast.ply", LK_FORMAT_PLY, NULL, &mesh, &error),
        LK_ERR_PARSE);
    assert_string_equal(error.message, expected);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse_double_edge_cases),
        cmocka_unit_test(test_parse_double_random),
        cmocka_unit_test(test_parse_int64),
        cmocka_unit_test(test_obj_coordinates_like_strtod),
        cmocka_unit_test(test_format_float_like_reference),
        cmocka_unit_test(test_ply_layouts_agree),
        cmocka_unit_test(test_ply_fast_path_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
