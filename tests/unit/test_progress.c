/* SPDX-License-Identifier: MIT */
/* Progress callbacks of the simplifiers: lk_simplify (every method),
 * lk_animation_simplify and lk_animation_simplify_levels report 0 first
 * and 1 last, fractions in between stay in [0, 1] and never go back, and
 * a cancel at the first report stops the call. Procedural shapes only. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* Every fraction a callback was given. */
typedef struct recording {
    double fractions[4096];
    size_t count;
    int cancel; /* returned to the caller */
} recording;

static int record(void *user, double fraction, const char *stage)
{
    recording *r = user;
    assert_non_null(stage);
    if (r->count < sizeof r->fractions / sizeof r->fractions[0]) r->fractions[r->count++] = fraction;
    return r->cancel;
}

static void assert_zero_to_one(const recording *r, const char *what)
{
    if (r->count < 2) fail_msg("%s: %zu progress reports, expected at least 0 and 1", what, r->count);
    if (r->fractions[0] != 0.0) fail_msg("%s: first report %g, expected 0", what, r->fractions[0]);
    if (r->fractions[r->count - 1] != 1.0) fail_msg("%s: last report %g, expected 1", what, r->fractions[r->count - 1]);
    for (size_t i = 1; i < r->count; i++)
        if (!(r->fractions[i] >= r->fractions[i - 1] && r->fractions[i] <= 1.0))
            fail_msg("%s: report %zu is %g after %g", what, i, r->fractions[i], r->fractions[i - 1]);
}

static void test_simplify_every_method(void **state)
{
    (void)state;
    /* 128 x 64: enough contractions at 10% for the QEM's own reports
     * (every 4096 contractions) to come between 0 and 1. */
    lk_mesh torus;
    lk_test_make_torus(&torus, 128, 64);
    static const lk_simplify_method methods[] = {LK_SIMPLIFY_QEM, LK_SIMPLIFY_UNIFORM, LK_SIMPLIFY_FLOATING,
                                                 LK_SIMPLIFY_WAVELET};
    static const char *const names[] = {"qem", "uniform", "floating", "wavelet"};
    for (size_t m = 0; m < sizeof methods / sizeof methods[0]; m++) {
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_ratio = 0.1;
        recording r = {.count = 0};
        lk_simplify_result result;
        lk_error error = {0};
        if (lk_simplify(&torus, methods[m], &options, &result, record, &r, &error) != LK_OK)
            fail_msg("%s: %s", names[m], error.message);
        assert_true(result.mesh.triangle_count > 0);
        assert_zero_to_one(&r, names[m]);
        if (methods[m] == LK_SIMPLIFY_QEM) assert_true(r.count >= 3); /* its own report in between */
        lk_simplify_result_free(&result);
    }
    lk_mesh_free(&torus);
}

static void test_simplify_cancel_at_start(void **state)
{
    (void)state;
    lk_mesh torus;
    lk_test_make_torus(&torus, 16, 8);
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = 0.5;
    recording r = {.cancel = 1};
    lk_simplify_result result;
    lk_error error = {0};
    assert_int_equal(lk_simplify(&torus, LK_SIMPLIFY_QEM, &options, &result, record, &r, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "cancelled");
    assert_int_equal(r.count, 1);
    assert_true(r.fractions[0] == 0.0);
    assert_null(result.mesh.positions);
    lk_mesh_free(&torus);
}

/* An n x m torus breathing over three frames (scaled by 1, 1.5, 2). */
static void breathing_torus(lk_animation *animation, uint32_t n, uint32_t m)
{
    lk_animation_init(animation);
    lk_test_make_torus(&animation->mesh, n, m);
    size_t v_count = animation->mesh.vertex_count;
    animation->frame_count = 3;
    animation->frames_per_second = 10;
    animation->frame_positions = malloc(3 * v_count * 3 * sizeof(float));
    assert_non_null(animation->frame_positions);
    for (size_t f = 0; f < 3; f++)
        for (size_t i = 0; i < 3 * v_count; i++)
            animation->frame_positions[3 * v_count * f + i] = animation->mesh.positions[i] * (1.0f + 0.5f * (float)f);
}

static void test_animation_simplify(void **state)
{
    (void)state;
    /* 256 x 64 (32768 triangles): the runs make thousands of contractions,
     * so that the QEM's own reports (every 4096) come between 0 and 1;
     * without the lost-surface term to keep it fast. */
    lk_animation animation;
    breathing_torus(&animation, 256, 64);
    lk_anim_simplify_options options;
    lk_anim_simplify_options_default(&options);
    options.lost_surface = 0;
    options.simplify.target_ratio = 0.2;
    recording r = {.count = 0};
    lk_anim_simplify_result result;
    lk_error error = {0};
    if (lk_animation_simplify(&animation, &options, &result, record, &r, &error) != LK_OK)
        fail_msg("lk_animation_simplify: %s", error.message);
    assert_zero_to_one(&r, "lk_animation_simplify");
    assert_true(r.count >= 3);
    lk_anim_simplify_result_free(&result);

    /* Two levels, one run each, reported as parts of the whole: the first
     * run (4915 contractions) reports 5/6 of its way, the second (9830) a
     * third and 5/6 of its way; alone each would go back. */
    static const double ratios[2] = {0.1, 0.7};
    lk_anim_simplify_result levels[2];
    memset(&r, 0, sizeof r);
    if (lk_animation_simplify_levels(&animation, &options, ratios, 2, levels, record, &r, &error) != LK_OK)
        fail_msg("lk_animation_simplify_levels: %s", error.message);
    assert_zero_to_one(&r, "lk_animation_simplify_levels");
    assert_true(r.count >= 5);
    for (int k = 0; k < 2; k++) lk_anim_simplify_result_free(&levels[k]);

    /* Cancelled at the first report: nothing is made. */
    recording cancel = {.cancel = 1};
    assert_int_equal(lk_animation_simplify(&animation, &options, &result, record, &cancel, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "cancelled");
    assert_int_equal(cancel.count, 1);
    assert_null(result.animation.frame_positions);
    lk_animation_free(&animation);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_simplify_every_method),
        cmocka_unit_test(test_simplify_cancel_at_start),
        cmocka_unit_test(test_animation_simplify),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
