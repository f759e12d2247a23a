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
unformatted=0
for file in "${c_files[@]}"; do
  [ -f "$file" ] || continue
  if ! clang-format --dry-run --Werror "$file" >/dev/null 2>&1; then
    echo "style: $file is not formatted by .clang-format (clang-format -i $file)"
    unformatted=$((unformatted + 1))
  fi
done
[ "$unformatted" -eq 0 ] || status=1

mapfile -d '' all_files < <(git ls-files -z -- '*.c' '*.h' '*.sh' '*.py' '*.js' '*.mjs' '*.cmake' '*.in' 'CMakeLists.txt' '*/CMakeLists.txt' 'Makefile' '*/Makefile' '*.glsl' '*.html' '*.css' ':!:data/**' ':!:tests/data/**' 2>/dev/null)
unlicensed=0
for file in "${all_files[@]}"; do
  [ -f "$file" ] || continue
  if ! head -n 3 "$file" | grep -q "SPDX-License-Identifier: MIT"; then
    echo "style: $file has no 'SPDX-License-Identifier: MIT' line in its first 3 lines"
    unlicensed=$((unlicensed + 1))
  fi
done
[ "$unlicensed" -eq 0 ] || status=1
[ "$status" -eq 0 ] && echo "style: ${#c_files[@]} C files formatted, ${#all_files[@]} source files with an SPDX line"
exit "$status"
