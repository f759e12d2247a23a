/* SPDX-License-Identifier: MIT */
/* The format table (lk_format_info_at, src/io.c) against what the library
 * does: every extension in one entry, lk_format_from_path and
 * lk_format_name agreeing with it, every reader and writer it names
 * reading or writing (and the others refusing), and the messages for the
 * extensions of other kinds. Procedural shapes only. */
#include <ctype.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

static size_t format_count(void)
{
    size_t count = 0;
    while (lk_format_info_at(count)) count++;
    return count;
}

/* Calls fn(info, extension) for every extension of every entry. */
static void for_each_extension(void (*fn)(const lk_format_info *, const char *))
{
    const lk_format_info *info;
    for (size_t i = 0; (info = lk_format_info_at(i)); i++) {
        for (const char *word = info->extensions; *word;) {
            size_t length = strcspn(word, " ");
            char extension[32];
            assert_true(length > 0 && length < sizeof extension);
            memcpy(extension, word, length);
            extension[length] = '\0';
            fn(info, extension);
            word += length;
            if (*word == ' ') word++;
        }
    }
}

static void check_entry_shape(const lk_format_info *info, const char *extension)
{
    for (const char *c = extension; *c; c++)
        if (!(islower((unsigned char)*c) || isdigit((unsigned char)*c)))
            fail_msg("%s: extension '%s'", info->name, extension);
    char path[64];
    snprintf(path, sizeof path, "dir.v2/model.%s", extension);
    if (lk_format_info_from_path(path) != info) fail_msg(".%s does not lead to %s", extension, info->name);
    for (char *c = path; *c; c++) *c = (char)toupper((unsigned char)*c);
    if (lk_format_info_from_path(path) != info) fail_msg("%s does not lead to %s", path, info->name);
    if (lk_format_from_path(path) != info->format) fail_msg("lk_format_from_path(%s) is not %s's", path, info->name);
}

static void test_table_shape(void **state)
{
    (void)state;
    size_t count = format_count();
    assert_true(count >= 20);
    for (size_t i = 0; i < count; i++) {
        const lk_format_info *info = lk_format_info_at(i);
        assert_non_null(info->name);
        assert_non_null(info->description);
        assert_true(info->name[0] && info->description[0] && info->extensions[0]);
        assert_non_null(lk_format_kind_name(info->kind));
        /* lk_mesh_read reads exactly the entries that have an lk_format */
        assert_int_equal((info->read & LK_IO_MESH) != 0, info->format != LK_FORMAT_UNKNOWN);
        assert_true(info->read != 0);
        assert_false(strstr(info->extensions, "  ") || strchr(info->extensions, '.'));
        for (size_t j = 0; j < i; j++) assert_string_not_equal(lk_format_info_at(j)->name, info->name);
    }
    /* each extension leads back to its own entry: none is in two */
    for_each_extension(check_entry_shape);
    assert_null(lk_format_info_from_path("dir.obj/model"));
    assert_null(lk_format_info_from_path("model."));
    assert_null(lk_format_info_from_path("model"));
    assert_null(lk_format_info_from_path("model.unknownext"));
    assert_int_equal(lk_format_info_from_path("a.lks")->kind, LK_FORMAT_KIND_STREAM);
    assert_int_equal(lk_format_info_from_path("a.tif")->kind, LK_FORMAT_KIND_GRID);
    assert_int_equal(lk_format_info_from_path("a.xyzn")->kind, LK_FORMAT_KIND_POINTS);
    assert_int_equal(lk_format_info_from_path("a.amc")->kind, LK_FORMAT_KIND_ANIMATION);
    assert_null(lk_format_kind_name((lk_format_kind)99));
    /* lk_format_name is the name of the format's first entry */
    for (lk_format format = LK_FORMAT_OBJ; format < LK_FORMAT_UNKNOWN; format++) {
        const lk_format_info *first = NULL;
        for (size_t i = 0; i < count && !first; i++)
            if (lk_format_info_at(i)->format == format) first = lk_format_info_at(i);
        assert_non_null(first);
        assert_string_equal(lk_format_name(format), first->name);
    }
    assert_string_equal(lk_format_name(LK_FORMAT_AUTO), "auto");
    assert_string_equal(lk_format_name(LK_FORMAT_UNKNOWN), "unknown");
}

static void make_tetrahedron(lk_mesh *mesh)
{
    static const float positions[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const uint32_t indices[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    lk_test_make_mesh(mesh, positions, 4, indices, 4);
}

/* Two frames of the tetrahedron, the second moved up. */
static void make_animation(lk_animation *animation)
{
    lk_animation_init(animation);
    make_tetrahedron(&animation->mesh);
    animation->frame_count = 2;
    animation->frames_per_second = 10;
    animation->frame_positions = malloc(2 * 12 * sizeof(float));
    assert_non_null(animation->frame_positions);
    for (int i = 0; i < 12; i++) {
        animation->frame_positions[i] = animation->mesh.positions[i];
        animation->frame_positions[12 + i] = animation->mesh.positions[i] + (i % 3 == 2 ? 1.0f : 0.0f);
    }
}

static void check_mesh_io(const lk_format_info *info, const char *extension)
{
    char name[32];
    snprintf(name, sizeof name, "t.%s", extension);
    const char *path = lk_test_tmpfile(name);
    lk_mesh mesh, back;
    make_tetrahedron(&mesh);
    lk_error error = {0};
    lk_status status = lk_mesh_write(path, LK_FORMAT_AUTO, &mesh, NULL, &error);
    if (info->write & LK_IO_MESH) {
        if (status != LK_OK) fail_msg("lk_mesh_write %s: %s", name, error.message);
        if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &back, &error) != LK_OK)
            fail_msg("lk_mesh_read %s: %s", name, error.message);
        if (info->kind == LK_FORMAT_KIND_POINTS)
            assert_int_equal(back.vertex_count, 4);
        else
            assert_int_equal(back.triangle_count, 4);
        lk_mesh_free(&back);
    } else if (status != LK_ERR_UNSUPPORTED) {
        fail_msg("lk_mesh_write %s: status %d, expected a refusal", name, (int)status);
    }
    /* lk_mesh_read recognises its formats by the name alone; the others are
     * named for what they hold */
    static const unsigned char junk[4] = {1, 2, 3, 4};
    status = lk_mesh_read_memory(junk, sizeof junk, name, LK_FORMAT_AUTO, NULL, &back, &error);
    assert_int_not_equal(status, LK_OK);
    if (info->read & LK_IO_MESH) {
        if (strstr(error.message, "unknown file format") || strstr(error.message, "not meshes"))
            fail_msg("lk_mesh_read_memory %s: %s", name, error.message);
    } else {
        char expected[128];
        snprintf(expected, sizeof expected, "%s: .%s files hold ", name, extension);
        lk_assert_message_contains(error, expected);
    }
    lk_mesh_free(&mesh);
}

static void test_mesh_readers_and_writers(void **state)
{
    (void)state;
    for_each_extension(check_mesh_io);
}

static void check_animation_io(const lk_format_info *info, const char *extension)
{
    char name[32];
    snprintf(name, sizeof name, "a.%s", extension);
    const char *path = lk_test_tmpfile(name);
    lk_animation animation, back;
    make_animation(&animation);
    lk_error error = {0};
    lk_status status = lk_animation_write(path, &animation, &error);
    if (info->write & LK_IO_ANIMATION) {
        if (status != LK_OK) fail_msg("lk_animation_write %s: %s", name, error.message);
        if (lk_animation_read(path, &back, &error) != LK_OK) fail_msg("lk_animation_read %s: %s", name, error.message);
        assert_int_equal(back.frame_count, 2);
        assert_int_equal(back.mesh.triangle_count, 4);
        lk_animation_free(&back);
    } else if (status != LK_ERR_UNSUPPORTED) {
        fail_msg("lk_animation_write %s: status %d, expected a refusal", name, (int)status);
    }
    static const unsigned char junk[4] = {1, 2, 3, 4};
    status = lk_animation_read_memory(junk, sizeof junk, name, NULL, &back, NULL, &error);
    assert_int_not_equal(status, LK_OK);
    bool recognised = strstr(error.message, "not an animation file") == NULL;
    if (recognised != ((info->read & LK_IO_ANIMATION) != 0))
        fail_msg("lk_animation_read_memory %s: %s", name, error.message);
    lk_animation_free(&animation);
}

static void test_animation_readers_and_writers(void **state)
{
    (void)state;
    for_each_extension(check_animation_io);
}

static void test_grid_entry_reads(void **state)
{
    (void)state;
    const lk_format_info *pgm = lk_format_info_from_path("x.pgm");
    assert_non_null(pgm);
    assert_true(pgm->read & LK_IO_GRID);
    const char *path = lk_test_tmpfile("grid.pgm");
    static const char text[] = "P2\n2 2\n255\n0 1\n2 3\n";
    lk_test_write_file(path, text, sizeof text - 1);
    lk_heightfield field;
    lk_error error = {0};
    if (lk_dem_read(path, NULL, &field, &error) != LK_OK) fail_msg("lk_dem_read: %s", error.message);
    lk_heightfield_free(&field);
}

static void test_messages(void **state)
{
    (void)state;
    static const unsigned char junk[4] = {1, 2, 3, 4};
    lk_mesh mesh;
    lk_error error = {0};
    assert_int_equal(lk_mesh_read_memory(junk, sizeof junk, "horse.lks", LK_FORMAT_AUTO, NULL, &mesh, &error),
                     LK_ERR_UNSUPPORTED);
    assert_string_equal(error.message, "horse.lks: .lks files hold progressive streams, not meshes");
    assert_int_equal(lk_mesh_read_memory(junk, sizeof junk, "dem.TIF", LK_FORMAT_AUTO, NULL, &mesh, &error),
                     LK_ERR_UNSUPPORTED);
    assert_string_equal(error.message, "dem.TIF: .TIF files hold elevation grids, not meshes");
    /* every extension lk_mesh_read knows, from the table */
    assert_int_equal(lk_mesh_read_memory(junk, sizeof junk, "x.foo", LK_FORMAT_AUTO, NULL, &mesh, &error),
                     LK_ERR_UNSUPPORTED);
    assert_string_equal(error.message,
                        "x.foo: unknown file format (expected obj, ply, off, smf, xyz, xyzn, pts, stl, gltf, glb, md2, "
                        "kmf, pcd or las)");
    make_tetrahedron(&mesh);
    assert_int_equal(lk_mesh_write(lk_test_tmpfile("out.lks"), LK_FORMAT_AUTO, &mesh, NULL, &error),
                     LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "out.lks: .lks files hold progressive streams, not meshes (use .obj .ply .off "
                                      ".smf .xyz .stl .gltf .glb .las)");
    assert_int_equal(lk_mesh_write(lk_test_tmpfile("out.foo"), LK_FORMAT_AUTO, &mesh, NULL, &error),
                     LK_ERR_UNSUPPORTED);
    lk_assert_message_contains(error, "out.foo: cannot tell the output format from the extension (use .obj .ply .off "
                                      ".smf .xyz .stl .gltf .glb .las)");
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_table_shape),
        cmocka_unit_test(test_mesh_readers_and_writers),
        cmocka_unit_test(test_animation_readers_and_writers),
        cmocka_unit_test(test_grid_entry_reads),
        cmocka_unit_test(test_messages),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
