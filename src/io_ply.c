/* SPDX-License-Identifier: MIT */
/* PLY (Stanford polygon file format): reader for the ascii and both binary
 * encodings, writer for all three.
 *
 * The reader understands any element and property layout: it uses the
 * "vertex" element (positions, normals, texture coordinates, colours,
 * splat radii from a property named "radius") and
 * the "face" element's vertex_indices list (polygons are fanned into
 * triangles) and skips everything else. A file without faces is a point set.
 * Binary values are decoded byte by byte, so the host's endianness and
 * alignment never matter; the usual binary layouts have fast paths. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

typedef enum ply_type {
    PLY_NONE = 0,
    PLY_INT8,
    PLY_UINT8,
    PLY_INT16,
    PLY_UINT16,
    PLY_INT32,
    PLY_UINT32,
    PLY_FLOAT32,
    PLY_FLOAT64
} ply_type;

static const struct {
    const char *name;
    ply_type type;
} ply_type_names[] = {
    {"char", PLY_INT8},     {"int8", PLY_INT8},       {"uchar", PLY_UINT8},    {"uint8", PLY_UINT8},
    {"short", PLY_INT16},   {"int16", PLY_INT16},     {"ushort", PLY_UINT16},  {"uint16", PLY_UINT16},
    {"int", PLY_INT32},     {"int32", PLY_INT32},     {"uint", PLY_UINT32},    {"uint32", PLY_UINT32},
    {"float", PLY_FLOAT32}, {"float32", PLY_FLOAT32}, {"double", PLY_FLOAT64}, {"float64", PLY_FLOAT64},
};

static size_t type_size(ply_type type)
{
    switch (type) {
    case PLY_INT8:
    case PLY_UINT8: return 1;
    case PLY_INT16:
    case PLY_UINT16: return 2;
    case PLY_INT32:
    case PLY_UINT32:
    case PLY_FLOAT32: return 4;
    case PLY_FLOAT64: return 8;
    case PLY_NONE: break;
    }
    return 0;
}

static bool type_is_integer(ply_type type) { return type != PLY_FLOAT32 && type != PLY_FLOAT64; }

/* Integer colour channels are scaled by the largest value of their type
 * (uchar 255 -> 1.0); float channels are already in [0,1]. */
static double colour_scale(ply_type type)
{
    switch (type) {
    case PLY_INT8: return 1.0 / 127.0;
    case PLY_UINT8: return 1.0 / 255.0;
    case PLY_INT16: return 1.0 / 32767.0;
    case PLY_UINT16: return 1.0 / 65535.0;
    case PLY_INT32: return 1.0 / 2147483647.0;
    case PLY_UINT32: return 1.0 / 4294967295.0;
    default: return 1.0;
    }
}

/* What a property of the vertex or face element is used for. */
enum ply_role {
    ROLE_NONE = 0,
    ROLE_X,
    ROLE_Y,
    ROLE_Z,
    ROLE_NX,
    ROLE_NY,
    ROLE_NZ,
    ROLE_U,
    ROLE_V,
    ROLE_RED,
    ROLE_GREEN,
    ROLE_BLUE,
    ROLE_ALPHA,
    ROLE_RADIUS,
    ROLE_FACE_INDICES,
    ROLE_COUNT
};

static const struct {
    const char *name;
    enum ply_role role;
} vertex_property_names[] = {
    {"x", ROLE_X},
    {"y", ROLE_Y},
    {"z", ROLE_Z},
    {"nx", ROLE_NX},
    {"ny", ROLE_NY},
    {"nz", ROLE_NZ},
    {"normal_x", ROLE_NX},
    {"normal_y", ROLE_NY},
    {"normal_z", ROLE_NZ},
    {"u", ROLE_U},
    {"v", ROLE_V},
    {"s", ROLE_U},
    {"t", ROLE_V},
    {"texture_u", ROLE_U},
    {"texture_v", ROLE_V},
    {"texture_s", ROLE_U},
    {"texture_t", ROLE_V},
    {"red", ROLE_RED},
    {"green", ROLE_GREEN},
    {"blue", ROLE_BLUE},
    {"alpha", ROLE_ALPHA},
    {"diffuse_red", ROLE_RED},
    {"diffuse_green", ROLE_GREEN},
    {"diffuse_blue", ROLE_BLUE},
    {"radius", ROLE_RADIUS},
};

typedef struct ply_property {
    const char *name;
    size_t name_length;
    ply_type type;       /* scalar type, or item type of a list */
    ply_type count_type; /* PLY_NONE for scalar properties */
    enum ply_role role;
} ply_property;

typedef struct ply_element {
    const char *name;
    size_t name_length;
    unsigned long long count;
    size_t line; /* header line of the "element" declaration */
    ply_property *properties;
    size_t property_count, property_capacity;
} ply_element;

typedef struct ply_header {
    lk_ply_encoding encoding;
    ply_element *elements;
    size_t element_count, element_capacity;
    size_t body_offset; /* first byte after the end_header line */
    size_t body_line;   /* line number of that byte (ascii bodies) */
    size_t end_line;    /* line number of end_header */
    lk__budget *budget; /* the element and property arrays are charged to it */
    size_t charged;     /* bytes of them */
} ply_header;

static void header_free(ply_header *header)
{
    for (size_t i = 0; i < header->element_count; i++) free(header->elements[i].properties);
    free(header->elements);
    header->elements = NULL;
    header->element_count = header->element_capacity = 0;
    if (header->budget) lk__budget_release(header->budget, header->charged, 1);
    header->charged = 0;
}

/* Charges the growth of a header array from `old` to `new` items of `size`
 * bytes: a header of short lines ("element e 0") holds several times its
 * text in these structures. */
static lk_status charge_header(ply_header *header, size_t old, size_t new, size_t size, const char *name, size_t line,
                               lk_error *error)
{
    if (!lk__budget_charge(header->budget, new - old, size))
        return lk_error_set(error, LK_ERR_LIMIT, "%s:%zu: the header needs more than the memory budget of %zu bytes",
                            name, line, header->budget->limit);
    header->charged += (new - old) * size;
    return LK_OK;
}

/* Longest piece of a name or token quoted in messages. */
static int quoted_length(size_t length) { return length > 40 ? 40 : (int)length; }

typedef struct ply_word {
    const char *start;
    size_t length;
} ply_word;

/* Next space-separated word before `end` (which excludes the newline). */
static bool next_word(const char **p, const char *end, ply_word *word)
{
    const char *start = lk__skip_spaces(*p, end);
    const char *stop = start;
    while (stop < end && !lk__is_space(*stop)) stop++;
    if (stop == start) return false;
    word->start = start;
    word->length = (size_t)(stop - start);
    *p = stop;
    return true;
}

static bool word_is(ply_word word, const char *text) { return lk__word_equals(word.start, word.length, text); }

static ply_type parse_type(ply_word word)
{
    for (size_t i = 0; i < sizeof ply_type_names / sizeof ply_type_names[0]; i++)
        if (word_is(word, ply_type_names[i].name)) return ply_type_names[i].type;
    return PLY_NONE;
}

static lk_status unknown_type(const char *name, size_t line, ply_word word, lk_error *error)
{
    return lk_error_set(error, LK_ERR_PARSE,
                        "%s:%zu: unknown property type '%.*s' (expected char, uchar, short, ushort, int, uint, "
                        "float, double or int8 ... float64)",
                        name, line, quoted_length(word.length), word.start);
}

static lk_status add_property(ply_header *header, ply_element *element, ply_property property, const char *name,
                              size_t line, lk_error *error)
{
    if (element->property_count == element->property_capacity) {
        size_t capacity = element->property_capacity ? 2 * element->property_capacity : 16;
        lk_status status =
            charge_header(header, element->property_capacity, capacity, sizeof(ply_property), name, line, error);
        if (status != LK_OK) return status;
        ply_property *grown = lk__realloc_array(element->properties, capacity, sizeof *grown);
        if (!grown) return lk_error_set(error, LK_ERR_NOMEM, "%s:%zu: out of memory", name, line);
        element->properties = grown;
        element->property_capacity = capacity;
    }
    element->properties[element->property_count++] = property;
    return LK_OK;
}

static lk_status parse_property_line(const char **p, const char *content_end, ply_header *header, const char *name,
                                     size_t line, lk_error *error)
{
    if (header->element_count == 0)
        return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: 'property' before any 'element' line", name, line);
    ply_element *element = &header->elements[header->element_count - 1];
    ply_property property = {0};
    ply_word word;
    if (!next_word(p, content_end, &word))
        return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: expected a type after 'property'", name, line);
    if (word_is(word, "list")) {
        ply_word count_word, item_word;
        if (!next_word(p, content_end, &count_word) || !next_word(p, content_end, &item_word))
            return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: expected 'property list COUNT_TYPE ITEM_TYPE NAME'", name,
                                line);
        property.count_type = parse_type(count_word);
        if (property.count_type == PLY_NONE) return unknown_type(name, line, count_word, error);
        if (!type_is_integer(property.count_type))
            return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: list count type must be an integer type, got '%.*s'",
                                name, line, quoted_length(count_word.length), count_word.start);
        property.type = parse_type(item_word);
        if (property.type == PLY_NONE) return unknown_type(name, line, item_word, error);
    } else {
        property.type = parse_type(word);
        if (property.type == PLY_NONE) return unknown_type(name, line, word, error);
    }
    if (!next_word(p, content_end, &word))
        return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: property has no name", name, line);
    property.name = word.start;
    property.name_length = word.length;
    return add_property(header, element, property, name, line, error);
}

static lk_status parse_element_line(const char **p, const char *content_end, ply_header *header, const char *name,
                                    size_t line, lk_error *error)
{
    ply_word element_name, count_word;
    if (!next_word(p, content_end, &element_name) || !next_word(p, content_end, &count_word))
        return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: expected 'element NAME COUNT'", name, line);
    const char *q = count_word.start;
    long long count;
    if (!lk__parse_int64(&q, count_word.start + count_word.length, &count) ||
        q != count_word.start + count_word.length || count < 0)
        return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: element count must be a non-negative integer, got '%.*s'",
                            name, line, quoted_length(count_word.length), count_word.start);
    if (header->element_count == header->element_capacity) {
        size_t capacity = header->element_capacity ? 2 * header->element_capacity : 8;
        lk_status status =
            charge_header(header, header->element_capacity, capacity, sizeof(ply_element), name, line, error);
        if (status != LK_OK) return status;
        ply_element *grown = lk__realloc_array(header->elements, capacity, sizeof *grown);
        if (!grown) return lk_error_set(error, LK_ERR_NOMEM, "%s:%zu: out of memory", name, line);
        header->elements = grown;
        header->element_capacity = capacity;
    }
    ply_element *element = &header->elements[header->element_count++];
    memset(element, 0, sizeof *element);
    element->name = element_name.start;
    element->name_length = element_name.length;
    element->count = (unsigned long long)count;
    element->line = line;
    return LK_OK;
}

static lk_status parse_format_line(const char **p, const char *content_end, ply_header *header, bool *seen,
                                   const char *name, size_t line, lk_error *error)
{
    ply_word encoding, version;
    if (*seen) return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: second 'format' line", name, line);
    if (!next_word(p, content_end, &encoding) || !next_word(p, content_end, &version))
        return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: expected 'format ENCODING 1.0'", name, line);
    if (word_is(encoding, "ascii"))
        header->encoding = LK_PLY_ASCII;
    else if (word_is(encoding, "binary_little_endian"))
        header->encoding = LK_PLY_BINARY_LE;
    else if (word_is(encoding, "binary_big_endian"))
        header->encoding = LK_PLY_BINARY_BE;
    else
        return lk_error_set(error, LK_ERR_PARSE,
                            "%s:%zu: unknown format '%.*s' (expected ascii, binary_little_endian or "
                            "binary_big_endian)",
                            name, line, quoted_length(encoding.length), encoding.start);
    if (!word_is(version, "1.0") && !word_is(version, "1"))
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s:%zu: unsupported PLY version '%.*s' (expected 1.0)", name,
                            line, quoted_length(version.length), version.start);
    *seen = true;
    return LK_OK;
}

/* Reads the header up to and including the end_header line. Lines with an
 * unknown keyword are ignored like comments: old exporters (Blender 2.4x)
 * wrote free text there, and every line that matters has a keyword. */
static lk_status parse_header(const char *data, size_t size, const char *name, lk__budget *budget, ply_header *header,
                              lk_error *error)
{
    const char *p = data, *end = data + size;
    size_t line = 1;
    bool format_seen = false;
    memset(header, 0, sizeof *header);
    header->budget = budget;
    while (p < end) {
        const char *line_end = lk__skip_line(p, end);
        const char *content_end = line_end;
        if (content_end > p && content_end[-1] == '\n') content_end--;
        const char *q = p;
        ply_word keyword;
        bool has_word = next_word(&q, content_end, &keyword);
        lk_status status = LK_OK;
        if (line == 1) {
            ply_word extra;
            if (!has_word || !word_is(keyword, "ply") || next_word(&q, content_end, &extra))
                return lk_error_set(error, LK_ERR_PARSE, "%s:1: not a PLY file (the first line must be 'ply')", name);
        } else if (!has_word) {
            /* blank line */
        } else if (word_is(keyword, "format")) {
            status = parse_format_line(&q, content_end, header, &format_seen, name, line, error);
        } else if (word_is(keyword, "element")) {
            status = parse_element_line(&q, content_end, header, name, line, error);
        } else if (word_is(keyword, "property")) {
            status = parse_property_line(&q, content_end, header, name, line, error);
        } else if (word_is(keyword, "end_header")) {
            if (!format_seen)
                return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: header has no 'format' line", name, line);
            header->body_offset = (size_t)(line_end - data);
            header->body_line = line + 1;
            header->end_line = line;
            return LK_OK;
        }
        if (status != LK_OK) return status;
        p = line_end;
        line++;
    }
    return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: header ends without 'end_header'", name, line > 1 ? line - 1 : 1);
}

/* Element names in messages: "vertices", "faces", "'edge' elements". */
static void plural_name(const ply_element *element, char *out, size_t size)
{
    if (lk__word_equals(element->name, element->name_length, "vertex"))
        snprintf(out, size, "vertices");
    else if (lk__word_equals(element->name, element->name_length, "face"))
        snprintf(out, size, "faces");
    else
        snprintf(out, size, "'%.*s' elements", quoted_length(element->name_length), element->name);
}

static void singular_name(const ply_element *element, char *out, size_t size)
{
    snprintf(out, size, "%.*s", quoted_length(element->name_length), element->name);
}

/* ---- body ------------------------------------------------------------------ */

typedef struct ply_body {
    const char *data;
    size_t size;
    size_t pos; /* next byte to read */
    bool ascii;
    bool big_endian;
    size_t line;        /* ascii: line number of `pos` */
    size_t line_end;    /* ascii: end of the current record's line (before '\n') */
    size_t value_start; /* binary: offset reported in messages */
    const char *name;
    lk_error *error;
} ply_body;

/* Sets an error prefixed with the location: "NAME:LINE: " for ascii bodies,
 * "NAME: byte N: " for binary ones. */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
static lk_status
body_error(const ply_body *body, lk_status status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    if (body->ascii)
        status = lk__error_at_line_v(body->error, status, body->name, body->line, format, args);
    else
        status = lk__error_at_byte_v(body->error, status, body->name, body->value_start, format, args);
    va_end(args);
    return status;
}

/* Moves to the next record. Ascii records are lines (blank lines are
 * skipped); returns false when the data has ended. */
static bool begin_record(ply_body *body)
{
    body->value_start = body->pos;
    if (!body->ascii) return body->pos < body->size;
    for (;;) {
        const char *p = lk__skip_spaces(body->data + body->pos, body->data + body->size);
        body->pos = (size_t)(p - body->data);
        if (body->pos == body->size) {
            /* Report the end of data on the last line, not after its newline. */
            if (body->size > 0 && body->data[body->size - 1] == '\n' && body->line > 1) body->line--;
            return false;
        }
        if (*p != '\n') break;
        body->pos++;
        body->line++;
    }
    const char *newline = memchr(body->data + body->pos, '\n', body->size - body->pos);
    body->line_end = newline ? (size_t)(newline - body->data) : body->size;
    return true;
}

/* Ascii records must not hold more values than the header declares. */
static lk_status end_record(ply_body *body, const char *record_name, unsigned long long index)
{
    if (!body->ascii) return LK_OK;
    const char *p = lk__skip_spaces(body->data + body->pos, body->data + body->line_end);
    if (p != body->data + body->line_end) {
        ply_word extra = {p, 0};
        while (p + extra.length < body->data + body->line_end && !lk__is_space(p[extra.length])) extra.length++;
        return body_error(body, LK_ERR_PARSE,
                          "%s %llu: unexpected extra value '%.*s' (more values than the header declares)", record_name,
                          index, quoted_length(extra.length), extra.start);
    }
    body->pos = body->line_end;
    if (body->pos < body->size) {
        body->pos++;
        body->line++;
    }
    return LK_OK;
}

static double decode_binary(const unsigned char *bytes, ply_type type, bool big_endian)
{
    size_t length = type_size(type);
    uint64_t bits = 0;
    for (size_t i = 0; i < length; i++) bits = (bits << 8) | bytes[big_endian ? i : length - 1 - i];
    switch (type) {
    case PLY_INT8: return bits >= 0x80u ? (double)bits - 256.0 : (double)bits;
    case PLY_INT16: return bits >= 0x8000u ? (double)bits - 65536.0 : (double)bits;
    case PLY_INT32: return bits >= 0x80000000u ? (double)bits - 4294967296.0 : (double)bits;
    case PLY_FLOAT32: {
        uint32_t word = (uint32_t)bits;
        float value;
        memcpy(&value, &word, sizeof value);
        return value;
    }
    case PLY_FLOAT64: {
        double value;
        memcpy(&value, &bits, sizeof value);
        return value;
    }
    default: return (double)bits;
    }
}

enum value_result { VALUE_OK, VALUE_END, VALUE_BAD };

static enum value_result read_value(ply_body *body, ply_type type, double *out)
{
    if (!body->ascii) {
        body->value_start = body->pos;
        size_t length = type_size(type);
        if (body->size - body->pos < length) return VALUE_END;
        *out = decode_binary((const unsigned char *)body->data + body->pos, type, body->big_endian);
        body->pos += length;
        return VALUE_OK;
    }
    const char *line_end = body->data + body->line_end;
    const char *p = lk__skip_spaces(body->data + body->pos, line_end);
    body->pos = (size_t)(p - body->data);
    if (p == line_end) return VALUE_END;
    if (!lk__parse_double(&p, line_end, out) || (p < line_end && !lk__is_space(*p))) return VALUE_BAD;
    body->pos = (size_t)(p - body->data);
    return VALUE_OK;
}

/* The word at the ascii cursor, for "expected a number, got 'abc'". */
static ply_word word_at_cursor(const ply_body *body)
{
    ply_word word = {body->data + body->pos, 0};
    while (body->pos + word.length < body->line_end && !lk__is_space(word.start[word.length])) word.length++;
    return word;
}

typedef struct ply_reader {
    ply_body body;
    lk_mesh *mesh;
    const ply_element *vertex_element;
    size_t vertex_count;
    int role_property[ROLE_COUNT]; /* vertex property index per role, or -1 */
    bool has_normals, has_texcoords, has_colors, has_radii;
    ply_type color_type[4];
    uint32_t *triangles;
    size_t triangle_count, triangle_capacity; /* the capacity is charged to the budget */
    lk__budget *budget;
} ply_reader;

static lk_status value_failure(ply_reader *reader, enum value_result result, const ply_element *element,
                               unsigned long long index, const ply_property *property)
{
    ply_body *body = &reader->body;
    char plural[64], singular[64];
    plural_name(element, plural, sizeof plural);
    singular_name(element, singular, sizeof singular);
    if (result == VALUE_END && !body->ascii)
        return body_error(body, LK_ERR_PARSE, "expected %llu %s, data ends after %llu", element->count, plural, index);
    if (result == VALUE_END)
        return body_error(body, LK_ERR_PARSE,
                          "%s %llu: line ends before property '%.*s' (fewer values than the header declares)", singular,
                          index, quoted_length(property->name_length), property->name);
    ply_word word = word_at_cursor(body);
    return body_error(body, LK_ERR_PARSE, "%s %llu: property '%.*s': expected a number, got '%.*s'", singular, index,
                      quoted_length(property->name_length), property->name, quoted_length(word.length), word.start);
}

/* Reads a list's length and checks that a binary list fits in the data, so
 * that a corrupt count (say 2^31) is refused before anything is done. */
static lk_status read_list_count(ply_reader *reader, const ply_element *element, unsigned long long index,
                                 const ply_property *property, unsigned long long *count)
{
    ply_body *body = &reader->body;
    double value;
    enum value_result result = read_value(body, property->count_type, &value);
    if (result != VALUE_OK) return value_failure(reader, result, element, index, property);
    char singular[64] = ""; /* named only for a message: it is a format call */
    if (!(value >= 0 && value <= 4294967295.0) || value != floor(value)) {
        singular_name(element, singular, sizeof singular);
        return body_error(body, LK_ERR_PARSE, "%s %llu: list '%.*s' has an invalid length %g", singular, index,
                          quoted_length(property->name_length), property->name, value);
    }
    *count = (unsigned long long)value;
    if (!body->ascii) {
        unsigned long long needed = *count * type_size(property->type);
        if (needed > body->size - body->pos) {
            singular_name(element, singular, sizeof singular);
            return body_error(body, LK_ERR_PARSE,
                              "%s %llu: list '%.*s' of %llu items needs %llu bytes but only %zu are left", singular,
                              index, quoted_length(property->name_length), property->name, *count, needed,
                              body->size - body->pos);
        }
    }
    return LK_OK;
}

static lk_status emit_triangle(ply_reader *reader, uint32_t a, uint32_t b, uint32_t c, unsigned long long face)
{
    if (reader->triangle_count == reader->triangle_capacity) {
        /* Polygons fan into more triangles than faces: grow within the budget. */
        size_t per_triangle = 3 * sizeof(uint32_t);
        size_t capacity = lk__budget_grow_capacity(reader->budget, reader->triangle_capacity,
                                                   reader->triangle_count + 1, per_triangle, 16);
        if (capacity == 0 || reader->triangle_count >= LK_MAX_ELEMENTS)
            return body_error(&reader->body, LK_ERR_LIMIT, "face %llu: more triangles than the memory budget allows",
                              face);
        uint32_t *grown = lk__realloc_array(reader->triangles, capacity, per_triangle);
        if (!grown) return body_error(&reader->body, LK_ERR_NOMEM, "out of memory for %zu triangles", capacity);
        lk__budget_charge(reader->budget, capacity - reader->triangle_capacity, per_triangle); /* fits */
        reader->triangles = grown;
        reader->triangle_capacity = capacity;
    }
    uint32_t *triangle = reader->triangles + 3 * reader->triangle_count++;
    triangle[0] = a;
    triangle[1] = b;
    triangle[2] = c;
    return LK_OK;
}

/* Reads a face's vertex index list and fans the polygon into triangles. */
static lk_status read_face(ply_reader *reader, const ply_element *element, unsigned long long index,
                           const ply_property *property)
{
    ply_body *body = &reader->body;
    unsigned long long count;
    lk_status status = read_list_count(reader, element, index, property, &count);
    if (status != LK_OK) return status;
    if (count < 3)
        return body_error(body, LK_ERR_PARSE, "face %llu has %llu vertex indices (a face needs at least 3)", index,
                          count);
    uint32_t first = 0, previous = 0;
    for (unsigned long long k = 0; k < count; k++) {
        double value;
        enum value_result result = read_value(body, property->type, &value);
        if (result != VALUE_OK) return value_failure(reader, result, element, index, property);
        if (value < 0) return body_error(body, LK_ERR_RANGE, "face %llu: vertex index %g is negative", index, value);
        if (value != floor(value))
            return body_error(body, LK_ERR_PARSE, "face %llu: vertex index %g is not an integer", index, value);
        if (!(value < (double)reader->vertex_count))
            return body_error(body, LK_ERR_RANGE, "face %llu: vertex index %.0f is out of range (%zu vertices)", index,
                              value, reader->vertex_count);
        uint32_t vertex = (uint32_t)value;
        if (k == 0) first = vertex;
        if (k >= 2) {
            status = emit_triangle(reader, first, previous, vertex, index);
            if (status != LK_OK) return status;
        }
        previous = vertex;
    }
    return LK_OK;
}

static lk_status skip_list(ply_reader *reader, const ply_element *element, unsigned long long index,
                           const ply_property *property)
{
    ply_body *body = &reader->body;
    unsigned long long count;
    lk_status status = read_list_count(reader, element, index, property, &count);
    if (status != LK_OK) return status;
    if (!body->ascii) {
        body->pos += (size_t)(count * type_size(property->type)); /* checked by read_list_count */
        return LK_OK;
    }
    for (unsigned long long k = 0; k < count; k++) {
        double value;
        enum value_result result = read_value(body, property->type, &value);
        if (result != VALUE_OK) return value_failure(reader, result, element, index, property);
    }
    return LK_OK;
}

/* Rounds a file value to float; refuses NaN, infinities and values that
 * overflow float (from FLT_MAX plus half its last-place unit on). Values
 * just above FLT_MAX, like "3.402823e+38", round down to it. */
static bool to_float(double value, float *out)
{
    const double overflow = (double)FLT_MAX + 0x1p103;
    if (!(fabs(value) < overflow)) return false;
    if (value > FLT_MAX) value = FLT_MAX;
    if (value < -FLT_MAX) value = -FLT_MAX;
    *out = (float)value;
    return true;
}

static lk_status not_finite(ply_reader *reader, size_t index, int property, double value, size_t record_start)
{
    const ply_property *declared = &reader->vertex_element->properties[property];
    reader->body.value_start = record_start;
    return body_error(&reader->body, LK_ERR_RANGE, "vertex %zu: %.*s = %g is not a finite float", index,
                      quoted_length(declared->name_length), declared->name, value);
}

static lk_status store_vertex(ply_reader *reader, size_t index, const double *values, size_t record_start)
{
    lk_mesh *mesh = reader->mesh;
    struct {
        float *target;
        enum ply_role first;
        int width;
    } groups[3] = {
        {mesh->positions + 3 * index, ROLE_X, 3},
        {mesh->normals ? mesh->normals + 3 * index : NULL, ROLE_NX, 3},
        {mesh->texcoords ? mesh->texcoords + 2 * index : NULL, ROLE_U, 2},
    };
    for (int g = 0; g < 3; g++) {
        if (!groups[g].target) continue;
        for (int k = 0; k < groups[g].width; k++) {
            enum ply_role role = (enum ply_role)(groups[g].first + k);
            int property = reader->role_property[role];
            double value = values[property];
            if (!to_float(value, &groups[g].target[k])) return not_finite(reader, index, property, value, record_start);
        }
    }
    if (mesh->colors) {
        float *colour = mesh->colors + 4 * index;
        for (int k = 0; k < 4; k++) {
            enum ply_role role = (enum ply_role)(ROLE_RED + k);
            int property = reader->role_property[role];
            double value = property < 0 ? 1.0 : values[property] * colour_scale(reader->color_type[k]);
            if (!to_float(value, &colour[k])) return not_finite(reader, index, property, value, record_start);
        }
    }
    if (mesh->radii) {
        /* Checked here rather than left to lk_mesh_validate so that the
         * message carries the line or byte offset of the bad record. */
        int property = reader->role_property[ROLE_RADIUS];
        double value = values[property];
        if (!to_float(value, &mesh->radii[index])) return not_finite(reader, index, property, value, record_start);
        if (!(mesh->radii[index] > 0)) {
            reader->body.value_start = record_start;
            return body_error(&reader->body, LK_ERR_RANGE, "vertex %zu: radius = %g must be > 0", index, value);
        }
    }
    return LK_OK;
}

/* ---- binary fast paths ------------------------------------------------------
 * The usual binary layouts (vertices whose positions, normals and texture
 * coordinates are floats, without colours or radii; faces that are nothing
 * but a list of int or uint indices with a char or uchar count) are read by
 * tight loops over whole records. A loop stops at the first record it cannot
 * take as it is (a polygon, an index out of range, a value that is not
 * finite, data that ends): read_element reads on from that record, so the
 * result and every message are the same as without the loop. */

/* A 4-byte value of the file as an unsigned integer; byte by byte, which
 * compilers turn into one load (and a byte swap on a foreign endianness). */
static inline uint32_t load_u32(const unsigned char *bytes, bool big_endian)
{
    if (big_endian)
        return (uint32_t)bytes[0] << 24 | (uint32_t)bytes[1] << 16 | (uint32_t)bytes[2] << 8 | (uint32_t)bytes[3];
    return (uint32_t)bytes[3] << 24 | (uint32_t)bytes[2] << 16 | (uint32_t)bytes[1] << 8 | (uint32_t)bytes[0];
}

enum { FAST_FLOATS_MAX = 8 }; /* x y z nx ny nz u v */

/* Reads the vertex records the fast path can take; returns how many. */
static unsigned long long read_vertices_fast(ply_reader *reader, const ply_element *element)
{
    ply_body *body = &reader->body;
    lk_mesh *mesh = reader->mesh;
    if (body->ascii || mesh->colors || mesh->radii) return 0;
    size_t record_size = 0, offsets[ROLE_COUNT];
    for (size_t j = 0; j < element->property_count; j++) {
        const ply_property *property = &element->properties[j];
        if (property->count_type != PLY_NONE) return 0;
        if (property->role != ROLE_NONE) offsets[property->role] = record_size;
        record_size += type_size(property->type);
    }
    /* The floats each record gives: where they are and where they go. */
    size_t float_offsets[FAST_FLOATS_MAX];
    float *targets[FAST_FLOATS_MAX];
    int widths[FAST_FLOATS_MAX];
    int float_count = 0;
    const struct {
        float *array;
        enum ply_role first;
        int width;
    } groups[3] = {{mesh->positions, ROLE_X, 3}, {mesh->normals, ROLE_NX, 3}, {mesh->texcoords, ROLE_U, 2}};
    for (int g = 0; g < 3; g++) {
        if (!groups[g].array) continue;
        for (int k = 0; k < groups[g].width; k++) {
            enum ply_role role = (enum ply_role)(groups[g].first + k);
            if (element->properties[reader->role_property[role]].type != PLY_FLOAT32) return 0;
            float_offsets[float_count] = offsets[role];
            targets[float_count] = groups[g].array + k;
            widths[float_count] = groups[g].width;
            float_count++;
        }
    }
    const unsigned char *record = (const unsigned char *)body->data + body->pos;
    size_t whole_records = (body->size - body->pos) / record_size;
    unsigned long long count = element->count < whole_records ? element->count : whole_records;
    bool big_endian = body->big_endian;
    unsigned long long index = 0;
    for (; index < count; index++, record += record_size) {
        uint32_t bits[FAST_FLOATS_MAX];
        uint32_t exponents_all_ones = 0;
        for (int k = 0; k < float_count; k++) {
            bits[k] = load_u32(record + float_offsets[k], big_endian);
            /* NaN or infinity: the slow path says which and where. */
            exponents_all_ones |= (bits[k] & 0x7f800000u) == 0x7f800000u;
        }
        if (exponents_all_ones) break;
        for (int k = 0; k < float_count; k++) memcpy(targets[k] + (size_t)index * (size_t)widths[k], &bits[k], 4);
    }
    body->pos += (size_t)index * record_size;
    return index;
}

/* Reads the triangles (count 3) of a face element that holds only its index
 * list, as long as they fit and index existing vertices; returns how many. */
static unsigned long long read_triangles_fast(ply_reader *reader, const ply_element *element)
{
    ply_body *body = &reader->body;
    if (body->ascii || element->property_count != 1 || !reader->triangles) return 0;
    const ply_property *list = &element->properties[0];
    if (list->role != ROLE_FACE_INDICES || (list->count_type != PLY_UINT8 && list->count_type != PLY_INT8) ||
        (list->type != PLY_INT32 && list->type != PLY_UINT32))
        return 0;
    enum { RECORD = 1 + 3 * 4 };
    const unsigned char *record = (const unsigned char *)body->data + body->pos;
    size_t whole_records = (body->size - body->pos) / RECORD;
    size_t room = reader->triangle_capacity - reader->triangle_count;
    unsigned long long count = element->count;
    if (count > whole_records) count = whole_records;
    if (count > room) count = room;
    bool big_endian = body->big_endian;
    /* Negative int indices are above every vertex count as uint32_t. */
    uint32_t vertex_count = (uint32_t)reader->vertex_count;
    uint32_t *triangle = reader->triangles + 3 * reader->triangle_count;
    unsigned long long index = 0;
    for (; index < count; index++, record += RECORD, triangle += 3) {
        if (record[0] != 3) break;
        uint32_t a = load_u32(record + 1, big_endian), b = load_u32(record + 5, big_endian),
                 c = load_u32(record + 9, big_endian);
        if (a >= vertex_count || b >= vertex_count || c >= vertex_count) break;
        triangle[0] = a;
        triangle[1] = b;
        triangle[2] = c;
    }
    reader->triangle_count += (size_t)index;
    body->pos += (size_t)index * RECORD;
    return index;
}

static lk_status read_element(ply_reader *reader, const ply_element *element, bool is_vertex, double *values)
{
    ply_body *body = &reader->body;
    if (element->property_count == 0) return LK_OK; /* records of zero bytes */
    char singular[64], plural[64];
    singular_name(element, singular, sizeof singular);
    plural_name(element, plural, sizeof plural);
    unsigned long long first = is_vertex ? read_vertices_fast(reader, element) : read_triangles_fast(reader, element);
    for (unsigned long long index = first; index < element->count; index++) {
        if (!begin_record(body))
            return body_error(body, LK_ERR_PARSE, "expected %llu %s, data ends after %llu", element->count, plural,
                              index);
        size_t record_start = body->pos;
        for (size_t j = 0; j < element->property_count; j++) {
            const ply_property *property = &element->properties[j];
            lk_status status = LK_OK;
            if (property->count_type == PLY_NONE) {
                enum value_result result = read_value(body, property->type, &values[j]);
                if (result != VALUE_OK) status = value_failure(reader, result, element, index, property);
            } else if (property->role == ROLE_FACE_INDICES) {
                status = read_face(reader, element, index, property);
            } else {
                status = skip_list(reader, element, index, property);
            }
            if (status != LK_OK) return status;
        }
        if (is_vertex) {
            lk_status status = store_vertex(reader, (size_t)index, values, record_start);
            if (status != LK_OK) return status;
        }
        lk_status status = end_record(body, singular, index);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

/* Finds the vertex and face elements and what their properties mean. */
static lk_status assign_roles(ply_header *header, ply_reader *reader, const char *name, ply_element **vertex_out,
                              ply_element **face_out, lk_error *error)
{
    ply_element *vertex = NULL, *face = NULL;
    for (int r = 0; r < ROLE_COUNT; r++) reader->role_property[r] = -1;
    for (size_t i = 0; i < header->element_count; i++) {
        ply_element *element = &header->elements[i];
        if (lk__word_equals(element->name, element->name_length, "vertex")) {
            if (vertex)
                return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: second 'vertex' element", name, element->line);
            vertex = element;
            for (size_t j = 0; j < element->property_count; j++) {
                ply_property *property = &element->properties[j];
                for (size_t n = 0; n < sizeof vertex_property_names / sizeof vertex_property_names[0]; n++) {
                    if (!lk__word_equals(property->name, property->name_length, vertex_property_names[n].name))
                        continue;
                    enum ply_role role = vertex_property_names[n].role;
                    if (property->count_type != PLY_NONE)
                        return lk_error_set(error, LK_ERR_PARSE,
                                            "%s:%zu: vertex property '%.*s' is a list; expected a single value", name,
                                            element->line, quoted_length(property->name_length), property->name);
                    if (reader->role_property[role] < 0) {
                        reader->role_property[role] = (int)j;
                        property->role = role;
                    }
                    break;
                }
            }
        } else if (lk__word_equals(element->name, element->name_length, "face")) {
            if (face) return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: second 'face' element", name, element->line);
            face = element;
            for (size_t j = 0; j < element->property_count; j++) {
                ply_property *property = &element->properties[j];
                if (!lk__word_equals(property->name, property->name_length, "vertex_indices") &&
                    !lk__word_equals(property->name, property->name_length, "vertex_index"))
                    continue;
                if (property->count_type == PLY_NONE)
                    return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: face property '%.*s' must be a list", name,
                                        element->line, quoted_length(property->name_length), property->name);
                property->role = ROLE_FACE_INDICES;
                break;
            }
        }
    }
    if (!vertex)
        return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: the header declares no 'vertex' element", name,
                            header->end_line);
    static const char *const required[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; k++)
        if (reader->role_property[ROLE_X + k] < 0)
            return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: element vertex has no property '%s'", name, vertex->line,
                                required[k]);
    if (face && face->count > 0) {
        bool has_indices = false;
        for (size_t j = 0; j < face->property_count; j++) has_indices |= face->properties[j].role == ROLE_FACE_INDICES;
        if (!has_indices)
            return lk_error_set(error, LK_ERR_PARSE, "%s:%zu: element face has no 'vertex_indices' list", name,
                                face->line);
    }
    const int *role = reader->role_property;
    reader->has_normals = role[ROLE_NX] >= 0 && role[ROLE_NY] >= 0 && role[ROLE_NZ] >= 0;
    reader->has_texcoords = role[ROLE_U] >= 0 && role[ROLE_V] >= 0;
    reader->has_colors = role[ROLE_RED] >= 0 && role[ROLE_GREEN] >= 0 && role[ROLE_BLUE] >= 0;
    reader->has_radii = role[ROLE_RADIUS] >= 0;
    for (int k = 0; k < 4; k++)
        reader->color_type[k] = role[ROLE_RED + k] >= 0 ? vertex->properties[role[ROLE_RED + k]].type : PLY_FLOAT32;
    *vertex_out = vertex;
    *face_out = face;
    return LK_OK;
}

/* Refuses element counts that the remaining bytes or the memory budget
 * cannot hold, before anything is allocated. */
static lk_status check_claims(const ply_header *header, const ply_reader *reader, const ply_element *vertex,
                              const ply_element *face, size_t size, const lk__read_context *ctx, lk_error *error)
{
    size_t available = size - header->body_offset;
    size_t vertex_bytes = 3 * sizeof(float) + (reader->has_normals ? 3 * sizeof(float) : 0) +
                          (reader->has_texcoords ? 2 * sizeof(float) : 0) +
                          (reader->has_colors ? 4 * sizeof(float) : 0) + (reader->has_radii ? sizeof(float) : 0);
    size_t triangle_bytes = 3 * sizeof(uint32_t);
    for (size_t i = 0; i < header->element_count; i++) {
        const ply_element *element = &header->elements[i];
        if (element->property_count == 0) continue;
        size_t min_bytes = 0;
        if (header->encoding == LK_PLY_ASCII) {
            min_bytes = 2; /* a value and a separator */
        } else {
            for (size_t j = 0; j < element->property_count; j++) {
                const ply_property *property = &element->properties[j];
                min_bytes += type_size(property->count_type != PLY_NONE ? property->count_type : property->type);
            }
        }
        char what[64], where[300];
        plural_name(element, what, sizeof what);
        snprintf(where, sizeof where, "%s:%zu", ctx->name, element->line);
        size_t per_element = element == vertex ? vertex_bytes : element == face ? triangle_bytes : 0;
        lk_status status =
            lk__check_claim(element->count, min_bytes, available, per_element, ctx->budget, what, where, error);
        if (status != LK_OK) return status;
        available -= (size_t)element->count * min_bytes;
    }
    /* The mesh arrays, one triangle per face to begin with, are charged
     * here: lk__read_ply allocates them next. */
    unsigned long long face_count = face ? face->count : 0;
    if ((unsigned long long)vertex->count * vertex_bytes + face_count * triangle_bytes > lk__budget_room(ctx->budget))
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s:%zu: %llu vertices and %llu faces would need more than the memory budget of %zu bytes",
                            ctx->name, vertex->line, vertex->count, face_count, ctx->budget->limit);
    lk__budget_charge(ctx->budget, (size_t)vertex->count * vertex_bytes + (size_t)face_count * triangle_bytes, 1);
    return LK_OK;
}

lk_status lk__read_ply(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    ply_header header;
    lk_status status = parse_header(data, size, ctx->name, ctx->budget, &header, error);
    if (status != LK_OK) {
        header_free(&header);
        return status;
    }
    ply_reader reader;
    memset(&reader, 0, sizeof reader);
    ply_element *vertex = NULL, *face = NULL;
    double *values = NULL;
    status = assign_roles(&header, &reader, ctx->name, &vertex, &face, error);
    if (status == LK_OK) status = check_claims(&header, &reader, vertex, face, size, ctx, error);
    if (status == LK_OK) {
        unsigned flags = (reader.has_normals ? LK_ATTR_NORMALS : 0u) | (reader.has_texcoords ? LK_ATTR_TEXCOORDS : 0u) |
                         (reader.has_colors ? LK_ATTR_COLORS : 0u) | (reader.has_radii ? LK_ATTR_RADII : 0u);
        status = lk_mesh_alloc(mesh, (size_t)vertex->count, 0, flags, error);
        size_t most_properties = 1;
        for (size_t i = 0; i < header.element_count; i++)
            if (header.elements[i].property_count > most_properties)
                most_properties = header.elements[i].property_count;
        /* One double per property: not charged, a fifth of what the header's (charged) arrays hold for it. */
        values = lk__malloc_array(most_properties, sizeof *values);
        if (status == LK_OK && !values) status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
    }
    if (status == LK_OK) {
        reader.mesh = mesh;
        reader.vertex_element = vertex;
        reader.vertex_count = (size_t)vertex->count;
        reader.budget = ctx->budget;
        reader.body = (ply_body){
            .data = data,
            .size = size,
            .pos = header.body_offset,
            .ascii = header.encoding == LK_PLY_ASCII,
            .big_endian = header.encoding == LK_PLY_BINARY_BE,
            .line = header.body_line,
            .name = ctx->name,
            .error = error,
        };
        if (face && face->count) {
            reader.triangles = lk__alloc_random_access((size_t)face->count, 3 * sizeof(uint32_t), false);
            reader.triangle_capacity = (size_t)face->count;
            if (!reader.triangles) status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
        }
        for (size_t i = 0; status == LK_OK && i < header.element_count; i++)
            status = read_element(&reader, &header.elements[i], &header.elements[i] == vertex, values);
    }
    if (status == LK_OK && reader.triangle_count) {
        free(mesh->indices);
        mesh->indices = reader.triangles;
        mesh->triangle_count = reader.triangle_count;
        reader.triangles = NULL;
    }
    free(reader.triangles);
    free(values);
    header_free(&header);
    if (status != LK_OK) lk_mesh_free(mesh);
    return status;
}

/* ---- writer ---------------------------------------------------------------- */

typedef struct ply_output {
    FILE *file;
    unsigned char buffer[1 << 16];
    size_t used;
    bool big_endian;
    bool failed;
} ply_output;

static void output_flush(ply_output *out)
{
    if (out->used && fwrite(out->buffer, 1, out->used, out->file) != out->used) out->failed = true;
    out->used = 0;
}

static void output_bytes(ply_output *out, const void *bytes, size_t length)
{
    if (sizeof out->buffer - out->used < length) output_flush(out);
    memcpy(out->buffer + out->used, bytes, length);
    out->used += length;
}

static void output_u32(ply_output *out, uint32_t value)
{
    unsigned char bytes[4];
    for (int i = 0; i < 4; i++) {
        int shift = out->big_endian ? 8 * (3 - i) : 8 * i;
        bytes[i] = (unsigned char)(value >> shift);
    }
    output_bytes(out, bytes, 4);
}

static void output_float(ply_output *out, float value)
{
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    output_u32(out, bits);
}

static void output_text_float(ply_output *out, float value, char separator)
{
    char text[40];
    int length = lk__format_float(text, sizeof text - 1, value);
    if (length < 0 || (size_t)length >= sizeof text - 1) length = (int)strlen(text);
    text[length++] = separator;
    output_bytes(out, text, (size_t)length);
}

static void output_text_uint(ply_output *out, unsigned long value, char separator)
{
    char text[32];
    int length = snprintf(text, sizeof text, "%lu%c", value, separator);
    output_bytes(out, text, (size_t)length);
}

static unsigned char colour_byte(float value)
{
    if (!(value > 0)) return 0;
    if (value >= 1) return 255;
    return (unsigned char)lrintf(value * 255.0f);
}

lk_status lk__write_ply(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error)
{
    lk_ply_encoding encoding = options->ply_encoding;
    static const char *const format_names[] = {"binary_little_endian", "binary_big_endian", "ascii"};
    if (encoding != LK_PLY_BINARY_LE && encoding != LK_PLY_BINARY_BE && encoding != LK_PLY_ASCII)
        return lk_error_set(error, LK_ERR_INVALID, "unknown PLY encoding %d", (int)encoding);
    bool normals = mesh->normals && !options->skip_normals;
    bool texcoords = mesh->texcoords && !options->skip_texcoords;
    bool colors = mesh->colors && !options->skip_colors;
    bool radii = mesh->radii != NULL; /* lk_write_options has no switch for radii */
    /* "int" is what most tools expect; fall back to uint for huge meshes. */
    const char *index_type = mesh->vertex_count > 0x7FFFFFFFu ? "uint" : "int";

    if (fprintf(file, "ply\nformat %s 1.0\ncomment written by lodkit %s\nelement vertex %zu\n", format_names[encoding],
                LK_VERSION_STRING, mesh->vertex_count) < 0 ||
        fputs("property float x\nproperty float y\nproperty float z\n", file) < 0 ||
        (normals && fputs("property float nx\nproperty float ny\nproperty float nz\n", file) < 0) ||
        (texcoords && fputs("property float s\nproperty float t\n", file) < 0) ||
        (radii && fputs("property float radius\n", file) < 0) ||
        (colors &&
         fputs("property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n", file) < 0) ||
        (mesh->triangle_count && fprintf(file, "element face %zu\nproperty list uchar %s vertex_indices\n",
                                         mesh->triangle_count, index_type) < 0) ||
        fputs("end_header\n", file) < 0)
        return lk_error_set(error, LK_ERR_IO, "write error while writing the PLY header");

    ply_output *out = malloc(sizeof *out);
    if (!out) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    out->file = file;
    out->used = 0;
    out->big_endian = encoding == LK_PLY_BINARY_BE;
    out->failed = false;
    bool ascii = encoding == LK_PLY_ASCII;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        float values[9];
        int count = 0;
        for (int k = 0; k < 3; k++) values[count++] = mesh->positions[3 * v + k];
        if (normals)
            for (int k = 0; k < 3; k++) values[count++] = mesh->normals[3 * v + k];
        if (texcoords)
            for (int k = 0; k < 2; k++) values[count++] = mesh->texcoords[2 * v + k];
        if (radii) values[count++] = mesh->radii[v];
        unsigned char colour[4];
        if (colors)
            for (int k = 0; k < 4; k++) colour[k] = colour_byte(mesh->colors[4 * v + k]);
        for (int i = 0; i < count; i++) {
            if (ascii)
                output_text_float(out, values[i], i + 1 == count && !colors ? '\n' : ' ');
            else
                output_float(out, values[i]);
        }
        if (colors) {
            if (ascii)
                for (int k = 0; k < 4; k++) output_text_uint(out, colour[k], k == 3 ? '\n' : ' ');
            else
                output_bytes(out, colour, 4);
        }
    }
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *triangle = mesh->indices + 3 * t;
        if (ascii) {
            output_bytes(out, "3 ", 2);
            for (int k = 0; k < 3; k++) output_text_uint(out, triangle[k], k == 2 ? '\n' : ' ');
        } else {
            unsigned char three = 3;
            output_bytes(out, &three, 1);
            for (int k = 0; k < 3; k++) output_u32(out, triangle[k]);
        }
    }
    output_flush(out);
    bool failed = out->failed || ferror(file);
    free(out);
    if (failed) return lk_error_set(error, LK_ERR_IO, "write error while writing PLY data");
    return LK_OK;
}

/* ---- streamed point clouds (the octree's reader) --------------------------- */

lk_status lk__ply_stream_layout(const char *head, size_t head_size, unsigned long long file_size, const char *name,
                                lk__ply_layout *layout, lk_error *error)
{
    memset(layout, 0, sizeof *layout);
    lk__budget budget = {(size_t)1 << 30, 0};
    ply_header header;
    lk_status status = parse_header(head, head_size, name, &budget, &header, error);
    if (status != LK_OK) {
        /* a header longer than `head` is read whole instead */
        if (strstr(error ? error->message : "", "without 'end_header'")) status = LK_ERR_UNSUPPORTED;
        header_free(&header);
        return status;
    }
    ply_element *vertex = header.element_count ? &header.elements[0] : NULL;
    status = LK_ERR_UNSUPPORTED;
    bool ascii = header.encoding == LK_PLY_ASCII;
    if (vertex && lk__word_equals(vertex->name, vertex->name_length, "vertex")) {
        for (int r = 0; r < 9; r++) layout->at[r] = SIZE_MAX;
        static const enum ply_role roles[9] = {ROLE_X,  ROLE_Y,   ROLE_Z,     ROLE_NX,  ROLE_NY,
                                               ROLE_NZ, ROLE_RED, ROLE_GREEN, ROLE_BLUE};
        size_t offset = 0;
        bool fixed = true;
        for (size_t j = 0; j < vertex->property_count; j++) {
            const ply_property *property = &vertex->properties[j];
            if (property->count_type != PLY_NONE) fixed = false;
            for (size_t n = 0; n < sizeof vertex_property_names / sizeof vertex_property_names[0]; n++) {
                if (!lk__word_equals(property->name, property->name_length, vertex_property_names[n].name)) continue;
                for (int r = 0; r < 9; r++)
                    if (roles[r] == vertex_property_names[n].role && layout->at[r] == SIZE_MAX) {
                        layout->at[r] = ascii ? j : offset; /* ASCII: the value's place on its line */
                        layout->type[r] = (int)property->type;
                    }
            }
            offset += type_size(property->type);
        }
        if (fixed && layout->at[0] != SIZE_MAX && layout->at[1] != SIZE_MAX && layout->at[2] != SIZE_MAX) {
            status = LK_OK;
            layout->count = vertex->count;
            layout->record_size = offset;
            layout->body_offset = header.body_offset;
            layout->ascii = ascii;
            layout->body_line = header.body_line;
            layout->property_count = vertex->property_count;
            layout->big_endian = header.encoding == LK_PLY_BINARY_BE;
            layout->has_normals = layout->at[3] != SIZE_MAX && layout->at[4] != SIZE_MAX && layout->at[5] != SIZE_MAX;
            layout->has_colors = layout->at[6] != SIZE_MAX && layout->at[7] != SIZE_MAX && layout->at[8] != SIZE_MAX;
            for (int k = 0; k < 3; k++)
                layout->color_scale[k] = layout->has_colors ? colour_scale((ply_type)layout->type[6 + k]) : 1.0;
            unsigned long long available = file_size - header.body_offset;
            /* an ASCII value takes two bytes at least (a digit and a separator) */
            size_t least = ascii ? 2 * vertex->property_count : offset;
            if (least == 0 || layout->count > available / least)
                status = lk_error_set(error, LK_ERR_PARSE,
                                      "%s:%zu: %llu vertices of %s%zu bytes do not fit in the %llu bytes after "
                                      "the header (truncated or corrupt file)",
                                      name, vertex->line, layout->count, ascii ? "at least " : "", least, available);
            else if (layout->count == 0)
                status = lk_error_set(error, LK_ERR_PARSE, "%s:%zu: no vertices", name, vertex->line);
        }
    }
    header_free(&header);
    return status;
}

double lk__ply_stream_value(const unsigned char *bytes, int type, int big_endian)
{
    return decode_binary(bytes, (ply_type)type, big_endian != 0);
}

double lk__ply_ascii_value(double value, int type)
{
    return (ply_type)type == PLY_FLOAT32 ? (double)(float)value : value;
}
