#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The CLI of issue 18: every --help generated from the option declarations
# (every declared option shown, no literal %%, 80 columns), one meaning per
# flag across commands (old spellings refused with the new one named),
# and what a new user met: .lks and elevation grids given to mesh commands,
# info on a grid, md2 outputs, unpack --level past the end, plurals, and a
# progress bar on a terminal for the long commands.
set -u
source "$(dirname "$0")/lib.sh"
S="$LK_SAMPLES_DIR"
commands=(info convert metro simplify subdivide progressive unpack inspect render sample splat terrain slices animate serve formats)

# ---- help: generated from the declarations --------------------------------
# The declarations, read from cli/cli_options.c itself: "command option" per line.
python3 - "$LK_SOURCE_DIR/cli/cli_options.c" "$LK_SOURCE_DIR/cli/cli.h" >"$TMP/declared.txt" <<'EOF'
import re, sys
source, header = open(sys.argv[1]).read(), open(sys.argv[2]).read()
ids = re.search(r"typedef enum cli_command_id \{(.*?)\}", header, re.S).group(1)
names = [n.strip() for n in re.sub(r"/\*.*?\*/", "", ids).split(",") if n.strip()]
values = {name: index for index, name in enumerate(names)}
def value(expression):
    expression = re.sub(r"/\*.*?\*/", "", expression).replace("1u", "1")
    return eval(re.sub(r"\b[A-Z_]+\b", lambda m: str(values[m.group(0)]), expression))
bits = source.split("const cli_option cli_options")[0]
bits = re.search(r"enum \{(.*?)\};", bits[bits.index("Command bits"):], re.S).group(1)
for entry in re.sub(r"/\*.*?\*/", "", bits).split(","):
    name, expression = entry.split("=")
    values[name.strip()] = value(expression)
table = source.split("const cli_option cli_options")[1].split("};")[0]
declarations = re.findall(r'\[OPT_[A-Z_]+\] = \{"([a-z-]+)", (?:0|\'.\'), (?:NULL|"[^"]*"),\s*([A-Z_ |&~()]+),', table)
if len(declarations) != len(re.findall(r"\n\s+\[OPT_", table)): sys.exit("read %d declarations only" % len(declarations))
for name, mask in declarations:
    for index, command in enumerate(names[:names.index("CMD_MAIN")]):
        if value(mask) >> index & 1: print(command[4:].lower(), name)
EOF
check "the declarations were read ($(wc -l <"$TMP/declared.txt") pairs)" test "$(wc -l <"$TMP/declared.txt")" -gt 150
for command in "${commands[@]}"; do
  "$LODKIT" $command --help >"$TMP/help-$command.txt" 2>&1
  check "$command --help: exit 0" test $? -eq 0
  check "$command --help: usage line" grep -qE "^Usage: lodkit $command \[options\]( |\$)" "$TMP/help-$command.txt"
  check "$command --help: no literal %%" bash -c "! grep -qF '%%' '$TMP/help-$command.txt'"
  check "$command --help: 80 columns" bash -c "! grep -qE '^.{81}' '$TMP/help-$command.txt'"
  while read -r declared option; do
    [ "$declared" = "$command" ] || continue
    check "$command --help shows --$option" grep -qE "^  (-[a-zA-Z], |    )--$option([=[]|\$| )" "$TMP/help-$command.txt"
  done <"$TMP/declared.txt"
  expect_exit 0 "$LODKIT" $command -h
done
"$LODKIT" --help >"$TMP/help-main.txt"
for command in "${commands[@]}"; do check "--help lists $command" grep -qE "^  $command " "$TMP/help-main.txt"; done
check "--help: --max-memory" grep -q -- "--max-memory=SIZE" "$TMP/help-main.txt"
check "--help: no literal %%" bash -c "! grep -qF '%%' '$TMP/help-main.txt'"
# one letter, one long name (and one argument name) in every command
cat "$TMP"/help-*.txt | grep -oE '^  -[a-zA-Z], --[a-z-]+(=[^ ]+)?' | sort -u >"$TMP/letters.txt"
check "each short letter means one option: $(tr '\n' ' ' <"$TMP/letters.txt")" \
  test "$(cut -c3-4 "$TMP/letters.txt" | sort | uniq -d | wc -l)" -eq 0
cat "$TMP"/help-*.txt | grep -oE '^  (-[a-zA-Z], |    )--[a-z-]+(=[^ ]+|\[=[^ ]+\])?' | sed 's/^  \(-., \|    \)//' |
  sort -u >"$TMP/longs.txt"
check "each long option takes one argument name: $(cut -d= -f1 "$TMP/longs.txt" | sed 's/\[$//' | uniq -d | tr '\n' ' ')" \
  test "$(sed 's/\[\?=.*//' "$TMP/longs.txt" | uniq -d | wc -l)" -eq 0

# ---- one meaning per flag: the old spellings are refused and say the new one
refused() {  # refused NEW-SPELLING COMMAND...: exit 2 and the message names the new spelling
  local new="$1"; shift
  "$@" >"$TMP/out.txt" 2>"$TMP/err.txt"
  local code=$?
  check "$* : exit 2 (got $code)" test $code -eq 2
  check "$* : names $new ($(head -1 "$TMP/err.txt"))" grep -qF -- "$new" "$TMP/err.txt"
}
refused --vertices "$LODKIT" simplify -v 100 "$S/cow.off" "$TMP/v.obj"
refused --vertices "$LODKIT" slices -v 100 "$S/cow.off" "$TMP/v.svg"
refused --slices "$LODKIT" slices -n 12 "$S/cow.off" "$TMP/v.svg"
refused --iterations "$LODKIT" subdivide -n 2 "$S/cow.off" "$TMP/v.obj"
refused --scheme "$LODKIT" subdivide -s midpoint "$S/cow.off" "$TMP/v.obj"
refused --scheme "$LODKIT" animate -s all "$S/faerie.md2" "$TMP/v"
refused --levels "$LODKIT" animate -l 3 "$S/faerie.md2" "$TMP/v"
refused --samples-per-face "$LODKIT" animate --samples=3 "$S/faerie.md2" "$TMP/v"
refused --bytes "$LODKIT" unpack -b 4000 "$TMP/none.lks" "$TMP/v.obj"
refused --bandwidth-levels "$LODKIT" progressive --levels=4 "$S/cow.off" "$TMP/v.lks"
refused --grid-size "$LODKIT" terrain --size=257 "$S/etopo20.cdf"
refused --no-frustum-culling "$LODKIT" terrain --no-culling "$S/etopo20.cdf"
refused --cell-size "$LODKIT" simplify -m uniform --max-error=5 "$S/cow.off" "$TMP/v.obj"
refused --max-error "$LODKIT" simplify -m qem --cell-size=5 "$S/cow.off" "$TMP/v.obj"
refused "is ambiguous" "$LODKIT" simplify --no "$S/cow.off" "$TMP/v.obj"
refused "unknown option '--bogus'" "$LODKIT" render --bogus "$S/cow.off" -o "$TMP/v.png"
refused "needs an argument (WxH)" "$LODKIT" render "$S/cow.off" -o "$TMP/v.png" --size
refused "--up: 'w' is not x, y or z" "$LODKIT" render --up=w "$S/cow.off" -o "$TMP/v.png"
check "nothing written by the refusals" test -z "$(ls "$TMP" | grep '^v\.')"
# the new spellings work, and the aliases kept
"$LODKIT" simplify -q --vertices=200 "$S/cow.off" "$TMP/200.obj"
check "simplify --vertices=200" grep -qE '"vertices":(19[0-9]|200)\b' <("$LODKIT" info --json "$TMP/200.obj")
"$LODKIT" simplify -q -m uniform --cell-size=5 "$S/cow.off" "$TMP/cells.obj"
check "simplify -m uniform --cell-size" test -s "$TMP/cells.obj"
expect_exit 0 "$LODKIT" subdivide -q --scheme=midpoint --iterations=1 "$S/cow.off" "$TMP/mid.obj"
expect_exit 0 "$LODKIT" sample -q -n 500 --neighbors=4 "$S/cow.off" "$TMP/points.ply"
check "sample -n 500: 500 points" grep -q '^element vertex 500' <(head -c 300 "$TMP/points.ply")
expect_exit 0 "$LODKIT" terrain -q --flight=2 --grid-size=129 --error=40 --no-frustum-culling "$S/etopo20.cdf"
expect_exit 0 "$LODKIT" progressive -q --stream-version=1 --bandwidth-levels=4 "$S/cow.off" "$TMP/cow.lks"
# --weld wherever a mesh is read: a triangle soup (every corner its own vertex)
awk 'NF == 0 || /^OFF/ { next } !counted { nv = $1; counted = 1; next } seen < nv { v[seen++] = $1 " " $2 " " $3; next }
     $1 == 3 { for (k = 2; k <= 4; k++) print "v " v[$k]; n += 3; print "f " n - 2, n - 1, n }' \
  "$S/cow.off" >"$TMP/soup.obj"
soup=$("$LODKIT" info --json "$TMP/soup.obj" | grep -oE '"vertices":[0-9]+' | cut -d: -f2)
welded=$("$LODKIT" info --json --weld "$TMP/soup.obj" | grep -oE '"vertices":[0-9]+' | cut -d: -f2)
check "info --weld merges the corners ($soup -> $welded)" test "$soup" -eq 17412 -a "$welded" -lt 2905
expect_output_contains "soup.obj: $(printf '%s' "$welded" | sed 's/\(.\)\(...\)$/\1,\2/') vertices" \
  "$LODKIT" simplify --weld -r 0.5 "$TMP/soup.obj" "$TMP/w.obj"
# --up: the camera orbits another axis
if "$LODKIT" render -q -s 64x64 "$S/cow.off" -o "$TMP/y.png" 2>/dev/null; then
  "$LODKIT" render -q -s 64x64 --up=z "$S/cow.off" -o "$TMP/z.png"
  check "render --up=z draws another picture" bash -c "! cmp -s '$TMP/y.png' '$TMP/z.png'"
  "$LODKIT" render -q -s 64x64 --up=y "$S/cow.off" -o "$TMP/y2.png"
  check "render --up=y is the default" cmp -s "$TMP/y.png" "$TMP/y2.png"
  expect_exit 0 "$LODKIT" splat -q -s 64x64 -n 2000 --up=x --background=0,0,0 --flat "$S/cow.off" -o "$TMP/splat.png"
  # splat shares render's camera: a Z-up scan stands up with --up=z
  "$LODKIT" splat -q -s 64x64 -n 2000 "$S/cow.off" -o "$TMP/splat_y.png"
  "$LODKIT" splat -q -s 64x64 -n 2000 --up=z "$S/cow.off" -o "$TMP/splat_z.png"
  check "splat --up=z draws another picture" bash -c "! cmp -s '$TMP/splat_y.png' '$TMP/splat_z.png'"
  "$LODKIT" splat -q -s 64x64 -n 2000 --up=y "$S/cow.off" -o "$TMP/splat_y2.png"
  check "splat --up=y is the default" cmp -s "$TMP/splat_y.png" "$TMP/splat_y2.png"
fi

# ---- what a new user met ------------------------------------------------------
"$LODKIT" info "$S/etopo20.cdf" >"$TMP/grid.txt" 2>&1
check "info on a netCDF grid: exit 0" test $? -eq 0
check "info on a grid: its size" grep -qE '^samples +1,081 x 540 ' "$TMP/grid.txt"
check "info on a grid: its heights" grep -qE '^heights +-9026.6.* \.\. 6228.8.* m$' "$TMP/grid.txt"
check "info --json on a grid" grep -q '"format":"grid","width":403,"height":344' <("$LODKIT" info --json "$S/jacksboro_fault_dem.npz")
expect_output_contains "elevation grid 403 x 344" "$LODKIT" info "$S/cow.off" "$S/jacksboro_fault_dem.npz"
for command in info render metro; do
  case $command in
    info) args=("$TMP/cow.lks") ;; render) args=("$TMP/cow.lks" -o "$TMP/x.png") ;; metro) args=("$TMP/cow.lks" "$S/cow.off") ;;
  esac
  "$LODKIT" $command "${args[@]}" >/dev/null 2>"$TMP/err.txt"
  check "$command on a .lks: exit 1" test $? -eq 1
  check "$command on a .lks points to inspect and unpack: $(cat "$TMP/err.txt")" \
    grep -q "progressive stream.*lodkit inspect.*lodkit unpack" "$TMP/err.txt"
done
cp "$TMP/cow.lks" "$TMP/renamed.bin"
expect_output_contains "lodkit inspect" "$LODKIT" info "$TMP/renamed.bin"
expect_output_contains "'lodkit terrain' flies over it" "$LODKIT" render "$S/etopo20.cdf" -o "$TMP/x.png"
for out in x.md2 x.kmf; do
  "$LODKIT" convert "$S/cow.off" "$TMP/$out" 2>"$TMP/err.txt"
  check "convert to $out: exit 2" test $? -eq 2
  check "convert to $out points to lodkit animate" grep -q "lodkit animate" "$TMP/err.txt"
  check "convert to $out: no library function named" bash -c "! grep -q lk_animation_write '$TMP/err.txt'"
done
expect_exit 2 "$LODKIT" simplify -r 0.5 "$S/faerie.md2" "$TMP/x.md2"
# unpack --level past the end: refused, not clamped
splits=$("$LODKIT" inspect --json "$TMP/cow.lks" | grep -oE '"splits":[0-9]+' | head -1 | cut -d: -f2)
"$LODKIT" unpack --level 99999999 "$TMP/cow.lks" "$TMP/far.obj" 2>"$TMP/err.txt"
check "unpack --level 99999999: exit 2" test $? -eq 2
check "unpack --level 99999999: says the levels ($(head -1 "$TMP/err.txt"))" \
  grep -qE "cow.lks has [0-9,]+ vertex splits, levels 0 to [0-9,]+$" "$TMP/err.txt"
check "unpack --level 99999999: nothing written" test ! -e "$TMP/far.obj"
expect_exit 0 "$LODKIT" unpack -q --level "$splits" "$TMP/cow.lks" "$TMP/last.obj"
# plurals
expect_output_contains ", 1 chunk -> " "$LODKIT" unpack --level 0 "$TMP/cow.lks" "$TMP/base.obj"
expect_output_contains ", 1 chunk, " "$LODKIT" progressive --base-ratio=1 "$S/cow.off" "$TMP/one.lks"
expect_output_contains "the one chunk present" "$LODKIT" inspect "$TMP/one.lks"
expect_output_contains "for 1 level," "$LODKIT" animate --ratio=0.5 --no-metro "$S/faerie.md2" "$TMP/one-level"
expect_output_contains "flight: 1 frame at" "$LODKIT" terrain --flight=1 --grid-size=129 "$S/etopo20.cdf"

# ---- progress on a terminal (script gives the command one), not elsewhere ----
require script util-linux
on_terminal() { script -qefc "$(printf '%q ' "$@")" /dev/null; }
on_terminal "$LODKIT" sample --poisson -n 20000 "$S/bunny.obj" "$TMP/poisson.ply" >"$TMP/tty.txt" 2>&1
check "sample --poisson: progress while it weighs the samples" grep -qE 'sample poisson +\[#* *\] +(2[1-9]|3[0-9]|4[0-9])\.' "$TMP/tty.txt"
on_terminal "$LODKIT" progressive --stream-version=1 "$S/bunny.obj" "$TMP/bunny.lks" >"$TMP/tty.txt" 2>&1
for stage in simplify splits strips encode "strip bandwidth"; do
  check "progressive v1: stage $stage shown" grep -q "progressive $stage" "$TMP/tty.txt"
done
on_terminal "$LODKIT" progressive "$S/bunny.obj" "$TMP/bunny2.lks" >"$TMP/tty.txt" 2>&1
for stage in simplify splits encode; do
  check "progressive: stage $stage shown" grep -q "progressive $stage" "$TMP/tty.txt"
done
on_terminal "$LODKIT" terrain --flight=30 --grid-size=257 "$S/etopo20.cdf" >"$TMP/tty.txt" 2>&1
for stage in reading quadtree flight; do check "terrain: stage $stage shown" grep -q "terrain $stage" "$TMP/tty.txt"; done
on_terminal "$LODKIT" info "$S/etopo20.cdf" >"$TMP/tty.txt" 2>&1
check "info on a grid: reading progress" grep -q "info reading" "$TMP/tty.txt"
on_terminal "$LODKIT" animate --levels=2 --metro-step=50 "$S/faerie.md2" "$TMP/anim" >"$TMP/tty.txt" 2>&1
check "animate: metro advances within a level" grep -qE 'metro metro +\[#* *\] +(1[0-9]|2[0-9]|3[0-9]|4[0-8])\.' "$TMP/tty.txt"
on_terminal "$LODKIT" progressive -q "$S/cow.off" "$TMP/quiet.lks" >"$TMP/tty.txt" 2>&1
check "--quiet: no progress on a terminal" test ! -s "$TMP/tty.txt"
"$LODKIT" sample --poisson -n 20000 "$S/cow.off" "$TMP/poisson.ply" >/dev/null 2>"$TMP/err.txt"
check "no progress when stderr is not a terminal" test ! -s "$TMP/err.txt"

finish
