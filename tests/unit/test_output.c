/* SPDX-License-Identifier: MIT */
/* The public file helpers (src/output.c): lk_output_open/stream/commit/abort
 * write a file whole or not at all, lk_output_folder_create makes the
 * hidden folder a whole-folder output is built in, lk_file_read reads a
 * regular file within a budget. */
#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <signal.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "testutil.h"

/* Entries of the test's folder whose name starts with `prefix`. */
static size_t entries_starting(const char *directory, const char *prefix)
{
    DIR *dir = opendir(directory);
    assert_non_null(dir);
    size_t count = 0;
    for (struct dirent *entry; (entry = readdir(dir));) count += strncmp(entry->d_name, prefix, strlen(prefix)) == 0;
    closedir(dir);
    return count;
}

static void test_output_commit_and_abort(void **state)
{
    (void)state;
    char path[4096];
    snprintf(path, sizeof path, "%s", lk_test_tmpfile("table.csv"));
    lk_test_write_file(path, "old\n", 4);
    lk_output *output;
    lk_error error = {0};
    /* abort: the path keeps what it held, no temporary file is left */
    assert_int_equal(lk_output_open(path, &output, &error), LK_OK);
    fputs("half a table", lk_output_stream(output));
    lk_output_abort(output);
    size_t size;
    unsigned char *bytes = lk_test_read_file(path, &size);
    assert_int_equal(size, 4);
    assert_memory_equal(bytes, "old\n", 4);
    free(bytes);
    assert_int_equal(entries_starting(lk_test_tmpdir(), ".table.csv."), 0);
    lk_output_abort(NULL);
    /* commit: the new bytes replace the old ones */
    assert_int_equal(lk_output_open(path, &output, &error), LK_OK);
    assert_int_equal(entries_starting(lk_test_tmpdir(), ".table.csv.tmp-"), 1); /* hidden, beside it */
    fprintf(lk_output_stream(output), "a,b\n%d,%d\n", 1, 2);
    assert_int_equal(lk_output_commit(output, &error), LK_OK);
    bytes = lk_test_read_file(path, &size);
    assert_int_equal(size, 8);
    assert_memory_equal(bytes, "a,b\n1,2\n", 8);
    free(bytes);
    assert_int_equal(entries_starting(lk_test_tmpdir(), ".table.csv."), 0);
}

static void test_output_refusals(void **state)
{
    (void)state;
    lk_output *output = (lk_output *)&output;
    lk_error error = {0};
    /* a directory at the path is not replaced */
    assert_int_equal(lk_output_open(lk_test_tmpdir(), &output, &error), LK_ERR_IO);
    assert_null(output);
    assert_non_null(strstr(error.message, "not a regular file"));
    /* a missing folder is named */
    assert_int_equal(lk_output_open(lk_test_tmpfile("missing/out.csv"), &output, &error), LK_ERR_IO);
    assert_non_null(strstr(error.message, "No such file or directory"));
    /* a write error (here past the file size limit) is reported by the
     * commit, and the path keeps what it held */
    char path[4096];
    snprintf(path, sizeof path, "%s", lk_test_tmpfile("big.csv"));
    lk_test_write_file(path, "old\n", 4);
    struct rlimit limit, small;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &limit), 0);
    small = limit;
    small.rlim_cur = 4096;
    void (*previous)(int) = signal(SIGXFSZ, SIG_IGN);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &small), 0);
    assert_int_equal(lk_output_open(path, &output, &error), LK_OK);
    for (int i = 0; i < 10000; i++) fprintf(lk_output_stream(output), "%d,%d\n", i, i * i);
    lk_status status = lk_output_commit(output, &error);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &limit), 0);
    signal(SIGXFSZ, previous);
    assert_int_equal(status, LK_ERR_IO);
    assert_non_null(strstr(error.message, "big.csv: write error: File too large"));
    size_t size;
    unsigned char *bytes = lk_test_read_file(path, &size);
    assert_int_equal(size, 4);
    free(bytes);
    assert_int_equal(entries_starting(lk_test_tmpdir(), ".big.csv."), 0);
}

static void test_output_folder(void **state)
{
    (void)state;
    char path[4096], folder[4096];
    snprintf(path, sizeof path, "%s", lk_test_tmpfile("levels"));
    lk_error error = {0};
    assert_int_equal(lk_output_folder_create(path, "tmp", folder, sizeof folder, &error), LK_OK);
    struct stat info;
    assert_int_equal(stat(folder, &info), 0);
    assert_true(S_ISDIR(info.st_mode));
    const char *name = strrchr(folder, '/') + 1;
    assert_int_equal(strncmp(name, ".levels.tmp-", 12), 0);
    assert_int_equal(strlen(name), 12 + 6);
    assert_int_equal(rmdir(folder), 0);
    /* a buffer too small: refused, and no folder is left behind */
    char small[8];
    assert_int_equal(lk_output_folder_create(path, "tmp", small, sizeof small, &error), LK_ERR_INVALID);
    assert_int_equal(entries_starting(lk_test_tmpdir(), ".levels."), 0);
}

static void test_file_read(void **state)
{
    (void)state;
    char path[4096];
    snprintf(path, sizeof path, "%s", lk_test_tmpfile("bytes.bin"));
    lk_test_write_file(path, "\x89LKS\r\n\x1a\n", 8);
    unsigned char *data = NULL;
    size_t size = 0;
    lk_error error = {0};
    assert_int_equal(lk_file_read(path, 0, &data, &size, &error), LK_OK);
    assert_int_equal(size, 8);
    assert_memory_equal(data, "\x89LKS\r\n\x1a\n", 8);
    assert_int_equal(data[8], 0);
    lk_free(data);
    assert_int_equal(lk_file_read(path, 7, &data, &size, &error), LK_ERR_LIMIT);
    assert_null(data);
    assert_non_null(strstr(error.message, "the file has 8 bytes, more than the memory budget of 7 bytes"));
    char fifo[4096];
    snprintf(fifo, sizeof fifo, "%s", lk_test_tmpfile("pipe"));
    assert_int_equal(mkfifo(fifo, 0600), 0);
    assert_int_equal(lk_file_read(fifo, 0, &data, &size, &error), LK_ERR_IO);
    assert_non_null(strstr(error.message, "is a FIFO, not a regular file"));
    assert_int_equal(lk_file_read(lk_test_tmpfile("none.bin"), 0, &data, &size, &error), LK_ERR_IO);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_output_commit_and_abort),
        cmocka_unit_test(test_output_refusals),
        cmocka_unit_test(test_output_folder),
        cmocka_unit_test(test_file_read),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
