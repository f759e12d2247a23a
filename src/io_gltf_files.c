/* SPDX-License-Identifier: MIT */
/* glTF writer: the files a .gltf names beside itself (its buffer, STEM.bin,
 * and with LK_GLTF_EXTERNAL_IMAGES its images, STEM_N.png ...), each
 * written whole or not at all before the .gltf that names them. */
#include "io_gltf.h"

#include <stdlib.h>
#include <string.h>

lk_status lk__gltf_sibling_names(const char *path, const char *suffix, char **file_path, char **uri, lk_error *error)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t stem = dot ? (size_t)(dot - path) : strlen(path);
    size_t suffix_length = strlen(suffix);
    *file_path = malloc(stem + suffix_length + 1);
    /* A URI: percent-encode everything but unreserved characters (the
     * suffix is made of those). */
    size_t base_stem = stem - (size_t)(base - path);
    *uri = malloc(3 * base_stem + suffix_length + 1);
    if (!*file_path || !*uri) {
        free(*file_path), free(*uri);
        *file_path = *uri = NULL;
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    memcpy(*file_path, path, stem);
    strcpy(*file_path + stem, suffix);
    size_t used = 0;
    for (size_t i = 0; i < base_stem; i++) {
        unsigned char c = (unsigned char)base[i];
        bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' ||
                     c == '_' || c == '.' || c == '~';
        if (plain) {
            (*uri)[used++] = (char)c;
        } else {
            static const char hex[] = "0123456789ABCDEF";
            (*uri)[used++] = '%';
            (*uri)[used++] = hex[c >> 4];
            (*uri)[used++] = hex[c & 15];
        }
    }
    strcpy(*uri + used, suffix);
    return LK_OK;
}

lk_status lk__gltf_write_sibling(const char *file_path, const void *data, size_t size, lk_error *error)
{
    lk__atomic_file file;
    lk_status status = lk__atomic_open(&file, file_path, error);
    if (status != LK_OK) return status;
    if (size && fwrite(data, 1, size, file.file) != size) {
        lk_error_set(error, LK_ERR_IO, "%s: write error", file_path);
        return lk__atomic_fail(&file, error);
    }
    return lk__atomic_commit(&file, error);
}

const char *lk__gltf_image_extension(const char *mime_type)
{
    static const char *const known[][2] = {{"image/png", "png"},   {"image/jpeg", "jpg"}, {"image/webp", "webp"},
                                           {"image/ktx2", "ktx2"}, {"image/gif", "gif"},  {"image/bmp", "bmp"}};
    for (size_t i = 0; mime_type && i < sizeof known / sizeof known[0]; i++)
        if (strcmp(mime_type, known[i][0]) == 0) return known[i][1];
    return "bin";
}
