#!/usr/bin/python3
"""Profile scenarios beyond tools/axis.py's cycle, for reproducing what the independent units
showed (tests/independent/README.md). Exit status 0 when the profile behaves as
docs/axis-profile.md says, 1 with the observed pages when it does not.

  scenarios.py SCENARIO --port PORT --unit U[,V]

home-position  after home is done, the position is the reference (0 within 2 counts)
Exit status 2: not applicable (the axis has no jog).

abort-jog      move_absolute during a jog aborts the jog and reaches the target (Aborting mode)
cross-axis     a jog on axis V does not change axis U's running jog (two profile axes of a node)
shared-stop    stop on axis U of a controller whose stop halts every axis of the node (Centent Q,
               Whedco HT) ends axis V's running move aborted, not done short of its target
negative-target  (Centent: the position register takes only positive numbers, p.35) a negative
               absolute target is refused with exception 0x03 and the axis does not move

Issue 49 ("done" means arrived), checked against the unit's own state through its control
socket (--control, unit_common.Control), not against the gateway's word:
reset-mid-move  first a move left alone must end done at its target; then, --rounds times, a long
               move_absolute on axis U and the unit power-cycled once it covered a quarter,
               three quarters or 2 % of it: the command never reads done; it ends error with one of --reset-codes (what
               docs/axis-profile.md says the family gives), or, with --reset-may-stay-busy,
               stays busy until the bounded wait
simultaneous-axes  move_absolute written to every axis of the node at once (one connection per
               axis, released together; --rounds times): every axis that reads done stands, in
               the unit's own position, at its own target (0 false done), some read done, and,
               as no fault is injected, every command ends done at its target
home-no-velocity  on a fresh daemon and unit, home on axis U before any velocity was written:
               refused with 0x03, or ends (done or error) within 30 s; if done, the unit's own
               position is the reference (0 within 2)
"""
import argparse
import json
import socket
import sys
import threading
import time

from pymodbus.client import ModbusTcpClient

STATES = ["Disabled", "Standstill", "Homing", "DiscreteMotion", "ContinuousMotion", "Stopping",
          "ErrorStop"]
POWER_ON, HOME, MOVE_ABSOLUTE, JOG_POSITIVE, STOP, RESET = 1, 3, 4, 6, 8, 10
BUSY, DONE, ERROR, ABORTED = 1, 2, 3, 4
STATUS = {0: "idle", 1: "busy", 2: "done", 3: "error", 4: "aborted"}


def words(v):
    v &= 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


class Profile:
    def __init__(self, port, timeout=5):
        self.c = ModbusTcpClient("127.0.0.1", port=port, timeout=timeout)
        if not self.c.connect():
            raise SystemExit("cannot connect")
        self.seq = {}

    def page(self, unit):
        for _ in range(100):
            r = self.c.read_input_registers(0, 12, slave=unit)
            if not r.isError():
                w = r.registers
                pos = (w[0] << 16) | w[1]
                pos -= (1 << 32) if pos & 0x80000000 else 0
                return {"position": pos, "moving": bool(w[4] >> 2 & 1),
                        "state": STATES[w[5]] if w[5] < 7 else w[5], "seq": w[7],
                        "cmd_status": w[8], "cmd": w[9], "cmd_error": w[10]}
            time.sleep(0.1)
        raise SystemExit("unit %d: page not readable" % unit)

    def command(self, unit, code):
        seq = self.seq.get(unit, self.page(unit)["seq"]) % 65535 + 1
        self.seq[unit] = seq
        return self.c.write_registers(8, [code, seq], slave=unit)

    def setpoints(self, unit, target=None, velocity=None):
        if target is not None:
            self.c.write_registers(0, words(target), slave=unit)
        if velocity is not None:
            self.c.write_registers(2, words(velocity), slave=unit)

    def wait(self, unit, pred, timeout=30.0):
        deadline = time.monotonic() + timeout
        while True:
            p = self.page(unit)
            if pred(p) or time.monotonic() > deadline:
                return p
            time.sleep(0.02)


class UnitControl:
    """The unit's control socket (unit_common.Control): power-cycle and its own state."""

    def __init__(self, path, names):
        if not path:
            raise SystemExit("this scenario needs the unit's control socket (--control)")
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        for _ in range(50):
            try:
                self.sock.connect(path)
                break
            except OSError:
                time.sleep(0.1)
        else:
            raise SystemExit("cannot connect to the unit's control socket %s" % path)
        self.file = self.sock.makefile("rwb")
        self.names = names  # profile unit -> the unit's own axis name

    def ask(self, text):
        self.file.write(text.encode() + b"\n")
        self.file.flush()
        return self.file.readline().decode().strip()

    def axes(self):
        return json.loads(self.ask("state"))["axes"]

    def axis(self, unit):
        """(position, moving) of profile unit `unit`'s axis, as the unit itself has it."""
        a = self.axes()[self.names[unit]]
        return a["position"], a["moving"]

    def power_cycles(self):
        return json.loads(self.ask("state"))["power_cycles"]

    def power_cycle(self, who=None):
        answer = self.ask("power-cycle" + (" " + who if who else ""))
        if not answer.startswith("ok"):
            raise SystemExit("power-cycle refused by the unit: %s" % answer)
        return answer


def describe(p):
    return "%s/%s err 0x%04x pos %d %s" % (STATUS.get(p["cmd_status"], p["cmd_status"]),
                                          p["cmd"], p["cmd_error"], p["position"], p["state"])


def recover(pr, unit, seconds=20):
    """Back to Standstill after a scenario's round: stop a motion still running, reset
    ErrorStop."""
    p = pr.page(unit)
    if p["cmd_status"] == BUSY or p["moving"]:
        print("  unit %d (%s): stop" % (unit, describe(p)), flush=True)
        print("  stop: %s" % pr.command(unit, STOP))
        p = pr.wait(unit, lambda p: p["cmd_status"] != BUSY, seconds)
    if p["state"] == "ErrorStop":
        print("  unit %d (%s): reset" % (unit, describe(p)), flush=True)
        print("  reset: %s" % pr.command(unit, RESET))
        p = pr.wait(unit, lambda p: p["state"] != "ErrorStop" and p["cmd_status"] != BUSY,
                    seconds)
    p = pr.wait(unit, lambda p: p["state"] == "Standstill", seconds)
    return p


def reset_mid_move(pr, units, args):
    """A long move, the unit power-cycled once the axis has covered a part of it (by the
    unit's own position): the command must not read done."""
    u = units[0]
    ctl = UnitControl(args.control, args.unit_axes)
    span = 4 * args.distance
    expected = set(args.reset_codes)
    counts = {"rounds": 0, "false done": 0, "error as documented": 0, "busy at the bound": 0,
              "other": 0, "control move done at target": 0}
    # First a move left alone: it must end done at its target (else "not done" below would
    # prove nothing about the power cycle).
    recover(pr, u)
    own, _ = ctl.axis(u)
    target = int(own) + args.distance
    pr.setpoints(u, target=target, velocity=args.velocity or None)
    t0 = time.monotonic()
    r = pr.command(u, MOVE_ABSOLUTE)
    p = pr.wait(u, lambda p: p["cmd_status"] != BUSY, args.bound)
    own_pos, _ = ctl.axis(u)
    print("control move (no power cycle) %d -> %d: %s; after %.2f s: %s, the unit at %s" % (
        own, target, r, time.monotonic() - t0, describe(p), own_pos))
    if p["cmd_status"] == DONE and abs(own_pos - target) <= args.tolerance:
        counts["control move done at target"] += 1
    else:
        print("  NOT as documented: a move nothing interrupted did not end done at its target")
    for rnd in range(args.rounds):
        start = recover(pr, u)
        if start["state"] != "Standstill":
            print("round %d: axis not at Standstill before the move: %s" % (rnd, describe(start)))
            counts["other"] += 1
            break
        own, _ = ctl.axis(u)
        target = int(own) + span
        pr.setpoints(u, target=target, velocity=args.velocity or None)
        t0 = time.monotonic()
        r = pr.command(u, MOVE_ABSOLUTE)
        seq = pr.seq[u]
        print("round %d: move_absolute %d -> %d (seq %d): %s" % (rnd, own, target, seq, r))
        if r.isError():
            counts["other"] += 1
            continue
        # Until the unit itself has covered a part of the way (bounded): a quarter, three
        # quarters, or just started.
        part = (0.25, 0.75, 0.02)[rnd % 3]
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            pos, moving = ctl.axis(u)
            if abs(pos - own) >= span * part:
                break
            time.sleep(0.005)
        before = pr.page(u)
        answer = ctl.power_cycle()
        pos_after, moving_after = ctl.axis(u)
        print("  power-cycled at the unit's position %s (%.2f s after the command; the page "
              "read %s); unit now %s %s: %s" % (pos, time.monotonic() - t0, describe(before),
                                               pos_after, "moving" if moving_after else
                                               "at rest", answer))
        counts["rounds"] += 1
        # The command's end, watched at every page read: a done seen at any moment counts.
        deadline = time.monotonic() + args.bound
        end = None
        while time.monotonic() < deadline:
            p = pr.page(u)
            if p["seq"] != seq:
                end = p
                break
            if p["cmd_status"] == DONE:
                own_pos, own_moving = ctl.axis(u)
                end = p
                print("  DONE read: %s; the unit's own position %s%s, target %d" %
                      (describe(p), own_pos, " moving" if own_moving else "", target))
                break
            if p["cmd_status"] != BUSY:
                end = p
                break
            time.sleep(0.02)
        took = time.monotonic() - t0
        if end is None:
            end = pr.page(u)
        if end["seq"] != seq:
            print("  the sequence echo changed (%d): %s" % (end["seq"], describe(end)))
            counts["other"] += 1
        elif end["cmd_status"] == DONE:
            own_pos, _ = ctl.axis(u)
            if abs(own_pos - target) > args.tolerance:
                counts["false done"] += 1
                print("  FALSE DONE after %.2f s: %s, the unit stands at %s, target %d" %
                      (took, describe(end), own_pos, target))
            else:
                counts["other"] += 1
                print("  done at the target: the power cycle did not interrupt the move")
        elif end["cmd_status"] == BUSY:
            ok = args.reset_may_stay_busy
            counts["busy at the bound" if ok else "other"] += 1
            print("  still busy after %.0f s: %s (%s)" % (args.bound, describe(end),
                                                         "as documented" if ok else "unexpected"))
        elif end["cmd_status"] == ERROR and end["cmd_error"] in expected:
            counts["error as documented"] += 1
            print("  error 0x%04x after %.2f s, as documented: %s" % (end["cmd_error"], took,
                                                                   describe(end)))
        else:
            counts["other"] += 1
            print("  ended %s after %.2f s, not as documented (expected error %s): the unit "
                  "stands at %s" % (describe(end), took,
                                    "/".join("0x%04x" % c for c in sorted(expected)),
                                    ctl.axis(u)[0]))
        print("  after recovery:", describe(recover(pr, u)))
    print("reset-mid-move counts:", counts)
    return counts["rounds"] == args.rounds and counts["false done"] == 0 and \
        counts["other"] == 0 and counts["control move done at target"] == 1


def simultaneous_axes(pr, units, args):
    """move_absolute to every axis of the node in one burst: one connection per axis, the
    writes released together."""
    ctl = UnitControl(args.control, args.unit_axes)
    counts = {"commands": 0, "refused 0x06": 0, "not taken": 0, "done": 0, "done at target": 0,
              "false done": 0, "error": 0, "aborted": 0, "busy at the bound": 0}
    # A write is answered once the command's first step is acknowledged, and a command queues
    # behind the other axes' (a Techno M holds the line until the motion ends): the clients
    # wait as long as the bounded wait, and the latency is shown, not judged.
    clients = {u: Profile(args.port, timeout=args.bound) for u in units}
    for rnd in range(args.rounds):
        for u in units:
            p = recover(pr, u)
            if p["state"] != "Standstill":
                print("round %d: unit %d not at Standstill: %s" % (rnd, u, describe(p)))
        targets = {}
        for i, u in enumerate(units):
            own, _ = ctl.axis(u)
            step = (i + 1) * args.distance + 11 * (i + 1)
            targets[u] = int(own) + (step if rnd % 2 == 0 else -(step // 2))
            pr.setpoints(u, target=targets[u], velocity=args.velocity or None)
            clients[u].seq[u] = pr.seq.get(u, pr.page(u)["seq"])
        barrier = threading.Barrier(len(units))
        results, sent_at = {}, {}

        answered_at = {}

        def fire(u):
            barrier.wait()
            sent_at[u] = time.monotonic()
            try:
                results[u] = clients[u].command(u, MOVE_ABSOLUTE)
            except Exception as e:  # no reply within the client's timeout: taken or not
                results[u] = e
            answered_at[u] = time.monotonic()
        threads = [threading.Thread(target=fire, args=(u,)) for u in units]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        spread = (max(sent_at.values()) - min(sent_at.values())) * 1000
        print("round %d: move_absolute to %s, sent within %.1f ms" % (
            rnd, ", ".join("%d -> %d" % (u, targets[u]) for u in units), spread))
        seqs = {}
        for u in units:
            pr.seq[u] = clients[u].seq[u]
            r = results[u]
            print("  unit %d write answered after %.2f s: %s" % (
                u, answered_at[u] - sent_at[u], r))
            counts["commands"] += 1
            if isinstance(r, Exception) or r.isError():
                if getattr(r, "exception_code", None) == 6:
                    counts["refused 0x06"] += 1  # server busy: documented, nothing taken
                    continue
                if pr.page(u)["seq"] != pr.seq[u]:
                    counts["not taken"] += 1
                    print("  unit %d: the command was not taken (sequence echo %d)" % (
                        u, pr.page(u)["seq"]))
                    continue
            seqs[u] = pr.seq[u]
        deadline = time.monotonic() + args.bound
        pending = dict(seqs)
        ends = {}
        while pending and time.monotonic() < deadline:
            for u in list(pending):
                p = pr.page(u)
                if p["seq"] != pending[u] or p["cmd_status"] != BUSY:
                    own = ctl.axes()
                    ends[u] = (p, own)
                    del pending[u]
            time.sleep(0.02)
        for u in seqs:
            if u in pending:
                counts["busy at the bound"] += 1
                print("  unit %d still busy after %.0f s: %s" % (u, args.bound,
                                                                 describe(pr.page(u))))
                continue
            p, own = ends[u]
            pos = own[args.unit_axes[u]]["position"]
            where = "the unit's own positions %s" % ", ".join(
                "%s %s" % (k, v["position"]) for k, v in sorted(own.items()))
            if p["seq"] != seqs[u]:
                counts["aborted"] += 1
                print("  unit %d: the sequence echo changed: %s" % (u, describe(p)))
            elif p["cmd_status"] == DONE:
                counts["done"] += 1
                if abs(pos - targets[u]) <= args.tolerance:
                    counts["done at target"] += 1
                    print("  unit %d done at its target %d (%s)" % (u, targets[u], where))
                else:
                    counts["false done"] += 1
                    print("  unit %d FALSE DONE: target %d, the unit stands at %s (%s; page %s)"
                          % (u, targets[u], pos, where, describe(p)))
            elif p["cmd_status"] == ABORTED:
                counts["aborted"] += 1
                print("  unit %d aborted: %s (%s)" % (u, describe(p), where))
            else:
                counts["error"] += 1
                print("  unit %d ended %s (%s)%s" % (
                    u, describe(p), where,
                    "; 0xfffa says the controller reset, the unit was never power-cycled"
                    if p["cmd_error"] == 0xFFFA and ctl.power_cycles() == 0 else ""))
    print("simultaneous-axes counts:", counts)
    if counts["done"] == 0:
        print("vacuous: no command read done")
    # No fault is injected: every command must arrive (an error, abort or refusal is the
    # gateway's misreading, reported as not documented, though it is no false done).
    taken = counts["commands"] - counts["refused 0x06"]
    if counts["done at target"] != taken:
        print("NOT as documented: %d of %d commands taken did not end done at their target, "
              "with no fault injected" % (taken - counts["done at target"], taken))
    return counts["false done"] == 0 and counts["done"] > 0 and counts["done at target"] == taken


def home_no_velocity(pr, units, args):
    """Home before any velocity was written (the daemon and unit fresh): it ends within
    seconds, refused or done or failed."""
    u = units[0]
    ctl = UnitControl(args.control, args.unit_axes) if args.control else None
    t0 = time.monotonic()
    r = pr.command(u, HOME)
    print("home with no velocity written:", r)
    if r.isError():
        code = getattr(r, "exception_code", None)
        print("refused with exception 0x%02x after %.2f s" % (code or 0, time.monotonic() - t0))
        return code == 3
    p = pr.wait(u, lambda p: p["cmd_status"] != BUSY, args.bound)
    took = time.monotonic() - t0
    print("after %.2f s: %s" % (took, describe(p)))
    if p["cmd_status"] == BUSY:
        print("still busy after %.0f s" % args.bound)
        print("stop:", pr.command(u, STOP))
        return False
    if p["cmd_status"] == DONE and ctl:
        pos, moving = ctl.axis(u)
        print("the unit's own position %s%s" % (pos, " moving" if moving else ""))
        return abs(pos) <= 2 and not moving
    if p["cmd_status"] == ERROR and p["cmd_error"] == 0xFFFA and ctl and \
            ctl.power_cycles() == 0:
        print("NOT as documented: 0xfffa says the controller reset, the unit was never "
              "power-cycled")
        return False
    return p["cmd_status"] in (DONE, ERROR)


def ready(pr, unit):
    """Until the first polls have told the axis's state: a unit that powers up enabled reads
    Disabled for a moment after it came online. One still Disabled after that is powered on
    where the axis has the command (supported_commands bit 1)."""
    p = pr.wait(unit, lambda p: p["state"] != "Disabled", 5)
    if p["state"] != "Disabled":
        return
    r = pr.c.read_input_registers(11, 1, slave=unit)
    if not r.isError() and r.registers[0] >> 1 & 1:
        pr.command(unit, POWER_ON)
        pr.wait(unit, lambda p: p["state"] == "Standstill", 30)


def home_position(pr, units, args):
    u = units[0]
    if args.velocity:
        pr.setpoints(u, velocity=args.velocity)
    print("home:", pr.command(u, HOME))
    p = pr.wait(u, lambda p: p["cmd_status"] != BUSY, 60)
    print("at done:", p)
    return p["cmd_status"] == DONE and abs(p["position"]) <= 2


def abort_jog(pr, units, args):
    u = units[0]
    pr.setpoints(u, velocity=args.velocity or None)
    r = pr.command(u, JOG_POSITIVE)
    print("jog:", r)
    if r.isError():
        return None
    pr.wait(u, lambda p: p["state"] == "ContinuousMotion")
    time.sleep(0.5)
    start = pr.page(u)
    target = start["position"] + args.distance
    pr.setpoints(u, target=target)
    r = pr.command(u, MOVE_ABSOLUTE)
    print("move_absolute during the jog:", r)
    p = pr.wait(u, lambda p: p["cmd_status"] != BUSY, 60)
    print("then:", p)
    ok = not r.isError() and p["cmd_status"] == DONE and abs(p["position"] - target) <= 4
    if not ok:
        print("stop:", pr.command(u, STOP))
        time.sleep(0.5)
        print("after stop:", pr.page(u))
        print("reset:", pr.command(u, 10))
        time.sleep(0.5)
        print("after reset:", pr.page(u))
        print("stop:", pr.command(u, STOP))
        print("after stop:", pr.wait(u, lambda p: p["state"] == "Standstill", 10))
    return ok


def cross_axis(pr, units, args):
    u, v = units[0], units[1]
    for unit in (u, v):
        pr.setpoints(unit, velocity=args.velocity or None)
    r = pr.command(u, JOG_POSITIVE)
    print("jog U:", r)
    if r.isError():
        return None
    print("jog V:", pr.command(v, JOG_POSITIVE))
    time.sleep(1.0)
    pu, pv = pr.page(u), pr.page(v)
    print("U:", pu)
    print("V:", pv)
    pr.command(u, STOP)
    pr.wait(u, lambda p: p["state"] == "Standstill")
    pr.command(v, STOP)
    pr.wait(v, lambda p: p["state"] == "Standstill")
    return pu["cmd"] == JOG_POSITIVE and pu["cmd_status"] == DONE and \
        pu["state"] == "ContinuousMotion"


def shared_stop(pr, units, args):
    u, v = units[0], units[1]
    pr.setpoints(v, velocity=args.velocity or None)
    start = pr.page(v)
    pr.setpoints(v, target=start["position"] + 5 * args.distance)
    print("move_absolute V:", pr.command(v, MOVE_ABSOLUTE))
    moving = pr.wait(v, lambda p: p["moving"], 10)
    print("V moving:", moving)
    print("stop U:", pr.command(u, STOP))
    pu = pr.wait(u, lambda p: p["cmd_status"] != BUSY and not p["moving"], 30)
    pv = pr.wait(v, lambda p: p["cmd_status"] != BUSY and not p["moving"], 30)
    print("U:", pu)
    print("V:", pv)
    return moving["moving"] and pu["cmd_status"] == DONE and pv["cmd_status"] == ABORTED and \
        pv["state"] == "Standstill"


def negative_target(pr, units, args):
    u = units[0]
    before = pr.page(u)
    pr.setpoints(u, target=-10240, velocity=args.velocity or None)
    r = pr.command(u, MOVE_ABSOLUTE)
    print("move_absolute to -10240:", r)
    time.sleep(1.0)
    after = pr.page(u)
    print("before:", before)
    print("after:", after)
    refused = r.isError() and getattr(r, "exception_code", None) == 3
    if after["moving"]:
        print("stop:", pr.command(u, STOP))
        pr.wait(u, lambda p: not p["moving"], 10)
    return refused and not after["moving"] and abs(after["position"] - before["position"]) <= 2


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario",
                    choices=["home-position", "abort-jog", "cross-axis", "shared-stop",
                             "negative-target", "reset-mid-move", "simultaneous-axes",
                             "home-no-velocity"])
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--unit", required=True)
    ap.add_argument("--distance", type=int, default=2000)
    ap.add_argument("--velocity", type=int, default=0)
    ap.add_argument("--tolerance", type=int, default=0,
                    help="counts a position may differ from its target")
    ap.add_argument("--control", help="the unit's control socket (unit_common.Control)")
    ap.add_argument("--unit-axes", default="",
                    help="profile unit = the unit's own axis name, e.g. 31=X,32=Y")
    ap.add_argument("--reset-codes", default="0xfffa,0xffec",
                    help="command_error values a move interrupted by a power cycle may end with")
    ap.add_argument("--reset-may-stay-busy", action="store_true")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--bound", type=float, default=20.0,
                    help="seconds to wait for a command's end")
    args, _ = ap.parse_known_args()
    units = [int(x) for x in args.unit.split(",") if x]
    args.unit_axes = {int(k): v for k, v in
                      (x.split("=", 1) for x in args.unit_axes.split(",") if x)}
    args.reset_codes = [int(x, 0) for x in args.reset_codes.split(",") if x]
    pr = Profile(args.port)
    for u in units:
        ready(pr, u)
    ok = {"home-position": home_position, "abort-jog": abort_jog,
          "cross-axis": cross_axis, "shared-stop": shared_stop,
          "negative-target": negative_target, "reset-mid-move": reset_mid_move,
          "simultaneous-axes": simultaneous_axes, "home-no-velocity": home_no_velocity}[
              args.scenario](pr, units, args)
    if ok is None:
        print("%s: not applicable (no jog on this axis)" % args.scenario)
        return 2
    print("%s: %s" % (args.scenario, "as documented" if ok else "NOT as documented"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
