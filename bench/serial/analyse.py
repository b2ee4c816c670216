#!/usr/bin/python3
"""Serial chain efficiency from a simulator's wire log (--wire-log): achieved transactions/s
against the ideal computed from the simulator's own byte counts, per transaction
(request + echo + reply bytes) x bits per character / baud + device delay (turnaround plus the
device's own latency). The first WARMUP seconds are left out.

  analyse.py WIRE_LOG BAUD [--bits 10] [--warmup 1.0]

An echo (IMS, Whedco, Centent) travels on the other wire pair while the request is still
arriving, so counting it after the request (the formula above) overstates the ideal time and can
give ratios above 1. The second ideal overlaps it: request + reply bytes, plus one character
for the echo's last byte.

Prints: transactions, achieved/s, ideal/s and ratio (echo counted in series), ideal/s and ratio
(echo overlapped), and the mean gap the gateway left between the end of a reply and the next
request (its guard times, pacing and scheduling).
"""
import argparse

p = argparse.ArgumentParser()
p.add_argument("log")
p.add_argument("baud", type=float)
p.add_argument("--bits", type=float, default=10)
p.add_argument("--warmup", type=float, default=1.0)
a = p.parse_args()

rows = []
with open(a.log) as f:
    for line in f:
        parts = line.split(" ", 6)
        if len(parts) < 6:
            continue
        started, arrived, req, echo, reply, delay = (int(x) for x in parts[:6])
        rows.append((started, arrived, req, echo, reply, delay))
if not rows:
    raise SystemExit("no transactions in " + a.log)
t0 = rows[0][0] + a.warmup * 1e9
rows = [r for r in rows if r[0] >= t0]
if len(rows) < 3:
    raise SystemExit(f"too few transactions after the warm-up ({len(rows)})")
char_ns = a.bits / a.baud * 1e9
ideal_ns = 0.0
overlap_ns = 0.0
gaps = []
for r, nxt in zip(rows, rows[1:]):
    started, arrived, req, echo, reply, delay = r
    ideal_ns += (req + echo + reply) * char_ns + delay * 1000
    overlap_ns += (req + (1 if echo else 0) + reply) * char_ns + delay * 1000
    reply_end = arrived + delay * 1000 + reply * char_ns
    gaps.append(max(0.0, nxt[0] - reply_end))
n = len(rows) - 1
window_ns = rows[-1][0] - rows[0][0]
achieved = n / (window_ns / 1e9)
ideal = n / (ideal_ns / 1e9)
overlap = n / (overlap_ns / 1e9)
print(f"{n} {achieved:.1f} {ideal:.1f} {achieved / ideal:.3f} {overlap:.1f} "
      f"{achieved / overlap:.3f} {sum(gaps) / len(gaps) / 1000:.0f}")
