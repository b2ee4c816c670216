"""Helpers of the Python integration tests that start real processes (sparkplug_host.py,
console_browser.py)."""
import os
import shutil
import socket
import subprocess
import time

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"


def free_port():
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(pred, timeout=15.0, step=0.05):
    """pred's first true result within `timeout` seconds, else its last result."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        r = pred()
        if r:
            return r
        time.sleep(step)
    return pred()


def stop_processes(*processes):
    """Terminates each process still running; one that does not exit within 10 s is killed."""
    for p in processes:
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()


class Broker:
    """A Mosquitto broker of the test's own on a loopback port (anonymous clients, no
    persistence, unless `conf` says otherwise), its log in D/mosquitto.log."""

    def __init__(self, d, port, conf=None):
        self.port = port
        self.conf = os.path.join(d, "mosquitto.conf")
        with open(self.conf, "w") as f:
            f.write(conf or f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
        self.log = open(os.path.join(d, "mosquitto.log"), "a")
        self.proc = None

    def start(self):
        self.proc = subprocess.Popen([MOSQUITTO, "-c", self.conf], stdout=self.log, stderr=self.log)

        def up():
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return True
            except OSError:
                return False
        assert wait_for(up, 10), "mosquitto did not start"

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(10)


# The checks that failed; a test exits non-zero if any did.
failures = []


def check(name, cond, detail=""):
    """Prints the check's outcome; a failed one is recorded in failures."""
    print(("ok: " if cond else "FAIL: ") + name + ("" if cond else f" ({detail})"), flush=True)
    if not cond:
        failures.append(name)
    return cond


# The simulators behind the demo plant's serial buses (config/demo.yaml), started as
# scripts/demo starts them, by the name of their link (the bus's device): the program under the
# build's sim/ and its arguments.
DEMO_SIMULATORS = {
    "copley0": ("copley/fieldgate-sim-copley", ["--nodes", "0,3,5", "--baud", "115200"]),
    "ims0": ("ims/fieldgate-sim-ims", ["--axes", "A,B,C", "--baud", "9600"]),
    "centent0": ("centent/fieldgate-sim-centent",
                 ["--units", "0,1,2", "--baud", "9600", "--hop-delay-us", "500", "--power-up"]),
    "techno-c142": ("techno/fieldgate-sim-techno", ["--variant", "c142", "--baud", "19200"]),
    "techno-it116g": ("techno/fieldgate-sim-techno", ["--variant", "it116g", "--baud", "9600"]),
    "whedco0": ("whedco/fieldgate-sim-whedco", ["--units", "4", "--axes", "XY", "--baud", "38400"]),
}
