/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: scenes (lk_scene; src/scene.c,
 * src/io_gltf_scene.c, the scene writer in src/io_gltf_mesh_write.c) on a
 * scene built here: a node tree with translation / rotation / mirroring /
 * matrix transforms, a mesh of two primitives with two materials used by
 * two nodes, a textured sphere with a texture seam, a texture, sampler,
 * image and camera.
 *   - .glb and .gltf round trips keep everything exactly (positions bit for
 *     bit; texture coordinates and tangents within a float rounding);
 *   - lk_scene_flatten places the primitives as the flat glTF reader does
 *     (the same triangles, mirrored winding included);
 *   - quantised output: a mesh on a node with children moves to a new
 *     child node, and the scene as drawn stays within the grid's step;
 *   - lk_scene_simplify keeps texture seams closed (the copies of a seam
 *     vertex move together), the attributes and the tangents;
 *   - refusals: external images from memory, a material whose JSON does
 *     not parse. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

static char *copy_text(const char *text)
{
    char *copy = malloc(strlen(text) + 1);
    assert_non_null(copy);
    strcpy(copy, text);
    return copy;
}

/* The textured sphere of shapes.c with its tangents and material 0. */
static void textured_sphere(lk_scene_primitive *primitive, unsigned slices, unsigned stacks)
{
    shape_textured_sphere(&primitive->mesh, slices, stacks, &primitive->tangents);
    primitive->material = 0;
}

static void set_trs(lk_scene_node *node, const double t[3], const double r[4], const double s[3])
{
    memcpy(node->translation, t, sizeof node->translation);
    memcpy(node->rotation, r, sizeof node->rotation);
    memcpy(node->scale, s, sizeof node->scale);
    double x = r[0], y = r[1], z = r[2], w = r[3];
    double m[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    for (int c = 0; c < 3; c++) {
        for (int row = 0; row < 3; row++) node->matrix[4 * c + row] = m[3 * c + row] * s[c];
        node->matrix[4 * c + 3] = 0;
    }
    for (int row = 0; row < 3; row++) node->matrix[12 + row] = t[row];
    node->matrix[15] = 1;
}

/* nodes: 0 "root" (translated; children 1, 2, 3), 1 "sphere" (rotated,
 * mesh 1), 2 "mirror" (scale -1 in x, mesh 0, child 4), 3 "matrix" (a
 * matrix, mesh 0 again), 4 "camera". Mesh 0: two boxes, two materials. */
static void build_scene(lk_scene *scene)
{
    lk_scene_init(scene);
    scene->node_count = 5;
    scene->nodes = calloc(5, sizeof *scene->nodes);
    scene->root_count = 1;
    scene->roots = calloc(1, sizeof *scene->roots);
    scene->mesh_count = 2;
    scene->meshes = calloc(2, sizeof *scene->meshes);
    assert_true(scene->nodes && scene->roots && scene->meshes);
    for (size_t i = 0; i < 5; i++) {
        lk_scene_node *node = &scene->nodes[i];
        node->mesh = node->camera = -1;
        node->rotation[3] = 1;
        node->scale[0] = node->scale[1] = node->scale[2] = 1;
        for (int k = 0; k < 4; k++) node->matrix[5 * k] = 1;
    }
    static const char *const names[] = {"root", "sphere", "mirror", "matrix", "camera"};
    for (size_t i = 0; i < 5; i++) scene->nodes[i].name = copy_text(names[i]);
    scene->nodes[0].children = calloc(3, sizeof(uint32_t));
    scene->nodes[0].child_count = 3;
    for (uint32_t c = 0; c < 3; c++) scene->nodes[0].children[c] = c + 1;
    set_trs(&scene->nodes[0], (double[]){10, 0, -2}, (double[]){0, 0, 0, 1}, (double[]){1, 1, 1});
    double half = sqrt(0.5);
    set_trs(&scene->nodes[1], (double[]){0, 3, 0}, (double[]){0, half, 0, half}, (double[]){2, 2, 2});
    scene->nodes[1].mesh = 1;
    set_trs(&scene->nodes[2], (double[]){-4, 0, 0}, (double[]){0, 0, 0, 1}, (double[]){-1, 1, 1});
    scene->nodes[2].mesh = 0;
    scene->nodes[2].children = calloc(1, sizeof(uint32_t));
    scene->nodes[2].children[0] = 4;
    scene->nodes[2].child_count = 1;
    scene->nodes[3].has_matrix = 1;
    static const double matrix[16] = {0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 5, 1, 2, 1};
    memcpy(scene->nodes[3].matrix, matrix, sizeof matrix);
    scene->nodes[3].mesh = 0;
    scene->nodes[3].extras = copy_text("{\"note\":\"kept\"}");
    scene->nodes[4].camera = 0;

    lk_scene_mesh *boxes = &scene->meshes[0];
    boxes->name = copy_text("boxes");
    boxes->primitives = calloc(2, sizeof *boxes->primitives);
    boxes->primitive_count = 2;
    shape_box(&boxes->primitives[0].mesh, 1, 2, 3, 2);
    shape_box(&boxes->primitives[1].mesh, 0.5, 0.5, 0.5, 1);
    lk_mesh_translate(&boxes->primitives[1].mesh, 2, 0, 0);
    boxes->primitives[0].material = 1;
    boxes->primitives[1].material = -1;
    scene->meshes[1].primitives = calloc(1, sizeof(lk_scene_primitive));
    scene->meshes[1].primitive_count = 1;
    textured_sphere(&scene->meshes[1].primitives[0], 24, 12);

    scene->material_count = 2;
    scene->materials = calloc(2, sizeof *scene->materials);
    scene->materials[0].json = copy_text("{\"name\":\"textured\",\"pbrMetallicRoughness\":{\"baseColorTexture\":"
                                         "{\"index\":0},\"metallicFactor\":0},\"doubleSided\":true}");
    scene->materials[0].base_color_texture = 0;
    scene->materials[1].json =
        copy_text("{\"name\":\"red\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[1,0,0,1]},"
                  "\"extensions\":{\"KHR_materials_emissive_strength\":{\"emissiveStrength\":2}}}");
    scene->materials[1].base_color_texture = -1;
    scene->texture_count = 1;
    scene->textures = calloc(1, sizeof *scene->textures);
    scene->textures[0].json = copy_text("{\"sampler\":0,\"source\":0}");
    scene->sampler_count = 1;
    scene->samplers = calloc(1, sizeof(char *));
    scene->samplers[0] = copy_text("{\"magFilter\":9729,\"wrapS\":33648}");
    scene->camera_count = 1;
    scene->cameras = calloc(1, sizeof(char *));
    scene->cameras[0] = copy_text("{\"type\":\"perspective\",\"perspective\":{\"yfov\":0.8,\"znear\":0.1}}");
    scene->image_count = 1;
    scene->images = calloc(1, sizeof *scene->images);
    static const unsigned char png[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0,
                                        0,    0,   13,  'I', 'H',  'D',  'R',  7};
    scene->images[0].data = malloc(sizeof png);
    memcpy(scene->images[0].data, png, sizeof png);
    scene->images[0].size = sizeof png;
    scene->images[0].mime_type = copy_text("image/png");
    scene->images[0].name = copy_text("logo");
}

static void assert_floats_near(const float *a, const float *b, size_t count, float tolerance)
{
    for (size_t i = 0; i < count; i++)
        if (fabsf(a[i] - b[i]) > tolerance) fail_msg("value %zu: %.9g vs %.9g", i, (double)a[i], (double)b[i]);
}

static void assert_same_scene(const lk_scene *a, const lk_scene *b)
{
    assert_int_equal(a->node_count, b->node_count);
    assert_int_equal(a->root_count, b->root_count);
    for (size_t i = 0; i < a->node_count; i++) {
        const lk_scene_node *x = &a->nodes[i], *y = &b->nodes[i];
        assert_string_equal(x->name, y->name);
        assert_int_equal(x->mesh, y->mesh);
        assert_int_equal(x->camera, y->camera);
        assert_int_equal(x->child_count, y->child_count);
        for (size_t c = 0; c < x->child_count; c++) assert_int_equal(x->children[c], y->children[c]);
        for (int k = 0; k < 16; k++) assert_true(fabs(x->matrix[k] - y->matrix[k]) < 1e-6);
        assert_int_equal(x->has_matrix, y->has_matrix);
    }
    assert_string_equal(b->nodes[3].extras, "{\"note\":\"kept\"}");
    assert_int_equal(a->mesh_count, b->mesh_count);
    for (size_t m = 0; m < a->mesh_count; m++) {
        assert_int_equal(a->meshes[m].primitive_count, b->meshes[m].primitive_count);
        for (size_t p = 0; p < a->meshes[m].primitive_count; p++) {
            const lk_scene_primitive *x = &a->meshes[m].primitives[p], *y = &b->meshes[m].primitives[p];
            assert_int_equal(x->material, y->material);
            assert_int_equal(x->mesh.vertex_count, y->mesh.vertex_count);
            assert_int_equal(x->mesh.triangle_count, y->mesh.triangle_count);
            /* equal floats (a -0 may come back as +0) */
            assert_floats_near(x->mesh.positions, y->mesh.positions, 3 * x->mesh.vertex_count, 0.0f);
            assert_memory_equal(x->mesh.indices, y->mesh.indices, 3 * x->mesh.triangle_count * sizeof(uint32_t));
            assert_int_equal(x->mesh.texcoords != NULL, y->mesh.texcoords != NULL);
            if (x->mesh.texcoords)
                assert_floats_near(x->mesh.texcoords, y->mesh.texcoords, 2 * x->mesh.vertex_count, 1e-6f);
            assert_int_equal(x->tangents != NULL, y->tangents != NULL);
            if (x->tangents) assert_floats_near(x->tangents, y->tangents, 4 * x->mesh.vertex_count, 1e-6f);
        }
    }
    assert_int_equal(a->material_count, b->material_count);
    for (size_t i = 0; i < a->material_count; i++) {
        assert_string_equal(a->materials[i].json, b->materials[i].json);
        assert_int_equal(a->materials[i].base_color_texture, b->materials[i].base_color_texture);
    }
    assert_int_equal(a->texture_count, b->texture_count);
    assert_string_equal(a->textures[0].json, b->textures[0].json);
    assert_int_equal(b->textures[0].image, 0);
    assert_int_equal(b->textures[0].sampler, 0);
    assert_string_equal(a->samplers[0], b->samplers[0]);
    assert_string_equal(a->cameras[0], b->cameras[0]);
    assert_int_equal(a->image_count, b->image_count);
    assert_int_equal(a->images[0].size, b->images[0].size);
    assert_memory_equal(a->images[0].data, b->images[0].data, a->images[0].size);
    assert_string_equal(b->images[0].mime_type, "image/png");
    assert_string_equal(b->images[0].name, "logo");
}

static void test_scene_round_trip(void **state)
{
    (void)state;
    lk_scene scene, back;
    build_scene(&scene);
    lk_error error = {0};
    static const char *const names[] = {"scene.glb", "scene.gltf"};
    for (int i = 0; i < 2; i++) {
        const char *path = lk_test_tmpfile(names[i]);
        assert_int_equal(lk_scene_write(path, &scene, NULL, &error), LK_OK);
        assert_int_equal(lk_scene_read(path, NULL, &back, &error), LK_OK);
        assert_same_scene(&scene, &back);
        assert_null(back.notes);
        lk_scene_free(&back);
    }
    /* The textured material's name survives in the decoded value too. */
    lk_scene_free(&scene);
}

/* Triangles as sorted lists of nine rounded coordinates: equal lists mean
 * the same triangles (orientation kept) whatever the order. */
typedef struct triangle_key {
    long p[9];
} triangle_key;

static int compare_keys(const void *a, const void *b) { return memcmp(a, b, sizeof(triangle_key)); }

static triangle_key *triangle_keys(const lk_mesh *mesh)
{
    triangle_key *keys = calloc(mesh->triangle_count, sizeof *keys);
    assert_non_null(keys);
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        long corner[3][3];
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                corner[c][k] = lround(mesh->positions[3 * (size_t)mesh->indices[3 * t + (size_t)c] + (size_t)k] * 1e4);
        int first = 0;
        for (int c = 1; c < 3; c++)
            if (memcmp(corner[c], corner[first], sizeof corner[0]) < 0) first = c;
        for (int c = 0; c < 3; c++) memcpy(keys[t].p + 3 * c, corner[(first + c) % 3], sizeof corner[0]);
    }
    qsort(keys, mesh->triangle_count, sizeof *keys, compare_keys);
    return keys;
}

static void test_scene_flatten(void **state)
{
    (void)state;
    lk_scene scene;
    build_scene(&scene);
    lk_error error = {0};
    const char *path = lk_test_tmpfile("flatten.glb");
    assert_int_equal(lk_scene_write(path, &scene, NULL, &error), LK_OK);
    lk_mesh flat, read;
    assert_int_equal(lk_scene_flatten(&scene, &flat, &error), LK_OK);
    lk_test_load(path, &read);
    /* mesh 0 twice (two primitives each), the sphere once */
    size_t boxes =
        scene.meshes[0].primitives[0].mesh.triangle_count + scene.meshes[0].primitives[1].mesh.triangle_count;
    assert_int_equal(flat.triangle_count, 2 * boxes + scene.meshes[1].primitives[0].mesh.triangle_count);
    assert_int_equal(read.triangle_count, flat.triangle_count);
    triangle_key *a = triangle_keys(&flat), *b = triangle_keys(&read);
    assert_memory_equal(a, b, flat.triangle_count * sizeof *a);
    free(a), free(b);
    /* the mirrored boxes stay outward: the volume is positive and equals
     * the unmirrored scene's (boxes 6 and 0.125, twice; sphere ~ 8 * 4.1) */
    assert_true(shape_volume(&flat) > 2 * 6.125 + 30);
    assert_int_equal(lk_scene_triangle_count(&scene), boxes + scene.meshes[1].primitives[0].mesh.triangle_count);
    lk_mesh_free(&flat);
    lk_mesh_free(&read);
    lk_scene_free(&scene);
}

static void test_scene_quantized(void **state)
{
    (void)state;
    lk_scene scene, back;
    build_scene(&scene);
    lk_error error = {0};
    lk_write_options options = {0};
    options.gltf_flags = LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT;
    const char *path = lk_test_tmpfile("quantized.glb");
    assert_int_equal(lk_scene_write(path, &scene, &options, &error), LK_OK);
    assert_int_equal(lk_scene_read(path, NULL, &back, &error), LK_OK);
    /* node 2 ("mirror") has a child: its mesh moved to a new child node */
    assert_int_equal(back.node_count, scene.node_count + 1);
    assert_int_equal(back.nodes[2].mesh, -1);
    assert_int_equal(back.nodes[2].child_count, 2);
    assert_int_equal(back.nodes[back.nodes[2].children[1]].mesh, 0);
    assert_int_equal(back.nodes[3].mesh, 0);
    lk_mesh flat, flat_back;
    assert_int_equal(lk_scene_flatten(&scene, &flat, &error), LK_OK);
    assert_int_equal(lk_scene_flatten(&back, &flat_back, &error), LK_OK);
    assert_int_equal(flat.triangle_count, flat_back.triangle_count);
    lk_metro_result metro = shape_metro(&flat, &flat_back, 2);
    double diagonal = lk_mesh_bounds(&flat, NULL, NULL);
    /* 14-bit grids over meshes at most ~6 units wide, scaled by 2 at most */
    assert_true(metro.hausdorff < 2 * 6.0 / 16383 * 2);
    assert_true(metro.hausdorff < 1e-3 * diagonal);
    lk_mesh_free(&flat);
    lk_mesh_free(&flat_back);
    lk_scene_free(&back);
    lk_scene_free(&scene);
}

static size_t welded_boundary_edges(const lk_mesh *mesh)
{
    lk_mesh copy;
    assert_int_equal(lk_mesh_copy(&copy, mesh, NULL), LK_OK);
    assert_int_equal(lk_mesh_weld(&copy, 0, NULL, NULL), LK_OK);
    lk_mesh_stats stats = shape_stats(&copy);
    lk_mesh_free(&copy);
    return stats.boundary_edge_count;
}

static void test_scene_simplify_keeps_seams(void **state)
{
    (void)state;
    lk_scene scene;
    build_scene(&scene);
    lk_error error = {0};
    lk_scene_primitive *sphere = &scene.meshes[1].primitives[0];
    size_t before = sphere->mesh.triangle_count;
    assert_int_equal(welded_boundary_edges(&sphere->mesh), 0);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.2;
    lk_scene_simplify_stats stats;
    assert_int_equal(lk_scene_simplify(&scene, LK_SIMPLIFY_QEM, &options, &stats, &error), LK_OK);
    assert_int_equal(stats.primitives, 3);
    size_t after = sphere->mesh.triangle_count;
    assert_true(after <= before / 5 + 2 && after >= before / 6);
    /* seam copies moved together: welded by position the sphere is closed */
    assert_int_equal(welded_boundary_edges(&sphere->mesh), 0);
    /* and the seam is still a seam: no triangle spans the texture (a
     * corner given the u = 0 copy on the u = 1 side would stretch it
     * across the whole image), and some position has both copies */
    const lk_mesh *out = &sphere->mesh;
    /* (triangles away from the poles, where 20% leaves them a few grid
     * cells wide; a pole's fan may legitimately span half the image) */
    size_t checked = 0;
    for (size_t t = 0; t < out->triangle_count; t++) {
        float low = 1, high = 0;
        bool polar = false;
        for (int c = 0; c < 3; c++) {
            size_t v = out->indices[3 * t + (size_t)c];
            float u = out->texcoords[2 * v];
            low = u < low ? u : low, high = u > high ? u : high;
            polar = polar || fabsf(out->positions[3 * v + 1]) > 0.8f;
        }
        if (polar) continue;
        checked++;
        if (high - low > 0.4f) fail_msg("triangle %zu spans u %g .. %g", t, (double)low, (double)high);
    }
    assert_true(checked > out->triangle_count / 3);
    size_t seam_pairs = 0;
    for (size_t a = 0; a < out->vertex_count; a++)
        for (size_t b = 0; b < out->vertex_count; b++)
            if (out->texcoords[2 * a] == 0.0f && out->texcoords[2 * b] == 1.0f &&
                !memcmp(out->positions + 3 * a, out->positions + 3 * b, 3 * sizeof(float)))
                seam_pairs++;
    assert_true(seam_pairs >= 1);
    assert_non_null(sphere->mesh.normals);
    assert_non_null(sphere->tangents);
    /* each output vertex's tangent is that of an input vertex: unit, w = 1 */
    for (size_t v = 0; v < sphere->mesh.vertex_count; v++) {
        const float *t = sphere->tangents + 4 * v;
        assert_true(fabsf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2] - 1) < 1e-5f && t[3] == 1);
    }
    assert_true(stats.triangles_out < stats.triangles_in / 3);
    /* the sphere still looks like one */
    double centre[3] = {0, 0, 0};
    assert_true(shape_sphere_deviation(&sphere->mesh, centre, 1.0) < 0.1);
    lk_scene_free(&scene);
}

/* A scene that draws nothing (no root node) still simplifies: its
 * primitives cannot be judged as drawn, so lk_scene_simplify runs QEM once
 * (regression: the run without the crease constraints measured both
 * against the empty drawing and failed, "surface index: the mesh has no
 * vertices", on 3 inputs of the gltfscene fuzz corpus). */
static void test_scene_simplify_undrawn(void **state)
{
    (void)state;
    lk_scene scene;
    build_scene(&scene);
    scene.root_count = 0;
    lk_mesh flat;
    lk_error error = {0};
    assert_int_equal(lk_scene_flatten(&scene, &flat, &error), LK_OK);
    assert_int_equal(flat.vertex_count, 0);
    lk_mesh_free(&flat);
    size_t before = lk_scene_triangle_count(&scene);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.5;
    lk_scene_simplify_stats stats;
    assert_int_equal(lk_scene_simplify(&scene, LK_SIMPLIFY_QEM, &options, &stats, &error), LK_OK);
    assert_int_equal(stats.primitives, 3);
    assert_true(lk_scene_triangle_count(&scene) <= before / 2 + 3);
    lk_scene_free(&scene);
}

static void test_scene_refusals(void **state)
{
    (void)state;
    lk_scene scene;
    lk_error error = {0};
    static const char gltf[] = "{\"asset\":{\"version\":\"2.0\"},\"images\":[{\"uri\":\"logo.png\"}],"
                               "\"textures\":[{\"source\":0}]}";
    assert_int_equal(lk_scene_read_memory(gltf, strlen(gltf), "memory.gltf", NULL, &scene, &error), LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "images[0]");
    lk_assert_message_contains(error, "cannot be read when reading from memory");
    assert_int_equal(scene.node_count, 0);
    static const char crossed[] = "{\"asset\":{\"version\":\"2.0\"},\"textures\":[{\"source\":2}],\"images\":[]}";
    assert_int_equal(lk_scene_read_memory(crossed, strlen(crossed), "memory.gltf", NULL, &scene, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "textures[0].source: images 2 out of range (0 images)");
    /* a material whose JSON is not an object: refused, no file */
    build_scene(&scene);
    free(scene.materials[1].json);
    scene.materials[1].json = copy_text("[1, 2");
    const char *path = lk_test_tmpfile("refused.glb");
    assert_int_equal(lk_scene_write(path, &scene, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "materials[1]");
    FILE *file = fopen(path, "rb");
    assert_null(file);
    lk_scene_free(&scene);
}

/* ---- skins and animations ------------------------------------------------ */

static void base64(const unsigned char *bytes, size_t size, char *out)
{
    static const char digits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (size_t i = 0; i < size; i += 3) {
        uint32_t group = (uint32_t)bytes[i] << 16 | (i + 1 < size ? (uint32_t)bytes[i + 1] << 8 : 0) |
                         (i + 2 < size ? bytes[i + 2] : 0);
        *out++ = digits[group >> 18 & 63];
        *out++ = digits[group >> 12 & 63];
        *out++ = i + 1 < size ? digits[group >> 6 & 63] : '=';
        *out++ = i + 2 < size ? digits[group & 63] : '=';
    }
    *out = '\0';
}

/* A skinned triangle (node 0) on joints nodes 1 and 2 with one animation
 * moving node 1; `vertex2_joint` is the joint of its last vertex and the
 * other arguments replace the skin's joints, the sampler's input and the
 * channel's sampler. */
static char *skinned_gltf(unsigned vertex2_joint, const char *joints, const char *input, const char *sampler)
{
    unsigned char buffer[128] = {0};
    static const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    static const float weights[12] = {1, 0, 0, 0, 0.5f, 0.5f, 0, 0, 1, 0, 0, 0};
    static const float times[2] = {0, 1};
    static const float translations[6] = {0, 0, 0, 0, 2, 0};
    memcpy(buffer, positions, sizeof positions);
    unsigned char joint_bytes[12] = {0, 0, 0, 0, 0, 1, 0, 0, (unsigned char)vertex2_joint, 0, 0, 0};
    memcpy(buffer + 36, joint_bytes, sizeof joint_bytes);
    memcpy(buffer + 48, weights, sizeof weights);
    memcpy(buffer + 96, times, sizeof times);
    memcpy(buffer + 104, translations, sizeof translations);
    char data[200];
    base64(buffer, sizeof buffer, data);
    char *text = malloc(4096);
    assert_non_null(text);
    snprintf(text, 4096,
             "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0,1]}],"
             "\"nodes\":[{\"mesh\":0,\"skin\":0},{\"name\":\"hip\",\"children\":[2]},{\"translation\":[0,1,0]}],"
             "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"JOINTS_0\":1,\"WEIGHTS_0\":2}}]}],"
             "\"skins\":[{\"joints\":%s,\"skeleton\":1}],"
             "\"animations\":[{\"name\":\"lift\",\"samplers\":[{\"input\":%s,\"output\":4}],"
             "\"channels\":[{\"sampler\":%s,\"target\":{\"node\":1,\"path\":\"translation\"}}]}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\","
             "\"min\":[0,0,0],\"max\":[1,1,0]},"
             "{\"bufferView\":0,\"byteOffset\":36,\"componentType\":5121,\"count\":3,\"type\":\"VEC4\"},"
             "{\"bufferView\":0,\"byteOffset\":48,\"componentType\":5126,\"count\":3,\"type\":\"VEC4\"},"
             "{\"bufferView\":0,\"byteOffset\":96,\"componentType\":5126,\"count\":2,\"type\":\"SCALAR\","
             "\"min\":[0],\"max\":[1]},"
             "{\"bufferView\":0,\"byteOffset\":104,\"componentType\":5126,\"count\":2,\"type\":\"VEC3\"}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteLength\":128}],"
             "\"buffers\":[{\"byteLength\":128,\"uri\":\"data:application/octet-stream;base64,%s\"}]}",
             joints, input, sampler, data);
    return text;
}

static lk_status read_text(const char *text, lk_scene *scene, lk_error *error)
{
    return lk_scene_read_memory(text, strlen(text), "skin.gltf", NULL, scene, error);
}

static void test_scene_skins_and_animations(void **state)
{
    (void)state;
    lk_scene scene, back;
    lk_error error = {0};
    char *text = skinned_gltf(1, "[1,2]", "3", "0");
    assert_int_equal(read_text(text, &scene, &error), LK_OK);
    free(text);
    assert_null(scene.notes);
    assert_int_equal(scene.skin_count, 1);
    assert_int_equal(scene.skins[0].joint_count, 2);
    assert_int_equal(scene.skins[0].joints[1], 2);
    assert_int_equal(scene.skins[0].skeleton, 1);
    assert_null(scene.skins[0].inverse_bind_matrices);
    assert_int_equal(scene.nodes[0].skin, 0);
    assert_int_equal(scene.nodes[1].skin, -1);
    const lk_scene_primitive *primitive = &scene.meshes[0].primitives[0];
    static const uint16_t joints[12] = {0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0};
    assert_memory_equal(primitive->joints, joints, sizeof joints);
    assert_true(primitive->weights[4] == 0.5f && primitive->weights[8] == 1.0f);
    assert_int_equal(scene.animation_count, 1);
    const lk_scene_animation *animation = &scene.animations[0];
    assert_string_equal(animation->name, "lift");
    assert_int_equal(animation->channel_count, 1);
    assert_int_equal(animation->channels[0].node, 1);
    assert_int_equal(animation->channels[0].path, LK_SCENE_PATH_TRANSLATION);
    assert_int_equal(animation->samplers[0].key_count, 2);
    assert_int_equal(animation->samplers[0].components, 3);
    assert_true(animation->samplers[0].input[1] == 1.0f && animation->samplers[0].output[4] == 2.0f);

    /* written (plain and compact) and read back: the same skins, joints,
     * weights and keys. Compact output puts the skinned mesh's positions on
     * a 14-bit grid whose transform its skin's inverse bind matrices carry
     * (identities before), the weights in bytes: equal within a step. */
    for (int compact = 0; compact < 2; compact++) {
        lk_write_options options = {0};
        options.gltf_flags = compact ? LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT : 0;
        const char *path = lk_test_tmpfile("skin.glb");
        assert_int_equal(lk_scene_write(path, &scene, &options, &error), LK_OK);
        assert_int_equal(lk_scene_read(path, NULL, &back, &error), LK_OK);
        assert_int_equal(back.node_count, 3);
        assert_int_equal(back.nodes[0].skin, 0);
        assert_int_equal(back.nodes[0].has_matrix, 0);
        assert_true(back.nodes[0].scale[0] == 1.0 && back.nodes[0].translation[0] == 0.0);
        assert_int_equal(back.skin_count, 1);
        assert_memory_equal(back.skins[0].joints, scene.skins[0].joints, 2 * sizeof(uint32_t));
        const lk_scene_primitive *read = &back.meshes[0].primitives[0];
        assert_int_equal(read->mesh.vertex_count, 3);
        const float *bind = back.skins[0].inverse_bind_matrices;
        assert_true(compact ? bind != NULL : bind == NULL);
        if (compact) assert_memory_equal(bind, bind + 16, 16 * sizeof(float));
        /* compact output may reorder the vertices: compare as sets */
        for (size_t v = 0; v < 3; v++) {
            size_t w = 0;
            for (; w < 3; w++) {
                double distance = 0;
                for (int row = 0; row < 3; row++) {
                    const float *q = read->mesh.positions + 3 * w;
                    double x =
                        bind ? bind[row] * q[0] + bind[4 + row] * q[1] + bind[8 + row] * q[2] + bind[12 + row] : q[row];
                    distance = fmax(distance, fabs(x - primitive->mesh.positions[3 * v + (size_t)row]));
                }
                if (distance <= (compact ? 0.5 / 16383 : 0.0)) break;
            }
            assert_true(w < 3);
            assert_memory_equal(read->joints + 4 * w, primitive->joints + 4 * v, 4 * sizeof(uint16_t));
            for (int k = 0; k < 4; k++)
                assert_true(fabsf(read->weights[4 * w + (size_t)k] - primitive->weights[4 * v + (size_t)k]) <=
                            (compact ? 1.0f / 255 : 0.0f));
        }
        assert_int_equal(back.animation_count, 1);
        assert_memory_equal(back.animations[0].samplers[0].input, animation->samplers[0].input, 2 * sizeof(float));
        assert_memory_equal(back.animations[0].samplers[0].output, animation->samplers[0].output, 6 * sizeof(float));
        assert_memory_equal(back.animations[0].channels, animation->channels, sizeof *animation->channels);
        lk_scene_free(&back);
    }
    lk_scene_copy(&back, &scene, &error);
    assert_memory_equal(back.meshes[0].primitives[0].joints, joints, sizeof joints);
    assert_string_equal(back.animations[0].name, "lift");
    lk_scene_free(&back);
    lk_scene_free(&scene);

    /* bad input names the item */
    text = skinned_gltf(2, "[1,2]", "3", "0");
    assert_int_equal(read_text(text, &scene, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error,
                               "skin.gltf: nodes[0].skin: meshes[0].primitives[0] vertex 2 uses joint 2 but skins[0] "
                               "has 2 joints");
    free(text);
    text = skinned_gltf(1, "[1,40]", "3", "0");
    assert_int_equal(read_text(text, &scene, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "skin.gltf: skins[0].joints[1]: node 40 out of range (3 nodes)");
    free(text);
    text = skinned_gltf(1, "[1,2]", "9", "0");
    assert_int_equal(read_text(text, &scene, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error,
                               "skin.gltf: animations[0].samplers[0].input: accessor 9 out of range (5 accessors)");
    free(text);
    text = skinned_gltf(1, "[1,2]", "3", "1");
    assert_int_equal(read_text(text, &scene, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error,
                               "skin.gltf: animations[0].channels[0].sampler: sampler 1 out of range (1 sampler)");
    free(text);
    /* key times from a VEC3 accessor */
    text = skinned_gltf(1, "[1,2]", "0", "0");
    assert_int_equal(read_text(text, &scene, &error), LK_ERR_PARSE);
    lk_assert_message_contains(error, "animations[0].samplers[0].input needs a SCALAR");
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_scene_round_trip),       cmocka_unit_test(test_scene_flatten),
        cmocka_unit_test(test_scene_quantized),        cmocka_unit_test(test_scene_simplify_keeps_seams),
        cmocka_unit_test(test_scene_refusals),         cmocka_unit_test(test_scene_skins_and_animations),
        cmocka_unit_test(test_scene_simplify_undrawn),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
