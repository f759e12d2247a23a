/* SPDX-License-Identifier: MIT */
/* k-d tree and thread pool for the point-set code (points_kd.h). */
#include "points_kd.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- threads ------------------------------------------------------------ */


typedef struct range_job {
    range_fn fn;
    void *context;
    size_t begin, end;
} range_job;

static void *range_thread(void *argument)
{
    range_job *job = argument;
    job->fn(job->context, job->begin, job->end);
    return NULL;
}

void lk__points_parallel_for(size_t count, size_t min_per_thread, range_fn fn, void *context)
{
    enum { MOST_THREADS = 32 };
    long online = sysconf(_SC_NPROCESSORS_ONLN);
    size_t thread_count = online > 0 ? (size_t)online : 1;
    if (thread_count > MOST_THREADS) thread_count = MOST_THREADS;
    if (min_per_thread == 0) min_per_thread = 1;
    if (thread_count > count / min_per_thread) thread_count = count / min_per_thread;
    if (thread_count <= 1) {
        if (count) fn(context, 0, count);
        return;
    }
    range_job jobs[MOST_THREADS];
    pthread_t threads[MOST_THREADS];
    size_t started = 0;
    for (size_t t = 0; t < thread_count; t++) {
        jobs[t] = (range_job){fn, context, count * t / thread_count, count * (t + 1) / thread_count};
        if (t == 0) continue; /* the calling thread does the first range */
        if (pthread_create(&threads[started], NULL, range_thread, &jobs[t]) != 0) {
            /* Do this range and the remaining ones here instead. */
            fn(context, jobs[t].begin, count);
            break;
        }
        started++;
    }
    fn(context, jobs[0].begin, jobs[0].end);
    for (size_t t = 0; t < started; t++) pthread_join(threads[t], NULL);
}

/* ---- k-d tree ------------------------------------------------------------ */


void lk__kd_free(kd_tree *tree)
{
    free(tree->entries);
    free(tree->nodes);
    memset(tree, 0, sizeof *tree);
}

/* Places the element of rank `nth` (by coordinate `axis`) at entries[nth],
 * smaller or equal ones before it and greater or equal ones after it.
 * Quickselect with a three-way partition, so runs of equal coordinates
 * (grids, duplicates) cannot make it quadratic; pivots are the median of
 * three positions picked by a hash of the range, which keeps it
 * deterministic without being fooled by sorted input. */
static void kd_select(kd_entry *entries, size_t lo, size_t hi, size_t nth, int axis)
{
    while (hi - lo > 1) {
        size_t length = hi - lo;
        uint64_t h = lk__mix64(((uint64_t)lo << 32) ^ hi);
        float a = entries[lo + (size_t)(h % length)].p[axis];
        float b = entries[lo + (size_t)((h >> 21) % length)].p[axis];
        float c = entries[lo + (size_t)((h >> 42) % length)].p[axis];
        float pivot = a < b ? (b < c ? b : (a < c ? c : a)) : (a < c ? a : (b < c ? c : b));
        /* [lo, less) < pivot, [less, i) == pivot, [greater, hi) > pivot */
        size_t less = lo, i = lo, greater = hi;
        while (i < greater) {
            float value = entries[i].p[axis];
            if (value < pivot) {
                kd_entry swap = entries[i];
                entries[i++] = entries[less];
                entries[less++] = swap;
            } else if (value > pivot) {
                kd_entry swap = entries[i];
                entries[i] = entries[--greater];
                entries[greater] = swap;
            } else {
                i++;
            }
        }
        if (nth < less)
            hi = less;
        else if (nth >= greater)
            lo = greater;
        else
            return;
    }
}

/* Builds the tree over positions (3 floats each, all finite). Nodes are
 * split at the median of their widest axis until they hold at most
 * KD_LEAF_SIZE points; even a node of identical points is split, so leaves
 * stay small and a query never scans a long run of duplicates. O(N log N). */
lk_status lk__kd_build(kd_tree *tree, const float *positions, size_t count, lk_error *error)
{
    memset(tree, 0, sizeof *tree);
    tree->count = count;
    /* Leaves hold at least KD_LEAF_SIZE / 2 points, so there are at most
     * 2 * count / (KD_LEAF_SIZE / 2) + 1 nodes. */
    size_t node_capacity = count / (KD_LEAF_SIZE / 2) * 2 + 2;
    tree->entries = lk__malloc_array(count, sizeof(kd_entry));
    tree->nodes = lk__malloc_array(node_capacity, sizeof(kd_node));
    if (!tree->entries || !tree->nodes) {
        lk__kd_free(tree);
        return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate a k-d tree of %zu points", count);
    }
    for (size_t i = 0; i < count; i++) {
        memcpy(tree->entries[i].p, positions + 3 * i, 3 * sizeof(float));
        tree->entries[i].id = (uint32_t)i;
    }
    tree->nodes[0] = (kd_node){.begin = 0, .end = (uint32_t)count, .child = 0};
    tree->node_count = 1;
    /* Breadth-first: children are appended behind the node being split. */
    for (size_t n = 0; n < tree->node_count; n++) {
        kd_node *node = &tree->nodes[n];
        float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
        if (node->end > node->begin) {
            memcpy(lo, tree->entries[node->begin].p, sizeof lo);
            memcpy(hi, lo, sizeof hi);
        }
        for (uint32_t i = node->begin + 1; i < node->end; i++) {
            const float *p = tree->entries[i].p;
            for (int k = 0; k < 3; k++) {
                if (p[k] < lo[k]) lo[k] = p[k];
                if (p[k] > hi[k]) hi[k] = p[k];
            }
        }
        memcpy(node->lo, lo, sizeof lo);
        memcpy(node->hi, hi, sizeof hi);
        node->child = 0;
        if (node->end - node->begin <= KD_LEAF_SIZE) continue;
        int axis = 0;
        for (int k = 1; k < 3; k++)
            if ((double)hi[k] - lo[k] > (double)hi[axis] - lo[axis]) axis = k;
        uint32_t mid = node->begin + (node->end - node->begin) / 2;
        kd_select(tree->entries, node->begin, node->end, mid, axis);
        if (tree->node_count + 2 > node_capacity) { /* cannot happen (see above); stay safe */
            lk__kd_free(tree);
            return lk_error_set(error, LK_ERR_NOMEM, "k-d tree node budget exceeded");
        }
        node->child = (uint32_t)tree->node_count;
        uint32_t begin = node->begin, end = node->end;
        tree->nodes[tree->node_count++] = (kd_node){.begin = begin, .end = mid};
        tree->nodes[tree->node_count++] = (kd_node){.begin = mid, .end = end};
    }
    return LK_OK;
}

static double box_distance2(const kd_node *node, const float q[3])
{
    double sum = 0;
    for (int k = 0; k < 3; k++) {
        double d = 0;
        if (q[k] < node->lo[k])
            d = (double)node->lo[k] - q[k];
        else if (q[k] > node->hi[k])
            d = (double)q[k] - node->hi[k];
        sum += d * d;
    }
    return sum;
}


/* The k nearest points to q other than the point `exclude` (UINT32_MAX:
 * none), nearest first, in distance2[] / id[]; returns how many were found
 * (fewer than k only when the tree holds fewer points). With positive_only,
 * points at distance 0 from q are ignored (for coincident points).
 * Depth-first, nearer child first, pruning boxes no closer than the current
 * k-th candidate. Pruning at equal distance too means that among points
 * tied with the k-th, the ones met first win (the traversal is fixed, so
 * the answer is still deterministic); it is what keeps a pile of
 * coincident points from making every query scan the whole pile. */
unsigned lk__kd_nearest(const kd_tree *tree, const float q[3], uint32_t exclude, unsigned k, bool positive_only,
                        double *distance2, uint32_t *id)
{
    unsigned found = 0;
    if (tree->count == 0 || k == 0) return 0;
    struct {
        uint32_t node;
        double distance2;
    } stack[KD_STACK];
    size_t depth = 0;
    stack[depth].node = 0;
    stack[depth++].distance2 = box_distance2(&tree->nodes[0], q);
    while (depth > 0) {
        depth--;
        const kd_node *node = &tree->nodes[stack[depth].node];
        if (found == k && stack[depth].distance2 >= distance2[k - 1]) continue;
        if (positive_only) {
            /* A box shrunk to the query point holds only coincident points. */
            bool collapsed = true;
            for (int c = 0; c < 3; c++) collapsed &= node->lo[c] == q[c] && node->hi[c] == q[c];
            if (collapsed) continue;
        }
        if (node->child == 0) {
            for (uint32_t i = node->begin; i < node->end; i++) {
                const kd_entry *entry = &tree->entries[i];
                if (entry->id == exclude) continue;
                double d = lk__point_distance2(entry->p, q);
                if (positive_only && d == 0) continue;
                if (found == k && !(d < distance2[k - 1] || (d == distance2[k - 1] && entry->id < id[k - 1]))) continue;
                /* Insertion into the sorted candidate list; ties by index. */
                unsigned slot = found < k ? found++ : k - 1;
                while (slot > 0 &&
                       (distance2[slot - 1] > d || (distance2[slot - 1] == d && id[slot - 1] > entry->id))) {
                    distance2[slot] = distance2[slot - 1];
                    id[slot] = id[slot - 1];
                    slot--;
                }
                distance2[slot] = d;
                id[slot] = entry->id;
            }
            continue;
        }
        uint32_t near = node->child, far = node->child + 1;
        double near_d = box_distance2(&tree->nodes[near], q), far_d = box_distance2(&tree->nodes[far], q);
        if (far_d < near_d) {
            uint32_t swap_node = near;
            near = far;
            far = swap_node;
            double swap_d = near_d;
            near_d = far_d;
            far_d = swap_d;
        }
        /* Median splits keep the depth below about log2(N / 4) + 1 < 32 and
         * the stack holds one pending sibling per level, so this never
         * fills; the test only guards the array. */
        if (depth + 2 > KD_STACK) continue;
        if (!(found == k && far_d >= distance2[k - 1])) {
            stack[depth].node = far;
            stack[depth++].distance2 = far_d;
        }
        if (!(found == k && near_d >= distance2[k - 1])) {
            stack[depth].node = near;
            stack[depth++].distance2 = near_d;
        }
    }
    return found;
}
