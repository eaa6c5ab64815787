"""What the commands leave: output paths checked before any work, and the exit code of an accuracy verdict."""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

from ..errors import EXIT_ACCURACY, EXIT_OK, InputError
from ..files import check_target

__all__ = ["check_writable", "check_folder", "write_outputs", "accuracy_exit"]


def check_writable(path) -> None:
    """Nothing if a file can be written at *path*; one sentence if not (see :func:`~analogy.files.check_target`).

    Parameters
    ----------
    path : str or Path or None
        Where a file will go (None: nothing to check).
    """
    if path is None:
        return
    check_target(path)
    # the folder as the system will resolve it ("missing/.." is no folder), not normalised by name
    folder = Path(path).parent
    try:
        if not folder.is_dir():
            raise InputError(f"cannot write {path}: folder {folder} does not exist")
        if not os.access(folder, os.W_OK) or (
                Path(path).is_file() and not Path(path).is_symlink() and not os.access(path, os.W_OK)):
            raise InputError(f"cannot write {path}: permission denied")
    except OSError as exc:          # a folder name too long, a loop of symlinks
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None


def check_folder(path, what: str = "the output") -> None:
    """Nothing if *path* is a folder, or none exists there yet; one sentence if files cannot go there.

    Parameters
    ----------
    path : str or Path
        The output folder.
    what : str
        What goes in it, for the sentence.
    """
    try:
        if Path(path).exists() and not Path(path).is_dir():
            raise InputError(f"cannot write {what} into {path}: it is a file")
    except OSError as exc:
        raise InputError(f"cannot write {what} into {path}: {exc.strerror or exc}") from None


def write_outputs(writes) -> None:
    """Write each output in turn, saying each one written; a failed one does not stop the others.

    Nothing computed is lost to one bad path or a full disk: the failures are said together
    in one sentence at the end (:class:`InputError`, exit 2).

    Parameters
    ----------
    writes : iterable of (str or Path or None, callable)
        Each output's path and what writes it; a None path is skipped.
    """
    failed = []
    for path, write in writes:
        if path is None:
            continue
        try:
            write()
        except OSError as exc:
            failed.append(f"{path} ({exc.strerror or exc})")
            continue
        print(f"wrote {path}")
    if failed:
        raise InputError("cannot write " + "; nor ".join(failed))


def accuracy_exit(flags: dict, preset: str, bound: float, result=None) -> int:
    """Exit 3 and one line per solver whose worst output is past *bound*, or on a closed chain's
    motion near a singular pose (:attr:`Comparison.singular`); else 0.

    Parameters
    ----------
    flags : dict
        Solver to its worst error over its own peak, for those past the bound.
    preset : str
        The preset that promised the bound.
    bound : float
        The bound.
    result : Comparison, optional
        Names each solver's worst output.
    """
    for solver, err in flags.items():
        if err == math.inf and solver in getattr(result, "unestimated", {}):
            print(f"analogy: accuracy: {solver}'s error cannot be estimated without a reference: "
                  f"{result.unestimated[solver]}", file=sys.stderr)
            continue
        worst = getattr(result, "worst_output", None)
        which = ""
        if worst is not None and solver in result.results:
            provenance = getattr(getattr(result, "system", None), "provenance", None)
            name = worst(solver)[0]
            which = f" on {provenance.output_name(name) if provenance is not None else name}"
        print(f"analogy: accuracy: {solver} error{which} {err:.3g} of its own peak is above the {preset} "
              f"preset's bound {bound:g}", file=sys.stderr)
    singular = getattr(result, "singular", "")
    if singular:
        print(f"analogy: accuracy: {singular}", file=sys.stderr)
    return EXIT_ACCURACY if flags or singular else EXIT_OK
