/* SPDX-License-Identifier: MIT */
/* Wavefront OBJ with its .mtl materials into an lk_scene (lk_scene_read).
 *
 * One node holding one mesh; its faces are split into one primitive per
 * material, in the order the `usemtl` statements first use them (faces
 * before any `usemtl` form a primitive without a material, glTF's default
 * one). Each primitive gets a vertex per distinct (v, vt, vn) triple of its
 * corners, as glTF wants; polygons become fans around their first corner,
 * as in the mesh reader (io_obj.c), so both read the same triangles.
 * Texture coordinates stay as OBJ writes them: lk_mesh's v points up like
 * OBJ's, and the glTF writer flips them to glTF's convention.
 *
 * The .mtl files (`mtllib`, read from the .obj's folder once all of the
 * .obj is read) give each material's glTF values: Kd -> baseColorFactor
 * rgb, d (or 1 - Tr) -> its alpha and alphaMode BLEND when below 1, Ke ->
 * emissiveFactor, Pr / Pm (the PBR extension of MTL) -> roughness and
 * metallic factors, else a roughness estimated from Ns and Ks (see
 * roughness_of), map_Kd -> baseColorTexture, map_Bump / bump / norm ->
 * normalTexture. Textures are read from files next to the .mtl, inside the
 * .obj's folder only (lk__open_input: no absolute paths, no "..", no links),
 * charged to the read's budget. What cannot be found or is not kept (a
 * missing .mtl or image, a material no .mtl defines, map_d, other maps,
 * texture options) is said in scene->notes and left out; it is not an
 * error, as OBJ users expect. Malformed statements in the .obj or the .mtl
 * are errors naming the file and line. */
#include "internal.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* A face corner: 1-based indices (negative ones resolved), 0: not given. */
typedef struct corner {
    uint32_t v, vt, vn;
} corner;

/* Names in first-use order, each with its index: usemtl names, newmtl
 * names, image paths, .mtl files. Charged to the read's budget. */
typedef struct name_table {
    lk__buffer text;    /* the names, each followed by a NUL */
    lk__buffer offsets; /* size_t per name: where it starts in text */
    uint32_t *slots;    /* open addressing: name index + 1, 0 empty */
    size_t capacity;    /* slots (a power of two) */
    size_t count;
} name_table;

/* A material as a .mtl defines it. */
typedef struct mtl_material {
    double diffuse[3], specular[3], emissive[3];
    double alpha, shininess, roughness, metallic;
    bool has_specular, has_shininess, has_roughness, has_metallic;
    size_t color_map, normal_map; /* offset + 1 into the parser's map_paths text, 0: none */
} mtl_material;

/* The largest positive index seen and the line that used it, checked once
 * the whole file is read (OBJ allows references forward). */
typedef struct max_reference {
    uint32_t index;
    size_t line;
} max_reference;

/* Which notes are capped: a file naming thousands of missing textures
 * says so a few times, then once that there is more. */
enum { NOTE_LIMIT = 24 };

typedef struct scene_parser {
    const char *name;      /* the .obj, for messages */
    const char *directory; /* its folder, NULL when read from memory */
    lk__budget *budget;
    lk_error *error;
    lk__buffer positions, colors, texcoords, normals; /* float[3], float[4], float[2], float[3] */
    lk__buffer corners;                               /* corner[3] per triangle */
    lk__buffer triangle_groups;                       /* uint32_t per triangle: index into groups */
    lk__buffer polygon;                               /* corner per corner of the face being read */
    lk__buffer joined;                                /* a line joined from backslash continuations */
    lk__buffer mtllibs;                               /* per mtllib: size_t line, then the text and a NUL */
    size_t position_count, texcoord_count, normal_count;
    max_reference max_v, max_vt, max_vn;
    name_table groups; /* usemtl names in first-use order; "\n" is faces without usemtl */
    uint32_t group;    /* the current one */
    char *object_name; /* the first `o`, or NULL */
    /* .mtl */
    const char *mtl_name;   /* the .mtl being parsed, for messages */
    const char *mtl_folder; /* its folder relative to the .obj's: "" or ending in '/' */
    int64_t mtl_current;    /* index of the material being defined, -1: none, -2: a repeated name */
    mtl_material mtl_repeated;
    name_table mtl_files, mtl_inodes, materials;
    bool memory_mtl_read;     /* the fuzz target's .mtl text was read (once for all) */
    lk__buffer mtl_materials; /* mtl_material per name in materials */
    lk__buffer map_paths;     /* texture paths (relative to the .obj's folder), each followed by a NUL */
    const char *memory_mtl;   /* the fuzz target's .mtl text for every mtllib (see lk__read_obj_scene_text) */
    size_t memory_mtl_size;
    /* images */
    name_table image_paths;
    int32_t *image_of_path; /* per image path: index into scene->images, -1 not readable */
    lk__buffer notes;
    size_t note_count;
    lk_scene *scene;
} scene_parser;

static const char no_material_group[] = "\n"; /* no name read from a line holds a newline */

static lk_status fail_at(scene_parser *parser, const char *name, size_t line, lk_status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;
static lk_status fail_at(scene_parser *parser, const char *name, size_t line, lk_status status, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    status = lk__error_at_line_v(parser->error, status, name, line, format, args);
    va_end(args);
    return status;
}

static lk_status out_of_memory(scene_parser *parser)
{
    return lk_error_set(parser->error, LK_ERR_NOMEM, "%s: out of memory", parser->name);
}

static lk_status over_budget(scene_parser *parser)
{
    return lk_error_set(parser->error, LK_ERR_LIMIT, "%s: the model needs more than the memory budget of %zu bytes",
                        parser->name, parser->budget->limit);
}

/* LK_ERR_LIMIT / LK_ERR_NOMEM of a charged buffer into a message. */
static lk_status growth_failure(scene_parser *parser, lk_status status)
{
    return status == LK_ERR_LIMIT ? over_budget(parser) : out_of_memory(parser);
}

static lk_status append(scene_parser *parser, lk__buffer *buffer, const void *bytes, size_t size)
{
    lk_status status = lk__buffer_append_charged(buffer, bytes, size, parser->budget);
    return status == LK_OK ? LK_OK : growth_failure(parser, status);
}

static void note(scene_parser *parser, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void note(scene_parser *parser, const char *format, ...)
{
    if (parser->note_count > NOTE_LIMIT) return;
    if (parser->note_count == NOTE_LIMIT) {
        parser->note_count++;
        lk__buffer_append(&parser->notes, "(further notes left out)\n", 25);
        return;
    }
    va_list args;
    va_start(args, format);
    if (lk__notes_vadd(&parser->notes, format, args)) parser->note_count++;
    va_end(args);
}

/* ---- name tables --------------------------------------------------------- */

static uint64_t name_hash(const char *name, size_t length)
{
    uint64_t hash = 1469598103934665603ull; /* FNV-1a */
    for (size_t i = 0; i < length; i++) hash = (hash ^ (unsigned char)name[i]) * 1099511628211ull;
    return lk__mix64(hash);
}

static const char *name_at(const name_table *table, size_t index)
{
    return (const char *)table->text.data + ((const size_t *)table->offsets.data)[index];
}

/* Where `name` is or would go. */
static uint32_t *name_slot(const name_table *table, const char *name, size_t length)
{
    size_t at = name_hash(name, length) & (table->capacity - 1);
    for (;;) {
        uint32_t *slot = &table->slots[at];
        if (*slot == 0) return slot;
        const char *other = name_at(table, *slot - 1);
        if (strncmp(other, name, length) == 0 && other[length] == '\0') return slot;
        at = (at + 1) & (table->capacity - 1);
    }
}

static lk_status name_table_grow(scene_parser *parser, name_table *table)
{
    size_t capacity = table->capacity ? table->capacity * 2 : 16;
    if (!lk__budget_charge(parser->budget, capacity, sizeof(uint32_t))) return over_budget(parser);
    uint32_t *slots = lk__calloc_array(capacity, sizeof *slots);
    if (!slots) {
        lk__budget_release(parser->budget, capacity, sizeof(uint32_t));
        return out_of_memory(parser);
    }
    uint32_t *old = table->slots;
    size_t old_capacity = table->capacity;
    table->slots = slots;
    table->capacity = capacity;
    for (size_t i = 0; i < table->count; i++) {
        const char *name = name_at(table, i);
        *name_slot(table, name, strlen(name)) = (uint32_t)i + 1;
    }
    free(old);
    lk__budget_release(parser->budget, old_capacity, sizeof(uint32_t));
    return LK_OK;
}

/* The index of `name` (length bytes, no NUL inside), added at the end when
 * new (*added says so). */
static lk_status name_table_add(scene_parser *parser, name_table *table, const char *name, size_t length,
                                uint32_t *index, bool *added)
{
    *added = false;
    if (2 * (table->count + 1) > table->capacity) {
        lk_status status = name_table_grow(parser, table);
        if (status != LK_OK) return status;
    }
    uint32_t *slot = name_slot(table, name, length);
    if (*slot) {
        *index = *slot - 1;
        return LK_OK;
    }
    if (table->count >= UINT32_MAX - 1) return over_budget(parser);
    size_t offset = table->text.size;
    lk_status status = append(parser, &table->text, name, length);
    if (status == LK_OK) status = append(parser, &table->text, "", 1);
    if (status == LK_OK) status = append(parser, &table->offsets, &offset, sizeof offset);
    if (status != LK_OK) return status;
    *index = (uint32_t)table->count++;
    *slot = *index + 1;
    *added = true;
    return LK_OK;
}

/* -1 when absent. */
static int64_t name_table_find(const name_table *table, const char *name)
{
    if (table->count == 0) return -1;
    uint32_t *slot = name_slot(table, name, strlen(name));
    return *slot ? (int64_t)*slot - 1 : -1;
}

static void name_table_free(scene_parser *parser, name_table *table)
{
    lk__buffer_free_charged(&table->text, parser->budget);
    lk__buffer_free_charged(&table->offsets, parser->budget);
    free(table->slots);
    lk__budget_release(parser->budget, table->capacity, sizeof(uint32_t));
    memset(table, 0, sizeof *table);
}

/* ---- lines --------------------------------------------------------------- */

/* The rest of a statement with spaces trimmed at both ends (names may hold
 * spaces: "usemtl Hard Shiny Plastic"); a comment ends it only after a
 * space, as "#" may be part of a name. */
static void rest_of_line(const char *p, const char *end, const char **start, size_t *length)
{
    p = lk__skip_spaces(p, end);
    const char *stop = p;
    while (stop < end && !(*stop == '#' && (stop == p || lk__is_space(stop[-1])))) stop++;
    while (stop > p && lk__is_space(stop[-1])) stop--;
    *start = p;
    *length = (size_t)(stop - p);
}

/* Calls parse(parser, start, end, line) for every logical line of a text
 * file (backslash continuations joined), after refusing UTF-16 and
 * binary data and skipping a UTF-8 byte order mark. */
typedef lk_status (*line_parser)(scene_parser *parser, const char *p, const char *end, size_t line);

static const char *continuation(const char *line_start, const char *line_end)
{
    const char *q = line_end;
    if (q > line_start && q[-1] == '\r') q--;
    return q > line_start && q[-1] == '\\' ? q - 1 : NULL;
}

static lk_status for_each_line(scene_parser *parser, const char *name, const char *data, size_t size, line_parser parse)
{
    const unsigned char *bytes = (const unsigned char *)data;
    if (size >= 2 && ((bytes[0] == 0xFE && bytes[1] == 0xFF) || (bytes[0] == 0xFF && bytes[1] == 0xFE)))
        return lk_error_set(parser->error, LK_ERR_UNSUPPORTED,
                            "%s: file is UTF-16 encoded (byte order mark %02X %02X); save it as UTF-8 or ASCII", name,
                            bytes[0], bytes[1]);
    const unsigned char *nul = memchr(bytes, 0, size < 4096 ? size : 4096);
    if (nul)
        return lk_error_set(parser->error, LK_ERR_PARSE, "%s: byte %zu: NUL byte in what should be a text file", name,
                            (size_t)(nul - bytes));
    const char *p = data, *end = data + size;
    if (size >= 3 && memcmp(p, "\xEF\xBB\xBF", 3) == 0) p += 3;
    size_t line = 0;
    while (p < end) {
        size_t first_line = ++line;
        const char *newline = memchr(p, '\n', (size_t)(end - p));
        const char *line_start = p, *line_end = newline ? newline : end;
        p = newline ? newline + 1 : end;
        const char *cut = continuation(line_start, line_end);
        if (cut) {
            parser->joined.size = 0;
            for (;;) {
                lk_status status = append(parser, &parser->joined, line_start, (size_t)(cut - line_start));
                if (status == LK_OK) status = append(parser, &parser->joined, " ", 1);
                if (status != LK_OK) return status;
                if (p >= end) break;
                line++;
                newline = memchr(p, '\n', (size_t)(end - p));
                line_start = p;
                line_end = newline ? newline : end;
                p = newline ? newline + 1 : end;
                cut = continuation(line_start, line_end);
                if (!cut) {
                    status = append(parser, &parser->joined, line_start, (size_t)(line_end - line_start));
                    if (status != LK_OK) return status;
                    break;
                }
            }
            line_start = (const char *)parser->joined.data;
            line_end = line_start + parser->joined.size;
        }
        /* NUL bytes past the probe would cut names short: refused too. */
        if (memchr(line_start, '\0', (size_t)(line_end - line_start)))
            return fail_at(parser, name, first_line, LK_ERR_PARSE, "NUL byte in what should be a text file");
        lk_status status = parse(parser, line_start, line_end, first_line);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

/* ---- .obj statements ----------------------------------------------------- */

static int parse_numbers(const char **p, const char *end, double *values, int capacity)
{
    int count = 0;
    while (count < capacity && lk__parse_double(p, end, &values[count])) count++;
    return count;
}

static lk_status check_finite(scene_parser *parser, const char *name, size_t line, const double *values, int count)
{
    for (int i = 0; i < count; i++)
        if (!isfinite((float)values[i]))
            return fail_at(parser, name, line, LK_ERR_RANGE, "%g is not a finite float", values[i]);
    return LK_OK;
}

/* Nothing but a comment may follow a statement's numbers. */
static lk_status expect_end(scene_parser *parser, const char *name, size_t line, const char *p, const char *end,
                            const char *keyword)
{
    const char *rest = lk__skip_spaces(p, end);
    if (rest >= end || *rest == '#') return LK_OK;
    char token[32];
    lk__quote_token(rest, end, token, sizeof token);
    return fail_at(parser, name, line, LK_ERR_PARSE, "unexpected '%s' after the numbers of '%s'", token, keyword);
}

static const float white[4] = {1.0f, 1.0f, 1.0f, 1.0f};

/* `v x y z [w]` or `v x y z r g b` (as in io_obj.c: characters glued to
 * the last number are ignored, a separate word is refused). */
static lk_status read_position(scene_parser *parser, const char *p, const char *end, size_t line)
{
    double values[7];
    int count = parse_numbers(&p, end, values, 7);
    if (count < 3)
        return fail_at(parser, parser->name, line, LK_ERR_PARSE, "expected 3 coordinates after 'v', got %d", count);
    const char *rest = lk__skip_spaces(p, end);
    if (rest != p && rest < end && *rest != '#') return expect_end(parser, parser->name, line, p, end, "v");
    lk_status status = check_finite(parser, parser->name, line, values, count >= 6 ? 6 : 3);
    float position[3] = {(float)values[0], (float)values[1], (float)values[2]};
    if (status == LK_OK) status = append(parser, &parser->positions, position, sizeof position);
    if (status == LK_OK && count >= 6 && parser->colors.size == 0) {
        /* The first coloured vertex: the earlier ones are white. */
        for (size_t i = 0; status == LK_OK && i < parser->position_count; i++)
            status = append(parser, &parser->colors, white, sizeof white);
    }
    if (status == LK_OK && count >= 6) {
        float color[4] = {(float)values[3], (float)values[4], (float)values[5], 1.0f};
        status = append(parser, &parser->colors, color, sizeof color);
    } else if (status == LK_OK && parser->colors.size) {
        status = append(parser, &parser->colors, white, sizeof white);
    }
    if (status == LK_OK) parser->position_count++;
    return status;
}

static lk_status read_texcoord(scene_parser *parser, const char *p, const char *end, size_t line)
{
    double values[3] = {0, 0, 0};
    if (parse_numbers(&p, end, values, 3) < 1)
        return fail_at(parser, parser->name, line, LK_ERR_PARSE, "expected texture coordinates 'u [v [w]]' after 'vt'");
    lk_status status = check_finite(parser, parser->name, line, values, 2);
    float texcoord[2] = {(float)values[0], (float)values[1]};
    if (status == LK_OK) status = append(parser, &parser->texcoords, texcoord, sizeof texcoord);
    if (status == LK_OK) parser->texcoord_count++;
    return status;
}

static lk_status read_normal(scene_parser *parser, const char *p, const char *end, size_t line)
{
    double values[3];
    int count = parse_numbers(&p, end, values, 3);
    if (count < 3)
        return fail_at(parser, parser->name, line, LK_ERR_PARSE, "expected 3 numbers after 'vn', got %d", count);
    lk_status status = check_finite(parser, parser->name, line, values, 3);
    float normal[3] = {(float)values[0], (float)values[1], (float)values[2]};
    if (status == LK_OK) status = append(parser, &parser->normals, normal, sizeof normal);
    if (status == LK_OK) parser->normal_count++;
    return status;
}

static lk_status resolve_index(scene_parser *parser, size_t line, long long value, size_t defined, max_reference *max,
                               const char *what, uint32_t *out)
{
    if (value == 0)
        return fail_at(parser, parser->name, line, LK_ERR_RANGE, "%s index 0 is invalid (OBJ indices start at 1)",
                       what);
    if (value < 0) {
        if ((unsigned long long)-(value + 1) >= defined)
            return fail_at(parser, parser->name, line, LK_ERR_RANGE, "%s index %lld out of range (%zu defined so far)",
                           what, value, defined);
        *out = (uint32_t)(defined - (size_t) - (value + 1));
        return LK_OK;
    }
    if ((unsigned long long)value > LK_MAX_ELEMENTS)
        return fail_at(parser, parser->name, line, LK_ERR_RANGE, "%s index %lld out of range", what, value);
    *out = (uint32_t)value;
    if (*out > max->index) *max = (max_reference){*out, line};
    return LK_OK;
}

/* `v`, `v/vt`, `v//vn` or `v/vt/vn`. */
static lk_status read_corner(scene_parser *parser, const char **cursor, const char *end, size_t line, corner *out)
{
    const char *p = *cursor;
    long long value;
    lk_status status;
    out->vt = out->vn = 0;
    if (!lk__parse_int64(&p, end, &value)) goto bad;
    status = resolve_index(parser, line, value, parser->position_count, &parser->max_v, "vertex", &out->v);
    if (status != LK_OK) return status;
    if (p < end && *p == '/') {
        p++;
        if (p < end && *p != '/') {
            if (!lk__parse_int64(&p, end, &value)) goto bad;
            status = resolve_index(parser, line, value, parser->texcoord_count, &parser->max_vt, "texture coordinate",
                                   &out->vt);
            if (status != LK_OK) return status;
        }
        if (p < end && *p == '/') {
            p++;
            if (!lk__parse_int64(&p, end, &value)) goto bad;
            status = resolve_index(parser, line, value, parser->normal_count, &parser->max_vn, "normal", &out->vn);
            if (status != LK_OK) return status;
        }
    }
    if (p < end && !lk__is_space(*p) && *p != '#') goto bad;
    *cursor = p;
    return LK_OK;
bad:;
    char token[32];
    lk__quote_token(*cursor, end, token, sizeof token);
    return fail_at(parser, parser->name, line, LK_ERR_PARSE,
                   "expected a face corner like 1, 1/2, 1//3 or 1/2/3, got '%s'", token);
}

static lk_status read_face(scene_parser *parser, const char *p, const char *end, size_t line)
{
    parser->polygon.size = 0;
    for (;;) {
        p = lk__skip_spaces(p, end);
        if (p >= end || *p == '#') break;
        corner c;
        lk_status status = read_corner(parser, &p, end, line, &c);
        if (status == LK_OK) status = append(parser, &parser->polygon, &c, sizeof c);
        if (status != LK_OK) return status;
    }
    size_t count = parser->polygon.size / sizeof(corner);
    if (count < 3)
        return fail_at(parser, parser->name, line, LK_ERR_PARSE,
                       "expected at least 3 vertex indices after 'f', got %zu", count);
    if (parser->group == UINT32_MAX) {
        bool added;
        lk_status status = name_table_add(parser, &parser->groups, no_material_group, 1, &parser->group, &added);
        if (status != LK_OK) return status;
    }
    const corner *polygon = (const corner *)parser->polygon.data;
    for (size_t k = 1; k + 1 < count; k++) {
        corner triangle[3] = {polygon[0], polygon[k], polygon[k + 1]};
        lk_status status = append(parser, &parser->corners, triangle, sizeof triangle);
        if (status == LK_OK) status = append(parser, &parser->triangle_groups, &parser->group, sizeof parser->group);
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

static lk_status read_usemtl(scene_parser *parser, const char *p, const char *end)
{
    const char *name;
    size_t length;
    rest_of_line(p, end, &name, &length);
    bool added;
    return name_table_add(parser, &parser->groups, name, length, &parser->group, &added);
}

static lk_status read_mtllib(scene_parser *parser, const char *p, const char *end, size_t line)
{
    const char *text;
    size_t length;
    rest_of_line(p, end, &text, &length);
    if (length == 0) return LK_OK;
    lk_status status = append(parser, &parser->mtllibs, &line, sizeof line);
    if (status == LK_OK) status = append(parser, &parser->mtllibs, text, length);
    if (status == LK_OK) status = append(parser, &parser->mtllibs, "", 1);
    return status;
}

static lk_status parse_obj_line(scene_parser *parser, const char *p, const char *end, size_t line)
{
    p = lk__skip_spaces(p, end);
    if (p >= end || *p == '#') return LK_OK;
    const char *keyword = p;
    while (p < end && !lk__is_space(*p)) p++;
    size_t length = (size_t)(p - keyword);
    if (length == 1 && keyword[0] == 'v') return read_position(parser, p, end, line);
    if (length == 1 && keyword[0] == 'f') return read_face(parser, p, end, line);
    if (length == 2 && memcmp(keyword, "vt", 2) == 0) return read_texcoord(parser, p, end, line);
    if (length == 2 && memcmp(keyword, "vn", 2) == 0) return read_normal(parser, p, end, line);
    if (length == 6 && memcmp(keyword, "usemtl", 6) == 0) return read_usemtl(parser, p, end);
    if (length == 6 && memcmp(keyword, "mtllib", 6) == 0) return read_mtllib(parser, p, end, line);
    if (length == 1 && keyword[0] == 'o' && !parser->object_name) {
        const char *name;
        size_t name_length;
        rest_of_line(p, end, &name, &name_length);
        if (name_length) {
            if (!(parser->object_name = malloc(name_length + 1))) return out_of_memory(parser);
            memcpy(parser->object_name, name, name_length);
            parser->object_name[name_length] = '\0';
        }
    }
    return LK_OK; /* g s l p vp curves ...: not kept */
}

static lk_status check_references(scene_parser *parser)
{
    const struct {
        const max_reference *max;
        size_t count;
        const char *what;
    } kinds[] = {{&parser->max_v, parser->position_count, "vertex"},
                 {&parser->max_vt, parser->texcoord_count, "texture coordinate"},
                 {&parser->max_vn, parser->normal_count, "normal"}};
    for (size_t k = 0; k < 3; k++)
        if (kinds[k].max->index > kinds[k].count)
            return fail_at(parser, parser->name, kinds[k].max->line, LK_ERR_RANGE,
                           "%s index %u out of range (the file defines %zu)", kinds[k].what, kinds[k].max->index,
                           kinds[k].count);
    return LK_OK;
}

/* ---- .mtl ---------------------------------------------------------------- */

/* `Kd r [g [b]]` (g and b default to r); "spectral" and "xyz" forms are
 * noted and skipped. false in *read when skipped. */
static lk_status read_color(scene_parser *parser, const char *p, const char *end, size_t line, const char *keyword,
                            double color[3], bool *read)
{
    *read = false;
    const char *word = lk__skip_spaces(p, end);
    if (end - word >= 3 &&
        (lk__word_equals(word, 3, "xyz") || (end - word >= 8 && lk__word_equals(word, 8, "spectral")))) {
        note(parser, "%s:%zu: %s given as spectral or xyz: ignored", parser->mtl_name, line, keyword);
        return LK_OK;
    }
    double values[4]; /* a fourth (alpha) number, as some exporters write, is ignored */
    int count = parse_numbers(&p, end, values, 4);
    if (count < 1)
        return fail_at(parser, parser->mtl_name, line, LK_ERR_PARSE, "expected a colour 'r [g b]' after '%s'", keyword);
    lk_status status = expect_end(parser, parser->mtl_name, line, p, end, keyword);
    if (status == LK_OK) status = check_finite(parser, parser->mtl_name, line, values, count < 3 ? count : 3);
    if (status != LK_OK) return status;
    for (int c = 0; c < 3; c++) color[c] = values[c < count ? c : 0];
    *read = true;
    return LK_OK;
}

static lk_status read_scalar(scene_parser *parser, const char *p, const char *end, size_t line, const char *keyword,
                             double *value)
{
    if (!lk__parse_double(&p, end, value))
        return fail_at(parser, parser->mtl_name, line, LK_ERR_PARSE, "expected a number after '%s'", keyword);
    lk_status status = expect_end(parser, parser->mtl_name, line, p, end, keyword);
    return status == LK_OK ? check_finite(parser, parser->mtl_name, line, value, 1) : status;
}

/* Options of a texture statement (-o u v w, -s u v w, -bm 1, ...) and the
 * file name after them, which may hold spaces. */
static lk_status read_map(scene_parser *parser, const char *p, const char *end, size_t line, const char *keyword,
                          const char *mtl_folder, size_t *out)
{
    static const struct {
        const char *name;
        int arguments; /* -1: up to 3 numbers */
    } options[] = {{"blendu", 1}, {"blendv", 1}, {"bm", 1}, {"boost", 1}, {"cc", 1},     {"clamp", 1}, {"imfchan", 1},
                   {"mm", 2},     {"o", -1},     {"s", -1}, {"t", -1},    {"texres", 1}, {"type", 1}};
    for (;;) {
        p = lk__skip_spaces(p, end);
        if (p >= end || *p != '-') break;
        const char *option = ++p;
        while (p < end && !lk__is_space(*p)) p++;
        size_t length = (size_t)(p - option);
        int arguments = 0;
        for (size_t i = 0; i < sizeof options / sizeof options[0]; i++)
            if (lk__word_equals(option, length, options[i].name)) arguments = options[i].arguments;
        if (arguments == 0) {
            note(parser, "%s:%zu: unknown option '-%.*s' of %s ignored", parser->mtl_name, line,
                 (int)(length < 24 ? length : 24), option, keyword);
            continue;
        }
        if (arguments < 0) {
            double value;
            int count = 0;
            while (count < 3 && lk__parse_double(&p, end, &value)) count++;
            if (count == 0)
                return fail_at(parser, parser->mtl_name, line, LK_ERR_PARSE, "option '-%.*s' of '%s' needs a number",
                               (int)length, option, keyword);
            note(parser, "%s:%zu: %s option -%.*s (texture offset, scale or turbulence) ignored", parser->mtl_name,
                 line, keyword, (int)length, option);
            continue;
        }
        for (int a = 0; a < arguments; a++) {
            p = lk__skip_spaces(p, end);
            if (p >= end || *p == '#')
                return fail_at(parser, parser->mtl_name, line, LK_ERR_PARSE, "option '-%.*s' of '%s' needs a value",
                               (int)length, option, keyword);
            while (p < end && !lk__is_space(*p)) p++;
        }
    }
    const char *file;
    size_t length;
    rest_of_line(p, end, &file, &length);
    if (length == 0)
        return fail_at(parser, parser->mtl_name, line, LK_ERR_PARSE, "expected a file name after '%s'", keyword);
    /* Relative to the .obj's folder: the .mtl's folder, then the name with
     * Windows separators made '/' and leading "./" dropped. */
    size_t offset = parser->map_paths.size;
    lk_status status = LK_OK;
    if (*mtl_folder) status = append(parser, &parser->map_paths, mtl_folder, strlen(mtl_folder));
    for (;;) {
        if (length >= 2 && file[0] == '.' && (file[1] == '/' || file[1] == '\\')) {
            file += 2;
            length -= 2;
        } else {
            break;
        }
    }
    size_t name_start = parser->map_paths.size;
    if (status == LK_OK) status = append(parser, &parser->map_paths, file, length);
    if (status == LK_OK) status = append(parser, &parser->map_paths, "", 1);
    if (status != LK_OK) return status;
    for (char *c = (char *)parser->map_paths.data + name_start; *c; c++)
        if (*c == '\\') *c = '/';
    *out = offset + 1;
    return LK_OK;
}

static lk_status parse_mtl_line(scene_parser *parser, const char *p, const char *end, size_t line)
{
    p = lk__skip_spaces(p, end);
    if (p >= end || *p == '#') return LK_OK;
    const char *keyword = p;
    while (p < end && !lk__is_space(*p)) p++;
    size_t length = (size_t)(p - keyword);
    char word[16] = "";
    if (length < sizeof word) {
        memcpy(word, keyword, length);
        word[length] = '\0';
    }
    if (lk__word_equals(keyword, length, "newmtl")) {
        const char *name;
        size_t name_length;
        rest_of_line(p, end, &name, &name_length);
        uint32_t index;
        bool added;
        lk_status status = name_table_add(parser, &parser->materials, name, name_length, &index, &added);
        if (status != LK_OK) return status;
        if (!added) {
            /* Its statements are checked, then forgotten. */
            note(parser, "%s:%zu: material \"%.*s\" defined again: the first definition is used", parser->mtl_name,
                 line, (int)(name_length < 64 ? name_length : 64), name);
            parser->mtl_current = -2;
            parser->mtl_repeated = (mtl_material){.diffuse = {1, 1, 1}, .alpha = 1};
            return LK_OK;
        }
        mtl_material material = {.diffuse = {1, 1, 1}, .alpha = 1};
        parser->mtl_current = index;
        return append(parser, &parser->mtl_materials, &material, sizeof material);
    }
    if (parser->mtl_current == -1) {
        note(parser, "%s:%zu: '%s' before any newmtl: ignored", parser->mtl_name, line, word);
        return LK_OK;
    }
    mtl_material *material = parser->mtl_current == -2
                                 ? &parser->mtl_repeated
                                 : (mtl_material *)parser->mtl_materials.data + parser->mtl_current;
    bool read;
    double value;
    lk_status status = LK_OK;
    if (lk__word_equals(keyword, length, "Kd")) return read_color(parser, p, end, line, "Kd", material->diffuse, &read);
    if (lk__word_equals(keyword, length, "Ks")) {
        status = read_color(parser, p, end, line, "Ks", material->specular, &read);
        if (read) material->has_specular = true;
        return status;
    }
    if (lk__word_equals(keyword, length, "Ke"))
        return read_color(parser, p, end, line, "Ke", material->emissive, &read);
    if (lk__word_equals(keyword, length, "d")) {
        const char *q = lk__skip_spaces(p, end);
        if (end - q >= 5 && lk__word_equals(q, 5, "-halo")) p = q + 5;
        status = read_scalar(parser, p, end, line, "d", &value);
        if (status == LK_OK) material->alpha = value;
        return status;
    }
    if (lk__word_equals(keyword, length, "Tr")) {
        status = read_scalar(parser, p, end, line, "Tr", &value);
        if (status == LK_OK) material->alpha = 1.0 - value;
        return status;
    }
    if (lk__word_equals(keyword, length, "Ns")) {
        status = read_scalar(parser, p, end, line, "Ns", &material->shininess);
        material->has_shininess = status == LK_OK;
        return status;
    }
    if (lk__word_equals(keyword, length, "Pr")) {
        status = read_scalar(parser, p, end, line, "Pr", &material->roughness);
        material->has_roughness = status == LK_OK;
        return status;
    }
    if (lk__word_equals(keyword, length, "Pm")) {
        status = read_scalar(parser, p, end, line, "Pm", &material->metallic);
        material->has_metallic = status == LK_OK;
        return status;
    }
    if (lk__word_equals(keyword, length, "map_Kd"))
        return read_map(parser, p, end, line, "map_Kd", parser->mtl_folder, &material->color_map);
    if (lk__word_equals(keyword, length, "map_Bump") || lk__word_equals(keyword, length, "bump") ||
        lk__word_equals(keyword, length, "norm"))
        return read_map(parser, p, end, line, word[0] ? word : "bump", parser->mtl_folder, &material->normal_map);
    if (lk__word_equals(keyword, length, "map_d")) {
        note(parser, "%s:%zu: map_d (an alpha texture) ignored: glTF takes alpha from the base colour texture",
             parser->mtl_name, line);
        return LK_OK;
    }
    if ((length > 4 && lk__word_equals(keyword, 4, "map_")) || lk__word_equals(keyword, length, "disp") ||
        lk__word_equals(keyword, length, "decal") || lk__word_equals(keyword, length, "refl"))
        note(parser, "%s:%zu: %.*s ignored (lodkit keeps map_Kd and map_Bump)", parser->mtl_name, line,
             (int)(length < 24 ? length : 24), keyword);
    return LK_OK; /* Ka Ni illum Tf sharpness ...: no glTF counterpart kept */
}

/* Parses one .mtl's text; `folder` is its folder relative to the .obj's
 * ("" or ending in '/'). */
static lk_status read_mtl_text(scene_parser *parser, const char *mtl_name, const char *folder, const char *data,
                               size_t size)
{
    parser->mtl_name = mtl_name;
    parser->mtl_folder = folder;
    parser->mtl_current = -1;
    lk_status status = for_each_line(parser, mtl_name, data, size, parse_mtl_line);
    parser->mtl_folder = "";
    return status;
}

/* A file below the .obj's folder, whole, charged to the budget; on
 * failure a reason (no error set). With `seen`, a file already in it (by
 * device and inode: "a.mtl" and "b/./a.mtl" are one file) is not read
 * again: *out stays NULL. */
static lk_status read_side_file(scene_parser *parser, const char *relative, name_table *seen, unsigned char **out,
                                size_t *size, char *reason, size_t reason_size)
{
    *out = NULL;
    *size = 0;
    int fd;
    struct stat info;
    lk_error opened = {0};
    if (lk__open_input(parser->directory, relative, &fd, &info, &opened) != LK_OK) {
        /* lk__open_input's message is "RELATIVE: reason". */
        size_t prefix = strlen(relative) + 2;
        snprintf(reason, reason_size, "%.150s",
                 strlen(opened.message) >= prefix ? opened.message + prefix : opened.message);
        return LK_ERR_IO;
    }
    lk_status status = LK_OK;
    size_t length = (size_t)info.st_size;
    if (seen) {
        char key[48];
        int key_length =
            snprintf(key, sizeof key, "%llx:%llx", (unsigned long long)info.st_dev, (unsigned long long)info.st_ino);
        uint32_t index;
        bool added;
        status = name_table_add(parser, seen, key, (size_t)key_length, &index, &added);
        if (status != LK_OK || !added) {
            close(fd);
            return status;
        }
    }
    if ((unsigned long long)info.st_size > lk__budget_room(parser->budget)) {
        snprintf(reason, reason_size, "%llu bytes do not fit the memory budget of %zu bytes",
                 (unsigned long long)info.st_size, parser->budget->limit);
        status = LK_ERR_LIMIT;
    } else if (!(*out = lk__malloc_array(length ? length : 1, 1))) {
        status = out_of_memory(parser);
        reason[0] = '\0';
    } else if (lk__read_prefix(fd, &info, relative, length, *out, &opened) != LK_OK) {
        snprintf(reason, reason_size, "%.150s", opened.message);
        status = LK_ERR_IO;
    } else {
        lk__budget_charge(parser->budget, length, 1); /* the room was checked */
        *size = length;
    }
    close(fd);
    if (status != LK_OK) {
        free(*out);
        *out = NULL;
    }
    return status;
}

/* Reads the .mtl named `relative` (once per file); a missing or unreadable
 * one is a note. */
static lk_status load_mtl(scene_parser *parser, const char *relative, size_t line)
{
    uint32_t index;
    bool added;
    lk_status status = name_table_add(parser, &parser->mtl_files, relative, strlen(relative), &index, &added);
    if (status != LK_OK || !added) return status;
    /* The folder of the .mtl, for the textures it names, and its name as
     * messages give it (next to the .obj). */
    const char *slash = strrchr(relative, '/');
    size_t folder_length = slash ? (size_t)(slash - relative) + 1 : 0;
    const char *directory = parser->directory ? parser->directory : "";
    size_t shown_size = strlen(directory) + strlen(relative) + 2;
    char *buffer = malloc(folder_length + 1 + shown_size);
    if (!buffer) return out_of_memory(parser);
    char *folder = buffer, *shown = buffer + folder_length + 1;
    memcpy(folder, relative, folder_length);
    folder[folder_length] = '\0';
    if (!*directory || strcmp(directory, ".") == 0)
        snprintf(shown, shown_size, "%s", relative);
    else
        snprintf(shown, shown_size, "%s%s%s", directory, directory[strlen(directory) - 1] == '/' ? "" : "/", relative);
    if (parser->memory_mtl) {
        /* One text stands for every .mtl: read once. */
        status = read_mtl_text(parser, shown, folder, parser->memory_mtl, parser->memory_mtl_size);
        parser->memory_mtl = NULL;
        parser->memory_mtl_read = true;
    } else if (parser->memory_mtl_read) {
        /* the fuzz target's one .mtl text was read */
    } else if (!parser->directory) {
        note(parser, "%s:%zu: mtllib %s not read (reading from memory: no folder to find it in)", parser->name, line,
             relative);
    } else {
        unsigned char *data;
        size_t size;
        char reason[200];
        status = read_side_file(parser, relative, &parser->mtl_inodes, &data, &size, reason, sizeof reason);
        if (status == LK_OK && data) {
            status = read_mtl_text(parser, shown, folder, (const char *)data, size);
            free(data);
            lk__budget_release(parser->budget, size, 1);
        } else if (status != LK_OK && status != LK_ERR_NOMEM) {
            note(parser, "%s:%zu: mtllib %s not read (%s): its materials get default values", parser->name, line,
                 relative, reason);
            status = LK_OK;
        }
    }
    free(buffer);
    return status;
}

static bool side_file_exists(const scene_parser *parser, const char *relative)
{
    int fd;
    lk_error ignored = {0};
    if (!parser->directory || lk__open_input(parser->directory, relative, &fd, NULL, &ignored) != LK_OK) return false;
    close(fd);
    return true;
}

/* Every mtllib statement: a list of file names, or one name with spaces
 * when a file of that whole name exists. Windows separators become '/'. */
static lk_status load_mtllibs(scene_parser *parser)
{
    for (size_t at = 0; at < parser->mtllibs.size;) {
        size_t line;
        memcpy(&line, parser->mtllibs.data + at, sizeof line);
        char *text = (char *)parser->mtllibs.data + at + sizeof line;
        size_t length = strlen(text);
        at += sizeof line + length + 1;
        for (char *c = text; *c; c++)
            if (*c == '\\') *c = '/';
        while (text[0] == '.' && text[1] == '/') text += 2;
        lk_status status = LK_OK;
        if (!strpbrk(text, " \t") || side_file_exists(parser, text)) {
            status = load_mtl(parser, text, line);
        } else {
            /* Split in place: the names end at the spaces made NULs. */
            for (char *name = text; *name && status == LK_OK;) {
                size_t name_length = strcspn(name, " \t\r\v\f");
                char *next = name + name_length;
                if (*next) *next++ = '\0';
                while (name[0] == '.' && name[1] == '/') name += 2;
                if (*name) status = load_mtl(parser, name, line);
                name = next;
                while (lk__is_space(*name)) name++;
            }
        }
        if (status != LK_OK) return status;
    }
    return LK_OK;
}

/* ---- the scene ----------------------------------------------------------- */

static const char *sniff_image_type(const unsigned char *data, size_t size)
{
    if (size >= 8 && memcmp(data, "\x89PNG\r\n\x1a\n", 8) == 0) return "image/png";
    if (size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF) return "image/jpeg";
    return NULL;
}

static char *copy_string(const char *text)
{
    size_t length = strlen(text);
    char *copy = malloc(length + 1);
    if (copy) memcpy(copy, text, length + 1);
    return copy;
}

/* Whether text is well-formed UTF-8 (no overlong forms, surrogates or
 * code points above U+10FFFF). */
static bool is_utf8(const unsigned char *text)
{
    while (*text) {
        unsigned char c = *text;
        size_t extra = c < 0x80                 ? 0
                       : c >= 0xC2 && c <= 0xDF ? 1
                       : c >= 0xE0 && c <= 0xEF ? 2
                       : c >= 0xF0 && c <= 0xF4 ? 3
                                                : 9;
        if (extra == 9) return false;
        for (size_t k = 1; k <= extra; k++)
            if ((text[k] & 0xC0) != 0x80) return false;
        if ((c == 0xE0 && text[1] < 0xA0) || (c == 0xED && text[1] >= 0xA0) || (c == 0xF0 && text[1] < 0x90) ||
            (c == 0xF4 && text[1] >= 0x90))
            return false;
        text += extra + 1;
    }
    return true;
}

/* A copy of a name from the files as UTF-8, which glTF's JSON must be:
 * names that are not are taken as Latin-1, as older Windows exporters
 * wrote them ("Terraind\xE6k"), with a note. */
static char *utf8_name(scene_parser *parser, const char *text)
{
    if (is_utf8((const unsigned char *)text)) return copy_string(text);
    note(parser, "names that are not UTF-8 were read as Latin-1");
    size_t length = strlen(text);
    char *copy = malloc(2 * length + 1), *out = copy;
    for (const unsigned char *c = (const unsigned char *)text; copy && *c; c++) {
        if (*c < 0x80) {
            *out++ = (char)*c;
        } else {
            *out++ = (char)(0xC0 | (*c >> 6));
            *out++ = (char)(0x80 | (*c & 0x3F));
        }
    }
    if (copy) *out = '\0';
    return copy;
}

/* The texture (index into scene->textures, one per image) of a map path,
 * reading its image the first time; -1 with a note when it cannot be read
 * or is not PNG or JPEG. */
static lk_status texture_of(scene_parser *parser, const char *path, const char *material, int32_t *texture)
{
    lk_scene *scene = parser->scene;
    uint32_t index;
    bool added;
    *texture = -1;
    lk_status status = name_table_add(parser, &parser->image_paths, path, strlen(path), &index, &added);
    if (status != LK_OK) return status;
    if (!added) {
        *texture = parser->image_of_path[index];
        return LK_OK;
    }
    parser->image_of_path[index] = -1;
    if (!parser->directory) {
        note(parser, "material \"%s\": texture %s not read (reading from memory: no folder to find it in)", material,
             path);
        return LK_OK;
    }
    unsigned char *data;
    size_t size;
    char reason[200];
    status = read_side_file(parser, path, NULL, &data, &size, reason, sizeof reason);
    if (status == LK_ERR_NOMEM) return status;
    if (status != LK_OK) {
        note(parser, "material \"%s\": texture %s not read (%s)", material, path, reason);
        return LK_OK;
    }
    const char *type = sniff_image_type(data, size);
    if (!type) {
        note(parser, "material \"%s\": texture %s dropped (not a PNG or JPEG image, which glTF needs)", material, path);
        free(data);
        lk__budget_release(parser->budget, size, 1);
        return LK_OK;
    }
    lk_scene_image *image = &scene->images[scene->image_count];
    lk_scene_texture *slot = &scene->textures[scene->texture_count];
    const char *base = strrchr(path, '/');
    image->data = data;
    image->size = size;
    if (!(image->mime_type = copy_string(type)) || !(image->name = utf8_name(parser, base ? base + 1 : path))) {
        scene->image_count++; /* freed with the scene */
        return out_of_memory(parser);
    }
    slot->image = (int32_t)scene->image_count++;
    slot->sampler = -1;
    char json[48];
    snprintf(json, sizeof json, "{\"source\":%d}", slot->image);
    if (!(slot->json = copy_string(json))) return out_of_memory(parser);
    *texture = (int32_t)scene->texture_count++;
    parser->image_of_path[index] = *texture;
    return LK_OK;
}

static double clamp01(double value) { return value < 0 ? 0 : value > 1 ? 1 : value; }

/* glTF's roughness from Phong's specular exponent Ns (0..1000) and colour
 * Ks: no specular colour means no highlight (roughness 1); otherwise
 * 1 - sqrt(Ns / 1000), so that Ns 1000 is a mirror-like 0, Ns 250 gives
 * 0.5 and the exponents around 10..100 common in exported files land in
 * 0.9..0.7. An estimate: Phong and glTF's BRDF do not map exactly. */
static double roughness_of(const mtl_material *material)
{
    if (material->has_roughness) return clamp01(material->roughness);
    double specular = 0;
    for (int c = 0; c < 3; c++)
        if (material->specular[c] > specular) specular = material->specular[c];
    if (!material->has_shininess || (material->has_specular && specular <= 0)) return 1.0;
    return 1.0 - sqrt(clamp01(material->shininess / 1000.0));
}

static cJSON *add_factor(cJSON *object, const char *key, const double *values, int count)
{
    cJSON *array = cJSON_AddArrayToObject(object, key);
    for (int i = 0; array && i < count; i++) {
        cJSON *number = cJSON_CreateNumber(values[i]);
        if (!number) return NULL;
        cJSON_AddItemToArray(array, number);
    }
    return array;
}

static cJSON *texture_reference(cJSON *object, const char *key, int32_t texture)
{
    cJSON *reference = cJSON_AddObjectToObject(object, key);
    return reference && cJSON_AddNumberToObject(reference, "index", texture) ? reference : NULL;
}

/* The scene material of usemtl `name`: the .mtl's values as glTF. */
static lk_status make_material(scene_parser *parser, const char *name, lk_scene_material *out)
{
    static const mtl_material defaults = {.diffuse = {1, 1, 1}, .alpha = 1};
    int64_t index = name_table_find(&parser->materials, name);
    const mtl_material *material = index >= 0 ? (const mtl_material *)parser->mtl_materials.data + index : &defaults;
    if (index < 0 && parser->mtllibs.size)
        note(parser, "material \"%.100s\" is used but no .mtl read defines it: default values", name);
    out->base_color_texture = -1;
    if (!(out->name = utf8_name(parser, name))) return out_of_memory(parser);
    double base[4];
    for (int c = 0; c < 3; c++) base[c] = clamp01(material->diffuse[c]);
    base[3] = clamp01(material->alpha);
    for (int c = 0; c < 4; c++) out->base_color[c] = (float)base[c];
    int32_t color_texture = -1, normal_texture = -1;
    const char *paths = (const char *)parser->map_paths.data;
    lk_status status = LK_OK;
    if (material->color_map) status = texture_of(parser, paths + material->color_map - 1, name, &color_texture);
    if (status == LK_OK && material->normal_map)
        status = texture_of(parser, paths + material->normal_map - 1, name, &normal_texture);
    if (status != LK_OK) return status;
    out->base_color_texture = color_texture;

    cJSON *json = cJSON_CreateObject(), *pbr = NULL;
    bool ok =
        json && (!*name || cJSON_AddStringToObject(json, "name", out->name)) &&
        (pbr = cJSON_AddObjectToObject(json, "pbrMetallicRoughness")) && add_factor(pbr, "baseColorFactor", base, 4) &&
        (color_texture < 0 || texture_reference(pbr, "baseColorTexture", color_texture)) &&
        cJSON_AddNumberToObject(pbr, "metallicFactor", material->has_metallic ? clamp01(material->metallic) : 0.0) &&
        cJSON_AddNumberToObject(pbr, "roughnessFactor", roughness_of(material)) &&
        (normal_texture < 0 || texture_reference(json, "normalTexture", normal_texture));
    double emissive[3];
    bool glows = false;
    for (int c = 0; c < 3; c++) glows |= (emissive[c] = clamp01(material->emissive[c])) > 0;
    if (ok && glows) ok = add_factor(json, "emissiveFactor", emissive, 3) != NULL;
    if (ok && base[3] < 1) ok = cJSON_AddStringToObject(json, "alphaMode", "BLEND") != NULL;
    if (ok) out->json = cJSON_PrintUnformatted(json);
    cJSON_Delete(json);
    if (!ok || !out->json) return out_of_memory(parser);
    return lk__budget_charge(parser->budget, strlen(out->json) + strlen(out->name) + 2, 1) ? LK_OK
                                                                                           : over_budget(parser);
}

/* The vertex a position got first in the primitive being built (stamp:
 * which primitive, so the table is cleared by moving on), with the vt and
 * vn it came with; most corners reuse it. One per `v`, made once. */
typedef struct first_use {
    uint32_t stamp, vertex, vt, vn;
} first_use;

/* Open addressing from a corner to its vertex, for the corners whose vt or
 * vn differ from their position's first use (texture seams, hard edges). */
typedef struct vertex_slot {
    corner key; /* key.v == 0: empty */
    uint32_t vertex;
} vertex_slot;

typedef struct vertex_map {
    vertex_slot *slots;
    size_t capacity, count;
} vertex_map;

static size_t corner_hash(corner c) { return (size_t)lk__mix64(((uint64_t)c.v << 32 | c.vt) ^ lk__mix64(c.vn)); }

static vertex_slot *vertex_map_find(const vertex_map *map, corner c)
{
    size_t at = corner_hash(c) & (map->capacity - 1);
    while (map->slots[at].key.v &&
           (map->slots[at].key.v != c.v || map->slots[at].key.vt != c.vt || map->slots[at].key.vn != c.vn))
        at = (at + 1) & (map->capacity - 1);
    return &map->slots[at];
}

/* Doubles the table, charged before it is made. */
static lk_status vertex_map_grow(scene_parser *parser, vertex_map *map)
{
    size_t capacity = map->capacity ? 2 * map->capacity : 64;
    if (!lk__budget_charge(parser->budget, capacity, sizeof(vertex_slot))) return over_budget(parser);
    vertex_map grown = {lk__calloc_array(capacity, sizeof(vertex_slot)), capacity, map->count};
    if (!grown.slots) {
        lk__budget_release(parser->budget, capacity, sizeof(vertex_slot));
        return out_of_memory(parser);
    }
    for (size_t i = 0; i < map->capacity; i++)
        if (map->slots[i].key.v) *vertex_map_find(&grown, map->slots[i].key) = map->slots[i];
    free(map->slots);
    lk__budget_release(parser->budget, map->capacity, sizeof(vertex_slot));
    *map = grown;
    return LK_OK;
}

/* The primitive of the `count` triangles listed in `triangles`; `stamp`
 * is unique to it (first_use entries of other primitives do not count). */
static lk_status build_primitive(scene_parser *parser, const uint32_t *triangles, size_t count, first_use *first,
                                 uint32_t stamp, lk_scene_primitive *primitive)
{
    const corner *corners = (const corner *)parser->corners.data;
    size_t corner_count = 3 * count;
    vertex_map conflicts = {0};
    lk__buffer sources = {0}; /* corner per vertex */
    uint32_t *indices = NULL;
    lk_status status = LK_OK;
    bool index_charged = lk__budget_charge(parser->budget, corner_count, sizeof(uint32_t));
    if (!index_charged) status = over_budget(parser);
    if (status == LK_OK && !(indices = lk__malloc_array(corner_count, sizeof *indices))) status = out_of_memory(parser);
    bool with_texcoords = false, with_normals = false;
    for (size_t i = 0; status == LK_OK && i < corner_count; i++) {
        corner c = corners[3 * (size_t)triangles[i / 3] + i % 3];
        first_use *use = &first[c.v - 1];
        if (use->stamp == stamp && use->vt == c.vt && use->vn == c.vn) {
            indices[i] = use->vertex;
            continue;
        }
        uint32_t vertex = (uint32_t)(sources.size / sizeof c);
        if (use->stamp == stamp) {
            /* Another vt / vn for this position: the map keeps those. */
            if (2 * (conflicts.count + 1) > conflicts.capacity &&
                (status = vertex_map_grow(parser, &conflicts)) != LK_OK)
                break;
            vertex_slot *slot = vertex_map_find(&conflicts, c);
            if (slot->key.v) {
                indices[i] = slot->vertex;
                continue;
            }
            *slot = (vertex_slot){c, vertex};
            conflicts.count++;
        } else {
            *use = (first_use){stamp, vertex, c.vt, c.vn};
        }
        status = append(parser, &sources, &c, sizeof c);
        with_texcoords |= c.vt != 0;
        with_normals |= c.vn != 0;
        indices[i] = vertex;
    }
    free(conflicts.slots);
    lk__budget_release(parser->budget, conflicts.capacity, sizeof(vertex_slot));
    size_t vertex_count = sources.size / sizeof(corner);
    bool with_colors = parser->colors.size != 0;
    unsigned flags = (with_normals ? LK_ATTR_NORMALS : 0u) | (with_texcoords ? LK_ATTR_TEXCOORDS : 0u) |
                     (with_colors ? LK_ATTR_COLORS : 0u);
    if (status == LK_OK && !lk__budget_charge_mesh(parser->budget, vertex_count, 0, flags))
        status = over_budget(parser);
    if (status == LK_OK) status = lk_mesh_alloc(&primitive->mesh, vertex_count, 0, flags, parser->error);
    if (status == LK_OK) {
        lk_mesh *mesh = &primitive->mesh;
        free(mesh->indices);
        mesh->indices = indices; /* stays charged, as the mesh does */
        mesh->triangle_count = count;
        indices = NULL;
        index_charged = false;
        const corner *source = (const corner *)sources.data;
        const float *positions = (const float *)parser->positions.data, *colors = (const float *)parser->colors.data;
        const float *texcoords = (const float *)parser->texcoords.data, *normals = (const float *)parser->normals.data;
        for (size_t v = 0; v < vertex_count; v++) {
            corner c = source[v];
            memcpy(mesh->positions + 3 * v, positions + 3 * (c.v - 1), 3 * sizeof(float));
            if (with_colors) memcpy(mesh->colors + 4 * v, colors + 4 * (c.v - 1), 4 * sizeof(float));
            if (with_texcoords) {
                if (c.vt)
                    memcpy(mesh->texcoords + 2 * v, texcoords + 2 * (c.vt - 1), 2 * sizeof(float));
                else
                    mesh->texcoords[2 * v] = mesh->texcoords[2 * v + 1] = 0.0f;
            }
            if (with_normals) {
                if (c.vn)
                    memcpy(mesh->normals + 3 * v, normals + 3 * (c.vn - 1), 3 * sizeof(float));
                else
                    memset(mesh->normals + 3 * v, 0, 3 * sizeof(float));
            }
        }
    }
    free(indices);
    if (index_charged) lk__budget_release(parser->budget, corner_count, sizeof(uint32_t));
    lk__buffer_free_charged(&sources, parser->budget);
    return status;
}

/* One node, one mesh, a primitive per group of faces in first-use order. */
static lk_status build_scene(scene_parser *parser)
{
    lk_scene *scene = parser->scene;
    size_t group_count = parser->groups.count;
    size_t triangle_count = parser->triangle_groups.size / sizeof(uint32_t);
    const uint32_t *groups = (const uint32_t *)parser->triangle_groups.data;
    size_t material_slots = 0, map_count = 0;
    for (size_t g = 0; g < group_count; g++)
        material_slots += strcmp(name_at(&parser->groups, g), no_material_group) != 0;
    for (size_t m = 0; m < parser->mtl_materials.size / sizeof(mtl_material); m++) {
        const mtl_material *material = (const mtl_material *)parser->mtl_materials.data + m;
        map_count += (material->color_map != 0) + (material->normal_map != 0);
    }
    if (map_count > material_slots * 2) map_count = material_slots * 2;
    /* The scene's arrays are part of what the read holds (a line of
     * "usemtl" and one of "f" make a primitive and a material). */
    size_t per_texture = sizeof(lk_scene_texture) + sizeof(lk_scene_image) + sizeof(int32_t);
    if (!lk__budget_charge(parser->budget, group_count, sizeof(lk_scene_primitive)) ||
        !lk__budget_charge(parser->budget, material_slots, sizeof(lk_scene_material)) ||
        !lk__budget_charge(parser->budget, map_count, per_texture))
        return over_budget(parser);
    scene->nodes = lk__calloc_array(1, sizeof *scene->nodes);
    scene->roots = lk__calloc_array(1, sizeof *scene->roots);
    scene->meshes = lk__calloc_array(1, sizeof *scene->meshes);
    if (scene->meshes) scene->meshes[0].primitives = lk__calloc_array(group_count, sizeof(lk_scene_primitive));
    scene->materials = lk__calloc_array(material_slots, sizeof *scene->materials);
    scene->textures = lk__calloc_array(map_count, sizeof *scene->textures);
    scene->images = lk__calloc_array(map_count, sizeof *scene->images);
    parser->image_of_path = lk__calloc_array(map_count, sizeof *parser->image_of_path);
    if (!scene->nodes || !scene->roots || !scene->meshes || !scene->meshes[0].primitives || !scene->materials ||
        !scene->textures || !scene->images || !parser->image_of_path)
        return out_of_memory(parser);
    lk__scene_node_init(&scene->nodes[0]);
    scene->nodes[0].mesh = 0;
    scene->node_count = scene->root_count = scene->mesh_count = 1;
    if (parser->object_name) {
        if (!(scene->nodes[0].name = utf8_name(parser, parser->object_name)) ||
            !(scene->meshes[0].name = copy_string(scene->nodes[0].name)))
            return out_of_memory(parser);
    }
    /* Triangles ordered by group (counting sort), charged while held. */
    if (triangle_count > LK_MAX_ELEMENTS / 3 ||
        !lk__budget_charge(parser->budget, triangle_count + group_count + 1, sizeof(uint32_t)))
        return over_budget(parser);
    uint32_t *order = lk__malloc_array(triangle_count, sizeof *order);
    uint32_t *starts = lk__calloc_array(group_count + 1, sizeof *starts);
    first_use *first = NULL;
    bool first_charged = lk__budget_charge(parser->budget, parser->position_count, sizeof *first);
    lk_status status = LK_OK;
    if (!first_charged)
        status = over_budget(parser);
    else if (!order || !starts || !(first = lk__calloc_array(parser->position_count, sizeof *first)))
        status = out_of_memory(parser);
    if (status == LK_OK) {
        for (size_t t = 0; t < triangle_count; t++) starts[groups[t] + 1]++;
        for (size_t g = 0; g < group_count; g++) starts[g + 1] += starts[g];
        for (size_t t = 0; t < triangle_count; t++) order[starts[groups[t]]++] = (uint32_t)t;
        for (size_t g = group_count; g > 0; g--) starts[g] = starts[g - 1];
        starts[0] = 0;
    }
    lk_scene_mesh *mesh = &scene->meshes[0];
    for (size_t g = 0; status == LK_OK && g < group_count; g++) {
        size_t count = starts[g + 1] - starts[g];
        if (count == 0) continue; /* a usemtl with no face after it */
        const char *name = name_at(&parser->groups, g);
        lk_scene_primitive *primitive = &mesh->primitives[mesh->primitive_count++];
        lk_mesh_init(&primitive->mesh);
        primitive->material = -1;
        if (strcmp(name, no_material_group) != 0) {
            primitive->material = (int32_t)scene->material_count;
            status = make_material(parser, name, &scene->materials[scene->material_count++]);
        }
        if (status == LK_OK)
            status = build_primitive(parser, order + starts[g], count, first, (uint32_t)g + 1, primitive);
    }
    free(order);
    free(starts);
    free(first);
    lk__budget_release(parser->budget, triangle_count + group_count + 1, sizeof(uint32_t));
    if (first_charged) lk__budget_release(parser->budget, parser->position_count, sizeof *first);
    return status;
}

static void parser_free(scene_parser *parser)
{
    lk__buffer *buffers[] = {&parser->positions, &parser->colors,          &parser->texcoords,    &parser->normals,
                             &parser->corners,   &parser->triangle_groups, &parser->polygon,      &parser->joined,
                             &parser->mtllibs,   &parser->map_paths,       &parser->mtl_materials};
    for (size_t i = 0; i < sizeof buffers / sizeof buffers[0]; i++) lk__buffer_free_charged(buffers[i], parser->budget);
    name_table *tables[] = {&parser->groups, &parser->mtl_files, &parser->mtl_inodes, &parser->materials,
                            &parser->image_paths};
    for (size_t i = 0; i < sizeof tables / sizeof tables[0]; i++) name_table_free(parser, tables[i]);
    free(parser->image_of_path);
    free(parser->object_name);
    lk__buffer_free(&parser->notes);
}

/* Whether a line of the file starts with `usemtl`. */
static bool uses_materials(const char *data, size_t size)
{
    const char *p = data, *end = data + size;
    if (size >= 3 && memcmp(p, "\xEF\xBB\xBF", 3) == 0) p += 3;
    while (p < end) {
        p = lk__skip_spaces(p, end);
        if (end - p > 6 && memcmp(p, "usemtl", 6) == 0 && (lk__is_space(p[6]) || p[6] == '\n')) return true;
        if (end - p == 6 && memcmp(p, "usemtl", 6) == 0) return true;
        const char *newline = memchr(p, '\n', (size_t)(end - p));
        p = newline ? newline + 1 : end;
    }
    return false;
}

/* The mesh reader's mesh as a scene of one primitive without material:
 * what an OBJ without materials or faces is, read within the mesh
 * reader's memory (it keeps less per face than the split by material). */
static lk_status read_as_mesh(const char *data, size_t size, const lk__read_context *ctx, lk_scene *scene,
                              lk_error *error)
{
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_status status = size ? lk__read_obj(data, size, ctx, &mesh, error)
                            : lk_error_set(error, LK_ERR_PARSE, "%s: empty file", ctx->name);
    if (status == LK_OK) status = lk_scene_from_mesh(scene, &mesh, error);
    lk_mesh_free(&mesh); /* empty when the scene took it */
    return status;
}

lk_status lk__read_obj_scene_text(const char *data, size_t size, const char *mtl, size_t mtl_size,
                                  const lk__read_context *ctx, lk_scene *scene, lk_error *error)
{
    lk_scene_init(scene);
    if (!uses_materials(data, size)) return read_as_mesh(data, size, ctx, scene, error);
    scene_parser parser;
    memset(&parser, 0, sizeof parser);
    parser.name = ctx->name;
    parser.directory = ctx->directory;
    parser.budget = ctx->budget;
    parser.error = error;
    parser.group = UINT32_MAX;
    parser.memory_mtl = mtl;
    parser.memory_mtl_size = mtl_size;
    parser.scene = scene;
    parser.mtl_folder = "";
    lk_scene_init(scene);
    lk_status status = size ? for_each_line(&parser, parser.name, data, size, parse_obj_line)
                            : lk_error_set(error, LK_ERR_PARSE, "%s: empty file", ctx->name);
    if (status == LK_OK) status = check_references(&parser);
    if (status == LK_OK && parser.position_count == 0)
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no vertices ('v' lines): not an OBJ model", ctx->name);
    bool points_only = status == LK_OK && parser.triangle_groups.size == 0;
    if (status == LK_OK && !points_only) status = load_mtllibs(&parser);
    if (status == LK_OK && !points_only) status = build_scene(&parser);
    if (status == LK_OK && parser.notes.size) {
        parser.notes.data[parser.notes.size - 1] = '\0'; /* the last newline */
        scene->notes = lk__buffer_take(&parser.notes);
    }
    parser_free(&parser);
    if (status == LK_OK && points_only) {
        /* A point cloud has no faces to carry materials: the mesh reader's
         * points (with the normals or texture coordinates of each `v`). */
        lk_scene_free(scene);
        status = read_as_mesh(data, size, ctx, scene, error);
    }
    if (status != LK_OK) lk_scene_free(scene);
    return status;
}

lk_status lk__read_obj_scene(const char *data, size_t size, const lk__read_context *ctx, lk_scene *scene,
                             lk_error *error)
{
    return lk__read_obj_scene_text(data, size, NULL, 0, ctx, scene, error);
}
