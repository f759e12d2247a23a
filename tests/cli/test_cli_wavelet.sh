#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `lodkit simplify --method wavelet` and `lodkit slices` on real models:
# closed manifold output, targets, options, drawings, and clear refusals.
set -u
source "$(dirname "$0")/lib.sh"
cow="$LK_SAMPLES_DIR/cow.off"
tri="$LK_SAMPLES_DIR/triceratops.off"
num() { grep -o "\"$1\":[-0-9.e+]*" | head -1 | cut -d: -f2; }
within() { awk -v v="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(v >= lo && v <= hi) }'; }

expect_output_contains "wavelet" "$LODKIT" simplify --help
expect_output_contains "--slices" "$LODKIT" simplify --help
expect_output_contains "--axis" "$LODKIT" simplify --help
expect_exit 2 "$LODKIT" simplify --method=wavelet --slices=1 --ratio=0.2 "$cow" "$TMP/o.obj"
expect_exit 2 "$LODKIT" simplify --method=wavelet --slices=many --ratio=0.2 "$cow" "$TMP/o.obj"
expect_exit 2 "$LODKIT" simplify --method=wavelet --axis=w --ratio=0.2 "$cow" "$TMP/o.obj"

# vertex target, closed 2-manifold, measured
json=$("$LODKIT" simplify --json --measure --method=wavelet --vertices=580 "$cow" "$TMP/cow-w.ply")
check "method reported" grep -q '"method":"wavelet"' <<<"$json"
v=$(grep -o '"vertices":[0-9]*' <<<"$json" | tail -1 | cut -d: -f2)
check "about 580 vertices ($v)" within "$v" 550 580
check "target reached" grep -q '"target_reached":true' <<<"$json"
check "metro reported" grep -q '"hausdorff_percent"' <<<"$json"
info=$("$LODKIT" info --json "$TMP/cow-w.ply")
check "closed" grep -q '"boundary_edges":0' <<<"$info"
check "no non-manifold edges" grep -q '"nonmanifold_edges":0' <<<"$info"
check "no non-manifold vertices" grep -q '"nonmanifold_vertices":0' <<<"$info"

# contour criterion: the paper's energy (default) or the max-norm distance
expect_output_contains "--criterion" "$LODKIT" simplify --help
expect_exit 2 "$LODKIT" simplify --method=wavelet --criterion=size --vertices=580 "$cow" "$TMP/o.obj"
for criterion in energy distance; do
  json=$("$LODKIT" simplify --json --method=wavelet --criterion=$criterion --vertices=580 "$cow" "$TMP/cow-$criterion.ply")
  v=$(grep -o '"vertices":[0-9]*' <<<"$json" | tail -1 | cut -d: -f2)
  check "$criterion: about 580 vertices ($v)" within "$v" 550 580
  info=$("$LODKIT" info --json "$TMP/cow-$criterion.ply")
  check "$criterion: closed manifold" \
    test "$(grep -o '"\(boundary_edges\|nonmanifold_edges\|nonmanifold_vertices\|duplicate_triangles\)":0' <<<"$info" | wc -l)" -eq 4
done
check "energy is the default" cmp -s "$TMP/cow-w.ply" "$TMP/cow-energy.ply"
check "the criteria differ" bash -c "! cmp -s \"\$1\" \"\$2\"" _ "$TMP/cow-energy.ply" "$TMP/cow-distance.ply"

# every axis and a few slice counts stay closed (fandisk has sharp, axis-aligned features)
for axis in x y z auto; do
  for slices in 5 33 150; do
    "$LODKIT" simplify -q --method=wavelet --axis=$axis --slices=$slices --ratio=0.2 \
      "$LK_SAMPLES_DIR/fandisk.off" "$TMP/fan.off" || echo "FAIL: fandisk axis $axis slices $slices"
    info=$("$LODKIT" info --json "$TMP/fan.off")
    check "fandisk $axis/$slices closed manifold" \
      test "$(grep -o '"\(boundary_edges\|nonmanifold_edges\|nonmanifold_vertices\|duplicate_triangles\)":0' <<<"$info" | wc -l)" -eq 4
  done
done

# error target: the in-plane bound plus the sampling error
json=$("$LODKIT" simplify --json --method=wavelet --slices=150 --max-error=1 "$tri" "$TMP/tri.obj")
check "error within sqrt(1^2 + sampling^2) ($(num error_percent <<<"$json"))" within "$(num error_percent <<<"$json")" 0 1.01

# a connected model stays connected, on every axis (issue 24: the cow came
# back in up to 8 parts), and the summary line says so
for axis in x y z; do
  json=$("$LODKIT" simplify --json --method=wavelet --ratio=0.1 --axis=$axis "$cow" "$TMP/cow-$axis.obj")
  check "cow along $axis: 1 component in, 1 out" grep -q '"input_components":1,.*"components":1,' <<<"$json"
done
expect_output_contains "1 component -> $TMP/cow-s.obj: " "$LODKIT" simplify --method=wavelet --ratio=0.1 "$cow" "$TMP/cow-s.obj"
# a model missing a few triangles is closed first, and the summary says so
dragon="$LK_SAMPLES_DIR/ChineseDragon-10kv.off"
out=$("$LODKIT" simplify --method=wavelet --ratio=0.1 "$dragon" "$TMP/dragon.obj")
check "dragon: holes closed and said ($out)" grep -q "the input's 2 holes (6 boundary edges) were closed first" <<<"$out"
check "dragon: one closed component" grep -q '"components":1,.*"boundary_edges":0' <<<"$("$LODKIT" info --json "$TMP/dragon.obj")"

# open sheets (most edges on a boundary) are refused with a clear message
# and no output
printf 'v 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 3\n' > "$TMP/open.obj"
expect_exit 1 "$LODKIT" simplify --method=wavelet --ratio=0.5 "$TMP/open.obj" "$TMP/open-out.obj"
err=$("$LODKIT" simplify --method=wavelet --ratio=0.5 "$TMP/open.obj" "$TMP/open-out.obj" 2>&1)
check "open mesh refused ($err)" grep -q "closed surface" <<<"$err"
check "no output for refused input" test ! -e "$TMP/open-out.obj"

# slices drawings
expect_exit 0 "$LODKIT" slices --help
expect_exit 2 "$LODKIT" slices "$cow" "$TMP/s.jpg"
expect_exit 2 "$LODKIT" slices --count=0 "$cow" "$TMP/s.svg"
expect_exit 0 "$LODKIT" slices -q --count=3 "$tri" "$TMP/s.svg"
check "svg written" grep -q '<svg' "$TMP/s.svg"
check "svg has 3 panels" test "$(grep -c '<text' "$TMP/s.svg")" -eq 3
check "svg has simplified contours" grep -q '#1e50c8' "$TMP/s.svg"
expect_output_contains "contour points" "$LODKIT" slices --slices=40 --ratio=0.2 "$cow" "$TMP/s.png"
check "png written" test "$(head -c 4 "$TMP/s.png" | od -An -c | tr -d ' ')" = '211PNG'
expect_exit 1 "$LODKIT" slices "$TMP/open.obj" "$TMP/open.svg"
finish
