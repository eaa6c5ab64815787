"""SPICE, ODE and exact solutions on shared time points, with errors and run times."""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from .errors import AnalogyError, InputError
from .presets import preset as get_preset

__all__ = ["Comparison", "compare", "SOLVERS", "check_plot_path"]

SOLVERS = ("spice", "ode", "exact")


_PLOT_FORMATS = ("png", "svg", "pdf", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp")


def check_plot_path(path) -> Path:
    """*path* as a Path if matplotlib can write its format; checked before any work is done."""
    path = Path(path)
    if path.suffix.lower().lstrip(".") not in _PLOT_FORMATS:
        raise InputError(f"cannot plot to {str(path)!r}: use one of "
                         f"{', '.join('.' + f for f in _PLOT_FORMATS[:4])}")
    return path


@dataclass(eq=False)
class Comparison:
    """Joint rates from several solvers on one time grid, with errors against the exact solution.

    Attributes
    ----------
    system : NodeSystem
    preset : str
    time : ndarray
        Shared time points: SPICE's own output points when SPICE ran (so its
        values are compared without interpolation), else a uniform grid.
    results : dict of str to Trajectory
    failures : dict of str to str
        Solvers that failed, with the reason; the others are kept.
    """

    system: object
    preset: str
    time: np.ndarray
    results: dict = field(default_factory=dict)
    failures: dict = field(default_factory=dict)

    @property
    def peak(self) -> float:
        """max |R_exact| over joints and times."""
        ex = self.results.get("exact")
        return float(np.max(np.abs(ex.rates))) if ex is not None and ex.rates.size else float("nan")

    def errors(self) -> dict:
        """Per solver: (max |R − R_exact|, that divided by the peak)."""
        ex = self.results.get("exact")
        out = {}
        for name, tr in self.results.items():
            if ex is None:
                out[name] = (float("nan"), float("nan"))
                continue
            err = float(np.max(np.abs(tr.rates - ex.rates))) if tr.rates.size else float("nan")
            out[name] = (err, err / self.peak if self.peak > 0 else float("nan"))
        return out

    def max_relative_error(self, solver: str) -> float:
        """Max error of *solver* relative to the peak exact joint rate."""
        return self.errors()[solver][1]

    def table(self) -> str:
        """A plain-text table of run time and error per solver."""
        info = self.system.info
        lines = [f"robot {info.get('robot', 'custom')}, topology {self.system.topology.name}, "
                 f"preset {self.preset}, {self.time.size} time points, "
                 f"peak joint rate {self.peak:.6g}",
                 f"{'solver':<8}{'run time [ms]':>15}{'max |error|':>14}{'error / peak':>14}"]
        errs = self.errors()
        for name in SOLVERS:
            if name in self.results:
                tr = self.results[name]
                e, r = errs[name]
                lines.append(f"{name:<8}{tr.run_time * 1e3:>15.3f}{e:>14.3e}{r:>14.3e}"
                             + ("  (reference)" if name == "exact" else ""))
            elif name in self.failures:
                lines.append(f"{name:<8}  failed: {self.failures[name]}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def to_csv(self, path) -> Path:
        """Write time, then every solver's joint rates r1…rn, one row per time point."""
        path = Path(path)
        names = [s for s in SOLVERS if s in self.results]
        n = self.system.dof
        header = ["time"] + [f"r{j + 1}_{s}" for s in names for j in range(n)]
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            cols = [self.time] + [self.results[s].rates[:, j] for s in names for j in range(n)]
            for row in zip(*cols):
                w.writerow([repr(float(x)) for x in row])
        return path

    def plot(self, path=None):
        """Plot joint rates (all solvers overlaid) and |error| against time; save PNG if *path*."""
        from matplotlib.figure import Figure   # no pyplot: works headless, no global state
        fig = Figure(figsize=(8, 6), layout="constrained")
        ax, axe = fig.subplots(2, 1, sharex=True)
        styles = {"exact": dict(ls="-", lw=2.0, alpha=0.5), "spice": dict(ls="--", lw=1.2),
                  "ode": dict(ls=":", lw=1.2)}
        for name in SOLVERS:
            tr = self.results.get(name)
            if tr is None:
                continue
            for j in range(self.system.dof):
                ax.plot(tr.time, tr.rates[:, j], color=f"C{j}", label=f"r{j + 1} {name}", **styles[name])
        ax.set_ylabel("joint rate [rad/s or m/s]")
        ax.set_title(f"{self.system.info.get('robot', 'custom')}: SPICE, ODE and exact "
                     f"(preset {self.preset})")
        ax.legend(ncol=3, fontsize="small")
        ex = self.results.get("exact")
        for name in ("spice", "ode"):
            tr = self.results.get(name)
            if tr is None or ex is None:
                continue
            err = np.max(np.abs(tr.rates - ex.rates), axis=1)
            axe.semilogy(tr.time, np.maximum(err, 1e-18), label=name, **styles[name])
        axe.set_xlabel("time [s]")
        axe.set_ylabel("max |error| over joints")
        axe.legend(fontsize="small")
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def compare(system, preset="accurate", solvers: Sequence[str] = SOLVERS, times=None) -> Comparison:
    """Run the requested solvers on *system* and compare them on shared time points.

    A failing solver is recorded in :attr:`Comparison.failures`; the others still run.
    *times* sets the grid when SPICE is not run; with SPICE, its own output points are used.
    """
    solvers = list(dict.fromkeys(solvers))
    unknown = [s for s in solvers if s not in SOLVERS]
    if unknown:
        raise InputError(f"unknown solver {unknown[0]!r}: use {', '.join(SOLVERS)}")
    p = get_preset(preset)
    results, failures = {}, {}
    grid = None
    if "spice" in solvers:
        from .spice import solve_spice
        try:
            tr = solve_spice(system, p)
            results["spice"] = tr
            if grid is None:
                grid = tr.time
        except AnalogyError as exc:
            failures["spice"] = str(exc)
    if grid is None:
        grid = (np.linspace(0.0, system.t_stop, p.steps + 1) if times is None
                else np.asarray(times, dtype=float))
    if "ode" in solvers:
        from .ode import solve_ode
        try:
            results["ode"] = solve_ode(system, grid, p.ode_method, p.ode_rtol)
        except AnalogyError as exc:
            failures["ode"] = str(exc)
    # The exact solution is the yardstick for the others, so it runs whenever it applies.
    from .exact import solve_exact
    try:
        results["exact"] = solve_exact(system, grid)
    except AnalogyError as exc:
        failures["exact"] = str(exc)
    ordered = {s: results[s] for s in SOLVERS if s in results}
    return Comparison(system, p.name, grid, ordered, failures)
