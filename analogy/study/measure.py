"""Each solver's errors against the reference, output by output, on its own points or their sufficient subset."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..circuit.currents import trajectory_currents
from ..circuit.node_stack import NodeStack
from ..circuit.scales import system_scales
from ..presets import Preset
from ..results.metrics import OutputErrors, stack_errors
from ..results.trajectory import Trajectory
from ..results.trajectory_stack import TrajectoryStack
from ..solvers.registry import run_many
from .grid import SUBSET_FROM, sufficient_points

__all__ = ["measure", "sufficient", "subset", "contact_outputs"]


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


def measure(systems, runs, native, ref_name, p, save=(), resampled=frozenset()) -> list[dict]:
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
    out: list[dict] = [{} for _ in systems]
    if ref_name is None:
        return out
    ref = runs[ref_name]
    n = systems[0].dof
    forces = contact_outputs(systems[0])        # measured like element currents, against their own peaks
    names = tuple(f"r{j + 1}" for j in range(n)) + tuple(f"i_{c}" for c in save) + forces
    measured = tuple(save) + forces
    for name, trs in runs.items():
        own = native.get(name, trs)
        for idx in own.by_grid():
            ok = [k for k in idx if name == ref_name or ref[k].success]
            if not ok:
                continue
            if name == ref_name:
                for k in ok:
                    out[k][name] = OutputErrors.zero(names)
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
            for j, k in enumerate(ok):
                if refs[j].success:
                    shapes.setdefault(own[k].rates.shape, []).append(j)
            for at in shapes.values():
                group = [ok[j] for j in at]
                a, b = _outputs(own.take(group), measured), _outputs(refs.take(at), measured)
                err, rel, whole = stack_errors(a, b, p.bound, [systems[k].topology.rounding for k in group])
                whole = whole.tolist()
                worst = np.argmax(np.where(np.isnan(rel), -np.inf, rel), axis=1)
                top, peaks, rows = np.max(err, axis=1).tolist(), rel[np.arange(len(group)), worst].tolist(), rel.tolist()
                for row, k in enumerate(group):      # plain floats: one record per scene, built cheaply
                    out[k][name] = OutputErrors(top[row], peaks[row], names[worst[row]],
                                                dict(zip(names, rows[row])), whole[row])
    return out
