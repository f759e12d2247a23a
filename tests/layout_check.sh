#!/usr/bin/env bash
# The layout rules `make test` checks (CTest: layout_check): no include or
# symbol cycle among the modules of src/ (scripts/check-cycles.py, on the
# objects of the sources that exist now: a stale object of a removed or
# renamed file is left out), and no file in src/ or cli/ over 1,500 lines.
# Usage: tests/layout_check.sh SOURCE_DIR OBJECT_DIR
# (OBJECT_DIR: where CMake puts lodkit_objects' src/NAME.c.o files.)
set -uo pipefail
source_dir=$(cd "$1" && pwd)
objects=$(cd "$2" && pwd) || exit 1
max_lines=1500
status=0

current="$(mktemp -d /tmp/lodkit-layout.XXXXXX)"
trap 'rm -rf "$current"' EXIT
while IFS= read -r -d '' source; do
  relative=${source#"$source_dir"/}
  if [ ! -f "$objects/$relative.o" ]; then
    echo "layout: no object for $relative in $objects (build the library first)"
    status=1
    continue
  fi
  mkdir -p "$current/$(dirname "$relative")"
  ln -s "$objects/$relative.o" "$current/$relative.o"
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
[ "$status" -eq 0 ] && echo "layout: no file in src/ or cli/ over $max_lines lines"
exit "$status"
