/* SPDX-License-Identifier: MIT */
/* Octrees drawn under a point budget (lk_octree_select, src/octree_select.c;
 * lk_render_octree, src/gl/octree_draw.c) on a real model: the bunny
 * sampled into 400,000 oriented points, built into an octree of 5,000-point
 * leaves. The budget holds, the picture covers what the whole cloud
 * covers, nearer views select deeper nodes, and nodes outside the view are
 * not selected.
 *
 * Set LK_TEST_SAVE_IMAGES=DIR to keep the pictures as PNGs in DIR. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#define SIDE 512 /* llvmpipe: 400k splats at 512^2 take ~0.3 s */

typedef struct fixture {
    lk_mesh points; /* the whole cloud, absolute coordinates */
    lk_octree *octree;
    lk_renderer *renderer;
} fixture;

static const float magenta[3] = {1.0f, 0.0f, 1.0f};

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f) return -1;
    lk_mesh bunny;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_sample_options sample;
    lk_sample_options_default(&sample);
    sample.point_count = 400000;
    lk_error error = {0};
    if (lk_mesh_sample_points(&bunny, &sample, &f->points, NULL, NULL, &error) != LK_OK) return -1;
    lk_mesh_free(&bunny);
    const char *ply = lk_test_tmpfile("bunny400k.ply");
    if (lk_mesh_write(ply, LK_FORMAT_AUTO, &f->points, NULL, &error) != LK_OK) return -1;
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_node_points = 5000;
    options.threads = 1;
    const char *directory = lk_test_tmpfile("bunny_octree");
    if (lk_octree_build(&ply, 1, directory, &options, NULL, NULL, NULL, &error) != LK_OK ||
        lk_octree_open(directory, &f->octree, &error) != LK_OK ||
        lk_renderer_create(SIDE, SIDE, &f->renderer, &error) != LK_OK) {
        fprintf(stderr, "setup: %s\n", error.message);
        return -1;
    }
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    lk_mesh_free(&f->points);
    lk_octree_close(f->octree);
    lk_renderer_free(f->renderer);
    free(f);
    return 0;
}

static size_t covered_pixels(lk_renderer *renderer, const char *save_as)
{
    unsigned char *rgba = malloc((size_t)SIDE * SIDE * 4);
    assert_non_null(rgba);
    lk_error error = {0};
    assert_int_equal(lk_renderer_read_pixels(renderer, rgba, &error), LK_OK);
    size_t covered = 0;
    for (size_t i = 0; i < (size_t)SIDE * SIDE; i++)
        covered += !(rgba[4 * i] == 255 && rgba[4 * i + 1] == 0 && rgba[4 * i + 2] == 255);
    const char *directory = getenv("LK_TEST_SAVE_IMAGES");
    if (directory && *directory) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", directory, save_as);
        assert_int_equal(lk_image_write_png(path, rgba, SIDE, SIDE, &error), LK_OK);
    }
    free(rgba);
    return covered;
}

/* The whole cloud and the octree under several budgets, from the same
 * camera (both framed on the cloud's tight bounds). */
static void test_budget_holds_and_covers(void **state)
{
    fixture *f = *state;
    const lk_octree_info *info = lk_octree_get_info(f->octree);
    assert_int_equal(info->points, 400000);
    lk_render_options options;
    lk_render_options_default(&options);
    memcpy(options.background, magenta, sizeof magenta);
    options.use_bounds = 1;
    for (int k = 0; k < 3; k++) {
        options.bounds_min[k] = (float)info->min[k];
        options.bounds_max[k] = (float)info->max[k];
    }
    lk_error error = {0};
    assert_int_equal(lk_render_points(f->renderer, &f->points, &options, NULL, &error), LK_OK);
    size_t whole = covered_pixels(f->renderer, "octree_whole.png");
    assert_true(whole > SIDE * SIDE / 5); /* the bunny fills a good part of the frame */

    options.use_bounds = 0; /* lk_render_octree frames the octree's bounds itself */
    static const uint64_t budgets[] = {1000000, 50000, 30000, 15000};
    uint64_t previous = UINT64_MAX;
    for (size_t b = 0; b < sizeof budgets / sizeof *budgets; b++) {
        lk_octree_select_options select;
        lk_octree_select_options_default(&select);
        select.point_budget = budgets[b];
        lk_render_octree_stats stats;
        assert_int_equal(lk_render_octree(f->renderer, f->octree, &options, &select, &stats, &error), LK_OK);
        char name[64];
        snprintf(name, sizeof name, "octree_%llu.png", (unsigned long long)budgets[b]);
        size_t covered = covered_pixels(f->renderer, name);
        double ratio = (double)covered / (double)whole;
        printf("budget %7llu: %zu nodes, %llu points, %.1f KB read, coverage %.4f of the whole cloud's\n",
               (unsigned long long)budgets[b], stats.nodes, (unsigned long long)stats.points, stats.bytes / 1e3, ratio);
        assert_true(stats.points <= budgets[b]);
        assert_true(stats.points <= previous);
        /* at 512 px the 1 px spacing rule stops before a 1M budget: 62k of the 400k points are enough */
        if (b == 0) assert_true(stats.points < 100000);
        assert_true(stats.nodes > 0);
        assert_int_equal(stats.bytes, stats.points * info->stride);
        previous = stats.points;
        /* Sparser nodes carry larger radii (the spacing of the deepest
         * drawn node, 1.5 times it for its ancestors' points): no holes, and
         * a silhouette within a few pixels of the whole cloud's (measured:
         * 0.9999-1.0015; 1.002-1.006 with every inner node's points at
         * least its spacing). */
        assert_true(ratio > 0.99);
        assert_true(ratio < 1.03);
    }
    /* Every node drawn (no spacing limit, the whole budget): each point at
     * its own radius (lk_octree_load_selection), so the octree's picture is
     * the whole cloud's; with every inner node's points at least its
     * spacing it spilled past the silhouette (measured 1.0064; 1.0001 now). */
    lk_octree_select_options select;
    lk_octree_select_options_default(&select);
    select.point_budget = info->points;
    select.min_spacing_pixels = 0;
    lk_render_octree_stats all_stats;
    assert_int_equal(lk_render_octree(f->renderer, f->octree, &options, &select, &all_stats, &error), LK_OK);
    assert_int_equal(all_stats.points, info->points);
    double all_ratio = (double)covered_pixels(f->renderer, "octree_all.png") / (double)whole;
    printf("every node: %zu nodes, coverage %.4f of the whole cloud's\n", all_stats.nodes, all_ratio);
    assert_true(all_ratio > 0.995 && all_ratio < 1.003);
    /* The root alone (13,453 points) is over a budget of 1. */
    lk_octree_select_options_default(&select);
    select.point_budget = 1;
    assert_int_equal(lk_render_octree(f->renderer, f->octree, &options, &select, NULL, &error), LK_ERR_LIMIT);
    assert_non_null(strstr(error.message, "below the root node's"));
}

/* A view of the octree: the eye at `distance` from the cloud's centre along +z. */
static lk_octree_view view_from(const lk_octree_info *info, double distance)
{
    lk_octree_view view;
    memset(&view, 0, sizeof view);
    for (int k = 0; k < 3; k++) view.eye[k] = 0.5 * (info->min[k] + info->max[k]) - info->offset[k];
    view.eye[2] += distance;
    view.fov_y = 35;
    view.viewport_height = 800;
    return view;
}

static unsigned deepest_level(const lk_octree *octree, const size_t *nodes, size_t count)
{
    unsigned deepest = 0;
    for (size_t i = 0; i < count; i++) {
        unsigned level = lk_octree_node_at(octree, nodes[i])->level;
        if (level > deepest) deepest = level;
    }
    return deepest;
}

/* Sets view->clip to a 35-degree perspective from view->eye looking along
 * z (direction -1: down -z, towards the cloud from view_from's eye; +1:
 * away from it), square viewport. */
static void look_along_z(lk_octree_view *view, double direction)
{
    view->has_clip = 1;
    double f_y = 1.0 / tan(0.5 * 35.0 * 3.14159265358979323846 / 180.0), n = 0.01, fa = 100.0;
    double projection[16] = {f_y, 0, 0, 0, 0, f_y, 0, 0, 0, 0, (fa + n) / (n - fa), -1, 0, 0, 2 * fa * n / (n - fa), 0};
    /* looking down +z is a half turn about y of the camera looking down -z */
    double turn = direction > 0 ? -1.0 : 1.0;
    double rotation[16] = {turn, 0, 0, 0, 0, 1, 0, 0, 0, 0, turn, 0, 0, 0, 0, 1};
    for (int k = 0; k < 3; k++)
        rotation[12 + k] =
            -(rotation[k] * view->eye[0] + rotation[4 + k] * view->eye[1] + rotation[8 + k] * view->eye[2]);
    for (int col = 0; col < 4; col++)
        for (int row = 0; row < 4; row++) {
            double sum = 0;
            for (int k = 0; k < 4; k++) sum += projection[k * 4 + row] * rotation[col * 4 + k];
            view->clip[col * 4 + row] = sum;
        }
}

static void test_selection_follows_the_view(void **state)
{
    fixture *f = *state;
    const lk_octree_info *info = lk_octree_get_info(f->octree);
    lk_octree_select_options select;
    lk_octree_select_options_default(&select);
    lk_error error = {0};
    size_t *far_nodes, far_count, *near_nodes, near_count;
    uint64_t far_points, near_points;
    lk_octree_view far = view_from(info, 20.0), near = view_from(info, 2.0);
    assert_int_equal(lk_octree_select(f->octree, &far, &select, &far_nodes, &far_count, &far_points, &error), LK_OK);
    assert_int_equal(lk_octree_select(f->octree, &near, &select, &near_nodes, &near_count, &near_points, &error),
                     LK_OK);
    printf("far: %zu nodes %llu points (level <= %u); near: %zu nodes %llu points (level <= %u)\n", far_count,
           (unsigned long long)far_points, deepest_level(f->octree, far_nodes, far_count), near_count,
           (unsigned long long)near_points, deepest_level(f->octree, near_nodes, near_count));
    assert_true(far_points < near_points);
    assert_true(deepest_level(f->octree, far_nodes, far_count) < deepest_level(f->octree, near_nodes, near_count));
    /* the root first, and every node after its parent */
    assert_int_equal(near_nodes[0], 0);
    for (size_t i = 1; i < near_count; i++) {
        const char *name = lk_octree_node_at(f->octree, near_nodes[i])->name;
        size_t length = strlen(name), found = 0;
        for (size_t j = 0; j < i && !found; j++) {
            const char *parent = lk_octree_node_at(f->octree, near_nodes[j])->name;
            found = strlen(parent) == length - 1 && strncmp(parent, name, length - 1) == 0;
        }
        assert_true(found);
    }
    /* A budget smaller than the near selection: the points stay under it. */
    select.point_budget = near_points / 2;
    size_t *half_nodes, half_count;
    uint64_t half_points;
    assert_int_equal(lk_octree_select(f->octree, &near, &select, &half_nodes, &half_count, &half_points, &error),
                     LK_OK);
    assert_true(half_points <= near_points / 2 && half_points > near_points / 4);

    /* A frustum looking away (+z from the eye, the cloud behind): only the
     * root, which is always taken. */
    lk_octree_view away = near;
    away.has_clip = 1;
    look_along_z(&away, +1.0);
    size_t *away_nodes, away_count;
    select.point_budget = 1000000;
    assert_int_equal(lk_octree_select(f->octree, &away, &select, &away_nodes, &away_count, NULL, &error), LK_OK);
    assert_int_equal(away_count, 1);
    /* ... and the same frustum turned back towards the cloud keeps what the unculled view had, or less */
    look_along_z(&away, -1.0);
    size_t *facing_nodes, facing_count;
    assert_int_equal(lk_octree_select(f->octree, &away, &select, &facing_nodes, &facing_count, NULL, &error), LK_OK);
    assert_true(facing_count > 1 && facing_count <= near_count);
    lk_free(far_nodes);
    lk_free(near_nodes);
    lk_free(half_nodes);
    lk_free(away_nodes);
    lk_free(facing_nodes);

    /* refusals */
    lk_octree_view bad = near;
    bad.fov_y = 0;
    size_t *none, none_count;
    assert_int_equal(lk_octree_select(f->octree, &bad, &select, &none, &none_count, NULL, &error), LK_ERR_INVALID);
    assert_null(none);
    bad = near;
    bad.eye[1] = NAN;
    assert_int_equal(lk_octree_select(f->octree, &bad, &select, &none, &none_count, NULL, &error), LK_ERR_RANGE);
}

/* The clip lines an octree stores reach the splats: Haystack_Rock (an
 * airborne scan whose returns end at the water and in gaps, normals
 * estimated) seen from above with its border splats cut covers fewer
 * pixels than with whole discs, by about the border's rim (measured 4.8%
 * at 512x512; against a surface made from its points, bench_radii, the
 * splat pixels off it fall from 13.7% to 9.1%), and every pixel it covers
 * the whole discs cover too (a cut only removes). */
static void test_clip_lines_cut_borders(void **state)
{
    fixture *f = *state;
    lk_error error = {0};
    lk_octree_options build;
    lk_octree_options_default(&build);
    build.normals = LK_OCTREE_NORMALS_ESTIMATE;
    build.threads = 1;
    const char *input = lk_test_sample("las/Haystack_Rock.las"), *directory = lk_test_tmpfile("haystack_octree");
    lk_octree *octree;
    assert_int_equal(lk_octree_build(&input, 1, directory, &build, NULL, NULL, NULL, &error), LK_OK);
    assert_int_equal(lk_octree_open(directory, &octree, &error), LK_OK);
    assert_true(lk_octree_get_info(octree)->has_clips);
    lk_render_options options;
    lk_render_options_default(&options);
    memcpy(options.background, magenta, sizeof magenta);
    options.up_axis = LK_AXIS_Z;
    options.elevation = 90;
    options.backface_culling = 0;
    lk_octree_select_options select;
    lk_octree_select_options_default(&select);
    select.min_spacing_pixels = 0;
    unsigned char *pictures[2];
    size_t covered[2];
    for (int cut = 0; cut < 2; cut++) {
        options.clip_borders = (uint64_t)cut;
        assert_int_equal(lk_render_octree(f->renderer, octree, &options, &select, NULL, &error), LK_OK);
        covered[cut] = covered_pixels(f->renderer, cut ? "haystack_cut.png" : "haystack_whole.png");
        pictures[cut] = malloc((size_t)SIDE * SIDE * 4);
        assert_non_null(pictures[cut]);
        assert_int_equal(lk_renderer_read_pixels(f->renderer, pictures[cut], &error), LK_OK);
    }
    size_t cut_only = 0;
    for (size_t i = 0; i < (size_t)SIDE * SIDE; i++) {
        const unsigned char *whole = pictures[0] + 4 * i, *cut = pictures[1] + 4 * i;
        int in_whole = !(whole[0] == 255 && whole[1] == 0 && whole[2] == 255);
        int in_cut = !(cut[0] == 255 && cut[1] == 0 && cut[2] == 255);
        cut_only += in_cut && !in_whole;
    }
    double ratio = (double)covered[1] / (double)covered[0];
    printf("Haystack_Rock from above: %zu pixels with whole discs, %zu cut (%.4f), %zu only cut\n", covered[0],
           covered[1], ratio, cut_only);
    assert_true(ratio > 0.9 && ratio < 0.99);
    assert_int_equal(cut_only, 0);
    free(pictures[0]);
    free(pictures[1]);
    lk_octree_close(octree);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_budget_holds_and_covers),
        cmocka_unit_test(test_selection_follows_the_view),
        cmocka_unit_test(test_clip_lines_cut_borders),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
