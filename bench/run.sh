#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `make bench`: lodkit's benchmarks, side by side with the peers, in one run.
# The run is printed as Markdown and, once every part has finished, written
# into docs/benchmarks.md between its "bench-run" markers with the date and
# the machine (the previous run there is replaced; the rest of the file is
# written by hand and kept).
#
# Usage: bench/run.sh BUILD_DIR [--docs FILE] [PART...]   (after scripts/install-deps.sh --bench)
#   PART: metro simplify agreement wavelet anim progressive splat octree terrain gltf io
#         scale; none: all of them but scale (minutes, about 0.9 GB of temporary
#         PLY in /tmp and up to 4 GB of memory: run it by name).
#   --docs FILE: write the run into FILE instead. A run of only some parts
#         writes nothing unless --docs is given, so a quick check never
#         replaces the full run in docs/benchmarks.md.
set -euo pipefail
build="$(cd "${1:-build}" && pwd)"
shift || true
root="$(cd "$(dirname "$0")/.." && pwd)"
docs="" parts=()
while [ $# -gt 0 ]; do
  case "$1" in
    --docs) docs="$2"; shift 2 ;;
    --docs=*) docs="${1#--docs=}"; shift ;;
    metro|simplify|agreement|wavelet|anim|progressive|splat|octree|terrain|gltf|io|scale) parts+=("$1"); shift ;;
    *) echo "bench/run.sh: unknown part '$1' (metro simplify agreement wavelet anim progressive splat octree terrain gltf io scale)" >&2
       exit 2 ;;
  esac
done
[ -z "$docs" ] && [ ${#parts[@]} -eq 0 ] && docs="$root/docs/benchmarks.md"
samples="$root/data/samples"
out="$root/bench/out"
mkdir -p "$out"
lodkit="$build/lodkit"
python=/usr/bin/python3   # Debian's python, which has open3d and numpy

want() {  # want PART: is PART part of this run? (scale only when named)
  [ ${#parts[@]} -eq 0 ] && [ "$1" != scale ] && return 0
  local part
  for part in "${parts[@]}"; do [ "$part" = "$1" ] && return 0; done
  return 1
}

# serve DIR LOG: starts `lodkit serve DIR` on a free port in the background;
# sets served_pid and served_url (empty if it did not start within 10 s).
serve() {
  "$lodkit" serve "$1" --port 0 >"$2" 2>/dev/null &
  served_pid=$! served_url=""
  for _ in $(seq 100); do
    served_url=$(grep -o 'http://[^ ]*' "$2" 2>/dev/null | head -1) || true # (no line yet: grep fails, pipefail)
    [ -n "$served_url" ] && break
    sleep 0.1
  done
}

machine() {
  local cpu os
  cpu="$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')"
  os="$(. /etc/os-release 2>/dev/null && echo "$PRETTY_NAME")"
  echo "$(nproc) cores ($cpu), $(free -g | awk '/^Mem:/ {print $2}') GiB RAM, ${os:-$(uname -s)}, kernel $(uname -r)"
}

run_benchmarks() {
  local commit
  commit="$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "## The latest run: $(date -u +%Y-%m-%d)"
  echo
  echo "Machine: $(machine). $("$lodkit" --version), commit $commit, release build."
  [ ${#parts[@]} -gt 0 ] && echo "Parts run: ${parts[*]}."
  echo
  if want metro; then
    echo "### Metro surface distance: speed (forward + backward samples per second, index builds included)"
    echo
    echo '```'
    "$build/bench_metro" "$samples"
    echo '```'
    echo
  fi
  if want simplify; then
    echo "### Simplification: lodkit vs meshoptimizer 0.18 and Open3D 0.16, one thread"
    echo
    "$build/bench_simplify" --samples "$samples" --out "$out" --script "$root/bench/simplify_open3d.py"
    echo
  fi
  if want agreement; then
    echo "### Metro agreement with independent tools"
    echo
    echo "Open3D (RaycastingScene, exact distances; uniform random face samples, same"
    echo "count as lodkit) and MeshLab's Hausdorff Distance filter (Metro's vertex +"
    echo "edge + face sampling, same count; its RMS from a face-only run). Each cell:"
    echo "lodkit % of diagonal, peer % of diagonal, relative difference."
    echo
    echo "| pair, peer | forward max | forward rms | backward max | backward rms | worst |"
    echo "|---|---|---|---|---|---|"
    local pairs=() pair label a b extra counts have_meshlab=0
    "$build/bench_metro" --write-perturbed "$out/bunny-perturbed.obj" "$samples" >/dev/null
    pairs+=("bunny vs perturbed bunny|$samples/bunny.obj|$out/bunny-perturbed.obj|")
    pairs+=("same, 10M face samples|$samples/bunny.obj|$out/bunny-perturbed.obj|--samples=10000000")
    for method in qem uniform; do
      if "$lodkit" simplify --quiet --method=$method --ratio=0.1 "$samples/bunny.obj" "$out/bunny-$method-10.obj" 2>/dev/null; then
        pairs+=("bunny vs $method 10%|$samples/bunny.obj|$out/bunny-$method-10.obj|")
      fi
    done
    [ -f "$out/bunny-qem-10.obj" ] &&
      pairs+=("same, 10M face samples|$samples/bunny.obj|$out/bunny-qem-10.obj|--samples=10000000")
    command -v meshlabserver >/dev/null && command -v xvfb-run >/dev/null && have_meshlab=1
    for pair in "${pairs[@]}"; do
      IFS='|' read -r label a b extra <<<"$pair"
      "$lodkit" metro --json --quiet $extra "$a" "$b" > "$out/ours.json"
      counts=$(grep -o '"samples":[0-9]*' "$out/ours.json" | head -2 | cut -d: -f2 | tr '\n' ' ')
      set -- $counts
      "$python" "$root/bench/metro_open3d.py" "$a" "$b" --samples-a "$1" --samples-b "$2" > "$out/open3d.json"
      "$python" "$root/bench/compare_metro.py" "$label, Open3D" "$out/ours.json" "$out/open3d.json"
      if [ $have_meshlab = 1 ] && [ -z "$extra" ]; then  # MeshLab takes minutes at 10M samples
        LODKIT="$lodkit" bash "$root/bench/metro_meshlab.sh" "$a" "$b" $counts > "$out/meshlab.json"
        "$python" "$root/bench/compare_metro.py" "$label, MeshLab" "$out/ours.json" "$out/meshlab.json"
      fi
    done
    echo
    echo "Maxima depend on where the samples fall: at 10 samples per face they differ by"
    echo "a few percent between tools; with dense sampling they converge."
    echo
  fi
  if want wavelet; then
    echo "### Wavelet simplification by planar sampling vs vertex clustering (paper Table 4)"
    echo
    "$build/bench_wavelet" "$samples" | sed 's/^### /#### /'
    echo
  fi
  if want anim; then
    echo "### Animated models: max / avg / one-frame multi-frame QEM, Metro per level and frame (paper Fig. 8)"
    echo
    "$build/bench_anim" --out "$out" "$samples" | sed 's/^### /#### /'
    echo "CSV and heat maps (level x frame -> RMS): bench/out/anim_<model>_<scheme>.csv, _rms.png"
    echo
  fi
  if want progressive; then
    echo "### Progressive meshes, progressive strips and the .lks stream"
    echo
    "$build/bench_progressive" --samples "$samples" --out "$out" | sed 's/^### /#### /'
    if command -v gnuplot >/dev/null; then
      for model in cow bunny; do
        [ -f "$out/bandwidth-$model.csv" ] || continue
        gnuplot <<PLOT
set terminal pngcairo size 900,520 noenhanced
set output "$out/bandwidth-$model.png"
set datafile separator ","
set key top left
set title "$model: indices sent to the GPU per level (paper Fig. 4)"
set xlabel "vertex splits applied"
set ylabel "indices"
set grid
plot "$out/bandwidth-$model.csv" using 1:3 with lines lw 2 title "PM (3 per triangle)", \
     "" using 1:4 with lines lw 2 title "progressive strips, unfiltered", \
     "" using 1:5 with lines lw 2 title "progressive strips, DTFS-filtered"
PLOT
        echo
        echo "Plot: bench/out/bandwidth-$model.png"
      done
      for model in cow bunny fandisk; do
        [ -f "$out/rd-$model.csv" ] || continue
        gnuplot <<PLOT
set terminal pngcairo size 900,520 noenhanced
set output "$out/rd-$model.png"
set datafile separator ","
set key top right
set title "$model: distance from the full mesh against bytes received (11 bits)"
set xlabel "bytes received"
set ylabel "Hausdorff distance, % of the diagonal"
set logscale y
set grid
plot "< grep '^stream' $out/rd-$model.csv" using 2:4 with linespoints lw 2 title ".lks version 2, prefix of whole chunks", \
     "< grep '^chain' $out/rd-$model.csv" using 2:4 with linespoints lw 2 title "discrete LOD chain, Draco -cl 10, level completed"
PLOT
        echo
        echo "Plot: bench/out/rd-$model.png"
      done
    fi
    echo
    echo "### The bunny's .lks (version 2) in the viewer: headless Chromium, decoded in a Web Worker"
    echo
    mkdir -p "$out/stream_browser"
    "$lodkit" progressive -q "$samples/bunny.obj" "$out/stream_browser/bunny.lks"
    serve "$out/stream_browser" "$out/stream_browser.serve.out"
    node "$root/bench/stream_browser.mjs" "$served_url" bunny.lks || echo "(the browser bench failed)"
    kill -TERM "$served_pid"; wait "$served_pid" || true
    echo
  fi
  if want splat; then
    echo "### Point splatting on OpenGL ES 2.0 (Mesa llvmpipe, no GPU): memory and frame time"
    echo
    "$build/bench_splat" --out "$out" "$samples" | sed 's/^### /#### /'
    echo
    echo "### Splat radii on the samples: outliers and silhouette coverage"
    echo
    # the sample scans against surfaces made from their points (Open3D, SciPy)
    mkdir -p "$out/scan_references"
    "$build/lodkit" convert -q "$samples/las/Haystack_Rock.las" "$out/scan_references/Haystack_Rock.xyz"
    if "$python" "$root/bench/reconstruct_scans.py" "$samples" "$out/scan_references" >&2; then
      "$build/bench_radii" --scans "$out/scan_references" "$samples"
    else
      "$build/bench_radii" "$samples"
    fi
    echo
  fi
  if want octree; then
    echo "### Point octree build (lodkit octree): 1M and 10M points, 2 threads; drawn under a budget (C, llvmpipe)"
    echo
    "$build/bench_octree" --out "$out" "$samples"
    echo
    echo "### Point octree in the viewer: headless Chromium (SwiftShader) under a budget"
    echo
    serve "$out" "$out/serve.out"
    node "$root/bench/octree_browser.mjs" "$served_url" bench_octree_10000000_normals || echo "(the browser bench failed)"
    kill -TERM "$served_pid"; wait "$served_pid" || true
    echo
  fi
  if want terrain; then
    echo "### Terrain continuous LOD: cracks, popping and update time over 500-frame flights"
    echo
    "$build/bench_terrain" --out "$out" "$samples" | sed 's/^### /#### /'
    echo
  fi
  if want scale; then
    echo "### Large meshes: 20M triangles to 1% and 0.1%, 5M through progressive; time and peak memory per stage"
    echo
    "$build/bench_scale" --out "${TMPDIR:-/tmp}" "$samples"
    echo
  fi
  if want io; then
    echo "### Readers and writers: MB/s of lk_mesh_read and lk_mesh_write on a >= 100 MB mesh (file in the page cache)"
    echo
    "$build/bench_io" --python "$python" "$samples"
    echo
  fi
  if want gltf; then
    echo "### glTF output: size, quantisation and compression, simplification, against gltfpack (npm)"
    echo
    bash "$root/bench/gltf.sh" "$lodkit" "$samples" "$out"
    echo
  fi
}

# The run between the markers of FILE (created with a title when missing;
# markers appended when it has none), replaced whole by a rename.
begin_marker='<!-- bench-run: written by bench/run.sh (make bench); the next run replaces everything down to the closing marker -->'
end_marker='<!-- /bench-run -->'
write_run() {  # write_run REPORT FILE
  local report="$1" file="$2" temporary
  temporary="$(dirname "$file")/.$(basename "$file").tmp-$$"
  if [ ! -f "$file" ]; then
    printf '# lodkit benchmarks\n\n%s\n%s\n' "$begin_marker" "$end_marker" > "$file"
  elif ! grep -qxF "$begin_marker" "$file" || ! grep -qxF "$end_marker" "$file"; then
    printf '\n%s\n%s\n' "$begin_marker" "$end_marker" >> "$file"
  fi
  awk -v report="$report" -v begin="$begin_marker" -v end="$end_marker" '
    $0 == begin { print; while ((getline line < report) > 0) print line; skipping = 1; next }
    $0 == end { skipping = 0 }
    !skipping { print }' "$file" > "$temporary"
  mv "$temporary" "$file"
}

report="$out/benchmarks-run.md"
start=$(date +%s)
run_benchmarks | tee "$report"
seconds=$(( $(date +%s) - start ))
echo "The run took $((seconds / 60)) min $((seconds % 60)) s." | tee -a "$report"
if [ -n "$docs" ]; then
  write_run "$report" "$docs"
  echo "bench/run.sh: wrote the run into ${docs#"$root"/}"
fi
