#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `lodkit serve` on an ephemeral port over a temporary directory: the start
# line, Range, 404, path traversal, the index, the request log, a clean stop
# on SIGTERM (exit 0) and on SIGINT, usage errors. Every step is bounded in time.
set -u
source "$(dirname "$0")/lib.sh"
require curl curl
fetch() { curl -sS --max-time 20 --path-as-is "$@"; }
status() { fetch -o /dev/null -w '%{http_code}' "$@"; }

expect_exit 0 "$LODKIT" serve --help
expect_output_contains "--simplify-on-demand" "$LODKIT" serve --help
expect_exit 2 "$LODKIT" serve
expect_exit 2 "$LODKIT" serve --port=70000 "$TMP"
expect_exit 2 "$LODKIT" serve --timeout=0 "$TMP"
expect_exit 2 "$LODKIT" serve --max-connections=x "$TMP"
expect_exit 1 timeout 20 "$LODKIT" serve --port 0 "$TMP/missing"
expect_output_contains "missing" timeout 20 "$LODKIT" serve --port 0 "$TMP/missing"

content="$TMP/content"
mkdir -p "$content"
"$LODKIT" progressive -q "$LK_SAMPLES_DIR/cow.off" "$content/cow.lks"
# a small mesh for simplify-on-demand, so the build stays short under ASan on a loaded machine
cp "$LK_SAMPLES_DIR/triceratops.off" "$content/dino.off"
echo "secret outside" > "$TMP/outside.txt"
# point octrees: listed by their index, named after their folder (issue 23)
"$LODKIT" octree -q "$LK_SAMPLES_DIR/kitten.xyz" "$content/kitten_tree"
mkdir -p "$content/bad_tree" && echo '{"format": "lodkit point octree",' > "$content/bad_tree/octree.json"

# start, and read the URL from the start line
timeout -k 10 120 "$LODKIT" serve --port 0 --timeout 5 --simplify-on-demand "$content" \
  > "$TMP/stdout" 2> "$TMP/stderr" &
pid=$!
for _ in $(seq 100); do
  grep -q "^lodkit serve: serving " "$TMP/stdout" 2>/dev/null && break
  sleep 0.1
done
line=$(head -1 "$TMP/stdout")
check "start line ($line)" grep -qE "^lodkit serve: serving .*content at http://127\.0\.0\.1:[0-9]+/$" "$TMP/stdout"
url=${line##* at }

size=$(stat -c %s "$content/cow.lks")
check "whole file" cmp -s <(fetch "${url}m/cow.lks") "$content/cow.lks"
check "Range 206" test "$(status -r 100-199 "${url}m/cow.lks")" = 206
check "Range bytes" cmp -s <(fetch -r 100-199 "${url}m/cow.lks") <(tail -c +101 "$content/cow.lks" | head -c 100)
check "Content-Range" grep -qi "^content-range: bytes 100-199/$size" <(fetch -D - -o /dev/null -r 100-199 "${url}m/cow.lks")
check "unsatisfiable Range 416" test "$(status -r "$size"- "${url}m/cow.lks")" = 416
check "missing 404" test "$(status "${url}m/missing.lks")" = 404
check "traversal 403" test "$(status "${url}m/../outside.txt")" = 403
check "encoded traversal 403" test "$(status "${url}m/%2e%2e/outside.txt")" = 403
check "no outside bytes" sh -c "! curl -s --path-as-is '${url}m/%2e%2e/outside.txt' | grep -q secret"
check "POST 405" test "$(status -X POST "${url}m/cow.lks")" = 405
index=$(fetch "${url}api/index.json")
check "index lists the stream" grep -q '"name":"cow.lks","url":"/m/cow.lks","bytes":'"$size"',"kind":"stream","vertices":2904,"triangles":5804' <<<"$index"
check "index lists the mesh with its stream" grep -q '"name":"dino.off".*"vertices":2832,"triangles":5660,"stream":"/m/dino.lks"' <<<"$index"
check "index lists the octree" grep -q '"name":"kitten_tree","path":"kitten_tree/octree.json","url":"/m/kitten_tree/octree.json","bytes":[0-9]*,"kind":"octree","points":5210,"nodes":23,"normals":true,"colors":false' <<<"$index"
check "index says why an octree index is refused" grep -q '"name":"bad_tree",[^}]*"kind":"unknown","error":"bad_tree/octree.json' <<<"$index"
check "octree node by Range 206" test "$(status -r 0-19 "${url}m/kitten_tree/octree.bin")" = 206
check "gzip when accepted" grep -qi "^content-encoding: gzip" <(fetch -D - -o /dev/null -H "Accept-Encoding: gzip" "${url}api/index.json")
# simplify-on-demand: the stream is built on the first request
check "built on demand" test "$(status "${url}m/dino.lks")" = 200
check "cached on disk" test -s "$content/.lodkit-cache/dino.lks"
check "cached stream is valid" sh -c "'$LODKIT' inspect '$content/.lodkit-cache/dino.lks' > /dev/null"
check "the server builds version-2 streams (first frame in the first kilobytes)" \
  grep -q '"version":2' <("$LODKIT" inspect --json "$content/.lodkit-cache/dino.lks")
check "log line per request" grep -qE '^127\.0\.0\.1 "GET /m/cow\.lks" 206 100 bytes [0-9.]+ ms$' "$TMP/stderr"

kill -TERM "$pid"
wait "$pid"
code=$?
check "SIGTERM: exit 0 (got $code)" test "$code" -eq 0
[ "$code" -eq 0 ] || { echo "server stderr:"; tail -20 "$TMP/stderr"; }

# SIGINT stops it too; --quiet logs nothing; --max-memory bounds what is parsed
timeout -k 10 60 "$LODKIT" serve --port 0 --quiet --max-memory 64K "$content" > "$TMP/stdout2" 2> "$TMP/stderr2" &
pid=$!
for _ in $(seq 100); do grep -q "serving" "$TMP/stdout2" 2>/dev/null && break; sleep 0.1; done
line=$(head -1 "$TMP/stdout2")
url=${line##* at }
check "second server answers" test "$(status "${url}m/cow.lks")" = 200
check "mesh over --max-memory: 413" test "$(status "${url}api/points/dino.off")" = 413
check "413 names the limit" sh -c "curl -s '${url}api/points/dino.off' | grep -q 'limit\|budget'"
kill -INT "$pid"
wait "$pid"
code=$?
check "SIGINT: exit 0 (got $code)" test "$code" -eq 0
[ "$code" -eq 0 ] || { echo "server stderr:"; tail -20 "$TMP/stderr2"; }
check "quiet: no request log" test ! -s "$TMP/stderr2"

# The viewer's files: compiled in, or from --web WEBDIR; the stream decoder
# built as WebAssembly (LK_STREAM2_WASM, when this build made it) from the
# library even when WEBDIR has none (it is not a file of web/).
webdir="$TMP/webdir"
mkdir -p "$webdir" && echo '<title>mine</title>' > "$webdir/index.html"
timeout -k 10 60 "$LODKIT" serve --port 0 --quiet --web "$webdir" "$content" > "$TMP/stdout3" 2> "$TMP/stderr3" &
pid=$!
for _ in $(seq 100); do grep -q "serving" "$TMP/stdout3" 2>/dev/null && break; sleep 0.1; done
line=$(head -1 "$TMP/stdout3")
url=${line##* at }
check "--web: the viewer's page from WEBDIR" sh -c "curl -s '${url}' | grep -q mine"
check "--web: a file WEBDIR lacks is 404" test "$(status "${url}web/viewer.css")" = 404
if [ -n "${LK_STREAM2_WASM:-}" ]; then
  check "--web: stream2.wasm from the library, the build's bytes" cmp -s <(fetch "${url}web/stream2.wasm") "$LK_STREAM2_WASM"
  check "stream2.wasm as application/wasm" grep -qi "^content-type: application/wasm" <(fetch -D - -o /dev/null "${url}web/stream2.wasm")
  check "stream2.wasm gzipped when accepted" grep -qi "^content-encoding: gzip" \
    <(fetch -D - -o /dev/null -H "Accept-Encoding: gzip" "${url}web/stream2.wasm")
  check "stream2.wasm gzipped: the same bytes" cmp -s <(fetch --compressed "${url}web/stream2.wasm") "$LK_STREAM2_WASM"
fi
kill -TERM "$pid"
wait "$pid"
finish
