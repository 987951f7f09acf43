#!/usr/bin/python3
"""The homogeneous FGM plate's two halves: the rate of its time-step loop over its first 7 us
(elastic, the crack starting) and over the 7 us after (the crack running, the borders breaking
up). The case runs ended at 7 and at 14 us (outputs as in bench/real_cases.py: no snapshots,
plots or end checkpoint), the fastest of REPS runs of each; the second half's rate comes from
the difference of their loop times. With several binaries, alternating rounds; medians of the
rounds' ratios of the second half's rate to the first's.

    PYTHONPATH=build/release/python /usr/bin/python3 bench/fgm_halves.py [ROUNDS=3] [LDEM...]

Environment: THREADS (default 2), REPS (default 5). LDEM defaults to build/release/ldem.
CASES=graded also runs the two graded plates (graded toughness; graded modulus and toughness)
in each round and prints each half's rate, and the whole run's, over the homogeneous plate's,
per round and as medians: the first half compares the materials on a plate still nearly
elastic, the second adds their different damage.
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
PLATES = {"homogeneous": "cases/fgm_plate/homogeneous.toml",
          "graded toughness": "cases/fgm_plate/graded_toughness.toml",
          "graded modulus and toughness": "cases/fgm_plate/graded_modulus_toughness.toml"}
CASES = list(PLATES) if os.environ.get("CASES") == "graded" else ["homogeneous"]


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


def halves(binary: str, first_case: Path, whole_case: Path,
           work: Path) -> tuple[float, float, float]:
    """The first half's, the second half's and the whole run's bar updates per second."""
    a, w = fastest(binary, first_case, work), fastest(binary, whole_case, work)
    first = a["bars"] * a["steps"] / a["wall_s"]
    second = a["bars"] * (w["steps"] - a["steps"]) / (w["wall_s"] - a["wall_s"])
    return first, second, w["bars"] * w["steps"] / w["wall_s"]


def summary(label: str, q: list[float]) -> str:
    return f"{label} median {statistics.median(q):.2f} ({min(q):.2f} to {max(q):.2f})"


def main() -> None:
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    binaries = sys.argv[2:] or [str(ROOT / "build" / "release" / "ldem")]
    ratios = {b: [] for b in binaries}
    # (binary, case, half) -> that half's rate over the homogeneous plate's, per round
    over_homogeneous = {(b, c, h): [] for b in binaries for c in CASES[1:] for h in (0, 1, 2)}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cases = {c: (prepared(PLATES[c], 7.0e-6, work, f"first{i}")[0],
                     prepared(PLATES[c], 14.0e-6, work, f"whole{i}")[0])
                 for i, c in enumerate(CASES)}
        for r in range(rounds):
            for b in binaries:
                rates = {}
                for c in CASES:
                    first, second, _ = rates[c] = halves(b, *cases[c], work)
                    if c == "homogeneous":
                        ratios[b].append(second / first)
                    print(f"round {r + 1} {b} {c}: first half {first / 1e6:.0f}e6, second half "
                          f"{second / 1e6:.0f}e6 bar updates/s, ratio {second / first:.2f}",
                          flush=True)
                for c in CASES[1:]:
                    for h in (0, 1, 2):
                        over_homogeneous[b, c, h].append(rates[c][h] / rates["homogeneous"][h])
    for b in binaries:
        print(f"{b}: " + summary("homogeneous plate, second half / first half,", ratios[b]))
        for c in CASES[1:]:
            for h, part in ((0, "first half"), (1, "second half"), (2, "whole run")):
                print(f"{b}: " + summary(f"{c}, {part} / the homogeneous plate's,",
                                         over_homogeneous[b, c, h]))


if __name__ == "__main__":
    main()
