"""Running a sweep into its results store: worker processes or Dask, retries, progress, clean stops."""

from __future__ import annotations

import sys
import time as _time
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import InputError
from ..presets import Preset
from ..solvers.registry import SOLVER_NAMES
from ..progress import Progress
from .executor import ATTEMPTS, execute
from .plan import Group, plan_groups, solve_group as solve_members
from .store import ResultStore, status_counts
from .sweep import Sweep

if TYPE_CHECKING:
    import pandas
    import pyarrow

__all__ = ["SweepRun", "row_schema", "run_sweep", "solve_points", "with_overrides"]



@dataclass
class SweepRun:
    """What one ``run_sweep`` call did: scenes solved now and before, by status, and how fast.

    Attributes
    ----------
    directory : str
        The results store.
    total : int
        Scenes in the sweep.
    skipped : int
        Scenes already stored (a resumed run).
    solved : int
        Scenes solved and stored by this run.
    statuses : dict of str to int
        Rows written by this run, by status.
    stored : dict of str to int
        Every row in the store after this run (earlier runs' too), by status: what the exit code judges.
    wall_time : float
        Seconds of this run.
    interrupted : bool
        Stopped by SIGINT or SIGTERM before the end.
    replaced : str or None
        The sweep whose store this run took over, because it held no computed scene.
    """

    directory: str
    total: int
    skipped: int
    solved: int = 0
    statuses: dict = field(default_factory=dict)
    stored: dict = field(default_factory=dict)
    wall_time: float = 0.0
    interrupted: bool = False
    replaced: str | None = None

    @property
    def throughput(self) -> float:
        """Scenes solved per second of wall time."""
        return self.solved / self.wall_time if self.wall_time > 0 else float("nan")

    def summary(self) -> str:
        """One line: what was solved, how fast, and the statuses."""
        counts = ", ".join(f"{v} {k}" for k, v in sorted(self.statuses.items())) or "none new"
        took = (f" (the folder held no computed scene of sweep {self.replaced}, only invalid ones or none, and this one replaced it)"
                if self.replaced else "")
        rate = f"{self.throughput:,.0f} scenes/s; {self.skipped} already stored"
        if self.interrupted:        # counted as the progress lines count: every stored scene
            return (f"interrupted with {self.skipped + self.solved:,} of {self.total:,} scenes stored, "
                    f"{self.solved:,} by this run in {self.wall_time:.1f} s ({rate}): {counts}{took}")
        return f"solved {self.solved} of {self.total} scenes in {self.wall_time:.1f} s ({rate}): {counts}{took}"

    def __repr__(self) -> str:
        return f"<SweepRun {self.summary()}>"

    def to_frame(self) -> "pandas.DataFrame":
        """The whole store as a DataFrame (:func:`analogy.batch.store.read`)."""
        from .store import read
        return read(self.directory)


def row_schema(sweep: Sweep, solvers: Sequence[str]) -> "pyarrow.Schema":
    """The Parquet schema of a sweep's rows.

    Parameters
    ----------
    sweep : Sweep
        The sweep.
    solvers : sequence of str
        The solvers with error and seconds columns.
    """
    import pyarrow as pa
    cols = [("key", pa.string()), ("scene", pa.int64())]
    cols += [(a.name, pa.float64() if a.numeric else pa.string()) for a in sweep.axes]
    cols += [("status", pa.string()), ("message", pa.string())]
    for name in solvers:
        cols += [(f"error_{name}", pa.float64()), (f"seconds_{name}", pa.float64())]
    return pa.schema(cols)


def _solvers(sweep: Sweep) -> list[str]:
    return list(dict.fromkeys(sweep.base.solvers))


def solve_points(sweep: Sweep, start: int, points: np.ndarray, todo: np.ndarray,
                isolated: bool = False, trajectories: int = 0) -> tuple[dict, object]:
    """Solve the scenes of one group that are still to do; return their columns and trajectories.

    Scenes that share a family are built as one stack and run as one ngspice circuit
    (each alone with *isolated*). A scene that cannot be built is ``invalid``; one
    whose solver failed is ``failed``; one whose error is above its preset's bound is
    ``inaccurate``.

    Parameters
    ----------
    sweep : Sweep
        The sweep.
    start : int
        Index of the group's first scene.
    points : ndarray
        The group's design points.
    todo : ndarray of bool
        Which of the group's scenes to solve.
    isolated : bool
        One ngspice run per scene.
    trajectories : int
        Keep this many evenly spaced points of each solver's joint rates (0: none).
    """
    solvers = _solvers(sweep)
    rows = np.flatnonzero(todo)
    values = {k: v[rows] for k, v in sweep.values(points).items()}
    count = len(rows)
    cols: dict = {"key": [""] * count, "scene": (start + rows).astype(np.int64)}
    cols.update(values)
    status, message = ["ok"] * count, [None] * count      # null where nothing is to be said
    errors = {name: np.full(count, np.nan) for name in solvers}
    seconds = {name: np.zeros(count) for name in solvers}
    try:
        scenes: list = sweep.scenes_at(values) if count else []
    except InputError:              # a bad value: find which, scene by scene
        scenes = [None] * count
        for j in range(count):
            try:
                scenes[j] = sweep.scenes_at({k: v[j:j + 1] for k, v in values.items()})[0]
            except InputError as exc:
                status[j], message[j] = "invalid", str(exc)
    cols["key"] = [s.key if s is not None else "" for s in scenes]
    kept: dict = {}
    reference = "auto" if sweep.base.errors else None
    by_preset: dict = {}
    for j, sc in enumerate(scenes):
        if sc is not None:
            by_preset.setdefault(sc.preset, []).append(j)
    for members in by_preset.values():
        group = [scenes[j] for j in members]
        settings = group[0].settings
        tasks = [Group((k,), (s,)) for k, s in enumerate(group)] if isolated else plan_groups(group, len(group))
        for task in tasks:
            idx = task.rows
            errs, secs, failed, invalid, refused, rates = solve_members(task, settings, solvers, reference,
                                                                        trajectories > 0)
            bound = settings.bound
            for local, k in enumerate(idx):
                j = members[k]
                for name in solvers:
                    errors[name][j], seconds[name][j] = errs[name][local], secs[name][local]
                if local in failed:
                    status[j] = "invalid" if local in invalid else "refused" if local in refused else "failed"
                    message[j] = failed[local]
                elif outside := [f"{n} {errs[n][local]:.3g}" for n in solvers
                                 if errs[n][local] > bound]:
                    status[j] = "inaccurate"
                    message[j] = f"{', '.join(outside)} above the {preset_name} bound {bound:g}"
                if rates is not None and rates[local]:
                    kept[j] = rates[local]
    cols["status"], cols["message"] = status, message
    for name in solvers:
        cols[f"error_{name}"], cols[f"seconds_{name}"] = errors[name], seconds[name]
    return cols, (_downsampled(kept, cols["key"], sweep, trajectories) if trajectories else None)


def _downsampled(kept: dict, keys: list, sweep: Sweep, points: int):
    """Long table of trajectories: key, solver, t, then each joint's rate r1 … (the name the CSV
    and ``to_frame`` give it too)."""
    import pyarrow as pa
    t = np.linspace(0.0, sweep.base.t_stop, points)
    n = len(sweep.base.q)
    out: dict = {"key": [], "solver": [], "t": []}
    out.update({f"r{i + 1}": [] for i in range(n)})
    for j, per_solver in sorted(kept.items()):
        for name, (time, rates) in per_solver.items():
            out["key"] += [keys[j]] * points
            out["solver"] += [name] * points
            out["t"].append(t)
            for i in range(n):
                out[f"r{i + 1}"].append(np.interp(t, time, rates[:, i]))
    for k in ["t"] + [f"r{i + 1}" for i in range(n)]:
        out[k] = np.concatenate(out[k]) if out[k] else np.empty(0)
    return pa.table(out)


def _remote(payload):
    """Worker entry: one group (a module-level function, so that it pickles by name).

    An unexpected exception fails only its own scene: the group is solved again scene
    by scene, and a scene that still raises is stored as ``failed`` with the exception.
    """
    sweep, start, points, todo, isolated, trajectories = payload
    try:
        return solve_points(sweep, start, points, todo, isolated, trajectories)
    except Exception:       # noqa: BLE001 - any bug in one scene must not lose the group
        pass
    parts, trajs = [], []
    for j in np.flatnonzero(todo):
        one = np.zeros_like(todo)
        one[j] = True
        try:
            cols, traj = solve_points(sweep, start, points, one, True, trajectories)
        except InputError as exc:       # the scene itself could not be built
            cols, traj = _died(sweep, start, points, one, _solvers(sweep)), None
            cols["status"] = ["invalid"]
            cols["message"] = [str(exc)]
        except Exception as exc:        # noqa: BLE001
            cols, traj = _died(sweep, start, points, one, _solvers(sweep)), None
            cols["status"] = ["failed"]
            cols["message"] = [f"internal error: {type(exc).__name__}: {exc}"]
        parts.append(cols)
        if traj is not None:
            trajs.append(traj)
    merged = {k: np.concatenate([np.asarray(p[k], dtype=object if isinstance(p[k], list) else None)
                                 for p in parts]).tolist() if isinstance(parts[0][k], list)
              else np.concatenate([p[k] for p in parts]) for k in parts[0]}
    if trajs:
        import pyarrow as pa
        return merged, pa.concat_tables(trajs)
    return merged, None


def run_sweep(sweep: Sweep, directory, *, workers: int = 2, executor: Executor | None = None,
              isolated: bool = False, trajectories: int = 0, progress: bool | None = None,
              log=None) -> SweepRun:
    """Solve every scene of *sweep* not yet in the results store *directory*, and store it.

    Groups of :attr:`Sweep.group_size` scenes run on *workers* local processes (or on
    *executor*, e.g. a Dask client's ``get_executor()``); each finished group is stored
    at once. A worker that dies has its groups retried once, then they are stored as
    ``worker-died``. SIGINT and SIGTERM stop the run cleanly: finished groups are kept,
    workers ended, and the same call resumes.

    Parameters
    ----------
    sweep : Sweep
        The sweep.
    directory : str or Path
        The results store (:class:`analogy.batch.store.ResultStore`).
    workers : int
        Local worker processes.
    executor : Executor, optional
        Runs the groups instead of local processes.
    isolated : bool
        One ngspice run per scene: each scene's result exactly as alone, but slower.
    trajectories : int
        Also store this many evenly spaced points of every solver's joint rates.
    progress : bool, optional
        A progress bar (default: when stderr is a terminal; plain lines otherwise).
    log : file, optional
        Where progress goes (default stderr).
    """
    if workers < 1:
        raise InputError("workers must be at least 1")
    if trajectories < 0 or trajectories > 100_000:
        raise InputError(f"trajectories must be between 0 and 100000 points, got {trajectories}")
    solvers = _solvers(sweep)
    if not solvers:
        raise InputError("the sweep's scene names no solver: set [solvers] use")
    if bad := [s for s in solvers if s not in SOLVER_NAMES]:
        raise InputError(f"unknown solver {bad[0]!r}")
    start_time = _time.perf_counter()
    store = ResultStore(directory, {**sweep.describe(), "isolated": isolated}, row_schema(sweep, solvers))
    done = np.zeros(sweep.size, dtype=bool)
    stored = store.stored_indices()
    done[stored[(stored >= 0) & (stored < sweep.size)]] = True
    result = SweepRun(str(directory), sweep.size, int(done.sum()), replaced=store.replaced)
    bar = Progress(sweep.size, initial=result.skipped, bar=progress, stream=log or sys.stderr)
    chunks = ((a, b, pts) for a, b, pts in sweep.chunks() if not done[a:b].all())

    def stored(cols, traj=None) -> None:
        store.add(cols, traj)
        for st in cols["status"]:
            result.statuses[st] = result.statuses.get(st, 0) + 1
        result.solved += len(cols["status"])
        bar.update(len(cols["status"]))

    def finished(chunk, out) -> None:
        a, b, _ = chunk
        stored(*out)
        done[a:b] = True

    def died(chunk) -> None:
        a, b, pts = chunk
        stored(_died(sweep, a, pts, ~done[a:b], solvers))
        done[a:b] = True

    def kept() -> str:
        return (f": {int(done.sum()):,} of {sweep.size:,} scenes are stored in {directory}; "
                "run the same command to resume")
    try:
        result.interrupted = execute(chunks, lambda c: (sweep, c[0], c[2], ~done[c[0]:c[1]], isolated, trajectories),
                                     _remote, finished, died, workers=workers, executor=executor, stored=kept)
    finally:
        try:
            store.compact()
            result.stored = status_counts(directory)
        finally:
            store.close()
            bar.close()
    result.wall_time = _time.perf_counter() - start_time
    return result


def _died(sweep: Sweep, start: int, points: np.ndarray, todo: np.ndarray, solvers) -> dict:
    """Rows for a group whose worker process died on every attempt."""
    rows = np.flatnonzero(todo)
    values = {k: v[rows] for k, v in sweep.values(points).items()}
    count = len(rows)
    keys = []
    for j in range(count):
        try:
            keys.append(sweep.scenes_at({k: v[j:j + 1] for k, v in values.items()})[0].key)
        except InputError:
            keys.append("")
    cols = {"key": keys, "scene": (start + rows).astype(np.int64), **values,
            "status": ["worker-died"] * count,
            "message": [f"the worker process died while solving this group ({ATTEMPTS} attempts)"] * count}
    for name in solvers:
        cols[f"error_{name}"], cols[f"seconds_{name}"] = np.full(count, np.nan), np.full(count, np.nan)
    return cols


def with_overrides(sweep: Sweep, preset: str | Preset | None = None, solvers: Sequence[str] | None = None) -> Sweep:
    """*sweep* with its base scene's preset or solvers replaced (a new sweep, with its own key).

    Parameters
    ----------
    sweep : Sweep
        The sweep.
    preset : str or Preset, optional
        Accuracy preset.
    solvers : sequence of str, optional
        Solvers.
    """
    changes: dict = {}
    if preset is not None:
        changes["preset"] = preset         # the scene keeps its name
    if solvers is not None:
        changes["solvers"] = tuple(solvers)
    return replace(sweep, base=sweep.base.replace(**changes)) if changes else sweep
