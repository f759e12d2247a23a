/* SPDX-License-Identifier: MIT */
/* Elevation grids in memory: lk_heightfield_free, bilinear resampling and
 * synthetic fractal terrain. Part of the core: terrain CLOD works on any
 * lk_heightfield; reading grids from files is lodkit-dem's (src/io_dem.c). */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void lk_heightfield_free(lk_heightfield *field)
{
    if (!field) return;
    free(field->heights);
    memset(field, 0, sizeof *field);
}

/* min_height and max_height from the heights. */
void lk__heightfield_compute_range(lk_heightfield *field)
{
    size_t count = field->width * field->height;
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < count; k++) {
        double h = field->heights[k];
        if (h < lo) lo = h;
        if (h > hi) hi = h;
    }
    field->min_height = lo;
    field->max_height = hi;
}

/* ---- resampling --------------------------------------------------------- */

/* Bilinear in sample space, which keeps the extent: output sample (i, j)
 * stands at input position (i (w-1)/(size-1), j (h-1)/(size-1)), so the
 * corners are copied and planes are reproduced exactly (up to float
 * rounding). Any size >= 2 is accepted (terrain code wants 2^n + 1, which
 * size 0 picks); the result is never outside the input's height range. */

lk_status lk_heightfield_resample(const lk_heightfield *in, size_t size, lk_heightfield *out, lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "lk_heightfield_resample: out is NULL");
    if (!in || !in->heights || in->width < 2 || in->height < 2)
        return lk_error_set(error, LK_ERR_INVALID, "lk_heightfield_resample: input needs at least 2x2 samples");
    if (in == out) return lk_error_set(error, LK_ERR_INVALID, "lk_heightfield_resample: in and out must differ");
    memset(out, 0, sizeof *out);
    if (size == 0) {
        size_t largest = in->width > in->height ? in->width : in->height;
        size = 2;
        while (size < largest) {
            if (size - 1 > SIZE_MAX / 4)
                return lk_error_set(error, LK_ERR_LIMIT, "lk_heightfield_resample: grid too large");
            size = 2 * (size - 1) + 1;
        }
    }
    if (size < 2)
        return lk_error_set(error, LK_ERR_INVALID, "lk_heightfield_resample: size %zu is too small (need >= 2)", size);
    if (size > SIZE_MAX / size / sizeof(float))
        return lk_error_set(error, LK_ERR_LIMIT, "lk_heightfield_resample: %zux%zu grid is too large", size, size);
    float *heights = lk__malloc_array(size * size, sizeof *heights);
    if (!heights)
        return lk_error_set(error, LK_ERR_NOMEM, "lk_heightfield_resample: out of memory for %zux%zu samples", size,
                            size);
    size_t width = in->width, height = in->height;
    /* Column weights are the same for every row: compute them once. */
    size_t *column = lk__malloc_array(size, sizeof *column);
    double *column_t = lk__malloc_array(size, sizeof *column_t);
    if (!column || !column_t) {
        free(heights);
        free(column);
        free(column_t);
        return lk_error_set(error, LK_ERR_NOMEM, "lk_heightfield_resample: out of memory");
    }
    for (size_t i = 0; i < size; i++) {
        /* Exact rational position; the last sample lands on the last input
         * column (cell width-2 at t = 1) so the extent is kept exactly. */
        double position = (double)i * (double)(width - 1) / (double)(size - 1);
        size_t cell = (size_t)position;
        if (cell > width - 2) cell = width - 2;
        column[i] = cell;
        column_t[i] = position - (double)cell;
    }
    for (size_t j = 0; j < size; j++) {
        double position = (double)j * (double)(height - 1) / (double)(size - 1);
        size_t row = (size_t)position;
        if (row > height - 2) row = height - 2;
        double v = position - (double)row;
        const float *r0 = in->heights + row * width, *r1 = r0 + width;
        float *target = heights + j * size;
        for (size_t i = 0; i < size; i++) {
            size_t c = column[i];
            double u = column_t[i];
            double bottom = (double)r0[c] + u * ((double)r0[c + 1] - (double)r0[c]);
            double top = (double)r1[c] + u * ((double)r1[c + 1] - (double)r1[c]);
            target[i] = (float)(bottom + v * (top - bottom));
        }
    }
    free(column);
    free(column_t);
    out->width = size;
    out->height = size;
    out->heights = heights;
    out->spacing_x = in->spacing_x * (double)(width - 1) / (double)(size - 1);
    out->spacing_y = in->spacing_y * (double)(height - 1) / (double)(size - 1);
    out->origin_x = in->origin_x;
    out->origin_y = in->origin_y;
    /* Every output sample is interpolated, none was read as no-data; the
     * source's count stays with the source (and could exceed size^2). */
    out->nodata_count = 0;
    lk__heightfield_compute_range(out);
    return LK_OK;
}

/* ---- synthetic terrain ---------------------------------------------------- */

/* A hash of the lattice point, in [0, 1]. */
static float lattice_noise(unsigned x, unsigned y, unsigned octave)
{
    unsigned h = x * 374761393u + y * 668265263u + octave * 2246822519u;
    h = (h ^ (h >> 13)) * 1274126177u;
    h ^= h >> 16;
    return (float)(h & 0xffff) / 65535.0f;
}

lk_status lk_heightfield_fractal(size_t size, double spacing, lk_heightfield *out, lk_error *error)
{
    memset(out, 0, sizeof *out);
    if (size < 2 || size > 65537 || !(spacing > 0) || !isfinite(spacing))
        return lk_error_set(error, LK_ERR_INVALID, "fractal terrain: size must be 2..65537 and spacing > 0");
    float *heights = lk__malloc_array(size * size, sizeof *heights);
    if (!heights) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a %zux%zu terrain", size, size);
    double lo = INFINITY, hi = -INFINITY;
    for (size_t j = 0; j < size; j++)
        for (size_t i = 0; i < size; i++) {
            double z = 0, amplitude = 1000, frequency = 4.0 / (double)(size - 1);
            for (unsigned octave = 0; octave < 7; octave++) {
                double x = (double)i * frequency, y = (double)j * frequency;
                unsigned xi = (unsigned)x, yi = (unsigned)y;
                double fx = x - xi, fy = y - yi;
                fx = fx * fx * (3 - 2 * fx); /* smoothstep between lattice points */
                fy = fy * fy * (3 - 2 * fy);
                double a = lattice_noise(xi, yi, octave), b = lattice_noise(xi + 1, yi, octave);
                double c = lattice_noise(xi, yi + 1, octave), d = lattice_noise(xi + 1, yi + 1, octave);
                z += amplitude * ((a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy);
                amplitude *= 0.5;
                frequency *= 2;
            }
            heights[j * size + i] = (float)z;
            if (z < lo) lo = z;
            if (z > hi) hi = z;
        }
    out->width = out->height = size;
    out->heights = heights;
    out->spacing_x = out->spacing_y = spacing;
    out->min_height = lo;
    out->max_height = hi;
    return LK_OK;
}
