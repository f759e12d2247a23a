// SPDX-License-Identifier: MIT
// Two-sided Phong shading with a headlight and a key light (eye space).
precision mediump float;

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_color;

#include "lighting.glsl"

void main()
{
    gl_FragColor = vec4(shade(normalize(v_normal), normalize(v_to_eye), v_color.rgb), 1.0);
}
