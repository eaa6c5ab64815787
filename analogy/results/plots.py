"""Plots of trajectories, comparisons and scene results, with one line style per solver."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure  # no pyplot: works headless, with no global state

from ..errors import InputError
from .output import check_plot_path

__all__ = ["solver_style", "plot_trajectory", "plot_comparison", "plot_quantities", "plot_linear_horizon",
           "plot_bode"]


_STYLES = {"exact": dict(ls="-", lw=2.0, alpha=0.5), "spice": dict(ls="--", lw=1.2),
           "ode": dict(ls=":", lw=1.2)}


def solver_style(name: str) -> dict:
    """Line style of a solver's curves (a registered solver without its own gets dash-dots).

    Parameters
    ----------
    name : str
        Solver name.
    """
    return dict(_STYLES.get(name, dict(ls="-.", lw=1.2)))


def _save(fig: Figure, path) -> Figure:
    if path is not None:
        check_plot_path(path)
        fig.savefig(path, dpi=110)
    return fig


def plot_trajectory(trajectory, path=None) -> Figure:
    """Joint rates of one trajectory against time.

    Parameters
    ----------
    trajectory : Trajectory
        A successful solver result.
    path : str or Path, optional
        Image file to write.
    """
    fig = Figure(figsize=(8, 3.5), layout="constrained")
    ax = fig.subplots()
    for j in range(trajectory.rates.shape[1]):
        ax.plot(trajectory.time, trajectory.rates[:, j], color=f"C{j % 10}", label=f"r{j + 1}",
                **solver_style(trajectory.solver))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("joint rate [rad/s or m/s]")
    ax.set_title(f"{trajectory.solver}")
    ax.legend(fontsize="small")
    return _save(fig, path)


def plot_comparison(comparison, path=None) -> Figure:
    """Joint rates (all solvers overlaid) and |error| against the reference.

    Parameters
    ----------
    comparison : Comparison
        The result to draw.
    path : str or Path, optional
        Image file to write.
    """
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax, axe = fig.subplots(2, 1, sharex=True)
    for name, tr in comparison.results.items():
        for j in range(comparison.system.dof):
            ax.plot(tr.time, tr.rates[:, j], color=f"C{j % 10}", label=f"r{j + 1} {name}",
                    **solver_style(name))
    ax.set_ylabel("joint rate [rad/s or m/s]")
    ax.set_title(f"{comparison.system.info.get('robot', 'custom')}: "
                 f"{', '.join(comparison.results)} (preset {comparison.preset})")
    ax.legend(ncol=3, fontsize="small")
    ref = comparison.results.get(comparison.reference) if comparison.reference else None
    for name, tr in comparison.results.items():
        if ref is None or name == comparison.reference:
            continue
        err = np.max(np.abs(tr.rates - ref.rates), axis=1)
        axe.semilogy(tr.time, np.maximum(err, 1e-18), label=name, **solver_style(name))
    axe.set_xlabel("time [s]")
    axe.set_ylabel(f"max |error| over joints (vs {comparison.reference})")
    if axe.lines:
        axe.legend(fontsize="small")
    return _save(fig, path)


def plot_quantities(time: np.ndarray, groups: list, errors: dict, title: str, path=None,
                    reference: str | None = None) -> Figure:
    """One panel per quantity (solvers overlaid) and, with a reference, each solver's error / peak.

    Parameters
    ----------
    time : ndarray
        Shared time points.
    groups : list of (str, dict)
        (quantity, {solver: {name: values}}).
    errors : dict
        ``{quantity: {solver: (abs, rel)}}``; empty without a reference.
    title : str
        Heading of the first panel.
    path : str or Path, optional
        Image file to write.
    reference : str, optional
        The solver the errors are measured against.
    """
    if not groups:
        raise InputError("no solver ran: nothing to plot")
    panels = len(groups) + (1 if errors else 0)
    fig = Figure(figsize=(8, 2.6 * panels + 0.6), layout="constrained")
    axes = fig.subplots(panels, 1, sharex=True, squeeze=False)[:, 0]
    for ax, (quantity, by_solver) in zip(axes, groups):
        for s, vals in by_solver.items():
            for k, (name, v) in enumerate(vals.items()):
                ax.plot(time, v, color=f"C{k % 10}", label=f"{name} {s}", **solver_style(s))
        ax.set_ylabel(quantity)
        ax.legend(ncol=3, fontsize="x-small")
    axes[0].set_title(title)
    if errors and reference is not None:
        ax = axes[-1]
        solvers = dict.fromkeys(s for by in groups for s in by[1] if s != reference)
        for s in solvers:
            curves = []
            for quantity, by_solver in groups:
                ref, vals = by_solver.get(reference), by_solver.get(s)
                if ref is None or vals is None:
                    continue
                top = max(float(np.max(np.abs(x))) for x in ref.values()) or 1.0
                curves += [np.abs(vals[k] - ref[k]) / top for k in ref]
            if curves:
                ax.semilogy(time, np.maximum(np.max(curves, axis=0), 1e-18), label=s, **solver_style(s))
        ax.set_ylabel("max |error| / peak")
        if ax.lines:
            ax.legend(fontsize="small")
    axes[-1].set_xlabel("time [s]")
    return _save(fig, path)


def plot_linear_horizon(time: np.ndarray, nonlinear: np.ndarray, linear: np.ndarray, deviation: np.ndarray,
                        thresholds: dict, title: str, path=None) -> Figure:
    """The full motion against the circuit linearised at q0, and how far apart they are.

    Parameters
    ----------
    time : ndarray
        Time points.
    nonlinear, linear : ndarray, shape (N, n)
        Joint rates of the nonlinear reference and of the linear circuit.
    deviation : ndarray, shape (N,)
        max over joints of |R_linear − R_nonlinear| / peak.
    thresholds : dict of float to float
        Relative deviation -> the time the linear circuit first exceeds it.
    title : str
        Heading.
    path : str or Path, optional
        Image file to write.
    """
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax, axe = fig.subplots(2, 1, sharex=True)
    for j in range(nonlinear.shape[1]):
        ax.plot(time, nonlinear[:, j], color=f"C{j % 10}", lw=2.0, alpha=0.6, label=f"r{j + 1} nonlinear")
        ax.plot(time, linear[:, j], color=f"C{j % 10}", ls="--", lw=1.2, label=f"r{j + 1} linear at q0")
    ax.set_ylabel("joint rate [rad/s or m/s]")
    ax.set_title(title)
    ax.legend(ncol=2, fontsize="small")
    axe.semilogy(time, np.maximum(deviation, 1e-18), color="k", lw=1.2, label="deviation")
    colours = ("tab:green", "tab:purple", "tab:red", "tab:brown")   # apart from the joints' C0, C1
    for k, (tol, t) in enumerate(sorted(thresholds.items())):
        held = f"until t = {t:.3g} s" if np.isfinite(t) else "throughout"
        colour = colours[k % len(colours)]
        axe.axhline(tol, color=colour, ls=":", lw=1, label=f"within {tol:g} {held}")
        if np.isfinite(t):
            axe.axvline(t, color=colour, ls=":", lw=1)
    axe.set_ylim(max(1e-8, min(thresholds) / 1e4) if thresholds else 1e-8, 2.0)
    axe.legend(fontsize="small", loc="lower right")
    axe.set_xlabel("time [s]")
    axe.set_ylabel("|linear - nonlinear| / peak")
    return _save(fig, path)


def plot_bode(response, reference=None, path=None) -> Figure:
    """Bode plot of the driving-point mobilities R_j/F_j and their phase, one colour per joint.

    Parameters
    ----------
    response : FrequencyResponse
        The response drawn in its solver's line style.
    reference : FrequencyResponse, optional
        Drawn beneath in its own style (the exact mobility).
    path : str or Path, optional
        Image file to write.
    """
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    mag, phase = fig.subplots(2, 1, sharex=True)
    joints = response.mobility.shape[2]
    for r in ([reference] if reference is not None else []) + [response]:
        style = solver_style(r.solver)
        points = r.driving_point()
        for j in range(joints):
            y = points[:, j]
            label = f"joint {j + 1}" if r is response else None
            mag.loglog(r.frequency, np.abs(y), color=f"C{j % 10}", label=label, **style)
            phase.semilogx(r.frequency, np.degrees(np.angle(y)), color=f"C{j % 10}", **style)
    for f in response.resonances():
        mag.axvline(f, color="0.8", lw=0.6, zorder=0)
    mag.set_ylabel("|R_j / F_j| [(rad/s)/(N·m) or (m/s)/N]")
    phase.set_ylabel("phase [deg]")
    phase.set_yticks([-90, -45, 0, 45, 90])
    phase.set_xlabel("frequency [Hz]")
    solvers = response.solver + (f" ({reference.solver} beneath)" if reference is not None else "")
    mag.set_title(f"driving-point mobilities, {solvers}; grey lines: resonances")
    mag.legend(fontsize="small", loc="center left", bbox_to_anchor=(1.0, 0.5))
    return _save(fig, path)
