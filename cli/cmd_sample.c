/* SPDX-License-Identifier: MIT */
/* lodkit sample: a mesh into an oriented point set with splat radii, or
 * radii (and normals) for a point set. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help sample_help = {
    "IN OUT.ply",
    "Turn a mesh into an oriented point set for splatting: points on the surface\n"
    "(uniform and area-proportional, or Poisson-disk), each with the normal of the\n"
    "surface (interpolated vertex normals when the mesh has them) and a splat\n"
    "radius from the local spacing (scale x distance to the k-th nearest other\n"
    "point, at most 1.25x the reach of the point's cell among those k in its\n"
    "tangent plane when it has a normal, 4x the median radius of those k points\n"
    "and 4x the 99th percentile of all radii, so stray points stay small). A\n"
    "point-set input (no faces: .xyz, or .ply without faces) is not resampled:\n"
    "its points get radii, and normals with --estimate-normals (estimated first).\n"
    "OUT is a PLY file with properties x y z nx ny nz radius.\n",
    NULL,
};

typedef struct radius_summary {
    double min, median, max;
} radius_summary;

static int compare_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static int summarise_radii(const lk_mesh *points, radius_summary *summary)
{
    memset(summary, 0, sizeof *summary);
    if (points->vertex_count == 0) return 1;
    float *sorted = malloc_array(points->vertex_count, sizeof(float));
    if (!sorted) return 0;
    memcpy(sorted, points->radii, points->vertex_count * sizeof(float));
    qsort(sorted, points->vertex_count, sizeof(float), compare_float);
    summary->min = sorted[0];
    summary->median = sorted[points->vertex_count / 2];
    summary->max = sorted[points->vertex_count - 1];
    free(sorted);
    return 1;
}

int cmd_sample(int argc, char **argv)
{
    lk_sample_options sample_options;
    lk_sample_options_default(&sample_options);
    lk_write_options write_options = {0};
    int estimate = 0, sampling_options_given = 0;
    size_t value;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_SAMPLE, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_POINTS:
            if (!parse_size_option(arg, &sample_options.point_count) || sample_options.point_count == 0 ||
                sample_options.point_count > LK_MAX_ELEMENTS)
                return usage_error("sample", "--points: '%s' is not a positive integer (at most 4294967280)", arg);
            sampling_options_given = 1;
            break;
        case OPT_POISSON:
            sample_options.poisson = 1;
            sampling_options_given = 1;
            break;
        case OPT_SEED:
            if (!parse_size_option(arg, &value))
                return usage_error("sample", "--seed: '%s' is not a non-negative integer", arg);
            sample_options.seed = (uint64_t)value;
            sampling_options_given = 1;
            break;
        case OPT_NEIGHBOURS:
            if (!parse_size_option(arg, &value) || value < 1 || value > 256)
                return usage_error("sample", "--neighbours: '%s' is not an integer from 1 to 256", arg);
            sample_options.neighbours = (unsigned)value;
            break;
        case OPT_RADIUS_SCALE:
            if (!parse_double_option(arg, &sample_options.radius_scale) || !(sample_options.radius_scale > 0))
                return usage_error("sample", "--radius-scale: '%s' is not a number > 0", arg);
            break;
        case OPT_ESTIMATE_NORMALS: estimate = 1; break;
        case OPT_ASCII: write_options.ply_encoding = LK_PLY_ASCII; break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("sample", "%s", "expected IN and OUT.ply");
    const char *in = argv[optind], *out = argv[optind + 1];
    if (lk_format_from_path(out) != LK_FORMAT_PLY)
        return usage_error("sample",
                           "cannot write '%s': the output must be a .ply file (the format with a radius "
                           "property)",
                           out);

    lk_mesh input, points;
    lk_mesh_init(&points);
    lk_error error = {0};
    double load_seconds = 0;
    if (load_mesh(in, &input, &load_seconds, NULL, &error) != LK_OK) {
        print_error_for(in, out, &error);
        return EXIT_BAD_INPUT;
    }
    int is_point_set = input.triangle_count == 0;
    size_t input_vertices = input.vertex_count, input_triangles = input.triangle_count;
    int had_normals = input.normals != NULL;
    if (is_point_set && !had_normals && !estimate) {
        fprintf(stderr,
                "%s: %s: a point set without normals (%s points); splats need normals: add --estimate-normals\n",
                program, in, thousands(input.vertex_count));
        lk_mesh_free(&input);
        return EXIT_BAD_INPUT;
    }
    if (is_point_set && input.vertex_count == 0) {
        fprintf(stderr, "%s: %s: the point set is empty\n", program, in);
        lk_mesh_free(&input);
        return EXIT_BAD_INPUT;
    }
    if (!quiet && !json) {
        if (is_point_set && sampling_options_given)
            fprintf(stderr, "%s sample: note: %s is a point set; --points, --poisson and --seed are ignored\n", program,
                    in);
        if (!is_point_set && estimate)
            fprintf(stderr,
                    "%s sample: note: %s is a mesh; its samples take the surface's normals, "
                    "--estimate-normals is ignored\n",
                    program, in);
    }

    progress_state progress;
    progress_init(&progress, quiet || json, "sample");
    double start = now_seconds(), normals_seconds = 0, radii_seconds = 0;
    lk_status status = LK_OK;
    if (!is_point_set) {
        status = lk_mesh_sample_points(&input, &sample_options, &points, progress_draw, &progress, &error);
    } else {
        /* Keep positions and normals only: the output is an oriented point
         * set with radii; other attributes are not carried. */
        points = input;
        lk_mesh_init(&input);
        free(points.texcoords), points.texcoords = NULL;
        free(points.colors), points.colors = NULL;
        if (estimate) {
            double t = now_seconds();
            progress_draw(&progress, 0, "normals"); /* these two report no progress: say what runs */
            status = lk_points_estimate_normals(&points, sample_options.neighbours, &error);
            normals_seconds = now_seconds() - t;
        }
        if (status == LK_OK) {
            double t = now_seconds();
            progress_draw(&progress, 0.5, "radii");
            status = lk_points_estimate_radii(&points, sample_options.neighbours, sample_options.radius_scale, &error);
            radii_seconds = now_seconds() - t;
        }
    }
    double seconds = now_seconds() - start;
    progress_done(&progress);
    if (status == LK_OK) status = lk_mesh_write(out, LK_FORMAT_PLY, &points, &write_options, &error);
    radius_summary radii;
    if (status == LK_OK && !summarise_radii(&points, &radii))
        status = lk_error_set(&error, LK_ERR_NOMEM, "out of memory");
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        lk_mesh_free(&input);
        lk_mesh_free(&points);
        return EXIT_BAD_INPUT;
    }
    double area = is_point_set ? 0 : lk_mesh_area(&input);
    double spacing = is_point_set ? 0 : sqrt(area / (double)points.vertex_count);
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddStringToObject(root, "mode",
                                !is_point_set ? (sample_options.poisson ? "poisson" : "uniform")
                                : estimate    ? "point set, normals estimated"
                                              : "point set");
        cJSON_AddNumberToObject(root, "input_vertices", (double)input_vertices);
        cJSON_AddNumberToObject(root, "input_triangles", (double)input_triangles);
        cJSON_AddNumberToObject(root, "points", (double)points.vertex_count);
        if (!is_point_set) {
            cJSON_AddNumberToObject(root, "seed", (double)sample_options.seed);
            cJSON_AddNumberToObject(root, "area", area);
            cJSON_AddNumberToObject(root, "spacing", spacing);
        }
        cJSON_AddNumberToObject(root, "neighbours", sample_options.neighbours);
        cJSON_AddNumberToObject(root, "radius_scale", sample_options.radius_scale);
        cJSON *radius = cJSON_AddObjectToObject(root, "radius");
        cJSON_AddNumberToObject(radius, "min", radii.min);
        cJSON_AddNumberToObject(radius, "median", radii.median);
        cJSON_AddNumberToObject(radius, "max", radii.max);
        cJSON *times = cJSON_AddObjectToObject(root, "seconds");
        cJSON_AddNumberToObject(times, "load", load_seconds);
        cJSON_AddNumberToObject(times, "total", seconds);
        if (is_point_set) {
            cJSON_AddNumberToObject(times, "normals", normals_seconds);
            cJSON_AddNumberToObject(times, "radii", radii_seconds);
        }
        print_json(root);
    } else if (!quiet) {
        if (!is_point_set)
            printf("%s: %s -> %s %s %s in %.2f s\n", in, n_triangles(input_triangles), thousands(points.vertex_count),
                   sample_options.poisson ? "Poisson-disk" : "uniform", points.vertex_count == 1 ? "point" : "points",
                   seconds);
        else
            printf("%s: %s%s, radii in %.2f s\n", in, count_noun(points.vertex_count, "point", "points"),
                   estimate ? had_normals ? ", normals re-estimated" : ", normals estimated" : "", seconds);
        printf("radius (k=%u, scale %g): median %.4g", sample_options.neighbours, sample_options.radius_scale,
               radii.median);
        if (spacing > 0) printf(" = %.2f x sqrt(area / points)", radii.median / spacing);
        printf(", min %.4g, max %.4g\n", radii.min, radii.max);
        printf("wrote %s\n", out);
    }
    lk_mesh_free(&input);
    lk_mesh_free(&points);
    return EXIT_OK;
}
