/* SPDX-License-Identifier: MIT */
/* Core, no samples needed: round trips through every core writer and
 * reader on procedural shapes. Meshes: OBJ, PLY (ASCII, binary little- and
 * big-endian), OFF, SMF, STL (binary and ASCII) and XYZ point sets, read
 * back from the file and from memory; animations: KMF, MD2 and glTF. What
 * each format keeps is compared exactly (positions, normals, texture
 * coordinates bit for bit) or within its documented quantisation (PLY's
 * 8-bit colours, MD2's 8-bit positions). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

enum {
    KEEPS_NORMALS = 1,
    KEEPS_TEXCOORDS = 2,
    KEEPS_COLORS = 4,
    KEEPS_RADII = 8,
    BYTE_COLORS = 16,
    RGB_ONLY = 32,
    /* glTF: normals are normalised again and v is flipped (1 - v) each way,
     * a float rounding or two: within 1e-6 instead of bit for bit. */
    NEAR_FLOATS = 64,
    /* .gltf's buffer is a .bin next to it: not readable from memory. */
    FILE_ONLY = 128
};

typedef struct format_case {
    const char *file;
    lk_format format;
    lk_ply_encoding ply_encoding;
    int stl_ascii;
    unsigned keeps;
} format_case;

static const format_case cases[] = {
    {"shape.obj", LK_FORMAT_OBJ, 0, 0, KEEPS_NORMALS | KEEPS_TEXCOORDS | KEEPS_COLORS | RGB_ONLY},
    {"shape_ascii.ply", LK_FORMAT_PLY, LK_PLY_ASCII, 0,
     KEEPS_NORMALS | KEEPS_TEXCOORDS | KEEPS_COLORS | KEEPS_RADII | BYTE_COLORS},
    {"shape_le.ply", LK_FORMAT_PLY, LK_PLY_BINARY_LE, 0,
     KEEPS_NORMALS | KEEPS_TEXCOORDS | KEEPS_COLORS | KEEPS_RADII | BYTE_COLORS},
    {"shape_be.ply", LK_FORMAT_PLY, LK_PLY_BINARY_BE, 0,
     KEEPS_NORMALS | KEEPS_TEXCOORDS | KEEPS_COLORS | KEEPS_RADII | BYTE_COLORS},
    {"shape.off", LK_FORMAT_OFF, 0, 0, KEEPS_COLORS},
    {"shape.smf", LK_FORMAT_SMF, 0, 0, 0},
    {"shape.stl", LK_FORMAT_STL, 0, 0, 0},
    {"shape_ascii.stl", LK_FORMAT_STL, 0, 1, 0},
    {"shape.glb", LK_FORMAT_GLTF, 0, 0, KEEPS_NORMALS | KEEPS_TEXCOORDS | KEEPS_COLORS | NEAR_FLOATS},
    {"shape.gltf", LK_FORMAT_GLTF, 0, 0, KEEPS_NORMALS | KEEPS_TEXCOORDS | KEEPS_COLORS | NEAR_FLOATS | FILE_ONLY},
};

/* A noisy sphere (positions that need all nine digits) with every
 * attribute: unit normals, spherical texture coordinates, random colours
 * and radii. */
static void attributed_sphere(lk_mesh *mesh)
{
    lk_mesh shape;
    shape_noisy_sphere(&shape, 1.7, 3, 0.1, 11);
    lk_error error = {0};
    if (lk_mesh_alloc(mesh, shape.vertex_count, shape.triangle_count,
                      LK_ATTR_NORMALS | LK_ATTR_TEXCOORDS | LK_ATTR_COLORS | LK_ATTR_RADII, &error) != LK_OK)
        fail_msg("%s", error.message);
    memcpy(mesh->positions, shape.positions, 3 * shape.vertex_count * sizeof(float));
    memcpy(mesh->indices, shape.indices, 3 * shape.triangle_count * sizeof(uint32_t));
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        const float *p = mesh->positions + 3 * v;
        double length = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
        for (int k = 0; k < 3; k++) mesh->normals[3 * v + (size_t)k] = (float)(p[k] / length);
        mesh->texcoords[2 * v] = (float)(atan2(p[1], p[0]) / (2 * SHAPE_PI) + 0.5);
        mesh->texcoords[2 * v + 1] = (float)(acos(p[2] / length) / SHAPE_PI);
        for (int k = 0; k < 4; k++) mesh->colors[4 * v + (size_t)k] = (float)shape_random(5, 4 * v + (size_t)k);
        mesh->radii[v] = (float)(0.01 + 0.05 * shape_random(6, v));
    }
    lk_mesh_free(&shape);
}

static int same_floats(const float *a, const float *b, size_t count)
{
    return memcmp(a, b, count * sizeof(float)) == 0;
}

static int near_floats(const float *a, const float *b, size_t count)
{
    for (size_t i = 0; i < count; i++)
        if (!(fabsf(a[i] - b[i]) <= 1e-6f)) return 0;
    return 1;
}

/* The read mesh equals the written one up to a renumbering of the
 * vertices (STL and OBJ number them in order of first use): same counts,
 * and corner by corner the same position (bit for bit) and the same kept
 * attributes. Triangles keep their order and orientation. */
static void assert_same_mesh(const lk_mesh *written, const lk_mesh *read, unsigned keeps, const char *what)
{
    if (read->vertex_count != written->vertex_count || read->triangle_count != written->triangle_count)
        fail_msg("%s: %zu v %zu t read, %zu v %zu t written", what, read->vertex_count, read->triangle_count,
                 written->vertex_count, written->triangle_count);
    /* What the format keeps and the mesh has comes back; nothing else. */
    if (!written->normals) keeps &= ~(unsigned)KEEPS_NORMALS;
    if (!written->texcoords) keeps &= ~(unsigned)KEEPS_TEXCOORDS;
    if (!written->colors) keeps &= ~(unsigned)KEEPS_COLORS;
    if (!written->radii) keeps &= ~(unsigned)KEEPS_RADII;
    if (!(keeps & KEEPS_NORMALS) != !read->normals) fail_msg("%s: normals kept or not", what);
    if (!(keeps & KEEPS_TEXCOORDS) != !read->texcoords) fail_msg("%s: texcoords kept or not", what);
    if (!(keeps & KEEPS_COLORS) != !read->colors) fail_msg("%s: colours kept or not", what);
    if (!(keeps & KEEPS_RADII) != !read->radii) fail_msg("%s: radii kept or not", what);
    for (size_t c = 0; c < 3 * written->triangle_count; c++) {
        size_t w = written->indices[c], r = read->indices[c];
        if (!same_floats(written->positions + 3 * w, read->positions + 3 * r, 3))
            fail_msg("%s: corner %zu: position differs", what, c);
        int (*same)(const float *, const float *, size_t) = keeps & NEAR_FLOATS ? near_floats : same_floats;
        if ((keeps & KEEPS_NORMALS) && !same(written->normals + 3 * w, read->normals + 3 * r, 3))
            fail_msg("%s: corner %zu: normal differs", what, c);
        if ((keeps & KEEPS_TEXCOORDS) && !same(written->texcoords + 2 * w, read->texcoords + 2 * r, 2))
            fail_msg("%s: corner %zu: texture coordinate differs", what, c);
        if ((keeps & KEEPS_RADII) && written->radii[w] != read->radii[r])
            fail_msg("%s: corner %zu: radius differs", what, c);
        if (keeps & KEEPS_COLORS) {
            for (int k = 0; k < 4; k++) {
                float a = written->colors[4 * w + (size_t)k], b = read->colors[4 * r + (size_t)k];
                if (k == 3 && (keeps & RGB_ONLY)) a = 1; /* OBJ colours are r g b; alpha reads as 1 */
                /* 8-bit colours: round to the nearest 1/255. */
                double bound = keeps & BYTE_COLORS ? 0.5 / 255 + 1e-7 : 0;
                if (fabs((double)a - b) > bound) fail_msg("%s: corner %zu: colour %d: %g vs %g", what, c, k, a, b);
            }
        }
    }
}

static void write_ok(const char *path, const format_case *format, const lk_mesh *mesh)
{
    lk_write_options options = {0};
    options.ply_encoding = format->ply_encoding;
    options.stl_ascii = format->stl_ascii;
    lk_error error = {0};
    if (lk_mesh_write(path, format->format, mesh, &options, &error) != LK_OK)
        fail_msg("writing %s: %s", path, error.message);
}

/* Each format: write, read the file back (by extension and by the given
 * format) and from memory, compare; writing again gives the same bytes. */
static void round_trip(const lk_mesh *mesh, const char *label)
{
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const format_case *format = &cases[i];
        char path[4096], what[256];
        snprintf(path, sizeof path, "%s", lk_test_tmpfile(format->file));
        snprintf(what, sizeof what, "%s as %s", label, format->file);
        write_ok(path, format, mesh);

        lk_mesh read;
        lk_test_load(path, &read);
        assert_same_mesh(mesh, &read, format->keeps, what);
        lk_mesh_free(&read);

        size_t size;
        unsigned char *bytes = lk_test_read_file(path, &size);
        lk_error error = {0};
        lk_mesh_init(&read);
        if (!(format->keeps & FILE_ONLY)) {
            if (lk_mesh_read_memory(bytes, size, format->file, format->format, NULL, &read, &error) != LK_OK)
                fail_msg("%s from memory: %s", what, error.message);
            assert_same_mesh(mesh, &read, format->keeps, what);
            lk_mesh_free(&read);
        }

        /* Written twice: the same bytes (apart from nothing: no dates). */
        write_ok(path, format, mesh);
        size_t again_size;
        unsigned char *again = lk_test_read_file(path, &again_size);
        assert_int_equal(again_size, size);
        assert_memory_equal(again, bytes, size);
        free(again);
        free(bytes);
    }
}

static void test_shapes_round_trip(void **state)
{
    (void)state;
    lk_mesh mesh;
    shape_noisy_sphere(&mesh, 1.7, 3, 0.1, 11);
    round_trip(&mesh, "noisy sphere");
    lk_mesh_free(&mesh);

    /* Two parts, one open: borders and a second component survive. */
    lk_mesh part;
    shape_torus(&mesh, 3, 0.75, 24, 12);
    shape_cylinder(&part, 0.5, 2, 10, 3);
    shape_append(&mesh, &part, 0.1, 0.2, -0.3);
    lk_mesh_free(&part);
    round_trip(&mesh, "torus + cylinder");
    lk_mesh_stats s = shape_stats(&mesh);
    assert_int_equal(s.component_count, 2);
    lk_mesh_free(&mesh);

    /* Large coordinates far from the origin (a scan in survey units). */
    shape_box(&mesh, 2, 3, 4, 3);
    lk_mesh_translate(&mesh, 654321.125, -123456.5, 2500.25);
    round_trip(&mesh, "far box");
    lk_mesh_free(&mesh);
}

static void test_attributes_round_trip(void **state)
{
    (void)state;
    lk_mesh mesh;
    attributed_sphere(&mesh);
    round_trip(&mesh, "attributed sphere");
    lk_mesh_free(&mesh);
}

/* XYZ point sets: positions and normals bit for bit, no triangles. */
static void test_points_round_trip(void **state)
{
    (void)state;
    lk_mesh points, read;
    shape_sphere_points(&points, 2000, 3.3, (double[3]){1, -2, 0.5});
    const char *path = lk_test_tmpfile("points.xyz");
    lk_error error = {0};
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_XYZ, &points, NULL, &error), LK_OK);
    lk_test_load(path, &read);
    assert_int_equal(read.vertex_count, 2000);
    assert_int_equal(read.triangle_count, 0);
    assert_non_null(read.normals);
    assert_true(same_floats(read.positions, points.positions, 3 * 2000));
    assert_true(same_floats(read.normals, points.normals, 3 * 2000));
    lk_mesh_free(&read);
    /* Without normals: positions only. */
    lk_write_options options = {0};
    options.skip_normals = 1;
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_XYZ, &points, &options, &error), LK_OK);
    lk_test_load(path, &read);
    assert_null(read.normals);
    assert_true(same_floats(read.positions, points.positions, 3 * 2000));
    lk_mesh_free(&read);
    /* The point set in binary PLY keeps normals too. */
    path = lk_test_tmpfile("points.ply");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_PLY, &points, NULL, &error), LK_OK);
    lk_test_load(path, &read);
    assert_int_equal(read.triangle_count, 0);
    assert_true(same_floats(read.positions, points.positions, 3 * 2000));
    assert_true(same_floats(read.normals, points.normals, 3 * 2000));
    lk_mesh_free(&read);
    lk_mesh_free(&points);
}

/* ---- animations ------------------------------------------------------------- */

static void read_animation_ok(const char *path, lk_animation *animation)
{
    lk_error error = {0};
    if (lk_animation_read(path, animation, &error) != LK_OK) fail_msg("reading %s: %s", path, error.message);
}

static void write_animation_ok(const char *path, const lk_animation *animation)
{
    lk_error error = {0};
    if (lk_animation_write(path, animation, &error) != LK_OK) fail_msg("writing %s: %s", path, error.message);
}

/* A twisting box with named frames, a non-integer rate and texture
 * coordinates on a 1/16 x 1/8 lattice (whole texels of a 16 x 8 skin, so
 * that MD2 keeps them exactly). */
static void named_twisting_box(lk_animation *animation)
{
    shape_twisting_box(animation, 1.5, 1, 3, 4, 9, 120);
    animation->frames_per_second = 12.5;
    animation->frame_names = calloc(animation->frame_count, sizeof *animation->frame_names);
    assert_non_null(animation->frame_names);
    for (size_t f = 0; f < animation->frame_count; f++) {
        animation->frame_names[f] = malloc(16);
        assert_non_null(animation->frame_names[f]);
        snprintf(animation->frame_names[f], 16, "twist%02u", (unsigned)f);
    }
    lk_mesh *mesh = &animation->mesh;
    mesh->texcoords = malloc(2 * mesh->vertex_count * sizeof(float));
    assert_non_null(mesh->texcoords);
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        mesh->texcoords[2 * v] = (float)(v % 17) / 16;
        mesh->texcoords[2 * v + 1] = (float)(v % 9) / 8;
    }
}

/* KMF: every frame, the texture coordinates, names and rate bit for bit. */
static void test_kmf_round_trip(void **state)
{
    (void)state;
    lk_animation animation, read;
    named_twisting_box(&animation);
    const char *path = lk_test_tmpfile("twist.kmf");
    write_animation_ok(path, &animation);
    read_animation_ok(path, &read);
    size_t v_count = animation.mesh.vertex_count;
    assert_int_equal(read.frame_count, 9);
    assert_int_equal(read.mesh.vertex_count, v_count);
    assert_int_equal(read.mesh.triangle_count, animation.mesh.triangle_count);
    assert_true(read.frames_per_second == 12.5);
    assert_memory_equal(read.mesh.indices, animation.mesh.indices,
                        3 * animation.mesh.triangle_count * sizeof(uint32_t));
    assert_true(same_floats(read.frame_positions, animation.frame_positions, 9 * 3 * v_count));
    assert_true(same_floats(read.mesh.positions, animation.frame_positions, 3 * v_count));
    assert_non_null(read.mesh.texcoords);
    assert_true(same_floats(read.mesh.texcoords, animation.mesh.texcoords, 2 * v_count));
    assert_non_null(read.frame_names);
    for (size_t f = 0; f < 9; f++) assert_string_equal(read.frame_names[f], animation.frame_names[f]);
    lk_animation_free(&read);

    /* From memory, the same. */
    size_t size;
    unsigned char *bytes = lk_test_read_file(path, &size);
    lk_error error = {0};
    lk_animation_init(&read);
    assert_int_equal(lk_animation_read_memory(bytes, size, "twist.kmf", NULL, &read, NULL, &error), LK_OK);
    assert_true(same_floats(read.frame_positions, animation.frame_positions, 9 * 3 * v_count));
    lk_animation_free(&read);
    free(bytes);
    lk_animation_free(&animation);
}

/* MD2: 8 bits per axis over each frame's box, so every position is within
 * half a step, (max - min) / 510 per axis, of the original; vertices are
 * renumbered in order of first use, triangles keep their order and
 * orientation, texture coordinates on whole texels come back exactly, the
 * rate is Quake's 10 per second. */
static void test_md2_round_trip(void **state)
{
    (void)state;
    lk_animation animation, read;
    named_twisting_box(&animation);
    const char *path = lk_test_tmpfile("twist.md2");
    write_animation_ok(path, &animation);
    read_animation_ok(path, &read);
    size_t v_count = animation.mesh.vertex_count, t_count = animation.mesh.triangle_count;
    assert_int_equal(read.frame_count, 9);
    assert_int_equal(read.mesh.vertex_count, v_count);
    assert_int_equal(read.mesh.triangle_count, t_count);
    assert_true(read.frames_per_second == 10);
    double worst = 0;
    for (size_t f = 0; f < 9; f++) {
        const float *original = animation.frame_positions + 3 * f * v_count;
        const float *decoded = read.frame_positions + 3 * f * v_count;
        double step[3];
        for (int k = 0; k < 3; k++) {
            float lo = original[k], hi = original[k];
            for (size_t v = 0; v < v_count; v++) {
                lo = fminf(lo, original[3 * v + (size_t)k]);
                hi = fmaxf(hi, original[3 * v + (size_t)k]);
            }
            step[k] = ((double)hi - lo) / 255;
        }
        for (size_t c = 0; c < 3 * t_count; c++) {
            const float *p = original + 3 * animation.mesh.indices[c], *q = decoded + 3 * read.mesh.indices[c];
            for (int k = 0; k < 3; k++) {
                double off = fabs((double)p[k] - q[k]);
                /* half a step, plus float rounding of scale * q + translate */
                if (off > step[k] / 2 + 1e-6) fail_msg("frame %zu corner %zu axis %d off by %g", f, c, k, off);
                if (off / step[k] > worst) worst = off / step[k];
            }
            if (f == 0) {
                const float *s = animation.mesh.texcoords + 2 * animation.mesh.indices[c];
                const float *t = read.mesh.texcoords + 2 * read.mesh.indices[c];
                assert_true(same_floats(s, t, 2));
            }
        }
        assert_string_equal(read.frame_names[f], animation.frame_names[f]);
    }
    print_message("md2: largest position error %.3f quantisation steps (bound 0.5)\n", worst);
    lk_animation_free(&read);
    lk_animation_free(&animation);
}

/* glTF morph targets: frame 0 is the base, frame f = base + (frame f -
 * base) in float: within a few float roundings of the original. */
static void test_gltf_round_trip(void **state)
{
    (void)state;
    lk_animation animation, read;
    shape_bending_capsule(&animation, 0.3, 4, 12, 8, 3, 6, 90);
    const char *path = lk_test_tmpfile("bend.gltf");
    write_animation_ok(path, &animation);
    read_animation_ok(path, &read);
    size_t v_count = animation.mesh.vertex_count;
    assert_int_equal(read.frame_count, 6);
    assert_int_equal(read.mesh.vertex_count, v_count);
    assert_memory_equal(read.mesh.indices, animation.mesh.indices,
                        3 * animation.mesh.triangle_count * sizeof(uint32_t));
    assert_true(same_floats(read.frame_positions, animation.frame_positions, 3 * v_count));
    double worst = 0;
    for (size_t i = 0; i < 6 * 3 * v_count; i++) {
        double off = fabs((double)read.frame_positions[i] - animation.frame_positions[i]);
        if (off > worst) worst = off;
    }
    /* Coordinates are below 5 in magnitude: one float rounding is 2.4e-7
     * at most there, a sum and a difference give two or three. */
    print_message("gltf: largest position error %.3g\n", worst);
    assert_true(worst <= 1e-6);
    lk_animation_free(&read);
    lk_animation_free(&animation);
}


/* The glTF mesh writer's choices (src/io_gltf_mesh_write.c): the smallest
 * index type, unit normals (a zero normal gets its triangles' normal),
 * byte colours when they are multiples of 1/255, points as mode 0, an
 * empty mesh as an empty scene, and a .gltf's buffer in NAME.bin with the
 * name percent-encoded in the URI. */
static char *gltf_text(const char *path)
{
    size_t size;
    unsigned char *bytes = lk_test_read_file(path, &size);
    char *text = malloc(size + 1);
    assert_non_null(text);
    memcpy(text, bytes, size);
    text[size] = '\0';
    free(bytes);
    return text;
}

static void test_gltf_mesh_writer(void **state)
{
    (void)state;
    lk_error error = {0};
    static const struct {
        unsigned slices, stacks;
        const char *component_type;
    } sizes[] = {{10, 8, "\"componentType\":\t5121"},
                 {40, 30, "\"componentType\":\t5123"},
                 {300, 240, "\"componentType\":\t5125"}};
    const char *path = lk_test_tmpfile("sphere.gltf");
    for (size_t i = 0; i < 3; i++) {
        lk_mesh sphere, read;
        shape_uv_sphere(&sphere, 1, sizes[i].slices, sizes[i].stacks);
        assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, &sphere, NULL, &error), LK_OK);
        char *text = gltf_text(path);
        assert_non_null(strstr(text, sizes[i].component_type));
        assert_non_null(strstr(text, "\"target\":\t34963"));
        assert_non_null(strstr(text, "\"uri\":\t\"sphere.bin\""));
        free(text);
        lk_test_load(path, &read);
        assert_int_equal(read.vertex_count, sphere.vertex_count);
        assert_memory_equal(read.indices, sphere.indices, 3 * sphere.triangle_count * sizeof(uint32_t));
        print_message("glTF: %zu vertices: %s\n", sphere.vertex_count, sizes[i].component_type);
        lk_mesh_free(&read);
        lk_mesh_free(&sphere);
    }

    /* A zero normal and 8-bit colours; a name with a space. */
    lk_mesh box, read;
    shape_box(&box, 1, 1, 1, 2);
    lk_mesh with;
    assert_int_equal(
        lk_mesh_alloc(&with, box.vertex_count, box.triangle_count, LK_ATTR_NORMALS | LK_ATTR_COLORS, &error), LK_OK);
    memcpy(with.positions, box.positions, 3 * box.vertex_count * sizeof(float));
    memcpy(with.indices, box.indices, 3 * box.triangle_count * sizeof(uint32_t));
    for (size_t v = 0; v < with.vertex_count; v++) {
        for (int k = 0; k < 3; k++) with.normals[3 * v + (size_t)k] = 2 * with.positions[3 * v + (size_t)k];
        for (int k = 0; k < 4; k++) with.colors[4 * v + (size_t)k] = (float)((v * 37 + (size_t)k * 11) % 256) / 255;
    }
    with.normals[0] = with.normals[1] = with.normals[2] = 0;
    path = lk_test_tmpfile("a box.gltf");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_GLTF, &with, NULL, &error), LK_OK);
    char *text = gltf_text(path);
    assert_non_null(strstr(text, "\"uri\":\t\"a%20box.bin\""));
    assert_non_null(strstr(text, "\"normalized\":\ttrue"));
    free(text);
    lk_test_load(path, &read);
    for (size_t v = 0; v < read.vertex_count; v++) {
        const float *n = read.normals + 3 * v;
        assert_true(fabs(sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]) - 1) < 1e-6);
        for (int k = 0; k < 4; k++) assert_true(read.colors[4 * v + (size_t)k] == with.colors[4 * v + (size_t)k]);
    }
    /* Vertex 0 is a corner of the box: its triangles' normal points out
     * along the corner's diagonal. */
    const float *p = with.positions, *n = read.normals;
    assert_true(n[0] * p[0] + n[1] * p[1] + n[2] * p[2] > 0);
    lk_mesh_free(&read);
    lk_mesh_free(&with);
    lk_mesh_free(&box);

    /* A point set: mode 0, normals kept. */
    lk_mesh points;
    shape_sphere_points(&points, 500, 2, (double[3]){0, 0, 0});
    path = lk_test_tmpfile("points.glb");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, &points, NULL, &error), LK_OK);
    lk_test_load(path, &read);
    assert_int_equal(read.vertex_count, 500);
    assert_int_equal(read.triangle_count, 0);
    assert_true(same_floats(read.positions, points.positions, 3 * 500));
    assert_true(near_floats(read.normals, points.normals, 3 * 500));
    lk_mesh_free(&read);
    lk_mesh_free(&points);

    /* An empty mesh: a valid file with an empty scene, read back empty. */
    lk_mesh empty;
    lk_mesh_init(&empty);
    path = lk_test_tmpfile("empty.glb");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, &empty, NULL, &error), LK_OK);
    size_t size;
    unsigned char *bytes = lk_test_read_file(path, &size);
    assert_true(size >= 20 && memcmp(bytes, "glTF", 4) == 0 && size % 4 == 0);
    free(bytes);
    lk_mesh_init(&read);
    assert_int_equal(lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &read, &error), LK_ERR_PARSE);
    assert_non_null(strstr(error.message, "no mesh geometry"));
}


/* lk_mesh_write_lods: one glTF with MSFT_lod (level 0 in the scene, the
 * others listed in its ids, the coverage hints and each level's numbers in
 * extras), read back as level 0; other extensions and empty levels
 * refused, nothing written. */
static void test_gltf_lods(void **state)
{
    (void)state;
    lk_mesh levels[3];
    shape_uv_sphere(&levels[0], 1, 48, 24);
    shape_uv_sphere(&levels[1], 1, 24, 12);
    shape_uv_sphere(&levels[2], 1, 12, 6);
    lk_lod_level_info info[3] = {{0.5, 0}, {0.125, 0.01}, {0, 0.04}};
    lk_error error = {0};
    const char *path = lk_test_tmpfile("chain.gltf");
    assert_int_equal(lk_mesh_write_lods(path, levels, 3, info, NULL, &error), LK_OK);
    char *text = gltf_text(path);
    assert_non_null(strstr(text, "\"extensionsUsed\":\t[\"MSFT_lod\"]"));
    assert_non_null(strstr(text, "\"ids\":\t[1, 2]"));
    assert_non_null(strstr(text, "\"MSFT_screencoverage\":\t[0.5, 0.125, 0]"));
    assert_non_null(strstr(text, "\"error\":\t0.04"));
    free(text);
    lk_mesh read;
    lk_test_load(path, &read);
    assert_int_equal(read.triangle_count, levels[0].triangle_count);
    lk_mesh_free(&read);
    /* .glb: the same, one file */
    path = lk_test_tmpfile("chain.glb");
    assert_int_equal(lk_mesh_write_lods(path, levels, 3, NULL, NULL, &error), LK_OK);
    lk_test_load(path, &read);
    assert_int_equal(read.triangle_count, levels[0].triangle_count);
    lk_mesh_free(&read);
    /* refusals */
    path = lk_test_tmpfile("chain.ply");
    assert_int_equal(lk_mesh_write_lods(path, levels, 3, NULL, NULL, &error), LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "name the output .glb or .gltf");
    lk_mesh empty;
    lk_mesh_init(&empty);
    lk_mesh with_empty[2] = {levels[0], empty};
    path = lk_test_tmpfile("broken.glb");
    assert_int_equal(lk_mesh_write_lods(path, with_empty, 2, NULL, NULL, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "level 1 of detail is empty");
    FILE *file = fopen(path, "rb");
    assert_null(file);
    for (int i = 0; i < 3; i++) lk_mesh_free(&levels[i]);
}


/* Triangles as 9 position floats, rotated to start at their smallest
 * corner (orientation kept), then sorted: equal lists mean the same
 * triangles whatever the vertex and triangle order. */
typedef struct corner_triangle {
    float p[9];
} corner_triangle;

static int compare_corner_triangles(const void *a, const void *b)
{
    return memcmp(((const corner_triangle *)a)->p, ((const corner_triangle *)b)->p, sizeof(float[9]));
}

static corner_triangle *sorted_triangles(const lk_mesh *mesh)
{
    corner_triangle *out = malloc(mesh->triangle_count * sizeof *out);
    assert_non_null(out);
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        int first = 0;
        for (int c = 1; c < 3; c++)
            if (memcmp(mesh->positions + 3 * (size_t)mesh->indices[3 * t + (size_t)c],
                       mesh->positions + 3 * (size_t)mesh->indices[3 * t + (size_t)first], 3 * sizeof(float)) < 0)
                first = c;
        for (int c = 0; c < 3; c++)
            memcpy(out[t].p + 3 * c, mesh->positions + 3 * (size_t)mesh->indices[3 * t + (size_t)((first + c) % 3)],
                   3 * sizeof(float));
    }
    qsort(out, mesh->triangle_count, sizeof *out, compare_corner_triangles);
    return out;
}

/* KHR_mesh_quantization and EXT_meshopt_compression: the quantised file
 * reads back within half a grid step of every attribute; the compressed
 * one decodes (meshoptimizer's decoders, in lodkit's reader) to exactly
 * the quantised triangles, reordered. */
static void test_gltf_quantized_and_meshopt(void **state)
{
    (void)state;
    lk_mesh mesh, quantized, packed;
    attributed_sphere(&mesh);
    float low[3], high[3];
    lk_mesh_bounds(&mesh, low, high);
    double extent = fmax(high[0] - low[0], fmax(high[1] - low[1], high[2] - low[2]));
    lk_write_options options = {0};
    options.gltf_flags = LK_GLTF_QUANTIZE;
    lk_error error = {0};
    const char *path = lk_test_tmpfile("quantized.glb");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, &mesh, &options, &error), LK_OK);
    size_t quantized_size;
    free(lk_test_read_file(path, &quantized_size));
    lk_test_load(path, &quantized);
    assert_int_equal(quantized.vertex_count, mesh.vertex_count);
    assert_memory_equal(quantized.indices, mesh.indices, 3 * mesh.triangle_count * sizeof(uint32_t));
    double worst[4] = {0, 0, 0, 0}; /* position, normal, texcoord, colour */
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        for (int k = 0; k < 3; k++) {
            size_t i = 3 * v + (size_t)k;
            worst[0] = fmax(worst[0], fabs((double)quantized.positions[i] - mesh.positions[i]));
            worst[1] = fmax(worst[1], fabs((double)quantized.normals[i] - mesh.normals[i]));
        }
        for (int k = 0; k < 2; k++) {
            size_t i = 2 * v + (size_t)k;
            worst[2] = fmax(worst[2], fabs((double)quantized.texcoords[i] - mesh.texcoords[i]));
        }
        for (int k = 0; k < 4; k++) {
            size_t i = 4 * v + (size_t)k;
            worst[3] = fmax(worst[3], fabs((double)quantized.colors[i] - mesh.colors[i]));
        }
    }
    print_message("quantised glTF: worst position %.3g (step %.3g), normal %.3g, texcoord %.3g, colour %.3g\n",
                  worst[0], extent / 16383, worst[1], worst[2], worst[3]);
    assert_true(worst[0] <= 0.5 * extent / 16383 * 1.001 + 1e-6);
    assert_true(worst[1] <= 0.5 / 127 + 1e-6 + 0.01); /* a rounding per component, then normalised */
    assert_true(worst[2] <= 0.5 / 4095 + 1.0 / 65535);
    assert_true(worst[3] <= 0.5 / 255 + 1e-6);

    options.gltf_flags = LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT;
    path = lk_test_tmpfile("packed.glb");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, &mesh, &options, &error), LK_OK);
    size_t packed_size;
    free(lk_test_read_file(path, &packed_size));
    lk_test_load(path, &packed);
    print_message("glTF sizes: quantised %zu bytes, meshopt %zu bytes\n", quantized_size, packed_size);
    assert_true(packed_size < quantized_size);
    assert_int_equal(packed.vertex_count, quantized.vertex_count);
    assert_int_equal(packed.triangle_count, quantized.triangle_count);
    corner_triangle *a = sorted_triangles(&quantized), *b = sorted_triangles(&packed);
    assert_memory_equal(a, b, quantized.triangle_count * sizeof *a);
    free(a);
    free(b);
    lk_mesh_free(&packed);
    lk_mesh_free(&quantized);
    lk_mesh_free(&mesh);
}


/* A compressed view that does not decode (its bytes cut or overwritten)
 * is a clear error naming the view, never a crash; so is a view whose
 * count does not match its byteLength. */
static void test_gltf_meshopt_damaged(void **state)
{
    (void)state;
    lk_mesh mesh, read;
    shape_uv_sphere(&mesh, 1, 24, 12);
    lk_write_options options = {0};
    options.gltf_flags = LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT;
    lk_error error = {0};
    const char *path = lk_test_tmpfile("damaged.glb");
    assert_int_equal(lk_mesh_write(path, LK_FORMAT_AUTO, &mesh, &options, &error), LK_OK);
    size_t size;
    unsigned char *bytes = lk_test_read_file(path, &size);
    /* The BIN chunk follows the JSON chunk: header 12 + 8 + JSON length. */
    size_t json_length = (size_t)bytes[12] | (size_t)bytes[13] << 8 | (size_t)bytes[14] << 16 | (size_t)bytes[15] << 24;
    size_t bin = 12 + 8 + json_length + 8;
    assert_true(bin < size);
    unsigned char *damaged = malloc(size);
    assert_non_null(damaged);
    memcpy(damaged, bytes, size);
    /* The vertex codec's header byte (0xA0 | version) of the first view. */
    damaged[bin] = 0x00;
    lk_mesh_init(&read);
    assert_int_equal(lk_mesh_read_memory(damaged, size, "damaged.glb", LK_FORMAT_GLTF, NULL, &read, &error),
                     LK_ERR_PARSE);
    lk_assert_message_contains(error, "bufferViews[0].extensions.EXT_meshopt_compression");
    lk_assert_message_contains(error, "do not decode");
    /* Every byte of the compressed data overwritten in turn: an error or a
     * mesh, never a crash (ASan watches). */
    size_t errors = 0;
    for (size_t i = bin; i < size; i += 7) {
        memcpy(damaged, bytes, size);
        damaged[i] ^= 0x5A;
        lk_mesh_init(&read);
        if (lk_mesh_read_memory(damaged, size, "damaged.glb", LK_FORMAT_GLTF, NULL, &read, &error) == LK_OK)
            lk_mesh_free(&read);
        else
            errors++;
    }
    print_message("meshopt glb: %zu of %zu damaged copies refused\n", errors, (size - bin + 6) / 7);
    free(damaged);
    free(bytes);
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_shapes_round_trip),
        cmocka_unit_test(test_attributes_round_trip),
        cmocka_unit_test(test_points_round_trip),
        cmocka_unit_test(test_kmf_round_trip),
        cmocka_unit_test(test_md2_round_trip),
        cmocka_unit_test(test_gltf_round_trip),
        cmocka_unit_test(test_gltf_mesh_writer),
        cmocka_unit_test(test_gltf_lods),
        cmocka_unit_test(test_gltf_quantized_and_meshopt),
        cmocka_unit_test(test_gltf_meshopt_damaged),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
