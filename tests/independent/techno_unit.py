#!/usr/bin/python3
"""A Techno/Isel C-series controller card (C142: X, Y, Z; IT116G: X only), written from
"Wiring, Setup & ASCII Programming for C-Series Controllers" (shared/seeds/001, digest
shared/protocols/techno-cseries.md) only.

  techno_unit.py --link PATH [--variant c142|it116g] [--baud 19200] [--control SOCKET]

The card powers up with no axes defined (every command but `@0<A>` answers `4`), positions 0,
not homed, acceleration from the jumpers (C142 75 Hz/ms, IT116G 25 Hz/ms, p.6).
Readings of the manual where it leaves room:
- One command runs at a time. Lines that arrive while a motion runs (a lower-case command
  acknowledged at its start, p.29) wait in the input buffer and run when it ends: the Stop
  command's note (p.73) "in case another command is in the buffer ... the buffered command will
  start running". So `@0P` during a move is answered when the move ends. `--queries live`
  presents the other reading (answered at once, the motion running on).
- 0xFF (Stop, p.73) decelerates the running motion and ends it; the buffered line, if any,
  then runs (a second 0xFF drops it). A capital-letter command that was stopped acknowledges
  `0` as it ends. 0xFF itself answers nothing. 0xFE halts at once, drops the buffer, answers
  nothing.
- `@0P` (p.43) answers the handshake `0` and then the 18 hex characters, like Peek ("replies
  with the software handshake, followed by two digits", p.54); no terminator. All three axis
  registers are always sent.
- Home (p.41) runs toward the motor (negative) at the `@0d` speed to the home switch, which sits
  3000 steps from where the axis powered up; the position there becomes 0.
- A move that would run into the home switch (travel toward the motor past home) stops there
  and answers `2` ("emergency stop or limit switch encountered", p.90); the far end of travel
  is 1,000,000 steps out.
- A power cycle (`power-cycle` on --control, unit_common.Control): the card powers up as above
  (no axes defined: `4` to everything but `@0<A>`), the running motion stops at once and is never
  acknowledged, the input buffer is lost; positions count from 0 where the motors stopped.
"""
import argparse
import re
import time

import unit_common as uc

ORDER = "XYZ"


class Card:
    def __init__(self, variant, pty, live_queries, p_reply_cr=False):
        self.variant = variant
        self.p_reply_cr = p_reply_cr
        self.live_queries = live_queries
        self.pty = pty
        self.max_mask = 7 if variant == "c142" else 1
        accel = (75 if variant == "c142" else 25) * 1000.0
        self.axes = {}
        for letter in ORDER:
            a = uc.Axis(accel=accel, limit_neg=-3000.0, limit_pos=1e6, home_switch=-3000.0)
            self.axes[letter] = a
        self.power_up()

    def power_up(self):
        """Power applied: no axes defined (every command but `@0<A>` answers `4`, p.69), the
        motion and the input buffer gone (no acknowledge of a command that was running), positions
        0, immediate mode, plane XY, home speeds at this module's default. The motors stay where
        they stopped (the home switches do not move)."""
        for a in self.axes.values():
            a.power_up(0.0)
        self.mask = 0
        self.home_speed = {k: 2000.0 for k in ORDER}
        self.plane = 0
        self.buffer = []  # lines waiting for the running command
        self.job = None  # running command: {"legs": [...], "ack_at_end": bool, ...}
        self.line = bytearray()
        self.stop_pending = False

    def control(self, line, now):
        """The test's requests (unit_common.Control): one card per line, so WHO is ignored."""
        def power_cycle(who):
            self.tick(now)  # the motion up to this instant
            was = " ".join("%s %.0f" % (k, self.axes[k].position()) for k in ORDER)
            running = self.job is not None
            self.power_up()
            uc.log("techno: power-cycled at %s%s: no axes defined" %
                   (was, ", the running command not acknowledged" if running else ""))
            return "card"

        def state():
            return {k: (round(self.axes[k].position()), self.axes[k].moving()) for k in ORDER}
        return uc.control_request(self, line.split(), power_cycle, state)

    def defined(self):
        return [k for i, k in enumerate(ORDER) if self.mask >> i & 1]

    def ack(self, text):
        uc.wire("  tx %r" % text)
        self.pty.send(text.encode())

    # Input
    def on_bytes(self, data, now):
        for b in data:
            if b == 0xFF:
                uc.wire("0xFF (stop)")
                if self.job:
                    self.stop_job()
                elif self.buffer:
                    self.buffer.pop(0)  # the second 0xFF: the buffered command does not run
                continue
            if b == 0xFE:
                uc.wire("0xFE (reset)")
                for a in self.axes.values():
                    a.hard_stop()
                self.job = None
                self.buffer.clear()
                continue
            if b == 0x0D:
                text = self.line.decode(errors="replace")
                self.line.clear()
                if self.job and not (self.live_queries and text.replace(" ", "") == "@0P"):
                    self.buffer.append(text)
                else:
                    self.execute(text)
            elif b == 0x0A:
                continue
            elif len(self.line) < 120:
                self.line.append(b)

    def execute(self, text):
        uc.wire(text)
        m = re.fullmatch(r"@(\d)(.*)", text)
        if not m:
            self.ack("5")
            return
        if m.group(1) != "0":
            return  # another card's number: not for us
        body = m.group(2).replace(" ", "")
        if not body:
            self.ack("\r")
            return
        cmd, rest = body[0], body[1:]
        if cmd.isdigit() and not rest:
            mask = int(cmd)
            if mask not in (1, 3, 5, 7) or mask & ~self.max_mask:
                self.ack("3")
                return
            self.mask = mask
            self.ack("0")
            return
        if not self.mask:
            self.ack("4")
            return
        if cmd == "P" and not rest:
            text = "".join("%06X" % (round(self.axes[k].position()) & 0xFFFFFF) for k in ORDER)
            self.ack("0" + text)
            if self.p_reply_cr:
                # The CR leaves the card a moment after the digits (a card's firmware, a USB
                # adapter's latency): a host that stops at 18 digits reads it as the next answer.
                time.sleep(0.015)
                self.ack("\r")
            return
        if cmd in "AaMm":
            self.move(cmd, rest)
            return
        if cmd in "Rr":
            if not re.fullmatch(r"[1-7]", rest):
                self.ack("3" if rest.isdigit() else "5")
                return
            mask = int(rest)
            if mask & ~self.mask:
                self.ack("3")
                return
            legs = [[("home", k)] for k in reversed(ORDER) if mask >> ORDER.index(k) & 1]
            self.start_job(legs, cmd == "R")
            return
        if cmd == "n":
            if not re.fullmatch(r"[1-7]", rest) or int(rest) & ~self.mask:
                self.ack("3")
                return
            for i, k in enumerate(ORDER):
                if int(rest) >> i & 1:
                    self.axes[k].set_position(0.0)
            self.ack("0")
            return
        if cmd == "d":
            values = self.values(rest)
            if values is None:
                return
            if len(values) != len(self.defined()):
                self.ack("7")
                return
            if any(v < 30 or v > 10000 for v in values):
                self.ack("D")
                return
            for k, v in zip(self.defined(), values):
                self.home_speed[k] = float(v)
            self.ack("0")
            return
        if cmd == "e" and rest in ("0", "1", "2"):
            self.plane = int(rest)
            self.ack("0")
            return
        if cmd in "zf" and self.variant == "c142":
            self.ack("0")
            return
        if cmd in "ik":
            self.ack("0")
            return
        if cmd in "Ss":
            self.ack("G")  # no program in memory
            return
        if cmd == "b" or cmd == "c":
            self.ack("0FF")  # inputs open read 1 (p.15)
            return
        if cmd == "B":
            self.ack("0")
            return
        self.ack("5")

    def values(self, rest):
        parts = [p for p in rest.split(",")]
        try:
            return [int(p) for p in parts]
        except ValueError:
            self.ack("5")
            return None

    def move(self, cmd, rest):
        values = self.values(rest)
        if values is None:
            return
        axes = self.defined()
        count = {1: 2, 3: 4, 5: 6, 7: 8}[self.mask]
        if len(values) != count:
            self.ack("7")
            return
        pairs = [(values[i], values[i + 1]) for i in range(0, len(values), 2)]
        for g, s in pairs:
            if abs(g) > 8000000:
                self.ack("7")
                return
            if s < 30 or s > 10000:
                self.ack("D")
                return
        absolute = cmd in "Mm"
        # Plane pair together, then the third axis down (Z1) and back (Z2) (p.58).
        plane_axes = {0: "XY", 1: "XZ", 2: "YZ"}[self.plane]
        third = [k for k in ORDER if k not in plane_axes][0]
        if self.mask == 1:
            roles = ["X"]
        elif self.mask == 3:
            roles = ["X", "Y"]
        elif self.mask == 5:
            roles = ["X", "Z", "Z"]
        else:
            roles = [plane_axes[0], plane_axes[1], third, third]
        legs = []
        together = []
        for role, (g, s) in zip(roles[:2] if self.mask != 5 else roles[:1], pairs):
            together.append(("abs" if absolute else "rel", role, g, s))
        legs.append(together)
        for role, (g, s) in list(zip(roles, pairs))[len(together):]:
            legs.append([("abs" if absolute else "rel", role, g, s)])
        self.start_job(legs, cmd in "AM")

    def start_job(self, legs, ack_at_end):
        self.job = {"legs": legs, "ack_at_end": ack_at_end, "leg": -1, "error": None}
        if not ack_at_end:
            self.ack("0")
        self.next_leg()

    def next_leg(self):
        job = self.job
        job["leg"] += 1
        if job["leg"] >= len(job["legs"]):
            self.finish_job()
            return
        for step in job["legs"][job["leg"]]:
            if step[0] == "home":
                a = self.axes[step[1]]
                job.setdefault("homing", set()).add(step[1])
                a.run_at(-self.home_speed[step[1]])
            else:
                kind, role, g, s = step
                a = self.axes[role]
                target = g if kind == "abs" else a.position() + g
                if abs(target - a.position()) > 1e-6:
                    a.move_to(target, s)

    def finish_job(self):
        job, self.job = self.job, None
        if job["ack_at_end"]:
            self.ack(job["error"] or "0")
        while self.buffer and not self.job:
            self.execute(self.buffer.pop(0))

    def stop_job(self):
        for a in self.axes.values():
            a.stop()
        self.job["legs"] = self.job["legs"][: self.job["leg"] + 1]
        self.job.pop("homing", None)

    def tick(self, now):
        for a in self.axes.values():
            a.tick(now)
        job = self.job
        if not job:
            return
        homing = job.get("homing", set())
        for k in list(homing):
            a = self.axes[k]
            if a.hit_limit < 0 or a.home_input_high():
                a.hard_stop()
                a.set_position(0.0)
                a.hit_limit = 0
                homing.discard(k)
        if any(a.moving() for a in self.axes.values()):
            return
        for a in self.axes.values():
            if a.hit_limit:
                job["error"] = "2"
                job["legs"] = job["legs"][: job["leg"] + 1]
                a.hit_limit = 0
        self.next_leg()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--variant", default="c142", choices=["c142", "it116g"])
    ap.add_argument("--baud", type=int, default=19200)
    ap.add_argument("--queries", default="deferred", choices=["deferred", "live"],
                    help="deferred: `@0P` during a motion waits in the buffer (p.73, this "
                    "module's reading); live: it is answered at once (the other reading)")
    ap.add_argument("--p-reply-cr", action="store_true",
                    help="the `@0P` reply ends with a CR after its 18 digits (the manual leaves "
                    "the terminator of the P reply open; issue 26)")
    uc.control_argument(ap)
    args = ap.parse_args()
    pty = uc.Pty(args.link, args.baud)
    card = Card(args.variant, pty, args.queries == "live", args.p_reply_cr)
    uc.log("techno: %s at %d baud on %s" % (args.variant, args.baud, args.link))
    uc.run(pty, uc.heard_only_at(pty, args.baud, "card", card.on_bytes), card.tick,
           control=uc.Control.open(args.control, card))


if __name__ == "__main__":
    main()
