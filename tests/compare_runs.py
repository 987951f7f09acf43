#!/usr/bin/env python3
"""Compares the output folders of two runs of one case (for instance one process and several):
every file must be byte for byte the same, energy.csv included, except summary.json, where the
wall time, the rate, the threads, the processes, their grid and the memory per module may differ (every other entry
the same). The checkpoint folder, if any, is not compared.

usage: compare_runs.py DIR_A DIR_B      exits non-zero with a message on the first difference
"""
import json
import os
import sys

VARYING = {"wall_s", "bar_updates_per_s", "threads", "processes", "process_grid",
           "bytes_per_module"}


def fail(msg):
    sys.exit("compare_runs: " + msg)


def first_difference(pa, pb):
    """The first differing line of two text files, for the message."""
    with open(pa, errors="replace") as x, open(pb, errors="replace") as y:
        for i, (u, v) in enumerate(zip(x, y)):
            if u != v:
                return f" (line {i + 1}: {u.strip()} against {v.strip()})"
    return ""


def main():
    a, b = sys.argv[1], sys.argv[2]
    fa, fb = sorted(os.listdir(a)), sorted(os.listdir(b))
    fa = [f for f in fa if f != "checkpoint"]
    fb = [f for f in fb if f != "checkpoint"]
    if fa != fb:
        fail(f"different files: {sorted(set(fa) ^ set(fb))}")
    for name in fa:
        pa, pb = os.path.join(a, name), os.path.join(b, name)
        if name == "summary.json":
            with open(pa) as x, open(pb) as y:
                sa, sb = json.load(x), json.load(y)
            for k in sa.keys() | sb.keys():
                if k not in VARYING and sa.get(k) != sb.get(k):
                    fail(f"summary.json {k}: {sa.get(k)} against {sb.get(k)}")
        else:
            with open(pa, "rb") as x, open(pb, "rb") as y:
                if x.read() != y.read():
                    more = first_difference(pa, pb) if name.endswith(".csv") else ""
                    fail(f"{name} differs{more}")
    print(f"compare_runs: {a} and {b} agree ({len(fa)} files)")


if __name__ == "__main__":
    main()
