// SPDX-License-Identifier: MIT
// 2-pass splatting, visibility pass: depth only (colour writes are masked
// off); splat.vert.glsl pushed the splats back by u_depth_offset radii.
precision mediump float;

void main()
{
    vec2 offset = gl_PointCoord * 2.0 - 1.0;
    if (dot(offset, offset) > 1.0) discard;
    gl_FragColor = vec4(0.0);
}
