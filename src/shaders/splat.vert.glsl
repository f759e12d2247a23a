// SPDX-License-Identifier: MIT
// Point splats (Kim 2010, after Botsch et al.'s Phong splatting): one point
// sprite per oriented point, as wide as the splat's projected diameter.
// Vertex stage of every splat program: 1-pass Phong (splat.frag.glsl),
// 2-pass visibility and accumulation (splat_visibility.frag.glsl,
// splat_accumulate.frag.glsl) and the flat-point baseline (points_flat.frag.glsl).
// Attribute locations: a_position 0, a_normal 1, a_radius 2, a_color 3, a_clip 4.
attribute vec3 a_position;
attribute vec3 a_normal;
attribute float a_radius;
attribute vec4 a_color;   // a constant attribute when the points have no colours
// A border splat's clip line (lk_points_estimate_clips): keep the part of the
// disc where dot(offset, a_clip.xyz) <= a_clip.w, the offset in units of
// a_radius (so that normalised bytes carry it: lodkit serve's LKMB); a zero
// direction cuts nothing (a constant attribute when nothing is clipped).
attribute vec4 a_clip;

uniform mat4 u_view;
uniform mat4 u_projection;
uniform mat3 u_normal_matrix;
// 1 / camera distance, as in mesh.vert.glsl: keeps the view vector near unit
// length for mediump fragment shaders whatever the model's units.
uniform float u_eye_scale;
// n * h_vp / (t - b) of eq. 1, so that the sprite size is 2 r * u_size_scale / z_eye.
uniform float u_size_scale;
uniform float u_radius_scale;
uniform vec2 u_point_size_range;
// 1.0: splats whose normal faces away from the eye are dropped here, before
// they make any fragment (the paper's culling).
uniform float u_culling;
// Visibility pass: how far (in splat radii) each splat is pushed away from
// the eye, so that the accumulation pass accepts every splat of the front
// surface and none behind it. 0 otherwise.
uniform float u_depth_offset;

varying vec3 v_normal;    // eye space, unit length
varying vec3 v_to_eye;    // eye space, from the splat towards the camera (scaled)
varying vec4 v_color;
varying vec4 v_clip;      // eye space direction, offset in radii (splat_disc.glsl)

void main()
{
    vec4 eye_position = u_view * vec4(a_position, 1.0);
    vec3 normal = normalize(u_normal_matrix * a_normal);
    v_normal = normal;
    v_to_eye = -eye_position.xyz * u_eye_scale;
    v_color = a_color;
    // The eye is the origin: the splat faces away when its normal points
    // along the eye-to-splat direction.
    if (u_culling > 0.5 && dot(normal, eye_position.xyz) > 0.0) {
        // Outside the clip volume: the point is clipped whole.
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        gl_PointSize = 1.0;
        return;
    }
    float radius = a_radius * u_radius_scale;
    // a direction in the tangent plane: the view is a rotation, so the normal
    // matrix turns it as the view does (GLSL ES 1.00 has no mat3(mat4))
    vec3 clip_direction = u_normal_matrix * a_clip.xyz;
    float clip_length = length(clip_direction);
    v_clip = clip_length > 0.0 ? vec4(clip_direction / clip_length, a_clip.w / u_radius_scale) : vec4(0.0, 0.0, 0.0, 1.0);
    float z_eye = max(-eye_position.z, 1e-6);
    gl_PointSize = clamp(2.0 * radius * u_size_scale / z_eye, u_point_size_range.x, u_point_size_range.y);
    if (u_depth_offset > 0.0) {
        float distance_to_eye = length(eye_position.xyz);
        if (distance_to_eye > 0.0)
            eye_position.xyz += eye_position.xyz * (u_depth_offset * radius / distance_to_eye);
    }
    gl_Position = u_projection * eye_position;
}
