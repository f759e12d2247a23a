/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: progressive meshes (src/pm.c), triangle strips
 * and progressive strips (src/strips.c) and the .lks stream (src/stream_*.c)
 * on procedural shapes (closed: sphere, torus, sharp box; open: cylinder,
 * two parts). The full level is the input exactly; every level keeps the
 * topology; strips draw exactly the level's triangles; the stream decodes
 * every chunk to the progressive mesh's level within the quantisation
 * bound, a truncated stream to a prefix, and a corrupt CRC is refused. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

typedef struct model {
    const char *name;
    lk_mesh mesh;
    long long genus;
    size_t components;
    lk_progressive_mesh pm;
    lk_progressive_strips ps;
} model;

static void build_model(model *m)
{
    lk_error error = {0};
    lk_progressive_options options;
    lk_progressive_options_default(&options);
    if (lk_progressive_mesh_build(&m->mesh, &options, &m->pm, NULL, NULL, &error) != LK_OK)
        fail_msg("%s: progressive mesh: %s", m->name, error.message);
    if (lk_progressive_strips_build(&m->pm, LK_STRIPIFY_BEST, &m->ps, &error) != LK_OK)
        fail_msg("%s: progressive strips: %s", m->name, error.message);
}

static void free_model(model *m)
{
    lk_progressive_strips_free(&m->ps);
    lk_progressive_mesh_free(&m->pm);
    lk_mesh_free(&m->mesh);
}

enum { SPHERE, TORUS, BOX, CYLINDER, PARTS, MODEL_COUNT };

static int setup(void **state)
{
    model *models = calloc(MODEL_COUNT, sizeof *models);
    if (!models) return -1;
    models[SPHERE] = (model){.name = "sphere", .genus = 0, .components = 1};
    shape_icosphere(&models[SPHERE].mesh, 1, 4);
    models[TORUS] = (model){.name = "torus", .genus = 1, .components = 1};
    shape_torus(&models[TORUS].mesh, 2, 0.5, 48, 24);
    models[BOX] = (model){.name = "box", .genus = 0, .components = 1};
    shape_box(&models[BOX].mesh, 2, 3, 4, 8);
    models[CYLINDER] = (model){.name = "open cylinder", .genus = 0, .components = 1};
    shape_cylinder(&models[CYLINDER].mesh, 1, 3, 24, 20);
    models[PARTS] = (model){.name = "capsule + torus", .genus = 1, .components = 2};
    shape_capsule(&models[PARTS].mesh, 0.2, 3, 16, 20, 4);
    lk_mesh torus;
    shape_torus(&torus, 1, 0.3, 24, 12);
    shape_append(&models[PARTS].mesh, &torus, 3, 0, 0);
    lk_mesh_free(&torus);
    for (int i = 0; i < MODEL_COUNT; i++) build_model(&models[i]);
    *state = models;
    return 0;
}

static int teardown(void **state)
{
    model *models = *state;
    for (int i = 0; i < MODEL_COUNT; i++) free_model(&models[i]);
    free(models);
    return 0;
}

/* ---- triangle sets ---------------------------------------------------------- */

static int compare_triangles(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int i = 0; i < 3; i++)
        if (x[i] != y[i]) return x[i] < y[i] ? -1 : 1;
    return 0;
}

/* Sorted oriented triangles (each rotated to start at its smallest vertex),
 * optionally through a vertex map. Caller frees. */
static uint32_t *canonical(const uint32_t *indices, size_t count, const uint32_t *map)
{
    uint32_t *out = malloc((count ? count : 1) * 3 * sizeof *out);
    assert_non_null(out);
    for (size_t t = 0; t < count; t++) {
        uint32_t v[3];
        for (int k = 0; k < 3; k++) v[k] = map ? map[indices[3 * t + (size_t)k]] : indices[3 * t + (size_t)k];
        int first = v[0] <= v[1] && v[0] <= v[2] ? 0 : v[1] <= v[2] ? 1 : 2;
        for (int k = 0; k < 3; k++) out[3 * t + (size_t)k] = v[(first + k) % 3];
    }
    qsort(out, count, 3 * sizeof *out, compare_triangles);
    return out;
}

static void assert_same_triangles(const uint32_t *a, size_t a_count, const uint32_t *a_map, const uint32_t *b,
                                  size_t b_count, const char *what)
{
    if (a_count != b_count) fail_msg("%s: %zu triangles vs %zu", what, a_count, b_count);
    uint32_t *x = canonical(a, a_count, a_map), *y = canonical(b, b_count, NULL);
    for (size_t t = 0; t < a_count; t++)
        if (compare_triangles(x + 3 * t, y + 3 * t) != 0) fail_msg("%s: oriented triangle %zu differs", what, t);
    free(x);
    free(y);
}

static void pm_level(const lk_progressive_mesh *pm, size_t level, lk_mesh *out)
{
    lk_error error = {0};
    if (lk_progressive_mesh_level(pm, level, out, &error) != LK_OK) fail_msg("pm level: %s", error.message);
}

/* ---- progressive meshes ------------------------------------------------------- */

/* Base at 5% of the triangles; the full level is the input exactly
 * (triangles through vertex_order, positions bit for bit); the triangle
 * count grows by the splits' counts; every level is a manifold with the
 * input's genus, parts and (for the cylinder) border loops. */
static void test_levels(void **state)
{
    model *models = *state;
    for (int i = 0; i < MODEL_COUNT; i++) {
        model *m = &models[i];
        const lk_progressive_mesh *pm = &m->pm;
        assert_int_equal(pm->vertex_count, m->mesh.vertex_count);
        assert_int_equal(pm->triangle_count, m->mesh.triangle_count);
        assert_int_equal(pm->split_count, pm->vertex_count - pm->base_vertex_count);
        assert_true(pm->base_triangle_count <= m->mesh.triangle_count / 20 + 2);
        lk_mesh_stats input = shape_stats(&m->mesh);

        lk_mesh full;
        pm_level(pm, pm->split_count, &full);
        assert_same_triangles(full.indices, full.triangle_count, pm->vertex_order, m->mesh.indices,
                              m->mesh.triangle_count, m->name);
        for (size_t v = 0; v < full.vertex_count; v++)
            assert_memory_equal(full.positions + 3 * v, m->mesh.positions + 3 * pm->vertex_order[v], 3 * sizeof(float));
        lk_mesh_free(&full);

        size_t triangles = pm->base_triangle_count;
        for (size_t k = 0; k < pm->split_count; k++) {
            assert_int_equal(pm->splits[k].first_triangle, triangles);
            assert_true(pm->splits[k].triangle_count == 1 || pm->splits[k].triangle_count == 2);
            assert_true(pm->splits[k].kept < pm->base_vertex_count + k);
            triangles += pm->splits[k].triangle_count;
        }
        assert_int_equal(triangles, pm->triangle_count);

        for (size_t level = 0; level <= pm->split_count; level += pm->split_count / 7 + 1) {
            lk_mesh mesh;
            pm_level(pm, level, &mesh);
            assert_int_equal(mesh.vertex_count, pm->base_vertex_count + level);
            assert_int_equal(mesh.triangle_count, lk_progressive_mesh_level_triangles(pm, level));
            lk_mesh_stats s = shape_stats(&mesh);
            if (s.genus != m->genus || s.component_count != m->components || s.nonmanifold_edge_count ||
                s.boundary_loop_count != input.boundary_loop_count || s.degenerate_triangle_count)
                fail_msg("%s level %zu: genus %lld, %zu parts, %zu loops, %zu non-manifold edges", m->name, level,
                         s.genus, s.component_count, s.boundary_loop_count, s.nonmanifold_edge_count);
            lk_mesh_free(&mesh);
        }
    }
}

/* The sphere's base is within the QEM bound of test_core_qem (2
 * sagittas of its triangle count; measured 1.33), and the collapses were
 * made cheapest first, so the first split (the last collapse) carries a
 * larger error than any split of the second half of the refinement. */
static void test_base_quality(void **state)
{
    model *models = *state;
    const lk_progressive_mesh *pm = &models[SPHERE].pm;
    lk_mesh base;
    pm_level(pm, 0, &base);
    lk_metro_result metro = shape_metro(&models[SPHERE].mesh, &base, 10);
    double area = 4 * SHAPE_PI / (double)base.triangle_count, side = sqrt(4 * area / sqrt(3.0));
    double sagitta = 1 - sqrt(1 - side * side / 3);
    print_message("sphere base: %zu triangles, Hausdorff %.3f (%.2f sagittas)\n", base.triangle_count, metro.hausdorff,
                  metro.hausdorff / sagitta);
    assert_true(metro.hausdorff < 2 * sagitta);
    lk_mesh_free(&base);
    float largest_late = 0;
    for (size_t k = pm->split_count / 2; k < pm->split_count; k++)
        largest_late = fmaxf(largest_late, pm->splits[k].error);
    assert_true(pm->splits[0].error >= largest_late);
}

/* ---- strips ---------------------------------------------------------------------- */

/* One strip per shape draws exactly its triangles, each once and in the
 * same orientation, with fewer than 1.5 indices per triangle (measured
 * 1.04 to 1.13 for lodkit's stripifier, 1.04 to 1.21 for meshoptimizer's
 * on these grids; strips of two triangles joined by degenerate ones would
 * need 3), and the DTFS filter keeps them. */
static void test_stripify(void **state)
{
    model *models = *state;
    for (int i = 0; i < MODEL_COUNT; i++) {
        const lk_mesh *mesh = &models[i].mesh;
        for (int method = LK_STRIPIFY_BEST; method <= LK_STRIPIFY_MESHOPT; method++) {
            uint32_t *strip = NULL;
            size_t length = 0;
            lk_error error = {0};
            lk_status status = lk_stripify(mesh->indices, mesh->triangle_count, mesh->vertex_count,
                                           (lk_stripifier)method, &strip, &length, NULL, &error);
            /* meshoptimizer's stripifier is optional in a core-only build. */
            if (method == LK_STRIPIFY_MESHOPT && status == LK_ERR_UNSUPPORTED) continue;
            if (status != LK_OK) fail_msg("%s: stripify: %s", models[i].name, error.message);
            uint32_t *triangles = malloc(3 * length * sizeof *triangles);
            assert_non_null(triangles);
            size_t drawn = lk_strip_triangles(strip, length, triangles);
            assert_same_triangles(triangles, drawn, NULL, mesh->indices, mesh->triangle_count, models[i].name);
            double per_triangle = (double)length / (double)mesh->triangle_count;
            print_message("%-16s strip (%s): %.2f indices per triangle\n", models[i].name,
                          method == LK_STRIPIFY_BEST     ? "best"
                          : method == LK_STRIPIFY_LODKIT ? "lodkit"
                                                         : "meshopt",
                          per_triangle);
            assert_true(per_triangle < 1.5);
            uint32_t *filtered = malloc(lk_strip_filter_bound(length) * sizeof *filtered);
            assert_non_null(filtered);
            size_t filtered_length = lk_strip_filter(strip, length, filtered);
            drawn = lk_strip_triangles(filtered, filtered_length, triangles);
            assert_same_triangles(triangles, drawn, NULL, mesh->indices, mesh->triangle_count, "filtered");
            free(filtered);
            free(triangles);
            lk_free(strip);
        }
    }
}

/* The progressive strip at a level draws the progressive mesh's level. */
static void test_progressive_strips(void **state)
{
    model *models = *state;
    for (int i = 0; i < MODEL_COUNT; i++) {
        const model *m = &models[i];
        uint32_t *strip = malloc(m->ps.strip_length * sizeof *strip);
        uint32_t *triangles = malloc(3 * m->ps.strip_length * sizeof *triangles);
        assert_true(strip && triangles);
        for (size_t level = 0; level <= m->pm.split_count; level += m->pm.split_count / 5 + 1) {
            lk_error error = {0};
            assert_int_equal(lk_progressive_strips_level(&m->ps, &m->pm, level, strip, &error), LK_OK);
            size_t drawn = lk_strip_triangles(strip, m->ps.strip_length, triangles);
            lk_mesh mesh;
            pm_level(&m->pm, level, &mesh);
            assert_same_triangles(triangles, drawn, NULL, mesh.indices, mesh.triangle_count, m->name);
            lk_mesh_free(&mesh);
        }
        free(strip);
        free(triangles);
    }
}

/* ---- stream ------------------------------------------------------------------------ */

static void encode_ok(const model *m, size_t splits_per_chunk, unsigned char **bytes, size_t *size)
{
    lk_stream_options options;
    lk_stream_options_default(&options);
    options.splits_per_chunk = splits_per_chunk;
    lk_error error = {0};
    if (lk_stream_encode(&m->pm, &m->ps, &options, bytes, size, &error) != LK_OK)
        fail_msg("%s: encode: %s", m->name, error.message);
}

static lk_stream_decoder *decoder_new(void)
{
    lk_stream_decoder *decoder = NULL;
    lk_error error = {0};
    if (lk_stream_decoder_create(SIZE_MAX, &decoder, &error) != LK_OK) fail_msg("decoder: %s", error.message);
    return decoder;
}

/* The decoder's mesh equals the progressive mesh at its level: the same
 * oriented triangles, positions within the quantisation bound. Returns
 * the largest position error. */
static double assert_decoder_at_level(const lk_stream_decoder *decoder, const model *m)
{
    size_t level = lk_stream_decoder_level(decoder);
    const lk_stream_info *info = lk_stream_decoder_info(decoder);
    lk_mesh decoded, reference;
    lk_error error = {0};
    assert_int_equal(lk_stream_decoder_mesh(decoder, &decoded, &error), LK_OK);
    pm_level(&m->pm, level, &reference);
    assert_int_equal(decoded.vertex_count, reference.vertex_count);
    assert_same_triangles(decoded.indices, decoded.triangle_count, NULL, reference.indices, reference.triangle_count,
                          m->name);
    double worst = 0;
    for (size_t v = 0; v < decoded.vertex_count; v++) {
        const float *p = decoded.positions + 3 * v, *q = reference.positions + 3 * v;
        double d = sqrt(pow((double)p[0] - q[0], 2) + pow((double)p[1] - q[1], 2) + pow((double)p[2] - q[2], 2));
        if (d > info->quantisation_error * (1 + 1e-9)) fail_msg("%s vertex %zu off by %g", m->name, v, d);
        worst = fmax(worst, d);
    }
    lk_mesh_free(&decoded);
    lk_mesh_free(&reference);
    return worst;
}

/* Encode with 64 splits per chunk (several chunks even on small shapes),
 * feed chunk by chunk: after each chunk the decoder holds the table's
 * level and equals the progressive mesh there; at the end the input's
 * triangles come back exactly and every position within the quantisation
 * bound, which the default bits keep under 0.01% of the diagonal. */
static void test_stream_round_trip(void **state)
{
    model *models = *state;
    for (int i = 0; i < MODEL_COUNT; i++) {
        const model *m = &models[i];
        unsigned char *bytes;
        size_t size;
        encode_ok(m, 64, &bytes, &size);
        lk_stream_info info;
        lk_stream_chunk_info *chunks;
        lk_error error = {0};
        assert_int_equal(lk_stream_inspect(bytes, size, &info, &chunks, &error), LK_OK);
        assert_int_equal(info.chunk_count, 1 + (m->pm.split_count + 63) / 64);
        assert_int_equal(info.vertex_count, m->mesh.vertex_count);
        assert_true(info.quantisation_error <= 1e-4 * info.diagonal);

        lk_stream_decoder *decoder = decoder_new();
        assert_int_equal(lk_stream_decoder_feed(decoder, bytes, info.header_size, &error), LK_OK);
        double worst = 0;
        for (size_t c = 0; c < info.chunk_count; c++) {
            assert_int_equal(lk_stream_decoder_feed(decoder, bytes + chunks[c].offset, chunks[c].size, &error), LK_OK);
            assert_int_equal(lk_stream_decoder_level(decoder), chunks[c].first_split + chunks[c].split_count);
            worst = fmax(worst, assert_decoder_at_level(decoder, m));
        }
        assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_OK);
        assert_int_equal(lk_stream_decoder_level(decoder), m->pm.split_count);

        lk_mesh decoded;
        assert_int_equal(lk_stream_decoder_mesh(decoder, &decoded, &error), LK_OK);
        assert_same_triangles(decoded.indices, decoded.triangle_count, m->pm.vertex_order, m->mesh.indices,
                              m->mesh.triangle_count, m->name);
        for (size_t v = 0; v < decoded.vertex_count; v++) {
            const float *p = decoded.positions + 3 * v, *q = m->mesh.positions + 3 * m->pm.vertex_order[v];
            for (int k = 0; k < 3; k++) assert_true(fabs((double)p[k] - q[k]) <= info.quantisation_error * (1 + 1e-9));
        }
        print_message("%-16s %zu bytes, %zu chunks, %u bits, position error <= %.2g of the diagonal (bound %.2g)\n",
                      m->name, size, info.chunk_count, info.position_bits, worst / info.diagonal,
                      info.quantisation_error / info.diagonal);
        lk_mesh_free(&decoded);
        lk_stream_decoder_free(decoder);
        lk_free(chunks);
        lk_free(bytes);
    }
}

/* Cut inside chunk 2: the decoder stops at chunk 1's level (the PM level
 * there, usable) and finish says where; a flipped payload byte in chunk 2
 * is refused by its CRC with the level of chunk 1 kept. */
static void test_truncated_and_corrupt(void **state)
{
    model *models = *state;
    const model *m = &models[TORUS];
    unsigned char *bytes;
    size_t size;
    encode_ok(m, 64, &bytes, &size);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    lk_error error = {0};
    assert_int_equal(lk_stream_inspect(bytes, size, &info, &chunks, &error), LK_OK);
    assert_true(info.chunk_count >= 4);
    size_t level_after_1 = chunks[1].first_split + chunks[1].split_count;

    size_t cut = (size_t)chunks[2].offset + chunks[2].size / 2;
    lk_stream_decoder *decoder = decoder_new();
    assert_int_equal(lk_stream_decoder_feed(decoder, bytes, cut, &error), LK_OK);
    assert_int_equal(lk_stream_decoder_finish(decoder, &error), LK_ERR_TRUNCATED);
    char needle[96];
    snprintf(needle, sizeof needle, "stopped at byte %zu in chunk 2 of %zu", cut, info.chunk_count);
    lk_assert_message_contains(error, needle);
    assert_int_equal(lk_stream_decoder_level(decoder), level_after_1);
    assert_decoder_at_level(decoder, m);
    lk_stream_decoder_free(decoder);

    unsigned char *corrupt = malloc(size);
    assert_non_null(corrupt);
    memcpy(corrupt, bytes, size);
    corrupt[chunks[2].offset + 8 + (chunks[2].size - 8) / 2] ^= 0x01;
    decoder = decoder_new();
    lk_error_clear(&error);
    assert_int_equal(lk_stream_decoder_feed(decoder, corrupt, size, &error), LK_ERR_PARSE);
    lk_assert_message_contains(error, "CRC");
    lk_assert_message_contains(error, "chunk 2");
    assert_int_equal(lk_stream_decoder_level(decoder), level_after_1);
    assert_decoder_at_level(decoder, m);
    lk_stream_decoder_free(decoder);
    lk_stream_chunk_info *inspected = NULL;
    assert_int_equal(lk_stream_inspect(corrupt, size, &info, &inspected, &error), LK_ERR_PARSE);
    lk_free(inspected);
    free(corrupt);
    lk_free(chunks);
    lk_free(bytes);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_levels),
        cmocka_unit_test(test_base_quality),
        cmocka_unit_test(test_stripify),
        cmocka_unit_test(test_progressive_strips),
        cmocka_unit_test(test_stream_round_trip),
        cmocka_unit_test(test_truncated_and_corrupt),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
