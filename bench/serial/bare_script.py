#!/usr/bin/python3
"""The bare exchange's script from a gateway run, and the check that it was replayed faithfully.

  bare_script.py make WIRE_LOG SCRIPT   writes SCRIPT for bare_exchange from the simulator's
                                        --wire-log of a gateway run; prints "cycle P start-up A
                                        silent K" (K: exchanges of the cycle without a reply)
  bare_script.py rate SCRIPT WIRE_LOG [WARMUP]
                                        exchanges/s in WIRE_LOG (the gateway's or the bare
                                        exchange's) over whole poll cycles of SCRIPT, from the
                                        first cycle start WARMUP (default 1) s after the first
                                        request to the last one, on the simulator's clock;
                                        prints "per_s R cycles C seconds S"
  bare_script.py check SCRIPT WIRE_LOG  compares the simulator's --wire-log of a bare exchange
                                        run with SCRIPT; prints "replayed N differ D" and, when D
                                        is not 0, the first difference (bytes back compared per
                                        run of silent requests and the one that ends it)

The script repeats the gateway's own traffic: every request it wrote, in its order, with the
number of bytes the simulator sent back for it (echo plus reply). The gateway's poll cycle is the
shortest period P with which the end of its log repeats (at least two whole cycles observed);
the start-up is everything before the first of those cycles. bare_exchange runs the start-up
once, so the simulated devices are in the state the cycle expects (Centent's selected unit,
Whedco's cleared faults), then the cycle over and over. A log that does not end in a repeating
cycle has no faithful replay: `make` fails and says so.

Script lines: "P|L BYTES HEX" (P: start-up, L: cycle; HEX the request's bytes).

Rates over whole cycles, not over a time window: a cycle mixes long and short exchanges (at 9600
Centent's status query takes about 190 ms and its selections 4 ms), and a window that cuts the
cycles differently for the gateway and the bare exchange would weigh them differently. Both
logs follow the script (the gateway's by construction, the bare exchange's as `check` proves),
so a cycle starts at every exchange number start-up + k x cycle in both.
"""
import sys


def unescape(text):
    """Inverse of the simulator's escape_bytes: \\r, \\n, \\\\, \\xHH; the rest verbatim."""
    out = bytearray()
    i = 0
    while i < len(text):
        c = text[i]
        if c != "\\" or i + 1 == len(text):
            out += c.encode("latin-1")
            i += 1
            continue
        n = text[i + 1]
        if n == "r":
            out += b"\r"
            i += 2
        elif n == "n":
            out += b"\n"
            i += 2
        elif n == "\\":
            out += b"\\"
            i += 2
        elif n == "x":
            out.append(int(text[i + 2:i + 4], 16))
            i += 4
        else:
            raise ValueError(f"unknown escape in {text!r}")
    return bytes(out)


def read_log(path):
    """(request escaped, echoed bytes, reply bytes) per executed request."""
    rows = []
    with open(path, encoding="latin-1") as f:
        for line in f:
            if not line.endswith("\n"):
                break  # the simulator was stopped while writing it
            parts = line[:-1].split(" ", 6)
            if len(parts) < 7:
                continue
            rows.append((parts[6], int(parts[3]), int(parts[4])))
    return rows


def periodic_start(seq, p):
    """Start of the longest suffix of seq with period p."""
    i = len(seq) - p - 1
    while i >= 0 and seq[i] == seq[i + p]:
        i -= 1
    return i + 1


def make(log, out):
    # The last request may have been cut short by the end of the run.
    seq = read_log(log)[:-1]
    best = None
    for p in range(1, len(seq) // 2 + 1):
        a = periodic_start(seq, p)
        if len(seq) - a >= 2 * p and (best is None or a < best[1]):
            best = (p, a)
    if best is None:
        raise SystemExit(f"no repeating poll cycle in {log} ({len(seq)} exchanges): the gateway's "
                         "traffic cannot be replayed faithfully; a longer run may show one")
    p, a = best
    with open(out, "w") as f:
        f.write(f"# bare_exchange script from {log}: start-up {a}, cycle {p}\n")
        for i, (request, echo, reply) in enumerate(seq[:a + p]):
            f.write(f"{'P' if i < a else 'L'} {echo + reply} {unescape(request).hex()}\n")
    silent = sum(1 for _, echo, reply in seq[a:a + p] if echo + reply == 0)
    print(f"cycle {p} start-up {a} silent {silent}")


def read_script(script):
    """([(request bytes, bytes back)], start-up length)"""
    items = []
    prologue = 0
    with open(script) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            kind, expect, request = line.split()
            items.append((bytes.fromhex(request), int(expect)))
            if kind == "P":
                prologue = len(items)
    return items, prologue


def rate(script, log, warmup):
    items, prologue = read_script(script)
    cycle = len(items) - prologue
    starts = []
    with open(log, encoding="latin-1") as f:
        for line in f:
            parts = line.split(" ", 1)
            if line.endswith("\n") and len(parts) == 2:
                starts.append(int(parts[0]))
    if not starts:
        raise SystemExit(f"no exchanges in {log}")
    t0 = starts[0] + warmup * 1e9
    cycle_starts = [starts[i] for i in range(prologue, len(starts), cycle) if starts[i] >= t0]
    if len(cycle_starts) < 2:
        raise SystemExit(f"fewer than two starts of the {cycle}-exchange cycle after the "
                         f"{warmup:g} s warm-up in {log}: run longer")
    cycles = len(cycle_starts) - 1
    seconds = (cycle_starts[-1] - cycle_starts[0]) / 1e9
    print(f"per_s {cycles * cycle / seconds:.1f} cycles {cycles} seconds {seconds:.3f}")


def check(script, log):
    items, prologue = read_script(script)
    rows = read_log(log)
    # Requests that expect nothing back go out back to back with the next one, and the simulator
    # may read them in one go and log their echo against the first: the bytes back are compared
    # per group of such requests and the one that ends it (the host reads them as one).
    # The last request may have had no time to be answered: its log line is written when the
    # simulator executes it, so it still counts.
    differ = 0
    first = None
    k = 0
    want_group = got_group = 0
    for n, (request, echo, reply) in enumerate(rows):
        want_request, want_back = items[k]
        want_group += want_back
        got_group += echo + reply
        ends_group = want_back > 0 or n + 1 == len(rows)
        if unescape(request) != want_request or (ends_group and got_group != want_group):
            differ += 1
            if first is None:
                first = (f"exchange {n}: sent {want_request!r} expecting {want_back} bytes "
                         f"({want_group} with the silent ones before), the simulator logged "
                         f"{unescape(request)!r} answered with {echo}+{reply} ({got_group})")
        if ends_group:
            want_group = got_group = 0
        k = k + 1 if k + 1 < len(items) else prologue
    print(f"replayed {len(rows)} differ {differ}" + (f" first {first}" if first else ""))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "make":
        make(sys.argv[2], sys.argv[3])
    elif len(sys.argv) in (4, 5) and sys.argv[1] == "rate":
        rate(sys.argv[2], sys.argv[3], float(sys.argv[4]) if len(sys.argv) == 5 else 1.0)
    elif len(sys.argv) == 4 and sys.argv[1] == "check":
        check(sys.argv[2], sys.argv[3])
    else:
        raise SystemExit(__doc__)
