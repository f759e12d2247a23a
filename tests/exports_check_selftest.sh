#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# scripts/check-exports.sh fails when it should (CTest
# exports_check_selftest): on small libraries built here from one header, it
# passes the clean pair and refuses each kind of fault with a message naming
# it: an exported lk__ name, a non-lk name, an lk_ name the header does not
# declare, a declaration without a comment or without LK_API, and an LK_API
# declaration no library defines.
# Usage: tests/exports_check_selftest.sh SOURCE_DIR [CC]
set -uo pipefail
source_dir=$(cd "$1" && pwd)
cc=${2:-cc}
check_exports="$source_dir/scripts/check-exports.sh"
work="$(mktemp -d /tmp/lodkit-exports.XXXXXX)"
trap 'rm -rf "$work"' EXIT
failures=0
checks=0

# expect_check WANT TEXT DESCRIPTION LIB... HEADER: check-exports.sh exits
# with WANT (0 or 1) and, for 1, prints TEXT.
expect_check() {
  local want="$1" text="$2" description="$3"; shift 3
  checks=$((checks + 1))
  local output got
  output=$(bash "$check_exports" "$@" 2>&1)
  got=$?
  if [ "$got" -ne "$want" ]; then
    echo "FAIL: $description: exit $got, expected $want"; echo "$output" | sed 's/^/  /'
    failures=$((failures + 1))
  elif [ "$want" -ne 0 ] && ! grep -qF -- "$text" <<<"$output"; then
    echo "FAIL: $description: no '$text' in"; echo "$output" | sed 's/^/  /'
    failures=$((failures + 1))
  fi
}

# build NAME SOURCE [LINK FLAGS]: lib NAME.so from C source text, hidden by
# default and linked with lodkit's version script, like liblodkit.so.
build() {
  local name="$1" source="$2"; shift 2
  [ $# -gt 0 ] || set -- -Wl,--version-script="$source_dir/cmake/lodkit.map"
  printf '%s\n' "$source" >"$work/$name.c"
  "$cc" -shared -fPIC -fvisibility=hidden -I"$work" "$@" -o "$work/$name.so" "$work/$name.c" ||
    { echo "FAIL: cannot build $name.so with $cc"; exit 1; }
}

cat >"$work/good.h" <<'H'
/* A header in lodkit.h's style. */
#define LK_API __attribute__((visibility("default")))

/* Adds one. */
LK_API int lk_one(int x);
LK_API int lk_two(int x); /* trailing comment */
/* A pair under one comment:
 * both are documented. */
LK_API void lk_pair_init(int *x);
LK_API void lk_pair_free(int *x);
/* Data. */
LK_API extern const double lk_table[2];

/* ---- Library: lodkit-extra ---- */
/* From the other library. */
LK_API int lk_extra_thing(void);
/* Also. */
LK_API int lk_extra_other(void);
H
core='#include "good.h"
int lk_one(int x) { return x + 1; }
int lk_two(int x) { return x + 2; }
void lk_pair_init(int *x) { *x = 0; }
void lk_pair_free(int *x) { *x = 0; }
const double lk_table[2] = {1, 2};
int lk__internal(void) { return 3; }   /* hidden: not exported */
int helper(void) { return 4; }'
extra='#include "good.h"
int lk_extra_thing(void) { return 5; }
int lk_extra_other(void) { return 6; }'
mkdir -p "$work/clean" && build clean/liblodkit "$core" && build clean/liblodkit-extra "$extra"
expect_check 0 "" "the clean pair" "$work/clean/liblodkit.so" "$work/clean/liblodkit-extra.so" "$work/good.h"
expect_check 0 "" "the core alone (lodkit-extra not given)" "$work/clean/liblodkit.so" "$work/good.h"
# lk_extra_thing moved into the core library: allowed when both are given
mkdir -p "$work/moved" && build moved/liblodkit "$core
int lk_extra_thing(void) { return 5; }" && build moved/liblodkit-extra '#include "good.h"
int lk_extra_other(void) { return 6; }'
expect_check 0 "" "a function defined in the other library" \
  "$work/moved/liblodkit.so" "$work/moved/liblodkit-extra.so" "$work/good.h"
expect_check 1 "lk_extra_thing (library lodkit-extra) is declared with LK_API but none of" \
  "lodkit-extra without one of its functions" "$work/clean/liblodkit.so" "$work/moved/liblodkit-extra.so" "$work/good.h"
expect_check 1 "defines lk_extra_thing, which $work/moved/liblodkit.so defines too" "a function defined twice" \
  "$work/moved/liblodkit.so" "$work/clean/liblodkit-extra.so" "$work/good.h"

mkdir -p "$work/internal" && build internal/liblodkit "$core
__attribute__((visibility(\"default\"))) int lk__test_hook(void) { return 6; }"
expect_check 1 "exports lk__test_hook, an internal lk__ name" "an exported lk__ name" \
  "$work/internal/liblodkit.so" "$work/good.h"

# without the version script, which would make it local (and the linker's
# _edata, _end, __bss_start with it)
mkdir -p "$work/foreign" && build foreign/liblodkit "$core
__attribute__((visibility(\"default\"))) int parse_number(void) { return 7; }" -Wl,-O1
expect_check 1 "exports parse_number, which is not an lk_ name" "an exported non-lk name" \
  "$work/foreign/liblodkit.so" "$work/good.h"

mkdir -p "$work/undeclared" && build undeclared/liblodkit "$core
__attribute__((visibility(\"default\"))) int lk_secret(void) { return 8; }"
expect_check 1 "exports lk_secret, which $work/good.h does not declare with LK_API" "an undeclared lk_ name" \
  "$work/undeclared/liblodkit.so" "$work/good.h"

sed 's|^/\* Adds one. \*/$||' "$work/good.h" >"$work/undocumented.h"
expect_check 1 "exports lk_one, whose declaration ($work/undocumented.h:5) has no comment" \
  "a declaration without a comment" "$work/clean/liblodkit.so" "$work/undocumented.h"

sed 's|^LK_API int lk_two|int lk_two|' "$work/good.h" >"$work/bare.h"
expect_check 1 "lk_two is declared without LK_API" "a prototype without LK_API" \
  "$work/clean/liblodkit.so" "$work/bare.h"

awk '/Library: lodkit-extra/ { print "/* Declared, never defined. */"; print "LK_API int lk_missing(void);" } { print }' \
  "$work/good.h" >"$work/missing.h"
expect_check 1 "lk_missing (library lodkit) is declared with LK_API but none of" \
  "an LK_API declaration no library defines" "$work/clean/liblodkit.so" "$work/clean/liblodkit-extra.so" "$work/missing.h"

echo "$checks checks, $failures failed"
[ "$failures" -eq 0 ]
