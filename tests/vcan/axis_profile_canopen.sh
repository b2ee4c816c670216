#!/bin/bash
# The axis profile of a CiA 402 drive on CANopen: tools/axis.py's full cycle (power, a home that
# searches the switch, moves, stop and halt of a running move, power off, a move refused while
# Disabled, a target beyond the node's limit and the reset of the still enabled drive), then axis_cia402_checks.py: a stop during a home, and a device fault (EMCY,
# statusword Fault) injected by the simulator: ErrorStop with the drive's error code, reset,
# power on. Then mbpoll -m rtu moves the axis through the RTU port (tests/integration/rtu_axis.sh).
# The daemon and fieldgate-sim-canopen on a kernel vcan0; runs inside scripts/vcan-run.
#   axis_profile_canopen.sh FIELDGATE SIM_CANOPEN MODELS_DIR AXIS_PY
set -u
fieldgate=$1 sim=$2 models=$3 axis_py=$4
here=$(cd "$(dirname "$0")" && pwd)
ifname=${FIELDGATE_VCAN_IF:-vcan0}
echo "interface $ifname on $(uname -r) (${FIELDGATE_VCAN_BACKEND:-?})"

dir=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null; wait 2>/dev/null; rm -rf "$dir"' EXIT
# The simulator's control line (fault injection) stays open for the whole run.
mkfifo "$dir/control"
"$sim" --interface "$ifname" --nodes 2 <"$dir/control" >"$dir/sim.log" 2>&1 &
exec 3>"$dir/control"
for _ in $(seq 100); do grep -q '^ready' "$dir/sim.log" && break; sleep 0.1; done
grep -q '^ready' "$dir/sim.log" || { echo "simulator did not start"; cat "$dir/sim.log"; exit 1; }

cat >"$dir/gw.yaml" <<YAML
modbus: {listen: 127.0.0.1:0}
models: $models
buses:
  - name: canopen
    protocol: canopen
    can: {interface: $ifname}
    timing: {reply_timeout: 500ms, retries: 1, offline_after: 3, probe_interval: 300ms,
             heartbeat_timeout: 500ms, start_nodes: true}
    nodes:
      - {name: drive_2, address: 2, model: canopen-cia402, unit_id: 1, profile_unit: 21,
         limits: {target: {min: -10000000, max: 10000000}}}
YAML
source "$here/../integration/daemon.sh"
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log"

# The home of the cycle searches the home switch (method 17), so that it takes time and can be
# stopped: home_method on the node's own unit, its address from the register map.
address=$("$fieldgate" map --format csv "$dir/gw.yaml" |
  awk -F, '$1 == 1 && $5 == "holding registers" && $8 == "home_method" {print $6}')
[ -n "$address" ] || { echo "no home_method in the map of unit 1"; exit 1; }
/usr/bin/python3 - "$port" "$address" <<'PY' || exit 1
import sys
from pymodbus.client import ModbusTcpClient
c = ModbusTcpClient("127.0.0.1", port=int(sys.argv[1]), timeout=5)
c.connect()
r = c.write_register(int(sys.argv[2]), 17, slave=1)
print("home_method := 17 at holding %s: %s" % (sys.argv[2], r))
sys.exit(1 if r.isError() else 0)
PY

# Timing under QEMU's TCG is several times the host's: generous, bounded waits per command.
rc=0
/usr/bin/python3 "$axis_py" --port "$port" --unit 21 --distance 4000 --timeout 60 \
  --refused-target 20000000 --no-device-error -v || rc=$?
if [ "$rc" -eq 0 ]; then
  /usr/bin/python3 "$here/axis_cia402_checks.py" "$axis_py" "$port" 21 0x2310 --timeout 60 -- \
    bash -c 'echo "fault 2 0x2310" >"$0"' "$dir/control" || rc=$?
fi
if [ "$rc" -ne 0 ]; then
  echo "--- daemon log ---"
  cat "$dir/daemon.log"
  echo "--- simulator log ---"
  cat "$dir/sim.log"
  exit "$rc"
fi

# Issue #18 in the same guest: mbpoll -m rtu moves the CANopen axis through the daemon's RTU port
# (tests/integration/rtu_axis.sh, a PTY pair paced at 19200 baud), with a fresh daemon and
# simulator. Its response timeout is longer than on the host: SDO answers under TCG are slow.
kill $(jobs -p) 2>/dev/null
wait 2>/dev/null
exec 3>&-
echo "--- mbpoll -m rtu on the CANopen axis ---"
build=$(cd "$(dirname "$sim")/../.." && pwd)
FIELDGATE_RTU_TIMEOUT=5 "$here/../integration/rtu_axis.sh" canopen "$fieldgate" "$build" "$models"
