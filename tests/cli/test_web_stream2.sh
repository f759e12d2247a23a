#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The viewer's version-2 stream decoders in node against the C decoder:
# web/stream2.js and, when the build made it (LK_STREAM2_WASM), the C
# decoder built as WebAssembly (stream2.wasm, web/stream2_wasm.js).
# tests/browser/stream2.test.mjs decodes v2 streams of the bunny, the cow,
# the fandisk, a non-manifold mesh and the spider and compares every
# position and triangle with `lodkit unpack` (full level, level 0, levels
# inside a chunk), and refuses a corrupt chunk as C does, keeping the level
# before. Needs node only (no browser, no node_modules).
set -u
source "$(dirname "$0")/lib.sh"
browser_dir="$(cd "$(dirname "$0")/../browser" && pwd)"
require node nodejs
wasm="${LK_STREAM2_WASM:-}"
if [ -n "$wasm" ] && [ ! -s "$wasm" ]; then
  echo "FAIL: the build says it made $wasm, which is missing"
  failures=$((failures + 1))
  wasm=""
fi
[ -n "$wasm" ] || echo "note: no stream2.wasm in this build: web/stream2.js alone is checked"
checks=$((checks + 1))
if ! (cd "$browser_dir" && timeout -k 5 180 node stream2.test.mjs "$LODKIT" "$LK_SAMPLES_DIR" "$TMP" $wasm); then
  echo "FAIL: web/stream2.js (and stream2.wasm) against lodkit unpack"
  failures=$((failures + 1))
fi
finish
