/* SPDX-License-Identifier: MIT */
/* Internal contract between the files of src/gl/: the renderer object, the
 * shader loader and the camera. Not installed. */
#ifndef LODKIT_GL_INTERNAL_H
#define LODKIT_GL_INTERNAL_H

#include <EGL/egl.h>
#include <GLES2/gl2.h>
#include <GLES2/gl2ext.h>

#include "internal.h"

/* Shader programs, compiled on first use and kept with the renderer. */
typedef enum lk__program {
    LK__PROGRAM_MESH = 0,         /* mesh.vert + mesh.frag: lit triangles */
    LK__PROGRAM_WIREFRAME,        /* mesh.vert + wire.frag: edges overlay */
    LK__PROGRAM_SPLAT,            /* splat.vert + splat.frag: 1-pass Phong splats */
    LK__PROGRAM_SPLAT_VISIBILITY, /* splat.vert + splat_visibility.frag: 2-pass, depth only */
    LK__PROGRAM_SPLAT_ACCUMULATE, /* splat.vert + splat_accumulate.frag: 2-pass, weighted sums */
    LK__PROGRAM_SPLAT_NORMALIZE,  /* fullscreen.vert + splat_normalize.frag: colour / weight */
    LK__PROGRAM_FLAT_POINTS,      /* splat.vert + points_flat.frag: baseline square points */
    LK__PROGRAM_TEXTURED,         /* mesh_textured.vert + .frag: a scene's materials */
    LK__PROGRAM_COUNT
} lk__program;

struct lk_renderer {
    EGLDisplay display;
    EGLContext context;
    unsigned width, height;
    GLuint framebuffer, color_buffer, depth_buffer; /* RGBA8 + DEPTH24 (or 16) */
    GLint point_size_range[2];                      /* GL_ALIASED_POINT_SIZE_RANGE */
    char description[256];
    GLuint programs[LK__PROGRAM_COUNT]; /* 0 until compiled */
    /* Owned by src/gl/splat.c (kernel texture, accumulation targets...):
     * freed through splat_state_free by lk_renderer_free. */
    void *splat_state;
    void (*splat_state_free)(struct lk_renderer *renderer);
};

/* The key light of lighting.glsl's u_key_direction (eye space, unit, towards
 * the light: upper left, in front), shared by meshes and splats so that
 * both renders of one model look alike. */
#define LK__KEY_LIGHT_DIRECTION                                                                                        \
    {                                                                                                                  \
        -0.4444f, 0.6667f, 0.5981f                                                                                     \
    }

/* Shader text embedded from src/shaders at build time (generated file). */
const char *lk__shader_source(const char *name);

/* Compiles and links (once) the program `which` from the named shader
 * files, binding attribute locations in order from `attributes` (NULL-
 * terminated list, may be NULL); the info log goes into the error. */
lk_status lk__gl_program(lk_renderer *renderer, lk__program which, const char *vertex_shader,
                         const char *fragment_shader, const char *const *attributes, GLuint *program, lk_error *error);

/* Makes the renderer's context current and binds its framebuffer and
 * viewport. */
lk_status lk__gl_begin(lk_renderer *renderer, lk_error *error);
/* Whether the current context lists the GL extension `name`. */
int lk__gl_has_extension(const char *name);
/* glGetError check: LK_ERR_UNSUPPORTED naming `what` on failure. */
lk_status lk__gl_check(const char *what, lk_error *error);

/* Camera for a render: column-major matrices as OpenGL expects. */
typedef struct lk__camera {
    float view[16];
    float projection[16];
    float normal_matrix[9];                   /* upper 3x3 of view (rigid: its own inverse transpose) */
    float eye[3];                             /* world-space camera position */
    float near_plane, far_plane, top, bottom; /* frustum at the near plane (eq. 1 of the splatting paper) */
    float radius;                             /* bounding-sphere radius of the framed box */
} lk__camera;

/* Orbit camera from the options around the box (options->bounds when
 * use_bounds, else the given box), near/far fitted to the sphere. */
void lk__camera_setup(const lk_render_options *options, const float box_min[3], const float box_max[3], unsigned width,
                      unsigned height, lk__camera *camera);

/* GL computes in float, flushes denormals and cannot take 1 / far of a
 * model 1e38 across: drawn as stored, a model near FLT_MAX or one of
 * denormal size comes out blank. So the mesh and splat renderers upload
 * positions normalised, in double on the CPU, as (p - origin) * scale with
 * the framed box mapped into the unit sphere, and set the camera up on the
 * normalised box (the picture is the same: the camera frames the box
 * whatever its size). */
typedef struct lk__model_normalization {
    double origin[3];
    double scale;
    lk_render_options options; /* the caller's, with use_bounds = the normalised box */
} lk__model_normalization;
void lk__normalization_setup(const lk_render_options *options, const float box_min[3], const float box_max[3],
                             lk__model_normalization *out);
/* The normalised copy of `count` positions (NULL when out of memory). */
float *lk__normalized_positions(const lk__model_normalization *n, const float *positions, size_t count);

/* src/gl/mesh_draw.c, shared with scene_draw.c: the render options'
 * checks, and per-vertex normals summed from the faces around each vertex
 * (area-weighted, unit; +y where no face gives one) in a new array. */
lk_status lk__render_check_options(const lk_render_options *options, lk_error *error);
float *lk__face_averaged_normals(const lk_mesh *mesh, lk_error *error);
/* The state an opaque, depth-tested, two-sided draw relies on (splats may
 * have left blending, culling... behind), and the clear colour and depth. */
void lk__gl_opaque_state(const lk_render_options *options);
/* src/gl/texture_image.c: a PNG or JPEG into RGBA8, top row first (a new
 * array, free). */
lk_status lk__decode_image(const unsigned char *data, size_t size, unsigned char **rgba, unsigned *width,
                           unsigned *height, lk_error *error);

/* Test hook of src/gl/mesh_draw.c: lk_render_mesh forcing how indices
 * reach the GPU: 1 = 32-bit indices, 2 = as if GL_OES_element_index_uint
 * were missing, 3 = vertices copied per index, drawn without indices. */
lk_status lk__render_mesh_index_mode(lk_renderer *renderer, const lk_mesh *mesh, const lk_render_options *options,
                                     int index_mode, lk_render_stats *stats, lk_error *error);

/* lk_render_points with the clip lines given (4 floats a point, offsets in
 * radii: lk_octree_load_node_clips') instead of estimated when
 * options->clip_borders; clips may be NULL (then estimated). */
lk_status lk__render_points_clipped(lk_renderer *renderer, const lk_mesh *points, const float *clips,
                                    const lk_render_options *options, lk_render_stats *stats, lk_error *error);

/* Test hooks of src/gl/splat.c. Counts the fragments the splats shade
 * (discs adding 1/255 each with the depth test off, red channel summed;
 * LK_ERR_LIMIT when a pixel saturates). */
lk_status lk__splat_count_fragments(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                                    uint64_t *count, lk_error *error);
/* Name of the 2-pass accumulation target; force_rgba8 = 1 forces the RGBA8
 * fallback, 0 restores the normal choice, -1 only asks. */
const char *lk__splat_target(lk_renderer *renderer, int force_rgba8);

#endif
