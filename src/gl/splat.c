/* SPDX-License-Identifier: MIT */
/* Point sets drawn as splats (Kim 2010, "3D point set rendering for
 * iPhone", after Botsch et al.'s Phong splatting): one point sprite per
 * oriented point, sized by eq. 1 of the paper, lit per fragment, with a
 * Gaussian kernel read from a small texture.
 *
 *   1 pass  (the paper): alpha blending of the Gaussian-weighted splats over
 *           what is already drawn, depth writes on, depth test LEQUAL (so
 *           that splats at one depth, e.g. a plane facing the eye, blend
 *           instead of the first one drawn winning). Where a nearer splat's
 *           translucent rim was drawn first, splats behind it fail the depth
 *           test and the background shows through: the overlap artefacts
 *           the paper reports, which the 2-pass mode removes.
 *   2 passes (the paper's future work, normalised splatting): a visibility
 *           pass writes the splats' depth pushed back by depth_epsilon radii;
 *           an accumulation pass adds (w r, w g, w b, w) of every splat that
 *           passes that depth test into an offscreen target, without depth
 *           writes; a normalisation pass divides by the summed weight.
 *   flat    the baseline: square, unlit, opaque points of the same size.
 *
 * Back-facing splats are dropped in the vertex shader (moved outside the
 * clip volume), so they never make fragments.
 *
 * GL state kept with the renderer (renderer->splat_state): the kernel
 * texture, the accumulation target of the 2-pass mode (texture + FBO that
 * shares the renderer's depth buffer), the full-screen triangle and the
 * vertex buffer (refilled by every draw). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"

/* Kernel texture side (texels). The Gaussian is smooth, so 32x32 with
 * bilinear filtering is plenty even for the largest (255 px) sprites. */
#define KERNEL_SIZE 32
/* Standard deviation of the Gaussian in splat radii: exp(-d^2 / (2 s^2))
 * is 0.36 at the disc's rim. Measured on the bunny and on a flat patch: a
 * narrower kernel (s = 0.5, rim 0.14) lets the background shine through
 * the translucent rims of the front splats in 1-pass mode much more (a
 * white lace over the surface) and gains nothing visible in 2-pass mode. */
#define KERNEL_SIGMA 0.7
/* Weight scale of the RGBA8 accumulation fallback: 16 full weights fit
 * before the target saturates (see choose_target). */
#define RGBA8_WEIGHT_SCALE (1.0f / 16.0f)
/* Neighbours used when a point set comes without radii. */
#define DEFAULT_RADIUS_NEIGHBOURS 8
/* Neighbours that decide whether a point is on a border (clip_borders).
 * bench_radii, clip lines through border points: with 8, unevenly sampled
 * interior points were taken for borders and cut (coverage of the bunny's
 * random 100k sample 99.99 -> 99.74%, of the hippo scan 99.75 -> 98.81%);
 * 16 keeps them (99.99%, 99.09%) and cuts about as much spill. */
#define CLIP_NEIGHBOURS 16

/* The key light meshes are lit with (gl_internal.h). */
static const float key_direction[3] = LK__KEY_LIGHT_DIRECTION;

/* Attribute locations of splat.vert.glsl, bound in this order. */
enum { ATTRIBUTE_POSITION = 0, ATTRIBUTE_NORMAL, ATTRIBUTE_RADIUS, ATTRIBUTE_COLOR, ATTRIBUTE_CLIP };
static const char *const splat_attributes[] = {"a_position", "a_normal", "a_radius", "a_color", "a_clip", NULL};
static const char *const fullscreen_attributes[] = {"a_position", NULL};

typedef enum target_kind {
    TARGET_NONE = 0,
    TARGET_HALF_FLOAT, /* OES_texture_half_float + EXT_color_buffer_half_float */
    TARGET_FLOAT,      /* OES_texture_float + a colour-buffer-float extension */
    TARGET_RGBA8       /* weights scaled by RGBA8_WEIGHT_SCALE */
} target_kind;

static const char *const target_names[] = {"none", "RGBA16F (half float)", "RGBA32F (float)", "RGBA8 (weights / 16)"};

typedef struct splat_state {
    GLuint kernel_texture;
    GLuint fullscreen_buffer;        /* one triangle covering the viewport */
    GLuint accumulation_texture;     /* 2-pass target, width x height */
    GLuint accumulation_framebuffer; /* that texture + the renderer's depth buffer */
    GLuint point_buffer;             /* vertex data of the last draw, reused */
    size_t point_buffer_bytes;       /* its allocated size */
    target_kind target;
    int force_rgba8; /* test hook: skip the floating-point targets */
} splat_state;

typedef enum draw_mode {
    DRAW_ONE_PASS = 0,
    DRAW_TWO_PASS,
    DRAW_FLAT,
    DRAW_COUNT_FRAGMENTS /* discs adding 1/255 each into a cleared buffer, no depth test */
} draw_mode;

static void delete_target(splat_state *state)
{
    if (state->accumulation_framebuffer) glDeleteFramebuffers(1, &state->accumulation_framebuffer);
    if (state->accumulation_texture) glDeleteTextures(1, &state->accumulation_texture);
    state->accumulation_framebuffer = 0;
    state->accumulation_texture = 0;
    state->target = TARGET_NONE;
}

static void splat_state_free(lk_renderer *renderer)
{
    splat_state *state = renderer->splat_state;
    if (!state) return;
    delete_target(state);
    if (state->kernel_texture) glDeleteTextures(1, &state->kernel_texture);
    if (state->fullscreen_buffer) glDeleteBuffers(1, &state->fullscreen_buffer);
    if (state->point_buffer) glDeleteBuffers(1, &state->point_buffer);
    free(state);
    renderer->splat_state = NULL;
    renderer->splat_state_free = NULL;
}

/* The kernel texture of the paper's Fig. 1: a Gaussian over the sprite in
 * the alpha channel. Texel centres map to [-1, 1]^2 (gl_PointCoord * 2 - 1);
 * the texture keeps the Gaussian beyond the disc too (the shader discards
 * those fragments), so bilinear filtering near the rim never mixes in zeros. */
static lk_status create_kernel_texture(splat_state *state, lk_error *error)
{
    unsigned char texels[KERNEL_SIZE * KERNEL_SIZE];
    for (int row = 0; row < KERNEL_SIZE; row++)
        for (int col = 0; col < KERNEL_SIZE; col++) {
            double x = 2.0 * (col + 0.5) / KERNEL_SIZE - 1.0, y = 2.0 * (row + 0.5) / KERNEL_SIZE - 1.0;
            double weight = exp(-(x * x + y * y) / (2.0 * KERNEL_SIGMA * KERNEL_SIGMA));
            texels[row * KERNEL_SIZE + col] = (unsigned char)lround(255.0 * weight);
        }
    glGenTextures(1, &state->kernel_texture);
    glBindTexture(GL_TEXTURE_2D, state->kernel_texture);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_ALPHA, KERNEL_SIZE, KERNEL_SIZE, 0, GL_ALPHA, GL_UNSIGNED_BYTE, texels);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glBindTexture(GL_TEXTURE_2D, 0);
    return lk__gl_check("creating the splat kernel texture", error);
}

static lk_status get_state(lk_renderer *renderer, splat_state **out, lk_error *error)
{
    if (renderer->splat_state) {
        *out = renderer->splat_state;
        return LK_OK;
    }
    splat_state *state = calloc(1, sizeof *state);
    if (!state) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for the splat renderer state");
    renderer->splat_state = state;
    renderer->splat_state_free = splat_state_free;
    lk_status status = create_kernel_texture(state, error);
    if (status == LK_OK) {
        static const float triangle[6] = {-1, -1, 3, -1, -1, 3};
        glGenBuffers(1, &state->fullscreen_buffer);
        glBindBuffer(GL_ARRAY_BUFFER, state->fullscreen_buffer);
        glBufferData(GL_ARRAY_BUFFER, sizeof triangle, triangle, GL_STATIC_DRAW);
        glBindBuffer(GL_ARRAY_BUFFER, 0);
        status = lk__gl_check("creating the full-screen triangle", error);
    }
    if (status != LK_OK) {
        splat_state_free(renderer);
        return status;
    }
    *out = state;
    return LK_OK;
}

/* Tries one accumulation format: a texture of the renderer's size attached
 * with the renderer's depth buffer, which must make a complete framebuffer. */
static int try_target(lk_renderer *renderer, splat_state *state, GLenum type)
{
    while (glGetError() != GL_NO_ERROR) {
    }
    glGenTextures(1, &state->accumulation_texture);
    glBindTexture(GL_TEXTURE_2D, state->accumulation_texture);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, (GLsizei)renderer->width, (GLsizei)renderer->height, 0, GL_RGBA, type,
                 NULL);
    /* Sampled at texel centres only: nearest filtering is exact and needs
     * no *_linear extension for the float formats. */
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glBindTexture(GL_TEXTURE_2D, 0);
    glGenFramebuffers(1, &state->accumulation_framebuffer);
    glBindFramebuffer(GL_FRAMEBUFFER, state->accumulation_framebuffer);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, state->accumulation_texture, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, renderer->depth_buffer);
    int ok = glGetError() == GL_NO_ERROR && glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
    glBindFramebuffer(GL_FRAMEBUFFER, renderer->framebuffer);
    if (!ok) delete_target(state);
    return ok;
}

/* The 2-pass target: the most precise renderable format of this context.
 * Half floats are enough (11-bit mantissa, range 65504) and are what
 * llvmpipe and most ES2 GPUs render to. RGBA8 is the last resort: each
 * fragment's (w r, w g, w b, w) / 16 is rounded to 1/255, i.e. weights are
 * kept to steps of 16/255 = 0.063 (a rim fragment of weight 0.135 counts
 * as 0.125 or 0.188), so normalised colours carry an error of a few
 * percent near silhouettes and where few splats overlap, and more than 16
 * full-weight splats on one pixel saturate (colour stays right as long as
 * the weight does not saturate first, which it does at the same time). */
static lk_status choose_target(lk_renderer *renderer, splat_state *state, lk_error *error)
{
    if (state->target != TARGET_NONE) return LK_OK;
    if (!state->force_rgba8) {
        if (lk__gl_has_extension("GL_OES_texture_half_float") &&
            lk__gl_has_extension("GL_EXT_color_buffer_half_float") && try_target(renderer, state, GL_HALF_FLOAT_OES)) {
            state->target = TARGET_HALF_FLOAT;
            return LK_OK;
        }
        /* 32-bit float targets also need blending (EXT_float_blend). */
        if (lk__gl_has_extension("GL_OES_texture_float") &&
            (lk__gl_has_extension("GL_EXT_color_buffer_float") ||
             lk__gl_has_extension("GL_WEBGL_color_buffer_float")) &&
            lk__gl_has_extension("GL_EXT_float_blend") && try_target(renderer, state, GL_FLOAT)) {
            state->target = TARGET_FLOAT;
            return LK_OK;
        }
    }
    if (try_target(renderer, state, GL_UNSIGNED_BYTE)) {
        state->target = TARGET_RGBA8;
        return LK_OK;
    }
    return lk_error_set(error, LK_ERR_UNSUPPORTED,
                        "no colour target for 2-pass splatting: even an RGBA8 texture with the depth buffer is "
                        "an incomplete framebuffer here (use 1 pass)");
}

/* ---- input checks ------------------------------------------------------- */

static lk_status check_options(const lk_render_options *options, lk_error *error)
{
    if (options->passes != 1 && options->passes != 2)
        return lk_error_set(error, LK_ERR_INVALID, "splatting passes must be 1 or 2, not %u", options->passes);
    if (!(options->radius_scale > 0) || !isfinite(options->radius_scale))
        return lk_error_set(error, LK_ERR_INVALID, "splat radius scale must be a positive number, not %g",
                            options->radius_scale);
    if (!(options->depth_epsilon >= 0) || !isfinite(options->depth_epsilon))
        return lk_error_set(error, LK_ERR_INVALID, "2-pass depth epsilon must be >= 0, not %g", options->depth_epsilon);
    return LK_OK;
}

static lk_status check_points(const lk_mesh *points, lk_error *error)
{
    if (points->vertex_count == 0) return lk_error_set(error, LK_ERR_INVALID, "no points to render");
    if (points->vertex_count > (size_t)INT32_MAX)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu points: one draw call takes at most %d", points->vertex_count,
                            (int)INT32_MAX);
    if (!points->positions) return lk_error_set(error, LK_ERR_INVALID, "the points have no positions");
    if (!points->normals)
        return lk_error_set(error, LK_ERR_INVALID,
                            "the points have no normals, which splats need (estimate them with "
                            "`lodkit sample --estimate-normals` or lk_points_estimate_normals)");
    for (size_t i = 0; i < points->vertex_count; i++) {
        const float *p = points->positions + 3 * i, *n = points->normals + 3 * i;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return lk_error_set(error, LK_ERR_RANGE, "point %zu has a non-finite position", i);
        if (!isfinite(n[0]) || !isfinite(n[1]) || !isfinite(n[2]))
            return lk_error_set(error, LK_ERR_RANGE, "point %zu has a non-finite normal", i);
        if (n[0] == 0 && n[1] == 0 && n[2] == 0)
            return lk_error_set(error, LK_ERR_RANGE, "point %zu has a zero normal, so no orientation", i);
        if (points->radii && (!(points->radii[i] > 0) || !isfinite(points->radii[i])))
            return lk_error_set(error, LK_ERR_RANGE, "point %zu has splat radius %g: radii must be positive and finite",
                                i, (double)points->radii[i]);
    }
    return LK_OK;
}

/* ---- drawing ------------------------------------------------------------ */

static float clamp01(float value) { return value > 0 ? (value < 1 ? value : 1) : 0; /* NaN -> 0 */ }

/* Per-draw uniforms shared by every program using splat.vert.glsl. */
typedef struct splat_uniforms {
    lk__camera camera;
    float eye_scale;
    float size_scale;
    float radius_scale;
    float point_size_range[2];
    float culling;
} splat_uniforms;

static void set_splat_uniforms(GLuint program, const splat_uniforms *u, float depth_offset)
{
    glUseProgram(program);
    glUniformMatrix4fv(glGetUniformLocation(program, "u_view"), 1, GL_FALSE, u->camera.view);
    glUniformMatrix4fv(glGetUniformLocation(program, "u_projection"), 1, GL_FALSE, u->camera.projection);
    glUniformMatrix3fv(glGetUniformLocation(program, "u_normal_matrix"), 1, GL_FALSE, u->camera.normal_matrix);
    glUniform1f(glGetUniformLocation(program, "u_eye_scale"), u->eye_scale);
    glUniform1f(glGetUniformLocation(program, "u_size_scale"), u->size_scale);
    glUniform1f(glGetUniformLocation(program, "u_radius_scale"), u->radius_scale);
    glUniform2f(glGetUniformLocation(program, "u_point_size_range"), u->point_size_range[0], u->point_size_range[1]);
    glUniform1f(glGetUniformLocation(program, "u_culling"), u->culling);
    glUniform1f(glGetUniformLocation(program, "u_depth_offset"), depth_offset);
    GLint location = glGetUniformLocation(program, "u_kernel");
    if (location >= 0) glUniform1i(location, 0);
    location = glGetUniformLocation(program, "u_key_direction");
    if (location >= 0) glUniform3fv(location, 1, key_direction);
}

/* Uploads positions, normals, radii (and colours) into one buffer, each
 * array whole (no interleaving copy on the CPU), and points the attributes
 * at them. The buffer stays with the renderer and is only reallocated to
 * grow: a new multi-megabyte buffer per frame made llvmpipe's (glibc's)
 * heap grow by a buffer per frame for the first few frames (1M points:
 * peak RSS 437 MiB instead of 322). */
static lk_status upload_points(splat_state *state, const lk_mesh *points, const float *radii, const float *clips,
                               const float color[3], lk_error *error)
{
    size_t count = points->vertex_count;
    size_t position_bytes = 3 * sizeof(float) * count, radius_bytes = sizeof(float) * count;
    size_t color_bytes = points->colors ? 4 * sizeof(float) * count : 0,
           clip_bytes = clips ? 4 * sizeof(float) * count : 0;
    size_t total = 2 * position_bytes + radius_bytes + color_bytes + clip_bytes;
    if (total > (size_t)INT32_MAX)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu points need %zu bytes of vertex data, more than one buffer holds",
                            count, total);
    if (!state->point_buffer) glGenBuffers(1, &state->point_buffer);
    glBindBuffer(GL_ARRAY_BUFFER, state->point_buffer);
    if (total > state->point_buffer_bytes) {
        state->point_buffer_bytes = 0;
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)total, NULL, GL_DYNAMIC_DRAW);
        lk_status status = lk__gl_check("allocating the point buffer", error);
        if (status != LK_OK) return status;
        state->point_buffer_bytes = total;
    }
    size_t offset = 0;
    glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)offset, (GLsizeiptr)position_bytes, points->positions);
    glVertexAttribPointer(ATTRIBUTE_POSITION, 3, GL_FLOAT, GL_FALSE, 0, (const void *)(uintptr_t)offset);
    offset += position_bytes;
    glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)offset, (GLsizeiptr)position_bytes, points->normals);
    glVertexAttribPointer(ATTRIBUTE_NORMAL, 3, GL_FLOAT, GL_FALSE, 0, (const void *)(uintptr_t)offset);
    offset += position_bytes;
    glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)offset, (GLsizeiptr)radius_bytes, radii);
    glVertexAttribPointer(ATTRIBUTE_RADIUS, 1, GL_FLOAT, GL_FALSE, 0, (const void *)(uintptr_t)offset);
    offset += radius_bytes;
    glEnableVertexAttribArray(ATTRIBUTE_POSITION);
    glEnableVertexAttribArray(ATTRIBUTE_NORMAL);
    glEnableVertexAttribArray(ATTRIBUTE_RADIUS);
    if (points->colors) {
        glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)offset, (GLsizeiptr)color_bytes, points->colors);
        glVertexAttribPointer(ATTRIBUTE_COLOR, 4, GL_FLOAT, GL_FALSE, 0, (const void *)(uintptr_t)offset);
        glEnableVertexAttribArray(ATTRIBUTE_COLOR);
    } else {
        glDisableVertexAttribArray(ATTRIBUTE_COLOR);
        glVertexAttrib4f(ATTRIBUTE_COLOR, color[0], color[1], color[2], 1.0f);
    }
    if (clips) {
        offset += color_bytes;
        glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)offset, (GLsizeiptr)clip_bytes, clips);
        glVertexAttribPointer(ATTRIBUTE_CLIP, 4, GL_FLOAT, GL_FALSE, 0, (const void *)(uintptr_t)offset);
        glEnableVertexAttribArray(ATTRIBUTE_CLIP);
    } else {
        glDisableVertexAttribArray(ATTRIBUTE_CLIP);
        glVertexAttrib4f(ATTRIBUTE_CLIP, 0.0f, 0.0f, 0.0f, 0.0f);
    }
    return lk__gl_check("uploading the points", error);
}

/* Leaves the GL state as the other drawing code of src/gl expects it. */
static void restore_state(void)
{
    for (GLuint location = 0; location <= ATTRIBUTE_CLIP; location++) glDisableVertexAttribArray(location);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    glBindTexture(GL_TEXTURE_2D, 0);
    glUseProgram(0);
    glDisable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ZERO);
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_LESS);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
}

/* The three programs of the 2-pass mode. */
typedef struct two_pass_programs {
    GLuint visibility, accumulate, normalize;
} two_pass_programs;

static lk_status get_two_pass_programs(lk_renderer *renderer, two_pass_programs *programs, lk_error *error)
{
    lk_status status = lk__gl_program(renderer, LK__PROGRAM_SPLAT_VISIBILITY, "splat.vert", "splat_visibility.frag",
                                      splat_attributes, &programs->visibility, error);
    if (status == LK_OK)
        status = lk__gl_program(renderer, LK__PROGRAM_SPLAT_ACCUMULATE, "splat.vert", "splat_accumulate.frag",
                                splat_attributes, &programs->accumulate, error);
    if (status == LK_OK)
        status = lk__gl_program(renderer, LK__PROGRAM_SPLAT_NORMALIZE, "fullscreen.vert", "splat_normalize.frag",
                                fullscreen_attributes, &programs->normalize, error);
    return status;
}

static void draw_two_pass(lk_renderer *renderer, const splat_state *state, const two_pass_programs *programs,
                          const splat_uniforms *uniforms, const float background[3], double depth_epsilon,
                          GLsizei count)
{
    /* Passes 1 and 2 draw into the accumulation texture, whose framebuffer
     * shares the renderer's depth buffer. */
    glBindFramebuffer(GL_FRAMEBUFFER, state->accumulation_framebuffer);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);

    /* 1: visibility, depth only, every splat pushed back by epsilon radii. */
    glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    glDisable(GL_BLEND);
    set_splat_uniforms(programs->visibility, uniforms, (float)depth_epsilon);
    glDrawArrays(GL_POINTS, 0, count);

    /* 2: accumulation of every splat in front of that depth. */
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthFunc(GL_LEQUAL);
    glDepthMask(GL_FALSE);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE);
    set_splat_uniforms(programs->accumulate, uniforms, 0.0f);
    glUniform1f(glGetUniformLocation(programs->accumulate, "u_weight_scale"),
                state->target == TARGET_RGBA8 ? RGBA8_WEIGHT_SCALE : 1.0f);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, state->kernel_texture);
    glDrawArrays(GL_POINTS, 0, count);

    /* 3: normalisation into the renderer's framebuffer over the background
     * (its depth buffer keeps the visibility pass's depths). */
    glBindFramebuffer(GL_FRAMEBUFFER, renderer->framebuffer);
    glClearColor(background[0], background[1], background[2], 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    glDisable(GL_BLEND);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(programs->normalize);
    glUniform1i(glGetUniformLocation(programs->normalize, "u_accumulated"), 0);
    glBindTexture(GL_TEXTURE_2D, state->accumulation_texture);
    glDisableVertexAttribArray(ATTRIBUTE_NORMAL);
    glDisableVertexAttribArray(ATTRIBUTE_RADIUS);
    glDisableVertexAttribArray(ATTRIBUTE_COLOR);
    glDisableVertexAttribArray(ATTRIBUTE_CLIP);
    glBindBuffer(GL_ARRAY_BUFFER, state->fullscreen_buffer);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 0, NULL);
    glEnableVertexAttribArray(0);
    glDrawArrays(GL_TRIANGLES, 0, 3);
}

/* Validates, uploads and draws in one of the modes; *milliseconds is the
 * wall time of the draw calls up to glFinish. given_clips (offsets in
 * radii), when not NULL, are the clip lines drawn with clip_borders instead
 * of estimated ones. */
static lk_status draw_points(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                             draw_mode mode, const float *given_clips, double *milliseconds, lk_error *error)
{
    if (!renderer) return lk_error_set(error, LK_ERR_INVALID, "no renderer");
    if (!points) return lk_error_set(error, LK_ERR_INVALID, "no point set");
    lk_render_options defaults;
    if (!options) {
        lk_render_options_default(&defaults);
        options = &defaults;
    }
    lk_status status = check_options(options, error);
    if (status == LK_OK) status = check_points(points, error);
    if (status != LK_OK) return status;

    lk__model_normalization normalization;
    {
        float box_min[3], box_max[3];
        lk_mesh_bounds(points, box_min, box_max);
        lk__normalization_setup(options, box_min, box_max, &normalization);
    }
    lk_mesh drawn;
    lk_mesh_init(&drawn);
    drawn.vertex_count = points->vertex_count;
    drawn.normals = points->normals;
    drawn.colors = points->colors;
    drawn.positions = lk__normalized_positions(&normalization, points->positions, points->vertex_count);
    drawn.radii = lk__malloc_array(points->vertex_count, sizeof *drawn.radii);
    if (!drawn.positions || !drawn.radii) {
        free(drawn.positions);
        free(drawn.radii);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu normalised points", points->vertex_count);
    }
    if (points->radii) {
        for (size_t i = 0; i < points->vertex_count; i++) {
            /* Scaled like the positions, and kept > 0 and finite. */
            double radius = (double)points->radii[i] * normalization.scale;
            drawn.radii[i] = radius > FLT_MAX ? FLT_MAX : radius < FLT_MIN ? FLT_MIN : (float)radius;
        }
    } else {
        /* Without radii: the k-nearest-neighbour spacing of the normalised
         * positions (already in the drawn scale). */
        lk_mesh view;
        lk_mesh_init(&view);
        view.vertex_count = points->vertex_count;
        view.positions = drawn.positions;
        status = lk_points_estimate_radii(&view, DEFAULT_RADIUS_NEIGHBOURS, 1.0, error);
        if (status == LK_OK) memcpy(drawn.radii, view.radii, points->vertex_count * sizeof *drawn.radii);
        free(view.radii);
        for (size_t i = 0; status == LK_OK && i < points->vertex_count; i++)
            if (!(drawn.radii[i] > 0) || !isfinite(drawn.radii[i])) /* e.g. every point at one place */
                status = lk_error_set(error, LK_ERR_RANGE,
                                      "point %zu: estimated splat radius %g is not positive (duplicate points?)", i,
                                      (double)drawn.radii[i] / normalization.scale);
        if (status != LK_OK) {
            free(drawn.positions);
            free(drawn.radii);
            return status;
        }
    }
    float *drawn_radii = drawn.radii, *drawn_positions = drawn.positions; /* freed below */
    const float *radii = drawn.radii;
    /* Clip lines of the drawn (normalised) points: their offsets are then in
     * the drawn scale too. Flat points are squares: nothing to clip. */
    float *clips = NULL;
    if (options->clip_borders && given_clips && (mode == DRAW_ONE_PASS || mode == DRAW_TWO_PASS)) {
        /* offsets in radii: the normalisation scales radius and offset alike */
        clips = lk__malloc_array(points->vertex_count, 4 * sizeof *clips);
        if (!clips) {
            free(drawn_radii);
            free(drawn_positions);
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu clip lines", points->vertex_count);
        }
        memcpy(clips, given_clips, points->vertex_count * 4 * sizeof *clips);
    } else if (options->clip_borders && (mode == DRAW_ONE_PASS || mode == DRAW_TWO_PASS)) {
        clips = lk__malloc_array(points->vertex_count, 4 * sizeof *clips);
        status = clips ? lk_points_estimate_clips(&drawn, CLIP_NEIGHBOURS, clips, error)
                       : lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu clip lines", points->vertex_count);
        /* the shader takes the offset in radii (splat.vert.glsl) */
        for (size_t i = 0; status == LK_OK && i < points->vertex_count; i++) clips[4 * i + 3] /= drawn.radii[i];
        if (status != LK_OK) {
            free(clips);
            free(drawn_radii);
            free(drawn_positions);
            return status;
        }
    }

    splat_state *state = NULL;
    GLuint program = 0;
    two_pass_programs two_pass = {0, 0, 0};
    status = lk__gl_begin(renderer, error);
    if (status == LK_OK) status = get_state(renderer, &state, error);
    if (status == LK_OK && mode == DRAW_TWO_PASS) status = choose_target(renderer, state, error);
    if (status == LK_OK) {
        if (mode == DRAW_TWO_PASS)
            status = get_two_pass_programs(renderer, &two_pass, error);
        else if (mode == DRAW_ONE_PASS)
            status = lk__gl_program(renderer, LK__PROGRAM_SPLAT, "splat.vert", "splat.frag", splat_attributes, &program,
                                    error);
        else if (mode == DRAW_FLAT || mode == DRAW_COUNT_FRAGMENTS)
            status = lk__gl_program(renderer, LK__PROGRAM_FLAT_POINTS, "splat.vert", "points_flat.frag",
                                    splat_attributes, &program, error);
    }
    if (status != LK_OK) {
        free(clips);
        free(drawn_radii);
        free(drawn_positions);
        return status;
    }

    splat_uniforms uniforms;
    lk__camera_setup(&normalization.options, NULL, NULL, renderer->width, renderer->height, &uniforms.camera);
    /* as mesh_draw.c: keeps the view vector of mediump shaders near unit length */
    uniforms.eye_scale = uniforms.camera.far_plane > 0 ? 1.0f / uniforms.camera.far_plane : 1.0f;
    /* eq. 1: size = 2 r n / z_eye * h_vp / (t - b) */
    uniforms.size_scale = (float)((double)uniforms.camera.near_plane * (double)renderer->height /
                                  ((double)uniforms.camera.top - (double)uniforms.camera.bottom));
    uniforms.radius_scale = (float)options->radius_scale;
    uniforms.point_size_range[0] = (float)renderer->point_size_range[0];
    uniforms.point_size_range[1] = (float)renderer->point_size_range[1];
    uniforms.culling = options->backface_culling ? 1.0f : 0.0f;

    float count_color[3] = {1.0f / 255.0f, 1.0f / 255.0f, 1.0f / 255.0f};
    float color[3] = {clamp01(options->color[0]), clamp01(options->color[1]), clamp01(options->color[2])};
    float background[3] = {clamp01(options->background[0]), clamp01(options->background[1]),
                           clamp01(options->background[2])};
    status = upload_points(state, &drawn, radii, clips, mode == DRAW_COUNT_FRAGMENTS ? count_color : color, error);
    free(clips);
    free(drawn_radii);
    free(drawn_positions);
    if (status != LK_OK) {
        restore_state();
        return status;
    }
    GLsizei count = (GLsizei)points->vertex_count;
    /* Mesh drawing may have left its state behind: set all we rely on. */
    glDisable(GL_CULL_FACE);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_STENCIL_TEST);
    glDisable(GL_POLYGON_OFFSET_FILL);
    glClearDepthf(1.0f);
    glFinish(); /* the upload is setup, not drawing */
    double start = lk__now();
    if (mode == DRAW_TWO_PASS) {
        draw_two_pass(renderer, state, &two_pass, &uniforms, background, options->depth_epsilon, count);
    } else {
        glBindFramebuffer(GL_FRAMEBUFFER, renderer->framebuffer);
        glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        glDepthMask(GL_TRUE);
        if (mode == DRAW_COUNT_FRAGMENTS)
            glClearColor(0, 0, 0, 0);
        else
            glClearColor(background[0], background[1], background[2], 1.0f);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        set_splat_uniforms(program, &uniforms, 0.0f);
        if (mode == DRAW_ONE_PASS) {
            glEnable(GL_DEPTH_TEST);
            glDepthFunc(GL_LEQUAL);
            glEnable(GL_BLEND);
            /* "over" for colour; alpha accumulates towards 1 so the image stays opaque */
            glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
            glActiveTexture(GL_TEXTURE0);
            glBindTexture(GL_TEXTURE_2D, state->kernel_texture);
        } else if (mode == DRAW_FLAT) {
            glEnable(GL_DEPTH_TEST);
            glDepthFunc(GL_LESS);
            glDisable(GL_BLEND);
            glUniform1f(glGetUniformLocation(program, "u_disc"), 0.0f);
        } else {
            glDisable(GL_DEPTH_TEST);
            glEnable(GL_BLEND);
            glBlendFunc(GL_ONE, GL_ONE);
            glUniform1f(glGetUniformLocation(program, "u_disc"), 1.0f);
        }
        glDrawArrays(GL_POINTS, 0, count);
    }
    glFinish();
    if (milliseconds) *milliseconds = 1000.0 * (lk__now() - start);
    if (status == LK_OK) status = lk__gl_check("drawing the splats", error);
    restore_state();
    glBindFramebuffer(GL_FRAMEBUFFER, renderer->framebuffer);
    return status;
}

lk_status lk_render_points(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                           lk_render_stats *stats, lk_error *error)
{
    return lk__render_points_clipped(renderer, points, NULL, options, stats, error);
}

lk_status lk__render_points_clipped(lk_renderer *renderer, const lk_mesh *points, const float *clips,
                                    const lk_render_options *options, lk_render_stats *stats, lk_error *error)
{
    double milliseconds = 0;
    draw_mode mode = DRAW_ONE_PASS;
    if (options && options->flat_points)
        mode = DRAW_FLAT;
    else if (options && options->passes == 2)
        mode = DRAW_TWO_PASS;
    lk_status status = draw_points(renderer, points, options, mode, clips, &milliseconds, error);
    if (status == LK_OK && stats) {
        memset(stats, 0, sizeof *stats);
        stats->milliseconds = milliseconds;
        stats->primitives = points->vertex_count;
    }
    return status;
}

/* ---- internal hooks for tests and benches -------------------------------- */

/* Counts the fragments the splats of `points` make under `options` (culling
 * included): every disc adds 1/255 into a cleared buffer with the depth test
 * off, and the red channel is summed. LK_ERR_LIMIT when some pixel reaches
 * 255 fragments (the count would be clipped). The framebuffer holds the
 * count image afterwards. */
lk_status lk__splat_count_fragments(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                                    uint64_t *fragment_count, lk_error *error);
lk_status lk__splat_count_fragments(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                                    uint64_t *fragment_count, lk_error *error)
{
    if (!fragment_count) return lk_error_set(error, LK_ERR_INVALID, "fragment_count is NULL");
    lk_status status = draw_points(renderer, points, options, DRAW_COUNT_FRAGMENTS, NULL, NULL, error);
    if (status != LK_OK) return status;
    size_t pixel_count = (size_t)renderer->width * renderer->height;
    unsigned char *rgba = lk__malloc_array(pixel_count, 4);
    if (!rgba) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu pixels", pixel_count);
    status = lk_renderer_read_pixels(renderer, rgba, error);
    uint64_t total = 0;
    for (size_t i = 0; status == LK_OK && i < pixel_count; i++) {
        if (rgba[4 * i] == 255)
            status = lk_error_set(error, LK_ERR_LIMIT, "more than 254 splat fragments on one pixel: counts would clip");
        total += rgba[4 * i];
    }
    free(rgba);
    if (status == LK_OK) *fragment_count = total;
    return status;
}

/* Test hook: force_rgba8 = 1 makes 2-pass splatting use the RGBA8 fallback
 * even when a floating-point target is renderable, 0 restores the normal
 * choice, -1 changes nothing. Returns the name of the 2-pass target (chosen
 * now if it was not yet), e.g. "RGBA16F (half float)". */
const char *lk__splat_target(lk_renderer *renderer, int force_rgba8);
const char *lk__splat_target(lk_renderer *renderer, int force_rgba8)
{
    if (!renderer) return target_names[TARGET_NONE];
    splat_state *state = NULL;
    if (lk__gl_begin(renderer, NULL) != LK_OK || get_state(renderer, &state, NULL) != LK_OK)
        return target_names[TARGET_NONE];
    if (force_rgba8 >= 0 && (force_rgba8 != 0) != (state->force_rgba8 != 0)) {
        state->force_rgba8 = force_rgba8 != 0;
        delete_target(state);
    }
    if (state->target == TARGET_NONE) choose_target(renderer, state, NULL);
    return target_names[state->target];
}
