"""Error estimates without a reference: each solver again under refined settings, Richardson's factor on the difference."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from ..circuit.currents import trajectory_currents
from ..circuit.scales import system_scales
from ..presets import Preset
from ..results.metrics import OutputErrors, judged_peaks, output_errors
from ..results.trajectory import Trajectory
from ..solvers.registry import run, run_many, solver
from ..solvers.transient import REFINE

__all__ = ["estimated_errors", "unresolved_outputs", "on_points", "refined_run", "REFINED_STEPS", "MAX_REFINEMENTS"]


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


def _estimate(coarse: np.ndarray, fine: np.ndarray, factor: float, names: Sequence[str],
              bound: float | None = None, rounding: float = 0.0) -> OutputErrors:
    err, rel = output_errors(coarse, fine, bound, rounding)
    err, rel = err * factor, rel * factor
    worst = int(np.argmax(np.where(np.isnan(rel), -np.inf, rel)))
    top = float(np.max(np.abs(fine))) if fine.size else np.nan
    whole = float(np.max(err)) / top if top > 0 else np.nan
    return OutputErrors(float(np.max(err)), float(rel[worst]), names[worst], dict(zip(names, rel.tolist())), whole)


def unresolved_outputs(system, time: np.ndarray, rates: np.ndarray, bound: float, stretch: float = 1.0) -> dict[str, str]:
    """Outputs of a SPICE run that move on a decay its steps do not resolve, and why.

    A preset's step cap leaves a decay to ngspice's truncation check, and ignores one under
    ten times the bound of the largest peak (:meth:`~analogy.circuit.scales.Scales.fastest`).
    An output whose own peak is as small as such a decay's share can still be all of it;
    stepped at β·h > 1 the trapezoidal rule turns the decay into a ringing that a run with
    twice shorter steps repeats, so Richardson's difference cannot see it. Such an output
    has no estimate: where a decay's share of the peak exceeds the bound of that output's
    own peak, every step while it lasts after a force's corner (and after t = 0, unless the
    system starts at rest with no force) must keep β·h ≤ 1. Conservative: every decay is
    held against every output small enough to be all of it, coupled to it or not.

    Parameters
    ----------
    system : NodeDynamics
        The system (its :class:`~analogy.circuit.scales.Scales` give the decays and their shares).
    time : ndarray
        Time points whose intervals, times *stretch*, are the run's steps.
    rates : ndarray, shape (N, n)
        Its joint rates (their peaks, relative to the largest).
    bound : float
        The preset's bound.
    stretch : float
        The run's steps over the intervals of *time* (REFINE where *time* is its refined run's,
        the run itself being measured on a subset of its points).
    """
    scales = system_scales(system)
    own = np.max(np.abs(rates), axis=0)
    top = float(np.max(own)) if own.size else 0.0
    if not top > 0 or time.size < 2 or not scales.decays.size:
        return {}
    steps = np.diff(time) * stretch
    corners = [float(c) for c in system.breakpoints() if c < time[-1]]
    at_rest = (system.kind == "linear" and not np.any(system.initial_voltages)
               and not np.any(system.force(min(corners + [time[-1]]) * 0.5)))
    starts = sorted(set(corners) | (set() if at_rest else {0.0}))
    out: dict[str, str] = {}
    for beta, share in zip(scales.decays, scales.shares):
        for j, peak in enumerate(own / top):
            allowed = bound * float(judged_peaks(peak, 1.0, bound, system.topology.rounding))
            if not (beta > 0 and share > allowed) or f"r{j + 1}" in out:
                continue
            lasts = math.log(share / allowed) / beta         # until the decay is under the allowance
            for start in starts:
                first, last = np.searchsorted(time, [start, start + lasts])
                h = float(np.max(steps[max(first - 1, 0):max(last, first) + 1], initial=0.0))
                if beta * h > 1:
                    out[f"r{j + 1}"] = (f"r{j + 1} may move on a decay of {beta:.3g}/s ({share:.2g} of the peak "
                                        f"velocity) that steps of {h:.3g} s after t = {start:g} s do not resolve "
                                        f"(β·h = {beta * h:.3g})")
                    break
    return out


#: The most refinements past the first estimate when a run must meet its bound: a reported run of up
#: to 2³ times the steps (SPICE), estimated by one of 2⁴, so 1 + 2 + 4 + 8 + 16 = 31 times the first
#: run's cost in all; or rtol up to 10⁶ times tighter (ODE).
MAX_REFINEMENTS = 3

#: A refined run must take at least this share of REFINE times the first run's steps: Richardson's
#: factor assumes every step was shortened.
REFINED_STEPS = 0.75


def _not_refined(coarse: Trajectory, fine: Trajectory) -> str:
    """Why *fine* is no refinement of *coarse* (too few steps, another method), or ``""``."""
    ran = [(getattr(tr.settings, "loosen", None), getattr(tr.settings, "method", None)) for tr in (coarse, fine)]
    if fine.message.startswith("retried") and (ran[0] != ran[1] or ran[0][0] is None):
        # a retry that the first run did not need changes abstol or the method, not only the step
        return f"its refined run had to be retried, so it is no refinement ({fine.message})"
    steps, more = coarse.stats.steps, fine.stats.steps
    if steps and more is not None and more < REFINED_STEPS * REFINE * steps:
        return f"its refined run took {more:,} steps against {steps:,}, not about {REFINE:g} times as many"
    return ""


def _judged(system, coarse: Trajectory, fine: Trajectory, factor: float, names, preset: Preset, own_grid: bool,
            missing: dict, name: str) -> OutputErrors:
    """The estimate of *coarse* from *fine*; no claim where an output is one its steps cannot see."""
    values = on_points(fine, coarse.time, system.breakpoints()) if own_grid else fine.rates
    est = _estimate(coarse.rates, values, factor, names, preset.bound, system.topology.rounding)
    if not own_grid:
        return est
    whole = coarse.stats.steps is None or coarse.time.size > coarse.stats.steps   # not a subset of its points
    blind = unresolved_outputs(system, coarse.time if whole else fine.time, values, preset.bound,
                               1.0 if whole else REFINE)
    if not blind:
        return est
    missing[name] = "; ".join(blind.values())
    return est._replace(relative=math.nan, worst=next(iter(blind)),
                        per_output={o: (math.nan if o in blind else e) for o, e in est.per_output.items()})


def estimated_errors(systems: Sequence, runs: dict[str, Sequence[Trajectory]], preset: Preset,
                     refine: int = 0, save: Sequence[str] = (), positions: bool = False) -> \
        tuple[list[dict[str, OutputErrors]], dict[str, str], list[dict]]:
    """Per system and solver, the estimated error of its joint rates, each against its own peak;
    with *refine*, the run refined until its estimate meets the bound.

    Each solver with :meth:`~analogy.solvers.registry.Solver.refinements` runs again under the
    first of them that refines its run (the next where one fails or is no refinement); the
    difference of the two runs on the first run's own points, times the refinement's factor,
    is the estimate (Richardson's). A solver with its own points (SPICE) is read between the
    second run's points by :func:`on_points`.

    Where the estimate exceeds the bound and *refine* allows, the refined run becomes the run
    to judge, and it is refined once more (the same rung again) for its own estimate: at most
    *refine* times, each halving SPICE's steps (or the ODE's rtol a hundred times tighter).
    The run handed back is always one whose error was estimated, never a prediction.

    Parameters
    ----------
    systems : sequence of NodeDynamics
        The systems.
    runs : dict of str to sequence of Trajectory
        Each solver's trajectories, one per system, on the solver's own points.
    preset : Preset
        The settings they ran with.
    refine : int
        The most refinements past the first estimate, for a run estimated past the bound.
    save, positions :
        What a refined run that may replace the first must keep (element currents, node
        positions), as the first run was asked for.

    Returns
    -------
    estimates : list of dict of str to OutputErrors
        One dict per system.
    missing : dict of str to str
        Solvers with no estimate, and why (no refined settings; the refined run failed; an
        output its steps cannot see). The yardsticks (exact, reference) are in neither.
    refined : list of dict of str to (Trajectory, int, float)
        One dict per system: each solver whose run was replaced by a refined one, with how
        many times it was refined and the seconds every refined run took (those refused too).
    """
    out: list[dict] = [{} for _ in systems]
    better: list[dict] = [{} for _ in systems]
    missing: dict[str, str] = {}
    names = tuple(f"r{j + 1}" for j in range(systems[0].dof)) if len(systems) else ()
    keep = {"save": tuple(save), "positions": positions} if refine else {}
    for name, trs in runs.items():
        s = solver(name)
        ladder = s.refinements(preset)
        if not ladder:
            if not s.yardstick:
                missing[name] = f"the {name} solver has no refined settings to estimate its error with"
            continue
        todo = [k for k, tr in enumerate(trs) if tr.success]
        why = ""
        for rung, (finer, factor) in enumerate(ladder):     # each rung for the systems the one before could not refine
            if not todo:
                break
            fines = _runs(s, name, [systems[k] for k in todo], [trs[k] for k in todo], finer, keep)
            left = []
            for k, fine in zip(todo, fines):
                coarse = trs[k]
                reason = f"its refined run failed: {fine.message}" if not fine.success else \
                    (_not_refined(coarse, fine) if s.own_grid else "")
                if reason:
                    why = reason
                    left.append(k)
                    continue
                out[k][name] = _judged(systems[k], coarse, fine, factor, names, preset, s.own_grid, missing, name)
                if refine:
                    _refine(s, name, systems[k], fine, finer, factor, rung, preset, refine, names, out[k], better[k],
                            missing, keep)
            todo = left
        if todo:                               # no rung refined these: no estimate, the last reason said
            missing[name] = why
    return out, missing, better


def _runs(s, name: str, systems: Sequence, coarse: Sequence[Trajectory], finer: Preset,
          keep: dict) -> list[Trajectory]:
    """*systems* run again under *finer* (keeping what *keep* asks): together where the solver
    chooses its points, else on the coarse runs' points."""
    if s.own_grid:
        return list(run_many(name, systems, None, finer, **keep))
    return [run(name, system, tr.time, finer, **keep) for system, tr in zip(systems, coarse)]


def _refine(s, name: str, system, fine: Trajectory, finer: Preset, factor: float, rung: int, preset: Preset,
            most: int, names, estimates: dict, better: dict, missing: dict, keep: dict) -> None:
    """While *name*'s estimate exceeds the bound, take its refined run as the run and refine that
    once more by the same rung (at most *most* times), as long as each estimate falls at least
    REFINE times (REFINE² expected); the last run so estimated replaces the first."""
    spent = _seconds(fine)
    for level in range(1, most + 1):
        est = estimates.get(name)
        if est is None or not est.relative > preset.bound:      # met, or no claim (NaN): stop
            break
        for finest, factor in s.refinements(finer)[rung:]:     # the same rung, or the next where it does not refine
            again = _runs(s, name, [system], [fine], finest, keep)[0]
            spent += _seconds(again)
            if again.success and not (s.own_grid and _not_refined(fine, again)):
                break
        else:
            break           # no refinement of the run: the last estimate stands, past the bound (flagged)
        blind: dict = {}
        new = _judged(system, fine, again, factor, names, finer, s.own_grid, blind, name)
        if not new.relative <= est.relative / REFINE:
            # not falling as the step's square: past the range where Richardson's premise holds (a
            # nonlinear circuit's Newton tolerance), so the run before stands with its estimate
            break
        missing.update(blind)
        estimates[name] = new
        better[name] = (fine, level, spent)
        fine, finer = again, finest
    if name in better:                  # every refined run counted, those refused too
        better[name] = better[name][:2] + (spent,)


def _seconds(tr: Trajectory) -> float:
    return tr.run_time if math.isfinite(tr.run_time) else 0.0


def refined_run(tr: Trajectory, level: int, seconds: float, met: bool, system, save: Sequence[str]) -> Trajectory:
    """*tr*, a refined run that replaces the first, with a note of how many times it was refined
    for its bound and what every run cost, and the element currents *save* asks for.

    Parameters
    ----------
    tr : Trajectory
        The refined run.
    level : int
        How many times it was refined past the first estimate.
    seconds : float
        What the first run and every refined run took.
    met : bool
        Its estimate meets the bound.
    system : NodeDynamics
        Its system (element currents from its node voltages).
    save : sequence of str
        Element currents to report, as the first runs got them.
    """
    if save and not tr.currents:
        tr.currents = trajectory_currents(system, tr, save)
    note = f"refined {level} time{'s' if level > 1 else ''} " + ("to meet the bound" if met else
                                                                "(its estimate still exceeds the bound)")
    tr.message = "; ".join(m for m in (tr.message, f"{note}, {seconds:.3g} s for all runs") if m)
    return tr
