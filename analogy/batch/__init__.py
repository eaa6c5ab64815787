"""Many scenes at once: grouped runs through the orchestrator, over worker processes or any executor."""

from .run import BatchResult, run_batch

__all__ = ["BatchResult", "run_batch"]
