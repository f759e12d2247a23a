/* SPDX-License-Identifier: MIT */
/* Hostile sizes (issue 10): headers and tables that claim billions of
 * elements, huge offsets, deeply nested or enormous glTF JSON, amplifying
 * inputs (a few bytes that ask for megabytes) — for every reader. Each
 * input is generated here; each must be refused with LK_ERR_LIMIT or
 * LK_ERR_PARSE (or TRUNCATED/RANGE where the claim is checked against the
 * file) and a message saying where, before anything of the claimed size
 * is allocated. Peak RSS is checked after the hostile cases (ASan also
 * aborts on any allocation it cannot satisfy), and the budgets are shown
 * to leave the real sample models alone. */
#include <limits.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>
#include <zlib.h>

#include "testutil.h"

lk_status lk__dem_read_memory(const void *data, size_t size, const char *name, const lk_dem_options *options,
                              lk_heightfield *out, lk_error *error);

static long start_rss_kb;

static long peak_rss_kb(void)
{
    struct rusage usage;
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_maxrss;
}

#if defined(__SANITIZE_ADDRESS__)
#define LK_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LK_TEST_ASAN 1
#endif
#endif

/* Every hostile case must leave the peak RSS close to where it started.
 * Under ASan freed blocks sit in a quarantine (and RSS means little), but
 * ASan aborts on any allocation it cannot satisfy, which is the check. */
static void assert_rss_small(void)
{
#ifndef LK_TEST_ASAN
    long grown = peak_rss_kb() - start_rss_kb;
    if (grown > 200 * 1024) fail_msg("peak RSS grew by %ld KiB", grown);
#endif
}

/* A growable text built by the tests. */
typedef struct text {
    char *data;
    size_t size, capacity;
} text;

#if defined(__GNUC__)
__attribute__((noinline))
#endif
static void
put(text *t, const void *bytes, size_t size)
{
    if (size == 0) return;
    if (t->size + size + 1 > t->capacity) {
        size_t capacity = t->capacity ? t->capacity : 1024;
        while (capacity < t->size + size + 1) capacity *= 2;
        t->data = realloc(t->data, capacity);
        assert_non_null(t->data);
        t->capacity = capacity;
    }
    memcpy(t->data + t->size, bytes, size);
    t->size += size;
    t->data[t->size] = '\0';
}
static void puts_text(text *t, const char *s) { put(t, s, strlen(s)); }
static void repeat(text *t, const char *s, size_t times)
{
    for (size_t i = 0; i < times; i++) puts_text(t, s);
}
static void put_fill(text *t, char c, size_t count)
{
    if (t->size + count + 1 > t->capacity) {
        t->capacity = t->size + count + 1;
        t->data = realloc(t->data, t->capacity);
        assert_non_null(t->data);
    }
    memset(t->data + t->size, c, count);
    t->size += count;
    t->data[t->size] = '\0';
}

/* Reads bytes (an exact-size heap copy, so ASan sees overruns) as a mesh. */
static lk_status read_mesh_bytes(const void *bytes, size_t size, const char *name, size_t max_bytes, lk_mesh *mesh,
                                 lk_error *error)
{
    void *copy = malloc(size ? size : 1);
    assert_non_null(copy);
    memcpy(copy, bytes, size);
    lk_read_options options = {.max_bytes = max_bytes};
    lk_error_clear(error);
    lk_status status = lk_mesh_read_memory(copy, size, name, LK_FORMAT_AUTO, &options, mesh, error);
    free(copy);
    return status;
}

static void expect_mesh_refused(const void *bytes, size_t size, const char *name, size_t max_bytes, lk_status status,
                                const char *needle)
{
    lk_mesh mesh;
    lk_error error;
    lk_status got = read_mesh_bytes(bytes, size, name, max_bytes, &mesh, &error);
    if (got != status)
        fail_msg("%s: expected %s, got %s (\"%s\")", name, lk_status_string(status), lk_status_string(got),
                 error.message);
    lk_assert_message_contains(error, needle);
    assert_null(mesh.positions);
    assert_int_equal(mesh.vertex_count, 0);
    assert_rss_small();
}

static void expect_animation_refused(const void *bytes, size_t size, const char *name,
                                     const lk_animation_read_options *options, lk_status status, const char *needle)
{
    void *copy = malloc(size);
    assert_non_null(copy);
    memcpy(copy, bytes, size);
    lk_animation animation;
    lk_error error = {0};
    lk_status got = lk_animation_read_memory(copy, size, name, options, &animation, NULL, &error);
    free(copy);
    if (got != status)
        fail_msg("%s: expected %s, got %s (\"%s\")", name, lk_status_string(status), lk_status_string(got),
                 error.message);
    lk_assert_message_contains(error, needle);
    assert_null(animation.frame_positions);
    assert_rss_small();
}

static void put_u32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static void put_u64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}

/* ---- everything a read holds counts (issue 17) -------------------------- */

#ifndef LK_TEST_ASAN
/* Resident memory now (ru_maxrss is the peak so far), from /proc. */
static long current_rss_kb(void)
{
    long pages = 0, resident = 0;
    FILE *file = fopen("/proc/self/statm", "r");
    if (file) {
        if (fscanf(file, "%ld %ld", &pages, &resident) != 2) resident = 0;
        fclose(file);
    }
    return resident * (sysconf(_SC_PAGESIZE) / 1024);
}
#endif

static void put_u32(unsigned char *p, uint32_t v);

/* Regressions: the input, a decoded data: URI and the arrays were each held
 * to the whole budget, so a read could hold several times it. */
static void test_read_holds_everything(void **state)
{
    (void)state;
    /* 100,000 vertex lines (800 KB) make 1.2 MB of positions: they fit in
     * 1.5 MiB, not with the text they come from */
    text t = {0};
    repeat(&t, "v 0 0 0\n", 100000);
    expect_mesh_refused(t.data, t.size, "text.obj", 3 << 19, LK_ERR_LIMIT,
                        "the model needs more than the memory budget of 1572864 bytes");
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_mesh_bytes(t.data, t.size, "text.obj", 4 << 20, &mesh, &error), LK_OK);
    lk_mesh_free(&mesh);
    free(t.data);

    /* a 3 MB base64 data: URI decodes to 2.25 MB: it fits in 4 MiB, not
     * with the document holding it */
    size_t decoded = 2250000;
    unsigned char *bytes = calloc(1, decoded);
    char *base64 = malloc(decoded / 3 * 4 + 8);
    assert_non_null(bytes);
    assert_non_null(base64);
    float one = 1.0f;
    memcpy(bytes + 12, &one, 4);
    memcpy(bytes + 28, &one, 4);
    lk_test_base64(bytes, decoded, base64);
    free(bytes);
    t = (text){0};
    char head[256];
    snprintf(head, sizeof head,
             "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":%zu,\"uri\":"
             "\"data:application/octet-stream;base64,",
             decoded);
    puts_text(&t, head);
    puts_text(&t, base64);
    free(base64);
    puts_text(&t, "\"}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],\"accessors\":[{\"bufferView\":0,"
                  "\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}],\"meshes\":[{\"primitives\":"
                  "[{\"attributes\":{\"POSITION\":0}}]}]}");
    expect_mesh_refused(t.data, t.size, "uri.gltf", 4 << 20, LK_ERR_LIMIT,
                        "uri.gltf: buffers[0].uri: 3000000 bytes of base64 data would exceed the memory budget of "
                        "4194304 bytes");
    assert_int_equal(read_mesh_bytes(t.data, t.size, "uri.gltf", 8 << 20, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 1);
    lk_mesh_free(&mesh);
    free(t.data);

    /* a binary PLY grid of 490,000 vertices and 976,082 triangles (18.6
     * MB) whose arrays (17.6 MB) fit in a budget of 22.8 MB, not with the
     * file: refused, and the read's resident memory grows by no more than
     * 8 MiB (it was 17 MB of arrays) */
    size_t n = 700, vertex_count = n * n, triangle_count = 2 * (n - 1) * (n - 1);
    char header[256];
    int header_length = snprintf(header, sizeof header,
                                 "ply\nformat binary_little_endian 1.0\nelement vertex %zu\nproperty float x\n"
                                 "property float y\nproperty float z\nelement face %zu\n"
                                 "property list uchar int vertex_indices\nend_header\n",
                                 vertex_count, triangle_count);
    size_t size = (size_t)header_length + 12 * vertex_count + 13 * triangle_count;
    unsigned char *ply = malloc(size), *p = ply;
    assert_non_null(ply);
    memcpy(p, header, (size_t)header_length);
    p += header_length;
    for (size_t v = 0; v < vertex_count; v++, p += 12) {
        float xyz[3] = {(float)(v % n), (float)(v / n), 0};
        memcpy(p, xyz, sizeof xyz);
    }
    for (size_t j = 0; j + 1 < n; j++)
        for (size_t i = 0; i + 1 < n; i++) {
            uint32_t a = (uint32_t)(j * n + i),
                     corners[6] = {a, a + 1, a + (uint32_t)n, a + 1, a + (uint32_t)n + 1, a + (uint32_t)n};
            for (int k = 0; k < 2; k++, p += 13) {
                *p = 3;
                for (int c = 0; c < 3; c++) put_u32(p + 1 + 4 * c, corners[3 * k + c]);
            }
        }
    assert_int_equal((size_t)(p - ply), size);
    lk_read_options options = {.max_bytes = size + (4 << 20)};
#ifndef LK_TEST_ASAN
    long before_kb = current_rss_kb();
#endif
    lk_error_clear(&error);
    assert_int_equal(lk_mesh_read_memory(ply, size, "grid.ply", LK_FORMAT_AUTO, &options, &mesh, &error), LK_ERR_LIMIT);
    char needle[128];
    snprintf(needle, sizeof needle, "grid.ply:3: 490000 vertices would need more than the memory budget of %zu bytes",
             options.max_bytes);
    lk_assert_message_contains(error, needle);
#ifndef LK_TEST_ASAN
    long grown_kb = peak_rss_kb() - before_kb;
    if (grown_kb > 8 << 10) fail_msg("the refused read grew the resident memory by %ld KiB", grown_kb);
#endif
    options.max_bytes = size + (48 << 20);
    assert_int_equal(lk_mesh_read_memory(ply, size, "grid.ply", LK_FORMAT_AUTO, &options, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, triangle_count);
    lk_mesh_free(&mesh);
    free(ply);
}

/* ---- PLY, OFF, OBJ, SMF, STL, XYZ ------------------------------------- */

static void test_ply_claims(void **state)
{
    (void)state;
    static const struct {
        const char *text;
        const char *needle;
    } headers[] = {
        /* 4e9 vertices in an ascii file of a few bytes */
        {"ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\n"
         "end_header\n0 0 0\n",
         "claims.ply:3: header claims 4000000000 vertices"},
        /* more than LK_MAX_ELEMENTS */
        {"ply\nformat binary_little_endian 1.0\nelement vertex 9223372036854775807\nproperty float x\n"
         "property float y\nproperty float z\nend_header\n",
         "claims.ply:3: 9223372036854775807 vertices is more than lodkit supports"},
        /* 4e9 faces after three real vertices */
        {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nelement face 4000000000\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 0\n0 0 0\n0 0 0\n",
         "claims.ply:7: header claims 4000000000 faces"},
        /* a skipped element of 4e9 records */
        {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
         "element edge 4000000000\nproperty int a\nend_header\n0 0 0\n",
         "claims.ply:7: header claims 4000000000 'edge' elements"},
    };
    for (size_t i = 0; i < sizeof headers / sizeof headers[0]; i++)
        expect_mesh_refused(headers[i].text, strlen(headers[i].text), "claims.ply", 0, LK_ERR_LIMIT, headers[i].needle);
    /* 2^63 does not even parse as a count */
    const char *huge = "ply\nformat ascii 1.0\nelement vertex 9223372036854775808\nproperty float x\nend_header\n";
    expect_mesh_refused(huge, strlen(huge), "huge.ply", 0, LK_ERR_PARSE, "huge.ply:3: element count");
    /* a list that claims 2^32-1 items in a binary face */
    unsigned char body[256];
    const char *header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                         "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n";
    size_t length = strlen(header);
    memcpy(body, header, length);
    memset(body + length, 0, 36);
    put_u32(body + length + 36, 0xFFFFFFFFu);
    expect_mesh_refused(body, length + 40, "list.ply", 0, LK_ERR_PARSE, "list 'vertex_indices' of 4294967295 items");
    /* the budget is applied to real counts too */
    const char *small = "ply\nformat ascii 1.0\nelement vertex 1000\nproperty float x\nproperty float y\n"
                        "property float z\nend_header\n";
    text t = {0};
    puts_text(&t, small);
    repeat(&t, "0 0 0\n", 1000);
    expect_mesh_refused(t.data, t.size, "budget.ply", 1000, LK_ERR_LIMIT, "memory budget of 1000 bytes");
    free(t.data);
}

static void test_off_claims_and_fans(void **state)
{
    (void)state;
    const char *vertices = "OFF\n4000000000 1 0\n0 0 0\n";
    expect_mesh_refused(vertices, strlen(vertices), "v.off", 0, LK_ERR_LIMIT,
                        "v.off:2: header claims 4000000000 vertices");
    const char *faces = "OFF\n3 4000000000 0\n0 0 0\n1 0 0\n0 1 0\n";
    expect_mesh_refused(faces, strlen(faces), "f.off", 0, LK_ERR_LIMIT, "4000000000 faces");
    const char *negative = "OFF\n-1 1 0\n";
    expect_mesh_refused(negative, strlen(negative), "n.off", 0, LK_ERR_PARSE, "negative count");
    /* Regression: a polygon of n corners (2n bytes) is fanned into n - 2
     * triangles (12n bytes); the triangles were not held to the budget. */
    text t = {0};
    puts_text(&t, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n200000");
    repeat(&t, " 0 1 2 1", 50000);
    puts_text(&t, "\n");
    expect_mesh_refused(t.data, t.size, "fan.off", 1 << 20, LK_ERR_LIMIT, "fan.off:6: face of 200000 vertices");
    /* the same face within a budget that holds it */
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_mesh_bytes(t.data, t.size, "fan.off", 8 << 20, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 199998);
    lk_mesh_free(&mesh);
    free(t.data);
}

static void test_obj_amplification(void **state)
{
    (void)state;
    /* one face line of 300,000 corners: 600 KB of text, 3.6 MB of corners */
    text t = {0};
    puts_text(&t, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf");
    repeat(&t, " 1 2 3", 100000);
    puts_text(&t, "\n");
    expect_mesh_refused(t.data, t.size, "fan.obj", 1 << 20, LK_ERR_LIMIT,
                        "fan.obj:4: the model needs more than the memory budget of 1048576 bytes");
    free(t.data);
    /* Regression: the first coloured vertex back-fills a colour for every
     * earlier one (16 bytes each): 100,000 plain vertices then one coloured
     * passed the budget unchecked. */
    memset(&t, 0, sizeof t);
    repeat(&t, "v 0 0 0\n", 100000);
    puts_text(&t, "v 0 0 0 1 1 1\n");
    expect_mesh_refused(t.data, t.size, "colours.obj", 2 << 20, LK_ERR_LIMIT, "colours.obj:100001:");
    free(t.data);
    /* texture coordinates and normals count too */
    memset(&t, 0, sizeof t);
    puts_text(&t, "v 0 0 0\n");
    repeat(&t, "vn 0 0 1\n", 100000);
    expect_mesh_refused(t.data, t.size, "normals.obj", 1 << 20, LK_ERR_LIMIT, "memory budget of 1048576 bytes");
    free(t.data);
}

static void test_smf_stl_xyz(void **state)
{
    (void)state;
    text t = {0};
    repeat(&t, "v 0 0 0\n", 100000);
    expect_mesh_refused(t.data, t.size, "many.smf", 1 << 20, LK_ERR_LIMIT, "many.smf:");
    expect_mesh_refused(t.data, t.size, "many.xyz", 0, LK_ERR_PARSE, "many.xyz:1"); /* "v" is not a number */
    free(t.data);
    memset(&t, 0, sizeof t);
    puts_text(&t, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf");
    repeat(&t, " 1 2 3", 100000);
    puts_text(&t, "\n");
    expect_mesh_refused(t.data, t.size, "fan.smf", 1 << 20, LK_ERR_LIMIT, "fan.smf:4: the model needs more");
    free(t.data);
    memset(&t, 0, sizeof t);
    repeat(&t, "0 0 0\n", 100000);
    expect_mesh_refused(t.data, t.size, "points.xyz", 1 << 20, LK_ERR_LIMIT, "points.xyz:");
    free(t.data);
    /* binary STL claiming 2^32-1 triangles in 84 bytes: not a binary file
     * of that size, and not ASCII either */
    unsigned char stl[84] = {0};
    put_u32(stl + 80, 0xFFFFFFFFu);
    lk_mesh mesh;
    lk_error error;
    assert_int_not_equal(read_mesh_bytes(stl, sizeof stl, "claim.stl", 0, &mesh, &error), LK_OK);
    assert_null(mesh.positions);
    /* a real binary STL over the budget: 20,000 triangles of 3 new vertices */
    size_t count = 20000, size = 84 + 50 * count;
    unsigned char *binary = calloc(1, size);
    assert_non_null(binary);
    put_u32(binary + 80, (uint32_t)count);
    for (size_t i = 0; i < count; i++) {
        float corner[9] = {(float)i, 0, 0, (float)i, 1, 0, (float)i, 0, 1};
        memcpy(binary + 84 + 50 * i + 12, corner, sizeof corner);
    }
    /* (the file itself, 1 MB, fits: the 240 KB of triangles do not) */
    expect_mesh_refused(binary, size, "big.stl", 1100000, LK_ERR_LIMIT,
                        "big.stl: byte 80: 20000 triangles would need more");
    free(binary);
    assert_rss_small();
}

/* ---- glTF / GLB --------------------------------------------------------- */

/* A one-triangle glTF with an embedded buffer and `extra` spliced into the
 * top-level object (after a comma). */
static void gltf_triangle(text *t, const char *extra_accessors, const char *extra)
{
    static const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    char base64[64];
    lk_test_base64((const unsigned char *)positions, sizeof positions, base64);
    char head[1024];
    snprintf(head, sizeof head,
             "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":36,\"uri\":"
             "\"data:application/octet-stream;base64,%s\"}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}%s],"
             "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],"
             "\"nodes\":[{\"mesh\":0}],\"scenes\":[{\"nodes\":[0]}]",
             base64, extra_accessors ? extra_accessors : "");
    puts_text(t, head);
    if (extra) {
        puts_text(t, ",");
        puts_text(t, extra);
    }
    puts_text(t, "}");
}

static void expect_gltf_refused(const char *json_text, size_t max_bytes, lk_status status, const char *needle)
{
    expect_mesh_refused(json_text, strlen(json_text), "hostile.gltf", max_bytes, status, needle);
}

static void test_gltf_accessor_claims(void **state)
{
    (void)state;
    static const struct {
        const char *accessor;
        lk_status status;
        const char *needle;
    } cases[] = {
        /* zeros without a bufferView: 4e9 vertices would be 48 GB */
        {"{\"componentType\":5126,\"count\":4000000000,\"type\":\"VEC3\"}", LK_ERR_LIMIT, "memory budget"},
        {"{\"componentType\":5126,\"count\":9007199254740992,\"type\":\"VEC3\"}", LK_ERR_LIMIT,
         "more than lodkit supports"},
        {"{\"componentType\":5126,\"count\":1e300,\"type\":\"VEC3\"}", LK_ERR_PARSE, "non-negative integer"},
        {"{\"bufferView\":0,\"componentType\":5126,\"count\":4000000000,\"type\":\"VEC3\"}", LK_ERR_RANGE,
         "count 4000000000 exceeds bufferView 0"},
        {"{\"bufferView\":0,\"byteOffset\":9007199254740990,\"componentType\":5126,\"count\":1,\"type\":\"VEC3\"}",
         LK_ERR_RANGE, "accessors[1]"},
        {"{\"bufferView\":1,\"componentType\":5126,\"count\":1,\"type\":\"VEC3\"}", LK_ERR_RANGE,
         "bufferView 1 out of range"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char accessors[256];
        snprintf(accessors, sizeof accessors, ",%s", cases[i].accessor);
        text t = {0};
        gltf_triangle(&t, accessors, NULL);
        /* POSITION of the mesh -> accessor 1 */
        char *position = strstr(t.data, "\"POSITION\":0");
        assert_non_null(position);
        position[11] = '1';
        expect_gltf_refused(t.data, 0, cases[i].status, cases[i].needle);
        free(t.data);
    }
    /* buffer and bufferView lengths far beyond the data */
    text t = {0};
    gltf_triangle(&t, NULL, NULL);
    char *length = strstr(t.data, "\"byteLength\":36,\"uri\"");
    assert_non_null(length);
    char *patched = malloc(t.size + 32);
    assert_non_null(patched);
    size_t prefix = (size_t)(length - t.data);
    memcpy(patched, t.data, prefix);
    sprintf(patched + prefix, "\"byteLength\":4294967296%s", length + strlen("\"byteLength\":36"));
    expect_gltf_refused(patched, 0, LK_ERR_RANGE, "byteLength: 4294967296 bytes but the data: URI holds only 36");
    free(patched);
    free(t.data);
}

static void test_glb_chunks(void **state)
{
    (void)state;
    unsigned char glb[64] = {0};
    memcpy(glb, "glTF", 4);
    put_u32(glb + 4, 2);
    put_u32(glb + 8, sizeof glb);
    put_u32(glb + 12, 0xFFFFFFFFu); /* JSON chunk length */
    put_u32(glb + 16, 0x4E4F534Au);
    expect_mesh_refused(glb, sizeof glb, "chunk.glb", 0, LK_ERR_PARSE,
                        "chunk.glb: byte 12: chunk 0 claims 4294967295 bytes");
    put_u32(glb + 8, 0xFFFFFFFFu); /* total length */
    expect_mesh_refused(glb, sizeof glb, "length.glb", 0, LK_ERR_PARSE,
                        "length.glb: byte 8: header says the file has 4294967295 bytes");
    /* a BIN chunk of 2^32 - 4 bytes after a valid JSON chunk */
    put_u32(glb + 8, sizeof glb);
    put_u32(glb + 12, 12);
    memcpy(glb + 20, "{}          ", 12);
    put_u32(glb + 32, 0xFFFFFFFCu);
    put_u32(glb + 36, 0x004E4942u);
    expect_mesh_refused(glb, sizeof glb, "bin.glb", 0, LK_ERR_PARSE,
                        "bin.glb: byte 32: chunk 1 claims 4294967292 bytes");
}

static void test_gltf_deep_json(void **state)
{
    (void)state;
    /* 100,000 '[' (and the matching ']'): refused with the byte where the
     * depth limit is passed, before cJSON sees it (cJSON itself stops at
     * CJSON_NESTING_LIMIT = 1000 with a bare parse failure) */
    text t = {0};
    puts_text(&t, "{\"asset\":{\"version\":\"2.0\"},\"extras\":");
    size_t opening = t.size;
    put_fill(&t, '[', 100000);
    put_fill(&t, ']', 100000);
    puts_text(&t, "}");
    char needle[96];
    snprintf(needle, sizeof needle, "hostile.gltf: byte %zu: JSON nested deeper than 512 levels", opening + 511);
    expect_gltf_refused(t.data, 0, LK_ERR_LIMIT, needle);
    free(t.data);
    /* just past cJSON's own limit, and just inside ours */
    memset(&t, 0, sizeof t);
    puts_text(&t, "{\"asset\":{\"version\":\"2.0\"},\"extras\":");
    put_fill(&t, '{', 0);
    for (int i = 0; i < 1001; i++) puts_text(&t, "{\"a\":");
    puts_text(&t, "1");
    put_fill(&t, '}', 1001);
    puts_text(&t, "}");
    expect_gltf_refused(t.data, 0, LK_ERR_LIMIT, "JSON nested deeper than 512 levels");
    free(t.data);
    memset(&t, 0, sizeof t);
    puts_text(&t, "{\"a\":");
    for (int i = 0; i < 500; i++) puts_text(&t, "[");
    for (int i = 0; i < 500; i++) puts_text(&t, "]");
    puts_text(&t, ",");
    /* brackets inside strings do not count */
    puts_text(&t, "\"s\":\"");
    put_fill(&t, '[', 5000);
    puts_text(&t, "\\\"\",\"extras\":0}");
    /* a document of the right depth reaches the glTF checks */
    expect_gltf_refused(t.data, 0, LK_ERR_PARSE, "asset: missing");
    free(t.data);
}

static void test_gltf_enormous_json(void **state)
{
    (void)state;
    /* 20 MB of whitespace around a valid one-triangle document: read */
    text t = {0};
    gltf_triangle(&t, NULL, NULL);
    t.data[t.size - 1] = ' ';
    put_fill(&t, ' ', (size_t)20 << 20);
    puts_text(&t, "}");
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_mesh_bytes(t.data, t.size, "spaces.gltf", 0, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 1);
    lk_mesh_free(&mesh);
    /* ... and refused under a 24 MiB budget (the 20 MiB input fits, its
     * parse does not even with 16 MiB more), naming it */
    expect_mesh_refused(t.data, t.size, "spaces.gltf", 24 << 20, LK_ERR_LIMIT,
                        "more than the memory budget of 25165824 bytes (+ 16 MiB for parsing)");
    free(t.data);
    /* a giant string in extras */
    memset(&t, 0, sizeof t);
    puts_text(&t, "\"extras\":\"");
    put_fill(&t, 'x', (size_t)10 << 20);
    puts_text(&t, "\"");
    text doc = {0};
    gltf_triangle(&doc, NULL, t.data);
    free(t.data);
    t = (text){0};
    assert_int_equal(read_mesh_bytes(doc.data, doc.size, "string.gltf", 0, &mesh, &error), LK_OK);
    lk_mesh_free(&mesh);
    free(doc.data);
    free(t.data);
    /* 2 million values (4 MB of "0,") parse into ~160 MB of cJSON items:
     * refused under 64 MiB before cJSON allocates them */
    memset(&t, 0, sizeof t);
    puts_text(&t, "\"extras\":[");
    repeat(&t, "0,", 2000000);
    puts_text(&t, "0]");
    memset(&doc, 0, sizeof doc);
    gltf_triangle(&doc, NULL, t.data);
    expect_mesh_refused(doc.data, doc.size, "values.gltf", 64 << 20, LK_ERR_LIMIT, "up to 2000");
    free(doc.data);
    free(t.data);
}

static void test_gltf_animation_claims(void **state)
{
    (void)state;
    lk_animation_read_options options;
    memset(&options, 0, sizeof options);
    /* Regression: key times from an accessor without a bufferView
     * (count zeros) were allocated and filled before anything was checked:
     * 4e9 keys asked for 16 GB. */
    text t = {0};
    gltf_triangle(&t, ",{\"componentType\":5126,\"count\":4000000000,\"type\":\"SCALAR\"}",
                  "\"animations\":[{\"samplers\":[{\"input\":1,\"output\":1}],"
                  "\"channels\":[{\"sampler\":0,\"target\":{\"node\":0,\"path\":\"scale\"}}]}]");
    expect_animation_refused(t.data, t.size, "keys.gltf", &options, LK_ERR_LIMIT, "4000000000 accessor elements");
    /* 100 million (400 MB) under a 64 MiB budget */
    char *count = strstr(t.data, "4000000000");
    memcpy(count, " 100000000", 10);
    options.max_bytes = 64 << 20;
    expect_animation_refused(t.data, t.size, "keys.gltf", &options, LK_ERR_LIMIT, "memory budget of 67108864 bytes");
    free(t.data);
    /* Regression: 100,000 morph targets ("{}," each) on 100,000 vertices
     * of zeros asked calloc for 120 GB. */
    text targets = {0};
    puts_text(&targets, "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":1},\"targets\":[");
    repeat(&targets, "{},", 99999);
    puts_text(&targets, "{}]}]}]");
    memset(&t, 0, sizeof t);
    gltf_triangle(&t, ",{\"componentType\":5126,\"count\":99999,\"type\":\"VEC3\"}", NULL);
    char *meshes = strstr(t.data, "\"meshes\"");
    char *nodes = strstr(t.data, ",\"nodes\"");
    text doc = {0};
    put(&doc, t.data, (size_t)(meshes - t.data));
    put(&doc, targets.data, targets.size);
    puts_text(&doc, nodes);
    options.max_bytes = 0;
    expect_animation_refused(doc.data, doc.size, "morph.gltf", &options, LK_ERR_LIMIT, "100000 morph target deltas");
    free(doc.data);
    free(targets.data);
    free(t.data);
    /* a skin of a million joints (2 MB of JSON, 264 MB of matrices) */
    text skin = {0};
    puts_text(&skin, "\"skins\":[{\"joints\":[");
    repeat(&skin, "0,", 999999);
    puts_text(&skin, "0]}]");
    memset(&t, 0, sizeof t);
    gltf_triangle(&t, NULL, skin.data);
    options.max_bytes = 128 << 20; /* the JSON tree itself (~80 MB) fits */
    expect_animation_refused(t.data, t.size, "skin.gltf", &options, LK_ERR_LIMIT, "1000000 joints");
    free(t.data);
    free(skin.data);
}

/* ---- key-frame formats -------------------------------------------------- */

static void test_kmf_claims(void **state)
{
    (void)state;
    const char *claim = "kmf 1\nframes 99999\nfps 10\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    lk_animation_read_options options;
    memset(&options, 0, sizeof options);
    expect_animation_refused(claim, strlen(claim), "claim.kmf", &options, LK_ERR_LIMIT,
                             "claim.kmf:2: the header claims 99999 frames");
    /* Regression: with a caller's high frame limit, the per-frame name
     * table was allocated from the claim before the file was looked at
     * (a 60-byte file asked calloc for 8 TB). */
    const char *trillion = "kmf 1\nframes 1000000000000\nfps 10\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    options.max_frames = (size_t)1 << 50;
    expect_animation_refused(trillion, strlen(trillion), "trillion.kmf", &options, LK_ERR_LIMIT,
                             "claims 1000000000000 frames");
    const char *limit = "kmf 1\nframes 1000000000000\nfps 10\nframe\n";
    options.max_frames = 0;
    expect_animation_refused(limit, strlen(limit), "limit.kmf", &options, LK_ERR_LIMIT,
                             "more than the limit of 100000");
}

static void md2_header(unsigned char *data, const int32_t fields[17])
{
    memcpy(data, "IDP2", 4);
    for (int i = 1; i < 17; i++) put_u32(data + 4 * i, (uint32_t)fields[i]);
}

static void test_md2_claims(void **state)
{
    (void)state;
    enum { SIZE = 68 + 40 + 12 };
    unsigned char data[SIZE] = {0};
    /* version, skin w/h, frame size, skins, vertices, st, triangles, glcmds, frames, offsets */
    int32_t good[17] = {0, 8, 0, 0, 44, 0, 1, 0, 0, 0, 1, 68, 68, 68, 68, SIZE, SIZE};
    lk_animation_read_options options;
    memset(&options, 0, sizeof options);
    static const struct {
        int field;
        int32_t value;
        lk_status status;
        const char *needle;
    } cases[] = {
        {10, 0x7FFFFFFF, LK_ERR_LIMIT, "byte 40: 2147483647 frames is more than the limit"},
        {6, 0x7FFFFFFF, LK_ERR_PARSE, "byte 16: frame size 44 is too small for 2147483647 vertices"},
        {8, 0x7FFFFFFF, LK_ERR_TRUNCATED, "triangle block (2147483647 x 12 bytes) runs past the end"},
        {14, 0x7FFFFFF0, LK_ERR_TRUNCATED, "byte 2147483632: frame block"},
        {14, -4, LK_ERR_PARSE, "byte 56: negative frames offset"},
        {9, 0x7FFFFFFF, LK_ERR_TRUNCATED, "GL command block"},
        {16, 0x7FFFFFFF, LK_ERR_TRUNCATED, "byte 64: the header says the file has 2147483647 bytes"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int32_t fields[17];
        memcpy(fields, good, sizeof fields);
        fields[cases[i].field] = cases[i].value;
        md2_header(data, fields);
        expect_animation_refused(data, SIZE, "claim.md2", &options, cases[i].status, cases[i].needle);
    }
    /* 100,000 frames of 2,000 vertices: 2.4 GB of positions under a 64 MiB budget
     * (frames read from one block overlapping itself is fine: the budget comes first) */
    int32_t frames[17];
    memcpy(frames, good, sizeof frames);
    frames[4] = 40 + 4 * 2000;
    frames[6] = 2000;
    frames[10] = 100000;
    frames[14] = 68;
    size_t big = 68 + (size_t)100000 * (size_t)frames[4];
    (void)big; /* the file would have to be that large: the size check comes first */
    md2_header(data, frames);
    expect_animation_refused(data, SIZE, "frames.md2", &options, LK_ERR_TRUNCATED, "frame block (100000 x 8040 bytes)");
}

/* ---- Acclaim ------------------------------------------------------------ */

static void write_text(const char *path, const char *content)
{
    FILE *file = fopen(path, "w");
    assert_non_null(file);
    fputs(content, file);
    fclose(file);
}

static void test_acclaim_budget(void **state)
{
    (void)state;
    const char *dir = lk_test_tmpdir();
    char smf[512], asf[512], amc[512], wgt[512];
    snprintf(smf, sizeof smf, "%s/hostile.smf", dir);
    snprintf(asf, sizeof asf, "%s/hostile.asf", dir);
    snprintf(amc, sizeof amc, "%s/hostile.amc", dir);
    snprintf(wgt, sizeof wgt, "%s/hostile.wgt", dir);
    write_text(smf, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    write_text(asf, ":units\nangle deg\n:root\norder TX TY TZ RX RY RZ\naxis XYZ\nposition 0 0 0\norientation 0 0 0\n"
                    ":bonedata\nbegin\nname a\ndirection 0 1 0\nlength 1\naxis 0 0 0 XYZ\ndof rx ry rz\nend\n"
                    ":hierarchy\nbegin\nroot a\nend\n");
    write_text(wgt, "wgt 1\n1 a 1\n2 a 1\n3 a 1\n");
    text t = {0};
    for (int f = 1; f <= 2000; f++) {
        char frame[128];
        snprintf(frame, sizeof frame, "%d\nroot 0 0 0 0 0 0\na 0 0 %d\n", f, f % 360);
        puts_text(&t, frame);
    }
    write_text(amc, t.data);
    free(t.data);
    lk_animation animation;
    lk_error error = {0};
    lk_animation_read_options options;
    memset(&options, 0, sizeof options);
    /* the control: it reads */
    assert_int_equal(lk_animation_read_acclaim(smf, asf, amc, wgt, &options, &animation, NULL, &error), LK_OK);
    assert_int_equal(animation.frame_count, 2000);
    lk_animation_free(&animation);
    /* the frame limit stops the motion while it is read */
    options.max_frames = 100;
    assert_int_equal(lk_animation_read_acclaim(smf, asf, amc, wgt, &options, &animation, NULL, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "hostile.amc:");
    lk_assert_message_contains(error, "more than 100 frames");
    /* 2000 frames x 9 channels x 8 bytes = 144,000 bytes of motion */
    options.max_frames = 0;
    options.max_bytes = 100000;
    assert_int_equal(lk_animation_read_acclaim(smf, asf, amc, wgt, &options, &animation, NULL, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "channels need more than the memory budget of 100000 bytes");
    /* Regression: the skinned frames ignored the caller's budget (they
     * used the 8 GiB default): 2000 frames x 3 vertices x 12 = 72,000
     * bytes pass the motion (fewer channels) but not 50,000 */
    write_text(asf, ":units\nangle deg\n:root\norder TX\naxis XYZ\nposition 0 0 0\norientation 0 0 0\n");
    t = (text){0};
    for (int f = 1; f <= 2000; f++) {
        char frame[64];
        snprintf(frame, sizeof frame, "%d\nroot 0\n", f);
        puts_text(&t, frame);
    }
    write_text(amc, t.data);
    free(t.data);
    write_text(wgt, "wgt 1\n1 root 1\n2 root 1\n3 root 1\n");
    options.max_bytes = 50000;
    assert_int_equal(lk_animation_read_acclaim(smf, asf, amc, wgt, &options, &animation, NULL, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "2000 frames of 3 vertices would need more than the memory budget of 50000");
    assert_null(animation.frame_positions);
    /* bone weights: 3 vertices with 2000 pairs each (12 bytes while read),
     * next to the 42 KB file */
    options.max_bytes = 110000;
    t = (text){0};
    puts_text(&t, "wgt 1\n");
    for (int v = 1; v <= 3; v++) {
        char head[16];
        snprintf(head, sizeof head, "%d", v);
        puts_text(&t, head);
        repeat(&t, " root 1", 2000);
        puts_text(&t, "\n");
    }
    write_text(wgt, t.data);
    free(t.data);
    write_text(amc, "1\nroot 0\n");
    assert_int_equal(lk_animation_read_acclaim(smf, asf, amc, wgt, &options, &animation, NULL, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error,
                               "hostile.wgt:4: the bone weights need more than the memory budget of 110000 bytes");
    /* the files themselves count: a 42 KB WGT under a 1 KB budget */
    options.max_bytes = 1024;
    assert_int_equal(lk_animation_read_acclaim(smf, asf, amc, wgt, &options, &animation, NULL, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "hostile.wgt: the file has");
    assert_rss_small();
}

/* ---- DEM: PGM, PNG, NPZ ---------------------------------------------------- */

static void expect_dem_refused(const void *bytes, size_t size, const char *name, lk_status status, const char *needle)
{
    void *copy = malloc(size);
    assert_non_null(copy);
    memcpy(copy, bytes, size);
    lk_heightfield field;
    lk_error error = {0};
    lk_status got = lk__dem_read_memory(copy, size, name, NULL, &field, &error);
    free(copy);
    if (got != status)
        fail_msg("%s: expected %s, got %s (\"%s\")", name, lk_status_string(status), lk_status_string(got),
                 error.message);
    lk_assert_message_contains(error, needle);
    assert_null(field.heights);
    assert_rss_small();
}

static void png_chunk(text *t, const char *type, const unsigned char *data, uint32_t length)
{
    unsigned char header[8];
    for (int i = 0; i < 4; i++) header[i] = (unsigned char)(length >> (24 - 8 * i));
    memcpy(header + 4, type, 4);
    put(t, header, 8);
    if (length) put(t, data, length);
    uLong crc = crc32(0L, Z_NULL, 0);
    crc = crc32(crc, (const Bytef *)type, 4);
    if (length) crc = crc32(crc, data, length);
    unsigned char tail[4];
    for (int i = 0; i < 4; i++) tail[i] = (unsigned char)(crc >> (24 - 8 * i));
    put(t, tail, 4);
}

static void test_dem_claims(void **state)
{
    (void)state;
    const char *p5 = "P5\n100000 100000\n255\n\x01\x02";
    expect_dem_refused(p5, strlen(p5), "big.pgm", LK_ERR_LIMIT, "big.pgm: 100000x100000 grid (10000000000 samples)");
    const char *p2 = "P2\n100000 100000\n255\n1 2 3\n";
    expect_dem_refused(p2, strlen(p2), "big.pgm", LK_ERR_LIMIT, "exceeds the budget of 67108864 samples");
    const char *wide = "P5 4294967295 2 65535\n";
    expect_dem_refused(wide, strlen(wide), "wide.pgm", LK_ERR_LIMIT, "4294967295x2 grid");
    const char *over = "P5 4294967296 2 255\n";
    expect_dem_refused(over, strlen(over), "over.pgm", LK_ERR_PARSE, "width too large");
    /* a PNG whose IHDR says 100000 x 100000 */
    text t = {0};
    put(&t, "\x89PNG\r\n\x1a\n", 8);
    unsigned char ihdr[13] = {0, 1, 0x86, 0xA0, 0, 1, 0x86, 0xA0, 16, 0, 0, 0, 0};
    png_chunk(&t, "IHDR", ihdr, 13);
    png_chunk(&t, "IDAT", NULL, 0);
    png_chunk(&t, "IEND", NULL, 0);
    expect_dem_refused(t.data, t.size, "big.png", LK_ERR_LIMIT, "big.png: 100000x100000 grid");
    free(t.data);
    /* an .npz whose member claims 4 GB inflated from 10 bytes, and one
     * claiming 2^32-1 bytes stored */
    for (int method = 0; method <= 8; method += 8) {
        memset(&t, 0, sizeof t);
        unsigned char local[30 + 14] = {0};
        put_u32(local, 0x04034b50u);
        memcpy(local + 30, "elevation.npy", 13);
        local[26] = 13;
        put(&t, local, 43);
        put(&t, "0123456789", 10);
        unsigned char central[46 + 13] = {0};
        put_u32(central, 0x02014b50u);
        central[10] = (unsigned char)method;
        put_u32(central + 20, 10);
        put_u32(central + 24, 0xFFFFFFFFu);
        central[28] = 13;
        put_u32(central + 42, 0);
        memcpy(central + 46, "elevation.npy", 13);
        size_t directory = t.size;
        put(&t, central, sizeof central);
        unsigned char end[22] = {0};
        put_u32(end, 0x06054b50u);
        end[10] = 1;
        put_u32(end + 12, sizeof central);
        put_u32(end + 16, (uint32_t)directory);
        put(&t, end, 22);
        expect_dem_refused(t.data, t.size, "claim.npz", LK_ERR_PARSE,
                           "member elevation.npy claims 4294967295 bytes from 10");
        free(t.data);
    }
}

/* ---- .lks streams ------------------------------------------------------------ */

/* A header (CRC included) and table for a stream of one base chunk of
 * chunk_size bytes, claiming the given counts. */
static void lks_header(unsigned char *out, uint32_t vertices, uint32_t strip, uint32_t chunk_count, uint64_t total_size)
{
    static const unsigned char magic[8] = {0x89, 'L', 'K', 'S', '\r', '\n', 0x1a, '\n'};
    memset(out, 0, 96);
    memcpy(out, magic, 8);
    out[8] = 1;
    put_u32(out + 12, 96 + 32 * chunk_count + 4);
    put_u64(out + 16, total_size);
    put_u32(out + 24, vertices);
    put_u32(out + 28, 1);
    put_u32(out + 32, vertices);
    put_u32(out + 36, 1);
    put_u32(out + 44, strip);
    put_u32(out + 48, chunk_count);
    put_u32(out + 52, 1024);
    out[56] = 8;
    float one = 1.0f;
    for (int axis = 0; axis < 3; axis++) memcpy(out + 72 + 4 * axis, &one, 4);
    put_u32(out + 92, (uint32_t)crc32(crc32(0L, Z_NULL, 0), out, 92));
}

static lk_status feed_stream(const unsigned char *bytes, size_t size, size_t max_bytes, lk_error *error)
{
    lk_stream_decoder *decoder = NULL;
    lk_error_clear(error);
    lk_status status = lk_stream_decoder_create(SIZE_MAX, &decoder, error);
    if (status == LK_OK && max_bytes) status = lk_stream_decoder_set_max_bytes(decoder, max_bytes, error);
    if (status == LK_OK) status = lk_stream_decoder_feed(decoder, bytes, size, error);
    if (status == LK_OK) status = lk_stream_decoder_finish(decoder, error);
    lk_stream_decoder_free(decoder);
    return status;
}

static void test_stream_claims(void **state)
{
    (void)state;
    lk_error error;
    unsigned char bytes[96 + 32 + 4];
    /* 4e9 vertices and a strip of 4e9 entries: 112 GB to decode */
    lks_header(bytes, 4000000000u, 4000000000u, 1, (uint64_t)1 << 40);
    assert_int_equal(feed_stream(bytes, 96, 0, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "header at byte 24: 4000000000 vertices and a strip of 4000000000 entries need");
    lk_assert_message_contains(error, "memory budget of 8589934592 bytes");
    /* 100 million chunks: a 3.2 GB table under a 1 GiB budget */
    lks_header(bytes, 3, 3, 100000000u, (uint64_t)1 << 40);
    assert_int_equal(feed_stream(bytes, 96, (size_t)1 << 30, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "header at byte 48: a table of 100000000 chunks needs 7200000000 bytes");
    /* one chunk of 2^32 - 16 bytes at a 4 GB offset claim: refused from
     * the table under 1 GiB, before a byte of it is buffered */
    uint32_t chunk_size = 0xFFFFFFF0u;
    lks_header(bytes, 3, 3, 1, 132 + (uint64_t)chunk_size);
    unsigned char *entry = bytes + 96;
    memset(entry, 0, 36);
    put_u64(entry, 132);
    put_u32(entry + 8, chunk_size);
    put_u32(entry + 12, chunk_size - 8);
    put_u32(entry + 24, 1);
    put_u32(entry + 32, (uint32_t)crc32(crc32(0L, Z_NULL, 0), entry, 32));
    assert_int_equal(feed_stream(bytes, sizeof bytes, (size_t)1 << 30, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "chunk table entry 0 at byte 104: a chunk of 4294967280 bytes");
    /* with the default budget the claim is accepted, nothing is allocated
     * for it, and the stream is reported cut short */
    assert_int_equal(feed_stream(bytes, sizeof bytes, 0, &error), LK_ERR_TRUNCATED);
    lk_assert_message_contains(error, "stopped at byte 132 in chunk 0 of 1");
    /* lk_stream_inspect on the same bytes: the chunk lies beyond the data */
    lk_stream_info info;
    lk_stream_chunk_info *chunks = NULL;
    assert_int_equal(lk_stream_inspect(bytes, sizeof bytes, &info, &chunks, &error), LK_ERR_TRUNCATED);
    lk_free(chunks);
    /* total size beyond 2^63 */
    lks_header(bytes, 3, 3, 1, UINT64_MAX);
    assert_int_equal(feed_stream(bytes, 96, 0, &error), LK_ERR_TRUNCATED);
    lk_assert_message_contains(error, "stopped at byte 96 in the chunk table");
    /* the budget must be set before feeding */
    lk_stream_decoder *decoder = NULL;
    assert_int_equal(lk_stream_decoder_create(SIZE_MAX, &decoder, &error), LK_OK);
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, 8, &error), LK_OK);
    assert_int_equal(lk_stream_decoder_set_max_bytes(decoder, 1024, &error), LK_ERR_INVALID);
    lk_stream_decoder_free(decoder);
    assert_rss_small();
}

/* ---- budgets leave real data alone ---------------------------------------- */

static void test_budgets_on_samples(void **state)
{
    (void)state;
    /* the bunny needs 34,835 x 12 + 69,666 x 12 bytes of arrays and its
     * file is 2.4 MB: 1 MiB refuses it (the file), 4 MiB reads it */
    lk_read_options options = {.max_bytes = 1 << 20};
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read(lk_test_sample("bunny.obj"), LK_FORMAT_AUTO, &options, &mesh, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error,
                               "bunny.obj: the file has 2397075 bytes, more than the memory budget of 1048576 bytes");
    options.max_bytes = 4 << 20;
    assert_int_equal(lk_mesh_read(lk_test_sample("bunny.obj"), LK_FORMAT_AUTO, &options, &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 34835);
    assert_int_equal(mesh.triangle_count, 69666);
    lk_mesh_free(&mesh);
    /* the cow (2904 vertices, 183 KB): fine at 1 MiB, not at 64 KiB */
    options.max_bytes = 1 << 20;
    assert_int_equal(lk_mesh_read(lk_test_sample("cow.off"), LK_FORMAT_AUTO, &options, &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 2904);
    lk_mesh_free(&mesh);
    options.max_bytes = 64 << 10;
    assert_int_equal(lk_mesh_read(lk_test_sample("cow.off"), LK_FORMAT_AUTO, &options, &mesh, &error), LK_ERR_LIMIT);
    /* the faerie (198 frames) reads under 16 MiB, not under 1 MiB */
    lk_animation animation;
    lk_animation_read_options anim_options;
    memset(&anim_options, 0, sizeof anim_options);
    anim_options.max_bytes = 16 << 20;
    assert_int_equal(lk_animation_read_ex(lk_test_sample("faerie.md2"), &anim_options, &animation, NULL, &error),
                     LK_OK);
    assert_int_equal(animation.frame_count, 198);
    size_t vertices = animation.mesh.vertex_count;
    lk_animation_free(&animation);
    anim_options.max_bytes = 1 << 20;
    assert_int_equal(lk_animation_read_ex(lk_test_sample("faerie.md2"), &anim_options, &animation, NULL, &error),
                     LK_ERR_LIMIT);
    lk_assert_message_contains(error, "memory budget");
    assert_true(vertices * 198 * 12 > (1u << 20));
    /* a real stream decodes under a budget that holds it, not under 16 KiB */
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    lk_progressive_options pm_options;
    lk_progressive_options_default(&pm_options);
    lk_progressive_mesh pm;
    lk_progressive_strips ps;
    assert_int_equal(lk_progressive_mesh_build(&cow, &pm_options, &pm, NULL, NULL, &error), LK_OK);
    assert_int_equal(lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &ps, &error), LK_OK);
    unsigned char *bytes = NULL;
    size_t size = 0;
    assert_int_equal(lk_stream_encode(&pm, &ps, NULL, &bytes, &size, &error), LK_OK);
    assert_int_equal(feed_stream(bytes, size, 1 << 20, &error), LK_OK);
    assert_int_equal(feed_stream(bytes, size, 16 << 10, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "header at byte 24: 2904 vertices");
    lk_free(bytes);
    lk_progressive_strips_free(&ps);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&cow);
}

int main(void)
{
    start_rss_kb = peak_rss_kb();
    const struct CMUnitTest tests[] = {
        /* first: its resident-memory check needs a low peak so far */
        cmocka_unit_test(test_read_holds_everything),
        cmocka_unit_test(test_ply_claims),
        cmocka_unit_test(test_off_claims_and_fans),
        cmocka_unit_test(test_obj_amplification),
        cmocka_unit_test(test_smf_stl_xyz),
        cmocka_unit_test(test_gltf_accessor_claims),
        cmocka_unit_test(test_glb_chunks),
        cmocka_unit_test(test_gltf_deep_json),
        cmocka_unit_test(test_gltf_enormous_json),
        cmocka_unit_test(test_gltf_animation_claims),
        cmocka_unit_test(test_kmf_claims),
        cmocka_unit_test(test_md2_claims),
        cmocka_unit_test(test_acclaim_budget),
        cmocka_unit_test(test_dem_claims),
        cmocka_unit_test(test_stream_claims),
        cmocka_unit_test(test_budgets_on_samples),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
