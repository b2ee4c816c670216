#!/usr/bin/python3
"""Newport ESP301 three-axis motion controller (RS-232), written from the ESP300-series user's
manual, section 3 "Remote Mode" (the ESP301 manual EDH0235En1030 shares its command set), as
far as its pages could be read, and from public drivers' transcriptions of its error appendix
where the pages were not at hand (see "Sources"). Nothing here is taken from sim/, drivers/
or config/.

  esp301_unit.py --link PATH [--axes 1,2] [--baud 19200] [--decimals N]
                 [--log first|all|none] [--self-test]

Facts from the manual:
- Syntax `xxAAnn`: axis number xx (range 1 to MAX AXES), two-letter mnemonic AA, parameter nn.
  Missing axis: error 37 AXIS NUMBER MISSING; out of range: error 9 AXIS NUMBER OUT OF RANGE;
  missing parameter: 38 COMMAND PARAMETER MISSING.
- PA/PR (IMM, PGM and MIP: accepted while a motion is in progress): a target beyond the
  software limits is error xx06 POSITIVE / xx07 NEGATIVE SOFTWARE LIMIT (xx = axis); a
  hardware limit met is xx04 / xx05. A move for a motor that is off is xx13 MOTOR NOT
  ENABLED. Axis errors are axis*100 + code: `113` = axis 1 motor not enabled.
- MD? returns 0 while a motion is in progress, 1 when it is done. `3MV+` / `3MV-` move axis 3
  indefinitely; `3MV?` answers 0 while it moves (the manual's example).
- TB? returns `code, timestamp, message`, e.g. `0, 451322, NO ERROR DETECTED` or
  `9, 451339, AXIS NUMBER NOT AVAILABLE`; the timestamp counts servo cycles (400 us) since the
  last reset. Errors sit in a FIFO ten deep; TB? or TE? removes one element, so an error is read
  once, by either command. TE? returns the code alone.
- PH returns two hexadecimal registers, `18000404H, 4H` (the manual's example). First
  register: bit n-1 axis n positive hardware travel limit, bit n+7 axis n negative travel
  limit (the layout the EPICS drvESP300 driver reads); second register: bit n-1 axis n home
  signal, bits 8..10 index signals, 16/17 digital inputs A/B (manual p.3-111).
- TS returns a status character: bit 0..2 axis 1..3 in motion, bit 4 motor power of at least
  one axis on; the example `[P` shows bit 6 always set (an ASCII letter), so TS = 0x40 | bits.
- Responses end with CR LF (the manual's section 3.4 note, quoted by drvESP300).

Readings chosen where the manual (as found) is silent or was not at hand:
- Commands end in CR; LF is ignored. Several commands may share a line separated by `;`; each
  query answers on its own CR-LF line, in order. Upper/lower case both accepted; blanks
  ignored. The axis number is read as a decimal integer, so `01TP?` and `1TP?` both address
  axis 1 (the EPICS driver sends `%.2d` prefixes to real ESP300/301 units). Axes that are not
  in --axes (or > 3) are error 9.
- Read-only queries accept the `?` or not: `1TP?`/`1TP`, `1MD?`/`1MD` (drvESP300 sends `MD`
  bare), `PH`/`PH?`/`01PH` (the axis prefix of PH is ignored), `TB?`, `TE?`, `TS`.
- TP? prints the position in user units (mm) with trailing zeros removed, as the manual's
  examples print (`5.32`); --decimals N prints exactly N decimals instead.
- Power-up: all motors off, not homed, positions 0. VA 2.5, VU 5, AC = AG 10, AU 20 (mm/s,
  mm/s^2), SL -25, SR 25; the home switch 10 mm on the negative side of the power-up position
  (home signal high below it), hardware travel limits 0.5 mm beyond SL/SR from there. Axes that
  are not in --axes read both travel limits high in PH (like the example's unconnected axis 3).
- Error codes used: 6 COMMAND DOES NOT EXIST, 7 PARAMETER OUT OF RANGE, 9, 37, 38,
  xx04/xx05 (hardware limit met while moving: the axis stops there), xx06/xx07 (a target
  beyond SL/SR is refused; an MV that reaches SL/SR stops there with the same codes),
  xx10 MAXIMUM VELOCITY EXCEEDED (VA > VU), xx11 MAXIMUM ACCELERATION EXCEEDED (AC/AG > AU),
  xx13 MOTOR NOT ENABLED, xx20 HOMING ABORTED (ST during OR), xx30 COMMAND NOT ALLOWED
  DURING HOMING (PA/PR/MV/OR while homing). A full FIFO drops its oldest error.
- Error 9's text: the PA/PR/ID pages say AXIS NUMBER OUT OF RANGE, the TB? example prints
  `9, 451339, AXIS NUMBER NOT AVAILABLE`; this module uses the former.
- The manual calls the buffer a FIFO but says TB/TE return "the last error that occurred":
  read here as FIFO order (the oldest unread error first).
- MO / MF with no axis apply to every axis; `1MO?` answers 1/0. MF stops a moving axis at
  once. ST with no axis stops every axis (decelerating at AG). AB stops every axis without
  deceleration and turns every motor off.
- OR<n>: 0 go to position count 0; 1 home switch and index, 2 home switch (both: run at OH
  2.5 mm/s to the home signal's edge, set 0 there; the index is taken at the edge); 3/5 positive
  and 4/6 negative limit (run to the switch, set 0 there). OR without a mode uses mode 1. MD? is
  0 while homing. DH<nn> defines the current position as nn (default 0).
- Unsolicited lines: the manual describes only the polled FIFO (TB?/TE?) and no message the
  unit sends on its own, and says nothing of silence after a travel limit. The issue's
  "ESP301 sends `E…` lines on its own and stays silent 2-5 s after hitting a travel limit"
  has no support in the pages found (drvESP300's recv_mess only guesses at "an unsolicited
  error message response?" and calls it "an unconfirmed ESP300 bug"), so no
  --unsolicited-errors option is offered.
- Bytes sent at another host baud rate than --baud are unreadable and dropped.

Sources: easymanua.ls/newport/esp300-series/manual pages 92 (DP, TP example), 141 (MV), 151
(PH), 152 (PR), 178 (TB), 182 (TS); manualshive ESP300 page 184 (TX); scribd 349711322
"ESP301 User's Manual" (title and scope only); error appendix as transcribed by pymeasure's
ESP300 and InstrumentKit's ESP301 drivers; epics-motor/motorNewport drvESP300.cc (PH bit
layout, `%.2d` axis prefixes, CR LF terminator note).
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

SCALE = 100000.0  # axis counts per mm
HOME_SWITCH_MM = -10.0
TICK = 0.0004  # servo cycle, TB timestamps

GENERAL = {0: "NO ERROR DETECTED", 6: "COMMAND DOES NOT EXIST", 7: "PARAMETER OUT OF RANGE",
           9: "AXIS NUMBER OUT OF RANGE", 27: "COMMAND NOT ALLOWED", 37: "AXIS NUMBER MISSING",
           38: "COMMAND PARAMETER MISSING"}
AXIS_ERRORS = {4: "POSITIVE HARDWARE LIMIT DETECTED", 5: "NEGATIVE HARDWARE LIMIT DETECTED",
               6: "POSITIVE SOFTWARE LIMIT DETECTED", 7: "NEGATIVE SOFTWARE LIMIT DETECTED",
               10: "MAXIMUM VELOCITY EXCEEDED", 11: "MAXIMUM ACCELERATION EXCEEDED",
               13: "MOTOR NOT ENABLED", 20: "HOMING ABORTED",
               30: "COMMAND NOT ALLOWED DURING HOMING"}

rx = uc.rx


class Refused(Exception):
    def __init__(self, code):
        self.code = code


class EspAxis:
    def __init__(self, n):
        self.n = n
        self.axis = uc.Axis(home_switch=HOME_SWITCH_MM * SCALE)
        self.motor = False
        self.va, self.vu, self.ac, self.ag, self.au, self.oh = 2.5, 5.0, 10.0, 10.0, 20.0, 2.5
        self.sl, self.sr = -25.0, 25.0
        self.axis.limit_neg = (HOME_SWITCH_MM + self.sl - 0.5) * SCALE
        self.axis.limit_pos = (HOME_SWITCH_MM + self.sr + 0.5) * SCALE
        self.target = 0.0
        self.dh = 0.0
        self.mode = None  # None, "move", "jog", "home", "stop"
        self.home_kind = None  # "switch", "limit+", "limit-"
        self.home_dir = 0
        self.set_ramp()

    def power_up(self):
        """Power removed and restored: the stage stops where it is (no power to ramp it down)
        and stays there with its switches; the axis is as at power-up, motor off, not homed,
        position 0, parameters at their defaults."""
        axis = self.axis
        axis.power_up(0.0)
        self.__init__(self.n)
        self.axis = axis
        self.set_ramp()

    def set_ramp(self):
        self.axis.accel = self.ac * SCALE
        self.axis.decel = self.ag * SCALE

    def pos(self):
        return self.axis.position() / SCALE

    def busy(self):
        return self.mode is not None

    def err(self, code):
        return self.n * 100 + code


class Esp301:
    def __init__(self, pty, axes, decimals):
        self.pty = pty
        self.decimals = decimals
        self.axes = {n: EspAxis(n) for n in axes}
        self.fifo = collections.deque()
        self.t0 = time.monotonic()
        self.buf = bytearray()

    # -- errors
    def push(self, code, now):
        if len(self.fifo) >= 10:
            self.fifo.popleft()
        self.fifo.append((code, int((now - self.t0) / TICK)))

    def text(self, code):
        if code >= 100:
            return AXIS_ERRORS.get(code % 100, "AXIS ERROR")
        return GENERAL.get(code, "ERROR")

    def pop(self, now):
        if self.fifo:
            return self.fifo.popleft()
        return 0, int((now - self.t0) / TICK)

    def control(self, line, now):
        """The test's requests (unit_common.Control). A power cycle concerns the whole
        controller (WHO, an axis number, must be one of its axes): every axis as at power-up,
        the error FIFO and any half-received line gone."""
        def power_cycle(who):
            if who is not None and (not who.isdigit() or int(who) not in self.axes):
                return None
            self.on_tick(now)  # the motion up to this instant
            was = " ".join("%d %s" % (n, self.fmt(ax.pos())) for n, ax in self.axes.items())
            for ax in self.axes.values():
                ax.power_up()
            self.fifo.clear()
            self.buf = bytearray()
            uc.log("esp301: power-cycled at %s mm: motors off, not homed, positions 0" % was)
            return "controller"

        def state():
            return {str(n): (ax.pos(), ax.axis.moving()) for n, ax in self.axes.items()}
        return uc.control_request(self, line.split(), power_cycle, state)

    def fmt(self, v):
        if self.decimals is not None:
            return "%.*f" % (self.decimals, v)
        s = ("%.6f" % v).rstrip("0").rstrip(".")
        return "0" if s in ("-0", "", "-") else s

    # -- line handling
    def on_bytes(self, data, now):
        for b in data:
            if b == 0x0D:
                text = bytes(self.buf).decode("ascii", errors="replace")
                self.buf.clear()
                if text.strip():
                    rx(text)
                    self.line(text, now)
            elif b != 0x0A:
                self.buf.append(b)
                if len(self.buf) > 512:
                    del self.buf[:-512]

    def line(self, text, now):
        out = []
        for cmd in text.split(";"):
            cmd = cmd.replace(" ", "").replace("\t", "").upper()
            if not cmd:
                continue
            try:
                reply = self.command(cmd, now)
            except Refused as r:
                self.push(r.code, now)
                continue
            if reply is not None:
                out.append(reply + "\r\n")
        if out:
            self.pty.send("".join(out).encode())

    def axis_of(self, digits, required=True):
        if digits == "":
            if required:
                raise Refused(37)
            return None
        n = int(digits)
        if n not in self.axes:
            raise Refused(9)
        return self.axes[n]

    def command(self, cmd, now):
        m = re.match(r"(\d*)([A-Z]{2})(.*)$", cmd)
        if not m:
            raise Refused(6)
        digits, code, param = m.groups()
        query = param == "?"
        if code == "TB":
            c, stamp = self.pop(now)
            return "%d, %d, %s" % (c, stamp, self.text(c))
        if code == "TE":
            return "%d" % self.pop(now)[0]
        if code == "PH":
            return self.hardware_status()
        if code == "TS":
            bits = 0x40
            for ax in self.axes.values():
                if ax.busy():
                    bits |= 1 << (ax.n - 1)
                if ax.motor:
                    bits |= 0x10
            return chr(bits)
        if code == "VE":
            return "ESP301 Version 3.0 (independent simulator)"
        if code in ("MO", "MF") and digits == "" and not query:
            for ax in self.axes.values():
                self.power(ax, code == "MO")
            return None
        if code == "ST" and digits == "":
            for ax in self.axes.values():
                self.stop(ax, now)
            return None
        if code == "AB":
            for ax in self.axes.values():
                ax.axis.hard_stop()
                ax.mode = None
                ax.motor = False
            return None
        if code not in ("TP", "MD", "MO", "MF", "PA", "PR", "OR", "ST", "MV", "VA", "VU", "AC",
                        "AG", "AU", "SL", "SR", "DH", "OH"):
            raise Refused(6)
        ax = self.axis_of(digits)
        if code == "TP":
            return self.fmt(ax.pos())
        if code == "MD" or (code == "MV" and query):
            return "0" if ax.busy() else "1"
        if code in ("MO", "MF"):
            if query:
                return "1" if ax.motor else "0"
            self.power(ax, code == "MO")
            return None
        if code == "ST":
            self.stop(ax, now)
            return None
        if code in ("PA", "PR"):
            if query:
                return self.fmt(ax.target)
            return self.move(ax, code, self.number(param))
        if code == "MV":
            return self.jog(ax, param)
        if code == "OR":
            return self.home(ax, param)
        if code == "DH":
            if query:
                return self.fmt(ax.dh)
            value = self.number(param) if param else 0.0
            ax.dh = value
            ax.axis.set_position(value * SCALE)
            ax.target = value
            return None
        return self.parameter(ax, code, param)

    def number(self, param):
        if param == "":
            raise Refused(38)
        try:
            return float(param)
        except ValueError:
            raise Refused(7)

    def parameter(self, ax, code, param):
        names = {"VA": "va", "VU": "vu", "AC": "ac", "AG": "ag", "AU": "au", "SL": "sl",
                 "SR": "sr", "OH": "oh"}
        if param == "?":
            return self.fmt(getattr(ax, names[code]))
        v = self.number(param)
        if code in ("VA", "VU", "AC", "AG", "AU", "OH") and v < 0:
            raise Refused(7)
        if code in ("VA", "OH") and v > ax.vu:
            raise Refused(ax.err(10))
        if code in ("AC", "AG") and v > ax.au:
            raise Refused(ax.err(11))
        setattr(ax, names[code], v)
        if code in ("AC", "AG"):
            ax.set_ramp()
        return None

    def power(self, ax, on):
        if not on and ax.busy():
            ax.axis.hard_stop()
            ax.mode = None
            ax.target = ax.pos()
        ax.motor = on

    def stop(self, ax, now):
        if not ax.busy():
            return
        if ax.mode == "home":
            self.push(ax.err(20), now)
        ax.mode = "stop"
        ax.axis.stop(decel=ax.ag * SCALE)

    def check_motion(self, ax):
        if not ax.motor:
            raise Refused(ax.err(13))
        if ax.mode == "home":
            raise Refused(ax.err(30))

    def move(self, ax, code, v):
        self.check_motion(ax)
        base = ax.target if ax.busy() else ax.pos()
        target = v if code == "PA" else base + v
        if target > ax.sr:
            raise Refused(ax.err(6))
        if target < ax.sl:
            raise Refused(ax.err(7))
        if target > ax.pos() and ax.axis.limit_active(1):
            raise Refused(ax.err(4))
        if target < ax.pos() and ax.axis.limit_active(-1):
            raise Refused(ax.err(5))
        ax.target = target
        ax.mode = "move"
        ax.set_ramp()
        ax.axis.move_to(target * SCALE, ax.va * SCALE)
        return None

    def jog(self, ax, param):
        if param not in ("+", "-"):
            raise Refused(38 if param == "" else 7)
        self.check_motion(ax)
        sign = 1 if param == "+" else -1
        if ax.axis.limit_active(sign):
            raise Refused(ax.err(4 if sign > 0 else 5))
        ax.mode = "jog"
        ax.set_ramp()
        ax.axis.run_at(sign * ax.va * SCALE)
        return None

    def home(self, ax, param):
        mode = 1
        if param:
            try:
                mode = int(param)
            except ValueError:
                raise Refused(7)
            if not 0 <= mode <= 6:
                raise Refused(7)
        self.check_motion(ax)
        if ax.busy():
            raise Refused(27)
        ax.set_ramp()
        if mode == 0:
            ax.target = 0.0
            ax.mode = "move"
            ax.axis.move_to(0.0, ax.oh * SCALE)
            return None
        ax.mode = "home"
        if mode in (1, 2):
            ax.home_kind = "switch"
            ax.home_dir = 1 if ax.axis.home_input_high() else -1
        else:
            ax.home_kind = "limit"
            ax.home_dir = 1 if mode in (3, 5) else -1
        ax.axis.run_at(ax.home_dir * ax.oh * SCALE)
        return None

    def hardware_status(self):
        first = second = 0
        for n in (1, 2, 3):
            ax = self.axes.get(n)
            if ax is None:
                first |= 1 << (n - 1) | 1 << (n + 7)
                continue
            if ax.axis.limit_active(1):
                first |= 1 << (n - 1)
            if ax.axis.limit_active(-1):
                first |= 1 << (n + 7)
            if ax.axis.home_input_high():
                second |= 1 << (n - 1)
        return "%XH, %XH" % (first, second)

    def on_tick(self, now):
        for ax in self.axes.values():
            ax.axis.tick(now)
            if ax.mode == "home":
                done = False
                if ax.home_kind == "switch":
                    done = ax.axis.home_input_high() != (ax.home_dir > 0)
                else:
                    done = ax.axis.limit_active(ax.home_dir)
                if done:
                    ax.axis.hard_stop()
                    ax.axis.set_position(0.0)
                    ax.target = 0.0
                    ax.mode = None
                elif not ax.axis.moving():  # switch never found: stopped on a limit
                    ax.mode = None
                    self.push(ax.err(20), now)
                continue
            if ax.mode == "jog":
                p = ax.pos()
                if p >= ax.sr or p <= ax.sl:
                    ax.axis.hard_stop()
                    ax.axis.set_position((ax.sr if p >= ax.sr else ax.sl) * SCALE)
                    self.push(ax.err(6 if p >= ax.sr else 7), now)
            if ax.mode and not ax.axis.moving():
                if ax.axis.hit_limit:
                    self.push(ax.err(4 if ax.axis.hit_limit > 0 else 5), now)
                    ax.axis.hit_limit = 0
                ax.mode = None
                ax.target = ax.pos()


# ---------------------------------------------------------------------------------------------
# Self-test

def Host(link, baud):
    return uc.TestHost(link, baud, 0.15)


def self_test(args):
    link = "/tmp/esp301_selftest_%d" % os.getpid()
    pty = uc.Pty(link, args.baud)
    unit = Esp301(pty, [1, 2], args.decimals)
    on_bytes = uc.heard_only_at(pty, args.baud, "esp301", unit.on_bytes)
    threading.Thread(target=uc.run, args=(pty, on_bytes, unit.on_tick), daemon=True).start()
    host = Host(link, args.baud)
    test = uc.SelfTest(host, 0.1)
    check, wait_for = test.check, test.wait_for



    tb = lambda code, text: (lambda got: re.fullmatch(rb"%d, \d+, %s\r\n" % (code, text), got))
    check("power-up position", host.ask("1TP?\r"), b"0\r\n")
    check("leading zero axis", host.ask("01TP?\r"), b"0\r\n")
    check("motor off", host.ask("1MO?\r"), b"0\r\n")
    check("motion done", host.ask("01MD\r"), b"1\r\n")
    check("empty buffer", host.ask("TB?\r"), tb(0, b"NO ERROR DETECTED"))
    check("PA with motor off: silent", host.ask("1PA5\r"), b"")
    check("... 113 queued", host.ask("TB?\r"), tb(113, b"MOTOR NOT ENABLED"))
    check("axis 3 not present", host.ask("3TP?\rTE?\r"), b"9\r\n")
    check("unknown command", host.ask("1XX\rTE?\r"), b"6\r\n")
    check("axis missing", host.ask("PA1\rTE?\r"), b"37\r\n")
    check("PH at rest (axis 3 absent)", host.ask("PH\r"), b"404H, 0H\r\n")
    check("two queries on a line", host.ask("1TP?;2TP?\r"), b"0\r\n0\r\n")
    host.ask("MO\r")
    check("TS: power on, still", host.ask("TS\r"), b"P\r\n")
    check("target beyond SR", host.ask("1PA30\rTE?\r"), b"106\r\n")
    host.ask("1OR\r", 0.05)
    check("homing: MD 0", host.ask("1MD?\r"), b"0\r\n")
    check("PA while homing", host.ask("1PA1\rTE?\r"), b"130\r\n")
    check("home done", wait_for("1MD?\r", b"1\r\n", 7.0), b"1\r\n")
    check("homed at 0", host.ask("1TP?\r"), b"0\r\n")
    host.ask("1VA5\r1PA2.5\r", 0.05)
    check("moving: TS bit 0", host.ask("TS\r"), b"Q\r\n")
    check("move done", wait_for("1MD?\r", b"1\r\n", 3.0), b"1\r\n")
    check("at 2.5", host.ask("1TP?\r"), b"2.5\r\n")
    check("VA above VU", host.ask("1VA9\rTE?\r"), b"110\r\n")
    host.ask("2MV+\r", 0.05)
    check("jog: MV? 0", host.ask("2MV?\r"), b"0\r\n")
    check("jog reaches + limit", wait_for("2MD?\r", b"1\r\n", 8.0), b"1\r\n")
    check("... 204 queued", host.ask("TB?\r"), tb(204, b"POSITIVE HARDWARE LIMIT DETECTED"))
    check("PH shows axis 2 + limit", host.ask("PH\r"), b"406H, 0H\r\n")
    host.ask("2MV-\r", 0.3)
    host.ask("2ST\r", 0.6)
    check("ST stops the jog", host.ask("2MD?\r"), b"1\r\n")
    host.ask("MF\r")
    check("MF: all motors off", host.ask("1MO?\r2MO?\r"), b"0\r\n0\r\n")
    return test.finish(link, 9600, "1TP?\r")


def main():
    ap = uc.unit_arguments(__doc__, 19200)
    ap.add_argument("--axes", default="1,2", help="axes with a stage, of 1..3")
    ap.add_argument("--decimals", type=int, default=None,
                    help="print TP? etc. with exactly N decimals (default: trimmed)")
    uc.control_argument(ap)
    args = uc.parse_unit_arguments(ap, self_test)
    axes = [int(a) for a in args.axes.split(",") if a]
    if any(not 1 <= a <= 3 for a in axes):
        ap.error("axes are 1..3")
    pty = uc.Pty(args.link, args.baud)
    unit = Esp301(pty, axes, args.decimals)
    uc.log("esp301: axes %s at %d baud on %s" % (args.axes, args.baud, args.link))
    uc.run(pty, uc.heard_only_at(pty, args.baud, "esp301", unit.on_bytes), unit.on_tick,
           control=uc.Control.open(args.control, unit))


if __name__ == "__main__":
    main()
