#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The demo run by `make demo`: what lodkit can do today, on the real sample
# models. Usage: scripts/demo.sh path/to/lodkit
set -euo pipefail
lodkit="$(realpath "${1:-build/lodkit}")"
root="$(cd "$(dirname "$0")/.." && pwd)"
samples="$root/data/samples"
work="$(mktemp -d /tmp/lodkit-demo.XXXXXX)"
pictures="$root/demo-out"
trap 'rm -rf "$work"' EXIT
models=(bunny.obj cow.off triceratops.off fandisk.off ChineseDragon-10kv.off)

echo "== lodkit $("$lodkit" --version | cut -d' ' -f2): the sample models (lodkit info) =="
(cd "$samples" && "$lodkit" info "${models[@]}")
echo
echo "== Metro surface distance (lodkit metro, 10 samples per face) =="
echo "   each model against itself, and against a copy moved by 1% of its diagonal along x"
printf "%-24s %14s %14s %14s %14s %12s\n" "model" "self haus.%" "moved fwd max%" "moved bwd max%" "moved rms%" "moved Ms/s"
field() { grep -o "\"$1\":{[^}]*}" | grep -o "\"$2\":[-0-9.e+]*" | cut -d: -f2; }
top() { grep -o "\"$1\":[-0-9.e+]*" | head -1 | cut -d: -f2; }
for model in "${models[@]}"; do
  ext="${model##*.}"
  "$lodkit" convert --quiet --translate-diagonal=0.01,0,0 "$samples/$model" "$work/moved.$ext"
  self=$("$lodkit" metro --json "$samples/$model" "$samples/$model")
  moved=$("$lodkit" metro --json "$samples/$model" "$work/moved.$ext")
  diag=$(echo "$moved" | top diagonal)
  awk -v m="$model" -v d="$diag" -v s="$(echo "$self" | top hausdorff)" \
      -v f="$(echo "$moved" | field forward max)" -v b="$(echo "$moved" | field backward max)" \
      -v r="$(echo "$moved" | field forward rms)" -v n="$(echo "$moved" | top samples)" \
      -v t="$(echo "$moved" | top seconds)" \
      'BEGIN { printf "%-24s %14.6f %14.4f %14.4f %14.4f %12.2f\n", m, 100*s/d, 100*f/d, 100*b/d, 100*r/d, n/t/1e6 }'
done
echo
echo "== Simplification (lodkit simplify --measure): the bunny and the triceratops =="
printf "%-18s %-9s %8s %10s %10s %10s %12s\n" "model" "method" "target" "triangles" "ms" "haus. %" "rms fwd %"
for model in bunny.obj triceratops.off; do
  for target in 10 1; do
    for method in qem uniform floating; do
      json=$("$lodkit" simplify --json --measure --method=$method --ratio=0.$(printf %02d $target) \
             "$samples/$model" "$work/simplified.ply")
      metro=$(echo "$json" | grep -o '"metro":{.*')
      awk -v m="$model" -v k="$method" -v t="$target%" -v n="$(echo "$json" | top triangles)" \
          -v s="$(echo "$json" | top seconds)" -v h="$(echo "$metro" | top hausdorff_percent)" \
          -v r="$(echo "$metro" | field forward rms)" -v d="$(echo "$json" | top diagonal)" \
          'BEGIN { printf "%-18s %-9s %8s %10d %10.1f %10.3f %12.4f\n", m, k, t, n, 1000*s, h, 100*r/d }'
    done
  done
done
echo
echo "== Wavelet simplification by planar sampling vs clustering at 12.5% of the vertices (paper Table 4) =="
printf "%-18s %-9s %9s %10s %10s %10s\n" "model" "method" "vertices" "triangles" "ms" "haus. %"
for model in triceratops.off bunny.obj; do
  vertices=$("$lodkit" info --json "$samples/$model" | top vertices)
  target=$(( (vertices + 4) / 8 ))
  for method in uniform floating wavelet; do
    json=$("$lodkit" simplify --json --measure --method=$method --vertices=$target "$samples/$model" "$work/w.ply")
    metro=$(echo "$json" | grep -o '"metro":{.*')
    awk -v m="$model" -v k="$method" -v v="$(echo "$json" | grep -o '"vertices":[0-9]*' | tail -1 | cut -d: -f2)" \
        -v n="$(echo "$json" | top triangles)" -v s="$(echo "$json" | top seconds)" \
        -v h="$(echo "$metro" | top hausdorff_percent)" \
        'BEGIN { printf "%-18s %-9s %9d %10d %10.1f %10.3f\n", m, k, v, n, 1000*s, h }'
  done
done
mkdir -p "$pictures"
"$lodkit" slices --vertices=4354 "$samples/bunny.obj" "$pictures/bunny-slices.svg"
echo
echo "== Animated model: faerie.md2 (198 frames), max / avg / frame-0 schemes, 10 levels -> $pictures/animate =="
echo "   (Metro on every 10th frame here; make bench measures all)"
# animate replaces its folder whole and refuses one it cannot tell is its own:
# a set from a lodkit before .lodkit-animate manifests goes first
[ ! -d "$pictures/animate" ] || [ -e "$pictures/animate/.lodkit-animate" ] || rm -rf "$pictures/animate"
"$lodkit" animate --scheme=all --levels=10 --metro-step=10 "$samples/faerie.md2" "$pictures/animate"
echo
echo "== Progressive meshes on triangle strips (lodkit progressive --stream-version=1): the paper's cow and bunny =="
for model in cow.off bunny.obj; do
  "$lodkit" progressive --stream-version=1 "$samples/$model" "$work/${model%.*}-strips.lks"
  echo
done
echo "== The same as stream version 2, the default (range-coded splits, first frame in the first kilobytes) =="
for model in cow.off bunny.obj; do
  "$lodkit" progressive "$samples/$model" "$work/${model%.*}.lks"
  echo
done
echo "== Partial download: the bunny stream cut at a quarter of its bytes (lodkit unpack --bytes) =="
size=$(stat -c %s "$work/bunny.lks")
"$lodkit" unpack --bytes=$((size / 4)) "$work/bunny.lks" "$work/bunny-quarter.ply"
"$lodkit" metro "$samples/bunny.obj" "$work/bunny-quarter.ply" | grep -E "max|hausdorff"
echo
echo "== Pictures (lodkit render / lodkit splat, headless OpenGL ES 2.0 on Mesa) -> $pictures =="
mkdir -p "$pictures"
"$lodkit" render "$samples/bunny.obj" -o "$pictures/bunny.png"
"$lodkit" render --wireframe "$samples/triceratops.off" -o "$pictures/triceratops-wireframe.png"
"$lodkit" render "$work/bunny-quarter.ply" -o "$pictures/bunny-stream-quarter.png"
"$lodkit" sample --points=100000 "$samples/bunny.obj" "$work/bunny-points.ply"
"$lodkit" splat --passes=1 "$work/bunny-points.ply" -o "$pictures/bunny-splats-1pass.png"
"$lodkit" splat --passes=2 "$work/bunny-points.ply" -o "$pictures/bunny-splats-2pass.png"
"$lodkit" sample "$samples/kitten.xyz" "$work/kitten.ply"
"$lodkit" splat --passes=2 "$work/kitten.ply" -o "$pictures/kitten-splats.png"
echo
echo "Try: $lodkit info $samples/bunny.obj"
echo "     $lodkit metro $samples/bunny.obj $samples/bunny.obj"
echo "     $lodkit simplify --ratio=0.1 --measure $samples/bunny.obj bunny-10.ply"
echo "     $lodkit progressive $samples/bunny.obj bunny.lks && $lodkit inspect bunny.lks"
echo
echo "== Streaming: content for the WebGL viewer (lodkit serve) -> $pictures/serve =="
serve="$pictures/serve"
mkdir -p "$serve"
# Version-2 streams (the default): the bunny's first frame is in its first
# 1.2% (docs/stream-format.md). The viewer decodes them in a Web Worker.
for model in bunny.obj cow.off triceratops.off; do
  "$lodkit" progressive -q "$samples/$model" "$serve/${model%.*}.lks"
done
"$lodkit" sample -q --points=100000 "$samples/bunny.obj" "$serve/bunny-points.ply"
cp "$samples/jacksboro_fault_dem.npz" "$serve/"
ls -l "$serve"
echo
echo "Serve them (the start line prints the URL; open it in a browser):"
echo "     $lodkit serve $serve"
echo "     -> http://127.0.0.1:8080/"
