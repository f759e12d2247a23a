#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# three.js's GLTFLoader (npm three, pinned in tests/browser/package-lock.json)
# loads every kind of glTF lodkit writes, in headless Chromium, with the
# counts lodkit's own reader sees (issue 20): convert to .glb, .gltf + .bin,
# --quantize and --meshopt (decoded by three's MeshoptDecoder) for a mesh
# without attributes, one with normals, a point set with normals, a mesh
# with colours and one with normals and texture coordinates; simplify
# --meshopt; MSFT_lod chains plain and compressed; a skinned, animated
# scene (CGE's knight: one THREE.SkinnedMesh, 5 clips, posed by its joints
# as three.js poses the input) converted, quantised and simplified; an
# animate morph-target .gltf. The expected counts and attributes are `lodkit info` of the same
# output file; the bounding box is that of the input (of the output itself
# after simplify and animate). tests/browser/gltf-three.test.mjs says what
# is compared, and draws each file.
# The harness is shown to fail: wrong expected counts and attributes, a
# missing file, and a quantised file whose node lost its scale and
# translation (the dequantisation three.js must do) are each reported.
# Needs node, /usr/bin/chromium and tests/browser/node_modules (three,
# playwright-core), which scripts/install-deps.sh installs: without them the
# test says what is missing and fails. It never installs anything itself.
set -u
source "$(dirname "$0")/lib.sh"
browser_dir="$(cd "$(dirname "$0")/../browser" && pwd)"
S="$LK_SAMPLES_DIR"

require node nodejs
[ -x /usr/bin/chromium ] || { echo "FAIL: this test needs /usr/bin/chromium (Debian package: chromium); run scripts/install-deps.sh"; exit 1; }
for module in three playwright-core; do
  if [ ! -d "$browser_dir/node_modules/$module" ]; then
    echo "FAIL: $browser_dir/node_modules lacks $module; run scripts/install-deps.sh (npm ci from the lock file)"
    exit 1
  fi
done

O="$TMP/out"
mkdir -p "$O"
manifest="$TMP/manifest.json"
entries=()

# json_field NAME JSON: the number after "NAME": in lodkit's one-line JSON.
json_field() { grep -o "\"$1\":[-0-9.e]*" <<<"$2" | head -1 | cut -d: -f2; }

# entry FILE BBOX_SOURCE [FLAGS]: a manifest entry for $O/FILE, its counts and
# attributes as `lodkit info` reads them, its box that of BBOX_SOURCE (or
# three:FILE, what three.js saw for that earlier entry; -: none); FLAGS is
# quantized, meshopt (implies quantized), levels=N, scene, skinned=N (number
# of THREE.SkinnedMesh), animations=N (clips), lines=N (line segments) and/or
# offbox (an input three.js draws outside its box).
entry() {
  local file="$1" bbox_source="$2" flags="${3:-}" info text bbox_info vertices triangles attributes kind extra=""
  checks=$((checks + 1))
  if ! info=$("$LODKIT" info -q --json "$O/$file" 2>&1) || ! text=$("$LODKIT" info -q "$O/$file" 2>&1) ||
     ! bbox_info=$("$LODKIT" info -q --json "$(case "$bbox_source" in three:* | -) echo "$O/$file" ;; *) echo "$bbox_source" ;; esac)" 2>&1); then
    echo "FAIL: lodkit info $file or $bbox_source: $info"; failures=$((failures + 1)); return
  fi
  vertices=$(json_field vertices "$info")
  triangles=$(json_field triangles "$info")
  attributes=$(sed -n 's/^attributes *//p' <<<"$text" | tr -s ' ' '\n' | sed -n 's/^normals$/"normal"/p; s/^texcoords$/"uv"/p; s/^colors$/"color"/p' |
    paste -sd,)
  kind=mesh
  [ "$triangles" = 0 ] && kind=points
  case " $flags " in *" meshopt "*) extra+=',"meshopt":true,"quantized":true' ;; *" quantized "*) extra+=',"quantized":true' ;; esac
  case " $flags " in *" levels="*) extra+=",\"levels\":$(sed 's/.*levels=\([0-9]*\).*/\1/' <<<"$flags")" ;; esac
  local meshes=1
  # a scene: three.js makes one mesh per primitive a node draws
  case " $flags " in *" scene "*) meshes=$(json_field drawn_primitives "$info"); extra+=',"scene":true' ;; esac
  case " $flags " in *" skinned="*) extra+=",\"skinned\":$(sed 's/.*skinned=\([0-9]*\).*/\1/' <<<"$flags")" ;; esac
  case " $flags " in *" morph="*) extra+=",\"morph\":$(sed 's/.*morph=\([0-9]*\).*/\1/' <<<"$flags")" ;; esac
  case " $flags " in *" offbox "*) extra+=',"offBox":true' ;; esac
  case " $flags " in *" lines="*) extra+=",\"lines\":$(sed 's/.*lines=\([0-9]*\).*/\1/' <<<"$flags")" ;; esac
  case " $flags " in *" animations="*) extra+=",\"animations\":$(sed 's/.*animations=\([0-9]*\).*/\1/' <<<"$flags")" ;; esac
  local box
  box=$(grep -o '"bbox":{[^}]*}' <<<"$bbox_info")
  # a skinned mesh is posed by its joints, not placed by its node as in
  # lodkit's box
  case "$bbox_source" in three:*) box="\"bboxOf\":\"${bbox_source#three:}\"" ;; -) box='"bboxOf":null' ;; esac
  entries+=("{\"file\":\"$file\",\"kind\":\"$kind\",\"meshes\":$meshes,\"vertices\":$vertices,\"triangles\":$triangles,\"attributes\":[$attributes],$box$extra}")
}
write_manifest() {  # write_manifest FILE ENTRY...
  local file="$1"; shift
  local IFS=,
  printf '{"files":[\n%s\n]}\n' "$*" | sed 's/},{"file"/},\n{"file"/g' >"$file"
}

# ---- the outputs -------------------------------------------------------------
# name:input; the cow's .gltf has a space in its name (the .bin's URI is
# percent-encoded).
for pair in "cow:cow.off" "bunny:bunny.obj" "hippo:hippo1.ply" "float-color:assimp/PLY/float-color.ply" \
  "box:assimp/glTF2/BoxTextured-glTF/BoxTextured.gltf"; do
  name="${pair%%:*}" input="$S/${pair#*:}"
  gltf="$name.gltf"
  [ "$name" = cow ] && gltf="cow text.gltf"
  check "convert $name .glb" "$LODKIT" convert -q "$input" "$O/$name.glb" && entry "$name.glb" "$input"
  check "convert $name .gltf" "$LODKIT" convert -q "$input" "$O/$gltf" && entry "$gltf" "$input"
  check "convert $name --quantize" "$LODKIT" convert -q --quantize "$input" "$O/$name-q.glb" && entry "$name-q.glb" "$input" quantized
  check "convert $name --meshopt" "$LODKIT" convert -q --meshopt "$input" "$O/$name-m.glb" && entry "$name-m.glb" "$input" meshopt
done
check "the .bin beside the .gltf" test -s "$O/cow text.bin"
check "simplify bunny --meshopt" "$LODKIT" simplify -q --ratio=0.1 --meshopt "$S/bunny.obj" "$O/bunny-10-m.glb" &&
  entry bunny-10-m.glb "$O/bunny-10-m.glb" meshopt
check "lod cow" "$LODKIT" lod -q --levels=3 "$S/cow.off" "$O/cow-lod.glb" && entry cow-lod.glb "$S/cow.off" levels=3
check "lod bunny --meshopt" "$LODKIT" lod -q --levels=3 --meshopt "$S/bunny.obj" "$O/bunny-lod-m.glb" &&
  entry bunny-lod-m.glb "$S/bunny.obj" "meshopt levels=3"
# Scenes (glTF in, glTF out): many nodes and instanced meshes, textures and
# normal maps (generated tangents), texture transforms; quantised (a mesh on
# a node with children moves to a new child node), compressed, simplified.
G="$S/assimp/glTF2"
for pair in "engine:2CylinderEngine-glTF-Binary/2CylinderEngine.glb" "clearcoat:ClearCoat-glTF/ClearCoatTest.gltf" \
  "transform:textureTransform/TextureTransformTest.gltf"; do
  name="${pair%%:*}" input="$G/${pair#*:}"
  check "convert scene $name" "$LODKIT" convert -q "$input" "$O/$name.glb" && entry "$name.glb" "$input" scene
  check "convert scene $name --quantize" "$LODKIT" convert -q --quantize "$input" "$O/$name-q.glb" &&
    entry "$name-q.glb" "$input" "scene quantized"
  check "convert scene $name --meshopt" "$LODKIT" convert -q --meshopt "$input" "$O/$name-m.glb" &&
    entry "$name-m.glb" "$input" "scene meshopt"
done
# a box with 18 line segments added (tests/cli/gltf_add_lines.py): a Mesh and
# a LineSegments, plain and through MeshoptDecoder (meshopt's INDICES codec)
python3 "$(dirname "$0")/gltf_add_lines.py" "$G/BoxTextured-glTF-Embedded/BoxTextured.gltf" "$TMP/box-lines.gltf"
check "convert box with lines" "$LODKIT" convert -q "$TMP/box-lines.gltf" "$O/box-lines.glb" &&
  entry box-lines.glb "$TMP/box-lines.gltf" "scene lines=18"
check "convert box with lines --meshopt" "$LODKIT" convert -q --meshopt "$TMP/box-lines.gltf" "$O/box-lines-m.glb" &&
  entry box-lines-m.glb "$TMP/box-lines.gltf" "scene meshopt lines=18"
check "convert clearcoat --external-images" "$LODKIT" convert -q --external-images "$G/ClearCoat-glTF/ClearCoatTest.gltf" \
  "$O/clearcoat-ext.gltf" && entry clearcoat-ext.gltf "$G/ClearCoat-glTF/ClearCoatTest.gltf" scene
check "simplify scene engine --meshopt" "$LODKIT" simplify -q --ratio=0.25 --meshopt "$G/2CylinderEngine-glTF-Binary/2CylinderEngine.glb" \
  "$O/engine-25-m.glb" && entry engine-25-m.glb "$O/engine-25-m.glb" "scene meshopt"
# A skinned, animated scene: one THREE.SkinnedMesh and 5 clips, posed by
# its joints as three.js poses the input file (under --quantize and
# --meshopt its positions are on a grid that the skin's inverse bind
# matrices undo, its weights bytes, its rotation keys shorts, with
# --meshopt through meshopt's quaternion and exponential filters).
# The knight comes with `scripts/fetch-samples.sh --bench` only; where it is
# missing, simple_skin (1 skin, 1 animation; assimp-testmodels) stands in.
skin_dir="$S/cge/knight" skin_name=knight skin_files=(knight.gltf knight.bin knight.png) clips=5
if [ ! -f "$skin_dir/knight.gltf" ]; then
  skin_dir="$G/simple_skin" skin_name=simple_skin skin_files=(simple_skin.gltf) clips=1
fi
mkdir -p "$O/skin-in"
for f in "${skin_files[@]}"; do cp "$skin_dir/$f" "$O/skin-in/"; done
entry "skin-in/$skin_name.gltf" - "scene skinned=1 animations=$clips"
check "convert $skin_name" "$LODKIT" convert -q "$O/skin-in/$skin_name.gltf" "$O/$skin_name.glb" &&
  entry "$skin_name.glb" "three:skin-in/$skin_name.gltf" "scene skinned=1 animations=$clips"
check "convert $skin_name --quantize" "$LODKIT" convert -q --quantize "$O/skin-in/$skin_name.gltf" "$O/$skin_name-q.glb" &&
  entry "$skin_name-q.glb" "three:skin-in/$skin_name.gltf" "scene quantized skinned=1 animations=$clips"
check "convert $skin_name --meshopt" "$LODKIT" convert -q --meshopt "$O/skin-in/$skin_name.gltf" "$O/$skin_name-m.glb" &&
  entry "$skin_name-m.glb" "three:skin-in/$skin_name.gltf" "scene meshopt skinned=1 animations=$clips"
# simple_skin below a transformed parent (tests/cli/gltf_nest.py): the writer
# moves the skinned mesh to a root node; three.js computes the same posed
# box for both, but draws the input outside it (the validator's
# NODE_SKINNED_MESH_NON_ROOT warning is about that) and the output inside.
python3 "$(dirname "$0")/gltf_nest.py" "$G/simple_skin/simple_skin.gltf" "$O/skin-in/nested.gltf"
entry skin-in/nested.gltf - "scene skinned=1 animations=1 offbox"
check "convert nested skin" "$LODKIT" convert -q "$O/skin-in/nested.gltf" "$O/nested.glb" &&
  entry nested.glb "three:skin-in/nested.gltf" "scene skinned=1 animations=1"
# simplified: posed as three.js poses the same simplification uncompressed
check "simplify $skin_name" "$LODKIT" simplify -q --ratio=0.3 "$O/skin-in/$skin_name.gltf" "$O/$skin_name-30.glb" &&
  entry "$skin_name-30.glb" - "scene skinned=1 animations=$clips"
check "simplify $skin_name --meshopt" "$LODKIT" simplify -q --ratio=0.3 --quantize --meshopt \
  "$O/skin-in/$skin_name.gltf" "$O/$skin_name-30-m.glb" &&
  entry "$skin_name-30-m.glb" "three:$skin_name-30.glb" "scene meshopt skinned=1 animations=$clips"
# Morph targets: AnimatedMorphCube's 2 targets and the animation of their
# weights through convert (plain, quantised, compressed: positions stay
# floats) and simplify, three.js making morphAttributes of each.
morph="$G/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf"
check "convert morph cube" "$LODKIT" convert -q "$morph" "$O/morph-cube.glb" &&
  entry morph-cube.glb "$morph" "scene morph=2 animations=1"
check "convert morph cube --quantize" "$LODKIT" convert -q --quantize "$morph" "$O/morph-cube-q.glb" &&
  entry morph-cube-q.glb "$morph" "scene quantized morph=2 animations=1"
check "convert morph cube --meshopt" "$LODKIT" convert -q --meshopt "$morph" "$O/morph-cube-m.glb" &&
  entry morph-cube-m.glb "$morph" "scene meshopt morph=2 animations=1"
check "simplify morph cube" "$LODKIT" simplify -q --ratio=0.5 "$morph" "$O/morph-cube-50.glb" &&
  entry morph-cube-50.glb - "scene morph=2 animations=1"
check "animate morph cube" "$LODKIT" animate -q --levels=2 --no-metro \
  "$S/assimp/glTF2/glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf" "$O/morph"
entry morph/AnimatedMorphCube-max-L01.gltf "$O/morph/AnimatedMorphCube-max-L01.gltf"
write_manifest "$manifest" "${entries[@]}"

# ---- three.js ------------------------------------------------------------------
checks=$((checks + 1))
if ! (cd "$browser_dir" && timeout -k 5 60 node gltf-three.test.mjs "$O" "$manifest"); then
  echo "FAIL: three.js does not see in lodkit's glTF what lodkit's reader sees (lines 'not ok' above)"
  failures=$((failures + 1))
fi

# ---- the harness fails when it should ------------------------------------------
# cow-q.glb with its node's scale and translation removed: the quantised
# positions (0..16383) are then read as model units, far outside the box.
(cd "$browser_dir" && node --input-type=module -e '
import fs from "node:fs";
const [from, to] = process.argv.slice(1);
const glb = fs.readFileSync(from);
const jsonLength = glb.readUInt32LE(12);
const json = JSON.parse(glb.subarray(20, 20 + jsonLength).toString());
delete json.nodes[0].scale;
delete json.nodes[0].translation;
let text = JSON.stringify(json);
text += " ".repeat((4 - (text.length % 4)) % 4);
const header = Buffer.alloc(20);
const rest = glb.subarray(20 + jsonLength);
header.write("glTF", 0);
header.writeUInt32LE(2, 4);
header.writeUInt32LE(20 + text.length + rest.length, 8);
header.writeUInt32LE(text.length, 12);
header.writeUInt32LE(0x4e4f534a, 16);
fs.writeFileSync(to, Buffer.concat([header, Buffer.from(text), rest]));
' "$O/cow-q.glb" "$O/cow-q-unplaced.glb")
good=$(grep -F '"file":"cow-q.glb"' "$manifest" | sed 's/,$//')
write_manifest "$TMP/negative.json" \
  "$good" \
  "$(sed 's/"triangles":5804/"triangles":5805/' <<<"$good")" \
  "$(sed 's/"attributes":\[\]/"attributes":["uv"]/' <<<"$good")" \
  "$(sed 's/"cow-q.glb"/"no-such-file.glb"/' <<<"$good")" \
  "$(sed 's/"cow-q.glb"/"cow-q-unplaced.glb"/' <<<"$good")"
checks=$((checks + 1))
(cd "$browser_dir" && timeout -k 5 60 node gltf-three.test.mjs "$O" "$TMP/negative.json") >"$TMP/negative.txt" 2>&1
status=$?
if [ "$status" -ne 1 ]; then
  echo "FAIL: the harness exits $status on a manifest with wrong expectations (1 expected):"
  sed 's/^/  /' "$TMP/negative.txt"
  failures=$((failures + 1))
fi
# negative TEXT: the negative run's report has a line with TEXT.
negative() {
  checks=$((checks + 1))
  if ! grep -qE -- "$1" "$TMP/negative.txt"; then
    echo "FAIL: the harness does not report '$1':"; sed 's/^/  /' "$TMP/negative.txt"; failures=$((failures + 1))
  fi
}
negative '^ok - cow-q\.glb: '
negative '^not ok - cow-q\.glb: 5804 triangles, expected 5805'
negative '^not ok - cow-q\.glb: no uv attribute'
negative '^not ok - no-such-file\.glb: GLTFLoader failed'
negative '^not ok - cow-q-unplaced\.glb: .*bbox .* is off by .*; not drawn'
negative '^5 checks, 4 failed'
finish
