// SPDX-License-Identifier: MIT
// Wireframe overlay: edges in one flat colour (vertex stage: mesh.vert.glsl).
precision mediump float;

uniform vec4 u_wire_color;

void main()
{
    gl_FragColor = u_wire_color;
}
