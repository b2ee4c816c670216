#!/usr/bin/python3
"""Run with the fieldgate unit's sandbox (systemd-run -p ... copies it): tries what the service
must be able to do and what it must not, and prints one line per attempt:
"allowed NAME" / "refused NAME: error" / "absent NAME: error". Python stdlib only."""
import errno
import os
import socket


def attempt(name, action):
    try:
        action()
        print(f"allowed {name}", flush=True)
    except OSError as e:
        kind = "absent" if e.errno in (errno.ENXIO, errno.ENODEV, errno.ENOENT) else "refused"
        print(f"{kind} {name}: {errno.errorcode.get(e.errno, e.errno)}", flush=True)


def open_rw(path):
    def action():
        os.close(os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK))
    return action


def can_socket():
    s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    s.bind(("vcan0",))
    s.close()


def tcp_listen(port):
    def action():
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("0.0.0.0", port))
        s.listen()
        s.close()
    return action


def packet_socket():
    socket.socket(socket.AF_PACKET, socket.SOCK_RAW).close()


def write_config_dir():
    with open("/etc/fieldgate/probe", "w") as f:
        f.write("x")


def chroot():
    os.chroot("/")


def setuid_root():
    os.setuid(0)


attempt("serial /dev/ttyS3 (dialout)", open_rw("/dev/ttyS3"))
attempt("ttyUSB node (usbserial not loaded)", open_rw("/dev/ttyUSB7"))
attempt("ttyACM node (cdc_acm not loaded)", open_rw("/dev/ttyACM7"))
attempt("CAN raw socket on vcan0", can_socket)
attempt("TCP listen on port 503 (privileged)", tcp_listen(503))
attempt("block device /dev/vda", open_rw("/dev/vda"))
attempt("AF_PACKET socket", packet_socket)
attempt("write to /etc/fieldgate", write_config_dir)
attempt("chroot", chroot)
attempt("setuid(0)", setuid_root)
