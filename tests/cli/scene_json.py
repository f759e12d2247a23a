#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The "scene" object of `lodkit info --json` (read from stdin) printed
canonically (sorted keys, compact), so that two scenes compare as strings.

  --hoist       the scene as lodkit's glTF writer writes it: a node holding
                a skinned mesh under a parent gives its mesh, skin and morph
                weights to a new root node appended to the nodes (identity
                transform, no children, the same name), listed among the
                roots after the old node's topmost ancestor; channels on the
                old node's morph weights follow (src/io_gltf_hoist.c). An
                independent statement of that rule, for the round trips in
                test_cli_scene.sh.
  --no-weights  WEIGHTS_0 hashes left out (the writer normalises weights
                that do not sum to 1)."""
import json
import sys

info = json.load(sys.stdin)
scene = info["scene"]


def drop_weight_hashes(item):
    if isinstance(item, dict):
        return {k: drop_weight_hashes(v) for k, v in item.items() if not (k == "weights" and isinstance(v, str))}
    if isinstance(item, list):
        return [drop_weight_hashes(v) for v in item]
    return item


if "--hoist" in sys.argv[1:]:
    nodes = scene["nodes"]
    parent = {child: index for index, node in enumerate(nodes) for child in node.get("children", [])}
    for index in range(len(nodes)):
        node = nodes[index]
        if index not in parent or "skin" not in node or "mesh" not in node:
            continue
        moved = {"name": node["name"]} if "name" in node else {}
        moved["mesh"] = node.pop("mesh")
        moved["skin"] = node.pop("skin")
        moved["children"] = []
        moved["matrix"] = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
        if "weights" in node:
            moved["weights"] = node.pop("weights")
        nodes.append(moved)
        top = index
        while top in parent:
            top = parent[top]
        if top in scene["roots"]:
            scene["roots"].append(len(nodes) - 1)
        for animation in scene.get("animations", []):
            for channel in animation.get("channels", []):
                if channel.get("node") == index and channel.get("path") == "weights":
                    channel["node"] = len(nodes) - 1
if "--no-weights" in sys.argv[1:]:
    scene = drop_weight_hashes(scene)
print(json.dumps(scene, sort_keys=True, separators=(",", ":")))
