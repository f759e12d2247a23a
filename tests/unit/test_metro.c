/* SPDX-License-Identifier: MIT */
/* Tests of the Metro-style surface distance (src/metro.c): exact
 * point-triangle distances in every Voronoi region and for degenerate
 * triangles, nearest-point queries against brute force, one-sided measures
 * against a brute-force reference on the same samples, known answers on the
 * bunny (itself, translated), analytic means, determinism across thread
 * counts, point sets, and errors. */
#include <math.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* Internal entry points of src/metro.c, exposed for these tests only. */
double lk__triangle_closest_point(const float tri[9], const double point[3], double closest[3]);
lk_status lk__metro_samples(const lk_mesh *mesh, const lk_metro_options *options, double **points,
                            unsigned char **averaged, size_t *count, lk_error *error);

/* ---- an independent reference: project, else nearest of the three sides ---- */

static double ref_segment(const double a[3], const double b[3], const double p[3])
{
    double ab[3], ap[3], length_sq = 0, along = 0;
    for (int k = 0; k < 3; k++) {
        ab[k] = b[k] - a[k];
        ap[k] = p[k] - a[k];
        length_sq += ab[k] * ab[k];
        along += ap[k] * ab[k];
    }
    double t = length_sq > 0 ? along / length_sq : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double d = 0;
    for (int k = 0; k < 3; k++) {
        double e = a[k] + t * ab[k] - p[k];
        d += e * e;
    }
    return d;
}

/* Squared distance from p to triangle (a, b, c): the projection onto the
 * plane when it falls inside (barycentric signs), else the nearest side. */
static double ref_triangle(const float *fa, const float *fb, const float *fc, const double p[3])
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++) {
        a[k] = fa[k];
        b[k] = fb[k];
        c[k] = fc[k];
    }
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    double nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    double best = ref_segment(a, b, p);
    double d = ref_segment(b, c, p);
    if (d < best) best = d;
    d = ref_segment(c, a, p);
    if (d < best) best = d;
    if (nn > 0) {
        double h = ((p[0] - a[0]) * n[0] + (p[1] - a[1]) * n[1] + (p[2] - a[2]) * n[2]) / nn;
        double q[3] = {p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]};
        /* inside when q is on the inner side of all three edges */
        const double *corner[3] = {a, b, c};
        bool inside = true;
        for (int e = 0; e < 3 && inside; e++) {
            const double *s = corner[e], *t = corner[(e + 1) % 3];
            double edge[3] = {t[0] - s[0], t[1] - s[1], t[2] - s[2]}, sq[3] = {q[0] - s[0], q[1] - s[1], q[2] - s[2]};
            double cr[3] = {edge[1] * sq[2] - edge[2] * sq[1], edge[2] * sq[0] - edge[0] * sq[2],
                            edge[0] * sq[1] - edge[1] * sq[0]};
            if (cr[0] * n[0] + cr[1] * n[1] + cr[2] * n[2] < 0) inside = false;
        }
        if (inside) {
            double plane = h * h * nn;
            if (plane < best) best = plane;
        }
    }
    return best;
}

static double ref_nearest_sq(const lk_mesh *mesh, const double p[3])
{
    double best = INFINITY;
    if (mesh->triangle_count == 0) {
        for (size_t v = 0; v < mesh->vertex_count; v++) {
            double d = 0;
            for (int k = 0; k < 3; k++) {
                double e = mesh->positions[3 * v + k] - p[k];
                d += e * e;
            }
            if (d < best) best = d;
        }
        return best;
    }
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *tri = mesh->indices + 3 * t;
        double d =
            ref_triangle(mesh->positions + 3 * tri[0], mesh->positions + 3 * tri[1], mesh->positions + 3 * tri[2], p);
        if (d < best) best = d;
    }
    return best;
}

static void assert_close(double actual, double expected, double relative, const char *what)
{
    double tolerance = relative * fabs(expected) + 1e-300;
    if (!(fabs(actual - expected) <= tolerance))
        fail_msg("%s: got %.17g, expected %.17g (tolerance %.3g)", what, actual, expected, tolerance);
}

/* ---- meshes ---- */

/* The first `triangle_count` triangles of a mesh (all vertices kept). */
static void take_triangles(lk_mesh *mesh, size_t triangle_count)
{
    assert_true(mesh->triangle_count >= triangle_count);
    mesh->triangle_count = triangle_count;
}

/* Moves each vertex by a deterministic pseudo-random offset of up to
 * `amount` per coordinate. */
static void perturb(lk_mesh *mesh, double amount, uint64_t seed)
{
    uint64_t state = seed;
    for (size_t i = 0; i < 3 * mesh->vertex_count; i++) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        double unit = (double)(state >> 11) / 9007199254740992.0;
        mesh->positions[i] = (float)(mesh->positions[i] + amount * (2 * unit - 1));
    }
}

/* A wavy height field over [0,1]^2 with n x n quads. */
static void make_wavy_grid(lk_mesh *mesh, int n, double amplitude, double phase)
{
    lk_error error = {0};
    size_t side = (size_t)n + 1;
    assert_int_equal(lk_mesh_alloc(mesh, side * side, 2 * (size_t)n * n, 0, &error), LK_OK);
    for (size_t j = 0; j < side; j++)
        for (size_t i = 0; i < side; i++) {
            float *p = mesh->positions + 3 * (j * side + i);
            double x = (double)i / n, y = (double)j / n;
            p[0] = (float)x;
            p[1] = (float)y;
            p[2] = (float)(amplitude * sin(6.0 * x + phase) * cos(5.0 * y - phase));
        }
    size_t t = 0;
    for (size_t j = 0; j < (size_t)n; j++)
        for (size_t i = 0; i < (size_t)n; i++) {
            uint32_t v = (uint32_t)(j * side + i);
            uint32_t quad[6] = {v, v + 1, v + (uint32_t)side + 1, v, v + (uint32_t)side + 1, v + (uint32_t)side};
            memcpy(mesh->indices + 3 * t, quad, sizeof quad);
            t += 2;
        }
}

/* ---- point-triangle distance ---- */

static void check_point(const float tri[9], double x, double y, double z, double distance, double cx, double cy,
                        double cz)
{
    double p[3] = {x, y, z}, q[3];
    double d = lk__triangle_closest_point(tri, p, q);
    assert_close(sqrt(d), distance, 1e-12, "distance");
    assert_close(q[0], cx, 1e-12, "closest x");
    assert_close(q[1], cy, 1e-12, "closest y");
    assert_close(q[2], cz, 1e-12, "closest z");
}

static void test_point_triangle_regions(void **state)
{
    (void)state;
    const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    check_point(tri, 0.2, 0.3, 1, 1, 0.2, 0.3, 0);      /* face, above */
    check_point(tri, 0.2, 0.3, -2, 2, 0.2, 0.3, 0);     /* face, below */
    check_point(tri, -1, -1, 0.5, 1.5, 0, 0, 0);        /* vertex a */
    check_point(tri, 2, -1, 0, sqrt(2.0), 1, 0, 0);     /* vertex b */
    check_point(tri, -0.5, 2, 0, sqrt(1.25), 0, 1, 0);  /* vertex c */
    check_point(tri, 0.5, -1, 1, sqrt(2.0), 0.5, 0, 0); /* edge ab */
    check_point(tri, -1, 0.5, 0, 1, 0, 0.5, 0);         /* edge ac */
    check_point(tri, 1, 1, 0, sqrt(0.5), 0.5, 0.5, 0);  /* edge bc */
    check_point(tri, 0.25, 0.25, 0, 0, 0.25, 0.25, 0);  /* on the face */
    check_point(tri, 1, 0, 0, 0, 1, 0, 0);              /* on a corner */
}

static void test_point_triangle_degenerate(void **state)
{
    (void)state;
    const float collinear[9] = {0, 0, 0, 1, 0, 0, 2, 0, 0};
    check_point(collinear, 1.5, 1, 0, 1, 1.5, 0, 0);
    check_point(collinear, 3, 0, 0, 1, 2, 0, 0);
    check_point(collinear, -1, 0, 1, sqrt(2.0), 0, 0, 0);
    const float middle_first[9] = {1, 0, 0, 0, 0, 0, 2, 0, 0}; /* a between b and c */
    check_point(middle_first, 0.5, 0, 3, 3, 0.5, 0, 0);
    const float repeated[9] = {0, 0, 0, 0, 0, 0, 0, 2, 0};
    check_point(repeated, 1, 1, 0, 1, 0, 1, 0);
    check_point(repeated, 0, 3, 0, 1, 0, 2, 0);
    const float repeated_last[9] = {0, 0, 0, 0, 2, 0, 0, 2, 0};
    check_point(repeated_last, 1, 1, 0, 1, 0, 1, 0);
    const float single[9] = {1, 2, 3, 1, 2, 3, 1, 2, 3};
    check_point(single, 1, 2, 5, 2, 1, 2, 3);
    /* a sliver: nearly collinear, but the answer is still the segment's */
    const float sliver[9] = {0, 0, 0, 1, 1e-12f, 0, 2, 0, 0};
    check_point(sliver, 1, -1, 0, 1, 1, 0, 0);
}

/* Random points against random triangles (some thin) agree with the
 * independent reference. */
static void test_point_triangle_random(void **state)
{
    (void)state;
    uint64_t seed = 12345;
    for (int trial = 0; trial < 20000; trial++) {
        float tri[9];
        double p[3], q[3];
        for (int k = 0; k < 9; k++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            tri[k] = (float)((double)(seed >> 11) / 9007199254740992.0 * 2 - 1);
        }
        if (trial % 4 == 0) /* make c nearly on line ab */
            for (int k = 0; k < 3; k++) tri[6 + k] = (float)(tri[k] + 0.37 * (tri[3 + k] - tri[k]) + 1e-4 * k);
        for (int k = 0; k < 3; k++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            p[k] = (double)(seed >> 11) / 9007199254740992.0 * 4 - 2;
        }
        double d = lk__triangle_closest_point(tri, p, q);
        double expected = ref_triangle(tri, tri + 3, tri + 6, p);
        assert_close(sqrt(d), sqrt(expected), 1e-9, "random triangle distance");
        double dq = 0;
        for (int k = 0; k < 3; k++) dq += (q[k] - p[k]) * (q[k] - p[k]);
        assert_close(sqrt(dq), sqrt(expected), 1e-9, "distance to the closest point");
    }
}

/* ---- nearest-point queries ---- */

static void test_nearest_matches_brute_force(void **state)
{
    (void)state;
    lk_mesh mesh;
    make_wavy_grid(&mesh, 20, 0.2, 0.3);
    lk_surface_index *index = NULL;
    lk_error error = {0};
    assert_int_equal(lk_surface_index_build(&mesh, &index, &error), LK_OK);
    uint64_t seed = 99;
    for (int i = 0; i < 3000; i++) {
        double p[3], q[3];
        for (int k = 0; k < 3; k++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            p[k] = (double)(seed >> 11) / 9007199254740992.0 * 2 - 0.5;
        }
        uint32_t primitive = UINT32_MAX;
        double d = lk_surface_index_nearest(index, p, INFINITY, q, &primitive);
        assert_close(d, sqrt(ref_nearest_sq(&mesh, p)), 1e-9, "nearest distance");
        assert_true(primitive < mesh.triangle_count);
        const uint32_t *tri = mesh.indices + 3 * primitive;
        double own =
            ref_triangle(mesh.positions + 3 * tri[0], mesh.positions + 3 * tri[1], mesh.positions + 3 * tri[2], p);
        assert_close(sqrt(own), d, 1e-9, "distance to the reported triangle");
        double dq = sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]));
        assert_close(dq, d, 1e-9, "distance to the reported point");
    }
    lk_surface_index_free(index);
    lk_mesh_free(&mesh);
}

static void test_nearest_max_distance(void **state)
{
    (void)state;
    const float positions[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 0, 6, 5, 0, 5, 6, 0};
    const uint32_t indices[] = {0, 1, 2, 3, 4, 5};
    lk_mesh mesh;
    lk_test_make_mesh(&mesh, positions, 6, indices, 2);
    lk_surface_index *index = NULL;
    assert_int_equal(lk_surface_index_build(&mesh, &index, NULL), LK_OK);
    lk_mesh_free(&mesh); /* the index keeps its own copy */
    double p[3] = {5.2, 5.2, 2}, q[3];
    uint32_t primitive = 7;
    assert_true(isinf(lk_surface_index_nearest(index, p, 1.5, q, &primitive)));
    assert_int_equal(primitive, 7); /* untouched when nothing is found */
    assert_close(lk_surface_index_nearest(index, p, 2.0, q, &primitive), 2.0, 1e-15, "at the bound");
    assert_int_equal(primitive, 1);
    assert_close(q[0], 5.2, 1e-6, "closest x");
    assert_close(lk_surface_index_nearest(index, p, INFINITY, NULL, NULL), 2.0, 1e-15, "unbounded");
    double origin[3] = {0.1, 0.1, -1};
    assert_close(lk_surface_index_nearest(index, origin, INFINITY, q, &primitive), 1.0, 1e-15, "first triangle");
    assert_int_equal(primitive, 0);
    assert_true(isinf(lk_surface_index_nearest(NULL, origin, INFINITY, q, &primitive)));
    lk_surface_index_free(index);
    lk_surface_index_free(NULL);
}

/* ---- one-sided measures against brute force on the same samples ---- */

static void check_one_sided_against_brute_force(const lk_mesh *source, const lk_mesh *target,
                                                const lk_metro_options *options)
{
    lk_error error = {0};
    double *points = NULL;
    unsigned char *averaged = NULL;
    size_t count = 0;
    assert_int_equal(lk__metro_samples(source, options, &points, &averaged, &count, &error), LK_OK);
    double max = 0, sum = 0, sum_sq = 0;
    size_t averaged_count = 0;
    for (size_t i = 0; i < count; i++) {
        double d_sq = ref_nearest_sq(target, points + 3 * i);
        double d = sqrt(d_sq);
        if (d > max) max = d;
        if (averaged[i]) {
            sum += d;
            sum_sq += d_sq;
            averaged_count++;
        }
    }
    assert_true(averaged_count > 0);
    lk_surface_index *index = NULL;
    assert_int_equal(lk_surface_index_build(target, &index, &error), LK_OK);
    lk_distance_stats stats;
    assert_int_equal(lk_metro_one_sided(source, index, options, &stats, &error), LK_OK);
    assert_int_equal(stats.sample_count, count);
    assert_close(stats.max, max, 1e-6, "max");
    assert_close(stats.mean, sum / (double)averaged_count, 1e-6, "mean");
    assert_close(stats.rms, sqrt(sum_sq / (double)averaged_count), 1e-6, "rms");
    assert_true(stats.max > 0);
    lk_surface_index_free(index);
    free(points);
    free(averaged);
}

static void test_one_sided_cow_subset(void **state)
{
    (void)state;
    lk_mesh cow, perturbed;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    assert_int_equal(cow.triangle_count, 5804);
    take_triangles(&cow, 700);
    lk_error error = {0};
    assert_int_equal(lk_mesh_copy(&perturbed, &cow, &error), LK_OK);
    perturb(&perturbed, 0.01 * lk_mesh_bounds(&cow, NULL, NULL), 7);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = 4;
    check_one_sided_against_brute_force(&cow, &perturbed, &options);
    check_one_sided_against_brute_force(&perturbed, &cow, &options);
    options.sample_vertices = -1;
    options.sample_edges = -1;
    options.seed = 42;
    check_one_sided_against_brute_force(&cow, &perturbed, &options);
    lk_mesh_free(&cow);
    lk_mesh_free(&perturbed);
}

static void test_one_sided_wavy_grids(void **state)
{
    (void)state;
    lk_mesh a, b;
    make_wavy_grid(&a, 24, 0.1, 0.0);
    make_wavy_grid(&b, 17, 0.12, 0.4);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.sample_count = 20000;
    options.thread_count = 2;
    check_one_sided_against_brute_force(&a, &b, &options);
    check_one_sided_against_brute_force(&b, &a, &options);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

/* Degenerate triangles (repeated vertices, collinear corners, duplicates)
 * in the source and in the target. */
static void make_degenerate(lk_mesh *mesh, size_t every)
{
    for (size_t t = 0; t < mesh->triangle_count; t += every) {
        uint32_t *tri = mesh->indices + 3 * t;
        if (t % 3 == 0)
            tri[1] = tri[0]; /* repeated vertex */
        else if (t % 3 == 1) /* collinear: third corner halfway along the first side */
            for (int k = 0; k < 3; k++)
                mesh->positions[3 * tri[2] + k] =
                    0.5f * (mesh->positions[3 * tri[0] + k] + mesh->positions[3 * tri[1] + k]);
        else
            memcpy(tri, tri - 3, 3 * sizeof(uint32_t)); /* duplicate of the previous one */
    }
}

/* Appends to `mesh` lone degenerate triangles lying on `surface`: a
 * collinear one, one with a repeated corner and a single point, so that
 * they are the nearest geometry for part of the surface. */
static void add_lone_degenerates(lk_mesh *mesh, const lk_mesh *surface)
{
    size_t v0 = mesh->vertex_count, t0 = mesh->triangle_count;
    lk_error error = {0};
    lk_mesh grown;
    assert_int_equal(lk_mesh_alloc(&grown, v0 + 6, t0 + 3, 0, &error), LK_OK);
    memcpy(grown.positions, mesh->positions, v0 * 3 * sizeof(float));
    memcpy(grown.indices, mesh->indices, t0 * 3 * sizeof(uint32_t));
    const size_t picks[5] = {20, 100, 60, 150, 200}; /* surface vertices */
    for (int i = 0; i < 5; i++)
        memcpy(grown.positions + 3 * (v0 + i), surface->positions + 3 * picks[i], 3 * sizeof(float));
    for (int k = 0; k < 3; k++) /* midpoint of the first two: collinear */
        grown.positions[3 * (v0 + 5) + k] = 0.5f * (grown.positions[3 * v0 + k] + grown.positions[3 * (v0 + 1) + k]);
    uint32_t v = (uint32_t)v0;
    const uint32_t lone[9] = {v, v + 5, v + 1, v + 2, v + 2, v + 3, v + 4, v + 4, v + 4};
    memcpy(grown.indices + 3 * t0, lone, sizeof lone);
    lk_mesh_free(mesh);
    *mesh = grown;
}

static void test_one_sided_degenerate_triangles(void **state)
{
    (void)state;
    lk_mesh a, b;
    make_wavy_grid(&a, 14, 0.1, 0.1);
    make_wavy_grid(&b, 11, 0.1, 0.6);
    make_degenerate(&a, 5);
    make_degenerate(&b, 4);
    add_lone_degenerates(&b, &a);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = 20;
    check_one_sided_against_brute_force(&a, &b, &options);
    check_one_sided_against_brute_force(&b, &a, &options);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

/* A mesh without area: a "triangle" along a segment at height 1 above the
 * unit square. Its samples share the face samples equally. */
static void test_zero_area_mesh(void **state)
{
    (void)state;
    const float segment[] = {0, 0, 1, 0.5f, 0, 1, 1, 0, 1};
    const uint32_t segment_indices[] = {0, 1, 2};
    const float square[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint32_t square_indices[] = {0, 1, 2, 0, 2, 3};
    lk_mesh a, b;
    lk_test_make_mesh(&a, segment, 3, segment_indices, 1);
    lk_test_make_mesh(&b, square, 4, square_indices, 2);
    lk_metro_result result;
    lk_error error = {0};
    assert_int_equal(lk_metro(&a, &b, NULL, &result, NULL, NULL, &error), LK_OK);
    assert_close(result.forward.max, 1, 1e-15, "segment to square, max");
    assert_close(result.forward.mean, 1, 1e-15, "segment to square, mean");
    assert_close(result.forward.rms, 1, 1e-15, "segment to square, rms");
    assert_int_equal(result.forward.sample_count, 10 + 3 + 1);
    /* square to segment: (x, y, 0) is sqrt(1 + y^2) away */
    assert_close(result.backward.max, sqrt(2.0), 1e-12, "square to segment, max");
    assert_true(result.backward.mean > 1 && result.backward.mean < sqrt(2.0));
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

/* ---- sampling ---- */

static void test_sample_layout(void **state)
{
    (void)state;
    /* Three triangles of areas 0.5, 0.4 and 0.1 tiling the unit square. */
    const float positions[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0.2f, 1, 0, 0, 1, 0};
    const uint32_t indices[] = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    lk_mesh mesh;
    lk_test_make_mesh(&mesh, positions, 5, indices, 3);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.sample_count = 1000;
    double *points;
    unsigned char *averaged;
    size_t count;
    assert_int_equal(lk__metro_samples(&mesh, &options, &points, &averaged, &count, NULL), LK_OK);
    /* 1000 face samples, 5 vertices, and edge samples at the linear density
     * matching the faces' (sqrt(1000 / area 1) per unit length) along the 7
     * unique edges of total length 6.4340: round(203.47) = 203. */
    assert_int_equal(count, 1000 + 5 + 203);
    size_t per_triangle[3] = {0, 0, 0}, faces = 0;
    for (size_t i = 0; i < count; i++) {
        const double *p = points + 3 * i;
        assert_true(p[0] >= 0 && p[0] <= 1 && p[1] >= 0 && p[1] <= 1 && p[2] == 0);
        if (!averaged[i]) continue;
        faces++;
        /* which triangle: below the diagonal y < x, else left of x = 0.2 y */
        if (p[1] < p[0])
            per_triangle[0]++;
        else if (p[0] > 0.2 * p[1])
            per_triangle[1]++;
        else
            per_triangle[2]++;
    }
    assert_int_equal(faces, 1000);
    /* stratified by area: exactly 500, 400, 100 (up to samples on the borders) */
    assert_true(per_triangle[0] >= 498 && per_triangle[0] <= 502);
    assert_true(per_triangle[1] >= 398 && per_triangle[1] <= 402);
    assert_true(per_triangle[2] >= 98 && per_triangle[2] <= 102);
    free(points);
    free(averaged);
    /* without vertices and edges only face samples remain */
    options.sample_vertices = -1;
    options.sample_edges = -1;
    assert_int_equal(lk__metro_samples(&mesh, &options, &points, &averaged, &count, NULL), LK_OK);
    assert_int_equal(count, 1000);
    free(points);
    free(averaged);
    lk_mesh_free(&mesh);
}

/* The unit square against the same square tilted to z = x: a point
 * (x, y, 0) is x / sqrt(2) from it, so mean = 1/(2 sqrt 2), RMS =
 * 1/sqrt(6), max = 1/sqrt(2). Uses unequal triangles to check area weighting. */
static void test_analytic_tilted_square(void **state)
{
    (void)state;
    const float flat[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0.2f, 1, 0, 0, 1, 0};
    const float tilted[] = {0, 0, 0, 1, 0, 1, 1, 1, 1, 0, 1, 0};
    const uint32_t flat_indices[] = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    const uint32_t tilted_indices[] = {0, 1, 2, 0, 2, 3};
    lk_mesh a, b;
    lk_test_make_mesh(&a, flat, 5, flat_indices, 3);
    lk_test_make_mesh(&b, tilted, 4, tilted_indices, 2);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.sample_count = 1000000;
    lk_metro_result result;
    lk_error error = {0};
    assert_int_equal(lk_metro(&a, &b, &options, &result, NULL, NULL, &error), LK_OK);
    assert_close(result.forward.max, 1 / sqrt(2.0), 1e-7, "forward max");
    assert_close(result.forward.mean, 1 / (2 * sqrt(2.0)), 2e-3, "forward mean");
    assert_close(result.forward.rms, 1 / sqrt(6.0), 2e-3, "forward rms");
    /* tilted point (x, y, x) is x from the flat square: area element sqrt 2
     * is uniform, so the same distribution scaled by sqrt(2) */
    assert_close(result.backward.max, 1.0, 1e-7, "backward max");
    assert_close(result.backward.mean, 0.5, 2e-3, "backward mean");
    assert_close(result.backward.rms, 1 / sqrt(3.0), 2e-3, "backward rms");
    assert_close(result.hausdorff, 1.0, 1e-7, "hausdorff");
    assert_close(result.diagonal, sqrt(2.0), 1e-7, "diagonal of A");
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

/* ---- the bunny ---- */

static void test_bunny_against_itself(void **state)
{
    (void)state;
    lk_mesh bunny;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    assert_int_equal(bunny.triangle_count, 69666);
    lk_metro_result result;
    lk_error error = {0};
    assert_int_equal(lk_metro(&bunny, &bunny, NULL, &result, NULL, NULL, &error), LK_OK);
    double diagonal = lk_mesh_bounds(&bunny, NULL, NULL);
    assert_close(result.diagonal, diagonal, 1e-15, "diagonal");
    assert_true(result.hausdorff <= 1e-6 * diagonal);
    assert_true(result.forward.mean <= 1e-6 * diagonal && result.forward.rms <= 1e-6 * diagonal);
    assert_true(result.backward.mean <= 1e-6 * diagonal && result.backward.rms <= 1e-6 * diagonal);
    /* 10 per face, every vertex, and 534,549 edge samples (Metro's linear
     * density sqrt(face samples / area) along 104,499 edges) */
    assert_int_equal(result.forward.sample_count, 696660 + bunny.vertex_count + 534549);
    assert_int_equal(result.sample_count, 2 * result.forward.sample_count);
    assert_true(result.seconds > 0);
    lk_mesh_free(&bunny);
}

static void test_bunny_translated(void **state)
{
    (void)state;
    lk_mesh bunny, moved;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_error error = {0};
    assert_int_equal(lk_mesh_copy(&moved, &bunny, &error), LK_OK);
    double diagonal = lk_mesh_bounds(&bunny, NULL, NULL);
    lk_mesh_translate(&moved, 0.01 * diagonal, 0, 0);
    lk_metro_result result;
    assert_int_equal(lk_metro(&bunny, &moved, NULL, &result, NULL, NULL, &error), LK_OK);
    double forward = result.forward.max / diagonal, backward = result.backward.max / diagonal;
    if (fabs(forward - 0.01) > 1e-4 || fabs(backward - 0.01) > 1e-4)
        fail_msg("max distances %.6f%%, %.6f%% of the diagonal, expected 1%%", 100 * forward, 100 * backward);
    assert_close(result.hausdorff, forward > backward ? result.forward.max : result.backward.max, 0, "hausdorff");
    assert_true(result.forward.mean < 0.01 * diagonal && result.forward.mean > 0.001 * diagonal);
    assert_true(result.forward.rms < 0.01 * diagonal && result.forward.rms > result.forward.mean);
    assert_true(result.backward.mean < 0.01 * diagonal && result.backward.rms < 0.01 * diagonal);
    lk_mesh_free(&bunny);
    lk_mesh_free(&moved);
}

/* ---- determinism ---- */

static void test_thread_count_does_not_matter(void **state)
{
    (void)state;
    lk_mesh bunny, moved;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_error error = {0};
    assert_int_equal(lk_mesh_copy(&moved, &bunny, &error), LK_OK);
    perturb(&moved, 0.002, 3);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = 3;
    options.seed = 77;
    lk_metro_result results[3];
    int threads[3] = {1, 2, 3};
    for (int i = 0; i < 3; i++) {
        options.thread_count = threads[i];
        assert_int_equal(lk_metro(&bunny, &moved, &options, &results[i], NULL, NULL, &error), LK_OK);
        results[i].seconds = 0;
    }
    assert_true(results[0].forward.max > 0 && results[0].forward.mean > 0);
    assert_memory_equal(&results[0], &results[1], sizeof results[0]);
    assert_memory_equal(&results[0], &results[2], sizeof results[0]);
    /* another seed gives other samples, hence (slightly) other numbers */
    options.seed = 78;
    lk_metro_result other;
    assert_int_equal(lk_metro(&bunny, &moved, &options, &other, NULL, NULL, &error), LK_OK);
    assert_true(other.forward.mean != results[0].forward.mean);
    assert_close(other.forward.mean, results[0].forward.mean, 0.01, "mean under another seed");
    lk_mesh_free(&bunny);
    lk_mesh_free(&moved);
}

/* ---- point sets ---- */

static void test_point_set_target(void **state)
{
    (void)state;
    lk_mesh surface, points;
    make_wavy_grid(&surface, 12, 0.15, 0.2);
    lk_mesh grid_points;
    make_wavy_grid(&grid_points, 9, 0.1, 0.7);
    /* a point set: the vertices of another grid */
    lk_test_make_mesh(&points, grid_points.positions, grid_points.vertex_count, NULL, 0);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = 5;
    check_one_sided_against_brute_force(&surface, &points, &options);
    /* point set as the source: its vertices are the samples, mean/rms over them */
    check_one_sided_against_brute_force(&points, &surface, &options);
    lk_metro_result result;
    lk_error error = {0};
    assert_int_equal(lk_metro(&surface, &points, &options, &result, NULL, NULL, &error), LK_OK);
    assert_int_equal(result.backward.sample_count, points.vertex_count);
    assert_true(result.forward.max > result.backward.max); /* the surface is far from sparse points */
    lk_mesh_free(&surface);
    lk_mesh_free(&points);
    lk_mesh_free(&grid_points);
}

static void test_point_set_known_answer(void **state)
{
    (void)state;
    const float square[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint32_t indices[] = {0, 1, 2, 0, 2, 3};
    const float cloud[] = {0.5f, 0.5f, 1, 0.5f, 0.5f, -3, 2, 0.5f, 0};
    lk_mesh a, b;
    lk_test_make_mesh(&a, square, 4, indices, 2);
    lk_test_make_mesh(&b, cloud, 3, NULL, 0);
    lk_metro_result result;
    lk_error error = {0};
    assert_int_equal(lk_metro(&a, &b, NULL, &result, NULL, NULL, &error), LK_OK);
    /* backward: the three points are 1, 3 and 1 from the square */
    assert_close(result.backward.max, 3, 1e-15, "point set max");
    assert_close(result.backward.mean, 5.0 / 3.0, 1e-15, "point set mean");
    assert_close(result.backward.rms, sqrt(11.0 / 3.0), 1e-15, "point set rms");
    assert_int_equal(result.backward.sample_count, 3);
    /* forward: corner (0,0,0) is nearest to (0.5,0.5,1): sqrt(1.5) */
    assert_close(result.forward.max, sqrt(1.5), 1e-12, "to a point set");
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

/* ---- errors and progress ---- */

static void test_errors(void **state)
{
    (void)state;
    const float square[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint32_t indices[] = {0, 1, 2, 0, 2, 3};
    lk_mesh good, empty, bad;
    lk_test_make_mesh(&good, square, 4, indices, 2);
    lk_mesh_init(&empty);
    lk_test_make_mesh(&bad, square, 4, indices, 2);
    bad.positions[4] = NAN;
    lk_metro_result result;
    lk_error error = {0};
    assert_int_equal(lk_metro(NULL, &good, NULL, &result, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "mesh A");
    assert_int_equal(lk_metro(&good, &empty, NULL, &result, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "mesh B is empty");
    assert_int_equal(lk_metro(&bad, &good, NULL, &result, NULL, NULL, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "not finite");
    lk_assert_message_contains(error, "vertex 1");
    assert_int_equal(lk_metro(&good, &good, NULL, NULL, NULL, NULL, &error), LK_ERR_INVALID);

    lk_surface_index *index = (lk_surface_index *)&error; /* must be reset to NULL */
    assert_int_equal(lk_surface_index_build(&empty, &index, &error), LK_ERR_INVALID);
    assert_null(index);
    lk_assert_message_contains(error, "no vertices");
    assert_int_equal(lk_surface_index_build(&bad, &index, &error), LK_ERR_RANGE);
    assert_int_equal(lk_surface_index_build(NULL, &index, &error), LK_ERR_INVALID);
    bad.positions[4] = 0;
    bad.indices[5] = 9;
    assert_int_equal(lk_surface_index_build(&bad, &index, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "out of range");

    assert_int_equal(lk_surface_index_build(&good, &index, &error), LK_OK);
    lk_distance_stats stats;
    assert_int_equal(lk_metro_one_sided(&empty, index, NULL, &stats, &error), LK_ERR_INVALID);
    assert_int_equal(lk_metro_one_sided(&good, NULL, NULL, &stats, &error), LK_ERR_INVALID);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = 0;
    assert_int_equal(lk_metro_one_sided(&good, index, &options, &stats, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "samples_per_face");
    options.samples_per_face = NAN;
    assert_int_equal(lk_metro_one_sided(&good, index, &options, &stats, &error), LK_ERR_INVALID);
    lk_metro_options_default(&options);
    options.thread_count = -2;
    assert_int_equal(lk_metro_one_sided(&good, index, &options, &stats, &error), LK_ERR_INVALID);
    lk_metro_options_default(&options);
    options.samples_per_face = 1e15;
    assert_int_equal(lk_metro_one_sided(&good, index, &options, &stats, &error), LK_ERR_LIMIT);
    lk_surface_index_free(index);
    lk_mesh_free(&good);
    lk_mesh_free(&bad);
}

typedef struct progress_log {
    pthread_t main_thread;
    int calls;
    int cancel_after; /* cancel at this call (0 = never) */
    double last_fraction;
    bool wrong_thread, went_back;
} progress_log;

static int record_progress(void *user, double fraction, const char *stage)
{
    progress_log *log = user;
    assert_non_null(stage);
    if (!pthread_equal(pthread_self(), log->main_thread)) log->wrong_thread = true;
    if (fraction < log->last_fraction || fraction > 1) log->went_back = true;
    log->last_fraction = fraction;
    log->calls++;
    return log->cancel_after && log->calls >= log->cancel_after;
}

static void test_progress_and_cancel(void **state)
{
    (void)state;
    lk_mesh a, b;
    make_wavy_grid(&a, 40, 0.1, 0.0);
    make_wavy_grid(&b, 30, 0.1, 0.5);
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.thread_count = 2;
    options.sample_count = 200000; /* many chunks */
    lk_metro_result result;
    lk_error error = {0};
    progress_log log = {pthread_self(), 0, 0, 0, false, false};
    assert_int_equal(lk_metro(&a, &b, &options, &result, record_progress, &log, &error), LK_OK);
    assert_true(log.calls >= 3);
    assert_false(log.wrong_thread);
    assert_false(log.went_back);
    assert_true(log.last_fraction == 1.0);
    progress_log cancel = {pthread_self(), 0, 3, 0, false, false};
    assert_int_equal(lk_metro(&a, &b, &options, &result, record_progress, &cancel, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "cancelled");
    assert_int_equal(cancel.calls, 3);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_point_triangle_regions),
        cmocka_unit_test(test_point_triangle_degenerate),
        cmocka_unit_test(test_point_triangle_random),
        cmocka_unit_test(test_nearest_matches_brute_force),
        cmocka_unit_test(test_nearest_max_distance),
        cmocka_unit_test(test_one_sided_cow_subset),
        cmocka_unit_test(test_one_sided_wavy_grids),
        cmocka_unit_test(test_one_sided_degenerate_triangles),
        cmocka_unit_test(test_zero_area_mesh),
        cmocka_unit_test(test_sample_layout),
        cmocka_unit_test(test_analytic_tilted_square),
        cmocka_unit_test(test_bunny_against_itself),
        cmocka_unit_test(test_bunny_translated),
        cmocka_unit_test(test_thread_count_does_not_matter),
        cmocka_unit_test(test_point_set_target),
        cmocka_unit_test(test_point_set_known_answer),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_progress_and_cancel),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
