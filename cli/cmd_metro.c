/* SPDX-License-Identifier: MIT */
/* lodkit metro: the Metro surface distance between two meshes. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help metro_help = {
    "A B",
    "Measure the distance between two surfaces, Metro-style: sample each surface\n"
    "(every vertex, points along every edge, and area-proportional face samples),\n"
    "find each sample's nearest point on the other surface, and report the maximum,\n"
    "mean and RMS distance in both directions and the symmetric Hausdorff distance,\n"
    "in model units and as % of A's bounding-box diagonal. Mean and RMS are\n"
    "area-weighted (face samples only); the maximum is over all samples.\n",
    NULL,
};

int cmd_metro(int argc, char **argv)
{
    lk_metro_options metro_options;
    lk_metro_options_default(&metro_options);
    size_t value;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_METRO, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_SAMPLES_PER_FACE:
            if (!parse_double_option(arg, &metro_options.samples_per_face) || metro_options.samples_per_face <= 0)
                return usage_error("metro", "--samples-per-face: '%s' is not a positive number", arg);
            break;
        case OPT_SAMPLES:
            if (!parse_size_option(arg, &metro_options.sample_count) || metro_options.sample_count == 0)
                return usage_error("metro", "--samples: '%s' is not a positive integer", arg);
            break;
        case OPT_NO_VERTEX_SAMPLES: metro_options.sample_vertices = -1; break;
        case OPT_NO_EDGE_SAMPLES: metro_options.sample_edges = -1; break;
        case OPT_SEED:
            if (!parse_size_option(arg, &value)) return usage_error("metro", "--seed: '%s' is not an integer", arg);
            metro_options.seed = value;
            break;
        case OPT_THREADS:
            if (!parse_size_option(arg, &value) || value > 256)
                return usage_error("metro", "--threads: '%s' is not a count from 0 to 256", arg);
            metro_options.thread_count = (int)value;
            break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("metro", "%s", "expected two files A and B");
    const char *path_a = argv[optind], *path_b = argv[optind + 1];
    lk_mesh a, b;
    lk_error error = {0};
    lk_mesh_init(&b);
    lk_status status = load_mesh(path_a, &a, NULL, NULL, &error);
    if (status == LK_OK) status = load_mesh(path_b, &b, NULL, NULL, &error);
    if (status != LK_OK) {
        print_error(&error); /* the readers name their file */
        lk_mesh_free(&a);
        lk_mesh_free(&b);
        return EXIT_BAD_INPUT;
    }
    lk_metro_result result;
    progress_state progress;
    progress_init(&progress, quiet || json, "metro");
    status = lk_metro(&a, &b, &metro_options, &result, progress_draw, &progress, &error);
    progress_done(&progress);
    lk_mesh_free(&a);
    lk_mesh_free(&b);
    if (status != LK_OK) {
        /* lk_metro says "mesh A" / "mesh B": name both files. */
        fprintf(stderr, "%s: %s (A) and %s (B): %s\n", program, path_a, path_b, error.message);
        return EXIT_BAD_INPUT;
    }
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "a", path_a);
        cJSON_AddStringToObject(root, "b", path_b);
        cJSON_AddNumberToObject(root, "diagonal", result.diagonal);
        cJSON_AddItemToObject(root, "forward", distance_json(&result.forward));
        cJSON_AddItemToObject(root, "backward", distance_json(&result.backward));
        cJSON_AddNumberToObject(root, "hausdorff", result.hausdorff);
        cJSON_AddNumberToObject(root, "hausdorff_percent",
                                result.diagonal > 0 ? 100 * result.hausdorff / result.diagonal : 0);
        cJSON_AddNumberToObject(root, "samples", (double)result.sample_count);
        cJSON_AddNumberToObject(root, "seconds", result.seconds);
        print_json(root);
        return EXIT_OK;
    }
    double percent = result.diagonal > 0 ? 100.0 / result.diagonal : 0;
    printf("A: %s\nB: %s\ndiagonal of A: %g\n\n", path_a, path_b, result.diagonal);
    printf("%-18s %12s %9s %12s %9s %12s %9s\n", "", "max", "%diag", "mean", "%diag", "rms", "%diag");
    const lk_distance_stats *rows[2] = {&result.forward, &result.backward};
    const char *names[2] = {"forward (A->B)", "backward (B->A)"};
    for (int i = 0; i < 2; i++)
        printf("%-18s %12.6g %9.5f %12.6g %9.5f %12.6g %9.5f\n", names[i], rows[i]->max, rows[i]->max * percent,
               rows[i]->mean, rows[i]->mean * percent, rows[i]->rms, rows[i]->rms * percent);
    printf("%-18s %12.6g %9.5f\n", "hausdorff", result.hausdorff, result.hausdorff * percent);
    printf("\nsamples: %s (A: %s, B: %s) in %.3f s, %.2f M samples/s\n", thousands(result.sample_count),
           thousands(result.forward.sample_count), thousands(result.backward.sample_count), result.seconds,
           result.seconds > 0 ? result.sample_count / result.seconds * 1e-6 : 0);
    return EXIT_OK;
}
