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
"""
import argparse
import sys
import time

from pymodbus.client import ModbusTcpClient

STATES = ["Disabled", "Standstill", "Homing", "DiscreteMotion", "ContinuousMotion", "Stopping",
          "ErrorStop"]
POWER_ON, HOME, MOVE_ABSOLUTE, JOG_POSITIVE, STOP = 1, 3, 4, 6, 8
BUSY, DONE, ABORTED = 1, 2, 4


def words(v):
    v &= 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


class Profile:
    def __init__(self, port):
        self.c = ModbusTcpClient("127.0.0.1", port=port, timeout=5)
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
                             "negative-target"])
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--unit", required=True)
    ap.add_argument("--distance", type=int, default=2000)
    ap.add_argument("--velocity", type=int, default=0)
    args, _ = ap.parse_known_args()
    units = [int(x) for x in args.unit.split(",") if x]
    pr = Profile(args.port)
    for u in units:
        ready(pr, u)
    ok = {"home-position": home_position, "abort-jog": abort_jog,
          "cross-axis": cross_axis, "shared-stop": shared_stop,
          "negative-target": negative_target}[args.scenario](
              pr, units, args)
    if ok is None:
        print("%s: not applicable (no jog on this axis)" % args.scenario)
        return 2
    print("%s: %s" % (args.scenario, "as documented" if ok else "NOT as documented"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
