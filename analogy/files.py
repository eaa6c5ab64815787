"""Files written whole or not at all: each through a temporary file beside it, renamed into place."""

from __future__ import annotations

import os
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

from .errors import InputError

__all__ = ["replaced", "write_text", "write_figure", "written", "check_target"]

# the mode a plain open() gives a new file; mkstemp's own is 0600
_UMASK = os.umask(0)
os.umask(_UMASK)


def check_target(path) -> bool:
    """Whether *path* is a device written in place (``/dev/null``, a terminal); one sentence if it
    cannot take a file at all (a folder, a FIFO or socket that would block, a name too long).

    Parameters
    ----------
    path : str or Path
        Where a file will go.
    """
    path = Path(path)
    if "\x00" in str(path):
        raise InputError(f"cannot write {str(path)!r}: it contains a NUL byte, which no file name may hold")
    try:
        info = path.stat()          # through a symlink: what a write would reach
    except FileNotFoundError:
        return False
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(info.st_mode):
        raise InputError(f"cannot write {path}: it is a folder")
    if stat.S_ISFIFO(info.st_mode) or stat.S_ISSOCK(info.st_mode):
        raise InputError(f"cannot write {path}: it is a pipe or socket, which would wait for a reader; "
                         "write to a file (or, for a netlist, to standard output without -o)")
    return stat.S_ISCHR(info.st_mode)


@contextmanager
def replaced(path) -> Iterator[Path]:
    """A temporary path beside *path* to write; renamed over *path* when the block ends without error.

    A reader never sees half a file, a signal mid-write leaves the old file (or none), and a
    symlink at *path* is replaced, never followed: nothing is written outside *path*'s folder.
    A character device (``/dev/null``) is written in place.

    Parameters
    ----------
    path : str or Path
        The file to write; its folder must exist.
    """
    path = Path(path)
    if check_target(path):
        yield path
        return
    # the suffix kept, so that writers that pick a format by it (savefig, animations) still do
    fd, name = tempfile.mkstemp(prefix=f".{path.stem[:80]}.", suffix=path.suffix[:20], dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_text(path, text: str) -> Path:
    """Write *text* to *path* (UTF-8) through :func:`replaced`.

    Parameters
    ----------
    path : str or Path
        The file.
    text : str
        Its content.
    """
    with replaced(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_figure(fig, path, **options) -> Path:
    """Save a matplotlib figure (or anything with ``savefig``) to *path* through :func:`replaced`.

    Parameters
    ----------
    fig : Figure
        The figure.
    path : str or Path
        The image file; its suffix names the format.
    **options
        ``savefig``'s options (dpi, bbox_inches …).
    """
    with replaced(path) as tmp:
        fig.savefig(tmp, format=Path(path).suffix.lstrip(".").lower() or None, **options)
    return Path(path)


def written(path, write: Callable[[Path], object]) -> Path:
    """Call *write* with a temporary path beside *path*, then rename it into place (:func:`replaced`).

    Parameters
    ----------
    path : str or Path
        The file.
    write : callable
        Writes the file at the path it is given.
    """
    with replaced(path) as tmp:
        write(tmp)
    return Path(path)
