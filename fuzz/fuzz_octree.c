/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the point octree's index parser (src/octree.c,
 * lk_octree_open_memory): the input is an octree.json. Any input must give
 * an error with a message and no octree, or an octree whose nodes keep the
 * contract: names "r" + digits 0-7 matching their level, sorted by level
 * then name, length = points * stride, offset + length without overflow,
 * node cubes inside the root cube, point counts summing to the total. */
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
        total += node->points;
    }
    if (lk_octree_node_at(octree, info->node_count) != NULL || total != info->points) abort();
    /* no data file: loading is refused with a message */
    lk_mesh points;
    if (lk_octree_load_node(octree, 0, &points, &error) == LK_OK || error.message[0] == '\0') abort();
    lk_octree_close(octree);
    return 0;
}
