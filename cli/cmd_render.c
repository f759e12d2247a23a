/* lodkit render: a mesh (lit, indexed or strips) or a point set (Phong
 * splats) drawn offscreen into a PNG. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static const char render_help[] =
    "Usage: lodkit render [options] IN -o OUT.png\n"
    "Draw a mesh (lit, two-sided Phong shading) or a point set (Phong splats) with\n"
    "OpenGL ES 2.0 offscreen (EGL, no display needed) and save the picture as PNG.\n"
    "The camera orbits the model's centre and frames it unless --view gives a distance.\n"
    "\n"
    "  -o, --output=OUT.png    image to write (required)\n"
    "  -s, --size=WxH          image size in pixels, 1..8192 a side (default 800x800)\n"
    "      --view=A,E,D        azimuth and elevation in degrees, distance in bounding-\n"
    "                          sphere radii (0 frames the model; default 30,20,0)\n"
    "      --background=R,G,B  background colour, 0..1 (or 0..255) each (default white)\n"
    "  meshes:\n"
    "      --wireframe         draw the edges over the surface\n"
    "      --strips            draw one triangle strip (lodkit's stripifiers) instead of\n"
    "                          indexed triangles\n"
    "  point sets:\n"
    "      --passes=1|2        1: Gaussian splats blended in one pass (default);\n"
    "                          2: visibility + accumulation + normalisation\n"
    "      --no-culling        keep back-facing splats\n"
    "      --flat-points       plain square points, no lighting (the baseline)\n"
    "\n"
    "      --json              print one JSON object\n"
    "  -q, --quiet             print nothing but errors\n"
    "  -h, --help              show this help\n"
    CLI_MEMORY_HELP
    "\n"
    "Without an EGL/GLES2 driver (Debian: libegl-mesa0 libgl1-mesa-dri libgles2) the\n"
    "command fails with exit status 1 and says what is missing.\n";


int command_render(int argc, char **argv)
{
    enum { OPT_VIEW = 256, OPT_BACKGROUND, OPT_WIREFRAME, OPT_STRIPS, OPT_PASSES, OPT_NO_CULLING, OPT_FLAT, OPT_JSON };
    static const struct option options[] = {
        {"output", required_argument, NULL, 'o'},     {"size", required_argument, NULL, 's'},
        {"view", required_argument, NULL, OPT_VIEW},  {"background", required_argument, NULL, OPT_BACKGROUND},
        {"wireframe", no_argument, NULL, OPT_WIREFRAME}, {"strips", no_argument, NULL, OPT_STRIPS},
        {"passes", required_argument, NULL, OPT_PASSES}, {"no-culling", no_argument, NULL, OPT_NO_CULLING},
        {"flat-points", no_argument, NULL, OPT_FLAT}, {"json", no_argument, NULL, OPT_JSON},
        {"quiet", no_argument, NULL, 'q'},            {"help", no_argument, NULL, 'h'},
        {0}};
    lk_render_options render_options;
    lk_render_options_default(&render_options);
    unsigned width = 800, height = 800;
    const char *out = NULL;
    int json = 0, quiet = 0, option;
    double vector[3];
    size_t passes;
    while ((option = getopt_long(argc, argv, "o:s:qh", options, NULL)) != -1) {
        switch (option) {
        case 'o': out = optarg; break;
        case 's':
            if (!parse_image_size(optarg, &width, &height))
                return usage_error("render", "--size: '%s' is not WxH with sides from 1 to 8192", optarg);
            break;
        case OPT_VIEW:
            if (!parse_view_option(optarg, &render_options))
                return usage_error("render", "--view: '%s' is not azimuth,elevation,distance (distance >= 0)",
                                   optarg);
            break;
        case OPT_BACKGROUND: {
            if (!parse_vector3(optarg, vector))
                return usage_error("render", "--background: '%s' is not r,g,b", optarg);
            int bytes = vector[0] > 1 || vector[1] > 1 || vector[2] > 1; /* 0..255 given */
            for (int k = 0; k < 3; k++) {
                double value = bytes ? vector[k] / 255.0 : vector[k];
                if (value < 0 || value > 1)
                    return usage_error("render", "--background: '%s' has a channel outside 0..1 (or 0..255)",
                                       optarg);
                render_options.background[k] = (float)value;
            }
            break;
        }
        case OPT_WIREFRAME: render_options.wireframe = 1; break;
        case OPT_STRIPS: render_options.strips = 1; break;
        case OPT_PASSES:
            if (!parse_size_option(optarg, &passes) || passes < 1 || passes > 2)
                return usage_error("render", "--passes: '%s' is not 1 or 2", optarg);
            render_options.passes = (unsigned)passes;
            break;
        case OPT_NO_CULLING: render_options.backface_culling = 0; break;
        case OPT_FLAT: render_options.flat_points = 1; break;
        case OPT_JSON: json = 1; break;
        case 'q': quiet = 1; break;
        case 'h': fputs(render_help, stdout); return EXIT_OK;
        default: return usage_error("render", "%s", "invalid option");
        }
    }
    if (argc - optind != 1) return usage_error("render", "%s", "expected one input file");
    if (!out) return usage_error("render", "%s", "missing -o OUT.png");
    const char *in = argv[optind];

    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_render_stats stats;
    memset(&stats, 0, sizeof stats);
    char renderer_name[256] = "";
    lk_error error = {0};
    lk_status status = load_mesh(in, &mesh, NULL, &error);
    int points = status == LK_OK && mesh.triangle_count == 0;
    if (status == LK_OK)
        status = render_to_png(&mesh, points, width, height, &render_options, out, &stats, renderer_name,
                               sizeof renderer_name, &error);

    int exit_code = EXIT_OK;
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        exit_code = EXIT_BAD_INPUT;
    } else if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddStringToObject(root, "kind", points ? "points" : "mesh");
        cJSON_AddNumberToObject(root, "width", width);
        cJSON_AddNumberToObject(root, "height", height);
        cJSON_AddNumberToObject(root, "vertices", (double)mesh.vertex_count);
        cJSON_AddNumberToObject(root, "triangles", (double)mesh.triangle_count);
        cJSON_AddNumberToObject(root, "primitives", (double)stats.primitives);
        cJSON_AddNumberToObject(root, "indices", (double)stats.indices);
        cJSON_AddNumberToObject(root, "milliseconds", stats.milliseconds);
        cJSON_AddStringToObject(root, "renderer", renderer_name);
        print_json(root);
    } else if (!quiet) {
        if (points)
            printf("%s: %ux%u, %s points (%s, %u pass%s) in %.1f ms [%s]\n", out, width, height,
                   thousands(stats.primitives), render_options.flat_points ? "flat" : "Phong splats",
                   render_options.passes, render_options.passes == 1 ? "" : "es", stats.milliseconds,
                   renderer_name);
        else
            printf("%s: %ux%u, %s %s (%s indices) in %.1f ms [%s]\n", out, width, height,
                   thousands(stats.primitives), render_options.strips ? "strip triangles" : "triangles",
                   thousands(stats.indices), stats.milliseconds, renderer_name);
    }
    lk_mesh_free(&mesh);
    return exit_code;
}
