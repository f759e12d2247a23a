// SPDX-License-Identifier: MIT
// 1-pass Phong splats (discs in their tangent plane, splat_disc.glsl): lit with the splat's normal (the lights of
// mesh.frag.glsl), alpha from the Gaussian kernel texture (the paper's
// Fig. 1), blended over what is already drawn.
precision mediump float;

uniform sampler2D u_kernel;

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
    float alpha = splat_kernel(u_kernel, r2);
    gl_FragColor = vec4(shade(normalize(v_normal), normalize(v_to_eye), v_color.rgb), alpha);
}
