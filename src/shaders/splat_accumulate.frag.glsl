// SPDX-License-Identifier: MIT
// 2-pass splatting, accumulation pass: every splat of the visible surface
// adds (w r, w g, w b, w), w its Gaussian weight (additive blending, depth
// test against the visibility pass, no depth writes); splat_normalize.frag.glsl
// then divides by the summed weight, so that overlaps neither brighten nor
// let the background through.
precision mediump float;

uniform sampler2D u_kernel;
// 1.0 into a floating-point target; 1/16 into the RGBA8 fallback, so that
// sixteen full weights can pile up before the target saturates.
uniform float u_weight_scale;

varying vec3 v_normal;
varying vec3 v_to_eye;
varying vec4 v_clip;
varying vec4 v_color;

#include "lighting.glsl"
#include "splat_disc.glsl"

void main()
{
    float r2 = splat_disc_radius2(normalize(v_normal), v_to_eye, v_clip);
    if (r2 > 1.0) discard;
    float weight = splat_kernel(u_kernel, r2) * u_weight_scale;
    gl_FragColor = vec4(shade(normalize(v_normal), normalize(v_to_eye), v_color.rgb) * weight, weight);
}
