#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Prints one table row comparing lodkit metro's JSON with metro_open3d.py's.

Usage: compare_metro.py LABEL LODKIT.json OPEN3D.json
Columns: forward/backward max and RMS of both tools, as % of the diagonal,
and the relative difference of each (target: within 2%).
"""
import json
import sys

label, ours_path, theirs_path = sys.argv[1:4]
ours = json.load(open(ours_path))
theirs = json.load(open(theirs_path))
diagonal = ours["diagonal"]
cells = []
worst = 0.0
for side in ("forward", "backward"):
    for key in ("max", "rms"):
        a, b = ours[side][key], theirs[side][key]
        difference = 100.0 * (a - b) / b if b else 0.0
        worst = max(worst, abs(difference))
        cells.append(f"{100 * a / diagonal:8.4f} {100 * b / diagonal:8.4f} {difference:+6.2f}%")
print(f"| {label:<28} | " + " | ".join(cells) + f" | {worst:5.2f}% |")
