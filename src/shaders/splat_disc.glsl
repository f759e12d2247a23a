// SPDX-License-Identifier: MIT
// The splat as a disc in its tangent plane (Botsch and Kobbelt's
// object-space ellipses, affinely approximated per splat): a fragment of the
// point sprite at offset (x, y) from its centre, in radii, lies on the disc
// at depth offset z = -(n.x x + n.y y) / n.z, and inside it when
// x^2 + y^2 + z^2 <= 1. A splat facing the eye stays round; one at the
// silhouette, seen edge-on, becomes a thin ellipse and no longer reaches
// past the surface it stands for (screen-aligned discs spilled a rim of one
// radius: 5% of the bunny's splat pixels).
// The depth is taken along the splat's own ray from the eye (to_eye: from
// the splat towards the eye, any length), not along the optical axis: off
// the middle of the picture the two differ by up to half the field of view,
// so a splat edge-on to its ray (at the silhouette) has |n.z| up to
// sin(17.5 deg) = 0.3 and, measured along z, was an ellipse up to 0.3
// radii wide across the silhouette instead of a sliver: a rim outside the
// surface in proportion to the radii. The offset is first moved into the
// plane across the ray. Measured (bench/bench_radii.c, docs/benchmarks.md):
// splat pixels outside the bunny's silhouette 1.48% -> 1.31% (100k
// samples), 2.57% -> 2.23% (its vertices); with the sliver below 0.1
// radii instead of 0.2: 1.01% and 1.79%, coverage 99.99% and 100%.
// A border splat keeps only the side of its clip line towards its
// neighbours (clip: eye-space direction, offset in radii; splat.vert.glsl),
// so that it does not reach into the gap beside it.
// Returns the squared distance from the centre in radii (> 1: outside the
// disc or clipped, discard).
float splat_disc_radius2(vec3 normal, vec3 to_eye, vec4 clip)
{
    vec2 sprite = vec2(gl_PointCoord.x * 2.0 - 1.0, 1.0 - gl_PointCoord.y * 2.0);
    vec3 view = normalize(to_eye);
    vec3 across = vec3(sprite, 0.0);
    across -= dot(across, view) * view;
    // Edge-on splats (facing -> 0) keep a sliver (at least 0.1 radii wide),
    // so that a surface seen at a grazing angle still closes.
    float facing = dot(normal, view);
    facing = abs(facing) < 0.1 ? (facing < 0.0 ? -0.1 : 0.1) : facing;
    float along = -dot(normal, across) / facing;
    if (dot(across + along * view, clip.xyz) > clip.w) return 2.0;
    return dot(across, across) + along * along;
}

// The Gaussian kernel's weight at squared disc radius r2 (the kernel
// texture is radially symmetric: sampled along its middle row).
float splat_kernel(sampler2D kernel, float r2)
{
    return texture2D(kernel, vec2(0.5 + 0.5 * sqrt(min(r2, 1.0)), 0.5)).a;
}
