/* SPDX-License-Identifier: MIT */
/* glTF writer: an animation as one morph-target .gltf.
 *
 * One mesh, one node, one animation. Frame 0 is the base geometry; frame f
 * (f >= 1) is morph target f-1 holding frame_f - frame_0. The animation's
 * key f at time f / fps has weight 1 for target f-1 and 0 elsewhere, with
 * LINEAR interpolation, which blends consecutive frames linearly as a
 * key-frame player would. Everything goes into one .gltf with the buffer
 * embedded as a base64 data: URI. Reading it back gives the same frames up
 * to float rounding of base + (frame - base); frame names and normals of
 * later frames (never stored) are lost.
 *
 * The file passes the Khronos glTF-Validator with no error and no warning
 * (tests/cli/test_gltf_validate.sh): normals are written at unit length,
 * colours clamped to 0..1, vertex and index views carry their target, and
 * an animation whose frame offsets or key times do not fit a float is
 * refused rather than written with an infinity. */
#include "bytes.h"
#include "io_gltf.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define GLTF_WRITE_MAX_FRAMES 2048 /* the weights output grows as frames^2 */

/* bufferView.target: vertex attributes (morph targets too) and indices;
 * animation data has none. */
enum { WRITE_TARGET_NONE = 0, WRITE_TARGET_VERTICES = 34962, WRITE_TARGET_INDICES = 34963 };

typedef struct gltf_writer {
    lk__buffer bin;
    cJSON *views, *accessors;
    size_t view_count, accessor_count;
    bool failed;
} gltf_writer;

/* Describes bytes [offset, offset + bytes) of the buffer, already written,
 * as a new bufferView (with `target` unless WRITE_TARGET_NONE) and an
 * accessor of `count` elements; returns the accessor (NULL when out of
 * memory: writer->failed is set). */
static cJSON *add_view_accessor(gltf_writer *writer, size_t offset, size_t bytes, int target, int component_type,
                                size_t count, const char *type)
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
    if (target != WRITE_TARGET_NONE) cJSON_AddNumberToObject(view, "target", target);
    cJSON_AddNumberToObject(accessor, "bufferView", (double)writer->view_count++);
    cJSON_AddNumberToObject(accessor, "componentType", component_type);
    cJSON_AddNumberToObject(accessor, "count", (double)count);
    cJSON_AddStringToObject(accessor, "type", type);
    writer->accessor_count++;
    return accessor;
}

/* Appends `count` elements of `components` floats as a new bufferView for
 * `target` and an accessor; returns the accessor index. with_bounds adds
 * min/max. */
static size_t write_float_accessor(gltf_writer *writer, const float *values, size_t count, unsigned components,
                                   int target, const char *type, bool with_bounds)
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
    cJSON *accessor = add_view_accessor(writer, offset, bytes, target, COMPONENT_FLOAT, count, type);
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

/* glTF wants every NORMAL at unit length; a lodkit mesh may hold any length,
 * and zero where a vertex has no normal (the glTF reader gives a primitive
 * without normals zeros; so does an OBJ corner without vn). Writes
 * mesh->normals scaled to unit length into `out` (3 floats per vertex). A
 * missing one becomes the area-weighted normal of the vertex's triangles in
 * `positions` (frame 0), or +z where they have no area either: such a vertex
 * draws no pixel, so any unit vector will do. False when out of memory. */
bool lk__gltf_unit_normals(const lk_mesh *mesh, const float *positions, float *out)
{
    size_t vertex_count = mesh->vertex_count;
    bool some_missing = false;
    for (size_t v = 0; v < vertex_count; v++) {
        const double n[3] = {mesh->normals[3 * v], mesh->normals[3 * v + 1], mesh->normals[3 * v + 2]};
        double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        bool usable = length > 0 && isfinite(length);
        /* A missing normal stays (0, 0, 0) here until the faces give one. */
        for (int c = 0; c < 3; c++) out[3 * v + c] = usable ? (float)(n[c] / length) : 0.0f;
        some_missing |= !usable;
    }
    if (!some_missing) return true;
    double *sums = lk__calloc_array(vertex_count, 3 * sizeof(double));
    if (!sums) return false;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *corner = mesh->indices + 3 * t;
        const float *a = positions + 3 * corner[0], *b = positions + 3 * corner[1], *c = positions + 3 * corner[2];
        /* In double: differences of floats near FLT_MAX overflow a float. */
        double u[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
        double w[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
        double face[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++) sums[3 * corner[k] + i] += face[i];
    }
    for (size_t v = 0; v < vertex_count; v++) {
        float *n = out + 3 * v;
        if (n[0] != 0 || n[1] != 0 || n[2] != 0) continue; /* the mesh's own */
        const double *sum = sums + 3 * v;
        double length = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
        for (int c = 0; c < 3; c++)
            n[c] = length > 0 && isfinite(length) ? (float)(sum[c] / length) : (c == 2 ? 1.0f : 0.0f);
    }
    free(sums);
    return true;
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
                            (double)write_float_accessor(&writer, animation->frame_positions, vertex_count, 3,
                                                         WRITE_TARGET_VERTICES, "VEC3", true));
    if (mesh->normals) {
        if (!lk__gltf_unit_normals(mesh, animation->frame_positions, scratch)) goto nomem;
        cJSON_AddNumberToObject(
            attributes, "NORMAL",
            (double)write_float_accessor(&writer, scratch, vertex_count, 3, WRITE_TARGET_VERTICES, "VEC3", false));
    }
    if (mesh->texcoords) {
        /* lodkit's v points up, glTF's down. */
        for (size_t v = 0; v < vertex_count; v++) {
            scratch[2 * v] = mesh->texcoords[2 * v];
            scratch[2 * v + 1] = 1.0f - mesh->texcoords[2 * v + 1];
        }
        cJSON_AddNumberToObject(
            attributes, "TEXCOORD_0",
            (double)write_float_accessor(&writer, scratch, vertex_count, 2, WRITE_TARGET_VERTICES, "VEC2", false));
    }
    if (mesh->colors) {
        /* glTF colours are 0..1; SMF and OBJ colours may lie outside. */
        for (size_t i = 0; i < vertex_count * 4; i++) scratch[i] = fminf(fmaxf(mesh->colors[i], 0.0f), 1.0f);
        cJSON_AddNumberToObject(
            attributes, "COLOR_0",
            (double)write_float_accessor(&writer, scratch, vertex_count, 4, WRITE_TARGET_VERTICES, "VEC4", false));
    }
    if (mesh->triangle_count) {
        size_t offset = writer.bin.size, bytes = mesh->triangle_count * 12;
        if (!lk__buffer_reserve(&writer.bin, bytes)) goto nomem;
        for (size_t i = 0; i < mesh->triangle_count * 3; i++)
            lk__store_u32le(writer.bin.data + offset + 4 * i, mesh->indices[i]);
        writer.bin.size += bytes;
        add_view_accessor(&writer, offset, bytes, WRITE_TARGET_INDICES, COMPONENT_UNSIGNED_INT,
                          mesh->triangle_count * 3, "SCALAR");
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
            for (size_t i = 0; i < vertex_count * 3; i++) {
                scratch[i] = frame[i] - base[i];
                if (!isfinite(scratch[i])) {
                    status = lk_error_set(error, LK_ERR_RANGE,
                                          "%s: frame %zu: vertex %zu moves farther from frame 0 than a float holds "
                                          "(glTF stores a frame as its offset from frame 0); use .kmf",
                                          name, f, i / 3);
                    goto done;
                }
            }
            cJSON *target = cJSON_CreateObject();
            cJSON_AddItemToArray(targets, target);
            cJSON_AddNumberToObject(
                target, "POSITION",
                (double)write_float_accessor(&writer, scratch, vertex_count, 3, WRITE_TARGET_VERTICES, "VEC3", true));
            cJSON_AddItemToArray(weights, cJSON_CreateNumber(0));
        }
        /* Key times must be finite floats, each above the one before. */
        for (size_t f = 0; f < frame_count; f++) {
            scratch[f] = (float)((double)f / animation->frames_per_second);
            if (!isfinite(scratch[f]) || (f > 0 && !(scratch[f] > scratch[f - 1]))) {
                status = lk_error_set(error, LK_ERR_RANGE,
                                      "%s: at %g frames per second, frame %zu's time (%g s) has no float above "
                                      "the previous frame's (glTF key times must increase); use .kmf",
                                      name, animation->frames_per_second, f, (double)f / animation->frames_per_second);
                goto done;
            }
        }
        size_t input = write_float_accessor(&writer, scratch, frame_count, 1, WRITE_TARGET_NONE, "SCALAR", true);
        /* Weights: key f selects target f-1. Written in rows to keep the
         * scratch small. */
        size_t target_count = frame_count - 1, offset = writer.bin.size;
        size_t bytes = frame_count * target_count * 4;
        if (!lk__buffer_reserve(&writer.bin, bytes)) goto nomem;
        memset(writer.bin.data + offset, 0, bytes);
        for (size_t f = 1; f < frame_count; f++)
            lk__store_f32le(writer.bin.data + offset + 4 * (f * target_count + (f - 1)), 1.0f);
        writer.bin.size += bytes;
        add_view_accessor(&writer, offset, bytes, WRITE_TARGET_NONE, COMPONENT_FLOAT, frame_count * target_count,
                          "SCALAR");
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
