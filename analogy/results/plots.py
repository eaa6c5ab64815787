"""Plots of trajectories, comparisons and scene results, with one line style per solver."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure  # no pyplot: works headless, with no global state

from ..files import write_figure
from ..errors import InputError
from ..units import quantity_label, rate_label, rate_unit
from .metrics import PEAK_FLOOR
from .output import check_plot_path

__all__ = ["save_figure", "solver_style", "shown_joints", "error_envelope", "plot_trajectory", "plot_comparison",
           "plot_quantities", "plot_linear_horizon", "plot_bode", "plot_error_histogram", "MANY_JOINTS",
           "rate_labels"]


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


def save_figure(fig: Figure, path) -> Figure:
    """*fig*, written to *path* first if one is given (its kind checked).

    Parameters
    ----------
    fig : Figure
        A figure made without pyplot.
    path : str or Path or None
        Image file to write.
    """
    if path is not None:
        check_plot_path(path)
        write_figure(fig, path, dpi=110)
    return fig


#: From this many joints up, plots show a chosen few (the largest peaks) and the error over all.
MANY_JOINTS = 7
_FEW = 4


def shown_joints(rates: np.ndarray) -> list[int]:
    """Joints to draw: all of up to 6, else the 4 with the largest peak |rate| (in joint order).

    Parameters
    ----------
    rates : ndarray, shape (N, n)
        Joint rates of one solver.
    """
    n = rates.shape[1]
    if n < MANY_JOINTS:
        return list(range(n))
    peaks = np.max(np.abs(rates), axis=0) if rates.size else np.zeros(n)
    return sorted(np.argsort(-peaks, kind="stable")[:_FEW].tolist())


def error_envelope(time: np.ndarray, error: np.ndarray, bins: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """The maximum of *error* within each of *bins* equal windows of time, as a step curve.

    Step-to-step ringing (trapezoidal, or SPICE's own steps) fills a plain plot of the
    error with a solid band; its envelope shows how large the error gets, and when.

    Parameters
    ----------
    time : ndarray
        Time points (ascending).
    error : ndarray
        Error at each point.
    bins : int
        Windows over [t0, t_end].
    """
    if time.size <= 2 * bins:
        return time, error
    edges = np.linspace(time[0], time[-1], bins + 1)
    which = np.clip(np.searchsorted(edges, time, side="right") - 1, 0, bins - 1)
    top = np.full(bins, np.nan)
    np.fmax.at(top, which, error)
    keep = np.isfinite(top)
    t = np.repeat(edges[:-1][keep], 2)
    t[1::2] = edges[1:][keep]
    return t, np.repeat(top[keep], 2)


def rate_labels(n: int, names=None) -> list[str]:
    """Per joint, the label of its rate: ``r1`` …, or its own name (a URDF robot's joints).

    Parameters
    ----------
    n : int
        Joints.
    names : sequence of str, optional
        The joints' names.
    """
    return list(names) if names and len(names) == n else [f"r{j + 1}" for j in range(n)]


def _legends(ax, joints: list[int], units, solvers: list[str], names=None) -> None:
    """Two compact legends outside the axes: colour is the joint, line style the solver."""
    from matplotlib.lines import Line2D
    labels = rate_labels(max(joints, default=-1) + 1 if not names else len(names), names)
    handles = [Line2D([], [], color=f"C{j % 10}", lw=2, label=labels[j] + (f" [{rate_unit(units[j])}]"
                                                                           if units else ""))
               for j in joints]
    handles += [Line2D([], [], color="k", label=name, **solver_style(name)) for name in solvers]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False,
              fontsize="small", title="joint / solver", title_fontsize="small")


def plot_trajectory(trajectory, path=None, units=None) -> Figure:
    """Joint rates of one trajectory against time.

    Parameters
    ----------
    trajectory : Trajectory
        A successful solver result.
    path : str or Path, optional
        Image file to write.
    units : sequence of str, optional
        Joint units (:func:`analogy.units.joint_units`).
    """
    fig = Figure(figsize=(8.5, 3.5), layout="constrained")
    ax = fig.subplots()
    joints = shown_joints(trajectory.rates)
    for j in joints:
        ax.plot(trajectory.time, trajectory.rates[:, j], color=f"C{j % 10}", **solver_style(trajectory.solver))
    ax.set_xlabel("time [s]")
    ax.set_ylabel(rate_label(units))
    n = trajectory.rates.shape[1]
    ax.set_title(f"{trajectory.solver}" + (f": {len(joints)} of {n} joints (largest peaks)" if len(joints) < n
                                           else ""), fontsize="medium")
    _legends(ax, joints, units, [trajectory.solver])
    return save_figure(fig, path)


def plot_comparison(comparison, path=None) -> Figure:
    """Joint rates of every solver overlaid, and each solver's error envelope against the reference.

    Colour is the joint and line style the solver in both panels. From 7 joints up the
    top panel shows the 4 with the largest peaks; the error is over all joints.

    Parameters
    ----------
    comparison : Comparison
        The result to draw.
    path : str or Path, optional
        Image file to write.
    """
    units = comparison.system.provenance.units
    n = comparison.system.dof
    # rad/s and m/s never share an axis: one panel of rates per unit (a flexible arm's joints and modes)
    kinds: dict = {}
    for j in range(n):
        kinds.setdefault(units[j] if units else None, []).append(j)
    fig = Figure(figsize=(9, 6 + 2.2 * (len(kinds) - 1)), layout="constrained")
    *axes, axe = fig.subplots(len(kinds) + 1, 1, sharex=True)
    ok = {name: tr for name, tr in comparison.results.items() if tr.success and tr.rates.size}
    ref = ok.get(comparison.reference) if comparison.reference else None
    first = ref if ref is not None else next(iter(ok.values()), None)
    count = 0
    for ax, (unit, idx) in zip(axes, kinds.items()):
        joints = [idx[k] for k in shown_joints(first.rates[:, idx])] if first is not None else []
        count += len(joints)
        for name, tr in ok.items():
            for j in joints:
                ax.plot(tr.time, tr.rates[:, j], color=f"C{j % 10}", **solver_style(name))
        ax.set_ylabel(rate_label(None if unit is None else [unit]))
        _legends(ax, joints, units, list(ok), comparison.system.provenance.joints)
    shown = f"; {count} of {n} joints shown (largest peaks)" if count < n else ""
    axes[0].set_title(f"{comparison.system.provenance.robot}: {', '.join(ok)} "
                      f"(preset {comparison.preset}){shown}", fontsize="medium")
    if ref is not None:
        own = np.max(np.abs(ref.rates), axis=0)
        peak = np.maximum(own, PEAK_FLOOR * np.max(own))      # each joint against its own peak, as the table
        peak = np.where(peak > 0, peak, 1.0)
        for name, tr in ok.items():
            if name == comparison.reference or tr.rates.shape != ref.rates.shape:
                continue
            err = np.max(np.abs(tr.rates - ref.rates) / peak, axis=1)
            t, env = error_envelope(tr.time, np.where(err > 0, err, np.nan))     # log axis: no zeros
            axe.semilogy(t, env, color="k", label=name, **solver_style(name))
        which = "the joint's rate, relative to its peak" if n == 1 else \
            f"worst of the {n} joints, each relative to its own peak"
        axe.set_title(f"error against {comparison.reference}: {which} (largest in each time window)",
                      fontsize="small")
    else:           # no reference: each solver's estimate, a worst over the run, as a level
        estimated = {k: e.relative for k, e in getattr(comparison, "estimated", {}).items()
                     if k in ok and np.isfinite(e.relative) and e.relative > 0}
        for name, level in estimated.items():
            axe.axhline(level, color="k", label=f"{name} (estimated)", **solver_style(name))
        if estimated:
            axe.set_yscale("log")
        axe.set_title("no reference: each solver's estimated worst error over its own peak (a refined run)"
                      if estimated else "no reference, so no errors measured", fontsize="small")
    axe.set_xlabel("time [s]")
    axe.set_ylabel("|error| / own peak rate [1]")
    if axe.lines:
        axe.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, fontsize="small",
                   title="solver", title_fontsize="small")
        axe.axhline(comparison.bound, color="tab:red", lw=0.8, ls=(0, (1, 3)))
        axe.annotate(f"{comparison.preset} bound {comparison.bound:g}", (0.99, comparison.bound),
                     xycoords=("axes fraction", "data"), ha="right", va="top", fontsize="x-small",
                     color="tab:red")
    return save_figure(fig, path)


def plot_quantities(time: np.ndarray, groups: list, errors: dict, title: str, path=None,
                    reference: str | None = None, units=None) -> Figure:
    """One panel per quantity (solvers overlaid) and, with a reference, each solver's error / peak.

    Colour is the curve (joint, node or element) and line style the solver, in every panel.

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
    units : sequence of str, optional
        Joint units (:func:`analogy.units.joint_units`), for the axis labels.
    """
    from matplotlib.lines import Line2D
    if not groups:
        raise InputError("no solver ran: nothing to plot")
    panels = len(groups) + (1 if errors else 0)
    fig = Figure(figsize=(9, 2.6 * panels + 0.6), layout="constrained")
    axes = fig.subplots(panels, 1, sharex=True, squeeze=False)[:, 0]
    for ax, (quantity, by_solver) in zip(axes, groups):
        names = list(dict.fromkeys(k for vals in by_solver.values() for k in vals))
        if len(names) >= MANY_JOINTS:
            first = next(iter(by_solver.values()))
            stack = np.array([first[k] for k in names if k in first]).T
            names = [names[k] for k in shown_joints(stack)]
        for s, vals in by_solver.items():
            for k, name in enumerate(names):
                if name in vals:
                    ax.plot(time, vals[name], color=f"C{k % 10}", **solver_style(s))
        ax.set_ylabel(quantity_label(quantity, units))
        handles = [Line2D([], [], color=f"C{k % 10}", lw=2, label=name) for k, name in enumerate(names)]
        handles += [Line2D([], [], color="k", label=s, **solver_style(s)) for s in by_solver]
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False,
                  fontsize="x-small")
    axes[0].set_title(title, fontsize="medium")
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
                worst = np.max(curves, axis=0)
                t, env = error_envelope(time, np.where(worst > 0, worst, np.nan))
                ax.semilogy(t, env, color="k", label=s, **solver_style(s))
        ax.set_ylabel("|error| / peak [1]")
        ax.set_title(f"error against {reference}: max over every curve, relative to its quantity's peak "
                     "(largest in each time window)", fontsize="small")
        if ax.lines:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, fontsize="small")
    axes[-1].set_xlabel("time [s]")
    return save_figure(fig, path)


def plot_linear_horizon(time: np.ndarray, nonlinear: np.ndarray, linear: np.ndarray, deviation: np.ndarray,
                        thresholds: dict, title: str, path=None, units=None, names=None) -> Figure:
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
    units : sequence of str, optional
        Joint units (:func:`analogy.units.joint_units`).
    names : sequence of str, optional
        The joints' names (:func:`rate_labels`).
    """
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax, axe = fig.subplots(2, 1, sharex=True)
    labels = rate_labels(nonlinear.shape[1], names)
    for j in range(nonlinear.shape[1]):
        ax.plot(time, nonlinear[:, j], color=f"C{j % 10}", lw=2.0, alpha=0.6, label=f"{labels[j]} nonlinear")
        ax.plot(time, linear[:, j], color=f"C{j % 10}", ls="--", lw=1.2, label=f"{labels[j]} linear at q0")
    ax.set_ylabel(rate_label(units))
    ax.set_title(title)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    axe.semilogy(time, np.maximum(deviation, 1e-18), color="k", lw=1.2, label="deviation")
    colours = ("tab:green", "tab:purple", "tab:red", "tab:brown")   # apart from the joints' C0, C1
    for k, (tol, t) in enumerate(sorted(thresholds.items())):
        held = f"until t = {t:.3g} s" if np.isfinite(t) else "throughout"
        colour = colours[k % len(colours)]
        axe.axhline(tol, color=colour, ls=":", lw=1, label=f"within {tol:g} {held}")
        if np.isfinite(t):
            axe.axvline(t, color=colour, ls=":", lw=1)
    axe.set_ylim(max(1e-8, min(thresholds) / 1e4) if thresholds else 1e-8, 2.0)
    axe.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    axe.set_xlabel("time [s]")
    axe.set_ylabel("|linear − nonlinear| / peak [1]")
    return save_figure(fig, path)


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
    units = response.units
    each = {"rad": "(rad/s)/(N·m)", "m": "(m/s)/N"}
    mixed = len(set(units or ())) > 1 or not units       # then each joint's unit goes in its legend entry
    for r in ([reference] if reference is not None else []) + [response]:
        style = solver_style(r.solver)
        points = r.driving_point()
        for j in range(joints):
            y = points[:, j]
            names = response.coordinates
            name = names[j] if names and len(names) == joints else f"joint {j + 1}"
            if mixed and units and len(units) == joints:
                name = f"{name} [{each.get(units[j], '?')}]"
            label = name if r is response else None
            mag.loglog(r.frequency, np.abs(y), color=f"C{j % 10}", label=label, **style)
            phase.semilogx(r.frequency, np.degrees(np.angle(y)), color=f"C{j % 10}", **style)
    for f in response.resonances():
        mag.axvline(f, color="0.8", lw=0.6, zorder=0)
    unit = "" if mixed else f" [{each.get(units[0], '?')}]"
    mag.set_ylabel(f"driving-point mobility |R/F|{unit}")
    phase.set_ylabel("phase [deg]")
    phase.set_yticks([-90, -45, 0, 45, 90])
    phase.set_xlabel("frequency [Hz]")
    solvers = response.solver + (f" ({reference.solver} beneath)" if reference is not None else "")
    marks = "; grey lines: resonances" if len(response.resonances()) else "; no resonance in the band"
    mag.set_title(f"driving-point mobilities, {solvers}{marks}")
    mag.legend(fontsize="small", loc="center left", bbox_to_anchor=(1.0, 0.5))
    return save_figure(fig, path)


def plot_error_histogram(errors: dict, title: str, bounds: dict | None = None, counted: str = "scenes",
                         path=None) -> Figure:
    """Each solver's errors over many scenes as a histogram of log10(error / peak), on one set of bins
    so that the solvers' bars compare, each preset's bound marked.

    Parameters
    ----------
    errors : dict of str to array_like
        Per solver, its error over each scene (NaN and 0 are left out: not measured, or exact).
    title : str
        The figure's title.
    bounds : dict of str to float, optional
        Per preset name, its bound.
    counted : str
        What the bars count.
    path : str or Path, optional
        Image file to write.
    """
    fig = Figure(figsize=(6, 3.6), layout="constrained")
    ax = fig.subplots()
    logs = {name: np.log10(e[np.isfinite(e) & (e > 0)]) for name, e in
            ((name, np.asarray(e, dtype=float)) for name, e in errors.items())}
    logs = {name: x for name, x in logs.items() if x.size}
    marks = [np.log10(b) for b in (bounds or {}).values()]
    ends = [x.min() for x in logs.values()] + [x.max() for x in logs.values()] + marks
    if ends:
        edges = np.linspace(min(ends), max(ends), 61) if max(ends) > min(ends) else 60
        for name, x in logs.items():
            ax.hist(x, bins=edges, histtype="step", linewidth=1.5, label=name)
    for (name, bound), style in zip((bounds or {}).items(), ("--", ":", "-.")):
        ax.axvline(np.log10(bound), color="k", linestyle=style, linewidth=1, label=f"{name} bound")
    ax.set_xlabel("log10(worst error / own peak)")
    ax.set_ylabel(counted)
    if logs or bounds:
        ax.legend(loc="best", frameon=False, fontsize="small")
    ax.set_title(title, fontsize="medium" if len(title) <= 60 else "small")
    return save_figure(fig, path)
