#!/usr/bin/python3
"""Hostile-peer checks against the real daemon: malformed Modbus, connection abuse, metrics abuse.

Usage: abuse_test.py FIELDGATE MODELS_DIR SCENARIO

The daemon serves one Copley bus whose TCP serial server is absent, so its units answer 0x0B:
every check here is about the Modbus side staying correct and available, not about values.
Counts are printed; nothing asserts a wall-clock limit.
"""
import os
import resource
import select
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

FIELDGATE, MODELS, SCENARIO = sys.argv[1], os.path.abspath(sys.argv[2]), sys.argv[3]
failures = []


def check(condition, message):
    print(("ok   " if condition else "FAIL ") + message, flush=True)
    if not condition:
        failures.append(message)


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Daemon:
    def __init__(self, modbus_extra="", metrics=False, nofile=None):
        self.port = free_port()
        self.metrics_port = free_port() if metrics else None
        self.dir = tempfile.mkdtemp(prefix="fieldgate-abuse-")
        config = os.path.join(self.dir, "fieldgate.yaml")
        with open(config, "w") as f:
            f.write(f"modbus:\n  listen: 127.0.0.1:{self.port}\n{modbus_extra}")
            if metrics:
                f.write(f"metrics: {{listen: 127.0.0.1:{self.metrics_port}}}\n")
            f.write(f"""models: {MODELS}
buses:
  - name: absent
    protocol: copley-ascii
    tcp: {{host: 127.0.0.1, port: {free_port()}, baud: 115200}}
    timing: {{reply_timeout: 50ms, reconnect_min: 1s, reconnect_max: 5s}}
    nodes:
      - {{name: axis_1, address: 0, model: copley-amplifier, unit_id: 1}}
      - {{name: axis_2, address: 3, model: copley-amplifier, unit_id: 2}}
""")
        self.log = open(os.path.join(self.dir, "daemon.log"), "w")

        def limit():
            if nofile:
                resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))

        self.proc = subprocess.Popen([FIELDGATE, "--config", config], stdout=self.log,
                                     stderr=subprocess.STDOUT, preexec_fn=limit)
        for port in [self.port] + ([self.metrics_port] if metrics else []):
            deadline = time.time() + 60  # an ASan build on a loaded machine starts slowly
            while True:
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=1).close()
                    break
                except OSError:
                    if self.proc.poll() is not None or time.time() > deadline:
                        failures.append("daemon did not start listening")
                        self.stop()  # prints the daemon's log
                        sys.exit("daemon did not start listening")
                    time.sleep(0.05)

    def alive(self):
        return self.proc.poll() is None

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()
        # A sanitizer build (scripts/test --sanitize) reports into the daemon's log.
        log = open(os.path.join(self.dir, "daemon.log"), errors="replace").read()
        check("Sanitizer" not in log and "runtime error" not in log,
              "no sanitizer report in the daemon's log")
        if failures:
            print("--- daemon log ---\n" + log[-4000:])
        shutil.rmtree(self.dir, ignore_errors=True)


def adu(tid, unit, pdu):
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + bytes(pdu)


def read_pdu(address=0, count=1, function=3):
    return struct.pack(">BHH", function, address, count)


def connect(port, source=None, timeout=3):
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    s.settimeout(timeout)
    if source:
        s.bind((source, 0))
    s.connect(("127.0.0.1", port))
    return s


def recv_exact(s, n):
    data = b""
    while len(data) < n:
        chunk = s.recv(n - len(data))
        if not chunk:
            break
        data += chunk
    return data


def read_reply(s):
    """One response ADU as (tid, unit, pdu), or None if the connection closed or timed out."""
    try:
        header = recv_exact(s, 7)
        if len(header) < 7:
            return None
        tid, proto, length, unit = struct.unpack(">HHHB", header)
        pdu = recv_exact(s, length - 1)
        return (tid, unit, pdu) if len(pdu) == length - 1 else None
    except OSError:
        return None


def closed_unanswered(s, timeout=3):
    s.settimeout(timeout)
    try:
        return s.recv(100) == b""
    except ConnectionResetError:
        return True
    except OSError:
        return False


def served(port, tid=1, source=None):
    """A fresh connection gets a reply to one read (a value or an exception: both are served)."""
    try:
        s = connect(port, source)
        s.sendall(adu(tid, 1, read_pdu()))
        reply = read_reply(s)
        s.close()
        return reply is not None and reply[0] == tid and reply[2][0] in (0x03, 0x83)
    except OSError:
        return False


# --- Scenarios -----------------------------------------------------------------------------

def malformed_mbap(d):
    cases = {
        "protocol id 1": struct.pack(">HHHB", 1, 1, 6, 1) + read_pdu(),
        "length 0": struct.pack(">HHHB", 2, 0, 0, 1),
        "length 1 (unit id, no function)": struct.pack(">HHHB", 3, 0, 1, 1),
        "length 255 (beyond 254)": struct.pack(">HHHB", 4, 0, 255, 1),
        "length 0xFFFF": struct.pack(">HHHB", 5, 0, 0xFFFF, 1),
    }
    for name, frame in cases.items():
        s = connect(d.port)
        s.sendall(frame)
        check(closed_unanswered(s), f"malformed MBAP header ({name}): closed without a reply")
        s.close()
    # A length that promises more than is sent is a half request: the request timeout ends it.
    check(served(d.port), "a well-formed request is still served afterwards")


def every_function_code(d):
    s = connect(d.port)
    supported = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F, 0x10, 0x17, 0x2B}
    answered = illegal_function = 0
    for fc in range(256):
        s.sendall(adu(fc, 1, [fc, 0, 0, 0, 1]))
        reply = read_reply(s)
        if reply is None or reply[0] != fc:
            check(False, f"function 0x{fc:02X}: no reply (connection lost)")
            s = connect(d.port)
            continue
        answered += 1
        pdu = reply[2]
        if fc not in supported or fc in (0x00, 0x80):
            if pdu == bytes([fc | 0x80, 0x01]):
                illegal_function += 1
        check(pdu[0] in (fc, fc | 0x80), f"function 0x{fc:02X}: reply is for this function")
    check(answered == 256, f"all 256 function codes answered on one connection ({answered})")
    unsupported = 256 - len(supported)
    check(illegal_function == unsupported,
          f"unsupported function codes answer 0x01 ({illegal_function} of {unsupported})")
    s.close()


def bad_counts(d):
    s = connect(d.port)
    cases = [
        ("read holding count 0", read_pdu(0, 0, 3), 0x03),
        ("read holding count 126", read_pdu(0, 126, 3), 0x03),
        ("read coils count 2001", read_pdu(0, 2001, 1), 0x03),
        ("read input address+count past 0xFFFF", read_pdu(0xFFFF, 2, 4), 0x02),
        ("write registers byte count 3 for 2", bytes([0x10, 0, 0, 0, 2, 3, 0, 0, 0]), 0x03),
        # 124 registers cannot fit an ADU: the count alone is answered.
        ("write registers count 124", bytes([0x10, 0, 0, 0, 124, 248]), 0x03),
        ("write coils byte count short", bytes([0x0F, 0, 0, 0, 9, 1, 0xFF]), 0x03),
        ("write single coil value 0x1234", bytes([0x05, 0, 0, 0x12, 0x34]), 0x03),
        ("read request one byte short", bytes([0x03, 0, 0, 0]), 0x03),
        ("read request one byte long", bytes([0x03, 0, 0, 0, 1, 0]), 0x03),
        ("read/write 0x17 write count 0", bytes([0x17, 0, 0, 0, 1, 0, 0, 0, 0, 0]), 0x03),
        ("device identification code 5", bytes([0x2B, 0x0E, 5, 0]), 0x03),
        ("MEI type 0x0D", bytes([0x2B, 0x0D, 1, 0]), 0x01),
    ]
    for tid, (name, pdu, code) in enumerate(cases, start=1):
        s.sendall(adu(tid, 1, pdu))
        reply = read_reply(s)
        ok = reply is not None and reply[0] == tid and reply[2] == bytes([pdu[0] | 0x80, code])
        check(ok, f"{name}: exception 0x{code:02X} ({reply[2].hex() if reply else 'no reply'})")
    s.close()


def byte_by_byte(d):
    s = connect(d.port)
    frame = adu(7, 1, read_pdu(0, 2, 4))
    for b in frame:
        s.sendall(bytes([b]))
        time.sleep(0.005)
    reply = read_reply(s)
    check(reply is not None and reply[0] == 7, "a request sent one byte at a time is answered")
    # Two requests split at every possible point of one segment boundary.
    two = adu(8, 1, read_pdu()) + adu(9, 2, read_pdu())
    for cut in range(1, len(two)):
        s.sendall(two[:cut])
        time.sleep(0.002)
        s.sendall(two[cut:])
        r1, r2 = read_reply(s), read_reply(s)
        if not (r1 and r2 and r1[0] == 8 and r2[0] == 9 and r2[1] == 2):
            check(False, f"two requests cut at byte {cut}: both answered in order")
            return
    check(True, f"two requests cut at each of {len(two) - 1} points: both answered in order")
    s.close()


def pipelining(d):
    s = connect(d.port)
    n = 200
    s.sendall(b"".join(adu(i, 1 + i % 2, read_pdu(i % 10)) for i in range(n)))
    tids = []
    for _ in range(n):
        reply = read_reply(s)
        if reply is None:
            break
        tids.append(reply[0])
    check(tids == list(range(n)), f"{n} pipelined requests in one write: {len(tids)} replies in "
          "order")
    s.close()


def attacker(port, stop, kind):
    """Keeps misbehaving on fresh connections until stop is set; returns nothing."""
    while not stop.is_set():
        try:
            s = connect(port, timeout=0.5)
            if kind == "garbage":
                s.sendall(os.urandom(300))
            elif kind == "half":
                s.sendall(adu(1, 1, read_pdu())[:5])
            elif kind == "bad_count":
                for i in range(50):
                    s.sendall(adu(i, 1, read_pdu(0, 0)))
            time.sleep(0.01)
            s.close()
        except OSError:
            time.sleep(0.01)


def good_client_under_attack(d):
    stop = threading.Event()
    threads = [threading.Thread(target=attacker, args=(d.port, stop, k))
               for k in ("garbage", "half", "bad_count", "garbage")]
    for t in threads:
        t.start()
    s = connect(d.port)
    n = 2000
    good = 0
    for i in range(n):
        s.sendall(adu(i, 1, read_pdu(0, 2, 4)))
        reply = read_reply(s)
        if reply and reply[0] == i and reply[2][0] in (0x04, 0x84):
            good += 1
        elif reply is None:
            s = connect(d.port)
    stop.set()
    for t in threads:
        t.join()
    check(good == n, f"well-behaved client while 4 connections attack: {good}/{n} requests "
          "answered")
    check(d.alive(), "daemon still running")


def reconnecting_plc(d, expect_served):
    """max_clients stalled sockets (re-opened as soon as closed) while a PLC reconnects."""
    max_clients = 4
    stop = threading.Event()
    stalled = []
    evicted = [0]

    def hold():
        while not stop.is_set():
            alive = []
            for s in stalled:
                r, _, _ = select.select([s], [], [], 0)
                if r:
                    evicted[0] += 1
                    s.close()
                else:
                    alive.append(s)
            stalled[:] = alive
            while len(stalled) < max_clients and not stop.is_set():
                try:
                    s = connect(d.port)
                    s.sendall(adu(1, 1, read_pdu())[:3])  # half a header, then nothing
                    stalled.append(s)
                except OSError:
                    break
            time.sleep(0.01)

    holder = threading.Thread(target=hold)
    holder.start()
    time.sleep(0.5)
    attempts = 10
    ok = sum(1 for i in range(attempts) if (time.sleep(0.3) or served(d.port, tid=100 + i)))
    stop.set()
    holder.join()
    for s in stalled:
        s.close()
    print(f"     stalled sockets closed by the server meanwhile: {evicted[0]}")
    if expect_served:
        check(ok == attempts, f"reconnecting PLC served at {ok} of {attempts} attempts while "
              f"{max_clients} stalled sockets hold max_clients")
    else:
        check(ok == 0, f"control (when_full: refuse): the PLC is shut out ({ok} of {attempts} "
              "served), as before the fix")


def silent_churn(d):
    """Peers from 8 addresses connect and say nothing (about 450 connects/s in all), keeping a
    few connections each open, while a PLC polls (two FC4 reads every 50 ms) on one connection:
    every read is answered. With max_clients: 16, the default when_full and connect rates."""
    stop = threading.Event()
    connects = [0]

    def churn(source):
        held = []
        while not stop.is_set():
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.setblocking(False)
            try:
                s.bind((source, 0))
                s.connect_ex(("127.0.0.1", d.port))
                connects[0] += 1
            except OSError:
                s.close()
                time.sleep(0.01)
                continue
            held.append(s)
            if len(held) > 5:
                held.pop(0).close()
            time.sleep(0.015)  # about 60 connects/s per address, 450-500/s in all
        for s in held:
            s.close()

    threads = [threading.Thread(target=churn, args=(f"127.0.0.{i}",)) for i in range(2, 10)]
    for t in threads:
        t.start()
    time.sleep(0.3)
    plc = connect(d.port)
    polls, failed = 150, 0
    for i in range(polls):
        for j in range(2):
            tid = (2 * i + j) & 0xFFFF
            plc.sendall(adu(tid, 1, read_pdu(0, 2, 4)))
            reply = read_reply(plc)
            if not (reply and reply[0] == tid and reply[2][0] in (0x04, 0x84)):
                failed += 1
                plc.close()
                plc = connect(d.port)
        time.sleep(0.05)
    stop.set()
    for t in threads:
        t.join()
    print(f"     silent connects from 8 addresses meanwhile: {connects[0]}")
    check(failed == 0, f"polling PLC beside silent churn: {2 * polls - failed} of {2 * polls} "
          "reads answered")
    check(connects[0] > 2 * polls, "the churn outpaced the PLC's polls")
    check(d.alive(), "daemon still running")


def idle_timer(d):
    idle = connect(d.port)
    active = connect(d.port)
    t0 = time.time()
    closed = False
    while time.time() - t0 < 10:
        active.sendall(adu(1, 1, read_pdu()))
        if read_reply(active) is None:
            break
        r, _, _ = select.select([idle], [], [], 0.1)
        if r and idle.recv(10) == b"":
            closed = True
            break
    check(closed, "idle connection (no request) closed by idle_timeout")
    active.sendall(adu(2, 1, read_pdu()))
    check(read_reply(active) is not None, "an active connection stays open meanwhile")
    half = connect(d.port)
    half.sendall(adu(3, 1, read_pdu())[:9])
    check(closed_unanswered(half, timeout=10), "a half-sent request closed by request_timeout")


def allow_list(d):
    s = connect(d.port)
    s.sendall(adu(1, 1, read_pdu()))
    check(closed_unanswered(s), "a client outside the allow-list is closed unanswered")


def per_address(d):
    held = [connect(d.port, source="127.0.0.2") for _ in range(2)]
    for s in held:
        s.sendall(adu(1, 1, read_pdu()))
        read_reply(s)
    check(not served(d.port, source="127.0.0.2"),
          "a third connection from one address is refused (max_clients_per_address: 2)")
    check(served(d.port, source="127.0.0.1"), "another address is served meanwhile")
    for s in held:
        s.close()


def metrics_flood(d):
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = 1400
    if soft < want:
        if hard < want:
            check(False, f"this test needs {want} descriptors; hard limit is {hard}")
            return
        resource.setrlimit(resource.RLIMIT_NOFILE, (want, hard))
    stalled = []
    failed_connects = 0
    for _ in range(1100):
        try:
            s = socket.socket()
            s.setblocking(False)
            s.connect_ex(("127.0.0.1", d.metrics_port))
            stalled.append(s)
        except OSError:
            failed_connects += 1
    time.sleep(1)
    ok = sum(1 for i in range(10) if served(d.port, tid=i + 1))
    check(ok == 10, f"with 1100 stalled metrics connections (daemon limited to 1024 descriptors) "
          f"{ok} of 10 new Modbus connections served")
    # The metrics endpoint itself still answers once the stalled ones are gone.
    for s in stalled:
        s.close()
    time.sleep(0.5)
    m = connect(d.metrics_port)
    m.sendall(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n")
    body = b""
    while True:
        chunk = m.recv(65536)
        if not chunk:
            break
        body += chunk
    check(b"fieldgate_modbus_clients_evicted_total" in body, "metrics answer afterwards")
    check(d.alive(), "daemon still running")


def device_identification(d):
    s = connect(d.port)
    s.sendall(adu(1, 1, [0x2B, 0x0E, 0x01, 0x00]))
    reply = read_reply(s)
    ok = reply is not None and reply[2][:3] == bytes([0x2B, 0x0E, 0x01])
    objects = {}
    if ok:
        pdu = reply[2]
        pos = 7
        for _ in range(pdu[6]):
            oid, n = pdu[pos], pdu[pos + 1]
            objects[oid] = pdu[pos + 2:pos + 2 + n].decode()
            pos += 2 + n
    print(f"     objects: {objects}")
    check(objects.get(0) == "Copley Controls", "VendorName is the controller's vendor")
    check(objects.get(1) == "copley-amplifier", "ProductCode is the node's model")
    check(0x02 in objects, "MajorMinorRevision present")
    s.sendall(adu(2, 2, [0x2B, 0x0E, 0x04, 0x06]))
    reply = read_reply(s)
    check(reply is not None and b"axis_2" in reply[2], "individual access: unit 2 names its node")
    s.sendall(adu(3, 99, [0x2B, 0x0E, 0x01, 0x00]))
    reply = read_reply(s)
    check(reply is not None and reply[2] == bytes([0xAB, 0x0A]), "unknown unit: exception 0x0A")


SCENARIOS = {
    "malformed_mbap": ("", malformed_mbap),
    "every_function_code": ("", every_function_code),
    "bad_counts": ("", bad_counts),
    "byte_by_byte": ("", byte_by_byte),
    "pipelining": ("", pipelining),
    "good_client_under_attack": ("  request_timeout: 1s\n", good_client_under_attack),
    "reconnecting_plc": ("  max_clients: 4\n  request_timeout: 60s\n  idle_timeout: 60s\n",
                         lambda d: reconnecting_plc(d, True)),
    "reconnecting_plc_refuse_control": (
        "  max_clients: 4\n  when_full: refuse\n  request_timeout: 60s\n  idle_timeout: 60s\n",
        lambda d: reconnecting_plc(d, False)),
    "idle_timer": ("  idle_timeout: 2s\n  request_timeout: 2s\n", idle_timer),
    "silent_churn": ("  max_clients: 16\n", silent_churn),
    "allow_list": ("  allow: [10.0.0.0/8]\n", allow_list),
    "per_address": ("  max_clients_per_address: 2\n", per_address),
    "device_identification": ("", device_identification),
}

if SCENARIO == "metrics_flood":
    daemon = Daemon(metrics=True, nofile=1024)
    runner = metrics_flood
else:
    extra, runner = SCENARIOS[SCENARIO]
    daemon = Daemon(extra)
try:
    runner(daemon)
finally:
    daemon.stop()
if failures:
    print(f"{len(failures)} check(s) failed")
    sys.exit(1)
