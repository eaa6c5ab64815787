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
  :class:`~analogy.results.trajectory.SolverStats`. The base class keeps this once:
  it checks the times, lets the solver load what it needs once (:meth:`Solver.ready`, untimed),
  times the solver's own hook :meth:`Solver._solve`, interpolates a
  solver with its own points onto given times and checks the result's shape; a
  subclass implements ``_solve`` and may not override ``solve``.
* :func:`solve` is the public entry, shaped like ``scipy.integrate.solve_ivp``:
  ``solve(system, method, t_eval, preset)``.
* A solver raises :class:`~analogy.errors.SimulationError` when it cannot produce a
  solution and :class:`~analogy.errors.InputError` for bad input; :func:`run` turns
  the former (and a solver that does not apply) into a failed Trajectory, so that only
  bad input raises past the orchestrator.
* :meth:`Solver.solve_many` solves many systems under the same contract, row by row: the
  default loops over :meth:`Solver.solve`, and a solver may do better in its own hook
  :meth:`Solver._solve_many` (one ngspice run, stacked linear algebra), whose rows are
  checked as :meth:`Solver.solve` checks one; a subclass may not override ``solve_many``.

Adding a solver is one module defining ``SOLVER = MySolver()`` and one line in
:data:`_MODULES`. Modules load on first use, so a job that does not use SPICE never
loads ngspice.
"""

from __future__ import annotations

import time as _time
from dataclasses import replace
from importlib import import_module
from typing import Literal, Sequence

import numpy as np

from ..circuit.node_stack import NodeStack, shared_row
from ..errors import InputError, SimulationError
from ..presets import Preset
from ..presets import preset as get_preset
from ..results.trajectory import SolverStats, Trajectory
from ..results.trajectory_stack import TrajectoryStack

__all__ = ["Solver", "SolverName", "SOLVER_NAMES", "solver", "solve", "run", "run_many", "stacked_trajectories"]

#: What numbers leaving the floating-point range raise inside a solver: a failed run, not a bug.
_BROKEN = (np.linalg.LinAlgError, FloatingPointError, OverflowError, ZeroDivisionError)

#: Registered solver names.
SolverName = Literal["spice", "gnucap", "ode", "exact", "reference"]

# name -> module that defines SOLVER; imported on first use.
_MODULES: dict[str, str] = {
    "spice": "analogy.solvers.spice",
    "gnucap": "analogy.solvers.gnucap",
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
    yardstick : bool
        True for the references (exact, reference): no error estimate of their own.
    label : str
        A few words for reports.
    """

    name: str = ""
    linear_only: bool = False
    own_grid: bool = False
    label: str = ""
    #: A yardstick (a closed form, the tight reference): the others' errors are measured against it,
    #: and it has no estimate of its own.
    yardstick: bool = False

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        for name in ("solve", "solve_many"):    # the contract is kept in one place: solvers implement the hooks
            if name in vars(cls):
                raise TypeError(f"{cls.__name__} overrides Solver.{name}: implement _{name} instead")

    def ready(self) -> None:
        """Load what every run needs once per process (a shared library), before a run is timed: a
        run's time is its own work, as the ODE's excludes importing scipy. By default nothing."""

    def supports(self, system) -> str | None:
        """None if the solver applies to *system*, else one sentence why not.

        Parameters
        ----------
        system : NodeDynamics
            The system to be solved.
        """
        if self.linear_only and system.kind != "linear":
            return f"the {self.name} solver applies only to linear systems"
        return None

    def solve(self, system, times, preset: Preset, *, save: Sequence[str] = (),
              positions: bool = False) -> Trajectory:
        """Solve *system*: the contract, kept here once for every solver.

        The grid is checked (or the preset's uniform one made), the solver's own
        :meth:`_solve` runs and is timed, a solver with its own points is interpolated
        onto *times* when they are given, and the result is checked to start at t = 0
        with one row of node voltages and joint rates per time point.

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
        grid = None if times is None and self.own_grid else self.grid(system, times, preset)
        self.ready()
        start = _time.perf_counter()
        try:
            tr = self._solve(system, None if self.own_grid else grid, preset, save=save, positions=positions)
        except _BROKEN as exc:
            raise self._broke(exc) from None
        tr = self._checked(tr, system, _time.perf_counter() - start)
        if grid is None or not self.own_grid or not tr.success:
            return tr
        return tr.resampled(grid, system.joint_rates, system.breakpoints())

    def _broke(self, exc: Exception) -> SimulationError:
        # the numbers left the floating-point range (g = 1e308, say): a failed run, said once
        detail = " ".join(str(exc).split())[:200] or type(exc).__name__
        return SimulationError(f"the {self.name} solver's numerics broke down: {detail} (are the model's "
                               "values within the floating-point range?)")

    def _checked(self, tr: Trajectory, system, elapsed: float | None) -> Trajectory:
        """*tr* if it keeps the contract (its wall time set to *elapsed* where given); a failed
        trajectory if its values are not finite; :class:`SimulationError` if its shape breaks it."""
        if elapsed is not None:
            tr = replace(tr, stats=replace(tr.stats, wall_time=elapsed))
        if not tr.success:
            return tr
        n = system.dof
        if not (tr.time.size and tr.time[0] == 0.0 and tr.voltages.shape == (tr.time.size, n)
                and tr.rates.shape == tr.voltages.shape):
            raise SimulationError(f"the {self.name} solver broke its contract: its result must start at t = 0 "
                                  f"with {n} node voltages and joint rates per time point")
        if not np.all(np.isfinite(tr.voltages)):
            first = float(tr.time[np.flatnonzero(~np.isfinite(tr.voltages).all(axis=1))[0]])
            return Trajectory.failed(self.name, f"its result is not finite from t = {first:g} s on",
                                     tr.stats.wall_time)
        return tr

    def refinements(self, preset: Preset) -> list[tuple[Preset, float]]:
        """Settings under which this solver errs a known fraction of what it errs under *preset*,
        each with the factor that turns the difference of the two runs into the first run's error
        (Richardson's), tried in turn while a refined run fails; empty where the solver has no
        such estimate (a closed form, a reference).

        Parameters
        ----------
        preset : Preset
            The settings of the run to be judged.
        """
        return []

    def _solve(self, system, times, preset: Preset, *, save: Sequence[str] = (),
               positions: bool = False) -> Trajectory:
        """The solver's own work, which :meth:`solve` times, resamples and checks.

        Parameters
        ----------
        system : NodeDynamics
            The system.
        times : ndarray or None
            Checked output times; None for a solver with its own points.
        preset : Preset
            Accuracy settings.
        save : sequence of str
            Element currents wanted, where the solver simulates them.
        positions : bool
            Also return node positions where the system has springs.
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
            Its :meth:`~analogy.presets.Preset.grid` is the default.
        """
        return system.time_points(preset.grid(system.t_stop) if times is None else times)

    def solve_many(self, systems: Sequence, times, preset: Preset, *, save: Sequence[str] = (),
                   positions: bool = False) -> Sequence[Trajectory]:
        """Solve each of *systems* at *times*, each row under :meth:`solve`'s contract; failures
        come back as failed trajectories.

        The solver's hook :meth:`_solve_many` may solve them together; its rows are checked as
        :meth:`solve` checks one (a stack solved as one, at once), and if the numbers break down
        for the stack as a whole, each system runs alone.

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
        if type(self)._solve_many is Solver._solve_many:    # each through solve, checked there
            return Solver._solve_many(self, systems, times, preset, save=save, positions=positions)
        try:
            rows = self._solve_many(systems, times, preset, save=save, positions=positions)
        except _BROKEN:             # each alone: only a system whose numbers leave the range fails
            return Solver._solve_many(self, systems, times, preset, save=save, positions=positions)
        if isinstance(rows, TrajectoryStack) and rows.whole:
            if rows.time[0] == 0.0 and rows.voltages.shape[2] == shared_row(systems).dof and \
                    np.isfinite(rows.voltages).all():
                return rows         # the contract, checked for the whole stack at once (else row by row)
        out: list = []
        for tr, s in zip(rows, systems):
            try:
                out.append(self._checked(tr, s, None))
            except SimulationError as exc:
                out.append(Trajectory.failed(self.name, str(exc), tr.stats.wall_time))
        return out

    def _solve_many(self, systems: Sequence, times, preset: Preset, *, save: Sequence[str] = (),
                    positions: bool = False) -> Sequence[Trajectory]:
        """The solver's own way with many systems, which :meth:`solve_many` checks row by row;
        by default each through :func:`run` (and so :meth:`solve`).

        Parameters
        ----------
        systems : sequence of NodeDynamics
            The systems.
        times : array_like or None
            Shared output times, or None.
        preset : Preset
            Accuracy settings.
        save : sequence of str
            Element currents wanted.
        positions : bool
            Also return node positions where the systems have springs.
        """
        return [run(self.name, s, times, preset, save=save, positions=positions) for s in systems]

    def __repr__(self) -> str:
        return f"<solver {self.name}: {self.label}>"


def stacked_trajectories(name: str, systems: Sequence, time: np.ndarray, voltages: np.ndarray,
                         stats: SolverStats) -> TrajectoryStack:
    """The stack of systems solved together on one time grid, joint rates mapped per topology.

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
    if isinstance(systems, NodeStack) and systems.shares_inputs:    # one topology: its rows are not made
        groups[None] = [0]
    else:
        for k, s in enumerate(systems):
            groups.setdefault(s.topology.key, []).append(k)
    if len(groups) == 1:
        rates = shared_row(systems).joint_rates(voltages)
    else:
        rates = np.empty_like(voltages)
        for idx in groups.values():
            rates[idx] = systems[idx[0]].joint_rates(voltages[idx])
    return TrajectoryStack.solved_as_one(name, time, voltages, rates, stats)


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
             positions: bool = False) -> TrajectoryStack:
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
    return TrajectoryStack.of(solver(name).solve_many(systems, times, preset, save=save, positions=positions))


def solve(system, method: str = "spice", t_eval=None, preset: str | Preset = "accurate", *,
          t_stop: float | None = None, forces=None, save: Sequence[str] = (),
          positions: bool = False) -> Trajectory:
    """Solve *system* with the registered solver *method*, as ``scipy.integrate.solve_ivp`` does.

    The system holds what ``solve_ivp`` takes as ``fun`` and ``y0`` (its node dynamics
    and initial rates); the horizon and the forces are the system's own unless *t_stop*
    or *forces* are given here (:meth:`~analogy.circuit.node_system.NodeCoordinates.driven`). Like ``solve_ivp``, a solver that cannot finish
    returns its result with ``success`` False and the reason in ``message``; only bad input
    raises.

    Parameters
    ----------
    system : NodeDynamics
        The system.
    method : str
        A registered solver (:data:`SOLVER_NAMES`).
    t_eval : array_like, optional
        Output times in [0, t_stop]; default the solver's own points (SPICE) or the
        preset's uniform grid.
    preset : str or Preset
        Accuracy preset.
    t_stop : float, optional
        End of the simulated interval [s], instead of the system's.
    forces : sequence, optional
        Joint forces, one entry per joint, instead of the system's (gravity is kept).
    save : sequence of str
        Element currents wanted from a solver that simulates them.
    positions : bool
        Also return node positions where the system has springs.
    """
    if t_stop is not None or forces is not None:
        system = system.driven(forces, t_stop)
    return run(method, system, t_eval, get_preset(preset), save=save, positions=positions)
