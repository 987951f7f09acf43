#!/usr/bin/env python3
"""Compares the output folders of two runs of one case (for instance one process and several):
every file must be byte for byte the same, except

- summary.json: wall time, rate, threads, processes and their grid may differ; every other
  entry the same;
- energy.csv: time, elastic and dissipated energy the same text; the external work, the kinetic
  and the damping energy within one unit of their last printed digit (9 significant digits),
  and the balance error within 1e-12. Why: a distributed run sums the work, the damping and the
  imposed-velocity DOF's kinetic energy per process first, then over the processes, so those
  sums can differ from one process's by rounding (about 1e-16 relative per addition); the
  printed digits then differ by at most one unit in the last place, and the balance error
  (a small difference of those sums, relative to them) by 1e-15 on short runs and up to
  2e-13 over the coarse fatigue plate's 24,652 reports (docs/validation/distributed.md).

usage: compare_runs.py DIR_A DIR_B      exits non-zero with a message on the first difference
"""
import csv
import json
import math
import os
import sys

ROUNDED = {"external_work", "kinetic", "damping_dissipated"}
EXACT = {"time", "elastic", "damage_dissipated"}
VARYING = {"wall_s", "bar_updates_per_s", "threads", "processes", "process_grid"}


def fail(msg):
    sys.exit("compare_runs: " + msg)


def last_digit(x):
    """One unit in the ninth significant digit of x."""
    return 10.0 ** (math.floor(math.log10(abs(x))) - 8) if x != 0 else 0.0


def compare_energy(a, b):
    with open(a) as fa, open(b) as fb:
        ra, rb = list(csv.DictReader(fa)), list(csv.DictReader(fb))
    if len(ra) != len(rb):
        fail(f"energy.csv: {len(ra)} rows against {len(rb)}")
    for i, (x, y) in enumerate(zip(ra, rb)):
        if x.keys() != y.keys():
            fail("energy.csv: different columns")
        for k in x:
            if k in EXACT and x[k] != y[k]:
                fail(f"energy.csv row {i + 1} {k}: {x[k]} against {y[k]}")
            if k in ROUNDED:
                u, v = float(x[k]), float(y[k])
                if abs(u - v) > 1.01 * max(last_digit(u), last_digit(v)):
                    fail(f"energy.csv row {i + 1} {k}: {x[k]} against {y[k]}")
            if k == "balance_error" and abs(float(x[k]) - float(y[k])) > 1e-12:
                fail(f"energy.csv row {i + 1} balance_error: {x[k]} against {y[k]}")


def main():
    a, b = sys.argv[1], sys.argv[2]
    fa, fb = sorted(os.listdir(a)), sorted(os.listdir(b))
    fa = [f for f in fa if f != "checkpoint"]
    fb = [f for f in fb if f != "checkpoint"]
    if fa != fb:
        fail(f"different files: {sorted(set(fa) ^ set(fb))}")
    for name in fa:
        pa, pb = os.path.join(a, name), os.path.join(b, name)
        if name == "energy.csv":
            compare_energy(pa, pb)
        elif name == "summary.json":
            with open(pa) as x, open(pb) as y:
                sa, sb = json.load(x), json.load(y)
            for k in sa.keys() | sb.keys():
                if k == "max_balance_error" and k in sa and k in sb:
                    if abs(sa[k] - sb[k]) > 1e-12:
                        fail(f"summary.json {k}: {sa[k]} against {sb[k]}")
                elif k not in VARYING and sa.get(k) != sb.get(k):
                    fail(f"summary.json {k}: {sa.get(k)} against {sb.get(k)}")
        else:
            with open(pa, "rb") as x, open(pb, "rb") as y:
                if x.read() != y.read():
                    fail(f"{name} differs")
    print(f"compare_runs: {a} and {b} agree ({len(fa)} files)")


if __name__ == "__main__":
    main()
