#!/usr/bin/python3
"""Drives fieldgate axis-profile units through one motion script and checks every handshake and
PLCopen state transition. Knows only the profile page (docs/axis-profile.md), nothing of the
controller family behind it.

  tools/axis.py --host 127.0.0.1 --port 1502 --unit 5 --unit 21,22

Per axis: reset if in ErrorStop, power on, home, move absolute, move relative, jog + and stop,
jog - and halt, a repeated sequence number (ignored), every unsupported command (exception 0x01),
errors and their reset: a move while Disabled (axes with power_off); a device error that puts the
axis in ErrorStop (--beyond: a target the controller refuses; --fault-command: a fault it
reports), where a move is refused until reset returns to Standstill; a target beyond the node's
configured limit (--refused-target, exception 0x03). One of --beyond, --fault-command or
--no-device-error (the controller has no error to provoke) is required. Exit status 0 only
if every check passed. Needs Debian's python3-pymodbus (3.0).
"""
import argparse
import subprocess
import sys
import time

from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse

# The page (docs/axis-profile.md).
IN_POSITION, IN_VELOCITY, IN_STATUS, IN_STATE, IN_ERROR_ID = 0, 2, 4, 5, 6
IN_SEQ, IN_CMD_STATUS, IN_CMD_ECHO, IN_CMD_ERROR, IN_SUPPORTED, IN_COUNT = 7, 8, 9, 10, 11, 12
HR_TARGET, HR_VELOCITY, HR_ACCEL, HR_DECEL, HR_COMMAND = 0, 2, 4, 6, 8

BITS = ["enabled", "homed", "moving", "in_position", "error", "limit_positive",
        "limit_negative", "warning", "velocity_reported", "online"]
STATES = ["Disabled", "Standstill", "Homing", "DiscreteMotion", "ContinuousMotion", "Stopping",
          "ErrorStop"]
COMMANDS = {"power_on": 1, "power_off": 2, "home": 3, "move_absolute": 4, "move_relative": 5,
            "jog_positive": 6, "jog_negative": 7, "stop": 8, "halt": 9, "reset": 10}
IDLE, BUSY, DONE, ERROR, ABORTED = 0, 1, 2, 3, 4
STATUS_NAMES = ["idle", "busy", "done", "error", "aborted"]
ERR_DISABLED = 0xFFF0
ERR_ERROR_STOP = 0xFFEF

# The PLCopen state diagram: the transitions a profile axis may show between two reads.
ALLOWED = {
    "Disabled": {"Standstill", "ErrorStop"},
    "Standstill": {"Disabled", "Homing", "DiscreteMotion", "ContinuousMotion", "Stopping",
                   "ErrorStop"},
    "Homing": {"Standstill", "Stopping", "ErrorStop", "Disabled"},
    "DiscreteMotion": {"Standstill", "ContinuousMotion", "Stopping", "ErrorStop", "Disabled"},
    "ContinuousMotion": {"DiscreteMotion", "Standstill", "Stopping", "ErrorStop", "Disabled"},
    "Stopping": {"Standstill", "ErrorStop", "Disabled"},
    "ErrorStop": {"Standstill", "Disabled"},
}


def s32(hi, lo):
    v = (hi << 16) | lo
    return v - (1 << 32) if v & 0x80000000 else v


def words(v):
    v &= 0xFFFFFFFF
    return [v >> 16, v & 0xFFFF]


class Failed(Exception):
    pass


class Axis:
    def __init__(self, client, unit, args):
        self.c, self.unit, self.args = client, unit, args
        self.seq = 0
        self.checks = 0
        self.last_state = None

    def log(self, text):
        print("unit %d: %s" % (self.unit, text), flush=True)

    def check(self, what, cond, detail=""):
        self.checks += 1
        if not cond:
            raise Failed("%s%s" % (what, (": " + detail) if detail else ""))
        if self.args.verbose:
            self.log("ok: " + what)

    def page(self):
        for _ in range(50):
            r = self.c.read_input_registers(0, IN_COUNT, slave=self.unit)
            if not r.isError():
                w = r.registers
                p = {"position": s32(w[0], w[1]), "velocity": s32(w[2], w[3]),
                     "status": w[IN_STATUS], "state": STATES[w[IN_STATE]] if w[IN_STATE] < 7
                     else "?%d" % w[IN_STATE], "error_id": w[IN_ERROR_ID], "seq": w[IN_SEQ],
                     "cmd_status": w[IN_CMD_STATUS], "cmd": w[IN_CMD_ECHO],
                     "cmd_error": w[IN_CMD_ERROR], "supported": w[IN_SUPPORTED]}
                for i, name in enumerate(BITS):
                    p[name] = bool(w[IN_STATUS] >> i & 1)
                self.track(p["state"])
                return p
            time.sleep(0.1)  # not online yet (0x0B)
        raise Failed("the profile page cannot be read: %s" % r)

    def track(self, state):
        if self.last_state is not None and state != self.last_state:
            self.check("transition %s -> %s is in the PLCopen diagram" % (self.last_state, state),
                       state in ALLOWED.get(self.last_state, set()))
            if self.args.verbose:
                self.log("state %s -> %s" % (self.last_state, state))
        self.last_state = state

    def supports(self, name):
        return bool(self.page()["supported"] >> COMMANDS[name] & 1)

    def set_setpoints(self, target=None, velocity=None):
        if target is not None:
            r = self.c.write_registers(HR_TARGET, words(target), slave=self.unit)
            self.check("target written", not r.isError(), str(r))
        if velocity is not None:
            r = self.c.write_registers(HR_VELOCITY, words(velocity), slave=self.unit)
            self.check("velocity written", not r.isError(), str(r))

    def send(self, name):
        """Writes command and a new sequence number in one request; returns the response."""
        self.seq = self.seq % 65535 + 1
        if self.seq == self.page()["seq"]:
            self.seq = self.seq % 65535 + 1
        return self.c.write_registers(HR_COMMAND, [COMMANDS[name], self.seq], slave=self.unit)

    def command(self, name, expect=DONE, during=None, timeout=None):
        """Runs a command through the handshake; returns the states seen while it was busy."""
        r = self.send(name)
        if isinstance(r, ExceptionResponse):
            raise Failed("%s answered exception 0x%02x" % (name, r.exception_code))
        self.check(name + " write confirmed", not r.isError(), str(r))
        p = self.page()
        self.check(name + ": sequence echoed", p["seq"] == self.seq,
                   "echo %d, sent %d" % (p["seq"], self.seq))
        self.check(name + ": command echoed", p["cmd"] == COMMANDS[name])
        self.check(name + ": status busy or complete", p["cmd_status"] in (BUSY, DONE, ERROR),
                   STATUS_NAMES[p["cmd_status"]])
        seen = set()
        deadline = time.monotonic() + (timeout or self.args.timeout)
        while p["cmd_status"] == BUSY:
            seen.add(p["state"])
            if during:
                during(p)
            self.check(name + " completes in time", time.monotonic() < deadline, str(p))
            time.sleep(0.02)
            p = self.page()
            self.check(name + ": sequence stays echoed", p["seq"] == self.seq)
        self.check("%s ends %s" % (name, STATUS_NAMES[expect]), p["cmd_status"] == expect,
                   "status %s, command error 0x%04x, state %s" %
                   (STATUS_NAMES[p["cmd_status"]], p["cmd_error"], p["state"]))
        return seen, p

    def expect_exception(self, name, code):
        r = self.send(name)
        self.check("%s answers exception 0x%02x" % (name, code),
                   isinstance(r, ExceptionResponse) and r.exception_code == code, str(r))
        self.seq -= 1  # not taken

    def wait_state(self, wanted, timeout=None):
        deadline = time.monotonic() + (timeout or self.args.timeout)
        while True:
            p = self.page()
            if p["state"] in wanted:
                return p
            self.check("state becomes %s" % "/".join(wanted), time.monotonic() < deadline,
                       "still %s" % p["state"])
            time.sleep(0.02)

    def error_stop_and_reset(self, p):
        """In ErrorStop: the error ID is set, a move is refused, reset returns to Standstill."""
        self.log("ErrorStop: error ID 0x%04x, command error 0x%04x" % (p["error_id"],
                                                                        p["cmd_error"]))
        self.check("ErrorStop: error ID set", p["error_id"] != 0, str(p))
        self.set_setpoints(target=p["position"])
        _, q = self.command("move_absolute", expect=ERROR)
        self.check("ErrorStop refuses a move: command error 0x%04x" % ERR_ERROR_STOP,
                   q["state"] == "ErrorStop" and q["cmd_error"] == ERR_ERROR_STOP, str(q))
        self.command("reset")
        p = self.wait_state({"Standstill"})
        self.check("reset clears the error", p["error_id"] == 0 and not p["error"], str(p))

    def run(self):
        a = self.args
        p = self.page()
        self.seq = p["seq"]
        self.log("start: state %s, position %d, supported %s" % (
            p["state"], p["position"],
            ",".join(n for n, c in COMMANDS.items() if p["supported"] >> c & 1)))
        if p["state"] == "ErrorStop":
            self.command("reset")
            p = self.wait_state({"Disabled", "Standstill"})
        # Power
        if self.supports("power_on"):
            if self.supports("power_off"):
                self.command("power_off")
                p = self.wait_state({"Disabled"})
                self.check("power off: not enabled", not p["enabled"])
            self.command("power_on")
            p = self.wait_state({"Standstill"})
            self.check("power on: enabled", p["enabled"])
        else:
            self.expect_exception("power_on", 0x01)
            self.check("an axis without power command is enabled", self.page()["enabled"])
        # Home
        if self.supports("home"):
            if a.home_velocity:
                self.set_setpoints(velocity=a.home_velocity)
            seen, p = self.command("home", timeout=a.timeout * 2)
            self.check("home: Homing seen or over at once", seen <= {"Homing"}, str(seen))
            p = self.wait_state({"Standstill"})
            self.check("home: homed bit", p["homed"] or not a.expect_homed)
        else:
            self.expect_exception("home", 0x01)
        # Move absolute
        start = self.page()["position"]
        target = start + a.distance
        self.set_setpoints(target=target, velocity=a.velocity if a.velocity else None)
        seen, p = self.command("move_absolute")
        self.check("move absolute: DiscreteMotion while busy", seen <= {"DiscreteMotion"} and
                   (seen or a.distance == 0), str(seen))
        p = self.wait_state({"Standstill"})
        self.check("move absolute reaches %d" % target, abs(p["position"] - target) <= a.tolerance,
                   "at %d" % p["position"])
        self.check("move absolute: in position", p["in_position"] and not p["moving"])
        # A repeated sequence number is ignored.
        r = self.c.write_registers(HR_COMMAND, [COMMANDS["move_relative"], self.seq],
                                   slave=self.unit)
        self.check("repeated sequence number: write answered", not r.isError(), str(r))
        time.sleep(0.2)
        q = self.page()
        self.check("repeated sequence number ignored", q["cmd"] == COMMANDS["move_absolute"] and
                   q["cmd_status"] == DONE and abs(q["position"] - p["position"]) <= a.tolerance,
                   str(q))
        # Move relative
        if self.supports("move_relative"):
            self.set_setpoints(target=-(a.distance // 2))
            seen, p = self.command("move_relative")
            self.check("move relative: DiscreteMotion while busy", seen <= {"DiscreteMotion"},
                       str(seen))
            p = self.wait_state({"Standstill"})
            want = target - a.distance // 2
            self.check("move relative reaches %d" % want, abs(p["position"] - want) <= a.tolerance,
                       "at %d" % p["position"])
        else:
            self.expect_exception("move_relative", 0x01)
        # Jog + and stop, jog - and halt
        for jog, end, sign in (("jog_positive", "stop", 1), ("jog_negative", "halt", -1)):
            if not self.supports(jog):
                self.expect_exception(jog, 0x01)
                continue
            if a.jog_velocity:
                self.set_setpoints(velocity=a.jog_velocity)
            before = self.page()["position"]
            _, p = self.command(jog)
            self.check(jog + ": done once the axis runs", p["moving"], str(p))
            p = self.wait_state({"ContinuousMotion"})
            deadline = time.monotonic() + a.timeout
            while (p["position"] - before) * sign <= a.tolerance:
                self.check(jog + ": the axis moves", time.monotonic() < deadline,
                           "position %d" % p["position"])
                time.sleep(0.05)
                p = self.page()
                self.check(jog + ": ContinuousMotion while jogging",
                           p["state"] == "ContinuousMotion", p["state"])
            if not self.supports(end):
                end = "stop"
            seen, p = self.command(end)
            self.check(end + ": Stopping/DiscreteMotion while busy",
                       seen <= ({"Stopping"} if end == "stop" else {"DiscreteMotion"}), str(seen))
            self.check(end + ": done means stopped", not p["moving"], str(p))
            p = self.wait_state({"Standstill"})
            time.sleep(0.3)
            q = self.page()
            self.check(end + ": the axis stands still", abs(q["position"] - p["position"]) <=
                       a.tolerance and q["state"] == "Standstill", "%d -> %d" %
                       (p["position"], q["position"]))
        # An axis without jogs: stop and halt a running move instead.
        if not self.supports("jog_positive") and not self.supports("jog_negative"):
            for end in ("stop", "halt"):
                if not self.supports(end):
                    continue
                start = self.page()["position"]
                self.set_setpoints(target=start + 4 * a.distance)
                r = self.send("move_absolute")
                self.check("long move taken", not r.isError(), str(r))
                deadline = time.monotonic() + a.timeout
                p = self.page()
                while not p["moving"]:
                    self.check("long move: the axis moves", time.monotonic() < deadline, str(p))
                    time.sleep(0.02)
                    p = self.page()
                seen, p = self.command(end)
                self.check(end + " of a move: Stopping/DiscreteMotion while busy",
                           seen <= ({"Stopping"} if end == "stop" else {"DiscreteMotion"}),
                           str(seen))
                self.check(end + " of a move: done means stopped", not p["moving"], str(p))
                self.check(end + " of a move: short of the target",
                           abs(p["position"] - (start + 4 * a.distance)) > a.tolerance, str(p))
                self.wait_state({"Standstill"})
        # Every unsupported command answers 0x01.
        for name in COMMANDS:
            if not self.supports(name):
                self.expect_exception(name, 0x01)
        # Errors, then reset: every way the options and the axis allow.
        if self.supports("power_off"):
            self.command("power_off")
            self.wait_state({"Disabled"})
            self.set_setpoints(target=self.page()["position"] + a.distance)
            _, p = self.command("move_absolute", expect=ERROR)
            self.check("move while Disabled: command error 0x%04x" % ERR_DISABLED,
                       p["cmd_error"] == ERR_DISABLED, "0x%04x" % p["cmd_error"])
            self.check("move while Disabled: stays Disabled", p["state"] == "Disabled")
            self.command("reset")
            self.command("power_on")
            self.wait_state({"Standstill"})
        if a.beyond is not None:
            # A target the controller itself refuses (or fails on): ErrorStop with its code.
            self.set_setpoints(target=a.beyond)
            r = self.send("move_absolute")
            self.check("move beyond the limit: write answered or refused by the device",
                       not r.isError() or (isinstance(r, ExceptionResponse) and
                                           r.exception_code == 0x04), str(r))
            p = self.wait_state({"ErrorStop"})
            self.check("move beyond the limit: command error", p["cmd_status"] == ERROR and
                       p["cmd_error"] != 0, str(p))
            self.error_stop_and_reset(p)
        if a.fault_command:
            # A fault the controller reports by itself (for a simulator: injected on its control
            # channel): ErrorStop from the error bit, with the device's code.
            command = a.fault_command.replace("{unit}", str(self.unit))
            self.check("fault command runs", subprocess.run(command, shell=True).returncode == 0,
                       command)
            p = self.wait_state({"ErrorStop"})
            self.check("device fault: error bit", p["error"], str(p))
            self.error_stop_and_reset(p)
        if a.refused_target is not None:
            # A target beyond the node's configured limit is refused by the gateway before
            # anything moves.
            before = self.page()
            self.set_setpoints(target=a.refused_target)
            self.expect_exception("move_absolute", 0x03)
            time.sleep(0.2)
            p = self.page()
            self.check("refused move: nothing taken", p["seq"] == before["seq"] and
                       not p["moving"] and abs(p["position"] - before["position"]) <= a.tolerance,
                       str(p))
            self.command("reset")
            self.check("reset: Standstill", self.wait_state({"Standstill"})["error_id"] == 0)
        self.log("all %d checks passed" % self.checks)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=1502)
    ap.add_argument("--unit", action="append", required=True,
                    help="profile unit ID(s), repeatable or comma-separated")
    ap.add_argument("--distance", type=int, default=4000, help="move distance (axis units)")
    ap.add_argument("--velocity", type=int, default=0, help="move velocity (0: the axis default)")
    ap.add_argument("--home-velocity", type=int, default=0,
                    help="velocity register for home (0: leave it)")
    ap.add_argument("--jog-velocity", type=int, default=0, help="jog velocity (0: as --velocity)")
    ap.add_argument("--tolerance", type=int, default=2, help="position tolerance")
    ap.add_argument("--beyond", type=int,
                    help="a target the controller refuses or fails on (a device error)")
    ap.add_argument("--fault-command",
                    help="shell command that makes the controller report a fault ({unit}: the "
                         "profile unit), e.g. a simulator's fault injection")
    ap.add_argument("--no-device-error", action="store_true",
                    help="the controller has no error to provoke: ErrorStop is not exercised")
    ap.add_argument("--refused-target", type=int,
                    help="a target beyond the node's configured limit (exception 0x03)")
    ap.add_argument("--expect-homed", action="store_true", help="require the homed bit")
    ap.add_argument("--timeout", type=float, default=20.0, help="seconds per command")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args()
    if args.beyond is None and not args.fault_command and not args.no_device_error:
        ap.error("no device error to provoke, so ErrorStop would not be exercised: give --beyond "
                 "or --fault-command, or --no-device-error for a controller that has none")
    units = [int(u) for arg in args.unit for u in arg.split(",") if u]
    client = ModbusTcpClient(args.host, port=args.port, timeout=5)
    if not client.connect():
        print("cannot connect to %s:%d" % (args.host, args.port))
        return 2
    failed = []
    for unit in units:
        axis = Axis(client, unit, args)
        try:
            axis.run()
        except Failed as e:
            axis.log("FAIL: %s" % e)
            failed.append(unit)
    client.close()
    print("%d axis(es) passed, %d failed%s" % (len(units) - len(failed), len(failed),
                                                (": units " + ",".join(map(str, failed)))
                                                if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
