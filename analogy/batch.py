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

    All systems must share t_stop, so that one ``.tran`` serves them all. Element values
    come from one :func:`~analogy.elements.element_table` per size of system (with or
    without springs), and the sources of systems that share forces and topology are
    derived once.
    """
    from .elements import element_table, spice_value
    from .netlist import analysis_lines, circuit_lines, source_lines, source_terms
    if not systems:
        raise InputError("a batch needs at least one system")
    t_stop = systems[0].t_stop
    if any(s.t_stop != t_stop for s in systems):
        raise InputError("systems in one ngspice run must share t_stop")
    parts: list = [None] * len(systems)
    kinds: dict = {}
    for k, s in enumerate(systems):
        kinds.setdefault((s.dof, s.stiffness is None), []).append(k)
    for (_, no_springs), idx in kinds.items():
        def stack(attr):
            return np.stack([getattr(systems[k], attr) for k in idx])
        table = element_table(stack("mass"), stack("damping"), None if no_springs else stack("stiffness"))
        # per element: its SPICE value and whether it is present, in every system of the stack
        columns = [(kind, a, b, spice_value(kind, c).tolist(), (c != 0).tolist()) for kind, a, b, c in table]
        for j, k in enumerate(idx):
            parts[k] = [(kind, a, b, values[j]) for kind, a, b, values, present in columns if present[j]]
    lines, ic, save, sources = [f"* analogy batch of {len(systems)} independent circuits"], {}, [], {}
    for k, s in enumerate(systems):
        prefix = f"x{k}_"
        key = (id(s.forces), id(s.current_map))
        terms = sources.get(key)
        if terms is None:
            terms = sources[key] = source_terms(s)
        lines += circuit_lines(parts[k], prefix)[0]
        lines += source_lines(s, prefix=prefix, terms=terms)
        nodes = [f"{prefix}{n}" for n in s.nodes]
        ic.update(zip(nodes, s.initial_voltages.tolist()))
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
        Scenes that could not be built or simulated, with the reason.
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


def _model(sc):
    """A scene's evaluable model, derived (or loaded compiled) once per process."""
    key = sc.model if isinstance(sc.model, str) else id(sc.model)
    model = _MODELS.get(key)
    if model is None:
        model = _MODELS[key] = sc.numeric_model()
    return model


def _system(item):
    """A NodeSystem from a NodeSystem or a Scene."""
    from .scenes import Scene
    return item.system(_model(item)) if isinstance(item, Scene) else item


def _systems(task) -> tuple[list, dict]:
    """Build a task's systems; return them (None where a build failed) and the failures.

    A task is ("family", scene, configurations), scenes that differ only in q and are
    built as one stack, or ("items", [Scene or NodeSystem, ...]).
    """
    kind, *rest = task
    if kind == "family":
        base, qs = rest
        try:
            return base.systems(qs, _model(base)), {}
        except AnalogyError:            # one row is bad: build row by row to keep the others
            items = [base.replace(q=tuple(row)) for row in np.asarray(qs).tolist()]
    else:
        items = rest[0]
    systems, failures = [], {}
    for k, item in enumerate(items):
        try:
            systems.append(_system(item))
        except AnalogyError as exc:
            systems.append(None)
            failures[k] = str(exc)
    return systems, failures


def _relative_errors(systems, volts, exact) -> np.ndarray:
    """max |R − R_exact| / max |R_exact| per system, stacked over systems sharing a topology."""
    errors = np.empty(len(systems))
    by_map: dict = {}
    for k, s in enumerate(systems):
        by_map.setdefault(id(s.topology), []).append(k)
    for idx in by_map.values():
        top = systems[idx[0]].topology
        r = top.joint_rates(np.stack([volts[k] for k in idx]))
        ex = top.joint_rates(np.stack([exact[k] for k in idx]))
        errors[idx] = np.abs(r - ex).max(axis=(1, 2)) / np.abs(ex).max(axis=(1, 2))
    return errors


def _exact_errors(systems, volts, t, failures: dict, idx) -> np.ndarray:
    """Errors against the exact solution, solved for the group at once or, if that
    fails, system by system so that only a system the exact solver cannot take fails."""
    from .exact import solve_exact_many
    try:
        return _relative_errors(systems, volts, solve_exact_many(systems, t))
    except AnalogyError:
        pass
    errors = np.full(len(systems), np.nan)
    for j, (s, v) in enumerate(zip(systems, volts)):
        try:
            errors[j] = _relative_errors([s], [v], solve_exact_many([s], t))[0]
        except AnalogyError as exc:
            failures[idx[j]] = f"exact solution: {exc}"
    return errors


def _group(payload):
    """Worker: one ngspice run for a group, then each scene against its exact solution.

    If the shared run fails, each scene is run alone, so that one scene's failure is
    reported as its own and does not take the others with it.
    """
    task, preset, compare_exact, keep = payload
    built, failures = _systems(task)
    ok = [k for k, s in enumerate(built) if s is not None]
    systems = [built[k] for k in ok]
    errors = np.full(len(built), np.nan)
    rates: list = [None] * len(built)
    spice_seconds = 0.0
    runs = [(ok, systems)]
    while runs:
        idx, group = runs.pop()
        if not group:
            continue
        try:
            t, volts, sec = solve_spice_group(group, preset)
        except AnalogyError as exc:
            if len(group) == 1:
                failures[idx[0]] = str(exc)
            else:
                runs += [([k], [s]) for k, s in zip(idx, group)]
            continue
        spice_seconds += sec
        if compare_exact:
            errors[idx] = _exact_errors(group, volts, t, failures, idx)
        if keep:
            for k, s, v in zip(idx, group, volts):
                rates[k] = (t, s.joint_rates(v))
    return errors, spice_seconds, failures, (rates if keep else None)


def _tasks(systems, group_size: int) -> list[tuple[list[int], tuple]]:
    """Split *systems* into (indices, task) groups of at most *group_size* with one time grid.

    Scenes that differ only in their configuration form one family, built as a stack.
    """
    from .scenes import Scene
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
                qs = np.array([systems[k].q for k in chunk], dtype=float).reshape(len(chunk), -1)
                tasks.append((chunk, ("family", systems[chunk[0]], qs)))
            else:
                tasks.append((chunk, ("items", [systems[k] for k in chunk])))
    return tasks


def _worker_context():
    """How worker processes start.

    Fork when this process runs no other thread: workers start at once, with the
    modules and models already loaded, and the caller's script is not imported again
    (a lab without an ``if __name__ == "__main__"`` guard still works). Forking a
    process with threads can deadlock, so then a fork server starts them clean.
    """
    import multiprocessing
    import threading
    if threading.active_count() == 1 and "fork" in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("fork")
    ctx = multiprocessing.get_context("forkserver")
    # Imports done once in the server are shared by every worker forked from it.
    ctx.set_forkserver_preload(["analogy.batch", "analogy.spice", "analogy.exact",
                                "analogy.netlist", "analogy.compiled", "analogy.scenes",
                                "PySpice.Spice.NgSpice.Shared"])
    return ctx


def run_batch(systems: Sequence, preset="fast", *, group_size: int = 100, workers: int = 2,
              executor: Executor | None = None, compare_exact: bool = True,
              keep_rates: bool = False, progress: bool = False) -> BatchResult:
    """Simulate many systems: groups of *group_size* share one ngspice run.

    *systems* holds NodeSystems or Scenes. Scenes are built in the workers; those that
    differ only in q are built as one stack (:func:`analogy.system.node_systems`), and a
    built-in model is derived and compiled once per worker process. Groups share one
    time grid (t_stop) and are spread over *workers* processes (or any
    ``concurrent.futures.Executor``, e.g. a Dask client's ``get_executor()``).
    """
    p = get_preset(preset)
    if group_size < 1 or workers < 1:
        raise InputError("group_size and workers must be at least 1")
    start = _time.perf_counter()
    tasks = _tasks(systems, group_size)
    payloads = [(task, p, compare_exact, keep_rates) for _, task in tasks]
    own = None
    if executor is None and workers > 1 and len(tasks) > 1:
        from concurrent.futures import ProcessPoolExecutor
        executor = own = ProcessPoolExecutor(workers, mp_context=_worker_context())
    try:
        outputs = executor.map(_group, payloads) if executor is not None else map(_group, payloads)
        if progress:
            from tqdm import tqdm
            outputs = tqdm(outputs, total=len(payloads), unit="group")
        errors = np.full(len(systems), np.nan)
        failures, times, rates = {}, [None] * len(systems), [None] * len(systems)
        spice_seconds = 0.0
        for (idx, _), (errs, sec, failed, kept) in zip(tasks, outputs):
            spice_seconds += sec
            errors[idx] = errs
            failures.update((idx[j], why) for j, why in failed.items())
            for j, k in enumerate(idx):
                if kept is not None and kept[j] is not None:
                    times[k], rates[k] = kept[j]
    finally:
        if own is not None:
            own.shutdown()
    wall = _time.perf_counter() - start
    return BatchResult(errors, wall, spice_seconds, dict(sorted(failures.items())),
                       times if keep_rates else None, rates if keep_rates else None)
