"""Worker processes owned by the process that starts them: none outlives it, however it ends."""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import shutil
import signal
import sys
import tempfile
import threading
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .heap import retain_freed_memory

__all__ = ["worker_pool", "die_with_parent", "scratch_folder", "stop_requests", "halt_requests"]


class _StopRequests:
    """A request to stop, noted where a loop or a wait can look at it.

    SIGTERM's handler can be swallowed (it may run inside a garbage-collector callback or a
    finalizer, whose exceptions Python only prints), so it also notes the request in
    :data:`stop_requests`; a batch stopping its group threads notes one in :data:`halt_requests`.
    """

    def __init__(self) -> None:
        self._asked = threading.Event()

    def ask(self) -> None:
        """Note that the process was told to stop."""
        self._asked.set()

    def asked(self) -> bool:
        """Whether a stop was asked since the last :meth:`clear`."""
        return self._asked.is_set()

    def clear(self) -> None:
        """Forget earlier requests (a command starting afresh)."""
        self._asked.clear()


#: The process's one record of SIGTERM (set by the command's handler and the batch loop's).
stop_requests = _StopRequests()

#: Set while a batch in this process stops its group threads: a circuit running in ngspice is
#: halted and a new one is not started (each raises KeyboardInterrupt in its thread).
halt_requests = _StopRequests()


def die_with_parent(parent: int) -> None:
    """Worker initialiser: end when *parent* does (Linux parent-death signal) or on SIGTERM, leave Ctrl-C to
    it, and keep freed memory for reuse (:func:`~analogy.heap.retain_freed_memory`).

    Parameters
    ----------
    parent : int
        The pid of the process that started this worker, its direct parent.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # a forked worker inherits the command's SIGTERM handler: told to end, it ends (its groups are retried)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))     # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:          # the parent died before prctl
        os._exit(1)
    retain_freed_memory()               # a worker of ours: its allocator is ours to set


def worker_pool(workers: int, *, fresh: bool = False) -> ProcessPoolExecutor:
    """A process pool whose workers are this process's own children, and die with it.

    Fork when this process runs no other thread and *fresh* is not asked: workers start
    at once with the modules and models already loaded, and a script without an
    ``if __name__ == "__main__"`` guard still works. Otherwise spawn: forking a process
    with threads can deadlock, and a fresh interpreter has no ngspice loaded. Never a
    fork server: its workers are its children, not ours, so a parent killed with SIGKILL
    would leave the server and its workers running with no one to end them.

    Parameters
    ----------
    workers : int
        Worker processes.
    fresh : bool
        Start each worker in a new interpreter (nothing inherited but the environment).
    """
    methods = multiprocessing.get_all_start_methods()
    single = threading.active_count() == 1
    ctx = multiprocessing.get_context("fork" if single and not fresh and "fork" in methods else "spawn")
    return ProcessPoolExecutor(workers, mp_context=ctx, initializer=die_with_parent, initargs=(os.getpid(),))


def _remove_orphan_scratch(kind: str) -> None:
    """Remove the scratch folders of *kind* left by processes that no longer run (SIGKILL skips every clean-up)."""
    if not sys.platform.startswith("linux"):
        return
    for folder in Path(tempfile.gettempdir()).glob(f"analogy-{kind}-*-*"):
        pid = folder.name.split("-")[2]
        if pid.isdigit() and not Path(f"/proc/{pid}").exists():
            shutil.rmtree(folder, ignore_errors=True)


@contextmanager
def scratch_folder(kind: str) -> Iterator[Path]:
    """A temporary folder ``analogy-<kind>-<pid>-…`` for as long as the block runs.

    It is removed when the block ends, however it ends short of SIGKILL; what a killed
    process left is removed by the next one that asks for a folder of the same kind.

    Parameters
    ----------
    kind : str
        What it holds (``dask`` for a local cluster's worker spill space).
    """
    _remove_orphan_scratch(kind)
    with tempfile.TemporaryDirectory(prefix=f"analogy-{kind}-{os.getpid()}-") as folder:
        yield Path(folder)
