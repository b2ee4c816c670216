#!/usr/bin/python3
"""Newport SMC100CC / SMC100PP single-axis controllers on one RS-485 line (up to 31 addresses),
written from the SMC100CC & SMC100PP user's manual (EDH0206En, section 6 "Commands") as far as
it could be read, and from secondary transcriptions of its tables where the manual's own pages
were not at hand (see "Sources"). Nothing here is taken from sim/, drivers/ or config/.

  smc100_unit.py --link PATH [--addresses 1,2] [--baud 57600] [--decimals N]
                 [--limit-error C|G] [--log first|all|none] [--self-test]
                 [--chaos SEED [--chaos-paused]] [--journal PATH]

Facts from the manual (6.3 Command Syntax, manualslib page 26 of EDH0206En2042):
- Command format `nnAAxx`: optional/required controller address nn, a two-letter command
  name, an optional value or `?` to query. Upper and lower case are accepted. Blanks are
  allowed and ignored in any position, even inside a number (`2P A1.43 6` = `2PA1.436`).
- A dot is the decimal separator. Commands execute when the terminator CR LF arrives; after
  the execution "all remaining characters in the input string, if any, will be ignored" (no
  concatenation of commands). An invalid command or parameter is not executed: the error is
  memorised and read with TE.
- Replies repeat address and command: `1TS000032`, `1TE@`, `1TP...`, each ending CR LF.
  Set commands (PA, PR, OR, ST, MM, RS, VA, AC, SL, SR) produce no reply.
- TS returns `1TSabcdef`: 4 hex digits of positioner error bits, 2 characters of controller
  state. Positioner errors (SMC100CC): bit 0 negative end of run, 1 positive end of run,
  2 peak current limit, 3 RMS current limit, 4 short circuit, 5 following error, 6 homing
  time-out, 7 wrong ESP stage, 8 DC voltage too low, 9 80 W output power exceeded.
  States: 0A..0F NOT REFERENCED from reset/homing/configuration/disable/ready/moving,
  10 NOT REFERENCED ESP stage error, 11 NOT REFERENCED from jogging, 14 CONFIGURATION,
  1E HOMING (RS-232-C), 1F HOMING (SMC-RC), 28 MOVING, 32..35 READY from homing/moving/
  disable/jogging, 3C..3E DISABLE from ready/moving/jogging, 46/47 JOGGING from ready/disable.
- TE letters: @ no error, A unknown message code or floating point controller address,
  B controller address not correct, C parameter missing or out of range, D command not
  allowed, E home sequence already started, F ESP stage name unknown, G displacement out of
  limits, H..M command not allowed in NOT REFERENCED / CONFIGURATION / DISABLE / READY /
  HOMING / MOVING state, N current position out of software limit, S communication time out,
  U error during EEPROM access, V error during command execution, W not allowed for PP
  version, X not allowed for CC version.
- There is no jog command on the RS-485 line: the JOGGING states are entered from the SMC-RC
  hand-held remote's keys; JD only leaves the JOGGING state. Nothing here can jog.

Readings chosen where the manual (as found) is silent or was not at hand:
- Terminator: a line executes on LF; a CR right before it is dropped. A line ending in CR
  alone waits for its LF (the terminator is the pair). A line without an address, or for an
  address that is not in --addresses, is ignored (no controller claims it; a real chain would
  be silent too). The address is read as a decimal integer, so `01TS` is address 1.
- Position format: `%.6f` with trailing zeros (and a trailing dot) removed: `1TP10.5`,
  `1TP0`, `1TP-2.000125`. --decimals N prints exactly N decimals instead (`1TP10.500000`).
  VA/AC/SL/SR/PA?/PR? read-backs use the same format.
- PA/PR are executed only in READY (32..35); in the other states the state's letter (H, I, J,
  L, M) is memorised. A target outside SL..SR is refused with C (--limit-error G memorises
  G, "displacement out of limits", the other letter the table offers). PR is relative to the
  current set-point. A missing or non-numeric value is C.
- OR only in NOT REFERENCED (any 0A..11): HOMING 1E, the stage runs at OH (home search
  velocity, 2.5 mm/s) to the home switch edge (10 mm on the negative side of the power-up
  position), stops, sets the position to 0 and goes READY from HOMING (32). OR while HOMING
  memorises E; in READY K, MOVING M, DISABLE J.
- ST: MOVING decelerates at AC and ends READY from MOVING (33); HOMING stops and ends
  NOT REFERENCED from HOMING (0B); elsewhere ST does nothing and memorises nothing.
- MM0 (enter DISABLE): READY -> 3C, MOVING -> 3D (the motion stops at once, motor off);
  MM1 (leave DISABLE): 3C..3E -> READY from DISABLE (34). MM in NOT REFERENCED is H, in
  HOMING L, in CONFIGURATION I; MM1 in READY / MM0 in DISABLE do nothing. `MM?` answers
  `1MM<state>`.
- RS: the controller reboots; it hears nothing for 1.0 s, then powers up as at power-on
  (NOT REFERENCED from reset, position 0 where it stands, VA/AC/SL/SR back to defaults, TE @).
- VA (velocity, mm/s, > 1e-6 and < 1e12), AC (mm/s^2, same range), SL (-1e12..0), SR
  (0..1e12): out of range C; in MOVING M, in HOMING L; `VA?` etc. answer `1VA2.5`.
  Defaults VA 2.5, AC 10, SL -25, SR 25 (a 50 mm stage); the end-of-run switches sit 0.5 mm
  beyond SL and SR from the home position.
- TH (set-point position) answers like TP (no following error is modelled).
- TB: `1TBC` answers `1TBC Parameter missing or out of range.` (letter, space, the table's
  text); `1TB` alone answers the memorised error's text without clearing it; an unknown
  letter memorises C. VE answers `1VE SMC_CC 2.0.0 (independent simulator)`.
- A two-letter code this module does not know memorises A (including real ones not modelled
  here, e.g. KP, ZT, PW).
- No fault state can be provoked through the line (following error, current limits, ESP
  stage errors come from the hardware); the refused target is the error this unit offers.
- Bytes sent at another host baud rate than --baud are unreadable and dropped.

Test instruments (not the manual's; without these flags nothing changes):
- --journal PATH: one line per command executed (`T exec 1PA2.5 ok state=28 target=2.5
  pos=0`, or `refused=C` for one that memorised an error) and per reply queued for the wire
  (`T sent 1TP1.5`, `T sent 1TP1.5 late=312ms`), and one per injected fault (`T fault drop
  1TP1.5`, `T fault garble 1TP1.5 -> <hex>`, `T fault truncate 1TP1.5 -> <hex>`, `T fault
  lost-command 1PA2.5`). T is time.monotonic() (seconds). Flushed per line.
- --chaos SEED: a bad line, from random.Random(SEED): a reply is late (250-400 ms, and the
  replies behind it wait too: the device answers its backlog), dropped, garbled (1-3 of its
  characters get bit 7 set, so it cannot spell another valid reply) or truncated; an incoming
  command line is lost (never heard: neither executed nor journaled as executed). Rates: the
  --chaos-rates option. --chaos-paused starts with the chaos off; SIGUSR1 turns it on, SIGUSR2
  off (journaled as `T chaos on|off`).

Sources: manualslib.com/manual/1238858/Newport-Smc100cc.html (page 26, 6.3 Command Syntax and
6.4 Command Execution Time); the state, positioner-error and command-error tables as
transcribed (identically) by several public drivers citing "SMC100CC User Manual p.61/p.65";
the NPC1USB manual's TS page (same Newport command family) for the `1TSabcdef` layout.
"""
import argparse
import os
import random
import re
import select
import signal
import sys
import termios
import threading
import time
import tty

import unit_common as uc

SCALE = 100000.0  # axis counts per mm (uc.Axis works in counts)
HOME_SWITCH_MM = -10.0  # physical, relative to the power-up position
RESET_TIME = 1.0

ERRORS = {
    "@": "No error.",
    "A": "Unknown message code or floating point controller address.",
    "B": "Controller address not correct.",
    "C": "Parameter missing or out of range.",
    "D": "Command not allowed.",
    "E": "Home sequence already started.",
    "F": "ESP stage name unknown.",
    "G": "Displacement out of limits.",
    "H": "Command not allowed in NOT REFERENCED state.",
    "I": "Command not allowed in CONFIGURATION state.",
    "J": "Command not allowed in DISABLE state.",
    "K": "Command not allowed in READY state.",
    "L": "Command not allowed in HOMING state.",
    "M": "Command not allowed in MOVING state.",
    "N": "Current position out of software limit.",
    "S": "Communication Time Out.",
    "U": "Error during EEPROM access.",
    "V": "Error during command execution.",
    "W": "Command not allowed for PP version.",
    "X": "Command not allowed for CC version.",
}

NOT_REFERENCED = {"0A", "0B", "0C", "0D", "0E", "0F", "10", "11"}
READY = {"32", "33", "34", "35"}
DISABLE = {"3C", "3D", "3E"}
HOMING = {"1E", "1F"}
MOVING = {"28"}
CONFIGURATION = {"14"}

rx = uc.rx


def state_letter(state):
    """The error letter for a command refused in `state`."""
    if state in NOT_REFERENCED:
        return "H"
    if state in CONFIGURATION:
        return "I"
    if state in DISABLE:
        return "J"
    if state in READY:
        return "K"
    if state in HOMING:
        return "L"
    return "M"


class Controller:
    def __init__(self, address, decimals, limit_error):
        self.address = address
        self.decimals = decimals
        self.limit_error = limit_error
        self.axis = uc.Axis(home_switch=HOME_SWITCH_MM * SCALE)
        self.power_up()

    def power_up(self):
        self.va, self.ac, self.oh = 2.5, 10.0, 2.5
        self.sl, self.sr = -25.0, 25.0
        self.state = "0A"
        self.error = "@"
        self.stopping_to = None
        self.home_dir = 0
        self.last_pr = 0.0
        self.axis.hard_stop()
        self.axis.accel = self.axis.decel = self.ac * SCALE
        self.axis.set_position(0.0)
        self.target = 0.0
        self.set_switches()
        self.booting_until = None

    def set_switches(self):
        """End-of-run switches 0.5 mm beyond SL/SR, measured from the home switch."""
        self.axis.limit_neg = (HOME_SWITCH_MM + self.sl - 0.5) * SCALE
        self.axis.limit_pos = (HOME_SWITCH_MM + self.sr + 0.5) * SCALE

    def fmt(self, v):
        if self.decimals is not None:
            return "%.*f" % (self.decimals, v)
        s = ("%.6f" % v).rstrip("0").rstrip(".")
        return "0" if s in ("-0", "", "-") else s

    def position(self):
        return self.axis.position() / SCALE

    def positioner_errors(self):
        bits = 0
        if self.axis.limit_active(-1):
            bits |= 0x0001
        if self.axis.limit_active(1):
            bits |= 0x0002
        return bits

    # One command (blanks removed, address stripped): returns the reply text or None.
    def execute(self, code, param, now):
        a = "%d" % self.address
        if code == "TS":
            return "%sTS%04X%s" % (a, self.positioner_errors(), self.state)
        if code in ("TP", "TH"):
            return "%s%s%s" % (a, code, self.fmt(self.position()))
        if code == "TE":
            e, self.error = self.error, "@"
            return "%sTE%s" % (a, e)
        if code == "TB":
            letter = param[:1].upper() if param else self.error
            if letter not in ERRORS:
                self.error = "C"
                return None
            return "%sTB%s %s" % (a, letter, ERRORS[letter])
        if code == "VE":
            return "%sVE SMC_CC 2.0.0 (independent simulator)" % a
        if code in ("PA", "PR"):
            return self.move(code, param)
        if code == "OR":
            if self.state in NOT_REFERENCED:
                self.state = "1E"
                self.home_dir = 1 if self.axis.home_input_high() else -1
                self.axis.accel = self.axis.decel = self.ac * SCALE
                self.axis.run_at(self.home_dir * self.oh * SCALE)
            elif self.state in HOMING:
                self.error = "E"
            else:
                self.error = state_letter(self.state)
            return None
        if code == "ST":
            if self.state in MOVING:
                self.axis.stop(decel=self.ac * SCALE)
                self.stopping_to = "33"
            elif self.state in HOMING:
                self.axis.stop(decel=self.ac * SCALE)
                self.stopping_to = "0B"
            return None
        if code == "MM":
            return self.motor(param)
        if code == "RS":
            self.axis.hard_stop()
            self.booting_until = now + RESET_TIME
            return None
        if code in ("VA", "AC", "SL", "SR"):
            return self.parameter(code, param)
        if code == "JD":
            return None  # leaves JOGGING, which the line cannot enter
        self.error = "A"
        return None

    def number(self, param):
        """The parameter as a number, or None with error C (parameter missing or out of range)."""
        try:
            return float(param)
        except ValueError:
            self.error = "C"
            return None

    def parameter(self, code, param):
        a = "%d" % self.address
        if param.startswith("?"):
            value = {"VA": self.va, "AC": self.ac, "SL": self.sl, "SR": self.sr}[code]
            return "%s%s%s" % (a, code, self.fmt(value))
        if self.state in MOVING | HOMING:
            self.error = state_letter(self.state)
            return None
        v = self.number(param)
        if v is None:
            return None
        ok = {"VA": 1e-6 < v < 1e12, "AC": 1e-6 < v < 1e12,
              "SL": -1e12 <= v <= 0, "SR": 0 <= v <= 1e12}[code]
        if not ok:
            self.error = "C"
            return None
        if code == "VA":
            self.va = v
        elif code == "AC":
            self.ac = v
            self.axis.accel = self.axis.decel = v * SCALE
        elif code == "SL":
            self.sl = v
        else:
            self.sr = v
        return None

    def move(self, code, param):
        a = "%d" % self.address
        if param.startswith("?"):
            return "%s%s%s" % (a, code, self.fmt(self.target if code == "PA" else self.last_pr))
        if self.state not in READY:
            self.error = state_letter(self.state)
            return None
        v = self.number(param)
        if v is None:
            return None
        target = v if code == "PA" else self.target + v
        if not self.sl <= target <= self.sr:
            self.error = self.limit_error
            return None
        if code == "PR":
            self.last_pr = v
        self.target = target
        self.state = "28"
        self.stopping_to = None
        self.axis.accel = self.axis.decel = self.ac * SCALE
        self.axis.move_to(target * SCALE, self.va * SCALE)
        return None

    def motor(self, param):
        a = "%d" % self.address
        if param.startswith("?"):
            return "%sMM%s" % (a, self.state)
        if param not in ("0", "1"):
            self.error = "C"
            return None
        if self.state in NOT_REFERENCED | HOMING | CONFIGURATION:
            self.error = state_letter(self.state)
        elif param == "0":
            if self.state in READY:
                self.state = "3C"
            elif self.state in MOVING:
                self.axis.hard_stop()
                self.target = self.position()
                self.state = "3D"
        elif self.state in DISABLE:
            self.target = self.position()
            self.state = "34"
        return None

    def tick(self, now):
        if self.booting_until is not None:
            if now >= self.booting_until:
                self.power_up()
            return
        self.axis.tick(now)
        if self.state in HOMING:
            if self.stopping_to is None and self.axis.home_input_high() != (self.home_dir > 0):
                self.axis.hard_stop()
                self.axis.set_position(0.0)
                self.target = 0.0
                self.state = "32"
            elif self.stopping_to and not self.axis.moving():
                self.state, self.stopping_to = self.stopping_to, None
            elif not self.axis.moving():  # ran into an end of run without the switch
                self.state = "0B"
        elif self.state in MOVING and not self.axis.moving():
            if self.stopping_to:
                self.target = self.position()
            self.state, self.stopping_to = "33", None


class Chaos:
    """A bad line (--chaos): decides each reply's and each command's fate from a seeded RNG."""

    def __init__(self, seed, rates, active):
        self.rng = random.Random(seed)
        self.late, self.drop, self.garble, self.truncate, self.lost = rates
        self.active = active


class Journal:
    """--journal: one line per executed command, per reply queued and per fault, flushed."""

    def __init__(self, path):
        self.f = open(path, "a", buffering=1) if path else None

    def write(self, text):
        if self.f is not None:
            self.f.write("%.6f %s\n" % (time.monotonic(), text))
            self.f.flush()


class Line:
    def __init__(self, pty, controllers, chaos=None, journal=None):
        self.pty = pty
        self.controllers = {c.address: c for c in controllers}
        self.buf = bytearray()
        self.chaos = chaos
        self.journal = journal or Journal(None)

    def control(self, line, now):
        """The test's requests (unit_common.Control); WHO is a controller address. A power cycle
        is the manual's power-on: the motor stops where it is (no power to ramp it down), the
        controller boots (deaf for RESET_TIME, as after RS), then NOT REFERENCED at position 0,
        parameters at their defaults. The stage and its switches stay where they are."""
        def power_cycle(who):
            if who is not None and not who.isdigit():
                return None
            chosen = [c for a, c in self.controllers.items() if who is None or a == int(who)]
            if not chosen:
                return None
            for c in chosen:
                c.tick(now)  # the motion up to this instant
                was = c.position()
                c.axis.hard_stop()
                c.booting_until = now + RESET_TIME
                uc.log("smc100: %d power-cycled at %s mm: booting, then NOT REFERENCED at 0"
                       % (c.address, c.fmt(was)))
            return ",".join(str(c.address) for c in chosen)

        def state():
            return {str(a): (c.position(), c.axis.moving()) for a, c in self.controllers.items()}
        return uc.control_request(self, line.split(), power_cycle, state)

    def set_chaos(self, on):
        if self.chaos is not None and self.chaos.active != on:
            self.chaos.active = on
            self.journal.write("chaos %s" % ("on" if on else "off"))

    def on_bytes(self, data, now):
        for b in data:
            line = uc.feed_line(self.buf, b, (0x0A,), 256)
            if line is not None:
                self.line(line, now)

    def line(self, text, now):
        body = text.replace(" ", "").replace("\t", "")
        m = re.match(r"(\d+)([A-Za-z]{2})(.*)$", body)
        if not m:
            return
        c = self.controllers.get(int(m.group(1)))
        if c is None or c.booting_until is not None:
            return
        chaos = self.chaos
        if chaos is not None and chaos.active and chaos.rng.random() < chaos.lost:
            self.journal.write("fault lost-command %s" % body)
            return
        rx(text)
        code = m.group(2).upper()
        if self.journal.f is None:
            reply = c.execute(code, m.group(3), now)
        else:
            reply = self.execute_journaled(c, code, m.group(3), body, now)
        if reply is not None:
            self.send_reply(reply, now)

    def execute_journaled(self, c, code, param, body, now):
        """execute(), journaled with what resulted. An error memorised by this very command is
        told apart from one already memorised: the register is set aside for the command (not
        for TE, which reads it) and restored if the command memorised nothing."""
        if code == "TE":
            memorised = c.error
            reply = c.execute(code, param, now)
            outcome = "ok error-read=%s" % memorised
        else:
            before, c.error = c.error, None
            reply = c.execute(code, param, now)
            if c.error is None:
                c.error, outcome = before, "ok"
            else:
                outcome = "refused=%s" % c.error
        self.journal.write("exec %s %s state=%s target=%s pos=%s" % (
            body, outcome, c.state, c.fmt(c.target), c.fmt(c.position())))
        return reply

    def send_reply(self, reply, now):
        data = (reply + "\r\n").encode()
        chaos = self.chaos
        late = ""
        if chaos is not None and chaos.active:
            r = chaos.rng.random()
            if r < chaos.late:
                delay = chaos.rng.uniform(0.25, 0.40)
                # The device answers late, and what it answers after waits behind it.
                self.pty.busy_until = max(self.pty.busy_until, now + delay)
                late = " late=%dms" % round(delay * 1000)
            elif r < chaos.late + chaos.drop:
                self.journal.write("fault drop %s" % reply)
                return
            elif r < chaos.late + chaos.drop + chaos.garble:
                data = bytearray(data)
                body = len(data) - 2
                for i in chaos.rng.sample(range(body), min(body, chaos.rng.randint(1, 3))):
                    data[i] |= 0x80
                data = bytes(data)
                self.journal.write("fault garble %s -> %s" % (reply, data.hex()))
                self.pty.send(data)
                return
            elif r < chaos.late + chaos.drop + chaos.garble + chaos.truncate:
                data = data[:chaos.rng.randint(1, len(data) - 1)]
                self.journal.write("fault truncate %s -> %s" % (reply, data.hex()))
                self.pty.send(data)
                return
        self.journal.write("sent %s%s" % (reply, late))
        self.pty.send(data)

    def on_tick(self, now):
        for c in self.controllers.values():
            c.tick(now)


def make_line(pty, args):
    addresses = [int(a) for a in args.addresses.split(",") if a]
    for a in addresses:
        if not 1 <= a <= 31:
            sys.exit("smc100: address %d outside 1..31" % a)
    chaos = None
    if getattr(args, "chaos", None) is not None:
        rates = [float(r) for r in args.chaos_rates.split(",")]
        if len(rates) != 5:
            sys.exit("smc100: --chaos-rates takes 5 numbers")
        chaos = Chaos(args.chaos, rates, not args.chaos_paused)
    return Line(pty, [Controller(a, args.decimals, args.limit_error) for a in addresses],
                chaos, Journal(getattr(args, "journal", None)))


# ---------------------------------------------------------------------------------------------
# Self-test: the unit on a PTY in a thread, a host on the other end.

def Host(link, baud):
    return uc.TestHost(link, baud, 0.15)


def self_test(args):
    link = "/tmp/smc100_selftest_%d" % os.getpid()
    args.addresses = "1,2"
    pty = uc.Pty(link, args.baud)
    line = make_line(pty, args)
    on_bytes = uc.heard_only_at(pty, args.baud, "smc100", line.on_bytes)
    threading.Thread(target=uc.run, args=(pty, on_bytes, line.on_tick), daemon=True).start()
    host = Host(link, args.baud)
    test = uc.SelfTest(host, 0.1)
    check, wait_for = test.check, test.wait_for



    check("power up state", host.ask("1TS\r\n"), b"1TS00000A\r\n")
    check("CR alone waits for LF", host.ask("1TS\r"), b"")
    check("... then executes", host.ask("\n"), b"1TS00000A\r\n")
    check("leading zero address", host.ask("01TS\r\n"), b"1TS00000A\r\n")
    check("address 2", host.ask("2TS\r\n"), b"2TS00000A\r\n")
    check("unknown address silent", host.ask("5TS\r\n"), b"")
    check("PA in NOT REFERENCED: no reply", host.ask("1PA5\r\n"), b"")
    check("... error H", host.ask("1TE\r\n"), b"1TEH\r\n")
    check("TE cleared by reading", host.ask("1TE\r\n"), b"1TE@\r\n")
    check("TB text", host.ask("1TBH\r\n"), b"1TBH " + ERRORS["H"].encode() + b"\r\n")
    check("unknown code -> A", host.ask("1QQ\r\n1TE\r\n"), b"1TEA\r\n")
    check("VA read-back", host.ask("1VA?\r\n"), b"1VA2.5\r\n")
    host.ask("1VA 5\r\n")  # blanks ignored
    check("VA set with a blank", host.ask("1VA?\r\n"), b"1VA5\r\n")
    check("OR -> HOMING", host.ask("1OR\r\n1TS\r\n", 0.1), b"1TS00001E\r\n")
    check("OR again -> E", host.ask("1OR\r\n1TE\r\n"), b"1TEE\r\n")
    check("homed: READY from HOMING", wait_for("1TS\r\n", b"1TS000032\r\n", 7.0),
          b"1TS000032\r\n")
    check("position 0", host.ask("1TP\r\n"), b"1TP0\r\n")
    check("target out of SL..SR", host.ask("1PA30\r\n1TE\r\n"), b"1TEC\r\n")
    host.ask("1PA2.5\r\n", 0.05)
    check("moving", host.ask("1TS\r\n", 0.1), b"1TS000028\r\n")
    check("PA while MOVING -> M", host.ask("1PA1\r\n1TE\r\n"), b"1TEM\r\n")
    check("PA? target", host.ask("1PA?\r\n"), b"1PA2.5\r\n")
    check("READY from MOVING", wait_for("1TS\r\n", b"1TS000033\r\n", 3.0), b"1TS000033\r\n")
    check("at target", host.ask("1TP?\r\n"), b"1TP2.5\r\n")
    host.ask("1PR-10\r\n", 0.3)
    host.ask("1ST\r\n", 0.6)
    r = host.ask("1TS\r\n1TP\r\n")
    check("ST ends READY 33", r.split(b"\r\n")[0], b"1TS000033")
    pos = float(r.split(b"\r\n")[1][3:])
    check("stopped short of -7.5", -7.5 < pos < 2.5, True)
    host.ask("1MM0\r\n")
    check("MM0 -> DISABLE from READY", host.ask("1TS\r\n"), b"1TS00003C\r\n")
    check("PA in DISABLE -> J", host.ask("1PA0\r\n1TE\r\n"), b"1TEJ\r\n")
    host.ask("1MM1\r\n")
    check("MM1 -> READY from DISABLE", host.ask("1TS\r\n"), b"1TS000034\r\n")
    host.ask("1RS\r\n")
    check("silent while rebooting", host.ask("1TS\r\n", 0.3), b"")
    time.sleep(1.0)
    check("after RS: NOT REFERENCED", host.ask("1TS\r\n"), b"1TS00000A\r\n")
    check("2 untouched", host.ask("2TS\r\n2TP\r\n"), b"2TS00000A\r\n2TP0\r\n")
    # Bytes at another host rate are unreadable.
    return test.finish(link, 9600, "1TS\r\n")


def main():
    ap = uc.unit_arguments(__doc__, 57600)
    ap.add_argument("--addresses", default="1", help="controller addresses, 1..31 (e.g. 1,2)")
    ap.add_argument("--decimals", type=int, default=None,
                    help="print positions with exactly N decimals (default: trimmed %%.6f)")
    ap.add_argument("--limit-error", default="C", choices=["C", "G"],
                    help="letter memorised for a target outside SL..SR")
    ap.add_argument("--chaos", type=int, default=None, metavar="SEED",
                    help="a bad line: late, dropped, garbled, truncated replies, lost commands")
    ap.add_argument("--chaos-rates", default="0.05,0.04,0.04,0.04,0.03",
                    metavar="LATE,DROP,GARBLE,TRUNCATE,LOST",
                    help="probability of each fault per reply (the last: per command line)")
    ap.add_argument("--chaos-paused", action="store_true",
                    help="start with the chaos off (SIGUSR1 on, SIGUSR2 off)")
    ap.add_argument("--journal", default=None, metavar="PATH",
                    help="journal of executed commands, replies sent and faults injected")
    uc.control_argument(ap)
    args = uc.parse_unit_arguments(ap, self_test)
    pty = uc.Pty(args.link, args.baud)
    line = make_line(pty, args)
    if line.chaos is not None:
        signal.signal(signal.SIGUSR1, lambda *_: line.set_chaos(True))
        signal.signal(signal.SIGUSR2, lambda *_: line.set_chaos(False))
        line.journal.write("chaos seed %d %s" % (args.chaos, "paused" if args.chaos_paused
                                                 else "on"))
    uc.log("smc100: addresses %s at %d baud on %s" % (args.addresses, args.baud, args.link))
    uc.run(pty, uc.heard_only_at(pty, args.baud, "smc100", line.on_bytes), line.on_tick,
           control=uc.Control.open(args.control, line))


if __name__ == "__main__":
    main()
