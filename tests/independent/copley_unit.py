#!/usr/bin/python3
"""Copley amplifiers behind one RS-232 port (the first node is the serial gateway, the others
are reached over CAN by a node-ID prefix), written from the Copley ASCII Interface Programmer's
Guide (shared/seeds/002, digest shared/protocols/copley-ascii.md) only.

  copley_unit.py --link PATH [--nodes 0,3] [--control SOCKET]

Each amp powers up as a commissioned amp does: RAM reloaded from flash, so the desired state
0x24 comes up as flash holds it (21, programmed position: an amp whose flash holds 0 is
"unprogrammed" for CME 2, section 3.1), not referenced (0xc9 bit 12 clear), 0xa0 bit 20
"amplifier has been reset" set, 9600 baud (section 1.2).
Readings of the manual where it leaves room:
- Replies `v <value>` with one space (every transcript but 2.8's `v1200`), ending in CR only.
- A node prefix naming the gateway's own node (0) runs the command locally (2.1: node IDs
  0-127; the gateway is node 0).
- A prefix naming a node that is not on the CAN bus: `e 32` (App. E, "CAN Network
  communications failure") after a CAN timeout.
- `t 1` or `t 2` while the amp is disabled (0x24 = 0) or not in a trajectory mode: the guide
  gives no error code, and `ok` only means "accepted" (2.6); the amp answers `ok` and nothing
  moves (homing then sets 0xc9 bit 11, homing error).
- 0xa0 bit 20 stays set after power-up (the guide documents no way to clear it).
- Home methods: 512 sets the current position as home; home-switch methods (low nibble 2 or 3)
  seek the home switch edge in the method's direction (0x010 = negative); limit methods (low
  nibble 1) seek the limit switch edge. The position at the reference is minus the home offset
  0xc6. A limit reached first ends homing with 0xc9 bit 11.
- The gateway amp handles one command at a time: a reply waits behind the one before it (an
  absent node's `e 32` after the CAN timeout, --can-timeout-ms, holds back what follows).
- --pause-ms P --pause-every-ms E: every E ms the amp stops answering for P ms (a busy CPU, a USB
  adapter's buffer) and then answers its backlog in order (issue 26).
- A power cycle (`power-cycle [NODE]` on --control, unit_common.Control; default every amp) is
  `r` for that amp: RAM from flash, 9600 baud, 0xa0 bit 20, not referenced, motion stopped, the
  position counting from 0; it answers nothing for 0.3 s (boot time undocumented).
"""
import argparse
import re
import time

import unit_common as uc

# id: (flash default or None if RAM-only, writable)
RF_DEFAULTS = {
    0x00: 100, 0x01: 50, 0x02: 0, 0x19: 1000, 0x1a: 0, 0x21: 600, 0x22: 300, 0x23: 1000,
    0x24: 21, 0x26: 0, 0x27: 200, 0x28: 100, 0x2f: 0, 0x30: 1000, 0x33: 0, 0x34: 0,
    0x36: 100, 0x37: 100, 0x39: 200, 0x3a: 1000000, 0x5f: 0, 0x6a: 0, 0x6b: 0,
    0x70: 0, 0x71: 0, 0x72: 0, 0x73: 0, 0x74: 0, 0x75: 0, 0x76: 0, 0x77: 0,
    0xa8: 0, 0xa9: 0x00010001, 0xae: 0, 0xb8: 0, 0xb9: 0, 0xbf: 250, 0xc2: 514,
    0xc3: 50000, 0xc4: 10000, 0xc5: 10000, 0xc6: 0, 0xc7: 100, 0xc8: 0, 0xca: 0,
    0xcb: 100000, 0xcc: 10000, 0xcd: 10000, 0xce: 1000, 0xcf: 20000, 0xe3: 100,
}
RAM_WRITABLE = {0x90, 0xa4, 0xab}
RAM_MONITORS = {0x0c, 0x15, 0x17, 0x18, 0x1b, 0x1c, 0x1d, 0x1e, 0x20, 0x25, 0x29, 0x2a, 0x2c,
                0x2d, 0x32, 0x35, 0x3b, 0x3c, 0x3d, 0x5e, 0xa0, 0xa6, 0xb0, 0xc9}
TRAJECTORY_STATES = (21, 31)
SETTLE = 0.02  # s the amp stays "in motion" (0xa0 bit 27) after the profile ends


class Amp:
    def __init__(self, node):
        self.node = node
        self.flash = dict(RF_DEFAULTS)
        self.axis = uc.Axis(limit_neg=-2e6, limit_pos=2e6, home_switch=8000.0)
        self.power_up()

    def power_up(self):
        """`r` or a power cycle (1.1, 1.2, 2.5): RAM reloaded from flash (what `c r…` saved
        stays), RAM-only variables clear, 9600 baud, 0xa0 bit 20 "amplifier has been reset",
        not referenced; the motor stops (no power) and the position counts from 0 where it
        stopped (the switches do not move)."""
        self.ram = dict(self.flash)
        self.ram.update({0x90: 9600, 0xa4: 0, 0xab: 0})
        self.axis.power_up(0.0)
        self.referenced = self.homing_error = self.aborted = False
        self.homing = None
        self.reset_seen = True
        self.settle_until = 0.0
        self.profile_mode = False  # the generator runs a velocity move (profile type 2)
        self.booting_until = 0.0

    def enabled(self):
        return self.ram[0x24] != 0

    def home_switch_active(self):
        return not self.axis.home_input_high()  # active at and above the switch

    def event_status(self, now):
        a = self.axis
        v = 0
        if a.limit_active(1):
            v |= 1 << 9
        if a.limit_active(-1):
            v |= 1 << 10
        if not self.enabled():
            v |= 1 << 12 | 1 << 15
        if self.reset_seen:
            v |= 1 << 20
        if self.ram[0xa4]:
            v |= 1 << 22
        if self.home_switch_active():
            v |= 1 << 26
        if a.moving() or now < self.settle_until:
            v |= 1 << 27
        if a.mode == "stop":
            v |= 1 << 13
        return v

    def traj_status(self):
        v = 0
        if self.homing_error:
            v |= 1 << 11
        if self.referenced:
            v |= 1 << 12
        if self.homing:
            v |= 1 << 13
        if self.aborted:
            v |= 1 << 14
        if self.axis.moving():
            v |= 1 << 15
        return v

    def monitor(self, vid, now):
        a = self.axis
        return {
            0x0c: 0 if not self.enabled() else (150 if a.moving() else 20), 0x15: 0,
            0x17: round(a.position()), 0x18: round(a.v * 10), 0x1b: 0, 0x1c: 0, 0x1d: 0,
            0x1e: 480, 0x20: 35, 0x25: 0, 0x29: round(a.v * 10), 0x2a: 0,
            0x2c: round(a.v * 10), 0x2d: round(a.position()), 0x32: round(a.position()),
            0x35: 0, 0x3b: round(a.v * 10), 0x3c: 0, 0x3d: round(a.position()),
            0x5e: round(a.v * 10), 0xa0: self.event_status(now), 0xa6: 0, 0xb0: 0,
            0xc9: self.traj_status(),
        }[vid]

    # Commands; each returns the reply text without CR, or None for no reply.
    def command(self, code, params, now, bus):
        if code == "r":
            if params:
                return "e 5"
            self.power_up()
            self.booting_until = now + 0.3
            return None
        if code in ("g", "s", "c"):
            if not params:
                return "e 4"
            m = re.fullmatch(r"([rf])(0x[0-9a-fA-F]+|\d+)", params[0])
            if not m:
                return "e 33"
            bank, vid = m.group(1), int(m.group(2), 0)
            known = vid in RF_DEFAULTS or vid in RAM_MONITORS or vid in RAM_WRITABLE
            if not known:
                return "e 9"
            if bank == "f" and vid not in RF_DEFAULTS:
                return "e 15"
            if code == "g":
                if len(params) > 1:
                    return "e 5"
                if bank == "f":
                    return "v %d" % self.flash[vid]
                if vid in RAM_MONITORS:
                    return "v %d" % self.monitor(vid, now)
                return "v %d" % self.ram[vid]
            if code == "c":
                if len(params) > 1:
                    return "e 5"
                if bank == "r":
                    self.flash[vid] = self.ram[vid]
                else:
                    self.ram[vid] = self.flash[vid]
                    self.apply(vid, now)
                return "ok"
            # s
            if vid in RAM_MONITORS:
                return "e 11"
            if len(params) < 2:
                return "e 4"
            try:
                value = int(params[1], 0)
            except ValueError:
                return "e 33"
            if bank == "f":
                self.flash[vid] = value
                return "ok"
            if vid == 0xa4:
                self.ram[vid] &= ~value  # write 1 to clear
                return "ok"
            if vid == 0x24 and value not in (0, 1, 2, 3, 4, 5, 11, 12, 13, 14, 21, 22, 23, 24, 25,
                                             30, 31, 33, 34, 35, 40, 42):
                return "e 14"
            if vid == 0xc8 and value not in (0, 1, 2, 256, 257):
                return "e 25"
            self.ram[vid] = value
            if vid == 0x90:
                bus.set_baud(value)
            self.apply(vid, now)
            return "ok"
        if code == "t":
            if len(params) != 1 or params[0] not in ("0", "1", "2"):
                return "e 33" if len(params) == 1 else ("e 4" if not params else "e 5")
            return self.trajectory(int(params[0]), now)
        if code == "i":
            return "e 4" if not params else ("ok" if len(params) > 1 else "r 0")
        return "e 3"

    def apply(self, vid, now):
        if vid == 0x24 and not self.enabled():
            self.axis.hard_stop()  # the bridge switches off; the motor coasts to rest
            self.homing = None
            self.profile_mode = False

    def trajectory(self, sub, now):
        a = self.axis
        if sub == 0:
            if a.moving():
                a.decel = self.ram[0xcf] * 10.0
                a.stop()
                self.aborted = True
            self.homing = None
            return "ok"
        if self.ram[0x24] not in TRAJECTORY_STATES:
            if sub == 2:
                self.homing_error, self.referenced = True, False
            return "ok"
        if sub == 1:
            ptype = self.ram[0xc8]
            if a.moving() and (ptype & 1):
                return "e 18"  # S-curve moves cannot be updated
            vmax = self.ram[0xcb] / 10.0
            if vmax <= 0 and ptype != 2:
                return "e 19"
            a.accel = max(self.ram[0xcc], 1) * 10.0
            a.decel = max(self.ram[0xcd], 1) * 10.0
            self.aborted = False
            self.homing = None
            target = self.ram[0xca]
            if ptype == 2:
                if vmax <= 0:
                    a.stop()
                else:
                    a.run_at(vmax if target >= 0 else -vmax)
            elif ptype & 256:
                base = a.target - a.offset if a.mode == "pos" else a.position()
                a.move_to(base + target, vmax)
            else:
                a.move_to(target, vmax)
            self.settle_until = now + SETTLE
            return "ok"
        # sub == 2: home
        self.referenced = self.homing_error = self.aborted = False
        method = self.ram[0xc2]
        a.accel = a.decel = max(self.ram[0xc5], 1) * 10.0
        kind = method & 0xF
        negative = bool(method & 0x10)
        if kind == 0:
            a.set_position(-self.ram[0xc6])
            self.referenced = True
            return "ok"
        self.homing = {"kind": kind, "sign": -1 if negative else 1, "phase": 1}
        if kind == 1:
            a.run_at(self.homing["sign"] * self.ram[0xc3] / 10.0)
        else:
            # Seek the switch edge: toward it from whichever side the axis is on.
            toward = 1 if not self.home_switch_active() else -1
            self.homing["toward"] = toward
            a.run_at(toward * self.ram[0xc3] / 10.0)
        return "ok"

    def tick(self, now):
        a = self.axis
        was_moving = a.moving()
        a.tick(now)
        h = self.homing
        if h:
            if h["kind"] == 1:
                if a.hit_limit == h["sign"]:
                    # Limit switch homing: the limit transition is the reference.
                    a.set_position(-self.ram[0xc6])
                    self.referenced, self.homing = True, None
                elif not a.moving():
                    self.homing_error, self.homing = True, None
            else:
                if a.hit_limit:
                    self.homing_error, self.homing = True, None
                elif h["phase"] == 1 and self.home_switch_active() == (h["toward"] > 0):
                    # Crossed the edge at fast speed: come back to it at slow speed.
                    h["phase"] = 2
                    a.stop()
                elif h["phase"] == 2 and not a.moving():
                    h["phase"] = 3
                    back = -h["toward"]
                    a.run_at(back * self.ram[0xc4] / 10.0)
                elif h["phase"] == 3 and self.home_switch_active() != (h["toward"] > 0):
                    a.hard_stop()
                    a.set_position(-self.ram[0xc6])
                    self.referenced, self.homing = True, None
                elif not a.moving() and h["phase"] != 2:
                    self.homing_error, self.homing = True, None
        if was_moving and not a.moving():
            self.settle_until = now + SETTLE
        if a.hit_limit and was_moving and not a.moving() and not h:
            self.aborted = True


LINE_RE = re.compile(r"(?:(\d{1,3})(?:\.([abc]))? )?([a-z])(?: (.*))?")


class Bus:
    def __init__(self, pty, nodes, can_timeout=0.01, pause=0.0, pause_every=0.0):
        self.pty = pty
        self.amps = {n: Amp(n) for n in nodes}
        self.gateway = self.amps[nodes[0]]
        self.buf = bytearray()
        self.later = []  # (time, reply), in the order the commands came
        self.can_timeout = can_timeout
        self.pause = pause
        self.pause_every = pause_every

    def set_baud(self, baud):
        self.pty.char_time = 10.0 / baud

    def on_bytes(self, data, now):
        # 4.1: the host switches as soon as the CR has left; see Pty.heard_at.
        rate = self.gateway.ram[0x90]
        if not self.pty.heard_at(rate, now):
            host = self.pty.rate_now
            # At another rate the amp sees framing errors only, and answers nothing.
            uc.wire("(host at %d baud, amp at %d: %d bytes unreadable)" %
                    (host, self.gateway.ram[0x90], len(data)))
            self.buf.clear()
            return
        for b in data:
            if b == 0x0D:
                self.line(self.buf.decode(errors="replace"), now)
                self.buf.clear()
            elif len(self.buf) < 200:
                self.buf.append(b)

    def line(self, text, now):
        if now < self.gateway.booting_until:
            return
        uc.wire(text)
        m = LINE_RE.fullmatch(text)
        if not m:
            self.reply("e 33")
            return
        node_text, axis_letter, code, rest = m.groups()
        if axis_letter:
            self.reply("e 33")  # single-axis amps
            return
        params = rest.split(" ") if rest is not None else []
        if rest is not None and (rest == "" or "" in params):
            self.reply("e 33")  # exactly one space between tokens (2.2)
            return
        if node_text is None:
            amp = self.gateway
        else:
            node = int(node_text)
            if node > 127:
                self.reply("e 31")
                return
            amp = self.amps.get(node)
            if amp is None or now < amp.booting_until:
                self.queue(now + self.can_timeout, "e 32")
                return
            if amp is not self.gateway:
                result = amp.command(code, params, now, self)
                # A remote reset answers e 32: it resets before it answers (2.5).
                self.queue(now + 0.002, result if result is not None else "e 32")
                return
        result = amp.command(code, params, now, self)
        if result is not None:
            self.queue(now, result)

    def queue(self, when, text):
        """One command at a time: a reply never overtakes the one before it."""
        if self.later:
            when = max(when, self.later[-1][0])
        if self.pause_every > 0:
            into = when % self.pause_every
            if into < self.pause:
                when += self.pause - into
        if not self.later and when <= time.monotonic():
            self.reply(text)
        else:
            self.later.append((when, text))

    def reply(self, text):
        self.pty.send(text.encode() + b"\r")

    def control(self, line, now):
        """The test's requests (unit_common.Control); WHO is a node number (default: every amp
        behind the port). The gateway amp's power cycle drops the line to 9600 baud and loses
        the replies it still owed."""
        def power_cycle(who):
            amps = [a for n, a in self.amps.items() if who is None or str(n) == who]
            if not amps:
                return None
            for amp in amps:
                amp.tick(now)  # the motion up to this instant
                was = amp.axis.position()
                amp.power_up()
                amp.booting_until = now + 0.3
                uc.log("copley: node %d power-cycled at position %.0f: 9600 baud, reset event "
                       "bit 20, RAM from flash" % (amp.node, was))
            if self.gateway in amps:
                self.later.clear()
                self.buf.clear()
                self.set_baud(9600)
            return ",".join(str(a.node) for a in amps)

        def state():
            return {str(n): (round(a.axis.position()), a.axis.moving())
                    for n, a in self.amps.items()}
        return uc.control_request(self, line.split(), power_cycle, state)

    def on_tick(self, now):
        for amp in self.amps.values():
            amp.tick(now)
        while self.later and self.later[0][0] <= now:
            self.reply(self.later.pop(0)[1])
        if self.gateway.ram[0x90] == 9600 and self.pty.char_time != 10.0 / 9600:
            self.set_baud(9600)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--nodes", default="0,3")
    ap.add_argument("--can-timeout-ms", type=float, default=10.0)
    ap.add_argument("--pause-ms", type=float, default=0.0)
    ap.add_argument("--pause-every-ms", type=float, default=0.0)
    uc.control_argument(ap)
    args = ap.parse_args()
    nodes = [int(n) for n in args.nodes.split(",") if n]
    uc.serve(args.link, 9600,
             lambda pty: Bus(pty, nodes, args.can_timeout_ms / 1000, args.pause_ms / 1000,
                             args.pause_every_ms / 1000),
             "copley: nodes %s on %s" % (args.nodes, args.link), args.control)


if __name__ == "__main__":
    main()
