/* SPDX-License-Identifier: MIT */
/* Quake II MD2 key-frame models (ident "IDP2", version 8), read and written.
 *
 * Layout (little-endian; offsets from the start of the file):
 *   header   17 int32: ident, version, skin_width, skin_height, frame_size,
 *            skin_count, vertex_count, st_count, triangle_count,
 *            glcmd_count, frame_count, then the offsets of skins, st,
 *            triangles, frames, glcmds and the end of the file.
 *   skins    64-byte names (ignored here)
 *   st       int16 s, t: texel coordinates, u = s / skin_width,
 *            v (down) = t / skin_height
 *   triangles  uint16 vertex[3], uint16 st[3]
 *   frames   frame_size bytes each: float scale[3], float translate[3],
 *            char name[16], then vertex_count x (uint8 x, y, z, normal index);
 *            position = byte * scale + translate
 *   glcmds   strips/fans for the GL renderer (ignored; the triangles say
 *            the same)
 *
 * MD2 triangles index positions and texture coordinates separately; lodkit
 * vertices carry both, so every distinct (position, st) pair used by a
 * triangle becomes one vertex, numbered in order of first use. The same
 * connectivity then serves every frame. Positions not used by any triangle
 * are dropped. Quake's triangles face clockwise (seen from the front);
 * lodkit's face counter-clockwise, so corners 1 and 2 are swapped on reading
 * and swapped back on writing. Coordinates stay in Quake's units and axes
 * (Z up). Normals (an index into Quake's table of 162 directions) are not
 * read; the writer stores index 0. MD2 has no frame rate: Quake II plays
 * frames at 10 per second, which is what frames_per_second is set to.
 *
 * Every count and offset is checked against the file size (64-bit
 * arithmetic) before anything is allocated; errors say "FILE: byte N". */
#include "anim_io.h"
#include "bytes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MD2_IDENT "IDP2"
#define MD2_VERSION 8
#define MD2_HEADER_SIZE 68u
#define MD2_SKIN_NAME_SIZE 64u
#define MD2_ST_SIZE 4u
#define MD2_TRIANGLE_SIZE 12u
#define MD2_FRAME_HEADER_SIZE 40u
#define MD2_FRAME_VERTEX_SIZE 4u
#define MD2_FRAME_RATE 10.0
/* MD2 indices are 16-bit (signed in Quake's own structs): stay below 2^15. */
#define MD2_MAX_INDEX 32767u

enum {
    H_IDENT,
    H_VERSION,
    H_SKIN_WIDTH,
    H_SKIN_HEIGHT,
    H_FRAME_SIZE,
    H_SKIN_COUNT,
    H_VERTEX_COUNT,
    H_ST_COUNT,
    H_TRIANGLE_COUNT,
    H_GLCMD_COUNT,
    H_FRAME_COUNT,
    H_OFS_SKINS,
    H_OFS_ST,
    H_OFS_TRIANGLES,
    H_OFS_FRAMES,
    H_OFS_GLCMDS,
    H_OFS_END,
    H_FIELD_COUNT
};
static const char *const header_names[H_FIELD_COUNT] = {
    "ident",        "version",          "skin width",     "skin height",   "frame size",  "skin count",
    "vertex count", "st count",         "triangle count", "glcmd count",   "frame count", "skins offset",
    "st offset",    "triangles offset", "frames offset",  "glcmds offset", "end offset"};

/* Checks that [offset, offset + count * element_size) lies inside the file. */
static lk_status check_block(const char *name, size_t file_size, int32_t offset, uint64_t count, uint64_t element_size,
                             const char *what, lk_error *error)
{
    uint64_t bytes = count * element_size; /* both < 2^31: no overflow */
    if (offset < 0 || (uint64_t)offset > file_size || bytes > file_size - (uint64_t)offset)
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "%s: byte %d: %s block (%llu x %llu bytes) runs past the end of the file (%zu bytes)", name,
                            (int)offset, what, (unsigned long long)count, (unsigned long long)element_size, file_size);
    return LK_OK;
}

/* Open-addressing map from (position index, st index) to a lodkit vertex. */
typedef struct pair_map {
    uint64_t *keys; /* key + 1; 0 = empty */
    uint32_t *values;
    size_t mask;
} pair_map;

static uint32_t pair_map_get_or_add(pair_map *map, uint64_t key, uint32_t next_value, bool *added)
{
    size_t slot = (size_t)lk__mix64(key) & map->mask;
    while (map->keys[slot]) {
        if (map->keys[slot] == key + 1) {
            *added = false;
            return map->values[slot];
        }
        slot = (slot + 1) & map->mask;
    }
    map->keys[slot] = key + 1;
    map->values[slot] = next_value;
    *added = true;
    return next_value;
}

lk_status lk__anim_read_md2(const unsigned char *data, size_t size, const lk__anim_context *ctx,
                            lk_animation *animation, lk_error *error)
{
    const char *name = ctx->name;
    lk_animation_init(animation);
    if (size < MD2_HEADER_SIZE)
        return lk_error_set(error, LK_ERR_TRUNCATED, "%s: byte %zu: file ends inside the %u-byte MD2 header", name,
                            size, MD2_HEADER_SIZE);
    if (memcmp(data, MD2_IDENT, 4) != 0)
        return lk_error_set(error, LK_ERR_PARSE, "%s: byte 0: not an MD2 file (ident is not \"IDP2\")", name);
    int32_t header[H_FIELD_COUNT];
    for (int i = 0; i < H_FIELD_COUNT; i++) header[i] = lk__load_i32le(data + 4 * i);
    if (header[H_VERSION] != MD2_VERSION)
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: byte 4: MD2 version %d (only version 8 exists)", name,
                            (int)header[H_VERSION]);
    for (int i = H_SKIN_WIDTH; i < H_FIELD_COUNT; i++)
        if (header[i] < 0)
            return lk_error_set(error, LK_ERR_PARSE, "%s: byte %d: negative %s (%d)", name, 4 * i, header_names[i],
                                (int)header[i]);
    size_t vertex_count = (size_t)header[H_VERTEX_COUNT], st_count = (size_t)header[H_ST_COUNT];
    size_t triangle_count = (size_t)header[H_TRIANGLE_COUNT], frame_count = (size_t)header[H_FRAME_COUNT];
    size_t frame_size = (size_t)header[H_FRAME_SIZE];
    if (frame_count == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: byte 40: the model has no frames", name);
    if (vertex_count == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: byte 24: the model has no vertices", name);
    if (frame_count > ctx->max_frames)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: byte 40: %zu frames is more than the limit of %zu", name,
                            frame_count, ctx->max_frames);
    if (frame_size < MD2_FRAME_HEADER_SIZE + (uint64_t)vertex_count * MD2_FRAME_VERTEX_SIZE)
        return lk_error_set(
            error, LK_ERR_PARSE, "%s: byte 16: frame size %zu is too small for %zu vertices (needs %llu)", name,
            frame_size, vertex_count,
            (unsigned long long)(MD2_FRAME_HEADER_SIZE + (uint64_t)vertex_count * MD2_FRAME_VERTEX_SIZE));
    lk_status status;
    if ((status = check_block(name, size, header[H_OFS_SKINS], (uint64_t)header[H_SKIN_COUNT], MD2_SKIN_NAME_SIZE,
                              "skins", error)) != LK_OK ||
        (status = check_block(name, size, header[H_OFS_ST], st_count, MD2_ST_SIZE, "texture coordinate", error)) !=
            LK_OK ||
        (status = check_block(name, size, header[H_OFS_TRIANGLES], triangle_count, MD2_TRIANGLE_SIZE, "triangle",
                              error)) != LK_OK ||
        (status = check_block(name, size, header[H_OFS_FRAMES], frame_count, frame_size, "frame", error)) != LK_OK ||
        (status = check_block(name, size, header[H_OFS_GLCMDS], (uint64_t)header[H_GLCMD_COUNT], 4, "GL command",
                              error)) != LK_OK)
        return status;
    /* The glcmds are not used, but a file shorter than its own end offset
     * has lost something: refuse it rather than guess. */
    if ((uint64_t)header[H_OFS_END] > size)
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "%s: byte 64: the header says the file has %d bytes but it has %zu", name,
                            (int)header[H_OFS_END], size);

    /* Texture coordinates only when they can be turned into [0,1] units. */
    bool has_texcoords = st_count > 0 && header[H_SKIN_WIDTH] > 0 && header[H_SKIN_HEIGHT] > 0;
    const unsigned char *triangles = data + header[H_OFS_TRIANGLES];
    for (size_t t = 0; t < triangle_count; t++) {
        const unsigned char *tri = triangles + t * MD2_TRIANGLE_SIZE;
        for (int k = 0; k < 3; k++) {
            uint16_t position = lk__load_u16le(tri + 2 * k), st = lk__load_u16le(tri + 6 + 2 * k);
            if (position >= vertex_count)
                return lk_error_set(error, LK_ERR_RANGE,
                                    "%s: byte %zu: triangle %zu uses vertex %u but the model has %zu", name,
                                    (size_t)header[H_OFS_TRIANGLES] + t * MD2_TRIANGLE_SIZE + 2 * (size_t)k, t,
                                    (unsigned)position, vertex_count);
            if (has_texcoords && st >= st_count)
                return lk_error_set(error, LK_ERR_RANGE,
                                    "%s: byte %zu: triangle %zu uses texture coordinate %u but the model has %zu", name,
                                    (size_t)header[H_OFS_TRIANGLES] + t * MD2_TRIANGLE_SIZE + 6 + 2 * (size_t)k, t,
                                    (unsigned)st, st_count);
        }
    }
    /* Budget: per vertex 3 floats per frame + 2 texcoords + the source map. */
    size_t corner_count = triangle_count * 3;
    size_t welded_bound = corner_count < vertex_count ? vertex_count : corner_count;
    if ((uint64_t)welded_bound * frame_count > lk__budget_room(ctx->budget) / (3 * sizeof(float)))
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: %zu frames of up to %zu vertices exceed the memory budget (%zu bytes)", name,
                            frame_count, welded_bound, ctx->budget->limit);

    /* Weld (position, st) pairs. The welding scratch is charged until it
     * is freed below. */
    size_t table_size = 16;
    while (table_size < 2 * corner_count) table_size *= 2;
    size_t scratch_bytes = table_size * (sizeof(uint64_t) + sizeof(uint32_t)) +
                           (welded_bound + 1) * 2 * sizeof(uint32_t) + (corner_count + 1) * sizeof(uint32_t);
    if (!lk__budget_charge(ctx->budget, scratch_bytes, 1))
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: welding %zu triangles needs more than the memory budget of %zu bytes", name,
                            triangle_count, ctx->budget->limit);
    pair_map map = {lk__calloc_array(table_size, sizeof(uint64_t)), lk__malloc_array(table_size, sizeof(uint32_t)),
                    table_size - 1};
    uint32_t *source_position = lk__malloc_array(welded_bound + 1, sizeof(uint32_t));
    uint32_t *source_st = lk__malloc_array(welded_bound + 1, sizeof(uint32_t));
    uint32_t *indices = lk__malloc_array(corner_count + 1, sizeof(uint32_t));
    if (!map.keys || !map.values || !source_position || !source_st || !indices) {
        status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for %zu triangles", name, triangle_count);
        goto done;
    }
    uint32_t welded_count = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const unsigned char *tri = triangles + t * MD2_TRIANGLE_SIZE;
        /* Corner order 0, 2, 1: clockwise -> counter-clockwise. */
        static const int corner_order[3] = {0, 2, 1};
        for (int k = 0; k < 3; k++) {
            int corner = corner_order[k];
            uint32_t position = lk__load_u16le(tri + 2 * corner);
            uint32_t st = has_texcoords ? lk__load_u16le(tri + 6 + 2 * corner) : 0;
            bool added;
            uint32_t vertex = pair_map_get_or_add(&map, (uint64_t)position << 16 | st, welded_count, &added);
            if (added) {
                source_position[welded_count] = position;
                source_st[welded_count] = st;
                welded_count++;
            }
            indices[3 * t + (size_t)k] = vertex;
        }
    }
    if (triangle_count == 0) {
        /* A point set: keep every position. */
        for (uint32_t v = 0; v < vertex_count; v++) source_position[v] = v, source_st[v] = 0;
        welded_count = (uint32_t)vertex_count;
        has_texcoords = false;
    }
    if (!lk__budget_charge_mesh(ctx->budget, welded_count, triangle_count, has_texcoords ? LK_ATTR_TEXCOORDS : 0)) {
        status = lk_error_set(error, LK_ERR_LIMIT,
                              "%s: %u vertices and %zu triangles need more than the memory budget "
                              "of %zu bytes",
                              name, welded_count, triangle_count, ctx->budget->limit);
        goto done;
    }
    status =
        lk_mesh_alloc(&animation->mesh, welded_count, triangle_count, has_texcoords ? LK_ATTR_TEXCOORDS : 0, error);
    if (status != LK_OK) goto done;
    if (corner_count) memcpy(animation->mesh.indices, indices, corner_count * sizeof(uint32_t));
    if (has_texcoords) {
        const unsigned char *st_block = data + header[H_OFS_ST];
        double inverse_width = 1.0 / header[H_SKIN_WIDTH], inverse_height = 1.0 / header[H_SKIN_HEIGHT];
        for (size_t v = 0; v < welded_count; v++) {
            const unsigned char *st = st_block + (size_t)source_st[v] * MD2_ST_SIZE;
            animation->mesh.texcoords[2 * v] = (float)(lk__load_i16le(st) * inverse_width);
            animation->mesh.texcoords[2 * v + 1] = (float)(1.0 - lk__load_i16le(st + 2) * inverse_height);
        }
    }
    status = lk__animation_alloc_frames(animation, frame_count, ctx->budget, name, error);
    if (status != LK_OK) goto done;
    animation->frames_per_second = MD2_FRAME_RATE;
    /* Names of at most 16 characters, with their pointers. */
    if (!lk__budget_charge(ctx->budget, frame_count, sizeof(char *) + 32)) {
        status = lk_error_set(error, LK_ERR_LIMIT, "%s: %zu frame names need more than the memory budget of %zu bytes",
                              name, frame_count, ctx->budget->limit);
        goto done;
    }
    animation->frame_names = lk__calloc_array(frame_count, sizeof(char *));
    if (!animation->frame_names) {
        status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for frame names", name);
        goto done;
    }
    for (size_t f = 0; f < frame_count; f++) {
        size_t frame_offset = (size_t)header[H_OFS_FRAMES] + f * frame_size;
        const unsigned char *frame = data + frame_offset;
        float scale[3], translate[3];
        for (int k = 0; k < 3; k++) {
            scale[k] = lk__load_f32le(frame + 4 * k);
            translate[k] = lk__load_f32le(frame + 12 + 4 * k);
            if (!isfinite(scale[k]) || !isfinite(translate[k])) {
                status = lk_error_set(error, LK_ERR_RANGE, "%s: byte %zu: frame %zu has a non-finite %s", name,
                                      frame_offset + (size_t)(isfinite(scale[k]) ? 12 + 4 * k : 4 * k), f,
                                      isfinite(scale[k]) ? "translation" : "scale");
                goto done;
            }
        }
        char frame_name[17];
        memcpy(frame_name, frame + 24, 16);
        frame_name[16] = '\0';
        /* Names are C strings padded with garbage after the NUL; keep
         * printable characters only so messages and KMF stay clean. */
        for (char *c = frame_name; *c; c++)
            if ((unsigned char)*c <= ' ' || (unsigned char)*c >= 127) *c = '_';
        animation->frame_names[f] = malloc(strlen(frame_name) + 1);
        if (!animation->frame_names[f]) {
            status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for frame names", name);
            goto done;
        }
        strcpy(animation->frame_names[f], frame_name);
        const unsigned char *packed = frame + MD2_FRAME_HEADER_SIZE;
        float *out = animation->frame_positions + f * (size_t)welded_count * 3;
        for (size_t v = 0; v < welded_count; v++) {
            const unsigned char *p = packed + (size_t)source_position[v] * MD2_FRAME_VERTEX_SIZE;
            for (int k = 0; k < 3; k++) {
                out[3 * v + (size_t)k] = p[k] * scale[k] + translate[k];
                if (!isfinite(out[3 * v + (size_t)k])) {
                    status = lk_error_set(error, LK_ERR_RANGE, "%s: byte %zu: frame %zu vertex %u overflows a float",
                                          name, frame_offset, f, source_position[v]);
                    goto done;
                }
            }
        }
    }
    memcpy(animation->mesh.positions, animation->frame_positions, (size_t)welded_count * 3 * sizeof(float));
    ctx->report->key_count = frame_count;
done:
    free(map.keys);
    free(map.values);
    free(source_position);
    free(source_st);
    free(indices);
    lk__budget_release(ctx->budget, scratch_bytes, 1);
    if (status != LK_OK) lk_animation_free(animation);
    return status;
}

lk_status lk__read_md2(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    lk_animation_report report;
    memset(&report, 0, sizeof report);
    lk__anim_context anim_ctx = {ctx->name, ctx->directory, ctx->budget, LK__ANIM_DEFAULT_MAX_FRAMES, 0, 0, 0, &report};
    /* Only frame 0 is needed, but reading all frames keeps one code path;
     * MD2 files are small (Quake caps them at 512 frames of 2048 vertices). */
    lk_animation animation;
    lk_status status = lk__anim_read_md2((const unsigned char *)data, size, &anim_ctx, &animation, error);
    if (status != LK_OK) return status;
    return lk__animation_take_frame0(&animation, mesh, error);
}

/* ---- writer ------------------------------------------------------------- */

/* The skin size that makes every texture coordinate a whole texel (so that a
 * model read from MD2 is written back with its own st values), or 256. */
static int32_t pick_skin_size(const float *texcoords, size_t vertex_count, int component)
{
    for (int32_t size = 1; size <= 4096; size++) {
        bool whole = true;
        for (size_t v = 0; v < vertex_count && whole; v++) {
            double value = texcoords[2 * v + (size_t)component];
            double texel = (component ? 1.0 - value : value) * size;
            double rounded = floor(texel + 0.5);
            if (fabs(rounded) > 32767 || (float)(component ? 1.0 - rounded / size : rounded / size) != (float)value)
                whole = false;
        }
        if (whole) return size;
    }
    return 256;
}

lk_status lk__anim_write_md2(FILE *file, const lk_animation *animation, const char *name, lk_error *error)
{
    const lk_mesh *mesh = &animation->mesh;
    size_t vertex_count = mesh->vertex_count, triangle_count = mesh->triangle_count;
    if (vertex_count == 0 || vertex_count > MD2_MAX_INDEX)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: MD2 holds 1 to %u vertices, the animation has %zu", name,
                            MD2_MAX_INDEX, vertex_count);
    if (triangle_count > INT32_MAX / MD2_TRIANGLE_SIZE || animation->frame_count > 0x7FFFFF)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: too many triangles or frames for MD2", name);
    bool has_texcoords = mesh->texcoords != NULL;
    int32_t skin_width = has_texcoords ? pick_skin_size(mesh->texcoords, vertex_count, 0) : 0;
    int32_t skin_height = has_texcoords ? pick_skin_size(mesh->texcoords, vertex_count, 1) : 0;
    size_t st_count = has_texcoords ? vertex_count : 0;
    size_t frame_size = MD2_FRAME_HEADER_SIZE + vertex_count * MD2_FRAME_VERTEX_SIZE;
    uint64_t ofs_st = MD2_HEADER_SIZE;
    uint64_t ofs_triangles = ofs_st + st_count * MD2_ST_SIZE;
    uint64_t ofs_frames = ofs_triangles + (uint64_t)triangle_count * MD2_TRIANGLE_SIZE;
    uint64_t ofs_end = ofs_frames + (uint64_t)animation->frame_count * frame_size;
    if (ofs_end > INT32_MAX) return lk_error_set(error, LK_ERR_LIMIT, "%s: the MD2 file would exceed 2 GiB", name);
    unsigned char header[MD2_HEADER_SIZE];
    memcpy(header, MD2_IDENT, 4);
    int32_t fields[H_FIELD_COUNT] = {0};
    fields[H_VERSION] = MD2_VERSION;
    fields[H_SKIN_WIDTH] = skin_width;
    fields[H_SKIN_HEIGHT] = skin_height;
    fields[H_FRAME_SIZE] = (int32_t)frame_size;
    fields[H_VERTEX_COUNT] = (int32_t)vertex_count;
    fields[H_ST_COUNT] = (int32_t)st_count;
    fields[H_TRIANGLE_COUNT] = (int32_t)triangle_count;
    fields[H_FRAME_COUNT] = (int32_t)animation->frame_count;
    fields[H_OFS_SKINS] = (int32_t)ofs_st;
    fields[H_OFS_ST] = (int32_t)ofs_st;
    fields[H_OFS_TRIANGLES] = (int32_t)ofs_triangles;
    fields[H_OFS_FRAMES] = (int32_t)ofs_frames;
    fields[H_OFS_GLCMDS] = (int32_t)ofs_end;
    fields[H_OFS_END] = (int32_t)ofs_end;
    for (int i = 1; i < H_FIELD_COUNT; i++) lk__store_i32le(header + 4 * i, fields[i]);
    bool ok = fwrite(header, 1, sizeof header, file) == sizeof header;
    for (size_t v = 0; ok && v < st_count; v++) {
        unsigned char st[MD2_ST_SIZE];
        double s = floor(mesh->texcoords[2 * v] * skin_width + 0.5);
        double t = floor((1.0 - mesh->texcoords[2 * v + 1]) * skin_height + 0.5);
        s = s < -32768 ? -32768 : s > 32767 ? 32767 : s;
        t = t < -32768 ? -32768 : t > 32767 ? 32767 : t;
        lk__store_u16le(st, (uint16_t)(int16_t)s);
        lk__store_u16le(st + 2, (uint16_t)(int16_t)t);
        ok = fwrite(st, 1, sizeof st, file) == sizeof st;
    }
    for (size_t t = 0; ok && t < triangle_count; t++) {
        unsigned char tri[MD2_TRIANGLE_SIZE];
        static const int corner_order[3] = {0, 2, 1}; /* back to clockwise */
        for (int k = 0; k < 3; k++) {
            uint32_t vertex = mesh->indices[3 * t + (size_t)corner_order[k]];
            lk__store_u16le(tri + 2 * k, (uint16_t)vertex);
            lk__store_u16le(tri + 6 + 2 * k, (uint16_t)(has_texcoords ? vertex : 0));
        }
        ok = fwrite(tri, 1, sizeof tri, file) == sizeof tri;
    }
    unsigned char *frame = ok ? lk__malloc_array(frame_size, 1) : NULL;
    if (ok && !frame) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
    for (size_t f = 0; ok && f < animation->frame_count; f++) {
        const float *positions = animation->frame_positions + f * vertex_count * 3;
        float lo[3], hi[3];
        for (int k = 0; k < 3; k++) lo[k] = hi[k] = positions[k];
        for (size_t v = 1; v < vertex_count; v++)
            for (int k = 0; k < 3; k++) {
                float value = positions[3 * v + (size_t)k];
                if (value < lo[k]) lo[k] = value;
                if (value > hi[k]) hi[k] = value;
            }
        float scale[3];
        for (int k = 0; k < 3; k++) {
            scale[k] = (float)(((double)hi[k] - lo[k]) / 255.0);
            if (!isfinite(scale[k])) {
                free(frame);
                return lk_error_set(error, LK_ERR_RANGE, "%s: frame %zu spans more than a float can hold", name, f);
            }
            lk__store_f32le(frame + 4 * k, scale[k]);
            lk__store_f32le(frame + 12 + 4 * k, lo[k]);
        }
        memset(frame + 24, 0, 16);
        if (animation->frame_names && animation->frame_names[f])
            strncpy((char *)frame + 24, animation->frame_names[f], 15);
        else
            snprintf((char *)frame + 24, 16, "frame%u", (unsigned)f);
        for (size_t v = 0; v < vertex_count; v++) {
            unsigned char *packed = frame + MD2_FRAME_HEADER_SIZE + v * MD2_FRAME_VERTEX_SIZE;
            for (int k = 0; k < 3; k++) {
                double q = scale[k] > 0 ? floor((positions[3 * v + (size_t)k] - lo[k]) / scale[k] + 0.5) : 0;
                packed[k] = (unsigned char)(q < 0 ? 0 : q > 255 ? 255 : q);
            }
            packed[3] = 0;
        }
        ok = fwrite(frame, 1, frame_size, file) == frame_size;
    }
    free(frame);
    if (!ok) return lk_error_set(error, LK_ERR_IO, "%s: write error", name);
    return LK_OK;
}
