#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""gltf_nest.py IN.gltf OUT.gltf: IN with the roots of its default scene
moved below one new root node, "mover", translated by (5, 0, 0). A skinned
mesh's node then has a parent, as in Qt 3D's RiggedFigure: the Khronos
validator warns NODE_SKINNED_MESH_NON_ROOT, and a viewer still draws the
mesh where its joints (now moved too) put it. IN must be self-contained
(data: URIs) or OUT written next to its files."""
import json
import sys

source, target = sys.argv[1], sys.argv[2]
with open(source) as file:
    document = json.load(file)
scene = document["scenes"][document.get("scene", 0)]
document["nodes"].append({"name": "mover", "translation": [5, 0, 0], "children": scene["nodes"]})
scene["nodes"] = [len(document["nodes"]) - 1]
with open(target, "w") as file:
    json.dump(document, file)
