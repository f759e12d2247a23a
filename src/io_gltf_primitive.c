/* SPDX-License-Identifier: MIT */
/* What the glTF scene writer (io_gltf_mesh_write.c) does to a primitive's
 * data before it encodes it: the compact encodings' vertex welding and
 * reordering, what a material samples, and tangents for normal maps. */
#include "io_gltf.h"

#include <meshoptimizer.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A copy of `mesh` made ready for the compact encodings (quantised or
 * meshopt-compressed output): vertices equal in every attribute written
 * merged into one (meshopt_generateVertexRemapMulti), triangles whose
 * corners became one vertex dropped (they cover no pixel), triangles
 * reordered for the vertex cache and vertices in order of first use
 * (optimizeVertexCache, optimizeVertexFetchRemap: what makes meshopt's
 * codecs effective), vertices no triangle uses dropped. When nothing
 * would be left, a plain copy in the same order. */
bool lk__gltf_compact_for_codecs(const lk_scene_primitive *in, lk_scene_primitive *out)
{
    const lk_mesh *mesh = &in->mesh;
    memset(out, 0, sizeof *out);
    lk_mesh_init(&out->mesh);
    out->material = in->material;
    size_t vertex_count = mesh->vertex_count, index_count = 3 * mesh->triangle_count;
    struct meshopt_Stream streams[8];
    size_t stream_count = 0;
    streams[stream_count++] = (struct meshopt_Stream){mesh->positions, 3 * sizeof(float), 3 * sizeof(float)};
    if (mesh->normals)
        streams[stream_count++] = (struct meshopt_Stream){mesh->normals, 3 * sizeof(float), 3 * sizeof(float)};
    if (mesh->texcoords)
        streams[stream_count++] = (struct meshopt_Stream){mesh->texcoords, 2 * sizeof(float), 2 * sizeof(float)};
    if (mesh->colors)
        streams[stream_count++] = (struct meshopt_Stream){mesh->colors, 4 * sizeof(float), 4 * sizeof(float)};
    if (in->tangents)
        streams[stream_count++] = (struct meshopt_Stream){in->tangents, 4 * sizeof(float), 4 * sizeof(float)};
    if (in->texcoords1)
        streams[stream_count++] = (struct meshopt_Stream){in->texcoords1, 2 * sizeof(float), 2 * sizeof(float)};
    if (in->joints)
        streams[stream_count++] = (struct meshopt_Stream){in->joints, 4 * sizeof(uint16_t), 4 * sizeof(uint16_t)};
    if (in->weights)
        streams[stream_count++] = (struct meshopt_Stream){in->weights, 4 * sizeof(float), 4 * sizeof(float)};
    unsigned int *weld = lk__malloc_array(vertex_count, sizeof(unsigned int));
    unsigned int *indices = lk__malloc_array(index_count, sizeof(unsigned int));
    unsigned int *fetch = lk__malloc_array(vertex_count, sizeof(unsigned int));
    bool ok = false;
    if (!weld || !indices || !fetch) goto done;
    size_t unique =
        meshopt_generateVertexRemapMulti(weld, mesh->indices, index_count, vertex_count, streams, stream_count);
    size_t kept = 0;
    for (size_t i = 0; i < index_count; i += 3) {
        unsigned int a = weld[mesh->indices[i]], b = weld[mesh->indices[i + 1]], c = weld[mesh->indices[i + 2]];
        if (a == b || b == c || a == c) continue;
        indices[kept++] = a, indices[kept++] = b, indices[kept++] = c;
    }
    if (kept == 0) { /* all degenerate: keep them as they are */
        memcpy(indices, mesh->indices, index_count * sizeof(unsigned int));
        for (size_t v = 0; v < vertex_count; v++) weld[v] = (unsigned int)v;
        unique = vertex_count, kept = index_count;
    }
    meshopt_optimizeVertexCacheStrip(indices, indices, kept, unique);
    size_t used = meshopt_optimizeVertexFetchRemap(fetch, indices, kept, unique);
    unsigned flags = (mesh->normals ? LK_ATTR_NORMALS : 0) | (mesh->texcoords ? LK_ATTR_TEXCOORDS : 0) |
                     (mesh->colors ? LK_ATTR_COLORS : 0);
    if (lk_mesh_alloc(&out->mesh, used, kept / 3, flags, NULL) != LK_OK) goto done;
    meshopt_remapIndexBuffer(out->mesh.indices, indices, kept, fetch);
    /* Input vertex -> output vertex (~0: merged away unused); merged
     * vertices write the same values. */
    for (size_t v = 0; v < vertex_count; v++) weld[v] = weld[v] == ~0u ? ~0u : fetch[weld[v]];
    for (size_t k = 0; k < stream_count; k++) {
        const void *source = streams[k].data;
        size_t size = streams[k].size;
        void *target = source == mesh->positions   ? out->mesh.positions
                       : source == mesh->normals   ? out->mesh.normals
                       : source == mesh->texcoords ? out->mesh.texcoords
                       : source == mesh->colors    ? out->mesh.colors
                                                   : lk__malloc_array(used ? used : 1, size);
        if (!target) goto done;
        if (source == in->tangents) out->tangents = target;
        if (source == in->texcoords1) out->texcoords1 = target;
        if (source == in->joints) out->joints = target;
        if (source == in->weights) out->weights = target;
        meshopt_remapVertexBuffer(target, source, vertex_count, size, weld);
    }
    ok = true;
done:
    free(weld);
    free(indices);
    free(fetch);
    return ok;
}

void lk__gltf_compacted_free(lk_scene_primitive *primitive)
{
    lk_mesh_free(&primitive->mesh);
    free(primitive->tangents), free(primitive->texcoords1), free(primitive->joints), free(primitive->weights);
    memset(primitive, 0, sizeof *primitive);
}

/* Which TEXCOORD_n sets a material (its JSON) samples, bit n: the
 * texCoord (default 0) of every texture reference (an object with an
 * "index" under a key ending in "Texture": baseColorTexture,
 * normalTexture, KHR_materials_*'s ...Texture) and the texCoord that
 * KHR_texture_transform substitutes. */
unsigned lk__gltf_sampled_texcoord_sets(const cJSON *item)
{
    unsigned sets = 0;
    const cJSON *child;
    cJSON_ArrayForEach(child, item)
    {
        if (!cJSON_IsObject(child) && !cJSON_IsArray(child)) continue;
        if (child->string && strcmp(child->string, "extras") == 0) continue;
        size_t length = child->string ? strlen(child->string) : 0;
        bool reference = length >= 7 && strcmp(child->string + length - 7, "Texture") == 0 &&
                         cJSON_IsNumber(cJSON_GetObjectItem(child, "index"));
        bool transform = child->string && strcmp(child->string, "KHR_texture_transform") == 0;
        if (reference || transform) {
            const cJSON *set = cJSON_GetObjectItem(child, "texCoord");
            if (cJSON_IsNumber(set) && set->valuedouble >= 0 && set->valuedouble < 32)
                sets |= 1u << (unsigned)set->valuedouble;
            else if (reference)
                sets |= 1u;
        }
        sets |= lk__gltf_sampled_texcoord_sets(child);
    }
    return sets;
}

/* Whether a material (its JSON) samples a normal map: normalTexture, or a
 * "...NormalTexture" of an extension (KHR_materials_clearcoat's). Such a
 * material needs tangents. */
bool lk__gltf_uses_normal_map(const cJSON *item)
{
    const cJSON *child;
    cJSON_ArrayForEach(child, item)
    {
        if (!cJSON_IsObject(child)) continue;
        if (child->string && strcmp(child->string, "extras") == 0) continue;
        size_t length = child->string ? strlen(child->string) : 0;
        if (length >= 13 &&
            (strcmp(child->string, "normalTexture") == 0 || strcmp(child->string + length - 13, "NormalTexture") == 0))
            return true;
        if (lk__gltf_uses_normal_map(child)) return true;
    }
    return false;
}

/* Per-vertex tangents for a normal-mapped primitive that has none: each
 * triangle's direction of increasing u (with v up, OpenGL's convention,
 * the one glTF's normal maps use), area-weighted at its corners, made
 * perpendicular to the normal; w says whether the direction of increasing
 * v is cross(normal, tangent) (+1) or its opposite (-1). Written into
 * `out` (4 floats per vertex). */
void lk__gltf_compute_tangents(const lk_mesh *mesh, const float *normals, float *out)
{
    size_t vertex_count = mesh->vertex_count;
    double *sum = lk__calloc_array(vertex_count ? 6 * vertex_count : 1, sizeof(double));
    for (size_t t = 0; sum && t < mesh->triangle_count; t++) {
        const uint32_t *v = mesh->indices + 3 * t;
        const float *p0 = mesh->positions + 3 * v[0], *p1 = mesh->positions + 3 * v[1],
                    *p2 = mesh->positions + 3 * v[2];
        const float *t0 = mesh->texcoords + 2 * v[0], *t1 = mesh->texcoords + 2 * v[1],
                    *t2 = mesh->texcoords + 2 * v[2];
        double e1[3], e2[3], du1 = t1[0] - t0[0], dv1 = t1[1] - t0[1], du2 = t2[0] - t0[0], dv2 = t2[1] - t0[1];
        for (int k = 0; k < 3; k++) e1[k] = p1[k] - p0[k], e2[k] = p2[k] - p0[k];
        double r = du1 * dv2 - du2 * dv1;
        if (r == 0.0 || !isfinite(r)) continue;
        double sign = r > 0 ? 1.0 : -1.0;
        /* (e1 dv2 - e2 dv1) / r scaled by |r|: weighs by the UV area */
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) {
                sum[6 * v[c] + (size_t)k] += sign * (e1[k] * dv2 - e2[k] * dv1);
                sum[6 * v[c] + 3 + (size_t)k] += sign * (e2[k] * du1 - e1[k] * du2);
            }
    }
    for (size_t i = 0; i < vertex_count; i++) {
        const float *n = normals + 3 * i;
        double tangent[3], bitangent[3], dot = 0.0;
        for (int k = 0; k < 3; k++) {
            tangent[k] = sum ? sum[6 * i + (size_t)k] : 0.0;
            bitangent[k] = sum ? sum[6 * i + 3 + (size_t)k] : 0.0;
            dot += tangent[k] * n[k];
        }
        for (int k = 0; k < 3; k++) tangent[k] -= dot * n[k];
        double length = sqrt(tangent[0] * tangent[0] + tangent[1] * tangent[1] + tangent[2] * tangent[2]);
        if (!(length > 1e-20)) {
            /* no UV gradient here: any direction perpendicular to the normal */
            double axis[3] = {fabs(n[0]) < 0.9 ? 1.0 : 0.0, fabs(n[0]) < 0.9 ? 0.0 : 1.0, 0.0};
            double d = axis[0] * n[0] + axis[1] * n[1];
            for (int k = 0; k < 3; k++) tangent[k] = axis[k] - d * n[k];
            length = sqrt(tangent[0] * tangent[0] + tangent[1] * tangent[1] + tangent[2] * tangent[2]);
        }
        double cross[3] = {n[1] * tangent[2] - n[2] * tangent[1], n[2] * tangent[0] - n[0] * tangent[2],
                           n[0] * tangent[1] - n[1] * tangent[0]};
        double handedness = cross[0] * bitangent[0] + cross[1] * bitangent[1] + cross[2] * bitangent[2];
        for (int k = 0; k < 3; k++) out[4 * i + (size_t)k] = (float)(tangent[k] / length);
        out[4 * i + 3] = handedness < 0 ? -1.0f : 1.0f;
    }
    free(sum);
}
