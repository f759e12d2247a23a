// SPDX-License-Identifier: MIT
// A material's base colour (glTF baseColorFactor times baseColorTexture
// times the vertex colour), lit as mesh.frag lights.
precision mediump float;

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_color;
varying vec2 v_texcoord;

uniform vec4 u_base_color;
uniform sampler2D u_texture;
uniform float u_textured; // 1: sample u_texture

#include "lighting.glsl"

void main()
{
    vec3 albedo = v_color.rgb * u_base_color.rgb;
    // The image's first row is t = 0 (glTF's v = 0); lodkit's v points up.
    if (u_textured > 0.5) albedo *= texture2D(u_texture, vec2(v_texcoord.x, 1.0 - v_texcoord.y)).rgb;
    gl_FragColor = vec4(shade(normalize(v_normal), normalize(v_to_eye), albedo), 1.0);
}
