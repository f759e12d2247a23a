#!/bin/bash
# SPDX-License-Identifier: MIT
# lodkit octree (src/octree.c, cli/cmd_octree.c): a LAS file and a PCD into
# one octree, the summary and --json, --help, and bad inputs (a missing
# file, a cut LAS, an output folder that cannot be made, bad option values)
# refused with a message naming the file and no output left behind.
source "$(dirname "$0")/lib.sh"

S="$LK_SAMPLES_DIR"
expect_output_contains "Usage: lodkit octree [options] IN... OUTDIR" "$LODKIT" octree --help
expect_output_contains "--chunk-points" "$LODKIT" octree --help
expect_output_contains "octree" "$LODKIT" --help

check "build from LAS" "$LODKIT" octree -q "$S/las/Haystack_Rock.las" "$TMP/rock"
check "index written" test -s "$TMP/rock/octree.json"
check "data written" test -s "$TMP/rock/octree.bin"
check "no spill folder left" test "$(ls -A "$TMP/rock" | sort | tr '\n' ' ')" = "octree.bin octree.json "
expect_output_contains "21,932 points in" "$LODKIT" octree --threads 2 --chunk-points 2000 "$S/las/Haystack_Rock.las" "$TMP/rock2"
expect_output_contains '"points":21932' "$LODKIT" octree --json "$S/las/Haystack_Rock.las" "$TMP/rock3"
# same octree for 1 and 2 threads
check "1 thread" "$LODKIT" octree -q --threads 1 --chunk-points 2000 "$S/las/Haystack_Rock.las" "$TMP/rock1"
check "1 vs 2 threads: same data" cmp "$TMP/rock1/octree.bin" "$TMP/rock2/octree.bin"
check "1 vs 2 threads: same index" cmp "$TMP/rock1/octree.json" "$TMP/rock2/octree.json"
# a small cloud gets levels (the default root spacing and leaf size adapt to
# the cloud): kitten.xyz's 5,210 points were all in the root (1 level) at
# side / 128; now 3 levels, the root 236 points; --spacing still rules
expect_output_contains '"levels":3' "$LODKIT" octree --json "$S/kitten.xyz" "$TMP/kitten"
check "kitten: root spacing side / 16" grep -qE '"spacing":\s+0.067108864,' "$TMP/kitten/octree.json"
expect_output_contains '"levels":1' "$LODKIT" octree --json --spacing 0.008388608 --node-points 20000 \
  "$S/kitten.xyz" "$TMP/kitten_fine"
check "kitten: explicit spacing kept" grep -qE '"spacing":\s+0.008388608,' "$TMP/kitten_fine/octree.json"
# two inputs (a coloured PCD and a LAS without colours), a temp folder elsewhere
mkdir -p "$TMP/spill"
expect_output_contains "34,507 points in" "$LODKIT" octree --temp-dir "$TMP/spill" --node-points 5000 \
  "$S/pcd/milk.pcd" "$S/las/Haystack_Rock.las" "$TMP/both"
check "spill folder emptied" test -z "$(ls -A "$TMP/spill")"
check "colours kept" grep -q '"uint8x3"' "$TMP/both/octree.json"

# XYZ, ASCII PLY and PCD stream in bounded memory (issue 23): 200,000
# points (7.6 MB of XYZ, 5.6 MB of ASCII PLY, 7.6 MB of ascii PCD) build
# under --max-memory 1M, which refuses the same points as an OBJ (read
# whole) before reading it
awk 'BEGIN { srand(7); print "# x y z"; for (i = 0; i < 200000; i++)
  printf "%.6f %.6f %.6f\n", 500000 + rand() * 100, 4000000 + rand() * 100, rand() * 10 }' >"$TMP/big.xyz"
expect_output_contains "200,000 points in" "$LODKIT" --max-memory 1M octree "$TMP/big.xyz" "$TMP/bigxyz"
"$LODKIT" convert -q --ascii "$TMP/big.xyz" "$TMP/big.ply"
check "the PLY is ASCII" grep -q "^format ascii" <(head -c 200 "$TMP/big.ply")
expect_output_contains "200,000 points in" "$LODKIT" --max-memory 1M octree "$TMP/big.ply" "$TMP/bigply"
{ printf '# .PCD v0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 200000\nHEIGHT 1\n'
  printf 'POINTS 200000\nDATA ascii\n'; grep -v '^#' "$TMP/big.xyz"; } >"$TMP/big.pcd"
expect_output_contains "200,000 points in" "$LODKIT" --max-memory 1M octree "$TMP/big.pcd" "$TMP/bigpcd"
"$LODKIT" convert -q "$TMP/big.xyz" "$TMP/big.obj"
expect_exit 1 "$LODKIT" --max-memory 1M octree "$TMP/big.obj" "$TMP/bigobj"
expect_output_contains "more than the memory budget of 1048576 bytes (--max-memory)" \
  "$LODKIT" --max-memory 1M octree "$TMP/big.obj" "$TMP/bigobj"
printf '1 2 3\n4 5 6\n7 8\n' >"$TMP/short.xyz"
expect_output_contains "short.xyz:3: expected 3 numbers like line 1, got 2" "$LODKIT" octree "$TMP/short.xyz" "$TMP/short"
check "no output folder from a bad XYZ" test ! -e "$TMP/short"

# lodkit splat on an octree (issue 23): the nodes chosen under --budget
"$LODKIT" sample -q -n 100000 "$S/bunny.obj" "$TMP/bunny.ply" >/dev/null
check "bunny octree" "$LODKIT" octree -q --node-points 5000 "$TMP/bunny.ply" "$TMP/bunny_octree"
splat_points() { "$LODKIT" splat --json "$@" | sed -n 's/.*"points":\([0-9]*\).*/\1/p'; }
all=$(splat_points --size 400x400 "$TMP/bunny_octree" -o "$TMP/all.png")
some=$(splat_points --size 400x400 --budget 20000 "$TMP/bunny_octree/octree.json" -o "$TMP/some.png")
check "budget 1M: some points ($all)" test "${all:-0}" -gt 20000
check "budget 20000 holds ($some)" test "${some:-0}" -gt 0 -a "${some:-0}" -le 20000
check "png written" test -s "$TMP/some.png"
expect_output_contains "(budget 20,000)" "$LODKIT" splat --size 64x64 --budget 20000 "$TMP/bunny_octree" -o "$TMP/x.png"
expect_exit 1 "$LODKIT" splat --budget 10 "$TMP/bunny_octree" -o "$TMP/none.png"
expect_output_contains "below the root node's" "$LODKIT" splat --budget 10 "$TMP/bunny_octree" -o "$TMP/none.png"
check "no png from a refused budget" test ! -e "$TMP/none.png"
expect_output_contains "no normals, which splats need" "$LODKIT" splat "$TMP/rock" -o "$TMP/none.png"
expect_exit 2 "$LODKIT" splat --budget 0 "$TMP/bunny_octree" -o "$TMP/none.png"
expect_exit 2 "$LODKIT" splat --budget 1000 "$TMP/bunny.ply" -o "$TMP/none.png"

# bad inputs
expect_exit 1 "$LODKIT" octree "$TMP/missing.las" "$TMP/none"
expect_output_contains "missing.las" "$LODKIT" octree "$TMP/missing.las" "$TMP/none"
head -c 200000 "$S/las/Haystack_Rock.las" >"$TMP/cut.las"
expect_exit 1 "$LODKIT" octree "$TMP/cut.las" "$TMP/cut"
expect_output_contains "cut.las: byte 331: the header claims 21932 points" "$LODKIT" octree "$TMP/cut.las" "$TMP/cut"
check "no output folder from a cut file" test ! -e "$TMP/cut"
touch "$TMP/afile"
expect_exit 1 "$LODKIT" octree "$S/las/Haystack_Rock.las" "$TMP/afile/sub"
expect_output_contains "afile/sub" "$LODKIT" octree "$S/las/Haystack_Rock.las" "$TMP/afile/sub"
if [ "$(id -u)" != 0 ]; then
  mkdir -p "$TMP/readonly" && chmod 555 "$TMP/readonly"
  expect_exit 1 "$LODKIT" octree "$S/las/Haystack_Rock.las" "$TMP/readonly"
fi
expect_exit 2 "$LODKIT" octree "$S/las/Haystack_Rock.las"
expect_exit 2 "$LODKIT" octree --spacing -1 "$S/las/Haystack_Rock.las" "$TMP/x"
expect_exit 2 "$LODKIT" octree --threads 0 "$S/las/Haystack_Rock.las" "$TMP/x"
expect_exit 2 "$LODKIT" octree --chunk-points abc "$S/las/Haystack_Rock.las" "$TMP/x"
finish
