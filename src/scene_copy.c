/* SPDX-License-Identifier: MIT */
/* Scenes' lifetimes (lk_scene, include/lodkit.h): initialising, freeing and
 * deep copies (lk_scene_copy; lk__scene_copy with room for the levels of
 * an LOD chain; lk__scene_copy_primitive for simplification's variants). */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

void lk_scene_init(lk_scene *scene)
{
    if (scene) memset(scene, 0, sizeof *scene);
}

static void free_strings(char **strings, size_t count)
{
    for (size_t i = 0; strings && i < count; i++) free(strings[i]);
    free(strings);
}

void lk__scene_primitive_free(lk_scene_primitive *primitive)
{
    lk_mesh_free(&primitive->mesh);
    free(primitive->tangents);
    free(primitive->texcoords1);
    free(primitive->joints);
    free(primitive->weights);
    free(primitive->target_positions);
    free(primitive->target_normals);
    free(primitive->target_tangents);
    free(primitive->lines);
    memset(primitive, 0, sizeof *primitive);
    lk_mesh_init(&primitive->mesh);
}

void lk_scene_free(lk_scene *scene)
{
    if (!scene) return;
    for (size_t i = 0; scene->nodes && i < scene->node_count; i++) {
        lk_scene_node *node = &scene->nodes[i];
        free(node->name);
        free(node->children);
        free(node->lod_nodes);
        free(node->extras);
        free(node->weights);
    }
    free(scene->nodes);
    free(scene->roots);
    for (size_t i = 0; scene->meshes && i < scene->mesh_count; i++) {
        lk_scene_mesh *mesh = &scene->meshes[i];
        for (size_t p = 0; mesh->primitives && p < mesh->primitive_count; p++)
            lk__scene_primitive_free(&mesh->primitives[p]);
        free(mesh->primitives);
        free(mesh->name);
        free(mesh->weights);
        free_strings(mesh->target_names, mesh->target_names ? mesh->target_count : 0);
    }
    free(scene->meshes);
    for (size_t i = 0; scene->materials && i < scene->material_count; i++) {
        free(scene->materials[i].name);
        free(scene->materials[i].json);
    }
    free(scene->materials);
    for (size_t i = 0; scene->textures && i < scene->texture_count; i++) free(scene->textures[i].json);
    free(scene->textures);
    for (size_t i = 0; scene->images && i < scene->image_count; i++) {
        free(scene->images[i].name);
        free(scene->images[i].mime_type);
        free(scene->images[i].data);
    }
    free(scene->images);
    free_strings(scene->samplers, scene->sampler_count);
    free_strings(scene->cameras, scene->camera_count);
    free_strings(scene->required_extensions, scene->required_extension_count);
    free(scene->notes);
    for (size_t i = 0; scene->skins && i < scene->skin_count; i++) {
        free(scene->skins[i].name);
        free(scene->skins[i].joints);
        free(scene->skins[i].inverse_bind_matrices);
    }
    free(scene->skins);
    for (size_t i = 0; scene->animations && i < scene->animation_count; i++) {
        lk_scene_animation *animation = &scene->animations[i];
        free(animation->name);
        for (size_t s = 0; animation->samplers && s < animation->sampler_count; s++) {
            free(animation->samplers[s].input);
            free(animation->samplers[s].output);
        }
        free(animation->samplers);
        free(animation->channels);
    }
    free(scene->animations);
    memset(scene, 0, sizeof *scene);
}

void lk__scene_node_init(lk_scene_node *node)
{
    memset(node, 0, sizeof *node);
    node->mesh = -1;
    node->camera = -1;
    node->skin = -1;
    for (int i = 0; i < 4; i++) node->matrix[5 * i] = 1.0;
    node->rotation[3] = 1.0;
    for (int i = 0; i < 3; i++) node->scale[i] = 1.0;
}


static bool copy_string(char **out, const char *text)
{
    *out = NULL;
    if (!text) return true;
    size_t length = strlen(text);
    *out = malloc(length + 1);
    if (*out) memcpy(*out, text, length + 1);
    return *out != NULL;
}

bool lk__scene_copy_array(void **out, const void *in, size_t count, size_t size)
{
    *out = NULL;
    if (!in || count == 0) return true;
    *out = lk__malloc_array(count, size);
    if (*out) memcpy(*out, in, count * size);
    return *out != NULL;
}

static bool copy_strings(char ***out, char *const *in, size_t count)
{
    *out = NULL;
    if (!in || count == 0) return true;
    *out = lk__calloc_array(count, sizeof **out);
    if (!*out) return false;
    for (size_t i = 0; i < count; i++)
        if (!copy_string(&(*out)[i], in[i])) return false;
    return true;
}

bool lk__scene_copy_primitive(lk_scene_primitive *out, const lk_scene_primitive *in, size_t target_count)
{
    memset(out, 0, sizeof *out);
    size_t deltas = target_count * in->mesh.vertex_count;
    out->material = in->material;
    out->line_count = in->line_count;
    if (lk_mesh_copy(&out->mesh, &in->mesh, NULL) != LK_OK) {
        lk_mesh_init(&out->mesh);
        return false;
    }
    return lk__scene_copy_array((void **)&out->tangents, in->tangents, in->mesh.vertex_count, 4 * sizeof(float)) &&
           lk__scene_copy_array((void **)&out->texcoords1, in->texcoords1, in->mesh.vertex_count, 2 * sizeof(float)) &&
           lk__scene_copy_array((void **)&out->joints, in->joints, in->mesh.vertex_count, 4 * sizeof(uint16_t)) &&
           lk__scene_copy_array((void **)&out->weights, in->weights, in->mesh.vertex_count, 4 * sizeof(float)) &&
           lk__scene_copy_array((void **)&out->target_positions, in->target_positions, deltas, 3 * sizeof(float)) &&
           lk__scene_copy_array((void **)&out->target_normals, in->target_normals, deltas, 3 * sizeof(float)) &&
           lk__scene_copy_array((void **)&out->target_tangents, in->target_tangents, deltas, 3 * sizeof(float)) &&
           lk__scene_copy_array((void **)&out->lines, in->lines, in->line_count, 2 * sizeof(uint32_t));
}

bool lk__scene_copy_mesh(lk_scene_mesh *out, const lk_scene_mesh *in)
{
    memset(out, 0, sizeof *out);
    if (!copy_string(&out->name, in->name)) return false;
    out->target_count = in->target_count;
    if (!lk__scene_copy_array((void **)&out->weights, in->weights, in->target_count, sizeof(float)) ||
        !copy_strings(&out->target_names, in->target_names, in->target_count))
        return false;
    if (in->primitive_count == 0) return true;
    out->primitives = lk__calloc_array(in->primitive_count, sizeof *out->primitives);
    if (!out->primitives) return false;
    for (size_t p = 0; p < in->primitive_count; p++) {
        out->primitive_count++;
        if (!lk__scene_copy_primitive(&out->primitives[p], &in->primitives[p], in->target_count)) return false;
    }
    return true;
}

/* weight_count: the target_count of the node's mesh. */
static bool copy_node(lk_scene_node *out, const lk_scene_node *in, size_t weight_count)
{
    *out = *in;
    out->name = NULL, out->children = NULL, out->lod_nodes = NULL, out->extras = NULL, out->weights = NULL;
    out->child_count = in->children ? in->child_count : 0;
    out->lod_count = in->lod_nodes ? in->lod_count : 0;
    return copy_string(&out->name, in->name) && copy_string(&out->extras, in->extras) &&
           lk__scene_copy_array((void **)&out->children, in->children, out->child_count, sizeof(uint32_t)) &&
           lk__scene_copy_array((void **)&out->lod_nodes, in->lod_nodes, out->lod_count, sizeof(uint32_t)) &&
           lk__scene_copy_array((void **)&out->weights, in->weights, weight_count, sizeof(float));
}

static bool copy_animation(lk_scene_animation *out, const lk_scene_animation *in)
{
    memset(out, 0, sizeof *out);
    if (!copy_string(&out->name, in->name) ||
        !lk__scene_copy_array((void **)&out->channels, in->channels, in->channel_count, sizeof *in->channels))
        return false;
    out->channel_count = in->channels ? in->channel_count : 0;
    if (in->sampler_count == 0 || !in->samplers) return true;
    out->samplers = lk__calloc_array(in->sampler_count, sizeof *out->samplers);
    if (!out->samplers) return false;
    for (size_t s = 0; s < in->sampler_count; s++) {
        const lk_scene_animation_sampler *sampler = &in->samplers[s];
        lk_scene_animation_sampler *copy = &out->samplers[s];
        out->sampler_count = s + 1;
        *copy = *sampler;
        copy->input = copy->output = NULL;
        if (!lk__scene_copy_array((void **)&copy->input, sampler->input, sampler->key_count, sizeof(float)) ||
            !lk__scene_copy_array((void **)&copy->output, sampler->output, sampler->output_count,
                                  sampler->components * sizeof(float)))
            return false;
    }
    return true;
}

static bool copy_skins_and_animations(lk_scene *out, const lk_scene *in)
{
    if (in->skin_count && in->skins) {
        if (!(out->skins = lk__calloc_array(in->skin_count, sizeof *out->skins))) return false;
        for (size_t i = 0; i < in->skin_count; i++) {
            const lk_scene_skin *skin = &in->skins[i];
            lk_scene_skin *copy = &out->skins[i];
            out->skin_count = i + 1;
            *copy = *skin;
            copy->name = NULL, copy->joints = NULL, copy->inverse_bind_matrices = NULL;
            if (!copy_string(&copy->name, skin->name) ||
                !lk__scene_copy_array((void **)&copy->joints, skin->joints, skin->joint_count, sizeof(uint32_t)) ||
                !lk__scene_copy_array((void **)&copy->inverse_bind_matrices, skin->inverse_bind_matrices,
                                      skin->joint_count, 16 * sizeof(float)))
                return false;
        }
    }
    if (in->animation_count && in->animations) {
        if (!(out->animations = lk__calloc_array(in->animation_count, sizeof *out->animations))) return false;
        for (size_t i = 0; i < in->animation_count; i++) {
            out->animation_count = i + 1;
            if (!copy_animation(&out->animations[i], &in->animations[i])) return false;
        }
    }
    return true;
}

/* Deep copy into `out` with room for `extra_nodes` and `extra_meshes`
 * more (zeroed) entries at the ends of the node and mesh arrays. */
lk_status lk__scene_copy(lk_scene *out, const lk_scene *in, size_t extra_nodes, size_t extra_meshes, lk_error *error)
{
    lk_scene_init(out);
    bool ok = true;
    size_t nodes = in->node_count + extra_nodes, meshes = in->mesh_count + extra_meshes;
    if (nodes) ok = (out->nodes = lk__calloc_array(nodes, sizeof *out->nodes)) != NULL;
    for (size_t i = 0; ok && i < in->node_count; i++) {
        int32_t mesh = in->nodes[i].mesh;
        ok = copy_node(&out->nodes[i], &in->nodes[i],
                       mesh >= 0 && (size_t)mesh < in->mesh_count ? in->meshes[mesh].target_count : 0);
        out->node_count = i + 1;
    }
    if (ok && meshes) ok = (out->meshes = lk__calloc_array(meshes, sizeof *out->meshes)) != NULL;
    for (size_t i = 0; ok && i < in->mesh_count; i++) {
        out->mesh_count = i + 1;
        ok = lk__scene_copy_mesh(&out->meshes[i], &in->meshes[i]);
    }
    ok = ok && lk__scene_copy_array((void **)&out->roots, in->roots, in->root_count, sizeof(uint32_t));
    if (ok) out->root_count = in->roots ? in->root_count : 0;
    if (ok && in->material_count)
        ok = (out->materials = lk__calloc_array(in->material_count, sizeof *out->materials)) != NULL;
    for (size_t i = 0; ok && i < in->material_count; i++) {
        out->material_count = i + 1;
        out->materials[i] = in->materials[i];
        out->materials[i].name = out->materials[i].json = NULL;
        ok = copy_string(&out->materials[i].name, in->materials[i].name) &&
             copy_string(&out->materials[i].json, in->materials[i].json);
    }
    if (ok && in->texture_count)
        ok = (out->textures = lk__calloc_array(in->texture_count, sizeof *out->textures)) != NULL;
    for (size_t i = 0; ok && i < in->texture_count; i++) {
        out->texture_count = i + 1;
        out->textures[i] = in->textures[i];
        out->textures[i].json = NULL;
        ok = copy_string(&out->textures[i].json, in->textures[i].json);
    }
    if (ok && in->image_count) ok = (out->images = lk__calloc_array(in->image_count, sizeof *out->images)) != NULL;
    for (size_t i = 0; ok && i < in->image_count; i++) {
        const lk_scene_image *image = &in->images[i];
        out->image_count = i + 1;
        ok = copy_string(&out->images[i].name, image->name) &&
             copy_string(&out->images[i].mime_type, image->mime_type) &&
             lk__scene_copy_array((void **)&out->images[i].data, image->data, image->size, 1);
        if (ok) out->images[i].size = image->data ? image->size : 0;
    }
    ok = ok && copy_strings(&out->samplers, in->samplers, in->sampler_count);
    if (ok) out->sampler_count = in->samplers ? in->sampler_count : 0;
    ok = ok && copy_strings(&out->cameras, in->cameras, in->camera_count);
    if (ok) out->camera_count = in->cameras ? in->camera_count : 0;
    ok = ok && copy_strings(&out->required_extensions, in->required_extensions, in->required_extension_count);
    if (ok) out->required_extension_count = in->required_extensions ? in->required_extension_count : 0;
    ok = ok && copy_string(&out->notes, in->notes);
    ok = ok && copy_skins_and_animations(out, in);
    if (!ok) {
        lk_scene_free(out);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory copying a scene");
    }
    return LK_OK;
}

lk_status lk_scene_copy(lk_scene *dst, const lk_scene *src, lk_error *error)
{
    if (!dst || !src) return lk_error_set(error, LK_ERR_INVALID, "lk_scene_copy: NULL argument");
    return lk__scene_copy(dst, src, 0, 0, error);
}
