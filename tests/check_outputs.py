#!/usr/bin/env python3
"""Checks an ldem output folder against the output contract, reading the ParaView files with
VTK's own readers (Debian's python3-vtk9), not with ldem's code.

usage: check_outputs.py DIR     exits non-zero with a message on the first violation
"""
import csv
import json
import math
import os
import sys
import tomllib
import xml.etree.ElementTree as ET

import vtk
from vtk.util.numpy_support import vtk_to_numpy


def fail(msg):
    sys.exit("check_outputs: " + msg)


def main():
    d = sys.argv[1]
    for name in ["case.resolved.toml", "energy.csv", "events.csv", "probes.csv", "summary.json",
                 "lattice.pvd"]:
        if not os.path.isfile(os.path.join(d, name)):
            fail(f"{name} missing")
    if [f for f in os.listdir(d) if f.endswith(".part")]:
        fail("a temporary .part file was left behind")
    with open(os.path.join(d, "case.resolved.toml"), "rb") as f:
        case = tomllib.load(f)
    res = case["resolved"]
    with open(os.path.join(d, "energy.csv")) as f:
        header = f.readline().strip()
        if header != ("time,external_work,elastic,kinetic,damage_dissipated,"
                      "damping_dissipated,balance_error"):
            fail(f"energy.csv header: {header}")
        rows = list(csv.reader(f))
    last = [float(v) for v in rows[-1]]
    if not last[0] > 0:
        fail("energy.csv: no time advanced")
    summary = json.load(open(os.path.join(d, "summary.json")))
    for key in ["nodes", "bars", "steps", "dt", "dt_stable", "wall_s", "bar_updates_per_s",
                "threads", "max_balance_error", "broken_bars_at_end", "softening_bars_at_end",
                "analysis"]:
        if key not in summary:
            fail(f"summary.json lacks {key}")
    # The run simulated the resolved case's steps, to the time of its last energy row and
    # snapshot (the step after the last report is not counted; dt is printed to 9 digits).
    if summary["steps"] != res["steps"]:
        fail(f"summary.json steps {summary['steps']}, the case's {res['steps']}")
    if not math.isclose(summary["end_time"], res["steps"] * summary["dt"], rel_tol=1e-8) or \
            not math.isclose(summary["end_time"], last[0], rel_tol=1e-8):
        fail(f"summary.json end_time {summary['end_time']}: expected {res['steps']} x dt = "
             f"the last energy row's time {last[0]}")
    if summary["max_balance_error"] > 0.01:
        fail(f"balance error {summary['max_balance_error']} above 1 %")
    # Every row's, the first (nothing put in yet) included: relative to the floor there.
    worst = max(float(r[-1]) for r in rows)
    if worst > 0.01:
        fail(f"energy.csv: a balance error of {worst:g} (relative), above 1 %")
    with open(os.path.join(d, "events.csv")) as f:
        if f.readline().strip() != "bar,event,time,x,y,z":
            fail("events.csv header")
        events = list(csv.reader(f))
    broken = {int(r[0]) for r in events if r[1] == "broken"}
    softened = {int(r[0]) for r in events if r[1] == "softening"}
    if not broken <= softened:
        fail("a bar broke without a softening event")
    with open(os.path.join(d, "probes.csv")) as f:
        ph = f.readline().strip().split(",")
    if ph != ["time"] + [p["name"] for p in case.get("probe", [])]:
        fail(f"probes.csv header {ph}")

    # The PVD collection (an XML list, parsed with the standard library; VTK's Python module has
    # no reader for it) and every snapshot it lists, read by VTK.
    root = ET.parse(os.path.join(d, "lattice.pvd")).getroot()
    if root.get("type") != "Collection":
        fail("lattice.pvd is not a VTK collection")
    sets = list(root.iter("DataSet"))
    times = [float(e.get("timestep")) for e in sets]
    if times != sorted(times):
        fail("lattice.pvd: time steps out of order")
    files = [e.get("file") for e in sets]
    reader = vtk.vtkXMLUnstructuredGridReader()
    if not files:
        fail("lattice.pvd lists no dataset")
    for name in files:
        reader.SetFileName(os.path.join(d, name))
        reader.Update()
        g = reader.GetOutput()
        if g.GetNumberOfPoints() != res["nodes"] or g.GetNumberOfCells() != res["bars"]:
            fail(f"{name}: {g.GetNumberOfPoints()} points, {g.GetNumberOfCells()} cells")
    if not math.isclose(times[-1], summary["end_time"], rel_tol=1e-8):
        fail(f"lattice.pvd: the last snapshot at t = {times[-1]}, the run ends at "
             f"{summary['end_time']}")
    g = reader.GetOutput()  # the last snapshot: the end of the run
    # The arrays it holds: those output.vtu_arrays chose (the material fields only where they
    # vary), besides a shaped body's node and bar numbers.
    held = {g.GetPointData().GetArrayName(i) for i in range(g.GetPointData().GetNumberOfArrays())}
    held |= {g.GetCellData().GetArrayName(i) for i in range(g.GetCellData().GetNumberOfArrays())}
    held -= {"node", "bar"}
    chosen = case.get("output", {}).get("vtu_arrays")
    if chosen is not None:
        fields = {"E", "Gf", "e_p", "e_r"}
        if not held <= set(chosen) or not set(chosen) - fields <= held:
            fail(f"the snapshot holds {sorted(held)}; output.vtu_arrays chose {chosen}")
    if "state" not in held or "displacement" not in held:
        print(f"check_outputs: {d}: {len(files)} snapshots read by VTK (arrays {sorted(held)}), "
              f"{len(rows)} energy rows: consistent")
        return
    state = vtk_to_numpy(g.GetCellData().GetArray("state"))
    # The last snapshot holds the states at the start of the last step; events that step's bar
    # pass found (at that same time) come after it.
    before = [r for r in events if float(r[2]) < times[-1] * (1.0 - 1e-8)]
    broken_then = {int(r[0]) for r in before if r[1] == "broken"}
    softened_then = {int(r[0]) for r in before if r[1] == "softening"}
    n_broken_vtu = int((state == 2).sum())
    expected = len(broken_then) + res["precracked_bars"]
    if n_broken_vtu != expected:
        fail(f"last snapshot has {n_broken_vtu} broken bars; events + pre-cracks give {expected}")
    if int((state >= 1).sum()) != len(softened_then | broken_then) + res["precracked_bars"]:
        fail("softening/broken states of the last snapshot disagree with events.csv")
    ids = g.GetCellData().GetArray("bar")
    if ids is not None:  # a shaped body: each cell's bar number in the body, as events.csv's
        ids = vtk_to_numpy(ids)
        if not (ids[1:] > ids[:-1]).all():
            fail("the snapshot's bar numbers are not in the body's order")
        if not broken_then <= set(int(b) for b in ids[state == 2]):
            fail("bars broken in events.csv are not broken in the last snapshot (bar numbers)")
        if g.GetPointData().GetArray("node") is None:
            fail("a shaped body's snapshot has bar numbers but no node numbers")
    # Broken bars: those broken during the run (events.csv); pre-cracked ones apart.
    if summary["broken_bars_at_end"] != len(broken) or \
            summary["precracked_bars"] != res["precracked_bars"]:
        fail(f"summary.json counts {summary['broken_bars_at_end']} broken and "
             f"{summary['precracked_bars']} pre-cracked bars; events.csv has {len(broken)} "
             f"ruptures, the case {res['precracked_bars']} pre-cracked bars")
    disp = vtk_to_numpy(g.GetPointData().GetArray("displacement"))
    if disp.shape != (res["nodes"], 3) or not math.isfinite(float(abs(disp).max())):
        fail("displacement array")
    # Each bar's strain is (l - l0) / l0 from its nodes' positions and displacements (both
    # written in single precision: the relative error of the recomputed strain is about 1e-7 of
    # the displacements' scale over the bar's length).
    pts = vtk_to_numpy(g.GetPoints().GetData()).astype("float64")
    conn = vtk_to_numpy(g.GetCells().GetConnectivityArray()).reshape(-1, 2)
    d0 = pts[conn[:, 1]] - pts[conn[:, 0]]
    du = disp[conn[:, 1]].astype("float64") - disp[conn[:, 0]].astype("float64")
    l0 = (d0 ** 2).sum(axis=1) ** 0.5
    strain = (((d0 + du) ** 2).sum(axis=1) ** 0.5 - l0) / l0
    written = vtk_to_numpy(g.GetCellData().GetArray("strain")).astype("float64") \
        if "strain" in held else strain
    scale = float(abs(disp).max()) / float(l0.min())
    worst = float(abs(written - strain).max())
    if worst > 1e-5 * scale + 1e-12:
        fail(f"strain array: differs from (l - l0) / l0 of the nodes by up to {worst:.3e} "
             f"(displacements / bar length up to {scale:.3e})")
    print(f"check_outputs: {d}: {len(files)} snapshots read by VTK, "
          f"{len(rows)} energy rows, {len(broken)} bars broken in the run, balance "
          f"{summary['max_balance_error']:.2e}: all consistent")


if __name__ == "__main__":
    main()
