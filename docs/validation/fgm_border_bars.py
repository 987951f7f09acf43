#!/usr/bin/env python3
"""Bars broken near the pulled borders of the FGM plate, per run of one or more ensembles.

usage: fgm_border_bars.py ENSEMBLE_DIR [ENSEMBLE_DIR ...]

For every case folder and run_NN of each ensemble, reads events.csv and counts the bars broken
during the run (the pre-crack left out): all of them, and those whose centre lies within one
and within 1, 2, 5 and 10 modules of the top or bottom border (z < n L or z > H - n L). Prints one
markdown table per ensemble with the median and range over the runs. Standard library only.
"""
import csv
import pathlib
import statistics
import sys
import tomllib


BANDS = (1, 2, 5, 10) # modules from a pulled border


def counts(run):
    lattice = tomllib.loads((run / "case.resolved.toml").read_text())["lattice"]
    L = lattice["L"]
    H = lattice["modules"][2] * L
    tol = 1e-9 * L
    z = [float(r["z"]) for r in csv.DictReader(open(run / "events.csv")) if r["event"] == "broken"]
    near = lambda n: sum(1 for v in z if v < n * L + tol or v > H - n * L - tol)
    return [len(z)] + [near(n) for n in BANDS]


def cell(values):
    return f"{statistics.median(values):g} ({min(values)} to {max(values)})"


for ensemble in map(pathlib.Path, sys.argv[1:]):
    print(f"{ensemble}\n")
    print("| case | runs | broken bars | " +
          " | ".join(f"within {n} module{'s' if n > 1 else ''} of a pulled border" for n in BANDS) + " |")
    print("|---|---|---|" + "---|" * len(BANDS))
    for case in sorted(p for p in ensemble.iterdir() if p.is_dir()):
        runs = sorted(p for p in case.glob("run_*") if p.is_dir())
        c = [counts(r) for r in runs]
        print(f"| {case.name} | {len(runs)} | " + " | ".join(cell([x[i] for x in c]) for i in range(1 + len(BANDS))) + " |")
    print()
