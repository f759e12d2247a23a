#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Acceptance of `lodkit metro` on the real bunny: distance to itself is 0,
# and to a copy moved by 1% of the diagonal it is 1% (+-0.01%) both ways.
set -u
source "$(dirname "$0")/lib.sh"
bunny="$LK_SAMPLES_DIR/bunny.obj"
num() { grep -o "\"$1\":[-0-9.e+]*" | head -1 | cut -d: -f2; }
sub() { grep -o "\"$1\":{[^}]*}" | grep -o "\"$2\":[-0-9.e+]*" | cut -d: -f2; }
within() { awk -v v="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(v >= lo && v <= hi) }'; }

self=$("$LODKIT" metro --json "$bunny" "$bunny")
for key in '"diagonal":' '"forward":{' '"backward":{' '"hausdorff":' '"samples":' '"max":' '"mean":' '"rms":'; do
  check "json has $key" grep -qF "$key" <<<"$self"
done
# Samples lie on the surface; what remains is double rounding (~1e-16).
self_ratio=$(awk -v h="$(num hausdorff <<<"$self")" -v d="$(num diagonal <<<"$self")" 'BEGIN { print h / d }')
check "bunny to itself is 0 ($self_ratio of the diagonal)" within "$self_ratio" 0 1e-12
samples=$(grep -o "\"samples\":[0-9]*" <<<"$self" | tail -1 | cut -d: -f2)
# 10 per face + every vertex + edge samples at the matching linear density
check "samples on both sides ($samples)" within "$samples" 2400000 2700000

for axis in "0.01,0,0" "0,0.01,0" "0,0,0.01"; do
  "$LODKIT" convert --quiet --translate-diagonal="$axis" "$bunny" "$TMP/moved.obj"
  moved=$("$LODKIT" metro --json "$bunny" "$TMP/moved.obj")
  diagonal=$(num diagonal <<<"$moved")
  forward=$(sub forward max <<<"$moved")
  backward=$(sub backward max <<<"$moved")
  fwd_pct=$(awk -v a="$forward" -v d="$diagonal" 'BEGIN { print 100 * a / d }')
  bwd_pct=$(awk -v a="$backward" -v d="$diagonal" 'BEGIN { print 100 * a / d }')
  check "moved $axis: forward max $fwd_pct% of diagonal" within "$fwd_pct" 0.99 1.01
  check "moved $axis: backward max $bwd_pct% of diagonal" within "$bwd_pct" 0.99 1.01
  rms_pct=$(awk -v a="$(sub forward rms <<<"$moved")" -v d="$diagonal" 'BEGIN { print 100 * a / d }')
  check "moved $axis: rms $rms_pct% below 1%" within "$rms_pct" 0.05 1.0
done

# Human-readable output and errors.
expect_output_contains "hausdorff" "$LODKIT" metro "$LK_SAMPLES_DIR/cow.off" "$LK_SAMPLES_DIR/cow.off"
printf 'v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n' > "$TMP/nan.obj"
expect_exit 1 "$LODKIT" metro "$TMP/nan.obj" "$bunny"
err=$("$LODKIT" metro "$TMP/nan.obj" "$bunny" 2>&1 >/dev/null)
check "NaN error names the file ($err)" grep -q "nan.obj" <<<"$err"
# deterministic across thread counts
one=$("$LODKIT" metro --json --threads=1 "$LK_SAMPLES_DIR/cow.off" "$LK_SAMPLES_DIR/triceratops.off" | sed 's/"seconds":[^,}]*//')
two=$("$LODKIT" metro --json --threads=2 "$LK_SAMPLES_DIR/cow.off" "$LK_SAMPLES_DIR/triceratops.off" | sed 's/"seconds":[^,}]*//')
check "same result with 1 and 2 threads" test "$one" = "$two"
finish
