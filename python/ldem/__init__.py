"""ldem from Python: cases, runs, simulations stepped from a script, and output folders as arrays.

    import ldem
    case = ldem.load_case("cases/fgm_plate/homogeneous.toml")
    summary = ldem.run(case, out="results/h", threads=2, plots=False)
    energy = ldem.read_energy("results/h")          # columns as numpy arrays

    sim = ldem.Simulation(case, threads=2)
    sim.step(100)
    u = sim.displacement                             # (nodes, 3) numpy array

Bad input raises ldem.CaseError, with the file, line and key that the command line prints.
The reference is docs/python.md.
"""

from __future__ import annotations

import json
import math
import os
import re
import tomllib
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from . import _core

__all__ = [
    "CaseError", "RunError", "Case", "load_case", "run", "resume", "Simulation", "Table",
    "read_table", "read_energy", "read_events", "read_probes", "read_crack_tip", "read_fatigue",
    "read_fatigue_front", "read_fields", "read_summary", "read_vtu", "read_snapshots",
    "read_body",
]


class CaseError(ValueError):
    """Bad input: a case that does not validate, or an argument ldem cannot honour.

    Attributes: ``file`` (the case file, ``"<string>"`` or ``"<dict>"``, or None), ``line``
    (int or None), ``key`` (``"time.end"``, ``"probe[1].name"``, or None) and ``message`` (what
    was expected and what was found). ``str(error)`` is the message the command line prints.
    """

    def __init__(self, text: str):
        super().__init__(text)
        self.file: str | None = None
        self.line: int | None = None
        self.key: str | None = None
        self.message = text
        m = re.match(r"^(?P<file>[^\n]*?):(?P<line>\d+): (?P<rest>.*)$", text, re.S)
        if m:
            self.file, self.line, rest = m["file"], int(m["line"]), m["rest"]
        else:
            m = re.match(r"^(?P<file>[^\n:]*\.toml|<string>|<dict>): (?P<rest>.*)$", text, re.S)
            rest = m["rest"] if m else text
            if m:
                self.file = m["file"]
        k = re.match(r"^(?P<key>[A-Za-z_][\w.\[\]-]*): ", rest)
        if k:
            self.key = k["key"]
        self.message = rest


class RunError(RuntimeError):
    """A run that ended without reaching its end: a numerical blow-up (exit code 3)."""


def _case_error(e: Exception) -> CaseError:
    return CaseError(str(e))


# --- cases -------------------------------------------------------------------------------

def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if math.isnan(f):
            return "nan"
        if math.isinf(f):
            return "inf" if f > 0 else "-inf"
        return repr(f)
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string: the same escapes
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"a case value must be a number, string, bool, list or dict, got {type(v)}")


def _toml_key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def to_toml(case: Mapping[str, Any]) -> str:
    """A case as a dict (tables as dicts, arrays of tables as lists of dicts) written as TOML."""
    out: list[str] = []
    for k, v in case.items():
        if not isinstance(v, Mapping) and not _is_table_array(v):
            out.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for k, v in case.items():
        if isinstance(v, Mapping):
            out.append(f"\n[{_toml_key(k)}]")
            out.extend(f"{_toml_key(a)} = {_toml_value(b)}" for a, b in v.items())
        elif _is_table_array(v):
            for t in v:
                out.append(f"\n[[{_toml_key(k)}]]")
                out.extend(f"{_toml_key(a)} = {_toml_value(b)}" for a, b in t.items())
    return "\n".join(out) + "\n"


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and len(v) > 0 and all(isinstance(t, Mapping) for t in v)


def _absolute_files(node: Any, base: Path) -> bool:
    """Makes the relative `file` of every shape under node absolute from base; True if any."""
    changed = False
    if isinstance(node, dict):
        f = node.get("file")
        if isinstance(f, str) and node.get("type") in ("npy", "stl") and not os.path.isabs(f):
            node["file"] = str((base / f).resolve())
            changed = True
        for v in node.values():
            changed |= _absolute_files(v, base)
    elif isinstance(node, list):
        for v in node:
            changed |= _absolute_files(v, base)
    return changed


class Case:
    """A validated case: its TOML text, the name it goes by in messages, and its file if any.

    Made by load_case(). ``to_dict()`` gives the case as nested dicts, to change and load again.
    """

    def __init__(self, text: str, name: str, path: str | None):
        self.text = text
        self.name = name
        self.path = path

    def to_dict(self) -> dict[str, Any]:
        return tomllib.loads(self.text)

    def __repr__(self) -> str:
        return f"ldem.Case({self.path or self.name!r})"


def load_case(case: str | os.PathLike | Mapping[str, Any] | Case) -> Case:
    """A case from a file path, a TOML string or a dict, validated as `ldem check` does.

    A string holding a newline or '=' is TOML text; any other string is a path. Text and dicts
    go by the names "<string>" and "<dict>" in errors; relative NumPy or STL file names in them
    are from the current folder. Raises CaseError for bad input (file, line and key).
    """
    if isinstance(case, Case):
        return case
    if isinstance(case, Mapping):
        d = json.loads(json.dumps(case, default=_json_default))  # a deep copy of plain values
        _absolute_files(d, Path.cwd())
        text, name, path = to_toml(d), "<dict>", None
    elif isinstance(case, os.PathLike) or ("\n" not in case and "=" not in case):
        path = str(case)
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as e:
            raise CaseError(f"{path}: cannot read the case file ({e.strerror})") from None
        name = path
    else:
        text, name, path = case, "<string>", None
        try:
            d = tomllib.loads(text)
        except tomllib.TOMLDecodeError:
            d = None  # the C++ reader says where
        if d is not None and _absolute_files(d, Path.cwd()):
            text = to_toml(d)
    try:
        _core.check_case(name, text)
    except _core.InputError as e:
        raise _case_error(e) from None
    return Case(text, name, path)


def _json_default(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, os.PathLike):
        return str(v)
    raise TypeError(f"a case value must be a number, string, bool, list or dict, got {type(v)}")


def _stopped(code: int, out: str) -> None:
    if code in (130, 143):
        raise KeyboardInterrupt(f"the run stopped with a checkpoint; go on with ldem.resume({out!r})")
    if code == 3:
        raise RunError(f"numerical blow-up (see the messages above); outputs in {out} up to the "
                       "last report")
    if code != 0:
        raise RunError(f"the run ended with exit code {code}")


def run(case, out: str | os.PathLike, threads: int = 0, plots: bool = True,
        force: bool = False) -> dict[str, Any]:
    """Runs a case as `ldem run CASE --out OUT` does, and returns its summary.json as a dict.

    threads: 0 takes OpenMP's default (OMP_NUM_THREADS, else all cores, shared with other ldem
    runs on the machine as the command line does). force: overwrite a folder's results. The GIL
    is released while the run steps; Ctrl-C stops it with a checkpoint and raises
    KeyboardInterrupt (resume() goes on). A case from text or a dict is written to OUT/case.toml,
    the file the summary names and a resume reads.
    """
    c = load_case(case)
    out = str(out)
    try:
        code = _core.run(c.path if c.path else c.name, None if c.path else c.text, out,
                         int(threads), bool(plots), bool(force))
    except _core.InputError as e:
        raise _case_error(e) from None
    _stopped(code, out)
    return read_summary(out)


def resume(out: str | os.PathLike, end: float | None = None, threads: int = 0,
           plots: bool = True) -> dict[str, Any]:
    """Continues the run in folder out from its checkpoint (`ldem resume OUT [--end T]`)."""
    out = str(out)
    try:
        code = _core.resume(out, int(threads), bool(plots), end)
    except _core.InputError as e:
        raise _case_error(e) from None
    _stopped(code, out)
    return read_summary(out)


# --- a simulation stepped from Python ---------------------------------------------------------

def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class Simulation:
    """A case's body in memory, stepped from Python: the same steps as `ldem run` takes.

    The state comes as numpy arrays in the body's node and bar numbers (docs/model.md): node
    arrays are (nodes, 3), bar arrays (bars,). They are read-only copies, made when asked
    (the step keeps its own padded layout), and stay as they were when the body steps on.
    No output files are written.
    """

    def __init__(self, case, threads: int = 0):
        c = load_case(case)
        self.case = c
        try:
            self._s = _core.Simulation(c.path if c.path else c.name, c.text, int(threads))
        except _core.InputError as e:
            raise _case_error(e) from None
        self._bars: tuple[int, dict[str, np.ndarray]] | None = None

    # progress
    def step(self, n: int = 1) -> "Simulation":
        """Takes n steps; the last reports (energies and probes at its start). Ctrl-C stops
        between steps with KeyboardInterrupt, the steps taken kept."""
        if n < 0:
            raise CaseError(f"step: expected a number of steps >= 0, got {n}")
        if n > 0:
            self._s.step(int(n))
        return self

    def run_until(self, t: float) -> "Simulation":
        """Steps until the time is at least t [s]."""
        n = math.ceil((t - self.time) / self.dt - 1e-9)
        return self.step(max(0, n))

    @property
    def time(self) -> float:
        """t_n = n dt [s], n the steps taken."""
        return self._s.time

    @property
    def step_count(self) -> int:
        return self._s.step_count

    @property
    def dt(self) -> float:
        return self._s.dt

    @property
    def modules(self) -> tuple[int, int, int]:
        return tuple(self._s.modules)

    @property
    def L(self) -> float:
        """The module's edge [m]."""
        return self._s.L

    # nodes
    @property
    def displacement(self) -> np.ndarray:
        """u_n, (nodes, 3) [m]."""
        return _readonly(self._s.displacement())

    @property
    def velocity(self) -> np.ndarray:
        """v_{n-1/2}, the central-difference velocity of the last step, (nodes, 3) [m/s]."""
        return _readonly(self._s.velocity())

    @property
    def reference_positions(self) -> np.ndarray:
        """The nodes' positions at rest, (nodes, 3) [m]."""
        return _readonly(self._s.reference_positions())

    @property
    def node_present(self) -> np.ndarray:
        """Whether each node belongs to the body (all True for a full box)."""
        return _readonly(self._s.node_present())

    # bars
    @property
    def bar_nodes(self) -> np.ndarray:
        """Each bar's two nodes, (bars, 2)."""
        return _readonly(self._s.bar_nodes())

    def _bar(self, name: str) -> np.ndarray:
        if self._bars is None or self._bars[0] != self.step_count:
            self._bars = (self.step_count, {k: _readonly(v) for k, v in self._s.bars().items()})
        return self._bars[1][name]

    @property
    def strain(self) -> np.ndarray:
        """Axial strain (l - l0) / l0 of each bar (0 for an absent bar)."""
        return self._bar("strain")

    @property
    def damage(self) -> np.ndarray:
        """Energy dissipated over Gf A^f (0 intact, 1 broken)."""
        return self._bar("damage")

    @property
    def state(self) -> np.ndarray:
        """0 intact, 1 softening, 2 broken."""
        return self._bar("state")

    @property
    def force(self) -> np.ndarray:
        """Axial force of each bar [N]."""
        return self._bar("force")

    @property
    def bar_present(self) -> np.ndarray:
        return self._bar("present")

    # ledger and probes
    @property
    def energies(self) -> dict[str, float]:
        """The energy ledger at the last report (the start of the last step taken; its "time")."""
        return dict(self._s.energies())

    @property
    def probes(self) -> dict[str, float]:
        """The case's probes at the last report, by name."""
        return dict(self._s.probes())

    # loading
    def _index(self, which, names: list[str], what: str) -> int:
        if isinstance(which, (int, np.integer)):
            return int(which)
        hits = [i for i, n in enumerate(names) if n == which]
        if len(hits) != 1:
            raise CaseError(f"{what} {which!r}: expected an index or one of {names}, got "
                            f"{'several' if hits else 'none'}")
        return hits[0]

    def set_velocity(self, which: int | str, factor: float) -> None:
        """Multiplies imposed velocity `which` (its index among [[velocity]], or its set's name)
        by factor from the next step on: 0 holds the set still, -1 unloads."""
        try:
            self._s.set_velocity_factor(self._index(which, self._s.velocity_sets(), "velocity"),
                                        float(factor))
        except _core.InputError as e:
            raise _case_error(e) from None

    def set_load(self, which: int | str, factor: float) -> None:
        """Multiplies load `which` (its index among [[load]], or its name) by factor from the
        next step on."""
        try:
            self._s.set_load_factor(self._index(which, self._s.load_sets(), "load"),
                                    float(factor))
        except _core.InputError as e:
            raise _case_error(e) from None

    def velocity_factor(self, which: int | str) -> float:
        return self._s.velocity_factor(self._index(which, self._s.velocity_sets(), "velocity"))

    def load_factor(self, which: int | str) -> float:
        return self._s.load_factor(self._index(which, self._s.load_sets(), "load"))

    @property
    def threads(self) -> int:
        return self._s.threads()

    @threads.setter
    def threads(self, n: int) -> None:
        self._s.set_threads(int(n))


# --- output folders ------------------------------------------------------------------------

class Table(dict):
    """A CSV table as columns: name -> numpy array, in the file's order. to_pandas() gives a
    pandas DataFrame (pandas is not required otherwise)."""

    def to_pandas(self):
        import pandas as pd
        return pd.DataFrame(dict(self))

    def __repr__(self) -> str:
        rows = len(next(iter(self.values()))) if self else 0
        return f"ldem.Table({rows} rows: {', '.join(self.keys())})"


def read_table(path: str | os.PathLike) -> Table:
    """A CSV file of ldem's (a header line, then rows) as a Table; numbers as float64 or int64,
    other columns as strings."""
    path = Path(path)
    with open(path, encoding="utf-8") as f:
        lines = [ln for ln in f.read().splitlines() if ln and not ln.startswith("#")]
    if not lines:
        raise CaseError(f"{path}: expected a CSV table with a header line, got an empty file")
    names = lines[0].split(",")
    rows = [ln.split(",") for ln in lines[1:]]
    t = Table()
    for j, n in enumerate(names):
        col = [r[j] if j < len(r) else "" for r in rows]
        t[n] = _column(col)
    return t


def _column(col: list[str]) -> np.ndarray:
    try:
        ints = np.array([int(x) for x in col], dtype=np.int64)
        return ints
    except ValueError:
        pass
    try:
        return np.array([float(x) for x in col], dtype=np.float64)
    except ValueError:
        return np.array(col, dtype=str)


def _folder_file(out, name: str) -> Path:
    p = Path(out) / name
    if not p.exists():
        raise FileNotFoundError(f"{p}: not in this output folder")
    return p


def read_energy(out) -> Table:
    """energy.csv: time and the energy ledger's terms [J], one row per report."""
    return read_table(_folder_file(out, "energy.csv"))


def read_events(out) -> Table:
    """events.csv: each bar's softening and rupture, with its step and time."""
    return read_table(_folder_file(out, "events.csv"))


def read_probes(out) -> Table:
    """probes.csv: the case's probes at each report."""
    return read_table(_folder_file(out, "probes.csv"))


def read_crack_tip(out) -> Table:
    """crack_tip.csv of the crack analysis."""
    return read_table(_folder_file(out, "crack_tip.csv"))


def read_fatigue(out) -> Table:
    """fatigue.csv of the fatigue analysis."""
    return read_table(_folder_file(out, "fatigue.csv"))


def read_fatigue_front(out) -> Table:
    """fatigue_front.csv of the fatigue analysis."""
    return read_table(_folder_file(out, "fatigue_front.csv"))


def read_fields(out) -> Table:
    """fields.csv: the material of every bar (or a regular sample of them)."""
    return read_table(_folder_file(out, "fields.csv"))


def read_summary(out) -> dict[str, Any]:
    """summary.json as a dict."""
    with open(_folder_file(out, "summary.json"), encoding="utf-8") as f:
        return json.load(f)


def read_body(out) -> np.ndarray:
    """body.npy of a shaped body: which modules are present, (nx, ny, nz) booleans."""
    return np.load(_folder_file(out, "body.npy"))


def read_snapshots(out) -> list[tuple[float, Path]]:
    """lattice.pvd's snapshots: (time, path of the VTU file), in time order."""
    root = ET.parse(_folder_file(out, "lattice.pvd")).getroot()
    return [(float(d.get("timestep")), Path(out) / d.get("file")) for d in root.iter("DataSet")]


_VTK_TYPES = {"Float32": np.float32, "Float64": np.float64, "Int8": np.int8, "UInt8": np.uint8,
              "Int32": np.int32, "UInt32": np.uint32, "Int64": np.int64, "UInt64": np.uint64}


def read_vtu(path) -> dict[str, np.ndarray]:
    """A VTU snapshot's arrays by name, each of shape (n,) or (n, components): "points" (the
    present nodes' positions at rest), "connectivity", "offsets", "types", the point arrays
    ("displacement", "velocity", ...) and the cell (bar) arrays ("damage", "state",
    "axial_force", "strain", ...), as the file stores them (Float32 for the values)."""
    raw = Path(path).read_bytes()
    start = raw.index(b"<AppendedData")
    data_at = raw.index(b"_", start) + 1
    root = ET.fromstring(raw[:start].decode("utf-8") + "</VTKFile>")
    compressed = root.get("compressor") is not None
    out: dict[str, np.ndarray] = {}
    for el in root.iter("DataArray"):
        name = "points" if el.get("Name") == "Points" else el.get("Name")
        dtype = np.dtype(_VTK_TYPES[el.get("type")])
        at = data_at + int(el.get("offset"))
        if compressed:
            nb, _, _ = np.frombuffer(raw, np.uint64, 3, at)
            sizes = np.frombuffer(raw, np.uint64, int(nb), at + 24)
            p = at + 24 + 8 * int(nb)
            parts = []
            for s in sizes:
                parts.append(zlib.decompress(raw[p:p + int(s)]))
                p += int(s)
            values = np.frombuffer(b"".join(parts), dtype)
        else:
            n = int(np.frombuffer(raw, np.uint64, 1, at)[0])
            values = np.frombuffer(raw, dtype, n // dtype.itemsize, at + 8)
        comps = int(el.get("NumberOfComponents", "1"))
        out[name] = values.reshape(-1, comps) if comps > 1 else values
    return out
