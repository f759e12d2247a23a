// SPDX-License-Identifier: MIT
// Baseline for the splats: plain square points of the splat's projected
// size, unlit, opaque. With u_disc = 1.0 the square is cut to the splat's
// disc (used to count the fragments splats make).
precision mediump float;

uniform float u_disc;

varying vec4 v_color;

void main()
{
    vec2 offset = gl_PointCoord * 2.0 - 1.0;
    if (u_disc > 0.5 && dot(offset, offset) > 1.0) discard;
    gl_FragColor = v_color;
}
