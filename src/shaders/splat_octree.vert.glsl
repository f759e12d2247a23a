// SPDX-License-Identifier: MIT
// The splat vertex stage with Potree's adaptive point size for point
// octrees (web/octree_view.js): splat.vert.glsl with the walk of the drawn
// nodes, which reads a texture in the vertex stage. WebGL 1 allows
// devices without vertex textures, so only this program declares one; the
// octree view falls back to splat.vert.glsl there.
#define LK_ADAPTIVE_SIZE 1
#include "splat.vert.glsl"
