"""Fresh copies of a shared library, each loaded with its own global state, leaving nothing on disk."""

from __future__ import annotations

import itertools
import os
import shutil
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..errors import SpiceError

__all__ = ["library_copy", "remove_orphan_copies"]

#: The in-memory library copies' descriptors, kept open for the life of the process: dlopen
#: matches a loaded library by its path first, and a closed descriptor's number (so its path
#: ``/proc/self/fd/N``) would be reused by the next copy.
_COPIES: list[int] = []
#: Numbers the process's copies, in their names.
_NUMBERS = itertools.count(1)


@contextmanager
def library_copy(src: Path, in_memory: bool = True) -> Iterator[str]:
    """A path to a fresh copy of the library file *src*, to be loaded inside the block.

    On Linux the copy is an anonymous file in memory (``memfd_create``), so a process killed
    while it copies, even by SIGKILL, leaves nothing on disk; it stays in memory (shared, not
    evictable page cache) for as long as the process runs, about 8 MB a copy. Where that is not
    available or refused, it is a temporary folder, removed when the block ends (the mapping
    stays); what a killed process left there is removed by the next process that makes a copy.

    Parameters
    ----------
    src : Path
        The library file.
    in_memory : bool
        Try the copy in memory first (where that is available).
    """
    name = f"libngspice-{next(_NUMBERS)}"
    memfd = getattr(os, "memfd_create", None)
    fd = None
    if in_memory and memfd is not None and os.path.isdir("/proc/self/fd"):
        try:
            fd = memfd(name)
            with open(src, "rb") as source, os.fdopen(fd, "wb", closefd=False) as copy:
                shutil.copyfileobj(source, copy, 1 << 20)
        except OSError:             # refused (a sandbox, memfd_noexec): a copy on disk instead
            if fd is not None:
                os.close(fd)
            fd = None
    if fd is not None:
        _COPIES.append(fd)
        yield f"/proc/self/fd/{fd}"
        return
    remove_orphan_copies()
    with tempfile.TemporaryDirectory(prefix=f"analogy-ngspice-{os.getpid()}-") as folder:
        dst = Path(folder) / f"{name}.so"
        try:
            shutil.copy(src, dst)
        except OSError as exc:
            raise SpiceError(f"cannot copy the ngspice shared library {src} to load it afresh: {exc}") from None
        yield str(dst)


def _alive(pid: int) -> bool:
    if sys.platform == "win32":     # os.kill would end it: every folder is kept
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:         # someone else's
        return True
    return True


def remove_orphan_copies() -> None:
    """Remove library copies left on disk by processes that were killed (SIGKILL skips every clean-up)."""
    for folder in Path(tempfile.gettempdir()).glob("analogy-ngspice-*-*"):
        pid = folder.name.split("-")[2]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)
