"""In-process ngspice through PySpice's shared-library interface, wrapped for robustness."""

from __future__ import annotations

import ctypes.util
import itertools
import locale
import logging
import os
import re
import shutil
import tempfile
import threading
import time as _time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..circuit.currents import element_currents
from ..circuit.description import circuit
from ..circuit.netlist import batch_netlist, netlist, save_vectors
from ..circuit.node_system import stacked
from ..errors import SimulationError, SpiceError
from ..presets import Preset
from ..results.trajectory import SolverStats, Trajectory
from .registry import Solver, stacked_trajectories

__all__ = ["NgspiceSession", "session", "run_netlist", "solve_spice", "library_path", "vector_key",
           "SpiceSolver", "SOLVER", "RETRY_LOOSEN"]

#: Factors on abstol and vntol of the first run and of the retries after "time step too small".
RETRY_LOOSEN = (1.0, 1e3, 1e6)

_INFO_PREFIXES = ("warning", "note", "using", "doing analysis", "reference value",
                  "circuit:", "no. of data rows")
_CDEF_DONE = False
_CANARY = "* canary\nI1 0 n1 DC 1\nR1 n1 0 1\nC1 n1 0 1\n.tran 0.1 1 uic\n.end\n"


def vector_key(name: str) -> str:
    """The key of a vector in :meth:`NgspiceSession.run`'s result.

    ngspice names device vectors in lower case, so keys are lower case, and a node
    voltage ``v(n1)`` is keyed by its node, ``n1``; a device current ``@C1_2[i]`` is
    ``@c1_2[i]``.

    Parameters
    ----------
    name : str
        A vector name such as ``v(n1)`` or ``@C1_2[i]``.
    """
    key = name.strip().lower()
    if key.startswith("v(") and key.endswith(")"):
        key = key[2:-1]
    return key


def library_path() -> str:
    """The ngspice shared library to load: $NGSPICE_LIBRARY_PATH or the system's libngspice."""
    path = os.environ.get("NGSPICE_LIBRARY_PATH") or ctypes.util.find_library("ngspice")
    if not path:
        raise SpiceError("the ngspice shared library was not found: install the Debian package "
                         "libngspice0 (bash setup.sh does) or set NGSPICE_LIBRARY_PATH")
    return path


def _shared_class():
    """A PySpice NgSpiceShared subclass that records output instead of judging it."""
    logging.getLogger("PySpice").setLevel(logging.CRITICAL)  # it logs harmless notes as errors
    from PySpice.Spice.NgSpice import Shared

    class _Shared(Shared.NgSpiceShared):

        def __init__(self, path: str):
            self._path = path
            self.lines: list[tuple[str, str]] = []
            self.exited = False
            super().__init__(ngspice_id=0, send_data=False, verbose=False)

        @property
        def library_path(self):
            return self._path

        def _load_library(self, verbose):
            locale.setlocale(locale.LC_NUMERIC, "C")   # ngspice parses numbers with the C locale
            global _CDEF_DONE
            if not _CDEF_DONE:        # PySpice's one ffi object takes the declarations once
                api = Path(Shared.__file__).with_name("api.h").read_text()
                Shared.ffi.cdef(api)
                _CDEF_DONE = True
            self._ngspice_shared = Shared.ffi.dlopen(self._path)

        def send_char(self, message, ngspice_id):
            stream, _, text = message.partition(" ")
            self.lines.append((stream, text.strip()))
            return 0

        @staticmethod
        def _exit(exit_status, immediate_unloading, quit_exit, ngspice_id, user_data):
            self = Shared.ffi.from_handle(user_data)
            self.exited = True
            return exit_status

    return _Shared, Shared.ffi


def _is_error(text: str) -> bool:
    low = text.lower()
    if low.startswith(_INFO_PREFIXES):
        return False
    return ("error" in low or "aborted" in low or "too small" in low or "not parsed" in low
            or "fatal" in low)


def _describe_failure(lines: list[str], stage: str) -> str:
    text = " ".join(lines)
    node = None
    m = re.search(r"(?:check node|trouble with node)\s+\"?([\w#.()-]+)\"?", text, re.I)
    if m:
        node = m.group(1)
    m = re.search(r"timestep too small; time = ([0-9.eE+-]+)", text, re.I)
    if m:
        msg = f"ngspice {stage}: time step too small at t = {float(m.group(1)):.6g} s"
        if "singular" in text.lower():
            msg += ", singular matrix"
        return msg + (f" at node {node}" if node else "")
    if "singular matrix" in text.lower():
        return f"ngspice {stage}: singular matrix" + (f" at node {node}" if node else "")
    m = re.search(r"error on line (\d+)[^:]*:\s*(.*)", text, re.I)
    if m:
        return f"ngspice {stage}: error on netlist line {m.group(1)}: {m.group(2).strip()}"
    errors = [ln for ln in lines if _is_error(ln)]
    detail = errors[0] if errors else (lines[-1] if lines else "no output")
    return f"ngspice {stage}: {detail}"


class NgspiceSession:
    """One loaded ngspice library: load a netlist, run it, read vectors, free the circuit.

    Each :meth:`run` ends with ``destroy all`` and ``remcirc`` so that memory stays
    flat over thousands of runs. If ngspice asks to exit or fails its canary after an
    error, the library is loaded afresh from a private copy, since ngspice keeps
    global state that a fatal error can leave broken.
    """

    def __init__(self, path: str | None = None):
        self._lock = threading.Lock()
        self._source = path or library_path()
        self._tmp: tempfile.TemporaryDirectory | None = None
        self._generation = 0
        self._open(self._source)

    def _open(self, path: str):
        cls, self._ffi = _shared_class()
        try:
            self._ng = cls(path)
        except OSError as exc:
            raise SpiceError(f"cannot load the ngspice shared library {path}: {exc}") from None
        self._lib = self._ng._ngspice_shared
        self._command("set nomoremode")

    def _reload(self):
        # A fresh copy has its own global state; dlopen of the same path would share it.
        if self._tmp is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="analogy-ngspice-")
        src = Path(self._resolve(self._source))
        self._generation += 1
        dst = Path(self._tmp.name) / f"libngspice-{self._generation}.so"
        shutil.copy(src, dst)
        self._open(str(dst))

    @staticmethod
    def _resolve(name: str) -> str:
        if os.path.sep in name:
            return name
        for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib", "/usr/local/lib"):
            p = Path(d) / name
            if p.exists():
                return str(p)
        raise SpiceError(f"cannot locate {name} on disk to reload ngspice")

    @property
    def version(self) -> int | None:
        return self._ng.ngspice_version

    def _command(self, cmd: str) -> list[tuple[str, str]]:
        self._ng.lines = []
        rc = self._lib.ngSpice_Command(cmd.encode("ascii"))
        if rc:
            raise SpiceError(f"ngspice rejected the command {cmd!r}")
        return self._ng.lines

    def _load(self, netlist: str) -> list[tuple[str, str]]:
        ffi = self._ffi
        raw = [line.encode("ascii", "replace") for line in netlist.splitlines() if line]
        # One buffer of NUL-terminated lines and pointers into it: one allocation, not one per line.
        buf = ffi.new("char[]", b"\0".join(raw) + b"\0")
        array = ffi.new("char *[]", len(raw) + 1)       # zero-filled: the last pointer is NULL
        for i, off in zip(range(len(raw)), itertools.accumulate((len(r) + 1 for r in raw), initial=0)):
            array[i] = buf + off
        self._ng.lines = []
        rc = self._lib.ngSpice_Circ(array)
        lines = self._ng.lines
        if rc:
            lines = lines + [("stderr", f"error: ngSpice_Circ returned {rc}")]
        return lines

    def _vectors(self, plot: str) -> dict[str, np.ndarray]:
        ffi = self._ffi
        names = self._ng._convert_string_array(self._lib.ngSpice_AllVecs(plot.encode()))
        out = {}
        for name in names:
            info = self._lib.ngGet_Vec_Info(f"{plot}.{name}".encode())
            if info == ffi.NULL:
                continue
            if info.v_realdata != ffi.NULL:
                data = np.frombuffer(ffi.buffer(info.v_realdata, info.v_length * 8), dtype=np.float64).copy()
            elif info.v_compdata != ffi.NULL:      # an AC sweep: (re, im) pairs
                pairs = np.frombuffer(ffi.buffer(info.v_compdata, info.v_length * 16), dtype=np.float64)
                data = pairs[0::2] + 1j * pairs[1::2]
            else:
                continue
            out[vector_key(name)] = data
        return out

    def _free(self):
        self._command("destroy all")
        self._command("remcirc")
        # PySpice keeps every line ngspice prints; what a run said is read by then.
        for kept in (getattr(self._ng, "_stdout", None), getattr(self._ng, "_stderr", None)):
            if isinstance(kept, list):
                kept.clear()

    def _healthy(self) -> bool:
        try:
            lines = self._load(_CANARY) + self._command("run")
            ok = not any(_is_error(t) for s, t in lines) and not self._ng.exited
            ok = ok and self._lib.ngSpice_CurPlot() != self._ffi.NULL and \
                self._ffi.string(self._lib.ngSpice_CurPlot()).decode().startswith("tran")
            self._free()
            return ok
        except SpiceError:
            return False

    def run(self, netlist: str, vectors=None, stats: dict | None = None,
            analysis: str = "tran") -> dict[str, np.ndarray]:
        """Run a transient (or, with *analysis* ``"ac"``, an AC) netlist: ``{"time": …, node: …}``.

        Parameters
        ----------
        netlist : str
            The netlist text (ASCII).
        vectors : sequence of str, optional
            Return only these, keyed as given; each is looked up by :func:`vector_key`,
            so ``n1``, ``v(n1)`` and ``@c1_2[i]`` all work.
        stats : dict, optional
            Filled with ngspice's ``iterations`` and ``rejected`` time points.
        analysis : {"tran", "ac"}
            The netlist's analysis; an AC run returns ``"frequency"`` and complex vectors.

        Raises
        ------
        SpiceError
            With one sentence naming the failure and, where ngspice says, the node.
        """
        with self._lock:
            try:
                return self._run(netlist, vectors, stats, analysis)
            except SpiceError:
                # Leave a clean instance for the next run, whatever state ngspice is in.
                if self._ng.exited or not self._healthy():
                    self._reload()
                raise

    def _run(self, netlist, vectors, stats=None, analysis="tran"):
        index = "time" if analysis == "tran" else "frequency"
        try:
            netlist.encode("ascii")
        except UnicodeEncodeError:
            raise SpiceError("netlist contains non-ASCII characters") from None
        load = self._load(netlist)
        errors = [t for s, t in load if _is_error(t)]
        if errors or self._ng.exited:
            self._free()
            raise SpiceError(_describe_failure([t for s, t in load], "could not parse the netlist"))
        ran = self._command("run")
        failed = [t for s, t in ran if _is_error(t)]
        plot_c = self._lib.ngSpice_CurPlot()
        plot = self._ffi.string(plot_c).decode() if plot_c != self._ffi.NULL else ""
        if failed or self._ng.exited or not plot.startswith(analysis):
            self._free()
            stage = "transient analysis failed" if analysis == "tran" else "AC analysis failed"
            raise SpiceError(_describe_failure([t for s, t in ran], stage))
        data = self._vectors(plot)
        if stats is not None:
            for _, text in self._command("rusage rejected"):
                name, _, value = text.partition(" = ")
                key = {"Transient iterations": "iterations", "Rejected timepoints": "rejected"}.get(name)
                if key and value.strip().isdigit():
                    stats[key] = int(value)
        self._free()
        if index not in data:
            raise SpiceError(f"ngspice returned no {index} vector")
        if index == "frequency":
            data[index] = data[index].real
        if vectors is not None:
            missing = [v for v in vectors if vector_key(v) not in data]
            if missing:
                raise SpiceError(f"ngspice did not save vector {missing[0]!r}")
            data = {index: data[index], **{v: data[vector_key(v)] for v in vectors}}
        return data


_SESSION: NgspiceSession | None = None
_SESSION_LOCK = threading.Lock()


def session() -> NgspiceSession:
    """The process's ngspice session, loaded on first use (once, whichever thread asks)."""
    global _SESSION
    with _SESSION_LOCK:
        if _SESSION is None:
            _SESSION = NgspiceSession()
        return _SESSION


def run_netlist(netlist: str, vectors=None) -> dict[str, np.ndarray]:
    """Run *netlist* in the process's ngspice session.

    Parameters
    ----------
    netlist : str
        The netlist text.
    vectors : sequence of str, optional
        Vectors to return (see :meth:`NgspiceSession.run`).
    """
    return session().run(netlist, vectors)


def _from_start(time: np.ndarray) -> tuple[np.ndarray, bool]:
    """SPICE's time points with t = 0 first (ngspice's first output point is its first step)."""
    if time.size and time[0] > 0:
        return np.concatenate([[0.0], time]), True
    return time, False


def _trajectory(system, time, prepended: bool, volts, currents, stats, elapsed,
                positions=None) -> Trajectory:
    """A SPICE result on *time*; with *prepended*, its first row is the initial state."""
    if prepended:
        v0 = system.initial_voltages
        volts = np.vstack([v0, volts])
        if positions is not None:
            positions = np.vstack([np.zeros(system.dof), positions])
        if currents:
            first = element_currents(system, np.zeros(1), v0[None], np.zeros((1, system.dof)),
                                     list(currents))
            currents = {k: np.concatenate([first[k], x]) for k, x in currents.items()}
    info = SolverStats(elapsed, max(int(time.size) - 1, 0), stats.get("rejected"), stats.get("iterations"))
    return Trajectory("spice", time, volts, system.joint_rates(volts), positions, currents=currents,
                      stats=info)


def solve_spice(system, preset="accurate", save=None) -> Trajectory:
    """Simulate *system*'s netlist in ngspice and recover joint rates from node voltages.

    A run whose step collapses ("time step too small": rounding read as truncation error)
    is run again with abstol and vntol :data:`RETRY_LOOSEN` times larger; the
    trajectory's :attr:`~Trajectory.message` says so, and the bound judges the result.

    Parameters
    ----------
    system : NodeSystem or NonlinearNodeSystem
        A linear system, or a nonlinear one with a symbolic model (its circuit has
        charge-defined capacitors, behavioural currents and integrators).
    preset : str or Preset
        Accuracy preset.
    save : sequence of str, optional
        Element names whose currents to return in :attr:`Trajectory.currents`.
    """
    circ = circuit(system, describe=False)
    names = [e for e in (save or []) if e not in system.nodes] + circ.state_nodes
    vectors = save_vectors(circ, list(system.nodes) + names)
    sess = session()
    start = _time.perf_counter()
    note = ""
    for loosen in RETRY_LOOSEN:
        stats: dict = {}
        text = netlist(circ, preset, save=list(system.nodes) + names, printing=False, loosen=loosen)
        try:
            data = sess.run(text, vectors, stats)
            break
        except SimulationError as exc:
            # Rounding read as truncation error collapses the step: retry with looser
            # absolute tolerances, say so, and let the bound judge the result.
            if "time step too small" not in str(exc) or loosen == RETRY_LOOSEN[-1]:
                raise
            note = f"retried with abstol and vntol × {RETRY_LOOSEN[RETRY_LOOSEN.index(loosen) + 1]:g} ({exc})"
    elapsed = _time.perf_counter() - start
    v = np.column_stack([data[f"v({n})"] for n in system.nodes])
    x = np.column_stack([data[f"v({n})"] for n in circ.state_nodes]) if circ.state_nodes else None
    currents = {name: data[vec] for name, vec in zip(names, vectors[system.dof:]) if name not in circ.state_nodes}
    tr = _trajectory(system, *_from_start(data["time"]), v, currents, stats, elapsed, x)
    return replace(tr, message=note) if note else tr


class SpiceSolver(Solver):
    """ngspice in process: the equivalent circuit, simulated on its own time points."""

    name = "spice"
    own_grid = True
    label = "ngspice (shared library)"

    def supports(self, system) -> str | None:
        """Linear systems, and nonlinear ones with a symbolic model to write as a circuit.

        Parameters
        ----------
        system : NodeDynamics
            The system to be solved.
        """
        if getattr(system, "kind", "linear") != "linear" and getattr(system, "model", None) is None:
            return "the spice solver needs the symbolic model of a nonlinear system"
        return None

    def solve(self, system, times, preset: Preset, *, save=(), positions=False) -> Trajectory:
        """Simulate on SPICE's own points; given *times*, the result is interpolated onto them.

        Parameters
        ----------
        system : NodeSystem
            A linear system.
        times : array_like or None
            None keeps SPICE's points (t = 0 added); else linear interpolation onto them.
        preset : Preset
            Accuracy settings (``.options`` and ``.tran``).
        save : sequence of str
            Element names whose device currents to return.
        positions : bool
            Unused: the circuit's states are node voltages.
        """
        tr = solve_spice(system, preset, save)
        return tr if times is None else tr.resampled(system.time_points(times), system.joint_rates)

    def solve_many(self, systems, times, preset: Preset, *, save=(), positions=False) -> list[Trajectory]:
        """One ngspice run for all systems (sharing t_stop); if it fails, one run each.

        Parameters
        ----------
        systems : sequence of NodeSystem
            Linear systems sharing t_stop.
        times : array_like or None
            Must be None: a shared run has SPICE's own points.
        preset : Preset
            Accuracy settings.
        save : sequence of str
            Element currents to return (then each system runs alone).
        positions : bool
            Unused.
        """
        if len(systems) == 1 or save or times is not None:
            return super().solve_many(systems, times, preset, save=save)
        text = batch_netlist(systems, preset)
        stats: dict = {}
        start = _time.perf_counter()
        try:
            data = session().run(text, None, stats)
        except SimulationError:
            return super().solve_many(systems, times, preset)
        elapsed = (_time.perf_counter() - start) / len(systems)
        time, prepended = _from_start(data["time"])
        n = systems[0].dof
        if any(s.dof != n for s in systems):
            return [_trajectory(s, time, prepended, np.column_stack([data[f"x{k}_{m}"] for m in s.nodes]),
                                {}, stats, elapsed) for k, s in enumerate(systems)]
        nodes = systems[0].nodes
        count = len(systems)
        volts = np.stack([data[f"x{k}_{node}"] for k in range(count) for node in nodes])
        volts = volts.reshape(count, n, -1).transpose(0, 2, 1)
        if prepended:
            v0 = stacked(systems, "initial_voltages")[:, None, :]
            volts = np.concatenate([v0, volts], axis=1)
        info = SolverStats(elapsed, time.size - 1, stats.get("rejected"), stats.get("iterations"))
        return stacked_trajectories(self.name, systems, time, volts, info)


SOLVER = SpiceSolver()
