/* SPDX-License-Identifier: MIT */
/* STL (stereolithography): reader for ASCII and binary files, writer for both.
 *
 * STL stores every triangle with its own three corners, so the reader welds
 * corners with bit-identical positions (-0.0 counts as 0.0) into shared
 * vertices; the result is an indexed mesh with real topology. Facet normals
 * in the file are ignored; the writer computes them from the triangles. */
#include "bytes.h"
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

enum { STL_HEADER_BYTES = 80, STL_FIRST_TRIANGLE = 84, STL_TRIANGLE_BYTES = 50 };

/* ---- welding --------------------------------------------------------------- */

#define STL_EMPTY_SLOT UINT32_MAX

/* The three arrays are charged to the budget at their capacity. */
typedef struct stl_welder {
    float *positions; /* 3 per vertex */
    size_t vertex_count, vertex_capacity;
    uint32_t *slots;   /* open-addressing hash table of vertex indices */
    size_t slot_count; /* power of two */
    uint32_t *indices;
    size_t triangle_count, triangle_capacity;
    lk__budget *budget;
} stl_welder;

static void welder_free(stl_welder *welder)
{
    lk__budget *budget = welder->budget;
    free(welder->positions);
    free(welder->slots);
    free(welder->indices);
    lk__budget_release(budget, welder->vertex_capacity, 3 * sizeof(float));
    lk__budget_release(budget, welder->slot_count, sizeof(uint32_t));
    lk__budget_release(budget, welder->triangle_capacity, 3 * sizeof(uint32_t));
    memset(welder, 0, sizeof *welder);
    welder->budget = budget;
}

/* Grows one of the welder's arrays from *capacity to at least `need`
 * elements of `size` bytes: doubling as far as the budget reaches, charged.
 * Returns LK_OK, LK_ERR_LIMIT or LK_ERR_NOMEM. */
static lk_status welder_grow(stl_welder *welder, void **array, size_t *capacity, size_t need, size_t size)
{
    if (need > LK_MAX_ELEMENTS) return LK_ERR_LIMIT;
    size_t grown_capacity = lk__budget_grow_capacity(welder->budget, *capacity, need, size, 256);
    if (grown_capacity == 0) return LK_ERR_LIMIT;
    void *grown = lk__realloc_array(*array, grown_capacity, size);
    if (!grown) return LK_ERR_NOMEM;
    lk__budget_charge(welder->budget, grown_capacity - *capacity, size); /* fits */
    *array = grown;
    *capacity = grown_capacity;
    return LK_OK;
}

/* Hashes the bit patterns, with -0.0 folded into 0.0 so both weld. */
static uint64_t hash_position(const float position[3])
{
    uint64_t hash = 0;
    for (int k = 0; k < 3; k++) {
        float value = position[k] == 0.0f ? 0.0f : position[k];
        uint32_t bits;
        memcpy(&bits, &value, sizeof bits);
        hash = lk__mix64(hash ^ bits);
    }
    return hash;
}

/* Returns LK_OK, LK_ERR_LIMIT or LK_ERR_NOMEM; the new table is charged
 * while the old one still exists. */
static lk_status welder_rehash(stl_welder *welder, size_t slot_count)
{
    if (!lk__budget_charge(welder->budget, slot_count, sizeof(uint32_t))) return LK_ERR_LIMIT;
    uint32_t *slots = lk__malloc_array(slot_count, sizeof *slots);
    if (!slots) {
        lk__budget_release(welder->budget, slot_count, sizeof(uint32_t));
        return LK_ERR_NOMEM;
    }
    for (size_t i = 0; i < slot_count; i++) slots[i] = STL_EMPTY_SLOT;
    for (size_t v = 0; v < welder->vertex_count; v++) {
        size_t slot = (size_t)hash_position(welder->positions + 3 * v) & (slot_count - 1);
        while (slots[slot] != STL_EMPTY_SLOT) slot = (slot + 1) & (slot_count - 1);
        slots[slot] = (uint32_t)v;
    }
    free(welder->slots);
    lk__budget_release(welder->budget, welder->slot_count, sizeof(uint32_t));
    welder->slots = slots;
    welder->slot_count = slot_count;
    return LK_OK;
}

/* Index of the vertex at `position`, adding it if new. Positions are finite
 * here, so == is exact equality with -0.0 == 0.0. Returns LK_ERR_NOMEM or
 * LK_ERR_LIMIT on failure. */
static lk_status welder_vertex(stl_welder *welder, const float position[3], uint32_t *index)
{
    if (2 * (welder->vertex_count + 1) > welder->slot_count) {
        size_t slot_count = welder->slot_count ? 2 * welder->slot_count : 1024;
        lk_status status = welder_rehash(welder, slot_count);
        if (status != LK_OK) return status;
    }
    size_t slot = (size_t)hash_position(position) & (welder->slot_count - 1);
    while (welder->slots[slot] != STL_EMPTY_SLOT) {
        const float *other = welder->positions + 3 * (size_t)welder->slots[slot];
        if (other[0] == position[0] && other[1] == position[1] && other[2] == position[2]) {
            *index = welder->slots[slot];
            return LK_OK;
        }
        slot = (slot + 1) & (welder->slot_count - 1);
    }
    if (welder->vertex_count == welder->vertex_capacity) {
        void *positions = welder->positions;
        lk_status status =
            welder_grow(welder, &positions, &welder->vertex_capacity, welder->vertex_count + 1, 3 * sizeof(float));
        welder->positions = positions;
        if (status != LK_OK) return status;
    }
    memcpy(welder->positions + 3 * welder->vertex_count, position, 3 * sizeof(float));
    welder->slots[slot] = (uint32_t)welder->vertex_count;
    *index = (uint32_t)welder->vertex_count++;
    return LK_OK;
}

static lk_status welder_triangle(stl_welder *welder, uint32_t a, uint32_t b, uint32_t c)
{
    if (welder->triangle_count == welder->triangle_capacity) {
        void *indices = welder->indices;
        lk_status status =
            welder_grow(welder, &indices, &welder->triangle_capacity, welder->triangle_count + 1, 3 * sizeof(uint32_t));
        welder->indices = indices;
        if (status != LK_OK) return status;
    }
    uint32_t *triangle = welder->indices + 3 * welder->triangle_count++;
    triangle[0] = a;
    triangle[1] = b;
    triangle[2] = c;
    return LK_OK;
}

/* Hands the welded arrays over to the mesh. */
static lk_status welder_finish(stl_welder *welder, lk_mesh *mesh, const char *name, lk_error *error)
{
    lk_mesh_init(mesh);
    /* Shrink to fit; keep the larger block if realloc declines. The hash
     * table goes first: the arrays handed over stay charged. */
    free(welder->slots);
    welder->slots = NULL;
    lk__budget_release(welder->budget, welder->slot_count, sizeof(uint32_t));
    welder->slot_count = 0;
    float *positions = lk__realloc_array(welder->positions, welder->vertex_count, 3 * sizeof(float));
    if (positions) {
        welder->positions = positions;
        lk__budget_release(welder->budget, welder->vertex_capacity - welder->vertex_count, 3 * sizeof(float));
        welder->vertex_capacity = welder->vertex_count;
    }
    uint32_t *indices = lk__realloc_array(welder->indices, welder->triangle_count, 3 * sizeof(uint32_t));
    if (indices) {
        welder->indices = indices;
        lk__budget_release(welder->budget, welder->triangle_capacity - welder->triangle_count, 3 * sizeof(uint32_t));
        welder->triangle_capacity = welder->triangle_count;
    }
    if (!welder->positions) welder->positions = lk__malloc_array(0, sizeof(float));
    if (!welder->indices) welder->indices = lk__malloc_array(0, sizeof(uint32_t));
    if (!welder->positions || !welder->indices) {
        welder_free(welder);
        return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
    }
    mesh->vertex_count = welder->vertex_count;
    mesh->triangle_count = welder->triangle_count;
    mesh->positions = welder->positions;
    mesh->indices = welder->indices;
    welder->positions = NULL;
    welder->indices = NULL;
    welder->vertex_capacity = welder->triangle_capacity = 0; /* now the mesh's, still charged */
    welder_free(welder);
    return LK_OK;
}

static lk_status welder_failure(lk_status status, const char *location, const stl_welder *welder, lk_error *error)
{
    if (status == LK_ERR_LIMIT)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: mesh would exceed the memory budget of %zu bytes", location,
                            welder->budget->limit);
    return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", location);
}

/* ---- binary ---------------------------------------------------------------- */

static lk_status read_binary(const unsigned char *data, uint32_t triangle_count, const lk__read_context *ctx,
                             lk_mesh *mesh, lk_error *error)
{
    char where[300];
    snprintf(where, sizeof where, "%s: byte %d", ctx->name, STL_HEADER_BYTES);
    /* The file size already matches the count; this checks the budget for
     * the triangles, allocated at once (the vertices are charged as
     * welding finds them). */
    lk_status status =
        lk__check_claim(triangle_count, 0, 0, 3 * sizeof(uint32_t), ctx->budget, "triangles", where, error);
    if (status != LK_OK) return status;
    stl_welder welder = {0};
    welder.budget = ctx->budget;
    void *indices = NULL;
    status = welder_grow(&welder, &indices, &welder.triangle_capacity, triangle_count, 3 * sizeof(uint32_t));
    welder.indices = indices;
    if (status != LK_OK) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
    for (uint32_t t = 0; t < triangle_count; t++) {
        size_t record = STL_FIRST_TRIANGLE + (size_t)t * STL_TRIANGLE_BYTES;
        uint32_t corners[3];
        for (int c = 0; c < 3; c++) {
            size_t offset = record + 12 + 12 * (size_t)c; /* after the facet normal */
            float position[3];
            for (int k = 0; k < 3; k++) {
                position[k] = lk__load_f32le(data + offset + 4 * (size_t)k);
                if (!isfinite(position[k])) {
                    welder_free(&welder);
                    return lk_error_set(error, LK_ERR_RANGE,
                                        "%s: byte %zu: triangle %u: vertex coordinate is not finite (%g)", ctx->name,
                                        offset + 4 * (size_t)k, t, (double)position[k]);
                }
            }
            status = welder_vertex(&welder, position, &corners[c]);
            if (status != LK_OK) {
                snprintf(where, sizeof where, "%s: byte %zu", ctx->name, record);
                status = welder_failure(status, where, &welder, error);
                welder_free(&welder);
                return status;
            }
        }
        welder_triangle(&welder, corners[0], corners[1], corners[2]); /* preallocated: cannot fail */
    }
    return welder_finish(&welder, mesh, ctx->name, error);
}

/* ---- ASCII ----------------------------------------------------------------- */

typedef struct stl_text {
    const char *p, *end;
    size_t line;
    const char *name;
    lk_error *error;
} stl_text;

typedef struct stl_token {
    const char *start;
    size_t length;
    size_t line;
} stl_token;

/* Next whitespace-separated token, across lines. */
static bool next_token(stl_text *text, stl_token *token)
{
    const char *p = text->p;
    while (p < text->end && (lk__is_space(*p) || *p == '\n')) {
        if (*p == '\n') text->line++;
        p++;
    }
    if (p == text->end) {
        /* Report end of file on the last line, not after its newline. */
        if (p > text->p && p[-1] == '\n') text->line--;
        text->p = p;
        return false;
    }
    token->start = p;
    while (p < text->end && !lk__is_space(*p) && *p != '\n') p++;
    token->length = (size_t)(p - token->start);
    token->line = text->line;
    text->p = p;
    return true;
}

/* Skips the rest of the current line (solid names, facet normals). */
static void skip_rest_of_line(stl_text *text)
{
    const char *next = lk__skip_line(text->p, text->end);
    if (next > text->p && next[-1] == '\n') text->line++;
    text->p = next;
}

static bool token_is(const stl_token *token, const char *word)
{
    return lk__word_equals(token->start, token->length, word);
}

static int shown_length(size_t length) { return length > 40 ? 40 : (int)length; }

/* Reads a token that must be `word`. */
static lk_status expect_word(stl_text *text, const char *word)
{
    stl_token token;
    if (!next_token(text, &token))
        return lk_error_set(text->error, LK_ERR_PARSE, "%s:%zu: expected '%s', file ends", text->name, text->line,
                            word);
    if (!token_is(&token, word))
        return lk_error_set(text->error, LK_ERR_PARSE, "%s:%zu: expected '%s', got '%.*s'", text->name, token.line,
                            word, shown_length(token.length), token.start);
    return LK_OK;
}

/* Reads one of the three coordinates on the line of a "vertex" keyword. */
static lk_status read_coordinate(stl_text *text, size_t vertex_line, float *out)
{
    const char *before = text->p;
    size_t line_before = text->line;
    stl_token token;
    if (!next_token(text, &token) || token.line != vertex_line) {
        text->p = before; /* leave the next line for the caller's context */
        text->line = line_before;
        return lk_error_set(text->error, LK_ERR_PARSE, "%s:%zu: expected 3 coordinates after 'vertex', line ends",
                            text->name, vertex_line);
    }
    const char *p = token.start;
    double value;
    if (!lk__parse_double(&p, token.start + token.length, &value) || p != token.start + token.length)
        return lk_error_set(text->error, LK_ERR_PARSE, "%s:%zu: expected 3 coordinates after 'vertex', got '%.*s'",
                            text->name, token.line, shown_length(token.length), token.start);
    /* Values just above FLT_MAX (like "3.402823e+38") round down to it; from
     * FLT_MAX plus half its last-place unit on they overflow. */
    const double overflow = (double)FLT_MAX + 0x1p103;
    if (!(fabs(value) < overflow))
        return lk_error_set(text->error, LK_ERR_RANGE, "%s:%zu: vertex coordinate '%.*s' is not a finite float",
                            text->name, token.line, shown_length(token.length), token.start);
    if (value > FLT_MAX) value = FLT_MAX;
    if (value < -FLT_MAX) value = -FLT_MAX;
    *out = (float)value;
    return LK_OK;
}

/* One facet after its "facet" keyword: "outer loop", vertices, "endloop",
 * "endfacet". Loops of more than three vertices are fanned. */
static lk_status read_facet(stl_text *text, stl_welder *welder)
{
    size_t facet_line = text->line;
    skip_rest_of_line(text); /* "normal nx ny nz": recomputed when needed */
    lk_status status = expect_word(text, "outer");
    if (status == LK_OK) status = expect_word(text, "loop");
    if (status != LK_OK) return status;
    uint32_t first = 0, previous = 0;
    size_t corner_count = 0;
    for (;;) {
        stl_token token;
        if (!next_token(text, &token))
            return lk_error_set(text->error, LK_ERR_PARSE, "%s:%zu: expected 'vertex' or 'endloop', file ends",
                                text->name, text->line);
        if (token_is(&token, "endloop")) break;
        if (!token_is(&token, "vertex"))
            return lk_error_set(text->error, LK_ERR_PARSE, "%s:%zu: expected 'vertex' or 'endloop', got '%.*s'",
                                text->name, token.line, shown_length(token.length), token.start);
        float position[3];
        for (int k = 0; k < 3; k++) {
            status = read_coordinate(text, token.line, &position[k]);
            if (status != LK_OK) return status;
        }
        char where[300];
        snprintf(where, sizeof where, "%s:%zu", text->name, token.line);
        uint32_t vertex;
        status = welder_vertex(welder, position, &vertex);
        if (status != LK_OK) return welder_failure(status, where, welder, text->error);
        if (corner_count == 0) first = vertex;
        if (corner_count >= 2) {
            status = welder_triangle(welder, first, previous, vertex);
            if (status != LK_OK) return welder_failure(status, where, welder, text->error);
        }
        previous = vertex;
        corner_count++;
    }
    if (corner_count < 3)
        return lk_error_set(text->error, LK_ERR_PARSE, "%s:%zu: facet has %zu vertices, expected 3", text->name,
                            facet_line, corner_count);
    return expect_word(text, "endfacet");
}

/* One or more "solid NAME ... endsolid NAME" blocks; a missing final
 * endsolid is tolerated. */
static lk_status read_ascii(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    stl_text text = {data, data + size, 1, ctx->name, error};
    stl_welder welder = {0};
    welder.budget = ctx->budget;
    lk_status status = LK_OK;
    stl_token token;
    while (status == LK_OK && next_token(&text, &token)) {
        if (!token_is(&token, "solid")) {
            status = lk_error_set(error, LK_ERR_PARSE, "%s:%zu: expected 'solid', got '%.*s'", ctx->name, token.line,
                                  shown_length(token.length), token.start);
            break;
        }
        skip_rest_of_line(&text); /* the solid's name */
        while (status == LK_OK) {
            if (!next_token(&text, &token)) break;
            if (token_is(&token, "endsolid")) {
                skip_rest_of_line(&text);
                break;
            }
            if (token_is(&token, "facet")) {
                status = read_facet(&text, &welder);
            } else {
                status = lk_error_set(error, LK_ERR_PARSE, "%s:%zu: expected 'facet' or 'endsolid', got '%.*s'",
                                      ctx->name, token.line, shown_length(token.length), token.start);
            }
        }
    }
    if (status != LK_OK) {
        welder_free(&welder);
        return status;
    }
    return welder_finish(&welder, mesh, ctx->name, error);
}

/* ---- detection ------------------------------------------------------------- */

/* ASCII STL starts with "solid", but so do some binary headers; those have
 * control bytes (usually NUL padding) in the first line or header. */
static bool looks_like_ascii(const char *data, size_t size)
{
    const char *p = data, *end = data + size;
    while (p < end && (lk__is_space(*p) || *p == '\n')) p++;
    if ((size_t)(end - p) < 5 || !lk__word_equals(p, 5, "solid")) return false;
    size_t checked = size < 1024 ? size : 1024;
    for (size_t i = 0; i < checked; i++) {
        unsigned char c = (unsigned char)data[i];
        if (c < 0x20 && c != '\t' && c != '\n' && c != '\r' && c != '\v' && c != '\f') return false;
    }
    return true;
}

lk_status lk__read_stl(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    const unsigned char *bytes = (const unsigned char *)data;
    /* A binary file's size is fixed by its count: trust that first, since
     * binary headers may start with "solid" too. */
    if (size >= STL_FIRST_TRIANGLE) {
        uint32_t triangle_count = lk__load_u32le(bytes + STL_HEADER_BYTES);
        if ((uint64_t)STL_FIRST_TRIANGLE + (uint64_t)triangle_count * STL_TRIANGLE_BYTES == size)
            return read_binary(bytes, triangle_count, ctx, mesh, error);
    }
    if (looks_like_ascii(data, size)) return read_ascii(data, size, ctx, mesh, error);
    if (size < STL_FIRST_TRIANGLE)
        return lk_error_set(error, LK_ERR_PARSE,
                            "%s: byte %zu: not an STL file: too short for binary STL (%zu bytes, need at least %d) "
                            "and not ASCII STL (which starts with 'solid')",
                            ctx->name, size, size, STL_FIRST_TRIANGLE);
    uint32_t triangle_count = lk__load_u32le(bytes + STL_HEADER_BYTES);
    uint64_t expected = (uint64_t)STL_FIRST_TRIANGLE + (uint64_t)triangle_count * STL_TRIANGLE_BYTES;
    /* A count the file cannot hold is a refused header claim (like
     * lk__check_claim); extra bytes are a different kind of corruption. */
    return lk_error_set(error, expected > size ? LK_ERR_LIMIT : LK_ERR_PARSE,
                        "%s: byte %d: expected %u triangles (%llu bytes), file has %zu%s", ctx->name,
                        STL_HEADER_BYTES + 4, triangle_count, (unsigned long long)expected, size,
                        expected > size ? " (truncated or corrupt binary STL)"
                                        : " (corrupt binary STL: bytes after the last triangle)");
}

/* ---- writer ---------------------------------------------------------------- */

/* Unit facet normal from the corner order (counter-clockwise front);
 * zero for degenerate triangles. */
static void facet_normal(const lk_mesh *mesh, size_t triangle, float normal[3])
{
    const uint32_t *corner = mesh->indices + 3 * triangle;
    const float *a = mesh->positions + 3 * (size_t)corner[0];
    const float *b = mesh->positions + 3 * (size_t)corner[1];
    const float *c = mesh->positions + 3 * (size_t)corner[2];
    double u[3], v[3];
    for (int k = 0; k < 3; k++) {
        u[k] = (double)b[k] - a[k];
        v[k] = (double)c[k] - a[k];
    }
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int k = 0; k < 3; k++) normal[k] = length > 0 ? (float)(n[k] / length) : 0.0f;
}

static lk_status write_binary(FILE *file, const lk_mesh *mesh, lk_error *error)
{
    /* The header must not start with "solid" or readers take it for ASCII. */
    unsigned char header[STL_FIRST_TRIANGLE] = {0};
    static const char label[] = "binary STL written by lodkit " LK_VERSION_STRING;
    memcpy(header, label, sizeof label - 1);
    lk__store_u32le(header + STL_HEADER_BYTES, (uint32_t)mesh->triangle_count);
    bool failed = fwrite(header, 1, sizeof header, file) != sizeof header;
    for (size_t t = 0; t < mesh->triangle_count && !failed; t++) {
        unsigned char record[STL_TRIANGLE_BYTES] = {0}; /* attribute byte count stays 0 */
        float normal[3];
        facet_normal(mesh, t, normal);
        for (int k = 0; k < 3; k++) lk__store_f32le(record + 4 * k, normal[k]);
        for (int c = 0; c < 3; c++) {
            const float *position = mesh->positions + 3 * (size_t)mesh->indices[3 * t + (size_t)c];
            for (int k = 0; k < 3; k++) lk__store_f32le(record + 12 + 12 * c + 4 * k, position[k]);
        }
        failed = fwrite(record, 1, sizeof record, file) != sizeof record;
    }
    if (failed || ferror(file)) return lk_error_set(error, LK_ERR_IO, "write error while writing binary STL");
    return LK_OK;
}

static lk_status write_ascii(FILE *file, const lk_mesh *mesh, lk_error *error)
{
    bool failed = fputs("solid lodkit\n", file) < 0;
    for (size_t t = 0; t < mesh->triangle_count && !failed; t++) {
        float normal[3];
        facet_normal(mesh, t, normal);
        char text[3][40];
        for (int k = 0; k < 3; k++) lk__format_float(text[k], sizeof text[k], normal[k]);
        failed = fprintf(file, "  facet normal %s %s %s\n    outer loop\n", text[0], text[1], text[2]) < 0;
        for (int c = 0; c < 3 && !failed; c++) {
            const float *position = mesh->positions + 3 * (size_t)mesh->indices[3 * t + (size_t)c];
            for (int k = 0; k < 3; k++) lk__format_float(text[k], sizeof text[k], position[k]);
            failed = fprintf(file, "      vertex %s %s %s\n", text[0], text[1], text[2]) < 0;
        }
        if (!failed) failed = fputs("    endloop\n  endfacet\n", file) < 0;
    }
    if (!failed) failed = fputs("endsolid lodkit\n", file) < 0;
    if (failed || ferror(file)) return lk_error_set(error, LK_ERR_IO, "write error while writing ASCII STL");
    return LK_OK;
}

lk_status lk__write_stl(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error)
{
    if (mesh->triangle_count == 0 && mesh->vertex_count > 0)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "STL holds only triangles; this mesh is a point set of %zu vertices (use ply or xyz)",
                            mesh->vertex_count);
    return options->stl_ascii ? write_ascii(file, mesh, error) : write_binary(file, mesh, error);
}
