/* SPDX-License-Identifier: MIT */
/* The server's index follows the library's format table: a folder holding
 * a file of every extension the table has is served with each file lodkit
 * can read as a mesh, a point set, frame 0 of an animation, an elevation
 * grid or a stream listed in /api/index.json (a format added to the table
 * is listed without a list of its own in src/serve/), files of the other
 * kinds (Acclaim .asf/.amc) are not, and a missing NAME.lks is built on
 * demand from a NAME.md2 as from a NAME.obj. Procedural shapes only. */
#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "shapes.h"

static char content_dir[512], cache_dir[512];
static lk_server *server;

static const char *content_path(const char *name) { return lk_test_path(content_dir, name); }

/* ---- a GET on a fresh connection -------------------------------------------- */

typedef struct response {
    int status;
    char *body; /* NUL-terminated */
    size_t body_size;
} response;

static void get(const char *target, response *out)
{
    int fd = lk_test_connect(lk_server_port(server), NULL, 0, 60);
    assert_true(fd >= 0);
    char request[1024];
    int length =
        snprintf(request, sizeof request, "GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n", target);
    assert_true(lk_test_send_all(fd, request, (size_t)length));
    size_t capacity = 1 << 16, size = 0;
    char *raw = malloc(capacity + 1);
    assert_non_null(raw);
    for (ssize_t n; (n = recv(fd, raw + size, capacity - size, 0)) > 0;) {
        size += (size_t)n;
        if (size == capacity) {
            capacity *= 2;
            raw = realloc(raw, capacity + 1);
            assert_non_null(raw);
        }
    }
    close(fd);
    raw[size] = '\0';
    char *end = strstr(raw, "\r\n\r\n");
    assert_true(size > 12 && end && memcmp(raw, "HTTP/1.1 ", 9) == 0);
    out->status = atoi(raw + 9);
    out->body_size = size - (size_t)(end + 4 - raw);
    out->body = malloc(out->body_size + 1);
    assert_non_null(out->body);
    memcpy(out->body, end + 4, out->body_size + 1);
    free(raw);
}

/* ---- a folder with a file of every extension in the table ------------------- */

/* What the index should say of a file: the kind for files written here
 * with real content, NULL for placeholders (listed; "unknown" is fine). */
typedef struct written_file {
    char name[64];
    const char *kind;
    bool listed; /* the server reads this format */
} written_file;

static written_file files[128];
static size_t file_count;

static void write_text(const char *name, const char *text)
{
    lk_test_write_file(content_path(name), text, strlen(text));
}

/* A real file of this extension when the library (or a few lines of text)
 * can write one; the kind the index gives it, or NULL. */
static const char *write_model(const lk_format_info *info, const char *name, const lk_mesh *mesh, const lk_mesh *points,
                               const lk_animation *animation, const unsigned char *stream, size_t stream_size)
{
    lk_error error = {0};
    const char *path = content_path(name);
    if (info->write & LK_IO_MESH) {
        bool point_set = info->kind == LK_FORMAT_KIND_POINTS;
        if (lk_mesh_write(path, info->format, point_set ? points : mesh, NULL, &error) != LK_OK)
            fail_msg("%s: %s", name, error.message);
        return point_set ? "points" : "mesh";
    }
    if ((info->write & LK_IO_ANIMATION) && (info->read & LK_IO_MESH)) {
        if (lk_animation_write(path, animation, &error) != LK_OK) fail_msg("%s: %s", name, error.message);
        return "mesh"; /* frame 0 */
    }
    if (info->kind == LK_FORMAT_KIND_STREAM) {
        lk_test_write_file(path, stream, stream_size);
        return "stream";
    }
    const char *extension = strrchr(name, '.') + 1;
    if (strcmp(extension, "pgm") == 0) { /* lodkit's own reader */
        write_text(name, "P2\n3 3\n255\n0 10 20\n30 40 50\n60 70 80\n");
        return "terrain";
    }
    if (strcmp(extension, "grd") == 0) { /* Surfer ASCII grid, through GDAL */
        write_text(name, "DSAA\n3 3\n0 2\n0 2\n0 8\n0 1 2\n3 4 5\n6 7 8\n");
        return "terrain";
    }
    write_text(name, "placeholder, not a model\n");
    return NULL;
}

static int setup(void **state)
{
    (void)state;
    snprintf(content_dir, sizeof content_dir, "%s/content", lk_test_tmpdir());
    snprintf(cache_dir, sizeof cache_dir, "%s/cache", lk_test_tmpdir());
    if (mkdir(content_dir, 0755) != 0) return -1;

    lk_mesh mesh, points;
    shape_icosphere(&mesh, 1.0, 2);
    const double centre[3] = {0, 0, 0};
    shape_sphere_points(&points, 500, 1.0, centre);
    lk_animation animation;
    shape_bending_capsule(&animation, 0.2, 2.0, 12, 6, 3, 4, 60.0);

    lk_error error = {0};
    lk_progressive_options pm_options;
    lk_progressive_options_default(&pm_options);
    lk_progressive_mesh pm;
    lk_progressive_strips strips;
    lk_stream_options stream_options;
    lk_stream_options_default(&stream_options);
    unsigned char *stream = NULL;
    size_t stream_size = 0;
    if (lk_progressive_mesh_build(&mesh, &pm_options, &pm, NULL, NULL, &error) != LK_OK ||
        lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &strips, &error) != LK_OK ||
        lk_stream_encode(&pm, &strips, &stream_options, &stream, &stream_size, &error) != LK_OK)
        fail_msg("stream: %s", error.message);
    lk_progressive_strips_free(&strips);
    lk_progressive_mesh_free(&pm);

    const lk_format_info *info;
    for (size_t i = 0; (info = lk_format_info_at(i)); i++) {
        for (const char *word = info->extensions; *word;) {
            size_t length = strcspn(word, " ");
            assert_true(file_count < sizeof files / sizeof files[0] && length < 20);
            written_file *file = &files[file_count++];
            /* "model-EXT.EXT": one file per extension, none another's NAME.lks */
            snprintf(file->name, sizeof file->name, "model-%.*s.%.*s", (int)length, word, (int)length, word);
            file->listed = (info->read & (LK_IO_MESH | LK_IO_GRID)) || info->kind == LK_FORMAT_KIND_STREAM;
            file->kind = write_model(info, file->name, &mesh, &points, &animation, stream, stream_size);
            word += length;
            if (*word == ' ') word++;
        }
    }
    write_text("notes.txt", "not a model\n");
    free(stream);
    lk_animation_free(&animation);
    lk_mesh_free(&points);
    lk_mesh_free(&mesh);

    lk_server_options options;
    lk_server_options_default(&options);
    options.port = 0;
    options.simplify_on_demand = 1;
    options.cache_dir = cache_dir;
    options.timeout_seconds = 30;
    if (lk_server_start(content_dir, &options, &server, &error) != LK_OK) {
        fprintf(stderr, "server: %s\n", error.message);
        return -1;
    }
    return lk_server_port(server) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    lk_server_stop(server);
    return 0;
}

static const cJSON *find_model(const cJSON *models, const char *name)
{
    const cJSON *model;
    cJSON_ArrayForEach(model, models)
    {
        const cJSON *item = cJSON_GetObjectItemCaseSensitive(model, "name");
        if (cJSON_IsString(item) && strcmp(item->valuestring, name) == 0) return model;
    }
    return NULL;
}

static const char *string_of(const cJSON *model, const char *key)
{
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(model, key);
    return cJSON_IsString(item) ? item->valuestring : "";
}

/* ---- tests ---------------------------------------------------------------------- */

static void test_index_lists_every_readable_format(void **state)
{
    (void)state;
    response r;
    get("/api/index.json", &r);
    assert_int_equal(r.status, 200);
    cJSON *json = cJSON_Parse(r.body);
    assert_non_null(json);
    const cJSON *models = cJSON_GetObjectItemCaseSensitive(json, "models");
    assert_true(cJSON_IsArray(models));
    size_t listed = 0;
    for (size_t i = 0; i < file_count; i++) {
        const written_file *file = &files[i];
        const cJSON *model = find_model(models, file->name);
        if (!file->listed) {
            if (model) fail_msg("%s is listed, but the server reads no file of its format", file->name);
            continue;
        }
        listed++;
        if (!model) fail_msg("%s is missing from /api/index.json", file->name);
        if (file->kind && strcmp(string_of(model, "kind"), file->kind) != 0)
            fail_msg("%s: kind '%s' (expected '%s'; error: %s)", file->name, string_of(model, "kind"), file->kind,
                     string_of(model, "error"));
    }
    assert_int_equal((size_t)cJSON_GetArraySize(models), listed);
    assert_null(find_model(models, "notes.txt"));
    /* the formats the server's own lists had left out, by name */
    const char *drifted[] = {"model-xyzn.xyzn", "model-pts.pts", "model-md2.md2", "model-kmf.kmf"};
    const char *drifted_kinds[] = {"points", "points", "mesh", "mesh"};
    for (size_t i = 0; i < sizeof drifted / sizeof drifted[0]; i++)
        assert_string_equal(string_of(find_model(models, drifted[i]), "kind"), drifted_kinds[i]);
    assert_string_equal(string_of(find_model(models, "model-grd.grd"), "kind"), "terrain");
    assert_null(find_model(models, "model-asf.asf"));
    /* frame 0 of an animation is a mesh the viewer gets a stream of */
    assert_string_equal(string_of(find_model(models, "model-md2.md2"), "stream"), "/m/model-md2.lks");
    cJSON_Delete(json);
    free(r.body);
}

static void test_stream_built_from_an_animation(void **state)
{
    (void)state;
    response r;
    get("/m/model-md2.lks", &r);
    assert_int_equal(r.status, 200);
    lk_stream_info info;
    lk_stream_chunk_info *chunks = NULL;
    lk_error error = {0};
    assert_int_equal(lk_stream_inspect((const unsigned char *)r.body, r.body_size, &info, &chunks, &error), LK_OK);
    free(chunks);
    lk_mesh frame0;
    lk_test_load(content_path("model-md2.md2"), &frame0);
    assert_int_equal(info.vertex_count, frame0.vertex_count);
    assert_int_equal(info.triangle_count, frame0.triangle_count);
    lk_mesh_free(&frame0);
    free(r.body);
    /* a point set is no source of a stream */
    get("/m/model-pts.lks", &r);
    assert_int_equal(r.status, 404);
    free(r.body);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_index_lists_every_readable_format),
        cmocka_unit_test(test_stream_built_from_an_animation),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
