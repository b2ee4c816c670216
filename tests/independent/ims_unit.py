#!/usr/bin/python3
"""IMS microstepper indexer units on one RS-422 party line, written from the software reference
manual (shared/seeds/003, digest shared/protocols/ims-indexer.md) only.

  ims_unit.py --link PATH [--axes A,B] [--control SOCKET]

Each unit powers up in Party Line mode with its origin at 0 (power-up, p.8), not homed, idle.
Readings of the manual where it leaves room (section numbers are the manual's pages):
- p.10 "Once the Name is received, the target axis will wake-up and start echoing": the name
  character itself is not echoed; the echo runs from the command character up to the LF.
- p.12 RESULT cycle: every command ends with a result; a number (space padded) and CR LF, or a
  bare CR LF when there is no number. So `AR100\n` answers `R100\n\r\n`.
- p.13: a second action command during a completion cycle (an index until it ends, F until
  home is found, M until its ramp ends) is pending: its echo comes back at once (entry), but
  the unit runs nothing else until the cycle ends; then it executes it and sends its CR LF. ESC, ^C and `@` are one-character interrupts seen at any time.
- `@` and ESC are Global (command set): every axis on the line soft/hard stops.
- `]0` reports a limit bit as 1 while that limit switch is active (the switch level, whatever
  the `l` polarity).
- `O` while moving is refused (no change) but still answers CR LF.
- ^C and a power cycle (`power-cycle` on --control, unit_common.Control) do the same (p.8): the
  motion aborts at once, the parameters last saved by `S` (I, V, K here; the factory values until
  an `S`) are loaded, the origin is set to 0; in Party mode nothing is sent (no sign-on, p.10).
  The motor stays where it stopped: the home switch does not move with the origin.
"""
import argparse
import re

import unit_common as uc

NAME_RE = re.compile(rb"[A-Za-z\[\\\]^_`]")


def fmt_number(v, width=7):
    if abs(v - round(v)) < 0.005:
        s = "%d" % round(v)
    else:
        s = "%.2f" % v
    return s.rjust(width).encode()


class Unit:
    def __init__(self, name, bus):
        self.name = name
        self.bus = bus
        self.axis = uc.Axis(home_switch=-1500.0)
        # The parameters last saved by `S` (nonvolatile): the factory values until then.
        self.saved = {"init_vel": 400.0, "slew": 3004.0, "k": (10, 10)}
        self.power_up()

    def power_up(self):
        """^C or a power cycle (p.8): every motion aborts, the saved parameters are loaded, the
        origin is set to 0, then idle. In Party mode there is no sign-on (p.10): nothing goes out
        on the line. The motor stays where it stopped (the switches do not move)."""
        self.axis.power_up(0.0)
        self.init_vel, self.slew = self.saved["init_vel"], self.saved["slew"]
        self.k_up, self.k_down = self.saved["k"]
        self.apply_ramp()
        self.awake = False
        self.skipping = False
        self.line = bytearray()
        self.backlog = bytearray()
        self.pending = None  # an action line waiting for the current motion
        self.homing = None  # None or dict(phase, dir)
        self.const_vel = False
        self.wait_motion = False  # W0 from the host: result held until motion ends
        self.outputs = 0

    def apply_ramp(self):
        # [K] steps per point on a 0-500 point curve: read as a rate; 0 means no ramp.
        self.axis.accel = 2000.0 * self.k_up if self.k_up else 1e9
        self.axis.decel = 2000.0 * self.k_down if self.k_down else 1e9

    # Interrupts (ISR level): seen on every byte, awake or not.
    def interrupt(self, b):
        if b == 0x1B:  # ESC: hard stop, clear the line, drop the pending command
            self.axis.hard_stop()
            self.homing, self.const_vel, self.pending = None, False, None
            self.line.clear()
            self.backlog.clear()
            self.awake = self.skipping = False
            return True
        if b == 0x03:  # ^C: reset as at power-up
            self.power_up()
            return True
        if b == 0x40 and self.axis.moving():  # @ soft stop, cancels a pending command
            self.soft_stop()
        return False

    def soft_stop(self):
        self.axis.stop()
        self.homing, self.const_vel = None, False
        self.pending = None

    def blocked(self):
        return self.pending is not None or self.wait_motion

    def feed(self, b):
        if self.interrupt(b):
            return
        if self.blocked():
            self.backlog.append(b)
            return
        self.take(b)

    def take(self, b):
        if not self.awake and not self.skipping:
            if b == ord(self.name):
                self.awake = True
                self.line.clear()
            elif b != 0x0A:
                self.skipping = True
            return
        if self.skipping:
            if b == 0x0A:
                self.skipping = False
            return
        self.bus.send(bytes([b]))  # echo, up to and including LF
        if b == 0x08:
            if self.line:
                self.line.pop()
            return
        if b != 0x0A:
            if len(self.line) < 12:
                self.line.append(b)
            return
        self.awake = False
        line = bytes(self.line)
        self.line.clear()
        if line[:1] in (b"+", b"-", b"R", b"M", b"F", b"G", b"H") and self.in_completion():
            self.pending = line  # executed when the completion cycle ends
            return
        self.execute(line)

    def in_completion(self):
        """p.13: an index until it ends, F until home is found, M until its ramp ends."""
        a = self.axis
        if self.homing:
            return True
        if self.const_vel:
            return a.mode == "vel" and a.v != a.vmax
        return a.moving()

    def drain(self):
        while self.backlog and not self.blocked():
            self.take(self.backlog.pop(0))

    def result(self, number=None, width=7):
        self.bus.send((fmt_number(number, width) if number is not None else b"") + b"\r\n")

    def execute(self, line):
        uc.wire("%s %r" % (self.name, line))
        if not line:
            self.result()
            return
        cmd = chr(line[0])
        args = line[1:].decode(errors="replace").split()
        try:
            nums = [float(a) for a in args]
        except ValueError:
            nums = []
        d1 = nums[0] if nums else 0.0
        d2 = nums[1] if len(nums) > 1 else 0.0
        a = self.axis
        if cmd == "Z" or cmd == "z":
            self.result(a.position())
        elif cmd == "^":
            self.result(self.status(), 3)
        elif cmd == "]":
            if int(d1) == 0:
                self.result((1 if a.limit_active(1) else 0) | (2 if a.limit_active(-1) else 0), 3)
            else:
                # 1 Home, 16 soft-stop, 32/64 jog, 128 jog speed: inputs idle high (p.50).
                self.result((1 if a.home_input_high() else 0) | 8 | 16 | 32 | 64 | 128, 3)
        elif cmd == "A":
            if int(d1) == 129:
                self.result(7 | self.outputs, 3)
            else:
                self.outputs = int(d1) & 0x38
                self.result()
        elif cmd in "+-":
            dist = d1 if cmd == "+" else -d1
            a.move_to(a.position() + dist, self.slew)
            self.const_vel = False
            self.result()
        elif cmd == "R":
            a.move_to(d1, self.slew)
            self.const_vel = False
            self.result()
        elif cmd == "M":
            if d1 == 0:
                a.stop()
                self.const_vel = False
            else:
                a.run_at(max(-20000.0, min(20000.0, d1)))
                self.const_vel = True
            self.result()
        elif cmd == "F":
            speed = d1 if d1 else self.init_vel
            high = a.home_input_high()
            direction = int(d2) & 1
            sign = (-1 if not high else 1) if direction == 0 else (1 if not high else -1)
            self.homing = {"was_high": high, "sign": sign, "phase": 1}
            a.run_at(sign * speed)
            self.const_vel = False
            self.result()
        elif cmd in "Oo":
            if not a.moving():
                a.set_position(0.0)
            self.result()
        elif cmd == "@":
            if a.moving():
                self.soft_stop()
            self.result()
        elif cmd == "I":
            self.init_vel = max(20.0, min(20000.0, d1))
            self.result()
        elif cmd == "V":
            v = max(20.0, min(20000.0, d1))
            self.slew = 1228800.0 / int(1228800.0 / v)  # the next achievable rate ([V])
            self.result()
        elif cmd == "K":
            self.k_up, self.k_down = int(d1), int(d2)
            self.apply_ramp()
            self.result()
        elif cmd == "W":
            if int(d1) == 0 and a.moving():
                self.wait_motion = True  # result when the index ends
            else:
                self.result()
        elif cmd == "X":
            self.bus.send(b'"32.\r\n')  # Party mode: [X]
        elif cmd == "S":
            # Save the working parameters to nonvolatile memory: a power-up loads them.
            self.saved = {"init_vel": self.init_vel, "slew": self.slew,
                          "k": (self.k_up, self.k_down)}
            self.result()
        else:
            # D E H Y B l S C T d e ... : accepted; the manual defines no error reply.
            self.result()

    def status(self):
        a = self.axis
        v = 0
        if a.moving():
            v |= 1
            if self.const_vel:
                v |= 2
            if self.homing:
                v |= 8
            if (a.mode in ("stop",) or (a.mode == "vel" and abs(a.v) != abs(a.vmax))
                    or (a.mode == "pos" and abs(a.v) < a.vmax)):
                v |= 32
        return v

    def tick(self, now):
        a = self.axis
        a.tick(now)
        h = self.homing
        if h:
            high = a.home_input_high()
            if not a.moving():
                self.homing = None  # stopped by a limit, @ or ESC
            elif h["phase"] == 1 and high != h["was_high"]:
                if high:  # low -> high: found; no decel at the switch ([F] C)
                    a.hard_stop()
                    self.homing = None
                else:  # high -> low: reverse and creep at I until high ([F] D)
                    a.hard_stop()
                    h["phase"] = 2
                    a.run_at(-h["sign"] * self.init_vel)
            elif h["phase"] == 2 and high:
                a.hard_stop()
                self.homing = None
        if not a.moving():
            self.const_vel = False
        if self.wait_motion and not a.moving():
            self.wait_motion = False
            self.result()
            self.drain()
        if self.pending is not None and not self.in_completion():
            line, self.pending = self.pending, None
            self.execute(line)
            self.drain()


class Bus:
    def __init__(self, pty, names):
        self.pty = pty
        self.units = [Unit(n, self) for n in names]

    def send(self, data):
        self.pty.send(data)

    def on_bytes(self, data, now):
        for b in data:
            for u in self.units:
                u.feed(b)

    def on_tick(self, now):
        for u in self.units:
            u.tick(now)

    def control(self, line, now):
        """The test's requests (unit_common.Control); WHO is a party-line name."""
        def power_cycle(who):
            units = [u for u in self.units if who is None or u.name == who]
            if not units:
                return None
            for u in units:
                u.tick(now)  # the motion up to this instant
                was = u.axis.position()
                u.power_up()
                uc.log("ims: %s power-cycled at position %.0f: origin 0, saved parameters "
                       "loaded, no sign-on (party mode)" % (u.name, was))
            return ",".join(u.name for u in units)

        def state():
            return {u.name: (round(u.axis.position()), u.axis.moving()) for u in self.units}
        return uc.control_request(self, line.split(), power_cycle, state)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--axes", default="A,B")
    uc.control_argument(ap)
    args = ap.parse_args()
    names = [n for n in args.axes.split(",") if n]
    for n in names:
        if len(n) != 1 or not NAME_RE.fullmatch(n.encode()):
            raise SystemExit("invalid party-line name %r (p.10)" % n)
    uc.serve(args.link, 9600, lambda pty: Bus(pty, names),
             "ims: units %s on %s" % (",".join(names), args.link), args.control)


if __name__ == "__main__":
    main()
