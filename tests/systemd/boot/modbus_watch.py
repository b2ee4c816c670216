#!/usr/bin/python3
"""A Modbus TCP client that keeps one connection and reads one unit every 100 ms.

Usage: modbus_watch.py HOST PORT UNIT STATE_FILE
The state file is rewritten after every read: "reads=N ok=N exceptions=N failures=N
connections=N last=..." (a failure is no answer or a broken connection; an exception is a Modbus
exception response, e.g. 0x0B while a bus is reopened). Stops on SIGTERM. Python stdlib only.
"""
import signal
import socket
import struct
import sys
import time

host, port, unit, state_file = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
counts = {"reads": 0, "ok": 0, "exceptions": 0, "failures": 0, "connections": 0}
last = "none"
running = True


def stop(*_):
    global running
    running = False


signal.signal(signal.SIGTERM, stop)


def save():
    with open(state_file + ".new", "w") as f:
        f.write(" ".join(f"{k}={v}" for k, v in counts.items()) + f" last={last}\n")
    import os
    os.replace(state_file + ".new", state_file)


def receive(sock, n):
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("closed by the server")
        data += chunk
    return data


sock = None
tid = 0
while running:
    try:
        if sock is None:
            sock = socket.create_connection((host, port), timeout=2)
            counts["connections"] += 1
        tid = (tid + 1) & 0xFFFF
        # Read input registers 0..1 (function 4).
        sock.sendall(struct.pack(">HHHBBHH", tid, 0, 6, unit, 4, 0, 2))
        header = receive(sock, 7)
        rtid, _, length, _ = struct.unpack(">HHHB", header)
        body = receive(sock, length - 1)
        counts["reads"] += 1
        if rtid != tid:
            counts["failures"] += 1
            last = f"transaction {rtid} for {tid}"
        elif body[0] & 0x80:
            counts["exceptions"] += 1
            last = f"exception 0x{body[1]:02x}"
        else:
            counts["ok"] += 1
            last = "ok"
    except (OSError, ConnectionError) as e:
        counts["reads"] += 1
        counts["failures"] += 1
        last = f"error {e}"
        if sock is not None:
            sock.close()
        sock = None
        time.sleep(0.5)
    save()
    time.sleep(0.1)
save()
