#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Output safety (issue 10). Every output is written to a hidden temporary
# file next to it (.NAME.tmp-XXXXXX) and renamed over it, so a kill -9 at any
# instant of simplify (qem, wavelet; .obj .ply .off), progressive (.lks) and
# convert leaves each output path either as it was before the run (absent, or
# the previous complete file byte for byte) or holding the complete new file
# (byte-identical to a reference run, which `info`/`inspect` read back: the
# output is deterministic). animate's output is a folder (level files, CSV,
# PNG, its manifest .lodkit-animate), built in a hidden .NAME.tmp-XXXXXX
# folder beside it and swapped in whole: after a kill the folder is absent
# (when it was), the previous complete set or the new complete set, never a
# mix. Kills land at fractions of the run's measured time, at random
# instants, and just after the temporary file or folder appears; for animate
# also at the swap itself (an LD_PRELOAD shim stops the run just before and
# just after renameat2, and the run waits on an flock the test holds). A
# killed process cannot remove its temporary: what is left must be a hidden
# .NAME.tmp-XXXXXX of a known output, and a later run must succeed beside it
# without touching it. File systems without RENAME_EXCHANGE (the shim fails
# it with EINVAL, as NFS does): animate moves the previous set aside first.
# Then write failures: a file-size limit (EFBIG, always), a full and a
# read-only tmpfs (ENOSPC, EROFS: only where a private mount namespace can be
# made, else skipped with a note), a missing directory, a directory we may not
# write (run as nobody when we are root), an output that is a symlink to
# /dev/full or a directory: exit 1, a message naming the file and the cause,
# the previous output unchanged, no temporary file left behind.
set -u
source "$(dirname "$0")/lib.sh"
S="$LK_SAMPLES_DIR"
TIMEOUT="timeout -k 5"
shopt -s nullglob dotglob
exec {never}<> <(:)
seconds_now() { local t="$EPOCHREALTIME"; echo "${t/,/.}"; }
calc() { awk "BEGIN { printf \"%.3f\", $1 }"; }

# ---- the commands (each writes into the directory $1) -------------------
# new_* set cmd to the run under test; old_* to a run writing files of the
# same names with other contents (the "previous complete output").
new_qem_obj() { cmd=("$LODKIT" simplify -q -r 0.1 "$S/bunny.obj" "$1/out.obj"); }
old_qem_obj() { cmd=("$LODKIT" simplify -q -r 0.05 "$S/cow.off" "$1/out.obj"); }
new_qem_ply() { cmd=("$LODKIT" simplify -q -r 0.5 "$S/cow.off" "$1/out.ply"); }
old_qem_ply() { cmd=("$LODKIT" simplify -q -r 0.05 "$S/cow.off" "$1/out.ply"); }
new_wavelet_off() { cmd=("$LODKIT" simplify -q -m wavelet --slices=16 -r 0.1 "$S/cow.off" "$1/out.off"); }
old_wavelet_off() { cmd=("$LODKIT" simplify -q -r 0.05 "$S/cow.off" "$1/out.off"); }
new_progressive() { cmd=("$LODKIT" progressive -q --stream-version=1 -b 0.5 --bandwidth-levels=4 --stripifier=lodkit "$S/bunny.obj" "$1/out.lks"); }
old_progressive() { cmd=("$LODKIT" progressive -q "$S/cow.off" "$1/out.lks"); }
new_convert() { cmd=("$LODKIT" convert -q "$S/bunny.obj" "$1/out.off"); }
old_convert() { cmd=("$LODKIT" convert -q "$S/cow.off" "$1/out.off"); }
new_animate() { cmd=("$LODKIT" animate -q --levels=2 --metro-step=99 --samples-per-face=1 "$S/faerie.md2" "$1/set"); }
old_animate() { cmd=("$LODKIT" animate -q --levels=2 --metro-step=66 --samples-per-face=1 --keep-seams "$S/faerie.md2" "$1/set"); }

# same PATH REF: the same file byte for byte, or the same folder: the same
# files (hidden ones too), nothing more, nothing less.
same() {
  [ $# -eq 2 ] || return 1  # a glob that matched no file or several
  if [ -d "$2" ]; then [ -d "$1" ] && [ ! -L "$1" ] && diff -r -q "$1" "$2" >/dev/null 2>&1
  else [ -f "$2" ] && [ -f "$1" ] && cmp -s "$1" "$2"; fi
}

# verify DIR REF OLD WAS_OLD: every entry of DIR is a complete new output
# (the same as REF/NAME), the previous one (OLD/NAME, if it was there) or a
# hidden temporary .NAME.tmp-XXXXXX (file or folder) of an output; no
# previous output is lost.
verify() {
  local dir=$1 ref=$2 old=$3 was_old=$4 path name bad=0
  for path in "$dir"/*; do
    name=${path##*/}
    if [[ $name =~ ^\.(.+)\.tmp-[A-Za-z0-9]{6}$ ]] && [ -e "$ref/${BASH_REMATCH[1]}" ]; then
      temps_left=$((temps_left + 1))
    elif same "$path" "$ref/$name"; then
      outputs_new=$((outputs_new + 1))
    elif [ "$was_old" = 1 ] && same "$path" "$old/$name"; then
      outputs_old=$((outputs_old + 1))
    else
      echo "  corrupt, mixed or unexpected: $name ($(stat -c %s "$path") bytes$([ -d "$path" ] && echo ", a folder of $(ls -A "$path" | wc -l) entries"))"
      bad=1
    fi
  done
  for path in "$ref"/*; do
    name=${path##*/}
    if [ ! -e "$dir/$name" ]; then
      if [ "$was_old" = 1 ] && [ -e "$old/$name" ]; then echo "  previous $name vanished"; bad=1; fi
      outputs_absent=$((outputs_absent + 1))
    fi
  done
  return $bad
}

# prepare DIR OLD WAS_OLD: an empty output directory, or one holding the
# previous complete outputs.
prepare() {
  rm -rf "$1"
  mkdir -p "$1"
  if [ "$3" = 1 ]; then cp -a "$2"/* "$1"/; fi
}

# trial NAME DIR REF OLD WAS_OLD MODE DELAY: run new_NAME into DIR in the
# background; MODE "time": kill -9 after DELAY seconds; MODE "watch": kill -9
# DELAY seconds after a new directory entry (the temporary file) appears.
trial() {
  local name=$1 dir=$2 ref=$3 old=$4 was_old=$5 mode=$6 delay=$7 pid code base
  prepare "$dir" "$old" "$was_old"
  local entries=("$dir"/*)
  base=${#entries[@]}
  "new_$name" "$dir"
  { "${cmd[@]}" & } 2>/dev/null
  pid=$!
  if [ "$mode" = watch ]; then
    local limit=$((SECONDS + 120))
    while kill -0 "$pid" 2>/dev/null && [ "$SECONDS" -lt "$limit" ]; do
      entries=("$dir"/*)
      [ "${#entries[@]}" -gt "$base" ] && break
      read -r -t 0.001 -u "$never" || true  # a 1 ms pause without a process
    done
  fi
  [ "$delay" = 0 ] || sleep "$delay"
  kill -9 "$pid" 2>/dev/null
  { wait "$pid"; } 2>/dev/null
  code=$?
  case $code in
    137) killed=$((killed + 1)) ;;
    0) completed=$((completed + 1)) ;;
    *) echo "  $name: exit $code (not killed, not success)"; trial_failures=$((trial_failures + 1)) ;;
  esac
  if ! verify "$dir" "$ref" "$old" "$was_old"; then
    echo "  ^ $name $mode ${delay}s, previous output present: $was_old"
    trial_failures=$((trial_failures + 1))
  fi
}

# kill_test NAME CHECK [stale]: reference run (timed), previous outputs, the
# kills; with "stale", a last run beside the temporaries the kills left.
all_temps=0 budget=${LK_KILL_BUDGET:-35} kinds_left=6
kill_test() {
  local name=$1 check_command=$2 stale=${3:-}
  local ref="$TMP/ref-$name" old="$TMP/old-$name" dir="$TMP/run-$name" test_start=$SECONDS
  mkdir -p "$ref" "$old"
  local start end duration
  start=$(seconds_now)
  "new_$name" "$ref"
  $TIMEOUT 300 "${cmd[@]}"
  local code=$?
  end=$(seconds_now)
  duration=$(calc "$end - $start")
  check "$name: reference run exit 0 ($code)" test "$code" -eq 0
  "old_$name" "$old"
  $TIMEOUT 300 "${cmd[@]}"
  check "$name: previous-output run" test $? -eq 0
  local files=("$ref"/*)
  check "$name: reference wrote files (${#files[@]})" test "${#files[@]}" -gt 0
  local path
  for path in "$ref"/*; do
    check "$name: reference ${path##*/} reads back" $check_command "$path"
    if same "$path" "$old/${path##*/}"; then echo "  note: $name ${path##*/}: previous = new"; fi
  done
  # Kills: at 1 or 2 random instants; 2 right after write-out starts (+0,
  # +2 ms); at fractions 0.05..1.05 of the run, 3..12 of them: as many as
  # this kind's share of the time left in a $budget s budget allows (12 in
  # the release build; fewer in the ASan build or on a loaded machine).
  local timed random
  random=$(awk -v t="$duration" 'BEGIN { print t < 0.5 ? 2 : 1 }')
  timed=$(awk -v t="$duration" -v left="$((budget - SECONDS))" -v kinds="$kinds_left" -v random="$random" \
    'BEGIN { share = left / kinds - t * (2 + random * 0.5); n = int(share / (0.55 * t + 0.03));
             if (n > 12) n = 12; if (n < 3) n = 3; print n }')
  kinds_left=$((kinds_left - 1))
  killed=0 completed=0 temps_left=0 outputs_new=0 outputs_old=0 outputs_absent=0 trial_failures=0
  local k fraction
  for ((k = 1; k <= timed; k++)); do
    fraction=$(calc "($k - 0.5) / $timed * 1.1")
    trial "$name" "$dir" "$ref" "$old" $((k % 2)) time "$(calc "$fraction * $duration")"
  done
  for ((k = 1; k <= random; k++)); do
    trial "$name" "$dir" "$ref" "$old" $((k % 2)) time "$(calc "$RANDOM / 32767 * 1.05 * $duration")"
  done
  for delay in 0 0.002; do
    trial "$name" "$dir" "$ref" "$old" 0 watch "$delay"
  done
  echo "$name: run ${duration}s; $((timed + random + 2)) kills ($timed timed, $random random, 2 at write-out): $killed killed," \
       "$completed completed first; outputs afterwards: $outputs_absent absent, $outputs_old previous," \
       "$outputs_new new; $temps_left temporary files left; $((SECONDS - test_start)) s"
  all_temps=$((all_temps + temps_left))
  check "$name: every kill left old-or-complete outputs ($trial_failures bad trials)" test "$trial_failures" -eq 0
  check "$name: some runs were killed ($killed)" test "$killed" -gt 0
  # Leftover temporaries of killed runs do not disturb the next run, which
  # leaves them alone (they may belong to a run still going on).
  if [ "$stale" != stale ]; then rm -rf "$dir" "$old"; return; fi
  touch "$dir/.out.stale.tmp-AAAAAA"
  local temps=("$dir"/.*.tmp-*)
  "new_$name" "$dir"
  $TIMEOUT 300 "${cmd[@]}"
  check "$name: run beside ${#temps[@]} leftover temporaries exit 0" test $? -eq 0
  local after=("$dir"/.*.tmp-*)
  check "$name: leftovers untouched (${#after[@]} of ${#temps[@]})" test "${#after[@]}" -eq "${#temps[@]}"
  for path in "$ref"/*; do
    check "$name: ${path##*/} complete after the leftovers" same "$dir/${path##*/}" "$path"
  done
  rm -rf "$dir" "$old"
}

info_ok() { $TIMEOUT 60 "$LODKIT" info "$1" >/dev/null 2>&1; }
inspect_ok() { $TIMEOUT 60 "$LODKIT" inspect "$1" >/dev/null 2>&1; }
animate_file_ok() {
  case $1 in
    *.md2) info_ok "$1" ;;
    *.csv) head -1 "$1" | grep -q '^level,ratio,frame,' ;;
    *.png) head -c 8 "$1" | od -An -tx1 | grep -q '89 50 4e 47 0d 0a 1a 0a' ;;
    *) false ;;
  esac
}
# animate_set_ok DIR: a complete set: its manifest lists exactly its files,
# and each reads back.
animate_set_ok() {
  local path
  [ -d "$1" ] && [ "$(tail -n +2 "$1/.lodkit-animate" | sort)" = "$(ls "$1" | sort)" ] || return 1
  for path in "$1"/*; do
    [ "${path##*/}" = .lodkit-animate ] || animate_file_ok "$path" || return 1
  done
}

kill_test qem_obj info_ok
kill_test qem_ply info_ok
kill_test wavelet_off info_ok
kill_test progressive inspect_ok
kill_test convert info_ok stale
kill_test animate animate_set_ok stale
# A kill just after the temporary file appears almost always finds it.
check "some kills during write-out left a temporary file ($all_temps)" test "$all_temps" -gt 0
# The reference outputs read back as the expected meshes.
check "qem .obj holds 10% of the bunny" sh -c "'$LODKIT' info --json '$TMP/ref-qem_obj/out.obj' | grep -q '\"triangles\":6966[,}]'"
check "convert .off holds the whole bunny" sh -c "'$LODKIT' info --json '$TMP/ref-convert/out.off' | grep -q '\"triangles\":69666[,}]'"

# ---- animate: one output set --------------------------------------------
# An LD_PRELOAD shim over renameat2 and rename: LK_SHIM_NO_EXCHANGE=1 fails
# RENAME_EXCHANGE with EINVAL, as NFS and CIFS do; LK_SHIM_PAUSE=INSTANT
# creates $LK_SHIM_MARK and stops the run there (until $LK_SHIM_RESUME
# exists, at most 60 s), for the test to kill it or act meanwhile:
# before-exchange, after-exchange, or after-aside (no exchange: the previous
# set renamed aside, the new one not yet in).
require cc build-essential
cat >"$TMP/shim.c" <<'SHIM'
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
static void pause_at(const char *instant)
{
    const char *want = getenv("LK_SHIM_PAUSE"), *mark = getenv("LK_SHIM_MARK");
    if (!want || !mark || strcmp(want, instant) != 0) return;
    int fd = open(mark, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) close(fd);
    const char *resume = getenv("LK_SHIM_RESUME");
    struct timespec millisecond = {0, 1000000};
    for (int i = 0; i < 60000 && !(resume && access(resume, F_OK) == 0); i++) nanosleep(&millisecond, NULL);
}
int renameat2(int from_fd, const char *from, int to_fd, const char *to, unsigned int flags)
{
    int (*real)(int, const char *, int, const char *, unsigned int) =
        (int (*)(int, const char *, int, const char *, unsigned int))dlsym(RTLD_NEXT, "renameat2");
    if (flags & RENAME_EXCHANGE) {
        if (getenv("LK_SHIM_NO_EXCHANGE")) { errno = EINVAL; return -1; }
        pause_at("before-exchange");
    }
    int result = real(from_fd, from, to_fd, to, flags);
    if (result == 0 && (flags & RENAME_EXCHANGE)) pause_at("after-exchange");
    return result;
}
int rename(const char *from, const char *to)
{
    int (*real)(const char *, const char *) = (int (*)(const char *, const char *))dlsym(RTLD_NEXT, "rename");
    int result = real(from, to);
    const char *name = strrchr(to, '/');
    if (result == 0 && strstr(name ? name : to, ".old-")) pause_at("after-aside");
    return result;
}
SHIM
cc -shared -fPIC -O1 -o "$TMP/shim.so" "$TMP/shim.c" -ldl
check "the rename shim builds" test -f "$TMP/shim.so"
# The ASan runtime wants to be the first library; the shim only wraps rename.
shim=(env LD_PRELOAD="$TMP/shim.so" ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0")
new_set="$TMP/ref-animate"  # kill_test's reference: the new set is new_set/set
old_set="$TMP/old-set"
mkdir -p "$old_set"
old_animate "$old_set"
"${cmd[@]}"
check "previous set for the swap checks" animate_set_ok "$old_set/set"

# beside_only DIR PATTERN: DIR holds nothing but `set` (if present) and
# hidden folders whose names match PATTERN.
beside_only() {
  local entry name
  for entry in "$1"/*; do
    name=${entry##*/}
    [ "$name" = set ] || { [[ $name =~ $2 ]] && [ -d "$entry" ]; } || { echo "  unexpected: $name"; return 1; }
  done
}

# swap_kill INSTANT WAS_OLD EXPECT [VAR=VALUE...]: new_animate into $TMP/swap
# (holding the previous set when WAS_OLD is 1), stopped by the shim at
# INSTANT and killed there; then set must be EXPECT (new, old or absent).
swap_kill() {
  local instant=$1 was_old=$2 expect=$3 dir="$TMP/swap" mark="$TMP/swap-mark" pid code limit
  shift 3
  prepare "$dir" "$old_set" "$was_old"
  rm -f "$mark"
  new_animate "$dir"
  { "${shim[@]}" LK_SHIM_PAUSE="$instant" LK_SHIM_MARK="$mark" "$@" "${cmd[@]}" & } 2>/dev/null
  pid=$!
  limit=$((SECONDS + 60))
  while [ ! -e "$mark" ] && kill -0 "$pid" 2>/dev/null && [ "$SECONDS" -lt "$limit" ]; do
    read -r -t 0.002 -u "$never" || true
  done
  kill -9 "$pid" 2>/dev/null
  { wait "$pid"; } 2>/dev/null
  code=$?
  check "swap kill $instant $*: the run stopped there and was killed (exit $code)" test -e "$mark" -a "$code" -eq 137
  case $expect in
    new) check "swap kill $instant $*: the new set in place" same "$dir/set" "$new_set/set" ;;
    old) check "swap kill $instant $*: the previous set in place" same "$dir/set" "$old_set/set" ;;
    absent) check "swap kill $instant $*: no set in place" test ! -e "$dir/set" ;;
  esac
  check "swap kill $instant $*: beside it only hidden folders" beside_only "$dir" '^\.set\.(tmp|old)-[A-Za-z0-9]{6}$'
}
swap_kill before-exchange 1 old
check "before the exchange: the new set complete in the hidden folder" same "$TMP"/swap/.set.tmp-* "$new_set/set"
swap_kill after-exchange 1 new
check "after the exchange: the previous set complete in the hidden folder" same "$TMP"/swap/.set.tmp-* "$old_set/set"
# The run waits on the lock the test holds: killed there, nothing changed.
dir="$TMP/swap"
prepare "$dir" "$old_set" 1
exec {lock}<"$dir/set"
flock -x "$lock"
: >"$TMP/wait.txt"
{ "$LODKIT" animate --levels=2 --metro-step=99 --samples-per-face=1 "$S/faerie.md2" "$dir/set" >/dev/null 2>"$TMP/wait.txt" \
    {lock}<&- & } 2>/dev/null
pid=$!
limit=$((SECONDS + 60))
until grep -q "waiting for another" "$TMP/wait.txt" || ! kill -0 "$pid" 2>/dev/null || [ "$SECONDS" -ge "$limit" ]; do
  read -r -t 0.005 -u "$never" || true
done
check "lock held: the run says it waits: $(head -1 "$TMP/wait.txt")" \
  grep -q "lodkit animate: waiting for another lodkit animate writing $dir/set" "$TMP/wait.txt"
kill -9 "$pid" 2>/dev/null
{ wait "$pid"; } 2>/dev/null
exec {lock}<&-
check "lock held, run killed: the previous set in place" same "$dir/set" "$old_set/set"
check "lock held, run killed: beside it only its hidden folder" beside_only "$dir" '^\.set\.tmp-[A-Za-z0-9]{6}$'
# A file that appears in OUTDIR after the run checked it (here: while the
# run is stopped just before the exchange) is not deleted: the previous
# set's folder stays at its hidden name with it, the run says so, exit 0.
dir="$TMP/swap"
prepare "$dir" "$old_set" 1
rm -f "$TMP/swap-mark" "$TMP/swap-resume"
new_animate "$dir"
{ "${shim[@]}" LK_SHIM_PAUSE=before-exchange LK_SHIM_MARK="$TMP/swap-mark" LK_SHIM_RESUME="$TMP/swap-resume" \
    "${cmd[@]}" 2>"$TMP/late.txt" & } 2>/dev/null
pid=$!
limit=$((SECONDS + 60))
until [ -e "$TMP/swap-mark" ] || ! kill -0 "$pid" 2>/dev/null || [ "$SECONDS" -ge "$limit" ]; do
  read -r -t 0.002 -u "$never" || true
done
echo "mine" >"$dir/set/late.txt"
touch "$TMP/swap-resume"
{ wait "$pid"; } 2>/dev/null
check "a file appeared during the swap: exit 0 ($?)" test $? -eq 0
check "a file appeared during the swap: the new set in place" same "$dir/set" "$new_set/set"
late=("$dir"/.set.tmp-* "$dir/no-hidden-folder")
check "a file appeared during the swap: kept in the previous folder (${late[*]##*/})" \
  test "${#late[@]}" -eq 2 -a "$(cat "${late[0]}/late.txt" 2>/dev/null)" = mine
check "a file appeared during the swap: only it is left there ($(ls -A "${late[0]}" 2>&1 | tr '\n' ' '))" \
  test "$(ls -A "${late[0]}" 2>&1)" = late.txt
check "a file appeared during the swap: the run says where: $(head -1 "$TMP/late.txt")" \
  grep -qF "$dir/set: the previous set's folder also held files lodkit animate did not write: left them in ${late[0]}" \
  "$TMP/late.txt"
# No RENAME_EXCHANGE: the previous set is moved aside, then the new one in;
# killed in between, both are complete at their hidden names.
swap_kill after-aside 1 absent LK_SHIM_NO_EXCHANGE=1
check "no exchange, killed between: the previous set complete at .set.old-*" same "$TMP"/swap/.set.old-* "$old_set/set"
check "no exchange, killed between: the new set complete at .set.tmp-*" same "$TMP"/swap/.set.tmp-* "$new_set/set"
# A later run succeeds beside the leftovers and leaves them alone.
new_animate "$TMP/swap"
"${shim[@]}" LK_SHIM_NO_EXCHANGE=1 $TIMEOUT 120 "${cmd[@]}"
check "no exchange: a run beside the leftovers exit 0 ($?)" test $? -eq 0
check "no exchange: its set in place" same "$TMP/swap/set" "$new_set/set"
check "no exchange: the leftovers untouched" test "$(ls -A "$TMP/swap" | wc -l)" -eq 3

# Two runs with different options into one folder at the same time (the
# same work but another lost-surface weight: they finish together, and their
# level-1 files, CSV and PNG differ): each builds its own set and the lock
# orders their swaps; the folder ends with one run's complete set byte for
# byte, both exit 0, nothing beside it.
# HOLD 1: the test holds the lock until both runs wait on it, so the second
# to get it finds the folder swapped under it and locks the new one.
# (The runs must not inherit the test's locked descriptor: a lock lasts while
# any copy of it is open.)
# race HOLD WAS_OLD [VAR=VALUE...]
race() {
  local hold=$1 was_old=$2 dir="$TMP/race" pid_a pid_b code_a code_b limit winner=mixed race_lock label
  shift 2
  label="race hold=$hold previous=$was_old${*:+ $*}"
  prepare "$dir" "$old_set" "$was_old"
  if [ "$hold" = 1 ]; then exec {race_lock}<"$dir/set"; flock -x "$race_lock"; fi
  { ( [ "$hold" = 0 ] || exec {race_lock}<&-
      exec "${shim[@]}" "$@" "$LODKIT" animate --levels=2 --metro-step=99 --samples-per-face=1 "$S/faerie.md2" "$dir/set"
    ) >/dev/null 2>"$TMP/race-a.txt" & } 2>/dev/null
  pid_a=$!
  { ( [ "$hold" = 0 ] || exec {race_lock}<&-
      exec "${shim[@]}" "$@" "$LODKIT" animate "${race_b[@]}" "$S/faerie.md2" "$dir/set"
    ) >/dev/null 2>"$TMP/race-b.txt" & } 2>/dev/null
  pid_b=$!
  if [ "$hold" = 1 ]; then
    limit=$((SECONDS + 60))
    until { grep -q "waiting for another" "$TMP/race-a.txt" && grep -q "waiting for another" "$TMP/race-b.txt"; } ||
          [ "$SECONDS" -ge "$limit" ]; do
      read -r -t 0.005 -u "$never" || true
    done
    check "$label: both runs wait for the lock" \
      sh -c "grep -q 'waiting for another' '$TMP/race-a.txt' && grep -q 'waiting for another' '$TMP/race-b.txt'"
    exec {race_lock}<&-
  fi
  { wait "$pid_a"; } 2>/dev/null
  code_a=$?
  { wait "$pid_b"; } 2>/dev/null
  code_b=$?
  if same "$dir/set" "$new_set/set"; then winner=a; elif same "$dir/set" "$TMP/race-b/set"; then winner=b; fi
  races="$races $winner"
  check "$label: both exit 0 ($code_a, $code_b)$(grep -hv waiting "$TMP/race-a.txt" "$TMP/race-b.txt" | head -2)" \
    test "$code_a" -eq 0 -a "$code_b" -eq 0
  check "$label: one complete set ($winner)" test "$winner" != mixed
  check "$label: nothing beside it ($(ls -A "$dir" | tr '\n' ' '))" test "$(ls -A "$dir")" = set
}
race_b=(--levels=2 --metro-step=99 --samples-per-face=1 --lost-surface=200)
mkdir -p "$TMP/race-b"
"$LODKIT" animate -q "${race_b[@]}" "$S/faerie.md2" "$TMP/race-b/set"
check "race: the two runs' sets differ" test -n "$(diff -rq "$new_set/set" "$TMP/race-b/set")"
races="" race_start=$SECONDS
race 1 1
race 0 0
race 0 1
race 1 1 LK_SHIM_NO_EXCHANGE=1
race 0 1 LK_SHIM_NO_EXCHANGE=1
echo "animate races: the set of run a or b won:$races; $((SECONDS - race_start)) s"

# ---- write failures -----------------------------------------------------
# only_file DIR NAME: DIR holds NAME and nothing else (no temporary file).
only_file() { local entries=("$1"/*); [ "${#entries[@]}" -eq 1 ] && [ -e "$1/$2" ]; }
w="$TMP/write"
mkdir -p "$w"
"$LODKIT" simplify -q -r 0.05 "$S/cow.off" "$TMP/previous.obj"
"$LODKIT" progressive -q "$S/triceratops.off" "$TMP/previous.lks"
cp "$TMP/previous.obj" "$TMP/previous.lks" "$w"/
mv "$w/previous.obj" "$w/out.obj"
mv "$w/previous.lks" "$w/out.lks"

# A file-size limit: writes fail with EFBIG (SIGXFSZ ignored, as a shell
# with `trap '' XFSZ` passes on). Each new output is larger than 16 KB.
limited() { (trap '' XFSZ; ulimit -f 16; exec $TIMEOUT 120 "$@"); }
limited "$LODKIT" simplify -q -r 1 "$S/cow.off" "$w/out.obj" 2>"$TMP/err.txt"
check "EFBIG: simplify exit 1 ($?)" test $? -eq 1
check "EFBIG: message names the file and the OS reason: $(head -1 "$TMP/err.txt")" \
  grep -q "out.obj: write error.*: File too large" "$TMP/err.txt"
check "EFBIG: previous .obj unchanged" cmp -s "$w/out.obj" "$TMP/previous.obj"
limited "$LODKIT" progressive -q "$S/bunny.obj" "$w/out.lks" 2>"$TMP/err.txt"  # 131 KB
check "EFBIG: progressive exit 1 ($?)" test $? -eq 1
check "EFBIG: progressive says why: $(head -1 "$TMP/err.txt")" grep -q "out.lks: write error: File too large" "$TMP/err.txt"
check "EFBIG: previous .lks unchanged" cmp -s "$w/out.lks" "$TMP/previous.lks"
expect_exit 1 limited "$LODKIT" convert -q "$S/cow.off" "$w/big.ply"
check "EFBIG: no new file, no temporary ($(ls -A "$w" | tr '\n' ' '))" test "$(ls -A "$w" | tr '\n' ' ')" = "out.lks out.obj "
# animate: the limit (300 KB) stops the second level (416 KB) after the first
# (233 KB) was written: OUTDIR as it was (absent, or the previous set), no
# hidden folder left beside it, the message names the file in OUTDIR.
a="$TMP/anim-parent"
mkdir -p "$a"
limited "$LODKIT" animate -q --levels=2 --no-metro "$S/faerie.md2" "$a/new" 2>"$TMP/err.txt"
check "EFBIG: animate exit 1 ($?)" test $? -eq 1
check "EFBIG: animate names the file: $(head -1 "$TMP/err.txt")" grep -q "$a/new/faerie-max-L01.md2: write error" "$TMP/err.txt"
check "EFBIG: animate created nothing ($(ls -A "$a" | tr '\n' ' '))" test -z "$(ls -A "$a")"
cp -a "$old_set/set" "$a/anim"
(trap '' XFSZ; ulimit -f 300; exec $TIMEOUT 120 "$LODKIT" animate -q --levels=2 --no-metro "$S/faerie.md2" "$a/anim") \
  2>"$TMP/err.txt"
check "EFBIG: animate over a previous set exit 1 ($?)" test $? -eq 1
check "EFBIG: the second level failed: $(head -1 "$TMP/err.txt")" grep -q "$a/anim/faerie-max-L02.md2: write error" "$TMP/err.txt"
check "EFBIG: the previous set unchanged" same "$a/anim" "$old_set/set"
check "EFBIG: nothing beside it ($(ls -A "$a" | tr '\n' ' '))" test "$(ls -A "$a")" = anim

# A missing directory, a directory path, a symlink to a device: refused.
"$LODKIT" simplify -q -r 0.5 "$S/cow.off" "$TMP/missing/dir/out.obj" 2>"$TMP/err.txt"
check "missing directory: exit 1" test $? -eq 1
check "missing directory: says which and why: $(head -1 "$TMP/err.txt")" \
  grep -q "missing/dir'*: No such file or directory" "$TMP/err.txt"
check "missing directory: nothing created" test ! -e "$TMP/missing"
expect_exit 1 "$LODKIT" progressive -q "$S/cow.off" "$TMP/missing/out.lks"
expect_exit 1 "$LODKIT" animate -q --ratio=0.5 --no-metro "$S/faerie.md2" "$TMP/missing/a/b"
check "animate: missing parent not created" test ! -e "$TMP/missing"
mkdir -p "$w/dir.obj"
expect_output_contains "not a regular file" "$LODKIT" simplify -q -r 0.5 "$S/cow.off" "$w/dir.obj"
ln -s /dev/full "$w/full.obj"
"$LODKIT" simplify -q -r 0.5 "$S/cow.off" "$w/full.obj" 2>"$TMP/err.txt"
check "symlink to /dev/full: exit 1" test $? -eq 1
check "symlink to /dev/full: refused: $(head -1 "$TMP/err.txt")" grep -q "not a regular file" "$TMP/err.txt"
check "symlink to /dev/full: link and device kept" test -L "$w/full.obj" -a -c /dev/full
rm -f "$w/full.obj"
rmdir "$w/dir.obj"
# An output that is a symlink to a regular file: the new file replaces the
# link (rename replaces the name), the file it pointed to is left as it was
# (documented in SECURITY.md: lodkit never writes through a link).
cp "$TMP/previous.obj" "$TMP/link-target.obj"
ln -s "$TMP/link-target.obj" "$w/linked.obj"
expect_exit 0 "$LODKIT" simplify -q -r 0.5 "$S/cow.off" "$w/linked.obj"
check "symlink output: the link is now a regular file" test -f "$w/linked.obj" -a ! -L "$w/linked.obj"
check "symlink output: the link's target unchanged" cmp -s "$TMP/link-target.obj" "$TMP/previous.obj"
rm -f "$w/linked.obj"

# A directory we may not write: as root, run as nobody (root ignores modes).
# The binary (static) and the input are copied into $TMP, so nobody can run
# and read them wherever the build tree and the samples live.
ro="$TMP/readonly"
mkdir -p "$ro"
cp "$TMP/previous.obj" "$ro/out.obj"
cp "$LODKIT" "$TMP/lodkit-copy"
cp "$S/cow.off" "$TMP/cow-copy.off"
chmod 755 "$TMP" "$TMP/lodkit-copy"
chmod 644 "$TMP/cow-copy.off"
chmod 555 "$ro"
as_user=()
if [ "$(id -u)" = 0 ]; then as_user=(setpriv --reuid=65534 --regid=65534 --clear-groups); fi
"${as_user[@]}" $TIMEOUT 60 "$TMP/lodkit-copy" simplify -q -r 0.5 "$TMP/cow-copy.off" "$ro/out.obj" 2>"$TMP/err.txt"
check "read-only directory: exit 1" test $? -eq 1
check "read-only directory: clear message: $(head -1 "$TMP/err.txt")" grep -q "Permission denied" "$TMP/err.txt"
check "read-only directory: previous output unchanged" cmp -s "$ro/out.obj" "$TMP/previous.obj"
check "read-only directory: nothing else" only_file "$ro" out.obj
chmod 755 "$ro"
chmod 700 "$TMP"

# ENOSPC and EROFS on a small tmpfs in a private mount namespace (nothing is
# mounted outside it; needs CAP_SYS_ADMIN or unprivileged user namespaces).
cat >"$TMP/tmpfs.sh" <<'EOF'
set -u
ok() { echo "ok $*"; }
bad() { echo "FAIL $*"; }
m="$TMP/tmpfs"
mount -t tmpfs -o size=24k lodkit-test "$m" || { echo "SKIP mount"; exit 0; }
# an empty mount point: animate cannot rename it, and says so before any work
$TIMEOUT 60 "$LODKIT" animate -q --ratio=0.5 --no-metro "$S/faerie.md2" "$m" 2>"$TMP/tmpfs-err.txt"
[ $? -eq 1 ] && ok "animate into a mount point exit 1" || bad "animate into a mount point exit"
grep -q "$m: is a mount point" "$TMP/tmpfs-err.txt" && ok "animate into a mount point: refused" \
  || bad "animate into a mount point: $(cat "$TMP/tmpfs-err.txt")"
[ -z "$(ls -A "$m")" ] && ! ls -A "$TMP" | grep -q '^\.tmpfs\.' && ok "animate into a mount point: nothing written" \
  || bad "animate into a mount point left: $(ls -A "$m" "$TMP" | tr '\n' ' ')"
"$LODKIT" simplify -q -r 0.05 "$S/cow.off" "$m/out.obj" || bad "small output"
cp "$m/out.obj" "$TMP/tmpfs-previous.obj"
$TIMEOUT 120 "$LODKIT" simplify -q -r 1 "$S/cow.off" "$m/out.obj" 2>"$TMP/tmpfs-err.txt"
[ $? -eq 1 ] && ok "ENOSPC simplify exit 1" || bad "ENOSPC simplify exit"
grep -q "out.obj: write error.*: No space left on device" "$TMP/tmpfs-err.txt" && ok "ENOSPC message" || bad "ENOSPC message: $(cat "$TMP/tmpfs-err.txt")"
cmp -s "$m/out.obj" "$TMP/tmpfs-previous.obj" && ok "ENOSPC previous kept" || bad "ENOSPC previous changed"
$TIMEOUT 120 "$LODKIT" progressive -q "$S/cow.off" "$m/out.lks" 2>/dev/null
[ $? -eq 1 ] && ok "ENOSPC progressive exit 1" || bad "ENOSPC progressive exit"
$TIMEOUT 120 "$LODKIT" animate -q --levels=2 --no-metro "$S/faerie.md2" "$m/anim" 2>/dev/null
[ $? -eq 1 ] && ok "ENOSPC animate exit 1" || bad "ENOSPC animate exit"
[ "$(ls -A "$m")" = out.obj ] && ok "ENOSPC no temporary left, no OUTDIR created" \
  || bad "ENOSPC leftovers: $(ls -A "$m" | tr '\n' ' ')"
mount -o remount,ro "$m" || { echo "SKIP remount"; exit 0; }
$TIMEOUT 60 "$LODKIT" simplify -q -r 0.01 "$S/cow.off" "$m/out.obj" 2>"$TMP/tmpfs-err.txt"
[ $? -eq 1 ] && ok "EROFS exit 1" || bad "EROFS exit"
grep -q "Read-only file system" "$TMP/tmpfs-err.txt" && ok "EROFS message" || bad "EROFS message: $(cat "$TMP/tmpfs-err.txt")"
cmp -s "$m/out.obj" "$TMP/tmpfs-previous.obj" && ok "EROFS previous kept" || bad "EROFS previous changed"
EOF
mkdir -p "$TMP/tmpfs"
namespace=()
if unshare -m true 2>/dev/null; then namespace=(unshare -m)
elif unshare -rm true 2>/dev/null; then namespace=(unshare -rm)
fi
if [ "${#namespace[@]}" -gt 0 ]; then
  TMP="$TMP" S="$S" LODKIT="$LODKIT" TIMEOUT="$TIMEOUT" $TIMEOUT 300 "${namespace[@]}" bash "$TMP/tmpfs.sh" >"$TMP/tmpfs.txt" 2>&1
  if grep -q '^SKIP' "$TMP/tmpfs.txt"; then
    echo "SKIP: tmpfs checks: $(grep '^SKIP' "$TMP/tmpfs.txt")"
  fi
  while read -r word rest; do
    case $word in
      ok) check "tmpfs: $rest" true ;;
      FAIL) check "tmpfs: $rest" false ;;
    esac
  done <"$TMP/tmpfs.txt"
  check "tmpfs: checks ran or were skipped" grep -q '^ok\|^SKIP' "$TMP/tmpfs.txt"
else
  echo "SKIP: no private mount namespace here: ENOSPC/EROFS checked only through the file-size limit"
fi
finish
