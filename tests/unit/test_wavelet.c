/* SPDX-License-Identifier: MIT */
/* Wavelet simplification by planar sampling (src/wavelet.c, slice.c,
 * tile.c): the CDF 9/7 transform against the paper's Tables 1-2 and perfect
 * reconstruction; what midpoint padding really gives (zero details only on
 * stretches that are polynomial in the sample index, e.g. equally spaced
 * collinear samples); slicing with planes through vertices; closed,
 * consistently oriented 2-manifold output on the real models at several
 * slice counts; the paper's Table 4 experiment next to both clusterings
 * (wavelet no worse than either, measured in the test); the paper's energy
 * criterion (eq. 7) against coefficients computed here; tiling of a hole
 * that opens into a notch and of band starts on the bunny; bad input
 * (open, non-manifold, flat, NaN, point sets); targets, determinism,
 * progress and cancellation. LK_TEST_FILTER=PATTERN runs some tests only. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* The paper's Table 1 (analysis) filters, typed in from the paper. */
static const double paper_low[5] = {0.6029490182363579, 0.2668641184428723, -0.07822326652898785, -0.01686411844287495,
                                    0.02674875741080976};
static const double paper_high[4] = {1.115087052456994, -0.5912717631142470, -0.05754352622849957, 0.09127176311424948};

static uint64_t rng_state = 12345;
static double next_random(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0) * 2 - 1;
}

/* ---- the transform ------------------------------------------------------ */

static void test_filters_match_table1(void **state)
{
    (void)state;
    /* The exported filters are the paper's. */
    for (int j = -4; j <= 4; j++) assert_true(fabs(lk_cdf97_analysis_low[j + 4] - paper_low[abs(j)]) < 1e-15);
    for (int j = -3; j <= 3; j++) assert_true(fabs(lk_cdf97_analysis_high[j + 3] - paper_high[abs(j)]) < 1e-15);
    double low_sum = 0, high_sum = 0;
    for (int j = 0; j < 9; j++) low_sum += lk_cdf97_analysis_low[j];
    for (int j = 0; j < 7; j++) high_sum += lk_cdf97_analysis_high[j];
    assert_true(fabs(low_sum - 1) < 1e-9); /* Table 1's normalisation: averages */
    assert_true(fabs(high_sum) < 1e-9);
    /* One lifting level equals the convolution of equations (2)-(3), low
     * centred on even samples, high on odd ones, periodic. */
    enum { N = 32 };
    double x[N], y[N];
    for (int i = 0; i < N; i++) x[i] = y[i] = next_random();
    assert_int_equal(lk_wavelet_forward(y, N, 1, NULL), LK_OK);
    for (int i = 0; i < N / 2; i++) {
        double a = 0, d = 0;
        for (int j = -4; j <= 4; j++) a += paper_low[abs(j)] * x[((2 * i + j) % N + N) % N];
        for (int j = -3; j <= 3; j++) d += paper_high[abs(j)] * x[((2 * i + 1 + j) % N + N) % N];
        assert_true(fabs(y[i] - a) < 1e-9);
        assert_true(fabs(y[N / 2 + i] - d) < 1e-9);
    }
}

static void test_synthesis_filters_table2(void **state)
{
    (void)state;
    /* Synthesis of one unit approximation gives Table 2's h'_L (7 taps,
     * summing to 2), of one unit detail its h'_H (9 taps: Table 2 prints the
     * +-4 tap 0.0267... in the h'_L column, a misprint). */
    static const double synthesis_low[4] = {1.115087052456994, 0.5912717631142470, -0.05754352622849957,
                                            -0.09127176311424948};
    static const double synthesis_high[5] = {0.6029490182363579, -0.2668641184428723, -0.07822326652898785,
                                             0.01686411844287495, 0.02674875741080976};
    enum { N = 32 };
    double x[N] = {0};
    x[8] = 1; /* approximation 8 -> centred on sample 16 */
    assert_int_equal(lk_wavelet_inverse(x, N, 1, NULL), LK_OK);
    for (int n = 0; n < N; n++) {
        int j = n - 16;
        double expected = abs(j) <= 3 ? synthesis_low[abs(j)] : 0;
        assert_true(fabs(x[n] - expected) < 1e-12);
    }
    memset(x, 0, sizeof x);
    x[N / 2 + 8] = 1; /* detail 8 -> centred on sample 17 */
    assert_int_equal(lk_wavelet_inverse(x, N, 1, NULL), LK_OK);
    for (int n = 0; n < N; n++) {
        int j = n - 17;
        double expected = abs(j) <= 4 ? synthesis_high[abs(j)] : 0;
        assert_true(fabs(x[n] - expected) < 1e-12);
    }
}

static void test_perfect_reconstruction(void **state)
{
    (void)state;
    static const size_t sizes[] = {2, 4, 8, 12, 64, 96, 1024, 4096};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        size_t n = sizes[s];
        double *x = malloc(n * sizeof(double)), *y = malloc(n * sizeof(double));
        assert_non_null(x);
        assert_non_null(y);
        for (size_t i = 0; i < n; i++) x[i] = y[i] = 100 * next_random() + 1e3;
        unsigned levels = 0;
        while ((n >> (levels + 1)) >= 2 && (n & (((size_t)1 << (levels + 1)) - 1)) == 0) levels++;
        for (unsigned l = 0; l <= levels; l++) {
            memcpy(y, x, n * sizeof(double));
            assert_int_equal(lk_wavelet_forward(y, n, l, NULL), LK_OK);
            assert_int_equal(lk_wavelet_inverse(y, n, l, NULL), LK_OK);
            double worst = 0;
            for (size_t i = 0; i < n; i++) worst = fmax(worst, fabs(y[i] - x[i]));
            assert_true(worst < 1e-9);
        }
        free(x);
        free(y);
    }
    /* Bad layouts are refused. */
    double z[12] = {0};
    lk_error error = {0};
    assert_int_equal(lk_wavelet_forward(z, 12, 3, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "12 samples");
    assert_int_equal(lk_wavelet_forward(z, 12, 2, NULL), LK_OK); /* 12 -> 6 -> 3 */
}

static void test_zero_details(void **state)
{
    (void)state;
    /* 4 vanishing moments: a periodic sequence that is a cubic in the
     * index over a filter's 7 samples gives a zero detail there. */
    enum { N = 64 };
    double x[N];
    for (int i = 0; i < N; i++) {
        double t = i;
        x[i] = 0.5 - 0.25 * t + 0.01 * t * t - 0.0003 * t * t * t;
    }
    assert_int_equal(lk_wavelet_forward(x, N, 1, NULL), LK_OK);
    for (int i = 2; i < N / 2 - 2; i++) /* away from the periodic seam */
        assert_true(fabs(x[N / 2 + i]) < 1e-9);
    /* A quartic does not vanish. */
    for (int i = 0; i < N; i++) x[i] = pow(i - 32.0, 4) * 1e-4;
    assert_int_equal(lk_wavelet_forward(x, N, 1, NULL), LK_OK);
    assert_true(fabs(x[N / 2 + 16]) > 1e-6);

    /* The true midpoint property: a square sampled every 1/16 along its
     * sides, 64 points; the details (level 1) of samples whose 7-sample
     * window lies on one side vanish. */
    double u[N], v[N];
    for (int i = 0; i < N; i++) {
        int side = i / 16;
        double t = (i % 16) / 16.0;
        double corners[5][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0, 0}};
        u[i] = corners[side][0] + t * (corners[side + 1][0] - corners[side][0]);
        v[i] = corners[side][1] + t * (corners[side + 1][1] - corners[side][1]);
    }
    double du[N], dv[N];
    memcpy(du, u, sizeof u);
    memcpy(dv, v, sizeof v);
    lk_wavelet_forward(du, N, 1, NULL);
    lk_wavelet_forward(dv, N, 1, NULL);
    int vanished = 0;
    for (int i = 0; i < N / 2; i++) {
        int odd = 2 * i + 1, side = (odd - 3) / 16;
        if (odd - 3 < 0 || odd + 3 > 16 * side + 16) continue; /* the window turns a corner */
        assert_true(fabs(du[N / 2 + i]) < 1e-12 && fabs(dv[N / 2 + i]) < 1e-12);
        vanished++;
    }
    assert_int_equal(vanished, 4 * 6); /* samples 3, 5, ..., 13 of each side */
    /* Near a corner they do not: the padding's "zero detail" is only exact
     * on straight, evenly sampled stretches. */
    assert_true(fabs(du[N / 2 + 7]) + fabs(dv[N / 2 + 7]) > 1e-3); /* sample 15, next to corner 16 */

    /* A midpoint padded into a segment of a circle polygon (7 points + 1
     * midpoint) has a clearly non-zero detail. */
    double cu[8], cv[8];
    for (int i = 0, k = 0; i < 7; i++) {
        double angle = 2 * 3.14159265358979323846 * i / 7;
        cu[k] = cos(angle);
        cv[k] = sin(angle);
        k++;
        if (i == 2) { /* midpoint between points 2 and 3 -> index 3 (odd) */
            double next = 2 * 3.14159265358979323846 * 3 / 7;
            cu[k] = 0.5 * (cos(angle) + cos(next));
            cv[k] = 0.5 * (sin(angle) + sin(next));
            k++;
        }
    }
    lk_wavelet_forward(cu, 8, 1, NULL);
    lk_wavelet_forward(cv, 8, 1, NULL);
    double detail = hypot(cu[4 + 1], cv[4 + 1]);
    print_message("detail at a midpoint inserted in a 7-gon: %.4f (radius 1)\n", detail);
    assert_true(detail > 0.01);
}

/* ---- helpers for meshes ---------------------------------------------------- */

/* Closed, every edge in two triangles in opposite directions, no repeated
 * or duplicate triangles, every vertex a single fan, and positive volume
 * (outward). */
static void assert_closed_manifold(const lk_mesh *mesh)
{
    lk_error error = {0};
    lk_mesh_stats stats;
    if (lk_mesh_validate(mesh, &error) != LK_OK) fail_msg("invalid output: %s", error.message);
    if (lk_mesh_compute_stats(mesh, &stats, &error) != LK_OK) fail_msg("stats: %s", error.message);
    assert_true(mesh->triangle_count > 0);
    assert_int_equal(stats.boundary_edge_count, 0);
    assert_int_equal(stats.nonmanifold_edge_count, 0);
    assert_int_equal(stats.nonmanifold_vertex_count, 0);
    assert_int_equal(stats.degenerate_triangle_count, 0);
    assert_int_equal(stats.duplicate_triangle_count, 0);
    assert_int_equal(stats.used_vertex_count, mesh->vertex_count);
    assert_int_equal(stats.edge_count * 2, mesh->triangle_count * 3);
    /* Orientation: each directed edge exactly once. */
    lk_edge_adjacency edges;
    assert_int_equal(lk_edge_adjacency_build(mesh, &edges, &error), LK_OK);
    for (size_t e = 0; e < edges.edge_count; e++) {
        uint32_t a = edges.vertices[2 * e];
        int forward = 0;
        for (uint32_t k = edges.offsets[e]; k < edges.offsets[e + 1]; k++) {
            uint32_t t = edges.triangles[k];
            for (int c = 0; c < 3; c++)
                if (edges.triangle_edges[3 * t + c] == e && mesh->indices[3 * t + c] == a) forward++;
        }
        if (forward != 1) fail_msg("edge %zu is not used once in each direction", e);
    }
    lk_edge_adjacency_free(&edges);
    double volume = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const float *p = mesh->positions + 3 * (size_t)mesh->indices[3 * t];
        const float *q = mesh->positions + 3 * (size_t)mesh->indices[3 * t + 1];
        const float *r = mesh->positions + 3 * (size_t)mesh->indices[3 * t + 2];
        volume +=
            (p[0] * ((double)q[1] * r[2] - (double)q[2] * r[1]) - p[1] * ((double)q[0] * r[2] - (double)q[2] * r[0]) +
             p[2] * ((double)q[0] * r[1] - (double)q[1] * r[0])) /
            6;
    }
    assert_true(volume > 0);
}

static void wavelet_ok(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result)
{
    lk_error error = {0};
    if (lk_simplify(mesh, LK_SIMPLIFY_WAVELET, options, result, NULL, NULL, &error) != LK_OK)
        fail_msg("wavelet simplification failed: %s", error.message);
}

static double hausdorff_percent(const lk_mesh *original, const lk_mesh *simplified)
{
    lk_metro_result metro;
    lk_error error = {0};
    if (lk_metro(original, simplified, NULL, &metro, NULL, NULL, &error) != LK_OK) fail_msg("metro: %s", error.message);
    return 100 * metro.hausdorff / metro.diagonal;
}

/* ---- slicing --------------------------------------------------------------- */

static void test_slice_through_vertices(void **state)
{
    (void)state;
    /* The unit cube subdivided twice: vertices at multiples of 1/4, so
     * with 2 slices the planes z = 1/4 and 3/4 pass through rows of
     * vertices and edges lie in the planes. */
    lk_mesh cube, fine;
    lk_test_make_cube(&cube);
    assert_int_equal(lk_subdivide(&cube, LK_SUBDIVIDE_MIDPOINT, 2, &fine, NULL), LK_OK);
    lk_error error = {0};
    assert_int_equal(lk_mesh_weld(&fine, 0, NULL, &error), LK_OK);
    static const size_t counts[] = {2, 3, 6, 10};
    for (int axis = LK_AXIS_X; axis <= LK_AXIS_Z; axis++)
        for (size_t c = 0; c < sizeof counts / sizeof counts[0]; c++) {
            lk_slices slices;
            assert_int_equal(lk_mesh_slice(&fine, (lk_axis)axis, counts[c], &slices, NULL, NULL, &error), LK_OK);
            assert_int_equal(slices.contour_count, counts[c]);
            assert_true(fabs(slices.spacing - 1.0 / counts[c]) < 1e-12);
            assert_true(fabs(slices.sampling_error - 0.5 / counts[c]) < 1e-12);
            for (size_t k = 0; k < slices.contour_count; k++) {
                const lk_contour *contour = &slices.contours[k];
                assert_int_equal(contour->slice, k);
                assert_true(fabs(contour->area - 1) < 1e-9); /* counter-clockwise unit square */
                /* no repeated consecutive points */
                for (uint32_t i = 0; i < contour->count; i++) {
                    const double *p = slices.points + 2 * ((size_t)contour->first + i);
                    const double *q = slices.points + 2 * ((size_t)contour->first + (i + 1) % contour->count);
                    assert_false(p[0] == q[0] && p[1] == q[1]);
                }
            }
            lk_mesh tiled;
            lk_tile_info info;
            assert_int_equal(lk_slices_tile(&slices, &tiled, &info, &error), LK_OK);
            assert_closed_manifold(&tiled);
            assert_int_equal(info.caps, 2);
            assert_int_equal(info.bands, counts[c] - 1);
            lk_mesh_free(&tiled);
            lk_slices_free(&slices);
        }
    lk_mesh_free(&cube);
    lk_mesh_free(&fine);
}

static void test_small_contours_kept(void **state)
{
    (void)state;
    /* A tetrahedron: every contour is a triangle or a quadrilateral, kept as
     * it is (fewer than 4 points) or transformed. */
    static const float positions[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.2f, 0.3f, 1};
    static const uint32_t indices[] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};
    lk_mesh tetra;
    lk_test_make_mesh(&tetra, positions, 4, indices, 4);
    lk_error error = {0};
    lk_slices slices, simplified;
    assert_int_equal(lk_mesh_slice(&tetra, LK_AXIS_Z, 5, &slices, NULL, NULL, &error), LK_OK);
    assert_int_equal(slices.contour_count, 5);
    lk_contour_simplify_options options = {.max_error = 0.5, .criterion = LK_WAVELET_DISTANCE};
    lk_contour_simplify_info info;
    assert_int_equal(lk_slices_simplify(&slices, &options, &simplified, &info, NULL, NULL, &error), LK_OK);
    assert_int_equal(info.untransformed, 5);
    assert_int_equal(simplified.point_count, slices.point_count);
    lk_mesh tiled;
    assert_int_equal(lk_slices_tile(&simplified, &tiled, NULL, &error), LK_OK);
    assert_closed_manifold(&tiled);
    assert_int_equal(tiled.vertex_count, 15);
    lk_mesh_free(&tiled);
    lk_slices_free(&slices);
    lk_slices_free(&simplified);
    lk_mesh_free(&tetra);
}

static void test_padding_changes_nothing(void **state)
{
    (void)state;
    /* Two versions of one square contour: 64 evenly spaced points, and 60
     * with one point removed in the middle of each side (odd indices 5, 21,
     * 37, 53). Padding to 64 puts the midpoints back exactly, so the
     * simplified contours are identical. */
    lk_slices full, holey;
    lk_slices_init(&full);
    lk_slices_init(&holey);
    lk_contour contour_full = {0, 0, 64, 0, 1, 0, 0}, contour_holey = {0, 0, 60, 0, 1, 0, 0};
    double points_full[128], points_holey[120];
    for (int i = 0, k = 0; i < 64; i++) {
        int side = i / 16;
        double t = (i % 16) / 16.0 * 10;
        double p[2] = {side == 0   ? t
                       : side == 1 ? 10
                       : side == 2 ? 10 - t
                                   : 0,
                       side == 0   ? 0
                       : side == 1 ? t
                       : side == 2 ? 10
                                   : 10 - t};
        points_full[2 * i] = p[0];
        points_full[2 * i + 1] = p[1];
        if (i % 16 == 5) continue;
        points_holey[2 * k] = p[0];
        points_holey[2 * k + 1] = p[1];
        k++;
    }
    full.axis = holey.axis = LK_AXIS_Z;
    full.slice_count = holey.slice_count = 1;
    full.spacing = holey.spacing = 1;
    full.diagonal = holey.diagonal = 15;
    full.contour_count = holey.contour_count = 1;
    full.contours = &contour_full;
    holey.contours = &contour_holey;
    full.point_count = 64;
    holey.point_count = 60;
    full.points = points_full;
    holey.points = points_holey;
    static const double errors[] = {0.01, 0.3, 2};
    for (int e = 0; e < 3; e++) {
        lk_contour_simplify_options options = {.max_error = errors[e], .criterion = LK_WAVELET_DISTANCE};
        lk_slices a, b;
        lk_contour_simplify_info info_a, info_b;
        assert_int_equal(lk_slices_simplify(&full, &options, &a, &info_a, NULL, NULL, NULL), LK_OK);
        assert_int_equal(lk_slices_simplify(&holey, &options, &b, &info_b, NULL, NULL, NULL), LK_OK);
        assert_int_equal(info_a.midpoints, 0);
        assert_int_equal(info_b.midpoints, 4);
        assert_int_equal(a.point_count, b.point_count);
        assert_int_equal(a.contours[0].level, b.contours[0].level);
        for (size_t i = 0; i < 2 * a.point_count; i++) assert_true(fabs(a.points[i] - b.points[i]) < 1e-9);
        /* a square needs no more than its 4 corners once the bound allows */
        if (errors[e] >= 0.3) assert_true(a.point_count <= 8);
        lk_slices_free(&a);
        lk_slices_free(&b);
    }
}

/* ---- real models ------------------------------------------------------------ */

static void test_closed_on_real_models(void **state)
{
    (void)state;
    static const char *names[] = {"cow.off", "triceratops.off", "fandisk.off"};
    static const size_t slice_counts[] = {7, 31, 150};
    for (int m = 0; m < 3; m++) {
        lk_mesh mesh;
        lk_test_load(lk_test_sample(names[m]), &mesh);
        for (int s = 0; s < 3; s++) {
            for (int axis = LK_AXIS_AUTO; axis <= LK_AXIS_Z; axis += (s == 1 ? 1 : 3)) {
                lk_simplify_options options;
                lk_simplify_options_default(&options);
                options.slice_count = slice_counts[s];
                options.slice_axis = axis;
                options.target_vertices = mesh.vertex_count / 5;
                lk_simplify_result result;
                wavelet_ok(&mesh, &options, &result);
                assert_closed_manifold(&result.mesh);
                assert_non_null(result.vertex_map);
                assert_int_equal(result.vertex_map[0], UINT32_MAX);
                lk_simplify_result_free(&result);
            }
        }
        lk_mesh_free(&mesh);
    }
    /* The bunny at the paper's 150 slices, error target. */
    lk_mesh bunny;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.max_error = 0.005;
    options.slice_count = 150;
    lk_simplify_result result;
    wavelet_ok(&bunny, &options, &result);
    assert_closed_manifold(&result.mesh);
    print_message("bunny, 150 slices, --max-error 0.5%%: %zu v, %zu t, error %.3f%%\n", result.mesh.vertex_count,
                  result.mesh.triangle_count, 100 * result.error / result.diagonal);
    lk_slices slices;
    assert_int_equal(lk_mesh_slice(&bunny, LK_AXIS_AUTO, 150, &slices, NULL, NULL, NULL), LK_OK);
    assert_true(result.error <= hypot(0.005 * result.diagonal, slices.sampling_error) * (1 + 1e-9));
    lk_slices_free(&slices);
    lk_simplify_result_free(&result);
    lk_mesh_free(&bunny);
}

typedef struct table4_row {
    const char *name;
    double paper_wavelet_percent;
    size_t paper_triangles;
    double bound_percent; /* what this implementation reaches, with margin */
} table4_row;

static void check_table4(const table4_row *row)
{
    lk_mesh mesh;
    lk_test_load(lk_test_sample(row->name), &mesh);
    size_t target = (size_t)llround(0.125 * (double)mesh.vertex_count);
    double errors[3];
    size_t triangles[3], vertices[3];
    static const lk_simplify_method methods[3] = {LK_SIMPLIFY_UNIFORM, LK_SIMPLIFY_FLOATING, LK_SIMPLIFY_WAVELET};
    for (int m = 0; m < 3; m++) {
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_vertices = target;
        lk_simplify_result result;
        lk_error error = {0};
        if (lk_simplify(&mesh, methods[m], &options, &result, NULL, NULL, &error) != LK_OK)
            fail_msg("%s: %s", row->name, error.message);
        if (m == 2) {
            assert_closed_manifold(&result.mesh);
            assert_true(result.target_reached);
            assert_true(result.mesh.vertex_count <= target);
            assert_true(result.mesh.vertex_count >= target * 95 / 100);
        }
        errors[m] = hausdorff_percent(&mesh, &result.mesh);
        triangles[m] = result.mesh.triangle_count;
        vertices[m] = result.mesh.vertex_count;
        lk_simplify_result_free(&result);
    }
    print_message("%s at %zu vertices: uniform %zu v %zu t %.2f%%, floating %zu v %zu t %.2f%%, wavelet %zu v %zu t "
                  "%.2f%% (paper: wavelet %zu t %.2f%%)\n",
                  row->name, target, vertices[0], triangles[0], errors[0], vertices[1], triangles[1], errors[1],
                  vertices[2], triangles[2], errors[2], row->paper_triangles, row->paper_wavelet_percent);
    assert_true(errors[2] <= row->bound_percent);
    /* The acceptance: no worse than both clusterings, as measured
     * here and now. */
    assert_true(errors[2] <= fmin(errors[0], errors[1]));
    lk_mesh_free(&mesh);
}

static void test_table4_bunny(void **state)
{
    (void)state;
    /* 0.36% against 1.02% (uniform) and 0.61% (floating); 1.25% before
     * the refinement between planes and the tiling fixes (docs/wavelet.md). */
    const table4_row row = {"bunny.obj", 0.97, 4862, 0.5};
    check_table4(&row);
}

static void test_table4_triceratops(void **state)
{
    (void)state;
    const table4_row row = {"triceratops.off", 2.78, 1832, 1.6}; /* 1.25% */
    check_table4(&row);
}

/* ---- connected input stays connected (issue 24) -------------------------------------- */

/* Every sample model at 12.5%, 10% and 5% of its vertices (the slicing
 * axis chosen automatically): one component in, one out, closed and
 * manifold. Before the tiling followed the surface pieces between the
 * planes, the cow came back in 4, 4 and 8 parts (thin limbs whose contours
 * do not overlap from one plane to the next, small branches capped instead
 * of bridged), and the dragon (two 3-edge holes) was refused. The bounds
 * are today's Hausdorff distances (% of the diagonal) plus a margin; all
 * but the triceratops at 5% and the dragon at 12.5% and 5% are below both
 * clusterings at the same vertex count (docs/wavelet.md, "Connected
 * input"). The bunny runs at 5% only (12.5% is test_table4_bunny). */
static void test_connected_stays_connected(void **state)
{
    (void)state;
    static const struct {
        const char *name;
        double ratio, bound_percent;
    } cases[] = {
        {"cow.off", 0.125, 2.1},
        {"cow.off", 0.10, 2.0},
        {"cow.off", 0.05, 3.4},
        {"triceratops.off", 0.125, 1.6},
        {"triceratops.off", 0.10, 2.7},
        {"triceratops.off", 0.05, 9.9},
        {"fandisk.off", 0.125, 1.5},
        {"fandisk.off", 0.10, 1.8},
        {"fandisk.off", 0.05, 2.6},
        {"ChineseDragon-10kv.off", 0.125, 4.1},
        {"ChineseDragon-10kv.off", 0.10, 2.2},
        {"ChineseDragon-10kv.off", 0.05, 3.8},
        {"bunny.obj", 0.05, 1.0},
    };
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    const char *loaded = "";
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        if (strcmp(loaded, cases[i].name) != 0) {
            lk_mesh_free(&mesh);
            lk_test_load(lk_test_sample(cases[i].name), &mesh);
            loaded = cases[i].name;
        }
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_vertices = (size_t)lround(cases[i].ratio * (double)mesh.vertex_count);
        lk_simplify_result result;
        lk_error error = {0};
        if (lk_simplify(&mesh, LK_SIMPLIFY_WAVELET, &options, &result, NULL, NULL, &error) != LK_OK)
            fail_msg("%s: %s", cases[i].name, error.message);
        assert_closed_manifold(&result.mesh);
        lk_mesh_stats stats;
        assert_int_equal(lk_mesh_compute_stats(&result.mesh, &stats, &error), LK_OK);
        double percent = hausdorff_percent(&mesh, &result.mesh);
        print_message("%s at %.1f%% (%zu v): %zu v, %zu component(s), Hausdorff %.2f%%\n", cases[i].name,
                      100 * cases[i].ratio, options.target_vertices, result.mesh.vertex_count, stats.component_count,
                      percent);
        assert_int_equal(stats.component_count, 1);
        assert_true(result.mesh.vertex_count <= options.target_vertices);
        assert_true(percent <= cases[i].bound_percent);
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&mesh);
}

/* ---- the energy criterion (paper eq. 7) -------------------------------------------- */

static void test_energy_criterion(void **state)
{
    (void)state;
    /* One contour of 64 points (a power of two: no padding), a wobbly
     * circle, so every level has details. */
    enum { N = 64, LEVELS = 4 }; /* 64 -> 4 coarse samples */
    double points[2 * N];
    for (int i = 0; i < N; i++) {
        double angle = 2 * 3.14159265358979323846 * i / N;
        double radius = 1 + 0.05 * sin(5 * angle) + 0.01 * sin(17 * angle);
        points[2 * i] = radius * cos(angle);
        points[2 * i + 1] = radius * sin(angle);
    }
    /* Eq. 7 by hand: the energy of the details of levels 1..L. */
    double u[N], v[N];
    for (int i = 0; i < N; i++) {
        u[i] = points[2 * i];
        v[i] = points[2 * i + 1];
    }
    assert_int_equal(lk_wavelet_forward(u, N, LEVELS, NULL), LK_OK);
    assert_int_equal(lk_wavelet_forward(v, N, LEVELS, NULL), LK_OK);
    double energy[LEVELS + 1] = {0};
    for (int level = 1; level <= LEVELS; level++) {
        energy[level] = energy[level - 1];
        for (int i = N >> level; i < N >> (level - 1); i++) energy[level] += u[i] * u[i] + v[i] * v[i];
    }
    lk_contour contour = {0, 0, N, 0, 0, 0, 0};
    lk_slices slices;
    lk_slices_init(&slices);
    slices.axis = LK_AXIS_Z;
    slices.u_axis = 0;
    slices.v_axis = 1;
    slices.slice_count = 1;
    slices.spacing = 1;
    slices.diagonal = 3;
    slices.contour_count = 1;
    slices.contours = &contour;
    slices.point_count = N;
    slices.points = points;
    for (int level = 1; level <= LEVELS; level++) {
        /* A threshold between the energies of levels L and L + 1 keeps L. */
        double above = level < LEVELS ? energy[level + 1] : 4 * energy[LEVELS];
        double threshold = sqrt(0.5 * (energy[level] + above));
        lk_contour_simplify_options options = {.max_error = threshold, .criterion = LK_WAVELET_ENERGY};
        lk_slices out;
        lk_contour_simplify_info info;
        assert_int_equal(lk_slices_simplify(&slices, &options, &out, &info, NULL, NULL, NULL), LK_OK);
        assert_int_equal(out.contour_count, 1);
        assert_int_equal(out.contours[0].level, level);
        assert_true(out.contours[0].count <= (size_t)N >> level);
        lk_slices_free(&out);
    }
    /* Just below level 1's energy nothing is dropped. */
    lk_contour_simplify_options options = {.max_error = 0.999 * sqrt(energy[1]), .criterion = LK_WAVELET_ENERGY};
    lk_slices out;
    assert_int_equal(lk_slices_simplify(&slices, &options, &out, NULL, NULL, NULL, NULL), LK_OK);
    assert_int_equal(out.contours[0].level, 0);
    lk_slices_free(&out);
    /* An unknown criterion is refused. */
    options.criterion = (lk_wavelet_criterion)7;
    lk_error error = {0};
    assert_int_equal(lk_slices_simplify(&slices, &options, &out, NULL, NULL, NULL, &error), LK_ERR_INVALID);
    assert_non_null(strstr(error.message, "criterion"));

    /* Both criteria through lk_simplify's wavelet_criterion on a real
     * model: closed, on target, and the default is the energy one. */
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    lk_simplify_options simplify_options;
    lk_simplify_options_default(&simplify_options);
    simplify_options.target_vertices = 400;
    lk_simplify_result by_energy, by_distance, by_default;
    wavelet_ok(&cow, &simplify_options, &by_default);
    simplify_options.wavelet_criterion = LK_WAVELET_ENERGY;
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &simplify_options, &by_energy, NULL, NULL, NULL), LK_OK);
    simplify_options.wavelet_criterion = LK_WAVELET_DISTANCE;
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &simplify_options, &by_distance, NULL, NULL, NULL), LK_OK);
    assert_closed_manifold(&by_energy.mesh);
    assert_closed_manifold(&by_distance.mesh);
    assert_true(by_energy.mesh.vertex_count <= 400 && by_energy.mesh.vertex_count >= 380);
    assert_true(by_distance.mesh.vertex_count <= 400 && by_distance.mesh.vertex_count >= 380);
    /* The paper's pipeline alone (no vertices between the planes) is also
     * closed, with fewer vertices than the target (the refinement's share
     * is not spent). */
    lk_simplify_result paper_only;
    simplify_options.wavelet_criterion = LK_WAVELET_ENERGY;
    simplify_options.flags |= LK_SIMPLIFY_NO_REFINE;
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &simplify_options, &paper_only, NULL, NULL, NULL), LK_OK);
    simplify_options.flags &= ~(unsigned)LK_SIMPLIFY_NO_REFINE;
    assert_closed_manifold(&paper_only.mesh);
    assert_true(paper_only.mesh.vertex_count <= 400);
    print_message("cow at 400 vertices without refinement: %zu v, %.2f%%\n", paper_only.mesh.vertex_count,
                  hausdorff_percent(&cow, &paper_only.mesh));
    lk_simplify_result_free(&paper_only);
    lk_simplify_result *same = LK_WAVELET_CRITERION_DEFAULT == LK_WAVELET_ENERGY ? &by_energy : &by_distance;
    assert_int_equal(by_default.mesh.triangle_count, same->mesh.triangle_count);
    assert_memory_equal(by_default.mesh.indices, same->mesh.indices, 3 * same->mesh.triangle_count * sizeof(uint32_t));
    print_message("cow at 400 vertices: energy %.2f%%, distance %.2f%%\n", hausdorff_percent(&cow, &by_energy.mesh),
                  hausdorff_percent(&cow, &by_distance.mesh));
    /* Refusals, as lk_simplify's. */
    lk_simplify_result refused;
    simplify_options.target_ratio = 2;
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &simplify_options, &refused, NULL, NULL, &error),
                     LK_ERR_INVALID);
    simplify_options.target_ratio = 0;
    simplify_options.target_vertices = 0;
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &simplify_options, &refused, NULL, NULL, &error),
                     LK_ERR_INVALID);
    simplify_options.target_vertices = 400;
    simplify_options.wavelet_criterion = 3;
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &simplify_options, &refused, NULL, NULL, &error),
                     LK_ERR_INVALID);
    assert_non_null(strstr(error.message, "criterion"));
    lk_simplify_result_free(&by_energy);
    lk_simplify_result_free(&by_distance);
    lk_simplify_result_free(&by_default);
    lk_mesh_free(&cow);
}

/* ---- tiling: notches, holes and band starts -------------------------------------- */

/* A square with a square hole on plane 0; on plane 1 the hole has opened
 * into a notch from the right side. The hole must be bridged into the
 * outer contour's band (one bridge), not capped under the notch. */
static void test_hole_opens_into_notch(void **state)
{
    (void)state;
    static const double outer[] = {0, 0, 4, 0, 4, 4, 0, 4};                           /* counter-clockwise */
    static const double hole[] = {1, 1, 1, 3, 3, 3, 3, 1};                            /* clockwise */
    static const double notched[] = {0, 0, 4, 0, 4, 1, 1, 1, 1, 3, 4, 3, 4, 4, 0, 4}; /* counter-clockwise */
    static const double bottom[] = {0, 0, 4, 0, 4, 4, 0, 4};
    double points[2 * (4 + 4 + 8 + 4)];
    memcpy(points, bottom, sizeof bottom);
    memcpy(points + 8, outer, sizeof outer);
    memcpy(points + 16, hole, sizeof hole);
    memcpy(points + 24, notched, sizeof notched);
    /* Pieces unknown (0): paired by the overlap of their areas. */
    lk_contour contours[4] = {
        {0, 0, 4, 0, 16, 0, 0}, {1, 4, 4, 0, 16, 0, 0}, {1, 8, 4, 0, -4, 0, 0}, {2, 12, 8, 0, 10, 0, 0}};
    lk_slices slices;
    lk_slices_init(&slices);
    slices.axis = LK_AXIS_Z;
    slices.u_axis = 0;
    slices.v_axis = 1;
    slices.slice_count = 3;
    slices.spacing = 1;
    slices.diagonal = 6;
    slices.contour_count = 4;
    slices.contours = contours;
    slices.point_count = 20;
    slices.points = points;
    lk_mesh mesh;
    lk_tile_info info;
    assert_int_equal(lk_slices_tile(&slices, &mesh, &info, NULL), LK_OK);
    assert_closed_manifold(&mesh);
    assert_int_equal(info.bridges, 1);
    /* Caps: the bottom square (lower side), the notched contour (upper
     * side), the hole's lower side (the pit's floor on plane 1). A lid on
     * the hole (its upper side) would close the pit under the open notch. */
    assert_int_equal(info.caps, 3);
    size_t over_hole = 0; /* triangles on plane 1 (z = 1.5) inside the hole */
    for (size_t t = 0; t < mesh.triangle_count; t++) {
        double centre[3] = {0, 0, 0};
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) centre[k] += mesh.positions[3 * (size_t)mesh.indices[3 * t + c] + k] / 3;
        over_hole += centre[0] > 1 && centre[0] < 3 && centre[1] > 1 && centre[1] < 3 && fabs(centre[2] - 1.5) < 1e-6;
    }
    assert_int_equal(over_hole, 2); /* the floor's two triangles, no lid */
    lk_mesh_free(&mesh);
}

/* The band between the two contours of neighbouring bunny slices must not
 * start its pairing across a notch: the whole band then turned in long
 * fans (edges of 0.75 on a diagonal of 3.2; 3.65% Hausdorff for the tiling
 * alone, 1.44% now, at 150 slices). */
static void test_band_starts(void **state)
{
    (void)state;
    lk_mesh bunny;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_slices slices, simplified;
    assert_int_equal(lk_mesh_slice(&bunny, LK_AXIS_AUTO, 150, &slices, NULL, NULL, NULL), LK_OK);
    lk_contour_simplify_options options = {.target_vertices = 4180, .criterion = LK_WAVELET_ENERGY};
    assert_int_equal(lk_slices_simplify(&slices, &options, &simplified, NULL, NULL, NULL, NULL), LK_OK);
    lk_mesh mesh;
    assert_int_equal(lk_slices_tile(&simplified, &mesh, NULL, NULL), LK_OK);
    assert_closed_manifold(&mesh);
    lk_metro_options metro_options;
    lk_metro_options_default(&metro_options);
    metro_options.sample_count = 100000; /* per surface, with vertices and edges: enough for a 3% defect */
    lk_metro_result metro;
    assert_int_equal(lk_metro(&bunny, &mesh, &metro_options, &metro, NULL, NULL, NULL), LK_OK);
    double percent = 100 * metro.hausdorff / metro.diagonal;
    print_message("bunny, 150 slices, tiling alone: %zu v, Hausdorff %.2f%%\n", mesh.vertex_count, percent);
    assert_true(percent < 2);
    lk_mesh_free(&mesh);
    lk_slices_free(&simplified);
    lk_slices_free(&slices);
    lk_mesh_free(&bunny);
}

/* ---- bad input ----------------------------------------------------------------- */

static void test_bad_input(void **state)
{
    (void)state;
    lk_error error = {0};
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.5;
    lk_simplify_result result;
    /* open */
    lk_mesh grid;
    lk_test_make_grid(&grid, 4);
    grid.positions[2] = 0.5f; /* give it some height */
    assert_int_equal(lk_simplify(&grid, LK_SIMPLIFY_WAVELET, &options, &result, NULL, NULL, &error),
                     LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "boundary edges");
    lk_mesh_free(&grid);
    /* flat: a closed two-sided triangle has no extent along z */
    static const float flat_positions[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    static const uint32_t flat_indices[] = {0, 1, 2, 0, 2, 1};
    lk_mesh flat;
    lk_test_make_mesh(&flat, flat_positions, 3, flat_indices, 2);
    assert_int_equal(lk_simplify(&flat, LK_SIMPLIFY_WAVELET, &options, &result, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "flat along z");
    lk_mesh_free(&flat);
    /* non-manifold: three triangles on one edge (plus closing ones do not
     * matter: the first check reports it) */
    static const float fin_positions[] = {0, 0, 0, 1, 0, 0, 0, 1, 1, 0, -1, 1, 1, 1, -1};
    static const uint32_t fin_indices[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    lk_mesh fin;
    lk_test_make_mesh(&fin, fin_positions, 5, fin_indices, 3);
    lk_slices slices;
    assert_int_equal(lk_mesh_slice(&fin, LK_AXIS_Z, 4, &slices, NULL, NULL, &error), LK_ERR_UNSUPPORTED);
    lk_mesh_free(&fin);
    /* inconsistent orientation: a cube with one triangle flipped */
    lk_mesh cube;
    lk_test_make_cube(&cube);
    uint32_t swap = cube.indices[0];
    cube.indices[0] = cube.indices[1];
    cube.indices[1] = swap;
    assert_int_equal(lk_mesh_slice(&cube, LK_AXIS_Z, 4, &slices, NULL, NULL, &error), LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "oriented");
    cube.indices[1] = cube.indices[0];
    cube.indices[0] = swap;
    /* slice counts and axes */
    assert_int_equal(lk_mesh_slice(&cube, LK_AXIS_Z, 1, &slices, NULL, NULL, &error), LK_ERR_INVALID);
    assert_int_equal(lk_mesh_slice(&cube, (lk_axis)7, 4, &slices, NULL, NULL, &error), LK_ERR_INVALID);
    options.slice_axis = 9;
    assert_int_equal(lk_simplify(&cube, LK_SIMPLIFY_WAVELET, &options, &result, NULL, NULL, &error), LK_ERR_INVALID);
    options.slice_axis = LK_AXIS_AUTO;
    /* NaN */
    cube.positions[4] = NAN;
    assert_int_equal(lk_simplify(&cube, LK_SIMPLIFY_WAVELET, &options, &result, NULL, NULL, &error), LK_ERR_RANGE);
    assert_int_equal(lk_mesh_slice(&cube, LK_AXIS_Z, 4, &slices, NULL, NULL, &error), LK_ERR_RANGE);
    lk_mesh_free(&cube);
    /* a point set */
    lk_mesh points;
    lk_mesh_init(&points);
    assert_int_equal(lk_mesh_alloc(&points, 3, 0, 0, &error), LK_OK);
    memset(points.positions, 0, 9 * sizeof(float));
    assert_int_equal(lk_mesh_slice(&points, LK_AXIS_Z, 4, &slices, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "point set");
    lk_mesh_free(&points);
}

static void test_components_and_targets(void **state)
{
    (void)state;
    /* Two separate cubes, one above the other's corner: two components,
     * closed output, outward. */
    lk_mesh a, b;
    lk_test_make_cube(&a);
    lk_test_make_cube(&b);
    lk_mesh_translate(&b, 2, 0.5, 0.3);
    lk_mesh both;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&both, 16, 24, 0, &error), LK_OK);
    memcpy(both.positions, a.positions, 24 * sizeof(float));
    memcpy(both.positions + 24, b.positions, 24 * sizeof(float));
    for (int i = 0; i < 36; i++) {
        both.indices[i] = a.indices[i];
        both.indices[36 + i] = b.indices[i] + 8;
    }
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.max_error = 0.01;
    options.slice_count = 9;
    lk_simplify_result result;
    wavelet_ok(&both, &options, &result);
    assert_closed_manifold(&result.mesh);
    lk_mesh_stats stats;
    assert_int_equal(lk_mesh_compute_stats(&result.mesh, &stats, &error), LK_OK);
    assert_int_equal(stats.component_count, 2);
    assert_int_equal(stats.genus, 0);
    lk_simplify_result_free(&result);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
    lk_mesh_free(&both);

    /* Count targets on the cow; an impossible one reports target_reached 0. */
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    lk_simplify_options_default(&options);
    options.slice_count = 40;
    options.target_vertices = 800;
    wavelet_ok(&cow, &options, &result);
    assert_true(result.target_reached);
    assert_true(result.mesh.vertex_count <= 800 && result.mesh.vertex_count >= 760);
    size_t vertex_count = result.mesh.vertex_count;
    /* determinism */
    lk_simplify_result again;
    wavelet_ok(&cow, &options, &again);
    assert_int_equal(again.mesh.vertex_count, vertex_count);
    assert_int_equal(again.mesh.triangle_count, result.mesh.triangle_count);
    assert_memory_equal(again.mesh.positions, result.mesh.positions, 3 * vertex_count * sizeof(float));
    assert_memory_equal(again.mesh.indices, result.mesh.indices, 3 * result.mesh.triangle_count * sizeof(uint32_t));
    lk_simplify_result_free(&again);
    lk_simplify_result_free(&result);
    options.target_vertices = 20; /* three points per contour at least */
    wavelet_ok(&cow, &options, &result);
    assert_false(result.target_reached);
    assert_closed_manifold(&result.mesh);
    lk_simplify_result_free(&result);
    /* triangle target ~ 2 V */
    options.target_vertices = 0;
    options.target_triangles = 1000;
    wavelet_ok(&cow, &options, &result);
    assert_true(result.mesh.vertex_count <= 502);
    assert_true(result.mesh.triangle_count <= 1010);
    lk_simplify_result_free(&result);
    lk_mesh_free(&cow);
}

static int count_calls(void *user, double fraction, const char *stage)
{
    (void)stage;
    int *calls = user;
    assert_true(fraction >= 0 && fraction <= 1);
    (*calls)++;
    return 0;
}

static int cancel_now(void *user, double fraction, const char *stage)
{
    (void)user;
    (void)fraction;
    (void)stage;
    return 1;
}

static void test_progress_and_cancel(void **state)
{
    (void)state;
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.2;
    lk_simplify_result result;
    int calls = 0;
    lk_error error = {0};
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &options, &result, count_calls, &calls, &error), LK_OK);
    assert_true(calls > 3);
    lk_simplify_result_free(&result);
    options.slice_count = 60;
    assert_int_equal(lk_simplify(&cow, LK_SIMPLIFY_WAVELET, &options, &result, cancel_now, NULL, &error),
                     LK_ERR_INVALID);
    lk_assert_message_contains(error, "cancelled");
    lk_mesh_free(&cow);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_filters_match_table1),
        cmocka_unit_test(test_synthesis_filters_table2),
        cmocka_unit_test(test_perfect_reconstruction),
        cmocka_unit_test(test_zero_details),
        cmocka_unit_test(test_slice_through_vertices),
        cmocka_unit_test(test_small_contours_kept),
        cmocka_unit_test(test_padding_changes_nothing),
        cmocka_unit_test(test_closed_on_real_models),
        cmocka_unit_test(test_table4_bunny),
        cmocka_unit_test(test_table4_triceratops),
        cmocka_unit_test(test_connected_stays_connected),
        cmocka_unit_test(test_energy_criterion),
        cmocka_unit_test(test_hole_opens_into_notch),
        cmocka_unit_test(test_band_starts),
        cmocka_unit_test(test_bad_input),
        cmocka_unit_test(test_components_and_targets),
        cmocka_unit_test(test_progress_and_cancel),
    };
    /* LK_TEST_FILTER=PATTERN runs the matching tests only (for timing). */
    const char *filter = getenv("LK_TEST_FILTER");
    if (filter) cmocka_set_test_filter(filter);
    return cmocka_run_group_tests(tests, NULL, NULL);
}
