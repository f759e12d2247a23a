/* SPDX-License-Identifier: MIT */
/* lodkit splat: a point set (or a mesh sampled into one, or a point octree
 * under a point budget) drawn as Phong splats, 1- or 2-pass, or as flat
 * points, offscreen into a PNG. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help splat_help = {
    "IN -o OUT.png",
    "Draw an oriented point set (PLY/XYZ with normals) as Phong splats: point\n"
    "sprites sized to each splat's projected diameter, lit per fragment,\n"
    "Gaussian-weighted. A mesh is sampled into points first (like `lodkit sample`).\n"
    "Points without radii get the distance to their 8th nearest neighbour, at\n"
    "most 1.25x the reach of their cell among those 8 in their tangent plane and\n"
    "4x the median radius of those 8 points (so stray points stay small).\n"
    "IN may be a point octree (`lodkit octree`'s folder or its octree.json): only\n"
    "the nodes of largest projected size are loaded, at most --budget points.\n",
    "Without an EGL/GLES2 driver (Debian: libegl-mesa0 libgl1-mesa-dri libgles2) the\n"
    "command fails with exit status 1 and says what is missing.\n",
};

/* 1 when `path` names an octree: a folder, or a file called octree.json. */
static int is_octree_path(const char *path)
{
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) return 1;
    size_t length = strlen(path);
    return length >= 11 && strcmp(path + length - 11, "octree.json") == 0;
}

/* Draws the octree at `in` into `out`. */
static lk_status splat_octree(const char *in, const char *out, unsigned width, unsigned height,
                              const lk_render_options *options, const lk_octree_select_options *select,
                              lk_render_octree_stats *stats, char *renderer_name, size_t renderer_name_size,
                              lk_error *error)
{
    lk_octree *octree = NULL;
    lk_renderer *renderer = NULL;
    lk_status status = lk_octree_open(in, &octree, error);
    if (status == LK_OK) status = lk_renderer_create(width, height, &renderer, error);
    if (status == LK_OK) snprintf(renderer_name, renderer_name_size, "%s", lk_renderer_description(renderer));
    if (status == LK_OK) status = lk_render_octree(renderer, octree, options, select, stats, error);
    if (status == LK_OK) status = write_framebuffer_png(renderer, out, error);
    lk_renderer_free(renderer);
    lk_octree_close(octree);
    return status;
}

int cmd_splat(int argc, char **argv)
{
    lk_octree_select_options select_options;
    lk_octree_select_options_default(&select_options);
    int budget_given = 0;
    lk_render_options render_options;
    lk_render_options_default(&render_options);
    lk_sample_options sample_options;
    lk_sample_options_default(&sample_options);
    unsigned width = 800, height = 800;
    const char *out = NULL;
    int points_given = 0, refused;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_SPLAT, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        if (camera_option(&parser, id, &render_options, &width, &height, &refused)) {
            if (refused >= 0) return refused;
            continue;
        }
        switch (id) {
        case OPT_OUTPUT: out = arg; break;
        case OPT_RADIUS_SCALE:
            if (!parse_double_option(arg, &render_options.radius_scale) || render_options.radius_scale <= 0)
                return usage_error("splat", "--radius-scale: '%s' is not a positive number", arg);
            break;
        case OPT_POINTS:
            if (!parse_size_option(arg, &sample_options.point_count) || sample_options.point_count < 1 ||
                sample_options.point_count > LK_MAX_ELEMENTS)
                return usage_error("splat", "--points: '%s' is not a positive count", arg);
            points_given = 1;
            break;
        case OPT_BUDGET: {
            size_t budget;
            if (!parse_size_option(arg, &budget) || budget < 1)
                return usage_error("splat", "--budget: '%s' is not a positive point count", arg);
            select_options.point_budget = budget;
            budget_given = 1;
            break;
        }
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 1) return usage_error("splat", "%s", "expected one input file");
    if (!out) return usage_error("splat", "%s", "missing -o OUT.png");
    const char *in = argv[optind];
    int octree = is_octree_path(in);
    if (octree && points_given) return usage_error("splat", "%s", "--points applies to meshes, not octrees");
    if (!octree && budget_given) return usage_error("splat", "%s", "--budget applies to octrees only");

    lk_mesh mesh, sampled;
    lk_mesh_init(&mesh);
    lk_mesh_init(&sampled);
    char renderer_name[256] = "";
    lk_render_stats stats;
    memset(&stats, 0, sizeof stats);
    lk_render_octree_stats octree_stats;
    memset(&octree_stats, 0, sizeof octree_stats);
    lk_error error = {0};
    progress_state progress;
    progress_init(&progress, quiet || json, "splat");
    double sample_seconds = 0;
    lk_status status = octree ? LK_OK : load_mesh(in, &mesh, NULL, NULL, &error);
    int from_mesh = status == LK_OK && mesh.triangle_count > 0;
    if (status == LK_OK && !from_mesh && points_given)
        status = lk_error_set(&error, LK_ERR_INVALID, "%s is a point set: --points only applies to meshes", in);
    if (status == LK_OK && from_mesh) {
        double start = now_seconds();
        status = lk_mesh_sample_points(&mesh, &sample_options, &sampled, progress_draw, &progress, &error);
        sample_seconds = now_seconds() - start;
    }
    progress_done(&progress);
    const lk_mesh *points = from_mesh ? &sampled : &mesh;
    if (status == LK_OK && octree) {
        status = splat_octree(in, out, width, height, &render_options, &select_options, &octree_stats, renderer_name,
                              sizeof renderer_name, &error);
        stats.milliseconds = octree_stats.draw_milliseconds;
    } else if (status == LK_OK)
        status = render_to_png(points, 1, width, height, &render_options, out, &stats, renderer_name,
                               sizeof renderer_name, &error);

    int exit_code = EXIT_OK;
    const char *mode = render_options.flat_points   ? "flat points"
                       : render_options.passes == 2 ? "2-pass splats"
                                                    : "1-pass splats";
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        exit_code = EXIT_BAD_INPUT;
    } else if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddStringToObject(root, "mode",
                                render_options.flat_points   ? "flat"
                                : render_options.passes == 2 ? "2-pass"
                                                             : "1-pass");
        cJSON_AddBoolToObject(root, "culling", render_options.backface_culling != 0);
        cJSON_AddNumberToObject(root, "width", width);
        cJSON_AddNumberToObject(root, "height", height);
        cJSON_AddNumberToObject(root, "points", octree ? (double)octree_stats.points : (double)points->vertex_count);
        if (octree) {
            cJSON_AddNumberToObject(root, "budget", (double)select_options.point_budget);
            cJSON_AddNumberToObject(root, "nodes", (double)octree_stats.nodes);
            cJSON_AddNumberToObject(root, "bytes_loaded", (double)octree_stats.bytes);
            cJSON_AddNumberToObject(root, "select_milliseconds", octree_stats.select_milliseconds);
            cJSON_AddNumberToObject(root, "load_milliseconds", octree_stats.load_milliseconds);
        }
        cJSON_AddBoolToObject(root, "sampled", from_mesh);
        if (from_mesh) cJSON_AddNumberToObject(root, "sample_seconds", sample_seconds);
        cJSON_AddNumberToObject(root, "radius_scale", render_options.radius_scale);
        cJSON_AddNumberToObject(root, "milliseconds", stats.milliseconds);
        cJSON_AddStringToObject(root, "renderer", renderer_name);
        print_json(root);
    } else if (!quiet) {
        if (from_mesh)
            printf("%s: %s sampled into %s in %.2f s\n", in, n_triangles(mesh.triangle_count),
                   count_noun(points->vertex_count, "point", "points"), sample_seconds);
        if (octree)
            printf("%s: %s nodes, %s points (budget %s) loaded in %.1f ms\n", in, thousands(octree_stats.nodes),
                   thousands(octree_stats.points), thousands(select_options.point_budget),
                   octree_stats.load_milliseconds);
        printf("%s: %ux%u, %s %s in %.1f ms [%s]\n", out, width, height,
               thousands(octree ? octree_stats.points : points->vertex_count), mode, stats.milliseconds, renderer_name);
    }
    lk_mesh_free(&sampled);
    lk_mesh_free(&mesh);
    return exit_code;
}
