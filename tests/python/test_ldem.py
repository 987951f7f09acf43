"""The Python module against the command line and against theory (run by CTest: python_module).

Environment: PYTHONPATH holds the built package, LDEM the command-line binary, LDEM_SOURCE_DIR
the source tree.
"""

import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import ldem

LDEM = os.environ["LDEM"]
SOURCE = Path(os.environ["LDEM_SOURCE_DIR"])
TUTORIAL = SOURCE / "cases" / "tutorial" / "notched_plate.toml"


def cli_run(case: Path, out: Path, *extra: str) -> None:
    subprocess.run([LDEM, "run", str(case), "--out", str(out), "--threads", "1", "--no-plot",
                    *extra], check=True, capture_output=True)


def short_tutorial(tmp_path: Path, end: float, every: int, vtu: bool = False) -> Path:
    """The tutorial plate with its own end and report interval, as a file."""
    d = ldem.load_case(TUTORIAL).to_dict()
    d["time"]["end"] = end
    d["output"]["energy_every"] = every
    d["output"]["vtu"] = vtu
    if vtu:
        d["output"]["vtu_every"] = 10**9  # the first and the last state only
    p = tmp_path / "short.toml"
    p.write_text(ldem.to_toml(d))
    return p


@pytest.mark.parametrize("source", ["file", "dict"])
def test_run_writes_the_command_lines_bytes(tmp_path, source):
    # The whole tutorial run (bars break: events.csv has rows) on one thread, from the file and
    # from the same case as a dict: energy.csv, events.csv and probes.csv are the CLI's bytes.
    cli_run(TUTORIAL, tmp_path / "cli")
    case = TUTORIAL if source == "file" else ldem.load_case(TUTORIAL).to_dict()
    summary = ldem.run(case, out=tmp_path / "py", threads=1, plots=False)
    assert summary["steps"] > 0 and summary["broken_bars_at_end"] > 0
    for name in ("energy.csv", "events.csv", "probes.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    if source == "dict":  # the case the run was given is in its folder, and names it
        assert (tmp_path / "py" / "case.toml").exists()
        assert summary["case"] == str((tmp_path / "py" / "case.toml").resolve())


def test_a_run_from_a_dict_can_be_resumed_to_a_later_end(tmp_path):
    # A case without a file: the run keeps it as case.toml, from which a resume goes on; the
    # resumed run's energy.csv is the one of a run straight to the later end.
    d = ldem.load_case(TUTORIAL).to_dict()
    d["time"]["end"] = 1.0e-3
    ldem.run(d, out=tmp_path / "a", threads=1, plots=False)
    s = ldem.resume(tmp_path / "a", end=2.0e-3, threads=1, plots=False)
    assert s["end_time"] == pytest.approx(2.0e-3, abs=s["dt"])
    d["time"]["end"] = 2.0e-3
    ldem.run(d, out=tmp_path / "b", threads=1, plots=False)
    assert (tmp_path / "a" / "energy.csv").read_bytes() == (tmp_path / "b" / "energy.csv").read_bytes()


def test_simulation_steps_as_the_command_line_does(tmp_path):
    # 400 steps reported at every step by the CLI; the Simulation's report after k steps is the
    # state at the start of its last step, t = (k - 1) dt: row k - 1 of energy.csv, written with
    # 9 significant digits. The displacements after 400 steps are the last snapshot's (which
    # stores Float32: the same doubles give the same floats).
    case = short_tutorial(tmp_path, end=1.0e-5, every=1, vtu=True)
    dt = ldem.Simulation(case, threads=1).dt
    d = ldem.load_case(case).to_dict()
    d["time"]["end"] = 400 * dt
    case.write_text(ldem.to_toml(d))
    cli_run(case, tmp_path / "cli")
    energy = ldem.read_energy(tmp_path / "cli")
    probes = ldem.read_probes(tmp_path / "cli")
    sim = ldem.Simulation(case, threads=1)
    done = 0
    for k in (1, 37, 200, 400):
        sim.step(k - done)
        done = k
        e = sim.energies
        row = k - 1
        assert f"{e['time']:.9g}" == f"{energy['time'][row]:.9g}"
        for col in ("external_work", "elastic", "kinetic", "damping_dissipated"):
            assert f"{e[col]:.9g}" == f"{energy[col][row]:.9g}", (k, col)
        for name, value in sim.probes.items():
            assert f"{value:.9g}" == f"{probes[name][row]:.9g}", (k, name)
    assert sim.step_count == 400 and sim.time == pytest.approx(400 * sim.dt, rel=1e-15)
    snapshots = ldem.read_snapshots(tmp_path / "cli")
    last = ldem.read_vtu(snapshots[-1][1])
    assert snapshots[-1][0] == pytest.approx(sim.time, rel=1e-12)
    present = sim.node_present
    np.testing.assert_array_equal(last["displacement"],
                                  sim.displacement[present].astype(np.float32))
    np.testing.assert_array_equal(last["points"],
                                  sim.reference_positions[present].astype(np.float32))


def test_views_have_the_bodys_shapes_and_follow_its_state(tmp_path):
    sim = ldem.Simulation(TUTORIAL, threads=1)
    nx, ny, nz = sim.modules
    nodes = (nx + 1) * (ny + 1) * (nz + 1) + nx * ny * nz  # corners and module centres
    bars = sim.bar_nodes.shape[0]
    assert sim.displacement.shape == (nodes, 3) and sim.velocity.shape == (nodes, 3)
    assert sim.reference_positions.shape == (nodes, 3)
    for name in ("strain", "damage", "state", "force"):
        assert getattr(sim, name).shape == (bars,), name
    # At rest: nothing moves or strains; the notch's bars are broken from the start.
    assert not sim.displacement.any() and not sim.strain.any()
    assert (sim.state == 2).sum() > 0
    # The reference positions span the plate: 40 x 20 modules of 5 mm in x and z.
    x = sim.reference_positions
    assert x[:, 0].max() == pytest.approx(nx * sim.L) and x[:, 2].max() == pytest.approx(nz * sim.L)
    before = sim.displacement
    sim.step(300)
    after = sim.displacement
    assert not before.any() and after.any()  # an earlier array keeps its values
    assert sim.strain.max() > 0 and sim.velocity.any()
    with pytest.raises(ValueError):
        after[0, 0] = 1.0  # read-only
    # Each bar's strain is (l - l0) / l0 from its nodes' displacements, l = |(x_b - x_a) +
    # (u_b - u_a)|. Both sides round l at about eps l0 (eps = 2.2e-16) and the reference vectors
    # at eps |x| (|x| up to 40 l0 here): a few times 1e-15 of strain, against strains of 1e-6.
    a, b = sim.bar_nodes[:, 0], sim.bar_nodes[:, 1]
    l0 = np.linalg.norm(x[b] - x[a], axis=1)
    l = np.linalg.norm((x[b] - x[a]) + (after[b] - after[a]), axis=1)
    np.testing.assert_allclose(sim.strain, (l - l0) / l0, rtol=0, atol=1e-14)
    assert np.abs(sim.strain).max() > 1e-7


def test_bad_input_raises_case_error_with_file_line_and_key(tmp_path):
    with pytest.raises(ldem.CaseError) as e:
        ldem.load_case("[lattice]\nmodules = [4, 4, 4]\nL = -1.0\n")
    assert e.value.file == "<string>" and e.value.line == 3 and e.value.key == "lattice.L"
    assert "expected" in str(e.value) and "got -1" in str(e.value)
    bad = tmp_path / "bad.toml"
    bad.write_text(TUTORIAL.read_text().replace("damping = 200.0", "dampin = 200.0"))
    with pytest.raises(ldem.CaseError) as e:
        ldem.load_case(bad)
    assert e.value.file == str(bad) and e.value.key == "time.dampin"
    assert "damping" in e.value.message  # the suggestion
    with pytest.raises(ldem.CaseError):
        ldem.load_case(tmp_path / "missing.toml")
    with pytest.raises(ldem.CaseError) as e:  # a dict: its name in messages
        d = ldem.load_case(TUTORIAL).to_dict()
        d["velocity"][0]["set"] = "nowhere"
        ldem.load_case(d)
    assert e.value.file == "<dict>" and "nowhere" in str(e.value)
    with pytest.raises(ldem.CaseError):  # a run into a folder that holds results
        (tmp_path / "full").mkdir()
        (tmp_path / "full" / "x").write_text("x")
        ldem.run(TUTORIAL, out=tmp_path / "full", threads=1, plots=False)


FREE_CUBE = {
    "lattice": {"modules": [2, 2, 2], "L": 0.01},
    "material": {"E": 30.0e9, "rho": 2400.0, "Gf": 100.0, "e_p": 1.0e-4},
    "node_set": [{"name": "all", "all": True}, {"name": "top", "face": "z+"}],
    "load": [{"name": "gravity", "set": "all", "acceleration": [0.0, 0.0, -9.81]}],
    "probe": [{"name": "weight", "kind": "load", "load": "gravity"}],
    "time": {"end": 1.0e-3},
    "output": {"vtu": False, "plots": False},
}


def test_a_load_factor_scales_the_load_from_the_next_step():
    # A free body under a uniform acceleration a moves as a rigid body (no bar strains): by
    # central differences v_{k+1/2} = v_{k-1/2} + dt a_k and u_{k+1} = u_k + dt v_{k+1/2} at
    # every node. With the factor 2 from step m on, a_k = 2 a for k >= m. The load probe (the
    # load's total, m_total a) doubles too.
    sim = ldem.Simulation(FREE_CUBE, threads=1)
    dt, a, m = sim.dt, -9.81, 20
    sim.step(m)
    w1 = sim.probes["weight"]
    sim.set_load("gravity", 2.0)
    assert sim.load_factor("gravity") == 2.0
    sim.step(30)
    u = v = 0.0
    for k in range(m + 30):
        v += dt * (a if k < m else 2 * a)
        u += dt * v
    # The step rounds each bar's length at eps l0 (eps = 2.2e-16, l0 = 1 cm: 2e-18 m), and the
    # forces of that rounding move the nodes by a few times as much: 50 eps L = 1.1e-16 m,
    # against a displacement of 3.4e-8 m; the velocities by that over dt.
    noise = 50 * 2.2e-16 * 0.01
    np.testing.assert_allclose(sim.displacement[:, 2], u, rtol=0, atol=noise)
    np.testing.assert_allclose(sim.velocity[:, 2], v, rtol=0, atol=noise / dt)
    assert abs(u) > 1e8 * noise
    assert np.abs(sim.strain).max() < 1e-12
    assert sim.probes["weight"] == pytest.approx(2 * w1, rel=1e-15)
    # The total weight, along the load's direction: rho V g on the cube of 2 cm.
    assert w1 == pytest.approx(2400.0 * (0.02**3) * 9.81, rel=1e-12)


def test_a_velocity_factor_holds_and_reverses_a_set():
    # A displacement-controlled pull with unloading: the top face driven at 1 mm/s, then held
    # (factor 0: its displacement stays), then reversed (factor -1: it comes back at the same
    # rate, dt v per step).
    d = dict(FREE_CUBE)
    d.pop("load")
    d.pop("probe")
    d["fixed"] = [{"set": "bottom", "dofs": "xyz"}]
    d["node_set"] = FREE_CUBE["node_set"] + [{"name": "bottom", "face": "z-"}]
    d["velocity"] = [{"set": "top", "dofs": "z", "value": [0.0, 0.0, 1.0e-3]}]
    sim = ldem.Simulation(d, threads=1)
    top = np.isclose(sim.reference_positions[:, 2], 0.02) & sim.node_present
    sim.step(40)
    up = sim.displacement[top, 2]
    np.testing.assert_allclose(up, 40 * sim.dt * 1.0e-3, rtol=1e-12)
    sim.set_velocity("top", 0.0)
    sim.step(25)
    np.testing.assert_array_equal(sim.displacement[top, 2], up)
    sim.set_velocity(0, -1.0)
    sim.step(40)
    np.testing.assert_allclose(sim.displacement[top, 2], 0.0, atol=1e-18)
    with pytest.raises(ldem.CaseError):
        sim.set_velocity(3, 1.0)
    with pytest.raises(ldem.CaseError):
        sim.set_velocity("nowhere", 1.0)


def test_readers_give_the_folders_tables(tmp_path):
    case = short_tutorial(tmp_path, end=1.0e-3, every=50, vtu=True)
    ldem.run(case, out=tmp_path / "r", threads=1, plots=False)
    e = ldem.read_energy(tmp_path / "r")
    assert e["time"].dtype == np.float64 and len(e["time"]) > 10
    # The columns are the ledger's: where bars break (balance error above 1e-4), the error
    # column is |W - (U + K + D + Dd)| / W from the other columns, to their 9 digits (the
    # difference of numbers of 1e-2 J known to 1e-11 J, over errors of 1e-6 J or more).
    lhs = e["external_work"]
    rhs = e["elastic"] + e["kinetic"] + e["damage_dissipated"] + e["damping_dissipated"]
    late = e["balance_error"] > 1e-4
    assert late.sum() > 3
    np.testing.assert_allclose(np.abs(lhs - rhs)[late] / lhs[late], e["balance_error"][late],
                               rtol=1e-3)
    p = ldem.read_probes(tmp_path / "r")
    assert set(p) >= {"time", "pull_force", "notch_opening"}
    s = ldem.read_summary(tmp_path / "r")
    assert s["steps"] > 0
    snaps = ldem.read_snapshots(tmp_path / "r")
    v = ldem.read_vtu(snaps[-1][1])
    assert v["points"].shape[1] == 3 and v["displacement"].shape == v["points"].shape


INTERRUPTED = r'''
import sys, time, ldem
d = ldem.load_case(sys.argv[1]).to_dict()
d["time"]["end"] = 10.0  # far beyond what runs before the signal
print("ready", flush=True)
try:
    if sys.argv[3] == "run":
        ldem.run(d, out=sys.argv[2], threads=1, plots=False)
    else:
        sim = ldem.Simulation(d, threads=1)
        sim.step(10**9)
except KeyboardInterrupt as e:
    print("interrupted:", sim.step_count if sys.argv[3] == "sim" else e, flush=True)
    sys.exit(0)
print("not interrupted", flush=True)
sys.exit(1)
'''


@pytest.mark.parametrize("what", ["run", "sim"])
def test_ctrl_c_stops_cleanly(tmp_path, what):
    # SIGINT 1.5 s after start: ldem.run stops between steps with a checkpoint and its summary
    # says so; Simulation.step stops between steps; both raise KeyboardInterrupt.
    import signal
    import time
    p = subprocess.Popen([os.environ.get("PYTHON", "/usr/bin/python3"), "-c", INTERRUPTED,
                          str(TUTORIAL), str(tmp_path / "out"), what],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "ready"
    time.sleep(1.5)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 0, err
    assert out.startswith("interrupted:")
    if what == "run":
        assert "ldem.resume" in out
        assert (tmp_path / "out" / "checkpoint" / "state.ckpt").exists()
        assert ldem.read_summary(tmp_path / "out")["interrupted"] is True
    else:
        assert int(out.split()[1]) > 0


def test_the_size_effect_example_coarsened(tmp_path):
    # docs/examples/size_effect.py on its two smallest sizes, two seeds each: geometrically
    # similar notched plates are weaker the larger they are (Bazant's law, sigma_N decreasing
    # in D for any finite D0), in the mean over the seeds; the fit finds B f_t and D0 > 0.
    script = SOURCE / "docs" / "examples" / "size_effect.py"
    r = subprocess.run([os.environ.get("PYTHON", "/usr/bin/python3"), str(script), "--sizes",
                        "20", "40", "--seeds", "2", "--threads", "1", "--no-plot", "--out",
                        str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    t = ldem.read_table(tmp_path / "size_effect.csv")
    assert len(t["seed"]) == 4
    small = t["sigma_N_Pa"][t["W_modules"] == 20].mean()
    large = t["sigma_N_Pa"][t["W_modules"] == 40].mean()
    assert large < small
    assert "Bazant's law: B f_t = " in r.stdout


def test_read_vtu_reads_compressed_snapshots_as_raw_ones(tmp_path):
    # The same run with raw and with zlib-compressed snapshots: every array of the last
    # snapshot read back equal, bit for bit (compression is lossless).
    case = short_tutorial(tmp_path, end=2.0e-4, every=50, vtu=True)
    d = ldem.load_case(case).to_dict()
    ldem.run(d, out=tmp_path / "raw", threads=1, plots=False)
    d["output"]["vtu_compression"] = "zlib"
    ldem.run(d, out=tmp_path / "zlib", threads=1, plots=False)
    raw = ldem.read_vtu(ldem.read_snapshots(tmp_path / "raw")[-1][1])
    packed = ldem.read_vtu(ldem.read_snapshots(tmp_path / "zlib")[-1][1])
    assert raw.keys() == packed.keys() and {"points", "displacement", "damage"} <= raw.keys()
    for k in raw:
        np.testing.assert_array_equal(raw[k], packed[k], err_msg=k)
    assert np.abs(raw["displacement"]).max() > 0


def test_run_until_stops_at_the_first_step_at_or_after_the_time():
    sim = ldem.Simulation(TUTORIAL, threads=1)
    sim.run_until(1.0e-4)
    assert 1.0e-4 <= sim.time < 1.0e-4 + sim.dt
    n = sim.step_count
    sim.run_until(0.5e-4)  # already past: no step
    assert sim.step_count == n
