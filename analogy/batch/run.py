"""Many scenes at once: groups solved together through the orchestrator, spread over worker processes."""

from __future__ import annotations

import time as _time
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import InputError
from ..presets import Preset
from ..presets import preset as get_preset
from ..progress import Progress
from ..results.output import html_table, write_rows
from ..solvers.registry import solver
from .executor import ATTEMPTS, PIPELINE, execute
from ..scenes.scene import Scene
from .plan import Group, GroupResult, plan_groups, solve_group_isolated

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
    interrupted : bool
        Stopped by SIGTERM under a caller's handler that returned: the scenes not reached have NaN errors.
    """

    errors: np.ndarray
    wall_time: float
    spice_time: float
    failures: dict = field(default_factory=dict)
    times: list | None = None
    rates: list | None = None
    solver_errors: dict = field(default_factory=dict)
    solver_seconds: dict = field(default_factory=dict)
    interrupted: bool = False

    @property
    def throughput(self) -> float:
        """Scenes per second of wall time."""
        return len(self.errors) / self.wall_time if self.wall_time > 0 else float("inf")

    def summary(self) -> str:
        """One line: scenes, seconds, throughput, worst error, failures."""
        ok = self.errors[np.isfinite(self.errors)]
        worst = f"{ok.max():.3e}" if ok.size else "n/a"
        stop = "interrupted: " if self.interrupted else ""
        return (f"{stop}{len(self.errors)} scenes in {self.wall_time:.3f} s ({self.throughput:.0f} scenes/s), "
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
        from ..results.plots import plot_error_histogram
        return plot_error_histogram(self.solver_errors or {"spice": self.errors}, self.summary(), None, "scenes", path)


def _solve(payload) -> GroupResult:
    """Worker entry: one group (a module-level function, so that it pickles by name)."""
    return solve_group_isolated(*payload)


def _preset_of(group: Group) -> Preset:
    """The preset a group's members share (:func:`plan_groups` keeps presets apart)."""
    first = group.base if group.base is not None else group.items[0]
    return first.settings if isinstance(first, Scene) else get_preset(Scene.preset)     # systems: the default


#: Most SPICE circuits of one family a batch group holds: its stack is built and checked once for them
#: all (about 2 ms a group of 100 two-joint scenes), while each circuit stays as small as asked.
CIRCUITS_PER_GROUP = 10


def _circuits(count: int, group_size: int, workers: int, threads: int, executor: Executor | None) -> int:
    """Circuits per group: at most :data:`CIRCUITS_PER_GROUP`, and few enough that each of *workers*
    processes (or, in this process, each of its *threads*) still gets two groups; one with an
    *executor*, whose workers are not known here."""
    if executor is not None:
        return 1
    return max(1, min(CIRCUITS_PER_GROUP, -(-count // group_size) // (2 * (workers if workers > 1 else threads))))


def run_batch(systems: Sequence, preset=None, *, solvers: Sequence[str] = ("spice",),
              group_size: int = 100, workers: int = 2, executor: Executor | None = None,
              compare_exact: bool = True, keep_rates: bool = False, progress: bool = False,
              threads: int = PIPELINE) -> BatchResult:
    """Simulate many systems: circuits of *group_size* run together through :func:`compare_many`.

    *systems* holds NodeSystems or Scenes. Scenes are built in the workers; those that
    differ only in q, parameters and t_stop are built as one stack
    (:func:`analogy.circuit.node_system.node_systems`), and a built-in model is derived and
    compiled once per worker process. A circuit's horizons lie within
    :data:`~analogy.batch.plan.HORIZON_SPREAD` of each other, so that one ngspice run to the
    longest serves them all. A group holds up to :data:`CIRCUITS_PER_GROUP` circuits of one
    family and one horizon, built and checked once (fewer where the workers would otherwise go
    short of groups; one with an *executor*); each circuit is still its own ngspice run, and a
    group whose worker died is run again circuit by circuit. Groups are spread over *workers* processes (or any
    ``concurrent.futures.Executor``, e.g. a Dask client's ``get_executor()``) by the
    same loop as :func:`~analogy.batch.runner.run_sweep`: a group whose worker died is
    retried. SIGINT and SIGTERM end the workers cleanly, then reach the caller as
    they would without the batch (KeyboardInterrupt, or the caller's SIGTERM handler).

    Parameters
    ----------
    systems : sequence of NodeSystem or Scene
        What to simulate.
    preset : str or Preset, optional
        Accuracy preset for every member. None: each Scene's own preset, and ``accurate``
        (a Scene's default) for a NodeSystem.
    solvers : sequence of str
        Solvers to run on every scene (SPICE runs each circuit as one netlist).
    group_size : int
        Scenes per SPICE circuit.
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
    threads : int
        Groups in flight on threads where the batch runs in this process (*workers* 1), one's Python
        beside another's ngspice run; 1: one at a time, the least CPU where two busy cores slow each other.
    """
    fixed = None if preset is None else get_preset(preset)
    names = list(dict.fromkeys(solvers))
    if group_size < 1 or workers < 1 or threads < 1:
        raise InputError("group_size, workers and threads must be at least 1")
    if not names:
        raise InputError("a batch needs at least one solver")
    start = _time.perf_counter()
    groups = plan_groups(systems, group_size, _circuits(len(systems), group_size, workers, threads, executor))
    reference = "auto" if compare_exact else None
    errors = {name: np.full(len(systems), np.nan) for name in names}
    seconds = {name: 0.0 for name in names}
    failures: dict = {}
    times: list = [None] * len(systems)
    rates: list = [None] * len(systems)
    bar = Progress(len(systems), bar=True) if progress else None

    def done(group, result: GroupResult) -> None:
        idx = list(group.rows)
        for name in names:
            errors[name][idx] = result.errors[name]
            seconds[name] += float(result.seconds[name].sum())
        failures.update((idx[j], why) for j, why in result.failures.items())
        for j, k in enumerate(idx):
            kept = result.rates[j] if result.rates is not None else None
            if kept:
                times[k], rates[k] = kept[names[0]] if names[0] in kept else next(iter(kept.values()))
        if bar is not None:
            bar.update(len(idx))

    split: list = []

    def died(group) -> None:    # a group of circuits runs again one circuit a group: only the culprit is lost
        split.extend(group.circuits()) if group.runs else failures.update(
            (k, f"the worker process died while solving this group ({ATTEMPTS} attempts)") for k in group.rows)

    spread = executor is None and workers > 1 and len(groups) > 1
    if spread:
        for name in names + ["exact"]:
            solver(name)            # imported once here, so that forked workers start with it
    try:
        for todo in (groups, split):
            interrupted = execute(todo, lambda g: (g, fixed or _preset_of(g), names, reference, keep_rates), _solve,
                                  done, died, workers=workers if spread else 1, executor=executor, in_process=True,
                                  pass_signals=True, pipeline=threads)
            if interrupted:
                break
    finally:
        if bar is not None:
            bar.close()
    wall = _time.perf_counter() - start
    return BatchResult(errors[names[0]], wall, seconds.get("spice", 0.0), dict(sorted(failures.items())),
                       times if keep_rates else None, rates if keep_rates else None, errors, seconds,
                       interrupted)
