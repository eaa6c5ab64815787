"""Error estimates without a reference: each solver again under refined settings, Richardson's factor on the difference."""

from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from ..presets import Preset
from ..results.metrics import OutputErrors, output_errors
from ..results.trajectory import Trajectory
from ..solvers.registry import run, run_many, solver

__all__ = ["estimated_errors", "on_points"]


def on_points(tr: Trajectory, times: np.ndarray, breakpoints: np.ndarray) -> np.ndarray:
    """*tr*'s joint rates at *times*: a cubic spline through its own points on each interval
    between the forces' *breakpoints*, where the rates are smooth.

    A spline's error is O(h⁴) of the step, far under the O(h²) error of the trapezoidal rule
    it measures; across a breakpoint the rates have a corner, which no spline spans.

    Parameters
    ----------
    tr : Trajectory
        A successful trajectory on its own points.
    times : ndarray
        Times within its span.
    breakpoints : ndarray
        The forces' breakpoints (t_stop among them or not).
    """
    t, y = tr.time, tr.rates
    span = float(t[-1]) if t.size else 0.0
    keep = np.append(np.diff(t) > 1e-12 * span, True)       # of two coinciding points, the later one
    t, y = t[keep], y[keep]
    edges = np.unique(np.concatenate([[0.0], np.asarray(breakpoints, float), [span]]))
    edges = edges[(edges >= 0.0) & (edges <= span)]
    out = np.empty((len(times), y.shape[1]))
    for a, b in zip(edges[:-1], edges[1:]):
        inside = (times >= a) & (times <= b)
        if not inside.any():
            continue
        src = (t >= a) & (t <= b)
        if np.count_nonzero(src) < 2:
            out[inside] = np.column_stack([np.interp(times[inside], t, y[:, j]) for j in range(y.shape[1])])
            continue
        out[inside] = CubicSpline(t[src], y[src], axis=0)(times[inside])
    return out


def _estimate(coarse: np.ndarray, fine: np.ndarray, factor: float, names: Sequence[str]) -> OutputErrors:
    err, rel = output_errors(coarse, fine)
    err, rel = err * factor, rel * factor
    worst = int(np.argmax(np.where(np.isnan(rel), -np.inf, rel)))
    top = float(np.max(np.abs(fine))) if fine.size else np.nan
    whole = float(np.max(err)) / top if top > 0 else np.nan
    return OutputErrors(float(np.max(err)), float(rel[worst]), names[worst], dict(zip(names, rel.tolist())), whole)


def estimated_errors(systems: Sequence, runs: dict[str, Sequence[Trajectory]], preset: Preset) -> \
        tuple[list[dict[str, OutputErrors]], dict[str, str]]:
    """Per system and solver, the estimated error of its joint rates, each against its own peak.

    Each solver with a :meth:`~analogy.solvers.registry.Solver.refinement` runs again under
    it; the difference of the two runs on the first run's own points, times the refinement's
    factor, is the estimate (Richardson's). A solver with its own points (SPICE) is read
    between the second run's points by :func:`on_points`.

    Parameters
    ----------
    systems : sequence of NodeDynamics
        The systems.
    runs : dict of str to sequence of Trajectory
        Each solver's trajectories, one per system, on the solver's own points.
    preset : Preset
        The settings they ran with.

    Returns
    -------
    estimates : list of dict of str to OutputErrors
        One dict per system.
    missing : dict of str to str
        Solvers with no estimate, and why (a closed form; the refined run failed).
    """
    out: list[dict] = [{} for _ in systems]
    missing: dict[str, str] = {}
    names = tuple(f"r{j + 1}" for j in range(systems[0].dof)) if len(systems) else ()
    for name, trs in runs.items():
        s = solver(name)
        refinement = s.refinement(preset)
        if refinement is None:
            continue
        finer, factor = refinement
        ok = [k for k, tr in enumerate(trs) if tr.success]
        if not ok:
            continue
        if s.own_grid:
            fines = run_many(name, [systems[k] for k in ok], None, finer)
        else:
            fines = [run(name, systems[k], trs[k].time, finer) for k in ok]
        for k, fine in zip(ok, fines):
            if not fine.success:
                missing[name] = f"its refined run failed: {fine.message}"
                continue
            coarse = trs[k]
            values = on_points(fine, coarse.time, systems[k].breakpoints()) if s.own_grid else fine.rates
            out[k][name] = _estimate(coarse.rates, values, factor, names)
    return out, missing
