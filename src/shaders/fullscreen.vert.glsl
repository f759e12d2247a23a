// SPDX-License-Identifier: MIT
// One triangle covering the viewport: a_position is (-1,-1), (3,-1), (-1,3).
attribute vec2 a_position;

varying vec2 v_texcoord;

void main()
{
    v_texcoord = a_position * 0.5 + 0.5;
    gl_Position = vec4(a_position, 0.0, 1.0);
}
