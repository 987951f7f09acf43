#!/usr/bin/env python3
"""Pictures of an ldem output folder: crack.png, energy.png and, for heterogeneous materials,
fields.png.

usage: ldem_plot.py [--view AB] [--slice AXIS=VALUE] DIR
                                     (run by `ldem run` at the end, or `ldem plot DIR`)
       ldem_plot.py --ensemble DIR   (run by `ldem ensemble` at the end)

crack.png: the bars that softened (grey) and broke (black) during the run, drawn at their
centres, with the pre-cracks in red: a body at most two modules thick seen face on (the plane
of its two largest extents); a 3-D body as two panels, the crack face on (seen along the
direction in which its broken bars spread least, coloured by their depth) and a slice one
module thick through the middle of the body's thinnest direction; --view AB (xz, xy, yz): every
bar projected on that plane; --slice AXIS=VALUE (m): the bars within half a module of that
plane; energy.png: every term of the energy balance against time, and the balance error; fields.png: for each property that varies, its histogram over
the bars (with the target Weibull density for random fields) and its map over the body seen
face on; crack_speed.png (after a crack analysis): the tip speed of the trunk and of each
branch against time with its standard error and the Rayleigh speed marked, and the tips' and
the softened zone's distance along the crack.

After a fatigue analysis: fatigue_load.png (remote stress of the cyclic load and the probed
bar forces against time), fatigue_cracks.png (damage at six moments of the growth),
fatigue_front.png (time of every bar's first softening and rupture against the x of its
centre, with the damage front), fatigue_aN.png (a against N with the representative points)
and fatigue_paris.png (log da/dN against log Delta K with the fitted Paris line).

With --ensemble, DIR holds one folder per case with runs run_00, run_01, ...: the pictures
compare the cases' first runs (crack patterns side by side; elastic, kinetic and dissipated
energies, one figure each; crack tip speeds).
"""
import json
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


def crack_analysis(d):
    path = os.path.join(d, "summary.json")
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return json.load(f).get("analysis", {}).get("crack")


def read_events(d):
    """Each bar's softening and rupture centres: (softened only, broken), bar -> (x, y, z)."""
    soft, broken = {}, {}
    for row in read_csv(os.path.join(d, "events.csv")):
        p = (float(row["x"]), float(row["y"]), float(row["z"]))
        (soft if row["event"] == "softening" else broken)[row["bar"]] = p
    for bar in broken:
        soft.pop(bar, None)
    return soft, broken


def face_on_plane(case):
    """The plane of the body's two largest extents (a <= b)."""
    n = case["lattice"]["modules"]
    return tuple(sorted(sorted(range(3), key=lambda i: -n[i])[:2]))


def draw_body(ax, d, L, plane, slab):
    """A shaped body (body.npy in the run folder): its modules in light grey, projected on the
    plane (a module column counts where any of its modules is present), or those of the slab."""
    path = os.path.join(d, "body.npy")
    if not os.path.exists(path):
        return
    import numpy as np
    body = np.load(path) != 0  # [i, j, k]
    a, b = plane
    depth = 3 - a - b
    if slab:
        k, v, _ = slab
        layer = min(max(int(v / L), 0), body.shape[k] - 1)
        cut = np.take(body, layer, axis=k)
    else:
        cut = body.any(axis=depth)
    if cut.shape != (body.shape[a], body.shape[b]):
        cut = cut.T
    mm = 1e3
    ax.imshow(np.where(cut.T, 0.93, 1.0), origin="lower", cmap="gray", vmin=0.0, vmax=1.0,
              extent=(0, body.shape[a] * L * mm, 0, body.shape[b] * L * mm),
              interpolation="nearest", zorder=0)


def draw_crack(ax, d, case, legend=True, plane=None, depth=None, slab=None, events=None):
    """The crack pattern of run folder d on ax, projected on `plane` (two axis indices, default
    the body's face-on plane); `depth`: colour broken bars by this axis; `slab` = (axis, value,
    half width): only bars whose centre lies that close to the plane axis = value."""
    n = case["lattice"]["modules"]
    L = case["lattice"]["L"]
    ext = [n[i] * L for i in range(3)]
    a, b = plane if plane else face_on_plane(case)
    names = "xyz"
    soft, broken = events if events else read_events(d)
    if slab:
        k, v, w = slab
        soft = {bar: p for bar, p in soft.items() if abs(p[k] - v) <= w}
        broken = {bar: p for bar, p in broken.items() if abs(p[k] - v) <= w}
    ax.add_patch(plt.Rectangle((0, 0), ext[a], ext[b], fill=False, lw=0.8, color="0.3"))
    mm = 1e3
    draw_body(ax, d, L, (a, b), slab)
    if soft:
        ps = list(soft.values())
        ax.scatter([p[a] * mm for p in ps], [p[b] * mm for p in ps], s=2, c="0.65", lw=0,
                   label=f"softened ({len(soft)})")
    if broken:
        ps = list(broken.values())
        if depth is None:
            ax.scatter([p[a] * mm for p in ps], [p[b] * mm for p in ps], s=3, c="k", lw=0,
                       label=f"broken ({len(broken)})")
        else:
            # One point per position in the plane, coloured by the mean depth of the broken bars
            # behind it (a crack through the depth reads as its middle).
            column = {}
            for p in ps:
                key = (round(p[a] / (L / 8)), round(p[b] / (L / 8)))
                s_, c_, n_ = column.get(key, (p, 0.0, 0))
                column[key] = (s_, c_ + p[depth], n_ + 1)
            pts = list(column.values())
            sc = ax.scatter([p[a] * mm for p, _, _ in pts], [p[b] * mm for p, _, _ in pts], s=4,
                            c=[c / k * mm for _, c, k in pts], cmap="viridis", lw=0, vmin=0.0,
                            vmax=ext[depth] * mm, label=f"broken ({len(broken)})")
            ax.figure.colorbar(sc, ax=ax, shrink=0.8,
                               label=f"mean {names[depth]} of the broken bars behind [mm]")
    for pc in case.get("precrack", []):
        o, e1, e2 = pc["origin"], pc["edge1"], pc["edge2"]
        pts = [o, [o[i] + e1[i] for i in range(3)], [o[i] + e1[i] + e2[i] for i in range(3)],
               [o[i] + e2[i] for i in range(3)], o]
        ax.plot([p[a] * mm for p in pts], [p[b] * mm for p in pts], "r-", lw=1.2)
    an = crack_analysis(d)
    if an and an.get("branching_point_m") and an.get("plane_axes") == names[a] + names[b]:
        import math
        pa, pb = an["branching_point_m"]
        for br in an["branches"]:
            if br["level"] != 1:
                continue
            th = math.radians(br["angle_deg"])
            sense = 1.0 if an["precrack_tip_m"] >= an["mouth_m"] else -1.0
            ln = an["branch_fit_length_m"]
            ax.plot([pa * mm, (pa + sense * ln * math.cos(th)) * mm],
                    [pb * mm, (pb + ln * math.sin(th)) * mm], "-", color="tab:blue", lw=1.5)
        ax.plot([pa * mm], [pb * mm], "o", color="tab:blue", ms=5)
        ax.plot([], [], "o", color="tab:blue", ms=1.5,
                label=f"branching at {an['branching_length_m'] * mm:.3g} mm, "
                + ", ".join(f"{br['angle_deg']:+.0f}" for br in an["branches"]
                            if br["level"] == 1) + " deg")
    ax.set_xlim(0, ext[a] * mm)
    ax.set_ylim(0, ext[b] * mm)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{names[a]} [mm]")
    ax.set_ylabel(f"{names[b]} [mm]")
    if legend and (soft or broken):
        ax.legend(loc="upper right", fontsize=7, markerscale=4)


def fail(message):
    """Bad input: the message, exit status 2 (ldem plot passes it on), no picture written."""
    print(message, file=sys.stderr)
    sys.exit(2)


def parse_view(text):
    """'xz' -> (0, 2)."""
    if len(text) != 2 or any(c not in "xyz" for c in text) or text[0] == text[1]:
        fail(f"ldem plot: --view: expected two different axes among x, y, z (xz, xy, yz); "
             f"got '{text}'")
    return tuple(sorted("xyz".index(c) for c in text))


def parse_slice(text, case):
    """'y=0.015' -> (1, 0.015): the axis and the plane's coordinate in m, inside the body."""
    axis, _, value = text.partition("=")
    n, L = case["lattice"]["modules"], case["lattice"]["L"]
    try:
        k, v = "xyz".index(axis.strip()), float(value)
    except ValueError:
        fail(f"ldem plot: --slice: expected AXIS=VALUE with AXIS one of x, y, z and VALUE "
             f"in m (for example y=0.015); got '{text}'")
    if not 0.0 <= v <= n[k] * L:
        fail(f"ldem plot: --slice: expected {axis.strip()} between 0 and {n[k] * L:.6g} m "
             f"(the body); got {v:.6g}")
    return k, v


def crack_png(d, case, view=None, cut=None):
    """crack.png. A body thin in one direction (at most two modules), or a view asked for: the
    bars seen face on. A 3-D body: the crack seen face on (along the direction in which its
    broken bars spread least), coloured by depth, beside a slice through the middle of the
    body's thinnest direction. A slice asked for: the bars within half a module of it."""
    n = case["lattice"]["modules"]
    L = case["lattice"]["L"]
    ext = [n[i] * L for i in range(3)]
    names = "xyz"
    title = case.get("case", {}).get("title", "")
    events = read_events(d)
    soft, broken = events
    cloud = list(broken.values()) or list(soft.values())
    panels = []  # (plane, depth, slab, title)
    if cut:
        k, v = cut
        plane = tuple(i for i in range(3) if i != k)
        panels.append((plane, None, (k, v, 0.5 * L),
                       f"slice {names[k]} = {v * 1e3:.4g} mm (bars within half a module)"))
    elif view or min(n) <= 2 or not cloud:
        plane = view if view else face_on_plane(case)
        panels.append((plane, None, None,
                       f"every bar projected on the {names[plane[0]]}-{names[plane[1]]} plane"
                       if view else "crack pattern (pre-crack in red)"))
    else:
        # The crack's normal: the direction of least spread of the broken bars (the smallest
        # principal axis of their centres), taken as the coordinate axis nearest to it.
        import numpy as np
        w, vec = np.linalg.eigh(np.cov(np.array(cloud).T))
        normal = int(np.argmax(np.abs(vec[:, 0])))
        face = tuple(i for i in range(3) if i != normal)
        # The slice: through the middle of the body's thinnest direction (the section a 2-D
        # model of the specimen would show; for a cube, across the crack).
        across = min(range(3), key=lambda i: (ext[i], i == normal))
        mid = 0.5 * ext[across]
        panels.append((face, normal, None,
                       f"the crack face on, {names[face[0]]}-{names[face[1]]} "
                       f"(colour: {names[normal]})"))
        panels.append((tuple(i for i in range(3) if i != across), None,
                       (across, mid, 0.5 * L),
                       f"slice {names[across]} = {mid * 1e3:.4g} mm, the middle of the body"))
    width = [ext[p[0]] / max(ext[p[1]], 1e-300) for p, *_ in panels]
    fig, axes = plt.subplots(1, len(panels), squeeze=False, layout="constrained",
                             figsize=(sum(min(max(5.0 * w, 3.0), 9.0) for w in width) + 1.5 *
                                      len(panels), 5.0))
    for ax, (plane, depth, slab, sub) in zip(axes[0], panels):
        draw_crack(ax, d, case, plane=plane, depth=depth, slab=slab, events=events)
        ax.set_title(sub, fontsize=9)
    fig.suptitle((title + "\n" if title else "") + "softened (grey) and broken (black) bars",
                 fontsize=10)
    save(fig, os.path.join(d, "crack.png"))
    print("crack.png: " + "; ".join(sub for _, _, _, sub in panels))


def tip_parts(rows):
    """crack_tip.csv's rows split by part: 0 the trunk, 1, 2, ... the branches."""
    parts = {}
    for r in rows:
        parts.setdefault(int(r.get("branch", 0)), []).append(r)
    return parts


def crack_speed_png(d):
    path = os.path.join(d, "crack_tip.csv")
    an = crack_analysis(d)
    if not os.path.isfile(path) or not an:
        return
    rows = read_csv(path)
    if not rows:
        return
    us = 1e6
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 6.5), sharex=True)
    cR = an["rayleigh_speed_m_s"]
    along, normal = an["plane_axes"]
    for b, part in sorted(tip_parts(rows).items()):
        name = "trunk" if b == 0 else f"branch {b}"
        t = [float(r["time"]) * us for r in part]
        v = [float(r["speed"]) / cR for r in part]
        se = [float(r["speed_se"]) / cR if r["speed_se"] != "nan" else 0.0 for r in part]
        line, = ax.plot(t, v, lw=1, label=name)
        ax.fill_between(t, [x - e for x, e in zip(v, se)], [x + e for x, e in zip(v, se)],
                        color=line.get_color(), alpha=0.25, lw=0)
        marked = [x if (r["flagged"] == "1" or r["jump"] == "1") else float("nan")
                  for x, r in zip(v, part)]
        ax.plot(t, marked, ".", ms=3, color=line.get_color())
        ax2.plot(t, [float(r["length"]) * 1e3 for r in part], lw=1, color=line.get_color(),
                 label=f"{name}: tip")
    front = {float(r["time"]): float(r["softening_length"]) for r in rows}
    ax2.plot([t * us for t in sorted(front)], [front[t] * 1e3 for t in sorted(front)], "k:", lw=1,
             label="softened zone's front")
    ax.axhline(1.0, color="tab:red", ls="--", lw=1, label=f"Rayleigh speed {cR:.0f} m/s")
    ax.axhline(0.45, color="tab:red", ls=":", lw=1, label="0.45 c_R")
    ax.set_ylabel("tip speed / c_R")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"crack tip: speed fitted over {an['speed_fit_length_m'] * 1e3:.2g} mm of advance, "
                 f"band +- its standard error;\ndots: windows where the softened zone ran more than "
                 f"{an['zone_flag_length_m'] * 1e3:.2g} mm ahead, or the tip jumped", fontsize=9)
    ax2.set_ylabel("distance along the crack [mm]")
    ax2.set_xlabel("time [us]")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    save(fig, os.path.join(d, "crack_speed.png"))


def ensemble(d):
    """Pictures comparing the first run of each case of an ensemble folder."""
    cases = []
    table = os.path.join(d, "ensemble.csv")
    if os.path.isfile(table):  # in the order the cases were given
        for row in read_csv(table):
            if row["case"] not in cases:
                cases.append(row["case"])
    cases = [c for c in cases if os.path.isdir(os.path.join(d, c, "run_00"))]
    if not cases:
        return
    runs = [os.path.join(d, c, "run_00") for c in cases]
    loaded = []
    for r in runs:
        with open(os.path.join(r, "case.resolved.toml"), "rb") as f:
            loaded.append(tomllib.load(f))
    fig, axes = plt.subplots(1, len(runs), figsize=(4.6 * len(runs), 4.8), squeeze=False)
    for ax, r, case, name in zip(axes[0], runs, loaded, cases):
        draw_crack(ax, r, case, legend=True)
        ax.set_title(case.get("case", {}).get("title", name), fontsize=9)
    fig.suptitle("final crack patterns (first run of each case; pre-crack in red)", fontsize=11)
    save(fig, os.path.join(d, "cracks.png"))
    us = 1e6
    energies = [read_csv(os.path.join(r, "energy.csv")) for r in runs]
    for key, label in [("elastic", "elastic energy"), ("kinetic", "kinetic energy"),
                       ("damage_dissipated", "energy dissipated by damage")]:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for rows, case, name in zip(energies, loaded, cases):
            ax.plot([float(x["time"]) * us for x in rows], [float(x[key]) for x in rows],
                    label=case.get("case", {}).get("title", name))
        ax.set_xlabel("time [us]")
        ax.set_ylabel(f"{label} [J]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        save(fig, os.path.join(d, f"{key}.png"))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    cR = None
    for r, case, name in zip(runs, loaded, cases):
        path = os.path.join(r, "crack_tip.csv")
        if not os.path.isfile(path):
            continue
        rows = tip_parts(read_csv(path))
        title = case.get("case", {}).get("title", name)
        color = None
        for b, part in sorted(rows.items()):
            # Jumps (the crack joining bars broken ahead of it) are not a tip speed.
            v = [float(x["speed"]) if x.get("jump", "0") == "0" else float("nan") for x in part]
            line, = ax.plot([float(x["time"]) * us for x in part], v, lw=1, color=color,
                            ls="-" if b == 0 else "--", label=title if b == 0 else None)
            color = line.get_color()
        an = crack_analysis(r)
        cR = an["rayleigh_speed_m_s"] if an else cR
    if cR:
        ax.axhline(cR, color="tab:red", ls="--", lw=1, label=f"Rayleigh speed {cR:.0f} m/s")
    ax.set_xlabel("time [us]")
    ax.set_ylabel("crack tip speed [m/s]")
    ax.set_title("run 0 of each case: trunk solid, branches dashed, jumps left out", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    save(fig, os.path.join(d, "crack_speed.png"))


def energy_png(d):
    rows = read_csv(os.path.join(d, "energy.csv"))
    t = [float(r["time"]) for r in rows]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 6.5), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 1]})
    labels = {"external_work": "external work", "elastic": "elastic", "kinetic": "kinetic",
              "damage_dissipated": "damage", "damping_dissipated": "damping"}
    # The fatigue law's column: the energy bars held when their fatigue life ran out.
    fatigue = "fatigue_dissipated" in rows[0]
    if fatigue:
        labels["fatigue_dissipated"] = "fatigue"
    # Platens' columns: their springs' energy and their friction's dissipation.
    platens = "contact_energy" in rows[0]
    if platens:
        labels["contact_energy"] = "contact"
        labels["friction_dissipated"] = "friction"
    for key, lab in labels.items():
        ax.plot(t, [float(r[key]) for r in rows], label=lab)
    held = [k for k in labels if k != "external_work"]
    total = [sum(float(r[k]) for k in held) for r in rows]
    ax.plot(t, total, "k--", lw=0.8,
            label=" + ".join(labels[k] for k in held))
    ax.set_ylabel("energy [J]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax2.semilogy(t, [max(float(r["balance_error"]), 1e-16) for r in rows], "k-", lw=0.8)
    ax2.set_ylabel("relative\nbalance error")
    ax2.set_title("|W + E0 - (U + K + D + Dc{}{})| / (W + E0)".format(
        " + F" if fatigue else "", " + Ec + Df" if platens else ""),
                  fontsize=8)
    ax2.set_xlabel("time [s]")
    ax2.grid(alpha=0.3)
    save(fig, os.path.join(d, "energy.png"))


def probes_png(d, case):
    """probes.png: each probe's column of probes.csv against time, one panel per probe."""
    path = os.path.join(d, "probes.csv")
    if not os.path.isfile(path):
        return
    rows = read_csv(path)
    if not rows:
        return
    names = [k for k in rows[0] if k != "time"]
    if not names:
        return
    kinds = {p["name"]: p.get("kind", "") for p in case.get("probe", [])}
    unit = {"reaction": "N", "load": "N", "bar_force": "N", "displacement": "m", "opening": "m",
            "strain": "-", "platen": "N", "platen_displacement": "m"}
    t = [float(r["time"]) * 1e3 for r in rows]
    fig, axes = plt.subplots(len(names), 1, figsize=(7, 1.2 + 1.8 * len(names)), sharex=True,
                             squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        ax.plot(t, [float(r[name]) for r in rows], "k-", lw=0.9)
        ax.set_ylabel(f"{name} [{unit.get(kinds.get(name), '')}]")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [ms]")
    axes[0, 0].set_title(case.get("case", {}).get("title", ""), fontsize=9)
    save(fig, os.path.join(d, "probes.png"))
    # A laboratory's curve: the first force probe against the first gauge (load-CMOD,
    # load-deflection, stress-strain), in response.png.
    forces = [n for n in names if kinds.get(n) in ("reaction", "load", "platen")]
    gauges = [n for n in names if kinds.get(n) in ("opening", "displacement", "strain",
                                                    "platen_displacement")]
    if forces and gauges:
        f, g = forces[0], gauges[0]
        scale, gunit = (1e3, "mm") if kinds[g] != "strain" else (1e6, "1e-6")
        fig, ax = plt.subplots(figsize=(6, 4.2))
        ax.plot([float(r[g]) * scale for r in rows], [float(r[f]) for r in rows], "k-", lw=0.9)
        ax.set_xlabel(f"{g} [{gunit}]")
        ax.set_ylabel(f"{f} [N]")
        ax.grid(alpha=0.3)
        ax.set_title(case.get("case", {}).get("title", ""), fontsize=9)
        save(fig, os.path.join(d, "response.png"))


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
    from matplotlib.ticker import MaxNLocator
    units = {"E": " [Pa]", "Gf": " [N/m]", "e_p": "", "e_r": " (normal and diagonal bars)"}
    bins = 60
    for row_axes, p in zip(axes, props):
        vals = [float(r[p]) for r in rows]
        h = row_axes[0]
        # The share of the bars in each bin (they add up to 1), and the target's share per bin.
        h.hist(vals, bins=bins, weights=[1.0 / len(vals)] * len(vals), color="0.6", label="bars")
        spec = case.get("fields", {}).get(p)
        if spec and spec.get("kind") == "weibull":
            g, lam = spec["shape"], spec["scale"]
            lo, hi = min(vals), max(vals)
            width = (hi - lo) / bins
            xs = [lo + (hi - lo) * i / 200 for i in range(201)]
            ys = [width * g / lam * (x / lam) ** (g - 1) * math.exp(-((x / lam) ** g)) for x in xs]
            h.plot(xs, ys, "r-", lw=1.2, label=f"Weibull target (shape {g:.3g})")
            h.legend(fontsize=8)
        h.set_xlabel(f"{p}{units[p]}")
        h.set_ylabel("share of the bars per bin")
        # A few ticks, in scientific notation for small strains, so that the labels never meet.
        h.xaxis.set_major_locator(MaxNLocator(5))
        h.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
        m = row_axes[1]
        sc = m.scatter([float(r["xyz"[a]]) * 1e3 for r in rows],
                       [float(r["xyz"[b]]) * 1e3 for r in rows], c=vals, s=2, lw=0, cmap="viridis")
        bar = fig.colorbar(sc, ax=m, label=p)
        bar.formatter.set_powerlimits((-3, 4))
        bar.update_ticks()
        m.set_aspect("equal")
        m.set_xlabel(f"{'xyz'[a]} [mm]")
        m.set_ylabel(f"{'xyz'[b]} [mm]")
    fig.suptitle("material fields per bar", fontsize=11)
    save(fig, os.path.join(d, "fields.png"))


def fatigue_analysis(d):
    path = os.path.join(d, "summary.json")
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return json.load(f).get("analysis", {}).get("fatigue")


def fatigue_pngs(d, case):
    fa = fatigue_analysis(d)
    if not fa or not os.path.isfile(os.path.join(d, "fatigue_front.csv")):
        return
    import math
    tmax = fa["tmax_s"]
    t_const = fa["constant_amplitude_from_s"]
    f_load = fa["load_frequency_hz"]
    marks = [(fa.get("subcritical_start_t_over_tmax"), "subcritical start", "tab:green"),
             (t_const / tmax, "constant amplitude", "0.4"),
             (fa.get("unstable_t_over_tmax"), "unstable", "tab:red")]

    def mark(ax, scale=1.0, vertical=True):
        for v, lab, col in marks:
            if v is not None and 0 <= v <= 1:
                (ax.axvline if vertical else ax.axhline)(v * scale, color=col, ls=":", lw=1,
                                                         label=lab)

    # Loading history and probes (the paper's figure 6, right).
    probes = read_csv(os.path.join(d, "probes.csv")) if os.path.isfile(
        os.path.join(d, "probes.csv")) else []
    if probes:
        n = case["lattice"]["modules"]
        L = case["lattice"]["L"]
        ext = [n[i] * L for i in range(3)]
        fig, ax = plt.subplots(figsize=(8, 4))
        ax2 = ax.twinx()
        t = [float(r["time"]) / tmax for r in probes]
        loads = {ld["name"]: ld for ld in case.get("load", [])}
        for pr in case.get("probe", []):
            col = pr["name"]
            if col not in probes[0]:
                continue
            vals = [float(r[col]) for r in probes]
            if pr["kind"] == "load" and pr.get("load") in loads:
                ld = loads[pr["load"]]
                force = next(ld[k] for k in ("force", "traction", "total", "acceleration")
                             if k in ld)  # its direction
                axis = max(range(3), key=lambda k: abs(force[k]))
                section = math.prod(ext[k] for k in range(3) if k != axis)
                ax.plot(t, [abs(v) / section / 1e6 for v in vals], lw=0.5, color="tab:blue",
                        label=f"remote stress ({pr['load']})")
            elif pr["kind"] == "bar_force":
                ax2.plot(t, vals, lw=0.5, color="tab:orange", label=f"bar force ({col})")
        mark(ax)
        ax.set_xlabel("t / tmax")
        ax.set_ylabel("remote stress [MPa]")
        ax2.set_ylabel("bar force [N]")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="lower right")
        ax.set_title(f"cyclic load at {f_load:g} Hz and the probed bar", fontsize=10)
        save(fig, os.path.join(d, "fatigue_load.png"))

    # Time against x of first softening (e_p) and rupture (e_r), with the front (figure 8 left).
    n = case["lattice"]["modules"]
    L = case["lattice"]["L"]
    ext = [n[i] * L for i in range(3)]
    a_ax, b_ax = sorted(sorted(range(3), key=lambda i: -ext[i])[:2])
    events = read_csv(os.path.join(d, "events.csv"))
    soft = [(float(r["xyz"[a_ax]]), float(r["time"]) / tmax) for r in events
            if r["event"] == "softening"]
    brk = [(float(r["xyz"[a_ax]]), float(r["time"]) / tmax) for r in events
           if r["event"] == "broken"]
    front = read_csv(os.path.join(d, "fatigue_front.csv"))
    fig, ax = plt.subplots(figsize=(7, 5))
    if soft:
        ax.scatter(*zip(*soft), s=2, lw=0, c="tab:red", label="reaches e_p")
    if brk:
        ax.scatter(*zip(*brk), s=2, lw=0, c="tab:blue", label="breaks (e_r, or its fatigue life)")
    if front:
        xs, ts = [fa["precrack_length_m"]], [float(front[0]["t"]) / tmax]
        for r in front:
            xs += [xs[-1], float(r["a"])]
            ts += [float(r["t"]) / tmax, float(r["t"]) / tmax]
        xs.append(xs[-1])
        ts.append(1.0)  # the front holds until the run's end
        ax.plot(xs, ts, "-", color="tab:green", lw=1.5, label="damage front a(t)")
    mark(ax, vertical=False)
    ax.set_xlabel("x of the bar's centre [m]")
    ax.set_ylabel("t / tmax")
    ax.set_xlim(0, ext[a_ax])
    ax.legend(fontsize=7, markerscale=4, loc="lower right")
    ax.set_title("when each bar softens and breaks (bars within the band around the crack "
                 "plane make the front)", fontsize=9)
    save(fig, os.path.join(d, "fatigue_front.png"))

    # Crack configurations at six moments (figure 7 left).
    t0 = fa.get("subcritical_start_t_over_tmax") or t_const / tmax
    t1 = fa.get("unstable_t_over_tmax")
    moments = ([t0 + (t1 - t0) * k / 4 for k in range(5)] + [1.0] if t1 is not None
               else [t0 + (1.0 - t0) * k / 5 for k in range(6)])
    fig, axes = plt.subplots(3, 2, figsize=(10, 10 * ext[b_ax] / ext[a_ax] * 3 / 2 + 1))
    for ax, tm in zip(axes.flat, moments):
        s_pts, b_pts = {}, {}
        for r in events:
            if float(r["time"]) / tmax <= tm:
                p = (float(r["xyz"[a_ax]]), float(r["xyz"[b_ax]]))
                (s_pts if r["event"] == "softening" else b_pts)[r["bar"]] = p
        for bar in b_pts:
            s_pts.pop(bar, None)
        ax.add_patch(plt.Rectangle((0, 0), ext[a_ax], ext[b_ax], fill=False, lw=0.8,
                                   color="0.3"))
        if s_pts:
            ax.scatter(*zip(*s_pts.values()), s=2, lw=0, c="0.6")
        if b_pts:
            ax.scatter(*zip(*b_pts.values()), s=3, lw=0, c="k")
        ax.set_xlim(0, ext[a_ax])
        ax.set_ylim(0, ext[b_ax])
        ax.set_aspect("equal")
        ax.set_title(f"t / tmax = {tm:.3f}: {len(s_pts)} softening, {len(b_pts)} broken",
                     fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle("damage during the growth (grey: softening bars, black: broken)", fontsize=10)
    save(fig, os.path.join(d, "fatigue_cracks.png"))

    # a against N, and the Paris plot (figure 8 right).
    rows = read_csv(os.path.join(d, "fatigue.csv"))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    Ns, As = [], []
    for r in front:
        Ns += [float(r["N"])] * 2
        As += [As[-1] if As else fa["precrack_length_m"], float(r["a"])]
    if Ns:
        Ns.append((tmax - t_const) * f_load)  # the front holds until the run's end
        As.append(As[-1])
        ax.plot(Ns, As, "-", color="tab:green", lw=1, label="damage front")
    if rows:
        ax.plot([float(r["N"]) for r in rows], [float(r["a"]) for r in rows], "o",
                color="k", ms=4, label="interval midpoints of the representative points")
    ax.axvline(0.0, color="0.4", ls=":", lw=1, label="constant amplitude (N = 0)")
    if fa.get("cycles_to_failure") is not None:
        ax.axvline(fa["cycles_to_failure"], color="tab:red", ls=":", lw=1, label="unstable")
    ax.set_xlabel("N (cycles at constant amplitude)")
    ax.set_ylabel("a [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    save(fig, os.path.join(d, "fatigue_aN.png"))

    fig, ax = plt.subplots(figsize=(6, 4.5))
    pts = [(float(r["delta_K"]), float(r["da_dN"])) for r in rows
           if float(r["da_dN"]) > 0 and math.isfinite(float(r["delta_K"]))]
    if pts:
        ax.loglog([p[0] for p in pts], [p[1] * 1e6 for p in pts], "o", color="k", ms=5,
                  label="intervals between representative points")
    if fa.get("paris_m") is not None and pts:
        C, m = fa["paris_C"], fa["paris_m"]
        lo, hi = min(p[0] for p in pts), max(p[0] for p in pts)
        xs = [lo * (hi / lo) ** (i / 50) for i in range(51)]
        ci = fa["paris_m_interval"]
        ax.loglog(xs, [C * x ** m * 1e6 for x in xs], "-", color="tab:red",
                  label=f"da/dN = {C:.3g} DK^{m:.3g}  (R2 = {fa['paris_r2']:.3f}, "
                  f"m in [{ci[0]:.2g}, {ci[1]:.2g}])")
    ax.set_xlabel("Delta K [Pa m^0.5]")
    ax.set_ylabel("da/dN [um / cycle]")
    ax.grid(alpha=0.3, which="both")
    if pts:
        ax.legend(fontsize=7)
    else:
        ax.text(0.5, 0.5, fa.get("note", ""), ha="center", va="center", wrap=True, fontsize=8,
                transform=ax.transAxes)
    ax.set_title("Paris law (Pa, m)" + ("" if pts else ": no growth to fit"), fontsize=10)
    save(fig, os.path.join(d, "fatigue_paris.png"))


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--ensemble":
        ensemble(sys.argv[2])
        return
    args = sys.argv[1:]
    options = {}
    while len(args) >= 2 and args[0] in ("--view", "--slice"):
        options[args[0]] = args[1]
        args = args[2:]
    if len(args) != 1:
        sys.exit(__doc__)
    d = args[0]
    with open(os.path.join(d, "case.resolved.toml"), "rb") as f:
        case = tomllib.load(f)
    view = parse_view(options["--view"]) if "--view" in options else None
    cut = parse_slice(options["--slice"], case) if "--slice" in options else None
    crack_png(d, case, view, cut)
    energy_png(d)
    probes_png(d, case)
    fields_png(d, case)
    crack_speed_png(d)
    fatigue_pngs(d, case)


if __name__ == "__main__":
    main()
