/* SPDX-License-Identifier: MIT */
/* Object File Format (Geomview OFF) reader and writer.
 *
 * Header keyword [ST][C][N]OFF, then counts "V F E" (E optional, may share
 * the header line), then V vertex lines and F face lines. A vertex line is
 *     x y z [nx ny nz] [r g b [a]] [s t]
 * with the optional groups present when N, C and ST are in the keyword.
 * Colours are integers 0..255 when every component is written as an
 * integer, otherwise floats 0..1. A face line is "k i1 .. ik [colour]"
 * (0-based indices); polygons become a fan around i1 and face colours are
 * ignored. Comments start with '#'. Each vertex and face is on its own line.
 *
 * The writer emits OFF, or COFF with float colours "r g b a" (always with a
 * decimal point, so they read back exactly and are never mistaken for
 * 0..255 integers) when the mesh has colours and they are not skipped. */
#include "internal.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

typedef struct off_reader {
    const char *name;
    lk_error *error;
    const char *p, *end; /* cursor: start of the next unread line */
    size_t line;         /* number of the last line handed out */
} off_reader;

static lk_status off_fail(off_reader *reader, lk_status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static lk_status off_fail(off_reader *reader, lk_status status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_line_v(reader->error, status, reader->name, reader->line, format, args);
    va_end(args);
    return status;
}

/* Hands out the next line that holds data, without its comment, skipping
 * blank and comment-only lines. Returns false at the end of the input. */
static bool off_next_line(off_reader *reader, const char **line_start, const char **line_end)
{
    while (reader->p < reader->end) {
        const char *start = reader->p;
        const char *newline = memchr(start, '\n', (size_t)(reader->end - start));
        const char *stop = newline ? newline : reader->end;
        reader->p = newline ? newline + 1 : reader->end;
        reader->line++;
        const char *comment = memchr(start, '#', (size_t)(stop - start));
        if (comment) stop = comment;
        const char *first = lk__skip_spaces(start, stop);
        if (first < stop) {
            *line_start = first;
            *line_end = stop;
            return true;
        }
    }
    return false;
}

/* A number token written as an integer (optional sign, digits only). */
static bool off_is_integer_token(const char *start, const char *stop)
{
    if (start < stop && (*start == '+' || *start == '-')) start++;
    if (start >= stop) return false;
    for (; start < stop; start++)
        if (*start < '0' || *start > '9') return false;
    return true;
}

typedef struct off_layout {
    bool texcoords, colors, normals;
} off_layout;

#define OFF_MAX_FIELDS 16

/* Parses the header keyword at the start of the first data line. */
static lk_status off_read_keyword(off_reader *reader, const char **p, const char *end, off_layout *layout)
{
    const char *s = *p;
    const char *token_end = s;
    while (token_end < end && !lk__is_space(*token_end)) token_end++;
    char token[32];
    lk__quote_token(s, end, token, sizeof token);
    if ((size_t)(token_end - s) >= 2 && memcmp(s, "ST", 2) == 0) {
        layout->texcoords = true;
        s += 2;
    }
    if (s < token_end && *s == 'C') {
        layout->colors = true;
        s++;
    }
    if (s < token_end && *s == 'N') {
        layout->normals = true;
        s++;
    }
    if (s < token_end && (*s == '4' || *s == 'n'))
        return off_fail(reader, LK_ERR_UNSUPPORTED, "'%s': 4D and n-dimensional OFF files are not supported", token);
    if (token_end - s != 3 || memcmp(s, "OFF", 3) != 0)
        return off_fail(reader, LK_ERR_PARSE,
                        "missing OFF header: expected OFF, COFF, NOFF, CNOFF or STOFF first, got '%s'", token);
    s = lk__skip_spaces(token_end, end);
    if ((size_t)(end - s) >= 6 && lk__word_equals(s, 6, "BINARY"))
        return off_fail(reader, LK_ERR_UNSUPPORTED, "binary OFF is not supported (convert it to ASCII OFF)");
    *p = s;
    return LK_OK;
}

/* Reads "V F [E]" and refuses counts the remaining bytes or the budget
 * cannot hold; charges the vertex arrays. */
static lk_status off_read_counts(off_reader *reader, const char *p, const char *end, unsigned flags,
                                 size_t bytes_per_vertex, lk__budget *budget, long long *vertex_count,
                                 long long *face_count)
{
    if (p >= end && !off_next_line(reader, &p, &end))
        return off_fail(reader, LK_ERR_PARSE, "file ends before the counts line 'vertices faces edges'");
    long long edge_count;
    if (!lk__parse_int64(&p, end, vertex_count) || !lk__parse_int64(&p, end, face_count))
        return off_fail(reader, LK_ERR_PARSE, "expected the counts 'vertices faces edges' after the header");
    lk__parse_int64(&p, end, &edge_count); /* optional and unused */
    if (lk__skip_spaces(p, end) != end) {
        char token[32];
        lk__quote_token(p, end, token, sizeof token);
        return off_fail(reader, LK_ERR_PARSE, "unexpected '%s' after the counts 'vertices faces edges'", token);
    }
    if (*vertex_count < 0 || *face_count < 0)
        return off_fail(reader, LK_ERR_PARSE, "negative count in the header (%lld vertices, %lld faces)", *vertex_count,
                        *face_count);
    char where[300];
    snprintf(where, sizeof where, "%s:%zu", reader->name, reader->line);
    /* Shortest possible lines: "0 0 0\n" and "3 0 1 2\n"; the last line
     * may lack its newline. */
    size_t available = (size_t)(reader->end - reader->p) + 1;
    lk_status status = lk__check_claim((unsigned long long)*vertex_count, 6, available, bytes_per_vertex, budget,
                                       "vertices", where, reader->error);
    if (status != LK_OK) return status;
    size_t vertices = (size_t)*vertex_count;
    lk__budget_charge_mesh(budget, vertices, 0, flags); /* fits: checked above */
    return lk__check_claim((unsigned long long)*face_count, 8, available - 6 * vertices, 12, budget,
                           "faces after the vertex lines", where, reader->error);
}

static lk_status off_read_vertex(off_reader *reader, const off_layout *layout, lk_mesh *mesh, size_t vertex)
{
    const char *p, *end;
    if (!off_next_line(reader, &p, &end))
        return off_fail(reader, LK_ERR_PARSE, "expected %zu vertices, file ends after %zu", mesh->vertex_count, vertex);
    double values[OFF_MAX_FIELDS];
    const char *starts[OFF_MAX_FIELDS + 1];
    int count = 0;
    for (;;) {
        const char *start = lk__skip_spaces(p, end);
        double value;
        if (!lk__parse_double(&p, end, &value)) break;
        if (count < OFF_MAX_FIELDS) {
            values[count] = value;
            starts[count] = start;
        }
        count++;
    }
    if (lk__skip_spaces(p, end) != end) {
        char token[32];
        lk__quote_token(p, end, token, sizeof token);
        return off_fail(reader, LK_ERR_PARSE, "vertex %zu: expected a number, got '%s'", vertex, token);
    }
    if (count > OFF_MAX_FIELDS) count = OFF_MAX_FIELDS;
    starts[count] = p;
    int fixed = 3 + (layout->normals ? 3 : 0);
    int texcoord_fields = layout->texcoords ? 2 : 0;
    int color_fields = 0;
    if (layout->colors) {
        color_fields = count - fixed - texcoord_fields;
        if (!layout->texcoords && color_fields > 4) color_fields = 4;
    }
    if (count < fixed + texcoord_fields + (layout->colors ? 3 : 0) || (layout->colors && color_fields > 4))
        return off_fail(reader, LK_ERR_PARSE, "vertex %zu: expected x y z%s%s%s, got %d numbers", vertex,
                        layout->normals ? " nx ny nz" : "", layout->colors ? " r g b [a]" : "",
                        layout->texcoords ? " s t" : "", count);
    for (int i = 0; i < fixed + color_fields + texcoord_fields; i++) {
        if (!isfinite((float)values[i]))
            return off_fail(reader, LK_ERR_RANGE, "vertex %zu: %g is not a finite float", vertex, values[i]);
    }
    for (int k = 0; k < 3; k++) mesh->positions[3 * vertex + (size_t)k] = (float)values[k];
    if (layout->normals)
        for (int k = 0; k < 3; k++) mesh->normals[3 * vertex + (size_t)k] = (float)values[3 + k];
    if (layout->colors) {
        bool integers = true;
        for (int k = 0; k < color_fields; k++) {
            /* Token text ends at the next token's start (or the cursor). */
            const char *stop = starts[fixed + k + 1];
            while (stop > starts[fixed + k] && lk__is_space(stop[-1])) stop--;
            if (!off_is_integer_token(starts[fixed + k], stop)) integers = false;
        }
        float *color = mesh->colors + 4 * vertex;
        color[3] = 1.0f;
        for (int k = 0; k < color_fields; k++)
            color[k] = integers ? (float)(values[fixed + k] / 255.0) : (float)values[fixed + k];
    }
    if (layout->texcoords)
        for (int k = 0; k < 2; k++) mesh->texcoords[2 * vertex + (size_t)k] = (float)values[fixed + color_fields + k];
    return LK_OK;
}

typedef struct off_triangles {
    uint32_t *indices;
    size_t count, capacity; /* the capacity is charged to the budget */
    lk__budget *budget;
} off_triangles;

/* Makes room for `extra` more triangles within the budget (the first
 * reservation is the face count: exact for triangle meshes). Returns LK_OK,
 * LK_ERR_LIMIT or LK_ERR_NOMEM. */
static lk_status off_reserve_triangles(off_triangles *triangles, size_t extra)
{
    if (extra > SIZE_MAX - triangles->count) return LK_ERR_LIMIT;
    size_t need = triangles->count + extra;
    if (need <= triangles->capacity) return LK_OK;
    size_t capacity = lk__budget_grow_capacity(triangles->budget, triangles->capacity, need, 12, 64);
    if (capacity == 0) return LK_ERR_LIMIT;
    uint32_t *indices = lk__realloc_array(triangles->indices, capacity, 3 * sizeof(uint32_t));
    if (!indices) return LK_ERR_NOMEM;
    lk__budget_charge(triangles->budget, capacity - triangles->capacity, 12); /* fits */
    triangles->indices = indices;
    triangles->capacity = capacity;
    return LK_OK;
}

static lk_status off_read_index(off_reader *reader, const char **p, const char *end, size_t vertex_count,
                                long long corner_count, long long corner, uint32_t *out)
{
    long long value;
    const char *s = *p;
    if (!lk__parse_int64(&s, end, &value)) {
        char token[32];
        lk__quote_token(s, end, token, sizeof token);
        return off_fail(reader, LK_ERR_PARSE, "expected %lld vertex indices, got %lld%s%s%s", corner_count, corner,
                        token[0] ? " then '" : "", token, token[0] ? "'" : "");
    }
    if (s < end && !lk__is_space(*s)) {
        char token[32];
        lk__quote_token(*p, end, token, sizeof token);
        return off_fail(reader, LK_ERR_PARSE, "vertex index '%s' is not an integer", token);
    }
    if (value < 0 || (unsigned long long)value >= vertex_count)
        return off_fail(reader, LK_ERR_RANGE, "vertex index %lld out of range (%zu vertices)", value, vertex_count);
    *out = (uint32_t)value;
    *p = s;
    return LK_OK;
}

static lk_status off_read_face(off_reader *reader, size_t vertex_count, size_t face_count, size_t face,
                               off_triangles *triangles)
{
    const char *p, *end;
    if (!off_next_line(reader, &p, &end))
        return off_fail(reader, LK_ERR_PARSE, "expected %zu faces, file ends after %zu", face_count, face);
    long long corner_count;
    if (!lk__parse_int64(&p, end, &corner_count)) {
        char token[32];
        lk__quote_token(p, end, token, sizeof token);
        return off_fail(reader, LK_ERR_PARSE, "expected a face 'count index index index ...', got '%s'", token);
    }
    if (corner_count < 3)
        return off_fail(reader, LK_ERR_PARSE, "face has %lld vertices, expected at least 3", corner_count);
    /* Each index takes at least two characters, which bounds the growth. */
    if (corner_count > (end - p) / 2 + 1)
        return off_fail(reader, LK_ERR_PARSE, "face claims %lld vertices but the line is too short", corner_count);
    /* Polygons are fanned: a line of n indices (2n bytes) makes n - 2
     * triangles of 12 bytes, so the faces can need 6 times the file. */
    lk_status reserved = off_reserve_triangles(triangles, (size_t)corner_count - 2);
    if (reserved == LK_ERR_LIMIT)
        return off_fail(reader, LK_ERR_LIMIT,
                        "face of %lld vertices: the triangles would need more than the memory budget", corner_count);
    if (reserved != LK_OK) return lk_error_set(reader->error, LK_ERR_NOMEM, "%s: out of memory", reader->name);
    uint32_t first, previous, current;
    lk_status status = off_read_index(reader, &p, end, vertex_count, corner_count, 0, &first);
    if (status == LK_OK) status = off_read_index(reader, &p, end, vertex_count, corner_count, 1, &previous);
    for (long long corner = 2; status == LK_OK && corner < corner_count; corner++) {
        status = off_read_index(reader, &p, end, vertex_count, corner_count, corner, &current);
        if (status != LK_OK) break;
        uint32_t *out = triangles->indices + 3 * triangles->count++;
        out[0] = first;
        out[1] = previous;
        out[2] = current;
        previous = current;
    }
    return status; /* anything after the indices is a face colour: ignored */
}

lk_status lk__read_off(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    off_reader reader = {ctx->name, error, data, data + size, 0};
    lk_mesh_init(mesh);
    const char *p, *end;
    if (!off_next_line(&reader, &p, &end))
        return lk_error_set(error, LK_ERR_PARSE, "%s: no OFF header (the file holds only comments or blanks)",
                            ctx->name);
    off_layout layout = {false, false, false};
    lk_status status = off_read_keyword(&reader, &p, end, &layout);
    if (status != LK_OK) return status;
    size_t bytes_per_vertex = 12 + (layout.normals ? 12 : 0) + (layout.colors ? 16 : 0) + (layout.texcoords ? 8 : 0);
    long long vertex_count, face_count;
    unsigned flags = (layout.normals ? LK_ATTR_NORMALS : 0u) | (layout.colors ? LK_ATTR_COLORS : 0u) |
                     (layout.texcoords ? LK_ATTR_TEXCOORDS : 0u);
    status = off_read_counts(&reader, p, end, flags, bytes_per_vertex, ctx->budget, &vertex_count, &face_count);
    if (status != LK_OK) return status;
    status = lk_mesh_alloc(mesh, (size_t)vertex_count, 0, flags, error);
    if (status != LK_OK) return status;
    off_triangles triangles = {NULL, 0, 0, ctx->budget};
    for (size_t v = 0; status == LK_OK && v < mesh->vertex_count; v++)
        status = off_read_vertex(&reader, &layout, mesh, v);
    /* off_read_counts made sure one triangle per face fits. */
    if (status == LK_OK && face_count > 0 && off_reserve_triangles(&triangles, (size_t)face_count) != LK_OK)
        status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
    for (size_t f = 0; status == LK_OK && f < (size_t)face_count; f++)
        status = off_read_face(&reader, mesh->vertex_count, (size_t)face_count, f, &triangles);
    if (status == LK_OK && triangles.count > LK_MAX_ELEMENTS)
        status = lk_error_set(error, LK_ERR_LIMIT, "%s: %zu triangles is more than lodkit supports", ctx->name,
                              triangles.count);
    if (status != LK_OK) {
        free(triangles.indices);
        lk_mesh_free(mesh);
        return status;
    }
    /* Trailing text after the last face is ignored. */
    if (triangles.indices) {
        free(mesh->indices);
        mesh->indices = triangles.indices;
        mesh->triangle_count = triangles.count;
    }
    return LK_OK;
}

/* ---- writer ------------------------------------------------------------ */

/* A float that always reads back as a float token (never as an integer). */
static int off_format_color(char *buffer, size_t size, float value)
{
    int length = lk__format_float(buffer, size, value);
    if (!strpbrk(buffer, ".eEnNiI") && length + 2 < (int)size) {
        memcpy(buffer + length, ".0", 3);
        length += 2;
    }
    return length;
}

lk_status lk__write_off(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error)
{
    bool with_colors = mesh->colors && !options->skip_colors;
    fprintf(file, "%s\n# lodkit %s\n%zu %zu 0\n", with_colors ? "COFF" : "OFF", lk_version(), mesh->vertex_count,
            mesh->triangle_count);
    char line[320];
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        size_t at = 0;
        for (int k = 0; k < 3; k++) {
            if (k) line[at++] = ' ';
            at += (size_t)lk__format_float(line + at, 32, mesh->positions[3 * i + (size_t)k]);
        }
        if (with_colors) {
            for (int k = 0; k < 4; k++) {
                line[at++] = ' ';
                at += (size_t)off_format_color(line + at, 32, mesh->colors[4 * i + (size_t)k]);
            }
        }
        line[at++] = '\n';
        fwrite(line, 1, at, file);
    }
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *triangle = mesh->indices + 3 * t;
        fprintf(file, "3 %lu %lu %lu\n", (unsigned long)triangle[0], (unsigned long)triangle[1],
                (unsigned long)triangle[2]);
    }
    if (ferror(file)) return lk_error_set(error, LK_ERR_IO, "write error while writing OFF");
    return LK_OK;
}
