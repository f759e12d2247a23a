/* SPDX-License-Identifier: MIT */
/* Procedural shapes for the core unit tests (no samples needed): closed,
 * open, sharp, thin, noisy and multi-part meshes whose counts and topology
 * are known in closed form, a deforming animation, an oriented point set
 * on a sphere and a heightfield. Every mesh is indexed with shared vertices
 * (no duplicates, no unused vertices) and counter-clockwise outward faces;
 * the functions fail the running test on allocation failure. Include after
 * cmocka's headers (through testutil.h). */
#ifndef LODKIT_SHAPES_H
#define LODKIT_SHAPES_H

#include "testutil.h"

#define SHAPE_PI 3.14159265358979323846

/* A surface of revolution about +z through `count` profile points (r, z)
 * listed from the bottom up, `around` segments per ring. A profile point
 * with r == 0 is a pole (one vertex; only the first and the last may be).
 * V = poles + around * rings, T = 2 * around * (count - 1) - around * poles. */
void shape_revolve(lk_mesh *mesh, const double *r, const double *z, unsigned count, unsigned around);

/* UV sphere centred at the origin: `stacks` bands from pole to pole.
 * V = slices * (stacks - 1) + 2, T = 2 * slices * (stacks - 1). Genus 0. */
void shape_uv_sphere(lk_mesh *mesh, double radius, unsigned slices, unsigned stacks);
/* A unit UV sphere as texture mapping makes it: a (slices+1) x (stacks+1)
 * grid whose first and last columns (the seam, u = 0 and 1) and pole rows
 * repeat positions with other texture coordinates (v up); unit normals.
 * T = 2 * slices * (stacks - 1). With tangents not NULL, *tangents gets 4
 * floats per vertex (the direction of increasing u, w = 1; malloc). */
void shape_textured_sphere(lk_mesh *mesh, unsigned slices, unsigned stacks, float **tangents);

/* Icosahedron split `subdivisions` times (every triangle into four at edge
 * midpoints pushed onto the sphere). V = 10 * 4^s + 2, T = 20 * 4^s.
 * Every vertex lies on the sphere (to float rounding). Genus 0. */
void shape_icosphere(lk_mesh *mesh, double radius, unsigned subdivisions);

/* Torus about +z: tube centre circle of radius `major`, tube radius
 * `minor`. V = n_major * n_minor, T = 2 V. Genus 1. */
void shape_torus(lk_mesh *mesh, double major, double minor, unsigned n_major, unsigned n_minor);

/* Axis-aligned box of the given size centred at the origin, each face an
 * n x n grid (sharp 90-degree edges and corners). V = 6 n^2 + 2,
 * T = 12 n^2. Genus 0. */
void shape_box(lk_mesh *mesh, double size_x, double size_y, double size_z, unsigned n);

/* Open cylinder about +z from z = 0 to `height`, no caps: two border loops
 * of `around` edges. V = around * (rows + 1), T = 2 * around * rows,
 * Euler characteristic 0, genus 0. */
void shape_cylinder(lk_mesh *mesh, double radius, double height, unsigned around, unsigned rows);

/* Flat open grid on z = 0 over [0, width] x [0, depth], nx x ny cells.
 * V = (nx + 1)(ny + 1), T = 2 nx ny, one border loop of 2(nx + ny) edges. */
void shape_plane(lk_mesh *mesh, double width, double depth, unsigned nx, unsigned ny);

/* Capsule (a thin limb): a cylinder of `radius` from z = 0 to `length`
 * closed by two hemispheres of `cap_rings` rings each, `rows` bands along
 * the cylinder. V = around * (2 cap_rings + rows - 1) + 2,
 * T = 2 * around * (2 cap_rings + rows - 1). Genus 0. */
void shape_capsule(lk_mesh *mesh, double radius, double length, unsigned around, unsigned rows, unsigned cap_rings);

/* Icosphere whose vertex v sits at radius * (1 + amplitude * u_v), u_v a
 * deterministic value in [-1, 1] from (seed, v): a rough, spiky sphere with
 * the icosphere's counts and topology. */
void shape_noisy_sphere(lk_mesh *mesh, double radius, unsigned subdivisions, double amplitude, uint64_t seed);

/* Appends `part` moved by (dx, dy, dz) to `mesh` (both positions-only). */
void shape_append(lk_mesh *mesh, const lk_mesh *part, double dx, double dy, double dz);

/* A deterministic value in [0, 1) from (seed, index). */
double shape_random(uint64_t seed, uint64_t index);

/* ---- animation ---------------------------------------------------------- */

/* A capsule (shape_capsule) bending over the frames like an arm at the
 * elbow: in frame f its axis turns towards +x by f / (frames - 1) *
 * max_degrees, the turn spread smoothly (smoothstep) over a joint from
 * z = length / 2 - 2 radius to length / 2 + 2 radius; each cross-section
 * stays perpendicular to the bent axis, so the limb keeps its shape apart
 * from the joint (no fold for angles under ~200 degrees). Frame 0 is the
 * straight capsule; connectivity is shared; fps 10. */
void shape_bending_capsule(lk_animation *animation, double radius, double length, unsigned around, unsigned rows,
                           unsigned cap_rings, size_t frames, double max_degrees);

/* A box grid twisting about +z: frame f turns the slice at height z by
 * f / (frames - 1) * max_degrees * (z - z_min) / size_z. fps 10. */
void shape_twisting_box(lk_animation *animation, double size_x, double size_y, double size_z, unsigned n, size_t frames,
                        double max_degrees);

/* ---- points and heightfield --------------------------------------------- */

/* `count` points of the sphere of `radius` about `centre` on a Fibonacci
 * spiral (evenly spread), with their exact outward unit normals and no
 * triangles or radii. */
void shape_sphere_points(lk_mesh *points, size_t count, double radius, const double centre[3]);

/* A size x size heightfield (size = 2^n + 1 for the terrain) with `spacing`
 * metres between samples: ridges of sines plus five octaves of bilinear
 * value noise, relief about `relief` metres, deterministic. Release with
 * shape_heightfield_free. */
void shape_heightfield(lk_heightfield *field, size_t size, double spacing, double relief);
void shape_heightfield_free(lk_heightfield *field);

/* ---- measures the core tests share ---------------------------------------- */

/* lk_mesh_compute_stats, failing the test with the library's message. */
lk_mesh_stats shape_stats(const lk_mesh *mesh);
/* Signed volume enclosed by the triangles (divergence theorem, double):
 * positive when a closed mesh's faces point outwards. */
double shape_volume(const lk_mesh *mesh);
/* lk_metro with `samples_per_face` face samples per triangle on average,
 * vertex and edge samples, seed 1; fails the test on error. */
lk_metro_result shape_metro(const lk_mesh *a, const lk_mesh *b, double samples_per_face);
/* Largest depth of a face plane below the sphere of `radius` about the
 * origin, as a fraction of the radius (1 - plane distance / radius): for
 * a mesh whose vertices lie on the sphere, every surface point lies
 * between radius * (1 - depth) and radius. */
double shape_face_depth(const lk_mesh *mesh, double radius);
/* Largest | |p - centre| - radius | over the vertices. */
double shape_sphere_deviation(const lk_mesh *mesh, const double centre[3], double radius);

#endif
