"""Each solver's errors against the reference, output by output, on its own points or their sufficient subset."""

from __future__ import annotations

from typing import Sequence, overload

import numpy as np

from ..circuit.currents import trajectory_currents
from ..circuit.node_stack import NodeStack, shared_row
from ..circuit.scales import system_scales
from ..presets import Preset
from ..results.metrics import OutputErrors, stack_errors
from ..results.trajectory import Trajectory
from ..results.trajectory_stack import TrajectoryStack
from ..solvers.registry import run_many
from .grid import SUBSET_FROM, sufficient_points

__all__ = ["measure", "MeasuredErrors", "sufficient", "subset", "contact_outputs"]


def subset(systems: Sequence, rows: list[int]) -> Sequence:
    """The systems of *rows*: a sub-stack of a node stack, else a list.

    Parameters
    ----------
    systems : sequence of NodeDynamics
        The systems (a :class:`~analogy.circuit.node_stack.NodeStack` or a list).
    rows : list of int
        Their indices.
    """
    return systems.take(rows) if isinstance(systems, NodeStack) else [systems[k] for k in rows]


def sufficient(tr: Trajectory, system, p: Preset) -> Trajectory:
    """*tr* on the sufficient subset of its own points (:func:`~analogy.study.grid.sufficient_points`), or as it is.

    Parameters
    ----------
    tr : Trajectory
        A successful run on its own points.
    system : NodeDynamics
        Its system (the fastest rate in its error, the forces' corners).
    p : Preset
        The settings it ran with (their bound sets which decays count).
    """
    if tr.time.size <= SUBSET_FROM or contact_outputs(system):
        return tr           # a contact's switch is faster than any rate of the circuit's scales
    omega = system_scales(system).fastest(p.bound)
    rows = sufficient_points(tr.time, omega, system.breakpoints())
    if rows is None:
        return tr
    reach = omega * float(np.max(np.diff(tr.time[rows])))
    return tr.at(rows, f"measured on {rows.size:,} of its {tr.time.size:,} points, ω_max·Δt ≤ {reach:.2g}: "
                       f"the largest error within a factor {1 - reach / 2:.3g} of that over all")


def contact_outputs(system) -> tuple[str, ...]:
    """The contact forces ``f_<contact>`` a system's runs carry beside its joint rates (none without contacts).

    Parameters
    ----------
    system : NodeDynamics
        The system.
    """
    contacts = getattr(getattr(system, "functions", None), "contacts", None)
    return () if contacts is None else tuple(f"f_{name}" for name in contacts.names)


def _outputs(stack: TrajectoryStack, names: Sequence[str]) -> np.ndarray:
    """Joint rates, then the element currents *names*, as one (count, N, outputs) stack."""
    if not names:
        return stack.rates
    currents = np.stack([np.column_stack([tr.currents[c] for c in names]) for tr in stack])
    return np.concatenate([stack.rates, currents], axis=2)


class MeasuredErrors(Sequence):
    """Per system, each solver's :class:`OutputErrors`: kept as the arrays they were measured in,
    a system's records made when it is asked for, and each solver's errors as one column.

    Parameters
    ----------
    count : int
        Systems measured.
    names : tuple of str
        The outputs (joint rates ``r1`` …, then currents and contact forces).
    """

    def __init__(self, count: int, names: tuple):
        self.names = names
        self._blocks: list[tuple] = []      # (solver, rows, absolute, relative, worst, per output, whole)
        self._rows: list = [None] * count

    def add(self, name: str, rows: list[int], absolute: np.ndarray, relative: np.ndarray, worst: np.ndarray,
            per_output: np.ndarray, whole: np.ndarray) -> None:
        """Solver *name*'s errors on systems *rows*: per row, its largest error, worst relative error, the
        index of the output that has it, each output's relative error and the whole stack's.

        Parameters
        ----------
        name : str
            The solver.
        rows : list of int
            The systems.
        absolute, relative, worst : ndarray, shape (len(rows),)
            Per row: the largest error, the worst output's error over its peak, and that output's index.
        per_output : ndarray, shape (len(rows), outputs)
            Each output's error over its own peak.
        whole : ndarray, shape (len(rows),)
            Per row, the largest error over the largest output's peak.
        """
        self._blocks.append((name, rows, absolute, relative, worst, per_output, whole))
        self._rows = [None] * len(self._rows)

    def __len__(self) -> int:
        return len(self._rows)

    @overload
    def __getitem__(self, index: int) -> dict: ...

    @overload
    def __getitem__(self, index: slice) -> list: ...

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[k] for k in range(len(self))[index]]
        if self._rows[index] is None:
            self._make_rows()
        return self._rows[index]

    def _make_rows(self) -> None:
        """Every system's records, made once from the blocks (plain floats: one record per system)."""
        out: list[dict] = [{} for _ in self._rows]
        names = self.names
        for name, rows, absolute, relative, worst, per_output, whole in self._blocks:
            if absolute is None:            # the reference against itself
                for k in rows:
                    out[k][name] = OutputErrors.zero(names)
                continue
            for k, a, r, w, each, all_ in zip(rows, absolute.tolist(), relative.tolist(), worst.tolist(),
                                               per_output.tolist(), whole.tolist()):
                out[k][name] = OutputErrors(a, r, names[w], dict(zip(names, each)), all_)
        self._rows = out

    def relative(self, name: str) -> np.ndarray:
        """Solver *name*'s worst error over each output's peak, per system (NaN where not measured).

        Parameters
        ----------
        name : str
            A solver.
        """
        out = np.full(len(self), np.nan)
        for solver, rows, _, relative, *_ in self._blocks:
            if solver == name:
                out[rows] = 0.0 if relative is None else relative
        return out


def measure(systems, runs, native, ref_name, p, save=(), resampled=frozenset()) -> MeasuredErrors:
    """Per system and solver, its :class:`OutputErrors` against the reference, on its own points.

    Parameters
    ----------
    systems : sequence of NodeDynamics
        The systems.
    runs : dict of str to TrajectoryStack
        Each solver's trajectories as reported (perhaps on another solver's points).
    native : dict of str to TrajectoryStack
        The own-grid solvers' trajectories on their own points.
    ref_name : str or None
        The reference solver (None: nothing is measured).
    p : Preset
        The settings the reference runs with where it must run again on a solver's own points.
    save : sequence of str
        Element currents measured beside the joint rates.
    resampled : set of str
        Solvers whose reported points are not their own.
    """
    first = shared_row(systems)
    n = first.dof
    forces = contact_outputs(first)        # measured like element currents, against their own peaks
    names = tuple(f"r{j + 1}" for j in range(n)) + tuple(f"i_{c}" for c in save) + forces
    out = MeasuredErrors(len(systems), names)
    if ref_name is None:
        return out
    ref = runs[ref_name]
    succeeded = ref.successes
    shared = isinstance(systems, NodeStack) and systems.shares_inputs    # one map: its first row's rounding
    measured = tuple(save) + forces
    for name, trs in runs.items():
        own = native.get(name, trs)
        for idx in own.by_grid():
            ok = idx if name == ref_name or succeeded[idx].all() else [k for k in idx if succeeded[k]]
            if not ok:
                continue
            if name == ref_name:
                out.add(name, ok, None, None, None, None, None)
                continue
            if name in resampled:      # measured on its own points, with the reference there
                refs = run_many(ref_name, subset(systems, ok), own[ok[0]].time, p, positions=bool(save))
                if save:
                    for j, k in enumerate(ok):
                        if refs[j].success and not refs[j].currents:
                            refs[j].currents = trajectory_currents(systems[k], refs[j], save)
                        if not own[k].currents:
                            own[k].currents = trajectory_currents(systems[k], own[k], save)
            else:
                refs = ref.take(ok)
            shapes: dict = {}
            if own.whole and refs.whole and refs.successes.all():      # one grid, every reference run
                shapes[None] = list(range(len(ok)))
            else:
                for j, k in enumerate(ok):
                    if refs[j].success:
                        shapes.setdefault(own[k].rates.shape, []).append(j)
            for at in shapes.values():
                group = [ok[j] for j in at]
                a, b = _outputs(own.take(group), measured), _outputs(refs.take(at), measured)
                rounding = first.topology.rounding if shared else [systems[k].topology.rounding for k in group]
                err, rel, whole = stack_errors(a, b, p.bound, rounding)
                worst = np.argmax(np.where(np.isnan(rel), -np.inf, rel), axis=1)
                out.add(name, group, np.max(err, axis=1), rel[np.arange(len(group)), worst], worst, rel, whole)
    return out
