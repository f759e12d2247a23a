/* SPDX-License-Identifier: MIT */
/* libFuzzer target for lodkit's own heightmap readers (src/io_dem.c): PGM
 * (P2/P5) and PNG (through libpng), reached through the in-memory entry
 * point lk__dem_read_memory (GDAL formats are not fuzzed here).
 *
 * The input is the file itself, so sample files are valid seeds. Inputs
 * that start with the PNG signature get their chunk CRCs recomputed before
 * reading: otherwise nearly every mutation dies at libpng's CRC check and
 * our conversion code is never reached. Inputs that start with "PK" (zip)
 * are read as "fuzz.npz" (NumPy archives); anything else as "fuzz.pgm" (so
 * non-PGM bytes exercise the magic check).
 *
 * Any input must give an error with a message and an empty field, or a
 * field that keeps the contract: at least 2x2, finite heights, min/max
 * equal to the real range, positive spacing. A valid field is also
 * resampled to 9x9 and checked the same way. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "lodkit.h"

lk_status lk__dem_read_memory(const void *data, size_t size, const char *name, const lk_dem_options *options,
                              lk_heightfield *out, lk_error *error);

static uint32_t get_be32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | (uint32_t)p[3];
}

/* Rewrites the CRC of every complete chunk (length, type, data, CRC). */
static void reseal_png(uint8_t *bytes, size_t size)
{
    size_t pos = 8;
    while (pos + 12 <= size) {
        uint32_t length = get_be32(bytes + pos);
        if (length > size - pos - 12) break;
        uint32_t crc = (uint32_t)crc32(0L, bytes + pos + 4, (uInt)length + 4);
        uint8_t *target = bytes + pos + 8 + length;
        target[0] = (uint8_t)(crc >> 24);
        target[1] = (uint8_t)(crc >> 16);
        target[2] = (uint8_t)(crc >> 8);
        target[3] = (uint8_t)crc;
        pos += 12 + (size_t)length;
    }
}

static void check_field(const lk_heightfield *field)
{
    if (field->width < 2 || field->height < 2 || !field->heights) abort();
    if (!(field->spacing_x > 0.0) || !(field->spacing_y > 0.0)) abort();
    size_t count = field->width * field->height;
    if (field->nodata_count >= count) abort();
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < count; k++) {
        double h = field->heights[k];
        if (!isfinite(h)) abort();
        if (h < lo) lo = h;
        if (h > hi) hi = h;
    }
    if (lo != field->min_height || hi != field->max_height) abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy) return 0;
    memcpy(copy, data, size);
    if (size >= 8 && memcmp(copy, "\x89PNG\r\n\x1a\n", 8) == 0) reseal_png(copy, size);

    lk_dem_options options;
    lk_dem_options_default(&options);
    options.max_samples = (size_t)1 << 20; /* keep each run fast and small */
    lk_heightfield field;
    lk_error error = {0};
    const char *name = size >= 2 && copy[0] == 'P' && copy[1] == 'K' ? "fuzz.npz" : "fuzz.pgm";
    lk_status status = lk__dem_read_memory(copy, size, name, &options, &field, &error);
    if (status != LK_OK) {
        if (error.message[0] == '\0' || field.heights || field.width) abort();
    } else {
        check_field(&field);
        lk_heightfield resampled;
        if (lk_heightfield_resample(&field, 9, &resampled, NULL) != LK_OK) abort();
        check_field(&resampled);
        if (resampled.min_height < field.min_height || resampled.max_height > field.max_height) abort();
        lk_heightfield_free(&resampled);
        lk_heightfield_free(&field);
    }
    free(copy);
    return 0;
}
