/* SPDX-License-Identifier: MIT */
#define _XOPEN_SOURCE 700 /* nftw */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <arpa/inet.h>
#include <errno.h>
#include <ftw.h>
#include <netinet/in.h>
#include <pthread.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include "testutil.h"

static char slots[4][4096];
static int next_slot;

static const char *format_path(const char *a, const char *b)
{
    char *slot = slots[next_slot];
    next_slot = (next_slot + 1) % 4;
    snprintf(slot, sizeof slots[0], "%s/%s", a, b);
    return slot;
}

const char *lk_test_sample(const char *name)
{
    const char *path = format_path(LK_SAMPLES_DIR, name);
    if (access(path, R_OK) != 0) fail_msg("sample %s missing: run scripts/fetch-samples.sh", path);
    return path;
}

const char *lk_test_data(const char *name) { return format_path(LK_TEST_DATA_DIR, name); }

static char tmpdir[256];

static int remove_entry(const char *path, const struct stat *info, int type, struct FTW *walk)
{
    (void)info, (void)type, (void)walk;
    return remove(path);
}

static void remove_tmpdir(void)
{
    if (tmpdir[0]) nftw(tmpdir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

const char *lk_test_tmpdir(void)
{
    if (!tmpdir[0]) {
        snprintf(tmpdir, sizeof tmpdir, "/tmp/lodkit-test-XXXXXX");
        if (!mkdtemp(tmpdir)) fail_msg("cannot create temporary directory");
        atexit(remove_tmpdir);
    }
    return tmpdir;
}

const char *lk_test_tmpfile(const char *name) { return format_path(lk_test_tmpdir(), name); }

const char *lk_test_path(const char *directory, const char *name) { return format_path(directory, name); }

unsigned char *lk_test_read_file(const char *path, size_t *size)
{
    FILE *file = fopen(path, "rb");
    if (!file) fail_msg("cannot open %s", path);
    fseek(file, 0, SEEK_END);
    long length = ftell(file);
    fseek(file, 0, SEEK_SET);
    if (length < 0) fail_msg("cannot size %s", path);
    unsigned char *data = malloc((size_t)length + 1);
    assert_non_null(data);
    assert_int_equal(fread(data, 1, (size_t)length, file), (size_t)length);
    fclose(file);
    *size = (size_t)length;
    return data;
}

void lk_test_base64(const unsigned char *bytes, size_t size, char *out)
{
    static const char alphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    size_t o = 0;
    for (size_t i = 0; i < size; i += 3) {
        uint32_t group = (uint32_t)bytes[i] << 16;
        if (i + 1 < size) group |= (uint32_t)bytes[i + 1] << 8;
        if (i + 2 < size) group |= bytes[i + 2];
        out[o++] = alphabet[(group >> 18) & 63];
        out[o++] = alphabet[(group >> 12) & 63];
        out[o++] = i + 1 < size ? alphabet[(group >> 6) & 63] : '=';
        out[o++] = i + 2 < size ? alphabet[group & 63] : '=';
    }
    out[o] = '\0';
}

void lk_test_write_gltf_triangle(const char *path, const char *uri)
{
    char json[1024];
    int length = snprintf(json, sizeof json,
                          "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"uri\":\"%s\",\"byteLength\":36}],"
                          "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
                          "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}],"
                          "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],"
                          "\"nodes\":[{\"mesh\":0}],\"scenes\":[{\"nodes\":[0]}],\"scene\":0}",
                          uri);
    if (length <= 0 || (size_t)length >= sizeof json) fail_msg("uri too long: %s", uri);
    lk_test_write_file(path, json, (size_t)length);
}

const unsigned char *lk_test_secret_floats(void)
{
    static float values[9] = {1234.5678f, -8765.4321f, 31415.927f,  2718.2818f, -1414.2136f,
                              1732.0508f, 2236.0679f,  -2645.7513f, 3162.2776f};
    return (const unsigned char *)values;
}

void lk_test_make_socket(const char *path)
{
    struct sockaddr_un address;
    memset(&address, 0, sizeof address);
    address.sun_family = AF_UNIX;
    if (strlen(path) >= sizeof address.sun_path) fail_msg("socket path too long: %s", path);
    strcpy(address.sun_path, path);
    int fd = socket(AF_UNIX, SOCK_STREAM, 0);
    if (fd < 0 || bind(fd, (struct sockaddr *)&address, sizeof address) != 0)
        fail_msg("cannot make the socket %s: %s", path, strerror(errno));
    close(fd); /* the socket file stays */
}

void lk_test_load(const char *path, lk_mesh *mesh)
{
    lk_error error = {0};
    lk_mesh_init(mesh);
    if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, mesh, &error) != LK_OK)
        fail_msg("loading %s failed: %s", path, error.message);
}

lk_status lk_test_read_string(const char *text, const char *name, lk_format format, lk_mesh *mesh, lk_error *error)
{
    lk_error_clear(error);
    lk_mesh_init(mesh);
    return lk_mesh_read_memory(text, strlen(text), name, format, NULL, mesh, error);
}

void lk_test_make_mesh(lk_mesh *mesh, const float *positions, size_t vertex_count, const uint32_t *indices,
                       size_t triangle_count)
{
    lk_error error = {0};
    if (lk_mesh_alloc(mesh, vertex_count, triangle_count, 0, &error) != LK_OK) fail_msg("%s", error.message);
    if (vertex_count) memcpy(mesh->positions, positions, vertex_count * 3 * sizeof(float));
    if (triangle_count) memcpy(mesh->indices, indices, triangle_count * 3 * sizeof(uint32_t));
}

void lk_test_make_cube(lk_mesh *mesh)
{
    static const float positions[24] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    static const uint32_t indices[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                         1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    lk_test_make_mesh(mesh, positions, 8, indices, 12);
}

void lk_test_make_torus(lk_mesh *mesh, uint32_t n, uint32_t m)
{
    if (lk_mesh_alloc(mesh, (size_t)n * m, 2 * (size_t)n * m, 0, NULL) != LK_OK) fail_msg("out of memory");
    for (uint32_t i = 0; i < n; i++) {
        for (uint32_t j = 0; j < m; j++) {
            double u = 2 * 3.14159265358979 * i / n, v = 2 * 3.14159265358979 * j / m;
            float *p = mesh->positions + 3 * (i * m + j);
            p[0] = (float)((2 + cos(v)) * cos(u));
            p[1] = (float)((2 + cos(v)) * sin(u));
            p[2] = (float)sin(v);
            uint32_t a = i * m + j, b = ((i + 1) % n) * m + j, c = ((i + 1) % n) * m + (j + 1) % m,
                     d = i * m + (j + 1) % m;
            uint32_t *t = mesh->indices + 6 * (i * m + j);
            t[0] = a, t[1] = b, t[2] = c, t[3] = a, t[4] = c, t[5] = d;
        }
    }
}

void lk_test_make_grid(lk_mesh *mesh, uint32_t n)
{
    if (lk_mesh_alloc(mesh, (size_t)(n + 1) * (n + 1), 2 * (size_t)n * n, 0, NULL) != LK_OK) fail_msg("out of memory");
    for (uint32_t i = 0; i <= n; i++)
        for (uint32_t j = 0; j <= n; j++) {
            float *p = mesh->positions + 3 * (i * (n + 1) + j);
            p[0] = (float)j, p[1] = (float)i, p[2] = 0;
        }
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t j = 0; j < n; j++) {
            uint32_t a = i * (n + 1) + j, b = a + 1, c = a + n + 2, d = a + n + 1;
            uint32_t *t = mesh->indices + 6 * (i * n + j);
            t[0] = a, t[1] = b, t[2] = c, t[3] = a, t[4] = c, t[5] = d;
        }
}

void lk_test_write_file(const char *path, const void *bytes, size_t size)
{
    FILE *file = fopen(path, "wb");
    int ok = file && fwrite(bytes, 1, size, file) == size;
    if (file && fclose(file) != 0) ok = 0;
    if (!ok) fail_msg("cannot write %s", path);
}

double lk_test_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

void lk_test_sleep_ms(long milliseconds)
{
    struct timespec t = {milliseconds / 1000, (milliseconds % 1000) * 1000000L};
    nanosleep(&t, NULL);
}

static pthread_mutex_t log_lock = PTHREAD_MUTEX_INITIALIZER;
static char log_text[1 << 16];
static size_t log_length;

void lk_test_log_line(void *user, const char *line)
{
    (void)user;
    pthread_mutex_lock(&log_lock);
    size_t length = strlen(line);
    if (log_length + length + 2 < sizeof log_text) {
        memcpy(log_text + log_length, line, length);
        log_length += length;
        log_text[log_length++] = '\n';
        log_text[log_length] = '\0';
    }
    pthread_mutex_unlock(&log_lock);
}

size_t lk_test_log_count(const char *needle)
{
    pthread_mutex_lock(&log_lock);
    size_t count = 0;
    for (const char *p = log_text; (p = strstr(p, needle)); p++) count++;
    pthread_mutex_unlock(&log_lock);
    return count;
}

int lk_test_connect(unsigned port, const char *source, int receive_buffer, int receive_timeout_seconds)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    struct timeval send_timeout = {10, 0}, receive_timeout = {receive_timeout_seconds, 0};
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &send_timeout, sizeof send_timeout);
    if (receive_timeout_seconds > 0) setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &receive_timeout, sizeof receive_timeout);
    if (receive_buffer) setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
    struct sockaddr_in address;
    if (source) {
        memset(&address, 0, sizeof address);
        address.sin_family = AF_INET;
        inet_pton(AF_INET, source, &address.sin_addr);
        if (bind(fd, (struct sockaddr *)&address, sizeof address) != 0) {
            close(fd);
            return -2;
        }
    }
    memset(&address, 0, sizeof address);
    address.sin_family = AF_INET;
    address.sin_port = htons((uint16_t)port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, (struct sockaddr *)&address, sizeof address) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

_Bool lk_test_send_all(int fd, const void *bytes, size_t length)
{
    const char *p = bytes;
    while (length) {
        ssize_t sent = send(fd, p, length, MSG_NOSIGNAL);
        if (sent < 0 && errno == EINTR) continue;
        if (sent <= 0) return 0;
        p += sent;
        length -= (size_t)sent;
    }
    return 1;
}

const char *lk_test_http_header(const char *head, size_t length, const char *name)
{
    static _Thread_local char value[1024]; /* one per thread: the server tests' clients run at once */
    size_t name_length = strlen(name);
    const char *end = head + length;
    const char *line = strstr(head, "\r\n");
    while (line && line + 2 < end) {
        line += 2;
        if (strncasecmp(line, name, name_length) == 0 && line[name_length] == ':') {
            const char *v = line + name_length + 1;
            while (*v == ' ') v++;
            size_t value_length = strcspn(v, "\r\n");
            if (value_length >= sizeof value) value_length = sizeof value - 1;
            memcpy(value, v, value_length);
            value[value_length] = '\0';
            return value;
        }
        line = strstr(line, "\r\n");
    }
    return NULL;
}

static int compare_triangles(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int i = 0; i < 3; i++)
        if (x[i] != y[i]) return x[i] < y[i] ? -1 : 1;
    return 0;
}

uint32_t *lk_test_canonical_triangles(const uint32_t *indices, size_t triangle_count, const uint32_t *map)
{
    uint32_t *out = malloc((triangle_count ? triangle_count : 1) * 3 * sizeof(uint32_t));
    assert_non_null(out);
    for (size_t t = 0; t < triangle_count; t++) {
        uint32_t v[3];
        for (int k = 0; k < 3; k++) v[k] = map ? map[indices[3 * t + k]] : indices[3 * t + k];
        int first = v[0] <= v[1] && v[0] <= v[2] ? 0 : v[1] <= v[2] ? 1 : 2;
        for (int k = 0; k < 3; k++) out[3 * t + k] = v[(first + k) % 3];
    }
    qsort(out, triangle_count, 3 * sizeof(uint32_t), compare_triangles);
    return out;
}

lk_stream_decoder *lk_test_stream_decoder(size_t max_level)
{
    lk_stream_decoder *decoder = NULL;
    lk_error error = {0};
    if (lk_stream_decoder_create(max_level, &decoder, &error) != LK_OK) fail_msg("create: %s", error.message);
    return decoder;
}

void lk_test_stream_mesh(const lk_stream_decoder *decoder, lk_mesh *mesh)
{
    lk_error error = {0};
    if (lk_stream_decoder_mesh(decoder, mesh, &error) != LK_OK) fail_msg("decoder mesh: %s", error.message);
}
