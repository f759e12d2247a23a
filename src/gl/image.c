/* SPDX-License-Identifier: MIT */
/* PNG output of renders (libpng), written atomically. */
#include <png.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "internal.h"

/* libpng reports errors by calling this and expects it not to return:
 * record the message in the caller's lk_error and jump back. */
static void on_png_error(png_structp png, png_const_charp message)
{
    lk_error *error = png_get_error_ptr(png);
    lk_error_set(error, LK_ERR_IO, "libpng: %s", message ? message : "unknown error");
    png_longjmp(png, 1);
}

static void on_png_warning(png_structp png, png_const_charp message)
{
    (void)png;
    (void)message; /* the library prints nothing */
}

/* Everything libpng may longjmp out of lives here. `rows` is filled by the
 * caller before the call and no local changes after setjmp, so nothing can
 * be clobbered by the jump (-Wclobbered stays quiet by construction). */
static lk_status encode_png(FILE *file, png_bytep *rows, unsigned width, unsigned height, lk_error *error)
{
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, error, on_png_error, on_png_warning);
    if (!png) return lk_error_set(error, LK_ERR_NOMEM, "libpng: out of memory");
    png_infop info = png_create_info_struct(png);
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        return lk_error_set(error, LK_ERR_NOMEM, "libpng: out of memory");
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        /* on_png_error has written the message (when error is not NULL). */
        return LK_ERR_IO;
    }
    png_init_io(png, file);
    png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB_ALPHA, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_rows(png, info, rows);
    png_write_png(png, info, PNG_TRANSFORM_IDENTITY, NULL);
    png_destroy_write_struct(&png, &info);
    return LK_OK;
}

lk_status lk_image_write_png(const char *path, const unsigned char *rgba, unsigned width, unsigned height,
                             lk_error *error)
{
    if (!path || !rgba) return lk_error_set(error, LK_ERR_INVALID, "lk_image_write_png: NULL argument");
    /* PNG allows 2^31 - 1 a side; libpng's default user limit is 1,000,000. */
    if (width < 1 || height < 1 || width > 1000000u || height > 1000000u)
        return lk_error_set(error, LK_ERR_INVALID, "%s: image size %ux%u is out of range", path, width, height);
    /* The temporary file is renamed over the target: that would replace a
     * device such as /dev/null (when run as root) or fail on a directory,
     * so only regular files (or new names) are accepted. */
    struct stat target;
    if (stat(path, &target) == 0 && !S_ISREG(target.st_mode))
        return lk_error_set(error, LK_ERR_IO,
                            "%s: not a regular file (images are written to a temporary file and renamed)", path);
    size_t row_bytes = (size_t)width * 4;
    if ((size_t)height > SIZE_MAX / row_bytes)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: image of %ux%u pixels is too large", path, width, height);
    png_bytep *rows = lk__malloc_array(height, sizeof *rows);
    if (!rows) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory for %u row pointers", path, height);
    /* libpng takes non-const rows but only reads them when writing. */
    for (size_t y = 0; y < height; y++) rows[y] = (png_bytep)(uintptr_t)(rgba + y * row_bytes);

    lk__atomic_file out;
    lk_status status = lk__atomic_open(&out, path, error);
    if (status == LK_OK) {
        status = encode_png(out.file, rows, width, height, error);
        if (status == LK_OK)
            status = lk__atomic_commit(&out, error);
        else
            lk__atomic_fail(&out, error);
    }
    if (status == LK_ERR_IO && error && error->status == LK_ERR_IO && strncmp(error->message, "libpng", 6) == 0) {
        /* Name the file in libpng's messages too. */
        char detail[sizeof error->message];
        snprintf(detail, sizeof detail, "%s", error->message);
        lk_error_set(error, LK_ERR_IO, "%s: %s", path, detail);
    }
    free(rows);
    return status;
}
