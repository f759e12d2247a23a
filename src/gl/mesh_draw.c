/* SPDX-License-Identifier: MIT */
/* Lit triangle meshes: indexed triangles or one triangle strip, optional
 * wireframe overlay, through mesh.vert/mesh.frag/wire.frag. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"

/* How element lists reach the GPU. GLES2 core only has 16-bit indices;
 * GL_OES_element_index_uint adds 32-bit ones. */
enum {
    INDEX_AUTO = 0,  /* 16-bit when every vertex fits, else 32-bit, else expanded */
    INDEX_32 = 1,    /* 32-bit indices (fails without GL_OES_element_index_uint) */
    INDEX_16 = 2,    /* as a driver without the extension: 16-bit when they fit, else expanded */
    INDEX_EXPAND = 3 /* no indices: attributes copied per element, glDrawArrays */
};

/* Test hook (the same as lk_render_mesh with the index path forced to one
 * of the INDEX_* values above) so that the unit tests reach the paths a
 * driver without GL_OES_element_index_uint would take. */
lk_status lk__render_mesh_index_mode(lk_renderer *renderer, const lk_mesh *mesh, const lk_render_options *options,
                                     int index_mode, lk_render_stats *stats, lk_error *error);

enum { ATTRIBUTE_POSITION = 0, ATTRIBUTE_NORMAL, ATTRIBUTE_COLOR, ATTRIBUTE_COUNT };
static const char *const attribute_names[] = {"a_position", "a_normal", "a_color", NULL};
static const GLint attribute_components[ATTRIBUTE_COUNT] = {3, 3, 4};

/* Vertex attributes of the mesh, as uploaded (NULL colours: constant). */
typedef struct vertex_source {
    const float *arrays[ATTRIBUTE_COUNT];
    size_t vertex_count;
} vertex_source;

/* One prepared draw call: indices in a buffer, or (expanded) its own copy
 * of the attributes, one per element. */
typedef struct gpu_draw {
    GLenum mode;       /* GL_TRIANGLES, GL_TRIANGLE_STRIP or GL_LINES */
    GLsizei count;     /* elements */
    GLenum index_type; /* GL_UNSIGNED_SHORT / GL_UNSIGNED_INT, 0 when expanded */
    GLuint index_buffer;
    GLuint attribute_buffers[ATTRIBUTE_COUNT]; /* expanded only */
} gpu_draw;

static void gpu_draw_free(gpu_draw *draw)
{
    if (draw->index_buffer) glDeleteBuffers(1, &draw->index_buffer);
    for (int i = 0; i < ATTRIBUTE_COUNT; i++)
        if (draw->attribute_buffers[i]) glDeleteBuffers(1, &draw->attribute_buffers[i]);
    memset(draw, 0, sizeof *draw);
}

static lk_status upload(GLenum target, const void *data, size_t bytes, GLuint *buffer, const char *what,
                        lk_error *error)
{
    if (bytes > (size_t)PTRDIFF_MAX)
        return lk_error_set(error, LK_ERR_LIMIT, "%s: %zu bytes exceed what OpenGL ES can address", what, bytes);
    glGenBuffers(1, buffer);
    glBindBuffer(target, *buffer);
    glBufferData(target, (GLsizeiptr)bytes, data, GL_STATIC_DRAW);
    return lk__gl_check(what, error);
}

/* Uploads the elements of one draw call in the chosen index format. */
static lk_status prepare_draw(const vertex_source *source, GLenum mode, const uint32_t *elements, size_t count,
                              int index_mode, gpu_draw *draw, lk_error *error)
{
    memset(draw, 0, sizeof *draw);
    if (count > (size_t)INT_MAX)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu indices in one draw call exceed OpenGL ES's limit of %d", count,
                            INT_MAX);
    if (count > SIZE_MAX / sizeof *elements)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu indices do not fit in memory", count);
    draw->mode = mode;
    draw->count = (GLsizei)count;
    if (count == 0) return LK_OK;
    lk_status status = LK_OK;
    if (index_mode == INDEX_32) {
        draw->index_type = GL_UNSIGNED_INT;
        status = upload(GL_ELEMENT_ARRAY_BUFFER, elements, count * sizeof *elements, &draw->index_buffer,
                        "uploading 32-bit indices", error);
    } else if (index_mode == INDEX_16) {
        uint16_t *short_indices = lk__malloc_array(count, sizeof *short_indices);
        if (!short_indices) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu 16-bit indices", count);
        for (size_t i = 0; i < count; i++) short_indices[i] = (uint16_t)elements[i];
        draw->index_type = GL_UNSIGNED_SHORT;
        status = upload(GL_ELEMENT_ARRAY_BUFFER, short_indices, count * sizeof *short_indices, &draw->index_buffer,
                        "uploading 16-bit indices", error);
        free(short_indices);
    } else {
        /* Expanded: every element gets its own copy of the attributes, so
         * any vertex count works without 32-bit indices. */
        for (int a = 0; a < ATTRIBUTE_COUNT && status == LK_OK; a++) {
            const float *array = source->arrays[a];
            if (!array) continue;
            size_t components = (size_t)attribute_components[a];
            if (count > SIZE_MAX / components) return lk_error_set(error, LK_ERR_LIMIT, "draw call too large");
            float *expanded = lk__malloc_array(count * components, sizeof *expanded);
            if (!expanded) return lk_error_set(error, LK_ERR_NOMEM, "out of memory expanding %zu vertices", count);
            for (size_t i = 0; i < count; i++)
                memcpy(expanded + i * components, array + (size_t)elements[i] * components,
                       components * sizeof *expanded);
            status = upload(GL_ARRAY_BUFFER, expanded, count * components * sizeof *expanded,
                            &draw->attribute_buffers[a], "uploading expanded vertices", error);
            free(expanded);
        }
    }
    return status;
}

static void bind_attributes(const gpu_draw *draw, const GLuint shared[ATTRIBUTE_COUNT], const float color[3])
{
    for (int a = 0; a < ATTRIBUTE_COUNT; a++) {
        GLuint buffer = draw->index_type ? shared[a] : draw->attribute_buffers[a];
        if (buffer) {
            glBindBuffer(GL_ARRAY_BUFFER, buffer);
            glEnableVertexAttribArray((GLuint)a);
            glVertexAttribPointer((GLuint)a, attribute_components[a], GL_FLOAT, GL_FALSE, 0, NULL);
        } else {
            /* Only colours can be absent: one colour for the whole model. */
            glDisableVertexAttribArray((GLuint)a);
            glVertexAttrib4f((GLuint)a, color[0], color[1], color[2], 1.0f);
        }
    }
}

static void execute_draw(const gpu_draw *draw, const GLuint shared[ATTRIBUTE_COUNT], const float color[3])
{
    if (draw->count == 0) return;
    bind_attributes(draw, shared, color);
    if (draw->index_type) {
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, draw->index_buffer);
        glDrawElements(draw->mode, draw->count, draw->index_type, NULL);
    } else {
        glDrawArrays(draw->mode, 0, draw->count);
    }
}

/* Per-vertex normals from the faces: the sum of the unnormalised face
 * normals (cross products, so each face weighs by its area) of the
 * triangles around each vertex. Smooth shading matches the contract
 * ("normals averaged from the faces") and keeps the mesh indexed; flat
 * shading would need every corner duplicated. */
float *lk__face_averaged_normals(const lk_mesh *mesh, lk_error *error)
{
    float *normals = lk__calloc_array(mesh->vertex_count, 3 * sizeof *normals);
    if (!normals) {
        lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu vertex normals", mesh->vertex_count);
        return NULL;
    }
    const float *p = mesh->positions;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *corner = mesh->indices + 3 * t;
        const float *a = p + 3 * (size_t)corner[0], *b = p + 3 * (size_t)corner[1], *c = p + 3 * (size_t)corner[2];
        double u[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
        double v[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++) normals[3 * (size_t)corner[k] + j] += (float)n[j];
    }
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        float *n = normals + 3 * i;
        double length = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (length > 0 && isfinite(length)) {
            for (int j = 0; j < 3; j++) n[j] = (float)(n[j] / length);
        } else {
            /* Only degenerate triangles (or none) touch this vertex: any
             * unit vector keeps the shader's normalize() defined. */
            n[0] = 0.0f;
            n[1] = 1.0f;
            n[2] = 0.0f;
        }
    }
    return normals;
}

lk_status lk__render_check_options(const lk_render_options *options, lk_error *error)
{
    if (!isfinite(options->fov_y) || options->fov_y <= 0 || options->fov_y >= 180)
        return lk_error_set(error, LK_ERR_INVALID, "field of view %g: must be in (0, 180) degrees", options->fov_y);
    if (!isfinite(options->distance) || options->distance < 0)
        return lk_error_set(error, LK_ERR_INVALID, "camera distance %g: must be >= 0 (0 frames the model)",
                            options->distance);
    if (!isfinite(options->azimuth) || !isfinite(options->elevation))
        return lk_error_set(error, LK_ERR_INVALID, "camera angles must be finite");
    for (int k = 0; k < 3; k++) {
        if (!isfinite(options->background[k]) || !isfinite(options->color[k]))
            return lk_error_set(error, LK_ERR_INVALID, "background and surface colours must be finite");
        if (options->use_bounds && (!isfinite(options->bounds_min[k]) || !isfinite(options->bounds_max[k])))
            return lk_error_set(error, LK_ERR_INVALID, "camera bounds must be finite");
    }
    return LK_OK;
}

static float clamp01(float value) { return value < 0 ? 0 : value > 1 ? 1 : value; }

void lk__gl_opaque_state(const lk_render_options *options)
{
    /* Splat drawing may have left its state behind: set all we rely on. */
    glDisable(GL_BLEND);
    glDisable(GL_CULL_FACE); /* two-sided lighting: back faces are drawn */
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_STENCIL_TEST);
    glDisable(GL_POLYGON_OFFSET_FILL);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glDepthMask(GL_TRUE);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glClearColor(clamp01(options->background[0]), clamp01(options->background[1]), clamp01(options->background[2]),
                 1.0f);
    glClearDepthf(1.0f);
}

lk_status lk__render_mesh_index_mode(lk_renderer *renderer, const lk_mesh *mesh, const lk_render_options *options,
                                     int index_mode, lk_render_stats *stats, lk_error *error)
{
    if (stats) memset(stats, 0, sizeof *stats);
    if (!renderer || !mesh) return lk_error_set(error, LK_ERR_INVALID, "lk_render_mesh: NULL renderer or mesh");
    if (mesh->triangle_count == 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "the model has no triangles (a point set of %zu points?): use lk_render_points",
                            mesh->vertex_count);
    lk_render_options defaults;
    if (!options) {
        lk_render_options_default(&defaults);
        options = &defaults;
    }
    lk_status status = lk__render_check_options(options, error);
    if (status != LK_OK) return status;
    /* Out-of-range indices would make the driver read past the buffers:
     * validate what is drawn (radii and texture coordinates are not). */
    lk_mesh drawn = *mesh;
    drawn.radii = NULL;
    drawn.texcoords = NULL;
    status = lk_mesh_validate(&drawn, error);
    if (status != LK_OK) return status;
    /* Byte sizes below are products of these counts: keep them in size_t
     * (and in a signed GLsizeiptr, checked by upload). */
    if (mesh->vertex_count > SIZE_MAX / (4 * sizeof(float)))
        return lk_error_set(error, LK_ERR_LIMIT, "%zu vertices do not fit in memory", mesh->vertex_count);
    if (mesh->triangle_count > (size_t)INT_MAX / 3)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu triangles exceed what one OpenGL ES draw call takes",
                            mesh->triangle_count);

    status = lk__gl_begin(renderer, error);
    if (status != LK_OK) return status;
    GLuint mesh_program = 0, wire_program = 0;
    status =
        lk__gl_program(renderer, LK__PROGRAM_MESH, "mesh.vert", "mesh.frag", attribute_names, &mesh_program, error);
    if (status == LK_OK && options->wireframe)
        status = lk__gl_program(renderer, LK__PROGRAM_WIREFRAME, "mesh.vert", "wire.frag", attribute_names,
                                &wire_program, error);
    if (status != LK_OK) return status;

    int has_uint = lk__gl_has_extension("GL_OES_element_index_uint");
    if (index_mode == INDEX_AUTO)
        index_mode = mesh->vertex_count <= 65536 ? INDEX_16 : has_uint ? INDEX_32 : INDEX_EXPAND;
    else if (index_mode == INDEX_16 && mesh->vertex_count > 65536)
        index_mode = INDEX_EXPAND;
    if (index_mode == INDEX_32 && !has_uint)
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "32-bit indices need GL_OES_element_index_uint");
    if (index_mode < INDEX_AUTO || index_mode > INDEX_EXPAND)
        return lk_error_set(error, LK_ERR_INVALID, "unknown index mode %d", index_mode);

    float *computed_normals = NULL;
    uint32_t *strip = NULL;
    lk_edge_adjacency edges = {0};
    gpu_draw fill = {0}, wire = {0};
    GLuint shared[ATTRIBUTE_COUNT] = {0, 0, 0};

    lk__model_normalization normalization;
    {
        float box_min[3], box_max[3];
        lk_mesh_bounds(mesh, box_min, box_max);
        lk__normalization_setup(options, box_min, box_max, &normalization);
    }
    float *drawn_positions = lk__normalized_positions(&normalization, mesh->positions, mesh->vertex_count);
    if (!drawn_positions)
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu vertex positions", mesh->vertex_count);
    /* The normals too come from the normalised positions: the cross
     * products of a 1e38 model overflow float, those of a 1e-40 one vanish. */
    lk_mesh normalized_mesh = *mesh;
    normalized_mesh.positions = drawn_positions;
    vertex_source source = {{drawn_positions, mesh->normals, mesh->colors}, mesh->vertex_count};
    if (!mesh->normals) {
        computed_normals = lk__face_averaged_normals(&normalized_mesh, error);
        if (!computed_normals) {
            free(drawn_positions);
            return LK_ERR_NOMEM;
        }
        source.arrays[ATTRIBUTE_NORMAL] = computed_normals;
    }
    if (index_mode != INDEX_EXPAND) {
        for (int a = 0; a < ATTRIBUTE_COUNT && status == LK_OK; a++) {
            if (!source.arrays[a]) continue;
            size_t bytes = mesh->vertex_count * (size_t)attribute_components[a] * sizeof(float);
            status = upload(GL_ARRAY_BUFFER, source.arrays[a], bytes, &shared[a], "uploading vertices", error);
        }
    }

    size_t primitives = 0;
    if (status == LK_OK && options->strips) {
        size_t strip_length = 0;
        status = lk_stripify(mesh->indices, mesh->triangle_count, mesh->vertex_count, LK_STRIPIFY_BEST, &strip,
                             &strip_length, NULL, error);
        if (status == LK_OK)
            status = prepare_draw(&source, GL_TRIANGLE_STRIP, strip, strip_length, index_mode, &fill, error);
        primitives = strip_length >= 3 ? strip_length - 2 : 0;
        if (strip_length < 3) fill.count = 0; /* nothing but degenerate triangles */
    } else if (status == LK_OK) {
        status = prepare_draw(&source, GL_TRIANGLES, mesh->indices, 3 * mesh->triangle_count, index_mode, &fill, error);
        primitives = mesh->triangle_count;
    }
    if (status == LK_OK && options->wireframe) {
        status = lk_edge_adjacency_build(mesh, &edges, error);
        if (status == LK_OK)
            status = prepare_draw(&source, GL_LINES, edges.vertices, 2 * edges.edge_count, index_mode, &wire, error);
    }

    if (status == LK_OK) {
        lk__camera camera;
        lk__camera_setup(&normalization.options, NULL, NULL, renderer->width, renderer->height, &camera);
        /* Key light from the upper left, in front of the model (eye space). */
        static const float key_direction[3] = LK__KEY_LIGHT_DIRECTION;
        float color[3] = {clamp01(options->color[0]), clamp01(options->color[1]), clamp01(options->color[2])};
        static const float wire_color[4] = {0.12f, 0.14f, 0.20f, 1.0f};
        float eye_scale = camera.far_plane > 0 ? 1.0f / camera.far_plane : 1.0f;

        GLuint programs[2] = {mesh_program, wire_program};
        for (int i = 0; i < 2; i++) {
            if (!programs[i]) continue;
            glUseProgram(programs[i]);
            glUniformMatrix4fv(glGetUniformLocation(programs[i], "u_view"), 1, GL_FALSE, camera.view);
            glUniformMatrix4fv(glGetUniformLocation(programs[i], "u_projection"), 1, GL_FALSE, camera.projection);
            glUniformMatrix3fv(glGetUniformLocation(programs[i], "u_normal_matrix"), 1, GL_FALSE, camera.normal_matrix);
            glUniform1f(glGetUniformLocation(programs[i], "u_eye_scale"), eye_scale);
        }
        glUseProgram(mesh_program);
        glUniform3fv(glGetUniformLocation(mesh_program, "u_key_direction"), 1, key_direction);
        if (wire_program) {
            glUseProgram(wire_program);
            glUniform4fv(glGetUniformLocation(wire_program, "u_wire_color"), 1, wire_color);
        }
        lk__gl_opaque_state(options);
        status = lk__gl_check("setting up the mesh draw", error);
        glFinish(); /* uploads done: time the drawing alone */

        double start = lk__now();
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        if (wire_program) {
            /* Push the filled surface back so that its own edges win the
             * depth test against it. */
            glEnable(GL_POLYGON_OFFSET_FILL);
            glPolygonOffset(1.0f, 1.0f);
        }
        glUseProgram(mesh_program);
        execute_draw(&fill, shared, color);
        glDisable(GL_POLYGON_OFFSET_FILL);
        if (wire_program) {
            glUseProgram(wire_program);
            execute_draw(&wire, shared, color);
        }
        glFinish();
        double milliseconds = (lk__now() - start) * 1000.0;
        if (status == LK_OK) status = lk__gl_check("drawing the mesh", error);
        if (status == LK_OK && stats) {
            stats->milliseconds = milliseconds;
            stats->primitives = primitives;
            stats->indices = (size_t)fill.count;
        }
    }

    glBindBuffer(GL_ARRAY_BUFFER, 0);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
    gpu_draw_free(&fill);
    gpu_draw_free(&wire);
    for (int a = 0; a < ATTRIBUTE_COUNT; a++)
        if (shared[a]) glDeleteBuffers(1, &shared[a]);
    lk_edge_adjacency_free(&edges);
    lk_free(strip);
    free(computed_normals);
    free(drawn_positions);
    return status;
}

lk_status lk_render_mesh(lk_renderer *renderer, const lk_mesh *mesh, const lk_render_options *options,
                         lk_render_stats *stats, lk_error *error)
{
    return lk__render_mesh_index_mode(renderer, mesh, options, INDEX_AUTO, stats, error);
}
