#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Independent check of lodkit metro with MeshLab's "Hausdorff Distance"
# filter (Debian meshlab, run headless through xvfb-run).
# Usage: bench/metro_meshlab.sh A B SAMPLES_A SAMPLES_B
# SAMPLES_X: the number of samples lodkit takes on X (so densities match).
# MeshLab samples vertices, edges and faces like Metro; its max comes from
# that run, its RMS from a run with face samples only (area-weighted, which
# is what lodkit's RMS is). Prints JSON like metro_open3d.py.
set -euo pipefail
a="$1"; b="$2"; samples_a="$3"; samples_b="$4"
work="$(mktemp -d /tmp/lodkit-meshlab.XXXXXX)"
trap 'rm -rf "$work"' EXIT
lodkit="${LODKIT:-lodkit}"
# MeshLab's OBJ importer asserts on some files (e.g. the glmark2 bunny): use PLY.
"$lodkit" convert --quiet "$a" "$work/a.ply"
"$lodkit" convert --quiet "$b" "$work/b.ply"
script() {  # script VERT EDGE SAMPLES
  cat <<XML
<!DOCTYPE FilterScript>
<FilterScript>
 <filter name="Hausdorff Distance">
  <Param type="RichMesh" value="0" name="SampledMesh"/>
  <Param type="RichMesh" value="1" name="TargetMesh"/>
  <Param type="RichBool" value="false" name="SaveSample"/>
  <Param type="RichBool" value="$1" name="SampleVert"/>
  <Param type="RichBool" value="$2" name="SampleEdge"/>
  <Param type="RichBool" value="false" name="SampleFauxEdge"/>
  <Param type="RichBool" value="true" name="SampleFace"/>
  <Param type="RichInt" value="$3" name="SampleNum"/>
  <Param type="RichAbsPerc" value="1e9" min="0" max="1e9" name="MaxDist"/>
 </filter>
</FilterScript>
XML
}
run() {  # run SAMPLED TARGET VERT EDGE SAMPLES -> "max mean rms"
  script "$3" "$4" "$5" > "$work/filter.mlx"
  xvfb-run -a meshlabserver -i "$1" -i "$2" -s "$work/filter.mlx" > "$work/log.txt" 2>&1 || {
    echo "metro_meshlab: meshlabserver failed:" >&2; tail -5 "$work/log.txt" >&2; exit 1; }
  grep -m1 -E '^ *min : .* max ' "$work/log.txt" | sed -E 's/.*max ([0-9.e+-]+) +mean : ([0-9.e+-]+) +RMS : ([0-9.e+-]+).*/\1 \2 \3/'
}
read -r fmax _ _ < <(run "$work/a.ply" "$work/b.ply" true true "$samples_a")
read -r _ fmean frms < <(run "$work/a.ply" "$work/b.ply" false false "$samples_a")
read -r bmax _ _ < <(run "$work/b.ply" "$work/a.ply" true true "$samples_b")
read -r _ bmean brms < <(run "$work/b.ply" "$work/a.ply" false false "$samples_b")
cat <<JSON
{"forward": {"max": $fmax, "mean": $fmean, "rms": $frms},
 "backward": {"max": $bmax, "mean": $bmean, "rms": $brms}}
JSON
