#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The viewer's version-2 stream decoder (web/stream.js, web/stream2.js) in
# node against the C decoder: tests/browser/stream2.test.mjs decodes v2
# streams of the bunny, the cow and the fandisk and compares every position
# and triangle with `lodkit unpack` (full level, level 0, levels inside a
# chunk), and refuses a corrupt chunk as C does, keeping the level before.
# Needs node only (no browser, no node_modules).
set -u
source "$(dirname "$0")/lib.sh"
browser_dir="$(cd "$(dirname "$0")/../browser" && pwd)"
require node nodejs
checks=$((checks + 1))
if ! (cd "$browser_dir" && timeout -k 5 120 node stream2.test.mjs "$LODKIT" "$LK_SAMPLES_DIR" "$TMP"); then
  echo "FAIL: web/stream2.js against lodkit unpack"
  failures=$((failures + 1))
fi
finish
