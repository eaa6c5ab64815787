"""Trajectory: one solver's node voltages and joint rates on its time points, with its status and statistics."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .output import Tabular

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["Trajectory", "SolverStats"]


@dataclass(frozen=True, slots=True)
class SolverStats:
    """What a solver spent: wall time, steps and evaluations (None where it does not count them).

    Attributes
    ----------
    wall_time : float
        Seconds in the solver call.
    steps : int or None
        Accepted time steps.
    rejected : int or None
        Rejected time steps.
    evaluations : int or None
        Right-hand-side evaluations (Newton iterations for SPICE).
    jacobians : int or None
        Jacobian evaluations.
    """

    wall_time: float = math.nan
    steps: int | None = None
    rejected: int | None = None
    evaluations: int | None = None
    jacobians: int | None = None

    def __repr__(self) -> str:
        parts = [f"{self.wall_time * 1e3:.3g} ms"]
        parts += [f"{v} {k}" for k, v in (("steps", self.steps), ("rejected", self.rejected),
                                         ("evaluations", self.evaluations),
                                         ("jacobians", self.jacobians)) if v is not None]
        return f"SolverStats({', '.join(parts)})"


_EMPTY = np.empty((0, 0))


@dataclass(eq=False, slots=True)
class Trajectory(Tabular):
    """Result of one solver: a success with its values, or a failure with the reason.

    Attributes
    ----------
    solver : str
        The registered solver's name (``"spice"``, ``"ode"``, ``"exact"`` …).
    time : ndarray, shape (N,)
        Output times, t = 0 included.
    voltages : ndarray, shape (N, n)
        Node velocities v.
    rates : ndarray, shape (N, n)
        Joint rates R = T⁻¹·v.
    positions : ndarray, shape (N, n), or None
        Node positions x = ∫v, when asked for and the system has springs.
    currents : dict of str to ndarray
        Element currents the solver produced itself (SPICE's device currents).
    success : bool
        False if the solver could not run or failed; *message* says why.
    message : str
        The reason of a failure, or a note.
    stats : SolverStats
        Wall time, steps and evaluations.
    work : ndarray, shape (N,), or None
        ∫(F − G)·q̇ − q̇ᵀBq̇ dt, where the solver integrates it (nonlinear systems):
        the work of every force not in the kinetic and spring energies.
    settings : object or None
        What the solver ran with, retries included (SPICE: its
        :class:`~analogy.solvers.transient.TransientSettings`, which
        :func:`~analogy.circuit.netlist.write_netlist` turns into the netlist that ran).
    estimated : OutputErrors or None
        Its joint rates' errors estimated without a reference, each over its own peak, where
        asked for (:func:`~analogy.study.estimate.estimated_errors`).
    """

    solver: str
    time: np.ndarray
    voltages: np.ndarray
    rates: np.ndarray
    positions: np.ndarray | None = None
    currents: dict = field(default_factory=dict)
    success: bool = True
    message: str = ""
    stats: SolverStats = field(default_factory=SolverStats)
    work: np.ndarray | None = None
    settings: object = None
    estimated: object = None

    @classmethod
    def failed(cls, solver: str, message: str, wall_time: float = math.nan) -> "Trajectory":
        """A failed result: no values, the reason in :attr:`message`.

        Parameters
        ----------
        solver : str
            The solver's name.
        message : str
            One sentence saying why.
        wall_time : float
            Seconds spent before it failed.
        """
        empty = np.empty(0)
        return cls(solver, empty, _EMPTY, _EMPTY, success=False, message=message,
                   stats=SolverStats(wall_time))

    @property
    def run_time(self) -> float:
        """Seconds in the solver (:attr:`SolverStats.wall_time`)."""
        return self.stats.wall_time

    def __repr__(self) -> str:
        if not self.success:
            return f"Trajectory({self.solver}: failed: {self.message})"
        guess = "" if self.estimated is None else f", estimated error {self.estimated.relative:.2g} of its peak"
        return (f"Trajectory({self.solver}: {self.time.size} points to t = {self.time[-1]:g} s, "
                f"{self.rates.shape[1]} joints, {self.run_time * 1e3:.3g} ms{guess})")

    def resampled(self, times: np.ndarray, joint_rates, breakpoints=None) -> "Trajectory":
        """This trajectory interpolated onto *times* (an output grid, not a new solution): by a cubic
        spline through its points inside each interval between *breakpoints*, where the motion is smooth,
        linearly without them or where an interval holds fewer than four points. A cubic errs h⁴·|y⁗|/384
        between points h apart, under the trapezoidal rule's own h²·E; a straight line h²/8·|y″|, which
        at the steps a truncation model allows passes the bound (the default arm: 1.1e-6 at accurate).

        Parameters
        ----------
        times : ndarray
            New output times within the trajectory's span.
        joint_rates : callable
            R = T⁻¹·v of the system, for the new voltages.
        breakpoints : array_like, optional
            Times where the forces' derivatives jump (:meth:`NodeSystem.breakpoints`).
        """
        t = np.asarray(times, dtype=float)
        edges = np.unique(np.concatenate([[self.time[0]], np.asarray(breakpoints if breakpoints is not None else [],
                                                                      float), [self.time[-1]]]))
        smooth = breakpoints is not None

        def interp(a):
            return None if a is None else _piecewise(self.time, np.asarray(a, float).reshape(len(self.time), -1), t,
                                                     edges, smooth).reshape((t.size,) + np.shape(a)[1:])
        volts = interp(self.voltages)
        currents = {k: interp(x) for k, x in self.currents.items()}
        return Trajectory(self.solver, t, volts, joint_rates(volts), interp(self.positions), currents,
                          self.success, "; ".join(m for m in (self.message, f"interpolated from its {self.time.size} "
                                                                               "own time points") if m),
                          self.stats, settings=self.settings)

    def at(self, rows: np.ndarray, message: str = "") -> "Trajectory":
        """This trajectory on a subset of its own points (every array's *rows*; no interpolation).

        Parameters
        ----------
        rows : ndarray of int
            Indices of the points kept, increasing.
        message : str
            Said in :attr:`message` (appended to the trajectory's own).
        """
        def pick(a):
            return None if a is None else a[rows]
        note = "; ".join(m for m in (self.message, message) if m)
        return Trajectory(self.solver, self.time[rows], self.voltages[rows], self.rates[rows], pick(self.positions),
                          {k: x[rows] for k, x in self.currents.items()}, self.success, note, self.stats,
                          pick(self.work), self.settings)

    def columns(self) -> dict[str, np.ndarray]:
        """``time``, joint rates ``r1`` …, node voltages ``v_n1`` … and currents ``i_C1_2`` …"""
        cols = {"time": self.time}
        cols.update((f"r{j + 1}", self.rates[:, j]) for j in range(self.rates.shape[1]))
        cols.update((f"v_n{j + 1}", self.voltages[:, j]) for j in range(self.voltages.shape[1]))
        cols.update((f"i_{name}", values) for name, values in self.currents.items())
        return cols

    def plot(self, path=None) -> "Figure":
        """Joint rates against time; saved to *path* if given.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from .plots import plot_trajectory
        return plot_trajectory(self, path)


def _piecewise(time: np.ndarray, values: np.ndarray, t: np.ndarray, edges: np.ndarray, smooth: bool) -> np.ndarray:
    """*values* (m, k) on *time* at *t*: a not-a-knot cubic spline inside each interval of *edges* (*smooth*),
    else linear."""
    out = np.column_stack([np.interp(t, time, values[:, j]) for j in range(values.shape[1])]) if values.size \
        else np.zeros((t.size, values.shape[1]))
    if not smooth:
        return out
    from scipy.interpolate import CubicSpline     # only where a grid is resampled

    for a, b in zip(edges[:-1], edges[1:]):
        inside = (time >= a) & (time <= b)
        x, keep = np.unique(time[inside], return_index=True)
        wanted = (t >= a) & (t <= b)
        if x.size >= 4 and wanted.any():
            out[wanted] = CubicSpline(x, values[inside][keep], axis=0)(t[wanted])
    return out
