/* SPDX-License-Identifier: MIT */
/* lodkit subdivide: a mesh refined by Loop or midpoint subdivision. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help subdivide_help = {
    "IN OUT",
    "Subdivide a triangle mesh; each iteration multiplies the triangle count by 4.\n",
    NULL,
};

int cmd_subdivide(int argc, char **argv)
{
    lk_subdivide_scheme scheme = LK_SUBDIVIDE_LOOP;
    size_t iterations = 1;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_SUBDIVIDE, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_SCHEME:
            if (!strcmp(arg, "loop"))
                scheme = LK_SUBDIVIDE_LOOP;
            else if (!strcmp(arg, "midpoint"))
                scheme = LK_SUBDIVIDE_MIDPOINT;
            else
                return usage_error("subdivide", "--scheme: '%s' is not loop or midpoint", arg);
            break;
        case OPT_ITERATIONS:
            if (!parse_size_option(arg, &iterations) || iterations > 16)
                return usage_error("subdivide", "--iterations: '%s' is not a count from 0 to 16", arg);
            break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("subdivide", "%s", "expected IN and OUT");
    const char *in = argv[optind], *out = argv[optind + 1];
    lk_format out_format = output_mesh_format("subdivide", out, 0);
    if (out_format == LK_FORMAT_UNKNOWN) return EXIT_USAGE;
    lk_mesh mesh, result;
    lk_error error = {0};
    lk_mesh_init(&result);
    double start = 0;
    lk_status status = load_mesh(in, &mesh, NULL, NULL, &error);
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
        printf("%s: %s -> %s: %s, %s (%s x%zu, %.1f ms)\n", in, n_triangles(mesh.triangle_count), out,
               n_vertices(result.vertex_count), n_triangles(result.triangle_count),
               scheme == LK_SUBDIVIDE_LOOP ? "loop" : "midpoint", iterations, seconds * 1000);
    lk_mesh_free(&mesh);
    lk_mesh_free(&result);
    return EXIT_OK;
}
