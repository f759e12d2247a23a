/* SPDX-License-Identifier: MIT */
/* Progress callbacks of the long library calls the CLI shows a bar for:
 * lk_dem_read (GDAL and lodkit's own readers), lk_progressive_mesh_build,
 * lk_progressive_strips_build_ex and lk_mesh_sample_points --poisson. Each
 * reports 0.0 first and 1.0 last, never goes back, reports along the way
 * (no long silence), cancels when asked, and changes no result. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

typedef struct progress_log {
    double fractions[100000];
    size_t count;
    size_t cancel_at; /* the report (1-based) that returns non-zero; 0: none */
} progress_log;

static int record(void *user, double fraction, const char *stage)
{
    progress_log *log = user;
    assert_non_null(stage);
    if (log->count < sizeof log->fractions / sizeof log->fractions[0]) log->fractions[log->count] = fraction;
    log->count++;
    return log->cancel_at && log->count == log->cancel_at;
}

static progress_log *new_log(void)
{
    progress_log *log = calloc(1, sizeof *log);
    assert_non_null(log);
    return log;
}

/* 0.0 first, 1.0 last, never backwards, and at least `inner` reports in between. */
static void assert_complete(const progress_log *log, size_t inner)
{
    assert_true(log->count >= 2 + inner);
    assert_true(log->fractions[0] == 0.0);
    assert_true(log->fractions[log->count - 1] == 1.0);
    for (size_t i = 1; i < log->count; i++) {
        if (log->fractions[i] < log->fractions[i - 1])
            fail_msg("report %zu went back: %g after %g", i, log->fractions[i], log->fractions[i - 1]);
        assert_true(log->fractions[i] <= 1.0);
    }
}

static void test_dem_read(void **state)
{
    (void)state;
    const char *grids[] = {"etopo20.cdf", "jacksboro_fault_dem.npz"}; /* GDAL, lodkit's own reader */
    for (size_t g = 0; g < 2; g++) {
        lk_dem_options options;
        lk_dem_options_default(&options);
        assert_null(options.progress);
        progress_log *log = new_log();
        options.progress = record;
        options.progress_user = log;
        lk_heightfield with, without;
        lk_error error = {0};
        if (lk_dem_read(lk_test_sample(grids[g]), &options, &with, &error) != LK_OK) fail_msg("%s", error.message);
        assert_complete(log, 1);
        if (lk_dem_read(lk_test_sample(grids[g]), NULL, &without, &error) != LK_OK) fail_msg("%s", error.message);
        assert_int_equal(with.width, without.width);
        assert_int_equal(with.height, without.height);
        assert_memory_equal(with.heights, without.heights, with.width * with.height * sizeof(float));
        lk_heightfield_free(&with);
        lk_heightfield_free(&without);
        /* cancelled at the first report: nothing read */
        memset(log, 0, sizeof *log);
        log->cancel_at = 1;
        assert_int_equal(lk_dem_read(lk_test_sample(grids[g]), &options, &with, &error), LK_ERR_INVALID);
        assert_non_null(strstr(error.message, "cancelled"));
        assert_null(with.heights);
        free(log);
    }
}

static lk_mesh read_sample(const char *name)
{
    lk_mesh mesh;
    lk_error error = {0};
    if (lk_mesh_read(lk_test_sample(name), LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK) fail_msg("%s", error.message);
    return mesh;
}

static void test_progressive_build(void **state)
{
    (void)state;
    lk_mesh bunny = read_sample("bunny.obj");
    progress_log *log = new_log();
    lk_progressive_mesh pm, plain;
    lk_error error = {0};
    if (lk_progressive_mesh_build(&bunny, NULL, &pm, record, log, &error) != LK_OK) fail_msg("%s", error.message);
    assert_complete(log, 2);
    if (lk_progressive_mesh_build(&bunny, NULL, &plain, NULL, NULL, &error) != LK_OK) fail_msg("%s", error.message);
    assert_int_equal(pm.split_count, plain.split_count);
    assert_memory_equal(pm.indices, plain.indices, 3 * pm.triangle_count * sizeof *pm.indices);

    /* the strips */
    memset(log, 0, sizeof *log);
    lk_progressive_strips strips, plain_strips;
    if (lk_progressive_strips_build_ex(&pm, LK_STRIPIFY_BEST, &strips, record, log, &error) != LK_OK)
        fail_msg("%s", error.message);
    assert_complete(log, 2);
    if (lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &plain_strips, &error) != LK_OK)
        fail_msg("%s", error.message);
    assert_int_equal(strips.strip_length, plain_strips.strip_length);
    assert_memory_equal(strips.strip, plain_strips.strip, strips.strip_length * sizeof *strips.strip);
    lk_progressive_strips_free(&plain_strips);
    memset(log, 0, sizeof *log);
    log->cancel_at = 2;
    assert_int_equal(lk_progressive_strips_build_ex(&pm, LK_STRIPIFY_BEST, &plain_strips, record, log, &error),
                     LK_ERR_INVALID);
    assert_null(plain_strips.strip);

    /* cancelled before the simplification */
    memset(log, 0, sizeof *log);
    log->cancel_at = 1;
    lk_progressive_mesh cancelled;
    assert_int_equal(lk_progressive_mesh_build(&bunny, NULL, &cancelled, record, log, &error), LK_ERR_INVALID);
    assert_int_equal(log->count, 1);
    lk_progressive_strips_free(&strips);
    lk_progressive_mesh_free(&pm);
    lk_progressive_mesh_free(&plain);
    lk_mesh_free(&bunny);
    free(log);
}

/* Poisson-disk sampling reports while it weighs the samples, before the
 * elimination starts: no more than a tenth of the run without a report. */
static void test_poisson_sampling(void **state)
{
    (void)state;
    lk_mesh cow = read_sample("cow.off");
    lk_sample_options options;
    lk_sample_options_default(&options);
    options.poisson = 1;
    options.point_count = 20000;
    progress_log *log = new_log();
    lk_mesh points, plain;
    lk_error error = {0};
    if (lk_mesh_sample_points(&cow, &options, &points, record, log, &error) != LK_OK) fail_msg("%s", error.message);
    assert_complete(log, 10);
    size_t weighing = 0; /* reports between the grid (0.2) and the elimination (0.5) */
    for (size_t i = 0; i < log->count; i++) weighing += log->fractions[i] > 0.2 && log->fractions[i] < 0.5;
    assert_true(weighing >= 10);
    if (lk_mesh_sample_points(&cow, &options, &plain, NULL, NULL, &error) != LK_OK) fail_msg("%s", error.message);
    assert_int_equal(points.vertex_count, plain.vertex_count);
    assert_memory_equal(points.positions, plain.positions, 3 * points.vertex_count * sizeof(float));
    assert_memory_equal(points.radii, plain.radii, points.vertex_count * sizeof(float));
    lk_mesh_free(&points);
    lk_mesh_free(&plain);
    lk_mesh_free(&cow);
    free(log);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dem_read),
        cmocka_unit_test(test_progressive_build),
        cmocka_unit_test(test_poisson_sampling),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
