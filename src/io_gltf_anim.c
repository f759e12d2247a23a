/* SPDX-License-Identifier: MIT */
/* glTF animations: morph targets, skins and node animation, evaluated
 * frame by frame on the mesh the reader (io_gltf.c) reads.
 *
 * lk__anim_read_gltf reads the default scene like lk__read_gltf (that fixes
 * the connectivity and the attributes) and then evaluates the scene at every
 * frame time: animated node TRS (LINEAR with slerp for rotations, or STEP;
 * CUBICSPLINE is refused), morph target weights (POSITION deltas) and skins
 * (JOINTS_0/WEIGHTS_0, joint world matrix x inverseBindMatrix, linear blend).
 * As the specification says, a skinned mesh ignores its own node's
 * transform: the joints place it (pose_skins does the same for lk_mesh_read,
 * lk__read_gltf below, at the nodes' own transforms). Frame times are the union of the key
 * times of the chosen animation, or a uniform resampling at
 * frames_per_second over [first key, last key]. Normals, texture
 * coordinates and colours are those of the bind pose. */
#include "io_gltf.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { PATH_TRANSLATION, PATH_ROTATION, PATH_SCALE, PATH_WEIGHTS };

typedef struct anim_sampler {
    float *times;
    size_t key_count;
    float *values; /* key_count * width floats */
    size_t width;  /* floats per key */
    bool step;
} anim_sampler;

typedef struct anim_channel {
    size_t node;
    int path;
    size_t sampler; /* into the sampler list of all chosen animations */
} anim_channel;

/* Per node state at one time. */
typedef struct anim_node {
    double translation[3], rotation[4], scale[3];
    double rest_translation[3], rest_rotation[4], rest_scale[3]; /* the node's own values */
    double matrix[16];                                           /* "matrix" nodes (cannot be animated) */
    bool has_matrix;
    size_t parent; /* SIZE_MAX for roots */
    double world[16];
    size_t target_count; /* morph targets of its mesh */
    double *weights;     /* target_count, or NULL */
    double *rest_weights;
} anim_node;

/* What one instanced primitive needs each frame. */
typedef struct anim_primitive {
    const gltf_instance *instance;
    float *base;   /* 3 * count bind-pose positions (mesh space) */
    float *deltas; /* target_count * 3 * count, or NULL */
    size_t target_count;
    long skin;        /* index into skins, -1 when not skinned */
    uint16_t *joints; /* 4 * count */
    float *weights;   /* 4 * count, normalised; a vertex with sum 0 is unweighted */
} anim_primitive;

typedef struct anim_skin {
    size_t joint_count;
    size_t *joints;         /* node indices */
    double *inverse_bind;   /* 16 * joint_count */
    double *joint_matrices; /* 16 * joint_count, per frame */
} anim_skin;

typedef struct anim_state {
    gltf_reader *reader;
    const lk__anim_context *ctx;
    size_t node_count;
    anim_node *nodes;
    size_t *order; /* nodes, parents first */
    size_t sampler_count, channel_count;
    anim_sampler *samplers;
    anim_channel *channels;
    size_t primitive_count;
    anim_primitive *primitives;
    size_t skin_count;
    anim_skin *skins;
    json_table skins_json, animations_json;
} anim_state;

static void anim_state_free(anim_state *state)
{
    for (size_t i = 0; i < state->node_count && state->nodes; i++) {
        free(state->nodes[i].weights);
        free(state->nodes[i].rest_weights);
    }
    free(state->nodes);
    free(state->order);
    for (size_t i = 0; i < state->sampler_count; i++) {
        free(state->samplers[i].times);
        free(state->samplers[i].values);
    }
    free(state->samplers);
    free(state->channels);
    for (size_t i = 0; i < state->primitive_count; i++) {
        free(state->primitives[i].base);
        free(state->primitives[i].deltas);
        free(state->primitives[i].joints);
        free(state->primitives[i].weights);
    }
    free(state->primitives);
    for (size_t i = 0; i < state->skin_count; i++) {
        free(state->skins[i].joints);
        free(state->skins[i].inverse_bind);
        free(state->skins[i].joint_matrices);
    }
    free(state->skins);
    lk__gltf_table_free(state->reader, &state->skins_json);
    lk__gltf_table_free(state->reader, &state->animations_json);
}

/* Charges `count` elements of `size` bytes to the budget before they are
 * allocated: what the animation reader holds besides the mesh can be out
 * of proportion to the file (an accessor without a bufferView is `count`
 * zeros; every instance of a mesh gets its own morph deltas; a joint is 2
 * bytes of JSON and 264 bytes of matrices). These charges are not given
 * back: the animation state lives until the end of the read. */
static lk_status anim_charge(gltf_reader *reader, const char *where, const char *what, uint64_t count, uint64_t size)
{
    lk__budget *budget = reader->ctx->budget;
    if (count > SIZE_MAX || size > SIZE_MAX || !lk__budget_charge(budget, (size_t)count, (size_t)size))
        return lk__gltf_fail(reader, LK_ERR_LIMIT, where, NULL,
                             "%llu %s of %llu bytes would exceed the memory budget of %zu bytes (%zu already held)",
                             (unsigned long long)count, what, (unsigned long long)size, budget->limit, budget->held);
    return LK_OK;
}

/* Reads an accessor fully as floats (component_count per element; io_gltf.h). */
lk_status lk__gltf_read_accessor_floats(gltf_reader *reader, uint64_t index, const char *where, const char *key,
                                        unsigned type_mask, const char *expected, gltf_accessor *accessor, float **out)
{
    *out = NULL;
    bool was_allowed = reader->sparse_allowed;
    reader->sparse_allowed = true; /* applied below */
    lk_status status = lk__gltf_open_accessor(reader, index, where, key, type_mask, false, expected, accessor);
    reader->sparse_allowed = was_allowed;
    if (status == LK_OK)
        status = anim_charge(reader, where, "accessor elements", accessor->count,
                             (uint64_t)accessor->component_count * sizeof(float));
    if (status != LK_OK) return status;
    *out = lk__malloc_array(accessor->count, accessor->component_count * sizeof(float));
    if (!*out) return lk__gltf_nomem(reader);
    for (size_t i = 0; i < accessor->count; i++)
        lk__gltf_accessor_floats(accessor, i, *out + i * accessor->component_count);
    if ((status = lk__gltf_apply_sparse(reader, accessor, *out)) != LK_OK) {
        free(*out);
        *out = NULL;
        return status;
    }
    for (size_t i = 0; i < accessor->count; i++) {
        float *values = *out + i * accessor->component_count;
        for (unsigned c = 0; c < accessor->component_count; c++)
            if (!isfinite(values[c])) {
                /* Callers take ownership only on success. */
                free(*out);
                *out = NULL;
                char accessor_where[48];
                snprintf(accessor_where, sizeof accessor_where, "accessors[%zu]", accessor->index);
                return lk__gltf_fail(reader, LK_ERR_RANGE, accessor_where, NULL, "element %zu is not finite", i);
            }
    }
    return LK_OK;
}

static lk_status anim_nodes_init(anim_state *state)
{
    gltf_reader *reader = state->reader;
    size_t count = reader->nodes.count;
    lk_status charged =
        anim_charge(reader, "nodes", "node states", count, sizeof *state->nodes + sizeof *state->order + 1);
    if (charged != LK_OK) return charged;
    state->node_count = count;
    state->nodes = lk__calloc_array(count, sizeof *state->nodes);
    state->order = lk__malloc_array(count, sizeof *state->order);
    if (!state->nodes || !state->order) return lk__gltf_nomem(reader);
    for (size_t i = 0; i < count; i++) state->nodes[i].parent = SIZE_MAX;
    for (size_t i = 0; i < count; i++) {
        const cJSON *node = reader->nodes.items[i];
        anim_node *n = &state->nodes[i];
        char where[48];
        snprintf(where, sizeof where, "nodes[%zu]", i);
        double t[3] = {0, 0, 0}, r[4] = {0, 0, 0, 1}, sc[3] = {1, 1, 1};
        bool present;
        lk_status status = lk__gltf_get_number_array(reader, node, where, "matrix", 16, n->matrix, &present);
        if (status != LK_OK) return status;
        n->has_matrix = present;
        if ((status = lk__gltf_get_number_array(reader, node, where, "translation", 3, t, NULL)) != LK_OK)
            return status;
        if ((status = lk__gltf_get_number_array(reader, node, where, "rotation", 4, r, NULL)) != LK_OK) return status;
        if ((status = lk__gltf_get_number_array(reader, node, where, "scale", 3, sc, NULL)) != LK_OK) return status;
        memcpy(n->rest_translation, t, sizeof t);
        memcpy(n->rest_rotation, r, sizeof r);
        memcpy(n->rest_scale, sc, sizeof sc);
        const cJSON *children = lk__gltf_member(node, "children"), *child;
        if (!cJSON_IsArray(children)) continue;
        cJSON_ArrayForEach(child, children)
        {
            if ((status = lk__gltf_check_uint(reader, child, where, "children")) != LK_OK) return status;
            if (child->valuedouble >= (double)count)
                return lk__gltf_fail(reader, LK_ERR_RANGE, where, "children", "node %.0f out of range (%zu node%s)",
                                     child->valuedouble, count, count == 1 ? "" : "s");
            size_t c = (size_t)child->valuedouble;
            if (state->nodes[c].parent != SIZE_MAX || c == i)
                return lk__gltf_fail(reader, LK_ERR_PARSE, where, "children",
                                     "node %zu has two parents or is its own child", c);
            state->nodes[c].parent = i;
        }
    }
    /* Parents-first order: repeatedly take nodes whose parent is placed.
     * Nodes on a cycle never get placed and are reported. */
    unsigned char *placed = lk__calloc_array(count, 1);
    if (!placed) return lk__gltf_nomem(reader);
    size_t placed_count = 0;
    for (size_t i = 0; i < count; i++)
        if (state->nodes[i].parent == SIZE_MAX) {
            state->order[placed_count++] = i;
            placed[i] = 1;
        }
    for (size_t head = 0; head < placed_count; head++) {
        const cJSON *children = lk__gltf_member(reader->nodes.items[state->order[head]], "children"), *child;
        if (!cJSON_IsArray(children)) continue;
        cJSON_ArrayForEach(child, children)
        {
            size_t c = (size_t)child->valuedouble;
            if (!placed[c]) {
                placed[c] = 1;
                state->order[placed_count++] = c;
            }
        }
    }
    free(placed);
    if (placed_count != count)
        return lk__gltf_fail(reader, LK_ERR_PARSE, "", "nodes", "the node hierarchy has a cycle");
    return LK_OK;
}

static void quaternion_matrix(const double q_in[4], const double scale[3], const double translation[3], double m[16])
{
    double length = sqrt(q_in[0] * q_in[0] + q_in[1] * q_in[1] + q_in[2] * q_in[2] + q_in[3] * q_in[3]);
    double x = 0, y = 0, z = 0, w = 1;
    if (length > 0 && isfinite(length))
        x = q_in[0] / length, y = q_in[1] / length, z = q_in[2] / length, w = q_in[3] / length;
    double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    for (int column = 0; column < 3; column++) {
        for (int row = 0; row < 3; row++) m[column * 4 + row] = r[column * 3 + row] * scale[column];
        m[column * 4 + 3] = 0.0;
    }
    m[12] = translation[0];
    m[13] = translation[1];
    m[14] = translation[2];
    m[15] = 1.0;
}

/* Reads the samplers and channels of one animation; sampler indices are
 * offset by the samplers already read (for all_animations). */
static lk_status anim_read_animation(anim_state *state, size_t chosen)
{
    gltf_reader *reader = state->reader;
    lk_status status;
    const cJSON *animation = state->animations_json.items[chosen];
    char where[48];
    snprintf(where, sizeof where, "animations[%zu]", chosen);
    const cJSON *samplers, *channels, *item;
    if ((status = lk__gltf_get_array(reader, animation, where, "samplers", &samplers)) != LK_OK) return status;
    if ((status = lk__gltf_get_array(reader, animation, where, "channels", &channels)) != LK_OK) return status;
    if (!samplers || !channels)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "needs \"samplers\" and \"channels\"");
    size_t sampler_base = state->sampler_count;
    size_t sampler_count = (size_t)cJSON_GetArraySize(samplers), channel_count = (size_t)cJSON_GetArraySize(channels);
    status = anim_charge(reader, where, "samplers and channels", sampler_count + channel_count + 2,
                         sizeof(anim_sampler) + sizeof(anim_channel));
    if (status != LK_OK) return status;
    anim_sampler *grown_samplers =
        lk__realloc_array(state->samplers, sampler_base + sampler_count + 1, sizeof *state->samplers);
    if (!grown_samplers) return lk__gltf_nomem(reader);
    state->samplers = grown_samplers;
    memset(state->samplers + sampler_base, 0, (sampler_count + 1) * sizeof *state->samplers);
    anim_channel *grown_channels =
        lk__realloc_array(state->channels, state->channel_count + channel_count + 1, sizeof *state->channels);
    if (!grown_channels) return lk__gltf_nomem(reader);
    state->channels = grown_channels;
    size_t index = 0;
    cJSON_ArrayForEach(item, samplers)
    {
        char sampler_where[80];
        snprintf(sampler_where, sizeof sampler_where, "%s.samplers[%zu]", where, index);
        anim_sampler *sampler = &state->samplers[sampler_base + index];
        index++;
        state->sampler_count = sampler_base + index;
        if (!cJSON_IsObject(item))
            return lk__gltf_fail(reader, LK_ERR_PARSE, sampler_where, NULL, "expected an object");
        const cJSON *interpolation;
        if ((status = lk__gltf_get_string(reader, item, sampler_where, "interpolation", &interpolation)) != LK_OK)
            return status;
        if (interpolation && strcmp(interpolation->valuestring, "CUBICSPLINE") == 0)
            return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, sampler_where, "interpolation",
                                 "CUBICSPLINE is not supported (only LINEAR and STEP); resample the animation first");
        if (interpolation && strcmp(interpolation->valuestring, "STEP") != 0 &&
            strcmp(interpolation->valuestring, "LINEAR") != 0)
            return lk__gltf_fail(reader, LK_ERR_PARSE, sampler_where, "interpolation",
                                 "\"%.40s\" is not LINEAR, STEP or CUBICSPLINE", interpolation->valuestring);
        sampler->step = interpolation && strcmp(interpolation->valuestring, "STEP") == 0;
        uint64_t input, output;
        if ((status = lk__gltf_get_uint(reader, item, sampler_where, "input", true, 0, &input)) != LK_OK) return status;
        if ((status = lk__gltf_get_uint(reader, item, sampler_where, "output", true, 0, &output)) != LK_OK)
            return status;
        gltf_accessor accessor;
        status = lk__gltf_read_accessor_floats(reader, input, sampler_where, "input", TYPE_SCALAR, "a SCALAR",
                                               &accessor, &sampler->times);
        if (status != LK_OK) return status;
        if (accessor.component_type != COMPONENT_FLOAT)
            return lk__gltf_fail(reader, LK_ERR_PARSE, sampler_where, "input",
                                 "key times must be floats (componentType 5126)");
        sampler->key_count = accessor.count;
        for (size_t k = 1; k < sampler->key_count; k++)
            if (!(sampler->times[k] > sampler->times[k - 1]))
                return lk__gltf_fail(reader, LK_ERR_RANGE, sampler_where, "input",
                                     "key times must increase strictly (key %zu: %g after %g)", k,
                                     (double)sampler->times[k], (double)sampler->times[k - 1]);
        status =
            lk__gltf_read_accessor_floats(reader, output, sampler_where, "output", TYPE_SCALAR | TYPE_VEC3 | TYPE_VEC4,
                                          "a SCALAR, VEC3 or VEC4", &accessor, &sampler->values);
        if (status != LK_OK) return status;
        if (accessor.count % sampler->key_count != 0)
            return lk__gltf_fail(reader, LK_ERR_RANGE, sampler_where, "output",
                                 "%zu output elements for %zu key times (not a multiple)", accessor.count,
                                 sampler->key_count);
        sampler->width = accessor.count / sampler->key_count * accessor.component_count;
    }
    index = 0;
    cJSON_ArrayForEach(item, channels)
    {
        char channel_where[80];
        snprintf(channel_where, sizeof channel_where, "%s.channels[%zu]", where, index++);
        if (!cJSON_IsObject(item))
            return lk__gltf_fail(reader, LK_ERR_PARSE, channel_where, NULL, "expected an object");
        uint64_t sampler_index, node_index;
        const cJSON *target, *path;
        if ((status = lk__gltf_get_uint(reader, item, channel_where, "sampler", true, 0, &sampler_index)) != LK_OK)
            return status;
        if (sampler_index >= sampler_count)
            return lk__gltf_fail(reader, LK_ERR_RANGE, channel_where, "sampler",
                                 "sampler %llu out of range (%zu sampler%s)", (unsigned long long)sampler_index,
                                 sampler_count, sampler_count == 1 ? "" : "s");
        sampler_index += sampler_base;
        if ((status = lk__gltf_get_object(reader, item, channel_where, "target", &target)) != LK_OK) return status;
        if (!target) return lk__gltf_fail(reader, LK_ERR_PARSE, channel_where, NULL, "missing required \"target\"");
        char target_where[96];
        snprintf(target_where, sizeof target_where, "%s.target", channel_where);
        if ((status = lk__gltf_get_uint(reader, target, target_where, "node", false, UINT64_MAX, &node_index)) != LK_OK)
            return status;
        if (node_index == UINT64_MAX) continue; /* targets something an extension defines */
        if (node_index >= state->node_count)
            return lk__gltf_fail(reader, LK_ERR_RANGE, target_where, "node", "node %llu out of range (%zu node%s)",
                                 (unsigned long long)node_index, state->node_count, state->node_count == 1 ? "" : "s");
        if ((status = lk__gltf_get_string(reader, target, target_where, "path", &path)) != LK_OK) return status;
        if (!path) return lk__gltf_fail(reader, LK_ERR_PARSE, target_where, NULL, "missing required \"path\"");
        int path_id;
        size_t width;
        anim_node *node = &state->nodes[node_index];
        if (strcmp(path->valuestring, "translation") == 0)
            path_id = PATH_TRANSLATION, width = 3;
        else if (strcmp(path->valuestring, "rotation") == 0)
            path_id = PATH_ROTATION, width = 4;
        else if (strcmp(path->valuestring, "scale") == 0)
            path_id = PATH_SCALE, width = 3;
        else if (strcmp(path->valuestring, "weights") == 0)
            path_id = PATH_WEIGHTS, width = node->target_count;
        else
            return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, target_where, "path",
                                 "\"%.40s\" is not an animatable node property", path->valuestring);
        if (path_id != PATH_WEIGHTS && node->has_matrix)
            return lk__gltf_fail(reader, LK_ERR_PARSE, target_where, "node",
                                 "node %llu has a \"matrix\" and cannot be animated (glTF requires TRS)",
                                 (unsigned long long)node_index);
        if (path_id == PATH_WEIGHTS && node->target_count == 0)
            return lk__gltf_fail(reader, LK_ERR_PARSE, target_where, "node", "node %llu has no morph targets to weigh",
                                 (unsigned long long)node_index);
        if (state->samplers[sampler_index].width != width)
            return lk__gltf_fail(reader, LK_ERR_RANGE, channel_where, "sampler",
                                 "sampler %llu gives %zu values per key but \"%s\" needs %zu",
                                 (unsigned long long)(sampler_index - sampler_base),
                                 state->samplers[sampler_index].width, path->valuestring, width);
        anim_channel *channel = &state->channels[state->channel_count++];
        channel->node = (size_t)node_index;
        channel->path = path_id;
        channel->sampler = (size_t)sampler_index;
    }
    return LK_OK;
}


/* Which animations play: `animation_index`, all of them, or none when the
 * file has no animations (then one frame of the static pose). */
static lk_status anim_read_channels(anim_state *state)
{
    gltf_reader *reader = state->reader;
    lk_status status = lk__gltf_build_table(reader, "animations", &state->animations_json);
    if (status != LK_OK) return status;
    if (state->animations_json.count == 0) return LK_OK;
    if (state->ctx->all_animations) {
        for (size_t a = 0; a < state->animations_json.count; a++)
            if ((status = anim_read_animation(state, a)) != LK_OK) return status;
        return LK_OK;
    }
    size_t chosen = state->ctx->animation_index;
    if (chosen >= state->animations_json.count)
        return lk__gltf_fail(reader, LK_ERR_RANGE, "", "animations", "animation %zu requested but the file has %zu",
                             chosen, state->animations_json.count);
    return anim_read_animation(state, chosen);
}

/* Decodes the morph targets, skins and weights of every instanced primitive. */
static lk_status anim_read_primitives(anim_state *state, lk_animation_report *report)
{
    gltf_reader *reader = state->reader;
    lk_status status = lk__gltf_build_table(reader, "skins", &state->skins_json);
    if (status != LK_OK) return status;
    state->skin_count = state->skins_json.count;
    if ((status = anim_charge(reader, "skins", "skins", state->skin_count, sizeof *state->skins)) != LK_OK)
        return status;
    state->skins = lk__calloc_array(state->skin_count, sizeof *state->skins);
    if (!state->skins) return lk__gltf_nomem(reader);
    for (size_t s = 0; s < state->skin_count; s++) {
        const cJSON *skin = state->skins_json.items[s], *joints, *item;
        anim_skin *out = &state->skins[s];
        char where[48];
        snprintf(where, sizeof where, "skins[%zu]", s);
        if ((status = lk__gltf_get_array(reader, skin, where, "joints", &joints)) != LK_OK) return status;
        if (!joints || cJSON_GetArraySize(joints) == 0)
            return lk__gltf_fail(reader, LK_ERR_PARSE, where, "joints", "missing or empty");
        out->joint_count = (size_t)cJSON_GetArraySize(joints);
        if ((status = anim_charge(reader, where, "joints", out->joint_count, sizeof(size_t) + 32 * sizeof(double))) !=
            LK_OK)
            return status;
        out->joints = lk__malloc_array(out->joint_count, sizeof *out->joints);
        out->inverse_bind = lk__malloc_array(out->joint_count, 16 * sizeof(double));
        out->joint_matrices = lk__malloc_array(out->joint_count, 16 * sizeof(double));
        if (!out->joints || !out->inverse_bind || !out->joint_matrices) return lk__gltf_nomem(reader);
        size_t j = 0;
        cJSON_ArrayForEach(item, joints)
        {
            if ((status = lk__gltf_check_uint(reader, item, where, "joints")) != LK_OK) return status;
            if (item->valuedouble >= (double)state->node_count)
                return lk__gltf_fail(reader, LK_ERR_RANGE, where, "joints", "node %.0f out of range (%zu node%s)",
                                     item->valuedouble, state->node_count, state->node_count == 1 ? "" : "s");
            out->joints[j] = (size_t)item->valuedouble;
            lk__mat4_identity(out->inverse_bind + 16 * j);
            j++;
        }
        uint64_t ibm;
        if ((status = lk__gltf_get_uint(reader, skin, where, "inverseBindMatrices", false, UINT64_MAX, &ibm)) != LK_OK)
            return status;
        if (ibm != UINT64_MAX) {
            gltf_accessor accessor;
            float *values = NULL;
            status = lk__gltf_read_accessor_floats(reader, ibm, where, "inverseBindMatrices", TYPE_MAT4, "a MAT4",
                                                   &accessor, &values);
            if (status == LK_OK && accessor.count < out->joint_count)
                status = lk__gltf_fail(reader, LK_ERR_RANGE, where, "inverseBindMatrices",
                                       "accessor %llu has %zu matrices for %zu joints", (unsigned long long)ibm,
                                       accessor.count, out->joint_count);
            if (status == LK_OK)
                for (size_t k = 0; k < 16 * out->joint_count; k++) out->inverse_bind[k] = values[k];
            free(values);
            if (status != LK_OK) return status;
        }
        if (out->joint_count > report->bone_count) report->bone_count = out->joint_count;
    }

    const gltf_instance *instances = (const gltf_instance *)reader->instances.data;
    state->primitive_count = reader->instances.size / sizeof(gltf_instance);
    if ((status = anim_charge(reader, "meshes", "primitive instances", state->primitive_count,
                              sizeof *state->primitives)) != LK_OK)
        return status;
    state->primitives = lk__calloc_array(state->primitive_count, sizeof *state->primitives);
    if (!state->primitives) return lk__gltf_nomem(reader);
    for (size_t p = 0; p < state->primitive_count; p++) {
        const gltf_instance *instance = &instances[p];
        anim_primitive *out = &state->primitives[p];
        out->instance = instance;
        out->skin = -1;
        char where[96];
        snprintf(where, sizeof where, "meshes[%zu]", instance->mesh);
        primitive_attributes attributes;
        if ((status = lk__gltf_open_attributes(reader, instance->primitive, where, &attributes)) != LK_OK)
            return status;
        size_t count = instance->count;
        if ((status = anim_charge(reader, where, "bind-pose positions", count, 3 * sizeof(float))) != LK_OK)
            return status;
        out->base = lk__malloc_array(count, 3 * sizeof(float));
        if (!out->base) return lk__gltf_nomem(reader);
        for (size_t v = 0; v < count; v++) lk__gltf_accessor_floats(&attributes.position, v, out->base + 3 * v);
        /* Morph targets. */
        const cJSON *targets = lk__gltf_member(instance->primitive, "targets"), *target;
        if (cJSON_IsArray(targets) && cJSON_GetArraySize(targets) > 0) {
            out->target_count = (size_t)cJSON_GetArraySize(targets);
            if ((status = anim_charge(reader, where, "morph target deltas", out->target_count,
                                      3 * (uint64_t)count * sizeof(float))) != LK_OK)
                return status;
            out->deltas = lk__calloc_array(out->target_count, 3 * count * sizeof(float));
            if (!out->deltas) return lk__gltf_nomem(reader);
            size_t k = 0;
            cJSON_ArrayForEach(target, targets)
            {
                char target_where[128];
                snprintf(target_where, sizeof target_where, "%s.primitives.targets[%zu]", where, k);
                uint64_t position;
                if (!cJSON_IsObject(target))
                    return lk__gltf_fail(reader, LK_ERR_PARSE, target_where, NULL, "expected an object");
                if ((status = lk__gltf_get_uint(reader, target, target_where, "POSITION", false, UINT64_MAX,
                                                &position)) != LK_OK)
                    return status;
                if (position != UINT64_MAX) {
                    gltf_accessor accessor;
                    float *values;
                    status = lk__gltf_read_accessor_floats(reader, position, target_where, "POSITION", TYPE_VEC3,
                                                           "a VEC3", &accessor, &values);
                    if (status == LK_OK && accessor.count != count)
                        status = lk__gltf_fail(reader, LK_ERR_RANGE, target_where, "POSITION",
                                               "%zu deltas for %zu vertices", accessor.count, count);
                    if (status == LK_OK) memcpy(out->deltas + k * 3 * count, values, 3 * count * sizeof(float));
                    free(values);
                    if (status != LK_OK) return status;
                }
                k++;
            }
            report->morphed = 1;
        }
        if (instance->node == SIZE_MAX) continue;
        anim_node *node = &state->nodes[instance->node];
        if (out->target_count) {
            if (node->target_count && node->target_count != out->target_count)
                return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                                     "primitives have different numbers of morph targets (%zu and %zu)",
                                     node->target_count, out->target_count);
            node->target_count = out->target_count;
        }
        /* Skin. */
        const cJSON *node_json = reader->nodes.items[instance->node];
        char node_where[48];
        snprintf(node_where, sizeof node_where, "nodes[%zu]", instance->node);
        uint64_t skin_index;
        if ((status = lk__gltf_get_uint(reader, node_json, node_where, "skin", false, UINT64_MAX, &skin_index)) !=
            LK_OK)
            return status;
        if (skin_index == UINT64_MAX) continue;
        if (skin_index >= state->skin_count)
            return lk__gltf_fail(reader, LK_ERR_RANGE, node_where, "skin", "skin %llu out of range (%zu skin%s)",
                                 (unsigned long long)skin_index, state->skin_count, state->skin_count == 1 ? "" : "s");
        const cJSON *map = lk__gltf_member(instance->primitive, "attributes");
        char map_where[128];
        snprintf(map_where, sizeof map_where, "%s.attributes", where);
        uint64_t joints_index, weights_index;
        if ((status = lk__gltf_get_uint(reader, map, map_where, "JOINTS_0", false, UINT64_MAX, &joints_index)) !=
                LK_OK ||
            (status = lk__gltf_get_uint(reader, map, map_where, "WEIGHTS_0", false, UINT64_MAX, &weights_index)) !=
                LK_OK)
            return status;
        if (joints_index == UINT64_MAX || weights_index == UINT64_MAX)
            return lk__gltf_fail(reader, LK_ERR_PARSE, map_where, NULL,
                                 "the node has a skin but the primitive lacks JOINTS_0 or WEIGHTS_0");
        if (lk__gltf_member(map, "JOINTS_1"))
            return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, map_where, "JOINTS_1",
                                 "more than 4 joints per vertex (JOINTS_1) are not supported");
        gltf_accessor joints, weights;
        if ((status = lk__gltf_open_accessor(reader, joints_index, map_where, "JOINTS_0", TYPE_VEC4, false, "a VEC4",
                                             &joints)) != LK_OK)
            return status;
        if (joints.component_type != COMPONENT_UNSIGNED_BYTE && joints.component_type != COMPONENT_UNSIGNED_SHORT)
            return lk__gltf_fail(reader, LK_ERR_PARSE, map_where, "JOINTS_0",
                                 "joints must be unsigned bytes or shorts");
        float *weight_values;
        if ((status = lk__gltf_read_accessor_floats(reader, weights_index, map_where, "WEIGHTS_0", TYPE_VEC4, "a VEC4",
                                                    &weights, &weight_values)) != LK_OK)
            return status;
        out->weights = weight_values;
        if (joints.count != count || weights.count != count)
            return lk__gltf_fail(reader, LK_ERR_RANGE, map_where, NULL,
                                 "JOINTS_0 (%zu) or WEIGHTS_0 (%zu) is not per vertex (%zu)", joints.count,
                                 weights.count, count);
        if ((status = anim_charge(reader, map_where, "joint indices", count, 4 * sizeof(uint16_t))) != LK_OK)
            return status;
        out->joints = lk__malloc_array(count, 4 * sizeof(uint16_t));
        if (!out->joints) return lk__gltf_nomem(reader);
        const anim_skin *skin = &state->skins[skin_index];
        for (size_t v = 0; v < count; v++) {
            float j[4];
            lk__gltf_accessor_floats(&joints, v, j);
            double sum = 0;
            for (int k = 0; k < 4; k++) {
                float w = out->weights[4 * v + (size_t)k];
                if (w < 0)
                    return lk__gltf_fail(reader, LK_ERR_RANGE, map_where, "WEIGHTS_0",
                                         "vertex %zu has a negative weight (%g)", v, (double)w);
                if (w > 0 && j[k] >= (float)skin->joint_count)
                    return lk__gltf_fail(reader, LK_ERR_RANGE, map_where, "JOINTS_0",
                                         "vertex %zu uses joint %.0f but skins[%llu] has %zu joints", v, (double)j[k],
                                         (unsigned long long)skin_index, skin->joint_count);
                out->joints[4 * v + (size_t)k] = w > 0 ? (uint16_t)j[k] : 0;
                sum += w;
            }
            if (!(sum > 0)) {
                report->vertices_unweighted++;
                continue;
            }
            if (fabs(sum - 1) > 1e-3) report->weights_normalised++;
            for (int k = 0; k < 4; k++)
                out->weights[4 * v + (size_t)k] = (float)(out->weights[4 * v + (size_t)k] / sum);
        }
        out->skin = (long)skin_index;
        report->skinned = 1;
    }
    /* Morph weights of nodes: node.weights, else mesh.weights, else 0. */
    for (size_t i = 0; i < state->node_count; i++) {
        anim_node *node = &state->nodes[i];
        if (!node->target_count) continue;
        if ((status = anim_charge(reader, "nodes", "morph weights", node->target_count, 2 * sizeof(double))) != LK_OK)
            return status;
        node->weights = lk__calloc_array(node->target_count, sizeof(double));
        node->rest_weights = lk__calloc_array(node->target_count, sizeof(double));
        if (!node->weights || !node->rest_weights) return lk__gltf_nomem(reader);
        char where[48];
        snprintf(where, sizeof where, "nodes[%zu]", i);
        bool present = false;
        const cJSON *node_json = reader->nodes.items[i];
        if (lk__gltf_member(node_json, "weights")) {
            status = lk__gltf_get_number_array(reader, node_json, where, "weights", node->target_count,
                                               node->rest_weights, &present);
            if (status != LK_OK) return status;
        }
        if (!present) {
            uint64_t mesh_index;
            if ((status = lk__gltf_get_uint(reader, node_json, where, "mesh", false, UINT64_MAX, &mesh_index)) != LK_OK)
                return status;
            if (mesh_index < reader->meshes.count && lk__gltf_member(reader->meshes.items[mesh_index], "weights")) {
                snprintf(where, sizeof where, "meshes[%llu]", (unsigned long long)mesh_index);
                status = lk__gltf_get_number_array(reader, reader->meshes.items[mesh_index], where, "weights",
                                                   node->target_count, node->rest_weights, NULL);
                if (status != LK_OK) return status;
            }
        }
    }
    return LK_OK;
}

/* Value of a sampler at time t into out (width floats). */
static void sampler_evaluate(const anim_sampler *sampler, double t, bool rotation, double *out)
{
    size_t width = sampler->width, last = sampler->key_count - 1;
    const float *values = sampler->values;
    if (t <= sampler->times[0] || last == 0) {
        for (size_t c = 0; c < width; c++) out[c] = values[c];
        return;
    }
    if (t >= sampler->times[last]) {
        for (size_t c = 0; c < width; c++) out[c] = values[last * width + c];
        return;
    }
    size_t lo = 0, hi = last; /* times[lo] <= t < times[hi] */
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (sampler->times[mid] <= t)
            lo = mid;
        else
            hi = mid;
    }
    const float *a = values + lo * width, *b = values + hi * width;
    if (sampler->step) {
        for (size_t c = 0; c < width; c++) out[c] = a[c];
        return;
    }
    double u = (t - sampler->times[lo]) / ((double)sampler->times[hi] - sampler->times[lo]);
    if (!rotation) {
        for (size_t c = 0; c < width; c++) out[c] = a[c] + (b[c] - (double)a[c]) * u;
        return;
    }
    /* Spherical interpolation along the shorter arc. */
    double dot = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2] + (double)a[3] * b[3];
    double sign = dot < 0 ? -1.0 : 1.0;
    dot *= sign;
    double wa = 1 - u, wb = u * sign;
    if (dot < 0.9995) {
        double angle = acos(dot > 1 ? 1 : dot), s = sin(angle);
        wa = sin((1 - u) * angle) / s;
        wb = sin(u * angle) / s * sign;
    }
    double length = 0;
    for (int c = 0; c < 4; c++) {
        out[c] = wa * a[c] + wb * b[c];
        length += out[c] * out[c];
    }
    length = sqrt(length);
    if (length > 0)
        for (int c = 0; c < 4; c++) out[c] /= length;
}

/* Poses the instanced primitives at time t into `positions` (all of them,
 * or with skinned_only those with a skin). */
static lk_status anim_evaluate(anim_state *state, double t, float *positions, size_t frame, bool skinned_only)
{
    gltf_reader *reader = state->reader;
    for (size_t i = 0; i < state->node_count; i++) {
        anim_node *n = &state->nodes[i];
        /* Start from the node's own values each frame. */
        memcpy(n->translation, n->rest_translation, sizeof n->translation);
        memcpy(n->rotation, n->rest_rotation, sizeof n->rotation);
        memcpy(n->scale, n->rest_scale, sizeof n->scale);
        if (n->target_count) memcpy(n->weights, n->rest_weights, n->target_count * sizeof(double));
    }
    for (size_t c = 0; c < state->channel_count; c++) {
        const anim_channel *channel = &state->channels[c];
        anim_node *n = &state->nodes[channel->node];
        const anim_sampler *sampler = &state->samplers[channel->sampler];
        switch (channel->path) {
        case PATH_TRANSLATION: sampler_evaluate(sampler, t, false, n->translation); break;
        case PATH_ROTATION: sampler_evaluate(sampler, t, true, n->rotation); break;
        case PATH_SCALE: sampler_evaluate(sampler, t, false, n->scale); break;
        default: sampler_evaluate(sampler, t, false, n->weights); break;
        }
    }
    for (size_t k = 0; k < state->node_count; k++) {
        size_t i = state->order[k];
        anim_node *n = &state->nodes[i];
        double local[16];
        if (n->has_matrix)
            memcpy(local, n->matrix, sizeof local);
        else
            quaternion_matrix(n->rotation, n->scale, n->translation, local);
        if (n->parent == SIZE_MAX)
            memcpy(n->world, local, sizeof local);
        else
            lk__mat4_multiply(state->nodes[n->parent].world, local, n->world);
    }
    for (size_t s = 0; s < state->skin_count; s++) {
        anim_skin *skin = &state->skins[s];
        for (size_t j = 0; j < skin->joint_count; j++)
            lk__mat4_multiply(state->nodes[skin->joints[j]].world, skin->inverse_bind + 16 * j,
                              skin->joint_matrices + 16 * j);
    }
    for (size_t p = 0; p < state->primitive_count; p++) {
        const anim_primitive *primitive = &state->primitives[p];
        if (skinned_only && primitive->skin < 0) continue;
        const gltf_instance *instance = primitive->instance;
        const anim_node *node = instance->node == SIZE_MAX ? NULL : &state->nodes[instance->node];
        double identity[16];
        lk__mat4_identity(identity);
        const double *world = node ? node->world : identity;
        const anim_skin *skin = primitive->skin >= 0 ? &state->skins[primitive->skin] : NULL;
        for (size_t v = 0; v < instance->count; v++) {
            double position[3];
            for (int c = 0; c < 3; c++) position[c] = primitive->base[3 * v + (size_t)c];
            if (primitive->deltas && node && node->weights)
                for (size_t k = 0; k < primitive->target_count; k++) {
                    if (node->weights[k] == 0) continue; /* most are, in key-frame morphs */
                    const float *d = primitive->deltas + (k * instance->count + v) * 3;
                    for (int c = 0; c < 3; c++) position[c] += node->weights[k] * d[c];
                }
            double out[3] = {0, 0, 0};
            const float *w = primitive->weights ? primitive->weights + 4 * v : NULL;
            /* an unweighted vertex follows its first joint, as the writer
             * (and a renderer, falling back) makes it */
            static const float first_joint[4] = {1, 0, 0, 0};
            if (skin && !(w[0] > 0 || w[1] > 0 || w[2] > 0 || w[3] > 0)) w = first_joint;
            if (skin) {
                for (int k = 0; k < 4; k++) {
                    if (!(w[k] > 0)) continue;
                    const double *m = skin->joint_matrices + 16 * primitive->joints[4 * v + (size_t)k];
                    for (int r = 0; r < 3; r++)
                        out[r] +=
                            w[k] * (m[r] * position[0] + m[4 + r] * position[1] + m[8 + r] * position[2] + m[12 + r]);
                }
            } else {
                for (int r = 0; r < 3; r++)
                    out[r] = world[r] * position[0] + world[4 + r] * position[1] + world[8 + r] * position[2] +
                             world[12 + r];
            }
            float *dst = positions + 3 * (instance->base + v);
            for (int r = 0; r < 3; r++) {
                dst[r] = (float)out[r];
                if (!isfinite(dst[r]))
                    return lk_error_set(reader->error, LK_ERR_RANGE,
                                        "%s: frame %zu (t = %g): vertex %zu of meshes[%zu] is not finite after "
                                        "animation and skinning",
                                        reader->ctx->name, frame, t, v, instance->mesh);
            }
        }
    }
    return LK_OK;
}

static int compare_floats(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

/* Moves the vertices of skinned primitives in `positions` (the reader's
 * output, loaded with record_instances) to where their joints put them at
 * the nodes' own transforms, as a viewer draws the file before an animation
 * plays; the node's transform (already applied) does not count for them.
 * Normals are left as the node placed them. */
static lk_status pose_skins(gltf_reader *reader, float *positions)
{
    anim_state state;
    memset(&state, 0, sizeof state);
    state.reader = reader;
    lk_animation_report report;
    memset(&report, 0, sizeof report);
    lk_status status = anim_nodes_init(&state);
    if (status == LK_OK) status = anim_read_primitives(&state, &report);
    /* no channels: every node at its own transform */
    if (status == LK_OK && report.skinned) status = anim_evaluate(&state, 0.0, positions, 0, true);
    anim_state_free(&state);
    return status;
}

lk_status lk__anim_read_gltf(const char *data, size_t size, const lk__anim_context *ctx, lk_animation *animation,
                             lk_error *error)
{
    lk_animation_init(animation);
    lk__read_context read_ctx = {ctx->name, ctx->directory, ctx->budget};
    gltf_reader reader;
    memset(&reader, 0, sizeof reader);
    reader.ctx = &read_ctx;
    reader.error = error;
    reader.record_instances = true;
    anim_state state;
    memset(&state, 0, sizeof state);
    state.reader = &reader;
    state.ctx = ctx;
    float *times = NULL;
    cJSON *root = NULL;
    /* The mesh arrays, the buffers and the JSON stay charged while the
     * frames are computed. */
    lk_status status = lk__gltf_load(&reader, data, size, &root);
    if (status == LK_OK) status = anim_nodes_init(&state);
    if (status == LK_OK) status = anim_read_primitives(&state, ctx->report);
    if (status == LK_OK) status = anim_read_channels(&state);
    if (status != LK_OK) goto done;
    /* Frame times. */
    size_t key_total = 0;
    for (size_t c = 0; c < state.channel_count; c++) key_total += state.samplers[state.channels[c].sampler].key_count;
    /* Channels may share one long sampler: the union of their key times is
     * gathered first, so it is what gets charged. */
    status = anim_charge(&reader, "animations", "key times", (uint64_t)key_total + 1, sizeof(float));
    if (status != LK_OK) goto done;
    times = lk__malloc_array(key_total + 1, sizeof(float));
    if (!times) {
        status = lk__gltf_nomem(&reader);
        goto done;
    }
    size_t time_count = 0;
    for (size_t c = 0; c < state.channel_count; c++) {
        const anim_sampler *sampler = &state.samplers[state.channels[c].sampler];
        memcpy(times + time_count, sampler->times, sampler->key_count * sizeof(float));
        time_count += sampler->key_count;
    }
    qsort(times, time_count, sizeof(float), compare_floats);
    size_t unique = 0;
    for (size_t i = 0; i < time_count; i++)
        if (unique == 0 || times[i] != times[unique - 1]) times[unique++] = times[i];
    ctx->report->key_count = unique;
    double first = unique ? times[0] : 0, last = unique ? times[unique - 1] : 0;
    size_t frame_count = unique ? unique : 1;
    double fps = ctx->frames_per_second;
    if (fps > 0) {
        double span = (last - first) * fps;
        if (span + 1 > (double)ctx->max_frames)
            frame_count = ctx->max_frames + 1;
        else
            frame_count = (size_t)floor(span + 1e-9) + 1;
    }
    if (frame_count > ctx->max_frames) {
        status = lk_error_set(error, LK_ERR_LIMIT,
                              "%s: %zu frames is more than the limit of %zu (resample with a lower "
                              "frame rate)",
                              ctx->name, frame_count, ctx->max_frames);
        goto done;
    }
    status = lk__gltf_take_mesh(&reader, &animation->mesh);
    if (status != LK_OK) goto done;
    status = lk__animation_alloc_frames(animation, frame_count, ctx->budget, ctx->name, error);
    if (status != LK_OK) goto done;
    /* Names of at most 32 bytes ("t" and a %.9g time) with their pointers. */
    status = anim_charge(&reader, "animations", "frame names", frame_count, sizeof(char *) + 32);
    if (status != LK_OK) goto done;
    animation->frame_names = lk__calloc_array(frame_count, sizeof(char *));
    if (!animation->frame_names) {
        status = lk__gltf_nomem(&reader);
        goto done;
    }
    if (fps > 0)
        animation->frames_per_second = fps;
    else if (frame_count > 1 && last > first)
        animation->frames_per_second = (double)(frame_count - 1) / (last - first);
    else
        animation->frames_per_second = 30;
    size_t vertex_count = animation->mesh.vertex_count;
    for (size_t f = 0; f < frame_count; f++) {
        double t = fps > 0 ? first + (double)f / fps : (unique ? times[f] : 0);
        float *positions = animation->frame_positions + f * vertex_count * 3;
        /* Vertices of primitives not instanced keep their static position. */
        memcpy(positions, animation->mesh.positions, vertex_count * 3 * sizeof(float));
        status = anim_evaluate(&state, t, positions, f, false);
        if (status != LK_OK) goto done;
        char name[32];
        snprintf(name, sizeof name, "t%.9g", t);
        animation->frame_names[f] = malloc(strlen(name) + 1);
        if (!animation->frame_names[f]) {
            status = lk__gltf_nomem(&reader);
            goto done;
        }
        strcpy(animation->frame_names[f], name);
    }
    memcpy(animation->mesh.positions, animation->frame_positions, vertex_count * 3 * sizeof(float));
done:
    free(times);
    anim_state_free(&state);
    lk__gltf_release(&reader, root);
    if (status != LK_OK) lk_animation_free(animation);
    return status;
}

/* lk_mesh_read's glTF reader: the default scene as one mesh (io_gltf.c),
 * skinned meshes posed at rest (pose_skins). Here rather than in
 * io_gltf.c so that the animation code depends on the reader, not both
 * ways. */
lk_status lk__read_gltf(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    gltf_reader reader;
    memset(&reader, 0, sizeof reader);
    reader.ctx = ctx;
    reader.error = error;
    reader.record_instances = true; /* for skins */
    lk_mesh_init(mesh);
    cJSON *root = NULL;
    lk_status status = lk__gltf_load(&reader, data, size, &root);
    /* skinned meshes go where their joints put them (glTF ignores their
     * nodes' transforms), as lk_scene_flatten places them */
    if (status == LK_OK && cJSON_GetArraySize(lk__gltf_member(root, "skins")) > 0)
        status = pose_skins(&reader, (float *)reader.positions.data);
    if (status == LK_OK) status = lk__gltf_take_mesh(&reader, mesh);
    lk__gltf_release(&reader, root);
    if (status != LK_OK) lk_mesh_free(mesh);
    return status;
}
