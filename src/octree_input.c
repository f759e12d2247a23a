/* SPDX-License-Identifier: MIT */
/* The point octree's inputs, read in batches (src/octree.c's passes): LAS,
 * PLY and PCD streamed record by record (ascii ones line by line), XYZ line
 * by line, in bounded memory whatever the file's size; other formats (and
 * binary_compressed PCD) read whole by lk_mesh_read and handed out in
 * batches. */
#include "bytes.h"
#include "internal.h"
#include "octree_internal.h"

#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

enum { LAS_HEAD_BYTES = 375 /* a LAS 1.4 public header block */ };


static int path_has_extension(const char *path, const char *extension)
{
    size_t length = strlen(path);
    return length >= 4 && (strcasecmp(path + length - 4, extension) == 0);
}

/* Opens path with lk__open_input as a stdio stream. */
static lk_status open_stream(const char *path, FILE **file, unsigned long long *size, lk_error *error)
{
    int fd;
    struct stat info;
    lk_status status = lk__open_input(NULL, path, &fd, &info, error);
    if (status != LK_OK) return status;
    *file = fdopen(fd, "rb");
    if (!*file) {
        close(fd);
        return lk_error_set(error, LK_ERR_IO, "%s: %s", path, strerror(errno));
    }
    *size = (unsigned long long)info.st_size;
    return LK_OK;
}

/* A colour channel scaled to 0..255 (plus 0.5) as a byte, clamped; NaN (a
 * float colour property of a corrupt file) gives 0 (found by
 * fuzz_pointstream: casting NaN to an integer is undefined). */
static uint8_t colour_byte(double scaled) { return scaled > 0.0 ? (scaled < 255.0 ? (uint8_t)scaled : 255) : 0; }

static lk_status open_text(ot_source *source, lk_error *error);

/* A PLY or a PCD whose records can be streamed (its header, parsed by the
 * format's own parser, in the first 64 KiB; PLY: a first element "vertex"
 * of scalars; PCD: ascii or binary data): *streamed says whether it is
 * (else it is read whole). */
static lk_status open_records(ot_source *source, const char *path, int pcd, int *streamed, lk_error *error)
{
    *streamed = 0;
    unsigned long long file_size = 0;
    lk_status status = open_stream(path, &source->file, &file_size, error);
    if (status != LK_OK) return status;
    enum { HEAD = 1 << 16 };
    char *head = malloc(HEAD + 1);
    if (!head) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    size_t got = fread(head, 1, HEAD, source->file);
    head[got] = '\0';
    lk_error quiet = {0};
    if (pcd)
        status = lk__pcd_stream_open(head, got, file_size, path, &source->pcd, &quiet);
    else if (strstr(head, "end_header"))
        status = lk__ply_stream_layout(head, got, file_size, path, &source->ply, &quiet);
    else
        status = LK_ERR_UNSUPPORTED;
    free(head);
    if (status == LK_ERR_UNSUPPORTED) {
        fclose(source->file);
        source->file = NULL;
        return LK_OK;
    }
    if (status != LK_OK) {
        if (error) *error = quiet;
        return status;
    }
    *streamed = 1;
    int text;
    size_t record_size, first_line, offset;
    if (pcd) {
        source->is_pcd = 1;
        source->count = ULLONG_MAX; /* known once every record is read: NaN points are dropped */
        source->has_colors = source->pcd.has_colors;
        source->has_normals = source->pcd.has_normals;
        text = !source->pcd.binary;
        record_size = source->pcd.record_size, first_line = source->pcd.data_line, offset = source->pcd.data_offset;
    } else {
        source->is_ply = 1;
        source->count = source->ply.count;
        source->has_colors = source->ply.has_colors;
        source->has_normals = source->ply.has_normals;
        text = source->ply.ascii;
        record_size = source->ply.record_size, first_line = source->ply.body_line, offset = source->ply.body_offset;
    }
    if (text) {
        source->line = first_line - 1; /* the header's last line */
        status = open_text(source, error);
    } else {
        source->records = lk__malloc_array(OT_BATCH, record_size);
        if (!source->records) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    if (status == LK_OK && fseeko(source->file, (off_t)offset, SEEK_SET) != 0)
        return lk_error_set(error, LK_ERR_IO, "%s: seek error: %s", path, strerror(errno));
    return status;
}

/* ---- text sources: lines read in blocks --------------------------------- */

/* A block read at a time, and the longest line taken: the buffer holds
 * both, so a line never needs more than one refill. */
enum { TEXT_BLOCK = 1 << 20, LONGEST_LINE = 1 << 20 };

static lk_status open_text(ot_source *source, lk_error *error)
{
    source->text_capacity = TEXT_BLOCK + LONGEST_LINE;
    source->text = malloc(source->text_capacity);
    if (!source->text) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", source->path);
    source->text_start = source->text_end = 0;
    source->text_eof = 0;
    return LK_OK;
}

/* The next line [*start, *end) without its newline (a '\r' before it is
 * left to the parsers, which take it as a space); *start = NULL at the end
 * of the file. source->line counts the lines handed out. */
static lk_status text_line(ot_source *source, const char **start, const char **end, lk_error *error)
{
    for (;;) {
        char *from = source->text + source->text_start, *limit = source->text + source->text_end;
        char *newline = memchr(from, '\n', (size_t)(limit - from));
        if (newline || (source->text_eof && from < limit)) {
            *start = from;
            *end = newline ? newline : limit;
            source->text_start = newline ? (size_t)(newline + 1 - source->text) : source->text_end;
            source->line++;
            return LK_OK;
        }
        if (source->text_eof) {
            *start = *end = NULL;
            return LK_OK;
        }
        size_t partial = source->text_end - source->text_start;
        if (partial >= LONGEST_LINE)
            return lk__error_at_line(error, LK_ERR_PARSE, source->path, source->line + 1,
                                     "a line longer than %d bytes (not a text point file?)", LONGEST_LINE);
        memmove(source->text, from, partial);
        source->text_start = 0;
        source->text_end = partial;
        size_t got = fread(source->text + partial, 1, source->text_capacity - partial, source->file);
        if (got == 0) {
            if (ferror(source->file))
                return lk_error_set(error, LK_ERR_IO, "%s: read error: %s", source->path, strerror(errno));
            source->text_eof = 1;
        }
        source->text_end += got;
    }
}

/* The next batch of an XYZ file (lk__xyz_line's rules); at its end the
 * source's count becomes the points read. */
static lk_status xyz_next(ot_source *source, ot_batch *batch, lk_error *error)
{
    size_t count = 0;
    while (count < OT_BATCH) {
        const char *start, *end;
        lk_status status = text_line(source, &start, &end, error);
        if (status != LK_OK) return status;
        if (!start) {
            source->count = source->next + count;
            if (source->count == 0)
                return lk_error_set(error, LK_ERR_PARSE, "%s: no points (expected lines of 'x y z [nx ny nz]')",
                                    source->path);
            break;
        }
        double values[6];
        int numbers;
        status = lk__xyz_line(&source->xyz, start, end, source->path, source->line, values, &numbers, error);
        if (status != LK_OK) return status;
        if (numbers == 0) continue;
        for (int k = 0; k < numbers; k++)
            if (!isfinite(values[k]))
                return lk__error_at_line(error, LK_ERR_RANGE, source->path, source->line, "%g is not a finite number",
                                         values[k]);
        for (int k = 0; k < 3; k++) {
            batch->xyz[3 * count + (size_t)k] = values[k];
            if (numbers == 6) batch->normals[3 * count + (size_t)k] = (float)values[3 + k];
        }
        count++;
    }
    source->has_normals = source->xyz.numbers_per_line == 6;
    batch->count = count;
    source->next += count;
    return LK_OK;
}

/* The next batch of a PCD: binary records or ascii lines (blank lines
 * skipped), points with a coordinate that is not finite dropped; after the
 * last record the source's count becomes the points kept. */
static lk_status pcd_next(ot_source *source, ot_batch *batch, lk_error *error)
{
    const lk__pcd_stream *pcd = &source->pcd;
    size_t count = 0;
    while (count < OT_BATCH && source->records_done < pcd->points) {
        if (pcd->binary) {
            unsigned long long left = pcd->points - source->records_done;
            size_t want = left < OT_BATCH - count ? (size_t)left : OT_BATCH - count;
            if (fread(source->records, pcd->record_size, want, source->file) != want)
                return lk__error_at_byte(error, LK_ERR_IO, source->path,
                                         pcd->data_offset + (size_t)source->records_done * pcd->record_size,
                                         "read error: the points end early (the file changed while it was read?)");
            for (size_t i = 0; i < want; i++)
                count += lk__pcd_stream_record(pcd, source->records + i * pcd->record_size, batch->xyz + 3 * count,
                                               batch->normals + 3 * count, batch->rgb + 3 * count);
            source->records_done += want;
            continue;
        }
        const char *start, *end;
        lk_status status = text_line(source, &start, &end, error);
        if (status != LK_OK) return status;
        if (!start)
            return lk__error_at_line(error, LK_ERR_PARSE, source->path, source->line,
                                     "the file ends after %llu of %llu points", source->records_done, pcd->points);
        if (lk__skip_spaces(start, end) == end) continue;
        bool kept;
        status = lk__pcd_stream_line(pcd, start, end, source->path, source->line, batch->xyz + 3 * count,
                                     batch->normals + 3 * count, batch->rgb + 3 * count, &kept, error);
        if (status != LK_OK) return status;
        count += kept;
        source->records_done++;
    }
    if (source->records_done == pcd->points) {
        source->count = source->next + count;
        if (source->count == 0)
            return lk_error_set(error, LK_ERR_PARSE, "%s: no points left: all %llu have NaN coordinates", source->path,
                                pcd->points);
    }
    batch->count = count;
    source->next += count;
    return LK_OK;
}

/* The next batch of an ASCII PLY: a vertex per line of the header's
 * property count (blank lines skipped, as the whole-file reader does). */
static lk_status ply_ascii_next(ot_source *source, ot_batch *batch, size_t count, lk_error *error)
{
    const lk__ply_layout *ply = &source->ply;
    for (size_t i = 0; i < count; i++) {
        unsigned long long index = source->next + i;
        const char *start = NULL, *end = NULL;
        do {
            lk_status status = text_line(source, &start, &end, error);
            if (status != LK_OK) return status;
        } while (start && lk__skip_spaces(start, end) == end);
        if (!start)
            return lk__error_at_line(error, LK_ERR_PARSE, source->path, source->line,
                                     "expected %llu vertices, data ends after %llu", ply->count, index);
        double values[9] = {0};
        const char *p = start;
        for (size_t j = 0; j < ply->property_count; j++) {
            double value;
            const char *before = lk__skip_spaces(p, end);
            if (before == end)
                return lk__error_at_line(error, LK_ERR_PARSE, source->path, source->line,
                                         "vertex %llu: line ends before property %zu (fewer values than the header "
                                         "declares)",
                                         index, j + 1);
            p = before;
            if (!lk__parse_double(&p, end, &value) || (p < end && !lk__is_space(*p)))
                return lk__error_at_line(error, LK_ERR_PARSE, source->path, source->line,
                                         "vertex %llu: property %zu: expected a number", index, j + 1);
            for (int r = 0; r < 9; r++)
                if (ply->at[r] == j) values[r] = lk__ply_ascii_value(value, ply->type[r]);
        }
        if (lk__skip_spaces(p, end) != end)
            return lk__error_at_line(error, LK_ERR_PARSE, source->path, source->line,
                                     "vertex %llu: more values than the header declares", index);
        for (int k = 0; k < 3; k++) {
            if (!isfinite(values[k]))
                return lk__error_at_line(error, LK_ERR_PARSE, source->path, source->line,
                                         "vertex %llu: a coordinate is not finite", index);
            batch->xyz[3 * i + (size_t)k] = values[k];
            if (ply->has_normals) batch->normals[3 * i + (size_t)k] = (float)values[3 + k];
            if (ply->has_colors) {
                double c = values[6 + k] * ply->color_scale[k] * 255.0 + 0.5;
                batch->rgb[3 * i + (size_t)k] = colour_byte(c);
            }
        }
    }
    source->next += count;
    return LK_OK;
}

static lk_status ply_next(ot_source *source, ot_batch *batch, size_t count, lk_error *error)
{
    const lk__ply_layout *ply = &source->ply;
    if (fread(source->records, ply->record_size, count, source->file) != count)
        return lk__error_at_byte(error, LK_ERR_IO, source->path,
                                 ply->body_offset + (size_t)source->next * ply->record_size,
                                 "read error: the vertices end early (the file changed while it was read?)");
    for (size_t i = 0; i < count; i++) {
        const unsigned char *record = source->records + i * ply->record_size;
        for (int k = 0; k < 3; k++) {
            double v = lk__ply_stream_value(record + ply->at[k], ply->type[k], ply->big_endian);
            if (!isfinite(v))
                return lk__error_at_byte(error, LK_ERR_PARSE, source->path,
                                         ply->body_offset + (size_t)(source->next + i) * ply->record_size + ply->at[k],
                                         "vertex %llu: a coordinate is not finite",
                                         (unsigned long long)(source->next + i));
            batch->xyz[3 * i + (size_t)k] = v;
            if (ply->has_normals)
                batch->normals[3 * i + (size_t)k] =
                    (float)lk__ply_stream_value(record + ply->at[3 + k], ply->type[3 + k], ply->big_endian);
            if (ply->has_colors) {
                double c = lk__ply_stream_value(record + ply->at[6 + k], ply->type[6 + k], ply->big_endian) *
                               ply->color_scale[k] * 255.0 +
                           0.5;
                batch->rgb[3 * i + (size_t)k] = colour_byte(c);
            }
        }
    }
    source->next += count;
    return LK_OK;
}

void lk__octree_source_close(ot_source *source)
{
    if (source->file) fclose(source->file);
    source->file = NULL;
    free(source->records);
    source->records = NULL;
    free(source->text);
    source->text = NULL;
    lk__pcd_stream_close(&source->pcd);
    lk_mesh_free(&source->mesh);
}

/* Opens `path` for a pass (colors_16bit is kept from an earlier pass). */
lk_status lk__octree_source_open(ot_source *source, const char *path, lk_error *error)
{
    int colors_16bit = source->colors_16bit;
    size_t max_read_bytes = source->max_read_bytes;
    memset(source, 0, sizeof *source);
    source->max_read_bytes = max_read_bytes;
    lk_mesh_init(&source->mesh);
    source->path = path;
    source->colors_16bit = colors_16bit;
    source->is_las = path_has_extension(path, ".las");
    if (path_has_extension(path, ".ply")) {
        int streamed;
        lk_status status = open_records(source, path, 0, &streamed, error);
        if (status != LK_OK || streamed) return status;
    }
    if (lk_format_from_path(path) == LK_FORMAT_PCD) {
        int streamed;
        lk_status status = open_records(source, path, 1, &streamed, error);
        if (status != LK_OK || streamed) return status;
    }
    if (lk_format_from_path(path) == LK_FORMAT_XYZ) {
        unsigned long long size = 0;
        lk_status status = open_stream(path, &source->file, &size, error);
        if (status == LK_OK) status = open_text(source, error);
        source->is_xyz = 1;
        source->count = ULLONG_MAX; /* known at the last line */
        return status;
    }
    if (!source->is_las) {
        lk_read_options read_options;
        memset(&read_options, 0, sizeof read_options);
        read_options.max_bytes = source->max_read_bytes;
        lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, &read_options, &source->mesh, error);
        if (status != LK_OK) return status;
        source->count = source->mesh.vertex_count;
        source->has_colors = source->mesh.colors != NULL;
        source->has_normals = source->mesh.normals != NULL;
        if (source->count == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: no points", path);
        return LK_OK;
    }
    unsigned long long size = 0;
    lk_status status = open_stream(path, &source->file, &size, error);
    if (status != LK_OK) return status;
    unsigned char head[LAS_HEAD_BYTES];
    memset(head, 0, sizeof head);
    size_t file_size = (size_t)size;
    size_t want = file_size < sizeof head ? file_size : sizeof head;
    if (fread(head, 1, want, source->file) != want)
        return lk_error_set(error, LK_ERR_IO, "%s: read error: %s", path, strerror(errno));
    status = lk__las_parse_header(head, file_size, path, &source->las, error);
    if (status != LK_OK) return status;
    size_t available = file_size - source->las.point_offset;
    if (source->las.point_count == 0)
        return lk__error_at_byte(error, LK_ERR_PARSE, path, source->las.count_at, "no points (the point count is 0)");
    if (source->las.point_count > available / source->las.record_length)
        return lk__error_at_byte(error, LK_ERR_PARSE, path, source->las.point_offset,
                                 "the header claims %llu points of %zu bytes but only %zu bytes (%zu points) follow "
                                 "(truncated or corrupt file)",
                                 source->las.point_count, source->las.record_length, available,
                                 available / source->las.record_length);
    source->count = source->las.point_count;
    source->rgb_at = lk__las_rgb_offset(source->las.format);
    source->has_colors = source->rgb_at != 0;
    source->records = lk__malloc_array(OT_BATCH, source->las.record_length);
    if (!source->records) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", path);
    if (fseeko(source->file, (off_t)source->las.point_offset, SEEK_SET) != 0)
        return lk_error_set(error, LK_ERR_IO, "%s: seek error: %s", path, strerror(errno));
    return LK_OK;
}

lk_status lk__octree_source_next(ot_source *source, ot_batch *batch, lk_error *error)
{
    unsigned long long left = source->count - source->next;
    size_t count = left < OT_BATCH ? (size_t)left : OT_BATCH;
    batch->count = count;
    if (source->is_xyz) return xyz_next(source, batch, error);
    if (source->is_pcd) return pcd_next(source, batch, error);
    if (source->is_ply && source->ply.ascii) return ply_ascii_next(source, batch, count, error);
    if (source->is_ply) return ply_next(source, batch, count, error);
    if (!source->is_las) {
        const lk_mesh *mesh = &source->mesh;
        for (size_t i = 0; i < count; i++) {
            size_t at = (size_t)source->next + i;
            for (int k = 0; k < 3; k++) {
                float value = mesh->positions[3 * at + (size_t)k];
                if (!isfinite(value))
                    return lk_error_set(error, LK_ERR_PARSE, "%s: point %zu has a coordinate that is not finite",
                                        source->path, at);
                batch->xyz[3 * i + (size_t)k] = value;
                if (mesh->normals) batch->normals[3 * i + (size_t)k] = mesh->normals[3 * at + (size_t)k];
                if (mesh->colors) {
                    float c = mesh->colors[4 * at + (size_t)k] * 255.0f + 0.5f;
                    batch->rgb[3 * i + (size_t)k] = colour_byte(c);
                }
            }
        }
        source->next += count;
        return LK_OK;
    }
    const lk__las_header *las = &source->las;
    if (fread(source->records, las->record_length, count, source->file) != count) {
        size_t at = las->point_offset + (size_t)source->next * las->record_length;
        return lk__error_at_byte(error, LK_ERR_IO, source->path, at,
                                 "read error: the point records end early (the file changed while it was read?)");
    }
    for (size_t i = 0; i < count; i++) {
        const unsigned char *record = source->records + i * las->record_length;
        for (int k = 0; k < 3; k++) {
            double value = lk__load_i32le(record + 4 * k) * las->scale[k] + las->offset[k];
            if (!(fabs(value) <= DBL_MAX)) {
                size_t at = las->point_offset + (size_t)(source->next + i) * las->record_length;
                return lk__error_at_byte(error, LK_ERR_PARSE, source->path, at + 4 * (size_t)k,
                                         "point %llu: coordinate %d is not a finite number",
                                         (unsigned long long)(source->next + i), k);
            }
            batch->xyz[3 * i + (size_t)k] = value;
        }
        if (source->rgb_at)
            for (int k = 0; k < 3; k++) {
                unsigned channel = lk__load_u16le(record + source->rgb_at + 2 * k);
                if (channel > source->color_max) source->color_max = channel;
                /* As lk__read_las: 16-bit colours unless no channel exceeds 255. */
                batch->rgb[3 * i + (size_t)k] =
                    (uint8_t)(source->colors_16bit ? (channel * 255u + 32767u) / 65535u : channel & 0xffu);
            }
    }
    source->next += count;
    return LK_OK;
}
