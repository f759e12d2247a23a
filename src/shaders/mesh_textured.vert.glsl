// SPDX-License-Identifier: MIT
// Lit, textured triangles of a scene (with mesh_textured.frag.glsl): the C
// renderer's lk_render_scene. mesh.vert with texture coordinates.
// Attribute locations: a_position 0, a_normal 1, a_color 2, a_texcoord 3.
attribute vec3 a_position;
attribute vec3 a_normal;
attribute vec4 a_color;    // a constant attribute when the scene has no colours
attribute vec2 a_texcoord; // lodkit's: v up

uniform mat4 u_view;
uniform mat4 u_projection;
uniform mat3 u_normal_matrix;
uniform float u_eye_scale;

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_color;
varying vec2 v_texcoord;

void main()
{
    vec4 eye_position = u_view * vec4(a_position, 1.0);
    v_normal = u_normal_matrix * a_normal;
    v_to_eye = -eye_position.xyz * u_eye_scale;
    v_color = a_color;
    v_texcoord = a_texcoord;
    gl_Position = u_projection * eye_position;
}
