#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Prints a SHA-256 for every output of simplify (each method), progressive,
# unpack, animate, terrain and render on the sample models: run it before and
# after a change that must not change behaviour (a refactor) and diff the two
# lists. Timings are left out (terrain's CSV: the update_ms column).
# Usage: scripts/output-hashes.sh [LODKIT] > hashes.txt
set -euo pipefail
lodkit="$(realpath "${1:-build/lodkit}")"
samples="$(cd "$(dirname "$0")/.." && pwd)/data/samples"
out="$(mktemp -d /tmp/lodkit-hashes.XXXXXX)"
trap 'rm -rf "$out"' EXIT
run() { "$lodkit" "$@" >/dev/null 2>&1 || echo "exit $?: ${*//$out/OUT}"; }

for model in cow.off bunny.obj fandisk.off triceratops.off ChineseDragon-10kv.off; do
  stem=${model%.*}
  for method in qem uniform floating wavelet; do
    run simplify -q -m "$method" -r 0.1 "$samples/$model" "$out/$stem-$method.obj"
  done
  run simplify -q --attributes -r 0.25 "$samples/$model" "$out/$stem-attr.ply"
  run progressive -q "$samples/$model" "$out/$stem.lks"
  run unpack -q --ratio 0.3 "$out/$stem.lks" "$out/$stem-unpack30.off"
  run unpack -q "$out/$stem.lks" "$out/$stem-unpack.obj"
  run render "$samples/$model" -o "$out/$stem.png" --size 256x256
done
run progressive -q --base-ratio=0.02 --placement endpoint --bits 11 "$samples/bunny.obj" "$out/bunny-b2.lks"
run animate -q --scheme=all --levels=3 --metro-step=20 "$samples/faerie.md2" "$out/faerie"
run animate -q --ratio 0.3 --no-metro "$samples/assimp/glTF2/simple_skin/simple_skin.gltf" "$out/skin" || true
run terrain -q --flight=40 --csv "$out/jacksboro.csv" --png "$out/jacksboro-png" "$samples/jacksboro_fault_dem.npz"
run terrain -q --flight=20 --grid-size=257 --csv "$out/etopo.csv" "$samples/etopo20.cdf"
for csv in "$out"/*.csv; do  # drop timing columns
  awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i ~ /_ms$|seconds/) skip[i] = 1 }
           { line = ""; for (i = 1; i <= NF; i++) if (!skip[i]) line = line $i ","; print line }' "$csv" >"$csv.t"
  mv "$csv.t" "$csv"
done
cd "$out" && find . -type f ! -name '.*' | LC_ALL=C sort | xargs sha256sum
