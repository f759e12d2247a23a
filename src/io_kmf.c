/* SPDX-License-Identifier: MIT */
/* KMF, the key-frame model format: a list of SMF frames sharing one
 * connectivity (docs/formats.md has the full definition).
 *
 *   kmf 1                header: magic and version
 *   frames F             number of frames (>= 1)
 *   fps R                playback rate (> 0)
 *   frame [NAME]         frame 0: a complete SMF model (v, f, and optional
 *   v ... / f ...        per-vertex r, n, c and bind statements)
 *   frame [NAME]         frames 1 .. F-1: exactly as many `v` lines as
 *   v ...                frame 0 has, nothing else
 *
 * '#' starts a comment; blank lines are ignored. Frame 0 is handed to the
 * SMF reader (with the KMF lines commented out, so its line numbers are the
 * file's). Errors say FILE:LINE. The writer prints floats with %.7g, or %.9g
 * when that does not read back to the same float, so write + read is exact. */
#include "anim_io.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

typedef struct kmf_line {
    const char *start; /* first non-space character */
    const char *end;   /* before the comment or newline */
    const char *next;  /* start of the next line */
    const char *keyword_end;
} kmf_line;

/* Splits the line at p; returns false when p == end. */
static bool kmf_next_line(const char *p, const char *end, kmf_line *line)
{
    if (p >= end) return false;
    const char *newline = memchr(p, '\n', (size_t)(end - p));
    const char *line_end = newline ? newline : end;
    line->next = newline ? newline + 1 : end;
    const char *comment = memchr(p, '#', (size_t)(line_end - p));
    if (comment) line_end = comment;
    line->start = lk__skip_spaces(p, line_end);
    /* Trailing spaces (and '\r') do not count. */
    while (line_end > line->start && lk__is_space(line_end[-1])) line_end--;
    line->end = line_end;
    const char *k = line->start;
    while (k < line_end && !lk__is_space(*k)) k++;
    line->keyword_end = k;
    return true;
}

static bool kmf_is(const kmf_line *line, const char *word)
{
    size_t length = (size_t)(line->keyword_end - line->start);
    return length == strlen(word) && memcmp(line->start, word, length) == 0;
}

static bool kmf_blank(const kmf_line *line) { return line->start == line->end; }

/* Reads the frame name after `frame` (one token, optional), charged to the
 * budget: names are the animation's and stay charged. */
static lk_status kmf_frame_name(const kmf_line *line, const char *name, size_t line_number, lk__budget *budget,
                                char **out, lk_error *error)
{
    const char *p = lk__skip_spaces(line->keyword_end, line->end);
    *out = NULL;
    if (p == line->end) return LK_OK;
    const char *q = p;
    while (q < line->end && !lk__is_space(*q)) q++;
    if (q != line->end)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line_number,
                                 "expected 'frame [NAME]' with a name without spaces");
    if (!lk__budget_charge(budget, (size_t)(q - p) + 1, 1))
        return lk__error_at_line(error, LK_ERR_LIMIT, name, line_number,
                                 "the frame names need more than the memory budget of %zu bytes", budget->limit);
    *out = malloc((size_t)(q - p) + 1);
    if (!*out) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
    memcpy(*out, p, (size_t)(q - p));
    (*out)[q - p] = '\0';
    return LK_OK;
}

static lk_status kmf_header_number(const kmf_line *line, const char *name, size_t line_number, const char *keyword,
                                   double *value, lk_error *error)
{
    if (!kmf_is(line, keyword))
        return lk__error_at_line(error, LK_ERR_PARSE, name, line_number,
                                 "expected '%s' (KMF header: kmf 1, frames F, fps R)", keyword);
    const char *p = line->keyword_end;
    if (!lk__parse_double(&p, line->end, value) || lk__skip_spaces(p, line->end) != line->end)
        return lk__error_at_line(error, LK_ERR_PARSE, name, line_number, "expected one number after '%s'", keyword);
    return LK_OK;
}

lk_status lk__anim_read_kmf(const char *data, size_t size, const lk__anim_context *ctx, lk_animation *animation,
                            lk_error *error)
{
    const char *name = ctx->name;
    const char *p = data, *end = data + size;
    lk_animation_init(animation);
    kmf_line line;
    size_t line_number = 0;
    /* Header: the first three statements. */
    double values[3] = {0, 0, 0};
    static const char *const header_keywords[3] = {"kmf", "frames", "fps"};
    int header_seen = 0;
    size_t frames_line = 1; /* where the frame count was given, for messages */
    while (header_seen < 3) {
        if (!kmf_next_line(p, end, &line))
            return lk__error_at_line(error, LK_ERR_PARSE, name, line_number ? line_number : 1,
                                     "file ends inside the KMF header (expected kmf 1, frames F, fps R)");
        line_number++;
        p = line.next;
        if (kmf_blank(&line)) continue;
        lk_status status =
            kmf_header_number(&line, name, line_number, header_keywords[header_seen], &values[header_seen], error);
        if (status != LK_OK) {
            if (header_seen == 0)
                return lk__error_at_line(error, LK_ERR_PARSE, name, line_number, "not a KMF file (expected 'kmf 1')");
            return status;
        }
        if (header_seen == 0 && values[0] != 1)
            return lk__error_at_line(error, LK_ERR_UNSUPPORTED, name, line_number, "KMF version %g (only 1 exists)",
                                     values[0]);
        if (header_seen == 1 && (!(values[1] >= 1) || values[1] != floor(values[1]) || values[1] > 1e15))
            return lk__error_at_line(error, LK_ERR_PARSE, name, line_number, "frame count %g is not a positive integer",
                                     values[1]);
        if (header_seen == 2 && (!(values[2] > 0) || !isfinite(values[2])))
            return lk__error_at_line(error, LK_ERR_RANGE, name, line_number, "fps %g is not a positive number",
                                     values[2]);
        if (header_seen == 1) frames_line = line_number;
        header_seen++;
    }
    size_t frame_count = (size_t)values[1];
    if (frame_count > ctx->max_frames)
        return lk__error_at_line(error, LK_ERR_LIMIT, name, frames_line, "%zu frames is more than the limit of %zu",
                                 frame_count, ctx->max_frames);
    /* Frame 0 starts at the first `frame` line. */
    for (;;) {
        if (!kmf_next_line(p, end, &line))
            return lk__error_at_line(error, LK_ERR_PARSE, name, line_number, "no 'frame' line after the header");
        line_number++;
        p = line.next;
        if (kmf_blank(&line)) continue;
        if (!kmf_is(&line, "frame"))
            return lk__error_at_line(error, LK_ERR_PARSE, name, line_number, "expected 'frame' after the header");
        break;
    }
    /* Every later frame needs at least its "frame" line (6 bytes with the
     * newline): refuse claims the file cannot hold before allocating per
     * frame. */
    if (frame_count - 1 > ((size_t)(end - p) + 1) / 6)
        return lk__error_at_line(error, LK_ERR_LIMIT, name, frames_line,
                                 "the header claims %zu frames but only %zu bytes follow the first 'frame' line "
                                 "(missing frames?)",
                                 frame_count, (size_t)(end - p));
    if (!lk__budget_charge(ctx->budget, frame_count, sizeof(char *)))
        return lk__error_at_line(error, LK_ERR_LIMIT, name, frames_line,
                                 "%zu frames need more than the memory budget of %zu bytes", frame_count,
                                 ctx->budget->limit);
    char **names = lk__calloc_array(frame_count, sizeof(char *));
    if (!names) return lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
    bool any_name = false;
    char *smf_copy = NULL;
    lk_status status = kmf_frame_name(&line, name, line_number, ctx->budget, &names[0], error);
    if (status != LK_OK) goto done;
    any_name = names[0] != NULL;
    /* Find the end of frame 0: the next `frame` line. */
    const char *frame0_end = end;
    size_t frame0_last_line = line_number;
    {
        const char *q = p;
        size_t n = line_number;
        kmf_line scan;
        while (kmf_next_line(q, end, &scan)) {
            n++;
            if (kmf_is(&scan, "frame")) {
                frame0_end = q;
                break;
            }
            q = scan.next;
            frame0_last_line = n;
        }
    }
    /* The SMF reader sees the file up to the end of frame 0 with the KMF
     * statements turned into comments, so its line numbers stay right. */
    size_t smf_size = (size_t)(frame0_end - data);
    if (!lk__budget_charge(ctx->budget, smf_size + 1, 1)) {
        status = lk_error_set(error, LK_ERR_LIMIT, "%s: frame 0 needs more than the memory budget of %zu bytes", name,
                              ctx->budget->limit);
        goto done;
    }
    smf_copy = malloc(smf_size + 1);
    if (!smf_copy) {
        status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
        goto done;
    }
    memcpy(smf_copy, data, smf_size);
    smf_copy[smf_size] = '\0';
    {
        const char *q = smf_copy, *smf_end = smf_copy + smf_size;
        kmf_line scan;
        int commented = 0;
        while (commented < 4 && kmf_next_line(q, smf_end, &scan)) {
            if (!kmf_blank(&scan)) {
                smf_copy[scan.start - smf_copy] = '#';
                commented++;
            }
            q = scan.next;
        }
    }
    lk__read_context smf_ctx = {name, ctx->directory, ctx->budget};
    status = lk__read_smf(smf_copy, smf_size, &smf_ctx, &animation->mesh, error);
    free(smf_copy);
    smf_copy = NULL;
    lk__budget_release(ctx->budget, smf_size + 1, 1);
    if (status != LK_OK) goto done;
    size_t vertex_count = animation->mesh.vertex_count;
    /* Every later frame needs at least "v 0 0 0" (7 bytes) per vertex. */
    size_t remaining = (size_t)(end - frame0_end);
    if (frame_count > 1 && (uint64_t)(frame_count - 1) * vertex_count > remaining / 7) {
        status = lk__error_at_line(error, LK_ERR_RANGE, name, 2,
                                   "the header says %zu frames of %zu vertices but only %zu bytes follow frame 0 "
                                   "(missing frames?)",
                                   frame_count, vertex_count, remaining);
        goto done;
    }
    status = lk__animation_alloc_frames(animation, frame_count, ctx->budget, name, error);
    if (status != LK_OK) goto done;
    animation->frames_per_second = values[2];
    memcpy(animation->frame_positions, animation->mesh.positions, vertex_count * 3 * sizeof(float));
    /* Frames 1 .. F-1. */
    p = frame0_end;
    line_number = frame0_last_line;
    size_t frame = 0, frame_vertices = vertex_count, frame_line = 0;
    float *out = NULL;
    while (kmf_next_line(p, end, &line)) {
        line_number++;
        p = line.next;
        if (kmf_blank(&line)) continue;
        if (kmf_is(&line, "frame")) {
            if (frame_vertices != vertex_count) {
                status = lk__error_at_line(error, LK_ERR_RANGE, name, line_number,
                                           "frame %zu (line %zu) has %zu vertices but frame 0 has %zu", frame,
                                           frame_line, frame_vertices, vertex_count);
                goto done;
            }
            frame++;
            if (frame >= frame_count) {
                status = lk__error_at_line(error, LK_ERR_RANGE, name, line_number,
                                           "frame %zu found but the header says %zu frames", frame, frame_count);
                goto done;
            }
            status = kmf_frame_name(&line, name, line_number, ctx->budget, &names[frame], error);
            if (status != LK_OK) goto done;
            any_name = any_name || names[frame] != NULL;
            frame_vertices = 0;
            frame_line = line_number;
            out = animation->frame_positions + frame * vertex_count * 3;
            continue;
        }
        if (!kmf_is(&line, "v")) {
            char token[32];
            lk__quote_token(line.start, line.end, token, sizeof token);
            status = lk__error_at_line(error, LK_ERR_PARSE, name, line_number,
                                       "unexpected '%s' in frame %zu (frames after the first hold only 'v' lines)",
                                       token, frame);
            goto done;
        }
        if (frame_vertices == vertex_count) {
            status = lk__error_at_line(error, LK_ERR_RANGE, name, line_number,
                                       "frame %zu has more vertices than frame 0 (%zu)", frame, vertex_count);
            goto done;
        }
        const char *q = line.keyword_end;
        for (int k = 0; k < 3; k++) {
            double value;
            if (!lk__parse_double(&q, line.end, &value)) {
                status = lk__error_at_line(error, LK_ERR_PARSE, name, line_number, "expected 3 numbers after 'v'");
                goto done;
            }
            float f = (float)value;
            if (!isfinite(f)) {
                status = lk__error_at_line(error, LK_ERR_RANGE, name, line_number, "'v' value %g is not a finite float",
                                           value);
                goto done;
            }
            out[3 * frame_vertices + (size_t)k] = f;
        }
        if (lk__skip_spaces(q, line.end) != line.end) {
            status =
                lk__error_at_line(error, LK_ERR_PARSE, name, line_number, "expected 3 numbers after 'v', got more");
            goto done;
        }
        frame_vertices++;
    }
    if (frame_vertices != vertex_count) {
        status = lk__error_at_line(error, LK_ERR_RANGE, name, line_number,
                                   "frame %zu (line %zu) has %zu vertices but frame 0 has %zu", frame, frame_line,
                                   frame_vertices, vertex_count);
        goto done;
    }
    if (frame + 1 != frame_count) {
        status = lk__error_at_line(error, LK_ERR_RANGE, name, line_number,
                                   "the header says %zu frames but the file has %zu (missing frames)", frame_count,
                                   frame + 1);
        goto done;
    }
    if (any_name) {
        for (size_t f = 0; f < frame_count; f++)
            if (!names[f] && !(names[f] = calloc(1, 1))) {
                status = lk_error_set(error, LK_ERR_NOMEM, "%s: out of memory", name);
                goto done;
            }
        animation->frame_names = names;
        names = NULL;
    }
    ctx->report->key_count = frame_count;
done:
    if (names) {
        for (size_t f = 0; f < frame_count; f++) free(names[f]);
        free(names);
    }
    free(smf_copy);
    if (status != LK_OK) lk_animation_free(animation);
    return status;
}

lk_status lk__read_kmf(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error)
{
    lk_animation_report report;
    memset(&report, 0, sizeof report);
    lk__anim_context anim_ctx = {ctx->name, ctx->directory, ctx->budget, LK__ANIM_DEFAULT_MAX_FRAMES, 0, 0, 0, &report};
    lk_animation animation;
    lk_status status = lk__anim_read_kmf(data, size, &anim_ctx, &animation, error);
    if (status != LK_OK) return status;
    return lk__animation_take_frame0(&animation, mesh, error);
}

/* A float that reads back exactly: %.7g when that suffices (short and
 * common), else %.9g, which always does. One strtof per value keeps the
 * writer fast (lk__format_float's shortest search costs ~4x more). */
static size_t kmf_format_float(char *out, float value)
{
    int length = snprintf(out, 32, "%.7g", (double)value);
    if (strtof(out, NULL) == value) return (size_t)length;
    return (size_t)snprintf(out, 32, "%.9g", (double)value);
}

/* "KEY a b c\n" with floats that read back exactly. */
static void kmf_put_floats(FILE *file, const char *keyword, const float *values, int count)
{
    char line[160];
    size_t at = strlen(keyword);
    memcpy(line, keyword, at);
    for (int k = 0; k < count; k++) {
        line[at++] = ' ';
        at += kmf_format_float(line + at, values[k]);
    }
    line[at++] = '\n';
    fwrite(line, 1, at, file);
}

static void kmf_put_frame_line(FILE *file, const lk_animation *animation, size_t frame)
{
    const char *frame_name = animation->frame_names ? animation->frame_names[frame] : NULL;
    if (!frame_name || !frame_name[0]) {
        fputs("frame\n", file);
        return;
    }
    /* One token: spaces and comment characters become '_'. */
    fputs("frame ", file);
    for (const char *c = frame_name; *c; c++) fputc(lk__is_space(*c) || *c == '#' || *c == '\n' ? '_' : *c, file);
    fputc('\n', file);
}

lk_status lk__anim_write_kmf(FILE *file, const lk_animation *animation, const char *name, lk_error *error)
{
    const lk_mesh *mesh = &animation->mesh;
    size_t vertex_count = mesh->vertex_count;
    fprintf(file, "kmf 1\nframes %zu\nfps %.17g\n", animation->frame_count, animation->frames_per_second);
    fprintf(file, "# %zu vertices, %zu triangles per frame (lodkit)\n", vertex_count, mesh->triangle_count);
    kmf_put_frame_line(file, animation, 0);
    for (size_t v = 0; v < vertex_count; v++) kmf_put_floats(file, "v", animation->frame_positions + 3 * v, 3);
    if (mesh->texcoords)
        for (size_t v = 0; v < vertex_count; v++) kmf_put_floats(file, "r", mesh->texcoords + 2 * v, 2);
    if (mesh->normals)
        for (size_t v = 0; v < vertex_count; v++) kmf_put_floats(file, "n", mesh->normals + 3 * v, 3);
    if (mesh->colors) /* SMF colours are r g b: alpha is not kept */
        for (size_t v = 0; v < vertex_count; v++) kmf_put_floats(file, "c", mesh->colors + 4 * v, 3);
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *triangle = mesh->indices + 3 * t;
        fprintf(file, "f %lu %lu %lu\n", triangle[0] + 1ul, triangle[1] + 1ul, triangle[2] + 1ul);
    }
    for (size_t f = 1; f < animation->frame_count; f++) {
        kmf_put_frame_line(file, animation, f);
        const float *positions = animation->frame_positions + f * vertex_count * 3;
        for (size_t v = 0; v < vertex_count; v++) kmf_put_floats(file, "v", positions + 3 * v, 3);
        if (ferror(file)) break;
    }
    if (ferror(file)) return lk_error_set(error, LK_ERR_IO, "%s: write error", name);
    return LK_OK;
}
