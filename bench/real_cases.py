#!/usr/bin/python3
"""Real cases beside `ldem bench` on the same lattice: bar updates per second of each case's
time-step loop (its summary's rate, without snapshots, plots or end checkpoint, energy rows
only at its start and end) over the bench's (a uniform elastic lattice of the same modules,
stepped as long), in alternating rounds; medians of the per-round ratios.

    PYTHONPATH=build/release/python /usr/bin/python3 bench/real_cases.py [ROUNDS=3]

Environment: LDEM (default build/release/ldem), THREADS (default 2); LAMMPS_RUN, the peer
benchmark's run_lammps.sh (bench/README.md, "The peer"): when set, LAMMPS also runs each lattice
(elastic bonds: it has no softening law) for as many steps, MPI ranks as many as THREADS, and
the table gains its rate and the case's ratio to it.
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import ldem

ROOT = Path(__file__).resolve().parent.parent
LDEM = os.environ.get("LDEM", str(ROOT / "build" / "release" / "ldem"))
THREADS = os.environ.get("THREADS", "2")


def weibull_cube(n: int, damaged: bool) -> dict:
    """An n^3 cube of concrete with a Weibull E (per-bar constants), pulled along z; damaged:
    pulled fast enough that its bars soften and break within the run."""
    speed = 2.0 if damaged else 0.01
    return {
        "lattice": {"modules": [n, n, n], "L": 0.01},
        "material": {"E": {"type": "weibull", "mean": 30.0e9, "cv": 0.1, "seed": 1},
                     "rho": 2400.0, "Gf": 100.0, "e_p": 1.0e-4},
        "node_set": [{"name": "base", "face": "z-"}, {"name": "top", "face": "z+"}],
        "fixed": [{"set": "base", "dofs": "z"}],
        "velocity": [{"set": "top", "dofs": "z", "value": [0.0, 0.0, speed]}],
        "time": {"end": 1.0e-3},
    }


# name, case (a file of the source tree or a dict), end time [s] (None: the case's)
CASES = [
    ("FGM plate, homogeneous (60 x 1 x 60)", "cases/fgm_plate/homogeneous.toml", None),
    ("FGM plate, graded toughness", "cases/fgm_plate/graded_toughness.toml", None),
    ("FGM plate, graded modulus and toughness", "cases/fgm_plate/graded_modulus_toughness.toml",
     None),
    ("fatigue plate (100 x 1 x 41), its first 0.03 s (elastic)",
     "cases/fatigue/paper_plate.toml", 0.03),
    ("Weibull E cube 48^3, elastic", weibull_cube(48, False), 4.0e-4),
    ("Weibull E cube 48^3, bars softening and breaking", weibull_cube(48, True), 4.0e-4),
]


def prepared(case, end, work: Path, name: str) -> tuple[Path, list[int]]:
    d = ldem.load_case(str(ROOT / case) if isinstance(case, str) else case).to_dict()
    if end is not None:
        d["time"]["end"] = end
    out = d.setdefault("output", {})
    out.update({"vtu": False, "plots": False, "end_checkpoint": False,
                "energy_every": 10**9, "checkpoint_seconds": 0.0})
    d.pop("analysis", None)
    p = work / f"{name}.toml"
    p.write_text(ldem.to_toml(d))
    return p, d["lattice"]["modules"]


def run_case(path: Path, work: Path) -> dict:
    out = work / "out"
    subprocess.run([LDEM, "run", str(path), "--out", str(out), "--force", "--no-plot",
                    "--threads", THREADS], check=True, capture_output=True)
    return json.loads((out / "summary.json").read_text())


def run_bench(modules: list[int], steps: int) -> float:
    r = subprocess.run([LDEM, "bench", "--modules", *map(str, modules), "--steps", str(steps),
                        "--threads", THREADS], check=True, capture_output=True, text=True)
    line = r.stdout.strip().splitlines()[-1]
    return float(line.split("bar_updates_per_s=")[1].split()[0])


LAMMPS_RUN = os.environ.get("LAMMPS_RUN")


def run_lammps(modules: list[int], steps: int) -> float:
    r = subprocess.run(["bash", LAMMPS_RUN, *map(str, modules), str(steps), THREADS],
                       check=True, capture_output=True, text=True)
    line = r.stdout.strip().splitlines()[-1]
    return float(line.split("bar_updates_per_s=")[1].split()[0])


def main() -> None:
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cases = [(label, *prepared(c, end, work, f"case{i}")) for i, (label, c, end)
                 in enumerate(CASES)]
        ratios = {label: [] for label, _, _ in cases}
        rates = {label: [] for label, _, _ in cases}
        bench = {label: [] for label, _, _ in cases}
        peer = {label: [] for label, _, _ in cases}
        for r in range(rounds):
            for label, path, modules in cases:
                s = run_case(path, work)
                steps = max(2, min(int(s["steps"]), 20000))
                b = run_bench(modules, steps)
                rates[label].append(s["bar_updates_per_s"])
                bench[label].append(b)
                ratios[label].append(s["bar_updates_per_s"] / b)
                msg = ""
                if LAMMPS_RUN:
                    peer[label].append(run_lammps(modules, steps))
                    msg = f", LAMMPS {peer[label][-1]:.3g}"
                print(f"round {r + 1} {label}: {s['bar_updates_per_s']:.3g} against bench "
                      f"{b:.3g}{msg} ({s['steps']} steps, {s['softening_bars_at_end']} "
                      f"softening, {s['broken_bars_at_end']} broken at the end)", flush=True)
        extra = " LAMMPS, same lattice, median | run / LAMMPS: median (min to max) |" \
            if LAMMPS_RUN else ""
        print("\n| case | ldem run, median (1e6/s) | ldem bench, same lattice, median | "
              "run / bench: median (min to max) |" + extra)
        print("|---|---|---|---|" + ("---|---|" if LAMMPS_RUN else ""))
        for label, _, _ in cases:
            q = ratios[label]
            row = (f"| {label} | {statistics.median(rates[label]) / 1e6:.0f} | "
                   f"{statistics.median(bench[label]) / 1e6:.0f} | {statistics.median(q):.2f} "
                   f"({min(q):.2f} to {max(q):.2f}) |")
            if LAMMPS_RUN:
                p = [a / b for a, b in zip(rates[label], peer[label])]
                row += (f" {statistics.median(peer[label]) / 1e6:.0f} | "
                        f"{statistics.median(p):.2f} ({min(p):.2f} to {max(p):.2f}) |")
            print(row)


if __name__ == "__main__":
    main()
