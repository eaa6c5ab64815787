"""The one orchestrator: registered solvers on shared time points, errors against a reference."""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, Iterator, Sequence

import numpy as np

from ..errors import InputError
from ..presets import DEFAULT_SOLVERS, Preset
from ..presets import preset as get_preset
from ..solvers.registry import SOLVER_NAMES, solver
from .estimate import MAX_REFINEMENTS, estimated_errors, refined_run
from .comparisons import Comparisons
from .measure import MeasuredErrors, contact_outputs, measure
from .solver_record import SolverRecord
from .stack_runs import StackRuns
from .work import check_works
from ..results.metrics import OutputErrors, peak
from ..results.output import Tabular, html_table
from ..results.trajectory import Trajectory
from ..circuit.node_stack import NodeStack, shared_row
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
    records : dict of str to SolverRecord
        One record per solver asked for (and the reference): its run, its errors, its
        estimate, its status. Solvers that ran or failed come in run order, then those
        that do not apply.
    reference : str or None
        The solver the errors are measured against (None: no reference applied).
    bound : float
        The preset's promised worst error / peak (:attr:`Preset.bound`).

    The dictionaries below are views of :attr:`records`, by solver name.
    """

    system: object
    preset: str
    time: np.ndarray
    records: dict = field(default_factory=dict)
    reference: str | None = "exact"
    bound: float = math.nan

    def _of(self, value: Callable[[SolverRecord], object], keep: Callable[[SolverRecord], bool]) -> dict:
        return {n: value(r) for n, r in self.records.items() if keep(r)}

    @property
    def results(self) -> dict[str, Trajectory]:
        """Successful solvers' trajectories on the shared points, in run order."""
        return self._of(lambda r: r.trajectory, lambda r: r.ran)

    @property
    def failures(self) -> dict[str, str]:
        """Solvers that failed, with the reason; the others were kept."""
        return self._of(lambda r: r.reason, lambda r: r.status == "failed")

    @property
    def skipped(self) -> dict[str, str]:
        """Solvers asked for that do not apply to the system (the exact solver to a nonlinear one): not failures."""
        return self._of(lambda r: r.reason, lambda r: r.status == "skipped")

    @property
    def measured(self) -> dict[str, OutputErrors]:
        """Per solver, every output (joint rate, element current asked for) against the reference on the
        solver's own points, each against its own peak; indexed as a pair, (max |error|, worst error / peak)."""
        return self._of(lambda r: r.errors, lambda r: r.errors is not None)

    @property
    def estimated(self) -> dict[str, OutputErrors]:
        """Per solver, when asked for: its errors estimated without a reference
        (:func:`~analogy.study.estimate.estimated_errors`), each output against its own peak."""
        return self._of(lambda r: r.estimate, lambda r: r.estimate is not None)

    @property
    def unestimated(self) -> dict[str, str]:
        """Solvers whose estimate was asked for and could not be made, with the reason."""
        return self._of(lambda r: r.unestimated, lambda r: bool(r.unestimated))

    @property
    def energy(self) -> dict[str, float]:
        """Nonlinear systems: per solver, max |T + U − T(0) − W| over the energy scale
        (:meth:`~analogy.circuit.nonlinear.NonlinearNodeSystem.energy_residual`)."""
        return self._of(lambda r: r.energy, lambda r: r.energy is not None)

    @property
    def loop(self) -> dict[str, tuple[float, float]]:
        """Closed chains: per solver, the largest loop residual |Φ| and the largest equilibrated
        cond(Φ_p) along its run (:meth:`~analogy.circuit.nonlinear.NonlinearNodeSystem.loop_residual`)."""
        return self._of(lambda r: r.loop, lambda r: r.loop is not None)

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
        return {n: r.errors or nan for n, r in self.records.items() if r.ran}

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
        for name, r in self.records.items():
            if not r.ran or name == self.reference:
                continue
            judged = r.relative_error
            if math.isnan(judged) and r.estimate is not None:
                judged = r.estimate.relative
            if math.isnan(judged) and r.unestimated:
                judged = math.inf           # asked for and not to be had: no promise can be said kept
            if judged > self.bound:
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
        rows, blank = [], [""] * 6
        ran = [r for r in self.records.values() if r.ran]
        for r in ran + [r for r in self.records.values() if not r.ran]:
            if not r.ran:
                rows.append([r.name, r.status, *blank, r.reason])
                continue
            err, st = r.errors or OutputErrors(math.nan, math.nan, "", {}, math.nan), r.trajectory.stats
            note = "reference" if r.name == self.reference else r.trajectory.message
            if r.loop is not None and r.name not in ("ode", "reference"):        # those solve the loop exactly
                note = f"loop residual {r.loop[0]:.2e}" + (f", {note}" if note else "")
            if r.energy is not None:
                note = f"energy residual {r.energy:.2e}" + (f", {note}" if note else "")
            if r.unestimated:
                note = f"no estimate: {r.unestimated}" + (f", {note}" if note else "")
            worst = "" if r.name == self.reference else err.worst
            if not self.reference and r.estimate is not None:
                worst = r.estimate.worst
            worst = self.system.provenance.output_name(worst)
            est = math.nan if r.estimate is None else r.estimate.relative
            rows.append([r.name, r.trajectory.run_time * 1e3, err.absolute, worst, err.relative, est, err.whole,
                         "" if st.steps is None else st.steps, note])
        return rows

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
        """``time``, then every solver's joint rates ``r1_spice`` … and contact forces ``f_foot_spice`` …"""
        n = self.system.dof
        cols = {"time": self.time}
        for s, tr in self.results.items():
            cols.update((f"r{j + 1}_{s}", tr.rates[:, j]) for j in range(n))
            cols.update((f"{name}_{s}", tr.currents[name]) for name in contact_outputs(self.system)
                        if name in tr.currents and tr.currents[name].shape == self.time.shape)
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


def compare_many(systems: Sequence, preset: str | Preset = "accurate",
                 solvers: Sequence[str] = DEFAULT_SOLVERS, times=None, *,
                 reference: str | None = "auto", step: float | None = None,
                 save: Sequence[str] = (), positions: bool = False,
                 t_stop: float | None = None, forces=None,
                 progress: Callable[[str | None], None] | None = None, estimate: bool = False,
                 refine: bool = False) -> Comparisons[Comparison]:
    """:func:`compare` for many systems, each solver running them together where it can: their
    :class:`~analogy.study.comparisons.Comparisons`, each system's :class:`Comparison` made when asked for.

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
        p = get_preset(preset)
        return Comparisons(lambda k: None, {}, MeasuredErrors(0, ()), {}, None, p.name, p.bound)
    if t_stop is not None or forces is not None:
        systems = systems.driven(forces, t_stop) if isinstance(systems, NodeStack) else \
            [s.driven(forces, t_stop) for s in systems]
    p = get_preset(preset)
    names = _names(solvers)
    check_works(systems, p, spice="spice" in names)     # a run past the budget is refused before any starts
    first = shared_row(systems)
    ref_name = _reference(first, names, reference)
    order, skipped = _run_order(first, names, ref_name)
    positions = positions or bool(save) or first.kind != "linear"     # the energy balance needs positions
    runs = StackRuns.start(systems, p, step, times)
    with _announced(progress) as tell:
        for name in order:
            tell(name)
            runs.run(name, save, positions)
    estimates: list[dict] = [{} for _ in range(len(systems))]
    unestimated: dict = {}
    if estimate or refine:
        estimates, unestimated = _estimates(runs, order, MAX_REFINEMENTS if refine else 0, save, positions, progress)
    measured = measure(systems, runs.shown, runs.own, ref_name, p, tuple(save), runs.resampled)
    return Comparisons(lambda k: _comparison(k, systems[k], runs, order, skipped, ref_name, measured[k],
                                             estimates[k], unestimated),
                       runs.shown, measured, skipped, ref_name if ref_name in runs.shown else None, p.name, p.bound)


def _run_order(system, names: list[str], ref_name: str | None) -> tuple[list[str], dict[str, str]]:
    """The solvers that apply, own time points first, and those that do not, with the reason."""
    order = [s for s in SOLVER_NAMES if s in names or s == ref_name]
    order += [s for s in names if s not in order]
    if ref_name is not None and ref_name not in order:
        order.append(ref_name)
    order.sort(key=lambda s: not solver(s).own_grid)
    why = {name: solver(name).supports(system) for name in order}
    return [n for n in order if why[n] is None], {n: r for n, r in why.items() if r is not None}


@contextmanager
def _announced(progress: Callable[[str | None], None] | None) -> Iterator[Callable[[str], None]]:
    """*progress* told of each stage as it starts, and once with None when they end, whatever happened."""
    try:
        yield progress if progress is not None else (lambda stage: None)
    finally:
        if progress is not None:
            progress(None)


def _estimates(runs: StackRuns, order: list[str], refinements: int, save: Sequence[str], positions: bool,
               progress) -> tuple[list[dict], dict]:
    """Each solver's errors estimated without a reference; a refined run replaces the first where one was made."""
    p, systems = runs.preset, runs.systems
    with _announced(progress) as tell:
        tell("estimates")
        estimates, unestimated, better = estimated_errors(systems, {n: runs.solved(n) for n in order}, p,
                                                          refinements, save, positions)
    for n in order:
        first = runs.solved(n)
        runs.take_refined(n, {k: refined_run(got[n][0], got[n][1], first[k].run_time + got[n][2],
                                             estimates[k][n].relative <= p.bound, systems[k], save)
                              for k, got in enumerate(better) if n in got})
    return estimates, unestimated


def _balances(system, tr: Trajectory) -> tuple[float | None, tuple[float, float] | None]:
    """A nonlinear run's energy residual over its scale and, for a closed chain, its loop residual."""
    if system.kind == "linear" or not tr.success or tr.positions is None:
        return None, None
    loop = system.loop_residual(tr)
    try:
        residual, scale = system.energy_residual(tr)
        energy = float(np.max(np.abs(residual))) / scale
    except InputError:      # a closed chain's run went where its loop does not close
        energy = math.nan
    return energy, loop


def _comparison(k: int, system, runs: StackRuns, order: list[str], skipped: dict[str, str], ref_name: str | None,
                measured: dict, estimates: dict, unestimated: dict) -> Comparison:
    """System *k*'s comparison: one record per solver, its errors measured where the reference ran."""
    records = {}
    for n in order:
        shown = runs.shown[n][k]
        own = runs.own[n][k] if n in runs.own else shown
        est = estimates.get(n)
        if not shown.success:
            records[n] = SolverRecord(n, "failed", shown.message, estimate=est, unestimated=unestimated.get(n, ""))
            continue
        if est is not None:
            shown.estimated = est
        energy, loop = _balances(system, own)
        records[n] = SolverRecord(n, "ok", "", shown, own, None, est, unestimated.get(n, ""), energy, loop)
    ref = ref_name if ref_name in records and records[ref_name].ran else None
    for n, errors in (measured.items() if ref else ()):
        records[n].errors = errors
    records.update((n, SolverRecord(n, "skipped", why)) for n, why in skipped.items())
    grid = runs.grids[k] if runs.grids[k] is not None else runs.preset.grid(system.t_stop)
    return Comparison(system, runs.preset.name, grid, records, ref, runs.preset.bound)


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
