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
 * Compact output (lk_write_options.gltf_flags):
 *   - LK_GLTF_QUANTIZE (KHR_mesh_quantization): positions as 14-bit
 *     integers on a uniform grid over the bounding box, the node's scale and
 *     translation mapping them back (error at most half a step, 1/32766 of
 *     the longest side); normals as 8-bit normalised bytes; texture
 *     coordinates in [0, 1] on a 12-bit grid as normalised shorts (others
 *     stay floats); colours as bytes;
 *   - LK_GLTF_MESHOPT (EXT_meshopt_compression): every bufferView encoded
 *     with meshoptimizer's vertex and index codecs (Debian's
 *     libmeshoptimizer), after reordering triangles for the vertex cache and
 *     vertices in first-use order (what makes the codecs effective); the
 *     uncompressed views live in a fallback buffer without data, so the
 *     extension is required. */
#include "bytes.h"
#include "io_gltf.h"

#include <meshoptimizer.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TARGET_ARRAY_BUFFER 34962
#define TARGET_ELEMENT_ARRAY_BUFFER 34963
#define GLB_MAGIC 0x46546C67u /* "glTF" */
#define GLB_CHUNK_JSON 0x4E4F534Au
#define GLB_CHUNK_BIN 0x004E4942u

/* A bufferView written so far: what EXT_meshopt_compression needs. */
typedef struct view_record {
    cJSON *json;
    size_t offset, bytes, stride, count;
    unsigned index_size; /* 0: vertex attributes */
} view_record;

typedef struct mesh_writer {
    lk__buffer bin;
    cJSON *views, *accessors;
    size_t accessor_count;
    view_record *records;
    size_t record_count, record_capacity;
    uint64_t flags; /* lk_write_options.gltf_flags */
    bool quantized; /* some attribute is not float: KHR_mesh_quantization */
    bool failed;
} mesh_writer;

/* Reserves `bytes` at the end of the buffer, after padding it to 4 bytes;
 * returns the offset (writer->failed on allocation failure). */
static size_t reserve_section(mesh_writer *writer, size_t bytes)
{
    while (writer->bin.size % 4) {
        if (!lk__buffer_reserve(&writer->bin, 1)) {
            writer->failed = true;
            return 0;
        }
        writer->bin.data[writer->bin.size++] = 0;
    }
    if (!lk__buffer_reserve(&writer->bin, bytes)) {
        writer->failed = true;
        return 0;
    }
    size_t offset = writer->bin.size;
    writer->bin.size += bytes;
    return offset;
}

/* A bufferView over [offset, offset + bytes) and an accessor of `count`
 * elements on it; returns the accessor's JSON (NULL on failure). */
static cJSON *add_accessor(mesh_writer *writer, size_t offset, size_t bytes, size_t stride, int target,
                           int component_type, bool normalized, size_t count, const char *type)
{
    cJSON *view = cJSON_CreateObject(), *accessor = cJSON_CreateObject();
    if (!view || !accessor) {
        cJSON_Delete(view);
        cJSON_Delete(accessor);
        writer->failed = true;
        return NULL;
    }
    cJSON_AddItemToArray(writer->views, view);
    cJSON_AddNumberToObject(view, "buffer", 0);
    cJSON_AddNumberToObject(view, "byteOffset", (double)offset);
    cJSON_AddNumberToObject(view, "byteLength", (double)bytes);
    size_t components = type[0] == 'V' ? (size_t)(type[3] - '0') : 1; /* "VEC3" or "SCALAR" */
    size_t component_size = component_type == COMPONENT_FLOAT || component_type == COMPONENT_UNSIGNED_INT     ? 4
                            : component_type == COMPONENT_SHORT || component_type == COMPONENT_UNSIGNED_SHORT ? 2
                                                                                                              : 1;
    size_t element = components * component_size;
    if (target == TARGET_ARRAY_BUFFER && (stride != element || (writer->flags & LK_GLTF_MESHOPT)))
        cJSON_AddNumberToObject(view, "byteStride", (double)stride);
    cJSON_AddNumberToObject(view, "target", target);
    if (writer->record_count == writer->record_capacity) {
        size_t capacity = writer->record_capacity ? 2 * writer->record_capacity : 16;
        view_record *records = lk__realloc_array(writer->records, capacity, sizeof(view_record));
        if (!records) {
            cJSON_Delete(accessor);
            writer->failed = true;
            return NULL;
        }
        writer->records = records;
        writer->record_capacity = capacity;
    }
    writer->records[writer->record_count++] = (view_record){
        view,
        offset,
        bytes,
        stride,
        count,
        target == TARGET_ELEMENT_ARRAY_BUFFER ? (unsigned)(component_type == COMPONENT_UNSIGNED_INT ? 4 : 2) : 0};
    cJSON_AddItemToArray(writer->accessors, accessor);
    cJSON_AddNumberToObject(accessor, "bufferView", (double)cJSON_GetArraySize(writer->views) - 1);
    cJSON_AddNumberToObject(accessor, "componentType", component_type);
    if (normalized) cJSON_AddBoolToObject(accessor, "normalized", true);
    cJSON_AddNumberToObject(accessor, "count", (double)count);
    cJSON_AddStringToObject(accessor, "type", type);
    writer->accessor_count++;
    return accessor;
}

/* `count` elements of `components` floats; min/max when with_bounds. Returns
 * the accessor index. */
static size_t add_floats(mesh_writer *writer, const float *values, size_t count, unsigned components, const char *type,
                         bool with_bounds)
{
    size_t bytes = count * components * 4, offset = reserve_section(writer, bytes);
    if (writer->failed) return 0;
    double low[4], high[4];
    for (unsigned c = 0; c < components; c++) low[c] = high[c] = values[c];
    for (size_t i = 0; i < count * components; i++) {
        lk__store_f32le(writer->bin.data + offset + 4 * i, values[i]);
        unsigned c = (unsigned)(i % components);
        if (values[i] < low[c]) low[c] = values[i];
        if (values[i] > high[c]) high[c] = values[i];
    }
    cJSON *accessor =
        add_accessor(writer, offset, bytes, 4 * components, TARGET_ARRAY_BUFFER, COMPONENT_FLOAT, false, count, type);
    if (accessor && with_bounds) {
        cJSON *min = cJSON_AddArrayToObject(accessor, "min"), *max = cJSON_AddArrayToObject(accessor, "max");
        for (unsigned c = 0; c < components; c++) {
            /* The float's own value: the validator compares the bounds
             * with the stored floats exactly. */
            cJSON_AddItemToArray(min, cJSON_CreateNumber((double)(float)low[c]));
            cJSON_AddItemToArray(max, cJSON_CreateNumber((double)(float)high[c]));
        }
    }
    return writer->accessor_count - 1;
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
    size_t offset = reserve_section(writer, 4 * count);
    if (writer->failed) return 0;
    for (size_t i = 0; i < 4 * count; i++)
        writer->bin.data[offset + i] = (unsigned char)lroundf(clamp01(mesh->colors[i]) * 255.0f);
    add_accessor(writer, offset, 4 * count, 4, TARGET_ARRAY_BUFFER, COMPONENT_UNSIGNED_BYTE, true, count, "VEC4");
    writer->quantized = true;
    return writer->accessor_count - 1;
}

/* KHR_mesh_quantization: positions as 14-bit unsigned shorts (padded to 8
 * bytes) on a uniform grid; the node's translation and scale map them
 * back. */
#define POSITION_BITS 14
#define TEXCOORD_BITS 12

static size_t add_quantized_positions(mesh_writer *writer, const lk_mesh *mesh, cJSON *node)
{
    size_t count = mesh->vertex_count;
    double low[3], high[3];
    for (int k = 0; k < 3; k++) low[k] = high[k] = mesh->positions[k];
    for (size_t i = 0; i < 3 * count; i++) {
        int k = (int)(i % 3);
        if (mesh->positions[i] < low[k]) low[k] = mesh->positions[i];
        if (mesh->positions[i] > high[k]) high[k] = mesh->positions[i];
    }
    double extent = fmax(high[0] - low[0], fmax(high[1] - low[1], high[2] - low[2]));
    const double steps = (double)((1u << POSITION_BITS) - 1);
    /* The node's values as the file stores them (floats), so that decoding
     * uses exactly these. */
    float origin[3] = {(float)low[0], (float)low[1], (float)low[2]};
    float scale = extent > 0 ? (float)(extent / steps) : 1.0f;
    size_t offset = reserve_section(writer, 8 * count);
    if (writer->failed) return 0;
    unsigned q_low[3] = {65535, 65535, 65535}, q_high[3] = {0, 0, 0};
    for (size_t v = 0; v < count; v++) {
        unsigned char *out = writer->bin.data + offset + 8 * v;
        for (int k = 0; k < 3; k++) {
            double q = round(((double)mesh->positions[3 * v + (size_t)k] - origin[k]) / scale);
            unsigned value = q < 0 ? 0 : q > 65535 ? 65535 : (unsigned)q;
            lk__store_u16le(out + 2 * k, (uint16_t)value);
            if (value < q_low[k]) q_low[k] = value;
            if (value > q_high[k]) q_high[k] = value;
        }
        lk__store_u16le(out + 6, 0);
    }
    cJSON *accessor =
        add_accessor(writer, offset, 8 * count, 8, TARGET_ARRAY_BUFFER, COMPONENT_UNSIGNED_SHORT, false, count, "VEC3");
    if (!accessor) return 0;
    cJSON *min = cJSON_AddArrayToObject(accessor, "min"), *max = cJSON_AddArrayToObject(accessor, "max");
    cJSON *translation = cJSON_AddArrayToObject(node, "translation"),
          *node_scale = cJSON_AddArrayToObject(node, "scale");
    for (int k = 0; k < 3; k++) {
        cJSON_AddItemToArray(min, cJSON_CreateNumber(q_low[k]));
        cJSON_AddItemToArray(max, cJSON_CreateNumber(q_high[k]));
        cJSON_AddItemToArray(translation, cJSON_CreateNumber(origin[k]));
        cJSON_AddItemToArray(node_scale, cJSON_CreateNumber(scale));
    }
    writer->quantized = true;
    return writer->accessor_count - 1;
}

/* Unit normals as normalised signed bytes, padded to 4 bytes. */
static size_t add_quantized_normals(mesh_writer *writer, const float *normals, size_t count)
{
    size_t offset = reserve_section(writer, 4 * count);
    if (writer->failed) return 0;
    for (size_t v = 0; v < count; v++) {
        unsigned char *out = writer->bin.data + offset + 4 * v;
        for (int k = 0; k < 3; k++) {
            long q = lroundf(normals[3 * v + (size_t)k] * 127.0f);
            out[k] = (unsigned char)(int8_t)(q < -127 ? -127 : q > 127 ? 127 : q);
        }
        out[3] = 0;
    }
    add_accessor(writer, offset, 4 * count, 4, TARGET_ARRAY_BUFFER, COMPONENT_BYTE, true, count, "VEC3");
    writer->quantized = true;
    return writer->accessor_count - 1;
}

/* Texture coordinates in [0, 1] (already flipped) on a 12-bit grid, as
 * normalised unsigned shorts; SIZE_MAX when one is outside (then floats). */
static size_t add_quantized_texcoords(mesh_writer *writer, const float *texcoords, size_t count)
{
    for (size_t i = 0; i < 2 * count; i++)
        if (!(texcoords[i] >= 0 && texcoords[i] <= 1)) return SIZE_MAX;
    size_t offset = reserve_section(writer, 4 * count);
    if (writer->failed) return 0;
    const double steps = (double)((1u << TEXCOORD_BITS) - 1);
    for (size_t i = 0; i < 2 * count; i++) {
        double on_grid = round(texcoords[i] * steps) / steps;
        lk__store_u16le(writer->bin.data + offset + 2 * i, (uint16_t)lround(on_grid * 65535.0));
    }
    add_accessor(writer, offset, 4 * count, 4, TARGET_ARRAY_BUFFER, COMPONENT_UNSIGNED_SHORT, true, count, "VEC2");
    writer->quantized = true;
    return writer->accessor_count - 1;
}

static size_t add_indices(mesh_writer *writer, const lk_mesh *mesh)
{
    size_t count = 3 * mesh->triangle_count;
    /* meshopt's index codec takes 16 or 32-bit indices */
    int type = mesh->vertex_count <= 0xFF && !(writer->flags & LK_GLTF_MESHOPT) ? COMPONENT_UNSIGNED_BYTE
               : mesh->vertex_count <= 0xFFFF                                   ? COMPONENT_UNSIGNED_SHORT
                                                                                : COMPONENT_UNSIGNED_INT;
    size_t size = type == COMPONENT_UNSIGNED_BYTE ? 1 : type == COMPONENT_UNSIGNED_SHORT ? 2 : 4;
    size_t offset = reserve_section(writer, count * size);
    if (writer->failed) return 0;
    unsigned char *out = writer->bin.data + offset;
    for (size_t i = 0; i < count; i++) {
        uint32_t index = mesh->indices[i];
        if (size == 1)
            out[i] = (unsigned char)index;
        else if (size == 2)
            lk__store_u16le(out + 2 * i, (uint16_t)index);
        else
            lk__store_u32le(out + 4 * i, index);
    }
    add_accessor(writer, offset, count * size, size, TARGET_ELEMENT_ARRAY_BUFFER, type, false, count, "SCALAR");
    return writer->accessor_count - 1;
}

/* The file name of `path` without its folder, extension replaced by .bin
 * (the .gltf's buffer), and the same next to `path`. */
static lk_status bin_names(const char *path, char **bin_path, char **bin_uri, lk_error *error)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t stem = dot ? (size_t)(dot - path) : strlen(path);
    *bin_path = malloc(stem + 5);
    /* A URI: percent-encode everything but unreserved characters. */
    size_t base_stem = stem - (size_t)(base - path);
    *bin_uri = malloc(3 * base_stem + 5);
    if (!*bin_path || !*bin_uri) {
        free(*bin_path), free(*bin_uri);
        *bin_path = *bin_uri = NULL;
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    memcpy(*bin_path, path, stem);
    strcpy(*bin_path + stem, ".bin");
    size_t used = 0;
    for (size_t i = 0; i < base_stem; i++) {
        unsigned char c = (unsigned char)base[i];
        bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' ||
                     c == '_' || c == '.' || c == '~';
        if (plain) {
            (*bin_uri)[used++] = (char)c;
        } else {
            static const char hex[] = "0123456789ABCDEF";
            (*bin_uri)[used++] = '%';
            (*bin_uri)[used++] = hex[c >> 4];
            (*bin_uri)[used++] = hex[c & 15];
        }
    }
    strcpy(*bin_uri + used, ".bin");
    return LK_OK;
}

static bool write_u32(FILE *file, uint32_t value)
{
    unsigned char bytes[4];
    lk__store_u32le(bytes, value);
    return fwrite(bytes, 1, 4, file) == 4;
}

/* A copy of `mesh` reordered for meshopt's codecs: triangles for the
 * vertex cache, vertices in order of first use (meshoptimizer's
 * optimizeVertexCache and optimizeVertexFetchRemap). */
static bool reorder_for_codecs(const lk_mesh *mesh, lk_mesh *out)
{
    lk_mesh_init(out);
    size_t vertex_count = mesh->vertex_count, index_count = 3 * mesh->triangle_count;
    unsigned flags = (mesh->normals ? LK_ATTR_NORMALS : 0) | (mesh->texcoords ? LK_ATTR_TEXCOORDS : 0) |
                     (mesh->colors ? LK_ATTR_COLORS : 0);
    unsigned int *remap = lk__malloc_array(vertex_count, sizeof(unsigned int));
    if (!remap || lk_mesh_alloc(out, vertex_count, mesh->triangle_count, flags, NULL) != LK_OK) {
        free(remap);
        lk_mesh_free(out);
        return false;
    }
    meshopt_optimizeVertexCache(out->indices, mesh->indices, index_count, vertex_count);
    size_t used = meshopt_optimizeVertexFetchRemap(remap, out->indices, index_count, vertex_count);
    meshopt_remapIndexBuffer(out->indices, out->indices, index_count, remap);
    /* Unused vertices (remap ~0) go after the used ones, in their order. */
    for (size_t v = 0; v < vertex_count; v++)
        if (remap[v] == ~0u) remap[v] = (unsigned int)used++;
    meshopt_remapVertexBuffer(out->positions, mesh->positions, vertex_count, 3 * sizeof(float), remap);
    if (mesh->normals) meshopt_remapVertexBuffer(out->normals, mesh->normals, vertex_count, 3 * sizeof(float), remap);
    if (mesh->texcoords)
        meshopt_remapVertexBuffer(out->texcoords, mesh->texcoords, vertex_count, 2 * sizeof(float), remap);
    if (mesh->colors) meshopt_remapVertexBuffer(out->colors, mesh->colors, vertex_count, 4 * sizeof(float), remap);
    free(remap);
    return true;
}

/* Adds `mesh` as a glTF mesh of one primitive (and, for quantised
 * positions, their transform to `node`); returns false on failure. */
static bool add_mesh(mesh_writer *writer, cJSON *meshes, cJSON *node, const lk_mesh *input,
                     const lk_write_options *options)
{
    lk_mesh reordered;
    lk_mesh_init(&reordered);
    const lk_mesh *mesh = input;
    if ((writer->flags & LK_GLTF_MESHOPT) && input->triangle_count) {
        if (!reorder_for_codecs(input, &reordered)) return false;
        mesh = &reordered;
    }
    bool quantize = (writer->flags & LK_GLTF_QUANTIZE) != 0, ok = false;
    size_t vertex_count = mesh->vertex_count;
    float *scratch = NULL;
    cJSON *gltf_mesh = cJSON_CreateObject();
    if (!gltf_mesh) goto done;
    cJSON_AddItemToArray(meshes, gltf_mesh);
    cJSON *primitive = cJSON_CreateObject();
    cJSON_AddItemToArray(cJSON_AddArrayToObject(gltf_mesh, "primitives"), primitive);
    cJSON *attributes = cJSON_AddObjectToObject(primitive, "attributes");
    if (!attributes) goto done;
    cJSON_AddNumberToObject(attributes, "POSITION",
                            quantize ? (double)add_quantized_positions(writer, mesh, node)
                                     : (double)add_floats(writer, mesh->positions, vertex_count, 3, "VEC3", true));
    if (mesh->normals && !options->skip_normals) {
        scratch = unit_normals(mesh);
        if (!scratch) goto done;
        cJSON_AddNumberToObject(attributes, "NORMAL",
                                quantize ? (double)add_quantized_normals(writer, scratch, vertex_count)
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
    if (mesh->colors && !options->skip_colors)
        cJSON_AddNumberToObject(attributes, "COLOR_0", (double)add_colors(writer, mesh));
    if (mesh->triangle_count) {
        cJSON_AddNumberToObject(primitive, "indices", (double)add_indices(writer, mesh));
        cJSON_AddNumberToObject(primitive, "mode", MODE_TRIANGLES);
    } else {
        cJSON_AddNumberToObject(primitive, "mode", MODE_POINTS);
    }
    ok = !writer->failed;
done:
    free(scratch);
    lk_mesh_free(&reordered);
    return ok;
}

/* EXT_meshopt_compression: every view recorded so far encoded into
 * `packed`; the views move to buffer 1 (the fallback without data) and
 * name their compressed bytes in buffer 0. */
static bool compress_views(mesh_writer *writer, lk__buffer *packed)
{
    for (size_t i = 0; i < writer->record_count; i++) {
        const view_record *record = &writer->records[i];
        const unsigned char *source = writer->bin.data + record->offset;
        size_t bound = record->index_size ? meshopt_encodeIndexBufferBound(record->count, UINT32_MAX / 2)
                                          : meshopt_encodeVertexBufferBound(record->count, record->stride);
        while (packed->size % 4) {
            if (!lk__buffer_reserve(packed, 1)) return false;
            packed->data[packed->size++] = 0;
        }
        if (!lk__buffer_reserve(packed, bound)) return false;
        size_t written;
        if (record->index_size) {
            unsigned int *indices = lk__malloc_array(record->count, sizeof(unsigned int));
            if (!indices) return false;
            for (size_t k = 0; k < record->count; k++)
                indices[k] = record->index_size == 2 ? lk__load_u16le(source + 2 * k) : lk__load_u32le(source + 4 * k);
            written = meshopt_encodeIndexBuffer(packed->data + packed->size, bound, indices, record->count);
            free(indices);
        } else {
            written =
                meshopt_encodeVertexBuffer(packed->data + packed->size, bound, source, record->count, record->stride);
        }
        if (written == 0) return false;
        cJSON *extension = cJSON_CreateObject();
        if (!extension) return false;
        cJSON_AddNumberToObject(extension, "buffer", 0);
        cJSON_AddNumberToObject(extension, "byteOffset", (double)packed->size);
        cJSON_AddNumberToObject(extension, "byteLength", (double)written);
        cJSON_AddNumberToObject(extension, "byteStride",
                                (double)(record->index_size ? record->index_size : record->stride));
        cJSON_AddStringToObject(extension, "mode", record->index_size ? "TRIANGLES" : "ATTRIBUTES");
        cJSON_AddNumberToObject(extension, "count", (double)record->count);
        cJSON_AddItemToObject(cJSON_AddObjectToObject(record->json, "extensions"), "EXT_meshopt_compression",
                              extension);
        cJSON_ReplaceItemInObject(record->json, "buffer", cJSON_CreateNumber(1));
        packed->size += written;
    }
    return true;
}

/* Levels of detail (MSFT_lod): node 0, in the scene, holds level 0; nodes
 * 1..n-1 hold the coarser levels and are listed in node 0's MSFT_lod ids;
 * node 0's extras carry MSFT_screencoverage (one value per level) and each
 * node's extras lodkit's numbers for its level. One level: a plain node. */
lk_status lk__write_gltf_levels(FILE *file, const char *path, bool binary, const lk_mesh *levels, size_t level_count,
                                const lk_lod_level_info *info, const lk_write_options *options, lk_error *error)
{
    mesh_writer writer;
    memset(&writer, 0, sizeof writer);
    writer.flags = options->gltf_flags;
    if (writer.flags & ~(uint64_t)(LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT))
        return lk_error_set(error, LK_ERR_INVALID, "unknown glTF flags 0x%llx", (unsigned long long)writer.flags);
    lk__buffer packed = {0};
    const lk__buffer *data = &writer.bin; /* what the file holds: the views, or packed */
    cJSON *root = cJSON_CreateObject();
    char *text = NULL, *bin_path = NULL, *bin_uri = NULL;
    lk_status status = LK_OK;
    if (!root) goto nomem;
    cJSON *asset = cJSON_AddObjectToObject(root, "asset");
    cJSON_AddStringToObject(asset, "version", "2.0");
    cJSON_AddStringToObject(asset, "generator", "lodkit " LK_VERSION_STRING);
    cJSON *used = cJSON_AddArrayToObject(root, "extensionsUsed");
    cJSON *required = cJSON_AddArrayToObject(root, "extensionsRequired");
    cJSON_AddNumberToObject(root, "scene", 0);
    cJSON *scene = cJSON_CreateObject();
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene);
    if (level_count > 0 && levels[0].vertex_count > 0) {
        cJSON_AddItemToArray(cJSON_AddArrayToObject(scene, "nodes"), cJSON_CreateNumber(0));
        cJSON *nodes = cJSON_AddArrayToObject(root, "nodes"), *meshes = cJSON_AddArrayToObject(root, "meshes");
        writer.accessors = cJSON_AddArrayToObject(root, "accessors");
        writer.views = cJSON_AddArrayToObject(root, "bufferViews");
        if (!nodes || !meshes || !writer.accessors || !writer.views) goto nomem;
        cJSON *coverage = NULL, *ids = NULL;
        for (size_t level = 0; level < level_count; level++) {
            if (levels[level].vertex_count == 0) {
                status = lk_error_set(error, LK_ERR_INVALID, "level %zu of detail is empty", level);
                goto done;
            }
            cJSON *node = cJSON_CreateObject();
            if (!node) goto nomem;
            cJSON_AddItemToArray(nodes, node);
            cJSON_AddNumberToObject(node, "mesh", (double)level);
            if (!add_mesh(&writer, meshes, node, &levels[level], options)) goto nomem;
            if (level_count == 1) continue;
            if (level == 0) {
                ids = cJSON_AddArrayToObject(
                    cJSON_AddObjectToObject(cJSON_AddObjectToObject(node, "extensions"), "MSFT_lod"), "ids");
                cJSON *extras = cJSON_AddObjectToObject(node, "extras");
                coverage = cJSON_AddArrayToObject(extras, "MSFT_screencoverage");
            } else {
                cJSON_AddItemToArray(ids, cJSON_CreateNumber((double)level));
            }
            cJSON_AddItemToArray(coverage, cJSON_CreateNumber(info ? info[level].screen_coverage : 0));
            cJSON *extras = level == 0 ? cJSON_GetObjectItem(node, "extras") : cJSON_AddObjectToObject(node, "extras");
            cJSON *ours = cJSON_AddObjectToObject(extras, "lodkit");
            cJSON_AddNumberToObject(ours, "level", (double)level);
            cJSON_AddNumberToObject(ours, "triangles", (double)levels[level].triangle_count);
            if (info) cJSON_AddNumberToObject(ours, "error", info[level].error);
        }
        if (writer.failed) goto nomem;
        if (level_count > 1) cJSON_AddItemToArray(used, cJSON_CreateString("MSFT_lod"));
        if (writer.quantized) {
            cJSON_AddItemToArray(used, cJSON_CreateString("KHR_mesh_quantization"));
            cJSON_AddItemToArray(required, cJSON_CreateString("KHR_mesh_quantization"));
        }
        cJSON *buffers = cJSON_AddArrayToObject(root, "buffers");
        cJSON *buffer = cJSON_CreateObject();
        cJSON_AddItemToArray(buffers, buffer);
        if (writer.flags & LK_GLTF_MESHOPT) {
            if (!compress_views(&writer, &packed)) goto nomem;
            data = &packed;
            cJSON_AddItemToArray(used, cJSON_CreateString("EXT_meshopt_compression"));
            cJSON_AddItemToArray(required, cJSON_CreateString("EXT_meshopt_compression"));
            cJSON *fallback = cJSON_CreateObject();
            cJSON_AddItemToArray(buffers, fallback);
            cJSON_AddNumberToObject(fallback, "byteLength", (double)writer.bin.size);
            cJSON_AddBoolToObject(
                cJSON_AddObjectToObject(cJSON_AddObjectToObject(fallback, "extensions"), "EXT_meshopt_compression"),
                "fallback", true);
        }
        cJSON_AddNumberToObject(buffer, "byteLength", (double)data->size);
        if (!binary) {
            status = bin_names(path, &bin_path, &bin_uri, error);
            if (status != LK_OK) goto done;
            cJSON_AddStringToObject(buffer, "uri", bin_uri);
        }
    }
    /* glTF wants no empty extension lists */
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
    if (bin_path) {
        /* The buffer first, whole or not at all; then the JSON naming it. */
        lk__atomic_file bin;
        status = lk__atomic_open(&bin, bin_path, error);
        if (status != LK_OK) goto done;
        if (fwrite(data->data, 1, data->size, bin.file) != data->size) {
            lk_error_set(error, LK_ERR_IO, "%s: write error", bin_path);
            status = lk__atomic_fail(&bin, error);
            goto done;
        }
        status = lk__atomic_commit(&bin, error);
        if (status != LK_OK) goto done;
    }
    if (fwrite(text, 1, text_length, file) != text_length || fputc('\n', file) == EOF || ferror(file))
        status = lk_error_set(error, LK_ERR_IO, "write error");
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "out of memory while building the glTF");
done:
    free(text);
    free(bin_path);
    free(bin_uri);
    lk__buffer_free(&writer.bin);
    lk__buffer_free(&packed);
    free(writer.records);
    cJSON_Delete(root);
    return status;
}

lk_status lk__write_gltf_mesh(FILE *file, const char *path, bool binary, const lk_mesh *mesh,
                              const lk_write_options *options, lk_error *error)
{
    return lk__write_gltf_levels(file, path, binary, mesh, 1, NULL, options, error);
}
