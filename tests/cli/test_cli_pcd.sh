#!/bin/bash
# SPDX-License-Identifier: MIT
# PCD point clouds (src/io_pcd.c) through the CLI: `lodkit info` and
# `lodkit convert` on python-pcl's example clouds (data/samples/pcd/, DATA
# ascii and binary_compressed, rgb and rgba, an organised cloud with NaN
# points), `lodkit splat` on a PCD with normals written here and on a real
# cloud once `lodkit sample --estimate-normals` gave it normals, and a cut
# file refused with its byte offset and no output.
source "$(dirname "$0")/lib.sh"

S="$LK_SAMPLES_DIR/pcd"
expect_output_contains "vertices              1,771" "$LODKIT" info "$S/test_pcd.pcd"
expect_output_contains "format                pcd" "$LODKIT" info "$S/bun0.pcd"
expect_output_contains "vertices              112,586" "$LODKIT" info "$S/bun0.pcd"
# 307,200 points, 97,920 of them NaN (missing in the stereo grid)
expect_output_contains "vertices              209,280" "$LODKIT" info "$S/table_scene_mug_stereo_textured.pcd"
expect_output_contains "attributes            colors" "$LODKIT" info "$S/milk.pcd"

check "convert PCD to PLY" "$LODKIT" convert "$S/milk.pcd" "$TMP/milk.ply"
expect_output_contains "vertices              12,575" "$LODKIT" info "$TMP/milk.ply"
expect_output_contains "attributes            colors" "$LODKIT" info "$TMP/milk.ply"
check "convert PCD to XYZ" "$LODKIT" convert "$S/test_pcd.pcd" "$TMP/test.xyz"
check "1,771 lines of XYZ" test "$(wc -l <"$TMP/test.xyz")" -eq 1771

# A 20x20 patch with normals (z = 0, normal +z), DATA ascii, by hand.
{
  printf '# .PCD v0.7\nVERSION 0.7\nFIELDS x y z normal_x normal_y normal_z\nSIZE 4 4 4 4 4 4\n'
  printf 'TYPE F F F F F F\nCOUNT 1 1 1 1 1 1\nWIDTH 400\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 400\nDATA ascii\n'
  for i in $(seq 0 19); do for j in $(seq 0 19); do printf '%d %d 0 0 0 1\n' "$i" "$j"; done; done
} >"$TMP/patch.pcd"
check "splat a PCD with normals" "$LODKIT" splat "$TMP/patch.pcd" -o "$TMP/patch.png" -s 64x64
check "the splat image exists" test -s "$TMP/patch.png"
# A real cloud has no normals: the message says how to get them, and that way works.
expect_output_contains "no normals" "$LODKIT" splat "$S/bun0.pcd" -o "$TMP/bun0.png" -s 64x64
check "no image without normals" test ! -e "$TMP/bun0.png"
check "sample --estimate-normals on a PCD" "$LODKIT" sample --estimate-normals "$S/milk.pcd" "$TMP/milk_oriented.ply"
check "splat the oriented PCD cloud" "$LODKIT" splat "$TMP/milk_oriented.ply" -o "$TMP/milk.png" -s 64x64

# A cut binary_compressed file: the compressed size runs past the end.
head -c 100000 "$S/bun0.pcd" >"$TMP/cut.pcd"
expect_exit 1 "$LODKIT" convert "$TMP/cut.pcd" "$TMP/cut.ply"
expect_output_contains "cut.pcd: byte 185: compressed size 599800 is more than the 99807 bytes that follow" "$LODKIT" info "$TMP/cut.pcd"
check "no output from a cut file" test ! -e "$TMP/cut.ply"
finish
