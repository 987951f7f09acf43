#!/usr/bin/env python3
"""The pictures of docs/validation/fatigue.md from the study folders of run.sh.

Usage: /usr/bin/python3 docs/validation/fatigue/plot.py [results/fatigue] [docs/validation/fatigue]
Each run folder holds fatigue_front.csv (t, N, a) and fatigue.csv (N, a, da_dN, delta_K) and
summary.json (analysis.fatigue: paris_C, paris_m, paris_m_interval); folders missing are left
out of the pictures.
"""
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def table(path):
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def fit(folder):
    with open(os.path.join(folder, "summary.json")) as f:
        return json.load(f).get("analysis", {}).get("fatigue", {})


def runs(root, pairs):
    out = []
    for label, sub in pairs:
        d = os.path.join(root, sub)
        if os.path.exists(os.path.join(d, "fatigue.csv")):
            out.append((label, d))
    return out


def plot_front(ax, folder, label):
    """The damage front a(N) of a run, as steps; returns its first N."""
    front = table(os.path.join(folder, "fatigue_front.csv"))
    ax.step([r["N"] for r in front], [1e3 * r["a"] for r in front], where="post", label=label)
    return min(r["N"] for r in front)


def label_front(ax, first_n=0.0):
    """Axes of a(N): N on a log scale, or linear where the front moves before N = 0 (while
    the amplitude rises)."""
    ax.set_xlabel("cycles N (resolved and jumped; N = 0 when the amplitude is constant)")
    ax.set_ylabel("damage front a [mm]")
    if first_n >= 0.0:
        ax.set_xscale("symlog", linthresh=1e3)
    ax.legend(fontsize=8)


def plot_set(root, dest, name, pairs, title):
    found = runs(root, pairs)
    if not found:
        return
    fig, (ax_a, ax_p) = plt.subplots(1, 2, figsize=(11, 4.2))
    first_n = 0.0
    for label, d in found:
        first_n = min(first_n, plot_front(ax_a, d, label))
        rows = [r for r in table(os.path.join(d, "fatigue.csv")) if r["da_dN"] > 0]
        if not rows:
            continue
        used = [r for r in rows if r.get("in_fit", 1) > 0]
        left = [r for r in rows if r.get("in_fit", 1) == 0]
        f = fit(d)
        lab = label
        if f.get("paris_m") is not None:
            lo, hi = f["paris_m_interval"]
            lab += f": m = {f['paris_m']:.2f} [{lo:.2f}, {hi:.2f}]"
        pts = ax_p.loglog([r["delta_K"] for r in used], [r["da_dN"] for r in used], "o",
                          ms=4, label=lab)
        ax_p.loglog([r["delta_K"] for r in left], [r["da_dN"] for r in left], "o", ms=4,
                    mfc="none", color=pts[0].get_color())
        if f.get("paris_m") is not None and used:
            ks = sorted(r["delta_K"] for r in used)
            ax_p.loglog([ks[0], ks[-1]], [f["paris_C"] * k ** f["paris_m"] for k in
                                          (ks[0], ks[-1])], "-", color=pts[0].get_color())
    label_front(ax_a, first_n)
    ax_p.set_xlabel("Delta K [Pa m^0.5] (Tada)")
    ax_p.set_ylabel("da/dN [m/cycle] (secant; hollow: left out of the fit)")
    ax_p.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(os.path.join(dest, name), dpi=110)
    plt.close(fig)


def plot_damping(root, dest):
    """The m = 6 plate with and without damping: the front, and the kinetic energy that the
    breaks leave in the body."""
    found = runs(root, [("damped (a = 1000 1/s)", "exponents/m6"), ("undamped", "undamped/m6")])
    if len(found) < 2:
        return
    fig, (ax_a, ax_k) = plt.subplots(1, 2, figsize=(11, 4.2))
    for label, d in found:
        plot_front(ax_a, d, label)
        energy = table(os.path.join(d, "energy.csv"))
        ax_k.semilogy([r["time"] for r in energy], [max(r["kinetic"], 1e-12) for r in energy],
                      lw=0.5, label=label)
    label_front(ax_a)
    ax_k.set_xlabel("resolved time [s]")
    ax_k.set_ylabel("kinetic energy [J]")
    ax_k.set_ylim(1e-10, 1e-2)
    ax_k.legend(fontsize=8)
    fig.suptitle("LEFM plate, m = 6: the ringing of the breaks, damped and undamped")
    fig.tight_layout()
    fig.savefig(os.path.join(dest, "damping.png"), dpi=110)
    plt.close(fig)


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "results/fatigue"
    dest = sys.argv[2] if len(sys.argv) > 2 else "docs/validation/fatigue"
    os.makedirs(dest, exist_ok=True)
    plot_set(root, dest, "exponents.png",
             [("law m = 3", "exponents/m3"), ("law m = 6", "exponents/m6"),
              ("law m = 10", "exponents/m10")],
             "LEFM plate: the front and Paris' law for three exponents of the bar law")
    plot_set(root, dest, "mesh_frequency.png",
             [("L = 10 mm, 200 Hz", "exponents/m6"), ("L = 5 mm", "mesh/half"),
              ("100 Hz", "frequency/f100")],
             "LEFM plate, m = 6: the load frequency and the module size (the runs made)")
    plot_damping(root, dest)
    plot_set(root, dest, "threshold.png",
             [("no threshold, peak 0.3 MPa", "exponents/m6"),
              ("threshold 2e-5, peak 0.3 MPa", "threshold/peak_0.3")],
             "LEFM plate, m = 6: a threshold (at 0.25 MPa one bar breaks, at 0.2 MPa none)")
    plot_set(root, dest, "seeds.png",
             [("seed 1", "seeds/seed1"), ("seed 2", "seeds/seed2"), ("seed 3", "seeds/seed3")],
             "The paper's plate with the fatigue law (L = 7.5 mm)")
    plot_set(root, dest, "seeds_coarse.png",
             [("seed 1", "seeds_coarse/seed1"), ("seed 2", "seeds_coarse/seed2"),
              ("seed 3", "seeds_coarse/seed3")],
             "The paper's plate with the fatigue law (coarse lattice, L = 15 mm)")


if __name__ == "__main__":
    main()
