/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: deformation-sensitive simplification
 * (lk_animation_simplify, src/qem.c and src/anim_simplify.c) on procedural
 * animations: a capsule bending like an arm at the elbow (straight in
 * frame 0) and a twisting box. One connectivity serves every frame, each
 * frame stays a closed genus-0 surface, the per-frame Metro error is
 * bounded, the max scheme beats the single-frame scheme on its worst
 * frame (the paper's claim: frame 0 sees a straight tube whose joint rings
 * cost nothing to remove), and a level set equals separate calls. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

static void simplify_ok(const lk_animation *animation, lk_anim_scheme scheme, double ratio,
                        lk_anim_simplify_result *result)
{
    lk_anim_simplify_options options;
    lk_anim_simplify_options_default(&options);
    options.scheme = scheme;
    options.simplify.target_ratio = ratio;
    lk_error error = {0};
    if (lk_animation_simplify(animation, &options, result, NULL, NULL, &error) != LK_OK)
        fail_msg("lk_animation_simplify: %s", error.message);
}

typedef struct frame_errors {
    double first, worst, worst_rms; /* Hausdorff of frame 0, worst Hausdorff and RMS; fractions of the diagonal */
} frame_errors;

/* Metro per frame (lk_animation_metro), and every frame of the result a
 * closed genus-0 surface. */
static frame_errors measure(const lk_animation *simplified, const lk_animation *original)
{
    size_t frames = original->frame_count;
    lk_metro_result *rows = calloc(frames, sizeof *rows);
    assert_non_null(rows);
    lk_error error = {0};
    if (lk_animation_metro(simplified, original, NULL, frames, NULL, rows, NULL, NULL, &error) != LK_OK)
        fail_msg("lk_animation_metro: %s", error.message);
    frame_errors e = {rows[0].hausdorff / rows[0].diagonal, 0, 0};
    for (size_t f = 0; f < frames; f++) {
        e.worst = fmax(e.worst, rows[f].hausdorff / rows[f].diagonal);
        e.worst_rms = fmax(e.worst_rms, fmax(rows[f].forward.rms, rows[f].backward.rms) / rows[f].diagonal);
        lk_mesh frame;
        assert_int_equal(lk_animation_frame(simplified, f, &frame, &error), LK_OK);
        lk_mesh_stats s = shape_stats(&frame);
        if (s.boundary_edge_count || s.nonmanifold_edge_count || s.genus != 0 || s.component_count != 1)
            fail_msg("frame %zu: border %zu, non-manifold %zu, genus %lld, parts %zu", f, s.boundary_edge_count,
                     s.nonmanifold_edge_count, s.genus, s.component_count);
        lk_mesh_free(&frame);
    }
    free(rows);
    return e;
}

/* The bending capsule (498 vertices, 992 triangles, 8 frames from
 * straight to 120 degrees) to 20%. Measured, as % of the diagonal:
 *   max scheme:      frame 0 0.53, worst frame 0.84, worst RMS 0.12;
 *   frame-0 scheme:  frame 0 0.26, worst frame 4.76, worst RMS 0.76.
 * Bounds: the max scheme's worst frame under 1.2% and RMS under 0.2%, and
 * under a third of the frame scheme's worst frame; the frame scheme wins
 * on its own frame. */
static void test_bending_limb(void **state)
{
    (void)state;
    lk_animation limb;
    shape_bending_capsule(&limb, 0.3, 4, 16, 24, 4, 8, 120);
    assert_int_equal(limb.mesh.vertex_count, 498);
    assert_int_equal(limb.mesh.triangle_count, 992);

    lk_anim_simplify_result max, single;
    simplify_ok(&limb, LK_ANIM_SCHEME_MAX, 0.2, &max);
    simplify_ok(&limb, LK_ANIM_SCHEME_FRAME, 0.2, &single);
    assert_true(max.target_reached && single.target_reached);
    assert_int_equal(max.animation.mesh.triangle_count, 198);
    assert_int_equal(max.animation.frame_count, 8);
    assert_true(max.animation.frames_per_second == limb.frames_per_second);
    size_t v_count = max.animation.mesh.vertex_count;
    assert_memory_equal(max.animation.mesh.positions, max.animation.frame_positions, 3 * v_count * sizeof(float));

    frame_errors m = measure(&max.animation, &limb), s = measure(&single.animation, &limb);
    print_message("bending limb 20%%: max scheme frame 0 %.3f%%, worst %.3f%%, RMS %.3f%%; frame scheme %.3f%%, "
                  "%.3f%%, %.3f%%\n",
                  100 * m.first, 100 * m.worst, 100 * m.worst_rms, 100 * s.first, 100 * s.worst, 100 * s.worst_rms);
    assert_true(m.worst < 0.012);
    assert_true(m.worst_rms < 0.002);
    assert_true(m.worst < s.worst / 3);
    assert_true(s.first < m.first);

    /* Every input vertex went somewhere; every output vertex came from one. */
    size_t *preimages = calloc(v_count, sizeof *preimages);
    assert_non_null(preimages);
    for (size_t v = 0; v < limb.mesh.vertex_count; v++) {
        assert_true(max.vertex_map[v] < v_count);
        preimages[max.vertex_map[v]]++;
    }
    for (size_t v = 0; v < v_count; v++) assert_true(preimages[v] > 0);
    free(preimages);
    lk_anim_simplify_result_free(&max);
    lk_anim_simplify_result_free(&single);
    lk_animation_free(&limb);
}

/* The twisting box (218 vertices, 8 frames up to half a turn) to 20%:
 * frame 0 is a box, kept exactly by both schemes; measured worst frames
 * 2.64% (max) and 6.39% (frame 0); bounds 3.5% and half the frame
 * scheme's. */
static void test_twisting_box(void **state)
{
    (void)state;
    lk_animation box;
    shape_twisting_box(&box, 1, 1, 4, 6, 8, 180);
    lk_anim_simplify_result max, single;
    simplify_ok(&box, LK_ANIM_SCHEME_MAX, 0.2, &max);
    simplify_ok(&box, LK_ANIM_SCHEME_FRAME, 0.2, &single);
    frame_errors m = measure(&max.animation, &box), s = measure(&single.animation, &box);
    print_message("twisting box 20%%: worst frame %.3f%% (max), %.3f%% (frame 0)\n", 100 * m.worst, 100 * s.worst);
    assert_true(m.first < 1e-6 && s.first < 1e-6);
    assert_true(m.worst < 0.035);
    assert_true(m.worst < s.worst / 2);
    lk_anim_simplify_result_free(&max);
    lk_anim_simplify_result_free(&single);
    lk_animation_free(&box);
}

/* A level set in one run equals separate calls, bit for bit. */
static void test_levels_equal_separate_calls(void **state)
{
    (void)state;
    lk_animation limb;
    shape_bending_capsule(&limb, 0.3, 4, 12, 16, 3, 5, 90);
    const double ratios[2] = {0.5, 0.2};
    lk_anim_simplify_options options;
    lk_anim_simplify_options_default(&options);
    lk_anim_simplify_result levels[2];
    lk_error error = {0};
    assert_int_equal(lk_animation_simplify_levels(&limb, &options, ratios, 2, levels, NULL, NULL, &error), LK_OK);
    for (int i = 0; i < 2; i++) {
        lk_anim_simplify_result one;
        simplify_ok(&limb, LK_ANIM_SCHEME_MAX, ratios[i], &one);
        const lk_animation *a = &levels[i].animation, *b = &one.animation;
        assert_int_equal(a->mesh.triangle_count, (size_t)(ratios[i] * (double)limb.mesh.triangle_count));
        assert_int_equal(a->mesh.triangle_count, b->mesh.triangle_count);
        assert_int_equal(a->mesh.vertex_count, b->mesh.vertex_count);
        assert_memory_equal(a->mesh.indices, b->mesh.indices, 3 * a->mesh.triangle_count * sizeof(uint32_t));
        assert_memory_equal(a->frame_positions, b->frame_positions, 5 * 3 * a->mesh.vertex_count * sizeof(float));
        lk_anim_simplify_result_free(&one);
        lk_anim_simplify_result_free(&levels[i]);
    }
    lk_animation_free(&limb);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bending_limb),
        cmocka_unit_test(test_twisting_box),
        cmocka_unit_test(test_levels_equal_separate_calls),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
