/* SPDX-License-Identifier: MIT */
/* How lodkit opens the files it reads (lk__open_input, lk__read_opened in
 * src/util.c; issue 17): only regular files are read, whatever the readers
 * are given:
 *   - a FIFO (no writer), a socket, a directory, a character device
 *     (/dev/zero, /dev/urandom, directly or through a link), a symlink loop
 *     are refused at once with a message naming the file and what it is:
 *     never a reader blocked in open() or reading forever;
 *   - below a folder (glTF external buffers), no symbolic link is
 *     followed, neither a linked file nor a linked directory on the way,
 *     so a model's buffer can never be a file outside its folder; ".."
 *     and absolute paths are refused too;
 *   - a file that shrinks, grows or is rewritten while it is read gives a
 *     "read error", never a mix of versions or a short buffer;
 *   - every reader goes through them: meshes, animations, Acclaim files,
 *     our own grid formats, and GDAL (checked first, restricted to
 *     single-file drivers: a VRT, which can name any file, is refused).
 * FIFOs, sockets and links are made here at run time. An alarm turns a
 * regression into a failure instead of a hang. */
#define _GNU_SOURCE /* memmem */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/time.h>
#include <sys/types.h>
#include <unistd.h>

#include "internal.h"
#include "testutil.h"

static char dir[512];     /* the model's folder */
static char outside[512]; /* a folder next to it, holding the secret */

static const char *in_dir(const char *name) { return lk_test_path(dir, name); }

/* Any call of lodkit that blocks ends the test program after 20 s. */
static void arm_alarm(void) { alarm(20); }

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "%s/model", lk_test_tmpdir());
    snprintf(outside, sizeof outside, "%s/outside", lk_test_tmpdir());
    if (mkdir(dir, 0755) != 0 || mkdir(outside, 0755) != 0) return -1;
    if (mkdir(in_dir("sub"), 0755) != 0 || mkdir(in_dir("dir.obj"), 0755) != 0) return -1;
    lk_test_write_file(lk_test_path(outside, "secret36.bin"), lk_test_secret_floats(), 36);
    lk_test_write_file(in_dir("inside36.bin"), lk_test_secret_floats(), 36);
    lk_test_write_file(in_dir("sub/inside36.bin"), lk_test_secret_floats(), 36);
    lk_test_write_file(in_dir("plain.txt"), "not a directory\n", 16);
    if (mkfifo(in_dir("fifo.bin"), 0644) != 0 || mkfifo(in_dir("fifo.obj"), 0644) != 0) return -1;
    if (mkfifo(in_dir("sub/fifo.bin"), 0644) != 0) return -1;
    lk_test_make_socket(in_dir("socket.bin"));
    if (symlink(outside, in_dir("link_out")) != 0) return -1;
    if (symlink(lk_test_path(outside, "secret36.bin"), in_dir("secret-link.bin")) != 0) return -1;
    if (symlink("inside36.bin", in_dir("inside-link.bin")) != 0) return -1;
    if (symlink("/dev/zero", in_dir("zero.bin")) != 0 || symlink("/dev/zero", in_dir("zero.obj")) != 0) return -1;
    if (symlink("loop2.bin", in_dir("loop1.bin")) != 0 || symlink("loop1.bin", in_dir("loop2.bin")) != 0) return -1;
    arm_alarm();
    return 0;
}

/* ---- lk__open_input ---------------------------------------------------------------- */

static void expect_model_refused(const char *model, const char *uri, const char *needle);

/* Opening `path` (under `folder` when not NULL) is refused at once, with
 * a message naming the path and containing `needle`, and errno as given. */
static void expect_refused(const char *folder, const char *path, const char *needle, int expected_errno)
{
    int fd = 12345;
    lk_error error = {0};
    errno = 0;
    lk_status status = lk__open_input(folder, path, &fd, NULL, &error);
    int saved = errno;
    if (status != LK_ERR_IO) fail_msg("%s: opened (status %d)", path, status);
    assert_int_equal(fd, -1);
    lk_assert_message_contains(error, path);
    lk_assert_message_contains(error, needle);
    if (expected_errno && saved != expected_errno)
        fail_msg("%s: errno %d (%s), expected %d", path, saved, strerror(saved), expected_errno);
}

static void expect_opened(const char *folder, const char *path, size_t size)
{
    int fd = -1;
    struct stat info;
    lk_error error = {0};
    if (lk__open_input(folder, path, &fd, &info, &error) != LK_OK) fail_msg("%s: %s", path, error.message);
    assert_true(fd >= 0);
    assert_int_equal((size_t)info.st_size, size);
    assert_int_equal(fcntl(fd, F_GETFL) & O_NONBLOCK, 0); /* reads block again */
    assert_true(fcntl(fd, F_GETFD) & FD_CLOEXEC);
    close(fd);
}

static void test_open_kinds(void **state)
{
    (void)state;
    /* regular files, also through a link, open */
    expect_opened(NULL, in_dir("inside36.bin"), 36);
    expect_opened(NULL, in_dir("inside-link.bin"), 36);
    /* everything else is refused before a read could block or never end */
    expect_refused(NULL, in_dir("fifo.bin"), "is a FIFO, not a regular file", EPERM);
    expect_refused(NULL, in_dir("socket.bin"), "is a socket, not a regular file", EPERM);
    expect_refused(NULL, in_dir("sub"), "is a directory, not a regular file", EISDIR);
    expect_refused(NULL, in_dir("dir.obj"), "is a directory", EISDIR);
    expect_refused(NULL, "/dev/zero", "is a character device, not a regular file", EPERM);
    expect_refused(NULL, "/dev/urandom", "is a character device", EPERM);
    expect_refused(NULL, in_dir("zero.bin"), "is a character device", EPERM);
    expect_refused(NULL, in_dir("loop1.bin"), "cannot open: Too many levels of symbolic links", ELOOP);
    expect_refused(NULL, in_dir("missing.bin"), "cannot open: No such file or directory", ENOENT);
    /* a device node in the folder itself (creating one needs root) */
    if (mknod(in_dir("null.bin"), S_IFCHR | 0644, makedev(1, 3)) == 0) {
        expect_refused(NULL, in_dir("null.bin"), "is a character device, not a regular file", EPERM);
        expect_refused(dir, "null.bin", "is a character device, not a regular file", EPERM);
        expect_model_refused("null.gltf", "null.bin", "buffers[0].uri: \"null.bin\": is a character device");
    } else {
        printf("  mknod: %s; a device node in the folder is not tried (links to /dev/zero are)\n", strerror(errno));
    }
}

static void test_open_below_folder(void **state)
{
    (void)state;
    expect_opened(dir, "inside36.bin", 36);
    expect_opened(dir, "sub/inside36.bin", 36);
    expect_opened(dir, "./sub//inside36.bin", 36);
    /* no link is followed below the folder: to a file or a directory
     * outside, nor even one inside */
    expect_refused(dir, "link_out/secret36.bin", "\"link_out\" is a symbolic link (not followed)", ELOOP);
    expect_refused(dir, "secret-link.bin", "is a symbolic link (not followed)", ELOOP);
    expect_refused(dir, "inside-link.bin", "is a symbolic link", ELOOP);
    expect_refused(dir, "zero.bin", "is a symbolic link", ELOOP);
    expect_refused(dir, "loop1.bin", "is a symbolic link", ELOOP);
    /* nor does the path leave the folder */
    expect_refused(dir, "../outside/secret36.bin", "\"..\" leaves the folder", EPERM);
    expect_refused(dir, "sub/../../outside/secret36.bin", "\"..\" leaves the folder", EPERM);
    expect_refused(dir, "/etc/hostname", "not a relative path inside the folder", EPERM);
    /* and the kinds are refused as without a folder */
    expect_refused(dir, "fifo.bin", "is a FIFO, not a regular file", EPERM);
    expect_refused(dir, "sub/fifo.bin", "is a FIFO", EPERM);
    expect_refused(dir, "socket.bin", "is a socket", EPERM);
    expect_refused(dir, "sub", "is a directory", EISDIR);
    expect_refused(dir, "plain.txt/x.bin", "\"plain.txt\" is a regular file, not a directory", ENOTDIR);
    expect_refused(dir, "fifo.bin/x.bin", "\"fifo.bin\" is a FIFO, not a directory", ENOTDIR);
    expect_refused(dir, "sub/missing.bin", "cannot open: No such file or directory", ENOENT);
}

/* ---- files changing under the read -------------------------------------------------------- */

static void test_read_changes(void **state)
{
    (void)state;
    const char *path = in_dir("changing.bin");
    unsigned char bytes[4096];
    for (size_t i = 0; i < sizeof bytes; i++) bytes[i] = (unsigned char)(i * 7);
    static const char *const changes[] = {"truncated", "grown", "rewritten", "unchanged"};
    for (int change = 0; change < 4; change++) {
        lk_test_write_file(path, bytes, sizeof bytes);
        int fd;
        struct stat info;
        lk_error error = {0};
        assert_int_equal(lk__open_input(NULL, path, &fd, &info, &error), LK_OK);
        /* between the fstat and the read */
        if (change == 0) assert_int_equal(truncate(path, 1000), 0);
        if (change == 1) {
            FILE *file = fopen(path, "ab");
            assert_non_null(file);
            assert_int_equal(fwrite("more", 1, 4, file), 4);
            assert_int_equal(fclose(file), 0);
        }
        if (change == 2) { /* same size, another modification time */
            struct timespec times[2] = {{0, UTIME_OMIT}, {1000000000, 0}};
            assert_int_equal(utimensat(AT_FDCWD, path, times, 0), 0);
        }
        char *data = NULL;
        size_t size = 0;
        lk_status status = lk__read_opened(fd, &info, "changing.bin", 0, &data, &size, &error);
        close(fd);
        printf("  %s: %s\n", changes[change], status == LK_OK ? "read" : error.message);
        if (change < 3) {
            assert_int_equal(status, LK_ERR_IO);
            assert_null(data);
            lk_assert_message_contains(error, "changing.bin: read error: the file changed while it was read");
        } else {
            assert_int_equal(status, LK_OK);
            assert_int_equal(size, sizeof bytes);
            assert_memory_equal(data, bytes, sizeof bytes);
            free(data);
        }
    }
    /* over the budget: refused before anything is read */
    char *data = NULL;
    size_t size = 0;
    lk_error error = {0};
    assert_int_equal(lk__read_file(path, 100, &data, &size, &error), LK_ERR_LIMIT);
    lk_assert_message_contains(error,
                               "changing.bin: the file has 4096 bytes, more than the memory budget of 100 bytes");
    assert_null(data);
}

/* ---- glTF external buffers ------------------------------------------------------------- */

static void expect_model_refused(const char *model, const char *uri, const char *needle)
{
    lk_test_write_gltf_triangle(in_dir(model), uri);
    lk_mesh mesh;
    lk_error error = {0};
    lk_status status = lk_mesh_read(in_dir(model), LK_FORMAT_AUTO, NULL, &mesh, &error);
    if (status == LK_OK) {
        bool secret = memmem(mesh.positions, 36, lk_test_secret_floats(), 36) != NULL;
        lk_mesh_free(&mesh);
        fail_msg("%s (buffer %s) was read%s", model, uri, secret ? ", with the secret bytes" : "");
    }
    assert_int_equal(status, LK_ERR_IO);
    assert_int_equal(mesh.vertex_count, 0);
    lk_assert_message_contains(error, in_dir(model));
    lk_assert_message_contains(error, needle);
}

static void test_gltf_external_buffers(void **state)
{
    (void)state;
    /* the control: the same 36 bytes inside the folder are the triangle */
    lk_test_write_gltf_triangle(in_dir("control.gltf"), "sub/inside36.bin");
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read(in_dir("control.gltf"), LK_FORMAT_AUTO, NULL, &mesh, &error), LK_OK);
    assert_int_equal(mesh.vertex_count, 3);
    assert_memory_equal(mesh.positions, lk_test_secret_floats(), 36);
    lk_mesh_free(&mesh);

    static const char rule[] = "; external files must be regular files inside the model's folder";
    char needle[300];
    snprintf(needle, sizeof needle,
             "buffers[0].uri: \"link_out/secret36.bin\": \"link_out\" is a symbolic link "
             "(not followed)%s",
             rule);
    expect_model_refused("dir-link.gltf", "link_out/secret36.bin", needle);
    snprintf(needle, sizeof needle, "buffers[0].uri: \"secret-link.bin\": is a symbolic link (not followed)%s", rule);
    expect_model_refused("file-link.gltf", "secret-link.bin", needle);
    expect_model_refused("escaped-link.gltf", "link%5fout/secret36.bin", "\"link_out\" is a symbolic link");
    snprintf(needle, sizeof needle, "buffers[0].uri: \"fifo.bin\": is a FIFO, not a regular file%s", rule);
    expect_model_refused("fifo.gltf", "fifo.bin", needle);
    expect_model_refused("sub-fifo.gltf", "sub/fifo.bin", "\"sub/fifo.bin\": is a FIFO");
    expect_model_refused("socket.gltf", "socket.bin", "\"socket.bin\": is a socket, not a regular file");
    expect_model_refused("directory.gltf", "sub", "\"sub\": is a directory, not a regular file");
    expect_model_refused("zero.gltf", "zero.bin", "\"zero.bin\": is a symbolic link");
    expect_model_refused("loop.gltf", "loop1.bin", "\"loop1.bin\": is a symbolic link");
    expect_model_refused("not-dir.gltf", "plain.txt/x.bin", "\"plain.txt\" is a regular file, not a directory");
    expect_model_refused("missing.gltf", "sub/none.bin", "buffers[0].uri: cannot open \"sub/none.bin\"");
}

/* ---- every reader ------------------------------------------------------------------------- */

static void test_readers_refuse_non_files(void **state)
{
    (void)state;
    static const char *const names[] = {"fifo.obj", "zero.obj", "dir.obj"};
    static const char *const kinds[] = {"is a FIFO", "is a character device", "is a directory"};
    static const char *const extensions[] = {"obj", "md2", "pgm", "tif", "asf", "lks"};
    for (size_t n = 0; n < 3; n++) {
        for (size_t e = 0; e < sizeof extensions / sizeof extensions[0]; e++) {
            /* the same non-file under every reader's extension */
            char name[64];
            snprintf(name, sizeof name, "%.*s.%s", (int)(strlen(names[n]) - 4), names[n], extensions[e]);
            const char *path = in_dir(name);
            if (strcmp(name, names[n]) != 0) {
                char target[600];
                snprintf(target, sizeof target, "%s", in_dir(names[n]));
                unlink(path);
                rmdir(path);
                assert_int_equal(symlink(target, path), 0);
            }
            lk_error error = {0};
            lk_status status;
            if (e == 0) {
                lk_mesh mesh;
                status = lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &mesh, &error);
            } else if (e == 1) {
                lk_animation animation;
                status = lk_animation_read(path, &animation, &error);
            } else if (e == 2 || e == 3) {
                lk_heightfield field;
                status = lk_dem_read(path, NULL, &field, &error);
            } else if (e == 4) {
                lk_skeleton skeleton;
                status = lk_skeleton_read(path, &skeleton, &error);
            } else {
                char *data = NULL;
                size_t size = 0;
                status = lk__read_file(path, 0, &data, &size, &error);
            }
            if (status != LK_ERR_IO) fail_msg("%s: status %d (%s)", name, status, error.message);
            lk_assert_message_contains(error, kinds[n]);
            lk_assert_message_contains(error, name);
        }
    }
}

/* ---- GDAL ------------------------------------------------------------------------------ */

static void test_gdal_single_files(void **state)
{
    (void)state;
    /* an ASCII grid outside the folder, read directly: GDAL's AAIGrid */
    const char *grid = "ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 10\n"
                       "1234 1235 1236\n1237 1238 1239\n1240 1241 1242\n";
    char secret_grid[600];
    snprintf(secret_grid, sizeof secret_grid, "%s/secret.asc", outside);
    lk_test_write_file(secret_grid, grid, strlen(grid));
    lk_heightfield field;
    lk_error error = {0};
    assert_int_equal(lk_dem_read(secret_grid, NULL, &field, &error), LK_OK);
    assert_int_equal(field.width, 3);
    assert_float_equal(field.max_height, 1242, 0);
    lk_heightfield_free(&field);

    /* a VRT in the folder naming it: GDAL would read it (the heights
     * 1234..1242 of a file outside); it is refused */
    char vrt[2048];
    snprintf(vrt, sizeof vrt,
             "<VRTDataset rasterXSize=\"3\" rasterYSize=\"3\">\n"
             "  <VRTRasterBand dataType=\"Float32\" band=\"1\">\n"
             "    <SimpleSource>\n"
             "      <SourceFilename relativeToVRT=\"0\">%s</SourceFilename>\n"
             "      <SourceBand>1</SourceBand>\n"
             "    </SimpleSource>\n"
             "  </VRTRasterBand>\n"
             "</VRTDataset>\n",
             secret_grid);
    static const char *const names[] = {"grid.vrt", "grid.tif"}; /* the content decides, not the name */
    for (int i = 0; i < 2; i++) {
        lk_test_write_file(in_dir(names[i]), vrt, strlen(vrt));
        lk_status status = lk_dem_read(in_dir(names[i]), NULL, &field, &error);
        if (status == LK_OK) {
            double highest = field.max_height;
            lk_heightfield_free(&field);
            fail_msg("%s was read (max height %g)", names[i], highest);
        }
        assert_int_equal(status, LK_ERR_UNSUPPORTED);
        lk_assert_message_contains(error, names[i]);
        lk_assert_message_contains(error, "(GDAL driver VRT), whose data can lie in other files");
        assert_null(strstr(error.message, secret_grid));
    }
    /* GDAL's virtual file systems cannot be checked: refused */
    char vsi[700];
    snprintf(vsi, sizeof vsi, "/vsigzip/%s", secret_grid);
    assert_int_equal(lk_dem_read(vsi, NULL, &field, &error), LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "GDAL virtual file systems (/vsi...) are not read");
    /* the subdataset syntax checks its file like any input */
    char subdataset[700];
    snprintf(subdataset, sizeof subdataset, "NETCDF:\"%s\":z", in_dir("fifo.bin"));
    assert_int_equal(lk_dem_read(subdataset, NULL, &field, &error), LK_ERR_IO);
    lk_assert_message_contains(error, "fifo.bin: is a FIFO, not a regular file");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_open_kinds),
        cmocka_unit_test(test_open_below_folder),
        cmocka_unit_test(test_read_changes),
        cmocka_unit_test(test_gltf_external_buffers),
        cmocka_unit_test(test_readers_refuse_non_files),
        cmocka_unit_test(test_gdal_single_files),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
