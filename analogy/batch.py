"""Many scenes at once: sub-circuits grouped into shared ngspice runs, spread over worker processes."""

from __future__ import annotations

import csv
import time as _time
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from .errors import AnalogyError, InputError
from .presets import preset as get_preset

__all__ = ["batch_netlist", "solve_spice_group", "BatchResult", "run_batch"]


def batch_netlist(systems: Sequence, preset="fast") -> str:
    """One netlist holding every system as an independent sub-circuit (prefix ``x<k>_``).

    All systems must share t_stop, so that one ``.tran`` serves them all.
    """
    from .netlist import analysis_lines, element_lines, source_lines
    if not systems:
        raise InputError("a batch needs at least one system")
    t_stop = systems[0].t_stop
    if any(s.t_stop != t_stop for s in systems):
        raise InputError("systems in one ngspice run must share t_stop")
    lines, ic, save = [f"* analogy batch of {len(systems)} independent circuits"], {}, []
    for k, s in enumerate(systems):
        prefix = f"x{k}_"
        body, aux = element_lines(s, prefix=prefix)
        lines += body + source_lines(s, prefix=prefix)
        nodes = [f"{prefix}{n}" for n in s.nodes]
        ic.update(zip(nodes, s.initial_voltages.tolist()))
        ic.update(aux)
        save += [f"v({n})" for n in nodes]
    return "\n".join(lines + analysis_lines(preset, t_stop, ic, save) + [".end"]) + "\n"


def solve_spice_group(systems: Sequence, preset="fast"):
    """Run *systems* in one ngspice run; return (time, [node voltages per system], seconds)."""
    from .spice import session
    text = batch_netlist(systems, preset)
    start = _time.perf_counter()
    data = session().run(text)
    elapsed = _time.perf_counter() - start
    volts = [np.column_stack([data[f"x{k}_{n}"] for n in s.nodes]) for k, s in enumerate(systems)]
    return data["time"], volts, elapsed


@dataclass(eq=False)
class BatchResult:
    """Per-scene SPICE errors against the exact solution, and the batch's throughput.

    Attributes
    ----------
    errors : ndarray
        Max |R_spice − R_exact| / peak |R_exact| per scene (NaN where not compared).
    failures : dict of int to str
        Scenes whose group failed, with the reason.
    wall_time : float
        Seconds for the whole batch, workers included.
    rates : list of ndarray or None
        Joint rates per scene on its group's time points, when kept.
    """

    errors: np.ndarray
    wall_time: float
    spice_time: float
    failures: dict = field(default_factory=dict)
    times: list | None = None
    rates: list | None = None

    @property
    def throughput(self) -> float:
        """Scenes per second of wall time."""
        return len(self.errors) / self.wall_time if self.wall_time > 0 else float("inf")

    def summary(self) -> str:
        ok = self.errors[np.isfinite(self.errors)]
        worst = f"{ok.max():.3e}" if ok.size else "n/a"
        return (f"{len(self.errors)} scenes in {self.wall_time:.3f} s ({self.throughput:.0f} scenes/s), "
                f"ngspice {self.spice_time:.3f} s, worst error/peak {worst}, {len(self.failures)} failed")

    def __str__(self):
        return self.summary()

    def to_csv(self, path) -> Path:
        """One row per scene: index, error relative to the peak, failure reason."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["scene", "error_over_peak", "failure"])
            for k, e in enumerate(self.errors):
                w.writerow([k, repr(float(e)), self.failures.get(k, "")])
        return path

    def plot(self, path=None):
        """Histogram of the per-scene errors (log scale)."""
        from matplotlib.figure import Figure
        fig = Figure(figsize=(6, 3.5), layout="constrained")
        ax = fig.subplots()
        ok = self.errors[np.isfinite(self.errors) & (self.errors > 0)]
        if ok.size:
            ax.hist(np.log10(ok), bins=40)
        ax.set_xlabel("log10(max error / peak)")
        ax.set_ylabel("scenes")
        ax.set_title(self.summary(), fontsize="small")
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


_MODELS: dict = {}


def _system(item):
    """A NodeSystem from a NodeSystem or a Scene (its model built once per process)."""
    from .scenes import Scene
    if not isinstance(item, Scene):
        return item
    key = item.model if isinstance(item.model, str) else id(item.model)
    model = _MODELS.get(key)
    if model is None:
        model = _MODELS[key] = item.numeric_model()
    return item.system(model)


def _group(payload):
    """Worker: one ngspice run for a group, then each scene against its exact solution."""
    items, preset, compare_exact, keep = payload
    try:
        systems = [_system(x) for x in items]
    except AnalogyError as exc:
        return [np.nan] * len(items), 0.0, str(exc), None, None
    try:
        t, volts, spice_seconds = solve_spice_group(systems, preset)
    except AnalogyError as exc:
        return [np.nan] * len(systems), 0.0, str(exc), None, None
    errors, rates = [], []
    from .exact import solve_exact_many
    exact = solve_exact_many(systems, t) if compare_exact else [None] * len(systems)
    for s, v, ev in zip(systems, volts, exact):
        r = s.joint_rates(v)
        if ev is not None:
            ex = s.joint_rates(ev)
            errors.append(float(np.max(np.abs(r - ex)) / np.max(np.abs(ex))))
        else:
            errors.append(np.nan)
        if keep:
            rates.append(r)
    return errors, spice_seconds, None, (t if keep else None), (rates if keep else None)


def run_batch(systems: Sequence, preset="fast", *, group_size: int = 100, workers: int = 2,
              executor: Executor | None = None, compare_exact: bool = True,
              keep_rates: bool = False, progress: bool = False) -> BatchResult:
    """Simulate many systems: groups of *group_size* share one ngspice run.

    *systems* holds NodeSystems or Scenes; Scenes are built in the workers (a
    built-in model is derived and compiled once per worker process).
    Systems are grouped by t_stop (their time grids must agree), split into groups,
    and the groups are spread over *workers* processes (or any
    ``concurrent.futures.Executor``, e.g. a Dask client's ``get_executor()``).
    """
    p = get_preset(preset)
    if group_size < 1 or workers < 1:
        raise InputError("group_size and workers must be at least 1")
    start = _time.perf_counter()
    by_grid: dict[float, list[int]] = {}
    for k, s in enumerate(systems):
        by_grid.setdefault(s.t_stop, []).append(k)
    groups = [idx[i:i + group_size] for idx in by_grid.values() for i in range(0, len(idx), group_size)]
    payloads = [([systems[k] for k in g], p, compare_exact, keep_rates) for g in groups]
    own = None
    if executor is None and workers > 1 and len(groups) > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        # forkserver: workers start clean, each with its own ngspice library state.
        ctx = multiprocessing.get_context("forkserver")
        # Imports done once in the server are shared by every worker forked from it.
        ctx.set_forkserver_preload(["analogy.batch", "analogy.spice", "analogy.exact",
                                    "analogy.netlist", "analogy.compiled", "analogy.scenes",
                                    "PySpice.Spice.NgSpice.Shared"])
        executor = own = ProcessPoolExecutor(workers, mp_context=ctx)
    try:
        outputs = executor.map(_group, payloads) if executor is not None else map(_group, payloads)
        if progress:
            from tqdm import tqdm
            outputs = tqdm(outputs, total=len(payloads), unit="group")
        errors = np.full(len(systems), np.nan)
        failures, times, rates = {}, [None] * len(systems), [None] * len(systems)
        spice_seconds = 0.0
        for g, (errs, sec, failure, t, r) in zip(groups, outputs):
            spice_seconds += sec
            errors[g] = errs
            for j, k in enumerate(g):
                if failure:
                    failures[k] = failure
                if t is not None:
                    times[k], rates[k] = t, r[j]
    finally:
        if own is not None:
            own.shutdown()
    wall = _time.perf_counter() - start
    return BatchResult(errors, wall, spice_seconds, failures,
                       times if keep_rates else None, rates if keep_rates else None)
