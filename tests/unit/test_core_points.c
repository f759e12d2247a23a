/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: point sets (src/points.c) on spheres. Surface
 * sampling puts points on the mesh with outward face normals and radii of
 * the expected size; Poisson-disk sampling spreads them; PCA normals of
 * evenly spread sphere points point outwards on every part; k-nearest
 * radii are positive and even on even points. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

static void sample_ok(const lk_mesh *mesh, size_t count, int poisson, lk_mesh *points)
{
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.point_count = count;
    options.poisson = poisson;
    lk_error error = {0};
    lk_mesh_init(points);
    if (lk_mesh_sample_points(mesh, &options, points, NULL, NULL, &error) != LK_OK)
        fail_msg("sample: %s", error.message);
}

static double closest_pair(const lk_mesh *points)
{
    double closest = INFINITY;
    for (size_t i = 0; i < points->vertex_count; i++)
        for (size_t j = i + 1; j < points->vertex_count; j++) {
            const float *p = points->positions + 3 * i, *q = points->positions + 3 * j;
            double dx = (double)p[0] - q[0], dy = (double)p[1] - q[1], dz = (double)p[2] - q[2];
            closest = fmin(closest, dx * dx + dy * dy + dz * dz);
        }
    return sqrt(closest);
}

/* 5000 points on a unit icosphere (3 subdivisions). A point on a face is
 * at most the face depth inside the sphere, and its face normal is within
 * the face's angular radius of the radial direction: dot >= 1 - depth
 * (depth 0.0045; measured dot >= 0.9959, 0.00448 deep). The distance to
 * the 8th neighbour is about sqrt(8 A / (pi N)) for N points spread over
 * an area A (0.0798); with normals a radius is at most that distance and
 * at most 1.25 times the farthest corner of the point's cell among those
 * neighbours: measured mean 0.0651 (uniform) and 0.0497 (Poisson: regular
 * cells), bounded to 0.5-0.9 of it; every radius within 0.1 to 2.5 times it
 * (measured 0.18 to 1.60). Poisson-disk points keep apart: the closest pair
 * is 0.037 apart (uniform: 0.0007), bounded below by a quarter of the mean
 * spacing; their radii spread less (max / min 2.87, uniform 8.9; bound
 * 3.5). */
static void test_sampling_a_sphere(void **state)
{
    (void)state;
    lk_mesh sphere;
    shape_icosphere(&sphere, 1, 3);
    double depth = shape_face_depth(&sphere, 1);
    double expected_radius = sqrt(8 * lk_mesh_area(&sphere) / (SHAPE_PI * 5000));
    for (int poisson = 0; poisson <= 1; poisson++) {
        lk_mesh points;
        sample_ok(&sphere, 5000, poisson, &points);
        assert_int_equal(points.triangle_count, 0);
        assert_true(points.vertex_count <= 5000 && points.vertex_count > (poisson ? 4500 : 4999));
        assert_non_null(points.normals);
        assert_non_null(points.radii);
        double lowest_dot = 1, smallest = INFINITY, largest = 0, sum = 0;
        for (size_t i = 0; i < points.vertex_count; i++) {
            const float *p = points.positions + 3 * i, *n = points.normals + 3 * i;
            double length = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
            assert_true(length <= 1 + 1e-6 && length >= 1 - depth - 1e-6);
            assert_true(fabs(sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]) - 1) < 1e-5);
            lowest_dot = fmin(lowest_dot, ((double)p[0] * n[0] + (double)p[1] * n[1] + (double)p[2] * n[2]) / length);
            double r = points.radii[i];
            assert_true(r > 0 && isfinite(r));
            smallest = fmin(smallest, r), largest = fmax(largest, r), sum += r;
        }
        double mean = sum / (double)points.vertex_count, pair = closest_pair(&points);
        print_message("%s: %zu points, lowest normal dot %.5f, radii %.4f..%.4f mean %.4f (expected %.4f), closest "
                      "pair %.5f\n",
                      poisson ? "poisson" : "uniform", points.vertex_count, lowest_dot, smallest, largest, mean,
                      expected_radius, pair);
        assert_true(lowest_dot >= 1 - depth - 1e-6);
        assert_true(mean > 0.5 * expected_radius && mean < 0.9 * expected_radius);
        assert_true(smallest > 0.1 * expected_radius && largest < 2.5 * expected_radius);
        if (poisson) {
            assert_true(pair > 0.25 * sqrt(lk_mesh_area(&sphere) / 5000));
            assert_true(largest / smallest < 3.5);
        }
        lk_mesh_free(&points);
    }

    /* The same seed gives the same points; another seed others. */
    lk_mesh a, b;
    sample_ok(&sphere, 1000, 0, &a);
    sample_ok(&sphere, 1000, 0, &b);
    assert_memory_equal(a.positions, b.positions, 3 * 1000 * sizeof(float));
    lk_mesh_free(&b);
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.point_count = 1000;
    options.seed = 2;
    lk_error error = {0};
    lk_mesh_init(&b);
    assert_int_equal(lk_mesh_sample_points(&sphere, &options, &b, NULL, NULL, &error), LK_OK);
    assert_true(memcmp(a.positions, b.positions, 3 * 1000 * sizeof(float)) != 0);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
    lk_mesh_free(&sphere);
}

/* Two spheres of points (radius 2 about (1, 2, 3), radius 0.5 about
 * (8, 0, 0)) with their normals forgotten: the estimated normals are
 * within 8 degrees of the true outward normals on both parts (each part is
 * oriented from its own highest point; measured lowest dot 0.9987, bound
 * 0.99). The k = 8 radii of evenly spread points are even: max / min
 * under 1.5 (measured 1.30). */
static void test_normals_and_radii(void **state)
{
    (void)state;
    const double centres[2][3] = {{1, 2, 3}, {8, 0, 0}}, radii[2] = {2, 0.5};
    const size_t counts[2] = {3000, 800};
    lk_mesh parts[2], points;
    lk_error error = {0};
    for (int i = 0; i < 2; i++) shape_sphere_points(&parts[i], counts[i], radii[i], centres[i]);
    assert_int_equal(lk_mesh_alloc(&points, counts[0] + counts[1], 0, 0, &error), LK_OK);
    memcpy(points.positions, parts[0].positions, 3 * counts[0] * sizeof(float));
    memcpy(points.positions + 3 * counts[0], parts[1].positions, 3 * counts[1] * sizeof(float));
    assert_int_equal(lk_points_estimate_normals(&points, 10, &error), LK_OK);
    double lowest = 1;
    for (size_t i = 0; i < points.vertex_count; i++) {
        const float *truth = i < counts[0] ? parts[0].normals + 3 * i : parts[1].normals + 3 * (i - counts[0]);
        const float *n = points.normals + 3 * i;
        lowest = fmin(lowest, (double)n[0] * truth[0] + (double)n[1] * truth[1] + (double)n[2] * truth[2]);
    }
    print_message("estimated normals: lowest dot with the truth %.5f\n", lowest);
    assert_true(lowest > 0.99);

    lk_mesh *sphere = &parts[0];
    assert_int_equal(lk_points_estimate_radii(sphere, 8, 1, &error), LK_OK);
    double smallest = INFINITY, largest = 0;
    for (size_t i = 0; i < sphere->vertex_count; i++)
        smallest = fmin(smallest, sphere->radii[i]), largest = fmax(largest, sphere->radii[i]);
    print_message("even points: radii %.4f..%.4f\n", smallest, largest);
    assert_true(smallest > 0 && largest / smallest < 1.5);
    for (int i = 0; i < 2; i++) lk_mesh_free(&parts[i]);
    lk_mesh_free(&points);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sampling_a_sphere),
        cmocka_unit_test(test_normals_and_radii),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
