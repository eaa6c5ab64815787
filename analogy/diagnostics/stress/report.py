"""Running the stress families: each run's error, time, steps and status, as CSV, plots and a summary."""

from __future__ import annotations

import math
import textwrap
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from ...files import write_figure, write_text
from ...errors import AnalogyError, InputError
from ...progress import Progress
from ...study.comparison import compare
from ...results.metrics import relative_error
from ...results.output import Tabular, write_rows
from .families import ALL_FAMILIES, FAMILY_TITLES, StressCase, cases

__all__ = ["StressRow", "StressReport", "stress", "write_report", "EXACT_BOUND"]

#: The exact solver's promise against the 40-digit solution (relative to the peak).
EXACT_BOUND = 1e-12


@dataclass
class StressRow:
    """One solver run on one case.

    ``status`` is ``ok`` (error within the bound), ``outside bound`` (flagged), or
    ``failed`` with the reason in ``message``.
    """

    family: str
    case: str
    axis: str
    value: float
    solver: str
    status: str
    error: float
    bound: float
    seconds: float
    steps: float
    message: str = ""


@dataclass
class StressReport(Tabular):
    """Every row of a stress run, with its CSV, a plot per family and a markdown summary."""

    rows: list = field(default_factory=list)

    def __repr__(self) -> str:
        bad = sum(r.status != "ok" for r in self.rows)
        return f"StressReport({len(self.rows)} runs, {bad} flagged or failed)"

    def columns(self) -> dict:
        """One column per :class:`StressRow` field."""
        names = list(StressRow.__dataclass_fields__)
        return {n: np.array([getattr(r, n) for r in self.rows], dtype=object) for n in names}

    def to_csv(self, path) -> Path:
        """Write the rows, text columns as they are.

        Parameters
        ----------
        path : str or Path
            The file to write.
        """
        names = list(StressRow.__dataclass_fields__)
        return write_rows(path, names, ([getattr(r, n) for n in names] for r in self.rows))

    def growth(self) -> dict[str, float]:
        """Family d: per solver, the exponent p of seconds ∝ n^p, fitted over n ≥ 10."""
        out = {}
        for solver in sorted({r.solver for r in self.rows if r.family == "d"}):
            pts = [(r.value, r.seconds) for r in self.rows
                   if r.family == "d" and r.solver == solver and r.value >= 10 and r.status != "failed"
                   and r.seconds > 0]
            if len(pts) >= 2:
                x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
                out[solver] = float(np.polyfit(x, y, 1)[0])
        return out

    def summary(self) -> str:
        """A markdown table per family and solver: runs, ok, flagged, failed, worst error, median time."""
        lines = ["| family | solver | runs | ok | outside bound | failed | worst error / peak | median s |",
                 "|---|---|---|---|---|---|---|---|"]
        for fam in sorted({r.family for r in self.rows}):
            for solver in sorted({r.solver for r in self.rows if r.family == fam}):
                rs = [r for r in self.rows if r.family == fam and r.solver == solver]
                errs = [r.error for r in rs if np.isfinite(r.error)]
                secs = [r.seconds for r in rs if np.isfinite(r.seconds)]
                count = {s: sum(r.status == s for r in rs) for s in ("ok", "outside bound", "failed")}
                worst = f"{max(errs):.2e}" if errs else "-"
                med = f"{np.median(secs):.3g}" if secs else "-"
                lines.append(f"| {fam} | {solver} | {len(rs)} | {count['ok']} | {count['outside bound']} | "
                             f"{count['failed']} | {worst} | {med} |")
        growth = self.growth()
        if growth:
            lines += ["", "Family d, cost growth (seconds ∝ n^p over n ≥ 10): "
                      + ", ".join(f"{k} p = {v:.2f}" for k, v in growth.items())]
        horizon = [r for r in self.rows if r.axis == "chaotic pendulum" and r.message.startswith("horizon")]
        lines += [f"{r.case}, {r.solver}: {r.message}" for r in horizon]
        return "\n".join(lines)

    def plot(self, folder) -> list[Path]:
        """One figure per family: error / peak (top) and seconds (bottom) against the swept value.

        Parameters
        ----------
        folder : str or Path
            Where ``stress_<family>.png`` are written.
        """
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        folder = Path(folder)
        written = []
        for fam in sorted({r.family for r in self.rows}):
            rows = [r for r in self.rows if r.family == fam]
            fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.5, 6.5), sharex=True, constrained_layout=True)
            solvers = sorted({r.solver for r in rows})
            axes = list(dict.fromkeys(r.axis for r in rows))
            for k, solver in enumerate(solvers):        # colour: solver; line style: swept quantity
                for a, axis in enumerate(axes):
                    rs = sorted((r for r in rows if r.solver == solver and r.axis == axis), key=lambda r: r.value)
                    if not rs:
                        continue
                    x = [r.value for r in rs]
                    err = [r.error if r.status != "failed" and r.error > 0 else np.nan for r in rs]
                    style = dict(marker="os^vDx"[k % 6], color=f"C{k}", ls=("-", "--", ":", "-.")[a % 4],
                                 label=solver if len(axes) == 1 else f"{solver}, {axis}")
                    top.plot(x, err, **style)
                    bad = [(r.value, r.error) for r in rs if r.status == "outside bound" and r.error > 0]
                    if bad:
                        top.plot(*zip(*bad), "o", ms=11, mfc="none", color="red")
                    bottom.plot(x, [r.seconds for r in rs], **style)
            values = np.array([r.value for r in rows], dtype=float)
            if np.any(values <= 0):         # signed sweeps (an MP capacitance through zero)
                tiny = np.min(np.abs(values[values != 0])) if np.any(values != 0) else 1.0
                bottom.set_xscale("symlog", linthresh=tiny)
            else:
                bottom.set_xscale("log")
            bounds = sorted({r.bound for r in rows if np.isfinite(r.bound)})
            for b in bounds:
                top.axhline(b, color="grey", ls=":", lw=1)
            top.set(yscale="log", ylabel="max |error| / peak [1]")
            # what this run swept (a --quick run only the ends of each range), not the full ranges
            swept = "; ".join(f"{axis} " + (f"{lo:g}" if lo == hi else f"from {lo:g} to {hi:g}")
                              for axis in axes for lo, hi in [(min(r.value for r in rows if r.axis == axis),
                                                               max(r.value for r in rows if r.axis == axis))])
            fig.suptitle(textwrap.fill(f"family {fam}, {FAMILY_TITLES[fam].split(':')[0]}: {swept}", 80)
                         + "\n(dotted: bounds; red rings: outside bound)", fontsize=10)
            bottom.set(yscale="log", ylabel="run time [s]",
                       xlabel=_AXIS_UNITS.get(axes[0], f"{axes[0]} [1]") if len(axes) == 1
                       else "swept value [1] (line style: " + ", ".join(axes) + ")")
            top.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
            path = folder / f"stress_{fam}.png"
            write_figure(fig, path, dpi=110)
            plt.close(fig)
            written.append(path)
        return written


def _bound(solver: str, preset) -> float:
    return EXACT_BOUND if solver == "exact" else preset.bound


def _exact_check(system, points: int = 9) -> tuple[float, float, str]:
    """The exact solution against the 40-digit one on *points* points: error / peak, its own seconds, a note."""
    from ...solvers.exact import solve_exact
    from ...solvers.reference import solve_reference
    # golden-ratio points: a uniform grid can fall on the zeros of a periodic motion
    golden = np.modf(np.arange(1, max(points - 1, 1)) * 0.6180339887498949)[0]
    probe = system.t_stop * np.sort(np.concatenate([[0.0, 1.0], golden]))
    start = _time.perf_counter()
    exact = solve_exact(system, probe).voltages
    seconds = _time.perf_counter() - start
    if system.dof > 20:
        return math.nan, seconds, "no 40-digit reference at this size"
    return relative_error(exact, solve_reference(system, probe).voltages), seconds, ""


# Swept quantities that carry a unit; the others are ratios or counts.
_AXIS_UNITS = {"MP capacitance": "MP capacitance m12 [F] = [kg]", "force": "force scale [1] (× the base torque)",
               "n": "joints n [1]", "periods": "undamped periods [1]"}


def _case_rows(case: StressCase) -> list[StressRow]:
    base = dict(family=case.family, case=case.label, axis=case.axis, value=case.value)
    try:
        system = case.build()
    except AnalogyError as exc:
        return [StressRow(**base, solver="build", status="failed", error=math.nan, bound=math.nan,
                          seconds=0.0, steps=math.nan, message=str(exc))]
    rows = []
    linear = system.kind == "linear"
    for label, preset in case.runs:
        solver = label.split("/")[0]
        if solver == "exact":
            try:
                err, seconds, note = _exact_check(system, case.reference_points)
            except AnalogyError as exc:
                err, seconds, note = math.nan, math.nan, str(exc)
            status = "failed" if note and not math.isfinite(err) and "size" not in note else \
                ("ok" if not math.isfinite(err) or err <= EXACT_BOUND else "outside bound")
            rows.append(StressRow(**base, solver="exact", status=status, error=err, bound=EXACT_BOUND,
                                  seconds=seconds, steps=math.nan,
                                  message=note or "against the 40-digit solution on 9 points"))
            continue
        c = compare(system, preset, [solver] + (["exact"] if linear else ["reference"]))
        tr = c.results.get(solver)
        if tr is None:
            rows.append(StressRow(**base, solver=label, status="failed", error=math.nan,
                                  bound=_bound(solver, preset), seconds=math.nan, steps=math.nan,
                                  message=c.failures.get(solver) or c.skipped.get(solver, "")))
            continue
        err = c.errors()[solver][1] if c.reference else math.nan
        status = "ok" if math.isfinite(err) and err <= preset.bound else \
            ("outside bound" if math.isfinite(err) else "failed")
        message = tr.message or ("" if c.reference else f"no reference: {c.failures}")
        if case.horizon and c.reference:
            h = c.horizon(solver, 1e-3)
            message = (f"horizon {h:.3g} s (deviation past 1e-3 of the peak)" if math.isfinite(h) else
                       f"within 1e-3 of the peak over the whole run ({c.time[-1]:.3g} s): no horizon reached")
            status = "ok"                 # a chaotic motion is judged by its horizon, not its error
        rows.append(StressRow(**base, solver=label, status=status, error=err, bound=preset.bound,
                              seconds=tr.run_time, steps=math.nan if tr.stats.steps is None else tr.stats.steps,
                              message=message))
    return rows


def stress(families: str = ALL_FAMILIES, quick: bool = False, timeout: float = 10.0,
           progress: bool = True) -> StressReport:
    """Run every case of the chosen families and collect a :class:`StressReport`.

    Parameters
    ----------
    families : str
        Letters of :data:`~analogy.stress.families.FAMILY_TITLES`.
    quick : bool
        A subset that runs in under a minute.
    timeout : float
        Wall-time limit of each ODE run [s].
    progress : bool
        A progress bar on a terminal.
    """
    bad = sorted(set(families) - set(FAMILY_TITLES))
    if bad or not families:
        raise InputError(f"unknown stress families {''.join(bad) or '(none)'}: use letters of "
                         f"{''.join(FAMILY_TITLES)}")
    todo: Iterable = list(cases(families, quick, timeout))
    bar = Progress(len(todo), unit="case", enabled=progress)
    report = StressReport()
    for case in todo:
        try:
            report.rows.extend(_case_rows(case))
        except Exception as exc:        # a defect found by the stress suite is a row, not a lost run
            report.rows.append(StressRow(case.family, case.label, case.axis, case.value, "all", "failed",
                                         math.nan, math.nan, math.nan, math.nan,
                                         f"internal error: {type(exc).__name__}: {exc}"))
        bar.update(1)
    bar.close()
    return report


def write_report(report: StressReport, folder) -> list[Path]:
    """``stress.csv``, ``stress.md`` and ``stress_<family>.png`` in *folder*.

    Parameters
    ----------
    report : StressReport
        The rows.
    folder : str or Path
        An existing folder.
    """
    folder = Path(folder)
    out = [report.to_csv(folder / "stress.csv")]
    write_text(folder / "stress.md", "# Stress report\n\n" + report.summary() + "\n")
    return out + [folder / "stress.md"] + report.plot(folder)


