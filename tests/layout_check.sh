#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The layout rules `make test` checks (CTest: layout_check): no include or
# symbol cycle among the modules of src/ (scripts/check-cycles.py, on the
# objects of the sources that exist now: a stale object of a removed or
# renamed file is left out), no file in src/ or cli/ over 1,500 lines, and
# nothing in cli/ includes a src/ header (the command uses the public API).
# Usage: tests/layout_check.sh SOURCE_DIR OBJECT_DIR...
# (OBJECT_DIRs: where CMake puts each library's src/NAME.c.o files: the
# core's lodkit_objects.dir and the components' lodkit_NAME_objects.dir.)
set -uo pipefail
source_dir=$(cd "$1" && pwd)
shift
object_dirs=()
for directory in "$@"; do
  [ -d "$directory" ] && object_dirs+=("$(cd "$directory" && pwd)")
done
max_lines=1500
status=0

current="$(mktemp -d /tmp/lodkit-layout.XXXXXX)"
trap 'rm -rf "$current"' EXIT
while IFS= read -r -d '' source; do
  relative=${source#"$source_dir"/}
  object=""
  for objects in "${object_dirs[@]}"; do
    [ -f "$objects/$relative.o" ] && object="$objects/$relative.o"
  done
  if [ -z "$object" ]; then
    case "$relative" in
      src/gl/* | src/serve/* | src/io_dem.c | src/io_dem_gdal.c)
        continue ;; # a component that is not built
      src/wasm/*)
        continue ;; # built by clang for WebAssembly (stream2.wasm), not into a library
    esac
    echo "layout: no object for $relative in ${object_dirs[*]} (build the library first)"
    status=1
    continue
  fi
  mkdir -p "$current/$(dirname "$relative")"
  ln -s "$object" "$current/$relative.o"
done < <(find "$source_dir/src" -name '*.c' -print0)
python3 "$source_dir/scripts/check-cycles.py" "$source_dir/src" "$current" || status=1

for directory in src cli; do
  [ -d "$source_dir/$directory" ] || continue
  while IFS= read -r -d '' file; do
    lines=$(wc -l <"$file")
    if [ "$lines" -gt "$max_lines" ]; then
      echo "layout: ${file#"$source_dir"/} has $lines lines (at most $max_lines: split it by concern)"
      status=1
    fi
  done < <(find "$source_dir/$directory" -type f -print0 | sort -z)
done
# The command is a thin layer over the public API: no src/ header, by any path.
while IFS= read -r -d '' header; do
  name=$(basename "$header")
  if grep -rnE "^[[:space:]]*#[[:space:]]*include[[:space:]]*[\"<]([^\">]*/)?${name//./\\.}[\">]" "$source_dir/cli"; then
    echo "layout: cli/ includes src/ header $name (use include/lodkit.h; make what is missing public API)"
    status=1
  fi
done < <(find "$source_dir/src" -name '*.h' -print0)
[ "$status" -eq 0 ] && echo "layout: no file in src/ or cli/ over $max_lines lines"
exit "$status"
