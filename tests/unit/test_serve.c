/* SPDX-License-Identifier: MIT */
/* HTTP server (src/serve/): an in-process server on 127.0.0.1 and a small
 * HTTP/1.1 client written here on raw sockets. Asserts exact bytes of
 * Range requests (206/416), 404, path traversal (.., %2e%2e, backslash,
 * hidden names, symlink escape: 403 and never the bytes), HEAD, 405,
 * content types, gzip only when accepted (round trip with zlib), ETag/304,
 * the index JSON on real files (the bunny stream built here with the
 * library's encoder, a sampled bunny point set, the jacksboro DEM), LKMB
 * buffers parsed back (points: count, normals, radii > 0; terrain:
 * triangles > 0 and no crack), simplify-on-demand (built once, then served
 * from the cache; the cached file is a valid stream), the connection limit
 * and the timeout of a client that sends half a request. */
#include <arpa/inet.h>
#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <netinet/in.h>
#include <pthread.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include "testutil.h"

/* ---- fixture: a content directory and a server ---------------------------- */

static char content_dir[512], cache_dir[512], outside_file[512];
static unsigned char *bunny_stream;
static size_t bunny_stream_size;
static lk_stream_info bunny_info;
static lk_progressive_mesh bunny_pm_counts; /* only the counts are kept */
static lk_server *server;
static unsigned port;

static void copy_file(const char *from, const char *to)
{
    size_t size = 0;
    unsigned char *bytes = lk_test_read_file(from, &size);
    if (!bytes) fail_msg("cannot read %s", from);
    lk_test_write_file(to, bytes, size);
    free(bytes);
}

static const char *content_path(const char *name) { return lk_test_path(content_dir, name); }

static int setup_content(void **state)
{
    (void)state;
    lk_error error = {0};
    snprintf(content_dir, sizeof content_dir, "%s/content", lk_test_tmpdir());
    snprintf(cache_dir, sizeof cache_dir, "%s/cache", lk_test_tmpdir());
    snprintf(outside_file, sizeof outside_file, "%s/outside.txt", lk_test_tmpdir());
    if (mkdir(content_dir, 0755) != 0) return -1;
    if (mkdir(content_path("sub"), 0755) != 0) return -1;

    /* The bunny stream, built with the library's encoder (defaults of `lodkit progressive`). */
    lk_mesh bunny;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_progressive_options pm_options;
    lk_progressive_options_default(&pm_options);
    lk_progressive_mesh pm;
    lk_progressive_strips strips;
    lk_stream_options stream_options;
    lk_stream_options_default(&stream_options);
    lk_stream_chunk_info *chunks = NULL;
    if (lk_progressive_mesh_build(&bunny, &pm_options, &pm, NULL, NULL, &error) != LK_OK ||
        lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &strips, &error) != LK_OK ||
        lk_stream_encode(&pm, &strips, &stream_options, &bunny_stream, &bunny_stream_size, &error) != LK_OK ||
        lk_stream_inspect(bunny_stream, bunny_stream_size, &bunny_info, &chunks, &error) != LK_OK) {
        fprintf(stderr, "bunny stream: %s\n", error.message);
        return -1;
    }
    lk_free(chunks);
    bunny_pm_counts.vertex_count = pm.vertex_count;
    bunny_pm_counts.triangle_count = pm.triangle_count;
    bunny_pm_counts.base_vertex_count = pm.base_vertex_count;
    bunny_pm_counts.base_triangle_count = pm.base_triangle_count;
    bunny_pm_counts.split_count = pm.split_count;
    lk_progressive_strips_free(&strips);
    lk_progressive_mesh_free(&pm);
    lk_test_write_file(content_path("bunny.lks"), bunny_stream, bunny_stream_size);

    /* A point set with normals and radii (binary PLY), and one without (XYZ). */
    lk_sample_options sample;
    lk_sample_options_default(&sample);
    sample.point_count = 20000;
    lk_mesh points;
    if (lk_mesh_sample_points(&bunny, &sample, &points, NULL, NULL, &error) != LK_OK ||
        lk_mesh_write(content_path("bunny-points.ply"), LK_FORMAT_PLY, &points, NULL, &error) != LK_OK) {
        fprintf(stderr, "points: %s\n", error.message);
        return -1;
    }
    lk_mesh plain;
    if (lk_mesh_alloc(&plain, 3000, 0, 0, &error) != LK_OK) return -1;
    memcpy(plain.positions, points.positions, 3000 * 3 * sizeof(float));
    lk_write_options write_options = {0};
    write_options.skip_normals = 1;
    if (lk_mesh_write(content_path("plain.xyz"), LK_FORMAT_XYZ, &plain, &write_options, &error) != LK_OK) return -1;
    lk_mesh_free(&plain);
    lk_mesh_free(&points);
    lk_mesh_free(&bunny);

    copy_file(lk_test_sample("jacksboro_fault_dem.npz"), content_path("jacksboro_fault_dem.npz"));
    copy_file(lk_test_sample("cow.off"), content_path("cow.off"));
    lk_test_write_file(content_path("broken.obj"), "garbage\n", 8);
    lk_test_write_file(content_path("notes.txt"), "not a model\n", 12);
    lk_test_write_file(content_path(".secret"), "hidden\n", 7);
    lk_test_write_file(content_path("sub/page.txt"), "inside a subdirectory\n", 22);
    lk_test_write_file(outside_file, "TOPSECRET outside the root\n", 27);
    /* a link that escapes the root, and one that stays inside */
    if (symlink(outside_file, content_path("leak.txt")) != 0) return -1;
    if (symlink("bunny.lks", content_path("inside.lks")) != 0) return -1;

    lk_server_options options;
    lk_server_options_default(&options);
    options.port = 0;
    options.simplify_on_demand = 1;
    options.cache_dir = cache_dir;
    options.timeout_seconds = 10;
    options.log = lk_test_log_line;
    if (lk_server_start(content_dir, &options, &server, &error) != LK_OK) {
        fprintf(stderr, "server: %s\n", error.message);
        return -1;
    }
    port = lk_server_port(server);
    return port ? 0 : -1;
}

static int teardown_content(void **state)
{
    (void)state;
    lk_server_stop(server);
    lk_free(bunny_stream);
    return 0;
}

/* ---- a minimal HTTP/1.1 client ---------------------------------------------- */

typedef struct response {
    int status;         /* -1: no response (connection closed or refused) */
    char headers[8192]; /* raw header block, lines "Name: value\r\n" */
    unsigned char *body;
    size_t body_size;
} response;

static void response_free(response *r)
{
    free(r->body);
    r->body = NULL;
}

/* Reads until the server closes; parses status, headers, body. */
static void read_response(int fd, response *out)
{
    size_t capacity = 1 << 16, size = 0;
    unsigned char *raw = malloc(capacity);
    assert_non_null(raw);
    for (;;) {
        if (size == capacity) {
            capacity *= 2;
            raw = realloc(raw, capacity);
            assert_non_null(raw);
        }
        ssize_t n = recv(fd, raw + size, capacity - size, 0);
        if (n <= 0) break;
        size += (size_t)n;
    }
    out->status = -1;
    out->headers[0] = '\0';
    out->body = NULL;
    out->body_size = 0;
    unsigned char *end = NULL;
    for (size_t i = 0; i + 3 < size; i++)
        if (memcmp(raw + i, "\r\n\r\n", 4) == 0) {
            end = raw + i;
            break;
        }
    if (!end || size < 12 || memcmp(raw, "HTTP/1.", 7) != 0) {
        free(raw);
        return;
    }
    out->status = atoi((const char *)raw + 9);
    size_t header_length = (size_t)(end - raw) + 2;
    if (header_length >= sizeof out->headers) header_length = sizeof out->headers - 1;
    memcpy(out->headers, raw, header_length);
    out->headers[header_length] = '\0';
    out->body_size = size - (size_t)(end + 4 - raw);
    out->body = malloc(out->body_size + 1);
    assert_non_null(out->body);
    memcpy(out->body, end + 4, out->body_size);
    out->body[out->body_size] = '\0';
    free(raw);
}

/* One request on a fresh connection ("Connection: close"). extra holds
 * more header lines, each ending in \r\n. */
static void http_on(unsigned to_port, const char *method, const char *target, const char *extra, response *out)
{
    int fd = lk_test_connect(to_port, NULL, 0, 20);
    assert_true(fd >= 0);
    char request[4096];
    int length = snprintf(request, sizeof request, "%s %s HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n%s\r\n",
                          method, target, extra ? extra : "");
    assert_true(lk_test_send_all(fd, request, (size_t)length));
    read_response(fd, out);
    close(fd);
}

static void http(const char *method, const char *target, const char *extra, response *out)
{
    http_on(port, method, target, extra, out);
}

/* The value of a header (case-insensitive name) in a static buffer, or NULL. */
static const char *header(const response *r, const char *name)
{
    return lk_test_http_header(r->headers, strlen(r->headers), name);
}

static bool body_contains(const response *r, const char *needle)
{
    size_t length = strlen(needle);
    for (size_t i = 0; r->body && i + length <= r->body_size; i++)
        if (memcmp(r->body + i, needle, length) == 0) return true;
    return false;
}

static void assert_json_error(const response *r)
{
    cJSON *json = cJSON_ParseWithLength((const char *)r->body, r->body_size);
    assert_non_null(json);
    assert_true(cJSON_IsString(cJSON_GetObjectItemCaseSensitive(json, "error")));
    cJSON_Delete(json);
}

/* ---- raw files, Range ---------------------------------------------------------- */

static void test_full_file(void **state)
{
    (void)state;
    response r;
    http("GET", "/m/bunny.lks", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_size, bunny_stream_size);
    assert_memory_equal(r.body, bunny_stream, bunny_stream_size);
    assert_string_equal(header(&r, "Content-Type"), "application/vnd.lodkit.stream");
    assert_string_equal(header(&r, "Accept-Ranges"), "bytes");
    assert_int_equal(strtoull(header(&r, "Content-Length"), NULL, 10), bunny_stream_size);
    assert_non_null(header(&r, "ETag"));
    assert_non_null(header(&r, "Last-Modified"));
    response_free(&r);
    /* a symlink that stays inside the root is served */
    http("GET", "/m/inside.lks", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_size, bunny_stream_size);
    response_free(&r);
    http("GET", "/m/sub/page.txt", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_true(body_contains(&r, "inside a subdirectory"));
    response_free(&r);
}

static void test_range(void **state)
{
    (void)state;
    response r;
    char expected[128];
    size_t size = bunny_stream_size;

    http("GET", "/m/bunny.lks", "Range: bytes=100-199\r\n", &r);
    assert_int_equal(r.status, 206);
    assert_int_equal(r.body_size, 100);
    assert_memory_equal(r.body, bunny_stream + 100, 100);
    snprintf(expected, sizeof expected, "bytes 100-199/%zu", size);
    assert_string_equal(header(&r, "Content-Range"), expected);
    assert_string_equal(header(&r, "Content-Length"), "100");
    response_free(&r);

    /* open-ended, suffix, and an end past the size (clamped) */
    http("GET", "/m/bunny.lks", "Range: bytes=300000-\r\n", &r);
    assert_int_equal(r.status, 206);
    assert_int_equal(r.body_size, size - 300000);
    assert_memory_equal(r.body, bunny_stream + 300000, size - 300000);
    response_free(&r);
    http("GET", "/m/bunny.lks", "Range: bytes=-64\r\n", &r);
    assert_int_equal(r.status, 206);
    assert_int_equal(r.body_size, 64);
    assert_memory_equal(r.body, bunny_stream + size - 64, 64);
    snprintf(expected, sizeof expected, "bytes %zu-%zu/%zu", size - 64, size - 1, size);
    assert_string_equal(header(&r, "Content-Range"), expected);
    response_free(&r);
    http("GET", "/m/bunny.lks", "Range: bytes=0-99999999\r\n", &r);
    assert_int_equal(r.status, 206);
    assert_int_equal(r.body_size, size);
    response_free(&r);

    /* the header and chunk table, as a streaming client asks for them */
    http("GET", "/m/bunny.lks", "Range: bytes=0-0\r\n", &r);
    assert_int_equal(r.status, 206);
    assert_int_equal(r.body_size, 1);
    assert_int_equal(r.body[0], bunny_stream[0]);
    response_free(&r);

    /* unsatisfiable */
    char range[64];
    snprintf(range, sizeof range, "Range: bytes=%zu-\r\n", size);
    http("GET", "/m/bunny.lks", range, &r);
    assert_int_equal(r.status, 416);
    snprintf(expected, sizeof expected, "bytes */%zu", size);
    assert_string_equal(header(&r, "Content-Range"), expected);
    assert_json_error(&r);
    response_free(&r);
    http("GET", "/m/bunny.lks", "Range: bytes=-0\r\n", &r);
    assert_int_equal(r.status, 416);
    response_free(&r);
    /* several ranges or nonsense: the whole file (RFC 9110 lets a server ignore Range) */
    http("GET", "/m/bunny.lks", "Range: bytes=0-1,5-6\r\n", &r);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_size, size);
    response_free(&r);
    http("GET", "/m/bunny.lks", "Range: lines=1-2\r\n", &r);
    assert_int_equal(r.status, 200);
    response_free(&r);
}

/* ---- refusals -------------------------------------------------------------------- */

static void assert_refused(const char *target, int status)
{
    response r;
    http("GET", target, NULL, &r);
    if (r.status != status) fail_msg("%s: status %d, expected %d", target, r.status, status);
    if (body_contains(&r, "TOPSECRET") || body_contains(&r, "hidden\n") || body_contains(&r, "root:"))
        fail_msg("%s: the refused file's bytes were sent", target);
    response_free(&r);
}

static void test_not_found_and_traversal(void **state)
{
    (void)state;
    response r;
    http("GET", "/m/missing.lks", NULL, &r);
    assert_int_equal(r.status, 404);
    assert_json_error(&r);
    assert_string_equal(header(&r, "Content-Type"), "application/json");
    response_free(&r);
    assert_refused("/nothing/here", 404);
    assert_refused("/m/sub", 404); /* a directory is not a file */

    assert_refused("/m/../outside.txt", 403);
    assert_refused("/m/%2e%2e/outside.txt", 403);
    assert_refused("/m/%2E%2E/%2e%2e/%2e%2e/etc/passwd", 403);
    assert_refused("/m/sub/../../outside.txt", 403);
    assert_refused("/m/sub/%2e%2e/%2e%2e/outside.txt", 403);
    assert_refused("/m/..%2foutside.txt", 403);
    assert_refused("/m/..%5coutside.txt", 403);
    assert_refused("/m/sub%5c..%5c..%5coutside.txt", 403);
    assert_refused("/m/leak.txt", 403); /* symlink escape */
    assert_refused("/m/.secret", 403);  /* hidden names */
    assert_refused("/m/bunny.lks%00.txt", 400);
    assert_refused("/m/%zz", 400);
    assert_refused("/api/points/../outside.txt", 403);
    assert_refused("/api/terrain/%2e%2e/outside.txt/info", 403);
    assert_refused("/api/points/leak.txt", 403);
}

static void test_head_and_methods(void **state)
{
    (void)state;
    response r;
    http("HEAD", "/m/bunny.lks", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_size, 0);
    assert_int_equal(strtoull(header(&r, "Content-Length"), NULL, 10), bunny_stream_size);
    response_free(&r);
    http("HEAD", "/m/bunny.lks", "Range: bytes=10-19\r\n", &r);
    assert_int_equal(r.status, 206);
    assert_int_equal(r.body_size, 0);
    assert_string_equal(header(&r, "Content-Length"), "10");
    response_free(&r);
    const char *methods[] = {"POST", "PUT", "DELETE", "OPTIONS"};
    for (size_t i = 0; i < 4; i++) {
        http(methods[i], "/m/bunny.lks", "Content-Length: 0\r\n", &r);
        assert_int_equal(r.status, 405);
        assert_string_equal(header(&r, "Allow"), "GET, HEAD");
        assert_json_error(&r);
        response_free(&r);
    }
}

static void test_content_types(void **state)
{
    (void)state;
    static const struct {
        const char *target, *type;
    } cases[] = {
        {"/m/bunny.lks", "application/vnd.lodkit.stream"},
        {"/m/cow.off", "text/plain; charset=utf-8"},
        {"/m/broken.obj", "model/obj"},
        {"/m/bunny-points.ply", "application/octet-stream"}, /* binary PLY */
        {"/m/notes.txt", "text/plain; charset=utf-8"},
        {"/api/index.json", "application/json"},
        {"/api/points/plain.xyz?max=100", "application/vnd.lodkit.mesh"},
        {"/shaders/mesh.vert.glsl", "text/plain; charset=utf-8"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        response r;
        http("GET", cases[i].target, NULL, &r);
        if (r.status != 200) fail_msg("%s: status %d", cases[i].target, r.status);
        const char *type = header(&r, "Content-Type");
        if (!type || strcmp(type, cases[i].type) != 0)
            fail_msg("%s: Content-Type %s, expected %s", cases[i].target, type ? type : "(none)", cases[i].type);
        response_free(&r);
    }
    /* the shader is the C renderer's source, #include not expanded */
    char path[600];
    snprintf(path, sizeof path, "%s/../../src/shaders/mesh.frag.glsl", LK_TEST_DATA_DIR);
    size_t size = 0;
    unsigned char *source = lk_test_read_file(path, &size);
    assert_non_null(source);
    response r;
    http("GET", "/shaders/mesh.frag.glsl", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_size, size);
    assert_memory_equal(r.body, source, size);
    response_free(&r);
    free(source);
    http("GET", "/shaders/missing.glsl", NULL, &r);
    assert_int_equal(r.status, 404);
    response_free(&r);
}

/* ---- gzip and conditional requests ------------------------------------------------ */

static unsigned char *gunzip(const unsigned char *data, size_t size, size_t *out_size)
{
    size_t capacity = 8 * size + 1024;
    unsigned char *out = malloc(capacity);
    assert_non_null(out);
    z_stream z;
    memset(&z, 0, sizeof z);
    assert_int_equal(inflateInit2(&z, 15 + 16), Z_OK);
    z.next_in = (Bytef *)(uintptr_t)data;
    z.avail_in = (uInt)size;
    z.next_out = out;
    z.avail_out = (uInt)capacity;
    int result = inflate(&z, Z_FINISH);
    *out_size = z.total_out;
    inflateEnd(&z);
    assert_int_equal(result, Z_STREAM_END);
    return out;
}

static void test_gzip(void **state)
{
    (void)state;
    size_t cow_size = 0;
    unsigned char *cow = lk_test_read_file(content_path("cow.off"), &cow_size);
    assert_non_null(cow);
    response r;
    http("GET", "/m/cow.off", "Accept-Encoding: gzip, deflate\r\n", &r);
    assert_int_equal(r.status, 200);
    assert_string_equal(header(&r, "Content-Encoding"), "gzip");
    assert_string_equal(header(&r, "Vary"), "Accept-Encoding");
    assert_true(r.body_size < cow_size / 2); /* OFF text compresses well */
    size_t plain_size = 0;
    unsigned char *plain = gunzip(r.body, r.body_size, &plain_size);
    assert_int_equal(plain_size, cow_size);
    assert_memory_equal(plain, cow, cow_size);
    free(plain);
    char gzip_etag[128];
    snprintf(gzip_etag, sizeof gzip_etag, "%s", header(&r, "ETag"));
    response_free(&r);

    /* not accepted: identity */
    const char *refusals[] = {NULL, "Accept-Encoding: identity\r\n", "Accept-Encoding: gzip;q=0\r\n",
                              "Accept-Encoding: br\r\n"};
    for (size_t i = 0; i < 4; i++) {
        http("GET", "/m/cow.off", refusals[i], &r);
        assert_int_equal(r.status, 200);
        assert_null(header(&r, "Content-Encoding"));
        assert_int_equal(r.body_size, cow_size);
        assert_memory_equal(r.body, cow, cow_size);
        assert_string_not_equal(header(&r, "ETag"), gzip_etag); /* another representation */
        response_free(&r);
    }
    /* never with a Range, never for a stream (chunks are deflated already) */
    http("GET", "/m/cow.off", "Accept-Encoding: gzip\r\nRange: bytes=10-29\r\n", &r);
    assert_int_equal(r.status, 206);
    assert_null(header(&r, "Content-Encoding"));
    assert_memory_equal(r.body, cow + 10, 20);
    response_free(&r);
    http("GET", "/m/bunny.lks", "Accept-Encoding: gzip\r\n", &r);
    assert_null(header(&r, "Content-Encoding"));
    assert_int_equal(r.body_size, bunny_stream_size);
    response_free(&r);
    /* the index is JSON: compressed when accepted */
    http("GET", "/api/index.json", "Accept-Encoding: gzip\r\n", &r);
    assert_string_equal(header(&r, "Content-Encoding"), "gzip");
    plain = gunzip(r.body, r.body_size, &plain_size);
    cJSON *json = cJSON_ParseWithLength((const char *)plain, plain_size);
    assert_non_null(json);
    cJSON_Delete(json);
    free(plain);
    response_free(&r);
    free(cow);
}

static void test_etag(void **state)
{
    (void)state;
    response r;
    http("GET", "/m/bunny.lks", NULL, &r);
    char etag[128], condition[200];
    snprintf(etag, sizeof etag, "%s", header(&r, "ETag"));
    assert_true(etag[0] == '"');
    response_free(&r);
    snprintf(condition, sizeof condition, "If-None-Match: %s\r\n", etag);
    http("GET", "/m/bunny.lks", condition, &r);
    assert_int_equal(r.status, 304);
    assert_int_equal(r.body_size, 0);
    assert_string_equal(header(&r, "ETag"), etag);
    response_free(&r);
    snprintf(condition, sizeof condition, "If-None-Match: \"other\", W/%s\r\n", etag);
    http("GET", "/m/bunny.lks", condition, &r);
    assert_int_equal(r.status, 304);
    response_free(&r);
    http("GET", "/m/bunny.lks", "If-None-Match: \"other\"\r\n", &r);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_size, bunny_stream_size);
    response_free(&r);
    /* If-Range with a stale validator: the whole file instead of the range */
    http("GET", "/m/bunny.lks", "Range: bytes=0-9\r\nIf-Range: \"stale\"\r\n", &r);
    assert_int_equal(r.status, 200);
    response_free(&r);
    snprintf(condition, sizeof condition, "Range: bytes=0-9\r\nIf-Range: %s\r\n", etag);
    http("GET", "/m/bunny.lks", condition, &r);
    assert_int_equal(r.status, 206);
    response_free(&r);
    /* the index has a validator too */
    http("GET", "/api/index.json", NULL, &r);
    snprintf(condition, sizeof condition, "If-None-Match: %s\r\n", header(&r, "ETag"));
    response_free(&r);
    http("GET", "/api/index.json", condition, &r);
    assert_int_equal(r.status, 304);
    response_free(&r);
}

/* ---- the index ------------------------------------------------------------------------ */

static const cJSON *find_model(const cJSON *models, const char *name)
{
    const cJSON *model;
    cJSON_ArrayForEach(model, models)
    {
        const cJSON *n = cJSON_GetObjectItemCaseSensitive(model, "name");
        if (cJSON_IsString(n) && strcmp(n->valuestring, name) == 0) return model;
    }
    return NULL;
}

static double number(const cJSON *object, const char *key)
{
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(object, key);
    if (!cJSON_IsNumber(item)) fail_msg("no number \"%s\"", key);
    return item->valuedouble;
}

static const char *string(const cJSON *object, const char *key)
{
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(object, key);
    if (!cJSON_IsString(item)) fail_msg("no string \"%s\"", key);
    return item->valuestring;
}

static void test_index(void **state)
{
    (void)state;
    response r;
    http("GET", "/api/index.json", NULL, &r);
    assert_int_equal(r.status, 200);
    cJSON *json = cJSON_ParseWithLength((const char *)r.body, r.body_size);
    assert_non_null(json);
    const cJSON *models = cJSON_GetObjectItemCaseSensitive(json, "models");
    assert_true(cJSON_IsArray(models));
    /* models only (no notes.txt, no hidden files), sorted by name */
    const char *expected[] = {"broken.obj", "bunny-points.ply",        "bunny.lks", "cow.off",
                              "inside.lks", "jacksboro_fault_dem.npz", "plain.xyz"};
    assert_int_equal(cJSON_GetArraySize(models), 7);
    for (int i = 0; i < 7; i++) assert_string_equal(string(cJSON_GetArrayItem(models, i), "name"), expected[i]);
    assert_null(find_model(models, "leak.txt"));

    const cJSON *bunny = find_model(models, "bunny.lks");
    assert_string_equal(string(bunny, "kind"), "stream");
    assert_string_equal(string(bunny, "url"), "/m/bunny.lks");
    assert_int_equal((size_t)number(bunny, "bytes"), bunny_stream_size);
    assert_int_equal((size_t)number(bunny, "vertices"), 34835);
    assert_int_equal((size_t)number(bunny, "triangles"), 69666);
    assert_int_equal((size_t)number(bunny, "base_vertices"), bunny_pm_counts.base_vertex_count);
    assert_int_equal((size_t)number(bunny, "base_triangles"), bunny_pm_counts.base_triangle_count);
    assert_int_equal((size_t)number(bunny, "splits"), bunny_pm_counts.split_count);
    assert_int_equal((size_t)number(bunny, "chunks"), bunny_info.chunk_count);

    const cJSON *points = find_model(models, "bunny-points.ply");
    assert_string_equal(string(points, "kind"), "points");
    assert_int_equal((size_t)number(points, "points"), 20000);
    assert_string_equal(string(points, "data"), "/api/points/bunny-points.ply");
    assert_string_equal(string(find_model(models, "plain.xyz"), "kind"), "points");

    const cJSON *terrain = find_model(models, "jacksboro_fault_dem.npz");
    assert_string_equal(string(terrain, "kind"), "terrain");
    assert_int_equal((size_t)number(terrain, "width"), 403);
    assert_int_equal((size_t)number(terrain, "height"), 344);
    assert_string_equal(string(terrain, "data"), "/api/terrain/jacksboro_fault_dem.npz");

    const cJSON *cow = find_model(models, "cow.off");
    assert_string_equal(string(cow, "kind"), "mesh");
    assert_int_equal((size_t)number(cow, "vertices"), 2904);
    assert_int_equal((size_t)number(cow, "triangles"), 5804);
    assert_string_equal(string(cow, "stream"), "/m/cow.lks"); /* simplify-on-demand is on */

    const cJSON *broken = find_model(models, "broken.obj");
    assert_string_equal(string(broken, "kind"), "unknown");
    assert_true(strlen(string(broken, "error")) > 0);
    cJSON_Delete(json);
    response_free(&r);

    /* a new file shows up (the cached index is rebuilt), a removed one goes */
    copy_file(lk_test_sample("triceratops.off"), content_path("sub/triceratops.off"));
    http("GET", "/api/index.json", NULL, &r);
    json = cJSON_ParseWithLength((const char *)r.body, r.body_size);
    models = cJSON_GetObjectItemCaseSensitive(json, "models");
    assert_int_equal(cJSON_GetArraySize(models), 8);
    const cJSON *triceratops = find_model(models, "triceratops.off");
    assert_non_null(triceratops);
    assert_string_equal(string(triceratops, "url"), "/m/sub/triceratops.off");
    assert_int_equal((size_t)number(triceratops, "vertices"), 2832);
    cJSON_Delete(json);
    response_free(&r);
    assert_int_equal(unlink(content_path("sub/triceratops.off")), 0);
    http("GET", "/api/index.json", NULL, &r);
    json = cJSON_ParseWithLength((const char *)r.body, r.body_size);
    assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(json, "models")), 7);
    cJSON_Delete(json);
    response_free(&r);
}

/* ---- LKMB buffers ---------------------------------------------------------------------- */

typedef struct lkmb {
    uint32_t vertex_count, triangle_count, flags;
    const float *positions, *normals, *radii;
    const unsigned char *colors;
    const signed char *clips;
    const uint32_t *indices;
} lkmb;

/* Parses and checks the layout (sizes add up exactly, indices in range). */
static void parse_lkmb(const response *r, lkmb *out)
{
    assert_true(r->body_size >= 24);
    assert_memory_equal(r->body, "LKMB", 4);
    uint32_t header[5];
    memcpy(header, r->body + 4, sizeof header); /* little-endian host */
    assert_int_equal(header[0], 1);
    assert_int_equal(header[4], 0);
    out->vertex_count = header[1];
    out->triangle_count = header[2];
    out->flags = header[3];
    size_t v = out->vertex_count, offset = 24;
    out->positions = (const float *)(const void *)(r->body + offset);
    offset += 12 * v;
    out->normals = out->flags & 1 ? (const float *)(const void *)(r->body + offset) : NULL;
    offset += out->flags & 1 ? 12 * v : 0;
    out->colors = out->flags & 2 ? r->body + offset : NULL;
    offset += out->flags & 2 ? 4 * v : 0;
    out->radii = out->flags & 4 ? (const float *)(const void *)(r->body + offset) : NULL;
    offset += out->flags & 4 ? 4 * v : 0;
    out->clips = out->flags & 8 ? (const signed char *)(r->body + offset) : NULL;
    offset += out->flags & 8 ? 4 * v : 0;
    out->indices = (const uint32_t *)(const void *)(r->body + offset);
    offset += 12 * (size_t)out->triangle_count;
    assert_int_equal(offset, r->body_size);
    for (size_t i = 0; i < 3 * (size_t)out->triangle_count; i++) assert_true(out->indices[i] < out->vertex_count);
    for (size_t i = 0; i < 3 * v; i++) assert_true(isfinite(out->positions[i]));
}

/* Points with a clip line; checks each line (a unit direction across the
 * normal, an offset of 0..1 radii) and that it only comes with radii. */
static size_t clipped_points(const lkmb *m)
{
    assert_non_null(m->clips);
    assert_true(m->flags & 4);
    size_t clipped = 0;
    for (size_t i = 0; i < m->vertex_count; i++) {
        const signed char *clip = m->clips + 4 * i;
        if (!clip[0] && !clip[1] && !clip[2]) {
            assert_int_equal(clip[3], 0);
            continue;
        }
        clipped++;
        double x = clip[0] / 127.0, y = clip[1] / 127.0, z = clip[2] / 127.0;
        assert_true(fabs(sqrt(x * x + y * y + z * z) - 1) < 0.02);
        const float *n = m->normals + 3 * i;
        assert_true(fabs(x * n[0] + y * n[1] + z * n[2]) < 0.02);
        assert_true(clip[3] >= 0);
    }
    return clipped;
}

static void test_points_buffer(void **state)
{
    (void)state;
    response r;
    lkmb m;
    http("GET", "/api/points/bunny-points.ply", NULL, &r);
    assert_int_equal(r.status, 200);
    parse_lkmb(&r, &m);
    assert_int_equal(m.vertex_count, 20000);
    assert_int_equal(m.triangle_count, 0);
    assert_true((m.flags & 5) == 5);
    for (size_t i = 0; i < m.vertex_count; i++) {
        assert_true(m.radii[i] > 0 && isfinite(m.radii[i]));
        const float *n = m.normals + 3 * i;
        assert_true(fabs(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) - 1) < 1e-3);
    }
    /* a closed surface: hardly a border point */
    size_t closed_clips = clipped_points(&m);
    printf("bunny-points.ply: %zu of %u points clipped\n", closed_clips, m.vertex_count);
    assert_true(closed_clips < m.vertex_count / 100); /* measured 99 of 20,000 */
    response_free(&r);

    /* subsampled, deterministic */
    http("GET", "/api/points/bunny-points.ply?max=5000", NULL, &r);
    parse_lkmb(&r, &m);
    assert_int_equal(m.vertex_count, 5000);
    response again;
    http("GET", "/api/points/bunny-points.ply?max=5000", NULL, &again);
    assert_int_equal(again.body_size, r.body_size);
    assert_memory_equal(again.body, r.body, r.body_size);
    response_free(&again);
    response_free(&r);

    /* a file without normals or radii gets both estimated */
    http("GET", "/api/points/plain.xyz", NULL, &r);
    assert_int_equal(r.status, 200);
    parse_lkmb(&r, &m);
    assert_int_equal(m.vertex_count, 3000);
    assert_true((m.flags & 5) == 5);
    for (size_t i = 0; i < m.vertex_count; i++) assert_true(m.radii[i] > 0);
    /* 3,000 points spread over the whole (closed) bunny: sparse, so uneven
     * enough for a few false borders, each cut outside its neighbours
     * (lk_points_estimate_clips; borders are tests/unit/test_points.c's) */
    size_t sparse_clips = clipped_points(&m);
    printf("plain.xyz: %zu of %u points clipped\n", sparse_clips, m.vertex_count);
    assert_true(sparse_clips < 100); /* measured 57 */
    response_free(&r);

    http("GET", "/api/points/bunny-points.ply?max=-3", NULL, &r);
    assert_int_equal(r.status, 400);
    assert_json_error(&r);
    response_free(&r);
    http("GET", "/api/points/broken.obj", NULL, &r);
    assert_int_equal(r.status, 500);
    assert_json_error(&r);
    response_free(&r);
    http("GET", "/api/points/nothing.ply", NULL, &r);
    assert_int_equal(r.status, 404);
    response_free(&r);
}

static void test_terrain(void **state)
{
    (void)state;
    response r;
    http("GET", "/api/terrain/jacksboro_fault_dem.npz/info", NULL, &r);
    assert_int_equal(r.status, 200);
    cJSON *info = cJSON_ParseWithLength((const char *)r.body, r.body_size);
    assert_non_null(info);
    assert_int_equal((size_t)number(info, "size"), 513); /* 403 x 344 resampled to 2^9 + 1 */
    double min_height = number(info, "min_height"), max_height = number(info, "max_height");
    assert_true(min_height > 200 && min_height < 300 && max_height > 1000 && max_height < 1100);
    /* geographic grid converted to metres: 3 arc-seconds are about 60-90 m */
    assert_true(number(info, "spacing_y") > 40 && number(info, "spacing_y") < 100);
    const cJSON *center = cJSON_GetObjectItemCaseSensitive(info, "center");
    assert_int_equal(cJSON_GetArraySize(center), 3);
    double cx = cJSON_GetArrayItem(center, 0)->valuedouble, cy = cJSON_GetArrayItem(center, 1)->valuedouble;
    double radius = number(info, "radius");
    assert_true(radius > 10000 && radius < 40000);
    cJSON_Delete(info);
    response_free(&r);

    char target[512];
    snprintf(
        target, sizeof target,
        "/api/terrain/jacksboro_fault_dem.npz?eye=%.1f,%.1f,%.1f&target=%.1f,%.1f,%.1f&fov=60&aspect=1.5&height=720",
        cx, cy - 0.8 * radius, max_height + 3000, cx, cy, min_height);
    http("GET", target, NULL, &r);
    assert_int_equal(r.status, 200);
    assert_string_equal(header(&r, "Content-Type"), "application/vnd.lodkit.mesh");
    lkmb m;
    parse_lkmb(&r, &m);
    assert_true(m.triangle_count > 1000);
    assert_int_equal(m.flags, 2); /* colours */
    const char *stats_text = header(&r, "X-Lodkit-Terrain");
    assert_non_null(stats_text);
    cJSON *stats = cJSON_Parse(stats_text);
    assert_non_null(stats);
    assert_int_equal((size_t)number(stats, "cracks"), 0);
    assert_int_equal((size_t)number(stats, "triangles"), m.triangle_count);
    assert_int_equal((size_t)number(stats, "vertices"), m.vertex_count);
    assert_true(number(stats, "max_level") >= 1);
    cJSON_Delete(stats);
    response_free(&r);

    /* without geomorphing: another cached terrain, still crack-free */
    strcat(target, "&morph=0");
    http("GET", target, NULL, &r);
    assert_int_equal(r.status, 200);
    stats = cJSON_Parse(header(&r, "X-Lodkit-Terrain"));
    assert_int_equal((size_t)number(stats, "cracks"), 0);
    cJSON_Delete(stats);
    response_free(&r);

    const char *bad[] = {"/api/terrain/jacksboro_fault_dem.npz", "/api/terrain/jacksboro_fault_dem.npz?eye=1,2,3",
                         "/api/terrain/jacksboro_fault_dem.npz?eye=1,2,3&target=1,2,3",
                         "/api/terrain/jacksboro_fault_dem.npz?eye=1,2,3&target=4,5,6&fov=200",
                         "/api/terrain/jacksboro_fault_dem.npz/info?c=-1"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        http("GET", bad[i], NULL, &r);
        if (r.status != 400) fail_msg("%s: status %d", bad[i], r.status);
        assert_json_error(&r);
        response_free(&r);
    }
    http("GET", "/api/terrain/cow.off/info", NULL, &r);
    assert_int_equal(r.status, 500);
    assert_json_error(&r);
    response_free(&r);
}

/* ---- simplify on demand ------------------------------------------------------------------ */

static void test_simplify_on_demand(void **state)
{
    (void)state;
    size_t built_before = lk_test_log_count("simplify-on-demand: built cow.lks");
    response first;
    http("GET", "/m/cow.lks", NULL, &first);
    assert_int_equal(first.status, 200);
    assert_string_equal(header(&first, "Content-Type"), "application/vnd.lodkit.stream");
    lk_stream_info info;
    lk_stream_chunk_info *chunks = NULL;
    lk_error error = {0};
    assert_int_equal(lk_stream_inspect(first.body, first.body_size, &info, &chunks, &error), LK_OK);
    lk_free(chunks);
    assert_int_equal(info.vertex_count, 2904);
    assert_int_equal(info.triangle_count, 5804);
    assert_int_equal(lk_test_log_count("simplify-on-demand: built cow.lks"), built_before + 1);

    /* the cache file is the same valid stream */
    char cached[700];
    snprintf(cached, sizeof cached, "%s/cow.lks", cache_dir);
    struct stat st_before, st_after;
    assert_int_equal(stat(cached, &st_before), 0);
    size_t size = 0;
    unsigned char *bytes = lk_test_read_file(cached, &size);
    assert_non_null(bytes);
    assert_int_equal(size, first.body_size);
    assert_memory_equal(bytes, first.body, size);
    assert_int_equal(lk_stream_inspect(bytes, size, &info, &chunks, &error), LK_OK);
    lk_free(chunks);
    free(bytes);

    /* second request: from the cache, not built again; Range works on it */
    response second;
    http("GET", "/m/cow.lks", "Range: bytes=16-47\r\n", &second);
    assert_int_equal(second.status, 206);
    assert_int_equal(second.body_size, 32);
    assert_memory_equal(second.body, first.body + 16, 32);
    assert_int_equal(stat(cached, &st_after), 0);
    assert_true(st_after.st_mtim.tv_sec == st_before.st_mtim.tv_sec &&
                st_after.st_mtim.tv_nsec == st_before.st_mtim.tv_nsec);
    assert_int_equal(lk_test_log_count("simplify-on-demand: built cow.lks"), built_before + 1);
    response_free(&second);
    response_free(&first);

    /* no mesh of that name: 404; a points-only name is not a mesh */
    response r;
    http("GET", "/m/nothing.lks", NULL, &r);
    assert_int_equal(r.status, 404);
    response_free(&r);
    http("GET", "/m/broken.lks", NULL, &r); /* broken.obj does not parse */
    assert_int_equal(r.status, 500);
    assert_json_error(&r);
    response_free(&r);
}

static void test_log_lines(void **state)
{
    (void)state;
    response r;
    http("GET", "/m/bunny.lks", "Range: bytes=0-99\r\n", &r);
    response_free(&r);
    http("GET", "/m/%2e%2e/outside.txt", NULL, &r);
    response_free(&r);
    /* the completion callback runs just after the response: give it a moment */
    for (int i = 0; i < 100 && lk_test_log_count("\"GET /m/%2e%2e/outside.txt\" 403") == 0; i++) lk_test_sleep_ms(10);
    assert_true(lk_test_log_count("127.0.0.1 \"GET /m/bunny.lks\" 206 100 bytes ") >= 1);
    assert_true(lk_test_log_count("127.0.0.1 \"GET /m/%2e%2e/outside.txt\" 403 ") >= 1);
}

/* ---- limits --------------------------------------------------------------------------------- */

static lk_server *start_limited(unsigned max_connections, unsigned timeout)
{
    lk_server_options options;
    lk_server_options_default(&options);
    options.port = 0;
    options.max_connections = max_connections;
    options.timeout_seconds = timeout;
    lk_server *limited = NULL;
    lk_error error = {0};
    if (lk_server_start(content_dir, &options, &limited, &error) != LK_OK) fail_msg("%s", error.message);
    return limited;
}

static void test_connection_limit(void **state)
{
    (void)state;
    lk_server *limited = start_limited(2, 20);
    unsigned limited_port = lk_server_port(limited);
    int idle[2];
    for (int i = 0; i < 2; i++) {
        idle[i] = lk_test_connect(limited_port, NULL, 0, 20);
        assert_true(idle[i] >= 0);
    }
    lk_test_sleep_ms(200); /* let the server accept both */
    /* a third connection is accepted by the kernel but closed by the server unanswered */
    response r;
    http_on(limited_port, "GET", "/m/notes.txt", NULL, &r);
    assert_int_equal(r.status, -1);
    response_free(&r);
    /* one idle client leaves: service resumes */
    close(idle[0]);
    int status = -1;
    for (int attempt = 0; attempt < 50 && status != 200; attempt++) {
        lk_test_sleep_ms(50);
        http_on(limited_port, "GET", "/m/notes.txt", NULL, &r);
        status = r.status;
        response_free(&r);
    }
    assert_int_equal(status, 200);
    close(idle[1]);
    lk_server_stop(limited);
}

static void test_timeout(void **state)
{
    (void)state;
    lk_server *limited = start_limited(8, 1);
    unsigned limited_port = lk_server_port(limited);
    int slow = lk_test_connect(limited_port, NULL, 0, 20);
    assert_true(slow >= 0);
    const char *half = "GET /m/bunny.lks HTTP/1.1\r\nHost: 127.0.0.1\r\nRange: by";
    assert_true(lk_test_send_all(slow, half, strlen(half)));
    double start = lk_test_now();
    /* others are still served meanwhile */
    response r;
    http_on(limited_port, "GET", "/m/notes.txt", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_true(body_contains(&r, "not a model"));
    response_free(&r);
    /* the half request is dropped after the timeout, unanswered */
    char buffer[256];
    ssize_t n = recv(slow, buffer, sizeof buffer, 0);
    double waited = lk_test_now() - start;
    assert_true(n <= 0);
    assert_true(waited > 0.8 && waited < 6.0);
    close(slow);
    http_on(limited_port, "GET", "/m/notes.txt", NULL, &r);
    assert_int_equal(r.status, 200);
    response_free(&r);
    lk_server_stop(limited);
}

static void test_terrain_budget(void **state)
{
    (void)state;
    lk_server_options options;
    lk_server_options_default(&options);
    options.port = 0;
    options.terrain_bytes = 1 << 20; /* a 513^2 terrain needs about 6 MiB */
    lk_server *small = NULL;
    lk_error error = {0};
    assert_int_equal(lk_server_start(content_dir, &options, &small, &error), LK_OK);
    response r;
    http_on(lk_server_port(small), "GET", "/api/terrain/jacksboro_fault_dem.npz/info", NULL, &r);
    assert_int_equal(r.status, 503);
    assert_json_error(&r);
    assert_true(body_contains(&r, "budget"));
    response_free(&r);
    lk_server_stop(small);
}

/* Several clients at once, each checking the bytes it gets: ranges of a
 * file, the index (gzip), point buffers (the memory cache), a terrain's
 * description, views of two cached terrains (each updated under its own
 * lock, both at once) and a stream built on demand (found fresh in the
 * disk cache under the build lock). */
static char terrain_views[2][512]; /* with and without geomorphing: two terrain slots */
static unsigned char *cow_stream;
static size_t cow_stream_size;

typedef struct client_job {
    int index;
    int failures;
    char message[256];
} client_job;

static void *client_thread(void *argument)
{
    client_job *job = argument;
    for (int k = 0; k < 24 && !job->failures; k++) {
        response r;
        int which = (job->index + k) % 6;
        if (which == 0) {
            size_t first = (size_t)(job->index * 7919 + k * 104729) % (bunny_stream_size - 4096);
            char range[64];
            snprintf(range, sizeof range, "Range: bytes=%zu-%zu\r\n", first, first + 4095);
            http("GET", "/m/bunny.lks", range, &r);
            if (r.status != 206 || r.body_size != 4096 || memcmp(r.body, bunny_stream + first, 4096) != 0) {
                job->failures++;
                snprintf(job->message, sizeof job->message, "range at %zu: status %d", first, r.status);
            }
        } else if (which == 1) {
            http("GET", "/api/index.json", "Accept-Encoding: gzip\r\n", &r);
            if (r.status != 200) {
                job->failures++;
                snprintf(job->message, sizeof job->message, "index: status %d", r.status);
            }
        } else if (which == 2) {
            http("GET", "/api/points/bunny-points.ply?max=2000", NULL, &r);
            /* positions, normals, radii, clip lines: 12 + 12 + 4 + 4 bytes a point */
            if (r.status != 200 || r.body_size != 24 + 2000 * 32) {
                job->failures++;
                snprintf(job->message, sizeof job->message, "points: status %d, %zu bytes", r.status, r.body_size);
            }
        } else if (which == 4 && k < 6) { /* a view costs more: one per client, half of them on each slot */
            http("GET", terrain_views[job->index % 2], NULL, &r);
            const char *stats = header(&r, "X-Lodkit-Terrain");
            if (r.status != 200 || !stats || !strstr(stats, "\"cracks\":0,") || r.body_size < 24 ||
                memcmp(r.body, "LKMB", 4) != 0) {
                job->failures++;
                snprintf(job->message, sizeof job->message, "terrain view: status %d, %s", r.status,
                         stats ? stats : "no statistics");
            }
        } else if (which == 5) {
            http("GET", "/m/cow.lks", NULL, &r);
            if (r.status != 200 || r.body_size != cow_stream_size || memcmp(r.body, cow_stream, cow_stream_size) != 0) {
                job->failures++;
                snprintf(job->message, sizeof job->message, "stream on demand: status %d, %zu bytes", r.status,
                         r.body_size);
            }
        } else {
            http("GET", "/api/terrain/jacksboro_fault_dem.npz/info", NULL, &r);
            if (r.status != 200) {
                job->failures++;
                snprintf(job->message, sizeof job->message, "terrain info: status %d", r.status);
            }
        }
        response_free(&r);
    }
    return NULL;
}

static void test_concurrent_clients(void **state)
{
    (void)state;
    enum { CLIENTS = 8 };
    pthread_t threads[CLIENTS];
    client_job jobs[CLIENTS];
    /* Views looking at the whole terrain from above its south edge. */
    response r;
    http("GET", "/api/terrain/jacksboro_fault_dem.npz/info", NULL, &r);
    assert_int_equal(r.status, 200);
    cJSON *info = cJSON_ParseWithLength((const char *)r.body, r.body_size);
    assert_non_null(info);
    const cJSON *center = cJSON_GetObjectItemCaseSensitive(info, "center");
    assert_int_equal(cJSON_GetArraySize(center), 3);
    double cx = cJSON_GetArrayItem(center, 0)->valuedouble, cy = cJSON_GetArrayItem(center, 1)->valuedouble;
    double radius = number(info, "radius"), low = number(info, "min_height"), high = number(info, "max_height");
    for (int morph = 0; morph < 2; morph++)
        snprintf(terrain_views[morph], sizeof terrain_views[morph],
                 "/api/terrain/jacksboro_fault_dem.npz?eye=%.1f,%.1f,%.1f&target=%.1f,%.1f,%.1f&morph=%d", cx,
                 cy - 0.8 * radius, high + 3000, cx, cy, low, morph);
    cJSON_Delete(info);
    response_free(&r);
    /* The stream as the clients must get it (built now if no test built it yet). */
    http("GET", "/m/cow.lks", NULL, &r);
    assert_int_equal(r.status, 200);
    cow_stream = r.body;
    cow_stream_size = r.body_size;
    r.body = NULL;
    response_free(&r);
    for (int i = 0; i < CLIENTS; i++) {
        jobs[i] = (client_job){.index = i};
        assert_int_equal(pthread_create(&threads[i], NULL, client_thread, &jobs[i]), 0);
    }
    for (int i = 0; i < CLIENTS; i++) pthread_join(threads[i], NULL);
    free(cow_stream);
    cow_stream = NULL;
    for (int i = 0; i < CLIENTS; i++)
        if (jobs[i].failures) fail_msg("client %d: %s", i, jobs[i].message);
}

static void test_start_errors(void **state)
{
    (void)state;
    lk_server *other = NULL;
    lk_error error = {0};
    assert_int_equal(lk_server_start(content_path("missing-dir"), NULL, &other, &error), LK_ERR_IO);
    assert_null(other);
    lk_assert_message_contains(error, "missing-dir");
    lk_server_options options;
    lk_server_options_default(&options);
    options.port = port; /* taken by the fixture's server */
    assert_int_equal(lk_server_start(content_dir, &options, &other, &error), LK_ERR_IO);
    assert_null(other);
    options.port = 70000;
    assert_int_equal(lk_server_start(content_dir, &options, &other, &error), LK_ERR_INVALID);
    options.port = 0;
    options.web_dir = content_path("missing-web");
    assert_int_equal(lk_server_start(content_dir, &options, &other, &error), LK_ERR_IO);
    lk_server_stop(NULL);
}

static void test_web_dir(void **state)
{
    (void)state;
    char web[600];
    snprintf(web, sizeof web, "%s/web", lk_test_tmpdir());
    assert_int_equal(mkdir(web, 0755), 0);
    char index_path[700];
    snprintf(index_path, sizeof index_path, "%s/index.html", web);
    lk_test_write_file(index_path, "<!doctype html><title>viewer</title>\n", 37);
    snprintf(index_path, sizeof index_path, "%s/app.js", web);
    lk_test_write_file(index_path, "export const answer = 42;\n", 26);
    lk_server_options options;
    lk_server_options_default(&options);
    options.port = 0;
    options.web_dir = web;
    lk_server *with_web = NULL;
    lk_error error = {0};
    assert_int_equal(lk_server_start(content_dir, &options, &with_web, &error), LK_OK);
    unsigned web_port = lk_server_port(with_web);
    response r;
    http_on(web_port, "GET", "/", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_string_equal(header(&r, "Content-Type"), "text/html; charset=utf-8");
    assert_true(body_contains(&r, "<title>viewer</title>"));
    response_free(&r);
    http_on(web_port, "GET", "/web/app.js", NULL, &r);
    assert_int_equal(r.status, 200);
    assert_string_equal(header(&r, "Content-Type"), "text/javascript; charset=utf-8");
    response_free(&r);
    http_on(web_port, "GET", "/web/../outside.txt", NULL, &r);
    assert_int_equal(r.status, 403);
    assert_false(body_contains(&r, "TOPSECRET"));
    response_free(&r);
    http_on(web_port, "GET", "/web/missing.js", NULL, &r);
    assert_int_equal(r.status, 404);
    response_free(&r);
    lk_server_stop(with_web);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_full_file),
        cmocka_unit_test(test_range),
        cmocka_unit_test(test_not_found_and_traversal),
        cmocka_unit_test(test_head_and_methods),
        cmocka_unit_test(test_content_types),
        cmocka_unit_test(test_gzip),
        cmocka_unit_test(test_etag),
        cmocka_unit_test(test_index),
        cmocka_unit_test(test_points_buffer),
        cmocka_unit_test(test_terrain),
        cmocka_unit_test(test_simplify_on_demand),
        cmocka_unit_test(test_log_lines),
        cmocka_unit_test(test_connection_limit),
        cmocka_unit_test(test_timeout),
        cmocka_unit_test(test_terrain_budget),
        cmocka_unit_test(test_concurrent_clients),
        cmocka_unit_test(test_start_errors),
        cmocka_unit_test(test_web_dir),
    };
    return cmocka_run_group_tests(tests, setup_content, teardown_content);
}
