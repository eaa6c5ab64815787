"""Benchmarks: run time against error for SPICE settings, ODE methods and the exact solver."""

from __future__ import annotations

import gc
import logging
import multiprocessing
import os
import resource
import statistics
import time as _time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .batch.run import _system, run_batch
from .circuit.description import circuit
from .circuit.netlist import netlist
from .errors import AnalogyError, InputError
from .presets import PRESETS, Preset
from .presets import preset as get_preset
from .results.metrics import relative_error
from .results.output import write_rows
from .scenes.builtin import scene
from .scenes.scene import Scene
from .scenes.spec import ModelSpec
from .solvers.exact import solve_exact
from .solvers.reference import NONLINEAR_RTOL, solve_reference
from .solvers.spice import library_path, session, solve_spice

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["BenchRow", "BenchResult", "MemoryResult", "bench", "bench_scenes", "memory_per_run", "throughput",
           "spice_grid", "ode_grid", "nonlinear_spice_grid"]

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

    def to_csv(self, path) -> Path:
        """to_csv.

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
                 f"{'error/peak':>11}  status"]
        for r in self.rows:
            lines.append(f"{r.scene:<18}{r.dof:>4}  {r.solver:<10}{r.setting:<40}{r.median_s * 1e3:>12.3f}"
                         f"{r.runs:>5}{r.error:>11.2e}  {r.status}")
        lines += self.cost_lines()
        lines.append(f"{len(self.rows)} rows, {sum(r.status != 'ok' for r in self.rows)} failed; median of "
                     f"up to {self.repeats} warm runs (fewer for settings slower than "
                     f"{_BUDGET_S:g} s per run); {self.wall_s:.1f} s in all")
        return "\n".join(lines)

    def __str__(self):
        return self.table()

    def cost_lines(self) -> list[str]:
        """Per scene, the cheapest SPICE and ODE settings within 1e-6 of the peak, and their ratio."""
        lines = []
        for sc in dict.fromkeys(r.scene for r in self.rows):
            best = {}
            for solver in ("spice", "ode"):
                ok = [r for r in self.rows if r.scene == sc and r.solver == solver and r.status == "ok"
                      and r.error <= 1e-6]
                if ok:
                    best[solver] = min(ok, key=lambda r: r.median_s)
            if len(best) == 2:
                sp_, od = best["spice"], best["ode"]
                lines.append(f"{sc}: cheapest within 1e-6: SPICE {sp_.median_s * 1e3:.2f} ms ({sp_.setting}), "
                             f"ODE {od.median_s * 1e3:.2f} ms ({od.setting}), SPICE/ODE = "
                             f"{sp_.median_s / od.median_s:.2f}")
        return lines

    def plot(self, path=None) -> "Figure":
        """Work-precision diagram: median run time against max error / peak, log-log, per scene.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from matplotlib.figure import Figure
        scenes = list(dict.fromkeys(r.scene for r in self.rows))
        fig = Figure(figsize=(5.0 * len(scenes), 4.6), layout="constrained")
        axes = np.atleast_1d(fig.subplots(1, len(scenes), sharey=True))
        markers = {"spice": "o", "ode": "s", "exact": "*", "reference": "P"}
        for ax, sc in zip(axes, scenes):
            rows = [r for r in self.rows if r.scene == sc]
            families = dict.fromkeys((r.solver, r.setting.split(" ")[0]) for r in rows)
            for solver, family in families:
                sel = [r for r in rows if r.solver == solver and r.setting.split(" ")[0] == family
                       and r.status == "ok" and np.isfinite(r.error)]
                if not sel:
                    continue
                sel.sort(key=lambda r: r.error)
                ax.loglog([max(r.error, 1e-17) for r in sel], [r.median_s for r in sel],
                          marker=markers[solver], ms=8 if solver == "exact" else 4,
                          ls="-" if solver != "exact" else "none", label=f"{solver} {family}")
            unref = [r for r in rows if r.solver == "exact" and r.status == "ok" and not np.isfinite(r.error)]
            for r in unref:     # no independent reference at this size: time only, drawn at 1e-16
                ax.loglog([1e-16], [r.median_s], marker="*", ms=9, mfc="none", ls="none",
                          label="exact modal (no reference)")
            failed = [r for r in rows if r.status != "ok"]
            if failed:
                ax.text(0.02, 0.02, f"{len(failed)} settings failed", transform=ax.transAxes,
                        fontsize="small", color="tab:red")
            ax.set_title(f"{sc} ({rows[0].dof} DOF)")
            ax.set_xlabel("max error / peak (vs exact, or the reference if nonlinear)")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize="x-small", ncol=2)
        axes[0].set_ylabel(f"median run time [s] ({self.repeats} warm runs)")
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def bench_scenes() -> list[Scene]:
    """The benchmark's scenes: 2, 10 and 50 DOF, and the 2-DOF arm's nonlinear dynamics."""
    big = Scene.of("random50", ModelSpec(robot="random50", seed=2), topology="serial",
                   forces=tuple(["sine(0, 1, 0.7)"] + [f"step({1.0 / (k + 1)!r})" for k in range(1, 50)]),
                   t_stop=2.0, description="random SPD 50-DOF (seed 2), serial topology")
    nonlinear = scene("default").replace(name="default-nonlinear", dynamics="nonlinear",
                                         description="the default arm's full nonlinear dynamics")
    return [scene("default"), scene("random10"), big, nonlinear]


def spice_grid(full: bool = False) -> list[tuple]:
    """(label, options, max_steps) for ngspice: method, reltol, trtol and maximum step.

    Parameters
    ----------
    full : bool
        Also cross the step caps T/1000 and T/20000.
    """
    grid = []
    reltols = (1e-3, 1e-5, 1e-7, 1e-9)
    trtols = (7, 1)
    max_steps = (50, 1000, 20000) if full else (50,)
    for method in ("trap", "gear"):
        for rt in reltols:
            for tr in trtols:
                for ms in max_steps:
                    opts = {"method": method, "reltol": rt, "abstol": 1e-15, "vntol": 1e-13,
                            "chgtol": 1e-20, "trtol": tr}
                    grid.append((f"{method} reltol={rt:g} trtol={tr} tmax=T/{ms}", opts, ms, rt))
    for name, p in PRESETS.items():
        grid.append((f"preset-{name}", dict(p.spice_options), p.max_steps, p.spice_options["reltol"]))
    return grid


def nonlinear_spice_grid() -> list[tuple]:
    """(label, options, max_steps, reltol) for nonlinear circuits: the step cap sets their accuracy.

    Tight reltol with trtol = 1 is in the grid to show it failing ("timestep too small").
    """
    grid = [(f"{m} default tolerances tmax=T/{ms}", {"method": m}, ms, 1e-3)
            for m in ("trap", "gear") for ms in (500, 2000, 20000)]
    grid.append(("trap reltol=1e-6 trtol=1 tmax=T/2000", {"method": "trap", "reltol": 1e-6, "trtol": 1}, 2000, 1e-6))
    grid += [(f"preset-{name}", dict(p.behavioural_options), p.behavioural_max_steps, 1e-3)
             for name, p in PRESETS.items()]
    return grid


def ode_grid() -> list[tuple[str, float]]:
    """(method, rtol) pairs: rtol from 1e-3 to 1e-10."""
    return [(m, 10.0 ** -k) for m in ODE_BENCH_METHODS for k in range(3, 11)]


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


def bench(repeats: int = 5, full: bool = False, scenes=None, progress: bool = True) -> BenchResult:
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
        Show a progress bar.
    """
    from .solvers.ode import solve_ode

    start = _time.perf_counter()
    result = BenchResult(repeats=repeats)
    scenes = bench_scenes() if scenes is None else scenes
    jobs = []
    for sc in scenes:
        system = sc.system()
        linear = getattr(system, "kind", "linear") == "linear"
        jobs += [("spice", sc, system, g) for g in (spice_grid(full) if linear else nonlinear_spice_grid())]
        jobs += [("ode", sc, system, g) for g in ode_grid()]
        jobs.append(("exact" if linear else "reference", sc, system, None))
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), unit="setting", leave=False)
    sess = session()
    for kind, sc, system, g in jobs:
        n = system.dof
        linear = getattr(system, "kind", "linear") == "linear"
        try:
            if kind == "spice":
                label, opts, ms, tol = g
                text = netlist(system, Preset("bench", opts, steps=100, max_steps=ms, behavioural_options=opts,
                                              behavioural_max_steps=ms), printing=False)

                def run():
                    t0 = _time.perf_counter()
                    data = sess.run(text, system.nodes)
                    return data, _time.perf_counter() - t0

                med, data, runs = _median_time(run, repeats)
                t = data["time"]
                v = np.column_stack([data[k] for k in system.nodes])
                rates = system.joint_rates(v)
            elif kind == "ode":
                method, tol = g
                label = f"{method} rtol={tol:g}"
                t = np.linspace(0.0, system.t_stop, 201)

                def run():
                    tr = solve_ode(system, t, method, tol)
                    return tr, tr.run_time

                med, tr, runs = _median_time(run, repeats)
                rates = tr.rates
            elif kind == "exact":
                label, tol = "modal", 0.0
                t = np.linspace(0.0, system.t_stop, 201)

                def run():
                    tr = solve_exact(system, t)
                    return tr, tr.run_time

                med, tr, runs = _median_time(run, repeats)
                rates = tr.rates
            else:
                label, tol = f"DOP853 rtol={NONLINEAR_RTOL:g}", NONLINEAR_RTOL
                t = np.linspace(0.0, system.t_stop, 201)

                def run():
                    tr = solve_ode(system, t, "DOP853", NONLINEAR_RTOL)
                    return tr, tr.run_time

                med, tr, runs = _median_time(run, repeats)
                rates = tr.rates
            if kind == "reference":     # its own error: against a four times tighter run
                ref = solve_ode(system, t, "DOP853", NONLINEAR_RTOL / 4).rates
            elif linear:
                ref = solve_exact(system, t).rates
            else:
                ref = solve_ode(system, t, "DOP853", NONLINEAR_RTOL).rates
            err = relative_error(rates, ref)
            if kind == "exact":
                probe = np.linspace(0.0, system.t_stop, 5)
                # The exact solver's own error is measured against 40-digit mpmath where
                # that is affordable; above 10 DOF it has no independent reference here.
                err = float("nan")
                if n <= 10:
                    mp = solve_reference(system, probe)
                    ex = solve_exact(system, probe).voltages
                    err = relative_error(ex, mp)
            result.rows.append(BenchRow(sc.name, n, kind, label, tol, med, err, len(t), runs=runs))
        except (AnalogyError, ArithmeticError, ValueError) as exc:
            label = g[0] if kind == "spice" else (f"{g[0]} rtol={g[1]:g}" if kind == "ode" else kind)
            tol = g[3] if kind == "spice" else (g[1] if kind == "ode" else 0.0)
            result.rows.append(BenchRow(sc.name, n, kind, label, tol, float("nan"), float("nan"), 0,
                                        f"failed: {str(exc).splitlines()[0][:120]}"))
        if bar is not None:
            bar.update()
    if bar is not None:
        bar.close()
    result.wall_s = _time.perf_counter() - start
    return result


def _pyspice_loop(payload):
    """A plain PySpice loop: build a Circuit and call simulator().transient() per scene."""
    os.environ.setdefault("NGSPICE_LIBRARY_PATH", library_path())
    logging.getLogger("PySpice").setLevel(logging.CRITICAL)
    from PySpice.Spice.Netlist import Circuit

    items, preset_name = payload
    p = get_preset(preset_name)
    worst = 0.0
    start = None
    for k, item in enumerate([items[0]] + list(items)):
        if k == 1:      # the first pass is a warm-up: model, library and imports are ready
            start = _time.perf_counter()
        s = _system(item)
        c = Circuit("scene")
        desc = circuit(s)
        for e in desc.elements:
            getattr(c, e.kind)(e.name[1:], f"n{e.a}", c.gnd if e.b == 0 else f"n{e.b}", e.value)
        for src in desc.sources:        # constant forces: 'I n+ n- value' drives current into n-
            c.I(src.name[1:], c.gnd if src.b == 0 else f"n{src.b}", f"n{src.a}",
                src.scale * float(src.waveform.values[0]))
        sim = c.simulator(simulator="ngspice-shared")
        sim.initial_condition(**{n: float(v) for n, v in zip(s.nodes, s.initial_voltages)})
        sim.options(**p.spice_options)
        analysis = sim.transient(step_time=s.t_stop / p.steps, end_time=s.t_stop,
                                 max_time=s.t_stop / p.max_steps, use_initial_condition=True)
        t = np.array(analysis.time)
        v = np.column_stack([np.array(analysis[n]) for n in s.nodes])
        ex = solve_exact(s, t).rates
        worst = max(worst, relative_error(s.joint_rates(v), ex))
    return _time.perf_counter() - start, worst


def _solo_loop(payload):
    """One ngspice run per scene through the wrapped session, with the same comparison."""
    items, preset_name = payload
    worst, solves = 0.0, []
    start = None
    for k, item in enumerate([items[0]] + list(items)):
        if k == 1:      # the first pass is a warm-up, as in the PySpice loop
            start = _time.perf_counter()
            solves = []
        s = _system(item)
        tr = solve_spice(s, preset_name)
        solves.append(tr.run_time)
        ex = solve_exact(s, tr.time).rates
        worst = max(worst, relative_error(tr.rates, ex))
    return _time.perf_counter() - start, worst, statistics.median(solves)


def throughput(n: int = 10_000, preset: str = "fast", group_size: int = 100, workers: int = 2,
               baseline_n: int = 500, seed: int = 0, repeats: int = 3) -> str:
    """Scenes per second: batched (grouped runs on *workers* processes) against per-scene paths.

    The scenes are the default 2-DOF serial arm at random q2 in [−π, π]. Each path builds
    its systems, runs SPICE and compares with the exact solution. The per-scene paths
    run on *baseline_n* scenes in a fresh worker process each (timed after a warm-up
    pass); the batched path is timed whole, worker start-up included, on *workers*
    processes and, for the speed per core, on one. The paths take turns, *repeats*
    times, and the figures are medians.

    Parameters
    ----------
    n : int
        Scenes on the batched path.
    preset : str
        Accuracy preset.
    group_size : int
        Scenes per ngspice run.
    workers : int
        Worker processes of the batched path.
    baseline_n : int
        Scenes on each per-scene path.
    seed : int
        Seed of the random configurations.
    repeats : int
        Turns of every path; medians are reported.
    """
    if min(n, baseline_n, repeats, workers, group_size) < 1:
        raise InputError("n, baseline_n, repeats, workers and group_size must be at least 1")
    base = scene("default")
    q2 = np.random.default_rng(seed).uniform(-np.pi, np.pi, n)
    items = [base.replace(q=(0.0, float(x))) for x in q2]
    ctx = multiprocessing.get_context("forkserver")
    rates: dict = {k: [] for k in ("batched", "one", "solo", "pyspice")}
    worst: dict = {k: 0.0 for k in rates}
    failed, solves = 0, []
    for _ in range(repeats):
        with ProcessPoolExecutor(1, mp_context=ctx) as ex:
            sec, err, med = ex.submit(_solo_loop, (items[:baseline_n], preset)).result()
        rates["solo"].append(baseline_n / sec)
        worst["solo"], solves = max(worst["solo"], err), solves + [med]
        with ProcessPoolExecutor(1, mp_context=ctx) as ex:
            sec, err = ex.submit(_pyspice_loop, (items[:baseline_n], preset)).result()
        rates["pyspice"].append(baseline_n / sec)
        worst["pyspice"] = max(worst["pyspice"], err)
        for key, w in (("batched", workers), ("one", 1)):
            res = run_batch(items, preset, group_size=group_size, workers=w)
            rates[key].append(res.throughput)
            # a run with no finite error (all failed) makes the worst error NaN, not hidden
            ok = res.errors[np.isfinite(res.errors)]
            worst[key] = max(worst[key], float(ok.max())) if ok.size else float("nan")
            failed += len(res.failures)
    med = {k: statistics.median(v) for k, v in rates.items()}
    ratio = statistics.median(b / p for b, p in zip(rates["batched"], rates["pyspice"]))
    per_core = statistics.median(b / p for b, p in zip(rates["one"], rates["pyspice"]))

    def spread(key):
        return f"{med[key]:,.0f} scenes/s (runs {', '.join(f'{r:,.0f}' for r in rates[key])})"

    return "\n".join([
        f"throughput: default 2-DOF serial arm, random q2 in [-pi, pi], preset {preset}, "
        f"SPICE + comparison with the exact solution; medians of {repeats} turns",
        f"  batched, {workers} workers, {group_size} scenes per ngspice run, {n} scenes: "
        f"{spread('batched')}, worst error/peak {worst['batched']:.2e}",
        f"  batched, 1 process: {spread('one')}, worst error/peak {worst['one']:.2e}",
        f"  one ngspice run per scene (1 process, {baseline_n} scenes): {spread('solo')}, "
        f"worst error/peak {worst['solo']:.2e}, median SPICE solve {statistics.median(solves) * 1e3:.3f} ms",
        f"  plain PySpice loop (Circuit + simulator().transient(), 1 process, {baseline_n} scenes): "
        f"{spread('pyspice')}, worst error/peak {worst['pyspice']:.2e}",
        f"  speed-up over the PySpice loop (median of per-turn ratios): batched {ratio:.1f}x, "
        f"batched on 1 process {per_core:.1f}x; {failed} scenes failed",
    ])


@dataclass(frozen=True)
class MemoryResult:
    """Resident memory growth over many in-process SPICE runs of one system."""

    runs: int
    preset: str
    scene: str
    grown_kb: float
    seconds: float
    buffered_lines: int

    @property
    def kb_per_run(self) -> float:
        return self.grown_kb / self.runs

    def __str__(self) -> str:
        return (f"memory: {self.runs} in-process SPICE runs of scene {self.scene} at preset {self.preset}: "
                f"resident memory grew {self.grown_kb:.0f} kB, {self.kb_per_run:.3f} kB per run "
                f"({self.seconds:.1f} s; ngspice lines buffered after the runs: {self.buffered_lines})")


def _resident_kb() -> float:
    try:
        with open("/proc/self/statm") as f:         # current, not peak, resident size
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1024
    except OSError:
        return float(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def memory_per_run(runs: int = 10_000, preset: str = "accurate", scene_name: str = "default",
                   warmup: int = 200) -> MemoryResult:
    """Resident memory grown per in-process SPICE run (netlist, ngspice run, vectors read, freed).

    The first *warmup* runs are not counted: they fill caches and the allocator's pools.

    Parameters
    ----------
    runs : int
        Counted runs.
    preset : str
        Accuracy preset.
    scene_name : str
        A built-in scene.
    warmup : int
        Runs before the count starts.
    """
    if runs < 1 or warmup < 0:
        raise InputError("runs must be at least 1 and warmup at least 0")
    system = scene(scene_name).system()
    for _ in range(warmup):
        solve_spice(system, preset)
    gc.collect()
    before, start = _resident_kb(), _time.perf_counter()
    for _ in range(runs):
        solve_spice(system, preset)
    gc.collect()
    ng = session()._ng
    lines = len(getattr(ng, "_stdout", [])) + len(getattr(ng, "_stderr", []))
    return MemoryResult(runs, get_preset(preset).name, scene_name, _resident_kb() - before,
                        _time.perf_counter() - start, lines)
