# SPDX-License-Identifier: MIT
"""Silhouette references for the sample scans that come without a mesh (issue 23).

Usage: /usr/bin/python3 bench/reconstruct_scans.py SAMPLES_DIR OUT_DIR

Writes OUT_DIR/NAME.ply (a triangle mesh) for each scan, built from the scan's
own points so that the mesh covers where the scan measured a surface and no more:

- table_scene_mug_stereo_textured.pcd: an organised 640x480 stereo cloud. The
  range image is triangulated as Stanford triangulated its range scans: two
  triangles per 2x2 block of valid pixels, none across a depth jump (an edge
  longer than 4x the median grid edge).
- Haystack_Rock.las: airborne lidar, one height per place: Delaunay
  triangulation in x-y (a 2.5D surface), without triangles longer in x-y than
  4x the median x-y edge (the outline's concavities and the gaps where no
  return came back). Lengths in x-y, not 3D: the rock's steep faces are
  surface the lidar saw from above, only at a slant.
- kitten.xyz: a closed model sampled with normals: Open3D's screened Poisson
  reconstruction (depth 8), cut where the density of points is in the lowest 2%
  (the surface it invents far from any point).
- hippo1.ply: sampled with normals but open underneath, where Poisson closes it
  with a sheet out to its bounding box: ball pivoting at 1, 2, 4 and 8x the
  median spacing (the mesh goes through the points; it has holes where the
  points are sparser than that).
- pcd/bun0.pcd: a rotating-lidar room scan (not the bunny: see
  docs/benchmarks.md) taken from the origin (no point nearer than 0.100): its
  range image, Delaunay in azimuth-elevation, without triangles across depth jumps.

Needs Debian's python3-open3d, python3-numpy and python3-scipy (bench only;
scripts/install-deps.sh --bench).
"""
import os
import sys

import numpy as np
import open3d as o3d
from scipy.spatial import Delaunay


def write(mesh, path, points=None):
    """Writes the mesh; prints how far the scan's points are from it (in % of the box
    diagonal), so that a reference that misses part of the scan shows."""
    mesh.remove_unreferenced_vertices()
    mesh.remove_degenerate_triangles()
    o3d.io.write_triangle_mesh(path, mesh, write_ascii=False)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    points = np.asarray(mesh.vertices) if points is None else points
    distance = scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
    diagonal = np.linalg.norm(points.max(axis=0) - points.min(axis=0))
    print(f"{path}: {len(mesh.vertices)} vertices, {len(mesh.triangles)} triangles; scan points to it: "
          f"median {100 * np.median(distance) / diagonal:.3f}%, p99 {100 * np.quantile(distance, 0.99) / diagonal:.2f}% "
          f"of the diagonal, {100 * np.mean(distance > 0.01 * diagonal):.2f}% of the points farther than 1%")


def without_long_edges(points, triangles, factor):
    edges = np.stack([np.linalg.norm(points[triangles[:, a]] - points[triangles[:, b]], axis=1)
                      for a, b in ((0, 1), (1, 2), (2, 0))], axis=1)
    limit = factor * np.median(edges)
    return triangles[edges.max(axis=1) <= limit]


def mesh_of(points, triangles):
    return o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(points), o3d.utility.Vector3iVector(triangles))


def organised_grid(path):
    cloud = o3d.io.read_point_cloud(path, remove_nan_points=False, remove_infinite_points=False)
    points = np.asarray(cloud.points)
    width, height = 640, 480
    assert len(points) == width * height, len(points)
    valid = np.isfinite(points).all(axis=1).reshape(height, width)
    index = np.arange(width * height).reshape(height, width)
    a, b, c, d = index[:-1, :-1], index[:-1, 1:], index[1:, :-1], index[1:, 1:]
    va, vb, vc, vd = valid[:-1, :-1], valid[:-1, 1:], valid[1:, :-1], valid[1:, 1:]
    first = np.stack([a, c, b], axis=-1)[va & vc & vb]
    second = np.stack([b, c, d], axis=-1)[vb & vc & vd]
    triangles = without_long_edges(points, np.concatenate([first, second]), 4.0)
    return mesh_of(np.nan_to_num(points), triangles)


def heightfield(points):
    triangles = Delaunay(points[:, :2]).simplices
    return mesh_of(points, without_long_edges(points[:, :2], triangles, 4.0))


def poisson(cloud):
    mesh, density = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(cloud, depth=8)
    density = np.asarray(density)
    mesh.remove_vertices_by_mask(density < np.quantile(density, 0.02))
    return mesh


def ball_pivoting(cloud):
    distances = np.asarray(cloud.compute_nearest_neighbor_distance())
    spacing = float(np.median(distances[distances > 0]))
    radii = o3d.utility.DoubleVector([spacing * f for f in (1, 2, 4, 8)])
    return o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(cloud, radii)


def range_image(points):
    """A scan taken from the origin: Delaunay in (azimuth, elevation) seen from there,
    without triangles across depth jumps (longest edge over nearest range above 4x the
    median of that ratio: the angular step grows with the range)."""
    points = np.unique(points, axis=0)
    distance = np.linalg.norm(points, axis=1)
    angles = np.stack([np.arctan2(points[:, 1], points[:, 0]),
                       np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))], axis=1)
    triangles = Delaunay(angles).simplices
    edges = np.stack([np.linalg.norm(points[triangles[:, a]] - points[triangles[:, b]], axis=1)
                      for a, b in ((0, 1), (1, 2), (2, 0))], axis=1)
    ratio = edges.max(axis=1) / distance[triangles].min(axis=1)
    return mesh_of(points, triangles[ratio <= 4.0 * np.median(ratio)])


def main():
    samples, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    table = organised_grid(f"{samples}/pcd/table_scene_mug_stereo_textured.pcd")
    cloud = o3d.io.read_point_cloud(f"{samples}/pcd/table_scene_mug_stereo_textured.pcd", remove_nan_points=True)
    write(table, f"{out}/table_scene_mug_stereo_textured.ply", np.asarray(cloud.points))
    # Open3D reads no LAS: `lodkit convert las/Haystack_Rock.las OUT_DIR/Haystack_Rock.xyz` first
    haystack = np.loadtxt(f"{out}/Haystack_Rock.xyz")[:, :3]
    write(heightfield(haystack), f"{out}/Haystack_Rock.ply", haystack)
    columns = np.loadtxt(f"{samples}/kitten.xyz")  # x y z nx ny nz: Open3D's .xyz reader drops normals
    kitten = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(columns[:, :3]))
    kitten.normals = o3d.utility.Vector3dVector(columns[:, 3:6])
    write(poisson(kitten), f"{out}/kitten.ply", columns[:, :3])
    # hippo1 is not closed underneath: Poisson closes it with a sheet out to its box
    hippo = o3d.io.read_point_cloud(f"{samples}/hippo1.ply")
    write(ball_pivoting(hippo), f"{out}/hippo1.ply", np.asarray(hippo.points))
    cloud = o3d.io.read_point_cloud(f"{samples}/pcd/bun0.pcd")
    write(range_image(np.asarray(cloud.points)), f"{out}/bun0.ply", np.asarray(cloud.points))


if __name__ == "__main__":
    main()
