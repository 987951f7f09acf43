#!/usr/bin/env python3
"""Pictures of an ldem output folder: crack.png, energy.png and, for heterogeneous materials,
fields.png.

usage: ldem_plot.py DIR   (run by `ldem run` at the end, or `ldem plot DIR`)

crack.png: the bars that softened (grey) and broke (black) during the run, drawn at their
centres on the body seen face on (the plane of its two largest extents), with the pre-cracks
in red; energy.png: every term of the energy balance against time, and the balance error; fields.png: for each property that varies, its histogram over
the bars (with the target Weibull density for random fields) and its map over the body seen
face on.
"""
import csv
import os
import sys
import tomllib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def save(fig, path):
    tmp = path + ".part.png"
    fig.savefig(tmp, dpi=150, bbox_inches="tight")
    plt.close(fig)
    os.replace(tmp, path)


def crack_png(d, case):
    n = case["lattice"]["modules"]
    L = case["lattice"]["L"]
    ext = [n[i] * L for i in range(3)]
    a, b = sorted(range(3), key=lambda i: -ext[i])[:2]
    a, b = min(a, b), max(a, b)
    names = "xyz"
    soft, broken = {}, {}
    for row in read_csv(os.path.join(d, "events.csv")):
        p = (float(row["xyz"[a]]), float(row["xyz"[b]]))
        (soft if row["event"] == "softening" else broken)[row["bar"]] = p
    for bar in broken:
        soft.pop(bar, None)
    fig, ax = plt.subplots(figsize=(6.5, 6.5 * ext[b] / ext[a] if ext[a] > 0 else 6.5))
    ax.add_patch(plt.Rectangle((0, 0), ext[a], ext[b], fill=False, lw=0.8, color="0.3"))
    mm = 1e3
    if soft:
        xs, ys = zip(*soft.values())
        ax.scatter([x * mm for x in xs], [y * mm for y in ys], s=2, c="0.65", lw=0,
                   label=f"softened ({len(soft)})")
    if broken:
        xs, ys = zip(*broken.values())
        ax.scatter([x * mm for x in xs], [y * mm for y in ys], s=3, c="k", lw=0,
                   label=f"broken ({len(broken)})")
    for pc in case.get("precrack", []):
        o, e1, e2 = pc["origin"], pc["edge1"], pc["edge2"]
        pts = [o, [o[i] + e1[i] for i in range(3)], [o[i] + e1[i] + e2[i] for i in range(3)],
               [o[i] + e2[i] for i in range(3)], o]
        ax.plot([p[a] * mm for p in pts], [p[b] * mm for p in pts], "r-", lw=1.2)
    ax.set_xlim(0, ext[a] * mm)
    ax.set_ylim(0, ext[b] * mm)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{names[a]} [mm]")
    ax.set_ylabel(f"{names[b]} [mm]")
    title = case.get("case", {}).get("title", "")
    ax.set_title((title + "\n" if title else "") + "crack pattern (pre-crack in red)", fontsize=10)
    if soft or broken:
        ax.legend(loc="upper right", fontsize=8, markerscale=4)
    save(fig, os.path.join(d, "crack.png"))


def energy_png(d):
    rows = read_csv(os.path.join(d, "energy.csv"))
    t = [float(r["time"]) for r in rows]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 6.5), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 1]})
    labels = {"external_work": "external work", "elastic": "elastic", "kinetic": "kinetic",
              "damage_dissipated": "damage", "damping_dissipated": "damping"}
    for key, lab in labels.items():
        ax.plot(t, [float(r[key]) for r in rows], label=lab)
    total = [float(r["elastic"]) + float(r["kinetic"]) + float(r["damage_dissipated"])
             + float(r["damping_dissipated"]) for r in rows]
    ax.plot(t, total, "k--", lw=0.8, label="elastic + kinetic + damage + damping")
    ax.set_ylabel("energy [J]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax2.semilogy(t, [max(float(r["balance_error"]), 1e-16) for r in rows], "k-", lw=0.8)
    ax2.set_ylabel("balance error")
    ax2.set_xlabel("time [s]")
    ax2.grid(alpha=0.3)
    save(fig, os.path.join(d, "energy.png"))


def fields_png(d, case):
    path = os.path.join(d, "fields.csv")
    if not os.path.isfile(path):
        return
    import math
    rows = read_csv(path)
    props = [p for p in ["E", "Gf", "e_p", "e_r"]
             if len({r[p] for r in rows[:5000]}) > 1 or p in case.get("fields", {})]
    if not props:
        return
    n = case["lattice"]["modules"]
    L = case["lattice"]["L"]
    ext = [n[i] * L for i in range(3)]
    a, b = sorted(sorted(range(3), key=lambda i: -ext[i])[:2])
    fig, axes = plt.subplots(len(props), 2, figsize=(10, 3.6 * len(props)), squeeze=False)
    units = {"E": "Pa", "Gf": "N/m", "e_p": "", "e_r": "(normal and diagonal bars)"}
    for row_axes, p in zip(axes, props):
        vals = [float(r[p]) for r in rows]
        h = row_axes[0]
        h.hist(vals, bins=60, density=True, color="0.6", label="bars")
        spec = case.get("fields", {}).get(p)
        if spec and spec.get("kind") == "weibull":
            g, lam = spec["shape"], spec["scale"]
            lo, hi = min(vals), max(vals)
            xs = [lo + (hi - lo) * i / 200 for i in range(201)]
            ys = [g / lam * (x / lam) ** (g - 1) * math.exp(-((x / lam) ** g)) for x in xs]
            h.plot(xs, ys, "r-", lw=1.2, label=f"Weibull target (shape {g:.3g})")
            h.legend(fontsize=8)
        h.set_xlabel(f"{p} {units[p]}")
        h.set_ylabel("density")
        m = row_axes[1]
        sc = m.scatter([float(r["xyz"[a]]) * 1e3 for r in rows],
                       [float(r["xyz"[b]]) * 1e3 for r in rows], c=vals, s=2, lw=0, cmap="viridis")
        fig.colorbar(sc, ax=m, label=p)
        m.set_aspect("equal")
        m.set_xlabel(f"{'xyz'[a]} [mm]")
        m.set_ylabel(f"{'xyz'[b]} [mm]")
    fig.suptitle("material fields per bar", fontsize=11)
    save(fig, os.path.join(d, "fields.png"))


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    d = sys.argv[1]
    with open(os.path.join(d, "case.resolved.toml"), "rb") as f:
        case = tomllib.load(f)
    crack_png(d, case)
    energy_png(d)
    fields_png(d, case)


if __name__ == "__main__":
    main()
