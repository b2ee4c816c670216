#!/usr/bin/env bash
# The register map document (fieldgate map --format csv) checked against the live server:
# every documented register is read, and written where documented writable, as documented.
# Usage: map_document_check.sh FIELDGATE SIM_COPLEY MODELS_DIR
set -euo pipefail
fieldgate=$1 sim=$2 models=$3
source "$(dirname "$0")/lib.sh"
scratch_dir

copley_units "$sim"
"$fieldgate" map "$dir/gw.yaml" --format csv >"$dir/map.csv"
"$fieldgate" map "$dir/gw.yaml" --format md >"$dir/map.md"
grep -q '^| holding registers | 100 | 40101 | action.command |' "$dir/map.md" || { echo "FAIL: markdown lacks the action register"; exit 1; }
# The configuration named as an option, of the subcommand or of fieldgate, is the same file.
"$fieldgate" map --config "$dir/gw.yaml" --format csv | cmp -s - "$dir/map.csv" || { echo "FAIL: map --config X differs from map X"; exit 1; }
"$fieldgate" --config "$dir/gw.yaml" map --format csv | cmp -s - "$dir/map.csv" || { echo "FAIL: --config X map differs from map X"; exit 1; }
"$fieldgate" --config "$dir/gw.yaml" check | grep -q "^$dir/gw.yaml: ok" || { echo "FAIL: --config X check did not check X"; exit 1; }
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log"

/usr/bin/python3 - "$port" "$dir/map.csv" <<'PY'
import csv, sys, time
from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse

port, path = int(sys.argv[1]), sys.argv[2]
rows = list(csv.DictReader(open(path)))
c = ModbusTcpClient("127.0.0.1", port=port)
assert c.connect()
width = lambda t: 2 if t in ("int32", "uint32") else 1

def read(table, unit, address, count):
    if table == "discrete inputs": return c.read_discrete_inputs(address, count, slave=unit)
    if table == "coils": return c.read_coils(address, count, slave=unit)
    if table == "input registers": return c.read_input_registers(address, count, slave=unit)
    return c.read_holding_registers(address, count, slave=unit)

def code(r): return r.exception_code if isinstance(r, ExceptionResponse) else (0 if not r.isError() else -1)

# Every point has been polled once (slow class: 1 s).
for _ in range(100):
    if all(code(read("input registers", u, 0, 20)) == 0 and
           code(read("holding registers", u, 0, 35)) == 0 for u in (1, 2)): break
    time.sleep(0.05)

failures, checked = [], 0
def expect(cond, what):
    global checked
    checked += 1
    if not cond: failures.append(what)

last = {}
for row in rows:
    unit, address, table, n = int(row["unit"]), int(row["address"]), row["table"], width(row["type"])
    key = (unit, table)
    last[key] = max(last.get(key, -1), address + n - 1)
    what = "unit %d %s %d %s" % (unit, table, address, row["name"])
    r = read(table, unit, address, n)
    if "R" in row["access"]:
        expect(code(r) == 0, what + ": documented readable, got %s" % code(r))
    if table != "holding registers":
        continue
    if row["access"] == "R":
        w = c.write_register(address, 0, slave=unit)
        expect(code(w) == 2, what + ": documented read-only, write gave %s" % code(w))
    elif row["name"] == "action.command":
        w = c.write_register(address, 0xfffe, slave=unit)      # no such action code
        expect(code(w) == 3, what + ": writable command register refuses an unknown code with 0x03, got %s" % code(w))
    else:
        values = r.registers if code(r) == 0 else [0] * n
        w = c.write_registers(address, values, slave=unit)     # write back what was read
        expect(code(w) == 0, what + ": documented writable, write-back gave %s" % code(w))

for (unit, table), end in last.items():
    r = read(table, unit, end + 1, 1)
    expect(code(r) == 2, "unit %d %s %d past the documented end: expected 0x02, got %s" % (unit, table, end + 1, code(r)))
expect(code(read("coils", 1, 0, 1)) == 2, "coils are undocumented and unmapped")

print("checked %d documented behaviours of %d rows" % (checked, len(rows)))
for f in failures: print("FAIL:", f)
sys.exit(1 if failures else 0)
PY
