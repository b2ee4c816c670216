#!/usr/bin/python3
"""How long a reload holds up Modbus answers (bench/reload/run).

Usage: stall.py FIELDGATE MODELS_DIR [--reloads N] [--interval S]
A PLC reads two input registers back to back on one connection while the daemon gets SIGHUP every
INTERVAL seconds, with an unchanged file of two serial buses of two Copley nodes each (absent
devices: every read answers at once, 0x0B). A read's latency beyond the quiet ones is the stall.
"""
import argparse
import os
import signal
import socket
import statistics
import struct
import subprocess
import tempfile
import threading
import time

ap = argparse.ArgumentParser()
ap.add_argument("fieldgate")
ap.add_argument("models")
ap.add_argument("--reloads", type=int, default=20)
ap.add_argument("--interval", type=float, default=0.5)
a = ap.parse_args()


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


port = free_port()
work = tempfile.mkdtemp(prefix="fieldgate-reload-")
config = os.path.join(work, "fieldgate.yaml")
nodes = ""
buses = ""
for b, units in (("a", (1, 2)), ("b", (3, 4))):
    buses += f"""  - name: {b}
    protocol: copley-ascii
    serial: {{device: {work}/tty{b}, baud: 115200}}
    nodes:
"""
    for i, u in enumerate(units):
        buses += f"      - {{name: {b}{i}, address: {i + 1}, model: copley-amplifier, unit_id: {u}}}\n"
with open(config, "w") as f:
    f.write(f"models: {a.models}\nmodbus: {{listen: 127.0.0.1:{port}}}\nbuses:\n{buses}")
log_path = os.path.join(work, "log")
log = open(log_path, "w")
daemon = subprocess.Popen([a.fieldgate, "--config", config], stdout=log, stderr=log)


def log_text():
    with open(log_path) as f:
        return f.read()


deadline = time.time() + 10
while "modbus: listening" not in log_text():
    if time.time() > deadline or daemon.poll() is not None:
        raise SystemExit("the daemon did not start:\n" + log_text())
    time.sleep(0.05)

latencies = []  # (time sent, seconds)
stop = False


def plc():
    s = socket.create_connection(("127.0.0.1", port))
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    tid = 0
    while not stop:
        tid = (tid + 1) & 0xFFFF
        req = struct.pack(">HHHBBHH", tid, 0, 6, 1, 4, 0, 2)
        t0 = time.perf_counter()
        s.sendall(req)
        got = b""
        while len(got) < 9:
            chunk = s.recv(260)
            if not chunk:
                raise SystemExit("the daemon closed the PLC's connection")
            got += chunk
        latencies.append((t0, time.perf_counter() - t0))
    s.close()


t = threading.Thread(target=plc)
t.start()
time.sleep(1)
reload_times = []
for i in range(a.reloads):
    reload_times.append(time.perf_counter())
    daemon.send_signal(signal.SIGHUP)
    time.sleep(a.interval)
stop = True
t.join()
daemon.send_signal(signal.SIGTERM)
daemon.wait(timeout=10)
text = log_text()
reloaded = text.count("reloaded:")
quiet = sorted(l for t0, l in latencies if all(not (r - 0.01 <= t0 <= r + 0.2) for r in reload_times))
around = [max((l for t0, l in latencies if r - 0.2 <= t0 <= r + 0.2), default=0) for r in reload_times]
ms = lambda x: f"{x * 1000:.2f} ms"
print(f"reloads: {a.reloads} sent, {reloaded} logged 'reloaded:'")
print(f"reads: {len(latencies)}; quiet reads p50 {ms(quiet[len(quiet) // 2])}, "
      f"p99 {ms(quiet[int(len(quiet) * 0.99)])}, max {ms(quiet[-1])}")
print(f"longest read around each reload: median {ms(statistics.median(around))}, "
      f"max {ms(max(around))}, min {ms(min(around))}")
