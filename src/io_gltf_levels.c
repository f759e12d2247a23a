/* SPDX-License-Identifier: MIT */
/* glTF levels of detail of one mesh (lk_mesh_write_lods) and a single mesh
 * (lk_mesh_write): each built as a scene borrowing the meshes' arrays and
 * written by the scene writer (io_gltf_mesh_write.c). */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

/* Levels of detail (MSFT_lod): node 0, in the scene, holds level 0; nodes
 * 1..n-1 hold the coarser levels and are listed in node 0's MSFT_lod ids;
 * node 0's extras carry MSFT_screencoverage (one value per level) and each
 * node's extras lodkit's numbers for its level. One level: a plain node.
 * Written as a scene that borrows the levels' arrays. */
lk_status lk__write_gltf_levels(FILE *file, const char *path, bool binary, const lk_mesh *levels, size_t level_count,
                                const lk_lod_level_info *info, const lk_write_options *options, lk_error *error)
{
    lk_scene scene;
    lk_scene_init(&scene);
    lk_status status = LK_OK;
    bool empty = level_count == 0 || levels[0].vertex_count == 0;
    size_t count = empty ? 0 : level_count;
    for (size_t level = 0; level < count; level++)
        if (levels[level].vertex_count == 0)
            return lk_error_set(error, LK_ERR_INVALID, "level %zu of detail is empty", level);
    scene.nodes = lk__calloc_array(count ? count : 1, sizeof *scene.nodes);
    scene.meshes = lk__calloc_array(count ? count : 1, sizeof *scene.meshes);
    lk_scene_primitive *primitives = lk__calloc_array(count ? count : 1, sizeof *primitives);
    uint32_t root = 0, *ids = lk__calloc_array(count ? count : 1, sizeof *ids);
    if (!scene.nodes || !scene.meshes || !primitives || !ids) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory while building the glTF");
        goto done;
    }
    for (size_t level = 0; level < count; level++) {
        lk_scene_node *node = &scene.nodes[level];
        lk__scene_node_init(node);
        node->mesh = (int32_t)level;
        primitives[level].mesh = levels[level]; /* borrowed */
        primitives[level].material = -1;
        scene.meshes[level].primitives = &primitives[level];
        scene.meshes[level].primitive_count = 1;
        ids[level] = (uint32_t)level;
        if (level_count == 1) continue;
        char extras[512];
        int length = snprintf(extras, sizeof extras, "{");
        if (level == 0) {
            length += snprintf(extras + length, sizeof extras - (size_t)length, "\"MSFT_screencoverage\":[");
            for (size_t k = 0; k < level_count && length < (int)sizeof extras - 128; k++)
                length += snprintf(extras + length, sizeof extras - (size_t)length, "%s%.17g", k ? "," : "",
                                   info ? info[k].screen_coverage : 0.0);
            length += snprintf(extras + length, sizeof extras - (size_t)length, "],");
        }
        length += snprintf(extras + length, sizeof extras - (size_t)length,
                           "\"lodkit\":{\"level\":%zu,\"triangles\":%zu", level, levels[level].triangle_count);
        if (info)
            length += snprintf(extras + length, sizeof extras - (size_t)length, ",\"error\":%.17g", info[level].error);
        snprintf(extras + length, sizeof extras - (size_t)length, "}}");
        node->extras = lk__malloc_array(strlen(extras) + 1, 1);
        if (!node->extras) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory while building the glTF");
            goto done;
        }
        memcpy(node->extras, extras, strlen(extras) + 1);
    }
    if (count > 1) {
        scene.nodes[0].lod_nodes = ids + 1;
        scene.nodes[0].lod_count = count - 1;
    }
    scene.node_count = scene.mesh_count = count;
    scene.roots = count ? &root : NULL;
    scene.root_count = count ? 1 : 0;
    status = lk__write_gltf_scene(file, path, binary, &scene, options, error);
done:
    for (size_t level = 0; scene.nodes && level < count; level++) free(scene.nodes[level].extras);
    free(scene.nodes);
    free(scene.meshes);
    free(primitives);
    free(ids);
    return status;
}

lk_status lk__write_gltf_mesh(FILE *file, const char *path, bool binary, const lk_mesh *mesh,
                              const lk_write_options *options, lk_error *error)
{
    return lk__write_gltf_levels(file, path, binary, mesh, 1, NULL, options, error);
}
