/* SPDX-License-Identifier: MIT */
/* Text formats: OBJ, OFF, SMF and XYZ readers and writers. */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "testutil.h"

/* Reads `text` from a heap copy of exactly strlen(text) bytes, so that
 * AddressSanitizer catches any read past the end (readers must not rely on
 * a terminating NUL). */
static lk_status read_text(const char *text, const char *name, lk_mesh *mesh, lk_error *error)
{
    size_t size = strlen(text);
    char *copy = malloc(size ? size : 1);
    assert_non_null(copy);
    memcpy(copy, text, size);
    lk_error_clear(error);
    lk_mesh_init(mesh);
    lk_status status = lk_mesh_read_memory(copy, size, name, LK_FORMAT_AUTO, NULL, mesh, error);
    free(copy);
    return status;
}

/* Reads text that must load; fails the test with the message otherwise. */
static void load_text(const char *text, const char *name, lk_mesh *mesh)
{
    lk_error error;
    if (read_text(text, name, mesh, &error) != LK_OK) fail_msg("%s failed to load: %s", name, error.message);
}

/* Reads text that must fail with `status` and a message containing `needle`. */
static void expect_failure(const char *text, const char *name, lk_status status, const char *needle)
{
    lk_mesh mesh;
    lk_error error;
    lk_status got = read_text(text, name, &mesh, &error);
    if (got != status)
        fail_msg("%s: expected status %s, got %s (\"%s\") for input:\n%s", name, lk_status_string(status),
                 lk_status_string(got), error.message, text);
    lk_assert_message_contains(error, needle);
    assert_int_equal(mesh.vertex_count, 0);
    assert_null(mesh.positions);
}

static void assert_floats(const float *actual, const float *expected, size_t count)
{
    for (size_t i = 0; i < count; i++)
        if (actual[i] != expected[i]) fail_msg("value %zu: got %.9g, expected %.9g", i, actual[i], expected[i]);
}

static void assert_indices(const lk_mesh *mesh, const uint32_t *expected, size_t triangle_count)
{
    assert_int_equal(mesh->triangle_count, triangle_count);
    for (size_t i = 0; i < 3 * triangle_count; i++)
        if (mesh->indices[i] != expected[i])
            fail_msg("index %zu: got %u, expected %u", i, mesh->indices[i], expected[i]);
}

/* ---- real models ------------------------------------------------------- */

static void test_obj_bunny(void **state)
{
    (void)state;
    lk_mesh mesh;
    const char *path = lk_test_sample("bunny.obj");
    double best = INFINITY;
    for (int run = 0; run < 5; run++) {
        struct timespec start, stop;
        clock_gettime(CLOCK_MONOTONIC, &start);
        lk_test_load(path, &mesh);
        clock_gettime(CLOCK_MONOTONIC, &stop);
        double seconds = (double)(stop.tv_sec - start.tv_sec) + (double)(stop.tv_nsec - start.tv_nsec) * 1e-9;
        if (seconds < best) best = seconds;
        if (run < 4) lk_mesh_free(&mesh);
    }
    print_message("bunny.obj: lk_mesh_read best of 5: %.1f ms\n", best * 1e3);
    assert_int_equal(mesh.vertex_count, 34835);
    assert_int_equal(mesh.triangle_count, 69666);
    assert_null(mesh.normals);
    assert_null(mesh.texcoords);
    assert_null(mesh.colors);
    const float first[3] = {0.296502f, -0.907931f, 0.450151f};
    assert_floats(mesh.positions, first, 3);
    const uint32_t first_triangles[6] = {0, 1, 2, 3, 4, 5};
    assert_int_equal(mesh.indices[0], first_triangles[0]);
    assert_int_equal(mesh.indices[5], first_triangles[5]);
    lk_mesh_free(&mesh);
}

static void test_off_samples(void **state)
{
    (void)state;
    static const struct {
        const char *name;
        size_t vertex_count, triangle_count;
    } samples[] = {
        {"cow.off", 2904, 5804},
        {"fandisk.off", 6475, 12946},
        {"triceratops.off", 2832, 5660},
        {"ChineseDragon-10kv.off", 10000, 19994},
        {"assimp/OFF/Cube.off", 8, 12}, /* six quads */
        {"assimp/OFF/Wuson.off", 3205, 3732},
    };
    for (size_t i = 0; i < sizeof samples / sizeof samples[0]; i++) {
        lk_mesh mesh;
        lk_test_load(lk_test_sample(samples[i].name), &mesh);
        if (mesh.vertex_count != samples[i].vertex_count || mesh.triangle_count != samples[i].triangle_count)
            fail_msg("%s: %zu vertices %zu triangles, expected %zu and %zu", samples[i].name, mesh.vertex_count,
                     mesh.triangle_count, samples[i].vertex_count, samples[i].triangle_count);
        assert_null(mesh.colors);
        lk_mesh_free(&mesh);
    }
    /* Exact values from the files' first lines. */
    lk_mesh mesh;
    lk_test_load(lk_test_sample("cow.off"), &mesh);
    const float cow_first[3] = {0.281526f, 0.266379f, -1.55991e-008f};
    assert_floats(mesh.positions, cow_first, 3);
    lk_mesh_free(&mesh);
    lk_test_load(lk_test_sample("assimp/OFF/Cube.off"), &mesh);
    const uint32_t cube_fan[6] = {0, 1, 3, 0, 3, 2}; /* "4 0 1 3 2" */
    assert_memory_equal(mesh.indices, cube_fan, sizeof cube_fan);
    lk_mesh_free(&mesh);

    lk_error error = {0};
    const char *invalid = lk_test_sample("assimp/OFF/invalid.off");
    assert_int_not_equal(lk_mesh_read(invalid, LK_FORMAT_AUTO, NULL, &mesh, &error), LK_OK);
    lk_assert_message_contains(error, "invalid.off:");
    assert_null(mesh.positions);
}

static void test_xyz_kitten(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("kitten.xyz"), &mesh);
    assert_int_equal(mesh.vertex_count, 5210);
    assert_int_equal(mesh.triangle_count, 0);
    assert_non_null(mesh.normals);
    const float first[3] = {-0.0721898f, -0.159749f, -0.108444f};
    const float first_normal[3] = {0.340472f, 0.937712f, -0.0690972f};
    assert_floats(mesh.positions, first, 3);
    assert_floats(mesh.normals, first_normal, 3);
    lk_mesh_free(&mesh);
}

/* Every Assimp OBJ test file loads or is refused with a message that names
 * the file. */
static void test_obj_assimp_files(void **state)
{
    (void)state;
    char directory[4096];
    snprintf(directory, sizeof directory, "%s", lk_test_sample("assimp/OBJ"));
    DIR *dir = opendir(directory);
    assert_non_null(dir);
    int loaded = 0, refused = 0;
    struct dirent *entry;
    while ((entry = readdir(dir)) != NULL) {
        size_t length = strlen(entry->d_name);
        if (length < 4 || strcmp(entry->d_name + length - 4, ".obj") != 0) continue;
        char path[8192];
        snprintf(path, sizeof path, "%s/%s", directory, entry->d_name);
        lk_mesh mesh;
        lk_error error = {0};
        if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &mesh, &error) == LK_OK) {
            if (mesh.vertex_count == 0) fail_msg("%s loaded with no vertices", entry->d_name);
            loaded++;
        } else {
            if (!error.message[0] || !strstr(error.message, entry->d_name))
                fail_msg("%s refused without naming the file: \"%s\"", entry->d_name, error.message);
            refused++;
        }
        lk_mesh_free(&mesh);
    }
    closedir(dir);
    print_message("assimp/OBJ: %d loaded, %d refused\n", loaded, refused);
    assert_int_equal(loaded + refused, 22);
    assert_int_equal(refused, 1); /* only box_UTF16BE.obj */

    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read(lk_test_sample("assimp/OBJ/box_UTF16BE.obj"), LK_FORMAT_AUTO, NULL, &mesh, &error),
                     LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "UTF-16");

    static const struct {
        const char *name;
        size_t vertex_count, triangle_count;
    } expected[] = {
        {"assimp/OBJ/box.obj", 8, 12},
        {"assimp/OBJ/box_without_lineending.obj", 8, 12},
        {"assimp/OBJ/multiple_spaces.obj", 4, 1},
        {"assimp/OBJ/number_formats.obj", 15, 1},
        {"assimp/OBJ/testpoints.obj", 8, 0}, /* p statements are skipped */
        {"assimp/OBJ/testline.obj", 8, 0},   /* l statements are skipped */
        {"assimp/OBJ/testmixed.obj", 8, 12},
        {"assimp/OBJ/point_cloud.obj", 3, 0},
        {"assimp/OBJ/regr_3429812.obj", 4, 4},
        /* 8 positions with a different normal per face: each corner of the
         * cube is used with three normals, so 16 extra vertices. */
        {"assimp/OBJ/cube_with_vertexcolors.obj", 24, 12},
        {"assimp/OBJ/WusonOBJ.obj", 2117, 3732},
    };
    for (size_t i = 0; i < sizeof expected / sizeof expected[0]; i++) {
        lk_test_load(lk_test_sample(expected[i].name), &mesh);
        if (mesh.vertex_count != expected[i].vertex_count || mesh.triangle_count != expected[i].triangle_count)
            fail_msg("%s: %zu vertices %zu triangles, expected %zu and %zu", expected[i].name, mesh.vertex_count,
                     mesh.triangle_count, expected[i].vertex_count, expected[i].triangle_count);
        lk_mesh_free(&mesh);
    }

    /* number_formats.obj: "v 1e2 2.e1 3.1e2" and "v 1e+2 2.e+1 3.1+e2". */
    lk_test_load(lk_test_sample("assimp/OBJ/number_formats.obj"), &mesh);
    const float exponent[3] = {100.0f, 20.0f, 310.0f};
    const float odd_token[3] = {100.0f, 20.0f, 3.1f};
    assert_floats(mesh.positions + 3 * 4, exponent, 3);
    assert_floats(mesh.positions + 3 * 7, odd_token, 3);
    lk_mesh_free(&mesh);

    /* MeshLab point cloud: vn and v lines pair up into point normals. */
    lk_test_load(lk_test_sample("assimp/OBJ/point_cloud.obj"), &mesh);
    assert_non_null(mesh.normals);
    const float normal[3] = {-0.281034f, -0.057252f, 0.957989f};
    assert_floats(mesh.normals, normal, 3);
    lk_mesh_free(&mesh);

    /* Vertex colours "v x y z r g b" with alpha 1. */
    lk_test_load(lk_test_sample("assimp/OBJ/cube_with_vertexcolors.obj"), &mesh);
    assert_non_null(mesh.colors);
    assert_non_null(mesh.normals);
    const float color[4] = {0.48627f, 0.43137f, 0.47059f, 1.0f};
    assert_floats(mesh.colors, color, 4);
    lk_mesh_free(&mesh);
}

/* ---- OBJ specifics ----------------------------------------------------- */

static void test_obj_polygons_and_relative_indices(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_data("text/quad.obj"), &mesh);
    assert_int_equal(mesh.vertex_count, 4);
    const float positions[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    assert_floats(mesh.positions, positions, 12);
    const uint32_t fan[6] = {0, 1, 2, 0, 2, 3};
    assert_indices(&mesh, fan, 2);
    assert_non_null(mesh.normals);
    assert_null(mesh.texcoords);
    for (size_t i = 0; i < 4; i++) assert_true(mesh.normals[3 * i + 2] == 1.0f);
    lk_mesh_free(&mesh);

    /* A pentagon becomes 3 triangles around its first corner; faces may
     * refer to vertices defined later in the file. */
    load_text("f 1 2 3 4 5\nv 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\n", "pentagon.obj", &mesh);
    const uint32_t pentagon[9] = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    assert_indices(&mesh, pentagon, 3);
    lk_mesh_free(&mesh);

    /* Only v lines: a point set. */
    load_text("v 1 2 3\nv 4 5 6 1.0\n", "points.obj", &mesh);
    assert_int_equal(mesh.vertex_count, 2);
    assert_int_equal(mesh.triangle_count, 0);
    lk_mesh_free(&mesh);
}

static void test_obj_attribute_splitting(void **state)
{
    (void)state;
    lk_mesh mesh;
    /* Position 1 is used with two different (vt, vn) pairs, position 4 is
     * never used, position 3 is used with vt only. */
    const char *text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\n"
                       "vt 0.25 0.5\nvt 0.75 1\n"
                       "vn 0 0 1\nvn 0 0 -1\n"
                       "f 1/1/1 2/1/1 3/2\n"
                       "f 1/2/2 3/2 2/1/1\n"
                       "f 1/2/2 2/1/1 3/2\n";
    load_text(text, "split.obj", &mesh);
    assert_int_equal(mesh.vertex_count, 5); /* 4 positions + 1 copy of position 1 */
    const uint32_t indices[9] = {0, 1, 2, 4, 2, 1, 4, 1, 2};
    assert_indices(&mesh, indices, 3);
    const float copy[3] = {0, 0, 0};
    assert_floats(mesh.positions + 3 * 4, copy, 3);
    const float texcoords[10] = {0.25f, 0.5f, 0.25f, 0.5f, 0.75f, 1, 0, 0, 0.75f, 1};
    assert_floats(mesh.texcoords, texcoords, 10);
    const float normals[15] = {0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, -1};
    assert_floats(mesh.normals, normals, 15);
    lk_mesh_free(&mesh);

    /* Same pair everywhere: no splitting, vertex count == v count. */
    load_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n", "shared.obj", &mesh);
    assert_int_equal(mesh.vertex_count, 3);
    assert_null(mesh.texcoords);
    lk_mesh_free(&mesh);
}

static void test_obj_errors(void **state)
{
    (void)state;
    const char *triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    char text[256];
    expect_failure("v 1 2\n", "bad.obj", LK_ERR_PARSE, "bad.obj:1: expected 3 coordinates after 'v', got 2");
    expect_failure("# x\nv 1 2 abc\n", "bad.obj", LK_ERR_PARSE, "bad.obj:2: expected 3 coordinates");
    /* A word after the coordinates is refused as on 'f' lines (issue 17); a
     * comment, w, or r g b colours are not. */
    expect_failure("v 0 0 0 junk\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "bad.obj", LK_ERR_PARSE,
                   "bad.obj:1: unexpected 'junk' after the 3 numbers of 'v'");
    expect_failure("v 0 0 0 0.1 0.2 0.3 1 9\n", "bad.obj", LK_ERR_PARSE,
                   "bad.obj:1: unexpected '9' after the 7 numbers of 'v'");
    {
        lk_mesh mesh;
        const char *fine = "v 0 0 0 # origin\nv 1 0 0 1\nv 0 1 0 0.2 0.4 0.6\nf 1 2 3\n";
        assert_int_equal(lk_mesh_read_memory(fine, strlen(fine), "fine.obj", LK_FORMAT_OBJ, NULL, &mesh, NULL), LK_OK);
        assert_int_equal(mesh.vertex_count, 3);
        lk_mesh_free(&mesh);
    }
    snprintf(text, sizeof text, "%sf 1 2\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_PARSE, "bad.obj:4: expected at least 3 vertex indices after 'f', got 2");
    snprintf(text, sizeof text, "%s\nf 1 2 7\nf 1 2 3\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_RANGE, "bad.obj:5: vertex index 7 out of range (the file defines 3");
    snprintf(text, sizeof text, "%sf 0 1 2\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_RANGE, "bad.obj:4: vertex index 0 is invalid");
    snprintf(text, sizeof text, "%sf -1 -2 -4\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_RANGE,
                   "bad.obj:4: vertex index -4 out of range (3 vertices defined so far)");
    snprintf(text, sizeof text, "%svt 0 0\nf 1/1 2/1 3/2\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_RANGE, "bad.obj:5: texture coordinate index 2 out of range");
    snprintf(text, sizeof text, "%sf 1//1 2//1 3//1\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_RANGE, "bad.obj:4: normal index 1 out of range");
    snprintf(text, sizeof text, "%sf 1/x 2 3\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_PARSE,
                   "bad.obj:4: expected a face corner like 1, 1/2, 1//3 or 1/2/3, got '1/x'");
    snprintf(text, sizeof text, "%sf 1 2 3.5\n", triangle);
    expect_failure(text, "bad.obj", LK_ERR_PARSE, "bad.obj:4: expected a face corner");
    expect_failure("v 0 0 0\nv nan 0 0\n", "bad.obj", LK_ERR_RANGE, "bad.obj:2: coordinate nan is not a finite float");
    expect_failure("v 0 0 1e39\n", "bad.obj", LK_ERR_RANGE, "bad.obj:1: coordinate 1e+39 is not a finite float");
    expect_failure("v 0 0 0\nvn 0 1\n", "bad.obj", LK_ERR_PARSE, "bad.obj:2: expected 3 numbers after 'vn', got 2");
    expect_failure("v 0 0 0\nvn 0 inf 0\n", "bad.obj", LK_ERR_RANGE, "bad.obj:2: normal component inf");
    expect_failure("vt\n", "bad.obj", LK_ERR_PARSE, "bad.obj:1: expected texture coordinates");
    expect_failure("# just a comment\no nothing\n", "bad.obj", LK_ERR_PARSE, "bad.obj: no vertices");
    expect_failure("\xFF\xFEv\0 \0", "le.obj", LK_ERR_UNSUPPORTED, "le.obj: file is UTF-16 encoded");

    lk_mesh mesh;
    lk_error error = {0};
    static const char with_nul[] = "v 0 0 0\n\0v 1 1 1\n";
    assert_int_equal(lk_mesh_read_memory(with_nul, sizeof with_nul - 1, "nul.obj", LK_FORMAT_AUTO, NULL, &mesh, &error),
                     LK_ERR_PARSE);
    lk_assert_message_contains(error, "nul.obj: byte 8: NUL byte");

    /* The memory budget is enforced. */
    lk_read_options tiny = {.max_bytes = 64};
    error.message[0] = '\0';
    assert_int_equal(lk_mesh_read(lk_test_sample("bunny.obj"), LK_FORMAT_AUTO, &tiny, &mesh, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "memory budget");
}

/* ---- OFF specifics ----------------------------------------------------- */

static void test_off_variants(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_data("text/colored.off"), &mesh);
    assert_int_equal(mesh.vertex_count, 4);
    const uint32_t indices[6] = {0, 1, 2, 0, 2, 3};
    assert_indices(&mesh, indices, 2);
    assert_non_null(mesh.normals);
    assert_non_null(mesh.colors);
    assert_null(mesh.texcoords);
    const float colors[16] = {1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1, (float)(128 / 255.0), 1, 1, 1, 1};
    assert_floats(mesh.colors, colors, 16);
    const float normal[3] = {0, 0, 1};
    assert_floats(mesh.normals + 9, normal, 3);
    lk_mesh_free(&mesh);

    /* Counts on the header line, float colours with 3 components, a face
     * colour after the indices. */
    load_text("COFF 3 1 0\n0 0 0 0.5 0.25 1\n1 0 0 1.0 1 1\n0 1 0 0 0 0\n3 0 1 2 255 0 0\n", "c.off", &mesh);
    const float float_colors[12] = {0.5f, 0.25f, 1, 1, 1, 1, 1, 1, 0, 0, 0, 1};
    assert_floats(mesh.colors, float_colors, 12);
    assert_int_equal(mesh.triangle_count, 1);
    lk_mesh_free(&mesh);

    /* STOFF: texture coordinates after xyz; STCOFF: colour then st. */
    load_text("STOFF\n3 1 0\n0 0 0 0.5 0.75\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n", "st.off", &mesh);
    const float texcoords[6] = {0.5f, 0.75f, 1, 0, 0, 1};
    assert_floats(mesh.texcoords, texcoords, 6);
    lk_mesh_free(&mesh);
    load_text("STCOFF\n3 1\n0 0 0 1 0 0 0.5 0.75\n1 0 0 0 1 0 0.5 1 0\n0 1 0 0 0 1 0 1\n3 0 1 2\n", "stc.off", &mesh);
    const float stc_texcoords[6] = {0.5f, 0.75f, 1, 0, 0, 1};
    const float one = (float)(1 / 255.0);
    const float stc_colors[12] = {one, 0, 0, 1, 0, 1, 0, 0.5f, 0, 0, one, 1};
    assert_floats(mesh.texcoords, stc_texcoords, 6);
    assert_floats(mesh.colors, stc_colors, 12);
    lk_mesh_free(&mesh);

    /* A header with no faces is a point set. */
    load_text("OFF\n2 0 0\n0 0 0\n1 1 1\n", "points.off", &mesh);
    assert_int_equal(mesh.vertex_count, 2);
    assert_int_equal(mesh.triangle_count, 0);
    lk_mesh_free(&mesh);
}

static void test_off_errors(void **state)
{
    (void)state;
    expect_failure("3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "bad.off", LK_ERR_PARSE, "bad.off:1: missing OFF header");
    expect_failure("4OFF\n1 0 0\n0 0 0 0\n", "bad.off", LK_ERR_UNSUPPORTED, "bad.off:1: '4OFF'");
    expect_failure("OFF BINARY\n", "bad.off", LK_ERR_UNSUPPORTED, "bad.off:1: binary OFF");
    expect_failure("OFF\n# nothing else\n", "bad.off", LK_ERR_PARSE, "bad.off:2: file ends before the counts");
    expect_failure("OFF\n3 x\n", "bad.off", LK_ERR_PARSE, "bad.off:2: expected the counts");
    expect_failure("OFF\n-3 1 0\n", "bad.off", LK_ERR_PARSE, "bad.off:2: negative count");
    /* Truncated, with enough comment bytes to pass the size plausibility check. */
    expect_failure("OFF\n4 1 0\n# padding padding padding padding padding\n0 0 0\n1 0 0\n", "bad.off", LK_ERR_PARSE,
                   "bad.off:5: expected 4 vertices, file ends after 2");
    expect_failure("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n# padding padding\n", "bad.off", LK_ERR_PARSE,
                   "bad.off:7: expected 2 faces, file ends after 1");
    expect_failure("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "bad.off", LK_ERR_RANGE,
                   "bad.off:6: vertex index 3 out of range (3 vertices)");
    expect_failure("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", "bad.off", LK_ERR_RANGE,
                   "bad.off:6: vertex index -1 out of range");
    expect_failure("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1    \n", "bad.off", LK_ERR_PARSE,
                   "bad.off:6: face has 2 vertices, expected at least 3");
    expect_failure("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2  \n", "bad.off", LK_ERR_PARSE,
                   "bad.off:6: expected 4 vertex indices, got 3");
    expect_failure("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n", "bad.off", LK_ERR_PARSE,
                   "bad.off:6: vertex index '1.5' is not an integer");
    expect_failure("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n# padding\n", "bad.off", LK_ERR_PARSE,
                   "bad.off:4: vertex 1: expected x y z, got 2 numbers");
    expect_failure("OFF\n3 1 0\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", "bad.off", LK_ERR_RANGE,
                   "bad.off:4: vertex 1: nan is not a finite float");
    expect_failure("COFF\n3 1 0\n0 0 0 1 1\n1 0 0 1 1 1\n0 1 0 1 1 1\n3 0 1 2\n", "bad.off", LK_ERR_PARSE,
                   "bad.off:3: vertex 0: expected x y z r g b [a], got 5 numbers");
    /* Absurd counts are refused before anything is allocated. */
    expect_failure("OFF\n1099511627776 1 0\n0 0 0\n", "huge.off", LK_ERR_LIMIT, "huge.off:2: 1099511627776 vertices");
    expect_failure("OFF\n1 1099511627776 0\n0 0 0\n", "huge.off", LK_ERR_LIMIT, "huge.off:2: 1099511627776 faces");
    expect_failure("OFF\n1000000 1 0\n0 0 0\n", "huge.off", LK_ERR_LIMIT, "header claims 1000000 vertices but only");
    expect_failure("OFF 3 1000000000\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "bad.off", LK_ERR_LIMIT, "truncated");
}

/* A file cut short in the middle of its face lines. */
static void test_off_truncated_sample(void **state)
{
    (void)state;
    FILE *file = fopen(lk_test_sample("cow.off"), "rb");
    assert_non_null(file);
    static char data[1 << 20];
    size_t size = fread(data, 1, sizeof data, file);
    fclose(file);
    assert_true(size > 100000);
    size_t cut = size * 6 / 10;
    while (data[cut - 1] != '\n') cut--; /* cut after a whole face line */
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read_memory(data, cut, "cow.off", LK_FORMAT_AUTO, NULL, &mesh, &error), LK_ERR_PARSE);
    lk_assert_message_contains(error, "expected 5804 faces, file ends after");
    assert_true(strncmp(error.message, "cow.off:", 8) == 0);
    /* Cut in the middle of a line, before its last index. */
    size_t last_space = cut - 2;
    while (data[last_space] != ' ') last_space--;
    assert_int_equal(lk_mesh_read_memory(data, last_space, "cow.off", LK_FORMAT_AUTO, NULL, &mesh, &error),
                     LK_ERR_PARSE);
    lk_assert_message_contains(error, "expected 3 vertex indices, got 2");
    /* Cut in the vertex lines: too few bytes for the header's claims. */
    assert_int_equal(lk_mesh_read_memory(data, 3000, "cow.off", LK_FORMAT_AUTO, NULL, &mesh, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "cow.off:2: header claims 2904 vertices");
}

/* ---- SMF and XYZ ------------------------------------------------------- */

static void test_smf(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_data("text/bound.smf"), &mesh);
    assert_int_equal(mesh.vertex_count, 4);
    const uint32_t fan[6] = {0, 1, 2, 0, 2, 3};
    assert_indices(&mesh, fan, 2);
    assert_non_null(mesh.normals);
    assert_non_null(mesh.colors);
    assert_null(mesh.texcoords); /* bound per face: ignored */
    const float colors[16] = {1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1, 1, 1, 1, 1, 1};
    assert_floats(mesh.colors, colors, 16);
    lk_mesh_free(&mesh);

    load_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1 # relative\n", "rel.smf", &mesh);
    const uint32_t triangle[3] = {0, 1, 2};
    assert_indices(&mesh, triangle, 1);
    lk_mesh_free(&mesh);

    expect_failure("v 0 0 0\nv 1 0 0\nv 0 1 0\nquad 1 2 3\n", "bad.smf", LK_ERR_PARSE,
                   "bad.smf:4: unknown SMF statement 'quad'");
    expect_failure("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "bad.smf", LK_ERR_RANGE,
                   "bad.smf:4: vertex index 4 out of range");
    expect_failure("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "bad.smf", LK_ERR_PARSE, "bad.smf:4: expected at least 3");
    expect_failure("v 0 0\n", "bad.smf", LK_ERR_PARSE, "bad.smf:1: expected 3 numbers after 'v', got 2");
    expect_failure("v 0 0 0 0\n", "bad.smf", LK_ERR_PARSE, "bad.smf:1: expected 3 numbers after 'v', got more");
    expect_failure("v 0 0 0\nv inf 0 0\n", "bad.smf", LK_ERR_RANGE, "bad.smf:2: 'v' value inf");
    expect_failure("v 0 0 0\nv 1 0 0\nn 0 0 1\n", "bad.smf", LK_ERR_RANGE, "bad.smf:3: 1 normals for 2 vertices");
    expect_failure("v 0 0 0\nbind n everywhere\n", "bad.smf", LK_ERR_PARSE, "bad.smf:2: expected 'bind n|c|r");
    expect_failure("# empty\n", "bad.smf", LK_ERR_PARSE, "bad.smf: no vertices");
}

static void test_xyz(void **state)
{
    (void)state;
    lk_mesh mesh;
    load_text("# points\n1 2 3\n\n4 5 6 # second\n", "a.xyz", &mesh);
    assert_int_equal(mesh.vertex_count, 2);
    assert_null(mesh.normals);
    const float positions[6] = {1, 2, 3, 4, 5, 6};
    assert_floats(mesh.positions, positions, 6);
    lk_mesh_free(&mesh);

    expect_failure("1 2 3 0 0 1\n4 5 6 0 1\n", "bad.xyz", LK_ERR_PARSE,
                   "bad.xyz:2: expected 6 numbers like line 1, got 5");
    expect_failure("\n1 2 3 4\n", "bad.xyz", LK_ERR_PARSE, "bad.xyz:2: expected 3 or 6 numbers per line");
    expect_failure("1 2 3\n1 2 x\n", "bad.xyz", LK_ERR_PARSE, "bad.xyz:2: expected a number, got 'x'");
    expect_failure("1 2 3\n1 nan 3\n", "bad.xyz", LK_ERR_RANGE, "bad.xyz:2: nan is not a finite float");
    expect_failure("# nothing\n\n", "bad.xyz", LK_ERR_PARSE, "bad.xyz: no points");
}

static void test_empty_input(void **state)
{
    (void)state;
    static const char *const names[] = {"e.obj", "e.off", "e.smf", "e.xyz"};
    for (size_t i = 0; i < 4; i++) {
        expect_failure("", names[i], LK_ERR_PARSE, names[i]);
        lk_mesh mesh;
        lk_error error;
        /* Blank content is not a model either. */
        assert_int_equal(read_text("  \n\n", names[i], &mesh, &error), LK_ERR_PARSE);
        lk_assert_message_contains(error, names[i]);
    }
}

/* ---- writers ----------------------------------------------------------- */

/* A mesh whose floats need all 9 significant digits, with every attribute. */
static void make_awkward_mesh(lk_mesh *mesh)
{
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(mesh, 5, 3, LK_ATTR_NORMALS | LK_ATTR_TEXCOORDS | LK_ATTR_COLORS, &error), LK_OK);
    const float special[] = {0.1f,        -1.0f / 3.0f, 3.14159274f, 1e-7f, -3.40282347e38f, 1.17549435e-38f,
                             1e-45f,      123456789.0f, 0.0f,        -0.0f, 16777217.0f,     2.5f,
                             7.0f / 9.0f, 1e30f,        -2e-30f};
    for (size_t i = 0; i < 15; i++) mesh->positions[i] = special[i];
    for (size_t i = 0; i < 15; i++) mesh->normals[i] = special[(i + 3) % 15] / 4;
    for (size_t i = 0; i < 10; i++) mesh->texcoords[i] = special[(i + 7) % 15];
    for (size_t i = 0; i < 20; i++) mesh->colors[i] = (float)(i % 4 == 3 ? 1.0 : (double)i / 19.0);
    const uint32_t indices[9] = {0, 1, 2, 2, 1, 3, 4, 3, 1};
    memcpy(mesh->indices, indices, sizeof indices);
}

static void write_and_read(const lk_mesh *mesh, const char *file_name, const lk_write_options *options, lk_mesh *out)
{
    lk_error error = {0};
    const char *path = lk_test_tmpfile(file_name);
    if (lk_mesh_write(path, LK_FORMAT_AUTO, mesh, options, &error) != LK_OK)
        fail_msg("writing %s: %s", file_name, error.message);
    lk_test_load(path, out);
}

static void assert_same_floats(const float *a, const float *b, size_t count, const char *what)
{
    assert_non_null(a);
    assert_non_null(b);
    if (memcmp(a, b, count * sizeof(float)) != 0) {
        for (size_t i = 0; i < count; i++)
            if (memcmp(&a[i], &b[i], sizeof(float)) != 0)
                fail_msg("%s %zu: wrote %.9g, read %.9g", what, i, a[i], b[i]);
    }
}

static void test_round_trips(void **state)
{
    (void)state;
    lk_mesh mesh, back;
    make_awkward_mesh(&mesh);

    write_and_read(&mesh, "round.obj", NULL, &back);
    assert_int_equal(back.vertex_count, 5);
    assert_indices(&back, mesh.indices, 3);
    assert_same_floats(mesh.positions, back.positions, 15, "obj position");
    assert_same_floats(mesh.normals, back.normals, 15, "obj normal");
    assert_same_floats(mesh.texcoords, back.texcoords, 10, "obj texcoord");
    assert_same_floats(mesh.colors, back.colors, 20, "obj colour"); /* alpha is 1 */
    lk_mesh_free(&back);

    lk_write_options skip = {0};
    skip.skip_normals = skip.skip_texcoords = skip.skip_colors = 1;
    write_and_read(&mesh, "skip.obj", &skip, &back);
    assert_null(back.normals);
    assert_null(back.texcoords);
    assert_null(back.colors);
    assert_same_floats(mesh.positions, back.positions, 15, "obj position");
    lk_mesh_free(&back);
    skip.skip_texcoords = 0;
    write_and_read(&mesh, "uv.obj", &skip, &back);
    assert_null(back.normals);
    assert_same_floats(mesh.texcoords, back.texcoords, 10, "obj texcoord");
    lk_mesh_free(&back);

    mesh.colors[7] = 0.5f; /* a non-opaque alpha: COFF stores r g b a */
    write_and_read(&mesh, "round.off", NULL, &back);
    assert_indices(&back, mesh.indices, 3);
    assert_same_floats(mesh.positions, back.positions, 15, "off position");
    assert_same_floats(mesh.colors, back.colors, 20, "off colour");
    assert_null(back.normals);
    lk_mesh_free(&back);
    write_and_read(&mesh, "plain.off", &skip, &back);
    assert_null(back.colors);
    lk_mesh_free(&back);

    write_and_read(&mesh, "round.smf", NULL, &back);
    assert_indices(&back, mesh.indices, 3);
    assert_same_floats(mesh.positions, back.positions, 15, "smf position");
    assert_null(back.normals);
    lk_mesh_free(&back);

    write_and_read(&mesh, "round.xyz", NULL, &back);
    assert_int_equal(back.vertex_count, 5);
    assert_int_equal(back.triangle_count, 0);
    assert_same_floats(mesh.positions, back.positions, 15, "xyz position");
    assert_same_floats(mesh.normals, back.normals, 15, "xyz normal");
    lk_mesh_free(&back);
    write_and_read(&mesh, "bare.xyz", &skip, &back);
    assert_null(back.normals);
    lk_mesh_free(&back);
    lk_mesh_free(&mesh);

    /* A real model through every format. */
    lk_test_load(lk_test_sample("bunny.obj"), &mesh);
    static const char *const names[] = {"bunny.obj", "bunny.off", "bunny.smf"};
    for (size_t i = 0; i < 3; i++) {
        write_and_read(&mesh, names[i], NULL, &back);
        assert_int_equal(back.vertex_count, 34835);
        assert_indices(&back, mesh.indices, 69666);
        assert_same_floats(mesh.positions, back.positions, 3 * 34835, names[i]);
        lk_mesh_free(&back);
    }
    lk_mesh_free(&mesh);

    /* A point set with normals through OBJ keeps its normals. */
    lk_test_load(lk_test_sample("kitten.xyz"), &mesh);
    write_and_read(&mesh, "kitten.obj", NULL, &back);
    assert_int_equal(back.vertex_count, 5210);
    assert_same_floats(mesh.normals, back.normals, 3 * 5210, "kitten normal");
    lk_mesh_free(&back);
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_obj_bunny),
        cmocka_unit_test(test_off_samples),
        cmocka_unit_test(test_xyz_kitten),
        cmocka_unit_test(test_obj_assimp_files),
        cmocka_unit_test(test_obj_polygons_and_relative_indices),
        cmocka_unit_test(test_obj_attribute_splitting),
        cmocka_unit_test(test_obj_errors),
        cmocka_unit_test(test_off_variants),
        cmocka_unit_test(test_off_errors),
        cmocka_unit_test(test_off_truncated_sample),
        cmocka_unit_test(test_smf),
        cmocka_unit_test(test_xyz),
        cmocka_unit_test(test_empty_input),
        cmocka_unit_test(test_round_trips),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
