#!/usr/bin/python3
"""Whedco CMC-0 coordinated motion controllers (with CMC-2 servo axes) on one serial line,
written from the CMC manual excerpt (shared/seeds/004, digest shared/protocols/whedco-cmc.md)
only.

  whedco_unit.py --link PATH [--units 4] [--axes XY] [--baud 38400] [--non-echo]
                 [--control SOCKET]

The excerpt lacks sections 1-4 (frame format, reply layouts, status words), so this module has
to pick readings where the manual is silent; each is a guess a firmware engineer of a 1990s
terminal-oriented controller would plausibly make, and each is listed here:
- Prompt: after a line is done the controller sends `*` (the examples' "stars are the
  responses", each host line follows a `*`), with nothing after it: a terminal shows the next
  typed line on the same row as the star, as the examples print `*4AEX1`.
- Echo mode (factory, SW2-5): once its address character arrives, the controller echoes the
  line as typed, address included (the examples' `*4AEX1`); the CR comes back as CR LF. A query
  then sends its value and CR LF, then the prompt: `4RPX\r` answers `4RPX\r\n1234\r\n*`.
  Non-echo mode (`--non-echo`): no echo; `4RPX\r` answers `1234\r\n*`, a command `*`.
- A line for another address: silence. A command this module does not know: `?` CR LF, then
  the prompt.
- Positions (`RPa`, `RCa`, `FEa`) and `?` read-backs are decimal user units (position pulses /
  UR), no sign for positive values, up to 4 decimals only when UR makes them fractional.
- `RS`/`RSa` (4.3.1 missing): a decimal bit field laid out like the unit's hardware status
  outputs in pin order (A.2: CMC-0 P1-15 Set Pt A, 16 Set Pt B, 17 Busy, 18 Fault; axis P1-16,
  17 set points, 18 Busy, 19 Fault): bit 0 set point A, 1 set point B, 2 busy, 3 fault; RS bit 7
  Memory Lost. `--status-bits busy-first` presents the other layout a firmware might use (bit 0
  busy, bit 1 fault, axis bit 4 home input), the one config/models/whedco-cmc*.yaml assumes.
  `--status-bits busy-first-homed` is that layout with more axis states: bit 2 homed (set by a
  completed home search), bit 9 in position (at rest), bit 10 servo on; a homed axis at rest on
  its switch reads 0x0614 = 1556, bit 2 set without bit 0, as a busy word of the outputs layout
  would.
- Non-echo `FC`: 8 Unit Functional, 0 Power Failure, 1 Axis Initialized, 2 Arithmetic
  Overflow (the excerpt lists these names without their numbers); axis codes as section 6.1.2.
- Power-up: the CMC-0 and every axis report Power Failure (6.1.2: "the normal power-up fault
  condition"); `WB` clears it. Run, jog and home commands are ignored (prompt only) while the
  CMC-0 or the axis is faulted; the axes hold position, enabled.
- Jog (5.10.2): `AEa1` runs the axis at FS x LM; `AEa0` freezes the command position at once
  (the equation stops adding); `HT` decelerates every axis at its AC rate.
- Home (`SHZa`/`SHPannn`, 5.5; `SI…`/`SB…` alike): runs as a jog in the direction of LM's sign until the home input is
  active, then sets the position to 0 (or nnn) and disables the equation. The home switch is 3000
  position pulses on the negative side of the power-up position. Ignored while the axis moves.
- `RAd` answers the counts as a decimal number; `RDI`/`RDB` a decimal bit mask (bit n-1 = pin
  or variable n); all 0 here.
- Trajectory velocity default 0 is below the 10 pp/s minimum: moves then run at 10 pp/s.
- A power cycle (`power-cycle [ADDRESS]` on --control, unit_common.Control; default every unit):
  as at power-up, Power Failure on the CMC-0 and every axis until `WB`; parameters kept
  (battery-backed); motion stops at once; positions count from 0 where the motors stopped; a
  line being received is lost.
"""
import argparse
import re

import unit_common as uc

AXIS_FAULTS = {0: "Power Failure", 3: "Excessive Following Error", 6: "Lost Enable",
               7: "Position Register Overflow", 8: "Unit Functional"}
SYS_FAULT_CODES = {"Unit Functional": 8, "Power Failure": 0, "Axis Initialize": 1,
                   "Arithmetic Overflow": 2}
REG_MAX = 8388607


def fmt_user(pp, ur):
    v = pp / ur
    if abs(v - round(v)) < 1e-9:
        return "%d" % round(v)
    return ("%.4f" % v).rstrip("0").rstrip(".")


class ServoAxis:
    def __init__(self, letter):
        self.letter = letter
        self.axis = uc.Axis(accel=80000.0, limit_neg=-1e9, limit_pos=1e9, home_switch=-3000.0)
        self.ur = 1
        self.am = 0  # absolute-move register, pp
        self.im = 0
        self.ac = 80000.0
        self.fs = 0.0  # pp/s
        self.lm = 0.0
        self.li = "F"
        self.ae = False
        self.fault = 0  # Power Failure
        self.homing = False
        self.homed = False
        self.home_value = 0

    def moving(self):
        return self.axis.moving()

    def position(self):
        return round(self.axis.position())


class Controller:
    def __init__(self, address, letters, echo, status_bits):
        self.address = address
        self.status_bits = status_bits
        self.echo = echo
        self.axes = {k: ServoAxis(k) for k in letters}
        self.fault = "Power Failure"
        self.vx = 0.0  # pp/s, pair XY
        self.vw = 0.0
        self.variables = {}

    def faulted(self, ax=None):
        return self.fault != "Unit Functional" or (ax is not None and ax.fault != 8)

    def pair_velocity(self, letter):
        v = self.vx if letter in "XY" else self.vw
        return max(v, 10.0)

    def reply(self, line):
        """Executes one line (address stripped); returns the data line or None."""
        s = line.strip().upper()
        m = re.fullmatch(r"([A-Z]+?)([WXYZ]?)\?", s)
        if m and s not in ("RS?",):
            return self.readback(m.group(1), m.group(2))
        if s == "FC":
            return self.fault if self.echo else "%d" % (
                SYS_FAULT_CODES.get(self.fault, 8) + self.axis_fault_byte())
        m = re.fullmatch(r"FC([WXYZ])", s)
        if m and m.group(1) in self.axes:
            code = self.axes[m.group(1)].fault
            return AXIS_FAULTS[code] if self.echo else "%X" % code
        if s == "RS":
            busy = any(ax.moving() for ax in self.axes.values())
            return "%d" % self.status_word(busy, self.faulted(), False, None)
        m = re.fullmatch(r"(RS|RP|RC|FE)([WXYZ])", s)
        if m and m.group(2) in self.axes:
            ax = self.axes[m.group(2)]
            if m.group(1) == "RS":
                return "%d" % self.status_word(ax.moving(), ax.fault != 8,
                                               ax.axis.home_input_high(), ax)
            if m.group(1) == "FE":
                return "0"
            return fmt_user(ax.position(), ax.ur)
        if re.fullmatch(r"RA[1-4]", s):
            return "0"  # analog input counts (no voltage applied)
        if s in ("RDI", "RDB"):
            return "0"  # bit masks, decimal (layout of 4.4.3 missing)
        if s == "WB":
            self.fault = "Unit Functional"
            for ax in self.axes.values():
                ax.fault = 8
            return None
        if s == "HT":
            for ax in self.axes.values():
                ax.ae = ax.homing = False
                ax.axis.decel = ax.ac
                ax.axis.stop()
            return None
        if s == "EB":
            return None
        m = re.fullmatch(r"IT([WXYZ])", s)
        if m and m.group(1) in self.axes:
            self.fault = "Axis Initialize"
            return None
        num = r"([+-]?(?:\d+\.?\d*|\.\d+))"
        m = re.fullmatch(r"(AM|IM|AC|UR)([WXYZ])" + num, s)
        if m and m.group(2) in self.axes:
            ax = self.axes[m.group(2)]
            v = float(m.group(3))
            if m.group(1) == "UR":
                ax.ur = max(1, min(10000, int(v)))
            elif m.group(1) == "AM":
                ax.am = max(-REG_MAX, min(REG_MAX, round(v * ax.ur)))
            elif m.group(1) == "IM":
                ax.im = max(-65535, min(65535, round(v * ax.ur)))
            else:
                ax.ac = max(80000.0, min(6500000.0, v * ax.ur))
                ax.axis.accel = ax.axis.decel = ax.ac
            return None
        m = re.fullmatch(r"V([XW])" + num, s)
        if m:
            ur = self.axes.get(m.group(1), next(iter(self.axes.values()))).ur
            v = max(0.0, min(655350.0, float(m.group(2)) * ur))
            if m.group(1) == "X":
                self.vx = v
            else:
                self.vw = v
            return None
        m = re.fullmatch(r"FS([WXYZ])" + num, s)
        if m and m.group(1) in self.axes:
            ax = self.axes[m.group(1)]
            pp = float(m.group(2)) * ax.ur
            ax.fs = max(200.0, min(51200.0, round(pp / 200.0) * 200.0))  # steps of 200 pp/s
            self.update_jog(ax)
            return None
        m = re.fullmatch(r"LM([WXYZ])N" + num, s)
        if m and m.group(1) in self.axes:
            ax = self.axes[m.group(1)]
            ax.lm = max(-100.0, min(100.0, float(m.group(2))))
            self.update_jog(ax)
            return None
        m = re.fullmatch(r"LI([WXYZ])(F|E[1-3])", s)
        if m and m.group(1) in self.axes:
            self.axes[m.group(1)].li = m.group(2)
            return None
        m = re.fullmatch(r"AE([WXYZ])([01])", s)
        if m and m.group(1) in self.axes:
            ax = self.axes[m.group(1)]
            if m.group(2) == "1":
                if not self.faulted(ax):
                    ax.ae = True
                    self.update_jog(ax)
            else:
                ax.ae = ax.homing = False
                ax.axis.hard_stop()
            return None
        m = re.fullmatch(r"(RA|RI)([WXYZ]{1,4})", s)
        if m and all(k in self.axes for k in m.group(2)):
            self.run(m.group(1), m.group(2))
            return None
        m = re.fullmatch(r"S([HIB])([ZP])([WXYZ])" + num + "?", s)
        if m and m.group(3) in self.axes and (m.group(2) == "Z") == (m.group(4) is None):
            # Home, index and home-then-index searches: the index pulse is taken as arriving
            # at the home edge (one encoder, one switch in this emulation).
            ax = self.axes[m.group(3)]
            if not ax.moving() and not self.faulted(ax):
                ax.homing = True
                ax.homed = False
                ax.home_value = round(float(m.group(4)) * ax.ur) if m.group(4) else 0
                if ax.axis.home_input_high():
                    self.home_found(ax)
                else:
                    ax.axis.run_at(ax.fs * ax.lm)
            return None
        m = re.fullmatch(r"(STZ|STP)([WXYZ])" + num + "?", s)
        if m and m.group(2) in self.axes:
            ax = self.axes[m.group(2)]
            if not ax.moving():
                value = float(m.group(3)) * ax.ur if m.group(1) == "STP" and m.group(3) else 0
                ax.axis.set_position(round(value))
            return None
        m = re.fullmatch(r"(NO|PO)([WXYZ])" + num, s)
        if m or re.fullmatch(r"(WR|DF|PC|PS)[WXYZ][01]|(GN|ZR|PL|FF|DB|IB|PB|ER|CT|LD)[WXYZ]\d+|"
                             r"PE[01]|UE[01]|DG[01]|EL[WXYZ].*|VO[XW].*", s):
            return None
        m = re.fullmatch(r"V([0-9A-F])=" + num, s)
        if m:
            self.variables[m.group(1)] = int(float(m.group(2)))
            return None
        m = re.fullmatch(r"V([0-9A-F])=\?", s)
        if m:
            return "%d" % self.variables.get(m.group(1), 0)
        return "?"

    def status_word(self, busy, fault, home, ax):
        if self.status_bits.startswith("busy-first"):
            word = (1 if busy else 0) | (2 if fault else 0) | (16 if home else 0)
            if self.status_bits == "busy-first-homed" and ax is not None:
                word |= (4 if ax.homed else 0) | (0 if busy else 0x200) | 0x400
            return word
        return (4 if busy else 0) | (8 if fault else 0)

    def readback(self, name, letter):
        ax = self.axes.get(letter) if letter else None
        if name in ("AM", "IM", "AC", "UR", "FS") and ax:
            v = {"AM": ax.am, "IM": ax.im, "AC": ax.ac, "UR": ax.ur, "FS": ax.fs}[name]
            return fmt_user(v, 1 if name == "UR" else ax.ur)
        if name == "V" and letter in ("X", "W"):
            ur = self.axes.get(letter, next(iter(self.axes.values()))).ur
            return fmt_user(self.vx if letter == "X" else self.vw, ur)
        return "?"

    def update_jog(self, ax):
        if ax.ae and not ax.homing:
            ax.axis.run_at(ax.fs * ax.lm)

    def run(self, kind, letters):
        moves = []
        for k in letters:
            ax = self.axes[k]
            if self.faulted(ax) or (ax.moving() and not ax.ae):
                return  # ignored
            start = ax.position()
            target = ax.am if kind == "RA" else start + ax.im
            moves.append((ax, start, target))
        longest = max((abs(t - s) for _, s, t in moves), default=0)
        for ax, start, target in moves:
            if abs(target) > REG_MAX:
                ax.fault = 7
                self.fault = "%s Faulted" % ax.letter
                continue
            v = self.pair_velocity(ax.letter)
            if len(moves) > 1 and longest:
                v = v * abs(target - start) / longest  # interpolated: all finish together
            ax.ae = False
            ax.axis.move_to(target, max(v, 1.0))

    def home_found(self, ax):
        ax.axis.hard_stop()
        ax.axis.set_position(ax.home_value)
        ax.homing = ax.ae = False
        ax.homed = True

    def axis_fault_byte(self):
        v = 0
        for i, k in enumerate("XYWZ"):
            ax = self.axes.get(k)
            if ax and ax.fault != 8:
                v |= 1 << i | 1 << (i + 4)
        return v

    def power_up(self):
        """Power applied (6.1.2): the CMC-0 and every axis report Power Failure until `WB`;
        parameters and profiles stay (battery-backed RAM, 5.3.1); any motion stops at once (jog
        equations off, searches abandoned, not homed); the position counters start from 0 where
        the motors stopped (the excerpt does not say; the counters' reset value)."""
        self.fault = "Power Failure"
        for ax in self.axes.values():
            ax.fault = 0
            ax.ae = ax.homing = ax.homed = False
            ax.axis.power_up(0.0)

    def tick(self, now):
        for ax in self.axes.values():
            ax.axis.tick(now)
            if ax.homing and ax.axis.home_input_high():
                self.home_found(ax)
            if abs(ax.axis.position()) > REG_MAX and ax.fault == 8:
                ax.axis.hard_stop()
                ax.fault = 7
                self.fault = "%s Faulted" % ax.letter


class Line:
    def __init__(self, pty, controllers):
        self.pty = pty
        self.controllers = {c.address: c for c in controllers}
        self.buf = bytearray()
        self.addressed = None

    def on_bytes(self, data, now):
        for b in data:
            ch = chr(b)
            if not self.buf and self.addressed is None:
                if b in (0x0D, 0x0A):
                    continue
                self.addressed = self.controllers.get(ch)
                self.buf.append(b)
                if self.addressed and self.addressed.echo:
                    self.pty.send(bytes([b]))
                continue
            if b == 0x0D:
                self.end_line()
                continue
            if b == 0x0A:
                continue
            self.buf.append(b)
            if self.addressed and self.addressed.echo:
                self.pty.send(bytes([b]))

    def end_line(self):
        text = self.buf.decode(errors="replace")
        c = self.addressed
        self.buf.clear()
        self.addressed = None
        if c is None:
            return
        body = text[1:]
        uc.wire(text)
        out = "\r\n" if c.echo else ""
        if "!" in body:
            return self.pty.send((out + "*").encode())  # the whole line is ignored (5.17)
        data = c.reply(body)
        if data is not None:
            out += data + "\r\n"
        self.pty.send((out + "*").encode())

    def on_tick(self, now):
        for c in self.controllers.values():
            c.tick(now)

    def control(self, line, now):
        """The test's requests (unit_common.Control); WHO is a unit address (default: every unit
        on the line)."""
        def power_cycle(who):
            units = [c for a, c in self.controllers.items() if who is None or a == who]
            if not units:
                return None
            for c in units:
                c.tick(now)  # the motion up to this instant
                was = " ".join("%s %d" % (k, ax.position()) for k, ax in c.axes.items())
                c.power_up()
                uc.log("whedco: unit %s power-cycled at %s: Power Failure until WB" %
                       (c.address, was))
                if self.addressed is c:  # the line it was hearing is lost
                    self.buf.clear()
                    self.addressed = None
            return ",".join(c.address for c in units)

        def state():
            return {c.address + k: (float(fmt_user(ax.position(), ax.ur)), ax.moving())
                    for c in self.controllers.values() for k, ax in c.axes.items()}
        return uc.control_request(self, line.split(), power_cycle, state)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--units", default="4")
    ap.add_argument("--axes", default="XY")
    ap.add_argument("--baud", type=int, default=38400)
    ap.add_argument("--non-echo", action="store_true", help="SW2-5 set to non-echo")
    ap.add_argument("--status-bits", default="outputs", choices=["outputs", "busy-first", "busy-first-homed"])
    uc.control_argument(ap)
    args = ap.parse_args()
    pty = uc.Pty(args.link, args.baud)
    controllers = [Controller(a, args.axes, not args.non_echo, args.status_bits)
                   for a in args.units.split(",") if a]
    line = Line(pty, controllers)
    uc.log("whedco: units %s axes %s %s at %d baud on %s" % (
        args.units, args.axes, "non-echo" if args.non_echo else "echo", args.baud, args.link))
    uc.run(pty, uc.heard_only_at(pty, args.baud, "unit", line.on_bytes), line.on_tick,
           control=uc.Control.open(args.control, line))


if __name__ == "__main__":
    main()
