/* SPDX-License-Identifier: MIT */
/* glTF 2.0 writer for one mesh or point set (lk_mesh_write): `.glb`, or
 * `.gltf` with its buffer in NAME.bin next to it.
 *
 * One scene, one node, one mesh of one primitive: POSITION (with the bounds
 * the specification requires), NORMAL, TEXCOORD_0, COLOR_0 and indices as
 * the mesh has them; triangles (mode 4) or, for a point set, points (mode
 * 0). The choices the Khronos validator checks:
 *   - normals are unit length: each is normalised on the way out, and one
 *     that cannot be (zero, NaN) is replaced by the area-weighted normal of
 *     its triangles (or +z for a lone point);
 *   - texture coordinates: lodkit's v points up, glTF's down (v -> 1 - v);
 *   - colours in [0, 1]: clamped; stored as normalised unsigned bytes when
 *     every component is a multiple of 1/255 (PLY's colours: a quarter of
 *     the bytes, the same values), otherwise as floats;
 *   - indices: the smallest unsigned type that holds the vertex count;
 *   - every bufferView starts on a 4-byte boundary and says its target
 *     (ARRAY_BUFFER for attributes, ELEMENT_ARRAY_BUFFER for indices).
 * An empty mesh gives a valid file with an empty scene. Splat radii have no
 * glTF attribute and are not written.
 *
 * Compact output (lk_write_options.gltf_flags; docs/formats.md):
 *   - LK_GLTF_QUANTIZE (KHR_mesh_quantization): positions as 14-bit
 *     integers on a uniform grid with the whole scene's step (grids_of_scene),
 *     the node's scale and translation mapping them back; normals and
 *     tangents as 8-bit normalised bytes; texture coordinates in [0, 1] on
 *     a 12-bit grid as normalised shorts (others stay floats); colours as
 *     bytes;
 *   - LK_GLTF_MESHOPT (EXT_meshopt_compression): every bufferView encoded
 *     with meshoptimizer's vertex and index codecs (Debian's
 *     libmeshoptimizer), normals and tangents through its octahedral
 *     filter; the uncompressed views live in a fallback buffer without
 *     data, so the extension is required;
 *   - with either: attributes no material samples dropped; equal
 *     primitives share accessors, a kind of accessor a bufferView
 *     (group_views); with LK_GLTF_MESHOPT equal vertices merged, empty
 *     triangles dropped, strip order (src/io_gltf_primitive.c).
 * Skins (JOINTS_0 / WEIGHTS_0, inverse bind matrices) and node animations
 * (add_skins, add_animations): their matrices and key times go in views
 * without target and byteStride; a skinned mesh under a parent moves to a
 * root node (src/io_gltf_hoist.c). */
#include "bytes.h"
#include "io_gltf.h"

#include <meshoptimizer.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define GLB_MAGIC 0x46546C67u /* "glTF" */
#define GLB_CHUNK_JSON 0x4E4F534Au
#define GLB_CHUNK_BIN 0x004E4942u


static size_t add_floats(mesh_writer *writer, const float *values, size_t count, unsigned components, const char *type,
                         bool with_bounds)
{
    return lk__gltf_add_float_data(writer, values, count, components, type, with_bounds, GLTF_TARGET_ARRAY_BUFFER);
}


/* Unit normals (lk__gltf_unit_normals) in a new array, NULL when out of
 * memory. */
static float *unit_normals(const lk_mesh *mesh)
{
    float *out = lk__malloc_array(mesh->vertex_count, 3 * sizeof(float));
    if (out && !lk__gltf_unit_normals(mesh, mesh->positions, out)) {
        free(out);
        return NULL;
    }
    return out;
}

static float clamp01(float value) { return value > 0 ? (value < 1 ? value : 1) : 0; }

static size_t add_colors(mesh_writer *writer, const lk_mesh *mesh)
{
    size_t count = mesh->vertex_count;
    bool bytes_exact = true;
    for (size_t i = 0; i < 4 * count && bytes_exact && !(writer->flags & LK_GLTF_QUANTIZE); i++) {
        float scaled = clamp01(mesh->colors[i]) * 255.0f;
        bytes_exact = fabsf(scaled - roundf(scaled)) < 1e-3f;
    }
    if (!bytes_exact) {
        float *clamped = lk__malloc_array(count, 4 * sizeof(float));
        if (!clamped) {
            writer->failed = true;
            return 0;
        }
        for (size_t i = 0; i < 4 * count; i++) clamped[i] = clamp01(mesh->colors[i]);
        size_t accessor = add_floats(writer, clamped, count, 4, "VEC4", false);
        free(clamped);
        return accessor;
    }
    size_t offset = lk__gltf_reserve(writer, 4 * count);
    if (writer->failed) return 0;
    for (size_t i = 0; i < 4 * count; i++)
        writer->bin.data[offset + i] = (unsigned char)lroundf(clamp01(mesh->colors[i]) * 255.0f);
    lk__gltf_add_accessor(writer, offset, 4 * count, 4, GLTF_TARGET_ARRAY_BUFFER, COMPONENT_UNSIGNED_BYTE, true, count,
                          "VEC4");
    writer->quantized = true;
    return writer->accessor_count - 1;
}

/* KHR_mesh_quantization: positions as 14-bit unsigned shorts (padded to 8
 * bytes) on a uniform grid; the node's translation and scale map them
 * back. */
#define POSITION_BITS 14
#define TEXCOORD_BITS 12

/* A mesh's quantisation grid (position_grid): every primitive of the mesh
 * on one grid, so one transform (on the node) maps them back. The values
 * are floats as the file stores them, so that decoding uses exactly these. */

/* Widens [low, high] (empty while *first) by a mesh's positions. */
static void widen_box(const lk_scene_mesh *mesh, double low[3], double high[3], bool *first)
{
    for (size_t p = 0; p < mesh->primitive_count; p++) {
        const lk_mesh *m = &mesh->primitives[p].mesh;
        for (size_t i = 0; i < 3 * m->vertex_count; i++) {
            int k = (int)(i % 3);
            if (*first) low[k] = high[k] = m->positions[i];
            if (m->positions[i] < low[k]) low[k] = m->positions[i];
            if (m->positions[i] > high[k]) high[k] = m->positions[i];
            if (k == 2) *first = false;
        }
    }
}

/* The 14-bit grid over a box; returns its longest side. */
static double grid_of_box(const double low[3], const double high[3], position_grid *grid)
{
    double extent = fmax(high[0] - low[0], fmax(high[1] - low[1], high[2] - low[2]));
    const double steps = (double)((1u << POSITION_BITS) - 1);
    for (int k = 0; k < 3; k++) grid->origin[k] = (float)low[k];
    grid->step = extent > 0 ? (float)(extent / steps) : 1.0f;
    return extent;
}

static void grid_of_mesh(const lk_scene_mesh *mesh, position_grid *grid, double *extent_out)
{
    double low[3] = {0, 0, 0}, high[3] = {0, 0, 0};
    bool first = true;
    widen_box(mesh, low, high, &first);
    *extent_out = grid_of_box(low, high, grid);
}

/* Grids of skinned meshes. Their node transforms do nothing in glTF, so a
 * grid's transform goes into the inverse bind matrices of their skin
 * instead (io_gltf_skin_write.c): the meshes one skin binds then share one
 * grid, over their joint box in the bind pose (14 bits of it), and each
 * must be drawn with that skin only and have no morph targets (whose float
 * deltas would need the grid's scale). A skin whose meshes do not all
 * qualify leaves them as floats. Sets grids[m] and skinned[m] for the
 * meshes on a skin's grid, and skin_grids[s] (step 0: none). */
static lk_status skinned_grids(const lk_scene *scene, position_grid *grids, bool *skinned, position_grid *skin_grids)
{
    enum { UNDRAWN = -1, CONFLICT = -2 };
    int32_t *mesh_skin = lk__malloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *mesh_skin);
    bool *usable = lk__malloc_array(scene->skin_count ? scene->skin_count : 1, sizeof *usable);
    if (!mesh_skin || !usable) {
        free(mesh_skin);
        free(usable);
        return LK_ERR_NOMEM;
    }
    for (size_t m = 0; m < scene->mesh_count; m++) mesh_skin[m] = UNDRAWN;
    for (size_t s = 0; s < scene->skin_count; s++) usable[s] = true;
    for (size_t i = 0; i < scene->node_count; i++) {
        const lk_scene_node *node = &scene->nodes[i];
        if (!(node->mesh >= 0 && (size_t)node->mesh < scene->mesh_count)) continue;
        const lk_scene_mesh *mesh = &scene->meshes[node->mesh];
        int32_t skin = node->skin >= 0 && (size_t)node->skin < scene->skin_count && lk__gltf_mesh_is_skinned(mesh) &&
                               mesh->target_count == 0
                           ? node->skin
                           : CONFLICT;
        int32_t *seen = &mesh_skin[node->mesh];
        *seen = *seen == UNDRAWN || *seen == skin ? skin : CONFLICT;
    }
    for (size_t i = 0; i < scene->node_count; i++) {
        const lk_scene_node *node = &scene->nodes[i];
        if (node->skin >= 0 && (size_t)node->skin < scene->skin_count && node->mesh >= 0 &&
            (size_t)node->mesh < scene->mesh_count && mesh_skin[node->mesh] != node->skin)
            usable[node->skin] = false;
    }
    for (size_t s = 0; s < scene->skin_count; s++) {
        double low[3] = {0, 0, 0}, high[3] = {0, 0, 0};
        bool first = true;
        for (size_t m = 0; usable[s] && m < scene->mesh_count; m++)
            if (mesh_skin[m] == (int32_t)s) widen_box(&scene->meshes[m], low, high, &first);
        memset(&skin_grids[s], 0, sizeof skin_grids[s]);
        if (!usable[s] || first) continue;
        grid_of_box(low, high, &skin_grids[s]);
        for (size_t m = 0; m < scene->mesh_count; m++)
            if (mesh_skin[m] == (int32_t)s) grids[m] = skin_grids[s], skinned[m] = true;
    }
    free(mesh_skin);
    free(usable);
    return LK_OK;
}

/* Every mesh's grid. A mesh's own grid spends 14 bits on its own box, so a
 * bolt would get the precision of the whole engine; as gltfpack does, the
 * step is instead the whole scene's: the longest side of the scene's box
 * in the world over 2^14 - 1 steps, in each mesh's units (divided by the
 * largest stretch of the nodes drawing it), and never finer than the
 * mesh's own 14-bit grid (16 bits then always hold it). A mesh no node
 * draws keeps its own grid. */
static lk_status grids_of_scene(const lk_scene *scene, position_grid *grids, lk_error *error)
{
    double *stretches = lk__malloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *stretches);
    double *extents = lk__malloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *extents);
    double largest = 0.0;
    lk_status status = stretches && extents ? lk__scene_mesh_stretches(scene, stretches, &largest, error)
                                            : lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    if (status == LK_OK) {
        for (size_t m = 0; m < scene->mesh_count; m++) grid_of_mesh(&scene->meshes[m], &grids[m], &extents[m]);
        const double steps = (double)((1u << POSITION_BITS) - 1);
        for (size_t m = 0; m < scene->mesh_count; m++)
            if (stretches[m] > 0 && extents[m] > 0 && largest / steps / stretches[m] > grids[m].step)
                grids[m].step = (float)(largest / steps / stretches[m]);
    }
    free(stretches);
    free(extents);
    return status;
}

static size_t add_quantized_positions(mesh_writer *writer, const lk_mesh *mesh, const position_grid *grid)
{
    size_t count = mesh->vertex_count;
    size_t offset = lk__gltf_reserve(writer, 8 * count);
    if (writer->failed) return 0;
    unsigned q_low[3] = {65535, 65535, 65535}, q_high[3] = {0, 0, 0};
    for (size_t v = 0; v < count; v++) {
        unsigned char *out = writer->bin.data + offset + 8 * v;
        for (int k = 0; k < 3; k++) {
            double q = round(((double)mesh->positions[3 * v + (size_t)k] - grid->origin[k]) / grid->step);
            unsigned value = q < 0 ? 0 : q > 65535 ? 65535 : (unsigned)q;
            lk__store_u16le(out + 2 * k, (uint16_t)value);
            if (value < q_low[k]) q_low[k] = value;
            if (value > q_high[k]) q_high[k] = value;
        }
        lk__store_u16le(out + 6, 0);
    }
    cJSON *accessor = lk__gltf_add_accessor(writer, offset, 8 * count, 8, GLTF_TARGET_ARRAY_BUFFER,
                                            COMPONENT_UNSIGNED_SHORT, false, count, "VEC3");
    if (!accessor) return 0;
    cJSON *min = cJSON_AddArrayToObject(accessor, "min"), *max = cJSON_AddArrayToObject(accessor, "max");
    for (int k = 0; k < 3; k++) {
        cJSON_AddItemToArray(min, cJSON_CreateNumber(q_low[k]));
        cJSON_AddItemToArray(max, cJSON_CreateNumber(q_high[k]));
    }
    writer->quantized = true;
    return writer->accessor_count - 1;
}

/* Unit vectors (normals: 3 floats each, w = 0; tangents: 4 floats, w =
 * +-1) as normalised signed bytes, 4 per vertex. Compressed output stores
 * them through meshopt's octahedral filter (8-bit x and y on the
 * octahedron, z rebuilt by the decoder): the vertex codec then sees two
 * smooth channels instead of three, about a third fewer bytes on smooth
 * meshes. */
static size_t add_quantized_directions(mesh_writer *writer, const float *values, size_t count, unsigned components)
{
    size_t offset = lk__gltf_reserve(writer, 4 * count);
    if (writer->failed) return 0;
    unsigned char *out = writer->bin.data + offset;
    bool octahedral = (writer->flags & LK_GLTF_MESHOPT) != 0;
    if (octahedral) {
        float *four = lk__malloc_array(count ? count : 1, 4 * sizeof(float));
        if (!four) {
            writer->failed = true;
            return 0;
        }
        for (size_t v = 0; v < count; v++)
            for (unsigned k = 0; k < 4; k++) four[4 * v + k] = k < components ? values[components * v + k] : 0.0f;
        meshopt_encodeFilterOct(out, count, 4, 8, four);
        free(four);
    } else {
        for (size_t v = 0; v < count; v++)
            for (unsigned k = 0; k < 4; k++) {
                long q = k < components ? lroundf(values[components * v + k] * 127.0f) : 0;
                out[4 * v + k] = (unsigned char)(int8_t)(q < -127 ? -127 : q > 127 ? 127 : q);
            }
    }
    lk__gltf_add_accessor(writer, offset, 4 * count, 4, GLTF_TARGET_ARRAY_BUFFER, COMPONENT_BYTE, true, count,
                          components == 4 ? "VEC4" : "VEC3");
    if (!writer->failed && octahedral) writer->records[writer->record_count - 1].filter = GLTF_FILTER_OCTAHEDRAL;
    writer->quantized = true;
    return writer->accessor_count - 1;
}

/* Texture coordinates in [0, 1] (already flipped) on a 12-bit grid, as
 * normalised unsigned shorts; SIZE_MAX when one is outside (then floats). */
static size_t add_quantized_texcoords(mesh_writer *writer, const float *texcoords, size_t count)
{
    for (size_t i = 0; i < 2 * count; i++)
        if (!(texcoords[i] >= 0 && texcoords[i] <= 1)) return SIZE_MAX;
    size_t offset = lk__gltf_reserve(writer, 4 * count);
    if (writer->failed) return 0;
    const double steps = (double)((1u << TEXCOORD_BITS) - 1);
    for (size_t i = 0; i < 2 * count; i++) {
        double on_grid = round(texcoords[i] * steps) / steps;
        lk__store_u16le(writer->bin.data + offset + 2 * i, (uint16_t)lround(on_grid * 65535.0));
    }
    lk__gltf_add_accessor(writer, offset, 4 * count, 4, GLTF_TARGET_ARRAY_BUFFER, COMPONENT_UNSIGNED_SHORT, true, count,
                          "VEC2");
    writer->quantized = true;
    return writer->accessor_count - 1;
}

/* `count` indices of triangles, or of line segments (`lines`), into
 * vertex_count vertices. */
static size_t add_indices(mesh_writer *writer, const uint32_t *indices, size_t count, size_t vertex_count, bool lines)
{
    /* meshopt's index codec takes 16 or 32-bit indices */
    int type = vertex_count <= 0xFF && !(writer->flags & LK_GLTF_MESHOPT) ? COMPONENT_UNSIGNED_BYTE
               : vertex_count <= 0xFFFF                                   ? COMPONENT_UNSIGNED_SHORT
                                                                          : COMPONENT_UNSIGNED_INT;
    size_t size = type == COMPONENT_UNSIGNED_BYTE ? 1 : type == COMPONENT_UNSIGNED_SHORT ? 2 : 4;
    size_t offset = lk__gltf_reserve(writer, count * size);
    if (writer->failed) return 0;
    unsigned char *out = writer->bin.data + offset;
    for (size_t i = 0; i < count; i++) {
        uint32_t index = indices[i];
        if (size == 1)
            out[i] = (unsigned char)index;
        else if (size == 2)
            lk__store_u16le(out + 2 * i, (uint16_t)index);
        else
            lk__store_u32le(out + 4 * i, index);
    }
    lk__gltf_add_accessor(writer, offset, count * size, size, GLTF_TARGET_ELEMENT_ARRAY_BUFFER, type, false, count,
                          "SCALAR");
    if (!writer->failed) writer->records[writer->record_count - 1].sequence = lines;
    return writer->accessor_count - 1;
}

static bool write_u32(FILE *file, uint32_t value)
{
    unsigned char bytes[4];
    lk__store_u32le(bytes, value);
    return fwrite(bytes, 1, 4, file) == 4;
}

/* Adds one primitive of `input` (material -1: none) to `primitives`;
 * positions on `grid` when given (quantised), else floats. Returns the
 * primitive's JSON (NULL on failure). */
/* A primitive's morph targets: POSITION deltas (with the bounds glTF
 * requires; zeros when the primitive has none, since a target cannot be
 * empty) and the NORMAL and TANGENT deltas of the attributes written. */
static bool add_targets(mesh_writer *writer, cJSON *primitive, const lk_scene_primitive *source, size_t target_count,
                        bool normals, bool tangents)
{
    size_t vertex_count = source->mesh.vertex_count;
    float *zeros = NULL;
    const float *positions = source->target_positions;
    if (!positions && !(positions = zeros = lk__calloc_array(vertex_count, 3 * sizeof(float)))) return false;
    cJSON *targets = cJSON_AddArrayToObject(primitive, "targets");
    for (size_t k = 0; targets && k < target_count; k++) {
        cJSON *target = cJSON_CreateObject();
        if (!target || !cJSON_AddItemToArray(targets, target)) {
            cJSON_Delete(target);
            targets = NULL;
            break;
        }
        size_t at = 3 * k * vertex_count;
        cJSON_AddNumberToObject(
            target, "POSITION",
            (double)add_floats(writer, positions + (zeros ? 0 : at), vertex_count, 3, "VEC3", true));
        if (normals && source->target_normals)
            cJSON_AddNumberToObject(
                target, "NORMAL",
                (double)add_floats(writer, source->target_normals + at, vertex_count, 3, "VEC3", false));
        if (tangents && source->target_tangents)
            cJSON_AddNumberToObject(
                target, "TANGENT",
                (double)add_floats(writer, source->target_tangents + at, vertex_count, 3, "VEC3", false));
    }
    free(zeros);
    return targets && !writer->failed;
}

static cJSON *add_primitive(mesh_writer *writer, cJSON *primitives, const lk_scene_primitive *source,
                            size_t target_count, const position_grid *grid, const lk_write_options *options)
{
    lk_scene_primitive reordered;
    memset(&reordered, 0, sizeof reordered);
    lk_mesh_init(&reordered.mesh);
    /* Quantised alone, the primitive keeps its vertices and triangles as
     * they are (a file the same size whatever their order); so does one
     * with morph targets (merging vertices would have to compare them). */
    if ((writer->flags & LK_GLTF_MESHOPT) && source->mesh.triangle_count && target_count == 0) {
        if (!lk__gltf_compact_for_codecs(source, &reordered)) {
            lk__gltf_compacted_free(&reordered);
            return NULL;
        }
        source = &reordered;
    }
    const lk_mesh *mesh = &source->mesh;
    const float *tangents = source->tangents, *texcoords1 = source->texcoords1;
    int32_t material = source->material;
    bool quantize = (writer->flags & LK_GLTF_QUANTIZE) != 0, ok = false;
    size_t vertex_count = mesh->vertex_count;
    float *scratch = NULL;
    cJSON *primitive = cJSON_CreateObject();
    if (!primitive) goto done;
    cJSON_AddItemToArray(primitives, primitive);
    cJSON *attributes = cJSON_AddObjectToObject(primitive, "attributes");
    if (!attributes) goto done;
    cJSON_AddNumberToObject(attributes, "POSITION",
                            grid ? (double)add_quantized_positions(writer, mesh, grid)
                                 : (double)add_floats(writer, mesh->positions, vertex_count, 3, "VEC3", true));
    if (mesh->normals && !options->skip_normals) {
        scratch = unit_normals(mesh);
        if (!scratch) goto done;
        cJSON_AddNumberToObject(attributes, "NORMAL",
                                quantize ? (double)add_quantized_directions(writer, scratch, vertex_count, 3)
                                         : (double)add_floats(writer, scratch, vertex_count, 3, "VEC3", false));
        free(scratch);
        scratch = NULL;
    }
    if (mesh->texcoords && !options->skip_texcoords) {
        scratch = lk__malloc_array(vertex_count, 2 * sizeof(float));
        if (!scratch) goto done;
        for (size_t v = 0; v < vertex_count; v++) {
            scratch[2 * v] = mesh->texcoords[2 * v];
            scratch[2 * v + 1] = 1.0f - mesh->texcoords[2 * v + 1];
        }
        size_t accessor = quantize ? add_quantized_texcoords(writer, scratch, vertex_count) : SIZE_MAX;
        if (accessor == SIZE_MAX) accessor = add_floats(writer, scratch, vertex_count, 2, "VEC2", false);
        cJSON_AddNumberToObject(attributes, "TEXCOORD_0", (double)accessor);
    }
    if (texcoords1 && !options->skip_texcoords) {
        free(scratch);
        scratch = lk__malloc_array(vertex_count, 2 * sizeof(float));
        if (!scratch) goto done;
        for (size_t v = 0; v < vertex_count; v++) {
            scratch[2 * v] = texcoords1[2 * v];
            scratch[2 * v + 1] = 1.0f - texcoords1[2 * v + 1];
        }
        size_t accessor = quantize ? add_quantized_texcoords(writer, scratch, vertex_count) : SIZE_MAX;
        if (accessor == SIZE_MAX) accessor = add_floats(writer, scratch, vertex_count, 2, "VEC2", false);
        cJSON_AddNumberToObject(attributes, "TEXCOORD_1", (double)accessor);
    }
    if (tangents && !options->skip_normals) {
        /* Unit xyz and w = +-1, as the specification requires; a tangent
         * that cannot be normalised becomes one perpendicular to nothing
         * in particular (+x), which a renderer still accepts. */
        free(scratch);
        scratch = lk__malloc_array(vertex_count, 4 * sizeof(float));
        if (!scratch) goto done;
        for (size_t v = 0; v < vertex_count; v++) {
            const float *t = tangents + 4 * v;
            double length = sqrt((double)t[0] * t[0] + (double)t[1] * t[1] + (double)t[2] * t[2]);
            for (int k = 0; k < 3; k++)
                scratch[4 * v + (size_t)k] = length > 1e-12 ? (float)(t[k] / length) : (k == 0 ? 1.0f : 0.0f);
            scratch[4 * v + 3] = t[3] < 0 ? -1.0f : 1.0f;
        }
        cJSON_AddNumberToObject(attributes, "TANGENT",
                                quantize ? (double)add_quantized_directions(writer, scratch, vertex_count, 4)
                                         : (double)add_floats(writer, scratch, vertex_count, 4, "VEC4", false));
    }
    if (mesh->colors && !options->skip_colors)
        cJSON_AddNumberToObject(attributes, "COLOR_0", (double)add_colors(writer, mesh));
    if (source->joints && source->weights) {
        if (!lk__gltf_add_skin_attributes(writer, attributes, source->joints, source->weights, vertex_count)) goto done;
    }
    if (target_count && !add_targets(writer, primitive, source, target_count, mesh->normals && !options->skip_normals,
                                     tangents && !options->skip_normals))
        goto done;
    if (mesh->triangle_count) {
        cJSON_AddNumberToObject(
            primitive, "indices",
            (double)add_indices(writer, mesh->indices, 3 * mesh->triangle_count, vertex_count, false));
        cJSON_AddNumberToObject(primitive, "mode", MODE_TRIANGLES);
    } else if (source->line_count) {
        cJSON_AddNumberToObject(primitive, "indices",
                                (double)add_indices(writer, source->lines, 2 * source->line_count, vertex_count, true));
        cJSON_AddNumberToObject(primitive, "mode", MODE_LINES);
    } else {
        cJSON_AddNumberToObject(primitive, "mode", MODE_POINTS);
    }
    if (material >= 0) cJSON_AddNumberToObject(primitive, "material", material);
    ok = !writer->failed;
done:
    free(scratch);
    lk__gltf_compacted_free(&reordered);
    return ok ? primitive : NULL;
}


/* ---- scenes ------------------------------------------------------------------ */

#define NORMAL_MAP (1u << 31) /* in a material's use bits: it samples a normal map */

/* A primitive written with its own accessors: the data it wrote (arrays
 * of the scene, or tangents generated for it and owned here), the grid
 * its positions are on, and its JSON in the document. */
typedef struct written_primitive {
    lk_scene_primitive primitive;
    position_grid grid;
    cJSON *json;
    float *generated_tangents;
    uint64_t hash; /* primitive_hash */
} written_primitive;

/* FNV-1a over `bytes` bytes (none when data is NULL, marked apart from an
 * empty array), continuing from `hash`. */
static uint64_t hash_bytes(uint64_t hash, const void *data, size_t bytes)
{
    const unsigned char *p = data;
    hash = (hash ^ (data ? 1u : 2u)) * 1099511628211u;
    for (size_t i = 0; p && i < bytes; i++) hash = (hash ^ p[i]) * 1099511628211u;
    return hash;
}

/* A hash of what same_primitive_data compares (and the grid, when given). */
static uint64_t primitive_hash(const lk_scene_primitive *primitive, const position_grid *grid)
{
    const lk_mesh *mesh = &primitive->mesh;
    size_t n = mesh->vertex_count;
    uint64_t hash = 14695981039346656037u;
    size_t counts[2] = {n, mesh->triangle_count};
    hash = hash_bytes(hash, counts, sizeof counts);
    hash = hash_bytes(hash, mesh->positions, 3 * n * sizeof(float));
    hash = hash_bytes(hash, mesh->indices, 3 * mesh->triangle_count * sizeof(uint32_t));
    hash = hash_bytes(hash, mesh->normals, 3 * n * sizeof(float));
    hash = hash_bytes(hash, mesh->texcoords, 2 * n * sizeof(float));
    hash = hash_bytes(hash, mesh->colors, 4 * n * sizeof(float));
    hash = hash_bytes(hash, primitive->tangents, 4 * n * sizeof(float));
    hash = hash_bytes(hash, primitive->texcoords1, 2 * n * sizeof(float));
    hash = hash_bytes(hash, primitive->lines, 2 * primitive->line_count * sizeof(uint32_t));
    hash = hash_bytes(hash, primitive->joints, 4 * n * sizeof(uint16_t));
    hash = hash_bytes(hash, primitive->weights, 4 * n * sizeof(float));
    if (grid) hash = hash_bytes(hash, grid, sizeof *grid);
    return hash;
}


static bool same_primitive_data(const lk_scene_primitive *a, const lk_scene_primitive *b)
{
    const lk_mesh *x = &a->mesh, *y = &b->mesh;
    size_t n = x->vertex_count;
    if (n != y->vertex_count || x->triangle_count != y->triangle_count || a->line_count != b->line_count ||
        (a->lines != b->lines &&
         (!a->lines || !b->lines || memcmp(a->lines, b->lines, 2 * a->line_count * sizeof(uint32_t)))))
        return false;
    if (x->indices != y->indices &&
        (!x->indices || !y->indices || memcmp(x->indices, y->indices, 3 * x->triangle_count * sizeof(uint32_t))))
        return false;
    return lk__gltf_same_floats(x->positions, y->positions, 3 * n) &&
           lk__gltf_same_floats(x->normals, y->normals, 3 * n) &&
           lk__gltf_same_floats(x->texcoords, y->texcoords, 2 * n) &&
           lk__gltf_same_floats(x->colors, y->colors, 4 * n) && lk__gltf_same_floats(a->tangents, b->tangents, 4 * n) &&
           lk__gltf_same_floats(a->texcoords1, b->texcoords1, 2 * n) &&
           lk__gltf_same_floats(a->weights, b->weights, 4 * n) &&
           (a->joints == b->joints ||
            (a->joints && b->joints && memcmp(a->joints, b->joints, 4 * n * sizeof(uint16_t)) == 0));
}

static cJSON *number_array(const double *values, size_t count)
{
    cJSON *array = cJSON_CreateArray();
    for (size_t i = 0; array && i < count; i++) cJSON_AddItemToArray(array, cJSON_CreateNumber(values[i]));
    return array;
}

/* A node's transform into its JSON: the matrix when the scene has one
 * (omitted when identity), else translation, rotation and scale (each
 * omitted at its default). `grid` (quantised positions) is applied after
 * it: local * translate(origin) * scale(step). */
static void add_transform(cJSON *json, const lk_scene_node *node, const position_grid *grid)
{
    if (node->has_matrix) {
        double m[16];
        memcpy(m, node->matrix, sizeof m);
        if (grid) lk__gltf_matrix_times_grid(m, grid);
        bool identity = true;
        for (int i = 0; i < 16; i++) identity = identity && m[i] == (i % 5 == 0 ? 1.0 : 0.0);
        if (!identity) cJSON_AddItemToObject(json, "matrix", number_array(m, 16));
        return;
    }
    double translation[3], scale[3];
    memcpy(translation, node->translation, sizeof translation);
    memcpy(scale, node->scale, sizeof scale);
    if (grid) {
        /* T R S (step x + origin) = (T + R (S o)) + R (S step) x */
        const double *q = node->rotation;
        double x = q[0], y = q[1], z = q[2], w = q[3];
        double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                       2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                       2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
        double so[3] = {scale[0] * grid->origin[0], scale[1] * grid->origin[1], scale[2] * grid->origin[2]};
        for (int row = 0; row < 3; row++) translation[row] += r[row] * so[0] + r[3 + row] * so[1] + r[6 + row] * so[2];
        for (int k = 0; k < 3; k++) scale[k] *= grid->step;
    }
    if (translation[0] != 0 || translation[1] != 0 || translation[2] != 0)
        cJSON_AddItemToObject(json, "translation", number_array(translation, 3));
    if (node->rotation[0] != 0 || node->rotation[1] != 0 || node->rotation[2] != 0 || node->rotation[3] != 1)
        cJSON_AddItemToObject(json, "rotation", number_array(node->rotation, 4));
    if (scale[0] != 1 || scale[1] != 1 || scale[2] != 1) cJSON_AddItemToObject(json, "scale", number_array(scale, 3));
}

/* Adds the names of the extensions used inside `item` to `used` (once). */
static void collect_extensions(const cJSON *item, cJSON *used)
{
    const cJSON *child;
    cJSON_ArrayForEach(child, item)
    {
        if (child->string && strcmp(child->string, "extras") == 0) continue;
        if (child->string && strcmp(child->string, "extensions") == 0 && cJSON_IsObject(child)) {
            const cJSON *extension;
            cJSON_ArrayForEach(extension, child)
            {
                bool listed = false;
                const cJSON *name;
                cJSON_ArrayForEach(name, used) listed = listed || strcmp(name->valuestring, extension->string) == 0;
                if (!listed) cJSON_AddItemToArray(used, cJSON_CreateString(extension->string));
            }
        }
        if (cJSON_IsObject(child) || cJSON_IsArray(child)) collect_extensions(child, used);
    }
}

static bool add_unique_name(cJSON *list, const char *name)
{
    const cJSON *item;
    cJSON_ArrayForEach(item, list)
    {
        if (strcmp(item->valuestring, name) == 0) return true;
    }
    return cJSON_AddItemToArray(list, cJSON_CreateString(name));
}

/* Kept JSON objects (materials, textures, samplers, cameras) parsed back
 * into `array`; false with *bad set to the index that does not parse. */
static bool add_json_objects(cJSON *root, const char *key, char *const *texts, size_t count, size_t stride_bytes,
                             size_t *bad)
{
    if (count == 0) return true;
    cJSON *array = cJSON_AddArrayToObject(root, key);
    if (!array) return false;
    for (size_t i = 0; i < count; i++) {
        const char *text = *(char *const *)((const char *)texts + i * stride_bytes);
        cJSON *object = text ? cJSON_Parse(text) : cJSON_CreateObject();
        if (!cJSON_IsObject(object)) {
            cJSON_Delete(object);
            *bad = i;
            return false;
        }
        cJSON_AddItemToArray(array, object);
    }
    return true;
}

/* Writes the document: images appended to the buffer's data (after the
 * views, or after the meshopt-compressed bytes) or, with
 * LK_GLTF_EXTERNAL_IMAGES in a .gltf, files of their own (STEM_N.EXT), the
 * buffer(s), and the .glb or .gltf + .bin. */
static lk_status emit(mesh_writer *writer, cJSON *root, cJSON *used, cJSON *required, const lk_scene *scene, FILE *file,
                      const char *path, bool binary, lk_error *error)
{
    lk__buffer packed = {0};
    lk__buffer *data = &writer->bin;
    char *text = NULL, *bin_path = NULL, *bin_uri = NULL;
    lk_status status = LK_OK;
    if (writer->quantized) {
        add_unique_name(used, "KHR_mesh_quantization");
        add_unique_name(required, "KHR_mesh_quantization");
    }
    if (!lk__gltf_group_views(writer)) goto nomem;
    bool compressed = (writer->flags & LK_GLTF_MESHOPT) && writer->record_count > 0;
    if (compressed) {
        if (!lk__gltf_compress_views(writer, &packed)) goto nomem;
        data = &packed;
        add_unique_name(used, "EXT_meshopt_compression");
        add_unique_name(required, "EXT_meshopt_compression");
    }
    bool external_images = !binary && scene && (writer->flags & LK_GLTF_EXTERNAL_IMAGES);
    if (scene && scene->image_count) {
        cJSON *images = cJSON_AddArrayToObject(root, "images");
        if (!writer->views) writer->views = cJSON_AddArrayToObject(root, "bufferViews");
        if (!images || !writer->views) goto nomem;
        for (size_t i = 0; i < scene->image_count; i++) {
            const lk_scene_image *image = &scene->images[i];
            if (external_images) {
                char suffix[48], *image_path = NULL, *image_uri = NULL;
                /* the bytes are written by the loop below the JSON */
                snprintf(suffix, sizeof suffix, "_%zu.%s", i, lk__gltf_image_extension(image->mime_type));
                cJSON *json = cJSON_CreateObject();
                status = json ? lk__gltf_sibling_names(path, suffix, &image_path, &image_uri, error) : LK_ERR_NOMEM;
                if (status == LK_OK) cJSON_AddStringToObject(json, "uri", image_uri);
                free(image_path);
                free(image_uri);
                if (status != LK_OK) {
                    cJSON_Delete(json);
                    if (status == LK_ERR_NOMEM) goto nomem;
                    goto done;
                }
                if (image->mime_type) cJSON_AddStringToObject(json, "mimeType", image->mime_type);
                if (image->name) cJSON_AddStringToObject(json, "name", image->name);
                cJSON_AddItemToArray(images, json);
                continue;
            }
            while (data->size % 4) {
                if (!lk__buffer_reserve(data, 1)) goto nomem;
                data->data[data->size++] = 0;
            }
            size_t offset = data->size;
            if (!lk__gltf_image_bytes(image->data, image->size, data)) goto nomem;
            /* glTF wants byteLength >= 1: an empty image becomes one byte. */
            if (data->size == offset && !lk__buffer_append(data, "", 1)) goto nomem;
            size_t length = data->size - offset;
            cJSON *view = cJSON_CreateObject(), *json = cJSON_CreateObject();
            if (!view || !json) {
                cJSON_Delete(view);
                cJSON_Delete(json);
                goto nomem;
            }
            cJSON_AddNumberToObject(view, "buffer", 0);
            cJSON_AddNumberToObject(view, "byteOffset", (double)offset);
            cJSON_AddNumberToObject(view, "byteLength", (double)length);
            cJSON_AddItemToArray(writer->views, view);
            writer->view_count++;
            cJSON_AddNumberToObject(json, "bufferView", (double)writer->view_count - 1);
            cJSON_AddStringToObject(json, "mimeType", image->mime_type ? image->mime_type : "image/png");
            if (image->name) cJSON_AddStringToObject(json, "name", image->name);
            cJSON_AddItemToArray(images, json);
        }
    }
    if (data->size > 0) {
        cJSON *buffers = cJSON_AddArrayToObject(root, "buffers");
        cJSON *buffer = cJSON_CreateObject();
        if (!buffers || !buffer) {
            cJSON_Delete(buffer);
            goto nomem;
        }
        cJSON_AddItemToArray(buffers, buffer);
        cJSON_AddNumberToObject(buffer, "byteLength", (double)data->size);
        if (compressed) {
            cJSON *fallback = cJSON_CreateObject();
            cJSON_AddItemToArray(buffers, fallback);
            cJSON_AddNumberToObject(fallback, "byteLength", (double)writer->bin.size);
            cJSON_AddBoolToObject(
                cJSON_AddObjectToObject(cJSON_AddObjectToObject(fallback, "extensions"), "EXT_meshopt_compression"),
                "fallback", true);
        }
        if (!binary) {
            status = lk__gltf_sibling_names(path, ".bin", &bin_path, &bin_uri, error);
            if (status != LK_OK) goto done;
            cJSON_AddStringToObject(buffer, "uri", bin_uri);
        }
    }
    /* glTF wants no empty lists */
    if (cJSON_GetArraySize(writer->views) == 0) cJSON_DeleteItemFromObject(root, "bufferViews");
    if (cJSON_GetArraySize(used) == 0) cJSON_DeleteItemFromObject(root, "extensionsUsed");
    if (cJSON_GetArraySize(required) == 0) cJSON_DeleteItemFromObject(root, "extensionsRequired");
    text = binary ? cJSON_PrintUnformatted(root) : cJSON_Print(root);
    if (!text) goto nomem;
    size_t text_length = strlen(text);
    if (binary) {
        size_t json_chunk = (text_length + 3) / 4 * 4, bin_chunk = (data->size + 3) / 4 * 4;
        size_t total = 12 + 8 + json_chunk + (data->size ? 8 + bin_chunk : 0);
        if (total > UINT32_MAX) {
            status = lk_error_set(error, LK_ERR_LIMIT,
                                  "%zu bytes: a .glb holds at most 4 GiB (write .gltf, whose buffer is a .bin)", total);
            goto done;
        }
        bool ok = write_u32(file, GLB_MAGIC) && write_u32(file, 2) && write_u32(file, (uint32_t)total) &&
                  write_u32(file, (uint32_t)json_chunk) && write_u32(file, GLB_CHUNK_JSON) &&
                  fwrite(text, 1, text_length, file) == text_length;
        for (size_t i = text_length; ok && i < json_chunk; i++) ok = fputc(' ', file) != EOF;
        if (ok && data->size) {
            ok = write_u32(file, (uint32_t)bin_chunk) && write_u32(file, GLB_CHUNK_BIN) &&
                 fwrite(data->data, 1, data->size, file) == data->size;
            for (size_t i = data->size; ok && i < bin_chunk; i++) ok = fputc(0, file) != EOF;
        }
        if (!ok || ferror(file)) status = lk_error_set(error, LK_ERR_IO, "write error");
        goto done;
    }
    /* The images and the buffer first, each whole or not at all; then the
     * JSON naming them. */
    for (size_t i = 0; external_images && i < scene->image_count && status == LK_OK; i++) {
        char suffix[48], *image_path = NULL, *image_uri = NULL;
        snprintf(suffix, sizeof suffix, "_%zu.%s", i, lk__gltf_image_extension(scene->images[i].mime_type));
        lk__buffer bytes = {0};
        status = lk__gltf_sibling_names(path, suffix, &image_path, &image_uri, error);
        if (status == LK_OK && !lk__gltf_image_bytes(scene->images[i].data, scene->images[i].size, &bytes))
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        if (status == LK_OK) status = lk__gltf_write_sibling(image_path, bytes.data, bytes.size, error);
        lk__buffer_free(&bytes);
        free(image_path);
        free(image_uri);
    }
    if (status == LK_OK && bin_path) status = lk__gltf_write_sibling(bin_path, data->data, data->size, error);
    if (status != LK_OK) goto done;
    if (fwrite(text, 1, text_length, file) != text_length || fputc('\n', file) == EOF || ferror(file))
        status = lk_error_set(error, LK_ERR_IO, "write error");
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "out of memory while building the glTF");
done:
    free(text);
    free(bin_path);
    free(bin_uri);
    lk__buffer_free(&packed);
    return status;
}

static cJSON *float_array(const float *values, size_t count)
{
    cJSON *array = cJSON_CreateArray();
    for (size_t i = 0; array && i < count; i++) cJSON_AddItemToArray(array, cJSON_CreateNumber(values[i]));
    return array;
}

/* A mesh's default morph weights and extras.targetNames. */
static bool add_mesh_morph(cJSON *json, const lk_scene_mesh *mesh)
{
    if (mesh->weights && !cJSON_AddItemToObject(json, "weights", float_array(mesh->weights, mesh->target_count)))
        return false;
    if (!mesh->target_names) return true;
    cJSON *names = cJSON_AddArrayToObject(cJSON_AddObjectToObject(json, "extras"), "targetNames");
    for (size_t k = 0; names && k < mesh->target_count; k++)
        cJSON_AddItemToArray(names, cJSON_CreateString(mesh->target_names[k] ? mesh->target_names[k] : ""));
    return names != NULL;
}


/* Writes a whole scene (lk_scene_write). Meshes without a primitive that
 * has vertices are left out (glTF wants at least one) and the references
 * to them with them. With LK_GLTF_QUANTIZE each mesh's positions share one
 * grid whose transform goes onto the nodes using the mesh: composed into a
 * childless node's transform, or on a new child node holding the mesh so
 * that the children do not inherit it. */
lk_status lk__write_gltf_scene(FILE *file, const char *path, bool binary, const lk_scene *scene,
                               const lk_write_options *options, lk_error *error)
{
    mesh_writer writer;
    memset(&writer, 0, sizeof writer);
    writer.flags = options->gltf_flags;
    if (writer.flags & ~(uint64_t)(LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT | LK_GLTF_EXTERNAL_IMAGES))
        return lk_error_set(error, LK_ERR_INVALID, "unknown glTF flags 0x%llx", (unsigned long long)writer.flags);
    bool quantize = (writer.flags & LK_GLTF_QUANTIZE) != 0;
    bool compact = (writer.flags & (LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT)) != 0;
    lk_status status = LK_OK;
    unsigned *material_use = NULL;
    written_primitive *written = NULL;
    uint32_t *written_table = NULL; /* written index + 1, 0: empty */
    size_t written_count = 0, written_slots = 16;
    int32_t *mesh_index = lk__calloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *mesh_index);
    position_grid *grids = lk__calloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *grids);
    bool *on_grid = lk__calloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *on_grid);
    bool *skinned_on_grid = lk__calloc_array(scene->mesh_count ? scene->mesh_count : 1, sizeof *skinned_on_grid);
    position_grid *skin_grids = lk__calloc_array(scene->skin_count ? scene->skin_count : 1, sizeof *skin_grids);
    bool *animated = lk__calloc_array(scene->node_count ? scene->node_count : 1, sizeof *animated);
    cJSON *root = cJSON_CreateObject();
    if (!root || !mesh_index || !grids || !on_grid || !skinned_on_grid || !skin_grids || !animated) goto nomem;
    cJSON *asset = cJSON_AddObjectToObject(root, "asset");
    cJSON_AddStringToObject(asset, "version", "2.0");
    cJSON_AddStringToObject(asset, "generator", "lodkit " LK_VERSION_STRING);
    cJSON *used = cJSON_AddArrayToObject(root, "extensionsUsed");
    cJSON *required = cJSON_AddArrayToObject(root, "extensionsRequired");
    cJSON_AddNumberToObject(root, "scene", 0);
    cJSON *scene_json = cJSON_CreateObject();
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene_json);
    if (!used || !required || !scene_json) goto nomem;
    writer.accessors = cJSON_CreateArray();
    writer.views = cJSON_CreateArray();
    cJSON *meshes = cJSON_CreateArray();
    if (!writer.accessors || !writer.views || !meshes) {
        cJSON_Delete(writer.accessors);
        cJSON_Delete(writer.views);
        cJSON_Delete(meshes);
        writer.accessors = writer.views = NULL;
        goto nomem;
    }
    /* Added now so that the file lists them in glTF's usual order. */
    cJSON_AddItemToObject(root, "accessors", writer.accessors);
    cJSON_AddItemToObject(root, "bufferViews", writer.views);

    /* What each material samples: tangents are generated for normal maps;
     * compact output drops the texture coordinates and tangents nothing
     * samples (gltfpack does the same) and so merges the vertices that
     * differed only there. */
    size_t material_slots = scene->material_count ? scene->material_count : 1;
    material_use = lk__calloc_array(material_slots, sizeof *material_use);
    if (!material_use) goto nomem;
    for (size_t i = 0; i < scene->material_count; i++) {
        cJSON *material = cJSON_Parse(scene->materials[i].json ? scene->materials[i].json : "{}");
        material_use[i] =
            material ? lk__gltf_sampled_texcoord_sets(material) | (lk__gltf_uses_normal_map(material) ? NORMAL_MAP : 0u)
                     : ~0u; /* unparsable: the error comes below; keep all */
        cJSON_Delete(material);
    }
    if (quantize) {
        status = grids_of_scene(scene, grids, error);
        if (status != LK_OK) goto done;
        /* A skinned mesh ignores its node's transform (its joints place
         * it), so the grid's transform cannot go there: such meshes get
         * their skin's grid (skinned_grids) or keep float positions; so do
         * meshes with morph targets, whose float deltas would need the
         * grid's scale too. */
        for (size_t m = 0; m < scene->mesh_count; m++)
            on_grid[m] = !lk__gltf_mesh_is_skinned(&scene->meshes[m]) && scene->meshes[m].target_count == 0;
        for (size_t i = 0; i < scene->node_count; i++)
            if (scene->nodes[i].skin >= 0 && (size_t)scene->nodes[i].skin < scene->skin_count &&
                scene->nodes[i].mesh >= 0 && (size_t)scene->nodes[i].mesh < scene->mesh_count)
                on_grid[scene->nodes[i].mesh] = false;
        for (size_t m = 0; m < scene->mesh_count; m++)
            if (!on_grid[m]) memset(&grids[m], 0, sizeof grids[m]);
        if (skinned_grids(scene, grids, skinned_on_grid, skin_grids) != LK_OK) goto nomem;
    }
    /* An animated node's translation and scale are replaced by its
     * animation's: a grid's transform goes on a child node instead. */
    for (size_t a = 0; a < scene->animation_count; a++)
        for (size_t c = 0; c < scene->animations[a].channel_count; c++)
            if (scene->animations[a].channels[c].node < scene->node_count)
                animated[scene->animations[a].channels[c].node] = true;

    /* The primitives written with their own accessors, and a hash table
     * over them (open addressing, at most half full) to find equal data. */
    size_t primitive_total = 0;
    for (size_t m = 0; m < scene->mesh_count; m++) primitive_total += scene->meshes[m].primitive_count;
    if (primitive_total >= UINT32_MAX / 4) goto nomem;
    while (written_slots < 2 * primitive_total + 2) written_slots *= 2;
    written = lk__malloc_array(primitive_total ? primitive_total : 1, sizeof *written);
    written_table = lk__calloc_array(written_slots, sizeof *written_table);
    if (!written || !written_table) goto nomem;

    /* Meshes */
    int32_t written_meshes = 0;
    for (size_t m = 0; m < scene->mesh_count; m++) {
        const lk_scene_mesh *mesh = &scene->meshes[m];
        mesh_index[m] = -1;
        size_t drawable = 0;
        for (size_t p = 0; p < mesh->primitive_count; p++) drawable += mesh->primitives[p].mesh.vertex_count > 0;
        if (drawable == 0) continue;
        cJSON *json = cJSON_CreateObject();
        if (!json) goto nomem;
        cJSON_AddItemToArray(meshes, json);
        if (mesh->name) cJSON_AddStringToObject(json, "name", mesh->name);
        cJSON *primitives = cJSON_AddArrayToObject(json, "primitives");
        for (size_t p = 0; p < mesh->primitive_count; p++) {
            const lk_scene_primitive *primitive = &mesh->primitives[p];
            if (primitive->mesh.vertex_count == 0) continue;
            lk_scene_primitive own = *primitive;
            if (!(own.material >= 0 && (size_t)own.material < scene->material_count)) own.material = -1;
            if (options->skip_normals) own.mesh.normals = NULL, own.tangents = NULL;
            if (options->skip_texcoords) own.mesh.texcoords = NULL, own.texcoords1 = NULL;
            if (options->skip_colors) own.mesh.colors = NULL;
            unsigned use = own.material >= 0 ? material_use[own.material] : 0u;
            if (compact && own.material >= 0 && own.mesh.triangle_count) {
                if (!(use & 1u)) own.mesh.texcoords = NULL;
                if (!(use & 2u)) own.texcoords1 = NULL;
                if (!(use & NORMAL_MAP)) own.tangents = NULL;
            }
            float *generated = NULL;
            if ((use & NORMAL_MAP) && own.material >= 0 && !own.tangents && own.mesh.normals && own.mesh.texcoords &&
                own.mesh.triangle_count) {
                float *normals = unit_normals(&own.mesh);
                generated = normals ? lk__malloc_array(own.mesh.vertex_count, 4 * sizeof(float)) : NULL;
                if (!generated) {
                    free(normals);
                    goto nomem;
                }
                lk__gltf_compute_tangents(&own.mesh, normals, generated);
                free(normals);
                own.tangents = generated;
            }
            /* The same data as a primitive written before (glTF files share
             * accessors between meshes; the reader gave each its copy):
             * its accessors again. */
            const written_primitive *same = NULL;
            uint64_t hash = primitive_hash(&own, quantize ? &grids[m] : NULL);
            size_t slot = (size_t)hash & (written_slots - 1);
            bool shareable = mesh->target_count == 0; /* the hash does not cover targets */
            for (; shareable && written_table[slot] && !same; slot = (slot + 1) & (written_slots - 1)) {
                const written_primitive *candidate = &written[written_table[slot] - 1];
                if (candidate->hash == hash && same_primitive_data(&candidate->primitive, &own) &&
                    (!quantize || memcmp(&candidate->grid, &grids[m], sizeof grids[m]) == 0))
                    same = candidate;
            }
            cJSON *added = NULL;
            if (same) {
                added = cJSON_Duplicate(same->json, true);
                if (added) {
                    cJSON_DeleteItemFromObject(added, "material");
                    if (own.material >= 0) cJSON_AddNumberToObject(added, "material", own.material);
                    cJSON_AddItemToArray(primitives, added);
                }
                free(generated);
            } else if ((added = add_primitive(&writer, primitives, &own, mesh->target_count,
                                              on_grid[m] || skinned_on_grid[m] ? &grids[m] : NULL, options)) != NULL) {
                /* slot: the empty one the search stopped at */
                written[written_count] = (written_primitive){own, grids[m], added, generated, hash};
                ++written_count;
                if (shareable) written_table[slot] = (uint32_t)written_count;
            } else {
                free(generated);
            }
            if (!added) goto nomem;
        }
        if (mesh->target_count && !add_mesh_morph(json, mesh)) goto nomem;
        mesh_index[m] = written_meshes++;
    }
    if (written_meshes > 0)
        cJSON_AddItemToObject(root, "meshes", meshes);
    else
        cJSON_Delete(meshes);

    /* Nodes: the scene's, then any holding a quantised mesh under a parent. */
    if (scene->node_count > 0) {
        cJSON *nodes = cJSON_AddArrayToObject(root, "nodes");
        if (!nodes) goto nomem;
        size_t extra_node = scene->node_count;
        bool lods = false;
        for (size_t i = 0; i < scene->node_count; i++) {
            const lk_scene_node *node = &scene->nodes[i];
            cJSON *json = cJSON_CreateObject();
            if (!json) goto nomem;
            cJSON_AddItemToArray(nodes, json);
            if (node->name) cJSON_AddStringToObject(json, "name", node->name);
            int32_t mesh = node->mesh >= 0 && (size_t)node->mesh < scene->mesh_count ? mesh_index[node->mesh] : -1;
            bool separate = mesh >= 0 && on_grid[node->mesh] && (node->child_count > 0 || animated[i]);
            add_transform(json, node, mesh >= 0 && on_grid[node->mesh] && !separate ? &grids[node->mesh] : NULL);
            if (mesh >= 0 && !separate) cJSON_AddNumberToObject(json, "mesh", mesh);
            if (mesh >= 0 && node->skin >= 0 && (size_t)node->skin < scene->skin_count &&
                lk__gltf_mesh_is_skinned(&scene->meshes[node->mesh]))
                cJSON_AddNumberToObject(json, "skin", node->skin);
            if (node->camera >= 0 && (size_t)node->camera < scene->camera_count)
                cJSON_AddNumberToObject(json, "camera", node->camera);
            if (mesh >= 0 && node->weights && scene->meshes[node->mesh].target_count)
                cJSON_AddItemToObject(json, "weights",
                                      float_array(node->weights, scene->meshes[node->mesh].target_count));
            if (node->child_count > 0 || separate) {
                cJSON *children = cJSON_AddArrayToObject(json, "children");
                for (size_t c = 0; c < node->child_count; c++)
                    cJSON_AddItemToArray(children, cJSON_CreateNumber(node->children[c]));
                if (separate) cJSON_AddItemToArray(children, cJSON_CreateNumber((double)extra_node++));
            }
            if (node->lod_count > 0) {
                lods = true;
                cJSON *ids = cJSON_AddArrayToObject(
                    cJSON_AddObjectToObject(cJSON_AddObjectToObject(json, "extensions"), "MSFT_lod"), "ids");
                for (size_t l = 0; l < node->lod_count; l++)
                    cJSON_AddItemToArray(ids, cJSON_CreateNumber(node->lod_nodes[l]));
            }
            if (node->extras) {
                cJSON *extras = cJSON_Parse(node->extras);
                if (extras) cJSON_AddItemToObject(json, "extras", extras);
            }
        }
        for (size_t i = 0; i < scene->node_count; i++) {
            const lk_scene_node *node = &scene->nodes[i];
            int32_t mesh = node->mesh >= 0 && (size_t)node->mesh < scene->mesh_count ? mesh_index[node->mesh] : -1;
            if (!(mesh >= 0 && on_grid[node->mesh] && (node->child_count > 0 || animated[i]))) continue;
            cJSON *json = cJSON_CreateObject();
            if (!json) goto nomem;
            cJSON_AddItemToArray(nodes, json);
            lk_scene_node plain;
            lk__scene_node_init(&plain);
            add_transform(json, &plain, &grids[node->mesh]);
            cJSON_AddNumberToObject(json, "mesh", mesh);
        }
        if (lods) add_unique_name(used, "MSFT_lod");
        cJSON *roots = cJSON_AddArrayToObject(scene_json, "nodes");
        for (size_t r = 0; r < scene->root_count; r++) cJSON_AddItemToArray(roots, cJSON_CreateNumber(scene->roots[r]));
        if (scene->root_count == 0) cJSON_DeleteItemFromObject(scene_json, "nodes");
    }

    if (!lk__gltf_add_skins(&writer, root, scene, quantize ? skin_grids : NULL) ||
        !lk__gltf_add_animations(&writer, root, scene))
        goto nomem;

    size_t bad = 0;
    if (scene->material_count && !add_json_objects(root, "materials", &scene->materials[0].json, scene->material_count,
                                                   sizeof(lk_scene_material), &bad)) {
        status = lk_error_set(error, LK_ERR_INVALID, "materials[%zu]: its JSON does not parse as an object", bad);
        goto done;
    }
    if (scene->texture_count && !add_json_objects(root, "textures", &scene->textures[0].json, scene->texture_count,
                                                  sizeof(lk_scene_texture), &bad)) {
        status = lk_error_set(error, LK_ERR_INVALID, "textures[%zu]: its JSON does not parse as an object", bad);
        goto done;
    }
    if (!add_json_objects(root, "samplers", scene->samplers, scene->sampler_count, sizeof(char *), &bad)) {
        status = lk_error_set(error, LK_ERR_INVALID, "samplers[%zu]: its JSON does not parse as an object", bad);
        goto done;
    }
    if (!add_json_objects(root, "cameras", scene->cameras, scene->camera_count, sizeof(char *), &bad)) {
        status = lk_error_set(error, LK_ERR_INVALID, "cameras[%zu]: its JSON does not parse as an object", bad);
        goto done;
    }
    static const char *const kept[] = {"materials", "textures", "samplers", "cameras"};
    for (size_t k = 0; k < sizeof kept / sizeof kept[0]; k++)
        collect_extensions(cJSON_GetObjectItem(root, kept[k]), used);
    for (size_t i = 0; i < scene->required_extension_count; i++) {
        const cJSON *item;
        cJSON_ArrayForEach(item, used)
        {
            if (strcmp(item->valuestring, scene->required_extensions[i]) == 0)
                add_unique_name(required, scene->required_extensions[i]);
        }
    }
    if (writer.failed) goto nomem;
    if (cJSON_GetArraySize(writer.accessors) == 0) cJSON_DeleteItemFromObject(root, "accessors");
    if (!lk__gltf_hoist_skinned_meshes(root)) goto nomem;
    status = emit(&writer, root, used, required, scene, file, path, binary, error);
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "out of memory while building the glTF");
done:
    lk__buffer_free(&writer.bin);
    free(writer.records);
    free(mesh_index);
    free(grids);
    free(on_grid);
    free(skinned_on_grid);
    free(skin_grids);
    free(animated);
    free(material_use);
    for (size_t w = 0; w < written_count; w++) free(written[w].generated_tangents);
    free(written);
    free(written_table);
    cJSON_Delete(root);
    return status;
}
