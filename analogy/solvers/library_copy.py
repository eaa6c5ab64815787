"""Fresh copies of a shared library, each loaded with its own global state, leaving nothing on disk."""

from __future__ import annotations

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


@contextmanager
def library_copy(src: Path, generation: int) -> Iterator[str]:
    """A path to a fresh copy of the library file *src*, to be loaded inside the block.

    On Linux the copy is an anonymous file in memory (``memfd_create``), so a process killed
    while it copies, even by SIGKILL, leaves nothing on disk. Elsewhere it is a temporary
    folder, removed when the block ends (the mapping stays); what a killed process left there
    is removed by the next process that makes a copy.

    Parameters
    ----------
    src : Path
        The library file.
    generation : int
        The copy's number, in its name.
    """
    memfd = getattr(os, "memfd_create", None)
    if memfd is not None and os.path.isdir("/proc/self/fd"):
        try:
            fd = memfd(f"libngspice-{generation}")
            with open(src, "rb") as source, os.fdopen(fd, "wb", closefd=False) as copy:
                shutil.copyfileobj(source, copy, 1 << 20)
        except OSError as exc:
            raise SpiceError(f"cannot copy the ngspice shared library {src} to load it afresh: {exc}") from None
        _COPIES.append(fd)
        yield f"/proc/self/fd/{fd}"
        return
    remove_orphan_copies()
    with tempfile.TemporaryDirectory(prefix=f"analogy-ngspice-{os.getpid()}-") as folder:
        dst = Path(folder) / f"libngspice-{generation}.so"
        try:
            shutil.copy(src, dst)
        except OSError as exc:
            raise SpiceError(f"cannot copy the ngspice shared library {src} to load it afresh: {exc}") from None
        yield str(dst)


def remove_orphan_copies() -> None:
    """Remove library copies left by processes that were killed (SIGKILL skips every clean-up)."""
    for folder in Path(tempfile.gettempdir()).glob("analogy-ngspice-*-*"):
        pid = folder.name.split("-")[2]
        if not pid.isdigit() or Path(f"/proc/{pid}").exists() or not sys.platform.startswith("linux"):
            continue
        shutil.rmtree(folder, ignore_errors=True)
