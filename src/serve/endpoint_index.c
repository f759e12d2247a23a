/* SPDX-License-Identifier: MIT */
/* /api/index.json: the models of the served folder (streams, meshes,
 * point sets, terrains), each described once per version of its file. */
#define _XOPEN_SOURCE 700 /* realpath */
#include "serve_shared.h"

#include <dirent.h>
#include <stdlib.h>
#include <string.h>

#define SERVE_MAX_INDEX_FILES 10000
#define SERVE_MAX_INDEX_DEPTH 8

/* ---- the index ------------------------------------------------------------------------ */

typedef struct scanned_file {
    char *relative;
    long long size;
    char version[SERVE_VERSION_CHARS];
} scanned_file;

typedef struct scan_state {
    scanned_file *files;
    size_t count, capacity;
} scan_state;

/* A point octree is listed by its index, which `lodkit octree` always names
 * octree.json (docs/formats.md, "Point octree"); the viewer fetches its
 * nodes from the data file by Range requests on /m/. */
static bool is_octree_index(const char *name)
{
    const char *slash = strrchr(name, '/');
    return strcmp(slash ? slash + 1 : name, "octree.json") == 0;
}

static bool is_model_name(const char *name)
{
    return is_octree_index(name) || lk__serve_reads_mesh(name) || lk__serve_reads_grid(name) ||
           lk__serve_is_stream(name);
}

static void scan_directory(lk_server *server, const char *relative, unsigned depth, scan_state *state)
{
    size_t length = server->root_length + strlen(relative) + 2;
    char *path = malloc(length);
    if (!path) return;
    snprintf(path, length, "%s%s%s", server->root, relative[0] ? "/" : "", relative);
    DIR *directory = opendir(path);
    free(path);
    if (!directory) return;
    struct dirent *entry;
    while ((entry = readdir(directory)) && state->count < SERVE_MAX_INDEX_FILES) {
        if (entry->d_name[0] == '.') continue;
        size_t child_length = strlen(relative) + strlen(entry->d_name) + 2;
        char *child = malloc(child_length);
        if (!child) break;
        snprintf(child, child_length, "%s%s%s", relative, relative[0] ? "/" : "", entry->d_name);
        struct stat st;
        size_t full_length = server->root_length + child_length + 1;
        char *full = malloc(full_length);
        bool keep = false;
        if (full) {
            snprintf(full, full_length, "%s/%s", server->root, child);
            struct stat link_st;
            if (lstat(full, &link_st) == 0 && stat(full, &st) == 0) {
                if (S_ISLNK(link_st.st_mode)) { /* a link must stay inside the root */
                    char *real = realpath(full, NULL);
                    bool inside = real && lk__serve_inside_root(real, server->root, server->root_length);
                    free(real);
                    if (!inside) st.st_mode = 0;
                }
                if (S_ISDIR(st.st_mode) && depth < SERVE_MAX_INDEX_DEPTH)
                    scan_directory(server, child, depth + 1, state);
                else if (S_ISREG(st.st_mode) && is_model_name(entry->d_name))
                    keep = true;
            }
            free(full);
        }
        if (keep && state->count == state->capacity) {
            size_t capacity = state->capacity ? 2 * state->capacity : 64;
            scanned_file *grown = lk__realloc_array(state->files, capacity, sizeof *grown);
            if (!grown)
                keep = false;
            else {
                state->files = grown;
                state->capacity = capacity;
            }
        }
        if (keep) {
            scanned_file *scanned = &state->files[state->count++];
            scanned->relative = child;
            scanned->size = (long long)st.st_size;
            lk__serve_version_of(&st, scanned->version);
        } else
            free(child);
    }
    closedir(directory);
}

static int compare_scanned(const void *a, const void *b)
{
    return strcmp(((const scanned_file *)a)->relative, ((const scanned_file *)b)->relative);
}

/* The index entry of one file (without "stream"), parsing it. */
static cJSON *describe_file(lk_server *server, const scanned_file *scanned)
{
    cJSON *entry = cJSON_CreateObject();
    if (!entry) return NULL;
    const char *slash = strrchr(scanned->relative, '/');
    cJSON_AddStringToObject(entry, "name", slash ? slash + 1 : scanned->relative);
    if (slash) cJSON_AddStringToObject(entry, "path", scanned->relative);
    char *encoded = lk__serve_url_encode_path(scanned->relative);
    char url[PATH_MAX * 3 + 32];
    snprintf(url, sizeof url, "/m/%s", encoded ? encoded : "");
    cJSON_AddStringToObject(entry, "url", url);
    cJSON_AddNumberToObject(entry, "bytes", (double)scanned->size);
    opened_file file;
    lk_error error = {0};
    unsigned status = lk__serve_open_in_root(server->root, server->root_length, scanned->relative, &file, &error);
    if (status) {
        if (!error.message[0]) lk_error_set(&error, LK_ERR_IO, "cannot open (HTTP %u)", status);
    } else if (is_octree_index(scanned->relative)) {
        /* Named after its folder: every octree's index has the same name. */
        if (slash) {
            char folder[PATH_MAX];
            snprintf(folder, sizeof folder, "%.*s", (int)(slash - scanned->relative), scanned->relative);
            cJSON_ReplaceItemInObjectCaseSensitive(entry, "name", cJSON_CreateString(folder));
        }
        unsigned char *bytes = NULL;
        size_t size = 0;
        lk_octree *octree = NULL;
        if (lk__serve_read_opened(&file, server->options.max_file_bytes, &bytes, &size, &error) == LK_OK &&
            lk_octree_open_memory((const char *)bytes, size, scanned->relative, &octree, &error) == LK_OK) {
            const lk_octree_info *info = lk_octree_get_info(octree);
            cJSON_AddStringToObject(entry, "kind", "octree");
            cJSON_AddNumberToObject(entry, "points", (double)info->points);
            cJSON_AddNumberToObject(entry, "nodes", (double)info->node_count);
            cJSON_AddBoolToObject(entry, "normals", info->has_normals);
            cJSON_AddBoolToObject(entry, "colors", info->has_colors);
        }
        lk_octree_close(octree);
        free(bytes);
    } else if (lk__serve_is_stream(scanned->relative)) {
        unsigned char *bytes = NULL;
        size_t size = 0;
        lk_stream_info info;
        lk_stream_chunk_info *chunks = NULL;
        if (lk__serve_read_opened(&file, server->options.max_file_bytes, &bytes, &size, &error) == LK_OK &&
            lk_stream_inspect(bytes, size, &info, &chunks, &error) == LK_OK) {
            cJSON_AddStringToObject(entry, "kind", "stream");
            cJSON_AddNumberToObject(entry, "vertices", (double)info.vertex_count);
            cJSON_AddNumberToObject(entry, "triangles", (double)info.triangle_count);
            cJSON_AddNumberToObject(entry, "base_vertices", (double)info.base_vertex_count);
            cJSON_AddNumberToObject(entry, "base_triangles", (double)info.base_triangle_count);
            cJSON_AddNumberToObject(entry, "splits", (double)info.split_count);
            cJSON_AddNumberToObject(entry, "chunks", (double)info.chunk_count);
        }
        lk_free(chunks);
        free(bytes);
    } else if (lk__serve_reads_mesh(scanned->relative)) {
        lk_mesh mesh;
        if (lk__serve_read_mesh_opened(server, &file, &mesh, &error) == LK_OK) {
            if (mesh.triangle_count > 0) {
                cJSON_AddStringToObject(entry, "kind", "mesh");
                cJSON_AddNumberToObject(entry, "vertices", (double)mesh.vertex_count);
                cJSON_AddNumberToObject(entry, "triangles", (double)mesh.triangle_count);
            } else if (mesh.vertex_count > 0) {
                cJSON_AddStringToObject(entry, "kind", "points");
                cJSON_AddNumberToObject(entry, "points", (double)mesh.vertex_count);
                cJSON_AddBoolToObject(entry, "normals", mesh.normals != NULL);
                cJSON_AddBoolToObject(entry, "radii", mesh.radii != NULL);
                snprintf(url, sizeof url, "/api/points/%s", encoded ? encoded : "");
                cJSON_AddStringToObject(entry, "data", url);
            } else {
                lk_error_set(&error, LK_ERR_PARSE, "no vertices");
            }
            lk_mesh_free(&mesh);
        }
    } else {
        lk_heightfield field;
        if (lk__serve_read_heightfield(server, &file, &field, &error) == LK_OK) {
            cJSON_AddStringToObject(entry, "kind", "terrain");
            cJSON_AddNumberToObject(entry, "width", (double)field.width);
            cJSON_AddNumberToObject(entry, "height", (double)field.height);
            cJSON_AddNumberToObject(entry, "min_height", field.min_height);
            cJSON_AddNumberToObject(entry, "max_height", field.max_height);
            snprintf(url, sizeof url, "/api/terrain/%s", encoded ? encoded : "");
            cJSON_AddStringToObject(entry, "data", url);
            lk_heightfield_free(&field);
        }
    }
    if (!cJSON_GetObjectItemCaseSensitive(entry, "kind")) {
        cJSON_AddStringToObject(entry, "kind", "unknown");
        lk__serve_hide_directories(server, error.message);
        if (!error.message[0]) snprintf(error.message, sizeof error.message, "unreadable");
        /* The message names the file first, once, like every other the
         * server sends (the stream inspector's name none). */
        lk__serve_name_in_message(&error, scanned->relative);
        cJSON_AddStringToObject(entry, "error", error.message);
    }
    lk__serve_opened_close(&file);
    free(encoded);
    return entry;
}

void lk__serve_records_free(file_record *records, size_t count)
{
    for (size_t i = 0; i < count; i++) {
        free(records[i].relative);
        cJSON_Delete(records[i].entry);
    }
    free(records);
}

/* The index JSON (a new reference), rebuilt when any listed file changed. */
static blob *index_json(lk_server *server, lk_error *error)
{
    scan_state state = {0};
    scan_directory(server, "", 0, &state);
    qsort(state.files, state.count, sizeof *state.files, compare_scanned);
    /* A signature of what was listed: names and versions. */
    uint64_t signature = 1469598103934665603ull ^ (uint64_t)server->options.simplify_on_demand;
    for (size_t i = 0; i < state.count; i++) {
        for (const char *p = state.files[i].relative; *p; p++)
            signature = (signature ^ (unsigned char)*p) * 1099511628211ull;
        signature = lk__mix64(signature ^ 0xff);
        for (const char *p = state.files[i].version; *p; p++)
            signature = (signature ^ (unsigned char)*p) * 1099511628211ull;
        signature = lk__mix64(signature);
    }
    pthread_mutex_lock(&server->index_lock);
    blob *result = NULL;
    if (server->index_json && server->index_signature == signature) {
        result = server->index_json;
        lk__serve_blob_retain(result);
        goto done;
    }
    file_record *records = lk__calloc_array(state.count ? state.count : 1, sizeof *records);
    cJSON *root = cJSON_CreateObject();
    cJSON *models = root ? cJSON_AddArrayToObject(root, "models") : NULL;
    if (!records || !models) {
        free(records);
        cJSON_Delete(root);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory for the index");
        goto done;
    }
    for (size_t i = 0; i < state.count; i++) {
        const scanned_file *f = &state.files[i];
        cJSON *entry = NULL;
        for (size_t k = 0; k < server->record_count && !entry; k++)
            if (strcmp(server->records[k].version, f->version) == 0 &&
                strcmp(server->records[k].relative, f->relative) == 0) {
                entry = server->records[k].entry;
                server->records[k].entry = NULL;
            }
        if (!entry) entry = describe_file(server, f);
        records[i].relative = f->relative;
        memcpy(records[i].version, f->version, sizeof records[i].version);
        records[i].entry = entry;
        state.files[i].relative = NULL; /* moved into records[i] */
        if (!entry) continue;
        cJSON *copy = cJSON_Duplicate(entry, 1);
        if (!copy) continue;
        const cJSON *kind = cJSON_GetObjectItemCaseSensitive(copy, "kind");
        if (cJSON_IsString(kind) && strcmp(kind->valuestring, "mesh") == 0) {
            /* Where the stream of this mesh is: a NAME.lks next to it, or built on demand. */
            const char *relative = records[i].relative;
            size_t length = strlen(relative);
            const char *dot = strrchr(relative, '.');
            size_t stem = dot ? (size_t)(dot - relative) : length;
            char *stream = malloc(stem + 5);
            if (stream) {
                memcpy(stream, relative, stem);
                memcpy(stream + stem, ".lks", 5);
                bool exists = false;
                for (size_t k = 0; k < state.count && !exists; k++) {
                    /* names before i have moved into records already */
                    const char *other = k < i ? records[k].relative : k > i ? state.files[k].relative : NULL;
                    exists = other && strcmp(other, stream) == 0;
                }
                if (exists || server->options.simplify_on_demand) {
                    char *encoded = lk__serve_url_encode_path(stream);
                    if (encoded) {
                        char url[PATH_MAX * 3 + 8];
                        snprintf(url, sizeof url, "/m/%s", encoded);
                        cJSON_AddStringToObject(copy, "stream", url);
                        free(encoded);
                    }
                }
                free(stream);
            }
        }
        cJSON_AddItemToArray(models, copy);
    }
    lk__serve_records_free(server->records, server->record_count);
    server->records = records;
    server->record_count = state.count;
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    if (!text) {
        lk_error_set(error, LK_ERR_NOMEM, "out of memory for the index");
        goto done;
    }
    blob *fresh = lk__serve_blob_wrap((unsigned char *)text, strlen(text));
    if (!fresh) {
        free(text);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory for the index");
        goto done;
    }
    if (server->index_json) lk__serve_blob_release(server->index_json);
    server->index_json = fresh;
    server->index_signature = signature;
    result = fresh;
    lk__serve_blob_retain(result);
done:
    pthread_mutex_unlock(&server->index_lock);
    for (size_t i = 0; i < state.count; i++) free(state.files[i].relative);
    free(state.files);
    return result;
}

enum MHD_Result lk__serve_index(lk_server *server, struct MHD_Connection *connection, request *r)
{
    lk_error error = {0};
    blob *json = index_json(server, &error);
    if (!json) return lk__serve_respond_error(connection, r, 503, "index: %s", error.message);
    source s;
    lk__serve_source_from_blob(&s, json, SERVE_MIME_JSON, true, "index");
    return lk__serve_send_source(server, connection, r, &s);
}
