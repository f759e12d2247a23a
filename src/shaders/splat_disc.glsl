// SPDX-License-Identifier: MIT
// The splat as a disc in its tangent plane (Botsch and Kobbelt's
// object-space ellipses, affinely approximated per splat): a fragment of the
// point sprite at offset (x, y) from its centre, in radii, lies on the disc
// at depth offset z = -(n.x x + n.y y) / n.z, and inside it when
// x^2 + y^2 + z^2 <= 1. A splat facing the eye stays round; one at the
// silhouette, seen edge-on, becomes a thin ellipse and no longer reaches
// past the surface it stands for (screen-aligned discs spilled a rim of one
// radius: 5% of the bunny's splat pixels).
// Returns x^2 + y^2 + z^2 (> 1: outside the disc, discard).
float splat_disc_radius2(vec3 normal)
{
    vec2 offset = vec2(gl_PointCoord.x * 2.0 - 1.0, 1.0 - gl_PointCoord.y * 2.0);
    // Edge-on splats (|n.z| -> 0) keep a sliver, so that a surface seen at
    // a grazing angle still closes.
    float nz = abs(normal.z) < 0.2 ? (normal.z < 0.0 ? -0.2 : 0.2) : normal.z;
    float z = -(normal.x * offset.x + normal.y * offset.y) / nz;
    return dot(offset, offset) + z * z;
}

// The Gaussian kernel's weight at squared disc radius r2 (the kernel
// texture is radially symmetric: sampled along its middle row).
float splat_kernel(sampler2D kernel, float r2)
{
    return texture2D(kernel, vec2(0.5 + 0.5 * sqrt(min(r2, 1.0)), 0.5)).a;
}
