/* SPDX-License-Identifier: MIT */
/* Vertex clustering (src/cluster.c): Rossignac-Borrel uniform grid and
 * Low-Tan floating cells at 12.5% of the vertices on the bunny and the
 * triceratops (Hausdorff error printed next to the wavelet paper's table 4),
 * the cell-size bound of max_error, the documented representatives
 * (importance-weighted average / most important centre), monotonicity in the
 * cell size, vertex_map consistency, determinism, count targets, progress
 * and cancellation, and tiny cases (point sets, a cube collapsing to
 * nothing, unused vertices, attributes). */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#define GONE UINT32_MAX

static const char *method_name(lk_simplify_method method)
{
    return method == LK_SIMPLIFY_UNIFORM ? "uniform" : "floating";
}

static void simplify_ok(const lk_mesh *mesh, lk_simplify_method method, const lk_simplify_options *options,
                        lk_simplify_result *result)
{
    lk_error error = {0};
    lk_status status = lk_simplify(mesh, method, options, result, NULL, NULL, &error);
    if (status != LK_OK) fail_msg("%s clustering failed: %s", method_name(method), error.message);
}

/* A valid mesh: indices in range, no degenerate or duplicate triangle,
 * no unused vertex (when it has triangles). */
static void assert_clean(const lk_mesh *mesh)
{
    lk_error error = {0};
    lk_mesh_stats stats;
    if (lk_mesh_validate(mesh, &error) != LK_OK) fail_msg("invalid output: %s", error.message);
    if (lk_mesh_compute_stats(mesh, &stats, &error) != LK_OK) fail_msg("stats: %s", error.message);
    assert_int_equal(stats.degenerate_triangle_count, 0);
    assert_int_equal(stats.duplicate_triangle_count, 0);
    assert_int_equal(stats.used_vertex_count, mesh->triangle_count ? mesh->vertex_count : 0);
}

static double hausdorff_percent(const lk_mesh *original, const lk_mesh *simplified)
{
    lk_metro_result metro;
    lk_error error = {0};
    if (lk_metro(original, simplified, NULL, &metro, NULL, NULL, &error) != LK_OK) fail_msg("metro: %s", error.message);
    return 100 * metro.hausdorff / metro.diagonal;
}

/* ---- the paper's experiment: 12.5% of the vertices ----------------------- */

typedef struct paper_row {
    lk_simplify_method method;
    double paper_error_percent;
    size_t paper_triangles;
    double max_error_percent; /* measured x ~1.25 */
} paper_row;

static void check_paper_model(const char *name, const paper_row rows[2])
{
    lk_mesh mesh;
    lk_test_load(lk_test_sample(name), &mesh);
    size_t target = (size_t)llround(0.125 * (double)mesh.vertex_count);
    for (int i = 0; i < 2; i++) {
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_vertices = target;
        lk_simplify_result result;
        simplify_ok(&mesh, rows[i].method, &options, &result);
        assert_clean(&result.mesh);
        assert_true(result.target_reached);
        assert_true(fabs((double)result.mesh.vertex_count - (double)target) <= 0.02 * (double)target);
        assert_true(result.mesh.vertex_count <= target);
        assert_null(result.collapses);
        assert_int_equal(result.collapse_count, 0);
        double percent = hausdorff_percent(&mesh, &result.mesh);
        print_message("%-16s %-8s %5zu v (target %zu) %5zu t (paper %zu, Delaunay)  Hausdorff %.2f%% (paper %.2f%%)  "
                      "moved <= %.2f%%  %.3f s\n",
                      name, method_name(rows[i].method), result.mesh.vertex_count, target, result.mesh.triangle_count,
                      rows[i].paper_triangles, percent, rows[i].paper_error_percent,
                      100 * result.error / result.diagonal, result.seconds);
        assert_true(percent <= rows[i].max_error_percent);
        /* Clustering keeps a closed surface's 2:1 triangle/vertex ratio
         * (the paper re-triangulated, hence its lower counts). */
        assert_true(result.mesh.triangle_count > 1.8 * (double)result.mesh.vertex_count);
        assert_true(result.mesh.triangle_count < 2.2 * (double)result.mesh.vertex_count);
        /* Every vertex was moved by some positive amount but no further
         * than a few percent of the model. */
        assert_true(result.error > 0 && result.error < 0.1 * result.diagonal);
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&mesh);
}

static void test_bunny_paper(void **state)
{
    (void)state;
    /* Table 4: uniform 1.42%, floating 1.03% of the diagonal. */
    const paper_row rows[2] = {{LK_SIMPLIFY_UNIFORM, 1.42, 4989, 1.30}, {LK_SIMPLIFY_FLOATING, 1.03, 5426, 0.75}};
    check_paper_model("bunny.obj", rows);
}

static void test_triceratops_paper(void **state)
{
    (void)state;
    /* Table 4: uniform 3.10%, floating 3.08% of the diagonal. */
    const paper_row rows[2] = {{LK_SIMPLIFY_UNIFORM, 3.10, 1850, 4.50}, {LK_SIMPLIFY_FLOATING, 3.08, 1856, 5.00}};
    check_paper_model("triceratops.off", rows);
}

/* ---- max_error is the cell size ------------------------------------------ */

static void test_cell_size_bound(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("triceratops.off"), &mesh);
    float low[3], high[3];
    double diagonal = lk_mesh_bounds(&mesh, low, high);
    /* 0.6%: floating cells find their buckets through the hash table (the
     * box holds more bucket cells than the dense grid's 4 a vertex), 1% and
     * 4% through the dense grid. */
    const double fractions[3] = {0.006, 0.01, 0.04};
    for (int f = 0; f < 3; f++) {
        double cell = fractions[f] * diagonal;
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.max_error = fractions[f];

        /* Uniform: members of one output vertex share one grid cell (origin
         * at the bounding-box minimum), so nobody moves further than the
         * cell diagonal. */
        lk_simplify_result uniform;
        simplify_ok(&mesh, LK_SIMPLIFY_UNIFORM, &options, &uniform);
        assert_clean(&uniform.mesh);
        assert_true(uniform.target_reached);
        assert_true(uniform.error <= cell * sqrt(3.0) * (1 + 1e-6));
        int64_t *cell_of = malloc(uniform.mesh.vertex_count * 3 * sizeof(int64_t));
        unsigned char *seen = calloc(uniform.mesh.vertex_count, 1);
        assert_non_null(cell_of);
        assert_non_null(seen);
        for (size_t v = 0; v < mesh.vertex_count; v++) {
            uint32_t o = uniform.vertex_map[v];
            if (o == GONE) continue;
            int64_t key[3];
            for (int k = 0; k < 3; k++) key[k] = (int64_t)floor(((double)mesh.positions[3 * v + k] - low[k]) / cell);
            if (!seen[o]) {
                memcpy(cell_of + 3 * o, key, sizeof key);
                seen[o] = 1;
            } else {
                assert_memory_equal(cell_of + 3 * o, key, sizeof key);
            }
        }
        free(cell_of);
        free(seen);

        /* Floating: spheres of diameter `cell` centred on input vertices;
         * each centre lay outside every earlier sphere. */
        lk_simplify_result floating;
        simplify_ok(&mesh, LK_SIMPLIFY_FLOATING, &options, &floating);
        assert_clean(&floating.mesh);
        assert_true(floating.target_reached);
        assert_true(floating.error <= cell / 2 * (1 + 1e-6));
        for (size_t o = 0; o < floating.mesh.vertex_count; o++) {
            const float *p = floating.mesh.positions + 3 * o;
            bool is_input_vertex = false;
            for (size_t v = 0; v < mesh.vertex_count && !is_input_vertex; v++)
                is_input_vertex = floating.vertex_map[v] == o && memcmp(mesh.positions + 3 * v, p, 12) == 0;
            assert_true(is_input_vertex);
            for (size_t q = o + 1; q < floating.mesh.vertex_count; q++) {
                const float *r = floating.mesh.positions + 3 * q;
                double d0 = (double)p[0] - r[0], d1 = (double)p[1] - r[1], d2 = (double)p[2] - r[2];
                assert_true(sqrt(d0 * d0 + d1 * d1 + d2 * d2) > cell / 2);
            }
        }
        print_message("triceratops cell %.1f%%: uniform %zu v moved <= %.2f%%, floating %zu v moved <= %.2f%%\n",
                      100 * fractions[f], uniform.mesh.vertex_count, 100 * uniform.error / diagonal,
                      floating.mesh.vertex_count, 100 * floating.error / diagonal);
        /* The floating cell (a ball) is smaller than the cube: more clusters. */
        assert_true(floating.mesh.vertex_count > uniform.mesh.vertex_count);
        lk_simplify_result_free(&uniform);
        lk_simplify_result_free(&floating);
    }
    lk_mesh_free(&mesh);
}

/* Uniform cells' documented importance: longest incident edge L times
 * (|mean of the unit vectors along the incident edges| + 0.05), each edge
 * once per incident triangle. */
static double *reference_uniform_importance(const lk_mesh *mesh)
{
    double *sums = calloc(5 * mesh->vertex_count, sizeof(double)); /* xyz, longest, edges */
    double *importance = calloc(mesh->vertex_count, sizeof(double));
    assert_non_null(sums);
    assert_non_null(importance);
    for (size_t t = 0; t < mesh->triangle_count; t++)
        for (int corner = 0; corner < 3; corner++) {
            uint32_t v = mesh->indices[3 * t + corner];
            for (int other = 1; other <= 2; other++) {
                uint32_t u = mesh->indices[3 * t + (corner + other) % 3];
                double d[3], length = 0;
                for (int k = 0; k < 3; k++) {
                    d[k] = (double)mesh->positions[3 * u + k] - mesh->positions[3 * v + k];
                    length += d[k] * d[k];
                }
                length = sqrt(length);
                double *sum = sums + 5 * v;
                sum[3] = fmax(sum[3], length);
                if (length == 0) continue;
                for (int k = 0; k < 3; k++) sum[k] += d[k] / length;
                sum[4] += 1;
            }
        }
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        const double *sum = sums + 5 * v;
        double mean = sum[4] > 0 ? sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]) / sum[4] : 0;
        importance[v] = sum[3] * (fmin(mean, 1) + 0.05);
    }
    free(sums);
    return importance;
}

/* Floating cells' documented importance: longest incident edge L times
 * (cos(theta/2) + 0.05), theta the largest angle between two incident
 * edges, by brute force over all pairs of corners around each vertex. */
static double *reference_importance(const lk_mesh *mesh)
{
    lk_vertex_adjacency adjacency;
    assert_int_equal(lk_vertex_adjacency_build(mesh, &adjacency, NULL), LK_OK);
    double *importance = calloc(mesh->vertex_count, sizeof(double));
    assert_non_null(importance);
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        double longest = 0, min_dot = 1;
        for (uint32_t i = adjacency.offsets[v]; i < adjacency.offsets[v + 1]; i++)
            for (uint32_t j = adjacency.offsets[v]; j < adjacency.offsets[v + 1]; j++)
                for (int a = 0; a < 3; a++)
                    for (int b = 0; b < 3; b++) {
                        uint32_t u = mesh->indices[3 * adjacency.triangles[i] + a];
                        uint32_t w = mesh->indices[3 * adjacency.triangles[j] + b];
                        if (u == v || w == v) continue;
                        double d[3], g[3], dd = 0, gg = 0, dg = 0;
                        for (int k = 0; k < 3; k++) {
                            d[k] = (double)mesh->positions[3 * u + k] - mesh->positions[3 * v + k];
                            g[k] = (double)mesh->positions[3 * w + k] - mesh->positions[3 * v + k];
                            dd += d[k] * d[k], gg += g[k] * g[k], dg += d[k] * g[k];
                        }
                        longest = fmax(longest, sqrt(dd));
                        min_dot = fmin(min_dot, dg / sqrt(dd * gg));
                    }
        importance[v] = longest * (sqrt((1 + fmax(min_dot, -1)) / 2) + 0.05);
    }
    lk_vertex_adjacency_free(&adjacency);
    return importance;
}

static void test_representatives(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("triceratops.off"), &mesh);
    double *importance = reference_uniform_importance(&mesh);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.max_error = 0.04;
    lk_simplify_result result;
    simplify_ok(&mesh, LK_SIMPLIFY_UNIFORM, &options, &result);
    size_t count = result.mesh.vertex_count;
    double *sums = calloc(count * 8, sizeof(double)); /* weighted xyz, weight, plain xyz, members */
    assert_non_null(sums);
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        uint32_t o = result.vertex_map[v];
        if (o == GONE) continue;
        double *sum = sums + 8 * o;
        for (int k = 0; k < 3; k++) {
            sum[k] += importance[v] * mesh.positions[3 * v + k];
            sum[4 + k] += mesh.positions[3 * v + k];
        }
        sum[3] += importance[v];
        sum[7] += 1;
    }
    double worst_weighted = 0, largest_pull = 0;
    for (size_t o = 0; o < count; o++) {
        const double *sum = sums + 8 * o;
        for (int k = 0; k < 3; k++) {
            double out = result.mesh.positions[3 * o + k];
            worst_weighted = fmax(worst_weighted, fabs(out - sum[k] / sum[3]));
            largest_pull = fmax(largest_pull, fabs(out - sum[4 + k] / sum[7]));
        }
    }
    print_message("weighted average: off by %.2g, pulled up to %.2f%% of the diagonal from the centroid\n",
                  worst_weighted / result.diagonal, 100 * largest_pull / result.diagonal);
    assert_true(worst_weighted < 1e-5 * result.diagonal);
    /* The weights matter: some representatives sit well off the centroid. */
    assert_true(largest_pull > 0.3 * 0.01 * result.diagonal);
    free(sums);
    lk_simplify_result_free(&result);

    /* Floating cells: each representative is its most important member. */
    free(importance);
    importance = reference_importance(&mesh);
    simplify_ok(&mesh, LK_SIMPLIFY_FLOATING, &options, &result);
    count = result.mesh.vertex_count;
    double *best = calloc(count, sizeof(double)), *centre = calloc(count, sizeof(double));
    assert_non_null(best);
    assert_non_null(centre);
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        uint32_t o = result.vertex_map[v];
        if (o == GONE) continue;
        best[o] = fmax(best[o], importance[v]);
        if (memcmp(mesh.positions + 3 * v, result.mesh.positions + 3 * (size_t)o, 12) == 0)
            centre[o] = fmax(centre[o], importance[v]);
    }
    for (size_t o = 0; o < count; o++) assert_true(centre[o] >= best[o] * (1 - 1e-9));
    free(best);
    free(centre);
    free(importance);
    lk_simplify_result_free(&result);
    lk_mesh_free(&mesh);
}

static void test_finer_cells_keep_more(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("bunny.obj"), &mesh);
    const double fractions[4] = {0.004, 0.008, 0.016, 0.032};
    for (int m = 0; m < 2; m++) {
        lk_simplify_method method = m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM;
        size_t previous = SIZE_MAX;
        for (int f = 0; f < 4; f++) {
            lk_simplify_options options;
            lk_simplify_options_default(&options);
            options.max_error = fractions[f];
            lk_simplify_result result;
            simplify_ok(&mesh, method, &options, &result);
            print_message("bunny %-8s cell %.1f%%: %zu v\n", method_name(method), 100 * fractions[f],
                          result.mesh.vertex_count);
            assert_true(result.mesh.vertex_count < previous);
            assert_true(result.mesh.vertex_count < mesh.vertex_count);
            previous = result.mesh.vertex_count;
            lk_simplify_result_free(&result);
        }
        /* At 3.2% of the diagonal about 1,200 cubes or 2,300 balls remain
         * (a ball of diameter s is smaller than a cube of side s). */
        if (m == 0)
            assert_in_range(previous, 1000, 1400);
        else
            assert_in_range(previous, 1900, 2700);
    }
    lk_mesh_free(&mesh);
}

/* ---- vertex_map, determinism, count targets ------------------------------ */

/* Rotates a triangle so that its smallest index comes first (keeps the
 * orientation). */
static void canonical_rotation(uint32_t t[3])
{
    while (t[0] > t[1] || t[0] > t[2]) {
        uint32_t first = t[0];
        t[0] = t[1], t[1] = t[2], t[2] = first;
    }
}

static int compare_triples(const void *pa, const void *pb)
{
    const uint32_t *a = pa, *b = pb;
    for (int k = 0; k < 3; k++)
        if (a[k] != b[k]) return a[k] < b[k] ? -1 : 1;
    return 0;
}

static int compare_indices(const void *pa, const void *pb)
{
    uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
    return (a > b) - (a < b);
}

/* Every output triangle is the image of an input triangle under vertex_map,
 * with the same orientation; every input triangle whose image has three
 * distinct vertices survives (in some orientation); every output vertex is
 * the image of an input vertex. */
static void check_vertex_map(const lk_mesh *input, const lk_simplify_result *result)
{
    const lk_mesh *output = &result->mesh;
    uint32_t *images = malloc(input->triangle_count * 3 * sizeof(uint32_t));
    uint32_t *unordered = malloc(input->triangle_count * 3 * sizeof(uint32_t));
    unsigned char *hit = calloc(output->vertex_count + 1, 1);
    assert_non_null(images);
    assert_non_null(unordered);
    assert_non_null(hit);
    size_t image_count = 0;
    for (size_t t = 0; t < input->triangle_count; t++) {
        uint32_t image[3];
        for (int k = 0; k < 3; k++) image[k] = result->vertex_map[input->indices[3 * t + k]];
        if (image[0] == GONE || image[1] == GONE || image[2] == GONE) {
            /* A vertex is gone only when all its triangles collapsed. */
            assert_true(image[0] == image[1] || image[1] == image[2] || image[0] == image[2] || image[0] == GONE ||
                        image[1] == GONE || image[2] == GONE);
            continue;
        }
        if (image[0] == image[1] || image[1] == image[2] || image[0] == image[2]) continue;
        canonical_rotation(image);
        memcpy(images + 3 * image_count, image, sizeof image);
        qsort(image, 3, sizeof(uint32_t), compare_indices);
        memcpy(unordered + 3 * image_count, image, sizeof image);
        image_count++;
    }
    qsort(images, image_count, 3 * sizeof(uint32_t), compare_triples);
    qsort(unordered, image_count, 3 * sizeof(uint32_t), compare_triples);
    for (size_t t = 0; t < output->triangle_count; t++) {
        uint32_t triangle[3];
        memcpy(triangle, output->indices + 3 * t, sizeof triangle);
        canonical_rotation(triangle);
        assert_non_null(bsearch(triangle, images, image_count, 3 * sizeof(uint32_t), compare_triples));
    }
    /* Distinct unordered images = output triangles (duplicates merged). */
    size_t distinct = 0;
    for (size_t i = 0; i < image_count; i++)
        if (i == 0 || compare_triples(unordered + 3 * i, unordered + 3 * (i - 1)) != 0) distinct++;
    assert_int_equal(distinct, output->triangle_count);
    for (size_t v = 0; v < input->vertex_count; v++)
        if (result->vertex_map[v] != GONE) {
            assert_true(result->vertex_map[v] < output->vertex_count);
            hit[result->vertex_map[v]] = 1;
        }
    for (size_t o = 0; o < output->vertex_count; o++) assert_true(hit[o]);
    free(images);
    free(unordered);
    free(hit);
}

static void test_vertex_map_and_determinism(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("fandisk.off"), &mesh);
    for (int m = 0; m < 2; m++) {
        lk_simplify_method method = m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM;
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_vertices = 800;
        lk_simplify_result first, second;
        simplify_ok(&mesh, method, &options, &first);
        simplify_ok(&mesh, method, &options, &second);
        assert_clean(&first.mesh);
        check_vertex_map(&mesh, &first);
        assert_int_equal(first.mesh.vertex_count, second.mesh.vertex_count);
        assert_int_equal(first.mesh.triangle_count, second.mesh.triangle_count);
        assert_memory_equal(first.mesh.positions, second.mesh.positions, first.mesh.vertex_count * 12);
        assert_memory_equal(first.mesh.indices, second.mesh.indices, first.mesh.triangle_count * 12);
        assert_memory_equal(first.vertex_map, second.vertex_map, mesh.vertex_count * sizeof(uint32_t));
        assert_true(first.error == second.error);
        lk_simplify_result_free(&first);
        lk_simplify_result_free(&second);
    }
    lk_mesh_free(&mesh);
}

static void test_triangle_targets(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("bunny.obj"), &mesh);
    for (int m = 0; m < 2; m++) {
        lk_simplify_method method = m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM;
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_ratio = 0.05;
        lk_simplify_result result;
        simplify_ok(&mesh, method, &options, &result);
        double wanted = 0.05 * (double)mesh.triangle_count;
        assert_true(result.target_reached);
        assert_true(result.mesh.triangle_count <= (size_t)llround(wanted));
        assert_true((double)result.mesh.triangle_count >= 0.98 * wanted);
        lk_simplify_result_free(&result);

        /* Two rules: the first reached while coarsening (the larger count) wins. */
        lk_simplify_options_default(&options);
        options.target_triangles = 2000;
        options.target_vertices = 3000;
        simplify_ok(&mesh, method, &options, &result);
        assert_true(result.target_reached);
        assert_in_range(result.mesh.vertex_count, 2940, 3000);
        assert_true(result.mesh.triangle_count > 2000);
        lk_simplify_result_free(&result);

        /* A max_error finer than the count target stops first. */
        options.max_error = 0.002;
        simplify_ok(&mesh, method, &options, &result);
        assert_true(result.target_reached);
        assert_true(result.mesh.vertex_count > 3000);
        assert_true(result.error <= 0.002 * result.diagonal * sqrt(3.0) * (1 + 1e-6));
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&mesh);
}

/* Targets above an eighth of the triangles are searched on estimated
 * counts (candidate triangles scaled by fitted ratios), each found size
 * checked by an exact trial: the same tolerances as exact searches, for
 * triangle and vertex targets, and a finer max_error still stops first. */
static void test_large_targets(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("bunny.obj"), &mesh);
    for (int m = 0; m < 2; m++) {
        lk_simplify_method method = m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM;
        static const double ratios[] = {0.5, 0.25};
        for (size_t r = 0; r < 2; r++) {
            lk_simplify_options options;
            lk_simplify_options_default(&options);
            options.target_ratio = ratios[r];
            lk_simplify_result result;
            simplify_ok(&mesh, method, &options, &result);
            double wanted = ratios[r] * (double)mesh.triangle_count;
            print_message("%s, %.0f%%: %zu triangles (target %.0f)\n", method_name(method), 100 * ratios[r],
                          result.mesh.triangle_count, wanted);
            assert_true(result.target_reached);
            assert_true(result.mesh.triangle_count <= (size_t)llround(wanted));
            assert_true((double)result.mesh.triangle_count >= 0.98 * wanted);
            assert_clean(&result.mesh);
            lk_simplify_result_free(&result);
        }
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        size_t vertices = (size_t)llround(0.4 * (double)mesh.vertex_count);
        options.target_vertices = vertices;
        lk_simplify_result result;
        simplify_ok(&mesh, method, &options, &result);
        print_message("%s, 40%% of the vertices: %zu (target %zu)\n", method_name(method), result.mesh.vertex_count,
                      vertices);
        assert_true(result.target_reached);
        assert_true(result.mesh.vertex_count <= vertices);
        assert_true((double)result.mesh.vertex_count >= 0.98 * (double)vertices);
        lk_simplify_result_free(&result);

        lk_simplify_options_default(&options);
        options.target_ratio = 0.5;
        options.max_error = 0.001;
        simplify_ok(&mesh, method, &options, &result);
        assert_true(result.target_reached);
        assert_true((double)result.mesh.triangle_count > 0.5 * (double)mesh.triangle_count);
        assert_true(result.error <= 0.001 * result.diagonal * sqrt(3.0) * (1 + 1e-6));
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&mesh);
}

/* Six vertices is out of reach for floating cells on the triceratops (the
 * count jumps from 8 to 5): the nearest count at or under the target is
 * returned and flagged. */
static void test_unreachable_count(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("triceratops.off"), &mesh);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_vertices = 6;
    lk_simplify_result result;
    simplify_ok(&mesh, LK_SIMPLIFY_FLOATING, &options, &result);
    assert_int_equal(result.mesh.vertex_count, 5);
    assert_false(result.target_reached);
    assert_clean(&result.mesh);
    lk_simplify_result_free(&result);
    /* Five is reachable. */
    options.target_vertices = 5;
    simplify_ok(&mesh, LK_SIMPLIFY_FLOATING, &options, &result);
    assert_int_equal(result.mesh.vertex_count, 5);
    assert_true(result.target_reached);
    lk_simplify_result_free(&result);
    lk_mesh_free(&mesh);
}

/* Clustering reads the input as it is (no cleaned copy): degenerate
 * triangles must not make their vertices used (nor widen the grid's box),
 * and a repeated triangle must vanish like any repeat. Same result as the
 * clean input, for a cell size and for a searched vertex count. */
static void test_dirty_input(void **state)
{
    (void)state;
    lk_mesh cow, clean, dirty;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    /* Both get a far vertex (same diagonal); only the dirty one uses it, in
     * degenerate triangles. */
    size_t vertex_count = cow.vertex_count, triangle_count = cow.triangle_count;
    assert_int_equal(lk_mesh_alloc(&clean, vertex_count + 1, triangle_count, 0, NULL), LK_OK);
    assert_int_equal(lk_mesh_alloc(&dirty, vertex_count + 1, triangle_count + 3, 0, NULL), LK_OK);
    for (int i = 0; i < 2; i++) {
        lk_mesh *copy = i ? &dirty : &clean;
        memcpy(copy->positions, cow.positions, 3 * vertex_count * sizeof(float));
        float *far_away = copy->positions + 3 * vertex_count;
        far_away[0] = far_away[1] = far_away[2] = 1000;
        memcpy(copy->indices, cow.indices, 3 * triangle_count * sizeof(uint32_t));
    }
    double cow_diagonal = lk_mesh_bounds(&cow, NULL, NULL);
    uint32_t far = (uint32_t)vertex_count, *extra = dirty.indices + 3 * triangle_count;
    const uint32_t *first = cow.indices;
    uint32_t added[9] = {far, far, first[0], first[1], far, first[1], first[2], first[1], first[0]};
    memcpy(extra, added, sizeof added); /* two degenerate, one repeat (reversed) */
    for (int m = 0; m < 2; m++) {
        lk_simplify_method method = m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM;
        for (int rule = 0; rule < 2; rule++) {
            lk_simplify_options options;
            lk_simplify_options_default(&options);
            if (rule)
                options.target_vertices = 300;
            else
                options.max_error = 0.03;
            lk_simplify_result expected, result;
            simplify_ok(&clean, method, &options, &expected);
            simplify_ok(&dirty, method, &options, &result);
            assert_int_equal(result.mesh.vertex_count, expected.mesh.vertex_count);
            assert_int_equal(result.mesh.triangle_count, expected.mesh.triangle_count);
            /* The same cells; uniform weights see the repeat twice (its three
             * corners' averages move a little). */
            double moved = 0;
            for (size_t i = 0; i < 3 * expected.mesh.vertex_count; i++)
                moved = fmax(moved, fabs(result.mesh.positions[i] - expected.mesh.positions[i]));
            print_message("%s, %s: representatives moved by %.2g of the cow's diagonal\n", method_name(method),
                          rule ? "300 vertices" : "cell 3%", moved / cow_diagonal);
            if (method == LK_SIMPLIFY_FLOATING)
                assert_true(moved == 0);
            else
                assert_true(moved < 1e-3 * cow_diagonal);
            assert_memory_equal(result.mesh.indices, expected.mesh.indices,
                                3 * expected.mesh.triangle_count * sizeof(uint32_t));
            assert_memory_equal(result.vertex_map, expected.vertex_map, (vertex_count + 1) * sizeof(uint32_t));
            assert_int_equal(result.vertex_map[far], GONE);
            assert_clean(&result.mesh);
            lk_simplify_result_free(&expected);
            lk_simplify_result_free(&result);
        }
    }
    /* Only degenerate triangles: refused as before. */
    lk_mesh flat = dirty;
    flat.indices = extra;
    flat.triangle_count = 2;
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.max_error = 0.03;
    lk_simplify_result result;
    lk_error error = {0};
    assert_int_equal(lk_simplify(&flat, LK_SIMPLIFY_UNIFORM, &options, &result, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "degenerate");
    lk_mesh_free(&dirty);
    lk_mesh_free(&clean);
    lk_mesh_free(&cow);
}

/* ---- progress and cancellation ------------------------------------------ */

typedef struct progress_log {
    int calls;
    int cancel_at; /* 0 = never */
    double last;
} progress_log;

static int record_progress(void *user, double fraction, const char *stage)
{
    progress_log *log = user;
    assert_non_null(stage);
    assert_true(fraction >= 0 && fraction <= 1);
    log->calls++;
    log->last = fraction;
    return log->cancel_at && log->calls >= log->cancel_at;
}

static void test_progress_and_cancel(void **state)
{
    (void)state;
    lk_mesh mesh;
    lk_test_load(lk_test_sample("cow.off"), &mesh);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_vertices = 500;
    for (int m = 0; m < 2; m++) {
        lk_simplify_method method = m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM;
        progress_log log = {0, 0, 0};
        lk_simplify_result result;
        lk_error error = {0};
        assert_int_equal(lk_simplify(&mesh, method, &options, &result, record_progress, &log, &error), LK_OK);
        /* One call per trial of the search, bounded. */
        assert_in_range(log.calls, 3, 40);
        assert_true(result.target_reached);
        lk_simplify_result_free(&result);

        progress_log cancel = {0, 2, 0};
        assert_int_equal(lk_simplify(&mesh, method, &options, &result, record_progress, &cancel, &error),
                         LK_ERR_INVALID);
        lk_assert_message_contains(error, "cancelled");
        assert_int_equal(cancel.calls, 2);
        assert_null(result.mesh.positions);
        assert_null(result.vertex_map);
    }
    lk_mesh_free(&mesh);
}

/* ---- small cases --------------------------------------------------------- */

static void test_point_set_refused(void **state)
{
    (void)state;
    lk_mesh points;
    assert_int_equal(lk_mesh_alloc(&points, 3, 0, 0, NULL), LK_OK);
    for (int i = 0; i < 9; i++) points.positions[i] = (float)i;
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.max_error = 0.1;
    for (int m = 0; m < 2; m++) {
        lk_simplify_result result;
        lk_error error = {0};
        assert_int_equal(
            lk_simplify(&points, m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM, &options, &result, NULL, NULL, &error),
            LK_ERR_INVALID);
        lk_assert_message_contains(error, "point set");
    }
    lk_mesh_free(&points);
}

static void test_cube_cases(void **state)
{
    (void)state;
    lk_mesh cube;
    lk_test_make_cube(&cube);
    for (int m = 0; m < 2; m++) {
        lk_simplify_method method = m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM;
        lk_simplify_options options;
        lk_simplify_result result;

        /* A cell larger than the model: everything collapses to nothing. */
        lk_simplify_options_default(&options);
        options.max_error = 2.0;
        simplify_ok(&cube, method, &options, &result);
        assert_int_equal(result.mesh.triangle_count, 0);
        assert_int_equal(result.mesh.vertex_count, 0);
        assert_false(result.target_reached);
        assert_int_equal(lk_mesh_validate(&result.mesh, NULL), LK_OK);
        for (int v = 0; v < 8; v++) assert_int_equal(result.vertex_map[v], GONE);
        lk_simplify_result_free(&result);

        /* Cells smaller than an edge: the cube comes back unchanged. */
        options.max_error = 0.1;
        simplify_ok(&cube, method, &options, &result);
        assert_int_equal(result.mesh.vertex_count, 8);
        assert_int_equal(result.mesh.triangle_count, 12);
        assert_memory_equal(result.mesh.positions, cube.positions, sizeof(float) * 24);
        assert_memory_equal(result.mesh.indices, cube.indices, sizeof(uint32_t) * 36);
        assert_true(result.error == 0);
        assert_true(result.target_reached);
        lk_simplify_result_free(&result);

        /* A target the input already meets: unchanged. */
        lk_simplify_options_default(&options);
        options.target_vertices = 8;
        simplify_ok(&cube, method, &options, &result);
        assert_int_equal(result.mesh.triangle_count, 12);
        assert_true(result.target_reached);
        for (uint32_t v = 0; v < 8; v++) assert_int_equal(result.vertex_map[v], v);
        lk_simplify_result_free(&result);

        /* Two vertices cannot carry a triangle: the nearest non-empty
         * result comes back, marked as not reaching the target. */
        options.target_vertices = 2;
        simplify_ok(&cube, method, &options, &result);
        assert_false(result.target_reached);
        assert_true(result.mesh.triangle_count > 0);
        assert_clean(&result.mesh);
        check_vertex_map(&cube, &result);
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&cube);
}

/* A flat 11 x 11 grid with normals, colours, an unused vertex and a
 * degenerate triangle: averaged attributes stay meaningful. */
static void test_attributes_and_unused(void **state)
{
    (void)state;
    const uint32_t n = 10, side = n + 1, grid_vertices = side * side;
    lk_mesh mesh;
    assert_int_equal(lk_mesh_alloc(&mesh, grid_vertices + 1, 2 * n * n + 1, LK_ATTR_NORMALS | LK_ATTR_COLORS, NULL),
                     LK_OK);
    for (uint32_t i = 0; i <= grid_vertices; i++) {
        float *p = mesh.positions + 3 * i, *normal = mesh.normals + 3 * i, *color = mesh.colors + 4 * i;
        p[0] = (float)(i % side), p[1] = (float)(i / side), p[2] = 0;
        normal[0] = 0, normal[1] = 0, normal[2] = 1;
        color[0] = (float)(i % side) / n, color[1] = 0.5f, color[2] = 0, color[3] = 1;
    }
    float *far_away = mesh.positions + 3 * grid_vertices; /* unused: must not join a cluster */
    far_away[0] = 3.2f, far_away[1] = 3.2f, far_away[2] = 0;
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t j = 0; j < n; j++) {
            uint32_t a = i * side + j, b = a + 1, c = a + side + 1, d = a + side;
            uint32_t *t = mesh.indices + 6 * (i * n + j);
            t[0] = a, t[1] = b, t[2] = c, t[3] = a, t[4] = c, t[5] = d;
        }
    uint32_t *degenerate = mesh.indices + 6 * n * n;
    degenerate[0] = 0, degenerate[1] = 0, degenerate[2] = 1;
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.max_error = 2.5 / (n * sqrt(2.0)); /* cells of 2.5 units */
    for (int m = 0; m < 2; m++) {
        lk_simplify_result result;
        simplify_ok(&mesh, m ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM, &options, &result);
        assert_clean(&result.mesh);
        assert_int_equal(result.vertex_map[grid_vertices], GONE);
        /* Uniform: x and y cells 0..4 (the far border lands in cell 4).
         * Floating: balls of diameter 2.5 pack more densely. */
        if (m == 0)
            assert_int_equal(result.mesh.vertex_count, 25);
        else
            assert_in_range(result.mesh.vertex_count, 40, 80);
        assert_non_null(result.mesh.normals);
        assert_non_null(result.mesh.colors);
        assert_null(result.mesh.texcoords);
        for (size_t o = 0; o < result.mesh.vertex_count; o++) {
            const float *normal = result.mesh.normals + 3 * o, *color = result.mesh.colors + 4 * o;
            const float *p = result.mesh.positions + 3 * o;
            assert_true(normal[0] == 0 && normal[1] == 0 && fabsf(normal[2] - 1) < 1e-6f);
            assert_true(p[2] == 0 && p[0] >= 0 && p[0] <= n && p[1] >= 0 && p[1] <= n);
            /* The red channel follows x on the grid, so it follows x after averaging. */
            assert_true(fabsf(color[0] - p[0] / n) < 1e-5f);
            assert_true(color[1] == 0.5f && color[3] == 1);
        }
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bunny_paper),
        cmocka_unit_test(test_triceratops_paper),
        cmocka_unit_test(test_cell_size_bound),
        cmocka_unit_test(test_representatives),
        cmocka_unit_test(test_finer_cells_keep_more),
        cmocka_unit_test(test_vertex_map_and_determinism),
        cmocka_unit_test(test_triangle_targets),
        cmocka_unit_test(test_large_targets),
        cmocka_unit_test(test_unreachable_count),
        cmocka_unit_test(test_dirty_input),
        cmocka_unit_test(test_progress_and_cancel),
        cmocka_unit_test(test_point_set_refused),
        cmocka_unit_test(test_cube_cases),
        cmocka_unit_test(test_attributes_and_unused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
