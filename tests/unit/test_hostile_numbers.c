/* SPDX-License-Identifier: MIT */
/* Numerical hostility (issue 10): NaN/Inf refused with a clear message, and
 * finite extremes handled: models near FLT_MAX (3.4e38), 1e38 outliers,
 * denormal-sized models, all vertices at one point, a single triangle,
 * zero-area triangles. Every library entry point that computes on
 * positions gets such arrays (built here) and must answer with LK_OK and
 * finite output, or with an error naming the problem; never NaN, a crash
 * or a hang. The real cow, scaled by exact powers of two, must simplify to
 * the very same triangles as the cow itself. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* ---- shapes ---------------------------------------------------------------- */

/* Octahedron subdivided `levels` times onto the unit sphere (closed,
 * genus 0): 66 vertices / 128 triangles at 2 levels. */
static void make_sphere(lk_mesh *mesh, int levels)
{
    float v[3 * 258];
    uint32_t f[3 * 512];
    static const float corners[18] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
    static const uint32_t faces[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
    memcpy(v, corners, sizeof corners);
    memcpy(f, faces, sizeof faces);
    size_t vertex_count = 6, triangle_count = 8;
    for (int level = 0; level < levels; level++) {
        uint32_t next[3 * 512];
        size_t next_count = 0;
        /* midpoint of edge (a, b), shared through a linear search (tiny meshes) */
        uint32_t edge_a[768], edge_b[768], edge_mid[768];
        size_t edge_count = 0;
        for (size_t t = 0; t < triangle_count; t++) {
            uint32_t corner[3] = {f[3 * t], f[3 * t + 1], f[3 * t + 2]}, mid[3];
            for (int k = 0; k < 3; k++) {
                uint32_t a = corner[k], b = corner[(k + 1) % 3], lo = a < b ? a : b, hi = a < b ? b : a;
                size_t e = 0;
                while (e < edge_count && !(edge_a[e] == lo && edge_b[e] == hi)) e++;
                if (e == edge_count) {
                    float *p = v + 3 * vertex_count;
                    double length = 0;
                    for (int c = 0; c < 3; c++) {
                        p[c] = 0.5f * (v[3 * a + c] + v[3 * b + c]);
                        length += (double)p[c] * p[c];
                    }
                    for (int c = 0; c < 3; c++) p[c] = (float)(p[c] / sqrt(length));
                    edge_a[e] = lo, edge_b[e] = hi, edge_mid[e] = (uint32_t)vertex_count++;
                    edge_count++;
                }
                mid[k] = edge_mid[e];
            }
            uint32_t children[12] = {corner[0], mid[0], mid[2],    mid[0], corner[1], mid[1],
                                     mid[2],    mid[1], corner[2], mid[0], mid[1],    mid[2]};
            memcpy(next + 3 * next_count, children, sizeof children);
            next_count += 4;
        }
        memcpy(f, next, 3 * next_count * sizeof *f);
        triangle_count = next_count;
    }
    lk_test_make_mesh(mesh, v, vertex_count, f, triangle_count);
}

/* positions = positions * scale + offset, computed in double. */
static void transform(lk_mesh *mesh, double scale, double offset)
{
    for (size_t i = 0; i < 3 * mesh->vertex_count; i++)
        mesh->positions[i] = (float)((double)mesh->positions[i] * scale + offset);
}

static void assert_finite_mesh(const lk_mesh *mesh)
{
    for (size_t i = 0; i < 3 * mesh->vertex_count; i++)
        if (!isfinite(mesh->positions[i]))
            fail_msg("position %zu of vertex %zu is %g", i % 3, i / 3, (double)mesh->positions[i]);
    if (mesh->normals)
        for (size_t i = 0; i < 3 * mesh->vertex_count; i++)
            if (!isfinite(mesh->normals[i])) fail_msg("normal of vertex %zu is not finite", i / 3);
    if (mesh->radii)
        for (size_t i = 0; i < mesh->vertex_count; i++)
            if (!(mesh->radii[i] > 0) || !isfinite(mesh->radii[i]))
                fail_msg("radius of point %zu is %g", i, (double)mesh->radii[i]);
    for (size_t i = 0; i < 3 * mesh->triangle_count; i++) assert_true(mesh->indices[i] < mesh->vertex_count);
}

static const lk_simplify_method methods[4] = {LK_SIMPLIFY_QEM, LK_SIMPLIFY_UNIFORM, LK_SIMPLIFY_FLOATING,
                                              LK_SIMPLIFY_WAVELET};
static const char *const method_names[4] = {"qem", "uniform", "floating", "wavelet"};

/* ---- NaN and infinities: refused, naming the vertex ------------------------- */

static void test_non_finite_refused(void **state)
{
    (void)state;
    const float bad_values[3] = {NAN, INFINITY, -INFINITY};
    for (int b = 0; b < 3; b++) {
        lk_mesh mesh;
        make_sphere(&mesh, 1);
        mesh.positions[3 * 7 + 1] = bad_values[b];
        lk_error error = {0};
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_ratio = 0.5;
        for (int m = 0; m < 4; m++) {
            lk_simplify_result result;
            assert_int_equal(lk_simplify(&mesh, methods[m], &options, &result, NULL, NULL, &error), LK_ERR_RANGE);
            lk_assert_message_contains(error, "vertex 7: position is not finite");
        }
        lk_metro_result metro;
        assert_int_equal(lk_metro(&mesh, &mesh, NULL, &metro, NULL, NULL, &error), LK_ERR_RANGE);
        lk_assert_message_contains(error, "not finite");
        lk_progressive_mesh pm;
        assert_int_not_equal(lk_progressive_mesh_build(&mesh, NULL, &pm, NULL, NULL, &error), LK_OK);
        lk_assert_message_contains(error, "not finite");
        lk_mesh out;
        lk_mesh_init(&out);
        assert_int_not_equal(lk_subdivide(&mesh, LK_SUBDIVIDE_LOOP, 1, &out, &error), LK_OK);
        lk_assert_message_contains(error, "not finite");
        lk_sample_options sample;
        lk_sample_options_default(&sample);
        sample.point_count = 100;
        assert_int_not_equal(lk_mesh_sample_points(&mesh, &sample, &out, NULL, NULL, &error), LK_OK);
        lk_assert_message_contains(error, "not finite");
        /* as a point set */
        lk_mesh points;
        lk_mesh_init(&points);
        points.vertex_count = mesh.vertex_count;
        points.positions = mesh.positions;
        assert_int_equal(lk_points_estimate_radii(&points, 8, 1.0, &error), LK_ERR_RANGE);
        assert_int_equal(lk_points_estimate_normals(&points, 8, &error), LK_ERR_RANGE);
        lk_assert_message_contains(error, "not finite");
        free(points.radii);
        free(points.normals);
        lk_mesh_free(&mesh);
    }
}

/* ---- the cow at 2^125 and 2^-60: exactly the same simplification ---------- */

static void test_scaled_cow_simplifies_alike(void **state)
{
    (void)state;
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    assert_int_equal(cow.vertex_count, 2904);
    float low[3], high[3];
    double diagonal = lk_mesh_bounds(&cow, low, high);
    /* Powers of two scale floats exactly (no overflow up to FLT_MAX, no
     * denormals down to FLT_MIN): the normalised computations then see the
     * same numbers, so results must be identical, not merely close. */
    const double scales[2] = {ldexp(1.0, 125), ldexp(1.0, -60)};
    float largest = 0;
    for (int k = 0; k < 3; k++) largest = fmaxf(largest, fmaxf(fabsf(low[k]), fabsf(high[k])));
    assert_true(largest * scales[0] < FLT_MAX && largest * scales[0] > 1e37);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_triangles = 1000;
    for (int m = 0; m < 3; m++) {
        lk_error error = {0};
        lk_simplify_result reference;
        assert_int_equal(lk_simplify(&cow, methods[m], &options, &reference, NULL, NULL, &error), LK_OK);
        assert_true(reference.mesh.triangle_count > 0);
        for (int s = 0; s < 2; s++) {
            lk_mesh scaled;
            assert_int_equal(lk_mesh_copy(&scaled, &cow, &error), LK_OK);
            transform(&scaled, scales[s], 0);
            lk_simplify_result result;
            assert_int_equal(lk_simplify(&scaled, methods[m], &options, &result, NULL, NULL, &error), LK_OK);
            assert_finite_mesh(&result.mesh);
            if (result.mesh.triangle_count != reference.mesh.triangle_count)
                fail_msg("%s at scale 2^%d: %zu triangles, unscaled %zu", method_names[m], s ? -60 : 125,
                         result.mesh.triangle_count, reference.mesh.triangle_count);
            assert_memory_equal(result.mesh.indices, reference.mesh.indices,
                                3 * reference.mesh.triangle_count * sizeof(uint32_t));
            assert_true(fabs(result.diagonal / scales[s] - diagonal) <= 1e-9 * diagonal);
            assert_true(fabs(result.error / scales[s] - reference.error) <= 1e-6 * diagonal + 1e-6 * reference.error);
            lk_simplify_result_free(&result);
            lk_mesh_free(&scaled);
        }
        lk_simplify_result_free(&reference);
    }
    lk_mesh_free(&cow);
}

/* ---- a sphere at FLT_MAX: quadric optima and contours overshoot float ---- */

static void test_sphere_near_float_max(void **state)
{
    (void)state;
    const double scales[2] = {3.4e38, (double)FLT_MAX};
    for (int s = 0; s < 2; s++) {
        lk_mesh sphere;
        make_sphere(&sphere, 2);
        transform(&sphere, scales[s], 0);
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        const double ratios[3] = {0.5, 0.1, 0.01};
        for (int m = 0; m < 4; m++) {
            for (int r = 0; r < 3; r++) {
                options.target_ratio = ratios[r];
                lk_error error = {0};
                lk_simplify_result result;
                lk_status status = lk_simplify(&sphere, methods[m], &options, &result, NULL, NULL, &error);
                if (status != LK_OK) fail_msg("%s ratio %g: %s", method_names[m], ratios[r], error.message);
                /* Before the fix: QEM wrote -inf (optimum outside the float
                 * range), the wavelet tiling overflowed its float costs and
                 * walked off its table (UBSan, then SIGSEGV). */
                assert_finite_mesh(&result.mesh);
                assert_true(result.mesh.triangle_count > 0);
                assert_true(isfinite(result.error) && isfinite(result.diagonal));
                if (m == 0 && r == 0) assert_int_equal(result.mesh.triangle_count, 64);
                assert_int_equal(lk_mesh_validate(&result.mesh, &error), LK_OK);
                lk_simplify_result_free(&result);
            }
        }
        lk_metro_result metro;
        lk_error error = {0};
        assert_int_equal(lk_metro(&sphere, &sphere, NULL, &metro, NULL, NULL, &error), LK_OK);
        /* a surface against itself: 0 up to double rounding (~1e-16 of the diagonal) */
        assert_true(isfinite(metro.diagonal) && metro.diagonal > 1e39);
        assert_true(metro.hausdorff >= 0 && metro.hausdorff <= 1e-12 * metro.diagonal);
        lk_progressive_options progressive;
        lk_progressive_options_default(&progressive);
        lk_progressive_mesh pm;
        assert_int_equal(lk_progressive_mesh_build(&sphere, &progressive, &pm, NULL, NULL, &error), LK_OK);
        for (size_t i = 0; i < 3 * pm.base_vertex_count; i++) assert_true(isfinite(pm.base_positions[i]));
        lk_mesh level;
        lk_mesh_init(&level);
        assert_int_equal(lk_progressive_mesh_level(&pm, pm.split_count / 2, &level, &error), LK_OK);
        assert_finite_mesh(&level);
        lk_mesh_free(&level);
        lk_progressive_mesh_free(&pm);
        lk_mesh subdivided;
        lk_mesh_init(&subdivided);
        assert_int_equal(lk_subdivide(&sphere, LK_SUBDIVIDE_LOOP, 1, &subdivided, &error), LK_OK);
        assert_finite_mesh(&subdivided);
        lk_mesh_free(&subdivided);
        lk_mesh_free(&sphere);
    }
}

/* ---- one vertex pulled out to 1e38: metro's edge samples ------------------ */

static void test_metro_needle(void **state)
{
    (void)state;
    lk_mesh needle, sphere;
    make_sphere(&needle, 2);
    make_sphere(&sphere, 2);
    needle.positions[3 * 3 + 1] = -1e38f;
    lk_metro_options options;
    lk_metro_options_default(&options);
    lk_metro_result result;
    lk_error error = {0};
    /* Before: edges 1e38 long over an area of ~1e38 asked for 2e21 edge
     * samples, and metro failed with "cannot allocate 2251799813685250 chunks". */
    assert_int_equal(lk_metro(&needle, &sphere, &options, &result, NULL, NULL, &error), LK_OK);
    assert_true(result.forward.sample_count < 10 * 1280 + 128 * 10);
    assert_true(isfinite(result.hausdorff) && isfinite(result.forward.rms) && isfinite(result.backward.rms));
    /* the needle's tip is 1e38 from the unit sphere */
    assert_true(fabs(result.forward.max - 1e38) < 1e32);
    assert_true(result.backward.max < 1.0); /* the sphere is still in the needle */
    lk_mesh_free(&needle);
    lk_mesh_free(&sphere);
}

/* ---- every vertex at one point, one triangle, zero area ------------------- */

static void test_degenerate_shapes(void **state)
{
    (void)state;
    lk_mesh shapes[4];
    const char *names[4] = {"coincident", "single triangle", "zero area", "denormal"};
    make_sphere(&shapes[0], 1);
    for (size_t i = 0; i < shapes[0].vertex_count; i++) {
        shapes[0].positions[3 * i] = 1.5f, shapes[0].positions[3 * i + 1] = -2, shapes[0].positions[3 * i + 2] = 1e7f;
    }
    static const float triangle[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    static const uint32_t one[3] = {0, 1, 2};
    lk_test_make_mesh(&shapes[1], triangle, 3, one, 1);
    static const float line[24] = {0, 0, 0, 0.5f, 0, 0, 1, 0, 0, 1.5f, 0, 0, 2, 0, 0, 2.5f, 0, 0, 3, 0, 0, 3.5f, 0, 0};
    static const uint32_t fan[24] = {0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 5, 0, 5, 6, 0, 6, 7, 1, 3, 5, 2, 4, 6};
    lk_test_make_mesh(&shapes[2], line, 8, fan, 8);
    make_sphere(&shapes[3], 2);
    transform(&shapes[3], 1e-40, 0);
    for (int s = 0; s < 4; s++) {
        const lk_mesh *mesh = &shapes[s];
        lk_error error = {0};
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        const double ratios[2] = {0.5, 0.01};
        for (int m = 0; m < 4; m++) {
            for (int r = 0; r < 2; r++) {
                options.target_ratio = ratios[r];
                lk_simplify_result result;
                lk_status status = lk_simplify(mesh, methods[m], &options, &result, NULL, NULL, &error);
                if (m == 3 && s < 3) {
                    /* wavelet slicing: no volume to slice; the message says why */
                    assert_int_equal(status, LK_ERR_INVALID);
                    lk_assert_message_contains(error, s == 0 ? "one point" : "flat along z");
                    continue;
                }
                if (status != LK_OK) fail_msg("%s, %s: %s", names[s], method_names[m], error.message);
                assert_finite_mesh(&result.mesh);
                assert_true(isfinite(result.error) && result.error >= 0);
                assert_true(result.mesh.triangle_count <= mesh->triangle_count || m == 3);
                if (s == 0 && m == 0) assert_true(result.error == 0);
                if (s == 1) assert_int_equal(result.mesh.triangle_count, 1);
                lk_simplify_result_free(&result);
            }
        }
        lk_metro_result metro;
        assert_int_equal(lk_metro(mesh, &shapes[1], NULL, &metro, NULL, NULL, &error), LK_OK);
        assert_true(isfinite(metro.hausdorff) && isfinite(metro.forward.mean) && isfinite(metro.backward.rms));
        lk_progressive_mesh pm;
        lk_status status = lk_progressive_mesh_build(mesh, NULL, &pm, NULL, NULL, &error);
        if (status != LK_OK) fail_msg("%s: progressive: %s", names[s], error.message);
        for (size_t i = 0; i < 3 * pm.base_vertex_count; i++) assert_true(isfinite(pm.base_positions[i]));
        assert_true(isfinite(pm.diagonal));
        lk_progressive_mesh_free(&pm);
        lk_mesh out;
        lk_mesh_init(&out);
        assert_int_equal(lk_subdivide(mesh, LK_SUBDIVIDE_MIDPOINT, 2, &out, &error), LK_OK);
        assert_int_equal(out.triangle_count, 16 * mesh->triangle_count);
        assert_finite_mesh(&out);
        lk_mesh_free(&out);
        lk_sample_options sample;
        lk_sample_options_default(&sample);
        sample.point_count = 200;
        status = lk_mesh_sample_points(mesh, &sample, &out, NULL, NULL, &error);
        if (s == 0 || s == 2) {
            assert_int_equal(status, LK_ERR_INVALID);
            lk_assert_message_contains(error, "surface area is 0");
        } else {
            if (status != LK_OK) fail_msg("%s: sample: %s", names[s], error.message);
            assert_int_equal(out.vertex_count, 200);
            assert_finite_mesh(&out);
            if (s == 3) {
                /* Before: radii were clamped up to FLT_MIN (1.2e-38), splats
                 * a thousand times the model (2e-40 across). */
                for (size_t i = 0; i < out.vertex_count; i++) assert_true(out.radii[i] < 1e-39f);
            }
            lk_mesh_free(&out);
        }
    }
    for (int s = 0; s < 4; s++) lk_mesh_free(&shapes[s]);
}

/* ---- point sets: coincident, single, huge, denormal ------------------------ */

static void test_points(void **state)
{
    (void)state;
    enum { COUNT = 40 };
    float positions[3 * COUNT];
    const double scales[4] = {0, 1e38, 1e-41, 1};
    for (int s = 0; s < 4; s++) {
        for (size_t i = 0; i < COUNT; i++) {
            double angle = 0.7 * (double)i, z = (double)i / COUNT - 0.5;
            positions[3 * i] = (float)(cos(angle) * scales[s] + 3);
            positions[3 * i + 1] = (float)(sin(angle) * scales[s]);
            positions[3 * i + 2] = (float)(z * scales[s]);
        }
        size_t counts[2] = {COUNT, 1};
        for (int c = 0; c < 2; c++) {
            lk_mesh points;
            lk_mesh_init(&points);
            points.vertex_count = counts[c];
            points.positions = positions;
            lk_error error = {0};
            assert_int_equal(lk_points_estimate_radii(&points, 8, 1.0, &error), LK_OK);
            assert_int_equal(lk_points_estimate_normals(&points, 8, &error), LK_OK);
            points.positions = NULL;
            lk_mesh copy = points;
            copy.positions = positions;
            assert_finite_mesh(&copy);
            for (size_t i = 0; i < counts[c]; i++) {
                const float *n = copy.normals + 3 * i;
                double length = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
                assert_true(fabs(length - 1) < 1e-3);
            }
            if (s == 2 && c == 0)
                for (size_t i = 0; i < counts[c]; i++) assert_true(copy.radii[i] < 1e-39f);
            free(points.radii);
            free(points.normals);
        }
    }
}

/* ---- terrain: flat, tiny, and a 1e38 spike --------------------------------- */

static void test_terrain(void **state)
{
    (void)state;
    lk_heightfield field;
    memset(&field, 0, sizeof field);
    field.width = field.height = 9;
    field.spacing_x = field.spacing_y = 1;
    float heights[81];
    field.heights = heights;
    for (int variant = 0; variant < 3; variant++) {
        for (int i = 0; i < 81; i++) heights[i] = 1234;
        if (variant == 1) heights[40] = 1e38f;
        if (variant == 2) heights[40] = NAN;
        field.min_height = 1234;
        field.max_height = variant == 1 ? 1e38 : 1234;
        lk_terrain *terrain = NULL;
        lk_error error = {0};
        lk_status status = lk_terrain_create(&field, NULL, &terrain, &error);
        if (variant == 2) {
            assert_int_equal(status, LK_ERR_RANGE);
            lk_assert_message_contains(error, "not finite");
            continue;
        }
        assert_int_equal(status, LK_OK);
        size_t most = 0;
        for (size_t frame = 0; frame < 20; frame++) {
            lk_terrain_view view;
            lk_terrain_flight(terrain, frame, 0.5, &view);
            lk_mesh mesh;
            lk_mesh_init(&mesh);
            lk_terrain_stats stats;
            assert_int_equal(lk_terrain_update(terrain, &view, &mesh, &stats, &error), LK_OK);
            assert_finite_mesh(&mesh);
            if (mesh.triangle_count > most) most = mesh.triangle_count;
            lk_mesh_free(&mesh);
        }
        /* Before: the flight flew 10 samples above a grid 8 samples wide and
         * saw nothing in any frame. */
        if (variant == 0) assert_true(most >= 16);
        lk_terrain_free(terrain);
    }
}

/* ---- animation: coincident frames, 1e38 frames, NaN ------------------------ */

static void test_animation(void **state)
{
    (void)state;
    lk_mesh sphere;
    make_sphere(&sphere, 1);
    size_t v = sphere.vertex_count;
    for (int variant = 0; variant < 4; variant++) {
        lk_animation animation;
        lk_animation_init(&animation);
        lk_error error = {0};
        assert_int_equal(lk_mesh_copy(&animation.mesh, &sphere, &error), LK_OK);
        animation.frame_count = 3;
        animation.frames_per_second = 10;
        animation.frame_positions = malloc(3 * v * 3 * sizeof(float));
        assert_non_null(animation.frame_positions);
        for (size_t f = 0; f < 3; f++)
            for (size_t i = 0; i < 3 * v; i++) {
                double value = sphere.positions[i];
                if (variant == 0) value = (double)(i % 3) + 0.5 * (double)f; /* all coincident per frame */
                if (variant == 1) value *= f == 0 ? 1e38 : f == 1 ? -1e38 : 1;
                if (variant == 2) value *= 1 + 0.2 * (double)f;
                animation.frame_positions[3 * v * f + i] = (float)value;
            }
        if (variant == 3) animation.frame_positions[3 * v * 2 + 4] = NAN;
        memcpy(animation.mesh.positions, animation.frame_positions, 3 * v * sizeof(float));
        lk_anim_simplify_options options;
        lk_anim_simplify_options_default(&options);
        options.simplify.target_ratio = 0.25;
        options.allow_folds = 1;
        lk_anim_simplify_result result;
        lk_status status = lk_animation_simplify(&animation, &options, &result, NULL, NULL, &error);
        if (variant == 3) {
            assert_int_not_equal(status, LK_OK);
            lk_assert_message_contains(error, "not finite");
        } else if (variant == 0) {
            /* every frame collapses to a point: nothing but degenerate triangles */
            assert_int_equal(status, LK_ERR_INVALID);
            lk_assert_message_contains(error, "degenerate");
        } else {
            if (status != LK_OK) fail_msg("variant %d: %s", variant, error.message);
            for (size_t i = 0; i < 3 * result.animation.mesh.vertex_count * result.animation.frame_count; i++)
                assert_true(isfinite(result.animation.frame_positions[i]));
            assert_true(isfinite(result.error) && isfinite(result.diagonal));
            assert_true(result.animation.mesh.triangle_count <= 8);
            lk_anim_simplify_result_free(&result);
        }
        lk_animation_free(&animation);
    }
    lk_mesh_free(&sphere);
}

/* ---- rendering: the picture does not depend on the model's scale ----------- */

static size_t foreground(const unsigned char *rgba, size_t pixels)
{
    size_t count = 0;
    for (size_t i = 0; i < pixels; i++) count += rgba[4 * i] != 255 || rgba[4 * i + 1] != 255 || rgba[4 * i + 2] != 255;
    return count;
}

static void test_render_scale_invariant(void **state)
{
    (void)state;
    enum { SIDE = 96 };
    lk_renderer *renderer = NULL;
    lk_error error = {0};
    if (lk_renderer_create(SIDE, SIDE, &renderer, &error) != LK_OK) fail_msg("renderer: %s", error.message);
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    lk_sample_options sample;
    lk_sample_options_default(&sample);
    sample.point_count = 3000;
    unsigned char *reference[2] = {NULL, NULL};
    size_t reference_count[2] = {0, 0};
    const double scales[3] = {1, ldexp(1.0, 125), ldexp(1.0, -60)};
    for (int s = 0; s < 3; s++) {
        lk_mesh scaled;
        assert_int_equal(lk_mesh_copy(&scaled, &cow, &error), LK_OK);
        transform(&scaled, scales[s], 0);
        lk_mesh points;
        lk_mesh_init(&points);
        assert_int_equal(lk_mesh_sample_points(&scaled, &sample, &points, NULL, NULL, &error), LK_OK);
        for (int kind = 0; kind < 2; kind++) {
            lk_status status = kind ? lk_render_points(renderer, &points, NULL, NULL, &error)
                                    : lk_render_mesh(renderer, &scaled, NULL, NULL, &error);
            if (status != LK_OK) fail_msg("render: %s", error.message);
            unsigned char *pixels = malloc(SIDE * SIDE * 4);
            assert_non_null(pixels);
            assert_int_equal(lk_renderer_read_pixels(renderer, pixels, &error), LK_OK);
            size_t count = foreground(pixels, SIDE * SIDE);
            if (s == 0) {
                /* the cow fills a good part of the frame */
                assert_true(count > SIDE * SIDE / 8);
                reference[kind] = pixels;
                reference_count[kind] = count;
                continue;
            }
            /* Before: 2^125 gave a blank picture (1 / far underflows in GL);
             * the same picture now, give or take a few edge pixels. */
            size_t differing = 0;
            for (size_t i = 0; i < SIDE * SIDE * 4; i++) differing += abs((int)pixels[i] - (int)reference[kind][i]) > 8;
            if (differing > SIDE * SIDE / 100)
                fail_msg("%s at scale %g: %zu of %d channels differ (foreground %zu vs %zu)", kind ? "splats" : "mesh",
                         scales[s], differing, SIDE * SIDE * 4, count, reference_count[kind]);
            free(pixels);
        }
        lk_mesh_free(&points);
        lk_mesh_free(&scaled);
    }
    free(reference[0]);
    free(reference[1]);
    lk_mesh_free(&cow);
    lk_renderer_free(renderer);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_non_finite_refused),
        cmocka_unit_test(test_scaled_cow_simplifies_alike),
        cmocka_unit_test(test_sphere_near_float_max),
        cmocka_unit_test(test_metro_needle),
        cmocka_unit_test(test_degenerate_shapes),
        cmocka_unit_test(test_points),
        cmocka_unit_test(test_terrain),
        cmocka_unit_test(test_animation),
        cmocka_unit_test(test_render_scale_invariant),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
