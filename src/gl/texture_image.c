/* SPDX-License-Identifier: MIT */
/* Decoding the images of glTF materials for lk_render_scene: PNG (libpng's
 * simplified API) and JPEG (libjpeg-turbo), into RGBA8, top row first. The
 * bytes come from files anyone may hand lodkit: sizes are checked before
 * anything is allocated, and libjpeg's errors come back here instead of
 * ending the process. */
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* after stdio.h and stddef.h, which it needs */
#include <jpeglib.h>

#include "gl_internal.h"

/* Largest side decoded: 16384^2 RGBA is 1 GiB, more than any texture a GLES2
 * driver takes (GL_MAX_TEXTURE_SIZE is 2048 to 16384). */
#define MAX_IMAGE_SIDE 16384u

static lk_status decode_png(const unsigned char *data, size_t size, unsigned char **rgba, unsigned *width,
                            unsigned *height, lk_error *error)
{
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_memory(&image, data, size))
        return lk_error_set(error, LK_ERR_PARSE, "PNG: %s", image.message);
    if (image.width == 0 || image.height == 0 || image.width > MAX_IMAGE_SIDE || image.height > MAX_IMAGE_SIDE) {
        png_image_free(&image);
        return lk_error_set(error, LK_ERR_LIMIT, "PNG: %ux%u pixels (at most %u per side)", image.width, image.height,
                            MAX_IMAGE_SIDE);
    }
    image.format = PNG_FORMAT_RGBA;
    unsigned char *pixels = lk__malloc_array((size_t)image.width * image.height, 4);
    if (!pixels) {
        png_image_free(&image);
        return lk_error_set(error, LK_ERR_NOMEM, "PNG: out of memory for %ux%u pixels", image.width, image.height);
    }
    if (!png_image_finish_read(&image, NULL, pixels, 0, NULL)) {
        free(pixels);
        lk_status status = lk_error_set(error, LK_ERR_PARSE, "PNG: %s", image.message);
        png_image_free(&image);
        return status;
    }
    *rgba = pixels;
    *width = image.width;
    *height = image.height;
    return LK_OK;
}

typedef struct jpeg_failure {
    struct jpeg_error_mgr manager;
    jmp_buf jump;
    char message[JMSG_LENGTH_MAX];
} jpeg_failure;

static void on_jpeg_error(j_common_ptr info)
{
    jpeg_failure *failure = (jpeg_failure *)info->err;
    info->err->format_message(info, failure->message);
    longjmp(failure->jump, 1);
}

static void on_jpeg_message(j_common_ptr info, int level)
{
    (void)info;
    (void)level; /* warnings (a corrupt but readable stream) are not printed */
}

/* Everything libjpeg may longjmp out of lives here; what changes after
 * setjmp is volatile. */
static lk_status decode_jpeg(const unsigned char *data, size_t size, unsigned char **rgba, unsigned *width,
                             unsigned *height, lk_error *error)
{
    struct jpeg_decompress_struct info;
    jpeg_failure failure;
    unsigned char *volatile pixels = NULL;
    if (size > (unsigned long)-1) return lk_error_set(error, LK_ERR_LIMIT, "JPEG: %zu bytes", size);
    info.err = jpeg_std_error(&failure.manager);
    failure.manager.error_exit = on_jpeg_error;
    failure.manager.emit_message = on_jpeg_message;
    if (setjmp(failure.jump)) {
        jpeg_destroy_decompress(&info);
        free(pixels);
        return lk_error_set(error, LK_ERR_PARSE, "JPEG: %s", failure.message);
    }
    jpeg_create_decompress(&info);
    jpeg_mem_src(&info, data, (unsigned long)size);
    jpeg_read_header(&info, TRUE);
    if (info.image_width == 0 || info.image_height == 0 || info.image_width > MAX_IMAGE_SIDE ||
        info.image_height > MAX_IMAGE_SIDE) {
        unsigned w = info.image_width, h = info.image_height;
        jpeg_destroy_decompress(&info);
        return lk_error_set(error, LK_ERR_LIMIT, "JPEG: %ux%u pixels (at most %u per side)", w, h, MAX_IMAGE_SIDE);
    }
    info.out_color_space = JCS_EXT_RGBA;
    jpeg_start_decompress(&info);
    size_t w = info.output_width, h = info.output_height;
    pixels = lk__malloc_array(w * h, 4);
    if (!pixels) {
        jpeg_destroy_decompress(&info);
        return lk_error_set(error, LK_ERR_NOMEM, "JPEG: out of memory for %zux%zu pixels", w, h);
    }
    while (info.output_scanline < info.output_height) {
        JSAMPROW row = pixels + (size_t)info.output_scanline * w * 4;
        jpeg_read_scanlines(&info, &row, 1);
    }
    jpeg_finish_decompress(&info);
    jpeg_destroy_decompress(&info);
    *rgba = pixels;
    *width = (unsigned)w;
    *height = (unsigned)h;
    return LK_OK;
}

lk_status lk__decode_image(const unsigned char *data, size_t size, unsigned char **rgba, unsigned *width,
                           unsigned *height, lk_error *error)
{
    *rgba = NULL;
    *width = *height = 0;
    if (size >= 8 && memcmp(data, "\x89PNG\r\n\x1a\n", 8) == 0)
        return decode_png(data, size, rgba, width, height, error);
    if (size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF)
        return decode_jpeg(data, size, rgba, width, height, error);
    return lk_error_set(error, LK_ERR_UNSUPPORTED, "not a PNG or JPEG image (%zu bytes)", size);
}
