#!/usr/bin/python3
"""The size effect on the strength of notched plates with a random strength field.

Geometrically similar edge-notched plates in tension (the tutorial's plate: width W along x,
height W / 2 along z, one module thick in plane strain, a notch of W / 4 at mid-height), W from
20 to 320 modules of 5 mm, each with a few seeds of a correlated Weibull field of the peak
strain e_p (the material's strength; its correlation length, 10 mm, is the same at every size:
a material length). Each plate is pulled at the same nominal strain rate until its force has
fallen to half its peak; its nominal strength is sigma_N = P_max / (b W), b the thickness.
The top edge moves at the same speed at every size, so that the time to the peak over the
time a wave takes across the plate (about 200 here) is the same at every size: a constant
nominal strain rate would load the larger plates faster relative to their wave transits, and
inertia would make them stronger.

Bazant's size-effect law, sigma_N = B f_t / sqrt(1 + D / D0) with D = W, is fitted to the
points by least squares on 1 / sigma_N^2 = (1 + D / D0) / (B f_t)^2, a straight line in D. Its
asymptotes: strength theory (sigma_N constant) for D << D0 and linear elastic fracture
mechanics (sigma_N ~ D^-1/2) for D >> D0.

    PYTHONPATH=build/release/python /usr/bin/python3 docs/examples/size_effect.py

writes size_effect.csv (one row per plate) and size_effect.png into --out (default
docs/examples/size_effect/). About 3 minutes on 2 cores with the defaults.
"""

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np

import ldem

L = 0.005           # m, the module
E = 35.0e9          # Pa
SPEED = 2.5e-3      # m/s: the top edge's speed, the same at every size
GF = 10.0           # N/m
END = 1.0           # s: a bound; each plate stops once past its peak
E_P = 1.0e-4        # mean peak strain


def plate(W: int, seed: int) -> dict:
    """The case of a plate W modules wide, as a dict."""
    H = W // 2
    return {
        "case": {"title": f"notched plate W = {W}, seed {seed}"},
        "lattice": {"modules": [W, 1, H], "L": L, "plane_strain": "y"},
        "material": {
            "E": E, "rho": 2400.0, "Gf": GF,
            "e_p": {"type": "weibull", "mean": E_P, "cv": 0.2, "seed": seed,
                    "correlation_length": 0.01},
        },
        "node_set": [{"name": "bottom", "face": "z-"}, {"name": "top", "face": "z+"}],
        "fixed": [{"set": "bottom", "dofs": "z"}],
        "velocity": [{"set": "top", "dofs": "z", "value": [0.0, 0.0, SPEED],
                      "ramp": 1.0e-3}],
        # The notch: W / 4 long from the left edge, a quarter module above the node plane at
        # mid-height, through the thickness.
        "precrack": [{"name": "notch", "origin": [-1e-4, -1e-3, (H // 2 + 0.25) * L],
                      "edge1": [W / 4 * L + 1e-4, 0.0, 0.0], "edge2": [0.0, L + 2e-3, 0.0]}],
        "time": {"end": END, "safety": 0.5, "damping": 200.0},
        "output": {"vtu": False, "plots": False},
        "probe": [{"name": "force", "kind": "reaction", "set": "top", "component": "z"}],
    }


def strength(W: int, seed: int, threads: int) -> tuple[float, float]:
    """The peak force's nominal stress [Pa] and the time of the peak [s]: stepped until the force
    has fallen below half its peak (or the case's end)."""
    sim = ldem.Simulation(plate(W, seed), threads=threads)
    peak, t_peak = 0.0, 0.0
    while sim.time < END:
        sim.step(50)
        f = sim.probes["force"]
        if f > peak:
            peak, t_peak = f, sim.energies["time"]
        elif peak > 0.0 and f < 0.5 * peak:
            break
    return peak / (L * W * L), t_peak


def fit_sel(D: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """B f_t and D0 of Bazant's law from least squares on 1 / s^2 = a + c D."""
    c, a = np.polyfit(D, 1.0 / s**2, 1)
    if a <= 0 or c <= 0:
        raise RuntimeError(f"the points do not follow the law (1/s^2 = {a:.3g} + {c:.3g} D)")
    return 1.0 / math.sqrt(a), a / c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[20, 40, 80, 160, 320],
                    help="plate widths W in modules (even)")
    ap.add_argument("--seeds", type=int, default=3, help="random fields per size")
    ap.add_argument("--threads", type=int, default=0, help="threads per plate (0: all)")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "size_effect")
    ap.add_argument("--no-plot", action="store_true")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for W in a.sizes:
        for seed in range(1, a.seeds + 1):
            t0 = time.time()
            s, t_peak = strength(W, seed, a.threads)
            rows.append((W, W * L, seed, s, t_peak))
            print(f"W = {W:4d} modules ({W * L:.3f} m), seed {seed}: sigma_N = {s / 1e6:.4f} MPa "
                  f"(peak at {t_peak * 1e3:.3f} ms; {time.time() - t0:.1f} s)", flush=True)
    with open(a.out / "size_effect.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["W_modules", "D_m", "seed", "sigma_N_Pa", "t_peak_s"])
        w.writerows(rows)
    D = np.array([r[1] for r in rows])
    s = np.array([r[3] for r in rows])
    if len(set(a.sizes)) < 2:
        return
    Bft, D0 = fit_sel(D, s)
    print(f"Bazant's law: B f_t = {Bft / 1e6:.4f} MPa, D0 = {D0:.4f} m "
          f"(D / D0 from {D.min() / D0:.2f} to {D.max() / D0:.2f})")
    if a.no_plot:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.5))
    x = np.log10(D / D0)
    ax.plot(x, np.log10(s / Bft), "o", color="C0", label="ldem: each plate and seed")
    means = [(np.log10(d / D0), np.log10(s[D == d].mean() / Bft)) for d in sorted(set(D))]
    ax.plot(*zip(*means), "s", color="C3", mfc="none", ms=9, label="mean per size")
    xx = np.linspace(x.min() - 0.5, x.max() + 0.5, 200)
    ax.plot(xx, -0.5 * np.log10(1 + 10**xx), "k-", label=r"$\sigma_N = B f_t / \sqrt{1 + D/D_0}$")
    ax.plot(xx, 0 * xx, "k:", lw=0.8, label="strength criterion")
    ax.plot(xx, -0.5 * xx, "k--", lw=0.8, label="LEFM, slope -1/2")
    ax.set_xlabel(r"$\log_{10}(D / D_0)$")
    ax.set_ylabel(r"$\log_{10}(\sigma_N / B f_t)$")
    ax.set_ylim(min(-0.5 * np.log10(1 + 10 ** xx.max()), np.log10(s.min() / Bft)) - 0.05, 0.1)
    ax.set_title(f"Notched plates, Weibull e_p (cv 0.2): B f_t = {Bft / 1e6:.2f} MPa, "
                 f"D0 = {D0 * 1e3:.0f} mm", fontsize=9)
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(a.out / "size_effect.png", dpi=120)
    print(f"wrote {a.out / 'size_effect.png'}")


if __name__ == "__main__":
    main()
