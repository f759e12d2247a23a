#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Hostile sizes through the CLI (issue 10): --max-memory (before or after
# the command, LODKIT_MAX_MEMORY, usage errors), the bunny refused under
# 1M with a message naming the budget, and files whose headers claim
# billions of elements, 4 GB chunks or 100,000 nested JSON arrays: each is
# refused with exit 1 and a message saying where, and the peak RSS of the
# process (GNU time %M) stays small. Every hostile file is generated here.
set -u
source "$(dirname "$0")/lib.sh"
samples="$LK_SAMPLES_DIR"
# GNU time (not the shell keyword) reports the peak RSS; python3 writes a
# stream with valid CRCs. Both come from scripts/install-deps.sh.
[ -x /usr/bin/time ] || { echo "FAIL: this test needs /usr/bin/time (Debian package: time); run scripts/install-deps.sh"; exit 1; }
require python3 python3

# Runs a command under GNU time and prints its peak RSS in KiB on the last
# line of $TMP/rss; returns the command's exit status (GNU time passes it on).
peak_rss() {
  timeout -k 5 120 /usr/bin/time -o "$TMP/rss" -f %M "$@" >"$TMP/out" 2>"$TMP/err"
}
# refused_small DESCRIPTION NEEDLE COMMAND...: exit 1, NEEDLE in the output, peak RSS < 200 MB
refused_small() {
  local description="$1" needle="$2"; shift 2
  peak_rss "$@"
  local code=$?
  checks=$((checks + 1))
  if [ "$code" -ne 1 ]; then
    echo "FAIL: $description: exit $code, expected 1 ($(head -c 300 "$TMP/err"))"; failures=$((failures + 1)); return
  fi
  if ! cat "$TMP/err" "$TMP/out" | grep -qF -- "$needle"; then
    echo "FAIL: $description: output lacks '$needle': $(head -c 300 "$TMP/err")"; failures=$((failures + 1)); return
  fi
  local kb
  kb=$(tail -n 1 "$TMP/rss")
  if [ "$kb" -gt 204800 ]; then
    echo "FAIL: $description: peak RSS $kb KiB"; failures=$((failures + 1))
  fi
}

# ---- the option ------------------------------------------------------------
expect_output_contains "--max-memory=SIZE" "$LODKIT" --help
for command in info convert simplify progressive unpack inspect animate terrain slices render sample splat; do
  expect_output_contains "--max-memory=SIZE" "$LODKIT" $command --help
done
expect_exit 2 "$LODKIT" --max-memory
expect_exit 2 "$LODKIT" --max-memory 12Q info "$samples/cow.off"
expect_exit 2 "$LODKIT" info --max-memory=0 "$samples/cow.off"
expect_exit 2 "$LODKIT" info --max-memory=-5M "$samples/cow.off"
export LODKIT_MAX_MEMORY=lots
expect_exit 2 "$LODKIT" info "$samples/cow.off"
unset LODKIT_MAX_MEMORY

# the bunny (2.4 MB file, 1.25 MB of arrays) under 1M: before and after the
# command, as --max-memory=1M, and from the environment; the option wins
refused_small "bunny, 1M before" "more than the memory budget of 1048576 bytes" \
  "$LODKIT" --max-memory 1M simplify --ratio=0.5 "$samples/bunny.obj" "$TMP/b.obj"
refused_small "bunny, 1M after" "memory budget of 1048576 bytes (--max-memory)" \
  "$LODKIT" simplify --max-memory 1M --ratio=0.5 "$samples/bunny.obj" "$TMP/b.obj"
check "no output after a refusal" test ! -e "$TMP/b.obj"
refused_small "bunny, =1M" "1048576" "$LODKIT" info --max-memory=1M "$samples/bunny.obj"
LODKIT_MAX_MEMORY=1M refused_small "bunny, env" "1048576" "$LODKIT" info "$samples/bunny.obj"
LODKIT_MAX_MEMORY=1M expect_exit 0 "$LODKIT" --max-memory 64M info "$samples/bunny.obj"
expect_exit 0 "$LODKIT" --max-memory 64M info "$samples/bunny.obj"
expect_exit 0 "$LODKIT" info --max-memory 4MiB "$samples/bunny.obj"
# a file far under the budget whose arrays are not: a million vertices of
# zeros (an accessor without a bufferView) in a 200-byte glTF
printf '%s' '{"asset":{"version":"2.0"},"accessors":[{"componentType":5126,"count":1000000,"type":"VEC3"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0},"mode":0}]}]}' >"$TMP/million.gltf"
refused_small "arrays over the budget" "1000000 vertices and 0 triangles, more than the memory budget of 4194304 bytes" \
  "$LODKIT" info --max-memory=4M "$TMP/million.gltf"
expect_exit 0 "$LODKIT" info --max-memory=16M "$TMP/million.gltf"
# the other readers of the CLI get the budget too
refused_small "animate" "memory budget of 262144 bytes" \
  "$LODKIT" animate --max-memory 256K --ratio=0.5 "$samples/faerie.md2" "$TMP/anim"
refused_small "terrain" "max_samples" "$LODKIT" terrain --max-memory 1M --flight=2 "$samples/jacksboro_fault_dem.npz"
"$LODKIT" progressive -q "$samples/cow.off" "$TMP/cow.lks"
refused_small "unpack" "header at byte 24: 2904 vertices" "$LODKIT" unpack --max-memory 64K "$TMP/cow.lks" "$TMP/c.obj"
expect_exit 0 "$LODKIT" unpack --max-memory 1M -q "$TMP/cow.lks" "$TMP/c.obj"
# The file and the decoder share the budget (issue 17): the bunny's version-1
# stream (~314 KB) needs 1,382,700 bytes to decode, which fits 1448K alone but
# not beside the file; 1800K holds both.
"$LODKIT" progressive -q --stream-version=1 "$samples/bunny.obj" "$TMP/bunny.lks"
refused_small "unpack: file and decoder together" "what --max-memory leaves beside the file's" \
  "$LODKIT" unpack --max-memory 1448K "$TMP/bunny.lks" "$TMP/b.obj"
expect_exit 0 "$LODKIT" unpack --max-memory 1800K -q "$TMP/bunny.lks" "$TMP/b.obj"
# Version 2 (the default): 2,369,764 bytes of decoder state (per vertex 20,
# per triangle 24) plus what a chunk needs beside it (chunk 11: about 100 KB;
# the exact count follows the chunk's size) next to the 120 KB file: 2500K
# is too little, 2800K enough.
"$LODKIT" progressive -q "$samples/bunny.obj" "$TMP/bunny2.lks"
refused_small "unpack v2: decoder state" "34835 vertices and 69666 triangles need 2369764 bytes" \
  "$LODKIT" unpack --max-memory 1800K "$TMP/bunny2.lks" "$TMP/b.obj"
refused_small "unpack v2: a chunk beside the state" "bytes next to the 2369764 of the decoder state" \
  "$LODKIT" unpack --max-memory 2500K "$TMP/bunny2.lks" "$TMP/b.obj"
expect_exit 0 "$LODKIT" unpack --max-memory 2800K -q "$TMP/bunny2.lks" "$TMP/b.obj"
lks_bytes=$(stat -c %s "$TMP/cow.lks")
refused_small "inspect" "the file has $lks_bytes bytes" "$LODKIT" inspect --max-memory 1K "$TMP/cow.lks"

# ---- hostile headers -----------------------------------------------------------
printf 'ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n' >"$TMP/v.ply"
refused_small "ply 4e9 vertices" "v.ply:3: header claims 4000000000 vertices" "$LODKIT" info "$TMP/v.ply"
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 9223372036854775807\nproperty float x\nproperty float y\nproperty float z\nend_header\n' >"$TMP/w.ply"
refused_small "ply 2^63-1 vertices" "more than lodkit supports" "$LODKIT" info "$TMP/w.ply"
printf 'OFF\n3 4000000000 0\n0 0 0\n1 0 0\n0 1 0\n' >"$TMP/f.off"
refused_small "off 4e9 faces" "f.off:2: header claims 4000000000 faces" "$LODKIT" convert "$TMP/f.off" "$TMP/f.ply"
# MD2 claiming 2^31-1 frames, then 2^31-1 triangles
md2() {  # md2 FRAMES TRIANGLES: a 120-byte file
  local le
  le() { printf '\\x%02x\\x%02x\\x%02x\\x%02x' $(($1 & 255)) $((($1 >> 8) & 255)) $((($1 >> 16) & 255)) $((($1 >> 24) & 255)); }
  { printf 'IDP2'; for v in 8 0 0 44 0 1 0 "$2" 0 "$1" 68 68 68 68 120 120; do printf "$(le "$v")"; done; head -c 52 /dev/zero; }
}
md2 2147483647 0 >"$TMP/frames.md2"
refused_small "md2 frames" "frames.md2: byte 40: 2147483647 frames is more than the limit" "$LODKIT" info "$TMP/frames.md2"
md2 1 2147483647 >"$TMP/tris.md2"
refused_small "md2 triangles" "triangle block (2147483647 x 12 bytes) runs past the end" "$LODKIT" info "$TMP/tris.md2"
# KMF claiming a trillion frames
printf 'kmf 1\nframes 1000000000000\nfps 10\nframe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' >"$TMP/t.kmf"
refused_small "kmf frames" "t.kmf:2: 1000000000000 frames is more than the limit" \
  "$LODKIT" animate --ratio=0.5 "$TMP/t.kmf" "$TMP/anim2"
# GLB whose JSON chunk claims 4 GB
{ printf 'glTF\x02\x00\x00\x00\x1c\x00\x00\x00\xff\xff\xff\xffJSON'; head -c 8 /dev/zero; } >"$TMP/chunk.glb"
refused_small "glb chunk" "chunk.glb: byte 12: chunk 0 claims 4294967295 bytes" "$LODKIT" info "$TMP/chunk.glb"
# 100,000 nested arrays
{ printf '{"asset":{"version":"2.0"},"extras":'; head -c 100000 /dev/zero | tr '\0' '['; head -c 100000 /dev/zero | tr '\0' ']'; printf '}'; } >"$TMP/deep.gltf"
refused_small "deep json" "deep.gltf: byte 547: JSON nested deeper than 512 levels" "$LODKIT" info "$TMP/deep.gltf"
# 30 MB of whitespace around a real one-triangle document: read with the
# default budget, refused under 8M (file) and under 40M (the parse)
doc='{"asset":{"version":"2.0"},"buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],"bufferViews":[{"buffer":0,"byteLength":36}],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]'
{ printf '%s' "$doc"; head -c 30000000 /dev/zero | tr '\0' ' '; printf '}'; } >"$TMP/spaces.gltf"
out=$(timeout -k 5 120 "$LODKIT" info --json "$TMP/spaces.gltf")
check "whitespace gltf reads" grep -q '"vertices":3,"triangles":1' <<<"$out"
refused_small "whitespace gltf, 8M" "the file has 30000" "$LODKIT" --max-memory 8M info "$TMP/spaces.gltf"
refused_small "whitespace gltf, 40M" "(+ 16 MiB for parsing)" "$LODKIT" --max-memory 40M info "$TMP/spaces.gltf"
# an accessor of 4e9 zeros (no bufferView)
printf '%s' '{"asset":{"version":"2.0"},"accessors":[{"componentType":5126,"count":4000000000,"type":"VEC3"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0},"mode":0}]}]}' >"$TMP/zeros.gltf"
refused_small "gltf zeros" "the scene reaches 4000000000 vertices" "$LODKIT" info "$TMP/zeros.gltf"
# a PGM heightmap of 100000 x 100000
printf 'P5\n100000 100000\n65535\n\x00\x01' >"$TMP/big.pgm"
refused_small "pgm" "big.pgm: 100000x100000 grid" "$LODKIT" terrain --flight=2 "$TMP/big.pgm"
# a .lks whose only chunk is 4 GB long (header and table CRCs valid)
python3 - "$TMP/huge.lks" <<'EOF'
import struct, sys, zlib
chunk = 0xFFFFFFF0
header = bytearray(96)
header[0:8] = b'\x89LKS\r\n\x1a\n'
struct.pack_into('<HHIQ', header, 8, 1, 0, 132, 132 + chunk)
struct.pack_into('<9I', header, 24, 3, 1, 3, 1, 0, 3, 1, 1024, 8)
struct.pack_into('<3f', header, 72, 1, 1, 1)
struct.pack_into('<I', header, 92, zlib.crc32(bytes(header[:92])))
entry = struct.pack('<QIIIIII', 132, chunk, chunk - 8, 0, 0, 1, 0)
sys.stdout = open(sys.argv[1], 'wb')
sys.stdout.write(bytes(header) + entry + struct.pack('<I', zlib.crc32(entry)))
EOF
refused_small "lks 4 GB chunk" "chunk table entry 0 at byte 104: a chunk of 4294967280 bytes" \
  "$LODKIT" unpack --max-memory 1G "$TMP/huge.lks" "$TMP/h.obj"
refused_small "lks 4 GB chunk, inspect" "stopped at byte 132 in chunk 0 of 1" "$LODKIT" inspect "$TMP/huge.lks"
check "no output from a refused stream" test ! -e "$TMP/h.obj"

# ---- everything a read holds counts (issue 17) ----------------------------------
# The budget bounds the file's bytes, decoded buffers (base64 data: URIs,
# the GLB chunk), the JSON tree, the parser's growing arrays and the mesh
# together: each of these big files (generated here), read at a budget just
# above its own size, is accepted or refused with a peak RSS of at most the
# budget + 64 MiB (the program itself is about 35 MiB, see lk_read_options
# in lodkit.h); at a generous budget it reads (it is valid). Before, the
# pieces were each checked against the whole budget: the 63 MB OBJ was
# refused only at a peak of 156 MiB under 64M, the PLYs, OFF, STL, GLB and
# the glTF at 200M were accepted and `info` peaked at 2.5 to 6.5 times the
# budget. The issue's 300 MB glTF at 600M is scaled down to 100 MB (at
# 200M, and just above its size).
big_file() {  # big_file KIND PATH N: an N x N vertex grid, 2 (N-1)^2 triangles
  python3 - "$@" <<'EOF_PY'
import base64, json, struct, sys
kind, path, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
cells = 2 * (n - 1)  # triangles per row of cells
count = cells * (n - 1)
def row(j):  # the corners of the triangles of row j of cells
    out = []
    for a in range(j * n, j * n + n - 1):
        out += (a, a + 1, a + n, a + 1, a + n + 1, a + n)
    return out
rows = range(n - 1)
def xyz():
    return ''.join('%d %d 0\n' % (i, j) for j in range(n) for i in range(n))
def positions():
    return b''.join(struct.pack('<%df' % (3 * n), *[v for i in range(n) for v in (i, j, 0)]) for j in range(n))
ply = 'ply\nformat %s 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n' \
      'element face %d\nproperty list uchar int vertex_indices\nend_header\n'
with open(path, 'wb') as out:
    if kind in ('obj', 'off', 'ascii.ply'):
        form, base = ('f %d %d %d\n', 1) if kind == 'obj' else ('3 %d %d %d\n', 0)
        faces = ''.join((form * cells) % tuple(c + base for c in row(j)) for j in rows)
        if kind == 'obj': text = 'v ' + xyz()[:-1].replace('\n', '\nv ') + '\n' + faces
        elif kind == 'off': text = 'OFF\n%d %d 0\n' % (n * n, count) + xyz() + faces
        else: text = ply % ('ascii', n * n, count) + xyz() + faces
        out.write(text.encode())
    elif kind == 'binary.ply':
        out.write((ply % ('binary_little_endian', n * n, count)).encode() + positions())
        for j in rows:
            c = row(j)
            out.write(struct.pack('<' + 'B3i' * cells,
                                  *[v for k in range(0, len(c), 3) for v in (3, c[k], c[k + 1], c[k + 2])]))
    elif kind == 'stl':
        out.write(b'\0' * 80 + struct.pack('<I', count))
        for j in rows:
            c = row(j)
            out.write(struct.pack('<' + '12fH' * cells, *[v for k in range(0, len(c), 3) for v in
                                  (0, 0, 1, c[k] % n, c[k] // n, 0, c[k + 1] % n, c[k + 1] // n, 0,
                                   c[k + 2] % n, c[k + 2] // n, 0, 0)]))
    else:  # gltf (buffer in a base64 data: URI) or glb (buffer in the BIN chunk)
        indices = b''.join(struct.pack('<%dI' % (3 * cells), *row(j)) for j in rows)
        blob = positions() + indices
        doc = {'asset': {'version': '2.0'}, 'buffers': [{'byteLength': len(blob)}],
               'bufferViews': [{'buffer': 0, 'byteLength': len(blob) - len(indices)},
                               {'buffer': 0, 'byteOffset': len(blob) - len(indices), 'byteLength': len(indices)}],
               'accessors': [{'bufferView': 0, 'componentType': 5126, 'count': n * n, 'type': 'VEC3'},
                             {'bufferView': 1, 'componentType': 5125, 'count': 3 * count, 'type': 'SCALAR'}],
               'meshes': [{'primitives': [{'attributes': {'POSITION': 0}, 'indices': 1}]}],
               'nodes': [{'mesh': 0}], 'scenes': [{'nodes': [0]}]}
        if kind == 'gltf':
            doc['buffers'][0]['uri'] = '@'
            head, tail = json.dumps(doc).encode().split(b'"@"')
            out.write(head + b'"data:application/octet-stream;base64,' + base64.b64encode(blob) + b'"' + tail)
        else:
            text = json.dumps(doc).encode()
            text += b' ' * (-len(text) % 4)
            out.write(b'glTF' + struct.pack('<II', 2, 28 + len(text) + len(blob)) + struct.pack('<I', len(text)) +
                      b'JSON' + text + struct.pack('<I', len(blob)) + b'BIN\0' + blob)
EOF_PY
}
# Sanitizer builds hold freed memory in a quarantine and shadow every byte:
# their RSS says nothing about the budget, so only the outcome is checked
# (and the files are not read whole again: the release build shows them valid).
sanitized=0
grep -qa __asan_init "$LODKIT" && sanitized=1
# within_budget MIB FILE: exit 0, or 1 with a message naming the file and the
# budget; peak RSS <= MIB + 64 MiB
within_budget() {
  local mib="$1" file="$2"
  peak_rss "$LODKIT" --max-memory "${mib}M" info "$file"
  local code=$? kb
  kb=$(tail -n 1 "$TMP/rss")
  checks=$((checks + 1))
  echo "  $(basename "$file") ($(stat -c %s "$file") bytes) at ${mib}M: exit $code, peak RSS $((kb / 1024)) MiB"
  if [ "$code" -ne 0 ] && ! { [ "$code" -eq 1 ] && grep -qF "$file" "$TMP/err" &&
                              grep -qF "memory budget of $((mib << 20)) bytes" "$TMP/err"; }; then
    echo "FAIL: $file at ${mib}M: exit $code: $(head -c 300 "$TMP/err")"; failures=$((failures + 1)); return
  fi
  if [ "$sanitized" -eq 0 ] && [ "$kb" -gt $(((mib + 64) * 1024)) ]; then
    echo "FAIL: $file at ${mib}M: peak RSS $kb KiB, more than the budget + 64 MiB"; failures=$((failures + 1))
  fi
}
# KIND N BUDGET... (MiB): the file's size in MiB is just under the first budget
for row in "obj 1050 64" "ascii.ply 625 22" "binary.ply 744 22" "off 717 28" "stl 778 58" "glb 1291 58" \
           "gltf 1444 96 200"; do
  set -- $row
  kind=$1 n=$2
  shift 2
  big="$TMP/big.$kind"
  big_file "$kind" "$big" "$n"
  for mib in "$@"; do within_budget "$mib" "$big"; done
  [ "$sanitized" -eq 1 ] || expect_exit 0 "$LODKIT" --max-memory 4G info "$big"
  rm -f "$big"
done

# Hostile work, not memory: one polygon of 200,000 corners repeating 4
# vertices (found by the OBJ fuzz campaign as a 10-second input) makes
# 199,998 triangles over one spot. Regressions: edge adjacency sorted each
# vertex's half-edges by insertion (quadratic in the valence: 4.3 s for
# 80k corners), and Metro's index visited every copy (13.6 s).
{ printf 'v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf'
  for ((i = 0; i < 50000; i++)); do printf ' 1 2 3 4'; done; printf '\n'; } > "$TMP/fan.obj"
check "200k-corner fan: info in bounded time" timeout -k 5 20 "$LODKIT" info "$TMP/fan.obj"
check "200k-corner fan: metro in bounded time" timeout -k 5 20 "$LODKIT" metro "$TMP/fan.obj" "$TMP/fan.obj"

# 60,000 materials of one triangle each (a 1.3 MB OBJ): as a scene, 60,000
# primitives. Regression: the glTF writer counted its bufferViews by
# walking cJSON's list for every accessor (quadratic: 100,000 primitives
# took over 10 minutes).
{ printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\n'
  for ((i = 0; i < 60000; i++)); do printf 'usemtl m%d\nf 1 2 3\n' "$i"; done; } > "$TMP/materials.obj"
check "60k materials: convert to glTF in bounded time" \
  timeout -k 5 30 "$LODKIT" convert -q "$TMP/materials.obj" "$TMP/materials.glb"
# The scene paths of the CLI (OBJ or glTF to glTF, render, info) read
# within --max-memory as the mesh paths do (they used the default budget).
expect_output_contains "materials.obj: the model needs more than the memory budget of 4194304 bytes (--max-memory)" \
  "$LODKIT" convert --max-memory=4M "$TMP/materials.obj" "$TMP/materials-4m.glb"
check "no output over --max-memory" test ! -e "$TMP/materials-4m.glb"
finish
