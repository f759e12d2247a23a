/* SPDX-License-Identifier: MIT */
/* lk_simplify: option checks, input clean-up and dispatch to the QEM and
 * clustering back ends. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void lk_simplify_options_default(lk_simplify_options *options)
{
    memset(options, 0, sizeof *options);
    options->feature_angle = 40.0;
    options->feature_weight = 1.0;
    options->attribute_weight = 1.0;
    options->slice_count = 0;           /* wavelet: automatic (see lodkit.h) */
    options->slice_axis = LK_AXIS_AUTO; /* wavelet: the shortest bounding-box side */
}

void lk_simplify_result_free(lk_simplify_result *result)
{
    if (!result) return;
    lk_mesh_free(&result->mesh);
    free(result->vertex_map);
    free(result->collapses);
    free(result->vanished);
    memset(result, 0, sizeof *result);
}

static lk_status check_options(const lk_simplify_options *options, lk_error *error)
{
    if (!(options->target_ratio >= 0 && options->target_ratio <= 1))
        return lk_error_set(error, LK_ERR_INVALID, "target ratio must be in (0, 1], got %g", options->target_ratio);
    if (!(options->max_error >= 0) || !isfinite(options->max_error))
        return lk_error_set(error, LK_ERR_INVALID, "max error must be a finite number >= 0");
    if (options->target_ratio == 0 && options->target_triangles == 0 && options->target_vertices == 0 &&
        options->max_error == 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "no target: set a ratio, a triangle or vertex count, or a maximum error");
    if (options->thread_count > 64)
        return lk_error_set(error, LK_ERR_INVALID, "thread count must be at most 64, got %llu",
                            (unsigned long long)options->thread_count);
    if (!(options->pair_distance >= 0) || !isfinite(options->pair_distance))
        return lk_error_set(error, LK_ERR_INVALID, "pair distance must be a finite number >= 0");
    if (!(options->feature_angle >= 0 && options->feature_angle <= 180))
        return lk_error_set(error, LK_ERR_INVALID, "feature angle must be in [0, 180] degrees");
    if (!(options->feature_weight >= 0) || !isfinite(options->feature_weight) || !(options->attribute_weight >= 0) ||
        !isfinite(options->attribute_weight))
        return lk_error_set(error, LK_ERR_INVALID, "weights must be finite numbers >= 0");
    return LK_OK;
}

/* Whether some triangle has three distinct corners. */
static bool has_surface(const lk_mesh *mesh)
{
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *v = mesh->indices + 3 * t;
        if (v[0] != v[1] && v[1] != v[2] && v[0] != v[2]) return true;
    }
    return false;
}

/* The end of every method: the time taken and the last progress report,
 * or no result at all. */
static lk_status finish(lk_status status, lk_simplify_result *result, double start, lk_progress_fn progress,
                        void *progress_user)
{
    if (status != LK_OK) {
        lk_simplify_result_free(result);
        return status;
    }
    result->seconds = lk__now() - start;
    if (progress) (void)progress(progress_user, 1.0, "done"); /* done: too late to cancel */
    return LK_OK;
}

lk_status lk_simplify(const lk_mesh *mesh, lk_simplify_method method, const lk_simplify_options *options,
                      lk_simplify_result *result, lk_progress_fn progress, void *progress_user, lk_error *error)
{
    memset(result, 0, sizeof *result);
    lk_simplify_options defaults;
    if (!options) {
        lk_simplify_options_default(&defaults);
        options = &defaults;
    }
    lk_status status = check_options(options, error);
    if (status != LK_OK) return status;
    status = lk_mesh_validate(mesh, error);
    if (status != LK_OK) return status;
    if (mesh->triangle_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "cannot simplify a point set (%zu points, no triangles)",
                            mesh->vertex_count);
    /* Every method reports 0 first and 1 last, whatever it reports between. */
    if (progress && progress(progress_user, 0.0, "simplify")) return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    double start = lk__now();
    result->diagonal = lk_mesh_bounds(mesh, NULL, NULL); /* cleaning keeps every vertex */
    if (method == LK_SIMPLIFY_UNIFORM || method == LK_SIMPLIFY_FLOATING) {
        /* Clustering ignores degenerate triangles and merges repeated ones
         * itself: no cleaned copy (which would cost more than clustering). */
        if (!has_surface(mesh))
            return lk_error_set(error, LK_ERR_INVALID, "every triangle is degenerate: nothing to simplify");
        status = method == LK_SIMPLIFY_UNIFORM
                     ? lk__simplify_uniform(mesh, options, result, progress, progress_user, error)
                     : lk__simplify_floating(mesh, options, result, progress, progress_user, error);
        return finish(status, result, start, progress, progress_user);
    }
    if (method == LK_SIMPLIFY_QEM && options->thread_count > 1 && mesh->triangle_count >= LK_SIMPLIFY_PARALLEL_MIN &&
        !(options->flags & LK_SIMPLIFY_RECORD)) {
        /* each slab is cleaned on its own thread: no cleaned copy of the whole */
        status = lk__simplify_qem_parallel(mesh, options, (unsigned)options->thread_count, result, progress,
                                           progress_user, error);
        return finish(status, result, start, progress, progress_user);
    }
    /* Work without degenerate or duplicate triangles: they carry no
     * surface and would only confuse adjacency. The methods read the mesh
     * only, so the view shares the vertex arrays (a copy would add 24 bytes
     * per triangle to the peak memory of a large run). */
    lk_mesh clean;
    uint32_t *clean_indices;
    lk__memory_trace("simplify: input");
    status = lk__mesh_clean_view(mesh, &clean, &clean_indices, error);
    if (status != LK_OK) return status;
    if (status == LK_OK && clean.triangle_count == 0)
        status = lk_error_set(error, LK_ERR_INVALID, "every triangle is degenerate: nothing to simplify");
    if (status == LK_OK) {
        switch (method) {
        case LK_SIMPLIFY_QEM: status = lk__simplify_qem(&clean, options, result, progress, progress_user, error); break;
        case LK_SIMPLIFY_WAVELET:
            status = lk__simplify_wavelet(&clean, options, result, progress, progress_user, error);
            break;
        default: status = lk_error_set(error, LK_ERR_INVALID, "unknown simplification method %d", (int)method);
        }
    }
    free(clean_indices);
    return finish(status, result, start, progress, progress_user);
}
