/* SPDX-License-Identifier: MIT */
/* lodkit octree: point clouds of any size into a level-of-detail octree
 * (one data file + a JSON index) with bounded memory (lk_octree_build). */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "cli.h"

const cli_help octree_help = {
    "IN... OUTDIR",
    "Build a Potree-like level-of-detail octree of point clouds (LAS, PLY, XYZ,\n"
    "PCD): each node a subsample at its level's spacing (spacing / 2^level), every\n"
    "point in exactly one node. Writes OUTDIR/octree.bin (the nodes' points) and\n"
    "OUTDIR/octree.json (the index: bounds, encodings, per node its byte range),\n"
    "so a static HTTP server can serve each node by Range. Memory stays bounded:\n"
    "the points are spilled to temporary files by chunk and each chunk is built\n"
    "on its own (LAS and binary PLY are streamed; ASCII PLY, XYZ and PCD are read\n"
    "whole, one file at a time).\n",
    "Format: docs/formats.md, \"Point octree\".\n",
};

static long peak_rss_kib(void)
{
    struct rusage usage;
    return getrusage(RUSAGE_SELF, &usage) == 0 ? usage.ru_maxrss : 0;
}

static int positive_count(const char *arg, size_t *out)
{
    return parse_size_option(arg, out) && *out >= 1 && *out <= LK_MAX_ELEMENTS;
}

int cmd_octree(int argc, char **argv)
{
    lk_octree_options options;
    lk_octree_options_default(&options);
    options.max_read_bytes = cli_max_memory; /* inputs read whole (streamed ones need little) */
    size_t value;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_OCTREE, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case CLI_EXIT: return parser.exit_code;
        case OPT_SPACING:
            if (!parse_double_option(arg, &options.spacing) || !(options.spacing > 0))
                return usage_error("octree", "--spacing: '%s' is not a positive number", arg);
            break;
        case OPT_NODE_POINTS:
            if (!positive_count(arg, &options.max_node_points))
                return usage_error("octree", "--node-points: '%s' is not a positive count", arg);
            break;
        case OPT_CHUNK_POINTS:
            if (!positive_count(arg, &options.chunk_points))
                return usage_error("octree", "--chunk-points: '%s' is not a positive count", arg);
            break;
        case OPT_THREADS:
            if (!parse_size_option(arg, &value) || value < 1 || value > 64)
                return usage_error("octree", "--threads: '%s' is not a count from 1 to 64", arg);
            options.threads = (unsigned)value;
            break;
        case OPT_NEIGHBOURS:
            if (!parse_size_option(arg, &value) || value < 1 || value > 256)
                return usage_error("octree", "--neighbours: '%s' is not a count from 1 to 256", arg);
            options.neighbours = (unsigned)value;
            break;
        case OPT_TEMP_DIR: options.temp_dir = arg; break;
        case OPT_ESTIMATE_NORMALS: options.normals = LK_OCTREE_NORMALS_ESTIMATE; break;
        case OPT_NO_NORMALS: options.normals = LK_OCTREE_NORMALS_NONE; break;
        case OPT_NO_RADII: options.no_radii = 1; break;
        case OPT_NO_CLIP: options.no_clips = 1; break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind < 2) return usage_error("octree", "%s", "expected one or more inputs and an output folder");
    const char *out_dir = argv[argc - 1];
    const char *const *inputs = (const char *const *)argv + optind;
    size_t input_count = (size_t)(argc - optind - 1);

    progress_state progress;
    progress_init(&progress, quiet || json, "octree");
    lk_octree_stats stats;
    lk_error error = {0};
    lk_status status =
        lk_octree_build(inputs, input_count, out_dir, &options, &stats, progress_draw, &progress, &error);
    progress_done(&progress);
    if (status != LK_OK) {
        print_error_for(input_count == 1 ? inputs[0] : out_dir, out_dir, &error);
        return EXIT_BAD_INPUT;
    }
    double rate = stats.seconds > 0 ? (double)stats.points / stats.seconds : 0;
    long rss = peak_rss_kib();
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "output", out_dir);
        cJSON_AddNumberToObject(root, "points", (double)stats.points);
        cJSON_AddNumberToObject(root, "nodes", (double)stats.nodes);
        cJSON_AddNumberToObject(root, "levels", stats.levels);
        cJSON_AddNumberToObject(root, "chunks", (double)stats.chunks);
        cJSON_AddNumberToObject(root, "temp_bytes", (double)stats.temp_bytes);
        cJSON_AddNumberToObject(root, "seconds", stats.seconds);
        cJSON_AddNumberToObject(root, "points_per_second", rate);
        cJSON_AddNumberToObject(root, "peak_rss_bytes", (double)rss * 1024.0);
        print_json(root);
    } else if (!quiet) {
        printf("%s: %s in %s, %u levels, %s; %.2f s (%s points/s), peak RSS %ld MiB\n", out_dir,
               count_noun(stats.points, "point", "points"), count_noun(stats.nodes, "node", "nodes"), stats.levels,
               count_noun(stats.chunks, "chunk", "chunks"), stats.seconds, thousands((unsigned long long)rate),
               rss / 1024);
    }
    return EXIT_OK;
}
