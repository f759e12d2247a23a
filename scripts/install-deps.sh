#!/usr/bin/env bash
# Install what lodkit needs to build and test, from Debian packages.
# Idempotent: when every package is already installed it only checks and exits.
# Usage: scripts/install-deps.sh [--bench]   (--bench adds the peers used by `make bench`)
set -euo pipefail

packages=(
  build-essential cmake pkg-config git ca-certificates
  clang libclang-rt-dev          # libFuzzer + sanitizer runtimes for `make fuzz`
  libcjson-dev                   # JSON output and glTF parsing
  libcmocka-dev                  # unit tests
  zlib1g-dev                     # CRC-32 and deflate (progressive streams)
  libmeshoptimizer-dev           # meshopt_stripify, one of the two stripifiers
  libegl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri  # headless OpenGL ES 2.0 (Mesa llvmpipe)
  libpng-dev                     # PNG output of renders
  libgdal-dev                    # elevation grids: GeoTIFF, netCDF, SRTM, ASCII grids
)
if [ "${1:-}" = "--bench" ]; then
  packages+=(draco python3-open3d python3-numpy meshlab xvfb xauth hyperfine gnuplot-nox)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
