#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `lodkit terrain` over the real etopo20 grid: crack elimination, geomorphing,
# JSON summary, pictures, clear errors on bad grids.
set -u
source "$(dirname "$0")/lib.sh"
etopo="$LK_SAMPLES_DIR/etopo20.cdf"
obj() { grep -o "\"$1\":{[^}]*}" | grep -o "\"$2\":[-0-9.e+]*" | cut -d: -f2; }
within() { awk -v v="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(v >= lo && v <= hi) }'; }

expect_exit 0 "$LODKIT" terrain --help
expect_exit 2 "$LODKIT" terrain --cracks=some "$etopo"
expect_exit 2 "$LODKIT" terrain --flight=0 "$etopo"

full=$("$LODKIT" terrain --json --flight=60 --grid-size=513 "$etopo")
none=$("$LODKIT" terrain --json --flight=60 --grid-size=513 --cracks=none "$etopo")
midpoint=$("$LODKIT" terrain --json --flight=60 --grid-size=513 --cracks=midpoint "$etopo")
nomorph=$("$LODKIT" terrain --json --flight=60 --grid-size=513 --no-morph "$etopo")
check "full: no crack on any frame" test "$(obj cracks max <<<"$full")" = 0
check "none: cracks ($(obj cracks max <<<"$none"))" within "$(obj cracks max <<<"$none")" 1 1e9
check "midpoint: fewer cracks than none" awk -v a="$(obj cracks total <<<"$midpoint")" \
  -v b="$(obj cracks total <<<"$none")" 'BEGIN { exit !(a > 0 && a < b) }'
check "morphing pops at least 3x less" awk -v a="$(obj popping max <<<"$full")" \
  -v b="$(obj popping max <<<"$nomorph")" 'BEGIN { exit !(3 * a <= b) }'
check "triangles in a sensible band" within "$(obj triangles median <<<"$full")" 3000 20000
"$LODKIT" terrain -q --flight=10 --grid-size=257 --png="$TMP/pictures" --csv="$TMP/flight.csv" "$etopo"
check "map pictures written" test -s "$TMP/pictures/map_0000.png"
check "CSV has a row per frame" test "$(wc -l < "$TMP/flight.csv")" -eq 11

# a hand-made 16-bit PGM heightmap works; broken grids are refused clearly
printf 'P2\n5 5\n65535\n' > "$TMP/hill.pgm"
for j in 0 1 2 3 4; do echo "0 1000 4000 1000 0"; done >> "$TMP/hill.pgm"
expect_exit 0 "$LODKIT" terrain -q --flight=5 "$TMP/hill.pgm"
printf 'P5\n4 4\n255\nab' > "$TMP/short.pgm"
expect_exit 1 "$LODKIT" terrain "$TMP/short.pgm"
expect_output_contains "byte" "$LODKIT" terrain "$TMP/short.pgm"
expect_exit 1 "$LODKIT" terrain "$LK_SAMPLES_DIR/cow.off"
# GDAL is loaded when a grid needs it, not linked: the command starts
# without it, and says what to install when it cannot be loaded.
check "lodkit does not load gdal at start" bash -c '! ldd "$1" | grep -qi gdal' _ "$LODKIT"
out=$(LODKIT_GDAL_LIBRARY="$TMP/missing/libgdal.so" "$LODKIT" terrain --flight=2 "$etopo" 2>&1); code=$?
check "no GDAL: exit 1 (got $code)" test "$code" = 1
check "no GDAL: the message says what to install ($out)" grep -q "needs GDAL, which could not be loaded from .*missing/libgdal.so.*Debian package libgdal" <<<"$out"
expect_exit 1 "$LODKIT" terrain "$TMP/missing.tif"
finish
