#!/usr/bin/python3
"""A serial line between two PTYs at a given baud: bytes written on one side come out of the
other no sooner than a UART would shift them (bits per character / baud each), back to back.
What one write put on the line comes out in one piece, when its last character would have
arrived: released byte by byte, a relay not scheduled for longer than t3.5 (3.6 ms at 9600) in
the middle of a frame would split it, and the gateway would rightly drop the pieces, a gap that
a UART never makes.
Usage: rtu_wire_relay.py GATEWAY_LINK MASTER_LINK BAUD BITS_PER_CHARACTER
The gateway opens GATEWAY_LINK, the masters open MASTER_LINK. Runs until killed."""
import os, select, sys, threading, time, tty, collections

gateway_link, master_link, baud, bits = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
char_time = bits / baud


def make_pty(link):
    master, slave = os.openpty()  # the slave stays open: no hang-up when a client closes
    tty.setraw(slave)
    tmp = link + ".tmp"
    if os.path.lexists(tmp):
        os.remove(tmp)
    os.symlink(os.ttyname(slave), tmp)
    os.rename(tmp, link)
    return master, slave


def relay(src, dst):
    pending = collections.deque()  # (due, bytes)
    line_free = 0.0
    while True:
        now = time.monotonic()
        timeout = max(0.0, pending[0][0] - now) if pending else None
        readable, _, _ = select.select([src], [], [], timeout)
        now = time.monotonic()
        if readable:
            try:
                data = os.read(src, 4096)
            except OSError:
                data = b""
            if data:
                line_free = max(line_free, now) + len(data) * char_time
                pending.append((line_free, data))
        out = bytearray()
        while pending and pending[0][0] <= now:
            out += pending.popleft()[1]
        if out:
            os.write(dst, bytes(out))


gw_master, _gw_slave = make_pty(gateway_link)
m_master, _m_slave = make_pty(master_link)
threading.Thread(target=relay, args=(m_master, gw_master), daemon=True).start()
relay(gw_master, m_master)
