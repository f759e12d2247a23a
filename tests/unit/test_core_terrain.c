/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: terrain continuous LOD (src/terrain.c) on a
 * procedural 257 x 257 heightfield (shapes.c: ridges and five octaves of
 * value noise, ~2 km of relief, 30 m spacing). Over a 30-frame flight the
 * full crack rules leave no crack while the per-leaf rules do, geomorphing
 * cuts popping, the leaves tile the grid with neighbours at most one level
 * apart, and the triangle count falls with distance and rises with the
 * resolution C. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

enum { SIZE = 257, FRAMES = 30, PROBES = 100 /* not a divisor of 256: probes fall between grid points */ };

static int setup(void **state)
{
    lk_heightfield *field = malloc(sizeof *field);
    if (!field) return -1;
    shape_heightfield(field, SIZE, 30, 2000);
    *state = field;
    return 0;
}

static int teardown(void **state)
{
    shape_heightfield_free(*state);
    free(*state);
    return 0;
}

static lk_terrain *make_terrain(const lk_heightfield *field, lk_terrain_cracks cracks, int morph, int culling,
                                double resolution)
{
    lk_terrain_options options;
    lk_terrain_options_default(&options);
    options.cracks = cracks;
    options.morph = morph;
    options.culling = culling;
    if (resolution > 0) options.resolution = resolution;
    lk_terrain *terrain = NULL;
    lk_error error = {0};
    if (lk_terrain_create(field, &options, &terrain, &error) != LK_OK) fail_msg("lk_terrain_create: %s", error.message);
    return terrain;
}

static void update(lk_terrain *terrain, const lk_terrain_view *view, lk_mesh *mesh, lk_terrain_stats *stats)
{
    lk_error error = {0};
    if (lk_terrain_update(terrain, view, mesh, stats, &error) != LK_OK)
        fail_msg("lk_terrain_update: %s", error.message);
}

typedef struct flight_result {
    size_t cracks, crack_frames;
    double popping; /* metres, largest change between frames */
} flight_result;

static flight_result fly(const lk_heightfield *field, lk_terrain_cracks cracks, int morph)
{
    lk_terrain *terrain = make_terrain(field, cracks, morph, 1, 0);
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    float *before = malloc(PROBES * PROBES * sizeof *before), *now = malloc(PROBES * PROBES * sizeof *now);
    assert_true(before && now);
    flight_result result = {0};
    lk_error error = {0};
    for (size_t frame = 0; frame < FRAMES; frame++) {
        lk_terrain_view view;
        lk_terrain_flight(terrain, frame, 0, &view);
        update(terrain, &view, &mesh, NULL);
        lk_terrain_crack_stats counted;
        assert_int_equal(lk_terrain_count_cracks(terrain, &mesh, 0, &counted, &error), LK_OK);
        result.cracks += counted.cracks;
        result.crack_frames += counted.cracks > 0;
        assert_int_equal(lk_terrain_sample_surface(terrain, &mesh, PROBES, now, &error), LK_OK);
        if (frame > 0) {
            lk_terrain_popping popping;
            lk_terrain_measure_popping(terrain, &view, before, now, PROBES, &popping);
            assert_true(popping.probes > 100);
            result.popping = fmax(result.popping, popping.max_metres);
        }
        float *swap = before;
        before = now;
        now = swap;
    }
    free(before);
    free(now);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
    return result;
}

/* Measured over 30 frames: full rules 0 cracks; per-leaf morphing ("none")
 * 31,440, on every frame; Röttger's midpoint rule fewer (1,397). Popping:
 * 0.04 m with morphing, 3.79 m without (bound: 10 times less). */
static void test_no_cracks_with_the_full_rules(void **state)
{
    const lk_heightfield *field = *state;
    flight_result full = fly(field, LK_TERRAIN_CRACKS_FULL, 1);
    flight_result none = fly(field, LK_TERRAIN_CRACKS_NONE, 1);
    flight_result midpoint = fly(field, LK_TERRAIN_CRACKS_MIDPOINT, 1);
    flight_result still = fly(field, LK_TERRAIN_CRACKS_FULL, 0);
    print_message("%d frames: cracks full %zu, none %zu (%zu frames), midpoint %zu; popping %.2f m morphing, %.2f m "
                  "not\n",
                  FRAMES, full.cracks, none.cracks, none.crack_frames, midpoint.cracks, full.popping, still.popping);
    assert_int_equal(full.cracks, 0);
    assert_int_equal(none.crack_frames, FRAMES);
    assert_true(midpoint.cracks > 0 && midpoint.cracks < none.cracks);
    assert_int_equal(still.cracks, 0); /* true heights everywhere: nothing to crack */
    assert_true(still.popping > 1 && still.popping > 10 * full.popping);
}

/* Paints every grid cell with the level of the leaf covering it: each cell
 * exactly once, and leaves sharing an edge at most one level apart (the
 * d2 propagation's guarantee). */
static void assert_restricted_quadtree(const lk_terrain *terrain)
{
    size_t cells = SIZE - 1, count = 0;
    unsigned char *level = malloc(cells * cells);
    assert_non_null(level);
    memset(level, 0xff, cells * cells);
    const lk_terrain_leaf *leaves = lk_terrain_leaves(terrain, &count);
    for (size_t k = 0; k < count; k++)
        for (uint32_t y = leaves[k].y; y < leaves[k].y + leaves[k].size; y++)
            for (uint32_t x = leaves[k].x; x < leaves[k].x + leaves[k].size; x++) {
                if (level[y * cells + x] != 0xff) fail_msg("cell %u,%u in two leaves", x, y);
                level[y * cells + x] = (unsigned char)leaves[k].level;
            }
    for (size_t y = 0; y < cells; y++)
        for (size_t x = 0; x < cells; x++) {
            int here = level[y * cells + x];
            if (here == 0xff) fail_msg("cell %zu,%zu not covered", x, y);
            if (x + 1 < cells) assert_true(abs(here - level[y * cells + x + 1]) <= 1);
            if (y + 1 < cells) assert_true(abs(here - level[(y + 1) * cells + x]) <= 1);
        }
    free(level);
}

/* From 500 m to 64 km away (no culling), the triangle count never grows
 * (measured 63,660 down to 904) and the leaves always tile the grid as a
 * restricted quadtree; the fans cover the grid's area exactly with every
 * triangle facing up, and every vertex's height lies within the field's. */
static void test_detail_falls_with_distance(void **state)
{
    const lk_heightfield *field = *state;
    lk_terrain *terrain = make_terrain(field, LK_TERRAIN_CRACKS_FULL, 1, 0, 0);
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    size_t previous = SIZE_MAX;
    double centre = 128 * 30.0, extent = 256 * 30.0;
    for (double distance = 500; distance <= 64000; distance *= 2) {
        lk_terrain_view view = {{centre + distance, centre, 2500}, {centre, centre, 0}, 60, 4.0 / 3, 768};
        lk_terrain_stats stats;
        update(terrain, &view, &mesh, &stats);
        print_message("%6.0f m: %6zu triangles, deepest level %u\n", distance, stats.triangles, stats.max_level);
        assert_true(stats.triangles <= previous);
        previous = stats.triangles;
        assert_int_equal(stats.restriction_violations, 0);
        assert_restricted_quadtree(terrain);
        double area = 0;
        for (size_t t = 0; t < mesh.triangle_count; t++) {
            const float *a = mesh.positions + 3 * mesh.indices[3 * t],
                        *b = mesh.positions + 3 * mesh.indices[3 * t + 1],
                        *c = mesh.positions + 3 * mesh.indices[3 * t + 2];
            double cross =
                ((double)b[0] - a[0]) * ((double)c[1] - a[1]) - ((double)c[0] - a[0]) * ((double)b[1] - a[1]);
            assert_true(cross > 0);
            area += cross / 2;
        }
        assert_true(fabs(area - extent * extent) < 1e-6 * extent * extent);
        for (size_t v = 0; v < mesh.vertex_count; v++) {
            float z = mesh.positions[3 * v + 2];
            assert_true(z >= field->min_height - 1e-3 && z <= field->max_height + 1e-3);
        }
    }
    assert_true(previous < 2000);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
}

/* A larger minimum global resolution C gives more triangles for the same
 * view (measured 4,430 / 14,304 / 36,292 / 72,778 for C = 2, 4, 8, 16). */
static void test_detail_rises_with_resolution(void **state)
{
    const lk_heightfield *field = *state;
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    size_t previous = 0;
    for (double resolution = 2; resolution <= 16; resolution *= 2) {
        lk_terrain *terrain = make_terrain(field, LK_TERRAIN_CRACKS_FULL, 1, 0, resolution);
        lk_terrain_view view = {{3840, -2000, 3000}, {3840, 3840, 0}, 60, 4.0 / 3, 768};
        lk_terrain_stats stats;
        update(terrain, &view, &mesh, &stats);
        assert_true(stats.triangles > previous);
        previous = stats.triangles;
        lk_terrain_free(terrain);
    }
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_no_cracks_with_the_full_rules),
        cmocka_unit_test(test_detail_falls_with_distance),
        cmocka_unit_test(test_detail_rises_with_resolution),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
