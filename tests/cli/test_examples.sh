#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# examples/ as a user builds them against an installed lodkit: through
# pkg-config (examples/Makefile, shared and STATIC=1) and through CMake's
# find_package (examples/CMakeLists.txt, shared and static), then run on a
# sample model with the numbers they must print.
set -u
source "$(dirname "$0")/lib.sh"
: "${LK_BUILD_DIR:?}" "${LK_SOURCE_DIR:?}"
require cc gcc
require pkg-config pkg-config
require make make
prefix="$TMP/prefix"
check "cmake --install" cmake --install "$LK_BUILD_DIR" --prefix "$prefix" >/dev/null
libdir=$(dirname "$(dirname "$(find "$prefix" -name lodkit.pc | head -1)")")
export PKG_CONFIG_PATH="$libdir/pkgconfig"
cow="$LK_SAMPLES_DIR/cow.off"

# run_examples DIR LABEL: the three programs of DIR on the cow.
run_examples() {
  local dir="$1" label="$2" out
  out=$(LD_LIBRARY_PATH="$libdir" "$dir/simplify" "$cow" "$TMP/cow-$label.obj" 0.1 2>&1)
  check "$label simplify: $out" grep -qx "5804 -> 580 triangles, error [0-9.]*% of the diagonal" <<<"$out"
  check "$label simplify wrote an OBJ" grep -q "^f " "$TMP/cow-$label.obj"
  out=$(LD_LIBRARY_PATH="$libdir" "$dir/stream" "$cow" 25 2>&1)
  check "$label stream: cut prefix drawable ($out)" grep -qE "^[0-9]+ of [0-9]+ bytes: [0-9]+ vertices, [1-9][0-9]* triangles \(cut\)$" <<<"$out"
  check "$label stream: whole stream gives the cow" grep -qE "vertices, 5804 triangles \(complete\)$" <<<"$out"
  out=$(LD_LIBRARY_PATH="$libdir" "$dir/measure" "$cow" "$TMP/cow-$label.obj" 2>&1)
  # The cow at 10%: Hausdorff 1.30% of the diagonal (lodkit metro says the
  # same; 1.81% before issue 22's lighter crease constraints).
  check "$label measure: ${out%%$'\n'*}" awk '/^hausdorff/ { p = $3; gsub(/[(%)]/, "", p); ok = p > 1.1 && p < 1.6 } END { exit !ok }' <<<"$out"
  check "$label measure prints both directions" grep -qE "^B to A: max [0-9.e+-]+ mean [0-9.e+-]+ rms [0-9.e+-]+$" <<<"$out"
  out=$(LD_LIBRARY_PATH="$libdir" "$dir/measure" "$cow" "$cow" 2>&1)
  check "$label measure of a mesh to itself is 0 ($out)" awk '/^hausdorff/ { ok = $2 < 1e-9 } END { exit !ok }' <<<"$out"
  out=$(LD_LIBRARY_PATH="$libdir" "$dir/simplify" "$TMP/missing.obj" "$TMP/x.obj" 2>&1)
  check "$label simplify names a missing input ($out)" grep -q "missing.obj" <<<"$out"
}

for variant in shared static; do
  dir="$TMP/make-$variant"
  cp -r "$LK_SOURCE_DIR/examples" "$dir"
  static=0; [ "$variant" = static ] && static=1
  check "examples/Makefile ($variant)" make -s -C "$dir" STATIC=$static CFLAGS="-O2 -Wall -Wextra -Werror" >/dev/null
  if [ "$variant" = static ]; then
    check "static example does not load liblodkit.so" bash -c '! ldd "$1" | grep -q liblodkit' _ "$dir/simplify"
  else
    check "shared example loads liblodkit.so" bash -c 'LD_LIBRARY_PATH="$2" ldd "$1" | grep -q liblodkit.so' _ \
      "$dir/simplify" "$libdir"
  fi
  run_examples "$dir" "make-$variant"

  dir="$TMP/cmake-$variant"
  on=OFF; [ "$variant" = static ] && on=ON
  check "examples/CMakeLists.txt configures ($variant)" cmake -S "$LK_SOURCE_DIR/examples" -B "$dir" \
    -DCMAKE_PREFIX_PATH="$prefix" -DLODKIT_EXAMPLES_STATIC=$on >/dev/null
  check "examples/CMakeLists.txt builds ($variant)" cmake --build "$dir" >/dev/null
  run_examples "$dir" "cmake-$variant"
done
finish
