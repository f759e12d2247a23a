#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `make bench`, part gltf: lodkit's glTF output against gltfpack (npm, pinned
# in bench/npm) on the same inputs, in one run. Prints Markdown tables:
#   1. file size: plain, quantised (KHR_mesh_quantization) and compressed
#      (EXT_meshopt_compression), lodkit vs gltfpack, and the position error
#      the quantisation costs (lodkit metro, Hausdorff % of the diagonal);
#   2. simplification written as compressed glTF: gltfpack -si R -cc (R =
#      10%, 1%), then lodkit simplify --meshopt to the triangle count
#      gltfpack wrote; Hausdorff and RMS (lodkit metro against the input),
#      bytes, seconds;
#   3. textured scenes (glTF samples of Debian packages): the same at 25%
#      and 10% without quantisation, and the compressed sizes.
# Usage: bench/gltf.sh LODKIT SAMPLES OUT_DIR
set -euo pipefail
lodkit="$1" samples="$2" out="$3/gltf"
root="$(cd "$(dirname "$0")/.." && pwd)"
gltfpack="$root/bench/npm/node_modules/gltfpack/cli.js"
[ -f "$gltfpack" ] || { echo "bench/gltf.sh: $gltfpack missing: run scripts/install-deps.sh --bench" >&2; exit 1; }
mkdir -p "$out"

size() { stat -c %s "$1"; }
seconds() { date +%s.%N; }
metro() {  # metro A B: "hausdorff% rms%" of B against A
  "$lodkit" metro --json --threads=1 "$1" "$2" |
    python3 -c 'import json, sys; d = json.load(sys.stdin); rms = max(d["forward"]["rms"], d["backward"]["rms"])
print("%.4f %.4f" % (d["hausdorff_percent"], 100 * rms / d["diagonal"]))'
}
triangles() { "$lodkit" info --json "$1" | python3 -c 'import json, sys; print(json.load(sys.stdin)["triangles"])'; }

models=(bunny.obj ChineseDragon-10kv.off cow.off triceratops.off fandisk.off)
gltfpack_version="$(node "$gltfpack" -v 2>&1 | head -1)"

echo "#### File size: lodkit vs $gltfpack_version"
echo
echo "Bytes of one \`.glb\` per model. lodkit: \`convert\` (floats), \`--quantize\`, \`--meshopt\`; gltfpack on"
echo "lodkit's float \`.glb\`: \`-noq\`, default (quantised), \`-cc\`. Error: Hausdorff % of the diagonal of the"
echo "compressed file against the input (lodkit metro)."
echo
echo "| model | lodkit | gltfpack -noq | lodkit --quantize | gltfpack | lodkit --meshopt | gltfpack -cc | meshopt / -cc | error lodkit | error gltfpack |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for model in "${models[@]}"; do
  input="$samples/$model" stem="${model%%.*}"
  "$lodkit" convert -q "$input" "$out/$stem.glb"
  "$lodkit" convert -q --quantize "$input" "$out/$stem-q.glb"
  "$lodkit" convert -q --meshopt "$input" "$out/$stem-m.glb"
  node "$gltfpack" -noq -i "$out/$stem.glb" -o "$out/$stem-gp-noq.glb" >/dev/null
  node "$gltfpack" -i "$out/$stem.glb" -o "$out/$stem-gp.glb" >/dev/null
  node "$gltfpack" -cc -i "$out/$stem.glb" -o "$out/$stem-gp-cc.glb" >/dev/null
  ours=$(metro "$input" "$out/$stem-m.glb") theirs=$(metro "$input" "$out/$stem-gp-cc.glb")
  ratio=$(python3 -c "print('%.3f' % ($(size "$out/$stem-m.glb") / $(size "$out/$stem-gp-cc.glb")))")
  echo "| $stem | $(size "$out/$stem.glb") | $(size "$out/$stem-gp-noq.glb") | $(size "$out/$stem-q.glb") |" \
    "$(size "$out/$stem-gp.glb") | $(size "$out/$stem-m.glb") | $(size "$out/$stem-gp-cc.glb") | $ratio |" \
    "${ours%% *} | ${theirs%% *} |"
done
echo

echo "#### Simplified and compressed: gltfpack -si R -cc, then lodkit simplify --meshopt to the same triangle count"
echo
echo "Each tool from the float \`.glb\`. gltfpack stops short of R where a further collapse would cross its limits"
echo "(the 1% rows), so lodkit is asked for the triangle count gltfpack wrote: the same size, compared by error."
echo "Hausdorff and RMS % of the diagonal against the input (lodkit metro, both directions); seconds of the whole"
echo "command (read, simplify, write)."
echo
echo "| model | R | triangles | Hausdorff lodkit | gltfpack | RMS lodkit | gltfpack | bytes lodkit | gltfpack | s lodkit | gltfpack |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for model in "${models[@]}"; do
  input="$samples/$model" stem="${model%%.*}"
  for ratio in 0.1 0.01; do
    start=$(seconds)
    node "$gltfpack" -cc -si "$ratio" -i "$out/$stem.glb" -o "$out/$stem-gp-s$ratio.glb" >/dev/null
    theirs_time=$(python3 -c "print('%.3f' % ($(seconds) - $start))")
    count=$(triangles "$out/$stem-gp-s$ratio.glb")
    start=$(seconds)
    "$lodkit" simplify -q --meshopt --triangles="$count" "$out/$stem.glb" "$out/$stem-s$ratio.glb"
    ours_time=$(python3 -c "print('%.3f' % ($(seconds) - $start))")
    read -r ours_h ours_r <<<"$(metro "$input" "$out/$stem-s$ratio.glb")"
    read -r theirs_h theirs_r <<<"$(metro "$input" "$out/$stem-gp-s$ratio.glb")"
    ours_count=$(triangles "$out/$stem-s$ratio.glb")
    [ "$ours_count" = "$count" ] || count="$count (lodkit $ours_count)"
    echo "| $stem | $ratio | $count | $ours_h | $theirs_h | $ours_r | $theirs_r |" \
      "$(size "$out/$stem-s$ratio.glb") | $(size "$out/$stem-gp-s$ratio.glb") | $ours_time | $theirs_time |"
  done
done
echo

# ---- textured scenes ----------------------------------------------------------
# Every primitive, material and texture kept (lodkit's scene path); gltfpack
# also merges meshes and primitives, so the triangles are counted over the
# distinct meshes of each file (what -si counts).
scene_triangles() {
  "$lodkit" info --json "$1" | python3 -c 'import json, sys
d = json.load(sys.stdin)
print(sum(p["triangles"] for m in d["scene"]["meshes"] for p in m["primitives"]))'
}
G="$samples/assimp/glTF2" C="$samples/cge"
scenes=("$G/2CylinderEngine-glTF-Binary/2CylinderEngine.glb" "$G/ClearCoat-glTF/ClearCoatTest.gltf")
for f in "$C/level/level-dungeon.gltf" "$C/castle/castle.gltf" "$C/knight/knight.gltf" "$C/avatar/avatar.gltf" \
  "$C/monkey/monkey.gltf"; do
  [ -f "$f" ] && scenes+=("$f")
done
echo "#### Textured scenes: gltfpack -noq -si R, then lodkit simplify to the same triangle count"
echo
echo "glTF samples of Debian packages (assimp-testmodels; castle-game-engine-doc, fetched by"
echo '`scripts/fetch-samples.sh --bench`), every material and texture kept by both tools, no quantisation (the'
echo "error is the simplification's). Triangles of the distinct meshes; Hausdorff and RMS % of the diagonal of the"
echo "scene as drawn (lodkit metro, both directions); seconds of the whole command. Then the unsimplified scene"
echo 'compressed: lodkit `convert --meshopt` and gltfpack `-cc` (both 14-bit positions; images embedded).'
echo
echo "| scene | R | triangles | Hausdorff lodkit | gltfpack | RMS lodkit | gltfpack | s lodkit | gltfpack |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for input in "${scenes[@]}"; do
  stem="$(basename "${input%.*}")"
  for ratio in 0.25 0.1; do
    start=$(seconds)
    node "$gltfpack" -noq -si "$ratio" -i "$input" -o "$out/$stem-gp-s$ratio.glb" >/dev/null
    theirs_time=$(python3 -c "print('%.3f' % ($(seconds) - $start))")
    count=$(scene_triangles "$out/$stem-gp-s$ratio.glb")
    start=$(seconds)
    "$lodkit" simplify -q --triangles="$count" "$input" "$out/$stem-s$ratio.glb"
    ours_time=$(python3 -c "print('%.3f' % ($(seconds) - $start))")
    read -r ours_h ours_r <<<"$(metro "$input" "$out/$stem-s$ratio.glb")"
    read -r theirs_h theirs_r <<<"$(metro "$input" "$out/$stem-gp-s$ratio.glb")"
    ours_count=$(scene_triangles "$out/$stem-s$ratio.glb")
    [ "$ours_count" = "$count" ] || count="$count (lodkit $ours_count)"
    echo "| $stem | $ratio | $count | $ours_h | $theirs_h | $ours_r | $theirs_r | $ours_time | $theirs_time |"
  done
done
echo
echo "| scene | triangles | bytes .glb | lodkit --meshopt | gltfpack -cc | meshopt / -cc |"
echo "|---|---:|---:|---:|---:|---:|"
for input in "${scenes[@]}"; do
  stem="$(basename "${input%.*}")"
  "$lodkit" convert -q "$input" "$out/$stem-scene.glb"
  "$lodkit" convert -q --meshopt "$input" "$out/$stem-scene-m.glb"
  node "$gltfpack" -cc -i "$input" -o "$out/$stem-scene-gp-cc.glb" >/dev/null
  ratio=$(python3 -c "print('%.3f' % ($(size "$out/$stem-scene-m.glb") / $(size "$out/$stem-scene-gp-cc.glb")))")
  echo "| $stem | $(scene_triangles "$input") | $(size "$out/$stem-scene.glb") | $(size "$out/$stem-scene-m.glb") |" \
    "$(size "$out/$stem-scene-gp-cc.glb") | $ratio |"
done
echo
if python3 -c 'import open3d' 2>/dev/null; then
  echo "Open3D (python3-open3d) reads each scene lodkit wrote: triangles of its distinct meshes (Open3D merges the"
  echo "primitives and counts a mesh once), whether it found texture coordinates, and the textures it loaded."
  echo
  echo "| file | lodkit's triangles | Open3D triangles | Open3D UVs | Open3D textures |"
  echo "|---|---:|---:|---|---:|"
  for input in "${scenes[@]}"; do
    stem="$(basename "${input%.*}")"
    for file in "$out/$stem-scene.glb" "$out/$stem-s0.25.glb"; do
      python3 - "$file" "$(scene_triangles "$file")" <<'PY'
import os, sys
import open3d as o3d
path, ours = sys.argv[1], sys.argv[2]
mesh = o3d.io.read_triangle_mesh(path)
print("| %s | %s | %d | %s | %d |" % (os.path.basename(path), ours, len(mesh.triangles),
                                      "yes" if mesh.has_triangle_uvs() else "no", len(mesh.textures)))
PY
    done
  done
  echo
fi
echo "gltfpack's times include node and its WebAssembly start (about 0.1 s); lodkit's include reading and writing."
