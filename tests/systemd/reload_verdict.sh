#!/usr/bin/env bash
# `fieldgate reload` without systemd: the daemon started with --runtime-dir, then a good file
# (exit 0, the next configuration in force), a broken one (exit 1 from the check, no signal
# sent), the broken one again with --no-check (the daemon's own refusal: exit 1, the running
# configuration kept) and a good one after that. The verdict file tells which configuration is
# in force each time. Usage: reload_verdict.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1
src=$2
source "$src/tests/integration/lib.sh"
scratch_dir
fieldgate=$build/gateway/fieldgate
models=$src/config/models
run=$dir/run
mkdir -p "$run"
good() { gateway_config "$dir/gw.yaml" "$1" <<<"  []"; }
good "metrics: {enabled: false}"
: >"$dir/daemon.log"
"$fieldgate" --runtime-dir "$run" --config "$dir/gw.yaml" >"$dir/daemon.log" 2>&1 &
daemon=$!
wait_for_log "$dir/daemon.log" 'config #1 .* in force' || { echo "FAIL: daemon never started"; cat "$dir/daemon.log"; exit 1; }
verdict() { sed -n "s/^$1=//p" "$run/reload-verdict"; }
check "verdict of start-up" "started 0 1 $daemon" "$(verdict result) $(verdict reload) $(verdict config_number) $(verdict pid)"
grep -q 'no field bus configured' "$dir/daemon.log" && echo "ok: a configuration without buses says so" ||
  { echo "FAIL: no notice about the missing buses"; fail=1; }

good "metrics: {enabled: false}
# edited"
"$fieldgate" reload --runtime-dir "$run" --pid "$daemon" >"$dir/r1.out" 2>&1
check "good reload: exit status" 0 $?
check "good reload: verdict" "accepted 1 2" "$(verdict result) $(verdict reload) $(verdict config_number)"
grep -q 'config #2 (.*) in force' "$dir/r1.out" && echo "ok: the helper names config #2" ||
  { echo "FAIL: helper output"; cat "$dir/r1.out"; fail=1; }

echo "modbus: {listen: [oops" >"$dir/gw.yaml"
"$fieldgate" reload --runtime-dir "$run" --pid "$daemon" >"$dir/r2.out" 2>&1
check "broken file: exit status" 1 $?
check "broken file: no signal sent (reload count)" 1 "$(verdict reload)"
grep -q 'gw.yaml:[0-9]*:[0-9]*: ' "$dir/r2.out" && grep -q 'config #2 (.*) stays in force' "$dir/r2.out" &&
  echo "ok: the check's error and the configuration in force are printed" ||
  { echo "FAIL: helper output"; cat "$dir/r2.out"; fail=1; }

"$fieldgate" reload --no-check --runtime-dir "$run" >"$dir/r3.out" 2>&1
check "refused by the daemon: exit status" 1 $?
check "refused by the daemon: verdict" "rejected 2 2" "$(verdict result) $(verdict reload) $(verdict config_number)"
grep -q 'rejected by the daemon: config #2 (.*) stays in force' "$dir/r3.out" &&
  grep -q 'gw.yaml:[0-9]*:[0-9]*: ' "$dir/r3.out" && echo "ok: the daemon's errors reach the helper" ||
  { echo "FAIL: helper output"; cat "$dir/r3.out"; fail=1; }
grep -q 'reload rejected: .*config #2 (.*) stays in force' "$dir/daemon.log" &&
  echo "ok: the daemon logs the refusal" || { echo "FAIL: daemon log"; cat "$dir/daemon.log"; fail=1; }

good "metrics: {enabled: false}"
"$fieldgate" reload --runtime-dir "$run" >"$dir/r4.out" 2>&1
check "good reload after a refusal: exit status" 0 $?
check "good reload after a refusal: verdict" "accepted 3 3" "$(verdict result) $(verdict reload) $(verdict config_number)"

"$fieldgate" reload --runtime-dir "$run" --pid 1 >"$dir/r5.out" 2>&1
check "another pid than the verdict's: exit status" 1 $?
"$fieldgate" reload --runtime-dir "$dir/nowhere" >"$dir/r6.out" 2>&1
check "no verdict file: exit status" 1 $?
kill -STOP "$daemon"
"$fieldgate" reload --runtime-dir "$run" --timeout 0.3 >"$dir/r7.out" 2>&1
check "a daemon that never answers: exit status" 1 $?
grep -q 'no verdict from pid' "$dir/r7.out" && echo "ok: the wait ends" || { echo "FAIL"; cat "$dir/r7.out"; fail=1; }
kill -CONT "$daemon"
exit $fail
