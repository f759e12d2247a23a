/* SPDX-License-Identifier: MIT */
/* Which octree nodes to draw for one view under a point budget
 * (lk_octree_select; lodkit.h, "Choosing the nodes to draw"): Potree's
 * traversal, a max-heap of candidate nodes keyed by projected spacing.
 * Only the index is read. The web viewer (web/octree_view.js) follows the
 * same rule, so `lodkit splat` on an octree shows what the viewer shows. */
#include "internal.h"
#include "octree_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void lk_octree_select_options_default(lk_octree_select_options *options)
{
    if (!options) return;
    memset(options, 0, sizeof *options);
    options->point_budget = 1000000;
    options->min_spacing_pixels = 1.0;
}

typedef struct candidate {
    double priority; /* projected spacing in pixels */
    size_t node;
} candidate;

typedef struct heap {
    candidate *items;
    size_t count, capacity;
} heap;

static int heap_push(heap *h, candidate c)
{
    if (h->count == h->capacity) {
        size_t capacity = h->capacity ? 2 * h->capacity : 64;
        candidate *grown = lk__realloc_array(h->items, capacity, sizeof *grown);
        if (!grown) return 0;
        h->items = grown;
        h->capacity = capacity;
    }
    size_t i = h->count++;
    /* ties go to the lower node index (parents, then names), so the order is deterministic */
    while (i > 0) {
        size_t parent = (i - 1) / 2;
        const candidate *p = &h->items[parent];
        if (p->priority > c.priority || (p->priority == c.priority && p->node < c.node)) break;
        h->items[i] = *p;
        i = parent;
    }
    h->items[i] = c;
    return 1;
}

static int before(const candidate *a, const candidate *b)
{
    return a->priority > b->priority || (a->priority == b->priority && a->node < b->node);
}

static candidate heap_pop(heap *h)
{
    candidate top = h->items[0], last = h->items[--h->count];
    size_t i = 0;
    for (;;) {
        size_t child = 2 * i + 1;
        if (child >= h->count) break;
        if (child + 1 < h->count && before(&h->items[child + 1], &h->items[child])) child++;
        if (!before(&h->items[child], &last)) break;
        h->items[i] = h->items[child];
        i = child;
    }
    if (h->count > 0) h->items[i] = last;
    return top;
}

/* 1 when the box [lo, hi] is at least partly inside the six planes of the
 * clip matrix (Gribb & Hartmann; column-major m[col * 4 + row]): for each
 * plane, the box corner farthest along its normal must be on the inside. */
static int box_in_frustum(const double m[16], const double lo[3], const double hi[3])
{
    for (int plane = 0; plane < 6; plane++) {
        int axis_row = plane / 2;
        double sign = (plane % 2) ? -1.0 : 1.0;
        double p[4];
        for (int col = 0; col < 4; col++) p[col] = m[col * 4 + 3] + sign * m[col * 4 + axis_row];
        double far_corner = p[3];
        for (int k = 0; k < 3; k++) far_corner += p[k] * (p[k] >= 0 ? hi[k] : lo[k]);
        if (far_corner < 0) return 0;
    }
    return 1;
}

/* Projected spacing of node `index` in pixels (DBL_MAX with the eye inside
 * its bounding sphere). */
static double projected_spacing(const lk_octree *octree, size_t index, const lk_octree_view *view,
                                double pixels_per_unit)
{
    const lk_octree_info *info = lk_octree_get_info(octree);
    const lk_octree_node *node = lk_octree_node_at(octree, index);
    double squared = 0, half_side = 0.5 * (node->max[0] - node->min[0]);
    for (int k = 0; k < 3; k++) {
        /* node cubes are absolute; the view is relative to the offset */
        double centre = 0.5 * (node->min[k] + node->max[k]) - info->offset[k];
        double d = centre - view->eye[k];
        squared += d * d;
    }
    double distance = sqrt(squared), sphere = half_side * sqrt(3.0);
    if (distance <= sphere) return DBL_MAX;
    return ldexp(info->spacing, -(int)node->level) / distance * pixels_per_unit;
}

/* First index of level `level` in the sorted node list (by level, then
 * name), or node_count. */
static size_t level_start(const lk_octree *octree, size_t count, unsigned level)
{
    size_t lo = 0, hi = count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (lk_octree_node_at(octree, mid)->level < level)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

lk_status lk_octree_select(const lk_octree *octree, const lk_octree_view *view, const lk_octree_select_options *options,
                           size_t **nodes, size_t *node_count, uint64_t *points, lk_error *error)
{
    if (nodes) *nodes = NULL;
    if (node_count) *node_count = 0;
    if (points) *points = 0;
    if (!octree || !view || !nodes || !node_count)
        return lk_error_set(error, LK_ERR_INVALID, "lk_octree_select: octree, view, nodes and node_count are needed");
    lk_octree_select_options defaults;
    if (!options) {
        lk_octree_select_options_default(&defaults);
        options = &defaults;
    }
    if (!(view->fov_y > 0 && view->fov_y < 180) || view->viewport_height == 0)
        return lk_error_set(error, LK_ERR_INVALID, "octree view: field of view %g degrees or viewport height %u",
                            view->fov_y, view->viewport_height);
    if (!isfinite(view->eye[0]) || !isfinite(view->eye[1]) || !isfinite(view->eye[2]))
        return lk_error_set(error, LK_ERR_RANGE, "octree view: the eye is not a finite point");
    if (!(options->min_spacing_pixels >= 0) || !isfinite(options->min_spacing_pixels))
        return lk_error_set(error, LK_ERR_INVALID, "octree selection: min_spacing_pixels %g is not >= 0",
                            options->min_spacing_pixels);
    const lk_octree_info *info = lk_octree_get_info(octree);
    size_t count = info->node_count;
    if (count == 0) return LK_OK;
    double pixels_per_unit = 0.5 * view->viewport_height / tan(0.5 * view->fov_y * 3.14159265358979323846 / 180.0);

    heap candidates = {0};
    size_t *taken = NULL, taken_count = 0, taken_capacity = 0;
    uint64_t taken_points = 0;
    lk_status status = LK_OK;
    if (!heap_push(&candidates, (candidate){projected_spacing(octree, 0, view, pixels_per_unit), 0}))
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the octree selection");
    while (status == LK_OK && candidates.count > 0) {
        candidate next = heap_pop(&candidates);
        const lk_octree_node *node = lk_octree_node_at(octree, next.node);
        if (node->level > 0 && next.priority < options->min_spacing_pixels) continue;
        if (taken_points + node->points > options->point_budget) break; /* Potree: the front stops here */
        if (taken_count == taken_capacity) {
            size_t capacity = taken_capacity ? 2 * taken_capacity : 64;
            size_t *grown = lk__realloc_array(taken, capacity, sizeof *grown);
            if (!grown) {
                status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the octree selection");
                break;
            }
            taken = grown;
            taken_capacity = capacity;
        }
        taken[taken_count++] = next.node;
        taken_points += node->points;
        /* The children: level + 1, names starting with this node's, contiguous
         * in the sorted list. */
        size_t name_length = strlen(node->name);
        size_t first = level_start(octree, count, node->level + 1), last = level_start(octree, count, node->level + 2);
        size_t lo = first, hi = last;
        while (lo < hi) { /* first child name >= this node's name */
            size_t mid = lo + (hi - lo) / 2;
            if (strcmp(lk_octree_node_at(octree, mid)->name, node->name) < 0)
                lo = mid + 1;
            else
                hi = mid;
        }
        for (size_t c = lo; c < last && status == LK_OK; c++) {
            const lk_octree_node *child = lk_octree_node_at(octree, c);
            if (strncmp(child->name, node->name, name_length) != 0) break;
            if (view->has_clip) {
                double lo_box[3], hi_box[3];
                for (int k = 0; k < 3; k++) {
                    lo_box[k] = child->min[k] - info->offset[k];
                    hi_box[k] = child->max[k] - info->offset[k];
                }
                if (!box_in_frustum(view->clip, lo_box, hi_box)) continue;
            }
            if (!heap_push(&candidates, (candidate){projected_spacing(octree, c, view, pixels_per_unit), c}))
                status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the octree selection");
        }
    }
    free(candidates.items);
    if (status != LK_OK) {
        free(taken);
        return status;
    }
    *nodes = taken;
    *node_count = taken_count;
    if (points) *points = taken_points;
    return LK_OK;
}

/* ---- loading a selection with adaptive radii ---------------------------------- */

/* What a drawn node knows of its children for the walk: per child digit,
 * the slot of the child among the drawn nodes, ABSENT (no such child: no
 * point of the cloud lies in that cube but the node's and its ancestors')
 * or NOT_DRAWN. */
enum { CHILD_ABSENT = -1, CHILD_NOT_DRAWN = -2 };

typedef struct drawn_node {
    long child[8];
    double centre[3]; /* relative to info.offset */
    double spacing;
} drawn_node;

/* A drawn node's index in the octree and its slot in `nodes`, sorted by
 * index to find a child's slot. */
typedef struct node_slot {
    size_t index, slot;
} node_slot;

static int compare_slots(const void *a, const void *b)
{
    size_t x = ((const node_slot *)a)->index, y = ((const node_slot *)b)->index;
    return (x > y) - (x < y);
}

/* How much wider than the spacing of the deepest drawn node a point of one
 * of its ancestors is drawn where that node's child is missing. The node's
 * own points keep its spacing (as drawn alone), the ancestors' shrink to
 * this: a Poisson-disk sample at spacing s lies within s of every input
 * point, but not of the surface between them, and with the ancestors at
 * exactly s the bunny's silhouette lost 0.6-1% of its pixels at a quarter
 * of its points (bench_radii, docs/benchmarks.md: 99.17% -> 99.55%
 * covered with 1.5, 98.97% -> 99.75% for the million-point bunny; the
 * hippo at a quarter 99.25%). All points at 1.25 covered as well but drew
 * the frontier nodes' points, most of a view's, 1.25 times wider: more
 * spill and 1.5 times the pixels. */
#define OT_ANCESTOR_FLOOR 1.5

/* The radius floor of a point at `position` drawn in drawn node `slot`:
 * down the drawn children whose cube holds it, the spacing of the first
 * node whose child there exists but is not drawn (OT_ANCESTOR_FLOOR times
 * it when that node is below the point's), or 0 where the path ends in a
 * cube with no child. */
static double walk_floor(const drawn_node *drawn, long slot, const float position[3])
{
    double factor = 1.0;
    for (;;) {
        const drawn_node *node = &drawn[slot];
        int digit = 0;
        for (int k = 0; k < 3; k++)
            if ((double)position[k] >= node->centre[k]) digit |= 4 >> k;
        long next = node->child[digit];
        if (next == CHILD_ABSENT) return 0.0;
        if (next == CHILD_NOT_DRAWN) return factor * node->spacing;
        slot = next;
        factor = OT_ANCESTOR_FLOOR;
    }
}

lk_status lk_octree_load_selection(const lk_octree *octree, const size_t *nodes, size_t node_count, lk_mesh *points,
                                   float **clips, lk_error *error)
{
    if (points) lk_mesh_init(points);
    if (clips) *clips = NULL;
    if (!octree || !points || (!nodes && node_count))
        return lk_error_set(error, LK_ERR_INVALID, "lk_octree_load_selection: no octree, nodes or points");
    const lk_octree_info *info = lk_octree_get_info(octree);
    int with_clips = clips && info->has_clips;
    uint64_t total = 0;
    for (size_t i = 0; i < node_count; i++) {
        const lk_octree_node *node = lk_octree_node_at(octree, nodes[i]);
        if (!node) return lk_error_set(error, LK_ERR_INVALID, "node %zu does not exist", nodes[i]);
        total += node->points;
    }
    if (total > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "%llu points selected: more than a point set holds",
                            (unsigned long long)total);
    node_slot *sorted = lk__malloc_array(node_count ? node_count : 1, sizeof *sorted);
    drawn_node *drawn = lk__malloc_array(node_count ? node_count : 1, sizeof *drawn);
    float *all_clips = NULL;
    lk_status status = LK_OK;
    if (!sorted || !drawn) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu nodes", node_count);
    if (status == LK_OK)
        status = lk_mesh_alloc(points, (size_t)total, 0,
                               LK_ATTR_RADII | (info->has_colors ? LK_ATTR_COLORS : 0u) |
                                   (info->has_normals ? LK_ATTR_NORMALS : 0u),
                               error);
    if (status == LK_OK && with_clips && !(all_clips = lk__malloc_array(total ? (size_t)total : 1, 4 * sizeof(float))))
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %llu clip lines", (unsigned long long)total);
    if (status == LK_OK) {
        for (size_t i = 0; i < node_count; i++) sorted[i] = (node_slot){nodes[i], i};
        qsort(sorted, node_count, sizeof *sorted, compare_slots);
    }
    /* the drawn nodes' children, found by name */
    for (size_t i = 0; status == LK_OK && i < node_count; i++) {
        const lk_octree_node *node = lk_octree_node_at(octree, nodes[i]);
        drawn_node *d = &drawn[i];
        double half = 0.5 * (node->max[0] - node->min[0]);
        for (int k = 0; k < 3; k++) d->centre[k] = node->min[k] + half - info->offset[k];
        d->spacing = ldexp(info->spacing, -(int)node->level);
        char name[OT_MAX_BITS + 3]; /* the node's (at most OT_MAX_BITS + 1), a child's digit, NUL */
        size_t length = strlen(node->name);
        memcpy(name, node->name, length);
        name[length + 1] = '\0';
        for (int digit = 0; digit < 8; digit++) {
            d->child[digit] = CHILD_ABSENT;
            if (!(node->children >> digit & 1u) || length > OT_MAX_BITS) continue;
            d->child[digit] = CHILD_NOT_DRAWN;
            name[length] = (char)('0' + digit);
            node_slot key = {lk__octree_find_node(octree, name, node->level + 1), 0};
            const node_slot *at = bsearch(&key, sorted, node_count, sizeof *sorted, compare_slots);
            if (at) d->child[digit] = (long)at->slot;
        }
    }
    size_t filled = 0;
    for (size_t i = 0; status == LK_OK && i < node_count; i++) {
        lk_mesh node;
        float *node_clips = NULL;
        status = lk__octree_load_node(octree, nodes[i], &node, with_clips ? &node_clips : NULL, 0, error);
        if (status != LK_OK) break;
        size_t n = node.vertex_count;
        const lk_octree_node *header = lk_octree_node_at(octree, nodes[i]);
        /* drawn alone, the node's points would be at least its spacing */
        double alone = header->children ? drawn[i].spacing : 0.0;
        for (size_t p = 0; p < n; p++) {
            double own = node.radii[p];
            /* below the point's node the floor is at most 1.5 / 2 of its spacing */
            double floor = alone > own ? walk_floor(drawn, (long)i, node.positions + 3 * p) : 0.0;
            double radius = own > floor ? own : floor;
            points->radii[filled + p] = (float)radius;
            if (node_clips) {
                /* the stored offset is in the radius drawn alone */
                double base = own > alone ? own : alone;
                for (int k = 0; k < 3; k++) all_clips[4 * (filled + p) + (size_t)k] = node_clips[4 * p + (size_t)k];
                all_clips[4 * (filled + p) + 3] =
                    radius > 0 ? (float)(node_clips[4 * p + 3] * base / radius) : node_clips[4 * p + 3];
            }
        }
        memcpy(points->positions + 3 * filled, node.positions, 3 * n * sizeof *points->positions);
        if (points->normals) memcpy(points->normals + 3 * filled, node.normals, 3 * n * sizeof *points->normals);
        if (points->colors) memcpy(points->colors + 4 * filled, node.colors, 4 * n * sizeof *points->colors);
        filled += n;
        lk_mesh_free(&node);
        free(node_clips);
    }
    free(sorted);
    free(drawn);
    if (status != LK_OK) {
        lk_mesh_free(points);
        free(all_clips);
        return status;
    }
    if (clips) *clips = all_clips;
    return LK_OK;
}
