#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The tree's habits `make test` checks (CTest: style_check):
#   - every C file is formatted by the committed .clang-format (Debian 12's
#     clang-format 14: `clang-format -i FILE` fixes one);
#   - every source file names its licence with an SPDX line near the top.
# Usage: tests/style_check.sh SOURCE_DIR
set -uo pipefail
source_dir=$(cd "$1" && pwd)
cd "$source_dir" || exit 1
status=0
unlicensed_list=()
if ! command -v clang-format >/dev/null 2>&1; then
  echo "style: this check needs clang-format (Debian package: clang-format); run scripts/install-deps.sh"
  exit 1
fi
# Sources of this project only (not node_modules, not generated files).
mapfile -d '' c_files < <(git ls-files -z -- '*.c' '*.h' 2>/dev/null || find src cli include tests examples bench fuzz -name '*.[ch]' -print0)
if [ "${#c_files[@]}" -eq 0 ]; then
  echo "style: no C files found under $source_dir"
  exit 1
fi
mapfile -t existing < <(for file in "${c_files[@]}"; do [ -f "$file" ] && printf '%s\n' "$file"; done)
# One clang-format for every file (each start costs about 0.17 s); when it
# objects, one per file to name them.
if ! clang-format --dry-run --Werror "${existing[@]}" >/dev/null 2>&1; then
  unformatted=0
  for file in "${existing[@]}"; do
    if ! clang-format --dry-run --Werror "$file" >/dev/null 2>&1; then
      echo "style: $file is not formatted by .clang-format (clang-format -i $file)"
      unformatted=$((unformatted + 1))
    fi
  done
  # clang-format itself failed on the whole list (not one file): say so.
  [ "$unformatted" -gt 0 ] || echo "style: clang-format failed on the file list"
  status=1
fi

mapfile -d '' all_files < <(git ls-files -z -- '*.c' '*.h' '*.sh' '*.py' '*.js' '*.mjs' '*.cmake' '*.in' 'CMakeLists.txt' '*/CMakeLists.txt' 'Makefile' '*/Makefile' '*.glsl' '*.html' '*.css' ':!:data/**' ':!:tests/data/**' 2>/dev/null)
# One awk over every file (mawk: no ENDFILE, so a file is judged when the
# next one starts); an empty file has no first line to judge.
present=()
for file in "${all_files[@]}"; do
  [ -f "$file" ] || continue
  if [ -s "$file" ]; then present+=("$file"); else unlicensed_list+=("$file"); fi
done
mapfile -t -O "${#unlicensed_list[@]}" unlicensed_list < <(
  awk 'FNR == 1 { if (NR > 1 && !found) print name; found = 0; name = FILENAME }
       FNR <= 3 && /SPDX-License-Identifier: MIT/ { found = 1 }
       END { if (NR > 0 && !found) print name }' "${present[@]}")
for file in "${unlicensed_list[@]}"; do
  echo "style: $file has no 'SPDX-License-Identifier: MIT' line in its first 3 lines"
done
[ "${#unlicensed_list[@]}" -eq 0 ] || status=1
[ "$status" -eq 0 ] && echo "style: ${#c_files[@]} C files formatted, ${#all_files[@]} source files with an SPDX line"
exit "$status"
