/* SPDX-License-Identifier: MIT */
/* PCD point clouds (the Point Cloud Library's format, header versions 0.5
 * to 0.7): a text header (FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT,
 * POINTS, DATA), then the points as text (DATA ascii), as little-endian
 * records with the fields interleaved (binary), or LZF-compressed with the
 * fields one after the other (binary_compressed: all x, then all y, ...).
 * Kept: x y z, normal_x normal_y normal_z, and rgb / rgba (PCL packs a
 * colour in 4 bytes, 0x00RRGGBB or 0xAARRGGBB, rgb usually typed as a
 * float: its bits are the colour). Other fields are skipped. Points with a
 * NaN coordinate (missing points of organised clouds) are dropped. */
#include "bytes.h"
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PCD_MAX_FIELDS 256
#define PCD_MAX_COUNT 1000000u

typedef struct pcd_field {
    int size;      /* SIZE: 1, 2, 4 or 8 bytes */
    char type;     /* TYPE: 'I', 'U' or 'F' */
    size_t count;  /* COUNT: elements of the field */
    size_t offset; /* bytes before it in a point record */
    size_t value;  /* values before it in an ascii point */
} pcd_field;

enum { PCD_ASCII, PCD_BINARY, PCD_COMPRESSED };

typedef struct pcd_header {
    pcd_field fields[PCD_MAX_FIELDS];
    size_t field_count, size_count, type_count, count_count; /* entries on each line (0: no line) */
    int x, y, z, nx, ny, nz, color;                          /* field indices, -1 when absent */
    bool color_has_alpha;                                    /* rgba rather than rgb */
    unsigned long long width, height, points;
    bool has_width, has_height, has_points;
    int data_kind;
    size_t data_offset; /* first byte after the DATA line */
    size_t data_line;   /* its line number */
    size_t point_size;  /* bytes of one record */
    size_t values_per_point;
} pcd_header;

/* The next space-separated word of [*p, end): its start, length in *length
 * (0 at the end of the line). */
static const char *next_word(const char **p, const char *end, size_t *length)
{
    const char *start = lk__skip_spaces(*p, end);
    const char *q = start;
    while (q < end && !lk__is_space(*q)) q++;
    *length = (size_t)(q - start);
    *p = q;
    return start;
}

static bool word_is(const char *word, size_t length, const char *expected)
{
    return length == strlen(expected) && memcmp(word, expected, length) == 0;
}

static lk_status parse_count_line(const char *p, const char *end, const char *key, unsigned long long *out,
                                  const char *name, size_t line, lk_error *error)
{
    long long value;
    if (!lk__parse_int64(&p, end, &value) || value < 0)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "%s needs a count of 0 or more", key);
    *out = (unsigned long long)value;
    return LK_OK;
}

/* One of the per-field lines (FIELDS, SIZE, TYPE, COUNT). */
static lk_status parse_field_line(pcd_header *header, const char *key, const char *p, const char *end, const char *name,
                                  size_t line, lk_error *error)
{
    size_t *entries = key[0] == 'S'   ? &header->size_count
                      : key[0] == 'T' ? &header->type_count
                      : key[0] == 'F' ? &header->field_count
                                      : &header->count_count;
    /* A second line would leave fields (and x, y, z) of the first one behind. */
    if (*entries) return lk__error_at_line(error, LK_ERR_PARSE, name, line, "a second %s line", key);
    size_t n = 0, length;
    for (const char *word = next_word(&p, end, &length); length; word = next_word(&p, end, &length), n++) {
        if (n >= PCD_MAX_FIELDS)
            return lk__error_at_line(error, LK_ERR_LIMIT, name, line, "more than %d fields", PCD_MAX_FIELDS);
        pcd_field *field = &header->fields[n];
        if (key[0] == 'F') {
            int *roles[] = {&header->x, &header->y, &header->z, &header->nx, &header->ny, &header->nz};
            static const char *const role_names[] = {"x", "y", "z", "normal_x", "normal_y", "normal_z"};
            for (int r = 0; r < 6; r++)
                if (word_is(word, length, role_names[r]) && *roles[r] < 0) *roles[r] = (int)n;
            if ((word_is(word, length, "rgb") || word_is(word, length, "rgba")) && header->color < 0) {
                header->color = (int)n;
                header->color_has_alpha = length == 4;
            }
        } else if (key[0] == 'S') {
            if (length != 1 || (word[0] != '1' && word[0] != '2' && word[0] != '4' && word[0] != '8'))
                return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                         "SIZE of field %zu is '%.*s' (expected 1, 2, 4 or 8)", n + 1,
                                         (int)(length < 24 ? length : 24), word);
            field->size = word[0] - '0';
        } else if (key[0] == 'T') {
            if (length != 1 || (word[0] != 'I' && word[0] != 'U' && word[0] != 'F'))
                return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                         "TYPE of field %zu is '%.*s' (expected I, U or F)", n + 1,
                                         (int)(length < 24 ? length : 24), word);
            field->type = word[0];
        } else {
            const char *q = word;
            long long count;
            if (!lk__parse_int64(&q, word + length, &count) || q != word + length || count < 1 ||
                count > (long long)PCD_MAX_COUNT)
                return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                         "COUNT of field %zu is '%.*s' (expected 1 to %u)", n + 1,
                                         (int)(length < 24 ? length : 24), word, PCD_MAX_COUNT);
            field->count = (size_t)count;
        }
    }
    if (n == 0) return lk__error_at_line(error, LK_ERR_PARSE, name, line, "%s has no entries", key);
    *entries = n;
    return LK_OK;
}

/* Checks the header read up to the DATA line and fills the layout. */
static lk_status check_header(pcd_header *header, const char *name, size_t line, lk_error *error)
{
    if (header->field_count == 0)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "no FIELDS line before DATA");
    if (header->size_count == 0) return lk__error_at_line(error, LK_ERR_PARSE, name, line, "no SIZE line before DATA");
    const char *keys[] = {"SIZE", "TYPE", "COUNT"};
    size_t counts[] = {header->size_count, header->type_count, header->count_count};
    for (int k = 0; k < 3; k++)
        if (counts[k] && counts[k] != header->field_count)
            return lk__error_at_line(error, LK_ERR_PARSE, name, line, "%s has %zu entries but FIELDS has %zu", keys[k],
                                     counts[k], header->field_count);
    /* Headers before 0.7 may lack TYPE (floats) and COUNT (one each). */
    size_t offset = 0, values = 0;
    for (size_t i = 0; i < header->field_count; i++) {
        pcd_field *field = &header->fields[i];
        if (!header->type_count) field->type = 'F';
        if (!header->count_count) field->count = 1;
        if (field->type == 'F' && field->size != 4 && field->size != 8)
            return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                     "field %zu has TYPE F and SIZE %d (expected 4 or 8)", i + 1, field->size);
        field->offset = offset;
        field->value = values;
        offset += (size_t)field->size * field->count;
        values += field->count;
    }
    header->point_size = offset;
    header->values_per_point = values;
    if (header->x < 0 || header->y < 0 || header->z < 0)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "FIELDS has no %s (x, y and z are needed)",
                                 header->x < 0   ? "x"
                                 : header->y < 0 ? "y"
                                                 : "z");
    if (header->nx < 0 || header->ny < 0 || header->nz < 0) header->nx = header->ny = header->nz = -1;
    if (header->color >= 0 && header->fields[header->color].size != 4)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                 "field %s has SIZE %d (PCL packs a colour in 4 bytes)",
                                 header->color_has_alpha ? "rgba" : "rgb", header->fields[header->color].size);
    /* WIDTH x HEIGHT is the grid of an organised cloud; older headers may
     * give only POINTS or only WIDTH. */
    if (!header->has_height) header->height = 1;
    if (!header->has_width && header->has_points) header->width = header->points;
    if (!header->has_width && !header->has_points)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "no WIDTH or POINTS line before DATA");
    if (header->height && header->width > ~0ull / header->height)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "WIDTH x HEIGHT overflows");
    if (!header->has_points) header->points = header->width * header->height;
    if (header->points != header->width * header->height)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "POINTS %llu is not WIDTH %llu x HEIGHT %llu",
                                 header->points, header->width, header->height);
    return LK_OK;
}

static lk_status parse_header(const char *data, size_t size, const char *name, pcd_header *header, lk_error *error)
{
    memset(header, 0, sizeof *header);
    header->x = header->y = header->z = header->nx = header->ny = header->nz = header->color = -1;
    const char *p = data, *end = data + size;
    size_t line = 0;
    while (p < end) {
        line++;
        const char *line_end = memchr(p, '\n', (size_t)(end - p));
        if (!line_end) line_end = end;
        const char *q = p;
        p = line_end < end ? line_end + 1 : end;
        size_t length;
        const char *key = next_word(&q, line_end, &length);
        if (length == 0 || key[0] == '#') continue;
        lk_status status = LK_OK;
        if (word_is(key, length, "FIELDS") || word_is(key, length, "COLUMNS"))
            status = parse_field_line(header, "FIELDS", q, line_end, name, line, error);
        else if (word_is(key, length, "SIZE"))
            status = parse_field_line(header, "SIZE", q, line_end, name, line, error);
        else if (word_is(key, length, "TYPE"))
            status = parse_field_line(header, "TYPE", q, line_end, name, line, error);
        else if (word_is(key, length, "COUNT"))
            status = parse_field_line(header, "COUNT", q, line_end, name, line, error);
        else if (word_is(key, length, "WIDTH")) {
            status = parse_count_line(q, line_end, "WIDTH", &header->width, name, line, error);
            header->has_width = true;
        } else if (word_is(key, length, "HEIGHT")) {
            status = parse_count_line(q, line_end, "HEIGHT", &header->height, name, line, error);
            header->has_height = true;
        } else if (word_is(key, length, "POINTS")) {
            status = parse_count_line(q, line_end, "POINTS", &header->points, name, line, error);
            header->has_points = true;
        } else if (word_is(key, length, "DATA")) {
            const char *kind = next_word(&q, line_end, &length);
            if (word_is(kind, length, "ascii"))
                header->data_kind = PCD_ASCII;
            else if (word_is(kind, length, "binary"))
                header->data_kind = PCD_BINARY;
            else if (word_is(kind, length, "binary_compressed"))
                header->data_kind = PCD_COMPRESSED;
            else
                return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                         "unknown DATA '%.*s' (expected ascii, binary or binary_compressed)",
                                         (int)(length < 24 ? length : 24), kind);
            header->data_offset = (size_t)(p - data);
            header->data_line = line + 1;
            return check_header(header, name, line, error);
        }
        /* VERSION, VIEWPOINT and unknown keys are not needed. */
        if (status != LK_OK) return status;
    }
    return lk_error_set(error, LK_ERR_PARSE, "%s: no DATA line (not a PCD header?)", name);
}

/* LZF (liblzf's format): a control byte below 32 starts a run of ctrl + 1
 * literal bytes; else its top 3 bits are a length - 2 (7: one more length
 * byte follows) and its low 5 bits with the next byte an offset - 1 back
 * into the output. Every copy is checked against both buffers. */
static lk_status lzf_decompress(const unsigned char *in, size_t in_size, size_t in_offset, unsigned char *out,
                                size_t out_size, const char *name, lk_error *error)
{
    size_t ip = 0, op = 0;
    while (ip < in_size) {
        size_t at = in_offset + ip;
        unsigned ctrl = in[ip++];
        if (ctrl < 32) {
            size_t length = ctrl + 1u;
            if (length > in_size - ip)
                return lk__error_at_byte(error, LK_ERR_PARSE, name, at,
                                         "LZF literal run of %zu bytes past the data's end", length);
            if (length > out_size - op)
                return lk__error_at_byte(error, LK_ERR_PARSE, name, at,
                                         "LZF data decompresses to more than the %zu bytes announced", out_size);
            memcpy(out + op, in + ip, length);
            ip += length;
            op += length;
            continue;
        }
        size_t length = ctrl >> 5;
        if (length == 7) {
            if (ip >= in_size) return lk__error_at_byte(error, LK_ERR_PARSE, name, at, "LZF back-reference cut short");
            length += in[ip++];
        }
        if (ip >= in_size) return lk__error_at_byte(error, LK_ERR_PARSE, name, at, "LZF back-reference cut short");
        size_t distance = (((size_t)(ctrl & 0x1f) << 8) | in[ip++]) + 1;
        length += 2;
        if (distance > op)
            return lk__error_at_byte(error, LK_ERR_PARSE, name, at,
                                     "LZF back-reference %zu bytes back from output byte %zu (before the start)",
                                     distance, op);
        if (length > out_size - op)
            return lk__error_at_byte(error, LK_ERR_PARSE, name, at,
                                     "LZF data decompresses to more than the %zu bytes announced", out_size);
        /* Byte by byte: the source may overlap what is being written. */
        for (size_t k = 0; k < length; k++, op++) out[op] = out[op - distance];
    }
    if (op != out_size)
        return lk__error_at_byte(error, LK_ERR_PARSE, name, in_offset + in_size,
                                 "LZF data decompresses to %zu bytes, the header announced %zu", op, out_size);
    return LK_OK;
}

static double binary_value(const unsigned char *at, const pcd_field *field)
{
    /* PCD's TYPE letters F U I are NumPy's f u i */
    char kind = field->type == 'F' ? 'f' : field->type == 'U' ? 'u' : 'i';
    return lk__load_number_le(at, (unsigned)field->size, kind);
}

static uint32_t binary_color(const unsigned char *at)
{
    return (uint32_t)at[0] | (uint32_t)at[1] << 8 | (uint32_t)at[2] << 16 | (uint32_t)at[3] << 24;
}

/* Stores one point (values or packed colour already decoded); false when
 * a coordinate is NaN (or infinite) and it is dropped. A normal that is
 * not finite (PCL's mark of "could not be estimated") becomes 0 0 0. */
static bool store_point(lk_mesh *mesh, size_t kept, const double position[3], const double normal[3], uint32_t color,
                        bool color_has_alpha)
{
    float point[3], direction[3];
    bool normal_finite = true;
    for (int k = 0; k < 3; k++) {
        point[k] = (float)position[k];
        direction[k] = (float)normal[k];
        if (!isfinite(point[k])) return false;
        normal_finite &= isfinite(direction[k]) != 0;
    }
    memcpy(mesh->positions + 3 * kept, point, sizeof point);
    if (mesh->normals) {
        if (!normal_finite) direction[0] = direction[1] = direction[2] = 0.0f;
        memcpy(mesh->normals + 3 * kept, direction, sizeof direction);
    }
    if (mesh->colors) {
        float *rgba = mesh->colors + 4 * kept;
        rgba[0] = (float)((color >> 16) & 0xff) / 255.0f;
        rgba[1] = (float)((color >> 8) & 0xff) / 255.0f;
        rgba[2] = (float)(color & 0xff) / 255.0f;
        rgba[3] = color_has_alpha ? (float)(color >> 24) / 255.0f : 1.0f;
    }
    return true;
}

/* The values of record i of a binary or decompressed body (count records:
 * interleaved, or field after field): x y z, the normal (0 when absent) and
 * the packed colour. */
static void record_values(const pcd_header *header, const unsigned char *body, size_t i, size_t count, bool by_field,
                          double values[6], uint32_t *color)
{
    const int roles[6] = {header->x, header->y, header->z, header->nx, header->ny, header->nz};
    for (int r = 0; r < 6; r++) {
        values[r] = 0;
        if (roles[r] < 0) continue;
        const pcd_field *field = &header->fields[roles[r]];
        size_t at = by_field ? field->offset * count + i * (size_t)field->size * field->count
                             : i * header->point_size + field->offset;
        values[r] = binary_value(body + at, field);
    }
    *color = 0;
    if (header->color >= 0) {
        const pcd_field *field = &header->fields[header->color];
        size_t at = by_field ? field->offset * count + i * (size_t)field->size * field->count
                             : i * header->point_size + field->offset;
        *color = binary_color(body + at);
    }
}

/* Records of a binary or decompressed body: interleaved, or field after field. */
static size_t read_records(const pcd_header *header, const unsigned char *body, bool by_field, lk_mesh *mesh)
{
    size_t count = (size_t)header->points, kept = 0;
    for (size_t i = 0; i < count; i++) {
        double values[6];
        uint32_t color;
        record_values(header, body, i, count, by_field, values, &color);
        if (store_point(mesh, kept, values, values + 3, color, header->color_has_alpha)) kept++;
    }
    return kept;
}

/* The values of an ascii point line [q, line_end) (number `line`), as
 * record_values; an ascii value of a float field rounded to float, as a
 * binary one would hold it. */
static lk_status ascii_values(const pcd_header *header, const char *q, const char *line_end, const char *name,
                              size_t line, double values[6], uint32_t *color, lk_error *error)
{
    const int roles[6] = {header->x, header->y, header->z, header->nx, header->ny, header->nz};
    for (int r = 0; r < 6; r++) values[r] = 0;
    *color = 0;
    for (size_t f = 0, v = 0; f < header->field_count; f++) {
        const pcd_field *field = &header->fields[f];
        for (size_t e = 0; e < field->count; e++, v++) {
            double value;
            if (!lk__parse_double(&q, line_end, &value)) {
                char token[32];
                lk__quote_token(q, line_end, token, sizeof token);
                if (token[0])
                    return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected a number, got '%s'", token);
                return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected %zu values per point, got %zu",
                                         header->values_per_point, v);
            }
            if (e != 0) continue;
            for (int r = 0; r < 6; r++)
                if (roles[r] == (int)f)
                    values[r] = field->type == 'F' && field->size == 4 ? (double)(float)value : value;
            if ((int)f == header->color) {
                if (field->type == 'F') { /* the float's bits are the colour */
                    float as_float = (float)value;
                    memcpy(color, &as_float, 4);
                } else {
                    *color = value >= 0 && value <= 4294967295.0   ? (uint32_t)value
                             : value < 0 && value >= -2147483648.0 ? (uint32_t)(int32_t)value
                                                                   : 0;
                }
            }
        }
    }
    q = lk__skip_spaces(q, line_end);
    if (q < line_end)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "more than %zu values per point",
                                 header->values_per_point);
    return LK_OK;
}

static lk_status read_ascii(const pcd_header *header, const char *data, size_t size, const char *name, lk_mesh *mesh,
                            size_t *kept_out, lk_error *error)
{
    const char *p = data + header->data_offset, *end = data + size;
    size_t line = header->data_line - 1, count = (size_t)header->points, kept = 0;
    for (size_t i = 0; i < count;) {
        if (p >= end)
            return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: the file ends after %zu of %zu points", name, line, i,
                                count);
        line++;
        const char *line_end = memchr(p, '\n', (size_t)(end - p));
        if (!line_end) line_end = end;
        const char *q = lk__skip_spaces(p, line_end);
        p = line_end < end ? line_end + 1 : end;
        if (q >= line_end) continue; /* blank line */
        double values[6];
        uint32_t color;
        lk_status status = ascii_values(header, q, line_end, name, line, values, &color, error);
        if (status != LK_OK) return status;
        if (store_point(mesh, kept, values, values + 3, color, header->color_has_alpha)) kept++;
        i++;
    }
    *kept_out = kept;
    return LK_OK;
}

/* ---- streamed point clouds (the octree's reader) --------------------------- */

/* A point as the octree takes it: false when a coordinate is not finite
 * (dropped, as lk__read_pcd drops it); a normal that is not finite becomes
 * 0 0 0. */
static bool stream_point(const pcd_header *header, const double values[6], uint32_t color, double xyz[3],
                         float normal[3], uint8_t rgb[3])
{
    for (int k = 0; k < 3; k++)
        if (!isfinite(values[k])) return false;
    bool normal_finite = true;
    for (int k = 0; k < 3; k++) {
        xyz[k] = values[k];
        normal[k] = (float)values[3 + k];
        normal_finite &= isfinite(normal[k]) != 0;
    }
    if (!normal_finite) normal[0] = normal[1] = normal[2] = 0.0f;
    (void)header;
    rgb[0] = (uint8_t)(color >> 16), rgb[1] = (uint8_t)(color >> 8), rgb[2] = (uint8_t)color;
    return true;
}

lk_status lk__pcd_stream_open(const char *head, size_t head_size, unsigned long long file_size, const char *name,
                              lk__pcd_stream *stream, lk_error *error)
{
    memset(stream, 0, sizeof *stream);
    pcd_header *header = malloc(sizeof *header);
    if (!header) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
    lk_status status = parse_header(head, head_size, name, header, error);
    if (status != LK_OK && head_size < file_size && strstr(error ? error->message : "", "no DATA line"))
        status = LK_ERR_UNSUPPORTED; /* a header longer than `head`: read whole */
    if (status == LK_OK && header->data_kind == PCD_COMPRESSED) status = LK_ERR_UNSUPPORTED;
    unsigned long long available = status == LK_OK ? file_size - header->data_offset : 0;
    if (status == LK_OK && header->points == 0)
        status = lk__error_at_line(error, LK_ERR_PARSE, name, header->data_line - 1, "no points (POINTS 0)");
    if (status == LK_OK && header->data_kind == PCD_BINARY && header->points > available / header->point_size)
        status = lk__error_at_byte(error, LK_ERR_PARSE, name, header->data_offset,
                                   "truncated: %llu points of %zu bytes need %llu bytes, only %llu follow",
                                   header->points, header->point_size, header->points * header->point_size, available);
    if (status != LK_OK) {
        free(header);
        return status;
    }
    stream->header = header;
    stream->binary = header->data_kind == PCD_BINARY;
    stream->data_offset = header->data_offset;
    stream->data_line = header->data_line;
    stream->record_size = header->point_size;
    stream->points = header->points;
    stream->has_normals = header->nx >= 0;
    stream->has_colors = header->color >= 0;
    return LK_OK;
}

void lk__pcd_stream_close(lk__pcd_stream *stream)
{
    free(stream->header);
    stream->header = NULL;
}

bool lk__pcd_stream_record(const lk__pcd_stream *stream, const unsigned char *record, double xyz[3], float normal[3],
                           uint8_t rgb[3])
{
    double values[6];
    uint32_t color;
    record_values(stream->header, record, 0, 1, false, values, &color);
    return stream_point(stream->header, values, color, xyz, normal, rgb);
}

lk_status lk__pcd_stream_line(const lk__pcd_stream *stream, const char *p, const char *end, const char *name,
                              size_t line, double xyz[3], float normal[3], uint8_t rgb[3], bool *kept, lk_error *error)
{
    double values[6];
    uint32_t color;
    lk_status status = ascii_values(stream->header, lk__skip_spaces(p, end), end, name, line, values, &color, error);
    *kept = status == LK_OK && stream_point(stream->header, values, color, xyz, normal, rgb);
    return status;
}

lk_status lk__read_pcd(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    pcd_header *header = malloc(sizeof *header); /* fixed size (256 fields), not charged */
    if (!header) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
    lk_status status = parse_header(data, size, ctx->name, header, error);
    unsigned char *decompressed = NULL;
    size_t decompressed_charge = 0, mesh_charge_count = 0, kept = 0;
    unsigned flags = (header->nx >= 0 ? LK_ATTR_NORMALS : 0u) | (header->color >= 0 ? LK_ATTR_COLORS : 0u);
    size_t available = size - (status == LK_OK ? header->data_offset : 0);
    char where[300];
    snprintf(where, sizeof where, "%s:%zu", ctx->name, header->data_line ? header->data_line - 1 : 0);
    if (status == LK_OK && header->points == 0)
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no points (POINTS 0)", where);
    size_t per_point = (3 + (header->nx >= 0 ? 3 : 0) + (header->color >= 0 ? 4 : 0)) * sizeof(float);
    if (status == LK_OK && header->data_kind == PCD_ASCII) {
        /* a value and a separator each; the last line may lack its newline */
        if (header->points > (available + 1) / (2 * header->values_per_point))
            status = lk_error_set(error, LK_ERR_LIMIT,
                                  "%s: header claims %llu points but only %zu bytes follow (truncated or corrupt file)",
                                  where, header->points, available);
        else
            status = lk__check_claim(header->points, 0, available, per_point, ctx->budget, "points", where, error);
    }
    if (status == LK_OK && header->data_kind == PCD_BINARY) {
        if (header->points > available / header->point_size)
            status =
                lk__error_at_byte(error, LK_ERR_PARSE, ctx->name, header->data_offset,
                                  "truncated: %llu points of %zu bytes need %llu bytes, only %zu follow",
                                  header->points, header->point_size, header->points * header->point_size, available);
        else
            status = lk__check_claim(header->points, 0, available, per_point, ctx->budget, "points", where, error);
    }
    size_t compressed_size = 0;
    if (status == LK_OK && header->data_kind == PCD_COMPRESSED) {
        const unsigned char *at = (const unsigned char *)data + header->data_offset;
        if (available < 8) {
            status = lk__error_at_byte(error, LK_ERR_PARSE, ctx->name, header->data_offset,
                                       "truncated: the compressed and uncompressed sizes need 8 bytes, only %zu follow",
                                       available);
        } else {
            compressed_size = binary_color(at);
            uint32_t uncompressed_size = binary_color(at + 4);
            if (compressed_size > available - 8)
                status = lk__error_at_byte(error, LK_ERR_PARSE, ctx->name, header->data_offset,
                                           "compressed size %zu is more than the %zu bytes that follow",
                                           compressed_size, available - 8);
            else if (header->points > ~0ull / header->point_size ||
                     uncompressed_size != header->points * header->point_size)
                status = lk__error_at_byte(error, LK_ERR_PARSE, ctx->name, header->data_offset + 4,
                                           "uncompressed size %u is not POINTS %llu x %zu bytes per point",
                                           (unsigned)uncompressed_size, header->points, header->point_size);
            /* One LZF back-reference of 3 bytes gives at most 264: a larger
             * claim cannot be real (and is not allocated). */
            else if ((unsigned long long)uncompressed_size > 88ull * compressed_size)
                status = lk__error_at_byte(error, LK_ERR_PARSE, ctx->name, header->data_offset + 4,
                                           "uncompressed size %u cannot come from %zu bytes of LZF data",
                                           (unsigned)uncompressed_size, compressed_size);
            else if (!lk__budget_charge(ctx->budget, uncompressed_size, 1))
                status = lk__error_at_byte(error, LK_ERR_LIMIT, ctx->name, header->data_offset + 4,
                                           "uncompressed size %u is more than the memory budget of %zu bytes",
                                           (unsigned)uncompressed_size, ctx->budget->limit);
            else {
                decompressed_charge = uncompressed_size;
                decompressed = malloc(uncompressed_size ? uncompressed_size : 1);
                if (!decompressed) status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
            }
            if (status == LK_OK)
                status = lzf_decompress(at + 8, compressed_size, header->data_offset + 8, decompressed,
                                        uncompressed_size, ctx->name, error);
            if (status == LK_OK)
                status = lk__check_claim(header->points, 0, available, per_point, ctx->budget, "points", where, error);
        }
    }
    if (status == LK_OK) {
        if (!lk__budget_charge_mesh(ctx->budget, (size_t)header->points, 0, flags))
            status =
                lk_error_set(error, LK_ERR_LIMIT, "%s: %llu points would need more than the memory budget of %zu bytes",
                             where, header->points, ctx->budget->limit);
        else
            mesh_charge_count = (size_t)header->points;
    }
    if (status == LK_OK) status = lk_mesh_alloc(mesh, (size_t)header->points, 0, flags, error);
    if (status == LK_OK) {
        if (header->data_kind == PCD_ASCII)
            status = read_ascii(header, data, size, ctx->name, mesh, &kept, error);
        else if (header->data_kind == PCD_BINARY)
            kept = read_records(header, (const unsigned char *)data + header->data_offset, false, mesh);
        else
            kept = read_records(header, decompressed, true, mesh);
    }
    if (status == LK_OK && kept == 0)
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no points left: all %llu have NaN coordinates", ctx->name,
                              header->points);
    free(decompressed);
    lk__budget_release(ctx->budget, decompressed_charge, 1);
    free(header);
    if (status != LK_OK) {
        lk_mesh_free(mesh);
        lk__budget_release(ctx->budget, mesh_charge_count, per_point);
        return status;
    }
    /* Dropped points (NaN) leave the arrays' tails unused. */
    mesh->vertex_count = kept;
    /* Older PCL clouds leave the alpha byte of rgba at 0 for every point
     * (python-pcl's milk.pcd): that means "no alpha", not invisible. */
    bool all_transparent = mesh->colors != NULL;
    for (size_t i = 0; i < kept && all_transparent; i++) all_transparent = mesh->colors[4 * i + 3] == 0.0f;
    if (all_transparent)
        for (size_t i = 0; i < kept; i++) mesh->colors[4 * i + 3] = 1.0f;
    return LK_OK;
}
