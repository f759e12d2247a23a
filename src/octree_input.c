/* SPDX-License-Identifier: MIT */
/* The point octree's inputs, read in batches (src/octree.c's passes): LAS
 * and binary PLY streamed record by record, other formats read whole by
 * lk_mesh_read and handed out in batches. */
#include "bytes.h"
#include "internal.h"
#include "octree_internal.h"

#include <errno.h>
#include <float.h>
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

/* A binary PLY whose vertices can be streamed: *streamed says whether it
 * is (else it is read whole). */
static lk_status open_ply(ot_source *source, const char *path, int *streamed, lk_error *error)
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
    if (strstr(head, "end_header"))
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
    source->is_ply = 1;
    source->count = source->ply.count;
    source->has_colors = source->ply.has_colors;
    source->has_normals = source->ply.has_normals;
    source->records = lk__malloc_array(OT_BATCH, source->ply.record_size);
    if (!source->records) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    if (fseeko(source->file, (off_t)source->ply.body_offset, SEEK_SET) != 0)
        return lk_error_set(error, LK_ERR_IO, "%s: seek error: %s", path, strerror(errno));
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
                batch->rgb[3 * i + (size_t)k] = (uint8_t)(c <= 0.0 ? 0.0 : c >= 255.0 ? 255.0 : c);
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
    lk_mesh_free(&source->mesh);
}

/* Opens `path` for a pass (colors_16bit is kept from an earlier pass). */
lk_status lk__octree_source_open(ot_source *source, const char *path, lk_error *error)
{
    int colors_16bit = source->colors_16bit;
    memset(source, 0, sizeof *source);
    lk_mesh_init(&source->mesh);
    source->path = path;
    source->colors_16bit = colors_16bit;
    source->is_las = path_has_extension(path, ".las");
    if (path_has_extension(path, ".ply")) {
        int streamed;
        lk_status status = open_ply(source, path, &streamed, error);
        if (status != LK_OK || streamed) return status;
    }
    if (!source->is_las) {
        lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &source->mesh, error);
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
                    batch->rgb[3 * i + (size_t)k] = (uint8_t)(c <= 0.0f ? 0.0f : c >= 255.0f ? 255.0f : c);
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
