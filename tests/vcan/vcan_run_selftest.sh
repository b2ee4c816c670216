#!/bin/bash
# Checks scripts/vcan-run itself: where it ran, vcan0 up, working directory, environment,
# arguments, stdout/stderr, exit status, clean-up, and a loud failure when no vcan can be had.
# One vcan-run with the default backend, then one per forced backend where it must explain itself.
#   vcan_run_selftest.sh PATH/TO/vcan-run
set -u
vcan_run=${1:?usage: vcan_run_selftest.sh PATH/TO/vcan-run}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir "$work/tmp" "$work/cwd"
cd "$work/cwd" || exit 1

failures=0
check() {  # description, then a command that must succeed
  local what=$1
  shift
  if "$@"; then echo "ok   $what"; else
    echo "FAIL $what"
    failures=$((failures + 1))
  fi
}
has_line() { grep -q -x -F -- "$2" "$1"; }

# shellcheck disable=SC2016  # the $ and quotes are the test data
export VCAN_SELFTEST_VALUE='two words "quoted" $dollar'
start=$(date +%s%N)
# shellcheck disable=SC2016  # expanded by the inner shell
TMPDIR=$work/tmp "$vcan_run" bash -c '
  echo "cwd=$PWD"
  echo "value=$VCAN_SELFTEST_VALUE"
  echo "args=$#:$1|$2"
  ip -details link show vcan0 | grep -q -w vcan && echo "vcan0 is vcan"
  ip link show vcan0 | grep -q "[<,]UP[,>]" && echo "vcan0 is up"
  [ -t 0 ] || echo "stdin is not a terminal"
  echo "backend=$FIELDGATE_VCAN_BACKEND"
  echo to-stderr >&2
  exit 7' _ arg1 'arg 2' >"$work/out" 2>"$work/err"
rc=$?
elapsed_ms=$((($(date +%s%N) - start) / 1000000))

echo "--- vcan-run stdout"
cat "$work/out"
echo "--- vcan-run stderr"
cat "$work/err"
echo "---"
echo "vcan-run took ${elapsed_ms} ms"

check "exit status 7 passed back (got $rc)" test "$rc" -eq 7
check "first line says where it ran" \
  grep -q -x -E 'vcan: (host|user-mode-linux [0-9][0-9A-Za-z.+~-]*|qemu-(kvm|tcg) [0-9][0-9A-Za-z.+~-]*)' \
  <(head -n 1 "$work/out")
check "CMD is told the backend of the first line" \
  has_line "$work/out" "backend=$(head -n 1 "$work/out" | sed 's/^vcan: //')"
check "vcan0 is a vcan device" has_line "$work/out" "vcan0 is vcan"
check "vcan0 is up" has_line "$work/out" "vcan0 is up"
check "runs in the caller's directory" has_line "$work/out" "cwd=$work/cwd"
check "caller's environment, quoting intact" has_line "$work/out" "value=$VCAN_SELFTEST_VALUE"
check "arguments, quoting intact" has_line "$work/out" "args=2:arg1|arg 2"
check "stdin is not a terminal" has_line "$work/out" "stdin is not a terminal"
check "stderr comes back on stderr" has_line "$work/err" "to-stderr"
check "stdout has no stderr lines" bash -c "! grep -q to-stderr '$work/out'"
check "temporary files removed" test -z "$(ls -A "$work/tmp")"

# Without a way to get vcan it must fail loudly and not run the command.
FIELDGATE_VCAN=uml FIELDGATE_UML_KERNEL=/nonexistent/linux.uml \
  "$vcan_run" touch "$work/ran" >"$work/out2" 2>"$work/err2"
rc=$?
check "no vcan: non-zero exit (got $rc)" test "$rc" -ne 0
check "no vcan: command not run" test ! -e "$work/ran"
check "no vcan: says why" grep -q "User-Mode Linux: '/nonexistent/linux.uml' not found" "$work/err2"
check "no vcan: names the command" grep -q "vcan-run: error: cannot run 'touch' with vcan0" "$work/err2"

FIELDGATE_VCAN=nonsense "$vcan_run" touch "$work/ran" >/dev/null 2>"$work/err3"
rc=$?
check "unknown backend: exit 125 (got $rc)" test "$rc" -eq 125
check "unknown backend: command not run" test ! -e "$work/ran"
check "unknown backend: lists the valid ones" grep -q 'auto, host, uml, qemu' "$work/err3"

# Forced User-Mode Linux: it runs where UML runs user space on this CPU, and where it does not
# (UML 6.1 on AMX/AVX-512 CPUs), vcan-run says so instead of running the command.
FIELDGATE_VCAN=uml "$vcan_run" bash -c 'touch "$1"; ip link show vcan0 >/dev/null' _ "$work/ran-uml" \
  >"$work/out4" 2>"$work/err4"
rc=$?
echo "--- FIELDGATE_VCAN=uml: status $rc"
cat "$work/out4" "$work/err4"
if [[ $rc -eq 0 ]]; then
  check "uml: says it ran in UML" grep -q -x -E 'vcan: user-mode-linux .+' <(head -n 1 "$work/out4")
  check "uml: command ran" test -e "$work/ran-uml"
else
  check "uml unusable: exit 125 (got $rc)" test "$rc" -eq 125
  check "uml unusable: command not run" test ! -e "$work/ran-uml"
  check "uml unusable: says why" grep -q -E 'User-Mode Linux: .*(ran no user space|not found|missing)' "$work/err4"
fi

"$vcan_run" >/dev/null 2>&1
rc=$?
check "no command: usage and non-zero exit (got $rc)" test "$rc" -ne 0

((failures == 0)) && echo "all checks passed"
((failures == 0))
