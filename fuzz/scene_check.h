/* SPDX-License-Identifier: MIT */
/* What the scene fuzz targets (fuzz_scene.c, fuzz_objscene.c) check of
 * every scene a reader returns: references in range, valid primitives
 * (line segments on their vertices), a scene that flattens; abort() otherwise. */
#ifndef LODKIT_FUZZ_SCENE_CHECK_H
#define LODKIT_FUZZ_SCENE_CHECK_H

#include <stdlib.h>

#include "lodkit.h"

static void check_scene(const lk_scene *scene)
{
    for (size_t i = 0; i < scene->root_count; i++)
        if (scene->roots[i] >= scene->node_count) abort();
    for (size_t i = 0; i < scene->node_count; i++) {
        const lk_scene_node *node = &scene->nodes[i];
        if (node->mesh >= (int32_t)scene->mesh_count || node->camera >= (int32_t)scene->camera_count) abort();
        for (size_t c = 0; c < node->child_count; c++)
            if (node->children[c] >= scene->node_count) abort();
        for (size_t l = 0; l < node->lod_count; l++)
            if (node->lod_nodes[l] >= scene->node_count) abort();
    }
    for (size_t m = 0; m < scene->mesh_count; m++)
        for (size_t p = 0; p < scene->meshes[m].primitive_count; p++) {
            const lk_scene_primitive *primitive = &scene->meshes[m].primitives[p];
            if (primitive->material >= (int32_t)scene->material_count) abort();
            if (lk_mesh_validate(&primitive->mesh, NULL) != LK_OK) abort();
            if (primitive->line_count && (!primitive->lines || primitive->mesh.triangle_count)) abort();
            for (size_t i = 0; i < 2 * primitive->line_count; i++)
                if (primitive->lines[i] >= primitive->mesh.vertex_count) abort();
        }
    for (size_t t = 0; t < scene->texture_count; t++)
        if (scene->textures[t].image >= (int32_t)scene->image_count ||
            scene->textures[t].sampler >= (int32_t)scene->sampler_count || !scene->textures[t].json)
            abort();
    for (size_t i = 0; i < scene->material_count; i++)
        if (!scene->materials[i].json || scene->materials[i].base_color_texture >= (int32_t)scene->texture_count)
            abort();
    lk_mesh flat;
    lk_error error = {0};
    if (lk_scene_flatten(scene, &flat, &error) == LK_OK) {
        if (lk_mesh_validate(&flat, NULL) != LK_OK) abort();
        lk_mesh_free(&flat);
    } else if (error.message[0] == '\0') {
        abort();
    }
}

#endif
