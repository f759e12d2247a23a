// SPDX-License-Identifier: MIT
// 2-pass splatting, normalisation: the accumulated colour divided by the
// accumulated weight; pixels no splat reached keep the cleared background.
#ifdef GL_FRAGMENT_PRECISION_HIGH
precision highp float; // texture coordinates of large viewports
#else
precision mediump float;
#endif

uniform sampler2D u_accumulated;

varying vec2 v_texcoord;

void main()
{
    vec4 sum = texture2D(u_accumulated, v_texcoord);
    if (sum.a <= 0.0) discard;
    gl_FragColor = vec4(sum.rgb / sum.a, 1.0);
}
