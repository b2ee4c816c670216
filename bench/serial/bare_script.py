#!/usr/bin/python3
"""The bare exchange's script from a gateway run, the check that it was replayed faithfully, and
the two rates over the same exchanges.

  bare_script.py make WIRE_LOG SCRIPT   writes SCRIPT for bare_exchange from the simulator's
                                        --wire-log of a gateway run; prints "cycle P start-up A
                                        silent K" (K: exchanges of the cycle without a reply)
  bare_script.py check SCRIPT WIRE_LOG  compares the simulator's --wire-log of a bare exchange
                                        run with SCRIPT; prints "replayed N differ D" and, when D
                                        is not 0, the first difference (bytes back compared per
                                        run of silent requests and the one that ends it)
  bare_script.py compare GATEWAY_LOG BARE_LOG [WARMUP]
                                        exchanges/s of the gateway and of the bare exchange over
                                        the same exchanges: from the gateway's first request
                                        WARMUP (default 1) s into its run to the last request
                                        both logs hold, each on the simulator's clock; prints
                                        "gw_per_s G bare_per_s B exchanges N gw_s S bare_s T"

The script repeats the gateway's own traffic: every request it wrote, in its order, with the
number of bytes the simulator sent back for it (echo plus reply). The gateway's poll cycle is the
shortest period P with which the end of its log repeats (at least two whole cycles observed);
the start-up is everything before the first of those cycles, retries and time-outs included.
bare_exchange runs the start-up once (which also puts the simulated devices into the state the
cycle expects: Centent's selected unit, Whedco's cleared faults), then the cycle over and over.
When the log ends in no such cycle (a long cycle at 9600 in a short run), the whole log is the
start-up ("cycle 0") and the bare exchange stops at its end.

Either way the bare exchange's n-th request is the gateway's n-th for as far as the gateway's log
goes, so `compare` times the very same exchanges in both logs: a cycle mixes exchanges of a few
ms and of 190 ms (Centent at 9600), and two time windows would weigh them differently; a stall
of the gateway's (a time-out, a retry) inside the window counts against it.

Script lines: "P|L BYTES HEX" (P: start-up, L: cycle; HEX the request's bytes).
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
    """(first byte in ns, request escaped, echoed bytes, reply bytes) per executed request."""
    rows = []
    with open(path, encoding="latin-1") as f:
        for line in f:
            if not line.endswith("\n"):
                break  # the simulator was stopped while writing it
            parts = line[:-1].split(" ", 6)
            if len(parts) < 7:
                continue
            rows.append((int(parts[0]), parts[6], int(parts[3]), int(parts[4])))
    return rows


def periodic_start(seq, p):
    """Start of the longest suffix of seq with period p."""
    i = len(seq) - p - 1
    while i >= 0 and seq[i] == seq[i + p]:
        i -= 1
    return i + 1


def make(log, out):
    # The last request may have been cut short by the end of the run.
    seq = [row[1:] for row in read_log(log)[:-1]]
    best = None
    for p in range(1, len(seq) // 2 + 1):
        a = periodic_start(seq, p)
        if len(seq) - a >= 2 * p and (best is None or a < best[1]):
            best = (p, a)
    if not seq:
        raise SystemExit(f"no exchanges in {log}")
    p, a = best if best is not None else (0, len(seq))
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


def compare(gateway_log, bare_log, warmup):
    g = [row[0] for row in read_log(gateway_log)]
    b = [row[0] for row in read_log(bare_log)]
    if not g or not b:
        raise SystemExit("no exchanges to compare")
    t0 = g[0] + warmup * 1e9
    first = next((i for i, t in enumerate(g) if t >= t0), len(g))
    # The gateway's last request is not in the script (make leaves it out).
    last = min(len(g) - 1, len(b)) - 1
    if last - first < 10:
        raise SystemExit(f"too few exchanges after the {warmup:g} s warm-up in both logs "
                         f"({max(0, last - first)})")
    n = last - first
    gs = (g[last] - g[first]) / 1e9
    bs = (b[last] - b[first]) / 1e9
    print(f"gw_per_s {n / gs:.1f} bare_per_s {n / bs:.1f} exchanges {n} gw_s {gs:.3f} "
          f"bare_s {bs:.3f}")


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
    for n, (_, request, echo, reply) in enumerate(rows):
        if k == len(items):  # a script without a cycle ends: nothing more was to be sent
            differ += 1
            first = first or f"exchange {n}: {unescape(request)!r} after the end of the script"
            continue
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
        k = k + 1 if k + 1 < len(items) or prologue == len(items) else prologue
    print(f"replayed {len(rows)} differ {differ}" + (f" first {first}" if first else ""))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "make":
        make(sys.argv[2], sys.argv[3])
    elif len(sys.argv) in (4, 5) and sys.argv[1] == "compare":
        compare(sys.argv[2], sys.argv[3], float(sys.argv[4]) if len(sys.argv) == 5 else 1.0)
    elif len(sys.argv) == 4 and sys.argv[1] == "check":
        check(sys.argv[2], sys.argv[3])
    else:
        raise SystemExit(__doc__)
