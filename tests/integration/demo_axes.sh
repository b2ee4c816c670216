#!/usr/bin/env bash
# scripts/demo-axes against the real daemon on a small plant of two buses: a Copley chain (node 0
# simulated, node 7 configured but absent) and an IMS party line (axis A). The units come
# from `fieldgate map --profile` of the config; every present axis passes tools/axis.py's cycle,
# the absent one passes only as expected offline, and without that expectation the run fails.
# Usage: demo_axes.sh FIELDGATE BUILD_DIR MODELS_DIR DEMO_AXES
set -euo pipefail
fieldgate=$1 build=$2 models=$3 demo_axes=$4
here=$(cd "$(dirname "$0")" && pwd)
source "$here/lib.sh"
scratch_dir

start_copley "$build/sim/copley/fieldgate-sim-copley" "$dir/copley" 0 "$dir/copley.log"
start_sim "$dir/ims.log" "$build/sim/ims/fieldgate-sim-ims" --link "$dir/ims" --axes A
gateway_config "$dir/gw.yaml" <<YAML
$copley_bus
    timing: {reply_timeout: 150ms, probe_interval: 300ms}
    nodes:
      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1, profile_unit: 21,
         limits: {target: {min: -100000000, max: 100000000}}}
      - {name: amp7, address: 7, model: copley-amplifier, unit_id: 3, profile_unit: 23}
  - name: ims
    protocol: ims-party-line
    serial: {device: $dir/ims, baud: 9600}
    timing: {reply_timeout: 100ms, byte_timeout: 30ms, probe_interval: 300ms}
    nodes:
      - {name: ims_a, address: A, model: ims-indexer, unit_id: 11, profile_unit: 31}
YAML
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log"

failures=0
fail() {
  echo "FAIL $*"
  failures=$((failures + 1))
}
rc=0
/usr/bin/python3 "$demo_axes" --port "$port" --config "$dir/gw.yaml" --fieldgate "$fieldgate" \
  --expect-offline 23 --wait-online 20 >"$dir/run.log" 2>&1 || rc=$?
cat "$dir/run.log"
[ "$rc" -eq 0 ] || fail "demo-axes exit status $rc, want 0"
for line in '^21 pass [0-9]+ checks$' '^31 pass [0-9]+ checks$' \
  '^23 offline offline \(exception 0x0B\)$' '^3 of 3 axes passed$'; do
  grep -E -q "$line" "$dir/run.log" || fail "no line matching '$line'"
done

# Unexpected offline is a failure; so is an axis whose cycle fails (a unit that is no profile
# unit: its page cannot be read).
rc=0
/usr/bin/python3 "$demo_axes" --port "$port" --unit 23 --wait-online 2 >"$dir/offline.log" 2>&1 ||
  rc=$?
cat "$dir/offline.log"
[ "$rc" -eq 1 ] || fail "an unexpected offline unit: exit status $rc, want 1"
grep -E -q '^23 FAIL offline \(exception 0x0B\)$' "$dir/offline.log" || fail "no FAIL line for unit 23"

if [ "$failures" -ne 0 ]; then
  echo "--- daemon log ---"
  cat "$dir/daemon.log"
  exit 1
fi
echo "all demo-axes checks passed"
