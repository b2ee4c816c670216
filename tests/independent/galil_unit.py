#!/usr/bin/python3
"""Galil DMC motion controller (DMC-21x3 / DMC-40x0 style) on its RS-232 main port, axes A-H in
one controller, written from Galil's public command reference (DMC-40x0 / DMC-21x3 Command
Reference, the "Controller Response to Data" and "Error Codes" sections of the user manual) as
this reader knows it. Nothing here is taken from sim/, drivers/ or config/.

  galil_unit.py --link PATH [--axes AB] [--baud 115200] [--control SOCK]
                [--chaos SEED [--chaos-paused]] [--journal PATH] [--log first|all|none]
                [--self-test]

Facts from the reference:
- A command is two upper-case letters and its operands; commands end with a carriage return or
  a semicolon (several commands on one line). LF is ignored.
- Every command the controller accepts is answered by a colon `:`; a command it cannot execute
  by a question mark `?`. `TC1` then tells why: the code and its text, `1 Unrecognized command`
  (`TC` / `TC0`: the code alone). A response carrying data (TP, TS, MG, a `?` query) is the data,
  CR LF, then the colon.
- Numbers print with a space or a minus before the digits: `TPA` -> ` 1000`, `-250`; `TP` gives
  every axis, separated by commas (` 1000,-250`, ` 0, 0`). `MG` prints a number with four decimals
  (`MG _BGA` -> ` 1.0000`). `TS` prints each axis's status byte as a decimal number.
- Axis operands, in two notations: implicit (`PA 1000,2000`; an empty slot leaves that axis
  unchanged: `PA ,2000` sets B only) and explicit (`PAA=1000`, `PAB=?` asks for B's value).
  Axis-list commands take the letters: `BG A`, `BGAB`, `ST A`, `SH AB`, `MO A`; without letters
  they apply to every axis.
- PA absolute target, PR relative distance, JG jog speed (signed), SP speed, AC/DC acceleration
  and deceleration, all in counts (per second, per second squared); BG begins the motion the
  last of PA/PR/JG set up; ST decelerates to a stop; AB aborts every motion at once; SH servo
  here (motor on), MO motor off; DP defines the position; HM + BG homes (toward the home switch
  at SP, then to the encoder index at HV; position 0 there); FI + BG finds the index alone
  (direction of JG's sign, at HV); RS resets the controller to its power-up state.
- `_BGx` is 1 while axis x profiles a motion (homing included), `_MOx` 1 while its motor is
  off, `_TPx` its position, `_TC` the last error code.
- TS status byte: bit 7 axis in motion, bit 6 position error exceeds the limit, bit 5 motor off,
  bit 3 forward limit switch inactive, bit 2 reverse limit switch inactive, bit 1 home switch
  input, bit 0 latch occurred.
- Error codes used (TC1 text): 1 Unrecognized command, 4 Operand error, 6 Number out of range,
  7 Command not valid while running, 20 Begin not valid with motor off, 21 Begin not valid
  while running, 22 Begin not possible due to Limit Switch.

Readings chosen where the reference (as remembered) is silent or ambiguous:
- After a refused command the rest of its line is discarded (no further responses until CR).
- Lower-case mnemonics are unrecognized (1). Spaces outside a quoted text are ignored.
- TC1 does not clear the code; with none it prints `0 No error`.
- Power-up: motors off, positions 0, SP 25000, AC and DC 256000, HV 256, JG 25000, no echo;
  no banner on the serial port; after a power cycle the controller is deaf for 0.3 s while it
  boots (RS resets the axes at once and answers its colon).
- PA/PR/SP/AC/DC are accepted while the axis moves (they apply at the next BG); DP and MO
  while it moves are 7; BG while it moves is 21; BG with the motor off is 20; BG toward an
  active limit switch is 22. SP 0..12000000, AC/DC 1024..1073740800, PA/PR within +-2147483647
  (6 otherwise); no rounding of AC/DC to 1024 multiples.
- The home switch is 1500 counts on the negative side of the power-up position (input high
  below it), an index 100 counts above it and every 4000 counts from there, the limit switches
  at +-3000000 counts.
- Bytes at another host rate than --baud are unreadable and dropped.

--chaos SEED (for galil_fault_property.py): each command's response late (250-400 ms, what
follows waiting behind it), dropped, garbled or truncated, each command line lost, at the rates
of --chaos-rates; --journal PATH records `exec KEY ok|err N`, `sent KEY 'data'` and `fault ...`
lines (KEY: the command without blanks); SIGUSR1/SIGUSR2 turn the chaos on and off.
"""
import math
import os
import random
import signal
import threading
import time

import unit_common as uc

ERRORS = {0: "No error", 1: "Unrecognized command", 4: "Operand error", 6: "Number out of range",
          7: "Command not valid while running", 20: "Begin not valid with motor off",
          21: "Begin not valid while running", 22: "Begin not possible due to Limit Switch"}
BOOT_TIME = 0.3
INDEX_PITCH = 4000.0
INDEX_OFFSET = -1400.0  # the index pulses: 100 counts above the home switch, then every 4000
LIMIT = 3000000.0
INT_MAX = 2147483647


class Refused(Exception):
    def __init__(self, code):
        Exception.__init__(self, code)
        self.code = code


def num(value):
    """A number as Galil prints it: a space or a minus before the digits."""
    value = int(round(value))
    return ("-%d" % -value) if value < 0 else (" %d" % value)


def num4(value):
    """MG's default: four decimals."""
    return ("-%.4f" % -value) if value < 0 else (" %.4f" % value)


class GalilAxis:
    def __init__(self, name):
        self.name = name
        self.axis = uc.Axis(accel=256000.0, limit_neg=-LIMIT, limit_pos=LIMIT, home_switch=-1500.0)
        self.power_up()

    def power_up(self):
        self.axis.power_up(0.0)
        self.motor_off = True
        self.sp, self.ac, self.dc, self.hv, self.jg = 25000, 256000, 256000, 256, 25000
        self.pa, self.pr = 0, 0
        self.mode = "PA"  # what BG begins: PA, PR, JG, HM, FI
        self.phase = None  # homing: "switch", "index"

    def position(self):
        return int(round(self.axis.position()))

    def moving(self):
        return self.axis.moving() or self.phase is not None

    def status_byte(self):
        a = self.axis
        b = 0
        if self.moving():
            b |= 0x80
        if self.motor_off:
            b |= 0x20
        if not a.limit_active(1):
            b |= 0x08
        if not a.limit_active(-1):
            b |= 0x04
        if a.home_input_high():
            b |= 0x02
        return b

    def begin(self):
        if self.moving():
            raise Refused(21)
        if self.motor_off:
            raise Refused(20)
        a = self.axis
        a.accel, a.decel = float(self.ac), float(self.dc)
        if self.mode == "PA":
            direction = self.pa - a.position()
            self._check_limit(direction)
            a.move_to(float(self.pa), self.sp)
        elif self.mode == "PR":
            self._check_limit(self.pr)
            a.move_to(a.position() + self.pr, self.sp)
        elif self.mode == "JG":
            self._check_limit(self.jg)
            a.run_at(float(self.jg))
        elif self.mode == "HM":
            # Toward the home switch's edge at SP: positive while the input is high.
            self.phase = "switch"
            a.move_to(a.home_switch - a.offset, self.sp)
        elif self.mode == "FI":
            self._start_index(1 if self.jg >= 0 else -1)

    def _check_limit(self, direction):
        if direction > 0 and self.axis.limit_active(1):
            raise Refused(22)
        if direction < 0 and self.axis.limit_active(-1):
            raise Refused(22)

    def _start_index(self, sign):
        a = self.axis
        k = math.floor((a.pos - INDEX_OFFSET) / INDEX_PITCH)
        nxt = INDEX_OFFSET + (k + 1 if sign > 0 else k) * INDEX_PITCH
        if sign < 0 and nxt >= a.pos:
            nxt -= INDEX_PITCH
        self.phase = "index"
        a.move_to(nxt - a.offset, self.hv)

    def stop(self):
        if self.phase is not None:
            self.phase = "stopping"
        self.axis.stop(float(self.dc))

    def tick(self, now):
        a = self.axis
        if now <= a.last:
            return
        a.tick(now)
        if a.moving() or self.phase is None:
            return
        if self.phase == "switch" and a.hit_limit == 0:
            self._start_index(1)
        elif self.phase == "index" and a.hit_limit == 0:
            a.set_position(0.0)
            self.phase = None
        else:
            self.phase = None


class Chaos:
    """A bad line (--chaos): each response late (250-400 ms, the responses after it waiting
    behind it), dropped, garbled (bit 7 set on 1-3 characters) or truncated, each command line
    lost (never heard), from a seeded RNG."""

    def __init__(self, seed, rates, active):
        self.rng = random.Random(seed)
        self.late, self.drop, self.garble, self.truncate, self.lost = rates
        self.active = active


class Journal:
    """--journal: one line per executed command, per response queued and per fault."""

    def __init__(self, path):
        self.f = open(path, "a", buffering=1) if path else None

    def write(self, text):
        if self.f is not None:
            self.f.write("%.6f %s\n" % (time.monotonic(), text))
            self.f.flush()


class Controller:
    def __init__(self, pty, letters, chaos=None, journal=None):
        self.pty = pty
        self.letters = letters
        self.axes = {c: GalilAxis(c) for c in letters}
        self.buf = bytearray()
        self.skip = False  # discarding the rest of a line after a refusal
        self.tc = 0
        self.deaf_until = 0.0
        self.chaos = chaos
        self.journal = journal or Journal(None)
        self.line_lost = False

    # The test's hand (unit_common.Control): one controller on the line, WHO ignored.
    def control(self, line, now):
        def power_cycle(who):
            for g in self.axes.values():
                g.tick(now)
                g.power_up()
            self.tc, self.skip = 0, False
            self.buf.clear()
            self.line_text = ""
            self.deaf_until = now + BOOT_TIME
            self.journal.write("power-cycle")
            uc.log("galil: power-cycled: motors off, positions 0, deaf for %.1f s" % BOOT_TIME)
            return "".join(self.letters)

        def state():
            return {c: (g.position(), g.moving()) for c, g in self.axes.items()}
        return uc.control_request(self, line.split(), power_cycle, state)

    def set_chaos(self, on):
        if self.chaos is not None and self.chaos.active != on:
            self.chaos.active = on
            self.journal.write("chaos %s" % ("on" if on else "off"))

    def on_bytes(self, data, now):
        if now < self.deaf_until:
            return
        for g in self.axes.values():
            g.tick(now)
        for b in data:
            if b == 0x0A:
                continue
            if b in (0x0D, 0x3B) and not self._in_quote():
                text = bytes(self.buf).decode("ascii", errors="replace")
                self.buf.clear()
                end_of_line = b == 0x0D
                self.line_text += text + ("<CR>" if end_of_line else ";")
                if end_of_line:
                    uc.rx(self.line_text)
                    self.line_text = ""
                if self.line_lost:
                    pass
                elif not self.skip and text.strip():
                    self.command(text, now)
                elif not self.skip and not end_of_line:
                    self.command(text, now)  # an empty command between separators
                if end_of_line:
                    self.skip = False
                    self.line_lost = False
                    self._start_line()
                continue
            if not self.buf and self._new_line and self.chaos is not None and self.chaos.active:
                if self.chaos.rng.random() < self.chaos.lost:
                    self.line_lost = True
                    self.journal.write("fault lost-line")
            self._new_line = False
            self.buf.append(b)
            if len(self.buf) > 200:
                del self.buf[:-200]

    _new_line = True
    line_text = ""

    def _start_line(self):
        self._new_line = True

    def _in_quote(self):
        return self.buf.count(b'"') % 2 == 1

    chaos_wanted = None  # set by the signal handlers

    def on_tick(self, now):
        if self.chaos_wanted is not None:
            self.set_chaos(self.chaos_wanted)
            self.chaos_wanted = None
        for g in self.axes.values():
            g.tick(now)

    def respond(self, data, now, key):
        """Queues one command's response; journaled as `sent KEY 'data'` (KEY: the command
        without blanks), or the fault injected instead."""
        raw = data.encode()
        chaos = self.chaos
        if chaos is not None and chaos.active:
            r = chaos.rng.random()
            if r < chaos.late:
                delay = chaos.rng.uniform(0.25, 0.40)
                # The controller answers late, and what it answers after waits behind it: a
                # serial line keeps its order.
                self.pty.busy_until = max(self.pty.busy_until, now + delay)
                self.journal.write("fault late %s %.3f %r" % (key, delay, data))
                self.journal.write("sent %s %r late" % (key, data))
                self.pty.send(raw)
                return
            if r < chaos.late + chaos.drop:
                self.journal.write("fault drop %s %r" % (key, data))
                return
            if r < chaos.late + chaos.drop + chaos.garble:
                b = bytearray(raw)
                for i in chaos.rng.sample(range(len(b)), min(len(b), chaos.rng.randint(1, 3))):
                    b[i] |= 0x80
                self.journal.write("fault garble %s %r -> %s" % (key, data, bytes(b).hex()))
                self.pty.send(bytes(b))
                return
            if r < chaos.late + chaos.drop + chaos.garble + chaos.truncate and len(raw) > 1:
                b = raw[:chaos.rng.randint(1, len(raw) - 1)]
                self.journal.write("fault truncate %s %r -> %s" % (key, data, b.hex()))
                self.pty.send(b)
                return
        self.journal.write("sent %s %r" % (key, data))
        self.pty.send(raw)

    def command(self, text, now):
        key = text.replace(" ", "") or "(empty)"
        try:
            out = self.execute(text.strip() if not text.strip().startswith("MG") else text.strip())
        except Refused as e:
            self.tc = e.code
            self.skip = True
            self.journal.write("exec %s err %d" % (key, e.code))
            self.respond("?", now, key)
            return
        self.journal.write("exec %s ok%s" % (key, self._positions()))
        self.respond((out + "\r\n:") if out is not None else ":", now, key)

    def _positions(self):
        return "".join(" %s=%d/%d" % (c, g.position(), g.pa) for c, g in self.axes.items())

    # -----------------------------------------------------------------------------------------
    def axis_list(self, operand):
        if operand == "":
            return list(self.axes.values())
        if any(c not in self.axes for c in operand):
            raise Refused(4)
        return [self.axes[c] for c in operand]

    def number(self, text, low=-INT_MAX, high=INT_MAX):
        try:
            value = int(text)
        except ValueError:
            try:
                value = int(round(float(text)))
            except ValueError:
                raise Refused(4)
        if not low <= value <= high:
            raise Refused(6)
        return value

    def values(self, mnemonic, operand, attr, low, high, after=None):
        """PA/PR/SP/AC/DC/JG/DP: explicit (PAA=1000, PAA=?) or implicit (PA 1000,,2000)."""
        if len(operand) >= 2 and operand[0].isalpha() and operand[1] == "=":
            slots = {operand[0]: operand[2:]}
        elif operand == "":
            raise Refused(4)
        else:
            parts = operand.split(",")
            if len(parts) > len(self.letters):
                raise Refused(4)
            slots = {self.letters[i]: p for i, p in enumerate(parts)}
        if any(c not in self.axes for c in slots):
            raise Refused(4)
        queries = [c for c, v in slots.items() if v == "?"]
        if queries:
            return ",".join(num(getattr(self.axes[c], attr)) for c in queries)
        parsed = {c: self.number(v, low, high) for c, v in slots.items() if v != ""}
        for c, v in parsed.items():
            if after is not None:
                after(self.axes[c], v)
            else:
                setattr(self.axes[c], attr, v)
        if mnemonic in ("PA", "PR", "JG"):
            for c in parsed:
                self.axes[c].mode = mnemonic
        return None

    def execute(self, text):
        if text.startswith("MG"):
            return self.message(text[2:].strip())
        text = text.replace(" ", "")
        if len(text) < 2 or not text[:2].isalpha() or not text[:2].isupper():
            raise Refused(1)
        mn, op = text[:2], text[2:]
        if mn == "TP":
            return ",".join(num(g.position()) for g in self.axis_list(op))
        if mn == "TS":
            return ",".join(num(g.status_byte()) for g in self.axis_list(op))
        if mn == "TC":
            if op in ("", "0"):
                return num(self.tc)
            if op == "1":
                return "%d %s" % (self.tc, ERRORS.get(self.tc, "Error"))
            raise Refused(4)
        if mn == "PA":
            return self.values(mn, op, "pa", -INT_MAX, INT_MAX)
        if mn == "PR":
            return self.values(mn, op, "pr", -INT_MAX, INT_MAX)
        if mn == "SP":
            return self.values(mn, op, "sp", 0, 12000000)
        if mn == "AC":
            return self.values(mn, op, "ac", 1024, 1073740800)
        if mn == "DC":
            return self.values(mn, op, "dc", 1024, 1073740800)
        if mn == "HV":
            return self.values(mn, op, "hv", 0, 12000000)
        if mn == "JG":
            return self.values(mn, op, "jg", -12000000, 12000000)
        if mn == "DP":
            def define(g, v):
                if g.moving():
                    raise Refused(7)
                g.axis.set_position(float(v))
            return self.values(mn, op, "pa", -INT_MAX, INT_MAX, define)
        if mn == "BG":
            chosen = self.axis_list(op)
            for g in chosen:  # all or none
                if g.moving():
                    raise Refused(21)
                if g.motor_off:
                    raise Refused(20)
            for g in chosen:
                g.begin()
            return None
        if mn == "ST":
            for g in self.axis_list(op):
                g.stop()
            return None
        if mn == "AB":
            if op not in ("", "0", "1"):
                raise Refused(4)
            for g in self.axes.values():
                g.axis.hard_stop()
                g.phase = None
            return None
        if mn == "SH":
            for g in self.axis_list(op):
                g.motor_off = False
            return None
        if mn == "MO":
            chosen = self.axis_list(op)
            if any(g.moving() for g in chosen):
                raise Refused(7)
            for g in chosen:
                g.motor_off = True
            return None
        if mn in ("HM", "FI"):
            for g in self.axis_list(op):
                g.mode = mn
            return None
        if mn == "RS":
            for g in self.axes.values():
                g.power_up()
            self.tc = 0
            return None
        if mn == "EO":
            return None
        raise Refused(1)

    def message(self, operand):
        if operand.startswith('"') and operand.endswith('"') and len(operand) >= 2:
            return operand[1:-1]
        name = operand.replace(" ", "")
        if name == "_TC":
            return num4(self.tc)
        if len(name) == 4 and name[0] == "_" and name[3] in self.axes:
            g = self.axes[name[3]]
            value = {"BG": 1 if g.moving() else 0, "MO": 1 if g.motor_off else 0,
                     "TP": g.position(), "TS": g.status_byte(), "SP": g.sp, "AC": g.ac,
                     "DC": g.dc, "PA": g.pa, "JG": g.jg}.get(name[1:3])
            if value is not None:
                return num4(value)
        raise Refused(1)


def make_controller(pty, args):
    letters = args.axes.upper()
    if not letters or any(c not in "ABCDEFGH" for c in letters) or \
            len(set(letters)) != len(letters):
        raise SystemExit("galil: --axes takes letters A-H")
    letters = "".join(sorted(letters))
    chaos = None
    if getattr(args, "chaos", None) is not None:
        rates = [float(r) for r in args.chaos_rates.split(",")]
        if len(rates) != 5:
            raise SystemExit("galil: --chaos-rates takes 5 numbers")
        chaos = Chaos(args.chaos, rates, not args.chaos_paused)
    return Controller(pty, letters, chaos, Journal(getattr(args, "journal", None)))


def self_test(args):
    link = "/tmp/galil_selftest_%d" % os.getpid()
    args.axes = "AB"
    pty = uc.Pty(link, args.baud)
    c = make_controller(pty, args)
    on_bytes = uc.heard_only_at(pty, args.baud, "galil", c.on_bytes)
    threading.Thread(target=uc.run, args=(pty, on_bytes, c.on_tick), daemon=True).start()
    host = uc.TestHost(link, args.baud, 0.1)
    test = uc.SelfTest(host, 0.1)
    check, wait_for = test.check, test.wait_for
    check("TP both axes", host.ask("TP\r"), b" 0, 0\r\n:")
    check("TPA", host.ask("TPA\r"), b" 0\r\n:")
    check("TS motors off", host.ask("TSA\r"), b" 44\r\n:")
    check("unknown command ?", host.ask("XQ\r"), b"?")
    check("TC1 tells why", host.ask("TC1\r"), b"1 Unrecognized command\r\n:")
    check("BG with motor off: 20", host.ask("BGA\rTC1\r"),
          b"?20 Begin not valid with motor off\r\n:")
    check("rest of a refused line dropped", host.ask("BGA;TPA\r"), b"?")
    check("SH;PA;BG: three prompts", host.ask("SHAB;PAA=-25000;BGA\r"), b":::")
    check("B untouched by PAA=", host.ask("PA ?,?\r"), b"-25000, 0\r\n:")
    check("moving: MG _BGA", host.ask("MG _BGA\r"), b" 1.0000\r\n:")
    check("BG while running: 21", host.ask("BGA\rTC1\r"),
          b"?21 Begin not valid while running\r\n:")
    check("done", wait_for("MG _BGA\r", b" 0.0000\r\n:", 3.0), b" 0.0000\r\n:")
    check("negative position", host.ask("TPA\r"), b"-25000\r\n:")
    check("implicit PA ,2000 leaves A", host.ask("PA ,2000\rPAA=?\rPAB=?\r"),
          b":-25000\r\n: 2000\r\n:")
    check("MG _MOA", host.ask("MG _MOA\r"), b" 0.0000\r\n:")
    check("MO while moving: 7", host.ask("JGA=5000;BGA\rMOA\rTC1\r"),
          b"::?7 Command not valid while running\r\n:")
    check("ST", host.ask("STA\r", 0.5), b":")
    check("HM", host.ask("HMA;BGA\r"), b"::")
    check("homed at 0", wait_for("MG _BGA\r", b" 0.0000\r\n:", 6.0), b" 0.0000\r\n:")
    check("position 0 after HM", host.ask("TPA\r"), b" 0\r\n:")
    check("number out of range", host.ask("SPA=-5\rTC1\r"), b"?6 Number out of range\r\n:")
    check("lower case unknown", host.ask("tpa\r"), b"?")
    check("text", host.ask('MG "a;b"\r'), b"a;b\r\n:")
    return test.finish(link, 9600, "TPA\r")


def main():
    ap = uc.unit_arguments(__doc__, 115200)
    ap.add_argument("--axes", default="AB", help="axis letters A-H (e.g. AB)")
    ap.add_argument("--chaos", type=int, default=None, metavar="SEED",
                    help="a bad line: late, dropped, garbled, truncated responses, lost lines")
    ap.add_argument("--chaos-rates", default="0.05,0.04,0.04,0.04,0.03",
                    metavar="LATE,DROP,GARBLE,TRUNCATE,LOST")
    ap.add_argument("--chaos-paused", action="store_true",
                    help="start with the chaos off (SIGUSR1 on, SIGUSR2 off)")
    ap.add_argument("--journal", default=None, metavar="PATH")
    uc.control_argument(ap)
    args = uc.parse_unit_arguments(ap, self_test)
    pty = uc.Pty(args.link, args.baud)
    c = make_controller(pty, args)
    if c.chaos is not None:
        # Applied by the serving loop (on_tick): a handler writing the journal itself could
        # interrupt a journal write.
        signal.signal(signal.SIGUSR1, lambda *_: setattr(c, "chaos_wanted", True))
        signal.signal(signal.SIGUSR2, lambda *_: setattr(c, "chaos_wanted", False))
        c.journal.write("chaos seed %d %s" % (args.chaos, "paused" if args.chaos_paused else "on"))
    uc.log("galil: axes %s at %d baud on %s" % (c.letters, args.baud, args.link))
    uc.run(pty, uc.heard_only_at(pty, args.baud, "galil", c.on_bytes), c.on_tick,
           control=uc.Control.open(args.control, c))


if __name__ == "__main__":
    main()
