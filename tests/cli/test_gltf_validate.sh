#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Every glTF lodkit writes passes the Khronos glTF-Validator (npm
# gltf-validator, pinned in tests/browser/package-lock.json) with 0 errors
# and 0 warnings (issue 20); infos and hints are allowed. Today the one
# writer is `lodkit animate` on glTF and Acclaim input (a morph-target
# .gltf per level); each producer below is a lodkit run and one `validate`
# line. Regressions of src/io_gltf_write.c: zero normals (a primitive
# without NORMAL beside one with it), normals not of unit length and
# colours outside 0..1 (an SMF rest pose) were validator errors.
# The harness is shown to fail: broken files written here (an accessor
# longer than its buffer, an unexpected property, a buffer outside the
# file's folder) must be reported.
# Needs node and tests/browser/node_modules, which scripts/install-deps.sh
# installs (Debian nodejs, `npm ci` from the lock file): without them the
# test says what is missing and fails. It never installs anything itself.
set -u
source "$(dirname "$0")/lib.sh"
browser_dir="$(cd "$(dirname "$0")/../browser" && pwd)"
S="$LK_SAMPLES_DIR"
anim="${LK_TEST_DATA_DIR:-$(dirname "$0")/../data}/anim"

require node nodejs
if [ ! -d "$browser_dir/node_modules/gltf-validator" ]; then
  echo "FAIL: $browser_dir/node_modules lacks gltf-validator; run scripts/install-deps.sh (npm ci from the lock file)"
  exit 1
fi

# validate NAME FILE...: each FILE (.gltf or .glb) has no validator error or
# warning. No FILE at all is a failure too (the producer wrote nothing).
validate() {
  local name="$1"; shift
  checks=$((checks + 1))
  if [ $# -eq 0 ] || [ ! -e "$1" ]; then
    echo "FAIL: $name: no glTF written"; failures=$((failures + 1)); return
  fi
  if ! node "$browser_dir/validate-gltf.mjs" "$@" >"$TMP/report.txt" 2>&1; then
    echo "FAIL: $name: the glTF-Validator reports errors or warnings:"
    sed 's/^/  /' "$TMP/report.txt"
    failures=$((failures + 1))
  fi
}
# invalid NAME TEXT FILE: the validator rejects FILE and its report says TEXT.
invalid() {
  local name="$1" text="$2" file="$3"
  checks=$((checks + 1))
  if node "$browser_dir/validate-gltf.mjs" "$file" >"$TMP/report.txt" 2>&1; then
    echo "FAIL: $name: the validator accepted it"; failures=$((failures + 1))
  elif ! grep -qF -- "$text" "$TMP/report.txt"; then
    echo "FAIL: $name: the report lacks '$text':"; cat "$TMP/report.txt"; failures=$((failures + 1))
  fi
}
O="$TMP/out"
mkdir -p "$O"

# ---- lodkit animate: a morph-target .gltf per level ------------------------
check "animate morph cube" "$LODKIT" animate -q --levels=3 --no-metro \
  "$S/assimp/glTF2/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf" "$O/morph"
validate "animate morph cube (normals, morph targets, 3 levels)" "$O"/morph/*.gltf
check "animate skin" "$LODKIT" animate -q --scheme=all --ratio=0.5 --no-metro \
  "$S/assimp/glTF2/simple_skin/simple_skin.gltf" "$O/skin"
validate "animate simple skin (every scheme)" "$O"/skin/*.gltf
check "animate acclaim" "$LODKIT" animate -q --levels=2 --keep-seams --no-metro "$anim/tube.asf" "$O/tube"
validate "animate acclaim tube" "$O"/tube/*.gltf
check "animate two primitives" "$LODKIT" animate -q --levels=2 --no-metro "$anim/two-primitives.gltf" "$O/two"
validate "animate two primitives (one without normals)" "$O"/two/*.gltf
check "animate textured box" "$LODKIT" animate -q --ratio=0.5 --no-metro \
  "$S/assimp/glTF2/BoxTextured-glTF/BoxTextured.gltf" "$O/box"
validate "animate textured box (one frame, texture coordinates)" "$O"/box/*.gltf
check "animate engine" "$LODKIT" animate -q --ratio=0.25 --no-metro \
  "$S/assimp/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb" "$O/engine"
validate "animate 2CylinderEngine.glb (many meshes)" "$O"/engine/*.gltf

# The tube's rest pose with SMF normals of length 2 and 0 and colours outside
# 0..1 (the SMF reader keeps them as written).
mkdir -p "$TMP/tube-attributes"
cp "$anim"/tube.{asf,amc,wgt} "$TMP/tube-attributes/"
awk '{ print } /^v / { print (++n % 2 ? "n 0 2 0" : "n 0 0 0"); print "c 2 0.5 -1" }' "$anim/tube.smf" \
  >"$TMP/tube-attributes/tube.smf"
check "animate tube with SMF attributes" "$LODKIT" animate -q --levels=2 --no-metro \
  "$TMP/tube-attributes/tube.asf" "$O/tube-attributes"
validate "animate tube (normals not of unit length, colours outside 0..1)" "$O"/tube-attributes/*.gltf

# ---- meshes and point sets: convert, simplify, lod ---------------------------
# Every sample format into .glb (attributes: normals, texture coordinates,
# colours, a point set), .gltf + .bin, quantised, meshopt-compressed,
# simplified with attributes, and MSFT_lod chains.
mkdir -p "$O/mesh"
n=0
for input in "$S/cow.off" "$S/bunny.obj" "$S/hippo1.ply" "$S/kitten.xyz" "$S/assimp/PLY/float-color.ply" \
  "$S/assimp/PLY/cube_uv.ply" "$S/assimp/STL/Spider_binary.stl" "$S/assimp/glTF2/BoxTextured-glTF/BoxTextured.gltf"; do
  n=$((n + 1))
  check "convert $(basename "$input")" "$LODKIT" convert -q "$input" "$O/mesh/$n.glb"
  check "convert $(basename "$input") --quantize" "$LODKIT" convert -q --quantize "$input" "$O/mesh/$n-q.glb"
  check "convert $(basename "$input") --meshopt" "$LODKIT" convert -q --meshopt "$input" "$O/mesh/$n-m.glb"
done
validate "convert: every sample kind as .glb, quantised and meshopt-compressed" "$O"/mesh/*.glb
check "convert to .gltf + .bin" "$LODKIT" convert -q "$S/cow.off" "$O/mesh/cow text.gltf"
validate "convert: .gltf with its .bin (a name with a space)" "$O/mesh/cow text.gltf"
check "simplify with attributes" "$LODKIT" simplify -q --attributes --ratio=0.2 \
  "$S/assimp/glTF2/BoxTextured-glTF/BoxTextured.gltf" "$O/mesh/box-simplified.glb"
check "simplify the bunny, meshopt" "$LODKIT" simplify -q --ratio=0.1 --meshopt "$S/bunny.obj" "$O/mesh/bunny-10.glb"
validate "simplify: .glb outputs" "$O/mesh/box-simplified.glb" "$O/mesh/bunny-10.glb"
check "lod chain" "$LODKIT" lod -q --levels=3 "$S/cow.off" "$O/mesh/cow-lod.glb"
check "lod chain, meshopt" "$LODKIT" lod -q --levels=3 --meshopt "$S/cow.off" "$O/mesh/cow-lod-m.gltf"
validate "lod: MSFT_lod chains" "$O/mesh/cow-lod.glb" "$O/mesh/cow-lod-m.gltf"

# ---- scenes: glTF in, glTF out ---------------------------------------------
# Every glTF sample lodkit reads, converted (.glb, .gltf + .bin, quantised,
# meshopt-compressed) and simplified: nodes, materials (glTF 1.0 leftovers
# and unknown extensions dropped), textures with their images embedded,
# tangents generated for normal maps, cameras, TEXCOORD_1 without TEXCOORD_0.
mkdir -p "$O/scene"
G="$S/assimp/glTF2"
n=0
for input in "$G/2CylinderEngine-glTF-Binary/2CylinderEngine.glb" "$G/BoxBadNormals-glTF-Binary/BoxBadNormals.glb" \
  "$G/BoxTexcoords-glTF/boxTexcoords.gltf" "$G"/BoxTextured-glTF*/BoxTextured.gl* "$G/ClearCoat-glTF/ClearCoatTest.gltf" \
  "$G/cameras/Cameras.gltf" "$G/glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_"{00,05,06,13}.gltf \
  "$G/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf" "$G/issue_3269/texcoord_crash.gltf" \
  "$G/simple_skin/simple_skin.gltf" "$G/textureTransform/TextureTransformTest.gltf"; do
  n=$((n + 1))
  check "scene $n convert" "$LODKIT" convert -q "$input" "$O/scene/$n.glb"
  check "scene $n convert .gltf" "$LODKIT" convert -q "$input" "$O/scene/$n.gltf"
  check "scene $n --quantize" "$LODKIT" convert -q --quantize "$input" "$O/scene/$n-q.glb"
  check "scene $n --meshopt" "$LODKIT" convert -q --meshopt "$input" "$O/scene/$n-m.glb"
  check "scene $n simplify" "$LODKIT" simplify -q --ratio=0.3 "$input" "$O/scene/$n-s.glb"
done
# line primitives (the samples' LINES, LINE_LOOP, LINE_STRIP; a box with
# lines added, tests/cli/gltf_add_lines.py), compressed with meshopt's
# INDICES codec, simplified and as a lod chain (the lines stay)
for mode in 01 02 03 08 09 10; do
  check "lines $mode --meshopt" "$LODKIT" convert -q --meshopt \
    "$G/glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_$mode.gltf" "$O/scene/lines-$mode-m.glb"
done
python3 "$(dirname "$0")/gltf_add_lines.py" "$G/BoxTextured-glTF-Embedded/BoxTextured.gltf" "$O/box-lines.gltf"
check "box with lines convert" "$LODKIT" convert -q "$O/box-lines.gltf" "$O/scene/box-lines.glb"
check "box with lines --meshopt" "$LODKIT" convert -q --meshopt "$O/box-lines.gltf" "$O/scene/box-lines-m.glb"
check "box with lines simplify" "$LODKIT" simplify -q --ratio=0.5 "$O/box-lines.gltf" "$O/scene/box-lines-s.glb"
check "box with lines lod" "$LODKIT" lod -q --levels=3 --meshopt "$O/box-lines.gltf" "$O/scene/box-lines-lod.glb"
# An image with an embedded ICC profile (an iCCP chunk, as CGE's castle's
# normal maps have): the input draws IMAGE_FEATURES_UNSUPPORTED, the output
# none; the image written is the PNG without the chunk, byte for byte.
mkdir -p "$O/icc" "$O/icc-out"
cp "$G/BoxTextured-glTF/BoxTextured.gltf" "$G/BoxTextured-glTF/BoxTextured0.bin" "$O/icc/"
python3 - "$G/BoxTextured-glTF/CesiumLogoFlat.png" "$O/icc/CesiumLogoFlat.png" <<'PY'
import struct, sys, zlib
png = open(sys.argv[1], "rb").read()
body = b"test profile\0\0" + zlib.compress(b"not a real ICC profile")
chunk = struct.pack(">I", len(body)) + b"iCCP" + body + struct.pack(">I", zlib.crc32(b"iCCP" + body))
ihdr_end = 8 + 12 + struct.unpack(">I", png[8:12])[0]
open(sys.argv[2], "wb").write(png[:ihdr_end] + chunk + png[ihdr_end:])
PY
invalid "control: a PNG with an ICC profile" "warning IMAGE_FEATURES_UNSUPPORTED" "$O/icc/BoxTextured.gltf"
check "ICC profile: convert" "$LODKIT" convert -q "$O/icc/BoxTextured.gltf" "$O/scene/icc.glb"
check "ICC profile: convert --external-images" "$LODKIT" convert -q --external-images "$O/icc/BoxTextured.gltf" \
  "$O/icc-out/box.gltf"
check "ICC profile: the PNG written is the original without the chunk" cmp "$G/BoxTextured-glTF/CesiumLogoFlat.png" \
  "$O/icc-out/box_0.png"
validate "ICC profile dropped" "$O/scene/icc.glb" "$O/icc-out/box.gltf"
# images as files beside the .gltf (--external-images)
check "scene clearcoat --external-images" "$LODKIT" convert -q --external-images "$G/ClearCoat-glTF/ClearCoatTest.gltf" \
  "$O/scene/clearcoat-ext.gltf"
check "scene box simplify --external-images" "$LODKIT" simplify -q --ratio=0.5 --external-images \
  "$G/BoxTextured-glTF/BoxTextured.gltf" "$O/scene/box-ext.gltf"
check "scene lod engine" "$LODKIT" lod -q --levels=3 "$G/2CylinderEngine-glTF-Binary/2CylinderEngine.glb" "$O/scene/engine-lod.glb"
# morph targets (AnimatedMorphCube's 2, with the animation of their weights):
# simplified with --quantize (positions stay floats) and MSFT_lod chains
morph="$G/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf"
check "scene morph simplify --quantize" "$LODKIT" simplify -q --ratio=0.5 --quantize "$morph" "$O/scene/morph-50-q.glb"
check "scene morph lod" "$LODKIT" lod -q --levels=3 "$morph" "$O/scene/morph-lod.glb"
check "scene morph lod --meshopt" "$LODKIT" lod -q --levels=3 --meshopt "$morph" "$O/scene/morph-lod-m.glb"
check "scene lod clearcoat --meshopt" "$LODKIT" lod -q --levels=3 --meshopt "$G/ClearCoat-glTF/ClearCoatTest.gltf" \
  "$O/scene/clearcoat-lod.glb"
validate "scenes: every glTF sample converted, quantised, compressed and simplified; MSFT_lod chains" \
  "$O"/scene/*.glb "$O"/scene/*.gltf

# ---- scenes: OBJ with .mtl materials in, glTF out ----------------------------
# spider.obj: four materials with JPEG textures (map_Kd .\NAME.jpg); the
# assimp material samples (names with spaces, a material no .mtl defines,
# a Latin-1 name, an empty name).
mkdir -p "$O/obj"
OBJ="$S/assimp/OBJ"
check "spider convert" "$LODKIT" convert -q "$OBJ/spider.obj" "$O/obj/spider.glb"
check "spider convert .gltf" "$LODKIT" convert -q "$OBJ/spider.obj" "$O/obj/spider.gltf"
check "spider --quantize" "$LODKIT" convert -q --quantize "$OBJ/spider.obj" "$O/obj/spider-q.glb"
check "spider --meshopt" "$LODKIT" convert -q --meshopt "$OBJ/spider.obj" "$O/obj/spider-m.glb"
check "spider simplify" "$LODKIT" simplify -q --ratio=0.3 "$OBJ/spider.obj" "$O/obj/spider-s.glb"
check "spider lod" "$LODKIT" lod -q --levels=3 "$OBJ/spider.obj" "$O/obj/spider-lod.glb"
for name in cube_usemtl space_in_material_name cube_mtllib_after_g empty_mat regr01 concave_polygon; do
  check "$name convert" "$LODKIT" convert -q "$OBJ/$name.obj" "$O/obj/$name.glb"
done
validate "OBJ scenes: spider with its textures converted, quantised, compressed, simplified, MSFT_lod; material samples" \
  "$O"/obj/*.glb "$O"/obj/*.gltf

# ---- skins and node animations ---------------------------------------------
# CGE's knight (1 skin of 49 joints, 5 animations) and simple_skin: JOINTS_0
# as unsigned bytes, WEIGHTS_0 summing to 1, inverse bind matrices and key
# times in views without target or byteStride, key times with min and max;
# quantised output puts a skinned mesh's positions on a grid folded into
# the inverse bind matrices (its node's transform does not apply), its
# weights in bytes summing to 255 (joints without weight 0: the validator
# warns ACCESSOR_JOINTS_USED_ZERO_WEIGHT otherwise) and rotation keys in
# normalised shorts; meshopt compresses the animation views too, rotations
# and translations through its quaternion and exponential filters.
mkdir -p "$O/skin"
for input in "$S/cge/knight/knight.gltf" "$G/simple_skin/simple_skin.gltf"; do
  [ -f "$input" ] || continue # the knight: `scripts/fetch-samples.sh --bench` only
  n="$(basename "$input" .gltf)"
  check "skin $n convert" "$LODKIT" convert -q "$input" "$O/skin/$n.glb"
  check "skin $n convert .gltf" "$LODKIT" convert -q "$input" "$O/skin/$n.gltf"
  check "skin $n --quantize" "$LODKIT" convert -q --quantize "$input" "$O/skin/$n-q.glb"
  check "skin $n --meshopt" "$LODKIT" convert -q --meshopt "$input" "$O/skin/$n-m.glb"
  check "skin $n simplify" "$LODKIT" simplify -q --ratio=0.3 "$input" "$O/skin/$n-s.glb"
  check "skin $n simplify compact" "$LODKIT" simplify -q --ratio=0.3 --quantize --meshopt "$input" "$O/skin/$n-sqm.glb"
  check "skin $n lod" "$LODKIT" lod -q --levels=3 "$input" "$O/skin/$n-lod.glb"
done
# A skinned mesh under a transformed parent (simple_skin nested below a
# new root node moved by (5, 0, 0); Qt 3D's RiggedFigure and CGE's dungeon
# level come so): the input draws a validator warning, every output none
# (the writer moves the mesh to a root node: src/io_gltf_hoist.c).
python3 "$(dirname "$0")/gltf_nest.py" "$G/simple_skin/simple_skin.gltf" "$O/skin-nested-in.gltf"
invalid "control: simple_skin nested below a parent" "warning NODE_SKINNED_MESH_NON_ROOT" "$O/skin-nested-in.gltf"
check "skin nested convert" "$LODKIT" convert -q "$O/skin-nested-in.gltf" "$O/skin/nested.glb"
check "skin nested --meshopt" "$LODKIT" convert -q --meshopt "$O/skin-nested-in.gltf" "$O/skin/nested-m.glb"
check "skin nested simplify" "$LODKIT" simplify -q --ratio=0.5 "$O/skin-nested-in.gltf" "$O/skin/nested-s.glb"
check "skin nested lod" "$LODKIT" lod -q --levels=2 "$O/skin-nested-in.gltf" "$O/skin/nested-lod.glb"
for input in "$S/RiggedFigure/RiggedFigure.gltf" "$S/cge/level/level-dungeon.gltf"; do
  [ -f "$input" ] || continue # `scripts/fetch-samples.sh --bench` only
  n="$(basename "$input" .gltf)"
  check "skin $n convert" "$LODKIT" convert -q "$input" "$O/skin/$n.glb"
  check "skin $n simplify" "$LODKIT" simplify -q --ratio=0.5 "$input" "$O/skin/$n-s.glb"
done
for output in "$O"/skin/knight*.gl*; do
  [ -f "$output" ] || continue
  expect_output_contains "1 skin, 5 animations" "$LODKIT" info "$output"
done
validate "skins and animations: converted, quantised, compressed, simplified, lod" "$O"/skin/*.glb "$O"/skin/*.gltf

# ---- the harness fails when it should --------------------------------------
# One triangle in triangle.bin: (0,0,0) (1,0,0) (0,1,0) as little-endian floats.
N="$TMP/negative"
mkdir -p "$N/inside"
printf '\0\0\0\0\0\0\0\0\0\0\0\0\0\0\200\77\0\0\0\0\0\0\0\0\0\0\0\0\0\0\200\77\0\0\0\0' >"$N/inside/triangle.bin"
cp "$N/inside/triangle.bin" "$N/outside.bin"
# triangle_gltf COUNT URI [ASSET_EXTRA]: a glTF of that triangle whose
# accessor claims COUNT vertices, its buffer at URI.
triangle_gltf() {
  printf '{"asset":{"version":"2.0"%s},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],' "${3:-}"
  printf '"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],'
  printf '"accessors":[{"bufferView":0,"componentType":5126,"count":%d,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],' "$1"
  printf '"bufferViews":[{"buffer":0,"byteLength":36,"target":34962}],"buffers":[{"byteLength":36,"uri":"%s"}]}\n' "$2"
}
triangle_gltf 3 triangle.bin >"$N/inside/good.gltf"
validate "control: a valid triangle with its .bin beside it" "$N/inside/good.gltf"
triangle_gltf 4 triangle.bin >"$N/inside/long.gltf"
invalid "an accessor longer than its buffer view" "error ACCESSOR_TOO_LONG" "$N/inside/long.gltf"
triangle_gltf 3 triangle.bin ',"lodkit":1' >"$N/inside/warning.gltf"
invalid "a warning alone fails" "warning UNEXPECTED_PROPERTY" "$N/inside/warning.gltf"
triangle_gltf 3 ../outside.bin >"$N/inside/escape.gltf"
invalid "a buffer outside the file's folder is not read" "outside the folder" "$N/inside/escape.gltf"
ln -s ../outside.bin "$N/inside/link.bin"
triangle_gltf 3 link.bin >"$N/inside/link.gltf"
invalid "a link out of the file's folder is not followed" "outside the folder" "$N/inside/link.gltf"
printf 'not glTF' >"$N/garbage.gltf"
invalid "bytes that are not glTF" "garbage.gltf: " "$N/garbage.gltf"
finish
