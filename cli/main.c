/* SPDX-License-Identifier: MIT */
/* lodkit — the command-line tool: main and the command table. A thin layer
 * over liblodkit: parse options, call the library, print results; each
 * command is in its own cmd_NAME.c, every option is declared once in
 * cli_options.c. */
#include <stdio.h>
#include <string.h>

#include "cli.h"

const cli_command cli_commands[CMD_COUNT] = {
    [CMD_INFO] = {"info",
                  "sizes, bounds and topology of meshes and point sets; size, extent and heights of "
                  "elevation grids",
                  cmd_info, &info_help},
    [CMD_CONVERT] = {"convert", "convert between mesh formats (weld, clean, move on the way)", cmd_convert,
                     &convert_help},
    [CMD_METRO] = {"metro", "surface distance between two meshes (Hausdorff, mean, RMS)", cmd_metro, &metro_help},
    [CMD_SIMPLIFY] = {"simplify", "reduce a mesh: quadric error metric, vertex clustering or contour wavelets",
                      cmd_simplify, &simplify_help},
    [CMD_LOD] = {"lod", "levels of detail of a mesh in one glTF (MSFT_lod) or one file per level", cmd_lod, &lod_help},
    [CMD_SUBDIVIDE] = {"subdivide", "refine a mesh: Loop or midpoint subdivision", cmd_subdivide, &subdivide_help},
    [CMD_PROGRESSIVE] = {"progressive", "build a progressive mesh on triangle strips as a .lks stream", cmd_progressive,
                         &progressive_help},
    [CMD_UNPACK] = {"unpack", "decode a .lks stream up to a level into a mesh", cmd_unpack, &unpack_help},
    [CMD_INSPECT] = {"inspect", "header and chunk table of a .lks stream", cmd_inspect, &inspect_help},
    [CMD_RENDER] = {"render", "draw a mesh (or point set) offscreen into a PNG (OpenGL ES 2.0)", cmd_render,
                    &render_help},
    [CMD_SAMPLE] = {"sample", "turn a mesh into an oriented point set with splat radii", cmd_sample, &sample_help},
    [CMD_SPLAT] = {"splat", "draw a point set as Phong splats into a PNG (1- or 2-pass)", cmd_splat, &splat_help},
    [CMD_OCTREE] = {"octree", "build a level-of-detail point octree (out of core) for streaming by Range", cmd_octree,
                    &octree_help},
    [CMD_TERRAIN] = {"terrain", "fly over an elevation grid with continuous LOD: cracks, popping, timing", cmd_terrain,
                     &terrain_help},
    [CMD_SLICES] = {"slices", "draw a mesh's planar-sampling contours before and after wavelet simplification",
                    cmd_slices, &slices_help},
    [CMD_ANIMATE] = {"animate", "simplify a key-frame or skinned animation into LOD levels, measured per frame",
                     cmd_animate, &animate_help},
    [CMD_SERVE] = {"serve", "HTTP server: the WebGL viewer and progressive streams, point sets, terrains", cmd_serve,
                   &serve_help},
    [CMD_FORMATS] = {"formats", "the file formats lodkit reads and writes, by extension", cmd_formats, &formats_help},
    [CMD_MAIN] = {"lodkit", "", NULL, &main_help},
};

const cli_help main_help = {
    "COMMAND [options] [args]",
    "lodkit: multiresolution 3D geometry for networked graphics.\n",
    "Exit status: 0 success, 1 bad input (unreadable or invalid files), 2 usage error.\n",
};

int main(int argc, char **argv)
{
    /* --max-memory may come before or after the command name. */
    int global = cli_take_global_options(&argc, argv);
    if (global >= 0) return global;
    if (argc < 2) {
        cli_print_help(stderr, CMD_MAIN);
        return EXIT_USAGE;
    }
    const char *command = argv[1];
    if (!strcmp(command, "-h") || !strcmp(command, "--help") || !strcmp(command, "help")) {
        cli_print_help(stdout, CMD_MAIN);
        return EXIT_OK;
    }
    if (!strcmp(command, "-V") || !strcmp(command, "--version")) {
        printf("lodkit %s\n", lk_version());
        return EXIT_OK;
    }
    for (int c = 0; c < CMD_MAIN; c++)
        if (strcmp(command, cli_commands[c].name) == 0) return cli_commands[c].run(argc - 1, argv + 1);
    fprintf(stderr, "%s: unknown command '%s'\nTry '%s --help' for the list of commands.\n", program, command, program);
    return EXIT_USAGE;
}
