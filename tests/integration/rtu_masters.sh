#!/usr/bin/env bash
# Modbus RTU masters this project did not write (mbpoll, Debian's pymodbus) and raw frames
# against the real daemon's RTU port, through a relay that paces bytes at the line's baud
# rate. Ten units on two Copley simulators; the second answers 1.5 s late, so a write to it
# outlasts the master's response timeout.
# Usage: rtu_masters.sh FIELDGATE SIM_COPLEY MODELS_DIR BAUD
set -euo pipefail
fieldgate=$1 sim=$2 models=$3 baud=$4
here=$(cd "$(dirname "$0")" && pwd)
source "$here/lib.sh"
scratch_dir 'exec 7>&- 2>/dev/null'

start_sim "$dir/fast.log" "$sim" --link "$dir/copley0" --nodes 0,1,2,3,4,5,6,7,8
mkfifo "$dir/slow.ctl"
"$sim" --link "$dir/copley1" --nodes 0 <"$dir/slow.ctl" >"$dir/slow.log" 2>&1 &
exec 7>"$dir/slow.ctl"
echo "delay 1500" >&7
# 8N1 on the emulated line: 10 bits a character.
"$here/rtu_wire_relay.py" "$dir/gw-rtu" "$dir/master" "$baud" 10 >"$dir/relay.log" 2>&1 &
wait_for_paths "$dir/copley1" "$dir/master"

nodes=""
for n in 0 1 2 3 4 5 6 7 8; do
  nodes+="      - {name: a$n, address: $n, model: copley-amplifier, unit_id: $((n + 1))}"$'\n'
done
gateway_config "$dir/gw.yaml" "metrics: {listen: 127.0.0.1:0}
modbus_rtu:
  device: $dir/gw-rtu
  baud: $baud
  parity: none
  response_timeout: 500ms
  broadcast_stop: {actions: {copley-amplifier: abort}}" <<YAML
  - name: fast
    protocol: copley-ascii
    serial: {device: $dir/copley0, baud: 115200}
    timing: {reply_timeout: 100ms, probe_interval: 300ms}
    nodes:
$nodes  - name: slow
    protocol: copley-ascii
    serial: {device: $dir/copley1, baud: 115200}
    timing: {reply_timeout: 4s}
    nodes:
      - {name: s0, address: 0, model: copley-amplifier, unit_id: 10}
YAML
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log" "modbus rtu: serving on"
metrics=$(metrics_port "$dir/daemon.log")
[ -n "$metrics" ] || { echo "daemon did not start"; cat "$dir/daemon.log"; exit 1; }
mbpoll_args=(-m rtu -b "$baud" -P none -o 1) mbpoll_target=$dir/master

mbpoll_basics "mbpoll rtu"
check "mbpoll rtu sees 0x02 for an unmapped address" "1" "$(mb -a 1 -t 3 -r 600 | grep -c 'Illegal data address')"
check "mbpoll rtu gets no answer for a unit nobody serves" "1" "$(mb -a 33 -t 3 -r 0 | grep -c 'timed out')"

/usr/bin/python3 - "$dir/master" "$baud" "$metrics" <<'PY' || fail=1
import sys, time, urllib.request
import serial
from pymodbus.client import ModbusSerialClient
from pymodbus.pdu import ExceptionResponse
from pymodbus_steps import move_to_2500

device, baud, metrics_port = sys.argv[1], int(sys.argv[2]), sys.argv[3]
failed = False
def ok(name, cond):
    global failed
    print(("ok: " if cond else "FAIL: ") + name)
    failed = failed or not cond

c = ModbusSerialClient(port=device, baudrate=baud, parity="N", stopbits=1, bytesize=8, timeout=1)
assert c.connect(), "pymodbus cannot open " + device
move_to_2500(c, ok, "pymodbus rtu")
r = c.write_register(110, 7, slave=2)           # half of the 32-bit target
ok("pymodbus rtu: half a 32-bit value gives 0x03", isinstance(r, ExceptionResponse) and r.exception_code == 3)
c.close()

# A master polling ten units; unit 10's write is confirmed only after 1.5-3 s. The gateway
# answers by 450 ms (response_timeout 500ms less its guard). The master's response timeout is
# the configured one: every request gets its answer within it, and the longest gap between two
# answers the master sees is not longer than it.
RESPONSE_TIMEOUT = 0.5  # modbus_rtu.response_timeout in gw.yaml
c = ModbusSerialClient(port=device, baudrate=baud, parity="N", stopbits=1, bytesize=8,
                       timeout=1, retries=0)
c.params.timeout = RESPONSE_TIMEOUT  # this pymodbus (3.0.0rc1) truncates the argument to int
assert c.connect()
unanswered, answered, slow_write, max_gap, max_wait = 0, 0, None, 0.0, 0.0
slow_wait = None
last = time.monotonic()
for cycle in range(4):
    for unit in range(1, 11):
        sent = time.monotonic()
        if cycle == 1 and unit == 10:
            r = c.write_register(100, 1, slave=10)  # enable on the slow bus
            slow_write = r
        else:
            r = c.read_input_registers(1000, 1, slave=unit)  # online flag
        now = time.monotonic()
        if cycle == 1 and unit == 10:
            slow_wait = now - sent
        if r.isError() and not isinstance(r, ExceptionResponse):
            unanswered += 1
            print("info: unit %d (cycle %d) unanswered after %.0f ms: %s" %
                  (unit, cycle, (now - sent) * 1000, r))
        else:
            answered += 1
            max_gap, max_wait = max(max_gap, now - last), max(max_wait, now - sent)
        last = now
ok("pymodbus rtu: the slow write was acknowledged (0x05) or confirmed (%s, after %.0f ms)" %
   (slow_write, (slow_wait or 0) * 1000),
   isinstance(slow_write, ExceptionResponse) and slow_write.exception_code == 5 or
   (slow_write is not None and not slow_write.isError()))
ok("pymodbus rtu: 40 requests to 10 units, none unanswered within the configured %d ms (%d "
   "unanswered)" % (RESPONSE_TIMEOUT * 1000, unanswered), unanswered == 0 and answered == 40)
ok("pymodbus rtu: no gap between answers longer than the configured %d ms (longest %.0f ms, "
   "longest wait %.0f ms, at %d baud)" % (RESPONSE_TIMEOUT * 1000, max_gap * 1000,
                                          max_wait * 1000, baud), max_gap <= RESPONSE_TIMEOUT)
deadline = time.monotonic() + 30  # bounded by time: each read may itself wait its timeout
while time.monotonic() < deadline:
    r = c.read_holding_registers(100, 4, slave=10)
    if not r.isError() and r.registers[1] == 2: break
    time.sleep(0.05)
ok("pymodbus rtu: the acknowledged enable completed on unit 10 (%s)" % getattr(r, "registers", r),
   not r.isError() and r.registers[0] == 1 and r.registers[1] == 2)
c.close()

def crc(b):
    v = 0xFFFF
    for x in b:
        v ^= x
        for _ in range(8):
            v = (v >> 1) ^ 0xA001 if v & 1 else v >> 1
    return bytes(b) + bytes([v & 0xFF, v >> 8])

s = serial.Serial(device, baud, timeout=0.6)
def exchange(frame):
    s.reset_input_buffer()
    s.write(frame)
    return s.read(64)

def metrics_text():
    return urllib.request.urlopen("http://127.0.0.1:%s/metrics" % metrics_port).read().decode()

def counter(text, name):
    for line in text.splitlines():
        if line.startswith(name + "{") or line.startswith(name + " "):
            return float(line.rsplit(" ", 1)[1])
    return None

def dropped():  # (CRC errors, framing errors) counted so far
    text = metrics_text()
    return tuple(counter(text, "fieldgate_modbus_rtu_%s_errors_total" % k) for k in ("crc", "framing"))

good = crc([1, 3, 0, 0, 0, 2])
ok("raw: a good frame is answered", exchange(good)[:3] == bytes([1, 3, 4]))
bad = bytearray(good); bad[4] ^= 0x40
before = dropped()
ok("raw: bad CRC, no answer", exchange(bytes(bad)) == b"")
after = dropped()
# Counted as dropped: as a CRC error, or, where this host delivered the frame's bytes with a
# gap longer than t3.5 (the paced relay starved of CPU), as framing errors of its pieces.
ok("raw: the bad CRC is counted (CRC, framing errors: %s -> %s)" % (before, after),
   None not in before + after and sum(after) > sum(before))
before = after
ok("raw: truncated frame, no answer", exchange(good[:5]) == b"")
after = dropped()
ok("raw: the truncated frame is counted (CRC, framing errors: %s -> %s)" % (before, after),
   None not in before + after and sum(after) > sum(before))
before = after
other = crc([2, 3, 0, 0, 0, 2])
interleaved = bytes(x for pair in zip(good, other) for x in pair)
ok("raw: two masters' frames interleaved, no answer", exchange(interleaved) == b"")
after = dropped()
ok("raw: the interleaved frames are counted as dropped (%s -> %s)" % (before, after),
   None not in before + after and sum(after) > sum(before))
ok("raw: answered again after the garbage", exchange(good)[:3] == bytes([1, 3, 4]))
ok("raw: a broadcast read is dropped", exchange(crc([0, 3, 0, 0, 0, 1])) == b"")
ok("raw: the broadcast stop is not answered", exchange(crc([0, 6, 0, 100, 0xFF, 0xFF])) == b"")
s.close()

c = ModbusSerialClient(port=device, baudrate=baud, parity="N", stopbits=1, bytesize=8, timeout=1)
assert c.connect()
codes = {}
for _ in range(100):
    codes = {u: c.read_holding_registers(100, 1, slave=u) for u in (1, 2, 10)}
    if all(not r.isError() and r.registers[0] == 6 for r in codes.values()): break
    time.sleep(0.05)
ok("broadcast stop ran abort (6) on units 1, 2 and 10 (%s)" %
   {u: getattr(r, "registers", r) for u, r in codes.items()},
   all(not r.isError() and r.registers[0] == 6 for r in codes.values()))
c.close()

text = urllib.request.urlopen("http://127.0.0.1:%s/metrics" % metrics_port).read().decode()
def metric(name):
    for line in text.splitlines():
        if line.startswith(name + "{") or line.startswith(name + " "):
            return float(line.rsplit(" ", 1)[1])
    return None
ok("metrics: CRC errors counted (%s)" % metric("fieldgate_modbus_rtu_crc_errors_total"),
   metric("fieldgate_modbus_rtu_crc_errors_total") >= 2)
ok("metrics: framing errors counted (%s)" % metric("fieldgate_modbus_rtu_framing_errors_total"),
   metric("fieldgate_modbus_rtu_framing_errors_total") >= 1)
ok("metrics: one broadcast stop accepted", metric("fieldgate_modbus_rtu_broadcasts_accepted_total") == 1)
ok("metrics: one broadcast dropped", metric("fieldgate_modbus_rtu_broadcasts_dropped_total") == 1)
exceptions = [l for l in text.splitlines() if l.startswith("fieldgate_modbus_rtu_exceptions_total{")]
ok("metrics: exceptions by code 2, 3 and 5 (%s)" % exceptions,
   all(any('code="%d"' % code in l for l in exceptions) for code in (2, 3, 5)))
sys.exit(1 if failed else 0)
PY
[ $fail -eq 0 ] || { echo "--- daemon log"; grep -v "reply_timeout .* is below" "$dir/daemon.log" | tail -n 40; }
exit $fail
