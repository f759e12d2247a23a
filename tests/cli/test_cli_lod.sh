#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `lodkit lod`: levels of detail in one glTF with MSFT_lod, or one file per
# level; counts, errors growing level by level, and clear refusals.
set -u
source "$(dirname "$0")/lib.sh"
cow="$LK_SAMPLES_DIR/cow.off"
num_list() { grep -o "\"$1\":[-0-9.e+]*" | cut -d: -f2; }

expect_output_contains "MSFT_lod" "$LODKIT" lod --help
json=$("$LODKIT" lod --json --levels=3 "$cow" "$TMP/cow-lod.glb")
check "three levels: 5804, ~2902, ~1451 triangles ($(num_list triangles <<<"$json" | tr '\n' ' '))" \
  test "$(num_list triangles <<<"$json" | tr '\n' ' ')" = "5804 2902 1450 "
errors=($(num_list error <<<"$json"))
check "level 0 has no error" test "${errors[0]}" = 0
check "errors grow with the level (${errors[*]})" awk -v a="${errors[1]}" -v b="${errors[2]}" 'BEGIN { exit !(a > 0 && b > a) }'
# the file: level 0 in the scene, levels 1 and 2 in MSFT_lod, coverage hints
check "MSFT_lod declared" grep -aq '"extensionsUsed":\["MSFT_lod"\]' "$TMP/cow-lod.glb"
check "MSFT_lod ids 1 and 2" grep -aq '"MSFT_lod":{"ids":\[1,2\]}' "$TMP/cow-lod.glb"
check "screen coverage hints" grep -aq '"MSFT_screencoverage":\[' "$TMP/cow-lod.glb"
info=$("$LODKIT" info --json "$TMP/cow-lod.glb")
check "a reader without MSFT_lod gets level 0" grep -q '"triangles":5804' <<<"$info"

# one file per level, any format
"$LODKIT" lod -q --separate --levels=3 --ratio=0.25 "$cow" "$TMP/cow.ply"
for level in 0 1 2; do check "cow_lod$level.ply written" test -s "$TMP/cow_lod$level.ply"; done
check "level 2 at 1/16 of the triangles" grep -q '"triangles":362' <<<"$("$LODKIT" info --json "$TMP/cow_lod2.ply")"

# compact glTF: quantised and meshopt-compressed, read back whole, smaller
"$LODKIT" convert -q "$cow" "$TMP/cow.glb"
"$LODKIT" convert -q --quantize "$cow" "$TMP/cow-q.glb"
"$LODKIT" convert -q --meshopt "$cow" "$TMP/cow-m.glb"
for f in cow-q cow-m; do
  check "$f.glb reads back 5804 triangles" grep -q '"triangles":5804' <<<"$("$LODKIT" info --json "$TMP/$f.glb")"
done
check "KHR_mesh_quantization required" grep -aq '"extensionsRequired":\["KHR_mesh_quantization"\]' "$TMP/cow-q.glb"
check "EXT_meshopt_compression required" grep -aq '"extensionsRequired":\["KHR_mesh_quantization","EXT_meshopt_compression"\]' "$TMP/cow-m.glb"
sizes="$(stat -c %s "$TMP/cow.glb") $(stat -c %s "$TMP/cow-q.glb") $(stat -c %s "$TMP/cow-m.glb")"
check "sizes shrink: $sizes" awk -v s="$sizes" 'BEGIN { split(s, a, " "); exit !(a[2] < a[1] && a[3] < a[2] / 2) }'
hausdorff=$("$LODKIT" metro --json "$cow" "$TMP/cow-m.glb" | grep -o '"hausdorff_percent":[0-9.e+-]*' | cut -d: -f2)
check "meshopt file within 0.01% of the diagonal ($hausdorff)" awk -v h="$hausdorff" 'BEGIN { exit !(h < 0.01) }'
"$LODKIT" lod -q --meshopt --levels=2 "$cow" "$TMP/cow-lod-m.glb"
check "MSFT_lod with meshopt reads back" grep -q '"triangles":5804' <<<"$("$LODKIT" info --json "$TMP/cow-lod-m.glb")"
expect_exit 2 "$LODKIT" convert --meshopt "$cow" "$TMP/cow-m.obj"
err=$("$LODKIT" convert --meshopt "$cow" "$TMP/cow-m.obj" 2>&1)
check "--meshopt needs glTF output ($err)" grep -q "are for glTF output" <<<"$err"

# refusals: exit 2 for the command line, 1 for the input; nothing written
expect_exit 2 "$LODKIT" lod "$cow" "$TMP/one.obj"
check "OBJ without --separate: nothing written" test ! -e "$TMP/one.obj"
expect_exit 2 "$LODKIT" lod --ratio=1 "$cow" "$TMP/r.glb"
expect_exit 2 "$LODKIT" lod --levels=0 "$cow" "$TMP/l.glb"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\n' > "$TMP/points.obj"
expect_exit 1 "$LODKIT" lod "$TMP/points.obj" "$TMP/p.glb"
err=$("$LODKIT" lod "$TMP/points.obj" "$TMP/p.glb" 2>&1)
check "point set refused ($err)" grep -q "levels of detail need triangles" <<<"$err"
check "point set: nothing written" test ! -e "$TMP/p.glb"
finish
