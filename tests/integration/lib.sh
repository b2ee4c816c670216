# shellcheck shell=bash
# Sourced by the integration scripts and tests/independent/run.sh: the scratch directory and its
# EXIT trap, simulators and the daemon started as jobs of the calling shell (so the trap's
# `kill $(jobs -p)` stops them), the daemon's config, and the checks and mbpoll calls they share.

# The scripts' Python steps import what they share (pymodbus_steps.py) from this folder.
PYTHONPATH="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONPATH

# scratch_dir [CLEANUP]: sets dir to a new scratch directory; on exit runs CLEANUP (e.g. closing
# a FIFO's descriptor), stops the shell's jobs and removes the directory.
scratch_dir() {
  dir=$(mktemp -d)
  # shellcheck disable=SC2064 # CLEANUP is fixed now; $dir and the jobs are read at exit.
  trap "${1:+$1; }"'kill $(jobs -p) 2>/dev/null; wait 2>/dev/null; rm -rf "$dir"' EXIT
}

# wait_for_paths PATH...: waits up to 5 s for each path (a simulator's or relay's PTY link).
wait_for_paths() {
  local path
  for path in "$@"; do
    for _ in $(seq 50); do [ -e "$path" ] && break; sleep 0.1; done
  done
}

# start_sim LOG COMMAND...: a simulator as a job, stdin /dev/null, output to LOG; waits for the
# path after its --link.
start_sim() {
  local log=$1 link="" arg previous=""
  shift
  for arg in "$@"; do
    [ "$previous" = --link ] && link=$arg
    previous=$arg
  done
  "$@" </dev/null >"$log" 2>&1 &
  [ -z "$link" ] || wait_for_paths "$link"
}

# gateway_config FILE [SECTIONS]: the daemon's config: Modbus TCP on a free loopback port, the
# models in $models, SECTIONS (further top-level YAML), then the buses list read from stdin.
gateway_config() {
  {
    echo "modbus: {listen: 127.0.0.1:0}"
    echo "models: $models"
    [ -z "${protocols:-}" ] || echo "protocols: $protocols"
    [ -z "${2:-}" ] || printf '%s\n' "$2"
    echo "buses:"
    cat
  } >"$1"
}

# one_bus_config FILE NAME [SECTIONS]: gateway_config with the one bus NAME whose YAML after its
# name is $bus (as axis_family_start sets it).
one_bus_config() {
  gateway_config "$1" "${3:-}" <<YAML
  - name: $2
    $bus
YAML
}

# log_value LOG SED_SCRIPT: waits up to 10 s for SED_SCRIPT (sed -n) to print something from
# LOG, and prints it.
log_value() {
  local value=""
  for _ in $(seq 100); do
    value=$(sed -n "$2" "$1")
    [ -n "$value" ] && break
    sleep 0.1
  done
  echo "$value"
}

# wait_for_log LOG PATTERN: waits up to 10 s for a line of LOG matching PATTERN (grep -E).
wait_for_log() {
  for _ in $(seq 100); do
    grep -qE "$2" "$1" && return 0
    sleep 0.1
  done
  return 1
}

# start_daemon FIELDGATE CONFIG LOG [READY]: the daemon as a job (-v when FIELDGATE_VERBOSE is
# set); sets `port` to its Modbus TCP port, and waits for a log line matching READY too; exits 1
# with the log if the daemon never gets there.
start_daemon() {
  # The log is created here, not by the job's redirection: the job may not have run yet when
  # the loop below first reads it.
  : >"$3"
  "$1" ${FIELDGATE_VERBOSE:+-v} --config "$2" >"$3" 2>&1 &
  port=$(log_value "$3" 's/.*modbus: listening on 127.0.0.1:\([0-9]*\).*/\1/p')
  [ -n "$port" ] || { echo "daemon did not start"; cat "$3"; exit 1; }
  [ -z "${4:-}" ] || wait_for_log "$3" "$4" || { echo "daemon never logged '$4'"; cat "$3"; exit 1; }
}

# metrics_port LOG: the daemon's metrics port, once logged.
metrics_port() {
  log_value "$1" 's|.*metrics: http://127.0.0.1:\([0-9]*\)/metrics.*|\1|p'
}

fail=0
# check NAME EXPECTED ACTUAL: prints ok or FAIL (and sets fail=1).
check() {
  if [ "$2" == "$3" ]; then echo "ok: $1"; else echo "FAIL: $1: expected '$2', got '$3'"; fail=1; fi
}

# mb OPTIONS... [-- WRITE_VALUES...]: one mbpoll request, 0-based addresses, 1 s timeout, with
# the connection options mbpoll_args (e.g. -m tcp -p PORT) to mbpoll_target (host or device).
mb() {
  local opts=() values=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do opts+=("$1"); shift; done
  [ $# -gt 0 ] && { shift; values=("$@"); }
  mbpoll "${mbpoll_args[@]}" -0 -1 -q "${opts[@]}" -- "$mbpoll_target" "${values[@]}" 2>&1
}

# start_copley SIM LINK NODES LOG: the Copley simulator with NODES (e.g. 0,3) on LINK; sets
# copley_bus to the start of a bus named copley on it, for gateway_config (timing, nodes follow).
start_copley() {
  start_sim "$4" "$1" --link "$2" --nodes "$3"
  copley_bus="  - name: copley
    protocol: copley-ascii
    serial: {device: $2, baud: 115200}"
}

# copley_units SIM [TIMING [NODES]]: the Copley simulator with nodes 0 and 3 on $dir/copley0 and
# the config $dir/gw.yaml serving them as a0 (unit 1) and a3 (unit 2), as mbpoll_basics expects;
# TIMING (the bus's timing map) and NODES (further node lines) go into the bus.
copley_units() {
  start_copley "$1" "$dir/copley0" 0,3 "$dir/sim.log"
  {
    echo "$copley_bus"
    [ -z "${2:-}" ] || echo "    timing: $2"
    echo "    nodes:"
    echo "      - {name: a0, address: 0, model: copley-amplifier, unit_id: 1}"
    echo "      - {name: a3, address: 3, model: copley-amplifier, unit_id: 2}"
    [ -z "${3:-}" ] || echo "$3"
  } | gateway_config "$dir/gw.yaml"
}

# mbpoll_basics LABEL: what every Modbus master checks first on Copley units 1 and 2 (as mb
# reaches them): unit 2 polled, unit 1's position, unit 2's online flag, a 32-bit setpoint
# written and read back.
mbpoll_basics() {
  for _ in $(seq 100); do mb -a 2 -t 3:int -B -r 0 | grep -q '^\[0\]' && break; sleep 0.1; done
  check "$1 reads unit 1 position" "0" "$(mb -a 1 -t 3:int -B -r 0 | sed -n 's/^\[0\]:[[:space:]]*//p')"
  check "$1 reads the online flag" "1" \
    "$(mb -a 2 -t 1 -r 1000 | sed -n 's/^\[1000\]:[[:space:]]*//p')"
  mb -a 2 -t 4:int -B -r 110 -- -1500 >/dev/null || true
  check "$1 writes a 32-bit setpoint" "-1500" \
    "$(mb -a 2 -t 4:int -B -r 110 | sed -n 's/^\[110\]:[[:space:]]*//p')"
}
