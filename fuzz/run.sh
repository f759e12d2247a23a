#!/usr/bin/env bash
# Run the reader fuzz targets: fuzz/run.sh BUILD_DIR [FORMAT...]
# FUZZ_SECONDS (default 300) per target. Seeds: fuzz/corpus/<format>/ plus the
# sample and test files of that format; new inputs go to BUILD_DIR/fuzz-work,
# never into the repository. A crash leaves its input in BUILD_DIR/fuzz-work/
# and fails the run.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
build="$(cd "$1" && pwd)"; shift
formats=("$@")
[ ${#formats[@]} -gt 0 ] || formats=(obj ply off smf xyz stl gltf stream dem kmf md2 gltfanim asf amc wgt)
seconds="${FUZZ_SECONDS:-300}"
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
  for ext in $exts; do
    find "$samples" "$root/tests/data" -type f -iname "*.$ext" -size -64k 2>/dev/null | head -50 |
      while read -r f; do cp "$f" "$work/seeds/$(echo "$f" | md5sum | cut -c1-12).$ext"; done
  done
  echo "fuzz: $format for ${seconds}s ($(ls "$work/seeds" | wc -l) seeds)"
  # -rss_limit_mb bounds memory; -timeout catches hangs (seconds per input).
  "$target" "$work/corpus" "$work/seeds" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -max_len=65536 -artifact_prefix="$work/artifacts/" -print_final_stats=1 >"$work/log.txt" 2>&1 || {
      echo "fuzz: $format FAILED; input and log in $work" >&2; tail -40 "$work/log.txt" >&2; exit 1; }
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$work/log.txt" | sed "s/^/fuzz: $format /"
done
