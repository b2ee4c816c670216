#!/usr/bin/python3
"""The web console in a real browser: Debian's chromium, headless, driven over the DevTools
protocol, against the demo plant's serial buses (config/demo.yaml, each behind its family's
simulator; the CANopen bus needs vcan and is left out). Asserts what a person sees: the node
table's rows and states, a unit switched off at its simulator turning offline on the page, a
move's position plot advancing, wire-trace lines arriving, the Fleet tab showing the gateway's
own Sparkplug edge node and its devices born with their metrics (a real Mosquitto broker); and
that Modbus keeps answering while 100 live views are open and one client has stopped reading.
Issue 52's trips: the console's port from --console-port over FIELDGATE_CONSOLE_PORT over the
configuration, time_ms an integer, a sticky header with a UTC 24 h clock, no overflow at 1024 px
wide, and codes in hex.
The console has a token, as scripts/demo gives it in QEMU: the page is opened with it, and its
style and script load without it. Screenshots of every tab go to OUT_DIR.

Usage: console_browser.py FIELDGATE BUILD_DIR MODELS_DIR DEMO_YAML OUT_DIR
"""
import base64
import calendar
import hashlib
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

import websocket
import yaml
from pymodbus.client import ModbusTcpClient

from process_helpers import (DEMO_SIMULATORS, Broker, check, failures, free_port, stop_processes,
                             wait_for)

FIELDGATE, BUILD, MODELS, DEMO_YAML, OUT = sys.argv[1:6]
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
ABSENT = {"axis_7"}  # configured in the demo, on no simulated bus
TOKEN = "0123456789abcdef-console-test"
EDGE = "console-gw"  # the gateway's Sparkplug edge node ID
class Plant:
    """The demo's serial buses behind their simulators, and the daemon with its console."""

    def __init__(self, d):
        self.dir = d
        demo = yaml.safe_load(open(DEMO_YAML))
        buses = [b for b in demo["buses"] if "serial" in b]
        self.sims = {}
        self.nodes = []
        for bus in buses:
            link = os.path.basename(bus["serial"]["device"])
            path, args = DEMO_SIMULATORS[link]
            bus["serial"]["device"] = os.path.join(d, link)
            log = open(os.path.join(d, link + ".log"), "w")
            self.sims[link] = subprocess.Popen(
                [os.path.join(BUILD, "sim", path), "--link", bus["serial"]["device"], *args,
                 "--emulate-wire"], stdin=subprocess.PIPE, stdout=log, stderr=log, text=True)
            self.nodes += [n["name"] for n in bus["nodes"]]
        for link in self.sims:
            assert wait_for(lambda: os.path.exists(os.path.join(d, link)), 10), link
        self.modbus_port, self.console_port = free_port(), free_port()
        # The configuration's and the environment's ports are not the console's: the command
        # line's wins (docs/console.md, The port).
        self.config_console_port, self.env_console_port = free_port(), free_port()
        self.broker = Broker(d, free_port())
        self.broker.start()
        token_file = os.path.join(d, "console-token.sha256")
        with open(token_file, "w") as f:
            f.write(hashlib.sha256(TOKEN.encode()).hexdigest() + "  -\n")
        config = dict(demo)
        config.update({"modbus": {**demo["modbus"], "listen": f"127.0.0.1:{self.modbus_port}",
                                  "max_clients": 64},
                       "models": MODELS, "buses": buses,
                       "console": {"listen": f"127.0.0.1:{self.config_console_port}",
                                   "token_file": token_file},
                       "sparkplug": {"broker": f"mqtt://127.0.0.1:{self.broker.port}",
                                     "group_id": "console-test", "edge_node_id": EDGE}})
        self.config = os.path.join(d, "gateway.yaml")
        with open(self.config, "w") as f:
            yaml.safe_dump(config, f, sort_keys=False)
        self.log_path = os.path.join(d, "daemon.log")
        self.daemon = subprocess.Popen(
            [FIELDGATE, "--config", self.config, "--console-port", str(self.console_port)],
            env={**os.environ, "FIELDGATE_CONSOLE_PORT": str(self.env_console_port)},
            stdout=open(self.log_path, "w"), stderr=subprocess.STDOUT)
        self.url = f"http://127.0.0.1:{self.console_port}/"
        self.page = self.url + "?token=" + TOKEN

    def control(self, link, line):
        self.sims[link].stdin.write(line + "\n")
        self.sims[link].stdin.flush()

    def log(self):
        return open(self.log_path).read()

    def stop(self):
        stop_processes(self.daemon, *self.sims.values())
        self.broker.stop()


class Browser:
    """Headless chromium with one page, driven over the DevTools protocol."""

    def __init__(self, d):
        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--disable-dev-shm-usage", "--window-size=1400,1000", "--remote-debugging-port=0",
             f"--user-data-dir={os.path.join(d, 'chromium')}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        port = None
        end = time.monotonic() + 60
        while port is None and time.monotonic() < end:
            line = self.proc.stderr.readline()
            if not line and self.proc.poll() is not None:
                raise RuntimeError("chromium exited before it listened")
            m = re.search(r"DevTools listening on ws://127\.0\.0\.1:(\d+)/", line)
            if m:
                port = int(m.group(1))
        if port is None:
            raise RuntimeError("chromium did not open its DevTools port within 60 s")
        pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
        page = next(p for p in pages if p["type"] == "page")
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=30)
        self.next_id = 0
        self.call("Page.enable")
        self.call("Runtime.enable")

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def eval(self, expression):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def open(self, url):
        self.call("Page.navigate", url=url)
        wait_for(lambda: self.eval("document.readyState") == "complete", 20)

    def viewport(self, width, height):
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                  deviceScaleFactor=1, mobile=False)

    def screenshot(self, name):
        data = self.call("Page.captureScreenshot", format="png")["data"]
        path = os.path.join(OUT, name + ".png")
        with open(path, "wb") as f:
            f.write(base64.b64decode(data))
        print(f"screenshot: {path}", flush=True)

    def stop(self):
        try:
            self.ws.close()
        finally:
            stop_processes(self.proc)


ROW_STATES = ("Object.fromEntries([...document.querySelectorAll('#nodes tbody tr')]"
              ".map(r => [r.dataset.node, r.dataset.state]))")


def profile_move(mb, unit, target, velocity, sequence):
    """Move absolute on a profile unit: target and velocity (int32, high word first), then the
    command code with its sequence number (docs/axis-profile.md)."""
    words = []
    for v in (target, velocity):
        v &= 0xFFFFFFFF
        words += [v >> 16, v & 0xFFFF]
    assert not mb.write_registers(0, words, slave=unit).isError()
    assert not mb.write_registers(8, [4, sequence], slave=unit).isError()


def main():
    os.makedirs(OUT, exist_ok=True)
    d = tempfile.mkdtemp(prefix="fieldgate-console-")
    plant = Plant(d)
    browser = None
    try:
        check("the daemon prints the console's address, on the port of --console-port",
              wait_for(lambda: plant.url in plant.log(), 15), plant.log()[-2000:])
        raw = urllib.request.urlopen(plant.url + "api/plant?token=" + TOKEN).read().decode()
        check("time_ms is an integer", re.match(r'\{"time_ms":\d+,', raw), raw[:60])
        browser = Browser(d)
        browser.open(plant.page)
        check("the page goes live", wait_for(
            lambda: browser.eval("document.getElementById('link').textContent") == "live", 15))
        display = browser.eval("getComputedStyle(document.getElementById('axes')).display")
        check("its style applies (a tab not shown is hidden), loaded without the token",
              display == "none", display)

        # Plant: one row per configured node, each with the state the gateway gives it.
        rows = wait_for(lambda: (lambda s: s if s and all(
            v == "online" for k, v in s.items() if k not in ABSENT) else None)(
                browser.eval(ROW_STATES)), 40)
        rows = rows or browser.eval(ROW_STATES)
        check("a row for every node of the plant", sorted(rows) == sorted(plant.nodes),
              f"rows {sorted(rows)}, nodes {sorted(plant.nodes)}")
        check("every node on a simulated bus shows online",
              all(v == "online" for k, v in rows.items() if k not in ABSENT), rows)
        absent = wait_for(lambda: browser.eval(ROW_STATES).get("axis_7") == "offline", 20)
        check("the node absent from its bus shows offline", absent, browser.eval(ROW_STATES))
        reason = browser.eval("document.querySelector('#nodes tr[data-node=\"axis_7\"]')"
                              ".cells[6].textContent")
        check("an offline node says why", bool(reason), reason)
        browser.screenshot("plant")

        # The header's clock: UTC, 24 h, as the trace; the header stays in view when scrolled.
        clock = browser.eval("document.getElementById('clock').textContent")
        m = re.fullmatch(r"(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d) UTC", clock or "")
        shown = m and calendar.timegm(time.strptime(m.group(1), "%Y-%m-%d %H:%M:%S"))
        check("the header's clock is UTC, 24 h, and now",
              m and abs(shown - time.time()) < 5, f"{clock} at {time.time()}")
        # 1024 px wide, 500 px high: the Plant tab fits the width and scrolls under its header.
        browser.viewport(1024, 500)
        time.sleep(1.5)
        widths = browser.eval("[document.documentElement.scrollWidth, innerWidth, Math.max("
                              "...[...document.querySelectorAll('#plant table')]"
                              ".map(t => t.getBoundingClientRect().right))]")
        check("at 1024 px the Plant tab fits: no sideways scroll, its tables within the window",
              widths[0] <= widths[1] and widths[2] <= widths[1], widths)
        browser.screenshot("plant-1024")
        header = browser.eval("(() => { scrollTo(0, 100000); return [scrollY,"
                              " document.querySelector('header').getBoundingClientRect().top]; })()")
        check("the header stays at the top when the page is scrolled",
              header[0] > 0 and header[1] == 0, header)
        browser.screenshot("plant-1024-scrolled")
        browser.eval("scrollTo(0, 0)")
        browser.call("Emulation.clearDeviceMetricsOverride")

        # A unit switched off at its simulator turns offline on the page, without a reload.
        plant.control("ims0", "axis-off B")
        t0 = time.monotonic()
        went = wait_for(lambda: browser.eval(ROW_STATES).get("ims_b") == "offline", 20)
        check("ims_b switched off at the simulator turns offline on the page", went,
              browser.eval(ROW_STATES))
        print(f"offline on the page after {time.monotonic() - t0:.1f} s", flush=True)
        browser.screenshot("plant-ims_b-offline")
        plant.control("ims0", "axis-on B")
        check("and online again when switched back on", wait_for(
            lambda: browser.eval(ROW_STATES).get("ims_b") == "online", 20))

        # Axes: a move on ims_a's profile unit; its position plot advances.
        browser.eval("document.querySelector('nav button[data-tab=axes]').click()")
        card = "document.querySelector('.axis[data-axis=\"ims_a/axis\"]')"
        check("a card for every profile axis", wait_for(
            lambda: browser.eval(f"!!{card}"), 10), "no card for ims_a/axis")
        mb = ModbusTcpClient("127.0.0.1", port=plant.modbus_port)
        mb.connect()
        profile_move(mb, 111, 6000, 2000, 1)
        seen = []

        def position():
            p = browser.eval(f"{card}.querySelector('dd[data-field=position]').textContent")
            if p not in ("—", None) and (not seen or seen[-1] != p):
                seen.append(p)
            return len(seen) >= 5

        check("the position on the page advances during the move", wait_for(position, 20),
              seen)
        check("... monotonically", all(int(a) <= int(b) for a, b in zip(seen, seen[1:])), seen)
        samples = browser.eval(f"+{card}.dataset.samples")
        check("the plot has the samples", samples >= 5, samples)
        state = browser.eval(f"{card}.dataset.state")
        check("the card shows the PLCopen state of a move",
              state in ("DiscreteMotion", "Standstill"), state)
        browser.screenshot("axes-moving")
        wait_for(lambda: browser.eval(f"{card}.dataset.state") == "Standstill", 30)

        # A move refused on a Disabled axis: command_error 0xfff0 on the card, in hex as
        # docs/axis-profile.md gives it (65520 in decimal).
        disabled = browser.eval(
            "[...document.querySelectorAll('.axis[data-state=Disabled]')].map(c => [c.dataset.axis,"
            " +c.querySelector('h3').textContent.match(/unit (\\d+)/)[1]])")
        check("an axis stands Disabled (before its power-on)", disabled, disabled)
        if disabled:
            axis, unit = disabled[0]
            profile_move(mb, unit, 1000, 1000, 1)
            command = (f"document.querySelector('.axis[data-axis=\"{axis}\"]"
                       " dd[data-field=command]')")
            check(f"{axis}: a refused command's error shows in hex", wait_for(
                lambda: (browser.eval(f"{command}.textContent") or "").endswith("(error 0xfff0)"),
                10), browser.eval(f"{command}.textContent"))
        browser.screenshot("axes-refused")

        # Bus: trace lines arrive, with wall-clock time, filterable.
        browser.eval("document.querySelector('nav button[data-tab=bus]').click()")
        lines = wait_for(lambda: browser.eval("+document.getElementById('trace').dataset.lines"),
                         10)
        check("trace lines arrive on the Bus tab", lines and lines > 0, lines)
        text = browser.eval("document.getElementById('trace').textContent")
        first = text.splitlines()[0] if text else ""
        check("a trace line: wall-clock time, bus, node, direction, outcome, bytes",
              re.match(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d+ \S+ \S+ (tx|rx) \S+ '.*'$", first),
              first)
        browser.eval("(() => { const s = document.getElementById('trace-bus');"
                     " s.value = 'ims-party-line'; s.dispatchEvent(new Event('input')); })()")
        time.sleep(1)
        text = browser.eval("document.getElementById('trace').textContent")
        check("the bus filter shows that bus alone",
              text and all(" ims-party-line " in l for l in text.splitlines()), text[:300])
        clients = wait_for(lambda: browser.eval(
            "[...document.querySelectorAll('#clients tbody tr')].map(r => [r.dataset.client,"
            " +r.cells[4].textContent])"), 5)
        check("the Modbus client is listed with its requests",
              clients and any(requests >= 2 for _, requests in clients), clients)
        browser.screenshot("bus-trace")

        # Fleet: the gateway's own edge node on the broker, born, with its devices and metrics.
        browser.eval("document.querySelector('nav button[data-tab=fleet]').click()")
        edge = f"document.querySelector('#fleet-nodes tr[data-edge=\"{EDGE}\"]')"
        check("the Fleet tab shows the gateway's edge node born", wait_for(
            lambda: browser.eval(f"{edge} && {edge}.dataset.state") == "born", 20),
            browser.eval("document.getElementById('fleet-summary').textContent"))
        online = [n for n in plant.nodes if n not in ABSENT]
        born = wait_for(lambda: (lambda b: b if set(online) <= set(b) else None)(browser.eval(
            "[...document.querySelectorAll('#fleet-devices details[data-state=born]')]"
            ".map(d => d.dataset.device.split('/')[1])")), 20) or []
        check("... and every node on a simulated bus as a device born", set(online) <= set(born),
              f"born {sorted(born)}")
        metrics = browser.eval(
            f"document.querySelector('#fleet-devices details[data-device=\"{EDGE}/ims_a\"]')"
            "?.querySelector('summary').textContent")
        check("a device shows its metrics decoded", bool(metrics) and
              re.search(r": born, [1-9]\d* metrics$", metrics), metrics)
        browser.screenshot("fleet")

        # 100 live views and one client that stopped reading: Modbus keeps answering.
        views = []
        for _ in range(100):
            s = socket.create_connection(("127.0.0.1", plant.console_port))
            s.sendall(f"GET /events?trace=1&token={TOKEN} HTTP/1.1\r\nHost: x\r\n\r\n".encode())
            views.append(s)
        stalled = socket.create_connection(("127.0.0.1", plant.console_port))
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        stalled.sendall(f"GET /events?trace=1&token={TOKEN} HTTP/1.1\r\nHost: x\r\n\r\n".encode())
        good = 0
        end = time.monotonic() + 5
        reads = 0
        while time.monotonic() < end:
            for v in views:  # the live views keep reading, as browsers do
                v.setblocking(False)
                try:
                    while v.recv(65536):
                        pass
                except BlockingIOError:
                    pass
            r = mb.read_input_registers(0, 2, slave=11)
            reads += 1
            good += 0 if r.isError() else 1
        check("Modbus answers every read while 100 views and a stalled client are open",
              reads > 0 and good == reads, f"{good} of {reads}")
        check("the page still updates", wait_for(
            lambda: browser.eval("document.getElementById('link').textContent") == "live", 5))
        for v in views:
            v.close()
        stalled.close()
        mb.close()
        check("no console error in the daemon's log", "console: cannot" not in plant.log())
    finally:
        if browser:
            browser.stop()
        plant.stop()
    if failures:
        print(plant.log()[-4000:])
        print(f"{len(failures)} check(s) failed: {', '.join(failures)}")
        return 1
    print("console in a browser: every check passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
