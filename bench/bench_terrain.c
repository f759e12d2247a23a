/* SPDX-License-Identifier: MIT */
/* Terrain continuous LOD (issue 8): 500-frame flights over etopo20
 * (resampled to 1025^2 and to 2049^2, the real DEM made larger) and over a
 * 1025^2 procedural fractal (rougher, deeper hierarchy), for every crack
 * mode with geomorphing and for the full rules without it.
 *
 *   bench_terrain [--frames N] [--out DIR] [SAMPLES_DIR]
 *
 * Per run: triangles per frame, CPU time of the LOD update + mesh
 * generation, cracks (lk_terrain_count_cracks: rendered vertices off a
 * rendered edge through their grid point, > 1 mm), the largest gap, and
 * popping (largest height change of the visible surface between two frames,
 * 257^2 probes, metres and pixels at 768 px). The update time is measured
 * twice: inside the measuring loop (caches cold after crack counting) and
 * in a second pass that only updates (what a viewer pays per frame); the
 * medians of both are printed. Prints a markdown table; writes
 * DIR/terrain_<grid>_<mode>[_nomorph].csv (per frame, like the paper's
 * Fig. 10) and, at the middle frame, DIR/terrain_<grid>_<mode>_map.png
 * (top-down relief, quadtree, eye, cracks ringed in red: the paper's
 * Figs. 8/9 before and after crack elimination) and
 * DIR/terrain_<grid>_<mode>_view.png (3-D, colour ramp + hillshade, triangle
 * edges) for the modes none and full. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bench_common.h"
#include "lodkit.h"

typedef struct settings {
    size_t frames;
    const char *samples_dir;
    const char *out_dir;
} settings;

typedef struct run_result {
    double triangles_min, triangles_median, triangles_max;
    double ms_median_measured, ms_median_updates_only, ms_max_updates_only;
    size_t crack_max, crack_total, crack_frames;
    double max_gap;
    double popping_metres, popping_pixels;
    size_t violations;
} run_result;

/* The library's synthetic terrain: 1025^2 at 30 m spacing. */
static int make_fractal(lk_heightfield *field, size_t size)
{
    return lk_heightfield_fractal(size, 30.0, field, NULL) == LK_OK;
}

/* The mesh turned into the renderer's frame (y up, relief 4% of the extent). */
static lk_status render_view(const lk_terrain *terrain, const lk_mesh *mesh, const char *path, lk_error *error)
{
    lk_mesh copy;
    lk_status status = lk_mesh_copy(&copy, mesh, error);
    if (status != LK_OK) return status;
    status = lk_terrain_color_mesh(terrain, &copy, error);
    lk_renderer *renderer = NULL;
    unsigned char *pixels = NULL;
    const unsigned width = 1024, height = 768;
    if (status == LK_OK) {
        float lo[3], hi[3];
        lk_mesh_bounds(&copy, lo, hi);
        double extent = fmax(hi[0] - lo[0], hi[1] - lo[1]);
        double exaggeration = 0.04 * extent / fmax(1.0, (double)hi[2] - lo[2]);
        double cx = 0.5 * ((double)lo[0] + hi[0]), cy = 0.5 * ((double)lo[1] + hi[1]);
        for (size_t v = 0; v < copy.vertex_count; v++) {
            float *p = copy.positions + 3 * v;
            double x = p[0] - cx, y = p[1] - cy, z = p[2];
            p[0] = (float)x;
            p[1] = (float)(z * exaggeration);
            p[2] = (float)-y;
        }
        status = lk_renderer_create(width, height, &renderer, error);
    }
    if (status == LK_OK) {
        lk_render_options options;
        lk_render_options_default(&options);
        options.azimuth = 0;
        options.elevation = 55;
        options.wireframe = 1;
        status = lk_render_mesh(renderer, &copy, &options, NULL, error);
    }
    if (status == LK_OK) {
        pixels = malloc((size_t)width * height * 4);
        if (!pixels) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    if (status == LK_OK) status = lk_renderer_read_pixels(renderer, pixels, error);
    if (status == LK_OK) status = lk_image_write_png(path, pixels, width, height, error);
    free(pixels);
    lk_renderer_free(renderer);
    lk_mesh_free(&copy);
    return status;
}

static lk_status write_map(const lk_terrain *terrain, const lk_terrain_view *view, const lk_mesh *mesh,
                           const char *path, lk_error *error)
{
    unsigned width = 1024, height;
    lk_terrain_map_size(terrain, width, &height);
    unsigned char *rgba = malloc((size_t)width * height * 4);
    if (!rgba) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    lk_status status = lk_terrain_draw_map(terrain, view, mesh, 0, width, rgba, NULL, error);
    if (status == LK_OK) status = lk_image_write_png(path, rgba, width, height, error);
    free(rgba);
    return status;
}

static int run(const settings *s, const lk_heightfield *field, const char *grid_name, lk_terrain_cracks cracks,
               int morph, int pictures, run_result *result)
{
    memset(result, 0, sizeof *result);
    lk_terrain_options options;
    lk_terrain_options_default(&options);
    options.cracks = cracks;
    options.morph = morph;
    lk_error error = {0};
    lk_terrain *terrain = NULL;
    if (lk_terrain_create(field, &options, &terrain, &error) != LK_OK) {
        fprintf(stderr, "bench_terrain: %s: %s\n", grid_name, error.message);
        return 0;
    }
    enum { PROBES = 257 };
    size_t frames = s->frames;
    double *triangles = calloc(frames, sizeof *triangles), *ms = calloc(frames, sizeof *ms);
    double *ms_only = calloc(frames, sizeof *ms_only);
    float *before = malloc(PROBES * PROBES * sizeof *before), *now = malloc(PROBES * PROBES * sizeof *now);
    char path[4096];
    snprintf(path, sizeof path, "%s/terrain_%s_%s%s.csv", s->out_dir, grid_name, lk_terrain_cracks_name(cracks),
             morph ? "" : "_nomorph");
    FILE *csv = fopen(path, "w");
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    int ok = triangles && ms && ms_only && before && now && csv;
    if (!ok) fprintf(stderr, "bench_terrain: out of memory or cannot write %s\n", path);
    if (csv) fprintf(csv, "frame,triangles,update_ms,cracks,max_gap_m,popping_m,popping_px\n");
    for (size_t frame = 0; ok && frame < frames; frame++) {
        lk_terrain_view view;
        lk_terrain_flight(terrain, frame, 0, &view);
        lk_terrain_stats stats;
        lk_terrain_crack_stats crack_stats;
        ok = lk_terrain_update(terrain, &view, &mesh, &stats, &error) == LK_OK &&
             lk_terrain_count_cracks(terrain, &mesh, 0, &crack_stats, &error) == LK_OK &&
             lk_terrain_sample_surface(terrain, &mesh, PROBES, now, &error) == LK_OK;
        if (!ok) {
            fprintf(stderr, "bench_terrain: %s: %s\n", grid_name, error.message);
            break;
        }
        lk_terrain_popping popping = {0};
        if (frame > 0) lk_terrain_measure_popping(terrain, &view, before, now, PROBES, &popping);
        float *swap = before;
        before = now;
        now = swap;
        triangles[frame] = (double)stats.triangles;
        ms[frame] = stats.milliseconds;
        result->crack_total += crack_stats.cracks;
        result->crack_frames += crack_stats.cracks > 0;
        if (crack_stats.cracks > result->crack_max) result->crack_max = crack_stats.cracks;
        result->max_gap = fmax(result->max_gap, crack_stats.max_gap);
        result->popping_metres = fmax(result->popping_metres, popping.max_metres);
        result->popping_pixels = fmax(result->popping_pixels, popping.max_pixels);
        result->violations += stats.restriction_violations;
        fprintf(csv, "%zu,%zu,%.4f,%zu,%.6g,%.6g,%.6g\n", frame, stats.triangles, stats.milliseconds,
                crack_stats.cracks, crack_stats.max_gap, popping.max_metres, popping.max_pixels);
        if (pictures && frame == frames / 2) {
            snprintf(path, sizeof path, "%s/terrain_%s_%s_map.png", s->out_dir, grid_name,
                     lk_terrain_cracks_name(cracks));
            if (write_map(terrain, &view, &mesh, path, &error) != LK_OK)
                fprintf(stderr, "bench_terrain: %s\n", error.message);
            snprintf(path, sizeof path, "%s/terrain_%s_%s_view.png", s->out_dir, grid_name,
                     lk_terrain_cracks_name(cracks));
            if (render_view(terrain, &mesh, path, &error) != LK_OK)
                fprintf(stderr, "bench_terrain: no 3-D view: %s\n", error.message);
        }
    }
    /* updates only: the same flight, nothing else touching the caches */
    for (size_t frame = 0; ok && frame < frames; frame++) {
        lk_terrain_view view;
        lk_terrain_flight(terrain, frame, 0, &view);
        lk_terrain_stats stats;
        ok = lk_terrain_update(terrain, &view, &mesh, &stats, &error) == LK_OK;
        ms_only[frame] = stats.milliseconds;
    }
    if (ok) {
        qsort(triangles, frames, sizeof *triangles, compare_doubles);
        result->triangles_min = triangles[0];
        result->triangles_max = triangles[frames - 1];
        result->triangles_median = median(triangles, frames);
        result->ms_median_measured = median(ms, frames);
        result->ms_median_updates_only = median(ms_only, frames);
        result->ms_max_updates_only = ms_only[frames - 1];
    }
    if (csv) fclose(csv);
    free(triangles);
    free(ms);
    free(ms_only);
    free(before);
    free(now);
    lk_mesh_free(&mesh);
    lk_terrain_free(terrain);
    return ok;
}

int main(int argc, char **argv)
{
    settings s = {500, NULL, "/tmp"};
    for (int k = 1; k < argc; k++) {
        if (strcmp(argv[k], "--frames") == 0 && k + 1 < argc) {
            s.frames = strtoul(argv[++k], NULL, 10);
        } else if (strcmp(argv[k], "--out") == 0 && k + 1 < argc) {
            s.out_dir = argv[++k];
        } else if (argv[k][0] != '-') {
            s.samples_dir = argv[k];
        } else {
            fprintf(stderr, "usage: bench_terrain [--frames N] [--out DIR] [SAMPLES_DIR]\n");
            return 2;
        }
    }
    if (s.frames < 2) s.frames = 2;
    mkdir(s.out_dir, 0777);
    char etopo_path[4096];
    snprintf(etopo_path, sizeof etopo_path, "%s/etopo20.cdf", s.samples_dir ? s.samples_dir : "data/samples");
    lk_error error = {0};
    lk_heightfield raw, grids[3];
    memset(grids, 0, sizeof grids);
    const char *names[3] = {"etopo20-1025", "etopo20-2049", "fractal-1025"};
    if (lk_dem_read(etopo_path, NULL, &raw, &error) != LK_OK) {
        fprintf(stderr, "bench_terrain: %s\n", error.message);
        return 1;
    }
    if (lk_heightfield_resample(&raw, 1025, &grids[0], &error) != LK_OK ||
        lk_heightfield_resample(&raw, 2049, &grids[1], &error) != LK_OK) {
        fprintf(stderr, "bench_terrain: %s\n", error.message);
        lk_heightfield_free(&raw);
        return 1;
    }
    lk_heightfield_free(&raw);
    if (!make_fractal(&grids[2], 1025)) {
        fprintf(stderr, "bench_terrain: out of memory\n");
        return 1;
    }
    printf("%zu-frame flights (lk_terrain_flight: a circle of radius 0.3 x extent, 0.5 spacings per frame, 10\n"
           "spacings above the highest sample, 30 degrees down, 60 degree fov), C 8, c 50, culling on.\n"
           "update ms: median CPU time of the LOD update + mesh generation, in the measuring loop /\n"
           "in a pass of updates only. cracks: max per frame / total / frames with cracks.\n\n",
           s.frames);
    printf("| grid | cracks rule | morph | triangles min / median / max | update ms | cracks | max gap m | popping m | "
           "popping px | level jumps |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|\n");
    int failures = 0;
    for (int g = 0; g < 3; g++) {
        for (int mode = LK_TERRAIN_CRACKS_NONE; mode <= LK_TERRAIN_CRACKS_FULL + 1; mode++) {
            lk_terrain_cracks cracks = mode > LK_TERRAIN_CRACKS_FULL ? LK_TERRAIN_CRACKS_FULL : (lk_terrain_cracks)mode;
            int morph = mode <= LK_TERRAIN_CRACKS_FULL;
            int pictures = morph && (cracks == LK_TERRAIN_CRACKS_NONE || cracks == LK_TERRAIN_CRACKS_FULL);
            run_result r;
            if (!run(&s, &grids[g], names[g], cracks, morph, pictures, &r)) {
                failures++;
                continue;
            }
            printf("| %s %zux%zu | %s | %s | %.0f / %.0f / %.0f | %.3f / %.3f | %zu / %zu / %zu | %.3g | %.3g | %.3g | "
                   "%zu |\n",
                   names[g], grids[g].width, grids[g].height, lk_terrain_cracks_name(cracks), morph ? "on" : "off",
                   r.triangles_min, r.triangles_median, r.triangles_max, r.ms_median_measured, r.ms_median_updates_only,
                   r.crack_max, r.crack_total, r.crack_frames, r.max_gap, r.popping_metres, r.popping_pixels,
                   r.violations);
            fflush(stdout);
        }
    }
    printf("\nPer-frame CSVs and the before/after pictures (terrain_*_none_map.png vs terrain_*_full_map.png) are in "
           "%s.\n",
           s.out_dir);
    for (int g = 0; g < 3; g++) lk_heightfield_free(&grids[g]);
    return failures ? 1 : 0;
}
