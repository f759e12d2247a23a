/* SPDX-License-Identifier: MIT */
/* Textured scenes (lk_render_scene, src/gl/scene_draw.c and
 * texture_image.c): a sphere mapped with a red and blue checkerboard (a PNG
 * written here, and the same as a JPEG) is drawn with its texture; after
 * lk_scene_simplify to 20% the same camera sees the same checkerboard
 * (texture coverage: the colour class of each pixel agrees), while the
 * simplified sphere with its texture coordinates shifted by one square
 * (a control: red and blue swap) does not. Images that cannot be
 * decoded are drawn untextured and reported. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* after stdio.h and stddef.h, which it needs */
#include <jpeglib.h>

#include "shapes.h"

#define SIZE 200u
#define CHECKER 8 /* squares per side of the texture */

static char *copy_text(const char *text)
{
    char *copy = malloc(strlen(text) + 1);
    assert_non_null(copy);
    strcpy(copy, text);
    return copy;
}

static unsigned char *checker_rgba(unsigned side)
{
    unsigned char *rgba = malloc((size_t)side * side * 4);
    assert_non_null(rgba);
    for (unsigned y = 0; y < side; y++)
        for (unsigned x = 0; x < side; x++) {
            bool red = ((x * CHECKER / side) + (y * CHECKER / side)) % 2 == 0;
            unsigned char *p = rgba + 4 * ((size_t)y * side + x);
            p[0] = red ? 230 : 20, p[1] = 30, p[2] = red ? 20 : 230, p[3] = 255;
        }
    return rgba;
}

static unsigned char *file_bytes(const char *path, size_t *size)
{
    FILE *file = fopen(path, "rb");
    assert_non_null(file);
    fseek(file, 0, SEEK_END);
    long length = ftell(file);
    fseek(file, 0, SEEK_SET);
    unsigned char *bytes = malloc((size_t)length);
    assert_non_null(bytes);
    assert_int_equal(fread(bytes, 1, (size_t)length, file), (size_t)length);
    fclose(file);
    *size = (size_t)length;
    return bytes;
}

static unsigned char *checker_png(size_t *size)
{
    unsigned char *rgba = checker_rgba(256);
    const char *path = lk_test_tmpfile("checker.png");
    lk_error error = {0};
    assert_int_equal(lk_image_write_png(path, rgba, 256, 256, &error), LK_OK);
    free(rgba);
    return file_bytes(path, size);
}

static unsigned char *checker_jpeg(size_t *size)
{
    unsigned char *rgba = checker_rgba(256);
    struct jpeg_compress_struct info;
    struct jpeg_error_mgr errors;
    info.err = jpeg_std_error(&errors);
    jpeg_create_compress(&info);
    unsigned char *out = NULL;
    unsigned long out_size = 0;
    jpeg_mem_dest(&info, &out, &out_size);
    info.image_width = info.image_height = 256;
    info.input_components = 4;
    info.in_color_space = JCS_EXT_RGBA;
    jpeg_set_defaults(&info);
    jpeg_set_quality(&info, 90, TRUE);
    jpeg_start_compress(&info, TRUE);
    while (info.next_scanline < 256) {
        JSAMPROW row = rgba + (size_t)info.next_scanline * 256 * 4;
        jpeg_write_scanlines(&info, &row, 1);
    }
    jpeg_finish_compress(&info);
    jpeg_destroy_compress(&info);
    free(rgba);
    *size = (size_t)out_size;
    return out;
}

/* One node, one textured sphere (a (slices+1) x (stacks+1) grid with a
 * seam), one material using texture 0 of image 0 (the given bytes). */
static void textured_sphere_scene(lk_scene *scene, unsigned char *image, size_t image_size, const char *mime)
{
    const unsigned slices = 64, stacks = 32;
    lk_scene_init(scene);
    scene->nodes = calloc(1, sizeof *scene->nodes);
    scene->roots = calloc(1, sizeof *scene->roots);
    scene->meshes = calloc(1, sizeof *scene->meshes);
    lk_scene_primitive *primitive = calloc(1, sizeof *primitive);
    assert_true(scene->nodes && scene->roots && scene->meshes && primitive);
    scene->node_count = scene->root_count = scene->mesh_count = 1;
    lk_scene_node *node = &scene->nodes[0];
    node->mesh = 0, node->camera = -1;
    node->rotation[3] = 1;
    for (int k = 0; k < 3; k++) node->scale[k] = 1;
    for (int k = 0; k < 4; k++) node->matrix[5 * k] = 1;
    scene->meshes[0].primitives = primitive;
    scene->meshes[0].primitive_count = 1;
    primitive->material = 0;
    shape_textured_sphere(&primitive->mesh, slices, stacks, NULL);
    scene->material_count = scene->texture_count = scene->image_count = 1;
    scene->materials = calloc(1, sizeof *scene->materials);
    scene->textures = calloc(1, sizeof *scene->textures);
    scene->images = calloc(1, sizeof *scene->images);
    assert_true(scene->materials && scene->textures && scene->images);
    scene->materials[0].json = copy_text("{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}");
    for (int k = 0; k < 4; k++) scene->materials[0].base_color[k] = 1;
    scene->materials[0].base_color_texture = 0;
    scene->textures[0].json = copy_text("{\"source\":0}");
    scene->textures[0].image = 0, scene->textures[0].sampler = -1;
    scene->images[0].data = image;
    scene->images[0].size = image_size;
    scene->images[0].mime_type = copy_text(mime);
}

enum { BACKGROUND, RED, BLUE, OTHER };

/* Each pixel's class: the background (white), a red or a blue square (lit:
 * only the ratio of red to blue says which), or neither (a seam's blend). */
static unsigned char *classify(const unsigned char *rgba)
{
    unsigned char *classes = malloc(SIZE * SIZE);
    assert_non_null(classes);
    for (size_t i = 0; i < SIZE * SIZE; i++) {
        const unsigned char *p = rgba + 4 * i;
        if (p[0] == 255 && p[1] == 255 && p[2] == 255)
            classes[i] = BACKGROUND;
        else if (p[0] > 2 * p[2] + 10)
            classes[i] = RED;
        else if (p[2] > 2 * p[0] + 10)
            classes[i] = BLUE;
        else
            classes[i] = OTHER;
    }
    return classes;
}

static unsigned char *draw(lk_renderer *renderer, const lk_scene *scene, const lk_render_options *options,
                           lk_render_scene_info *info)
{
    lk_error error = {0};
    lk_render_stats stats;
    if (lk_render_scene(renderer, scene, options, &stats, info, &error) != LK_OK)
        fail_msg("lk_render_scene: %s", error.message);
    unsigned char *rgba = malloc(SIZE * SIZE * 4);
    assert_non_null(rgba);
    assert_int_equal(lk_renderer_read_pixels(renderer, rgba, &error), LK_OK);
    unsigned char *classes = classify(rgba);
    free(rgba);
    return classes;
}

/* Share of the pixels covered in both pictures whose class agrees. */
static double agreement(const unsigned char *a, const unsigned char *b)
{
    size_t both = 0, same = 0;
    for (size_t i = 0; i < SIZE * SIZE; i++) {
        if (a[i] == BACKGROUND || b[i] == BACKGROUND) continue;
        both++;
        same += a[i] == b[i];
    }
    return both ? (double)same / (double)both : 0.0;
}

static size_t count_class(const unsigned char *classes, int which)
{
    size_t count = 0;
    for (size_t i = 0; i < SIZE * SIZE; i++) count += classes[i] == which;
    return count;
}

static void check_texture_survives(unsigned char *image, size_t image_size, const char *mime)
{
    lk_renderer *renderer = NULL;
    lk_error error = {0};
    if (lk_renderer_create(SIZE, SIZE, &renderer, &error) != LK_OK) fail_msg("lk_renderer_create: %s", error.message);
    lk_scene scene;
    textured_sphere_scene(&scene, image, image_size, mime);
    lk_render_options options;
    lk_render_options_default(&options);
    /* one camera for every picture: the original's box */
    options.use_bounds = 1;
    lk_mesh_bounds(&scene.meshes[0].primitives[0].mesh, options.bounds_min, options.bounds_max);
    options.elevation = 20;
    options.azimuth = 90; /* the seam (u = 0 and 1) in view */
    lk_render_scene_info info;
    unsigned char *before = draw(renderer, &scene, &options, &info);
    assert_int_equal(info.materials, 1);
    assert_int_equal(info.textures_drawn, 1);
    assert_int_equal(info.textures_failed, 0);
    size_t red = count_class(before, RED), blue = count_class(before, BLUE);
    size_t covered = SIZE * SIZE - count_class(before, BACKGROUND);
    print_message("%s: %zu pixels covered, %zu red, %zu blue\n", mime, covered, red, blue);
    /* the checkerboard is there: both colours, each a fair share */
    assert_true(red > covered / 4 && blue > covered / 4);

    lk_simplify_options simplify;
    lk_simplify_options_default(&simplify);
    simplify.target_ratio = 0.2;
    lk_scene_simplify_stats stats;
    assert_int_equal(lk_scene_simplify(&scene, LK_SIMPLIFY_QEM, &simplify, &stats, &error), LK_OK);
    assert_true(stats.triangles_out <= stats.triangles_in / 5 + 1);
    unsigned char *after = draw(renderer, &scene, &options, &info);
    double kept = agreement(before, after);
    /* the control: texture coordinates one square off (red and blue swap) */
    lk_mesh *mesh = &scene.meshes[0].primitives[0].mesh;
    for (size_t v = 0; v < mesh->vertex_count; v++) mesh->texcoords[2 * v] += 1.0f / CHECKER;
    unsigned char *shifted = draw(renderer, &scene, &options, &info);
    double lost = agreement(before, shifted);
    print_message("%s at 20%% (%zu triangles): %.1f%% of the pixels keep their colour; texture shifted: %.1f%%\n", mime,
                  stats.triangles_out, 100 * kept, 100 * lost);
    /* 20% moves the squares' edges a little (fewer, larger triangles
     * interpolate the mapping linearly); a mapping that broke would match
     * no better than the swapped colours */
    assert_true(kept > 0.7);
    assert_true(lost < 0.3);
    free(before), free(after), free(shifted);
    lk_scene_free(&scene);
    lk_renderer_free(renderer);
}

static void test_png_texture_survives_simplification(void **state)
{
    (void)state;
    size_t size;
    unsigned char *png = checker_png(&size);
    check_texture_survives(png, size, "image/png");
}

static void test_jpeg_texture_survives_simplification(void **state)
{
    (void)state;
    size_t size;
    unsigned char *jpeg = checker_jpeg(&size);
    /* the scene frees its images with free(): copy out of libjpeg's buffer */
    unsigned char *copy = malloc(size);
    assert_non_null(copy);
    memcpy(copy, jpeg, size);
    free(jpeg);
    check_texture_survives(copy, size, "image/jpeg");
}

/* Images that cannot be decoded: drawn untextured (the material's base
 * colour), counted, the first reason kept. */
static void test_undecodable_images(void **state)
{
    (void)state;
    lk_renderer *renderer = NULL;
    lk_error error = {0};
    if (lk_renderer_create(SIZE, SIZE, &renderer, &error) != LK_OK) fail_msg("lk_renderer_create: %s", error.message);
    size_t size;
    unsigned char *png = checker_png(&size);
    static const struct {
        size_t keep;         /* bytes of the PNG kept (0: garbage instead) */
        const char *message; /* in first_failure */
    } cases[] = {{0, "not a PNG or JPEG image"}, {40, "PNG: "}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        size_t length = cases[c].keep ? cases[c].keep : 64;
        unsigned char *bytes = malloc(length);
        assert_non_null(bytes);
        if (cases[c].keep)
            memcpy(bytes, png, length);
        else
            memset(bytes, 0x5A, length);
        lk_scene scene;
        textured_sphere_scene(&scene, bytes, length, "image/png");
        lk_render_scene_info info;
        unsigned char *classes = draw(renderer, &scene, NULL, &info);
        assert_int_equal(info.textures_drawn, 0);
        assert_int_equal(info.textures_failed, 1);
        if (!strstr(info.first_failure, cases[c].message))
            fail_msg("first_failure \"%s\" lacks \"%s\"", info.first_failure, cases[c].message);
        /* drawn white-lit (the base colour 1), not red or blue */
        assert_int_equal(count_class(classes, RED) + count_class(classes, BLUE), 0);
        assert_true(count_class(classes, BACKGROUND) < SIZE * SIZE);
        free(classes);
        lk_scene_free(&scene);
    }
    /* a cut JPEG */
    unsigned char *jpeg = checker_jpeg(&size);
    unsigned char *cut = malloc(200);
    assert_non_null(cut);
    memcpy(cut, jpeg, 200);
    free(jpeg);
    lk_scene scene;
    textured_sphere_scene(&scene, cut, 200, "image/jpeg");
    lk_render_scene_info info;
    free(draw(renderer, &scene, NULL, &info));
    assert_int_equal(info.textures_failed + info.textures_drawn, 1);
    if (info.textures_failed) assert_non_null(strstr(info.first_failure, "JPEG: "));
    lk_scene_free(&scene);
    free(png);
    lk_renderer_free(renderer);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_png_texture_survives_simplification),
        cmocka_unit_test(test_jpeg_texture_survives_simplification),
        cmocka_unit_test(test_undecodable_images),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
