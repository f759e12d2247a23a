#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The viewer's octree view in a real browser (issue 23): the bunny sampled
# into 400,000 oriented points, built into an octree of 5,000-point leaves,
# served by `lodkit serve`; tests/browser/octree.test.mjs opens it in
# Debian's /usr/bin/chromium (headless, SwiftShader WebGL) through npm
# playwright-core and checks first points within 1 s, nodes by Range, the
# point budget held while flying, and the controls. The server log must show
# the data file answered with 206. Needs what test_browser.sh needs.
set -u
source "$(dirname "$0")/lib.sh"
source "$(dirname "$0")/lib_serve.sh"
require_browser

root="$TMP/root"
mkdir -p "$root"
"$LODKIT" sample -q --points=400000 "$LK_SAMPLES_DIR/bunny.obj" "$TMP/bunny.ply" || { echo "FAIL: lodkit sample"; exit 1; }
"$LODKIT" octree -q --node-points 5000 "$TMP/bunny.ply" "$root/bunny_octree" || { echo "FAIL: lodkit octree"; exit 1; }
# small enough to load whole (adaptive radii with every node drawn)
"$LODKIT" sample -q --points=40000 "$LK_SAMPLES_DIR/bunny.obj" "$TMP/small.ply" || { echo "FAIL: lodkit sample"; exit 1; }
"$LODKIT" octree -q --node-points 2000 "$TMP/small.ply" "$root/bunny_octree_small" || { echo "FAIL: lodkit octree"; exit 1; }

start_serve "$root"

checks=$((checks + 1))
if ! (cd "$browser_dir" && timeout -k 5 110 node octree.test.mjs "$url" bunny_octree 400000 ${LK_TEST_SHOTS:+"$LK_TEST_SHOTS"}); then
  echo "FAIL: octree browser tests (server log tail below)"
  tail -n 20 "$TMP/serve.log"
  failures=$((failures + 1))
fi
stop_server
check "the data file was served by Range (206)" grep -q '"GET /m/bunny_octree/octree.bin" 206' "$TMP/serve.log"
finish
