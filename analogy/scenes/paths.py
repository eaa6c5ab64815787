"""Output paths of scene files: relative names that resolve inside the output folder, through no symlink."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from ..errors import InputError

__all__ = ["check_relative_name", "inside_folder"]


def check_relative_name(value: str) -> str:
    """*value* if it is a usable relative file name (no NUL byte, no absolute path, no ``..``).

    Parameters
    ----------
    value : str
        A file name from a scene file.

    Raises
    ------
    InputError
        One sentence naming the problem.
    """
    if "\x00" in value:
        raise InputError(f"{value!r} contains a NUL byte, which no file name may hold")
    p = Path(value)
    if p.is_absolute() or ".." in p.parts:
        raise InputError(f"{value!r} must be a relative path inside the output folder "
                         "(no absolute path, no '..')")
    if not p.parts or p.name in ("", "."):
        raise InputError(f"{value!r} names no file")
    return value


def inside_folder(folder, name: str) -> Path:
    """Where *name* goes in *folder*: its real path inside the folder's, reached through no symlink.

    The folder itself may be reached through symlinks (it is the user's choice); below
    it, no existing part of the path may be a symlink, and an existing file must be a
    regular one, so that a scene file cannot write or overwrite anything elsewhere.

    Parameters
    ----------
    folder : str or Path
        The output folder.
    name : str
        A relative file name (checked with :func:`check_relative_name`).

    Raises
    ------
    InputError
        One sentence naming the file and why it is refused.
    """
    check_relative_name(name)
    root = Path(os.path.realpath(folder))
    current = root
    parts = Path(name).parts
    for k, part in enumerate(parts):
        current = current / part
        try:
            mode = os.lstat(current).st_mode
        except FileNotFoundError:
            break                        # the rest is made fresh inside the folder
        except OSError as exc:
            raise InputError(f"cannot write {name!r}: {exc.strerror or exc}") from None
        if stat.S_ISLNK(mode):
            raise InputError(f"cannot write {name!r}: {current} is a symbolic link, and outputs "
                             "are written only inside the output folder")
        last = k == len(parts) - 1
        if last and not stat.S_ISREG(mode):
            raise InputError(f"cannot write {name!r}: {current} exists and is not a regular file")
        if not last and not stat.S_ISDIR(mode):
            raise InputError(f"cannot write {name!r}: {current} is not a folder")
    target = root.joinpath(*parts)
    resolved = Path(os.path.realpath(target))
    if resolved != target or root not in resolved.parents:
        raise InputError(f"cannot write {name!r}: it resolves to {resolved}, outside the output "
                         f"folder {root}")
    return target
