/* lodkit metro: the Metro surface distance between two meshes. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "lodkit.h"


/* ---- metro ------------------------------------------------------------- */

static const char metro_help[] =
    "Usage: lodkit metro [options] A B\n"
    "Measure the distance between two surfaces, Metro-style: sample each surface\n"
    "(every vertex, points along every edge, and area-proportional face samples),\n"
    "find each sample's nearest point on the other surface, and report the maximum,\n"
    "mean and RMS distance in both directions and the symmetric Hausdorff distance,\n"
    "in model units and as %% of A's bounding-box diagonal. Mean and RMS are\n"
    "area-weighted (face samples only); the maximum is over all samples.\n"
    "\n"
    "  --samples-per-face=N   face samples per triangle on average (default 10)\n"
    "  --samples=N            total face samples per surface (overrides the above)\n"
    "  --no-vertex-samples    do not sample vertices\n"
    "  --no-edge-samples      do not sample edges\n"
    "  --seed=S               sampling seed (default 1); results are deterministic\n"
    "  --threads=T            worker threads (default: all cores)\n"
    "  --json                 print one JSON object\n"
    "  -q, --quiet            no progress bar\n"
    "  -h, --help             show this help\n"
    CLI_MEMORY_HELP;


int command_metro(int argc, char **argv)
{
    enum { OPT_SPF = 256, OPT_SAMPLES, OPT_NO_VERTEX, OPT_NO_EDGE, OPT_SEED, OPT_THREADS, OPT_JSON };
    static const struct option options[] = {
        {"samples-per-face", required_argument, NULL, OPT_SPF}, {"samples", required_argument, NULL, OPT_SAMPLES},
        {"no-vertex-samples", no_argument, NULL, OPT_NO_VERTEX}, {"no-edge-samples", no_argument, NULL, OPT_NO_EDGE},
        {"seed", required_argument, NULL, OPT_SEED}, {"threads", required_argument, NULL, OPT_THREADS},
        {"json", no_argument, NULL, OPT_JSON}, {"quiet", no_argument, NULL, 'q'}, {"help", no_argument, NULL, 'h'},
        {0}};
    lk_metro_options metro_options;
    lk_metro_options_default(&metro_options);
    int json = 0, quiet = 0, option;
    size_t value;
    while ((option = getopt_long(argc, argv, "qh", options, NULL)) != -1) {
        switch (option) {
        case OPT_SPF:
            if (!parse_double_option(optarg, &metro_options.samples_per_face) || metro_options.samples_per_face <= 0)
                return usage_error("metro", "--samples-per-face: '%s' is not a positive number", optarg);
            break;
        case OPT_SAMPLES:
            if (!parse_size_option(optarg, &metro_options.sample_count) || metro_options.sample_count == 0)
                return usage_error("metro", "--samples: '%s' is not a positive integer", optarg);
            break;
        case OPT_NO_VERTEX: metro_options.sample_vertices = -1; break;
        case OPT_NO_EDGE: metro_options.sample_edges = -1; break;
        case OPT_SEED:
            if (!parse_size_option(optarg, &value)) return usage_error("metro", "--seed: '%s' is not an integer", optarg);
            metro_options.seed = value;
            break;
        case OPT_THREADS:
            if (!parse_size_option(optarg, &value) || value > 256)
                return usage_error("metro", "--threads: '%s' is not a count from 0 to 256", optarg);
            metro_options.thread_count = (int)value;
            break;
        case OPT_JSON: json = 1; break;
        case 'q': quiet = 1; break;
        case 'h': fputs(metro_help, stdout); return EXIT_OK;
        default: return usage_error("metro", "%s", "invalid option");
        }
    }
    if (argc - optind != 2) return usage_error("metro", "%s", "expected two files A and B");
    const char *path_a = argv[optind], *path_b = argv[optind + 1];
    lk_mesh a, b;
    lk_error error = {0};
    lk_mesh_init(&b);
    lk_status status = load_mesh(path_a, &a, NULL, &error);
    if (status == LK_OK) status = load_mesh(path_b, &b, NULL, &error);
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
        cJSON_AddNumberToObject(root, "hausdorff_percent", result.diagonal > 0 ? 100 * result.hausdorff / result.diagonal : 0);
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
