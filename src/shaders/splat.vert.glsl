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

// Octree nodes (web/octree_view.js; the C renderer sizes its points on the
// CPU, lk_octree_load_selection, and leaves this 0): an inner node's points
// are at least u_radius_floor (its spacing: drawn alone it must cover where
// its children's points are missing).
uniform float u_radius_floor;
#ifdef LK_ADAPTIVE_SIZE
// splat_octree.vert.glsl (a vertex texture, which WebGL 1 may lack: the
// other programs declare none). With u_adaptive, Potree's adaptive point
// size: the floor is found by walking down the drawn nodes whose cube
// holds the point, in u_drawn_nodes (one texel per drawn node: r = mask of
// its drawn children, g = mask of the children it has, b * 256 + a = the
// texel of its first drawn child; drawn children are contiguous in digit
// order): the spacing of the first node whose child there is not drawn
// (1.5 times it below the point's own node: lk_octree_load_selection's
// OT_ANCESTOR_FLOOR), 0 where the path ends in a cube with no child (every
// point around is drawn at its own radius).
uniform float u_adaptive;
uniform sampler2D u_drawn_nodes;
uniform float u_drawn_width; // texels in u_drawn_nodes (one row)
uniform float u_node_texel;  // this node's
uniform vec4 u_node_cube;    // this node's cube: centre (as a_position), half its side
uniform float u_node_spacing;
#endif

varying vec3 v_normal;    // eye space, unit length
varying vec3 v_to_eye;    // eye space, from the splat towards the camera (scaled)
varying vec4 v_color;
varying vec4 v_clip;      // eye space direction, offset in radii (splat_disc.glsl)

#ifdef LK_ADAPTIVE_SIZE
// 2^digit for a digit 0..7, exact (exp2 need not be).
float power_of_two(float digit)
{
    float value = 1.0;
    for (int d = 0; d < 7; d++)
        if (float(d) < digit) value *= 2.0;
    return value;
}

// Is bit `bit` (a power of two) set in the byte `mask`?
bool has_bit(float mask, float bit) { return mod(floor(mask / bit), 2.0) > 0.5; }

// The radius floor of the point at `position` (see u_adaptive above).
float drawn_floor(vec3 position)
{
    float texel = u_node_texel;
    vec3 centre = u_node_cube.xyz;
    float half_side = u_node_cube.w;
    float spacing = u_node_spacing;
    float factor = 1.0;
    for (int level = 0; level < 31; level++) {
        vec4 node = floor(texture2D(u_drawn_nodes, vec2((texel + 0.5) / u_drawn_width, 0.5)) * 255.0 + 0.5);
        vec3 upper = step(centre, position); // 1 where position >= centre: child digit x*4 + y*2 + z
        float digit = dot(upper, vec3(4.0, 2.0, 1.0));
        float bit = power_of_two(digit);
        if (!has_bit(node.g, bit)) return 0.0;
        if (!has_bit(node.r, bit)) return factor * spacing;
        float before = 0.0; // drawn children of lower digits
        for (int d = 0; d < 7; d++)
            if (float(d) < digit && has_bit(node.r, power_of_two(float(d)))) before += 1.0;
        texel = node.b * 256.0 + node.a + before;
        half_side *= 0.5;
        centre += (upper * 2.0 - 1.0) * half_side;
        spacing *= 0.5;
        factor = 1.5;
    }
    return factor * spacing;
}
#endif

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
    // drawn alone, and as drawn with the nodes below (the clip line's
    // offset is in the former)
    float alone_radius = max(a_radius, u_radius_floor);
    float own_radius = alone_radius;
#ifdef LK_ADAPTIVE_SIZE
    if (u_adaptive > 0.5 && u_radius_floor > a_radius) own_radius = max(a_radius, drawn_floor(a_position));
#endif
    own_radius = max(own_radius, 1e-30);
    float radius = own_radius * u_radius_scale;
    // a direction in the tangent plane: the view is a rotation, so the normal
    // matrix turns it as the view does (GLSL ES 1.00 has no mat3(mat4))
    vec3 clip_direction = u_normal_matrix * a_clip.xyz;
    float clip_length = length(clip_direction);
    v_clip = clip_length > 0.0 ? vec4(clip_direction / clip_length, a_clip.w * alone_radius / radius) : vec4(0.0, 0.0, 0.0, 1.0);
    float z_eye = max(-eye_position.z, 1e-6);
    gl_PointSize = clamp(2.0 * radius * u_size_scale / z_eye, u_point_size_range.x, u_point_size_range.y);
    if (u_depth_offset > 0.0) {
        float distance_to_eye = length(eye_position.xyz);
        if (distance_to_eye > 0.0)
            eye_position.xyz += eye_position.xyz * (u_depth_offset * radius / distance_to_eye);
    }
    gl_Position = u_projection * eye_position;
}
