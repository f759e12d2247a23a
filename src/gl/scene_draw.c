/* SPDX-License-Identifier: MIT */
/* Scenes with their materials (lk_render_scene): the scene flattened into
 * one set of vertex buffers, its triangles grouped by material, one draw
 * call per material with its base colour factor and texture, through
 * mesh_textured.vert/.frag. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"

enum { ATTRIBUTE_POSITION = 0, ATTRIBUTE_NORMAL, ATTRIBUTE_COLOR, ATTRIBUTE_TEXCOORD, ATTRIBUTE_COUNT };
static const char *const attribute_names[] = {"a_position", "a_normal", "a_color", "a_texcoord", NULL};
static const GLint attribute_components[ATTRIBUTE_COUNT] = {3, 3, 4, 2};

/* Largest texture side uploaded; larger images are sampled down. */
#define MAX_TEXTURE_SIDE 2048u

static unsigned power_of_two_at_least(unsigned value)
{
    unsigned result = 1;
    while (result < value && result < MAX_TEXTURE_SIDE) result <<= 1;
    return result;
}

/* GLES 2.0 repeats (GL_REPEAT) only power-of-two textures: the image is
 * resampled (nearest texel, which the bilinear filter then smooths) to the
 * power of two at or above each side, at most MAX_TEXTURE_SIDE. */
static GLuint upload_texture(const unsigned char *rgba, unsigned width, unsigned height)
{
    unsigned w = power_of_two_at_least(width), h = power_of_two_at_least(height);
    unsigned char *resized = NULL;
    const unsigned char *pixels = rgba;
    if (w != width || h != height) {
        resized = lk__malloc_array((size_t)w * h, 4);
        if (!resized) return 0;
        for (unsigned y = 0; y < h; y++) {
            size_t source_y = (size_t)y * height / h;
            for (unsigned x = 0; x < w; x++) {
                size_t source_x = (size_t)x * width / w;
                memcpy(resized + 4 * ((size_t)y * w + x), rgba + 4 * (source_y * width + source_x), 4);
            }
        }
        pixels = resized;
    }
    GLuint texture = 0;
    glGenTextures(1, &texture);
    glBindTexture(GL_TEXTURE_2D, texture);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, (GLsizei)w, (GLsizei)h, 0, GL_RGBA, GL_UNSIGNED_BYTE, pixels);
    glGenerateMipmap(GL_TEXTURE_2D);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
    free(resized);
    return texture;
}

static lk_status upload_array(const float *data, size_t count, GLuint *buffer, lk_error *error)
{
    if (count > (size_t)PTRDIFF_MAX / sizeof(float))
        return lk_error_set(error, LK_ERR_LIMIT, "%zu values exceed what OpenGL ES can address", count);
    glGenBuffers(1, buffer);
    glBindBuffer(GL_ARRAY_BUFFER, *buffer);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(count * sizeof(float)), data, GL_STATIC_DRAW);
    return lk__gl_check("uploading the scene's vertices", error);
}

static float clamp01(float value) { return value < 0 ? 0 : value > 1 ? 1 : value; }

/* The texture of material m's base colour: decoded and uploaded once per
 * image (textures[m] = 0 when it has none or it failed). */
static void prepare_textures(const lk_scene *scene, const bool *used, GLuint *textures, GLuint *image_textures,
                             lk_render_scene_info *info)
{
    for (size_t m = 0; m < scene->material_count; m++) {
        textures[m] = 0;
        if (!used[m]) continue;
        int32_t t = scene->materials[m].base_color_texture;
        if (t < 0 || (size_t)t >= scene->texture_count) continue;
        int32_t i = scene->textures[t].image;
        if (i < 0 || (size_t)i >= scene->image_count) continue;
        if (image_textures[i] == 0) {
            const lk_scene_image *image = &scene->images[i];
            unsigned char *rgba = NULL;
            unsigned width = 0, height = 0;
            lk_error failure = {0};
            if (lk__decode_image(image->data, image->size, &rgba, &width, &height, &failure) == LK_OK)
                image_textures[i] = upload_texture(rgba, width, height);
            else if (!info->first_failure[0])
                snprintf(info->first_failure, sizeof info->first_failure, "images[%d] (%.20s): %.100s", i,
                         image->mime_type ? image->mime_type : "?", failure.message);
            free(rgba);
            if (image_textures[i] == 0) image_textures[i] = (GLuint)-1; /* tried: failed */
        }
        if (image_textures[i] != (GLuint)-1) {
            textures[m] = image_textures[i];
            info->textures_drawn++;
        } else {
            info->textures_failed++;
        }
    }
}

lk_status lk_render_scene(lk_renderer *renderer, const lk_scene *scene, const lk_render_options *options,
                          lk_render_stats *stats, lk_render_scene_info *info, lk_error *error)
{
    if (stats) memset(stats, 0, sizeof *stats);
    lk_render_scene_info local_info;
    if (!info) info = &local_info;
    memset(info, 0, sizeof *info);
    if (!renderer || !scene) return lk_error_set(error, LK_ERR_INVALID, "lk_render_scene: NULL renderer or scene");
    lk_render_options defaults;
    if (!options) {
        lk_render_options_default(&defaults);
        options = &defaults;
    }
    lk_status status = lk__render_check_options(options, error);
    if (status != LK_OK) return status;
    lk_mesh mesh;
    int32_t *materials = NULL;
    status = lk__scene_flatten_materials(scene, &mesh, &materials, error);
    if (status != LK_OK) return status;
    if (mesh.triangle_count == 0) {
        lk_mesh_free(&mesh);
        free(materials);
        return lk_error_set(error, LK_ERR_INVALID, "the scene draws no triangles");
    }
    if (mesh.triangle_count > (size_t)INT_MAX / 3) {
        size_t count = mesh.triangle_count;
        lk_mesh_free(&mesh);
        free(materials);
        return lk_error_set(error, LK_ERR_LIMIT, "%zu triangles exceed what one draw call takes", count);
    }
    status = lk__gl_begin(renderer, error);
    GLuint program = 0;
    if (status == LK_OK)
        status = lk__gl_program(renderer, LK__PROGRAM_TEXTURED, "mesh_textured.vert", "mesh_textured.frag",
                                attribute_names, &program, error);
    bool wide = mesh.vertex_count > 65535;
    if (status == LK_OK && wide && !lk__gl_has_extension("GL_OES_element_index_uint"))
        status =
            lk_error_set(error, LK_ERR_UNSUPPORTED, "%zu vertices need GL_OES_element_index_uint", mesh.vertex_count);

    /* Triangles grouped by material (slot 0: none; slot m + 1: material m). */
    size_t slots = scene->material_count + 1;
    size_t *group_start = lk__calloc_array(slots + 1, sizeof *group_start);
    uint32_t *grouped = lk__malloc_array(3 * mesh.triangle_count, sizeof *grouped);
    bool *used = lk__calloc_array(slots, sizeof *used);
    GLuint *textures = lk__calloc_array(slots, sizeof *textures);
    GLuint *image_textures = lk__calloc_array(scene->image_count + 1, sizeof *image_textures);
    float *positions = NULL, *computed_normals = NULL;
    GLuint buffers[ATTRIBUTE_COUNT] = {0, 0, 0, 0}, index_buffer = 0;
    if (status == LK_OK && (!group_start || !grouped || !used || !textures || !image_textures))
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory grouping %zu triangles", mesh.triangle_count);
    if (status == LK_OK) {
        for (size_t t = 0; t < mesh.triangle_count; t++) {
            int32_t m = materials[t];
            size_t slot = m >= 0 && (size_t)m < scene->material_count ? (size_t)m + 1 : 0;
            group_start[slot + 1]++;
        }
        for (size_t s = 0; s < slots; s++) group_start[s + 1] += group_start[s];
        size_t *fill = lk__malloc_array(slots, sizeof *fill);
        if (!fill) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        } else {
            memcpy(fill, group_start, slots * sizeof *fill);
            for (size_t t = 0; t < mesh.triangle_count; t++) {
                int32_t m = materials[t];
                size_t slot = m >= 0 && (size_t)m < scene->material_count ? (size_t)m + 1 : 0;
                memcpy(grouped + 3 * fill[slot]++, mesh.indices + 3 * t, 3 * sizeof *grouped);
            }
            free(fill);
        }
        for (size_t s = 1; s < slots; s++)
            if (group_start[s + 1] > group_start[s]) {
                used[s - 1] = true;
                info->materials++;
            }
    }

    lk__model_normalization normalization;
    if (status == LK_OK) {
        float box_min[3], box_max[3];
        lk_mesh_bounds(&mesh, box_min, box_max);
        lk__normalization_setup(options, box_min, box_max, &normalization);
        positions = lk__normalized_positions(&normalization, mesh.positions, mesh.vertex_count);
        if (!positions) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the scene's positions");
    }
    const float *normals = mesh.normals;
    if (status == LK_OK && !normals) {
        lk_mesh normalized = mesh;
        normalized.positions = positions;
        computed_normals = lk__face_averaged_normals(&normalized, error);
        if (!computed_normals) status = LK_ERR_NOMEM;
        normals = computed_normals;
    }
    const float *arrays[ATTRIBUTE_COUNT] = {positions, normals, mesh.colors, mesh.texcoords};
    for (int a = 0; a < ATTRIBUTE_COUNT && status == LK_OK; a++)
        if (arrays[a])
            status = upload_array(arrays[a], mesh.vertex_count * (size_t)attribute_components[a], &buffers[a], error);
    if (status == LK_OK) {
        /* the grouped indices in one buffer: 16-bit when they fit */
        size_t count = 3 * mesh.triangle_count;
        glGenBuffers(1, &index_buffer);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_buffer);
        if (wide) {
            glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(count * sizeof(uint32_t)), grouped, GL_STATIC_DRAW);
        } else {
            uint16_t *short_indices = lk__malloc_array(count, sizeof *short_indices);
            if (!short_indices) {
                status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu indices", count);
            } else {
                for (size_t i = 0; i < count; i++) short_indices[i] = (uint16_t)grouped[i];
                glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(count * sizeof(uint16_t)), short_indices,
                             GL_STATIC_DRAW);
                free(short_indices);
            }
        }
        if (status == LK_OK) status = lk__gl_check("uploading the scene's indices", error);
    }
    if (status == LK_OK) prepare_textures(scene, used, textures, image_textures, info);

    if (status == LK_OK) {
        lk__camera camera;
        lk__camera_setup(&normalization.options, NULL, NULL, renderer->width, renderer->height, &camera);
        static const float key_direction[3] = LK__KEY_LIGHT_DIRECTION;
        float eye_scale = camera.far_plane > 0 ? 1.0f / camera.far_plane : 1.0f;
        glUseProgram(program);
        glUniformMatrix4fv(glGetUniformLocation(program, "u_view"), 1, GL_FALSE, camera.view);
        glUniformMatrix4fv(glGetUniformLocation(program, "u_projection"), 1, GL_FALSE, camera.projection);
        glUniformMatrix3fv(glGetUniformLocation(program, "u_normal_matrix"), 1, GL_FALSE, camera.normal_matrix);
        glUniform1f(glGetUniformLocation(program, "u_eye_scale"), eye_scale);
        glUniform3fv(glGetUniformLocation(program, "u_key_direction"), 1, key_direction);
        glUniform1i(glGetUniformLocation(program, "u_texture"), 0);
        GLint base_color = glGetUniformLocation(program, "u_base_color");
        GLint textured = glGetUniformLocation(program, "u_textured");
        for (int a = 0; a < ATTRIBUTE_COUNT; a++) {
            if (buffers[a]) {
                glBindBuffer(GL_ARRAY_BUFFER, buffers[a]);
                glEnableVertexAttribArray((GLuint)a);
                glVertexAttribPointer((GLuint)a, attribute_components[a], GL_FLOAT, GL_FALSE, 0, NULL);
            } else {
                glDisableVertexAttribArray((GLuint)a);
                glVertexAttrib4f((GLuint)a, 1.0f, 1.0f, 1.0f, 1.0f); /* white colours; texcoords unused */
            }
        }
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_buffer);
        lk__gl_opaque_state(options);
        glActiveTexture(GL_TEXTURE0);
        glFinish();
        double start = lk__now();
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        for (size_t s = 0; s < slots; s++) {
            size_t first = group_start[s], end = group_start[s + 1];
            if (end == first) continue;
            float color[4] = {clamp01(options->color[0]), clamp01(options->color[1]), clamp01(options->color[2]), 1};
            GLuint texture = 0;
            if (s > 0) {
                const lk_scene_material *material = &scene->materials[s - 1];
                for (int k = 0; k < 4; k++) color[k] = clamp01(material->base_color[k]);
                texture = textures[s - 1];
            }
            glUniform4fv(base_color, 1, color);
            glUniform1f(textured, texture && buffers[ATTRIBUTE_TEXCOORD] ? 1.0f : 0.0f);
            glBindTexture(GL_TEXTURE_2D, texture);
            size_t element_size = wide ? sizeof(uint32_t) : sizeof(uint16_t);
            glDrawElements(GL_TRIANGLES, (GLsizei)(3 * (end - first)), wide ? GL_UNSIGNED_INT : GL_UNSIGNED_SHORT,
                           (const void *)(uintptr_t)(3 * first * element_size));
        }
        glFinish();
        double milliseconds = (lk__now() - start) * 1000.0;
        status = lk__gl_check("drawing the scene", error);
        if (status == LK_OK && stats) {
            stats->milliseconds = milliseconds;
            stats->primitives = mesh.triangle_count;
            stats->indices = 3 * mesh.triangle_count;
        }
    }

    glBindBuffer(GL_ARRAY_BUFFER, 0);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
    glBindTexture(GL_TEXTURE_2D, 0);
    for (int a = 0; a < ATTRIBUTE_COUNT; a++)
        if (buffers[a]) glDeleteBuffers(1, &buffers[a]);
    if (index_buffer) glDeleteBuffers(1, &index_buffer);
    for (size_t i = 0; image_textures && i < scene->image_count; i++)
        if (image_textures[i] && image_textures[i] != (GLuint)-1) glDeleteTextures(1, &image_textures[i]);
    free(group_start);
    free(grouped);
    free(used);
    free(textures);
    free(image_textures);
    free(positions);
    free(computed_normals);
    free(materials);
    lk_mesh_free(&mesh);
    return status;
}
