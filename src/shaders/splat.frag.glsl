// SPDX-License-Identifier: MIT
// 1-pass Phong splats: lit with the splat's normal (the lights of
// mesh.frag.glsl), alpha from the Gaussian kernel texture (the paper's
// Fig. 1), blended over what is already drawn.
precision mediump float;

uniform sampler2D u_kernel;

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_color;

#include "lighting.glsl"

void main()
{
    vec2 offset = gl_PointCoord * 2.0 - 1.0;
    if (dot(offset, offset) > 1.0) discard;
    float alpha = texture2D(u_kernel, gl_PointCoord).a;
    gl_FragColor = vec4(shade(normalize(v_normal), normalize(v_to_eye), v_color.rgb), alpha);
}
