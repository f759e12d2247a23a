/* SPDX-License-Identifier: MIT */
/* glTF 2.0 reader: .gltf (JSON with external or data: URI buffers) and .glb
 * (binary container with an embedded BIN chunk).
 *
 * What is read: the triangles (modes TRIANGLES, TRIANGLE_STRIP and
 * TRIANGLE_FAN) and points of every mesh instanced by the default scene,
 * with the node transforms applied, concatenated into one mesh with the
 * attributes POSITION, NORMAL, TEXCOORD_0 and COLOR_0 (lk__gltf_load).
 * lk_mesh_read's entry, lk__read_gltf, is in io_gltf_anim.c: it then poses
 * skinned meshes by their joints at the nodes' own transforms (glTF
 * ignores their nodes' transforms; normals keep the node's). Lines,
 * materials, animations and morph targets are ignored. cJSON parses the
 * JSON; the GLB container, base64 and accessors are handled in
 * io_gltf_document.c, the scene graph here; the animation reader is
 * io_gltf_anim.c, the writers io_gltf_write.c and io_gltf_mesh_write.c.
 *
 * Every count and offset in the JSON is checked against the bytes really
 * available (64-bit arithmetic, JSON integers limited to 2^53 so nothing
 * overflows) before it is used, and errors name the JSON location, e.g.
 * "model.gltf: accessors[3]: count 12 exceeds bufferView 1 (96 bytes)". */
#include "io_gltf.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- transforms ----------------------------------------------------------- */

/* 4x4 matrices are column-major like glTF's: m[column * 4 + row]. */
/* The node's local transform: `matrix`, or translation * rotation * scale. */
lk_status lk__gltf_node_local_matrix(const gltf_reader *reader, const cJSON *node, const char *where, double m[16])
{
    bool present;
    lk_status status = lk__gltf_get_number_array(reader, node, where, "matrix", 16, m, &present);
    if (status != LK_OK || present) return status;
    double translation[3] = {0, 0, 0}, rotation[4] = {0, 0, 0, 1}, scale[3] = {1, 1, 1};
    if ((status = lk__gltf_get_number_array(reader, node, where, "translation", 3, translation, NULL)) != LK_OK)
        return status;
    if ((status = lk__gltf_get_number_array(reader, node, where, "rotation", 4, rotation, NULL)) != LK_OK)
        return status;
    if ((status = lk__gltf_get_number_array(reader, node, where, "scale", 3, scale, NULL)) != LK_OK) return status;
    double length = sqrt(rotation[0] * rotation[0] + rotation[1] * rotation[1] + rotation[2] * rotation[2] +
                         rotation[3] * rotation[3]);
    if (!(length > 0.0) || !isfinite(length))
        return lk__gltf_fail(reader, LK_ERR_RANGE, where, "rotation", "is not a valid quaternion (length %g)", length);
    double x = rotation[0] / length, y = rotation[1] / length, z = rotation[2] / length, w = rotation[3] / length;
    double r[9] = {
        /* column 0 */ 1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
        /* column 1 */ 2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
        /* column 2 */ 2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    for (int column = 0; column < 3; column++) {
        for (int row = 0; row < 3; row++) m[column * 4 + row] = r[column * 3 + row] * scale[column];
        m[column * 4 + 3] = 0.0;
    }
    m[12] = translation[0];
    m[13] = translation[1];
    m[14] = translation[2];
    m[15] = 1.0;
    return LK_OK;
}

/* What a primitive needs from its node's world matrix. */
typedef struct vertex_transform {
    double matrix[16];
    double normal[9]; /* column-major 3x3: inverse-transpose up to a positive scale */
    bool mirror;      /* negative determinant: triangle winding must be reversed */
    size_t node;      /* for messages; SIZE_MAX when the mesh is not in a node */
} vertex_transform;

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static void make_vertex_transform(const double matrix[16], size_t node, vertex_transform *out)
{
    memcpy(out->matrix, matrix, sizeof out->matrix);
    out->node = node;
    const double *c0 = matrix, *c1 = matrix + 4, *c2 = matrix + 8;
    /* The cofactor matrix (columns c1xc2, c2xc0, c0xc1) is det * M^-T; it
     * exists even for singular matrices, and normals are renormalised, so
     * only the sign of the determinant matters. */
    cross(c1, c2, out->normal);
    cross(c2, c0, out->normal + 3);
    cross(c0, c1, out->normal + 6);
    double determinant = c0[0] * out->normal[0] + c0[1] * out->normal[1] + c0[2] * out->normal[2];
    out->mirror = determinant < 0.0;
    if (out->mirror)
        for (int i = 0; i < 9; i++) out->normal[i] = -out->normal[i];
}

/* ---- output arrays ---------------------------------------------------------- */

/* Grows `buffer` by `count` floats (or uint32s), charged to the budget,
 * and returns the new area; NULL with *status set on failure. */
static void *extend(const gltf_reader *reader, lk__buffer *buffer, size_t count, lk_status *status)
{
    /* At least one element, so that the area is never a NULL pointer. */
    lk__budget *budget = reader->ctx->budget;
    *status =
        count > SIZE_MAX / 4 - 1 ? LK_ERR_LIMIT : lk__buffer_reserve_charged(buffer, (count ? count : 1) * 4, budget);
    if (*status != LK_OK) {
        *status = *status == LK_ERR_LIMIT ? lk__gltf_over_budget(reader) : lk__gltf_nomem(reader);
        return NULL;
    }
    void *area = buffer->data + buffer->size;
    buffer->size += count * 4;
    return area;
}

static lk_status fill_floats(const gltf_reader *reader, lk__buffer *buffer, size_t count, float value)
{
    lk_status status;
    float *area = extend(reader, buffer, count, &status);
    if (!area) return status;
    for (size_t i = 0; i < count; i++) area[i] = value;
    return LK_OK;
}

/* ---- primitives ------------------------------------------------------------- */


lk_status lk__gltf_open_attributes(gltf_reader *reader, const cJSON *primitive, const char *where,
                                   primitive_attributes *attributes)
{
    const cJSON *map;
    char map_where[128];
    memset(attributes, 0, sizeof *attributes);
    snprintf(map_where, sizeof map_where, "%s.attributes", where);
    lk_status status = lk__gltf_get_object(reader, primitive, where, "attributes", &map);
    if (status != LK_OK) return status;
    if (!map) return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"attributes\"");
    uint64_t index;
    if ((status = lk__gltf_get_uint(reader, map, map_where, "POSITION", false, UINT64_MAX, &index)) != LK_OK)
        return status;
    if (index == UINT64_MAX) return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "has no POSITION attribute");
    status =
        lk__gltf_open_accessor(reader, index, map_where, "POSITION", TYPE_VEC3, false, "a VEC3", &attributes->position);
    if (status != LK_OK) return status;
    size_t vertex_count = attributes->position.count;

    static const struct {
        const char *name;
        unsigned type_mask;
        const char *expected;
    } optional[3] = {{"NORMAL", TYPE_VEC3, "a VEC3"},
                     {"TEXCOORD_0", TYPE_VEC2, "a VEC2"},
                     {"COLOR_0", TYPE_VEC3 | TYPE_VEC4, "a VEC3 or VEC4"}};
    gltf_accessor *targets[3] = {&attributes->normal, &attributes->texcoord, &attributes->color};
    bool *present[3] = {&attributes->has_normal, &attributes->has_texcoord, &attributes->has_color};
    for (int i = 0; i < 3; i++) {
        if ((status = lk__gltf_get_uint(reader, map, map_where, optional[i].name, false, UINT64_MAX, &index)) != LK_OK)
            return status;
        if (index == UINT64_MAX) continue;
        status = lk__gltf_open_accessor(reader, index, map_where, optional[i].name, optional[i].type_mask, false,
                                        optional[i].expected, targets[i]);
        if (status != LK_OK) return status;
        if (targets[i]->count != vertex_count)
            return lk__gltf_fail(reader, LK_ERR_RANGE, map_where, optional[i].name,
                                 "accessor %llu has %zu elements but POSITION has %zu", (unsigned long long)index,
                                 targets[i]->count, vertex_count);
        *present[i] = true;
    }
    return LK_OK;
}

static lk_status check_budget(const gltf_reader *reader, const char *where, size_t vertex_count, size_t triangle_count,
                              const primitive_attributes *attributes)
{
    uint64_t vertices = (uint64_t)reader->vertex_count + vertex_count;
    uint64_t triangles = (uint64_t)reader->triangle_count + triangle_count;
    if (vertices > LK_MAX_ELEMENTS || triangles > LK_MAX_ELEMENTS)
        return lk__gltf_fail(reader, LK_ERR_LIMIT, where, NULL,
                             "the scene reaches %llu vertices and %llu triangles, more than lodkit supports (%zu)",
                             (unsigned long long)vertices, (unsigned long long)triangles, (size_t)LK_MAX_ELEMENTS);
    /* What the output arrays grow by: this primitive's vertices and
     * triangles, and an attribute it brings for the earlier vertices. */
    uint64_t bytes_per_vertex = 12, earlier_bytes_per_vertex = 0;
    if (reader->has_normals || attributes->has_normal) bytes_per_vertex += 12;
    if (reader->has_texcoords || attributes->has_texcoord) bytes_per_vertex += 8;
    if (reader->has_colors || attributes->has_color) bytes_per_vertex += 16;
    if (!reader->has_normals && attributes->has_normal) earlier_bytes_per_vertex += 12;
    if (!reader->has_texcoords && attributes->has_texcoord) earlier_bytes_per_vertex += 8;
    if (!reader->has_colors && attributes->has_color) earlier_bytes_per_vertex += 16;
    uint64_t bytes = (uint64_t)vertex_count * bytes_per_vertex +
                     (uint64_t)reader->vertex_count * earlier_bytes_per_vertex + (uint64_t)triangle_count * 12;
    if (bytes > lk__budget_room(reader->ctx->budget))
        return lk__gltf_fail(
            reader, LK_ERR_LIMIT, where, NULL,
            "the scene reaches %llu vertices and %llu triangles, more than the memory budget of %zu bytes",
            (unsigned long long)vertices, (unsigned long long)triangles, reader->ctx->budget->limit);
    return LK_OK;
}

/* Checks a decoded attribute value; `what` names the attribute. */
static lk_status check_finite(const gltf_reader *reader, const char *where, const char *what,
                              const gltf_accessor *accessor, size_t element, const float *values, unsigned count,
                              const char *after)
{
    for (unsigned c = 0; c < count; c++)
        if (!isfinite(values[c]))
            return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                                 "%s of vertex %zu (accessors[%zu]) is not finite (%g)%s", what, element,
                                 accessor->index, (double)values[c], after);
    return LK_OK;
}

static lk_status append_vertices(gltf_reader *reader, const char *where, const primitive_attributes *attributes,
                                 const vertex_transform *transform)
{
    size_t vertex_count = attributes->position.count;
    const double *m = transform->matrix, *n = transform->normal;
    lk_status grown;
    float *positions = extend(reader, &reader->positions, 3 * vertex_count, &grown);
    if (!positions) return grown;
    char after[64] = " after the node transform";
    if (transform->node != SIZE_MAX)
        snprintf(after, sizeof after, " after the transform of nodes[%zu]", transform->node);
    for (size_t i = 0; i < vertex_count; i++) {
        float p[3];
        lk__gltf_accessor_floats(&attributes->position, i, p);
        lk_status status = check_finite(reader, where, "POSITION", &attributes->position, i, p, 3, "");
        if (status != LK_OK) return status;
        for (int row = 0; row < 3; row++)
            positions[3 * i + row] = (float)(m[row] * p[0] + m[4 + row] * p[1] + m[8 + row] * p[2] + m[12 + row]);
        status = check_finite(reader, where, "POSITION", &attributes->position, i, positions + 3 * i, 3, after);
        if (status != LK_OK) return status;
    }

    /* Attributes that only some primitives have: earlier vertices get
     * zero normals/texcoords and white colours, and so do later ones. */
    if (attributes->has_normal && !reader->has_normals) {
        if ((grown = fill_floats(reader, &reader->normals, 3 * reader->vertex_count, 0.0f)) != LK_OK) return grown;
        reader->has_normals = true;
    }
    if (reader->has_normals) {
        float *normals = extend(reader, &reader->normals, 3 * vertex_count, &grown);
        if (!normals) return grown;
        for (size_t i = 0; i < vertex_count; i++) {
            float v[3] = {0, 0, 0};
            if (attributes->has_normal) {
                lk__gltf_accessor_floats(&attributes->normal, i, v);
                lk_status status = check_finite(reader, where, "NORMAL", &attributes->normal, i, v, 3, "");
                if (status != LK_OK) return status;
            }
            double t[3], length = 0.0;
            for (int row = 0; row < 3; row++) {
                t[row] = n[row] * v[0] + n[3 + row] * v[1] + n[6 + row] * v[2];
                length += t[row] * t[row];
            }
            length = sqrt(length);
            /* Zero-length normals stay zero rather than becoming NaN. */
            for (int row = 0; row < 3; row++)
                normals[3 * i + row] = length > 0.0 && isfinite(length) ? (float)(t[row] / length) : 0.0f;
        }
    }

    if (attributes->has_texcoord && !reader->has_texcoords) {
        if ((grown = fill_floats(reader, &reader->texcoords, 2 * reader->vertex_count, 0.0f)) != LK_OK) return grown;
        reader->has_texcoords = true;
    }
    if (reader->has_texcoords) {
        float *texcoords = extend(reader, &reader->texcoords, 2 * vertex_count, &grown);
        if (!texcoords) return grown;
        for (size_t i = 0; i < vertex_count; i++) {
            float uv[2] = {0, 0};
            if (attributes->has_texcoord) {
                lk__gltf_accessor_floats(&attributes->texcoord, i, uv);
                lk_status status = check_finite(reader, where, "TEXCOORD_0", &attributes->texcoord, i, uv, 2, "");
                if (status != LK_OK) return status;
                /* glTF's v axis points down the image; lodkit (like OBJ and
                 * PLY) uses v up. */
                uv[1] = 1.0f - uv[1];
            }
            texcoords[2 * i] = uv[0];
            texcoords[2 * i + 1] = uv[1];
        }
    }

    if (attributes->has_color && !reader->has_colors) {
        if ((grown = fill_floats(reader, &reader->colors, 4 * reader->vertex_count, 1.0f)) != LK_OK) return grown;
        reader->has_colors = true;
    }
    if (reader->has_colors) {
        float *colors = extend(reader, &reader->colors, 4 * vertex_count, &grown);
        if (!colors) return grown;
        for (size_t i = 0; i < vertex_count; i++) {
            float rgba[4] = {1, 1, 1, 1};
            if (attributes->has_color) {
                lk__gltf_accessor_floats(&attributes->color, i, rgba);
                lk_status status = check_finite(reader, where, "COLOR_0", &attributes->color, i, rgba,
                                                attributes->color.component_count, "");
                if (status != LK_OK) return status;
                if (attributes->color.component_count == 3) rgba[3] = 1.0f;
            }
            for (int c = 0; c < 4; c++) colors[4 * i + c] = fminf(fmaxf(rgba[c], 0.0f), 1.0f);
        }
    }
    return LK_OK;
}

/* Appends the triangles of one primitive; `indices` is NULL for
 * non-indexed primitives (vertex i is element i). */
static lk_status append_triangles(gltf_reader *reader, const char *where, int mode, const gltf_accessor *indices,
                                  size_t vertex_count, size_t base, bool mirror)
{
    size_t corner_count = indices ? indices->count : vertex_count;
    size_t triangle_limit = mode == MODE_TRIANGLES ? corner_count / 3 : (corner_count >= 3 ? corner_count - 2 : 0);
    if (mode == MODE_TRIANGLES && corner_count % 3 != 0)
        return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                             "%zu %s do not form whole triangles (mode TRIANGLES needs a multiple of 3)", corner_count,
                             indices ? "indices" : "vertices");
    lk_status grown;
    uint32_t *out = extend(reader, &reader->indices, 3 * triangle_limit, &grown);
    if (!out) return grown;
    size_t written = 0;
    for (size_t t = 0; t < triangle_limit; t++) {
        size_t corners[3];
        if (mode == MODE_TRIANGLES) {
            corners[0] = 3 * t, corners[1] = 3 * t + 1, corners[2] = 3 * t + 2;
        } else if (mode == MODE_TRIANGLE_STRIP) {
            /* Every other strip triangle is reversed to keep one winding. */
            corners[0] = t, corners[1] = t + 1 + t % 2, corners[2] = t + 2 - t % 2;
        } else {
            corners[0] = t + 1, corners[1] = t + 2, corners[2] = 0;
        }
        uint32_t v[3];
        for (int k = 0; k < 3; k++) {
            v[k] = indices ? lk__gltf_accessor_index(indices, corners[k]) : (uint32_t)corners[k];
            if (v[k] >= vertex_count) {
                return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                                     "index %u out of range (%zu vertices) at element %zu of accessors[%zu]", v[k],
                                     vertex_count, corners[k], indices ? indices->index : 0);
            }
        }
        /* Strips and fans repeat vertices to stitch pieces together; those
         * zero-area triangles are encoding artefacts, not geometry. */
        if (mode != MODE_TRIANGLES && (v[0] == v[1] || v[1] == v[2] || v[0] == v[2])) continue;
        if (mirror) {
            uint32_t swap = v[1];
            v[1] = v[2];
            v[2] = swap;
        }
        for (int k = 0; k < 3; k++) out[3 * written + k] = (uint32_t)(base + v[k]);
        written++;
    }
    reader->indices.size -= 3 * (triangle_limit - written) * 4;
    reader->triangle_count += written;
    return LK_OK;
}

/* Appends the segments of a LINES, LINE_STRIP or LINE_LOOP primitive to
 * reader->lines, as indices into its own vertices (the scene reader reads
 * one primitive at a time). */
static lk_status append_lines(gltf_reader *reader, const char *where, int mode, const gltf_accessor *indices,
                              size_t vertex_count)
{
    size_t corner_count = indices ? indices->count : vertex_count;
    if (mode == MODE_LINES && corner_count % 2 != 0)
        return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                             "%zu %s do not form whole segments (mode LINES needs a multiple of 2)", corner_count,
                             indices ? "indices" : "vertices");
    size_t segment_count = mode == MODE_LINES ? corner_count / 2
                           : corner_count < 2 ? 0
                                              : corner_count - (mode == MODE_LINE_STRIP);
    lk_status grown;
    uint32_t *out = extend(reader, &reader->lines, 2 * segment_count, &grown);
    if (!out) return grown;
    for (size_t s = 0; s < segment_count; s++)
        for (size_t k = 0; k < 2; k++) {
            size_t corner = mode == MODE_LINES ? 2 * s + k : (s + k) % corner_count;
            uint32_t v = indices ? lk__gltf_accessor_index(indices, corner) : (uint32_t)corner;
            if (v >= vertex_count)
                return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                                     "index %u out of range (%zu vertices) at element %zu of accessors[%zu]", v,
                                     vertex_count, corner, indices ? indices->index : 0);
            out[2 * s + k] = v;
        }
    reader->line_count += segment_count;
    return LK_OK;
}

static lk_status read_primitive(gltf_reader *reader, const cJSON *primitive, const char *where,
                                const vertex_transform *transform)
{
    if (!cJSON_IsObject(primitive))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "expected an object, got %s",
                             lk__gltf_json_type_name(primitive));
    uint64_t mode;
    lk_status status = lk__gltf_get_uint(reader, primitive, where, "mode", false, MODE_TRIANGLES, &mode);
    if (status != LK_OK) return status;
    if (mode > MODE_TRIANGLE_FAN)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "mode", "%llu is not a glTF primitive mode (0..6)",
                             (unsigned long long)mode);
    const cJSON *extensions = lk__gltf_member(primitive, "extensions");
    const cJSON *draco = extensions ? lk__gltf_member(extensions, "KHR_draco_mesh_compression") : NULL;
    bool lines = mode == MODE_LINES || mode == MODE_LINE_LOOP || mode == MODE_LINE_STRIP;
    if (lines && !reader->keep_lines) {
        reader->skipped_line_primitives++;
        return LK_OK;
    }

    primitive_attributes attributes;
    status = lk__gltf_open_attributes(reader, primitive, where, &attributes);
    if (status != LK_OK) return status;
    /* A Draco primitive may carry uncompressed fallback data; without it
     * the accessors have no bufferView. */
    if (draco && !attributes.position.data)
        return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, NULL,
                             "Draco-compressed geometry (KHR_draco_mesh_compression) is not supported (Debian's "
                             "libdraco has no C interface): decompress the file with a Draco-aware glTF tool, or "
                             "export it with EXT_meshopt_compression, which lodkit reads");
    size_t vertex_count = attributes.position.count;

    gltf_accessor indices;
    bool indexed = false;
    uint64_t indices_index;
    if ((status = lk__gltf_get_uint(reader, primitive, where, "indices", false, UINT64_MAX, &indices_index)) != LK_OK)
        return status;
    if (indices_index != UINT64_MAX) {
        status =
            lk__gltf_open_accessor(reader, indices_index, where, "indices", TYPE_SCALAR, true, "a SCALAR", &indices);
        if (status != LK_OK) return status;
        indexed = true;
    }
    size_t corner_count = indexed ? indices.count : vertex_count;
    size_t triangle_count = 0;
    if (mode == MODE_TRIANGLES)
        triangle_count = corner_count / 3;
    else if (mode != MODE_POINTS && !lines && corner_count >= 3)
        triangle_count = corner_count - 2;

    status = check_budget(reader, where, vertex_count, triangle_count, &attributes);
    if (status != LK_OK) return status;
    size_t base = reader->vertex_count;
    status = append_vertices(reader, where, &attributes, transform);
    if (status != LK_OK) return status;
    reader->vertex_count += vertex_count;
    if (reader->record_instances) {
        gltf_instance instance = {primitive, reader->current_mesh, transform->node, base, vertex_count};
        status = lk__buffer_append_charged(&reader->instances, &instance, sizeof instance, reader->ctx->budget);
        if (status != LK_OK) return status == LK_ERR_LIMIT ? lk__gltf_over_budget(reader) : lk__gltf_nomem(reader);
    }
    if (mode == MODE_POINTS) {
        /* Points: the vertices are the data; indices only select which are
         * drawn, so just check them. */
        for (size_t i = 0; indexed && i < indices.count; i++) {
            uint32_t v = lk__gltf_accessor_index(&indices, i);
            if (v >= vertex_count)
                return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                                     "index %u out of range (%zu vertices) at element %zu of accessors[%zu]", v,
                                     vertex_count, i, indices.index);
        }
        return LK_OK;
    }
    if (lines) return append_lines(reader, where, (int)mode, indexed ? &indices : NULL, vertex_count);
    return append_triangles(reader, where, (int)mode, indexed ? &indices : NULL, vertex_count, base, transform->mirror);
}

lk_status lk__gltf_read_local_primitive(gltf_reader *reader, const cJSON *primitive, const char *where)
{
    vertex_transform identity;
    double matrix[16];
    lk__mat4_identity(matrix);
    make_vertex_transform(matrix, SIZE_MAX, &identity);
    return read_primitive(reader, primitive, where, &identity);
}

static lk_status read_mesh(gltf_reader *reader, uint64_t mesh_index, const char *referrer,
                           const vertex_transform *transform)
{
    const cJSON *mesh = NULL, *primitives = NULL;
    lk_status status = lk__gltf_resolve(reader, &reader->meshes, "mesh", "meshes", mesh_index, referrer, "mesh", &mesh);
    if (status != LK_OK) return status;
    char where[48];
    snprintf(where, sizeof where, "meshes[%llu]", (unsigned long long)mesh_index);
    if ((status = lk__gltf_get_array(reader, mesh, where, "primitives", &primitives)) != LK_OK) return status;
    if (!primitives) return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"primitives\"");
    reader->current_mesh = (size_t)mesh_index;
    size_t index = 0;
    const cJSON *primitive;
    cJSON_ArrayForEach(primitive, primitives)
    {
        char primitive_where[96];
        snprintf(primitive_where, sizeof primitive_where, "%s.primitives[%zu]", where, index++);
        status = read_primitive(reader, primitive, primitive_where, transform);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

/* ---- scene graph ------------------------------------------------------------- */

typedef struct walk_entry {
    size_t node;
    double parent_matrix[16];
} walk_entry;

/* Reads the node trees below `roots` (indices into nodes) depth-first with
 * an explicit stack, so deep hierarchies cannot overflow the C stack. A
 * node reached twice (a cycle, or a node with two parents) is an error:
 * glTF requires disjoint trees, and instancing a subtree repeatedly could
 * blow up exponentially. */
static lk_status walk_nodes(gltf_reader *reader, const size_t *roots, size_t root_count, const char *roots_where,
                            unsigned char *visited)
{
    lk_status status = LK_OK;
    walk_entry *stack = lk__gltf_charged_calloc(reader, reader->nodes.count, sizeof *stack, &status);
    if (!stack) return status;
    for (size_t r = 0; r < root_count && status == LK_OK; r++) {
        size_t root = roots[r];
        if (visited[root]) {
            status =
                lk__gltf_fail(reader, LK_ERR_PARSE, roots_where, NULL,
                              "node %zu is reached twice (listed twice, or also a descendant of another root)", root);
            break;
        }
        visited[root] = 1;
        size_t depth = 0;
        stack[depth].node = root;
        lk__mat4_identity(stack[depth].parent_matrix);
        depth++;
        while (depth > 0 && status == LK_OK) {
            walk_entry entry = stack[--depth];
            const cJSON *node = reader->nodes.items[entry.node];
            char where[48];
            snprintf(where, sizeof where, "nodes[%zu]", entry.node);
            double local[16], world[16];
            status = lk__gltf_node_local_matrix(reader, node, where, local);
            if (status != LK_OK) break;
            lk__mat4_multiply(entry.parent_matrix, local, world);

            uint64_t mesh_index;
            status = lk__gltf_get_uint(reader, node, where, "mesh", false, UINT64_MAX, &mesh_index);
            if (status != LK_OK) break;
            if (mesh_index != UINT64_MAX) {
                vertex_transform transform;
                make_vertex_transform(world, entry.node, &transform);
                status = read_mesh(reader, mesh_index, where, &transform);
                if (status != LK_OK) break;
            }

            const cJSON *children, *child;
            status = lk__gltf_get_array(reader, node, where, "children", &children);
            if (status != LK_OK || !children) continue;
            /* First pass: validate and mark. Every node is marked once, so
             * the stack never needs more than nodes.count entries. */
            size_t child_count = 0;
            cJSON_ArrayForEach(child, children)
            {
                char child_key[48];
                snprintf(child_key, sizeof child_key, "children[%zu]", child_count);
                status = lk__gltf_check_uint(reader, child, where, child_key);
                if (status != LK_OK) break;
                if (child->valuedouble >= (double)reader->nodes.count) {
                    status =
                        lk__gltf_fail(reader, LK_ERR_RANGE, where, child_key, "node %.0f out of range (%zu node%s)",
                                      child->valuedouble, reader->nodes.count, reader->nodes.count == 1 ? "" : "s");
                    break;
                }
                size_t child_node = (size_t)child->valuedouble;
                if (visited[child_node]) {
                    status =
                        lk__gltf_fail(reader, LK_ERR_PARSE, where, child_key,
                                      "node %zu is reached twice (the node hierarchy has a cycle or a node with two "
                                      "parents)",
                                      child_node);
                    break;
                }
                visited[child_node] = 1;
                child_count++;
            }
            if (status != LK_OK) break;
            /* Second pass: push in reverse so children are read in order. */
            size_t position = depth + child_count;
            cJSON_ArrayForEach(child, children)
            {
                position--;
                stack[position].node = (size_t)child->valuedouble;
                memcpy(stack[position].parent_matrix, world, sizeof world);
            }
            depth += child_count;
        }
    }
    lk__gltf_charged_free(reader, stack, reader->nodes.count, sizeof *stack);
    return status;
}

static lk_status read_scene(gltf_reader *reader)
{
    lk_status status = LK_OK;
    size_t node_count = reader->nodes.count;
    unsigned char *visited = lk__gltf_charged_calloc(reader, node_count, 1, &status);
    size_t *roots = visited ? lk__gltf_charged_calloc(reader, node_count, sizeof *roots, &status) : NULL;
    size_t root_count = 0;
    char roots_where[64] = "nodes";
    if (!visited || !roots) goto done;
    uint64_t scene_index;
    if ((status = lk__gltf_get_uint(reader, reader->root, "", "scene", false, UINT64_MAX, &scene_index)) != LK_OK)
        goto done;
    if (scene_index != UINT64_MAX && scene_index >= reader->scenes.count) {
        status =
            lk__gltf_fail(reader, LK_ERR_RANGE, "", "scene", "scene %llu out of range (%zu scene%s)",
                          (unsigned long long)scene_index, reader->scenes.count, reader->scenes.count == 1 ? "" : "s");
        goto done;
    }
    if (reader->scenes.count > 0) {
        if (scene_index == UINT64_MAX) scene_index = 0;
        const cJSON *scene = reader->scenes.items[scene_index], *list, *item;
        char scene_where[48];
        snprintf(scene_where, sizeof scene_where, "scenes[%llu]", (unsigned long long)scene_index);
        snprintf(roots_where, sizeof roots_where, "%s.nodes", scene_where);
        if ((status = lk__gltf_get_array(reader, scene, scene_where, "nodes", &list)) != LK_OK) goto done;
        cJSON_ArrayForEach(item, list)
        {
            char key[32];
            snprintf(key, sizeof key, "[%zu]", root_count);
            if ((status = lk__gltf_check_uint(reader, item, roots_where, key)) != LK_OK) goto done;
            if (item->valuedouble >= (double)node_count) {
                status = lk__gltf_fail(reader, LK_ERR_RANGE, roots_where, key, "node %.0f out of range (%zu node%s)",
                                       item->valuedouble, node_count, node_count == 1 ? "" : "s");
                goto done;
            }
            if (root_count == node_count) {
                status = lk__gltf_fail(reader, LK_ERR_PARSE, roots_where, NULL,
                                       "lists more nodes than the %zu that exist, so some twice", node_count);
                goto done;
            }
            roots[root_count++] = (size_t)item->valuedouble;
        }
    } else if (node_count > 0) {
        /* No scene: every node that is nobody's child is a root. */
        unsigned char *has_parent = visited; /* borrowed, cleared below */
        for (size_t i = 0; i < node_count; i++) {
            const cJSON *children = lk__gltf_member(reader->nodes.items[i], "children"), *child;
            if (!cJSON_IsArray(children)) continue;
            cJSON_ArrayForEach(child, children)
            {
                if (lk__gltf_is_json_uint(child) && child->valuedouble < (double)node_count)
                    has_parent[(size_t)child->valuedouble] = 1;
            }
        }
        for (size_t i = 0; i < node_count; i++)
            if (!has_parent[i]) roots[root_count++] = i;
        memset(visited, 0, node_count);
        if (root_count == 0) {
            status = lk__gltf_fail(reader, LK_ERR_PARSE, "", "nodes",
                                   "every node has a parent (the node hierarchy has a cycle)");
            goto done;
        }
    } else {
        /* Neither scenes nor nodes: take every mesh as it is. */
        vertex_transform identity;
        double matrix[16];
        lk__mat4_identity(matrix);
        make_vertex_transform(matrix, SIZE_MAX, &identity);
        for (size_t i = 0; i < reader->meshes.count && status == LK_OK; i++)
            status = read_mesh(reader, i, "meshes", &identity);
        goto done;
    }
    status = walk_nodes(reader, roots, root_count, roots_where, visited);
done:
    lk__gltf_charged_free(reader, visited, node_count, 1);
    lk__gltf_charged_free(reader, roots, node_count, sizeof *roots);
    return status;
}

/* Parses the container and the JSON, checks the document and reads the
 * default scene into the reader's output arrays. */
lk_status lk__gltf_open_document(gltf_reader *reader, const char *data, size_t size, cJSON **root)
{
    const char *json = data;
    size_t json_length = size, json_offset = 0;
    lk_status status = LK_OK;
    *root = NULL;
    if (size >= 4 && memcmp(data, "glTF", 4) == 0) {
        reader->is_glb = true;
        status = lk__gltf_parse_glb(reader, (const unsigned char *)data, size, &json, &json_length);
        json_offset = (size_t)(json - data);
    }
    if (status == LK_OK) status = lk__gltf_parse_json(reader, json, json_length, json_offset, root);
    reader->root = *root;
    if (status == LK_OK) status = lk__gltf_check_document(reader);
    if (status == LK_OK)
        reader->buffers = lk__gltf_charged_calloc(reader, reader->buffers_json.count, sizeof *reader->buffers, &status);
    return status;
}

lk_status lk__gltf_load(gltf_reader *reader, const char *data, size_t size, cJSON **root)
{
    lk_status status = lk__gltf_open_document(reader, data, size, root);
    if (status == LK_OK) status = read_scene(reader);
    if (status == LK_OK && reader->vertex_count == 0) {
        if (reader->skipped_line_primitives)
            status = lk_error_set(reader->error, LK_ERR_UNSUPPORTED,
                                  "%s: the scene holds only lines (%zu primitive%s), no mesh or points: lodkit keeps "
                                  "lines in glTF scenes only (convert or simplify it to .glb or .gltf)",
                                  reader->ctx->name, reader->skipped_line_primitives,
                                  reader->skipped_line_primitives == 1 ? "" : "s");
        else
            status =
                lk_error_set(reader->error, LK_ERR_PARSE, "%s: the scene contains no mesh geometry", reader->ctx->name);
    }
    return status;
}

/* Moves the output arrays into `mesh`. */
lk_status lk__gltf_take_mesh(gltf_reader *reader, lk_mesh *mesh)
{
    mesh->vertex_count = reader->vertex_count;
    mesh->triangle_count = reader->triangle_count;
    /* The arrays stay charged: the mesh holds them. */
    lk__budget *budget = reader->ctx->budget;
    mesh->positions = lk__buffer_take_charged(&reader->positions, budget);
    mesh->normals = reader->has_normals ? lk__buffer_take_charged(&reader->normals, budget) : NULL;
    mesh->texcoords = reader->has_texcoords ? lk__buffer_take_charged(&reader->texcoords, budget) : NULL;
    mesh->colors = reader->has_colors ? lk__buffer_take_charged(&reader->colors, budget) : NULL;
    mesh->indices = reader->triangle_count ? lk__buffer_take_charged(&reader->indices, budget) : NULL;
    /* Point sets: keep a valid (1-byte) index array like lk_mesh_alloc. */
    if (!mesh->indices) mesh->indices = lk__malloc_array(0, sizeof(uint32_t));
    /* Ready for the next primitive (scenes read one at a time). */
    reader->vertex_count = reader->triangle_count = 0;
    reader->has_normals = reader->has_texcoords = reader->has_colors = false;
    if (!mesh->indices) {
        lk_mesh_free(mesh);
        return lk__gltf_nomem(reader);
    }
    return LK_OK;
}

void lk__gltf_release(gltf_reader *reader, cJSON *root)
{
    lk__budget *budget = reader->ctx->budget;
    for (size_t i = 0; reader->buffers && i < reader->buffers_json.count; i++) free(reader->buffers[i].owned);
    for (size_t i = 0; reader->decoded_views && i < reader->buffer_views.count; i++)
        free(reader->decoded_views[i].owned);
    lk__gltf_charged_free(reader, reader->decoded_views, reader->decoded_views ? reader->buffer_views.count : 0,
                          sizeof *reader->decoded_views);
    lk__budget_release(budget, reader->buffer_bytes, 1);
    lk__gltf_charged_free(reader, reader->buffers, reader->buffers_json.count, sizeof *reader->buffers);
    lk__buffer *arrays[] = {&reader->positions, &reader->normals,   &reader->texcoords, &reader->colors,
                            &reader->indices,   &reader->instances, &reader->lines};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; i++) lk__buffer_free_charged(arrays[i], budget);
    json_table *tables[] = {&reader->accessors, &reader->buffer_views, &reader->buffers_json,
                            &reader->meshes,    &reader->nodes,        &reader->scenes};
    for (size_t i = 0; i < sizeof tables / sizeof tables[0]; i++) lk__gltf_table_free(reader, tables[i]);
    cJSON_Delete(root);
    lk__budget_release(budget, reader->json_bytes, 1);
}
