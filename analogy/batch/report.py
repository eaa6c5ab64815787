"""A results store summarised: error quantiles per solver and axis, the worst scenes, failures, plots."""

from __future__ import annotations

from dataclasses import dataclass
from html import escape
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..files import write_figure, write_text
from ..errors import InputError
from ..presets import preset as get_preset
from ..scenes.paths import inside_folder
from ..units import force_unit, rate_unit
from .store import manifest, read
from .sweep import axis_kind

if TYPE_CHECKING:
    import pandas
    from matplotlib.figure import Figure

__all__ = ["BatchReport", "batch_report"]

_QUANTILES = (0.5, 0.9, 0.99, 1.0)


def _fmt(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.2e}"


@dataclass(eq=False)
class BatchReport:
    """What a sweep's results say: a markdown summary and plots of error against each axis.

    Attributes
    ----------
    frame : pandas.DataFrame
        The store's rows.
    info : dict
        The sweep's manifest.
    """

    frame: "pandas.DataFrame"
    info: dict

    @property
    def solvers(self) -> list[str]:
        """Solvers with an error column that holds at least one number."""
        return [c[6:] for c in self.frame.columns if c.startswith("error_") and self.frame[c].notna().any()]

    @property
    def axes(self) -> list[str]:
        """The swept axes."""
        return [a["name"] for a in self.info.get("axes", [])]

    def __repr__(self) -> str:
        return f"<BatchReport {len(self.frame)} of {self.info.get('count', '?')} scenes, solvers {self.solvers}>"

    def sections(self, worst: int = 10) -> list[tuple[str | None, list[str], list[str], list[list]]]:
        """The report's content: per section a heading, its paragraphs, a table's header and rows.

        Parameters
        ----------
        worst : int
            How many of the worst scenes to list.
        """
        f, info = self.frame, self.info
        intro = [f"Design {info.get('method')} (seed {info.get('seed')}), {info.get('group_size')} scenes per "
                 f"group{', each scene in its own ngspice run' if info.get('isolated') else ''}; errors are "
                 "max |R − R_ref| / peak |R_ref| against the exact solution.",
                 "Status: " + ", ".join(f"{n:,} {s}" for s, n in (f["status"].value_counts().items()
                                                                if len(f) else ()))]
        if not self.info.get("isolated"):
            intro.append("Scenes of a group share one ngspice run, so its step control follows the fastest of "
                         "them: a scene's error can differ from its error alone (run with --isolated for that).")
        out: list = []
        rows = []
        for s in self.solvers:
            e = f[f"error_{s}"].dropna()
            rows.append([s, *(_fmt(e.quantile(p) if len(e) else np.nan) for p in _QUANTILES),
                         f"{f[f'seconds_{s}'].median():.2e}"])
        out.append((None, intro, ["solver", "median", "90 %", "99 %", "max", "median seconds"] if rows else [],
                    rows))
        for axis in self.axes:
            if axis not in f or not self.solvers:
                continue
            col = f[axis]
            if col.dtype.kind == "f" and col.nunique() > 8:
                import pandas as pd
                bins = pd.qcut(col, 5, duplicates="drop")
            else:
                bins = col
            rows = []
            for label, part in f.groupby(bins, observed=True):
                cells = []
                for s in self.solvers:
                    e = part[f"error_{s}"].dropna()
                    cells += [_fmt(e.median() if len(e) else np.nan), _fmt(e.max() if len(e) else np.nan)]
                rows.append([str(label), f"{len(part):,}", *cells])
            out.append((f"Error against {axis}", [],
                        [axis, "scenes", *(f"{s} {w}" for s in self.solvers for w in ("median", "max"))], rows))
        if self.solvers:
            first = f"error_{self.solvers[0]}"
            top = f.dropna(subset=[first]).nlargest(worst, first)
            rows = [[str(row["scene"]),
                     *(f"{row[a]:.6g}" if isinstance(row[a], float) else str(row[a]) for a in self.axes),
                     _fmt(row[first]), row["key"][:12]] for _, row in top.iterrows()]
            out.append((f"The {len(top)} worst scenes ({self.solvers[0]})", [],
                        ["scene", *self.axes, "error", "key"], rows))
        bad = f[f["status"] != "ok"]
        if len(bad):
            rows = [[status, f"{len(part):,}", " ".join(str(message).split())[:200]]
                    for (status, message), part in bad.groupby(["status", "message"])]
            out.append(("Not ok, by reason", [], ["status", "scenes", "reason (first seen)"], rows))
        return out

    @property
    def title(self) -> str:
        """What the report is of: the sweep's scene and how many of its scenes are stored."""
        return f"Sweep {self.info.get('scene', '')}: {len(self.frame):,} of {self.info.get('count', 0):,} " \
               "scenes stored"

    def summary(self, worst: int = 10) -> str:
        """The report as markdown: quantiles, errors by axis, worst scenes, failures.

        Parameters
        ----------
        worst : int
            How many of the worst scenes to list.
        """
        lines = [f"# {self.title}", ""]
        for heading, paragraphs, header, rows in self.sections(worst):
            if heading:
                lines += [f"## {heading}", ""]
            for text in paragraphs:
                lines += [text, ""]
            if header:
                lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
                lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
                lines.append("")
        return "\n".join(lines)

    def html(self, worst: int = 10, plots: bool = True) -> str:
        """The report as one self-contained HTML page: the tables, and the plots inline.

        Parameters
        ----------
        worst : int
            How many of the worst scenes to list.
        plots : bool
            Include the plots (PNG, embedded).
        """
        from ..results.output import figure_uri, html_table
        from ..scenes.report import html_page
        parts = []
        for heading, paragraphs, header, rows in self.sections(worst):
            body = "".join(f"<p>{escape(t)}</p>" for t in paragraphs) + (html_table(header, rows) if header else "")
            parts.append((heading or "Summary", body))
        if plots and len(self.frame) and self.solvers:
            figures = [("Error against each axis", self.plot_axes()), ("Error histogram", self.plot_histogram())]
            if (shown := self.plot_map()) is not None:
                figures.append(("Error map", shown))
            for heading, fig in figures:
                parts.append((heading, f"<img src='{figure_uri(fig)}' alt='{escape(heading)}'>"))
        return html_page(self.title, parts)

    def _repr_html_(self) -> str:
        return self.html(plots=False)

    def plot_axes(self, path=None) -> "Figure":
        """Error against each swept axis (one panel per axis, every solver), log scale.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from matplotlib.figure import Figure
        axes = [a for a in self.axes if a in self.frame] or ["scene"]
        fig = Figure(figsize=(4.2 * len(axes), 3.6), layout="constrained")
        panels = np.atleast_1d(fig.subplots(1, len(axes), sharey=True))
        f = self.frame.sample(min(len(self.frame), 20_000), random_state=0) if len(self.frame) else self.frame
        logs = {a["name"] for a in self.info.get("axes", []) if a.get("log")}
        for ax, axis in zip(panels, axes):
            x_all = f[axis]
            categories = None if x_all.dtype.kind in "fiu" else sorted(map(str, x_all.unique()))
            for s, marker in zip(self.solvers, "o^sv"):
                e = f[f"error_{s}"]
                ok = e > 0
                x = x_all[ok]
                if categories is not None:      # one column per value, spread so that its points show
                    at = np.array([categories.index(str(v)) for v in x], dtype=float)
                    x = at + np.random.default_rng(0).uniform(-0.3, 0.3, at.size)
                ax.scatter(x, e[ok], s=4, alpha=0.4, marker=marker, label=s, rasterized=True)
            if categories is not None:
                ax.set_xticks(range(len(categories)), categories)
            if axis in logs:
                ax.set_xscale("log")
            for name, bound in self._bounds().items():
                ax.axhline(bound, color="red", ls=":", lw=1.0, label=f"{name} bound {bound:g}")
            ax.set_yscale("log")
            ax.set_xlabel(_label(axis, self.info.get("joint_units")))
            ax.grid(alpha=0.3)
        panels[0].set_ylabel("max error / peak rate [1]")
        if self.solvers:
            fig.legend(*panels[0].get_legend_handles_labels(), loc="outside lower center",
                       ncols=len(self.solvers) + len(self._bounds()), markerscale=3)
        fig.suptitle(f"{self.info.get('scene', '')}: error against each swept axis "
                     f"({len(f):,} scenes shown)", fontsize="medium")
        if path is not None:
            write_figure(fig, path, dpi=110)
        return fig

    def _bounds(self) -> dict[str, float]:
        """Each preset the sweep ran at, and its bound."""
        names = self.frame["preset"].unique() if "preset" in self.frame else [self.info.get("preset")]
        out = {}
        for n in names:
            try:
                out[str(n)] = get_preset(str(n)).bound
            except InputError:          # a store written by another version: no bound to draw
                continue
        return out

    def plot_histogram(self, path=None) -> "Figure":
        """Histograms of each solver's error (log10).

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from ..results.plots import plot_error_histogram
        return plot_error_histogram({s: self.frame[f"error_{s}"].to_numpy() for s in self.solvers},
                                    f"{self.info.get('scene', '')}: {len(self.frame):,} scenes", self._bounds(),
                                    "scenes", path)

    def plot_map(self, path=None, solver: str | None = None) -> "Figure | None":
        """The error over the first two numeric axes, as a coloured map (None with fewer than two).

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        solver : str, optional
            Whose error (default: the first solver).
        """
        from matplotlib.colors import LogNorm
        from matplotlib.figure import Figure
        numeric = [a for a in self.axes if a in self.frame and self.frame[a].dtype.kind == "f"]
        if len(numeric) < 2 or not self.solvers:
            return None
        solver = solver or self.solvers[0]
        x, y = numeric[:2]
        f = self.frame
        e = f[f"error_{solver}"]
        fig = Figure(figsize=(6.4, 5), layout="constrained")
        ax = fig.subplots()
        good = e > 0
        sc = ax.scatter(f[x][good], f[y][good], c=e[good], s=max(2.0, 3e4 / max(len(f), 1)), marker="s",
                        norm=LogNorm(), cmap="viridis", rasterized=True)
        failed = f["status"].isin(["failed", "invalid", "refused", "worker-died"])
        if failed.any():
            ax.scatter(f[x][failed], f[y][failed], s=6, c="red", marker="x", label="no result")
            ax.legend(loc="outside lower center")
        fig.colorbar(sc, ax=ax, label=f"{solver} max error / peak rate [1]")
        ax.set_xlabel(_label(x, self.info.get("joint_units")))
        ax.set_ylabel(_label(y, self.info.get("joint_units")))
        ax.set_title(f"{self.info.get('scene', '')}: {solver} error over ({x}, {y})", fontsize="medium")
        if path is not None:
            write_figure(fig, path, dpi=110)
        return fig

    def write(self, folder) -> list[Path]:
        """Write ``report.md``, ``report.html``, ``errors_by_axis.png``, ``error_histogram.png`` and ``error_map.png``.

        Parameters
        ----------
        folder : str or Path
            Where (made if missing).
        """
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        # each file inside the folder, reached through no symlink (as every output of the package)
        md, page, by_axis, histogram, error_map = (inside_folder(out, name) for name in REPORT_FILES)
        written = [md, page]
        write_text(md, self.summary() + "\n")
        write_text(page, self.html())
        if len(self.frame) and self.solvers:
            self.plot_axes(by_axis)
            self.plot_histogram(histogram)
            written += [by_axis, histogram]
            if self.plot_map(error_map) is not None:
                written.append(error_map)
        return written


#: The files :meth:`BatchReport.write` writes, in its folder.
REPORT_FILES = ("report.md", "report.html", "errors_by_axis.png", "error_histogram.png", "error_map.png")


def _label(axis: str, joint_units=None) -> str:
    """An axis name with its unit: a joint's from the model (rad, m), t_stop in s, others as named."""
    kind, joint = axis_kind(axis)
    unit = joint_units[joint] if joint_units and 0 <= joint < len(joint_units) else None
    text = {"q": unit or "rad or m", "rate": rate_unit(unit), "force": force_unit(unit), "t_stop": "s"}.get(kind)
    return f"{axis} [{text}]" if text else axis


def batch_report(directory) -> BatchReport:
    """The report of the results store *directory*.

    Parameters
    ----------
    directory : str or Path
        A folder ``analogy batch`` wrote.
    """
    frame = read(directory)
    if frame.empty:
        raise InputError(f"{directory} holds no results yet")
    info = manifest(directory)
    if missing := [a["name"] for a in info.get("axes", []) if a["name"] not in frame.columns]:
        raise InputError(f"{directory}'s manifest names axis {missing[0]!r}, which its results do not hold: "
                         "restore the manifest, or run the sweep again in an empty folder")
    return BatchReport(frame, info)
