/* SPDX-License-Identifier: MIT */
/* Animated meshes: the lk_animation container (init, free, one frame as a
 * mesh, validation) and the frame allocation its readers share. Reading and
 * writing by extension live in anim_dispatch.c, the formats in io_md2.c,
 * io_kmf.c, io_gltf.c and io_acclaim.c, Acclaim forward kinematics and
 * skinning in anim_skeleton.c. */
#include "anim_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void lk_animation_init(lk_animation *animation) { memset(animation, 0, sizeof *animation); }

void lk_animation_free(lk_animation *animation)
{
    if (!animation) return;
    lk_mesh_free(&animation->mesh);
    free(animation->frame_positions);
    if (animation->frame_names) {
        for (size_t f = 0; f < animation->frame_count; f++) free(animation->frame_names[f]);
        free(animation->frame_names);
    }
    lk_animation_init(animation);
}

lk_status lk_animation_frame(const lk_animation *animation, size_t frame, lk_mesh *out, lk_error *error)
{
    if (!animation || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_animation_frame: NULL argument");
    if (frame >= animation->frame_count)
        return lk_error_set(error, LK_ERR_RANGE, "frame %zu does not exist (the animation has %zu frames)", frame,
                            animation->frame_count);
    if (!animation->frame_positions) return lk_error_set(error, LK_ERR_INVALID, "animation has no frame positions");
    lk_mesh copy;
    lk_status status = lk_mesh_copy(&copy, &animation->mesh, error);
    if (status != LK_OK) return status;
    size_t floats = animation->mesh.vertex_count * 3;
    if (floats) memcpy(copy.positions, animation->frame_positions + frame * floats, floats * sizeof(float));
    *out = copy;
    return LK_OK;
}

lk_status lk__animation_alloc_frames(lk_animation *animation, size_t frame_count, lk__budget *budget, const char *what,
                                     lk_error *error)
{
    size_t floats_per_frame = animation->mesh.vertex_count * 3;
    if (frame_count == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: no frames", what);
    if (floats_per_frame && (frame_count > lk__budget_room(budget) / sizeof(float) / floats_per_frame ||
                             !lk__budget_charge(budget, frame_count, floats_per_frame * sizeof(float))))
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%s: %zu frames of %zu vertices would need more than the memory budget of %zu bytes", what,
                            frame_count, animation->mesh.vertex_count, budget->limit);
    animation->frame_positions = lk__malloc_array(frame_count, floats_per_frame * sizeof(float));
    if (!animation->frame_positions)
        return lk_error_set(error, LK_ERR_NOMEM, "%s: cannot allocate %zu frames of %zu vertices", what, frame_count,
                            animation->mesh.vertex_count);
    animation->frame_count = frame_count;
    return LK_OK;
}

lk_status lk__animation_take_frame0(lk_animation *animation, lk_mesh *mesh, lk_error *error)
{
    (void)error;
    /* mesh.positions already hold frame 0 by contract. */
    *mesh = animation->mesh;
    lk_mesh_init(&animation->mesh);
    lk_animation_free(animation);
    return LK_OK;
}

lk_status lk_animation_validate(const lk_animation *animation, lk_error *error)
{
    if (!animation) return lk_error_set(error, LK_ERR_INVALID, "NULL animation");
    if (animation->frame_count < 1 || !animation->frame_positions)
        return lk_error_set(error, LK_ERR_INVALID, "animation has no frames");
    if (!(animation->frames_per_second > 0) || !isfinite(animation->frames_per_second))
        return lk_error_set(error, LK_ERR_INVALID, "frames_per_second %g is not a positive number",
                            animation->frames_per_second);
    lk_error inner = {0};
    lk_status status = lk_mesh_validate(&animation->mesh, &inner);
    if (status != LK_OK) return lk_error_set(error, status, "frame 0 mesh: %s", inner.message);
    size_t floats = animation->mesh.vertex_count * 3;
    for (size_t f = 0; f < animation->frame_count; f++) {
        const float *p = animation->frame_positions + f * floats;
        for (size_t i = 0; i < floats; i++)
            if (!isfinite(p[i]))
                return lk_error_set(error, LK_ERR_RANGE, "frame %zu: vertex %zu has a non-finite coordinate", f, i / 3);
    }
    return LK_OK;
}
