#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The WebGL viewer in a real browser against `lodkit serve`: Debian's
# /usr/bin/chromium (headless, SwiftShader WebGL) driven by npm playwright-core
# (tests/browser). Serves a directory holding the bunny as a progressive
# stream (version 1, and version 2), a point set sampled from it, the
# Jacksboro DEM and a broken OBJ, then runs tests/browser/viewer.test.mjs:
# streaming (first frame from <= 10% of the bytes, refinement to all 69,666
# triangles, every byte received; version 2 decoded in the viewer's worker,
# the page's thread only uploading; how long its tasks are is measured by
# bench/stream_browser.mjs, not here), pixels of the three views, Range /
# 404 / path traversal over HTTP.
# Needs node, /usr/bin/chromium and tests/browser/node_modules, which
# scripts/install-deps.sh installs (Debian nodejs + chromium, `npm ci` from
# the lock file): without them the test says what is missing and fails. It
# never installs anything itself (no network during tests).
set -u
source "$(dirname "$0")/lib.sh"
source "$(dirname "$0")/lib_serve.sh"
require_browser

# DIR/../secret.txt must never be served: the traversal checks look for it.
root="$TMP/root"
mkdir -p "$root"
echo "lodkit-secret-$$-do-not-serve" > "$TMP/secret.txt"
# A version-1 stream (strips) on a base of 2% of the triangles: with version
# 1's default 5% the base chunk alone is 13.3% of the bunny stream (its
# full-length strip tokens are ~31 KB whatever the base size), so no client
# could draw before 10% had arrived.
"$LODKIT" progressive -q --stream-version=1 --base-ratio=0.02 "$LK_SAMPLES_DIR/bunny.obj" "$root/bunny.lks" || { echo "FAIL: lodkit progressive"; exit 1; }
# The same mesh as a stream of the default version 2 (the viewer decodes it in a worker).
"$LODKIT" progressive -q "$LK_SAMPLES_DIR/bunny.obj" "$root/bunny-v2.lks" || { echo "FAIL: lodkit progressive (version 2)"; exit 1; }
"$LODKIT" sample -q --points=50000 "$LK_SAMPLES_DIR/bunny.obj" "$root/bunny-points.ply" || { echo "FAIL: lodkit sample"; exit 1; }
cp "$LK_SAMPLES_DIR/jacksboro_fault_dem.npz" "$root/jacksboro.npz"
# A mesh the reader refuses: the viewer shows the index's message for it.
printf 'v 1 2\n' > "$root/broken.obj"
# Outside the served directory, for the decoder's roll-back check in node.
"$LODKIT" progressive -q --stream-version=1 --no-compress --chunk-splits=256 "$LK_SAMPLES_DIR/cow.off" "$TMP/cow-raw.lks" || { echo "FAIL: lodkit progressive (cow)"; exit 1; }

start_serve "$root"

checks=$((checks + 1))
if ! (cd "$browser_dir" && timeout -k 5 60 node viewer.test.mjs "$url" "$root"); then
  echo "FAIL: browser tests (server log tail below)"
  tail -n 20 "$TMP/serve.log"
  failures=$((failures + 1))
fi

kill -TERM "$server" 2>/dev/null
wait "$server"
status=$?
checks=$((checks + 1))
[ "$status" -eq 0 ] || { echo "FAIL: lodkit serve exited $status on SIGTERM"; failures=$((failures + 1)); }
checks=$((checks + 1))
if grep -q '"GET /m/bunny.lks" 206' "$TMP/serve.log"; then :; else
  echo "FAIL: no 206 for the stream in the server log"; failures=$((failures + 1))
fi
finish
