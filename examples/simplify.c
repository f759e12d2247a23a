/* SPDX-License-Identifier: MIT */
/* Simplify a mesh file with the quadric error metric and write the result.
 *
 *   simplify IN OUT [RATIO]     e.g. simplify bunny.ply bunny-10.obj 0.1
 *
 * Formats follow the extensions (OBJ, PLY, OFF, STL, SMF, glTF/GLB in;
 * OBJ, PLY, OFF, STL, SMF out). Prints the triangles kept and the error. */
#include <lodkit.h>

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv)
{
    if (argc < 3 || argc > 4) {
        fprintf(stderr, "usage: %s IN OUT [RATIO]\n", argv[0]);
        return 2;
    }
    double ratio = argc == 4 ? atof(argv[3]) : 0.1;
    lk_error error = {0};
    lk_mesh mesh;
    if (lk_mesh_read(argv[1], LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK) {
        fprintf(stderr, "%s\n", error.message);
        return 1;
    }
    lk_simplify_options options;
    lk_simplify_options_default(&options);
    options.target_ratio = ratio;
    lk_simplify_result result;
    int status = 1;
    if (lk_simplify(&mesh, LK_SIMPLIFY_QEM, &options, &result, NULL, NULL, &error) == LK_OK) {
        if (lk_mesh_write(argv[2], LK_FORMAT_AUTO, &result.mesh, NULL, &error) == LK_OK) {
            /* result.error is in model units; relative to the diagonal it
             * compares across models. */
            printf("%zu -> %zu triangles, error %.4f%% of the diagonal\n", mesh.triangle_count,
                   result.mesh.triangle_count, 100.0 * result.error / result.diagonal);
            status = 0;
        }
        lk_simplify_result_free(&result);
    }
    if (status != 0) fprintf(stderr, "%s\n", error.message);
    lk_mesh_free(&mesh);
    return status;
}
