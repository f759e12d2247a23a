/* glTF 2.0 reader: .gltf (JSON with external or data: URI buffers) and .glb
 * (binary container with an embedded BIN chunk).
 *
 * What is read: the triangles (modes TRIANGLES, TRIANGLE_STRIP and
 * TRIANGLE_FAN) and points of every mesh instanced by the default scene,
 * with the node transforms applied, concatenated into one mesh with the
 * attributes POSITION, NORMAL, TEXCOORD_0 and COLOR_0. Lines, materials,
 * animations, skins (meshes stay in their bind pose) and morph targets are
 * ignored. cJSON parses the JSON; the GLB container, base64, accessors and
 * the scene graph are handled here.
 *
 * Every count and offset in the JSON is checked against the bytes really
 * available (64-bit arithmetic, JSON integers limited to 2^53 so nothing
 * overflows) before it is used, and errors name the JSON location, e.g.
 * "model.gltf: accessors[3]: count 12 exceeds bufferView 1 (96 bytes)". */
#include "anim_io.h"
#include "bytes.h"

#include <cjson/cJSON.h>

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define GLB_HEADER_SIZE 12u
#define GLB_CHUNK_HEADER_SIZE 8u
#define GLB_CHUNK_JSON 0x4E4F534Au /* "JSON" little-endian */
#define GLB_CHUNK_BIN 0x004E4942u  /* "BIN\0" little-endian */

/* JSON numbers are doubles: integers above 2^53 are not exact, so refuse
 * them. This also keeps every offset computation far below 2^64. */
#define JSON_MAX_INTEGER 9007199254740992.0

enum {
    COMPONENT_BYTE = 5120,
    COMPONENT_UNSIGNED_BYTE = 5121,
    COMPONENT_SHORT = 5122,
    COMPONENT_UNSIGNED_SHORT = 5123,
    COMPONENT_UNSIGNED_INT = 5125,
    COMPONENT_FLOAT = 5126
};

enum {
    MODE_POINTS = 0,
    MODE_LINES = 1,
    MODE_LINE_LOOP = 2,
    MODE_LINE_STRIP = 3,
    MODE_TRIANGLES = 4,
    MODE_TRIANGLE_STRIP = 5,
    MODE_TRIANGLE_FAN = 6
};

/* Bit masks of accepted accessor types (bit = number of components). */
#define TYPE_SCALAR (1u << 1)
#define TYPE_VEC2 (1u << 2)
#define TYPE_VEC3 (1u << 3)
#define TYPE_VEC4 (1u << 4)
#define TYPE_MAT4 (1u << 16) /* only where asked for: 16 components */

typedef struct gltf_buffer {
    bool loaded;
    const unsigned char *data; /* byteLength bytes */
    size_t size;               /* byteLength, checked against the real data */
    unsigned char *owned;      /* decoded data: URI or external file, else NULL */
} gltf_buffer;

/* A top-level JSON array turned into a pointer vector: cJSON arrays are
 * linked lists, and indexing them for every reference would be quadratic. */
typedef struct json_table {
    const cJSON **items;
    size_t count;
    size_t allocated; /* items charged to the budget */
} json_table;

typedef struct gltf_reader {
    const lk__read_context *ctx;
    lk_error *error;
    const cJSON *root;
    json_table accessors, buffer_views, buffers_json, meshes, nodes, scenes;

    /* GLB BIN chunk (buffer 0 without uri), if any. */
    bool is_glb;
    bool has_bin_chunk;
    const unsigned char *bin_chunk;
    size_t bin_chunk_size;

    gltf_buffer *buffers; /* buffers_json.count entries, loaded on first use */
    size_t buffer_bytes;  /* decoded data: URIs and external files held so far */
    size_t json_bytes;    /* the parsed JSON tree's charge to the budget */

    /* Output, grown primitive by primitive (charged to the budget). */
    lk__buffer positions, normals, texcoords, colors, indices;
    size_t vertex_count, triangle_count;
    bool has_normals, has_texcoords, has_colors;
    size_t skipped_line_primitives;

    /* Animation reading: where each primitive's vertices went. */
    bool record_instances;
    size_t current_mesh;
    lk__buffer instances; /* gltf_instance */
} gltf_reader;

/* One primitive instanced by one node: its vertices are
 * [base, base + count) of the output. */
typedef struct gltf_instance {
    const cJSON *primitive;
    size_t mesh;
    size_t node; /* SIZE_MAX when the mesh is not in a node */
    size_t base, count;
} gltf_instance;

/* A validated accessor, ready to be decoded element by element. */
typedef struct gltf_accessor {
    size_t index;               /* accessors[index], for messages */
    const unsigned char *data;  /* first element; NULL means all zeros (no bufferView) */
    size_t count;
    size_t stride;
    unsigned component_type;
    unsigned component_count;
    bool normalized;
} gltf_accessor;

/* ---- errors ------------------------------------------------------------ */

#if defined(__GNUC__)
__attribute__((format(printf, 5, 6)))
#endif
/* Sets "NAME: WHERE.KEY: message" (KEY may be NULL, WHERE may be ""). */
static lk_status fail(const gltf_reader *reader, lk_status status, const char *where, const char *key,
                      const char *format, ...)
{
    char message[400];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    const char *separator = where[0] && key && key[0] != '[' ? "." : "";
    return lk_error_set(reader->error, status, "%s: %s%s%s: %s", reader->ctx->name, where, separator,
                        key ? key : "", message);
}

static lk_status nomem(const gltf_reader *reader)
{
    return lk_error_set(reader->error, LK_ERR_NOMEM, "%s: out of memory", reader->ctx->name);
}

static lk_status over_budget(const gltf_reader *reader)
{
    return lk_error_set(reader->error, LK_ERR_LIMIT, "%s: the scene needs more than the memory budget of %zu bytes",
                        reader->ctx->name, reader->ctx->budget->limit);
}

/* Scratch arrays that grow with the document (per node, per table entry)
 * are charged to the read's budget: count * size bytes, zeroed, or NULL
 * with *status set. Free them with release(). */
static void *charged_calloc(const gltf_reader *reader, size_t count, size_t size, lk_status *status)
{
    if (!lk__budget_charge(reader->ctx->budget, count, size)) {
        *status = over_budget(reader);
        return NULL;
    }
    void *memory = lk__calloc_array(count, size);
    if (!memory) {
        lk__budget_release(reader->ctx->budget, count, size);
        *status = nomem(reader);
    }
    return memory;
}

static void release(const gltf_reader *reader, void *memory, size_t count, size_t size)
{
    if (!memory) return;
    free(memory);
    lk__budget_release(reader->ctx->budget, count, size);
}

static const char *json_type_name(const cJSON *item)
{
    if (cJSON_IsString(item)) return "a string";
    if (cJSON_IsNumber(item)) return "a number";
    if (cJSON_IsObject(item)) return "an object";
    if (cJSON_IsArray(item)) return "an array";
    if (cJSON_IsBool(item)) return "a boolean";
    if (cJSON_IsNull(item)) return "null";
    return "an invalid value";
}

/* ---- typed access to JSON members --------------------------------------- */

static const cJSON *member(const cJSON *object, const char *key)
{
    return cJSON_GetObjectItemCaseSensitive(object, key);
}

static bool is_json_uint(const cJSON *item)
{
    if (!cJSON_IsNumber(item)) return false;
    double value = item->valuedouble;
    return value >= 0.0 && value <= JSON_MAX_INTEGER && value == floor(value);
}

static lk_status check_uint(const gltf_reader *reader, const cJSON *item, const char *where, const char *key)
{
    if (!cJSON_IsNumber(item))
        return fail(reader, LK_ERR_PARSE, where, key, "expected a non-negative integer, got %s",
                    json_type_name(item));
    if (!is_json_uint(item))
        return fail(reader, LK_ERR_PARSE, where, key, "expected a non-negative integer, got %g", item->valuedouble);
    return LK_OK;
}

/* Optional (or required) non-negative integer member. */
static lk_status get_uint(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                          bool required, uint64_t default_value, uint64_t *out)
{
    const cJSON *item = member(object, key);
    *out = default_value;
    if (!item) {
        if (required) return fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"%s\"", key);
        return LK_OK;
    }
    lk_status status = check_uint(reader, item, where, key);
    if (status != LK_OK) return status;
    *out = (uint64_t)item->valuedouble;
    return LK_OK;
}

static lk_status get_number(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                            double default_value, double *out)
{
    const cJSON *item = member(object, key);
    *out = default_value;
    if (!item) return LK_OK;
    if (!cJSON_IsNumber(item))
        return fail(reader, LK_ERR_PARSE, where, key, "expected a number, got %s", json_type_name(item));
    if (!isfinite(item->valuedouble))
        return fail(reader, LK_ERR_RANGE, where, key, "number is not finite");
    *out = item->valuedouble;
    return LK_OK;
}

/* Optional member of a given cJSON type (cJSON_String, cJSON_Object, ...);
 * *out is NULL when absent. */
static lk_status get_typed(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                           int type, const char *type_name, const cJSON **out)
{
    const cJSON *item = member(object, key);
    *out = NULL;
    if (!item) return LK_OK;
    if ((item->type & 0xFF) != type)
        return fail(reader, LK_ERR_PARSE, where, key, "expected %s, got %s", type_name, json_type_name(item));
    *out = item;
    return LK_OK;
}

static lk_status get_object(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                            const cJSON **out)
{
    return get_typed(reader, object, where, key, cJSON_Object, "an object", out);
}

static lk_status get_array(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                           const cJSON **out)
{
    return get_typed(reader, object, where, key, cJSON_Array, "an array", out);
}

static lk_status get_string(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                            const cJSON **out)
{
    return get_typed(reader, object, where, key, cJSON_String, "a string", out);
}

static lk_status get_bool(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                          bool *out)
{
    const cJSON *item = member(object, key);
    *out = false;
    if (!item) return LK_OK;
    if (!cJSON_IsBool(item))
        return fail(reader, LK_ERR_PARSE, where, key, "expected true or false, got %s", json_type_name(item));
    *out = cJSON_IsTrue(item);
    return LK_OK;
}

/* Optional array of exactly `count` finite numbers; *present says whether
 * it was there (values untouched otherwise). */
static lk_status get_number_array(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                                  size_t count, double *values, bool *present)
{
    const cJSON *array;
    if (present) *present = false;
    lk_status status = get_array(reader, object, where, key, &array);
    if (status != LK_OK || !array) return status;
    size_t found = (size_t)cJSON_GetArraySize(array);
    if (found != count)
        return fail(reader, LK_ERR_PARSE, where, key, "expected %zu numbers, got %zu", count, found);
    size_t i = 0;
    const cJSON *item;
    cJSON_ArrayForEach(item, array) {
        if (!cJSON_IsNumber(item))
            return fail(reader, LK_ERR_PARSE, where, key, "element %zu: expected a number, got %s", i,
                        json_type_name(item));
        if (!isfinite(item->valuedouble))
            return fail(reader, LK_ERR_RANGE, where, key, "element %zu is not finite", i);
        values[i++] = item->valuedouble;
    }
    if (present) *present = true;
    return LK_OK;
}

static void table_free(const gltf_reader *reader, json_table *table)
{
    release(reader, table->items, table->allocated, sizeof *table->items);
    table->items = NULL;
    table->count = table->allocated = 0;
}

/* Turns an optional top-level array of objects into a table. */
static lk_status build_table(gltf_reader *reader, const char *key, json_table *table)
{
    const cJSON *array;
    table->items = NULL;
    table->count = table->allocated = 0;
    lk_status status = get_array(reader, reader->root, "", key, &array);
    if (status != LK_OK || !array) return status;
    size_t count = (size_t)cJSON_GetArraySize(array);
    table->items = charged_calloc(reader, count, sizeof *table->items, &status);
    if (!table->items) return status;
    table->allocated = count;
    const cJSON *item;
    cJSON_ArrayForEach(item, array) {
        if (!cJSON_IsObject(item))
            return fail(reader, LK_ERR_PARSE, "", key, "element %zu: expected an object, got %s", table->count,
                        json_type_name(item));
        table->items[table->count++] = item;
    }
    return LK_OK;
}

/* Resolves a reference `WHERE.KEY: index` into `table`, which is the
 * top-level array `table_name` ("accessors"); `what` is one element
 * ("accessor"). */
static lk_status resolve(const gltf_reader *reader, const json_table *table, const char *what,
                         const char *table_name, uint64_t index, const char *where, const char *key,
                         const cJSON **out)
{
    *out = NULL;
    if (index >= table->count)
        return fail(reader, LK_ERR_RANGE, where, key, "%s %llu out of range (%zu %s)", what,
                    (unsigned long long)index, table->count, table_name);
    *out = table->items[index];
    return LK_OK;
}

/* ---- document-level checks ---------------------------------------------- */

/* Extensions listed in extensionsRequired that do not change geometry
 * (materials, textures, lights) or whose geometry we read anyway
 * (quantized attributes use the component types we already decode). */
static bool extension_is_harmless(const char *name)
{
    static const char *const prefixes[] = {"KHR_materials_", "KHR_texture_", "EXT_texture_"};
    static const char *const names[] = {"KHR_mesh_quantization", "KHR_lights_punctual", "KHR_technique_webgl",
                                        "KHR_xmp_json_ld", "EXT_lights_image_based"};
    for (size_t i = 0; i < sizeof prefixes / sizeof prefixes[0]; i++)
        if (strncmp(name, prefixes[i], strlen(prefixes[i])) == 0) return true;
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(name, names[i]) == 0) return true;
    return false;
}

static lk_status check_extension_lists(const gltf_reader *reader)
{
    static const char *const keys[] = {"extensionsUsed", "extensionsRequired"};
    for (int k = 0; k < 2; k++) {
        const cJSON *list;
        lk_status status = get_array(reader, reader->root, "", keys[k], &list);
        if (status != LK_OK) return status;
        size_t i = 0;
        const cJSON *item;
        cJSON_ArrayForEach(item, list) {
            char where[64];
            snprintf(where, sizeof where, "%s[%zu]", keys[k], i++);
            if (!cJSON_IsString(item))
                return fail(reader, LK_ERR_PARSE, where, NULL, "expected a string, got %s", json_type_name(item));
            if (k == 0 || extension_is_harmless(item->valuestring)) continue;
            if (strcmp(item->valuestring, "KHR_draco_mesh_compression") == 0)
                return fail(reader, LK_ERR_UNSUPPORTED, where, NULL,
                            "Draco-compressed meshes (KHR_draco_mesh_compression) are not supported");
            return fail(reader, LK_ERR_UNSUPPORTED, where, NULL,
                        "required extension \"%s\" is not supported", item->valuestring);
        }
    }
    return LK_OK;
}

/* Checks, everywhere in the document except inside "extras" and inside
 * extension objects, that "name" is a string and "extensions" is an object
 * of objects. `path` holds the JSON location of `item` (length `length`). */
static lk_status check_common_properties(const gltf_reader *reader, const cJSON *item, char *path, size_t length,
                                         size_t capacity)
{
    if (!cJSON_IsObject(item) && !cJSON_IsArray(item)) return LK_OK;
    size_t index = 0;
    const cJSON *child;
    cJSON_ArrayForEach(child, item) {
        if (cJSON_IsArray(item)) {
            snprintf(path + length, capacity - length, "[%zu]", index++);
        } else {
            if (strcmp(child->string, "extras") == 0) continue;
            snprintf(path + length, capacity - length, "%s%s", length ? "." : "", child->string);
            if (strcmp(child->string, "name") == 0 && !cJSON_IsString(child))
                return fail(reader, LK_ERR_PARSE, path, NULL, "expected a string, got %s", json_type_name(child));
            if (strcmp(child->string, "extensions") == 0) {
                if (!cJSON_IsObject(child))
                    return fail(reader, LK_ERR_PARSE, path, NULL, "expected an object, got %s",
                                json_type_name(child));
                const cJSON *extension;
                cJSON_ArrayForEach(extension, child) {
                    if (!cJSON_IsObject(extension))
                        return fail(reader, LK_ERR_PARSE, path, extension->string, "expected an object, got %s",
                                    json_type_name(extension));
                }
                continue;
            }
        }
        /* snprintf truncates very deep paths; the check still runs. */
        lk_status status = check_common_properties(reader, child, path, strlen(path), capacity);
        if (status != LK_OK) return status;
        path[length] = '\0';
    }
    return LK_OK;
}

static lk_status check_texture_info(const gltf_reader *reader, const cJSON *object, const char *where,
                                    const char *key)
{
    const cJSON *info;
    lk_status status = get_object(reader, object, where, key, &info);
    if (status != LK_OK || !info) return status;
    char info_where[128];
    snprintf(info_where, sizeof info_where, "%s.%s", where, key);
    uint64_t index, texcoord;
    double factor;
    if ((status = get_uint(reader, info, info_where, "index", true, 0, &index)) != LK_OK) return status;
    if ((status = get_uint(reader, info, info_where, "texCoord", false, 0, &texcoord)) != LK_OK) return status;
    if ((status = get_number(reader, info, info_where, "scale", 1.0, &factor)) != LK_OK) return status;
    return get_number(reader, info, info_where, "strength", 1.0, &factor);
}

/* Materials are not used, but a wrongly typed material means a broken
 * exporter, and a strict reader should say so rather than guess. */
static lk_status check_materials(const gltf_reader *reader)
{
    const cJSON *array = member(reader->root, "materials");
    size_t index = 0;
    const cJSON *material;
    cJSON_ArrayForEach(material, array) {
        char where[64];
        snprintf(where, sizeof where, "materials[%zu]", index++);
        const cJSON *pbr, *text;
        double values[4], factor;
        bool flag;
        lk_status status = get_object(reader, material, where, "pbrMetallicRoughness", &pbr);
        if (status == LK_OK && pbr) {
            char pbr_where[96];
            snprintf(pbr_where, sizeof pbr_where, "%s.pbrMetallicRoughness", where);
            status = get_number_array(reader, pbr, pbr_where, "baseColorFactor", 4, values, NULL);
            if (status == LK_OK) status = get_number(reader, pbr, pbr_where, "metallicFactor", 1.0, &factor);
            if (status == LK_OK) status = get_number(reader, pbr, pbr_where, "roughnessFactor", 1.0, &factor);
            if (status == LK_OK) status = check_texture_info(reader, pbr, pbr_where, "baseColorTexture");
            if (status == LK_OK) status = check_texture_info(reader, pbr, pbr_where, "metallicRoughnessTexture");
        }
        if (status == LK_OK) status = check_texture_info(reader, material, where, "normalTexture");
        if (status == LK_OK) status = check_texture_info(reader, material, where, "occlusionTexture");
        if (status == LK_OK) status = check_texture_info(reader, material, where, "emissiveTexture");
        if (status == LK_OK) status = get_number_array(reader, material, where, "emissiveFactor", 3, values, NULL);
        if (status == LK_OK) status = get_string(reader, material, where, "alphaMode", &text);
        if (status == LK_OK) status = get_number(reader, material, where, "alphaCutoff", 0.5, &factor);
        if (status == LK_OK) status = get_bool(reader, material, where, "doubleSided", &flag);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

static lk_status check_document(gltf_reader *reader)
{
    if (!cJSON_IsObject(reader->root))
        return lk_error_set(reader->error, LK_ERR_PARSE, "%s: expected a JSON object at the top level, got %s",
                            reader->ctx->name, json_type_name(reader->root));
    const cJSON *asset, *version;
    lk_status status = get_object(reader, reader->root, "", "asset", &asset);
    if (status != LK_OK) return status;
    if (!asset) return fail(reader, LK_ERR_PARSE, "", "asset", "missing (not a glTF 2.0 file?)");
    status = get_string(reader, asset, "asset", "version", &version);
    if (status != LK_OK) return status;
    if (!version) return fail(reader, LK_ERR_PARSE, "asset", "version", "missing");
    if (version->valuestring[0] != '2' || (version->valuestring[1] != '\0' && version->valuestring[1] != '.'))
        return fail(reader, LK_ERR_UNSUPPORTED, "asset", "version",
                    "glTF version \"%s\" is not supported (only 2.x)", version->valuestring);
    status = check_extension_lists(reader);
    if (status != LK_OK) return status;

    /* Every top-level array of the specification must hold objects. */
    static const char *const arrays[] = {"animations", "cameras", "images", "materials", "samplers",
                                         "skins", "textures"};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; i++) {
        json_table table;
        status = build_table(reader, arrays[i], &table);
        table_free(reader, &table);
        if (status != LK_OK) return status;
    }
    if ((status = build_table(reader, "accessors", &reader->accessors)) != LK_OK) return status;
    if ((status = build_table(reader, "bufferViews", &reader->buffer_views)) != LK_OK) return status;
    if ((status = build_table(reader, "buffers", &reader->buffers_json)) != LK_OK) return status;
    if ((status = build_table(reader, "meshes", &reader->meshes)) != LK_OK) return status;
    if ((status = build_table(reader, "nodes", &reader->nodes)) != LK_OK) return status;
    if ((status = build_table(reader, "scenes", &reader->scenes)) != LK_OK) return status;

    char path[256] = "";
    status = check_common_properties(reader, reader->root, path, 0, sizeof path);
    if (status != LK_OK) return status;
    return check_materials(reader);
}

/* ---- buffers -------------------------------------------------------------- */

static int base64_value(unsigned char c)
{
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
}

/* Strict base64 (RFC 4648 alphabet, no whitespace; '=' padding optional but
 * only at the end). */
static lk_status base64_decode(const gltf_reader *reader, const char *text, size_t length, const char *where,
                               unsigned char **out, size_t *out_size)
{
    *out = NULL;
    *out_size = 0;
    size_t padding = 0;
    while (padding < 2 && length > 0 && text[length - 1] == '=') {
        length--;
        padding++;
    }
    if (padding && (length + padding) % 4 != 0)
        return fail(reader, LK_ERR_PARSE, where, "uri", "base64 data has misplaced '=' padding");
    if (length % 4 == 1)
        return fail(reader, LK_ERR_PARSE, where, "uri", "base64 data is truncated (%zu characters)", length);
    size_t size = length / 4 * 3 + (length % 4 ? length % 4 - 1 : 0);
    unsigned char *bytes = lk__malloc_array(size, 1);
    if (!bytes) return fail(reader, LK_ERR_NOMEM, where, "uri", "cannot allocate %zu bytes", size);
    size_t written = 0;
    uint32_t bits = 0;
    int bit_count = 0;
    for (size_t i = 0; i < length; i++) {
        int value = base64_value((unsigned char)text[i]);
        if (value < 0) {
            free(bytes);
            unsigned char c = (unsigned char)text[i];
            if (c > ' ' && c < 0x7F)
                return fail(reader, LK_ERR_PARSE, where, "uri", "invalid base64 character '%c' at position %zu of the data",
                            c, i);
            return fail(reader, LK_ERR_PARSE, where, "uri", "invalid base64 character 0x%02X at position %zu of the data",
                        c, i);
        }
        bits = (bits << 6) | (uint32_t)value;
        bit_count += 6;
        if (bit_count >= 8) {
            bit_count -= 8;
            bytes[written++] = (unsigned char)(bits >> bit_count);
            bits &= (1u << bit_count) - 1;
        }
    }
    *out = bytes;
    *out_size = written;
    return LK_OK;
}

/* Decodes %XX escapes of a relative URI into a file path and refuses paths
 * that could leave the model's directory. */
static lk_status uri_to_relative_path(const gltf_reader *reader, const char *uri, const char *where, char **out)
{
    *out = NULL;
    size_t length = strlen(uri);
    if (length == 0) return fail(reader, LK_ERR_PARSE, where, "uri", "empty uri");
    /* A scheme ("http:", "file:", "C:") comes before any '/'. */
    const char *colon = strchr(uri, ':');
    const char *slash = strchr(uri, '/');
    if (colon && (!slash || colon < slash))
        return fail(reader, LK_ERR_UNSUPPORTED, where, "uri",
                    "\"%.100s\": only data: URIs and relative file paths are supported", uri);
    char *path = malloc(length + 1);
    if (!path) return fail(reader, LK_ERR_NOMEM, where, "uri", "out of memory");
    size_t written = 0;
    for (size_t i = 0; i < length; i++) {
        char c = uri[i];
        if (c == '%') {
            int digits[2] = {-1, -1};
            for (int k = 0; k < 2 && i + 1 + (size_t)k < length; k++) {
                char h = uri[i + 1 + (size_t)k];
                if (h >= '0' && h <= '9') digits[k] = h - '0';
                else if (h >= 'a' && h <= 'f') digits[k] = h - 'a' + 10;
                else if (h >= 'A' && h <= 'F') digits[k] = h - 'A' + 10;
            }
            if (digits[0] < 0 || digits[1] < 0 || (digits[0] == 0 && digits[1] == 0)) {
                free(path);
                return fail(reader, LK_ERR_PARSE, where, "uri", "\"%.100s\": invalid %%-escape", uri);
            }
            c = (char)(digits[0] * 16 + digits[1]);
            i += 2;
        }
        path[written++] = c;
    }
    path[written] = '\0';
    bool escapes = path[0] == '/' || strchr(path, '\\') != NULL;
    for (const char *segment = path; !escapes && *segment;) {
        const char *end = strchr(segment, '/');
        size_t segment_length = end ? (size_t)(end - segment) : strlen(segment);
        if (segment_length == 2 && segment[0] == '.' && segment[1] == '.') escapes = true;
        segment += segment_length + (end ? 1 : 0);
    }
    if (escapes) {
        free(path);
        return fail(reader, LK_ERR_UNSUPPORTED, where, "uri",
                    "\"%.100s\": only relative paths inside the model's directory are allowed "
                    "(no absolute paths, no \"..\", no backslashes)",
                    uri);
    }
    *out = path;
    return LK_OK;
}

static lk_status load_external_file(gltf_reader *reader, gltf_buffer *buffer, const char *uri, const char *where,
                                    uint64_t byte_length)
{
    if (!reader->ctx->directory)
        return fail(reader, LK_ERR_UNSUPPORTED, where, "uri",
                    "refers to the external file \"%.100s\", which cannot be read when reading from memory "
                    "(read the file from disk instead)",
                    uri);
    char *relative;
    lk_status status = uri_to_relative_path(reader, uri, where, &relative);
    if (status != LK_OK) return status;
    /* Opened below the model's folder without following any link: a
     * linked file or directory could lead anywhere on the machine, and a
     * FIFO or a device would block or never end. */
    int fd;
    struct stat info;
    lk_error opened = {0};
    status = lk__open_input(reader->ctx->directory, relative, &fd, &info, &opened);
    if (status != LK_OK) {
        int reason_errno = errno;
        /* lk__open_input's message is "RELATIVE: reason". */
        size_t prefix = strlen(relative) + 2;
        const char *reason = strlen(opened.message) >= prefix ? opened.message + prefix : opened.message;
        if (reason_errno == ENOENT)
            status = fail(reader, LK_ERR_IO, where, "uri", "cannot open \"%.100s\": %s", uri, strerror(reason_errno));
        else
            status = fail(reader, LK_ERR_IO, where, "uri",
                          "\"%.100s\": %.200s; external files must be regular files inside the model's folder", uri,
                          reason);
        free(relative);
        return status;
    }
    if ((uint64_t)info.st_size < byte_length) {
        status = fail(reader, LK_ERR_RANGE, where, "byteLength", "%llu bytes but \"%.100s\" has only %llu",
                      (unsigned long long)byte_length, uri, (unsigned long long)info.st_size);
    } else if (byte_length > lk__budget_room(reader->ctx->budget)) {
        status = fail(reader, LK_ERR_LIMIT, where, "byteLength",
                      "%llu bytes is more than the memory budget of %zu (buffers already hold %zu)",
                      (unsigned long long)byte_length, reader->ctx->budget->limit, reader->buffer_bytes);
    } else {
        buffer->owned = lk__malloc_array((size_t)byte_length, 1);
        if (!buffer->owned) {
            status = fail(reader, LK_ERR_NOMEM, where, NULL, "cannot allocate %llu bytes",
                          (unsigned long long)byte_length);
        } else if (lk__read_prefix(fd, &info, relative, (size_t)byte_length, buffer->owned, &opened) != LK_OK) {
            status = fail(reader, LK_ERR_IO, where, "uri", "%.300s", opened.message);
        } else {
            buffer->data = buffer->owned;
            buffer->size = (size_t)byte_length;
        }
    }
    close(fd);
    free(relative);
    return status;
}

/* Makes buffers[index] available (GLB chunk, data: URI or external file). */
static lk_status load_buffer(gltf_reader *reader, uint64_t index, const char *referrer, const char *key,
                             const gltf_buffer **out)
{
    const cJSON *object = NULL;
    lk_status status = resolve(reader, &reader->buffers_json, "buffer", "buffers", index, referrer, key, &object);
    if (status != LK_OK) return status;
    gltf_buffer *buffer = &reader->buffers[index];
    *out = buffer;
    if (buffer->loaded) return LK_OK;
    char where[48];
    snprintf(where, sizeof where, "buffers[%llu]", (unsigned long long)index);
    uint64_t byte_length;
    const cJSON *uri;
    if ((status = get_uint(reader, object, where, "byteLength", true, 0, &byte_length)) != LK_OK) return status;
    if (byte_length == 0) return fail(reader, LK_ERR_PARSE, where, "byteLength", "must be at least 1");
    if ((status = get_string(reader, object, where, "uri", &uri)) != LK_OK) return status;

    if (!uri) {
        if (!reader->is_glb || index != 0 || !reader->has_bin_chunk)
            return fail(reader, LK_ERR_PARSE, where, NULL,
                        reader->is_glb && index == 0 ? "has no uri and the .glb file has no BIN chunk"
                                                     : "has no uri (only buffer 0 of a .glb file may omit it)");
        if (byte_length > reader->bin_chunk_size)
            return fail(reader, LK_ERR_RANGE, where, "byteLength", "%llu bytes but the BIN chunk has only %zu",
                        (unsigned long long)byte_length, reader->bin_chunk_size);
        buffer->data = reader->bin_chunk;
        buffer->size = (size_t)byte_length;
    } else if (strncmp(uri->valuestring, "data:", 5) == 0) {
        const char *text = uri->valuestring;
        const char *comma = strchr(text, ',');
        if (!comma || comma - text < 12 || strncmp(comma - 7, ";base64", 7) != 0)
            return fail(reader, LK_ERR_UNSUPPORTED, where, "uri", "only base64 data: URIs are supported");
        size_t size, text_length = strlen(comma + 1);
        /* The decoded bytes count against the budget with the rest. */
        size_t decoded = text_length / 4 * 3 + 3;
        if (!lk__budget_charge(reader->ctx->budget, decoded, 1))
            return fail(reader, LK_ERR_LIMIT, where, "uri",
                        "%zu bytes of base64 data would exceed the memory budget of %zu bytes (buffers hold %zu)",
                        text_length, reader->ctx->budget->limit, reader->buffer_bytes);
        status = base64_decode(reader, comma + 1, text_length, where, &buffer->owned, &size);
        lk__budget_release(reader->ctx->budget, decoded, 1);
        if (status != LK_OK) return status;
        lk__budget_charge(reader->ctx->budget, size, 1); /* size <= decoded */
        reader->buffer_bytes += size;
        if (size < byte_length)
            return fail(reader, LK_ERR_RANGE, where, "byteLength", "%llu bytes but the data: URI holds only %zu",
                        (unsigned long long)byte_length, size);
        buffer->data = buffer->owned;
        buffer->size = (size_t)byte_length;
    } else {
        status = load_external_file(reader, buffer, uri->valuestring, where, byte_length);
        if (status != LK_OK) return status;
        lk__budget_charge(reader->ctx->budget, buffer->size, 1); /* load_external_file checked the room */
        reader->buffer_bytes += buffer->size;
    }
    buffer->loaded = true;
    return LK_OK;
}

/* ---- accessors ------------------------------------------------------------ */

static size_t component_size(unsigned component_type)
{
    switch (component_type) {
    case COMPONENT_BYTE:
    case COMPONENT_UNSIGNED_BYTE: return 1;
    case COMPONENT_SHORT:
    case COMPONENT_UNSIGNED_SHORT: return 2;
    case COMPONENT_UNSIGNED_INT:
    case COMPONENT_FLOAT: return 4;
    default: return 0;
    }
}

static unsigned type_component_count(const char *type)
{
    if (strcmp(type, "SCALAR") == 0) return 1;
    if (strcmp(type, "VEC2") == 0) return 2;
    if (strcmp(type, "VEC3") == 0) return 3;
    if (strcmp(type, "VEC4") == 0) return 4;
    if (strcmp(type, "MAT2") == 0) return 4 + 100;
    if (strcmp(type, "MAT3") == 0) return 9 + 100;
    if (strcmp(type, "MAT4") == 0) return 16 + 100;
    return 0;
}

/* Validates accessors[index] for a use that accepts the types in
 * `type_mask` (what the use expects is in `expected`, for messages) and
 * that every element lies inside its bufferView and buffer. */
static lk_status open_accessor(gltf_reader *reader, uint64_t index, const char *referrer, const char *key,
                               unsigned type_mask, bool is_index, const char *expected, gltf_accessor *out)
{
    const cJSON *object = NULL;
    lk_status status = resolve(reader, &reader->accessors, "accessor", "accessors", index, referrer, key, &object);
    if (status != LK_OK) return status;
    char where[48];
    snprintf(where, sizeof where, "accessors[%llu]", (unsigned long long)index);
    memset(out, 0, sizeof *out);
    out->index = (size_t)index;

    if (member(object, "sparse"))
        return fail(reader, LK_ERR_UNSUPPORTED, where, "sparse", "sparse accessors are not supported");
    uint64_t component_type, count, byte_offset, view_index;
    const cJSON *type;
    bool normalized;
    if ((status = get_uint(reader, object, where, "componentType", true, 0, &component_type)) != LK_OK) return status;
    if ((status = get_uint(reader, object, where, "count", true, 0, &count)) != LK_OK) return status;
    if ((status = get_uint(reader, object, where, "byteOffset", false, 0, &byte_offset)) != LK_OK) return status;
    if ((status = get_bool(reader, object, where, "normalized", &normalized)) != LK_OK) return status;
    if ((status = get_string(reader, object, where, "type", &type)) != LK_OK) return status;
    if (!type) return fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"type\"");

    size_t size = component_size((unsigned)component_type);
    if (size == 0 || component_type > 0xFFFF)
        return fail(reader, LK_ERR_PARSE, where, "componentType",
                    "%llu is not a glTF component type (5120, 5121, 5122, 5123, 5125 or 5126)",
                    (unsigned long long)component_type);
    unsigned components = type_component_count(type->valuestring);
    if (components == 0)
        return fail(reader, LK_ERR_PARSE, where, "type", "\"%.40s\" is not a glTF accessor type", type->valuestring);
    if (components == 116 && (type_mask & TYPE_MAT4))
        components = 16; /* float matrices have no column padding */
    else if (components > 4 || !(type_mask & (1u << components)))
        return fail(reader, LK_ERR_PARSE, where, "type", "%s, but %s%s%s needs %s", type->valuestring, referrer,
                    key[0] == '[' ? "" : ".", key, expected);
    if (is_index) {
        if (component_type != COMPONENT_UNSIGNED_BYTE && component_type != COMPONENT_UNSIGNED_SHORT &&
            component_type != COMPONENT_UNSIGNED_INT)
            return fail(reader, LK_ERR_PARSE, where, "componentType",
                        "%llu is not valid for indices (expected 5121, 5123 or 5125)",
                        (unsigned long long)component_type);
        if (normalized) return fail(reader, LK_ERR_PARSE, where, "normalized", "indices cannot be normalized");
    } else if (normalized && (component_type == COMPONENT_FLOAT || component_type == COMPONENT_UNSIGNED_INT)) {
        return fail(reader, LK_ERR_PARSE, where, "normalized", "only integer types of 8 or 16 bits can be normalized");
    }
    if (count == 0) return fail(reader, LK_ERR_PARSE, where, "count", "must be at least 1");
    if (count > LK_MAX_ELEMENTS)
        return fail(reader, LK_ERR_LIMIT, where, "count", "%llu is more than lodkit supports (%zu)",
                    (unsigned long long)count, (size_t)LK_MAX_ELEMENTS);
    out->component_type = (unsigned)component_type;
    out->component_count = components;
    out->normalized = normalized;
    out->count = (size_t)count;
    size_t element_size = size * components;
    out->stride = element_size;

    const cJSON *view_item = member(object, "bufferView");
    if (!view_item) {
        /* The specification says such an accessor holds zeros. */
        if (byte_offset != 0)
            return fail(reader, LK_ERR_PARSE, where, "byteOffset", "must be 0 without a bufferView");
        return LK_OK;
    }
    if ((status = check_uint(reader, view_item, where, "bufferView")) != LK_OK) return status;
    view_index = (uint64_t)view_item->valuedouble;
    const cJSON *view = NULL;
    if ((status = resolve(reader, &reader->buffer_views, "bufferView", "bufferViews", view_index, where, "bufferView", &view)) != LK_OK)
        return status;
    char view_where[48];
    snprintf(view_where, sizeof view_where, "bufferViews[%llu]", (unsigned long long)view_index);
    uint64_t buffer_index, view_offset, view_length, byte_stride;
    if ((status = get_uint(reader, view, view_where, "buffer", true, 0, &buffer_index)) != LK_OK) return status;
    if ((status = get_uint(reader, view, view_where, "byteOffset", false, 0, &view_offset)) != LK_OK) return status;
    if ((status = get_uint(reader, view, view_where, "byteLength", true, 0, &view_length)) != LK_OK) return status;
    if ((status = get_uint(reader, view, view_where, "byteStride", false, 0, &byte_stride)) != LK_OK) return status;
    if (view_length == 0) return fail(reader, LK_ERR_PARSE, view_where, "byteLength", "must be at least 1");
    if (member(view, "byteStride") && (byte_stride < 4 || byte_stride > 252))
        return fail(reader, LK_ERR_PARSE, view_where, "byteStride", "%llu is outside 4..252",
                    (unsigned long long)byte_stride);
    const gltf_buffer *buffer;
    if ((status = load_buffer(reader, buffer_index, view_where, "buffer", &buffer)) != LK_OK) return status;
    /* All values are <= 2^53, so these sums cannot overflow 64 bits. */
    if (view_offset + view_length > buffer->size)
        return fail(reader, LK_ERR_RANGE, view_where, NULL,
                    "byteOffset %llu + byteLength %llu exceeds buffer %llu (%zu bytes)",
                    (unsigned long long)view_offset, (unsigned long long)view_length,
                    (unsigned long long)buffer_index, buffer->size);
    if (byte_stride) {
        if (byte_stride < element_size)
            return fail(reader, LK_ERR_RANGE, view_where, "byteStride",
                        "%llu is smaller than the %zu-byte elements of %s", (unsigned long long)byte_stride,
                        element_size, where);
        out->stride = (size_t)byte_stride;
    }
    uint64_t needed = byte_offset + (uint64_t)out->stride * (count - 1) + element_size;
    if (needed > view_length)
        return fail(reader, LK_ERR_RANGE, where, NULL,
                    "count %llu exceeds bufferView %llu (%llu bytes): byteOffset %llu + %llu x stride %zu + "
                    "element %zu = %llu bytes",
                    (unsigned long long)count, (unsigned long long)view_index, (unsigned long long)view_length,
                    (unsigned long long)byte_offset, (unsigned long long)(count - 1), out->stride, element_size,
                    (unsigned long long)needed);
    out->data = buffer->data + view_offset + byte_offset;
    return LK_OK;
}

/* Element `element` as floats (normalized integers mapped to [0,1] or [-1,1]). */
static void accessor_floats(const gltf_accessor *accessor, size_t element, float *values)
{
    if (!accessor->data) {
        for (unsigned c = 0; c < accessor->component_count; c++) values[c] = 0.0f;
        return;
    }
    const unsigned char *p = accessor->data + element * accessor->stride;
    bool normalized = accessor->normalized;
    for (unsigned c = 0; c < accessor->component_count; c++) {
        double value = 0.0;
        switch (accessor->component_type) {
        case COMPONENT_BYTE:
            value = (int8_t)p[c];
            if (normalized) value = fmax(value / 127.0, -1.0);
            break;
        case COMPONENT_UNSIGNED_BYTE:
            value = p[c];
            if (normalized) value /= 255.0;
            break;
        case COMPONENT_SHORT:
            value = (int16_t)lk__load_u16le(p + 2 * c);
            if (normalized) value = fmax(value / 32767.0, -1.0);
            break;
        case COMPONENT_UNSIGNED_SHORT:
            value = lk__load_u16le(p + 2 * c);
            if (normalized) value /= 65535.0;
            break;
        case COMPONENT_UNSIGNED_INT:
            value = lk__load_u32le(p + 4 * c);
            break;
        case COMPONENT_FLOAT: {
            uint32_t bits = lk__load_u32le(p + 4 * c);
            float f;
            memcpy(&f, &bits, sizeof f);
            value = f;
            break;
        }
        default: break;
        }
        values[c] = (float)value;
    }
}

static uint32_t accessor_index(const gltf_accessor *accessor, size_t element)
{
    if (!accessor->data) return 0;
    const unsigned char *p = accessor->data + element * accessor->stride;
    switch (accessor->component_type) {
    case COMPONENT_UNSIGNED_BYTE: return p[0];
    case COMPONENT_UNSIGNED_SHORT: return lk__load_u16le(p);
    default: return lk__load_u32le(p);
    }
}

/* ---- transforms ----------------------------------------------------------- */

/* 4x4 matrices are column-major like glTF's: m[column * 4 + row]. */
static void matrix_identity(double m[16])
{
    for (int i = 0; i < 16; i++) m[i] = (i % 5 == 0) ? 1.0 : 0.0;
}

static void matrix_multiply(const double a[16], const double b[16], double out[16])
{
    double result[16];
    for (int column = 0; column < 4; column++)
        for (int row = 0; row < 4; row++) {
            double sum = 0.0;
            for (int k = 0; k < 4; k++) sum += a[k * 4 + row] * b[column * 4 + k];
            result[column * 4 + row] = sum;
        }
    memcpy(out, result, sizeof result);
}

/* The node's local transform: `matrix`, or translation * rotation * scale. */
static lk_status node_local_matrix(const gltf_reader *reader, const cJSON *node, const char *where, double m[16])
{
    bool present;
    lk_status status = get_number_array(reader, node, where, "matrix", 16, m, &present);
    if (status != LK_OK || present) return status;
    double translation[3] = {0, 0, 0}, rotation[4] = {0, 0, 0, 1}, scale[3] = {1, 1, 1};
    if ((status = get_number_array(reader, node, where, "translation", 3, translation, NULL)) != LK_OK) return status;
    if ((status = get_number_array(reader, node, where, "rotation", 4, rotation, NULL)) != LK_OK) return status;
    if ((status = get_number_array(reader, node, where, "scale", 3, scale, NULL)) != LK_OK) return status;
    double length = sqrt(rotation[0] * rotation[0] + rotation[1] * rotation[1] + rotation[2] * rotation[2] +
                         rotation[3] * rotation[3]);
    if (!(length > 0.0) || !isfinite(length))
        return fail(reader, LK_ERR_RANGE, where, "rotation", "is not a valid quaternion (length %g)", length);
    double x = rotation[0] / length, y = rotation[1] / length, z = rotation[2] / length, w = rotation[3] / length;
    double r[9] = {/* column 0 */ 1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),
                   /* column 1 */ 2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   /* column 2 */ 2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)};
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
    *status = count > SIZE_MAX / 4 - 1 ? LK_ERR_LIMIT : lk__buffer_reserve_charged(buffer, (count ? count : 1) * 4, budget);
    if (*status != LK_OK) {
        *status = *status == LK_ERR_LIMIT ? over_budget(reader) : nomem(reader);
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

typedef struct primitive_attributes {
    gltf_accessor position, normal, texcoord, color;
    bool has_normal, has_texcoord, has_color;
} primitive_attributes;

static lk_status open_attributes(gltf_reader *reader, const cJSON *primitive, const char *where,
                                 primitive_attributes *attributes)
{
    const cJSON *map;
    char map_where[128];
    memset(attributes, 0, sizeof *attributes);
    snprintf(map_where, sizeof map_where, "%s.attributes", where);
    lk_status status = get_object(reader, primitive, where, "attributes", &map);
    if (status != LK_OK) return status;
    if (!map) return fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"attributes\"");
    uint64_t index;
    if ((status = get_uint(reader, map, map_where, "POSITION", false, UINT64_MAX, &index)) != LK_OK) return status;
    if (index == UINT64_MAX) return fail(reader, LK_ERR_PARSE, where, NULL, "has no POSITION attribute");
    status = open_accessor(reader, index, map_where, "POSITION", TYPE_VEC3, false, "a VEC3", &attributes->position);
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
        if ((status = get_uint(reader, map, map_where, optional[i].name, false, UINT64_MAX, &index)) != LK_OK)
            return status;
        if (index == UINT64_MAX) continue;
        status = open_accessor(reader, index, map_where, optional[i].name, optional[i].type_mask, false,
                               optional[i].expected, targets[i]);
        if (status != LK_OK) return status;
        if (targets[i]->count != vertex_count)
            return fail(reader, LK_ERR_RANGE, map_where, optional[i].name,
                        "accessor %llu has %zu elements but POSITION has %zu", (unsigned long long)index,
                        targets[i]->count, vertex_count);
        *present[i] = true;
    }
    return LK_OK;
}

static lk_status check_budget(const gltf_reader *reader, const char *where, size_t vertex_count,
                              size_t triangle_count, const primitive_attributes *attributes)
{
    uint64_t vertices = (uint64_t)reader->vertex_count + vertex_count;
    uint64_t triangles = (uint64_t)reader->triangle_count + triangle_count;
    if (vertices > LK_MAX_ELEMENTS || triangles > LK_MAX_ELEMENTS)
        return fail(reader, LK_ERR_LIMIT, where, NULL,
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
        return fail(reader, LK_ERR_LIMIT, where, NULL,
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
            return fail(reader, LK_ERR_RANGE, where, NULL, "%s of vertex %zu (accessors[%zu]) is not finite (%g)%s",
                        what, element, accessor->index, (double)values[c], after);
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
    if (transform->node != SIZE_MAX) snprintf(after, sizeof after, " after the transform of nodes[%zu]", transform->node);
    for (size_t i = 0; i < vertex_count; i++) {
        float p[3];
        accessor_floats(&attributes->position, i, p);
        lk_status status = check_finite(reader, where, "POSITION", &attributes->position, i, p, 3, "");
        if (status != LK_OK) return status;
        for (int row = 0; row < 3; row++)
            positions[3 * i + row] =
                (float)(m[row] * p[0] + m[4 + row] * p[1] + m[8 + row] * p[2] + m[12 + row]);
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
                accessor_floats(&attributes->normal, i, v);
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
                accessor_floats(&attributes->texcoord, i, uv);
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
                accessor_floats(&attributes->color, i, rgba);
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
        return fail(reader, LK_ERR_RANGE, where, NULL,
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
            v[k] = indices ? accessor_index(indices, corners[k]) : (uint32_t)corners[k];
            if (v[k] >= vertex_count) {
                return fail(reader, LK_ERR_RANGE, where, NULL,
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

static lk_status read_primitive(gltf_reader *reader, const cJSON *primitive, const char *where,
                                const vertex_transform *transform)
{
    if (!cJSON_IsObject(primitive))
        return fail(reader, LK_ERR_PARSE, where, NULL, "expected an object, got %s", json_type_name(primitive));
    uint64_t mode;
    lk_status status = get_uint(reader, primitive, where, "mode", false, MODE_TRIANGLES, &mode);
    if (status != LK_OK) return status;
    if (mode > MODE_TRIANGLE_FAN)
        return fail(reader, LK_ERR_PARSE, where, "mode", "%llu is not a glTF primitive mode (0..6)",
                    (unsigned long long)mode);
    const cJSON *extensions = member(primitive, "extensions");
    const cJSON *draco = extensions ? member(extensions, "KHR_draco_mesh_compression") : NULL;
    if (mode == MODE_LINES || mode == MODE_LINE_LOOP || mode == MODE_LINE_STRIP) {
        reader->skipped_line_primitives++;
        return LK_OK;
    }

    primitive_attributes attributes;
    status = open_attributes(reader, primitive, where, &attributes);
    if (status != LK_OK) return status;
    /* A Draco primitive may carry uncompressed fallback data; without it
     * the accessors have no bufferView. */
    if (draco && !attributes.position.data)
        return fail(reader, LK_ERR_UNSUPPORTED, where, NULL,
                    "Draco-compressed geometry (KHR_draco_mesh_compression) is not supported");
    size_t vertex_count = attributes.position.count;

    gltf_accessor indices;
    bool indexed = false;
    uint64_t indices_index;
    if ((status = get_uint(reader, primitive, where, "indices", false, UINT64_MAX, &indices_index)) != LK_OK)
        return status;
    if (indices_index != UINT64_MAX) {
        status = open_accessor(reader, indices_index, where, "indices", TYPE_SCALAR, true, "a SCALAR", &indices);
        if (status != LK_OK) return status;
        indexed = true;
    }
    size_t corner_count = indexed ? indices.count : vertex_count;
    size_t triangle_count = 0;
    if (mode == MODE_TRIANGLES) triangle_count = corner_count / 3;
    else if (mode != MODE_POINTS && corner_count >= 3) triangle_count = corner_count - 2;

    status = check_budget(reader, where, vertex_count, triangle_count, &attributes);
    if (status != LK_OK) return status;
    size_t base = reader->vertex_count;
    status = append_vertices(reader, where, &attributes, transform);
    if (status != LK_OK) return status;
    reader->vertex_count += vertex_count;
    if (reader->record_instances) {
        gltf_instance instance = {primitive, reader->current_mesh, transform->node, base, vertex_count};
        status = lk__buffer_append_charged(&reader->instances, &instance, sizeof instance, reader->ctx->budget);
        if (status != LK_OK) return status == LK_ERR_LIMIT ? over_budget(reader) : nomem(reader);
    }
    if (mode == MODE_POINTS) {
        /* Points: the vertices are the data; indices only select which are
         * drawn, so just check them. */
        for (size_t i = 0; indexed && i < indices.count; i++) {
            uint32_t v = accessor_index(&indices, i);
            if (v >= vertex_count)
                return fail(reader, LK_ERR_RANGE, where, NULL,
                            "index %u out of range (%zu vertices) at element %zu of accessors[%zu]", v,
                            vertex_count, i, indices.index);
        }
        return LK_OK;
    }
    return append_triangles(reader, where, (int)mode, indexed ? &indices : NULL, vertex_count, base,
                            transform->mirror);
}

static lk_status read_mesh(gltf_reader *reader, uint64_t mesh_index, const char *referrer,
                           const vertex_transform *transform)
{
    const cJSON *mesh = NULL, *primitives = NULL;
    lk_status status = resolve(reader, &reader->meshes, "mesh", "meshes", mesh_index, referrer, "mesh", &mesh);
    if (status != LK_OK) return status;
    char where[48];
    snprintf(where, sizeof where, "meshes[%llu]", (unsigned long long)mesh_index);
    if ((status = get_array(reader, mesh, where, "primitives", &primitives)) != LK_OK) return status;
    if (!primitives) return fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"primitives\"");
    reader->current_mesh = (size_t)mesh_index;
    size_t index = 0;
    const cJSON *primitive;
    cJSON_ArrayForEach(primitive, primitives) {
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
    walk_entry *stack = charged_calloc(reader, reader->nodes.count, sizeof *stack, &status);
    if (!stack) return status;
    for (size_t r = 0; r < root_count && status == LK_OK; r++) {
        size_t root = roots[r];
        if (visited[root]) {
            status = fail(reader, LK_ERR_PARSE, roots_where, NULL,
                          "node %zu is reached twice (listed twice, or also a descendant of another root)", root);
            break;
        }
        visited[root] = 1;
        size_t depth = 0;
        stack[depth].node = root;
        matrix_identity(stack[depth].parent_matrix);
        depth++;
        while (depth > 0 && status == LK_OK) {
            walk_entry entry = stack[--depth];
            const cJSON *node = reader->nodes.items[entry.node];
            char where[48];
            snprintf(where, sizeof where, "nodes[%zu]", entry.node);
            double local[16], world[16];
            status = node_local_matrix(reader, node, where, local);
            if (status != LK_OK) break;
            matrix_multiply(entry.parent_matrix, local, world);

            uint64_t mesh_index;
            status = get_uint(reader, node, where, "mesh", false, UINT64_MAX, &mesh_index);
            if (status != LK_OK) break;
            if (mesh_index != UINT64_MAX) {
                vertex_transform transform;
                make_vertex_transform(world, entry.node, &transform);
                status = read_mesh(reader, mesh_index, where, &transform);
                if (status != LK_OK) break;
            }

            const cJSON *children, *child;
            status = get_array(reader, node, where, "children", &children);
            if (status != LK_OK || !children) continue;
            /* First pass: validate and mark. Every node is marked once, so
             * the stack never needs more than nodes.count entries. */
            size_t child_count = 0;
            cJSON_ArrayForEach(child, children) {
                char child_key[48];
                snprintf(child_key, sizeof child_key, "children[%zu]", child_count);
                status = check_uint(reader, child, where, child_key);
                if (status != LK_OK) break;
                if (child->valuedouble >= (double)reader->nodes.count) {
                    status = fail(reader, LK_ERR_RANGE, where, child_key, "node %.0f out of range (%zu nodes)",
                                  child->valuedouble, reader->nodes.count);
                    break;
                }
                size_t child_node = (size_t)child->valuedouble;
                if (visited[child_node]) {
                    status = fail(reader, LK_ERR_PARSE, where, child_key,
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
            cJSON_ArrayForEach(child, children) {
                position--;
                stack[position].node = (size_t)child->valuedouble;
                memcpy(stack[position].parent_matrix, world, sizeof world);
            }
            depth += child_count;
        }
    }
    release(reader, stack, reader->nodes.count, sizeof *stack);
    return status;
}

static lk_status read_scene(gltf_reader *reader)
{
    lk_status status = LK_OK;
    size_t node_count = reader->nodes.count;
    unsigned char *visited = charged_calloc(reader, node_count, 1, &status);
    size_t *roots = visited ? charged_calloc(reader, node_count, sizeof *roots, &status) : NULL;
    size_t root_count = 0;
    char roots_where[64] = "nodes";
    if (!visited || !roots) goto done;
    uint64_t scene_index;
    if ((status = get_uint(reader, reader->root, "", "scene", false, UINT64_MAX, &scene_index)) != LK_OK) goto done;
    if (scene_index != UINT64_MAX && scene_index >= reader->scenes.count) {
        status = fail(reader, LK_ERR_RANGE, "", "scene", "scene %llu out of range (%zu scenes)",
                      (unsigned long long)scene_index, reader->scenes.count);
        goto done;
    }
    if (reader->scenes.count > 0) {
        if (scene_index == UINT64_MAX) scene_index = 0;
        const cJSON *scene = reader->scenes.items[scene_index], *list, *item;
        char scene_where[48];
        snprintf(scene_where, sizeof scene_where, "scenes[%llu]", (unsigned long long)scene_index);
        snprintf(roots_where, sizeof roots_where, "%s.nodes", scene_where);
        if ((status = get_array(reader, scene, scene_where, "nodes", &list)) != LK_OK) goto done;
        cJSON_ArrayForEach(item, list) {
            char key[32];
            snprintf(key, sizeof key, "[%zu]", root_count);
            if ((status = check_uint(reader, item, roots_where, key)) != LK_OK) goto done;
            if (item->valuedouble >= (double)node_count) {
                status = fail(reader, LK_ERR_RANGE, roots_where, key, "node %.0f out of range (%zu nodes)",
                              item->valuedouble, node_count);
                goto done;
            }
            if (root_count == node_count) {
                status = fail(reader, LK_ERR_PARSE, roots_where, NULL,
                              "lists more nodes than the %zu that exist, so some twice", node_count);
                goto done;
            }
            roots[root_count++] = (size_t)item->valuedouble;
        }
    } else if (node_count > 0) {
        /* No scene: every node that is nobody's child is a root. */
        unsigned char *has_parent = visited; /* borrowed, cleared below */
        for (size_t i = 0; i < node_count; i++) {
            const cJSON *children = member(reader->nodes.items[i], "children"), *child;
            if (!cJSON_IsArray(children)) continue;
            cJSON_ArrayForEach(child, children) {
                if (is_json_uint(child) && child->valuedouble < (double)node_count)
                    has_parent[(size_t)child->valuedouble] = 1;
            }
        }
        for (size_t i = 0; i < node_count; i++)
            if (!has_parent[i]) roots[root_count++] = i;
        memset(visited, 0, node_count);
        if (root_count == 0) {
            status = fail(reader, LK_ERR_PARSE, "", "nodes", "every node has a parent (the node hierarchy has a cycle)");
            goto done;
        }
    } else {
        /* Neither scenes nor nodes: take every mesh as it is. */
        vertex_transform identity;
        double matrix[16];
        matrix_identity(matrix);
        make_vertex_transform(matrix, SIZE_MAX, &identity);
        for (size_t i = 0; i < reader->meshes.count && status == LK_OK; i++)
            status = read_mesh(reader, i, "meshes", &identity);
        goto done;
    }
    status = walk_nodes(reader, roots, root_count, roots_where, visited);
done:
    release(reader, visited, node_count, 1);
    release(reader, roots, node_count, sizeof *roots);
    return status;
}

/* ---- containers ---------------------------------------------------------------- */

/* Deeper JSON than this is refused before cJSON sees it. cJSON stops at
 * CJSON_NESTING_LIMIT (1000) with a bare parse failure; glTF documents are
 * a few levels deep (extras included), and every recursive walk over the
 * tree (cJSON_Delete, check_common_properties) then stays shallow. */
#define GLTF_MAX_JSON_DEPTH 512
/* Parsing may go this far past the budget, so that small documents read
 * under any budget (lk_read_options in lodkit.h counts it in what a read
 * may exceed its budget by): the first 16 MiB of the JSON's cost are not
 * charged. */
#define GLTF_JSON_ALLOWANCE (16 << 20)

/* What a JSON text can cost once parsed, from one pass before it is parsed:
 * every value starts the document or follows '[', '{' or ',', so counting
 * those outside strings bounds the number of cJSON items; every string
 * (a key or a value) is copied once, in an allocation of at most its
 * length + 32 bytes. */
typedef struct json_cost {
    uint64_t values, strings;
    uint64_t tree;  /* bytes of the parsed tree */
    uint64_t parse; /* while parsing: the tree and parse_json's NUL-terminated copy */
} json_cost;

/* Refuses nesting deeper than GLTF_MAX_JSON_DEPTH (with the byte where it
 * happens) and measures what parsing will cost. */
static lk_status json_prescan(gltf_reader *reader, const char *text, size_t length, size_t file_offset,
                              json_cost *cost)
{
    size_t depth = 0;
    uint64_t values = 1, strings = 0;
    bool in_string = false;
    for (size_t i = 0; i < length; i++) {
        char c = text[i];
        if (in_string) {
            if (c == '\\') i++;
            else if (c == '"') in_string = false;
            continue;
        }
        if (c == '"') {
            in_string = true;
            strings++;
        } else if (c == '[' || c == '{') {
            if (++depth > GLTF_MAX_JSON_DEPTH)
                return lk_error_set(reader->error, LK_ERR_LIMIT,
                                    "%s: byte %zu: JSON nested deeper than %d levels (refused; glTF needs a handful)",
                                    reader->ctx->name, file_offset + i, GLTF_MAX_JSON_DEPTH);
            values++;
        } else if (c == ']' || c == '}') {
            if (depth) depth--;
        } else if (c == ',') {
            values++;
        }
    }
    cost->values = values;
    cost->strings = strings;
    cost->tree = (uint64_t)length + values * (sizeof(cJSON) + 16) + strings * 32;
    cost->parse = cost->tree + length + 1;
    return LK_OK;
}

static uint64_t beyond_allowance(uint64_t bytes)
{
    return bytes > GLTF_JSON_ALLOWANCE ? bytes - GLTF_JSON_ALLOWANCE : 0;
}

static lk_status parse_json(gltf_reader *reader, const char *text, size_t length, size_t file_offset,
                            cJSON **root)
{
    *root = NULL;
    json_cost cost = {0, 0, 0, 0};
    lk_status checked = json_prescan(reader, text, length, file_offset, &cost);
    if (checked != LK_OK) return checked;
    uint64_t charge = beyond_allowance(cost.parse);
    if (charge > lk__budget_room(reader->ctx->budget))
        return lk_error_set(reader->error, LK_ERR_LIMIT,
                            "%s: byte %zu: the JSON (%zu bytes, up to %llu values) would need about %llu bytes once "
                            "parsed next to the %zu already held, more than the memory budget of %zu bytes (+ %d MiB "
                            "for parsing)",
                            reader->ctx->name, file_offset, length, (unsigned long long)cost.values,
                            (unsigned long long)cost.parse, reader->ctx->budget->held, reader->ctx->budget->limit,
                            GLTF_JSON_ALLOWANCE >> 20);
    lk__budget_charge(reader->ctx->budget, (size_t)charge, 1);
    /* cJSON gets its own NUL-terminated copy: the input need not be
     * terminated, and this keeps any parser overrun inside our buffer. */
    char *copy = malloc(length + 1);
    if (!copy) {
        lk__budget_release(reader->ctx->budget, (size_t)charge, 1);
        return nomem(reader);
    }
    if (length) memcpy(copy, text, length);
    copy[length] = '\0';
    const char *end = NULL;
    *root = cJSON_ParseWithLengthOpts(copy, length, &end, 0);
    lk_status status = LK_OK;
    const char *what = "invalid JSON";
    if (*root) {
        /* Only whitespace (and the NUL padding some GLB writers use) may
         * follow the document. */
        while (end < copy + length && (*end == ' ' || *end == '\t' || *end == '\r' || *end == '\n' || *end == '\0'))
            end++;
        if (end < copy + length) what = "unexpected data after the JSON document";
    }
    if (!*root || end < copy + length) {
        size_t offset = end && end >= copy && end <= copy + length ? (size_t)(end - copy) : 0;
        size_t line = 1;
        for (size_t i = 0; i < offset; i++) line += copy[i] == '\n';
        if (reader->is_glb)
            status = lk_error_set(reader->error, LK_ERR_PARSE, "%s: byte %zu: %s (line %zu of the JSON chunk)",
                                  reader->ctx->name, file_offset + offset, what, line);
        else
            status = lk_error_set(reader->error, LK_ERR_PARSE, "%s: byte %zu: %s (line %zu)", reader->ctx->name,
                                  file_offset + offset, what, line);
        cJSON_Delete(*root);
        *root = NULL;
    }
    free(copy);
    /* What stays charged is the tree, until gltf_release deletes it. */
    reader->json_bytes = *root ? (size_t)beyond_allowance(cost.tree) : 0;
    lk__budget_release(reader->ctx->budget, (size_t)charge - reader->json_bytes, 1);
    return status;
}

#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
static lk_status fail_at(const gltf_reader *reader, lk_status status, size_t offset, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_byte_v(reader->error, status, reader->ctx->name, offset, format, args);
    va_end(args);
    return status;
}

/* Splits a .glb file into its JSON text and optional BIN chunk. */
static lk_status parse_glb(gltf_reader *reader, const unsigned char *data, size_t size, const char **json,
                           size_t *json_length)
{
    if (size < GLB_HEADER_SIZE)
        return fail_at(reader, LK_ERR_PARSE, 0, "file of %zu bytes is too short for the 12-byte GLB header", size);
    uint32_t version = lk__load_u32le(data + 4), length = lk__load_u32le(data + 8);
    if (version == 1)
        return fail_at(reader, LK_ERR_UNSUPPORTED, 4, "GLB version 1 (glTF 1.0) is not supported, only version 2");
    if (version != 2) return fail_at(reader, LK_ERR_PARSE, 4, "unknown GLB version %u (expected 2)", version);
    if (length != size)
        return fail_at(reader, LK_ERR_PARSE, 8, "header says the file has %u bytes but it has %zu (%s)", length, size,
                       length > size ? "truncated file" : "trailing data");
    size_t offset = GLB_HEADER_SIZE;
    size_t chunk_number = 0;
    while (offset < size) {
        if (size - offset < GLB_CHUNK_HEADER_SIZE)
            return fail_at(reader, LK_ERR_PARSE, offset, "truncated chunk header (%zu bytes left, 8 needed)",
                           size - offset);
        uint32_t chunk_length = lk__load_u32le(data + offset), chunk_type = lk__load_u32le(data + offset + 4);
        size_t available = size - offset - GLB_CHUNK_HEADER_SIZE;
        if (chunk_length > available)
            return fail_at(reader, LK_ERR_PARSE, offset, "chunk %zu claims %u bytes but only %zu follow (truncated file)",
                           chunk_number, chunk_length, available);
        if (chunk_length % 4 != 0)
            return fail_at(reader, LK_ERR_PARSE, offset, "chunk %zu length %u is not a multiple of 4", chunk_number,
                           chunk_length);
        const unsigned char *chunk = data + offset + GLB_CHUNK_HEADER_SIZE;
        if (chunk_number == 0) {
            if (chunk_type != GLB_CHUNK_JSON)
                return fail_at(reader, LK_ERR_PARSE, offset + 4,
                               "first chunk must be JSON (type 0x4E4F534A), found type 0x%08X", chunk_type);
            *json = (const char *)chunk;
            *json_length = chunk_length;
        } else if (chunk_type == GLB_CHUNK_BIN) {
            if (chunk_number != 1)
                return fail_at(reader, LK_ERR_PARSE, offset + 4, "BIN chunk must directly follow the JSON chunk");
            reader->has_bin_chunk = true;
            reader->bin_chunk = chunk;
            reader->bin_chunk_size = chunk_length;
        } else if (chunk_type == GLB_CHUNK_JSON) {
            return fail_at(reader, LK_ERR_PARSE, offset + 4, "second JSON chunk");
        }
        /* Other chunk types are skipped, as the specification asks. */
        offset += GLB_CHUNK_HEADER_SIZE + chunk_length;
        chunk_number++;
    }
    if (chunk_number == 0) return fail_at(reader, LK_ERR_PARSE, offset, "GLB file has no JSON chunk");
    return LK_OK;
}

/* Parses the container and the JSON, checks the document and reads the
 * default scene into the reader's output arrays. */
static lk_status gltf_load(gltf_reader *reader, const char *data, size_t size, cJSON **root)
{
    const char *json = data;
    size_t json_length = size, json_offset = 0;
    lk_status status = LK_OK;
    *root = NULL;
    if (size >= 4 && memcmp(data, "glTF", 4) == 0) {
        reader->is_glb = true;
        status = parse_glb(reader, (const unsigned char *)data, size, &json, &json_length);
        json_offset = (size_t)(json - data);
    }
    if (status == LK_OK) status = parse_json(reader, json, json_length, json_offset, root);
    reader->root = *root;
    if (status == LK_OK) status = check_document(reader);
    if (status == LK_OK)
        reader->buffers = charged_calloc(reader, reader->buffers_json.count, sizeof *reader->buffers, &status);
    if (status == LK_OK) status = read_scene(reader);
    if (status == LK_OK && reader->vertex_count == 0) {
        if (reader->skipped_line_primitives)
            status = lk_error_set(reader->error, LK_ERR_UNSUPPORTED,
                                  "%s: the scene holds only lines (%zu primitives), which lodkit does not read",
                                  reader->ctx->name, reader->skipped_line_primitives);
        else
            status = lk_error_set(reader->error, LK_ERR_PARSE, "%s: the scene contains no mesh geometry",
                                  reader->ctx->name);
    }
    return status;
}

/* Moves the output arrays into `mesh`. */
static lk_status gltf_take_mesh(gltf_reader *reader, lk_mesh *mesh)
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
    if (!mesh->indices) {
        lk_mesh_free(mesh);
        return nomem(reader);
    }
    return LK_OK;
}

static void gltf_release(gltf_reader *reader, cJSON *root)
{
    lk__budget *budget = reader->ctx->budget;
    for (size_t i = 0; reader->buffers && i < reader->buffers_json.count; i++) free(reader->buffers[i].owned);
    lk__budget_release(budget, reader->buffer_bytes, 1);
    release(reader, reader->buffers, reader->buffers_json.count, sizeof *reader->buffers);
    lk__buffer *arrays[] = {&reader->positions, &reader->normals, &reader->texcoords,
                            &reader->colors,    &reader->indices, &reader->instances};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; i++) lk__buffer_free_charged(arrays[i], budget);
    json_table *tables[] = {&reader->accessors, &reader->buffer_views, &reader->buffers_json,
                            &reader->meshes,    &reader->nodes,        &reader->scenes};
    for (size_t i = 0; i < sizeof tables / sizeof tables[0]; i++) table_free(reader, tables[i]);
    cJSON_Delete(root);
    lk__budget_release(budget, reader->json_bytes, 1);
}

lk_status lk__read_gltf(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    gltf_reader reader;
    memset(&reader, 0, sizeof reader);
    reader.ctx = ctx;
    reader.error = error;
    lk_mesh_init(mesh);
    cJSON *root = NULL;
    lk_status status = gltf_load(&reader, data, size, &root);
    if (status == LK_OK) status = gltf_take_mesh(&reader, mesh);
    gltf_release(&reader, root);
    if (status != LK_OK) lk_mesh_free(mesh);
    return status;
}

/* ---- animations: morph targets, skins, node animation ------------------------
 *
 * lk__anim_read_gltf reads the default scene like lk__read_gltf (that fixes
 * the connectivity and the attributes) and then evaluates the scene at every
 * frame time: animated node TRS (LINEAR with slerp for rotations, or STEP;
 * CUBICSPLINE is refused), morph target weights (POSITION deltas) and skins
 * (JOINTS_0/WEIGHTS_0, joint world matrix x inverseBindMatrix, linear blend).
 * As the specification says, a skinned mesh ignores its own node's
 * transform: the joints place it. Frame times are the union of the key
 * times of the chosen animation, or a uniform resampling at
 * frames_per_second over [first key, last key]. Normals, texture
 * coordinates and colours are those of the bind pose. */

enum { PATH_TRANSLATION, PATH_ROTATION, PATH_SCALE, PATH_WEIGHTS };

typedef struct anim_sampler {
    float *times;
    size_t key_count;
    float *values;     /* key_count * width floats */
    size_t width;      /* floats per key */
    bool step;
} anim_sampler;

typedef struct anim_channel {
    size_t node;
    int path;
    size_t sampler;    /* into the sampler list of all chosen animations */
} anim_channel;

/* Per node state at one time. */
typedef struct anim_node {
    double translation[3], rotation[4], scale[3];
    double rest_translation[3], rest_rotation[4], rest_scale[3]; /* the node's own values */
    double matrix[16];   /* "matrix" nodes (cannot be animated) */
    bool has_matrix;
    size_t parent;       /* SIZE_MAX for roots */
    double world[16];
    size_t target_count; /* morph targets of its mesh */
    double *weights;     /* target_count, or NULL */
    double *rest_weights;
} anim_node;

/* What one instanced primitive needs each frame. */
typedef struct anim_primitive {
    const gltf_instance *instance;
    float *base;         /* 3 * count bind-pose positions (mesh space) */
    float *deltas;       /* target_count * 3 * count, or NULL */
    size_t target_count;
    long skin;           /* index into skins, -1 when not skinned */
    uint16_t *joints;    /* 4 * count */
    float *weights;      /* 4 * count, normalised; a vertex with sum 0 is unweighted */
} anim_primitive;

typedef struct anim_skin {
    size_t joint_count;
    size_t *joints;          /* node indices */
    double *inverse_bind;    /* 16 * joint_count */
    double *joint_matrices;  /* 16 * joint_count, per frame */
} anim_skin;

typedef struct anim_state {
    gltf_reader *reader;
    const lk__anim_context *ctx;
    size_t node_count;
    anim_node *nodes;
    size_t *order;            /* nodes, parents first */
    size_t sampler_count, channel_count;
    anim_sampler *samplers;
    anim_channel *channels;
    size_t primitive_count;
    anim_primitive *primitives;
    size_t skin_count;
    anim_skin *skins;
    json_table skins_json, animations_json;
} anim_state;

static void anim_state_free(anim_state *state)
{
    for (size_t i = 0; i < state->node_count && state->nodes; i++) {
        free(state->nodes[i].weights);
        free(state->nodes[i].rest_weights);
    }
    free(state->nodes);
    free(state->order);
    for (size_t i = 0; i < state->sampler_count; i++) {
        free(state->samplers[i].times);
        free(state->samplers[i].values);
    }
    free(state->samplers);
    free(state->channels);
    for (size_t i = 0; i < state->primitive_count; i++) {
        free(state->primitives[i].base);
        free(state->primitives[i].deltas);
        free(state->primitives[i].joints);
        free(state->primitives[i].weights);
    }
    free(state->primitives);
    for (size_t i = 0; i < state->skin_count; i++) {
        free(state->skins[i].joints);
        free(state->skins[i].inverse_bind);
        free(state->skins[i].joint_matrices);
    }
    free(state->skins);
    table_free(state->reader, &state->skins_json);
    table_free(state->reader, &state->animations_json);
}

/* Charges `count` elements of `size` bytes to the budget before they are
 * allocated: what the animation reader holds besides the mesh can be out
 * of proportion to the file (an accessor without a bufferView is `count`
 * zeros; every instance of a mesh gets its own morph deltas; a joint is 2
 * bytes of JSON and 264 bytes of matrices). These charges are not given
 * back: the animation state lives until the end of the read. */
static lk_status anim_charge(gltf_reader *reader, const char *where, const char *what, uint64_t count, uint64_t size)
{
    lk__budget *budget = reader->ctx->budget;
    if (count > SIZE_MAX || size > SIZE_MAX || !lk__budget_charge(budget, (size_t)count, (size_t)size))
        return fail(reader, LK_ERR_LIMIT, where, NULL,
                    "%llu %s of %llu bytes would exceed the memory budget of %zu bytes (%zu already held)",
                    (unsigned long long)count, what, (unsigned long long)size, budget->limit, budget->held);
    return LK_OK;
}

/* Reads an accessor fully as floats (component_count per element). */
static lk_status read_accessor_floats(gltf_reader *reader, uint64_t index, const char *where, const char *key,
                                      unsigned type_mask, const char *expected, gltf_accessor *accessor,
                                      float **out)
{
    *out = NULL;
    lk_status status = open_accessor(reader, index, where, key, type_mask, false, expected, accessor);
    if (status == LK_OK)
        status = anim_charge(reader, where, "accessor elements", accessor->count,
                             (uint64_t)accessor->component_count * sizeof(float));
    if (status != LK_OK) return status;
    *out = lk__malloc_array(accessor->count, accessor->component_count * sizeof(float));
    if (!*out) return nomem(reader);
    for (size_t i = 0; i < accessor->count; i++) {
        float *values = *out + i * accessor->component_count;
        accessor_floats(accessor, i, values);
        for (unsigned c = 0; c < accessor->component_count; c++)
            if (!isfinite(values[c])) {
                /* Callers take ownership only on success. */
                free(*out);
                *out = NULL;
                char accessor_where[48];
                snprintf(accessor_where, sizeof accessor_where, "accessors[%zu]", accessor->index);
                return fail(reader, LK_ERR_RANGE, accessor_where, NULL, "element %zu is not finite", i);
            }
    }
    return LK_OK;
}

static lk_status anim_nodes_init(anim_state *state)
{
    gltf_reader *reader = state->reader;
    size_t count = reader->nodes.count;
    lk_status charged =
        anim_charge(reader, "nodes", "node states", count, sizeof *state->nodes + sizeof *state->order + 1);
    if (charged != LK_OK) return charged;
    state->node_count = count;
    state->nodes = lk__calloc_array(count, sizeof *state->nodes);
    state->order = lk__malloc_array(count, sizeof *state->order);
    if (!state->nodes || !state->order) return nomem(reader);
    for (size_t i = 0; i < count; i++) state->nodes[i].parent = SIZE_MAX;
    for (size_t i = 0; i < count; i++) {
        const cJSON *node = reader->nodes.items[i];
        anim_node *n = &state->nodes[i];
        char where[48];
        snprintf(where, sizeof where, "nodes[%zu]", i);
        double t[3] = {0, 0, 0}, r[4] = {0, 0, 0, 1}, sc[3] = {1, 1, 1};
        bool present;
        lk_status status = get_number_array(reader, node, where, "matrix", 16, n->matrix, &present);
        if (status != LK_OK) return status;
        n->has_matrix = present;
        if ((status = get_number_array(reader, node, where, "translation", 3, t, NULL)) != LK_OK) return status;
        if ((status = get_number_array(reader, node, where, "rotation", 4, r, NULL)) != LK_OK) return status;
        if ((status = get_number_array(reader, node, where, "scale", 3, sc, NULL)) != LK_OK) return status;
        memcpy(n->rest_translation, t, sizeof t);
        memcpy(n->rest_rotation, r, sizeof r);
        memcpy(n->rest_scale, sc, sizeof sc);
        const cJSON *children = member(node, "children"), *child;
        if (!cJSON_IsArray(children)) continue;
        cJSON_ArrayForEach(child, children) {
            if ((status = check_uint(reader, child, where, "children")) != LK_OK) return status;
            if (child->valuedouble >= (double)count)
                return fail(reader, LK_ERR_RANGE, where, "children", "node %.0f out of range (%zu nodes)",
                            child->valuedouble, count);
            size_t c = (size_t)child->valuedouble;
            if (state->nodes[c].parent != SIZE_MAX || c == i)
                return fail(reader, LK_ERR_PARSE, where, "children", "node %zu has two parents or is its own child",
                            c);
            state->nodes[c].parent = i;
        }
    }
    /* Parents-first order: repeatedly take nodes whose parent is placed.
     * Nodes on a cycle never get placed and are reported. */
    unsigned char *placed = lk__calloc_array(count, 1);
    if (!placed) return nomem(reader);
    size_t placed_count = 0;
    for (size_t i = 0; i < count; i++)
        if (state->nodes[i].parent == SIZE_MAX) {
            state->order[placed_count++] = i;
            placed[i] = 1;
        }
    for (size_t head = 0; head < placed_count; head++) {
        const cJSON *children = member(reader->nodes.items[state->order[head]], "children"), *child;
        if (!cJSON_IsArray(children)) continue;
        cJSON_ArrayForEach(child, children) {
            size_t c = (size_t)child->valuedouble;
            if (!placed[c]) {
                placed[c] = 1;
                state->order[placed_count++] = c;
            }
        }
    }
    free(placed);
    if (placed_count != count)
        return fail(reader, LK_ERR_PARSE, "", "nodes", "the node hierarchy has a cycle");
    return LK_OK;
}

static void quaternion_matrix(const double q_in[4], const double scale[3], const double translation[3], double m[16])
{
    double length = sqrt(q_in[0] * q_in[0] + q_in[1] * q_in[1] + q_in[2] * q_in[2] + q_in[3] * q_in[3]);
    double x = 0, y = 0, z = 0, w = 1;
    if (length > 0 && isfinite(length)) x = q_in[0] / length, y = q_in[1] / length, z = q_in[2] / length, w = q_in[3] / length;
    double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    for (int column = 0; column < 3; column++) {
        for (int row = 0; row < 3; row++) m[column * 4 + row] = r[column * 3 + row] * scale[column];
        m[column * 4 + 3] = 0.0;
    }
    m[12] = translation[0];
    m[13] = translation[1];
    m[14] = translation[2];
    m[15] = 1.0;
}

/* Reads the samplers and channels of one animation; sampler indices are
 * offset by the samplers already read (for all_animations). */
static lk_status anim_read_animation(anim_state *state, size_t chosen)
{
    gltf_reader *reader = state->reader;
    lk_status status;
    const cJSON *animation = state->animations_json.items[chosen];
    char where[48];
    snprintf(where, sizeof where, "animations[%zu]", chosen);
    const cJSON *samplers, *channels, *item;
    if ((status = get_array(reader, animation, where, "samplers", &samplers)) != LK_OK) return status;
    if ((status = get_array(reader, animation, where, "channels", &channels)) != LK_OK) return status;
    if (!samplers || !channels) return fail(reader, LK_ERR_PARSE, where, NULL, "needs \"samplers\" and \"channels\"");
    size_t sampler_base = state->sampler_count;
    size_t sampler_count = (size_t)cJSON_GetArraySize(samplers), channel_count = (size_t)cJSON_GetArraySize(channels);
    status = anim_charge(reader, where, "samplers and channels", sampler_count + channel_count + 2,
                         sizeof(anim_sampler) + sizeof(anim_channel));
    if (status != LK_OK) return status;
    anim_sampler *grown_samplers =
        lk__realloc_array(state->samplers, sampler_base + sampler_count + 1, sizeof *state->samplers);
    if (!grown_samplers) return nomem(reader);
    state->samplers = grown_samplers;
    memset(state->samplers + sampler_base, 0, (sampler_count + 1) * sizeof *state->samplers);
    anim_channel *grown_channels =
        lk__realloc_array(state->channels, state->channel_count + channel_count + 1, sizeof *state->channels);
    if (!grown_channels) return nomem(reader);
    state->channels = grown_channels;
    size_t index = 0;
    cJSON_ArrayForEach(item, samplers) {
        char sampler_where[80];
        snprintf(sampler_where, sizeof sampler_where, "%s.samplers[%zu]", where, index);
        anim_sampler *sampler = &state->samplers[sampler_base + index];
        index++;
        state->sampler_count = sampler_base + index;
        if (!cJSON_IsObject(item)) return fail(reader, LK_ERR_PARSE, sampler_where, NULL, "expected an object");
        const cJSON *interpolation;
        if ((status = get_string(reader, item, sampler_where, "interpolation", &interpolation)) != LK_OK) return status;
        if (interpolation && strcmp(interpolation->valuestring, "CUBICSPLINE") == 0)
            return fail(reader, LK_ERR_UNSUPPORTED, sampler_where, "interpolation",
                        "CUBICSPLINE is not supported (only LINEAR and STEP); resample the animation first");
        if (interpolation && strcmp(interpolation->valuestring, "STEP") != 0 &&
            strcmp(interpolation->valuestring, "LINEAR") != 0)
            return fail(reader, LK_ERR_PARSE, sampler_where, "interpolation", "\"%.40s\" is not LINEAR, STEP or CUBICSPLINE",
                        interpolation->valuestring);
        sampler->step = interpolation && strcmp(interpolation->valuestring, "STEP") == 0;
        uint64_t input, output;
        if ((status = get_uint(reader, item, sampler_where, "input", true, 0, &input)) != LK_OK) return status;
        if ((status = get_uint(reader, item, sampler_where, "output", true, 0, &output)) != LK_OK) return status;
        gltf_accessor accessor;
        status = read_accessor_floats(reader, input, sampler_where, "input", TYPE_SCALAR, "a SCALAR", &accessor,
                                      &sampler->times);
        if (status != LK_OK) return status;
        if (accessor.component_type != COMPONENT_FLOAT)
            return fail(reader, LK_ERR_PARSE, sampler_where, "input", "key times must be floats (componentType 5126)");
        sampler->key_count = accessor.count;
        for (size_t k = 1; k < sampler->key_count; k++)
            if (!(sampler->times[k] > sampler->times[k - 1]))
                return fail(reader, LK_ERR_RANGE, sampler_where, "input",
                            "key times must increase strictly (key %zu: %g after %g)", k, (double)sampler->times[k],
                            (double)sampler->times[k - 1]);
        status = read_accessor_floats(reader, output, sampler_where, "output", TYPE_SCALAR | TYPE_VEC3 | TYPE_VEC4,
                                      "a SCALAR, VEC3 or VEC4", &accessor, &sampler->values);
        if (status != LK_OK) return status;
        if (accessor.count % sampler->key_count != 0)
            return fail(reader, LK_ERR_RANGE, sampler_where, "output",
                        "%zu output elements for %zu key times (not a multiple)", accessor.count, sampler->key_count);
        sampler->width = accessor.count / sampler->key_count * accessor.component_count;
    }
    index = 0;
    cJSON_ArrayForEach(item, channels) {
        char channel_where[80];
        snprintf(channel_where, sizeof channel_where, "%s.channels[%zu]", where, index++);
        if (!cJSON_IsObject(item)) return fail(reader, LK_ERR_PARSE, channel_where, NULL, "expected an object");
        uint64_t sampler_index, node_index;
        const cJSON *target, *path;
        if ((status = get_uint(reader, item, channel_where, "sampler", true, 0, &sampler_index)) != LK_OK) return status;
        if (sampler_index >= sampler_count)
            return fail(reader, LK_ERR_RANGE, channel_where, "sampler", "sampler %llu out of range (%zu samplers)",
                        (unsigned long long)sampler_index, sampler_count);
        sampler_index += sampler_base;
        if ((status = get_object(reader, item, channel_where, "target", &target)) != LK_OK) return status;
        if (!target) return fail(reader, LK_ERR_PARSE, channel_where, NULL, "missing required \"target\"");
        char target_where[96];
        snprintf(target_where, sizeof target_where, "%s.target", channel_where);
        if ((status = get_uint(reader, target, target_where, "node", false, UINT64_MAX, &node_index)) != LK_OK)
            return status;
        if (node_index == UINT64_MAX) continue; /* targets something an extension defines */
        if (node_index >= state->node_count)
            return fail(reader, LK_ERR_RANGE, target_where, "node", "node %llu out of range (%zu nodes)",
                        (unsigned long long)node_index, state->node_count);
        if ((status = get_string(reader, target, target_where, "path", &path)) != LK_OK) return status;
        if (!path) return fail(reader, LK_ERR_PARSE, target_where, NULL, "missing required \"path\"");
        int path_id;
        size_t width;
        anim_node *node = &state->nodes[node_index];
        if (strcmp(path->valuestring, "translation") == 0) path_id = PATH_TRANSLATION, width = 3;
        else if (strcmp(path->valuestring, "rotation") == 0) path_id = PATH_ROTATION, width = 4;
        else if (strcmp(path->valuestring, "scale") == 0) path_id = PATH_SCALE, width = 3;
        else if (strcmp(path->valuestring, "weights") == 0) path_id = PATH_WEIGHTS, width = node->target_count;
        else
            return fail(reader, LK_ERR_UNSUPPORTED, target_where, "path", "\"%.40s\" is not an animatable node property",
                        path->valuestring);
        if (path_id != PATH_WEIGHTS && node->has_matrix)
            return fail(reader, LK_ERR_PARSE, target_where, "node",
                        "node %llu has a \"matrix\" and cannot be animated (glTF requires TRS)",
                        (unsigned long long)node_index);
        if (path_id == PATH_WEIGHTS && node->target_count == 0)
            return fail(reader, LK_ERR_PARSE, target_where, "node", "node %llu has no morph targets to weigh",
                        (unsigned long long)node_index);
        if (state->samplers[sampler_index].width != width)
            return fail(reader, LK_ERR_RANGE, channel_where, "sampler",
                        "sampler %llu gives %zu values per key but \"%s\" needs %zu",
                        (unsigned long long)(sampler_index - sampler_base), state->samplers[sampler_index].width,
                        path->valuestring, width);
        anim_channel *channel = &state->channels[state->channel_count++];
        channel->node = (size_t)node_index;
        channel->path = path_id;
        channel->sampler = (size_t)sampler_index;
    }
    return LK_OK;
}


/* Which animations play: `animation_index`, all of them, or none when the
 * file has no animations (then one frame of the static pose). */
static lk_status anim_read_channels(anim_state *state)
{
    gltf_reader *reader = state->reader;
    lk_status status = build_table(reader, "animations", &state->animations_json);
    if (status != LK_OK) return status;
    if (state->animations_json.count == 0) return LK_OK;
    if (state->ctx->all_animations) {
        for (size_t a = 0; a < state->animations_json.count; a++)
            if ((status = anim_read_animation(state, a)) != LK_OK) return status;
        return LK_OK;
    }
    size_t chosen = state->ctx->animation_index;
    if (chosen >= state->animations_json.count)
        return fail(reader, LK_ERR_RANGE, "", "animations", "animation %zu requested but the file has %zu", chosen,
                    state->animations_json.count);
    return anim_read_animation(state, chosen);
}

/* Decodes the morph targets, skins and weights of every instanced primitive. */
static lk_status anim_read_primitives(anim_state *state, lk_animation_report *report)
{
    gltf_reader *reader = state->reader;
    lk_status status = build_table(reader, "skins", &state->skins_json);
    if (status != LK_OK) return status;
    state->skin_count = state->skins_json.count;
    if ((status = anim_charge(reader, "skins", "skins", state->skin_count, sizeof *state->skins)) != LK_OK)
        return status;
    state->skins = lk__calloc_array(state->skin_count, sizeof *state->skins);
    if (!state->skins) return nomem(reader);
    for (size_t s = 0; s < state->skin_count; s++) {
        const cJSON *skin = state->skins_json.items[s], *joints, *item;
        anim_skin *out = &state->skins[s];
        char where[48];
        snprintf(where, sizeof where, "skins[%zu]", s);
        if ((status = get_array(reader, skin, where, "joints", &joints)) != LK_OK) return status;
        if (!joints || cJSON_GetArraySize(joints) == 0)
            return fail(reader, LK_ERR_PARSE, where, "joints", "missing or empty");
        out->joint_count = (size_t)cJSON_GetArraySize(joints);
        if ((status = anim_charge(reader, where, "joints", out->joint_count,
                                  sizeof(size_t) + 32 * sizeof(double))) != LK_OK)
            return status;
        out->joints = lk__malloc_array(out->joint_count, sizeof *out->joints);
        out->inverse_bind = lk__malloc_array(out->joint_count, 16 * sizeof(double));
        out->joint_matrices = lk__malloc_array(out->joint_count, 16 * sizeof(double));
        if (!out->joints || !out->inverse_bind || !out->joint_matrices) return nomem(reader);
        size_t j = 0;
        cJSON_ArrayForEach(item, joints) {
            if ((status = check_uint(reader, item, where, "joints")) != LK_OK) return status;
            if (item->valuedouble >= (double)state->node_count)
                return fail(reader, LK_ERR_RANGE, where, "joints", "node %.0f out of range (%zu nodes)",
                            item->valuedouble, state->node_count);
            out->joints[j] = (size_t)item->valuedouble;
            matrix_identity(out->inverse_bind + 16 * j);
            j++;
        }
        uint64_t ibm;
        if ((status = get_uint(reader, skin, where, "inverseBindMatrices", false, UINT64_MAX, &ibm)) != LK_OK)
            return status;
        if (ibm != UINT64_MAX) {
            gltf_accessor accessor;
            float *values = NULL;
            status = read_accessor_floats(reader, ibm, where, "inverseBindMatrices", TYPE_MAT4, "a MAT4", &accessor,
                                          &values);
            if (status == LK_OK && accessor.count < out->joint_count)
                status = fail(reader, LK_ERR_RANGE, where, "inverseBindMatrices",
                              "accessor %llu has %zu matrices for %zu joints", (unsigned long long)ibm,
                              accessor.count, out->joint_count);
            if (status == LK_OK)
                for (size_t k = 0; k < 16 * out->joint_count; k++) out->inverse_bind[k] = values[k];
            free(values);
            if (status != LK_OK) return status;
        }
        if (out->joint_count > report->bone_count) report->bone_count = out->joint_count;
    }

    const gltf_instance *instances = (const gltf_instance *)reader->instances.data;
    state->primitive_count = reader->instances.size / sizeof(gltf_instance);
    if ((status = anim_charge(reader, "meshes", "primitive instances", state->primitive_count,
                              sizeof *state->primitives)) != LK_OK)
        return status;
    state->primitives = lk__calloc_array(state->primitive_count, sizeof *state->primitives);
    if (!state->primitives) return nomem(reader);
    for (size_t p = 0; p < state->primitive_count; p++) {
        const gltf_instance *instance = &instances[p];
        anim_primitive *out = &state->primitives[p];
        out->instance = instance;
        out->skin = -1;
        char where[96];
        snprintf(where, sizeof where, "meshes[%zu]", instance->mesh);
        primitive_attributes attributes;
        if ((status = open_attributes(reader, instance->primitive, where, &attributes)) != LK_OK) return status;
        size_t count = instance->count;
        if ((status = anim_charge(reader, where, "bind-pose positions", count, 3 * sizeof(float))) != LK_OK)
            return status;
        out->base = lk__malloc_array(count, 3 * sizeof(float));
        if (!out->base) return nomem(reader);
        for (size_t v = 0; v < count; v++) accessor_floats(&attributes.position, v, out->base + 3 * v);
        /* Morph targets. */
        const cJSON *targets = member(instance->primitive, "targets"), *target;
        if (cJSON_IsArray(targets) && cJSON_GetArraySize(targets) > 0) {
            out->target_count = (size_t)cJSON_GetArraySize(targets);
            if ((status = anim_charge(reader, where, "morph target deltas", out->target_count,
                                      3 * (uint64_t)count * sizeof(float))) != LK_OK)
                return status;
            out->deltas = lk__calloc_array(out->target_count, 3 * count * sizeof(float));
            if (!out->deltas) return nomem(reader);
            size_t k = 0;
            cJSON_ArrayForEach(target, targets) {
                char target_where[128];
                snprintf(target_where, sizeof target_where, "%s.primitives.targets[%zu]", where, k);
                uint64_t position;
                if (!cJSON_IsObject(target)) return fail(reader, LK_ERR_PARSE, target_where, NULL, "expected an object");
                if ((status = get_uint(reader, target, target_where, "POSITION", false, UINT64_MAX, &position)) != LK_OK)
                    return status;
                if (position != UINT64_MAX) {
                    gltf_accessor accessor;
                    float *values;
                    status = read_accessor_floats(reader, position, target_where, "POSITION", TYPE_VEC3, "a VEC3",
                                                  &accessor, &values);
                    if (status == LK_OK && accessor.count != count)
                        status = fail(reader, LK_ERR_RANGE, target_where, "POSITION",
                                      "%zu deltas for %zu vertices", accessor.count, count);
                    if (status == LK_OK) memcpy(out->deltas + k * 3 * count, values, 3 * count * sizeof(float));
                    free(values);
                    if (status != LK_OK) return status;
                }
                k++;
            }
            report->morphed = 1;
        }
        if (instance->node == SIZE_MAX) continue;
        anim_node *node = &state->nodes[instance->node];
        if (out->target_count) {
            if (node->target_count && node->target_count != out->target_count)
                return fail(reader, LK_ERR_RANGE, where, NULL,
                            "primitives have different numbers of morph targets (%zu and %zu)", node->target_count,
                            out->target_count);
            node->target_count = out->target_count;
        }
        /* Skin. */
        const cJSON *node_json = reader->nodes.items[instance->node];
        char node_where[48];
        snprintf(node_where, sizeof node_where, "nodes[%zu]", instance->node);
        uint64_t skin_index;
        if ((status = get_uint(reader, node_json, node_where, "skin", false, UINT64_MAX, &skin_index)) != LK_OK)
            return status;
        if (skin_index == UINT64_MAX) continue;
        if (skin_index >= state->skin_count)
            return fail(reader, LK_ERR_RANGE, node_where, "skin", "skin %llu out of range (%zu skins)",
                        (unsigned long long)skin_index, state->skin_count);
        const cJSON *map = member(instance->primitive, "attributes");
        char map_where[128];
        snprintf(map_where, sizeof map_where, "%s.attributes", where);
        uint64_t joints_index, weights_index;
        if ((status = get_uint(reader, map, map_where, "JOINTS_0", false, UINT64_MAX, &joints_index)) != LK_OK ||
            (status = get_uint(reader, map, map_where, "WEIGHTS_0", false, UINT64_MAX, &weights_index)) != LK_OK)
            return status;
        if (joints_index == UINT64_MAX || weights_index == UINT64_MAX)
            return fail(reader, LK_ERR_PARSE, map_where, NULL,
                        "the node has a skin but the primitive lacks JOINTS_0 or WEIGHTS_0");
        if (member(map, "JOINTS_1"))
            return fail(reader, LK_ERR_UNSUPPORTED, map_where, "JOINTS_1",
                        "more than 4 joints per vertex (JOINTS_1) are not supported");
        gltf_accessor joints, weights;
        if ((status = open_accessor(reader, joints_index, map_where, "JOINTS_0", TYPE_VEC4, false, "a VEC4",
                                    &joints)) != LK_OK)
            return status;
        if (joints.component_type != COMPONENT_UNSIGNED_BYTE && joints.component_type != COMPONENT_UNSIGNED_SHORT)
            return fail(reader, LK_ERR_PARSE, map_where, "JOINTS_0", "joints must be unsigned bytes or shorts");
        float *weight_values;
        if ((status = read_accessor_floats(reader, weights_index, map_where, "WEIGHTS_0", TYPE_VEC4, "a VEC4",
                                           &weights, &weight_values)) != LK_OK)
            return status;
        out->weights = weight_values;
        if (joints.count != count || weights.count != count)
            return fail(reader, LK_ERR_RANGE, map_where, NULL, "JOINTS_0 (%zu) or WEIGHTS_0 (%zu) is not per vertex (%zu)",
                        joints.count, weights.count, count);
        if ((status = anim_charge(reader, map_where, "joint indices", count, 4 * sizeof(uint16_t))) != LK_OK)
            return status;
        out->joints = lk__malloc_array(count, 4 * sizeof(uint16_t));
        if (!out->joints) return nomem(reader);
        const anim_skin *skin = &state->skins[skin_index];
        for (size_t v = 0; v < count; v++) {
            float j[4];
            accessor_floats(&joints, v, j);
            double sum = 0;
            for (int k = 0; k < 4; k++) {
                float w = out->weights[4 * v + (size_t)k];
                if (w < 0)
                    return fail(reader, LK_ERR_RANGE, map_where, "WEIGHTS_0", "vertex %zu has a negative weight (%g)", v,
                                (double)w);
                if (w > 0 && j[k] >= (float)skin->joint_count)
                    return fail(reader, LK_ERR_RANGE, map_where, "JOINTS_0",
                                "vertex %zu uses joint %.0f but skins[%llu] has %zu joints", v, (double)j[k],
                                (unsigned long long)skin_index, skin->joint_count);
                out->joints[4 * v + (size_t)k] = w > 0 ? (uint16_t)j[k] : 0;
                sum += w;
            }
            if (!(sum > 0)) {
                report->vertices_unweighted++;
                continue;
            }
            if (fabs(sum - 1) > 1e-3) report->weights_normalised++;
            for (int k = 0; k < 4; k++) out->weights[4 * v + (size_t)k] = (float)(out->weights[4 * v + (size_t)k] / sum);
        }
        out->skin = (long)skin_index;
        report->skinned = 1;
    }
    /* Morph weights of nodes: node.weights, else mesh.weights, else 0. */
    for (size_t i = 0; i < state->node_count; i++) {
        anim_node *node = &state->nodes[i];
        if (!node->target_count) continue;
        if ((status = anim_charge(reader, "nodes", "morph weights", node->target_count, 2 * sizeof(double))) != LK_OK)
            return status;
        node->weights = lk__calloc_array(node->target_count, sizeof(double));
        node->rest_weights = lk__calloc_array(node->target_count, sizeof(double));
        if (!node->weights || !node->rest_weights) return nomem(reader);
        char where[48];
        snprintf(where, sizeof where, "nodes[%zu]", i);
        bool present = false;
        const cJSON *node_json = reader->nodes.items[i];
        if (member(node_json, "weights")) {
            status = get_number_array(reader, node_json, where, "weights", node->target_count, node->rest_weights,
                                      &present);
            if (status != LK_OK) return status;
        }
        if (!present) {
            uint64_t mesh_index;
            if ((status = get_uint(reader, node_json, where, "mesh", false, UINT64_MAX, &mesh_index)) != LK_OK)
                return status;
            if (mesh_index < reader->meshes.count && member(reader->meshes.items[mesh_index], "weights")) {
                snprintf(where, sizeof where, "meshes[%llu]", (unsigned long long)mesh_index);
                status = get_number_array(reader, reader->meshes.items[mesh_index], where, "weights",
                                          node->target_count, node->rest_weights, NULL);
                if (status != LK_OK) return status;
            }
        }
    }
    return LK_OK;
}

/* Value of a sampler at time t into out (width floats). */
static void sampler_evaluate(const anim_sampler *sampler, double t, bool rotation, double *out)
{
    size_t width = sampler->width, last = sampler->key_count - 1;
    const float *values = sampler->values;
    if (t <= sampler->times[0] || last == 0) {
        for (size_t c = 0; c < width; c++) out[c] = values[c];
        return;
    }
    if (t >= sampler->times[last]) {
        for (size_t c = 0; c < width; c++) out[c] = values[last * width + c];
        return;
    }
    size_t lo = 0, hi = last; /* times[lo] <= t < times[hi] */
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (sampler->times[mid] <= t) lo = mid;
        else hi = mid;
    }
    const float *a = values + lo * width, *b = values + hi * width;
    if (sampler->step) {
        for (size_t c = 0; c < width; c++) out[c] = a[c];
        return;
    }
    double u = (t - sampler->times[lo]) / ((double)sampler->times[hi] - sampler->times[lo]);
    if (!rotation) {
        for (size_t c = 0; c < width; c++) out[c] = a[c] + (b[c] - (double)a[c]) * u;
        return;
    }
    /* Spherical interpolation along the shorter arc. */
    double dot = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2] + (double)a[3] * b[3];
    double sign = dot < 0 ? -1.0 : 1.0;
    dot *= sign;
    double wa = 1 - u, wb = u * sign;
    if (dot < 0.9995) {
        double angle = acos(dot > 1 ? 1 : dot), s = sin(angle);
        wa = sin((1 - u) * angle) / s;
        wb = sin(u * angle) / s * sign;
    }
    double length = 0;
    for (int c = 0; c < 4; c++) {
        out[c] = wa * a[c] + wb * b[c];
        length += out[c] * out[c];
    }
    length = sqrt(length);
    if (length > 0)
        for (int c = 0; c < 4; c++) out[c] /= length;
}

static lk_status anim_evaluate(anim_state *state, double t, float *positions, size_t frame)
{
    gltf_reader *reader = state->reader;
    for (size_t i = 0; i < state->node_count; i++) {
        anim_node *n = &state->nodes[i];
        /* Start from the node's own values each frame. */
        memcpy(n->translation, n->rest_translation, sizeof n->translation);
        memcpy(n->rotation, n->rest_rotation, sizeof n->rotation);
        memcpy(n->scale, n->rest_scale, sizeof n->scale);
        if (n->target_count) memcpy(n->weights, n->rest_weights, n->target_count * sizeof(double));
    }
    for (size_t c = 0; c < state->channel_count; c++) {
        const anim_channel *channel = &state->channels[c];
        anim_node *n = &state->nodes[channel->node];
        const anim_sampler *sampler = &state->samplers[channel->sampler];
        switch (channel->path) {
        case PATH_TRANSLATION: sampler_evaluate(sampler, t, false, n->translation); break;
        case PATH_ROTATION: sampler_evaluate(sampler, t, true, n->rotation); break;
        case PATH_SCALE: sampler_evaluate(sampler, t, false, n->scale); break;
        default: sampler_evaluate(sampler, t, false, n->weights); break;
        }
    }
    for (size_t k = 0; k < state->node_count; k++) {
        size_t i = state->order[k];
        anim_node *n = &state->nodes[i];
        double local[16];
        if (n->has_matrix) memcpy(local, n->matrix, sizeof local);
        else quaternion_matrix(n->rotation, n->scale, n->translation, local);
        if (n->parent == SIZE_MAX) memcpy(n->world, local, sizeof local);
        else matrix_multiply(state->nodes[n->parent].world, local, n->world);
    }
    for (size_t s = 0; s < state->skin_count; s++) {
        anim_skin *skin = &state->skins[s];
        for (size_t j = 0; j < skin->joint_count; j++)
            matrix_multiply(state->nodes[skin->joints[j]].world, skin->inverse_bind + 16 * j,
                            skin->joint_matrices + 16 * j);
    }
    for (size_t p = 0; p < state->primitive_count; p++) {
        const anim_primitive *primitive = &state->primitives[p];
        const gltf_instance *instance = primitive->instance;
        const anim_node *node = instance->node == SIZE_MAX ? NULL : &state->nodes[instance->node];
        double identity[16];
        matrix_identity(identity);
        const double *world = node ? node->world : identity;
        const anim_skin *skin = primitive->skin >= 0 ? &state->skins[primitive->skin] : NULL;
        for (size_t v = 0; v < instance->count; v++) {
            double position[3];
            for (int c = 0; c < 3; c++) position[c] = primitive->base[3 * v + (size_t)c];
            if (primitive->deltas && node && node->weights)
                for (size_t k = 0; k < primitive->target_count; k++) {
                    if (node->weights[k] == 0) continue; /* most are, in key-frame morphs */
                    const float *d = primitive->deltas + (k * instance->count + v) * 3;
                    for (int c = 0; c < 3; c++) position[c] += node->weights[k] * d[c];
                }
            double out[3] = {0, 0, 0};
            const float *w = primitive->weights ? primitive->weights + 4 * v : NULL;
            if (skin && (w[0] > 0 || w[1] > 0 || w[2] > 0 || w[3] > 0)) {
                for (int k = 0; k < 4; k++) {
                    if (!(w[k] > 0)) continue;
                    const double *m = skin->joint_matrices + 16 * primitive->joints[4 * v + (size_t)k];
                    for (int r = 0; r < 3; r++)
                        out[r] += w[k] * (m[r] * position[0] + m[4 + r] * position[1] + m[8 + r] * position[2] + m[12 + r]);
                }
            } else {
                for (int r = 0; r < 3; r++)
                    out[r] = world[r] * position[0] + world[4 + r] * position[1] + world[8 + r] * position[2] +
                             world[12 + r];
            }
            float *dst = positions + 3 * (instance->base + v);
            for (int r = 0; r < 3; r++) {
                dst[r] = (float)out[r];
                if (!isfinite(dst[r]))
                    return lk_error_set(reader->error, LK_ERR_RANGE,
                                        "%s: frame %zu (t = %g): vertex %zu of meshes[%zu] is not finite after "
                                        "animation and skinning",
                                        reader->ctx->name, frame, t, v, instance->mesh);
            }
        }
    }
    return LK_OK;
}

static int compare_floats(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

lk_status lk__anim_read_gltf(const char *data, size_t size, const lk__anim_context *ctx, lk_animation *animation,
                             lk_error *error)
{
    lk_animation_init(animation);
    lk__read_context read_ctx = {ctx->name, ctx->directory, ctx->budget};
    gltf_reader reader;
    memset(&reader, 0, sizeof reader);
    reader.ctx = &read_ctx;
    reader.error = error;
    reader.record_instances = true;
    anim_state state;
    memset(&state, 0, sizeof state);
    state.reader = &reader;
    state.ctx = ctx;
    float *times = NULL;
    cJSON *root = NULL;
    /* The mesh arrays, the buffers and the JSON stay charged while the
     * frames are computed. */
    lk_status status = gltf_load(&reader, data, size, &root);
    if (status == LK_OK) status = anim_nodes_init(&state);
    if (status == LK_OK) status = anim_read_primitives(&state, ctx->report);
    if (status == LK_OK) status = anim_read_channels(&state);
    if (status != LK_OK) goto done;
    /* Frame times. */
    size_t key_total = 0;
    for (size_t c = 0; c < state.channel_count; c++) key_total += state.samplers[state.channels[c].sampler].key_count;
    /* Channels may share one long sampler: the union of their key times is
     * gathered first, so it is what gets charged. */
    status = anim_charge(&reader, "animations", "key times", (uint64_t)key_total + 1, sizeof(float));
    if (status != LK_OK) goto done;
    times = lk__malloc_array(key_total + 1, sizeof(float));
    if (!times) {
        status = nomem(&reader);
        goto done;
    }
    size_t time_count = 0;
    for (size_t c = 0; c < state.channel_count; c++) {
        const anim_sampler *sampler = &state.samplers[state.channels[c].sampler];
        memcpy(times + time_count, sampler->times, sampler->key_count * sizeof(float));
        time_count += sampler->key_count;
    }
    qsort(times, time_count, sizeof(float), compare_floats);
    size_t unique = 0;
    for (size_t i = 0; i < time_count; i++)
        if (unique == 0 || times[i] != times[unique - 1]) times[unique++] = times[i];
    ctx->report->key_count = unique;
    double first = unique ? times[0] : 0, last = unique ? times[unique - 1] : 0;
    size_t frame_count = unique ? unique : 1;
    double fps = ctx->frames_per_second;
    if (fps > 0) {
        double span = (last - first) * fps;
        if (span + 1 > (double)ctx->max_frames)
            frame_count = ctx->max_frames + 1;
        else
            frame_count = (size_t)floor(span + 1e-9) + 1;
    }
    if (frame_count > ctx->max_frames) {
        status = lk_error_set(error, LK_ERR_LIMIT, "%s: %zu frames is more than the limit of %zu (resample with a lower "
                              "frame rate)", ctx->name, frame_count, ctx->max_frames);
        goto done;
    }
    status = gltf_take_mesh(&reader, &animation->mesh);
    if (status != LK_OK) goto done;
    status = lk__animation_alloc_frames(animation, frame_count, ctx->budget, ctx->name, error);
    if (status != LK_OK) goto done;
    /* Names of at most 32 bytes ("t" and a %.9g time) with their pointers. */
    status = anim_charge(&reader, "animations", "frame names", frame_count, sizeof(char *) + 32);
    if (status != LK_OK) goto done;
    animation->frame_names = lk__calloc_array(frame_count, sizeof(char *));
    if (!animation->frame_names) {
        status = nomem(&reader);
        goto done;
    }
    if (fps > 0) animation->frames_per_second = fps;
    else if (frame_count > 1 && last > first) animation->frames_per_second = (double)(frame_count - 1) / (last - first);
    else animation->frames_per_second = 30;
    size_t vertex_count = animation->mesh.vertex_count;
    for (size_t f = 0; f < frame_count; f++) {
        double t = fps > 0 ? first + (double)f / fps : (unique ? times[f] : 0);
        float *positions = animation->frame_positions + f * vertex_count * 3;
        /* Vertices of primitives not instanced keep their static position. */
        memcpy(positions, animation->mesh.positions, vertex_count * 3 * sizeof(float));
        status = anim_evaluate(&state, t, positions, f);
        if (status != LK_OK) goto done;
        char name[32];
        snprintf(name, sizeof name, "t%.9g", t);
        animation->frame_names[f] = malloc(strlen(name) + 1);
        if (!animation->frame_names[f]) {
            status = nomem(&reader);
            goto done;
        }
        strcpy(animation->frame_names[f], name);
    }
    memcpy(animation->mesh.positions, animation->frame_positions, vertex_count * 3 * sizeof(float));
done:
    free(times);
    anim_state_free(&state);
    gltf_release(&reader, root);
    if (status != LK_OK) lk_animation_free(animation);
    return status;
}

/* ---- writing a morph-target animation ---------------------------------------
 *
 * One mesh, one node, one animation. Frame 0 is the base geometry; frame f
 * (f >= 1) is morph target f-1 holding frame_f - frame_0. The animation's
 * key f at time f / fps has weight 1 for target f-1 and 0 elsewhere, with
 * LINEAR interpolation, which blends consecutive frames linearly as a
 * key-frame player would. Everything goes into one .gltf with the buffer
 * embedded as a base64 data: URI. Reading it back gives the same frames up
 * to float rounding of base + (frame - base); frame names and normals of
 * later frames (never stored) are lost. */

#define GLTF_WRITE_MAX_FRAMES 2048 /* the weights output grows as frames^2 */

typedef struct gltf_writer {
    lk__buffer bin;
    cJSON *views, *accessors;
    size_t view_count, accessor_count;
    bool failed;
} gltf_writer;

/* Describes bytes [offset, offset + bytes) of the buffer, already written,
 * as a new bufferView and an accessor of `count` elements; returns the
 * accessor (NULL when out of memory: writer->failed is set). */
static cJSON *add_view_accessor(gltf_writer *writer, size_t offset, size_t bytes, int component_type, size_t count,
                                const char *type)
{
    cJSON *view = cJSON_CreateObject(), *accessor = cJSON_CreateObject();
    if (!view || !accessor) {
        cJSON_Delete(view), cJSON_Delete(accessor);
        writer->failed = true;
        return NULL;
    }
    cJSON_AddItemToArray(writer->views, view);
    cJSON_AddItemToArray(writer->accessors, accessor);
    cJSON_AddNumberToObject(view, "buffer", 0);
    cJSON_AddNumberToObject(view, "byteOffset", (double)offset);
    cJSON_AddNumberToObject(view, "byteLength", (double)bytes);
    cJSON_AddNumberToObject(accessor, "bufferView", (double)writer->view_count++);
    cJSON_AddNumberToObject(accessor, "componentType", component_type);
    cJSON_AddNumberToObject(accessor, "count", (double)count);
    cJSON_AddStringToObject(accessor, "type", type);
    writer->accessor_count++;
    return accessor;
}

/* Appends `count` elements of `components` floats as a new bufferView and
 * accessor; returns the accessor index. with_bounds adds min/max. */
static size_t write_float_accessor(gltf_writer *writer, const float *values, size_t count, unsigned components,
                                   const char *type, bool with_bounds)
{
    size_t offset = writer->bin.size, bytes = count * components * 4;
    if (!lk__buffer_reserve(&writer->bin, bytes)) {
        writer->failed = true;
        return 0;
    }
    double lo[4], hi[4];
    for (unsigned c = 0; c < components; c++) lo[c] = hi[c] = count ? values[c] : 0;
    for (size_t i = 0; i < count * components; i++) {
        lk__store_f32le(writer->bin.data + offset + 4 * i, values[i]);
        unsigned c = (unsigned)(i % components);
        if (values[i] < lo[c]) lo[c] = values[i];
        if (values[i] > hi[c]) hi[c] = values[i];
    }
    writer->bin.size += bytes;
    cJSON *accessor = add_view_accessor(writer, offset, bytes, COMPONENT_FLOAT, count, type);
    if (!accessor) return 0;
    if (with_bounds) {
        cJSON *min = cJSON_AddArrayToObject(accessor, "min"), *max = cJSON_AddArrayToObject(accessor, "max");
        for (unsigned c = 0; c < components; c++) {
            cJSON_AddItemToArray(min, cJSON_CreateNumber(lo[c]));
            cJSON_AddItemToArray(max, cJSON_CreateNumber(hi[c]));
        }
    }
    return writer->accessor_count - 1;
}

static char *base64_encode(const unsigned char *data, size_t size)
{
    static const char alphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    size_t out_size = (size + 2) / 3 * 4;
    char *out = malloc(out_size + 1);
    if (!out) return NULL;
    size_t o = 0;
    for (size_t i = 0; i < size; i += 3) {
        uint32_t chunk = (uint32_t)data[i] << 16;
        if (i + 1 < size) chunk |= (uint32_t)data[i + 1] << 8;
        if (i + 2 < size) chunk |= data[i + 2];
        out[o++] = alphabet[(chunk >> 18) & 63];
        out[o++] = alphabet[(chunk >> 12) & 63];
        out[o++] = i + 1 < size ? alphabet[(chunk >> 6) & 63] : '=';
        out[o++] = i + 2 < size ? alphabet[chunk & 63] : '=';
    }
    out[o] = '\0';
    return out;
}

lk_status lk__anim_write_gltf(FILE *file, const lk_animation *animation, const char *name, lk_error *error)
{
    const lk_mesh *mesh = &animation->mesh;
    size_t vertex_count = mesh->vertex_count, frame_count = animation->frame_count;
    if (frame_count > GLTF_WRITE_MAX_FRAMES)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: %zu frames: the glTF morph-target writer is limited to %d (its weights grow as "
                            "frames^2); use .kmf or .md2",
                            name, frame_count, GLTF_WRITE_MAX_FRAMES);
    if (vertex_count > UINT32_MAX) return lk_error_set(error, LK_ERR_LIMIT, "%s: too many vertices", name);
    gltf_writer writer;
    memset(&writer, 0, sizeof writer);
    cJSON *root = cJSON_CreateObject();
    char *text = NULL, *encoded = NULL;
    float *scratch = NULL;
    lk_status status = LK_OK;
    if (!root) goto nomem;
    cJSON *asset = cJSON_AddObjectToObject(root, "asset");
    cJSON_AddStringToObject(asset, "version", "2.0");
    cJSON_AddStringToObject(asset, "generator", "lodkit " LK_VERSION_STRING);
    cJSON_AddNumberToObject(root, "scene", 0);
    cJSON *scene = cJSON_CreateObject();
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scene);
    cJSON *scene_nodes = cJSON_AddArrayToObject(scene, "nodes");
    cJSON_AddItemToArray(scene_nodes, cJSON_CreateNumber(0));
    cJSON *node = cJSON_CreateObject();
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "nodes"), node);
    cJSON_AddNumberToObject(node, "mesh", 0);
    writer.accessors = cJSON_AddArrayToObject(root, "accessors");
    writer.views = cJSON_AddArrayToObject(root, "bufferViews");
    if (!writer.accessors || !writer.views) goto nomem;

    scratch = lk__malloc_array(vertex_count < frame_count ? frame_count : vertex_count, 4 * sizeof(float));
    if (!scratch) goto nomem;
    cJSON *gltf_mesh = cJSON_CreateObject();
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "meshes"), gltf_mesh);
    cJSON *primitive = cJSON_CreateObject();
    cJSON_AddItemToArray(cJSON_AddArrayToObject(gltf_mesh, "primitives"), primitive);
    cJSON *attributes = cJSON_AddObjectToObject(primitive, "attributes");
    cJSON_AddNumberToObject(attributes, "POSITION",
                            (double)write_float_accessor(&writer, animation->frame_positions, vertex_count, 3, "VEC3", true));
    if (mesh->normals)
        cJSON_AddNumberToObject(attributes, "NORMAL",
                                (double)write_float_accessor(&writer, mesh->normals, vertex_count, 3, "VEC3", false));
    if (mesh->texcoords) {
        /* lodkit's v points up, glTF's down. */
        for (size_t v = 0; v < vertex_count; v++) {
            scratch[2 * v] = mesh->texcoords[2 * v];
            scratch[2 * v + 1] = 1.0f - mesh->texcoords[2 * v + 1];
        }
        cJSON_AddNumberToObject(attributes, "TEXCOORD_0",
                                (double)write_float_accessor(&writer, scratch, vertex_count, 2, "VEC2", false));
    }
    if (mesh->colors)
        cJSON_AddNumberToObject(attributes, "COLOR_0",
                                (double)write_float_accessor(&writer, mesh->colors, vertex_count, 4, "VEC4", false));
    if (mesh->triangle_count) {
        size_t offset = writer.bin.size, bytes = mesh->triangle_count * 12;
        if (!lk__buffer_reserve(&writer.bin, bytes)) goto nomem;
        for (size_t i = 0; i < mesh->triangle_count * 3; i++)
            lk__store_u32le(writer.bin.data + offset + 4 * i, mesh->indices[i]);
        writer.bin.size += bytes;
        add_view_accessor(&writer, offset, bytes, COMPONENT_UNSIGNED_INT, mesh->triangle_count * 3, "SCALAR");
        cJSON_AddNumberToObject(primitive, "indices", (double)(writer.accessor_count - 1));
        cJSON_AddNumberToObject(primitive, "mode", MODE_TRIANGLES);
    } else {
        cJSON_AddNumberToObject(primitive, "mode", MODE_POINTS);
    }
    if (frame_count > 1) {
        cJSON *targets = cJSON_AddArrayToObject(primitive, "targets");
        cJSON *weights = cJSON_AddArrayToObject(gltf_mesh, "weights");
        for (size_t f = 1; f < frame_count && !writer.failed; f++) {
            const float *base = animation->frame_positions, *frame = base + f * vertex_count * 3;
            for (size_t i = 0; i < vertex_count * 3; i++) scratch[i] = frame[i] - base[i];
            cJSON *target = cJSON_CreateObject();
            cJSON_AddItemToArray(targets, target);
            cJSON_AddNumberToObject(target, "POSITION",
                                    (double)write_float_accessor(&writer, scratch, vertex_count, 3, "VEC3", true));
            cJSON_AddItemToArray(weights, cJSON_CreateNumber(0));
        }
        for (size_t f = 0; f < frame_count; f++) scratch[f] = (float)((double)f / animation->frames_per_second);
        size_t input = write_float_accessor(&writer, scratch, frame_count, 1, "SCALAR", true);
        /* Weights: key f selects target f-1. Written in rows to keep the
         * scratch small. */
        size_t target_count = frame_count - 1, offset = writer.bin.size;
        size_t bytes = frame_count * target_count * 4;
        if (!lk__buffer_reserve(&writer.bin, bytes)) goto nomem;
        memset(writer.bin.data + offset, 0, bytes);
        for (size_t f = 1; f < frame_count; f++)
            lk__store_f32le(writer.bin.data + offset + 4 * (f * target_count + (f - 1)), 1.0f);
        writer.bin.size += bytes;
        add_view_accessor(&writer, offset, bytes, COMPONENT_FLOAT, frame_count * target_count, "SCALAR");
        size_t output = writer.accessor_count - 1;
        cJSON *gltf_animation = cJSON_CreateObject();
        cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "animations"), gltf_animation);
        cJSON *sampler = cJSON_CreateObject(), *channel = cJSON_CreateObject();
        cJSON_AddItemToArray(cJSON_AddArrayToObject(gltf_animation, "samplers"), sampler);
        cJSON_AddItemToArray(cJSON_AddArrayToObject(gltf_animation, "channels"), channel);
        cJSON_AddNumberToObject(sampler, "input", (double)input);
        cJSON_AddNumberToObject(sampler, "output", (double)output);
        cJSON_AddStringToObject(sampler, "interpolation", "LINEAR");
        cJSON_AddNumberToObject(channel, "sampler", 0);
        cJSON *target = cJSON_AddObjectToObject(channel, "target");
        cJSON_AddNumberToObject(target, "node", 0);
        cJSON_AddStringToObject(target, "path", "weights");
    }
    if (writer.failed) goto nomem;
    encoded = base64_encode(writer.bin.data ? writer.bin.data : (const unsigned char *)"", writer.bin.size);
    if (!encoded) goto nomem;
    {
        static const char prefix[] = "data:application/octet-stream;base64,";
        size_t length = strlen(prefix) + strlen(encoded);
        char *uri = malloc(length + 1);
        if (!uri) goto nomem;
        strcpy(uri, prefix);
        strcat(uri, encoded);
        cJSON *buffer = cJSON_CreateObject();
        cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "buffers"), buffer);
        cJSON_AddNumberToObject(buffer, "byteLength", (double)writer.bin.size);
        cJSON *uri_item = cJSON_AddStringToObject(buffer, "uri", uri);
        free(uri);
        if (!uri_item) goto nomem;
    }
    text = cJSON_Print(root);
    if (!text) goto nomem;
    if (fputs(text, file) == EOF || fputc('\n', file) == EOF || ferror(file))
        status = lk_error_set(error, LK_ERR_IO, "%s: write error", name);
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory while building the glTF", name);
done:
    free(text);
    free(encoded);
    free(scratch);
    lk__buffer_free(&writer.bin);
    cJSON_Delete(root);
    return status;
}
