#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Checks that shared libraries export the public API of a header, no more
# and no less (CTest exports_check; docs/api.md, "LK_API and what a shared
# library exports"):
#   - every dynamic symbol a library defines is an lk_ name (not lk__),
#     declared with LK_API in the header, and documented: a comment ends on
#     the line just above the declaration, or sits on its own lines, or the
#     declaration directly follows a documented one (a group under one
#     comment, such as an _init/_free pair);
#   - every LK_API declaration in the header is declared as a statement of
#     its own, and a function prototype of the header without LK_API is an
#     error (it would not be exported);
#   - every LK_API declaration that belongs to one of the given libraries is
#     defined by one of them (the libraries of one build together: a name
#     may move from one to another).
# Which library a declaration belongs to: the header may say it in a
# comment line "Library: NAME" (NAME as in libNAME.so); declarations after
# it belong to NAME, up to the next such line; before the first, to
# "lodkit". Declarations of a library not given are not required, so
# `check-exports.sh liblodkit.so lodkit.h` checks the core of a build whose
# components are off.
# Usage: scripts/check-exports.sh LIB.so [LIB.so ...] HEADER
set -euo pipefail

if [ $# -lt 2 ]; then
  echo "usage: $0 LIB.so [LIB.so ...] HEADER" >&2
  exit 2
fi
header="${!#}"
libraries=("${@:1:$#-1}")
[ -r "$header" ] || { echo "$0: $header: cannot read the header" >&2; exit 2; }
command -v nm >/dev/null || { echo "$0: nm (binutils) is needed" >&2; exit 2; }

# The header's declarations, one line each: "decl NAME LIBRARY DOCUMENTED LINE"
# for LK_API ones, "bare NAME - - LINE" for prototypes without LK_API.
declarations=$(awk '
  # Code of a line with its comments removed; sets has_comment when the line
  # holds (part of) a comment and ends_comment when a comment closes with
  # nothing but blanks after it.
  function code_of(line,    out, start, stop) {
    out = ""; has_comment = in_comment; ends_comment = 0
    while (line != "") {
      if (in_comment) {
        stop = index(line, "*/")
        if (!stop) { line = ""; break }
        line = substr(line, stop + 2); in_comment = 0
        if (line ~ /^[ \t]*$/) ends_comment = 1
      } else {
        start = index(line, "/*")
        if (!start) { out = out line; break }
        out = out substr(line, 1, start - 1) " "; line = substr(line, start + 2)
        in_comment = 1; has_comment = 1
      }
    }
    return out
  }
  function name_of(text,    name) {
    if (index(text, "(")) text = substr(text, 1, index(text, "(") - 1)
    else if (index(text, "[")) text = substr(text, 1, index(text, "[") - 1)
    else sub(/[ \t]*(=.*)?;.*$/, "", text)
    if (match(text, /[A-Za-z_][A-Za-z0-9_]*[ \t]*$/)) name = substr(text, RSTART, RLENGTH)
    sub(/[ \t]+$/, "", name)
    return name
  }
  BEGIN { library = "lodkit"; previous = "other"; depth = 0 }
  {
    raw = $0
    was_in_comment = in_comment
    code = code_of(raw)
    if ((has_comment || was_in_comment) && match(raw, /Library:[ \t]*[A-Za-z0-9_.+-]+/)) {
      marker = substr(raw, RSTART, RLENGTH); sub(/Library:[ \t]*/, "", marker); library = marker
    }
    if (code ~ /^[ \t]*#/ && !in_statement) { previous = "other"; next }
    if (code ~ /^[ \t]*#/) next                       # #if inside a declaration
    if (!in_statement && code ~ /^[ \t]*extern "C" \{[ \t]*$/) { previous = "other"; next }
    if (!in_statement && depth == 0 && code ~ /^[ \t]*\}[ \t]*$/) { previous = "other"; next }
    if (code ~ /^[ \t]*$/) {
      if (!has_comment) previous = "other"
      else if (ends_comment || was_in_comment && !in_comment) previous = "comment"
      else if (!in_statement) previous = "other"
      if (in_statement && has_comment) statement_comment = 1
      next
    }
    if (!in_statement) {
      in_statement = 1; statement = ""; statement_comment = 0; statement_line = NR
      statement_documented = (previous == "comment" || previous == "documented")
    }
    statement = statement " " code
    if (has_comment) statement_comment = 1
    depth += gsub(/\{/, "{", code) - gsub(/\}/, "}", code)
    if (depth > 0 || code !~ /;[ \t]*$/) { previous = "other"; next }
    in_statement = 0
    previous = "other"
    if (statement ~ /(^|[^A-Za-z0-9_])LK_API([^A-Za-z0-9_]|$)/) {
      name = name_of(statement)
      documented = statement_documented || statement_comment
      print "decl", (name == "" ? "?" : name), library, (documented ? "yes" : "no"), statement_line
      if (documented) previous = "documented"
    } else if (statement !~ /^[ \t]*typedef/ && statement ~ /(^|[^A-Za-z0-9_])lk_[A-Za-z0-9_]*[ \t]*\(/ &&
               statement !~ /[{}]/) {
      print "bare", name_of(statement), "-", "-", statement_line
    }
  }' "$header")

problems=0
problem() { echo "check-exports: $*"; problems=$((problems + 1)); }

declare -A declared_library documented_at declared_line defined_in
while read -r kind name library documented line; do
  [ -n "$kind" ] || continue
  if [ "$kind" = bare ]; then
    problem "$header:$line: $name is declared without LK_API (it would not be exported)"
    continue
  fi
  if [ -n "${declared_line[$name]:-}" ]; then
    problem "$header:$line: $name is declared twice (also line ${declared_line[$name]})"
  fi
  declared_library[$name]=$library
  documented_at[$name]=$documented
  declared_line[$name]=$line
done <<<"$declarations"

declare -A given_library
symbol_total=0
for lib in "${libraries[@]}"; do
  [ -r "$lib" ] || { echo "$0: $lib: cannot read the library" >&2; exit 2; }
  base=$(basename "$lib")
  base=${base#lib}
  base=${base%%.so*}
  given_library[$base]=1
  symbols=$(nm -D --defined-only -P "$lib" | awk '{ sub(/@.*/, "", $1); print $1 }' | sort -u)
  while read -r symbol; do
    symbol_total=$((symbol_total + 1))
    if [[ "$symbol" == lk__* ]]; then
      problem "$lib: exports $symbol, an internal lk__ name"
    elif [[ "$symbol" != lk_* ]]; then
      problem "$lib: exports $symbol, which is not an lk_ name"
    elif [ -z "${declared_line[$symbol]:-}" ]; then
      problem "$lib: exports $symbol, which $header does not declare with LK_API"
    elif [ "${documented_at[$symbol]}" != yes ]; then
      problem "$lib: exports $symbol, whose declaration ($header:${declared_line[$symbol]}) has no comment"
    fi
    if [ -n "${defined_in[$symbol]:-}" ]; then
      problem "$lib: defines $symbol, which ${defined_in[$symbol]} defines too"
    fi
    defined_in[$symbol]=$lib
  done <<<"$symbols"
done

required=0
for name in "${!declared_library[@]}"; do
  [ -n "${given_library[${declared_library[$name]}]:-}" ] || continue
  required=$((required + 1))
  if [ -z "${defined_in[$name]:-}" ]; then
    problem "$header:${declared_line[$name]}: $name (library ${declared_library[$name]}) is declared with LK_API" \
      "but none of ${libraries[*]} defines it"
  fi
done

if [ "$problems" -gt 0 ]; then
  echo "check-exports: $problems problem(s)"
  exit 1
fi
echo "check-exports: ok: the $symbol_total symbols ${libraries[*]} export are documented LK_API names of $header," \
  "and its $required LK_API declarations for these libraries are all defined"
