#!/usr/bin/python3
"""Centent CN0170 two-axis controllers in a daisy chain, written from the CN0170 software
manual (shared/seeds/000, digest shared/protocols/centent-cn0170.md) only.

  centent_unit.py --link PATH [--units 0] [--control SOCKET]

Each unit powers up as after a reset (p.1): waiting for the auto-baud <CR>. The first character
it receives must be CR; it then answers `U<n>` (one line per unit, in chain order). Anything
else first leaves it at a wrong baud rate: it understands nothing and answers nothing until it
is reset (the manual's only recovery). Positions come up at 0 and are not homed; mode M1 (first
power-up); outputs off.
Readings of the manual where it leaves room:
- Reply lines end in CR (the only terminator shown, `U"n"<CR>`, p.1).
- Position query replies use the form of the Query Position section (p.35): `X=00C0E6B6h` at
  rest, `X+…h` / `X-…h` while moving CW / CCW; 8 hex digits, raw 1/1024 full steps, unsigned.
  Hex replies put a 0 in front when the first digit is a letter (`YV=0D485h`, p.30), as hex
  input must (p.2).
- Unit 0 sends no prefix; unit n (1-9) puts its digit straight before the message (p.13).
- At power-up the selected unit number is 0 (the manual does not say; the register's reset
  value).
- A second point-to-point move for an axis waits until that axis's current move ends (p.21,
  "the next X move" waits; instructions run through the Immediate Queue). Speed control
  (`X++`) runs "until the next instruction" (p.18), which then starts at once: a move from speed
  control decelerates and continues to its target.
- `Q` decelerates both axes of the selected unit (p.12: "abandons the current moves").
- Home (p.18, 38): with `XH-` the switch is at the 0 end: the axis runs CCW at its velocity
  until the HME input is active, decelerates, then creeps CW one increment (`XR`) per 1/256 s
  until the input releases; the position register is then 0. The switch sits 3000 full steps
  CCW of where the axis powered up.
- Velocity/acceleration defaults (undocumented) are the Getting Started values: XV=200,2000,
  XA=10000.
- `--power-up-mode 3`: the unit powers up in Operate Mode (M3), as one does whose last mode
  before power-off was M3 (power-up resumes it, p.5). Read: instructions the host sends in M3
  are discarded (a program would run them on `G`); only `M?` and the mode changes `M1`, `M2`,
  `M3` are obeyed.
- A power cycle (`power-cycle [N]` on --control, unit_common.Control; default the whole chain):
  the motors stop at once, queues and the selection are gone, outputs off, the mode in effect at
  power-off kept (p.5), motor parameters kept (battery-backed, p.7), position registers 0; the
  unit waits for its auto-baud CR again and answers it `U<n>` (p.1); any other first character
  leaves it at a wrong baud rate until the next power cycle. The 2-3 s before RTS goes active
  are not modelled (a PTY has no RTS): the unit listens at once.
"""
import argparse
import re

import unit_common as uc

RAW = 1024.0  # position counts per full step
SPAN = 1 << 32


def hexval(v, digits):
    s = "%0*X" % (digits, v)
    return ("0" + s if s[0] in "ABCDEF" else s) + "h"


def number(text, raw_scale, resolution):
    """Decimal (rounded to the resolution) or hex raw (`0FA000H`) -> raw register value."""
    if text.endswith("H"):
        return int(text[:-1], 16)
    v = float(text)
    return int(round(v * raw_scale / resolution)) * resolution if resolution else v * raw_scale


class Motor:
    def __init__(self, letter):
        self.letter = letter
        self.axis = uc.Axis(limit_neg=-1e12, limit_pos=1e12, home_switch=-3000.0 * RAW)
        self.base, self.vmax = 200.0, 2000.0  # full steps/s
        self.accel_raw = int(10000 / 64)
        self.axis.accel = self.axis.decel = self.accel_raw * 64 * RAW
        self.queue = []  # point-to-point moves waiting for the current one
        self.speed = False
        self.home_dir = -1
        self.resolution = 1
        self.homing = None
        self.trigger = False

    def raw_position(self):
        return int(round(self.axis.position())) % SPAN

    def direction(self):
        if not self.axis.moving():
            return "="
        return "+" if self.axis.v >= 0 else "-"

    def home_active(self):
        return self.axis.home_input_high()  # active on the 0 side of the switch

    def busy(self):
        return self.axis.moving() and not self.speed

    def start(self, kind, value):
        a = self.axis
        self.speed = False
        self.homing = None
        if kind == "abs":
            a.move_to(value, self.vmax * RAW)
        elif kind == "rel":
            a.move_to(a.position() + value, self.vmax * RAW)
        elif kind == "speed":
            self.speed = True
            a.run_at(value * RAW)
        elif kind == "home":
            self.homing = {"phase": 1}
            a.run_at(self.home_dir * self.vmax * RAW)

    def command_move(self, kind, value):
        if self.busy() or self.queue:
            self.queue.append((kind, value))
        else:
            self.start(kind, value)

    def quit(self):
        self.queue.clear()
        self.homing = None
        self.speed = False
        self.axis.stop()

    def kill(self):
        self.queue.clear()
        self.homing = None
        self.speed = False
        self.axis.hard_stop()

    def tick(self, now, unit):
        a = self.axis
        was = a.moving()
        a.tick(now)
        h = self.homing
        if h:
            if h["phase"] == 1 and self.home_active():
                h["phase"] = 2
                a.stop()
            elif h["phase"] == 2 and not a.moving():
                h["phase"] = 3
                a.run_at(-self.home_dir * 256.0 / self.resolution * RAW)
            elif h["phase"] == 3 and not self.home_active():
                a.hard_stop()
                a.set_position(0.0)
                self.homing = None
        if was and not a.moving() and not self.homing:
            if self.trigger:
                unit.say(self.letter + "P")
            if self.queue:
                self.start(*self.queue.pop(0))


class Unit:
    def __init__(self, number, mode=1):
        self.number = number
        self.motors = {"X": Motor("X"), "Y": Motor("Y")}
        self.power_up(mode)

    def power_up(self, mode):
        """Power applied (p.1, 5, 7): waits for the auto-baud CR; the mode in effect at power-off
        (`mode`), outputs off (p.42), motions and queues gone. Motor parameters are
        battery-backed (p.7) and stay. The position registers come up at 0 (the manual does not
        say; the register's reset value); the motors stay where they stopped."""
        self.baud_state = "waiting"  # waiting for the auto-baud CR, "ok" or "wrong"
        for motor in self.motors.values():
            motor.kill()
            motor.axis.power_up(0.0)
        self.mode = mode
        self.outputs = {3: 0, 4: 0}
        self.replies = []

    def say(self, text):
        prefix = "" if self.number == 0 else str(self.number)
        self.replies.append(prefix + text)

    def execute(self, text):
        """One instruction (terminators stripped)."""
        if self.baud_state != "ok":
            return  # not auto-bauded (or at a wrong rate): it understands nothing
        s = text.replace(" ", "")
        up = s.upper()
        m = self.motors
        if up == "M?":
            self.say("M%d" % self.mode)
            return
        if re.fullmatch(r"M[123]", up):
            self.mode = int(up[1])
            return
        if self.mode == 3:
            return  # discarded: in Operate Mode the program, not the host, drives the unit
        if re.fullmatch(r"M1\\[+-]", up):
            return
        if up == "Q":
            for motor in m.values():
                motor.quit()
            return
        if up == "K":
            for motor in m.values():
                motor.kill()
            self.outputs = {3: 0, 4: 0}
            return
        if self.mode == 2:
            return  # stored, not run (program download is not emulated further)
        mm = re.fullmatch(r"([XY])P\?", up)
        if mm:
            motor = m[mm.group(1)]
            self.say("%s%s%s" % (motor.letter, motor.direction(), hexval(motor.raw_position(), 8)))
            return
        mm = re.fullmatch(r"([XY])V\?", up)
        if mm:
            self.say("%sV=%s" % (mm.group(1), hexval(int(abs(m[mm.group(1)].axis.v) / RAW * 4),
                                                      4)))
            return
        mm = re.fullmatch(r"([XY])A\?", up)
        if mm:
            self.say("%sA=%s" % (mm.group(1), hexval(m[mm.group(1)].accel_raw, 4)))
            return
        mm = re.fullmatch(r"P([1-4])\?", up)
        if mm:
            n = int(mm.group(1))
            self.say("P%d=%d" % (n, self.outputs.get(n, 0)))
            return
        mm = re.fullmatch(r"A(\\[XY]|[12])\?", up)
        if mm:
            self.say("A%s=80h" % mm.group(1))  # inputs at mid-scale
            return
        mm = re.fullmatch(r"([XY])C\?", up)
        if mm:
            self.say("%sC=L" % mm.group(1))
            return
        if up == "P?":
            self.say("P= 00h")
            return
        mm = re.fullmatch(r"P([34])=([01])", up)
        if mm:
            self.outputs[int(mm.group(1))] = int(mm.group(2))
            return
        num = r"(\d*\.?\d*|[0-9A-F]+H)"
        mm = re.fullmatch(r"([XY])=" + num, s if s.endswith("H") else up)
        if mm and mm.group(2):
            m[mm.group(1)].command_move("abs", number(mm.group(2), RAW, 1))
            return
        mm = re.fullmatch(r"([XY])([+-])" + num, s if s.endswith("H") else up)
        if mm and mm.group(3):
            v = number(mm.group(3), RAW, 1)
            m[mm.group(1)].command_move("rel", v if mm.group(2) == "+" else -v)
            return
        mm = re.fullmatch(r"([XY])(\+\+|--)(\d*\.?\d*)", up)
        if mm:
            motor = m[mm.group(1)]
            v = float(mm.group(3)) if mm.group(3) else motor.vmax
            v = min(v, 16383.75)
            motor.queue.clear()
            motor.start("speed", v if mm.group(2) == "++" else -v)
            return
        mm = re.fullmatch(r"(X|Y|XY)H", up)
        if mm:
            for letter in mm.group(1):
                m[letter].command_move("home", 0)
            return
        mm = re.fullmatch(r"([XY])H([+-])", up)
        if mm:
            m[mm.group(1)].home_dir = 1 if mm.group(2) == "+" else -1
            return
        mm = re.fullmatch(r"([XY])R(1|2|10|125)", up)
        if mm:
            m[mm.group(1)].resolution = int(mm.group(2))
            return
        mm = re.fullmatch(r"([XY])V=(\d*\.?\d*)?(?:,(\d*\.?\d*))?", up)
        if mm and (mm.group(2) or mm.group(3)):
            motor = m[mm.group(1)]
            if mm.group(2):
                motor.base = round(float(mm.group(2)) * 4) / 4
            if mm.group(3):
                vmax = int(float(mm.group(3)) * 4) / 4  # .25 resolution: 3333.33 -> 3333.25
                if vmax <= 0 or vmax > 16383.75:
                    self.reject(text)
                    return
                motor.vmax = vmax
                if motor.axis.mode == "pos":
                    motor.axis.vmax = vmax * RAW
            return
        mm = re.fullmatch(r"([XY])A=(\d+\.?\d*|[0-9A-F]+H)", s.upper() if not s.endswith("H")
                          else s)
        if mm:
            t = mm.group(2)
            raw = int(t[:-1], 16) if t.endswith("H") else int(float(t) / 64 + 0.5)
            if raw <= 0 or raw > 0xFFFF:
                self.reject(text)
                return
            motor = m[mm.group(1)]
            motor.accel_raw = raw
            motor.axis.accel = motor.axis.decel = raw * 64 * RAW
            return
        mm = re.fullmatch(r"([XY])P=(\d*\.?\d*|[0-9A-F]+H)", s if s.endswith("H") else up)
        if mm and mm.group(2):
            motor = m[mm.group(1)]
            if not motor.axis.moving():
                motor.axis.set_position(number(mm.group(2), RAW, 1))
            return
        mm = re.fullmatch(r"([XY])P([+-])", up)
        if mm:
            m[mm.group(1)].trigger = mm.group(2) == "+"
            return
        if re.fullmatch(r"([XY])([LBMV])[+-]|([XY])C(\\[LPU]|\d{1,2})|([XY])I=\d+|XYV=.*|"
                        r"P1\\[GI]|[XY]J[0-7]|G\d*|H|T=.*|D=.*", up):
            return  # parameters this emulation accepts without modelling them
        self.reject(text)

    def reject(self, text):
        self.say('"%s" ?' % text)

    def tick(self, now):
        for motor in self.motors.values():
            motor.tick(now, self)


class Chain:
    def __init__(self, pty, numbers, mode):
        self.pty = pty
        self.units = [Unit(n, mode) for n in numbers]
        self.selected = 0
        self.buf = bytearray()

    def on_bytes(self, data, now):
        for b in data:
            waiting = [u for u in self.units if u.baud_state == "waiting"]
            if waiting:
                if b == 0x0D:
                    for u in waiting:  # the CR is forwarded; each unit measures it
                        u.baud_state = "ok"
                        u.say("U%d" % u.number if u.number else "U0")
                else:
                    for u in waiting:
                        u.baud_state = "wrong"
                    uc.log("centent: first character 0x%02x is not CR: wrong baud rate" % b)
                if len(waiting) == len(self.units):
                    continue
            if all(u.baud_state == "wrong" for u in self.units):
                continue
            if b in (0x0D, 0x0A, 0x3B):
                if self.buf:
                    self.line(self.buf.decode(errors="replace"))
                    self.buf.clear()
            elif len(self.buf) < 256:
                self.buf.append(b)

    def line(self, text):
        uc.wire(text)
        s = text.strip()
        mm = re.fullmatch(r"\.U(\d)", s.replace(" ", "").upper())
        if mm:
            self.selected = int(mm.group(1))
            return
        if s.replace(" ", "").upper() == ".U?":
            for u in self.units:
                u.say("[U%d]" % u.number)
            return
        unit = next((u for u in self.units if u.number == self.selected), None)
        if unit is None:
            return  # leaves the last unit's Port B
        if s.upper() == "K":
            for u in self.units:
                u.execute("K")
            return
        unit.execute(s)

    def on_tick(self, now):
        for u in self.units:
            u.tick(now)
            for r in u.replies:
                self.pty.send(r.encode() + b"\r")
            u.replies.clear()

    def control(self, line, now):
        """The test's requests (unit_common.Control); WHO is a unit number (default: the chain's
        supply, every unit)."""
        def power_cycle(who):
            units = [u for u in self.units if who is None or str(u.number) == who]
            if not units:
                return None
            for u in units:
                u.tick(now)  # the motion up to this instant
                was = {k: m.axis.position() for k, m in u.motors.items()}
                u.power_up(u.mode)
                uc.log("centent: unit %d power-cycled at X %.0f Y %.0f: waiting for the "
                       "auto-baud CR, mode M%d kept, positions 0" % (u.number, was["X"],
                                                                      was["Y"], u.mode))
            if len(units) == len(self.units):
                self.buf.clear()
                self.selected = 0
            return ",".join(str(u.number) for u in units)

        def state():
            out = {}
            for u in self.units:
                for k, m in u.motors.items():
                    raw = m.raw_position()
                    out["%d%s" % (u.number, k)] = (raw - SPAN if raw >= SPAN // 2 else raw,
                                                   m.axis.moving())
            return out
        return uc.control_request(self, line.split(), power_cycle, state)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--units", default="0")
    ap.add_argument("--power-up-mode", type=int, default=1, choices=[1, 3])
    uc.control_argument(ap)
    args = ap.parse_args()
    numbers = [int(n) for n in args.units.split(",") if n]
    uc.serve(args.link, 9600, lambda pty: Chain(pty, numbers, args.power_up_mode),
             "centent: units %s on %s" % (args.units, args.link), args.control)


if __name__ == "__main__":
    main()
