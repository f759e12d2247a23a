/* SPDX-License-Identifier: MIT */
/* glTF 2.0 into an lk_scene (lk_scene_read): the default scene's node tree,
 * every mesh with its primitives (each read in its mesh's coordinates by
 * the mesh reader, io_gltf.c), materials, textures, samplers, images and
 * cameras. Materials, textures, samplers and cameras are kept as their
 * JSON objects so that what lodkit does not interpret passes through
 * untouched; extensions lodkit does not know are removed from them and
 * named in scene->notes, as is everything else left out (attributes the
 * scene cannot hold). Line primitives are kept as segments. Skins (with JOINTS_0 / WEIGHTS_0), morph
 * targets (POSITION, NORMAL and TANGENT deltas, default and node weights,
 * extras.targetNames) and animations of nodes and of morph weights are
 * kept as the file has them, decoded to floats. */
#include "io_gltf.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

typedef struct scene_reader {
    gltf_reader gltf;
    json_table materials, textures, images, samplers, cameras, skins, animations;
    lk_scene *scene;
    lk__buffer notes; /* text, one line per note, no terminating zero yet */
} scene_reader;

static void note(scene_reader *reader, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void note(scene_reader *reader, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    lk__notes_vadd(&reader->notes, format, args);
    va_end(args);
}

static char *copy_string(const char *text)
{
    if (!text) return NULL;
    size_t length = strlen(text);
    char *copy = malloc(length + 1);
    if (copy) memcpy(copy, text, length + 1);
    return copy;
}

static lk_status nomem(scene_reader *reader) { return lk__gltf_nomem(&reader->gltf); }

/* Extensions whose objects pass through untouched (materials, textures). */
static bool extension_is_kept(const char *name)
{
    if (strcmp(name, "KHR_materials_variants") == 0) return false; /* names primitives we rewrite */
    static const char *const prefixes[] = {"KHR_materials_", "KHR_texture_", "EXT_texture_"};
    for (size_t i = 0; i < sizeof prefixes / sizeof prefixes[0]; i++)
        if (strncmp(name, prefixes[i], strlen(prefixes[i])) == 0) return true;
    return false;
}

/* Removes, everywhere inside `item` (a copy), extensions lodkit does not
 * pass through, noting each; an "extensions" object left empty goes too. */
static void strip_extensions(scene_reader *reader, cJSON *item, const char *where)
{
    cJSON *child = item ? item->child : NULL;
    while (child) {
        cJSON *next = child->next;
        if (child->string && strcmp(child->string, "extensions") == 0 && cJSON_IsObject(child)) {
            cJSON *extension = child->child;
            while (extension) {
                cJSON *following = extension->next;
                if (!extension_is_kept(extension->string)) {
                    note(reader, "%s: extension %s dropped (not supported)", where, extension->string);
                    cJSON_Delete(cJSON_DetachItemViaPointer(child, extension));
                } else {
                    strip_extensions(reader, extension, where);
                }
                extension = following;
            }
            if (!child->child) cJSON_Delete(cJSON_DetachItemViaPointer(item, child));
        } else if ((cJSON_IsObject(child) || cJSON_IsArray(child)) &&
                   !(child->string && strcmp(child->string, "extras") == 0)) {
            strip_extensions(reader, child, where);
        }
        child = next;
    }
}

/* The top-level properties glTF 2.0 defines for the kept objects; others
 * (glTF 1.0 leftovers such as a material's "technique" and "values") would
 * make the written file invalid and are dropped with a note. */
static const char *const material_properties[] = {
    "name",          "extensions",       "extras",          "pbrMetallicRoughness",
    "normalTexture", "occlusionTexture", "emissiveTexture", "emissiveFactor",
    "alphaMode",     "alphaCutoff",      "doubleSided",     NULL};
static const char *const texture_properties[] = {"name", "extensions", "extras", "sampler", "source", NULL};
static const char *const sampler_properties[] = {"name",      "extensions", "extras", "magFilter",
                                                 "minFilter", "wrapS",      "wrapT",  NULL};
static const char *const camera_properties[] = {"name",         "extensions",  "extras", "type",
                                                "orthographic", "perspective", NULL};

static void strip_properties(scene_reader *reader, cJSON *object, const char *const *allowed, const char *where)
{
    cJSON *child = object->child;
    while (child) {
        cJSON *next = child->next;
        bool known = false;
        for (size_t i = 0; allowed[i] && !known; i++) known = strcmp(child->string, allowed[i]) == 0;
        if (!known) {
            note(reader, "%s.%s dropped (not a glTF 2.0 property)", where, child->string);
            cJSON_Delete(cJSON_DetachItemViaPointer(object, child));
        }
        child = next;
    }
}

/* A copy of `object` with only glTF 2.0's properties (`allowed`) and
 * without unknown extensions, printed compactly. */
static lk_status keep_json(scene_reader *reader, const cJSON *object, const char *const *allowed, const char *where,
                           char **out)
{
    cJSON *copy = cJSON_Duplicate(object, true);
    if (!copy) return nomem(reader);
    strip_properties(reader, copy, allowed, where);
    strip_extensions(reader, copy, where);
    *out = cJSON_PrintUnformatted(copy);
    cJSON_Delete(copy);
    return *out ? LK_OK : nomem(reader);
}

/* An optional index member that must be < count; -1 when absent. */
static lk_status get_index(scene_reader *reader, const cJSON *object, const char *where, const char *key, size_t count,
                           const char *table, int32_t *out)
{
    uint64_t value;
    lk_status status = lk__gltf_get_uint(&reader->gltf, object, where, key, false, UINT64_MAX, &value);
    if (status != LK_OK) return status;
    *out = -1;
    if (value == UINT64_MAX) return LK_OK;
    if (value >= count)
        return lk__gltf_fail(&reader->gltf, LK_ERR_RANGE, where, key, "%s %llu out of range (%zu %s)", table,
                             (unsigned long long)value, count, table);
    *out = (int32_t)value;
    return LK_OK;
}

/* Every texture reference inside a material (members named "...Texture"
 * holding an "index", in the core and in extensions) must name a texture. */
static lk_status check_texture_references(scene_reader *reader, const cJSON *item, const char *where)
{
    const cJSON *child;
    cJSON_ArrayForEach(child, item)
    {
        if (!cJSON_IsObject(child) && !cJSON_IsArray(child)) continue;
        if (child->string && strcmp(child->string, "extras") == 0) continue;
        size_t length = child->string ? strlen(child->string) : 0;
        if (cJSON_IsObject(child) && length >= 7 && strcmp(child->string + length - 7, "Texture") == 0) {
            char texture_where[160];
            snprintf(texture_where, sizeof texture_where, "%s.%s", where, child->string);
            int32_t texture;
            lk_status status =
                get_index(reader, child, texture_where, "index", reader->textures.count, "textures", &texture);
            if (status != LK_OK) return status;
        }
        lk_status status = check_texture_references(reader, child, where);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

static lk_status read_materials(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    if (reader->materials.count == 0) return LK_OK;
    scene->materials = lk__calloc_array(reader->materials.count, sizeof *scene->materials);
    if (!scene->materials) return nomem(reader);
    for (size_t i = 0; i < reader->materials.count; i++) {
        const cJSON *object = reader->materials.items[i];
        lk_scene_material *material = &scene->materials[scene->material_count++];
        char where[48];
        snprintf(where, sizeof where, "materials[%zu]", i);
        material->base_color_texture = -1;
        for (int c = 0; c < 4; c++) material->base_color[c] = 1.0f;
        lk_status status = check_texture_references(reader, object, where);
        if (status != LK_OK) return status;
        const cJSON *name = lk__gltf_member(object, "name");
        if (cJSON_IsString(name) && !(material->name = copy_string(name->valuestring))) return nomem(reader);
        const cJSON *pbr = lk__gltf_member(object, "pbrMetallicRoughness");
        if (cJSON_IsObject(pbr)) {
            double factor[4];
            bool present = false;
            /* Types were checked with the document. */
            status = lk__gltf_get_number_array(&reader->gltf, pbr, where, "baseColorFactor", 4, factor, &present);
            if (status != LK_OK) return status;
            for (int c = 0; present && c < 4; c++) material->base_color[c] = (float)factor[c];
            const cJSON *texture = lk__gltf_member(pbr, "baseColorTexture");
            const cJSON *index = texture ? lk__gltf_member(texture, "index") : NULL;
            if (cJSON_IsNumber(index)) material->base_color_texture = (int32_t)index->valuedouble;
        }
        if ((status = keep_json(reader, object, material_properties, where, &material->json)) != LK_OK) return status;
    }
    return LK_OK;
}

static lk_status read_textures(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    if (reader->textures.count == 0) return LK_OK;
    scene->textures = lk__calloc_array(reader->textures.count, sizeof *scene->textures);
    if (!scene->textures) return nomem(reader);
    for (size_t i = 0; i < reader->textures.count; i++) {
        const cJSON *object = reader->textures.items[i];
        lk_scene_texture *texture = &scene->textures[scene->texture_count++];
        char where[48];
        snprintf(where, sizeof where, "textures[%zu]", i);
        lk_status status = get_index(reader, object, where, "source", reader->images.count, "images", &texture->image);
        if (status == LK_OK)
            status = get_index(reader, object, where, "sampler", reader->samplers.count, "samplers", &texture->sampler);
        /* KHR_texture_basisu, EXT_texture_webp, ...: their own "source". */
        const cJSON *extensions = lk__gltf_member(object, "extensions"), *extension;
        cJSON_ArrayForEach(extension, extensions)
        {
            if (status != LK_OK) break;
            char extension_where[128];
            snprintf(extension_where, sizeof extension_where, "%s.extensions.%s", where, extension->string);
            int32_t source;
            status = get_index(reader, extension, extension_where, "source", reader->images.count, "images", &source);
            if (status == LK_OK && texture->image < 0) texture->image = source;
        }
        if (status == LK_OK) status = keep_json(reader, object, texture_properties, where, &texture->json);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

/* The media type of an image from its first bytes, or NULL. */
static const char *sniff_image_type(const unsigned char *data, size_t size)
{
    if (size >= 8 && memcmp(data, "\x89PNG\r\n\x1a\n", 8) == 0) return "image/png";
    if (size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF) return "image/jpeg";
    if (size >= 12 && memcmp(data, "RIFF", 4) == 0 && memcmp(data + 8, "WEBP", 4) == 0) return "image/webp";
    if (size >= 12 && memcmp(data, "\xABKTX 20\xBB\r\n\x1a\n", 12) == 0) return "image/ktx2";
    return NULL;
}

static lk_status read_images(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    gltf_reader *gltf = &reader->gltf;
    if (reader->images.count == 0) return LK_OK;
    scene->images = lk__calloc_array(reader->images.count, sizeof *scene->images);
    if (!scene->images) return nomem(reader);
    for (size_t i = 0; i < reader->images.count; i++) {
        const cJSON *object = reader->images.items[i], *uri, *mime, *name;
        lk_scene_image *image = &scene->images[scene->image_count++];
        char where[48];
        snprintf(where, sizeof where, "images[%zu]", i);
        lk_status status = lk__gltf_get_string(gltf, object, where, "uri", &uri);
        if (status == LK_OK) status = lk__gltf_get_string(gltf, object, where, "mimeType", &mime);
        if (status == LK_OK) status = lk__gltf_get_string(gltf, object, where, "name", &name);
        if (status != LK_OK) return status;
        const cJSON *view = lk__gltf_member(object, "bufferView");
        if (uri && view) return lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL, "has both \"uri\" and \"bufferView\"");
        if (view) {
            if ((status = lk__gltf_check_uint(gltf, view, where, "bufferView")) != LK_OK) return status;
            if (!mime)
                return lk__gltf_fail(gltf, LK_ERR_PARSE, where, "mimeType", "missing (required with a bufferView)");
            const unsigned char *bytes;
            uint64_t length, stride;
            status =
                lk__gltf_view_bytes(gltf, (uint64_t)view->valuedouble, where, "bufferView", &bytes, &length, &stride);
            if (status != LK_OK) return status;
            if (!lk__budget_charge(gltf->ctx->budget, (size_t)length, 1)) return lk__gltf_over_budget(gltf);
            image->data = lk__malloc_array((size_t)length, 1);
            if (!image->data) return nomem(reader);
            memcpy(image->data, bytes, (size_t)length);
            image->size = (size_t)length;
        } else if (uri) {
            status = lk__gltf_uri_bytes(gltf, uri->valuestring, where, &image->data, &image->size);
            if (status != LK_OK) return status;
        } else {
            return lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL, "has neither \"uri\" nor \"bufferView\"");
        }
        const char *type = mime ? mime->valuestring : sniff_image_type(image->data, image->size);
        if (!type && uri && strncmp(uri->valuestring, "data:", 5) == 0) {
            /* data:image/png;base64,... */
            const char *start = uri->valuestring + 5, *end = strchr(start, ';');
            if (end && end > start && (size_t)(end - start) < 64) {
                char media[64];
                memcpy(media, start, (size_t)(end - start));
                media[end - start] = '\0';
                if (!(image->mime_type = copy_string(media))) return nomem(reader);
            }
        }
        if (!image->mime_type) {
            if (!type)
                return lk__gltf_fail(gltf, LK_ERR_UNSUPPORTED, where, NULL,
                                     "not a PNG, JPEG, WebP or KTX2 image and no mimeType says what it is");
            if (!(image->mime_type = copy_string(type))) return nomem(reader);
        }
        if (name && !(image->name = copy_string(name->valuestring))) return nomem(reader);
    }
    return LK_OK;
}

static lk_status read_json_array(scene_reader *reader, const json_table *table, const char *what,
                                 const char *const *allowed, char ***out, size_t *count)
{
    if (table->count == 0) return LK_OK;
    *out = lk__calloc_array(table->count, sizeof **out);
    if (!*out) return nomem(reader);
    for (size_t i = 0; i < table->count; i++) {
        char where[48];
        snprintf(where, sizeof where, "%s[%zu]", what, i);
        lk_status status = keep_json(reader, table->items[i], allowed, where, &(*out)[i]);
        if (status != LK_OK) return status;
        (*count)++;
    }
    return LK_OK;
}

/* The attributes lk_mesh holds; others are named in the notes. */
static void note_dropped_attributes(scene_reader *reader, const cJSON *primitive, const char *where)
{
    const cJSON *attributes = lk__gltf_member(primitive, "attributes"), *attribute;
    cJSON_ArrayForEach(attribute, attributes)
    {
        const char *name = attribute->string;
        if (strcmp(name, "POSITION") == 0 || strcmp(name, "NORMAL") == 0 || strcmp(name, "TEXCOORD_0") == 0 ||
            strcmp(name, "COLOR_0") == 0 || strcmp(name, "TANGENT") == 0 || strcmp(name, "TEXCOORD_1") == 0 ||
            strcmp(name, "JOINTS_0") == 0 || strcmp(name, "WEIGHTS_0") == 0)
            continue;
        note(reader,
             "%s: attribute %s dropped (lodkit keeps POSITION, NORMAL, TANGENT, TEXCOORD_0/1, COLOR_0, JOINTS_0 and "
             "WEIGHTS_0)",
             where, name);
    }
}

/* TANGENT (VEC4: unit xyz, w = +-1) or TEXCOORD_1 (VEC2, v flipped up like
 * TEXCOORD_0) of a primitive of `vertex_count` vertices, or NULL. */
static lk_status read_extra_attribute(scene_reader *reader, const cJSON *primitive, const char *where, const char *name,
                                      size_t vertex_count, float **out)
{
    gltf_reader *gltf = &reader->gltf;
    *out = NULL;
    const cJSON *attributes = lk__gltf_member(primitive, "attributes");
    char attributes_where[128];
    snprintf(attributes_where, sizeof attributes_where, "%s.attributes", where);
    uint64_t index;
    lk_status status = lk__gltf_get_uint(gltf, attributes, attributes_where, name, false, UINT64_MAX, &index);
    if (status != LK_OK || index == UINT64_MAX) return status;
    bool tangent = strcmp(name, "TANGENT") == 0;
    gltf_accessor accessor;
    status = lk__gltf_open_accessor(gltf, index, attributes_where, name, tangent ? TYPE_VEC4 : TYPE_VEC2, false,
                                    tangent ? "a VEC4" : "a VEC2", &accessor);
    if (status != LK_OK) return status;
    if (accessor.count != vertex_count)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, attributes_where, name, "%zu elements but POSITION has %zu",
                             accessor.count, vertex_count);
    size_t components = tangent ? 4 : 2;
    if (!lk__budget_charge(gltf->ctx->budget, vertex_count, components * sizeof(float)))
        return lk__gltf_over_budget(gltf);
    *out = lk__malloc_array(vertex_count, components * sizeof(float));
    if (!*out) return nomem(reader);
    for (size_t v = 0; v < vertex_count; v++) {
        float values[4] = {0, 0, 0, 1};
        lk__gltf_accessor_floats(&accessor, v, values);
        for (size_t c = 0; c < components; c++)
            if (!isfinite(values[c]))
                return lk__gltf_fail(gltf, LK_ERR_PARSE, attributes_where, name,
                                     "element %zu of accessors[%zu] is not finite", v, accessor.index);
        if (!tangent) values[1] = 1.0f - values[1];
        memcpy(*out + components * v, values, components * sizeof(float));
    }
    return LK_OK;
}

/* JOINTS_0 (unsigned bytes or shorts) and WEIGHTS_0 (floats or normalised
 * unsigned bytes or shorts) of a primitive of `vertex_count` vertices, both
 * or neither. A joint whose weight is 0 is stored as 0: it does not count,
 * and the skin may have fewer joints than its number. */
static lk_status read_skin_attributes(scene_reader *reader, const cJSON *primitive, const char *where,
                                      size_t vertex_count, lk_scene_primitive *out)
{
    gltf_reader *gltf = &reader->gltf;
    const cJSON *attributes = lk__gltf_member(primitive, "attributes");
    char attributes_where[128];
    snprintf(attributes_where, sizeof attributes_where, "%s.attributes", where);
    uint64_t joints_index, weights_index;
    lk_status status =
        lk__gltf_get_uint(gltf, attributes, attributes_where, "JOINTS_0", false, UINT64_MAX, &joints_index);
    if (status == LK_OK)
        status = lk__gltf_get_uint(gltf, attributes, attributes_where, "WEIGHTS_0", false, UINT64_MAX, &weights_index);
    if (status != LK_OK || (joints_index == UINT64_MAX && weights_index == UINT64_MAX)) return status;
    if (joints_index == UINT64_MAX || weights_index == UINT64_MAX) {
        note(reader, "%s: %s without %s dropped", where, joints_index == UINT64_MAX ? "WEIGHTS_0" : "JOINTS_0",
             joints_index == UINT64_MAX ? "JOINTS_0" : "WEIGHTS_0");
        return LK_OK;
    }
    gltf_accessor joints, weights;
    if ((status = lk__gltf_open_accessor(gltf, joints_index, attributes_where, "JOINTS_0", TYPE_VEC4, false, "a VEC4",
                                         &joints)) != LK_OK)
        return status;
    if (joints.component_type != COMPONENT_UNSIGNED_BYTE && joints.component_type != COMPONENT_UNSIGNED_SHORT)
        return lk__gltf_fail(gltf, LK_ERR_PARSE, attributes_where, "JOINTS_0",
                             "joints must be unsigned bytes or shorts (componentType 5121 or 5123)");
    if (joints.count != vertex_count)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, attributes_where, "JOINTS_0", "%zu elements but POSITION has %zu",
                             joints.count, vertex_count);
    if ((status = lk__gltf_read_accessor_floats(gltf, weights_index, attributes_where, "WEIGHTS_0", TYPE_VEC4, "a VEC4",
                                                &weights, &out->weights)) != LK_OK)
        return status;
    if (weights.component_type != COMPONENT_FLOAT &&
        !(weights.normalized &&
          (weights.component_type == COMPONENT_UNSIGNED_BYTE || weights.component_type == COMPONENT_UNSIGNED_SHORT)))
        return lk__gltf_fail(gltf, LK_ERR_PARSE, attributes_where, "WEIGHTS_0",
                             "weights must be floats or normalised unsigned bytes or shorts");
    if (weights.count != vertex_count)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, attributes_where, "WEIGHTS_0", "%zu elements but POSITION has %zu",
                             weights.count, vertex_count);
    if (!lk__budget_charge(gltf->ctx->budget, vertex_count, 4 * sizeof(uint16_t))) return lk__gltf_over_budget(gltf);
    out->joints = lk__malloc_array(vertex_count ? vertex_count : 1, 4 * sizeof(uint16_t));
    if (!out->joints) return nomem(reader);
    for (size_t v = 0; v < vertex_count; v++) {
        float joint[4];
        lk__gltf_accessor_floats(&joints, v, joint);
        for (size_t k = 0; k < 4; k++) {
            float weight = out->weights[4 * v + k];
            if (weight < 0)
                return lk__gltf_fail(gltf, LK_ERR_RANGE, attributes_where, "WEIGHTS_0",
                                     "vertex %zu has a negative weight (%g)", v, (double)weight);
            out->joints[4 * v + k] = weight > 0 ? (uint16_t)joint[k] : 0;
        }
    }
    return LK_OK;
}

/* One morph-target attribute (VEC3 deltas, sparse or not) of target k into
 * `*array` (allocated zeroed for every target on first use). */
static lk_status read_target_attribute(scene_reader *reader, const cJSON *target, const char *where, const char *name,
                                       size_t target_count, size_t k, size_t vertex_count, float **array)
{
    gltf_reader *gltf = &reader->gltf;
    uint64_t index;
    lk_status status = lk__gltf_get_uint(gltf, target, where, name, false, UINT64_MAX, &index);
    if (status != LK_OK || index == UINT64_MAX) return status;
    gltf_accessor accessor;
    float *values;
    if ((status = lk__gltf_read_accessor_floats(gltf, index, where, name, TYPE_VEC3, "a VEC3", &accessor, &values)) !=
        LK_OK)
        return status;
    if (accessor.count != vertex_count) {
        free(values);
        return lk__gltf_fail(gltf, LK_ERR_RANGE, where, name, "%zu deltas but POSITION has %zu vertices",
                             accessor.count, vertex_count);
    }
    if (!*array) {
        if (!lk__budget_charge(gltf->ctx->budget, target_count * vertex_count, 3 * sizeof(float))) {
            free(values);
            return lk__gltf_over_budget(gltf);
        }
        size_t deltas = target_count * vertex_count;
        *array = lk__calloc_array(deltas > 0 ? deltas : 1, 3 * sizeof(float));
        if (!*array) {
            free(values);
            return nomem(reader);
        }
    }
    memcpy(*array + 3 * k * vertex_count, values, 3 * vertex_count * sizeof(float));
    free(values);
    return LK_OK;
}

/* The primitive's morph targets (POSITION, NORMAL and TANGENT deltas; other
 * attributes of a target are noted and dropped). Every primitive of a mesh
 * has the mesh's number of targets, as glTF requires. */
static lk_status read_morph_targets(scene_reader *reader, const cJSON *primitive, const char *where,
                                    lk_scene_mesh *mesh, bool first, lk_scene_primitive *out)
{
    gltf_reader *gltf = &reader->gltf;
    const cJSON *targets, *target;
    lk_status status = lk__gltf_get_array(gltf, primitive, where, "targets", &targets);
    if (status != LK_OK) return status;
    size_t count = targets ? (size_t)cJSON_GetArraySize(targets) : 0;
    if (first) mesh->target_count = count;
    if (count != mesh->target_count)
        return lk__gltf_fail(gltf, LK_ERR_PARSE, where, "targets",
                             "%zu morph targets, but the mesh's first primitive has %zu (glTF wants the same number)",
                             count, mesh->target_count);
    size_t k = 0, vertex_count = out->mesh.vertex_count;
    cJSON_ArrayForEach(target, targets)
    {
        char target_where[128];
        snprintf(target_where, sizeof target_where, "%s.targets[%zu]", where, k);
        if (!cJSON_IsObject(target)) return lk__gltf_fail(gltf, LK_ERR_PARSE, target_where, NULL, "expected an object");
        const cJSON *attribute;
        cJSON_ArrayForEach(attribute, target)
        {
            const char *name = attribute->string;
            if (strcmp(name, "POSITION") != 0 && strcmp(name, "NORMAL") != 0 && strcmp(name, "TANGENT") != 0)
                note(reader, "%s: attribute %s dropped (lodkit keeps POSITION, NORMAL and TANGENT deltas)",
                     target_where, name);
        }
        if ((status = read_target_attribute(reader, target, target_where, "POSITION", count, k, vertex_count,
                                            &out->target_positions)) != LK_OK ||
            (status = read_target_attribute(reader, target, target_where, "NORMAL", count, k, vertex_count,
                                            &out->target_normals)) != LK_OK ||
            (status = read_target_attribute(reader, target, target_where, "TANGENT", count, k, vertex_count,
                                            &out->target_tangents)) != LK_OK)
            return status;
        k++;
    }
    return LK_OK;
}

/* The "weights" member of a mesh or node, `count` numbers, as floats. */
static lk_status read_weights(scene_reader *reader, const cJSON *object, const char *where, size_t count, float **out)
{
    double *values = lk__malloc_array(count, sizeof *values);
    *out = lk__malloc_array(count, sizeof **out);
    if (!values || !*out) {
        free(values);
        return nomem(reader);
    }
    lk_status status = lk__gltf_get_number_array(&reader->gltf, object, where, "weights", count, values, NULL);
    for (size_t k = 0; status == LK_OK && k < count; k++) (*out)[k] = (float)values[k];
    free(values);
    return status;
}

/* A mesh's default morph weights and extras.targetNames. */
static lk_status read_mesh_weights(scene_reader *reader, const cJSON *object, const char *where, lk_scene_mesh *mesh)
{
    gltf_reader *gltf = &reader->gltf;
    const cJSON *weights, *extras = lk__gltf_member(object, "extras");
    lk_status status = lk__gltf_get_array(gltf, object, where, "weights", &weights);
    if (status != LK_OK) return status;
    size_t count = mesh->target_count;
    if (weights && (size_t)cJSON_GetArraySize(weights) != count)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, where, "weights", "%d weights for %zu morph targets",
                             cJSON_GetArraySize(weights), count);
    if (count == 0) return LK_OK;
    if (weights && (status = read_weights(reader, object, where, count, &mesh->weights)) != LK_OK) return status;
    const cJSON *names = cJSON_IsObject(extras) ? lk__gltf_member(extras, "targetNames") : NULL, *name;
    if (!cJSON_IsArray(names) || (size_t)cJSON_GetArraySize(names) != count) {
        if (names) note(reader, "%s.extras.targetNames dropped (not %zu strings)", where, count);
        return LK_OK;
    }
    if (!(mesh->target_names = lk__calloc_array(count, sizeof *mesh->target_names))) return nomem(reader);
    size_t k = 0;
    cJSON_ArrayForEach(name, names)
    {
        if (cJSON_IsString(name) && !(mesh->target_names[k] = copy_string(name->valuestring))) return nomem(reader);
        k++;
    }
    return LK_OK;
}

static lk_status read_meshes(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    gltf_reader *gltf = &reader->gltf;
    const json_table *meshes = &gltf->meshes;
    if (meshes->count == 0) return LK_OK;
    scene->meshes = lk__calloc_array(meshes->count, sizeof *scene->meshes);
    if (!scene->meshes) return nomem(reader);
    for (size_t m = 0; m < meshes->count; m++) {
        const cJSON *object = meshes->items[m], *primitives, *name;
        lk_scene_mesh *mesh = &scene->meshes[scene->mesh_count++];
        char where[48];
        snprintf(where, sizeof where, "meshes[%zu]", m);
        lk_status status = lk__gltf_get_array(gltf, object, where, "primitives", &primitives);
        if (status == LK_OK) status = lk__gltf_get_string(gltf, object, where, "name", &name);
        if (status != LK_OK) return status;
        if (!primitives) return lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL, "missing required \"primitives\"");
        if (name && !(mesh->name = copy_string(name->valuestring))) return nomem(reader);
        size_t count = (size_t)cJSON_GetArraySize(primitives);
        mesh->primitives = lk__calloc_array(count ? count : 1, sizeof *mesh->primitives);
        if (!mesh->primitives) return nomem(reader);
        size_t index = 0;
        const cJSON *primitive;
        cJSON_ArrayForEach(primitive, primitives)
        {
            char primitive_where[96];
            snprintf(primitive_where, sizeof primitive_where, "%s.primitives[%zu]", where, index++);
            status = lk__gltf_read_local_primitive(gltf, primitive, primitive_where);
            if (status != LK_OK) return status;
            note_dropped_attributes(reader, primitive, primitive_where);
            lk_scene_primitive *out = &mesh->primitives[mesh->primitive_count];
            if ((status = get_index(reader, primitive, primitive_where, "material", reader->materials.count,
                                    "materials", &out->material)) != LK_OK)
                return status;
            if ((status = lk__gltf_take_mesh(gltf, &out->mesh)) != LK_OK) return status;
            mesh->primitive_count++;
            if (gltf->line_count) {
                /* the arrays stay charged: the scene holds them */
                out->lines = lk__buffer_take_charged(&gltf->lines, gltf->ctx->budget);
                out->line_count = gltf->line_count;
                gltf->line_count = 0;
            }
            if ((status = read_extra_attribute(reader, primitive, primitive_where, "TANGENT", out->mesh.vertex_count,
                                               &out->tangents)) != LK_OK)
                return status;
            if ((status = read_extra_attribute(reader, primitive, primitive_where, "TEXCOORD_1", out->mesh.vertex_count,
                                               &out->texcoords1)) != LK_OK)
                return status;
            if ((status = read_skin_attributes(reader, primitive, primitive_where, out->mesh.vertex_count, out)) !=
                LK_OK)
                return status;
            if ((status = read_morph_targets(reader, primitive, primitive_where, mesh, mesh->primitive_count == 1,
                                             out)) != LK_OK)
                return status;
            if (out->texcoords1 && !out->mesh.texcoords) {
                /* glTF numbers texture coordinates from 0 without gaps */
                note(reader, "%s: TEXCOORD_1 without TEXCOORD_0 becomes TEXCOORD_0", primitive_where);
                out->mesh.texcoords = out->texcoords1;
                out->texcoords1 = NULL;
            }
        }
        if ((status = read_mesh_weights(reader, object, where, mesh)) != LK_OK) return status;
    }
    return LK_OK;
}

/* node.weights: as many as its mesh has morph targets. */
static lk_status read_node_weights(scene_reader *reader, const cJSON *object, const char *where, lk_scene_node *node)
{
    gltf_reader *gltf = &reader->gltf;
    const cJSON *weights;
    lk_status status = lk__gltf_get_array(gltf, object, where, "weights", &weights);
    if (status != LK_OK || !weights) return status;
    size_t count = node->mesh >= 0 ? reader->scene->meshes[node->mesh].target_count : 0;
    if ((size_t)cJSON_GetArraySize(weights) != count || count == 0)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, where, "weights", "%d weights, but its mesh has %zu morph targets",
                             cJSON_GetArraySize(weights), count);
    return read_weights(reader, object, where, count, &node->weights);
}

static lk_status read_node(scene_reader *reader, size_t index, lk_scene_node *node)
{
    gltf_reader *gltf = &reader->gltf;
    const cJSON *object = gltf->nodes.items[index], *name, *children;
    char where[48];
    snprintf(where, sizeof where, "nodes[%zu]", index);
    lk__scene_node_init(node);
    lk_status status = lk__gltf_get_string(gltf, object, where, "name", &name);
    if (status == LK_OK)
        status = get_index(reader, object, where, "mesh", reader->scene->mesh_count, "meshes", &node->mesh);
    if (status == LK_OK)
        status = get_index(reader, object, where, "camera", reader->cameras.count, "cameras", &node->camera);
    if (status == LK_OK) status = get_index(reader, object, where, "skin", reader->skins.count, "skins", &node->skin);
    if (status == LK_OK) status = lk__gltf_get_array(gltf, object, where, "children", &children);
    if (status == LK_OK) status = lk__gltf_node_local_matrix(gltf, object, where, node->matrix);
    if (status != LK_OK) return status;
    if (name && !(node->name = copy_string(name->valuestring))) return nomem(reader);
    bool present = false;
    if ((status = lk__gltf_get_number_array(gltf, object, where, "matrix", 16, node->matrix, &present)) != LK_OK)
        return status;
    node->has_matrix = present;
    if (!present) {
        lk__gltf_get_number_array(gltf, object, where, "translation", 3, node->translation, NULL);
        lk__gltf_get_number_array(gltf, object, where, "rotation", 4, node->rotation, NULL);
        lk__gltf_get_number_array(gltf, object, where, "scale", 3, node->scale, NULL);
    }
    size_t child_count = children ? (size_t)cJSON_GetArraySize(children) : 0;
    if (child_count) {
        node->children = lk__calloc_array(child_count, sizeof *node->children);
        if (!node->children) return nomem(reader);
        const cJSON *child;
        cJSON_ArrayForEach(child, children)
        {
            char key[48];
            snprintf(key, sizeof key, "children[%zu]", node->child_count);
            if ((status = lk__gltf_check_uint(gltf, child, where, key)) != LK_OK) return status;
            if (child->valuedouble >= (double)gltf->nodes.count)
                return lk__gltf_fail(gltf, LK_ERR_RANGE, where, key, "node %.0f out of range (%zu nodes)",
                                     child->valuedouble, gltf->nodes.count);
            node->children[node->child_count++] = (uint32_t)child->valuedouble;
        }
    }
    const cJSON *extras = lk__gltf_member(object, "extras");
    if (extras && !(node->extras = cJSON_PrintUnformatted(extras))) return nomem(reader);
    if ((status = read_node_weights(reader, object, where, node)) != LK_OK) return status;
    const cJSON *extensions = lk__gltf_member(object, "extensions"), *extension;
    cJSON_ArrayForEach(extension, extensions)
    {
        if (strcmp(extension->string, "MSFT_lod") != 0) {
            note(reader, "%s: extension %s dropped (not supported)", where, extension->string);
            continue;
        }
        const cJSON *ids, *id;
        char lod_where[96];
        snprintf(lod_where, sizeof lod_where, "%s.extensions.MSFT_lod", where);
        if ((status = lk__gltf_get_array(gltf, extension, lod_where, "ids", &ids)) != LK_OK) return status;
        size_t count = ids ? (size_t)cJSON_GetArraySize(ids) : 0;
        if (count == 0) continue;
        node->lod_nodes = lk__calloc_array(count, sizeof *node->lod_nodes);
        if (!node->lod_nodes) return nomem(reader);
        cJSON_ArrayForEach(id, ids)
        {
            char key[48];
            snprintf(key, sizeof key, "ids[%zu]", node->lod_count);
            if ((status = lk__gltf_check_uint(gltf, id, lod_where, key)) != LK_OK) return status;
            if (id->valuedouble >= (double)gltf->nodes.count)
                return lk__gltf_fail(gltf, LK_ERR_RANGE, lod_where, key, "node %.0f out of range (%zu nodes)",
                                     id->valuedouble, gltf->nodes.count);
            node->lod_nodes[node->lod_count++] = (uint32_t)id->valuedouble;
        }
    }
    return LK_OK;
}

/* Nodes form disjoint trees: each node has at most one parent and no node
 * is its own ancestor. */
static lk_status check_tree(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    gltf_reader *gltf = &reader->gltf;
    lk_status status = LK_OK;
    uint32_t *parent = lk__gltf_charged_calloc(gltf, scene->node_count, sizeof *parent, &status);
    if (!parent) return status;
    for (size_t i = 0; i < scene->node_count; i++) parent[i] = UINT32_MAX;
    for (size_t i = 0; i < scene->node_count && status == LK_OK; i++)
        for (size_t c = 0; c < scene->nodes[i].child_count; c++) {
            uint32_t child = scene->nodes[i].children[c];
            if (parent[child] != UINT32_MAX || child == i) {
                char where[48];
                snprintf(where, sizeof where, "nodes[%zu]", i);
                status = lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL,
                                       "node %u is reached twice (the node hierarchy has a cycle or a node with two "
                                       "parents)",
                                       child);
                break;
            }
            parent[child] = (uint32_t)i;
        }
    /* A cycle leaves every node on it with a parent: climbing from any node
     * must reach a root within node_count steps. */
    for (size_t i = 0; i < scene->node_count && status == LK_OK; i++) {
        size_t steps = 0;
        for (uint32_t at = (uint32_t)i; parent[at] != UINT32_MAX; at = parent[at])
            if (++steps > scene->node_count) {
                status = lk__gltf_fail(gltf, LK_ERR_PARSE, "", "nodes",
                                       "node %zu is its own ancestor (the node hierarchy has a cycle)", i);
                break;
            }
    }
    lk__gltf_charged_free(gltf, parent, scene->node_count, sizeof *parent);
    return status;
}

static lk_status read_nodes_and_roots(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    gltf_reader *gltf = &reader->gltf;
    size_t node_count = gltf->nodes.count;
    if (node_count) {
        scene->nodes = lk__calloc_array(node_count, sizeof *scene->nodes);
        if (!scene->nodes) return nomem(reader);
        for (size_t i = 0; i < node_count; i++) {
            lk_status status = read_node(reader, i, &scene->nodes[i]);
            scene->node_count++;
            if (status != LK_OK) return status;
        }
    }
    lk_status status = check_tree(reader);
    if (status != LK_OK) return status;

    uint64_t scene_index;
    if ((status = lk__gltf_get_uint(gltf, gltf->root, "", "scene", false, UINT64_MAX, &scene_index)) != LK_OK)
        return status;
    if (scene_index != UINT64_MAX && scene_index >= gltf->scenes.count)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, "", "scene", "scene %llu out of range (%zu scenes)",
                             (unsigned long long)scene_index, gltf->scenes.count);
    if (gltf->scenes.count > 1) note(reader, "scenes other than the default one dropped");
    scene->roots = lk__calloc_array(node_count ? node_count : 1, sizeof *scene->roots);
    if (!scene->roots) return nomem(reader);
    if (gltf->scenes.count == 0) {
        /* No scene: every node without a parent is drawn; without nodes,
         * every mesh gets one. */
        unsigned char *has_parent = lk__gltf_charged_calloc(gltf, node_count ? node_count : 1, 1, &status);
        if (!has_parent) return status;
        for (size_t i = 0; i < node_count; i++)
            for (size_t c = 0; c < scene->nodes[i].child_count; c++) has_parent[scene->nodes[i].children[c]] = 1;
        for (size_t i = 0; i < node_count; i++)
            if (!has_parent[i]) scene->roots[scene->root_count++] = (uint32_t)i;
        lk__gltf_charged_free(gltf, has_parent, node_count ? node_count : 1, 1);
        if (node_count == 0 && scene->mesh_count > 0) {
            free(scene->roots);
            scene->nodes = lk__calloc_array(scene->mesh_count, sizeof *scene->nodes);
            scene->roots = lk__calloc_array(scene->mesh_count, sizeof *scene->roots);
            if (!scene->nodes || !scene->roots) return nomem(reader);
            for (size_t m = 0; m < scene->mesh_count; m++) {
                lk__scene_node_init(&scene->nodes[m]);
                scene->nodes[m].mesh = (int32_t)m;
                scene->roots[m] = (uint32_t)m;
            }
            scene->node_count = scene->root_count = scene->mesh_count;
        }
        return LK_OK;
    }
    if (scene_index == UINT64_MAX) scene_index = 0;
    const cJSON *list, *item;
    char where[48], roots_where[64];
    snprintf(where, sizeof where, "scenes[%llu]", (unsigned long long)scene_index);
    snprintf(roots_where, sizeof roots_where, "%s.nodes", where);
    if ((status = lk__gltf_get_array(gltf, gltf->scenes.items[scene_index], where, "nodes", &list)) != LK_OK)
        return status;
    cJSON_ArrayForEach(item, list)
    {
        char key[32];
        snprintf(key, sizeof key, "[%zu]", scene->root_count);
        if ((status = lk__gltf_check_uint(gltf, item, roots_where, key)) != LK_OK) return status;
        if (item->valuedouble >= (double)node_count)
            return lk__gltf_fail(gltf, LK_ERR_RANGE, roots_where, key, "node %.0f out of range (%zu nodes)",
                                 item->valuedouble, node_count);
        uint32_t root = (uint32_t)item->valuedouble;
        for (size_t r = 0; r < scene->root_count; r++)
            if (scene->roots[r] == root)
                return lk__gltf_fail(gltf, LK_ERR_PARSE, roots_where, key, "node %u is listed twice", root);
        if (scene->root_count == node_count)
            return lk__gltf_fail(gltf, LK_ERR_PARSE, roots_where, NULL, "lists more nodes than exist");
        scene->roots[scene->root_count++] = root;
    }
    return LK_OK;
}

/* extensionsRequired entries the kept objects still use. */
static lk_status read_required_extensions(scene_reader *reader)
{
    const cJSON *list = lk__gltf_member(reader->gltf.root, "extensionsRequired"), *item;
    size_t count = cJSON_IsArray(list) ? (size_t)cJSON_GetArraySize(list) : 0;
    if (count == 0) return LK_OK;
    lk_scene *scene = reader->scene;
    scene->required_extensions = lk__calloc_array(count, sizeof *scene->required_extensions);
    if (!scene->required_extensions) return nomem(reader);
    cJSON_ArrayForEach(item, list)
    {
        if (!cJSON_IsString(item) || !extension_is_kept(item->valuestring)) continue;
        char *copy = copy_string(item->valuestring);
        if (!copy) return nomem(reader);
        scene->required_extensions[scene->required_extension_count++] = copy;
    }
    return LK_OK;
}

/* A node index member of `where` in [0, node_count). */
static lk_status check_node(scene_reader *reader, const cJSON *item, const char *where, const char *key)
{
    gltf_reader *gltf = &reader->gltf;
    size_t node_count = reader->scene->node_count;
    lk_status status = lk__gltf_check_uint(gltf, item, where, key);
    if (status == LK_OK && item->valuedouble >= (double)node_count)
        status = lk__gltf_fail(gltf, LK_ERR_RANGE, where, key, "node %.0f out of range (%zu node%s)", item->valuedouble,
                               node_count, node_count == 1 ? "" : "s");
    return status;
}

static lk_status read_skin(scene_reader *reader, size_t index, lk_scene_skin *skin)
{
    gltf_reader *gltf = &reader->gltf;
    const cJSON *object = reader->skins.items[index], *name, *joints, *item;
    char where[48];
    snprintf(where, sizeof where, "skins[%zu]", index);
    skin->skeleton = -1;
    lk_status status = lk__gltf_get_string(gltf, object, where, "name", &name);
    if (status == LK_OK) status = lk__gltf_get_array(gltf, object, where, "joints", &joints);
    if (status == LK_OK)
        status = get_index(reader, object, where, "skeleton", reader->scene->node_count, "nodes", &skin->skeleton);
    if (status != LK_OK) return status;
    if (name && !(skin->name = copy_string(name->valuestring))) return nomem(reader);
    size_t count = joints ? (size_t)cJSON_GetArraySize(joints) : 0;
    if (count == 0) return lk__gltf_fail(gltf, LK_ERR_PARSE, where, "joints", "missing or empty");
    if (!lk__budget_charge(gltf->ctx->budget, count, sizeof(uint32_t))) return lk__gltf_over_budget(gltf);
    if (!(skin->joints = lk__malloc_array(count, sizeof(uint32_t)))) return nomem(reader);
    cJSON_ArrayForEach(item, joints)
    {
        char key[48];
        snprintf(key, sizeof key, "joints[%zu]", skin->joint_count);
        if ((status = check_node(reader, item, where, key)) != LK_OK) return status;
        skin->joints[skin->joint_count++] = (uint32_t)item->valuedouble;
    }
    uint64_t matrices;
    if ((status = lk__gltf_get_uint(gltf, object, where, "inverseBindMatrices", false, UINT64_MAX, &matrices)) !=
            LK_OK ||
        matrices == UINT64_MAX)
        return status;
    gltf_accessor accessor;
    if ((status = lk__gltf_read_accessor_floats(gltf, matrices, where, "inverseBindMatrices", TYPE_MAT4, "a MAT4",
                                                &accessor, &skin->inverse_bind_matrices)) != LK_OK)
        return status;
    if (accessor.component_type != COMPONENT_FLOAT)
        return lk__gltf_fail(gltf, LK_ERR_PARSE, where, "inverseBindMatrices", "must be floats (componentType 5126)");
    if (accessor.count < count)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, where, "inverseBindMatrices", "%zu matrices for %zu joints",
                             accessor.count, count);
    return LK_OK;
}

/* Skins, and each node's use of one: a node's skin needs the node's mesh,
 * whose primitives have joints, each naming one of the skin's joints. */
static lk_status read_skins(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    if (reader->skins.count) {
        if (!(scene->skins = lk__calloc_array(reader->skins.count, sizeof *scene->skins))) return nomem(reader);
        for (size_t i = 0; i < reader->skins.count; i++) {
            scene->skin_count++;
            lk_status status = read_skin(reader, i, &scene->skins[i]);
            if (status != LK_OK) return status;
        }
    }
    for (size_t n = 0; n < scene->node_count; n++) {
        lk_scene_node *node = &scene->nodes[n];
        if (node->skin < 0) continue;
        char where[48];
        snprintf(where, sizeof where, "nodes[%zu]", n);
        const lk_scene_mesh *mesh = node->mesh >= 0 ? &scene->meshes[node->mesh] : NULL;
        bool has_joints = mesh != NULL;
        for (size_t p = 0; mesh && p < mesh->primitive_count; p++) has_joints &= mesh->primitives[p].joints != NULL;
        if (!has_joints) {
            note(reader, "%s: skin dropped (%s)", where,
                 mesh ? "its mesh has primitives without JOINTS_0 and WEIGHTS_0" : "the node has no mesh");
            node->skin = -1;
            continue;
        }
        const lk_scene_skin *skin = &scene->skins[node->skin];
        for (size_t p = 0; p < mesh->primitive_count; p++) {
            const lk_scene_primitive *primitive = &mesh->primitives[p];
            for (size_t i = 0; i < 4 * primitive->mesh.vertex_count; i++)
                if (primitive->joints[i] >= skin->joint_count)
                    return lk__gltf_fail(&reader->gltf, LK_ERR_RANGE, where, "skin",
                                         "meshes[%d].primitives[%zu] vertex %zu uses joint %u but skins[%d] has %zu "
                                         "joint%s",
                                         node->mesh, p, i / 4, primitive->joints[i], node->skin, skin->joint_count,
                                         skin->joint_count == 1 ? "" : "s");
        }
    }
    return LK_OK;
}

/* One sampler: interpolation, key times (floats, strictly increasing) and
 * values (VEC3 or VEC4 floats or normalised integers, decoded). */
static lk_status read_animation_sampler(scene_reader *reader, const cJSON *object, const char *where,
                                        lk_scene_animation_sampler *sampler)
{
    gltf_reader *gltf = &reader->gltf;
    if (!cJSON_IsObject(object)) return lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL, "expected an object");
    const cJSON *interpolation;
    lk_status status = lk__gltf_get_string(gltf, object, where, "interpolation", &interpolation);
    if (status != LK_OK) return status;
    sampler->interpolation = LK_SCENE_LINEAR;
    if (interpolation && strcmp(interpolation->valuestring, "STEP") == 0)
        sampler->interpolation = LK_SCENE_STEP;
    else if (interpolation && strcmp(interpolation->valuestring, "CUBICSPLINE") == 0)
        sampler->interpolation = LK_SCENE_CUBICSPLINE;
    else if (interpolation && strcmp(interpolation->valuestring, "LINEAR") != 0)
        return lk__gltf_fail(gltf, LK_ERR_PARSE, where, "interpolation", "\"%.40s\" is not LINEAR, STEP or CUBICSPLINE",
                             interpolation->valuestring);
    uint64_t input, output;
    if ((status = lk__gltf_get_uint(gltf, object, where, "input", true, 0, &input)) != LK_OK ||
        (status = lk__gltf_get_uint(gltf, object, where, "output", true, 0, &output)) != LK_OK)
        return status;
    gltf_accessor accessor;
    if ((status = lk__gltf_read_accessor_floats(gltf, input, where, "input", TYPE_SCALAR, "a SCALAR", &accessor,
                                                &sampler->input)) != LK_OK)
        return status;
    sampler->key_count = accessor.count;
    if (accessor.component_type != COMPONENT_FLOAT)
        return lk__gltf_fail(gltf, LK_ERR_PARSE, where, "input", "key times must be floats (componentType 5126)");
    if (accessor.count == 0) return lk__gltf_fail(gltf, LK_ERR_PARSE, where, "input", "no key times");
    for (size_t k = 0; k < sampler->key_count; k++)
        if (sampler->input[k] < 0 || (k > 0 && !(sampler->input[k] > sampler->input[k - 1])))
            return lk__gltf_fail(gltf, LK_ERR_RANGE, where, "input",
                                 "key times must be >= 0 and increase strictly (key %zu: %g)", k,
                                 (double)sampler->input[k]);
    /* SCALAR: morph weights, a value per target and key */
    if ((status = lk__gltf_read_accessor_floats(gltf, output, where, "output", TYPE_SCALAR | TYPE_VEC3 | TYPE_VEC4,
                                                "a SCALAR, VEC3 or VEC4", &accessor, &sampler->output)) != LK_OK)
        return status;
    sampler->components = accessor.component_count;
    sampler->output_count = accessor.count;
    return LK_OK;
}

/* One channel; *kept false when it is dropped (targets that extensions
 * define, paths glTF 2.0 does not). */
static lk_status read_animation_channel(scene_reader *reader, const cJSON *object, const char *where,
                                        const lk_scene_animation *animation, size_t sampler_count,
                                        lk_scene_animation_channel *channel, bool *kept)
{
    gltf_reader *gltf = &reader->gltf;
    *kept = false;
    if (!cJSON_IsObject(object)) return lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL, "expected an object");
    uint64_t sampler;
    const cJSON *target, *node, *path;
    lk_status status = lk__gltf_get_uint(gltf, object, where, "sampler", true, 0, &sampler);
    if (status == LK_OK) status = lk__gltf_get_object(gltf, object, where, "target", &target);
    if (status != LK_OK) return status;
    if (sampler >= sampler_count)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, where, "sampler", "sampler %llu out of range (%zu sampler%s)",
                             (unsigned long long)sampler, sampler_count, sampler_count == 1 ? "" : "s");
    if (!target) return lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL, "missing required \"target\"");
    char target_where[128];
    snprintf(target_where, sizeof target_where, "%s.target", where);
    if ((status = lk__gltf_get_string(gltf, target, target_where, "path", &path)) != LK_OK) return status;
    if (!path) return lk__gltf_fail(gltf, LK_ERR_PARSE, target_where, NULL, "missing required \"path\"");
    node = lk__gltf_member(target, "node");
    if (!node) {
        note(reader, "%s: a target without a node dropped", where);
        return LK_OK;
    }
    if ((status = check_node(reader, node, target_where, "node")) != LK_OK) return status;
    unsigned components;
    size_t targets = 1; /* values per key and component: the morph targets for weights */
    if (strcmp(path->valuestring, "translation") == 0)
        channel->path = LK_SCENE_PATH_TRANSLATION, components = 3;
    else if (strcmp(path->valuestring, "rotation") == 0)
        channel->path = LK_SCENE_PATH_ROTATION, components = 4;
    else if (strcmp(path->valuestring, "scale") == 0)
        channel->path = LK_SCENE_PATH_SCALE, components = 3;
    else if (strcmp(path->valuestring, "weights") == 0) {
        int32_t mesh = reader->scene->nodes[(size_t)node->valuedouble].mesh;
        channel->path = LK_SCENE_PATH_WEIGHTS, components = 1;
        targets = mesh >= 0 ? reader->scene->meshes[mesh].target_count : 0;
        if (targets == 0)
            return lk__gltf_fail(gltf, LK_ERR_PARSE, target_where, "node", "node %.0f has no morph targets to weigh",
                                 node->valuedouble);
    } else {
        note(reader, "%s: path \"%.40s\" dropped (not supported)", where, path->valuestring);
        return LK_OK;
    }
    channel->node = (uint32_t)node->valuedouble;
    channel->sampler = (uint32_t)sampler;
    if (channel->path != LK_SCENE_PATH_WEIGHTS && reader->scene->nodes[channel->node].has_matrix)
        return lk__gltf_fail(gltf, LK_ERR_PARSE, target_where, "node",
                             "node %u has a \"matrix\" and cannot be animated (glTF requires TRS)", channel->node);
    const lk_scene_animation_sampler *used = &animation->samplers[sampler];
    if (used->components != components)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, where, "sampler",
                             "sampler %llu gives %u values per key but \"%s\" needs %u", (unsigned long long)sampler,
                             used->components, path->valuestring, components);
    size_t expected = used->key_count * (used->interpolation == LK_SCENE_CUBICSPLINE ? 3 : 1) * targets;
    if (used->output_count != expected)
        return lk__gltf_fail(gltf, LK_ERR_RANGE, where, "sampler",
                             "sampler %llu has %zu values for %zu key times (%zu expected)",
                             (unsigned long long)sampler, used->output_count, used->key_count, expected);
    *kept = true;
    return LK_OK;
}

/* Samplers no kept channel uses are dropped (glTF wants each used) and
 * the channels renumbered. */
static void drop_unused_samplers(lk_scene_animation *animation)
{
    size_t kept = 0;
    for (size_t s = 0; s < animation->sampler_count; s++) {
        bool used = false;
        for (size_t c = 0; c < animation->channel_count; c++) used |= animation->channels[c].sampler == s;
        if (!used) {
            free(animation->samplers[s].input);
            free(animation->samplers[s].output);
            continue;
        }
        for (size_t c = 0; c < animation->channel_count; c++)
            if (animation->channels[c].sampler == s) animation->channels[c].sampler = (uint32_t)kept;
        animation->samplers[kept++] = animation->samplers[s];
    }
    animation->sampler_count = kept;
}

static lk_status read_animation(scene_reader *reader, size_t index, lk_scene_animation *animation)
{
    gltf_reader *gltf = &reader->gltf;
    const cJSON *object = reader->animations.items[index], *name, *samplers, *channels, *item;
    char where[48];
    snprintf(where, sizeof where, "animations[%zu]", index);
    lk_status status = lk__gltf_get_string(gltf, object, where, "name", &name);
    if (status == LK_OK) status = lk__gltf_get_array(gltf, object, where, "samplers", &samplers);
    if (status == LK_OK) status = lk__gltf_get_array(gltf, object, where, "channels", &channels);
    if (status != LK_OK) return status;
    if (!samplers || !channels)
        return lk__gltf_fail(gltf, LK_ERR_PARSE, where, NULL, "needs \"samplers\" and \"channels\"");
    if (name && !(animation->name = copy_string(name->valuestring))) return nomem(reader);
    size_t sampler_count = (size_t)cJSON_GetArraySize(samplers), channel_count = (size_t)cJSON_GetArraySize(channels);
    if (!lk__budget_charge(gltf->ctx->budget, sampler_count + channel_count,
                           sizeof(lk_scene_animation_sampler) + sizeof(lk_scene_animation_channel)))
        return lk__gltf_over_budget(gltf);
    animation->samplers = lk__calloc_array(sampler_count ? sampler_count : 1, sizeof *animation->samplers);
    animation->channels = lk__calloc_array(channel_count ? channel_count : 1, sizeof *animation->channels);
    if (!animation->samplers || !animation->channels) return nomem(reader);
    cJSON_ArrayForEach(item, samplers)
    {
        char sampler_where[96];
        snprintf(sampler_where, sizeof sampler_where, "%s.samplers[%zu]", where, animation->sampler_count);
        status = read_animation_sampler(reader, item, sampler_where, &animation->samplers[animation->sampler_count++]);
        if (status != LK_OK) return status;
    }
    size_t c = 0;
    cJSON_ArrayForEach(item, channels)
    {
        char channel_where[96];
        snprintf(channel_where, sizeof channel_where, "%s.channels[%zu]", where, c++);
        bool kept;
        status = read_animation_channel(reader, item, channel_where, animation, sampler_count,
                                        &animation->channels[animation->channel_count], &kept);
        if (status != LK_OK) return status;
        animation->channel_count += kept;
    }
    drop_unused_samplers(animation);
    return LK_OK;
}

/* Node animations; one left without channels is dropped. */
static lk_status read_animations(scene_reader *reader)
{
    lk_scene *scene = reader->scene;
    if (reader->animations.count == 0) return LK_OK;
    if (!(scene->animations = lk__calloc_array(reader->animations.count, sizeof *scene->animations)))
        return nomem(reader);
    for (size_t i = 0; i < reader->animations.count; i++) {
        lk_scene_animation *animation = &scene->animations[scene->animation_count++];
        lk_status status = read_animation(reader, i, animation);
        if (status != LK_OK) return status;
        if (animation->channel_count == 0) {
            note(reader, "animations[%zu] dropped (nothing it animates is kept)", i);
            free(animation->name);
            free(animation->samplers);
            free(animation->channels);
            memset(animation, 0, sizeof *animation);
            scene->animation_count--;
        }
    }
    return LK_OK;
}

static void note_root_level(scene_reader *reader)
{
    const cJSON *root = reader->gltf.root;
    const cJSON *extensions = lk__gltf_member(root, "extensions"), *extension;
    cJSON_ArrayForEach(extension, extensions)
    {
        note(reader, "extension %s dropped (not supported)", extension->string);
    }
}

lk_status lk__read_gltf_scene(const char *data, size_t size, const lk__read_context *ctx, lk_scene *scene,
                              lk_error *error)
{
    scene_reader reader;
    memset(&reader, 0, sizeof reader);
    reader.gltf.ctx = ctx;
    reader.gltf.error = error;
    reader.gltf.keep_lines = true;
    reader.scene = scene;
    lk_scene_init(scene);
    cJSON *root = NULL;
    lk_status status = lk__gltf_open_document(&reader.gltf, data, size, &root);
    if (status == LK_OK) status = lk__gltf_build_table(&reader.gltf, "materials", &reader.materials);
    if (status == LK_OK) status = lk__gltf_build_table(&reader.gltf, "textures", &reader.textures);
    if (status == LK_OK) status = lk__gltf_build_table(&reader.gltf, "images", &reader.images);
    if (status == LK_OK) status = lk__gltf_build_table(&reader.gltf, "samplers", &reader.samplers);
    if (status == LK_OK) status = lk__gltf_build_table(&reader.gltf, "cameras", &reader.cameras);
    if (status == LK_OK) status = lk__gltf_build_table(&reader.gltf, "skins", &reader.skins);
    if (status == LK_OK) status = lk__gltf_build_table(&reader.gltf, "animations", &reader.animations);
    if (status == LK_OK) status = read_images(&reader);
    if (status == LK_OK)
        status = read_json_array(&reader, &reader.samplers, "samplers", sampler_properties, &scene->samplers,
                                 &scene->sampler_count);
    if (status == LK_OK)
        status = read_json_array(&reader, &reader.cameras, "cameras", camera_properties, &scene->cameras,
                                 &scene->camera_count);
    if (status == LK_OK) status = read_textures(&reader);
    if (status == LK_OK) status = read_materials(&reader);
    if (status == LK_OK) status = read_meshes(&reader);
    if (status == LK_OK) status = read_nodes_and_roots(&reader);
    if (status == LK_OK) status = read_skins(&reader);
    if (status == LK_OK) status = read_animations(&reader);
    if (status == LK_OK) status = read_required_extensions(&reader);
    if (status == LK_OK) note_root_level(&reader);
    if (status == LK_OK && reader.notes.size) {
        reader.notes.data[reader.notes.size - 1] = '\0'; /* the last newline */
        scene->notes = lk__buffer_take(&reader.notes);
    }
    lk__buffer_free(&reader.notes);
    json_table *tables[] = {&reader.materials, &reader.textures, &reader.images,    &reader.samplers,
                            &reader.cameras,   &reader.skins,    &reader.animations};
    for (size_t i = 0; i < sizeof tables / sizeof tables[0]; i++) lk__gltf_table_free(&reader.gltf, tables[i]);
    lk__gltf_release(&reader.gltf, root);
    if (status != LK_OK) lk_scene_free(scene);
    return status;
}
