#!/bin/bash
# SPDX-License-Identifier: MIT
# glTF scenes through the CLI (lk_scene, src/io_gltf_scene.c and the scene
# writer in src/io_gltf_mesh_write.c; issue 20):
# - round trip: every glTF sample of assimp-testmodels that lodkit reads comes
#   back from `convert` (.glb and .gltf + .bin) with the same node tree and
#   transforms, meshes, primitives (vertex and triangle counts, attributes,
#   material), materials (JSON), textures, samplers, cameras and image bytes,
#   as `lodkit info --json` sees them ("scene"); tangents the writer
#   generates for normal maps are the one allowed difference;
#   skins (joints, inverse bind matrices, JOINTS_0 and WEIGHTS_0 per vertex),
#   morph targets (POSITION, NORMAL and TANGENT deltas, weights) and
#   animations (channels, key times and values) included;
# - skins and animations are kept: simple_skin, CGE's knight and avatar;
# - morph targets (deltas, default weights, the animation of the weights)
#   are kept through convert and simplify;
# - what reading leaves out is said: glTF 1.0 material properties;
# - simplify keeps the scene: nodes, materials, textures, texture
#   coordinates, the triangle count; lod adds MSFT_lod nodes per level;
#   render draws the base colour textures (tests/unit/test_render_scene.c
#   measures that they stay mapped);
# - bad input names the item: a missing image, a texture's image or a
#   primitive's material out of range; no output is left.
source "$(dirname "$0")/lib.sh"
G="$LK_SAMPLES_DIR/assimp/glTF2"

# scene_of FILE: the "scene" object of `lodkit info --json FILE`, tangents
# left out.
scene_of() { "$LODKIT" info -q --json "$1" | sed 's/.*"scene"://; s/"tangents",//g'; }
# written_scene_of FILE [--no-weights]: the same, canonical, as lodkit's glTF
# writer gives it back: skinned meshes under a parent moved to new root
# nodes (tests/cli/scene_json.py --hoist says how; the validator warns
# NODE_SKINNED_MESH_NON_ROOT on the input, not on the output).
# canonical_scene_of FILE [--no-weights]: the same without the move.
scene_json="$(dirname "$0")/scene_json.py"
written_scene_of() { "$LODKIT" info -q --json "$1" | sed 's/"tangents",//g' | python3 "$scene_json" --hoist "${@:2}"; }
canonical_scene_of() { "$LODKIT" info -q --json "$1" | sed 's/"tangents",//g' | python3 "$scene_json" "${@:2}"; }

for input in "$G/2CylinderEngine-glTF-Binary/2CylinderEngine.glb" "$G/BoxBadNormals-glTF-Binary/BoxBadNormals.glb" \
  "$G/BoxTexcoords-glTF/boxTexcoords.gltf" "$G"/BoxTextured-glTF*/BoxTextured.gl* "$G/ClearCoat-glTF/ClearCoatTest.gltf" \
  "$G/cameras/Cameras.gltf" "$G/glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_"{00,01,02,03,04,05,06,07,08,09,10,11,12,13,14,15}.gltf \
  "$G/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf" "$G/issue_3269/texcoord_crash.gltf" \
  "$G/simple_skin/simple_skin.gltf" "$G/textureTransform/TextureTransformTest.gltf" \
  "$LK_SAMPLES_DIR/cge/knight/knight.gltf" "$LK_SAMPLES_DIR/cge/avatar/avatar.gltf"; do
  # CGE's knight and avatar come with `scripts/fetch-samples.sh --bench` only
  case "$input" in "$LK_SAMPLES_DIR/cge/"*) [ -f "$input" ] || continue ;; esac
  name="${input#$G/}"
  expected="$(written_scene_of "$input")"
  for ext in glb gltf; do
    checks=$((checks + 1))
    if ! "$LODKIT" convert -q "$input" "$TMP/round.$ext"; then
      echo "FAIL: convert $name to .$ext"; failures=$((failures + 1)); continue
    fi
    got="$(canonical_scene_of "$TMP/round.$ext")"
    if [ -z "$expected" ] || [ "$expected" != "$got" ]; then
      echo "FAIL: $name: the .$ext written differs from the input:"
      diff <(tr ',' '\n' <<<"$expected") <(tr ',' '\n' <<<"$got") | head -8
      failures=$((failures + 1))
    fi
  done
done

# Two skinned samples whose WEIGHTS_0 do not sum to 1 (the Khronos validator
# reports ACCESSOR_WEIGHTS_NON_NORMALIZED on the inputs: the dungeon level's
# avatar, Qt 3D's RiggedFigure) and whose skinned mesh sits under a parent
# (NODE_SKINNED_MESH_NON_ROOT): the writer divides those vertices' weights
# by their sum and moves the mesh to a root node, so the round trip is the
# same scene but for the weights' hash and the move, it draws the same
# (lodkit poses a skinned mesh by its joints, as glTF says: Hausdorff 0 to
# the input), and a second round trip changes nothing. With the --bench
# samples.
for input in "$LK_SAMPLES_DIR/cge/level/level-dungeon.gltf" "$LK_SAMPLES_DIR/RiggedFigure/RiggedFigure.gltf"; do
  [ -f "$input" ] || continue
  name="${input#$LK_SAMPLES_DIR/}"
  "$LODKIT" convert -q "$input" "$TMP/weights1.glb" && "$LODKIT" convert -q "$TMP/weights1.glb" "$TMP/weights2.glb"
  check "$name: the same scene but for the weights and the skinned mesh's node" \
    test "$(written_scene_of "$input" --no-weights)" = "$(canonical_scene_of "$TMP/weights1.glb" --no-weights)"
  check "$name: the skinned mesh moved" test "$(canonical_scene_of "$input")" != "$(written_scene_of "$input")"
  check "$name: the weights were rewritten" \
    test "$(written_scene_of "$input")" != "$(canonical_scene_of "$TMP/weights1.glb")"
  check "$name: a second round trip changes nothing" test "$(scene_of "$TMP/weights1.glb")" = "$(scene_of "$TMP/weights2.glb")"
  check "$name: drawn where the input is (Hausdorff under 1e-6% of the diagonal)" python3 -c \
    'import json, sys; sys.exit(json.load(sys.stdin)["hausdorff_percent"] >= 1e-6)' \
    < <("$LODKIT" metro --json "$input" "$TMP/weights1.glb")
done

# Lines: a box of 12 triangles with a LINES primitive of 18 segments added
# (tests/cli/gltf_add_lines.py): info counts them; simplify and every
# level of a lod chain keep the segments as they were (their indices'
# hash) while the triangles go; --meshopt keeps them too (meshopt's
# INDICES codec). The line samples themselves round trip above.
python3 "$(dirname "$0")/gltf_add_lines.py" "$G/BoxTextured-glTF-Embedded/BoxTextured.gltf" "$TMP/mixed.gltf"
expect_output_contains "2 nodes, 2 primitives, 48 vertices, 12 triangles, 1 material, 1 texture, 18 lines" \
  "$LODKIT" info "$TMP/mixed.gltf"
# primitives_of FILE: "triangles/lines/line hash" of each primitive
primitives_of() {
  "$LODKIT" info -q --json "$1" | python3 -c 'import json, sys
print(" ".join("%s/%s/%s" % (p["triangles"], p.get("lines", 0), p.get("line_indices", "-"))
               for m in json.load(sys.stdin)["scene"]["meshes"] for p in m["primitives"]))'
}
check "mixed: convert --meshopt" "$LODKIT" convert -q --meshopt "$TMP/mixed.gltf" "$TMP/mixed-m.glb"
check "mixed: simplify" "$LODKIT" simplify -q --ratio=0.5 "$TMP/mixed.gltf" "$TMP/mixed-50.glb"
check "mixed: lod" "$LODKIT" lod -q --levels=3 "$TMP/mixed.gltf" "$TMP/mixed-lod.glb"
check "mixed: the input's primitives" test "$(primitives_of "$TMP/mixed.gltf")" = "12/0/- 0/18/c5241045"
check "mixed: lines through --meshopt" test "$(primitives_of "$TMP/mixed-m.glb")" = "12/0/- 0/18/c5241045"
check "mixed: lines kept by simplify" test "$(primitives_of "$TMP/mixed-50.glb")" = "6/0/- 0/18/c5241045"
check "mixed: lines on every level" \
  test "$(primitives_of "$TMP/mixed-lod.glb")" = "12/0/- 0/18/c5241045 6/0/- 0/18/c5241045 4/0/- 0/18/c5241045"

# --external-images: a .gltf whose images are files beside it (STEM_N.png,
# .jpg; the stem percent-encoded in the URIs), the same scene read back
# (the images' bytes and hashes included), the .bin without them; a .glb
# refuses the option; an image that cannot be written leaves no .gltf.
clearcoat="$G/ClearCoat-glTF/ClearCoatTest.gltf"
mkdir -p "$TMP/external"
check "convert --external-images" "$LODKIT" convert -q --external-images "$clearcoat" "$TMP/external/clear coat.gltf"
check "ClearCoat with external images: the same scene" \
  test "$(canonical_scene_of "$clearcoat")" = "$(canonical_scene_of "$TMP/external/clear coat.gltf")"
check "six image files beside the .gltf" test "$(ls "$TMP/external" | grep -c '^clear coat_[0-5]\.\(png\|jpg\)$')" = 6
expect_output_contains '"uri":	"clear%20coat_4.jpg"' cat "$TMP/external/clear coat.gltf"
check "the .bin holds no image" test "$(stat -c %s "$TMP/external/clear coat.bin")" -lt 200000
expect_exit 2 "$LODKIT" convert -q --external-images "$clearcoat" "$TMP/external/clearcoat.glb"
mkdir -p "$TMP/external2/cc_2.png" # a folder where an image must go
expect_exit 1 "$LODKIT" convert -q --external-images "$clearcoat" "$TMP/external2/cc.gltf"
check "no .gltf or .bin left when an image cannot be written" test ! -e "$TMP/external2/cc.gltf" -a ! -e "$TMP/external2/cc.bin"

# The numbers of the round trip, once by hand: 82 nodes drawing 115
# primitives (meshes used by several nodes), 34 materials; the ClearCoat
# test's 10 textures and 6 images (bytes and hash as read from the files).
engine="$G/2CylinderEngine-glTF-Binary/2CylinderEngine.glb"
expect_output_contains "scene                82 nodes, 34 primitives, 55,843 vertices, 75,730 triangles, 34 materials, 0 textures" \
  "$LODKIT" info "$engine"
expect_output_contains '"drawn_primitives":115' "$LODKIT" info --json "$engine"
check "convert ClearCoat" "$LODKIT" convert -q "$G/ClearCoat-glTF/ClearCoatTest.gltf" "$TMP/clearcoat.glb"
expect_output_contains "27 primitives, 20,106 vertices, 37,116 triangles, 19 materials, 10 textures" \
  "$LODKIT" info "$TMP/clearcoat.glb"
checks=$((checks + 1))
images=$("$LODKIT" info -q --json "$TMP/clearcoat.glb" | grep -o '"fnv1a"' | wc -l)
[ "$images" -eq 6 ] || { echo "FAIL: clearcoat.glb holds $images images, expected 6"; failures=$((failures + 1)); }
checks=$((checks + 1))
png_bytes=$(stat -c %s "$G/ClearCoat-glTF/RibsNormal.png")
"$LODKIT" info -q --json "$TMP/clearcoat.glb" | grep -qF "\"bytes\":$png_bytes," ||
  { echo "FAIL: clearcoat.glb lacks RibsNormal.png's $png_bytes bytes"; failures=$((failures + 1)); }
# normal maps without tangents get them
expect_output_contains '"tangents"' "$LODKIT" info --json "$TMP/clearcoat.glb"

# What is left out is said.
# Morph targets are kept (the round trip above compares their deltas' hashes,
# the default weights and the animation of the weights): the cube's 2 targets
# with POSITION, NORMAL and TANGENT deltas, its "Square" animation of 127 keys
# on node 0's weights (254 values), and nothing said dropped.
morph="$G/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf"
check "convert morph cube" "$LODKIT" convert -q "$morph" "$TMP/morph.glb"
expect_output_contains '"targets":{"count":2,"positions":"4e49d698","normals":"973b3975","tangents":"59a252c5"}' \
  "$LODKIT" info -q --json "$TMP/morph.glb"
expect_output_contains '"channels":[{"sampler":0,"node":0,"path":"weights"}],"samplers":[{"interpolation":"LINEAR","keys":127,"components":1' \
  "$LODKIT" info -q --json "$TMP/morph.glb"
expect_output_contains "1 node, 1 primitive, 24 vertices, 12 triangles, 1 material, 0 textures, 2 morph targets, 1 animation" \
  "$LODKIT" info "$TMP/morph.glb"
checks=$((checks + 1))
if "$LODKIT" convert "$morph" "$TMP/morph.glb" 2>&1 | grep -q "note:"; then
  echo "FAIL: converting the morph cube still notes something dropped"; failures=$((failures + 1))
fi
# simplified to half its triangles, the targets stay with the surviving
# vertices (tests/unit/test_scene_morph.c measures the shapes' errors)
check "simplify morph cube" "$LODKIT" simplify -q --ratio=0.5 "$morph" "$TMP/morph-s.glb"
expect_output_contains "1 node, 1 primitive, 14 vertices, 6 triangles, 1 material, 0 textures, 2 morph targets, 1 animation" \
  "$LODKIT" info "$TMP/morph-s.glb"
expect_output_contains "note: materials[0].technique dropped (not a glTF 2.0 property)" \
  "$LODKIT" convert "$G/BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf" "$TMP/technique.glb"
expect_output_contains "TEXCOORD_1 without TEXCOORD_0 becomes TEXCOORD_0" \
  "$LODKIT" convert "$G/issue_3269/texcoord_crash.gltf" "$TMP/crash.glb"

# Skins and animations: the counts, and simplification keeps them whole
# (joints and weights carried to every kept vertex from its source vertex).
expect_output_contains "3 nodes, 1 primitive, 10 vertices, 8 triangles, 0 materials, 0 textures, 1 skin, 1 animation" \
  "$LODKIT" info "$G/simple_skin/simple_skin.gltf"
knight="$LK_SAMPLES_DIR/cge/knight/knight.gltf"
# skins_of FILE: the skins and animations of the "scene" object
skins_of() { scene_of "$1" | grep -o '"skins":.*' | sed 's/,"images":.*//'; }
# The knight (1 skin of 49 joints, 5 animations) comes with
# `scripts/fetch-samples.sh --bench` only; simple_skin (assimp-testmodels)
# is simplified the same way where it is missing.
skinned="$knight" counts="1 skin, 5 animations" attributes='"normals","texcoords","colors","joints","weights"]'
if [ ! -f "$knight" ]; then
  skinned="$G/simple_skin/simple_skin.gltf" counts="1 skin, 1 animation" attributes='["joints","weights"]'
fi
for flags in "" "--quantize --meshopt"; do
  # shellcheck disable=SC2086
  check "simplify $(basename "$skinned") $flags" "$LODKIT" simplify -q --ratio=0.3 $flags "$skinned" "$TMP/skinned-30.glb"
  expect_output_contains "$counts" "$LODKIT" info "$TMP/skinned-30.glb"
  expect_output_contains "$attributes" "$LODKIT" info --json "$TMP/skinned-30.glb"
  checks=$((checks + 1))
  expected_skins="$(skins_of "$skinned")" got_skins="$(skins_of "$TMP/skinned-30.glb")"
  expected_length=${#expected_skins} # before the cuts below: simple_skin's skin alone is 27 characters
  # compact output trims the animations (tests/unit/test_scene_anim_trim.c):
  # the skins are compared whole, the animations by their count above; and
  # it folds the positions' grid into the inverse bind matrices
  # (tests/unit/test_core_scene.c), so their hash is left out
  if [ -n "$flags" ]; then
    expected_skins="${expected_skins%%,\"animations\":*}" got_skins="${got_skins%%,\"animations\":*}"
    expected_skins="$(printf '%s' "$expected_skins" | sed 's/"inverse_bind_matrices":"[0-9a-f]*"//')"
    got_skins="$(printf '%s' "$got_skins" | sed 's/"inverse_bind_matrices":"[0-9a-f]*"//')"
  fi
  if [ "$expected_length" -lt 50 ] || [ "$expected_skins" != "$got_skins" ]; then
    echo "FAIL: $(basename "$skinned") simplified $flags lost its skins or animations:"
    diff <(tr ',' '\n' <<<"$expected_skins") <(skins_of "$TMP/skinned-30.glb" | tr ',' '\n') | head -8
    failures=$((failures + 1))
  fi
done

# simplify keeps the scene and maps each primitive to about the ratio.
check "simplify the engine" "$LODKIT" simplify -q --ratio=0.3 "$engine" "$TMP/engine-30.glb"
expect_output_contains "82 nodes, 34 primitives" "$LODKIT" info "$TMP/engine-30.glb"
expect_output_contains "34 materials" "$LODKIT" info "$TMP/engine-30.glb"
checks=$((checks + 1))
triangles=$("$LODKIT" info -q --json "$TMP/engine-30.glb" | sed 's/.*"scene"://' | grep -o '"triangles":[0-9]*' |
  cut -d: -f2 | awk '{ sum += $1 } END { print sum + 0 }')
if [ -z "$triangles" ] || [ "$triangles" -lt 18000 ] || [ "$triangles" -gt 24000 ]; then
  echo "FAIL: the engine at 30% has $triangles triangles in its meshes, expected about 22,719 of 75,730"
  failures=$((failures + 1))
fi
# The scene's triangles go where the measured error (Hausdorff, not only the
# QEM's mean) is largest: 0.32% of the diagonal at 30% (0.66% when the
# budget followed the QEM's errors alone).
checks=$((checks + 1))
percent=$("$LODKIT" metro --json "$engine" "$TMP/engine-30.glb" | python3 -c 'import json, sys; print(json.load(sys.stdin)["hausdorff_percent"])')
python3 -c "import sys; sys.exit(0 if $percent <= 0.45 else 1)" ||
  { echo "FAIL: the engine at 30%: Hausdorff $percent% of the diagonal, expected <= 0.45%"; failures=$((failures + 1)); }
# A level's floor tiles (24 triangles each, planar, a seam at every quad)
# keep their corners: the dungeon at 25% at 0.63% of the diagonal (1.35%
# before, when their corners were cut).
dungeon="$LK_SAMPLES_DIR/cge/level/level-dungeon.gltf"
if [ -f "$dungeon" ]; then
  check "simplify the dungeon" "$LODKIT" simplify -q --ratio=0.25 "$dungeon" "$TMP/dungeon-25.glb"
  checks=$((checks + 1))
  percent=$("$LODKIT" metro --json "$dungeon" "$TMP/dungeon-25.glb" | python3 -c 'import json, sys; print(json.load(sys.stdin)["hausdorff_percent"])')
  python3 -c "import sys; sys.exit(0 if $percent <= 0.8 else 1)" ||
    { echo "FAIL: the dungeon at 25%: Hausdorff $percent% of the diagonal, expected <= 0.8%"; failures=$((failures + 1)); }
fi
check "simplify ClearCoat" "$LODKIT" simplify -q --ratio=0.2 "$G/ClearCoat-glTF/ClearCoatTest.gltf" "$TMP/clearcoat-20.glb"
expect_output_contains "27 primitives" "$LODKIT" info "$TMP/clearcoat-20.glb"
expect_output_contains "19 materials, 10 textures" "$LODKIT" info "$TMP/clearcoat-20.glb"
expect_output_contains "attributes            normals texcoords" "$LODKIT" info "$TMP/clearcoat-20.glb"
checks=$((checks + 1))
[ "$(scene_of "$TMP/clearcoat-20.glb" | grep -o '"images":.*')" = "$(scene_of "$TMP/clearcoat.glb" | grep -o '"images":.*')" ] ||
  { echo "FAIL: simplify changed the ClearCoat images"; failures=$((failures + 1)); }
expect_output_contains '"metro"' "$LODKIT" simplify --json --measure --ratio=0.5 "$engine" "$TMP/engine-50.glb"

# A skinned mesh is simplified in its bind pose and as its joints pose it at
# rest, a merged vertex kept on one end (whose joints and weights it keeps):
# CGE's avatar (--bench samples) at 2,268 triangles, as drawn: Hausdorff
# 0.259% of the diagonal (0.933% in the bind pose alone; gltfpack 1.3 -si:
# 0.470%).
avatar="$LK_SAMPLES_DIR/cge/avatar/avatar.gltf"
if [ -f "$avatar" ]; then
  check "simplify the avatar" "$LODKIT" simplify -q --triangles=2268 "$avatar" "$TMP/avatar-s.glb"
  check "the avatar as drawn within 0.3% of the diagonal" python3 -c \
    'import json, sys; sys.exit(json.load(sys.stdin)["hausdorff_percent"] > 0.3)' \
    < <("$LODKIT" metro --json "$avatar" "$TMP/avatar-s.glb")
fi

# lod keeps the scene and adds a node per coarser level to every node
# drawing a mesh (67 of the engine's 82): 82 + 2 x 67 nodes, MSFT_lod.
check "lod the engine" "$LODKIT" lod -q --levels=3 "$engine" "$TMP/engine-lod.glb"
expect_output_contains "scene                216 nodes, 102 primitives" "$LODKIT" info "$TMP/engine-lod.glb"
check "MSFT_lod in the chain" grep -q '"MSFT_lod":{"ids":\[' "$TMP/engine-lod.glb"
check "screen coverage in the chain" grep -q '"MSFT_screencoverage":\[' "$TMP/engine-lod.glb"
expect_output_contains '"hausdorff_percent"' "$LODKIT" lod --json --measure --levels=2 "$G/BoxTextured-glTF/BoxTextured.gltf" "$TMP/box-lod.glb"
# the morph cube's weights animation drives every level (node 0 and its
# level nodes 1 and 2), not level 0 alone
check "lod the morph cube" "$LODKIT" lod -q --levels=3 "$morph" "$TMP/morph-lod.glb"
expect_output_contains '"channels":[{"sampler":0,"node":0,"path":"weights"},{"sampler":0,"node":1,"path":"weights"},{"sampler":0,"node":2,"path":"weights"}]' \
  "$LODKIT" info -q --json "$TMP/morph-lod.glb"
check "lod --separate of a scene" "$LODKIT" lod -q --levels=2 --separate "$G/BoxTextured-glTF/BoxTextured.gltf" "$TMP/box.glb"
expect_output_contains "1 material, 1 texture" "$LODKIT" info "$TMP/box_lod1.glb"

# render draws the materials: the box's base colour texture (PNG) before
# and after simplification; ClearCoat's labels and the others untextured.
expect_output_contains "materials: 1, 1 texture drawn" "$LODKIT" render -s 64x64 "$G/BoxTextured-glTF/BoxTextured.gltf" -o "$TMP/box.png"
expect_output_contains '"textures_drawn":1' "$LODKIT" render --json -s 64x64 "$TMP/box_lod1.glb" -o "$TMP/box1.png"
expect_output_contains '"textures_failed":0' "$LODKIT" render --json -s 64x64 "$TMP/clearcoat-20.glb" -o "$TMP/cc.png"

# Compact output (--quantize, --meshopt), as gltfpack writes it: what no
# material samples is dropped and the vertices it split are merged
# (monkey: its material has no texture, so no TEXCOORD_0 and 3,321 -> 2,012
# vertices); triangles whose corners became one vertex are dropped (the
# engine's 10,413 of 75,730); primitives with the same data share accessors
# (ClearCoat's 18 spheres: 3 kinds, with tangents, with texture coordinates,
# with neither); one bufferView per kind of data; normals through the
# octahedral filter. The positions stay within half a step of the scene's
# 14-bit grid on each axis: sqrt(3)/2 x 743.4 / 16383 of the diagonal 836.1,
# 0.0047%.
C="$LK_SAMPLES_DIR/cge"
check "meshopt engine" "$LODKIT" convert -q --meshopt "$engine" "$TMP/engine-m.glb"
expect_output_contains "82 nodes, 34 primitives, 55,843 vertices, 65,317 triangles" "$LODKIT" info "$TMP/engine-m.glb"
check "meshopt ClearCoat" "$LODKIT" convert -q --meshopt "$G/ClearCoat-glTF/ClearCoatTest.gltf" "$TMP/clearcoat-m.glb"
check "quantize ClearCoat" "$LODKIT" convert -q --quantize "$G/ClearCoat-glTF/ClearCoatTest.gltf" "$TMP/clearcoat-q.glb"
if [ -f "$C/monkey/monkey.gltf" ]; then
  check "meshopt monkey" "$LODKIT" convert -q --meshopt "$C/monkey/monkey.gltf" "$TMP/monkey-m.glb"
fi
# layout FILE: "distinct POSITION accessors of the spheres, bufferViews,
# attribute names, OCTAHEDRAL views" of a .glb.
layout() {
  python3 - "$1" <<'PY'
import json, struct, sys
data = open(sys.argv[1], 'rb').read()
doc = json.loads(data[20:20 + struct.unpack('<I', data[12:16])[0]])
spheres = {p['attributes']['POSITION'] for m in doc['meshes'] if m.get('name') == 'ClearCoatSampleMesh'
           for p in m['primitives']}
names = sorted({k for m in doc['meshes'] for p in m['primitives'] for k in p['attributes']})
octahedral = sum(v.get('extensions', {}).get('EXT_meshopt_compression', {}).get('filter') == 'OCTAHEDRAL'
                 for v in doc['bufferViews'])
print(len(spheres), len(doc['bufferViews']) - len(doc.get('images', [])), ','.join(names), octahedral)
PY
}
for pair in "clearcoat-m.glb:3 4 NORMAL,POSITION,TANGENT,TEXCOORD_0 1" "clearcoat-q.glb:3 4 NORMAL,POSITION,TANGENT,TEXCOORD_0 0" \
  "engine-m.glb:0 3 NORMAL,POSITION 1" "monkey-m.glb:0 3 NORMAL,POSITION 1"; do
  file="${pair%%:*}" expected="${pair#*:}"
  [ -f "$TMP/$file" ] || continue
  checks=$((checks + 1))
  got="$(layout "$TMP/$file")"
  [ "$got" = "$expected" ] || { echo "FAIL: $file: layout '$got', expected '$expected'"; failures=$((failures + 1)); }
done
[ -f "$TMP/monkey-m.glb" ] && expect_output_contains "1 primitive, 2,012 vertices, 3,936 triangles" "$LODKIT" info "$TMP/monkey-m.glb"
checks=$((checks + 1))
percent=$("$LODKIT" metro --json "$engine" "$TMP/engine-m.glb" | python3 -c 'import json, sys; print(json.load(sys.stdin)["hausdorff_percent"])')
python3 -c "import sys; sys.exit(0 if $percent <= 0.0047 else 1)" ||
  { echo "FAIL: engine-m.glb: Hausdorff $percent% of the diagonal, above the grid's bound (0.0047%)"; failures=$((failures + 1)); }

# OBJ with its .mtl (src/io_obj_scene.c): spider.obj's four used materials
# with their JPEG textures (map_Kd .\\NAME.jpg) reach the glTF whole, as
# `info --json` sees them (the glTF-Validator passes them:
# test_gltf_validate.sh); simplify and lod keep them; render draws them;
# what is missing is a note, not an error; OBJ to PLY stays a plain mesh.
O="$LK_SAMPLES_DIR/assimp/OBJ"
spider_scene="$(scene_of "$O/spider.obj")"
for ext in glb gltf; do
  expect_output_contains "spider.obj: 1 node, 4 primitives, 974 vertices, 1,368 triangles, 4 materials, 4 textures" \
    "$LODKIT" convert "$O/spider.obj" "$TMP/spider.$ext"
  checks=$((checks + 1))
  if [ -z "$spider_scene" ] || [ "$spider_scene" != "$(scene_of "$TMP/spider.$ext")" ]; then
    echo "FAIL: spider.obj converted to .$ext: its scene differs from the .obj's"; failures=$((failures + 1))
  fi
done
check "spider.glb embeds SpiderTex.jpg" grep -q '"name":"SpiderTex.jpg"' "$TMP/spider.glb"
check "spider.glb has Skin's Kd" grep -q '"name":"Skin","pbrMetallicRoughness":{"baseColorFactor":\[0.827451,0.792157,0.772549,1\]' "$TMP/spider.glb"
expect_output_contains "-> $TMP/spider-30.glb: 1 node, 4 primitives" "$LODKIT" simplify "$O/spider.obj" "$TMP/spider-30.glb" --ratio 0.3
# The exact counts of lodkit's QEM: 347 vertices and 409 triangles before
# issue 22's lighter border and crease constraints (Hausdorff distance of
# the scene 5.33% of the diagonal before, 2.34% after), 330 vertices before
# lk_scene_simplify also ran without the crease constraints and kept the
# closer scene (1.84%), 341 before the QEM queue's buckets went from 1/64 to
# 1/256 of an octave (1.81%).
expect_output_contains "1 node, 4 primitives, 338 vertices, 410 triangles, 4 materials, 4 textures" "$LODKIT" info "$TMP/spider-30.glb"
check "spider at 30%: Hausdorff below 2% of the diagonal" python3 -c "import json, subprocess, sys
d = json.loads(subprocess.run(['$LODKIT', 'metro', '--json', '$O/spider.obj', '$TMP/spider-30.glb'], capture_output=True, check=True).stdout)
sys.exit(0 if d['hausdorff_percent'] < 2.0 else 1)"
# CGE's knight (with `scripts/fetch-samples.sh --bench`): a low-polygon
# model whose sharp edges the crease constraints misrank; at gltfpack's 600
# of 646 triangles lodkit was at 0.61% (gltfpack 1.3 -si 0.25: 0.264%).
if [ -f "$knight" ]; then
  check "simplify knight to 600 triangles" "$LODKIT" simplify -q --triangles=600 "$knight" "$TMP/knight-600.glb"
  check "knight at 600 triangles: Hausdorff below 0.26% of the diagonal" python3 -c "import json, subprocess, sys
d = json.loads(subprocess.run(['$LODKIT', 'metro', '--json', '$knight', '$TMP/knight-600.glb'], capture_output=True, check=True).stdout)
sys.exit(0 if d['hausdorff_percent'] < 0.26 else 1)"
fi
check "lod of spider.obj" "$LODKIT" lod -q --levels=2 "$O/spider.obj" "$TMP/spider-lod.glb"
expect_output_contains "2 nodes, 8 primitives" "$LODKIT" info "$TMP/spider-lod.glb"
expect_output_contains '"materials":4,"textures_drawn":4,"textures_failed":0' \
  "$LODKIT" render --json -s 96x96 "$O/spider.obj" -o "$TMP/spider.png"
expect_output_contains "scene                1 node, 4 primitives" "$LODKIT" info "$O/spider.obj"
"$LODKIT" info --json "$O/cube_with_vertexcolors.obj" >"$TMP/box-info.json"
check "no scene in info of an OBJ without materials" test -z "$(grep -o '"scene"' "$TMP/box-info.json")"
mkdir -p "$TMP/obj"
cp "$O/spider.obj" "$O/spider.mtl" "$O/SpiderTex.jpg" "$TMP/obj/"
expect_output_contains 'note: material "Skin": texture wal67ar_small.jpg not read (cannot open: No such file or directory)' \
  "$LODKIT" convert "$TMP/obj/spider.obj" "$TMP/obj/spider.glb"
expect_output_contains "4 materials, 1 texture" "$LODKIT" info "$TMP/obj/spider.glb"
rm "$TMP/obj/spider.mtl"
expect_output_contains "note: $TMP/obj/spider.obj:3: mtllib spider.mtl not read" \
  "$LODKIT" convert "$TMP/obj/spider.obj" "$TMP/obj/spider.glb"
printf 'newmtl Skin\nKd 0.5 red 1\n' >"$TMP/obj/spider.mtl"
expect_output_contains "$TMP/obj/spider.mtl:2: unexpected 'red'" \
  "$LODKIT" convert "$TMP/obj/spider.obj" "$TMP/obj/bad.glb"
check "no output after a bad .mtl" test ! -e "$TMP/obj/bad.glb"
expect_output_contains "spider.obj: 974 vertices, 1,368 triangles -> $TMP/spider.ply" \
  "$LODKIT" convert "$O/spider.obj" "$TMP/spider.ply"

# Bad input names the item and writes nothing.
mkdir -p "$TMP/noimage"
cp "$G/BoxTextured-glTF/BoxTextured.gltf" "$G/BoxTextured-glTF/BoxTextured0.bin" "$TMP/noimage/"
expect_output_contains 'images[0].uri: cannot open "CesiumLogoFlat.png"' \
  "$LODKIT" convert "$TMP/noimage/BoxTextured.gltf" "$TMP/noimage.glb"
check "no output after a missing image" test ! -e "$TMP/noimage.glb"
cp "$G/BoxTextured-glTF/CesiumLogoFlat.png" "$TMP/noimage/"
sed 's/"source" *: *0/"source": 3/' "$G/BoxTextured-glTF/BoxTextured.gltf" >"$TMP/noimage/source.gltf"
expect_output_contains 'textures[0].source: images 3 out of range (1 images)' \
  "$LODKIT" convert "$TMP/noimage/source.gltf" "$TMP/source.glb"
sed 's/"material" *: *0/"material": 7/' "$G/BoxTextured-glTF/BoxTextured.gltf" >"$TMP/noimage/material.gltf"
expect_output_contains 'meshes[0].primitives[0].material: materials 7 out of range (1 materials)' \
  "$LODKIT" convert "$TMP/noimage/material.gltf" "$TMP/material.glb"
check "no output after a bad reference" test ! -e "$TMP/source.glb" -a ! -e "$TMP/material.glb"
finish
