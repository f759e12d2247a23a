/* SPDX-License-Identifier: MIT */
/* Scenes in memory (lk_scene, include/lodkit.h): freeing, wrapping a mesh,
 * flattening the node tree into one mesh, and simplifying every primitive.
 * Reading and writing glTF scenes live in io_gltf_scene.c and
 * io_gltf_mesh_write.c; lk_scene_read / lk_scene_write in io.c. */
#include "internal.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

lk_status lk_scene_from_mesh(lk_scene *scene, lk_mesh *mesh, lk_error *error)
{
    if (!scene || !mesh) return lk_error_set(error, LK_ERR_INVALID, "lk_scene_from_mesh: NULL argument");
    lk_scene_init(scene);
    scene->nodes = lk__calloc_array(1, sizeof *scene->nodes);
    scene->roots = lk__calloc_array(1, sizeof *scene->roots);
    scene->meshes = lk__calloc_array(1, sizeof *scene->meshes);
    lk_scene_primitive *primitive = lk__calloc_array(1, sizeof *primitive);
    if (!scene->nodes || !scene->roots || !scene->meshes || !primitive) {
        free(primitive);
        lk_scene_free(scene);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a scene");
    }
    lk__scene_node_init(&scene->nodes[0]);
    scene->nodes[0].mesh = 0;
    scene->node_count = scene->root_count = scene->mesh_count = 1;
    primitive->mesh = *mesh;
    primitive->material = -1;
    scene->meshes[0].primitives = primitive;
    scene->meshes[0].primitive_count = 1;
    lk_mesh_init(mesh);
    return LK_OK;
}

size_t lk_scene_triangle_count(const lk_scene *scene)
{
    size_t total = 0;
    for (size_t m = 0; scene && m < scene->mesh_count; m++)
        for (size_t p = 0; p < scene->meshes[m].primitive_count; p++)
            total += scene->meshes[m].primitives[p].mesh.triangle_count;
    return total;
}


/* Calls visit(node, world matrix) for every node below the roots, parents
 * first; a node reached twice (a cycle or a shared child) is an error. */
typedef lk_status (*node_visitor)(const lk_scene *scene, size_t node, const double world[16], void *user);

typedef struct walk_entry {
    size_t node;
    double parent[16];
} walk_entry;

static lk_status walk(const lk_scene *scene, node_visitor visit, void *user, lk_error *error)
{
    if (scene->node_count == 0) return LK_OK;
    walk_entry *stack = lk__malloc_array(scene->node_count, sizeof *stack);
    unsigned char *seen = lk__calloc_array(scene->node_count, 1);
    lk_status status = LK_OK;
    if (!stack || !seen) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory walking the scene");
        goto done;
    }
    for (size_t r = 0; r < scene->root_count && status == LK_OK; r++) {
        size_t depth = 0;
        if (scene->roots[r] >= scene->node_count || seen[scene->roots[r]]) {
            status = lk_error_set(error, LK_ERR_INVALID, "scene root %zu: node %u is out of range or reached twice", r,
                                  scene->roots[r]);
            break;
        }
        seen[scene->roots[r]] = 1;
        stack[depth].node = scene->roots[r];
        lk__mat4_identity(stack[depth].parent);
        depth++;
        while (depth > 0 && status == LK_OK) {
            walk_entry entry = stack[--depth];
            const lk_scene_node *node = &scene->nodes[entry.node];
            double world[16];
            lk__mat4_multiply(entry.parent, node->matrix, world);
            status = visit(scene, entry.node, world, user);
            for (size_t c = 0; c < node->child_count && status == LK_OK; c++) {
                uint32_t child = node->children[c];
                if (child >= scene->node_count || seen[child]) {
                    status = lk_error_set(error, LK_ERR_INVALID,
                                          "nodes[%zu].children[%zu]: node %u is out of range or reached twice",
                                          entry.node, c, child);
                    break;
                }
                seen[child] = 1;
                stack[depth].node = child;
                memcpy(stack[depth].parent, world, sizeof world);
                depth++;
            }
        }
    }
done:
    free(stack);
    free(seen);
    return status;
}

typedef struct flatten_state {
    lk_error *error;
    const double *worlds; /* 16 per node: world matrices, for skins (NULL: no skin) */
    int32_t *materials;   /* the material of each output triangle, or NULL */
    bool counting, with_points;
    size_t vertex_count, triangle_count;
    unsigned attributes;
    lk_mesh *out;
} flatten_state;

static bool takes(const flatten_state *state, const lk_scene_primitive *primitive)
{
    const lk_mesh *mesh = &primitive->mesh;
    return mesh->vertex_count > 0 && (mesh->triangle_count > 0 || (state->with_points && !primitive->lines));
}

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Normals go through the cofactor matrix (det * M^-T); a mirroring
 * transform reverses the winding. */
static bool normal_matrix(const double m[16], double normal[9])
{
    cross(m + 4, m + 8, normal);
    cross(m + 8, m, normal + 3);
    cross(m, m + 4, normal + 6);
    return m[0] * normal[0] + m[1] * normal[1] + m[2] * normal[2] < 0.0;
}

static lk_status store_world(const lk_scene *scene, size_t node, const double world[16], void *user)
{
    (void)scene;
    memcpy((double *)user + 16 * node, world, 16 * sizeof(double));
    return LK_OK;
}

static lk_status flatten_node(const lk_scene *scene, size_t node_index, const double node_world[16], void *user)
{
    flatten_state *state = user;
    const lk_scene_node *node = &scene->nodes[node_index];
    if (node->mesh < 0 || (size_t)node->mesh >= scene->mesh_count) return LK_OK;
    const lk_scene_mesh *mesh = &scene->meshes[node->mesh];
    const lk_scene_skin *skin =
        state->worlds && node->skin >= 0 && (size_t)node->skin < scene->skin_count ? &scene->skins[node->skin] : NULL;
    double *joint_matrices = NULL; /* 16 per joint of the skin, when a primitive is skinned */
    for (size_t p = 0; p < mesh->primitive_count; p++) {
        const lk_mesh *in = &mesh->primitives[p].mesh;
        if (!takes(state, &mesh->primitives[p])) continue;
        const lk_scene_primitive *primitive = &mesh->primitives[p];
        bool skinned = !state->counting && skin && primitive->joints && primitive->weights && in->vertex_count;
        if (skinned && !joint_matrices) {
            joint_matrices = lk__malloc_array(skin->joint_count, 16 * sizeof(double));
            if (!joint_matrices) return lk_error_set(state->error, LK_ERR_NOMEM, "out of memory posing a skin");
            lk__scene_joint_matrices(scene, state->worlds, skin, node_world, joint_matrices);
        }
        /* The winding follows the node's transform, or a skinned
         * primitive's first weighted vertex. */
        double normal[9], blended[16];
        const double *m = NULL;
        for (size_t v = 0; skinned && v < in->vertex_count && !m; v++)
            m = lk__scene_skin_matrix(primitive, v, joint_matrices, skin->joint_count, blended);
        if (!m) m = node_world;
        bool mirror = normal_matrix(m, normal);
        if (state->counting) {
            state->vertex_count += in->vertex_count;
            state->triangle_count += in->triangle_count;
            state->attributes |= (in->normals ? LK_ATTR_NORMALS : 0u) | (in->texcoords ? LK_ATTR_TEXCOORDS : 0u) |
                                 (in->colors ? LK_ATTR_COLORS : 0u);
            continue;
        }
        lk_mesh *out = state->out;
        size_t base = state->vertex_count;
        for (size_t v = 0; v < in->vertex_count; v++) {
            if (skinned) {
                m = lk__scene_skin_matrix(primitive, v, joint_matrices, skin->joint_count, blended);
                if (!m) m = node_world;
                normal_matrix(m, normal);
            }
            const float *p3 = in->positions + 3 * v;
            float *o = out->positions + 3 * (base + v);
            for (int row = 0; row < 3; row++) {
                o[row] = (float)(m[row] * p3[0] + m[4 + row] * p3[1] + m[8 + row] * p3[2] + m[12 + row]);
                if (!isfinite(o[row])) {
                    free(joint_matrices);
                    return lk_error_set(state->error, LK_ERR_RANGE,
                                        "nodes[%zu]: vertex %zu of meshes[%d].primitives[%zu] is not finite (%g) "
                                        "after the node's transform%s",
                                        node_index, v, node->mesh, p, (double)o[row], skinned ? " and its skin" : "");
                }
            }
            if (out->normals) {
                float *n = out->normals + 3 * (base + v);
                if (!in->normals) {
                    n[0] = n[1] = n[2] = 0.0f;
                } else {
                    const float *i3 = in->normals + 3 * v;
                    double t[3], length = 0.0;
                    for (int row = 0; row < 3; row++) {
                        t[row] = normal[row] * i3[0] + normal[3 + row] * i3[1] + normal[6 + row] * i3[2];
                        if (mirror) t[row] = -t[row];
                        length += t[row] * t[row];
                    }
                    length = sqrt(length);
                    for (int row = 0; row < 3; row++) n[row] = length > 0.0 ? (float)(t[row] / length) : 0.0f;
                }
            }
            if (out->texcoords) {
                float *t = out->texcoords + 2 * (base + v);
                t[0] = in->texcoords ? in->texcoords[2 * v] : 0.0f;
                t[1] = in->texcoords ? in->texcoords[2 * v + 1] : 0.0f;
            }
            if (out->colors)
                for (int c = 0; c < 4; c++)
                    out->colors[4 * (base + v) + (size_t)c] = in->colors ? in->colors[4 * v + (size_t)c] : 1.0f;
        }
        for (size_t t = 0; state->materials && t < in->triangle_count; t++)
            state->materials[state->triangle_count + t] = mesh->primitives[p].material;
        for (size_t t = 0; t < in->triangle_count; t++) {
            uint32_t *o = out->indices + 3 * (state->triangle_count + t);
            const uint32_t *i3 = in->indices + 3 * t;
            o[0] = (uint32_t)base + i3[0];
            o[1] = (uint32_t)base + (mirror ? i3[2] : i3[1]);
            o[2] = (uint32_t)base + (mirror ? i3[1] : i3[2]);
        }
        state->vertex_count += in->vertex_count;
        state->triangle_count += in->triangle_count;
    }
    free(joint_matrices);
    return LK_OK;
}

lk_status lk_scene_flatten(const lk_scene *scene, lk_mesh *mesh, lk_error *error)
{
    return lk__scene_flatten_materials(scene, mesh, NULL, error);
}

lk_status lk__scene_flatten_materials(const lk_scene *scene, lk_mesh *mesh, int32_t **materials, lk_error *error)
{
    if (!scene || !mesh) return lk_error_set(error, LK_ERR_INVALID, "lk_scene_flatten: NULL argument");
    lk_mesh_init(mesh);
    if (materials) *materials = NULL;
    flatten_state state;
    memset(&state, 0, sizeof state);
    state.error = error;
    state.counting = true;
    lk_status status = walk(scene, flatten_node, &state, error);
    if (status != LK_OK) return status;
    if (state.triangle_count == 0) {
        /* A point set: take the points. */
        state.with_points = true;
        state.vertex_count = 0;
        state.attributes = 0;
        status = walk(scene, flatten_node, &state, error);
        if (status != LK_OK) return status;
    }
    if (state.vertex_count > LK_MAX_ELEMENTS || state.triangle_count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "the scene draws %zu vertices and %zu triangles: more than %zu",
                            state.vertex_count, state.triangle_count, (size_t)LK_MAX_ELEMENTS);
    status = lk_mesh_alloc(mesh, state.vertex_count, state.triangle_count, state.attributes, error);
    if (status != LK_OK) return status;
    if (materials) {
        state.materials = lk__malloc_array(state.triangle_count ? state.triangle_count : 1, sizeof *state.materials);
        if (!state.materials) {
            lk_mesh_free(mesh);
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu triangle materials", state.triangle_count);
        }
    }
    state.counting = false;
    state.out = mesh;
    state.vertex_count = state.triangle_count = 0;
    /* Skinned meshes are posed by their joints, which may come later in
     * the walk: every node's world matrix first. */
    double *worlds = NULL;
    if (scene->skin_count > 0) {
        worlds = lk__calloc_array(scene->node_count, 16 * sizeof(double));
        status = worlds ? walk(scene, store_world, worlds, error)
                        : lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu node matrices", scene->node_count);
        state.worlds = worlds;
    }
    if (status == LK_OK) status = walk(scene, flatten_node, &state, error);
    free(worlds);
    if (status != LK_OK) {
        lk_mesh_free(mesh);
        free(state.materials);
    } else if (materials) {
        *materials = state.materials;
    }
    return status;
}

/* ---- simplification ----------------------------------------------------- */

static void as_animation(lk_mesh *mesh, lk_animation *animation);
static void anim_options_for(const lk_simplify_options *options, lk_anim_simplify_options *out);

/* The largest factor by which the world transforms of the nodes using each
 * mesh stretch it (their 3x3 parts' largest column length), 0 for a mesh
 * no node uses: converts a scene-wide length into the mesh's units. With
 * boxes (each mesh's local box, 6 doubles), also the scene's world box:
 * the union of those boxes' corners as each node places them. */
typedef struct stretch_state {
    double *stretches;
    const double *boxes; /* NULL: no world box */
    double world[6];     /* low xyz, high xyz */
    bool any;
} stretch_state;

static lk_status measure_stretch(const lk_scene *scene, size_t node, const double m[16], void *user)
{
    stretch_state *state = user;
    int32_t mesh = scene->nodes[node].mesh;
    if (mesh < 0 || (size_t)mesh >= scene->mesh_count) return LK_OK;
    for (int column = 0; column < 3; column++) {
        const double *c = m + 4 * column;
        double length = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        if (length > state->stretches[mesh]) state->stretches[mesh] = length;
    }
    const double *box = state->boxes ? state->boxes + 6 * (size_t)mesh : NULL;
    if (!box || box[0] > box[3]) return LK_OK; /* no vertices */
    for (int corner = 0; corner < 8; corner++) {
        double p[3] = {box[corner & 1 ? 3 : 0], box[corner & 2 ? 4 : 1], box[corner & 4 ? 5 : 2]};
        for (int k = 0; k < 3; k++) {
            double w = m[k] * p[0] + m[4 + k] * p[1] + m[8 + k] * p[2] + m[12 + k];
            if (!state->any || w < state->world[k]) state->world[k] = w;
            if (!state->any || w > state->world[3 + k]) state->world[3 + k] = w;
            if (k == 2) state->any = true;
        }
    }
    return LK_OK;
}

lk_status lk__scene_mesh_stretches(const lk_scene *scene, double *stretches, double *world_extent, lk_error *error)
{
    stretch_state state = {stretches, NULL, {0, 0, 0, 0, 0, 0}, false};
    double *boxes = NULL;
    if (world_extent) {
        *world_extent = 0.0;
        boxes = lk__malloc_array(scene->mesh_count ? scene->mesh_count : 1, 6 * sizeof(double));
        if (!boxes) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        for (size_t m = 0; m < scene->mesh_count; m++) {
            double *box = boxes + 6 * m;
            box[0] = box[1] = box[2] = HUGE_VAL;
            box[3] = box[4] = box[5] = -HUGE_VAL;
            for (size_t p = 0; p < scene->meshes[m].primitive_count; p++) {
                const lk_mesh *mesh = &scene->meshes[m].primitives[p].mesh;
                for (size_t i = 0; i < 3 * mesh->vertex_count; i++) {
                    size_t k = i % 3;
                    if (mesh->positions[i] < box[k]) box[k] = mesh->positions[i];
                    if (mesh->positions[i] > box[3 + k]) box[3 + k] = mesh->positions[i];
                }
            }
        }
        state.boxes = boxes;
    }
    for (size_t m = 0; m < scene->mesh_count; m++) stretches[m] = 0.0;
    lk_status status = walk(scene, measure_stretch, &state, error);
    if (status == LK_OK && world_extent && state.any)
        *world_extent = fmax(state.world[3] - state.world[0],
                             fmax(state.world[4] - state.world[1], state.world[5] - state.world[2]));
    free(boxes);
    return status;
}

/* Output vertex o's input vertex: one that vertex_map sends to o, the one
 * whose attributes the output copied when there are several (the copies of
 * a seam vertex, vertices merged into it). */
static bool same_attributes(const lk_mesh *in, size_t v, const lk_mesh *out, size_t o)
{
    if (in->texcoords && out->texcoords && memcmp(in->texcoords + 2 * v, out->texcoords + 2 * o, 2 * sizeof(float)))
        return false;
    if (in->normals && out->normals && memcmp(in->normals + 3 * v, out->normals + 3 * o, 3 * sizeof(float)))
        return false;
    return true;
}

/* The arrays of a primitive that lk_mesh does not hold, for its simplified
 * mesh (or NULL where the primitive has none). */
typedef struct primitive_extras {
    float *tangents, *texcoords1, *weights;
    uint16_t *joints;
    float *target_positions, *target_normals, *target_tangents;
} primitive_extras;

static void extras_free(primitive_extras *extras)
{
    free(extras->tangents), free(extras->texcoords1), free(extras->weights), free(extras->joints);
    free(extras->target_positions), free(extras->target_normals), free(extras->target_tangents);
    memset(extras, 0, sizeof *extras);
}

/* Target k's deltas (3 floats per vertex) of output vertex o: those of its
 * input vertex v. */
static void carry_deltas(const float *in, size_t in_count, float *out, size_t out_count, size_t target_count, size_t v,
                         size_t o)
{
    for (size_t k = 0; in && k < target_count; k++)
        memcpy(out + 3 * (k * out_count + o), in + 3 * (k * in_count + v), 3 * sizeof(float));
}

/* The primitive's tangents, second texture coordinates, joints, weights
 * and morph-target deltas for the simplified mesh, taken from each output
 * vertex's input vertex. `shapes` (the simplified animation of the
 * primitive's shapes, lk_scene_simplify's QEM) gives the POSITION deltas
 * instead: each shape's own position of the output vertex minus the
 * base's. */
static lk_status carry_extras(lk_scene_primitive *primitive, size_t target_count, const lk_mesh *out,
                              const uint32_t *vertex_map, const lk_animation *shapes, primitive_extras *extras,
                              lk_error *error)
{
    memset(extras, 0, sizeof *extras);
    bool morphed =
        target_count > 0 && (primitive->target_positions || primitive->target_normals || primitive->target_tangents);
    if (!primitive->tangents && !primitive->texcoords1 && !primitive->joints && !primitive->weights && !morphed)
        return LK_OK;
    const lk_mesh *in = &primitive->mesh;
    size_t slots = out->vertex_count ? out->vertex_count : 1, deltas = morphed ? target_count * slots : 1;
    uint32_t *source = lk__malloc_array(slots, sizeof *source);
    if (primitive->tangents) extras->tangents = lk__malloc_array(slots, 4 * sizeof(float));
    if (primitive->texcoords1) extras->texcoords1 = lk__malloc_array(slots, 2 * sizeof(float));
    if (primitive->joints) extras->joints = lk__malloc_array(slots, 4 * sizeof(uint16_t));
    if (primitive->weights) extras->weights = lk__malloc_array(slots, 4 * sizeof(float));
    if (morphed && primitive->target_positions) extras->target_positions = lk__malloc_array(deltas, 3 * sizeof(float));
    if (morphed && primitive->target_normals) extras->target_normals = lk__malloc_array(deltas, 3 * sizeof(float));
    if (morphed && primitive->target_tangents) extras->target_tangents = lk__malloc_array(deltas, 3 * sizeof(float));
    if (!source || (primitive->tangents && !extras->tangents) || (primitive->texcoords1 && !extras->texcoords1) ||
        (primitive->joints && !extras->joints) || (primitive->weights && !extras->weights) ||
        (morphed && primitive->target_positions && !extras->target_positions) ||
        (morphed && primitive->target_normals && !extras->target_normals) ||
        (morphed && primitive->target_tangents && !extras->target_tangents)) {
        free(source);
        extras_free(extras);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory carrying tangents, joints, weights and morph targets");
    }
    for (size_t o = 0; o < out->vertex_count; o++) source[o] = UINT32_MAX;
    /* The source of an output vertex: an input vertex at its very position
     * when there is one (a half-edge collapse's kept end: its joints and
     * weights pose it where the input vertex is), then one with its
     * attributes. */
    for (size_t v = 0; v < in->vertex_count; v++) {
        uint32_t o = vertex_map[v];
        if (o >= out->vertex_count) continue;
        bool at = memcmp(in->positions + 3 * v, out->positions + 3 * (size_t)o, 3 * sizeof(float)) == 0;
        bool source_at = source[o] != UINT32_MAX && memcmp(in->positions + 3 * (size_t)source[o],
                                                           out->positions + 3 * (size_t)o, 3 * sizeof(float)) == 0;
        if (source[o] == UINT32_MAX || (at && !source_at) ||
            (at == source_at && !same_attributes(in, source[o], out, o) && same_attributes(in, v, out, o)))
            source[o] = (uint32_t)v;
    }
    size_t n = in->vertex_count, m = out->vertex_count;
    for (size_t o = 0; o < m; o++) {
        size_t v = source[o] == UINT32_MAX ? 0 : source[o];
        if (extras->tangents) memcpy(extras->tangents + 4 * o, primitive->tangents + 4 * v, 4 * sizeof(float));
        if (extras->texcoords1) memcpy(extras->texcoords1 + 2 * o, primitive->texcoords1 + 2 * v, 2 * sizeof(float));
        if (extras->joints) memcpy(extras->joints + 4 * o, primitive->joints + 4 * v, 4 * sizeof(uint16_t));
        if (extras->weights) memcpy(extras->weights + 4 * o, primitive->weights + 4 * v, 4 * sizeof(float));
        carry_deltas(extras->target_normals ? primitive->target_normals : NULL, n, extras->target_normals, m,
                     target_count, v, o);
        carry_deltas(extras->target_tangents ? primitive->target_tangents : NULL, n, extras->target_tangents, m,
                     target_count, v, o);
        if (!extras->target_positions) continue;
        if (!shapes) {
            carry_deltas(primitive->target_positions, n, extras->target_positions, m, target_count, v, o);
            continue;
        }
        const float *base = shapes->frame_positions + 3 * o;
        for (size_t k = 0; k < target_count; k++) {
            const float *shape = shapes->frame_positions + 3 * ((k + 1) * m + o);
            float *delta = extras->target_positions + 3 * (k * m + o);
            for (int c = 0; c < 3; c++) delta[c] = shape[c] - base[c];
        }
    }
    free(source);
    return LK_OK;
}

/* The animation lk_scene_simplify's QEM simplifies a primitive as: one
 * frame, its mesh (borrowed), or with morph targets a frame per shape, the
 * base and base + each target at full weight (frame_positions then its
 * own: free with free_shapes), so that the max scheme's cost is the worst
 * over the shapes and every shape gets its own position of each vertex.
 * Shapes are simplified with the lost-surface term at its default weight:
 * faerie.md2's frames 0, 45, 90, 135 and 180 as 4 targets, at 25%, worst
 * shape Hausdorff 6.69% (RMS 1.37%) of the diagonal with the quadrics
 * alone, 5.08% (0.97%) with it, 6.33% (1.24%) ranking by the base alone
 * (tests/unit/test_scene_morph.c). */
static lk_status shapes_of(lk_scene_primitive *primitive, size_t target_count, const float *posed,
                           lk_animation *animation, lk_error *error)
{
    lk_mesh *mesh = &primitive->mesh;
    as_animation(mesh, animation);
    if (!primitive->target_positions) target_count = 0;
    if (target_count == 0 && !posed) return LK_OK;
    size_t n = mesh->vertex_count, frame_count = target_count + 1 + (posed != NULL);
    float *frames = lk__malloc_array(frame_count * (n ? n : 1), 3 * sizeof(float));
    if (!frames) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for the shapes of the morph targets");
    memcpy(frames, mesh->positions, 3 * n * sizeof(float));
    for (size_t k = 0; k < target_count; k++)
        for (size_t i = 0; i < 3 * n; i++)
            frames[3 * (k + 1) * n + i] = mesh->positions[i] + primitive->target_positions[3 * k * n + i];
    if (posed) memcpy(frames + 3 * (target_count + 1) * n, posed, 3 * n * sizeof(float));
    animation->frame_count = frame_count;
    animation->frame_positions = frames;
    return LK_OK;
}

static void free_shapes(lk_animation *animation)
{
    if (animation->frame_positions != animation->mesh.positions) free(animation->frame_positions);
    animation->frame_positions = NULL;
}

/* Simplifies one triangle primitive. QEM goes through the one-frame
 * animation path: it welds the copies of a vertex that texture seams and
 * hard normals split, simplifies them as one vertex and splits them again,
 * each corner taking the attributes of the copy in its input triangle's
 * chart, so seams stay seams and copies move together (see
 * lk_anim_simplify_options.keep_seams). */
static lk_status simplify_primitive(lk_scene_primitive *primitive, size_t target_count, const float *posed,
                                    lk_simplify_method method, const lk_simplify_options *options,
                                    double *reached_error, lk_error *error)
{
    lk_mesh *mesh = &primitive->mesh;
    lk_mesh simplified;
    lk_mesh_init(&simplified);
    primitive_extras extras = {0};
    lk_status status;
    if (method == LK_SIMPLIFY_QEM) {
        lk_animation animation;
        status = shapes_of(primitive, target_count, posed, &animation, error);
        if (status != LK_OK) return status;
        lk_anim_simplify_options anim_options;
        anim_options_for(options, &anim_options);
        /* The shapes of morph targets get the lost-surface term
         * (shapes_of); a skinned primitive's posed frame does not: it is
         * the same surface moved joint by joint, and the term ranked the
         * collapses worse there (CGE's knight at 600 of its 646 triangles:
         * Hausdorff 0.61% of the diagonal with it, 0.31% without; the
         * avatar at 1114 of 8492: 0.61%, 0.48%). */
        if (animation.frame_count > 1 + (posed != NULL)) anim_options.lost_surface = LK_ANIM_LOST_SURFACE_DEFAULT;
        /* A skinned vertex is drawn where its joints put it, by its own
         * weights: a merged vertex stays on one of its ends, whose weights
         * it keeps, so that it is drawn where that input vertex is. */
        if (primitive->joints && primitive->weights) anim_options.simplify.flags |= LK_SIMPLIFY_ENDPOINTS;
        lk_anim_simplify_result result;
        memset(&result, 0, sizeof result);
        status = lk_animation_simplify(&animation, &anim_options, &result, NULL, NULL, error);
        free_shapes(&animation);
        if (status == LK_OK)
            status = carry_extras(primitive, target_count, &result.animation.mesh, result.vertex_map, &result.animation,
                                  &extras, error);
        if (status == LK_OK) {
            simplified = result.animation.mesh;
            lk_mesh_init(&result.animation.mesh);
            *reached_error = result.error;
        }
        lk_anim_simplify_result_free(&result);
    } else {
        lk_simplify_result result;
        memset(&result, 0, sizeof result);
        status = lk_simplify(mesh, method, options, &result, NULL, NULL, error);
        if (status == LK_OK)
            status = carry_extras(primitive, target_count, &result.mesh, result.vertex_map, NULL, &extras, error);
        if (status == LK_OK) {
            simplified = result.mesh;
            lk_mesh_init(&result.mesh);
            *reached_error = result.error;
        }
        lk_simplify_result_free(&result);
    }
    if (status != LK_OK) return status;
    lk_mesh_free(mesh);
    *mesh = simplified;
    free(primitive->tangents);
    free(primitive->texcoords1);
    free(primitive->joints);
    free(primitive->weights);
    free(primitive->target_positions);
    free(primitive->target_normals);
    free(primitive->target_tangents);
    primitive->tangents = extras.tangents;
    primitive->texcoords1 = extras.texcoords1;
    primitive->joints = extras.joints;
    primitive->weights = extras.weights;
    primitive->target_positions = extras.target_positions;
    primitive->target_normals = extras.target_normals;
    primitive->target_tangents = extras.target_tangents;
    return LK_OK;
}

/* ---- sharing a triangle budget across primitives ----------------------- */

/* A primitive's error curve: triangles[k] kept at error errors[k] (world
 * units), finest (the input, error 0) first; errors never decrease. */
typedef struct error_curve {
    size_t count;
    bool steps; /* read as steps, not interpolated (a small primitive's fine curve) */
    size_t triangles[48];
    double errors[48];
} error_curve;

/* The one-frame animation lk_scene_simplify's QEM runs on (borrows mesh). */
static void as_animation(lk_mesh *mesh, lk_animation *animation)
{
    lk_animation_init(animation);
    animation->mesh = *mesh;
    animation->frame_count = 1;
    animation->frame_positions = mesh->positions;
    animation->frames_per_second = 1.0;
}

static void anim_options_for(const lk_simplify_options *options, lk_anim_simplify_options *out)
{
    lk_anim_simplify_options_default(out);
    out->simplify = *options;
    out->simplify.flags &= ~(unsigned)(LK_SIMPLIFY_ATTRIBUTES | LK_SIMPLIFY_RECORD);
    out->allow_folds = 1;  /* one frame: the checks of lk_simplify */
    out->hold_seams = 1;   /* textures stay mapped */
    out->lost_surface = 0; /* the quadrics alone, as lk_simplify (and as fast); the shapes of
                              morph targets get lk_animation_simplify's default (shapes_of) */
}

/* The largest distance from `points` (count of them, 3 doubles each) to
 * the surface, raised into *largest: each point asks only whether it is
 * farther than the largest so far, which prunes most of the search. */
static void farthest_from(const lk_surface_index *index, const double *points, size_t count, double *largest)
{
    for (size_t i = 0; i < count; i++) {
        double bound = *largest > 0 ? *largest : INFINITY;
        double d = lk_surface_index_nearest(index, points + 3 * i, bound, NULL, NULL);
        if (d == INFINITY && bound != INFINITY)
            d = lk_surface_index_nearest(index, points + 3 * i, INFINITY, NULL, NULL);
        if (d != INFINITY && d > *largest) *largest = d;
    }
}

/* A Hausdorff distance between a primitive and a level of it. Forward (the
 * primitive to the level), on few samples: its vertices, triangle centres
 * and edge midpoints (a cut-off corner shows at its vertex). Backward (the
 * level, a fraction of the size, to the primitive): Metro's own sampling,
 * faces, vertices and edges (a flap across a gap shows inside its
 * triangles). */
static lk_status level_distance(const lk_mesh *input, const lk_surface_index *input_index, const lk_mesh *level,
                                const uint32_t *vertex_map, double *out, lk_error *error)
{
    *out = 0.0;
    if (level->triangle_count == 0) return LK_OK;
    lk_metro_options metro;
    lk_metro_options_default(&metro);
    metro.thread_count = 1;
    metro.samples_per_face = 1;
    lk_distance_stats backward;
    lk_status status = lk_metro_one_sided(level, input_index, &metro, &backward, error);
    if (status != LK_OK) return status;
    *out = backward.max;
    /* Forward: an input vertex's distance to the level is at most its
     * distance to the vertex it became (vertex_map); only the vertices
     * whose bound exceeds the largest distance so far are looked up, and
     * the level is indexed only if one is. */
    lk_surface_index *level_index = NULL;
    for (size_t v = 0; v < input->vertex_count && status == LK_OK; v++) {
        const float *p = input->positions + 3 * v;
        uint32_t o = vertex_map ? vertex_map[v] : UINT32_MAX;
        if (o < level->vertex_count) {
            const float *q = level->positions + 3 * (size_t)o;
            double dx = (double)p[0] - q[0], dy = (double)p[1] - q[1], dz = (double)p[2] - q[2];
            if (sqrt(dx * dx + dy * dy + dz * dz) <= *out) continue;
        }
        if (!level_index) {
            status = lk_surface_index_build(level, &level_index, error);
            if (status != LK_OK) break;
        }
        double point[3] = {p[0], p[1], p[2]};
        farthest_from(level_index, point, 1, out);
    }
    lk_surface_index_free(level_index);
    return status;
}

/* Threads measuring error curves, at most. */
#define CURVE_THREADS_MAX 16

/* Primitives up to this many triangles get a curve of fine steps. */
#define CURVE_FINE_TRIANGLES 512

/* Samples the primitive's error at triangle counts a factor 2 apart
 * in one QEM run (lk_animation_simplify_levels: the collapse order does not
 * depend on the target). */
static lk_status measure_curve(lk_scene_primitive *primitive, size_t target_count, const lk_simplify_options *options,
                               double stretch, error_curve *curve, lk_error *error)
{
    lk_mesh *mesh = &primitive->mesh;
    double ratios[47];
    size_t level_count = 0;
    double count = (double)mesh->triangle_count;
    /* A small primitive (a floor tile of a level: 24 triangles) can lose a
     * corner in one collapse, an error the factor-2 points would hide
     * between them: its curve has 47 points down to one triangle, and the
     * scene's threshold reads it as steps (curve_triangles). */
    curve->steps = mesh->triangle_count <= CURVE_FINE_TRIANGLES;
    double factor = curve->steps ? pow(count, -1.0 / 47.0) : 0.5;
    for (size_t i = 1; level_count < 47; i++) {
        double ratio = pow(factor, (double)i);
        if (curve->steps && count <= 48.0) ratio = (count - (double)i) / count; /* every triangle count */
        if (ratio * count < 1.0) break;
        ratios[level_count++] = ratio;
    }
    curve->count = 1;
    curve->triangles[0] = mesh->triangle_count;
    curve->errors[0] = 0.0;
    if (level_count == 0) return LK_OK;
    lk_anim_simplify_result *results = lk__calloc_array(level_count, sizeof *results);
    if (!results) return lk_error_set(error, LK_ERR_NOMEM, "out of memory measuring a primitive");
    lk_animation animation;
    lk_status status = shapes_of(primitive, target_count, NULL, &animation, error);
    lk_anim_simplify_options anim_options;
    anim_options_for(options, &anim_options);
    if (animation.frame_count > 1) anim_options.lost_surface = LK_ANIM_LOST_SURFACE_DEFAULT;
    if (status == LK_OK)
        status =
            lk_animation_simplify_levels(&animation, &anim_options, ratios, level_count, results, NULL, NULL, error);
    free_shapes(&animation);
    /* The curve's error is the larger of the QEM's and the level's
     * Hausdorff distance to the primitive (level_distance): the QEM's cost
     * is an area-weighted mean, blind to a corner of a small flat panel
     * cut off, and the scene's threshold would then hand that primitive's
     * triangles to others (2CylinderEngine at 25%: 1.32% of the diagonal
     * with the QEM's errors alone, 0.78% with the measured ones). */
    lk_surface_index *index = NULL;
    status = status == LK_OK ? lk_surface_index_build(mesh, &index, error) : status;
    for (size_t k = 0; k < level_count; k++) {
        if (status == LK_OK) {
            double measured = 0.0;
            status = level_distance(mesh, index, &results[k].animation.mesh, results[k].vertex_map, &measured, error);
            double value = fmax(results[k].error, measured) * stretch;
            double previous = curve->errors[curve->count - 1];
            curve->triangles[curve->count] = results[k].animation.mesh.triangle_count;
            curve->errors[curve->count] = value > previous ? value : previous;
            curve->count++;
        }
        lk_anim_simplify_result_free(&results[k]);
    }
    lk_surface_index_free(index);
    free(results);
    return status;
}

/* The curves of every primitive with triangles (in scene order), measured
 * on the online cores (each curve is independent, so the result does not
 * depend on the thread count); the first failure in scene order is
 * reported. */
typedef struct curve_job {
    lk_scene_primitive *primitive;
    size_t target_count;
    double stretch;
    lk_status status;
    lk_error error;
} curve_job;

typedef struct curve_run {
    curve_job *jobs;
    error_curve *curves;
    size_t job_count;
    const lk_simplify_options *options;
    atomic_size_t next;
} curve_run;

static void *curve_worker(void *user)
{
    curve_run *run = user;
    for (;;) {
        size_t i = atomic_fetch_add(&run->next, 1);
        if (i >= run->job_count) return NULL;
        curve_job *job = &run->jobs[i];
        job->status =
            measure_curve(job->primitive, job->target_count, run->options, job->stretch, &run->curves[i], &job->error);
    }
}

static lk_status measure_curves(lk_scene *scene, const lk_simplify_options *options, const double *stretches,
                                error_curve *curves, size_t primitive_count, lk_error *error)
{
    curve_job *jobs = lk__calloc_array(primitive_count, sizeof *jobs);
    size_t *uses = lk__calloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *uses);
    if (!jobs || !uses) {
        free(jobs);
        free(uses);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    for (size_t n = 0; n < scene->node_count; n++)
        if (scene->nodes[n].mesh >= 0 && (size_t)scene->nodes[n].mesh < scene->mesh_count) uses[scene->nodes[n].mesh]++;
    size_t j = 0;
    for (size_t m = 0; m < scene->mesh_count; m++)
        for (size_t p = 0; p < scene->meshes[m].primitive_count; p++) {
            lk_scene_primitive *primitive = &scene->meshes[m].primitives[p];
            if (primitive->mesh.triangle_count == 0) continue;
            jobs[j].primitive = primitive;
            jobs[j].target_count = scene->meshes[m].target_count;
            /* A mesh drawn n times holds n times its share of the drawn
             * surface's squared error: its errors weigh sqrt(n) (the
             * castle's 16 trees and 5 tower roofs at 10%: RMS 0.063% of
             * the diagonal without, 0.034% with; gltfpack 0.047%). */
            jobs[j].stretch = stretches[m] * sqrt(uses[m] > 1 ? (double)uses[m] : 1.0);
            j++;
        }
    curve_run run = {jobs, curves, primitive_count, options, 0};
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    size_t thread_count = cores > 1 ? (size_t)cores : 1;
    if (thread_count > primitive_count) thread_count = primitive_count;
    if (thread_count > CURVE_THREADS_MAX) thread_count = CURVE_THREADS_MAX;
    pthread_t threads[CURVE_THREADS_MAX];
    size_t started = 0;
    while (started + 1 < thread_count && pthread_create(&threads[started], NULL, curve_worker, &run) == 0) started++;
    curve_worker(&run); /* this thread works too; fewer threads, same result */
    for (size_t t = 0; t < started; t++) pthread_join(threads[t], NULL);
    lk_status status = LK_OK;
    for (size_t i = 0; i < primitive_count && status == LK_OK; i++)
        if (jobs[i].status != LK_OK) {
            status = jobs[i].status;
            if (error) *error = jobs[i].error;
        }
    free(jobs);
    free(uses);
    return status;
}

/* Triangles the curve keeps at error e: between two samples, log-linear. */
static double curve_triangles(const error_curve *curve, double e)
{
    size_t k = 0;
    while (k + 1 < curve->count && curve->errors[k + 1] <= e) k++;
    if (k + 1 == curve->count) return (double)curve->triangles[k];
    /* Steps: the fewest triangles measured within e, never a count between
     * two points whose error is known only to be at most the next one's. */
    if (curve->steps) return (double)curve->triangles[k];
    double low = curve->errors[k], high = curve->errors[k + 1];
    double f = high > low ? (e - low) / (high - low) : 0.0;
    double a = log((double)curve->triangles[k] + 0.5), b = log((double)curve->triangles[k + 1] + 0.5);
    return exp(a + f * (b - a)) - 0.5;
}

/* The triangles that read the step curves as steps left unspent (up to
 * one step per small primitive, 11% of ClearCoatTest's at 10%): given to
 * the interpolated curves first (one threshold for them alone over what
 * remains), then step by step to the small primitive whose next finer
 * point has the smallest error, while a step fits. */
static void fill_budget(const error_curve *curves, size_t curve_count, size_t budget, double *counts)
{
    double spent = 0.0, stepped = 0.0, high = 0.0;
    bool interpolated = false;
    for (size_t i = 0; i < curve_count; i++) {
        spent += counts[i];
        if (curves[i].steps) {
            stepped += counts[i];
        } else {
            interpolated = true;
            high = fmax(high, curves[i].errors[curves[i].count - 1]);
        }
    }
    if (interpolated && spent < (double)budget) {
        double low = 0.0;
        for (int iteration = 0; iteration < 80; iteration++) {
            double middle = 0.5 * (low + high), kept = stepped;
            for (size_t i = 0; i < curve_count; i++)
                if (!curves[i].steps) kept += curve_triangles(&curves[i], middle);
            if (kept > (double)budget)
                low = middle;
            else
                high = middle;
        }
        spent = stepped;
        for (size_t i = 0; i < curve_count; i++)
            if (!curves[i].steps) {
                double kept = curve_triangles(&curves[i], high);
                if (kept > counts[i]) counts[i] = kept;
                spent += counts[i];
            }
    }
    for (;;) {
        size_t best = curve_count, best_point = 0;
        for (size_t i = 0; i < curve_count; i++) {
            if (!curves[i].steps) continue;
            size_t k = 0; /* the point counts[i] came from */
            while (k + 1 < curves[i].count && (double)curves[i].triangles[k] > counts[i]) k++;
            size_t finer = k;
            while (finer > 0 && (double)curves[i].triangles[finer] <= counts[i]) finer--;
            if ((double)curves[i].triangles[finer] <= counts[i]) continue; /* whole already */
            if (spent + (double)curves[i].triangles[finer] - counts[i] > (double)budget) continue;
            if (best == curve_count || curves[i].errors[finer] < curves[best].errors[best_point])
                best = i, best_point = finer;
        }
        if (best == curve_count) break;
        spent += (double)curves[best].triangles[best_point] - counts[best];
        counts[best] = (double)curves[best].triangles[best_point];
    }
}

/* ---- lk_scene_simplify ----------------------------------------------------- */

static lk_status simplify_scene(lk_scene *scene, lk_simplify_method method, const lk_simplify_options *options,
                                lk_scene_simplify_stats *stats, lk_error *error)
{
    lk_scene_simplify_stats local;
    memset(&local, 0, sizeof local);
    size_t total = lk_scene_triangle_count(scene);
    double scene_diagonal = 0.0;
    if (options->max_error > 0) {
        lk_mesh flat;
        lk_status status = lk_scene_flatten(scene, &flat, error);
        if (status != LK_OK) return status;
        scene_diagonal = lk_mesh_bounds(&flat, NULL, NULL);
        lk_mesh_free(&flat);
    }
    /* The primitives with triangles and the world scale of each's mesh. */
    size_t primitive_count = 0;
    for (size_t m = 0; m < scene->mesh_count; m++)
        for (size_t p = 0; p < scene->meshes[m].primitive_count; p++)
            primitive_count += scene->meshes[m].primitives[p].mesh.triangle_count > 0;
    if (primitive_count == 0) {
        if (stats) *stats = local;
        return LK_OK;
    }
    double *stretches = lk__malloc_array(scene->mesh_count, sizeof *stretches);
    double *counts = lk__calloc_array(primitive_count, sizeof *counts);
    error_curve *curves = NULL;
    lk_status status = stretches && counts ? LK_OK : lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    if (status == LK_OK) status = lk__scene_mesh_stretches(scene, stretches, NULL, error);
    for (size_t m = 0; status == LK_OK && m < scene->mesh_count; m++)
        if (!(stretches[m] > 0)) stretches[m] = 1.0;
    /* A count target over several primitives (QEM): one error threshold for
     * the whole scene, found on each primitive's error curve, decides how
     * many triangles each keeps, so the budget goes where it buys the most
     * (a flat panel of a machine gives its triangles to a curved part), as
     * one QEM over the whole scene would order its collapses. */
    size_t budget = options->target_triangles;
    if (options->target_ratio > 0) {
        size_t by_ratio = (size_t)floor(options->target_ratio * (double)total);
        if (budget == 0 || by_ratio < budget) budget = by_ratio;
    }
    bool shared = method == LK_SIMPLIFY_QEM && budget > 0 && primitive_count > 1;
    if (status == LK_OK && shared) {
        curves = lk__calloc_array(primitive_count, sizeof *curves);
        if (!curves) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        if (status == LK_OK) status = measure_curves(scene, options, stretches, curves, primitive_count, error);
        if (status == LK_OK) {
            double high = 0.0;
            for (size_t i = 0; i < primitive_count; i++) high = fmax(high, curves[i].errors[curves[i].count - 1]);
            double low = 0.0;
            for (int iteration = 0; iteration < 80; iteration++) {
                double middle = 0.5 * (low + high), kept = 0.0;
                for (size_t i = 0; i < primitive_count; i++) kept += curve_triangles(&curves[i], middle);
                if (kept > (double)budget)
                    low = middle;
                else
                    high = middle;
            }
            for (size_t i = 0; i < primitive_count; i++) counts[i] = curve_triangles(&curves[i], high);
            fill_budget(curves, primitive_count, budget, counts);
        }
    }
    /* Skinned primitives are simplified in their bind pose and as their
     * joints pose them at rest (what a viewer draws before an animation
     * plays), the larger of the two errors deciding (the animation path's
     * max scheme). */
    double *worlds = NULL;
    if (status == LK_OK && method == LK_SIMPLIFY_QEM && scene->skin_count > 0 && scene->node_count > 0) {
        worlds = lk__calloc_array(scene->node_count, 16 * sizeof(double));
        status = worlds ? walk(scene, store_world, worlds, error)
                        : lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu node matrices", scene->node_count);
    }
    size_t j = 0;
    for (size_t m = 0; status == LK_OK && m < scene->mesh_count; m++) {
        lk_scene_mesh *mesh = &scene->meshes[m];
        double stretch = stretches[m];
        for (size_t p = 0; status == LK_OK && p < mesh->primitive_count; p++) {
            lk_mesh *primitive = &mesh->primitives[p].mesh;
            if (primitive->triangle_count == 0) continue;
            lk_scene_primitive *whole = &mesh->primitives[p];
            lk_simplify_options own = *options;
            own.target_vertices = 0;
            size_t before = primitive->triangle_count;
            if (shared) {
                own.target_ratio = 0;
                own.target_triangles = (size_t)llround(counts[j] > 1 ? counts[j] : 1);
            } else if (options->target_triangles && primitive_count == 1) {
                own.target_triangles = options->target_triangles; /* the whole budget */
            } else if (options->target_triangles && total > 0) {
                double share = (double)options->target_triangles / (double)total;
                own.target_triangles = 0;
                own.target_ratio = share < 1.0 ? share : 1.0;
                if (options->target_ratio > 0 && options->target_ratio < own.target_ratio)
                    own.target_ratio = options->target_ratio;
            }
            j++;
            if (options->max_error > 0) {
                /* The scene's error in this primitive's units, as a share of
                 * its own diagonal (what lk_simplify takes). */
                double diagonal = lk_mesh_bounds(primitive, NULL, NULL);
                double allowed = options->max_error * scene_diagonal / stretch;
                own.max_error = diagonal > 0 ? allowed / diagonal : 0.0;
                if (!(own.target_ratio > 0) && own.target_triangles == 0) own.target_triangles = 1;
            }
            double reached = 0.0;
            float *posed = lk__scene_posed_primitive(scene, worlds, m, whole);
            if (!(shared && own.target_triangles >= before))
                status = simplify_primitive(whole, mesh->target_count, posed, method, &own, &reached, error);
            free(posed);
            if (status != LK_OK) {
                char message[sizeof error->message];
                if (error) {
                    snprintf(message, sizeof message, "%s", error->message);
                    lk_error_set(error, status, "meshes[%zu].primitives[%zu]: %s", m, p, message);
                }
                break;
            }
            local.primitives++;
            local.triangles_in += before;
            local.triangles_out += primitive->triangle_count;
            if (reached * stretch > local.error) local.error = reached * stretch;
        }
    }
    free(worlds);
    free(stretches);
    free(counts);
    free(curves);
    if (status == LK_OK && stats) *stats = local;
    return status;
}

/* The scene's Hausdorff distance as drawn (lk_scene_flatten) to `input`,
 * the input flattened: lk_metro, both ways, on every core. */
static lk_status scene_distance(const lk_scene *scene, const lk_mesh *input, double *out, lk_error *error)
{
    lk_mesh flat;
    lk_status status = lk_scene_flatten(scene, &flat, error);
    if (status != LK_OK) return status;
    lk_metro_result result;
    status = lk_metro(input, &flat, NULL, &result, NULL, NULL, error);
    if (status == LK_OK) *out = result.hausdorff;
    lk_mesh_free(&flat);
    return status;
}

/* QEM runs twice, with the crease and corner constraints and without
 * them, and the scene closer to the input as drawn is kept (when it has no
 * more triangles). The constraints hold a sharp edge against the smooth
 * surface around it; on a low-polygon model, where most edges are sharp,
 * they misrank the collapses instead: CGE's knight at 600 of its 646
 * triangles is at Hausdorff 0.31% of the diagonal with them and 0.25%
 * without (gltfpack: 0.26%), the spider (assimp-testmodels) at 30% at 2.34%
 * and 1.84%, while CGE's monkey at 1124 of 3936 is at 0.54% with them and
 * 0.68% without. Choosing per primitive was tried and lost: a primitive's
 * own error is not what the scene shows (a switch on a wall is hidden by
 * the wall where it is cut). One run when the caller turned the
 * constraints off, when an error bound (not a size) is the target (the two
 * would reach different sizes), or when a mesh has morph targets (the
 * scene as drawn shows one of its shapes). */
lk_status lk_scene_simplify(lk_scene *scene, lk_simplify_method method, const lk_simplify_options *options,
                            lk_scene_simplify_stats *stats, lk_error *error)
{
    if (!scene || !options) return lk_error_set(error, LK_ERR_INVALID, "lk_scene_simplify: NULL argument");
    if (!(options->target_ratio > 0) && options->target_triangles == 0 && options->target_vertices == 0 &&
        !(options->max_error > 0))
        return lk_error_set(error, LK_ERR_INVALID, "lk_scene_simplify: set a target (ratio, triangles or max_error)");
    bool shapes = false;
    for (size_t m = 0; m < scene->mesh_count; m++) shapes = shapes || scene->meshes[m].target_count > 0;
    if (method != LK_SIMPLIFY_QEM || (options->flags & LK_SIMPLIFY_NO_FEATURES) || options->max_error > 0 || shapes ||
        lk_scene_triangle_count(scene) == 0)
        return simplify_scene(scene, method, options, stats, error);
    /* The input as drawn, to measure both runs against. A scene that does
     * not flatten to triangles (no node draws them; a transform that is
     * not finite) cannot be judged so: one run, as before. */
    lk_mesh input;
    lk_error ignored = {0};
    if (lk_scene_flatten(scene, &input, &ignored) != LK_OK) return simplify_scene(scene, method, options, stats, error);
    if (input.triangle_count == 0) {
        lk_mesh_free(&input);
        return simplify_scene(scene, method, options, stats, error);
    }
    lk_scene plain;
    lk_scene_simplify_stats with_stats, plain_stats;
    lk_simplify_options without = *options;
    without.flags |= LK_SIMPLIFY_NO_FEATURES;
    double with_distance = 0.0, plain_distance = 0.0;
    lk_status status = lk_scene_copy(&plain, scene, error);
    if (status != LK_OK) {
        lk_mesh_free(&input);
        return status;
    }
    /* each run measures its own error curves: sharing the first's shares
     * of the target saved a quarter of the time on the 2CylinderEngine and
     * cost the spider its gain (2.34% instead of 1.84%) */
    status = simplify_scene(scene, method, options, &with_stats, error);
    /* The second run and the measurements only choose: when one of them
     * fails (a result that does not flatten, out of memory), the first
     * run's scene stands, as a single run would have given it. */
    bool swap = status == LK_OK && simplify_scene(&plain, method, &without, &plain_stats, &ignored) == LK_OK &&
                scene_distance(scene, &input, &with_distance, &ignored) == LK_OK &&
                scene_distance(&plain, &input, &plain_distance, &ignored) == LK_OK && plain_distance < with_distance &&
                lk_scene_triangle_count(&plain) <= lk_scene_triangle_count(scene);
    if (swap) {
        lk_scene featured = *scene;
        *scene = plain;
        plain = featured;
    }
    if (status == LK_OK && stats) *stats = swap ? plain_stats : with_stats;
    lk_scene_free(&plain);
    lk_mesh_free(&input);
    return status;
}

/* ---- LOD chains ------------------------------------------------------------ */

/* `extras` (a JSON object's text, or NULL) with `members` ("\"a\":1,\"b\":2")
 * added at its start; NULL when out of memory. */
static char *extras_with(const char *extras, const char *members)
{
    const char *rest = "}";
    if (extras) {
        const char *brace = extras;
        while (*brace == ' ' || *brace == '\t' || *brace == '\n' || *brace == '\r') brace++;
        if (*brace != '{') brace = NULL; /* not an object: replaced */
        if (brace) {
            const char *after = brace + 1;
            while (*after == ' ' || *after == '\t' || *after == '\n' || *after == '\r') after++;
            rest = *after == '}' ? "}" : NULL;
            if (!rest) rest = after - 1; /* ",..." follows */
        }
    }
    size_t size = strlen(members) + strlen(rest) + 4;
    char *out = malloc(size);
    if (!out) return NULL;
    if (rest[0] == '}')
        snprintf(out, size, "{%s}", members);
    else
        snprintf(out, size, "{%s,%s", members, rest + 1);
    return out;
}

/* A level node stands in for its node: every channel animating the node
 * animates its levels too, with the same sampler (morph weights always;
 * translation, rotation and scale unless the level is skinned, whose
 * node transform does not apply). */
static lk_status animate_levels(lk_scene *scene, lk_error *error)
{
    for (size_t a = 0; a < scene->animation_count; a++) {
        lk_scene_animation *animation = &scene->animations[a];
        size_t added = 0, count = animation->channel_count;
        for (size_t c = 0; c < count; c++)
            if (animation->channels[c].node < scene->node_count)
                added += scene->nodes[animation->channels[c].node].lod_count;
        if (added == 0) continue;
        lk_scene_animation_channel *channels = lk__realloc_array(animation->channels, count + added, sizeof *channels);
        if (!channels) return lk_error_set(error, LK_ERR_NOMEM, "out of memory building the chain");
        animation->channels = channels;
        for (size_t c = 0; c < count; c++) {
            lk_scene_animation_channel channel = channels[c];
            if (channel.node >= scene->node_count) continue;
            const lk_scene_node *node = &scene->nodes[channel.node];
            for (size_t l = 0; l < node->lod_count; l++) {
                if (channel.path != LK_SCENE_PATH_WEIGHTS && scene->nodes[node->lod_nodes[l]].skin >= 0) continue;
                channels[animation->channel_count] = channel;
                channels[animation->channel_count++].node = node->lod_nodes[l];
            }
        }
    }
    return LK_OK;
}

lk_status lk_scene_lod_chain(const lk_scene *levels, size_t level_count, const lk_lod_level_info *info, lk_scene *out,
                             lk_error *error)
{
    if (!levels || !out || level_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "lk_scene_lod_chain: no levels");
    const lk_scene *base = &levels[0];
    for (size_t k = 1; k < level_count; k++)
        if (levels[k].node_count != base->node_count || levels[k].mesh_count != base->mesh_count)
            return lk_error_set(error, LK_ERR_INVALID,
                                "level %zu has %zu nodes and %zu meshes, level 0 %zu and %zu: levels must share the "
                                "node tree",
                                k, levels[k].node_count, levels[k].mesh_count, base->node_count, base->mesh_count);
    size_t with_mesh = 0;
    for (size_t i = 0; i < base->node_count; i++) with_mesh += base->nodes[i].mesh >= 0;
    size_t coarser = level_count - 1;
    lk_status status = lk__scene_copy(out, base, with_mesh * coarser, base->mesh_count * coarser, error);
    if (status != LK_OK) return status;
    /* the coarser levels' meshes after level 0's */
    for (size_t k = 1; k < level_count && status == LK_OK; k++)
        for (size_t m = 0; m < base->mesh_count; m++) {
            lk_scene_mesh *mesh = &out->meshes[out->mesh_count];
            out->mesh_count++;
            if (!lk__scene_copy_mesh(mesh, &levels[k].meshes[m]))
                status = lk_error_set(error, LK_ERR_NOMEM, "out of memory building the chain");
        }
    char members[1024];
    for (size_t i = 0; i < base->node_count && status == LK_OK; i++) {
        lk_scene_node *node = &out->nodes[i];
        if (node->mesh < 0 || coarser == 0) continue;
        free(node->lod_nodes);
        node->lod_nodes = lk__calloc_array(coarser, sizeof *node->lod_nodes);
        node->lod_count = 0;
        if (!node->lod_nodes) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory building the chain");
            break;
        }
        for (size_t k = 1; k < level_count; k++) {
            size_t id = out->node_count;
            lk_scene_node *level_node = &out->nodes[id];
            lk__scene_node_init(level_node);
            out->node_count++;
            /* the same place as the node it stands in for */
            level_node->has_matrix = node->has_matrix;
            memcpy(level_node->matrix, node->matrix, sizeof node->matrix);
            memcpy(level_node->translation, node->translation, sizeof node->translation);
            memcpy(level_node->rotation, node->rotation, sizeof node->rotation);
            memcpy(level_node->scale, node->scale, sizeof node->scale);
            level_node->skin = node->skin;
            level_node->mesh = (int32_t)(base->mesh_count * k + (size_t)node->mesh);
            if (!lk__scene_copy_array((void **)&level_node->weights, node->weights,
                                      out->meshes[level_node->mesh].target_count, sizeof(float))) {
                status = lk_error_set(error, LK_ERR_NOMEM, "out of memory building the chain");
                break;
            }
            size_t triangles = 0;
            for (size_t p = 0; p < out->meshes[level_node->mesh].primitive_count; p++)
                triangles += out->meshes[level_node->mesh].primitives[p].mesh.triangle_count;
            snprintf(members, sizeof members, "\"lodkit\":{\"level\":%zu,\"triangles\":%zu,\"error\":%.9g}", k,
                     triangles, info ? info[k].error : 0.0);
            level_node->extras = extras_with(NULL, members);
            if (node->name) {
                size_t size = strlen(node->name) + 16;
                level_node->name = malloc(size);
                if (level_node->name) snprintf(level_node->name, size, "%s_lod%zu", node->name, k);
            }
            if (!level_node->extras || (node->name && !level_node->name)) {
                status = lk_error_set(error, LK_ERR_NOMEM, "out of memory building the chain");
                break;
            }
            node->lod_nodes[node->lod_count++] = (uint32_t)id;
        }
        if (status != LK_OK) break;
        size_t used = (size_t)snprintf(members, sizeof members, "\"MSFT_screencoverage\":[");
        for (size_t k = 0; k < level_count && used < sizeof members - 32; k++)
            used += (size_t)snprintf(members + used, sizeof members - used, "%s%.9g", k ? "," : "",
                                     info ? info[k].screen_coverage : 0.0);
        snprintf(members + used, sizeof members - used, "]");
        char *extras = extras_with(node->extras, members);
        if (!extras) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory building the chain");
            break;
        }
        free(node->extras);
        node->extras = extras;
    }
    if (status == LK_OK) status = animate_levels(out, error);
    if (status != LK_OK) lk_scene_free(out);
    return status;
}
