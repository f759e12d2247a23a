/* SPDX-License-Identifier: MIT */
/* Render options and the orbit camera shared by mesh and splat drawing. */
#include <math.h>
#include <string.h>

#include "gl_internal.h"

#define LK__PI 3.14159265358979323846

void lk_render_options_default(lk_render_options *options)
{
    if (!options) return;
    memset(options, 0, sizeof *options);
    options->azimuth = 30.0;
    options->elevation = 20.0;
    options->distance = 0.0;
    options->fov_y = 35.0;
    options->background[0] = options->background[1] = options->background[2] = 1.0f;
    options->color[0] = 0.70f; /* light grey-blue */
    options->color[1] = 0.76f;
    options->color[2] = 0.86f;
    options->passes = 1;
    options->backface_culling = 1;
    options->radius_scale = 1.0;
    options->depth_epsilon = 1.0;
    options->clip_borders = 1;
}

static int finite3(const float v[3]) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

void lk__camera_setup(const lk_render_options *options, const float box_min[3], const float box_max[3], unsigned width,
                      unsigned height, lk__camera *camera)
{
    lk_render_options defaults;
    if (!options) {
        lk_render_options_default(&defaults);
        options = &defaults;
    }
    const float *lo = options->use_bounds ? options->bounds_min : box_min;
    const float *hi = options->use_bounds ? options->bounds_max : box_max;
    static const float zero[3] = {0, 0, 0};
    if (!lo || !hi || !finite3(lo) || !finite3(hi)) lo = hi = zero;

    double centre[3], half_diagonal_squared = 0;
    for (int k = 0; k < 3; k++) {
        centre[k] = 0.5 * ((double)lo[k] + (double)hi[k]);
        double half = 0.5 * ((double)hi[k] - (double)lo[k]);
        half_diagonal_squared += half * half;
    }
    /* A point or an empty box still gets a usable (tiny) sphere. */
    double radius = fmax(sqrt(half_diagonal_squared), 1e-6);

    /* Out-of-range angles would give a degenerate projection: keep them
     * sane here so every caller gets a valid camera. */
    double fov_y = options->fov_y;
    if (!isfinite(fov_y) || fov_y < 1.0) fov_y = fov_y > 0 && isfinite(fov_y) ? 1.0 : 35.0;
    if (fov_y > 170.0) fov_y = 170.0;
    double aspect = (double)(width ? width : 1) / (double)(height ? height : 1);
    double half_y = 0.5 * fov_y * LK__PI / 180.0;
    double half_x = atan(tan(half_y) * aspect);
    double half_min = fmin(half_y, half_x);

    double distance;
    if (isfinite(options->distance) && options->distance > 0) {
        distance = options->distance * radius;
    } else {
        /* The sphere touches the narrower view cone at r / sin(half angle);
         * 5% more leaves a thin margin round the silhouette. */
        distance = 1.05 * radius / sin(half_min);
    }

    double azimuth = isfinite(options->azimuth) ? options->azimuth * LK__PI / 180.0 : 0.0;
    double elevation = isfinite(options->elevation) ? options->elevation * LK__PI / 180.0 : 0.0;
    /* Camera frame from the angles directly (not a look-at with a fixed
     * up vector), so that straight-down views (elevation +-90) work too:
     * back points from the centre to the eye, right stays horizontal. */
    double back[3] = {sin(azimuth) * cos(elevation), sin(elevation), cos(azimuth) * cos(elevation)};
    double right[3] = {cos(azimuth), 0.0, -sin(azimuth)};
    double up[3] = {back[1] * right[2] - back[2] * right[1], back[2] * right[0] - back[0] * right[2],
                    back[0] * right[1] - back[1] * right[0]};
    /* Another up axis: the same frame turned so that its y lands on that axis
     * (a rotation, so the view stays right-handed): z up is +90 degrees about
     * x, x up is -90 degrees about z. */
    if (options->up_axis == LK_AXIS_Z || options->up_axis == LK_AXIS_X) {
        double *axes_to_turn[3] = {back, right, up};
        for (int i = 0; i < 3; i++) {
            double *v = axes_to_turn[i], x = v[0], y = v[1], z = v[2];
            if (options->up_axis == LK_AXIS_Z)
                v[0] = x, v[1] = -z, v[2] = y;
            else
                v[0] = y, v[1] = -x, v[2] = z;
        }
    }
    double eye[3];
    for (int k = 0; k < 3; k++) eye[k] = centre[k] + distance * back[k];

    memset(camera, 0, sizeof *camera);
    const double *axes[3] = {right, up, back};
    for (int row = 0; row < 3; row++) {
        const double *axis = axes[row];
        for (int col = 0; col < 3; col++) {
            camera->view[col * 4 + row] = (float)axis[col];
            camera->normal_matrix[col * 3 + row] = (float)axis[col];
        }
        camera->view[12 + row] = (float)-(axis[0] * eye[0] + axis[1] * eye[1] + axis[2] * eye[2]);
    }
    camera->view[15] = 1.0f;
    for (int k = 0; k < 3; k++) camera->eye[k] = (float)eye[k];

    /* Depth range hugging the sphere (a little wider so that nothing on it
     * is clipped); when the eye is inside, near stays a small fraction of
     * the distance to keep depth precision. */
    double near_plane = fmax(distance - 1.1 * radius, distance * 1e-3);
    double far_plane = distance + 1.1 * radius;
    double top = near_plane * tan(half_y);
    double focal = 1.0 / tan(half_y);
    camera->projection[0] = (float)(focal / aspect);
    camera->projection[5] = (float)focal;
    camera->projection[10] = (float)((far_plane + near_plane) / (near_plane - far_plane));
    camera->projection[11] = -1.0f;
    camera->projection[14] = (float)(2.0 * far_plane * near_plane / (near_plane - far_plane));
    camera->near_plane = (float)near_plane;
    camera->far_plane = (float)far_plane;
    camera->top = (float)top;
    camera->bottom = (float)-top;
    camera->radius = (float)radius;
}

/* See gl_internal.h: normalised upload of huge or denormal models. */
void lk__normalization_setup(const lk_render_options *options, const float box_min[3], const float box_max[3],
                             lk__model_normalization *out)
{
    const float *lo = options->use_bounds ? options->bounds_min : box_min;
    const float *hi = options->use_bounds ? options->bounds_max : box_max;
    double half_diagonal_squared = 0;
    for (int k = 0; k < 3; k++) {
        out->origin[k] = 0.5 * ((double)lo[k] + (double)hi[k]);
        double half = 0.5 * ((double)hi[k] - (double)lo[k]);
        half_diagonal_squared += half * half;
    }
    double radius = sqrt(half_diagonal_squared);
    /* A point (radius 0) keeps scale 1: the camera gives it its own tiny sphere. */
    out->scale = radius > 0 && isfinite(radius) ? 1.0 / radius : 1.0;
    out->options = *options;
    out->options.use_bounds = 1;
    for (int k = 0; k < 3; k++) {
        out->options.bounds_min[k] = (float)(((double)lo[k] - out->origin[k]) * out->scale);
        out->options.bounds_max[k] = (float)(((double)hi[k] - out->origin[k]) * out->scale);
    }
}

/* The normalised copy of `count` positions (NULL when out of memory). */
float *lk__normalized_positions(const lk__model_normalization *n, const float *positions, size_t count)
{
    float *out = lk__malloc_array(count ? count : 1, 3 * sizeof *out);
    if (!out) return NULL;
    for (size_t i = 0; i < count; i++)
        for (int k = 0; k < 3; k++) out[3 * i + k] = (float)(((double)positions[3 * i + k] - n->origin[k]) * n->scale);
    return out;
}
