/* SPDX-License-Identifier: MIT */
/* Point splatting (src/gl/splat.c): the quality checks of issue 7 on real
 * models, rendered headless (Mesa llvmpipe), and the refusals.
 *
 * Set LK_TEST_SAVE_IMAGES=DIR to keep the pictures as PNGs in DIR. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* Internal hooks of src/gl/splat.c. */
lk_status lk__splat_count_fragments(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                                    uint64_t *fragment_count, lk_error *error);
const char *lk__splat_target(lk_renderer *renderer, int force_rgba8);

/* A background no shaded pixel takes: a pixel is "covered" when it differs. */
static const float magenta[3] = {1.0f, 0.0f, 1.0f};

typedef struct fixture {
    lk_mesh bunny;        /* the mesh */
    lk_mesh bunny_points; /* lk_mesh_sample_points with default options */
    float bunny_min[3], bunny_max[3];
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f) return -1;
    lk_test_load(lk_test_sample("bunny.obj"), &f->bunny);
    lk_error error = {0};
    if (lk_mesh_sample_points(&f->bunny, NULL, &f->bunny_points, NULL, NULL, &error) != LK_OK) {
        fprintf(stderr, "sampling the bunny: %s\n", error.message);
        lk_mesh_free(&f->bunny);
        free(f);
        return -1;
    }
    lk_mesh_bounds(&f->bunny, f->bunny_min, f->bunny_max);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    lk_mesh_free(&f->bunny);
    lk_mesh_free(&f->bunny_points);
    free(f);
    return 0;
}

static lk_renderer *make_renderer(unsigned width, unsigned height)
{
    lk_renderer *renderer = NULL;
    lk_error error = {0};
    if (lk_renderer_create(width, height, &renderer, &error) != LK_OK)
        fail_msg("no offscreen renderer (Mesa llvmpipe expected): %s", error.message);
    return renderer;
}

static void save_image(const char *name, const unsigned char *rgba, unsigned width, unsigned height)
{
    const char *directory = getenv("LK_TEST_SAVE_IMAGES");
    if (!directory || !*directory) return;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", directory, name);
    lk_error error = {0};
    if (lk_image_write_png(path, rgba, width, height, &error) != LK_OK) fail_msg("%s", error.message);
}

/* Renders (points or mesh) and reads the image into a new buffer. */
static unsigned char *render(lk_renderer *renderer, const lk_mesh *model, int as_mesh, const lk_render_options *options,
                             lk_render_stats *stats, const char *save_as)
{
    unsigned width, height;
    lk_renderer_size(renderer, &width, &height);
    lk_error error = {0};
    lk_status status = as_mesh ? lk_render_mesh(renderer, model, options, stats, &error)
                               : lk_render_points(renderer, model, options, stats, &error);
    if (status != LK_OK) fail_msg("render failed: %s", error.message);
    unsigned char *rgba = malloc((size_t)width * height * 4);
    assert_non_null(rgba);
    if (lk_renderer_read_pixels(renderer, rgba, &error) != LK_OK) fail_msg("%s", error.message);
    if (save_as) save_image(save_as, rgba, width, height);
    return rgba;
}

static int is_background(const unsigned char *pixel, const float background[3])
{
    for (int k = 0; k < 3; k++)
        if (pixel[k] != (unsigned char)lroundf(background[k] * 255.0f)) return 0;
    return 1;
}

static size_t covered_pixels(const unsigned char *rgba, size_t pixel_count, const float background[3])
{
    size_t covered = 0;
    for (size_t i = 0; i < pixel_count; i++) covered += !is_background(rgba + 4 * i, background);
    return covered;
}

static double luminance(const unsigned char *pixel) { return 0.299 * pixel[0] + 0.587 * pixel[1] + 0.114 * pixel[2]; }

/* Mean and standard deviation of the luminance over a window. */
static void window_stats(const unsigned char *rgba, unsigned width, unsigned x0, unsigned y0, unsigned x1, unsigned y1,
                         double *mean, double *deviation)
{
    double sum = 0, sum_squares = 0;
    size_t count = 0;
    for (unsigned y = y0; y < y1; y++)
        for (unsigned x = x0; x < x1; x++) {
            double value = luminance(rgba + 4 * ((size_t)y * width + x));
            sum += value;
            sum_squares += value * value;
            count++;
        }
    *mean = sum / (double)count;
    *deviation = sqrt(fmax(sum_squares / (double)count - *mean * *mean, 0.0));
}

/* ---- 1. hole-free ----------------------------------------------------------- */

/* The bunny as a mesh and as its default point sample, same camera: the
 * splats cover the mesh's silhouette and spill little outside it. */
static void test_bunny_splats_cover_the_mesh(void **state)
{
    fixture *f = *state;
    const unsigned size = 512;
    const size_t pixel_count = (size_t)size * size;
    lk_renderer *renderer = make_renderer(size, size);
    lk_render_options options;
    lk_render_options_default(&options);
    options.use_bounds = 1;
    memcpy(options.bounds_min, f->bunny_min, sizeof options.bounds_min);
    memcpy(options.bounds_max, f->bunny_max, sizeof options.bounds_max);
    memcpy(options.background, magenta, sizeof options.background);

    unsigned char *mesh = render(renderer, &f->bunny, 1, &options, NULL, "bunny_mesh.png");
    size_t mesh_pixels = covered_pixels(mesh, pixel_count, magenta);
    assert_true(mesh_pixels > pixel_count / 5); /* the bunny fills a good part of the frame */
    const char *names[2] = {"bunny_splats_1pass.png", "bunny_splats_2pass.png"};
    for (unsigned passes = 1; passes <= 2; passes++) {
        options.passes = passes;
        lk_render_stats stats;
        unsigned char *splats = render(renderer, &f->bunny_points, 0, &options, &stats, names[passes - 1]);
        assert_int_equal(stats.primitives, f->bunny_points.vertex_count);
        assert_true(stats.milliseconds > 0);
        size_t inside = 0, outside = 0;
        for (size_t i = 0; i < pixel_count; i++) {
            int splat = !is_background(splats + 4 * i, magenta), surface = !is_background(mesh + 4 * i, magenta);
            inside += splat && surface;
            outside += splat && !surface;
        }
        double coverage = (double)inside / (double)mesh_pixels, spill = (double)outside / (double)mesh_pixels;
        print_message("bunny %u-pass, %zu points, %ux%u: covers %.3f%% of the %zu mesh pixels, adds %.2f%% outside\n",
                      passes, f->bunny_points.vertex_count, size, size, 100 * coverage, mesh_pixels, 100 * spill);
        assert_true(coverage >= 0.99);
        /* measured 1.02% for both (issue 23: at most 3%): the splats are
         * discs in their tangent plane (splat_disc.glsl), thin where the
         * surface turns away; as screen-aligned discs they spilled 5.4%, a
         * rim of one radius along the silhouette, and 1.50% while the
         * disc's depth was taken along the optical axis instead of the
         * splat's own ray (a rim of up to 0.3 radii off the middle of the
         * picture) with a sliver of 0.2 radii for edge-on splats. */
        assert_true(spill < 0.0125);
        free(splats);
    }
    free(mesh);
    lk_renderer_free(renderer);
}

/* Pixels of `splats` off the silhouette in `mesh` (both non-magenta tests). */
static size_t pixels_outside(const unsigned char *splats, const unsigned char *mesh, size_t pixel_count)
{
    size_t outside = 0;
    for (size_t i = 0; i < pixel_count; i++)
        outside += !is_background(splats + 4 * i, magenta) && is_background(mesh + 4 * i, magenta);
    return outside;
}

/* Issue 23: stray points in a scan became large discs, their radius the
 * distance to the surface. Four strays at corners of the bunny's box, in
 * the frame but off the silhouette, added to its sample (radii estimated
 * again): the splats still cover the silhouette, and the strays add little
 * outside it (each at most 4x the radius of the surface points next to
 * it). */
static void test_stray_points_stay_small(void **state)
{
    fixture *f = *state;
    const unsigned size = 512;
    const size_t pixel_count = (size_t)size * size, count = f->bunny_points.vertex_count, strays = 4;
    lk_mesh noisy;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&noisy, count + strays, 0, LK_ATTR_NORMALS, &error), LK_OK);
    memcpy(noisy.positions, f->bunny_points.positions, 3 * count * sizeof(float));
    memcpy(noisy.normals, f->bunny_points.normals, 3 * count * sizeof(float));
    const float *lo = f->bunny_min, *hi = f->bunny_max;
    const float corners[4][3] = {
        {lo[0], hi[1], lo[2]}, {hi[0], hi[1], hi[2]}, {lo[0], lo[1], hi[2]}, {hi[0], hi[1], lo[2]}};
    for (size_t s = 0; s < strays; s++) {
        memcpy(noisy.positions + 3 * (count + s), corners[s], sizeof corners[s]);
        float *n = noisy.normals + 3 * (count + s);
        n[0] = 0, n[1] = 0, n[2] = 1;
    }
    assert_int_equal(lk_points_estimate_radii(&noisy, 8, 1.0, &error), LK_OK);

    lk_renderer *renderer = make_renderer(size, size);
    lk_render_options options;
    lk_render_options_default(&options);
    options.use_bounds = 1;
    memcpy(options.bounds_min, f->bunny_min, sizeof options.bounds_min);
    memcpy(options.bounds_max, f->bunny_max, sizeof options.bounds_max);
    memcpy(options.background, magenta, sizeof options.background);
    options.backface_culling = 0; /* the strays face +z whatever the camera */
    unsigned char *mesh = render(renderer, &f->bunny, 1, &options, NULL, NULL);
    unsigned char *clean = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
    unsigned char *splats = render(renderer, &noisy, 0, &options, NULL, "bunny_strays.png");
    size_t mesh_pixels = covered_pixels(mesh, pixel_count, magenta);
    size_t clean_outside = pixels_outside(clean, mesh, pixel_count),
           outside = pixels_outside(splats, mesh, pixel_count);
    size_t covered = mesh_pixels - pixels_outside(mesh, splats, pixel_count);
    float largest = 0;
    for (size_t s = 0; s < strays; s++) largest = fmaxf(largest, noisy.radii[count + s]);
    print_message("bunny + %zu strays (largest radius %.4f): %zu pixels outside the silhouette, %zu without the "
                  "strays (of %zu mesh pixels); covers %.3f%%\n",
                  strays, (double)largest, outside, clean_outside, mesh_pixels, 100.0 * covered / mesh_pixels);
    assert_true((double)covered >= 0.99 * mesh_pixels);
    /* measured: the 4 strays (radius <= 0.058, 4x their neighbours') add
     * 778 pixels, 1.4% of the silhouette (912 before the discs' depth was
     * taken along their own ray, splat_disc.glsl); at their unclamped radii (the
     * distance to the bunny, up to 1.05) they added 75566, 137% */
    assert_true((double)(outside - clean_outside) < 0.03 * mesh_pixels);
    free(mesh);
    free(clean);
    free(splats);
    lk_renderer_free(renderer);
    lk_mesh_free(&noisy);
}

/* ---- 2. 2-pass removes the overlap artefacts ---------------------------------- */

/* A flat 20x20 patch, uniformly sampled, seen obliquely (so splats lie at
 * different depths): 1-pass blending shows the overlaps (translucent rims of
 * the front splats over the background), normalised 2-pass splatting does
 * not, and its shade matches the mesh of the same patch. */
static void test_two_pass_flattens_a_uniform_patch(void **state)
{
    (void)state;
    const unsigned size = 256;
    lk_mesh grid, points;
    lk_test_make_grid(&grid, 20);
    lk_sample_options sample;
    lk_sample_options_default(&sample);
    sample.point_count = 20000;
    lk_error error = {0};
    if (lk_mesh_sample_points(&grid, &sample, &points, NULL, NULL, &error) != LK_OK) fail_msg("%s", error.message);
    lk_renderer *renderer = make_renderer(size, size);
    lk_render_options options;
    lk_render_options_default(&options);
    options.azimuth = 30;
    options.elevation = 20;
    /* The middle of the patch, well inside its silhouette. */
    const unsigned x0 = size * 3 / 8, x1 = size * 5 / 8, y0 = size * 7 / 16, y1 = size * 9 / 16;

    double mean[4], deviation[4], spread[4];
    static const char *const names[4] = {"patch_mesh.png", "patch_1pass.png", "patch_2pass.png",
                                         "patch_2pass_rgba8.png"};
    for (int run = 0; run < 4; run++) {
        options.passes = run >= 2 ? 2 : 1;
        lk__splat_target(renderer, run == 3);
        unsigned char *rgba = render(renderer, run == 0 ? &grid : &points, run == 0, &options, NULL, names[run]);
        window_stats(rgba, size, x0, y0, x1, y1, &mean[run], &deviation[run]);
        spread[run] = deviation[run] / mean[run];
        free(rgba);
    }
    print_message("patch std/mean: mesh %.4f, 1-pass %.4f, 2-pass %.4f (%s; %.1fx smaller), "
                  "2-pass RGBA8 %.4f (%.1fx smaller); means %.1f %.1f %.1f %.1f\n",
                  spread[0], spread[1], spread[2], lk__splat_target(renderer, 0), spread[1] / spread[2], spread[3],
                  spread[1] / spread[3], mean[0], mean[1], mean[2], mean[3]);
    assert_true(spread[1] >= 3 * spread[2]);
    /* RGBA8 fallback: coarser weights, still clearly better than 1 pass */
    assert_true(spread[1] >= 2 * spread[3]);
    /* normalised splats shade like the mesh (same lights, same normal) */
    assert_true(fabs(mean[2] - mean[0]) < 0.02 * mean[0]);
    assert_true(fabs(mean[3] - mean[0]) < 0.03 * mean[0]);
    /* 1 pass lets the background through the rims: brighter on white */
    assert_true(mean[1] > mean[0] + 2);
    lk_renderer_free(renderer);
    lk_mesh_free(&grid);
    lk_mesh_free(&points);
}

/* ---- 3. back-face culling ----------------------------------------------------- */

/* On the (nearly closed) bunny, culling in the vertex shader removes about
 * half of the fragments the splats make. */
static void test_culling_halves_the_fragments(void **state)
{
    fixture *f = *state;
    lk_renderer *renderer = make_renderer(256, 256);
    lk_render_options options;
    lk_render_options_default(&options);
    uint64_t culled = 0, all = 0;
    lk_error error = {0};
    if (lk__splat_count_fragments(renderer, &f->bunny_points, &options, &culled, &error) != LK_OK)
        fail_msg("%s", error.message);
    options.backface_culling = 0;
    if (lk__splat_count_fragments(renderer, &f->bunny_points, &options, &all, &error) != LK_OK)
        fail_msg("%s", error.message);
    double ratio = (double)culled / (double)all;
    print_message("bunny fragments: %llu with culling, %llu without (ratio %.3f)\n", (unsigned long long)culled,
                  (unsigned long long)all, ratio);
    assert_true(all > 0);
    assert_true(ratio >= 0.35 && ratio <= 0.65);

    /* And from other sides too. */
    for (int azimuth = 120; azimuth < 360; azimuth += 120) {
        options.azimuth = azimuth;
        options.backface_culling = 1;
        if (lk__splat_count_fragments(renderer, &f->bunny_points, &options, &culled, &error) != LK_OK)
            fail_msg("%s", error.message);
        options.backface_culling = 0;
        if (lk__splat_count_fragments(renderer, &f->bunny_points, &options, &all, &error) != LK_OK)
            fail_msg("%s", error.message);
        ratio = (double)culled / (double)all;
        print_message("  azimuth %d: ratio %.3f\n", azimuth, ratio);
        assert_true(ratio >= 0.35 && ratio <= 0.65);
    }
    lk_renderer_free(renderer);
}

/* ---- eq. 1 -------------------------------------------------------------------- */

/* One flat point of radius r facing the camera at a known distance is a
 * square sprite 2 r n / z_eye * h / (t - b) pixels wide; huge radii clamp
 * to the driver's largest point size. */
static void test_sprite_size_follows_equation_1(void **state)
{
    (void)state;
    const unsigned size = 400;
    lk_renderer *renderer = make_renderer(size, size);
    lk_mesh point;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&point, 1, 0, LK_ATTR_NORMALS | LK_ATTR_RADII, &error), LK_OK);
    point.positions[0] = point.positions[1] = point.positions[2] = 0;
    point.normals[0] = point.normals[1] = 0, point.normals[2] = 1;
    lk_render_options options;
    lk_render_options_default(&options);
    options.azimuth = 0, options.elevation = 0; /* looking down -z at the point */
    options.flat_points = 1;
    options.use_bounds = 1;
    for (int k = 0; k < 3; k++) options.bounds_min[k] = -1, options.bounds_max[k] = 1;
    /* lk__camera_setup frames the sphere of radius sqrt(3) at 1.05 R / sin(fov/2) */
    double half_fov = 0.5 * options.fov_y * 3.14159265358979323846 / 180;
    double distance = 1.05 * sqrt(3.0) / sin(half_fov);
    for (int i = 0; i < 3; i++) {
        point.radii[0] = (float)(0.02 * (1 << (2 * i))); /* 0.02, 0.08, 0.32 */
        unsigned char *rgba = render(renderer, &point, 0, &options, NULL, NULL);
        size_t pixels = covered_pixels(rgba, (size_t)size * size, options.background);
        free(rgba);
        /* n / z * h / (t - b) with t = n tan(fov/2): h / (2 z tan(fov/2)) */
        double expected = 2.0 * point.radii[0] * size / (2.0 * distance * tan(half_fov));
        double side = sqrt((double)pixels);
        print_message("radius %.2f: sprite %.2f px wide, eq. 1 says %.2f\n", (double)point.radii[0], side, expected);
        assert_true(fabs(side - expected) <= 1.0);
    }
    point.radii[0] = 100;
    unsigned char *rgba = render(renderer, &point, 0, &options, NULL, NULL);
    size_t pixels = covered_pixels(rgba, (size_t)size * size, options.background);
    free(rgba);
    double side = sqrt((double)pixels);
    print_message("radius 100: clamped to %.1f px\n", side);
    assert_true(side >= 60 && side <= 256); /* llvmpipe: 255 */
    lk_mesh_free(&point);
    lk_renderer_free(renderer);
}

/* ---- the sample point sets ------------------------------------------------------ */

static void render_point_file(const char *name, size_t expected_points)
{
    lk_mesh points;
    lk_test_load(lk_test_sample(name), &points);
    assert_int_equal(points.vertex_count, expected_points);
    assert_non_null(points.normals);
    const unsigned size = 256;
    lk_renderer *renderer = make_renderer(size, size);
    lk_render_options options;
    lk_render_options_default(&options);
    memcpy(options.background, magenta, sizeof options.background);
    size_t covered[3];
    for (int mode = 0; mode < 3; mode++) {
        options.flat_points = mode == 0;
        options.passes = mode == 2 ? 2 : 1;
        char save_as[128];
        snprintf(save_as, sizeof save_as, "%s_%s.png", name, mode == 0 ? "flat" : mode == 1 ? "1pass" : "2pass");
        lk_render_stats stats;
        unsigned char *rgba = render(renderer, &points, 0, &options, &stats, save_as);
        covered[mode] = covered_pixels(rgba, (size_t)size * size, magenta);
        assert_int_equal(stats.primitives, points.vertex_count);
        free(rgba);
    }
    print_message("%s: %zu points, covered pixels flat %zu, 1-pass %zu, 2-pass %zu of %u\n", name, points.vertex_count,
                  covered[0], covered[1], covered[2], size * size);
    /* The model framed: a solid part of the picture, never all of it. */
    for (int mode = 0; mode < 3; mode++) {
        assert_true(covered[mode] > (size_t)size * size / 10);
        assert_true(covered[mode] < (size_t)size * size * 9 / 10);
    }
    /* Same footprints: square sprites cover a bit more than discs. */
    assert_true(covered[0] >= covered[1]);
    assert_true(labs((long)covered[1] - (long)covered[2]) < (long)covered[1] / 50);
    lk_renderer_free(renderer);
    lk_mesh_free(&points);
}

static void test_kitten_xyz(void **state)
{
    (void)state;
    render_point_file("kitten.xyz", 5210); /* no radii: estimated */
}

static void test_hippo_ply(void **state)
{
    (void)state;
    render_point_file("hippo1.ply", 6104);
}

/* ---- behaviour ------------------------------------------------------------------ */

/* The same render twice gives the same bytes; options change the picture
 * as documented. */
static void test_deterministic_and_options(void **state)
{
    fixture *f = *state;
    const unsigned size = 256;
    const size_t pixel_count = (size_t)size * size;
    lk_renderer *renderer = make_renderer(size, size);
    lk_render_options options;
    lk_render_options_default(&options);
    memcpy(options.background, magenta, sizeof options.background);
    for (unsigned passes = 1; passes <= 2; passes++) {
        options.passes = passes;
        unsigned char *a = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
        unsigned char *b = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
        assert_memory_equal(a, b, pixel_count * 4);
        free(a);
        free(b);
    }
    options.passes = 1;
    unsigned char *normal = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
    options.radius_scale = 3;
    unsigned char *wide = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
    size_t normal_pixels = covered_pixels(normal, pixel_count, magenta);
    size_t wide_pixels = covered_pixels(wide, pixel_count, magenta);
    print_message("radius scale 3: %zu -> %zu covered pixels\n", normal_pixels, wide_pixels);
    assert_true(wide_pixels > normal_pixels + normal_pixels / 50);
    /* A mesh render after splats, and splats after a mesh, are unaffected by
     * each other's GL state. */
    unsigned char *mesh_before = render(renderer, &f->bunny, 1, &options, NULL, NULL);
    options.radius_scale = 1;
    options.passes = 2;
    free(render(renderer, &f->bunny_points, 0, &options, NULL, NULL));
    unsigned char *mesh_after = render(renderer, &f->bunny, 1, &options, NULL, NULL);
    assert_memory_equal(mesh_before, mesh_after, pixel_count * 4);
    options.passes = 1;
    unsigned char *again = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
    assert_memory_equal(normal, again, pixel_count * 4);
    free(normal);
    free(wide);
    free(mesh_before);
    free(mesh_after);
    free(again);
    lk_renderer_free(renderer);
}

/* The RGBA8 fallback of the 2-pass mode gives nearly the picture of the
 * floating-point target. */
static void test_rgba8_fallback_close_to_float(void **state)
{
    fixture *f = *state;
    const unsigned size = 256;
    const size_t pixel_count = (size_t)size * size;
    lk_renderer *renderer = make_renderer(size, size);
    lk_render_options options;
    lk_render_options_default(&options);
    options.passes = 2;
    const char *target = lk__splat_target(renderer, 0);
    unsigned char *precise = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
    assert_string_equal(lk__splat_target(renderer, 1), "RGBA8 (weights / 16)");
    unsigned char *coarse = render(renderer, &f->bunny_points, 0, &options, NULL, NULL);
    double difference = 0;
    int largest = 0;
    for (size_t i = 0; i < pixel_count * 4; i++) {
        int d = abs((int)precise[i] - (int)coarse[i]);
        difference += d;
        if (d > largest) largest = d;
    }
    difference /= (double)(pixel_count * 3);
    print_message("2-pass target %s vs RGBA8: mean |difference| %.3f, largest %d (of 255)\n", target, difference,
                  largest);
    assert_true(difference < 2.0);
    free(precise);
    free(coarse);
    lk_renderer_free(renderer);
}

/* ---- refusals ------------------------------------------------------------------- */

static void expect_refusal(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                           lk_status expected, const char *needle)
{
    lk_error error = {0};
    lk_render_stats stats;
    assert_int_equal(lk_render_points(renderer, points, options, &stats, &error), expected);
    lk_assert_message_contains(error, needle);
}

static void test_bad_input(void **state)
{
    (void)state;
    lk_renderer *renderer = make_renderer(64, 64);
    lk_mesh points;
    lk_error error = {0};
    assert_int_equal(lk_mesh_alloc(&points, 3, 0, LK_ATTR_NORMALS | LK_ATTR_RADII, &error), LK_OK);
    for (int i = 0; i < 3; i++) {
        float *p = points.positions + 3 * i, *n = points.normals + 3 * i;
        p[0] = (float)i, p[1] = 0, p[2] = 0;
        n[0] = 0, n[1] = 0, n[2] = 1;
        points.radii[i] = 0.5f;
    }
    lk_render_options options;
    lk_render_options_default(&options);
    /* the valid set draws */
    assert_int_equal(lk_render_points(renderer, &points, &options, NULL, &error), LK_OK);

    float kept = points.radii[1];
    const float bad_radii[4] = {0.0f, -1.0f, NAN, INFINITY};
    for (int i = 0; i < 4; i++) {
        points.radii[1] = bad_radii[i];
        expect_refusal(renderer, &points, &options, LK_ERR_RANGE, "point 1 has splat radius");
    }
    points.radii[1] = kept;
    points.normals[5] = NAN;
    expect_refusal(renderer, &points, &options, LK_ERR_RANGE, "non-finite normal");
    points.normals[5] = 0;
    expect_refusal(renderer, &points, &options, LK_ERR_RANGE, "zero normal");
    points.normals[5] = 1;
    points.positions[6] = INFINITY;
    expect_refusal(renderer, &points, &options, LK_ERR_RANGE, "point 2 has a non-finite position");
    points.positions[6] = 2;

    float *normals = points.normals;
    points.normals = NULL;
    expect_refusal(renderer, &points, &options, LK_ERR_INVALID, "--estimate-normals");
    points.normals = normals;

    size_t count = points.vertex_count;
    points.vertex_count = 0;
    expect_refusal(renderer, &points, &options, LK_ERR_INVALID, "no points");
    points.vertex_count = count;

    options.passes = 3;
    expect_refusal(renderer, &points, &options, LK_ERR_INVALID, "passes must be 1 or 2");
    options.passes = 0;
    expect_refusal(renderer, &points, &options, LK_ERR_INVALID, "passes must be 1 or 2");
    options.passes = 1;
    options.radius_scale = 0;
    expect_refusal(renderer, &points, &options, LK_ERR_INVALID, "radius scale");
    options.radius_scale = NAN;
    expect_refusal(renderer, &points, &options, LK_ERR_INVALID, "radius scale");
    options.radius_scale = 1;
    options.depth_epsilon = -1;
    expect_refusal(renderer, &points, &options, LK_ERR_INVALID, "epsilon");
    options.depth_epsilon = 1;
    expect_refusal(renderer, NULL, &options, LK_ERR_INVALID, "no point set");
    assert_int_equal(lk_render_points(NULL, &points, &options, NULL, &error), LK_ERR_INVALID);

    /* Without radii: estimated, also for coincident points (a tiny
     * fallback radius from lk_points_estimate_radii). */
    float *radii = points.radii;
    points.radii = NULL;
    assert_int_equal(lk_render_points(renderer, &points, NULL, NULL, &error), LK_OK);
    assert_null(points.radii); /* the caller's set is not modified */
    for (int i = 0; i < 3; i++) points.positions[3 * i] = 0;
    assert_int_equal(lk_render_points(renderer, &points, &options, NULL, &error), LK_OK);
    points.radii = radii;

    /* still usable after the refusals */
    for (int i = 0; i < 3; i++) points.positions[3 * i] = (float)i;
    assert_int_equal(lk_render_points(renderer, &points, &options, NULL, &error), LK_OK);
    uint64_t fragments = 0;
    assert_int_equal(lk__splat_count_fragments(renderer, &points, &options, &fragments, &error), LK_OK);
    assert_true(fragments > 0);
    lk_mesh_free(&points);
    lk_renderer_free(renderer);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bunny_splats_cover_the_mesh),
        cmocka_unit_test(test_stray_points_stay_small),
        cmocka_unit_test(test_two_pass_flattens_a_uniform_patch),
        cmocka_unit_test(test_culling_halves_the_fragments),
        cmocka_unit_test(test_sprite_size_follows_equation_1),
        cmocka_unit_test(test_kitten_xyz),
        cmocka_unit_test(test_hippo_ply),
        cmocka_unit_test(test_deterministic_and_options),
        cmocka_unit_test(test_rgba8_fallback_close_to_float),
        cmocka_unit_test(test_bad_input),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
