/* lodkit — the command-line tool: main and the command table. A thin layer
 * over liblodkit: parse options, call the library, print results; each
 * command is in its own cmd_NAME.c. */
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
