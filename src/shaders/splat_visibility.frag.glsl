// SPDX-License-Identifier: MIT
// 2-pass splatting, visibility pass: depth only (colour writes are masked
// off); splat.vert.glsl pushed the splats back by u_depth_offset radii.
precision mediump float;

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_clip;

#include "splat_disc.glsl"

void main()
{
    if (splat_disc_radius2(normalize(v_normal), v_to_eye, v_clip) > 1.0) discard;
    gl_FragColor = vec4(0.0);
}
