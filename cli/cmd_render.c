/* SPDX-License-Identifier: MIT */
/* lodkit render: a mesh (lit, indexed or strips) or a point set (Phong
 * splats) drawn offscreen into a PNG. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help render_help = {
    "IN -o OUT.png",
    "Draw a mesh (lit, two-sided Phong shading) or a point set (Phong splats) with\n"
    "OpenGL ES 2.0 offscreen (EGL, no display needed) and save the picture as PNG.\n"
    "The camera orbits the model's centre around the --up axis and frames the model\n"
    "unless --view gives a distance. A glTF scene is drawn with its materials: base\n"
    "colour factors and textures (PNG, JPEG).\n",
    "Without an EGL/GLES2 driver (Debian: libegl-mesa0 libgl1-mesa-dri libgles2) the\n"
    "command fails with exit status 1 and says what is missing.\n",
};

int cmd_render(int argc, char **argv)
{
    lk_render_options render_options;
    lk_render_options_default(&render_options);
    unsigned width = 800, height = 800;
    const char *out = NULL;
    int refused;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_RENDER, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        if (camera_option(&parser, id, &render_options, &width, &height, &refused)) {
            if (refused >= 0) return refused;
            continue;
        }
        switch (id) {
        case OPT_OUTPUT: out = parser.value; break;
        case OPT_WIREFRAME: render_options.wireframe = 1; break;
        case OPT_STRIPS: render_options.strips = 1; break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 1) return usage_error("render", "%s", "expected one input file");
    if (!out) return usage_error("render", "%s", "missing -o OUT.png");
    const char *in = argv[optind];

    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_render_stats stats;
    memset(&stats, 0, sizeof stats);
    char renderer_name[256] = "";
    lk_error error = {0};
    lk_status status = load_mesh(in, &mesh, NULL, NULL, &error);
    int points = status == LK_OK && mesh.triangle_count == 0;
    /* glTF and OBJ: the scene with its materials and base colour textures */
    lk_scene scene;
    lk_scene_init(&scene);
    lk_render_scene_info scene_info;
    memset(&scene_info, 0, sizeof scene_info);
    int with_scene = status == LK_OK && !points && reads_as_scene(in);
    if (with_scene) status = load_scene(in, &scene, &error);
    if (status == LK_OK)
        status = render_any_to_png(&mesh, with_scene ? &scene : NULL, points, width, height, &render_options, out,
                                   &stats, &scene_info, renderer_name, sizeof renderer_name, &error);

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
        if (with_scene) {
            cJSON_AddNumberToObject(root, "materials", (double)scene_info.materials);
            cJSON_AddNumberToObject(root, "textures_drawn", (double)scene_info.textures_drawn);
            cJSON_AddNumberToObject(root, "textures_failed", (double)scene_info.textures_failed);
        }
        print_json(root);
    } else if (!quiet) {
        if (points)
            printf("%s: %ux%u, %s (%s, %u pass%s) in %.1f ms [%s]\n", out, width, height,
                   count_noun(stats.primitives, "point", "points"),
                   render_options.flat_points ? "flat" : "Phong splats", render_options.passes,
                   render_options.passes == 1 ? "" : "es", stats.milliseconds, renderer_name);
        else
            printf("%s: %ux%u, %s (%s) in %.1f ms [%s]\n", out, width, height,
                   render_options.strips ? count_noun(stats.primitives, "strip triangle", "strip triangles")
                                         : n_triangles(stats.primitives),
                   count_noun(stats.indices, "index", "indices"), stats.milliseconds, renderer_name);
        if (with_scene)
            printf("materials: %s, %s drawn%s%s\n", thousands(scene_info.materials),
                   count_noun(scene_info.textures_drawn, "texture", "textures"),
                   scene_info.textures_failed ? "; not decoded (drawn without): " : "", scene_info.first_failure);
    }
    lk_scene_free(&scene);
    lk_mesh_free(&mesh);
    return exit_code;
}
