/* SPDX-License-Identifier: MIT */
/* The glTF scene writer's skins and animations: JOINTS_0 and WEIGHTS_0,
 * inverse bind matrices, animation samplers and channels.
 *
 * Compact output (docs/formats.md):
 *   - LK_GLTF_QUANTIZE: weights as normalised bytes (add_weight_bytes); a
 *     skinned mesh's positions on a grid whose transform goes into the
 *     inverse bind matrices of its skin (a skinned mesh's node transform
 *     does nothing in glTF); rotation keys as normalised shorts;
 *   - LK_GLTF_MESHOPT: rotation keys through meshopt's quaternion filter
 *     (12 bits) and translation and scale keys through its exponential
 *     filter (16-bit mantissas), gltfpack's defaults. */
#include "bytes.h"
#include "io_gltf.h"

#include <meshoptimizer.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* JOINTS_0: unsigned bytes when every joint is below 256, else shorts. */
static size_t add_joints(mesh_writer *writer, const uint16_t *joints, size_t count)
{
    bool bytes = true;
    for (size_t i = 0; i < 4 * count; i++) bytes &= joints[i] < 256;
    size_t size = bytes ? 1 : 2, offset = lk__gltf_reserve(writer, 4 * size * count);
    if (writer->failed) return 0;
    unsigned char *out = writer->bin.data + offset;
    for (size_t i = 0; i < 4 * count; i++) {
        if (bytes)
            out[i] = (unsigned char)joints[i];
        else
            lk__store_u16le(out + 2 * i, joints[i]);
    }
    lk__gltf_add_accessor(writer, offset, 4 * size * count, 4 * size, GLTF_TARGET_ARRAY_BUFFER,
                          bytes ? COMPONENT_UNSIGNED_BYTE : COMPONENT_UNSIGNED_SHORT, false, count, "VEC4");
    return writer->accessor_count - 1;
}

/* Weights as floats summing to 1 per vertex, as the specification wants.
 * The glTF-Validator adds each vertex's non-zero weights in float and
 * allows 2e-7 per weight; a vertex within that is kept as it is (a round
 * trip keeps the file's weights), others (simplification, 4 of more
 * influences) are divided by their sum. A vertex without weight gets all
 * of it on its first joint, the one a renderer falls back to anyway. */
static void normalise_weights(const float *weights, size_t count, float *normalised)
{
    for (size_t v = 0; v < count; v++) {
        const float *in = weights + 4 * v;
        float *out = normalised + 4 * v;
        float float_sum = 0;
        double sum = 0;
        int nonzero = 0;
        for (int k = 0; k < 4; k++) {
            float_sum += in[k], sum += in[k];
            nonzero += in[k] != 0;
        }
        if (nonzero && fabsf(float_sum - 1.0f) <= 2e-7f * (float)nonzero) {
            memcpy(out, in, 4 * sizeof(float));
            continue;
        }
        int largest = 0;
        for (int k = 0; k < 4; k++) {
            out[k] = sum > 0 ? (float)(in[k] / sum) : (k == 0 ? 1.0f : 0.0f);
            if (out[k] > out[largest]) largest = k;
        }
        /* what float rounding left over goes to the largest weight */
        out[largest] += 1.0f - (out[0] + out[1] + out[2] + out[3]);
    }
}

/* Compact output (LK_GLTF_QUANTIZE): weights as normalised unsigned bytes
 * (KHR_mesh_quantization), as gltfpack writes them: a quarter of the
 * bytes, steps of 1/255 (a vertex moves by at most 1/510 of a joint's
 * displacement). Each vertex's bytes sum to exactly 255, the rounding left
 * over going to its largest weight, so that they still sum to 1. */
static void weight_bytes(const float *normalised, size_t count, unsigned char *out)
{
    for (size_t v = 0; v < count; v++) {
        int sum = 0, largest = 0;
        for (int k = 0; k < 4; k++) {
            float weight = normalised[4 * v + (size_t)k];
            long q = lroundf((weight > 0 ? (weight < 1 ? weight : 1) : 0) * 255.0f);
            out[4 * v + (size_t)k] = (unsigned char)q;
            sum += (int)q;
            if (weight > normalised[4 * v + (size_t)largest]) largest = k;
        }
        out[4 * v + (size_t)largest] = (unsigned char)(out[4 * v + (size_t)largest] + 255 - sum);
    }
}

bool lk__gltf_add_skin_attributes(mesh_writer *writer, cJSON *attributes, const uint16_t *joints, const float *weights,
                                  size_t count)
{
    bool bytes = (writer->flags & LK_GLTF_QUANTIZE) != 0;
    float *normalised = lk__malloc_array(count ? count : 1, 4 * sizeof(float));
    uint16_t *used = lk__malloc_array(count ? count : 1, 4 * sizeof(uint16_t));
    unsigned char *quantised = bytes ? lk__malloc_array(count ? count : 1, 4) : NULL;
    if (!normalised || !used || (bytes && !quantised)) {
        free(normalised);
        free(used);
        free(quantised);
        writer->failed = true;
        return false;
    }
    normalise_weights(weights, count, normalised);
    if (bytes) weight_bytes(normalised, count, quantised);
    /* a joint without weight is 0: the validator warns about others */
    for (size_t i = 0; i < 4 * count; i++) used[i] = (bytes ? quantised[i] != 0 : normalised[i] != 0) ? joints[i] : 0;
    cJSON_AddNumberToObject(attributes, "JOINTS_0", (double)add_joints(writer, used, count));
    size_t accessor = 0;
    if (bytes) {
        size_t offset = lk__gltf_reserve(writer, 4 * count);
        if (!writer->failed) {
            memcpy(writer->bin.data + offset, quantised, 4 * count);
            lk__gltf_add_accessor(writer, offset, 4 * count, 4, GLTF_TARGET_ARRAY_BUFFER, COMPONENT_UNSIGNED_BYTE, true,
                                  count, "VEC4");
            writer->quantized = true;
            accessor = writer->accessor_count - 1;
        }
    } else {
        accessor = lk__gltf_add_float_data(writer, normalised, count, 4, "VEC4", false, GLTF_TARGET_ARRAY_BUFFER);
    }
    cJSON_AddNumberToObject(attributes, "WEIGHTS_0", (double)accessor);
    free(normalised);
    free(used);
    free(quantised);
    return !writer->failed;
}

/* Every primitive with vertices has joints and weights. */
bool lk__gltf_mesh_is_skinned(const lk_scene_mesh *mesh)
{
    bool skinned = false;
    for (size_t p = 0; p < mesh->primitive_count; p++) {
        const lk_scene_primitive *primitive = &mesh->primitives[p];
        if (primitive->mesh.vertex_count == 0) continue;
        if (!primitive->joints || !primitive->weights) return false;
        skinned = true;
    }
    return skinned;
}

void lk__gltf_matrix_times_grid(double m[16], const position_grid *grid)
{
    for (int row = 0; row < 4; row++) {
        double t = m[12 + row];
        for (int k = 0; k < 3; k++) t += m[k * 4 + row] * grid->origin[k];
        m[12 + row] = t;
        for (int column = 0; column < 3; column++) m[column * 4 + row] *= grid->step;
    }
}

/* An inverse bind matrix (column-major; NULL: the identity) times the
 * grid's transform into `out`: the joints then take quantised positions
 * (KHR_mesh_quantization) to where the float ones went. No grid: the
 * matrix as it is. */
static void fold_grid(const float *matrix, const position_grid *grid, float *out)
{
    double m[16];
    for (int i = 0; i < 16; i++) m[i] = matrix ? matrix[i] : (i % 5 == 0 ? 1.0 : 0.0);
    if (grid) lk__gltf_matrix_times_grid(m, grid);
    for (int i = 0; i < 16; i++) out[i] = (float)m[i];
}

/* Skins: joints (node indices are the scene's: written nodes keep them),
 * skeleton and inverse bind matrices (MAT4 floats, not vertex data). */
bool lk__gltf_add_skins(mesh_writer *writer, cJSON *root, const lk_scene *scene, const position_grid *skin_grids)
{
    if (scene->skin_count == 0) return true;
    cJSON *skins = cJSON_AddArrayToObject(root, "skins");
    if (!skins) return false;
    for (size_t i = 0; i < scene->skin_count; i++) {
        const lk_scene_skin *skin = &scene->skins[i];
        cJSON *json = cJSON_CreateObject();
        if (!json || !cJSON_AddItemToArray(skins, json)) {
            cJSON_Delete(json);
            return false;
        }
        if (skin->name) cJSON_AddStringToObject(json, "name", skin->name);
        const position_grid *grid = skin_grids && skin_grids[i].step > 0 ? &skin_grids[i] : NULL;
        if ((skin->inverse_bind_matrices || grid) && skin->joint_count) {
            float *matrices = lk__malloc_array(skin->joint_count, 16 * sizeof(float));
            if (!matrices) return false;
            for (size_t j = 0; j < skin->joint_count; j++)
                fold_grid(skin->inverse_bind_matrices ? skin->inverse_bind_matrices + 16 * j : NULL, grid,
                          matrices + 16 * j);
            cJSON_AddNumberToObject(
                json, "inverseBindMatrices",
                (double)lk__gltf_add_float_data(writer, matrices, skin->joint_count, 16, "MAT4", false, 0));
            free(matrices);
        }
        if (skin->skeleton >= 0 && (size_t)skin->skeleton < scene->node_count)
            cJSON_AddNumberToObject(json, "skeleton", skin->skeleton);
        cJSON *joints = cJSON_AddArrayToObject(json, "joints");
        for (size_t j = 0; joints && j < skin->joint_count; j++)
            cJSON_AddItemToArray(joints, cJSON_CreateNumber(skin->joints[j]));
    }
    return !writer->failed;
}

#define NO_PATH (-1)
#define MIXED_PATHS (-2)
#define ROTATION_BITS 12  /* meshopt's quaternion filter: gltfpack's default */
#define TRANSFORM_BITS 16 /* exponential filter's mantissa for translation and scale: the same */

/* A sampler's key values (`path`: what its channels drive). Floats, but
 * with compact output a rotation's keys (not CUBICSPLINE, whose tangents
 * are no unit quaternions) as normalised shorts, through meshopt's
 * quaternion filter when compressed; compressed translation and scale keys
 * through the exponential filter (still floats once decoded). */
static size_t add_output(mesh_writer *writer, const lk_scene_animation_sampler *sampler, int path)
{
    size_t count = sampler->output_count;
    unsigned components = sampler->components;
    const char *type = components == 4 ? "VEC4" : components == 3 ? "VEC3" : "SCALAR";
    bool meshopt = (writer->flags & LK_GLTF_MESHOPT) != 0;
    if (path == LK_SCENE_PATH_ROTATION && components == 4 && sampler->interpolation != LK_SCENE_CUBICSPLINE &&
        (writer->flags & LK_GLTF_QUANTIZE)) {
        float *unit = lk__malloc_array(count ? count : 1, 4 * sizeof(float));
        size_t offset = unit ? lk__gltf_reserve(writer, 8 * count) : 0;
        if (!unit || writer->failed) {
            free(unit);
            writer->failed = true;
            return 0;
        }
        for (size_t k = 0; k < count; k++) {
            const float *q = sampler->output + 4 * k;
            double length = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] + (double)q[3] * q[3]);
            for (int c = 0; c < 4; c++)
                unit[4 * k + (size_t)c] = length > 0 ? (float)(q[c] / length) : (c == 3 ? 1.0f : 0.0f);
        }
        unsigned char *out = writer->bin.data + offset;
        if (meshopt)
            meshopt_encodeFilterQuat(out, count, 8, ROTATION_BITS, unit);
        else
            for (size_t i = 0; i < 4 * count; i++)
                lk__store_u16le(out + 2 * i, (uint16_t)(int16_t)lroundf(unit[i] * 32767.0f));
        free(unit);
        lk__gltf_add_accessor(writer, offset, 8 * count, 8, 0, COMPONENT_SHORT, true, count, type);
        if (!writer->failed && meshopt) writer->records[writer->record_count - 1].filter = GLTF_FILTER_QUATERNION;
        return writer->accessor_count - 1;
    }
    if (meshopt && components == 3 && (path == LK_SCENE_PATH_TRANSLATION || path == LK_SCENE_PATH_SCALE)) {
        size_t offset = lk__gltf_reserve(writer, 12 * count);
        if (writer->failed) return 0;
        meshopt_encodeFilterExp(writer->bin.data + offset, count, 12, TRANSFORM_BITS, sampler->output);
        lk__gltf_add_accessor(writer, offset, 12 * count, 12, 0, COMPONENT_FLOAT, false, count, type);
        if (!writer->failed) writer->records[writer->record_count - 1].filter = GLTF_FILTER_EXPONENTIAL;
        return writer->accessor_count - 1;
    }
    return lk__gltf_add_float_data(writer, sampler->output, count, components, type, false, 0);
}

/* Animations: each sampler's key times (SCALAR floats with the min and max
 * glTF requires; a sampler with the times of one of the 8 before it shares
 * its accessor) and values (VEC3 / VEC4 floats). */
bool lk__gltf_add_animations(mesh_writer *writer, cJSON *root, const lk_scene *scene)
{
    if (scene->animation_count == 0) return true;
    static const char *const paths[] = {"translation", "rotation", "scale", "weights"};
    static const char *const interpolations[] = {"LINEAR", "STEP", "CUBICSPLINE"};
    cJSON *animations = cJSON_AddArrayToObject(root, "animations");
    if (!animations) return false;
    for (size_t a = 0; a < scene->animation_count; a++) {
        const lk_scene_animation *animation = &scene->animations[a];
        cJSON *json = cJSON_CreateObject();
        if (!json || !cJSON_AddItemToArray(animations, json)) {
            cJSON_Delete(json);
            return false;
        }
        if (animation->name) cJSON_AddStringToObject(json, "name", animation->name);
        cJSON *samplers = cJSON_AddArrayToObject(json, "samplers"),
              *channels = cJSON_AddArrayToObject(json, "channels");
        size_t *inputs = lk__malloc_array(animation->sampler_count ? animation->sampler_count : 1, sizeof *inputs);
        int *paths_of = lk__malloc_array(animation->sampler_count ? animation->sampler_count : 1, sizeof *paths_of);
        if (!samplers || !channels || !inputs || !paths_of) {
            free(inputs);
            free(paths_of);
            return false;
        }
        /* what each sampler drives: a path, or MIXED_PATHS (kept as floats) */
        for (size_t s = 0; s < animation->sampler_count; s++) paths_of[s] = NO_PATH;
        for (size_t c = 0; c < animation->channel_count; c++) {
            const lk_scene_animation_channel *channel = &animation->channels[c];
            if (channel->sampler >= animation->sampler_count) continue;
            int *path = &paths_of[channel->sampler];
            *path = *path == NO_PATH || *path == (int)channel->path ? (int)channel->path : MIXED_PATHS;
        }
        for (size_t s = 0; s < animation->sampler_count; s++) {
            const lk_scene_animation_sampler *sampler = &animation->samplers[s];
            cJSON *item = cJSON_CreateObject();
            if (!item || !cJSON_AddItemToArray(samplers, item)) {
                cJSON_Delete(item);
                free(inputs);
                free(paths_of);
                return false;
            }
            /* exporters give the samplers of an animation one set of times,
             * or one per bone in a row: the last few samplers are enough
             * to look at (and keep this linear) */
            inputs[s] = SIZE_MAX;
            for (size_t t = s > 64 ? s - 64 : 0; t < s && inputs[s] == SIZE_MAX; t++)
                if (animation->samplers[t].key_count == sampler->key_count &&
                    lk__gltf_same_floats(animation->samplers[t].input, sampler->input, sampler->key_count))
                    inputs[s] = inputs[t];
            if (inputs[s] == SIZE_MAX)
                inputs[s] = lk__gltf_add_float_data(writer, sampler->input, sampler->key_count, 1, "SCALAR", true, 0);
            cJSON_AddNumberToObject(item, "input", (double)inputs[s]);
            unsigned interpolation = (unsigned)sampler->interpolation;
            if (interpolation != LK_SCENE_LINEAR && interpolation < 3)
                cJSON_AddStringToObject(item, "interpolation", interpolations[interpolation]);
            cJSON_AddNumberToObject(item, "output", (double)add_output(writer, sampler, paths_of[s]));
        }
        free(inputs);
        free(paths_of);
        for (size_t c = 0; c < animation->channel_count; c++) {
            const lk_scene_animation_channel *channel = &animation->channels[c];
            cJSON *item = cJSON_CreateObject();
            if (!item || !cJSON_AddItemToArray(channels, item)) {
                cJSON_Delete(item);
                return false;
            }
            cJSON_AddNumberToObject(item, "sampler", channel->sampler);
            cJSON *target = cJSON_AddObjectToObject(item, "target");
            if (!target) return false;
            cJSON_AddNumberToObject(target, "node", channel->node);
            cJSON_AddStringToObject(target, "path", paths[(unsigned)channel->path < 4 ? channel->path : 0]);
        }
    }
    return !writer->failed;
}
