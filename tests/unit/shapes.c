/* SPDX-License-Identifier: MIT */
/* Procedural shapes for the core unit tests (see shapes.h): surfaces of
 * revolution (spheres, capsules, open cylinders), icospheres, tori, box
 * grids, planes, noisy spheres, two deforming animations, a sphere point
 * set and a heightfield. No samples needed. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapes.h"

static void alloc_mesh(lk_mesh *mesh, size_t vertex_count, size_t triangle_count)
{
    lk_error error = {0};
    lk_mesh_init(mesh);
    if (lk_mesh_alloc(mesh, vertex_count, triangle_count, 0, &error) != LK_OK) fail_msg("shape: %s", error.message);
}

static void set_position(lk_mesh *mesh, size_t v, double x, double y, double z)
{
    float *p = mesh->positions + 3 * v;
    p[0] = (float)x, p[1] = (float)y, p[2] = (float)z;
}

static void set_triangle(lk_mesh *mesh, size_t t, uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t *triangle = mesh->indices + 3 * t;
    triangle[0] = a, triangle[1] = b, triangle[2] = c;
}

void shape_revolve(lk_mesh *mesh, const double *r, const double *z, unsigned count, unsigned around)
{
    if (count < 2 || around < 3) fail_msg("shape_revolve: %u profile points, %u around", count, around);
    int bottom_pole = r[0] == 0, top_pole = r[count - 1] == 0;
    for (unsigned i = 1; i + 1 < count; i++)
        if (r[i] == 0) fail_msg("shape_revolve: pole inside the profile");
    unsigned poles = (unsigned)(bottom_pole + top_pole), rings = count - poles;
    size_t vertex_count = poles + (size_t)around * rings;
    size_t triangle_count = 2 * (size_t)around * (count - 1) - (size_t)around * poles;
    alloc_mesh(mesh, vertex_count, triangle_count);

    /* Vertex of profile point i at angle step j (a pole has one). */
    uint32_t *first = malloc(count * sizeof *first);
    assert_non_null(first);
    size_t v = 0;
    for (unsigned i = 0; i < count; i++) {
        first[i] = (uint32_t)v;
        if (r[i] == 0) {
            set_position(mesh, v++, 0, 0, z[i]);
            continue;
        }
        for (unsigned j = 0; j < around; j++) {
            double angle = 2 * SHAPE_PI * j / around;
            set_position(mesh, v++, r[i] * cos(angle), r[i] * sin(angle), z[i]);
        }
    }
    /* Quad (i, j) (i + 1, j + 1) as (a, b, c) (a, c, d): b - a runs along
     * the angle, d - a up the profile, so the normal points outwards. */
    size_t t = 0;
    for (unsigned i = 0; i + 1 < count; i++) {
        for (unsigned j = 0; j < around; j++) {
            unsigned k = (j + 1) % around;
            uint32_t a = first[i] + (r[i] == 0 ? 0 : j), b = first[i] + (r[i] == 0 ? 0 : k);
            uint32_t c = first[i + 1] + (r[i + 1] == 0 ? 0 : k), d = first[i + 1] + (r[i + 1] == 0 ? 0 : j);
            if (a != b) set_triangle(mesh, t++, a, b, c);
            if (c != d) set_triangle(mesh, t++, a, c, d);
        }
    }
    free(first);
    if (v != vertex_count || t != triangle_count) fail_msg("shape_revolve: counts");
}

void shape_textured_sphere(lk_mesh *mesh, unsigned slices, unsigned stacks, float **tangents)
{
    size_t vertex_count = (size_t)(slices + 1) * (stacks + 1), triangle_count = (size_t)2 * slices * (stacks - 1);
    assert_int_equal(lk_mesh_alloc(mesh, vertex_count, triangle_count, LK_ATTR_NORMALS | LK_ATTR_TEXCOORDS, NULL),
                     LK_OK);
    if (tangents) {
        *tangents = malloc(vertex_count * 4 * sizeof(float));
        assert_non_null(*tangents);
    }
    for (unsigned j = 0; j <= stacks; j++)
        for (unsigned i = 0; i <= slices; i++) {
            size_t v = (size_t)j * (slices + 1) + i;
            double theta = SHAPE_PI * j / stacks, phi = 2 * SHAPE_PI * (i % slices) / slices;
            double p[3] = {sin(theta) * cos(phi), cos(theta), -sin(theta) * sin(phi)};
            if (j == 0 || j == stacks) p[0] = p[2] = 0; /* the poles: one point */
            for (int k = 0; k < 3; k++)
                mesh->positions[3 * v + (size_t)k] = mesh->normals[3 * v + (size_t)k] = (float)p[k];
            mesh->texcoords[2 * v] = (float)i / (float)slices;
            mesh->texcoords[2 * v + 1] = 1.0f - (float)j / (float)stacks;
            if (tangents) {
                float *t = *tangents + 4 * v;
                t[0] = (float)-sin(phi), t[1] = 0, t[2] = (float)-cos(phi), t[3] = 1;
            }
        }
    size_t t = 0;
    for (unsigned j = 0; j < stacks; j++)
        for (unsigned i = 0; i < slices; i++) {
            uint32_t a = j * (slices + 1) + i, b = a + 1, c = a + slices + 1, d = c + 1;
            if (j != 0) {
                uint32_t *tri = mesh->indices + 3 * t++;
                tri[0] = a, tri[1] = c, tri[2] = b;
            }
            if (j != stacks - 1) {
                uint32_t *tri = mesh->indices + 3 * t++;
                tri[0] = b, tri[1] = c, tri[2] = d;
            }
        }
    assert_int_equal(t, triangle_count);
}

void shape_uv_sphere(lk_mesh *mesh, double radius, unsigned slices, unsigned stacks)
{
    double *r = malloc((stacks + 1) * sizeof *r), *z = malloc((stacks + 1) * sizeof *z);
    assert_true(r && z);
    for (unsigned i = 0; i <= stacks; i++) {
        double latitude = -SHAPE_PI / 2 + SHAPE_PI * i / stacks;
        r[i] = i == 0 || i == stacks ? 0 : radius * cos(latitude);
        z[i] = i == 0 ? -radius : i == stacks ? radius : radius * sin(latitude);
    }
    shape_revolve(mesh, r, z, stacks + 1, slices);
    free(r);
    free(z);
}

void shape_capsule(lk_mesh *mesh, double radius, double length, unsigned around, unsigned rows, unsigned cap_rings)
{
    unsigned count = 2 * cap_rings + rows + 1;
    double *r = malloc(count * sizeof *r), *z = malloc(count * sizeof *z);
    assert_true(r && z);
    unsigned i = 0;
    for (unsigned k = 0; k <= cap_rings; k++, i++) { /* bottom pole .. equator at z = 0 */
        double latitude = -SHAPE_PI / 2 + SHAPE_PI / 2 * k / cap_rings;
        r[i] = k == 0 ? 0 : radius * cos(latitude);
        z[i] = k == 0 ? -radius : radius * sin(latitude);
    }
    for (unsigned k = 1; k <= rows; k++, i++) { /* up the cylinder to z = length */
        r[i] = radius;
        z[i] = length * k / rows;
    }
    for (unsigned k = 1; k <= cap_rings; k++, i++) { /* top hemisphere to the pole */
        double latitude = SHAPE_PI / 2 * k / cap_rings;
        r[i] = k == cap_rings ? 0 : radius * cos(latitude);
        z[i] = length + (k == cap_rings ? radius : radius * sin(latitude));
    }
    shape_revolve(mesh, r, z, count, around);
    free(r);
    free(z);
}

void shape_cylinder(lk_mesh *mesh, double radius, double height, unsigned around, unsigned rows)
{
    double *r = malloc((rows + 1) * sizeof *r), *z = malloc((rows + 1) * sizeof *z);
    assert_true(r && z);
    for (unsigned i = 0; i <= rows; i++) r[i] = radius, z[i] = height * i / rows;
    shape_revolve(mesh, r, z, rows + 1, around);
    free(r);
    free(z);
}

/* ---- icosphere ------------------------------------------------------------- */

/* Midpoint vertices by edge: open addressing on the key (low << 32 | high). */
typedef struct edge_table {
    size_t mask;
    uint64_t *keys; /* 0 = empty (vertex 0 is never an edge's higher end) */
    uint32_t *values;
} edge_table;

static uint32_t midpoint_vertex(edge_table *table, lk_mesh *mesh, size_t *vertex_count, uint32_t a, uint32_t b,
                                double radius)
{
    uint32_t low = a < b ? a : b, high = a < b ? b : a;
    uint64_t key = (uint64_t)low << 32 | high;
    size_t slot = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 20) & table->mask;
    while (table->keys[slot] && table->keys[slot] != key) slot = (slot + 1) & table->mask;
    if (table->keys[slot]) return table->values[slot];
    const float *p = mesh->positions + 3 * a, *q = mesh->positions + 3 * b;
    double m[3] = {((double)p[0] + q[0]) / 2, ((double)p[1] + q[1]) / 2, ((double)p[2] + q[2]) / 2};
    double length = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    uint32_t v = (uint32_t)(*vertex_count)++;
    set_position(mesh, v, m[0] * radius / length, m[1] * radius / length, m[2] * radius / length);
    table->keys[slot] = key;
    table->values[slot] = v;
    return v;
}

void shape_icosphere(lk_mesh *mesh, double radius, unsigned subdivisions)
{
    /* The icosahedron: three golden rectangles; faces counter-clockwise
     * seen from outside. */
    const double g = (1 + sqrt(5.0)) / 2;
    const double corners[12][3] = {{-1, g, 0},  {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
                                   {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
    static const uint32_t faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    size_t final_triangles = 20, final_vertices;
    for (unsigned s = 0; s < subdivisions; s++) final_triangles *= 4;
    final_vertices = final_triangles / 2 + 2;
    alloc_mesh(mesh, final_vertices, final_triangles);
    uint32_t *scratch = malloc(final_triangles * 3 * sizeof *scratch);
    assert_non_null(scratch);
    double unit = sqrt(1 + g * g);
    for (int v = 0; v < 12; v++)
        set_position(mesh, (size_t)v, corners[v][0] * radius / unit, corners[v][1] * radius / unit,
                     corners[v][2] * radius / unit);
    memcpy(mesh->indices, faces, sizeof faces);
    size_t vertex_count = 12, triangle_count = 20;

    edge_table table;
    size_t slots = 1;
    while (slots < 4 * final_triangles) slots *= 2;
    table.mask = slots - 1;
    table.keys = malloc(slots * sizeof *table.keys);
    table.values = malloc(slots * sizeof *table.values);
    assert_true(table.keys && table.values);
    for (unsigned s = 0; s < subdivisions; s++) {
        memset(table.keys, 0, slots * sizeof *table.keys);
        memcpy(scratch, mesh->indices, triangle_count * 3 * sizeof *scratch);
        for (size_t t = 0; t < triangle_count; t++) {
            uint32_t a = scratch[3 * t], b = scratch[3 * t + 1], c = scratch[3 * t + 2];
            uint32_t ab = midpoint_vertex(&table, mesh, &vertex_count, a, b, radius);
            uint32_t bc = midpoint_vertex(&table, mesh, &vertex_count, b, c, radius);
            uint32_t ca = midpoint_vertex(&table, mesh, &vertex_count, c, a, radius);
            set_triangle(mesh, 4 * t, a, ab, ca);
            set_triangle(mesh, 4 * t + 1, ab, b, bc);
            set_triangle(mesh, 4 * t + 2, ca, bc, c);
            set_triangle(mesh, 4 * t + 3, ab, bc, ca);
        }
        triangle_count *= 4;
    }
    free(table.keys);
    free(table.values);
    free(scratch);
    if (vertex_count != final_vertices) fail_msg("shape_icosphere: %zu vertices", vertex_count);
}

/* ---- other closed and open shapes ------------------------------------------- */

void shape_torus(lk_mesh *mesh, double major, double minor, unsigned n_major, unsigned n_minor)
{
    alloc_mesh(mesh, (size_t)n_major * n_minor, 2 * (size_t)n_major * n_minor);
    for (unsigned i = 0; i < n_major; i++) {
        double u = 2 * SHAPE_PI * i / n_major;
        for (unsigned j = 0; j < n_minor; j++) {
            double w = 2 * SHAPE_PI * j / n_minor;
            set_position(mesh, (size_t)i * n_minor + j, (major + minor * cos(w)) * cos(u),
                         (major + minor * cos(w)) * sin(u), minor * sin(w));
            /* u grows around +z, w outwards then up: (d/du) x (d/dw) points out. */
            uint32_t a = i * n_minor + j, b = ((i + 1) % n_major) * n_minor + j,
                     c = ((i + 1) % n_major) * n_minor + (j + 1) % n_minor, d = i * n_minor + (j + 1) % n_minor;
            size_t t = 2 * ((size_t)i * n_minor + j);
            set_triangle(mesh, t, a, b, c);
            set_triangle(mesh, t + 1, a, c, d);
        }
    }
}

void shape_box(lk_mesh *mesh, double size_x, double size_y, double size_z, unsigned n)
{
    size_t side = (size_t)n + 1, lattice_count = side * side * side;
    alloc_mesh(mesh, 6 * (size_t)n * n + 2, 12 * (size_t)n * n);
    /* Lattice point (x, y, z) in [0, n]^3 -> vertex, shared by the faces
     * that meet on it. */
    uint32_t *vertex_of = malloc(lattice_count * sizeof *vertex_of);
    assert_non_null(vertex_of);
    memset(vertex_of, 0xFF, lattice_count * sizeof *vertex_of);
    const double size[3] = {size_x, size_y, size_z};
    size_t vertex_count = 0, t = 0;
    for (int axis = 0; axis < 3; axis++) {
        for (int high = 0; high <= 1; high++) {
            /* u x v = +axis (cyclic order); the low face swaps them. */
            int u = (axis + 1) % 3, v = (axis + 2) % 3;
            if (!high) u = (axis + 2) % 3, v = (axis + 1) % 3;
            uint32_t corner[2][2];
            for (unsigned i = 0; i < n; i++) {
                for (unsigned j = 0; j < n; j++) {
                    for (int di = 0; di <= 1; di++) {
                        for (int dj = 0; dj <= 1; dj++) {
                            unsigned p[3];
                            p[axis] = high ? n : 0;
                            p[u] = i + (unsigned)di;
                            p[v] = j + (unsigned)dj;
                            size_t key = (p[0] * side + p[1]) * side + p[2];
                            if (vertex_of[key] == UINT32_MAX) {
                                vertex_of[key] = (uint32_t)vertex_count;
                                set_position(mesh, vertex_count++, size[0] * ((double)p[0] / n - 0.5),
                                             size[1] * ((double)p[1] / n - 0.5), size[2] * ((double)p[2] / n - 0.5));
                            }
                            corner[di][dj] = vertex_of[key];
                        }
                    }
                    set_triangle(mesh, t++, corner[0][0], corner[1][0], corner[1][1]);
                    set_triangle(mesh, t++, corner[0][0], corner[1][1], corner[0][1]);
                }
            }
        }
    }
    free(vertex_of);
    if (vertex_count != mesh->vertex_count) fail_msg("shape_box: %zu vertices", vertex_count);
}

void shape_plane(lk_mesh *mesh, double width, double depth, unsigned nx, unsigned ny)
{
    alloc_mesh(mesh, (size_t)(nx + 1) * (ny + 1), 2 * (size_t)nx * ny);
    for (unsigned j = 0; j <= ny; j++)
        for (unsigned i = 0; i <= nx; i++)
            set_position(mesh, (size_t)j * (nx + 1) + i, width * i / nx, depth * j / ny, 0);
    size_t t = 0;
    for (unsigned j = 0; j < ny; j++)
        for (unsigned i = 0; i < nx; i++) {
            uint32_t a = j * (nx + 1) + i, b = a + 1, c = a + nx + 2, d = a + nx + 1;
            set_triangle(mesh, t++, a, b, c);
            set_triangle(mesh, t++, a, c, d);
        }
}

double shape_random(uint64_t seed, uint64_t index)
{
    uint64_t x = seed * 0x9E3779B97F4A7C15ull + index + 0x632BE59BD9B4E019ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    x ^= x >> 31;
    return (double)(x >> 11) / 9007199254740992.0; /* 2^53 */
}

void shape_noisy_sphere(lk_mesh *mesh, double radius, unsigned subdivisions, double amplitude, uint64_t seed)
{
    shape_icosphere(mesh, 1.0, subdivisions);
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        double scale = radius * (1 + amplitude * (2 * shape_random(seed, v) - 1));
        float *p = mesh->positions + 3 * v;
        for (int k = 0; k < 3; k++) p[k] = (float)(p[k] * scale);
    }
}

void shape_append(lk_mesh *mesh, const lk_mesh *part, double dx, double dy, double dz)
{
    size_t v0 = mesh->vertex_count, t0 = mesh->triangle_count;
    size_t vertex_count = v0 + part->vertex_count, triangle_count = t0 + part->triangle_count;
    float *positions = realloc(mesh->positions, (vertex_count ? vertex_count : 1) * 3 * sizeof *positions);
    assert_non_null(positions);
    mesh->positions = positions;
    uint32_t *indices = realloc(mesh->indices, (triangle_count ? triangle_count : 1) * 3 * sizeof *indices);
    assert_non_null(indices);
    mesh->indices = indices;
    for (size_t v = 0; v < part->vertex_count; v++) {
        const float *p = part->positions + 3 * v;
        set_position(mesh, v0 + v, p[0] + dx, p[1] + dy, p[2] + dz);
    }
    for (size_t i = 0; i < 3 * part->triangle_count; i++) indices[3 * t0 + i] = part->indices[i] + (uint32_t)v0;
    mesh->vertex_count = vertex_count;
    mesh->triangle_count = triangle_count;
}

/* ---- animations -------------------------------------------------------------- */

static void alloc_frames(lk_animation *animation, size_t frames)
{
    animation->frame_count = frames;
    animation->frames_per_second = 10;
    animation->frame_positions = malloc(frames * animation->mesh.vertex_count * 3 * sizeof(float));
    assert_non_null(animation->frame_positions);
}

/* Turn of the bent axis at height z: 0 below the joint, `angle` above it,
 * a smoothstep in between. */
static double bend_angle(double z, double joint_low, double joint_high, double angle)
{
    if (z <= joint_low) return 0;
    if (z >= joint_high) return angle;
    double s = (z - joint_low) / (joint_high - joint_low);
    return angle * s * s * (3 - 2 * s);
}

void shape_bending_capsule(lk_animation *animation, double radius, double length, unsigned around, unsigned rows,
                           unsigned cap_rings, size_t frames, double max_degrees)
{
    lk_animation_init(animation);
    shape_capsule(&animation->mesh, radius, length, around, rows, cap_rings);
    alloc_frames(animation, frames);
    size_t vertex_count = animation->mesh.vertex_count;
    double joint_low = length / 2 - 2 * radius, joint_high = length / 2 + 2 * radius;
    for (size_t f = 0; f < frames; f++) {
        double angle = frames > 1 ? max_degrees * SHAPE_PI / 180 * (double)f / (double)(frames - 1) : 0;
        for (size_t v = 0; v < vertex_count; v++) {
            const float *p = animation->mesh.positions + 3 * v;
            /* The bent axis c(z) = integral of (sin a(s), 0, cos a(s)) ds
             * from the joint's start (midpoint rule, 64 steps); the section
             * at z keeps its offsets (x, y) in the frame turned by a(z). */
            double z = p[2], cx = 0, cz = z < joint_low ? z : joint_low;
            if (z > joint_low) {
                int steps = 64;
                double h = (z - joint_low) / steps;
                for (int k = 0; k < steps; k++) {
                    double a = bend_angle(joint_low + (k + 0.5) * h, joint_low, joint_high, angle);
                    cx += sin(a) * h;
                    cz += cos(a) * h;
                }
            }
            double a = bend_angle(z, joint_low, joint_high, angle);
            float *out = animation->frame_positions + 3 * (f * vertex_count + v);
            out[0] = (float)(cx + p[0] * cos(a));
            out[1] = p[1];
            out[2] = (float)(cz - p[0] * sin(a));
        }
    }
    memcpy(animation->mesh.positions, animation->frame_positions, vertex_count * 3 * sizeof(float));
}

void shape_twisting_box(lk_animation *animation, double size_x, double size_y, double size_z, unsigned n, size_t frames,
                        double max_degrees)
{
    lk_animation_init(animation);
    shape_box(&animation->mesh, size_x, size_y, size_z, n);
    alloc_frames(animation, frames);
    size_t vertex_count = animation->mesh.vertex_count;
    for (size_t f = 0; f < frames; f++) {
        double turn = frames > 1 ? max_degrees * SHAPE_PI / 180 * (double)f / (double)(frames - 1) : 0;
        for (size_t v = 0; v < vertex_count; v++) {
            const float *p = animation->mesh.positions + 3 * v;
            double a = turn * ((double)p[2] / size_z + 0.5);
            float *out = animation->frame_positions + 3 * (f * vertex_count + v);
            out[0] = (float)(p[0] * cos(a) - p[1] * sin(a));
            out[1] = (float)(p[0] * sin(a) + p[1] * cos(a));
            out[2] = p[2];
        }
    }
    memcpy(animation->mesh.positions, animation->frame_positions, vertex_count * 3 * sizeof(float));
}

/* ---- points and heightfield ------------------------------------------------------ */

void shape_sphere_points(lk_mesh *points, size_t count, double radius, const double centre[3])
{
    lk_error error = {0};
    lk_mesh_init(points);
    if (lk_mesh_alloc(points, count, 0, LK_ATTR_NORMALS, &error) != LK_OK) fail_msg("shape: %s", error.message);
    const double golden_angle = SHAPE_PI * (3 - sqrt(5.0));
    for (size_t i = 0; i < count; i++) {
        double z = 1 - (2 * (double)i + 1) / (double)count, ring = sqrt(1 - z * z);
        double n[3] = {ring * cos(golden_angle * (double)i), ring * sin(golden_angle * (double)i), z};
        for (int k = 0; k < 3; k++) {
            points->normals[3 * i + k] = (float)n[k];
            points->positions[3 * i + k] = (float)(centre[k] + radius * n[k]);
        }
    }
}

/* Value noise: a random height at every integer lattice point of octave
 * `octave`, smoothstep-interpolated in between. */
static double value_noise(double x, double y, uint64_t octave)
{
    double fx = floor(x), fy = floor(y);
    int64_t ix = (int64_t)fx, iy = (int64_t)fy;
    double sx = x - fx, sy = y - fy;
    sx = sx * sx * (3 - 2 * sx);
    sy = sy * sy * (3 - 2 * sy);
    double h[2][2];
    for (int dy = 0; dy <= 1; dy++)
        for (int dx = 0; dx <= 1; dx++)
            h[dy][dx] = shape_random(octave, (uint64_t)(ix + dx) * 0x100000001B3ull ^ (uint64_t)(iy + dy));
    double low = h[0][0] + (h[0][1] - h[0][0]) * sx, high = h[1][0] + (h[1][1] - h[1][0]) * sx;
    return low + (high - low) * sy;
}

void shape_heightfield(lk_heightfield *field, size_t size, double spacing, double relief)
{
    memset(field, 0, sizeof *field);
    field->width = field->height = size;
    field->spacing_x = field->spacing_y = spacing;
    field->heights = malloc(size * size * sizeof *field->heights);
    assert_non_null(field->heights);
    field->min_height = INFINITY;
    field->max_height = -INFINITY;
    for (size_t j = 0; j < size; j++) {
        for (size_t i = 0; i < size; i++) {
            double u = (double)i / (double)(size - 1), v = (double)j / (double)(size - 1);
            /* Two ridges, then noise from 4 to 64 cells across. */
            double h = 0.25 * sin(2 * SHAPE_PI * (u + 0.3 * v)) + 0.15 * cos(3 * SHAPE_PI * v);
            double amplitude = 0.3;
            for (uint64_t octave = 0; octave < 5; octave++) {
                double cells = 4.0 * (double)(1u << octave);
                h += amplitude * (value_noise(u * cells, v * cells, octave) - 0.5);
                amplitude /= 2;
            }
            float height = (float)(relief * h);
            field->heights[j * size + i] = height;
            if (height < field->min_height) field->min_height = height;
            if (height > field->max_height) field->max_height = height;
        }
    }
}

void shape_heightfield_free(lk_heightfield *field)
{
    free(field->heights);
    memset(field, 0, sizeof *field);
}

/* ---- measures ------------------------------------------------------------------ */

lk_mesh_stats shape_stats(const lk_mesh *mesh)
{
    lk_mesh_stats stats;
    lk_error error = {0};
    if (lk_mesh_compute_stats(mesh, &stats, &error) != LK_OK) fail_msg("stats: %s", error.message);
    return stats;
}

double shape_volume(const lk_mesh *mesh)
{
    double volume = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const float *a = mesh->positions + 3 * mesh->indices[3 * t],
                    *b = mesh->positions + 3 * mesh->indices[3 * t + 1],
                    *c = mesh->positions + 3 * mesh->indices[3 * t + 2];
        volume += ((double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                   (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                   (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) /
                  6;
    }
    return volume;
}

lk_metro_result shape_metro(const lk_mesh *a, const lk_mesh *b, double samples_per_face)
{
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = samples_per_face;
    lk_metro_result result;
    lk_error error = {0};
    if (lk_metro(a, b, &options, &result, NULL, NULL, &error) != LK_OK) fail_msg("metro: %s", error.message);
    return result;
}

double shape_face_depth(const lk_mesh *mesh, double radius)
{
    double depth = 0;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const float *a = mesh->positions + 3 * mesh->indices[3 * t],
                    *b = mesh->positions + 3 * mesh->indices[3 * t + 1],
                    *c = mesh->positions + 3 * mesh->indices[3 * t + 2];
        double e0[3], e1[3], n[3];
        for (int k = 0; k < 3; k++) e0[k] = (double)b[k] - a[k], e1[k] = (double)c[k] - a[k];
        n[0] = e0[1] * e1[2] - e0[2] * e1[1], n[1] = e0[2] * e1[0] - e0[0] * e1[2],
        n[2] = e0[0] * e1[1] - e0[1] * e1[0];
        double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        double plane = (n[0] * a[0] + n[1] * a[1] + n[2] * a[2]) / length;
        if (1 - plane / radius > depth) depth = 1 - plane / radius;
    }
    return depth;
}

double shape_sphere_deviation(const lk_mesh *mesh, const double centre[3], double radius)
{
    double worst = 0;
    for (size_t v = 0; v < mesh->vertex_count; v++) {
        const float *p = mesh->positions + 3 * v;
        double dx = p[0] - centre[0], dy = p[1] - centre[1], dz = p[2] - centre[2];
        double off = fabs(sqrt(dx * dx + dy * dy + dz * dz) - radius);
        if (off > worst) worst = off;
    }
    return worst;
}
