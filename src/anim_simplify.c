/* SPDX-License-Identifier: MIT */
/* Deformation-sensitive simplification around the multi-frame QEM of
 * src/qem.c and qem_frames.c: options, results, scheme names,
 * lk_animation_simplify and lk_animation_simplify_levels (option checks,
 * welding the vertices that coincide in every frame, running the QEM level
 * after level, splitting texture seams again), and the per-frame Metro
 * measure of the paper's evaluation (its Fig. 8). */
#include "internal.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX

static const char *const scheme_names[] = {"max", "avg", "frame"};

const char *lk_anim_scheme_name(lk_anim_scheme scheme)
{
    if ((unsigned)scheme >= sizeof scheme_names / sizeof scheme_names[0]) return NULL;
    return scheme_names[scheme];
}

int lk_anim_scheme_parse(const char *name, lk_anim_scheme *scheme)
{
    if (!name || !scheme) return -1;
    if (!strcmp(name, "max"))
        *scheme = LK_ANIM_SCHEME_MAX;
    else if (!strcmp(name, "avg") || !strcmp(name, "mean"))
        *scheme = LK_ANIM_SCHEME_AVG;
    else if (!strcmp(name, "frame") || !strcmp(name, "single"))
        *scheme = LK_ANIM_SCHEME_FRAME;
    else
        return -1;
    return 0;
}

void lk_anim_simplify_options_default(lk_anim_simplify_options *options)
{
    memset(options, 0, sizeof *options);
    lk_simplify_options_default(&options->simplify);
    options->scheme = LK_ANIM_SCHEME_MAX;
    options->lost_surface = LK_ANIM_LOST_SURFACE_DEFAULT;
}

void lk_anim_simplify_result_free(lk_anim_simplify_result *result)
{
    if (!result) return;
    lk_animation_free(&result->animation);
    free(result->vertex_map);
    memset(result, 0, sizeof *result);
}

/* ------------------------------------------------------------------------ */
/* Simplifying the frames: welding, the multi-frame QEM (src/qem.c), seams    */
/* ------------------------------------------------------------------------ */

static lk_status check_animation(const lk_animation *animation, const lk_anim_simplify_options *options,
                                 lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "no animation given");
    if (animation->frame_count == 0 || !animation->frame_positions)
        return lk_error_set(error, LK_ERR_INVALID, "the animation has no frames");
    lk_status status = lk_mesh_validate(&animation->mesh, error);
    if (status != LK_OK) return status;
    if (animation->mesh.triangle_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "cannot simplify an animation without triangles");
    size_t v_count = animation->mesh.vertex_count;
    if (v_count > SIZE_MAX / 3 / animation->frame_count)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu frames of %zu vertices are too many", animation->frame_count,
                            v_count);
    size_t floats = 3 * v_count * animation->frame_count;
    for (size_t i = 0; i < floats; i++)
        if (!isfinite(animation->frame_positions[i]))
            return lk_error_set(error, LK_ERR_RANGE, "frame %zu, vertex %zu: position is not finite", i / 3 / v_count,
                                i / 3 % v_count);
    const lk_simplify_options *o = &options->simplify;
    if (options->scheme != LK_ANIM_SCHEME_MAX && options->scheme != LK_ANIM_SCHEME_AVG &&
        options->scheme != LK_ANIM_SCHEME_FRAME)
        return lk_error_set(error, LK_ERR_INVALID, "unknown scheme %d", (int)options->scheme);
    if (options->scheme == LK_ANIM_SCHEME_FRAME && options->frame >= animation->frame_count)
        return lk_error_set(error, LK_ERR_RANGE, "frame %zu does not exist (the animation has %zu frames)",
                            options->frame, animation->frame_count);
    if (o->flags & (LK_SIMPLIFY_ATTRIBUTES | LK_SIMPLIFY_RECORD))
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "attribute quadrics and contraction histories are not available for animations");
    if (!(o->target_ratio >= 0 && o->target_ratio <= 1))
        return lk_error_set(error, LK_ERR_INVALID, "target ratio must be in (0, 1], got %g", o->target_ratio);
    if (!(o->max_error >= 0) || !isfinite(o->max_error))
        return lk_error_set(error, LK_ERR_INVALID, "max error must be a finite number >= 0");
    if (!(o->pair_distance >= 0) || !isfinite(o->pair_distance))
        return lk_error_set(error, LK_ERR_INVALID, "pair distance must be a finite number >= 0");
    if (!(o->feature_angle >= 0 && o->feature_angle <= 180))
        return lk_error_set(error, LK_ERR_INVALID, "feature angle must be in [0, 180] degrees");
    if (!(o->feature_weight >= 0) || !isfinite(o->feature_weight))
        return lk_error_set(error, LK_ERR_INVALID, "weights must be finite numbers >= 0");
    if (!(options->lost_surface >= 0) || !isfinite(options->lost_surface))
        return lk_error_set(error, LK_ERR_INVALID, "the lost-surface weight must be a finite number >= 0, got %g",
                            options->lost_surface);
    size_t limit = options->max_bytes ? options->max_bytes : (size_t)2 << 30;
    size_t needed = lk__qem_frame_bytes(v_count, animation->frame_count, options->lost_surface > 0);
    if (needed > limit)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%zu frames of %zu vertices need %zu bytes of per-frame quadrics, more than the limit %zu",
                            animation->frame_count, v_count, needed, limit);
    return LK_OK;
}

typedef struct weld_key {
    uint64_t hash;
    uint32_t vertex;
} weld_key;

static int compare_weld_keys(const void *a, const void *b)
{
    const weld_key *x = a, *y = b;
    if (x->hash != y->hash) return x->hash < y->hash ? -1 : 1;
    return x->vertex < y->vertex ? -1 : x->vertex > y->vertex;
}

/* representative[v]: the first vertex whose positions equal v's in every
 * frame (texture seams split such vertices; the QEM must see them as one,
 * or every seam becomes a border that pins the simplification). Returns
 * the number of vertices merged, or SIZE_MAX when out of memory. */
static size_t weld_frames(const lk_animation *animation, uint32_t *representative)
{
    size_t v_count = animation->mesh.vertex_count, frames = animation->frame_count;
    weld_key *keys = lk__malloc_array(v_count, sizeof(weld_key));
    if (!keys) return SIZE_MAX;
    for (size_t v = 0; v < v_count; v++) {
        uint64_t hash = 0x9E3779B97F4A7C15ull;
        for (size_t f = 0; f < frames; f++) {
            const float *p = animation->frame_positions + 3 * (f * v_count + v);
            for (int k = 0; k < 3; k++) {
                float value = p[k] == 0 ? 0.0f : p[k]; /* -0 equals 0 */
                uint32_t bits;
                memcpy(&bits, &value, sizeof bits);
                hash = lk__mix64(hash ^ bits);
            }
        }
        keys[v].hash = hash, keys[v].vertex = (uint32_t)v;
        representative[v] = (uint32_t)v;
    }
    qsort(keys, v_count, sizeof *keys, compare_weld_keys);
    size_t merged = 0;
    for (size_t i = 0; i < v_count;) {
        size_t end = i + 1;
        while (end < v_count && keys[end].hash == keys[i].hash) end++;
        /* within a run of equal hashes (sorted by vertex), compare for real */
        for (size_t j = i + 1; j < end; j++) {
            uint32_t v = keys[j].vertex;
            for (size_t k = i; k < j; k++) {
                uint32_t u = keys[k].vertex;
                if (representative[u] != u) continue;
                bool same = true;
                for (size_t f = 0; f < frames && same; f++) {
                    const float *pu = animation->frame_positions + 3 * (f * v_count + u);
                    const float *pv = animation->frame_positions + 3 * (f * v_count + v);
                    same = pu[0] == pv[0] && pu[1] == pv[1] && pu[2] == pv[2];
                }
                if (same) {
                    representative[v] = u;
                    merged++;
                    break;
                }
            }
        }
        i = end;
    }
    free(keys);
    return merged;
}

/* Texture seams, for splitting welded vertices again on output. */
typedef struct seam_table {
    uint32_t *chart;        /* V: connected component of the input (split) mesh using each vertex */
    uint32_t *copy_start;   /* V + 1: the vertices welded into r are copies[copy_start[r] ..
                               copy_start[r + 1]) */
    uint32_t *copies;       /* V */
    uint32_t *clean_source; /* clean triangle -> input triangle */
} seam_table;

static void seam_table_free(seam_table *table)
{
    free(table->chart), free(table->copy_start), free(table->copies), free(table->clean_source);
    memset(table, 0, sizeof *table);
}

/* Charts, copies and the input triangle of every clean triangle. The
 * clean mesh keeps the input's triangle order and drops only degenerate
 * and duplicate triangles, so a single merge walk pairs them: a dropped
 * triangle never equals the next kept one (it would be a duplicate of an
 * earlier kept triangle, and so would that one). */
static lk_status build_seam_table(const lk_animation *animation, const uint32_t *representative, const lk_mesh *clean,
                                  seam_table *table, lk_error *error)
{
    const lk_mesh *mesh = &animation->mesh;
    size_t v_count = mesh->vertex_count, t_count = mesh->triangle_count;
    memset(table, 0, sizeof *table);
    table->chart = lk__malloc_array(v_count, sizeof(uint32_t));
    table->copy_start = lk__calloc_array(v_count + 1, sizeof(uint32_t));
    table->copies = lk__malloc_array(v_count, sizeof(uint32_t));
    table->clean_source = lk__malloc_array(clean->triangle_count, sizeof(uint32_t));
    uint32_t *component = lk__malloc_array(t_count, sizeof(uint32_t));
    if (!table->chart || !table->copy_start || !table->copies || !table->clean_source || !component) {
        free(component);
        seam_table_free(table);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam table");
    }
    size_t component_count = 0;
    lk_status status = lk_mesh_components(mesh, component, &component_count, error);
    if (status != LK_OK) {
        free(component);
        seam_table_free(table);
        return status;
    }
    for (size_t v = 0; v < v_count; v++) table->chart[v] = NONE;
    for (size_t c = 0; c < 3 * t_count; c++) table->chart[mesh->indices[c]] = component[c / 3];
    free(component);
    for (size_t v = 0; v < v_count; v++) table->copy_start[representative[v] + 1]++;
    for (size_t v = 0; v < v_count; v++) table->copy_start[v + 1] += table->copy_start[v];
    uint32_t *fill = lk__malloc_array(v_count, sizeof(uint32_t));
    if (!fill) {
        seam_table_free(table);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam table");
    }
    memcpy(fill, table->copy_start, v_count * sizeof(uint32_t));
    for (size_t v = 0; v < v_count; v++) table->copies[fill[representative[v]]++] = (uint32_t)v;
    free(fill);
    size_t next = 0;
    for (size_t t = 0; t < t_count && next < clean->triangle_count; t++) {
        const uint32_t *c = mesh->indices + 3 * t, *kept = clean->indices + 3 * next;
        if (representative[c[0]] == kept[0] && representative[c[1]] == kept[1] && representative[c[2]] == kept[2])
            table->clean_source[next++] = (uint32_t)t;
    }
    if (next != clean->triangle_count) {
        seam_table_free(table);
        return lk_error_set(error, LK_ERR_INVALID, "internal error: %zu of %zu triangles matched the input", next,
                            clean->triangle_count);
    }
    return LK_OK;
}

/* Splits the welded vertices of a result again where their copies carry
 * different attributes: each triangle corner takes the copy (of the vertex
 * it now uses) that lies in the chart of its input triangle, or, when that
 * vertex has no copy there, the attributes of its own input corner. Every
 * split vertex follows its welded vertex in every frame. */
/* Squared distance between the attributes of input vertices a and b:
 * texture coordinates, else normals, else colours (0 without any). */
static double attribute_distance(const lk_mesh *mesh, uint32_t a, uint32_t b)
{
    const float *values = mesh->texcoords ? mesh->texcoords : mesh->normals ? mesh->normals : mesh->colors;
    size_t width = mesh->texcoords ? 2 : mesh->normals ? 3 : 4;
    double sum = 0.0;
    for (size_t k = 0; values && k < width; k++) {
        double d = (double)values[width * a + k] - values[width * b + k];
        sum += d * d;
    }
    return sum;
}

/* Whether input vertices a and b differ in any attribute. */
static bool attributes_differ(const lk_mesh *mesh, uint32_t a, uint32_t b)
{
    return (mesh->texcoords &&
            memcmp(mesh->texcoords + 2 * (size_t)a, mesh->texcoords + 2 * (size_t)b, 2 * sizeof(float))) ||
           (mesh->normals && memcmp(mesh->normals + 3 * (size_t)a, mesh->normals + 3 * (size_t)b, 3 * sizeof(float))) ||
           (mesh->colors && memcmp(mesh->colors + 4 * (size_t)a, mesh->colors + 4 * (size_t)b, 4 * sizeof(float)));
}

static lk_status split_seams(const lk__qem *s, const lk_animation *animation, const uint32_t *representative,
                             const seam_table *table, lk_anim_simplify_result *result, lk_error *error)
{
    lk_animation *out = &result->animation;
    const lk_mesh *in = &animation->mesh;
    size_t welded_count = out->mesh.vertex_count, out_triangles = out->mesh.triangle_count;
    size_t frames = out->frame_count, v_count = in->vertex_count;
    uint32_t *survivor = lk__malloc_array(welded_count + 1, sizeof(uint32_t));         /* welded output -> input id */
    uint32_t *source_triangle = lk__malloc_array(out_triangles + 1, sizeof(uint32_t)); /* clean triangle */
    uint32_t *source = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));      /* corner -> input vertex */
    uint32_t *first_pair = lk__malloc_array(welded_count + 1, sizeof(uint32_t));
    uint32_t *pair_next = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    uint32_t *pair_source = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    uint32_t *pair_welded = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    uint32_t *corner_vertex = lk__malloc_array(3 * out_triangles + 1, sizeof(uint32_t));
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    float *positions = NULL;
    lk_status status = LK_OK;
    if (!survivor || !source_triangle || !source || !first_pair || !pair_next || !pair_source || !pair_welded ||
        !corner_vertex) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam split");
        goto done;
    }
    status = lk__qem_output_sources(s, result->vertex_map, survivor, source_triangle, error);
    if (status != LK_OK) goto done;
    /* output triangles are the live clean triangles in clean order (build_output) */
    size_t corner = 0;
    for (size_t t = 0; t < out_triangles; t++) {
        const uint32_t *original = in->indices + 3 * (size_t)table->clean_source[source_triangle[t]];
        for (int k = 0; k < 3; k++, corner++) {
            uint32_t u = original[k], kept = survivor[out->mesh.indices[corner]], chosen = u;
            /* u merged into kept: take the copy of kept in u's chart whose
             * attributes are nearest u's. A chart can meet itself along a
             * seam (a sphere's or cylinder's wrapped texture: u = 0 and 1
             * copies of one position), and then only the attributes tell
             * which side of the seam the triangle lies on. */
            if (representative[u] != kept) {
                double best = INFINITY;
                for (uint32_t i = table->copy_start[kept]; i < table->copy_start[kept + 1]; i++) {
                    uint32_t copy = table->copies[i];
                    if (table->chart[copy] != table->chart[u]) continue;
                    double distance = attribute_distance(in, copy, u);
                    if (distance < best) {
                        best = distance;
                        chosen = copy;
                    }
                }
            }
            source[corner] = chosen;
        }
    }
    /* one output vertex per (welded vertex, source) */
    for (size_t w = 0; w < welded_count; w++) first_pair[w] = NONE;
    size_t pair_count = 0;
    for (size_t c = 0; c < 3 * out_triangles; c++) {
        uint32_t w = out->mesh.indices[c], found = NONE;
        for (uint32_t p = first_pair[w]; p != NONE; p = pair_next[p])
            if (pair_source[p] == source[c]) {
                found = p;
                break;
            }
        if (found == NONE) {
            found = (uint32_t)pair_count++;
            pair_source[found] = source[c];
            pair_welded[found] = w;
            pair_next[found] = first_pair[w];
            first_pair[w] = found;
        }
        corner_vertex[c] = found;
    }
    unsigned flags = (out->mesh.normals ? LK_ATTR_NORMALS : 0) | (out->mesh.texcoords ? LK_ATTR_TEXCOORDS : 0) |
                     (out->mesh.colors ? LK_ATTR_COLORS : 0);
    status = lk_mesh_alloc(&mesh, pair_count, out_triangles, flags, error);
    if (status != LK_OK) goto done;
    positions = lk__malloc_array(frames * pair_count, 3 * sizeof(float));
    if (!positions && pair_count > 0) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu frames of %zu vertices", frames, pair_count);
        goto done;
    }
    for (size_t p = 0; p < pair_count; p++) {
        size_t w = pair_welded[p], u = pair_source[p];
        for (size_t f = 0; f < frames; f++)
            memcpy(positions + 3 * (f * pair_count + p), out->frame_positions + 3 * (f * welded_count + w),
                   3 * sizeof(float));
        if (mesh.normals) memcpy(mesh.normals + 3 * p, in->normals + 3 * u, 3 * sizeof(float));
        if (mesh.texcoords) memcpy(mesh.texcoords + 2 * p, in->texcoords + 2 * u, 2 * sizeof(float));
        if (mesh.colors) memcpy(mesh.colors + 4 * p, in->colors + 4 * u, 4 * sizeof(float));
    }
    if (pair_count) memcpy(mesh.positions, positions, 3 * pair_count * sizeof(float));
    memcpy(mesh.indices, corner_vertex, 3 * out_triangles * sizeof(uint32_t));
    /* an input vertex maps to its own pair when it is a source, else to any
     * pair of its welded vertex */
    for (size_t v = 0; v < v_count; v++) {
        uint32_t w = result->vertex_map[v];
        if (w == NONE) continue;
        uint32_t chosen = first_pair[w];
        for (uint32_t p = first_pair[w]; p != NONE; p = pair_next[p])
            if (pair_source[p] == v) chosen = p;
        result->vertex_map[v] = chosen;
    }
    lk_mesh_free(&out->mesh);
    free(out->frame_positions);
    out->mesh = mesh;
    out->frame_positions = positions;
    lk_mesh_init(&mesh);
    positions = NULL;
done:
    lk_mesh_free(&mesh);
    free(positions);
    free(survivor), free(source_triangle), free(source), free(first_pair), free(pair_next), free(pair_source);
    free(pair_welded), free(corner_vertex);
    return status;
}

/* The progress of level `level` of level_count runs as a part of the
 * whole: each run reports its own fraction from 0 to 1. */
typedef struct level_progress {
    lk_progress_fn progress;
    void *user;
    size_t level, level_count;
} level_progress;

static int report_level(void *user, double fraction, const char *stage)
{
    const level_progress *p = user;
    return p->progress(p->user, ((double)p->level + fraction) / (double)p->level_count, stage);
}

/* Simplifies down through the levels of `order` (targets descending),
 * taking a snapshot at each. Reports 0 first and 1 last. */
static lk_status simplify_animation(const lk_animation *animation, const lk_anim_simplify_options *options,
                                    const double *ratios, size_t level_count, const size_t *order,
                                    lk_anim_simplify_result *results, lk_progress_fn progress, void *progress_user,
                                    lk_error *error)
{
    if (progress && progress(progress_user, 0.0, "simplify")) return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    double start = lk__now();
    const lk_simplify_options *o = &options->simplify;
    size_t reference = options->scheme == LK_ANIM_SCHEME_FRAME ? options->frame : 0;
    size_t v_count = animation->mesh.vertex_count, frames = animation->frame_count;
    /* the reference frame's positions, without degenerate or duplicate
     * triangles (which carry no surface in any frame) */
    lk_mesh clean;
    lk_status status = lk_mesh_copy(&clean, &animation->mesh, error);
    if (status != LK_OK) return status;
    memcpy(clean.positions, animation->frame_positions + 3 * reference * v_count, 3 * v_count * sizeof(float));
    uint32_t *representative = NULL;
    if (!options->keep_seams) {
        representative = lk__malloc_array(v_count, sizeof(uint32_t));
        if (!representative || weld_frames(animation, representative) == SIZE_MAX) {
            free(representative);
            lk_mesh_free(&clean);
            return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam table of %zu vertices", v_count);
        }
        for (size_t c = 0; c < 3 * clean.triangle_count; c++) clean.indices[c] = representative[clean.indices[c]];
    }
    status = lk_mesh_remove_degenerate(&clean, NULL, NULL, error);
    /* attributes differ between welded copies: remember where they came from */
    seam_table seams;
    memset(&seams, 0, sizeof seams);
    bool split = representative && (clean.normals || clean.texcoords || clean.colors);
    if (status == LK_OK && split) status = build_seam_table(animation, representative, &clean, &seams, error);
    if (status == LK_OK && clean.triangle_count == 0)
        status = lk_error_set(error, LK_ERR_INVALID, "every triangle is degenerate: nothing to simplify");
    lk__qem *s = NULL;
    if (status == LK_OK) status = lk__qem_frames_start(&clean, animation, options, &s, error);
    if (status != LK_OK) {
        free(representative);
        seam_table_free(&seams);
        lk_mesh_free(&clean);
        return status;
    }
    if (split && options->hold_seams) {
        /* A welded vertex whose copies carry different attributes lies on a
         * seam: the QEM must not cut across it (each chart keeps its
         * outline, so no triangle spans a seam). */
        unsigned char *seam = lk__calloc_array(v_count ? v_count : 1, 1);
        if (!seam) {
            status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate the seam marks");
        } else {
            for (size_t r = 0; r < v_count; r++) {
                uint32_t first = seams.copy_start[r], end = seams.copy_start[r + 1];
                for (uint32_t i = first + 1; i < end && !seam[r]; i++)
                    if (attributes_differ(&animation->mesh, seams.copies[first], seams.copies[i])) seam[r] = 1;
            }
            lk__qem_mark_seams(s, seam);
            free(seam);
        }
    }
    lk__qem_outcome outcome;
    lk__qem_outcome_of(s, &outcome);
    double diagonal = outcome.diagonal;
    for (size_t level = 0; level < level_count && status == LK_OK; level++) {
        size_t k = order[level];
        size_t target_triangles = 0, target_vertices = o->target_vertices;
        if (ratios[k] > 0) target_triangles = (size_t)floor(ratios[k] * (double)clean.triangle_count);
        if (o->target_triangles > target_triangles) target_triangles = o->target_triangles;
        bool count_target = ratios[k] > 0 || o->target_triangles > 0 || o->target_vertices > 0;
        level_progress part = {progress, progress_user, level, level_count};
        status = lk__qem_run(s, target_triangles, target_vertices, progress ? report_level : NULL, &part, error);
        lk_anim_simplify_result *result = &results[k];
        if (status == LK_OK) status = lk__qem_animation_output(s, &clean, animation, result, error);
        if (status != LK_OK) break;
        /* welded copies follow their representative */
        if (representative)
            for (size_t v = 0; v < v_count; v++) result->vertex_map[v] = result->vertex_map[representative[v]];
        if (split) status = split_seams(s, animation, representative, &seams, result, error);
        if (status != LK_OK) break;
        lk__qem_outcome_of(s, &outcome);
        bool count_reached = outcome.live_triangles <= target_triangles || outcome.live_vertices <= target_vertices;
        result->target_reached = count_target ? count_reached || outcome.parked_for_error : 1;
        result->error = outcome.error;
        result->diagonal = diagonal;
        result->working_bytes = lk__qem_frame_bytes(v_count, frames, options->lost_surface > 0);
        result->folds_from_triangles = outcome.folds_from;
        result->seconds = lk__now() - start;
    }
    lk__qem_free(s);
    lk_mesh_free(&clean);
    free(representative);
    seam_table_free(&seams);
    if (status == LK_OK && progress) (void)progress(progress_user, 1.0, "done"); /* done: too late to cancel */
    return status;
}

lk_status lk_animation_simplify(const lk_animation *animation, const lk_anim_simplify_options *options,
                                lk_anim_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                lk_error *error)
{
    if (!result) return lk_error_set(error, LK_ERR_INVALID, "no result given");
    memset(result, 0, sizeof *result);
    if (!options) return lk_error_set(error, LK_ERR_INVALID, "no options given: set a target");
    lk_status status = check_animation(animation, options, error);
    if (status != LK_OK) return status;
    const lk_simplify_options *o = &options->simplify;
    if (o->target_ratio == 0 && o->target_triangles == 0 && o->target_vertices == 0 && o->max_error == 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "no target: set a ratio, a triangle or vertex count, or a maximum error");
    size_t order = 0;
    status =
        simplify_animation(animation, options, &o->target_ratio, 1, &order, result, progress, progress_user, error);
    if (status != LK_OK) lk_anim_simplify_result_free(result);
    return status;
}

lk_status lk_animation_simplify_levels(const lk_animation *animation, const lk_anim_simplify_options *options,
                                       const double *ratios, size_t level_count, lk_anim_simplify_result *results,
                                       lk_progress_fn progress, void *progress_user, lk_error *error)
{
    if (!results || !ratios || level_count == 0) return lk_error_set(error, LK_ERR_INVALID, "no levels given");
    memset(results, 0, level_count * sizeof *results);
    if (!options) return lk_error_set(error, LK_ERR_INVALID, "no options given");
    for (size_t k = 0; k < level_count; k++)
        if (!(ratios[k] > 0 && ratios[k] <= 1))
            return lk_error_set(error, LK_ERR_INVALID, "level %zu: ratio must be in (0, 1], got %g", k, ratios[k]);
    lk_anim_simplify_options level_options = *options;
    level_options.simplify.target_ratio = 0;
    level_options.simplify.target_triangles = 0;
    level_options.simplify.target_vertices = 0;
    lk_status status = check_animation(animation, &level_options, error);
    if (status != LK_OK) return status;
    size_t *order = lk__malloc_array(level_count, sizeof(size_t));
    if (!order) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate %zu levels", level_count);
    /* largest ratio first (insertion sort: a handful of levels; stable) */
    for (size_t k = 0; k < level_count; k++) {
        size_t at = k;
        while (at > 0 && ratios[order[at - 1]] < ratios[k]) {
            order[at] = order[at - 1];
            at--;
        }
        order[at] = k;
    }
    status = simplify_animation(animation, &level_options, ratios, level_count, order, results, progress, progress_user,
                                error);
    free(order);
    if (status != LK_OK)
        for (size_t k = 0; k < level_count; k++) lk_anim_simplify_result_free(&results[k]);
    return status;
}

lk_status lk_animation_metro(const lk_animation *simplified, const lk_animation *original, const size_t *frames,
                             size_t frame_count, const lk_metro_options *options, lk_metro_result *out,
                             lk_progress_fn progress, void *progress_user, lk_error *error)
{
    if (!simplified || !original || (!out && frame_count > 0))
        return lk_error_set(error, LK_ERR_INVALID, "lk_animation_metro: NULL argument");
    if (!frames && (simplified->frame_count != original->frame_count || frame_count > original->frame_count))
        return lk_error_set(error, LK_ERR_INVALID,
                            "cannot compare every frame: %zu simplified frames, %zu original frames, %zu asked",
                            simplified->frame_count, original->frame_count, frame_count);
    lk_mesh a, b;
    lk_mesh_init(&a), lk_mesh_init(&b);
    lk_status status = LK_OK;
    bool have_meshes = false;
    for (size_t k = 0; k < frame_count && status == LK_OK; k++) {
        size_t frame = frames ? frames[k] : k;
        if (frame >= simplified->frame_count || frame >= original->frame_count) {
            status = lk_error_set(error, LK_ERR_RANGE, "frame %zu does not exist (%zu and %zu frames)", frame,
                                  simplified->frame_count, original->frame_count);
            break;
        }
        /* the frames as meshes: made once, then only the positions change */
        if (!have_meshes) {
            status = lk_animation_frame(simplified, frame, &a, error);
            if (status == LK_OK) status = lk_animation_frame(original, frame, &b, error);
            if (status != LK_OK) break;
            have_meshes = true;
        }
        memcpy(a.positions, simplified->frame_positions + 3 * frame * a.vertex_count,
               3 * a.vertex_count * sizeof(float));
        memcpy(b.positions, original->frame_positions + 3 * frame * b.vertex_count, 3 * b.vertex_count * sizeof(float));
        status = lk_metro(&a, &b, options, &out[k], NULL, NULL, error);
        if (status == LK_OK && progress && progress(progress_user, (double)(k + 1) / (double)frame_count, "metro"))
            status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
    }
    lk_mesh_free(&a), lk_mesh_free(&b);
    return status;
}

/* ------------------------------------------------------------------------ */
/* Error map picture (the paper's Fig. 8 as a heat map)                     */
/* ------------------------------------------------------------------------ */

/* A 5x7 bitmap font (upper case, digits, a little punctuation), drawn by
 * lodkit itself so that the picture needs no font library; bit 4 of each
 * row is the leftmost pixel. Lower case is drawn in upper case. */
static const char glyph_chars[] = "%()+,-./0123456789:=ABCDEFGHIJKLMNOPQRSTUVWXYZ_";
static const unsigned char glyph_rows[][7] = {
    {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03}, /* % */
    {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}, /* ( */
    {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}, /* ) */
    {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00}, /* + */
    {0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08}, /* , */
    {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00}, /* - */
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}, /* . */
    {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00}, /* / */
    {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}, /* 0 */
    {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}, /* 1 */
    {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}, /* 2 */
    {0x1E, 0x01, 0x01, 0x0E, 0x01, 0x01, 0x1E}, /* 3 */
    {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}, /* 4 */
    {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}, /* 5 */
    {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}, /* 6 */
    {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}, /* 7 */
    {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}, /* 8 */
    {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}, /* 9 */
    {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00}, /* : */
    {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00}, /* = */
    {0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}, /* A */
    {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E}, /* B */
    {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E}, /* C */
    {0x1E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1E}, /* D */
    {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F}, /* E */
    {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10}, /* F */
    {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F}, /* G */
    {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}, /* H */
    {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}, /* I */
    {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C}, /* J */
    {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11}, /* K */
    {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F}, /* L */
    {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11}, /* M */
    {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11}, /* N */
    {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}, /* O */
    {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10}, /* P */
    {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D}, /* Q */
    {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11}, /* R */
    {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E}, /* S */
    {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}, /* T */
    {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}, /* U */
    {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04}, /* V */
    {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A}, /* W */
    {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11}, /* X */
    {0x11, 0x11, 0x0A, 0x04, 0x04, 0x04, 0x04}, /* Y */
    {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F}, /* Z */
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F}, /* _ */
};

#define GLYPH_SCALE 2
#define GLYPH_ADVANCE (6 * GLYPH_SCALE)
#define GLYPH_HEIGHT (7 * GLYPH_SCALE)

typedef struct canvas {
    unsigned char *rgba;
    unsigned width, height;
} canvas;

static void fill_rect(canvas *c, long x, long y, long w, long h, const unsigned char rgb[3])
{
    for (long j = y < 0 ? 0 : y; j < y + h && j < (long)c->height; j++)
        for (long i = x < 0 ? 0 : x; i < x + w && i < (long)c->width; i++) {
            unsigned char *p = c->rgba + 4 * ((size_t)j * c->width + (size_t)i);
            p[0] = rgb[0], p[1] = rgb[1], p[2] = rgb[2], p[3] = 255;
        }
}

static long text_width(const char *text) { return (long)strlen(text) * GLYPH_ADVANCE; }

/* Draws text with its top-left corner at (x, y). */
static void draw_text(canvas *c, long x, long y, const char *text, const unsigned char rgb[3])
{
    for (; *text; text++, x += GLYPH_ADVANCE) {
        char ch = (char)toupper((unsigned char)*text);
        const char *at = ch ? strchr(glyph_chars, ch) : NULL;
        if (!at) continue; /* space and unknown characters */
        const unsigned char *rows = glyph_rows[at - glyph_chars];
        for (int row = 0; row < 7; row++)
            for (int column = 0; column < 5; column++)
                if (rows[row] & (0x10 >> column))
                    fill_rect(c, x + column * GLYPH_SCALE, y + row * GLYPH_SCALE, GLYPH_SCALE, GLYPH_SCALE, rgb);
    }
}

/* Colour ramp from dark blue (low) through green and yellow to red (high). */
static void ramp(double t, unsigned char rgb[3])
{
    static const double stops[5][3] = {{25, 30, 110}, {35, 115, 200}, {50, 175, 115}, {240, 205, 55}, {200, 30, 30}};
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double x = t * 4;
    int i = x >= 4 ? 3 : (int)x;
    double f = x - i;
    for (int k = 0; k < 3; k++) rgb[k] = (unsigned char)lround(stops[i][k] + f * (stops[i + 1][k] - stops[i][k]));
}

/* Position of value v on the logarithmic colour scale [low, high]. */
static double scale_position(double v, double low, double high)
{
    if (!(v > low)) return 0;
    if (!(v < high)) return 1;
    return log(v / low) / log(high / low);
}

lk_status lk_anim_error_map(const double *values, size_t level_count, size_t frame_count, const double *level_ratios,
                            const size_t *frame_numbers, double scale_min, double scale_max, const char *title,
                            const char *value_label, unsigned char **rgba, unsigned *width, unsigned *height,
                            lk_error *error)
{
    if (!values || !rgba || !width || !height || level_count == 0 || frame_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "lk_anim_error_map: nothing to draw");
    if (level_count > 1000 || frame_count > 100000)
        return lk_error_set(error, LK_ERR_LIMIT, "lk_anim_error_map: %zu levels x %zu frames is too many to draw",
                            level_count, frame_count);
    *rgba = NULL;
    /* the colour scale: given, or the range of the positive values */
    double low = scale_min, high = scale_max;
    if (!(low > 0) || !(high > low)) {
        double found_low = INFINITY, found_high = 0;
        for (size_t i = 0; i < level_count * frame_count; i++)
            if (values[i] > 0 && isfinite(values[i])) {
                if (values[i] < found_low) found_low = values[i];
                if (values[i] > found_high) found_high = values[i];
            }
        /* three decades at most: rounding noise (1e-16 where nothing
         * changed) must not stretch the scale */
        if (!(low > 0)) low = isfinite(found_low) ? fmax(found_low, found_high * 1e-3) : 1e-6;
        if (!(high > low)) high = found_high > low ? found_high : low * 10;
    }
    /* layout: cells of cell_w x cell_h pixels, levels bottom (first) to top */
    unsigned cell_w = frame_count >= 600 ? 1 : (unsigned)(600 / frame_count);
    unsigned cell_h = level_count >= 40 ? 8 : (unsigned)(320 / level_count);
    unsigned plot_w = (unsigned)frame_count * cell_w, plot_h = (unsigned)level_count * cell_h;
    unsigned left = 80, top = 56, bottom = 64, legend_gap = 28, legend_w = 22, legend_text = 110;
    unsigned min_width = (unsigned)text_width(title ? title : "") + 40;
    canvas c;
    c.width = left + plot_w + legend_gap + legend_w + legend_text;
    if (c.width < min_width) c.width = min_width;
    c.height = top + plot_h + bottom;
    c.rgba = lk__malloc_array((size_t)c.width * c.height, 4);
    if (!c.rgba) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate a %ux%u picture", c.width, c.height);
    static const unsigned char white[3] = {255, 255, 255}, black[3] = {0, 0, 0}, grey[3] = {150, 150, 150};
    fill_rect(&c, 0, 0, c.width, c.height, white);
    if (title) draw_text(&c, 20, 12, title, black);
    char label[64];
    /* cells */
    for (size_t l = 0; l < level_count; l++)
        for (size_t f = 0; f < frame_count; f++) {
            double v = values[l * frame_count + f];
            unsigned char rgb[3];
            if (isnan(v))
                memcpy(rgb, grey, 3);
            else
                ramp(scale_position(v, low, high), rgb);
            long y = (long)top + (long)(level_count - 1 - l) * cell_h;
            fill_rect(&c, (long)left + (long)f * cell_w, y, cell_w, cell_h, rgb);
        }
    /* frame of the plot */
    fill_rect(&c, left - 1, top - 1, plot_w + 2, 1, black);
    fill_rect(&c, left - 1, top + plot_h, plot_w + 2, 1, black);
    fill_rect(&c, left - 1, top - 1, 1, plot_h + 2, black);
    fill_rect(&c, left + plot_w, top - 1, 1, plot_h + 2, black);
    /* y axis: one label per level (thinned when crowded) */
    size_t level_step = (level_count * (GLYPH_HEIGHT + 4) + plot_h - 1) / plot_h;
    for (size_t l = 0; l < level_count; l += level_step ? level_step : 1) {
        if (level_ratios)
            snprintf(label, sizeof label, "%g%%", 100 * level_ratios[l]);
        else
            snprintf(label, sizeof label, "%zu", l + 1);
        long y = (long)top + (long)(level_count - 1 - l) * cell_h + (long)cell_h / 2 - GLYPH_HEIGHT / 2;
        draw_text(&c, (long)left - 8 - text_width(label), y, label, black);
    }
    draw_text(&c, 8, top - GLYPH_HEIGHT - 8, level_ratios ? "KEPT" : "LEVEL", black);
    /* x axis: ticks at round frame steps, at most about 10 */
    size_t steps[] = {1, 2, 5, 10, 20, 25, 50, 100, 200, 250, 500, 1000, 2000, 5000, 10000, 20000, 50000, 100000};
    size_t step = steps[sizeof steps / sizeof steps[0] - 1];
    for (size_t i = 0; i < sizeof steps / sizeof steps[0]; i++)
        if (frame_count / steps[i] <= 10) {
            step = steps[i];
            break;
        }
    for (size_t f = 0; f < frame_count; f += step) {
        long x = (long)left + (long)f * cell_w + (long)cell_w / 2;
        fill_rect(&c, x, top + plot_h, 1, 6, black);
        snprintf(label, sizeof label, "%zu", frame_numbers ? frame_numbers[f] : f);
        draw_text(&c, x - text_width(label) / 2, top + plot_h + 10, label, black);
    }
    const char *x_label = "FRAME";
    draw_text(&c, (long)left + (long)plot_w / 2 - text_width(x_label) / 2, top + plot_h + 14 + GLYPH_HEIGHT, x_label,
              black);
    /* legend: the ramp bottom (low) to top (high), labels at 1-2-5 values */
    long legend_x = (long)left + plot_w + legend_gap;
    for (unsigned j = 0; j < plot_h; j++) {
        unsigned char rgb[3];
        ramp(1.0 - (double)j / (plot_h > 1 ? plot_h - 1 : 1), rgb);
        fill_rect(&c, legend_x, top + j, legend_w, 1, rgb);
    }
    double decade = pow(10, floor(log10(low)));
    long last_y = -1000;
    for (int i = 0; i < 64; i++) {
        static const double multiples[3] = {1, 2, 5};
        double v = decade * pow(10, i / 3) * multiples[i % 3];
        if (v > high * 1.0001) break;
        if (v < low * 0.9999) continue;
        long y = (long)top + (long)lround((1 - scale_position(v, low, high)) * (plot_h - 1));
        if (last_y > -1000 && last_y - y < GLYPH_HEIGHT + 2) continue;
        last_y = y;
        fill_rect(&c, legend_x + legend_w, y, 5, 1, black);
        snprintf(label, sizeof label, "%g", v);
        draw_text(&c, legend_x + legend_w + 8, y - GLYPH_HEIGHT / 2, label, black);
    }
    if (value_label) draw_text(&c, legend_x - 4, top - GLYPH_HEIGHT - 8, value_label, black);
    *rgba = c.rgba;
    *width = c.width;
    *height = c.height;
    return LK_OK;
}
