/* SPDX-License-Identifier: MIT */
/* Tests of the animation readers and writers: MD2 (faerie.md2 and
 * sydney.md2 from Assimp's test models), KMF, glTF skins and morph targets
 * (simple_skin, AnimatedMorphCube, documents built here) and the Acclaim
 * set (tests/data/anim/tube.*, a synthetic three-bone tube). */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#define FAERIE "faerie.md2"
#define SYDNEY "assimp/MD2/sydney.md2"
#define SIMPLE_SKIN "assimp/glTF2/simple_skin/simple_skin.gltf"
#define MORPH_CUBE "assimp/glTF2/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf"

/* ---- helpers --------------------------------------------------------------- */

static void load_animation(const char *path, const lk_animation_read_options *options, lk_animation *animation,
                           lk_animation_report *report)
{
    lk_error error = {0};
    lk_status status = lk_animation_read_ex(path, options, animation, report, &error);
    if (status != LK_OK) fail_msg("%s", error.message);
}

/* Reads from memory and expects a failure whose message contains `needle`. */
static void expect_memory_failure(const void *data, size_t size, const char *name, const char *needle)
{
    lk_animation animation;
    lk_error error = {0};
    lk_status status = lk_animation_read_memory(data, size, name, NULL, &animation, NULL, &error);
    if (status == LK_OK) {
        lk_animation_free(&animation);
        fail_msg("%s: expected a failure containing \"%s\"", name, needle);
    }
    assert_int_equal(animation.frame_count, 0);
    assert_null(animation.frame_positions);
    lk_assert_message_contains(error, needle);
}

static double max_frame_difference(const lk_animation *a, const lk_animation *b)
{
    double worst = 0;
    size_t count = a->frame_count * a->mesh.vertex_count * 3;
    for (size_t i = 0; i < count; i++) {
        double d = fabs((double)a->frame_positions[i] - b->frame_positions[i]);
        if (d > worst) worst = d;
    }
    return worst;
}

/* ---- MD2 --------------------------------------------------------------------- */

static void check_md2_sample(const char *name, size_t vertices, size_t triangles, const char *first_frame)
{
    lk_animation animation;
    lk_animation_report report;
    load_animation(lk_test_sample(name), NULL, &animation, &report);
    assert_int_equal(animation.frame_count, 198);
    assert_int_equal(report.key_count, 198);
    assert_int_equal(animation.mesh.vertex_count, vertices);
    assert_int_equal(animation.mesh.triangle_count, triangles);
    assert_true(animation.frames_per_second == 10.0);
    assert_non_null(animation.mesh.texcoords);
    assert_non_null(animation.frame_names);
    assert_string_equal(animation.frame_names[0], first_frame);
    for (size_t v = 0; v < animation.mesh.vertex_count; v++) {
        assert_true(animation.mesh.texcoords[2 * v] >= 0 && animation.mesh.texcoords[2 * v] <= 1);
        assert_true(animation.mesh.texcoords[2 * v + 1] >= 0 && animation.mesh.texcoords[2 * v + 1] <= 1);
    }
    /* mesh.positions is frame 0; every frame moves some vertex. */
    assert_memory_equal(animation.mesh.positions, animation.frame_positions, vertices * 3 * sizeof(float));
    size_t moving_frames = 0;
    for (size_t f = 1; f < animation.frame_count; f++)
        if (memcmp(animation.frame_positions + f * vertices * 3, animation.frame_positions + (f - 1) * vertices * 3,
                   vertices * 3 * sizeof(float)) != 0)
            moving_frames++;
    assert_true(moving_frames > 150);
    /* Outward orientation after the clockwise -> counter-clockwise swap:
     * frame 0 encloses a positive volume. */
    double volume = 0;
    for (size_t t = 0; t < triangles; t++) {
        const float *a = animation.mesh.positions + 3 * animation.mesh.indices[3 * t];
        const float *b = animation.mesh.positions + 3 * animation.mesh.indices[3 * t + 1];
        const float *c = animation.mesh.positions + 3 * animation.mesh.indices[3 * t + 2];
        volume +=
            (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) - a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
             a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) /
            6;
    }
    assert_true(volume > 100);
    /* Plain mesh reading gives frame 0. */
    lk_mesh mesh;
    lk_test_load(lk_test_sample(name), &mesh);
    assert_int_equal(mesh.vertex_count, vertices);
    assert_int_equal(mesh.triangle_count, triangles);
    assert_memory_equal(mesh.positions, animation.frame_positions, vertices * 3 * sizeof(float));
    assert_memory_equal(mesh.indices, animation.mesh.indices, triangles * 3 * sizeof(uint32_t));
    lk_mesh_free(&mesh);
    lk_animation_free(&animation);
}

static void test_md2_faerie(void **state)
{
    (void)state;
    /* 366 positions x 487 texture coordinates in the file, welded into
     * 503 (position, st) vertices used by 654 triangles. */
    check_md2_sample(FAERIE, 503, 654, "stand01");
}

static void test_md2_sydney(void **state)
{
    (void)state;
    check_md2_sample(SYDNEY, 482, 679, "stand1");
}

static void test_md2_write_roundtrip(void **state)
{
    (void)state;
    lk_animation original, again;
    load_animation(lk_test_sample(FAERIE), NULL, &original, NULL);
    const char *path = lk_test_tmpfile("faerie-copy.md2");
    lk_error error = {0};
    assert_int_equal(lk_animation_write(path, &original, &error), LK_OK);
    load_animation(path, NULL, &again, NULL);
    assert_int_equal(again.frame_count, 198);
    assert_int_equal(again.mesh.vertex_count, original.mesh.vertex_count);
    assert_int_equal(again.mesh.triangle_count, original.mesh.triangle_count);
    assert_memory_equal(again.mesh.indices, original.mesh.indices, original.mesh.triangle_count * 3 * sizeof(uint32_t));
    /* The skin size (220 x 193) is recovered, so texcoords are exact. */
    assert_memory_equal(again.mesh.texcoords, original.mesh.texcoords, original.mesh.vertex_count * 2 * sizeof(float));
    assert_string_equal(again.frame_names[197], original.frame_names[197]);
    /* Positions: re-quantised per frame to 8 bits per axis, so each moves
     * by at most half a step of that frame's grid. */
    size_t vertex_count = original.mesh.vertex_count;
    double worst_ratio = 0;
    for (size_t f = 0; f < original.frame_count; f++) {
        const float *a = original.frame_positions + f * vertex_count * 3,
                    *b = again.frame_positions + f * vertex_count * 3;
        for (int k = 0; k < 3; k++) {
            float lo = a[k], hi = a[k];
            for (size_t v = 1; v < vertex_count; v++) {
                if (a[3 * v + k] < lo) lo = a[3 * v + k];
                if (a[3 * v + k] > hi) hi = a[3 * v + k];
            }
            double half_step = (hi - lo) / 255.0 / 2;
            for (size_t v = 0; v < vertex_count; v++) {
                double d = fabs((double)a[3 * v + k] - b[3 * v + k]);
                if (half_step > 0 && d / half_step > worst_ratio) worst_ratio = d / half_step;
            }
        }
    }
    assert_true(worst_ratio <= 1.001);
    lk_animation_free(&original);
    lk_animation_free(&again);
}

static void put_i32(unsigned char *p, int32_t v) { memcpy(p, &v, 4); }

static void test_md2_truncated_and_corrupt(void **state)
{
    (void)state;
    size_t size;
    unsigned char *data = lk_test_read_file(lk_test_sample(FAERIE), &size);
    /* Every truncation fails cleanly: the header's blocks reach the end. */
    for (size_t cut = 0; cut < size; cut += cut < 256 ? 1 : 997) {
        lk_animation animation;
        lk_error error = {0};
        lk_status status = lk_animation_read_memory(data, cut, "cut.md2", NULL, &animation, NULL, &error);
        assert_int_not_equal(status, LK_OK);
        assert_true(error.message[0] != '\0');
        assert_null(animation.frame_positions);
    }
    expect_memory_failure(data, 0, "empty.md2", "empty file");
    expect_memory_failure(data, 40, "short.md2", "byte 40: file ends inside the 68-byte MD2 header");
    expect_memory_failure(data, size - 1, "cut.md2", "GL command block (3335 x 4 bytes) runs past the end");
    expect_memory_failure(data, 307656, "cut.md2", "GL command block");
    expect_memory_failure(data, 307655, "cut.md2", "frame block (198 x 1504 bytes) runs past the end");

    unsigned char *copy = malloc(size);
    assert_non_null(copy);
#define CORRUPT(offset, value, needle)                                                                                 \
    do {                                                                                                               \
        memcpy(copy, data, size);                                                                                      \
        put_i32(copy + (offset), (value));                                                                             \
        expect_memory_failure(copy, size, "bad.md2", (needle));                                                        \
    } while (0)
    CORRUPT(0, 0x32504449 + 1, "not an MD2 file");
    CORRUPT(4, 7, "MD2 version 7");
    CORRUPT(40, 0x7FFFFFFF, "frames is more than the limit"); /* frame count */
    CORRUPT(40, 5000, "frame block");                         /* plausible but past the end */
    CORRUPT(32, 0x40000000, "triangle block");                /* triangle count */
    CORRUPT(24, -5, "negative vertex count");
    CORRUPT(24, 2000, "frame size 1504 is too small for 2000 vertices");
    CORRUPT(56, 400000, "frame block"); /* frames offset */
    CORRUPT(52, -1, "negative triangles offset");
    /* A triangle pointing past the vertices (first triangle at 2016). */
    memcpy(copy, data, size);
    copy[2016] = 0xFF, copy[2017] = 0x7F;
    expect_memory_failure(copy, size, "bad.md2", "byte 2016: triangle 0 uses vertex 32767 but the model has 366");
    /* A texture coordinate index past the st block. */
    memcpy(copy, data, size);
    copy[2016 + 6] = 0xFF, copy[2017 + 6] = 0xFF;
    expect_memory_failure(copy, size, "bad.md2", "uses texture coordinate 65535 but the model has 487");
    /* NaN scale in frame 0 (frames at 9864). */
    memcpy(copy, data, size);
    put_i32(copy + 9864, 0x7FC00000);
    expect_memory_failure(copy, size, "bad.md2", "byte 9864: frame 0 has a non-finite scale");
#undef CORRUPT
    free(copy);
    free(data);
}

/* ---- KMF --------------------------------------------------------------------- */

static void test_kmf_roundtrip_exact(void **state)
{
    (void)state;
    lk_animation original, again;
    load_animation(lk_test_sample(FAERIE), NULL, &original, NULL);
    const char *path = lk_test_tmpfile("faerie.kmf");
    lk_error error = {0};
    assert_int_equal(lk_animation_write(path, &original, &error), LK_OK);
    load_animation(path, NULL, &again, NULL);
    assert_int_equal(again.frame_count, original.frame_count);
    assert_int_equal(again.mesh.vertex_count, original.mesh.vertex_count);
    assert_int_equal(again.mesh.triangle_count, original.mesh.triangle_count);
    assert_true(again.frames_per_second == original.frames_per_second);
    /* Bit-exact floats. */
    assert_memory_equal(again.frame_positions, original.frame_positions,
                        original.frame_count * original.mesh.vertex_count * 3 * sizeof(float));
    assert_memory_equal(again.mesh.positions, original.mesh.positions, original.mesh.vertex_count * 3 * sizeof(float));
    assert_memory_equal(again.mesh.texcoords, original.mesh.texcoords, original.mesh.vertex_count * 2 * sizeof(float));
    assert_memory_equal(again.mesh.indices, original.mesh.indices, original.mesh.triangle_count * 3 * sizeof(uint32_t));
    for (size_t f = 0; f < original.frame_count; f++)
        assert_string_equal(again.frame_names[f], original.frame_names[f]);
    /* Writing again gives the same bytes (deterministic). */
    const char *path2 = lk_test_tmpfile("faerie2.kmf");
    assert_int_equal(lk_animation_write(path2, &again, &error), LK_OK);
    size_t size1, size2;
    unsigned char *a = lk_test_read_file(path, &size1), *b = lk_test_read_file(path2, &size2);
    assert_int_equal(size1, size2);
    assert_memory_equal(a, b, size1);
    free(a);
    free(b);
    /* A mesh reader sees frame 0. */
    lk_mesh mesh;
    lk_test_load(path, &mesh);
    assert_int_equal(mesh.vertex_count, 503);
    assert_memory_equal(mesh.positions, original.frame_positions, 503 * 3 * sizeof(float));
    lk_mesh_free(&mesh);
    lk_animation_free(&original);
    lk_animation_free(&again);
}

static void test_kmf_small_and_errors(void **state)
{
    (void)state;
    const char *good = "# two frames of a triangle\n"
                       "kmf 1\nframes 2\nfps 24\n"
                       "frame rest\nv 0 0 0\nv 1 0 0\nv 0 1 0\nr 0 0\nr 1 0\nr 0 1\nf 1 2 3\n"
                       "frame moved\nv 0 0 1\nv 1 0 1\nv 0.5 1e-3 1 # comment\n";
    lk_animation animation;
    lk_error error = {0};
    assert_int_equal(lk_animation_read_memory(good, strlen(good), "t.kmf", NULL, &animation, NULL, &error), LK_OK);
    assert_int_equal(animation.frame_count, 2);
    assert_int_equal(animation.mesh.vertex_count, 3);
    assert_true(animation.frames_per_second == 24);
    assert_string_equal(animation.frame_names[1], "moved");
    assert_true(animation.frame_positions[9 + 6] == 0.5f && animation.frame_positions[9 + 7] == 1e-3f);
    assert_non_null(animation.mesh.texcoords);
    lk_animation_free(&animation);

    struct {
        const char *text, *needle;
    } cases[] = {
        {"", "empty file"},
        {"kmf 2\nframes 1\nfps 1\nframe\nv 0 0 0\n", "t.kmf:1: KMF version 2"},
        {"ply\n", "t.kmf:1: not a KMF file"},
        {"kmf 1\nframes 0\nfps 1\n", "t.kmf:2: frame count 0"},
        {"kmf 1\nframes 2\nfps -1\n", "t.kmf:3: fps -1"},
        {"kmf 1\nframes 3\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\n",
         "missing frames"},
        {"kmf 1\nframes 1\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\n",
         "t.kmf:9: frame 1 found but the header says 1 frames"},
        {"kmf 1\nframes 2\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe\nv 0 0 0\nv 1 0 0\n",
         "frame 1 (line 9) has 2 vertices but frame 0 has 3"},
        {"kmf 1\nframes 3\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe\nv 0 0 0\nv 1 0 0\nframe\nv 0 0 "
         "0\nv 1 0 0\nv 0 1 0\n",
         "t.kmf:12: frame 1 (line 9) has 2 vertices but frame 0 has 3"},
        {"kmf 1\nframes 2\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 "
         "1\n",
         "t.kmf:13: frame 1 has more vertices than frame 0 (3)"},
        {"kmf 1\nframes 2\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe\nv 0 0 0\nf 1 2 3\n",
         "t.kmf:11: unexpected 'f' in frame 1"},
        {"kmf 1\nframes 2\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe\nv 0 nan 0\nv 1 0 0\nv 0 1 0\n",
         "t.kmf:10: 'v' value nan is not a finite float"},
        {"kmf 1\nframes 1\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nf 1 2 5\n", "t.kmf:7: vertex index 5 out of range"},
        {"kmf 1\nframes 50000\nfps 1\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "missing frames?"},
        {"kmf 1\nframes 1\nfps 1\nv 0 0 0\n", "t.kmf:4: expected 'frame' after the header"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_memory_failure(cases[i].text, strlen(cases[i].text), "t.kmf", cases[i].needle);
}

/* ---- glTF ---------------------------------------------------------------------- */

/* simple_skin.gltf: what "rest pose" means there. Its two inverse bind
 * matrices are both translate(-0.5, -1, 0), i.e. the bind pose puts both
 * joints at (0.5, 1, 0); but the node transforms put joint nodes 1 and 2 at
 * (0, 1, 0) (node 2 is a child of node 1 with no translation) and the
 * animation's first key is the identity rotation. So at t = 0 every joint
 * matrix is translate(0,1,0) * translate(-0.5,-1,0) = translate(-0.5, 0, 0):
 * skinning reproduces the bind-pose shape exactly, moved by -0.5 in x. That
 * is what the file says (the node transforms and inverseBindMatrices
 * disagree by that offset), and what is asserted here; the
 * "rest pose == frame 0" identity itself is asserted on a skin built below
 * whose inverse bind matrices match its nodes. */
static void test_gltf_simple_skin(void **state)
{
    (void)state;
    lk_animation animation;
    lk_animation_report report;
    load_animation(lk_test_sample(SIMPLE_SKIN), NULL, &animation, &report);
    lk_mesh bind;
    lk_test_load(lk_test_sample(SIMPLE_SKIN), &bind);
    assert_int_equal(animation.frame_count, 12); /* key times 0, 0.5, ..., 5.5 */
    assert_int_equal(report.key_count, 12);
    assert_true(report.skinned);
    assert_int_equal(report.bone_count, 2);
    assert_int_equal(report.weights_normalised, 0);
    assert_int_equal(animation.mesh.vertex_count, 10);
    assert_int_equal(animation.mesh.triangle_count, 8);
    assert_true(fabs(animation.frames_per_second - 2.0) < 1e-9);
    /* lk_mesh_read poses the skin at the nodes' own transforms too (glTF
     * ignores the skinned mesh node's transform): vertex 0, (0, 0, 0) in
     * the file, is at (-0.5, 0, 0), where a viewer draws it; the first key
     * is the identity rotation, so frame 0 is that rest pose. */
    assert_float_equal(bind.positions[0], -0.5f, 1e-6);
    assert_float_equal(bind.positions[1], 0.0f, 1e-6);
    for (size_t v = 0; v < 10; v++) {
        assert_float_equal(animation.frame_positions[3 * v], bind.positions[3 * v], 1e-6);
        assert_float_equal(animation.frame_positions[3 * v + 1], bind.positions[3 * v + 1], 1e-6);
        assert_float_equal(animation.frame_positions[3 * v + 2], bind.positions[3 * v + 2], 1e-6);
    }
    /* t = 1.5 (frame 3): joint 2 is rotated 90 degrees about z (0.707,
     * 0.707 in the file). The top vertices (0,2,0) and (1,2,0) hang on
     * joint 2 only: T(0,1,0) Rz(90) T(-0.5,-1,0) maps them to (-1,0.5,0)
     * and (-1,1.5,0); the bottom ones hang on joint 1 and only shift. */
    const float *frame3 = animation.frame_positions + 3 * 10 * 3;
    assert_float_equal(frame3[3 * 8 + 0], -1.0f, 1e-3);
    assert_float_equal(frame3[3 * 8 + 1], 0.5f, 1e-3);
    assert_float_equal(frame3[3 * 9 + 0], -1.0f, 1e-3);
    assert_float_equal(frame3[3 * 9 + 1], 1.5f, 1e-3);
    assert_float_equal(frame3[0], -0.5f, 1e-6);
    assert_float_equal(frame3[1], 0.0f, 1e-6);
    lk_mesh_free(&bind);
    lk_animation_free(&animation);

    /* Resampling at 10 fps over [0, 5.5] gives 56 frames. */
    lk_animation_read_options options = {0};
    options.frames_per_second = 10;
    load_animation(lk_test_sample(SIMPLE_SKIN), &options, &animation, NULL);
    assert_int_equal(animation.frame_count, 56);
    assert_true(animation.frames_per_second == 10);
    lk_animation_free(&animation);
}

static void append_floats(unsigned char *buffer, size_t *offset, const float *values, size_t count)
{
    memcpy(buffer + *offset, values, count * sizeof(float));
    *offset += count * sizeof(float);
}

/* A 2-joint skin whose inverse bind matrices are the inverses of the joint
 * nodes' world matrices (joint 0 at (1,2,3) rotated 90 degrees about y,
 * joint 1 one unit above it): the standard case, where skinning at the
 * first key (identity animation value) must give back the bind pose. The
 * `weights_scale` multiplies every weight (2 -> sums of 2, normalised). */
static char *build_skin_gltf(float weights_scale, const char *interpolation, int joint_override)
{
    unsigned char bin[1024];
    size_t offset = 0;
    float positions[12] = {0, 0, 0, 1, 0, 0, 0, 2, 0, 1, 2, 1};
    append_floats(bin, &offset, positions, 12); /* 0: 48 bytes */
    uint8_t joints[16] = {0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
    if (joint_override >= 0) joints[0] = (uint8_t)joint_override;
    memcpy(bin + offset, joints, 16); /* 48: 16 bytes */
    offset += 16;
    float weights[16] = {1, 0, 0, 0, 0.5f, 0.5f, 0, 0, 1, 0, 0, 0, 0.25f, 0.75f, 0, 0};
    for (int i = 0; i < 16; i++) weights[i] *= weights_scale;
    append_floats(bin, &offset, weights, 16); /* 64: 64 bytes */
    /* World of joint 0: T(1,2,3) Ry(90): x -> -z, z -> x. Inverse: Ry(-90) T(-1,-2,-3). */
    float ibm[32] = {0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0, 0, 3, -2, -1, 1,
                     /* joint 1: world T(1,2,3) Ry(90) T(0,1,0) -> inverse adds -1 in y */
                     0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0, 0, 3, -3, -1, 1};
    append_floats(bin, &offset, ibm, 32); /* 128: 128 bytes */
    float times[2] = {0, 1};
    append_floats(bin, &offset, times, 2); /* 256: 8 bytes */
    float rotations[8] = {0, 0, 0, 1, 0.70710678f, 0, 0, 0.70710678f};
    append_floats(bin, &offset, rotations, 8); /* 264: 32 bytes */
    uint16_t indices[6] = {0, 1, 2, 1, 3, 2};
    memcpy(bin + offset, indices, 12); /* 296: 12 bytes */
    offset += 12;
    char encoded[2048];
    lk_test_base64(bin, offset, encoded);
    char *json = malloc(8192);
    assert_non_null(json);
    snprintf(json, 8192,
             "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0,1]}],"
             "\"nodes\":[{\"mesh\":0,\"skin\":0,\"translation\":[5,5,5]},"
             "{\"translation\":[1,2,3],\"rotation\":[0,0.70710678,0,0.70710678],\"children\":[2]},"
             "{\"translation\":[0,1,0]}],"
             "\"skins\":[{\"joints\":[1,2],\"inverseBindMatrices\":4}],"
             "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"JOINTS_0\":1,\"WEIGHTS_0\":2},\"indices\":"
             "5}]}],"
             "\"animations\":[{\"samplers\":[{\"input\":3,\"output\":6,\"interpolation\":\"%s\"}],"
             "\"channels\":[{\"sampler\":0,\"target\":{\"node\":2,\"path\":\"rotation\"}}]}],"
             "\"buffers\":[{\"byteLength\":%zu,\"uri\":\"data:application/octet-stream;base64,%s\"}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48},{\"buffer\":0,\"byteOffset\":48,"
             "\"byteLength\":16},"
             "{\"buffer\":0,\"byteOffset\":64,\"byteLength\":64},{\"buffer\":0,\"byteOffset\":128,\"byteLength\":128},"
             "{\"buffer\":0,\"byteOffset\":256,\"byteLength\":8},{\"buffer\":0,\"byteOffset\":264,\"byteLength\":32},"
             "{\"buffer\":0,\"byteOffset\":296,\"byteLength\":12}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\",\"min\":[0,0,0],"
             "\"max\":[1,2,1]},"
             "{\"bufferView\":1,\"componentType\":5121,\"count\":4,\"type\":\"VEC4\"},"
             "{\"bufferView\":2,\"componentType\":5126,\"count\":4,\"type\":\"VEC4\"},"
             "{\"bufferView\":4,\"componentType\":5126,\"count\":2,\"type\":\"SCALAR\",\"min\":[0],\"max\":[1]},"
             "{\"bufferView\":3,\"componentType\":5126,\"count\":2,\"type\":\"MAT4\"},"
             "{\"bufferView\":6,\"componentType\":5123,\"count\":6,\"type\":\"SCALAR\"},"
             "{\"bufferView\":5,\"componentType\":5126,\"count\":2,\"type\":\"VEC4\"}]}",
             interpolation, offset, encoded);
    return json;
}

static void test_gltf_skin_rest_pose(void **state)
{
    (void)state;
    char *json = build_skin_gltf(1, "LINEAR", -1);
    lk_animation animation;
    lk_animation_report report;
    lk_error error = {0};
    assert_int_equal(lk_animation_read_memory(json, strlen(json), "skin.gltf", NULL, &animation, &report, &error),
                     LK_OK);
    assert_int_equal(animation.frame_count, 2);
    assert_true(report.skinned);
    assert_int_equal(report.weights_normalised, 0);
    /* Frame 0 = bind pose (the POSITION data: a skinned mesh ignores its
     * node's translation (5,5,5)). */
    static const float bind[12] = {0, 0, 0, 1, 0, 0, 0, 2, 0, 1, 2, 1};
    for (int i = 0; i < 12; i++) assert_float_equal(animation.frame_positions[i], bind[i], 1e-5);
    /* Frame 1: joint 1 (world origin (1,3,3)) turns 90 degrees about its
     * local x axis, which the parent's Ry(90) points along world -z. Vertex
     * 2 (0,2,0) hangs on joint 1 only: its offset (-1,-1,-3) from the joint
     * becomes (-1,1,-3), so it lands at (0,4,0). */
    const float *frame1 = animation.frame_positions + 12;
    for (int k = 0; k < 3; k++) assert_float_equal(frame1[k], bind[k], 1e-5); /* vertex 0: joint 0 only */
    static const float expected_v2[3] = {0, 4, 0};
    for (int k = 0; k < 3; k++) assert_float_equal(frame1[6 + k], expected_v2[k], 1e-5);
    lk_animation_free(&animation);
    free(json);

    /* STEP holds the first key until t = 1: same frames here (keys only). */
    json = build_skin_gltf(1, "STEP", -1);
    assert_int_equal(lk_animation_read_memory(json, strlen(json), "skin.gltf", NULL, &animation, NULL, &error), LK_OK);
    assert_float_equal(animation.frame_positions[12 + 7], 4, 1e-5);
    lk_animation_free(&animation);
    lk_animation_read_options options = {0};
    options.frames_per_second = 4; /* t = 0, .25, .5, .75, 1: STEP keeps the bind pose until 1 */
    assert_int_equal(lk_animation_read_memory(json, strlen(json), "skin.gltf", &options, &animation, NULL, &error),
                     LK_OK);
    assert_int_equal(animation.frame_count, 5);
    assert_float_equal(animation.frame_positions[3 * 12 + 7], 2, 1e-5);
    lk_animation_free(&animation);
    free(json);

    /* Weights summing to 2 are normalised and counted. */
    json = build_skin_gltf(2, "LINEAR", -1);
    assert_int_equal(lk_animation_read_memory(json, strlen(json), "skin.gltf", NULL, &animation, &report, &error),
                     LK_OK);
    assert_int_equal(report.weights_normalised, 4);
    for (int i = 0; i < 12; i++) assert_float_equal(animation.frame_positions[i], bind[i], 1e-5);
    lk_animation_free(&animation);
    free(json);

    json = build_skin_gltf(1, "CUBICSPLINE", -1);
    expect_memory_failure(json, strlen(json), "skin.gltf", "CUBICSPLINE is not supported");
    free(json);
    json = build_skin_gltf(1, "LINEAR", 7);
    expect_memory_failure(json, strlen(json), "skin.gltf", "vertex 0 uses joint 7 but skins[0] has 2 joints");
    free(json);
}

static void test_gltf_morph_cube(void **state)
{
    (void)state;
    lk_animation animation;
    lk_animation_report report;
    load_animation(lk_test_sample(MORPH_CUBE), NULL, &animation, &report);
    assert_int_equal(animation.frame_count, 127);
    assert_int_equal(report.key_count, 127);
    assert_true(report.morphed);
    assert_false(report.skinned);
    assert_int_equal(animation.mesh.vertex_count, 24);
    assert_int_equal(animation.mesh.triangle_count, 12);
    /* Weights start at (0, 0): frame 0 is the static mesh. */
    lk_mesh mesh;
    lk_test_load(lk_test_sample(MORPH_CUBE), &mesh);
    for (size_t i = 0; i < 24 * 3; i++) assert_float_equal(animation.frame_positions[i], mesh.positions[i], 1e-4);
    /* Some frame moves a vertex by a visible fraction of the cube's size. */
    double largest = 0;
    for (size_t f = 1; f < animation.frame_count; f++)
        for (size_t i = 0; i < 24 * 3; i++) {
            double d = fabs((double)animation.frame_positions[f * 72 + i] - animation.frame_positions[i]);
            if (d > largest) largest = d;
        }
    double diagonal = lk_mesh_bounds(&mesh, NULL, NULL);
    print_message("morph cube: largest displacement %g, diagonal %g\n", largest, diagonal);
    assert_true(largest > 0.25 * diagonal);
    lk_mesh_free(&mesh);
    lk_animation_free(&animation);
}

static void test_gltf_write_roundtrip(void **state)
{
    (void)state;
    lk_animation original, again;
    lk_animation_report report;
    load_animation(lk_test_sample(FAERIE), NULL, &original, NULL);
    const char *path = lk_test_tmpfile("faerie.gltf");
    lk_error error = {0};
    assert_int_equal(lk_animation_write(path, &original, &error), LK_OK);
    load_animation(path, NULL, &again, &report);
    assert_true(report.morphed);
    assert_int_equal(again.frame_count, 198);
    assert_int_equal(again.mesh.vertex_count, 503);
    assert_int_equal(again.mesh.triangle_count, 654);
    assert_memory_equal(again.mesh.indices, original.mesh.indices, 654 * 3 * sizeof(uint32_t));
    assert_true(fabs(again.frames_per_second - 10) < 1e-3);
    /* base + (frame - base) in float: within a few ulps of the model size (~60). */
    assert_true(max_frame_difference(&original, &again) < 1e-4);
    for (size_t i = 0; i < 503 * 2; i++) assert_float_equal(again.mesh.texcoords[i], original.mesh.texcoords[i], 1e-6);
    lk_animation_free(&original);
    lk_animation_free(&again);
}

/* ---- Acclaim ---------------------------------------------------------------- */

static void test_acclaim_tube(void **state)
{
    (void)state;
    lk_animation animation;
    lk_animation_report report;
    load_animation(lk_test_data("anim/tube.amc"), NULL, &animation, &report);
    assert_int_equal(animation.frame_count, 10);
    assert_int_equal(animation.mesh.vertex_count, 104);
    assert_int_equal(animation.mesh.triangle_count, 192);
    assert_int_equal(report.bone_count, 4);
    assert_int_equal(report.key_count, 10);
    assert_int_equal(report.weights_normalised, 0);
    assert_int_equal(report.vertices_unweighted, 0);
    assert_true(animation.frames_per_second == 120);
    lk_mesh rest;
    lk_test_load(lk_test_data("anim/tube.smf"), &rest);
    /* AMC frame 1 is all zeros: the ASF base pose, so the rest mesh. */
    for (size_t i = 0; i < 104 * 3; i++) assert_float_equal(animation.frame_positions[i], rest.positions[i], 1e-6);
    /* Frame index 2 (AMC frame 3): root tx 0.2, middle rz 20 degrees.
     * Vertex 97 (0.2, 3, 0) hangs on `upper` only and turns about the
     * middle joint (0,1,0): (0.2,2,0) rotated by 20 degrees, plus (0.2,1,0). */
    const float *frame2 = animation.frame_positions + 2 * 104 * 3;
    double angle = 20 * 3.14159265358979323846 / 180;
    assert_float_equal(frame2[96 * 3 + 0], 0.2 * cos(angle) - 2 * sin(angle) + 0.2, 1e-5);
    assert_float_equal(frame2[96 * 3 + 1], 0.2 * sin(angle) + 2 * cos(angle) + 1, 1e-5);
    assert_float_equal(frame2[96 * 3 + 2], 0, 1e-6);
    /* Vertex 1 (0.2, 0, 0) hangs on `lower`, which does not turn: it slides. */
    assert_float_equal(frame2[0], 0.4, 1e-6);
    /* Frame index 9 (AMC 10): upper also twists 25 degrees about x; the
     * top ring stays 1 unit from the upper joint. */
    const float *frame9 = animation.frame_positions + 9 * 104 * 3;
    double middle = 90 * 3.14159265358979323846 / 180;
    double joint[3] = {0.9 - sin(middle), 1 + cos(middle), 0};
    for (size_t v = 96; v < 104; v++) {
        double dx = frame9[3 * v] - joint[0], dy = frame9[3 * v + 1] - joint[1], dz = frame9[3 * v + 2] - joint[2];
        assert_float_equal(sqrt(dx * dx + dy * dy + dz * dz), sqrt(1 + 0.04), 1e-5);
    }
    lk_mesh_free(&rest);
    lk_animation_free(&animation);
}

static const char *tube_asf_path(void) { return lk_test_data("anim/tube.asf"); }

static void test_acclaim_errors(void **state)
{
    (void)state;
    lk_skeleton skeleton;
    lk_error error = {0};
    assert_int_equal(lk_skeleton_read(tube_asf_path(), &skeleton, &error), LK_OK);
    assert_int_equal(skeleton.bone_count, 4);
    assert_string_equal(skeleton.bones[0].name, "root");
    assert_string_equal(skeleton.bones[2].name, "middle");
    assert_int_equal(skeleton.bones[2].parent, 1);
    assert_int_equal(skeleton.bones[2].dof_count, 1);
    assert_int_equal(skeleton.bones[2].dof[0], LK_DOF_RZ);
    assert_string_equal(skeleton.bones[2].axis_order, "XYZ");
    assert_float_equal(skeleton.bones[2].axis[2], 90, 0);
    assert_float_equal(skeleton.bones[3].limits[1][1], 90, 0);
    assert_int_equal(skeleton.bones[0].dof_count, 6);

    struct {
        const char *text, *needle;
    } amc[] = {
        {"1\nroot 0 0 0 0 0 0\nlower 0 0 0\nmiddle 0\nupper 0 0\nfoot 1 2\n", "m.amc:6: unknown bone 'foot'"},
        {"1\nroot 0 0 0 0 0 0\nlower 0 0 0\nmiddle 0\nupper 0 0\n3\n", "m.amc:6: frame 3 follows frame 1"},
        {"1\nroot 0 0 0 0 0 0\nlower 0 0 nan\nmiddle 0\nupper 0 0\n", "m.amc:3: bone 'lower' value 3 is not finite"},
        {"1\nroot 0 0 0 0 0 0\nlower 0 0 0\nupper 0 0\n", "m.amc:1: frame 1 lacks bone 'middle'"},
        {"1\nroot 0 0 0 0 0 0\nlower 0 0\nmiddle 0\nupper 0 0\n", "m.amc:3: bone 'lower' needs 3 values, got 2"},
        {"1\nroot 0 0 0 0 0 0\nlower 0 0 0 0\n", "m.amc:3: bone 'lower' has more than 3 values"},
        {"root 0 0 0 0 0 0\n", "before the first frame number"},
        {":FULLY-SPECIFIED\n", "no frames"},
        {"", "empty file"},
    };
    for (size_t i = 0; i < sizeof amc / sizeof amc[0]; i++) {
        lk_motion motion;
        lk_error_clear(&error);
        assert_int_not_equal(
            lk_motion_read_memory(amc[i].text, strlen(amc[i].text), "m.amc", &skeleton, &motion, &error), LK_OK);
        assert_null(motion.values);
        lk_assert_message_contains(error, amc[i].needle);
    }
    struct {
        const char *text, *needle;
    } wgt[] = {
        {"wgt 1\n1 lower 1\n2 elbow 1\n", "w.wgt:3: unknown bone 'elbow'"},
        {"wgt 1\n5 lower 1\n", "w.wgt:2: vertex 5 out of range (the mesh has 4)"},
        {"wgt 1\n1 lower 1\n1 upper 1\n", "w.wgt:3: vertex 1 already listed at line 2"},
        {"wgt 1\n1 lower -1\n", "w.wgt:2: weight -1 of bone 'lower'"},
        {"wgt 1\n1 lower nan\n", "w.wgt:2: weight nan"},
        {"wgt 1\n1 lower\n", "w.wgt:2: expected a weight after bone 'lower'"},
        {"wgt 1\n1\n", "w.wgt:2: vertex 1 has no 'bone weight' pair"},
        {"wgt 2\n", "w.wgt:1: WGT version 2"},
        {"bones\n", "w.wgt:1: not a WGT file"},
    };
    for (size_t i = 0; i < sizeof wgt / sizeof wgt[0]; i++) {
        lk_bone_weights weights;
        lk_error_clear(&error);
        assert_int_not_equal(
            lk_bone_weights_read_memory(wgt[i].text, strlen(wgt[i].text), "w.wgt", &skeleton, 4, &weights, &error),
            LK_OK);
        assert_null(weights.offsets);
        lk_assert_message_contains(error, wgt[i].needle);
    }
    struct {
        const char *text, *needle;
    } asf[] = {
        {":root\norder TX TY TZ RX RY RZ\n:bonedata\nbegin\nname a\ndirection 0 1 0\nlength "
         "1\nend\n:hierarchy\nbegin\nroot b\nend\n",
         "s.asf:11: unknown bone 'b' in :hierarchy"},
        {":root\n:bonedata\nbegin\nname a\ndirection 0 1 0\nlength 1\nend\nbegin\nname b\ndirection 0 1 0\nlength "
         "1\nend\n"
         ":hierarchy\nbegin\nroot a\nend\n",
         "s.asf:8: bone 'b' is not in the :hierarchy"},
        {":root\n:bonedata\nbegin\nname a\ndirection 0 1 0\nlength 1\nend\nbegin\nname b\ndirection 0 1 0\nlength "
         "1\nend\n"
         ":hierarchy\nbegin\na b\nb a\nend\n",
         "is on a cycle of the :hierarchy"},
        {":root\n:bonedata\nbegin\nname a\ndirection 0 1 0\nlength 1\nend\nbegin\nname a\ndirection 0 1 0\nlength "
         "1\nend\n",
         "s.asf:8: bone 'a' is defined twice"},
        {":root\n:bonedata\nbegin\nname a\ndirection 0 nan 0\nlength 1\nend\n",
         "s.asf:5: 'direction' value is not finite"},
        {":root\n:bonedata\nbegin\nname a\ndirection 0 1 0\nlength 1\ndof rx ry\nlimits (-1 "
         "1)\nend\n:hierarchy\nbegin\nroot a\nend\n",
         "s.asf:9: bone 'a' has 1 limits for 2 dofs"},
        {":root\n:bonedata\nbegin\nname a\ndof rq\nend\n", "s.asf:5: unknown dof 'rq'"},
        {":root\n:bonedata\nbegin\nname a\nlength 1\n", "file ends inside a bone"},
        {":units\nangle grad\n", "s.asf:2: expected 'angle deg' or 'angle rad'"},
        {"name x\n", "s.asf:1: expected an ASF section"},
        {":name x\n", "no :root section"},
    };
    for (size_t i = 0; i < sizeof asf / sizeof asf[0]; i++) {
        lk_skeleton bad;
        lk_error_clear(&error);
        assert_int_not_equal(lk_skeleton_read_memory(asf[i].text, strlen(asf[i].text), "s.asf", &bad, &error), LK_OK);
        assert_null(bad.bones);
        lk_assert_message_contains(error, asf[i].needle);
    }

    /* Weights that do not sum to 1 are normalised and counted: a square of
     * four vertices, two of them with weights summing to 2 and 0.5. */
    static const float square[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    static const uint32_t square_indices[6] = {0, 1, 2, 1, 3, 2};
    lk_mesh mesh;
    lk_test_make_mesh(&mesh, square, 4, square_indices, 2);
    const char *weights_text = "wgt 1\n1 lower 1\n2 lower 1 middle 1\n3 middle 0.25 upper 0.25\n";
    lk_bone_weights weights;
    assert_int_equal(
        lk_bone_weights_read_memory(weights_text, strlen(weights_text), "w.wgt", &skeleton, 4, &weights, &error),
        LK_OK);
    assert_int_equal(weights.offsets[4], 5);
    const char *motion_text = "1\nroot 0 0 0 0 0 0\nlower 0 0 0\nmiddle 0\nupper 0 0\n"
                              "2\nroot 1 0 0 0 0 0\nlower 0 0 0\nmiddle 0\nupper 0 0\n";
    lk_motion motion;
    assert_int_equal(lk_motion_read_memory(motion_text, strlen(motion_text), "m.amc", &skeleton, &motion, &error),
                     LK_OK);
    assert_int_equal(motion.frame_count, 2);
    lk_animation animation;
    lk_animation_report report;
    assert_int_equal(lk_animation_from_acclaim(&mesh, &skeleton, &motion, &weights, 30, &animation, &report, &error),
                     LK_OK);
    assert_int_equal(report.weights_normalised, 2);
    assert_int_equal(report.vertices_unweighted, 1); /* vertex 4 is not listed */
    /* Frame 1 moves every weighted vertex by the root's +1 in x (all bones
     * follow the root rigidly); the unweighted vertex stays at rest. */
    const float *frame1 = animation.frame_positions + 12;
    assert_float_equal(frame1[0], 1, 1e-6);
    assert_float_equal(frame1[3], 2, 1e-6);
    assert_float_equal(frame1[6], 1, 1e-6);
    assert_float_equal(frame1[9], 1, 1e-6);
    lk_animation_free(&animation);
    /* The mesh and the weights must agree on the vertex count. */
    mesh.vertex_count = 3;
    assert_int_not_equal(lk_animation_from_acclaim(&mesh, &skeleton, &motion, &weights, 30, &animation, NULL, &error),
                         LK_OK);
    lk_assert_message_contains(error, "weights are for 4 vertices but the mesh has 3");
    mesh.vertex_count = 4;
    lk_motion_free(&motion);
    lk_bone_weights_free(&weights);
    lk_mesh_free(&mesh);
    lk_skeleton_free(&skeleton);
}

/* ---- writer refusals ----------------------------------------------------------- */

/* Regression (fuzz_gltfanim, 2026-11-22): a skin whose WEIGHTS_0 holds a
 * non-finite value leaked the weights read so far. Refused with the
 * accessor named, and nothing leaks (LeakSanitizer in the ASan suite). */
static void test_gltf_nonfinite_weights(void **state)
{
    (void)state;
    char path[4096];
    snprintf(path, sizeof path, "%s/../../fuzz/corpus/gltfanim/regression-weights-nan-leak.gltf", LK_TEST_DATA_DIR);
    size_t size = 0;
    unsigned char *data = lk_test_read_file(path, &size);
    lk_animation animation;
    lk_animation_init(&animation);
    lk_error error = {0};
    assert_int_not_equal(lk_animation_read_memory(data, size, "leak.gltf", NULL, &animation, NULL, &error), LK_OK);
    lk_assert_message_contains(error, "not finite");
    assert_int_equal(animation.frame_count, 0);
    free(data);
}

/* What a .gltf cannot hold is refused, naming the frame, and leaves no file
 * (regression: the writer used to write an infinity there, which the
 * glTF-Validator rejects and lodkit's own reader refuses). */
static void expect_gltf_write_refused(const char *kmf, const char *needle)
{
    lk_animation animation;
    lk_error error = {0};
    if (lk_animation_read_memory(kmf, strlen(kmf), "refused.kmf", NULL, &animation, NULL, &error) != LK_OK)
        fail_msg("%s", error.message);
    const char *path = lk_test_tmpfile("refused.gltf");
    assert_int_equal(lk_animation_write(path, &animation, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, needle);
    FILE *file = fopen(path, "rb");
    assert_null(file);
    lk_animation_free(&animation);
}

static void test_write_refusals(void **state)
{
    (void)state;
    lk_animation animation;
    load_animation(lk_test_data("anim/tube.amc"), NULL, &animation, NULL);
    lk_error error = {0};
    assert_int_equal(lk_animation_write(lk_test_tmpfile("tube.obj"), &animation, &error), LK_ERR_UNSUPPORTED);
    assert_int_equal(lk_animation_write(lk_test_tmpfile("tube.glb"), &animation, &error), LK_ERR_UNSUPPORTED);
    /* A NaN in a frame is refused and leaves no file behind. */
    animation.frame_positions[5 * 104 * 3 + 7] = NAN;
    const char *path = lk_test_tmpfile("nan.kmf");
    assert_int_equal(lk_animation_write(path, &animation, &error), LK_ERR_RANGE);
    lk_assert_message_contains(error, "frame 5: vertex 2 has a non-finite coordinate");
    FILE *file = fopen(path, "rb");
    assert_null(file);
    lk_animation_free(&animation);
    /* Mesh writers refuse MD2/KMF with a pointer to lk_animation_write. */
    lk_mesh mesh;
    lk_test_make_cube(&mesh);
    assert_int_equal(lk_mesh_write(lk_test_tmpfile("cube.md2"), LK_FORMAT_AUTO, &mesh, NULL, &error),
                     LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "lk_animation_write");
    lk_mesh_free(&mesh);
    /* glTF stores frame f as its offset from frame 0: turned half-way round,
     * vertex 0 moves by 6e38, more than a float's 3.4e38. */
    expect_gltf_write_refused("kmf 1\nframes 2\nfps 10\n"
                              "frame a\nv 3e38 0 0\nv 0 3e38 0\nv 0 0 1\nf 1 2 3\n"
                              "frame b\nv -3e38 0 0\nv 0 -3e38 0\nv 0 0 1\n",
                              "frame 1: vertex 0 moves farther from frame 0 than a float holds");
    /* glTF key times f / fps are floats: 1e300 s is none, and 1e-300 s
     * rounds to 0, the time of frame 0. */
    const char *triangle = "frame a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nframe b\nv 0 0 1\nv 1 0 1\nv 0 1 1\n";
    char kmf[256];
    snprintf(kmf, sizeof kmf, "kmf 1\nframes 2\nfps 1e-300\n%s", triangle);
    expect_gltf_write_refused(kmf, "frame 1's time (1e+300 s) has no float above the previous frame's");
    snprintf(kmf, sizeof kmf, "kmf 1\nframes 2\nfps 1e300\n%s", triangle);
    expect_gltf_write_refused(kmf, "frame 1's time (1e-300 s) has no float above the previous frame's");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_md2_faerie),          cmocka_unit_test(test_md2_sydney),
        cmocka_unit_test(test_md2_write_roundtrip), cmocka_unit_test(test_md2_truncated_and_corrupt),
        cmocka_unit_test(test_kmf_roundtrip_exact), cmocka_unit_test(test_kmf_small_and_errors),
        cmocka_unit_test(test_gltf_simple_skin),    cmocka_unit_test(test_gltf_skin_rest_pose),
        cmocka_unit_test(test_gltf_morph_cube),     cmocka_unit_test(test_gltf_write_roundtrip),
        cmocka_unit_test(test_acclaim_tube),        cmocka_unit_test(test_acclaim_errors),
        cmocka_unit_test(test_write_refusals),      cmocka_unit_test(test_gltf_nonfinite_weights),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
