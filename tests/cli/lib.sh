# SPDX-License-Identifier: MIT
# Tiny assertion helpers for the CLI tests (sourced).
: "${LODKIT:?LODKIT must point to the lodkit binary}"
: "${LK_SAMPLES_DIR:?}"
TMP="$(mktemp -d /tmp/lodkit-cli.XXXXXX)"
trap 'rm -rf "$TMP"' EXIT
failures=0
checks=0
check() {  # check DESCRIPTION COMMAND...
  local description="$1"; shift
  checks=$((checks + 1))
  if ! "$@"; then echo "FAIL: $description"; failures=$((failures + 1)); fi
}
expect_exit() {  # expect_exit CODE COMMAND...
  local code="$1"; shift
  checks=$((checks + 1))
  "$@" >/dev/null 2>&1
  local got=$?
  if [ "$got" -ne "$code" ]; then echo "FAIL: exit $got, expected $code: $*"; failures=$((failures + 1)); fi
}
expect_output_contains() {  # expect_output_contains TEXT COMMAND...
  local text="$1"; shift
  checks=$((checks + 1))
  if ! "$@" 2>&1 | grep -qF -- "$text"; then echo "FAIL: output of '$*' lacks '$text'"; failures=$((failures + 1)); fi
}
# require COMMAND PACKAGE: a test that cannot run here says why and fails
# (it never passes silently); scripts/install-deps.sh installs PACKAGE.
require() {
  if ! command -v "$1" >/dev/null 2>&1; then
    echo "FAIL: this test needs '$1' (Debian package: $2), which is not installed; run scripts/install-deps.sh"
    exit 1
  fi
}
finish() {
  echo "$checks checks, $failures failed"
  [ "$failures" -eq 0 ]
}
