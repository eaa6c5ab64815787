"""The error estimates validated: estimated against true error, per solver and preset, on the bench and stress scenes."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Iterable

import numpy as np

from ...errors import AnalogyError
from ...presets import PRESETS
from ...progress import Progress
from ...results.metrics import PEAK_FLOOR
from ...results.output import Tabular, write_rows
from ...study.comparison import compare
from .families import ALL_FAMILIES, cases

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["EstimateRow", "EstimateValidation", "validate_estimates", "AGREEMENT", "reference_floor"]

#: The estimate must lie within this factor of the true error.
AGREEMENT = 3.0
#: The nonlinear reference's own error, relative to the peak (:data:`~analogy.solvers.reference.NONLINEAR_RTOL`
#: gives under 1e-10 on the built-in arms).
NONLINEAR_FLOOR = 1e-10


def reference_floor(system) -> float:
    """The reference's own error relative to the peak: under it a true error is not resolved.

    The exact solution's rounding, 10·n·ε·cond(M) and at least 1e-12 (its promise against the
    40-digit solution); the nonlinear reference's 1e-10.

    Parameters
    ----------
    system : NodeDynamics
        The system.
    """
    if system.kind != "linear":
        return NONLINEAR_FLOOR
    cond = float(np.linalg.cond(system.joint.mass_matrix))
    return max(1e-12, 10 * system.dof * np.finfo(float).eps * cond)


@dataclass
class EstimateRow:
    """One solver at one preset on one scene: its true error, its estimate and the verdict, on the
    worst output whose true error the reference resolves (``output``; ``floor`` is the reference's
    own error there, over that output's own peak).

    ``verdict`` is ``agrees`` (within :data:`AGREEMENT` of the true error), ``over`` or
    ``under`` (outside it, by ``ratio``), ``unresolved`` (the true error is under the
    reference's own, ``floor``), ``no estimate`` (the estimator declines: it cannot see an
    output, :func:`~analogy.study.estimate.unresolved_outputs`, or its refined run failed or
    was no refinement) or ``failed`` (the run itself). ``unsafe`` marks an estimate that says the
    bound is kept while the true error is more than AGREEMENT times past it.
    """

    scene: str
    solver: str
    preset: str
    true_error: float
    estimate: float
    ratio: float
    floor: float
    bound: float
    verdict: str
    unsafe: bool
    output: str = ""
    message: str = ""


@dataclass
class EstimateValidation(Tabular):
    """Every row of a validation run, with a summary, a table, a CSV and a plot of estimate against truth."""

    rows: list = field(default_factory=list)

    def __repr__(self) -> str:
        count = {v: sum(r.verdict == v for r in self.rows) for v in ("agrees", "over", "under", "unresolved",
                                                                   "no estimate", "failed")}
        return (f"EstimateValidation({len(self.rows)} runs: " + ", ".join(f"{n} {k}" for k, n in count.items() if n)
                + f", {sum(r.unsafe for r in self.rows)} unsafe)")

    def columns(self) -> dict:
        """One column per :class:`EstimateRow` field."""
        names = list(EstimateRow.__dataclass_fields__)
        return {n: np.array([getattr(r, n) for r in self.rows], dtype=object) for n in names}

    def to_csv(self, path, every: int = 1) -> Path:
        """Write the rows.

        Parameters
        ----------
        path : str or Path
            The file to write.
        every : int
            Keep one row in every *every*.
        """
        names = list(EstimateRow.__dataclass_fields__)
        return write_rows(path, names, ([getattr(r, n) for n in names] for r in self.rows[::every]))

    def table(self) -> str:
        """A markdown table: one line per run."""
        lines = ["| scene | solver | preset | true error / peak | estimate / peak | estimate / true | verdict |",
                 "|---|---|---|---|---|---|---|"]
        for r in self.rows:
            ratio = f"{r.ratio:.2f}" if math.isfinite(r.ratio) else "-"
            note = r.verdict + (" (unsafe)" if r.unsafe else "") + (f": {r.message}" if r.message else "")
            lines.append(f"| {r.scene} | {r.solver} | {r.preset} | {r.true_error:.2e} | {r.estimate:.2e} | "
                         f"{ratio} | {note} |")
        return "\n".join(lines)

    def summary(self) -> str:
        """Counts per solver and preset, and the largest ratios either way among the resolved runs."""
        lines = [f"| solver | preset | runs | agree (within {AGREEMENT:g}×) | over | under | unresolved | no estimate | "
                 "failed | unsafe | ratio range |", "|---|---|---|---|---|---|---|---|---|---|---|"]
        for solver in dict.fromkeys(r.solver for r in self.rows):
            for preset in dict.fromkeys(r.preset for r in self.rows):
                rs = [r for r in self.rows if r.solver == solver and r.preset == preset]
                if not rs:
                    continue
                n = {v: sum(r.verdict == v for r in rs) for v in ("agrees", "over", "under", "unresolved",
                                                                  "no estimate", "failed")}
                ratios = [r.ratio for r in rs if r.verdict in ("agrees", "over", "under")]
                span = f"{min(ratios):.2f} to {max(ratios):.2f}" if ratios else "-"
                lines.append(f"| {solver} | {preset} | {len(rs)} | {n['agrees']} | {n['over']} | {n['under']} | "
                             f"{n['unresolved']} | {n['no estimate']} | {n['failed']} | {sum(r.unsafe for r in rs)} | "
                             f"{span} |")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def plot(self, path=None) -> "Figure":
        """Estimated against true error / peak, log-log, with the factor-of-AGREEMENT band.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from matplotlib.figure import Figure
        from ...results.plots import save_figure
        fig = Figure(figsize=(6.5, 6), layout="constrained")
        ax = fig.subplots()
        ok = [r for r in self.rows if r.verdict != "failed" and r.true_error > 0 and r.estimate > 0]
        if ok:
            lo = min(min(r.true_error, r.estimate) for r in ok) / 3
            hi = max(max(r.true_error, r.estimate) for r in ok) * 3
            line = np.array([lo, hi])
            ax.fill_between(line, line / AGREEMENT, line * AGREEMENT, color="0.9",
                            label=f"within {AGREEMENT:g}× of the truth")
            ax.plot(line, line, color="0.5", lw=0.8)
        marks = {("spice", "fast"): ("o", "C0"), ("spice", "accurate"): ("s", "C0"),
                 ("ode", "fast"): ("o", "C1"), ("ode", "accurate"): ("s", "C1")}
        for (solver, preset), (m, c) in marks.items():
            rs = [r for r in ok if r.solver == solver and r.preset == preset]
            if rs:
                resolved = [r for r in rs if r.verdict != "unresolved"]
                ax.scatter([r.true_error for r in resolved], [r.estimate for r in resolved], marker=m, color=c,
                           label=f"{solver}, {preset}", s=28)
                under = [r for r in rs if r.verdict == "unresolved"]
                if under:
                    ax.scatter([r.true_error for r in under], [r.estimate for r in under], marker=m,
                               facecolors="none", edgecolors=c, s=28,
                               label=f"{solver}, {preset}: true error under the reference's own")
        ax.set(xscale="log", yscale="log", xlabel="true error / peak (against the exact or reference solution)",
               ylabel="estimated error / peak (refined run, Richardson)",
               title="Error estimates without a reference, worst output per run")
        ax.legend(fontsize=8, loc="upper left")
        return save_figure(fig, path)


def _items(quick: bool, families: str) -> list[tuple[str, object]]:
    from ..bench import bench_scenes
    out: list[tuple[str, object]] = [(s.name, s.system) for s in bench_scenes(quick)]
    out += [(f"{c.family}: {c.label}", c.build) for c in cases(families, quick)]
    return out


def validate_estimates(quick: bool = False, families: str = ALL_FAMILIES, timeout: float = 20.0,
                       progress: bool = True) -> EstimateValidation:
    """Estimate every solver's error at both presets on the bench scenes and the stress
    families' cases, and measure it against the exact or reference solution.

    A run is judged on its worst output, each against its own peak, the true error's and the
    estimate's each on its own worst (they may differ).

    Parameters
    ----------
    quick : bool
        The quick bench scenes and the ends of each stress sweep.
    families : str
        Stress family letters.
    timeout : float
        Wall-time limit of each ODE run [s]; SPICE takes at most 10⁶ steps.
    progress : bool
        A progress bar on a terminal.
    """
    todo: Iterable = _items(quick, families)
    todo = list(todo)
    bar = Progress(len(todo), unit="scene", enabled=progress)
    report = EstimateValidation()
    for label, build in todo:
        try:
            system = build()
        except AnalogyError as exc:
            report.rows.append(EstimateRow(label, "all", "-", math.nan, math.nan, math.nan, math.nan, math.nan,
                                           "failed", False, message=str(exc)))
            bar.update(1)
            continue
        floor = reference_floor(system)
        for name in PRESETS:
            p = replace(PRESETS[name], budget=replace(PRESETS[name].budget, timeout=timeout,
                                                              steps=min(PRESETS[name].budget.steps, 1_000_000)))
            try:
                c = compare(system, p, ("spice", "ode"), estimate=True)
            except AnalogyError as exc:         # refused before it ran (a work budget): a row, not a lost report
                report.rows.extend(EstimateRow(label, solver, name, math.nan, math.nan, math.nan, floor, p.bound,
                                               "failed", False, message=str(exc)[:200]) for solver in ("spice", "ode"))
                continue
            for solver in ("spice", "ode"):
                report.rows.append(_row(label, solver, name, c, floor, p.bound))
        bar.update(1)
    bar.close()
    return report


def _row(label: str, solver: str, preset: str, c, floor: float, bound: float) -> EstimateRow:
    """One run judged output by output: the worst output whose true error the reference resolves
    (above *floor* over that output's share of the largest peak), and its own estimate there."""
    why = c.failures.get(solver) or c.unestimated.get(solver, "") or c.skipped.get(solver, "")
    if solver not in c.measured or solver not in c.estimated:
        # the run itself failed, or it ran and the estimator declined (its refined run failed or was
        # no refinement): a failure, or no claim
        declined = solver in c.measured and solver in c.unestimated
        return EstimateRow(label, solver, preset, c.measured[solver].relative if declined else math.nan, math.nan,
                           math.nan, floor, bound, "no estimate" if declined else "failed", False, message=why[:200])
    truth, guess = c.measured[solver].per_output, c.estimated[solver].per_output
    own = np.max(np.abs(c.results[c.reference].rates), axis=0)
    share = own / np.max(own) if np.max(own) > 0 else np.ones_like(own)
    floors = {f"r{j + 1}": floor / max(float(s), PEAK_FLOOR) for j, s in enumerate(share)}
    resolved = [o for o in guess if o in truth and truth[o] > floors[o]]
    if not resolved:
        return EstimateRow(label, solver, preset, c.measured[solver].relative, c.estimated[solver].relative, math.nan,
                           floor, bound, "unresolved", False, c.measured[solver].worst, why[:200])
    worst = max(resolved, key=lambda o: truth[o])
    true, est = truth[worst], guess[worst]
    if math.isnan(c.estimated[solver].relative):
        return EstimateRow(label, solver, preset, true, math.nan, math.nan, floors[worst], bound, "no estimate",
                           False, worst, why[:200])
    ratio = est / true
    verdict = "agrees" if 1 / AGREEMENT <= ratio <= AGREEMENT else ("over" if ratio > 1 else "under")
    # unsafe: an output estimated within the bound whose resolved truth is more than AGREEMENT times past it
    unsafe = any(guess[o] <= bound < truth[o] / AGREEMENT for o in resolved)
    return EstimateRow(label, solver, preset, true, est, ratio, floors[worst], bound, verdict, unsafe, worst, why[:200])
