/* SPDX-License-Identifier: MIT */
/* lodkit terrain: fly a camera over an elevation grid with Röttger's
 * continuous LOD and measure, per frame, triangles, the CPU time of the LOD
 * update and mesh generation, geometric cracks and popping. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>

#include "cli.h"

const cli_help terrain_help = {
    "DEM",
    "Fly a camera along a fixed circle over an elevation grid drawn with Röttger's\n"
    "quadtree continuous LOD, geomorphing and crack elimination, and report per\n"
    "frame: triangles, the CPU time of the LOD update + mesh generation, cracks\n"
    "(rendered vertices off a neighbouring triangle's edge, counted geometrically,\n"
    "with the largest gap) and popping (the largest height change of the visible\n"
    "surface since the previous frame, in metres and in pixels). Prints\n"
    "min/median/max over the flight.\n"
    "Grids: {grid}\n",
    NULL,
};

typedef struct frame_record {
    size_t triangles, vertices, leaves, cracks, violations;
    double milliseconds, max_gap, popping_metres, popping_pixels;
    double eye[3];
} frame_record;

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

typedef struct summary {
    double min, median, max;
} summary;

/* min/median/max of one field over the frames (from `first`). */
static summary summarise(const frame_record *frames, size_t count, size_t first, size_t offset, int is_size)
{
    summary s = {0, 0, 0};
    if (count <= first) return s;
    size_t n = count - first;
    double *values = malloc(n * sizeof *values);
    if (!values) return s;
    for (size_t k = 0; k < n; k++) {
        const char *field = (const char *)&frames[first + k] + offset;
        values[k] = is_size ? (double)*(const size_t *)field : *(const double *)field;
    }
    qsort(values, n, sizeof *values, compare_double);
    s.min = values[0];
    s.max = values[n - 1];
    s.median = n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
    free(values);
    return s;
}

static cJSON *summary_json(summary s)
{
    cJSON *object = cJSON_CreateObject();
    cJSON_AddNumberToObject(object, "min", s.min);
    cJSON_AddNumberToObject(object, "median", s.median);
    cJSON_AddNumberToObject(object, "max", s.max);
    return object;
}

static lk_status write_csv(const char *path, const frame_record *frames, size_t count, lk_error *error)
{
    lk_output *file;
    lk_status status = lk_output_open(path, &file, error);
    if (status != LK_OK) return status;
    FILE *csv = lk_output_stream(file);
    fprintf(csv, "frame,triangles,vertices,leaves,update_ms,cracks,max_gap_m,popping_m,popping_px,"
                 "eye_x,eye_y,eye_z\n");
    for (size_t k = 0; k < count; k++) {
        const frame_record *f = &frames[k];
        fprintf(csv, "%zu,%zu,%zu,%zu,%.4f,%zu,%.6g,%.6g,%.6g,%.1f,%.1f,%.1f\n", k, f->triangles, f->vertices,
                f->leaves, f->milliseconds, f->cracks, f->max_gap, f->popping_metres, f->popping_pixels, f->eye[0],
                f->eye[1], f->eye[2]);
    }
    /* a write error (full disk) gives "PATH: write error: REASON" */
    return lk_output_commit(file, error);
}

/* The mesh in the renderer's frame (y up): x east, y the height
 * exaggerated so that the relief is 4% of the extent, z south. */
static lk_status render_view(const lk_terrain *terrain, const lk_mesh *mesh, const char *path, lk_error *error)
{
    lk_mesh copy;
    lk_status status = lk_mesh_copy(&copy, mesh, error);
    if (status != LK_OK) return status;
    status = lk_terrain_color_mesh(terrain, &copy, error);
    if (status == LK_OK) {
        float lo[3], hi[3];
        lk_mesh_bounds(&copy, lo, hi);
        double extent = fmax(hi[0] - lo[0], hi[1] - lo[1]);
        double relief = fmax(1.0, (double)hi[2] - lo[2]);
        double exaggeration = 0.04 * extent / relief;
        double cx = 0.5 * ((double)lo[0] + hi[0]), cy = 0.5 * ((double)lo[1] + hi[1]);
        for (size_t v = 0; v < copy.vertex_count; v++) {
            float *p = copy.positions + 3 * v;
            double x = p[0] - cx, y = p[1] - cy, z = p[2];
            p[0] = (float)x;
            p[1] = (float)(z * exaggeration);
            p[2] = (float)-y;
        }
        lk_render_options options;
        lk_render_options_default(&options);
        options.azimuth = 0;
        options.elevation = 55;
        options.wireframe = 1;
        status = render_to_png(&copy, 0, 1024, 768, &options, path, NULL, NULL, 0, error);
    }
    lk_mesh_free(&copy);
    return status;
}

static lk_status write_map(const lk_terrain *terrain, const lk_terrain_view *view, const lk_mesh *mesh,
                           const char *path, lk_error *error)
{
    unsigned width = 1024, height;
    lk_terrain_map_size(terrain, width, &height);
    unsigned char *rgba = malloc_array((size_t)width * height, 4);
    if (!rgba) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a %ux%u map", width, height);
    lk_status status = lk_terrain_draw_map(terrain, view, mesh, 0, width, rgba, NULL, error);
    if (status == LK_OK) status = lk_image_write_png(path, rgba, width, height, error);
    free(rgba);
    return status;
}

int cmd_terrain(int argc, char **argv)
{
    lk_terrain_options terrain_options;
    lk_terrain_options_default(&terrain_options);
    size_t frame_count = 500, size = 0, probes = 257;
    double speed = 0.5;
    const char *png_dir = NULL, *csv_path = NULL;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_TERRAIN, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_FLIGHT:
            if (!parse_size_option(arg, &frame_count) || frame_count < 1 || frame_count > 10000000)
                return usage_error("terrain", "--flight: '%s' is not a frame count from 1 to 10000000", arg);
            break;
        case OPT_CRACKS:
            if (strcmp(arg, "none") == 0)
                terrain_options.cracks = LK_TERRAIN_CRACKS_NONE;
            else if (strcmp(arg, "midpoint") == 0)
                terrain_options.cracks = LK_TERRAIN_CRACKS_MIDPOINT;
            else if (strcmp(arg, "paper") == 0)
                terrain_options.cracks = LK_TERRAIN_CRACKS_PAPER;
            else if (strcmp(arg, "full") == 0)
                terrain_options.cracks = LK_TERRAIN_CRACKS_FULL;
            else
                return usage_error("terrain", "--cracks: '%s' is not none, midpoint, paper or full", arg);
            break;
        case OPT_ERROR_SCALE:
            if (!parse_double_option(arg, &terrain_options.error_scale) || terrain_options.error_scale <= 0)
                return usage_error("terrain", "--error-scale: '%s' is not a positive number", arg);
            break;
        case OPT_RESOLUTION:
            if (!parse_double_option(arg, &terrain_options.resolution) || terrain_options.resolution <= 0)
                return usage_error("terrain", "--resolution: '%s' is not a positive number", arg);
            break;
        case OPT_NO_MORPH: terrain_options.morph = 0; break;
        case OPT_NO_FRUSTUM_CULLING: terrain_options.culling = 0; break;
        case OPT_SPEED:
            if (!parse_double_option(arg, &speed) || speed <= 0)
                return usage_error("terrain", "--speed: '%s' is not a positive number", arg);
            break;
        case OPT_GRID_SIZE: {
            size_t n = 0;
            int ok = parse_size_option(arg, &size) && size >= 5 && size <= 32769;
            while (ok && ((size_t)1 << n) + 1 < size) n++;
            if (!ok || ((size_t)1 << n) + 1 != size)
                return usage_error("terrain", "--grid-size: '%s' is not 2^n + 1 between 5 and 32769", arg);
            break;
        }
        case OPT_PROBES:
            if (!parse_size_option(arg, &probes) || probes < 2 || probes > 4097)
                return usage_error("terrain", "--probes: '%s' is not a count from 2 to 4097", arg);
            break;
        case OPT_PNG: png_dir = arg; break;
        case OPT_CSV: csv_path = arg; break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 1) return usage_error("terrain", "%s", "expected one DEM file");
    const char *in = argv[optind];

    lk_error error = {0};
    lk_heightfield raw, grid;
    memset(&raw, 0, sizeof raw);
    memset(&grid, 0, sizeof grid);
    lk_terrain *terrain = NULL;
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    frame_record *frames = NULL;
    float *before = NULL, *now = NULL;
    int exit_code = EXIT_OK, resampled = 0;
    size_t raw_width = 0, raw_height = 0;

    /* The memory budget bounds the grid read (and the terrain built on it). */
    lk_dem_options dem_options;
    lk_dem_options_default(&dem_options);
    dem_options.max_samples = cli_max_memory / LK_DEM_BYTES_PER_SAMPLE;
    if (dem_options.max_samples < 4) dem_options.max_samples = 4;
    if (cli_max_memory / 22 < terrain_options.max_samples) terrain_options.max_samples = cli_max_memory / 22;
    if (terrain_options.max_samples < 4) terrain_options.max_samples = 4;
    progress_state progress;
    progress_init(&progress, quiet || json, "terrain");
    dem_options.progress = progress_draw;
    dem_options.progress_user = &progress;
    lk_status status = lk_dem_read(in, &dem_options, &raw, &error);
    if (status == LK_OK) {
        raw_width = raw.width;
        raw_height = raw.height;
        size_t natural = 0;
        if (raw.width == raw.height) {
            size_t n = 0;
            while (((size_t)1 << n) + 1 < raw.width) n++;
            if (((size_t)1 << n) + 1 == raw.width) natural = raw.width;
        }
        if (size == 0 && natural) {
            grid = raw;
            memset(&raw, 0, sizeof raw);
        } else {
            progress_draw(&progress, 0, "resample");
            status = lk_heightfield_resample(&raw, size, &grid, &error);
            resampled = 1;
        }
    }
    if (status == LK_OK) progress_draw(&progress, 0, "quadtree");
    if (status == LK_OK) status = lk_terrain_create(&grid, &terrain_options, &terrain, &error);
    if (status == LK_OK) {
        frames = calloc_array(frame_count, sizeof *frames);
        before = malloc_array(probes * probes, sizeof *before);
        now = malloc_array(probes * probes, sizeof *now);
        if (!frames || !before || !now) status = lk_error_set(&error, LK_ERR_NOMEM, "out of memory");
    }
    if (status == LK_OK && png_dir && mkdir(png_dir, 0777) != 0 && errno != EEXIST)
        status = lk_error_set(&error, LK_ERR_IO, "%s: cannot create directory: %s", png_dir, strerror(errno));
    size_t crack_total = 0, frames_with_cracks = 0, violations = 0;
    double max_gap = 0;
    for (size_t frame = 0; status == LK_OK && frame < frame_count; frame++) {
        lk_terrain_view view;
        lk_terrain_flight(terrain, frame, speed, &view);
        lk_terrain_stats stats;
        status = lk_terrain_update(terrain, &view, &mesh, &stats, &error);
        lk_terrain_crack_stats cracks;
        if (status == LK_OK) status = lk_terrain_count_cracks(terrain, &mesh, 0, &cracks, &error);
        if (status == LK_OK) status = lk_terrain_sample_surface(terrain, &mesh, probes, now, &error);
        if (status != LK_OK) break;
        frame_record *record = &frames[frame];
        record->triangles = stats.triangles;
        record->vertices = stats.vertices;
        record->leaves = stats.leaves;
        record->violations = stats.restriction_violations;
        record->milliseconds = stats.milliseconds;
        record->cracks = cracks.cracks;
        record->max_gap = cracks.max_gap;
        memcpy(record->eye, view.eye, sizeof record->eye);
        if (frame > 0) {
            lk_terrain_popping popping;
            lk_terrain_measure_popping(terrain, &view, before, now, probes, &popping);
            record->popping_metres = popping.max_metres;
            record->popping_pixels = popping.max_pixels;
        }
        float *swap = before;
        before = now;
        now = swap;
        crack_total += cracks.cracks;
        frames_with_cracks += cracks.cracks > 0;
        violations += stats.restriction_violations;
        if (cracks.max_gap > max_gap) max_gap = cracks.max_gap;
        progress_draw(&progress, (double)(frame + 1) / (double)frame_count, "flight");
        /* pictures of 5 frames spread over the flight */
        if (png_dir && (frame_count < 5 || frame % ((frame_count + 3) / 4) == 0 || frame == frame_count - 1)) {
            char path[4096];
            snprintf(path, sizeof path, "%s/map_%04zu.png", png_dir, frame);
            status = write_map(terrain, &view, &mesh, path, &error);
            if (status != LK_OK) break;
            snprintf(path, sizeof path, "%s/view_%04zu.png", png_dir, frame);
            lk_error render_error = {0};
            if (mesh.triangle_count == 0) {
                progress_done(&progress);
                if (!quiet) fprintf(stderr, "%s: note: frame %zu drew no triangles (no 3-D view)\n", program, frame);
            } else if (render_view(terrain, &mesh, path, &render_error) != LK_OK && !quiet) {
                progress_done(&progress);
                fprintf(stderr, "%s: warning: no 3-D view of frame %zu: %s\n", program, frame, render_error.message);
            }
        }
    }
    if (status == LK_OK && csv_path) status = write_csv(csv_path, frames, frame_count, &error);
    progress_done(&progress);

    if (status != LK_OK) {
        print_error_for(in, NULL, &error);
        exit_code = EXIT_BAD_INPUT;
    } else {
        summary triangles = summarise(frames, frame_count, 0, offsetof(frame_record, triangles), 1);
        summary ms = summarise(frames, frame_count, 0, offsetof(frame_record, milliseconds), 0);
        summary cracks = summarise(frames, frame_count, 0, offsetof(frame_record, cracks), 1);
        summary gap = summarise(frames, frame_count, 0, offsetof(frame_record, max_gap), 0);
        summary pop = summarise(frames, frame_count, 1, offsetof(frame_record, popping_metres), 0);
        summary pop_px = summarise(frames, frame_count, 1, offsetof(frame_record, popping_pixels), 0);
        lk_terrain_info info;
        lk_terrain_get_info(terrain, &info);
        if (json) {
            cJSON *root = cJSON_CreateObject();
            cJSON_AddStringToObject(root, "input", in);
            cJSON_AddNumberToObject(root, "input_width", (double)raw_width);
            cJSON_AddNumberToObject(root, "input_height", (double)raw_height);
            cJSON_AddNumberToObject(root, "size", (double)info.size);
            cJSON_AddNumberToObject(root, "levels", info.levels);
            cJSON_AddNumberToObject(root, "spacing_x", info.spacing_x);
            cJSON_AddNumberToObject(root, "spacing_y", info.spacing_y);
            cJSON_AddNumberToObject(root, "frames", (double)frame_count);
            cJSON_AddNumberToObject(root, "speed", speed);
            cJSON_AddStringToObject(root, "crack_mode", lk_terrain_cracks_name(terrain_options.cracks));
            cJSON_AddBoolToObject(root, "morph", terrain_options.morph);
            cJSON_AddBoolToObject(root, "culling", terrain_options.culling);
            cJSON_AddNumberToObject(root, "resolution", terrain_options.resolution);
            cJSON_AddNumberToObject(root, "error_scale", terrain_options.error_scale);
            cJSON *crack_object = cJSON_AddObjectToObject(root, "cracks");
            cJSON_AddNumberToObject(crack_object, "max", cracks.max);
            cJSON_AddNumberToObject(crack_object, "total", (double)crack_total);
            cJSON_AddNumberToObject(crack_object, "frames", (double)frames_with_cracks);
            cJSON_AddNumberToObject(crack_object, "max_gap", max_gap);
            cJSON *pop_object = cJSON_AddObjectToObject(root, "popping");
            cJSON_AddNumberToObject(pop_object, "max", pop.max);
            cJSON_AddNumberToObject(pop_object, "median", pop.median);
            cJSON_AddNumberToObject(pop_object, "max_pixels", pop_px.max);
            cJSON_AddNumberToObject(pop_object, "median_pixels", pop_px.median);
            cJSON_AddItemToObject(root, "triangles", summary_json(triangles));
            cJSON_AddItemToObject(root, "update_ms", summary_json(ms));
            cJSON_AddNumberToObject(root, "restriction_violations", (double)violations);
            print_json(root);
        } else if (!quiet) {
            printf("%s: %zux%zu samples", in, info.size, info.size);
            if (resampled) printf(" (resampled from %zux%zu)", raw_width, raw_height);
            printf(", spacing %.1f x %.1f m, heights %.0f..%.0f m, %u levels\n", info.spacing_x, info.spacing_y,
                   info.min_height, info.max_height, info.levels);
            printf("flight: %s at %g spacings/frame; cracks %s, morph %s, culling %s, C %g, c %g\n",
                   count_noun(frame_count, "frame", "frames"), speed, lk_terrain_cracks_name(terrain_options.cracks),
                   terrain_options.morph ? "on" : "off", terrain_options.culling ? "on" : "off",
                   terrain_options.resolution, terrain_options.error_scale);
            printf("%-14s %12s %12s %12s\n", "", "min", "median", "max");
            printf("%-14s %12.0f %12.0f %12.0f\n", "triangles", triangles.min, triangles.median, triangles.max);
            printf("%-14s %12.3f %12.3f %12.3f\n", "update ms", ms.min, ms.median, ms.max);
            printf("%-14s %12.0f %12.0f %12.0f   total %zu in %s\n", "cracks", cracks.min, cracks.median, cracks.max,
                   crack_total, count_noun(frames_with_cracks, "frame", "frames"));
            printf("%-14s %12.3g %12.3g %12.3g\n", "max gap m", gap.min, gap.median, gap.max);
            printf("%-14s %12.3g %12.3g %12.3g\n", "popping m", pop.min, pop.median, pop.max);
            printf("%-14s %12.3g %12.3g %12.3g\n", "popping px", pop_px.min, pop_px.median, pop_px.max);
            if (violations) printf("restriction violations: %zu\n", violations);
            if (csv_path) printf("per-frame numbers: %s\n", csv_path);
            if (png_dir) printf("pictures: %s/map_*.png, %s/view_*.png\n", png_dir, png_dir);
        }
    }
    free(frames);
    free(before);
    free(now);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
    lk_heightfield_free(&grid);
    lk_heightfield_free(&raw);
    return exit_code;
}
