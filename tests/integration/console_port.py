#!/usr/bin/python3
"""The console's port (docs/console.md, The port): the command line's (--console-port) over the
environment's (FIELDGATE_CONSOLE_PORT) over the configuration's console: listen:, and held
across a reload; out of range on either, the daemon refuses to start. A daemon without buses,
its console answering at the port it logs.

Usage: console_port.py FIELDGATE MODELS_DIR
"""
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request

from process_helpers import check, failures, free_port, stop_processes, wait_for

FIELDGATE, MODELS = sys.argv[1], os.path.abspath(sys.argv[2])


def start(d, config, args=(), env_port=None):
    log = os.path.join(d, f"daemon-{time.monotonic_ns()}.log")
    env = dict(os.environ)
    env.pop("FIELDGATE_CONSOLE_PORT", None)
    if env_port is not None:
        env["FIELDGATE_CONSOLE_PORT"] = str(env_port)
    p = subprocess.Popen([FIELDGATE, "--config", config, *args], env=env,
                         stdout=open(log, "w"), stderr=subprocess.STDOUT)
    return p, log


def console_ports(log):
    return [int(p) for p in re.findall(r"console: http://127\.0\.0\.1:(\d+)/", open(log).read())]


def answers(port):
    try:
        return urllib.request.urlopen(f"http://127.0.0.1:{port}/api/plant", timeout=2).status == 200
    except OSError:
        return False


def main():
    d = tempfile.mkdtemp(prefix="fieldgate-console-port-")
    in_config, in_env, on_line = free_port(), free_port(), free_port()
    config = os.path.join(d, "gateway.yaml")
    with open(config, "w") as f:
        f.write(f"modbus:\n  listen: 127.0.0.1:{free_port()}\nmodels: {MODELS}\n"
                f"console:\n  listen: 127.0.0.1:{in_config}\nbuses: []\n")
    for name, args, env_port, want in (
            ("the configuration's port alone", (), None, in_config),
            ("the environment's over the configuration's", (), in_env, in_env),
            ("the command line's over the environment's", ("--console-port", str(on_line)),
             in_env, on_line)):
        p, log = start(d, config, args, env_port)
        try:
            got = wait_for(lambda: console_ports(log), 10)
            check(f"{name}: the console on {want}", got == [want] and answers(want),
                  f"logged {got}")
            if want != in_config:
                p.send_signal(signal.SIGHUP)
                again = wait_for(lambda: len(console_ports(log)) >= 2, 10)
                check(f"{name}: a reload keeps it", again and console_ports(log)[1] == want
                      and answers(want), open(log).read()[-600:])
        finally:
            stop_processes(p)
    for name, args, env_port in (("--console-port 0", ("--console-port", "0"), None),
                                 ("FIELDGATE_CONSOLE_PORT=70000", (), 70000)):
        p, log = start(d, config, args, env_port)
        try:
            p.wait(10)
        finally:
            stop_processes(p)
        check(f"{name}: refused", p.returncode != 0 and "not in range" in open(log).read(),
              open(log).read()[-300:])
    if failures:
        print(f"{len(failures)} check(s) failed: {', '.join(failures)}")
        return 1
    print("console port: every check passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
