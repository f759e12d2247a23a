/* SPDX-License-Identifier: MIT */
/* libFuzzer target for the animation readers (src/io_md2.c, io_kmf.c,
 * io_gltf_anim.c, io_acclaim.c). LK_FUZZ_ANIM selects one, compiled
 * once per reader by fuzz/CMakeLists.txt:
 *   "kmf", "md2", "gltfanim": lk_animation_read_memory on the input;
 *   "asf": lk_skeleton_read_memory; "amc" and "wgt": the motion / weight
 *   readers against a fixed three-bone skeleton (tests/data/anim/tube.asf),
 *   and for valid input also the skinning of a small tube.
 * Any input must give an error with a message and empty outputs, or
 * results that keep their contracts; never a crash, a leak or a hang. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "lodkit.h"

static const char tube_asf[] =
    ":units\n angle deg\n:root\n order TX TY TZ RX RY RZ\n axis XYZ\n position 0 0 0\n orientation 0 0 0\n"
    ":bonedata\n begin\n name lower\n direction 0 1 0\n length 1\n axis 0 0 0 XYZ\n dof rx ry rz\n end\n"
    " begin\n name middle\n direction 0 1 0\n length 1\n axis 0 0 90 XYZ\n dof rz\n end\n"
    " begin\n name upper\n direction 0 1 0\n length 1\n axis 0 0 0 XYZ\n dof rx rz\n end\n"
    ":hierarchy\n begin\n root lower\n lower middle\n middle upper\n end\n";

static void check_animation(const uint8_t *data, size_t size, const char *name)
{
    lk_animation animation;
    lk_animation_report report;
    lk_error error = {0};
    /* Small budgets keep every input fast: huge claims must be refused. */
    lk_animation_read_options options = {0};
    options.max_bytes = (size_t)64 << 20;
    options.max_frames = 5000;
    lk_status status = lk_animation_read_memory(data, size, name, &options, &animation, &report, &error);
    if (status == LK_OK) {
        if (lk_animation_validate(&animation, NULL) != LK_OK) abort();
        lk_mesh frame;
        if (lk_animation_frame(&animation, animation.frame_count - 1, &frame, NULL) != LK_OK) abort();
        lk_mesh_free(&frame);
    } else if (error.message[0] == '\0' || animation.frame_positions || animation.mesh.positions) {
        abort();
    }
    lk_animation_free(&animation);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *kind = LK_FUZZ_ANIM;
    if (strcmp(kind, "kmf") == 0)
        check_animation(data, size, "fuzz.kmf");
    else if (strcmp(kind, "md2") == 0)
        check_animation(data, size, "fuzz.md2");
    else if (strcmp(kind, "gltfanim") == 0)
        check_animation(data, size, size >= 4 && memcmp(data, "glTF", 4) == 0 ? "fuzz.glb" : "fuzz.gltf");
    else {
        lk_skeleton skeleton;
        lk_error error = {0};
        if (strcmp(kind, "asf") == 0) {
            lk_status status = lk_skeleton_read_memory((const char *)data, size, "fuzz.asf", &skeleton, &error);
            if (status == LK_OK) {
                if (skeleton.bone_count == 0 || skeleton.bones[0].parent != -1) abort();
                for (size_t b = 1; b < skeleton.bone_count; b++)
                    if (skeleton.bones[b].parent < 0 || (size_t)skeleton.bones[b].parent >= b) abort();
                double *pose = malloc(16 * sizeof(double) * skeleton.bone_count);
                if (!pose || lk_skeleton_pose(&skeleton, NULL, SIZE_MAX, pose, NULL) != LK_OK) abort();
                free(pose);
            } else if (error.message[0] == '\0' || skeleton.bones) {
                abort();
            }
            lk_skeleton_free(&skeleton);
            return 0;
        }
        if (lk_skeleton_read_memory(tube_asf, sizeof tube_asf - 1, "tube.asf", &skeleton, NULL) != LK_OK) abort();
        /* A 4-vertex square skinned by whatever the input says. */
        static const float square[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
        static const uint32_t indices[6] = {0, 1, 2, 1, 3, 2};
        lk_mesh mesh = {0};
        mesh.vertex_count = 4;
        mesh.triangle_count = 2;
        mesh.positions = (float *)square;
        mesh.indices = (uint32_t *)indices;
        lk_motion motion;
        lk_bone_weights weights;
        memset(&motion, 0, sizeof motion);
        memset(&weights, 0, sizeof weights);
        static const char still_motion[] = "1\nroot 0 0 0 0 0 0\nlower 0 0 0\nmiddle 0\nupper 0 0\n";
        static const char all_lower[] = "wgt 1\n1 lower 1\n2 lower 1\n3 middle 1\n4 upper 1\n";
        lk_status status;
        if (strcmp(kind, "amc") == 0) {
            status = lk_motion_read_memory((const char *)data, size, "fuzz.amc", &skeleton, &motion, &error);
            if (status != LK_OK && (error.message[0] == '\0' || motion.values)) abort();
            if (status == LK_OK && lk_bone_weights_read_memory(all_lower, sizeof all_lower - 1, "w.wgt", &skeleton, 4,
                                                               &weights, NULL) != LK_OK)
                abort();
        } else {
            status = lk_bone_weights_read_memory((const char *)data, size, "fuzz.wgt", &skeleton, 4, &weights, &error);
            if (status != LK_OK && (error.message[0] == '\0' || weights.offsets)) abort();
            if (status == LK_OK && lk_motion_read_memory(still_motion, sizeof still_motion - 1, "m.amc", &skeleton,
                                                         &motion, NULL) != LK_OK)
                abort();
        }
        if (status == LK_OK && motion.frame_count <= 2000) {
            lk_animation animation;
            /* Huge motion values may overflow to Inf: an error, not a crash. */
            if (lk_animation_from_acclaim(&mesh, &skeleton, &motion, &weights, 30, &animation, NULL, &error) == LK_OK) {
                if (animation.frame_count != motion.frame_count) abort();
                lk_animation_free(&animation);
            }
        }
        lk_motion_free(&motion);
        lk_bone_weights_free(&weights);
        lk_skeleton_free(&skeleton);
    }
    return 0;
}
