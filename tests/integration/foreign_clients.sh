#!/usr/bin/env bash
# mbpoll and Debian's pymodbus, clients this project did not write, against the real daemon
# and the Copley simulator. Usage: foreign_clients.sh FIELDGATE SIM_COPLEY MODELS_DIR
set -euo pipefail
fieldgate=$1 sim=$2 models=$3
dir=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null; wait 2>/dev/null; rm -rf "$dir"' EXIT

"$sim" --link "$dir/copley0" --nodes 0,3 </dev/null >"$dir/sim.log" 2>&1 &
for _ in $(seq 50); do [ -e "$dir/copley0" ] && break; sleep 0.1; done
cat >"$dir/gw.yaml" <<YAML
modbus: {listen: 127.0.0.1:0}
models: $models
buses:
  - name: copley
    protocol: copley-ascii
    serial: {device: $dir/copley0, baud: 115200}
    timing: {reply_timeout: 50ms, probe_interval: 300ms}
    nodes:
      - {name: a0, address: 0, model: copley-amplifier, unit_id: 1}
      - {name: a3, address: 3, model: copley-amplifier, unit_id: 2}
      - {name: a9, address: 9, model: copley-amplifier, unit_id: 3}
YAML
source "$(dirname "$0")/daemon.sh"
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log"

fail=0
check() {  # check NAME EXPECTED ACTUAL
  if [ "$2" == "$3" ]; then echo "ok: $1"; else echo "FAIL: $1: expected '$2', got '$3'"; fail=1; fi
}
# mb OPTIONS... [-- WRITE_VALUES...]
mb() {
  local opts=() values=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do opts+=("$1"); shift; done
  [ $# -gt 0 ] && { shift; values=("$@"); }
  mbpoll -m tcp -p "$port" -0 -1 -q "${opts[@]}" -- 127.0.0.1 "${values[@]}" 2>&1
}

# Wait until unit 2 is polled.
for _ in $(seq 100); do mb -a 2 -t 3:int -B -r 0 | grep -q '^\[0\]' && break; sleep 0.1; done

check "mbpoll reads unit 1 position" "0" "$(mb -a 1 -t 3:int -B -r 0 | sed -n 's/^\[0\]:[[:space:]]*//p')"
check "mbpoll reads online flag" "1" "$(mb -a 2 -t 1 -r 1000 | sed -n 's/^\[1000\]:[[:space:]]*//p')"
mb -a 2 -t 4:int -B -r 110 -- -1500 >/dev/null
check "mbpoll writes a 32-bit setpoint" "-1500" "$(mb -a 2 -t 4:int -B -r 110 | sed -n 's/^\[110\]:[[:space:]]*//p')"
check "mbpoll sees 0x0B for an absent node" "1" \
  "$(for _ in $(seq 50); do mb -a 3 -t 3 -r 0 | grep -c 'Target device failed to respond' && break; sleep 0.1; done | head -1)"
check "mbpoll sees 0x02 for an unmapped address" "1" "$(mb -a 1 -t 3 -r 600 | grep -c 'Illegal data address')"

/usr/bin/python3 - "$port" <<'PY' || fail=1
import sys, time
from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse
c = ModbusTcpClient("127.0.0.1", port=int(sys.argv[1]))
assert c.connect(), "pymodbus cannot connect"
def ok(name, cond):
    print(("ok: " if cond else "FAIL: ") + name)
    if not cond: sys.exit(1)
r = c.write_register(100, 1, slave=2)           # enable
ok("pymodbus: enable confirmed", not r.isError())
r = c.write_registers(110, [0, 2500], slave=2)  # target 2500
ok("pymodbus: target written", not r.isError())
r = c.write_register(100, 3, slave=2)           # move_absolute
ok("pymodbus: move confirmed", not r.isError())
for _ in range(200):
    if c.read_holding_registers(101, 1, slave=2).registers[0] == 2: break
    time.sleep(0.05)
pos = c.read_input_registers(0, 2, slave=2).registers
ok("pymodbus: position reached 2500 (%s)" % pos, pos == [0, 2500])
r = c.write_register(122, 5, slave=2)           # enable_mode below its min
ok("pymodbus: out-of-range setpoint gives 0x03", isinstance(r, ExceptionResponse) and r.exception_code == 3)
r = c.write_register(110, 7, slave=2)           # half of the 32-bit target
ok("pymodbus: half a 32-bit value gives 0x03", isinstance(r, ExceptionResponse) and r.exception_code == 3)
c.close()
PY
exit $fail
