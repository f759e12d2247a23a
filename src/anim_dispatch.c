/* SPDX-License-Identifier: MIT */
/* lk_animation_read, lk_animation_read_ex, lk_animation_read_memory and
 * lk_animation_write: the format by the file's extension, the file around
 * the reader or writer (its bytes, the memory budget, the directory of
 * external references, the atomic output) and the validation of what is
 * read. The formats themselves live in io_md2.c, io_kmf.c, io_gltf.c and
 * io_acclaim.c (their interface: anim_io.h). */
#include "anim_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef enum anim_format { ANIM_UNKNOWN, ANIM_KMF, ANIM_MD2, ANIM_GLTF, ANIM_ACCLAIM } anim_format;

static anim_format anim_format_from_path(const char *path, const char **extension)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    *extension = dot ? dot : base + strlen(base);
    if (!dot) return ANIM_UNKNOWN;
    size_t len = strlen(dot + 1);
    if (lk__word_equals(dot + 1, len, "kmf")) return ANIM_KMF;
    if (lk__word_equals(dot + 1, len, "md2")) return ANIM_MD2;
    if (lk__word_equals(dot + 1, len, "gltf") || lk__word_equals(dot + 1, len, "glb")) return ANIM_GLTF;
    if (lk__word_equals(dot + 1, len, "amc") || lk__word_equals(dot + 1, len, "asf")) return ANIM_ACCLAIM;
    return ANIM_UNKNOWN;
}

static char *directory_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    size_t length = slash ? (size_t)(slash - path) : 1;
    char *directory = malloc(length + 2);
    if (!directory) return NULL;
    if (!slash)
        strcpy(directory, ".");
    else if (slash == path)
        strcpy(directory, "/");
    else {
        memcpy(directory, path, length);
        directory[length] = '\0';
    }
    return directory;
}

/* path with its extension (starting at `extension`) replaced by `new_ext`. */
static char *with_extension(const char *path, const char *extension, const char *new_ext)
{
    size_t stem = (size_t)(extension - path);
    char *out = malloc(stem + strlen(new_ext) + 1);
    if (!out) return NULL;
    memcpy(out, path, stem);
    strcpy(out + stem, new_ext);
    return out;
}

lk_status lk_animation_read(const char *path, lk_animation *animation, lk_error *error)
{
    return lk_animation_read_ex(path, NULL, animation, NULL, error);
}

static size_t anim_limit(const lk_animation_read_options *options)
{
    return options && options->max_bytes ? options->max_bytes : LK__ANIM_DEFAULT_MAX_BYTES;
}

static void fill_context(lk__anim_context *ctx, const char *name, const char *directory, lk__budget *budget,
                         const lk_animation_read_options *options, lk_animation_report *report)
{
    ctx->name = name;
    ctx->directory = directory;
    ctx->budget = budget;
    ctx->max_frames = options && options->max_frames ? options->max_frames : LK__ANIM_DEFAULT_MAX_FRAMES;
    ctx->frames_per_second = options ? options->frames_per_second : 0;
    ctx->animation_index = options ? options->animation_index : 0;
    ctx->all_animations = options ? options->all_animations : 0;
    ctx->report = report;
}

/* Reads one file already in memory; validates the result. */
static lk_status read_data(const char *data, size_t size, anim_format format, const lk__anim_context *ctx,
                           lk_animation *animation, lk_error *error)
{
    lk_status status;
    if (size == 0) {
        status = lk_error_set(error, LK_ERR_PARSE, "%s: empty file", ctx->name);
    } else if (ctx->frames_per_second < 0 || !isfinite(ctx->frames_per_second)) {
        status = lk_error_set(error, LK_ERR_INVALID, "frames_per_second %g must be >= 0", ctx->frames_per_second);
    } else {
        switch (format) {
        case ANIM_KMF: status = lk__anim_read_kmf(data, size, ctx, animation, error); break;
        case ANIM_MD2: status = lk__anim_read_md2((const unsigned char *)data, size, ctx, animation, error); break;
        case ANIM_GLTF: status = lk__anim_read_gltf(data, size, ctx, animation, error); break;
        default:
            status =
                lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: an Acclaim set cannot be read from memory", ctx->name);
            break;
        }
    }
    if (status == LK_OK) {
        lk_error inner = {0};
        status = lk_animation_validate(animation, &inner);
        if (status != LK_OK) status = lk_error_set(error, status, "%s: %s", ctx->name, inner.message);
    }
    if (status != LK_OK) lk_animation_free(animation);
    return status;
}

lk_status lk_animation_read_memory(const void *data, size_t size, const char *name,
                                   const lk_animation_read_options *options, lk_animation *animation,
                                   lk_animation_report *report, lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_read_memory: NULL animation");
    lk_animation_init(animation);
    if (!name) name = "<memory>";
    lk_animation_report local_report;
    if (!report) report = &local_report;
    memset(report, 0, sizeof *report);
    const char *extension;
    anim_format format = anim_format_from_path(name, &extension);
    if (format == ANIM_UNKNOWN)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: not an animation file name (expected .kmf, .md2, .gltf or .glb)", name);
    /* The caller's bytes are held while they are parsed, as a file's are. */
    lk__budget budget = {anim_limit(options), 0};
    if (!lk__budget_charge(&budget, size, 1)) return lk__input_too_large(name, size, &budget, error);
    lk__anim_context ctx;
    fill_context(&ctx, name, NULL, &budget, options, report);
    return read_data(data, size, format, &ctx, animation, error);
}

lk_status lk_animation_read_ex(const char *path, const lk_animation_read_options *options, lk_animation *animation,
                               lk_animation_report *report, lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_read: NULL animation");
    lk_animation_init(animation);
    if (!path) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_read: NULL path");
    lk_animation_report local_report;
    if (!report) report = &local_report;
    memset(report, 0, sizeof *report);
    const char *extension;
    anim_format format = anim_format_from_path(path, &extension);
    if (format == ANIM_UNKNOWN)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: not an animation file (expected .kmf, .md2, .gltf, .glb, .amc or .asf)", path);
    if (format == ANIM_ACCLAIM) {
        /* The set is named by its stem: X.asf, X.amc, X.smf, X.wgt. */
        char *asf = with_extension(path, extension, ".asf");
        char *amc = with_extension(path, extension, ".amc");
        char *smf = with_extension(path, extension, ".smf");
        char *wgt = with_extension(path, extension, ".wgt");
        lk_status status;
        if (!asf || !amc || !smf || !wgt)
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        else
            status = lk_animation_read_acclaim(smf, asf, amc, wgt, options, animation, report, error);
        free(asf);
        free(amc);
        free(smf);
        free(wgt);
        return status;
    }
    char *data;
    size_t size;
    /* The file is held whole while it is parsed: it counts against the
     * budget, and one larger than it is refused before it is read. */
    lk__budget budget = {anim_limit(options), 0};
    lk_status status = lk__read_file_charged(path, &budget, &data, &size, error);
    if (status != LK_OK) return status;
    char *directory = directory_of(path);
    if (!directory) {
        free(data);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    lk__anim_context ctx;
    fill_context(&ctx, path, directory, &budget, options, report);
    status = read_data(data, size, format, &ctx, animation, error);
    free(directory);
    free(data);
    return status;
}

lk_status lk_animation_write(const char *path, const lk_animation *animation, lk_error *error)
{
    if (!path || !animation) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_write: NULL argument");
    const char *extension;
    anim_format format = anim_format_from_path(path, &extension);
    lk_status (*writer)(FILE *, const lk_animation *, const char *, lk_error *) = NULL;
    switch (format) {
    case ANIM_KMF: writer = lk__anim_write_kmf; break;
    case ANIM_MD2: writer = lk__anim_write_md2; break;
    case ANIM_GLTF:
        if (lk__word_equals(extension + 1, strlen(extension + 1), "glb"))
            return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: writing .glb is not supported (use .gltf)", path);
        writer = lk__anim_write_gltf;
        break;
    default:
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: cannot write an animation in this format (use .kmf, .md2 or .gltf)", path);
    }
    lk_error inner = {0};
    lk_status status = lk_animation_validate(animation, &inner);
    if (status != LK_OK)
        return lk_error_set(error, status, "%s: refusing to write an invalid animation: %s", path, inner.message);
    lk__atomic_file out;
    status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    status = writer(out.file, animation, path, error);
    if (status != LK_OK) return lk__atomic_fail(&out, error);
    return lk__atomic_commit(&out, error);
}
