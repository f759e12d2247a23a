/* lodkit splat: a point set (or a mesh sampled into one) drawn as Phong
 * splats, 1- or 2-pass, or as flat points, offscreen into a PNG. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static const char splat_help[] =
    "Usage: lodkit splat [options] IN -o OUT.png\n"
    "Draw an oriented point set (PLY/XYZ with normals) as Phong splats: point sprites\n"
    "sized to each splat's projected diameter, lit per fragment, Gaussian-weighted.\n"
    "A mesh is sampled into points first (like `lodkit sample`). Points without\n"
    "radii get the distance to their 8th nearest neighbour.\n"
    "\n"
    "  -o, --output=OUT.png    image to write (required)\n"
    "  -s, --size=WxH          image size in pixels, 1..8192 a side (default 800x800)\n"
    "      --view=A,E,D        azimuth and elevation in degrees, distance in bounding-\n"
    "                          sphere radii (0 frames the model; default 30,20,0)\n"
    "      --passes=1|2        1: splats alpha-blended in one pass (default);\n"
    "                          2: visibility + accumulation + normalisation (no\n"
    "                          brightening where splats overlap)\n"
    "      --no-culling        keep back-facing splats\n"
    "      --flat              plain square points, unlit, unblended (the baseline)\n"
    "      --radius-scale=F    multiply every splat radius by F (default 1)\n"
    "      --points=N          when IN is a mesh: sample N points (default 100000)\n"
    "      --json              print one JSON object\n"
    "  -q, --quiet             print nothing but errors\n"
    "  -h, --help              show this help\n"
    CLI_MEMORY_HELP
    "\n"
    "Without an EGL/GLES2 driver (Debian: libegl-mesa0 libgl1-mesa-dri libgles2) the\n"
    "command fails with exit status 1 and says what is missing.\n";


int command_splat(int argc, char **argv)
{
    enum { OPT_VIEW = 256, OPT_PASSES, OPT_NO_CULLING, OPT_FLAT, OPT_RADIUS_SCALE, OPT_POINTS, OPT_JSON };
    static const struct option options[] = {
        {"output", required_argument, NULL, 'o'},       {"size", required_argument, NULL, 's'},
        {"view", required_argument, NULL, OPT_VIEW},    {"passes", required_argument, NULL, OPT_PASSES},
        {"no-culling", no_argument, NULL, OPT_NO_CULLING}, {"flat", no_argument, NULL, OPT_FLAT},
        {"radius-scale", required_argument, NULL, OPT_RADIUS_SCALE},
        {"points", required_argument, NULL, OPT_POINTS}, {"json", no_argument, NULL, OPT_JSON},
        {"quiet", no_argument, NULL, 'q'},              {"help", no_argument, NULL, 'h'},
        {0}};
    lk_render_options render_options;
    lk_render_options_default(&render_options);
    lk_sample_options sample_options;
    lk_sample_options_default(&sample_options);
    unsigned width = 800, height = 800;
    const char *out = NULL;
    int json = 0, quiet = 0, points_given = 0, option;
    size_t value;
    while ((option = getopt_long(argc, argv, "o:s:qh", options, NULL)) != -1) {
        switch (option) {
        case 'o': out = optarg; break;
        case 's':
            if (!parse_image_size(optarg, &width, &height))
                return usage_error("splat", "--size: '%s' is not WxH with sides from 1 to 8192", optarg);
            break;
        case OPT_VIEW:
            if (!parse_view_option(optarg, &render_options))
                return usage_error("splat", "--view: '%s' is not azimuth,elevation,distance (distance >= 0)", optarg);
            break;
        case OPT_PASSES:
            if (!parse_size_option(optarg, &value) || value < 1 || value > 2)
                return usage_error("splat", "--passes: '%s' is not 1 or 2", optarg);
            render_options.passes = (unsigned)value;
            break;
        case OPT_NO_CULLING: render_options.backface_culling = 0; break;
        case OPT_FLAT: render_options.flat_points = 1; break;
        case OPT_RADIUS_SCALE:
            if (!parse_double_option(optarg, &render_options.radius_scale) || render_options.radius_scale <= 0)
                return usage_error("splat", "--radius-scale: '%s' is not a positive number", optarg);
            break;
        case OPT_POINTS:
            if (!parse_size_option(optarg, &sample_options.point_count) || sample_options.point_count < 1 ||
                sample_options.point_count > LK_MAX_ELEMENTS)
                return usage_error("splat", "--points: '%s' is not a positive count", optarg);
            points_given = 1;
            break;
        case OPT_JSON: json = 1; break;
        case 'q': quiet = 1; break;
        case 'h': fputs(splat_help, stdout); return EXIT_OK;
        default: return usage_error("splat", "%s", "invalid option");
        }
    }
    if (argc - optind != 1) return usage_error("splat", "%s", "expected one input file");
    if (!out) return usage_error("splat", "%s", "missing -o OUT.png");
    const char *in = argv[optind];

    lk_mesh mesh, sampled;
    lk_mesh_init(&mesh);
    lk_mesh_init(&sampled);
    char renderer_name[256] = "";
    lk_render_stats stats;
    memset(&stats, 0, sizeof stats);
    lk_error error = {0};
    progress_state progress;
    progress_init(&progress, quiet || json, "splat");
    double sample_seconds = 0;
    lk_status status = load_mesh(in, &mesh, NULL, &error);
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
    if (status == LK_OK)
        status = render_to_png(points, 1, width, height, &render_options, out, &stats, renderer_name,
                               sizeof renderer_name, &error);

    int exit_code = EXIT_OK;
    const char *mode = render_options.flat_points ? "flat points" : render_options.passes == 2 ? "2-pass splats"
                                                                                              : "1-pass splats";
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        exit_code = EXIT_BAD_INPUT;
    } else if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddStringToObject(root, "mode", render_options.flat_points ? "flat" : render_options.passes == 2 ? "2-pass"
                                                                                                              : "1-pass");
        cJSON_AddBoolToObject(root, "culling", render_options.backface_culling != 0);
        cJSON_AddNumberToObject(root, "width", width);
        cJSON_AddNumberToObject(root, "height", height);
        cJSON_AddNumberToObject(root, "points", (double)points->vertex_count);
        cJSON_AddBoolToObject(root, "sampled", from_mesh);
        if (from_mesh) cJSON_AddNumberToObject(root, "sample_seconds", sample_seconds);
        cJSON_AddNumberToObject(root, "radius_scale", render_options.radius_scale);
        cJSON_AddNumberToObject(root, "milliseconds", stats.milliseconds);
        cJSON_AddStringToObject(root, "renderer", renderer_name);
        print_json(root);
    } else if (!quiet) {
        if (from_mesh)
            printf("%s: %s triangles sampled into %s points in %.2f s\n", in, thousands(mesh.triangle_count),
                   thousands(points->vertex_count), sample_seconds);
        printf("%s: %ux%u, %s %s in %.1f ms [%s]\n", out, width, height, thousands(points->vertex_count), mode,
               stats.milliseconds, renderer_name);
    }
    lk_mesh_free(&sampled);
    lk_mesh_free(&mesh);
    return exit_code;
}
