/* SPDX-License-Identifier: MIT */
/* Offscreen mesh rendering (src/gl): context life cycle, camera framing,
 * image orientation, indexed vs strip vs wireframe drawing on the sample
 * models, the 16-bit / expanded index paths, PNG output and bad input. */
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testutil.h"

/* Test hook of src/gl/mesh_draw.c: 1 = 32-bit indices, 2 = as a driver
 * without GL_OES_element_index_uint (16-bit, else expanded), 3 = expanded
 * vertices with glDrawArrays. */
lk_status lk__render_mesh_index_mode(lk_renderer *renderer, const lk_mesh *mesh, const lk_render_options *options,
                                     int index_mode, lk_render_stats *stats, lk_error *error);

#define SIZE 256u

static lk_renderer *create_renderer(unsigned width, unsigned height)
{
    lk_renderer *renderer = NULL;
    lk_error error = {0};
    if (lk_renderer_create(width, height, &renderer, &error) != LK_OK)
        fail_msg("lk_renderer_create: %s", error.message);
    return renderer;
}

static unsigned char *read_pixels(lk_renderer *renderer)
{
    unsigned width, height;
    lk_renderer_size(renderer, &width, &height);
    unsigned char *rgba = malloc((size_t)width * height * 4);
    assert_non_null(rgba);
    lk_error error = {0};
    if (lk_renderer_read_pixels(renderer, rgba, &error) != LK_OK) fail_msg("read_pixels: %s", error.message);
    return rgba;
}

/* Draws and reads back; fails the test on any error. */
static unsigned char *render(lk_renderer *renderer, const lk_mesh *mesh, const lk_render_options *options,
                             lk_render_stats *stats)
{
    lk_error error = {0};
    if (lk_render_mesh(renderer, mesh, options, stats, &error) != LK_OK) fail_msg("render: %s", error.message);
    return read_pixels(renderer);
}

static int is_background(const unsigned char *pixel)
{
    return pixel[0] == 255 && pixel[1] == 255 && pixel[2] == 255; /* default white */
}

static size_t count_foreground(const unsigned char *rgba, unsigned width, unsigned height)
{
    size_t count = 0;
    for (size_t i = 0; i < (size_t)width * height; i++) count += !is_background(rgba + 4 * i);
    return count;
}

/* Pixels whose colour differs by more than `tolerance` in any channel. */
static size_t count_different(const unsigned char *a, const unsigned char *b, size_t pixel_count, int tolerance)
{
    size_t count = 0;
    for (size_t i = 0; i < pixel_count; i++)
        for (int c = 0; c < 4; c++)
            if (abs((int)a[4 * i + c] - (int)b[4 * i + c]) > tolerance) {
                count++;
                break;
            }
    return count;
}

/* Bounding box of the foreground: x0, y0, x1, y1 inclusive (top row 0). */
static void foreground_box(const unsigned char *rgba, unsigned width, unsigned height, int box[4])
{
    box[0] = (int)width, box[1] = (int)height, box[2] = -1, box[3] = -1;
    for (unsigned y = 0; y < height; y++)
        for (unsigned x = 0; x < width; x++)
            if (!is_background(rgba + 4 * ((size_t)y * width + x))) {
                if ((int)x < box[0]) box[0] = (int)x;
                if ((int)y < box[1]) box[1] = (int)y;
                if ((int)x > box[2]) box[2] = (int)x;
                if ((int)y > box[3]) box[3] = (int)y;
            }
}

/* Saves into the test's temporary directory (removed at exit), and also
 * into $LK_TEST_RENDER_DIR when set, to look at the pictures. */
static void save_png(const char *name, const unsigned char *rgba, unsigned width, unsigned height)
{
    lk_error error = {0};
    if (lk_image_write_png(lk_test_tmpfile(name), rgba, width, height, &error) != LK_OK)
        fail_msg("png: %s", error.message);
    const char *keep = getenv("LK_TEST_RENDER_DIR");
    if (keep && *keep) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", keep, name);
        if (lk_image_write_png(path, rgba, width, height, &error) != LK_OK) fail_msg("png: %s", error.message);
    }
}

/* ---- context ------------------------------------------------------------ */

static void test_renderer_lifecycle(void **state)
{
    (void)state;
    /* Several renderers, two of them alive at once, in one process: the
     * shared EGL display must survive the first free. */
    for (int round = 0; round < 3; round++) {
        lk_renderer *a = create_renderer(32, 16), *b = create_renderer(8, 8);
        unsigned width = 0, height = 0;
        lk_renderer_size(a, &width, &height);
        assert_int_equal(width, 32);
        assert_int_equal(height, 16);
        assert_non_null(strstr(lk_renderer_description(a), "OpenGL ES"));
        lk_renderer_free(b);
        lk_mesh cube;
        lk_test_make_cube(&cube);
        unsigned char *rgba = render(a, &cube, NULL, NULL);
        assert_true(count_foreground(rgba, 32, 16) > 50);
        free(rgba);
        lk_mesh_free(&cube);
        lk_renderer_free(a);
    }
    lk_renderer_free(NULL);
}

/* Without a usable driver the renderer fails cleanly, naming the Debian
 * packages to install. Run in a child process whose Mesa is pointed at an
 * empty driver directory (the parent's EGL state stays untouched). */
static void test_renderer_without_driver(void **state)
{
    (void)state;
    fflush(NULL);
    pid_t child = fork();
    assert_true(child >= 0);
    if (child == 0) {
        setenv("LIBGL_DRIVERS_PATH", "/nonexistent-lodkit-test", 1);
        setenv("EGL_LOG_LEVEL", "fatal", 1); /* Mesa's own warning on stderr */
        lk_renderer *renderer = NULL;
        lk_error error = {0};
        lk_status status = lk_renderer_create(16, 16, &renderer, &error);
        int ok = status == LK_ERR_UNSUPPORTED && renderer == NULL && strstr(error.message, "libgl1-mesa-dri") &&
                 strstr(error.message, "libegl-mesa0");
        if (!ok) fprintf(stderr, "status %d: %s\n", (int)status, error.message);
        lk_renderer_free(renderer);
        _exit(ok ? 0 : 1);
    }
    int child_status = 0;
    assert_int_equal(waitpid(child, &child_status, 0), child);
    assert_true(WIFEXITED(child_status));
    assert_int_equal(WEXITSTATUS(child_status), 0);
}

static void test_renderer_bad_sizes(void **state)
{
    (void)state;
    lk_renderer *renderer = (lk_renderer *)&renderer;
    lk_error error = {0};
    assert_int_equal(lk_renderer_create(0, 16, &renderer, &error), LK_ERR_INVALID);
    assert_null(renderer);
    lk_assert_message_contains(error, "0x16");
    assert_int_equal(lk_renderer_create(16, 0, &renderer, &error), LK_ERR_INVALID);
    assert_int_equal(lk_renderer_create(8193, 16, &renderer, &error), LK_ERR_INVALID);
    assert_int_equal(lk_renderer_create(16, 16, NULL, &error), LK_ERR_INVALID);
    /* The smallest and a non-square size work. */
    renderer = create_renderer(1, 1);
    lk_renderer_free(renderer);
    renderer = create_renderer(300, 7);
    lk_renderer_free(renderer);
}

/* ---- camera and image orientation -------------------------------------- */

/* A unit cube seen head-on (azimuth 0, elevation 0) from the framing
 * distance: only its front face (z = 1) shows, as a centred square whose
 * size follows from the camera formula: distance d = 1.05 r / sin(fov/2)
 * with r = sqrt(3)/2, front face at d - 1/2, half side in NDC
 * 0.5 / (d - 0.5) / tan(fov/2). */
static void test_camera_frames_cube(void **state)
{
    (void)state;
    lk_renderer *renderer = create_renderer(SIZE, SIZE);
    lk_mesh cube;
    lk_test_make_cube(&cube);
    lk_render_options options;
    lk_render_options_default(&options);
    options.azimuth = 0;
    options.elevation = 0;
    unsigned char *rgba = render(renderer, &cube, &options, NULL);
    int box[4];
    foreground_box(rgba, SIZE, SIZE, box);
    double half_fov = 17.5 * 3.14159265358979 / 180;
    double distance = 1.05 * (sqrt(3.0) / 2) / sin(half_fov);
    double half_ndc = 0.5 / (distance - 0.5) / tan(half_fov);
    double left = (1 - half_ndc) * SIZE / 2, right = (1 + half_ndc) * SIZE / 2;
    print_message("cube box x %d..%d y %d..%d, expected %.1f..%.1f\n", box[0], box[2], box[1], box[3], left, right);
    assert_true(fabs(box[0] - left) <= 1.0);
    assert_true(fabs(box[2] + 1 - right) <= 1.0);
    assert_true(fabs(box[1] - left) <= 1.0);
    assert_true(fabs(box[3] + 1 - right) <= 1.0);
    /* Filled: the square's area within a one-pixel rim. */
    double side = right - left;
    size_t count = count_foreground(rgba, SIZE, SIZE);
    assert_true(fabs((double)count - side * side) <= 4 * side);
    /* The face looks straight at the headlight: bright and uniform. */
    const unsigned char *centre = rgba + 4 * ((size_t)(SIZE / 2) * SIZE + SIZE / 2);
    assert_true(centre[0] > 150);
    free(rgba);

    /* A distance of 2 radii is closer than the framing one: bigger square. */
    options.distance = 2.0;
    rgba = render(renderer, &cube, &options, NULL);
    int near_box[4];
    foreground_box(rgba, SIZE, SIZE, near_box);
    assert_true(near_box[2] - near_box[0] > box[2] - box[0] + 20);
    free(rgba);

    /* Looking straight down (elevation 90) is a valid camera too: the top
     * face, the same square. */
    options.distance = 0;
    options.elevation = 90;
    rgba = render(renderer, &cube, &options, NULL);
    int top_box[4];
    foreground_box(rgba, SIZE, SIZE, top_box);
    assert_true(abs(top_box[0] - box[0]) <= 1 && abs(top_box[2] - box[2]) <= 1);
    assert_true(abs(top_box[1] - box[1]) <= 1 && abs(top_box[3] - box[3]) <= 1);
    free(rgba);
    lk_mesh_free(&cube);
    lk_renderer_free(renderer);
}

/* A rectangle only in y > 0 of a view framed on [-1,1]^2 must come out in
 * the top half of the image (read_pixels returns the top row first), and one
 * only at x > 0 in the right half. */
static void test_read_pixels_orientation(void **state)
{
    (void)state;
    static const float positions[12] = {-0.9f, 0.1f, 0, 0.9f, 0.1f, 0, 0.9f, 0.9f, 0, -0.9f, 0.9f, 0};
    static const uint32_t indices[6] = {0, 1, 2, 0, 2, 3};
    lk_mesh upper;
    lk_test_make_mesh(&upper, positions, 4, indices, 2);
    lk_renderer *renderer = create_renderer(64, 48);
    lk_render_options options;
    lk_render_options_default(&options);
    options.azimuth = 0;
    options.elevation = 0;
    options.use_bounds = 1;
    options.bounds_min[0] = options.bounds_min[1] = -1;
    options.bounds_max[0] = options.bounds_max[1] = 1;
    unsigned char *rgba = render(renderer, &upper, &options, NULL);
    size_t top = 0, bottom = 0;
    for (unsigned y = 0; y < 48; y++)
        for (unsigned x = 0; x < 64; x++)
            if (!is_background(rgba + 4 * ((size_t)y * 64 + x))) *(y < 24 ? &top : &bottom) += 1;
    assert_true(top > 200);
    assert_int_equal(bottom, 0);
    free(rgba);

    /* Same shape turned on its side: x in [0.1, 0.9] only. */
    lk_mesh right;
    lk_test_make_mesh(&right, positions, 4, indices, 2);
    for (size_t v = 0; v < 4; v++) {
        float x = right.positions[3 * v], y = right.positions[3 * v + 1];
        right.positions[3 * v] = y;
        right.positions[3 * v + 1] = -x;
    }
    rgba = render(renderer, &right, &options, NULL);
    size_t left_count = 0, right_count = 0;
    for (unsigned y = 0; y < 48; y++)
        for (unsigned x = 0; x < 64; x++)
            if (!is_background(rgba + 4 * ((size_t)y * 64 + x))) *(x < 32 ? &left_count : &right_count) += 1;
    assert_true(right_count > 200);
    assert_int_equal(left_count, 0);
    free(rgba);
    lk_mesh_free(&upper);
    lk_mesh_free(&right);
    lk_renderer_free(renderer);
}

/* ---- the sample models ------------------------------------------------- */

/* Foreground of the bunny at 256x256 with the default view, measured
 * (llvmpipe, Mesa 22.3): 13,747 pixels. The band allows for rasterisation
 * differences between drivers but not for a wrong camera (a 5% change of
 * scale moves the count by ~10%). */
#define BUNNY_FOREGROUND_MIN 13100
#define BUNNY_FOREGROUND_MAX 14400

static void test_bunny(void **state)
{
    (void)state;
    lk_mesh bunny;
    lk_test_load(lk_test_sample("bunny.obj"), &bunny);
    lk_renderer *renderer = create_renderer(SIZE, SIZE);
    lk_render_stats stats;
    unsigned char *rgba = render(renderer, &bunny, NULL, &stats);
    assert_int_equal(stats.primitives, 69666);
    assert_int_equal(stats.indices, 3 * 69666);
    assert_true(stats.milliseconds > 0);
    size_t foreground = count_foreground(rgba, SIZE, SIZE);
    print_message("bunny: %zu foreground pixels, %.1f ms\n", foreground, stats.milliseconds);
    assert_in_range(foreground, BUNNY_FOREGROUND_MIN, BUNNY_FOREGROUND_MAX);
    /* The model is framed: the centre region is covered, the border is not. */
    size_t centre = 0;
    for (unsigned y = SIZE / 2 - 16; y < SIZE / 2 + 16; y++)
        for (unsigned x = SIZE / 2 - 16; x < SIZE / 2 + 16; x++)
            centre += !is_background(rgba + 4 * ((size_t)y * SIZE + x));
    assert_true(centre > 32 * 32 * 9 / 10);
    int box[4];
    foreground_box(rgba, SIZE, SIZE, box);
    assert_true(box[0] > 4 && box[1] > 4 && box[2] < (int)SIZE - 5 && box[3] < (int)SIZE - 5);
    /* Lit, not flat: a wide spread of intensities on the surface, none of
     * them pure black (ambient + two-sided lighting). */
    int darkest = 255, brightest = 0;
    for (size_t i = 0; i < (size_t)SIZE * SIZE; i++) {
        const unsigned char *p = rgba + 4 * i;
        if (is_background(p)) continue;
        if (p[0] < darkest) darkest = p[0];
        if (p[0] > brightest) brightest = p[0];
        assert_int_equal(p[3], 255); /* opaque */
    }
    assert_true(darkest > 5 && brightest - darkest > 120);
    save_png("bunny.png", rgba, SIZE, SIZE);
    free(rgba);

    /* Strips draw the same triangles: the image is identical but for the
     * odd pixel where the rasteriser's order or edge rules differ. */
    lk_render_options options;
    lk_render_options_default(&options);
    options.strips = 1;
    rgba = render(renderer, &bunny, &options, &stats);
    unsigned char *indexed = NULL;
    lk_render_options_default(&options);
    indexed = render(renderer, &bunny, &options, NULL);
    size_t differing = count_different(rgba, indexed, (size_t)SIZE * SIZE, 2);
    print_message("bunny strips: %zu indices, %zu primitives, %zu pixels differ from indexed\n", stats.indices,
                  stats.primitives, differing);
    assert_true(stats.indices < 3 * 69666 / 2); /* a strip, not triangles */
    assert_int_equal(stats.primitives, stats.indices - 2);
    assert_true(differing <= 20);
    free(rgba);

    /* The wireframe darkens many pixels inside the silhouette; outside it
     * only the silhouette's own edges may spill over by up to a pixel
     * (measured: 276 pixels, 2% of the foreground). */
    options.wireframe = 1;
    rgba = render(renderer, &bunny, &options, NULL);
    size_t changed = count_different(rgba, indexed, (size_t)SIZE * SIZE, 30);
    size_t outside = 0;
    for (size_t i = 0; i < (size_t)SIZE * SIZE; i++)
        if (is_background(indexed + 4 * i) && !is_background(rgba + 4 * i)) outside++;
    print_message("bunny wireframe: %zu pixels changed, %zu outside the silhouette\n", changed, outside);
    assert_true(changed > foreground / 4);
    assert_true(outside < foreground / 25);
    free(rgba);
    free(indexed);
    lk_renderer_free(renderer);
    lk_mesh_free(&bunny);
}

static void test_triceratops(void **state)
{
    (void)state;
    lk_mesh triceratops;
    lk_test_load(lk_test_sample("triceratops.off"), &triceratops);
    lk_renderer *renderer = create_renderer(SIZE, SIZE);
    lk_render_stats stats;
    unsigned char *rgba = render(renderer, &triceratops, NULL, &stats);
    assert_int_equal(stats.primitives, triceratops.triangle_count);
    size_t foreground = count_foreground(rgba, SIZE, SIZE);
    print_message("triceratops: %zu triangles, %zu foreground pixels, %.1f ms\n", triceratops.triangle_count,
                  foreground, stats.milliseconds);
    /* Long and thin: fills much less of the frame than the bunny. */
    assert_in_range(foreground, 6000, 14000);
    save_png("triceratops.png", rgba, SIZE, SIZE);
    /* From the other side (azimuth + 180) the silhouette is mirrored, so
     * its area is nearly the same. */
    lk_render_options options;
    lk_render_options_default(&options);
    options.azimuth += 180;
    options.elevation = -options.elevation;
    unsigned char *behind = render(renderer, &triceratops, &options, NULL);
    size_t behind_foreground = count_foreground(behind, SIZE, SIZE);
    assert_true(fabs((double)behind_foreground - (double)foreground) < 0.08 * (double)foreground);
    free(behind);
    free(rgba);
    lk_renderer_free(renderer);
    lk_mesh_free(&triceratops);
}

/* Hidden edges stay hidden: the cube seen head-on shows the front face's
 * outline and diagonal, but not the back face's edges (a smaller square
 * inside it, at 0.5 / (d + 0.5) / tan(fov/2) in NDC) nor the side edges. */
static void test_wireframe_hidden_edges(void **state)
{
    (void)state;
    lk_renderer *renderer = create_renderer(SIZE, SIZE);
    lk_mesh cube;
    lk_test_make_cube(&cube);
    lk_render_options options;
    lk_render_options_default(&options);
    options.azimuth = 0;
    options.elevation = 0;
    options.wireframe = 1;
    unsigned char *rgba = render(renderer, &cube, &options, NULL);
    save_png("cube_wireframe.png", rgba, SIZE, SIZE);
    double half_fov = 17.5 * 3.14159265358979 / 180;
    double distance = 1.05 * (sqrt(3.0) / 2) / sin(half_fov);
    int back = (int)((1 - 0.5 / (distance + 0.5) / tan(half_fov)) * SIZE / 2);        /* ~70 */
    int front = (int)((1 - 0.5 / (distance - 0.5) / tan(half_fov)) * SIZE / 2 + 0.5); /* ~48 */
#define DARK(x, y) (rgba[4 * ((size_t)(y)*SIZE + (size_t)(x))] < 80)
    /* The front outline is drawn (left edge, mid-height)... */
    int outline = 0;
    for (int x = front - 1; x <= front + 1; x++) outline |= DARK(x, SIZE / 2 + 10);
    assert_true(outline);
    /* ...and one of the front face's diagonals. */
    int on_diagonal = 0, on_antidiagonal = 0;
    for (int i = 90; i < 110; i++) {
        for (int dx = -1; dx <= 1; dx++) {
            on_diagonal += DARK(i + dx, i);
            on_antidiagonal += DARK(i + dx, SIZE - 1 - i);
        }
    }
    assert_true(on_diagonal >= 18 || on_antidiagonal >= 18);
    /* The back face's left edge (all of its column band) is not. */
    const int size = (int)SIZE;
    for (int y = size / 2 - 20; y < size / 2 + 20; y++)
        for (int x = back - 2; x <= back + 2; x++)
            if (DARK(x, y) && !(on_antidiagonal >= 18 && abs(x - (size - 1 - y)) <= 2) &&
                !(on_diagonal >= 18 && abs(x - y) <= 2))
                fail_msg("hidden edge visible at %d,%d", x, y);
#undef DARK
    free(rgba);
    lk_mesh_free(&cube);
    lk_renderer_free(renderer);
}

/* Every index path draws the same image: 16-bit (automatic for the cow's
 * 2,904 vertices), 32-bit, and expanded vertices (what a driver without
 * GL_OES_element_index_uint gets for big meshes), with and without strips
 * and the wireframe. */
static void test_index_paths(void **state)
{
    (void)state;
    lk_mesh cow;
    lk_test_load(lk_test_sample("cow.off"), &cow);
    lk_renderer *renderer = create_renderer(SIZE, SIZE);
    for (int variant = 0; variant < 3; variant++) {
        lk_render_options options;
        lk_render_options_default(&options);
        options.strips = variant == 1;
        options.wireframe = variant == 2;
        unsigned char *reference = render(renderer, &cow, &options, NULL);
        for (int mode = 1; mode <= 3; mode++) {
            lk_error error = {0};
            lk_render_stats stats;
            if (lk__render_mesh_index_mode(renderer, &cow, &options, mode, &stats, &error) != LK_OK)
                fail_msg("mode %d: %s", mode, error.message);
            unsigned char *rgba = read_pixels(renderer);
            size_t differing = count_different(rgba, reference, (size_t)SIZE * SIZE, 2);
            if (differing > 2) fail_msg("variant %d, index mode %d: %zu pixels differ", variant, mode, differing);
            if (!options.strips) assert_int_equal(stats.indices, 3 * cow.triangle_count);
            free(rgba);
        }
        free(reference);
    }
    lk_renderer_free(renderer);
    lk_mesh_free(&cow);
}

/* Normals and colours stored in the mesh are used. */
static void test_attributes(void **state)
{
    (void)state;
    lk_mesh cube;
    lk_test_make_cube(&cube);
    lk_renderer *renderer = create_renderer(64, 64);
    lk_render_options options;
    lk_render_options_default(&options);
    options.azimuth = 0;
    options.elevation = 0;
    unsigned char *computed = render(renderer, &cube, &options, NULL);
    size_t centre = 4 * (32 * 64 + 32);

    /* Normals perpendicular to the view: the front face turns much darker. */
    lk_mesh sideways;
    lk_test_make_mesh(&sideways, cube.positions, cube.vertex_count, cube.indices, cube.triangle_count);
    sideways.normals = malloc(3 * sizeof(float) * cube.vertex_count);
    assert_non_null(sideways.normals);
    for (size_t v = 0; v < cube.vertex_count; v++) {
        sideways.normals[3 * v] = 0;
        sideways.normals[3 * v + 1] = -1;
        sideways.normals[3 * v + 2] = 0;
    }
    unsigned char *rgba = render(renderer, &sideways, &options, NULL);
    assert_true(rgba[centre] + 60 < computed[centre]);
    free(rgba);

    /* Per-vertex colours: a pure red cube stays red (the channels that are
     * zero stay nearly zero apart from the white highlight). */
    lk_mesh red;
    lk_test_make_mesh(&red, cube.positions, cube.vertex_count, cube.indices, cube.triangle_count);
    red.colors = malloc(4 * sizeof(float) * cube.vertex_count);
    assert_non_null(red.colors);
    for (size_t v = 0; v < cube.vertex_count; v++) {
        red.colors[4 * v] = 1;
        red.colors[4 * v + 1] = red.colors[4 * v + 2] = 0;
        red.colors[4 * v + 3] = 1;
    }
    options.azimuth = 30;
    options.elevation = 20;
    rgba = render(renderer, &red, &options, NULL);
    assert_true(rgba[centre] > 120);
    assert_true(rgba[centre] > rgba[centre + 1] + 60 && rgba[centre] > rgba[centre + 2] + 60);
    free(rgba);

    /* The surface colour option applies when the mesh has none. */
    options.color[0] = 0;
    options.color[1] = 1;
    options.color[2] = 0;
    rgba = render(renderer, &cube, &options, NULL);
    assert_true(rgba[centre + 1] > rgba[centre] + 60 && rgba[centre + 1] > rgba[centre + 2] + 60);
    free(rgba);
    /* And the background colour. */
    options.background[0] = 0.0f;
    options.background[1] = 0.0f;
    options.background[2] = 1.0f;
    rgba = render(renderer, &cube, &options, NULL);
    assert_int_equal(rgba[0], 0);
    assert_int_equal(rgba[2], 255);
    assert_int_equal(rgba[3], 255);
    free(rgba);

    free(computed);
    lk_mesh_free(&red);
    lk_mesh_free(&sideways);
    lk_mesh_free(&cube);
    lk_renderer_free(renderer);
}

/* ---- PNG ---------------------------------------------------------------- */

static unsigned read_be32(const unsigned char *bytes)
{
    return (unsigned)bytes[0] << 24 | (unsigned)bytes[1] << 16 | (unsigned)bytes[2] << 8 | bytes[3];
}

static void test_png(void **state)
{
    (void)state;
    enum { W = 37, H = 23 };
    unsigned char rgba[W * H * 4];
    for (size_t i = 0; i < sizeof rgba; i++) rgba[i] = (unsigned char)(i * 7 + i / 13);
    const char *path = lk_test_tmpfile("pattern.png");
    lk_error error = {0};
    assert_int_equal(lk_image_write_png(path, rgba, W, H, &error), LK_OK);

    FILE *file = fopen(path, "rb");
    assert_non_null(file);
    unsigned char header[33];
    assert_int_equal(fread(header, 1, sizeof header, file), sizeof header);
    static const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    assert_memory_equal(header, signature, 8);
    assert_memory_equal(header + 12, "IHDR", 4);
    assert_int_equal(read_be32(header + 16), W);
    assert_int_equal(read_be32(header + 20), H);
    assert_int_equal(header[24], 8); /* bit depth */
    assert_int_equal(header[25], 6); /* RGBA */
    fclose(file);

    /* Read back with libpng: the same pixels. */
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    assert_true(png_image_begin_read_from_file(&image, path));
    image.format = PNG_FORMAT_RGBA;
    unsigned char back[W * H * 4];
    assert_true(png_image_finish_read(&image, NULL, back, 0, NULL));
    assert_memory_equal(back, rgba, sizeof rgba);

    /* Deterministic: the same pixels give the same bytes. */
    const char *again = lk_test_tmpfile("pattern2.png");
    assert_int_equal(lk_image_write_png(again, rgba, W, H, &error), LK_OK);
    char *first = NULL, *second = NULL;
    size_t first_size = 0, second_size = 0;
    FILE *a = fopen(path, "rb"), *b = fopen(again, "rb");
    assert_true(a && b);
    fseek(a, 0, SEEK_END), fseek(b, 0, SEEK_END);
    first_size = (size_t)ftell(a), second_size = (size_t)ftell(b);
    rewind(a), rewind(b);
    first = malloc(first_size), second = malloc(second_size);
    assert_true(first && second);
    assert_int_equal(fread(first, 1, first_size, a), first_size);
    assert_int_equal(fread(second, 1, second_size, b), second_size);
    assert_int_equal(first_size, second_size);
    assert_memory_equal(first, second, first_size);
    fclose(a), fclose(b);
    free(first), free(second);

    /* Errors: a directory that does not exist (nothing left behind), bad sizes. */
    char missing[4096];
    snprintf(missing, sizeof missing, "%s/no/such/dir/x.png", lk_test_tmpdir());
    assert_int_equal(lk_image_write_png(missing, rgba, W, H, &error), LK_ERR_IO);
    assert_int_equal(lk_image_write_png(path, rgba, 0, H, &error), LK_ERR_INVALID);
    assert_int_equal(lk_image_write_png(path, NULL, W, H, &error), LK_ERR_INVALID);
    /* A special file is not replaced by the rename (think of /dev/null
     * when running as root): a FIFO stands in for a device. */
    const char *fifo = lk_test_tmpfile("fifo.png");
    assert_int_equal(mkfifo(fifo, 0600), 0);
    assert_int_equal(lk_image_write_png(fifo, rgba, W, H, &error), LK_ERR_IO);
    lk_assert_message_contains(error, "not a regular file");
    struct stat fifo_info;
    assert_int_equal(stat(fifo, &fifo_info), 0);
    assert_true(S_ISFIFO(fifo_info.st_mode));
    /* The good file is still there, unchanged in size. */
    struct stat info;
    assert_int_equal(stat(path, &info), 0);
    assert_int_equal((size_t)info.st_size, first_size);
}

/* ---- bad input ---------------------------------------------------------- */

static void test_bad_input(void **state)
{
    (void)state;
    lk_renderer *renderer = create_renderer(32, 32);
    lk_error error = {0};
    lk_render_stats stats;

    /* A point set: the message points to lk_render_points. */
    lk_mesh points;
    lk_test_load(lk_test_sample("kitten.xyz"), &points);
    assert_int_equal(points.triangle_count, 0);
    assert_int_equal(lk_render_mesh(renderer, &points, NULL, &stats, &error), LK_ERR_INVALID);
    lk_assert_message_contains(error, "lk_render_points");
    lk_mesh_free(&points);

    lk_mesh empty;
    lk_mesh_init(&empty);
    assert_int_equal(lk_render_mesh(renderer, &empty, NULL, NULL, &error), LK_ERR_INVALID);
    assert_int_equal(lk_render_mesh(renderer, NULL, NULL, NULL, &error), LK_ERR_INVALID);
    assert_int_equal(lk_render_mesh(NULL, &empty, NULL, NULL, &error), LK_ERR_INVALID);

    /* An index out of range is refused before the driver sees it. */
    lk_mesh cube;
    lk_test_make_cube(&cube);
    cube.indices[5] = 8;
    assert_int_equal(lk_render_mesh(renderer, &cube, NULL, NULL, &error), LK_ERR_RANGE);
    cube.indices[5] = 3;
    /* A NaN position too. */
    float saved = cube.positions[4];
    cube.positions[4] = NAN;
    assert_int_equal(lk_render_mesh(renderer, &cube, NULL, NULL, &error), LK_ERR_RANGE);
    cube.positions[4] = saved;

    /* Bad options. */
    lk_render_options options;
    lk_render_options_default(&options);
    options.fov_y = 0;
    assert_int_equal(lk_render_mesh(renderer, &cube, &options, NULL, &error), LK_ERR_INVALID);
    options.fov_y = 180;
    assert_int_equal(lk_render_mesh(renderer, &cube, &options, NULL, &error), LK_ERR_INVALID);
    lk_render_options_default(&options);
    options.distance = -1;
    assert_int_equal(lk_render_mesh(renderer, &cube, &options, NULL, &error), LK_ERR_INVALID);
    lk_render_options_default(&options);
    options.azimuth = INFINITY;
    assert_int_equal(lk_render_mesh(renderer, &cube, &options, NULL, &error), LK_ERR_INVALID);

    /* Radii on a mesh do not matter for mesh drawing, even invalid ones;
     * and the renderer still works after all the refusals. */
    cube.radii = calloc(cube.vertex_count, sizeof(float));
    assert_non_null(cube.radii);
    unsigned char *rgba = render(renderer, &cube, NULL, NULL);
    assert_true(count_foreground(rgba, 32, 32) > 100);
    free(rgba);
    assert_int_equal(lk_renderer_read_pixels(renderer, NULL, &error), LK_ERR_INVALID);
    lk_mesh_free(&cube);
    lk_renderer_free(renderer);
}

/* The options' defaults are the documented ones. */
/* up_axis z (x) draws a model as y up draws the model turned so that its z
 * (x) is y: the camera orbits the up axis. The default draws it otherwise. */
static void test_up_axis(void **state)
{
    (void)state;
    lk_mesh cow, turned;
    lk_error error = {0};
    if (lk_mesh_read(lk_test_sample("cow.off"), LK_FORMAT_AUTO, NULL, &cow, &error) != LK_OK)
        fail_msg("%s", error.message);
    lk_renderer *renderer = create_renderer(SIZE, SIZE);
    lk_render_options options;
    lk_render_options_default(&options);
    unsigned char *y_up = render(renderer, &cow, &options, NULL);
    for (int axis = LK_AXIS_X; axis <= LK_AXIS_Z; axis += LK_AXIS_Z - LK_AXIS_X) {
        if (lk_mesh_copy(&turned, &cow, &error) != LK_OK) fail_msg("%s", error.message);
        for (size_t v = 0; v < turned.vertex_count; v++) {
            float *p = turned.positions + 3 * v, x = p[0], y = p[1], z = p[2];
            if (axis == LK_AXIS_Z)
                p[0] = x, p[1] = z, p[2] = -y; /* z up -> y up */
            else
                p[0] = -y, p[1] = x, p[2] = z; /* x up -> y up */
        }
        free(turned.normals), turned.normals = NULL; /* the cow has none; face normals follow the turn */
        options.up_axis = axis;
        unsigned char *with_axis = render(renderer, &cow, &options, NULL);
        options.up_axis = LK_AXIS_AUTO;
        unsigned char *turned_y_up = render(renderer, &turned, &options, NULL);
        size_t pixels = (size_t)SIZE * SIZE;
        assert_true(count_foreground(with_axis, SIZE, SIZE) > pixels / 20);
        assert_true(count_different(with_axis, turned_y_up, pixels, 3) < pixels / 500);
        assert_true(count_different(with_axis, y_up, pixels, 3) > pixels / 50);
        free(with_axis);
        free(turned_y_up);
        lk_mesh_free(&turned);
    }
    options.up_axis = LK_AXIS_Y;
    unsigned char *explicit_y = render(renderer, &cow, &options, NULL);
    assert_int_equal(count_different(explicit_y, y_up, (size_t)SIZE * SIZE, 0), 0);
    free(explicit_y);
    free(y_up);
    lk_renderer_free(renderer);
    lk_mesh_free(&cow);
}

static void test_defaults(void **state)
{
    (void)state;
    lk_render_options options;
    memset(&options, 0x5a, sizeof options);
    lk_render_options_default(&options);
    assert_true(options.azimuth == 30 && options.elevation == 20 && options.distance == 0 && options.fov_y == 35);
    assert_int_equal(options.use_bounds, 0);
    assert_true(options.background[0] == 1 && options.background[1] == 1 && options.background[2] == 1);
    assert_true(options.color[2] > options.color[0]); /* grey-blue */
    assert_int_equal(options.wireframe, 0);
    assert_int_equal(options.strips, 0);
    assert_int_equal(options.passes, 1);
    assert_int_equal(options.backface_culling, 1);
    assert_true(options.radius_scale == 1 && options.depth_epsilon == 1);
    assert_int_equal(options.flat_points, 0);
    assert_int_equal(options.up_axis, LK_AXIS_AUTO); /* y up */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_defaults),
        cmocka_unit_test(test_renderer_without_driver),
        cmocka_unit_test(test_renderer_lifecycle),
        cmocka_unit_test(test_renderer_bad_sizes),
        cmocka_unit_test(test_camera_frames_cube),
        cmocka_unit_test(test_read_pixels_orientation),
        cmocka_unit_test(test_bunny),
        cmocka_unit_test(test_triceratops),
        cmocka_unit_test(test_wireframe_hidden_edges),
        cmocka_unit_test(test_index_paths),
        cmocka_unit_test(test_attributes),
        cmocka_unit_test(test_png),
        cmocka_unit_test(test_bad_input),
        cmocka_unit_test(test_up_axis),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
