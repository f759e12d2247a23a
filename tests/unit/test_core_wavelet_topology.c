/* SPDX-License-Identifier: MIT */
/* Two wavelet-simplification bugs found by the procedural shapes of
 * test_core_wavelet.c (issue 24), each failing before its fix. Core, no
 * samples needed.
 *
 * 1. A torus sliced across its axis (LK_AXIS_AUTO picks that axis: it is
 *    the shortest side of any flat ring) came back as two nested closed
 *    surfaces of genus 0 instead of one of genus 1, 21% of the diagonal
 *    away from the input: each plane cuts an outer contour and a hole, and
 *    the first and last slices' contours were capped one by one, so the
 *    hole got its own lid. The tiling now follows the surface pieces
 *    between the planes (lk_contour.below / .above from lk_mesh_slice):
 *    the piece under the first plane joins the outer contour and the hole,
 *    which are bridged into one loop and capped together (an annulus).
 *
 * 2. When no slice count reached a count target, simplify_wavelet kept the
 *    first candidate (150 slices), the one farthest from the target: a
 *    2 x 3 x 4 box of 768 triangles (386 vertices) to 10% (40 vertices)
 *    came back with 896 triangles and 450 vertices, more than the input.
 *    Now the candidate with the fewest points is kept. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

static void wavelet_ok(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result)
{
    lk_error error = {0};
    if (lk_simplify(mesh, LK_SIMPLIFY_WAVELET, options, result, NULL, NULL, &error) != LK_OK)
        fail_msg("wavelet: %s", error.message);
}

/* Bug 1. Before: 2 parts, genus 0, Hausdorff 20.8% (simplified) and 21.8%
 * (raw tiling); along the torus's plane the same simplification gives 1
 * part, genus 1, 2.5%. */
static void test_torus_across_its_axis(void **state)
{
    (void)state;
    lk_mesh torus;
    shape_torus(&torus, 2, 0.5, 64, 32);

    lk_slices slices;
    lk_slices_init(&slices);
    lk_error error = {0};
    assert_int_equal(lk_mesh_slice(&torus, LK_AXIS_AUTO, 20, &slices, NULL, NULL, &error), LK_OK);
    lk_mesh tiled;
    lk_mesh_init(&tiled);
    assert_int_equal(lk_slices_tile(&slices, &tiled, NULL, &error), LK_OK);
    lk_mesh_stats s = shape_stats(&tiled);
    lk_metro_result metro = shape_metro(&torus, &tiled, 10);
    print_message("raw tiling across the axis: %zu parts, genus %lld, Hausdorff %.2f%% of the diagonal\n",
                  s.component_count, s.genus, 100 * metro.hausdorff / metro.diagonal);
    assert_int_equal(s.component_count, 1);
    assert_int_equal(s.genus, 1);
    assert_true(metro.hausdorff < 0.035 * metro.diagonal);
    lk_mesh_free(&tiled);
    lk_slices_free(&slices);

    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.1;
    lk_simplify_result result;
    wavelet_ok(&torus, &options, &result);
    s = shape_stats(&result.mesh);
    metro = shape_metro(&torus, &result.mesh, 10);
    print_message("wavelet 10%% across the axis: %zu parts, genus %lld, Hausdorff %.2f%% of the diagonal\n",
                  s.component_count, s.genus, 100 * metro.hausdorff / metro.diagonal);
    assert_int_equal(s.component_count, 1);
    assert_int_equal(s.genus, 1);
    assert_true(metro.hausdorff < 0.035 * metro.diagonal);
    lk_simplify_result_free(&result);
    lk_mesh_free(&torus);
}

/* Bug 2. Before: 450 vertices, 896 triangles; 16 slices give 48 vertices,
 * 44.6% of the diagonal away (out of reach of the target every contour is
 * cut to its minimum of 3 points, a triangle inside each rectangle). */
static void test_unreachable_target(void **state)
{
    (void)state;
    lk_mesh box;
    shape_box(&box, 2, 3, 4, 8);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.1;
    lk_simplify_result automatic, sixteen;
    wavelet_ok(&box, &options, &automatic);
    options.slice_count = 16;
    wavelet_ok(&box, &options, &sixteen);
    assert_false(sixteen.target_reached);
    lk_metro_result metro = shape_metro(&box, &automatic.mesh, 10);
    lk_metro_result metro16 = shape_metro(&box, &sixteen.mesh, 10);
    print_message("box 10%%, automatic slice count: %zu v, %zu t, Hausdorff %.1f%%; 16 slices: %zu v, %.1f%%\n",
                  automatic.mesh.vertex_count, automatic.mesh.triangle_count, 100 * metro.hausdorff / metro.diagonal,
                  sixteen.mesh.vertex_count, 100 * metro16.hausdorff / metro16.diagonal);
    /* With 11 and 8 slices among the candidates now, the target is in
     * reach: 40 vertices, 2.3% of the diagonal. */
    assert_true(automatic.target_reached);
    assert_true(automatic.mesh.vertex_count <= 40);
    assert_true(metro.hausdorff < 0.05 * metro.diagonal);
    assert_true(automatic.mesh.vertex_count <= sixteen.mesh.vertex_count);
    assert_true(automatic.mesh.triangle_count < box.triangle_count);
    lk_simplify_result_free(&automatic);
    lk_simplify_result_free(&sixteen);
    lk_mesh_free(&box);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_torus_across_its_axis),
        cmocka_unit_test(test_unreachable_target),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
