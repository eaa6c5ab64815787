"""Many scenes at once: groups solved together through the orchestrator, spread over worker processes."""

from __future__ import annotations

import time as _time
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import AnalogyError, InputError
from ..presets import preset as get_preset
from ..processes import worker_pool
from ..study.comparison import compare_many
from ..study.work import check_work, check_works
from ..results.output import html_table, write_rows
from ..scenes.scene import Scene
from ..solvers.registry import solver

if TYPE_CHECKING:
    import pandas
    from matplotlib.figure import Figure

__all__ = ["BatchResult", "run_batch"]


@dataclass(eq=False)
class BatchResult:
    """Per-scene errors against the reference, and the batch's throughput.

    Attributes
    ----------
    errors : ndarray
        Max |R − R_ref| / peak |R_ref| per scene of the first solver (NaN where not compared).
    wall_time : float
        Seconds for the whole batch, workers included.
    spice_time : float
        Seconds in ngspice over all scenes.
    failures : dict of int to str
        Scenes that could not be built or simulated, with the reason.
    times, rates : list or None
        Time points and joint rates per scene (of the first solver), when kept.
    solver_errors : dict of str to ndarray
        Per solver, the error of every scene.
    solver_seconds : dict of str to float
        Per solver, seconds over all scenes.
    """

    errors: np.ndarray
    wall_time: float
    spice_time: float
    failures: dict = field(default_factory=dict)
    times: list | None = None
    rates: list | None = None
    solver_errors: dict = field(default_factory=dict)
    solver_seconds: dict = field(default_factory=dict)

    @property
    def throughput(self) -> float:
        """Scenes per second of wall time."""
        return len(self.errors) / self.wall_time if self.wall_time > 0 else float("inf")

    def summary(self) -> str:
        """One line: scenes, seconds, throughput, worst error, failures."""
        ok = self.errors[np.isfinite(self.errors)]
        worst = f"{ok.max():.3e}" if ok.size else "n/a"
        return (f"{len(self.errors)} scenes in {self.wall_time:.3f} s ({self.throughput:.0f} scenes/s), "
                f"ngspice {self.spice_time:.3f} s, worst error/peak {worst}, {len(self.failures)} failed")

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        return f"<BatchResult {self.summary()}>"

    def _repr_html_(self) -> str:
        rows = [[name, float(np.nanmax(e)) if np.isfinite(e).any() else float("nan"),
                 self.solver_seconds.get(name, float("nan"))] for name, e in self.solver_errors.items()]
        return html_table(["solver", "worst error / peak", "seconds"], rows)

    def columns(self) -> dict[str, np.ndarray]:
        """``scene``, then ``error_<solver>`` per solver and ``failure``."""
        cols = {"scene": np.arange(len(self.errors))}
        cols.update((f"error_{name}", e) for name, e in (self.solver_errors or {"spice": self.errors}).items())
        return cols

    def to_frame(self) -> "pandas.DataFrame":
        """The :meth:`columns` as a pandas DataFrame, with the failure reasons."""
        import pandas as pd
        frame = pd.DataFrame(self.columns()).set_index("scene")
        frame["failure"] = [self.failures.get(k, "") for k in range(len(self.errors))]
        return frame

    def to_csv(self, path) -> Path:
        """One row per scene: index, each solver's error relative to the peak, failure reason.

        Parameters
        ----------
        path : str or Path
            The file to write.
        """
        cols = self.columns()
        return write_rows(path, list(cols) + ["failure"],
                          ([k] + [float(c[k]) for c in list(cols.values())[1:]] + [self.failures.get(k, "")]
                           for k in range(len(self.errors))))

    def plot(self, path=None) -> "Figure":
        """Histogram of the per-scene errors (log scale).

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
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


def _system(item):
    """A node system from a NodeSystem or a Scene."""
    return item.system() if isinstance(item, Scene) else item


def _systems(task) -> tuple[list, dict]:
    """Build a task's systems; return them (None where a build failed) and the failures.

    A task is ("family", scene, configurations, parameters per row), scenes that differ
    only in q and a robot's parameter values and are built as one stack, or
    ("items", [Scene or NodeSystem, ...]).
    """
    kind, *rest = task
    if kind == "family":
        base, qs, params = rest
        try:
            return base.systems(qs, parameters=params), {}
        except AnalogyError:            # one row is bad: build row by row to keep the others
            pass
    items = _items(task)
    systems, failures = [], {}
    for k, item in enumerate(items):
        try:
            systems.append(_system(item))
        except AnalogyError as exc:
            systems.append(None)
            failures[k] = str(exc)
    return systems, failures


def _group(payload):
    """Worker: a group's systems, compared through the orchestrator in one go.

    SPICE runs the group as one circuit; if that run fails, each scene runs alone, so
    that one scene's failure is its own. Errors are against the exact solution. Returns
    per scene: errors and seconds per solver, failures (index to reason), the indices
    that could not be built and those refused by the work guard, and the kept trajectories.
    """
    task, preset, solvers, reference, keep = payload
    built, failures = _systems(task)
    invalid = set(failures)
    refused = set()
    try:
        check_works([s for s in built if s is not None], preset, spice="spice" in solvers)
    except InputError:                  # some scene is past the work budget: find which, and refuse it alone
        for k, s in enumerate(built):
            if s is not None:
                try:
                    check_work(s, preset, spice="spice" in solvers)
                except InputError as exc:
                    built[k], failures[k] = None, str(exc)
                    refused.add(k)
    ok = [k for k, s in enumerate(built) if s is not None]
    errors = {name: np.full(len(built), np.nan) for name in solvers}
    seconds = {name: np.zeros(len(built)) for name in solvers}
    rates: list = [None] * len(built)
    comparisons = compare_many([built[k] for k in ok], preset, solvers, reference=reference) if ok else []
    for k, c in zip(ok, comparisons):
        for name, why in c.failures.items():
            failures[k] = f"{name}: {why}" if name != "spice" else why
        measured = c.measured
        for name in solvers:
            tr = c.results.get(name)
            if tr is not None:
                seconds[name][k] = tr.run_time
                if name in measured and name != c.reference:     # the yardstick has no error
                    errors[name][k] = measured[name][1]
        if keep:
            rates[k] = {s: (c.results[s].time, c.results[s].rates) for s in solvers
                        if s in c.results and c.results[s].success}
    return errors, seconds, failures, (invalid, refused), (rates if keep else None)


def _isolated_group(payload):
    """Worker: :func:`_group`, and when it raises, each scene alone, so a bug in one scene fails only it."""
    try:
        return _group(payload)
    except Exception:       # noqa: BLE001 - one scene's bug must not lose the group's other scenes
        pass
    task, preset, solvers, reference, keep = payload
    items = _items(task)
    count = len(items)
    errors = {name: np.full(count, np.nan) for name in solvers}
    seconds = {name: np.zeros(count) for name in solvers}
    failures, invalid, refused, rates = {}, set(), set(), [None] * count
    for k, item in enumerate(items):
        try:
            errs, secs, failed, (bad, late), kept = _group((("items", [item]), preset, solvers, reference, keep))
        except Exception as exc:        # noqa: BLE001
            failures[k] = f"internal error: {type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
            continue
        for name in solvers:
            errors[name][k], seconds[name][k] = errs[name][0], secs[name][0]
        if 0 in failed:
            failures[k] = failed[0]
        invalid |= {k} if bad else set()
        refused |= {k} if late else set()
        if kept is not None:
            rates[k] = kept[0]
    return errors, seconds, failures, (invalid, refused), (rates if keep else None)


def _items(task) -> list:
    """The scenes or systems of a task, one by one."""
    kind, *rest = task
    if kind != "family":
        return list(rest[0])
    base, qs, params = rest
    return [base.replace(q=tuple(row), parameters={**dict(base.parameters), **{k: float(v[i]) for k, v in params.items()}})
            for i, row in enumerate(np.asarray(qs).tolist())]


def _tasks(systems, group_size: int) -> list[tuple[list[int], tuple]]:
    """Split *systems* into (indices, task) groups of at most *group_size* with one time grid.

    Scenes that differ only in their configuration and a robot's parameter values form
    one family, built as a stack.
    """
    kinds: dict = {}
    for k, item in enumerate(systems):
        family = item.family() if isinstance(item, Scene) else None
        key = ("family", family) if family is not None else ("grid", item.t_stop)
        kinds.setdefault(key, []).append(k)
    tasks = []
    for (kind, _), idx in kinds.items():
        for i in range(0, len(idx), group_size):
            chunk = idx[i:i + group_size]
            if kind == "family":
                first = systems[chunk[0]]
                qs = np.array([systems[k].q for k in chunk], dtype=float).reshape(len(chunk), -1)
                params = {}
                if first.model.robot is not None and first.parameters:
                    values = np.array([[v for _, v in systems[k].parameters] for k in chunk], dtype=float)
                    params = {name: values[:, j] for j, (name, _) in enumerate(first.parameters)
                              if np.any(values[:, j] != values[0, j])}
                tasks.append((chunk, ("family", first, qs, params)))
            else:
                tasks.append((chunk, ("items", [systems[k] for k in chunk])))
    return tasks


def run_batch(systems: Sequence, preset="fast", *, solvers: Sequence[str] = ("spice",),
              group_size: int = 100, workers: int = 2, executor: Executor | None = None,
              compare_exact: bool = True, keep_rates: bool = False, progress: bool = False) -> BatchResult:
    """Simulate many systems: groups of *group_size* run together through :func:`compare_many`.

    *systems* holds NodeSystems or Scenes. Scenes are built in the workers; those that
    differ only in q are built as one stack (:func:`analogy.circuit.node_system.node_systems`),
    and a built-in model is derived and compiled once per worker process. Groups share
    one time grid (t_stop) and are spread over *workers* processes (or any
    ``concurrent.futures.Executor``, e.g. a Dask client's ``get_executor()``).

    Parameters
    ----------
    systems : sequence of NodeSystem or Scene
        What to simulate.
    preset : str or Preset
        Accuracy preset.
    solvers : sequence of str
        Solvers to run on every scene (SPICE runs each group as one circuit).
    group_size : int
        Scenes per group.
    workers : int
        Worker processes (1: in this process).
    executor : Executor, optional
        Runs the groups instead of a process pool.
    compare_exact : bool
        Measure errors against the exact solution (run for that).
    keep_rates : bool
        Keep every scene's time points and joint rates.
    progress : bool
        Show a progress bar.
    """
    p = get_preset(preset)
    names = list(dict.fromkeys(solvers))
    if group_size < 1 or workers < 1:
        raise InputError("group_size and workers must be at least 1")
    if not names:
        raise InputError("a batch needs at least one solver")
    start = _time.perf_counter()
    tasks = _tasks(systems, group_size)
    reference = "auto" if compare_exact else None
    payloads = [(task, p, names, reference, keep_rates) for _, task in tasks]
    own = None
    if executor is None and workers > 1 and len(tasks) > 1:
        for name in names + ["exact"]:
            solver(name)            # imported once here, so that forked workers start with it
        executor = own = worker_pool(workers)
    try:
        outputs = executor.map(_isolated_group, payloads) if executor is not None else map(_isolated_group, payloads)
        if progress:
            from tqdm import tqdm
            outputs = tqdm(outputs, total=len(payloads), unit="group")
        errors = {name: np.full(len(systems), np.nan) for name in names}
        seconds = {name: 0.0 for name in names}
        failures, times, rates = {}, [None] * len(systems), [None] * len(systems)
        for (idx, _), (errs, sec, failed, _invalid, kept) in zip(tasks, outputs):
            for name in names:
                errors[name][idx] = errs[name]
                seconds[name] += float(sec[name].sum())
            failures.update((idx[j], why) for j, why in failed.items())
            for j, k in enumerate(idx):
                if kept is not None and kept[j]:
                    times[k], rates[k] = kept[j][names[0]] if names[0] in kept[j] else next(iter(kept[j].values()))
    finally:
        if own is not None:
            own.shutdown()
    wall = _time.perf_counter() - start
    return BatchResult(errors[names[0]], wall, seconds.get("spice", 0.0), dict(sorted(failures.items())),
                       times if keep_rates else None, rates if keep_rates else None, errors, seconds)
