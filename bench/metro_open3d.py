#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Independent check of lodkit's Metro distance with Open3D.

Usage: /usr/bin/python3 bench/metro_open3d.py A B [--samples-per-face 10] [--seed 1]
                                              [--samples-a N --samples-b N]

Samples each surface uniformly (Open3D's sample_points_uniformly) with
--samples-a / --samples-b points (bench/run.sh passes the counts lodkit
took), or else samples_per_face * triangles + the vertices, measures exact
point-to-surface distances with RaycastingScene.compute_distance in both
directions and prints JSON:
  {"forward": {"max", "max_faces", "mean", "rms", "samples"},
   "backward": {...}, "hausdorff", "diagonal"}
forward = samples of A measured to B, backward = B to A, diagonal = bounding
box diagonal of A (as lodkit reports them). Open3D samples are all on faces,
so mean and RMS are area-weighted like lodkit's. "max" is over those samples
and the mesh's vertices (lodkit samples every vertex too, which is where
the maximum of a spiky surface lies); "max_faces" over the face samples only.

Needs Debian's python3-open3d and python3-numpy: run it with /usr/bin/python3
(a pyenv python3 earlier on PATH does not have them).
"""
import argparse
import json
import sys

import numpy as np
import open3d as o3d


def load(path):
    mesh = o3d.io.read_triangle_mesh(path)
    if len(mesh.triangles) == 0:
        sys.exit(f"{path}: no triangles read")
    return mesh


def sample_count(mesh, samples_per_face):
    return int(round(samples_per_face * len(mesh.triangles))) + len(mesh.vertices)


def one_sided(source, target, count):
    """Distances from `count` uniform samples of `source` to the surface of `target`."""
    points = source.sample_points_uniformly(number_of_points=count)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(target))
    query = o3d.core.Tensor(np.asarray(points.points, dtype=np.float32))
    distance = scene.compute_distance(query).numpy().astype(np.float64)
    corners = o3d.core.Tensor(np.asarray(source.vertices, dtype=np.float32))
    corner_distance = scene.compute_distance(corners).numpy().astype(np.float64)
    return {
        "max": float(max(distance.max(), corner_distance.max())),
        "max_faces": float(distance.max()),
        "mean": float(distance.mean()),
        "rms": float(np.sqrt(np.mean(distance * distance))),
        "samples": int(distance.size),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a")
    parser.add_argument("b")
    parser.add_argument("--samples-per-face", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--samples-a", type=int, default=0)
    parser.add_argument("--samples-b", type=int, default=0)
    args = parser.parse_args()
    o3d.utility.random.seed(args.seed)
    a, b = load(args.a), load(args.b)
    forward = one_sided(a, b, args.samples_a or sample_count(a, args.samples_per_face))
    backward = one_sided(b, a, args.samples_b or sample_count(b, args.samples_per_face))
    box = a.get_axis_aligned_bounding_box()
    diagonal = float(np.linalg.norm(np.asarray(box.get_max_bound()) - np.asarray(box.get_min_bound())))
    print(json.dumps({
        "forward": forward,
        "backward": backward,
        "hausdorff": max(forward["max"], backward["max"]),
        "diagonal": diagonal,
    }, indent=2))


if __name__ == "__main__":
    main()
