#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# CLI contract: help, version, exit codes (0 ok, 1 bad input, 2 usage),
# the acceptance numbers of `lodkit info` on the bunny, conversions through
# every writable format, and errors that name the file and line.
set -u
source "$(dirname "$0")/lib.sh"

# help and version
expect_exit 0 "$LODKIT" --help
expect_output_contains "metro" "$LODKIT" --help
expect_exit 0 "$LODKIT" --version
expect_output_contains "lodkit 0." "$LODKIT" --version
for command in info convert metro; do
  expect_exit 0 "$LODKIT" $command --help
  expect_output_contains "Usage: lodkit $command" "$LODKIT" $command --help
done
# usage errors exit 2
expect_exit 2 "$LODKIT"
expect_exit 2 "$LODKIT" frobnicate
expect_exit 2 "$LODKIT" info
expect_exit 2 "$LODKIT" info --bogus "$LK_SAMPLES_DIR/cow.off"
expect_exit 2 "$LODKIT" metro "$LK_SAMPLES_DIR/cow.off"
expect_exit 2 "$LODKIT" metro --samples-per-face=-3 "$LK_SAMPLES_DIR/cow.off" "$LK_SAMPLES_DIR/cow.off"
expect_exit 2 "$LODKIT" convert "$LK_SAMPLES_DIR/cow.off" "$TMP/out.unknownext"

# info on the bunny: the acceptance numbers
out=$("$LODKIT" info "$LK_SAMPLES_DIR/bunny.obj")
check "bunny vertices" grep -qE '^vertices +34,835$' <<<"$out"
check "bunny triangles" grep -qE '^triangles +69,666$' <<<"$out"
check "bunny genus" grep -qE '^genus +0$' <<<"$out"
check "bunny boundary" grep -qE '^boundary edges +0 ' <<<"$out"
check "bunny components" grep -qE '^components +1$' <<<"$out"
json=$("$LODKIT" info --json "$LK_SAMPLES_DIR/bunny.obj")
check "info json" grep -q '"vertices":34835,"triangles":69666' <<<"$json"
check "info json genus" grep -q '"genus":0' <<<"$json"
check "info json: no attributes on the bunny" grep -q '"attributes":\[\]' <<<"$json"
check "info json: the hippo's normals" grep -q '"attributes":\["normals"\]' <<<"$("$LODKIT" info --json "$LK_SAMPLES_DIR/hippo1.ply")"
# several files: one table row each
rows=$("$LODKIT" info "$LK_SAMPLES_DIR/cow.off" "$LK_SAMPLES_DIR/fandisk.off" | wc -l)
check "info table rows" test "$rows" -eq 3

# bad input exits 1 with FILE:LINE
printf 'OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n' > "$TMP/bad.off"
expect_exit 1 "$LODKIT" info "$TMP/bad.off"
err=$("$LODKIT" info "$TMP/bad.off" 2>&1 >/dev/null)
check "error names file:line ($err)" grep -q "bad.off:6" <<<"$err"
: > "$TMP/empty.obj"
expect_exit 1 "$LODKIT" info "$TMP/empty.obj"
expect_exit 1 "$LODKIT" info "$TMP/does-not-exist.obj"

# convert through every writable format keeps the counts
for ext in obj ply off smf; do
  expect_exit 0 "$LODKIT" convert --quiet "$LK_SAMPLES_DIR/cow.off" "$TMP/cow.$ext"
  out=$("$LODKIT" info --json "$TMP/cow.$ext")
  check "cow via $ext" grep -q '"vertices":2904,"triangles":5804' <<<"$out"
done
# STL stores triangle soup; reading welds identical positions, and the cow
# has two vertices at the same position, so one vertex fewer comes back.
expect_exit 0 "$LODKIT" convert --quiet "$LK_SAMPLES_DIR/cow.off" "$TMP/cow.stl"
out=$("$LODKIT" info --json "$TMP/cow.stl")
check "cow via stl" grep -q '"vertices":2903,"triangles":5804' <<<"$out"
expect_exit 0 "$LODKIT" convert --quiet --weld "$LK_SAMPLES_DIR/cow.off" "$TMP/cow-welded.obj"
out=$("$LODKIT" info --json "$TMP/cow-welded.obj")
check "cow welded" grep -q '"vertices":2903,"triangles":5804' <<<"$out"
expect_exit 0 "$LODKIT" convert --quiet --ascii "$LK_SAMPLES_DIR/cow.off" "$TMP/cow-ascii.ply"
check "ascii ply" grep -q "format ascii" "$TMP/cow-ascii.ply"
expect_exit 0 "$LODKIT" convert --quiet "$LK_SAMPLES_DIR/kitten.xyz" "$TMP/kitten.ply"
out=$("$LODKIT" info --json "$TMP/kitten.ply")
check "point set via ply" grep -q '"triangles":0' <<<"$out"
# a failed conversion leaves no output file behind
expect_exit 1 "$LODKIT" convert --quiet "$TMP/bad.off" "$TMP/never.ply"
check "no partial output" test ! -e "$TMP/never.ply"
check "no temp files left" test -z "$(ls -A "$TMP" | grep tmp- || true)"


# Every error names its file (issue 17): content refusals of the algorithms
# and .lks decoder errors, not only the readers' own messages.
# expect_error_line TEXT COMMAND...: exit 1 and stderr has "lodkit: TEXT"
expect_error_line() {
  local text="$1"; shift
  checks=$((checks + 1))
  local err code
  err=$("$@" 2>&1 >/dev/null); code=$?
  if [ "$code" -ne 1 ] || ! grep -qF -- "lodkit: $text" <<<"$err"; then
    echo "FAIL: exit $code, stderr '$err' lacks 'lodkit: $text': $*"; failures=$((failures + 1))
  fi
}
printf 'v 0 0 0\nv 1 0 0\nv 2 1 0\n' >"$TMP/points.obj"
expect_error_line "$TMP/points.obj: cannot simplify a point set" "$LODKIT" simplify -r 0.5 "$TMP/points.obj" "$TMP/o.obj"
printf 'v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 2\nf 1 1 3\n' >"$TMP/degenerate.obj"
expect_error_line "$TMP/degenerate.obj: every triangle is degenerate" "$LODKIT" simplify -r 0.5 "$TMP/degenerate.obj" "$TMP/o.obj"
printf 'P2\n3 3\n9\n1 2 3\n4 5 6\n7 8 9\n' >"$TMP/small.pgm"
expect_error_line "$TMP/small.pgm: terrain: a 3x3 grid is too small" "$LODKIT" terrain "$TMP/small.pgm"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n' >"$TMP/flat.obj"
expect_error_line "$TMP/flat.obj: the mesh is flat along z" "$LODKIT" simplify -m wavelet -r 0.5 "$TMP/flat.obj" "$TMP/o.obj"
# A damaged chunk table, in each stream version (the CRC's offset follows the table).
"$LODKIT" progressive -q --stream-version=1 "$LK_SAMPLES_DIR/cow.off" "$TMP/cow.lks"
printf '\007' | dd of="$TMP/cow.lks" bs=1 seek=200 conv=notrunc 2>/dev/null  # inside the chunk table
expect_error_line "$TMP/cow.lks: chunk table at byte 224: CRC-32 mismatch" "$LODKIT" unpack "$TMP/cow.lks" "$TMP/o.obj"
expect_error_line "$TMP/cow.lks: chunk table at byte 224: CRC-32 mismatch" "$LODKIT" inspect "$TMP/cow.lks"
"$LODKIT" progressive -q "$LK_SAMPLES_DIR/cow.off" "$TMP/cow2.lks"
printf '\007' | dd of="$TMP/cow2.lks" bs=1 seek=200 conv=notrunc 2>/dev/null  # inside version 2's chunk table
expect_error_line "$TMP/cow2.lks: chunk table at byte 384: CRC-32 mismatch" "$LODKIT" unpack "$TMP/cow2.lks" "$TMP/o.obj"
expect_error_line "$TMP/cow2.lks: chunk table at byte 384: CRC-32 mismatch" "$LODKIT" inspect "$TMP/cow2.lks"

finish
