/* SPDX-License-Identifier: MIT */
/* An octree drawn as splats under a point budget (lk_render_octree): the
 * orbit camera of the options around the octree's bounds, the nodes
 * lk_octree_select picks for it, loaded one by one into one point set,
 * then lk_render_points with the same bounds (so the same camera). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"

/* Appends `node` (loaded) at point `at` of `all`. */
static void append_points(lk_mesh *all, size_t at, const lk_mesh *node)
{
    size_t n = node->vertex_count;
    memcpy(all->positions + 3 * at, node->positions, 3 * n * sizeof *all->positions);
    if (all->normals) memcpy(all->normals + 3 * at, node->normals, 3 * n * sizeof *all->normals);
    if (all->colors) memcpy(all->colors + 4 * at, node->colors, 4 * n * sizeof *all->colors);
    memcpy(all->radii + at, node->radii, n * sizeof *all->radii);
}

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
    /* Clip lines need each point's neighbours: a k-nearest-neighbour pass
     * over the whole selection every frame, seconds for a million points.
     * The octree's nodes do not carry them (yet): whole discs. */
    view_options.clip_borders = 0;
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
    if (status == LK_OK && point_count > LK_MAX_ELEMENTS)
        status = lk_error_set(error, LK_ERR_LIMIT, "%llu points selected: more than one draw takes",
                              (unsigned long long)point_count);
    if (status == LK_OK)
        status = lk_mesh_alloc(&all, (size_t)point_count, 0,
                               LK_ATTR_NORMALS | LK_ATTR_RADII | (info->has_colors ? LK_ATTR_COLORS : 0u), error);
    uint64_t bytes = 0;
    size_t filled = 0;
    for (size_t i = 0; status == LK_OK && i < node_count; i++) {
        lk_mesh node;
        status = lk_octree_load_node(octree, nodes[i], &node, error);
        if (status != LK_OK) break;
        append_points(&all, filled, &node);
        filled += node.vertex_count;
        bytes += lk_octree_node_at(octree, nodes[i])->length;
        lk_mesh_free(&node);
    }
    double loaded = lk__now();
    free(nodes);
    lk_render_stats draw_stats;
    memset(&draw_stats, 0, sizeof draw_stats);
    if (status == LK_OK) status = lk_render_points(renderer, &all, &view_options, &draw_stats, error);
    lk_mesh_free(&all);
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
