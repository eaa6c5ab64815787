"""The one orchestrator: registered solvers on shared time points, errors against a reference."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from ..circuit.currents import trajectory_currents
from ..errors import InputError
from ..presets import DEFAULT_SOLVERS, Preset
from ..presets import preset as get_preset
from ..solvers.registry import SOLVER_NAMES, run_many, solver
from .estimate import MAX_REFINEMENTS, estimated_errors, refined_run
from .grid import output_grid
from .measure import measure, subset, sufficient
from .work import check_works
from ..results.metrics import OutputErrors, peak
from ..results.output import Tabular, html_table
from ..results.trajectory import Trajectory
from ..results.trajectory_stack import TrajectoryStack
from ..circuit.node_stack import NodeStack
from ..model.assembly import SINGULAR_CONDITION

if TYPE_CHECKING:
    from matplotlib.figure import Figure


__all__ = ["Comparison", "compare", "compare_many", "DEFAULT_SOLVERS", "SINGULAR_CONDITION"]


@dataclass(eq=False, slots=True)
class Comparison(Tabular):
    """Joint rates from several solvers on one time grid, with errors against a reference.

    Attributes
    ----------
    system : NodeDynamics
        The system that was solved.
    preset : str
        The accuracy preset's name.
    time : ndarray
        Shared time points: SPICE's own output points (t = 0 included) when SPICE
        ran and no output step was asked for, else a uniform grid.
    results : dict of str to Trajectory
        Successful solvers, in run order.
    failures : dict of str to str
        Solvers that failed, with the reason; the others are kept.
    skipped : dict of str to str
        Solvers asked for that do not apply to the system (the exact solver to a
        nonlinear one), with the reason: not failures.
    reference : str or None
        The solver the errors are measured against (None: no reference applied).
    bound : float
        The preset's promised worst error / peak (:attr:`Preset.bound`).
    energy : dict of str to float
        Nonlinear systems: per solver, max |T + U − T(0) − W| over the energy scale
        (:meth:`~analogy.circuit.nonlinear.NonlinearNodeSystem.energy_residual`).
    loop : dict of str to (float, float)
        Closed chains: per solver, the largest loop residual |Φ| and the largest
        equilibrated cond(Φ_p) along its run
        (:meth:`~analogy.circuit.nonlinear.NonlinearNodeSystem.loop_residual`).
    measured : dict of str to OutputErrors
        Per solver, measured on its own time points: every output (joint rate, element
        current asked for) against that output's own peak; indexed as a pair, (max |error|,
        the worst output's error over its peak).
    estimated : dict of str to OutputErrors
        Per solver, when asked for: its joint rates' errors estimated without a reference
        (:func:`~analogy.study.estimate.estimated_errors`), each against its own peak.
    unestimated : dict of str to str
        Solvers whose estimate was asked for and could not be made, with the reason.
    """

    system: object
    preset: str
    time: np.ndarray
    results: dict = field(default_factory=dict)
    failures: dict = field(default_factory=dict)
    reference: str | None = "exact"
    measured: dict = field(default_factory=dict)
    bound: float = math.nan
    energy: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)
    loop: dict = field(default_factory=dict)
    estimated: dict = field(default_factory=dict)
    unestimated: dict = field(default_factory=dict)

    @property
    def singular(self) -> str:
        """A sentence if the motion came near a singular pose of a closed chain, else ``""``."""
        worst = max((c for _, c in self.loop.values()), default=0.0)
        if worst < SINGULAR_CONDITION:
            return ""
        return (f"the motion comes near a singular pose of the loop (equilibrated cond(Φ_p) reaches {worst:.3g}, "
                f"past {SINGULAR_CONDITION:g}): its constraint forces grow without bound there, and no solver's "
                "error is promised")

    @property
    def peak(self) -> float:
        """max |R_ref| over joints and times (NaN without a reference)."""
        ref = self.results.get(self.reference) if self.reference else None
        return peak(ref.rates) if ref is not None else math.nan

    def errors(self) -> dict[str, OutputErrors]:
        """Per solver: (max |error|, the worst output's error over its own peak, …); NaN without a reference."""
        nan = OutputErrors(math.nan, math.nan, "", {}, math.nan)
        return {name: self.measured.get(name, nan) for name in self.results}

    def worst_output(self, solver: str) -> tuple[str, float]:
        """The output of *solver* farthest from the reference relative to its own peak, and that figure.

        Parameters
        ----------
        solver : str
            A solver that ran.
        """
        e = self.errors()[solver]
        return e.worst, e.relative

    def horizon(self, solver: str, tolerance: float = 1e-6) -> float:
        """The first time at which *solver* leaves the reference by more than *tolerance* of
        the peak rate (max over joints), on the shared points; inf if it never does.

        For a chaotic motion this predictability horizon, not the error, is the figure.

        Parameters
        ----------
        solver : str
            A solver that ran.
        tolerance : float
            Relative deviation that ends the horizon.
        """
        ref = self.results.get(self.reference) if self.reference else None
        tr = self.results.get(solver)
        if ref is None or tr is None or tr.rates.shape != ref.rates.shape:
            return math.nan
        deviation = np.max(np.abs(tr.rates - ref.rates), axis=1) / peak(ref.rates)
        past = np.flatnonzero(deviation > tolerance)
        return float(self.time[past[0]]) if past.size else math.inf

    def outside_bound(self) -> dict[str, float]:
        """Solvers whose error / peak exceeds the preset's bound: a broken promise, flagged.

        The error against the reference judges where one ran; else the estimate, where one was made.
        """
        out = {}
        for name, e in self.errors().items():
            judged = e[1] if not math.isnan(e[1]) else self.estimated.get(name, e)[1]
            if math.isnan(judged) and name in self.unestimated:
                judged = math.inf           # asked for and not to be had: no promise can be said kept
            if name != self.reference and judged > self.bound:
                out[name] = judged
        return out

    def max_relative_error(self, solver: str) -> float:
        """The worst error of *solver*'s outputs, each relative to its own peak.

        Parameters
        ----------
        solver : str
            A solver that ran.
        """
        return self.errors()[solver][1]

    def _rows(self) -> list[list]:
        rows = []
        for name in list(self.results) + [f for f in self.failures if f not in self.results]:
            tr = self.results.get(name)
            if tr is None:
                rows.append([name, "failed", "", "", "", "", "", "", self.failures[name]])
                continue
            err = self.errors()[name]
            st = tr.stats
            note = "reference" if name == self.reference else tr.message
            if name in self.loop and name not in ("ode", "reference"):        # those solve the loop exactly
                note = f"loop residual {self.loop[name][0]:.2e}" + (f", {note}" if note else "")
            if name in self.energy:
                note = f"energy residual {self.energy[name]:.2e}" + (f", {note}" if note else "")
            if name in self.unestimated:
                note = f"no estimate: {self.unestimated[name]}" + (f", {note}" if note else "")
            worst = "" if name == self.reference else err.worst
            if not self.reference and name in self.estimated:
                worst = self.estimated[name].worst
            worst = self.system.provenance.output_name(worst)
            est = self.estimated[name].relative if name in self.estimated else math.nan
            rows.append([name, tr.run_time * 1e3, err.absolute, worst, err.relative, est, err.whole,
                         "" if st.steps is None else st.steps, note])
        return rows + [[name, "skipped", "", "", "", "", "", "", why] for name, why in self.skipped.items()]

    def table(self) -> str:
        """A plain-text table of run time, error and steps per solver."""
        where = (f"errors against the {self.reference} solution, on each solver's own points, each output "
                 "against its own peak" if self.reference else
                 "no reference: errors estimated by refined runs" if self.estimated or self.unestimated else
                 "no reference, so no errors measured")
        circuit = ", realizable circuit" if getattr(self.system, "realizable", False) else ""
        rows = self._rows()
        width = max([14] + [len(str(row[3])) + 2 for row in rows])     # joint names are long
        lines = [f"robot {self.system.provenance.robot}, topology {self.system.topology.name}{circuit}, "
                 f"preset {self.preset}, {self.time.size} time points; {where}",
                 f"{'solver':<10}{'run time [ms]':>15}{'max |error|':>14}{'worst output':>{width}}"
                 f"{'error / peak':>14}" + (f"{'estimated':>12}" if self.estimated else "")
                 + f"{'all / peak':>12}{'steps':>8}"]
        for name, ms, e, worst, r, est, whole, steps, note in rows:
            if ms in ("failed", "skipped"):
                lines.append(f"{name:<10}  {'failed' if ms == 'failed' else 'does not apply'}: {note}")
                continue
            tail = f"  ({note})" if note else ""
            guess = (f"{est:>12.2e}" if est == est else f"{'-':>12}") if self.estimated else ""
            errs = (f"{e:>14.3e}{worst or '-':>{width}}{r:>14.3e}{guess}{whole:>12.2e}" if self.reference
                    else f"{'-':>14}{worst or '-':>{width}}{'-':>14}{guess}{'-':>12}")
            lines.append(f"{name:<10}{ms:>15.3f}{errs}{steps!s:>8}{tail}")
        if getattr(getattr(self.system, "joint", None), "unstable", False):
            lines.append("unstable equilibrium: K + ∂G/∂q has a negative eigenvalue, so the motion grows")
        if self.singular:
            lines.append(self.singular)
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def __repr__(self) -> str:
        worst = {k: v[1] for k, v in self.errors().items() if k != self.reference}
        errs = ", ".join(f"{k} {v:.2e}" for k, v in worst.items()) or "no errors"
        failed = f", {len(self.failures)} failed" if self.failures else ""
        return (f"<Comparison {self.system.provenance.robot}: {', '.join(self.results)} "
                f"on {self.time.size} points, error/peak vs {self.reference}: {errs}{failed}>")

    def _repr_html_(self) -> str:
        header = ["solver", "run time [ms]", "max |error|", "worst output", "error / its peak",
                  "estimated error / its peak", "all / largest peak", "steps", "note"]
        rows = self._rows()
        if not self.estimated:          # as the text table: the column only where an estimate ran
            header, rows = header[:5] + header[6:], [row[:5] + row[6:] for row in rows]
        return html_table(header, rows, self.caption)

    @property
    def caption(self) -> str:
        """Robot, topology, preset, time points and reference: what the table's figures are of."""
        return self.table().splitlines()[0]

    def columns(self) -> dict[str, np.ndarray]:
        """``time``, then every solver's joint rates ``r1_spice`` …"""
        n = self.system.dof
        cols = {"time": self.time}
        for s, tr in self.results.items():
            cols.update((f"r{j + 1}_{s}", tr.rates[:, j]) for j in range(n))
        return cols

    def plot(self, path=None) -> "Figure":
        """Joint rates of every solver and their errors against time; saved to *path* if given.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write (``.png``, ``.svg``, ``.pdf`` …).
        """
        from ..results.plots import plot_comparison
        return plot_comparison(self, path)


def _names(solvers: Sequence[str]) -> list[str]:
    names = list(dict.fromkeys(solvers))
    if not names:
        raise InputError(f"no solver named: use {', '.join(SOLVER_NAMES)}")
    for name in names:
        solver(name)                        # one clear sentence for an unknown name
    return names


def _reference(system, names: list[str], reference: str | None) -> str | None:
    if reference != "auto":
        if reference is not None:
            solver(reference)
        return reference
    for name in ("exact", "reference"):     # closed form where it applies, else the tight reference
        if solver(name).supports(system) is None:
            return name
    return None


def _by_grid(grids: Sequence[np.ndarray]) -> list[list[int]]:
    """Indices grouped by equal time grids (by value)."""
    groups: dict = {}
    for k, g in enumerate(grids):
        groups.setdefault(g.tobytes(), []).append(k)
    return list(groups.values())


def compare_many(systems: Sequence, preset: str | Preset = "accurate",
                 solvers: Sequence[str] = DEFAULT_SOLVERS, times=None, *,
                 reference: str | None = "auto", step: float | None = None,
                 save: Sequence[str] = (), positions: bool = False,
                 t_stop: float | None = None, forces=None,
                 progress: Callable[[str | None], None] | None = None, estimate: bool = False,
                 refine: bool = False) -> list[Comparison]:
    """:func:`compare` for many systems, each solver running them together where it can.

    SPICE runs the systems as one circuit to the longest horizon, each system's output
    ending at its own; the exact solver stacks them; errors are measured stacked on shared grids.

    Parameters
    ----------
    systems : sequence of NodeDynamics
        Systems of one kind (linear or nonlinear).
    preset : str or Preset
        Accuracy preset.
    solvers : sequence of str
        Registered solver names.
    times : array_like, optional
        Output times when no solver chooses its own and no *step* is given.
    reference : str or None
        The yardstick: ``"auto"`` is the exact solver where it applies; it runs even
        when *solvers* does not name it. None measures no errors.
    step : float, optional
        Output step: a uniform grid for every solver (SPICE is interpolated onto it,
        its error measured on its own points first).
    save : sequence of str
        Element currents to report in each :attr:`Trajectory.currents`.
    positions : bool
        Also keep node positions where the systems have springs.
    t_stop : float, optional
        End of the simulated interval [s] for every system, instead of their own.
    forces : sequence, optional
        Joint forces for every system, one entry per joint, instead of their own.
    progress : callable, optional
        Called with each solver's name as it starts and with None when it ends (a
        :class:`~analogy.progress.Heartbeat` prints lines on long runs).
    estimate : bool
        Also estimate each solver's error without the reference: each runs again under
        refined settings (:func:`~analogy.study.estimate.estimated_errors`), which costs
        about what the first run did, and twice that for SPICE.
    refine : bool
        Estimate; where an estimate exceeds the bound, take the refined run and refine that in
        turn (at most :data:`MAX_REFINEMENTS` times): the run reported is the first whose estimate
        meets the bound, or the finest tried (flagged). Its note says how many times.
    """
    if not systems:
        return []
    if t_stop is not None or forces is not None:
        systems = systems.driven(forces, t_stop) if isinstance(systems, NodeStack) else \
            [s.driven(forces, t_stop) for s in systems]
    p = get_preset(preset)
    names = _names(solvers)
    check_works(systems, p, spice="spice" in names)     # a run past the budget is refused before any starts
    ref_name = _reference(systems[0], names, reference)
    order = [s for s in SOLVER_NAMES if s in names or s == ref_name]
    order += [s for s in names if s not in order]
    if ref_name is not None and ref_name not in order:
        order.append(ref_name)
    order.sort(key=lambda s: not solver(s).own_grid)         # own time points first
    count = len(systems)
    ends = [s.t_stop for s in systems]
    # A given grid per horizon: systems of one horizon share it (and run stacked).
    given = None if step is None and times is None else {
        t: output_grid(t, step, p.steps) if times is None else np.asarray(times, float) for t in dict.fromkeys(ends)}
    runs: dict[str, list[Trajectory]] = {}
    native: dict[str, list[Trajectory]] = {}
    grids: list = [None if given is None else given[t] for t in ends]
    nonlinear = systems[0].kind != "linear"
    want_x = positions or bool(save) or nonlinear       # the energy balance needs positions
    skipped = {}
    resampled: set = set()          # own-grid solvers reported on another's points
    for name in list(order):
        reason = solver(name).supports(systems[0])
        if reason is not None:
            skipped[name] = reason
            order.remove(name)
    try:
        for name in order:
            s = solver(name)
            if progress is not None:
                progress(name)
            if s.own_grid:
                trs = run_many(name, systems, None, p, save=save, positions=want_x)
                if given is None:       # millions of own points: measured on their sufficient subset
                    trs = TrajectoryStack([sufficient(tr, systems[k], p) if tr.success and grids[k] is None
                                           else tr for k, tr in enumerate(trs)])
                native[name] = trs
                # Per system, the first own-grid solver that succeeds sets the shared grid; a later one
                # is reported on it (for the table and plots) and measured on its own points.
                if any(g is not None and tr.success for g, tr in zip(grids, trs)):
                    resampled.add(name)
                    trs = TrajectoryStack([tr.resampled(grids[k], sys_.joint_rates)
                                           if tr.success and grids[k] is not None else tr
                                           for k, (tr, sys_) in enumerate(zip(trs, systems))])
                grids = [tr.time if tr.success and grids[k] is None else grids[k] for k, tr in enumerate(trs)]
            else:
                default = {t: np.linspace(0.0, t, p.steps + 1) for t in dict.fromkeys(ends)}
                grids = [default[t] if g is None else g for g, t in zip(grids, ends)]
                groups = _by_grid(grids)
                if len(groups) == 1:
                    trs = run_many(name, systems, grids[0], p, save=save, positions=want_x)
                else:
                    rows: list = [None] * count
                    for idx in groups:
                        for k, tr in zip(idx, run_many(name, subset(systems, idx), grids[idx[0]], p,
                                                       save=save, positions=want_x)):
                            rows[k] = tr
                    trs = TrajectoryStack(rows)
            if save:
                for tr, sys_ in zip(trs, systems):
                    if tr.success and not tr.currents:
                        tr.currents = trajectory_currents(sys_, tr, save)
            runs[name] = trs
    finally:             # a heartbeat ends whatever happened
        if progress is not None:
            progress(None)
    out = []
    estimates, unestimated = [{} for _ in systems], {}
    if estimate or refine:
        if progress is not None:
            progress("estimates")
        try:
            estimates, unestimated, better = estimated_errors(systems, {n: native.get(n, runs[n]) for n in order}, p,
                                                              MAX_REFINEMENTS if refine else 0, save, want_x)
        finally:
            if progress is not None:
                progress(None)
        for n in order:         # a refined run replaces the first: measured on its own points, shown on the grid
            first, swap = native.get(n, runs[n]), {}
            for k, got in enumerate(better):
                if n in got:
                    tr, level, spent = got[n]
                    swap[k] = refined_run(tr, level, first[k].run_time + spent, estimates[k][n].relative <= p.bound,
                                          systems[k], save)
            if not swap:
                continue
            if solver(n).own_grid:
                native[n] = TrajectoryStack([sufficient(swap[k], systems[k], p) if k in swap and given is None
                                             else swap.get(k, tr) for k, tr in enumerate(native[n])])
                runs[n] = TrajectoryStack([replace(swap[k].resampled(grids[k], systems[k].joint_rates),  # all its points
                                                   message=native[n][k].message) if k in swap else tr
                                           for k, tr in enumerate(runs[n])])
                resampled.add(n)
            else:
                runs[n] = TrajectoryStack([swap.get(k, tr) for k, tr in enumerate(runs[n])])
    measured = measure(systems, runs, native, ref_name, p, tuple(save), resampled)
    columns = [(n, runs[n]) for n in order]
    for k, system in enumerate(systems):
        results, failures = {}, {}
        for n, trs in columns:
            tr = trs[k]
            if tr.success:
                results[n] = tr
            else:
                failures[n] = tr.message
        grid = grids[k] if grids[k] is not None else np.linspace(0.0, system.t_stop, p.steps + 1)
        ref = ref_name if ref_name in results else None
        energy, loop = {}, {}
        if nonlinear:
            for n in results:
                tr = native[n][k] if n in native else results[n]     # on the solver's own points
                if tr.success and tr.positions is not None:
                    closure = system.loop_residual(tr)
                    if closure is not None:
                        loop[n] = closure
                    try:
                        residual, scale = system.energy_residual(tr)
                        energy[n] = float(np.max(np.abs(residual))) / scale
                    except InputError:      # a closed chain's run went where its loop does not close
                        energy[n] = math.nan
        for n, tr in results.items():
            if n in estimates[k]:
                tr.estimated = estimates[k][n]
        out.append(Comparison(system, p.name, grid, results, failures, ref, measured[k] if ref else {},
                              p.bound, energy, skipped, loop, estimates[k], unestimated))
    return out


def compare(system, preset: str | Preset = "accurate", solvers: Sequence[str] = DEFAULT_SOLVERS,
            times=None, *, reference: str | None = "auto", step: float | None = None,
            save: Sequence[str] = (), positions: bool = False,
            t_stop: float | None = None, forces=None,
            progress: Callable[[str | None], None] | None = None, estimate: bool = False,
            refine: bool = False) -> Comparison:
    """Run the requested solvers on *system* and compare them on shared time points.

    A failing solver, or one that does not apply, is recorded in
    :attr:`Comparison.failures`; the others still run. Only bad input raises.

    Parameters
    ----------
    system : NodeDynamics
        The system to solve.
    preset : str or Preset
        Accuracy preset.
    solvers : sequence of str
        Registered solver names (:data:`~analogy.solvers.registry.SOLVER_NAMES`).
    times : array_like, optional
        Output times when SPICE does not run and no *step* is given.
    reference : str or None
        The yardstick (``"auto"``: the exact solver where it applies).
    step : float, optional
        Output step for every solver; errors are still measured on each solver's own points.
    save : sequence of str
        Element currents to report in each :attr:`Trajectory.currents`.
    positions : bool
        Also keep node positions where the system has springs.
    t_stop : float, optional
        End of the simulated interval [s], instead of the system's.
    forces : sequence, optional
        Joint forces, one entry per joint, instead of the system's (gravity is kept).
    progress : callable, optional
        Called with each solver's name as it starts and with None when it ends.
    estimate : bool
        Also estimate each solver's error without the reference (see :func:`compare_many`).
    refine : bool
        Refine a run whose estimate exceeds the bound until it meets it (see :func:`compare_many`).
    """
    return compare_many([system], preset, solvers, times, reference=reference, step=step,
                        save=save, positions=positions, t_stop=t_stop, forces=forces, progress=progress,
                        estimate=estimate, refine=refine)[0]
