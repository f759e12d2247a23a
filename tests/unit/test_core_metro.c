/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: Metro surface distances (src/metro.c) on
 * analytic cases: a shape against itself (0), two parallel planes (the
 * offset, exactly), two concentric icospheres (the radius difference,
 * within the faces' sagitta), nearest-point queries against a sphere, the
 * one-sided measure, and determinism over seeds and thread counts. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

static lk_metro_result metro_with(const lk_mesh *a, const lk_mesh *b, size_t samples, int threads, uint64_t seed)
{
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.sample_count = samples;
    options.thread_count = threads;
    options.seed = seed;
    lk_metro_result result;
    lk_error error = {0};
    if (lk_metro(a, b, &options, &result, NULL, NULL, &error) != LK_OK) fail_msg("metro: %s", error.message);
    return result;
}

/* A shape against itself: every sample lies on the other surface. */
static void test_identical(void **state)
{
    (void)state;
    lk_mesh mesh;
    shape_noisy_sphere(&mesh, 1, 3, 0.1, 4);
    lk_metro_result result = shape_metro(&mesh, &mesh, 10);
    assert_true(result.hausdorff < 1e-6);
    assert_true(result.forward.mean < 1e-7 && result.backward.rms < 1e-7);
    assert_true(result.forward.sample_count >= 10 * mesh.triangle_count);
    assert_true(fabs(result.diagonal - lk_mesh_bounds(&mesh, NULL, NULL)) < 1e-12);
    lk_mesh_free(&mesh);
}

/* Two planes 0.25 apart: every distance is 0.25 (max, mean, RMS). */
static void test_parallel_planes(void **state)
{
    (void)state;
    lk_mesh a, b;
    shape_plane(&a, 4, 3, 8, 6);
    shape_plane(&b, 4, 3, 5, 7); /* another triangulation of the same square */
    lk_mesh_translate(&b, 0, 0, 0.25);
    lk_metro_result result = shape_metro(&a, &b, 20);
    print_message("planes 0.25 apart: max %.9f mean %.9f rms %.9f\n", result.hausdorff, result.forward.mean,
                  result.backward.rms);
    for (int side = 0; side < 2; side++) {
        const lk_distance_stats *d = side ? &result.backward : &result.forward;
        assert_true(fabs(d->max - 0.25) < 1e-6 && fabs(d->mean - 0.25) < 1e-6 && fabs(d->rms - 0.25) < 1e-6);
    }
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

/* Icospheres of radius 1 and 1.1 (the second a scaled copy): every face
 * of one is parallel to its copy, 0.1 h apart (h the face plane's
 * distance from the centre, in [1 - depth, 1]), and no point of the outer
 * sphere is nearer the unit ball than 1.1 (1 - depth) - 1, so every
 * distance lies in [0.1 - 1.1 depth, 0.1]. Measured: depth 0.00114;
 * forward max 0.09991, mean 0.09990; backward max 0.1, mean 0.09991. */
static void test_concentric_spheres(void **state)
{
    (void)state;
    lk_mesh inner, outer;
    shape_icosphere(&inner, 1, 4);
    shape_icosphere(&outer, 1, 4);
    for (size_t i = 0; i < 3 * outer.vertex_count; i++) outer.positions[i] *= 1.1f;
    double depth = shape_face_depth(&inner, 1);
    lk_metro_result result = shape_metro(&inner, &outer, 10);
    print_message("spheres 1 and 1.1: depth %.5f; forward max %.6f mean %.6f, backward max %.6f mean %.6f\n", depth,
                  result.forward.max, result.forward.mean, result.backward.max, result.backward.mean);
    double low = 0.1 - 1.1 * depth, high = 0.1 + 1e-6;
    for (int side = 0; side < 2; side++) {
        const lk_distance_stats *d = side ? &result.backward : &result.forward;
        assert_true(d->max <= high && d->max >= low);
        assert_true(d->mean >= low && d->mean <= high);
        assert_true(d->rms >= low && d->rms <= high);
    }
    assert_true(fabs(result.hausdorff - 0.1) < 1e-6);

    /* The same with a coarser outer sphere: its faces cut deeper (depth
     * 0.0178 of its radius at 2 subdivisions), so the distances spread by
     * that much: no more than 1.1 - (1 - depth of the inner one) (measured
     * 0.1), a mean no less than 0.1 - 1.1 * 0.0178 - 0.0011 (measured
     * 0.0878). */
    lk_mesh coarse;
    shape_icosphere(&coarse, 1.1, 2);
    double coarse_depth = shape_face_depth(&coarse, 1.1);
    result = shape_metro(&inner, &coarse, 10);
    print_message("against a coarse outer sphere: depth %.5f, Hausdorff %.5f, mean %.5f\n", coarse_depth,
                  result.hausdorff, result.forward.mean);
    assert_true(result.hausdorff <= 0.1 + depth + 1e-6);
    assert_true(result.forward.mean >= 0.1 - 1.1 * coarse_depth - depth && result.forward.mean < 0.1);
    lk_mesh_free(&coarse);
    lk_mesh_free(&inner);
    lk_mesh_free(&outer);
}

/* Nearest points of a unit icosphere: from a point at radius 2 the
 * distance is 2 - h with h in [1 - depth, 1], the closest point lies on
 * the mesh (its own nearest point at distance 0), and a search bounded
 * below that distance finds nothing. */
static void test_nearest_points(void **state)
{
    (void)state;
    lk_mesh sphere;
    shape_icosphere(&sphere, 1, 3);
    double depth = shape_face_depth(&sphere, 1);
    lk_surface_index *index = NULL;
    lk_error error = {0};
    assert_int_equal(lk_surface_index_build(&sphere, &index, &error), LK_OK);
    for (int i = 0; i < 200; i++) {
        double z = 2 * shape_random(8, (uint64_t)i) - 1, angle = 2 * SHAPE_PI * shape_random(9, (uint64_t)i);
        double point[3] = {2 * sqrt(1 - z * z) * cos(angle), 2 * sqrt(1 - z * z) * sin(angle), 2 * z};
        double closest[3];
        uint32_t triangle = UINT32_MAX;
        double d = lk_surface_index_nearest(index, point, INFINITY, closest, &triangle);
        assert_true(d >= 1 - 1e-6 && d <= 1 + depth + 1e-6);
        assert_true(triangle < sphere.triangle_count);
        assert_true(lk_surface_index_nearest(index, closest, INFINITY, NULL, NULL) < 1e-6);
        assert_true(isinf(lk_surface_index_nearest(index, point, 0.99, NULL, NULL)));
    }
    lk_surface_index_free(index);
    lk_mesh_free(&sphere);
}

/* The one-sided measure is the forward half of lk_metro; results do not
 * depend on the thread count, and a different seed moves the mean only
 * within sampling noise (max and vertex samples stay). */
static void test_one_sided_and_determinism(void **state)
{
    (void)state;
    lk_mesh a, b;
    shape_noisy_sphere(&a, 1, 3, 0.05, 1);
    shape_icosphere(&b, 1, 2);
    lk_metro_result one = metro_with(&a, &b, 20000, 1, 7), four = metro_with(&a, &b, 20000, 4, 7);
    assert_memory_equal(&one.forward, &four.forward, sizeof one.forward);
    assert_memory_equal(&one.backward, &four.backward, sizeof one.backward);
    assert_true(one.forward.sample_count >= 20000);

    lk_surface_index *index = NULL;
    lk_error error = {0};
    assert_int_equal(lk_surface_index_build(&b, &index, &error), LK_OK);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.sample_count = 20000;
    options.seed = 7;
    lk_distance_stats forward;
    assert_int_equal(lk_metro_one_sided(&a, index, &options, &forward, &error), LK_OK);
    assert_memory_equal(&forward, &one.forward, sizeof forward);
    lk_surface_index_free(index);

    lk_metro_result other = metro_with(&a, &b, 20000, 2, 8);
    assert_true(fabs(other.forward.mean - one.forward.mean) < 0.02 * one.forward.mean);
    assert_true(other.forward.max >= 0.95 * one.forward.max);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_identical),
        cmocka_unit_test(test_parallel_planes),
        cmocka_unit_test(test_concentric_spheres),
        cmocka_unit_test(test_nearest_points),
        cmocka_unit_test(test_one_sided_and_determinism),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
