/* lodkit simplify: a mesh reduced by quadrics, clustering or wavelets. */
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


/* ---- simplify ---------------------------------------------------------- */

static const char simplify_help[] =
    "Usage: lodkit simplify [options] IN OUT\n"
    "Simplify a triangle mesh to a target size or error.\n"
    "\n"
    "  -m, --method=M         qem (Garland-Heckbert quadrics, default), uniform\n"
    "                         (uniform-grid clustering), floating (floating-cell clustering)\n"
    "                         or wavelet (planar slices + CDF 9/7 contour wavelets; closed input)\n"
    "  -r, --ratio=R          keep this fraction of the triangles, 0 < R <= 1\n"
    "  -t, --triangles=N      keep N triangles\n"
    "  -v, --vertices=N       keep N vertices\n"
    "  -e, --max-error=E      qem: stop before a collapse's error exceeds E %% of the\n"
    "                         bounding-box diagonal; clustering: cell size in %% of the diagonal\n"
    "      --pair-distance=T  qem: also contract vertex pairs closer than T %% of the diagonal\n"
    "      --feature-angle=A  qem: creases are edges sharper than A degrees (default 40)\n"
    "      --feature-weight=W qem: weight of border and crease constraints (default 1)\n"
    "      --no-features      qem: do not detect creases and corners\n"
    "      --lock-border      qem: border vertices neither move nor vanish\n"
    "      --attributes       qem: keep normals, texture coordinates and colours faithful\n"
    "      --slices=N         wavelet: N slicing planes (default: 150 with --max-error, else\n"
    "                         the count in 16..150 balancing contour error and spacing)\n"
    "      --axis=A           wavelet: slice perpendicular to x, y, z or auto (the shortest side)\n"
    "                         wavelet: --max-error bounds the in-plane contour error\n"
    "      --criterion=C      wavelet: a contour's level by energy (the paper's sum of dropped\n"
    "                         c^2, default) or distance (max norm)\n"
    "      --no-refine        wavelet: no vertices between the planes (the paper's pipeline\n"
    "                         only; by default 8% of a vertex target refines the tiling)\n"
    "      --measure          measure the result with lodkit metro against the input\n"
    "      --json             print one JSON object\n"
    "  -q, --quiet            print nothing but errors\n"
    "  -h, --help             show this help\n"
    CLI_MEMORY_HELP
    "\n"
    "Several targets may be given; simplification stops at the first one reached.\n"
    "When no target can be reached (e.g. every further collapse would tear the\n"
    "surface), the nearest result is written and a note says so.\n";

static int parse_method(const char *text, lk_simplify_method *method)
{
    if (!strcmp(text, "qem")) *method = LK_SIMPLIFY_QEM;
    else if (!strcmp(text, "uniform")) *method = LK_SIMPLIFY_UNIFORM;
    else if (!strcmp(text, "floating")) *method = LK_SIMPLIFY_FLOATING;
    else if (!strcmp(text, "wavelet")) *method = LK_SIMPLIFY_WAVELET;
    else return 0;
    return 1;
}

/* What lk_simplify_result.error holds for each method. Only clustering's is
 * a distance between the surfaces' points; QEM's is a cost (it can exceed
 * the Hausdorff distance many times on spiky or tiny-area meshes). */
static const char *error_label(lk_simplify_method method)
{
    switch (method) {
    case LK_SIMPLIFY_QEM: return "largest collapse cost (RMS distance of a merged vertex to its planes)";
    case LK_SIMPLIFY_WAVELET: return "contour error (in-plane wavelet error with half the slice spacing)";
    default: return "largest vertex move (input vertex to its cell's representative)";
    }
}

static const char *method_name(lk_simplify_method method)
{
    return method == LK_SIMPLIFY_UNIFORM    ? "uniform"
           : method == LK_SIMPLIFY_FLOATING ? "floating"
           : method == LK_SIMPLIFY_WAVELET  ? "wavelet"
                                            : "qem";
}

int command_simplify(int argc, char **argv)
{
    enum { OPT_PAIR = 256, OPT_ANGLE, OPT_WEIGHT, OPT_NO_FEATURES, OPT_LOCK, OPT_ATTRIBUTES, OPT_MEASURE, OPT_JSON,
           OPT_SLICES, OPT_AXIS, OPT_CRITERION, OPT_NO_REFINE };
    static const struct option options[] = {
        {"method", required_argument, NULL, 'm'}, {"ratio", required_argument, NULL, 'r'},
        {"triangles", required_argument, NULL, 't'}, {"vertices", required_argument, NULL, 'v'},
        {"max-error", required_argument, NULL, 'e'}, {"pair-distance", required_argument, NULL, OPT_PAIR},
        {"feature-angle", required_argument, NULL, OPT_ANGLE}, {"feature-weight", required_argument, NULL, OPT_WEIGHT},
        {"no-features", no_argument, NULL, OPT_NO_FEATURES}, {"lock-border", no_argument, NULL, OPT_LOCK},
        {"attributes", no_argument, NULL, OPT_ATTRIBUTES}, {"measure", no_argument, NULL, OPT_MEASURE},
        {"json", no_argument, NULL, OPT_JSON}, {"quiet", no_argument, NULL, 'q'}, {"help", no_argument, NULL, 'h'},
        {"slices", required_argument, NULL, OPT_SLICES}, {"axis", required_argument, NULL, OPT_AXIS},
        {"criterion", required_argument, NULL, OPT_CRITERION}, {"no-refine", no_argument, NULL, OPT_NO_REFINE},
        {0}};
    lk_simplify_options simplify_options;
    lk_simplify_options_default(&simplify_options);
    lk_simplify_method method = LK_SIMPLIFY_QEM;
    int json = 0, quiet = 0, measure = 0, option;
    double percent;
    while ((option = getopt_long(argc, argv, "m:r:t:v:e:qh", options, NULL)) != -1) {
        switch (option) {
        case 'm':
            if (!parse_method(optarg, &method))
                return usage_error("simplify", "--method: '%s' is not qem, uniform, floating or wavelet", optarg);
            break;
        case 'r':
            if (!parse_double_option(optarg, &simplify_options.target_ratio) || simplify_options.target_ratio <= 0 ||
                simplify_options.target_ratio > 1)
                return usage_error("simplify", "--ratio: '%s' is not a number in (0, 1]", optarg);
            break;
        case 't':
            if (!parse_size_option(optarg, &simplify_options.target_triangles) || !simplify_options.target_triangles)
                return usage_error("simplify", "--triangles: '%s' is not a positive integer", optarg);
            break;
        case 'v':
            if (!parse_size_option(optarg, &simplify_options.target_vertices) || !simplify_options.target_vertices)
                return usage_error("simplify", "--vertices: '%s' is not a positive integer", optarg);
            break;
        case 'e':
            if (!parse_double_option(optarg, &percent) || percent <= 0)
                return usage_error("simplify", "--max-error: '%s' is not a positive percentage", optarg);
            simplify_options.max_error = percent / 100;
            break;
        case OPT_PAIR:
            if (!parse_double_option(optarg, &percent) || percent < 0)
                return usage_error("simplify", "--pair-distance: '%s' is not a percentage >= 0", optarg);
            simplify_options.pair_distance = percent / 100;
            break;
        case OPT_ANGLE:
            if (!parse_double_option(optarg, &simplify_options.feature_angle) || simplify_options.feature_angle < 0 ||
                simplify_options.feature_angle > 180)
                return usage_error("simplify", "--feature-angle: '%s' is not an angle in [0, 180]", optarg);
            break;
        case OPT_WEIGHT:
            if (!parse_double_option(optarg, &simplify_options.feature_weight) || simplify_options.feature_weight < 0)
                return usage_error("simplify", "--feature-weight: '%s' is not a weight >= 0", optarg);
            break;
        case OPT_NO_FEATURES: simplify_options.flags |= LK_SIMPLIFY_NO_FEATURES; break;
        case OPT_LOCK: simplify_options.flags |= LK_SIMPLIFY_LOCK_BORDER; break;
        case OPT_ATTRIBUTES: simplify_options.flags |= LK_SIMPLIFY_ATTRIBUTES; break;
        case OPT_MEASURE: measure = 1; break;
        case OPT_JSON: json = 1; break;
        case OPT_SLICES:
            if (!parse_size_option(optarg, &simplify_options.slice_count) || simplify_options.slice_count < 2 ||
                simplify_options.slice_count > 1000000)
                return usage_error("simplify", "--slices: '%s' is not an integer in 2..1000000", optarg);
            break;
        case OPT_AXIS:
            if (!strcmp(optarg, "auto")) simplify_options.slice_axis = LK_AXIS_AUTO;
            else if (!strcmp(optarg, "x")) simplify_options.slice_axis = LK_AXIS_X;
            else if (!strcmp(optarg, "y")) simplify_options.slice_axis = LK_AXIS_Y;
            else if (!strcmp(optarg, "z")) simplify_options.slice_axis = LK_AXIS_Z;
            else return usage_error("simplify", "--axis: '%s' is not x, y, z or auto", optarg);
            break;
        case OPT_CRITERION:
            if (!strcmp(optarg, "distance")) simplify_options.wavelet_criterion = LK_WAVELET_DISTANCE;
            else if (!strcmp(optarg, "energy")) simplify_options.wavelet_criterion = LK_WAVELET_ENERGY;
            else return usage_error("simplify", "--criterion: '%s' is not distance or energy", optarg);
            break;
        case OPT_NO_REFINE: simplify_options.flags |= LK_SIMPLIFY_NO_REFINE; break;
        case 'q': quiet = 1; break;
        case 'h': fputs(simplify_help, stdout); return EXIT_OK;
        default: return usage_error("simplify", "%s", "invalid option");
        }
    }
    if (argc - optind != 2) return usage_error("simplify", "%s", "expected IN and OUT");
    if (simplify_options.target_ratio == 0 && simplify_options.target_triangles == 0 &&
        simplify_options.target_vertices == 0 && simplify_options.max_error == 0)
        return usage_error("simplify", "%s", "no target: give --ratio, --triangles, --vertices or --max-error");
    const char *in = argv[optind], *out = argv[optind + 1];
    lk_format out_format = triangle_output_format(out);
    if (out_format == LK_FORMAT_UNKNOWN)
        return usage_error("simplify", "cannot write a mesh to '%s': use .obj .ply .off .smf or .stl", out);

    lk_mesh mesh;
    lk_error error = {0};
    double load_seconds;
    lk_simplify_result result;
    memset(&result, 0, sizeof result);
    progress_state progress;
    progress_init(&progress, quiet || json, "simplify");
    lk_status status = load_mesh(in, &mesh, &load_seconds, &error);
    if (status == LK_OK) {
        status = lk_simplify(&mesh, method, &simplify_options, &result, progress_draw, &progress, &error);
    }
    progress_done(&progress);
    if (status == LK_OK) status = lk_mesh_write(out, out_format, &result.mesh, NULL, &error);
    lk_metro_result metro;
    memset(&metro, 0, sizeof metro);
    if (status == LK_OK && measure) {
        progress_init(&progress, quiet || json, "metro");
        status = lk_metro(&mesh, &result.mesh, NULL, &metro, progress_draw, &progress, &error);
        progress_done(&progress);
    }
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        lk_mesh_free(&mesh);
        lk_simplify_result_free(&result);
        return EXIT_BAD_INPUT;
    }
    double diagonal = result.diagonal > 0 ? result.diagonal : 1;
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddStringToObject(root, "method", method_name(method));
        cJSON_AddNumberToObject(root, "input_vertices", (double)mesh.vertex_count);
        cJSON_AddNumberToObject(root, "input_triangles", (double)mesh.triangle_count);
        cJSON_AddNumberToObject(root, "vertices", (double)result.mesh.vertex_count);
        cJSON_AddNumberToObject(root, "triangles", (double)result.mesh.triangle_count);
        cJSON_AddNumberToObject(root, "seconds", result.seconds);
        cJSON_AddNumberToObject(root, "diagonal", result.diagonal);
        cJSON_AddNumberToObject(root, "error", result.error);
        cJSON_AddStringToObject(root, "error_kind", error_label(method));
        cJSON_AddNumberToObject(root, "error_percent", 100 * result.error / diagonal);
        cJSON_AddBoolToObject(root, "target_reached", result.target_reached != 0);
        if (measure) {
            cJSON *metro_json = cJSON_AddObjectToObject(root, "metro");
            cJSON_AddItemToObject(metro_json, "forward", distance_json(&metro.forward));
            cJSON_AddItemToObject(metro_json, "backward", distance_json(&metro.backward));
            cJSON_AddNumberToObject(metro_json, "hausdorff", metro.hausdorff);
            cJSON_AddNumberToObject(metro_json, "hausdorff_percent", 100 * metro.hausdorff / diagonal);
            cJSON_AddNumberToObject(metro_json, "rms_percent",
                                    100 * (metro.forward.rms > metro.backward.rms ? metro.forward.rms : metro.backward.rms) / diagonal);
        }
        print_json(root);
    } else if (!quiet) {
        printf("%s: %s vertices, %s triangles -> %s: %s vertices, %s triangles (%s, %.1f ms)\n", in,
               thousands(mesh.vertex_count), thousands(mesh.triangle_count), out, thousands(result.mesh.vertex_count),
               thousands(result.mesh.triangle_count), method_name(method), result.seconds * 1000);
        printf("%s: %.6g (%.4f%% of the diagonal)%s\n", error_label(method), result.error, 100 * result.error / diagonal,
               measure ? "" : "; --measure gives the surface distance (metro)");
        if (!result.target_reached)
            printf("note: the target could not be reached without breaking the surface; this is the nearest result\n");
        if (measure)
            printf("metro: hausdorff %.4f%%, rms %.4f%% / %.4f%% (forward / backward) of the diagonal\n",
                   100 * metro.hausdorff / diagonal, 100 * metro.forward.rms / diagonal,
                   100 * metro.backward.rms / diagonal);
    }
    lk_mesh_free(&mesh);
    lk_simplify_result_free(&result);
    return EXIT_OK;
}
