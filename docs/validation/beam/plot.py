#!/usr/bin/python3
"""The figures of docs/validation/beam.md from the runs of run.sh (results/beam/), and the table
the text quotes. usage: plot.py [RESULTS_DIR]"""
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
RES = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "../../../results/beam")
GF = 100.0  # N/m, the case's
LIGAMENT = 0.05  # m, D - a


def columns(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


RUNS = [
    ("cmod_L2", "CMOD control, L = 2 mm", "C0", "-"),
    ("cmod_L1", "CMOD control, L = 1 mm", "C1", "-"),
    ("deflection_L2", "deflection control, L = 2 mm", "0.5", "--"),
]

runs = []
for name, label, colour, style in RUNS:
    d = os.path.join(RES, name)
    if not os.path.exists(os.path.join(d, "summary.json")):
        print(f"plot.py: {d}: not run (run.sh)", file=sys.stderr)
        continue
    with open(os.path.join(d, "case.resolved.toml")) as f:
        L = next(float(line.split("=")[1]) for line in f if line.startswith("L = "))
    p = columns(os.path.join(d, "probes.csv"))
    e = columns(os.path.join(d, "energy.csv"))
    width = L  # one module thick
    load = [-x / width for x in p["load"]]  # N/m of width; the reaction on the load line is < 0
    runs.append((name, label, colour, style, L, p, e, load))

fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
for name, label, colour, style, L, p, e, load in runs:
    axes[0].plot([w * 1e3 for w in p["cmod"]], [x / 1e3 for x in load], style, color=colour,
                 label=label)
    axes[1].plot([-u * 1e3 for u in p["deflection"]], [x / 1e3 for x in load], style,
                 color=colour, label=label)
axes[0].set_xlabel("crack mouth opening CMOD [mm]")
axes[1].set_xlabel("load-line deflection [mm]")
for ax in axes:
    ax.set_ylabel("load per unit width [kN/m]")
    ax.grid(alpha=0.3)
    ax.set_xlim(left=0)
axes[0].legend()
fig.suptitle("Notched beam in three-point bending (D = 100 mm, S = 400 mm, a/D = 0.5)")
fig.tight_layout()
fig.savefig(os.path.join(HERE, "load_cmod.png"), dpi=110)

print("| run | peak [kN/m] | CMOD at peak [mm] | deflection at end [mm] | end load / peak "
      "| work of load / (Gf A_lig) | tail beyond the end / (Gf A_lig) "
      "| bars' dissipation / (Gf A_lig) | damping / (Gf A_lig) | largest balance error |")
print("|---|---|---|---|---|---|---|---|---|---|")
for name, label, colour, style, L, p, e, load in runs:
    i = max(range(len(load)), key=lambda k: load[k])
    area = LIGAMENT * L  # the ligament's area, t = L
    # The tail of the load-deflection curve beyond the end, P ~ A / d^2 (Elices, Guinea and
    # Planas 1992: a cohesive crack's far tail in three-point bending): its work P_e d_e. The
    # spread of P d^2 over the last quarter of the run says how well the hyperbola fits there.
    d = [-u for u in p["deflection"]]
    last = range(3 * len(d) // 4, len(d))
    A = [load[k] * d[k] ** 2 for k in last]
    tail = load[-1] * L * d[-1]
    print(f"| {label} | {load[i] / 1e3:.1f} | {p['cmod'][i] * 1e3:.4f} | {d[-1] * 1e3:.3f} | "
          f"{load[-1] / load[i]:.3f} | {e['external_work'][-1] / (GF * area):.3f} | "
          f"{tail / (GF * area):.3f} (P d^2 from {min(A) / max(A):.2f} of its largest) | "
          f"{e['damage_dissipated'][-1] / (GF * area):.3f} | "
          f"{e['damping_dissipated'][-1] / (GF * area):.3f} | "
          f"{max(abs(x) for x in e['balance_error']):.1e} |")

# The mesh check: the two CMOD-controlled runs at the time the shorter one ends (the same CMOD
# target), their peaks and energies.
by_name = {r[0]: r for r in runs}
if "cmod_L1" in by_name and "cmod_L2" in by_name:
    fine, coarse = by_name["cmod_L1"], by_name["cmod_L2"]
    t_end = fine[6]["time"][-1]
    k = max(i for i, t in enumerate(coarse[6]["time"]) if t <= t_end + 1e-12)
    print(f"\nmesh check at t = {t_end:.4g} s (L = 2 mm row at {coarse[6]['time'][k]:.4g} s):")
    for key in ("external_work", "damage_dissipated"):
        a = coarse[6][key][k] / (GF * LIGAMENT * coarse[4])
        b = fine[6][key][-1] / (GF * LIGAMENT * fine[4])
        print(f"  {key} / (Gf A_lig): L = 2 mm {a:.4f}, L = 1 mm {b:.4f}, difference {b / a - 1:+.2%}")
    for what, f in (("peak load", lambda r: max(r[7])),
                    ("CMOD at the peak", lambda r: r[5]["cmod"][r[7].index(max(r[7]))])):
        print(f"  {what}: L = 2 mm {f(coarse):.6g}, L = 1 mm {f(fine):.6g}, "
              f"difference {f(fine) / f(coarse) - 1:+.2%}")
