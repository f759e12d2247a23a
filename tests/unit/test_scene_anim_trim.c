/* SPDX-License-Identifier: MIT */
/* Compact glTF output trims animations (src/scene_anim_trim.c): keys their
 * neighbours reproduce and channels that hold their node's rest value go,
 * and what is left plays the same.
 *   - AnimatedMorphCube (assimp-testmodels): its weights track of 127 keys
 *     written with LK_GLTF_QUANTIZE and read back has 125, and at each of the
 *     127 input times the written track, interpolated, gives the input's
 *     value within a millionth;
 *   - Khronos' RiggedSimple (with `scripts/fetch-samples.sh --bench`): 6
 *     channels become 2 (4 hold their node's own translation, rotation or
 *     scale at every key), and the 2 left play as before: rotations within
 *     the step of the normalised shorts they are written as, and with
 *     EXT_meshopt_compression within its filters' steps. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "testutil.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void read_scene(const char *path, lk_scene *scene)
{
    lk_error error = {0};
    if (lk_scene_read(path, NULL, scene, &error) != LK_OK) fail_msg("%s: %s", path, error.message);
}

static void write_compact(const lk_scene *scene, const char *path, uint64_t flags)
{
    lk_write_options options = {0};
    options.gltf_flags = flags;
    lk_error error = {0};
    if (lk_scene_write(path, scene, &options, &error) != LK_OK) fail_msg("%s: %s", path, error.message);
}

/* The value of a LINEAR or STEP track at time t, component c (rotations
 * compared by the caller up to sign; the tracks here hold equal
 * quaternions between kept keys, so lerp is exact). */
static double track_value(const lk_scene_animation_sampler *sampler, double t, size_t width, size_t c)
{
    size_t k = 0;
    while (k + 1 < sampler->key_count && sampler->input[k + 1] <= t) k++;
    if (k + 1 >= sampler->key_count || sampler->interpolation == LK_SCENE_STEP) return sampler->output[k * width + c];
    double t0 = sampler->input[k], t1 = sampler->input[k + 1], f = t1 > t0 ? (t - t0) / (t1 - t0) : 0.0;
    return sampler->output[k * width + c] + (sampler->output[(k + 1) * width + c] - sampler->output[k * width + c]) * f;
}

/* Every channel of `written` plays as the channel of `input` on the same
 * node and path, at every key time of the input. Returns the channels. */
static size_t assert_same_playback(const lk_scene *input, const lk_scene *written, double rotation_tolerance,
                                   double tolerance)
{
    assert_int_equal(written->animation_count, input->animation_count);
    size_t channels = 0;
    for (size_t a = 0; a < input->animation_count; a++) {
        const lk_scene_animation *in = &input->animations[a], *out = &written->animations[a];
        for (size_t c = 0; c < out->channel_count; c++) {
            const lk_scene_animation_channel *channel = &out->channels[c];
            const lk_scene_animation_channel *source = NULL;
            for (size_t i = 0; i < in->channel_count && !source; i++)
                if (in->channels[i].node == channel->node && in->channels[i].path == channel->path)
                    source = &in->channels[i];
            assert_non_null(source);
            const lk_scene_animation_sampler *before = &in->samplers[source->sampler];
            const lk_scene_animation_sampler *after = &out->samplers[channel->sampler];
            size_t width = before->output_count / before->key_count * before->components;
            assert_int_equal(after->output_count / after->key_count * after->components, width);
            assert_true(after->key_count <= before->key_count);
            assert_true(after->input[0] == before->input[0]);
            assert_true(after->input[after->key_count - 1] == before->input[before->key_count - 1]);
            bool rotation = channel->path == LK_SCENE_PATH_ROTATION && width == 4;
            for (size_t k = 0; k < before->key_count; k++) {
                double got[4], expected[4], dot = 0;
                for (size_t i = 0; i < width; i++) {
                    expected[i % 4] = before->output[k * width + i];
                    got[i % 4] = track_value(after, before->input[k], width, i);
                    dot += got[i % 4] * expected[i % 4];
                    if (rotation) continue;
                    assert_true(fabs(got[i % 4] - expected[i % 4]) <= tolerance * fmax(1.0, fabs(expected[i % 4])));
                }
                /* q and -q are the same rotation (meshopt's filter may flip it) */
                for (size_t i = 0; rotation && i < 4; i++)
                    assert_true(fabs((dot < 0 ? -got[i] : got[i]) - expected[i]) <= rotation_tolerance);
            }
            channels++;
        }
    }
    return channels;
}

static size_t key_total(const lk_scene *scene)
{
    size_t keys = 0;
    for (size_t a = 0; a < scene->animation_count; a++)
        for (size_t s = 0; s < scene->animations[a].sampler_count; s++)
            keys += scene->animations[a].samplers[s].key_count;
    return keys;
}

static void test_morph_cube_trimmed(void **state)
{
    (void)state;
    lk_scene input, written;
    read_scene(lk_test_sample("assimp/glTF2/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf"), &input);
    const char *path = lk_test_tmpfile("cube-trimmed.glb");
    write_compact(&input, path, LK_GLTF_QUANTIZE);
    read_scene(path, &written);
    assert_int_equal(key_total(&input), 127);
    assert_int_equal(key_total(&written), 125);
    assert_int_equal(assert_same_playback(&input, &written, 1e-6, 1e-6), 1);
    lk_scene_free(&written);
    /* plain output keeps every key */
    lk_write_options plain = {0};
    lk_error error = {0};
    assert_int_equal(lk_scene_write(path, &input, &plain, &error), LK_OK);
    read_scene(path, &written);
    assert_int_equal(key_total(&written), 127);
    lk_scene_free(&written);
    lk_scene_free(&input);
}

static void test_rigged_simple_channels(void **state)
{
    (void)state;
    char sample[4096];
    snprintf(sample, sizeof sample, "%s/RiggedSimple/RiggedSimple.gltf", LK_SAMPLES_DIR);
    FILE *probe = fopen(sample, "rb");
    if (!probe) skip(); /* `scripts/fetch-samples.sh --bench` only */
    fclose(probe);
    lk_scene input, written;
    read_scene(sample, &input);
    const char *path = lk_test_tmpfile("rigged-trimmed.glb");
    write_compact(&input, path, LK_GLTF_QUANTIZE);
    read_scene(path, &written);
    size_t channels = 0;
    for (size_t a = 0; a < input.animation_count; a++) channels += input.animations[a].channel_count;
    assert_int_equal(channels, 6);
    /* rotations as normalised shorts: within half a step of 1/32767 */
    assert_int_equal(assert_same_playback(&input, &written, 2e-5, 1e-6), 2);
    lk_scene_free(&written);
    /* compressed: rotations through meshopt's quaternion filter (12 bits:
     * the 3 smaller components in steps of sqrt(2)/4095), translations
     * through its exponential filter (16-bit mantissas) */
    write_compact(&input, path, LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT);
    read_scene(path, &written);
    assert_int_equal(assert_same_playback(&input, &written, 4e-4, 3e-5), 2);
    lk_scene_free(&written);
    lk_scene_free(&input);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_morph_cube_trimmed),
        cmocka_unit_test(test_rigged_simple_channels),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
