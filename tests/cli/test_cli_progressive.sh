#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `lodkit progressive`, `unpack` and `inspect` on the cow and the bunny:
# round trip to the full mesh, levels, partial downloads, a corrupt chunk,
# usage errors.
set -u
source "$(dirname "$0")/lib.sh"
cow="$LK_SAMPLES_DIR/cow.off"
bunny="$LK_SAMPLES_DIR/bunny.obj"
num() { grep -o "\"$1\":[-0-9.e+]*" | head -1 | cut -d: -f2; }
within() { awk -v v="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(v >= lo && v <= hi) }'; }

for command in progressive unpack inspect; do
  expect_exit 0 "$LODKIT" $command --help
done
expect_output_contains "--base-ratio" "$LODKIT" progressive --help
expect_exit 2 "$LODKIT" progressive "$cow"                                   # no output
expect_exit 2 "$LODKIT" progressive --base-ratio=0 "$cow" "$TMP/x.lks"
expect_exit 2 "$LODKIT" progressive --bits=40 "$cow" "$TMP/x.lks"
expect_exit 2 "$LODKIT" progressive --stripifier=magic "$cow" "$TMP/x.lks"
expect_exit 2 "$LODKIT" unpack --level=3 --ratio=0.5 "$TMP/x.lks" "$TMP/x.obj"
expect_exit 1 "$LODKIT" progressive "$LK_SAMPLES_DIR/kitten.xyz" "$TMP/kitten.lks"
check "no stream for a point set" test ! -e "$TMP/kitten.lks"

# cow, stream version 1: paper-sized base mesh, E-PS and DTFS figures, round trip
json=$("$LODKIT" progressive --json --stream-version=1 --chunk-splits=256 "$cow" "$TMP/cow.lks")
check "cow base triangles ($(num base_triangles <<<"$json"))" within "$(num base_triangles <<<"$json")" 280 291
check "cow E-PS updates <= 3.2 ($(num encoded_updates_per_split <<<"$json"))" \
  within "$(num encoded_updates_per_split <<<"$json")" 1 3.2
check "cow naive updates > E-PS" awk -v a="$(num naive_updates_per_split <<<"$json")" \
  -v b="$(num encoded_updates_per_split <<<"$json")" 'BEGIN { exit !(a > b) }'
check "cow DTFS >= 40% less than PM ($(num dtfs_reduction_vs_pm <<<"$json"))" \
  within "$(num dtfs_reduction_vs_pm <<<"$json")" 0.40 1
chunks=$(num chunks <<<"$json")
check "cow chunks ($chunks)" within "$chunks" 11 13
expect_output_contains "all $chunks chunks present, CRCs match" "$LODKIT" inspect "$TMP/cow.lks"
"$LODKIT" unpack -q "$TMP/cow.lks" "$TMP/cow-full.ply"
out=$("$LODKIT" info --json "$TMP/cow-full.ply")
check "full level has every cow triangle" grep -q '"triangles":5804' <<<"$out"
check "full level closed genus 0" grep -q '"boundary_edges":0.*"genus":0' <<<"$out"
metro=$("$LODKIT" metro --json "$cow" "$TMP/cow-full.ply")
check "full level within the quantisation bound ($(num hausdorff_percent <<<"$metro"))" \
  within "$(num hausdorff_percent <<<"$metro")" 0 0.01
json=$("$LODKIT" unpack --json --ratio=0.5 "$TMP/cow.lks" "$TMP/cow-half.obj")
check "ratio 0.5 gives half the vertices ($(num vertices <<<"$json"))" within "$(num vertices <<<"$json")" 1450 1454
json=$("$LODKIT" unpack --json --level=0 "$TMP/cow.lks" "$TMP/cow-base.obj")
check "level 0 is the base mesh" within "$(num triangles <<<"$json")" 280 291

# a download that stopped: every complete chunk is used, a note says where
size=$(stat -c %s "$TMP/cow.lks")
json=$("$LODKIT" unpack --json --bytes=$((size / 2)) "$TMP/cow.lks" "$TMP/cow-part.obj")
check "partial download decodes a middle level" within "$(num level <<<"$json")" 1 2756
check "partial download says where it stopped" grep -q 'stopped at byte' <<<"$json"
# a file cut short: same mesh written, exit 1 with the place
head -c $((size - 100)) "$TMP/cow.lks" > "$TMP/cow-cut.lks"
expect_exit 1 "$LODKIT" unpack "$TMP/cow-cut.lks" "$TMP/cow-cut.obj"
expect_output_contains "stopped at byte" "$LODKIT" unpack "$TMP/cow-cut.lks" "$TMP/cow-cut.obj"
check "cut stream still gives a mesh" test -s "$TMP/cow-cut.obj"
expect_exit 1 "$LODKIT" inspect "$TMP/cow-cut.lks"
# a corrupt chunk: named, earlier levels written
cp "$TMP/cow.lks" "$TMP/cow-bad.lks"
offset=$("$LODKIT" inspect --json "$TMP/cow.lks" | grep -o '"offset":[0-9]*' | sed -n 4p | cut -d: -f2)
printf '\xff\xff\xff\xff' | dd of="$TMP/cow-bad.lks" bs=1 seek=$((offset + 40)) conv=notrunc status=none
expect_output_contains "chunk 3" "$LODKIT" unpack "$TMP/cow-bad.lks" "$TMP/cow-bad.obj"
expect_exit 1 "$LODKIT" unpack "$TMP/cow-bad.lks" "$TMP/cow-bad.obj"
expect_output_contains "chunk 3" "$LODKIT" inspect "$TMP/cow-bad.lks"
# not a stream at all
expect_exit 1 "$LODKIT" inspect "$cow"
expect_exit 1 "$LODKIT" unpack "$cow" "$TMP/nothing.obj"
check "no output from a non-stream" test ! -e "$TMP/nothing.obj"

# version 2: range-coded splits, one position per split, a 200-triangle base
json=$("$LODKIT" progressive --json --stream-version 2 --bits 11 "$cow" "$TMP/cow2.lks")
check "v2 cow under 40 bits/vertex ($(num bits_per_vertex <<<"$json"))" within "$(num bits_per_vertex <<<"$json")" 20 40
check "v2 base of about 200 triangles" within "$(num base_triangles <<<"$json")" 190 200
check "v2 says what it drops" grep -q '"dropped_attributes"' <<<"$json"
expect_output_contains "version 2" "$LODKIT" inspect "$TMP/cow2.lks"
expect_output_contains "bits/vertex split vertices" "$LODKIT" inspect "$TMP/cow2.lks"
json=$("$LODKIT" inspect --json "$TMP/cow2.lks")
check "v2 inspect: positions take most bits ($(num positions <<<"$json"))" within "$(num positions <<<"$json")" 15 30
"$LODKIT" unpack -q "$TMP/cow2.lks" "$TMP/cow2-full.ply"
metro=$("$LODKIT" metro --json "$cow" "$TMP/cow2-full.ply")
check "v2 full level within the 11-bit bound ($(num hausdorff_percent <<<"$metro"))" \
  within "$(num hausdorff_percent <<<"$metro")" 0 0.025
json=$("$LODKIT" unpack --json --ratio=0.5 "$TMP/cow2.lks" "$TMP/cow2-half.obj")
check "v2 ratio 0.5 gives half the vertices ($(num vertices <<<"$json"))" within "$(num vertices <<<"$json")" 1450 1454
size=$(stat -c %s "$TMP/cow2.lks")
head -c $((size - 100)) "$TMP/cow2.lks" > "$TMP/cow2-cut.lks"
expect_exit 1 "$LODKIT" unpack "$TMP/cow2-cut.lks" "$TMP/cow2-cut.obj"
check "cut v2 stream still gives a mesh" test -s "$TMP/cow2-cut.obj"
expect_exit 2 "$LODKIT" progressive --stream-version 3 "$cow" "$TMP/cow3.lks"
# version 2 carries normals and texture coordinates (assimp's spider); version 1 says it drops them
spider="$LK_SAMPLES_DIR/assimp/OBJ/spider.obj"
json=$("$LODKIT" progressive --json --stream-version 2 "$spider" "$TMP/spider2.lks")
check "v2 carries the spider's normals and texture coordinates" grep -q '"carried_attributes":"normals, texture coordinates"' <<<"$json"
"$LODKIT" unpack -q "$TMP/spider2.lks" "$TMP/spider2.obj"
check "unpacked spider has both" grep -q 'normals texcoords' <<<"$("$LODKIT" info "$TMP/spider2.obj")"
out=$("$LODKIT" inspect "$TMP/spider2.lks")
check "inspect gives the bits of normals and texture coordinates ($out)" grep -q 'normals [0-9.]*, texcoords [0-9.]*,' <<<"$out"
check "and no colours" test "$(grep -c colours <<<"$out")" -eq 0
json=$("$LODKIT" progressive --json --stream-version=1 "$spider" "$TMP/spider1.lks")
check "v1 says it drops them" grep -q '"dropped_attributes":"normals, texture coordinates"' <<<"$json"

# bunny, version 1: the paper's second model, with a bandwidth CSV
json=$("$LODKIT" progressive --json --stream-version=1 --bandwidth-levels=64 --bandwidth="$TMP/bunny.csv" "$bunny" "$TMP/bunny.lks")
check "bunny E-PS updates <= 3.2 ($(num encoded_updates_per_split <<<"$json"))" \
  within "$(num encoded_updates_per_split <<<"$json")" 1 3.2
check "bunny DTFS >= 40% less than PM ($(num dtfs_reduction_vs_pm <<<"$json"))" \
  within "$(num dtfs_reduction_vs_pm <<<"$json")" 0.40 1
check "bandwidth CSV has 64 levels" test "$(wc -l < "$TMP/bunny.csv")" -eq 65
"$LODKIT" unpack -q "$TMP/bunny.lks" "$TMP/bunny-full.ply"
check "full bunny" grep -q '"triangles":69666' <<<"$("$LODKIT" info --json "$TMP/bunny-full.ply")"

# the default is version 2 (issue 19): the bunny's first frame within the first 2% of the stream
json=$("$LODKIT" progressive --json "$bunny" "$TMP/bunny-default.lks")
check "default stream version 2" test "$(num stream_version <<<"$json")" = 2
first=$(num first_frame_bytes <<<"$json") bytes=$(num bytes <<<"$json")
check "bunny's first frame in the first 2% ($first of $bytes bytes)" awk -v f="$first" -v b="$bytes" 'BEGIN { exit !(f > 0 && f <= 0.02 * b) }'
check "default bunny stream under 40 bits/vertex ($(num bits_per_vertex <<<"$json"))" within "$(num bits_per_vertex <<<"$json")" 20 40
"$LODKIT" unpack -q "$TMP/bunny-default.lks" "$TMP/bunny-default.ply"
check "default stream: full bunny" grep -q '"triangles":69666' <<<"$("$LODKIT" info --json "$TMP/bunny-default.ply")"
# version-1-only options on a version-2 stream: refused, saying how
for option in --stripifier=lodkit --no-compress --bandwidth-levels=4 --bandwidth="$TMP/x.csv"; do
  expect_exit 2 "$LODKIT" progressive "$option" "$cow" "$TMP/x.lks"
  expect_output_contains "add --stream-version=1" "$LODKIT" progressive "$option" "$cow" "$TMP/x.lks"
done
expect_exit 0 "$LODKIT" progressive -q --stream-version=1 --no-compress "$cow" "$TMP/x.lks"
finish
