#!/usr/bin/python3
"""The figures of docs/validation/shapes.md from the runs of run.sh (results/shapes/), and the
numbers the text quotes. usage: plot.py [RESULTS_DIR]"""
import csv
import json
import math
import os
import shutil
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
RES = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "../../../results/shapes")


def probes(d):
    with open(os.path.join(d, "probes.csv")) as f:
        rows = list(csv.DictReader(f))
    return [float(r["time"]) for r in rows], [float(r["load"]) for r in rows]


def travel(t, v, ramp):
    """The imposed displacement of a velocity v reached linearly over `ramp`."""
    return v * t * t / (2 * ramp) if t < ramp else v * (t - ramp / 2)


def energy_end(d):
    with open(os.path.join(d, "energy.csv")) as f:
        rows = list(csv.DictReader(f))
    return rows[-1]


def curve(ax, d, v, ramp, scale_x, scale_y, label, sign=1.0):
    t, p = probes(d)
    x = [travel(s, v, ramp) * scale_x for s in t]
    y = [sign * q * scale_y for q in p]
    ax.plot(x, y, "k-", lw=1.0, label=label)
    i = max(range(len(y)), key=lambda k: y[k])
    return x, y, i


def main():
    out = {}
    # Direct tension: the material's tensile strength (50 mm wide, t = 1 mm).
    d = os.path.join(RES, "tension")
    if os.path.isdir(d):
        with open(os.path.join(d, "probes.csv")) as f:
            rows = list(csv.DictReader(f))
        t = [float(r["time"]) for r in rows]
        p = [float(r["load"]) + float(r["load_centres"]) for r in rows]
        f_t = max(p) / (0.05 * 0.001)
        out["tension_strength_MPa"] = f_t / 1e6
        i = max(range(len(p)), key=lambda k: p[k])
        out["tension_peak_strain"] = travel(t[i], 0.01, 2e-4) / 0.1
    # Brazilian disc: s_t = 2 P / (pi D t).
    d = os.path.join(RES, "brazilian_disc")
    if os.path.isdir(d):
        fig, ax = plt.subplots(figsize=(5, 3.6))
        x, y, i = curve(ax, d, 0.02, 2e-4, 1e6, 1.0, "lattice", sign=-1.0)
        P = y[i]
        out["disc_peak_N"] = P
        out["disc_splitting_MPa"] = 2 * P / (math.pi * 0.1 * 0.001) / 1e6
        ax.plot([x[i]], [P], "o", color="tab:red",
                label=f"peak {P:.0f} N: 2P/(pi D t) = {out['disc_splitting_MPa']:.2f} MPa")
        ax.set_xlabel("platen travel [um]")
        ax.set_ylabel("load [N] (t = 1 mm)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.savefig(os.path.join(HERE, "disc_load.png"), dpi=130, bbox_inches="tight")
        shutil.copy(os.path.join(d, "crack.png"), os.path.join(HERE, "disc_crack.png"))
    # Plate with a hole: nominal (gross) stress against the average strain.
    d = os.path.join(RES, "plate_with_hole")
    if os.path.isdir(d):
        fig, ax = plt.subplots(figsize=(5, 3.6))
        x, y, i = curve(ax, d, 0.01, 1e-3, 1e3 / 0.2, 1e-6 / (0.1 * 0.00125), "lattice")
        out["hole_peak_gross_MPa"] = y[i]
        out["hole_peak_net_MPa"] = y[i] * 0.1 / 0.08
        out["hole_peak_strain_permille"] = x[i]
        ax.set_xlabel("average strain [1e-3]")
        ax.set_ylabel("gross stress [MPa]")
        ax.grid(alpha=0.3)
        fig.savefig(os.path.join(HERE, "hole_stress.png"), dpi=130, bbox_inches="tight")
        shutil.copy(os.path.join(d, "crack.png"), os.path.join(HERE, "hole_crack.png"))
    # Notched beam: load against midspan deflection; the work of fracture.
    d = os.path.join(RES, "notched_beam")
    if os.path.isdir(d):
        fig, ax = plt.subplots(figsize=(5, 3.6))
        x, y, i = curve(ax, d, 0.01, 1e-3, 1e3, 1.0, "lattice", sign=-1.0)
        out["beam_peak_N"] = y[i]
        out["beam_peak_deflection_mm"] = x[i]
        # The work of fracture: the area under the load-deflection curve (mm -> m).
        W = sum(0.5 * (y[k] + y[k + 1]) * (x[k + 1] - x[k]) * 1e-3 for k in range(len(x) - 1))
        e = energy_end(d)
        lig = 0.05 * 0.002
        out["beam_work_J"] = W
        out["beam_work_over_ligament_N_per_m"] = W / lig
        out["beam_damage_over_ligament_N_per_m"] = float(e["damage_dissipated"]) / lig
        out["beam_end_load_fraction"] = y[-1] / y[i]
        ax.set_xlabel("midspan deflection [mm]")
        ax.set_ylabel("load [N] (t = 2 mm)")
        ax.grid(alpha=0.3)
        fig.savefig(os.path.join(HERE, "beam_load.png"), dpi=130, bbox_inches="tight")
        shutil.copy(os.path.join(d, "crack.png"), os.path.join(HERE, "beam_crack.png"))
    # Rock cylinder: axial stress against axial strain.
    d = os.path.join(RES, "rock_cylinder")
    if os.path.isdir(d):
        with open(os.path.join(d, "case.resolved.toml"), "rb") as f:
            import tomllib
            case = tomllib.load(f)
        # The loaded end's area: the present modules of the top layer.
        area = math.pi * 0.025 ** 2
        fig, ax = plt.subplots(figsize=(5, 3.6))
        x, y, i = curve(ax, d, 0.02, 5e-4, 1e3 / 0.1, 1e-6 / area, "lattice", sign=-1.0)
        out["cylinder_peak_MPa"] = y[i]
        out["cylinder_peak_strain_permille"] = x[i]
        out["cylinder_modules"] = case["lattice"].get("modules_present")
        ax.set_xlabel("axial strain [1e-3]")
        ax.set_ylabel("axial stress [MPa] (load / pi R^2)")
        ax.grid(alpha=0.3)
        fig.savefig(os.path.join(HERE, "cylinder_stress.png"), dpi=130, bbox_inches="tight")
        shutil.copy(os.path.join(d, "crack.png"), os.path.join(HERE, "cylinder_crack.png"))
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
