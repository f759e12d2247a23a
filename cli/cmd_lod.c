/* SPDX-License-Identifier: MIT */
/* lodkit lod: a chain of levels of detail of one mesh (QEM), written as one
 * glTF with MSFT_lod or as one file per level. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

/* The screen the coverage hints are computed for: a level is good while its
 * error covers at most this many pixels of a screen this many pixels high. */
#define SCREEN_HEIGHT_PIXELS 1080.0
#define PIXEL_ERROR 1.0

const cli_help lod_help = {
    "IN OUT",
    "Simplify a mesh into levels of detail, finest first (level 0 is the input), with the quadric error metric.\n"
    "OUT.glb or OUT.gltf gets every level in one file with the MSFT_lod extension: loaders that know it switch\n"
    "levels by the screen coverage in MSFT_screencoverage, the others draw level 0. With --separate, OUT names\n"
    "the first of one file per level (STEM_lod0.EXT, STEM_lod1.EXT, ...), in any mesh format.\n"
    "With a glTF input and output the scene is kept: each node drawing a mesh gets a\n"
    "node per coarser level. An OBJ input keeps its .mtl materials the same way.\n",
    "Screen coverage: level K is used while the model's bounding sphere covers at most\n"
    "diagonal / (error_K x 1080) of the screen's height, i.e. while its error stays under one pixel of a\n"
    "1080-pixel screen. Each node's extras.lodkit holds its level, triangles and error (model units).\n",
};

/* STEM_lodK.EXT for OUT = STEM.EXT. */
static char *level_path(const char *out, size_t level)
{
    const char *slash = strrchr(out, '/');
    const char *dot = strrchr(slash ? slash + 1 : out, '.');
    size_t stem = dot ? (size_t)(dot - out) : strlen(out);
    size_t size = strlen(out) + 32;
    char *path = malloc(size);
    if (path) snprintf(path, size, "%.*s_lod%zu%s", (int)stem, out, level, dot ? dot : "");
    return path;
}

/* Coverage: level K is good up to diagonal / (error_K * H) of the screen;
 * the switch from K to K + 1 happens below K + 1's value. */
static void set_screen_coverage(lk_lod_level_info *info, size_t level_count, double diagonal)
{
    for (size_t level = 0; level < level_count; level++) {
        double next_error = level + 1 < level_count ? info[level + 1].error : INFINITY;
        double coverage = next_error > 0 ? PIXEL_ERROR * diagonal / (next_error * SCREEN_HEIGHT_PIXELS) : 1;
        if (!(coverage < 1)) coverage = 1;
        if (level > 0 && coverage > info[level - 1].screen_coverage) coverage = info[level - 1].screen_coverage;
        info[level].screen_coverage = level + 1 < level_count ? coverage : 0;
    }
}

/* glTF in and out: every mesh of the scene gets its levels (lk_scene_lod_chain);
 * the errors are the largest over the primitives, the coverage as for one
 * mesh with the scene's diagonal. */
static int lod_scene(const char *in, const char *out, size_t level_count, double ratio, int separate, unsigned flags,
                     int measure, const lk_write_options *write_options, int json, int quiet)
{
    lk_scene *levels = calloc(level_count, sizeof *levels);
    double *measured = calloc(level_count, sizeof *measured);
    lk_lod_level_info *info = calloc(level_count, sizeof *info);
    size_t *triangles = calloc(level_count, sizeof *triangles);
    lk_error error = {0};
    lk_scene chain;
    lk_scene_init(&chain);
    if (!levels || !info || !triangles || !measured) {
        free(levels), free(info), free(triangles), free(measured);
        fprintf(stderr, "lodkit lod: out of memory\n");
        return EXIT_BAD_INPUT;
    }
    double diagonal = 1, start = now_seconds();
    lk_status status = load_scene(in, &levels[0], &error);
    if (status == LK_OK) {
        lk_mesh flat;
        status = lk_scene_flatten(&levels[0], &flat, &error);
        if (status == LK_OK) diagonal = lk_mesh_bounds(&flat, NULL, NULL);
        if (status == LK_OK && flat.triangle_count == 0)
            status = lk_error_set(&error, LK_ERR_INVALID, "%s: no triangles: levels of detail need triangles", in);
        lk_mesh_free(&flat);
        if (!(diagonal > 0)) diagonal = 1;
        triangles[0] = lk_scene_triangle_count(&levels[0]);
    }
    for (size_t level = 1; status == LK_OK && level < level_count; level++) {
        status = lk_scene_copy(&levels[level], &levels[level - 1], &error);
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        /* each level from the one before: the ratio compounds */
        options.target_ratio = ratio;
        options.flags = flags;
        lk_scene_simplify_stats stats;
        if (status == LK_OK) status = lk_scene_simplify(&levels[level], LK_SIMPLIFY_QEM, &options, &stats, &error);
        if (status != LK_OK) break;
        info[level].error = stats.error > info[level - 1].error ? stats.error : info[level - 1].error;
        triangles[level] = lk_scene_triangle_count(&levels[level]);
    }
    double seconds = now_seconds() - start;
    /* --measure: each level drawn against level 0 drawn (lk_metro on the
     * flattened scenes) */
    lk_mesh drawn_input;
    lk_mesh_init(&drawn_input);
    if (status == LK_OK && measure) status = lk_scene_flatten(&levels[0], &drawn_input, &error);
    for (size_t level = 1; status == LK_OK && measure && level < level_count; level++) {
        lk_mesh drawn;
        lk_metro_result metro;
        status = lk_scene_flatten(&levels[level], &drawn, &error);
        if (status == LK_OK) status = lk_metro(&drawn_input, &drawn, NULL, &metro, NULL, NULL, &error);
        if (status == LK_OK) measured[level] = metro.hausdorff;
        lk_mesh_free(&drawn);
    }
    lk_mesh_free(&drawn_input);
    if (status == LK_OK) set_screen_coverage(info, level_count, diagonal);
    if (status == LK_OK && !separate) {
        status = lk_scene_lod_chain(levels, level_count, info, &chain, &error);
        if (status == LK_OK) status = lk_scene_write(out, &chain, write_options, &error);
    }
    for (size_t level = 0; status == LK_OK && separate && level < level_count; level++) {
        char *path = level_path(out, level);
        status = path ? lk_scene_write(path, &levels[level], write_options, &error)
                      : lk_error_set(&error, LK_ERR_NOMEM, "out of memory");
        free(path);
    }
    int exit_code = EXIT_OK;
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        exit_code = EXIT_BAD_INPUT;
    } else if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddBoolToObject(root, "separate", separate);
        cJSON_AddBoolToObject(root, "scene", 1);
        cJSON_AddNumberToObject(root, "diagonal", diagonal);
        cJSON_AddNumberToObject(root, "seconds", seconds);
        cJSON *array = cJSON_AddArrayToObject(root, "levels");
        for (size_t level = 0; level < level_count; level++) {
            cJSON *item = cJSON_CreateObject();
            cJSON_AddItemToArray(array, item);
            cJSON_AddNumberToObject(item, "level", (double)level);
            cJSON_AddNumberToObject(item, "triangles", (double)triangles[level]);
            cJSON_AddNumberToObject(item, "error", info[level].error);
            if (measure) cJSON_AddNumberToObject(item, "hausdorff_percent", 100 * measured[level] / diagonal);
            cJSON_AddNumberToObject(item, "screen_coverage", info[level].screen_coverage);
        }
        print_json(root);
    } else if (!quiet) {
        printf("%s: %s -> %s%s: %zu levels of each mesh (qem per primitive, %.1f ms)\n", in, scene_summary(&levels[0]),
               out, separate ? " (one file per level)" : " (MSFT_lod)", level_count, seconds * 1000);
        for (size_t level = 0; level < level_count; level++) {
            printf("  level %zu: %s, error %.4f%% of the diagonal", level, n_triangles(triangles[level]),
                   100 * info[level].error / diagonal);
            if (measure && level > 0) printf(" (hausdorff %.4f%%)", 100 * measured[level] / diagonal);
            if (level + 1 < level_count)
                printf(", level %zu below %.4g%% of the screen height", level + 1, 100 * info[level].screen_coverage);
            putchar('\n');
        }
        print_scene_notes(&levels[0]);
    }
    for (size_t level = 0; level < level_count; level++) lk_scene_free(&levels[level]);
    lk_scene_free(&chain);
    free(levels), free(info), free(triangles), free(measured);
    return exit_code;
}

int cmd_lod(int argc, char **argv)
{
    size_t level_count = 4;
    double ratio = 0.5;
    int separate = 0, measure = 0;
    lk_write_options write_options = {0};
    unsigned flags = 0;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_LOD, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_LEVELS:
            if (!parse_size_option(arg, &level_count) || level_count < 1 || level_count > 32)
                return usage_error("lod", "--levels: '%s' is not a count from 1 to 32", arg);
            break;
        case OPT_RATIO:
            if (!parse_double_option(arg, &ratio) || !(ratio > 0 && ratio < 1))
                return usage_error("lod", "--ratio: '%s' is not a fraction between 0 and 1 (exclusive)", arg);
            break;
        case OPT_SEPARATE: separate = 1; break;
        case OPT_ATTRIBUTES: flags |= LK_SIMPLIFY_ATTRIBUTES; break;
        case OPT_MEASURE: measure = 1; break;
        case OPT_QUANTIZE:
        case OPT_MESHOPT:
        case OPT_EXTERNAL_IMAGES: gltf_flag_option(id, &write_options.gltf_flags); break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("lod", "%s", "expected IN and OUT");
    const char *in = argv[optind], *out = argv[optind + 1];
    if (!separate) {
        const lk_format_info *named = lk_format_info_from_path(out);
        if (!named || named->format != LK_FORMAT_GLTF)
            return usage_error("lod", "%s: the levels go into one glTF (name it .glb or .gltf), or use --separate",
                               out);
    } else if (output_mesh_format("lod", out, 0) == LK_FORMAT_UNKNOWN) {
        return EXIT_USAGE;
    }
    if (check_gltf_flags("lod", out, write_options.gltf_flags)) return EXIT_USAGE;
    if (is_gltf_path(out) && reads_as_scene(in))
        return lod_scene(in, out, level_count, ratio, separate, flags, measure, &write_options, json, quiet);

    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_error error = {0};
    lk_mesh *levels = calloc(level_count, sizeof(lk_mesh));
    lk_lod_level_info *info = calloc(level_count, sizeof(lk_lod_level_info));
    double *measured = calloc(level_count, sizeof(double));
    int *reached = calloc(level_count, sizeof(int));
    if (!levels || !info || !measured || !reached) {
        free(levels), free(info), free(measured), free(reached);
        fprintf(stderr, "lodkit lod: out of memory\n");
        return EXIT_BAD_INPUT;
    }
    double start = 0, diagonal = 1;
    lk_status status = load_mesh(in, &mesh, NULL, NULL, &error);
    if (status == LK_OK && mesh.triangle_count == 0)
        status = lk_error_set(&error, LK_ERR_INVALID, "%s: a point set (%zu points): levels of detail need triangles",
                              in, mesh.vertex_count);
    if (status == LK_OK) {
        float low[3], high[3];
        diagonal = lk_mesh_bounds(&mesh, low, high);
        if (!(diagonal > 0)) diagonal = 1;
        levels[0] = mesh; /* level 0 is the input (freed once, as `mesh`) */
        reached[0] = 1;
        start = now_seconds();
    }
    progress_state progress;
    for (size_t level = 1; status == LK_OK && level < level_count; level++) {
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_ratio = pow(ratio, (double)level);
        options.flags = flags;
        lk_simplify_result result;
        char label[32];
        snprintf(label, sizeof label, "level %zu", level);
        progress_init(&progress, quiet || json, label);
        status = lk_simplify(&mesh, LK_SIMPLIFY_QEM, &options, &result, progress_draw, &progress, &error);
        progress_done(&progress);
        if (status != LK_OK) break;
        levels[level] = result.mesh; /* moved: the result no longer owns it */
        lk_mesh_init(&result.mesh);
        info[level].error = result.error;
        reached[level] = result.target_reached;
        lk_simplify_result_free(&result);
        if (measure) {
            lk_metro_result metro;
            progress_init(&progress, quiet || json, "metro");
            status = lk_metro(&mesh, &levels[level], NULL, &metro, progress_draw, &progress, &error);
            progress_done(&progress);
            measured[level] = metro.hausdorff;
        }
    }
    double seconds = now_seconds() - start;
    if (status == LK_OK) set_screen_coverage(info, level_count, diagonal);
    size_t written = 0;
    if (status == LK_OK && !separate) {
        status = lk_mesh_write_lods(out, levels, level_count, info, &write_options, &error);
        written = 1;
    }
    for (size_t level = 0; status == LK_OK && separate && level < level_count; level++) {
        char *path = level_path(out, level);
        if (!path) {
            status = lk_error_set(&error, LK_ERR_NOMEM, "out of memory");
            break;
        }
        status = lk_mesh_write(path, LK_FORMAT_AUTO, &levels[level], &write_options, &error);
        free(path);
        written += status == LK_OK;
    }
    int exit_code = EXIT_OK;
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        if (separate && written)
            fprintf(stderr, "lodkit lod: levels 0 to %zu were written before the failure\n", written - 1);
        exit_code = EXIT_BAD_INPUT;
    } else if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddBoolToObject(root, "separate", separate);
        cJSON_AddNumberToObject(root, "diagonal", diagonal);
        cJSON_AddNumberToObject(root, "seconds", seconds);
        cJSON *array = cJSON_AddArrayToObject(root, "levels");
        for (size_t level = 0; level < level_count; level++) {
            cJSON *item = cJSON_CreateObject();
            cJSON_AddItemToArray(array, item);
            cJSON_AddNumberToObject(item, "level", (double)level);
            cJSON_AddNumberToObject(item, "vertices", (double)levels[level].vertex_count);
            cJSON_AddNumberToObject(item, "triangles", (double)levels[level].triangle_count);
            cJSON_AddNumberToObject(item, "error", info[level].error);
            cJSON_AddNumberToObject(item, "error_percent", 100 * info[level].error / diagonal);
            if (measure) cJSON_AddNumberToObject(item, "hausdorff_percent", 100 * measured[level] / diagonal);
            cJSON_AddNumberToObject(item, "screen_coverage", info[level].screen_coverage);
            cJSON_AddBoolToObject(item, "target_reached", reached[level] != 0);
        }
        print_json(root);
    } else if (!quiet) {
        printf("%s: %s -> %s%s: %zu levels (qem, %.1f ms)\n", in, n_triangles(mesh.triangle_count), out,
               separate ? " (one file per level)" : " (MSFT_lod)", level_count, seconds * 1000);
        for (size_t level = 0; level < level_count; level++) {
            printf("  level %zu: %s, %s, error %.4f%% of the diagonal", level, n_vertices(levels[level].vertex_count),
                   n_triangles(levels[level].triangle_count), 100 * info[level].error / diagonal);
            if (measure && level > 0) printf(" (hausdorff %.4f%%)", 100 * measured[level] / diagonal);
            if (level + 1 < level_count)
                printf(", level %zu below %.4g%% of the screen height", level + 1, 100 * info[level].screen_coverage);
            printf("%s\n", reached[level] ? "" : " (target not reached: nearest result)");
        }
    }
    lk_mesh_free(&mesh); /* also level 0 */
    for (size_t level = 1; level < level_count; level++) lk_mesh_free(&levels[level]);
    free(levels);
    free(info);
    free(measured);
    free(reached);
    return exit_code;
}
