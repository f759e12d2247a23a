/* SPDX-License-Identifier: MIT */
/* The public face of lodkit's file helpers (lodkit.h, "Output files and
 * whole input files"): atomic output files and folders, and whole-file
 * reads within a budget, for programs that write and read beside the
 * library (the lodkit CLI's CSV and SVG outputs, its animation sets, the
 * .lks files it decodes). The work is done by the lk__ helpers of util.c. */
#include "internal.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct lk_output {
    lk__atomic_file file;
};

lk_status lk_output_open(const char *path, lk_output **output, lk_error *error)
{
    *output = NULL;
    lk_output *opened = malloc(sizeof *opened);
    if (!opened) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", path);
    lk_status status = lk__atomic_open(&opened->file, path, error);
    if (status != LK_OK) {
        free(opened);
        return status;
    }
    *output = opened;
    return LK_OK;
}

FILE *lk_output_stream(lk_output *output) { return output->file.file; }

lk_status lk_output_commit(lk_output *output, lk_error *error)
{
    lk_status status = lk__atomic_commit(&output->file, error);
    free(output);
    return status;
}

void lk_output_abort(lk_output *output)
{
    if (!output) return;
    lk__atomic_abort(&output->file);
    free(output);
}

lk_status lk_output_folder_create(const char *path, const char *tag, char *temp_path, size_t size, lk_error *error)
{
    char *created = NULL;
    lk_status status = lk__temp_dir_create(path, tag, &created, error);
    if (status != LK_OK) return status;
    size_t length = strlen(created);
    if (length >= size) {
        rmdir(created);
        free(created);
        return lk_error_set(error, LK_ERR_INVALID, "%s: the temporary folder's path (%zu bytes) does not fit in %zu",
                            path, length, size);
    }
    memcpy(temp_path, created, length + 1);
    free(created);
    return LK_OK;
}

lk_status lk_file_read(const char *path, size_t max_bytes, unsigned char **data, size_t *size, lk_error *error)
{
    char *bytes = NULL;
    lk_status status = lk__read_file(path, max_bytes, &bytes, size, error);
    *data = (unsigned char *)bytes;
    return status;
}
