"""Many scenes at once: grouped runs, sweeps over a design, a resumable Parquet store, reports."""

from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .report import BatchReport, batch_report
    from .run import BatchResult, run_batch
    from .runner import SweepRun, run_sweep
    from .store import read, read_trajectories
    from .sweep import Axis, Sweep, load_sweep, sweep_from

__all__ = ["Axis", "BatchReport", "BatchResult", "Sweep", "SweepRun", "batch_report", "load_sweep", "read",
           "read_trajectories", "run_batch", "run_sweep", "sweep_from"]

# Loaded on first use, so that the command line's parser (analogy.cli.batch) starts without them.
_WHERE = {"BatchReport": "report", "batch_report": "report", "BatchResult": "run", "run_batch": "run",
          "SweepRun": "runner", "run_sweep": "runner", "read": "store", "read_trajectories": "store",
          "Axis": "sweep", "Sweep": "sweep", "load_sweep": "sweep", "sweep_from": "sweep"}


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
