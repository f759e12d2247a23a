/* SPDX-License-Identifier: MIT */
/* Shared by the point octree's builder (src/octree.c) and reader
 * (src/octree_read.c). Not installed. */
#ifndef LODKIT_OCTREE_INTERNAL_H
#define LODKIT_OCTREE_INTERNAL_H

#include "internal.h"

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#define OT_INDEX_NAME "octree.json"
#define OT_DATA_NAME "octree.bin"
#define OT_FORMAT_NAME "lodkit point octree"
/* Version 2 stores the points' own splat radii (readers floor an inner
 * node's at its spacing, or less where deeper nodes are drawn too);
 * version 1 stored them floored. Readers read both. */
#define OT_VERSION 2
#define OT_OLDEST_VERSION 1
/* Quantised coordinates are below 2^OT_MAX_BITS; node names have at most
 * that many digits. */
#define OT_MAX_BITS 30
/* Points a batch of input holds. */
#define OT_BATCH 65536

/* ---- streamed inputs (src/octree_input.c) ---- */
/* One batch of input points: positions in double, RGB8 (when the source
 * has colours), normals (when it has them). */
typedef struct ot_batch {
    size_t count;
    double xyz[3 * OT_BATCH];
    uint8_t rgb[3 * OT_BATCH];
    float normals[3 * OT_BATCH];
} ot_batch;

/* An input file, read in batches: LAS, PLY, XYZ and PCD (but
 * binary_compressed) streamed record by record (or line by line), other
 * formats read whole by lk_mesh_read and handed out in batches. */
typedef struct ot_source {
    const char *path;
    int is_las, is_ply, is_xyz, is_pcd; /* streamed formats (an ASCII PLY: is_ply with ply.ascii) */
    int has_colors, has_normals;
    lk__ply_layout ply;
    unsigned long long count; /* points; XYZ and PCD: ULLONG_MAX until the last is read */
    /* PCD: binary records or ascii lines, some points dropped (NaN) */
    lk__pcd_stream pcd;
    unsigned long long records_done; /* PCD records read */
    /* text (XYZ, ASCII PLY): the file read in blocks, cut into lines */
    char *text;
    size_t text_capacity, text_start, text_end;
    int text_eof;
    size_t line; /* number of the last line handed out */
    lk__xyz_lines xyz;
    /* LAS */
    FILE *file;
    lk__las_header las;
    unsigned rgb_at;
    unsigned color_max; /* largest 16-bit channel (pass 1) */
    int colors_16bit;   /* decided by pass 1: channels above 255 seen */
    unsigned char *records;
    /* others */
    lk_mesh mesh;
    unsigned long long next; /* next point to hand out */
    size_t max_read_bytes;   /* lk_read_options.max_bytes of a whole read (kept by open) */
} ot_source;

/* Opens `path` for one pass (source->colors_16bit, from an earlier pass,
 * and max_read_bytes are kept; zero the rest of *source first). LAS, PLY (a first element
 * "vertex" of scalar properties), XYZ and PCD (ascii or binary) are read in
 * batches, in bounded memory; other formats whole, by lk_mesh_read. Errors name the file (and
 * the line or byte). */
lk_status lk__octree_source_open(ot_source *source, const char *path, lk_error *error);
/* The next batch (at most OT_BATCH points, maybe 0 at the end of an XYZ
 * or PCD file; call while next < count). */
lk_status lk__octree_source_next(ot_source *source, ot_batch *batch, lk_error *error);
void lk__octree_source_close(ot_source *source);

/* ---- the builder (src/octree.c) ---- */

/* A point while building: quantised position, colour, normal, and the
 * local density's splat radius (model units; 0 when not estimated). Also
 * the spill files' record. */
typedef struct ot_point {
    uint32_t q[3];
    uint8_t rgb[3];
    uint8_t unused;
    uint16_t oct[2];
    float radius;
    int8_t clip[4]; /* the file's clip line (src/octree_clips.c), zero when none */
} ot_point;

/* The points' indices in Morton order of their coordinates (the cube's
 * side is 2^bits steps; LSD radix sort, 8 bits a pass): k-d tree queries in
 * that order walk the same parts of the tree, 2-3x faster than in input
 * order. malloc'ed; NULL when out of memory. */
uint32_t *lk__octree_morton_order(const ot_point *points, size_t count, unsigned bits);

/* The points of one chunk, each with the level of its node, for the clip
 * lines (src/octree_clips.c). */
typedef struct ot_clip_chunk {
    ot_point *points; /* clip set here */
    size_t count;
    const uint32_t *order;      /* the points in Morton order */
    const unsigned char *depth; /* each point's node level */
    const float *radius;        /* each point's splat radius in its node */
    unsigned first_level, last_level;
    double scale;               /* model units per quantisation step */
    double lo[3], hi[3];        /* the chunk's cube, model units from the root corner */
    int lo_open[3], hi_open[3]; /* its faces that are not the root cube's */
    const char *name;           /* for messages */
} ot_clip_chunk;

/* Sets point->clip of every point of the chunk: the clip line of a point
 * of level l among the chunk's points of levels <= l (docs/formats.md,
 * "Point octree"). */
lk_status lk__octree_chunk_clips(const ot_clip_chunk *chunk, lk_error *error);

/* ---- shared by the builder and the reader (src/octree_read.c) ---- */

/* zlib's CRC-32 of any number of bytes. */
uint32_t lk__octree_crc32(const unsigned char *bytes, size_t size);
/* The unit normal of an octahedral pair (docs/formats.md, "Point octree"). */
void lk__octree_oct_decode(const uint16_t in[2], float n[3]);
/* folder + "/" + name, malloc'ed (NULL when out of memory). */
char *lk__octree_join_path(const char *folder, const char *name);

/* ---- reading (src/octree_read.c) ---- */
/* The index of the node named `name` (its first level + 1 characters) at
 * `level`, or info.node_count when the index has none. Binary search. */
size_t lk__octree_find_node(const lk_octree *octree, const char *name, unsigned level);
/* lk_octree_load_node_clips; floored 0: radii as stored (version 2: the
 * points' own, not floored at an inner node's spacing). */
lk_status lk__octree_load_node(const lk_octree *octree, size_t index, lk_mesh *points, float **clips, int floored,
                               lk_error *error);

#endif
