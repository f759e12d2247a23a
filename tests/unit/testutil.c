#define _XOPEN_SOURCE 700 /* nftw */
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
