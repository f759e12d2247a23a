/* lodkit convert: a mesh from one format into another, welded, cleaned or moved on the way. */
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

int command_convert(int argc, char **argv)
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
