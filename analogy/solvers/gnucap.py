"""The gnucap solver: a linear circuit written in gnucap's dialect, run by the gnucap executable."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import tempfile
import time as _time
from pathlib import Path

import numpy as np

from ..errors import SimulationError
from ..presets import Preset
from ..presets import preset as get_preset
from ..results.trajectory import SolverStats, Trajectory
from .registry import Solver
from .transient import netlist

__all__ = ["read_gnucap", "solve_gnucap", "GnucapSolver", "SOLVER"]

# gnucap prints 1.5e-4 as 150.u: a number and one of its scale letters
_NUMBER = re.compile(r"^([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)(Meg|[fpnumKGT])?$")
_SCALE = {None: 1.0, "f": 1e-15, "p": 1e-12, "n": 1e-9, "u": 1e-6, "m": 1e-3, "K": 1e3, "Meg": 1e6,
          "G": 1e9, "T": 1e12}


def _value(text: str) -> float:
    m = _NUMBER.match(text)
    if m is None:
        raise SimulationError(f"gnucap printed {text!r} where a number belongs")
    return float(m.group(1)) * _SCALE[m.group(2)]


def read_gnucap(output: str) -> dict[str, np.ndarray]:
    """The table gnucap prints for ``.print tran``: ``{"time": …, "v(n1)": …}``.

    Parameters
    ----------
    output : str
        What ``gnucap -b`` wrote to its standard output.
    """
    lines = output.splitlines()
    head = next((k for k, line in enumerate(lines) if line.startswith("#Time")), None)
    if head is None:
        raise SimulationError("gnucap printed no transient table")
    names = ["time"] + lines[head].split()[1:]
    rows = []
    for line in lines[head + 1:]:
        words = line.split()
        if len(words) != len(names) or not _NUMBER.match(words[0]):
            break
        rows.append([_value(w) for w in words])
    if not rows:
        raise SimulationError("gnucap printed an empty transient table")
    table = np.array(rows)
    return {name: table[:, k] for k, name in enumerate(names)}


def solve_gnucap(system, preset: str | Preset = "accurate") -> Trajectory:
    """Run *system*'s circuit in gnucap and read its node voltages on the print step.

    gnucap prints zeros on its t = 0 row although the run starts from the capacitors'
    initial voltages, so that row is the initial state.

    Parameters
    ----------
    system : NodeSystem
        A linear system.
    preset : str or Preset
        Accuracy preset (the same settings as the spice solver's; its timeout bounds the run).
    """
    p = get_preset(preset)
    text = netlist(system, p, dialect="gnucap")
    program = shutil.which("gnucap")
    if program is None:
        raise SimulationError("gnucap is not installed (Debian: apt install gnucap)")
    limit = p.budget.timeout if p.budget.timeout is not None and math.isfinite(p.budget.timeout) else None
    start = _time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="analogy-gnucap-") as folder:
        path = Path(folder) / "circuit.ckt"
        path.write_text(text)
        try:
            res = subprocess.run([program, "-b", str(path)], capture_output=True, text=True, timeout=limit,
                                 cwd=folder)
        except subprocess.TimeoutExpired:
            raise SimulationError(f"gnucap ran past the preset's time limit ({limit:g} s)") from None
    elapsed = _time.perf_counter() - start
    # gnucap echoes the netlist's title (a robot's name may hold "fail"): comments are not its words
    said = [line for line in (res.stdout + res.stderr).splitlines()
            if not line.lstrip().startswith("*") and re.search(r"error|fail|abort", line, re.I)]
    if res.returncode != 0 or said:
        why = " ".join(said[0].split())[:200] if said else f"exit {res.returncode}"
        raise SimulationError(f"gnucap failed: {why}")
    data = read_gnucap(res.stdout)
    volts = np.column_stack([data[f"v({n})"] for n in system.nodes])
    time = data["time"]
    if time[0] == 0.0:
        volts[0] = system.initial_voltages
    else:
        time, volts = np.concatenate([[0.0], time]), np.vstack([system.initial_voltages, volts])
    if abs(time[-1] - system.t_stop) > 1e-9 * system.t_stop:
        raise SimulationError(f"gnucap stopped at t = {time[-1]:.6g} s, before t_stop = {system.t_stop:g} s")
    time[-1] = system.t_stop                # its last print time carries the rounding of its sums
    return Trajectory("gnucap", time, volts, system.joint_rates(volts),
                      stats=SolverStats(elapsed, time.size - 1, None, None))


class GnucapSolver(Solver):
    """gnucap as a program: the linear circuit in its dialect, on its print step."""

    name = "gnucap"
    linear_only = True
    own_grid = True
    label = "gnucap (executable)"

    def supports(self, system) -> str | None:
        """Linear systems, where the gnucap executable is installed.

        Parameters
        ----------
        system : NodeDynamics
            The system to be solved.
        """
        if system.kind != "linear":
            return ("gnucap has no charge-defined capacitors or behavioural sources, which a nonlinear "
                    "circuit needs: run it in ngspice (the spice solver)")
        if shutil.which("gnucap") is None:
            return "gnucap is not installed (Debian: apt install gnucap)"
        return None

    def _solve(self, system, times, preset: Preset, *, save=(), positions=False) -> Trajectory:
        """gnucap's print-step points (t = 0 the initial state); see :meth:`Solver.solve`.

        Parameters
        ----------
        system : NodeSystem
            A linear system.
        times : None
            gnucap chooses its points (the preset's print step).
        preset : Preset
            Accuracy settings, as the spice solver's.
        save : sequence of str
            Unused: element currents follow from the trajectory.
        positions : bool
            Node positions are not reported: refused for a system with springs.
        """
        if positions and getattr(system, "stiffness", None) is not None:
            raise SimulationError("gnucap reports node voltages only here: a system with springs needs its "
                                  "node positions for element currents or its energy (use the spice solver)")
        return solve_gnucap(system, preset)


SOLVER = GnucapSolver()
