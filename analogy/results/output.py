"""Output files: result columns as CSV, small HTML tables, and plot paths checked before any work."""

from __future__ import annotations

import base64
import csv
import io
import re
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from ..files import replaced
from ..errors import InputError
from ..units import rate_unit

if TYPE_CHECKING:
    import pandas

__all__ = ["Tabular", "column_unit", "write_columns", "write_rows", "html_table", "check_plot_path", "PLOT_FORMATS",
           "data_uri", "figure_uri"]

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
    with replaced(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(columns))
        for row in zip(*columns.values()):
            w.writerow([_cell(x) for x in row])
    return path


def _cell(x) -> str:
    """A CSV cell: a count as an integer, a number at full double precision, a word as itself."""
    if isinstance(x, (str, np.str_)):
        return str(x)
    if isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_)):
        return str(int(x))
    return repr(float(x))


def write_rows(path, header: list[str], rows) -> Path:
    """Write mixed rows as CSV: floats at full double precision (``repr``), the rest as text.

    Parameters
    ----------
    path : str or Path
        The file to write (its folder must exist).
    header : list of str
        Column names.
    rows : iterable of sequence
        The rows.
    """
    path = Path(path)
    with replaced(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows:
            w.writerow([repr(float(x)) if isinstance(x, (float, np.floating)) else x for x in row])
    return path


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


def html_table(header: list[str], rows: list[list], caption: str | None = None) -> str:
    """A small HTML table for notebooks (``_repr_html_``).

    Parameters
    ----------
    header : list of str
        Column titles.
    rows : list of list
        Cell values; floats are shown with four significant digits.
    caption : str, optional
        What the table is of (robot, preset, reference).
    """
    def cell(x):
        return f"{x:.4g}" if isinstance(x, float) else _escape(str(x))
    head = "".join(f"<th>{_escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(x)}</td>" for x in r) + "</tr>" for r in rows)
    top = f"<caption>{_escape(caption)}</caption>" if caption else ""
    return f"<table>{top}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


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


_RATE = re.compile(r"^r(\d+)(_|$)")


def column_unit(name: str, joint_units=None) -> str:
    """The unit of a result column by its name: time [s], joint rates, voltages [V], currents [A].

    Parameters
    ----------
    name : str
        ``time``, ``r2_spice``, ``v_n1_exact``, ``i_C1_2_spice`` …
    joint_units : sequence of str, optional
        :func:`analogy.units.joint_units` of the system.
    """
    if name == "time":
        return "s"
    if (m := _RATE.match(name)) is not None:
        j = int(m.group(1)) - 1
        return rate_unit(joint_units[j] if joint_units and j < len(joint_units) else None)
    if name.startswith("f_") and not name.startswith("f_hz"):      # a contact's force (f_hz: a frequency)
        return "N"
    return {"v_": "V", "i_": "A"}.get(name[:2], "")


def _with_unit(name: str, joint_units, plain: str | None = None) -> str:
    unit = column_unit(name if plain is None else plain, joint_units)
    return f"{name} [{unit}]" if unit else name


def _named(system):
    """The column renaming of *system*: joint rates after a URDF robot's joints, the rest as they are."""
    provenance = getattr(system, "provenance", None)
    return provenance.output_name if provenance is not None else (lambda name: name)


class Tabular:
    """Results whose :meth:`columns` (first column the index) give their CSV and their DataFrame."""

    __slots__ = ()

    def columns(self) -> dict[str, np.ndarray]:
        """Column name to values, the first column being the index (time, mode, scene)."""
        raise NotImplementedError

    def to_csv(self, path, every: int = 1) -> Path:
        """Write the :meth:`columns`, one row per entry of the first; the header names each unit.

        Parameters
        ----------
        path : str or Path
            The file to write (its folder must exist).
        every : int
            Write every *every*-th row and the last: rows as computed, none interpolated.
        """
        if not isinstance(every, (int, np.integer)) or isinstance(every, bool) or every < 1:
            raise ValueError(f"every must be a positive whole number, not {every!r}")
        system = getattr(self, "system", None)
        units = system.provenance.units if system is not None else None
        cols = self.columns()
        if every > 1:
            n = len(next(iter(cols.values())))
            rows = np.unique(np.append(np.arange(0, n, every), n - 1)) if n else np.arange(0)
            cols = {name: np.asarray(v)[rows] for name, v in cols.items()}
        named = _named(system)
        return write_columns(path, {_with_unit(named(name), units, name): v for name, v in cols.items()})

    def to_frame(self) -> "pandas.DataFrame":
        """The :meth:`columns` as a pandas DataFrame indexed by the first of them.

        Column names stay plain (``r1_spice``), so that code can index them; a URDF robot's
        joint rates are named after its joints (``shoulder_pan_joint_rate_spice``), the
        ``r1`` form they stand for in ``frame.attrs["outputs"]``. Units are in
        ``frame.attrs["units"]`` (``{"time": "s", "r1_spice": "rad/s", …}``), as the CSV's
        header names them.
        """
        import pandas as pd
        system = getattr(self, "system", None)
        joint = system.provenance.units if system is not None else None
        named = _named(system)
        cols = self.columns()
        frame = pd.DataFrame({named(name): v for name, v in cols.items()}).set_index(named(next(iter(cols))))
        frame.attrs["units"] = {named(name): u for name in cols if (u := column_unit(name, joint))}
        frame.attrs["outputs"] = {named(name): name for name in cols if named(name) != name}
        return frame


def data_uri(data: bytes, media: str) -> str:
    """*data* as a ``data:`` address, so that a page carries its images and files inside it.

    Parameters
    ----------
    data : bytes
        The file's bytes.
    media : str
        Its media type, e.g. ``"image/png"``.
    """
    return f"data:{media};base64," + base64.b64encode(data).decode("ascii")


def figure_uri(fig, dpi: int = 100) -> str:
    """A matplotlib figure drawn as PNG, as a ``data:`` address for an ``<img>``.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    dpi : int
        Resolution.
    """
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return data_uri(buffer.getvalue(), "image/png")
