/* SPDX-License-Identifier: MIT */
/* Splat radii on real data (issue 23): how far lk_points_estimate_radii's
 * radii stray from their neighbourhood, and what that does to the splats.
 *
 *   bench_radii [--size S] [--scans REFERENCE_DIR] [--save DIR] [--radius-scale F] [--no-clip] [SAMPLES_DIR]
 *
 * Radius statistics (k = 8, scale 1, radii always re-estimated): median,
 * 99th percentile, largest, largest / median, and the largest ratio of a
 * radius to the lower median of its 8 neighbours' radii (the neighbourhood
 * the clamp of lk_points_estimate_radii uses; lk__points_neighbour_medians),
 * with how many points exceed 4x. Point sets: the sample scans and point
 * files as read; meshes: their vertices as points (normals averaged from
 * the faces) and the bunny sampled with lk_mesh_sample_points' defaults.
 *
 * Splat quality, as tests/unit/test_splat.c measures it: the mesh and its
 * points drawn by the same camera (framing the mesh's box) at S x S
 * (default 512) on a magenta background; "covers" = splat pixels on the
 * mesh's silhouette / silhouette pixels; "outside / mesh" = splat pixels off
 * the silhouette / silhouette pixels (test_splat's measure); "outside /
 * splats" = the same / all splat pixels (the measure). Prints
 * markdown tables. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "internal.h"
#include "lodkit.h"

enum { NEIGHBOURS = 8 };

static const float magenta[3] = {1.0f, 0.0f, 1.0f};
static const char *save_dir;    /* --save DIR: the silhouettes and splats as PNGs */
static double radius_scale = 1; /* --radius-scale F: the splats drawn F times their radii */
static int clip_borders = 1;    /* --no-clip: whole discs at borders (lk_render_options.clip_borders) */

static void save(const char *name, const char *what, const unsigned char *rgba, unsigned size)
{
    if (!save_dir) return;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s_%s.png", save_dir, name, what);
    for (char *c = path + strlen(save_dir) + 1; *c; c++)
        if (*c == '/' || *c == ' ' || *c == ',') *c = '_';
    lk_error error = {0};
    if (lk_image_write_png(path, rgba, size, size, &error) != LK_OK) fprintf(stderr, "%s\n", error.message);
}

static int compare_floats(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

/* Value of rank round(q * (count - 1)) of sorted values. */
static double quantile(const float *sorted, size_t count, double q)
{
    return sorted[(size_t)llround(q * (double)(count - 1))];
}

static int radius_row(const char *name, const lk_mesh *points)
{
    size_t count = points->vertex_count;
    float *sorted = malloc(count * sizeof *sorted), *medians = malloc(count * sizeof *medians);
    lk_error error = {0};
    if (!sorted || !medians || lk__points_neighbour_medians(points, NEIGHBOURS, medians, &error) != LK_OK) {
        fprintf(stderr, "bench_radii: %s: %s\n", name, error.message[0] ? error.message : "out of memory");
        free(sorted);
        free(medians);
        return -1;
    }
    double worst = 0;
    size_t above = 0;
    for (size_t i = 0; i < count; i++) {
        double ratio = (double)points->radii[i] / medians[i];
        if (ratio > worst) worst = ratio;
        above += ratio > 4;
    }
    memcpy(sorted, points->radii, count * sizeof *sorted);
    qsort(sorted, count, sizeof *sorted, compare_floats);
    double median = quantile(sorted, count, 0.5);
    printf("| %s | %zu | %.4g | %.4g | %.4g | %.1f | %.1f | %zu |\n", name, count, median,
           quantile(sorted, count, 0.99), (double)sorted[count - 1], sorted[count - 1] / median, worst, above);
    free(sorted);
    free(medians);
    return 0;
}

/* The mesh's vertices as an oriented point set, normals averaged from the
 * faces (area-weighted), radii estimated. */
static lk_status vertices_as_points(const lk_mesh *mesh, lk_mesh *points, lk_error *error)
{
    size_t count = mesh->vertex_count;
    lk_status status = lk_mesh_alloc(points, count, 0, LK_ATTR_NORMALS, error);
    if (status != LK_OK) return status;
    memcpy(points->positions, mesh->positions, 3 * count * sizeof(float));
    double *sums = calloc(3 * count, sizeof *sums);
    if (!sums) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *v = mesh->indices + 3 * t;
        const float *a = mesh->positions + 3 * v[0], *b = mesh->positions + 3 * v[1], *c = mesh->positions + 3 * v[2];
        double e[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, f[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {e[1] * f[2] - e[2] * f[1], e[2] * f[0] - e[0] * f[2], e[0] * f[1] - e[1] * f[0]};
        for (int corner = 0; corner < 3; corner++)
            for (int k = 0; k < 3; k++) sums[3 * v[corner] + k] += n[k];
    }
    for (size_t i = 0; i < count; i++) {
        double *n = sums + 3 * i, length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int k = 0; k < 3; k++) points->normals[3 * i + k] = length > 0 ? (float)(n[k] / length) : k == 2;
    }
    free(sums);
    return lk_points_estimate_radii(points, NEIGHBOURS, 1.0, error);
}

static size_t differs(const unsigned char *pixel)
{
    for (int k = 0; k < 3; k++)
        if (pixel[k] != (unsigned char)lroundf(magenta[k] * 255.0f)) return 1;
    return 0;
}

static unsigned char *draw(lk_renderer *renderer, const lk_mesh *model, const lk_render_options *options, unsigned size,
                           lk_error *error)
{
    lk_status status = model->triangle_count ? lk_render_mesh(renderer, model, options, NULL, error)
                                             : lk_render_points(renderer, model, options, NULL, error);
    unsigned char *rgba = status == LK_OK ? malloc((size_t)size * size * 4) : NULL;
    if (rgba && lk_renderer_read_pixels(renderer, rgba, error) != LK_OK) {
        free(rgba);
        rgba = NULL;
    }
    return rgba;
}

/* Prints " covers | outside / mesh | outside / splats |" of one splat picture
 * against the silhouette (pixels differing from the magenta background). */
static void print_coverage(const unsigned char *silhouette, const unsigned char *splats, size_t pixel_count)
{
    size_t surface = 0, inside = 0, outside = 0;
    for (size_t i = 0; i < pixel_count; i++) {
        size_t on_mesh = differs(silhouette + 4 * i), on_splat = differs(splats + 4 * i);
        surface += on_mesh;
        inside += on_mesh && on_splat;
        outside += on_splat && !on_mesh;
    }
    printf(" %.2f%% | %.2f%% | %.2f%% |", 100.0 * inside / surface, 100.0 * outside / surface,
           100.0 * outside / (inside + outside));
}

static void coverage_row_with(const char *name, lk_renderer *renderer, unsigned size, const lk_mesh *mesh,
                              const lk_mesh *points, lk_render_options options)
{
    options.use_bounds = 1;
    options.radius_scale = radius_scale;
    options.clip_borders = (uint64_t)clip_borders;
    lk_mesh_bounds(mesh, options.bounds_min, options.bounds_max);
    memcpy(options.background, magenta, sizeof options.background);
    lk_error error = {0};
    unsigned char *silhouette = draw(renderer, mesh, &options, size, &error);
    if (silhouette) save(name, "mesh", silhouette, size);
    printf("| %s | %zu |", name, points->vertex_count);
    for (unsigned passes = 1; passes <= 2 && silhouette; passes++) {
        options.passes = passes;
        unsigned char *splats = draw(renderer, points, &options, size, &error);
        if (!splats) break;
        save(name, passes == 1 ? "1pass" : "2pass", splats, size);
        print_coverage(silhouette, splats, (size_t)size * size);
        free(splats);
    }
    if (error.message[0]) printf(" failed: %s", error.message);
    printf("\n");
    free(silhouette);
}

/* The bunny sampled into `count` points, built into a point octree (lodkit
 * octree's defaults, in a temporary folder) and drawn by lk_render_octree
 * under each budget, against the mesh's silhouette. The octree's inner
 * nodes' splats are at least their level's spacing (src/octree.c,
 * encode_node), larger than the whole cloud's own radii: these rows show
 * what that costs at the silhouette. Both drawings frame the octree's
 * tight bounds (the points' box), the octree's relative to its offset. */
static int octree_rows(lk_renderer *renderer, unsigned size, const lk_mesh *mesh, size_t count)
{
    char folder[] = "/tmp/lodkit-bench-radii-XXXXXX", ply[128], name[128];
    if (!mkdtemp(folder)) {
        perror("bench_radii: mkdtemp");
        return 1;
    }
    snprintf(ply, sizeof ply, "%s/points.ply", folder);
    lk_sample_options sample;
    lk_sample_options_default(&sample);
    sample.point_count = count;
    lk_mesh points;
    lk_mesh_init(&points);
    lk_octree *octree = NULL;
    lk_octree_options build;
    lk_octree_options_default(&build);
    const char *inputs[1] = {ply};
    lk_error error = {0};
    lk_status status = lk_mesh_sample_points(mesh, &sample, &points, NULL, NULL, &error);
    if (status == LK_OK) status = lk_mesh_write(ply, LK_FORMAT_PLY, &points, NULL, &error);
    if (status == LK_OK) status = lk_octree_build(inputs, 1, folder, &build, NULL, NULL, NULL, &error);
    if (status == LK_OK) status = lk_octree_open(folder, &octree, &error);
    lk_mesh_free(&points);
    if (status != LK_OK) {
        fprintf(stderr, "bench_radii: octree of %zu points: %s\n", count, error.message);
        return 1;
    }
    const lk_octree_info *info = lk_octree_get_info(octree);
    lk_render_options options;
    lk_render_options_default(&options);
    options.use_bounds = 1;
    options.radius_scale = radius_scale;
    options.clip_borders = (uint64_t)clip_borders;
    memcpy(options.background, magenta, sizeof options.background);
    for (int k = 0; k < 3; k++)
        options.bounds_min[k] = (float)info->min[k], options.bounds_max[k] = (float)info->max[k];
    snprintf(name, sizeof name, "bunny.obj sampled (%zu), octree", count);
    unsigned char *silhouette = draw(renderer, mesh, &options, size, &error);
    if (silhouette) save(name, "mesh", silhouette, size);
    for (int k = 0; k < 3; k++) {
        options.bounds_min[k] = (float)(info->min[k] - info->offset[k]);
        options.bounds_max[k] = (float)(info->max[k] - info->offset[k]);
    }
    static const double budget_fractions[] = {1.0, 0.25};
    for (size_t b = 0; b < sizeof budget_fractions / sizeof budget_fractions[0] && silhouette; b++) {
        lk_octree_select_options select;
        lk_octree_select_options_default(&select);
        select.point_budget = (uint64_t)llround(budget_fractions[b] * (double)info->points);
        select.min_spacing_pixels = 0; /* the budget alone decides */
        printf("| %s (%zu nodes, %u levels), budget %llu |", name, info->node_count,
               lk_octree_node_at(octree, info->node_count - 1)->level + 1, (unsigned long long)select.point_budget);
        for (unsigned passes = 1; passes <= 2; passes++) {
            options.passes = passes;
            lk_render_octree_stats stats;
            unsigned char *splats = NULL;
            if (lk_render_octree(renderer, octree, &options, &select, &stats, &error) == LK_OK &&
                (splats = malloc((size_t)size * size * 4)) &&
                lk_renderer_read_pixels(renderer, splats, &error) == LK_OK) {
                if (passes == 1) printf(" %llu |", (unsigned long long)stats.points);
                print_coverage(silhouette, splats, (size_t)size * size);
            } else {
                printf(" failed: %s |", error.message);
            }
            free(splats);
        }
        printf("\n");
    }
    free(silhouette);
    lk_octree_close(octree);
    static const char *const files[] = {"points.ply", "octree.bin", "octree.json"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        snprintf(ply, sizeof ply, "%s/%s", folder, files[i]);
        remove(ply);
    }
    rmdir(folder);
    return 0;
}

static void coverage_row(const char *name, lk_renderer *renderer, unsigned size, const lk_mesh *mesh,
                         const lk_mesh *points)
{
    lk_render_options options;
    lk_render_options_default(&options);
    coverage_row_with(name, renderer, size, mesh, points, options);
}

/* A scan without a mesh against the surface bench/reconstruct_scans.py
 * made from its points (REFERENCE_DIR/NAME.ply), seen from the default
 * view and from where the scanner stood (or above, for airborne lidar);
 * normals estimated where the file has none, radii always re-estimated,
 * as `lodkit splat` does. Culling off: a scan is one side of a surface and
 * its estimated normals may face away from a camera that is not the
 * scanner. */
typedef struct scan_case {
    const char *points, *reference, *view_name;
    int up_axis;
    double azimuth, elevation;
} scan_case;

static const scan_case scan_cases[] = {
    {"kitten.xyz", "kitten.ply", "default view", LK_AXIS_Y, 30, 20},
    {"hippo1.ply", "hippo1.ply", "default view", LK_AXIS_Y, 30, 20},
    {"las/Haystack_Rock.las", "Haystack_Rock.ply", "z up, default view", LK_AXIS_Z, 30, 20},
    {"las/Haystack_Rock.las", "Haystack_Rock.ply", "from above", LK_AXIS_Z, 0, 90},
    {"pcd/table_scene_mug_stereo_textured.pcd", "table_scene_mug_stereo_textured.ply", "default view", LK_AXIS_Y, 30,
     20},
    {"pcd/table_scene_mug_stereo_textured.pcd", "table_scene_mug_stereo_textured.ply", "from the camera", LK_AXIS_Y,
     180, 0},
    {"pcd/bun0.pcd", "bun0.ply", "z up, default view", LK_AXIS_Z, 30, 20},
    {"pcd/bun0.pcd", "bun0.ply", "from above", LK_AXIS_Z, 0, 90},
};
enum { SCAN_CASES = sizeof scan_cases / sizeof scan_cases[0] };

/* The case's camera, culling off. */
static lk_render_options scan_view(const scan_case *c)
{
    lk_render_options options;
    lk_render_options_default(&options);
    options.up_axis = c->up_axis;
    options.azimuth = c->azimuth;
    options.elevation = c->elevation;
    options.backface_culling = 0;
    return options;
}

static int scan_rows(lk_renderer *renderer, unsigned size, const char *samples, const char *references)
{
    for (size_t i = 0; i < SCAN_CASES; i++) {
        const scan_case *c = &scan_cases[i];
        char path[4096], name[256];
        lk_mesh points, mesh;
        lk_error error = {0};
        snprintf(path, sizeof path, "%s/%s", samples, c->points);
        lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &points, &error);
        if (status == LK_OK && !points.normals) status = lk_points_estimate_normals(&points, NEIGHBOURS, &error);
        if (status == LK_OK) status = lk_points_estimate_radii(&points, NEIGHBOURS, 1.0, &error);
        if (status != LK_OK) {
            fprintf(stderr, "bench_radii: %s: %s\n", path, error.message);
            return 1;
        }
        snprintf(path, sizeof path, "%s/%s", references, c->reference);
        if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK) {
            fprintf(stderr, "bench_radii: %s: %s (run bench/reconstruct_scans.py first)\n", path, error.message);
            lk_mesh_free(&points);
            return 1;
        }
        lk_render_options options = scan_view(c);
        snprintf(name, sizeof name, "%s, %s", c->points, c->view_name);
        coverage_row_with(name, renderer, size, &mesh, &points, options);
        lk_mesh_free(&points);
        lk_mesh_free(&mesh);
    }
    return 0;
}

/* One picture through an octree, 1-pass, against the silhouette: prints
 * " points drawn | covers | outside / mesh | outside / splats |". */
static void octree_coverage(lk_renderer *renderer, unsigned size, const lk_octree *octree,
                            const lk_render_options *options, uint64_t budget, const unsigned char *silhouette,
                            const char *name, const char *what)
{
    lk_octree_select_options select;
    lk_octree_select_options_default(&select);
    select.point_budget = budget;
    select.min_spacing_pixels = 0; /* the budget alone decides */
    lk_render_octree_stats stats;
    lk_error error = {0};
    unsigned char *splats = NULL;
    if (lk_render_octree(renderer, octree, options, &select, &stats, &error) == LK_OK &&
        (splats = malloc((size_t)size * size * 4)) && lk_renderer_read_pixels(renderer, splats, &error) == LK_OK) {
        printf(" %llu |", (unsigned long long)stats.points);
        save(name, what, splats, size);
        print_coverage(silhouette, splats, (size_t)size * size);
    } else {
        printf(" failed: %s |", error.message);
    }
    free(splats);
}

/* The scans of scan_rows built into point octrees (lodkit octree's
 * defaults, normals estimated where the file has none, as `lodkit octree
 * --estimate-normals`) and drawn by lk_render_octree at the whole and a
 * quarter of the point count, with whole discs (--no-clip) and with the
 * clip lines the octree stores, against the same references and views. */
static int octree_scan_rows(lk_renderer *renderer, unsigned size, const char *samples, const char *references)
{
    for (size_t i = 0; i < SCAN_CASES; i++) {
        const scan_case *c = &scan_cases[i];
        char path[4096], reference[4096], name[256];
        char folder[] = "/tmp/lodkit-bench-radii-XXXXXX";
        if (!mkdtemp(folder)) {
            perror("bench_radii: mkdtemp");
            return 1;
        }
        snprintf(path, sizeof path, "%s/%s", samples, c->points);
        snprintf(reference, sizeof reference, "%s/%s", references, c->reference);
        lk_mesh points, mesh;
        lk_mesh_init(&points);
        lk_mesh_init(&mesh);
        lk_octree *octree = NULL;
        lk_error error = {0};
        lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &points, &error);
        lk_octree_options build;
        lk_octree_options_default(&build);
        build.normals = status == LK_OK && points.normals ? LK_OCTREE_NORMALS_AUTO : LK_OCTREE_NORMALS_ESTIMATE;
        build.threads = 1;
        const char *inputs[1] = {path};
        if (status == LK_OK) status = lk_mesh_read(reference, LK_FORMAT_AUTO, NULL, &mesh, &error);
        if (status == LK_OK) status = lk_octree_build(inputs, 1, folder, &build, NULL, NULL, NULL, &error);
        if (status == LK_OK) status = lk_octree_open(folder, &octree, &error);
        lk_mesh_free(&points);
        if (status != LK_OK) {
            fprintf(stderr, "bench_radii: %s: octree: %s\n", path, error.message);
            lk_mesh_free(&mesh);
            return 1;
        }
        const lk_octree_info *info = lk_octree_get_info(octree);
        lk_render_options options = scan_view(c);
        options.use_bounds = 1;
        options.radius_scale = radius_scale;
        memcpy(options.background, magenta, sizeof options.background);
        lk_mesh_bounds(&mesh, options.bounds_min, options.bounds_max);
        snprintf(name, sizeof name, "%s, %s, octree", c->points, c->view_name);
        unsigned char *silhouette = draw(renderer, &mesh, &options, size, &error);
        for (int k = 0; k < 3; k++) {
            options.bounds_min[k] -= (float)info->offset[k];
            options.bounds_max[k] -= (float)info->offset[k];
        }
        for (int quarter = 0; quarter < 2 && silhouette; quarter++) {
            uint64_t budget = quarter ? info->points / 4 : info->points;
            printf("| %s, %s | %zu nodes | %llu |", c->points, c->view_name, info->node_count,
                   (unsigned long long)budget);
            options.clip_borders = 0;
            octree_coverage(renderer, size, octree, &options, budget, silhouette, name,
                            quarter ? "quarter_whole" : "whole");
            options.clip_borders = 1;
            octree_coverage(renderer, size, octree, &options, budget, silhouette, name,
                            quarter ? "quarter_cut" : "cut");
            printf("\n");
        }
        free(silhouette);
        lk_octree_close(octree);
        lk_mesh_free(&mesh);
        static const char *const files[] = {"octree.bin", "octree.json"};
        for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
            snprintf(path, sizeof path, "%s/%s", folder, files[f]);
            remove(path);
        }
        rmdir(folder);
    }
    return 0;
}

int main(int argc, char **argv)
{
    unsigned size = 512;
    const char *samples = "data/samples", *references = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--size") && i + 1 < argc)
            size = (unsigned)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--radius-scale") && i + 1 < argc)
            radius_scale = atof(argv[++i]);
        else if (!strcmp(argv[i], "--no-clip"))
            clip_borders = 0;
        else if (!strcmp(argv[i], "--save") && i + 1 < argc)
            save_dir = argv[++i];
        else if (!strcmp(argv[i], "--scans") && i + 1 < argc)
            references = argv[++i];
        else if (argv[i][0] != '-')
            samples = argv[i];
        else {
            fprintf(stderr,
                    "usage: bench_radii [--size S] [--scans REFERENCE_DIR] [--save DIR] [--radius-scale F] [--no-clip] "
                    "[SAMPLES_DIR]\n");
            return 2;
        }
    }
    if (size < 16 || size > 8192) {
        fprintf(stderr, "bench_radii: --size must be 16..8192\n");
        return 2;
    }
    static const char *const point_files[] = {"kitten.xyz",
                                              "hippo1.ply",
                                              "pcd/bun0.pcd",
                                              "pcd/milk.pcd",
                                              "pcd/table_scene_mug_stereo_textured.pcd",
                                              "pcd/test_pcd.pcd",
                                              "las/Haystack_Rock.las"};
    static const char *const mesh_files[] = {"bunny.obj", "cow.off", "fandisk.off", "triceratops.off",
                                             "ChineseDragon-10kv.off"};
    enum { MESH_COUNT = sizeof mesh_files / sizeof mesh_files[0] };
    lk_mesh meshes[MESH_COUNT], vertices[MESH_COUNT], sampled;
    lk_mesh_init(&sampled);
    lk_error error = {0};
    int failed = 0;

    printf("Splat radii, k = %d, scale 1 (ratio to neighbourhood: radius / lower median of its %d neighbours' "
           "radii)\n\n",
           NEIGHBOURS, NEIGHBOURS);
    printf("| point set | points | median | p99 | max | max / median | max / neighbourhood median | "
           "points > 4x neighbourhood |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (size_t i = 0; i < sizeof point_files / sizeof point_files[0]; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", samples, point_files[i]);
        lk_mesh points;
        if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &points, &error) != LK_OK ||
            lk_points_estimate_radii(&points, NEIGHBOURS, 1.0, &error) != LK_OK) {
            fprintf(stderr, "bench_radii: %s: %s\n", path, error.message);
            return 1;
        }
        failed |= radius_row(point_files[i], &points);
        lk_mesh_free(&points);
    }
    for (size_t i = 0; i < MESH_COUNT; i++) {
        char path[4096], name[128];
        snprintf(path, sizeof path, "%s/%s", samples, mesh_files[i]);
        lk_mesh_init(&vertices[i]);
        if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &meshes[i], &error) != LK_OK ||
            vertices_as_points(&meshes[i], &vertices[i], &error) != LK_OK) {
            fprintf(stderr, "bench_radii: %s: %s\n", path, error.message);
            return 1;
        }
        snprintf(name, sizeof name, "%s vertices", mesh_files[i]);
        failed |= radius_row(name, &vertices[i]);
    }
    if (lk_mesh_sample_points(&meshes[0], NULL, &sampled, NULL, NULL, &error) != LK_OK) {
        fprintf(stderr, "bench_radii: sampling the bunny: %s\n", error.message);
        return 1;
    }
    failed |= radius_row("bunny.obj sampled (100k)", &sampled);

    lk_renderer *renderer = NULL;
    if (lk_renderer_create(size, size, &renderer, &error) != LK_OK) {
        fprintf(stderr, "bench_radii: no renderer: %s\n", error.message);
        return 1;
    }
    printf("\nSplats against the mesh's silhouette, %ux%u\n\n", size, size);
    printf("| points | count | 1-pass covers | 1-pass outside / mesh | 1-pass outside / splats | 2-pass covers | "
           "2-pass outside / mesh | 2-pass outside / splats |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    coverage_row("bunny.obj sampled (100k)", renderer, size, &meshes[0], &sampled);
    for (size_t i = 0; i < MESH_COUNT; i++) {
        char name[128];
        snprintf(name, sizeof name, "%s vertices", mesh_files[i]);
        coverage_row(name, renderer, size, &meshes[i], &vertices[i]);
        if (i > 0) lk_mesh_free(&meshes[i]); /* the bunny's is drawn again below */
        lk_mesh_free(&vertices[i]);
    }
    printf("\nThe same through a point octree (lodkit octree's defaults; lk_render_octree, minimum spacing 0 "
           "pixels: the budget alone decides), %ux%u\n\n",
           size, size);
    printf("| octree, budget | points drawn | 1-pass covers | 1-pass outside / mesh | 1-pass outside / splats | "
           "2-pass covers | 2-pass outside / mesh | 2-pass outside / splats |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    failed |= octree_rows(renderer, size, &meshes[0], 100000);
    failed |= octree_rows(renderer, size, &meshes[0], 1000000);
    lk_mesh_free(&meshes[0]);
    if (references) {
        printf("\nScans against surfaces made from their points (bench/reconstruct_scans.py), no culling, "
               "%ux%u\n\n",
               size, size);
        printf("| scan, view | count | 1-pass covers | 1-pass outside / mesh | 1-pass outside / splats | "
               "2-pass covers | 2-pass outside / mesh | 2-pass outside / splats |\n");
        printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
        failed |= scan_rows(renderer, size, samples, references);
        printf("\nThe scans through point octrees (lodkit octree's defaults, normals estimated where the file has "
               "none; lk_render_octree, 1-pass, minimum spacing 0 pixels: the budget alone decides), whole discs "
               "(--no-clip) and cut by the clip lines the octree stores, %ux%u\n\n",
               size, size);
        printf("| scan, view | octree | budget | whole: points drawn | covers | outside / mesh | outside / splats | "
               "cut: points drawn | covers | outside / mesh | outside / splats |\n");
        printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        failed |= octree_scan_rows(renderer, size, samples, references);
    }
    lk_renderer_free(renderer);
    lk_mesh_free(&sampled);
    return failed ? 1 : 0;
}
