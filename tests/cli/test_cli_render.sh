#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `lodkit render`, `lodkit sample` and `lodkit splat` on real models,
# headless (Mesa llvmpipe): PNGs written, JSON figures, clear errors.
set -u
source "$(dirname "$0")/lib.sh"
bunny="$LK_SAMPLES_DIR/bunny.obj"
num() { grep -o "\"$1\":[-0-9.e+]*" | head -1 | cut -d: -f2; }
is_png() { [ "$(head -c 8 "$1" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]; }

for command in render sample splat; do expect_exit 0 "$LODKIT" $command --help; done
expect_exit 2 "$LODKIT" render "$bunny"                                  # no -o
expect_exit 2 "$LODKIT" render --size=0x10 "$bunny" -o "$TMP/x.png"
expect_exit 2 "$LODKIT" splat --passes=3 "$bunny" -o "$TMP/x.png"
expect_exit 2 "$LODKIT" sample "$bunny" "$TMP/x.obj"                      # PLY only

# meshes
"$LODKIT" render -q --size=256x256 "$bunny" -o "$TMP/bunny.png"
check "bunny render is a PNG" is_png "$TMP/bunny.png"
"$LODKIT" render -q --size=256x256 --wireframe --strips "$LK_SAMPLES_DIR/triceratops.off" -o "$TMP/tri.png"
check "triceratops wireframe strips PNG" is_png "$TMP/tri.png"
json=$("$LODKIT" render --json --size=128x128 "$LK_SAMPLES_DIR/cow.off" -o "$TMP/cow.png")
check "render JSON counts the cow's triangles" grep -q '"primitives":5804' <<<"$json"

# sample -> splat, 1 and 2 passes
json=$("$LODKIT" sample --json --points=20000 "$bunny" "$TMP/bunny-points.ply")
check "sample JSON has 20000 points" grep -q '"points":20000' <<<"$json"
out=$("$LODKIT" info --json "$TMP/bunny-points.ply")
check "sampled PLY readable as 20000 points" grep -q '"vertices":20000' <<<"$out"
for passes in 1 2; do
  "$LODKIT" splat -q --size=256x256 --passes=$passes "$TMP/bunny-points.ply" -o "$TMP/splat-$passes.png"
  check "splat $passes-pass PNG" is_png "$TMP/splat-$passes.png"
done
differ() { ! cmp -s "$1" "$2"; }
check "1- and 2-pass images differ" differ "$TMP/splat-1.png" "$TMP/splat-2.png"
"$LODKIT" splat -q --size=128x128 --flat-points --points=5000 "$bunny" -o "$TMP/flat.png"
check "splat samples a mesh itself" is_png "$TMP/flat.png"
# the kitten point set has normals: radii are added
"$LODKIT" sample -q "$LK_SAMPLES_DIR/kitten.xyz" "$TMP/kitten.ply"
"$LODKIT" splat -q --size=128x128 "$TMP/kitten.ply" -o "$TMP/kitten.png"
check "kitten splats" is_png "$TMP/kitten.png"

# errors: points without normals, an output that is not a regular file, no driver
awk 'NR <= 500 { print $1, $2, $3 }' "$LK_SAMPLES_DIR/kitten.xyz" > "$TMP/bare.xyz"
expect_exit 1 "$LODKIT" sample "$TMP/bare.xyz" "$TMP/bare.ply"
expect_output_contains "--estimate-normals" "$LODKIT" sample "$TMP/bare.xyz" "$TMP/bare.ply"
expect_exit 0 "$LODKIT" sample -q --estimate-normals "$TMP/bare.xyz" "$TMP/bare.ply"
expect_exit 1 "$LODKIT" splat "$TMP/bare.xyz" -o "$TMP/bare.png"
mkfifo "$TMP/fifo"
expect_exit 1 "$LODKIT" render --size=64x64 "$bunny" -o "$TMP/fifo"
check "fifo left in place" test -p "$TMP/fifo"
expect_exit 1 env LIBGL_DRIVERS_PATH=/nonexistent "$LODKIT" render --size=64x64 "$bunny" -o "$TMP/nodriver.png"
expect_output_contains "libgl1-mesa-dri" env LIBGL_DRIVERS_PATH=/nonexistent "$LODKIT" render --size=64x64 "$bunny" -o "$TMP/nodriver.png"
check "no PNG without a driver" test ! -e "$TMP/nodriver.png"
finish
