// SPDX-License-Identifier: MIT
// Lit triangles (with mesh.frag.glsl) and the wireframe overlay (with
// wire.frag.glsl). GLSL ES 1.00: shared by the C renderer and the WebGL viewer.
// Attribute locations: a_position 0, a_normal 1, a_color 2.
attribute vec3 a_position;
attribute vec3 a_normal;
attribute vec4 a_color;   // a constant attribute when the model has no colours

uniform mat4 u_view;
uniform mat4 u_projection;
uniform mat3 u_normal_matrix;
// 1 / camera distance: keeps the interpolated view vector near unit length,
// so mediump fragment shaders see no overflow whatever the model's units.
uniform float u_eye_scale;

varying vec3 v_normal;    // eye space, not normalised
varying vec3 v_to_eye;    // eye space, from the surface towards the camera (scaled)
varying vec4 v_color;

void main()
{
    vec4 eye_position = u_view * vec4(a_position, 1.0);
    v_normal = u_normal_matrix * a_normal;
    v_to_eye = -eye_position.xyz * u_eye_scale;
    v_color = a_color;
    gl_Position = u_projection * eye_position;
}
