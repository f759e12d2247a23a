/* SPDX-License-Identifier: MIT */
/* Wavefront OBJ reader and writer.
 *
 * Reading keeps `v` lines as vertices in file order (vertex i is the i-th
 * `v`, used or not) and takes `vt`/`vn` from the faces that reference them.
 * OBJ indexes positions, texture coordinates and normals separately, so a
 * position used with two different (vt, vn) pairs becomes two vertices: the
 * first pair stays on vertex i, each further distinct pair gets a copy of the
 * position appended after the `v` vertices.
 *
 * The parser makes one pass over the buffer, one logical line at a time,
 * appending to growable arrays; nothing is allocated per line. Unknown
 * statements (o, g, s, usemtl, mtllib, l, p, vp, ...) are skipped, as OBJ
 * readers traditionally do; malformed v/vt/vn/f lines are errors. */
#include "internal.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

/* One face corner as written in the file: 1-based indices after resolving
 * negative (relative) ones; 0 means "not given". */
typedef struct obj_corner {
    uint32_t v, vt, vn;
} obj_corner;

/* The texture coordinate and normal of a corner (0: not given). */
typedef struct obj_pair {
    uint32_t vt, vn;
} obj_pair;

/* The largest index seen for one kind of element and the line of the face
 * that used it, so that out-of-range references (which may point forward in
 * the file) can be reported once the whole file has been read. */
typedef struct obj_max_reference {
    uint32_t index;
    size_t line;
} obj_max_reference;

/* Every buffer is charged to the read's budget: a file of short lines
 * ("f 1 2 3 4 5 ...", or one coloured `v` after millions of plain ones)
 * can ask for several times its own size. */
typedef struct obj_parser {
    const char *name;
    lk__budget *budget;
    lk_error *error;
    lk__buffer positions;       /* float[3] per `v` */
    lk__buffer colors;          /* float[4] per `v`, only once a `v` had r g b */
    lk__buffer texcoords;       /* float[2] per `vt` */
    lk__buffer normals;         /* float[3] per `vn` */
    lk__buffer corner_vertices; /* uint32_t[3] per triangle: the `v` of each corner */
    lk__buffer corner_pairs;    /* obj_pair[3] per triangle, only once a corner had a vt or vn */
    lk__buffer polygon;         /* obj_corner per corner of the face being read */
    lk__buffer joined;          /* a logical line joined from backslash continuations */
    size_t position_count, texcoord_count, normal_count;
    bool texcoords_referenced, normals_referenced;
    obj_max_reference max_v, max_vt, max_vn;
} obj_parser;

static const float obj_default_color[4] = {1.0f, 1.0f, 1.0f, 1.0f};

static lk_status obj_fail(obj_parser *parser, size_t line, lk_status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
static lk_status obj_fail(obj_parser *parser, size_t line, lk_status status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_line_v(parser->error, status, parser->name, line, format, args);
    va_end(args);
    return status;
}

static lk_status obj_out_of_memory(obj_parser *parser)
{
    return lk_error_set(parser->error, LK_ERR_NOMEM, "%s: out of memory", parser->name);
}

/* Parses up to `capacity` numbers; returns how many were read. Anything
 * after them on the line is left for the caller. */
static int obj_parse_numbers(const char **p, const char *end, double *values, int capacity)
{
    int count = 0;
    while (count < capacity && lk__parse_double(p, end, &values[count])) count++;
    return count;
}

static lk_status obj_check_finite(obj_parser *parser, size_t line, const double *values, int count, const char *what)
{
    for (int i = 0; i < count; i++) {
        if (!isfinite((float)values[i]))
            return obj_fail(parser, line, LK_ERR_RANGE, "%s %g is not a finite float", what, values[i]);
    }
    return LK_OK;
}

/* Turns LK_ERR_LIMIT / LK_ERR_NOMEM from a charged buffer into a message. */
static lk_status obj_growth_failure(obj_parser *parser, size_t line, lk_status status)
{
    if (status == LK_ERR_LIMIT)
        return obj_fail(parser, line, LK_ERR_LIMIT, "the model needs more than the memory budget of %zu bytes",
                        parser->budget->limit);
    return obj_out_of_memory(parser);
}

static lk_status obj_reserve(obj_parser *parser, size_t line, lk__buffer *buffer, size_t extra)
{
    lk_status status = lk__buffer_reserve_charged(buffer, extra, parser->budget);
    return status == LK_OK ? LK_OK : obj_growth_failure(parser, line, status);
}

/* Inline, so that the copy of a vertex or a corner is a few moves rather
 * than a call to memcpy: it runs for every number of the file. */
static inline lk_status obj_append(obj_parser *parser, size_t line, lk__buffer *buffer, const void *bytes, size_t size)
{
    if (buffer->capacity - buffer->size < size) {
        lk_status status = lk__buffer_reserve_charged(buffer, size, parser->budget);
        if (status != LK_OK) return obj_growth_failure(parser, line, status);
    }
    if (size) memcpy(buffer->data + buffer->size, bytes, size);
    buffer->size += size;
    return LK_OK;
}

/* `v x y z [w]` or `v x y z r g b` (vertex colours, as MeshLab writes them),
 * then nothing but a comment. Characters glued to the last number are
 * ignored: Assimp's number_formats.obj contains tokens like `3.1+e2` that
 * other readers take as 3.1; a separate word (`v 0 0 0 junk`) is refused,
 * as on `f` lines. */
static lk_status obj_read_position(obj_parser *parser, const char *p, const char *end, size_t line)
{
    double values[7];
    int count = obj_parse_numbers(&p, end, values, 7);
    const char *rest = lk__skip_spaces(p, end);
    if (count < 3 || (rest != p && rest < end && *rest != '#')) {
        char token[32];
        lk__quote_token(rest, end, token, sizeof token);
        if (count >= 3)
            return obj_fail(parser, line, LK_ERR_PARSE, "unexpected '%s' after the %d numbers of 'v'", token, count);
        return obj_fail(parser, line, LK_ERR_PARSE, "expected 3 coordinates after 'v', got %d%s%s%s", count,
                        token[0] ? " then '" : "", token, token[0] ? "'" : "");
    }
    lk_status status = obj_check_finite(parser, line, values, count >= 6 ? 6 : 3, "coordinate");
    if (status != LK_OK) return status;
    float position[3] = {(float)values[0], (float)values[1], (float)values[2]};
    status = obj_append(parser, line, &parser->positions, position, sizeof position);
    if (status != LK_OK) return status;
    if (count >= 6) {
        if (parser->colors.size == 0) {
            /* First coloured vertex: earlier vertices get the default. */
            status =
                obj_reserve(parser, line, &parser->colors, (parser->position_count + 1) * sizeof obj_default_color);
            for (size_t i = 0; status == LK_OK && i < parser->position_count; i++)
                status = obj_append(parser, line, &parser->colors, obj_default_color, sizeof obj_default_color);
            if (status != LK_OK) return status;
        }
        float color[4] = {(float)values[3], (float)values[4], (float)values[5], 1.0f};
        status = obj_append(parser, line, &parser->colors, color, sizeof color);
    } else if (parser->colors.size != 0) {
        status = obj_append(parser, line, &parser->colors, obj_default_color, sizeof obj_default_color);
    }
    parser->position_count++;
    return status;
}

/* `vt u [v [w]]`: only u and v are kept. */
static lk_status obj_read_texcoord(obj_parser *parser, const char *p, const char *end, size_t line)
{
    double values[3] = {0, 0, 0};
    int count = obj_parse_numbers(&p, end, values, 3);
    if (count < 1) return obj_fail(parser, line, LK_ERR_PARSE, "expected texture coordinates 'u [v [w]]' after 'vt'");
    lk_status status = obj_check_finite(parser, line, values, 2, "texture coordinate");
    if (status != LK_OK) return status;
    float texcoord[2] = {(float)values[0], (float)values[1]};
    status = obj_append(parser, line, &parser->texcoords, texcoord, sizeof texcoord);
    if (status == LK_OK) parser->texcoord_count++;
    return status;
}

static lk_status obj_read_normal(obj_parser *parser, const char *p, const char *end, size_t line)
{
    double values[3];
    int count = obj_parse_numbers(&p, end, values, 3);
    if (count < 3) return obj_fail(parser, line, LK_ERR_PARSE, "expected 3 numbers after 'vn', got %d", count);
    lk_status status = obj_check_finite(parser, line, values, 3, "normal component");
    if (status != LK_OK) return status;
    float normal[3] = {(float)values[0], (float)values[1], (float)values[2]};
    status = obj_append(parser, line, &parser->normals, normal, sizeof normal);
    if (status == LK_OK) parser->normal_count++;
    return status;
}

/* Resolves one index of a corner: positive ones are 1-based (checked
 * against the final counts later, since exporters may refer forward),
 * negative ones count back from the elements defined so far. */
static inline lk_status obj_resolve_index(obj_parser *parser, size_t line, long long value, size_t defined,
                                          obj_max_reference *max, const char *what, const char *plural, uint32_t *out)
{
    if (value == 0) return obj_fail(parser, line, LK_ERR_RANGE, "%s index 0 is invalid (OBJ indices start at 1)", what);
    if (value < 0) {
        if ((unsigned long long)-(value + 1) >= defined)
            return obj_fail(parser, line, LK_ERR_RANGE, "%s index %lld out of range (%zu %s defined so far)", what,
                            value, defined, plural);
        *out = (uint32_t)(defined - (size_t) - (value + 1));
        return LK_OK;
    }
    if ((unsigned long long)value > LK_MAX_ELEMENTS)
        return obj_fail(parser, line, LK_ERR_RANGE, "%s index %lld out of range (more than lodkit supports)", what,
                        value);
    *out = (uint32_t)value;
    if (*out > max->index) {
        max->index = *out;
        max->line = line;
    }
    return LK_OK;
}

/* One corner `v`, `v/vt`, `v//vn` or `v/vt/vn`. */
static lk_status obj_read_corner(obj_parser *parser, const char **cursor, const char *end, size_t line,
                                 obj_corner *corner)
{
    const char *p = *cursor;
    long long value;
    char token[32];
    lk_status status;
    corner->vt = corner->vn = 0;
    if (!lk__parse_int64(&p, end, &value)) goto bad_corner;
    status = obj_resolve_index(parser, line, value, parser->position_count, &parser->max_v, "vertex", "vertices",
                               &corner->v);
    if (status != LK_OK) return status;
    if (p < end && *p == '/') {
        p++;
        if (p < end && *p != '/') {
            if (!lk__parse_int64(&p, end, &value)) goto bad_corner;
            status = obj_resolve_index(parser, line, value, parser->texcoord_count, &parser->max_vt,
                                       "texture coordinate", "texture coordinates", &corner->vt);
            if (status != LK_OK) return status;
            parser->texcoords_referenced = true;
        }
        if (p < end && *p == '/') {
            p++;
            if (!lk__parse_int64(&p, end, &value)) goto bad_corner;
            status = obj_resolve_index(parser, line, value, parser->normal_count, &parser->max_vn, "normal", "normals",
                                       &corner->vn);
            if (status != LK_OK) return status;
            parser->normals_referenced = true;
        }
    }
    if (p < end && !lk__is_space(*p) && *p != '#') goto bad_corner;
    *cursor = p;
    return LK_OK;
bad_corner:
    lk__quote_token(*cursor, end, token, sizeof token);
    return obj_fail(parser, line, LK_ERR_PARSE, "expected a face corner like 1, 1/2, 1//3 or 1/2/3, got '%s'", token);
}

/* `f c1 c2 c3 ...`: polygons become a fan around the first corner. */
static lk_status obj_read_face(obj_parser *parser, const char *p, const char *end, size_t line)
{
    parser->polygon.size = 0;
    for (;;) {
        p = lk__skip_spaces(p, end);
        if (p >= end || *p == '#') break;
        obj_corner corner;
        lk_status status = obj_read_corner(parser, &p, end, line, &corner);
        if (status != LK_OK) return status;
        status = obj_append(parser, line, &parser->polygon, &corner, sizeof corner);
        if (status != LK_OK) return status;
    }
    size_t corner_count = parser->polygon.size / sizeof(obj_corner);
    if (corner_count < 3)
        return obj_fail(parser, line, LK_ERR_PARSE, "expected at least 3 vertex indices after 'f', got %zu",
                        corner_count);
    const obj_corner *polygon = (const obj_corner *)parser->polygon.data;
    bool with_pairs = parser->corner_pairs.size != 0;
    for (size_t k = 0; !with_pairs && k < corner_count; k++) with_pairs = polygon[k].vt || polygon[k].vn;
    size_t new_corners = 3 * (corner_count - 2);
    /* Reserved before writing: the reservation itself is the allocation. */
    lk_status status = obj_reserve(parser, line, &parser->corner_vertices, new_corners * sizeof(uint32_t));
    if (status != LK_OK) return status;
    if (with_pairs) {
        /* The first corner with a vt or vn: the earlier ones get none. */
        size_t earlier = parser->corner_vertices.size / sizeof(uint32_t);
        if (parser->corner_pairs.size == 0) {
            status = obj_reserve(parser, line, &parser->corner_pairs, (earlier + new_corners) * sizeof(obj_pair));
            if (status != LK_OK) return status;
            memset(parser->corner_pairs.data, 0, earlier * sizeof(obj_pair));
            parser->corner_pairs.size = earlier * sizeof(obj_pair);
        }
        status = obj_reserve(parser, line, &parser->corner_pairs, new_corners * sizeof(obj_pair));
        if (status != LK_OK) return status;
    }
    uint32_t *vertices = (uint32_t *)(parser->corner_vertices.data + parser->corner_vertices.size);
    obj_pair *pairs = with_pairs ? (obj_pair *)(parser->corner_pairs.data + parser->corner_pairs.size) : NULL;
    for (size_t k = 1; k + 1 < corner_count; k++) {
        const obj_corner *fan[3] = {&polygon[0], &polygon[k], &polygon[k + 1]};
        for (int c = 0; c < 3; c++) {
            *vertices++ = fan[c]->v;
            if (pairs) *pairs++ = (obj_pair){fan[c]->vt, fan[c]->vn};
        }
    }
    parser->corner_vertices.size += new_corners * sizeof(uint32_t);
    if (with_pairs) parser->corner_pairs.size += new_corners * sizeof(obj_pair);
    return LK_OK;
}

static lk_status obj_parse_line(obj_parser *parser, const char *p, const char *end, size_t line)
{
    p = lk__skip_spaces(p, end);
    if (p >= end || *p == '#') return LK_OK;
    const char *keyword = p;
    while (p < end && !lk__is_space(*p)) p++;
    size_t length = (size_t)(p - keyword);
    if (length == 1 && keyword[0] == 'v') return obj_read_position(parser, p, end, line);
    if (length == 1 && keyword[0] == 'f') return obj_read_face(parser, p, end, line);
    if (length == 2 && keyword[0] == 'v' && keyword[1] == 't') return obj_read_texcoord(parser, p, end, line);
    if (length == 2 && keyword[0] == 'v' && keyword[1] == 'n') return obj_read_normal(parser, p, end, line);
    return LK_OK; /* o g s usemtl mtllib l p vp curves ...: not geometry lodkit keeps */
}

/* End of the text of a line that ends with a backslash continuation, or
 * NULL when the line does not continue. */
static const char *obj_continuation(const char *line_start, const char *line_end)
{
    const char *q = line_end;
    if (q > line_start && q[-1] == '\r') q--;
    return q > line_start && q[-1] == '\\' ? q - 1 : NULL;
}

/* Refuses encodings the byte-oriented parser would silently misread. */
static lk_status obj_check_encoding(obj_parser *parser, const unsigned char *data, size_t size)
{
    if (size >= 2 && ((data[0] == 0xFE && data[1] == 0xFF) || (data[0] == 0xFF && data[1] == 0xFE)))
        return lk_error_set(parser->error, LK_ERR_UNSUPPORTED,
                            "%s: file is UTF-16 encoded (byte order mark %02X %02X); save it as UTF-8 or ASCII",
                            parser->name, data[0], data[1]);
    size_t probe = size < 4096 ? size : 4096;
    const unsigned char *nul = memchr(data, 0, probe);
    if (nul)
        return lk_error_set(parser->error, LK_ERR_PARSE,
                            "%s: byte %zu: NUL byte in what should be an OBJ text file (binary or UTF-16/32 data?)",
                            parser->name, (size_t)(nul - data));
    return LK_OK;
}

static lk_status obj_parse(obj_parser *parser, const char *data, size_t size)
{
    lk_status status = obj_check_encoding(parser, (const unsigned char *)data, size);
    if (status != LK_OK) return status;
    const char *p = data, *end = data + size;
    if (size >= 3 && memcmp(p, "\xEF\xBB\xBF", 3) == 0) p += 3; /* UTF-8 byte order mark */
    size_t line = 0;
    while (p < end) {
        line++;
        size_t first_line = line;
        const char *newline = memchr(p, '\n', (size_t)(end - p));
        const char *line_start = p, *line_end = newline ? newline : end;
        p = newline ? newline + 1 : end;
        const char *cut = obj_continuation(line_start, line_end);
        if (cut) {
            /* Rare: join the continued lines into a scratch buffer. */
            parser->joined.size = 0;
            for (;;) {
                status = obj_append(parser, first_line, &parser->joined, line_start, (size_t)(cut - line_start));
                if (status == LK_OK) status = obj_append(parser, first_line, &parser->joined, " ", 1);
                if (status != LK_OK) return status;
                if (p >= end) break;
                line++;
                newline = memchr(p, '\n', (size_t)(end - p));
                line_start = p;
                line_end = newline ? newline : end;
                p = newline ? newline + 1 : end;
                cut = obj_continuation(line_start, line_end);
                if (!cut) {
                    status =
                        obj_append(parser, first_line, &parser->joined, line_start, (size_t)(line_end - line_start));
                    if (status != LK_OK) return status;
                    break;
                }
            }
            line_start = (const char *)parser->joined.data;
            line_end = line_start + parser->joined.size;
        }
        status = obj_parse_line(parser, line_start, line_end, first_line);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

static lk_status obj_check_references(obj_parser *parser)
{
    if (parser->max_v.index > parser->position_count)
        return obj_fail(parser, parser->max_v.line, LK_ERR_RANGE,
                        "vertex index %u out of range (the file defines %zu vertices)", parser->max_v.index,
                        parser->position_count);
    if (parser->max_vt.index > parser->texcoord_count)
        return obj_fail(parser, parser->max_vt.line, LK_ERR_RANGE,
                        "texture coordinate index %u out of range (the file defines %zu)", parser->max_vt.index,
                        parser->texcoord_count);
    if (parser->max_vn.index > parser->normal_count)
        return obj_fail(parser, parser->max_vn.line, LK_ERR_RANGE,
                        "normal index %u out of range (the file defines %zu)", parser->max_vn.index,
                        parser->normal_count);
    return LK_OK;
}

/* Open-addressing map from a (v, vt, vn) corner to the extra vertex made
 * for it. Only corners that conflict with a position's first pair go in. */
typedef struct obj_split_map {
    struct obj_split_entry {
        obj_corner key; /* key.v == 0: empty slot */
        uint32_t vertex;
    } * slots;
    size_t capacity, count;
} obj_split_map;

static size_t obj_corner_hash(obj_corner corner)
{
    return (size_t)lk__mix64(((uint64_t)corner.v << 32 | corner.vt) ^ lk__mix64(corner.vn));
}

/* Doubles the table; the new one is charged before it is made and the old
 * one released once it is gone. Returns LK_OK, LK_ERR_LIMIT or LK_ERR_NOMEM. */
static lk_status obj_split_map_grow(obj_split_map *map, lk__budget *budget)
{
    size_t capacity = map->capacity ? map->capacity * 2 : 64;
    if (!lk__budget_charge(budget, capacity, sizeof *map->slots)) return LK_ERR_LIMIT;
    struct obj_split_entry *slots = lk__calloc_array(capacity, sizeof *slots);
    if (!slots) {
        lk__budget_release(budget, capacity, sizeof *slots);
        return LK_ERR_NOMEM;
    }
    for (size_t i = 0; i < map->capacity; i++) {
        if (map->slots[i].key.v == 0) continue;
        size_t at = obj_corner_hash(map->slots[i].key) & (capacity - 1);
        while (slots[at].key.v != 0) at = (at + 1) & (capacity - 1);
        slots[at] = map->slots[i];
    }
    free(map->slots);
    lk__budget_release(budget, map->capacity, sizeof *slots);
    map->slots = slots;
    map->capacity = capacity;
    return LK_OK;
}

/* Returns the slot for `key`, empty if it is not in the map yet. */
static struct obj_split_entry *obj_split_map_find(obj_split_map *map, obj_corner key)
{
    size_t at = obj_corner_hash(key) & (map->capacity - 1);
    for (;;) {
        struct obj_split_entry *slot = &map->slots[at];
        if (slot->key.v == 0 || (slot->key.v == key.v && slot->key.vt == key.vt && slot->key.vn == key.vn)) return slot;
        at = (at + 1) & (map->capacity - 1);
    }
}

static lk_status obj_over_budget(obj_parser *parser, size_t vertex_count, size_t triangle_count)
{
    return lk_error_set(parser->error, LK_ERR_LIMIT,
                        "%s: %zu vertices and %zu triangles need more than the memory budget of %zu bytes",
                        parser->name, vertex_count, triangle_count, parser->budget->limit);
}

/* The corners' `v` (1-based) become the mesh's indices in place. */
static uint32_t *obj_take_indices(obj_parser *parser)
{
    uint32_t *indices = (uint32_t *)parser->corner_vertices.data;
    size_t corner_count = parser->corner_vertices.size / sizeof(uint32_t);
    for (size_t i = 0; i < corner_count; i++) indices[i] -= 1;
    if (corner_count == 0) {
        lk__buffer_free_charged(&parser->corner_vertices, parser->budget);
        return lk__malloc_array(0, sizeof(uint32_t));
    }
    return lk__buffer_take_charged(&parser->corner_vertices, parser->budget);
}

/* Simple case: faces give positions only (or there are no faces), so the
 * vertices are exactly the `v` lines and the arrays can be handed over. */
static lk_status obj_build_plain(obj_parser *parser, lk_mesh *mesh)
{
    size_t vertex_count = parser->position_count;
    size_t triangle_count = parser->corner_vertices.size / (3 * sizeof(uint32_t));
    if (vertex_count > LK_MAX_ELEMENTS || triangle_count > LK_MAX_ELEMENTS)
        return obj_over_budget(parser, vertex_count, triangle_count);
    /* A point cloud written as v + vn (or vt) pairs, as MeshLab does. */
    bool point_normals = triangle_count == 0 && parser->normal_count == vertex_count;
    bool point_texcoords = triangle_count == 0 && parser->texcoord_count == vertex_count;
    uint32_t *indices = obj_take_indices(parser);
    if (!indices) return obj_out_of_memory(parser);
    mesh->vertex_count = vertex_count;
    mesh->triangle_count = triangle_count;
    mesh->indices = indices;
    mesh->positions = (float *)lk__buffer_take_charged(&parser->positions, parser->budget);
    if (parser->colors.size) mesh->colors = (float *)lk__buffer_take_charged(&parser->colors, parser->budget);
    if (point_normals) mesh->normals = (float *)lk__buffer_take_charged(&parser->normals, parser->budget);
    if (point_texcoords) mesh->texcoords = (float *)lk__buffer_take_charged(&parser->texcoords, parser->budget);
    return LK_OK;
}

/* General case: attach each position's first (vt, vn) pair to it and append
 * a vertex for every further distinct pair. The indices replace the
 * corners' `v` in place. */
static lk_status obj_build_split(obj_parser *parser, lk_mesh *mesh)
{
    lk__budget *budget = parser->budget;
    size_t position_count = parser->position_count;
    size_t corner_count = parser->corner_vertices.size / sizeof(uint32_t);
    uint32_t *corner_vertices = (uint32_t *)parser->corner_vertices.data;
    const obj_pair *corner_pairs = (const obj_pair *)parser->corner_pairs.data;
    obj_corner *first_pair = NULL; /* per position; .v != 0: taken */
    lk__buffer extras = {0};       /* obj_corner per appended vertex */
    obj_split_map map = {0};
    lk_status status = LK_OK;
    bool first_pair_charged = lk__budget_charge(budget, position_count, sizeof(obj_corner));
    if (!first_pair_charged) {
        status = obj_over_budget(parser, position_count, corner_count / 3);
        goto done;
    }
    first_pair = lk__calloc_array(position_count, sizeof(obj_corner));
    if (!first_pair) goto out_of_memory;
    for (size_t i = 0; i < corner_count; i++) {
        obj_corner corner = {corner_vertices[i], corner_pairs[i].vt, corner_pairs[i].vn};
        obj_corner *first = &first_pair[corner.v - 1];
        if (first->v == 0) *first = corner;
        if (first->vt == corner.vt && first->vn == corner.vn) {
            corner_vertices[i] = corner.v - 1;
            continue;
        }
        if (2 * (map.count + 1) > map.capacity) {
            status = obj_split_map_grow(&map, budget);
            if (status == LK_ERR_LIMIT) status = obj_over_budget(parser, position_count + map.count, corner_count / 3);
            if (status != LK_OK) goto grown_or_failed;
        }
        struct obj_split_entry *slot = obj_split_map_find(&map, corner);
        if (slot->key.v == 0) {
            size_t vertex = position_count + extras.size / sizeof(obj_corner);
            if (vertex >= LK_MAX_ELEMENTS) {
                status = lk_error_set(parser->error, LK_ERR_LIMIT, "%s: too many distinct vertices", parser->name);
                goto done;
            }
            status = lk__buffer_append_charged(&extras, &corner, sizeof corner, budget);
            if (status == LK_ERR_LIMIT) status = obj_over_budget(parser, vertex + 1, corner_count / 3);
            if (status != LK_OK) goto grown_or_failed;
            slot->key = corner;
            slot->vertex = (uint32_t)vertex;
            map.count++;
        }
        corner_vertices[i] = slot->vertex;
    }
    size_t extra_count = extras.size / sizeof(obj_corner);
    size_t vertex_count = position_count + extra_count;
    bool with_texcoords = parser->texcoords_referenced, with_normals = parser->normals_referenced;
    bool with_colors = parser->colors.size != 0;
    unsigned flags = (with_normals ? LK_ATTR_NORMALS : 0u) | (with_texcoords ? LK_ATTR_TEXCOORDS : 0u) |
                     (with_colors ? LK_ATTR_COLORS : 0u);
    /* The map is no longer needed: give it back before the mesh is made. */
    free(map.slots);
    lk__budget_release(budget, map.capacity, sizeof *map.slots);
    map = (obj_split_map){0};
    if (vertex_count > LK_MAX_ELEMENTS || corner_count / 3 > LK_MAX_ELEMENTS ||
        !lk__budget_charge_mesh(budget, vertex_count, 0, flags)) {
        status = obj_over_budget(parser, vertex_count, corner_count / 3);
        goto done;
    }
    status = lk_mesh_alloc(mesh, vertex_count, 0, flags, parser->error);
    if (status != LK_OK) goto done;
    free(mesh->indices);
    mesh->indices = lk__buffer_take_charged(&parser->corner_vertices, budget);
    mesh->triangle_count = corner_count / 3;
    if (!mesh->indices) goto out_of_memory;
    const float *positions = (const float *)parser->positions.data;
    const float *texcoords = (const float *)parser->texcoords.data;
    const float *normals = (const float *)parser->normals.data;
    const float *colors = (const float *)parser->colors.data;
    const obj_corner *extra = (const obj_corner *)extras.data;
    for (size_t i = 0; i < vertex_count; i++) {
        /* Vertex i < position_count is `v` number i+1 with its first pair. */
        obj_corner source = i < position_count ? first_pair[i] : extra[i - position_count];
        size_t position = i < position_count ? i : source.v - 1;
        memcpy(mesh->positions + 3 * i, positions + 3 * position, 3 * sizeof(float));
        if (with_colors) memcpy(mesh->colors + 4 * i, colors + 4 * position, 4 * sizeof(float));
        if (with_texcoords) {
            float *out = mesh->texcoords + 2 * i;
            if (source.vt)
                memcpy(out, texcoords + 2 * (source.vt - 1), 2 * sizeof(float));
            else
                out[0] = out[1] = 0.0f;
        }
        if (with_normals) {
            float *out = mesh->normals + 3 * i;
            if (source.vn)
                memcpy(out, normals + 3 * (source.vn - 1), 3 * sizeof(float));
            else
                out[0] = out[1] = out[2] = 0.0f;
        }
    }
    goto done;
grown_or_failed:
    if (status != LK_ERR_NOMEM) goto done;
out_of_memory:
    status = obj_out_of_memory(parser);
done:
    free(first_pair);
    if (first_pair_charged) lk__budget_release(budget, position_count, sizeof(obj_corner));
    free(map.slots);
    lk__budget_release(budget, map.capacity, sizeof *map.slots);
    lk__buffer_free_charged(&extras, budget);
    return status;
}

lk_status lk__read_obj(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    obj_parser parser;
    memset(&parser, 0, sizeof parser);
    parser.name = ctx->name;
    parser.budget = ctx->budget;
    parser.error = error;
    lk_mesh_init(mesh);
    lk_status status = obj_parse(&parser, data, size);
    if (status == LK_OK) status = obj_check_references(&parser);
    if (status == LK_OK && parser.position_count == 0)
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no vertices ('v' lines): not an OBJ model", ctx->name);
    if (status == LK_OK) {
        if (parser.texcoords_referenced || parser.normals_referenced)
            status = obj_build_split(&parser, mesh);
        else
            status = obj_build_plain(&parser, mesh);
    }
    if (status != LK_OK) lk_mesh_free(mesh);
    lk__buffer *buffers[] = {&parser.positions,       &parser.colors,       &parser.texcoords, &parser.normals,
                             &parser.corner_vertices, &parser.corner_pairs, &parser.polygon,   &parser.joined};
    for (size_t i = 0; i < sizeof buffers / sizeof buffers[0]; i++) lk__buffer_free_charged(buffers[i], ctx->budget);
    return status;
}

/* ---- writer ------------------------------------------------------------ */

/* Appends " value" for each float to a line under construction. */
static size_t obj_format_floats(char *line, size_t at, const float *values, int count)
{
    for (int i = 0; i < count; i++) {
        line[at++] = ' ';
        at += (size_t)lk__format_float(line + at, 32, values[i]);
    }
    return at;
}

/* Appends the decimal digits of a 1-based index (printf is the writer's
 * slowest part otherwise). */
static size_t obj_format_index(char *line, size_t at, unsigned long index)
{
    char digits[24];
    int count = 0;
    do {
        digits[count++] = (char)('0' + index % 10);
        index /= 10;
    } while (index);
    while (count) line[at++] = digits[--count];
    return at;
}

lk_status lk__write_obj(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error)
{
    bool with_normals = mesh->normals && !options->skip_normals;
    bool with_texcoords = mesh->texcoords && !options->skip_texcoords;
    bool with_colors = mesh->colors && !options->skip_colors;
    char line[256];
    fprintf(file, "# lodkit %s: %zu vertices, %zu triangles\n", lk_version(), mesh->vertex_count, mesh->triangle_count);
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        size_t at = 1;
        line[0] = 'v';
        at = obj_format_floats(line, at, mesh->positions + 3 * i, 3);
        if (with_colors) at = obj_format_floats(line, at, mesh->colors + 4 * i, 3);
        line[at++] = '\n';
        fwrite(line, 1, at, file);
    }
    if (with_texcoords) {
        for (size_t i = 0; i < mesh->vertex_count; i++) {
            memcpy(line, "vt", 2);
            size_t at = obj_format_floats(line, 2, mesh->texcoords + 2 * i, 2);
            line[at++] = '\n';
            fwrite(line, 1, at, file);
        }
    }
    if (with_normals) {
        for (size_t i = 0; i < mesh->vertex_count; i++) {
            memcpy(line, "vn", 2);
            size_t at = obj_format_floats(line, 2, mesh->normals + 3 * i, 3);
            line[at++] = '\n';
            fwrite(line, 1, at, file);
        }
    }
    /* Vertex i has texture coordinate i and normal i, so corners repeat it:
     * "f a b c", "f a/a ...", "f a//a ..." or "f a/a/a ...". */
    const char *separator = with_normals && !with_texcoords ? "//" : "/";
    int repeats = (with_texcoords ? 1 : 0) + (with_normals ? 1 : 0);
    size_t separator_length = strlen(separator);
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *triangle = mesh->indices + 3 * t;
        size_t at = 1;
        line[0] = 'f';
        for (int k = 0; k < 3; k++) {
            line[at++] = ' ';
            at = obj_format_index(line, at, triangle[k] + 1ul);
            for (int r = 0; r < repeats; r++) {
                memcpy(line + at, separator, separator_length);
                at = obj_format_index(line, at + separator_length, triangle[k] + 1ul);
            }
        }
        line[at++] = '\n';
        fwrite(line, 1, at, file);
    }
    if (ferror(file)) return lk_error_set(error, LK_ERR_IO, "write error while writing OBJ");
    return LK_OK;
}
