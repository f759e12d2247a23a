/* SPDX-License-Identifier: MIT */
/* The k-nearest-neighbour machinery of the point-set code (points.c):
 * a k-d tree over float positions and a small thread pool for per-point
 * work. Internal: not part of the public API. */
#ifndef LODKIT_POINTS_KD_H
#define LODKIT_POINTS_KD_H

#include "internal.h"

#include <stdbool.h>

/* Runs fn(context, begin, end) over [0, count) split into equal ranges, one
 * per thread; small jobs stay on the calling thread. Falls back to fewer
 * threads (down to the caller alone) if threads cannot be created: the
 * results are the same either way. */
typedef void (*range_fn)(void *context, size_t begin, size_t end);

enum { KD_LEAF_SIZE = 8, KD_STACK = 160 };

/* A point in tree order: position and original index side by side, so a
 * leaf scan reads one contiguous run of memory. */
typedef struct kd_entry {
    float p[3];
    uint32_t id;
} kd_entry;

typedef struct kd_node {
    float lo[3], hi[3];  /* tight bounds of the node's points */
    uint32_t begin, end; /* its points: entries[begin .. end) */
    uint32_t child;      /* first child (the second is child + 1); 0 for a leaf */
} kd_node;

typedef struct kd_tree {
    size_t count;
    kd_entry *entries;
    kd_node *nodes;
    size_t node_count;
} kd_tree;

static inline double lk__point_distance2(const float a[3], const float b[3])
{
    double dx = (double)a[0] - b[0], dy = (double)a[1] - b[1], dz = (double)a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

/* Runs fn over [0, count) in up to one range per online processor, each of
 * at least min_per_thread items. */
void lk__points_parallel_for(size_t count, size_t min_per_thread, range_fn fn, void *context);
void lk__kd_free(kd_tree *tree);
/* Builds the tree over positions[3 * count] (not copied: entries hold
 * their own copies). */
lk_status lk__kd_build(kd_tree *tree, const float *positions, size_t count, lk_error *error);
/* The k nearest points to q other than `exclude` (with positive_only,
 * only points at a distance > 0), nearest first: squared distances and
 * ids; returns how many were found. */
unsigned lk__kd_nearest(const kd_tree *tree, const float q[3], uint32_t exclude, unsigned k, bool positive_only,
                        double *distance2, uint32_t *id);

#endif
