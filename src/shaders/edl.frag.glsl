// SPDX-License-Identifier: MIT
// Eye-dome lighting (Boucheny 2009, as Potree draws it): each pixel is
// darkened by how much nearer than it its neighbours at u_radius pixels
// are, in log2 of the eye distance, so that edges and depth steps of a
// point cloud read without normals or lights. Input: the splat picture and
// its depth texture (WebGL's WEBGL_depth_texture); the web viewer's octree
// view draws with it (web/octree_view.js). Background pixels stay as drawn.
#ifdef GL_FRAGMENT_PRECISION_HIGH
precision highp float; // depth needs more than mediump's 10 bits
#else
precision mediump float;
#endif

uniform sampler2D u_color;
uniform sampler2D u_depth;
uniform vec2 u_texel;     // (radius / width, radius / height)
uniform float u_near;
uniform float u_far;
uniform float u_strength; // 1: Potree's default

varying vec2 v_texcoord;

// log2 of the eye-space distance of a window depth in [0, 1)
float log_distance(float depth)
{
    float ndc = depth * 2.0 - 1.0;
    return log2(2.0 * u_near * u_far / (u_far + u_near - ndc * (u_far - u_near)));
}

void main()
{
    vec4 color = texture2D(u_color, v_texcoord);
    float depth = texture2D(u_depth, v_texcoord).r;
    if (depth >= 1.0) {
        gl_FragColor = color;
        return;
    }
    float centre = log_distance(depth);
    float response = 0.0;
    for (int i = 0; i < 8; i++) {
        float angle = float(i) * 0.785398163;
        vec2 offset = vec2(cos(angle), sin(angle)) * u_texel;
        float neighbour = texture2D(u_depth, v_texcoord + offset).r;
        if (neighbour < 1.0) response += max(0.0, centre - log_distance(neighbour));
    }
    float shade = exp(-response / 8.0 * 300.0 * u_strength);
    gl_FragColor = vec4(color.rgb * shade, 1.0);
}
