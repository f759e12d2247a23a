#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Issue 10: a subset of the suite under valgrind (memcheck) in the release
# build: uninitialised reads, invalid accesses and definite leaks that the
# optimised build would hide. Whole small unit-test executables (the
# readers, mesh, progressive meshes, strips, the stream) and CLI runs over the real
# samples: simplify (qem on the bunny, wavelet on the cow), progressive +
# inspect + unpack on the cow, metro, glTF (text + .bin, binary .glb, a
# skinned animation), DEMs through GDAL (netCDF) and our own .npz reader,
# MD2 animation, PLY/OFF/OBJ writers. Any memcheck error or definite leak
# makes valgrind exit 99 and the test fail. Two runs at a time.
# Not part of the sanitizer suite (valgrind cannot run ASan binaries; see
# tests/CMakeLists.txt); fails when valgrind is missing. EGL/GL paths (render, splat, terrain --png) are left
# out: Mesa's llvmpipe is noisy under valgrind.
set -u
source "$(dirname "$0")/lib.sh"
S="$LK_SAMPLES_DIR"
require valgrind valgrind
VALGRIND=(valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite
          --show-leak-kinds=definite --num-callers=30)
log="$TMP/logs"
mkdir -p "$log"

# The jobs: each a function run in its own bash (two at a time by xargs),
# which gets VALGRIND from $TMP/valgrind.sh and the function from the
# environment.
job_unit() { cd "$LK_BUILD_DIR/tests" && exec "${VALGRIND[@]}" "./$1"; }
job_simplify_qem() { exec "${VALGRIND[@]}" "$LODKIT" simplify -q -r 0.1 "$S/bunny.obj" "$TMP/bunny-10.ply"; }
job_simplify_wavelet() { exec "${VALGRIND[@]}" "$LODKIT" simplify -q -m wavelet --slices=32 -r 0.2 "$S/cow.off" "$TMP/cow-wavelet.obj"; }
job_progressive() {
  "${VALGRIND[@]}" "$LODKIT" progressive -q "$S/cow.off" "$TMP/cow.lks" || return
  "${VALGRIND[@]}" "$LODKIT" inspect "$TMP/cow.lks" >/dev/null || return
  "${VALGRIND[@]}" "$LODKIT" unpack -q -r 0.5 "$TMP/cow.lks" "$TMP/cow-half.off" || return
  "${VALGRIND[@]}" "$LODKIT" unpack -q --bytes=4000 "$TMP/cow.lks" "$TMP/cow-partial.obj"
}
job_metro() {
  "$LODKIT" simplify -q -r 0.2 "$S/cow.off" "$TMP/cow-20.obj" || return
  exec "${VALGRIND[@]}" "$LODKIT" metro "$S/cow.off" "$TMP/cow-20.obj"
}
job_gltf() {
  "${VALGRIND[@]}" "$LODKIT" convert -q "$S/assimp/glTF2/BoxTextured-glTF/BoxTextured.gltf" "$TMP/box.obj" || return
  "${VALGRIND[@]}" "$LODKIT" info "$S/assimp/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb" >/dev/null || return
  "${VALGRIND[@]}" "$LODKIT" animate -q --ratio=0.5 --no-metro "$S/assimp/glTF2/simple_skin/simple_skin.gltf" "$TMP/rigged"
}
job_dem() {
  "${VALGRIND[@]}" "$LODKIT" terrain -q --flight=3 --grid-size=129 "$S/etopo20.cdf" || return
  "${VALGRIND[@]}" "$LODKIT" terrain -q --flight=3 "$S/jacksboro_fault_dem.npz"
}
job_md2() { exec "${VALGRIND[@]}" "$LODKIT" animate -q --levels=2 --metro-step=99 --samples-per-face=1 "$S/faerie.md2" "$TMP/faerie"; }
job_convert() {
  "${VALGRIND[@]}" "$LODKIT" convert -q --weld --clean "$S/fandisk.off" "$TMP/fandisk.ply" || return
  "${VALGRIND[@]}" "$LODKIT" convert -q --ascii "$TMP/fandisk.ply" "$TMP/fandisk-ascii.ply" || return
  "${VALGRIND[@]}" "$LODKIT" info "$S/hippo1.ply" "$S/kitten.xyz" >/dev/null
}

units=(test_mesh test_io_text test_io_ply_stl test_io_gltf test_dem test_anim_io test_pm test_stream test_strips)
jobs=(simplify_qem simplify_wavelet progressive metro gltf dem md2 convert)
for unit in "${units[@]}"; do
  check "$unit is built" test -x "$LK_BUILD_DIR/tests/$unit"
done

# runner NAME FUNCTION [ARG]: one job, its log kept; prints "NAME EXIT SECONDS".
runner() {
  local name=$1 function=$2 argument=${3:-} start=$SECONDS
  ( "$function" $argument ) >"$log/$name.log" 2>&1
  echo "$name $? $((SECONDS - start))"
}
declare -p VALGRIND >"$TMP/valgrind.sh"
export LODKIT S TMP LK_BUILD_DIR log
export -f runner job_unit "${jobs[@]/#/job_}"
{
  for unit in "${units[@]}"; do echo "$unit job_unit $unit"; done
  for job in "${jobs[@]}"; do echo "$job job_$job"; done
} >"$TMP/jobs.txt"
start=$SECONDS
# A job that outlives 280 s is killed and reports nothing: counted below.
xargs -P 2 -L 1 timeout -k 5 280 bash -c 'source "$TMP/valgrind.sh"; runner "$@"' _ <"$TMP/jobs.txt" >"$TMP/results.txt"
while read -r name code seconds; do
  check "valgrind $name exit $code (${seconds}s)" test "$code" -eq 0
  if [ "$code" -ne 0 ]; then sed 's/^/    /' "$log/$name.log" | head -60; fi
done <"$TMP/results.txt"
check "every job reported ($(wc -l <"$TMP/results.txt") of $(wc -l <"$TMP/jobs.txt"))" \
  test "$(wc -l <"$TMP/results.txt")" -eq "$(wc -l <"$TMP/jobs.txt")"
echo "valgrind subset: $((SECONDS - start)) s"
sort -k3 -n -r "$TMP/results.txt" | awk '{ printf "  %-18s %4d s  exit %d\n", $1, $3, $2 }'
finish
