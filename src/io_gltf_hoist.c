/* SPDX-License-Identifier: MIT */
/* glTF writer, last step: skinned meshes moved onto root nodes.
 *
 * glTF places a skinned mesh by its joints alone: the transforms of the
 * node holding it and of that node's ancestors do not apply (glTF 2.0,
 * "Skins"). An exporter that nests such a node under a transformed parent
 * may have meant the parent to move it, so the Khronos validator warns
 * (NODE_SKINNED_MESH_NON_ROOT). Qt 3D's RiggedFigure and Castle Game
 * Engine's dungeon level nest theirs, and lodkit's writer kept the node
 * tree as read, so their outputs carried the warning.
 *
 * The fix draws exactly what the input drew: each such node gives its
 * mesh, skin, morph weights and MSFT_lod levels to a new node appended at
 * the end of the node list and listed among the roots of every scene that
 * shows the old node. The old node keeps its name, transform, children,
 * camera and extras, so every node index stays valid: joints, skeletons,
 * animation channels on its transform, children. Channels animating its
 * morph weights follow the mesh. The new node carries the old one's name,
 * so a three.js app that finds the mesh by name still finds it
 * (GLTFLoader makes the second name unique). Writing the result again
 * changes nothing: the node is a root by then. */
#include "io_gltf.h"

#include <stdlib.h>
#include <string.h>

static bool array_holds(const cJSON *array, int value)
{
    const cJSON *item;
    cJSON_ArrayForEach(item, array)
    {
        if (cJSON_IsNumber(item) && item->valueint == value) return true;
    }
    return false;
}

/* Moves `key` of `from` (if present) to `to`. */
static void move_member(cJSON *from, cJSON *to, const char *key)
{
    cJSON *item = cJSON_DetachItemFromObjectCaseSensitive(from, key);
    if (item) cJSON_AddItemToObject(to, key, item);
}

bool lk__gltf_hoist_skinned_meshes(cJSON *root)
{
    cJSON *nodes = cJSON_GetObjectItemCaseSensitive(root, "nodes");
    int node_count = cJSON_GetArraySize(nodes);
    if (node_count <= 0) return true;
    int *parent = malloc((size_t)node_count * sizeof *parent);
    if (!parent) return false;
    for (int i = 0; i < node_count; i++) parent[i] = -1;
    int index = 0;
    const cJSON *node;
    cJSON_ArrayForEach(node, nodes)
    {
        const cJSON *child;
        cJSON_ArrayForEach(child, cJSON_GetObjectItemCaseSensitive(node, "children"))
        {
            if (cJSON_IsNumber(child) && child->valueint >= 0 && child->valueint < node_count)
                parent[child->valueint] = index;
        }
        index++;
    }
    bool ok = true;
    int moved_count = 0;
    cJSON *old = nodes->child;
    for (int i = 0; i < node_count && ok; i++, old = old->next) {
        if (parent[i] < 0 || !cJSON_GetObjectItemCaseSensitive(old, "skin") ||
            !cJSON_GetObjectItemCaseSensitive(old, "mesh"))
            continue;
        cJSON *moved = cJSON_CreateObject();
        if (!moved || !cJSON_AddItemToArray(nodes, moved)) {
            cJSON_Delete(moved);
            ok = false;
            break;
        }
        int moved_index = node_count + moved_count++;
        const cJSON *name = cJSON_GetObjectItemCaseSensitive(old, "name");
        if (cJSON_IsString(name)) cJSON_AddStringToObject(moved, "name", name->valuestring);
        move_member(old, moved, "mesh");
        move_member(old, moved, "skin");
        move_member(old, moved, "weights");
        cJSON *extensions = cJSON_GetObjectItemCaseSensitive(old, "extensions");
        cJSON *lod = cJSON_DetachItemFromObjectCaseSensitive(extensions, "MSFT_lod");
        if (lod) {
            cJSON_AddItemToObject(cJSON_AddObjectToObject(moved, "extensions"), "MSFT_lod", lod);
            if (cJSON_GetArraySize(extensions) == 0) cJSON_DeleteItemFromObjectCaseSensitive(old, "extensions");
        }
        /* the scenes showing the old node list its topmost ancestor */
        int top = i;
        for (int steps = 0; parent[top] >= 0 && steps < node_count; steps++) top = parent[top];
        cJSON *scene;
        cJSON_ArrayForEach(scene, cJSON_GetObjectItemCaseSensitive(root, "scenes"))
        {
            cJSON *roots = cJSON_GetObjectItemCaseSensitive(scene, "nodes");
            if (array_holds(roots, top)) ok = ok && cJSON_AddItemToArray(roots, cJSON_CreateNumber(moved_index));
        }
        cJSON *animation;
        cJSON_ArrayForEach(animation, cJSON_GetObjectItemCaseSensitive(root, "animations"))
        {
            cJSON *channel;
            cJSON_ArrayForEach(channel, cJSON_GetObjectItemCaseSensitive(animation, "channels"))
            {
                cJSON *target = cJSON_GetObjectItemCaseSensitive(channel, "target");
                cJSON *target_node = cJSON_GetObjectItemCaseSensitive(target, "node");
                const cJSON *path = cJSON_GetObjectItemCaseSensitive(target, "path");
                if (cJSON_IsNumber(target_node) && target_node->valueint == i && cJSON_IsString(path) &&
                    strcmp(path->valuestring, "weights") == 0)
                    cJSON_SetNumberValue(target_node, moved_index);
            }
        }
    }
    free(parent);
    return ok;
}
