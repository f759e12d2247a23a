#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Every one of Assimp's odd OBJ/PLY/OFF/STL/glTF test models must either load
# (exit 0) or be refused with a message naming the file (exit 1) — never a
# crash, a hang or a usage error.
set -u
source "$(dirname "$0")/lib.sh"
loaded=0; refused=0
while IFS= read -r -d '' file; do
  err=$(timeout 60 "$LODKIT" info --json "$file" 2>&1 >/dev/null)
  code=$?
  case $code in
    0) loaded=$((loaded + 1)) ;;
    1) refused=$((refused + 1))
       check "message names $file: $err" grep -qF "$file" <<<"$err"
       echo "refused: $err" ;;
    *) check "exit code $code for $file" false ;;
  esac
done < <(find "$LK_SAMPLES_DIR/assimp" -type f \( -iname '*.obj' -o -iname '*.ply' -o -iname '*.off' \
           -o -iname '*.stl' -o -iname '*.gltf' -o -iname '*.glb' \) -print0 | sort -z)
echo "assimp models: $loaded loaded, $refused refused"
check "most assimp models load ($loaded)" test "$loaded" -ge 50
finish
