"""A sweep's throughput into its store beside the in-memory batched path, with peak memory, in one run."""

from __future__ import annotations

import resource
import time as _time
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..batch.run import run_batch
from ..batch.runner import run_sweep
from ..batch.sweep import Sweep

__all__ = ["store_throughput"]


def _peak_mb(who: int) -> float:
    return resource.getrusage(who).ru_maxrss / 1024.0       # kB on Linux


def store_throughput(sweep: Sweep, directory, sample: int = 20_000, workers: int = 2,
                     progress: bool | None = None) -> str:
    """Scenes per second of the whole sweep into its store, against :func:`run_batch` in memory.

    The in-memory path builds the first *sample* scenes as a list and runs them with
    :func:`run_batch` (the same circuits, workers and solvers; :func:`run_batch` builds up to
    ten of a family's circuits a group, where the sweep stores each as its own); then the sweep runs into
    *directory* (resuming whatever is stored there). Peak resident memory is read
    from ``getrusage``: this process, and the largest worker.

    Parameters
    ----------
    sweep : Sweep
        The sweep.
    directory : str or Path
        Its results store.
    sample : int
        Scenes on the in-memory path.
    workers : int
        Worker processes of both paths.
    progress : bool, optional
        Progress of the store run.
    """
    if sample < 1:
        raise InputError("the in-memory sample needs at least one scene")
    sample = min(sample, sweep.size)
    solvers = tuple(dict.fromkeys(sweep.base.solvers))
    start = _time.perf_counter()
    scenes = sweep.scenes(0, sample)
    memory = run_batch(scenes, sweep.base.preset, solvers=solvers, group_size=sweep.group_size,
                       workers=workers, compare_exact=sweep.base.errors)
    in_memory = sample / (_time.perf_counter() - start)
    del scenes
    run = run_sweep(sweep, directory, workers=workers, progress=progress)
    ok = memory.errors[np.isfinite(memory.errors)]
    lines = [
        f"sweep {sweep.base.name}: {sweep.size:,} scenes ({sweep.method}, {len(sweep.axes)} axes, "
        f"{sweep.group_size} per group), solvers {', '.join(solvers)}, preset {sweep.base.preset}, "
        f"{workers} workers",
        f"  in memory (run_batch on the first {sample:,} scenes, building them included): "
        f"{in_memory:,.0f} scenes/s, worst error/peak {ok.max() if ok.size else float('nan'):.2e}",
        f"  into the store {Path(directory)}: {run.summary()}",
        f"  throughput ratio store / in memory: {run.throughput / in_memory:.2f}",
        f"  peak resident memory: this process {_peak_mb(resource.RUSAGE_SELF):,.0f} MB, "
        f"largest worker {_peak_mb(resource.RUSAGE_CHILDREN):,.0f} MB",
    ]
    return "\n".join(lines)
