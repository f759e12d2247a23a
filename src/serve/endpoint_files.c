/* SPDX-License-Identifier: MIT */
/* /m/PATH: the files of the served folder, and the progressive streams
 * built on demand (--simplify-on-demand) for a mesh that has none, cached
 * on disk. */
#include "serve_shared.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

/* ---- simplify on demand ---------------------------------------------------- */

/* Creates the folders of `path` (below the cache folder). The first
 * `trusted` bytes are a path the user gave (--cache DIR, or the served
 * folder): symbolic links there are followed. Below that, an existing
 * component must be a real folder, never a link: a link planted in the
 * served folder (.lodkit-cache -> /elsewhere) must not make the server
 * write streams outside it. */
static lk_status make_directories(const char *path, size_t trusted, lk_error *error)
{
    char *copy = strdup(path);
    if (!copy) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    size_t length = strlen(copy);
    for (size_t i = 1; i <= length; i++) {
        if (copy[i] != '/' && copy[i] != '\0') continue;
        char saved_char = copy[i];
        copy[i] = '\0';
        struct stat st;
        int failure = 0;
        if (i > trusted && lstat(copy, &st) == 0) {
            if (!S_ISDIR(st.st_mode)) failure = S_ISLNK(st.st_mode) ? ELOOP : ENOTDIR;
        } else if (mkdir(copy, 0755) != 0 && errno != EEXIST) {
            failure = errno;
        }
        if (failure) {
            lk_error_set(error, LK_ERR_IO, "%s: cannot create directory: %s", copy,
                         failure == ELOOP ? "a symbolic link (the cache follows none)" : strerror(failure));
            free(copy);
            return LK_ERR_IO;
        }
        copy[i] = saved_char;
    }
    free(copy);
    return LK_OK;
}

/* Progress callback of long builds: cancels them once the server stops. */
static int cancel_when_stopping(void *user, double fraction, const char *stage)
{
    (void)fraction;
    (void)stage;
    lk_server *server = user;
    return atomic_load(&server->stopping);
}

static lk_status build_stream(lk_server *server, const opened_file *input, const char *output, lk_error *error)
{
    lk_mesh mesh;
    lk_progressive_mesh pm;
    memset(&pm, 0, sizeof pm);
    unsigned char *bytes = NULL;
    size_t size = 0;
    /* Version 2, as `lodkit progressive` builds by default: a first frame
     * in the first kilobytes, the input's attributes carried. */
    lk_progressive_options pm_options;
    lk_progressive_options_default(&pm_options);
    pm_options.simplify.flags |= LK_SIMPLIFY_ENDPOINTS | LK_SIMPLIFY_ROUNDS;
    pm_options.base_triangles = LK_STREAM_V2_BASE_TRIANGLES;
    lk_stream_options stream_options;
    lk_stream_options_default(&stream_options);
    stream_options.version = 2;
    lk_status status = lk__serve_read_mesh_opened(server, input, &mesh, error);
    if (status == LK_OK)
        status = lk_progressive_mesh_build(&mesh, &pm_options, &pm, cancel_when_stopping, server, error);
    if (status == LK_OK) status = lk_stream_encode_with_attributes(&pm, &mesh, &stream_options, &bytes, &size, error);
    if (status == LK_OK) {
        char *directory = strdup(output);
        if (!directory)
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        else {
            char *slash = strrchr(directory, '/');
            if (slash && slash != directory) {
                *slash = '\0';
                status = make_directories(directory, server->cache_trusted_length, error);
            }
            free(directory);
        }
    }
    if (status == LK_OK) status = lk_stream_write_file(output, bytes, size, error);
    lk_free(bytes);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
    return status;
}

/* The source mesh of a missing NAME.lks, or 404: the first NAME.EXT that
 * opens, EXT taken in the format table's order among the formats streams
 * are built from (lk__serve_builds_streams_from). */
static unsigned find_stream_source(lk_server *server, const char *relative, opened_file *file, lk_error *why)
{
    size_t length = strlen(relative);
    if (length < 5 || strcasecmp(relative + length - 4, ".lks") != 0) return 404;
    enum { LONGEST_EXTENSION = 31 };
    char *candidate = malloc(length - 3 + LONGEST_EXTENSION + 1);
    if (!candidate) return 500;
    memcpy(candidate, relative, length - 3);
    unsigned status = 404;
    const lk_format_info *info;
    for (size_t i = 0; (info = lk_format_info_at(i)) && status && status != 403; i++) {
        if (!lk__serve_builds_streams_from(info)) continue;
        for (const char *word = info->extensions; *word && status && status != 403;) {
            size_t word_length = strcspn(word, " ");
            if (word_length <= LONGEST_EXTENSION) {
                memcpy(candidate + length - 3, word, word_length);
                candidate[length - 3 + word_length] = '\0';
                status = lk__serve_open_in_root(server->root, server->root_length, candidate, file, why);
            }
            word += word_length;
            if (*word == ' ') word++;
        }
    }
    free(candidate);
    return status;
}

/* What a cached stream was built from, kept next to it as NAME.lks.source:
 * this lodkit and the stream version it builds (another may build other
 * streams; "revision 2": version 2's payload coding of 2026-11-27, whose
 * earlier streams no longer decode) and the source file's name and version
 * (lk__serve_version_of). Any difference rebuilds. */
static void stream_key(const opened_file *input, char *out, size_t size)
{
    char version[SERVE_VERSION_CHARS];
    lk__serve_version_of(&input->st, version);
    snprintf(out, size, "lodkit %s\nstream version 2 revision 2\nsource %s\nversion %s\n", LK_VERSION_STRING,
             input->name, version);
}

/* Is the cached stream there (non-empty) with this key? Both are opened
 * below the cache directory without following links. */
static bool cached_stream_fresh(const lk_server *server, const char *relative, const char *key_relative,
                                const char *key)
{
    int fd;
    struct stat st;
    lk_error ignored = {0};
    if (lk__open_input(server->cache_dir, relative, &fd, &st, &ignored) != LK_OK) return false;
    close(fd);
    if (st.st_size == 0 || lk__open_input(server->cache_dir, key_relative, &fd, &st, &ignored) != LK_OK) return false;
    char *text = NULL;
    size_t size = 0;
    bool same = lk__read_opened(fd, &st, key_relative, 4096, &text, &size, &ignored) == LK_OK && strcmp(text, key) == 0;
    close(fd);
    free(text);
    return same;
}

static lk_status write_stream_key(const char *path, const char *key, lk_error *error)
{
    lk__atomic_file out;
    lk_status status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    if (fputs(key, out.file) == EOF) {
        lk__atomic_abort(&out);
        return lk_error_set(error, LK_ERR_IO, "%s: write error", path);
    }
    return lk__atomic_commit(&out, error);
}

/* Opens (building it first when needed) the cached stream for `relative`.
 * Returns 0 or an HTTP status with a message in error. */
static unsigned open_on_demand_stream(lk_server *server, const char *relative, opened_file *out, lk_error *error)
{
    opened_file input;
    unsigned status = find_stream_source(server, relative, &input, error);
    if (status) return status;
    size_t length = strlen(server->cache_dir) + strlen(relative) + 16;
    char *cached = malloc(length), *key_path = malloc(length);
    char key[PATH_MAX + 256];
    stream_key(&input, key, sizeof key);
    if (!cached || !key_path) {
        free(cached);
        free(key_path);
        lk__serve_opened_close(&input);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        return 500;
    }
    snprintf(cached, length, "%s/%s", server->cache_dir, relative);
    snprintf(key_path, length, "%s.source", cached);
    const char *key_relative = key_path + strlen(server->cache_dir) + 1;
    pthread_mutex_lock(&server->build_lock);
    /* Checked again under the lock: an earlier request may just have built it. */
    if (!cached_stream_fresh(server, relative, key_relative, key)) {
        double start = lk__now();
        lk_status built = build_stream(server, &input, cached, error);
        if (built == LK_OK) built = write_stream_key(key_path, key, error);
        if (built != LK_OK) {
            status = atomic_load(&server->stopping) ? 503 : lk__serve_http_status_of(built);
            lk__serve_name_in_message(error, input.name);
        } else {
            lk__serve_server_log(server, "simplify-on-demand: built %s from %s (%.2f s)", relative, input.name,
                                 lk__now() - start);
        }
    }
    pthread_mutex_unlock(&server->build_lock);
    lk__serve_opened_close(&input);
    free(key_path);
    if (status == 0) {
        if (lk__open_input(server->cache_dir, relative, &out->fd, &out->st, error) != LK_OK) {
            lk_error_set(error, LK_ERR_IO, "%s: cannot open the cached stream", relative);
            status = 500;
        } else {
            out->real = cached;
            out->name = cached + strlen(server->cache_dir) + 1;
            cached = NULL;
        }
    }
    free(cached);
    return status;
}

enum MHD_Result lk__serve_content(lk_server *server, struct MHD_Connection *connection, request *r,
                                  const char *relative_raw)
{
    unsigned status = 0;
    char *relative = lk__serve_clean_relative_path(relative_raw, &status);
    if (!relative)
        return lk__serve_respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");
    opened_file file;
    lk_error why = {0};
    status = lk__serve_open_in_root(server->root, server->root_length, relative, &file, &why);
    if (status == 404 && server->options.simplify_on_demand) {
        lk_error build_error = {0};
        unsigned built = open_on_demand_stream(server, relative, &file, &build_error);
        if (built != 404) {
            status = built;
            why = build_error;
        }
    }
    if (status) {
        enum MHD_Result result =
            lk__serve_respond_error(connection, r, status, "%s", why.message[0] ? why.message : "error");
        free(relative);
        return result;
    }
    source s;
    lk__serve_source_from_file(&s, &file, relative);
    lk__serve_opened_close(&file);
    free(relative);
    return lk__serve_send_source(server, connection, r, &s);
}
