#!/usr/bin/python3
"""Churn of silent connections from 8 loopback addresses beside a polling PLC (bench/admission/run).

Usage: churn.py FIELDGATE MODELS_DIR [--seconds S] [--rate CONNECTS_PER_S]
The daemon's one bus is absent, so reads answer 0x0B: every answer counts as a served read.
"""
import argparse
import os
import re
import shutil
import socket
import struct
import subprocess
import tempfile
import threading
import time
import urllib.request

ap = argparse.ArgumentParser()
ap.add_argument("fieldgate")
ap.add_argument("models")
ap.add_argument("--seconds", type=float, default=30)
ap.add_argument("--rate", type=float, default=450)
a = ap.parse_args()


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


port, metrics_port = free_port(), free_port()
work = tempfile.mkdtemp(prefix="fieldgate-churn-")
config = os.path.join(work, "fieldgate.yaml")
with open(config, "w") as f:
    f.write(f"""modbus: {{listen: 127.0.0.1:{port}, max_clients: 16}}
metrics: {{listen: 127.0.0.1:{metrics_port}}}
models: {os.path.abspath(a.models)}
buses:
  - name: absent
    protocol: copley-ascii
    tcp: {{host: 127.0.0.1, port: {free_port()}, baud: 115200}}
    timing: {{reply_timeout: 50ms, reconnect_min: 1s, reconnect_max: 5s}}
    nodes:
      - {{name: axis_1, address: 0, model: copley-amplifier, unit_id: 1}}
""")
log = open(os.path.join(work, "daemon.log"), "w")
daemon = subprocess.Popen([a.fieldgate, "--config", config], stdout=log, stderr=subprocess.STDOUT)
for _ in range(600):
    try:
        socket.create_connection(("127.0.0.1", port), timeout=1).close()
        break
    except OSError:
        time.sleep(0.05)

stop = threading.Event()
connects = [0] * 8


def churn(index):
    source, held = f"127.0.0.{index + 2}", []
    period = 8 / a.rate
    next_at = time.monotonic()
    while not stop.is_set():
        s = socket.socket()
        s.setblocking(False)
        try:
            s.bind((source, 0))
            s.connect_ex(("127.0.0.1", port))
            connects[index] += 1
            held.append(s)
        except OSError:
            s.close()
        if len(held) > 5:  # 8 x 5 = 40 open at most
            held.pop(0).close()
        next_at += period
        time.sleep(max(0, next_at - time.monotonic()))
    for s in held:
        s.close()


def read(sock, tid):
    sock.sendall(struct.pack(">HHHBBHH", tid, 0, 6, 1, 4, 0, 2))
    data = b""
    while len(data) < 9:
        chunk = sock.recv(256)
        if not chunk:
            return False
        data += chunk
    return struct.unpack(">H", data[:2])[0] == tid


threads = [threading.Thread(target=churn, args=(i,)) for i in range(8)]
for t in threads:
    t.start()
plc = socket.create_connection(("127.0.0.1", port), timeout=3)
reads = failed = reconnects = 0
latencies = []
start = time.monotonic()
tid = 0
while time.monotonic() - start < a.seconds:
    for _ in range(2):
        tid = (tid + 1) & 0xFFFF
        t0 = time.monotonic()
        try:
            ok = read(plc, tid)
        except OSError:
            ok = False
        latencies.append(time.monotonic() - t0)
        reads += 1
        if not ok:
            failed += 1
            reconnects += 1
            plc.close()
            plc = socket.create_connection(("127.0.0.1", port), timeout=3)
    time.sleep(0.05)
elapsed = time.monotonic() - start
stop.set()
for t in threads:
    t.join()
metrics = urllib.request.urlopen(f"http://127.0.0.1:{metrics_port}/metrics", timeout=5).read()
daemon.terminate()
daemon.wait(10)
shutil.rmtree(work, ignore_errors=True)

latencies.sort()
pct = lambda p: latencies[min(len(latencies) - 1, int(p * len(latencies)))] * 1000
print(f"churn: {sum(connects)} silent connects from 8 addresses in {elapsed:.1f} s "
      f"({sum(connects) / elapsed:.0f}/s)")
print(f"plc: {reads - failed} of {reads} reads answered, {failed} failed, {reconnects} reconnects; "
      f"latency p50 {pct(0.5):.2f} ms, p99 {pct(0.99):.2f} ms, max {latencies[-1] * 1000:.2f} ms")
for line in metrics.decode().splitlines():
    if re.match(r"fieldgate_modbus_clients_(refused|evicted)_total\{", line):
        print("  " + line)
raise SystemExit(1 if failed else 0)
