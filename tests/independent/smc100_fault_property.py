#!/usr/bin/python3
"""End-to-end fault property test of the protocol-file family (config/protocols/newport-smc100.yaml
and its model) on the independent SMC100 unit (smc100_unit.py) under a bad line, in the spirit of
tests/harness/fault_property.hpp.

  smc100_fault_property.py --fieldgate PATH [--seed N] [--iterations 60] [--keep] [--verbose]

The unit runs with --chaos SEED (late, dropped, garbled and truncated replies; lost command lines)
and --journal (every command it executed, every reply it sent, every fault it injected). The
daemon serves its two controllers (addresses 1 and 2) as units 1 and 2. Both are homed with the
chaos off; then, with the chaos on, move_absolute actions are written (setpoint target, holding
110-111, then action code 2 at holding 100) while a second connection reads the input registers
0-6 (position, positioner errors, state, status, setpoint). Targets end in the unit ID, their
tens are the iteration: every one is unique. About a quarter lie beyond the unit's software
limits (+-25 mm, 250000 counts): the gateway's limit is widened to +-400000 here, so the gateway
sends them and the device refuses them (TE C).

Properties, checked against the journal afterwards:
 1. every value read as good (position, setpoint, errors, state, status) is one the unit sent in
    a clean reply (on time or late) of that controller, before the read was answered;
 2. every move answered success was executed by that controller (an `exec ... ok` line for its
    PA with that target, after the write began), and its read-back (PA?) reached the gateway
    in a clean reply; no move command was executed twice (commands are never retried);
 3. no move to a target the device refuses is answered success;
 4. not vacuous: faults were injected, several moves were confirmed, some answered 0x0B
    (outcome unknown), refusals were answered, and many reads were good;
 5. (a failure unless --lenient-refusals, which only reports it) no refusal the device did not give: a move
    answered 0x04 has an action error the controller sent in a clean TE reply during the write
    (or 0xFFFA, not taken, for a PA it did not execute), and its PA was not executed. A garbled
    TE reply is no refusal: its outcome is unknown (0x0B, docs/protocol-files.md).
Every write's outcome is success, 0x04, 0x0B or no answer at the client. Exit 0 only if all hold.
"""
import argparse
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
from decimal import ROUND_HALF_UP, Decimal

from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(ROOT, "tests", "integration"))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from axis import s32, words as axis_words  # noqa: E402
from process_helpers import stop_processes  # noqa: E402

UNITS = (1, 2)  # unit ID = controller address
READY = {0x32, 0x33, 0x34, 0x35}
NO_ANSWER = -1
TARGET_FAILED, DEVICE_FAILURE = 0x0B, 0x04
# Holding registers (fieldgate map of the native unit): action block, setpoints.
ACTION, ACTION_STATUS, ACTION_ERROR = 100, 101, 102
TARGET, VELOCITY, ACCELERATION = 110, 114, 116
HOME, MOVE_ABSOLUTE = 1, 2
# Input registers 0-6: position (int32), positioner_errors, state, status, setpoint (int32).
INPUTS = 7


def log(*a):
    print(*a, flush=True)


def counts(text):
    """A decimal(4) capture: the number times 10^4, half away from zero (protocol-files.md)."""
    return int(Decimal(text).scaleb(4).quantize(Decimal(1), rounding=ROUND_HALF_UP))


i32, words = s32, axis_words


def status_word(errors, state):
    """The read_state flags of the protocol file, as the model's status point."""
    bits = 0
    if state in (0x1E, 0x1F, 0x28, 0x46, 0x47):
        bits |= 1 << 0
    if state in (0x1E, 0x1F):
        bits |= 1 << 1
    if state not in (0x0A, 0x0B, 0x0C, 0x0D, 0x0E, 0x0F, 0x10, 0x11, 0x14):
        bits |= 1 << 2
    if state in (0x3C, 0x3D, 0x3E, 0x14):
        bits |= 1 << 3
    if errors & 1:
        bits |= 1 << 4
    if errors & 2:
        bits |= 1 << 5
    if errors not in (0, 1, 2, 3):
        bits |= 1 << 6
    return bits


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

class Journal:
    def __init__(self, path):
        self.lines = []  # (time, kind, rest)
        # unit -> value -> first time sent (clean, on time or late)
        self.tp, self.pa = defaultdict(dict), defaultdict(dict)
        self.ts_errors, self.ts_state, self.ts_status = (defaultdict(dict), defaultdict(dict),
                                                        defaultdict(dict))
        self.pa_sent = defaultdict(list)  # unit -> [(time, counts)], clean PA? replies
        self.te_sent = defaultdict(list)  # unit -> [(time, letter)], clean TE replies
        self.moves = defaultdict(list)  # (unit, counts) -> [(time, outcome, body)], PA commands
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

    @staticmethod
    def first(table, value, t):
        if value not in table:
            table[value] = t

    def sent(self, t, rest):
        reply = rest.split(" ", 1)[0]
        if " late=" in rest:
            self.faults["late"] += 1
        m = re.match(r"(\d+)(TP|PA|TS|TE)(.*)$", reply)
        if not m:
            return
        unit, code, value = int(m.group(1)), m.group(2), m.group(3)
        if code == "TE":
            self.te_sent[unit].append((t, value))
        elif code == "TP":
            self.first(self.tp[unit], counts(value), t)
        elif code == "PA":
            self.first(self.pa[unit], counts(value), t)
            self.pa_sent[unit].append((t, counts(value)))
        else:
            errors, state = int(value[:4], 16), int(value[4:6], 16)
            self.first(self.ts_errors[unit], errors, t)
            self.first(self.ts_state[unit], state, t)
            self.first(self.ts_status[unit], status_word(errors, state), t)

    def executed(self, t, rest):
        body, outcome = rest.split(" ", 2)[:2]
        m = re.match(r"(\d+)PA(-?[0-9.]+)$", body)
        if m:
            self.moves[(int(m.group(1)), counts(m.group(2)))].append((t, outcome, body))

    def excerpt(self, unit, t0, t1):
        pat = re.compile(r"^%d[A-Z]" % unit)
        return ["%.3f %s %s" % (t, k, r) for t, k, r in self.lines
                if t0 <= t <= t1 and (k == "chaos" or pat.match(r.split(" ", 1)[-1] if k ==
                                                                 "fault" else r))]


# ---------------------------------------------------------------------------------------------
# The run

class Run:
    def __init__(self, args):
        self.args = args
        self.dir = tempfile.mkdtemp(prefix="smc100-fault-property-")
        self.procs = []
        self.failures = []

    def fail(self, text):
        self.failures.append(text)
        log("FAIL: " + text)

    def start(self):
        d = self.dir
        # Only the SMC100's protocol file and model: other files in config/ (work in progress)
        # must not keep this daemon from starting.
        for sub, name in (("protocols", "newport-smc100.yaml"), ("models", "newport-smc100.yaml")):
            os.makedirs(os.path.join(d, sub))
            os.symlink(os.path.join(ROOT, "config", sub, name), os.path.join(d, sub, name))
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
        self.unit = subprocess.Popen(
            ["/usr/bin/python3", os.path.join(HERE, "smc100_unit.py"), "--link", d + "/port",
             "--addresses", "1,2", "--chaos", str(self.args.seed), "--chaos-paused",
             "--journal", d + "/journal", "--log", "none"],
            stdin=subprocess.DEVNULL, stdout=open(d + "/unit.log", "w"),
            stderr=subprocess.STDOUT, env=env)
        self.procs.append(self.unit)
        if not wait_until(lambda: os.path.exists(d + "/port"), 5):
            raise SystemExit("the unit did not start:\n" + open(d + "/unit.log").read())
        limits = "limits: {target: {min: -400000, max: 400000}}"
        with open(d + "/gw.yaml", "w") as f:
            f.write(f"""modbus: {{listen: 127.0.0.1:0}}
models: {d}/models
protocols: {d}/protocols
buses:
  - name: smc100
    protocol: newport-smc100
    serial: {{device: {d}/port, baud: 57600}}
    # A line this bad would take nodes offline every few polls with offline_after: 3; the
    # property is about the exchanges (as tests/harness/fault_property.cpp's fault_bus).
    timing: {{reply_timeout: 200ms, byte_timeout: 20ms, retries: 1, offline_after: 10,
             probe_interval: 300ms}}
    nodes:
      - {{name: smc_1, address: 1, model: newport-smc100, unit_id: 1, {limits}}}
      - {{name: smc_2, address: 2, model: newport-smc100, unit_id: 2, {limits}}}
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

    def home(self, client):
        ok = wait_until(lambda: all((client.inputs(u, 1000, 1) or [0])[0] == 1 for u in UNITS), 15)
        if not ok:
            raise SystemExit("units not online")
        for u in UNITS:
            # Fast moves: 200 mm/s, 2000 mm/s^2 (gateway-local setpoints, sent with each move).
            for address, value in ((VELOCITY, 2000000), (ACCELERATION, 20000000)):
                e, _ = client.call("write_registers", address, words(value), slave=u)
                if e != 0:
                    raise SystemExit("setpoint write on unit %d: exception %d" % (u, e))
            e, _ = client.call("write_register", ACTION, HOME, slave=u)
            if e != 0:
                raise SystemExit("home on unit %d: exception %d" % (u, e))

        def homed():
            return all((client.inputs(u, 3, 1) or [0])[0] == 0x32 for u in UNITS)
        if not wait_until(homed, 30, 0.2):
            raise SystemExit("units not homed")
        # One slow poll (PA?, 1 s) after homing, so that the setpoint read is the homed one.
        time.sleep(1.2)
        log("homed both units")

    def reader(self, stop, reads, misses):
        client = Client(self.port, 3)
        rng = random.Random(self.args.seed + 1000)
        while not stop.is_set():
            u = rng.choice(UNITS)
            e, r = client.call("read_input_registers", 0, INPUTS, slave=u)
            t = time.monotonic()
            if e == 0:
                reads.append((u, t, list(r.registers)))
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
            u = UNITS[rng.randrange(2)]
            refused = rng.random() < 0.25
            m = rng.randint(26, 39) if refused else rng.randint(0, 23)
            target = rng.choice((1, -1)) * (m * 10000 + i * 10 + u)

            # A unit at rest (READY, no action running), so that a move is not refused for
            # MOVING; after 4 s, write anyway.
            def at_rest():
                s = client.inputs(u, 3, 1)
                a = client.holding(u, ACTION_STATUS, 1)
                return s is not None and s[0] in READY and a is not None and a[0] != 1
            wait_until(at_rest, 4)
            e, _ = client.call("write_registers", TARGET, words(target), slave=u)
            if e != 0:
                # The setpoint is gateway-local: a failure here is the client's; without the
                # target in place the action would move to the previous one, so skip.
                log("iteration %d: target write answered %d, skipped" % (i, e))
                continue
            t0 = time.monotonic()
            e, _ = client.call("write_register", ACTION, MOVE_ABSOLUTE, slave=u)
            t1 = time.monotonic()
            action_error = None
            if e == DEVICE_FAILURE:
                r = client.holding(u, ACTION_ERROR, 1)
                action_error = r[0] if r else None
            writes.append(dict(i=i, unit=u, target=target, refused=refused, exception=e,
                               t0=t0, t1=t1, action_error=action_error))
            if self.args.verbose:
                log("write %2d unit %d target %7d%s: %s (%.0f ms)%s" % (
                    i, u, target, " (refused by the device)" if refused else "",
                    {0: "success", NO_ANSWER: "no answer"}.get(e, "exception 0x%02X" % e),
                    (t1 - t0) * 1000,
                    "" if action_error is None else " action error 0x%04X" % action_error))
            time.sleep(rng.random() * 0.04)
        return writes

    def main(self):
        try:
            self.start()
            client = Client(self.port, 10)
            self.home(client)
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
                log("  journal of controller %d around it:" % w["unit"])
                for line in j.excerpt(w["unit"], w["t0"] - 1.0, w["t1"] + 0.5):
                    log("    " + line)

        # Every outcome expected.
        outcomes = Counter(w["exception"] for w in writes)
        for w in writes:
            if w["exception"] not in (0, TARGET_FAILED, DEVICE_FAILURE, NO_ANSWER):
                show(w, "write %d (unit %d target %d) answered exception 0x%02X" %
                     (w["i"], w["unit"], w["target"], w["exception"]))

        # 2. A move answered success ran on its controller, and its read-back was clean.
        confirmed = [w for w in writes if w["exception"] == 0 and not w["refused"]]
        for w in confirmed:
            runs = j.moves.get((w["unit"], w["target"]), [])
            ok = [r for r in runs if r[1] == "ok" and r[0] >= w["t0"] - 0.01]
            if not ok:
                show(w, "move %d: unit %d target %d answered success, but the controller never "
                     "executed it (journal: %s)" % (w["i"], w["unit"], w["target"], runs or "none"))
                continue
            if not any(t >= ok[0][0] and v == w["target"] for t, v in j.pa_sent[w["unit"]]):
                show(w, "move %d: unit %d target %d answered success, but no clean PA? reply "
                     "with it was sent" % (w["i"], w["unit"], w["target"]))
        # Commands are never retried: no PA executed twice.
        for (u, target), runs in sorted(j.moves.items()):
            if len(runs) > 1:
                self.fail("PA %d executed %d times on controller %d: %s" %
                          (target, len(runs), u, runs))

        # 3. A target the device refuses is never answered success.
        refused = [w for w in writes if w["refused"]]
        for w in refused:
            if w["exception"] == 0:
                show(w, "move %d: unit %d target %d beyond the device's limits answered success"
                     % (w["i"], w["unit"], w["target"]))
            for t, outcome, body in j.moves.get((w["unit"], w["target"]), []):
                if outcome == "ok":
                    self.fail("the unit accepted %s beyond its limits (the test is wrong)" % body)

        # 5. No refusal the device did not give.
        false_refusals = []
        for w in writes:
            if w["exception"] != DEVICE_FAILURE:
                continue
            u, code = w["unit"], w["action_error"]
            executed = [r for r in j.moves.get((u, w["target"]), [])
                        if r[1] == "ok" and r[0] >= w["t0"] - 0.01]
            given = code == 0xFFFA or (code is not None and any(
                w["t0"] - 0.01 <= t <= w["t1"] + 0.01 and len(letter) == 1 and
                ord(letter) == code for t, letter in j.te_sent[u]))
            if executed or (code is not None and not given):
                false_refusals.append(w)
                why = ("move %d: unit %d target %d answered 0x04 (action error 0x%04X) but the "
                       "controller %s" % (w["i"], u, w["target"], code if code is not None else
                                          0xFFFF, "executed it" if executed else
                                          "sent no such error"))
                if not self.args.lenient_refusals:
                    show(w, why)
                else:
                    log("WARNING: " + why)
                    if excerpts < 5:
                        excerpts += 1
                        for line in j.excerpt(u, w["t0"] - 0.05, w["t1"] + 0.05):
                            log("    " + line)

        # 1. Every value served as good was sent in a clean reply, before the read answered.
        wrong = Counter()
        first_wrong = {}
        for u, t, r in reads:
            values = (("position", i32(r[0], r[1]), j.tp), ("positioner_errors", r[2],
                      j.ts_errors), ("state", r[3], j.ts_state), ("status", r[4], j.ts_status),
                      ("setpoint", i32(r[5], r[6]), j.pa))
            for name, value, table in values:
                sent_at = table[u].get(value)
                if sent_at is None or sent_at > t:
                    wrong[name] += 1
                    first_wrong.setdefault(name, (u, t, value, sent_at))
        for name, n in wrong.items():
            u, t, value, sent_at = first_wrong[name]
            self.fail("%d reads served a %s never sent by controller %d; first: %d at %.3f "
                      "(%s)" % (n, name, u, value, t, "never sent" if sent_at is None else
                                "first sent at %.3f" % sent_at))
            if excerpts < 5:
                excerpts += 1
                for line in j.excerpt(u, t - 1.0, t + 0.1):
                    log("    " + line)

        # 4. Not vacuous.
        unknown = outcomes[TARGET_FAILED]
        refused_answered = sum(1 for w in refused if w["exception"] == DEVICE_FAILURE)
        faults = sum(j.faults.values())
        not_taken = sum(1 for w in writes if w["action_error"] == 0xFFFA)
        summary = {
            "seed": self.args.seed,
            "writes": len(writes),
            "confirmed": len(confirmed),
            "unknown_0x0B": unknown,
            "device_failure_0x04": outcomes[DEVICE_FAILURE],
            "  of which not taken (0xFFFA)": not_taken,
            "  refusals never given (5)": len(false_refusals),
            "no_answer": outcomes[NO_ANSWER],
            "refused_targets": len(refused),
            "  answered 0x04": refused_answered,
            "faults_injected": faults,
            "  by kind": dict(sorted(j.faults.items())),
            "moves_executed": sum(len(v) for v in j.moves.values()),
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
        if refused_answered < 1:
            self.fail("vacuous: no refused target answered 0x04")
        if len(reads) < 100:
            self.fail("vacuous: only %d good reads" % len(reads))
        if self.failures:
            log("--- daemon log (last 60 lines) ---")
            for line in open(self.dir + "/daemon.log").read().splitlines()[-60:]:
                log("    " + line)
            log("FAILED (%d); scratch directory kept: %s" % (len(self.failures), self.dir))
            return 1
        log("PASS: no value served that the device never sent, no move confirmed that it did "
            "not execute, no refused target confirmed")
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
    ap.add_argument("--lenient-refusals", action="store_true",
                    help="only report property 5 (a 0x04 the device did not give)")
    ap.add_argument("--keep", action="store_true", help="keep the scratch directory")
    ap.add_argument("--verbose", action="store_true", help="each write; the daemon with -v")
    sys.exit(Run(ap.parse_args()).main())


if __name__ == "__main__":
    main()
