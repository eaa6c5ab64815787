"""The solver registry and the contract every solver keeps (as scipy.integrate's methods do).

Contract
--------
A solver is an instance of :class:`Solver` registered in :data:`REGISTRY` by name.

* :meth:`Solver.supports` says, before anything runs, whether the solver applies to a
  system: None if it does, else one sentence why not (the exact solver takes only
  linear systems).
* :meth:`Solver.solve` takes a system following
  :class:`~analogy.model.dynamics.NodeDynamics`, output times (None lets a solver with
  its own time points, such as SPICE, choose them) and a preset, and returns a
  :class:`~analogy.results.trajectory.Trajectory` that starts at t = 0 and carries its
  :class:`~analogy.results.trajectory.SolverStats`.
* A solver raises :class:`~analogy.errors.SimulationError` when it cannot produce a
  solution and :class:`~analogy.errors.InputError` for bad input; :func:`run` turns
  the former (and a solver that does not apply) into a failed Trajectory, so that only
  bad input raises past the orchestrator.
* :meth:`Solver.solve_many` solves many systems; the default loops, and a solver may do
  better (one ngspice run, stacked linear algebra).

Adding a solver is one module defining ``SOLVER = MySolver()`` and one line in
:data:`_MODULES`. Modules load on first use, so a job that does not use SPICE never
loads ngspice.
"""

from __future__ import annotations

import time as _time
from importlib import import_module
from typing import Literal, Sequence

import numpy as np

from ..errors import InputError, SimulationError
from ..presets import Preset
from ..results.trajectory import SolverStats, Trajectory

__all__ = ["Solver", "SolverName", "SOLVER_NAMES", "solver", "run", "run_many", "stacked_trajectories"]

#: Registered solver names.
SolverName = Literal["spice", "ode", "exact", "reference"]

# name -> module that defines SOLVER; imported on first use.
_MODULES: dict[str, str] = {
    "spice": "analogy.solvers.spice",
    "ode": "analogy.solvers.ode",
    "exact": "analogy.solvers.exact",
    "reference": "analogy.solvers.reference",
}

#: Names in the order a comparison runs them (a solver with its own time points first).
SOLVER_NAMES: tuple[str, ...] = tuple(_MODULES)


class Solver:
    """Base class of registered solvers; see the module docstring for the contract.

    Attributes
    ----------
    name : str
        Registry name.
    linear_only : bool
        True if the solver applies only to linear node systems.
    own_grid : bool
        True if the solver chooses its own output times when none are given.
    label : str
        A few words for reports.
    """

    name: str = ""
    linear_only: bool = False
    own_grid: bool = False
    label: str = ""

    def supports(self, system) -> str | None:
        """None if the solver applies to *system*, else one sentence why not.

        Parameters
        ----------
        system : NodeDynamics
            The system to be solved.
        """
        if self.linear_only and getattr(system, "kind", "linear") != "linear":
            return f"the {self.name} solver applies only to linear systems"
        return None

    def solve(self, system, times, preset: Preset, *, save: Sequence[str] = (),
              positions: bool = False) -> Trajectory:
        """Solve *system*; see the module docstring.

        Parameters
        ----------
        system : NodeDynamics
            The system.
        times : array_like or None
            Output times in [0, t_stop]; None lets the solver choose (or a uniform grid).
        preset : Preset
            Accuracy settings.
        save : sequence of str
            Element names whose currents the solver should report if it simulates them.
        positions : bool
            Also return node positions x = ∫v where the system has springs.
        """
        raise NotImplementedError

    @staticmethod
    def grid(system, times, preset: Preset) -> np.ndarray:
        """*times* checked against *system*, or the preset's uniform grid when None.

        Parameters
        ----------
        system : NodeDynamics
            The system.
        times : array_like or None
            Requested output times.
        preset : Preset
            Its ``steps`` set the default grid.
        """
        return system.time_points(np.linspace(0.0, system.t_stop, preset.steps + 1) if times is None else times)

    def solve_many(self, systems: Sequence, times, preset: Preset, *, save: Sequence[str] = (),
                   positions: bool = False) -> list[Trajectory]:
        """Solve each of *systems* at *times*; failures come back as failed trajectories.

        Parameters
        ----------
        systems : sequence of NodeDynamics
            The systems.
        times : array_like or None
            Output times shared by all systems, or None.
        preset : Preset
            Accuracy settings.
        save : sequence of str
            Element currents wanted from solvers that simulate them.
        positions : bool
            Also return node positions where the systems have springs.
        """
        return [run(self.name, s, times, preset, save=save, positions=positions) for s in systems]

    def __repr__(self) -> str:
        return f"<solver {self.name}: {self.label}>"


def stacked_trajectories(name: str, systems: Sequence, time: np.ndarray, voltages: np.ndarray,
                         stats: SolverStats) -> list[Trajectory]:
    """Trajectories of systems solved together on one time grid, joint rates mapped per topology.

    Parameters
    ----------
    name : str
        The solver's name.
    systems : sequence of NodeDynamics
        The systems, all of one size.
    time : ndarray, shape (N,)
        The shared time points.
    voltages : ndarray, shape (count, N, n)
        Node voltages of every system.
    stats : SolverStats
        Shared statistics (the group's time per system).
    """
    groups: dict = {}
    for k, s in enumerate(systems):
        groups.setdefault(id(s.topology), []).append(k)
    if len(groups) == 1:
        rates = systems[0].joint_rates(voltages)
    else:
        rates = np.empty_like(voltages)
        for idx in groups.values():
            rates[idx] = systems[idx[0]].joint_rates(voltages[idx])
    return [Trajectory(name, time, voltages[k], rates[k], stats=stats) for k in range(len(systems))]


def solver(name: str) -> Solver:
    """The registered solver *name*, its module imported on first use.

    Parameters
    ----------
    name : str
        One of :data:`SOLVER_NAMES`.
    """
    module = _MODULES.get(name) if isinstance(name, str) else None
    if module is None:
        raise InputError(f"unknown solver {name!r}: use {', '.join(SOLVER_NAMES)}")
    return import_module(module).SOLVER


def run(name: str, system, times, preset: Preset, *, save: Sequence[str] = (),
        positions: bool = False) -> Trajectory:
    """Run solver *name* on *system*; a failure or a solver that does not apply is a failed Trajectory.

    Parameters
    ----------
    name : str
        Registered solver name.
    system : NodeDynamics
        The system.
    times : array_like or None
        Output times, or None for the solver's own.
    preset : Preset
        Accuracy settings.
    save : sequence of str
        Element currents wanted from solvers that simulate them.
    positions : bool
        Also return node positions where the system has springs.
    """
    s = solver(name)
    reason = s.supports(system)
    if reason is not None:
        return Trajectory.failed(name, reason, 0.0)
    start = _time.perf_counter()
    try:
        return s.solve(system, times, preset, save=save, positions=positions)
    except SimulationError as exc:
        return Trajectory.failed(name, str(exc), _time.perf_counter() - start)


def run_many(name: str, systems: Sequence, times, preset: Preset, *, save: Sequence[str] = (),
             positions: bool = False) -> list[Trajectory]:
    """Run solver *name* on many systems at shared *times* (see :meth:`Solver.solve_many`).

    Parameters
    ----------
    name : str
        Registered solver name.
    systems : sequence of NodeDynamics
        The systems.
    times : array_like or None
        Shared output times, or None for the solver's own.
    preset : Preset
        Accuracy settings.
    save : sequence of str
        Element currents wanted from solvers that simulate them.
    positions : bool
        Also return node positions where the systems have springs.
    """
    return solver(name).solve_many(systems, times, preset, save=save, positions=positions)
