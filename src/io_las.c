/* SPDX-License-Identifier: MIT */
/* LAS point clouds (ASPRS LAS 1.0 to 1.4, uncompressed): a public header
 * block (227 bytes in 1.0-1.2, 235 in 1.3, 375 in 1.4), variable length
 * records (skipped: the header says where the points start), then point
 * records of one of the point data record formats 0 to 10, little-endian.
 * Every record starts with X Y Z as int32; the coordinate is
 * X * scale + offset (the header's doubles). Kept: the position and, in
 * formats 2, 3, 5, 7, 8 and 10, the 16-bit RGB colour; intensity, returns,
 * classification, scan angle, GPS time, NIR, wave packets and extra bytes
 * (a record longer than its format's minimum) are stepped over.
 *
 * Positions are computed in double and stored as lk_mesh's floats, with no
 * translation: georeferenced clouds (coordinates of 10^5 to 10^7 metres)
 * keep only what a float holds there (0.25 m at 2 million).
 * docs/formats.md ("LAS point clouds").
 *
 * LAZ (LASzip-compressed LAS, the same header with bit 7 of the point
 * format set) is refused with how to decompress it: Debian 12 packages no
 * LAZ decoder (no laszip, LASlib, PDAL or lazperf). */
#include "bytes.h"
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Sizes of the public header block by version, and where its fields are. */
enum {
    LAS_HEADER_SIZE_12 = 227,
    LAS_HEADER_SIZE_14 = 375,
    LAS_AT_VERSION = 24,
    LAS_AT_HEADER_SIZE = 94,
    LAS_AT_POINT_OFFSET = 96,
    LAS_AT_FORMAT = 104,
    LAS_AT_RECORD_LENGTH = 105,
    LAS_AT_LEGACY_COUNT = 107,
    LAS_AT_LEGACY_BY_RETURN = 111,
    LAS_AT_SCALE = 131,
    LAS_AT_OFFSET = 155,
    LAS_AT_BOUNDS = 179, /* max x, min x, max y, min y, max z, min z */
    LAS_AT_COUNT_64 = 247,
};

#define LAS_FORMAT_COUNT 11
/* Bytes of a record of each point data record format (a file may add extra
 * bytes after them), and where its RGB starts (0: no colour). */
static const unsigned short record_sizes[LAS_FORMAT_COUNT] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static const unsigned short rgb_offsets[LAS_FORMAT_COUNT] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

typedef lk__las_header las_header;

static const char axis_names[3] = {'x', 'y', 'z'};

lk_status lk__las_parse_header(const unsigned char *data, size_t size, const char *name, las_header *header,
                               lk_error *error)
{
    memset(header, 0, sizeof *header);
    if (size < 4 || memcmp(data, "LASF", 4) != 0)
        return lk__error_at_byte(error, LK_ERR_PARSE, name, 0, "not a LAS file (it does not start with LASF)");
    if (size < LAS_HEADER_SIZE_12)
        return lk__error_at_byte(error, LK_ERR_PARSE, name, size,
                                 "the header is cut short: a LAS header has at least %d bytes, the file %zu",
                                 LAS_HEADER_SIZE_12, size);
    unsigned major = data[LAS_AT_VERSION], minor = data[LAS_AT_VERSION + 1];
    if (major != 1 || minor > 4)
        return lk__error_at_byte(error, LK_ERR_UNSUPPORTED, name, LAS_AT_VERSION,
                                 "LAS version %u.%u (expected 1.0 to 1.4)", major, minor);
    header->header_size = lk__load_u16le(data + LAS_AT_HEADER_SIZE);
    if (header->header_size < LAS_HEADER_SIZE_12 || header->header_size > size)
        return lk__error_at_byte(error, LK_ERR_PARSE, name, LAS_AT_HEADER_SIZE,
                                 "header size %zu is %s (the file has %zu bytes)", header->header_size,
                                 header->header_size < LAS_HEADER_SIZE_12 ? "less than the 227 bytes of a LAS header"
                                                                          : "past the end of the file",
                                 size);
    header->point_offset = lk__load_u32le(data + LAS_AT_POINT_OFFSET);
    if (header->point_offset < header->header_size || header->point_offset > size)
        return lk__error_at_byte(
            error, LK_ERR_PARSE, name, LAS_AT_POINT_OFFSET,
            "offset to point data %zu is %s (header %zu bytes, file %zu bytes)", header->point_offset,
            header->point_offset > size ? "past the end of the file" : "inside the header", header->header_size, size);
    unsigned format_byte = data[LAS_AT_FORMAT];
    /* LASzip marks compressed points with bit 7 (and 6) of the format. */
    if (format_byte & 0xc0)
        return lk__error_at_byte(error, LK_ERR_UNSUPPORTED, name, LAS_AT_FORMAT,
                                 "the points are LAZ-compressed (point format byte 0x%02x); lodkit reads uncompressed "
                                 "LAS only: decompress it first, e.g. 'laszip -i IN.laz -o OUT.las' or "
                                 "'pdal translate IN.laz OUT.las'",
                                 format_byte);
    if (format_byte >= LAS_FORMAT_COUNT)
        return lk__error_at_byte(error, LK_ERR_UNSUPPORTED, name, LAS_AT_FORMAT,
                                 "point data record format %u (expected 0 to 10)", format_byte);
    header->format = format_byte;
    header->record_length = lk__load_u16le(data + LAS_AT_RECORD_LENGTH);
    if (header->record_length < record_sizes[header->format])
        return lk__error_at_byte(error, LK_ERR_PARSE, name, LAS_AT_RECORD_LENGTH,
                                 "point record length %zu is less than the %u bytes of point format %u",
                                 header->record_length, record_sizes[header->format], header->format);
    /* 1.4 adds a 64-bit count; the legacy 32-bit one is then 0 when the
     * count does not fit it (or for formats 6 to 10). */
    header->point_count = lk__load_u32le(data + LAS_AT_LEGACY_COUNT);
    header->count_at = LAS_AT_LEGACY_COUNT;
    if (minor >= 4 && header->header_size >= LAS_HEADER_SIZE_14) {
        unsigned long long count_64 = lk__load_u64le(data + LAS_AT_COUNT_64);
        if (count_64 != 0) {
            header->point_count = count_64;
            header->count_at = LAS_AT_COUNT_64;
        }
    }
    for (int k = 0; k < 3; k++) {
        header->scale[k] = lk__load_f64le(data + LAS_AT_SCALE + 8 * k);
        header->offset[k] = lk__load_f64le(data + LAS_AT_OFFSET + 8 * k);
        if (!isfinite(header->scale[k]) || header->scale[k] == 0.0)
            return lk__error_at_byte(error, LK_ERR_PARSE, name, LAS_AT_SCALE + 8 * (size_t)k,
                                     "%c scale factor %g (expected a finite number other than 0)", axis_names[k],
                                     header->scale[k]);
        if (!isfinite(header->offset[k]))
            return lk__error_at_byte(error, LK_ERR_PARSE, name, LAS_AT_OFFSET + 8 * (size_t)k,
                                     "%c offset %g is not a finite number", axis_names[k], header->offset[k]);
    }
    return LK_OK;
}

/* Reads the records into `mesh` (allocated for them). Colours are stored as
 * their 16-bit values here; *color_max is the largest channel value. */
static lk_status read_points(const las_header *header, const unsigned char *data, const char *name, lk_mesh *mesh,
                             unsigned *color_max, lk_error *error)
{
    size_t count = (size_t)header->point_count, rgb_at = rgb_offsets[header->format];
    unsigned largest = 0;
    for (size_t i = 0; i < count; i++) {
        size_t record_at = header->point_offset + i * header->record_length;
        const unsigned char *record = data + record_at;
        for (int k = 0; k < 3; k++) {
            double value = lk__load_i32le(record + 4 * k) * header->scale[k] + header->offset[k];
            /* Scales and offsets are checked finite, yet their product and
             * sum may be past what a float (or a double) holds. */
            if (!(fabs(value) <= FLT_MAX))
                return lk__error_at_byte(error, LK_ERR_PARSE, name, record_at + 4 * (size_t)k,
                                         "point %zu: %c = %g does not fit in a float", i, axis_names[k], value);
            mesh->positions[3 * i + (size_t)k] = (float)value;
        }
        if (rgb_at) {
            float *rgba = mesh->colors + 4 * i;
            for (int k = 0; k < 3; k++) {
                unsigned channel = lk__load_u16le(record + rgb_at + 2 * k);
                if (channel > largest) largest = channel;
                rgba[k] = (float)channel;
            }
            rgba[3] = 1.0f;
        }
    }
    *color_max = largest;
    return LK_OK;
}

unsigned lk__las_rgb_offset(unsigned format) { return format < LAS_FORMAT_COUNT ? rgb_offsets[format] : 0; }

lk_status lk__read_las(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    const unsigned char *bytes = (const unsigned char *)data;
    las_header header;
    lk_status status = lk__las_parse_header(bytes, size, ctx->name, &header, error);
    if (status != LK_OK) return status;
    size_t available = size - header.point_offset;
    if (header.point_count == 0)
        return lk__error_at_byte(error, LK_ERR_PARSE, ctx->name, header.count_at, "no points (the point count is 0)");
    if (header.point_count > available / header.record_length)
        return lk__error_at_byte(error, LK_ERR_PARSE, ctx->name, header.point_offset,
                                 "the header claims %llu points of %zu bytes but only %zu bytes (%zu points) follow "
                                 "(truncated or corrupt file)",
                                 header.point_count, header.record_length, available, available / header.record_length);
    unsigned flags = rgb_offsets[header.format] ? LK_ATTR_COLORS : 0u;
    size_t per_point = (3 + (flags ? 4 : 0)) * sizeof(float);
    char where[300];
    snprintf(where, sizeof where, "%s: byte %zu", ctx->name, header.count_at);
    status = lk__check_claim(header.point_count, header.record_length, available, per_point, ctx->budget, "points",
                             where, error);
    if (status != LK_OK) return status;
    size_t count = (size_t)header.point_count;
    if (!lk__budget_charge_mesh(ctx->budget, count, 0, flags))
        return lk_error_set(error, LK_ERR_LIMIT, "%s: %zu points would need more than the memory budget of %zu bytes",
                            where, count, ctx->budget->limit);
    unsigned color_max = 0;
    status = lk_mesh_alloc(mesh, count, 0, flags, error);
    if (status == LK_OK) status = read_points(&header, bytes, ctx->name, mesh, &color_max, error);
    if (status != LK_OK) {
        lk_mesh_free(mesh);
        lk__budget_release(ctx->budget, count, per_point);
        return status;
    }
    if (mesh->colors) {
        /* The specification scales colours to 16 bits, yet many writers
         * store 8-bit values as they are: when no channel of any point
         * exceeds 255 the colours are read as 8-bit (the usual
         * heuristic of LAS viewers). */
        float full = color_max <= 255 ? 255.0f : 65535.0f;
        for (size_t i = 0; i < count; i++)
            for (int k = 0; k < 3; k++) mesh->colors[4 * i + (size_t)k] /= full;
    }
    return LK_OK;
}

/* ---- writer --------------------------------------------------------------- */

/* The scale of one axis: a power of ten no larger than half a float's
 * spacing at the largest magnitude on it (so that positions come back as
 * the floats they were, or their neighbours near 0), and no coarser than a
 * thousandth; coarsened again only if the span (the offset is the minimum)
 * would not fit int32 in such steps. */
static double axis_scale(double magnitude, double span)
{
    double scale = magnitude > 0.0 ? pow(10.0, floor(log10(magnitude * 0x1p-24))) : 0.001;
    if (scale > 0.001) scale = 0.001;
    while (span / scale > 2147483647.0) scale *= 10.0;
    return scale;
}

static void store_f64(unsigned char *p, double value)
{
    uint64_t bits;
    memcpy(&bits, &value, sizeof bits);
    lk__store_u64le(p, bits);
}

lk_status lk__write_las(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error)
{
    if (mesh->vertex_count > 0xffffffffu)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu points are more than LAS 1.2 counts (2^32 - 1)",
                            mesh->vertex_count);
    bool with_colors = mesh->colors && !options->skip_colors;
    unsigned format = with_colors ? 2 : 0;
    size_t record_length = record_sizes[format];
    double min[3] = {0, 0, 0}, max[3] = {0, 0, 0}, scale[3];
    for (size_t i = 0; i < mesh->vertex_count; i++)
        for (int k = 0; k < 3; k++) {
            double value = mesh->positions[3 * i + (size_t)k];
            if (i == 0 || value < min[k]) min[k] = value;
            if (i == 0 || value > max[k]) max[k] = value;
        }
    for (int k = 0; k < 3; k++) scale[k] = axis_scale(fmax(fabs(min[k]), fabs(max[k])), max[k] - min[k]);

    unsigned char head[LAS_HEADER_SIZE_12] = {0};
    memcpy(head, "LASF", 4);
    head[LAS_AT_VERSION] = 1;
    head[LAS_AT_VERSION + 1] = 2;
    memcpy(head + 26, "lodkit", 6); /* system identifier (32 bytes) */
    memcpy(head + 58, "lodkit", 6); /* generating software (32 bytes) */
    /* Creation day and year stay 0 (unknown): the output depends on the input only. */
    lk__store_u16le(head + LAS_AT_HEADER_SIZE, LAS_HEADER_SIZE_12);
    lk__store_u32le(head + LAS_AT_POINT_OFFSET, LAS_HEADER_SIZE_12); /* no variable length records */
    head[LAS_AT_FORMAT] = (unsigned char)format;
    lk__store_u16le(head + LAS_AT_RECORD_LENGTH, (uint16_t)record_length);
    lk__store_u32le(head + LAS_AT_LEGACY_COUNT, (uint32_t)mesh->vertex_count);
    lk__store_u32le(head + LAS_AT_LEGACY_BY_RETURN, (uint32_t)mesh->vertex_count); /* all first returns */
    for (int k = 0; k < 3; k++) {
        store_f64(head + LAS_AT_SCALE + 8 * k, scale[k]);
        store_f64(head + LAS_AT_OFFSET + 8 * k, min[k]);
        /* The extents of the stored (rounded) coordinates. */
        double stored_max = llround((max[k] - min[k]) / scale[k]) * scale[k] + min[k];
        store_f64(head + LAS_AT_BOUNDS + 16 * k, stored_max);
        store_f64(head + LAS_AT_BOUNDS + 16 * k + 8, min[k]);
    }
    fwrite(head, 1, sizeof head, file);

    unsigned char records[256 * 26];
    size_t buffered = 0;
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        unsigned char *record = records + buffered * record_length;
        memset(record, 0, record_length);
        for (int k = 0; k < 3; k++) {
            double steps = llround((mesh->positions[3 * i + (size_t)k] - min[k]) / scale[k]);
            lk__store_i32le(record + 4 * k, (int32_t)steps);
        }
        record[14] = 1u | 1u << 3; /* return 1 of 1 */
        if (with_colors)
            for (int k = 0; k < 3; k++) {
                float channel = mesh->colors[4 * i + (size_t)k];
                channel = channel < 0.0f ? 0.0f : channel > 1.0f ? 1.0f : channel;
                lk__store_u16le(record + 20 + 2 * k, (uint16_t)lroundf(channel * 65535.0f));
            }
        if (++buffered == 256 || i + 1 == mesh->vertex_count) {
            fwrite(records, record_length, buffered, file);
            buffered = 0;
        }
    }
    if (ferror(file)) return lk_error_set(error, LK_ERR_IO, "write error while writing LAS");
    return LK_OK;
}
