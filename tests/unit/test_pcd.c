/* SPDX-License-Identifier: MIT */
/* PCD reader (src/io_pcd.c) on real PCL files from python-pcl's examples
 * (data/samples/pcd/, scripts/fetch-samples.sh). The expected counts,
 * bounds and colours come from an independent Python decoder of the same
 * files (header POINTS minus points with a NaN coordinate). */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

#include "testutil.h"

typedef struct expected_cloud {
    const char *name;
    size_t points; /* POINTS minus NaN points */
    float min[3], max[3];
    bool colors;
} expected_cloud;

static void read_cloud(const char *name, lk_mesh *mesh)
{
    lk_error error = {0};
    lk_status status = lk_mesh_read(lk_test_sample(name), LK_FORMAT_AUTO, NULL, mesh, &error);
    if (status != LK_OK) fprintf(stderr, "%s\n", error.message);
    assert_int_equal(status, LK_OK);
}

static void check_cloud(const expected_cloud *expected)
{
    lk_mesh mesh;
    read_cloud(expected->name, &mesh);
    assert_int_equal(mesh.vertex_count, expected->points);
    assert_int_equal(mesh.triangle_count, 0);
    assert_null(mesh.normals);
    assert_int_equal(mesh.colors != NULL, expected->colors);
    float min[3], max[3];
    lk_mesh_bounds(&mesh, min, max);
    for (int k = 0; k < 3; k++) {
        assert_float_equal(min[k], expected->min[k], 1e-5 * (1 + fabsf(min[k])));
        assert_float_equal(max[k], expected->max[k], 1e-5 * (1 + fabsf(max[k])));
    }
    lk_error error = {0};
    assert_int_equal(lk_mesh_validate(&mesh, &error), LK_OK);
    lk_mesh_free(&mesh);
}

/* DATA ascii, x y z. */
static void test_ascii(void **state)
{
    (void)state;
    expected_cloud cloud = {
        "pcd/test_pcd.pcd", 1771, {-11.171875f, -0.375f, -5.447998f}, {-9.765625f, 0.59375f, 0.46699905f}, false};
    check_cloud(&cloud);
}

/* DATA binary_compressed, x y z: the bunny scan. */
static void test_compressed(void **state)
{
    (void)state;
    expected_cloud cloud = {
        "pcd/bun0.pcd", 112586, {-13.79978f, -6.4928198f, -1.351705f}, {15.44711f, 7.979565f, 1.7090930f}, false};
    check_cloud(&cloud);
}

/* binary_compressed with rgba (U): alpha 0 on every point reads as opaque. */
static void test_compressed_rgba(void **state)
{
    (void)state;
    expected_cloud cloud = {
        "pcd/milk.pcd", 12575, {0.1786622f, -0.2107739f, -0.8268152f}, {0.3253836f, 8.603930e-05f, -0.6361504f}, true};
    check_cloud(&cloud);
    lk_mesh mesh;
    read_cloud("pcd/milk.pcd", &mesh);
    /* every point is 0x000000ff: blue */
    const float blue[4] = {0, 0, 1, 1};
    assert_memory_equal(mesh.colors, blue, sizeof blue);
    lk_mesh_free(&mesh);
}

/* An organised 640x480 stereo cloud, rgb typed F: 97,920 NaN points dropped. */
static void test_organised_rgb(void **state)
{
    (void)state;
    expected_cloud cloud = {"pcd/table_scene_mug_stereo_textured.pcd",
                            209280,
                            {-0.45643f, -0.51074f, 0.69001f},
                            {0.71518f, 0.17923f, 2.5927f},
                            true};
    check_cloud(&cloud);
    lk_mesh mesh;
    read_cloud("pcd/table_scene_mug_stereo_textured.pcd", &mesh);
    /* The first point kept is point 6538: (-0.38191, -0.4482, 2.0258), colour 0x43433e. */
    assert_float_equal(mesh.positions[0], -0.38191f, 1e-6);
    assert_float_equal(mesh.positions[2], 2.0258f, 1e-6);
    const float rgba[4] = {0x43 / 255.0f, 0x43 / 255.0f, 0x3e / 255.0f, 1.0f};
    assert_memory_equal(mesh.colors, rgba, sizeof rgba);
    lk_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ascii),
        cmocka_unit_test(test_compressed),
        cmocka_unit_test(test_compressed_rgba),
        cmocka_unit_test(test_organised_rgb),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
