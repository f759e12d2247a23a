/* SPDX-License-Identifier: MIT */
/* Skinned primitives posed by their joints (glTF's linear blend skinning at
 * the nodes' own transforms): what lk_scene_flatten draws and what scene
 * simplification measures a skinned primitive in (src/scene.c). */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

/* world(joint) x inverse bind matrix of each joint of the skin (a joint
 * that is no node: `fallback`). */
void lk__scene_joint_matrices(const lk_scene *scene, const double *worlds, const lk_scene_skin *skin,
                              const double fallback[16], double *out)
{
    for (size_t j = 0; j < skin->joint_count; j++) {
        double inverse_bind[16];
        for (int e = 0; e < 16; e++)
            inverse_bind[e] = skin->inverse_bind_matrices ? skin->inverse_bind_matrices[16 * j + (size_t)e]
                                                          : (e % 5 == 0 ? 1.0 : 0.0);
        const double *joint_world = skin->joints[j] < scene->node_count ? worlds + 16 * skin->joints[j] : fallback;
        lk__mat4_multiply(joint_world, inverse_bind, out + 16 * j);
    }
}

/* Vertex v of a skinned primitive posed by its joints: the blend of
 * world(joint) x inverse bind matrix by the vertex's weights (glTF's linear
 * blend skinning; the node's own transform does not apply). A vertex
 * without weight follows its first joint, as the writer makes it. NULL
 * when that joint does not exist: the vertex stays where its node puts it. */
const double *lk__scene_skin_matrix(const lk_scene_primitive *primitive, size_t v, const double *joint_matrices,
                                    size_t joint_count, double out[16])
{
    static const float first_joint[4] = {1, 0, 0, 0};
    const float *weights = primitive->weights + 4 * v;
    const uint16_t *joints = primitive->joints + 4 * v;
    if (!(weights[0] > 0 || weights[1] > 0 || weights[2] > 0 || weights[3] > 0)) weights = first_joint;
    double total = 0.0;
    for (int k = 0; k < 4; k++)
        if (weights[k] > 0 && joints[k] < joint_count) total += weights[k];
    if (!(total > 0)) return NULL;
    memset(out, 0, 16 * sizeof(double));
    for (int k = 0; k < 4; k++) {
        if (!(weights[k] > 0) || joints[k] >= joint_count) continue;
        const double *joint = joint_matrices + 16 * joints[k];
        for (int e = 0; e < 16; e++) out[e] += weights[k] / total * joint[e];
    }
    return out;
}

/* A skinned primitive of mesh `mesh_index` as the first node drawing it
 * with a skin poses it at the nodes' own transforms (worlds: 16 per node),
 * 3 floats a vertex; NULL when no such node (or out of memory: the
 * primitive is then simplified in its bind pose alone). */
float *lk__scene_posed_primitive(const lk_scene *scene, const double *worlds, size_t mesh_index,
                                 const lk_scene_primitive *primitive)
{
    if (!worlds || !primitive->joints || !primitive->weights) return NULL;
    size_t node = scene->node_count;
    for (size_t i = 0; i < scene->node_count && node == scene->node_count; i++)
        if (scene->nodes[i].mesh == (int32_t)mesh_index && scene->nodes[i].skin >= 0 &&
            (size_t)scene->nodes[i].skin < scene->skin_count)
            node = i;
    if (node == scene->node_count) return NULL;
    const lk_scene_skin *skin = &scene->skins[scene->nodes[node].skin];
    const lk_mesh *mesh = &primitive->mesh;
    double *joint_matrices = lk__malloc_array(skin->joint_count, 16 * sizeof(double));
    float *posed = lk__malloc_array(mesh->vertex_count ? mesh->vertex_count : 1, 3 * sizeof(float));
    if (!joint_matrices || !posed) {
        free(joint_matrices);
        free(posed);
        return NULL;
    }
    lk__scene_joint_matrices(scene, worlds, skin, worlds + 16 * node, joint_matrices);
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        double blended[16];
        const double *m = lk__scene_skin_matrix(primitive, v, joint_matrices, skin->joint_count, blended);
        if (!m) m = worlds + 16 * node;
        const float *p = mesh->positions + 3 * v;
        for (int row = 0; row < 3; row++)
            posed[3 * v + (size_t)row] = (float)(m[row] * p[0] + m[4 + row] * p[1] + m[8 + row] * p[2] + m[12 + row]);
    }
    free(joint_matrices);
    return posed;
}
