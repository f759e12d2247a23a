#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `lodkit animate` on faerie.md2: a 3-level set per scheme written as MD2,
# read back with the right frame and triangle counts, the CSV (header,
# one row per level and measured frame, rms_percent consistent with rms),
# the heat maps (PNG signature), JSON numbers, --ratio, --strict, usage
# and input errors; OUTDIR replaced whole, and refused when it holds what
# animate did not write (the swap itself: tests/cli/test_cli_kill.sh).
set -u
source "$(dirname "$0")/lib.sh"
faerie="$LK_SAMPLES_DIR/faerie.md2"
num() { grep -o "\"$1\":[-0-9.e+]*" | head -1 | cut -d: -f2; }
within() { awk -v v="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(v >= lo && v <= hi) }'; }

expect_exit 0 "$LODKIT" animate --help
expect_output_contains "--scheme" "$LODKIT" animate --help
expect_exit 2 "$LODKIT" animate "$faerie"                                 # no OUTDIR
expect_exit 2 "$LODKIT" animate --scheme=median "$faerie" "$TMP/a"
expect_exit 2 "$LODKIT" animate --levels=0 "$faerie" "$TMP/a"
expect_exit 2 "$LODKIT" animate --ratio=1.5 "$faerie" "$TMP/a"
expect_exit 2 "$LODKIT" animate --scheme=frame --frame=198 "$faerie" "$TMP/a"
expect_exit 1 "$LODKIT" animate "$TMP/missing.md2" "$TMP/a"
printf 'IDP2 not really' > "$TMP/broken.md2"
expect_exit 1 "$LODKIT" animate "$TMP/broken.md2" "$TMP/a"

# three levels (33%, 67%, 100%) for every scheme, every 20th frame measured
out="$TMP/faerie"
json=$("$LODKIT" animate --json --scheme=all --levels=3 --metro-step=20 "$faerie" "$out")
check "animate --json exit 0" test $? -eq 0
for scheme in max avg frame0; do
  for level in 01 02 03; do
    check "$scheme level $level written" test -s "$out/faerie-$scheme-L$level.md2"
  done
  check "$scheme csv written" test -s "$out/faerie-$scheme.csv"
  check "$scheme png is a PNG" sh -c "head -c 8 '$out/faerie-$scheme-rms.png' | od -An -tx1 | grep -q '89 50 4e 47 0d 0a 1a 0a'"
  csv="$out/faerie-$scheme.csv"
  check "$scheme csv header" sh -c "head -1 '$csv' | grep -qx 'level,ratio,frame,triangles,mean,rms,max,rms_forward,rms_backward,rms_percent'"
  # 3 levels x 10 measured frames (0, 20, ..., 180) + header
  check "$scheme csv rows ($(wc -l <"$csv"))" test "$(wc -l <"$csv")" -eq 31
  # level 3 keeps every triangle: zero distance
  check "$scheme full level exact" awk -F, 'NR > 1 && $1 == 3 && ($6 > 1e-4 || $4 != 654) { bad = 1 } END { exit bad }' "$csv"
  # level 1: a third of the triangles, error between 0.05% and 2% of the diagonal
  check "$scheme level 1 error plausible" awk -F, 'NR > 1 && $1 == 1 && ($10 < 0.05 || $10 > 2 || $4 > 218) { bad = 1 } END { exit bad }' "$csv"
done
for scheme in max avg frame0; do
  check "json names scheme $scheme" grep -q "\"scheme\":\"$scheme\"" <<<"$json"
done
check "json frames 198 ($(num frames <<<"$json"))" test "$(num frames <<<"$json")" = 198
worst=$(num worst_rms_percent <<<"$json")
check "json max level 1 worst rms ($worst) in [0.3, 1]" within "$worst" 0.3 1

# the written MD2 reads back as an animation of the kept triangles
"$LODKIT" info "$out/faerie-max-L01.md2" >"$TMP/info.txt" 2>&1
check "level file readable as a mesh" test $? -eq 0

# --ratio writes one animation, no level suffix; --strict stops at the fold floor
"$LODKIT" animate -q --ratio=0.5 --no-metro "$faerie" "$TMP/r"
check "--ratio output" test -s "$TMP/r/faerie-max.md2"
check "--no-metro writes no csv" test ! -e "$TMP/r/faerie-max.csv"
strict=$("$LODKIT" animate --json --strict --ratio=0.1 --no-metro "$faerie" "$TMP/s")
check "--strict misses 10% (fold floor)" grep -q '"target_reached":false' <<<"$strict"
folds=$("$LODKIT" animate --json --ratio=0.1 --no-metro "$faerie" "$TMP/f")
check "default allows folds below the floor ($(num folds_from_triangles <<<"$folds"))" \
  within "$(num folds_from_triangles <<<"$folds")" 150 260

# --lost-surface: 0 is the paper's cost alone; the default (300) keeps faerie
# closer at 50% (measured on every 10th frame: 0.17% against 0.24% of the diagonal)
expect_exit 2 "$LODKIT" animate --lost-surface=-1 "$faerie" "$TMP/a"
expect_exit 2 "$LODKIT" animate --lost-surface=nan "$faerie" "$TMP/a"
expect_output_contains "--lost-surface" "$LODKIT" animate --help
with=$("$LODKIT" animate --json --ratio=0.5 --metro-step=10 --samples-per-face=3 "$faerie" "$TMP/lost")
without=$("$LODKIT" animate --json --ratio=0.5 --metro-step=10 --samples-per-face=3 --lost-surface=0 "$faerie" "$TMP/paper")
w_with=$(num worst_rms_percent <<<"$with")
w_without=$(num worst_rms_percent <<<"$without")
check "lost surface lowers the worst frame at 50% ($w_with < 0.85 x $w_without)" \
  awk -v a="$w_with" -v b="$w_without" 'BEGIN { exit !(a > 0 && a < 0.85 * b) }'

# OUTDIR belongs to animate and is replaced whole: a 2-level set replaces a
# 3-level one without leaving level 3 behind, and the manifest lists the set.
p="$TMP/sets"
mkdir -p "$p"
"$LODKIT" animate -q --levels=3 --no-metro "$faerie" "$p/set"
check "3-level set written" test -s "$p/set/faerie-max-L03.md2"
"$LODKIT" animate -q --levels=2 --metro-step=99 --samples-per-face=1 "$faerie" "$p/set"
check "2-level set: exit 0" test $? -eq 0
check "the 2-level set replaced the 3-level one: $(ls -A "$p/set" | tr '\n' ' ')" \
  test "$(ls -A "$p/set" | tr '\n' ' ')" = ".lodkit-animate faerie-max-L01.md2 faerie-max-L02.md2 faerie-max-rms.png faerie-max.csv "
check "the manifest lists the set" \
  test "$(tail -n +2 "$p/set/.lodkit-animate" | sort | tr '\n' ' ')" = "faerie-max-L01.md2 faerie-max-L02.md2 faerie-max-rms.png faerie-max.csv "
check "nothing left beside the set: $(ls -A "$p" | tr '\n' ' ')" test "$(ls -A "$p")" = set

# Anything in OUTDIR that animate did not write is refused before any work
# (under a file-size limit that would fail the first write: the refusal
# comes first), and nothing changes: a folder at an output name, a file of
# the user's, a set from a lodkit without manifests, a plain file as OUTDIR.
# refused DESCRIPTION OUTDIR MESSAGE [IN]: animate into OUTDIR exits 1 with
# MESSAGE, and OUTDIR and what is beside it are as they were.
refused() {
  local description=$1 dir=$2 message=$3 input=${4:-$faerie} before
  before=$(cd "$(dirname "$dir")" && ls -lAR --time-style=+%s.%N . | md5sum)
  (trap '' XFSZ; ulimit -f 16; exec "$LODKIT" animate -q --levels=2 --metro-step=66 --samples-per-face=1 --keep-seams \
      "$input" "$dir") 2>"$TMP/err.txt"
  check "$description: exit 1 ($?)" test $? -eq 1
  check "$description: refused: $(head -1 "$TMP/err.txt")" grep -qF "$message" "$TMP/err.txt"
  check "$description: nothing changed" test "$(cd "$(dirname "$dir")" && ls -lAR --time-style=+%s.%N . | md5sum)" = "$before"
}
rm "$p/set/faerie-max-rms.png"
mkdir "$p/set/faerie-max-rms.png"
cp -a "$p/set" "$TMP/set-before"
refused "a folder at an output name" "$p/set" \
  "$p/set holds files lodkit animate did not write (faerie-max-rms.png/); animate replaces the whole folder: use a new or empty folder"
check "a folder at an output name: the set's files unchanged" diff -r "$p/set" "$TMP/set-before"
rmdir "$p/set/faerie-max-rms.png"
echo "my notes" >"$p/set/notes.txt"
refused "a file of the user's in a set" "$p/set" "$p/set holds files lodkit animate did not write (notes.txt); animate"
check "the user's file untouched" test "$(cat "$p/set/notes.txt")" = "my notes"
mkdir "$p/mine"
echo "my notes" >"$p/mine/notes.txt"
touch "$p/mine/a.md2" "$p/mine/b.md2" "$p/mine/c.md2"
refused "a folder of the user's" "$p/mine" "$p/mine holds files lodkit animate did not write ("
check "the refusal names at most 3 entries: $(head -1 "$TMP/err.txt")" grep -qF ", ...); animate replaces" "$TMP/err.txt"
cp -r "$TMP/set-before" "$p/old-layout"
rm -r "$p/old-layout/.lodkit-animate" "$p/old-layout/faerie-max-rms.png"
refused "a set without a manifest" "$p/old-layout" "$p/old-layout holds files lodkit animate did not write (faerie-max"
echo "not a folder" >"$p/file"
refused "a file as OUTDIR" "$p/file" "$p/file: exists and is not a folder"

# The manifest lists one name a line: an input name with a line break is
# refused before any work.
cp "$faerie" "$TMP/line"$'\n'"break.md2"
refused "a name with a line break" "$p/lines" "a name with a line break cannot be listed in the output set" \
  "$TMP/line"$'\n'"break.md2"
check "a name with a line break: no OUTDIR" test ! -e "$p/lines"

# An existing empty folder takes the set and keeps its permissions; a
# symbolic link to a set keeps pointing at the folder, which gets the new set.
mkdir -m 750 "$p/empty"
"$LODKIT" animate -q --ratio=0.5 --no-metro "$faerie" "$p/empty"
check "empty folder: exit 0" test $? -eq 0
check "empty folder: the set in it" test -s "$p/empty/faerie-max.md2"
check "empty folder: mode kept ($(stat -c %a "$p/empty"))" test "$(stat -c %a "$p/empty")" = 750
ln -s empty "$p/link"
"$LODKIT" animate -q --ratio=0.25 --no-metro "$faerie" "$p/link/"
check "link to a set: exit 0" test $? -eq 0
check "link to a set: still a link" test -L "$p/link"
check "link to a set: the new set in its folder" cmp -s "$p/empty/faerie-max.md2" "$p/link/faerie-max.md2"
"$LODKIT" animate -q --ratio=0.25 --no-metro "$faerie" "$TMP/q4"
check "link to a set: the 25% set" cmp -s "$TMP/q4/faerie-max.md2" "$p/empty/faerie-max.md2"
check "link to a set: mode kept ($(stat -c %a "$p/empty"))" test "$(stat -c %a "$p/empty")" = 750

finish
