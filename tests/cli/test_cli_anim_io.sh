#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Plain mesh commands on animation files: MD2 and KMF load as their frame 0;
# broken animation files are refused with FILE:LINE or FILE: byte N.
set -u
source "$(dirname "$0")/lib.sh"
faerie="$LK_SAMPLES_DIR/faerie.md2"
anim="${LK_TEST_DATA_DIR:-$(dirname "$0")/../data}/anim"

# faerie.md2: 366 positions x 487 texcoords welded into 503 vertices, 654 triangles.
expect_output_contains '"vertices":503' "$LODKIT" info --json "$faerie"
expect_output_contains '"triangles":654' "$LODKIT" info --json "$faerie"
expect_output_contains '"vertices":482' "$LODKIT" info --json "$LK_SAMPLES_DIR/assimp/MD2/sydney.md2"
check "convert faerie.md2 to OBJ" "$LODKIT" convert --quiet "$faerie" "$TMP/faerie.obj"
check "OBJ has 503 vertices" test "$(grep -c '^v ' "$TMP/faerie.obj")" -eq 503
check "OBJ has 654 faces" test "$(grep -c '^f ' "$TMP/faerie.obj")" -eq 654

# KMF: frame 0 of a two-frame triangle.
expect_output_contains '"vertices":3' "$LODKIT" info --json "$anim/triangle.kmf"

# Broken inputs: a clear message naming the file and where, exit 1.
expect_exit 1 "$LODKIT" info "$anim/bad-vertex-count.kmf"
expect_output_contains "bad-vertex-count.kmf:13: frame 1 (line 10) has 2 vertices but frame 0 has 3" \
  "$LODKIT" info "$anim/bad-vertex-count.kmf"
head -c 1000 "$faerie" > "$TMP/cut.md2"
expect_exit 1 "$LODKIT" info "$TMP/cut.md2"
expect_output_contains "cut.md2: byte 68: texture coordinate block (487 x 4 bytes) runs past the end of the file (1000 bytes)" "$LODKIT" info "$TMP/cut.md2"
: > "$TMP/empty.md2"
expect_exit 1 "$LODKIT" info "$TMP/empty.md2"
expect_output_contains "empty.md2: empty file" "$LODKIT" info "$TMP/empty.md2"
finish
