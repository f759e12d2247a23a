/* SPDX-License-Identifier: MIT */
/* /api/terrain/PATH: the CLOD terrain mesh of a grid for one view, and
 * its description (/info); the terrains of the most recent grids stay in
 * a few slots, within a memory budget. */
#include "serve_shared.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- terrains ---------------------------------------------------------------------- */

void lk__serve_terrain_slot_free(terrain_slot *slot)
{
    if (!slot) return;
    lk_terrain_free(slot->terrain);
    pthread_mutex_destroy(&slot->lock);
    free(slot->key);
    free(slot);
}

static void terrain_release(lk_server *server, terrain_slot *slot)
{
    pthread_mutex_lock(&server->terrain_lock);
    slot->users--;
    pthread_mutex_unlock(&server->terrain_lock);
}

/* The cached terrain for a file and options, creating it when needed.
 * Returns 0 or an HTTP status (503 beyond the memory budget) with error set. */
static unsigned terrain_acquire(lk_server *server, const opened_file *file, const lk_terrain_options *options,
                                terrain_slot **out, lk_error *error)
{
    char key[PATH_MAX + 240];
    char version[SERVE_VERSION_CHARS];
    lk__serve_version_of(&file->st, version);
    snprintf(key, sizeof key, "%s|%s|%g|%g|%d", file->real, version, options->resolution, options->error_scale,
             options->morph);
    pthread_mutex_lock(&server->terrain_lock);
    for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) {
        terrain_slot *slot = server->terrains[i];
        if (slot && strcmp(slot->key, key) == 0) {
            slot->users++;
            slot->last_used = ++server->terrain_clock;
            pthread_mutex_unlock(&server->terrain_lock);
            *out = slot;
            return 0;
        }
    }
    pthread_mutex_unlock(&server->terrain_lock);

    /* Build outside the lock: reading and resampling a grid takes a while. */
    lk_heightfield field, square;
    memset(&square, 0, sizeof square);
    lk_status status = lk__serve_read_heightfield(server, file, &field, error);
    if (status != LK_OK) return lk__serve_http_status_of(status);
    size_t largest = field.width > field.height ? field.width : field.height;
    size_t side = 2;
    while (side < largest) side = 2 * (side - 1) + 1;
    /* about 22 bytes per sample (lk_terrain_create), plus the copies made here */
    double estimate = 24.0 * (double)side * (double)side;
    if (estimate > (double)server->options.terrain_bytes) {
        lk_heightfield_free(&field);
        lk_error_set(error, LK_ERR_LIMIT, "a %zux%zu terrain needs about %.0f MiB, over the %.0f MiB budget", side,
                     side, estimate / 1048576.0, (double)server->options.terrain_bytes / 1048576.0);
        return 503;
    }
    const lk_heightfield *input = &field;
    if (field.width != side || field.height != side) {
        status = lk_heightfield_resample(&field, side, &square, error);
        input = &square;
    }
    lk_terrain *terrain = NULL;
    if (status == LK_OK) status = lk_terrain_create(input, options, &terrain, error);
    lk_heightfield_free(&field);
    lk_heightfield_free(&square);
    if (status != LK_OK) return lk__serve_http_status_of(status);
    terrain_slot *slot = calloc(1, sizeof *slot);
    if (slot) slot->key = strdup(key);
    if (!slot || !slot->key) {
        free(slot);
        lk_terrain_free(terrain);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        return 503;
    }
    pthread_mutex_init(&slot->lock, NULL);
    slot->terrain = terrain;
    lk_terrain_get_info(terrain, &slot->info);
    slot->memory = slot->info.memory_bytes;

    pthread_mutex_lock(&server->terrain_lock);
    for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) { /* built meanwhile by another request? */
        terrain_slot *other = server->terrains[i];
        if (other && strcmp(other->key, key) == 0) {
            other->users++;
            other->last_used = ++server->terrain_clock;
            pthread_mutex_unlock(&server->terrain_lock);
            lk__serve_terrain_slot_free(slot);
            *out = other;
            return 0;
        }
    }
    /* Evict idle terrains, least recently used first, until it fits. */
    for (;;) {
        int free_index = -1, oldest = -1;
        for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) {
            terrain_slot *s = server->terrains[i];
            if (!s)
                free_index = free_index < 0 ? i : free_index;
            else if (s->users == 0 && (oldest < 0 || s->last_used < server->terrains[oldest]->last_used))
                oldest = i;
        }
        bool fits = server->terrain_memory + slot->memory <= server->options.terrain_bytes;
        if (fits && free_index >= 0) {
            slot->users = 1;
            slot->last_used = ++server->terrain_clock;
            server->terrains[free_index] = slot;
            server->terrain_memory += slot->memory;
            pthread_mutex_unlock(&server->terrain_lock);
            *out = slot;
            return 0;
        }
        if (oldest < 0) break;
        server->terrain_memory -= server->terrains[oldest]->memory;
        lk__serve_terrain_slot_free(server->terrains[oldest]);
        server->terrains[oldest] = NULL;
    }
    pthread_mutex_unlock(&server->terrain_lock);
    lk__serve_terrain_slot_free(slot);
    lk_error_set(error, LK_ERR_LIMIT, "every terrain slot is busy or the %.0f MiB terrain budget is used",
                 (double)server->options.terrain_bytes / 1048576.0);
    return 503;
}

static bool query_number(struct MHD_Connection *connection, const char *name, double fallback, double *value)
{
    const char *text = MHD_lookup_connection_value(connection, MHD_GET_ARGUMENT_KIND, name);
    if (!text) {
        *value = fallback;
        return true;
    }
    char *end;
    errno = 0;
    *value = strtod(text, &end);
    return !errno && end != text && *end == '\0' && isfinite(*value);
}

static bool query_vector(struct MHD_Connection *connection, const char *name, double out[3])
{
    const char *text = MHD_lookup_connection_value(connection, MHD_GET_ARGUMENT_KIND, name);
    if (!text) return false;
    const char *p = text;
    for (int k = 0; k < 3; k++) {
        char *end;
        errno = 0;
        out[k] = strtod(p, &end);
        if (errno || end == p || !isfinite(out[k])) return false;
        if (k < 2 && *end != ',') return false;
        p = end + 1;
        if (k == 2 && *end) return false;
    }
    return true;
}

enum MHD_Result lk__serve_terrain(lk_server *server, struct MHD_Connection *connection, request *r,
                                  const char *relative_raw)
{
    size_t length = strlen(relative_raw);
    bool info_only = length > 5 && strcmp(relative_raw + length - 5, "/info") == 0;
    char *trimmed = strdup(relative_raw);
    if (!trimmed) return MHD_NO;
    if (info_only) trimmed[length - 5] = '\0';
    unsigned status = 0;
    char *relative = lk__serve_clean_relative_path(trimmed, &status);
    free(trimmed);
    if (!relative)
        return lk__serve_respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");

    lk_terrain_options options;
    lk_terrain_options_default(&options);
    lk_terrain_view view;
    memset(&view, 0, sizeof view);
    double morph = 1;
    enum MHD_Result result;
    if (!query_number(connection, "c", options.error_scale, &options.error_scale) || !(options.error_scale > 0) ||
        !query_number(connection, "C", options.resolution, &options.resolution) || !(options.resolution > 0) ||
        !query_number(connection, "morph", 1, &morph) || (morph != 0 && morph != 1)) {
        free(relative);
        return lk__serve_respond_error(connection, r, 400, "c and C must be positive numbers, morph 0 or 1");
    }
    options.morph = morph != 0;
    if (!info_only) {
        if (!query_vector(connection, "eye", view.eye) || !query_vector(connection, "target", view.target) ||
            !query_number(connection, "fov", 60, &view.fov_y) || !(view.fov_y > 0 && view.fov_y < 180) ||
            !query_number(connection, "aspect", 1.5, &view.aspect) || !(view.aspect > 0) ||
            !query_number(connection, "height", 720, &view.viewport_height) || !(view.viewport_height > 0) ||
            (view.eye[0] == view.target[0] && view.eye[1] == view.target[1] && view.eye[2] == view.target[2])) {
            free(relative);
            return lk__serve_respond_error(connection, r, 400,
                                           "need eye=x,y,z and target=x,y,z (different points); fov in (0,180), "
                                           "aspect > 0, height > 0");
        }
    }
    opened_file file;
    lk_error why = {0};
    status = lk__serve_open_in_root(server->root, server->root_length, relative, &file, &why);
    if (status) {
        result = lk__serve_respond_error(connection, r, status, "%s", why.message);
        free(relative);
        return result;
    }
    lk_error error = {0};
    terrain_slot *slot = NULL;
    status = terrain_acquire(server, &file, &options, &slot, &error);
    if (status) lk__serve_name_in_message(&error, file.name);
    lk__serve_opened_close(&file);
    if (status) {
        result = lk__serve_respond_error(connection, r, status, "%s", error.message);
        free(relative);
        return result;
    }
    free(relative);
    const lk_terrain_info *info = &slot->info;
    if (info_only) {
        double extent_x = (double)(info->size - 1) * info->spacing_x,
               extent_y = (double)(info->size - 1) * info->spacing_y;
        double relief = info->max_height - info->min_height;
        cJSON *root = cJSON_CreateObject();
        cJSON_AddNumberToObject(root, "size", (double)info->size);
        cJSON_AddNumberToObject(root, "levels", info->levels);
        cJSON_AddNumberToObject(root, "spacing_x", info->spacing_x);
        cJSON_AddNumberToObject(root, "spacing_y", info->spacing_y);
        cJSON_AddNumberToObject(root, "origin_x", info->origin_x);
        cJSON_AddNumberToObject(root, "origin_y", info->origin_y);
        cJSON_AddNumberToObject(root, "min_height", info->min_height);
        cJSON_AddNumberToObject(root, "max_height", info->max_height);
        double center[3] = {info->origin_x + 0.5 * extent_x, info->origin_y + 0.5 * extent_y,
                            0.5 * (info->min_height + info->max_height)};
        cJSON_AddItemToObject(root, "center", cJSON_CreateDoubleArray(center, 3));
        cJSON_AddNumberToObject(root, "radius",
                                0.5 * sqrt(extent_x * extent_x + extent_y * extent_y + relief * relief));
        char *text = cJSON_PrintUnformatted(root);
        cJSON_Delete(root);
        terrain_release(server, slot);
        return text ? lk__serve_respond_json_text(connection, r, 200, text) : MHD_NO;
    }

    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_terrain_stats stats;
    lk_terrain_crack_stats cracks;
    memset(&cracks, 0, sizeof cracks);
    pthread_mutex_lock(&slot->lock);
    lk_status built = lk_terrain_update(slot->terrain, &view, &mesh, &stats, &error);
    if (built == LK_OK) built = lk_terrain_color_mesh(slot->terrain, &mesh, &error);
    if (built == LK_OK) built = lk_terrain_count_cracks(slot->terrain, &mesh, 0, &cracks, &error);
    pthread_mutex_unlock(&slot->lock);
    terrain_release(server, slot);
    blob *buffer = NULL;
    if (built == LK_OK) {
        buffer = lk__serve_lkmb_encode(&mesh, false, true, false, NULL);
        if (!buffer) built = lk_error_set(&error, LK_ERR_NOMEM, "out of memory for the terrain mesh");
    }
    lk_mesh_free(&mesh);
    if (built != LK_OK)
        return lk__serve_respond_error(connection, r, lk__serve_http_status_of(built), "terrain: %s", error.message);
    char header[256];
    snprintf(header, sizeof header, "{\"triangles\":%zu,\"vertices\":%zu,\"cracks\":%zu,\"max_level\":%u,\"ms\":%.3f}",
             stats.triangles, stats.vertices, cracks.cracks, stats.max_level, stats.milliseconds);
    struct MHD_Response *response = MHD_create_response_from_buffer_with_free_callback_cls(
        buffer->size, buffer->data, lk__serve_blob_release, buffer);
    if (!response) {
        lk__serve_blob_release(buffer);
        return MHD_NO;
    }
    MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, SERVE_MIME_LKMB);
    MHD_add_response_header(response, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
    MHD_add_response_header(response, "X-Lodkit-Terrain", header);
    MHD_add_response_header(response, "Access-Control-Expose-Headers", "X-Lodkit-Terrain");
    return lk__serve_queue(connection, r, 200, response, buffer->size);
}
