/* SPDX-License-Identifier: MIT */
/* Simple Model Format (Garland's SMF, as read and written by QSlim).
 *
 * Statements, one per line:
 *   v x y z          vertex
 *   f a b c ...      face, 1-based indices (negative: relative); polygons
 *                    become a fan around the first corner
 *   n x y z          normal    } attached per vertex in file order while
 *   c r g b          colour    } their binding is "vertex" (the default);
 *   r u v            texcoord  } under "face"/"corner" binding they are ignored
 *   bind n|c|r vertex|face|corner
 *   # comment
 * Transform and grouping statements (begin, end, set, t, s, rot, scale,
 * trans, tex) are skipped; any other keyword is an error. The writer emits
 * positions and triangles only. */
#include "internal.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

enum { SMF_NORMAL, SMF_COLOR, SMF_TEXCOORD, SMF_ATTRIBUTE_COUNT };

typedef struct smf_attribute {
    const char *what;  /* "normal", ... for messages */
    int width;         /* floats per element as stored in the mesh */
    bool per_vertex;   /* current binding */
    lk__buffer values; /* float[width] per per-vertex element */
    size_t count;
    size_t last_line; /* line of the last per-vertex element */
} smf_attribute;

typedef struct smf_parser {
    const char *name;
    lk__budget *budget; /* every buffer is charged to it */
    lk_error *error;
    lk__buffer positions; /* float[3] per `v` */
    lk__buffer indices;   /* uint32_t[3] per triangle, 1-based until checked */
    lk__buffer polygon;   /* uint32_t per corner of the face being read */
    size_t vertex_count;
    uint32_t max_index; /* largest positive index used by a face */
    size_t max_index_line;
    smf_attribute attributes[SMF_ATTRIBUTE_COUNT];
} smf_parser;

static lk_status smf_fail(smf_parser *parser, size_t line, lk_status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
static lk_status smf_fail(smf_parser *parser, size_t line, lk_status status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_line_v(parser->error, status, parser->name, line, format, args);
    va_end(args);
    return status;
}

static lk_status smf_out_of_memory(smf_parser *parser)
{
    return lk_error_set(parser->error, LK_ERR_NOMEM, "%s: out of memory", parser->name);
}

/* Everything the parser holds counts against the budget (a file of short
 * lines can ask for several times its own size): grows `buffer` by `extra`
 * bytes, charged. */
static lk_status smf_reserve(smf_parser *parser, size_t line, lk__buffer *buffer, size_t extra)
{
    lk_status status = lk__buffer_reserve_charged(buffer, extra, parser->budget);
    if (status == LK_ERR_LIMIT)
        return smf_fail(parser, line, LK_ERR_LIMIT, "the model needs more than the memory budget of %zu bytes",
                        parser->budget->limit);
    return status == LK_OK ? LK_OK : smf_out_of_memory(parser);
}

static lk_status smf_append(smf_parser *parser, size_t line, lk__buffer *buffer, const void *bytes, size_t size)
{
    lk_status status = smf_reserve(parser, line, buffer, size);
    if (status != LK_OK) return status;
    memcpy(buffer->data + buffer->size, bytes, size);
    buffer->size += size;
    return LK_OK;
}

/* Reads exactly `count` finite numbers and nothing else on the line. */
static lk_status smf_read_numbers(smf_parser *parser, const char *p, const char *end, size_t line, const char *keyword,
                                  float *out, int count)
{
    for (int i = 0; i < count; i++) {
        double value;
        if (!lk__parse_double(&p, end, &value)) {
            char token[32];
            lk__quote_token(p, end, token, sizeof token);
            return smf_fail(parser, line, LK_ERR_PARSE, "expected %d numbers after '%s', got %d%s%s%s", count, keyword,
                            i, token[0] ? " then '" : "", token, token[0] ? "'" : "");
        }
        out[i] = (float)value;
        if (!isfinite(out[i]))
            return smf_fail(parser, line, LK_ERR_RANGE, "'%s' value %g is not a finite float", keyword, value);
    }
    if (lk__skip_spaces(p, end) != end) {
        char token[32];
        lk__quote_token(p, end, token, sizeof token);
        return smf_fail(parser, line, LK_ERR_PARSE, "expected %d numbers after '%s', got more: '%s'", count, keyword,
                        token);
    }
    return LK_OK;
}

static lk_status smf_read_attribute(smf_parser *parser, smf_attribute *attribute, const char *p, const char *end,
                                    size_t line, const char *keyword)
{
    float values[4] = {0, 0, 0, 1};
    int given = attribute->width == 4 ? 3 : attribute->width; /* colours: r g b, alpha 1 */
    lk_status status = smf_read_numbers(parser, p, end, line, keyword, values, given);
    if (status != LK_OK || !attribute->per_vertex) return status;
    status = smf_append(parser, line, &attribute->values, values, (size_t)attribute->width * sizeof(float));
    if (status != LK_OK) return status;
    attribute->count++;
    attribute->last_line = line;
    return LK_OK;
}

static lk_status smf_read_bind(smf_parser *parser, const char *p, const char *end, size_t line)
{
    const char *words[2];
    size_t lengths[2];
    for (int i = 0; i < 2; i++) {
        p = lk__skip_spaces(p, end);
        words[i] = p;
        while (p < end && !lk__is_space(*p)) p++;
        lengths[i] = (size_t)(p - words[i]);
    }
    int attribute = -1;
    if (lengths[0] == 1 && words[0][0] == 'n') attribute = SMF_NORMAL;
    if (lengths[0] == 1 && words[0][0] == 'c') attribute = SMF_COLOR;
    if (lengths[0] == 1 && words[0][0] == 'r') attribute = SMF_TEXCOORD;
    bool vertex = lk__word_equals(words[1], lengths[1], "vertex");
    bool other = lk__word_equals(words[1], lengths[1], "face") || lk__word_equals(words[1], lengths[1], "corner");
    if (attribute < 0 || (!vertex && !other) || lk__skip_spaces(p, end) != end)
        return smf_fail(parser, line, LK_ERR_PARSE, "expected 'bind n|c|r vertex|face|corner'");
    parser->attributes[attribute].per_vertex = vertex;
    return LK_OK;
}

static lk_status smf_read_face(smf_parser *parser, const char *p, const char *end, size_t line)
{
    parser->polygon.size = 0;
    for (;;) {
        p = lk__skip_spaces(p, end);
        if (p >= end) break;
        long long value;
        const char *start = p;
        if (!lk__parse_int64(&p, end, &value) || (p < end && !lk__is_space(*p))) {
            char token[32];
            lk__quote_token(start, end, token, sizeof token);
            return smf_fail(parser, line, LK_ERR_PARSE, "expected a vertex index after 'f', got '%s'", token);
        }
        uint32_t index;
        if (value == 0)
            return smf_fail(parser, line, LK_ERR_RANGE, "vertex index 0 is invalid (SMF indices start at 1)");
        if (value < 0) {
            if ((unsigned long long)-(value + 1) >= parser->vertex_count)
                return smf_fail(parser, line, LK_ERR_RANGE, "vertex index %lld out of range (%zu vertices so far)",
                                value, parser->vertex_count);
            index = (uint32_t)(parser->vertex_count - (size_t) - (value + 1));
        } else {
            if ((unsigned long long)value > LK_MAX_ELEMENTS)
                return smf_fail(parser, line, LK_ERR_RANGE, "vertex index %lld out of range", value);
            index = (uint32_t)value;
            if (index > parser->max_index) {
                parser->max_index = index;
                parser->max_index_line = line;
            }
        }
        lk_status status = smf_append(parser, line, &parser->polygon, &index, sizeof index);
        if (status != LK_OK) return status;
    }
    size_t corner_count = parser->polygon.size / sizeof(uint32_t);
    if (corner_count < 3)
        return smf_fail(parser, line, LK_ERR_PARSE, "expected at least 3 vertex indices after 'f', got %zu",
                        corner_count);
    size_t bytes = (corner_count - 2) * 3 * sizeof(uint32_t);
    lk_status status = smf_reserve(parser, line, &parser->indices, bytes);
    if (status != LK_OK) return status;
    const uint32_t *polygon = (const uint32_t *)parser->polygon.data;
    uint32_t *out = (uint32_t *)(parser->indices.data + parser->indices.size);
    for (size_t k = 1; k + 1 < corner_count; k++) {
        *out++ = polygon[0];
        *out++ = polygon[k];
        *out++ = polygon[k + 1];
    }
    parser->indices.size += bytes;
    return LK_OK;
}

static bool smf_is_skipped_keyword(const char *keyword, size_t length)
{
    static const char *const skipped[] = {"begin", "end", "set", "t", "s", "rot", "scale", "trans", "tex"};
    for (size_t i = 0; i < sizeof skipped / sizeof skipped[0]; i++)
        if (length == strlen(skipped[i]) && memcmp(keyword, skipped[i], length) == 0) return true;
    return false;
}

static lk_status smf_parse_line(smf_parser *parser, const char *p, const char *end, size_t line)
{
    p = lk__skip_spaces(p, end);
    if (p >= end || *p == '#') return LK_OK;
    const char *comment = memchr(p, '#', (size_t)(end - p));
    if (comment) end = comment;
    const char *keyword = p;
    while (p < end && !lk__is_space(*p)) p++;
    size_t length = (size_t)(p - keyword);
    if (length == 1) {
        switch (keyword[0]) {
        case 'v': {
            float position[3];
            lk_status status = smf_read_numbers(parser, p, end, line, "v", position, 3);
            if (status == LK_OK) status = smf_append(parser, line, &parser->positions, position, sizeof position);
            if (status != LK_OK) return status;
            parser->vertex_count++;
            return LK_OK;
        }
        case 'f': return smf_read_face(parser, p, end, line);
        case 'n': return smf_read_attribute(parser, &parser->attributes[SMF_NORMAL], p, end, line, "n");
        case 'c': return smf_read_attribute(parser, &parser->attributes[SMF_COLOR], p, end, line, "c");
        case 'r': return smf_read_attribute(parser, &parser->attributes[SMF_TEXCOORD], p, end, line, "r");
        default: break;
        }
    }
    if (length == 4 && memcmp(keyword, "bind", 4) == 0) return smf_read_bind(parser, p, end, line);
    if (smf_is_skipped_keyword(keyword, length)) return LK_OK;
    char token[32];
    lk__quote_token(keyword, end, token, sizeof token);
    return smf_fail(parser, line, LK_ERR_PARSE, "unknown SMF statement '%s' (expected v, f, n, c, r, bind or #)",
                    token);
}

static lk_status smf_parse(smf_parser *parser, const char *data, size_t size)
{
    const char *p = data, *end = data + size;
    size_t line = 0;
    while (p < end) {
        line++;
        const char *newline = memchr(p, '\n', (size_t)(end - p));
        const char *line_end = newline ? newline : end;
        lk_status status = smf_parse_line(parser, p, line_end, line);
        if (status != LK_OK) return status;
        p = newline ? newline + 1 : end;
    }
    return LK_OK;
}

static lk_status smf_build(smf_parser *parser, lk_mesh *mesh)
{
    if (parser->vertex_count == 0)
        return lk_error_set(parser->error, LK_ERR_PARSE, "%s: no vertices ('v' lines): not an SMF model", parser->name);
    if (parser->max_index > parser->vertex_count)
        return smf_fail(parser, parser->max_index_line, LK_ERR_RANGE,
                        "vertex index %u out of range (the file defines %zu vertices)", parser->max_index,
                        parser->vertex_count);
    for (int a = 0; a < SMF_ATTRIBUTE_COUNT; a++) {
        smf_attribute *attribute = &parser->attributes[a];
        if (attribute->count && attribute->count != parser->vertex_count)
            return smf_fail(parser, attribute->last_line, LK_ERR_RANGE,
                            "%zu %ss for %zu vertices (a per-vertex binding needs one per vertex)", attribute->count,
                            attribute->what, parser->vertex_count);
    }
    /* The mesh's arrays are the parser's, charged as they grew. */
    size_t triangle_count = parser->indices.size / (3 * sizeof(uint32_t));
    if (parser->vertex_count > LK_MAX_ELEMENTS || triangle_count > LK_MAX_ELEMENTS)
        return lk_error_set(parser->error, LK_ERR_LIMIT, "%s: the model has more elements than lodkit supports (%zu)",
                            parser->name, (size_t)LK_MAX_ELEMENTS);
    uint32_t *indices = (uint32_t *)parser->indices.data;
    for (size_t i = 0; i < 3 * triangle_count; i++) indices[i] -= 1;
    lk__budget *budget = parser->budget;
    mesh->vertex_count = parser->vertex_count;
    mesh->triangle_count = triangle_count;
    mesh->positions = (float *)lk__buffer_take_charged(&parser->positions, budget);
    mesh->indices =
        triangle_count ? (uint32_t *)lk__buffer_take_charged(&parser->indices, budget) : lk__malloc_array(0, 1);
    if (parser->attributes[SMF_NORMAL].count)
        mesh->normals = (float *)lk__buffer_take_charged(&parser->attributes[SMF_NORMAL].values, budget);
    if (parser->attributes[SMF_COLOR].count)
        mesh->colors = (float *)lk__buffer_take_charged(&parser->attributes[SMF_COLOR].values, budget);
    if (parser->attributes[SMF_TEXCOORD].count)
        mesh->texcoords = (float *)lk__buffer_take_charged(&parser->attributes[SMF_TEXCOORD].values, budget);
    if (!mesh->indices) return smf_out_of_memory(parser);
    return LK_OK;
}

lk_status lk__read_smf(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    smf_parser parser;
    memset(&parser, 0, sizeof parser);
    parser.name = ctx->name;
    parser.budget = ctx->budget;
    parser.error = error;
    parser.attributes[SMF_NORMAL] = (smf_attribute){"normal", 3, true, {0}, 0, 0};
    parser.attributes[SMF_COLOR] = (smf_attribute){"colour", 4, true, {0}, 0, 0};
    parser.attributes[SMF_TEXCOORD] = (smf_attribute){"texture coordinate", 2, true, {0}, 0, 0};
    lk_mesh_init(mesh);
    lk_status status = smf_parse(&parser, data, size);
    if (status == LK_OK) status = smf_build(&parser, mesh);
    if (status != LK_OK) lk_mesh_free(mesh);
    lk__buffer_free_charged(&parser.positions, ctx->budget);
    lk__buffer_free_charged(&parser.indices, ctx->budget);
    lk__buffer_free_charged(&parser.polygon, ctx->budget);
    for (int a = 0; a < SMF_ATTRIBUTE_COUNT; a++) lk__buffer_free_charged(&parser.attributes[a].values, ctx->budget);
    return status;
}

lk_status lk__write_smf(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error)
{
    (void)options; /* SMF output holds positions and triangles only */
    fprintf(file, "# lodkit SMF\n# %zu vertices, %zu triangles\n", mesh->vertex_count, mesh->triangle_count);
    char line[128];
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        size_t at = 1;
        line[0] = 'v';
        for (int k = 0; k < 3; k++) {
            line[at++] = ' ';
            at += (size_t)lk__format_float(line + at, 32, mesh->positions[3 * i + (size_t)k]);
        }
        line[at++] = '\n';
        fwrite(line, 1, at, file);
    }
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *triangle = mesh->indices + 3 * t;
        fprintf(file, "f %lu %lu %lu\n", triangle[0] + 1ul, triangle[1] + 1ul, triangle[2] + 1ul);
    }
    if (ferror(file)) return lk_error_set(error, LK_ERR_IO, "write error while writing SMF");
    return LK_OK;
}
