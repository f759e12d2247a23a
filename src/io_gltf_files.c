/* SPDX-License-Identifier: MIT */
/* glTF writer: the files a .gltf names beside itself (its buffer, STEM.bin,
 * and with LK_GLTF_EXTERNAL_IMAGES its images, STEM_N.png ...), each
 * written whole or not at all before the .gltf that names them; and the
 * bytes an image is written as (lk__gltf_image_bytes). */
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

/* Big-endian 32 bits, as PNG stores its chunk lengths. */
static size_t load_u32be(const unsigned char *p)
{
    return (size_t)p[0] << 24 | (size_t)p[1] << 16 | (size_t)p[2] << 8 | p[3];
}

bool lk__gltf_image_bytes(const unsigned char *data, size_t size, lk__buffer *out)
{
    static const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    bool png = size >= 8 && memcmp(data, signature, 8) == 0;
    /* every chunk must fit (length, type, data, CRC), else copy as it is */
    size_t at = 8, profiles = 0;
    while (png && at < size) {
        if (size - at < 12 || load_u32be(data + at) > size - at - 12) {
            png = false;
            break;
        }
        profiles += memcmp(data + at + 4, "iCCP", 4) == 0;
        at += 12 + load_u32be(data + at);
    }
    if (!png || profiles == 0) return lk__buffer_append(out, data, size);
    if (!lk__buffer_append(out, data, 8)) return false;
    for (at = 8; at < size; at += 12 + load_u32be(data + at))
        if (memcmp(data + at + 4, "iCCP", 4) != 0 && !lk__buffer_append(out, data + at, 12 + load_u32be(data + at)))
            return false;
    return true;
}
