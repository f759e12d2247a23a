/* SPDX-License-Identifier: MIT */
/* Progressive meshes: a QEM edge-collapse history turned into a base mesh
 * and vertex splits (Hoppe 1996), numbered so that every level is a prefix.
 *
 * Numbering. Base vertices come first (in input order), then split k
 * creates vertex base_vertex_count + k. Base triangles come first (in input
 * order), then the triangles each split brings back. A corner keeps its
 * full-level vertex; at a coarser level a vertex that does not exist yet
 * stands for its ancestor, found by following `kept` links, which always
 * point to smaller indices (p exists before q is split off it). So a level
 * is extracted in O(V + T) with no per-level storage. */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

void lk_progressive_options_default(lk_progressive_options *options)
{
    memset(options, 0, sizeof *options);
    options->base_ratio = 0.05;
    lk_simplify_options_default(&options->simplify);
}

void lk_progressive_mesh_free(lk_progressive_mesh *pm)
{
    if (!pm) return;
    free(pm->base_positions);
    free(pm->indices);
    free(pm->splits);
    free(pm->vertex_order);
    free(pm->triangle_order);
    memset(pm, 0, sizeof *pm);
}

size_t lk_progressive_mesh_level_triangles(const lk_progressive_mesh *pm, size_t level)
{
    if (level >= pm->split_count) return pm->triangle_count;
    return pm->splits[level].first_triangle;
}

/* The input triangles that lk_simplify keeps (it drops degenerate triangles
 * and later copies of the same three vertices), in input order: the QEM
 * history numbers triangles by their rank in this list. */
static lk_status surviving_triangles(const lk_mesh *mesh, uint32_t **out, size_t *out_count, lk_error *error)
{
    uint32_t *kept = lk__malloc_array(mesh->triangle_count ? mesh->triangle_count : 1, sizeof *kept);
    size_t count = kept ? lk__unique_triangles(mesh, true, kept) : SIZE_MAX;
    if (count == SIZE_MAX) {
        free(kept);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory listing %zu triangles", mesh->triangle_count);
    }
    *out = kept;
    *out_count = count;
    return LK_OK;
}

/* The simplification's progress as the first 90% of the build's. */
typedef struct build_progress {
    lk_progress_fn fn;
    void *user;
} build_progress;

static int simplify_progress(void *user, double fraction, const char *stage)
{
    const build_progress *p = user;
    return p->fn(p->user, 0.9 * fraction, stage);
}

lk_status lk_progressive_mesh_build(const lk_mesh *mesh, const lk_progressive_options *options,
                                    lk_progressive_mesh *out, lk_progress_fn progress, void *progress_user,
                                    lk_error *error)
{
    memset(out, 0, sizeof *out);
    lk_progressive_options defaults;
    if (!options) {
        lk_progressive_options_default(&defaults);
        options = &defaults;
    }
    if (options->base_triangles == 0 && !(options->base_ratio > 0 && options->base_ratio <= 1))
        return lk_error_set(error, LK_ERR_INVALID, "base ratio must be in (0, 1], got %g", options->base_ratio);
    if (options->simplify.pair_distance != 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "progressive meshes need edge collapses only (pair distance must be 0)");

    lk_simplify_options simplify = options->simplify;
    simplify.target_ratio = options->base_triangles ? 0 : options->base_ratio;
    simplify.target_triangles = options->base_triangles;
    simplify.target_vertices = 0;
    simplify.max_error = 0;
    simplify.flags |= LK_SIMPLIFY_RECORD;
    if (progress && progress(progress_user, 0.0, "simplify")) return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    build_progress scaled = {progress, progress_user};
    lk_simplify_result history;
    lk_status status =
        lk_simplify(mesh, LK_SIMPLIFY_QEM, &simplify, &history, progress ? simplify_progress : NULL, &scaled, error);
    if (status != LK_OK) return status;

    uint32_t *clean_triangles = NULL; /* history triangle id -> input triangle */
    size_t clean_count = 0;
    status = surviving_triangles(mesh, &clean_triangles, &clean_count, error);
    if (status != LK_OK) {
        lk_simplify_result_free(&history);
        return status;
    }

    size_t vertex_total = mesh->vertex_count, collapse_count = history.collapse_count;
    uint32_t *pm_vertex = lk__malloc_array(vertex_total, sizeof *pm_vertex); /* input -> PM */
    unsigned char *used = lk__calloc_array(vertex_total, 1);
    unsigned char *vanished = lk__calloc_array(clean_count, 1);
    float *current = lk__malloc_array(vertex_total, 3 * sizeof *current);
    if (!pm_vertex || !used || !vanished || !current) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory building a progressive mesh");
        goto done;
    }
    memcpy(current, mesh->positions, vertex_total * 3 * sizeof *current);
    for (size_t i = 0; i < clean_count; i++)
        for (int k = 0; k < 3; k++) used[mesh->indices[3 * (size_t)clean_triangles[i] + k]] = 1;

    /* Walk the collapses forward to learn where p and q stood just before
     * each one: that is what the inverse split must restore. */
    out->splits = lk__calloc_array(collapse_count, sizeof *out->splits);
    if (!out->splits) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu vertex splits", collapse_count);
        goto done;
    }
    for (size_t c = 0; c < collapse_count; c++) {
        const lk_collapse *collapse = &history.collapses[c];
        lk_vertex_split *split = &out->splits[collapse_count - 1 - c];
        memcpy(split->position, current + 3 * (size_t)collapse->removed, sizeof split->position);
        memcpy(split->kept_position, current + 3 * (size_t)collapse->kept, sizeof split->kept_position);
        memcpy(current + 3 * (size_t)collapse->kept, collapse->position, sizeof collapse->position);
        split->error = collapse->error;
        used[collapse->removed] = 2; /* a split vertex, numbered below */
        for (uint32_t i = 0; i < collapse->vanished_count; i++)
            vanished[history.vanished[collapse->first_vanished + i]] = 1;
    }

    size_t base_vertex_count = 0;
    for (size_t v = 0; v < vertex_total; v++)
        if (used[v] == 1)
            pm_vertex[v] = (uint32_t)base_vertex_count++;
        else
            pm_vertex[v] = UINT32_MAX;
    size_t vertex_count = base_vertex_count + collapse_count;
    out->vertex_count = vertex_count;
    out->base_vertex_count = base_vertex_count;
    out->split_count = collapse_count;
    out->triangle_count = clean_count;
    out->diagonal = history.diagonal;
    out->base_positions = lk__malloc_array(base_vertex_count, 3 * sizeof(float));
    out->vertex_order = lk__malloc_array(vertex_count, sizeof(uint32_t));
    out->indices = lk__malloc_array(clean_count, 3 * sizeof(uint32_t));
    out->triangle_order = lk__malloc_array(clean_count, sizeof(uint32_t));
    if (!out->base_positions || !out->vertex_order || !out->indices || !out->triangle_order) {
        status =
            lk_error_set(error, LK_ERR_NOMEM, "out of memory for a progressive mesh of %zu vertices", vertex_count);
        goto done;
    }
    for (size_t v = 0; v < vertex_total; v++)
        if (used[v] == 1) {
            out->vertex_order[pm_vertex[v]] = (uint32_t)v;
            memcpy(out->base_positions + 3 * (size_t)pm_vertex[v], current + 3 * v, 3 * sizeof(float));
        }
    for (size_t k = 0; k < collapse_count; k++) {
        uint32_t removed = history.collapses[collapse_count - 1 - k].removed;
        pm_vertex[removed] = (uint32_t)(base_vertex_count + k);
        out->vertex_order[base_vertex_count + k] = removed;
    }

    /* Triangles: the base mesh's in input order, then each split's. */
    size_t triangle_index = 0;
    for (size_t i = 0; i < clean_count; i++)
        if (!vanished[i]) out->triangle_order[triangle_index++] = clean_triangles[i];
    out->base_triangle_count = triangle_index;
    for (size_t k = 0; k < collapse_count; k++) {
        const lk_collapse *collapse = &history.collapses[collapse_count - 1 - k];
        lk_vertex_split *split = &out->splits[k];
        split->kept = pm_vertex[collapse->kept];
        split->first_triangle = (uint32_t)triangle_index;
        split->triangle_count = collapse->vanished_count;
        for (uint32_t i = 0; i < collapse->vanished_count; i++)
            out->triangle_order[triangle_index++] = clean_triangles[history.vanished[collapse->first_vanished + i]];
    }
    if (triangle_index != clean_count) {
        status = lk_error_set(error, LK_ERR_INVALID, "internal error: the collapse history covers %zu of %zu triangles",
                              triangle_index, clean_count);
        goto done;
    }
    for (size_t t = 0; t < clean_count; t++)
        for (int k = 0; k < 3; k++)
            out->indices[3 * t + k] = pm_vertex[mesh->indices[3 * (size_t)out->triangle_order[t] + k]];

done:
    free(pm_vertex);
    free(used);
    free(vanished);
    free(current);
    free(clean_triangles);
    lk_simplify_result_free(&history);
    if (status != LK_OK)
        lk_progressive_mesh_free(out);
    else if (progress)
        (void)progress(progress_user, 1.0, "splits"); /* done: too late to cancel */
    return status;
}

lk_status lk_progressive_mesh_level(const lk_progressive_mesh *pm, size_t level, lk_mesh *out, lk_error *error)
{
    if (level > pm->split_count) level = pm->split_count;
    size_t vertex_count = pm->base_vertex_count + level;
    size_t triangle_count = lk_progressive_mesh_level_triangles(pm, level);
    uint32_t *ancestor = lk__malloc_array(pm->vertex_count, sizeof *ancestor);
    if (!ancestor) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu vertices", pm->vertex_count);
    lk_mesh mesh;
    lk_status status = lk_mesh_alloc(&mesh, vertex_count, triangle_count, 0, error);
    if (status != LK_OK) {
        free(ancestor);
        return status;
    }
    memcpy(mesh.positions, pm->base_positions, pm->base_vertex_count * 3 * sizeof(float));
    for (size_t k = 0; k < level; k++) {
        const lk_vertex_split *split = &pm->splits[k];
        memcpy(mesh.positions + 3 * (pm->base_vertex_count + k), split->position, 3 * sizeof(float));
        memcpy(mesh.positions + 3 * (size_t)split->kept, split->kept_position, 3 * sizeof(float));
    }
    /* kept < v, so one increasing pass resolves every chain */
    for (size_t v = 0; v < pm->vertex_count; v++)
        ancestor[v] = v < vertex_count ? (uint32_t)v : ancestor[pm->splits[v - pm->base_vertex_count].kept];
    for (size_t i = 0; i < 3 * triangle_count; i++) mesh.indices[i] = ancestor[pm->indices[i]];
    free(ancestor);
    *out = mesh;
    return LK_OK;
}
