#!/usr/bin/python3
"""The homogeneous FGM plate's two halves: the rate of its time-step loop over its first 7 us
(elastic, the crack starting) and over the 7 us after (the crack running, the borders breaking
up). The case runs ended at 7 and at 14 us (outputs as in bench/real_cases.py: no snapshots,
plots or end checkpoint), the fastest of REPS runs of each; the second half's rate comes from
the difference of their loop times. With several binaries, alternating rounds; medians of the
rounds' ratios of the second half's rate to the first's.

    PYTHONPATH=build/release/python /usr/bin/python3 bench/fgm_halves.py [ROUNDS=3] [LDEM...]

Environment: THREADS (default 2), REPS (default 5). LDEM defaults to build/release/ldem.
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from real_cases import ROOT, prepared  # noqa: E402

THREADS = os.environ.get("THREADS", "2")
REPS = int(os.environ.get("REPS", "5"))
CASE = "cases/fgm_plate/homogeneous.toml"


def fastest(binary: str, case: Path, work: Path) -> dict:
    best = None
    for _ in range(REPS):
        out = work / "out"
        subprocess.run([binary, "run", str(case), "--out", str(out), "--force", "--no-plot",
                        "--threads", THREADS], check=True, capture_output=True)
        s = json.loads((out / "summary.json").read_text())
        if best is None or s["wall_s"] < best["wall_s"]:
            best = s
    return best


def main() -> None:
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    binaries = sys.argv[2:] or [str(ROOT / "build" / "release" / "ldem")]
    ratios = {b: [] for b in binaries}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        first_case, _ = prepared(CASE, 7.0e-6, work, "first")
        whole_case, _ = prepared(CASE, 14.0e-6, work, "whole")
        for r in range(rounds):
            for b in binaries:
                a, w = fastest(b, first_case, work), fastest(b, whole_case, work)
                first = a["bars"] * a["steps"] / a["wall_s"]
                second = a["bars"] * (w["steps"] - a["steps"]) / (w["wall_s"] - a["wall_s"])
                ratios[b].append(second / first)
                print(f"round {r + 1} {b}: first half {first / 1e6:.0f}e6, second half "
                      f"{second / 1e6:.0f}e6 bar updates/s, ratio {second / first:.2f} "
                      f"({a['steps']} and {w['steps'] - a['steps']} steps)", flush=True)
    for b in binaries:
        q = ratios[b]
        print(f"{b}: second half / first half, median {statistics.median(q):.2f} "
              f"({min(q):.2f} to {max(q):.2f})")


if __name__ == "__main__":
    main()
