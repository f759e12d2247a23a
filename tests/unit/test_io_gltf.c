/* SPDX-License-Identifier: MIT */
/* Tests of the glTF 2.0 reader (src/io_gltf.c): Assimp's glTF2 sample
 * models, every .gltf/.glb below data/samples/assimp/glTF2, and small
 * documents built in memory to hit each validation path. */
#include <dirent.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "testutil.h"

#define GLTF_DIR "assimp/glTF2/"

/* ---- helpers --------------------------------------------------------------- */

static lk_status read_memory(const void *data, size_t size, const char *name, lk_mesh *mesh, lk_error *error)
{
    lk_error_clear(error);
    lk_mesh_init(mesh);
    return lk_mesh_read_memory(data, size, name, LK_FORMAT_AUTO, NULL, mesh, error);
}

static lk_status read_path(const char *path, lk_mesh *mesh, lk_error *error)
{
    lk_error_clear(error);
    lk_mesh_init(mesh);
    return lk_mesh_read(path, LK_FORMAT_AUTO, NULL, mesh, error);
}

/* The triangle (0,0,0) (1,0,0) (0,1,0), counter-clockwise seen from +z:
 * 36 bytes of float positions, 6 bytes of uint16 indices, 2 bytes padding. */
static const char *triangle_base64(void)
{
    static char text[128];
    unsigned char bytes[44] = {0};
    float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint16_t indices[3] = {0, 1, 2};
    memcpy(bytes, positions, sizeof positions); /* tests run on little-endian hosts */
    memcpy(bytes + 36, indices, sizeof indices);
    lk_test_base64(bytes, sizeof bytes, text);
    return text;
}

#define TRIANGLE_VIEWS "[{\"buffer\":0,\"byteLength\":36},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}]"
#define TRIANGLE_ACCESSORS                                                                                             \
    "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"                                        \
    "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]"
#define TRIANGLE_MESHES "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}]"

/* A glTF document around the triangle buffer; NULL members take the
 * triangle defaults, `extra` is appended verbatim (starting with ','). */
static const char *make_doc(const char *buffers, const char *views, const char *accessors, const char *meshes,
                            const char *extra)
{
    static char text[1 << 16];
    char default_buffers[256];
    snprintf(default_buffers, sizeof default_buffers,
             "[{\"byteLength\":44,\"uri\":\"data:application/octet-stream;base64,%s\"}]", triangle_base64());
    snprintf(text, sizeof text,
             "{\"asset\":{\"version\":\"2.0\"},\"buffers\":%s,\"bufferViews\":%s,\"accessors\":%s,\"meshes\":%s%s}",
             buffers ? buffers : default_buffers, views ? views : TRIANGLE_VIEWS,
             accessors ? accessors : TRIANGLE_ACCESSORS, meshes ? meshes : TRIANGLE_MESHES, extra ? extra : "");
    return text;
}

static lk_status read_doc(const char *json, lk_mesh *mesh, lk_error *error)
{
    return lk_test_read_string(json, "mem.gltf", LK_FORMAT_AUTO, mesh, error);
}

/* Expects a failure with `status` whose message names mem.gltf and holds `needle`. */
static void expect_doc_error(const char *json, lk_status status, const char *needle)
{
    lk_mesh mesh;
    lk_error error;
    lk_status got = read_doc(json, &mesh, &error);
    if (got != status)
        fail_msg("expected status %s, got %s (\"%s\") for %s", lk_status_string(status), lk_status_string(got),
                 error.message, json);
    lk_assert_message_contains(error, "mem.gltf: ");
    lk_assert_message_contains(error, needle);
    assert_int_equal(mesh.vertex_count, 0);
    assert_null(mesh.positions);
}

static void assert_vec3(const float *v, double x, double y, double z)
{
    if (fabs(v[0] - x) > 1e-5 || fabs(v[1] - y) > 1e-5 || fabs(v[2] - z) > 1e-5)
        fail_msg("got (%g %g %g), expected (%g %g %g)", (double)v[0], (double)v[1], (double)v[2], x, y, z);
}

static void assert_bounds(const lk_mesh *mesh, double x0, double y0, double z0, double x1, double y1, double z1)
{
    float lo[3], hi[3];
    lk_mesh_bounds(mesh, lo, hi);
    double tolerance = 1e-3 * (1 + fabs(x1 - x0) + fabs(y1 - y0) + fabs(z1 - z0));
    double expected[6] = {x0, y0, z0, x1, y1, z1};
    float got[6] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
    for (int i = 0; i < 6; i++)
        if (fabs(got[i] - expected[i]) > tolerance)
            fail_msg("bounds (%g %g %g)-(%g %g %g), expected (%g %g %g)-(%g %g %g)", (double)got[0], (double)got[1],
                     (double)got[2], (double)got[3], (double)got[4], (double)got[5], x0, y0, z0, x1, y1, z1);
}

/* Geometric normal direction of triangle t, as the z of its cross product. */
static double triangle_normal_z(const lk_mesh *mesh, size_t t)
{
    const float *a = mesh->positions + 3 * mesh->indices[3 * t];
    const float *b = mesh->positions + 3 * mesh->indices[3 * t + 1];
    const float *c = mesh->positions + 3 * mesh->indices[3 * t + 2];
    return (double)(b[0] - a[0]) * (c[1] - a[1]) - (double)(b[1] - a[1]) * (c[0] - a[0]);
}

/* ---- sample models ------------------------------------------------------------ */

static void test_box_textured_three_encodings(void **state)
{
    (void)state;
    static const char *const paths[] = {GLTF_DIR "BoxTextured-glTF/BoxTextured.gltf",
                                        GLTF_DIR "BoxTextured-glTF-Binary/BoxTextured.glb",
                                        GLTF_DIR "BoxTextured-glTF-Embedded/BoxTextured.gltf"};
    lk_mesh meshes[3];
    for (int i = 0; i < 3; i++) {
        lk_test_load(lk_test_sample(paths[i]), &meshes[i]);
        lk_mesh *mesh = &meshes[i];
        assert_int_equal(mesh->vertex_count, 24);
        assert_int_equal(mesh->triangle_count, 12);
        assert_non_null(mesh->normals);
        assert_non_null(mesh->texcoords);
        assert_null(mesh->colors);
        assert_bounds(mesh, -0.5, -0.5, -0.5, 0.5, 0.5, 0.5);
        assert_true(fabs(lk_mesh_area(mesh) - 6.0) < 1e-5);
        for (size_t v = 0; v < mesh->vertex_count; v++) {
            const float *n = mesh->normals + 3 * v;
            assert_true(fabs(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) - 1.0) < 1e-5);
            /* The texture repeats 6 times along u; v is flipped to v-up. */
            assert_true(mesh->texcoords[2 * v] >= 0.0f && mesh->texcoords[2 * v] <= 6.0f);
            assert_true(mesh->texcoords[2 * v + 1] >= 0.0f && mesh->texcoords[2 * v + 1] <= 1.0f);
        }
        /* Outward faces: each triangle's normal points away from the centre. */
        for (size_t t = 0; t < mesh->triangle_count; t++) {
            const float *a = mesh->positions + 3 * mesh->indices[3 * t];
            const float *b = mesh->positions + 3 * mesh->indices[3 * t + 1];
            const float *c = mesh->positions + 3 * mesh->indices[3 * t + 2];
            double u[3], w[3], n[3];
            for (int k = 0; k < 3; k++) u[k] = b[k] - a[k], w[k] = c[k] - a[k];
            n[0] = u[1] * w[2] - u[2] * w[1];
            n[1] = u[2] * w[0] - u[0] * w[2];
            n[2] = u[0] * w[1] - u[1] * w[0];
            assert_true(n[0] * a[0] + n[1] * a[1] + n[2] * a[2] > 0.0);
        }
    }
    /* The three encodings hold the same data. */
    for (int i = 1; i < 3; i++) {
        assert_memory_equal(meshes[0].positions, meshes[i].positions, 24 * 3 * sizeof(float));
        assert_memory_equal(meshes[0].normals, meshes[i].normals, 24 * 3 * sizeof(float));
        assert_memory_equal(meshes[0].texcoords, meshes[i].texcoords, 24 * 2 * sizeof(float));
        assert_memory_equal(meshes[0].indices, meshes[i].indices, 12 * 3 * sizeof(uint32_t));
    }
    for (int i = 0; i < 3; i++) lk_mesh_free(&meshes[i]);
}

static void test_2cylinder_engine_glb(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample(GLTF_DIR "2CylinderEngine-glTF-Binary/2CylinderEngine.glb"), &mesh);
    /* Counts and bounds from an independent Python walk of the scene. */
    assert_int_equal(mesh.vertex_count, 84657);
    assert_int_equal(mesh.triangle_count, 121496);
    assert_non_null(mesh.normals);
    assert_null(mesh.texcoords);
    assert_bounds(&mesh, -371.6923, -180.9716, -140.0, 371.6922, 92.0416, 128.0);
    lk_mesh_free(&mesh);
}

static void test_other_sample_models(void **state)
{
    (void)state;
    static const struct {
        const char *path;
        size_t vertices, triangles;
        float min[3], max[3];
    } cases[] = {
        {"ClearCoat-glTF/ClearCoatTest.gltf", 20106, 37116, {-7.3578f, -6.25f, -0.06f}, {3.1f, 6.8545f, 1.05f}},
        {"glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf", 24, 12, {-1, -1, -1}, {1, 1, 1}},
        /* posed by its joints: their nodes and inverse bind matrices
         * disagree by -0.5 in x (test_anim_io.c, test_gltf_simple_skin) */
        {"simple_skin/simple_skin.gltf", 10, 8, {-0.5f, 0, 0}, {0.5f, 2, 0}},
        {"textureTransform/TextureTransformTest.gltf", 48, 24, {-1.6f, -1.1413f, 0}, {1.6f, 1.05f, 0.01f}},
        {"issue_3269/texcoord_crash.gltf", 20, 10, {-1.2f, -1.2f, -0.0526f}, {1.2f, 1.2f, 0}},
        {"cameras/Cameras.gltf", 4, 2, {0, 0, -0.7076f}, {1, 0.7066f, 0}},
        {"BoxTexcoords-glTF/boxTexcoords.gltf", 24, 12, {-1, -1, -1}, {1, 1, 1}},
        {"BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf", 24, 12, {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}},
        {"BoxTextured-glTF-pbrSpecularGlossiness/BoxTextured.gltf", 24, 12, {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[256];
        snprintf(path, sizeof path, GLTF_DIR "%s", cases[i].path);
        lk_mesh mesh;
        lk_test_load(lk_test_sample(path), &mesh);
        if (mesh.vertex_count != cases[i].vertices || mesh.triangle_count != cases[i].triangles)
            fail_msg("%s: %zu vertices %zu triangles, expected %zu %zu", path, mesh.vertex_count, mesh.triangle_count,
                     cases[i].vertices, cases[i].triangles);
        assert_bounds(&mesh, cases[i].min[0], cases[i].min[1], cases[i].min[2], cases[i].max[0], cases[i].max[1],
                      cases[i].max[2]);
        lk_mesh_free(&mesh);
    }
    /* BoxBadNormals: vertices 0-3 have zero normals (they stay zero, not
     * NaN), vertices 4-7 normals of length 0.1 (renormalised). */
    lk_mesh mesh;
    lk_test_load(lk_test_sample(GLTF_DIR "BoxBadNormals-glTF-Binary/BoxBadNormals.glb"), &mesh);
    assert_int_equal(mesh.vertex_count, 24);
    assert_int_equal(mesh.triangle_count, 12);
    assert_non_null(mesh.normals);
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        const float *n = mesh.normals + 3 * v;
        double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        assert_true(fabs(length - (v < 4 ? 0.0 : 1.0)) < 1e-6);
    }
    lk_mesh_free(&mesh);
}

/* The segments of a scene's one line primitive as position pairs, each
 * pair's smaller point first, the pairs sorted: the same square whatever
 * the mode and indexing. */
static int compare_segments(const void *a, const void *b) { return memcmp(a, b, 6 * sizeof(float)); }

static size_t scene_segments(const char *path, float segments[][6], size_t capacity)
{
    lk_scene scene;
    lk_error error = {0};
    assert_int_equal(lk_scene_read(path, NULL, &scene, &error), LK_OK);
    assert_int_equal(scene.mesh_count, 1);
    assert_int_equal(scene.meshes[0].primitive_count, 1);
    const lk_scene_primitive *primitive = &scene.meshes[0].primitives[0];
    assert_int_equal(primitive->mesh.triangle_count, 0);
    assert_true(primitive->line_count <= capacity);
    for (size_t s = 0; s < primitive->line_count; s++) {
        const float *a = primitive->mesh.positions + 3 * primitive->lines[2 * s];
        const float *b = primitive->mesh.positions + 3 * primitive->lines[2 * s + 1];
        bool swap = memcmp(a, b, 3 * sizeof(float)) > 0;
        memcpy(segments[s], swap ? b : a, 3 * sizeof(float));
        memcpy(segments[s] + 3, swap ? a : b, 3 * sizeof(float));
    }
    qsort(segments, primitive->line_count, sizeof segments[0], compare_segments);
    size_t count = primitive->line_count;
    lk_scene_free(&scene);
    return count;
}

/* Issue 20: line primitives are kept by the scene reader (the writer writes
 * them back as LINES): LINES, LINE_LOOP and LINE_STRIP, each plain (01-03)
 * and indexed (08-10), give the same 4 segments. lk_mesh_read still
 * refuses a file of lines only (test_primitive_modes). */
static void test_scene_lines(void **state)
{
    (void)state;
    static const int samples[] = {1, 2, 3, 8, 9, 10};
    float first[8][6], segments[8][6];
    char path[256];
    for (size_t i = 0; i < sizeof samples / sizeof samples[0]; i++) {
        snprintf(path, sizeof path, GLTF_DIR "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_%02d.gltf",
                 samples[i]);
        size_t count = scene_segments(lk_test_sample(path), i == 0 ? first : segments, 8);
        assert_int_equal(count, 4);
        if (i > 0) assert_memory_equal(first, segments, 4 * sizeof segments[0]);
    }
    /* the square's four sides are four different segments */
    for (size_t s = 1; s < 4; s++) assert_true(compare_segments(first[s - 1], first[s]) < 0);
}

static void test_primitive_modes(void **state)
{
    (void)state;
    char path[256];
    lk_mesh mesh;
    lk_error error;
    /* 00 and 07: points (1024 vertices, no triangles). */
    for (int n = 0; n <= 7; n += 7) {
        snprintf(path, sizeof path, GLTF_DIR "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_%02d.gltf", n);
        lk_test_load(lk_test_sample(path), &mesh);
        assert_int_equal(mesh.vertex_count, 1024);
        assert_int_equal(mesh.triangle_count, 0);
        lk_mesh_free(&mesh);
    }
    /* Lines only: refused, saying why. */
    static const int lines[] = {1, 2, 3, 8, 9, 10};
    for (size_t i = 0; i < sizeof lines / sizeof lines[0]; i++) {
        snprintf(path, sizeof path, GLTF_DIR "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_%02d.gltf",
                 lines[i]);
        assert_int_equal(read_path(lk_test_sample(path), &mesh, &error), LK_ERR_UNSUPPORTED);
        lk_assert_message_contains(error, "only lines");
    }
    /* The same quad as triangles (06, 13-15), strips (04, 11) and fans
     * (05, 12): two triangles, all facing the same way as the plain list. */
    snprintf(path, sizeof path, GLTF_DIR "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_06.gltf");
    lk_test_load(lk_test_sample(path), &mesh);
    assert_int_equal(mesh.vertex_count, 6);
    assert_int_equal(mesh.triangle_count, 2);
    double reference = triangle_normal_z(&mesh, 0);
    assert_true(fabs(reference) > 0.0);
    double reference_area = lk_mesh_area(&mesh);
    lk_mesh_free(&mesh);
    lk_mesh list;
    lk_mesh_init(&list);
    static const int quads[] = {4, 5, 11, 12, 13, 14, 15};
    for (size_t i = 0; i < sizeof quads / sizeof quads[0]; i++) {
        snprintf(path, sizeof path, GLTF_DIR "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_%02d.gltf",
                 quads[i]);
        lk_test_load(lk_test_sample(path), &mesh);
        assert_int_equal(mesh.vertex_count, 4);
        assert_int_equal(mesh.triangle_count, 2);
        for (size_t t = 0; t < 2; t++) assert_true(triangle_normal_z(&mesh, t) * reference > 0.0);
        assert_true(fabs(lk_mesh_area(&mesh) - reference_area) < 1e-6);
        if (quads[i] == 13) {
            /* Indices [1, 0, 3, 1, 3, 2] as uint32. */
            static const uint32_t expected[6] = {1, 0, 3, 1, 3, 2};
            assert_memory_equal(mesh.indices, expected, sizeof expected);
            lk_mesh_copy(&list, &mesh, NULL);
        }
        if (quads[i] == 14 || quads[i] == 15) {
            /* uint8 and uint16 indices decode to the same as uint32. */
            assert_memory_equal(mesh.indices, list.indices, 6 * sizeof(uint32_t));
            assert_memory_equal(mesh.positions, list.positions, 12 * sizeof(float));
        }
        lk_mesh_free(&mesh);
    }
    lk_mesh_free(&list);
}

static void test_refused_samples(void **state)
{
    (void)state;
    static const struct {
        const char *path;
        lk_status status;
        const char *needle;
    } cases[] = {
        {"IndexOutOfRange/IndexOutOfRange.gltf", LK_ERR_RANGE,
         "meshes[0].primitives[0]: index 255 out of range (24 vertices)"},
        {"IndexOutOfRange/AllIndicesOutOfRange.gltf", LK_ERR_RANGE, "index 65535 out of range (24 vertices)"},
        {"MissingBin/BoxTextured.gltf", LK_ERR_IO, "buffers[0].uri: cannot open \"BoxTextured0.bin\""},
        {"wrongTypes/badArray.gltf", LK_ERR_PARSE, "meshes[0].primitives: expected an array, got an object"},
        {"wrongTypes/badExtension.gltf", LK_ERR_PARSE,
         "baseColorTexture.extensions.KHR_texture_transform: expected an object, got a string"},
        {"wrongTypes/badNumber.gltf", LK_ERR_PARSE, "materials[0].normalTexture"},
        {"wrongTypes/badObject.gltf", LK_ERR_PARSE,
         "materials[0].pbrMetallicRoughness: expected an object, got an array"},
        {"wrongTypes/badString.gltf", LK_ERR_PARSE, "scenes[0].name: expected a string, got a number"},
        {"wrongTypes/badUint.gltf", LK_ERR_PARSE, "baseColorTexture.index: expected a non-negative integer, got -1"},
        {"SchemaFailures/sceneWrongType.gltf", LK_ERR_PARSE, "scene: expected a non-negative integer, got a string"},
        {"BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb", LK_ERR_RANGE,
         "meshes[0].primitives[0]: POSITION of vertex 0 (accessors[2]) is not finite"},
        {"draco/2CylinderEngine.gltf", LK_ERR_UNSUPPORTED, "KHR_draco_mesh_compression"},
        {"RecursiveNodes/RecursiveNodes.gltf", LK_ERR_PARSE, "nodes[1].children[0]: node 0 is reached twice"},
        {"TestNoRootNode/NoScene.gltf", LK_ERR_RANGE, "scene: scene 0 out of range (0 scenes)"},
        {"TestNoRootNode/SceneWithoutNodes.gltf", LK_ERR_PARSE, "no mesh geometry"},
        {"IncorrectVertexArrays/Cube.gltf", LK_ERR_RANGE,
         "meshes[1].primitives[0]: 35 vertices do not form whole triangles"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char relative[256];
        snprintf(relative, sizeof relative, GLTF_DIR "%s", cases[i].path);
        const char *path = lk_test_sample(relative);
        lk_mesh mesh;
        lk_error error;
        lk_status status = read_path(path, &mesh, &error);
        if (status != cases[i].status)
            fail_msg("%s: status %s, expected %s (%s)", path, lk_status_string(status),
                     lk_status_string(cases[i].status), error.message);
        lk_assert_message_contains(error, path);
        lk_assert_message_contains(error, cases[i].needle);
        assert_null(mesh.positions);
    }
}

/* ---- every sample file ------------------------------------------------------------ */

typedef struct sample_tally {
    size_t files, loaded, refused;
} sample_tally;

static bool has_gltf_extension(const char *name)
{
    size_t length = strlen(name);
    return (length > 5 && strcmp(name + length - 5, ".gltf") == 0) ||
           (length > 4 && strcmp(name + length - 4, ".glb") == 0);
}

static int compare_names(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static void visit_directory(const char *directory, sample_tally *tally)
{
    DIR *dir = opendir(directory);
    if (!dir) fail_msg("cannot open directory %s", directory);
    char **names = NULL;
    size_t count = 0;
    struct dirent *entry;
    while ((entry = readdir(dir)) != NULL) {
        if (entry->d_name[0] == '.') continue;
        names = realloc(names, (count + 1) * sizeof *names);
        assert_non_null(names);
        names[count] = malloc(strlen(entry->d_name) + 1);
        strcpy(names[count++], entry->d_name);
    }
    closedir(dir);
    qsort(names, count, sizeof *names, compare_names); /* stable output order */
    for (size_t i = 0; i < count; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", directory, names[i]);
        struct stat info;
        assert_int_equal(stat(path, &info), 0);
        if (S_ISDIR(info.st_mode)) {
            visit_directory(path, tally);
        } else if (has_gltf_extension(names[i])) {
            lk_mesh mesh;
            lk_error error;
            tally->files++;
            lk_status status = read_path(path, &mesh, &error);
            const char *relative = strstr(path, GLTF_DIR) ? strstr(path, GLTF_DIR) + strlen(GLTF_DIR) : path;
            if (status == LK_OK) {
                if (mesh.vertex_count == 0) fail_msg("%s loaded with no vertices", path);
                assert_int_equal(lk_mesh_validate(&mesh, NULL), LK_OK);
                print_message("gltf sample  loaded  %-70s %8zu v %8zu t\n", relative, mesh.vertex_count,
                              mesh.triangle_count);
                tally->loaded++;
                lk_mesh_free(&mesh);
            } else {
                if (!strstr(error.message, path)) fail_msg("%s: message lacks the path: %s", path, error.message);
                const char *reason = strstr(error.message, path) + strlen(path);
                if (strncmp(reason, ": ", 2) == 0) reason += 2;
                print_message("gltf sample  refused %-70s [%s] %s\n", relative, lk_status_string(status), reason);
                tally->refused++;
            }
        }
        free(names[i]);
    }
    free(names);
}

static void test_every_sample_file(void **state)
{
    (void)state;
    char root[4096];
    snprintf(root, sizeof root, "%s", lk_test_sample("assimp/glTF2"));
    sample_tally tally = {0, 0, 0};
    visit_directory(root, &tally);
    print_message("gltf samples: %zu files, %zu loaded, %zu refused\n", tally.files, tally.loaded, tally.refused);
    assert_int_equal(tally.files, 46);
    assert_int_equal(tally.loaded, 24);
    assert_int_equal(tally.refused, 22);
}

/* ---- documents built in memory ------------------------------------------------------ */

static void test_memory_triangle(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error;
    /* No nodes and no scenes: meshes are read as they are. */
    assert_int_equal(read_doc(make_doc(NULL, NULL, NULL, NULL, NULL), &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 3);
    assert_int_equal(mesh.triangle_count, 1);
    assert_vec3(mesh.positions + 3, 1, 0, 0);
    assert_vec3(mesh.positions + 6, 0, 1, 0);
    assert_int_equal(mesh.indices[0], 0);
    assert_int_equal(mesh.indices[1], 1);
    assert_int_equal(mesh.indices[2], 2);
    assert_null(mesh.normals);
    lk_mesh_free(&mesh);

    /* Non-indexed, unpadded base64 (the 36 position bytes need none) and a
     * sniffed format (no extension, leading '{'). */
    char buffers[256];
    char encoded[64];
    float positions[9] = {0, 0, 0, 2, 0, 0, 0, 2, 0};
    lk_test_base64((const unsigned char *)positions, 36, encoded);
    snprintf(buffers, sizeof buffers, "[{\"byteLength\":36,\"uri\":\"data:application/gltf-buffer;base64,%s\"}]",
             encoded);
    const char *json = make_doc(buffers, "[{\"buffer\":0,\"byteLength\":36}]",
                                "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}]",
                                "[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}]", NULL);
    assert_int_equal(lk_test_read_string(json, "noextension", LK_FORMAT_AUTO, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 1);
    assert_vec3(mesh.positions + 3, 2, 0, 0);
    lk_mesh_free(&mesh);
}

static void test_node_transforms(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error;
    /* Normal (1,1,0)/sqrt2 on every vertex, appended after the triangle. */
    unsigned char bytes[80] = {0};
    float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    float s = (float)(1.0 / sqrt(2.0));
    float normals[9] = {s, s, 0, s, s, 0, s, s, 0};
    uint16_t indices[3] = {0, 1, 2};
    memcpy(bytes, positions, 36);
    memcpy(bytes + 36, indices, 6);
    memcpy(bytes + 44, normals, 36);
    char encoded[128], buffers[256];
    lk_test_base64(bytes, sizeof bytes, encoded);
    snprintf(buffers, sizeof buffers, "[{\"byteLength\":80,\"uri\":\"data:application/octet-stream;base64,%s\"}]",
             encoded);
    const char *views = "[{\"buffer\":0,\"byteLength\":36},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6},"
                        "{\"buffer\":0,\"byteOffset\":44,\"byteLength\":36}]";
    const char *accessors = "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
                            "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"},"
                            "{\"bufferView\":2,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}]";
    const char *meshes = "[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"NORMAL\":2},\"indices\":1}]}]";

    /* Parent translates by (10,0,0), child scales x by 2: world = T * S. */
    const char *scene = ",\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":["
                        "{\"translation\":[10,0,0],\"children\":[1]},{\"scale\":[2,1,1],\"mesh\":0}]";
    assert_int_equal(read_doc(make_doc(buffers, views, accessors, meshes, scene), &mesh, &error), LK_OK);
    assert_vec3(mesh.positions + 0, 10, 0, 0);
    assert_vec3(mesh.positions + 3, 12, 0, 0);
    assert_vec3(mesh.positions + 6, 10, 1, 0);
    /* Normals use the inverse transpose: (0.5, 1, 0) normalised. */
    assert_vec3(mesh.normals, 0.5 / sqrt(1.25), 1.0 / sqrt(1.25), 0);
    assert_int_equal(mesh.indices[1], 1);
    lk_mesh_free(&mesh);

    /* The same as one column-major matrix. */
    scene = ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"matrix\":[2,0,0,0, 0,1,0,0, 0,0,1,0, 10,0,0,1],\"mesh\":0}]";
    assert_int_equal(read_doc(make_doc(buffers, views, accessors, meshes, scene), &mesh, &error), LK_OK);
    assert_vec3(mesh.positions + 3, 12, 0, 0);
    assert_vec3(mesh.normals + 6, 0.5 / sqrt(1.25), 1.0 / sqrt(1.25), 0);
    lk_mesh_free(&mesh);

    /* A rotation of 90 degrees about z maps x to y. */
    scene = ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"rotation\":[0,0,0.7071067811865476,0.7071067811865476],"
            "\"mesh\":0}]";
    assert_int_equal(read_doc(make_doc(buffers, views, accessors, meshes, scene), &mesh, &error), LK_OK);
    assert_vec3(mesh.positions + 3, 0, 1, 0);
    assert_vec3(mesh.positions + 6, -1, 0, 0);
    assert_vec3(mesh.normals, -s, s, 0);
    assert_true(triangle_normal_z(&mesh, 0) > 0.0);
    lk_mesh_free(&mesh);

    /* A mirror (negative determinant) reverses the winding, so the front
     * face still faces +z, and mirrors the normal. */
    scene = ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"scale\":[-1,1,1],\"mesh\":0}]";
    assert_int_equal(read_doc(make_doc(buffers, views, accessors, meshes, scene), &mesh, &error), LK_OK);
    assert_vec3(mesh.positions + 3, -1, 0, 0);
    assert_int_equal(mesh.indices[0], 0);
    assert_int_equal(mesh.indices[1], 2);
    assert_int_equal(mesh.indices[2], 1);
    assert_true(triangle_normal_z(&mesh, 0) > 0.0);
    assert_vec3(mesh.normals, -s, s, 0);
    lk_mesh_free(&mesh);

    /* No scenes: the parentless nodes are the roots; the mesh instanced twice. */
    scene = ",\"nodes\":[{\"children\":[1]},{\"mesh\":0,\"translation\":[0,0,1]},{\"mesh\":0}]";
    assert_int_equal(read_doc(make_doc(buffers, views, accessors, meshes, scene), &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 6);
    assert_int_equal(mesh.triangle_count, 2);
    assert_vec3(mesh.positions, 0, 0, 1);
    assert_vec3(mesh.positions + 9, 0, 0, 0);
    assert_int_equal(mesh.indices[3], 3);
    lk_mesh_free(&mesh);

    /* Bad transforms. */
    expect_doc_error(make_doc(buffers, views, accessors, meshes,
                              ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"rotation\":[0,0,0,0],\"mesh\":0}]"),
                     LK_ERR_RANGE, "nodes[0].rotation: is not a valid quaternion");
    expect_doc_error(make_doc(buffers, views, accessors, meshes,
                              ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"matrix\":[1,0,0],\"mesh\":0}]"),
                     LK_ERR_PARSE, "nodes[0].matrix: expected 16 numbers, got 3");
    expect_doc_error(make_doc(buffers, views, accessors, meshes,
                              ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"translation\":[0,\"x\",0],\"mesh\":0}]"),
                     LK_ERR_PARSE, "nodes[0].translation: element 1: expected a number, got a string");
    expect_doc_error(make_doc(buffers, views, accessors, meshes,
                              ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"scale\":[1e39,1e300,1],\"mesh\":0}]"),
                     LK_ERR_RANGE,
                     "POSITION of vertex 1 (accessors[0]) is not finite (inf) after the transform of nodes[0]");
}

static void test_scene_graph_errors(void **state)
{
    (void)state;
    static const struct {
        const char *scene;
        lk_status status;
        const char *needle;
    } cases[] = {
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"children\":[1]},{\"children\":[0]}]", LK_ERR_PARSE,
         "nodes[1].children[0]: node 0 is reached twice (the node hierarchy has a cycle"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"children\":[0],\"mesh\":0}]", LK_ERR_PARSE,
         "nodes[0].children[0]: node 0 is reached twice"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"children\":[1,2]},{\"children\":[2]},{\"mesh\":0}]", LK_ERR_PARSE,
         "nodes[1].children[0]: node 2 is reached twice"},
        {",\"scenes\":[{\"nodes\":[0,0]}],\"nodes\":[{\"mesh\":0}]", LK_ERR_PARSE,
         "scenes[0].nodes: lists more nodes than the 1 that exist"},
        {",\"scenes\":[{\"nodes\":[0,1]}],\"nodes\":[{\"children\":[1]},{\"mesh\":0}]", LK_ERR_PARSE,
         "scenes[0].nodes: node 1 is reached twice"},
        {",\"scenes\":[{\"nodes\":[3]}],\"nodes\":[{\"mesh\":0}]", LK_ERR_RANGE,
         "scenes[0].nodes[0]: node 3 out of range (1 node)"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"children\":[7]}]", LK_ERR_RANGE,
         "nodes[0].children[0]: node 7 out of range (1 node)"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"children\":{\"a\":1}}]", LK_ERR_PARSE,
         "nodes[0].children: expected an array, got an object"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":4}]", LK_ERR_RANGE,
         "nodes[0].mesh: mesh 4 out of range (1 mesh)"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":-1}]", LK_ERR_PARSE,
         "nodes[0].mesh: expected a non-negative integer, got -1"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0.5}]", LK_ERR_PARSE,
         "nodes[0].mesh: expected a non-negative integer, got 0.5"},
        {",\"scene\":1,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}]", LK_ERR_RANGE,
         "scene: scene 1 out of range (1 scene)"},
        {",\"nodes\":[{\"children\":[1]},{\"children\":[0]}]", LK_ERR_PARSE, "every node has a parent"},
        {",\"nodes\":[3]", LK_ERR_PARSE, "nodes: element 0: expected an object, got a number"},
        {",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{}]", LK_ERR_PARSE, "no mesh geometry"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_doc_error(make_doc(NULL, NULL, NULL, NULL, cases[i].scene), cases[i].status, cases[i].needle);
}

static void test_deep_node_chain(void **state)
{
    (void)state;
    /* 20000 nested nodes, each translating by 1 along x: an explicit stack
     * walks them; recursion would risk the C stack. */
    enum { depth = 20000 };
    size_t capacity = (size_t)depth * 48 + 256;
    char *nodes = malloc(capacity);
    assert_non_null(nodes);
    size_t length = (size_t)snprintf(nodes, capacity, ",\"scenes\":[{\"nodes\":[0]}],\"nodes\":[");
    for (int i = 0; i < depth; i++) {
        if (i + 1 < depth)
            length += (size_t)snprintf(nodes + length, capacity - length,
                                       "{\"translation\":[1,0,0],\"children\":[%d]},", i + 1);
        else
            length += (size_t)snprintf(nodes + length, capacity - length, "{\"translation\":[1,0,0],\"mesh\":0}]");
    }
    char *json = malloc(capacity + 4096);
    assert_non_null(json);
    snprintf(json, capacity + 4096, "%s", make_doc(NULL, NULL, NULL, NULL, ""));
    json[strlen(json) - 1] = '\0'; /* drop the closing brace */
    strcat(json, nodes);
    strcat(json, "}");
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_doc(json, &mesh, &error), LK_OK);
    assert_vec3(mesh.positions, depth, 0, 0);
    assert_vec3(mesh.positions + 3, depth + 1, 0, 0);
    lk_mesh_free(&mesh);
    free(json);
    free(nodes);
}

static void test_accessor_validation(void **state)
{
    (void)state;
    static const struct {
        const char *accessors;
        lk_status status;
        const char *needle;
    } cases[] = {
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":-1,\"type\":\"VEC3\"}]", LK_ERR_PARSE,
         "accessors[0].count: expected a non-negative integer, got -1"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":\"3\",\"type\":\"VEC3\"}]", LK_ERR_PARSE,
         "accessors[0].count: expected a non-negative integer, got a string"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":1e300,\"type\":\"VEC3\"}]", LK_ERR_PARSE,
         "accessors[0].count: expected a non-negative integer, got 1e+300"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":1099511627776,\"type\":\"VEC3\"}]", LK_ERR_LIMIT,
         "accessors[0].count: 1099511627776 is more than lodkit supports"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":4000000000,\"type\":\"VEC3\"}]", LK_ERR_RANGE,
         "accessors[0]: count 4000000000 exceeds bufferView 0 (36 bytes)"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"}]", LK_ERR_RANGE,
         "accessors[0]: count 4 exceeds bufferView 0 (36 bytes): byteOffset 0 + 3 x stride 12 + element 12 = 48 bytes"},
        {"[{\"bufferView\":0,\"byteOffset\":4,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}]", LK_ERR_RANGE,
         "accessors[0]: count 3 exceeds bufferView 0 (36 bytes)"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":0,\"type\":\"VEC3\"}]", LK_ERR_PARSE,
         "accessors[0].count: must be at least 1"},
        {"[{\"bufferView\":0,\"componentType\":5124,\"count\":3,\"type\":\"VEC3\"}]", LK_ERR_PARSE,
         "accessors[0].componentType: 5124 is not a glTF component type"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC5\"}]", LK_ERR_PARSE,
         "accessors[0].type: \"VEC5\" is not a glTF accessor type"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":1,\"type\":\"MAT3\"}]", LK_ERR_PARSE,
         "accessors[0].type: MAT3, but meshes[0].primitives[0].attributes.POSITION needs a VEC3"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":3}]", LK_ERR_PARSE,
         "accessors[0].type: expected a string, got a number"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":3}]", LK_ERR_PARSE,
         "accessors[0]: missing required \"type\""},
        {"[{\"bufferView\":0,\"componentType\":5126,\"normalized\":true,\"count\":3,\"type\":\"VEC3\"}]", LK_ERR_PARSE,
         "accessors[0].normalized: only integer types of 8 or 16 bits can be normalized"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"normalized\":1,\"count\":3,\"type\":\"VEC3\"}]", LK_ERR_PARSE,
         "accessors[0].normalized: expected true or false, got a number"},
        {"[{\"bufferView\":9,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}]", LK_ERR_RANGE,
         "accessors[0].bufferView: bufferView 9 out of range (2 bufferViews)"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\",\"sparse\":{}}]", LK_ERR_UNSUPPORTED,
         "accessors[0].sparse: sparse accessors are not supported"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
         "{\"bufferView\":1,\"componentType\":5126,\"count\":1,\"type\":\"SCALAR\"}]",
         LK_ERR_PARSE, "accessors[1].componentType: 5126 is not valid for indices"},
        {"[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}]", LK_ERR_RANGE,
         "meshes[0].primitives[0].indices: accessor 1 out of range (1 accessor)"},
        {"[4]", LK_ERR_PARSE, "accessors: element 0: expected an object, got a number"},
        {"{}", LK_ERR_PARSE, "accessors: expected an array, got an object"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_doc_error(make_doc(NULL, NULL, cases[i].accessors, NULL, NULL), cases[i].status, cases[i].needle);

    /* Views and buffers. */
    static const struct {
        const char *buffers, *views;
        lk_status status;
        const char *needle;
    } view_cases[] = {
        {NULL, "[{\"buffer\":0,\"byteLength\":36},{\"buffer\":0,\"byteOffset\":40,\"byteLength\":6}]", LK_ERR_RANGE,
         "bufferViews[1]: byteOffset 40 + byteLength 6 exceeds buffer 0 (44 bytes)"},
        {NULL, "[{\"buffer\":0,\"byteLength\":36},{\"buffer\":1,\"byteLength\":6}]", LK_ERR_RANGE,
         "bufferViews[1].buffer: buffer 1 out of range (1 buffer)"},
        {NULL, "[{\"buffer\":0,\"byteLength\":36,\"byteStride\":2},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}]",
         LK_ERR_PARSE, "bufferViews[0].byteStride: 2 is outside 4..252"},
        {NULL, "[{\"buffer\":0,\"byteLength\":36,\"byteStride\":8},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}]",
         LK_ERR_RANGE, "bufferViews[0].byteStride: 8 is smaller than the 12-byte elements of accessors[0]"},
        {NULL, "[{\"buffer\":0,\"byteLength\":36,\"byteStride\":16},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}]",
         LK_ERR_RANGE, "accessors[0]: count 3 exceeds bufferView 0 (36 bytes): byteOffset 0 + 2 x stride 16"},
        {NULL, "[{\"buffer\":0},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}]", LK_ERR_PARSE,
         "bufferViews[0]: missing required \"byteLength\""},
        {"[{\"byteLength\":4400000000000,\"uri\":\"data:application/octet-stream;base64,AAAA\"}]", NULL, LK_ERR_RANGE,
         "buffers[0].byteLength: 4400000000000 bytes but the data: URI holds only 3"},
        {"[{\"byteLength\":44}]", NULL, LK_ERR_PARSE, "buffers[0]: has no uri (only buffer 0 of a .glb file"},
        {"[{\"byteLength\":44,\"uri\":7}]", NULL, LK_ERR_PARSE, "buffers[0].uri: expected a string, got a number"},
        {"[{\"byteLength\":44,\"uri\":\"data:text/plain,hello\"}]", NULL, LK_ERR_UNSUPPORTED,
         "buffers[0].uri: only base64 data: URIs are supported"},
        {"[{\"byteLength\":44,\"uri\":\"triangle.bin\"}]", NULL, LK_ERR_UNSUPPORTED,
         "buffers[0].uri: refers to the external file \"triangle.bin\", which cannot be read when reading from memory"},
    };
    for (size_t i = 0; i < sizeof view_cases / sizeof view_cases[0]; i++)
        expect_doc_error(make_doc(view_cases[i].buffers, view_cases[i].views, NULL, NULL, NULL), view_cases[i].status,
                         view_cases[i].needle);
}

static void test_base64_errors(void **state)
{
    (void)state;
    const char *good = triangle_base64();
    char buffers[256], data[128];
    static const struct {
        int position; /* where to put `replacement` in the good text, -1: append */
        const char *replacement;
        const char *needle;
    } cases[] = {
        {5, "!", "invalid base64 character '!' at position 5 of the data"},
        {3, " ", "invalid base64 character 0x20 at position 3"},
        {8, "=", "invalid base64 character '=' at position 8"},
        {-1, "A", "base64 data is truncated (61 characters)"},
        {-1, "A=", "base64 data has misplaced '=' padding"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(data, sizeof data, "%s", good);
        if (cases[i].position >= 0)
            data[cases[i].position] = cases[i].replacement[0];
        else
            strcat(data, cases[i].replacement);
        snprintf(buffers, sizeof buffers, "[{\"byteLength\":44,\"uri\":\"data:application/octet-stream;base64,%s\"}]",
                 data);
        expect_doc_error(make_doc(buffers, NULL, NULL, NULL, NULL), LK_ERR_PARSE, cases[i].needle);
    }
    /* The good text itself decodes to the triangle, padding included. */
    assert_int_equal(strlen(good), 60);
    assert_int_equal(good[59], '=');
}

static void test_primitive_validation(void **state)
{
    (void)state;
    static const struct {
        const char *meshes;
        lk_status status;
        const char *needle;
    } cases[] = {
        {"[{\"primitives\":[{\"attributes\":{\"NORMAL\":0},\"indices\":1}]}]", LK_ERR_PARSE,
         "meshes[0].primitives[0]: has no POSITION attribute"},
        {"[{\"primitives\":[{\"indices\":1}]}]", LK_ERR_PARSE,
         "meshes[0].primitives[0]: missing required \"attributes\""},
        {"[{\"primitives\":[{\"attributes\":{\"POSITION\":\"0\"}}]}]", LK_ERR_PARSE,
         "meshes[0].primitives[0].attributes.POSITION: expected a non-negative integer, got a string"},
        {"[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1,\"mode\":7}]}]", LK_ERR_PARSE,
         "meshes[0].primitives[0].mode: 7 is not a glTF primitive mode (0..6)"},
        {"[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":0}]}]", LK_ERR_PARSE,
         "accessors[0].type: VEC3, but meshes[0].primitives[0].indices needs a SCALAR"},
        {"[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"TEXCOORD_0\":0},\"indices\":1}]}]", LK_ERR_PARSE,
         "accessors[0].type: VEC3, but meshes[0].primitives[0].attributes.TEXCOORD_0 needs a VEC2"},
        {"[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1,"
         "\"extensions\":{\"KHR_draco_mesh_compression\":5}}]}]",
         LK_ERR_PARSE, "meshes[0].primitives[0].extensions.KHR_draco_mesh_compression: expected an object"},
        {"[{\"primitives\":[1]}]", LK_ERR_PARSE, "meshes[0].primitives[0]: expected an object, got a number"},
        {"[{\"name\":[1],\"primitives\":[]}]", LK_ERR_PARSE, "meshes[0].name: expected a string, got an array"},
        {"[{}]", LK_ERR_PARSE, "meshes[0]: missing required \"primitives\""},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_doc_error(make_doc(NULL, NULL, NULL, cases[i].meshes, NULL), cases[i].status, cases[i].needle);

    /* Index out of range: the uint16 indices are 0 1 2, so with a
     * 2-element POSITION accessor index 2 is out of range. */
    expect_doc_error(
        make_doc(NULL, "[{\"buffer\":0,\"byteLength\":24},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}]",
                 "[{\"bufferView\":0,\"componentType\":5126,\"count\":2,\"type\":\"VEC3\"},"
                 "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]",
                 NULL, NULL),
        LK_ERR_RANGE, "meshes[0].primitives[0]: index 2 out of range (2 vertices) at element 2 of accessors[1]");
    /* Two indices do not make a triangle. */
    expect_doc_error(make_doc(NULL, NULL,
                              "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
                              "{\"bufferView\":1,\"componentType\":5123,\"count\":2,\"type\":\"SCALAR\"}]",
                              NULL, NULL),
                     LK_ERR_RANGE, "meshes[0].primitives[0]: 2 indices do not form whole triangles");
    /* NORMAL with fewer elements than POSITION. */
    expect_doc_error(make_doc(NULL, NULL,
                              "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
                              "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"},"
                              "{\"bufferView\":0,\"componentType\":5126,\"count\":2,\"type\":\"VEC3\"}]",
                              "[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"NORMAL\":2},\"indices\":1}]}]",
                              NULL),
                     LK_ERR_RANGE, "attributes.NORMAL: accessor 2 has 2 elements but POSITION has 3");
    /* Draco primitive without uncompressed fallback (no bufferView). */
    expect_doc_error(make_doc(NULL, NULL, "[{\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}]",
                              "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},"
                              "\"extensions\":{\"KHR_draco_mesh_compression\":{\"bufferView\":0}}}]}]",
                              NULL),
                     LK_ERR_UNSUPPORTED,
                     "meshes[0].primitives[0]: Draco-compressed geometry (KHR_draco_mesh_compression)");
}

static void test_document_errors(void **state)
{
    (void)state;
    /* Malformed JSON reports cJSON's byte offset (and line). */
    expect_doc_error("{\"asset\":{\"version\":\"2.0\"},\n\"meshes\":[}", LK_ERR_PARSE,
                     "mem.gltf: byte 38: invalid JSON (line 2)");
    expect_doc_error("{\"asset\":{\"version\":\"2.0\"}} x", LK_ERR_PARSE,
                     "byte 28: unexpected data after the JSON document (line 1)");
    expect_doc_error("{", LK_ERR_PARSE, "byte 0: invalid JSON");
    expect_doc_error("[1,2]", LK_ERR_PARSE, "expected a JSON object at the top level, got an array");
    expect_doc_error("{\"meshes\":[]}", LK_ERR_PARSE, "asset: missing (not a glTF 2.0 file?)");
    expect_doc_error("{\"asset\":{\"version\":2}}", LK_ERR_PARSE, "asset.version: expected a string, got a number");
    expect_doc_error("{\"asset\":{\"version\":\"1.0\"}}", LK_ERR_UNSUPPORTED,
                     "asset.version: glTF version \"1.0\" is not supported");
    expect_doc_error("{\"asset\":{\"version\":\"2.0\"}}", LK_ERR_PARSE, "the scene contains no mesh geometry");
    expect_doc_error(make_doc(NULL, NULL, NULL, NULL, ",\"extensionsRequired\":[\"EXT_unknown_thing\"]"),
                     LK_ERR_UNSUPPORTED,
                     "extensionsRequired[0]: required extension \"EXT_unknown_thing\" is not supported");
    expect_doc_error(make_doc(NULL, NULL, NULL, NULL, ",\"extensionsRequired\":[\"KHR_draco_mesh_compression\"]"),
                     LK_ERR_UNSUPPORTED, "KHR_draco_mesh_compression");
    expect_doc_error(make_doc(NULL, NULL, NULL, NULL, ",\"extensionsUsed\":[3]"), LK_ERR_PARSE,
                     "extensionsUsed[0]: expected a string, got a number");
    expect_doc_error(make_doc(NULL, NULL, NULL, NULL, ",\"materials\":[{\"emissiveFactor\":[1,1]}]"), LK_ERR_PARSE,
                     "materials[0].emissiveFactor: expected 3 numbers, got 2");
    expect_doc_error(make_doc(NULL, NULL, NULL, NULL, ",\"materials\":[{\"doubleSided\":\"yes\"}]"), LK_ERR_PARSE,
                     "materials[0].doubleSided: expected true or false, got a string");

    /* Extensions that do not affect geometry are fine when required, and
     * "extras" may hold anything. */
    lk_mesh mesh;
    lk_error error;
    const char *json = make_doc(NULL, NULL, NULL, NULL,
                                ",\"extensionsRequired\":[\"KHR_materials_unlit\",\"KHR_texture_transform\"],"
                                "\"extensionsUsed\":[\"KHR_materials_unlit\",\"KHR_texture_transform\"],"
                                "\"extras\":{\"name\":5,\"extensions\":3}");
    assert_int_equal(read_doc(json, &mesh, &error), LK_OK);
    assert_int_equal(mesh.triangle_count, 1);
    lk_mesh_free(&mesh);
}

static void test_strips_fans_points_and_mixed_attributes(void **state)
{
    (void)state;
    /* Five vertices of a zig-zag strip, indices of a stitched strip
     * (0 1 2 3 3 4: the repeated 3 makes two degenerate triangles). */
    unsigned char bytes[96] = {0};
    float positions[15] = {0, 0, 0, 0, 1, 0, 1, 0, 0, 1, 1, 0, 2, 0, 0};
    uint16_t indices[6] = {0, 1, 2, 3, 3, 4};
    uint8_t colors[20] = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 0, 51, 102, 153, 204};
    memcpy(bytes, positions, 60);
    memcpy(bytes + 60, indices, 12);
    memcpy(bytes + 72, colors, 20);
    char encoded[160], buffers[256];
    lk_test_base64(bytes, 92, encoded);
    snprintf(buffers, sizeof buffers, "[{\"byteLength\":92,\"uri\":\"data:application/octet-stream;base64,%s\"}]",
             encoded);
    const char *views = "[{\"buffer\":0,\"byteLength\":60},{\"buffer\":0,\"byteOffset\":60,\"byteLength\":12},"
                        "{\"buffer\":0,\"byteOffset\":72,\"byteLength\":20}]";
    const char *accessors =
        "[{\"bufferView\":0,\"componentType\":5126,\"count\":5,\"type\":\"VEC3\"},"
        "{\"bufferView\":1,\"componentType\":5123,\"count\":6,\"type\":\"SCALAR\"},"
        "{\"bufferView\":2,\"componentType\":5121,\"normalized\":true,\"count\":5,\"type\":\"VEC4\"},"
        "{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}]";
    /* Mesh 0: strip (no colours); mesh 1: fan over vertices 0..4 with
     * colours; mesh 2: points. */
    const char *meshes = "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1,\"mode\":5},"
                         "{\"attributes\":{\"POSITION\":0},\"mode\":1}]},"
                         "{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"COLOR_0\":2},\"mode\":6}]},"
                         "{\"primitives\":[{\"attributes\":{\"POSITION\":3},\"mode\":0}]}]";
    const char *scene = ",\"scenes\":[{\"nodes\":[0,1,2]}],\"nodes\":[{\"mesh\":0},{\"mesh\":1},{\"mesh\":2}]";
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_doc(make_doc(buffers, views, accessors, meshes, scene), &mesh, &error), LK_OK);
    /* 5 + 5 + 3 vertices; strip 6-2 = 4 minus 2 degenerate = 2 triangles;
     * fan 5-2 = 3 triangles; the lines primitive is skipped. */
    assert_int_equal(mesh.vertex_count, 13);
    assert_int_equal(mesh.triangle_count, 5);
    static const uint32_t expected[15] = {0, 1, 2, /* strip t=0 */ 1,
                                          3, 2, /* t=1: v1 v3 v2 */
                                          6, 7, 5, 7,
                                          8, 5, 8, 9,
                                          5 /* fan around vertex 5 */};
    assert_memory_equal(mesh.indices, expected, sizeof expected);
    for (size_t t = 0; t < 5; t++) assert_true(triangle_normal_z(&mesh, t) != 0.0);
    /* Colours: white for the strip and the points, decoded for the fan. */
    assert_non_null(mesh.colors);
    assert_null(mesh.normals);
    for (int c = 0; c < 4; c++) assert_true(mesh.colors[4 * 0 + c] == 1.0f);
    assert_true(mesh.colors[4 * 5 + 0] == 1.0f && mesh.colors[4 * 5 + 1] == 0.0f);
    assert_true(fabs(mesh.colors[4 * 9 + 0] - 0.2) < 1e-6 && fabs(mesh.colors[4 * 9 + 3] - 0.8) < 1e-6);
    for (int c = 0; c < 4; c++) assert_true(mesh.colors[4 * 12 + c] == 1.0f);
    lk_mesh_free(&mesh);
}

static void test_interleaved_and_normalized(void **state)
{
    (void)state;
    /* Interleaved vertex: float position (12 bytes), normalized int8 normal
     * (3 bytes + 1 pad), normalized uint16 texcoord (4 bytes): stride 20. */
    unsigned char bytes[3 * 20 + 8] = {0};
    float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    for (int v = 0; v < 3; v++) {
        memcpy(bytes + 20 * v, positions + 3 * v, 12);
        bytes[20 * v + 12] = 0;
        bytes[20 * v + 13] = (unsigned char)(int8_t)-127; /* normal (0,-1,0) */
        bytes[20 * v + 14] = 0;
        uint16_t uv[2] = {65535, (uint16_t)(v * 16384)};
        memcpy(bytes + 20 * v + 16, uv, 4);
    }
    uint16_t indices[3] = {0, 1, 2};
    memcpy(bytes + 60, indices, 6);
    char encoded[128], buffers[256];
    lk_test_base64(bytes, 68, encoded);
    snprintf(buffers, sizeof buffers, "[{\"byteLength\":68,\"uri\":\"data:application/octet-stream;base64,%s\"}]",
             encoded);
    const char *views = "[{\"buffer\":0,\"byteLength\":60,\"byteStride\":20},"
                        "{\"buffer\":0,\"byteOffset\":60,\"byteLength\":6}]";
    const char *accessors =
        "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
        "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"},"
        "{\"bufferView\":0,\"byteOffset\":12,\"componentType\":5120,\"normalized\":true,\"count\":3,\"type\":\"VEC3\"},"
        "{\"bufferView\":0,\"byteOffset\":16,\"componentType\":5123,\"normalized\":true,\"count\":3,\"type\":\"VEC2\"}"
        "]";
    const char *meshes =
        "[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"NORMAL\":2,\"TEXCOORD_0\":3},\"indices\":1}]}]";
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_doc(make_doc(buffers, views, accessors, meshes, NULL), &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 3);
    assert_vec3(mesh.positions + 3, 1, 0, 0);
    assert_vec3(mesh.positions + 6, 0, 1, 0);
    for (int v = 0; v < 3; v++) assert_vec3(mesh.normals + 3 * v, 0, -1, 0);
    /* u = 65535/65535; v is flipped to lodkit's v-up convention. */
    assert_true(fabs(mesh.texcoords[0] - 1.0) < 1e-6 && fabs(mesh.texcoords[1] - 1.0) < 1e-6);
    assert_true(fabs(mesh.texcoords[5] - (1.0 - 32768.0 / 65535.0)) < 1e-6);
    lk_mesh_free(&mesh);

    /* byteOffset 12 + 2 x 20 + 3 = 55 <= 60 fits; 17 + 40 + 4 = 61 does not. */
    const char *bad =
        "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
        "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"},"
        "{\"bufferView\":0,\"byteOffset\":12,\"componentType\":5120,\"normalized\":true,\"count\":3,\"type\":\"VEC3\"},"
        "{\"bufferView\":0,\"byteOffset\":17,\"componentType\":5123,\"normalized\":true,\"count\":3,\"type\":\"VEC2\"}"
        "]";
    expect_doc_error(make_doc(buffers, views, bad, meshes, NULL), LK_ERR_RANGE,
                     "accessors[3]: count 3 exceeds bufferView 0 (60 bytes): byteOffset 17 + 2 x stride 20 + element 4 "
                     "= 61 bytes");
}

static void test_memory_budget(void **state)
{
    (void)state;
    /* The budget holds the document, its small parsed tree (the first 16
     * MiB of parsing are not charged) and the arrays: one instance of
     * 100,000 vertices (1.2 MB of zeros: no bufferView) fits in 2 MiB, a
     * second one does not. */
    lk_read_options options = {.max_bytes = 2 << 20};
    lk_mesh mesh;
    lk_error error = {0};
    const char *one =
        "{\"asset\":{\"version\":\"2.0\"},\"accessors\":[{\"componentType\":5126,\"count\":100000,"
        "\"type\":\"VEC3\"}],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"mode\":0}]}],"
        "\"nodes\":[{\"mesh\":0},{\"mesh\":0}],\"scenes\":[{\"nodes\":[0]}]}";
    assert_int_equal(lk_mesh_read_memory(one, strlen(one), "mem.gltf", LK_FORMAT_AUTO, &options, &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 100000);
    lk_mesh_free(&mesh);
    char two[512];
    snprintf(two, sizeof two, "%s", one);
    memcpy(strstr(two, "\"nodes\":[0]"), "\"nodes\":[0,1]}]}", strlen("\"nodes\":[0,1]}]}") + 1);
    assert_int_equal(lk_mesh_read_memory(two, strlen(two), "mem.gltf", LK_FORMAT_AUTO, &options, &mesh, &error),
                     LK_ERR_LIMIT);
    lk_assert_message_contains(error, "mem.gltf: meshes[0].primitives[0]: the scene reaches 200000 vertices and 0 "
                                      "triangles, more than the memory budget of 2097152 bytes");
}

/* ---- files on disk --------------------------------------------------------------------- */

static void test_external_buffers(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_error error;
    static const char *const good[] = {"gltf/external.gltf", "gltf/escaped_name.gltf"};
    for (int i = 0; i < 2; i++) {
        assert_int_equal(read_path(lk_test_data(good[i]), &mesh, &error), LK_OK);
        assert_int_equal(mesh.vertex_count, 3);
        assert_int_equal(mesh.triangle_count, 1);
        assert_vec3(mesh.positions + 3, 1, 0, 5); /* node translation (0,0,5) */
        lk_mesh_free(&mesh);
    }
    static const struct {
        const char *file;
        lk_status status;
        const char *needle;
    } cases[] = {
        {"gltf/escape.gltf", LK_ERR_UNSUPPORTED,
         "buffers[0].uri: \"../gltf/bin/triangle.bin\": only relative paths inside the model's directory are allowed "
         "(no absolute paths, no \"..\""},
        {"gltf/absolute.gltf", LK_ERR_UNSUPPORTED, "buffers[0].uri: \"/etc/hostname\": only relative paths"},
        {"gltf/remote.gltf", LK_ERR_UNSUPPORTED,
         "\"https://example.com/triangle.bin\": only data: URIs and relative file paths are supported"},
        {"gltf/short_bin.gltf", LK_ERR_RANGE, "buffers[0].byteLength: 48 bytes but \"bin/triangle.bin\" has only 44"},
        {"gltf/missing_bin.gltf", LK_ERR_IO, "buffers[0].uri: cannot open \"bin/no_such_file.bin\""},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *path = lk_test_data(cases[i].file);
        assert_int_equal(read_path(path, &mesh, &error), cases[i].status);
        lk_assert_message_contains(error, path);
        lk_assert_message_contains(error, cases[i].needle);
    }
    /* The same document from memory cannot follow the reference. */
    size_t size;
    unsigned char *data = lk_test_read_file(lk_test_data("gltf/external.gltf"), &size);
    assert_int_equal(read_memory(data, size, "external.gltf", &mesh, &error), LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error,
                               "external.gltf: buffers[0].uri: refers to the external file \"bin/triangle.bin\"");
    free(data);
}

/* ---- GLB built in memory ------------------------------------------------------------------ */

static void put_u32(unsigned char *p, uint32_t value)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(value >> (8 * i));
}

/* A .glb with `json` (space-padded) and, when bin_size > 0, a BIN chunk. */
static unsigned char *build_glb(const char *json, const unsigned char *bin, size_t bin_size, size_t *size)
{
    size_t json_length = strlen(json), json_padded = (json_length + 3) / 4 * 4;
    size_t bin_padded = (bin_size + 3) / 4 * 4;
    *size = 12 + 8 + json_padded + (bin_size ? 8 + bin_padded : 0);
    unsigned char *data = calloc(1, *size);
    assert_non_null(data);
    memcpy(data, "glTF", 4);
    put_u32(data + 4, 2);
    put_u32(data + 8, (uint32_t)*size);
    put_u32(data + 12, (uint32_t)json_padded);
    put_u32(data + 16, 0x4E4F534A);
    memset(data + 20, ' ', json_padded);
    memcpy(data + 20, json, json_length);
    if (bin_size) {
        unsigned char *chunk = data + 20 + json_padded;
        put_u32(chunk, (uint32_t)bin_padded);
        put_u32(chunk + 4, 0x004E4942);
        memcpy(chunk + 8, bin, bin_size);
    }
    return data;
}

static const char *glb_json(void)
{
    return "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":42}],"
           "\"bufferViews\":" TRIANGLE_VIEWS ",\"accessors\":" TRIANGLE_ACCESSORS ",\"meshes\":" TRIANGLE_MESHES "}";
}

static unsigned char *triangle_glb(size_t *size)
{
    unsigned char bin[42] = {0};
    float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint16_t indices[3] = {0, 1, 2};
    memcpy(bin, positions, 36);
    memcpy(bin + 36, indices, 6);
    return build_glb(glb_json(), bin, sizeof bin, size);
}

static void expect_glb_error(const unsigned char *data, size_t size, lk_status status, const char *needle)
{
    lk_mesh mesh;
    lk_error error;
    lk_status got = read_memory(data, size, "mem.glb", &mesh, &error);
    if (got != status)
        fail_msg("expected %s, got %s (%s)", lk_status_string(status), lk_status_string(got), error.message);
    lk_assert_message_contains(error, "mem.glb: ");
    lk_assert_message_contains(error, needle);
}

static void test_glb_in_memory(void **state)
{
    (void)state;
    size_t size;
    unsigned char *glb = triangle_glb(&size);
    lk_mesh mesh;
    lk_error error;
    assert_int_equal(read_memory(glb, size, "mem.glb", &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 3);
    assert_int_equal(mesh.triangle_count, 1);
    assert_vec3(mesh.positions + 6, 0, 1, 0);
    lk_mesh_free(&mesh);
    /* Content sniffing: the magic is enough without an extension. */
    assert_int_equal(read_memory(glb, size, "noextension", &mesh, &error), LK_OK);
    lk_mesh_free(&mesh);

    unsigned char *copy = malloc(size);
    assert_non_null(copy);
    size_t json_chunk = (size_t)(glb[12] | glb[13] << 8);
    size_t bin_header = 20 + json_chunk;

    /* Truncated file: the header length no longer matches. */
    expect_glb_error(glb, size - 4, LK_ERR_PARSE, "byte 8: header says the file has");
    /* Truncated BIN chunk with a consistent header length. */
    memcpy(copy, glb, size);
    put_u32(copy + 8, (uint32_t)(size - 4));
    expect_glb_error(copy, size - 4, LK_ERR_PARSE, "chunk 1 claims 44 bytes but only 40 follow (truncated file)");
    /* Truncated chunk header. */
    memcpy(copy, glb, size);
    put_u32(copy + 8, (uint32_t)(bin_header + 4));
    expect_glb_error(copy, bin_header + 4, LK_ERR_PARSE, "truncated chunk header (4 bytes left, 8 needed)");
    /* Too short for the header. */
    expect_glb_error(glb, 10, LK_ERR_PARSE, "byte 0: file of 10 bytes is too short for the 12-byte GLB header");
    /* Versions. */
    memcpy(copy, glb, size);
    put_u32(copy + 4, 1);
    expect_glb_error(copy, size, LK_ERR_UNSUPPORTED, "byte 4: GLB version 1 (glTF 1.0) is not supported");
    put_u32(copy + 4, 3);
    expect_glb_error(copy, size, LK_ERR_PARSE, "byte 4: unknown GLB version 3");
    /* First chunk not JSON; unaligned chunk length; BIN chunk too short. */
    memcpy(copy, glb, size);
    put_u32(copy + 16, 0x004E4942);
    expect_glb_error(copy, size, LK_ERR_PARSE, "byte 16: first chunk must be JSON");
    memcpy(copy, glb, size);
    put_u32(copy + 12, (uint32_t)json_chunk - 2);
    expect_glb_error(copy, size, LK_ERR_PARSE, "byte 12: chunk 0 length");
    /* Broken JSON inside the chunk: the offset counts from the file start
     * (cJSON stops one byte after the '#' at 21). */
    memcpy(copy, glb, size);
    copy[20 + 1] = '#';
    expect_glb_error(copy, size, LK_ERR_PARSE, "mem.glb: byte 22: invalid JSON (line 1 of the JSON chunk)");
    free(copy);
    free(glb);

    /* No BIN chunk although buffer 0 has no uri. */
    glb = build_glb(glb_json(), NULL, 0, &size);
    expect_glb_error(glb, size, LK_ERR_PARSE, "buffers[0]: has no uri and the .glb file has no BIN chunk");
    free(glb);
    /* BIN chunk shorter than the buffer's byteLength. */
    unsigned char bin[20] = {0};
    glb = build_glb(glb_json(), bin, sizeof bin, &size);
    expect_glb_error(glb, size, LK_ERR_RANGE, "buffers[0].byteLength: 42 bytes but the BIN chunk has only 20");
    free(glb);
}

/* Deterministic pseudo-random numbers for the mutation tests. */
static uint64_t next_random(uint64_t *state)
{
    uint64_t x = (*state += 0x9E3779B97F4A7C15ull);
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

/* Reads `data` and checks the outcome is either a valid mesh or an error
 * that names the input. */
static void read_must_not_crash(const unsigned char *data, size_t size, const char *name, size_t *loaded)
{
    lk_mesh mesh;
    lk_error error;
    lk_status status = read_memory(data, size, name, &mesh, &error);
    if (status == LK_OK) {
        assert_int_equal(lk_mesh_validate(&mesh, NULL), LK_OK);
        (*loaded)++;
        lk_mesh_free(&mesh);
    } else {
        if (strncmp(error.message, name, strlen(name)) != 0)
            fail_msg("error for %s lacks the name: %s", name, error.message);
        assert_null(mesh.positions);
    }
}

static void test_truncations_and_mutations(void **state)
{
    (void)state;
    size_t size, loaded = 0;
    unsigned char *glb = lk_test_read_file(lk_test_sample(GLTF_DIR "BoxTextured-glTF-Binary/BoxTextured.glb"), &size);
    unsigned char *copy = malloc(size);
    assert_non_null(copy);
    /* Every prefix, with the header length patched to match so that the
     * chunk and JSON checks are reached. */
    for (size_t cut = 0; cut < size; cut++) {
        memcpy(copy, glb, cut);
        if (cut >= 12) put_u32(copy + 8, (uint32_t)cut);
        read_must_not_crash(copy, cut, "cut.glb", &loaded);
    }
    assert_int_equal(loaded, 0);
    /* Random byte changes: anything may happen except a crash, a leak or an
     * invalid mesh. */
    uint64_t random_state = 42;
    for (int round = 0; round < 3000; round++) {
        memcpy(copy, glb, size);
        int changes = 1 + (int)(next_random(&random_state) % 4);
        for (int c = 0; c < changes; c++) {
            size_t at = (size_t)(next_random(&random_state) % size);
            copy[at] = (unsigned char)next_random(&random_state);
        }
        read_must_not_crash(copy, size, "mutated.glb", &loaded);
    }
    /* Most changes hit the BIN chunk's image bytes or harmless JSON text. */
    assert_true(loaded > 0);
    free(copy);
    free(glb);

    /* The same on the JSON text with an embedded base64 buffer, mutating
     * only JSON-significant characters to reach deeper paths. */
    unsigned char *text =
        lk_test_read_file(lk_test_sample(GLTF_DIR "BoxTextured-glTF-Embedded/BoxTextured.gltf"), &size);
    copy = malloc(size);
    assert_non_null(copy);
    static const char alphabet[] = "0123456789-.e\"{}[],:tfn ";
    loaded = 0;
    for (int round = 0; round < 3000; round++) {
        memcpy(copy, text, size);
        size_t at = (size_t)(next_random(&random_state) % size);
        copy[at] = (unsigned char)alphabet[next_random(&random_state) % (sizeof alphabet - 1)];
        read_must_not_crash(copy, size, "mutated.gltf", &loaded);
    }
    assert_true(loaded > 0);
    free(copy);
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_box_textured_three_encodings),
        cmocka_unit_test(test_2cylinder_engine_glb),
        cmocka_unit_test(test_other_sample_models),
        cmocka_unit_test(test_primitive_modes),
        cmocka_unit_test(test_scene_lines),
        cmocka_unit_test(test_refused_samples),
        cmocka_unit_test(test_every_sample_file),
        cmocka_unit_test(test_memory_triangle),
        cmocka_unit_test(test_node_transforms),
        cmocka_unit_test(test_scene_graph_errors),
        cmocka_unit_test(test_deep_node_chain),
        cmocka_unit_test(test_accessor_validation),
        cmocka_unit_test(test_base64_errors),
        cmocka_unit_test(test_primitive_validation),
        cmocka_unit_test(test_document_errors),
        cmocka_unit_test(test_strips_fans_points_and_mixed_attributes),
        cmocka_unit_test(test_interleaved_and_normalized),
        cmocka_unit_test(test_memory_budget),
        cmocka_unit_test(test_external_buffers),
        cmocka_unit_test(test_glb_in_memory),
        cmocka_unit_test(test_truncations_and_mutations),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
