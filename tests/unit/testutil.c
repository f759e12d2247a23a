#define _XOPEN_SOURCE 700 /* nftw */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <ftw.h>
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
    if (access(path, R_OK) != 0)
        fail_msg("sample %s missing: run scripts/fetch-samples.sh", path);
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

void lk_test_load(const char *path, lk_mesh *mesh)
{
    lk_error error = {0};
    lk_mesh_init(mesh);
    if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, mesh, &error) != LK_OK)
        fail_msg("loading %s failed: %s", path, error.message);
}

lk_status lk_test_read_string(const char *text, const char *name, lk_format format, lk_mesh *mesh,
                              lk_error *error)
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
    if (lk_mesh_alloc(mesh, (size_t)(n + 1) * (n + 1), 2 * (size_t)n * n, 0, NULL) != LK_OK)
        fail_msg("out of memory");
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
