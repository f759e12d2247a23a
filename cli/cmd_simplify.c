/* SPDX-License-Identifier: MIT */
/* lodkit simplify: a mesh reduced by quadrics, clustering or wavelets. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"

const cli_help simplify_help = {
    "IN OUT",
    "Simplify a triangle mesh to a target size or error.\n",
    "Several targets may be given; simplification stops at the first one reached.\n"
    "With glTF in and out (.glb, .gltf) the scene is kept: every primitive is\n"
    "simplified with its attributes (texture seams held), a triangle target is\n"
    "shared between them by one error threshold, and nodes, materials and\n"
    "textures are written back. OBJ to glTF keeps the .mtl materials likewise.\n"
    "When no target can be reached (e.g. every further collapse would tear the\n"
    "surface), the nearest result is written and a note says so.\n",
};

static int parse_method(const char *text, lk_simplify_method *method)
{
    if (!strcmp(text, "qem"))
        *method = LK_SIMPLIFY_QEM;
    else if (!strcmp(text, "uniform"))
        *method = LK_SIMPLIFY_UNIFORM;
    else if (!strcmp(text, "floating"))
        *method = LK_SIMPLIFY_FLOATING;
    else if (!strcmp(text, "wavelet"))
        *method = LK_SIMPLIFY_WAVELET;
    else
        return 0;
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

/* The "metro" member of the JSON summary. */
static void add_metro_json(cJSON *root, const lk_metro_result *metro, double diagonal)
{
    cJSON *metro_json = cJSON_AddObjectToObject(root, "metro");
    cJSON_AddItemToObject(metro_json, "forward", distance_json(&metro->forward));
    cJSON_AddItemToObject(metro_json, "backward", distance_json(&metro->backward));
    cJSON_AddNumberToObject(metro_json, "hausdorff", metro->hausdorff);
    cJSON_AddNumberToObject(metro_json, "hausdorff_percent", 100 * metro->hausdorff / diagonal);
    double rms = metro->forward.rms > metro->backward.rms ? metro->forward.rms : metro->backward.rms;
    cJSON_AddNumberToObject(metro_json, "rms_percent", 100 * rms / diagonal);
}

/* glTF in and out: every primitive simplified, the scene kept (nodes,
 * materials, textures); errors and the metro measure on the scene as
 * drawn (lk_scene_flatten). */
static int simplify_scene(const char *in, const char *out, lk_simplify_method method,
                          const lk_simplify_options *options, const lk_write_options *write_options, int measure,
                          int json, int quiet)
{
    lk_scene scene;
    lk_error error = {0};
    lk_mesh before, after;
    lk_mesh_init(&before);
    lk_mesh_init(&after);
    lk_scene_simplify_stats stats;
    memset(&stats, 0, sizeof stats);
    lk_metro_result metro;
    memset(&metro, 0, sizeof metro);
    double started = 0;
    lk_status status = load_scene(in, &scene, &error);
    size_t input_vertices = 0;
    for (size_t m = 0; status == LK_OK && m < scene.mesh_count; m++)
        for (size_t p = 0; p < scene.meshes[m].primitive_count; p++)
            input_vertices += scene.meshes[m].primitives[p].mesh.vertex_count;
    char input_summary[384] = "";
    if (status == LK_OK) snprintf(input_summary, sizeof input_summary, "%s", scene_summary(&scene));
    if (status == LK_OK && measure) status = lk_scene_flatten(&scene, &before, &error);
    if (status == LK_OK) {
        started = now_seconds();
        status = lk_scene_simplify(&scene, method, options, &stats, &error);
        started = now_seconds() - started;
    }
    if (status == LK_OK) status = lk_scene_write(out, &scene, write_options, &error);
    if (status == LK_OK && measure) status = lk_scene_flatten(&scene, &after, &error);
    if (status == LK_OK && measure) status = lk_metro(&before, &after, NULL, &metro, NULL, NULL, &error);
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        lk_scene_free(&scene);
        lk_mesh_free(&before);
        lk_mesh_free(&after);
        return EXIT_BAD_INPUT;
    }
    double diagonal = measure ? lk_mesh_bounds(&before, NULL, NULL) : 0;
    if (diagonal <= 0) diagonal = 1;
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddStringToObject(root, "method", method_name(method));
        cJSON_AddNumberToObject(root, "primitives", (double)stats.primitives);
        cJSON_AddNumberToObject(root, "materials", (double)scene.material_count);
        cJSON_AddNumberToObject(root, "textures", (double)scene.texture_count);
        cJSON_AddNumberToObject(root, "input_vertices", (double)input_vertices);
        cJSON_AddNumberToObject(root, "input_triangles", (double)stats.triangles_in);
        cJSON_AddNumberToObject(root, "triangles", (double)stats.triangles_out);
        cJSON_AddNumberToObject(root, "seconds", started);
        cJSON_AddNumberToObject(root, "error", stats.error);
        cJSON_AddStringToObject(root, "error_kind", error_label(method));
        if (measure) add_metro_json(root, &metro, diagonal);
        cJSON *notes = cJSON_AddArrayToObject(root, "notes");
        for (const char *line = scene.notes; line && *line;) {
            const char *end = strchr(line, '\n');
            size_t length = end ? (size_t)(end - line) : strlen(line);
            char text[300];
            snprintf(text, sizeof text, "%.*s", (int)(length < 299 ? length : 299), line);
            cJSON_AddItemToArray(notes, cJSON_CreateString(text));
            line += length + (end ? 1 : 0);
        }
        print_json(root);
    } else if (!quiet) {
        printf("%s: %s -> %s: %s (%s per primitive, %.1f ms)\n", in, input_summary, out, scene_summary(&scene),
               method_name(method), started * 1000);
        printf("%s: %.6g (largest over the primitives, in the scene's units)%s\n", error_label(method), stats.error,
               measure ? "" : "; --measure gives the surface distance of the scene as drawn (metro)");
        print_scene_notes(&scene);
        if (measure)
            printf("metro: hausdorff %.4f%%, rms %.4f%% / %.4f%% (forward / backward) of the diagonal\n",
                   100 * metro.hausdorff / diagonal, 100 * metro.forward.rms / diagonal,
                   100 * metro.backward.rms / diagonal);
    }
    lk_scene_free(&scene);
    lk_mesh_free(&before);
    lk_mesh_free(&after);
    return EXIT_OK;
}

int cmd_simplify(int argc, char **argv)
{
    lk_simplify_options simplify_options;
    lk_simplify_options_default(&simplify_options);
    long cores = sysconf(_SC_NPROCESSORS_ONLN); /* --threads' default */
    simplify_options.thread_count = cores < 1 ? 1 : cores > 64 ? 64 : (uint64_t)cores;
    lk_simplify_method method = LK_SIMPLIFY_QEM;
    lk_write_options write_options = {0};
    int measure = 0;
    double percent, max_error = 0, cell_size = 0;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_SIMPLIFY, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_METHOD:
            if (!parse_method(arg, &method))
                return usage_error("simplify", "--method: '%s' is not qem, uniform, floating or wavelet", arg);
            break;
        case OPT_RATIO:
            if (!parse_double_option(arg, &simplify_options.target_ratio) || simplify_options.target_ratio <= 0 ||
                simplify_options.target_ratio > 1)
                return usage_error("simplify", "--ratio: '%s' is not a number in (0, 1]", arg);
            break;
        case OPT_TRIANGLES:
            if (!parse_size_option(arg, &simplify_options.target_triangles) || !simplify_options.target_triangles)
                return usage_error("simplify", "--triangles: '%s' is not a positive integer", arg);
            break;
        case OPT_VERTICES:
            if (!parse_size_option(arg, &simplify_options.target_vertices) || !simplify_options.target_vertices)
                return usage_error("simplify", "--vertices: '%s' is not a positive integer", arg);
            break;
        case OPT_MAX_ERROR:
            if (!parse_double_option(arg, &max_error) || max_error <= 0)
                return usage_error("simplify", "--max-error: '%s' is not a positive percentage", arg);
            break;
        case OPT_CELL_SIZE:
            if (!parse_double_option(arg, &cell_size) || cell_size <= 0)
                return usage_error("simplify", "--cell-size: '%s' is not a positive percentage", arg);
            break;
        case OPT_PAIR_DISTANCE:
            if (!parse_double_option(arg, &percent) || percent < 0)
                return usage_error("simplify", "--pair-distance: '%s' is not a percentage >= 0", arg);
            simplify_options.pair_distance = percent / 100;
            break;
        case OPT_FEATURE_ANGLE:
            if (!parse_double_option(arg, &simplify_options.feature_angle) || simplify_options.feature_angle < 0 ||
                simplify_options.feature_angle > 180)
                return usage_error("simplify", "--feature-angle: '%s' is not an angle in [0, 180]", arg);
            break;
        case OPT_FEATURE_WEIGHT:
            if (!parse_double_option(arg, &simplify_options.feature_weight) || simplify_options.feature_weight < 0)
                return usage_error("simplify", "--feature-weight: '%s' is not a weight >= 0", arg);
            break;
        case OPT_NO_FEATURES: simplify_options.flags |= LK_SIMPLIFY_NO_FEATURES; break;
        case OPT_LOCK_BORDER: simplify_options.flags |= LK_SIMPLIFY_LOCK_BORDER; break;
        case OPT_ATTRIBUTES: simplify_options.flags |= LK_SIMPLIFY_ATTRIBUTES; break;
        case OPT_MEASURE: measure = 1; break;
        case OPT_THREADS: {
            size_t value;
            if (!parse_size_option(arg, &value) || value < 1 || value > 64)
                return usage_error("simplify", "--threads: '%s' is not a count from 1 to 64", arg);
            simplify_options.thread_count = value;
            break;
        }
        case OPT_SLICES:
            if (!parse_size_option(arg, &simplify_options.slice_count) || simplify_options.slice_count < 2 ||
                simplify_options.slice_count > 1000000)
                return usage_error("simplify", "--slices: '%s' is not an integer in 2..1000000", arg);
            break;
        case OPT_AXIS:
            if (!strcmp(arg, "auto"))
                simplify_options.slice_axis = LK_AXIS_AUTO;
            else if (!strcmp(arg, "x"))
                simplify_options.slice_axis = LK_AXIS_X;
            else if (!strcmp(arg, "y"))
                simplify_options.slice_axis = LK_AXIS_Y;
            else if (!strcmp(arg, "z"))
                simplify_options.slice_axis = LK_AXIS_Z;
            else
                return usage_error("simplify", "--axis: '%s' is not x, y, z or auto", arg);
            break;
        case OPT_CRITERION:
            if (!strcmp(arg, "distance"))
                simplify_options.wavelet_criterion = LK_WAVELET_DISTANCE;
            else if (!strcmp(arg, "energy"))
                simplify_options.wavelet_criterion = LK_WAVELET_ENERGY;
            else
                return usage_error("simplify", "--criterion: '%s' is not distance or energy", arg);
            break;
        case OPT_NO_REFINE: simplify_options.flags |= LK_SIMPLIFY_NO_REFINE; break;
        case OPT_QUANTIZE:
        case OPT_MESHOPT:
        case OPT_EXTERNAL_IMAGES: gltf_flag_option(id, &write_options.gltf_flags); break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    int clustering = method == LK_SIMPLIFY_UNIFORM || method == LK_SIMPLIFY_FLOATING;
    /* --max-error bounds an error; clustering's parameter is a cell size */
    if (clustering && max_error > 0)
        return usage_error("simplify", "%s",
                           "--max-error is an error bound (qem, wavelet); the cell size of uniform and floating "
                           "clustering is --cell-size=P (in % of the diagonal)");
    if (!clustering && cell_size > 0)
        return usage_error("simplify", "%s",
                           "--cell-size is the cell size of uniform and floating clustering; "
                           "qem and wavelet take an error bound: --max-error=E");
    if (max_error > 0) simplify_options.max_error = max_error / 100;
    if (cell_size > 0) simplify_options.max_error = cell_size / 100;
    if (argc - optind != 2) return usage_error("simplify", "%s", "expected IN and OUT");
    if (simplify_options.target_ratio == 0 && simplify_options.target_triangles == 0 &&
        simplify_options.target_vertices == 0 && simplify_options.max_error == 0)
        return usage_error("simplify", "%s",
                           clustering ? "no target: give --ratio, --triangles, --vertices or --cell-size"
                                      : "no target: give --ratio, --triangles, --vertices or --max-error");
    const char *in = argv[optind], *out = argv[optind + 1];
    lk_format out_format = output_mesh_format("simplify", out, 0);
    if (out_format == LK_FORMAT_UNKNOWN) return EXIT_USAGE;
    if (check_gltf_flags("simplify", out, write_options.gltf_flags)) return EXIT_USAGE;

    if (is_gltf_path(out) && method != LK_SIMPLIFY_WAVELET && reads_as_scene(in))
        return simplify_scene(in, out, method, &simplify_options, &write_options, measure, json, quiet);

    lk_mesh mesh;
    lk_error error = {0};
    double load_seconds;
    lk_simplify_result result;
    memset(&result, 0, sizeof result);
    progress_state progress;
    progress_init(&progress, quiet || json, "simplify");
    /* Components and edges in and out, for the summary: a pass over both
     * meshes (and the input's adjacency, ~100 bytes per triangle), so only
     * when something prints them. */
    int summarise = json || !quiet;
    lk_mesh_stats input_stats, output_stats;
    memset(&input_stats, 0, sizeof input_stats);
    memset(&output_stats, 0, sizeof output_stats);
    lk_status status = load_mesh(in, &mesh, &load_seconds, NULL, &error);
    if (status == LK_OK && summarise) status = lk_mesh_compute_stats(&mesh, &input_stats, &error);
    if (status == LK_OK) {
        progress_draw(&progress, 0, "simplify"); /* at once, whatever the library reports */
        status = lk_simplify(&mesh, method, &simplify_options, &result, progress_draw, &progress, &error);
    }
    progress_done(&progress);
    /* before writing: a failure here leaves no output file behind */
    if (status == LK_OK && summarise) status = lk_mesh_compute_stats(&result.mesh, &output_stats, &error);
    if (status == LK_OK) status = lk_mesh_write(out, out_format, &result.mesh, &write_options, &error);
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
    /* The wavelet tiling keeps every component that crosses a plane (a
     * connected input stays connected), so fewer components out means
     * some crossed none. */
    size_t dropped_components =
        method == LK_SIMPLIFY_WAVELET && output_stats.component_count < input_stats.component_count
            ? input_stats.component_count - output_stats.component_count
            : 0;
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
        cJSON_AddNumberToObject(root, "input_components", (double)input_stats.component_count);
        cJSON_AddNumberToObject(root, "input_boundary_edges", (double)input_stats.boundary_edge_count);
        cJSON_AddNumberToObject(root, "input_nonmanifold_edges", (double)input_stats.nonmanifold_edge_count);
        cJSON_AddNumberToObject(root, "components", (double)output_stats.component_count);
        cJSON_AddNumberToObject(root, "boundary_edges", (double)output_stats.boundary_edge_count);
        cJSON_AddNumberToObject(root, "nonmanifold_edges", (double)output_stats.nonmanifold_edge_count);
        if (method == LK_SIMPLIFY_WAVELET) {
            cJSON_AddNumberToObject(root, "closed_holes", (double)input_stats.boundary_loop_count);
            cJSON_AddNumberToObject(root, "dropped_components", (double)dropped_components);
        }
        if (measure) add_metro_json(root, &metro, diagonal);
        print_json(root);
    } else if (!quiet) {
        /* the output's open and non-manifold edges are named only when it has
         * some; clustering merges whole cells, so its non-manifold edges are
         * expected, not a fault (a user reading the line should know that) */
        char output_edges[160] = "";
        if (output_stats.boundary_edge_count)
            snprintf(output_edges, sizeof output_edges, ", %s",
                     count_noun(output_stats.boundary_edge_count, "boundary edge", "boundary edges"));
        if (output_stats.nonmanifold_edge_count) {
            size_t used = strlen(output_edges);
            snprintf(output_edges + used, sizeof output_edges - used, ", %s",
                     count_noun(output_stats.nonmanifold_edge_count, "non-manifold edge", "non-manifold edges"));
        }
        char threads[32] = "";
        if (method == LK_SIMPLIFY_QEM && simplify_options.thread_count > 1 &&
            mesh.triangle_count >= LK_SIMPLIFY_PARALLEL_MIN && !(simplify_options.flags & LK_SIMPLIFY_RECORD))
            snprintf(threads, sizeof threads, " on %u threads", (unsigned)simplify_options.thread_count);
        printf("%s: %s, %s, %s -> %s: %s, %s, %s%s (%s%s, %.1f ms%s)\n", in, n_vertices(mesh.vertex_count),
               n_triangles(mesh.triangle_count), count_noun(input_stats.component_count, "component", "components"),
               out, n_vertices(result.mesh.vertex_count), n_triangles(result.mesh.triangle_count),
               count_noun(output_stats.component_count, "component", "components"), output_edges, method_name(method),
               threads, result.seconds * 1000,
               clustering && output_stats.nonmanifold_edge_count ? "; clustering makes non-manifold edges by design"
                                                                 : "");
        printf("%s: %.6g (%.4f%% of the diagonal)%s\n", error_label(method), result.error,
               100 * result.error / diagonal, measure ? "" : "; --measure gives the surface distance (metro)");
        if (!result.target_reached)
            printf("note: the target could not be reached without breaking the surface; this is the nearest result\n");
        if (method == LK_SIMPLIFY_WAVELET && input_stats.boundary_loop_count)
            printf("note: slicing needs a closed surface: the input's %s (%s) were closed first\n",
                   count_noun(input_stats.boundary_loop_count, "hole", "holes"),
                   count_noun(input_stats.boundary_edge_count, "boundary edge", "boundary edges"));
        if (dropped_components)
            printf("note: %s of the input cross no slicing plane (thinner than the slice spacing along the axis) "
                   "and were dropped; more --slices keep them\n",
                   count_noun(dropped_components, "component", "components"));
        if (measure)
            printf("metro: hausdorff %.4f%%, rms %.4f%% / %.4f%% (forward / backward) of the diagonal\n",
                   100 * metro.hausdorff / diagonal, 100 * metro.forward.rms / diagonal,
                   100 * metro.backward.rms / diagonal);
    }
    lk_mesh_free(&mesh);
    lk_simplify_result_free(&result);
    return EXIT_OK;
}
