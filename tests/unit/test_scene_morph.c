/* SPDX-License-Identifier: MIT */
/* glTF morph targets in scenes (issue 20): read, written back and
 * simplified with every target's shape in the cost (src/io_gltf_scene.c,
 * src/io_gltf_mesh_write.c, src/scene.c).
 *   - AnimatedMorphCube (assimp-testmodels): 2 targets with POSITION, NORMAL
 *     and TANGENT deltas, default weights, an animation of the weights;
 *     written and read back bit for bit;
 *   - faerie.md2's key frames 0, 45, 90, 135 and 180 as a base and 4 targets
 *     (written by lk_animation_write, read as a scene): simplified, each
 *     shape (base + target at full weight) measured with Metro against the
 *     input's same shape, and against a simplification that ranks the
 *     collapses by the base alone and carries each surviving vertex's
 *     deltas (what ignoring the targets gives);
 *   - sparse accessors in targets are read. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *cube_path(void)
{
    return lk_test_sample("assimp/glTF2/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf");
}

static void read_scene(const char *path, lk_scene *scene)
{
    lk_error error = {0};
    lk_status status = lk_scene_read(path, NULL, scene, &error);
    if (status != LK_OK) fail_msg("%s", error.message);
}

static void test_cube_round_trip(void **state)
{
    (void)state;
    lk_scene scene;
    read_scene(cube_path(), &scene);
    assert_null(scene.notes); /* nothing dropped */
    assert_int_equal(scene.mesh_count, 1);
    const lk_scene_mesh *mesh = &scene.meshes[0];
    assert_int_equal(mesh->target_count, 2);
    assert_non_null(mesh->weights);
    assert_true(mesh->weights[0] == 0.0f && mesh->weights[1] == 0.0f);
    const lk_scene_primitive *primitive = &mesh->primitives[0];
    assert_non_null(primitive->target_positions);
    assert_non_null(primitive->target_normals);
    assert_non_null(primitive->target_tangents);
    /* "thin" moves the top face up by at most 0.0189, "angle" by 0.0199
     * (the accessors' max) */
    float highest[2] = {0, 0};
    for (size_t k = 0; k < 2; k++)
        for (size_t v = 0; v < 24; v++)
            highest[k] = fmaxf(highest[k], primitive->target_positions[3 * (k * 24 + v) + 1]);
    assert_float_equal(highest[0], 0.01893253f, 1e-7);
    assert_float_equal(highest[1], 0.0198908355f, 1e-7);
    assert_int_equal(scene.animation_count, 1);
    const lk_scene_animation *animation = &scene.animations[0];
    assert_int_equal(animation->channel_count, 1);
    assert_int_equal(animation->channels[0].path, LK_SCENE_PATH_WEIGHTS);
    assert_int_equal(animation->samplers[0].key_count, 127);
    assert_int_equal(animation->samplers[0].output_count, 254);
    assert_int_equal(animation->samplers[0].components, 1);

    const char *formats[] = {"cube.glb", "cube.gltf"};
    for (size_t f = 0; f < 2; f++) {
        char path[4096];
        snprintf(path, sizeof path, "%s", lk_test_tmpfile(formats[f]));
        lk_error error = {0};
        assert_int_equal(lk_scene_write(path, &scene, NULL, &error), LK_OK);
        lk_scene back;
        read_scene(path, &back);
        const lk_scene_mesh *again = &back.meshes[0];
        assert_int_equal(again->target_count, 2);
        assert_memory_equal(again->weights, mesh->weights, 2 * sizeof(float));
        const lk_scene_primitive *p = &again->primitives[0];
        assert_memory_equal(p->target_positions, primitive->target_positions, 2 * 24 * 3 * sizeof(float));
        assert_memory_equal(p->target_normals, primitive->target_normals, 2 * 24 * 3 * sizeof(float));
        assert_memory_equal(p->target_tangents, primitive->target_tangents, 2 * 24 * 3 * sizeof(float));
        assert_int_equal(back.animations[0].channels[0].path, LK_SCENE_PATH_WEIGHTS);
        assert_memory_equal(back.animations[0].samplers[0].output, animation->samplers[0].output, 254 * sizeof(float));
        lk_scene_free(&back);
    }
    lk_scene_free(&scene);
}

/* Shape k (0: the base) of a primitive as a mesh sharing its indices. */
static void shape_of(const lk_scene_primitive *primitive, size_t k, lk_mesh *out)
{
    const lk_mesh *mesh = &primitive->mesh;
    lk_mesh_init(out);
    out->vertex_count = mesh->vertex_count;
    out->triangle_count = mesh->triangle_count;
    out->indices = mesh->indices;
    out->positions = malloc(3 * mesh->vertex_count * sizeof(float));
    assert_non_null(out->positions);
    for (size_t i = 0; i < 3 * mesh->vertex_count; i++)
        out->positions[i] =
            mesh->positions[i] + (k ? primitive->target_positions[3 * (k - 1) * mesh->vertex_count + i] : 0.0f);
}

/* Metro between shape k of two primitives: Hausdorff and RMS distances in %
 * of the input shape's diagonal. */
static void shape_error(const lk_scene_primitive *simplified, const lk_scene_primitive *input, size_t k,
                        double *hausdorff, double *rms)
{
    lk_mesh a, b;
    shape_of(simplified, k, &a);
    shape_of(input, k, &b);
    lk_metro_options options;
    lk_metro_options_default(&options);
    lk_metro_result result;
    lk_error error = {0};
    assert_int_equal(lk_metro(&a, &b, &options, &result, NULL, NULL, &error), LK_OK);
    double diagonal = lk_mesh_bounds(&b, NULL, NULL);
    *hausdorff = 100.0 * result.hausdorff / diagonal;
    *rms = 100.0 * fmax(result.forward.rms, result.backward.rms) / diagonal;
    free(a.positions);
    free(b.positions);
}

#define FAERIE_SHAPES 5
static const size_t faerie_frames[FAERIE_SHAPES] = {0, 45, 90, 135, 180};

/* faerie.md2's chosen frames as a morph-target glTF, read as a scene. */
static void faerie_scene(lk_scene *scene)
{
    lk_animation md2;
    lk_error error = {0};
    assert_int_equal(lk_animation_read(lk_test_sample("faerie.md2"), &md2, &error), LK_OK);
    size_t n = md2.mesh.vertex_count;
    lk_animation chosen = md2;
    chosen.frame_count = FAERIE_SHAPES;
    chosen.frame_names = NULL;
    chosen.frame_positions = malloc(FAERIE_SHAPES * 3 * n * sizeof(float));
    assert_non_null(chosen.frame_positions);
    for (size_t f = 0; f < FAERIE_SHAPES; f++)
        memcpy(chosen.frame_positions + 3 * n * f, md2.frame_positions + 3 * n * faerie_frames[f],
               3 * n * sizeof(float));
    const char *path = lk_test_tmpfile("faerie-morph.gltf");
    assert_int_equal(lk_animation_write(path, &chosen, &error), LK_OK);
    free(chosen.frame_positions);
    lk_animation_free(&md2);
    read_scene(path, scene);
    assert_int_equal(scene->meshes[0].target_count, FAERIE_SHAPES - 1);
}

/* What ignoring the targets gives: the base alone simplified (one frame,
 * as lk_scene_simplify's QEM without targets), each output vertex taking
 * the deltas of one input vertex merged into it. */
static void simplify_base_only(const lk_scene_primitive *input, size_t target_count, double ratio,
                               lk_scene_primitive *out)
{
    lk_animation one;
    lk_animation_init(&one);
    one.mesh = input->mesh;
    one.frame_count = 1;
    one.frame_positions = input->mesh.positions;
    one.frames_per_second = 1;
    lk_anim_simplify_options options;
    lk_anim_simplify_options_default(&options);
    options.simplify.target_ratio = ratio;
    options.allow_folds = 1;
    options.hold_seams = 1;
    options.lost_surface = 0;
    lk_anim_simplify_result result;
    lk_error error = {0};
    assert_int_equal(lk_animation_simplify(&one, &options, &result, NULL, NULL, &error), LK_OK);
    memset(out, 0, sizeof *out);
    out->mesh = result.animation.mesh;
    lk_mesh_init(&result.animation.mesh);
    size_t n = input->mesh.vertex_count, m = out->mesh.vertex_count;
    out->target_positions = calloc(target_count * m * 3, sizeof(float));
    assert_non_null(out->target_positions);
    for (size_t v = n; v-- > 0;) { /* the first input vertex of each output one wins */
        uint32_t o = result.vertex_map[v];
        if (o >= m) continue;
        for (size_t k = 0; k < target_count; k++)
            memcpy(out->target_positions + 3 * (k * m + o), input->target_positions + 3 * (k * n + v),
                   3 * sizeof(float));
    }
    lk_anim_simplify_result_free(&result);
}

static void test_faerie_simplified(void **state)
{
    (void)state;
    lk_scene input, simplified;
    faerie_scene(&input);
    const double ratio = 0.25;
    lk_error error = {0};
    assert_int_equal(lk_scene_copy(&simplified, &input, &error), LK_OK);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = ratio;
    lk_scene_simplify_stats stats;
    assert_int_equal(lk_scene_simplify(&simplified, LK_SIMPLIFY_QEM, &options, &stats, &error), LK_OK);
    const lk_scene_primitive *in = &input.meshes[0].primitives[0], *out = &simplified.meshes[0].primitives[0];
    assert_int_equal(in->mesh.triangle_count, 654);
    assert_int_equal(out->mesh.triangle_count, 163);
    assert_int_equal(simplified.meshes[0].target_count, FAERIE_SHAPES - 1);
    assert_non_null(out->target_positions);

    /* written and read back: the same deltas */
    const char *path = lk_test_tmpfile("faerie-25.glb");
    assert_int_equal(lk_scene_write(path, &simplified, NULL, &error), LK_OK);
    lk_scene back;
    read_scene(path, &back);
    assert_int_equal(back.meshes[0].primitives[0].mesh.vertex_count, out->mesh.vertex_count);
    assert_memory_equal(back.meshes[0].primitives[0].target_positions, out->target_positions,
                        3 * (FAERIE_SHAPES - 1) * out->mesh.vertex_count * sizeof(float));
    lk_scene_free(&back);

    lk_scene_primitive naive;
    simplify_base_only(in, FAERIE_SHAPES - 1, ratio, &naive);
    assert_int_equal(naive.mesh.triangle_count, 162);
    /* Measured (Hausdorff, RMS in % of each input shape's diagonal; Metro's
     * defaults): every target in the cost, then the base alone. Each may
     * grow by 10% before the test fails; the worst shape must stay below
     * the base-only order's worst. */
    static const double measured[FAERIE_SHAPES][4] = {{4.614, 0.9389, 4.066, 0.8286},
                                                      {3.701, 0.7748, 4.039, 0.9066},
                                                      {4.163, 0.8398, 3.949, 0.8563},
                                                      {5.078, 0.9746, 5.343, 1.1971},
                                                      {4.064, 0.8574, 6.331, 1.2385}};
    double worst[2] = {0, 0}, worst_naive[2] = {0, 0};
    for (size_t k = 0; k < FAERIE_SHAPES; k++) {
        double h, r, hn, rn;
        shape_error(out, in, k, &h, &r);
        shape_error(&naive, in, k, &hn, &rn);
        print_message("faerie frame %3zu (shape %zu) at 25%%: Hausdorff %.3f%% RMS %.4f%%; base-only order: "
                      "Hausdorff %.3f%% RMS %.4f%%\n",
                      faerie_frames[k], k, h, r, hn, rn);
        assert_true(h <= 1.1 * measured[k][0] && r <= 1.1 * measured[k][1]);
        assert_true(hn >= 0.9 * measured[k][2] && rn >= 0.9 * measured[k][3]); /* the comparison still holds */
        worst[0] = fmax(worst[0], h), worst[1] = fmax(worst[1], r);
        worst_naive[0] = fmax(worst_naive[0], hn), worst_naive[1] = fmax(worst_naive[1], rn);
    }
    print_message("worst shape: Hausdorff %.3f%% RMS %.4f%%; base-only order: Hausdorff %.3f%% RMS %.4f%%\n", worst[0],
                  worst[1], worst_naive[0], worst_naive[1]);
    assert_true(worst[0] < worst_naive[0] && worst[1] < worst_naive[1]);
    lk_mesh_free(&naive.mesh);
    free(naive.target_positions);
    lk_scene_free(&simplified);
    lk_scene_free(&input);
}

/* The cube to half its triangles: the targets follow the 14 vertices left,
 * and each shape's error is what removing 6 of 12 triangles costs a box. */
static void test_cube_simplified(void **state)
{
    (void)state;
    lk_scene input, simplified;
    read_scene(cube_path(), &input);
    lk_error error = {0};
    assert_int_equal(lk_scene_copy(&simplified, &input, &error), LK_OK);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.5;
    assert_int_equal(lk_scene_simplify(&simplified, LK_SIMPLIFY_QEM, &options, NULL, &error), LK_OK);
    const lk_scene_primitive *in = &input.meshes[0].primitives[0], *out = &simplified.meshes[0].primitives[0];
    assert_int_equal(out->mesh.triangle_count, 6);
    assert_int_equal(out->mesh.vertex_count, 14);
    assert_non_null(out->target_normals);
    assert_non_null(out->target_tangents);
    /* Measured (in % of each shape's diagonal), 10% margin: a box has no
     * triangle to spare, so the base and "angle" lose about a third of the
     * diagonal; "thin" 2.3% */
    static const double measured[3][2] = {{29.749, 15.6709}, {2.345, 1.3552}, {27.841, 14.2199}};
    for (size_t k = 0; k < 3; k++) {
        double h, r;
        shape_error(out, in, k, &h, &r);
        print_message("cube shape %zu at 50%%: Hausdorff %.3f%% RMS %.4f%%\n", k, h, r);
        assert_true(h <= 1.1 * measured[k][0] && r <= 1.1 * measured[k][1]);
    }
    lk_scene_free(&simplified);
    lk_scene_free(&input);
}

/* A triangle whose one target is a sparse accessor without a bufferView
 * (zeros) moving vertex 2 by (0, 0.5, 0); `indices` is the sparse index
 * list's JSON members after the bufferView. */
static lk_status sparse_scene(const char *count, lk_scene *scene, lk_error *error)
{
    unsigned char bin[52] = {0};
    const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, delta[3] = {0, 0.5f, 0};
    memcpy(bin, positions, sizeof positions);
    bin[36] = 2; /* the sparse index, a little-endian unsigned short */
    memcpy(bin + 40, delta, sizeof delta);
    char base64[80], text[2048];
    lk_test_base64(bin, sizeof bin, base64);
    snprintf(text, sizeof text,
             "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
             "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"targets\":[{\"POSITION\":1}]}],"
             "\"weights\":[0.25]}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\","
             "\"min\":[0,0,0],\"max\":[1,1,0]},"
             "{\"componentType\":5126,\"count\":3,\"type\":\"VEC3\",\"sparse\":{\"count\":%s,"
             "\"indices\":{\"bufferView\":1,\"componentType\":5123},\"values\":{\"bufferView\":2}}}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":4},"
             "{\"buffer\":0,\"byteOffset\":40,\"byteLength\":12}],"
             "\"buffers\":[{\"byteLength\":52,\"uri\":\"data:application/octet-stream;base64,%s\"}]}",
             count, base64);
    return lk_scene_read_memory(text, strlen(text), "sparse.gltf", NULL, scene, error);
}

static void test_sparse_target(void **state)
{
    (void)state;
    lk_scene scene;
    lk_error error = {0};
    assert_int_equal(sparse_scene("1", &scene, &error), LK_OK);
    assert_int_equal(scene.meshes[0].target_count, 1);
    assert_float_equal(scene.meshes[0].weights[0], 0.25f, 0);
    const float expected[9] = {0, 0, 0, 0, 0, 0, 0, 0.5f, 0};
    assert_memory_equal(scene.meshes[0].primitives[0].target_positions, expected, sizeof expected);
    lk_scene_free(&scene);
    /* two substitutions, values for one */
    assert_int_equal(sparse_scene("2", &scene, &error), LK_ERR_RANGE);
    assert_non_null(strstr(error.message, "sparse.gltf: accessors[1].sparse.values: 2 values from byteOffset 0 "
                                          "exceed bufferView 2 (12 bytes)"));
    /* more substitutions than elements */
    assert_int_equal(sparse_scene("4", &scene, &error), LK_ERR_RANGE);
    assert_non_null(strstr(error.message, "sparse.gltf: accessors[1].sparse.count: 4 is not in 1..3"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cube_round_trip),
        cmocka_unit_test(test_cube_simplified),
        cmocka_unit_test(test_faerie_simplified),
        cmocka_unit_test(test_sparse_target),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
