"""Many scenes at once: grouped runs, sweeps over a design, a resumable Parquet store, reports."""

from .report import BatchReport, batch_report
from .run import BatchResult, run_batch
from .runner import SweepRun, run_sweep
from .store import read, read_trajectories
from .sweep import Axis, Sweep, load_sweep, sweep_from

__all__ = ["Axis", "BatchReport", "BatchResult", "Sweep", "SweepRun", "batch_report", "load_sweep", "read",
           "read_trajectories", "run_batch", "run_sweep", "sweep_from"]
