"""Shared plumbing of the independent controller implementations: a PTY served under a symlink,
an event loop with timed output (characters leave at the line's baud rate), and a kinematic axis.

Written from the manuals only; nothing here is taken from sim/ or drivers/.
"""
import argparse
import json
import math
import os
import select
import socket
import sys
import termios
import time
import tty


class Pty:
    """The unit's end of a serial line: a PTY whose slave side is reachable at `link`."""

    def __init__(self, link, baud):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        attrs = termios.tcgetattr(self.master)
        attrs[3] &= ~termios.ECHO
        termios.tcsetattr(self.master, termios.TCSANOW, attrs)
        if os.path.lexists(link):
            os.unlink(link)
        os.symlink(os.ttyname(self.slave), link)
        self.link = link
        self.char_time = 10.0 / baud
        self.out = []  # (due time, message)
        self.rate_now = self.rate_before = None
        self.rate_changed = 0.0
        self.busy_until = 0.0

    def send(self, data):
        """Queues one message. It is written in one piece once the line would have carried its
        last character: a UART sends back to back, and a scheduler pause inside a reply must
        not look like a gap on the wire."""
        now = time.monotonic()
        start = max(now, self.busy_until)
        self.busy_until = start + len(data) * self.char_time
        self.out.append((self.busy_until, bytes(data)))

    def host_baud(self):
        """The rate the host set on its end of the line (its termios), or None if unknown."""
        try:
            speed = termios.tcgetattr(self.slave)[5]
        except termios.error:
            return None
        for name in dir(termios):
            if name.startswith("B") and name[1:].isdigit() and getattr(termios, name) == speed:
                return int(name[1:])
        return None

    def sample_rate(self, now):
        rate = self.host_baud()
        if rate != self.rate_now:
            self.rate_before, self.rate_now, self.rate_changed = self.rate_now, rate, now

    def heard_at(self, rate, now):
        """Whether bytes just read were sent at `rate`. A PTY carries bytes at any rate, and a
        host may switch its rate right after writing (its tcdrain returns at once here): bytes
        count as sent at the rate the host had up to 50 ms ago as well as at the current one."""
        self.sample_rate(now)
        if self.rate_now is None or self.rate_now == rate:
            return True
        return self.rate_before == rate and now - self.rate_changed < 0.05

    def next_due(self):
        return self.out[0][0] if self.out else None

    def flush_due(self, now):
        """Writes the messages whose last character has left."""
        chunk = bytearray()
        while self.out and self.out[0][0] <= now:
            chunk += self.out.pop(0)[1]
        if chunk:
            try:
                os.write(self.master, bytes(chunk))
            except OSError:
                pass

    def read(self):
        try:
            return os.read(self.master, 4096)
        except OSError:
            return b""


def serve(link, baud, make, what, control=None):
    """A PTY at `baud` on `link` for the unit make(pty) (with on_bytes and on_tick): logs `what`
    once the unit is made, then serves until killed. With `control` (a socket path), the unit's
    control(line, now) answers the lines of Control."""
    pty = Pty(link, baud)
    unit = make(pty)
    log(what)
    run(pty, unit.on_bytes, unit.on_tick, control=Control.open(control, unit))


class Control:
    """The test's hand on the unit: a Unix stream socket at `path` (--control PATH). Each line a
    client sends gets one line back, from handler(line, now):

      power-cycle [WHO]  remove and restore the power of the unit(s) on the line (WHO: one
                         controller, as the unit names it; default every one): exactly what the
                         vendor's manual says a power-up does, any motion aborted
      state              JSON: {"axes": {NAME: {"position": p, "moving": b}}, "power_cycles": n},
                         the position as the controller would report it on the wire

    A unit without a control line leaves it out; the test then has no hand on it."""

    @staticmethod
    def open(path, unit):
        if not path:
            return None
        return Control(path, unit.control)

    def __init__(self, path, handler):
        if os.path.lexists(path):
            os.unlink(path)
        self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.listener.bind(path)
        self.listener.listen(4)
        self.listener.setblocking(False)
        self.handler = handler
        self.clients = {}  # socket -> bytearray (the line being received)

    def sockets(self):
        return [self.listener] + list(self.clients)

    def ready(self, sock, now):
        if sock is self.listener:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            client.setblocking(True)
            self.clients[client] = bytearray()
            return
        try:
            data = sock.recv(4096)
        except OSError:
            data = b""
        if not data:
            self.clients.pop(sock, None)
            sock.close()
            return
        buf = self.clients[sock]
        buf += data
        while b"\n" in buf:
            line, _, rest = bytes(buf).partition(b"\n")
            buf[:] = rest
            text = line.decode(errors="replace").strip()
            try:
                answer = self.handler(text, now)
            except Exception as e:  # a bad request must not stop the unit
                answer = "error %s" % e
            if text != "state":  # state is polled: it would flood the log
                log("%.3f control %r -> %s" % (time.monotonic() - _t0, text, answer[:200]))
            try:
                sock.sendall(answer.encode() + b"\n")
            except OSError:
                self.clients.pop(sock, None)
                sock.close()


def control_request(unit, parts, power_cycle, state):
    """The common grammar of a unit's control(line, now): `power-cycle [WHO]` calls
    power_cycle(who or None) (which returns a text, or None for an unknown WHO), `state` returns
    json of state() (a dict of axis name -> (position, moving))."""
    if not parts:
        return "error empty request"
    if parts[0] == "power-cycle":
        who = parts[1] if len(parts) > 1 else None
        unit.power_cycles = getattr(unit, "power_cycles", 0) + 1
        done = power_cycle(who)
        if done is None:
            unit.power_cycles -= 1
            return "error no controller %r" % who
        return "ok " + done
    if parts[0] == "state":
        axes = {name: {"position": p, "moving": bool(m)} for name, (p, m) in state().items()}
        return json.dumps({"axes": axes, "power_cycles": getattr(unit, "power_cycles", 0)})
    return "error unknown request %r" % parts[0]


def heard_only_at(pty, baud, unit, on_bytes):
    """on_bytes for a unit fixed at `baud`: what the host sent at another rate is logged as
    unreadable and dropped."""
    def filtered(data, now):
        if not pty.heard_at(baud, now):
            wire("(host at %d baud, %s at %d: %d bytes unreadable)" %
                 (pty.rate_now, unit, baud, len(data)))
            return
        on_bytes(data, now)
    return filtered


def run(pty, on_bytes, on_tick, tick=0.005, control=None):
    """Serves until killed: bytes in go to on_bytes(data, now), on_tick(now) runs every tick;
    `control` (a Control, or None) answers the test's requests between them."""
    last = time.monotonic()
    while True:
        due = pty.next_due()
        timeout = tick if due is None else max(0.0, min(tick, due - time.monotonic()))
        watched = [pty.master] + (control.sockets() if control else [])
        r, _, _ = select.select(watched, [], [], timeout)
        now = time.monotonic()
        if control:
            for sock in r:
                if sock is not pty.master:
                    control.ready(sock, now)
            r = [x for x in r if x is pty.master]
        if not r:
            pty.sample_rate(now)
        if r:
            data = pty.read()
            if data:
                on_bytes(data, now)
            else:
                time.sleep(tick)
        if now - last >= tick:
            on_tick(now)
            last = now
        pty.flush_due(time.monotonic())


class Axis:
    """One motor with trapezoidal profiles, position in the unit's own counts (float).

    Limit switches sit at physical positions (relative to where the unit powered up); the home
    switch is an edge at `home_switch`: high below it, low above it."""

    def __init__(self, accel=20000.0, limit_neg=-1e6, limit_pos=1e6, home_switch=-1500.0):
        self.pos = 0.0  # physical position, counts
        self.offset = 0.0  # reported = physical - offset
        self.v = 0.0
        self.accel = accel
        self.decel = accel
        self.mode = "idle"  # idle, pos, vel, stop
        self.target = 0.0
        self.vmax = 0.0
        self.limit_neg, self.limit_pos = limit_neg, limit_pos
        self.home_switch = home_switch
        self.hit_limit = 0  # +1 or -1 when the last motion ended on a limit
        self.last = time.monotonic()

    # Reported position
    def position(self):
        return self.pos - self.offset

    def set_position(self, value):
        self.offset = self.pos - value

    def moving(self):
        return self.mode != "idle"

    def limit_active(self, sign):
        return self.pos >= self.limit_pos if sign > 0 else self.pos <= self.limit_neg

    def home_input_high(self):
        return self.pos < self.home_switch

    # Commands
    def move_to(self, reported_target, velocity):
        self.mode, self.target, self.vmax = "pos", reported_target + self.offset, abs(velocity)
        self.hit_limit = 0

    def run_at(self, velocity):
        self.mode, self.vmax = "vel", velocity
        self.hit_limit = 0

    def stop(self, decel=None):
        if self.mode != "idle":
            self.mode, self.vmax = "stop", 0.0
            if decel:
                self.decel = decel

    def hard_stop(self):
        self.mode, self.v = "idle", 0.0

    def power_up(self, position=0.0):
        """Power removed and restored: the motor stops where it is (no ramp: the drive has no
        power to decelerate it), and the controller counts from `position` again. The physical
        position, and so the switches, stay where they are."""
        self.hard_stop()
        self.hit_limit = 0
        self.set_position(position)

    def _approach(self, want, dt):
        rate = self.accel if abs(want) > abs(self.v) and want * self.v >= 0 else self.decel
        step = rate * dt
        if abs(want - self.v) <= step:
            self.v = want
        else:
            self.v += step if want > self.v else -step

    def tick(self, now):
        dt = now - self.last
        self.last = now
        if self.mode == "idle":
            return
        if self.mode == "pos":
            dist = self.target - self.pos
            if abs(dist) < 1e-6 and abs(self.v) < 1e-6:
                self.mode, self.v = "idle", 0.0
                return
            reach = math.sqrt(2.0 * self.decel * abs(dist))
            want = math.copysign(min(self.vmax, reach), dist)
            self._approach(want, dt)
            if abs(self.v) < 1e-9:
                self.v = math.copysign(min(self.vmax, self.accel * dt, abs(dist) / dt), dist)
            move = self.v * dt
            if abs(move) >= abs(dist) or (move * dist < 0 and abs(dist) < 1.0):
                self.pos, self.v, self.mode = self.target, 0.0, "idle"
            else:
                self.pos += move
        elif self.mode == "vel":
            self._approach(self.vmax, dt)
            self.pos += self.v * dt
        elif self.mode == "stop":
            self._approach(0.0, dt)
            self.pos += self.v * dt
            if self.v == 0.0:
                self.mode = "idle"
        # Limit switches stop motion in their direction, without a ramp.
        for sign in (1, -1):
            if self.mode != "idle" and self.v * sign > 0 and self.limit_active(sign):
                self.pos = self.limit_pos if sign > 0 else self.limit_neg
                self.mode, self.v, self.hit_limit = "idle", 0.0, sign


_seen = {}
_t0 = time.monotonic()


def wire(text):
    """Logs a command line the first few times it is seen (polls would flood the log)."""
    key = text[:40]
    _seen[key] = _seen.get(key, 0) + 1
    if _seen[key] <= 3 or os.environ.get("INDEPENDENT_WIRE_ALL"):
        log("%.3f rx %s" % (time.monotonic() - _t0, text))


def log(text):
    print(text, file=sys.stderr, flush=True)


def feed_line(buf, b, ends, limit):
    """Adds byte b to the line being received in buf: at one of the `ends` bytes, returns the
    line (without it or a CR before it) and starts the next; otherwise None. Keeps the last
    `limit` bytes of a line that never ends."""
    if b in ends:
        text = bytes(buf).rstrip(b"\r").decode("ascii", errors="replace")
        buf.clear()
        return text
    buf.append(b)
    if len(buf) > limit:
        del buf[:-limit]
    return None


# The received-line log of the units that print what they hear (--log first|all|none): each
# distinct line at most three times unless "all".
received_log = {"mode": "first", "seen": {}, "t0": time.monotonic()}


def rx(text):
    """Logs a command line as received, on stdout."""
    mode = received_log["mode"]
    if mode == "none":
        return
    seen = received_log["seen"]
    key = text[:40]
    seen[key] = seen.get(key, 0) + 1
    if mode == "all" or seen[key] <= 3:
        print("%.3f rx %s" % (time.monotonic() - received_log["t0"], text), flush=True)


class TestHost:
    """The host end of a unit's PTY for its --self-test: raw, at the unit's baud rate."""

    def __init__(self, link, baud, wait=0.15):
        self.fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
        self.wait = wait
        tty.setraw(self.fd)
        attrs = termios.tcgetattr(self.fd)
        attrs[4] = attrs[5] = getattr(termios, "B%d" % baud)
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)

    def send(self, text):
        os.write(self.fd, text.encode())

    def read_for(self, seconds):
        end = time.monotonic() + seconds
        out = b""
        while True:
            left = end - time.monotonic()
            if left <= 0:
                return out
            r, _, _ = select.select([self.fd], [], [], left)
            if r:
                out += os.read(self.fd, 4096)

    def ask(self, text, wait=None):
        self.send(text)
        return self.read_for(self.wait if wait is None else wait)

    def set_rate(self, baud):
        """Switches the host's end to another rate (the unit must then hear nothing)."""
        attrs = termios.tcgetattr(self.fd)
        attrs[4] = attrs[5] = getattr(termios, "B%d" % baud)
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)


class SelfTest:
    """The checks of a unit's --self-test, through its TestHost."""

    def __init__(self, host, poll=0.1):
        self.host, self.poll, self.failures = host, poll, []

    def check(self, what, got, want):
        ok = want(got) if callable(want) else got == want
        print("%s %-36s %r" % ("ok  " if ok else "FAIL", what, got))
        if not ok:
            self.failures.append(what)

    def wait_for(self, query, want, seconds):
        end = time.monotonic() + seconds
        got = b""
        while time.monotonic() < end:
            got = self.host.ask(query, self.poll)
            if got == want:
                break
        return got

    def finish(self, link, other_rate, query):
        """At another host rate the unit must hear nothing; then the count and exit status."""
        self.host.set_rate(other_rate)
        time.sleep(0.1)  # past the 50 ms during which the old rate still counts
        self.check("host at %d: unreadable" % other_rate, self.host.ask(query), b"")
        os.unlink(link)
        print("self-test: %d failure(s)" % len(self.failures))
        return 1 if self.failures else 0


def parse_unit_arguments(ap, self_test):
    """Parses a unit's options: --log takes effect, --self-test runs (and exits), --link is then
    required."""
    args = ap.parse_args()
    received_log["mode"] = args.log
    if args.self_test:
        sys.exit(self_test(args))
    if not args.link:
        ap.error("--link is required")
    return args


def control_argument(ap):
    """--control PATH: the socket of Control (the test's power-cycle and state requests)."""
    ap.add_argument("--control", help="Unix socket for the test's requests: power-cycle [WHO], "
                    "state (see unit_common.Control)")


def unit_arguments(doc, baud):
    """The options every unit takes (--link, --baud, --log, --self-test); the unit adds its own."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--link", help="symlink to the PTY slave the gateway opens")
    ap.add_argument("--baud", type=int, default=baud)
    ap.add_argument("--log", default="first", choices=["first", "all", "none"])
    ap.add_argument("--self-test", action="store_true")
    return ap
