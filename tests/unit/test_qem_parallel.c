/* SPDX-License-Identifier: MIT */
/* QEM on several threads (src/qem_parallel.c): slabs simplified apart with
 * their shared vertices locked, then the band around the cuts. Run on the
 * bunny (70K triangles, below LK_SIMPLIFY_PARALLEL_MIN, so through the
 * internal entry point): the counts, the vertex map, a closed seam, the
 * error against one thread, determinism, locks, attributes, the other
 * stopping rules and cancellation. Error bounds are about 10-25% above
 * what was measured (numbers in the comments). */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#include "internal.h" /* lk__simplify_qem_parallel, lk__simplify_qem_part */

#define NONE UINT32_MAX

static lk_mesh bunny(void)
{
    lk_mesh mesh;
    lk_error error = {0};
    if (lk_mesh_read(lk_test_sample("bunny.obj"), LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK)
        fail_msg("bunny: %s", error.message);
    return mesh;
}

static lk_simplify_options ratio_options(double ratio)
{
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = ratio;
    return options;
}

static void one_thread(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result)
{
    lk_error error = {0};
    if (lk_simplify(mesh, LK_SIMPLIFY_QEM, options, result, NULL, NULL, &error) != LK_OK)
        fail_msg("lk_simplify: %s", error.message);
}

static void slabs(const lk_mesh *mesh, const lk_simplify_options *options, unsigned parts, lk_simplify_result *result)
{
    lk_error error = {0};
    memset(result, 0, sizeof *result);
    result->diagonal = lk_mesh_bounds(mesh, NULL, NULL);
    if (lk__simplify_qem_parallel(mesh, options, parts, result, NULL, NULL, &error) != LK_OK)
        fail_msg("lk__simplify_qem_parallel: %s", error.message);
}

/* Hausdorff and the larger one-sided RMS distance, fractions of the diagonal */
static void measure(const lk_mesh *input, const lk_mesh *output, double *hausdorff, double *rms)
{
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = 3;
    lk_metro_result metro;
    lk_error error = {0};
    if (lk_metro(input, output, &options, &metro, NULL, NULL, &error) != LK_OK) fail_msg("metro: %s", error.message);
    *hausdorff = metro.hausdorff / metro.diagonal;
    *rms = fmax(metro.forward.rms, metro.backward.rms) / metro.diagonal;
}

static size_t boundary_edges(const lk_mesh *mesh)
{
    lk_mesh_stats stats;
    lk_error error = {0};
    if (lk_mesh_compute_stats(mesh, &stats, &error) != LK_OK) fail_msg("stats: %s", error.message);
    return stats.boundary_edge_count;
}

/* Every input vertex maps to an output vertex or nowhere, every output
 * vertex is reached, and every triangle's corners are in range. */
static void assert_valid_map(const lk_mesh *input, const lk_simplify_result *result)
{
    const lk_mesh *out = &result->mesh;
    unsigned char *reached = calloc(out->vertex_count + 1, 1);
    assert_non_null(reached);
    for (size_t v = 0; v < input->vertex_count; v++) {
        uint32_t o = result->vertex_map[v];
        if (o == NONE) continue;
        assert_true(o < out->vertex_count);
        reached[o] = 1;
    }
    for (size_t o = 0; o < out->vertex_count; o++) assert_true(reached[o]);
    for (size_t i = 0; i < 3 * out->triangle_count; i++) assert_true(out->indices[i] < out->vertex_count);
    free(reached);
}

/* The measured numbers (bunny, 3 samples per face; one thread / 2 slabs /
 * 3 slabs): 10%: H 0.188 / 0.196 / 0.177%, RMS 0.0256 / 0.0250 / 0.0248%;
 * 2%: H 1.006 / 0.752 / 0.793%, RMS 0.1025 / 0.1017 / 0.1006%. The seam
 * leaves no open edge: the output is as closed as one thread's (the
 * bunny: 0 boundary edges). */
static void test_slabs_match_one_thread(void **state)
{
    (void)state;
    lk_mesh mesh = bunny();
    const double ratios[] = {0.1, 0.02};
    for (int r = 0; r < 2; r++) {
        lk_simplify_options options = ratio_options(ratios[r]);
        lk_simplify_result single;
        one_thread(&mesh, &options, &single);
        double single_hausdorff, single_rms;
        measure(&mesh, &single.mesh, &single_hausdorff, &single_rms);
        size_t single_boundary = boundary_edges(&single.mesh);
        for (unsigned parts = 2; parts <= 3; parts++) {
            lk_simplify_result result;
            slabs(&mesh, &options, parts, &result);
            assert_int_equal(result.mesh.triangle_count, single.mesh.triangle_count);
            assert_true(result.target_reached);
            assert_valid_map(&mesh, &result);
            double hausdorff, rms;
            measure(&mesh, &result.mesh, &hausdorff, &rms);
            size_t boundary = boundary_edges(&result.mesh);
            printf("ratio %.2f, %u slabs: H %.4f%% (one thread %.4f%%), RMS %.5f%% (%.5f%%), boundary edges %zu "
                   "(%zu), error %.4g (%.4g)\n",
                   ratios[r], parts, 100 * hausdorff, 100 * single_hausdorff, 100 * rms, 100 * single_rms, boundary,
                   single_boundary, result.error, single.error);
            assert_true(hausdorff <= 1.25 * single_hausdorff);
            assert_true(rms <= 1.05 * single_rms);
            assert_int_equal(boundary, single_boundary);
            assert_true(result.error > 0 && result.error <= 1.5 * single.error);
            lk_simplify_result_free(&result);
        }
        lk_simplify_result_free(&single);
    }
    lk_mesh_free(&mesh);
}

static void test_deterministic(void **state)
{
    (void)state;
    lk_mesh mesh = bunny();
    lk_simplify_options options = ratio_options(0.05);
    lk_simplify_result first, second;
    slabs(&mesh, &options, 2, &first);
    slabs(&mesh, &options, 2, &second);
    assert_int_equal(first.mesh.vertex_count, second.mesh.vertex_count);
    assert_int_equal(first.mesh.triangle_count, second.mesh.triangle_count);
    assert_memory_equal(first.mesh.positions, second.mesh.positions, 3 * first.mesh.vertex_count * sizeof(float));
    assert_memory_equal(first.mesh.indices, second.mesh.indices, 3 * first.mesh.triangle_count * sizeof(uint32_t));
    assert_memory_equal(first.vertex_map, second.vertex_map, mesh.vertex_count * sizeof(uint32_t));
    lk_simplify_result_free(&first);
    lk_simplify_result_free(&second);
    lk_mesh_free(&mesh);
}

/* A part's locked vertices survive where they were, each its own vertex
 * (the slabs rely on it to join). */
static void test_locked_vertices_stay(void **state)
{
    (void)state;
    lk_mesh mesh = bunny();
    unsigned char *locked = calloc(mesh.vertex_count, 1);
    assert_non_null(locked);
    for (size_t v = 0; v < mesh.vertex_count; v += 7) locked[v] = 1;
    float min[3], max[3];
    lk__qem_part part = {.locked = locked, .extent = lk_mesh_bounds(&mesh, min, max)};
    for (int k = 0; k < 3; k++) part.center[k] = 0.5 * ((double)min[k] + max[k]);
    lk_simplify_options options = ratio_options(0.05);
    lk_simplify_result result = {0};
    lk_error error = {0};
    if (lk__simplify_qem_part(&mesh, &options, &part, &result, NULL, NULL, &error) != LK_OK)
        fail_msg("part: %s", error.message);
    unsigned char *taken = calloc(result.mesh.vertex_count, 1);
    assert_non_null(taken);
    size_t locked_count = 0;
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        if (!locked[v]) continue;
        locked_count++;
        uint32_t o = result.vertex_map[v];
        assert_int_not_equal(o, NONE);
        assert_false(taken[o]);
        taken[o] = 1;
        assert_memory_equal(result.mesh.positions + 3 * (size_t)o, mesh.positions + 3 * v, 3 * sizeof(float));
    }
    /* the lock is what kept them: 1/7 of the vertices survive a 5% target */
    assert_true(result.mesh.vertex_count >= locked_count);
    free(taken);
    free(locked);
    lk_simplify_result_free(&result);
    lk_mesh_free(&mesh);
}

/* Normals and texture coordinates come through; a vertex target is met. */
static void test_attributes_and_vertex_target(void **state)
{
    (void)state;
    lk_mesh plain = bunny(), mesh;
    lk_error error = {0};
    assert_int_equal(
        lk_mesh_alloc(&mesh, plain.vertex_count, plain.triangle_count, LK_ATTR_NORMALS | LK_ATTR_TEXCOORDS, &error),
        LK_OK);
    memcpy(mesh.positions, plain.positions, 3 * plain.vertex_count * sizeof(float));
    memcpy(mesh.indices, plain.indices, 3 * plain.triangle_count * sizeof(uint32_t));
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        const float *p = mesh.positions + 3 * v;
        float length = sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) + 1e-20f;
        for (int k = 0; k < 3; k++) mesh.normals[3 * v + k] = p[k] / length;
        mesh.texcoords[2 * v] = p[0] * 4, mesh.texcoords[2 * v + 1] = p[1] * 4;
    }
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_vertices = 2000;
    options.flags = LK_SIMPLIFY_ATTRIBUTES;
    lk_simplify_result result;
    slabs(&mesh, &options, 2, &result);
    assert_true(result.target_reached);
    assert_true(result.mesh.vertex_count <= 2000 && result.mesh.vertex_count >= 1900);
    assert_non_null(result.mesh.normals);
    assert_non_null(result.mesh.texcoords);
    assert_valid_map(&mesh, &result);
    /* each output vertex carries the attributes of the input vertices merged into it: its normal is unit length
     * and points like one of theirs */
    for (size_t o = 0; o < result.mesh.vertex_count; o++) {
        const float *n = result.mesh.normals + 3 * o;
        assert_true(fabsf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1) < 0.05f);
    }
    lk_simplify_result_free(&result);
    lk_mesh_free(&mesh);
    lk_mesh_free(&plain);
}

/* An error bound alone: every collapse of the slabs and of the band stays
 * under it. */
static void test_max_error_only(void **state)
{
    (void)state;
    lk_mesh mesh = bunny();
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.max_error = 0.002;
    lk_simplify_result single, result;
    one_thread(&mesh, &options, &single);
    slabs(&mesh, &options, 2, &result);
    assert_true(result.target_reached);
    assert_true(result.error <= 0.002 * result.diagonal * (1 + 1e-9));
    printf("max error 0.2%%: %zu triangles (one thread %zu)\n", result.mesh.triangle_count, single.mesh.triangle_count);
    /* as far as one thread goes, give or take the band */
    assert_true(result.mesh.triangle_count <= single.mesh.triangle_count * 11 / 10);
    lk_simplify_result_free(&single);
    lk_simplify_result_free(&result);
    lk_mesh_free(&mesh);
}

static int cancel_at_half(void *user, double fraction, const char *stage)
{
    (void)user, (void)stage;
    return fraction >= 0.5;
}

static void test_cancel_and_options(void **state)
{
    (void)state;
    lk_mesh mesh = bunny();
    lk_simplify_options options = ratio_options(0.01);
    lk_simplify_result result = {0};
    lk_error error = {0};
    assert_int_equal(lk__simplify_qem_parallel(&mesh, &options, 2, &result, cancel_at_half, NULL, &error),
                     LK_ERR_INVALID);
    assert_string_equal(error.message, "cancelled");
    /* the public option: checked, and below LK_SIMPLIFY_PARALLEL_MIN triangles the same as one thread */
    options.thread_count = 65;
    assert_int_equal(lk_simplify(&mesh, LK_SIMPLIFY_QEM, &options, &result, NULL, NULL, &error), LK_ERR_INVALID);
    options.thread_count = 2;
    lk_simplify_result single;
    one_thread(&mesh, &options, &result);
    options.thread_count = 1;
    one_thread(&mesh, &options, &single);
    assert_int_equal(result.mesh.triangle_count, single.mesh.triangle_count);
    assert_memory_equal(result.mesh.positions, single.mesh.positions, 3 * single.mesh.vertex_count * sizeof(float));
    lk_simplify_result_free(&result);
    lk_simplify_result_free(&single);
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_slabs_match_one_thread), cmocka_unit_test(test_deterministic),
        cmocka_unit_test(test_locked_vertices_stay),   cmocka_unit_test(test_attributes_and_vertex_target),
        cmocka_unit_test(test_max_error_only),         cmocka_unit_test(test_cancel_and_options),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
