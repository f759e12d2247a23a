/* SPDX-License-Identifier: MIT */
/* Progressive meshes: exact round trip, prefix levels, the base mesh equal to
 * lk_simplify's, endpoint placement, bad options. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

static void build(const char *sample, unsigned flags, lk_mesh *mesh, lk_progressive_mesh *pm)
{
    lk_test_load(lk_test_sample(sample), mesh);
    lk_progressive_options options;
    lk_progressive_options_default(&options);
    options.simplify.flags |= flags;
    lk_error error = {0};
    lk_status status = lk_progressive_mesh_build(mesh, &options, pm, NULL, NULL, &error);
    if (status != LK_OK) fail_msg("%s: %s", sample, error.message);
}

/* Splitting all the way back gives the input's triangles corner for corner
 * (through the recorded permutations) and its exact positions. */
static void check_round_trip(const char *sample, size_t expected_triangles)
{
    lk_mesh mesh;
    lk_progressive_mesh pm;
    build(sample, 0, &mesh, &pm);
    assert_int_equal(pm.triangle_count, expected_triangles);
    assert_int_equal(pm.vertex_count, pm.base_vertex_count + pm.split_count);
    /* the paper's base mesh: 5% of the triangles */
    assert_true(pm.base_triangle_count <= (size_t)ceil(0.05 * (double)pm.triangle_count) + 1);
    assert_true(pm.base_triangle_count >= (size_t)(0.04 * (double)pm.triangle_count));

    lk_mesh full;
    lk_error error = {0};
    assert_int_equal(lk_progressive_mesh_level(&pm, pm.split_count, &full, &error), LK_OK);
    assert_int_equal(full.triangle_count, pm.triangle_count);
    assert_int_equal(full.vertex_count, pm.vertex_count);
    unsigned char *seen = calloc(mesh.triangle_count, 1);
    assert_non_null(seen);
    for (size_t t = 0; t < full.triangle_count; t++) {
        uint32_t input = pm.triangle_order[t];
        assert_true(input < mesh.triangle_count);
        assert_false(seen[input]);
        seen[input] = 1;
        for (int k = 0; k < 3; k++)
            assert_int_equal(pm.vertex_order[full.indices[3 * t + k]], mesh.indices[3 * (size_t)input + k]);
    }
    for (size_t v = 0; v < full.vertex_count; v++)
        assert_memory_equal(full.positions + 3 * v, mesh.positions + 3 * (size_t)pm.vertex_order[v], 3 * sizeof(float));
    free(seen);
    lk_mesh_free(&full);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
}

static void test_round_trip_bunny(void **state)
{
    (void)state;
    check_round_trip("bunny.obj", 69666);
}

static void test_round_trip_cow_triceratops_fandisk(void **state)
{
    (void)state;
    check_round_trip("cow.off", 5804);
    check_round_trip("triceratops.off", 5660);
    check_round_trip("fandisk.off", 12946);
    check_round_trip("ChineseDragon-10kv.off", 19994); /* open: two boundary loops */
}

/* Every level is a valid mesh: the promised triangle count, no degenerate
 * triangle, every vertex used, and each split adds what it says. The error
 * against the original shrinks as splits arrive. */
static void test_levels(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_progressive_mesh pm;
    build("cow.off", 0, &mesh, &pm);
    const size_t levels[] = {0, 1, pm.split_count / 10, pm.split_count / 2, pm.split_count - 1, pm.split_count};
    double previous_error = INFINITY;
    for (size_t i = 0; i < sizeof levels / sizeof levels[0]; i++) {
        lk_mesh level;
        lk_error error = {0};
        assert_int_equal(lk_progressive_mesh_level(&pm, levels[i], &level, &error), LK_OK);
        assert_int_equal(level.vertex_count, pm.base_vertex_count + levels[i]);
        assert_int_equal(level.triangle_count, lk_progressive_mesh_level_triangles(&pm, levels[i]));
        unsigned char *used = calloc(level.vertex_count, 1);
        assert_non_null(used);
        for (size_t t = 0; t < level.triangle_count; t++) {
            const uint32_t *c = level.indices + 3 * t;
            assert_true(c[0] != c[1] && c[1] != c[2] && c[0] != c[2]);
            for (int k = 0; k < 3; k++) used[c[k]] = 1;
        }
        for (size_t v = 0; v < level.vertex_count; v++) assert_true(used[v]);
        free(used);
        if (levels[i] > 0 && levels[i] < pm.split_count)
            assert_int_equal(lk_progressive_mesh_level_triangles(&pm, levels[i] + 1) -
                                 lk_progressive_mesh_level_triangles(&pm, levels[i]),
                             pm.splits[levels[i]].triangle_count);
        lk_metro_options metro_options;
        lk_metro_options_default(&metro_options);
        lk_metro_result metro;
        assert_int_equal(lk_metro(&mesh, &level, &metro_options, &metro, NULL, NULL, &error), LK_OK);
        assert_true(metro.hausdorff <= previous_error + 1e-6 * pm.diagonal);
        previous_error = metro.hausdorff;
        if (levels[i] == pm.split_count) assert_true(metro.hausdorff <= 1e-6 * pm.diagonal);
        if (levels[i] == 0) assert_true(metro.hausdorff > 0.005 * pm.diagonal);
        lk_mesh_free(&level);
    }
    /* manifold cow: every split restores two triangles */
    size_t two = 0;
    for (size_t k = 0; k < pm.split_count; k++) two += pm.splits[k].triangle_count == 2;
    assert_int_equal(two, pm.split_count);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
}

/* The base mesh is exactly what lk_simplify gives at the same target. */
static void test_base_equals_simplify(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_progressive_mesh pm;
    build("bunny.obj", 0, &mesh, &pm);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.05;
    lk_simplify_result result;
    lk_error error = {0};
    assert_int_equal(lk_simplify(&mesh, LK_SIMPLIFY_QEM, &options, &result, NULL, NULL, &error), LK_OK);
    lk_mesh base;
    assert_int_equal(lk_progressive_mesh_level(&pm, 0, &base, &error), LK_OK);
    assert_int_equal(base.triangle_count, result.mesh.triangle_count);
    assert_int_equal(base.vertex_count, result.mesh.vertex_count);
    /* same positions as a sorted multiset */
    double sum_base = 0, sum_simplified = 0;
    for (size_t i = 0; i < 3 * base.vertex_count; i++) {
        sum_base += base.positions[i] * (double)(i % 3 + 1);
        sum_simplified += result.mesh.positions[i] * (double)(i % 3 + 1);
    }
    assert_true(fabs(sum_base - sum_simplified) <= 1e-9 * fabs(sum_simplified) + 1e-9);
    lk_mesh_free(&base);
    lk_simplify_result_free(&result);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
}

/* Half-edge collapses: p never moves, so every position at every level is
 * an input position. */
static void test_endpoint_placement(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_progressive_mesh pm;
    build("cow.off", LK_SIMPLIFY_ENDPOINTS, &mesh, &pm);
    for (size_t v = 0; v < pm.base_vertex_count; v++)
        assert_memory_equal(pm.base_positions + 3 * v, mesh.positions + 3 * (size_t)pm.vertex_order[v],
                            3 * sizeof(float));
    for (size_t k = 0; k < pm.split_count; k++) {
        const lk_vertex_split *split = &pm.splits[k];
        assert_memory_equal(split->kept_position, mesh.positions + 3 * (size_t)pm.vertex_order[split->kept],
                            3 * sizeof(float));
        assert_memory_equal(split->position, mesh.positions + 3 * (size_t)pm.vertex_order[pm.base_vertex_count + k],
                            3 * sizeof(float));
    }
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
}

/* Degenerate and duplicate input triangles and unused vertices are dropped
 * with the permutations still pointing into the input. */
static void test_dirty_input(void **state)
{
    (void)state;
    lk_mesh torus;
    lk_test_make_torus(&torus, 12, 8);
    size_t t0 = torus.triangle_count;
    /* add an unused vertex, a degenerate and a duplicate (reversed) triangle */
    lk_mesh dirty;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&dirty, torus.vertex_count + 1, t0 + 2, 0, &error), LK_OK);
    memcpy(dirty.positions, torus.positions, torus.vertex_count * 3 * sizeof(float));
    dirty.positions[3 * torus.vertex_count] = 100, dirty.positions[3 * torus.vertex_count + 1] = 0,
                        dirty.positions[3 * torus.vertex_count + 2] = 0;
    memcpy(dirty.indices, torus.indices, t0 * 3 * sizeof(uint32_t));
    uint32_t degenerate[3] = {1, 1, 2}, duplicate[3] = {torus.indices[2], torus.indices[1], torus.indices[0]};
    memcpy(dirty.indices + 3 * t0, degenerate, sizeof degenerate);
    memcpy(dirty.indices + 3 * (t0 + 1), duplicate, sizeof duplicate);
    lk_progressive_options options;
    lk_progressive_options_default(&options);
    options.base_triangles = 20;
    lk_progressive_mesh pm;
    assert_int_equal(lk_progressive_mesh_build(&dirty, &options, &pm, NULL, NULL, &error), LK_OK);
    assert_int_equal(pm.triangle_count, t0);
    assert_int_equal(pm.vertex_count, torus.vertex_count);
    assert_true(pm.base_triangle_count <= 20);
    for (size_t t = 0; t < pm.triangle_count; t++) assert_true(pm.triangle_order[t] < t0);
    for (size_t v = 0; v < pm.vertex_count; v++) assert_true(pm.vertex_order[v] < torus.vertex_count);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&dirty);
    lk_mesh_free(&torus);
}

static void test_bad_options(void **state)
{
    (void)state;
    lk_mesh cube, points;
    lk_test_make_cube(&cube);
    lk_progressive_options options;
    lk_progressive_mesh pm;
    lk_error error = {0};
    lk_progressive_options_default(&options);
    options.base_ratio = 0;
    assert_int_equal(lk_progressive_mesh_build(&cube, &options, &pm, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "base ratio");
    lk_progressive_options_default(&options);
    options.simplify.pair_distance = 0.01;
    assert_int_equal(lk_progressive_mesh_build(&cube, &options, &pm, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "pair distance");
    assert_int_equal(lk_mesh_alloc(&points, 4, 0, 0, &error), LK_OK);
    memset(points.positions, 0, 12 * sizeof(float));
    assert_int_equal(lk_progressive_mesh_build(&points, NULL, &pm, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "point set");
    lk_mesh_free(&points);
    lk_mesh_free(&cube);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_bunny),
        cmocka_unit_test(test_round_trip_cow_triceratops_fandisk),
        cmocka_unit_test(test_levels),
        cmocka_unit_test(test_base_equals_simplify),
        cmocka_unit_test(test_endpoint_placement),
        cmocka_unit_test(test_dirty_input),
        cmocka_unit_test(test_bad_options),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
