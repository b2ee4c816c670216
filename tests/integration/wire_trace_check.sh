#!/usr/bin/env bash
# The wire trace on an IMS party line (three indexers on one simulated chain): one poll cycle's
# bytes, both directions, for every node, with the outcome; switched off over the metrics
# endpoint and on again with SIGUSR2; plain log lines on a file, <N> prefixes only when
# JOURNAL_STREAM names stderr.
# Usage: wire_trace_check.sh FIELDGATE SIM_IMS MODELS_DIR
set -euo pipefail
fieldgate=$1 sim=$2 models=$3
source "$(dirname "$0")/lib.sh"
scratch_dir
fail() { echo "FAIL: $*"; echo "--- daemon log:"; tail -40 "$dir/daemon.log"; exit 1; }

start_sim "$dir/sim.log" "$sim" --link "$dir/ims0" --axes A,B,C --baud 9600 --emulate-wire
gateway_config "$dir/gw.yaml" "metrics: {listen: 127.0.0.1:0}" <<YAML
  - name: ims
    protocol: ims-party-line
    trace: true
    serial: {device: $dir/ims0, baud: 9600}
    timing: {reply_timeout: 80ms, byte_timeout: 30ms}
    nodes:
      - {name: ims_a, address: A, model: ims-indexer, unit_id: 11}
      - {name: ims_b, address: B, model: ims-indexer, unit_id: 12}
      - {name: ims_c, address: C, model: ims-indexer, unit_id: 13}
YAML

start_daemon() {
  : >"$dir/daemon.log"
  "$fieldgate" --config "$dir/gw.yaml" 2>>"$dir/daemon.log" >/dev/null &
  daemon=$!
}
wait_for() { wait_for_log "$dir/daemon.log" "$1"; }  # PATTERN: a log line matching it, in 10 s

unset JOURNAL_STREAM
start_daemon
# One poll cycle: every node's request (its name first, LF last) and its echo and answer, ok.
for n in a b c; do
  N=${n^^}
  wait_for "^trace ims \([0-9]+\.[0-9]{6}\) ims_$n tx ok '$N[^']*\\\\n'\$" || fail "no tx line for ims_$n"
  wait_for "^trace ims \([0-9]+\.[0-9]{6}\) ims_$n rx ok '.+'\$" || fail "no rx line for ims_$n"
done
grep -q '^<' "$dir/daemon.log" && fail "journald <N> prefixes on a plain file"

port=$(sed -n 's|.*metrics: http://127.0.0.1:\([0-9]*\)/metrics.*|\1|p' "$dir/daemon.log")
[ -n "$port" ] || fail "metrics port not logged"
reply=$(/usr/bin/python3 - "$port" <<'PY'
import sys, urllib.request
r = urllib.request.urlopen(urllib.request.Request(
    f"http://127.0.0.1:{sys.argv[1]}/trace?bus=ims&on=0", method="POST"), timeout=5)
print(r.status, r.read().decode().strip())
PY
)
case "$reply" in "200 trace ims: off ("*) ;; *) fail "POST /trace answered '$reply'" ;; esac
wait_for '^trace ims: off$' || fail "no 'trace ims: off' log line"
sleep 0.5  # several poll cycles
sed -n '/^trace ims: off$/,$p' "$dir/daemon.log" | grep -q '^trace ims (' &&
  fail "trace lines after the trace was switched off"

kill -USR2 "$daemon"
wait_for '^SIGUSR2: wire trace now on for every bus$' || fail "SIGUSR2 not logged"
for _ in $(seq 100); do
  sed -n '/^trace ims: on$/,$p' "$dir/daemon.log" | grep -q "^trace ims (.*) ims_. tx ok '" && break
  sleep 0.1
done
sed -n '/^trace ims: on$/,$p' "$dir/daemon.log" | grep -q "^trace ims (.*) ims_. tx ok '" ||
  fail "no trace lines after SIGUSR2"
kill "$daemon"
wait "$daemon" || true

# stderr is "the journal" when JOURNAL_STREAM names its device and inode.
: >"$dir/daemon.log"
JOURNAL_STREAM=$(stat -c '%d:%i' "$dir/daemon.log") start_daemon
wait_for '^<6>trace ims \(' || fail "no <6> prefix on trace lines with JOURNAL_STREAM set"
grep -qE '^<[0-9]>modbus: listening' "$dir/daemon.log" || fail "no <N> prefix on log lines"
kill "$daemon"
wait "$daemon" || true
echo "wire trace: ok"
