/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: subdivision (src/subdivide.c) on procedural
 * shapes. Loop on an icosahedron: exact counts per iteration, a closed
 * genus-0 surface, and the 12 original vertices converging to the limit
 * position given by Loop's limit mask at the rate of the subdivision
 * matrix's eigenvalue 5/8 - n beta; a torus keeps genus 1; an open plane
 * keeps its corners, outline and area (border rules); midpoint
 * subdivision keeps every position and the area. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

static void subdivide_ok(const lk_mesh *mesh, lk_subdivide_scheme scheme, unsigned iterations, lk_mesh *out)
{
    lk_error error = {0};
    lk_mesh_init(out);
    if (lk_subdivide(mesh, scheme, iterations, out, &error) != LK_OK) fail_msg("subdivide: %s", error.message);
}

/* Loop's weight for valence n (his original choice, as documented). */
static double loop_beta(double n)
{
    double c = 3.0 / 8 + cos(2 * SHAPE_PI / n) / 4;
    return (5.0 / 8 - c * c) / n;
}

/* An icosahedron (all valences 5) through 1..6 Loop steps: V = 10 4^k + 2,
 * T = 20 4^k, E = 30 4^k, genus 0, outward; the volume shrinks towards the
 * limit surface. An original vertex v (unit radius, 5 neighbours at dot
 * 1/sqrt(5)) has the limit chi-weighted average (1 - 5 chi) v + chi sum w
 * with chi = 1 / (n + 3 / (8 beta)): radius 0.707809. The distance to it
 * shrinks by 5/8 - 5 beta = 0.2045 per step (measured 0.292, 0.0598,
 * 0.0122, ... 2.1e-5 at 6 steps; ratios 0.2045 to 0.205), bounded by 0.21;
 * a wrong beta (Warren's 3 / (8 n), tried in subdivide.c) changes both
 * the limit and the rate, and fails here. */
static void test_loop_on_an_icosahedron(void **state)
{
    (void)state;
    lk_mesh icosahedron;
    shape_icosphere(&icosahedron, 1, 0);
    double beta = loop_beta(5), chi = 1 / (5 + 3 / (8 * beta));
    double limit = 1 - 5 * chi + chi * 5 / sqrt(5.0), rate = 5.0 / 8 - 5 * beta;
    print_message("Loop limit radius of the icosahedron's corners %.6f, rate %.4f\n", limit, rate);
    double previous_error = 1 - limit, previous_volume = shape_volume(&icosahedron), previous_change = INFINITY;
    for (unsigned k = 1; k <= 6; k++) {
        lk_mesh out;
        subdivide_ok(&icosahedron, LK_SUBDIVIDE_LOOP, k, &out);
        size_t scale = (size_t)1 << (2 * k);
        assert_int_equal(out.vertex_count, 10 * scale + 2);
        assert_int_equal(out.triangle_count, 20 * scale);
        lk_mesh_stats s = shape_stats(&out);
        assert_int_equal(s.edge_count, 30 * scale);
        assert_int_equal(s.genus, 0);
        assert_int_equal(s.boundary_edge_count + s.nonmanifold_edge_count, 0);
        double error = 0;
        for (size_t v = 0; v < 12; v++) {
            const float *p = out.positions + 3 * v;
            error = fmax(error, fabs(sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]) - limit));
        }
        /* float positions: the last step's error (2e-5) is far above rounding */
        assert_true(error <= 0.21 * previous_error);
        assert_true(error >= 0.19 * previous_error);
        double volume = shape_volume(&out), change = previous_volume - volume;
        assert_true(change > 0 && change < previous_change);
        previous_error = error, previous_volume = volume, previous_change = change;
        lk_mesh_free(&out);
    }
    assert_true(previous_error < 3e-5);
    lk_mesh_free(&icosahedron);
}

/* A torus through two Loop steps stays one closed genus-1 surface with 16
 * times the triangles. */
static void test_loop_keeps_genus(void **state)
{
    (void)state;
    lk_mesh torus, out;
    shape_torus(&torus, 2, 0.5, 12, 6);
    subdivide_ok(&torus, LK_SUBDIVIDE_LOOP, 2, &out);
    assert_int_equal(out.triangle_count, 16 * torus.triangle_count);
    lk_mesh_stats s = shape_stats(&out);
    assert_int_equal(s.genus, 1);
    assert_int_equal(s.component_count, 1);
    assert_int_equal(s.boundary_edge_count, 0);
    assert_true(shape_volume(&out) > 0);
    lk_mesh_free(&out);
    lk_mesh_free(&torus);
}

/* An open 6 x 4 plane: Loop's border rule moves border vertices along the
 * straight border and the 90-degree corners stay, so the plane keeps its
 * outline (border edges double each step), stays flat and keeps its area
 * exactly; the corners are where they were, bit for bit. */
static void test_loop_on_an_open_plane(void **state)
{
    (void)state;
    lk_mesh plane, out;
    shape_plane(&plane, 6, 4, 3, 2);
    subdivide_ok(&plane, LK_SUBDIVIDE_LOOP, 3, &out);
    lk_mesh_stats s = shape_stats(&out);
    assert_int_equal(out.triangle_count, 64 * plane.triangle_count);
    assert_int_equal(s.boundary_edge_count, 8 * 10);
    assert_int_equal(s.boundary_loop_count, 1);
    assert_true(fabs(s.area - 24) < 1e-5);
    assert_true(s.min[0] == 0 && s.min[1] == 0 && s.max[0] == 6 && s.max[1] == 4 && s.min[2] == 0 && s.max[2] == 0);
    const size_t corners[4] = {0, 3, 8, 11};
    for (int i = 0; i < 4; i++)
        assert_memory_equal(out.positions + 3 * corners[i], plane.positions + 3 * corners[i], 3 * sizeof(float));
    lk_mesh_free(&out);
    lk_mesh_free(&plane);
}

/* Midpoint subdivision of a box: the original vertices stay, each new one
 * is the midpoint of its edge (vertex V + e for edge e of
 * lk_edge_adjacency_build), and area and volume are unchanged. */
static void test_midpoint(void **state)
{
    (void)state;
    lk_mesh box, out;
    shape_box(&box, 2, 3, 4, 2);
    subdivide_ok(&box, LK_SUBDIVIDE_MIDPOINT, 1, &out);
    lk_edge_adjacency edges;
    lk_error error = {0};
    assert_int_equal(lk_edge_adjacency_build(&box, &edges, &error), LK_OK);
    assert_int_equal(out.vertex_count, box.vertex_count + edges.edge_count);
    assert_int_equal(out.triangle_count, 4 * box.triangle_count);
    assert_memory_equal(out.positions, box.positions, 3 * box.vertex_count * sizeof(float));
    for (size_t e = 0; e < edges.edge_count; e++) {
        const float *a = box.positions + 3 * edges.vertices[2 * e], *b = box.positions + 3 * edges.vertices[2 * e + 1];
        const float *m = out.positions + 3 * (box.vertex_count + e);
        for (int k = 0; k < 3; k++) assert_true(m[k] == (a[k] + b[k]) / 2);
    }
    lk_edge_adjacency_free(&edges);
    assert_true(fabs(lk_mesh_area(&out) - lk_mesh_area(&box)) < 1e-9);
    assert_true(fabs(shape_volume(&out) - 24) < 1e-9);
    lk_mesh_free(&out);
    lk_mesh_free(&box);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_loop_on_an_icosahedron),
        cmocka_unit_test(test_loop_keeps_genus),
        cmocka_unit_test(test_loop_on_an_open_plane),
        cmocka_unit_test(test_midpoint),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
