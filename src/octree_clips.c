/* SPDX-License-Identifier: MIT */
/* The nearest-neighbour work of a point octree's chunk besides its radii
 * and normals: the order of its queries (Morton), and the clip lines the
 * octree stores (docs/formats.md, "Point octree"): level by level, each
 * point's border test among the points a view draws with it. Called by the
 * builder (src/octree.c) once a chunk's points are assigned to its nodes. */
#include "internal.h"
#include "octree_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Neighbours asked by a clip line's border test (as the renderer's:
 * src/gl/splat.c, CLIP_NEIGHBOURS). */
enum { OT_CLIP_NEIGHBOURS = 16 };
/* A border found within its neighbourhood's reach of a face of the chunk's
 * cube, open towards that face, is where the chunk's points end, not the
 * cloud's: no cut there. "Towards": the cut's direction makes less than
 * 72.5 degrees with the face's outward normal (a surface crossing the face
 * at a slant has its false border's direction well inside that). The
 * bunny sampled into 100,000 points in 40 chunks: 5.4% of the points cut
 * without this rule, 0.38% with it, 0.30% in one chunk. */
#define OT_CLIP_FACE_COSINE 0.3

/* 3 x 21 bits interleaved (Morton order). */
static uint64_t morton(const uint32_t q[3], unsigned shift)
{
    uint64_t key = 0;
    for (int bit = 20; bit >= 0; bit--)
        for (int k = 0; k < 3; k++) key = key << 1 | ((q[k] >> shift >> bit) & 1u);
    return key;
}

uint32_t *lk__octree_morton_order(const ot_point *points, size_t count, unsigned bits)
{
    uint64_t *keys = lk__malloc_array(count, sizeof *keys), *keys2 = lk__malloc_array(count, sizeof *keys2);
    uint32_t *order = lk__malloc_array(count, sizeof *order), *order2 = lk__malloc_array(count, sizeof *order2);
    if (!keys || !keys2 || !order || !order2) {
        free(keys), free(keys2), free(order), free(order2);
        return NULL;
    }
    unsigned shift = bits > 21 ? bits - 21 : 0;
    for (size_t i = 0; i < count; i++) {
        keys[i] = morton(points[i].q, shift);
        order[i] = (uint32_t)i;
    }
    for (unsigned pass = 0; pass < 8; pass++) {
        size_t histogram[257] = {0};
        unsigned at = 8 * pass;
        for (size_t i = 0; i < count; i++) histogram[((keys[i] >> at) & 0xffu) + 1]++;
        if (histogram[((keys[0] >> at) & 0xffu) + 1] == count) continue; /* one bucket: nothing moves */
        for (int d = 0; d < 256; d++) histogram[d + 1] += histogram[d];
        for (size_t i = 0; i < count; i++) {
            size_t to = histogram[(keys[i] >> at) & 0xffu]++;
            keys2[to] = keys[i];
            order2[to] = order[i];
        }
        uint64_t *swap_keys = keys;
        keys = keys2;
        keys2 = swap_keys;
        uint32_t *swap_order = order;
        order = order2;
        order2 = swap_order;
    }
    free(keys);
    free(keys2);
    free(order2);
    return order;
}

/* One signed byte of a clip line: value in [-1, 1] times 127. */
static int8_t clip_byte(double value)
{
    if (!(value > -1.0)) value = value < 0 ? -1.0 : 0.0; /* NaN: 0 */
    if (value > 1.0) value = 1.0;
    return (int8_t)lrint(value * 127.0);
}

/* Whether the border of the point at p, cut along `direction`, is one of
 * the chunk's cube faces rather than the cloud's. */
static int at_chunk_face(const ot_clip_chunk *chunk, const float p[3], const float direction[3], float reach)
{
    for (int k = 0; k < 3; k++) {
        if (chunk->lo_open[k] && p[k] - chunk->lo[k] < reach && -direction[k] > OT_CLIP_FACE_COSINE) return 1;
        if (chunk->hi_open[k] && chunk->hi[k] - p[k] < reach && direction[k] > OT_CLIP_FACE_COSINE) return 1;
    }
    return 0;
}

lk_status lk__octree_chunk_clips(const ot_clip_chunk *chunk, lk_error *error)
{
    size_t count = chunk->count;
    for (size_t i = 0; i < count; i++) memset(chunk->points[i].clip, 0, sizeof chunk->points[i].clip);
    if (count == 0) return LK_OK;
    float *positions = lk__malloc_array(count, 3 * sizeof *positions);
    float *normals = lk__malloc_array(count, 3 * sizeof *normals);
    uint32_t *members = lk__malloc_array(count, sizeof *members); /* a level's set: Morton rank of each */
    uint32_t *queries = lk__malloc_array(count, sizeof *queries); /* the set's points of that level */
    float *clips = lk__malloc_array(count, 4 * sizeof *clips);
    float *reach = lk__malloc_array(count, sizeof *reach);
    lk_status status = LK_OK;
    if (!positions || !normals || !members || !queries || !clips || !reach)
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the clip lines of chunk %s", chunk->name);
    for (unsigned level = chunk->first_level; status == LK_OK && level <= chunk->last_level; level++) {
        /* the chunk's points of levels <= level, in Morton order (neighbouring
         * queries then walk the same parts of the k-d tree) */
        size_t member_count = 0, query_count = 0;
        for (size_t r = 0; r < count; r++) {
            uint32_t at = chunk->order[r];
            if (chunk->depth[at] > level) continue;
            if (chunk->depth[at] == level) queries[query_count++] = (uint32_t)member_count;
            const ot_point *point = &chunk->points[at];
            for (int k = 0; k < 3; k++) positions[3 * member_count + (size_t)k] = (float)(point->q[k] * chunk->scale);
            lk__octree_oct_decode(point->oct, normals + 3 * member_count);
            members[member_count++] = (uint32_t)r;
        }
        if (query_count == 0) continue;
        status = lk__points_estimate_clips_of(positions, normals, member_count, queries, query_count,
                                              OT_CLIP_NEIGHBOURS, clips, reach, error);
        for (size_t i = 0; status == LK_OK && i < query_count; i++) {
            uint32_t at = chunk->order[members[queries[i]]];
            const float *clip = clips + 4 * i, *p = positions + 3 * (size_t)queries[i];
            if (clip[0] == 0 && clip[1] == 0 && clip[2] == 0) continue;
            if (at_chunk_face(chunk, p, clip, reach[i])) continue;
            ot_point *point = &chunk->points[at];
            for (int k = 0; k < 3; k++) point->clip[k] = clip_byte(clip[k]);
            point->clip[3] = clip_byte(chunk->radius[at] > 0 ? clip[3] / chunk->radius[at] : 0.0);
        }
    }
    free(positions);
    free(normals);
    free(members);
    free(queries);
    free(clips);
    free(reach);
    return status;
}
