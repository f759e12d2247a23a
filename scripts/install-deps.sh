#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Install what lodkit needs to build and test, from Debian packages.
# Idempotent: when every package is already installed it only checks and exits.
# Usage: scripts/install-deps.sh [--bench | --core]
#   --bench adds the peers used by `make bench`;
#   --core installs only what the core library and its tests need
#          (`make test-core`: every component off).
set -euo pipefail

core_packages=(
  build-essential cmake pkg-config git ca-certificates
  libcjson-dev                   # JSON output and glTF parsing
  libcmocka-dev                  # unit tests
  zlib1g-dev                     # CRC-32 and deflate (progressive streams)
  libmeshoptimizer-dev           # meshopt_stripify, one of the two stripifiers
  python3                        # tests/layout_check.sh (scripts/check-cycles.py)
)
if [ "${1:-}" = "--core" ]; then
  packages=("${core_packages[@]}")
else
packages=(
  build-essential cmake pkg-config git ca-certificates
  clang libclang-rt-dev          # libFuzzer + sanitizer runtimes for `make fuzz`
  lld wasi-libc libclang-rt-dev-wasm32  # the viewer's stream decoder as WebAssembly (stream2.wasm: clang for wasm32-wasi)
  llvm                           # llvm-symbolizer: sanitizer reports name functions (tests/tsan.supp matches by name)
  libcjson-dev                   # JSON output and glTF parsing
  libcmocka-dev                  # unit tests
  zlib1g-dev                     # CRC-32 and deflate (progressive streams)
  libmeshoptimizer-dev           # meshopt_stripify, one of the two stripifiers
  libegl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri  # headless OpenGL ES 2.0 (Mesa llvmpipe)
  libpng-dev                     # PNG output of renders, PNG textures of glTF scenes
  libjpeg-dev                    # JPEG textures of glTF scenes (lodkit render)
  libgdal-dev                    # elevation grids: GeoTIFF, netCDF, SRTM, ASCII grids
  libmicrohttpd-dev              # `lodkit serve`
  valgrind                       # memcheck over a subset of the tests (tests/cli/test_valgrind.sh)
  chromium wrk curl              # browser tests of the WebGL viewer (Playwright drives Debian's chromium), server load/fault tests
  time python3                   # tests: GNU time measures peak RSS; python3 writes a crafted stream with valid CRCs
  clang-format                   # tests/style_check.sh: the tree is formatted by .clang-format
)
fi
# Node.js runs the browser tests; a machine that already has node (any source) keeps it.
if [ "${1:-}" != "--core" ] && { ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; }; then
  packages+=(nodejs npm)
fi
if [ "${1:-}" = "--bench" ]; then
  packages+=(draco python3-open3d python3-numpy python3-scipy meshlab xvfb xauth hyperfine gnuplot-nox)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

[ "${1:-}" = "--core" ] && exit 0

# The web code and its tests are written for Debian 12's nodejs 18.
node_major=$(node -p 'process.versions.node.split(".")[0]' 2>/dev/null || echo 0)
if [ "$node_major" -lt 18 ]; then
  echo "install-deps: node $(node --version 2>/dev/null) is too old: the browser tests need node 18 or newer (Debian 12's nodejs)" >&2
  exit 1
fi

# The browser tests drive Debian's chromium with npm's playwright-core
# (pinned in tests/browser/package-lock.json; never a downloaded browser).
browser_dir="$(cd "$(dirname "$0")/.." && pwd)/tests/browser"
if [ -f "$browser_dir/package-lock.json" ] &&
   { [ ! -d "$browser_dir/node_modules" ] || [ "$browser_dir/package-lock.json" -nt "$browser_dir/node_modules" ]; }; then
  echo "install-deps: npm ci in tests/browser"
  (cd "$browser_dir" && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --no-audit --no-fund --loglevel=error && touch node_modules)
fi
# `make bench` compares glTF output with npm's gltfpack (pinned in bench/npm).
bench_npm="$(cd "$(dirname "$0")/.." && pwd)/bench/npm"
if [ "${1:-}" = "--bench" ] &&
   { [ ! -d "$bench_npm/node_modules" ] || [ "$bench_npm/package-lock.json" -nt "$bench_npm/node_modules" ]; }; then
  echo "install-deps: npm ci in bench/npm"
  (cd "$bench_npm" && npm ci --no-audit --no-fund --loglevel=error && touch node_modules)
fi
