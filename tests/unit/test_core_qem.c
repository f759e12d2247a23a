/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: QEM simplification (src/qem.c) on procedural
 * shapes. Targets are reached, topology is kept (genus, components, closed
 * stays closed, borders stay with LK_SIMPLIFY_LOCK_BORDER), flat and sharp
 * shapes simplify without error, and the Metro distance to the input stays
 * under bounds derived from the shape (each bound's measured value and
 * margin are given where it is asserted). The recorded history replays to
 * the output. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h" /* lk__simplify_qem_pool_limit, lk__mesh_clean_view */
#include "shapes.h"

static lk_simplify_options qem_options(double ratio, size_t triangles, unsigned flags)
{
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = ratio;
    options.target_triangles = triangles;
    options.flags = flags;
    return options;
}

static void simplify_ok(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result)
{
    lk_error error = {0};
    if (lk_simplify(mesh, LK_SIMPLIFY_QEM, options, result, NULL, NULL, &error) != LK_OK)
        fail_msg("lk_simplify: %s", error.message);
}

/* Closed 2-manifold with the given genus and parts, nothing degenerate. */
static void assert_closed_manifold(const lk_mesh *mesh, long long genus, size_t components)
{
    lk_mesh_stats s = shape_stats(mesh);
    if (s.boundary_edge_count || s.nonmanifold_edge_count || s.nonmanifold_vertex_count ||
        s.degenerate_triangle_count || s.duplicate_triangle_count || s.genus != genus ||
        s.component_count != components || s.used_vertex_count != s.vertex_count)
        fail_msg("not a closed manifold of genus %lld in %zu parts: border %zu, non-manifold %zu/%zu, degenerate %zu, "
                 "duplicate %zu, genus %lld, parts %zu, unused %zu",
                 genus, components, s.boundary_edge_count, s.nonmanifold_edge_count, s.nonmanifold_vertex_count,
                 s.degenerate_triangle_count, s.duplicate_triangle_count, s.genus, s.component_count,
                 s.vertex_count - s.used_vertex_count);
}

/* The sagitta of a perfect triangulation of the unit sphere with T
 * equilateral triangles: how far a face's centre lies inside the sphere.
 * No T-triangle mesh with vertices on the sphere does much better, so it
 * scales the bounds below. */
static double sphere_sagitta(size_t triangles)
{
    double area = 4 * SHAPE_PI / (double)triangles, side = sqrt(4 * area / sqrt(3.0)), circumradius = side / sqrt(3.0);
    return 1 - sqrt(1 - circumradius * circumradius);
}

/* An icosphere of 5120 triangles to 10%: exactly 512 triangles and 258
 * vertices (closed genus 0: V = T/2 + 2), still a sphere. Measured: Metro
 * Hausdorff 0.354% of the diagonal (1.29 sagittas of a perfect
 * 512-triangle sphere), RMS 0.115%; bounded by 2 sagittas (0.55%) and 0.2%.
 * Placing each merged vertex at an end of its edge instead of the quadric
 * optimum (LK_SIMPLIFY_ENDPOINTS) gives 0.756% and 0.278%, at the edge's
 * midpoint (tried by breaking optimal_point in qem.c) 0.727% and 0.352%:
 * both bounds fail either way. */
static void test_sphere_to_ten_percent(void **state)
{
    (void)state;
    lk_mesh sphere;
    shape_icosphere(&sphere, 1, 4);
    lk_simplify_options options = qem_options(0.1, 0, 0);
    lk_simplify_result result;
    simplify_ok(&sphere, &options, &result);
    assert_true(result.target_reached);
    assert_int_equal(result.mesh.triangle_count, 512);
    assert_int_equal(result.mesh.vertex_count, 258);
    assert_closed_manifold(&result.mesh, 0, 1);
    assert_true(fabs(result.diagonal - 2 * sqrt(3.0)) < 1e-6);

    lk_metro_result metro = shape_metro(&sphere, &result.mesh, 10);
    double hausdorff = metro.hausdorff / metro.diagonal,
           rms = fmax(metro.forward.rms, metro.backward.rms) / metro.diagonal;
    double sagitta = sphere_sagitta(512) / result.diagonal; /* radius 1 */
    print_message("sphere 10%%: Hausdorff %.3f%% (%.2f sagittas), RMS %.3f%%, QEM error %.3f%% of the diagonal\n",
                  100 * hausdorff, hausdorff / sagitta, 100 * rms, 100 * result.error / result.diagonal);
    assert_true(hausdorff < 2 * sagitta);
    assert_true(rms < 0.002);
    /* The QEM error is an RMS plane distance: below the Hausdorff distance,
     * above zero. */
    assert_true(result.error > 0 && result.error <= metro.hausdorff);
    /* Every vertex stays near the sphere (measured 0.0074 of the radius). */
    assert_true(shape_sphere_deviation(&result.mesh, (double[3]){0, 0, 0}, 1) < 2 * sphere_sagitta(512));
    /* Outward: the volume shrinks a little (measured 0.85%), never flips. */
    double volume = shape_volume(&result.mesh), full = shape_volume(&sphere);
    assert_true(volume < full && volume > 0.98 * full);

    /* The vertex map: each output vertex is the image of at least one
     * input vertex; an input vertex's image is where it went. */
    size_t *preimages = calloc(result.mesh.vertex_count, sizeof *preimages);
    assert_non_null(preimages);
    for (size_t v = 0; v < sphere.vertex_count; v++) {
        assert_true(result.vertex_map[v] < result.mesh.vertex_count);
        preimages[result.vertex_map[v]]++;
    }
    for (size_t v = 0; v < result.mesh.vertex_count; v++) assert_true(preimages[v] >= 1);
    free(preimages);
    lk_simplify_result_free(&result);
    lk_mesh_free(&sphere);
}

/* Coarser targets, larger errors: the reported error is a running maximum
 * over the collapses, so it never shrinks as the target falls; the Metro
 * distance grows with it (measured 0.065, 0.136, 0.271, 0.503, 1.10, 1.95%
 * from 50% down to 1.6%) and stays under 2 sagittas of each count (1.3 to
 * 1.5 measured). */
static void test_error_grows_with_reduction(void **state)
{
    (void)state;
    lk_mesh sphere;
    shape_icosphere(&sphere, 1, 4);
    double previous_error = 0, previous_hausdorff = 0;
    for (size_t triangles = 2560; triangles >= 80; triangles /= 2) {
        lk_simplify_options options = qem_options(0, triangles, 0);
        lk_simplify_result result;
        simplify_ok(&sphere, &options, &result);
        assert_int_equal(result.mesh.triangle_count, triangles);
        assert_closed_manifold(&result.mesh, 0, 1);
        lk_metro_result metro = shape_metro(&sphere, &result.mesh, 10);
        assert_true(result.error >= previous_error);
        assert_true(metro.hausdorff > previous_hausdorff);
        assert_true(metro.hausdorff < 2 * sphere_sagitta(triangles));
        previous_error = result.error;
        previous_hausdorff = metro.hausdorff;
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&sphere);
}

/* Genus 1 and two parts survive strong reductions: the torus to 10% and
 * 2%, a torus and a sphere together to 1% (53 triangles left). Measured
 * Hausdorff: torus 10% 1.01% (bound 1.5%), 2% 4.13% (bound 5%). At 81
 * triangles the torus's distance follows the collapse order closely: it
 * was 2.75% with the queue's buckets 1/64 of an octave wide instead of
 * 1/256, while over 26 ratios from 1% to 6% the finer queue's Hausdorff
 * is 11% lower (geometric mean). */
static void test_topology_kept(void **state)
{
    (void)state;
    lk_mesh torus;
    shape_torus(&torus, 2, 0.5, 64, 32);
    const struct {
        double ratio, bound;
    } rows[] = {{0.1, 0.015}, {0.02, 0.05}};
    for (int i = 0; i < 2; i++) {
        lk_simplify_options options = qem_options(rows[i].ratio, 0, 0);
        lk_simplify_result result;
        simplify_ok(&torus, &options, &result);
        assert_true(result.target_reached);
        /* A collapse inside a closed surface removes two triangles: the
         * count lands on the target or one below. */
        size_t target = (size_t)(rows[i].ratio * 4096);
        assert_true(result.mesh.triangle_count <= target && result.mesh.triangle_count + 1 >= target);
        assert_closed_manifold(&result.mesh, 1, 1);
        lk_metro_result metro = shape_metro(&torus, &result.mesh, 10);
        print_message("torus %.0f%%: Hausdorff %.3f%% of the diagonal\n", 100 * rows[i].ratio,
                      100 * metro.hausdorff / metro.diagonal);
        assert_true(metro.hausdorff < rows[i].bound * metro.diagonal);
        lk_simplify_result_free(&result);
    }

    lk_mesh sphere;
    shape_icosphere(&sphere, 1, 3);
    shape_append(&torus, &sphere, 5, 0, 0);
    lk_mesh_free(&sphere);
    lk_simplify_options options = qem_options(0.01, 0, 0);
    lk_simplify_result result;
    simplify_ok(&torus, &options, &result);
    assert_closed_manifold(&result.mesh, 1, 2);
    assert_true(result.target_reached);
    assert_true(result.mesh.triangle_count <= 53 && result.mesh.triangle_count >= 50); /* 1% of 5376 */
    lk_simplify_result_free(&result);

    /* A thin limb (radius 0.1, length 3) to 3%: 48 triangles, still one
     * closed tube; measured Hausdorff 0.69% of the diagonal, bound 1%. */
    lk_mesh capsule;
    shape_capsule(&capsule, 0.1, 3, 16, 40, 6);
    options = qem_options(0.03, 0, 0);
    simplify_ok(&capsule, &options, &result);
    assert_closed_manifold(&result.mesh, 0, 1);
    lk_metro_result metro = shape_metro(&capsule, &result.mesh, 10);
    print_message("capsule 3%%: %zu triangles, Hausdorff %.3f%% of the diagonal\n", result.mesh.triangle_count,
                  100 * metro.hausdorff / metro.diagonal);
    assert_true(metro.hausdorff < 0.01 * metro.diagonal);
    lk_simplify_result_free(&result);
    lk_mesh_free(&capsule);
    lk_mesh_free(&torus);
}

/* Flat faces cost nothing: a box of 768 triangles goes down to its 12 with
 * the 8 corners exactly where they were and no error at all (measured
 * Hausdorff 1e-16 of the diagonal). */
static void test_box_to_twelve_triangles(void **state)
{
    (void)state;
    lk_mesh box;
    shape_box(&box, 2, 3, 4, 8);
    lk_simplify_options options = qem_options(0, 12, 0);
    lk_simplify_result result;
    simplify_ok(&box, &options, &result);
    assert_int_equal(result.mesh.triangle_count, 12);
    assert_int_equal(result.mesh.vertex_count, 8);
    assert_closed_manifold(&result.mesh, 0, 1);
    for (size_t v = 0; v < 8; v++) {
        const float *p = result.mesh.positions + 3 * v;
        assert_true(fabsf(p[0]) == 1 && fabsf(p[1]) == 1.5f && fabsf(p[2]) == 2);
    }
    assert_true(fabs(shape_volume(&result.mesh) - 24) < 1e-9);
    lk_metro_result metro = shape_metro(&box, &result.mesh, 10);
    assert_true(metro.hausdorff < 1e-9 * metro.diagonal);
    assert_true(result.error < 1e-6 * result.diagonal);
    lk_simplify_result_free(&result);
    lk_mesh_free(&box);
}

/* Open shapes: a flat plane keeps its outline and area exactly (border
 * constraint quadrics; measured Hausdorff 0); with LOCK_BORDER every
 * border vertex stays, bit for bit, so the 80 border edges remain and the
 * 5% target cannot be met (target_reached 0, 78 triangles). The open
 * cylinder keeps its two loops. */
static void test_borders(void **state)
{
    (void)state;
    lk_mesh plane;
    shape_plane(&plane, 6, 4, 24, 16);
    lk_simplify_options options = qem_options(0.05, 0, 0);
    lk_simplify_result result;
    simplify_ok(&plane, &options, &result);
    assert_true(result.target_reached);
    lk_mesh_stats s = shape_stats(&result.mesh);
    assert_int_equal(s.boundary_loop_count, 1);
    assert_int_equal(s.genus, 0);
    assert_true(fabs(s.area - 24) < 1e-9);
    /* Border vertices slide along the outline (to rounding: 1e-15). */
    assert_true(fabs(s.min[0]) < 1e-9 && fabs(s.min[1]) < 1e-9 && fabs(s.max[0] - 6) < 1e-9 &&
                fabs(s.max[1] - 4) < 1e-9);
    assert_true(s.min[2] == 0 && s.max[2] == 0);
    lk_simplify_result_free(&result);

    options.flags = LK_SIMPLIFY_LOCK_BORDER;
    simplify_ok(&plane, &options, &result);
    assert_false(result.target_reached);
    s = shape_stats(&result.mesh);
    assert_int_equal(s.boundary_edge_count, 80);
    assert_int_equal(s.boundary_loop_count, 1);
    assert_true(fabs(s.area - 24) < 1e-9);
    for (size_t v = 0; v < plane.vertex_count; v++) {
        const float *p = plane.positions + 3 * v;
        int on_border = p[0] == 0 || p[0] == 6 || p[1] == 0 || p[1] == 4;
        if (!on_border) continue;
        assert_true(result.vertex_map[v] != UINT32_MAX);
        assert_memory_equal(result.mesh.positions + 3 * result.vertex_map[v], p, 3 * sizeof(float));
    }
    lk_simplify_result_free(&result);
    lk_mesh_free(&plane);

    lk_mesh cylinder;
    shape_cylinder(&cylinder, 1, 2, 32, 16);
    for (int lock = 0; lock <= 1; lock++) {
        options = qem_options(0.1, 0, lock ? LK_SIMPLIFY_LOCK_BORDER : 0);
        simplify_ok(&cylinder, &options, &result);
        s = shape_stats(&result.mesh);
        assert_int_equal(s.boundary_loop_count, 2);
        assert_int_equal(s.boundary_edge_count, 64);
        assert_int_equal(s.genus, 0);
        assert_int_equal(s.component_count, 1);
        /* Rows are straight along z: the prism is kept exactly. */
        lk_metro_result metro = shape_metro(&cylinder, &result.mesh, 10);
        assert_true(metro.hausdorff < 1e-6 * metro.diagonal);
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&cylinder);
}

/* max_error stops before any collapse costs more: the reported error stays
 * under the bound (0.1% of the diagonal; 958 triangles left, measured). */
static void test_max_error(void **state)
{
    (void)state;
    lk_mesh sphere;
    shape_icosphere(&sphere, 1, 4);
    lk_simplify_options options = qem_options(0, 0, 0);
    options.max_error = 0.001;
    lk_simplify_result result;
    simplify_ok(&sphere, &options, &result);
    assert_true(result.error <= 0.001 * result.diagonal);
    assert_true(result.mesh.triangle_count > 512 && result.mesh.triangle_count < 2560);
    assert_closed_manifold(&result.mesh, 0, 1);
    lk_simplify_result_free(&result);
    lk_mesh_free(&sphere);
}

/* A rough sphere (radius 1 +- 5%) to 10%: still one closed genus-0
 * surface. Measured Hausdorff 2.72% of the diagonal, under the noise's
 * peak-to-valley 0.1 (2.89% of the diagonal) plus 2 sagittas (0.55%). */
static void test_noisy_sphere(void **state)
{
    (void)state;
    lk_mesh noisy;
    shape_noisy_sphere(&noisy, 1, 4, 0.05, 3);
    lk_simplify_options options = qem_options(0.1, 0, 0);
    lk_simplify_result result;
    simplify_ok(&noisy, &options, &result);
    assert_int_equal(result.mesh.triangle_count, 512);
    assert_closed_manifold(&result.mesh, 0, 1);
    lk_metro_result metro = shape_metro(&noisy, &result.mesh, 10);
    assert_true(metro.hausdorff < 0.1 + 2 * sphere_sagitta(512));
    lk_simplify_result_free(&result);
    lk_mesh_free(&noisy);
}

/* The recorded history replayed on the input (move `kept`, rename
 * `removed`, drop the vanished triangles) gives the output: the same
 * oriented triangles through vertex_map, the same positions. Running twice
 * gives the same bytes. */
static void test_history_replays(void **state)
{
    (void)state;
    lk_mesh torus;
    shape_torus(&torus, 2, 0.5, 32, 16);
    lk_simplify_options options = qem_options(0.1, 0, LK_SIMPLIFY_RECORD);
    lk_simplify_result result, again;
    simplify_ok(&torus, &options, &result);
    simplify_ok(&torus, &options, &again);
    assert_int_equal(again.mesh.triangle_count, result.mesh.triangle_count);
    assert_memory_equal(again.mesh.indices, result.mesh.indices, 3 * result.mesh.triangle_count * sizeof(uint32_t));
    assert_memory_equal(again.mesh.positions, result.mesh.positions, 3 * result.mesh.vertex_count * sizeof(float));
    lk_simplify_result_free(&again);

    assert_int_equal(result.collapse_count, torus.vertex_count - result.mesh.vertex_count);
    float *positions = malloc(3 * torus.vertex_count * sizeof(float));
    uint32_t *indices = malloc(3 * torus.triangle_count * sizeof(uint32_t));
    unsigned char *gone = calloc(torus.triangle_count, 1);
    assert_true(positions && indices && gone);
    memcpy(positions, torus.positions, 3 * torus.vertex_count * sizeof(float));
    memcpy(indices, torus.indices, 3 * torus.triangle_count * sizeof(uint32_t));
    size_t vanished = 0;
    for (size_t k = 0; k < result.collapse_count; k++) {
        const lk_collapse *c = &result.collapses[k];
        memcpy(positions + 3 * c->kept, c->position, sizeof c->position);
        for (uint32_t i = 0; i < c->vanished_count; i++) {
            uint32_t t = result.vanished[c->first_vanished + i];
            assert_false(gone[t]);
            gone[t] = 1;
            vanished++;
        }
        for (size_t i = 0; i < 3 * torus.triangle_count; i++)
            if (indices[i] == c->removed) indices[i] = c->kept;
    }
    assert_int_equal(torus.triangle_count - vanished, result.mesh.triangle_count);
    size_t out = 0;
    for (size_t t = 0; t < torus.triangle_count; t++) {
        if (gone[t]) continue;
        const uint32_t *triangle = indices + 3 * t;
        assert_true(triangle[0] != triangle[1] && triangle[1] != triangle[2] && triangle[0] != triangle[2]);
        /* Same oriented triangle as some output triangle: output order
         * follows input order. */
        const uint32_t *o = result.mesh.indices + 3 * out++;
        for (int k = 0; k < 3; k++) {
            assert_int_equal(result.vertex_map[triangle[k]], o[k]);
            assert_memory_equal(positions + 3 * triangle[k], result.mesh.positions + 3 * o[k], 3 * sizeof(float));
        }
    }
    free(positions);
    free(indices);
    free(gone);
    lk_simplify_result_free(&result);
    lk_mesh_free(&torus);
}

/* The triangle lists live in a pool with 32-bit offsets; a pool that would
 * pass its limit is compacted (qem.c compact_pool). With the limit at
 * 3T + 64 entries the torus compacts many times on the way to 10% (each
 * contraction may take a fresh block), and the result, history included,
 * must be the same as with room to spare. A limit below what the live
 * lists need is an error, not a crash. */
static void qem_with_pool_limit(const lk_mesh *mesh, const lk_simplify_options *options, size_t limit,
                                lk_simplify_result *result, lk_status expected)
{
    memset(result, 0, sizeof *result);
    result->diagonal = lk_mesh_bounds(mesh, NULL, NULL);
    lk_error error = {0};
    lk_status status = lk__simplify_qem_pool_limit(mesh, options, limit, result, NULL, NULL, &error);
    if (status != expected)
        fail_msg("pool limit %zu: status %d, expected %d (%s)", limit, status, expected, error.message);
}

static void test_pool_compaction(void **state)
{
    (void)state;
    lk_mesh torus;
    shape_torus(&torus, 2, 0.5, 32, 16);
    size_t tight = 3 * torus.triangle_count + 64;
    lk_simplify_options options = qem_options(0.1, 0, LK_SIMPLIFY_RECORD);
    lk_simplify_result roomy, compacted;
    qem_with_pool_limit(&torus, &options, SIZE_MAX, &roomy, LK_OK);
    qem_with_pool_limit(&torus, &options, tight, &compacted, LK_OK);
    assert_int_equal(compacted.mesh.triangle_count, roomy.mesh.triangle_count);
    assert_int_equal(compacted.mesh.vertex_count, roomy.mesh.vertex_count);
    assert_memory_equal(compacted.mesh.indices, roomy.mesh.indices, 3 * roomy.mesh.triangle_count * sizeof(uint32_t));
    assert_memory_equal(compacted.mesh.positions, roomy.mesh.positions, 3 * roomy.mesh.vertex_count * sizeof(float));
    assert_int_equal(compacted.collapse_count, roomy.collapse_count);
    assert_memory_equal(compacted.collapses, roomy.collapses, roomy.collapse_count * sizeof(lk_collapse));
    assert_memory_equal(compacted.vertex_map, roomy.vertex_map, torus.vertex_count * sizeof(uint32_t));
    lk_simplify_result_free(&compacted);
    lk_simplify_result_free(&roomy);
    /* the initial lists alone need 3T entries */
    lk_simplify_result refused;
    qem_with_pool_limit(&torus, &options, 3 * torus.triangle_count - 1, &refused, LK_ERR_LIMIT);
    lk_simplify_result_free(&refused);
    lk_mesh_free(&torus);
}

/* lk_simplify works on a view of its input without degenerate and
 * repeated triangles that shares the vertex arrays (no copy of the mesh:
 * 24 bytes per triangle of the peak on a large run). The view leaves the
 * input as it was, and simplifying a mesh with such triangles gives
 * exactly what simplifying it without them gives. */
static void test_clean_view_shares_vertices(void **state)
{
    (void)state;
    lk_mesh sphere, padded, clean;
    shape_noisy_sphere(&sphere, 1, 3, 0.02, 7);
    lk_error error = {0};
    uint32_t *owned = (uint32_t *)&error; /* must be overwritten */
    assert_int_equal(lk__mesh_clean_view(&sphere, &clean, &owned, &error), LK_OK);
    assert_null(owned);
    assert_ptr_equal(clean.positions, sphere.positions);
    assert_ptr_equal(clean.indices, sphere.indices);
    assert_int_equal(clean.triangle_count, sphere.triangle_count);

    /* a degenerate triangle first, a repeat (other corner order) last */
    size_t t = sphere.triangle_count;
    assert_int_equal(lk_mesh_alloc(&padded, sphere.vertex_count, t + 2, 0, &error), LK_OK);
    memcpy(padded.positions, sphere.positions, 3 * sphere.vertex_count * sizeof(float));
    const uint32_t *fifth = sphere.indices + 15;
    uint32_t degenerate[3] = {4, 9, 4}, repeat[3] = {fifth[1], fifth[2], fifth[0]};
    memcpy(padded.indices, degenerate, sizeof degenerate);
    memcpy(padded.indices + 3, sphere.indices, 3 * t * sizeof(uint32_t));
    memcpy(padded.indices + 3 * (t + 1), repeat, sizeof repeat);
    uint32_t *before = malloc(3 * (t + 2) * sizeof(uint32_t));
    assert_non_null(before);
    memcpy(before, padded.indices, 3 * (t + 2) * sizeof(uint32_t));
    assert_int_equal(lk__mesh_clean_view(&padded, &clean, &owned, &error), LK_OK);
    assert_non_null(owned);
    assert_ptr_equal(clean.indices, owned);
    assert_ptr_equal(clean.positions, padded.positions);
    assert_int_equal(clean.triangle_count, t);
    assert_memory_equal(clean.indices, sphere.indices, 3 * t * sizeof(uint32_t));
    assert_int_equal(padded.triangle_count, t + 2);
    assert_memory_equal(padded.indices, before, 3 * (t + 2) * sizeof(uint32_t));
    free(owned);

    lk_simplify_options options = qem_options(0.1, 0, 0);
    lk_simplify_result plain, cleaned;
    simplify_ok(&sphere, &options, &plain);
    simplify_ok(&padded, &options, &cleaned);
    assert_memory_equal(padded.indices, before, 3 * (t + 2) * sizeof(uint32_t));
    assert_int_equal(cleaned.mesh.vertex_count, plain.mesh.vertex_count);
    assert_int_equal(cleaned.mesh.triangle_count, plain.mesh.triangle_count);
    assert_memory_equal(cleaned.mesh.positions, plain.mesh.positions, 3 * plain.mesh.vertex_count * sizeof(float));
    assert_memory_equal(cleaned.mesh.indices, plain.mesh.indices, 3 * plain.mesh.triangle_count * sizeof(uint32_t));
    lk_simplify_result_free(&plain);
    lk_simplify_result_free(&cleaned);
    free(before);
    lk_mesh_free(&padded);
    lk_mesh_free(&sphere);
}

/* Every output vertex sits at the floats of one of the input vertices
 * merged into it. */
static void assert_outputs_at_input_floats(const lk_mesh *input, const lk_simplify_result *result)
{
    unsigned char *matched = calloc(result->mesh.vertex_count, 1);
    assert_non_null(matched);
    for (size_t v = 0; v < input->vertex_count; v++) {
        uint32_t o = result->vertex_map[v];
        if (o == UINT32_MAX) continue;
        if (!memcmp(result->mesh.positions + 3 * (size_t)o, input->positions + 3 * v, 3 * sizeof(float)))
            matched[o] = 1;
    }
    for (size_t o = 0; o < result->mesh.vertex_count; o++)
        if (!matched[o]) fail_msg("output vertex %zu is at none of its input vertices' positions", o);
    free(matched);
}

/* Output positions are not stored per vertex: a vertex that never moved
 * takes its input floats, bit for bit. With LK_SIMPLIFY_ENDPOINTS no
 * vertex moves, so every output position is one of the input's. */
static void test_endpoints_keep_input_floats(void **state)
{
    (void)state;
    lk_mesh sphere;
    shape_noisy_sphere(&sphere, 1, 3, 0.02, 11);
    lk_simplify_options options = qem_options(0.1, 0, LK_SIMPLIFY_ENDPOINTS);
    lk_simplify_result result;
    simplify_ok(&sphere, &options, &result);
    assert_outputs_at_input_floats(&sphere, &result);
    lk_simplify_result_free(&result);
    lk_mesh_free(&sphere);
}

/* LK_SIMPLIFY_ROUNDS only reorders the contractions: on a noisy sphere at
 * 10% the count is reached exactly, the result is a closed manifold, and
 * it is about as close to the input as greedy order (Hausdorff and RMS
 * within 1.2 times greedy's; measured 0.692% against 0.668% and 0.144%
 * against 0.139% of the diagonal); with endpoint placement as well, every
 * output vertex keeps its input floats. */
static void test_rounds(void **state)
{
    (void)state;
    lk_mesh sphere;
    shape_noisy_sphere(&sphere, 1, 4, 0.01, 5);
    double errors[2][2];
    for (int rounds = 0; rounds <= 1; rounds++) {
        lk_simplify_options options = qem_options(0.1, 0, rounds ? LK_SIMPLIFY_ROUNDS : 0);
        lk_simplify_result result;
        simplify_ok(&sphere, &options, &result);
        assert_true(result.target_reached);
        assert_int_equal(result.mesh.triangle_count, sphere.triangle_count / 10);
        assert_closed_manifold(&result.mesh, 0, 1);
        lk_metro_result metro = shape_metro(&sphere, &result.mesh, 10);
        errors[rounds][0] = metro.hausdorff / metro.diagonal;
        errors[rounds][1] = fmax(metro.forward.rms, metro.backward.rms) / metro.diagonal;
        lk_simplify_result_free(&result);
    }
    print_message("noisy sphere 10%%: Hausdorff %.4f%% greedy, %.4f%% rounds; RMS %.4f%%, %.4f%%\n", 100 * errors[0][0],
                  100 * errors[1][0], 100 * errors[0][1], 100 * errors[1][1]);
    assert_true(errors[1][0] <= 1.2 * errors[0][0] && errors[1][1] <= 1.2 * errors[0][1]);
    lk_simplify_options options = qem_options(0.1, 0, LK_SIMPLIFY_ROUNDS | LK_SIMPLIFY_ENDPOINTS);
    lk_simplify_result result;
    simplify_ok(&sphere, &options, &result);
    assert_outputs_at_input_floats(&sphere, &result);
    lk_simplify_result_free(&result);
    lk_mesh_free(&sphere);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sphere_to_ten_percent),
        cmocka_unit_test(test_rounds),
        cmocka_unit_test(test_error_grows_with_reduction),
        cmocka_unit_test(test_topology_kept),
        cmocka_unit_test(test_box_to_twelve_triangles),
        cmocka_unit_test(test_borders),
        cmocka_unit_test(test_max_error),
        cmocka_unit_test(test_noisy_sphere),
        cmocka_unit_test(test_history_replays),
        cmocka_unit_test(test_pool_compaction),
        cmocka_unit_test(test_clean_view_shares_vertices),
        cmocka_unit_test(test_endpoints_keep_input_floats),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
