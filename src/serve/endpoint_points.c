/* SPDX-License-Identifier: MIT */
/* /api/points/PATH: a point set (or a mesh's vertices) as an LKMB buffer
 * with normals, radii and the clip lines of border splats, subsampled to
 * at most max_points. */
#include "serve_shared.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* ---- point sets ---------------------------------------------------------------- */

/* Keeps `keep` of the points, evenly spread over the file order
 * (deterministic); drops the triangles. */
static lk_status subsample_points(lk_mesh *points, size_t keep, lk_error *error)
{
    size_t count = points->vertex_count;
    unsigned flags = (points->normals ? LK_ATTR_NORMALS : 0u) | (points->colors ? LK_ATTR_COLORS : 0u) |
                     (points->radii ? LK_ATTR_RADII : 0u);
    lk_mesh out;
    lk_status status = lk_mesh_alloc(&out, keep, 0, flags, error);
    if (status != LK_OK) return status;
    for (size_t k = 0; k < keep; k++) {
        size_t i = (size_t)((unsigned long long)k * count / keep);
        memcpy(out.positions + 3 * k, points->positions + 3 * i, 3 * sizeof(float));
        if (out.normals) memcpy(out.normals + 3 * k, points->normals + 3 * i, 3 * sizeof(float));
        if (out.colors) memcpy(out.colors + 4 * k, points->colors + 4 * i, 4 * sizeof(float));
        if (out.radii) out.radii[k] = points->radii[i];
    }
    lk_mesh_free(points);
    *points = out;
    return LK_OK;
}

static lk_status point_buffer(lk_server *server, const opened_file *file, size_t max_points, blob **out,
                              lk_error *error)
{
    lk_mesh points;
    lk_status status = lk__serve_read_mesh_opened(server, file, &points, error);
    if (status != LK_OK) return status;
    if (points.vertex_count == 0) {
        lk_mesh_free(&points);
        return lk_error_set(error, LK_ERR_PARSE, "no points");
    }
    /* Points are the vertices; triangles (if any) are not part of a point set. */
    free(points.indices);
    points.indices = NULL;
    points.triangle_count = 0;
    free(points.texcoords);
    points.texcoords = NULL;
    if (points.vertex_count > max_points) status = subsample_points(&points, max_points, error);
    if (status == LK_OK && !points.normals && points.vertex_count >= 3)
        status = lk_points_estimate_normals(&points, 12, error);
    if (status == LK_OK && !points.radii && points.vertex_count >= 2)
        status = lk_points_estimate_radii(&points, 8, 1.0, error);
    /* clip lines as the C renderer takes them (src/gl/splat.c, 16 neighbours) */
    float *clips = NULL;
    if (status == LK_OK && points.normals && points.radii && points.vertex_count >= 2) {
        clips = lk__malloc_array(points.vertex_count, 4 * sizeof *clips);
        status = clips ? lk_points_estimate_clips(&points, 16, clips, error)
                       : lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu clip lines", points.vertex_count);
    }
    if (status == LK_OK) {
        *out = lk__serve_lkmb_encode(&points, true, true, true, clips);
        if (!*out) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the point buffer");
    }
    free(clips);
    lk_mesh_free(&points);
    return status;
}

enum MHD_Result lk__serve_points(lk_server *server, struct MHD_Connection *connection, request *r,
                                 const char *relative_raw)
{
    size_t max_points = server->options.max_points;
    const char *max_text = MHD_lookup_connection_value(connection, MHD_GET_ARGUMENT_KIND, "max");
    if (max_text) {
        char *end;
        errno = 0;
        unsigned long long value = strtoull(max_text, &end, 10);
        if (errno || end == max_text || *end || value == 0 || max_text[0] == '-' || value > LK_MAX_ELEMENTS)
            return lk__serve_respond_error(connection, r, 400, "max: '%s' is not a positive count", max_text);
        max_points = (size_t)value;
    }
    unsigned status = 0;
    char *relative = lk__serve_clean_relative_path(relative_raw, &status);
    if (!relative)
        return lk__serve_respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");
    opened_file file;
    lk_error why = {0};
    status = lk__serve_open_in_root(server->root, server->root_length, relative, &file, &why);
    if (status) {
        enum MHD_Result result = lk__serve_respond_error(connection, r, status, "%s", why.message);
        free(relative);
        return result;
    }
    char key[PATH_MAX + 160];
    char version[SERVE_VERSION_CHARS];
    lk__serve_version_of(&file.st, version);
    snprintf(key, sizeof key, "points:%s|%s|%zu", file.real, version, max_points);
    blob *buffer = lk__serve_cache_get(&server->cache, key);
    lk_error error = {0};
    if (!buffer) {
        lk_status built = point_buffer(server, &file, max_points, &buffer, &error);
        if (built != LK_OK) {
            lk__serve_name_in_message(&error, file.name);
            enum MHD_Result result =
                lk__serve_respond_error(connection, r, lk__serve_http_status_of(built), "%s", error.message);
            lk__serve_opened_close(&file);
            free(relative);
            return result;
        }
        lk__serve_cache_put(&server->cache, key, buffer);
    }
    lk__serve_opened_close(&file);
    free(relative);
    source s;
    lk__serve_source_from_blob(&s, buffer, SERVE_MIME_LKMB, false, key);
    return lk__serve_send_source(server, connection, r, &s);
}
