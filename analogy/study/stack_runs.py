"""Every solver's runs over a stack of systems: on shared time points, and on each solver's own points."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from ..circuit.currents import trajectory_currents
from ..circuit.node_stack import NodeStack
from ..presets import Preset
from ..results.trajectory import Trajectory
from ..results.trajectory_stack import TrajectoryStack
from ..solvers.registry import run_many, solver
from .grid import SUBSET_FROM, output_grid
from .measure import subset, sufficient

__all__ = ["StackRuns"]


def _by_grid(grids: Sequence[np.ndarray]) -> list[list[int]]:
    """Indices grouped by equal time grids (by value)."""
    if all(g is grids[0] for g in grids):       # one grid for all: its values need not be read
        return [list(range(len(grids)))]
    groups: dict = {}
    for k, g in enumerate(grids):
        groups.setdefault(g.tobytes(), []).append(k)
    return list(groups.values())


@dataclass(eq=False)
class StackRuns:
    """The solvers' trajectories over one stack of systems, as they are run one solver at a time.

    Per system, the first own-grid solver that succeeds (SPICE) sets the shared time points
    unless a grid was given; a later own-grid solver is shown on them and measured on its own.

    Attributes
    ----------
    systems : sequence of NodeDynamics
        The systems, of one kind.
    preset : Preset
        The settings every solver runs with.
    given : bool
        True if the output points were given (a step or times), not chosen by a solver.
    ends : list of float
        Per system, its horizon t_stop.
    grids : list of ndarray or None
        Per system, its shared time points (None until a solver sets them).
    shown : dict of str to TrajectoryStack
        Per solver, its runs on the shared points.
    own : dict of str to TrajectoryStack
        Per own-grid solver, its runs on its own points (a sufficient subset of millions).
    resampled : set of str
        Solvers shown on points that are not their own.
    """

    systems: Sequence
    preset: Preset
    given: bool
    ends: list
    grids: list
    shown: dict = field(default_factory=dict)
    own: dict = field(default_factory=dict)
    resampled: set = field(default_factory=set)

    @classmethod
    def start(cls, systems: Sequence, preset: Preset, step: float | None, times) -> "StackRuns":
        """No run yet: the shared points are the given ones, one grid per horizon, or to be chosen.

        Parameters
        ----------
        systems : sequence of NodeDynamics
            The systems.
        preset : Preset
            The settings.
        step : float or None
            A uniform output step for every solver.
        times : array_like or None
            Output times when no solver chooses its own and no step is given.
        """
        ends = systems.t_stops.tolist() if isinstance(systems, NodeStack) else [s.t_stop for s in systems]
        if step is None and times is None:
            return cls(systems, preset, False, ends, [None] * len(ends))
        given = {t: output_grid(t, step, preset.steps) if times is None else np.asarray(times, float)
                 for t in dict.fromkeys(ends)}
        return cls(systems, preset, True, ends, [given[t] for t in ends])

    def solved(self, name: str) -> TrajectoryStack:
        """*name*'s runs where its errors are measured: on its own points if it has them.

        Parameters
        ----------
        name : str
            A solver that ran.
        """
        return self.own.get(name, self.shown[name])

    def run(self, name: str, save: Sequence[str], positions: bool) -> None:
        """Run solver *name* on every system, each on its shared points or its own.

        Parameters
        ----------
        name : str
            A registered solver that applies to the systems.
        save : sequence of str
            Element currents to report.
        positions : bool
            Also keep node positions.
        """
        systems, p = self.systems, self.preset
        if solver(name).own_grid:
            trs = run_many(name, systems, None, p, save=save, positions=positions)
            short = trs.whole and trs.time.size <= SUBSET_FROM      # measured whole, as :func:`sufficient` would
            if not self.given and not short:    # millions of own points: measured on their sufficient subset
                trs = TrajectoryStack([sufficient(tr, systems[k], p) if tr.success and self.grids[k] is None
                                       else tr for k, tr in enumerate(trs)])
            self.own[name] = trs
            ok = trs.successes.tolist()
            if any(g is not None and good for g, good in zip(self.grids, ok)):
                self.resampled.add(name)
                trs = TrajectoryStack([tr.resampled(self.grids[k], s.joint_rates, s.breakpoints())
                                       if tr.success and self.grids[k] is not None else tr
                                       for k, (tr, s) in enumerate(zip(trs, systems))])
            whole = trs.whole           # one grid for every row that ran: the same array for each
            self.grids = [(trs.time if whole else trs[k].time) if good and g is None else g
                          for k, (g, good) in enumerate(zip(self.grids, trs.successes.tolist()))]
        else:
            if any(g is None for g in self.grids):      # rows no solver has set points for: the preset's
                default = {t: self.preset.grid(t) for t in dict.fromkeys(self.ends)}    # one per horizon
                self.grids = [default[t] if g is None else g for g, t in zip(self.grids, self.ends)]
            groups = _by_grid(self.grids)
            if len(groups) == 1:
                trs = run_many(name, systems, self.grids[0], p, save=save, positions=positions)
            else:
                rows: list = [None] * len(systems)
                for idx in groups:
                    for k, tr in zip(idx, run_many(name, subset(systems, idx), self.grids[idx[0]], p,
                                                   save=save, positions=positions)):
                        rows[k] = tr
                trs = TrajectoryStack(rows)
        if save:
            for tr, s in zip(trs, systems):
                if tr.success and not tr.currents:
                    tr.currents = trajectory_currents(s, tr, save)
        self.shown[name] = trs

    def take_refined(self, name: str, better: dict[int, Trajectory]) -> None:
        """Replace *name*'s runs of the systems in *better* by their refined runs.

        A refined run is measured on its own points and shown on the shared ones.

        Parameters
        ----------
        name : str
            A solver that ran.
        better : dict of int to Trajectory
            Per system index, the run that replaces the first.
        """
        if not better:
            return
        if name not in self.own:
            self.shown[name] = TrajectoryStack([better.get(k, tr) for k, tr in enumerate(self.shown[name])])
            return
        self.own[name] = TrajectoryStack([sufficient(better[k], self.systems[k], self.preset)
                                          if k in better and not self.given else better.get(k, tr)
                                          for k, tr in enumerate(self.own[name])])
        self.shown[name] = TrajectoryStack([replace(better[k].resampled(self.grids[k], self.systems[k].joint_rates,
                                                                   self.systems[k].breakpoints()),
                                                    message=self.own[name][k].message) if k in better else tr
                                            for k, tr in enumerate(self.shown[name])])
        self.resampled.add(name)
