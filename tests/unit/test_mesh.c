/* SPDX-License-Identifier: MIT */
/* Mesh core: adjacency, welding, clean-up, components, topology statistics,
 * on hand-built shapes with known answers and on the real sample models. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

static lk_mesh_stats stats_of(const lk_mesh *mesh)
{
    lk_mesh_stats stats;
    lk_error error = {0};
    if (lk_mesh_compute_stats(mesh, &stats, &error) != LK_OK) fail_msg("stats: %s", error.message);
    return stats;
}

static void test_cube_topology(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_make_cube(&mesh);
    lk_mesh_stats stats = stats_of(&mesh);
    assert_int_equal(stats.edge_count, 18);
    assert_int_equal(stats.boundary_edge_count, 0);
    assert_int_equal(stats.nonmanifold_edge_count, 0);
    assert_int_equal(stats.nonmanifold_vertex_count, 0);
    assert_int_equal(stats.component_count, 1);
    assert_int_equal(stats.euler_characteristic, 2);
    assert_int_equal(stats.genus, 0);
    assert_true(fabs(stats.area - 6.0) < 1e-9);
    assert_true(fabs(stats.diagonal - sqrt(3.0)) < 1e-6);
    lk_mesh_free(&mesh);
}

static void test_torus_and_grid(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_make_torus(&mesh, 24, 12);
    lk_mesh_stats stats = stats_of(&mesh);
    assert_int_equal(stats.euler_characteristic, 0);
    assert_int_equal(stats.genus, 1);
    assert_int_equal(stats.boundary_edge_count, 0);
    lk_mesh_free(&mesh);

    lk_test_make_grid(&mesh, 10);
    stats = stats_of(&mesh);
    assert_int_equal(stats.boundary_edge_count, 40);
    assert_int_equal(stats.boundary_loop_count, 1);
    assert_int_equal(stats.euler_characteristic, 1);
    assert_int_equal(stats.genus, 0);
    assert_true(fabs(stats.area - 100.0) < 1e-9);
    lk_mesh_free(&mesh);
}

static void test_nonmanifold(void **state)
{
    (void)state;
    /* Bowtie: two triangles sharing only vertex 0. */
    lk_mesh mesh;
    assert_int_equal(lk_mesh_alloc(&mesh, 5, 2, 0, NULL), LK_OK);
    float positions[15] = {0, 0, 0, 1, 0, 0, 1, 1, 0, -1, 0, 0, -1, -1, 0};
    uint32_t indices[6] = {0, 1, 2, 0, 3, 4};
    memcpy(mesh.positions, positions, sizeof positions);
    memcpy(mesh.indices, indices, sizeof indices);
    lk_mesh_stats stats = stats_of(&mesh);
    assert_int_equal(stats.nonmanifold_vertex_count, 1);
    assert_int_equal(stats.nonmanifold_edge_count, 0);
    assert_int_equal(stats.component_count, 1);
    assert_int_equal(stats.genus, -1);
    lk_mesh_free(&mesh);

    /* Three triangles on one edge (0,1). */
    assert_int_equal(lk_mesh_alloc(&mesh, 5, 3, 0, NULL), LK_OK);
    float fin_positions[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1};
    uint32_t fin_indices[9] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    memcpy(mesh.positions, fin_positions, sizeof fin_positions);
    memcpy(mesh.indices, fin_indices, sizeof fin_indices);
    stats = stats_of(&mesh);
    assert_int_equal(stats.nonmanifold_edge_count, 1);
    assert_int_equal(stats.nonmanifold_vertex_count, 2);
    assert_int_equal(stats.boundary_edge_count, 6);
    assert_int_equal(stats.genus, -1);
    lk_mesh_free(&mesh);
}

static void test_edge_adjacency(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_make_torus(&mesh, 8, 6);
    lk_edge_adjacency edges;
    assert_int_equal(lk_edge_adjacency_build(&mesh, &edges, NULL), LK_OK);
    assert_int_equal(edges.edge_count, 3 * mesh.triangle_count / 2);
    for (size_t e = 0; e < edges.edge_count; e++) {
        assert_true(edges.vertices[2 * e] < edges.vertices[2 * e + 1]);
        if (e) {
            uint64_t prev = ((uint64_t)edges.vertices[2 * e - 2] << 32) | edges.vertices[2 * e - 1];
            uint64_t cur = ((uint64_t)edges.vertices[2 * e] << 32) | edges.vertices[2 * e + 1];
            assert_true(prev < cur);
        }
        assert_int_equal(edges.offsets[e + 1] - edges.offsets[e], 2);
        for (uint32_t i = edges.offsets[e]; i < edges.offsets[e + 1]; i++) {
            uint32_t t = edges.triangles[i];
            int hits = 0;
            for (int k = 0; k < 3; k++)
                hits += mesh.indices[3 * t + k] == edges.vertices[2 * e] ||
                        mesh.indices[3 * t + k] == edges.vertices[2 * e + 1];
            assert_int_equal(hits, 2);
        }
    }
    for (size_t c = 0; c < 3 * mesh.triangle_count; c++) {
        uint32_t e = edges.triangle_edges[c];
        uint32_t a = mesh.indices[c], b = mesh.indices[c - c % 3 + (c % 3 + 1) % 3];
        assert_int_equal(edges.vertices[2 * e], a < b ? a : b);
        assert_int_equal(edges.vertices[2 * e + 1], a < b ? b : a);
    }
    lk_edge_adjacency_free(&edges);

    lk_vertex_adjacency around;
    assert_int_equal(lk_vertex_adjacency_build(&mesh, &around, NULL), LK_OK);
    assert_int_equal(around.offsets[mesh.vertex_count], 3 * mesh.triangle_count);
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        assert_int_equal(around.offsets[v + 1] - around.offsets[v], 6); /* regular grid valence */
        for (uint32_t i = around.offsets[v]; i < around.offsets[v + 1]; i++) {
            uint32_t t = around.triangles[i];
            assert_true(mesh.indices[3 * t] == v || mesh.indices[3 * t + 1] == v || mesh.indices[3 * t + 2] == v);
        }
    }
    lk_vertex_adjacency_free(&around);
    lk_mesh_free(&mesh);
}

/* A triangle soup of the cube (36 vertices, as STL stores it) welds back. */
static void test_weld(void **state)
{
    (void)state;
    lk_mesh cube, soup;
    lk_test_make_cube(&cube);
    assert_int_equal(lk_mesh_alloc(&soup, 36, 12, LK_ATTR_NORMALS, NULL), LK_OK);
    for (size_t c = 0; c < 36; c++) {
        memcpy(soup.positions + 3 * c, cube.positions + 3 * cube.indices[c], 3 * sizeof(float));
        /* Jitter by up to 1e-5 so exact welding would fail. */
        soup.positions[3 * c] += (float)((c % 3) * 0.5e-5);
        soup.normals[3 * c] = soup.normals[3 * c + 1] = soup.normals[3 * c + 2] = (float)c;
        soup.indices[c] = (uint32_t)c;
    }
    lk_mesh exact;
    assert_int_equal(lk_mesh_copy(&exact, &soup, NULL), LK_OK);
    size_t merged = 0;
    assert_int_equal(lk_mesh_weld(&exact, 0.0, &merged, NULL), LK_OK);
    assert_true(exact.vertex_count > 8); /* jitter defeats exact welding */
    assert_int_equal(lk_mesh_weld(&soup, 1e-4, &merged, NULL), LK_OK);
    assert_int_equal(soup.vertex_count, 8);
    assert_int_equal(merged, 28);
    assert_non_null(soup.normals);
    lk_mesh_stats stats = stats_of(&soup);
    assert_int_equal(stats.genus, 0);
    assert_int_equal(stats.boundary_edge_count, 0);
    /* The first vertex of each group keeps its attributes. */
    assert_true(soup.normals[0] == 0.0f);
    lk_error error = {0};
    assert_int_equal(lk_mesh_weld(&soup, -1, NULL, &error), LK_ERR_INVALID);
    lk_mesh_free(&exact);
    lk_mesh_free(&soup);
    lk_mesh_free(&cube);
}

static void test_remove_degenerate_and_unused(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_make_cube(&mesh);
    /* Append: a degenerate, a reversed duplicate of triangle 0, an exact duplicate. */
    mesh.indices = realloc(mesh.indices, 15 * 3 * sizeof(uint32_t));
    uint32_t extra[9] = {1, 1, 2, 0, 1, 2, 0, 2, 1};
    memcpy(mesh.indices + 36, extra, sizeof extra);
    mesh.triangle_count = 15;
    lk_mesh_stats stats = stats_of(&mesh);
    assert_int_equal(stats.degenerate_triangle_count, 1);
    assert_int_equal(stats.duplicate_triangle_count, 2);
    size_t degenerate, duplicate;
    assert_int_equal(lk_mesh_remove_degenerate(&mesh, &degenerate, &duplicate, NULL), LK_OK);
    assert_int_equal(degenerate, 1);
    assert_int_equal(duplicate, 2);
    assert_int_equal(mesh.triangle_count, 12);
    assert_int_equal(stats_of(&mesh).genus, 0);

    /* Unused vertices: add two that no triangle references. */
    mesh.positions = realloc(mesh.positions, 10 * 3 * sizeof(float));
    memmove(mesh.positions + 6, mesh.positions, 8 * 3 * sizeof(float));
    for (size_t c = 0; c < 36; c++) mesh.indices[c] += 2;
    mesh.vertex_count = 10;
    size_t removed;
    assert_int_equal(lk_mesh_remove_unused_vertices(&mesh, &removed, NULL), LK_OK);
    assert_int_equal(removed, 2);
    assert_int_equal(mesh.vertex_count, 8);
    assert_true(fabs(lk_mesh_area(&mesh) - 6.0) < 1e-9);
    lk_mesh_free(&mesh);
}

static void test_components(void **state)
{
    (void)state;
    lk_mesh a, b;
    lk_test_make_cube(&a);
    lk_test_make_torus(&b, 6, 5);
    /* Concatenate cube + torus + cube. */
    lk_mesh mesh;
    size_t v = a.vertex_count * 2 + b.vertex_count, t = a.triangle_count * 2 + b.triangle_count;
    assert_int_equal(lk_mesh_alloc(&mesh, v, t, 0, NULL), LK_OK);
    const lk_mesh *parts[3] = {&a, &b, &a};
    size_t vo = 0, to = 0;
    for (int p = 0; p < 3; p++) {
        memcpy(mesh.positions + 3 * vo, parts[p]->positions, parts[p]->vertex_count * 3 * sizeof(float));
        for (size_t c = 0; c < 3 * parts[p]->triangle_count; c++)
            mesh.indices[3 * to + c] = parts[p]->indices[c] + (uint32_t)vo;
        vo += parts[p]->vertex_count;
        to += parts[p]->triangle_count;
    }
    uint32_t *component = malloc(t * sizeof *component);
    size_t count;
    assert_int_equal(lk_mesh_components(&mesh, component, &count, NULL), LK_OK);
    assert_int_equal(count, 3);
    assert_int_equal(component[0], 0);
    assert_int_equal(component[12], 1);
    assert_int_equal(component[t - 1], 2);
    lk_mesh_stats stats = stats_of(&mesh);
    assert_int_equal(stats.component_count, 3);
    assert_int_equal(stats.genus, 1); /* 0 + 1 + 0 */
    free(component);
    lk_mesh_free(&mesh);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
}

static void test_validate(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_make_cube(&mesh);
    lk_error error = {0};
    assert_int_equal(lk_mesh_validate(&mesh, &error), LK_OK);
    mesh.indices[7] = 8;
    assert_int_equal(lk_mesh_validate(&mesh, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "triangle 2");
    mesh.indices[7] = 3;
    mesh.positions[4] = NAN;
    assert_int_equal(lk_mesh_validate(&mesh, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "vertex 1");
    lk_mesh_free(&mesh);
}

/* The real models: counts and topology that later algorithms rely on. */
static void test_real_models(void **state)
{
    (void)state;
    struct {
        const char *name;
        size_t vertices, triangles;
        long long genus;
        size_t boundary, components, duplicate_positions;
    } expected[] = {
        {"bunny.obj", 34835, 69666, 0, 0, 1, 0},
        {"cow.off", 2904, 5804, 0, 0, 1, 1},
        {"fandisk.off", 6475, 12946, 0, 0, 1, 0},
        {"triceratops.off", 2832, 5660, 0, 0, 1, 0},
    };
    for (size_t i = 0; i < sizeof expected / sizeof expected[0]; i++) {
        lk_mesh mesh;
        lk_test_load(lk_test_sample(expected[i].name), &mesh);
        lk_mesh_stats stats = stats_of(&mesh);
        print_message(
            "%-16s V=%zu T=%zu E=%zu boundary=%zu nm-edges=%zu nm-vertices=%zu comp=%zu chi=%lld genus=%lld\n",
            expected[i].name, stats.vertex_count, stats.triangle_count, stats.edge_count, stats.boundary_edge_count,
            stats.nonmanifold_edge_count, stats.nonmanifold_vertex_count, stats.component_count,
            stats.euler_characteristic, stats.genus);
        assert_int_equal(stats.vertex_count, expected[i].vertices);
        assert_int_equal(stats.triangle_count, expected[i].triangles);
        assert_int_equal(stats.genus, expected[i].genus);
        assert_int_equal(stats.boundary_edge_count, expected[i].boundary);
        assert_int_equal(stats.component_count, expected[i].components);
        assert_int_equal(stats.nonmanifold_edge_count, 0);
        /* Exact welding only removes vertices that share a position. */
        size_t merged, vertex_count = mesh.vertex_count;
        assert_int_equal(lk_mesh_weld(&mesh, 0.0, &merged, NULL), LK_OK);
        assert_int_equal(mesh.vertex_count, vertex_count - merged);
        assert_int_equal(mesh.triangle_count, expected[i].triangles);
        print_message("%-16s %zu vertices share a position with an earlier one\n", expected[i].name, merged);
        assert_int_equal(merged, expected[i].duplicate_positions);
        lk_mesh_free(&mesh);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cube_topology), cmocka_unit_test(test_torus_and_grid),
        cmocka_unit_test(test_nonmanifold),   cmocka_unit_test(test_edge_adjacency),
        cmocka_unit_test(test_weld),          cmocka_unit_test(test_remove_degenerate_and_unused),
        cmocka_unit_test(test_components),    cmocka_unit_test(test_validate),
        cmocka_unit_test(test_real_models),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
