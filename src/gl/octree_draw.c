/* SPDX-License-Identifier: MIT */
/* An octree drawn as splats under a point budget (lk_render_octree): the
 * orbit camera of the options around the octree's bounds, the nodes
 * lk_octree_select picks for it, loaded into one point set with adaptive
 * radii (lk_octree_load_selection), then lk_render_points with the same
 * bounds (so the same camera). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"

/* C = A * B for column-major 4x4 matrices. */
static void multiply(const float a[16], const float b[16], double c[16])
{
    for (int col = 0; col < 4; col++)
        for (int row = 0; row < 4; row++) {
            double sum = 0;
            for (int k = 0; k < 4; k++) sum += (double)a[k * 4 + row] * (double)b[col * 4 + k];
            c[col * 4 + row] = sum;
        }
}

lk_status lk_render_octree(lk_renderer *renderer, const lk_octree *octree, const lk_render_options *options,
                           const lk_octree_select_options *select, lk_render_octree_stats *stats, lk_error *error)
{
    if (stats) memset(stats, 0, sizeof *stats);
    if (!renderer || !octree) return lk_error_set(error, LK_ERR_INVALID, "lk_render_octree: no renderer or octree");
    const lk_octree_info *info = lk_octree_get_info(octree);
    if (!info->has_normals)
        return lk_error_set(error, LK_ERR_INVALID,
                            "the octree has no normals, which splats need (build it with `lodkit octree "
                            "--estimate-normals`)");
    lk_render_options view_options;
    if (options)
        view_options = *options;
    else
        lk_render_options_default(&view_options);
    /* Clip lines come with the nodes when the octree has them (estimating
     * them here would take a nearest-neighbour pass over the selection
     * every frame, seconds for a million points); otherwise whole discs. */
    int clipped = view_options.clip_borders && info->has_clips;
    view_options.clip_borders = clipped;
    if (!view_options.use_bounds) {
        view_options.use_bounds = 1;
        for (int k = 0; k < 3; k++) {
            view_options.bounds_min[k] = (float)(info->min[k] - info->offset[k]);
            view_options.bounds_max[k] = (float)(info->max[k] - info->offset[k]);
        }
    }
    lk__camera camera;
    lk__camera_setup(&view_options, NULL, NULL, renderer->width, renderer->height, &camera);
    lk_octree_view view;
    memset(&view, 0, sizeof view);
    for (int k = 0; k < 3; k++) view.eye[k] = camera.eye[k];
    /* the camera's own (sanitised) field of view: projection[5] = 1 / tan(fov_y / 2) */
    view.fov_y = 2.0 * atan(1.0 / (double)camera.projection[5]) * 180.0 / 3.14159265358979323846;
    view.viewport_height = renderer->height;
    view.has_clip = 1;
    multiply(camera.projection, camera.view, view.clip);

    double start = lk__now();
    size_t *nodes = NULL, node_count = 0;
    uint64_t point_count = 0;
    lk_status status = lk_octree_select(octree, &view, select, &nodes, &node_count, &point_count, error);
    double selected = lk__now();
    if (status == LK_OK && point_count == 0) {
        const lk_octree_node *root = lk_octree_node_at(octree, 0);
        status = lk_error_set(error, LK_ERR_LIMIT,
                              "no points to draw: the point budget (%llu) is below the root node's %llu points",
                              (unsigned long long)(select ? select->point_budget : 1000000),
                              (unsigned long long)(root ? root->points : 0));
    }
    lk_mesh all;
    lk_mesh_init(&all);
    float *clips = NULL;
    uint64_t bytes = 0;
    if (status == LK_OK)
        status = lk_octree_load_selection(octree, nodes, node_count, &all, clipped ? &clips : NULL, error);
    for (size_t i = 0; status == LK_OK && i < node_count; i++) bytes += lk_octree_node_at(octree, nodes[i])->length;
    double loaded = lk__now();
    free(nodes);
    lk_render_stats draw_stats;
    memset(&draw_stats, 0, sizeof draw_stats);
    if (status == LK_OK) status = lk__render_points_clipped(renderer, &all, clips, &view_options, &draw_stats, error);
    lk_mesh_free(&all);
    free(clips);
    if (status == LK_OK && stats) {
        stats->nodes = node_count;
        stats->points = point_count;
        stats->bytes = bytes;
        stats->select_milliseconds = 1000.0 * (selected - start);
        stats->load_milliseconds = 1000.0 * (loaded - selected);
        stats->draw_milliseconds = draw_stats.milliseconds;
    }
    return status;
}
