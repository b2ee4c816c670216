#!/usr/bin/python3
"""What tools/axis.py's cycle leaves out on a CiA 402 profile axis, through its own handshake:
- a stop during a home that moves: Stopping, done only once the axis stands, short of the
  reference, then a new home completes;
- a device fault injected by the caller's command (the simulator's control line) on an enabled
  axis: ErrorStop with the drive's error code as error ID, a move refused, reset, power on.

  axis_cia402_checks.py AXIS_PY PORT UNIT CODE -- FAULT-COMMAND...
The node's homing method must be one that moves (a switch search), set beforehand.
"""
import argparse
import importlib.util
import subprocess
import sys
import time

from pymodbus.client import ModbusTcpClient

ERR_ERROR_STOP = 0xFFEF  # docs/axis-profile.md: anything but reset or power off in ErrorStop


def wait_until(ax, what, cond, timeout):
    deadline = time.monotonic() + timeout
    while True:
        p = ax.page()
        if cond(p):
            return p
        ax.check(what + " in time", time.monotonic() < deadline, str(p))
        time.sleep(0.02)


def stop_during_home(axis, ax, timeout):
    ax.command("home", timeout=timeout)  # from wherever the cycle left the axis
    # A gentle deceleration (the drive's profile deceleration, which its halt uses): the stop
    # takes seconds, so a 'done' before the axis stands cannot go unnoticed.
    r = ax.c.write_registers(axis.HR_DECEL, axis.words(2000), slave=ax.unit)
    ax.check("deceleration written", not r.isError(), str(r))
    ax.set_setpoints(target=ax.page()["position"] + 20000)
    ax.command("move_absolute", timeout=timeout)
    r = ax.send("home")
    ax.check("home taken", not r.isError(), str(r))
    p = wait_until(ax, "home: the axis moves", lambda q: q["moving"], timeout)
    ax.check("home: Homing while it moves", p["state"] == "Homing", p["state"])
    seen, p = ax.command("stop", timeout=timeout)
    ax.check("stop of a home: Stopping while busy", seen <= {"Stopping"}, str(seen))
    ax.check("stop of a home: done means stopped", not p["moving"], str(p))
    time.sleep(0.3)
    q = ax.page()
    ax.check("stop of a home: the axis stands", abs(q["position"] - p["position"]) <= 2 and
             q["state"] == "Standstill", "%d -> %d, %s" % (p["position"], q["position"],
                                                           q["state"]))
    ax.check("stop of a home: short of the reference", q["position"] != 0, str(q))
    ax.command("home", timeout=timeout)
    p = ax.wait_state({"Standstill"})
    ax.check("home after the stop: at the reference (home offset 0)", p["position"] == 0, str(p))


def fault(axis, ax, code, fault_command, timeout):
    if ax.page()["state"] != "Standstill":
        ax.command("power_on")
    p = ax.wait_state({"Standstill"})
    ax.check("before the fault: no error", not p["error"] and p["error_id"] == 0, str(p))
    subprocess.run(fault_command, check=True)
    p = ax.wait_state({"ErrorStop"})
    ax.check("fault: error bit", p["error"], str(p))
    ax.check("fault: not enabled", not p["enabled"], str(p))
    p = wait_until(ax, "error ID becomes 0x%04x" % code, lambda q: q["error_id"] == code, timeout)
    ax.set_setpoints(target=p["position"] + 1000)
    _, q = ax.command("move_absolute", expect=axis.ERROR)
    ax.check("ErrorStop refuses a move (0x%04x)" % ERR_ERROR_STOP,
             q["cmd_error"] == ERR_ERROR_STOP, "0x%04x" % q["cmd_error"])
    ax.check("ErrorStop stays", q["state"] == "ErrorStop", q["state"])
    ax.command("reset")
    p = ax.wait_state({"Disabled", "Standstill"})
    ax.check("reset: error bit clear", not p["error"], str(p))
    ax.check("reset: error ID 0", p["error_id"] == 0, str(p))
    ax.command("power_on")
    p = ax.wait_state({"Standstill"})
    ax.check("power on after the reset: enabled", p["enabled"], str(p))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("axis_py")
    ap.add_argument("port", type=int)
    ap.add_argument("unit", type=int)
    ap.add_argument("code", type=lambda s: int(s, 0), help="the error code the fault carries")
    ap.add_argument("fault_command", nargs="+")
    ap.add_argument("--timeout", type=float, default=30.0, help="seconds per command")
    a = ap.parse_args()
    sys.dont_write_bytecode = True  # nothing written next to tools/axis.py
    spec = importlib.util.spec_from_file_location("axis", a.axis_py)
    axis = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(axis)

    client = ModbusTcpClient("127.0.0.1", port=a.port, timeout=5)
    if not client.connect():
        print("cannot connect to 127.0.0.1:%d" % a.port)
        return 2
    ax = axis.Axis(client, a.unit, argparse.Namespace(verbose=True, timeout=a.timeout))
    try:
        ax.seq = ax.page()["seq"]
        stop_during_home(axis, ax, a.timeout)
        fault(axis, ax, a.code, a.fault_command, a.timeout)
        ax.log("all %d checks passed" % ax.checks)
        return 0
    except axis.Failed as e:
        ax.log("FAIL: %s" % e)
        return 1
    finally:
        client.close()


if __name__ == "__main__":
    sys.exit(main())
