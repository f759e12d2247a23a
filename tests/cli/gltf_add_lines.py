#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""gltf_add_lines.py IN.gltf OUT.gltf: IN with a LINES primitive added to
its first mesh, drawing the first primitive's vertices with its index
accessor read as segments (36 box indices -> 18 segments): a scene of
triangles and lines, as CAD exports come (glTF samples have lines only in
files of their own). IN must be self-contained (data: URIs)."""
import json
import sys

source, target = sys.argv[1], sys.argv[2]
with open(source) as file:
    document = json.load(file)
first = document["meshes"][0]["primitives"][0]
lines = {"attributes": {"POSITION": first["attributes"]["POSITION"]}, "indices": first["indices"], "mode": 1}
document["meshes"][0]["primitives"].append(lines)
with open(target, "w") as file:
    json.dump(document, file)
