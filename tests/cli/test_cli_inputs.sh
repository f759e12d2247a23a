#!/bin/bash
# SPDX-License-Identifier: MIT
# Inputs that are not regular files (issue 17): every command that reads a
# file, given a FIFO without a writer, /dev/zero (directly or through a
# link), a directory, a socket or a symlink loop, or a glTF whose buffer is
# a link out of its folder (to a file or through a linked directory), a
# FIFO or a socket, exits 1 within seconds with a message naming the file
# and what it is, and writes no output. Before, a FIFO hung the command in
# open() and a linked buffer was read as vertex positions.
# The FIFOs, sockets and links are made here; every run is bounded by
# timeout (exit 124 would be a hang).
source "$(dirname "$0")/lib.sh"
require python3 python3
require timeout coreutils

IN="$TMP/in"
OUT="$TMP/out"
AWAY="$TMP/away"
mkdir -p "$IN/dir.obj" "$OUT" "$AWAY"
printf '\001\002\003\004\005\006\007\010\011\012\013\014\015\016\017\020\021\022\023\024\025\026\027\030\031\032\033\034\035\036\037\040\041\042\043\044' >"$AWAY/secret36.bin"
for name in fifo.obj fifo.lks fifo.tif fifo.pgm fifo.md2 fifo.bin; do mkfifo "$IN/$name"; done
python3 -c 'import socket, sys
for path in sys.argv[1:]:
    socket.socket(socket.AF_UNIX).bind(path)' "$IN/socket.obj" "$IN/socket.bin"
ln -s /dev/zero "$IN/zero.obj"
ln -s /dev/zero "$IN/zero.pgm"
ln -s loop2.obj "$IN/loop1.obj"
ln -s loop1.obj "$IN/loop2.obj"
ln -s "$AWAY" "$IN/link_out"
ln -s "$AWAY/secret36.bin" "$IN/secret-link.bin"
gltf() {  # gltf NAME URI: one triangle whose 36 bytes of positions are the file URI
  printf '{"asset":{"version":"2.0"},"buffers":[{"uri":"%s","byteLength":36}],"bufferViews":[{"buffer":0,"byteLength":36}],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0}' "$2" >"$IN/$1"
}
gltf dirlink.gltf link_out/secret36.bin
gltf filelink.gltf secret-link.bin
gltf fifo.gltf fifo.bin
gltf socket.gltf socket.bin
cp "$AWAY/secret36.bin" "$IN/inside36.bin"
gltf control.gltf inside36.bin

# refused FILE KIND COMMAND...: exit 1 within 10 s, stderr names FILE and KIND, no output file
refused() {
  local file="$1" kind="$2"; shift 2
  rm -rf "$OUT"/*
  local start=$(date +%s%N)
  timeout -k 2 10 "$@" >"$TMP/stdout" 2>"$TMP/stderr"
  local code=$? ms=$((($(date +%s%N) - start) / 1000000))
  checks=$((checks + 1))
  if [ "$code" -ne 1 ]; then
    echo "FAIL: exit $code (124: hung) after $ms ms, expected 1: $*"; failures=$((failures + 1)); return
  fi
  checks=$((checks + 1))
  if ! grep -qF -- "$file" "$TMP/stderr" || ! grep -qF -- "$kind" "$TMP/stderr"; then
    echo "FAIL: '$*': the message lacks '$file' or '$kind': $(head -c 300 "$TMP/stderr")"; failures=$((failures + 1))
  fi
  check "no output after '$*'" test -z "$(ls -A "$OUT")"
}

# the control: the same 36 bytes inside the folder are the triangle
expect_output_contains "vertices              3" "$LODKIT" info "$IN/control.gltf"

cow="$LK_SAMPLES_DIR/cow.off"
for input in fifo.obj:"is a FIFO" zero.obj:"is a character device" dir.obj:"is a directory" \
             socket.obj:"is a socket" loop1.obj:"Too many levels of symbolic links"; do
  name="${input%%:*}" kind="${input#*:}" file="$IN/$name"
  refused "$name" "$kind" "$LODKIT" info "$file"
  refused "$name" "$kind" "$LODKIT" convert "$file" "$OUT/x.obj"
  refused "$name" "$kind" "$LODKIT" simplify --ratio=0.5 "$file" "$OUT/x.obj"
  refused "$name" "$kind" "$LODKIT" subdivide "$file" "$OUT/x.obj"
  refused "$name" "$kind" "$LODKIT" progressive "$file" "$OUT/x.lks"
  refused "$name" "$kind" "$LODKIT" metro "$file" "$cow"
  refused "$name" "$kind" "$LODKIT" metro "$cow" "$file"
  refused "$name" "$kind" "$LODKIT" sample --points=100 "$file" "$OUT/x.ply"
  refused "$name" "$kind" "$LODKIT" slices "$file" "$OUT/x.svg"
done
refused "/dev/zero" "is a character device" "$LODKIT" info /dev/zero
refused "/dev/urandom" "is a character device" "$LODKIT" convert /dev/urandom "$OUT/x.obj"
refused "fifo.lks" "is a FIFO" "$LODKIT" inspect "$IN/fifo.lks"
refused "fifo.lks" "is a FIFO" "$LODKIT" unpack "$IN/fifo.lks" "$OUT/x.obj"
refused "fifo.tif" "is a FIFO" "$LODKIT" terrain "$IN/fifo.tif"
refused "fifo.pgm" "is a FIFO" "$LODKIT" terrain "$IN/fifo.pgm"
refused "zero.pgm" "is a character device" "$LODKIT" terrain "$IN/zero.pgm"
refused "fifo.md2" "is a FIFO" "$LODKIT" animate "$IN/fifo.md2" "$OUT/anim"

# glTF buffers: never a link (out of the folder, to a file or through a
# directory), a FIFO or a socket; the message says why
rule="external files must be regular files inside the model's folder"
for input in dirlink.gltf:'"link_out" is a symbolic link (not followed)' \
             filelink.gltf:'"secret-link.bin": is a symbolic link (not followed)' \
             fifo.gltf:'"fifo.bin": is a FIFO, not a regular file' \
             socket.gltf:'"socket.bin": is a socket, not a regular file'; do
  name="${input%%:*}" kind="${input#*:}" file="$IN/$name"
  refused "$name" "$kind" "$LODKIT" info "$file"
  refused "$name" "$rule" "$LODKIT" convert "$file" "$OUT/x.obj"
  refused "$name" "$kind" "$LODKIT" progressive "$file" "$OUT/x.lks"
  refused "$name" "$kind" "$LODKIT" animate "$file" "$OUT/anim"
done
finish
