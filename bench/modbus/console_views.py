#!/usr/bin/python3
"""Live views of the web console for bench/modbus/run --console-views N: N event streams with the
wire trace (what N browser tabs on the Bus tab ask for), each read as it arrives, and one more
that is never read (a stalled client). Runs until killed; then prints what the views received.

Usage: console_views.py PORT N"""
import select
import signal
import socket
import sys

port, count = int(sys.argv[1]), int(sys.argv[2])
request = b"GET /events?trace=1 HTTP/1.1\r\nHost: bench\r\n\r\n"
views = []
for _ in range(count):
    s = socket.create_connection(("127.0.0.1", port))
    s.sendall(request)
    s.setblocking(False)
    views.append(s)
stalled = socket.create_connection(("127.0.0.1", port))
stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
stalled.sendall(request)
received = 0
closed = 0


def report(*_):
    print(f"console views: {count} read, 1 stalled; {received} bytes received, {closed} closed by "
          "the gateway", flush=True)
    sys.exit(0)


signal.signal(signal.SIGTERM, report)
signal.signal(signal.SIGINT, report)
print(f"console views: {count} open", flush=True)
while True:
    readable, _, _ = select.select(views, [], [], 1.0)
    for s in readable:
        try:
            data = s.recv(65536)
        except BlockingIOError:
            continue
        if not data:
            views.remove(s)
            closed += 1
        received += len(data)
