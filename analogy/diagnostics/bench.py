"""Benchmarks: run time against error for SPICE settings, ODE methods and the exact solver."""

from __future__ import annotations

import csv
import statistics
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..files import write_figure
from ..solvers.transient import netlist
from ..errors import AnalogyError
from ..presets import PRESETS, Preset, SpiceSettings, tolerance_preset
from ..progress import Progress
from ..results.metrics import output_errors
from ..results.output import write_rows
from ..scenes.builtin import scene
from ..scenes.scene import Scene
from ..scenes.spec import ModelSpec
from ..solvers.exact import solve_exact
from ..solvers.reference import NONLINEAR_RTOL, solve_reference
from ..solvers.spice import session
from ..solvers.truncation import MODEL_SHARE, truncation_model
from ..study.work import check_work

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["BenchRow", "BenchResult", "bench", "bench_scenes", "spice_grid", "ode_grid", "nonlinear_spice_grid",
           "tolerance_grid", "BENCH_TOLERANCES"]

ODE_BENCH_METHODS = ("LSODA", "Radau", "BDF", "RK45", "DOP853")


@dataclass
class BenchRow:
    """One solver setting on one scene: median run time and max error / peak."""

    scene: str
    dof: int
    solver: str
    setting: str
    tolerance: float
    median_s: float
    error: float
    points: int
    status: str = "ok"
    runs: int = 0


@dataclass
class BenchResult:
    """All rows of a benchmark, with CSV and work-precision plot."""

    rows: list = field(default_factory=list)
    repeats: int = 5
    wall_s: float = 0.0

    @classmethod
    def read_csv(cls, path, repeats: int = 5) -> "BenchResult":
        """The rows of a CSV that :meth:`to_csv` wrote (to plot or tabulate them again).

        Parameters
        ----------
        path : str or Path
            The file.
        repeats : int
            The timed runs per setting it was made with.
        """
        with open(path, newline="") as fh:
            rows = [BenchRow(r["scene"], int(r["dof"]), r["solver"], r["setting"], float(r["tolerance"]),
                             float(r["median_s"]), float(r["error_over_peak"]), int(r["points"]), r["status"],
                             int(r["runs"])) for r in csv.DictReader(fh)]
        return cls(rows, repeats)

    def to_csv(self, path) -> Path:
        """One row per setting and scene: time, runs, error over the peak, points, status.

        Parameters
        ----------
        path : str or Path
            The file to write.
        """
        return write_rows(path, ["scene", "dof", "solver", "setting", "tolerance", "median_s", "runs",
                                 "error_over_peak", "points", "status"],
                          ([r.scene, r.dof, r.solver, r.setting, float(r.tolerance), float(r.median_s), r.runs,
                            float(r.error), r.points, r.status] for r in self.rows))

    def table(self) -> str:
        lines = [f"{'scene':<18}{'dof':>4}  {'solver':<10}{'setting':<40}{'median [ms]':>12}{'runs':>5}"
                 f"{'error/peak':>11}{'points':>9}  status"]
        for r in self.rows:
            lines.append(f"{r.scene:<18}{r.dof:>4}  {r.solver:<10}{r.setting:<40}{r.median_s * 1e3:>12.3f}"
                         f"{r.runs:>5}{r.error:>11.2e}{r.points:>9}  {r.status}")
        lines += self.cost_lines()
        lines.append(f"{len(self.rows)} rows, {sum(r.status != 'ok' for r in self.rows)} failed; median of "
                     f"up to {self.repeats} warm runs (fewer for settings slower than "
                     f"{_BUDGET_S:g} s per run); {self.wall_s:.1f} s in all")
        return "\n".join(lines)

    def __str__(self):
        return self.table()

    def cost_lines(self) -> list[str]:
        """Per scene and tolerance (1e-3, 1e-6, 1e-9): the cheapest SPICE and ODE settings within it,
        their ratio, and what ``--tol`` costs beside the cheapest SPICE setting and whether it kept it."""
        lines = []
        for sc in dict.fromkeys(r.scene for r in self.rows):
            for tol in BENCH_TOLERANCES:
                best = {}
                for solver in ("spice", "ode"):
                    ok = [r for r in self.rows if r.scene == sc and r.solver == solver and r.status == "ok"
                          and r.error <= tol]
                    if ok:
                        best[solver] = min(ok, key=lambda r: r.median_s)
                sp_, od = best.get("spice"), best.get("ode")
                line = f"{sc} at {tol:g}: cheapest SPICE " + (
                    f"{sp_.median_s * 1e3:.2f} ms ({sp_.setting})" if sp_ else "none within it")
                line += ", ODE " + (f"{od.median_s * 1e3:.2f} ms ({od.setting})" if od else "none within it")
                if sp_ and od:
                    line += f", SPICE/ODE = {sp_.median_s / od.median_s:.2f}"
                for circuit in ("", "modal "):
                    line += self._chosen(sc, tol, circuit)
                lines.append(line)
        return lines

    def _chosen(self, sc: str, tol: float, circuit: str) -> str:
        """What ``--tol`` cost on one circuit of *sc* (the scene's own, or ``modal ``), beside the cheapest
        grid setting on that circuit that kept *tol*: the settings are the solver's, the circuit the scene's."""
        chosen = next((r for r in self.rows if r.scene == sc and r.solver == "spice"
                       and r.setting == f"{circuit}tol={tol:g}"), None)
        if chosen is None:
            return ""
        name = "; modal circuit" if circuit else f"; --tol {tol:g}"
        if chosen.status != "ok":
            return f"{name}: {chosen.status}"
        same = [r for r in self.rows if r.scene == sc and r.solver == "spice" and r.status == "ok"
                and r.error <= tol and r.setting.startswith("modal ") == bool(circuit)]
        cheapest = min(same, key=lambda r: r.median_s, default=None)
        kept = "kept" if chosen.error <= tol else f"missed, {chosen.error:.2e}"
        ideal = next((r for r in self.rows if r.scene == sc and r.solver == "ideal" and r.tolerance == tol), None)
        return (f"{name}: {chosen.median_s * 1e3:.2f} ms ({kept})" +
                (f", {chosen.median_s / cheapest.median_s:.2f}x the cheapest on it" if cheapest else "") +
                (f", {chosen.points:,} points beside the ideal {ideal.points:,}" if ideal else ""))

    def plot(self, path=None) -> "Figure":
        """Work-precision diagram: median run time against max error / peak, log-log, per scene.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from matplotlib.figure import Figure
        scenes = list(dict.fromkeys(r.scene for r in self.rows))
        fig = Figure(figsize=(4.6 * len(scenes), 5.2), layout="constrained")
        axes = np.atleast_1d(fig.subplots(1, len(scenes), sharex=True, sharey=True))
        markers = {"spice": "o", "ode": "s", "exact": "*", "reference": "P"}
        # One colour per solver setting family in every panel, so a family reads across scenes; the
        # modal circuit's settings are dashed, in the colour of the same settings on the scene's own.
        families = list(dict.fromkeys((r.solver, _family(r.setting)) for r in self.rows if r.solver != "ideal"))
        bases = list(dict.fromkeys((sv, f.removeprefix("modal ")) for sv, f in families if sv != "reference"))
        colour = {f: f"C{bases.index((f[0], f[1].removeprefix('modal '))) % 10}" for f in families
                  if f[0] != "reference"}
        colour.update({f: "k" for f in families if f[0] == "reference"})
        handles: dict = {}
        for ax, sc in zip(axes, scenes):
            rows = [r for r in self.rows if r.scene == sc and r.solver != "ideal"]     # counts, not runs
            for solver, family in families:
                sel = [r for r in rows if r.solver == solver and _family(r.setting) == family
                       and r.status == "ok" and np.isfinite(r.error)]
                if not sel:
                    continue
                sel.sort(key=lambda r: r.error)
                (line,) = ax.loglog([max(r.error, 1e-17) for r in sel], [r.median_s for r in sel],
                                    marker=markers[solver], ms=8 if solver == "exact" else 4,
                                    color=colour[(solver, family)],
                                    ls="none" if solver == "exact" else "--" if family.startswith("modal ") else "-",
                                    label=f"{solver} {family}")
                handles.setdefault(line.get_label(), line)
            unref = [r for r in rows if r.solver == "exact" and r.status == "ok" and not np.isfinite(r.error)]
            for r in unref:     # no independent reference at this size: time only, drawn at 1e-16
                (line,) = ax.loglog([1e-16], [r.median_s], marker="*", ms=9, mfc="none", ls="none", color="k",
                                    label="exact modal (no reference: time only)")
                handles.setdefault(line.get_label(), line)
            failed = [r for r in rows if r.status != "ok"]
            if failed:
                ax.text(0.02, 0.02, f"{len(failed)} setting{'s' if len(failed) > 1 else ''} failed",
                        transform=ax.transAxes,
                        fontsize="small", color="tab:red")
            ax.set_title(f"{sc} ({rows[0].dof} DOF)", fontsize="medium")
            ax.set_xlabel("max error / peak [1]")
            ax.grid(True, which="both", alpha=0.3)
        fig.legend(list(handles.values()), list(handles), loc="outside lower center",
                   ncols=min(6, len(handles)), fontsize="small", frameon=False)
        fig.suptitle("run time against error (vs the exact solution, or the reference if nonlinear)",
                     fontsize="medium")
        axes[0].set_ylabel(f"median run time [s] ({self.repeats} warm runs)")
        if path is not None:
            write_figure(fig, path, dpi=110)
        return fig


def _family(setting: str) -> str:
    """A setting's family in the plot: its method or preset, ``modal`` before it on the modal circuit."""
    words = setting.split(" ")
    return " ".join(words[:2]) if words[0] == "modal" and len(words) > 1 else words[0]


def bench_scenes(quick: bool = False) -> list[Scene]:
    """The benchmark's scenes: 2, 10 and 50 DOF, and the 2-DOF arm's nonlinear dynamics (*quick*: 2 and 10).

    Parameters
    ----------
    quick : bool
        Only the 2- and 10-DOF linear scenes.
    """
    big = Scene.of("random50", ModelSpec(robot="random50", seed=2), topology="serial",
                   forces=tuple(["sine(0, 1, 0.7)"] + [f"step({1.0 / (k + 1)!r})" for k in range(1, 50)]),
                   t_stop=2.0, description="random SPD 50-DOF (seed 2), serial topology")
    nonlinear = scene("default").replace(name="default-nonlinear", dynamics="nonlinear",
                                         description="the default arm's full nonlinear dynamics")
    return [scene("default"), scene("random10")] + ([] if quick else [big, nonlinear])


def spice_grid(full: bool = False, quick: bool = False) -> list[tuple]:
    """(label, options, max_steps) for ngspice: method, reltol, trtol and maximum step.

    Parameters
    ----------
    full : bool
        Also cross the step caps T/1000 and T/20000.
    quick : bool
        Only reltol 1e-3 and 1e-7 at trtol 7 (and the presets).
    """
    grid = []
    reltols = (1e-3, 1e-7) if quick else (1e-3, 1e-5, 1e-7, 1e-9)
    trtols = (7,) if quick else (7, 1)
    max_steps = (50, 1000, 20000) if full else (50,)
    for method in ("trap", "gear"):
        for rt in reltols:
            for tr in trtols:
                for ms in max_steps:
                    opts = {"method": method, "reltol": rt, "abstol": 1e-15, "vntol": 1e-13,
                            "chgtol": 1e-20, "trtol": tr}
                    grid.append((f"{method} reltol={rt:g} trtol={tr} tmax=T/{ms}", opts, ms, rt))
    return grid + tolerance_grid(quick)     # the presets are the tolerances 1e-3 and 1e-6


#: The tolerances the bench asks for as a whole preset (its scale-based step caps included).
BENCH_TOLERANCES = (1e-3, 1e-6, 1e-9)


def tolerance_grid(quick: bool = False) -> list[tuple]:
    """(label, preset, None, tolerance) per :data:`BENCH_TOLERANCES`: the settings ``--tol`` chooses,
    step caps from the system's scales and first step included.

    Parameters
    ----------
    quick : bool
        Leave out 1e-9 (seconds a run).
    """
    return [(f"tol={t:g}", tolerance_preset(t), None, t) for t in BENCH_TOLERANCES if not (quick and t < 1e-6)]


def nonlinear_spice_grid() -> list[tuple]:
    """(label, options, max_steps, reltol) for nonlinear circuits: the step cap sets their accuracy.

    Tight reltol with trtol = 1 is in the grid to show it failing ("timestep too small").
    """
    grid = [(f"{m} default tolerances tmax=T/{ms}", {"method": m}, ms, 1e-3)
            for m in ("trap", "gear") for ms in (500, 2000, 20000)]
    grid.append(("trap reltol=1e-6 trtol=1 tmax=T/2000", {"method": "trap", "reltol": 1e-6, "trtol": 1}, 2000, 1e-6))
    grid += [(f"preset-{name}", dict(p.spice.behavioural_options), p.spice.behavioural_max_steps, 1e-3)
             for name, p in PRESETS.items()]
    return grid + tolerance_grid()


def ode_grid(quick: bool = False) -> list[tuple[str, float]]:
    """(method, rtol) pairs: rtol from 1e-3 to 1e-10 (*quick*: 1e-3, 1e-6, 1e-9).

    Parameters
    ----------
    quick : bool
        Three tolerances per method.
    """
    return [(m, 10.0 ** -k) for m in ODE_BENCH_METHODS for k in ((3, 6, 9) if quick else range(3, 11))]


#: Timed seconds a setting may use; slow settings get fewer runs (recorded per row).
_BUDGET_S = 1.0


def _median_time(fn, repeats: int):
    result, warm = fn()                    # warm-up: caches, first-call costs
    runs = max(1, min(repeats, int(_BUDGET_S / max(warm, 1e-9))))
    times = []
    for _ in range(runs):
        result, seconds = fn()
        times.append(seconds)
    return statistics.median(times), result, runs


def _jobs(scenes, full: bool, quick: bool) -> list[tuple]:
    """(kind, scene, system, setting) for every solver setting on every scene."""
    jobs = []
    for sc in scenes:
        system = sc.system()
        linear = system.kind == "linear"
        jobs += [("spice", sc, system, g) for g in (spice_grid(full, quick) if linear else nonlinear_spice_grid())]
        if linear:      # the same physics with one node per mode: n grounded capacitors for n(n-1)/2 floating ones
            modal = sc.replace(topology="modal").system()
            jobs += [("spice", sc, modal, (f"modal {g[0]}",) + tuple(g[1:])) for g in spice_grid(full, quick)]
            # the ideal count: the same on every node map (its error is the joint rates', the physics')
            jobs += [("ideal", sc, system, ("", t)) for t in BENCH_TOLERANCES if not (quick and t < 1e-6)]
        jobs += [("ode", sc, system, g) for g in ode_grid(quick)]
        jobs.append(("exact" if linear else "reference", sc, system, None))
    return jobs


def _timed(kind: str, system, g, repeats: int) -> tuple:
    """One setting run *repeats* times, only the solver call timed: (label, tolerance, median seconds,
    time points, joint rates, timed runs)."""
    from ..solvers.ode import solve_ode

    if kind == "spice":
        label, opts, ms, tol = g
        if isinstance(opts, Preset):         # a tolerance: the whole preset, its work guarded first
            check_work(system, opts, spice=True)
            text = netlist(system, opts, printing=False)
        else:
            text = netlist(system, Preset("bench", steps=ms // 2, spice=SpiceSettings(
                opts, max_steps=ms, behavioural_options=opts, behavioural_max_steps=ms)), printing=False)
        sess = session()

        def run():
            t0 = _time.perf_counter()
            data = sess.run(text, system.nodes)
            return data, _time.perf_counter() - t0

        med, data, runs = _median_time(run, repeats)
        rates = system.joint_rates(np.column_stack([data[k] for k in system.nodes]))
        return label, tol, med, data["time"], rates, runs
    t = np.linspace(0.0, system.t_stop, 201)
    if kind == "ode":
        method, tol = g
        label = f"{method} rtol={tol:g}"
    elif kind == "exact":
        label, tol = "modal", 0.0
    else:
        method, tol = "DOP853", NONLINEAR_RTOL
        label = f"DOP853 rtol={NONLINEAR_RTOL:g}"

    def run():
        tr = solve_exact(system, t) if kind == "exact" else solve_ode(system, t, method, tol)
        return tr, tr.run_time

    med, tr, runs = _median_time(run, repeats)
    return label, tol, med, t, tr.rates, runs


def _error(kind: str, system, t: np.ndarray, rates: np.ndarray) -> float:
    """The worst output's error over its own peak, against the exact solution (linear), a tight
    reference (nonlinear), a four times tighter one (the reference itself) or, for the exact
    solver, 40-digit mpmath at five points (NaN past 10 DOF, where it has no independent reference)."""
    from ..solvers.ode import solve_ode

    if kind == "exact":
        if system.dof > 10:
            return float("nan")
        probe = np.linspace(0.0, system.t_stop, 5)
        return float(np.max(output_errors(solve_exact(system, probe).voltages,
                                          solve_reference(system, probe).voltages)[1]))
    if kind == "reference":
        ref = solve_ode(system, t, "DOP853", NONLINEAR_RTOL / 4).rates
    elif system.kind == "linear":
        ref = solve_exact(system, t).rates
    else:
        ref = solve_ode(system, t, "DOP853", NONLINEAR_RTOL).rates
    return float(np.max(output_errors(rates, ref)[1]))


def _ideal_row(sc: Scene, system, circuit: str, tol: float) -> BenchRow:
    """The ideal trapezoidal count at :data:`~analogy.solvers.truncation.MODEL_SHARE` of *tol* on *system*'s
    circuit: the equidistributed schedule of its truncation model (no run, no time)."""
    model = truncation_model(system)
    share = MODEL_SHARE * tol
    points = round(model.ideal_points(share)) if model is not None else 0
    return BenchRow(sc.name, system.dof, "ideal", f"{circuit}trapezoidal h~sigma^(-1/3)", tol, float("nan"), share,
                    points, "ok" if model is not None else "no model")


def bench(repeats: int = 5, full: bool = False, scenes=None, progress: bool = True,
          quick: bool = False) -> BenchResult:
    """Time every solver setting on every scene and measure its error against the exact solution.

    Only the solver call is timed (netlist text and the exact reference are built
    outside). A setting that raises, or whose time step collapses, is a failure row.
    A setting slower than 1 s per run gets fewer timed runs; each row records how many.

    Parameters
    ----------
    repeats : int
        Timed runs per setting (the median is reported).
    full : bool
        Cross every ngspice method, tolerance and step cap.
    scenes : sequence of Scene, optional
        Scenes to time (default :func:`bench_scenes`).
    progress : bool
        Show progress: a bar on a terminal, plain lines otherwise.
    quick : bool
        A small grid on the 2- and 10-DOF scenes, for a first look in seconds.
    """
    start = _time.perf_counter()
    result = BenchResult(repeats=repeats)
    jobs = _jobs(bench_scenes(quick) if scenes is None else scenes, full, quick)
    bar = Progress(len(jobs), unit="setting", enabled=progress)
    for kind, sc, system, g in jobs:
        if kind == "ideal":
            result.rows.append(_ideal_row(sc, system, *g))
            bar.update(1)
            continue
        try:
            label, tol, med, t, rates, runs = _timed(kind, system, g, repeats)
            result.rows.append(BenchRow(sc.name, system.dof, kind, label, tol, med, _error(kind, system, t, rates),
                                        len(t), runs=runs))
        except (AnalogyError, ArithmeticError, ValueError) as exc:
            label = g[0] if kind == "spice" else (f"{g[0]} rtol={g[1]:g}" if kind == "ode" else kind)
            tol = g[3] if kind == "spice" else (g[1] if kind == "ode" else 0.0)
            result.rows.append(BenchRow(sc.name, system.dof, kind, label, tol, float("nan"), float("nan"), 0,
                                        f"failed: {str(exc).splitlines()[0][:120]}"))
        bar.update(1)
    bar.close()
    result.wall_s = _time.perf_counter() - start
    return result
