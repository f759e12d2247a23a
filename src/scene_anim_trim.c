/* SPDX-License-Identifier: MIT */
/* Animation keys a player cannot tell apart from their neighbours, dropped
 * for the compact glTF output (LK_GLTF_QUANTIZE, LK_GLTF_MESHOPT), as
 * gltfpack trims its tracks. Exporters bake every bone at every frame: CGE's
 * knight has 750 channels of which 526 never change (44,475 of its 67,000
 * values), and keys on straight lines hold about 11,000 more.
 *
 * A key goes when every key between the last one kept and the one after it
 * lies on the segment joining those two, within a millionth of the track's
 * largest value (float rounding); rotations only where the quaternions are
 * equal (their LINEAR is a slerp, not a straight line). The first and the
 * last key stay, so each track keeps its time span and the animation its
 * length. CUBICSPLINE samplers are kept whole. A channel whose trimmed track
 * never leaves its node's own translation, rotation or scale is dropped (it
 * changes nothing; gltfpack drops them too unless told -ac: the knight keeps
 * 180 of its 750), with the samplers no channel uses; an animation keeps at
 * least one channel (its last). The scene is not changed: the caller gets
 * trimmed copies of its animations. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Whether keys (kept, next) exclusive lie on the segment from key `kept` to
 * key `next` (straight) or equal key `kept` (not straight). */
static bool between_on_segment(const lk_scene_animation_sampler *sampler, size_t width, size_t kept, size_t next,
                               bool straight, double tolerance)
{
    const float *a = sampler->output + kept * width, *b = sampler->output + next * width;
    double t0 = sampler->input[kept], t1 = sampler->input[next];
    for (size_t k = kept + 1; k < next; k++) {
        double f = straight && t1 > t0 ? ((double)sampler->input[k] - t0) / (t1 - t0) : 0.0;
        for (size_t c = 0; c < width; c++) {
            double expected = straight ? a[c] + ((double)b[c] - a[c]) * f : a[c];
            if (fabs(sampler->output[k * width + c] - expected) > tolerance) return false;
            if (!straight && fabs((double)b[c] - a[c]) > tolerance) return false;
        }
    }
    return true;
}

static bool trim_sampler(const lk_scene_animation_sampler *in, lk_scene_animation_sampler *out, bool rotation)
{
    *out = *in;
    out->input = NULL;
    out->output = NULL;
    size_t keys = in->key_count;
    if (keys == 0 || in->output_count % keys != 0) return false;
    size_t width = in->output_count / keys * in->components;
    bool keep_all = in->interpolation == LK_SCENE_CUBICSPLINE || keys < 3;
    out->input = lk__malloc_array(keys, sizeof(float));
    out->output = lk__malloc_array(keys, width * sizeof(float));
    if (!out->input || !out->output) return false;
    double largest = 0.0;
    for (size_t i = 0; i < keys * width; i++) largest = fmax(largest, fabs(in->output[i]));
    double tolerance = 1e-6 * (largest > 1.0 ? largest : 1.0);
    bool straight = !rotation && in->interpolation == LK_SCENE_LINEAR;
    size_t kept_count = 0, kept = 0;
    for (size_t k = 0; k < keys; k++) {
        /* key k stays unless the segment from the last kept key to k + 1 holds it */
        if (!keep_all && k > 0 && k + 1 < keys && between_on_segment(in, width, kept, k + 1, straight, tolerance))
            continue;
        out->input[kept_count] = in->input[k];
        memcpy(out->output + kept_count * width, in->output + k * width, width * sizeof(float));
        kept_count++;
        kept = k;
    }
    out->key_count = kept_count;
    out->output_count = in->output_count / keys * kept_count;
    return true;
}

void lk__scene_animations_free(lk_scene_animation *animations, size_t count)
{
    for (size_t a = 0; animations && a < count; a++) {
        for (size_t s = 0; animations[a].samplers && s < animations[a].sampler_count; s++) {
            free(animations[a].samplers[s].input);
            free(animations[a].samplers[s].output);
        }
        free(animations[a].samplers);
        free(animations[a].channels);
    }
    free(animations);
}

/* Whether a channel's (trimmed) track holds its node's own value at every
 * key: translation, rotation (q or -q) or scale of a node without a matrix. */
static bool holds_rest(const lk_scene *scene, const lk_scene_animation_channel *channel,
                       const lk_scene_animation_sampler *sampler)
{
    if (channel->node >= scene->node_count || channel->path == LK_SCENE_PATH_WEIGHTS ||
        sampler->interpolation == LK_SCENE_CUBICSPLINE || sampler->output_count != sampler->key_count)
        return false;
    const lk_scene_node *node = &scene->nodes[channel->node];
    if (node->has_matrix) return false;
    const double *rest = channel->path == LK_SCENE_PATH_TRANSLATION ? node->translation
                         : channel->path == LK_SCENE_PATH_ROTATION  ? node->rotation
                                                                    : node->scale;
    unsigned width = channel->path == LK_SCENE_PATH_ROTATION ? 4 : 3;
    if (sampler->components != width) return false;
    for (size_t k = 0; k < sampler->key_count; k++) {
        const float *value = sampler->output + k * width;
        bool same = true, opposite = channel->path == LK_SCENE_PATH_ROTATION;
        for (unsigned c = 0; c < width; c++) {
            double tolerance = 1e-6 * (fabs(rest[c]) > 1.0 ? fabs(rest[c]) : 1.0);
            same = same && fabs(value[c] - rest[c]) <= tolerance;
            opposite = opposite && fabs(value[c] + rest[c]) <= tolerance;
        }
        if (!same && !opposite) return false;
    }
    return true;
}

/* Drops the channels that hold their node's rest value (keeping the last
 * when all do) and the samplers no channel then uses. */
static void drop_resting(const lk_scene *scene, lk_scene_animation *animation)
{
    size_t kept = 0;
    for (size_t c = 0; c < animation->channel_count; c++) {
        const lk_scene_animation_channel *channel = &animation->channels[c];
        bool still = channel->sampler < animation->sampler_count &&
                     holds_rest(scene, channel, &animation->samplers[channel->sampler]);
        if (!still || (kept == 0 && c + 1 == animation->channel_count)) animation->channels[kept++] = *channel;
    }
    animation->channel_count = kept;
    size_t used = 0;
    for (size_t s = 0; s < animation->sampler_count; s++) {
        bool referenced = false;
        for (size_t c = 0; c < animation->channel_count; c++) referenced |= animation->channels[c].sampler == s;
        if (!referenced) {
            free(animation->samplers[s].input);
            free(animation->samplers[s].output);
            continue;
        }
        for (size_t c = 0; c < animation->channel_count; c++)
            if (animation->channels[c].sampler == s) animation->channels[c].sampler = (uint32_t)used;
        animation->samplers[used++] = animation->samplers[s];
    }
    animation->sampler_count = used;
}

lk_status lk__scene_trimmed_animations(const lk_scene *scene, lk_scene_animation **out, lk_error *error)
{
    *out = NULL;
    if (scene->animation_count == 0) return LK_OK;
    lk_scene_animation *animations = lk__calloc_array(scene->animation_count, sizeof *animations);
    bool ok = animations != NULL;
    for (size_t a = 0; ok && a < scene->animation_count; a++) {
        const lk_scene_animation *in = &scene->animations[a];
        animations[a] = *in; /* the name shared with the scene */
        animations[a].samplers = lk__calloc_array(in->sampler_count ? in->sampler_count : 1, sizeof(*in->samplers));
        animations[a].channels = lk__malloc_array(in->channel_count ? in->channel_count : 1, sizeof(*in->channels));
        ok = animations[a].samplers && animations[a].channels;
        if (ok && in->channel_count)
            memcpy(animations[a].channels, in->channels, in->channel_count * sizeof(*in->channels));
        for (size_t s = 0; ok && s < in->sampler_count; s++) {
            /* a sampler driving a rotation: equal keys only */
            bool rotation = false;
            for (size_t c = 0; c < in->channel_count; c++)
                rotation |= in->channels[c].sampler == s && in->channels[c].path == LK_SCENE_PATH_ROTATION;
            ok = trim_sampler(&in->samplers[s], &animations[a].samplers[s], rotation);
        }
        if (ok) drop_resting(scene, &animations[a]);
    }
    if (!ok) {
        lk__scene_animations_free(animations, scene->animation_count);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory trimming the animations");
    }
    *out = animations;
    return LK_OK;
}
