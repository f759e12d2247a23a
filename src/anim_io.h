/* SPDX-License-Identifier: MIT */
/* Internal interface of the animation formats: the readers and writers
 * (io_md2.c, io_kmf.c, io_acclaim.c, io_gltf.c) that the dispatch by
 * extension (anim_dispatch.c) and the plain mesh dispatch (io.c) call, and
 * what the formats use in return: the frame allocation of the model
 * (anim.c) and the budgeted skinning (anim_skeleton.c). A header of its
 * own, with no .c: the formats include it and the dispatch calls them, so
 * it must not belong to the dispatch. Not installed. */
#ifndef LODKIT_ANIM_IO_H
#define LODKIT_ANIM_IO_H

#include "internal.h"

/* Largest frame count any reader accepts unless the caller says otherwise. */
#define LK__ANIM_DEFAULT_MAX_FRAMES ((size_t)100000)
/* Memory budget of a read (and of lk_animation_from_acclaim) unless the
 * caller says otherwise. */
#define LK__ANIM_DEFAULT_MAX_BYTES ((size_t)8 << 30)

/* What a reader is allowed to do: the budget for everything the read holds
 * (the input's bytes are charged to it already; lk__read_context says how
 * readers use it), the frame limit, and the glTF options. */
typedef struct lk__anim_context {
    const char *name;      /* file name for messages */
    const char *directory; /* for external references (glTF buffers, Acclaim set), or NULL */
    lk__budget *budget;
    size_t max_frames;
    double frames_per_second;    /* glTF resampling rate, 0 = key times */
    size_t animation_index;      /* glTF */
    int all_animations;          /* glTF */
    lk_animation_report *report; /* never NULL here */
} lk__anim_context;

/* Readers: fill an initialised (empty) animation; on failure leave it empty. */
lk_status lk__anim_read_md2(const unsigned char *data, size_t size, const lk__anim_context *ctx,
                            lk_animation *animation, lk_error *error);
lk_status lk__anim_read_kmf(const char *data, size_t size, const lk__anim_context *ctx, lk_animation *animation,
                            lk_error *error);
lk_status lk__anim_read_gltf(const char *data, size_t size, const lk__anim_context *ctx, lk_animation *animation,
                             lk_error *error);

/* Writers: write to an open stream (the caller handles the temporary file);
 * `name` is used in messages. The animation has been validated. */
lk_status lk__anim_write_md2(FILE *file, const lk_animation *animation, const char *name, lk_error *error);
lk_status lk__anim_write_kmf(FILE *file, const lk_animation *animation, const char *name, lk_error *error);
lk_status lk__anim_write_gltf(FILE *file, const lk_animation *animation, const char *name, lk_error *error);

/* Plain mesh readers (frame 0), with the signature of lk__read_obj & co. */
lk_status lk__read_md2(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
lk_status lk__read_kmf(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);

/* lk_animation_from_acclaim charging the rest pose's copy, the frames and
 * its scratch to `budget`. */
lk_status lk__animation_from_acclaim(const lk_mesh *rest_pose, const lk_skeleton *skeleton, const lk_motion *motion,
                                     const lk_bone_weights *weights, double frames_per_second, lk__budget *budget,
                                     lk_animation *out, lk_animation_report *report, lk_error *error);

/* Moves frame 0 of an animation into a mesh (the animation is freed). */
lk_status lk__animation_take_frame0(lk_animation *animation, lk_mesh *mesh, lk_error *error);

/* Allocates frame_positions (frame_count * vertex_count * 3 floats),
 * charged to the budget; `what` names the file for messages. */
lk_status lk__animation_alloc_frames(lk_animation *animation, size_t frame_count, lk__budget *budget, const char *what,
                                     lk_error *error);

#endif
