#!/usr/bin/python3
"""Writes a gateway configuration with N Copley nodes spread over buses of up to 125 nodes and
over several Modbus listeners (each its own unit-ID space), and prints the simulator node list
of each bus: half the nodes (even addresses) present, half absent (probed by the gateway).

  gen_config.py NODES DIR MODELS_DIR [--listeners L] [--all-present]
"""
import argparse
import math
import os

p = argparse.ArgumentParser()
p.add_argument("nodes", type=int)
p.add_argument("dir")
p.add_argument("models")
p.add_argument("--listeners", type=int, default=0, help="0: one per 200 nodes, at least 2")
p.add_argument("--all-present", action="store_true")
a = p.parse_args()

per_bus = 125
buses = math.ceil(a.nodes / per_bus)
listeners = a.listeners or max(2, math.ceil(a.nodes / 200))
units = math.ceil(a.nodes / listeners)
assert units <= 247, "too few listeners for the unit-ID space"
names = ["default"] + [f"line{i}" for i in range(1, listeners)]
out = ["modbus: {listen: 127.0.0.1:0, max_clients: 64}",
       "metrics: {listen: 127.0.0.1:0}",
       f"models: {a.models}",
       "listeners:"]
out += [f"  - {{name: {n}, listen: 127.0.0.1:0}}" for n in names[1:]]
out.append("buses:")
k = 0
for b in range(buses):
    count = min(per_bus, a.nodes - k)
    link = os.path.join(a.dir, f"copley{b}")
    present = [str(x) for x in range(1, count) if a.all_present or x % 2 == 0]
    print(f"{link} {','.join(present) if present else '0'}")
    out += [f"  - name: copley{b}",
            "    protocol: copley-ascii",
            f"    serial: {{device: {link}, baud: 115200}}",
            "    timing: {reply_timeout: 150ms, probe_interval: 5s}",
            "    nodes:"]
    for x in range(count):
        out.append(f"      - {{name: n{k}, address: {x}, model: copley-amplifier, "
                   f"unit_id: {k // listeners + 1}, listener: {names[k % listeners]}}}")
        k += 1
with open(os.path.join(a.dir, "gw.yaml"), "w") as f:
    f.write("\n".join(out) + "\n")
