#!/usr/bin/env bash
# mbpoll and Debian's pymodbus, clients this project did not write, against the real daemon
# and the Copley simulator. Usage: foreign_clients.sh FIELDGATE SIM_COPLEY MODELS_DIR
set -euo pipefail
fieldgate=$1 sim=$2 models=$3
source "$(dirname "$0")/lib.sh"
scratch_dir

copley_units "$sim" "{reply_timeout: 50ms, probe_interval: 300ms}" \
  "      - {name: a9, address: 9, model: copley-amplifier, unit_id: 3}"
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log"
mbpoll_args=(-m tcp -p "$port") mbpoll_target=127.0.0.1

mbpoll_basics mbpoll
check "mbpoll sees 0x0B for an absent node" "1" \
  "$(for _ in $(seq 50); do mb -a 3 -t 3 -r 0 | grep -c 'Target device failed to respond' && break; sleep 0.1; done | head -1)"
check "mbpoll sees 0x02 for an unmapped address" "1" "$(mb -a 1 -t 3 -r 600 | grep -c 'Illegal data address')"

/usr/bin/python3 - "$port" <<'PY' || fail=1
import sys
from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse
from pymodbus_steps import move_to_2500
c = ModbusTcpClient("127.0.0.1", port=int(sys.argv[1]))
assert c.connect(), "pymodbus cannot connect"
def ok(name, cond):
    print(("ok: " if cond else "FAIL: ") + name)
    if not cond: sys.exit(1)
move_to_2500(c, ok, "pymodbus")
r = c.write_register(122, 5, slave=2)           # enable_mode below its min
ok("pymodbus: out-of-range setpoint gives 0x03", isinstance(r, ExceptionResponse) and r.exception_code == 3)
r = c.write_register(110, 7, slave=2)           # half of the 32-bit target
ok("pymodbus: half a 32-bit value gives 0x03", isinstance(r, ExceptionResponse) and r.exception_code == 3)
c.close()
PY
# What the daemon saw, where a step failed (a refused write says why in it).
[ "${fail:-0}" = 0 ] || { echo "--- daemon log ---"; tail -n 60 "$dir/daemon.log"; }
exit $fail
