/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the point octree's index parser (src/octree.c,
 * lk_octree_open_memory): the input is an octree.json. Any input must give
 * an error with a message and no octree, or an octree whose nodes keep the
 * contract: names "r" + digits 0-7 matching their level, sorted by level
 * then name, length = points * stride, offset + length without overflow,
 * node cubes inside the root cube, point counts summing to the total; and
 * a selection for a view (lk_octree_select) that stays within the budget,
 * takes the root first and no node twice; children masks of 8 bits; and
 * loading a selection without the data file refused with a message. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "lodkit.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    lk_octree *octree = NULL;
    lk_error error = {0};
    lk_status status = lk_octree_open_memory((const char *)data, size, "fuzz.json", &octree, &error);
    if (status != LK_OK) {
        if (octree || error.message[0] == '\0') abort();
        return 0;
    }
    const lk_octree_info *info = lk_octree_get_info(octree);
    if (info->node_count == 0 || info->stride < 16) abort();
    uint64_t total = 0;
    for (size_t i = 0; i < info->node_count; i++) {
        const lk_octree_node *node = lk_octree_node_at(octree, i);
        if (!node || strlen(node->name) != node->level + 1 || node->name[0] != 'r') abort();
        if (node->length != node->points * info->stride || node->offset + node->length < node->offset) abort();
        for (int k = 0; k < 3; k++)
            if (!(node->min[k] >= info->offset[k] - 1e-9 * fabs(info->offset[k]) - 1e-9) ||
                !(node->max[k] > node->min[k]))
                abort();
        if (i > 0 && strcmp(lk_octree_node_at(octree, i - 1)->name, node->name) == 0) abort();
        if (node->children > 255) abort();
        total += node->points;
    }
    if (lk_octree_node_at(octree, info->node_count) != NULL || total != info->points) abort();
    /* a view from outside the root cube, the budget a few times the root's points */
    lk_octree_view view;
    memset(&view, 0, sizeof view);
    for (int k = 0; k < 3; k++) view.eye[k] = 1.5 * info->cube_size;
    view.fov_y = 35;
    view.viewport_height = 600;
    lk_octree_select_options select;
    lk_octree_select_options_default(&select);
    select.point_budget = 3 * lk_octree_node_at(octree, 0)->points + 1000;
    size_t *taken = NULL, taken_count = 0;
    uint64_t taken_points = 0, sum = 0;
    if (lk_octree_select(octree, &view, &select, &taken, &taken_count, &taken_points, &error) == LK_OK) {
        if (taken_points > select.point_budget || taken_count > info->node_count || (taken_count && taken[0] != 0))
            abort();
        unsigned char *seen = calloc(info->node_count, 1);
        if (!seen) abort();
        for (size_t i = 0; i < taken_count; i++) {
            if (taken[i] >= info->node_count || seen[taken[i]]) abort();
            seen[taken[i]] = 1;
            sum += lk_octree_node_at(octree, taken[i])->points;
        }
        if (sum != taken_points) abort();
        free(seen);
        /* no data file: loading the selection is refused with a message */
        lk_mesh drawn;
        if (taken_count && (lk_octree_load_selection(octree, taken, taken_count, &drawn, NULL, &error) == LK_OK ||
                            error.message[0] == '\0'))
            abort();
        lk_free(taken);
    } else if (error.message[0] == '\0')
        abort();
    /* no data file: loading is refused with a message */
    lk_mesh points;
    if (lk_octree_load_node(octree, 0, &points, &error) == LK_OK || error.message[0] == '\0') abort();
    lk_octree_close(octree);
    return 0;
}
