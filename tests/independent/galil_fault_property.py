#!/usr/bin/python3
"""End-to-end fault property test of the Galil protocol file (config/protocols/galil-dmc.yaml and
the model galil-dmc) on the independent Galil unit (galil_unit.py) under a bad line, as
smc100_fault_property.py does for the SMC100.

  galil_fault_property.py --fieldgate PATH [--seed N] [--iterations 60] [--keep] [--verbose]

The unit (axes A and B, one node) runs with --chaos SEED (late, dropped, garbled and truncated
responses, each command's prompt on its own; lost command lines) and --journal (every command it
executed, every response it sent, every fault it injected). Axis A is powered on (SHA) with the
chaos off; axis B stays off, so the controller refuses every BG on B with `?` and TC1 says
`20 Begin not valid with motor off`. With the chaos on, move_absolute actions are written (the
axis's target setpoint, then the action code at holding 100) to A (three quarters) or B, while a
second connection reads input registers 0-7 (each axis's position, MG _BG flag and TS byte).
Targets end in the iteration number, so every one is unique; about half are negative.

Properties, checked against the journal afterwards:
 1. every value read as good (position, profiling flag, status byte of either axis) is one the
    unit sent in a clean response to that axis's query, before the read was answered;
 2. every move answered success was executed: the unit's journal has `PAx=target` executed and
    the `BGx` of the same line executed after the write began; no PA executed twice;
 3. no move on B (motor off) is answered success;
 4. not vacuous: faults injected, several moves confirmed, some answered 0x0B (outcome unknown),
    refusals on B answered 0x04, many good reads;
 5. no refusal the device did not give: a move answered 0x04 carries the code of a `?` the unit
    sent during the write, as its clean TC1 response gave it (or 0xFFF8: refused, code unknown,
    when the TC1 response was lost), and its BG was not executed.
Every write's outcome is success, 0x04, 0x0B or no answer at the client. Exit 0 only if all hold.
"""
import argparse
import ast
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, defaultdict

from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(ROOT, "tests", "integration"))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from axis import s32, words  # noqa: E402
from process_helpers import stop_processes  # noqa: E402

UNIT = 1
NO_ANSWER = -1
TARGET_FAILED, DEVICE_FAILURE = 0x0B, 0x04
ACTION, ACTION_STATUS, ACTION_ERROR = 100, 101, 102
BUSY = 1
# Setpoints (holding, int32) and actions of the model galil-dmc.
TARGET = {"A": 110, "B": 122}
VELOCITY = {"A": 114, "B": 126}
ACCELERATION = {"A": 116, "B": 128}
DECELERATION = {"A": 118, "B": 130}
POWER_ON = {"A": 1, "B": 9}
MOVE_ABSOLUTE = {"A": 4, "B": 12}
UNKNOWN_CODE = 0xFFF8
# Input registers 0-7: A position (int32), A profiling, A status, then the same for B.
INPUTS = 8


def log(*a):
    print(*a, flush=True)


class Client:
    """One Modbus TCP connection; a fresh one after a request without an answer, so that a late
    answer is not taken for the next request's."""

    def __init__(self, port, timeout):
        self.port, self.timeout = port, timeout
        self.c = None
        self.connect()

    def connect(self):
        if self.c is not None:
            self.c.close()
        self.c = ModbusTcpClient("127.0.0.1", port=self.port, timeout=self.timeout, retries=0)
        self.c.connect()

    def call(self, fn, *args, **kw):
        """(exception, response): 0 success, the Modbus exception code, or NO_ANSWER."""
        try:
            r = getattr(self.c, fn)(*args, **kw)
        except Exception:  # noqa: BLE001 -- pymodbus raises several kinds on a lost answer
            self.connect()
            return NO_ANSWER, None
        if isinstance(r, ExceptionResponse):
            return r.exception_code, r
        if r is None or r.isError() or not hasattr(r, "function_code"):
            self.connect()
            return NO_ANSWER, None
        return 0, r

    def inputs(self, unit, address, count):
        e, r = self.call("read_input_registers", address, count, slave=unit)
        return r.registers if e == 0 else None

    def holding(self, unit, address, count):
        e, r = self.call("read_holding_registers", address, count, slave=unit)
        return r.registers if e == 0 else None


def wait_until(what, seconds, step=0.05):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(step)
    return False



# ---------------------------------------------------------------------------------------------
# The journal

def first_line(data):
    """The data of a response ('` 1000\\r\\n:`'), or None for a bare prompt or a refusal."""
    if not data.endswith("\r\n:"):
        return None
    return data[:-3]


class Journal:
    def __init__(self, path):
        self.lines = []  # (time, kind, rest)
        # (axis, quantity) -> value -> first time sent in a clean response
        self.values = defaultdict(dict)
        self.tc_sent = []  # (time, code), clean TC1 responses
        self.refusals = []  # time of each '?' sent clean
        self.pa = defaultdict(list)  # (axis, target) -> [(time, outcome)]
        self.bg = defaultdict(list)  # axis -> [(time, outcome)]
        self.faults = Counter()
        with open(path, errors="replace") as f:
            for raw in f:
                parts = raw.rstrip("\n").split(" ", 2)
                if len(parts) < 3:
                    continue
                t, kind, rest = float(parts[0]), parts[1], parts[2]
                self.lines.append((t, kind, rest))
                if kind == "sent":
                    self.sent(t, rest)
                elif kind == "exec":
                    self.executed(t, rest)
                elif kind == "fault":
                    self.faults[rest.split(" ", 1)[0]] += 1

    def sent(self, t, rest):
        key, _, data = rest.partition(" ")
        if data.endswith(" late"):
            data = data[:-5]
        data = ast.literal_eval(data)
        if data == "?":
            self.refusals.append(t)
            return
        text = first_line(data)
        if text is None:
            return
        m = re.match(r"^(TP|TS|MG_BG)([A-H])$", key)
        if m:
            quantity = {"TP": "position", "TS": "status", "MG_BG": "profiling"}[m.group(1)]
            value = int(round(float(text)))
            self.values[(m.group(2), quantity)].setdefault(value, t)
        elif key == "TC1":
            self.tc_sent.append((t, int(text.split(" ", 1)[0])))

    def executed(self, t, rest):
        key, outcome = rest.split(" ", 2)[:2]
        m = re.match(r"^PA([A-H])=(-?\d+)$", key)
        if m:
            self.pa[(m.group(1), int(m.group(2)))].append((t, outcome))
        m = re.match(r"^BG([A-H])$", key)
        if m:
            self.bg[m.group(1)].append((t, outcome))

    def excerpt(self, t0, t1):
        return ["%.3f %s %s" % (t, k, r) for t, k, r in self.lines if t0 <= t <= t1 and
                not re.match(r"^(TP|TS|MG_BG)", r.split(" ", 2)[1] if k == "fault" else r)]


# ---------------------------------------------------------------------------------------------
# The run

class Run:
    def __init__(self, args):
        self.args = args
        self.dir = tempfile.mkdtemp(prefix="galil-fault-property-")
        self.procs = []
        self.failures = []

    def fail(self, text):
        self.failures.append(text)
        log("FAIL: " + text)

    def start(self):
        d = self.dir
        # Only the Galil protocol file and model: other files in config/ (work in progress)
        # must not keep this daemon from starting.
        for sub in ("protocols", "models"):
            os.makedirs(os.path.join(d, sub))
            os.symlink(os.path.join(ROOT, "config", sub, "galil-dmc.yaml"),
                       os.path.join(d, sub, "galil-dmc.yaml"))
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
        self.unit = subprocess.Popen(
            ["/usr/bin/python3", os.path.join(HERE, "galil_unit.py"), "--link", d + "/port",
             "--axes", "AB", "--chaos", str(self.args.seed), "--chaos-paused",
             "--journal", d + "/journal", "--log", "none"],
            stdin=subprocess.DEVNULL, stdout=open(d + "/unit.log", "w"),
            stderr=subprocess.STDOUT, env=env)
        self.procs.append(self.unit)
        if not wait_until(lambda: os.path.exists(d + "/port"), 5):
            raise SystemExit("the unit did not start:\n" + open(d + "/unit.log").read())
        with open(d + "/gw.yaml", "w") as f:
            f.write(f"""modbus: {{listen: 127.0.0.1:0}}
models: {d}/models
protocols: {d}/protocols
buses:
  - name: galil
    protocol: galil-dmc
    serial: {{device: {d}/port, baud: 115200}}
    # A line this bad would take the node offline every few polls with offline_after: 3; the
    # property is about the exchanges (as tests/harness/fault_property.cpp's fault_bus).
    timing: {{reply_timeout: 200ms, byte_timeout: 20ms, retries: 1, offline_after: 10,
             probe_interval: 300ms}}
    nodes:
      - {{name: dmc, address: 0, model: galil-dmc, unit_id: {UNIT}}}
""")
        cmd = [self.args.fieldgate] + (["-v"] if self.args.verbose else []) + \
            ["--config", d + "/gw.yaml"]
        self.daemon = subprocess.Popen(cmd, stdin=subprocess.DEVNULL,
                                       stdout=open(d + "/daemon.log", "w"),
                                       stderr=subprocess.STDOUT)
        self.procs.append(self.daemon)
        port = []

        def listening():
            m = re.search(r"modbus: listening on 127\.0\.0\.1:(\d+)",
                          open(d + "/daemon.log").read())
            if m:
                port.append(int(m.group(1)))
            return bool(m) or self.daemon.poll() is not None
        wait_until(listening, 10)
        if not port:
            raise SystemExit("the daemon did not start:\n" + open(d + "/daemon.log").read())
        self.port = port[0]

    def stop(self):
        stop_processes(*reversed(self.procs))

    def action_idle(self, client):
        a = client.holding(UNIT, ACTION_STATUS, 1)
        return a is not None and a[0] != BUSY

    def prepare(self, client):
        if not wait_until(lambda: (client.inputs(UNIT, 1000, 1) or [0])[0] == 1, 15):
            raise SystemExit("node not online")
        for axis in "AB":
            # Fast moves: 400000 counts/s, 4096000 counts/s^2 (gateway-local setpoints).
            for table, value in ((VELOCITY, 400000), (ACCELERATION, 4096000),
                                 (DECELERATION, 4096000)):
                e, _ = client.call("write_registers", table[axis], words(value), slave=UNIT)
                if e != 0:
                    raise SystemExit("setpoint write: exception %d" % e)
        e, _ = client.call("write_register", ACTION, POWER_ON["A"], slave=UNIT)
        if e != 0:
            raise SystemExit("power on A: exception %d" % e)
        if not wait_until(lambda: self.action_idle(client), 10):
            raise SystemExit("power on A never ended")
        log("axis A powered on, axis B left off")

    def reader(self, stop, reads, misses):
        client = Client(self.port, 3)
        while not stop.is_set():
            e, r = client.call("read_input_registers", 0, INPUTS, slave=UNIT)
            t = time.monotonic()
            if e == 0:
                reads.append((t, list(r.registers)))
            else:
                misses[e] += 1
            time.sleep(0.005)

    def writes(self, client):
        rng = random.Random(self.args.seed)
        writes = []
        started = time.monotonic()
        for i in range(1, self.args.iterations + 1):
            if time.monotonic() - started > self.args.budget:
                log("time budget reached after %d writes" % (i - 1))
                break
            axis = "B" if rng.random() < 0.25 else "A"
            target = rng.choice((1, -1)) * (rng.randint(1, 30) * 1000 + i)
            # The node's action slot idle, so that the write is not refused as busy; after 4 s,
            # write anyway.
            wait_until(lambda: self.action_idle(client), 4)
            e, _ = client.call("write_registers", TARGET[axis], words(target), slave=UNIT)
            if e != 0:
                log("iteration %d: target write answered %d, skipped" % (i, e))
                continue
            t0 = time.monotonic()
            e, _ = client.call("write_register", ACTION, MOVE_ABSOLUTE[axis], slave=UNIT)
            t1 = time.monotonic()
            action_error = None
            if e == DEVICE_FAILURE:
                r = client.holding(UNIT, ACTION_ERROR, 1)
                action_error = r[0] if r else None
            writes.append(dict(i=i, axis=axis, target=target, exception=e, t0=t0, t1=t1,
                               action_error=action_error))
            if self.args.verbose:
                log("write %2d axis %s target %7d: %s (%.0f ms)%s" % (
                    i, axis, target,
                    {0: "success", NO_ANSWER: "no answer"}.get(e, "exception 0x%02X" % e),
                    (t1 - t0) * 1000,
                    "" if action_error is None else " action error 0x%04X" % action_error))
            time.sleep(rng.random() * 0.04)
        return writes

    def main(self):
        try:
            self.start()
            client = Client(self.port, 10)
            self.prepare(client)
            stop, reads, misses = threading.Event(), [], Counter()
            reader = threading.Thread(target=self.reader, args=(stop, reads, misses))
            self.unit.send_signal(signal.SIGUSR1)  # chaos on
            time.sleep(0.05)
            reader.start()
            writes = self.writes(client)
            self.unit.send_signal(signal.SIGUSR2)  # chaos off
            stop.set()
            reader.join()
            time.sleep(0.3)
        finally:
            self.stop()
        return self.check(Journal(self.dir + "/journal"), writes, reads, misses)

    # -----------------------------------------------------------------------------------------
    def check(self, j, writes, reads, misses):
        excerpts = 0

        def show(w, why):
            nonlocal excerpts
            self.fail(why)
            if excerpts < 5:
                excerpts += 1
                log("  journal around it:")
                for line in j.excerpt(w["t0"] - 0.5, w["t1"] + 0.5):
                    log("    " + line)

        outcomes = Counter(w["exception"] for w in writes)
        for w in writes:
            if w["exception"] not in (0, TARGET_FAILED, DEVICE_FAILURE, NO_ANSWER):
                show(w, "write %d (axis %s target %d) answered exception 0x%02X" %
                     (w["i"], w["axis"], w["target"], w["exception"]))

        # 2. A move answered success ran: its PA and then its BG executed during the write.
        confirmed = [w for w in writes if w["exception"] == 0]
        for w in confirmed:
            pa = [t for t, o in j.pa.get((w["axis"], w["target"]), [])
                  if o == "ok" and t >= w["t0"] - 0.01]
            bg = [t for t, o in j.bg[w["axis"]] if o == "ok" and pa and pa[0] <= t <= w["t1"]]
            if not pa or not bg:
                show(w, "move %d: axis %s target %d answered success, but the controller %s" %
                     (w["i"], w["axis"], w["target"], "never took the target" if not pa else
                      "never began the move"))
        for (axis, target), runs in sorted(j.pa.items()):
            if len(runs) > 1:
                self.fail("PA%s=%d executed %d times: %s" % (axis, target, len(runs), runs))

        # 3. B's motor is off: no move on B answered success.
        on_b = [w for w in writes if w["axis"] == "B"]
        for w in on_b:
            if w["exception"] == 0:
                show(w, "move %d on axis B (motor off) answered success" % w["i"])
        for t, outcome in j.bg["B"]:
            if outcome == "ok":
                self.fail("the unit began a move on B with its motor off (the test is wrong)")

        # 5. No refusal the device did not give.
        false_refusals = []
        for w in writes:
            if w["exception"] != DEVICE_FAILURE:
                continue
            code = w["action_error"]
            began = [t for t, o in j.bg[w["axis"]] if o == "ok" and w["t0"] - 0.01 <= t <= w["t1"]]
            refused = [t for t in j.refusals if w["t0"] - 0.01 <= t <= w["t1"] + 0.01]
            told = [c for t, c in j.tc_sent if w["t0"] - 0.01 <= t <= w["t1"] + 0.01]
            given = bool(refused) and (code in told or code == UNKNOWN_CODE)
            if began or not given:
                false_refusals.append(w)
                show(w, "move %d: axis %s target %d answered 0x04 (action error 0x%04X) but the "
                     "controller %s" % (w["i"], w["axis"], w["target"],
                                        code if code is not None else 0xFFFF,
                                        "began it" if began else "gave no such refusal"))

        # 1. Every value served as good was sent in a clean response, before the read answered.
        wrong = Counter()
        first_wrong = {}
        for t, r in reads:
            for base, axis in ((0, "A"), (4, "B")):
                values = (("position", s32(r[base], r[base + 1])), ("profiling", r[base + 2]),
                          ("status", r[base + 3]))
                for name, value in values:
                    sent_at = j.values[(axis, name)].get(value)
                    if sent_at is None or sent_at > t:
                        wrong[(axis, name)] += 1
                        first_wrong.setdefault((axis, name), (t, value, sent_at))
        for (axis, name), n in wrong.items():
            t, value, sent_at = first_wrong[(axis, name)]
            self.fail("%d reads served a %s of axis %s never sent; first: %d at %.3f (%s)" % (
                n, name, axis, value, t, "never sent" if sent_at is None else
                "first sent at %.3f" % sent_at))
            if excerpts < 5:
                excerpts += 1
                for line in j.excerpt(t - 1.0, t + 0.1):
                    log("    " + line)

        # 4. Not vacuous.
        unknown = outcomes[TARGET_FAILED]
        refused_answered = sum(1 for w in on_b if w["exception"] == DEVICE_FAILURE)
        with_code = sum(1 for w in on_b if w["action_error"] == 20)
        faults = sum(j.faults.values())
        summary = {
            "seed": self.args.seed,
            "writes": len(writes),
            "confirmed": len(confirmed),
            "unknown_0x0B": unknown,
            "device_failure_0x04": outcomes[DEVICE_FAILURE],
            "  refusals never given (5)": len(false_refusals),
            "no_answer": outcomes[NO_ANSWER],
            "moves_on_b (motor off)": len(on_b),
            "  answered 0x04": refused_answered,
            "  with the device's code 20": with_code,
            "faults_injected": faults,
            "  by kind": dict(sorted(j.faults.items())),
            "moves_begun": sum(1 for a in "AB" for _, o in j.bg[a] if o == "ok"),
            "reads_checked": len(reads),
            "reads_not_good": dict(misses),
        }
        for k, v in summary.items():
            log("%-32s %s" % (k, v))
        if faults < 10:
            self.fail("vacuous: only %d faults injected" % faults)
        if len(confirmed) < 5:
            self.fail("vacuous: only %d moves confirmed" % len(confirmed))
        if unknown < 1:
            self.fail("vacuous: no write answered 0x0B")
        if with_code < 1:
            self.fail("vacuous: no move on B answered 0x04 with the device's code 20")
        if len(reads) < 100:
            self.fail("vacuous: only %d good reads" % len(reads))
        if self.failures:
            log("--- daemon log (last 60 lines) ---")
            for line in open(self.dir + "/daemon.log").read().splitlines()[-60:]:
                log("    " + line)
            log("FAILED (%d); scratch directory kept: %s" % (len(self.failures), self.dir))
            return 1
        log("PASS: no value served that the device never sent, no move confirmed that it did "
            "not begin, no refusal it did not give, its own code (TC1) on the refusals")
        if self.args.keep:
            log("scratch directory: " + self.dir)
        else:
            shutil.rmtree(self.dir, ignore_errors=True)
        return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fieldgate", required=True, help="the daemon binary")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--iterations", type=int, default=60)
    ap.add_argument("--budget", type=float, default=55.0,
                    help="seconds of writes under chaos at most")
    ap.add_argument("--keep", action="store_true", help="keep the scratch directory")
    ap.add_argument("--verbose", action="store_true", help="each write; the daemon with -v")
    sys.exit(Run(ap.parse_args()).main())


if __name__ == "__main__":
    main()
