#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Run the reader fuzz targets: fuzz/run.sh BUILD_DIR [FORMAT...]
# FUZZ_SECONDS (default 300) per target. Seeds: fuzz/corpus/<format>/ plus the
# sample and test files of that format; new inputs go to BUILD_DIR/fuzz-work,
# never into the repository. A crash leaves its input in BUILD_DIR/fuzz-work/
# and fails the run. Every run first replays all of fuzz/corpus/<format>/ (the
# minimised corpora of the campaigns and every past finding), so the CTest
# smoke runs are also the regression replay.
#
#   fuzz/run.sh --merge BUILD_DIR FORMAT...   minimise BUILD_DIR/fuzz-work/<format>/corpus
#       together with fuzz/corpus/<format>/ into fuzz/corpus/<format>/ (libFuzzer -merge=1;
#       inputs over 64 KiB are left out so the committed corpora stay small).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
merge=0; [ "${1:-}" = --merge ] && { merge=1; shift; }
build="$(cd "$1" && pwd)"; shift
formats=("$@")
[ ${#formats[@]} -gt 0 ] || formats=(obj ply off smf xyz stl gltf gltfscene objscene pcd las stream dem kmf md2 gltfanim asf amc wgt http octree pointstream)

if [ "$merge" = 1 ]; then
  for format in "${formats[@]}"; do
    target="$build/fuzz/fuzz_$format"
    work="$build/fuzz-work/$format"
    fresh="$work/merged"; rm -rf "$fresh"; mkdir -p "$fresh" "$here/corpus/$format"
    "$target" -merge=1 -max_len=65536 -timeout=10 -rss_limit_mb=2048 "$fresh" "$here/corpus/$format" "$work/corpus" \
      >"$work/merge-log.txt" 2>&1 || { echo "fuzz: merge of $format failed; see $work/merge-log.txt" >&2; exit 1; }
    # Keep the named regression inputs; replace the rest by the minimised set.
    find "$here/corpus/$format" -type f ! -name 'regression-*' ! -name 'seed-*' -delete
    for f in "$fresh"/*; do
      [ -f "$f" ] || continue
      name="$(basename "$f")"
      [ -e "$here/corpus/$format/regression-$name" ] || cp "$f" "$here/corpus/$format/$name"
    done
    echo "fuzz: $format corpus $(ls "$here/corpus/$format" | wc -l) files, $(du -sk "$here/corpus/$format" | cut -f1) KiB"
  done
  exit 0
fi
seconds="${FUZZ_SECONDS:-300}"
# FUZZ_RUNS=N runs exactly N executions per target instead (a campaign).
runs="${FUZZ_RUNS:-}"
limit=(-max_total_time="$seconds"); [ -n "$runs" ] && limit=(-runs="$runs")
samples="${LK_SAMPLES_DIR:-$root/data/samples}"

for format in "${formats[@]}"; do
  target="$build/fuzz/fuzz_$format"
  [ -x "$target" ] || { echo "fuzz: $target not built (configure with -DLODKIT_FUZZ=ON)" >&2; exit 1; }
  work="$build/fuzz-work/$format"
  rm -rf "$work/seeds"; mkdir -p "$work/seeds" "$work/corpus" "$work/artifacts"
  # Seeds: committed corpus + small real files of this format (< 64 KiB).
  [ -d "$here/corpus/$format" ] && cp "$here/corpus/$format"/* "$work/seeds/" 2>/dev/null || true
  exts="$format"; [ "$format" = gltf ] && exts="gltf glb"; [ "$format" = dem ] && exts="pgm png npz"
  [ "$format" = gltfanim ] && exts="gltf glb"
  if [ "$format" = objscene ]; then
    # every .obj that names an .mtl, also with that .mtl after a "#mtl" line
    exts="obj"
    cp "$here/corpus/obj"/* "$work/seeds/" 2>/dev/null || true
    for mtl in "$samples"/assimp/OBJ/*.mtl; do
      obj="${mtl%.mtl}.obj"
      [ -f "$obj" ] && { cat "$obj"; printf '\n#mtl\n'; cat "$mtl"; } >"$work/seeds/with-mtl-$(basename "$obj")"
    done
  fi
  if [ "$format" = pointstream ]; then
    # the kind's byte (0 xyz, 1 ply, 2 las, 3 pcd), then a sample of that kind
    exts=""
    kind=0
    for ext in xyz ply las pcd; do
      find "$samples" "$root/tests/data" -type f -iname "*.$ext" -size -64k 2>/dev/null | head -20 |
        while read -r f; do
          { printf "\\$(printf %03o "$kind")"; cat "$f"; } >"$work/seeds/$ext-$(echo "$f" | md5sum | cut -c1-12)"
        done
      kind=$((kind + 1))
    done
  fi
  if [ "$format" = gltfscene ]; then
    exts="gltf glb"
    cp "$here/corpus/gltf"/* "$work/seeds/" 2>/dev/null || true
  fi
  for ext in $exts; do
    find "$samples" "$root/tests/data" -type f -iname "*.$ext" -size -64k 2>/dev/null | head -50 |
      while read -r f; do cp "$f" "$work/seeds/$(echo "$f" | md5sum | cut -c1-12).$ext"; done
  done
  echo "fuzz: $format for ${runs:-${seconds}s} ${runs:+executions} ($(ls "$work/seeds" | wc -l) seeds)"
  # -rss_limit_mb bounds memory; -timeout catches hangs (seconds per input).
  "$target" "$work/corpus" "$work/seeds" "${limit[@]}" -timeout=10 -rss_limit_mb=2048 \
    -max_len=65536 -artifact_prefix="$work/artifacts/" -print_final_stats=1 >"$work/log.txt" 2>&1 || {
      echo "fuzz: $format FAILED; input and log in $work" >&2; tail -40 "$work/log.txt" >&2; exit 1; }
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$work/log.txt" | sed "s/^/fuzz: $format /"
done
