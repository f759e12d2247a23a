/* lodkit — the command-line tool. A thin layer over liblodkit: parse
 * options, call the library, print results. One function per subcommand. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "internal.h"
#include "lodkit.h"


/* ---- info -------------------------------------------------------------- */

static const char info_help[] =
    "Usage: lodkit info [options] FILE...\n"
    "Print the size, bounds and topology of meshes and point sets.\n"
    "\n"
    "  --json        one JSON object per file (one per line)\n"
    "  -h, --help    show this help\n"
    CLI_MEMORY_HELP
    "\n"
    "With one FILE the report is a list; with several, a table with a row per file.\n"
    "Genus is -1 when the mesh is not a manifold (it is then undefined).\n";

static cJSON *stats_json(const char *path, const lk_mesh_stats *stats, double load_seconds)
{
    cJSON *object = cJSON_CreateObject();
    cJSON_AddStringToObject(object, "file", path);
    cJSON_AddStringToObject(object, "format", lk_format_name(lk_format_from_path(path)));
    cJSON_AddNumberToObject(object, "vertices", (double)stats->vertex_count);
    cJSON_AddNumberToObject(object, "triangles", (double)stats->triangle_count);
    cJSON_AddNumberToObject(object, "used_vertices", (double)stats->used_vertex_count);
    cJSON_AddNumberToObject(object, "edges", (double)stats->edge_count);
    cJSON *bbox = cJSON_AddObjectToObject(object, "bbox");
    float min[3], max[3];
    memcpy(min, stats->min, sizeof min);
    memcpy(max, stats->max, sizeof max);
    double minimum[3] = {min[0], min[1], min[2]}, maximum[3] = {max[0], max[1], max[2]};
    cJSON_AddItemToObject(bbox, "min", cJSON_CreateDoubleArray(minimum, 3));
    cJSON_AddItemToObject(bbox, "max", cJSON_CreateDoubleArray(maximum, 3));
    cJSON_AddNumberToObject(object, "diagonal", stats->diagonal);
    cJSON_AddNumberToObject(object, "area", stats->area);
    cJSON_AddNumberToObject(object, "components", (double)stats->component_count);
    cJSON_AddNumberToObject(object, "boundary_edges", (double)stats->boundary_edge_count);
    cJSON_AddNumberToObject(object, "boundary_loops", (double)stats->boundary_loop_count);
    cJSON_AddNumberToObject(object, "nonmanifold_edges", (double)stats->nonmanifold_edge_count);
    cJSON_AddNumberToObject(object, "nonmanifold_vertices", (double)stats->nonmanifold_vertex_count);
    cJSON_AddNumberToObject(object, "degenerate_triangles", (double)stats->degenerate_triangle_count);
    cJSON_AddNumberToObject(object, "duplicate_triangles", (double)stats->duplicate_triangle_count);
    cJSON_AddNumberToObject(object, "euler_characteristic", (double)stats->euler_characteristic);
    cJSON_AddNumberToObject(object, "genus", (double)stats->genus);
    cJSON_AddNumberToObject(object, "load_seconds", load_seconds);
    return object;
}

static void print_stats_list(const char *path, const lk_mesh *mesh, const lk_mesh_stats *stats, double load_seconds)
{
    printf("file                  %s\n", path);
    printf("format                %s\n", lk_format_name(lk_format_from_path(path)));
    printf("vertices              %s\n", thousands(stats->vertex_count));
    printf("triangles             %s\n", thousands(stats->triangle_count));
    if (stats->triangle_count) {
        printf("edges                 %s\n", thousands(stats->edge_count));
        if (stats->used_vertex_count != stats->vertex_count)
            printf("unused vertices       %s\n", thousands(stats->vertex_count - stats->used_vertex_count));
    }
    printf("attributes           %s%s%s%s\n", mesh->normals ? " normals" : "", mesh->texcoords ? " texcoords" : "",
           mesh->colors ? " colors" : "", !mesh->normals && !mesh->texcoords && !mesh->colors ? " none" : "");
    printf("bbox min              %g %g %g\n", (double)stats->min[0], (double)stats->min[1], (double)stats->min[2]);
    printf("bbox max              %g %g %g\n", (double)stats->max[0], (double)stats->max[1], (double)stats->max[2]);
    printf("diagonal              %g\n", stats->diagonal);
    if (stats->triangle_count) {
        printf("area                  %g\n", stats->area);
        printf("components            %s\n", thousands(stats->component_count));
        printf("boundary edges        %s (%s loops)\n", thousands(stats->boundary_edge_count),
               thousands(stats->boundary_loop_count));
        printf("non-manifold edges    %s\n", thousands(stats->nonmanifold_edge_count));
        printf("non-manifold vertices %s\n", thousands(stats->nonmanifold_vertex_count));
        printf("degenerate triangles  %s\n", thousands(stats->degenerate_triangle_count));
        printf("duplicate triangles   %s\n", thousands(stats->duplicate_triangle_count));
        printf("euler characteristic  %lld\n", stats->euler_characteristic);
        if (stats->genus >= 0) printf("genus                 %lld\n", stats->genus);
        else printf("genus                 undefined (not a manifold)\n");
    }
    printf("load time             %.1f ms\n", load_seconds * 1000);
}

static const char *short_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

static int command_info(int argc, char **argv)
{
    static const struct option options[] = {{"json", no_argument, NULL, 'j'}, {"help", no_argument, NULL, 'h'}, {0}};
    int json = 0, option;
    while ((option = getopt_long(argc, argv, "h", options, NULL)) != -1) {
        switch (option) {
        case 'j': json = 1; break;
        case 'h': fputs(info_help, stdout); return EXIT_OK;
        default: return usage_error("info", "%s", "invalid option");
        }
    }
    if (optind >= argc) return usage_error("info", "%s", "missing FILE");
    int file_count = argc - optind, result = EXIT_OK;
    if (file_count > 1 && !json)
        printf("%-24s %10s %10s %10s %5s %8s %8s %5s %9s\n", "file", "vertices", "triangles", "diagonal", "comp",
               "boundary", "nonmanif", "genus", "load ms");
    for (int i = optind; i < argc; i++) {
        lk_mesh mesh;
        lk_error error = {0};
        double seconds;
        lk_mesh_stats stats;
        if (load_mesh(argv[i], &mesh, &seconds, &error) != LK_OK ||
            lk_mesh_compute_stats(&mesh, &stats, &error) != LK_OK) {
            print_error_for(argv[i], NULL, &error);
            lk_mesh_free(&mesh);
            result = EXIT_BAD_INPUT;
            continue;
        }
        if (json) {
            print_json(stats_json(argv[i], &stats, seconds));
        } else if (file_count == 1) {
            print_stats_list(argv[i], &mesh, &stats, seconds);
        } else {
            char genus[24];
            if (stats.genus >= 0) snprintf(genus, sizeof genus, "%lld", stats.genus);
            else snprintf(genus, sizeof genus, "-");
            printf("%-24s %10s %10s %10.4g %5s %8s %8s %5s %9.1f\n", short_name(argv[i]),
                   thousands(stats.vertex_count), thousands(stats.triangle_count), stats.diagonal,
                   thousands(stats.component_count), thousands(stats.boundary_edge_count),
                   thousands(stats.nonmanifold_edge_count), genus, seconds * 1000);
        }
        lk_mesh_free(&mesh);
    }
    return result;
}

/* ---- convert ----------------------------------------------------------- */

static const char convert_help[] =
    "Usage: lodkit convert [options] IN OUT\n"
    "Convert between mesh formats; the formats come from the file extensions\n"
    "(read: obj ply off smf xyz stl gltf glb; write: obj ply off smf xyz stl).\n"
    "\n"
    "  --ascii                  PLY/STL: write text instead of binary\n"
    "  --big-endian             PLY: write binary big-endian\n"
    "  --weld[=TOL]             merge vertices closer than TOL (model units, default 0 = identical)\n"
    "  --clean                  remove degenerate and duplicate triangles and unused vertices\n"
    "  --translate=X,Y,Z        move the mesh by (X,Y,Z) model units\n"
    "  --translate-diagonal=X,Y,Z  move the mesh by (X,Y,Z) times its bounding-box diagonal\n"
    "  --no-normals, --no-texcoords, --no-colors   drop these attributes\n"
    "  -q, --quiet              print nothing on success\n"
    "  -h, --help               show this help\n"
    CLI_MEMORY_HELP;

static int command_convert(int argc, char **argv)
{
    enum { OPT_ASCII = 256, OPT_BE, OPT_WELD, OPT_CLEAN, OPT_TRANSLATE, OPT_TRANSLATE_DIAGONAL, OPT_NO_NORMALS,
           OPT_NO_TEXCOORDS, OPT_NO_COLORS };
    static const struct option options[] = {
        {"ascii", no_argument, NULL, OPT_ASCII}, {"big-endian", no_argument, NULL, OPT_BE},
        {"weld", optional_argument, NULL, OPT_WELD}, {"clean", no_argument, NULL, OPT_CLEAN},
        {"translate", required_argument, NULL, OPT_TRANSLATE},
        {"translate-diagonal", required_argument, NULL, OPT_TRANSLATE_DIAGONAL},
        {"no-normals", no_argument, NULL, OPT_NO_NORMALS}, {"no-texcoords", no_argument, NULL, OPT_NO_TEXCOORDS},
        {"no-colors", no_argument, NULL, OPT_NO_COLORS}, {"quiet", no_argument, NULL, 'q'},
        {"help", no_argument, NULL, 'h'}, {0}};
    lk_write_options write_options = {0};
    int weld = 0, clean = 0, quiet = 0, translate = 0, translate_relative = 0, option;
    double weld_tolerance = 0, offset[3] = {0, 0, 0};
    while ((option = getopt_long(argc, argv, "qh", options, NULL)) != -1) {
        switch (option) {
        case OPT_ASCII: write_options.ply_encoding = LK_PLY_ASCII; write_options.stl_ascii = 1; break;
        case OPT_BE: write_options.ply_encoding = LK_PLY_BINARY_BE; break;
        case OPT_WELD:
            weld = 1;
            if (optarg && (!parse_double_option(optarg, &weld_tolerance) || weld_tolerance < 0))
                return usage_error("convert", "--weld: '%s' is not a tolerance >= 0", optarg);
            break;
        case OPT_CLEAN: clean = 1; break;
        case OPT_TRANSLATE:
        case OPT_TRANSLATE_DIAGONAL:
            if (!parse_vector3(optarg, offset)) return usage_error("convert", "expected X,Y,Z, got '%s'", optarg);
            translate = 1;
            translate_relative = option == OPT_TRANSLATE_DIAGONAL;
            break;
        case OPT_NO_NORMALS: write_options.skip_normals = 1; break;
        case OPT_NO_TEXCOORDS: write_options.skip_texcoords = 1; break;
        case OPT_NO_COLORS: write_options.skip_colors = 1; break;
        case 'q': quiet = 1; break;
        case 'h': fputs(convert_help, stdout); return EXIT_OK;
        default: return usage_error("convert", "%s", "invalid option");
        }
    }
    if (argc - optind != 2) return usage_error("convert", "%s", "expected IN and OUT");
    const char *in = argv[optind], *out = argv[optind + 1];
    lk_format out_format = lk_format_from_path(out);
    if (out_format == LK_FORMAT_UNKNOWN || out_format == LK_FORMAT_GLTF)
        return usage_error("convert", "cannot write '%s': use .obj .ply .off .smf .xyz or .stl", out);
    lk_mesh mesh;
    lk_error error = {0};
    size_t merged = 0, degenerate = 0, duplicate = 0, unused = 0;
    lk_status status = load_mesh(in, &mesh, NULL, &error);
    if (status == LK_OK && weld) status = lk_mesh_weld(&mesh, weld_tolerance, &merged, &error);
    if (status == LK_OK && clean) status = lk_mesh_remove_degenerate(&mesh, &degenerate, &duplicate, &error);
    if (status == LK_OK && clean) status = lk_mesh_remove_unused_vertices(&mesh, &unused, &error);
    if (status == LK_OK && translate) {
        double scale = translate_relative ? lk_mesh_bounds(&mesh, NULL, NULL) : 1.0;
        lk_mesh_translate(&mesh, offset[0] * scale, offset[1] * scale, offset[2] * scale);
    }
    if (status == LK_OK) status = lk_mesh_write(out, out_format, &mesh, &write_options, &error);
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        lk_mesh_free(&mesh);
        return EXIT_BAD_INPUT;
    }
    if (!quiet) {
        printf("%s: %s vertices, %s triangles -> %s", in, thousands(mesh.vertex_count),
               thousands(mesh.triangle_count), out);
        if (weld) printf(" (welded %s)", thousands(merged));
        if (clean)
            printf(" (removed %s degenerate, %s duplicate triangles, %s unused vertices)", thousands(degenerate),
                   thousands(duplicate), thousands(unused));
        putchar('\n');
    }
    lk_mesh_free(&mesh);
    return EXIT_OK;
}

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


static int command_metro(int argc, char **argv)
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

static int command_simplify(int argc, char **argv)
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

/* ---- subdivide --------------------------------------------------------- */

static const char subdivide_help[] =
    "Usage: lodkit subdivide [options] IN OUT\n"
    "Subdivide a triangle mesh; each iteration multiplies the triangle count by 4.\n"
    "\n"
    "  -s, --scheme=S        loop (smooth, default) or midpoint (flat, exact area)\n"
    "  -n, --iterations=N    how many times (default 1)\n"
    "  -q, --quiet           print nothing on success\n"
    "  -h, --help            show this help\n"
    CLI_MEMORY_HELP;

static int command_subdivide(int argc, char **argv)
{
    static const struct option options[] = {
        {"scheme", required_argument, NULL, 's'}, {"iterations", required_argument, NULL, 'n'},
        {"quiet", no_argument, NULL, 'q'}, {"help", no_argument, NULL, 'h'}, {0}};
    lk_subdivide_scheme scheme = LK_SUBDIVIDE_LOOP;
    size_t iterations = 1;
    int quiet = 0, option;
    while ((option = getopt_long(argc, argv, "s:n:qh", options, NULL)) != -1) {
        switch (option) {
        case 's':
            if (!strcmp(optarg, "loop")) scheme = LK_SUBDIVIDE_LOOP;
            else if (!strcmp(optarg, "midpoint")) scheme = LK_SUBDIVIDE_MIDPOINT;
            else return usage_error("subdivide", "--scheme: '%s' is not loop or midpoint", optarg);
            break;
        case 'n':
            if (!parse_size_option(optarg, &iterations) || iterations > 16)
                return usage_error("subdivide", "--iterations: '%s' is not a count from 0 to 16", optarg);
            break;
        case 'q': quiet = 1; break;
        case 'h': fputs(subdivide_help, stdout); return EXIT_OK;
        default: return usage_error("subdivide", "%s", "invalid option");
        }
    }
    if (argc - optind != 2) return usage_error("subdivide", "%s", "expected IN and OUT");
    const char *in = argv[optind], *out = argv[optind + 1];
    lk_format out_format = triangle_output_format(out);
    if (out_format == LK_FORMAT_UNKNOWN)
        return usage_error("subdivide", "cannot write a mesh to '%s': use .obj .ply .off .smf or .stl", out);
    lk_mesh mesh, result;
    lk_error error = {0};
    lk_mesh_init(&result);
    double start = 0;
    lk_status status = load_mesh(in, &mesh, NULL, &error);
    if (status == LK_OK) {
        start = lk__now();
        status = lk_subdivide(&mesh, scheme, (unsigned)iterations, &result, &error);
    }
    double seconds = lk__now() - start;
    if (status == LK_OK) status = lk_mesh_write(out, out_format, &result, NULL, &error);
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        lk_mesh_free(&mesh);
        lk_mesh_free(&result);
        return EXIT_BAD_INPUT;
    }
    if (!quiet)
        printf("%s: %s triangles -> %s: %s vertices, %s triangles (%s x%zu, %.1f ms)\n", in,
               thousands(mesh.triangle_count), out, thousands(result.vertex_count), thousands(result.triangle_count),
               scheme == LK_SUBDIVIDE_LOOP ? "loop" : "midpoint", iterations, seconds * 1000);
    lk_mesh_free(&mesh);
    lk_mesh_free(&result);
    return EXIT_OK;
}

/* ---- main -------------------------------------------------------------- */

static const char main_help[] =
    "Usage: lodkit COMMAND [options] [args]\n"
    "lodkit: multiresolution 3D geometry for networked graphics.\n"
    "\n"
    "Commands:\n"
    "  info      sizes, bounds and topology of meshes and point sets\n"
    "  convert   convert between obj, ply, off, smf, xyz, stl (and read gltf/glb)\n"
    "  metro     surface distance between two meshes (Hausdorff, mean, RMS)\n"
    "  simplify  reduce a mesh: quadric error metric or vertex clustering\n"
    "  subdivide refine a mesh: Loop or midpoint subdivision\n"
    "  progressive  build a progressive mesh on triangle strips as a .lks stream\n"
    "  unpack    decode a .lks stream up to a level into a mesh\n"
    "  inspect   header and chunk table of a .lks stream\n"
    "  render    draw a mesh (or point set) offscreen into a PNG (OpenGL ES 2.0)\n"
    "  sample    turn a mesh into an oriented point set with splat radii\n"
    "  splat     draw a point set as Phong splats into a PNG (1- or 2-pass)\n"
    "  terrain   fly over an elevation grid with continuous LOD: cracks, popping, timing\n"
    "  slices    draw a mesh's planar-sampling contours before and after wavelet simplification\n"
    "  animate   simplify a key-frame or skinned animation into LOD levels, measured per frame\n"
    "  serve     HTTP server: the WebGL viewer and progressive streams, point sets, terrains\n"
    "\n"
    "Run 'lodkit COMMAND --help' for a command's options.\n"
    "  -h, --help      show this help\n"
    "  -V, --version   print the version\n"
    "\n"
    "Global option (before or after COMMAND):\n"
    CLI_MEMORY_HELP
    "\n"
    "Exit status: 0 success, 1 bad input (unreadable or invalid files), 2 usage error.\n";

int main(int argc, char **argv)
{
    /* --max-memory may come before or after the command name. */
    int global = cli_take_global_options(&argc, argv);
    if (global >= 0) return global;
    if (argc < 2) {
        fputs(main_help, stderr);
        return EXIT_USAGE;
    }
    const char *command = argv[1];
    if (!strcmp(command, "-h") || !strcmp(command, "--help") || !strcmp(command, "help")) {
        fputs(main_help, stdout);
        return EXIT_OK;
    }
    if (!strcmp(command, "-V") || !strcmp(command, "--version")) {
        printf("lodkit %s\n", lk_version());
        return EXIT_OK;
    }
    static const struct { const char *name; int (*run)(int, char **); } commands[] = {
        {"info", command_info},         {"convert", command_convert},     {"metro", command_metro},
        {"simplify", command_simplify}, {"subdivide", command_subdivide}, {"progressive", command_progressive},
        {"unpack", command_unpack},     {"inspect", command_inspect},         {"render", command_render},
        {"sample", command_sample},     {"splat", command_splat},             {"terrain", command_terrain},
        {"slices", command_slices},     {"animate", command_animate},         {"serve", command_serve}};
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++) {
        if (strcmp(command, commands[i].name) == 0) {
            optind = 1;
            return commands[i].run(argc - 1, argv + 1);
        }
    }
    fprintf(stderr, "%s: unknown command '%s'\nTry '%s --help' for the list of commands.\n", program, command, program);
    return EXIT_USAGE;
}
