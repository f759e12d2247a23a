#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Open3D's simplifiers, timed, for bench_simplify's table.

Usage: /usr/bin/python3 bench/simplify_open3d.py IN OUT.ply --method quadric|clustering
                                                 --triangles N [--runs 5] [--budget 30]
Runs the method up to --runs times (stopping early once --budget seconds
are spent, since Open3D's quadric decimation takes ~30 s per run on a
1M-triangle mesh), writes the result to OUT.ply and prints JSON
{"median_ms": .., "runs": .., "triangles": ..}. Vertex clustering takes a
voxel size, not a count: the voxel size that gets closest to N triangles
without exceeding it is found first by bisection (untimed), then timed.
Single thread (OMP_NUM_THREADS=1 is set by the caller).
"""
import argparse
import json
import statistics
import sys
import time

import open3d as o3d


def run(mesh, method, parameter):
    if method == "quadric":
        return mesh.simplify_quadric_decimation(target_number_of_triangles=int(parameter))
    return mesh.simplify_vertex_clustering(voxel_size=parameter,
                                           contraction=o3d.geometry.SimplificationContraction.Average)


def voxel_for(mesh, triangles):
    extent = mesh.get_max_bound() - mesh.get_min_bound()
    low, high = 1e-6 * max(extent), max(extent)
    best = high
    for _ in range(30):
        middle = (low * high) ** 0.5
        count = len(run(mesh, "clustering", middle).triangles)
        if count > triangles:
            low = middle
        else:
            best, high = middle, middle
    return best


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("input")
    parser.add_argument("output")
    parser.add_argument("--method", choices=["quadric", "clustering"], required=True)
    parser.add_argument("--triangles", type=int, required=True)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--budget", type=float, default=30.0)
    args = parser.parse_args()
    mesh = o3d.io.read_triangle_mesh(args.input)
    if len(mesh.triangles) == 0:
        sys.exit(f"{args.input}: no triangles")
    parameter = args.triangles if args.method == "quadric" else voxel_for(mesh, args.triangles)
    times, result = [], None
    spent = 0.0
    for _ in range(args.runs):
        start = time.perf_counter()
        result = run(mesh, args.method, parameter)
        elapsed = time.perf_counter() - start
        times.append(elapsed)
        spent += elapsed
        if spent > args.budget:
            break
    result.remove_degenerate_triangles()
    result.remove_unreferenced_vertices()
    o3d.io.write_triangle_mesh(args.output, result, write_ascii=False)
    print(json.dumps({"median_ms": 1000 * statistics.median(times), "runs": len(times),
                      "triangles": len(result.triangles)}))


if __name__ == "__main__":
    main()
