"""Helpers of the Python integration tests that start real processes (sparkplug_host.py,
console_browser.py)."""
import socket
import subprocess
import time


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
