#!/usr/bin/python3
"""Where the gateway's turn goes on a serial bus: from `perf script` output of the syscall
tracepoints of one gateway process, the time from the wake-up that brought a reply to the
read that took it, from that read to the next syscall (the gateway's own code: the reply's
parsing and bookkeeping, the next poll's choice and its request), from the reply's read to the
next request's write, and from the write's return to the wait for its reply (while the gateway
still runs, a PTY's receive work queued on its CPU waits for it). Only turns that end in a
write count (a reply followed by the next request); reads of the reply's earlier chunks are
left out.

  perf record -e raw_syscalls:sys_enter,raw_syscalls:sys_exit -p GATEWAY_PID -o F -- sleep 3
  perf script -i F -F time,event,trace | bench/serial/turn_breakdown.py

Run it beside bench/serial/run's setup (a simulator with --emulate-wire and a gateway polling
as fast as it may); the bare exchange spends well under a microsecond between its read and
its write (its own mean_gap_us).
"""
import re
import sys

READ, WRITE, EPOLL_WAIT = 0, 1, 232
event = re.compile(r"\s*([\d.]+):\s+raw_syscalls:sys_(enter|exit): NR (\d+)(?: = (-?\d+))?")
events = []
for line in sys.stdin:
    m = event.match(line)
    if m:
        result = None if m.group(4) is None else int(m.group(4))
        events.append((float(m.group(1)) * 1e6, m.group(2), int(m.group(3)), result))

wake, code, turn, tail = [], [], [], []
for i, (t, kind, nr, result) in enumerate(events):
    if kind != "exit" or nr != READ or not result or result <= 0 or i + 1 >= len(events):
        continue
    # The reply's last read is followed by the next request's write before the loop waits again.
    write = None  # index of the write's enter
    for k in range(i + 1, min(i + 16, len(events))):
        if events[k][1] == "enter" and events[k][2] == EPOLL_WAIT:
            break
        if events[k][1] == "enter" and events[k][2] == WRITE:
            write = k
            break
    if write is None:
        continue
    turn.append(events[write][0] - t)
    # After the write's return, until the loop sleeps: the wait that lasts (the reply's
    # turnaround), not a poll of the reactor that returns at once. A capture that ends first
    # leaves the turn out of this figure.
    after = events[write + 1:write + 40]
    if after and after[0][1] == "exit" and after[0][2] == WRITE:
        for j, e in enumerate(after):
            if e[1] != "enter" or e[2] != EPOLL_WAIT:
                continue
            back = next((x for x in after[j + 1:] if x[1] == "exit" and x[2] == EPOLL_WAIT), None)
            if back is not None and back[0] - e[0] > 200:
                tail.append(e[0] - after[0][0])
                break
    code.append(events[i + 1][0] - t)
    before = events[i - 2] if i >= 2 else None  # exit of what preceded the read's enter
    if before and before[1] == "exit" and before[2] == EPOLL_WAIT:
        wake.append(events[i - 1][0] - before[0])


def summary(name, values):
    if not values:
        print(f"{name}: none")
        return
    values = sorted(values)
    n = len(values)
    p50, p90 = values[n // 2], values[int(0.9 * (n - 1))]
    print(f"{name}: {n} turns, p50 {p50:.0f} us, p90 {p90:.0f} us, mean {sum(values) / n:.1f} us")


summary("epoll_wait's return -> the reply's read", wake)
summary("the reply's read -> the next syscall (gateway code)", code)
summary("the reply's read -> the next request's write", turn)
summary("the write's return -> the wait for its reply", tail)
