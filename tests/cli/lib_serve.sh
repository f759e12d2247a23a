# SPDX-License-Identifier: MIT
# The browser tests' setup (sourced after lib.sh):
#   require_browser   node, /usr/bin/chromium and tests/browser/node_modules
#                     (scripts/install-deps.sh), or a FAIL saying what is
#                     missing (a test never installs anything); sets
#                     $browser_dir
#   start_serve DIR   starts `lodkit serve DIR` on a free port, sets $server (its pid) and
#                     $url, stops it and removes $TMP on exit; exits the test
#                     with a FAIL when it prints no URL within 10 s
#   stop_server       SIGTERM, then SIGKILL after 5 s; waits for it
require_browser() {
  browser_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/../browser" && pwd)"
  require node nodejs
  [ -x /usr/bin/chromium ] || { echo "FAIL: this test needs /usr/bin/chromium (Debian package: chromium); run scripts/install-deps.sh"; exit 1; }
  if [ ! -d "$browser_dir/node_modules/playwright-core" ]; then
    echo "FAIL: $browser_dir/node_modules lacks playwright-core; run scripts/install-deps.sh (npm ci from the lock file)"
    exit 1
  fi
}
start_serve() {
  "$LODKIT" serve "$1" --port 0 >"$TMP/serve.out" 2>"$TMP/serve.log" &
  server=$!
  trap 'stop_server; rm -rf "$TMP"' EXIT
  url=""
  for _ in $(seq 100); do
    url=$(grep -o 'http://[^ ]*' "$TMP/serve.out" 2>/dev/null | head -1)
    [ -n "$url" ] && break
    kill -0 "$server" 2>/dev/null || break
    sleep 0.1
  done
  if [ -z "$url" ]; then
    echo "FAIL: lodkit serve did not print its URL"; cat "$TMP/serve.out" "$TMP/serve.log"; exit 1
  fi
  echo "# server at $url"
}
stop_server() {
  if kill -0 "$server" 2>/dev/null; then
    kill -TERM "$server" 2>/dev/null
    for _ in $(seq 50); do kill -0 "$server" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$server" 2>/dev/null
  fi
  wait "$server" 2>/dev/null
}
