/* SPDX-License-Identifier: MIT */
/* Measure how far apart two surfaces are, as Metro does: the Hausdorff
 * distance and the mean and RMS distances in both directions, sampled.
 *
 *   measure A B     e.g. measure bunny.ply bunny-10.obj
 *
 * Distances are printed in model units and as a percentage of A's
 * bounding-box diagonal. */
#include <lodkit.h>

#include <stdio.h>

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s A B\n", argv[0]);
        return 2;
    }
    lk_error error = {0};
    lk_mesh a, b;
    if (lk_mesh_read(argv[1], LK_FORMAT_AUTO, NULL, &a, &error) != LK_OK) {
        fprintf(stderr, "%s\n", error.message);
        return 1;
    }
    if (lk_mesh_read(argv[2], LK_FORMAT_AUTO, NULL, &b, &error) != LK_OK) {
        fprintf(stderr, "%s\n", error.message);
        lk_mesh_free(&a);
        return 1;
    }
    lk_metro_result result;
    int status = 1;
    /* NULL options: 10 samples per face plus vertices and edges, seed 1,
     * every CPU; the result does not depend on the thread count. */
    if (lk_metro(&a, &b, NULL, &result, NULL, NULL, &error) == LK_OK) {
        double percent = 100.0 / result.diagonal;
        printf("hausdorff %.6g (%.4f%%)\n", result.hausdorff, result.hausdorff * percent);
        printf("A to B: max %.6g mean %.6g rms %.6g\n", result.forward.max, result.forward.mean, result.forward.rms);
        printf("B to A: max %.6g mean %.6g rms %.6g\n", result.backward.max, result.backward.mean, result.backward.rms);
        status = 0;
    } else {
        fprintf(stderr, "%s\n", error.message);
    }
    lk_mesh_free(&a);
    lk_mesh_free(&b);
    return status;
}
