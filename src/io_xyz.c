/* SPDX-License-Identifier: MIT */
/* XYZ point sets: one point per line, "x y z" or "x y z nx ny nz".
 * Every point line must hold the same count as the first one; blank lines
 * and '#' comments are skipped. The result has no triangles. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Parses one point line into values (up to 6 kept); returns the count of
 * numbers or -1 when something else is on the line (*bad points at it). */
static int xyz_parse_line(const char *p, const char *end, double values[6], const char **bad)
{
    int count = 0;
    double value;
    while (lk__parse_double(&p, end, &value)) {
        if (count < 6) values[count] = value;
        count++;
    }
    p = lk__skip_spaces(p, end);
    if (p < end && *p != '#') {
        *bad = p;
        return -1;
    }
    return count;
}

lk_status lk__xyz_line(lk__xyz_lines *state, const char *p, const char *end, const char *name, size_t line,
                       double values[6], int *count, lk_error *error)
{
    *count = 0;
    const char *start = lk__skip_spaces(p, end);
    if (start >= end || *start == '#') return LK_OK;
    const char *bad = NULL;
    int numbers = xyz_parse_line(start, end, values, &bad);
    if (numbers < 0) {
        char token[32];
        size_t length = 0;
        while (bad + length < end && !lk__is_space(bad[length]) && length < 24) length++;
        memcpy(token, bad, length);
        token[length] = '\0';
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected a number, got '%s'", token);
    }
    if (state->numbers_per_line == 0) {
        if (numbers != 3 && numbers != 6)
            return lk__error_at_line(error, LK_ERR_PARSE, name, line,
                                     "expected 3 or 6 numbers per line (x y z [nx ny nz]), got %d", numbers);
        state->numbers_per_line = numbers;
        state->first_line = line;
    } else if (numbers != state->numbers_per_line) {
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "expected %d numbers like line %zu, got %d",
                                 state->numbers_per_line, state->first_line, numbers);
    }
    *count = numbers;
    return LK_OK;
}

lk_status lk__read_xyz(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    lk__buffer positions = {0}, normals = {0};
    const char *p = data, *end = data + size;
    size_t line = 0, point_count = 0;
    lk__xyz_lines lines = {0, 0};
    lk_status status = LK_OK;
    while (p < end && status == LK_OK) {
        line++;
        const char *newline = memchr(p, '\n', (size_t)(end - p));
        const char *line_end = newline ? newline : end;
        const char *start = p;
        p = newline ? newline + 1 : end;
        double values[6];
        int count;
        status = lk__xyz_line(&lines, start, line_end, ctx->name, line, values, &count, error);
        if (status != LK_OK || count == 0) continue;
        float point[6];
        for (int k = 0; k < count; k++) {
            point[k] = (float)values[k];
            if (!isfinite(point[k])) {
                status = lk__error_at_line(error, LK_ERR_RANGE, ctx->name, line, "%g is not a finite float", values[k]);
                break;
            }
        }
        if (status != LK_OK) break;
        /* Both arrays are charged as they grow, the file being held too. */
        if (point_count + 1 > LK_MAX_ELEMENTS)
            status = LK_ERR_LIMIT;
        else
            status = lk__buffer_append_charged(&positions, point, 3 * sizeof(float), ctx->budget);
        if (status == LK_OK && count == 6)
            status = lk__buffer_append_charged(&normals, point + 3, 3 * sizeof(float), ctx->budget);
        if (status == LK_ERR_LIMIT) {
            status = lk__error_at_line(error, LK_ERR_LIMIT, ctx->name, line,
                                       "points need more than the memory budget of %zu bytes", ctx->budget->limit);
            break;
        }
        if (status != LK_OK) {
            status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
            break;
        }
        point_count++;
    }
    if (status == LK_OK && point_count == 0)
        status = lk_error_set(error, LK_ERR_PARSE, "%s: no points (expected lines of 'x y z [nx ny nz]')", ctx->name);
    if (status == LK_OK) {
        mesh->indices = lk__malloc_array(0, sizeof(uint32_t));
        if (!mesh->indices) status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", ctx->name);
    }
    if (status != LK_OK) {
        lk__buffer_free_charged(&positions, ctx->budget);
        lk__buffer_free_charged(&normals, ctx->budget);
        lk_mesh_free(mesh);
        return status;
    }
    mesh->vertex_count = point_count;
    mesh->positions = (float *)lk__buffer_take_charged(&positions, ctx->budget);
    if (lines.numbers_per_line == 6) mesh->normals = (float *)lk__buffer_take_charged(&normals, ctx->budget);
    return LK_OK;
}

lk_status lk__write_xyz(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error)
{
    bool with_normals = mesh->normals && !options->skip_normals;
    const float *sources[2] = {mesh->positions, with_normals ? mesh->normals : NULL};
    char line[256];
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        size_t at = 0;
        for (int s = 0; s < 2 && sources[s]; s++) {
            for (int k = 0; k < 3; k++) {
                if (at) line[at++] = ' ';
                at += (size_t)lk__format_float(line + at, 32, sources[s][3 * i + (size_t)k]);
            }
        }
        line[at++] = '\n';
        fwrite(line, 1, at, file);
    }
    if (ferror(file)) return lk_error_set(error, LK_ERR_IO, "write error while writing XYZ");
    return LK_OK;
}
