/* SPDX-License-Identifier: MIT */
/* What the endpoints read and send: meshes and grids read from an opened,
 * checked file, messages that name the file relative to the root, and
 * LKMB buffers (a mesh or point set as little-endian arrays, described in
 * docs/server.md). */
#include "bytes.h"
#include "serve_shared.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- reading what the endpoints serve ------------------------------------ */

/* What the server does with a file follows the library's format table
 * (lk_format_info_from_path), so a format added there is listed and served
 * without a list of its own here. */

bool lk__serve_reads_mesh(const char *name)
{
    const lk_format_info *info = lk_format_info_from_path(name);
    return info && (info->read & LK_IO_MESH);
}

bool lk__serve_reads_grid(const char *name)
{
    const lk_format_info *info = lk_format_info_from_path(name);
    return info && (info->read & LK_IO_GRID);
}

bool lk__serve_is_stream(const char *name)
{
    const lk_format_info *info = lk_format_info_from_path(name);
    return info && info->kind == LK_FORMAT_KIND_STREAM;
}

bool lk__serve_builds_streams_from(const lk_format_info *info)
{
    /* A point set has no triangles to build a progressive mesh from (a
     * PLY may hold either: its read says which). */
    return (info->read & LK_IO_MESH) && info->kind != LK_FORMAT_KIND_POINTS;
}

/* Reads a mesh from an opened file: the bytes of that descriptor, named by
 * the path relative to the root; a glTF's external buffers are opened
 * below the file's own (resolved) directory without following links. */
lk_status lk__serve_read_mesh_opened(lk_server *server, const opened_file *file, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    lk_read_options read_options = {.max_bytes = server->options.max_memory};
    unsigned char *data = NULL;
    size_t size = 0;
    lk_status status = lk__serve_read_opened(file, server->options.max_file_bytes, &data, &size, error);
    if (status != LK_OK) return status;
    char *directory = strdup(file->real);
    if (!directory) {
        free(data);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    char *slash = strrchr(directory, '/');
    if (slash == directory)
        slash[1] = '\0'; /* a file right under "/" */
    else if (slash)
        *slash = '\0';
    status = lk__mesh_read_buffer(data, size, file->name, directory, &read_options, mesh, error);
    free(directory);
    free(data);
    return status;
}

/* Makes an error message start with the file's name (relative to the root). */
void lk__serve_name_in_message(lk_error *error, const char *name)
{
    size_t length = strlen(name);
    if (strncmp(error->message, name, length) == 0 && error->message[length] == ':') return;
    char message[sizeof error->message];
    snprintf(message, sizeof message, "%.200s: %.300s", name, error->message);
    memcpy(error->message, message, sizeof message);
}

/* A grid from the opened, checked descriptor (GDAL formats: GDAL opens the
 * path, which must still be that file), named relative to the root. */
lk_status lk__serve_read_heightfield(lk_server *server, const opened_file *file, lk_heightfield *field, lk_error *error)
{
    memset(field, 0, sizeof *field);
    lk_dem_options dem_options;
    lk_dem_options_default(&dem_options);
    size_t budget_samples = server->options.max_memory / LK_DEM_BYTES_PER_SAMPLE;
    if (budget_samples < dem_options.max_samples) dem_options.max_samples = budget_samples ? budget_samples : 1;
    return lk__dem_read_opened(file->fd, &file->st, file->real, file->name, &dem_options, field, error);
}

/* ---- LKMB buffers ------------------------------------------------------------ */

/* Positions, then normals / colours / radii / clip lines when present,
 * then indices. clips: NULL, or 4 * vertex_count floats of
 * lk_points_estimate_clips (needs radii: its offsets go out in radii). */
blob *lk__serve_lkmb_encode(const lk_mesh *mesh, bool with_normals, bool with_colors, bool with_radii,
                            const float *clips)
{
    size_t v = mesh->vertex_count, t = mesh->triangle_count;
    uint32_t flags = (with_normals && mesh->normals ? 1u : 0u) | (with_colors && mesh->colors ? 2u : 0u) |
                     (with_radii && mesh->radii ? 4u : 0u);
    if (clips && (flags & 4)) flags |= 8u;
    size_t size = 24 + 12 * v + ((flags & 1) ? 12 * v : 0) + ((flags & 2) ? 4 * v : 0) + ((flags & 4) ? 4 * v : 0) +
                  ((flags & 8) ? 4 * v : 0) + 12 * t;
    unsigned char *data = malloc(size);
    if (!data) return NULL;
    unsigned char *p = data;
    memcpy(p, "LKMB", 4);
    lk__store_u32le(p + 4, 1);
    lk__store_u32le(p + 8, (uint32_t)v);
    lk__store_u32le(p + 12, (uint32_t)t);
    lk__store_u32le(p + 16, flags);
    lk__store_u32le(p + 20, 0);
    p += 24;
    for (size_t i = 0; i < 3 * v; i++, p += 4) lk__store_f32le(p, mesh->positions[i]);
    if (flags & 1)
        for (size_t i = 0; i < 3 * v; i++, p += 4) lk__store_f32le(p, mesh->normals[i]);
    if (flags & 2)
        for (size_t i = 0; i < 4 * v; i++) {
            float c = mesh->colors[i];
            c = c != c ? 0.0f : c < 0 ? 0.0f : c > 1 ? 1.0f : c;
            *p++ = (unsigned char)lrintf(c * 255.0f);
        }
    if (flags & 4)
        for (size_t i = 0; i < v; i++, p += 4) lk__store_f32le(p, mesh->radii[i]);
    if (flags & 8)
        for (size_t i = 0; i < v; i++, p += 4) {
            /* direction as three signed bytes / 127, offset in radii (a cut
             * past one radius cuts nothing of the disc) as one / 127 */
            const float *clip = clips + 4 * i;
            for (int k = 0; k < 3; k++) {
                float c = clip[k] != clip[k] ? 0.0f : clip[k] < -1 ? -1.0f : clip[k] > 1 ? 1.0f : clip[k];
                p[k] = (unsigned char)(signed char)lrintf(c * 127.0f);
            }
            float offset = mesh->radii[i] > 0 ? clip[3] / mesh->radii[i] : 0.0f;
            offset = offset != offset ? 0.0f : offset < 0 ? 0.0f : offset > 1 ? 1.0f : offset;
            p[3] = (unsigned char)lrintf(offset * 127.0f);
        }
    for (size_t i = 0; i < 3 * t; i++, p += 4) lk__store_u32le(p, mesh->indices[i]);
    blob *b = lk__serve_blob_wrap(data, size);
    if (!b) free(data);
    return b;
}
