/* SPDX-License-Identifier: MIT */
/* Subdivision: midpoint and Loop schemes on the sample models and on
 * hand-made shapes with known answers (counts, topology, area, Loop masks,
 * borders, orientation, attributes, limits, distance to the input). */
#include <math.h>
#include <stdio.h>
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

static void subdivide(const lk_mesh *mesh, lk_subdivide_scheme scheme, unsigned iterations, lk_mesh *out)
{
    lk_error error = {0};
    if (lk_subdivide(mesh, scheme, iterations, out, &error) != LK_OK) fail_msg("subdivide: %s", error.message);
}

/* Unit octahedron, outward-facing. */
static void make_octahedron(lk_mesh *mesh)
{
    static const float positions[18] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
    static const uint32_t indices[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
    lk_test_make_mesh(mesh, positions, 6, indices, 8);
}

/* V' = V + E and T' = 4T per iteration; a closed genus-0 manifold stays one. */
static void check_counts(const char *name)
{
    lk_mesh mesh, once, twice;
    lk_test_load(lk_test_sample(name), &mesh);
    lk_mesh_stats input = stats_of(&mesh);
    assert_int_equal(input.genus, 0);
    assert_int_equal(input.boundary_edge_count, 0);
    for (int scheme = LK_SUBDIVIDE_LOOP; scheme <= LK_SUBDIVIDE_MIDPOINT; scheme++) {
        subdivide(&mesh, (lk_subdivide_scheme)scheme, 1, &once);
        lk_mesh_stats first = stats_of(&once);
        assert_int_equal(once.vertex_count, input.vertex_count + input.edge_count);
        assert_int_equal(once.triangle_count, 4 * input.triangle_count);
        assert_int_equal(first.edge_count, 2 * input.edge_count + 3 * input.triangle_count);
        subdivide(&mesh, (lk_subdivide_scheme)scheme, 2, &twice);
        lk_mesh_stats second = stats_of(&twice);
        assert_int_equal(twice.vertex_count, once.vertex_count + first.edge_count);
        assert_int_equal(twice.triangle_count, 16 * input.triangle_count);
        assert_int_equal(second.boundary_edge_count, 0);
        assert_int_equal(second.nonmanifold_edge_count, 0);
        assert_int_equal(second.nonmanifold_vertex_count, 0);
        assert_int_equal(second.degenerate_triangle_count, 0);
        assert_int_equal(second.duplicate_triangle_count, 0);
        assert_int_equal(second.component_count, 1);
        assert_int_equal(second.euler_characteristic, 2);
        assert_int_equal(second.genus, 0);
        lk_mesh_free(&once);
        lk_mesh_free(&twice);
    }
    lk_mesh_free(&mesh);
}

static void test_counts_bunny(void **state)
{
    (void)state;
    check_counts("bunny.obj"); /* 34,835 v / 69,666 t -> 557,330 v / 1,114,656 t */
    lk_mesh mesh, out;
    lk_test_load(lk_test_sample("bunny.obj"), &mesh);
    subdivide(&mesh, LK_SUBDIVIDE_LOOP, 2, &out);
    assert_int_equal(out.vertex_count, 557330);
    assert_int_equal(out.triangle_count, 1114656);
    lk_mesh_free(&out);
    lk_mesh_free(&mesh);
}

static void test_counts_cow(void **state)
{
    (void)state;
    check_counts("cow.off");
}

/* Genus and Euler characteristic survive on a torus, under both schemes. */
static void test_torus_genus(void **state)
{
    (void)state;
    lk_mesh torus, out;
    lk_test_make_torus(&torus, 12, 8);
    for (int scheme = LK_SUBDIVIDE_LOOP; scheme <= LK_SUBDIVIDE_MIDPOINT; scheme++) {
        subdivide(&torus, (lk_subdivide_scheme)scheme, 3, &out);
        lk_mesh_stats stats = stats_of(&out);
        assert_int_equal(stats.triangle_count, 64 * torus.triangle_count);
        assert_int_equal(stats.euler_characteristic, 0);
        assert_int_equal(stats.genus, 1);
        assert_int_equal(stats.boundary_edge_count, 0);
        assert_int_equal(stats.nonmanifold_vertex_count, 0);
        assert_int_equal(stats.component_count, 1);
        lk_mesh_free(&out);
    }
    lk_mesh_free(&torus);
}

/* Midpoint subdivision does not move the surface: same area, and every odd
 * vertex is the average of its edge's endpoints. */
static void test_midpoint_area(void **state)
{
    (void)state;
    lk_mesh cube, out;
    lk_test_make_cube(&cube);
    subdivide(&cube, LK_SUBDIVIDE_MIDPOINT, 3, &out);
    assert_true(fabs(lk_mesh_area(&out) - 6.0) < 6.0 * 1e-9);
    float lo[3], hi[3];
    lk_mesh_bounds(&out, lo, hi);
    for (int k = 0; k < 3; k++) assert_true(lo[k] == 0.0f && hi[k] == 1.0f);
    lk_mesh_free(&out);
    lk_mesh_free(&cube);

    lk_mesh grid;
    lk_test_make_grid(&grid, 5);
    subdivide(&grid, LK_SUBDIVIDE_MIDPOINT, 2, &out);
    assert_true(fabs(lk_mesh_area(&out) - 25.0) < 25.0 * 1e-9);
    lk_mesh_free(&out);
    lk_mesh_free(&grid);

    /* The bunny's midpoints are rounded to float, yet the area still matches
     * to 1e-9 (measured 3.8e-10 for one iteration). */
    lk_mesh bunny;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    double area = lk_mesh_area(&bunny);
    subdivide(&bunny, LK_SUBDIVIDE_MIDPOINT, 1, &out);
    double relative = fabs(lk_mesh_area(&out) - area) / area;
    print_message("bunny midpoint area relative change: %.3g\n", relative);
    assert_true(relative < 1e-9);
    lk_edge_adjacency edges;
    assert_int_equal(lk_edge_adjacency_build(&bunny, &edges, NULL), LK_OK);
    assert_int_equal(out.vertex_count, bunny.vertex_count + edges.edge_count);
    for (size_t e = 0; e < edges.edge_count; e++) {
        const float *a = bunny.positions + 3 * (size_t)edges.vertices[2 * e];
        const float *b = bunny.positions + 3 * (size_t)edges.vertices[2 * e + 1];
        const float *m = out.positions + 3 * (bunny.vertex_count + e);
        for (int k = 0; k < 3; k++) assert_true(m[k] == (float)(0.5 * ((double)a[k] + b[k])));
    }
    assert_memory_equal(out.positions, bunny.positions, bunny.vertex_count * 3 * sizeof(float));
    lk_edge_adjacency_free(&edges);
    lk_mesh_free(&out);
    lk_mesh_free(&bunny);
}

/* Loop's masks with Loop's original beta on the octahedron (valence 4:
 * beta = 31/256): the even vertex (1,0,0) moves to 1 - 4 beta = 0.515625
 * (Warren's beta = 3/32 would give 0.625), and the odd vertex of edge
 * (1,0,0)-(0,1,0) is 3/8 (a + b) + 1/8 (c + d) = (0.375, 0.375, 0). */
static void test_loop_masks(void **state)
{
    (void)state;
    lk_mesh octahedron, out;
    make_octahedron(&octahedron);
    subdivide(&octahedron, LK_SUBDIVIDE_LOOP, 1, &out);
    assert_int_equal(out.vertex_count, 6 + 12);
    assert_true(out.positions[0] == 0.515625f && out.positions[1] == 0.0f && out.positions[2] == 0.0f);
    lk_edge_adjacency edges;
    assert_int_equal(lk_edge_adjacency_build(&octahedron, &edges, NULL), LK_OK);
    size_t found = 0;
    for (size_t e = 0; e < edges.edge_count; e++) {
        if (edges.vertices[2 * e] == 0 && edges.vertices[2 * e + 1] == 2) {
            const float *m = out.positions + 3 * (6 + e);
            assert_true(m[0] == 0.375f && m[1] == 0.375f && m[2] == 0.0f);
            found++;
        }
    }
    assert_int_equal(found, 1);
    lk_edge_adjacency_free(&edges);
    lk_mesh_free(&out);
    lk_mesh_free(&octahedron);
}

/* Distance from the vertex centroid: (max - min) / max. */
static double radial_spread(const lk_mesh *mesh)
{
    double centre[3] = {0, 0, 0};
    for (size_t v = 0; v < mesh->vertex_count; v++)
        for (int k = 0; k < 3; k++) centre[k] += mesh->positions[3 * v + k] / (double)mesh->vertex_count;
    double lo = INFINITY, hi = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += pow(mesh->positions[3 * v + k] - centre[k], 2);
        lo = fmin(lo, sqrt(d2)), hi = fmax(hi, sqrt(d2));
    }
    return (hi - lo) / hi;
}

/* Four Loop iterations round the octahedron off: the spread of distances
 * to the centroid, over the vertices of four midpoint iterations (the
 * octahedron itself, sampled), is about 0.4 (1 at the tips, near 1/sqrt 3 at
 * face centres); after four Loop iterations it is a measured 0.0629 (bound 0.08). The
 * surface also shrinks strictly inside the input. */
static void test_loop_smooths_octahedron(void **state)
{
    (void)state;
    lk_mesh octahedron, out;
    make_octahedron(&octahedron);
    subdivide(&octahedron, LK_SUBDIVIDE_MIDPOINT, 4, &out);
    double before = radial_spread(&out);
    lk_mesh_free(&out);
    subdivide(&octahedron, LK_SUBDIVIDE_LOOP, 4, &out);
    double after = radial_spread(&out);
    print_message("octahedron radial spread: %.4f (midpoint) -> %.4f (Loop), 4 iterations\n", before, after);
    assert_true(before > 0.4 && before < 1 - 1 / sqrt(3.0));
    assert_true(after < 0.08);
    float lo[3], hi[3];
    lk_mesh_bounds(&out, lo, hi);
    for (int k = 0; k < 3; k++) assert_true(lo[k] > -1.0f && hi[k] < 1.0f);
    lk_mesh_free(&out);
    lk_mesh_free(&octahedron);
}

/* Loop on the bunny: every position stays in the input's bounding box and
 * the surface stays close (Hausdorff measured with lk_metro). */
static void test_loop_bunny_distance(void **state)
{
    (void)state;
    lk_mesh bunny, out;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    float lo[3], hi[3];
    lk_mesh_bounds(&bunny, lo, hi);
    subdivide(&bunny, LK_SUBDIVIDE_LOOP, 1, &out);
    for (size_t v = 0; v < out.vertex_count; v++)
        for (int k = 0; k < 3; k++) assert_true(out.positions[3 * v + k] >= lo[k] && out.positions[3 * v + k] <= hi[k]);
    lk_metro_result result;
    lk_error error = {0};
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.sample_count = 200000;
    assert_int_equal(lk_metro(&bunny, &out, &options, &result, NULL, NULL, &error), LK_OK);
    print_message("bunny vs Loop(bunny): Hausdorff %.6g (%.4f%% of diagonal %.4g), rms %.3g / %.3g\n", result.hausdorff,
                  100 * result.hausdorff / result.diagonal, result.diagonal, result.forward.rms, result.backward.rms);
    assert_true(result.hausdorff > 0);
    /* Measured 0.00828 (0.26% of the 3.214 diagonal); bound 25% above. */
    assert_true(result.hausdorff < 0.0104);
    lk_mesh_free(&out);
    lk_mesh_free(&bunny);
}

/* Loop with a border: a flat grid stays flat (z = 0 exactly), its border
 * stays on the square (corners are kept, straight borders follow the
 * 1/8 3/4 1/8 rule which keeps them on their line), interior vertices move. */
static void test_loop_border(void **state)
{
    (void)state;
    const uint32_t n = 6;
    lk_mesh grid, out;
    lk_test_make_grid(&grid, n);
    subdivide(&grid, LK_SUBDIVIDE_LOOP, 3, &out);
    lk_mesh_stats stats = stats_of(&out);
    assert_int_equal(stats.boundary_loop_count, 1);
    assert_int_equal(stats.boundary_edge_count, 8 * 4 * n);
    assert_int_equal(stats.genus, 0);
    assert_true(fabs(stats.area - (double)n * n) < 1e-9 * n * n); /* flat, border on the square */
    for (size_t v = 0; v < out.vertex_count; v++) {
        const float *p = out.positions + 3 * v;
        assert_true(p[2] == 0.0f);
        assert_true(p[0] >= 0.0f && p[0] <= (float)n && p[1] >= 0.0f && p[1] <= (float)n);
    }
    /* Every border vertex lies on a side of the square. */
    lk_edge_adjacency edges;
    assert_int_equal(lk_edge_adjacency_build(&out, &edges, NULL), LK_OK);
    size_t border_vertices = 0;
    for (size_t e = 0; e < edges.edge_count; e++) {
        if (edges.offsets[e + 1] - edges.offsets[e] != 1) continue;
        for (int side = 0; side < 2; side++) {
            const float *p = out.positions + 3 * (size_t)edges.vertices[2 * e + side];
            assert_true(p[0] == 0.0f || p[0] == (float)n || p[1] == 0.0f || p[1] == (float)n);
            border_vertices++;
        }
    }
    assert_int_equal(border_vertices, 2 * 8 * 4 * n);
    lk_edge_adjacency_free(&edges);
    /* The corners stay; a centre vertex is smoothed but the flat regular grid
     * is reproduced (Loop reproduces linear functions). */
    assert_true(out.positions[0] == 0.0f && out.positions[1] == 0.0f);
    lk_mesh_free(&out);

    /* A bumped grid: the interior moves but the border still stays put. */
    grid.positions[3 * ((n / 2) * (n + 1) + n / 2) + 2] = 1.0f;
    subdivide(&grid, LK_SUBDIVIDE_LOOP, 1, &out);
    float bump = out.positions[3 * ((n / 2) * (n + 1) + n / 2) + 2];
    assert_true(bump > 0.0f && bump < 1.0f); /* 1 - 6 beta(6) = 5/8 */
    assert_true(bump == 0.625f);
    lk_mesh_free(&out);
    lk_mesh_free(&grid);

    /* A curved border follows Loop's crease rule 1/8 3/4 1/8: on a flat
     * regular 12-gon fan (the border turns by 30 degrees, not a corner) the
     * old border vertices move to radius 3/4 + cos(30 deg)/4 and the new
     * ones sit at the midpoints (radius cos 15 deg). */
    lk_mesh disk;
    assert_int_equal(lk_mesh_alloc(&disk, 13, 12, 0, NULL), LK_OK);
    memset(disk.positions, 0, 3 * sizeof(float));
    for (uint32_t i = 0; i < 12; i++) {
        disk.positions[3 * (i + 1)] = (float)cos(i * 3.14159265358979 / 6);
        disk.positions[3 * (i + 1) + 1] = (float)sin(i * 3.14159265358979 / 6);
        disk.positions[3 * (i + 1) + 2] = 0;
        disk.indices[3 * i] = 0, disk.indices[3 * i + 1] = i + 1, disk.indices[3 * i + 2] = (i + 1) % 12 + 1;
    }
    subdivide(&disk, LK_SUBDIVIDE_LOOP, 1, &out);
    assert_int_equal(out.vertex_count, 13 + 24);
    lk_edge_adjacency disk_edges;
    assert_int_equal(lk_edge_adjacency_build(&disk, &disk_edges, NULL), LK_OK);
    for (uint32_t v = 0; v < out.vertex_count; v++) {
        const float *p = out.positions + 3 * v;
        double radius = hypot(p[0], p[1]);
        assert_true(p[2] == 0.0f);
        if (v == 0) {
            assert_true(radius < 1e-7);
        } else if (v <= 12) {
            assert_true(fabs(radius - (0.75 + 0.25 * cos(3.14159265358979 / 6))) < 1e-6);
        } else if (disk_edges.offsets[v - 12] - disk_edges.offsets[v - 13] == 1) {
            assert_true(fabs(radius - cos(3.14159265358979 / 12)) < 1e-6); /* border midpoint */
        }
    }
    lk_edge_adjacency_free(&disk_edges);
    lk_mesh_free(&out);
    lk_mesh_free(&disk);

    /* The Chinese dragon has two holes: they stay two border loops. */
    lk_mesh dragon;
    lk_test_load(lk_test_sample("ChineseDragon-10kv.off"), &dragon);
    lk_mesh_stats before = stats_of(&dragon);
    subdivide(&dragon, LK_SUBDIVIDE_LOOP, 2, &out);
    stats = stats_of(&out);
    assert_int_equal(stats.boundary_loop_count, before.boundary_loop_count);
    assert_int_equal(stats.boundary_edge_count, 4 * before.boundary_edge_count);
    assert_int_equal(stats.genus, before.genus);
    assert_int_equal(stats.nonmanifold_vertex_count, 0);
    lk_mesh_free(&out);
    lk_mesh_free(&dragon);
}

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Counts directed edges (a,b) whose reverse (b,a) is used exactly once and
 * that are themselves used once; returns the number of interior edges
 * consistently oriented, or 0 if some edge is used twice in one direction. */
static size_t consistent_interior_edges(const lk_mesh *mesh)
{
    size_t corner_count = 3 * mesh->triangle_count, consistent = 0;
    uint64_t *keys = malloc(corner_count * sizeof *keys);
    assert_non_null(keys);
    for (size_t c = 0; c < corner_count; c++) {
        uint64_t a = mesh->indices[c], b = mesh->indices[c - c % 3 + (c % 3 + 1) % 3];
        keys[c] = (a << 32) | b;
    }
    qsort(keys, corner_count, sizeof *keys, compare_u64);
    for (size_t c = 0; c < corner_count; c++) {
        if (c && keys[c] == keys[c - 1]) {
            free(keys);
            return 0;
        }
        uint64_t reverse = (keys[c] << 32) | (keys[c] >> 32);
        if (bsearch(&reverse, keys, corner_count, sizeof *keys, compare_u64)) consistent++;
    }
    free(keys);
    return consistent / 2;
}

/* Orientation: the children keep the parent's winding, so every interior
 * edge is used once in each direction, as in the input. */
static void test_orientation(void **state)
{
    (void)state;
    lk_mesh bunny, out;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_mesh_stats input = stats_of(&bunny);
    assert_int_equal(consistent_interior_edges(&bunny), input.edge_count);
    for (int scheme = LK_SUBDIVIDE_LOOP; scheme <= LK_SUBDIVIDE_MIDPOINT; scheme++) {
        subdivide(&bunny, (lk_subdivide_scheme)scheme, 1, &out);
        assert_int_equal(consistent_interior_edges(&out), 2 * input.edge_count + 3 * input.triangle_count);
        lk_mesh_free(&out);
    }
    lk_mesh_free(&bunny);

    /* Open grid: interior edges consistent; outward normals still +z. */
    lk_mesh grid;
    lk_test_make_grid(&grid, 4);
    subdivide(&grid, LK_SUBDIVIDE_MIDPOINT, 2, &out);
    lk_mesh_stats stats = stats_of(&out);
    assert_int_equal(consistent_interior_edges(&out), stats.edge_count - stats.boundary_edge_count);
    for (size_t t = 0; t < out.triangle_count; t++) {
        const float *a = out.positions + 3 * (size_t)out.indices[3 * t];
        const float *b = out.positions + 3 * (size_t)out.indices[3 * t + 1];
        const float *c = out.positions + 3 * (size_t)out.indices[3 * t + 2];
        double cross_z = ((double)b[0] - a[0]) * ((double)c[1] - a[1]) - ((double)b[1] - a[1]) * ((double)c[0] - a[0]);
        assert_true(cross_z > 0);
    }
    lk_mesh_free(&out);
    lk_mesh_free(&grid);
}

/* Attributes are interpolated linearly: an odd vertex gets the average of
 * its edge's endpoints (normals renormalised), even vertices keep theirs;
 * the same under Loop. */
static void test_attributes(void **state)
{
    (void)state;
    lk_mesh quad, out;
    assert_int_equal(lk_mesh_alloc(&quad, 4, 2, LK_ATTR_NORMALS | LK_ATTR_TEXCOORDS | LK_ATTR_COLORS, NULL), LK_OK);
    static const float positions[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    static const float normals[12] = {0, 0, 1, 1, 0, 0, 0, 1, 0, 0, 0, 2};
    static const float texcoords[8] = {0, 0, 1, 0, 1, 1, 0, 1};
    static const float colors[16] = {1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1, 0.5f, 1, 1, 1, 0};
    static const uint32_t indices[6] = {0, 1, 2, 0, 2, 3};
    memcpy(quad.positions, positions, sizeof positions);
    memcpy(quad.normals, normals, sizeof normals);
    memcpy(quad.texcoords, texcoords, sizeof texcoords);
    memcpy(quad.colors, colors, sizeof colors);
    memcpy(quad.indices, indices, sizeof indices);
    lk_edge_adjacency edges;
    assert_int_equal(lk_edge_adjacency_build(&quad, &edges, NULL), LK_OK);
    assert_int_equal(edges.edge_count, 5);
    for (int scheme = LK_SUBDIVIDE_LOOP; scheme <= LK_SUBDIVIDE_MIDPOINT; scheme++) {
        subdivide(&quad, (lk_subdivide_scheme)scheme, 1, &out);
        assert_int_equal(out.vertex_count, 9);
        assert_non_null(out.normals);
        assert_non_null(out.texcoords);
        assert_non_null(out.colors);
        assert_memory_equal(out.normals, normals, sizeof normals);
        assert_memory_equal(out.texcoords, texcoords, sizeof texcoords);
        assert_memory_equal(out.colors, colors, sizeof colors);
        for (size_t e = 0; e < edges.edge_count; e++) {
            uint32_t a = edges.vertices[2 * e], b = edges.vertices[2 * e + 1];
            size_t m = 4 + e;
            for (int k = 0; k < 2; k++)
                assert_true(out.texcoords[2 * m + k] == 0.5f * (texcoords[2 * a + k] + texcoords[2 * b + k]));
            for (int k = 0; k < 4; k++)
                assert_true(out.colors[4 * m + k] == 0.5f * (colors[4 * a + k] + colors[4 * b + k]));
            double sum[3], length = 0;
            for (int k = 0; k < 3; k++) {
                sum[k] = (double)normals[3 * a + k] + normals[3 * b + k];
                length += sum[k] * sum[k];
            }
            for (int k = 0; k < 3; k++) assert_true(fabs(out.normals[3 * m + k] - sum[k] / sqrt(length)) < 1e-6);
        }
        /* The diagonal (0,2) midpoint: texcoord (0.5, 0.5), normal (0,1,1)/sqrt 2. */
        for (size_t e = 0; e < edges.edge_count; e++)
            if (edges.vertices[2 * e] == 0 && edges.vertices[2 * e + 1] == 2) {
                assert_true(out.texcoords[2 * (4 + e)] == 0.5f && out.texcoords[2 * (4 + e) + 1] == 0.5f);
                assert_true(fabs(out.normals[3 * (4 + e) + 1] - 1 / sqrt(2.0)) < 1e-6);
            }
        lk_mesh_free(&out);
    }
    lk_edge_adjacency_free(&edges);
    lk_mesh_free(&quad);
}

/* Zero iterations give an exact copy (own arrays, same contents). */
static void test_zero_iterations(void **state)
{
    (void)state;
    lk_mesh cow, out;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    for (int scheme = LK_SUBDIVIDE_LOOP; scheme <= LK_SUBDIVIDE_MIDPOINT; scheme++) {
        subdivide(&cow, (lk_subdivide_scheme)scheme, 0, &out);
        assert_int_equal(out.vertex_count, cow.vertex_count);
        assert_int_equal(out.triangle_count, cow.triangle_count);
        assert_true(out.positions != cow.positions && out.indices != cow.indices);
        assert_memory_equal(out.positions, cow.positions, cow.vertex_count * 3 * sizeof(float));
        assert_memory_equal(out.indices, cow.indices, cow.triangle_count * 3 * sizeof(uint32_t));
        assert_null(out.normals);
        lk_mesh_free(&out);
    }
    lk_mesh_free(&cow);
}

/* Sizes beyond LK_MAX_ELEMENTS are refused up front (no allocation: the
 * call returns at once and leaves `out` untouched). */
static void test_limits(void **state)
{
    (void)state;
    lk_mesh bunny, out;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    memset(&out, 0xAB, sizeof out);
    lk_error error = {0};
    assert_int_equal(lk_subdivide(&bunny, LK_SUBDIVIDE_LOOP, 20, &out, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error, "20 iterations");
    assert_int_equal(out.vertex_count, (size_t)0xABABABABABABABABull);
    lk_error_clear(&error);
    assert_int_equal(lk_subdivide(&bunny, LK_SUBDIVIDE_MIDPOINT, 0xFFFFFFFFu, &out, &error), LK_ERR_LIMIT);
    /* The first count that does not fit: 69,666 * 4^8 = 4.57e9 > 2^32 - 16. */
    lk_error_clear(&error);
    assert_int_equal(lk_subdivide(&bunny, LK_SUBDIVIDE_MIDPOINT, 8, &out, &error), LK_ERR_LIMIT);
    lk_mesh_free(&bunny);

    /* A point set has nothing to split: it comes back unchanged. */
    lk_mesh points;
    assert_int_equal(lk_mesh_alloc(&points, 3, 0, 0, NULL), LK_OK);
    for (int i = 0; i < 9; i++) points.positions[i] = (float)i;
    subdivide(&points, LK_SUBDIVIDE_LOOP, 1000, &out);
    assert_int_equal(out.vertex_count, 3);
    assert_int_equal(out.triangle_count, 0);
    assert_memory_equal(out.positions, points.positions, 9 * sizeof(float));
    lk_mesh_free(&out);
    lk_mesh_free(&points);
}

/* Invalid input: degenerate triangles, bad indices and schemes are refused;
 * non-manifold edges keep midpoints and their vertices stay put. */
static void test_invalid_and_nonmanifold(void **state)
{
    (void)state;
    static const float positions[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1};
    static const uint32_t degenerate[9] = {0, 1, 2, 1, 3, 1, 0, 1, 4};
    lk_mesh mesh, out;
    lk_error error = {0};
    lk_test_make_mesh(&mesh, positions, 5, degenerate, 3);
    assert_int_equal(lk_subdivide(&mesh, LK_SUBDIVIDE_LOOP, 1, &out, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "triangle 1 is degenerate");
    mesh.indices[5] = 7;
    lk_error_clear(&error);
    assert_int_equal(lk_subdivide(&mesh, LK_SUBDIVIDE_LOOP, 1, &out, &error), LK_ERR_RANGE);
    mesh.indices[5] = 0; /* fin: three triangles on edge (0,1) */
    lk_error_clear(&error);
    assert_int_equal(lk_subdivide(&mesh, (lk_subdivide_scheme)7, 1, &out, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "scheme");

    subdivide(&mesh, LK_SUBDIVIDE_LOOP, 1, &out);
    lk_mesh_stats stats = stats_of(&out);
    assert_int_equal(stats.nonmanifold_edge_count, 2);                /* (0,m) and (m,1) */
    assert_memory_equal(out.positions, positions, 6 * sizeof(float)); /* vertices 0 and 1 kept */
    lk_edge_adjacency edges;
    assert_int_equal(lk_edge_adjacency_build(&mesh, &edges, NULL), LK_OK);
    assert_int_equal(edges.vertices[0], 0);
    assert_int_equal(edges.vertices[1], 1);
    const float *m = out.positions + 3 * 5; /* edge 0 = (0,1) */
    assert_true(m[0] == 0.5f && m[1] == 0.0f && m[2] == 0.0f);
    lk_edge_adjacency_free(&edges);
    lk_mesh_free(&out);
    lk_mesh_free(&mesh);

    /* Two tetrahedra sharing edge (0,1): four triangles on it, no border.
     * Vertices 0 and 1 keep their positions, other vertices are smoothed. */
    static const float pair_positions[18] = {0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1, 0};
    static const uint32_t pair_indices[24] = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2, 0, 1, 4, 0, 4, 5, 0, 5, 1, 1, 5, 4};
    lk_test_make_mesh(&mesh, pair_positions, 6, pair_indices, 8);
    stats = stats_of(&mesh);
    assert_int_equal(stats.nonmanifold_edge_count, 1);
    assert_int_equal(stats.boundary_edge_count, 0);
    subdivide(&mesh, LK_SUBDIVIDE_LOOP, 1, &out);
    assert_memory_equal(out.positions, pair_positions, 6 * sizeof(float));
    assert_true(memcmp(out.positions + 6, pair_positions + 6, 3 * sizeof(float)) != 0);
    lk_mesh_free(&out);
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_counts_bunny),
        cmocka_unit_test(test_counts_cow),
        cmocka_unit_test(test_torus_genus),
        cmocka_unit_test(test_midpoint_area),
        cmocka_unit_test(test_loop_masks),
        cmocka_unit_test(test_loop_smooths_octahedron),
        cmocka_unit_test(test_loop_bunny_distance),
        cmocka_unit_test(test_loop_border),
        cmocka_unit_test(test_orientation),
        cmocka_unit_test(test_attributes),
        cmocka_unit_test(test_zero_iterations),
        cmocka_unit_test(test_limits),
        cmocka_unit_test(test_invalid_and_nonmanifold),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
