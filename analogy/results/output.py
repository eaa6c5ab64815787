"""Output files: result columns as CSV, small HTML tables, and plot paths checked before any work."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import InputError

__all__ = ["write_columns", "html_table", "check_plot_path", "PLOT_FORMATS"]

#: File formats matplotlib writes here.
PLOT_FORMATS = ("png", "svg", "pdf", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp")


def write_columns(path, columns: Mapping[str, np.ndarray]) -> Path:
    """Write equal-length *columns* as CSV with a header row, at full double precision.

    Parameters
    ----------
    path : str or Path
        The file to write (its folder must exist).
    columns : mapping of str to array
        Column name to values.
    """
    path = Path(path)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(columns))
        for row in zip(*columns.values()):
            w.writerow([repr(float(x)) for x in row])
    return path


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


def html_table(header: list[str], rows: list[list]) -> str:
    """A small HTML table for notebooks (``_repr_html_``).

    Parameters
    ----------
    header : list of str
        Column titles.
    rows : list of list
        Cell values; floats are shown with four significant digits.
    """
    def cell(x):
        return f"{x:.4g}" if isinstance(x, float) else _escape(str(x))
    head = "".join(f"<th>{_escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(x)}</td>" for x in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def check_plot_path(path) -> Path:
    """*path* as a Path if matplotlib can write its format; checked before any work is done.

    Parameters
    ----------
    path : str or Path
        The image file to be written.
    """
    path = Path(path)
    if path.suffix.lower().lstrip(".") not in PLOT_FORMATS:
        raise InputError(f"cannot plot to {str(path)!r}: use one of "
                         f"{', '.join('.' + f for f in PLOT_FORMATS[:4])}")
    return path
