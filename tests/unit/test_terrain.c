/* SPDX-License-Identifier: MIT */
/* Terrain continuous LOD (src/terrain.c): the restricted quadtree, fan
 * coverage, crack elimination and geomorphing on etopo20 (resampled to
 * 1025^2, the acceptance grid of issue 8) and on a procedural fractal, and
 * the refusals. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

typedef struct flight_result {
    int done;
    size_t crack_max, crack_total;
    double max_gap;
    double popping_max; /* metres */
    size_t triangles_min, triangles_max;
} flight_result;

typedef struct fixture {
    lk_heightfield etopo;      /* etopo20.cdf resampled to 1025 x 1025 */
    lk_heightfield fractal;    /* 257 x 257 value-noise fractal, 30 m spacing */
    lk_heightfield fractal513; /* the same noise on 513 x 513 samples */
    /* flights, flown once: [etopo, fractal513][crack mode][morph] */
    flight_result flights[2][4][2];
} fixture;

/* The library's synthetic terrain (lk_heightfield_fractal). */
static void make_fractal(lk_heightfield *field, size_t size, double spacing)
{
    lk_error error = {0};
    if (lk_heightfield_fractal(size, spacing, field, &error) != LK_OK) fail_msg("%s", error.message);
}

static uint64_t mix64(uint64_t x)
{
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f) return -1;
    lk_heightfield raw;
    lk_error error = {0};
    if (lk_dem_read(lk_test_sample("etopo20.cdf"), NULL, &raw, &error) != LK_OK) {
        fprintf(stderr, "etopo20.cdf: %s\n", error.message);
        free(f);
        return -1;
    }
    lk_status status = lk_heightfield_resample(&raw, 1025, &f->etopo, &error);
    lk_heightfield_free(&raw);
    if (status != LK_OK) {
        fprintf(stderr, "resampling etopo20: %s\n", error.message);
        free(f);
        return -1;
    }
    make_fractal(&f->fractal, 257, 30.0);
    make_fractal(&f->fractal513, 513, 30.0);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    lk_heightfield_free(&f->etopo);
    free(f->fractal.heights);
    free(f->fractal513.heights);
    free(f);
    return 0;
}

static lk_terrain *make_terrain(const lk_heightfield *field, lk_terrain_cracks cracks, int morph, int culling)
{
    lk_terrain_options options;
    lk_terrain_options_default(&options);
    options.cracks = cracks;
    options.morph = morph;
    options.culling = culling;
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

/* Independent check of the restricted quadtree: paint every grid cell with
 * the level of the leaf covering it, then compare cells across every leaf
 * edge. Returns the largest level difference of edge neighbours; *covered
 * counts cells painted (each exactly once or the test fails). */
static unsigned largest_level_jump(const lk_terrain *terrain, size_t size, size_t *covered)
{
    size_t cells = size - 1;
    unsigned char *level = malloc(cells * cells);
    assert_non_null(level);
    memset(level, 0xff, cells * cells);
    size_t count = 0;
    const lk_terrain_leaf *leaves = lk_terrain_leaves(terrain, &count);
    *covered = 0;
    for (size_t k = 0; k < count; k++)
        for (uint32_t y = leaves[k].y; y < leaves[k].y + leaves[k].size; y++)
            for (uint32_t x = leaves[k].x; x < leaves[k].x + leaves[k].size; x++) {
                if (level[y * cells + x] != 0xff) fail_msg("cell %u,%u covered by two leaves", x, y);
                level[y * cells + x] = (unsigned char)leaves[k].level;
                (*covered)++;
            }
    unsigned jump = 0;
    for (size_t y = 0; y < cells; y++)
        for (size_t x = 0; x < cells; x++) {
            unsigned here = level[y * cells + x];
            if (here == 0xff) continue;
            if (x + 1 < cells && level[y * cells + x + 1] != 0xff) {
                unsigned there = level[y * cells + x + 1];
                unsigned d = here > there ? here - there : there - here;
                jump = d > jump ? d : jump;
            }
            if (y + 1 < cells && level[(y + 1) * cells + x] != 0xff) {
                unsigned there = level[(y + 1) * cells + x];
                unsigned d = here > there ? here - there : there - here;
                jump = d > jump ? d : jump;
            }
        }
    free(level);
    return jump;
}

/* d2 propagation: edge neighbours differ by at most one level on every
 * frame of the flight and from 200 arbitrary viewpoints (low and high,
 * every direction), with and without culling. */
static void test_neighbours_differ_by_one_level(void **state)
{
    fixture *f = *state;
    for (int culling = 0; culling <= 1; culling++) {
        lk_terrain *terrain = make_terrain(&f->fractal, LK_TERRAIN_CRACKS_FULL, 1, culling);
        lk_mesh mesh;
        lk_mesh_init(&mesh);
        unsigned deepest = 0;
        for (size_t frame = 0; frame < 160; frame++) {
            lk_terrain_view view;
            lk_terrain_flight(terrain, frame, 2.0, &view);
            if (frame >= 60) {
                /* arbitrary viewpoints: anywhere over the grid, 1 to 200 spacings above the top */
                uint64_t seed = mix64(frame);
                double u = (double)((seed >> 11) & 0xffff) / 65535.0, v = (double)((seed >> 27) & 0xffff) / 65535.0;
                double w = (double)((seed >> 43) & 0xffff) / 65535.0;
                view.eye[0] = u * 256 * 30.0;
                view.eye[1] = v * 256 * 30.0;
                view.eye[2] = 2000 + 30.0 * (1 + 199 * w * w);
                double heading = 6.283185307 * w * 7;
                view.target[0] = view.eye[0] + cos(heading);
                view.target[1] = view.eye[1] + sin(heading);
                view.target[2] = view.eye[2] - 0.3 - 2 * u;
            }
            lk_terrain_stats stats;
            update(terrain, &view, &mesh, &stats);
            assert_int_equal(stats.restriction_violations, 0);
            size_t covered = 0;
            unsigned jump = largest_level_jump(terrain, f->fractal.width, &covered);
            if (jump > 1) fail_msg("frame %zu: neighbouring leaves %u levels apart", frame, jump);
            if (!culling) assert_int_equal(covered, 256 * 256);
            deepest = stats.max_level > deepest ? stats.max_level : deepest;
        }
        /* the flight must reach the finest level (half size 1) or the check says little */
        assert_int_equal(deepest, 7);
        lk_mesh_free(&mesh);
        lk_terrain_free(terrain);
    }
}

/* Without culling the fans tile the grid: the triangles' xy areas add up to
 * the extent, no triangle is flipped, and each leaf has 4 + (midpoints) triangles. */
static void test_fans_cover_the_grid(void **state)
{
    fixture *f = *state;
    lk_terrain *terrain = make_terrain(&f->etopo, LK_TERRAIN_CRACKS_FULL, 1, 0);
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_terrain_info info;
    lk_terrain_get_info(terrain, &info);
    assert_int_equal(info.size, 1025);
    assert_int_equal(info.levels, 10);
    double extent = 1024.0 * info.spacing_x * 1024.0 * info.spacing_y;
    for (size_t frame = 0; frame < 500; frame += 50) {
        lk_terrain_view view;
        lk_terrain_flight(terrain, frame, 0, &view);
        lk_terrain_stats stats;
        update(terrain, &view, &mesh, &stats);
        lk_error error = {0};
        assert_int_equal(lk_mesh_validate(&mesh, &error), LK_OK);
        assert_int_equal(stats.nodes_culled, 0);
        assert_true(stats.triangles >= 4 * stats.leaves && stats.triangles <= 8 * stats.leaves);
        assert_int_equal(mesh.triangle_count, stats.triangles);
        double area = 0;
        size_t flipped = 0;
        for (size_t t = 0; t < mesh.triangle_count; t++) {
            const float *a = mesh.positions + 3 * mesh.indices[3 * t];
            const float *b = mesh.positions + 3 * mesh.indices[3 * t + 1];
            const float *c = mesh.positions + 3 * mesh.indices[3 * t + 2];
            /* relative to the first vertex: positions are millions of metres from the origin */
            double cross =
                ((double)b[0] - a[0]) * ((double)c[1] - a[1]) - ((double)c[0] - a[0]) * ((double)b[1] - a[1]);
            if (cross <= 0) flipped++;
            area += 0.5 * cross;
        }
        assert_int_equal(flipped, 0);
        assert_true(fabs(area - extent) < 1e-5 * extent);
        size_t covered = 0;
        assert_true(largest_level_jump(terrain, 1025, &covered) <= 1);
        assert_int_equal(covered, 1024 * 1024);
    }
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
}

static flight_result fly(const lk_heightfield *field, lk_terrain_cracks cracks, int morph, size_t frames)
{
    lk_terrain *terrain = make_terrain(field, cracks, morph, 1);
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    enum { PROBES = 257 };
    float *before = malloc(PROBES * PROBES * sizeof *before), *now = malloc(PROBES * PROBES * sizeof *now);
    assert_non_null(before);
    assert_non_null(now);
    flight_result result = {0};
    result.triangles_min = SIZE_MAX;
    lk_error error = {0};
    for (size_t frame = 0; frame < frames; frame++) {
        lk_terrain_view view;
        lk_terrain_flight(terrain, frame, 0, &view);
        lk_terrain_stats stats;
        update(terrain, &view, &mesh, &stats);
        lk_terrain_crack_stats cracks_now;
        assert_int_equal(lk_terrain_count_cracks(terrain, &mesh, 0, &cracks_now, &error), LK_OK);
        result.crack_total += cracks_now.cracks;
        if (cracks_now.cracks > result.crack_max) result.crack_max = cracks_now.cracks;
        if (cracks_now.max_gap > result.max_gap) result.max_gap = cracks_now.max_gap;
        if (stats.triangles < result.triangles_min) result.triangles_min = stats.triangles;
        if (stats.triangles > result.triangles_max) result.triangles_max = stats.triangles;
        assert_int_equal(lk_terrain_sample_surface(terrain, &mesh, PROBES, now, &error), LK_OK);
        if (frame > 0) {
            lk_terrain_popping popping;
            lk_terrain_measure_popping(terrain, &view, before, now, PROBES, &popping);
            assert_true(popping.probes > 1000);
            if (popping.max_metres > result.popping_max) result.popping_max = popping.max_metres;
        }
        float *swap = before;
        before = now;
        now = swap;
    }
    free(before);
    free(now);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
    result.done = 1;
    return result;
}

/* The 100-frame flight over etopo20 (which 0) or 50 frames over the 513^2 fractal (1). */
static flight_result flight(fixture *f, int which, lk_terrain_cracks cracks, int morph)
{
    flight_result *cached = &f->flights[which][cracks][morph ? 1 : 0];
    if (!cached->done) *cached = fly(which == 0 ? &f->etopo : &f->fractal513, cracks, morph, which == 0 ? 100 : 50);
    return *cached;
}

/* Acceptance on etopo20 (100 frames here, 500 in the bench): no crack with
 * the full rules on any frame; the paper's "before" states crack. */
static void test_full_rules_leave_no_crack_on_etopo(void **state)
{
    fixture *f = *state;
    flight_result full = flight(f, 0, LK_TERRAIN_CRACKS_FULL, 1);
    flight_result none = flight(f, 0, LK_TERRAIN_CRACKS_NONE, 1);
    flight_result midpoint = flight(f, 0, LK_TERRAIN_CRACKS_MIDPOINT, 1);
    print_message("etopo20 1025^2, 100 frames: triangles %zu..%zu; cracks max/total: none %zu/%zu (gap %.1f m), "
                  "midpoint %zu/%zu (gap %.1f m), full %zu/%zu\n",
                  full.triangles_min, full.triangles_max, none.crack_max, none.crack_total, none.max_gap,
                  midpoint.crack_max, midpoint.crack_total, midpoint.max_gap, full.crack_max, full.crack_total);
    assert_int_equal(full.crack_total, 0);
    assert_true(full.max_gap == 0);
    assert_true(none.crack_max > 0 && none.max_gap > 1.0);
    assert_true(midpoint.crack_max > 0);
    /* Röttger's rule removes most of them */
    assert_true(midpoint.crack_total < none.crack_total);
    /* the defaults give the paper's ~10K triangles a frame on etopo20 */
    assert_true(full.triangles_min > 5000 && full.triangles_max < 15000);
}

/* The same on the fractal, whose rough, deep hierarchy also shows that the
 * paper's corner rules taken literally (parent edge midpoints only) leave
 * cracks where a corner lies on a grandparent's edge midpoint. */
static void test_full_rules_leave_no_crack_on_fractal(void **state)
{
    fixture *f = *state;
    flight_result full = flight(f, 1, LK_TERRAIN_CRACKS_FULL, 1);
    flight_result paper = flight(f, 1, LK_TERRAIN_CRACKS_PAPER, 1);
    flight_result midpoint = flight(f, 1, LK_TERRAIN_CRACKS_MIDPOINT, 1);
    print_message(
        "fractal 513^2, 50 frames: cracks max/total: midpoint %zu/%zu, paper %zu/%zu (gap %.2f m), full %zu/%zu\n",
        midpoint.crack_max, midpoint.crack_total, paper.crack_max, paper.crack_total, paper.max_gap, full.crack_max,
        full.crack_total);
    assert_int_equal(full.crack_total, 0);
    assert_true(midpoint.crack_total > 0);
    assert_true(paper.crack_total > 0);
    assert_true(paper.crack_total < midpoint.crack_total);
}

/* Geomorphing makes the largest height change of the surface between two
 * frames at least 3x smaller than switching levels outright. */
static void test_morphing_reduces_popping(void **state)
{
    fixture *f = *state;
    flight_result morph = flight(f, 0, LK_TERRAIN_CRACKS_FULL, 1);
    flight_result no_morph = flight(f, 0, LK_TERRAIN_CRACKS_FULL, 0);
    print_message("etopo20 popping: morph %.2f m, no morph %.2f m (ratio %.1f)\n", morph.popping_max,
                  no_morph.popping_max, no_morph.popping_max / morph.popping_max);
    assert_true(no_morph.popping_max > 100.0);
    assert_true(no_morph.popping_max >= 3.0 * morph.popping_max);
    flight_result fractal_morph = flight(f, 1, LK_TERRAIN_CRACKS_FULL, 1);
    flight_result fractal_no_morph = flight(f, 1, LK_TERRAIN_CRACKS_FULL, 0);
    print_message("fractal popping: morph %.2f m, no morph %.2f m\n", fractal_morph.popping_max,
                  fractal_no_morph.popping_max);
    assert_true(fractal_no_morph.popping_max >= 3.0 * fractal_morph.popping_max);
}

/* Blend 1 everywhere is the unmorphed mesh, bit for bit, in every crack
 * mode; blend 0 everywhere (full rules) folds every point back onto the
 * coarser surface, all the way to the root's fan. */
static void test_blend_limits(void **state)
{
    fixture *f = *state;
    lk_error error = {0};
    for (int mode = LK_TERRAIN_CRACKS_NONE; mode <= LK_TERRAIN_CRACKS_FULL; mode++) {
        lk_terrain_options options;
        lk_terrain_options_default(&options);
        options.cracks = (lk_terrain_cracks)mode;
        options.morph = 0;
        lk_terrain *plain = NULL, *forced = NULL;
        assert_int_equal(lk_terrain_create(&f->fractal, &options, &plain, &error), LK_OK);
        options.morph = 1;
        options.blend_override = 1.0;
        assert_int_equal(lk_terrain_create(&f->fractal, &options, &forced, &error), LK_OK);
        lk_mesh a, b;
        lk_mesh_init(&a);
        lk_mesh_init(&b);
        for (size_t frame = 0; frame < 40; frame += 13) {
            lk_terrain_view view;
            lk_terrain_flight(plain, frame, 0, &view);
            update(plain, &view, &a, NULL);
            update(forced, &view, &b, NULL);
            assert_int_equal(a.vertex_count, b.vertex_count);
            assert_int_equal(a.triangle_count, b.triangle_count);
            assert_memory_equal(a.positions, b.positions, a.vertex_count * 3 * sizeof(float));
            assert_memory_equal(a.indices, b.indices, a.triangle_count * 3 * sizeof(uint32_t));
        }
        lk_mesh_free(&a);
        lk_mesh_free(&b);
        lk_terrain_free(plain);
        lk_terrain_free(forced);
    }

    lk_terrain_options options;
    lk_terrain_options_default(&options);
    options.blend_override = 0.0;
    options.culling = 0;
    lk_terrain *terrain = NULL;
    assert_int_equal(lk_terrain_create(&f->fractal, &options, &terrain, &error), LK_OK);
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_terrain_view view;
    lk_terrain_flight(terrain, 0, 0, &view);
    lk_terrain_stats stats;
    update(terrain, &view, &mesh, &stats);
    assert_true(stats.triangles > 1000); /* deeply refined, yet... */
    /* ...the surface is the root's fan of its 9 true heights */
    const float *h = f->fractal.heights;
    float root_positions[9 * 3];
    static const int grid[9][2] = {{0, 0},     {128, 0}, {256, 0}, {256, 128}, {256, 256},
                                   {128, 256}, {0, 256}, {0, 128}, {128, 128}};
    for (int k = 0; k < 9; k++) {
        root_positions[3 * k] = (float)(grid[k][0] * 30.0);
        root_positions[3 * k + 1] = (float)(grid[k][1] * 30.0);
        root_positions[3 * k + 2] = h[grid[k][1] * 257 + grid[k][0]];
    }
    uint32_t root_indices[8 * 3];
    for (uint32_t k = 0; k < 8; k++) {
        root_indices[3 * k] = 8;
        root_indices[3 * k + 1] = k;
        root_indices[3 * k + 2] = (k + 1) % 8;
    }
    lk_mesh root;
    lk_test_make_mesh(&root, root_positions, 9, root_indices, 8);
    enum { PROBES = 129 };
    float *expected = malloc(PROBES * PROBES * sizeof *expected), *got = malloc(PROBES * PROBES * sizeof *got);
    assert_non_null(expected);
    assert_non_null(got);
    assert_int_equal(lk_terrain_sample_surface(terrain, &root, PROBES, expected, &error), LK_OK);
    assert_int_equal(lk_terrain_sample_surface(terrain, &mesh, PROBES, got, &error), LK_OK);
    double worst = 0;
    for (size_t k = 0; k < PROBES * PROBES; k++) {
        assert_true(isfinite(expected[k]) && isfinite(got[k]));
        worst = fmax(worst, fabs((double)expected[k] - got[k]));
    }
    assert_true(worst < 0.01); /* metres, on 2 km of relief */
    /* and the real surface is far from it */
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
    options.blend_override = -1;
    assert_int_equal(lk_terrain_create(&f->fractal, &options, &terrain, &error), LK_OK);
    update(terrain, &view, &mesh, NULL);
    assert_int_equal(lk_terrain_sample_surface(terrain, &mesh, PROBES, got, &error), LK_OK);
    worst = 0;
    for (size_t k = 0; k < PROBES * PROBES; k++) worst = fmax(worst, fabs((double)expected[k] - got[k]));
    assert_true(worst > 100);
    free(expected);
    free(got);
    lk_mesh_free(&root);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
}

/* The crack counter itself: a hand-made T-junction and a split vertex. */
static void test_crack_counter(void **state)
{
    fixture *f = *state;
    lk_terrain *terrain = make_terrain(&f->fractal, LK_TERRAIN_CRACKS_FULL, 1, 0);
    /* two triangles on grid points (0,0),(2,0),(0,2) and (2,0),(2,2),(0,2) plus
     * one using (1,1) - the middle of the shared diagonal - off by 5 m */
    float positions[] = {0, 0, 10, 60, 0, 10, 0, 60, 30, 60, 60, 30, 30, 30, 25, 90, 30, 0};
    uint32_t indices[] = {0, 1, 2, 1, 3, 2, 4, 3, 5};
    lk_mesh mesh;
    lk_test_make_mesh(&mesh, positions, 6, indices, 3);
    lk_terrain_crack_stats stats;
    lk_error error = {0};
    assert_int_equal(lk_terrain_count_cracks(terrain, &mesh, 0, &stats, &error), LK_OK);
    assert_int_equal(stats.cracks, 1);
    assert_true(fabs(stats.max_gap - 5.0) < 1e-4);
    mesh.positions[3 * 4 + 2] = 20; /* on the diagonal: (10 + 30) / 2 */
    assert_int_equal(lk_terrain_count_cracks(terrain, &mesh, 0, &stats, &error), LK_OK);
    assert_int_equal(stats.cracks, 0);
    assert_int_equal(stats.checks, 2); /* (1,1) against the diagonal, from both triangles */
    mesh.positions[3 * 4 + 0] = 40;    /* off the grid */
    assert_int_equal(lk_terrain_count_cracks(terrain, &mesh, 0, &stats, &error), LK_ERR_INVALID);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
}

/* The pictures' helpers: the map rings the same cracks the counter finds,
 * the outline has 4 segments per leaf, colours are in [0,1]. */
static void test_map_outline_colours(void **state)
{
    fixture *f = *state;
    lk_terrain *terrain = make_terrain(&f->fractal513, LK_TERRAIN_CRACKS_MIDPOINT, 1, 1);
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_terrain_view view;
    lk_terrain_crack_stats counted = {0}, drawn = {0};
    lk_error error = {0};
    lk_terrain_stats stats;
    size_t frame = 0;
    for (; frame < 50 && counted.cracks == 0; frame++) {
        lk_terrain_flight(terrain, frame, 0, &view);
        update(terrain, &view, &mesh, &stats);
        assert_int_equal(lk_terrain_count_cracks(terrain, &mesh, 0, &counted, &error), LK_OK);
    }
    assert_true(counted.cracks > 0);
    unsigned height = 0;
    lk_terrain_map_size(terrain, 256, &height);
    assert_int_equal(height, 256);
    unsigned char *rgba = malloc(256 * 256 * 4);
    assert_non_null(rgba);
    assert_int_equal(lk_terrain_draw_map(terrain, &view, &mesh, 0, 256, rgba, &drawn, &error), LK_OK);
    assert_int_equal(drawn.cracks, counted.cracks);
    size_t red = 0;
    for (size_t k = 0; k < 256 * 256; k++)
        red += rgba[4 * k] == 255 && rgba[4 * k + 1] == 0 && rgba[4 * k + 2] == 0 && rgba[4 * k + 3] == 255;
    assert_true(red > 0);
    free(rgba);
    float *segments = NULL;
    size_t segment_count = 0, leaf_count = 0;
    assert_int_equal(lk_terrain_outline(terrain, &segments, &segment_count, &error), LK_OK);
    assert_non_null(lk_terrain_leaves(terrain, &leaf_count));
    assert_int_equal(leaf_count, stats.leaves);
    assert_int_equal(segment_count, 4 * leaf_count);
    for (size_t k = 0; k < segment_count; k++)
        assert_true(isfinite(segments[6 * k + 2]) && isfinite(segments[6 * k + 5]));
    lk_free(segments);
    assert_int_equal(lk_terrain_color_mesh(terrain, &mesh, &error), LK_OK);
    assert_non_null(mesh.colors);
    for (size_t k = 0; k < 4 * mesh.vertex_count; k++) assert_true(mesh.colors[k] >= 0 && mesh.colors[k] <= 1);
    /* an update drops the colours again (the mesh is rewritten) */
    update(terrain, &view, &mesh, NULL);
    assert_null(mesh.colors);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
}

static void test_bad_input(void **state)
{
    fixture *f = *state;
    lk_terrain *terrain = NULL;
    lk_error error = {0};
    float heights[33 * 33];
    for (size_t k = 0; k < 33 * 33; k++) heights[k] = (float)(k % 7);
    lk_heightfield field = {0};
    field.heights = heights;
    field.spacing_x = field.spacing_y = 10;

    field.width = 33, field.height = 17;
    assert_int_equal(lk_terrain_create(&field, NULL, &terrain, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "square");
    field.width = field.height = 30;
    assert_int_equal(lk_terrain_create(&field, NULL, &terrain, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "2^n+1");
    lk_assert_message_contains(error, "33");
    field.width = field.height = 3;
    assert_int_equal(lk_terrain_create(&field, NULL, &terrain, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "too small");
    field.width = field.height = 33;
    heights[5 * 33 + 7] = NAN;
    assert_int_equal(lk_terrain_create(&field, NULL, &terrain, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "column 7, row 5");
    heights[5 * 33 + 7] = 1;
    field.spacing_y = -1;
    assert_int_equal(lk_terrain_create(&field, NULL, &terrain, &error), LK_ERR_RANGE);
    field.spacing_y = 10;
    lk_terrain_options options;
    lk_terrain_options_default(&options);
    options.max_samples = 1000;
    assert_int_equal(lk_terrain_create(&field, &options, &terrain, &error), LK_ERR_LIMIT);
    lk_terrain_options_default(&options);
    options.resolution = 0;
    assert_int_equal(lk_terrain_create(&field, &options, &terrain, &error), LK_ERR_INVALID);
    lk_terrain_options_default(&options);
    options.error_scale = NAN;
    assert_int_equal(lk_terrain_create(&field, &options, &terrain, &error), LK_ERR_INVALID);
    assert_null(terrain);
    assert_int_equal(lk_terrain_create(NULL, NULL, &terrain, &error), LK_ERR_INVALID);

    assert_int_equal(lk_terrain_create(&field, NULL, &terrain, &error), LK_OK);
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_terrain_view view;
    lk_terrain_flight(terrain, 0, 0, &view);
    view.target[0] = view.eye[0], view.target[1] = view.eye[1], view.target[2] = view.eye[2];
    assert_int_equal(lk_terrain_update(terrain, &view, &mesh, NULL, &error), LK_ERR_INVALID);
    lk_terrain_flight(terrain, 0, 0, &view);
    view.fov_y = 180;
    assert_int_equal(lk_terrain_update(terrain, &view, &mesh, NULL, &error), LK_ERR_INVALID);
    lk_terrain_flight(terrain, 0, 0, &view);
    view.eye[2] = NAN;
    assert_int_equal(lk_terrain_update(terrain, &view, &mesh, NULL, &error), LK_ERR_INVALID);
    assert_int_equal(mesh.triangle_count, 0);
    lk_terrain_flight(terrain, 0, 0, &view);
    assert_int_equal(lk_terrain_update(terrain, &view, &mesh, NULL, &error), LK_OK);
    assert_true(mesh.triangle_count >= 8);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
    (void)f;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_neighbours_differ_by_one_level),
        cmocka_unit_test(test_fans_cover_the_grid),
        cmocka_unit_test(test_full_rules_leave_no_crack_on_etopo),
        cmocka_unit_test(test_full_rules_leave_no_crack_on_fractal),
        cmocka_unit_test(test_morphing_reduces_popping),
        cmocka_unit_test(test_blend_limits),
        cmocka_unit_test(test_crack_counter),
        cmocka_unit_test(test_map_outline_colours),
        cmocka_unit_test(test_bad_input),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
