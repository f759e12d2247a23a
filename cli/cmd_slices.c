/* SPDX-License-Identifier: MIT */
/* lodkit slices: draws the contours of a few slices before and after the
 * wavelet simplification (like Fig. 4 of the planar-sampling paper), as an
 * SVG written by hand or a PNG rasterised here and written with
 * lk_image_write_png. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help slices_help = {
    "IN OUT.svg|OUT.png",
    "Draw the contours of a few slices of a closed mesh before (grey, every\n"
    "sampled point) and after (blue, kept vertices) wavelet simplification.\n",
    NULL,
};

typedef struct canvas {
    FILE *svg;           /* SVG output, or NULL */
    unsigned char *rgba; /* PNG pixels, or NULL */
    unsigned width, height;
} canvas;

typedef struct panel {
    double x0, y0, size;  /* pixel box */
    double min[2], scale; /* model -> pixels */
} panel;

static void to_pixels(const panel *p, const double *point, double *x, double *y)
{
    *x = p->x0 + (point[0] - p->min[0]) * p->scale;
    *y = p->y0 + p->size - (point[1] - p->min[1]) * p->scale; /* v up */
}

static void put_pixel(canvas *c, long x, long y, const unsigned char color[3])
{
    if (x < 0 || y < 0 || x >= (long)c->width || y >= (long)c->height) return;
    unsigned char *pixel = c->rgba + 4 * ((size_t)y * c->width + (size_t)x);
    pixel[0] = color[0];
    pixel[1] = color[1];
    pixel[2] = color[2];
    pixel[3] = 255;
}

static void raster_line(canvas *c, double x0, double y0, double x1, double y1, int thick, const unsigned char color[3])
{
    double steps = fmax(fabs(x1 - x0), fabs(y1 - y0));
    if (steps < 1) steps = 1;
    for (int s = 0; s <= (int)steps; s++) {
        double t = s / steps;
        long x = lround(x0 + t * (x1 - x0)), y = lround(y0 + t * (y1 - y0));
        for (int dx = 0; dx < thick; dx++)
            for (int dy = 0; dy < thick; dy++) put_pixel(c, x + dx, y + dy, color);
    }
}

static void raster_dot(canvas *c, double x, double y, int radius, const unsigned char color[3])
{
    for (int dx = -radius; dx <= radius; dx++)
        for (int dy = -radius; dy <= radius; dy++) put_pixel(c, lround(x) + dx, lround(y) + dy, color);
}

/* Draws every contour of `slice` in `set`. */
static void draw_contours(canvas *c, const panel *p, const lk_slices *set, size_t slice, const char *svg_color,
                          const unsigned char color[3], int thick, int dot)
{
    for (size_t k = 0; k < set->contour_count; k++) {
        const lk_contour *contour = &set->contours[k];
        if (contour->slice != slice) continue;
        const double *points = set->points + 2 * (size_t)contour->first;
        if (c->svg) {
            fprintf(c->svg, "<polygon fill=\"none\" stroke=\"%s\" stroke-width=\"%d\" points=\"", svg_color, thick);
            for (uint32_t i = 0; i < contour->count; i++) {
                double x, y;
                to_pixels(p, points + 2 * i, &x, &y);
                fprintf(c->svg, "%s%.2f,%.2f", i ? " " : "", x, y);
            }
            fprintf(c->svg, "\"/>\n");
            for (uint32_t i = 0; i < contour->count; i++) {
                double x, y;
                to_pixels(p, points + 2 * i, &x, &y);
                fprintf(c->svg, "<circle cx=\"%.2f\" cy=\"%.2f\" r=\"%d\" fill=\"%s\"/>\n", x, y, dot, svg_color);
            }
        } else {
            for (uint32_t i = 0; i < contour->count; i++) {
                double x0, y0, x1, y1;
                to_pixels(p, points + 2 * i, &x0, &y0);
                to_pixels(p, points + 2 * ((i + 1) % contour->count), &x1, &y1);
                raster_line(c, x0, y0, x1, y1, thick, color);
            }
            for (uint32_t i = 0; i < contour->count; i++) {
                double x, y;
                to_pixels(p, points + 2 * i, &x, &y);
                raster_dot(c, x, y, dot, color);
            }
        }
    }
}

static size_t slice_points(const lk_slices *set, size_t slice)
{
    size_t total = 0;
    for (size_t k = 0; k < set->contour_count; k++)
        if (set->contours[k].slice == slice) total += set->contours[k].count;
    return total;
}

int cmd_slices(int argc, char **argv)
{
    size_t slice_count = 150, vertices = 0, count = 4, width = 1200;
    double ratio = 0, max_error = 0;
    lk_axis axis = LK_AXIS_AUTO;
    lk_wavelet_criterion criterion = LK_WAVELET_CRITERION_DEFAULT;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_SLICES, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_SLICES:
            if (!parse_size_option(arg, &slice_count) || slice_count < 2 || slice_count > 1000000)
                return usage_error("slices", "--slices: '%s' is not an integer in 2..1000000", arg);
            break;
        case OPT_AXIS:
            if (!strcmp(arg, "auto"))
                axis = LK_AXIS_AUTO;
            else if (!strcmp(arg, "x"))
                axis = LK_AXIS_X;
            else if (!strcmp(arg, "y"))
                axis = LK_AXIS_Y;
            else if (!strcmp(arg, "z"))
                axis = LK_AXIS_Z;
            else
                return usage_error("slices", "--axis: '%s' is not x, y, z or auto", arg);
            break;
        case OPT_RATIO:
            if (!parse_double_option(arg, &ratio) || ratio <= 0 || ratio > 1)
                return usage_error("slices", "--ratio: '%s' is not a number in (0, 1]", arg);
            break;
        case OPT_VERTICES:
            if (!parse_size_option(arg, &vertices) || !vertices)
                return usage_error("slices", "--vertices: '%s' is not a positive integer", arg);
            break;
        case OPT_MAX_ERROR:
            if (!parse_double_option(arg, &max_error) || max_error <= 0)
                return usage_error("slices", "--max-error: '%s' is not a positive percentage", arg);
            break;
        case OPT_COUNT:
            if (!parse_size_option(arg, &count) || count < 1 || count > 16)
                return usage_error("slices", "--count: '%s' is not an integer in 1..16", arg);
            break;
        case OPT_WIDTH:
            if (!parse_size_option(arg, &width) || width < 100 || width > 8192)
                return usage_error("slices", "--width: '%s' is not an integer in 100..8192", arg);
            break;
        case OPT_CRITERION:
            if (!strcmp(arg, "energy"))
                criterion = LK_WAVELET_ENERGY;
            else if (!strcmp(arg, "distance"))
                criterion = LK_WAVELET_DISTANCE;
            else
                return usage_error("slices", "--criterion: '%s' is not energy or distance", arg);
            break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("slices", "%s", "expected IN and OUT.svg or OUT.png");
    const char *in = argv[optind], *out = argv[optind + 1];
    size_t length = strlen(out);
    int svg = length > 4 && !strcmp(out + length - 4, ".svg");
    int png = length > 4 && !strcmp(out + length - 4, ".png");
    if (!svg && !png) return usage_error("slices", "'%s' is neither .svg nor .png", out);
    if (count > slice_count) count = slice_count;

    lk_mesh mesh;
    lk_error error = {0};
    lk_slices sampled, simplified;
    lk_slices_init(&sampled);
    lk_slices_init(&simplified);
    lk_contour_simplify_info info;
    memset(&info, 0, sizeof info);
    progress_state progress;
    progress_init(&progress, quiet, "slices");
    lk_status status = load_mesh(in, &mesh, NULL, NULL, &error);
    if (status == LK_OK) {
        status = lk_mesh_remove_degenerate(&mesh, NULL, NULL, &error);
        if (status == LK_OK)
            status = lk_mesh_slice(&mesh, axis, slice_count, &sampled, progress_draw, &progress, &error);
    }
    if (status == LK_OK) {
        lk_contour_simplify_options contour_options = {.criterion = criterion};
        if (max_error > 0) contour_options.max_error = max_error / 100 * sampled.diagonal;
        if (vertices)
            contour_options.target_vertices = vertices;
        else if (ratio > 0 || max_error == 0)
            contour_options.target_vertices =
                (size_t)llround((ratio > 0 ? ratio : 0.125) * (double)sampled.point_count);
        if (contour_options.target_vertices == 0 && max_error == 0) contour_options.target_vertices = 1;
        status = lk_slices_simplify(&sampled, &contour_options, &simplified, &info, progress_draw, &progress, &error);
    }
    progress_done(&progress);
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        lk_mesh_free(&mesh);
        lk_slices_free(&sampled);
        return EXIT_BAD_INPUT;
    }

    /* Panels in a row of up to 4 per line, square. */
    unsigned columns = count < 4 ? (unsigned)count : 4, rows = (unsigned)((count + columns - 1) / columns);
    double cell = (double)width / columns, margin = 12, caption = 28;
    canvas c = {NULL, NULL, (unsigned)width, (unsigned)(rows * (cell + caption))};
    /* The SVG is written like every other output: a hidden temporary file
     * renamed over OUT only when complete. */
    lk_output *svg_file = NULL;
    if (svg) {
        if (lk_output_open(out, &svg_file, &error) != LK_OK) {
            print_error_for(in, out, &error);
            lk_mesh_free(&mesh);
            lk_slices_free(&sampled);
            lk_slices_free(&simplified);
            return EXIT_BAD_INPUT;
        }
        c.svg = lk_output_stream(svg_file);
        fprintf(c.svg,
                "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%u\" height=\"%u\" viewBox=\"0 0 %u %u\">\n"
                "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
                c.width, c.height, c.width, c.height);
    } else {
        c.rgba = malloc((size_t)c.width * c.height * 4);
        if (!c.rgba) {
            fprintf(stderr, "lodkit: out of memory for a %ux%u image\n", c.width, c.height);
            lk_mesh_free(&mesh);
            lk_slices_free(&sampled);
            lk_slices_free(&simplified);
            return EXIT_BAD_INPUT;
        }
        memset(c.rgba, 255, (size_t)c.width * c.height * 4);
    }
    static const unsigned char grey[3] = {150, 150, 150}, blue[3] = {30, 80, 200};
    for (size_t i = 0; i < count; i++) {
        size_t slice = (size_t)((double)(i + 1) / (double)(count + 1) * (double)slice_count);
        if (slice >= slice_count) slice = slice_count - 1;
        panel p;
        p.x0 = (double)(i % columns) * cell + margin;
        p.y0 = (double)(i / columns) * (cell + caption) + margin;
        p.size = cell - 2 * margin;
        double low[2] = {INFINITY, INFINITY}, high[2] = {-INFINITY, -INFINITY};
        for (size_t k = 0; k < sampled.contour_count; k++) {
            const lk_contour *contour = &sampled.contours[k];
            if (contour->slice != slice) continue;
            for (uint32_t j = 0; j < contour->count; j++)
                for (int a = 0; a < 2; a++) {
                    double value = sampled.points[2 * ((size_t)contour->first + j) + a];
                    low[a] = fmin(low[a], value);
                    high[a] = fmax(high[a], value);
                }
        }
        if (!(high[0] >= low[0])) low[0] = low[1] = 0, high[0] = high[1] = 1;
        double extent = fmax(high[0] - low[0], high[1] - low[1]);
        if (!(extent > 0)) extent = 1;
        p.scale = p.size / extent;
        p.min[0] = low[0] - (extent - (high[0] - low[0])) / 2;
        p.min[1] = low[1] - (extent - (high[1] - low[1])) / 2;
        draw_contours(&c, &p, &sampled, slice, "#969696", grey, 1, 1);
        draw_contours(&c, &p, &simplified, slice, "#1e50c8", blue, 2, 3);
        if (c.svg)
            fprintf(c.svg,
                    "<text x=\"%.1f\" y=\"%.1f\" font-family=\"sans-serif\" font-size=\"14\">slice %zu at %c = %.4g: "
                    "%zu -&gt; %zu points</text>\n",
                    p.x0, p.y0 + p.size + margin + 10, slice, "xyz"[sampled.axis - 1], lk_slices_plane(&sampled, slice),
                    slice_points(&sampled, slice), slice_points(&simplified, slice));
    }
    int failed = 0;
    if (c.svg) {
        fprintf(c.svg, "</svg>\n");
        if (lk_output_commit(svg_file, &error) != LK_OK) {
            print_error_for(in, out, &error);
            failed = 1;
        }
    } else {
        status = lk_image_write_png(out, c.rgba, c.width, c.height, &error);
        free(c.rgba);
        if (status != LK_OK) {
            print_error_for(in, out, &error);
            failed = 1;
        }
    }
    if (!failed && !quiet)
        printf("%s: %zu slices along %c, %s -> %s (threshold %.4g%% of the diagonal, %s "
               "padded); %s drawn to %s\n",
               in, slice_count, "xyz"[sampled.axis - 1],
               count_noun(sampled.point_count, "contour point", "contour points"), thousands(simplified.point_count),
               100 * info.threshold / (sampled.diagonal > 0 ? sampled.diagonal : 1),
               count_noun(info.midpoints, "midpoint", "midpoints"), count_noun(count, "slice", "slices"), out);
    lk_mesh_free(&mesh);
    lk_slices_free(&sampled);
    lk_slices_free(&simplified);
    return failed ? EXIT_BAD_INPUT : EXIT_OK;
}
