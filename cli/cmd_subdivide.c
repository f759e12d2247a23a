/* lodkit subdivide: a mesh refined by Loop or midpoint subdivision. */
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

int command_subdivide(int argc, char **argv)
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
        start = now_seconds();
        status = lk_subdivide(&mesh, scheme, (unsigned)iterations, &result, &error);
    }
    double seconds = now_seconds() - start;
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
