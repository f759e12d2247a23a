/* Deformation-sensitive simplification around the multi-frame QEM of
 * src/qem.c: options, results, scheme names and the per-frame Metro
 * measure of the paper's evaluation (its Fig. 8). */
#include "internal.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const scheme_names[] = {"max", "avg", "frame"};

const char *lk_anim_scheme_name(lk_anim_scheme scheme)
{
    if ((unsigned)scheme >= sizeof scheme_names / sizeof scheme_names[0]) return NULL;
    return scheme_names[scheme];
}

int lk_anim_scheme_parse(const char *name, lk_anim_scheme *scheme)
{
    if (!name || !scheme) return -1;
    if (!strcmp(name, "max")) *scheme = LK_ANIM_SCHEME_MAX;
    else if (!strcmp(name, "avg") || !strcmp(name, "mean")) *scheme = LK_ANIM_SCHEME_AVG;
    else if (!strcmp(name, "frame") || !strcmp(name, "single")) *scheme = LK_ANIM_SCHEME_FRAME;
    else return -1;
    return 0;
}

void lk_anim_simplify_options_default(lk_anim_simplify_options *options)
{
    memset(options, 0, sizeof *options);
    lk_simplify_options_default(&options->simplify);
    options->scheme = LK_ANIM_SCHEME_MAX;
    options->lost_surface = LK_ANIM_LOST_SURFACE_DEFAULT;
}

void lk_anim_simplify_result_free(lk_anim_simplify_result *result)
{
    if (!result) return;
    lk_animation_free(&result->animation);
    free(result->vertex_map);
    memset(result, 0, sizeof *result);
}

lk_status lk_animation_metro(const lk_animation *simplified, const lk_animation *original, const size_t *frames,
                             size_t frame_count, const lk_metro_options *options, lk_metro_result *out,
                             lk_progress_fn progress, void *progress_user, lk_error *error)
{
    if (!simplified || !original || (!out && frame_count > 0))
        return lk_error_set(error, LK_ERR_INVALID, "lk_animation_metro: NULL argument");
    if (!frames && (simplified->frame_count != original->frame_count || frame_count > original->frame_count))
        return lk_error_set(error, LK_ERR_INVALID,
                            "cannot compare every frame: %zu simplified frames, %zu original frames, %zu asked",
                            simplified->frame_count, original->frame_count, frame_count);
    lk_mesh a, b;
    lk_mesh_init(&a), lk_mesh_init(&b);
    lk_status status = LK_OK;
    bool have_meshes = false;
    for (size_t k = 0; k < frame_count && status == LK_OK; k++) {
        size_t frame = frames ? frames[k] : k;
        if (frame >= simplified->frame_count || frame >= original->frame_count) {
            status = lk_error_set(error, LK_ERR_RANGE, "frame %zu does not exist (%zu and %zu frames)", frame,
                                  simplified->frame_count, original->frame_count);
            break;
        }
        /* the frames as meshes: made once, then only the positions change */
        if (!have_meshes) {
            status = lk_animation_frame(simplified, frame, &a, error);
            if (status == LK_OK) status = lk_animation_frame(original, frame, &b, error);
            if (status != LK_OK) break;
            have_meshes = true;
        }
        memcpy(a.positions, simplified->frame_positions + 3 * frame * a.vertex_count, 3 * a.vertex_count * sizeof(float));
        memcpy(b.positions, original->frame_positions + 3 * frame * b.vertex_count, 3 * b.vertex_count * sizeof(float));
        status = lk_metro(&a, &b, options, &out[k], NULL, NULL, error);
        if (status == LK_OK && progress && progress(progress_user, (double)(k + 1) / (double)frame_count, "metro"))
            status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
    }
    lk_mesh_free(&a), lk_mesh_free(&b);
    return status;
}

/* ------------------------------------------------------------------------ */
/* Error map picture (the paper's Fig. 8 as a heat map)                     */
/* ------------------------------------------------------------------------ */

/* A 5x7 bitmap font (upper case, digits, a little punctuation), drawn by
 * lodkit itself so that the picture needs no font library; bit 4 of each
 * row is the leftmost pixel. Lower case is drawn in upper case. */
static const char glyph_chars[] = "%()+,-./0123456789:=ABCDEFGHIJKLMNOPQRSTUVWXYZ_";
static const unsigned char glyph_rows[][7] = {
    {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03}, /* % */
    {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}, /* ( */
    {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}, /* ) */
    {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00}, /* + */
    {0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08}, /* , */
    {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00}, /* - */
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}, /* . */
    {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00}, /* / */
    {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}, /* 0 */
    {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}, /* 1 */
    {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}, /* 2 */
    {0x1E, 0x01, 0x01, 0x0E, 0x01, 0x01, 0x1E}, /* 3 */
    {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}, /* 4 */
    {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}, /* 5 */
    {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}, /* 6 */
    {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}, /* 7 */
    {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}, /* 8 */
    {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}, /* 9 */
    {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00}, /* : */
    {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00}, /* = */
    {0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}, /* A */
    {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E}, /* B */
    {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E}, /* C */
    {0x1E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1E}, /* D */
    {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F}, /* E */
    {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10}, /* F */
    {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F}, /* G */
    {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}, /* H */
    {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}, /* I */
    {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C}, /* J */
    {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11}, /* K */
    {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F}, /* L */
    {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11}, /* M */
    {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11}, /* N */
    {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}, /* O */
    {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10}, /* P */
    {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D}, /* Q */
    {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11}, /* R */
    {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E}, /* S */
    {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}, /* T */
    {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}, /* U */
    {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04}, /* V */
    {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A}, /* W */
    {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11}, /* X */
    {0x11, 0x11, 0x0A, 0x04, 0x04, 0x04, 0x04}, /* Y */
    {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F}, /* Z */
    {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F}, /* _ */
};

#define GLYPH_SCALE 2
#define GLYPH_ADVANCE (6 * GLYPH_SCALE)
#define GLYPH_HEIGHT (7 * GLYPH_SCALE)

typedef struct canvas {
    unsigned char *rgba;
    unsigned width, height;
} canvas;

static void fill_rect(canvas *c, long x, long y, long w, long h, const unsigned char rgb[3])
{
    for (long j = y < 0 ? 0 : y; j < y + h && j < (long)c->height; j++)
        for (long i = x < 0 ? 0 : x; i < x + w && i < (long)c->width; i++) {
            unsigned char *p = c->rgba + 4 * ((size_t)j * c->width + (size_t)i);
            p[0] = rgb[0], p[1] = rgb[1], p[2] = rgb[2], p[3] = 255;
        }
}

static long text_width(const char *text)
{
    return (long)strlen(text) * GLYPH_ADVANCE;
}

/* Draws text with its top-left corner at (x, y). */
static void draw_text(canvas *c, long x, long y, const char *text, const unsigned char rgb[3])
{
    for (; *text; text++, x += GLYPH_ADVANCE) {
        char ch = (char)toupper((unsigned char)*text);
        const char *at = ch ? strchr(glyph_chars, ch) : NULL;
        if (!at) continue; /* space and unknown characters */
        const unsigned char *rows = glyph_rows[at - glyph_chars];
        for (int row = 0; row < 7; row++)
            for (int column = 0; column < 5; column++)
                if (rows[row] & (0x10 >> column))
                    fill_rect(c, x + column * GLYPH_SCALE, y + row * GLYPH_SCALE, GLYPH_SCALE, GLYPH_SCALE, rgb);
    }
}

/* Colour ramp from dark blue (low) through green and yellow to red (high). */
static void ramp(double t, unsigned char rgb[3])
{
    static const double stops[5][3] = {{25, 30, 110}, {35, 115, 200}, {50, 175, 115}, {240, 205, 55}, {200, 30, 30}};
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double x = t * 4;
    int i = x >= 4 ? 3 : (int)x;
    double f = x - i;
    for (int k = 0; k < 3; k++) rgb[k] = (unsigned char)lround(stops[i][k] + f * (stops[i + 1][k] - stops[i][k]));
}

/* Position of value v on the logarithmic colour scale [low, high]. */
static double scale_position(double v, double low, double high)
{
    if (!(v > low)) return 0;
    if (!(v < high)) return 1;
    return log(v / low) / log(high / low);
}

lk_status lk_anim_error_map(const double *values, size_t level_count, size_t frame_count, const double *level_ratios,
                            const size_t *frame_numbers, double scale_min, double scale_max, const char *title,
                            const char *value_label, unsigned char **rgba, unsigned *width, unsigned *height,
                            lk_error *error)
{
    if (!values || !rgba || !width || !height || level_count == 0 || frame_count == 0)
        return lk_error_set(error, LK_ERR_INVALID, "lk_anim_error_map: nothing to draw");
    if (level_count > 1000 || frame_count > 100000)
        return lk_error_set(error, LK_ERR_LIMIT, "lk_anim_error_map: %zu levels x %zu frames is too many to draw",
                            level_count, frame_count);
    *rgba = NULL;
    /* the colour scale: given, or the range of the positive values */
    double low = scale_min, high = scale_max;
    if (!(low > 0) || !(high > low)) {
        double found_low = INFINITY, found_high = 0;
        for (size_t i = 0; i < level_count * frame_count; i++)
            if (values[i] > 0 && isfinite(values[i])) {
                if (values[i] < found_low) found_low = values[i];
                if (values[i] > found_high) found_high = values[i];
            }
        /* three decades at most: rounding noise (1e-16 where nothing
         * changed) must not stretch the scale */
        if (!(low > 0)) low = isfinite(found_low) ? fmax(found_low, found_high * 1e-3) : 1e-6;
        if (!(high > low)) high = found_high > low ? found_high : low * 10;
    }
    /* layout: cells of cell_w x cell_h pixels, levels bottom (first) to top */
    unsigned cell_w = frame_count >= 600 ? 1 : (unsigned)(600 / frame_count);
    unsigned cell_h = level_count >= 40 ? 8 : (unsigned)(320 / level_count);
    unsigned plot_w = (unsigned)frame_count * cell_w, plot_h = (unsigned)level_count * cell_h;
    unsigned left = 80, top = 56, bottom = 64, legend_gap = 28, legend_w = 22, legend_text = 110;
    unsigned min_width = (unsigned)text_width(title ? title : "") + 40;
    canvas c;
    c.width = left + plot_w + legend_gap + legend_w + legend_text;
    if (c.width < min_width) c.width = min_width;
    c.height = top + plot_h + bottom;
    c.rgba = lk__malloc_array((size_t)c.width * c.height, 4);
    if (!c.rgba) return lk_error_set(error, LK_ERR_NOMEM, "cannot allocate a %ux%u picture", c.width, c.height);
    static const unsigned char white[3] = {255, 255, 255}, black[3] = {0, 0, 0}, grey[3] = {150, 150, 150};
    fill_rect(&c, 0, 0, c.width, c.height, white);
    if (title) draw_text(&c, 20, 12, title, black);
    char label[64];
    /* cells */
    for (size_t l = 0; l < level_count; l++)
        for (size_t f = 0; f < frame_count; f++) {
            double v = values[l * frame_count + f];
            unsigned char rgb[3];
            if (isnan(v)) memcpy(rgb, grey, 3);
            else ramp(scale_position(v, low, high), rgb);
            long y = (long)top + (long)(level_count - 1 - l) * cell_h;
            fill_rect(&c, (long)left + (long)f * cell_w, y, cell_w, cell_h, rgb);
        }
    /* frame of the plot */
    fill_rect(&c, left - 1, top - 1, plot_w + 2, 1, black);
    fill_rect(&c, left - 1, top + plot_h, plot_w + 2, 1, black);
    fill_rect(&c, left - 1, top - 1, 1, plot_h + 2, black);
    fill_rect(&c, left + plot_w, top - 1, 1, plot_h + 2, black);
    /* y axis: one label per level (thinned when crowded) */
    size_t level_step = (level_count * (GLYPH_HEIGHT + 4) + plot_h - 1) / plot_h;
    for (size_t l = 0; l < level_count; l += level_step ? level_step : 1) {
        if (level_ratios) snprintf(label, sizeof label, "%g%%", 100 * level_ratios[l]);
        else snprintf(label, sizeof label, "%zu", l + 1);
        long y = (long)top + (long)(level_count - 1 - l) * cell_h + (long)cell_h / 2 - GLYPH_HEIGHT / 2;
        draw_text(&c, (long)left - 8 - text_width(label), y, label, black);
    }
    draw_text(&c, 8, top - GLYPH_HEIGHT - 8, level_ratios ? "KEPT" : "LEVEL", black);
    /* x axis: ticks at round frame steps, at most about 10 */
    size_t steps[] = {1, 2, 5, 10, 20, 25, 50, 100, 200, 250, 500, 1000, 2000, 5000, 10000, 20000, 50000, 100000};
    size_t step = steps[sizeof steps / sizeof steps[0] - 1];
    for (size_t i = 0; i < sizeof steps / sizeof steps[0]; i++)
        if (frame_count / steps[i] <= 10) {
            step = steps[i];
            break;
        }
    for (size_t f = 0; f < frame_count; f += step) {
        long x = (long)left + (long)f * cell_w + (long)cell_w / 2;
        fill_rect(&c, x, top + plot_h, 1, 6, black);
        snprintf(label, sizeof label, "%zu", frame_numbers ? frame_numbers[f] : f);
        draw_text(&c, x - text_width(label) / 2, top + plot_h + 10, label, black);
    }
    const char *x_label = "FRAME";
    draw_text(&c, (long)left + (long)plot_w / 2 - text_width(x_label) / 2, top + plot_h + 14 + GLYPH_HEIGHT, x_label,
              black);
    /* legend: the ramp bottom (low) to top (high), labels at 1-2-5 values */
    long legend_x = (long)left + plot_w + legend_gap;
    for (unsigned j = 0; j < plot_h; j++) {
        unsigned char rgb[3];
        ramp(1.0 - (double)j / (plot_h > 1 ? plot_h - 1 : 1), rgb);
        fill_rect(&c, legend_x, top + j, legend_w, 1, rgb);
    }
    double decade = pow(10, floor(log10(low)));
    long last_y = -1000;
    for (int i = 0; i < 64; i++) {
        static const double multiples[3] = {1, 2, 5};
        double v = decade * pow(10, i / 3) * multiples[i % 3];
        if (v > high * 1.0001) break;
        if (v < low * 0.9999) continue;
        long y = (long)top + (long)lround((1 - scale_position(v, low, high)) * (plot_h - 1));
        if (last_y > -1000 && last_y - y < GLYPH_HEIGHT + 2) continue;
        last_y = y;
        fill_rect(&c, legend_x + legend_w, y, 5, 1, black);
        snprintf(label, sizeof label, "%g", v);
        draw_text(&c, legend_x + legend_w + 8, y - GLYPH_HEIGHT / 2, label, black);
    }
    if (value_label) draw_text(&c, legend_x - 4, top - GLYPH_HEIGHT - 8, value_label, black);
    *rgba = c.rgba;
    *width = c.width;
    *height = c.height;
    return LK_OK;
}
