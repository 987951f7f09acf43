#!/usr/bin/python3
"""The figures of docs/validation/compression.md from the runs of run.sh (results/compression/),
and the table the text quotes. usage: plot.py [RESULTS_DIR]"""
import bisect
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
RES = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "../../../results/compression")
L, NZ, H = 0.0025, 40, 0.1  # the cases' module size, layers and height
D = 0.05
FT = 50.0e9 * 2.0e-4  # the bars' mean strength E e_p: 10 MPa


def columns(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


RUNS = [
    ("mu0", "frictionless platens", "C0"),
    ("mu03", "platens, friction 0.3", "C1"),
    ("held", "end faces held", "0.4"),
]

runs = []
for name, label, colour in RUNS:
    d = os.path.join(RES, name)
    if not os.path.exists(os.path.join(d, "summary.json")):
        print(f"plot.py: {d}: not run (run.sh)", file=sys.stderr)
        continue
    with open(os.path.join(d, "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(d, "case.resolved.toml")) as f:
        present = next(int(line.split("=")[1]) for line in f if line.startswith("modules_present"))
    area = present / NZ * L * L  # the staircase cross-section
    p = columns(os.path.join(d, "probes.csv"))
    e = columns(os.path.join(d, "energy.csv"))
    stress = [-x / area / 1e6 for x in p["load"]]  # MPa, compression positive
    strain = [-x for x in p["axial_strain"]]
    lateral = [x / D for x in p["lateral"]]
    # The heights of the bars broken by the end, and when each broke.
    broken_z, broken_t = [], []
    with open(os.path.join(d, "events.csv")) as f:
        for r in csv.DictReader(f):
            if r["event"] == "broken":
                broken_z.append(float(r["z"]))
                broken_t.append(float(r["time"]))
    runs.append(dict(name=name, label=label, colour=colour, area=area, p=p, e=e, stress=stress,
                     strain=strain, lateral=lateral, broken_z=broken_z, broken_t=sorted(broken_t),
                     summary=summary))

fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
for r in runs:
    # The platen's (or held head's) travel over the height: a measure that keeps growing after a
    # failure, when the extensometer's nodes may fly apart.
    travel = [-x / H * 1e3 for x in r["p"]["travel"]]
    r["travel"] = travel
    axes[0].plot(travel, r["stress"], color=r["colour"], label=r["label"])
    # The extensometer and the lateral gauge up to the peak load (after it, pieces move apart).
    k = max(range(len(r["stress"])), key=lambda i: r["stress"][i])
    axes[1].plot([s * 1e3 for s in r["strain"][: k + 1]], r["stress"][: k + 1], color=r["colour"],
                 label=r["label"] + ": axial")
    axes[1].plot([-s * 1e3 for s in r["lateral"][: k + 1]], r["stress"][: k + 1], "--",
                 color=r["colour"], label=r["label"] + ": lateral (negated)")
    # Broken bars against the travel at their time.
    t = r["p"]["time"]
    counts = [bisect.bisect_right(r["broken_t"], x) for x in t]
    axes[2].plot(travel, counts, color=r["colour"], label=r["label"])
axes[0].set_xlabel("platen travel / height [1e-3]")
axes[1].set_xlabel("strain on the side, to the peak [1e-3]: axial (extensometer), lateral")
axes[2].set_xlabel("platen travel / height [1e-3]")
axes[0].set_ylabel("axial stress [MPa]")
axes[1].set_ylabel("axial stress [MPa]")
axes[2].set_ylabel("broken bars")
for ax in axes:
    ax.grid(alpha=0.3)
axes[0].legend(fontsize=8)
axes[1].legend(fontsize=7)
fig.suptitle("Rock cylinder in compression (D = 50 mm, H = 100 mm, E = 50 GPa, "
             "bar strength E e_p = 10 MPa)")
fig.tight_layout()
fig.savefig(os.path.join(HERE, "stress_strain.png"), dpi=110)

# Where the bars broke: their number per layer of modules along the height.
fig, ax = plt.subplots(figsize=(5.5, 4.5))
for r in runs:
    counts = [0] * NZ
    for z in r["broken_z"]:
        counts[min(int(z / L), NZ - 1)] += 1
    ax.plot(counts, [(k + 0.5) * L * 1e3 for k in range(NZ)], color=r["colour"], label=r["label"])
ax.set_xlabel("broken bars per layer of modules (2.5 mm)")
ax.set_ylabel("height z [mm]")
ax.set_ylim(0, H * 1e3)
ax.grid(alpha=0.3)
ax.legend(fontsize=8)
ax.set_title("where the bars broke, by the end", fontsize=10)
fig.tight_layout()
fig.savefig(os.path.join(HERE, "broken_by_height.png"), dpi=110)

# The table: the peak, the elastic start, the end.
print("| run | peak stress [MPa] | travel / H at the peak [1e-3] | stress at the end / peak | "
      "E from the extensometer to 20 MPa [GPa] | lateral / axial strain at 20 MPa | "
      "broken bars | of them in the 10 mm by each end | friction dissipated [J] | "
      "largest balance error |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in runs:
    k = max(range(len(r["stress"])), key=lambda i: r["stress"][i])
    j = next(i for i, s in enumerate(r["stress"]) if s >= 20.0)
    ends = sum(1 for z in r["broken_z"] if z < 0.01 or z > H - 0.01)
    fric = r["e"].get("friction_dissipated", [0.0])[-1]
    print(f"| {r['label']} | {r['stress'][k]:.1f} | {r['travel'][k]:.2f} | "
          f"{r['stress'][-1] / r['stress'][k]:.3f} | {r['stress'][j] / r['strain'][j] / 1e3:.1f} | "
          f"{r['lateral'][j] / r['strain'][j]:.3f} | {len(r['broken_z'])} | "
          f"{ends} ({100 * ends / max(1, len(r['broken_z'])):.0f} %) | {fric:.3f} | "
          f"{r['summary']['max_balance_error']:.1e} |")
print(f"bar strength E e_p = {FT / 1e6:.0f} MPa; areas {[round(r['area'] * 1e6) for r in runs]} mm^2")
