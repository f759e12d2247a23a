/* SPDX-License-Identifier: MIT */
/* The glTF 2.0 document model shared by the mesh reader (io_gltf.c) and
 * the animation reader (io_gltf_anim.c): errors that name the JSON
 * location, typed access to JSON members, the top-level tables, the checks
 * of the whole document, buffers (GLB BIN chunk, base64 data: URIs,
 * external files below the model's folder), accessors, and the two
 * containers (JSON text parsed under the read's budget, the GLB chunks).
 *
 * Every count and offset in the JSON is checked against the bytes really
 * available (64-bit arithmetic, JSON integers limited to 2^53 so nothing
 * overflows) before it is used. */
#include "bytes.h"
#include "io_gltf.h"

#include <meshoptimizer.h>

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

/* ---- errors ------------------------------------------------------------ */

#if defined(__GNUC__)
__attribute__((format(printf, 5, 6)))
#endif
/* Sets "NAME: WHERE.KEY: message" (KEY may be NULL, WHERE may be ""). */
lk_status
lk__gltf_fail(const gltf_reader *reader, lk_status status, const char *where, const char *key, const char *format, ...)
{
    char message[400];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    const char *separator = where[0] && key && key[0] != '[' ? "." : "";
    return lk_error_set(reader->error, status, "%s: %s%s%s: %s", reader->ctx->name, where, separator, key ? key : "",
                        message);
}

lk_status lk__gltf_nomem(const gltf_reader *reader)
{
    return lk_error_set(reader->error, LK_ERR_NOMEM, "%s: out of memory", reader->ctx->name);
}

lk_status lk__gltf_over_budget(const gltf_reader *reader)
{
    return lk_error_set(reader->error, LK_ERR_LIMIT, "%s: the scene needs more than the memory budget of %zu bytes",
                        reader->ctx->name, reader->ctx->budget->limit);
}

/* Scratch arrays that grow with the document (per node, per table entry)
 * are charged to the read's budget: count * size bytes, zeroed, or NULL
 * with *status set. Free them with lk__gltf_charged_free(). */
void *lk__gltf_charged_calloc(const gltf_reader *reader, size_t count, size_t size, lk_status *status)
{
    if (!lk__budget_charge(reader->ctx->budget, count, size)) {
        *status = lk__gltf_over_budget(reader);
        return NULL;
    }
    void *memory = lk__calloc_array(count, size);
    if (!memory) {
        lk__budget_release(reader->ctx->budget, count, size);
        *status = lk__gltf_nomem(reader);
    }
    return memory;
}

void lk__gltf_charged_free(const gltf_reader *reader, void *memory, size_t count, size_t size)
{
    if (!memory) return;
    free(memory);
    lk__budget_release(reader->ctx->budget, count, size);
}

const char *lk__gltf_json_type_name(const cJSON *item)
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

const cJSON *lk__gltf_member(const cJSON *object, const char *key)
{
    return cJSON_GetObjectItemCaseSensitive(object, key);
}

bool lk__gltf_is_json_uint(const cJSON *item)
{
    if (!cJSON_IsNumber(item)) return false;
    double value = item->valuedouble;
    return value >= 0.0 && value <= JSON_MAX_INTEGER && value == floor(value);
}

lk_status lk__gltf_check_uint(const gltf_reader *reader, const cJSON *item, const char *where, const char *key)
{
    if (!cJSON_IsNumber(item))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, key, "expected a non-negative integer, got %s",
                             lk__gltf_json_type_name(item));
    if (!lk__gltf_is_json_uint(item))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, key, "expected a non-negative integer, got %g",
                             item->valuedouble);
    return LK_OK;
}

/* Optional (or required) non-negative integer member. */
lk_status lk__gltf_get_uint(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                            bool required, uint64_t default_value, uint64_t *out)
{
    const cJSON *item = lk__gltf_member(object, key);
    *out = default_value;
    if (!item) {
        if (required) return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"%s\"", key);
        return LK_OK;
    }
    lk_status status = lk__gltf_check_uint(reader, item, where, key);
    if (status != LK_OK) return status;
    *out = (uint64_t)item->valuedouble;
    return LK_OK;
}

static lk_status get_number(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                            double default_value, double *out)
{
    const cJSON *item = lk__gltf_member(object, key);
    *out = default_value;
    if (!item) return LK_OK;
    if (!cJSON_IsNumber(item))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, key, "expected a number, got %s",
                             lk__gltf_json_type_name(item));
    if (!isfinite(item->valuedouble)) return lk__gltf_fail(reader, LK_ERR_RANGE, where, key, "number is not finite");
    *out = item->valuedouble;
    return LK_OK;
}

/* Optional member of a given cJSON type (cJSON_String, cJSON_Object, ...);
 * *out is NULL when absent. */
static lk_status get_typed(const gltf_reader *reader, const cJSON *object, const char *where, const char *key, int type,
                           const char *type_name, const cJSON **out)
{
    const cJSON *item = lk__gltf_member(object, key);
    *out = NULL;
    if (!item) return LK_OK;
    if ((item->type & 0xFF) != type)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, key, "expected %s, got %s", type_name,
                             lk__gltf_json_type_name(item));
    *out = item;
    return LK_OK;
}

lk_status lk__gltf_get_object(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                              const cJSON **out)
{
    return get_typed(reader, object, where, key, cJSON_Object, "an object", out);
}

lk_status lk__gltf_get_array(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                             const cJSON **out)
{
    return get_typed(reader, object, where, key, cJSON_Array, "an array", out);
}

lk_status lk__gltf_get_string(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                              const cJSON **out)
{
    return get_typed(reader, object, where, key, cJSON_String, "a string", out);
}

static lk_status get_bool(const gltf_reader *reader, const cJSON *object, const char *where, const char *key, bool *out)
{
    const cJSON *item = lk__gltf_member(object, key);
    *out = false;
    if (!item) return LK_OK;
    if (!cJSON_IsBool(item))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, key, "expected true or false, got %s",
                             lk__gltf_json_type_name(item));
    *out = cJSON_IsTrue(item);
    return LK_OK;
}

/* Optional array of exactly `count` finite numbers; *present says whether
 * it was there (values untouched otherwise). */
lk_status lk__gltf_get_number_array(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                                    size_t count, double *values, bool *present)
{
    const cJSON *array;
    if (present) *present = false;
    lk_status status = lk__gltf_get_array(reader, object, where, key, &array);
    if (status != LK_OK || !array) return status;
    size_t found = (size_t)cJSON_GetArraySize(array);
    if (found != count)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, key, "expected %zu numbers, got %zu", count, found);
    size_t i = 0;
    const cJSON *item;
    cJSON_ArrayForEach(item, array)
    {
        if (!cJSON_IsNumber(item))
            return lk__gltf_fail(reader, LK_ERR_PARSE, where, key, "element %zu: expected a number, got %s", i,
                                 lk__gltf_json_type_name(item));
        if (!isfinite(item->valuedouble))
            return lk__gltf_fail(reader, LK_ERR_RANGE, where, key, "element %zu is not finite", i);
        values[i++] = item->valuedouble;
    }
    if (present) *present = true;
    return LK_OK;
}

void lk__gltf_table_free(const gltf_reader *reader, json_table *table)
{
    lk__gltf_charged_free(reader, table->items, table->allocated, sizeof *table->items);
    table->items = NULL;
    table->count = table->allocated = 0;
}

/* Turns an optional top-level array of objects into a table. */
lk_status lk__gltf_build_table(gltf_reader *reader, const char *key, json_table *table)
{
    const cJSON *array;
    table->items = NULL;
    table->count = table->allocated = 0;
    lk_status status = lk__gltf_get_array(reader, reader->root, "", key, &array);
    if (status != LK_OK || !array) return status;
    size_t count = (size_t)cJSON_GetArraySize(array);
    table->items = lk__gltf_charged_calloc(reader, count, sizeof *table->items, &status);
    if (!table->items) return status;
    table->allocated = count;
    const cJSON *item;
    cJSON_ArrayForEach(item, array)
    {
        if (!cJSON_IsObject(item))
            return lk__gltf_fail(reader, LK_ERR_PARSE, "", key, "element %zu: expected an object, got %s", table->count,
                                 lk__gltf_json_type_name(item));
        table->items[table->count++] = item;
    }
    return LK_OK;
}

/* Resolves a reference `WHERE.KEY: index` into `table`, which is the
 * top-level array `table_name` ("accessors"); `what` is one element
 * ("accessor"). */
lk_status lk__gltf_resolve(const gltf_reader *reader, const json_table *table, const char *what, const char *table_name,
                           uint64_t index, const char *where, const char *key, const cJSON **out)
{
    *out = NULL;
    if (index >= table->count)
        return lk__gltf_fail(reader, LK_ERR_RANGE, where, key, "%s %llu out of range (%zu %s)", what,
                             (unsigned long long)index, table->count, table->count == 1 ? what : table_name);
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
    static const char *const names[] = {"KHR_mesh_quantization", "KHR_lights_punctual",    "KHR_technique_webgl",
                                        "KHR_xmp_json_ld",       "EXT_lights_image_based", "EXT_meshopt_compression"};
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
        lk_status status = lk__gltf_get_array(reader, reader->root, "", keys[k], &list);
        if (status != LK_OK) return status;
        size_t i = 0;
        const cJSON *item;
        cJSON_ArrayForEach(item, list)
        {
            char where[64];
            snprintf(where, sizeof where, "%s[%zu]", keys[k], i++);
            if (!cJSON_IsString(item))
                return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "expected a string, got %s",
                                     lk__gltf_json_type_name(item));
            if (k == 0 || extension_is_harmless(item->valuestring)) continue;
            if (strcmp(item->valuestring, "KHR_draco_mesh_compression") == 0)
                return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, NULL,
                                     "Draco-compressed meshes (KHR_draco_mesh_compression) are not supported (Debian's "
                                     "libdraco has no C interface): decompress the file with a Draco-aware glTF tool, "
                                     "or export it with EXT_meshopt_compression, which lodkit reads");
            return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, NULL, "required extension \"%s\" is not supported",
                                 item->valuestring);
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
    cJSON_ArrayForEach(child, item)
    {
        if (cJSON_IsArray(item)) {
            snprintf(path + length, capacity - length, "[%zu]", index++);
        } else {
            if (strcmp(child->string, "extras") == 0) continue;
            snprintf(path + length, capacity - length, "%s%s", length ? "." : "", child->string);
            if (strcmp(child->string, "name") == 0 && !cJSON_IsString(child))
                return lk__gltf_fail(reader, LK_ERR_PARSE, path, NULL, "expected a string, got %s",
                                     lk__gltf_json_type_name(child));
            if (strcmp(child->string, "extensions") == 0) {
                if (!cJSON_IsObject(child))
                    return lk__gltf_fail(reader, LK_ERR_PARSE, path, NULL, "expected an object, got %s",
                                         lk__gltf_json_type_name(child));
                const cJSON *extension;
                cJSON_ArrayForEach(extension, child)
                {
                    if (!cJSON_IsObject(extension))
                        return lk__gltf_fail(reader, LK_ERR_PARSE, path, extension->string,
                                             "expected an object, got %s", lk__gltf_json_type_name(extension));
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

static lk_status check_texture_info(const gltf_reader *reader, const cJSON *object, const char *where, const char *key)
{
    const cJSON *info;
    lk_status status = lk__gltf_get_object(reader, object, where, key, &info);
    if (status != LK_OK || !info) return status;
    char info_where[128];
    snprintf(info_where, sizeof info_where, "%s.%s", where, key);
    uint64_t index, texcoord;
    double factor;
    if ((status = lk__gltf_get_uint(reader, info, info_where, "index", true, 0, &index)) != LK_OK) return status;
    if ((status = lk__gltf_get_uint(reader, info, info_where, "texCoord", false, 0, &texcoord)) != LK_OK) return status;
    if ((status = get_number(reader, info, info_where, "scale", 1.0, &factor)) != LK_OK) return status;
    return get_number(reader, info, info_where, "strength", 1.0, &factor);
}

/* Materials are not used, but a wrongly typed material means a broken
 * exporter, and a strict reader should say so rather than guess. */
static lk_status check_materials(const gltf_reader *reader)
{
    const cJSON *array = lk__gltf_member(reader->root, "materials");
    size_t index = 0;
    const cJSON *material;
    cJSON_ArrayForEach(material, array)
    {
        char where[64];
        snprintf(where, sizeof where, "materials[%zu]", index++);
        const cJSON *pbr, *text;
        double values[4], factor;
        bool flag;
        lk_status status = lk__gltf_get_object(reader, material, where, "pbrMetallicRoughness", &pbr);
        if (status == LK_OK && pbr) {
            char pbr_where[96];
            snprintf(pbr_where, sizeof pbr_where, "%s.pbrMetallicRoughness", where);
            status = lk__gltf_get_number_array(reader, pbr, pbr_where, "baseColorFactor", 4, values, NULL);
            if (status == LK_OK) status = get_number(reader, pbr, pbr_where, "metallicFactor", 1.0, &factor);
            if (status == LK_OK) status = get_number(reader, pbr, pbr_where, "roughnessFactor", 1.0, &factor);
            if (status == LK_OK) status = check_texture_info(reader, pbr, pbr_where, "baseColorTexture");
            if (status == LK_OK) status = check_texture_info(reader, pbr, pbr_where, "metallicRoughnessTexture");
        }
        if (status == LK_OK) status = check_texture_info(reader, material, where, "normalTexture");
        if (status == LK_OK) status = check_texture_info(reader, material, where, "occlusionTexture");
        if (status == LK_OK) status = check_texture_info(reader, material, where, "emissiveTexture");
        if (status == LK_OK)
            status = lk__gltf_get_number_array(reader, material, where, "emissiveFactor", 3, values, NULL);
        if (status == LK_OK) status = lk__gltf_get_string(reader, material, where, "alphaMode", &text);
        if (status == LK_OK) status = get_number(reader, material, where, "alphaCutoff", 0.5, &factor);
        if (status == LK_OK) status = get_bool(reader, material, where, "doubleSided", &flag);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

lk_status lk__gltf_check_document(gltf_reader *reader)
{
    if (!cJSON_IsObject(reader->root))
        return lk_error_set(reader->error, LK_ERR_PARSE, "%s: expected a JSON object at the top level, got %s",
                            reader->ctx->name, lk__gltf_json_type_name(reader->root));
    const cJSON *asset, *version;
    lk_status status = lk__gltf_get_object(reader, reader->root, "", "asset", &asset);
    if (status != LK_OK) return status;
    if (!asset) return lk__gltf_fail(reader, LK_ERR_PARSE, "", "asset", "missing (not a glTF 2.0 file?)");
    status = lk__gltf_get_string(reader, asset, "asset", "version", &version);
    if (status != LK_OK) return status;
    if (!version) return lk__gltf_fail(reader, LK_ERR_PARSE, "asset", "version", "missing");
    if (version->valuestring[0] != '2' || (version->valuestring[1] != '\0' && version->valuestring[1] != '.'))
        return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, "asset", "version",
                             "glTF version \"%s\" is not supported (only 2.x)", version->valuestring);
    status = check_extension_lists(reader);
    if (status != LK_OK) return status;

    /* Every top-level array of the specification must hold objects. */
    static const char *const arrays[] = {"animations", "cameras", "images",  "materials",
                                         "samplers",   "skins",   "textures"};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; i++) {
        json_table table;
        status = lk__gltf_build_table(reader, arrays[i], &table);
        lk__gltf_table_free(reader, &table);
        if (status != LK_OK) return status;
    }
    if ((status = lk__gltf_build_table(reader, "accessors", &reader->accessors)) != LK_OK) return status;
    if ((status = lk__gltf_build_table(reader, "bufferViews", &reader->buffer_views)) != LK_OK) return status;
    if ((status = lk__gltf_build_table(reader, "buffers", &reader->buffers_json)) != LK_OK) return status;
    if ((status = lk__gltf_build_table(reader, "meshes", &reader->meshes)) != LK_OK) return status;
    if ((status = lk__gltf_build_table(reader, "nodes", &reader->nodes)) != LK_OK) return status;
    if ((status = lk__gltf_build_table(reader, "scenes", &reader->scenes)) != LK_OK) return status;

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
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "uri", "base64 data has misplaced '=' padding");
    if (length % 4 == 1)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "uri", "base64 data is truncated (%zu characters)", length);
    size_t size = length / 4 * 3 + (length % 4 ? length % 4 - 1 : 0);
    unsigned char *bytes = lk__malloc_array(size, 1);
    if (!bytes) return lk__gltf_fail(reader, LK_ERR_NOMEM, where, "uri", "cannot allocate %zu bytes", size);
    size_t written = 0;
    uint32_t bits = 0;
    int bit_count = 0;
    for (size_t i = 0; i < length; i++) {
        int value = base64_value((unsigned char)text[i]);
        if (value < 0) {
            free(bytes);
            unsigned char c = (unsigned char)text[i];
            if (c > ' ' && c < 0x7F)
                return lk__gltf_fail(reader, LK_ERR_PARSE, where, "uri",
                                     "invalid base64 character '%c' at position %zu of the data", c, i);
            return lk__gltf_fail(reader, LK_ERR_PARSE, where, "uri",
                                 "invalid base64 character 0x%02X at position %zu of the data", c, i);
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
    if (length == 0) return lk__gltf_fail(reader, LK_ERR_PARSE, where, "uri", "empty uri");
    /* A scheme ("http:", "file:", "C:") comes before any '/'. */
    const char *colon = strchr(uri, ':');
    const char *slash = strchr(uri, '/');
    if (colon && (!slash || colon < slash))
        return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, "uri",
                             "\"%.100s\": only data: URIs and relative file paths are supported", uri);
    char *path = malloc(length + 1);
    if (!path) return lk__gltf_fail(reader, LK_ERR_NOMEM, where, "uri", "out of memory");
    size_t written = 0;
    for (size_t i = 0; i < length; i++) {
        char c = uri[i];
        if (c == '%') {
            int digits[2] = {-1, -1};
            for (int k = 0; k < 2 && i + 1 + (size_t)k < length; k++) {
                char h = uri[i + 1 + (size_t)k];
                if (h >= '0' && h <= '9')
                    digits[k] = h - '0';
                else if (h >= 'a' && h <= 'f')
                    digits[k] = h - 'a' + 10;
                else if (h >= 'A' && h <= 'F')
                    digits[k] = h - 'A' + 10;
            }
            if (digits[0] < 0 || digits[1] < 0 || (digits[0] == 0 && digits[1] == 0)) {
                free(path);
                return lk__gltf_fail(reader, LK_ERR_PARSE, where, "uri", "\"%.100s\": invalid %%-escape", uri);
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
        return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, "uri",
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
        return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, "uri",
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
            status = lk__gltf_fail(reader, LK_ERR_IO, where, "uri", "cannot open \"%.100s\": %s", uri,
                                   strerror(reason_errno));
        else
            status = lk__gltf_fail(reader, LK_ERR_IO, where, "uri",
                                   "\"%.100s\": %.200s; external files must be regular files inside the model's folder",
                                   uri, reason);
        free(relative);
        return status;
    }
    if (byte_length == UINT64_MAX) byte_length = (uint64_t)info.st_size; /* an image: the whole file */
    if ((uint64_t)info.st_size < byte_length) {
        status = lk__gltf_fail(reader, LK_ERR_RANGE, where, "byteLength", "%llu bytes but \"%.100s\" has only %llu",
                               (unsigned long long)byte_length, uri, (unsigned long long)info.st_size);
    } else if (byte_length > lk__budget_room(reader->ctx->budget)) {
        status = lk__gltf_fail(reader, LK_ERR_LIMIT, where, "byteLength",
                               "%llu bytes is more than the memory budget of %zu (buffers already hold %zu)",
                               (unsigned long long)byte_length, reader->ctx->budget->limit, reader->buffer_bytes);
    } else {
        buffer->owned = lk__malloc_array((size_t)byte_length, 1);
        if (!buffer->owned) {
            status = lk__gltf_fail(reader, LK_ERR_NOMEM, where, NULL, "cannot allocate %llu bytes",
                                   (unsigned long long)byte_length);
        } else if (lk__read_prefix(fd, &info, relative, (size_t)byte_length, buffer->owned, &opened) != LK_OK) {
            status = lk__gltf_fail(reader, LK_ERR_IO, where, "uri", "%.300s", opened.message);
        } else {
            buffer->data = buffer->owned;
            buffer->size = (size_t)byte_length;
        }
    }
    close(fd);
    free(relative);
    return status;
}

/* The bytes a uri names (images): a base64 data: URI or a file next to the
 * document, whole, in a new array charged to the read's budget (release
 * with lk__budget_release(budget, *size, 1) and free). */
lk_status lk__gltf_uri_bytes(gltf_reader *reader, const char *uri, const char *where, unsigned char **out, size_t *size)
{
    *out = NULL;
    *size = 0;
    lk_status status;
    if (strncmp(uri, "data:", 5) == 0) {
        const char *comma = strchr(uri, ',');
        if (!comma || comma - uri < 12 || strncmp(comma - 7, ";base64", 7) != 0)
            return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, "uri", "only base64 data: URIs are supported");
        size_t text_length = strlen(comma + 1), decoded = text_length / 4 * 3 + 3;
        if (!lk__budget_charge(reader->ctx->budget, decoded, 1))
            return lk__gltf_fail(reader, LK_ERR_LIMIT, where, "uri",
                                 "%zu bytes of base64 data would exceed the memory budget of %zu bytes", text_length,
                                 reader->ctx->budget->limit);
        status = base64_decode(reader, comma + 1, text_length, where, out, size);
        lk__budget_release(reader->ctx->budget, decoded, 1);
        if (status == LK_OK) lk__budget_charge(reader->ctx->budget, *size, 1); /* size <= decoded */
        return status;
    }
    gltf_buffer file;
    memset(&file, 0, sizeof file);
    status = load_external_file(reader, &file, uri, where, UINT64_MAX);
    if (status != LK_OK) {
        free(file.owned);
        return status;
    }
    lk__budget_charge(reader->ctx->budget, file.size, 1); /* load_external_file checked the room */
    *out = file.owned;
    *size = file.size;
    return LK_OK;
}

/* Makes buffers[index] available (GLB chunk, data: URI or external file). */
static lk_status load_buffer(gltf_reader *reader, uint64_t index, const char *referrer, const char *key,
                             const gltf_buffer **out);

/* A bufferView compressed with EXT_meshopt_compression (meshoptimizer's
 * codecs, Debian's libmeshoptimizer): the extension names the compressed
 * bytes (buffer, byteOffset, byteLength) and what they decode to (count
 * elements of byteStride bytes, mode ATTRIBUTES, TRIANGLES or INDICES,
 * filter NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL); the view's own
 * buffer is then usually a fallback without data. Decoded once, charged to
 * the read's budget; *out is the decoded view, byteLength bytes. */
static lk_status decode_meshopt_view(gltf_reader *reader, uint64_t view_index, const cJSON *extension,
                                     const char *view_where, uint64_t view_length, const gltf_buffer **out)
{
    lk_status status = LK_OK;
    if (!reader->decoded_views) {
        reader->decoded_views =
            lk__gltf_charged_calloc(reader, reader->buffer_views.count, sizeof *reader->decoded_views, &status);
        if (status != LK_OK) return status;
    }
    gltf_buffer *decoded = &reader->decoded_views[view_index];
    *out = decoded;
    if (decoded->loaded) return LK_OK;
    char where[128];
    snprintf(where, sizeof where, "%s.extensions.EXT_meshopt_compression", view_where);
    if (!cJSON_IsObject(extension))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "expected an object, got %s",
                             lk__gltf_json_type_name(extension));
    uint64_t buffer_index, offset, length, stride, count;
    if ((status = lk__gltf_get_uint(reader, extension, where, "buffer", true, 0, &buffer_index)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, extension, where, "byteOffset", false, 0, &offset)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, extension, where, "byteLength", true, 0, &length)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, extension, where, "byteStride", true, 0, &stride)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, extension, where, "count", true, 0, &count)) != LK_OK)
        return status;
    const cJSON *mode_item, *filter_item;
    if ((status = lk__gltf_get_string(reader, extension, where, "mode", &mode_item)) != LK_OK ||
        (status = lk__gltf_get_string(reader, extension, where, "filter", &filter_item)) != LK_OK)
        return status;
    if (!mode_item) return lk__gltf_fail(reader, LK_ERR_PARSE, where, "mode", "is missing");
    const char *mode = mode_item->valuestring, *filter = filter_item ? filter_item->valuestring : "NONE";
    bool attributes = strcmp(mode, "ATTRIBUTES") == 0, triangles = strcmp(mode, "TRIANGLES") == 0,
         indices = strcmp(mode, "INDICES") == 0;
    if (!attributes && !triangles && !indices)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "mode", "\"%s\" is not ATTRIBUTES, TRIANGLES or INDICES",
                             mode);
    if (attributes ? stride == 0 || stride % 4 || stride > 256 : stride != 2 && stride != 4)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "byteStride", "%llu is not valid for mode %s",
                             (unsigned long long)stride, mode);
    if (triangles && count % 3)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "count", "%llu is not a multiple of 3 for TRIANGLES",
                             (unsigned long long)count);
    bool octahedral = strcmp(filter, "OCTAHEDRAL") == 0, quaternion = strcmp(filter, "QUATERNION") == 0,
         exponential = strcmp(filter, "EXPONENTIAL") == 0;
    if (!octahedral && !quaternion && !exponential && strcmp(filter, "NONE") != 0)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "filter",
                             "\"%s\" is not NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL", filter);
    if ((octahedral || quaternion || exponential) && !attributes)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "filter", "filters apply to ATTRIBUTES only");
    if ((octahedral && stride != 4 && stride != 8) || (quaternion && stride != 8))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "byteStride", "%llu does not suit filter %s",
                             (unsigned long long)stride, filter);
    if (count == 0 || count > LK_MAX_ELEMENTS || stride * count != view_length)
        return lk__gltf_fail(reader, LK_ERR_RANGE, where, "count",
                             "%llu x byteStride %llu is not the bufferView's byteLength %llu",
                             (unsigned long long)count, (unsigned long long)stride, (unsigned long long)view_length);
    const gltf_buffer *source;
    if ((status = load_buffer(reader, buffer_index, where, "buffer", &source)) != LK_OK) return status;
    if (offset + length > source->size)
        return lk__gltf_fail(
            reader, LK_ERR_RANGE, where, NULL, "byteOffset %llu + byteLength %llu exceeds buffer %llu (%zu bytes)",
            (unsigned long long)offset, (unsigned long long)length, (unsigned long long)buffer_index, source->size);
    if (!lk__budget_charge(reader->ctx->budget, (size_t)view_length, 1)) return lk__gltf_over_budget(reader);
    decoded->owned = malloc((size_t)view_length);
    if (!decoded->owned) {
        lk__budget_release(reader->ctx->budget, (size_t)view_length, 1);
        return lk__gltf_nomem(reader);
    }
    reader->buffer_bytes += (size_t)view_length;
    const unsigned char *bytes = source->data + offset;
    int failed =
        attributes  ? meshopt_decodeVertexBuffer(decoded->owned, (size_t)count, (size_t)stride, bytes, (size_t)length)
        : triangles ? meshopt_decodeIndexBuffer(decoded->owned, (size_t)count, (size_t)stride, bytes, (size_t)length)
                    : meshopt_decodeIndexSequence(decoded->owned, (size_t)count, (size_t)stride, bytes, (size_t)length);
    if (failed)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL,
                             "the %llu compressed bytes do not decode to %llu elements of %llu bytes (%s, error %d)",
                             (unsigned long long)length, (unsigned long long)count, (unsigned long long)stride, mode,
                             failed);
    if (octahedral) meshopt_decodeFilterOct(decoded->owned, (size_t)count, (size_t)stride);
    if (quaternion) meshopt_decodeFilterQuat(decoded->owned, (size_t)count, (size_t)stride);
    if (exponential) meshopt_decodeFilterExp(decoded->owned, (size_t)count, (size_t)stride);
    decoded->data = decoded->owned;
    decoded->size = (size_t)view_length;
    decoded->loaded = true;
    return LK_OK;
}

static lk_status load_buffer(gltf_reader *reader, uint64_t index, const char *referrer, const char *key,
                             const gltf_buffer **out)
{
    const cJSON *object = NULL;
    lk_status status =
        lk__gltf_resolve(reader, &reader->buffers_json, "buffer", "buffers", index, referrer, key, &object);
    if (status != LK_OK) return status;
    gltf_buffer *buffer = &reader->buffers[index];
    *out = buffer;
    if (buffer->loaded) return LK_OK;
    char where[48];
    snprintf(where, sizeof where, "buffers[%llu]", (unsigned long long)index);
    uint64_t byte_length;
    const cJSON *uri;
    if ((status = lk__gltf_get_uint(reader, object, where, "byteLength", true, 0, &byte_length)) != LK_OK)
        return status;
    if (byte_length == 0) return lk__gltf_fail(reader, LK_ERR_PARSE, where, "byteLength", "must be at least 1");
    if ((status = lk__gltf_get_string(reader, object, where, "uri", &uri)) != LK_OK) return status;

    if (!uri) {
        if (!reader->is_glb || index != 0 || !reader->has_bin_chunk)
            return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL,
                                 reader->is_glb && index == 0
                                     ? "has no uri and the .glb file has no BIN chunk"
                                     : "has no uri (only buffer 0 of a .glb file may omit it)");
        if (byte_length > reader->bin_chunk_size)
            return lk__gltf_fail(reader, LK_ERR_RANGE, where, "byteLength", "%llu bytes but the BIN chunk has only %zu",
                                 (unsigned long long)byte_length, reader->bin_chunk_size);
        buffer->data = reader->bin_chunk;
        buffer->size = (size_t)byte_length;
    } else if (strncmp(uri->valuestring, "data:", 5) == 0) {
        const char *text = uri->valuestring;
        const char *comma = strchr(text, ',');
        if (!comma || comma - text < 12 || strncmp(comma - 7, ";base64", 7) != 0)
            return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, "uri", "only base64 data: URIs are supported");
        size_t size, text_length = strlen(comma + 1);
        /* The decoded bytes count against the budget with the rest. */
        size_t decoded = text_length / 4 * 3 + 3;
        if (!lk__budget_charge(reader->ctx->budget, decoded, 1))
            return lk__gltf_fail(
                reader, LK_ERR_LIMIT, where, "uri",
                "%zu bytes of base64 data would exceed the memory budget of %zu bytes (buffers hold %zu)", text_length,
                reader->ctx->budget->limit, reader->buffer_bytes);
        status = base64_decode(reader, comma + 1, text_length, where, &buffer->owned, &size);
        lk__budget_release(reader->ctx->budget, decoded, 1);
        if (status != LK_OK) return status;
        lk__budget_charge(reader->ctx->budget, size, 1); /* size <= decoded */
        reader->buffer_bytes += size;
        if (size < byte_length)
            return lk__gltf_fail(reader, LK_ERR_RANGE, where, "byteLength",
                                 "%llu bytes but the data: URI holds only %zu", (unsigned long long)byte_length, size);
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
/* The bytes of bufferViews[view_index], referred to by `referrer`.`key`:
 * checked against its buffer (loaded, or decoded from
 * EXT_meshopt_compression, on first use); *byte_stride is 0 when absent. */
lk_status lk__gltf_view_bytes(gltf_reader *reader, uint64_t view_index, const char *referrer, const char *key,
                              const unsigned char **data, uint64_t *length, uint64_t *byte_stride)
{
    const cJSON *view = NULL;
    lk_status status;
    if ((status = lk__gltf_resolve(reader, &reader->buffer_views, "bufferView", "bufferViews", view_index, referrer,
                                   key, &view)) != LK_OK)
        return status;
    char view_where[48];
    snprintf(view_where, sizeof view_where, "bufferViews[%llu]", (unsigned long long)view_index);
    uint64_t buffer_index, view_offset, view_length;
    if ((status = lk__gltf_get_uint(reader, view, view_where, "buffer", true, 0, &buffer_index)) != LK_OK)
        return status;
    if ((status = lk__gltf_get_uint(reader, view, view_where, "byteOffset", false, 0, &view_offset)) != LK_OK)
        return status;
    if ((status = lk__gltf_get_uint(reader, view, view_where, "byteLength", true, 0, &view_length)) != LK_OK)
        return status;
    if ((status = lk__gltf_get_uint(reader, view, view_where, "byteStride", false, 0, byte_stride)) != LK_OK)
        return status;
    if (view_length == 0) return lk__gltf_fail(reader, LK_ERR_PARSE, view_where, "byteLength", "must be at least 1");
    if (lk__gltf_member(view, "byteStride") && (*byte_stride < 4 || *byte_stride > 252))
        return lk__gltf_fail(reader, LK_ERR_PARSE, view_where, "byteStride", "%llu is outside 4..252",
                             (unsigned long long)*byte_stride);
    const gltf_buffer *buffer;
    const cJSON *extensions = lk__gltf_member(view, "extensions");
    const cJSON *meshopt = cJSON_IsObject(extensions) ? lk__gltf_member(extensions, "EXT_meshopt_compression") : NULL;
    if (meshopt)
        status = decode_meshopt_view(reader, view_index, meshopt, view_where, view_length, &buffer);
    else
        status = load_buffer(reader, buffer_index, view_where, "buffer", &buffer);
    if (status != LK_OK) return status;
    if (meshopt) view_offset = 0; /* the decoded view is its own buffer */
    /* All values are <= 2^53, so these sums cannot overflow 64 bits. */
    if (view_offset + view_length > buffer->size)
        return lk__gltf_fail(reader, LK_ERR_RANGE, view_where, NULL,
                             "byteOffset %llu + byteLength %llu exceeds buffer %llu (%zu bytes)",
                             (unsigned long long)view_offset, (unsigned long long)view_length,
                             (unsigned long long)buffer_index, buffer->size);
    *data = buffer->data + view_offset;
    *length = view_length;
    return LK_OK;
}

lk_status lk__gltf_open_accessor(gltf_reader *reader, uint64_t index, const char *referrer, const char *key,
                                 unsigned type_mask, bool is_index, const char *expected, gltf_accessor *out)
{
    const cJSON *object = NULL;
    lk_status status =
        lk__gltf_resolve(reader, &reader->accessors, "accessor", "accessors", index, referrer, key, &object);
    if (status != LK_OK) return status;
    char where[48];
    snprintf(where, sizeof where, "accessors[%llu]", (unsigned long long)index);
    memset(out, 0, sizeof *out);
    out->index = (size_t)index;

    if (lk__gltf_member(object, "sparse")) {
        if (!reader->sparse_allowed)
            return lk__gltf_fail(reader, LK_ERR_UNSUPPORTED, where, "sparse",
                                 "sparse accessors are not supported here (lodkit reads them in morph targets, skins "
                                 "and animations)");
        out->sparse = lk__gltf_member(object, "sparse");
    }
    uint64_t component_type, count, byte_offset, view_index;
    const cJSON *type;
    bool normalized;
    if ((status = lk__gltf_get_uint(reader, object, where, "componentType", true, 0, &component_type)) != LK_OK)
        return status;
    if ((status = lk__gltf_get_uint(reader, object, where, "count", true, 0, &count)) != LK_OK) return status;
    if ((status = lk__gltf_get_uint(reader, object, where, "byteOffset", false, 0, &byte_offset)) != LK_OK)
        return status;
    if ((status = get_bool(reader, object, where, "normalized", &normalized)) != LK_OK) return status;
    if ((status = lk__gltf_get_string(reader, object, where, "type", &type)) != LK_OK) return status;
    if (!type) return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "missing required \"type\"");

    size_t size = component_size((unsigned)component_type);
    if (size == 0 || component_type > 0xFFFF)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "componentType",
                             "%llu is not a glTF component type (5120, 5121, 5122, 5123, 5125 or 5126)",
                             (unsigned long long)component_type);
    unsigned components = type_component_count(type->valuestring);
    if (components == 0)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "type", "\"%.40s\" is not a glTF accessor type",
                             type->valuestring);
    if (components == 116 && (type_mask & TYPE_MAT4))
        components = 16; /* float matrices have no column padding */
    else if (components > 4 || !(type_mask & (1u << components)))
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "type", "%s, but %s%s%s needs %s", type->valuestring,
                             referrer, key[0] == '[' ? "" : ".", key, expected);
    if (is_index) {
        if (component_type != COMPONENT_UNSIGNED_BYTE && component_type != COMPONENT_UNSIGNED_SHORT &&
            component_type != COMPONENT_UNSIGNED_INT)
            return lk__gltf_fail(reader, LK_ERR_PARSE, where, "componentType",
                                 "%llu is not valid for indices (expected 5121, 5123 or 5125)",
                                 (unsigned long long)component_type);
        if (normalized) return lk__gltf_fail(reader, LK_ERR_PARSE, where, "normalized", "indices cannot be normalized");
    } else if (normalized && (component_type == COMPONENT_FLOAT || component_type == COMPONENT_UNSIGNED_INT)) {
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, "normalized",
                             "only integer types of 8 or 16 bits can be normalized");
    }
    if (count == 0) return lk__gltf_fail(reader, LK_ERR_PARSE, where, "count", "must be at least 1");
    if (count > LK_MAX_ELEMENTS)
        return lk__gltf_fail(reader, LK_ERR_LIMIT, where, "count", "%llu is more than lodkit supports (%zu)",
                             (unsigned long long)count, (size_t)LK_MAX_ELEMENTS);
    out->component_type = (unsigned)component_type;
    out->component_count = components;
    out->normalized = normalized;
    out->count = (size_t)count;
    size_t element_size = size * components;
    out->stride = element_size;

    const cJSON *view_item = lk__gltf_member(object, "bufferView");
    if (!view_item) {
        /* The specification says such an accessor holds zeros. */
        if (byte_offset != 0)
            return lk__gltf_fail(reader, LK_ERR_PARSE, where, "byteOffset", "must be 0 without a bufferView");
        return LK_OK;
    }
    if ((status = lk__gltf_check_uint(reader, view_item, where, "bufferView")) != LK_OK) return status;
    view_index = (uint64_t)view_item->valuedouble;
    const unsigned char *view_data;
    uint64_t view_length, byte_stride;
    status = lk__gltf_view_bytes(reader, view_index, where, "bufferView", &view_data, &view_length, &byte_stride);
    if (status != LK_OK) return status;
    char view_where[48];
    snprintf(view_where, sizeof view_where, "bufferViews[%llu]", (unsigned long long)view_index);
    if (byte_stride) {
        if (byte_stride < element_size)
            return lk__gltf_fail(reader, LK_ERR_RANGE, view_where, "byteStride",
                                 "%llu is smaller than the %zu-byte elements of %s", (unsigned long long)byte_stride,
                                 element_size, where);
        out->stride = (size_t)byte_stride;
    }
    uint64_t needed = byte_offset + (uint64_t)out->stride * (count - 1) + element_size;
    if (needed > view_length)
        return lk__gltf_fail(reader, LK_ERR_RANGE, where, NULL,
                             "count %llu exceeds bufferView %llu (%llu bytes): byteOffset %llu + %llu x stride %zu + "
                             "element %zu = %llu bytes",
                             (unsigned long long)count, (unsigned long long)view_index, (unsigned long long)view_length,
                             (unsigned long long)byte_offset, (unsigned long long)(count - 1), out->stride,
                             element_size, (unsigned long long)needed);
    out->data = view_data + byte_offset;
    return LK_OK;
}

lk_status lk__gltf_apply_sparse(gltf_reader *reader, const gltf_accessor *accessor, float *values)
{
    const cJSON *sparse = accessor->sparse, *indices, *substitutes;
    if (!sparse) return LK_OK;
    char where[64], indices_where[80], values_where[80];
    snprintf(where, sizeof where, "accessors[%zu].sparse", accessor->index);
    snprintf(indices_where, sizeof indices_where, "%s.indices", where);
    snprintf(values_where, sizeof values_where, "%s.values", where);
    uint64_t count, index_type, index_view, index_offset, value_view, value_offset;
    lk_status status = lk__gltf_get_uint(reader, sparse, where, "count", true, 0, &count);
    if (status == LK_OK) status = lk__gltf_get_object(reader, sparse, where, "indices", &indices);
    if (status == LK_OK) status = lk__gltf_get_object(reader, sparse, where, "values", &substitutes);
    if (status != LK_OK) return status;
    if (!indices || !substitutes)
        return lk__gltf_fail(reader, LK_ERR_PARSE, where, NULL, "needs \"indices\" and \"values\"");
    if ((status = lk__gltf_get_uint(reader, indices, indices_where, "bufferView", true, 0, &index_view)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, indices, indices_where, "byteOffset", false, 0, &index_offset)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, indices, indices_where, "componentType", true, 0, &index_type)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, substitutes, values_where, "bufferView", true, 0, &value_view)) != LK_OK ||
        (status = lk__gltf_get_uint(reader, substitutes, values_where, "byteOffset", false, 0, &value_offset)) != LK_OK)
        return status;
    if (count == 0 || count > accessor->count)
        return lk__gltf_fail(reader, LK_ERR_RANGE, where, "count", "%llu is not in 1..%zu (the accessor's count)",
                             (unsigned long long)count, accessor->count);
    if (index_type != COMPONENT_UNSIGNED_BYTE && index_type != COMPONENT_UNSIGNED_SHORT &&
        index_type != COMPONENT_UNSIGNED_INT)
        return lk__gltf_fail(reader, LK_ERR_PARSE, indices_where, "componentType",
                             "%llu is not valid for sparse indices (expected 5121, 5123 or 5125)",
                             (unsigned long long)index_type);
    const unsigned char *index_data, *value_data;
    uint64_t index_length, value_length, stride;
    if ((status = lk__gltf_view_bytes(reader, index_view, indices_where, "bufferView", &index_data, &index_length,
                                      &stride)) != LK_OK ||
        (status = lk__gltf_view_bytes(reader, value_view, values_where, "bufferView", &value_data, &value_length,
                                      &stride)) != LK_OK)
        return status;
    size_t index_size = component_size((unsigned)index_type);
    size_t value_size = component_size(accessor->component_type) * accessor->component_count;
    if (index_offset + count * index_size > index_length)
        return lk__gltf_fail(reader, LK_ERR_RANGE, indices_where, NULL,
                             "%llu indices from byteOffset %llu exceed bufferView %llu (%llu bytes)",
                             (unsigned long long)count, (unsigned long long)index_offset,
                             (unsigned long long)index_view, (unsigned long long)index_length);
    if (value_offset + count * value_size > value_length)
        return lk__gltf_fail(reader, LK_ERR_RANGE, values_where, NULL,
                             "%llu values from byteOffset %llu exceed bufferView %llu (%llu bytes)",
                             (unsigned long long)count, (unsigned long long)value_offset,
                             (unsigned long long)value_view, (unsigned long long)value_length);
    gltf_accessor index_reader = {
        accessor->index, index_data + index_offset, (size_t)count, index_size, (unsigned)index_type, 1, false, NULL};
    gltf_accessor value_reader = *accessor;
    value_reader.data = value_data + value_offset;
    value_reader.count = (size_t)count;
    value_reader.stride = value_size; /* tightly packed */
    value_reader.sparse = NULL;
    uint32_t previous = 0;
    for (size_t i = 0; i < (size_t)count; i++) {
        uint32_t element = lk__gltf_accessor_index(&index_reader, i);
        if (element >= accessor->count || (i > 0 && element <= previous))
            return lk__gltf_fail(reader, LK_ERR_RANGE, indices_where, NULL,
                                 "index %zu (%u) must be below %zu and above the one before it", i, element,
                                 accessor->count);
        previous = element;
        lk__gltf_accessor_floats(&value_reader, i, values + (size_t)element * accessor->component_count);
    }
    return LK_OK;
}

/* Element `element` as floats (normalized integers mapped to [0,1] or [-1,1]). */
void lk__gltf_accessor_floats(const gltf_accessor *accessor, size_t element, float *values)
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
        case COMPONENT_UNSIGNED_INT: value = lk__load_u32le(p + 4 * c); break;
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

uint32_t lk__gltf_accessor_index(const gltf_accessor *accessor, size_t element)
{
    if (!accessor->data) return 0;
    const unsigned char *p = accessor->data + element * accessor->stride;
    switch (accessor->component_type) {
    case COMPONENT_UNSIGNED_BYTE: return p[0];
    case COMPONENT_UNSIGNED_SHORT: return lk__load_u16le(p);
    default: return lk__load_u32le(p);
    }
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
static lk_status json_prescan(gltf_reader *reader, const char *text, size_t length, size_t file_offset, json_cost *cost)
{
    size_t depth = 0;
    uint64_t values = 1, strings = 0;
    bool in_string = false;
    for (size_t i = 0; i < length; i++) {
        char c = text[i];
        if (in_string) {
            if (c == '\\')
                i++;
            else if (c == '"')
                in_string = false;
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

lk_status lk__gltf_parse_json(gltf_reader *reader, const char *text, size_t length, size_t file_offset, cJSON **root)
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
        return lk__gltf_nomem(reader);
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
static lk_status
fail_at(const gltf_reader *reader, lk_status status, size_t offset, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_byte_v(reader->error, status, reader->ctx->name, offset, format, args);
    va_end(args);
    return status;
}

/* Splits a .glb file into its JSON text and optional BIN chunk. */
lk_status lk__gltf_parse_glb(gltf_reader *reader, const unsigned char *data, size_t size, const char **json,
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
            return fail_at(reader, LK_ERR_PARSE, offset,
                           "chunk %zu claims %u bytes but only %zu follow (truncated file)", chunk_number, chunk_length,
                           available);
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
