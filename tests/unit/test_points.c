/* SPDX-License-Identifier: MIT */
/* Point sets (src/points.c): surface sampling, Poisson-disk subsets, splat
 * radii and normal estimation, measured on the bunny and the kitten. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* ---- shared data ------------------------------------------------------------ */

/* The bunny and one default sample of it (100k points, seed 1), made once. */
static lk_mesh bunny, bunny_points;
static double bunny_area, bunny_diagonal;

static int load_bunny(void **state)
{
    (void)state;
    lk_error error = {0};
    if (lk_mesh_read(lk_test_sample("bunny.obj"), LK_FORMAT_AUTO, NULL, &bunny, &error) != LK_OK) {
        fprintf(stderr, "%s\n", error.message);
        return -1;
    }
    bunny_area = lk_mesh_area(&bunny);
    bunny_diagonal = lk_mesh_bounds(&bunny, NULL, NULL);
    lk_sample_options options;
    lk_sample_options_default(&options);
    if (lk_mesh_sample_points(&bunny, &options, &bunny_points, NULL, NULL, &error) != LK_OK) {
        fprintf(stderr, "%s\n", error.message);
        return -1;
    }
    return 0;
}

static int free_bunny(void **state)
{
    (void)state;
    lk_mesh_free(&bunny);
    lk_mesh_free(&bunny_points);
    return 0;
}

static double dot3(const float *a, const float *b)
{
    return (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2];
}

static double distance3(const float *a, const float *b)
{
    double dx = (double)a[0] - b[0], dy = (double)a[1] - b[1], dz = (double)a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

static void triangle_normal(const lk_mesh *mesh, size_t t, float out[3])
{
    const float *a = mesh->positions + 3 * mesh->indices[3 * t], *b = mesh->positions + 3 * mesh->indices[3 * t + 1],
                *c = mesh->positions + 3 * mesh->indices[3 * t + 2];
    double e1[3], e2[3], n[3];
    for (int k = 0; k < 3; k++) e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int k = 0; k < 3; k++) out[k] = (float)(n[k] / length);
}

static int compare_floats(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static double median_of(const float *values, size_t count)
{
    float *sorted = malloc(count * sizeof *sorted);
    assert_non_null(sorted);
    memcpy(sorted, values, count * sizeof *sorted);
    qsort(sorted, count, sizeof *sorted, compare_floats);
    double median = sorted[count / 2];
    free(sorted);
    return median;
}

/* Area of the part of triangle t with coordinate `axis` below `plane`
 * (the triangle clipped by the plane, as a polygon). */
static double area_below(const lk_mesh *mesh, size_t t, int axis, double plane)
{
    double in[3][3], out[4][3];
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 3; k++) in[c][k] = mesh->positions[3 * mesh->indices[3 * t + c] + k];
    int count = 0;
    for (int c = 0; c < 3; c++) {
        const double *p = in[c], *q = in[(c + 1) % 3];
        bool p_in = p[axis] < plane, q_in = q[axis] < plane;
        if (p_in) memcpy(out[count++], p, sizeof out[0]);
        if (p_in != q_in) {
            double s = (plane - p[axis]) / (q[axis] - p[axis]);
            for (int k = 0; k < 3; k++) out[count][k] = p[k] + s * (q[k] - p[k]);
            count++;
        }
    }
    double area = 0;
    for (int i = 1; i + 1 < count; i++) {
        double e1[3], e2[3];
        for (int k = 0; k < 3; k++) e1[k] = out[i][k] - out[0][k], e2[k] = out[i + 1][k] - out[0][k];
        double n0 = e1[1] * e2[2] - e1[2] * e2[1], n1 = e1[2] * e2[0] - e1[0] * e2[2],
               n2 = e1[0] * e2[1] - e1[1] * e2[0];
        area += 0.5 * sqrt(n0 * n0 + n1 * n1 + n2 * n2);
    }
    return area;
}

/* Fractions of normals within 30 degrees of the reference (signed, so a
 * flipped normal counts as wrong) and with a positive dot product. */
static void normal_agreement(const float *estimated, const float *reference, size_t count, double *within,
                             double *positive)
{
    size_t close = 0, same_side = 0;
    double limit = cos(30 * 3.14159265358979323846 / 180);
    for (size_t i = 0; i < count; i++) {
        double d = dot3(estimated + 3 * i, reference + 3 * i);
        close += d >= limit;
        same_side += d > 0;
    }
    *within = (double)close / (double)count;
    *positive = (double)same_side / (double)count;
}

/* ---- sampling --------------------------------------------------------------- */

/* 100k samples lie on the bunny, with unit normals equal to their
 * triangle's, and each region gets points in proportion to its area. */
static void test_sample_bunny_on_surface_area_proportional(void **state)
{
    (void)state;
    const lk_mesh *points = &bunny_points;
    assert_int_equal(points->vertex_count, 100000);
    assert_int_equal(points->triangle_count, 0);
    assert_non_null(points->normals);
    assert_non_null(points->radii);
    assert_null(points->texcoords);
    lk_error error = {0};
    assert_int_equal(lk_mesh_validate(points, &error), LK_OK);

    lk_surface_index *index;
    assert_int_equal(lk_surface_index_build(&bunny, &index, &error), LK_OK);
    double worst = 0, tolerance = 1e-5 * bunny_diagonal;
    size_t aligned = 0, not_unit = 0, flipped = 0;
    for (size_t i = 0; i < points->vertex_count; i++) {
        const float *p = points->positions + 3 * i, *n = points->normals + 3 * i;
        double query[3] = {p[0], p[1], p[2]}, closest[3];
        uint32_t triangle = UINT32_MAX;
        double d = lk_surface_index_nearest(index, query, INFINITY, closest, &triangle);
        if (d > worst) worst = d;
        assert_true(triangle < bunny.triangle_count);
        if (fabs(sqrt(dot3(n, n)) - 1) > 1e-6) not_unit++;
        float face[3];
        triangle_normal(&bunny, triangle, face);
        /* A sample on a shared edge may find the neighbouring triangle
         * nearest; its normal is then close but not equal. */
        double agreement = dot3(n, face);
        aligned += agreement > 0.99999;
        flipped += agreement < 0;
    }
    lk_surface_index_free(index);
    print_message("farthest sample from the surface: %.3g (%.3g of the diagonal); normals equal to the nearest "
                  "triangle's: %.3f%%, opposite: %zu\n",
                  worst, worst / bunny_diagonal, 100.0 * (double)aligned / 1e5, flipped);
    assert_true(worst <= tolerance);
    assert_int_equal(not_unit, 0);
    assert_true(aligned >= 99900);
    assert_true(flipped <= 20);

    /* Area proportionality: the share of points below planes through the
     * quartiles of x, y and z matches the share of area below them. */
    float *coordinate = malloc(points->vertex_count * sizeof(float));
    assert_non_null(coordinate);
    for (int axis = 0; axis < 3; axis++) {
        for (size_t i = 0; i < points->vertex_count; i++) coordinate[i] = points->positions[3 * i + axis];
        qsort(coordinate, points->vertex_count, sizeof(float), compare_floats);
        for (int q = 1; q <= 3; q++) {
            double plane = coordinate[points->vertex_count * (size_t)q / 4];
            double below = 0;
            for (size_t t = 0; t < bunny.triangle_count; t++) below += area_below(&bunny, t, axis, plane);
            size_t count = 0;
            for (size_t i = 0; i < points->vertex_count; i++) count += points->positions[3 * i + axis] < plane;
            double point_share = (double)count / 1e5, area_share = below / bunny_area;
            if (axis == 0 && q == 2)
                print_message("below the median x plane: %.4f of the points, %.4f of the area\n", point_share,
                              area_share);
            assert_true(fabs(point_share - area_share) < 0.01);
        }
    }
    free(coordinate);
}

/* The same seed gives the same bytes; another seed gives other points. */
static void test_sample_deterministic_for_a_seed(void **state)
{
    (void)state;
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.point_count = 20000;
    lk_mesh a, b, c;
    lk_error error = {0};
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &a, NULL, NULL, &error), LK_OK);
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &b, NULL, NULL, &error), LK_OK);
    options.seed = 2;
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &c, NULL, NULL, &error), LK_OK);
    assert_memory_equal(a.positions, b.positions, 3 * 20000 * sizeof(float));
    assert_memory_equal(a.normals, b.normals, 3 * 20000 * sizeof(float));
    assert_memory_equal(a.radii, b.radii, 20000 * sizeof(float));
    size_t same = 0;
    for (size_t i = 0; i < 20000; i++) same += memcmp(a.positions + 3 * i, c.positions + 3 * i, 12) == 0;
    assert_true(same < 10);
    /* The first 20k samples of the 100k run are these 20k: sample i depends
     * only on the seed and i. */
    assert_memory_equal(a.positions, bunny_points.positions, 3 * 20000 * sizeof(float));
    lk_mesh_free(&a);
    lk_mesh_free(&b);
    lk_mesh_free(&c);
}

/* Vertex normals, when the mesh has them, are interpolated: on the cow
 * with normals made by averaging the faces, sample normals are unit length,
 * differ from the flat triangle normals, and stay on the same side. */
static void test_sample_interpolates_vertex_normals(void **state)
{
    (void)state;
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    assert_null(cow.normals);
    cow.normals = calloc(3 * cow.vertex_count, sizeof(float));
    assert_non_null(cow.normals);
    for (size_t t = 0; t < cow.triangle_count; t++) {
        float n[3];
        triangle_normal(&cow, t, n);
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) cow.normals[3 * cow.indices[3 * t + c] + k] += n[k];
    }
    for (size_t v = 0; v < cow.vertex_count; v++) {
        float *n = cow.normals + 3 * v;
        double length = sqrt(dot3(n, n));
        for (int k = 0; k < 3; k++) n[k] = length > 0 ? (float)(n[k] / length) : (k == 2);
    }
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.point_count = 5000;
    lk_mesh points;
    lk_error error = {0};
    assert_int_equal(lk_mesh_sample_points(&cow, &options, &points, NULL, NULL, &error), LK_OK);
    lk_surface_index *index;
    assert_int_equal(lk_surface_index_build(&cow, &index, &error), LK_OK);
    size_t smooth = 0, same_side = 0;
    for (size_t i = 0; i < points.vertex_count; i++) {
        const float *p = points.positions + 3 * i, *n = points.normals + 3 * i;
        assert_float_equal(sqrt(dot3(n, n)), 1.0, 1e-6);
        double query[3] = {p[0], p[1], p[2]};
        uint32_t triangle;
        lk_surface_index_nearest(index, query, INFINITY, NULL, &triangle);
        float face[3];
        triangle_normal(&cow, triangle, face);
        double d = dot3(n, face);
        smooth += d < 0.9999;
        same_side += d > 0;
    }
    lk_surface_index_free(index);
    print_message("cow: %zu of 5000 interpolated normals differ from the face normal, %zu on its side\n", smooth,
                  same_side);
    assert_true(smooth > 4000);
    assert_true(same_side > 4900);
    lk_mesh_free(&points);
    lk_mesh_free(&cow);
}

/* Poisson-disk: exactly the count asked for, on the surface, and the
 * closest pair far apart, unlike uniform sampling's. */
static void test_sample_poisson_spacing(void **state)
{
    (void)state;
    const size_t count = 20000;
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.point_count = count;
    options.neighbours = 1; /* radius = distance to the nearest other point */
    double spacing = sqrt(bunny_area / (double)count);
    double closest[2];
    lk_mesh points[2];
    lk_error error = {0};
    for (int poisson = 0; poisson < 2; poisson++) {
        options.poisson = poisson;
        assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points[poisson], NULL, NULL, &error), LK_OK);
        assert_int_equal(points[poisson].vertex_count, count);
        closest[poisson] = INFINITY;
        for (size_t i = 0; i < count; i++)
            if (points[poisson].radii[i] < closest[poisson]) closest[poisson] = points[poisson].radii[i];
    }
    print_message("closest pair / sqrt(area / N): uniform %.4f, Poisson %.4f\n", closest[0] / spacing,
                  closest[1] / spacing);
    assert_true(closest[1] >= 0.5 * spacing);
    assert_true(closest[0] < 0.05 * spacing);
    /* Brute force over a few hundred points confirms the k = 1 radii. */
    for (size_t i = 0; i < count; i += 97) {
        double best = INFINITY;
        for (size_t j = 0; j < count; j++)
            if (j != i) best = fmin(best, distance3(points[1].positions + 3 * i, points[1].positions + 3 * j));
        assert_true(points[1].radii[i] == (float)best);
    }
    lk_surface_index *index;
    assert_int_equal(lk_surface_index_build(&bunny, &index, &error), LK_OK);
    for (size_t i = 0; i < count; i++) {
        const float *p = points[1].positions + 3 * i;
        double query[3] = {p[0], p[1], p[2]};
        uint32_t triangle;
        assert_true(lk_surface_index_nearest(index, query, INFINITY, NULL, &triangle) <= 1e-5 * bunny_diagonal);
        float face[3];
        triangle_normal(&bunny, triangle, face);
        assert_true(dot3(points[1].normals + 3 * i, face) > 0.99);
    }
    lk_surface_index_free(index);
    /* Poisson spacing is also far more even: the radii vary less. */
    double mean[2] = {0, 0}, variance[2] = {0, 0};
    for (int s = 0; s < 2; s++) {
        for (size_t i = 0; i < count; i++) mean[s] += points[s].radii[i];
        mean[s] /= (double)count;
        for (size_t i = 0; i < count; i++) variance[s] += pow(points[s].radii[i] - mean[s], 2);
        variance[s] /= (double)count;
    }
    print_message("nearest-neighbour distance std/mean: uniform %.3f, Poisson %.3f\n", sqrt(variance[0]) / mean[0],
                  sqrt(variance[1]) / mean[1]);
    assert_true(sqrt(variance[1]) / mean[1] < 0.5 * sqrt(variance[0]) / mean[0]);
    lk_mesh_free(&points[0]);
    lk_mesh_free(&points[1]);
}

static int cancel_at_half(void *user, double fraction, const char *stage)
{
    int *calls = user;
    (*calls)++;
    assert_non_null(stage);
    assert_true(fraction >= 0 && fraction <= 1);
    return fraction >= 0.5;
}

static int count_calls(void *user, double fraction, const char *stage)
{
    (void)fraction, (void)stage;
    (*(int *)user)++;
    return 0;
}

static void test_sample_bad_input(void **state)
{
    (void)state;
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.point_count = 1000;
    lk_mesh points;
    lk_error error = {0};
    /* A point set has nothing to sample. */
    lk_mesh kitten;
    lk_test_load(lk_test_sample("kitten.xyz"), &kitten);
    assert_int_equal(lk_mesh_sample_points(&kitten, &options, &points, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "no triangles");
    assert_null(points.positions);
    lk_mesh_free(&kitten);
    /* Zero area: every triangle degenerate (collinear or repeated corners). */
    static const float line[] = {0, 0, 0, 1, 1, 1, 2, 2, 2, 5, 5, 5};
    static const uint32_t flat_triangles[] = {0, 1, 2, 1, 2, 3, 0, 0, 3};
    lk_mesh line_mesh;
    lk_test_make_mesh(&line_mesh, line, 4, flat_triangles, 3);
    assert_int_equal(lk_mesh_sample_points(&line_mesh, &options, &points, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "area is 0");
    assert_null(points.positions);
    /* A mesh with one real triangle among degenerate ones samples only it. */
    line_mesh.positions[3 * 3 + 1] = 0;
    assert_int_equal(lk_mesh_sample_points(&line_mesh, &options, &points, NULL, NULL, &error), LK_OK);
    for (size_t i = 0; i < points.vertex_count; i++) {
        const float *n = points.normals + 3 * i;
        assert_float_equal(fabs(n[0] + n[1] + n[2]), 0.0, 1e-6); /* normal of the plane x = z */
    }
    lk_mesh_free(&points);
    lk_mesh_free(&line_mesh);
    /* Counts and options. */
    options.point_count = 0;
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "point count");
    options.point_count = LK_MAX_ELEMENTS + 1;
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points, NULL, NULL, &error), LK_ERR_INVALID);
    options.point_count = 1000;
    options.neighbours = 0;
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "neighbours");
    options.neighbours = 8;
    options.radius_scale = -1;
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points, NULL, NULL, &error), LK_ERR_INVALID);
    options.radius_scale = NAN;
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points, NULL, NULL, &error), LK_ERR_INVALID);
    options.radius_scale = 1;
    /* NaN in the mesh. */
    lk_mesh broken;
    assert_int_equal(lk_mesh_copy(&broken, &bunny, &error), LK_OK);
    broken.positions[3 * 17 + 1] = NAN;
    assert_int_equal(lk_mesh_sample_points(&broken, &options, &points, NULL, NULL, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "vertex 17");
    lk_mesh_free(&broken);
    /* The output must not be the input. */
    assert_int_equal(lk_mesh_sample_points(&bunny, &options, &bunny, NULL, NULL, &error), LK_ERR_INVALID);
    assert_int_equal(bunny.triangle_count, 69666);
    /* Cancelling from the progress callback, uniform and Poisson. */
    for (int poisson = 0; poisson < 2; poisson++) {
        options.poisson = poisson;
        int calls = 0;
        assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points, cancel_at_half, &calls, &error),
                         LK_ERR_INVALID);
        lk_assert_message_contains(error, "cancelled");
        assert_true(calls >= 2);
        assert_null(points.positions);
        calls = 0;
        assert_int_equal(lk_mesh_sample_points(&bunny, &options, &points, count_calls, &calls, &error), LK_OK);
        assert_true(calls >= 3);
        lk_mesh_free(&points);
    }
}

/* ---- radii ----------------------------------------------------------------- */

/* Without normals, radius = scale x distance to the k-th nearest other
 * point: checked by brute force; on the bunny sample the median is about
 * the spacing a uniform density predicts (sqrt(k / pi) sqrt(area / N) for
 * k = 8). With normals (the sample's own), no radius is above that
 * distance nor below 1.25 x half the distance to the nearest point (the
 * point's cell holds the disc of that half-distance), and the median falls
 * (measured 0.82 of the median without normals on this Poisson-disk
 * sample, whose 8th neighbour is not far; test_core_points' uniform
 * sample: 0.80). */
static void test_radii_bunny_knn_distance(void **state)
{
    (void)state;
    const lk_mesh *oriented = &bunny_points;
    lk_mesh copy;
    lk_error error = {0};
    assert_int_equal(lk_mesh_copy(&copy, oriented, &error), LK_OK);
    free(copy.normals);
    copy.normals = NULL;
    assert_int_equal(lk_points_estimate_radii(&copy, 8, 1.0, &error), LK_OK);
    size_t count = copy.vertex_count;
    double spacing = sqrt(bunny_area / (double)count);
    double median = median_of(copy.radii, count), oriented_median = median_of(oriented->radii, count);
    float smallest = INFINITY;
    for (size_t i = 0; i < count; i++) smallest = fminf(smallest, copy.radii[i]);
    print_message("median radius %.5f = %.3f x sqrt(area / N); smallest %.3g; with normals median %.5f (%.3f of it)\n",
                  median, median / spacing, (double)smallest, oriented_median, oriented_median / median);
    assert_true(median >= 1.0 * spacing && median <= 2.0 * spacing);
    assert_true(oriented_median >= 0.6 * median && oriented_median <= 0.92 * median);
    assert_true(smallest > 0);
    /* Brute force: the 8th smallest distance to the other points. */
    double *distances = malloc(count * sizeof(double));
    assert_non_null(distances);
    for (size_t i = 0; i < count; i += 1009) {
        size_t n = 0;
        for (size_t j = 0; j < count; j++)
            if (j != i) distances[n++] = distance3(copy.positions + 3 * i, copy.positions + 3 * j);
        /* partial selection of the 8 smallest */
        for (size_t a = 0; a < 8; a++)
            for (size_t b = a + 1; b < n; b++)
                if (distances[b] < distances[a]) {
                    double swap = distances[a];
                    distances[a] = distances[b];
                    distances[b] = swap;
                }
        assert_true(copy.radii[i] == (float)distances[7]);
        assert_true(oriented->radii[i] <= (float)distances[7]);
        assert_true(oriented->radii[i] >= 0.999 * 1.25 * 0.5 * distances[0]);
    }
    free(distances);
    /* Scale multiplies; more neighbours, larger radii. */
    float *radii = malloc(count * sizeof(float));
    assert_non_null(radii);
    memcpy(radii, copy.radii, count * sizeof(float));
    assert_int_equal(lk_points_estimate_radii(&copy, 8, 2.0, &error), LK_OK);
    for (size_t i = 0; i < count; i++) assert_true(copy.radii[i] == 2 * radii[i]);
    assert_int_equal(lk_points_estimate_radii(&copy, 16, 1.0, &error), LK_OK);
    double median16 = median_of(copy.radii, count);
    assert_true(median16 > 1.3 * median && median16 < 1.6 * median); /* ~ sqrt(2) */
    /* A point set without radii gets them allocated. */
    free(copy.radii);
    copy.radii = NULL;
    assert_int_equal(lk_points_estimate_radii(&copy, 8, 1.0, &error), LK_OK);
    assert_memory_equal(copy.radii, radii, count * sizeof(float));
    free(radii);
    lk_mesh_free(&copy);
}

/* kitten.xyz: every radius positive, the median near the spacing. */
static void test_radii_kitten(void **state)
{
    (void)state;
    lk_mesh kitten;
    lk_test_load(lk_test_sample("kitten.xyz"), &kitten);
    assert_int_equal(kitten.vertex_count, 5210);
    lk_error error = {0};
    assert_int_equal(lk_points_estimate_radii(&kitten, 8, 1.0, &error), LK_OK);
    assert_non_null(kitten.radii);
    for (size_t i = 0; i < kitten.vertex_count; i++) assert_true(kitten.radii[i] > 0 && isfinite(kitten.radii[i]));
    assert_int_equal(lk_mesh_validate(&kitten, &error), LK_OK);
    double median = median_of(kitten.radii, kitten.vertex_count), diagonal = lk_mesh_bounds(&kitten, NULL, NULL);
    print_message("kitten: median radius %.4f (%.4f of the diagonal)\n", median, median / diagonal);
    /* 5210 points on a closed surface: a k=8 spacing of a few percent of
     * the diagonal. */
    assert_true(median > 0.003 * diagonal && median < 0.05 * diagonal);
    lk_mesh_free(&kitten);
}

/* Brute force: the lower median (rank (k - 1) / 2) of the radii of point
 * i's k nearest other points (ties by index, as the k-d tree breaks them). */
static double neighbourhood_median(const lk_mesh *points, size_t i, unsigned k)
{
    double best_distance[16];
    size_t best_id[16];
    unsigned found = 0;
    assert_true(k <= 16);
    for (size_t j = 0; j < points->vertex_count; j++) {
        if (j == i) continue;
        double d = distance3(points->positions + 3 * i, points->positions + 3 * j);
        if (found == k && d >= best_distance[k - 1]) continue; /* j > the ids kept: ties keep them */
        unsigned slot = found < k ? found++ : k - 1;
        while (slot > 0 && best_distance[slot - 1] > d) {
            best_distance[slot] = best_distance[slot - 1];
            best_id[slot] = best_id[slot - 1];
            slot--;
        }
        best_distance[slot] = d;
        best_id[slot] = j;
    }
    float radii[16];
    for (unsigned j = 0; j < found; j++) radii[j] = points->radii[best_id[j]];
    qsort(radii, found, sizeof radii[0], compare_floats);
    return radii[(found - 1) / 2];
}

/* Issue 23: stray points far from a real surface (the bunny's vertices)
 * must not become large splats. Three lone strays, whose neighbours are
 * all on the bunny, and a sparse group of 12 that are each other's
 * neighbours (so only the global cap holds them). Checked by brute force:
 * every radius is at most 4x the median of its neighbours' radii, the
 * strays' radii stay within 4x the largest radius of the bunny alone, and
 * the bunny's own radii are untouched (still its 8th-neighbour spacing). */
static void test_radii_stray_points_bounded(void **state)
{
    (void)state;
    const size_t count = bunny.vertex_count, lone = 3, group = 12, strays = lone + group;
    lk_mesh clean, noisy;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&clean, count, 0, 0, &error), LK_OK);
    memcpy(clean.positions, bunny.positions, 3 * count * sizeof(float));
    assert_int_equal(lk_points_estimate_radii(&clean, 8, 1.0, &error), LK_OK);
    float clean_largest = 0;
    for (size_t i = 0; i < count; i++) clean_largest = fmaxf(clean_largest, clean.radii[i]);

    float lo[3], hi[3];
    lk_mesh_bounds(&bunny, lo, hi);
    double d = bunny_diagonal;
    assert_int_equal(lk_mesh_alloc(&noisy, count + strays, 0, 0, &error), LK_OK);
    memcpy(noisy.positions, bunny.positions, 3 * count * sizeof(float));
    float *stray = noisy.positions + 3 * count;
    for (size_t s = 0; s < lone; s++) /* beyond three corners of the box */
        for (int c = 0; c < 3; c++) stray[3 * s + c] = (float)(c == (int)s ? lo[c] - 0.4 * d : hi[c] + 0.3 * d);
    for (size_t s = 0; s < group; s++) { /* a 4 x 3 grid of spacing d / 10, far away */
        float *p = stray + 3 * (lone + s);
        p[0] = (float)(hi[0] + 2 * d + 0.1 * d * (double)(s % 4));
        p[1] = (float)(hi[1] + 0.1 * d * (double)(s / 4));
        p[2] = hi[2];
    }
    assert_int_equal(lk_points_estimate_radii(&noisy, 8, 1.0, &error), LK_OK);

    size_t unchanged = 0;
    for (size_t i = 0; i < count; i++) unchanged += noisy.radii[i] == clean.radii[i];
    double worst_ratio = 0;
    for (size_t i = 0; i < count + strays; i = i + 97 < count ? i + 97 : (i < count ? count : i + 1)) {
        double ratio = noisy.radii[i] / neighbourhood_median(&noisy, i, 8);
        if (ratio > worst_ratio) worst_ratio = ratio;
        assert_true(ratio <= 4.0);
    }
    float stray_largest = 0;
    for (size_t s = 0; s < strays; s++) stray_largest = fmaxf(stray_largest, noisy.radii[count + s]);
    print_message("bunny vertices + %zu strays: largest stray radius %.4f = %.2f x the clean largest; radius / "
                  "neighbourhood median at most %.2f; %zu of %zu bunny radii unchanged\n",
                  strays, (double)stray_largest, (double)(stray_largest / clean_largest), worst_ratio, unchanged,
                  count);
    assert_true(stray_largest <= 4 * clean_largest);
    for (size_t s = 0; s < strays; s++) assert_true(noisy.radii[count + s] > 0);
    assert_true(unchanged >= count - count / 1000);
    /* The bunny alone: no radius clamped, each the 8th-neighbour spacing. */
    for (size_t i = 0; i < count; i += 997) {
        double distances[8];
        unsigned found = 0;
        for (size_t j = 0; j < count; j++) {
            if (j == i) continue;
            double dj = distance3(clean.positions + 3 * i, clean.positions + 3 * j);
            if (found == 8 && dj >= distances[7]) continue;
            unsigned slot = found < 8 ? found++ : 7;
            while (slot > 0 && distances[slot - 1] > dj) {
                distances[slot] = distances[slot - 1];
                slot--;
            }
            distances[slot] = dj;
        }
        assert_true(clean.radii[i] == (float)distances[7]);
    }
    lk_mesh_free(&clean);
    lk_mesh_free(&noisy);
}

/* Coincident points never get radius 0: with k or more copies of a point,
 * its radius comes from the nearest point elsewhere. */
static void test_radii_coincident_points(void **state)
{
    (void)state;
    lk_mesh kitten, copies;
    lk_error error = {0};
    lk_test_load(lk_test_sample("kitten.xyz"), &kitten);
    const size_t copy_count = 10, count = kitten.vertex_count;
    assert_int_equal(lk_mesh_alloc(&copies, count * copy_count, 0, 0, &error), LK_OK);
    for (size_t c = 0; c < copy_count; c++)
        memcpy(copies.positions + 3 * count * c, kitten.positions, 3 * count * sizeof(float));
    assert_int_equal(lk_points_estimate_radii(&copies, 8, 1.0, &error), LK_OK);
    assert_int_equal(lk_points_estimate_radii(&kitten, 1, 1.0, &error), LK_OK);
    /* Ten copies of each point and k = 8: the 8th neighbour is a copy at
     * distance 0, so the radius is the distance to the nearest distinct
     * point, which is the k = 1 radius of the original set. */
    for (size_t c = 0; c < copy_count; c++)
        for (size_t i = 0; i < count; i++) assert_true(copies.radii[c * count + i] == kitten.radii[i]);
    lk_mesh_free(&copies);
    /* All points at one place, and a single point: a small positive radius. */
    lk_mesh same;
    assert_int_equal(lk_mesh_alloc(&same, 50, 0, 0, &error), LK_OK);
    for (size_t i = 0; i < 150; i++) same.positions[i] = (float)(i % 3) * 100.0f;
    assert_int_equal(lk_points_estimate_radii(&same, 8, 1.0, &error), LK_OK);
    for (size_t i = 0; i < 50; i++) assert_true(same.radii[i] > 0 && same.radii[i] < 1e-3f);
    same.vertex_count = 1;
    assert_int_equal(lk_points_estimate_radii(&same, 8, 1.0, &error), LK_OK);
    assert_true(same.radii[0] > 0);
    /* Empty: nothing to do, not an error. */
    same.vertex_count = 0;
    assert_int_equal(lk_points_estimate_radii(&same, 8, 1.0, &error), LK_OK);
    lk_mesh_free(&same);
    lk_mesh_free(&kitten);
}

static void test_radii_and_normals_bad_input(void **state)
{
    (void)state;
    lk_mesh kitten;
    lk_error error = {0};
    lk_test_load(lk_test_sample("kitten.xyz"), &kitten);
    assert_int_equal(lk_points_estimate_radii(&kitten, 0, 1.0, &error), LK_ERR_INVALID);
    assert_int_equal(lk_points_estimate_radii(&kitten, 100000, 1.0, &error), LK_ERR_INVALID);
    assert_int_equal(lk_points_estimate_radii(&kitten, 8, 0.0, &error), LK_ERR_INVALID);
    assert_int_equal(lk_points_estimate_radii(&kitten, 8, INFINITY, &error), LK_ERR_INVALID);
    assert_int_equal(lk_points_estimate_normals(&kitten, 0, &error), LK_ERR_INVALID);
    assert_null(kitten.radii);
    kitten.positions[3 * 4321 + 2] = NAN;
    assert_int_equal(lk_points_estimate_radii(&kitten, 8, 1.0, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "point 4321: position is not finite");
    float *normals = kitten.normals;
    assert_int_equal(lk_points_estimate_normals(&kitten, 8, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "point 4321");
    assert_ptr_equal(kitten.normals, normals); /* untouched on failure */
    kitten.positions[3 * 4321 + 2] = -INFINITY;
    assert_int_equal(lk_points_estimate_radii(&kitten, 8, 1.0, &error), LK_ERR_RANGE);
    lk_mesh_free(&kitten);
}

/* ---- normals --------------------------------------------------------------- */

/* Normals estimated on the bunny sample (true normals removed) match the
 * surface's: direction and orientation. */
static void test_normals_bunny_sample(void **state)
{
    (void)state;
    lk_mesh points;
    lk_error error = {0};
    assert_int_equal(lk_mesh_copy(&points, &bunny_points, &error), LK_OK);
    float *truth = points.normals;
    points.normals = NULL;
    assert_int_equal(lk_points_estimate_normals(&points, 8, &error), LK_OK);
    assert_non_null(points.normals);
    for (size_t i = 0; i < points.vertex_count; i++)
        assert_float_equal(sqrt(dot3(points.normals + 3 * i, points.normals + 3 * i)), 1.0, 1e-5);
    double within, positive;
    normal_agreement(points.normals, truth, points.vertex_count, &within, &positive);
    print_message("bunny 100k, k=8: %.3f%% within 30 degrees, %.3f%% on the right side\n", 100 * within,
                  100 * positive);
    assert_true(within >= 0.98);
    assert_true(positive >= 0.98);
    /* Existing normals are replaced, deterministically. */
    float *first = malloc(3 * points.vertex_count * sizeof(float));
    assert_non_null(first);
    memcpy(first, points.normals, 3 * points.vertex_count * sizeof(float));
    assert_int_equal(lk_points_estimate_normals(&points, 8, &error), LK_OK);
    assert_memory_equal(first, points.normals, 3 * points.vertex_count * sizeof(float));
    free(first);
    free(truth);
    lk_mesh_free(&points);
}

/* kitten.xyz: estimated normals against the file's. */
static void test_normals_kitten(void **state)
{
    (void)state;
    lk_mesh kitten;
    lk_error error = {0};
    lk_test_load(lk_test_sample("kitten.xyz"), &kitten);
    float *truth = kitten.normals;
    kitten.normals = NULL;
    assert_int_equal(lk_points_estimate_normals(&kitten, 8, &error), LK_OK);
    double within, positive;
    normal_agreement(kitten.normals, truth, kitten.vertex_count, &within, &positive);
    print_message("kitten, k=8: %.3f%% within 30 degrees, %.3f%% on the right side\n", 100 * within, 100 * positive);
    assert_true(within >= 0.98);
    assert_true(positive >= 0.98);
    free(truth);
    lk_mesh_free(&kitten);
}

/* Two bunnies far apart: each part is seeded and oriented on its own. And
 * a thin closed box keeps opposite normals on its two big faces. */
static void test_normals_components_and_thin_sheet(void **state)
{
    (void)state;
    lk_error error = {0};
    size_t half = 30000;
    lk_mesh two;
    assert_int_equal(lk_mesh_alloc(&two, 2 * half, 0, LK_ATTR_NORMALS, &error), LK_OK);
    for (size_t c = 0; c < 2; c++)
        for (size_t i = 0; i < half; i++) {
            /* the second copy shifted by 3 diagonals along x */
            for (int k = 0; k < 3; k++) {
                two.positions[3 * (c * half + i) + k] =
                    bunny_points.positions[3 * (i + c * half) + k] + (k == 0 && c ? (float)(3 * bunny_diagonal) : 0);
                two.normals[3 * (c * half + i) + k] = bunny_points.normals[3 * (i + c * half) + k];
            }
        }
    float *truth = two.normals;
    two.normals = NULL;
    assert_int_equal(lk_points_estimate_normals(&two, 8, &error), LK_OK);
    for (size_t c = 0; c < 2; c++) {
        double within, positive;
        normal_agreement(two.normals + 3 * c * half, truth + 3 * c * half, half, &within, &positive);
        print_message("bunny copy %zu of 2: %.3f%% within 30 degrees, %.3f%% on the right side\n", c + 1, 100 * within,
                      100 * positive);
        assert_true(within >= 0.97 && positive >= 0.98);
    }
    free(truth);
    lk_mesh_free(&two);

    /* A closed thin box: 1 x 1 x 0.02, sampled at 40k points (spacing
     * ~0.007; the 8th neighbour is ~0.012 away, a few are beyond 0.02). The
     * few k-NN edges joining the top face to the bottom one directly join
     * parallel planes, so Hoppe's 1 - |n_i . n_j| alone would let the
     * orientation cross there and flip a whole face (measured: 50% on the
     * right side); the cost of running along the normals prevents it. */
    lk_mesh box;
    static const float corners[] = {0, 0, 0,     1, 0, 0,     1, 1, 0,     0, 1, 0,
                                    0, 0, 0.02f, 1, 0, 0.02f, 1, 1, 0.02f, 0, 1, 0.02f};
    static const uint32_t faces[] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                     1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    lk_test_make_mesh(&box, corners, 8, faces, 12);
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.point_count = 40000;
    lk_mesh points;
    assert_int_equal(lk_mesh_sample_points(&box, &options, &points, NULL, NULL, &error), LK_OK);
    truth = points.normals;
    points.normals = NULL;
    assert_int_equal(lk_points_estimate_normals(&points, 8, &error), LK_OK);
    double within, positive;
    normal_agreement(points.normals, truth, points.vertex_count, &within, &positive);
    print_message("thin box 1 x 1 x 0.02: %.3f%% within 30 degrees, %.3f%% on the right side\n", 100 * within,
                  100 * positive);
    assert_true(positive >= 0.98);
    free(truth);
    lk_mesh_free(&points);
    lk_mesh_free(&box);
}

/* Degenerate neighbourhoods: a plane (exact normals, one side), a line, and
 * points that all coincide still give finite unit normals. */
static void test_normals_degenerate_sets(void **state)
{
    (void)state;
    lk_error error = {0};
    lk_mesh grid;
    lk_test_make_grid(&grid, 40); /* 41 x 41 vertices at z = 0 */
    grid.triangle_count = 0;
    assert_int_equal(lk_points_estimate_normals(&grid, 8, &error), LK_OK);
    for (size_t i = 0; i < grid.vertex_count; i++) {
        const float *n = grid.normals + 3 * i;
        assert_true(n[0] == 0 && n[1] == 0 && n[2] == 1);
    }
    lk_mesh_free(&grid);

    lk_mesh line;
    assert_int_equal(lk_mesh_alloc(&line, 100, 0, 0, &error), LK_OK);
    for (size_t i = 0; i < 100; i++) {
        line.positions[3 * i] = (float)i;
        line.positions[3 * i + 1] = 2.0f * (float)i;
        line.positions[3 * i + 2] = -1.0f;
    }
    assert_int_equal(lk_points_estimate_normals(&line, 6, &error), LK_OK);
    for (size_t i = 0; i < 100; i++) {
        const float *n = line.normals + 3 * i;
        assert_float_equal(sqrt(dot3(n, n)), 1.0, 1e-6);
        assert_float_equal(n[0] + 2 * n[1], 0.0, 1e-5); /* perpendicular to the line */
    }
    for (size_t i = 0; i < 300; i++) line.positions[i] = 0.5f;
    assert_int_equal(lk_points_estimate_normals(&line, 6, &error), LK_OK);
    for (size_t i = 0; i < 100; i++) {
        const float *n = line.normals + 3 * i;
        assert_true(isfinite(n[0]) && isfinite(n[1]) && isfinite(n[2]));
        assert_float_equal(sqrt(dot3(n, n)), 1.0, 1e-6);
    }
    line.vertex_count = 1;
    assert_int_equal(lk_points_estimate_normals(&line, 6, &error), LK_OK);
    assert_true(line.normals[2] == 1);
    line.vertex_count = 0;
    assert_int_equal(lk_points_estimate_normals(&line, 6, &error), LK_OK);
    lk_mesh_free(&line);
}

/* ---- the radii attribute in the mesh functions ------------------------------ */

static void test_radii_follow_vertices(void **state)
{
    (void)state;
    lk_error error = {0};
    /* A 4 x 4 grid whose vertex 3 is replaced by a copy, vertex 25, in
     * every triangle, plus an unused vertex 26. */
    lk_mesh grid, mesh;
    lk_test_make_grid(&grid, 4);
    assert_int_equal(lk_mesh_alloc(&mesh, 27, grid.triangle_count, LK_ATTR_RADII, &error), LK_OK);
    memcpy(mesh.positions, grid.positions, 25 * 3 * sizeof(float));
    memcpy(mesh.positions + 75, grid.positions + 9, 3 * sizeof(float));
    mesh.positions[78] = 9, mesh.positions[79] = 9, mesh.positions[80] = 9;
    memcpy(mesh.indices, grid.indices, 3 * grid.triangle_count * sizeof(uint32_t));
    for (size_t c = 0; c < 3 * grid.triangle_count; c++)
        if (mesh.indices[c] == 3) mesh.indices[c] = 25;
    for (size_t v = 0; v < 27; v++) mesh.radii[v] = (float)(v + 1);
    assert_int_equal(lk_mesh_validate(&mesh, &error), LK_OK);
    lk_mesh copy;
    assert_int_equal(lk_mesh_copy(&copy, &mesh, &error), LK_OK);
    assert_non_null(copy.radii);
    assert_memory_equal(copy.radii, mesh.radii, 27 * sizeof(float));
    size_t merged;
    assert_int_equal(lk_mesh_weld(&copy, 0, &merged, &error), LK_OK);
    assert_int_equal(merged, 1);
    assert_int_equal(copy.vertex_count, 26);
    for (size_t v = 0; v < 25; v++) assert_true(copy.radii[v] == (float)(v + 1));
    assert_true(copy.radii[25] == 27.0f); /* the unused vertex moved down */
    size_t removed;
    assert_int_equal(lk_mesh_remove_unused_vertices(&copy, &removed, &error), LK_OK);
    assert_int_equal(removed, 1);
    assert_int_equal(copy.vertex_count, 25);
    assert_int_equal(lk_mesh_validate(&copy, &error), LK_OK);
    lk_mesh_free(&copy);
    /* Unused vertices in the middle and at the end: the radii compact
     * with the positions. */
    assert_int_equal(lk_mesh_remove_unused_vertices(&mesh, &removed, &error), LK_OK);
    assert_int_equal(removed, 2); /* vertex 3 (replaced by 25) and 26 */
    assert_int_equal(mesh.vertex_count, 25);
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        size_t original = v < 3 ? v : v + 1;
        assert_true(mesh.radii[v] == (float)(original + 1));
        assert_memory_equal(mesh.positions + 3 * v, grid.positions + 3 * (original == 25 ? 3 : original), 12);
    }
    mesh.radii[4] = 0;
    assert_int_equal(lk_mesh_validate(&mesh, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "vertex 4: radius 0 is not a finite number > 0");
    lk_mesh_free(&mesh);
    lk_mesh_free(&grid);
}

/* Clip lines on the vertices of the bunny cut open: the triangles below
 * y = CUT (the ears and head removed), normals from the faces around each
 * vertex. lk_points_estimate_clips (16 neighbours, as the renderer asks)
 * must find the cut's rim from the points alone, turn each cut away from
 * the surface, and leave the rest of the surface whole. */
#define CUT 0.2f
static void test_clips_find_the_border(void **state)
{
    (void)state;
    lk_error error = {0};
    size_t vertex_count = bunny.vertex_count;
    uint32_t *index_of = malloc(vertex_count * sizeof *index_of); /* bunny vertex -> point, or UINT32_MAX */
    uint32_t *kept = malloc(3 * bunny.triangle_count * sizeof *kept);
    assert_non_null(index_of);
    assert_non_null(kept);
    size_t triangle_count = 0, point_count = 0;
    for (size_t v = 0; v < vertex_count; v++) index_of[v] = UINT32_MAX;
    for (size_t t = 0; t < bunny.triangle_count; t++) {
        const uint32_t *corner = bunny.indices + 3 * t;
        if (bunny.positions[3 * corner[0] + 1] >= CUT || bunny.positions[3 * corner[1] + 1] >= CUT ||
            bunny.positions[3 * corner[2] + 1] >= CUT)
            continue;
        for (int c = 0; c < 3; c++) {
            if (index_of[corner[c]] == UINT32_MAX) index_of[corner[c]] = (uint32_t)point_count++;
            kept[3 * triangle_count + c] = index_of[corner[c]];
        }
        triangle_count++;
    }
    lk_mesh open;
    lk_mesh_init(&open);
    open.vertex_count = point_count;
    open.triangle_count = triangle_count;
    open.indices = kept;
    open.positions = malloc(3 * point_count * sizeof(float));
    open.normals = calloc(3 * point_count, sizeof(float));
    double *inward = calloc(3 * point_count, sizeof(double)); /* towards the faces' centroids */
    assert_non_null(open.positions);
    assert_non_null(open.normals);
    assert_non_null(inward);
    for (size_t v = 0; v < vertex_count; v++)
        if (index_of[v] != UINT32_MAX)
            memcpy(open.positions + 3 * index_of[v], bunny.positions + 3 * v, 3 * sizeof(float));
    for (size_t t = 0; t < triangle_count; t++) {
        float n[3];
        triangle_normal(&open, t, n);
        const uint32_t *corner = kept + 3 * t;
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) {
                double centroid = (open.positions[3 * corner[0] + k] + open.positions[3 * corner[1] + k] +
                                   open.positions[3 * corner[2] + k]) /
                                  3.0;
                open.normals[3 * corner[c] + k] += n[k];
                inward[3 * corner[c] + k] += centroid - open.positions[3 * corner[c] + k];
            }
    }
    /* border vertices: on an edge of one triangle (edges keyed by their
     * sorted ends in an open-addressing table) */
    size_t slots = 8 * triangle_count;
    uint64_t *keys = calloc(slots, sizeof *keys);
    unsigned *edge_uses = calloc(slots, sizeof *edge_uses);
    bool *border = calloc(point_count, sizeof *border);
    assert_non_null(keys);
    assert_non_null(edge_uses);
    assert_non_null(border);
    for (size_t t = 0; t < triangle_count; t++)
        for (int e = 0; e < 3; e++) {
            uint64_t a = kept[3 * t + e], b = kept[3 * t + (e + 1) % 3];
            uint64_t key = (a < b ? (a << 32 | b) : (b << 32 | a)) + 1;
            size_t slot = (size_t)((key * 0x9E3779B97F4A7C15ull) % slots);
            while (keys[slot] && keys[slot] != key) slot = (slot + 1) % slots;
            keys[slot] = key;
            edge_uses[slot]++;
        }
    size_t border_count = 0;
    for (size_t slot = 0; slot < slots; slot++)
        if (keys[slot] && edge_uses[slot] == 1) {
            uint64_t key = keys[slot] - 1;
            border[key >> 32] = border[key & 0xFFFFFFFFu] = true;
        }
    for (size_t v = 0; v < point_count; v++) border_count += border[v];

    float *clips = malloc(4 * point_count * sizeof *clips);
    assert_non_null(clips);
    assert_int_equal(lk_points_estimate_clips(&open, 16, clips, &error), LK_OK);
    size_t border_cut = 0, interior_cut = 0, outward = 0;
    for (size_t v = 0; v < point_count; v++) {
        const float *clip = clips + 4 * v, *n = open.normals + 3 * v;
        if (clip[0] == 0 && clip[1] == 0 && clip[2] == 0) continue;
        assert_true(fabs(dot3(clip, clip) - 1) < 1e-5);             /* a unit direction... */
        assert_true(fabs(dot3(clip, n)) < 1e-4 * sqrt(dot3(n, n))); /* ...in the tangent plane */
        assert_true(clip[3] >= 0);
        if (!border[v]) {
            interior_cut++;
            continue;
        }
        border_cut++;
        const double *in = inward + 3 * v;
        outward += clip[0] * in[0] + clip[1] * in[1] + clip[2] * in[2] < 0;
    }
    printf("bunny cut at y = %g: %zu points, %zu on the border, %zu of them cut (%zu away from the surface); "
           "%zu of the %zu others cut\n",
           (double)CUT, point_count, border_count, border_cut, outward, interior_cut, point_count - border_count);
    assert_true(border_count > 200);
    /* measured: 220 of 326 cut, all away from the surface; 103 of 25,754
     * others (mostly next to the rim) */
    assert_true(border_cut >= 0.6 * (double)border_count);
    assert_true(outward >= 0.98 * (double)border_cut);
    assert_true(interior_cut <= 0.005 * (double)(point_count - border_count));

    /* bad input: no normals, no array, no neighbours */
    float *normals = open.normals;
    open.normals = NULL;
    assert_int_equal(lk_points_estimate_clips(&open, 16, clips, &error), LK_ERR_INVALID);
    open.normals = normals;
    assert_int_equal(lk_points_estimate_clips(&open, 16, NULL, &error), LK_ERR_INVALID);
    assert_int_equal(lk_points_estimate_clips(&open, 0, clips, &error), LK_ERR_INVALID);
    free(clips);
    free(keys);
    free(edge_uses);
    free(border);
    free(inward);
    free(index_of);
    lk_mesh_free(&open);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sample_bunny_on_surface_area_proportional),
        cmocka_unit_test(test_sample_deterministic_for_a_seed),
        cmocka_unit_test(test_sample_interpolates_vertex_normals),
        cmocka_unit_test(test_sample_poisson_spacing),
        cmocka_unit_test(test_sample_bad_input),
        cmocka_unit_test(test_radii_bunny_knn_distance),
        cmocka_unit_test(test_radii_kitten),
        cmocka_unit_test(test_radii_stray_points_bounded),
        cmocka_unit_test(test_radii_coincident_points),
        cmocka_unit_test(test_radii_and_normals_bad_input),
        cmocka_unit_test(test_normals_bunny_sample),
        cmocka_unit_test(test_normals_kitten),
        cmocka_unit_test(test_normals_components_and_thin_sheet),
        cmocka_unit_test(test_normals_degenerate_sets),
        cmocka_unit_test(test_radii_follow_vertices),
        cmocka_unit_test(test_clips_find_the_border),
    };
    return cmocka_run_group_tests(tests, load_bunny, free_bunny);
}
