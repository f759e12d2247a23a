/* SPDX-License-Identifier: MIT */
/* Acclaim forward kinematics (lk_skeleton_pose: 4x4 bone transforms from
 * an ASF skeleton and an AMC motion) and linear-blend skinning
 * (lk_animation_from_acclaim). The ASF/AMC/WGT readers live in
 * io_acclaim.c. */
#include "anim_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LK_DEG_TO_RAD 0.017453292519943295769

/* 4x4 column-major matrices acting on column vectors: m[col * 4 + row]. */
static void mat_identity(double m[16])
{
    memset(m, 0, 16 * sizeof(double));
    m[0] = m[5] = m[10] = m[15] = 1;
}

static void mat_mul(const double a[16], const double b[16], double out[16])
{
    double r[16];
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[k * 4 + row] * b[c * 4 + k];
            r[c * 4 + row] = s;
        }
    memcpy(out, r, sizeof r);
}

static void mat_rotation(int axis, double radians, double m[16])
{
    mat_identity(m);
    double c = cos(radians), s = sin(radians);
    int i = (axis + 1) % 3, j = (axis + 2) % 3;
    /* Rotation in the (i, j) plane, right-handed about `axis`. */
    m[i * 4 + i] = c;
    m[j * 4 + i] = -s;
    m[i * 4 + j] = s;
    m[j * 4 + j] = c;
}

/* Rotation for angles (one per axis X, Y, Z) applied in `order` ("XYZ" = X
 * first, then Y, then Z; as column vectors R = Rz * Ry * Rx). */
static void euler_matrix(const double angles[3], const char order[4], double to_radians, double m[16])
{
    mat_identity(m);
    for (int k = 0; k < 3 && order[k]; k++) {
        int axis = order[k] - 'X';
        if (axis < 0 || axis > 2) continue;
        double r[16];
        mat_rotation(axis, angles[axis] * to_radians, r);
        mat_mul(r, m, m);
    }
}

static void mat_transpose3(const double a[16], double out[16])
{
    /* Rotation-only inverse. */
    mat_identity(out);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) out[c * 4 + r] = a[r * 4 + c];
}

lk_status lk_skeleton_pose(const lk_skeleton *skeleton, const lk_motion *motion, size_t frame, double *out,
                           lk_error *error)
{
    if (!skeleton || !out || skeleton->bone_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "lk_skeleton_pose: empty skeleton");
    if (frame != SIZE_MAX && (!motion || frame >= motion->frame_count))
        return lk_error_set(error, LK_ERR_RANGE, "motion has no frame %zu", frame);
    double to_radians = skeleton->angles_in_radians ? 1.0 : LK_DEG_TO_RAD;
    /* Bone start points in world space, from the base pose walk. */
    for (size_t b = 0; b < skeleton->bone_count; b++) {
        const lk_bone *bone = &skeleton->bones[b];
        const double *values =
            frame == SIZE_MAX ? NULL : motion->values + frame * motion->channel_count + motion->channel_offset[b];
        double rotation_angles[3] = {0, 0, 0}, translation[3] = {0, 0, 0};
        char order[4] = {0};
        int rotations = 0;
        for (unsigned k = 0; k < bone->dof_count; k++) {
            double value = values ? values[k] : 0;
            if (!isfinite(value))
                return lk_error_set(error, LK_ERR_RANGE, "frame %zu: bone '%s' channel %u is not finite", frame + 1,
                                    bone->name, k + 1);
            lk_dof dof = bone->dof[k];
            if (dof <= LK_DOF_TZ)
                translation[dof] = value;
            else if (dof <= LK_DOF_RZ) {
                rotation_angles[dof - LK_DOF_RX] = value;
                if (rotations < 3) order[rotations++] = (char)('X' + (dof - LK_DOF_RX));
            }
        }
        /* C: the bone's local axes; M: the motion in those axes; the world
         * rotation composes parent * C * M * C^-1 (the Acclaim convention). */
        double c[16], c_inverse[16], m[16], local[16];
        euler_matrix(bone->axis, bone->axis_order, to_radians, c);
        mat_transpose3(c, c_inverse);
        euler_matrix(rotation_angles, order, to_radians, m);
        mat_mul(c, m, local);
        mat_mul(local, c_inverse, local);
        double *world = out + 16 * b;
        if (bone->parent < 0) {
            memcpy(world, local, sizeof local);
            for (int k = 0; k < 3; k++) world[12 + k] = skeleton->root_position[k] + translation[k];
        } else {
            const double *parent = out + 16 * (size_t)bone->parent;
            const lk_bone *parent_bone = &skeleton->bones[bone->parent];
            mat_mul(parent, local, world);
            /* Start = parent's start + parent's world rotation applied to the
             * parent's base-pose vector. */
            double offset[3];
            for (int k = 0; k < 3; k++) offset[k] = parent_bone->direction[k] * parent_bone->length;
            for (int r = 0; r < 3; r++)
                world[12 + r] = parent[12 + r] + parent[0 * 4 + r] * offset[0] + parent[1 * 4 + r] * offset[1] +
                                parent[2 * 4 + r] * offset[2];
        }
        world[3] = world[7] = world[11] = 0;
        world[15] = 1;
    }
    return LK_OK;
}

lk_status lk_animation_from_acclaim(const lk_mesh *rest_pose, const lk_skeleton *skeleton, const lk_motion *motion,
                                    const lk_bone_weights *weights, double frames_per_second, lk_animation *out,
                                    lk_animation_report *report, lk_error *error)
{
    lk__budget budget = {LK__ANIM_DEFAULT_MAX_BYTES, 0};
    return lk__animation_from_acclaim(rest_pose, skeleton, motion, weights, frames_per_second, &budget, out, report,
                                      error);
}

lk_status lk__animation_from_acclaim(const lk_mesh *rest_pose, const lk_skeleton *skeleton, const lk_motion *motion,
                                     const lk_bone_weights *weights, double frames_per_second, lk__budget *budget,
                                     lk_animation *out, lk_animation_report *report, lk_error *error)
{
    lk_animation_report local_report;
    if (!report) report = &local_report;
    memset(report, 0, sizeof *report);
    if (!rest_pose || !skeleton || !motion || !weights || !out)
        return lk_error_set(error, LK_ERR_INVALID, "lk_animation_from_acclaim: NULL argument");
    lk_animation_init(out);
    if (weights->vertex_count != rest_pose->vertex_count)
        return lk_error_set(error, LK_ERR_RANGE, "weights are for %zu vertices but the mesh has %zu",
                            weights->vertex_count, rest_pose->vertex_count);
    if (motion->frame_count == 0) return lk_error_set(error, LK_ERR_PARSE, "motion has no frames");
    if (frames_per_second <= 0 || !isfinite(frames_per_second)) frames_per_second = 120;
    size_t bone_count = skeleton->bone_count;
    report->bone_count = bone_count;
    report->key_count = motion->frame_count;
    report->skinned = 1;
    /* Charged with the copy of the rest pose; the frames come next. */
    size_t pair_count = weights->offsets[weights->vertex_count];
    unsigned attributes = (rest_pose->normals ? LK_ATTR_NORMALS : 0u) |
                          (rest_pose->texcoords ? LK_ATTR_TEXCOORDS : 0u) | (rest_pose->colors ? LK_ATTR_COLORS : 0u) |
                          (rest_pose->radii ? LK_ATTR_RADII : 0u);
    if (!lk__budget_charge(budget, pair_count + 1, sizeof(float)) ||
        !lk__budget_charge_mesh(budget, rest_pose->vertex_count, rest_pose->triangle_count, attributes))
        return lk_error_set(error, LK_ERR_LIMIT,
                            "%zu vertices with %zu bone weights need more than the memory budget "
                            "of %zu bytes",
                            rest_pose->vertex_count, pair_count, budget->limit);
    double *base = lk__malloc_array(bone_count, 16 * sizeof(double));
    double *pose = lk__malloc_array(bone_count, 16 * sizeof(double));
    double *skin = lk__malloc_array(bone_count, 16 * sizeof(double));
    float *normalised = lk__malloc_array(pair_count + 1, sizeof(float));
    lk_status status = LK_OK;
    if (!base || !pose || !skin || !normalised) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu bones", bone_count);
        goto done;
    }
    /* Normalise weights once. */
    for (size_t v = 0; v < weights->vertex_count; v++) {
        double sum = 0;
        for (uint32_t k = weights->offsets[v]; k < weights->offsets[v + 1]; k++) sum += weights->weights[k];
        if (weights->offsets[v] == weights->offsets[v + 1] || !(sum > 0)) {
            report->vertices_unweighted++;
            continue;
        }
        if (fabs(sum - 1) > 1e-3) report->weights_normalised++;
        for (uint32_t k = weights->offsets[v]; k < weights->offsets[v + 1]; k++)
            normalised[k] = (float)(weights->weights[k] / sum);
    }
    status = lk_mesh_copy(&out->mesh, rest_pose, error);
    if (status != LK_OK) goto done;
    status = lk__animation_alloc_frames(out, motion->frame_count, budget, "acclaim", error);
    if (status != LK_OK) goto done;
    out->frames_per_second = frames_per_second;
    status = lk_skeleton_pose(skeleton, NULL, SIZE_MAX, base, error);
    if (status != LK_OK) goto done;
    for (size_t b = 0; b < bone_count; b++) {
        /* Base pose inverse: rotation transpose, translation -R^T t. */
        double *m = base + 16 * b, inverse[16];
        mat_transpose3(m, inverse);
        for (int r = 0; r < 3; r++)
            inverse[12 + r] = -(inverse[0 * 4 + r] * m[12] + inverse[1 * 4 + r] * m[13] + inverse[2 * 4 + r] * m[14]);
        memcpy(m, inverse, sizeof inverse);
    }
    size_t vertex_count = rest_pose->vertex_count;
    for (size_t f = 0; f < motion->frame_count; f++) {
        status = lk_skeleton_pose(skeleton, motion, f, pose, error);
        if (status != LK_OK) goto done;
        for (size_t b = 0; b < bone_count; b++) mat_mul(pose + 16 * b, base + 16 * b, skin + 16 * b);
        float *frame = out->frame_positions + f * vertex_count * 3;
        for (size_t v = 0; v < vertex_count; v++) {
            const float *p = rest_pose->positions + 3 * v;
            double acc[3] = {0, 0, 0};
            uint32_t begin = weights->offsets[v], end = weights->offsets[v + 1];
            double sum = 0;
            for (uint32_t k = begin; k < end; k++) sum += weights->weights[k];
            if (begin == end || !(sum > 0)) {
                for (int r = 0; r < 3; r++) frame[3 * v + r] = p[r];
                continue;
            }
            for (uint32_t k = begin; k < end; k++) {
                const double *s = skin + 16 * weights->bones[k];
                double w = normalised[k];
                for (int r = 0; r < 3; r++)
                    acc[r] += w * (s[0 * 4 + r] * p[0] + s[1 * 4 + r] * p[1] + s[2 * 4 + r] * p[2] + s[12 + r]);
            }
            for (int r = 0; r < 3; r++) {
                frame[3 * v + r] = (float)acc[r];
                if (!isfinite(frame[3 * v + r])) {
                    status = lk_error_set(error, LK_ERR_RANGE, "frame %zu: vertex %zu skins to a non-finite position",
                                          f + 1, v + 1);
                    goto done;
                }
            }
        }
    }
    if (vertex_count) memcpy(out->mesh.positions, out->frame_positions, vertex_count * 3 * sizeof(float));
done:
    free(base);
    free(pose);
    free(skin);
    free(normalised);
    if (status != LK_OK) lk_animation_free(out);
    return status;
}
