/* SPDX-License-Identifier: MIT */
/* Pictures: image size and camera options, and the offscreen render of a
 * mesh or point set into a PNG (render, splat, terrain --png). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

/* "800x600" -> 800, 600 (each 1..8192). */
int parse_image_size(const char *text, unsigned *width, unsigned *height)
{
    char *end;
    errno = 0;
    if (text[0] < '0' || text[0] > '9') return 0;
    unsigned long w = strtoul(text, &end, 10);
    if (errno || (*end != 'x' && *end != 'X')) return 0;
    const char *rest = end + 1;
    if (rest[0] < '0' || rest[0] > '9') return 0;
    unsigned long h = strtoul(rest, &end, 10);
    if (errno || *end != '\0' || w < 1 || h < 1 || w > 8192 || h > 8192) return 0;
    *width = (unsigned)w;
    *height = (unsigned)h;
    return 1;
}

int parse_view_option(const char *text, lk_render_options *options)
{
    double view[3];
    if (!parse_vector3(text, view) || view[2] < 0) return 0;
    options->azimuth = view[0];
    options->elevation = view[1];
    options->distance = view[2];
    return 1;
}

int parse_background_option(const char *text, lk_render_options *options)
{
    double vector[3];
    if (!parse_vector3(text, vector)) return 0;
    int bytes = vector[0] > 1 || vector[1] > 1 || vector[2] > 1; /* 0..255 given */
    float colour[3];
    for (int k = 0; k < 3; k++) {
        double value = bytes ? vector[k] / 255.0 : vector[k];
        if (value < 0 || value > 1) return -1;
        colour[k] = (float)value;
    }
    memcpy(options->background, colour, sizeof colour);
    return 1;
}

/* The camera options render and splat share; 1 when ID is one of them
 * (*exit_code gets -1, or the exit code when its value is refused). */
int camera_option(cli_parser *parser, int id, lk_render_options *options, unsigned *width, unsigned *height,
                  int *exit_code)
{
    const char *command = cli_commands[parser->command].name, *arg = parser->value;
    size_t passes;
    *exit_code = -1;
    switch (id) {
    case OPT_SIZE:
        if (!parse_image_size(arg, width, height))
            *exit_code = usage_error(command, "--size: '%s' is not WxH with sides from 1 to 8192", arg);
        return 1;
    case OPT_VIEW:
        if (!parse_view_option(arg, options))
            *exit_code = usage_error(command, "--view: '%s' is not azimuth,elevation,distance (distance >= 0)", arg);
        return 1;
    case OPT_UP:
        if (!parse_axis_letter(arg, &options->up_axis))
            *exit_code = usage_error(command, "--up: '%s' is not x, y or z", arg);
        return 1;
    case OPT_BACKGROUND: {
        int parsed = parse_background_option(arg, options);
        if (parsed == 0) *exit_code = usage_error(command, "--background: '%s' is not r,g,b", arg);
        if (parsed < 0)
            *exit_code = usage_error(command, "--background: '%s' has a channel outside 0..1 (or 0..255)", arg);
        return 1;
    }
    case OPT_PASSES:
        if (!parse_size_option(arg, &passes) || passes < 1 || passes > 2)
            *exit_code = usage_error(command, "--passes: '%s' is not 1 or 2", arg);
        else
            options->passes = (unsigned)passes;
        return 1;
    case OPT_NO_CULLING: options->backface_culling = 0; return 1;
    case OPT_NO_CLIP: options->clip_borders = 0; return 1;
    case OPT_FLAT_POINTS: options->flat_points = 1; return 1;
    default: return 0;
    }
}

lk_status render_to_png(const lk_mesh *mesh, int points, unsigned width, unsigned height,
                        const lk_render_options *options, const char *path, lk_render_stats *stats, char *renderer_name,
                        size_t renderer_name_size, lk_error *error)
{
    return render_any_to_png(mesh, NULL, points, width, height, options, path, stats, NULL, renderer_name,
                             renderer_name_size, error);
}

lk_status render_any_to_png(const lk_mesh *mesh, const lk_scene *scene, int points, unsigned width, unsigned height,
                            const lk_render_options *options, const char *path, lk_render_stats *stats,
                            lk_render_scene_info *info, char *renderer_name, size_t renderer_name_size, lk_error *error)
{
    lk_renderer *renderer = NULL;
    lk_status status = lk_renderer_create(width, height, &renderer, error);
    if (status == LK_OK && renderer_name)
        snprintf(renderer_name, renderer_name_size, "%s", lk_renderer_description(renderer));
    if (status == LK_OK)
        status = scene    ? lk_render_scene(renderer, scene, options, stats, info, error)
                 : points ? lk_render_points(renderer, mesh, options, stats, error)
                          : lk_render_mesh(renderer, mesh, options, stats, error);
    if (status == LK_OK) status = write_framebuffer_png(renderer, path, error);
    lk_renderer_free(renderer);
    return status;
}

lk_status write_framebuffer_png(const lk_renderer *renderer, const char *path, lk_error *error)
{
    unsigned width, height;
    lk_renderer_size(renderer, &width, &height);
    unsigned char *pixels = malloc_array((size_t)width * height, 4);
    if (!pixels) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a %ux%u image", width, height);
    lk_status status = lk_renderer_read_pixels(renderer, pixels, error);
    if (status == LK_OK) status = lk_image_write_png(path, pixels, width, height, error);
    free(pixels);
    return status;
}
