#!/usr/bin/python3
"""Parker Compumotor 6K2/6K4 motion controller on its RS-232 port, written from the 6K-family
command language as documented in the Gem6K (Gemini GV6K/GT6K) Command Reference, which
shares the 6K's communication commands (ERRLVL, EOT, ERRBAD, ERROK...), and from what two
public EPICS drivers for real 6K units read off the wire (see "Sources"). Nothing here is taken
from sim/, drivers/ or config/.

  parker6k_unit.py --link PATH [--axes 2] [--baud 9600] [--home-zeroes-encoder]
                   [--log first|all|none] [--self-test]

Facts from the command reference:
- Responses: BOT characters, `*`, the response text, EOT characters. EOT default 13,0,0 (a CR
  alone). A response of several lines ends each line with EOL and the last one with EOT.
- ERRLVL default 4 on RS-232. At level 4, a command without error is followed by the ERROK
  prompt: CR, LF, `>`, space. A command in error sends BOT, CR, LF, `*`, the error message,
  EOT, then the ERRBAD prompt (default 13,10,63,32: CR, LF, `?`, space). Up to 4 prompt
  characters; 0 (and 256) send nothing.
- A parameter command without a parameter reports its value (`ERRBAD` -> `*ERRBAD13,10,63,32`).
- TAS (from the drivers' bit tables, bit 1 first, 32 bits in groups of 4 joined by `_`:
  `*1TAS0000_0000_0000_0000_0000_0000_0000_0000`): 1 moving, 2 direction (1 = negative),
  3 accelerating, 4 at velocity, 5 home successful, 6 absolute mode (MA1), 7 continuous mode
  (MC1), 8 jog mode, 9 joystick, 12 stall, 13 drive shut down, 14 drive fault, 15 positive
  and 16 negative hardware limit hit, 17 positive and 18 negative software limit hit,
  23 position error, 24 in target zone.
- The drivers send `ECHO0` ("echo must be off") and `COMEXC1` first, `1TAS`, `1TPC`, `1TPE`,
  `1DRIVE1`, `1D<steps>` then `1GO`, `!K`; replies start with `*` and repeat the command:
  `1TPC` -> `*1TPC+0`. parker6k: "The P6K will send back a command with a \\r\\r\\n> " (response
  CR, then the prompt) and an error "with a ? prompt afterwards"; a GO refused for a shut-down
  drive contains "DRIVE SHUTDOWN"; "INVALID CONDITIONS FOR COMMAND" follows a move into an
  active limit.

Readings chosen where the pages found are silent:
- Power-up: ECHO1 (every received character, CR and LF included, goes back at once),
  COMEXC0, ERRLVL4, EOT 13,0,0, EOL 13,10,0, BOT 0,0,0, ERROK 13,10,62,32, ERRBAD
  13,10,63,32; drives disabled (DRIVE00: TAS bit 13 set), not homed, MA0 (incremental), MC0
  (preset), positions 0, no power-up banner. SCALE0 only: distances and positions in steps
  (DRES 25000 steps/rev, ERES 4000 counts/rev), V in rev/s (default 1), A and AD in rev/s^2
  (default 10), HOMV 1 rev/s. SCALE (and any command not listed below) is unknown here.
- A command line ends at CR or LF; an empty line does nothing (no prompt). `:` separates
  commands on a line; the prompt (ERROK, or ERRBAD if any command failed) follows the line's
  last command. Blanks are ignored; a `;` starts a comment.
- COMEXC0: after a GO or HOM, the following lines wait in the buffer until that motion ends
  (their echo is immediate, their responses come after). A line starting with `!` runs at
  once. S and K (immediate or not, once executed) discard the waiting lines (COMEXS0).
- Axis forms: `1TPC`, `1D1000`, `1GO`, `1DRIVE1`, `1S`, `1K`, `1HOM1`; all-axes forms
  `TPC` -> `*TPC+0,+0`, `D1000,-500` (an empty field leaves an axis unchanged), binary
  `DRIVE11`/`GO1X`/`MA01` (X = unchanged / not selected), `GO`, `S`, `K` alone = all axes.
  All-axes TAS answers one line per axis: `*TAS<axis 1>,` EOL `*<axis 2>` EOT.
- Positions TPC/TPE: signed integers, `%+d`. D, LSPOS, LSNEG report `%+d`; V, A, AD, HOMV
  `%.4f`; DRES, ERES, LH, LS `%d`. TVELA `%+.4f` rev/s. TER, TSS: 32 bits like TAS.
- Messages: an unknown command `*UNDEFINED LABEL`; a bad field or an axis beyond --axes
  `*INVALID DATA`; GO/HOM for an axis whose drive is off `*DRIVE SHUTDOWN`; a GO towards an
  active, enabled hardware limit `*INVALID CONDITIONS FOR COMMAND`. A refused GO moves no axis.
- ERRLVL 4 messages and both prompts; 3 both prompts, no messages; 2 the error prompt only;
  1 and 0 neither (responses still come).
- GO: MC0 moves to D (MA1) or by D (MA0) at V with A/AD; MC1 runs at V in D's direction until
  S/K/a limit. A GO for a moving axis replaces its move. HOM<d> (0 positive, 1 negative, X
  none) runs at HOMV until the home input changes state (the switch is 50000 steps on the
  negative side of the power-up position), reversing once at a hardware limit; success sets
  TPC to 0 and TAS bit 5. The encoder position (TPE) is not zeroed by a home (the parker6k
  README: "the controller does not reset the encoder position on a successful home");
  --home-zeroes-encoder zeroes it too. PSET sets both.
- Hardware limits 500000 steps either side of the power-up position; LH (default 3: 1 the
  negative, 2 the positive one enabled) stops motion at an enabled limit without a ramp.
  Soft limits LS (default 0), LSPOS/LSNEG (default 0) stop motion where they are crossed.
  DRIVE0 stops a moving axis at once. K stops without a ramp, S with AD.
- TER: bit 2 hardware limit hit, 3 software limit hit, 5 kill (K) executed; latched until the
  next GO. TSS: bit 1 system ready. TREV: `*TREV92-016740-01 (independent simulator)`.
- Bytes sent at another host baud rate than --baud are unreadable and dropped.

Sources: manualslib.com/manual/1270720 (Gemini GV6K Command Reference, page 119: ERRLVL);
manualshive.com/ru/manual/parker-automation/gemini-gt6k/756384 pages 114 (EOT) and 118
(ERRBAD, ERRDEF); EPICS drvPC6K.cc/drvPC6K.h (TAS bit table, `*<#>TAS` layout, `>` input EOS)
and mp49/parker6k (parker6kController.cpp, parker6kAxis.cpp, README).
"""
import argparse
import collections
import os
import re
import select
import sys
import termios
import threading
import time
import tty

import unit_common as uc

HOME_SWITCH = -50000.0  # steps, physical
LIMIT = 500000.0
HOMA = 10.0  # rev/s^2 during a home search

NUMERIC = {"V": ("v", "%.4f"), "A": ("a", "%.4f"), "AD": ("ad", "%.4f"), "HOMV": ("homv", "%.4f"),
           "D": ("d", "%+d"), "DRES": ("dres", "%d"), "ERES": ("eres", "%d"), "LH": ("lh", "%d"),
           "LS": ("ls", "%d"), "LSPOS": ("lspos", "%+d"), "LSNEG": ("lsneg", "%+d")}
BINARY = {"DRIVE": "drive", "MA": "ma", "MC": "mc"}
SYSTEM_INT = {"ECHO": ("echo", 0, 1), "COMEXC": ("comexc", 0, 1), "ERRLVL": ("errlvl", 0, 4)}
SYSTEM_LIST = {"EOT": ("eot", 3), "EOL": ("eol", 3), "BOT": ("bot", 3), "ERROK": ("errok", 4),
               "ERRBAD": ("errbad", 4)}
OTHER = ["TAS", "TPC", "TPE", "TER", "TSS", "TREV", "TVELA", "GO", "S", "K", "HOM", "PSET"]
NAMES = sorted(list(NUMERIC) + list(BINARY) + list(SYSTEM_INT) + list(SYSTEM_LIST) + OTHER,
               key=len, reverse=True)

rx = uc.rx


def bitstring(bits):
    """bits: set of 1-based bit numbers -> `0000_0000_..._0000` (bit 1 first)."""
    s = "".join("1" if i in bits else "0" for i in range(1, 33))
    return "_".join(s[i:i + 4] for i in range(0, 32, 4))


class Fail(Exception):
    pass


class Axis6K:
    def __init__(self, n):
        self.n = n
        self.axis = uc.Axis(limit_neg=-LIMIT, limit_pos=LIMIT, home_switch=HOME_SWITCH)
        self.drive = 0
        self.ma = 0
        self.mc = 0
        self.v, self.a, self.ad, self.homv = 1.0, 10.0, 10.0, 1.0
        self.d = 25000
        self.dres, self.eres = 25000, 4000
        self.lh, self.ls, self.lspos, self.lsneg = 3, 0, 0, 0
        self.enc_offset = 0.0  # steps
        self.homed = False
        self.mode = None  # None, "go", "home", "stop"
        self.neg = False
        self.home_high = False
        self.home_reversed = False
        self.soft_hit = 0
        self.prev_speed = 0.0
        self.accelerating = False

    def power_up(self):
        """Power removed and restored: the motor stops where it is (no power to ramp it down)
        and stays there with its switches; the axis is as at power-up, drive off, not homed,
        TPC and TPE 0, parameters at their defaults."""
        axis = self.axis
        axis.power_up(0.0)
        self.__init__(self.n)
        self.axis = axis
        self.enc_offset = -axis.pos
        self.apply_limits()

    def apply_limits(self):
        self.axis.limit_neg = -LIMIT if self.lh & 1 else -1e15
        self.axis.limit_pos = LIMIT if self.lh & 2 else 1e15

    def tpc(self):
        return int(round(self.axis.position()))

    def tpe(self):
        return int(round((self.axis.pos + self.enc_offset) * self.eres / self.dres))

    def busy(self):
        return self.mode is not None

    def status_bits(self):
        b = set()
        if self.busy():
            b.add(1)
            if self.accelerating:
                b.add(3)
            elif self.mode == "go" and abs(abs(self.axis.v) - self.axis.vmax) < 1e-6 * self.dres:
                b.add(4)
        if self.neg:
            b.add(2)
        if self.homed:
            b.add(5)
        if self.ma:
            b.add(6)
        if self.mc:
            b.add(7)
        if not self.drive:
            b.add(13)
        if self.lh & 2 and self.axis.limit_active(1):
            b.add(15)
        if self.lh & 1 and self.axis.limit_active(-1):
            b.add(16)
        if self.soft_hit > 0:
            b.add(17)
        if self.soft_hit < 0:
            b.add(18)
        return b


class Unit:
    def __init__(self, pty, n_axes, home_zeroes_encoder):
        self.pty = pty
        self.axes = [Axis6K(i + 1) for i in range(n_axes)]
        self.home_zeroes_encoder = home_zeroes_encoder
        self.echo, self.comexc, self.errlvl = 1, 0, 4
        self.eot, self.eol, self.bot = [13, 0, 0], [13, 10, 0], [0, 0, 0]
        self.errok, self.errbad = [13, 10, 62, 32], [13, 10, 63, 32]
        self.buf = bytearray()
        self.queue = collections.deque()  # lines waiting (COMEXC0): lists of commands
        self.hold = set()  # axes whose GO/HOM holds the queue
        self.ter = set()

    def power_up(self):
        """The controller's power-up (as at start): ECHO1, COMEXC0, ERRLVL4 and the default
        EOT, EOL, BOT and prompts; waiting lines and the half-received line gone."""
        self.echo, self.comexc, self.errlvl = 1, 0, 4
        self.eot, self.eol, self.bot = [13, 0, 0], [13, 10, 0], [0, 0, 0]
        self.errok, self.errbad = [13, 10, 62, 32], [13, 10, 63, 32]
        self.buf = bytearray()
        self.queue.clear()
        self.hold = set()
        self.ter = set()

    def control(self, line, now):
        """The test's requests (unit_common.Control). A power cycle concerns the whole
        controller (WHO, an axis number, must be one of its axes): every axis and the
        communication settings as at power-up."""
        def power_cycle(who):
            if who is not None and (not who.isdigit() or not 1 <= int(who) <= len(self.axes)):
                return None
            self.on_tick(now)  # the motion up to this instant
            was = " ".join("%d %+d" % (ax.n, ax.tpc()) for ax in self.axes)
            for ax in self.axes:
                ax.power_up()
            self.power_up()
            uc.log("parker6k: power-cycled at %s steps: drives off, not homed, TPC 0, ECHO1, "
                   "COMEXC0" % was)
            return "controller"

        def state():
            return {str(ax.n): (ax.tpc(), ax.axis.moving()) for ax in self.axes}
        return uc.control_request(self, line.split(), power_cycle, state)

    # -- output
    @staticmethod
    def chars(codes):
        return bytes(c for c in codes if 0 < c < 256)

    def respond(self, lines):
        out = self.chars(self.bot)
        for i, text in enumerate(lines):
            end = self.eot if i == len(lines) - 1 else self.eol
            out += b"*" + text.encode() + self.chars(end)
        self.pty.send(out)

    def error(self, message):
        if self.errlvl >= 4:
            self.pty.send(self.chars(self.bot) + b"\r\n*" + message.encode() + self.chars(self.eot))

    def prompt(self, failed):
        if failed and self.errlvl >= 2:
            self.pty.send(self.chars(self.errbad))
        elif not failed and self.errlvl >= 3:
            self.pty.send(self.chars(self.errok))

    # -- input
    def on_bytes(self, data, now):
        for b in data:
            if self.echo:
                self.pty.send(bytes([b]))
            text = uc.feed_line(self.buf, b, (0x0D, 0x0A), 512)
            if text is not None:
                self.line(text, now)

    def line(self, text, now):
        body = text.split(";")[0].replace(" ", "").replace("\t", "").upper()
        if not body.strip(":"):
            return
        rx(text)
        commands = [c for c in body.split(":") if c]
        item = [commands, False]
        if commands[0].startswith("!"):
            self.run_item(item, now)
            return
        self.queue.append(item)
        self.run_queue(now)

    def run_queue(self, now):
        while self.queue and not self.hold:
            item = self.queue[0]
            if self.run_item(item, now) and self.queue and self.queue[0] is item:
                self.queue.popleft()

    def run_item(self, item, now):
        """Runs the item's commands until a GO/HOM holds the buffer; True if it completed."""
        commands = item[0]
        while commands:
            cmd = commands.pop(0)
            try:
                self.command(cmd.lstrip("!"), now)
            except Fail as f:
                item[1] = True
                self.error(str(f))
            if self.hold and commands:
                return False
        self.prompt(item[1])
        return True

    # -- commands
    def axis(self, n):
        if not 1 <= n <= len(self.axes):
            raise Fail("INVALID DATA")
        return self.axes[n - 1]

    def selected(self, prefix, rest):
        """Axes chosen by an axis prefix, a binary field (1 = selected) or nothing (all)."""
        if prefix:
            if rest not in ("", "1"):
                raise Fail("INVALID DATA")
            return [self.axis(prefix)]
        if rest == "":
            return list(self.axes)
        if not re.fullmatch(r"[01X]+", rest):
            raise Fail("INVALID DATA")
        return [ax for ax, c in zip(self.axes, rest) if c == "1"]

    def command(self, cmd, now):
        m = re.match(r"([1-8])(?=[A-Z])", cmd)
        prefix = int(m.group(1)) if m else 0
        body = cmd[1:] if m else cmd
        name = next((n for n in NAMES if body.startswith(n)), None)
        rest = body[len(name):] if name else ""
        if name is None or not re.fullmatch(r"[0-9X+\-.,]*", rest):
            raise Fail("UNDEFINED LABEL")
        tag = ("%d" % prefix if prefix else "") + name
        if prefix:
            self.axis(prefix)
        if name in NUMERIC:
            return self.numeric(name, prefix, rest, tag)
        if name in BINARY:
            return self.binary(name, prefix, rest, tag, now)
        if name in SYSTEM_INT:
            attr, lo, hi = SYSTEM_INT[name]
            if rest == "":
                return self.respond([tag + "%d" % getattr(self, attr)])
            if not re.fullmatch(r"\d+", rest) or not lo <= int(rest) <= hi:
                raise Fail("INVALID DATA")
            setattr(self, attr, int(rest))
            if name == "COMEXC" and self.comexc:
                self.hold.clear()
            return None
        if name in SYSTEM_LIST:
            attr, count = SYSTEM_LIST[name]
            if rest == "":
                return self.respond([tag + ",".join("%d" % c for c in getattr(self, attr))])
            fields = rest.split(",")
            if len(fields) > count or not all(re.fullmatch(r"\d+", f) and int(f) <= 256
                                              for f in fields):
                raise Fail("INVALID DATA")
            setattr(self, attr, [int(f) for f in fields] + [0] * (count - len(fields)))
            return None
        if name in ("TPC", "TPE", "TVELA"):
            def value(ax):
                if name == "TPC":
                    return "%+d" % ax.tpc()
                if name == "TPE":
                    return "%+d" % ax.tpe()
                return "%+.4f" % (ax.axis.v / ax.dres)
            axes = [self.axis(prefix)] if prefix else self.axes
            return self.respond([tag + ",".join(value(ax) for ax in axes)])
        if name == "TAS":
            if prefix:
                return self.respond([tag + bitstring(self.axis(prefix).status_bits())])
            parts = [bitstring(ax.status_bits()) for ax in self.axes]
            lines = [p + ("," if i < len(parts) - 1 else "") for i, p in enumerate(parts)]
            lines[0] = "TAS" + lines[0]
            return self.respond(lines)
        if name == "TER":
            return self.respond([tag + bitstring(self.ter)])
        if name == "TSS":
            return self.respond([tag + bitstring({1})])
        if name == "TREV":
            return self.respond(["TREV92-016740-01 (independent simulator)"])
        if name == "GO":
            return self.go(self.selected(prefix, rest))
        if name in ("S", "K"):
            self.queue.clear()
            for ax in self.selected(prefix, rest):
                if name == "K":
                    ax.axis.hard_stop()
                    ax.mode = None
                    self.ter.add(5)
                elif ax.busy():
                    ax.axis.stop(decel=ax.ad * ax.dres)
                    ax.mode = "stop"
            self.release_hold()
            return None
        if name == "HOM":
            return self.home(prefix, rest)
        if name == "PSET":
            return self.pset(prefix, rest)
        raise Fail("UNDEFINED LABEL")

    def numeric(self, name, prefix, rest, tag):
        attr, form = NUMERIC[name]
        if rest == "":
            axes = [self.axis(prefix)] if prefix else self.axes
            return self.respond([tag + ",".join(form % getattr(ax, attr) for ax in axes)])
        fields = rest.split(",")
        targets = [(self.axis(prefix), fields[0])] if prefix else list(zip(self.axes, fields))
        new = []
        for ax, f in targets:
            if f == "":
                continue
            if name == "D" and f in ("+", "-"):
                new.append((ax, abs(ax.d) * (1 if f == "+" else -1)))
                continue
            try:
                v = float(f)
            except ValueError:
                raise Fail("INVALID DATA")
            if name in ("V", "A", "AD", "HOMV", "DRES", "ERES") and v <= 0:
                raise Fail("INVALID DATA")
            if name in ("LH", "LS") and v not in (0, 1, 2, 3):
                raise Fail("INVALID DATA")
            new.append((ax, v if form == "%.4f" else int(round(v))))
        for ax, v in new:
            setattr(ax, attr, v)
            if name == "LH":
                ax.apply_limits()
        return None

    def binary(self, name, prefix, rest, tag, now):
        attr = BINARY[name]
        if rest == "":
            axes = [self.axis(prefix)] if prefix else self.axes
            return self.respond([tag + "".join("%d" % getattr(ax, attr) for ax in axes)])
        if prefix:
            if rest not in ("0", "1"):
                raise Fail("INVALID DATA")
            pairs = [(self.axis(prefix), rest)]
        else:
            if not re.fullmatch(r"[01X]+", rest):
                raise Fail("INVALID DATA")
            pairs = list(zip(self.axes, rest))
        for ax, c in pairs:
            if c == "X":
                continue
            setattr(ax, attr, int(c))
            if name == "DRIVE" and c == "0" and ax.busy():
                ax.axis.hard_stop()
                ax.mode = None
        self.release_hold()
        return None

    def go(self, axes):
        plans = []
        for ax in axes:
            if not ax.drive:
                raise Fail("DRIVE SHUTDOWN")
            if ax.mc:
                sign = -1 if ax.d < 0 else 1
                plans.append((ax, None, sign))
                continue
            target = ax.d if ax.ma else ax.tpc() + ax.d
            if target == ax.tpc():
                continue
            plans.append((ax, target, 1 if target > ax.tpc() else -1))
        for ax, _, sign in plans:
            if ax.axis.limit_active(sign):
                raise Fail("INVALID CONDITIONS FOR COMMAND")
        self.ter.discard(2)
        self.ter.discard(3)
        self.ter.discard(5)
        for ax, target, sign in plans:
            ax.axis.accel, ax.axis.decel = ax.a * ax.dres, ax.ad * ax.dres
            if target is None:
                ax.axis.run_at(sign * ax.v * ax.dres)
            else:
                ax.axis.move_to(float(target), ax.v * ax.dres)
            ax.mode = "go"
            ax.neg = sign < 0
            ax.soft_hit = 0
            if not self.comexc:
                self.hold.add(ax.n)
        return None

    def home(self, prefix, rest):
        if prefix:
            pairs = [(self.axis(prefix), rest)]
            if rest not in ("0", "1"):
                raise Fail("INVALID DATA")
        else:
            if not re.fullmatch(r"[01X]+", rest):
                raise Fail("INVALID DATA")
            pairs = [(ax, c) for ax, c in zip(self.axes, rest) if c != "X"]
        for ax, _ in pairs:
            if not ax.drive:
                raise Fail("DRIVE SHUTDOWN")
        for ax, c in pairs:
            sign = 1 if c == "0" else -1
            ax.homed = False
            ax.home_high = ax.axis.home_input_high()
            ax.home_reversed = False
            ax.axis.accel = ax.axis.decel = HOMA * ax.dres
            ax.axis.run_at(sign * ax.homv * ax.dres)
            ax.mode = "home"
            ax.neg = sign < 0
            if not self.comexc:
                self.hold.add(ax.n)
        return None

    def pset(self, prefix, rest):
        fields = rest.split(",") if rest else []
        targets = [(self.axis(prefix), fields[0] if fields else "0")] if prefix else \
            list(zip(self.axes, fields))
        for ax, f in targets:
            if f == "":
                continue
            try:
                v = float(f)
            except ValueError:
                raise Fail("INVALID DATA")
            ax.axis.set_position(v)
            ax.enc_offset = v * ax.dres / ax.eres - ax.axis.pos
        return None

    def release_hold(self):
        self.hold = {n for n in self.hold if self.axes[n - 1].busy()}

    def on_tick(self, now):
        for ax in self.axes:
            ax.axis.tick(now)
            speed = abs(ax.axis.v)
            ax.accelerating = ax.busy() and speed > ax.prev_speed + 1e-9
            ax.prev_speed = speed
            if ax.mode == "home":
                if ax.axis.home_input_high() != ax.home_high:
                    ax.axis.hard_stop()
                    ax.axis.set_position(0.0)
                    if self.home_zeroes_encoder:
                        ax.enc_offset = -ax.axis.pos
                    ax.homed = True
                    ax.mode = None
                elif not ax.axis.moving():
                    if ax.axis.hit_limit and not ax.home_reversed:
                        ax.home_reversed = True
                        ax.neg = ax.axis.hit_limit > 0
                        ax.axis.run_at(-ax.axis.hit_limit * ax.homv * ax.dres)
                    else:
                        ax.mode = None
                continue
            if ax.mode == "go" and ax.ls:
                p = ax.axis.position()
                if ax.ls & 2 and p >= ax.lspos and ax.axis.v > 0:
                    ax.axis.hard_stop()
                    ax.soft_hit = 1
                    self.ter.add(3)
                elif ax.ls & 1 and p <= ax.lsneg and ax.axis.v < 0:
                    ax.axis.hard_stop()
                    ax.soft_hit = -1
                    self.ter.add(3)
            if ax.busy() and not ax.axis.moving():
                if ax.axis.hit_limit:
                    self.ter.add(2)
                    ax.axis.hit_limit = 0
                ax.mode = None
        if self.hold:
            self.release_hold()
            if not self.hold:
                self.run_queue(now)


# ---------------------------------------------------------------------------------------------
# Self-test

def Host(link, baud):
    return uc.TestHost(link, baud, 0.25)


def self_test(args):
    link = "/tmp/parker6k_selftest_%d" % os.getpid()
    pty = uc.Pty(link, args.baud)
    unit = Unit(pty, 2, args.home_zeroes_encoder)
    on_bytes = uc.heard_only_at(pty, args.baud, "6k", unit.on_bytes)
    threading.Thread(target=uc.run, args=(pty, on_bytes, unit.on_tick), daemon=True).start()
    host = Host(link, args.baud)
    test = uc.SelfTest(host, 0.2)
    check, wait_for = test.check, test.wait_for
    ok_p, bad_p = b"\r\n> ", b"\r\n? "
    z = bitstring(set())



    check("echo on at power-up", host.ask("1TPC\r"), b"1TPC\r*1TPC+0\r" + ok_p)
    check("ECHO0 is echoed, then off", host.ask("ECHO0\r"), b"ECHO0\r" + ok_p)
    check("no echo now", host.ask("1TPC\n"), b"*1TPC+0\r" + ok_p)
    check("empty line: nothing", host.ask("\r\n"), b"")
    tas = "*1TAS" + bitstring({13}) + "\r"
    check("drive shut down at power-up", host.ask("1TAS\r"), tas.encode() + ok_p)
    check("GO with drive off", host.ask("1GO\r"), b"\r\n*DRIVE SHUTDOWN\r" + bad_p)
    check("unknown command", host.ask("FOO\r"), b"\r\n*UNDEFINED LABEL\r" + bad_p)
    check("report DRIVE", host.ask("DRIVE\r"), b"*DRIVE00\r" + ok_p)
    check("DRIVE11", host.ask("DRIVE11\r"), ok_p)
    check("all-axes TPC", host.ask("TPC\r"), b"*TPC+0,+0\r" + ok_p)
    check("all-axes TAS", host.ask("TAS\r"),
          ("*TAS%s,\r\n*%s\r" % (z, z)).encode() + ok_p)
    check("EOT report", host.ask("EOT\r"), b"*EOT13,0,0\r" + ok_p)
    # COMEXC0: a query after GO waits for the end of the move.
    t = time.monotonic()
    r = host.ask("1V5:1A50:1AD50:1D25000:1GO\r1TPC\r", 2.0)
    check("COMEXC0 holds the query", r, ok_p + b"*1TPC+25000\r" + ok_p)
    check("... until the move ended", time.monotonic() - t > 0.2, True)
    host.ask("COMEXC1:MA11\r")
    host.ask("1D0:1GO\r", 0.05)
    r = host.ask("1TAS\r", 0.1)
    check("moving: bit 1 (COMEXC1 answers)", r[:6], b"*1TAS1")
    check("... negative direction bit 2", r[6:7], b"1")
    check("... absolute mode bit 6", r[11:12], b"1")
    check("move back to 0", wait_for("1TPC\r", b"*1TPC+0\r" + ok_p, 3.0), b"*1TPC+0\r" + ok_p)
    host.ask("1V1:1HOM1\r", 0.05)
    check("homed (bit 5)", wait_for("1TAS\r",
          ("*1TAS" + bitstring({2, 5, 6}) + "\r").encode() + ok_p, 6.0),
          ("*1TAS" + bitstring({2, 5, 6}) + "\r").encode() + ok_p)
    check("TPC 0 after home", host.ask("1TPC\r"), b"*1TPC+0\r" + ok_p)
    check("TPE not zeroed by home", host.ask("1TPE\r")[:6], b"*1TPE-")
    host.ask("2MC1:2V10:2A100:2AD100:2D+:2GO\r", 0.05)
    check("2: continuous bit 7", host.ask("2TAS\r", 0.1)[12:13], b"1")
    check("2 runs into + limit", wait_for("2TAS\r",
          ("*2TAS" + bitstring({6, 7, 15}) + "\r").encode() + ok_p, 5.0),
          ("*2TAS" + bitstring({6, 7, 15}) + "\r").encode() + ok_p)
    check("TER bit 2", host.ask("TER\r"), ("*TER" + bitstring({2}) + "\r").encode() + ok_p)
    check("GO into the active limit", host.ask("2GO\r"),
          b"\r\n*INVALID CONDITIONS FOR COMMAND\r" + bad_p)
    host.ask("2D-:2GO\r", 0.3)
    host.ask("!K\r")
    check("!K stops", host.ask("2TAS\r")[:6], b"*2TAS0")
    check("ERRLVL0: no prompts", host.ask("ERRLVL0\r1TPC\rFOO\r"), b"*1TPC+0\r")
    return test.finish(link, 19200, "1TPC\r")


def main():
    ap = uc.unit_arguments(__doc__, 9600)
    ap.add_argument("--axes", type=int, default=2, help="number of axes (6K2: 2, 6K4: 4)")
    ap.add_argument("--home-zeroes-encoder", action="store_true",
                    help="a successful HOM zeroes TPE as well as TPC")
    uc.control_argument(ap)
    args = uc.parse_unit_arguments(ap, self_test)
    if not 1 <= args.axes <= 8:
        ap.error("--axes is 1..8")
    pty = uc.Pty(args.link, args.baud)
    unit = Unit(pty, args.axes, args.home_zeroes_encoder)
    uc.log("parker6k: %d axes at %d baud on %s" % (args.axes, args.baud, args.link))
    uc.run(pty, uc.heard_only_at(pty, args.baud, "6k", unit.on_bytes), unit.on_tick,
           control=uc.Control.open(args.control, unit))


if __name__ == "__main__":
    main()
