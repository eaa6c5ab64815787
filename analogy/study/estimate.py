"""Error estimates without a reference: each solver again under refined settings, Richardson's factor on the difference."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from ..circuit.scales import system_scales
from ..errors import InputError
from ..presets import Preset
from ..results.metrics import PEAK_FLOOR, OutputErrors, output_errors
from ..results.output import Tabular
from ..results.trajectory import Trajectory
from ..solvers.registry import run, run_many, solver
from ..solvers.transient import REFINE, STEP_TOLERANCES

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["estimated_errors", "unresolved_outputs", "on_points", "netlist_estimate", "NetlistEstimate",
           "refined_netlist", "spice_number"]


def on_points(tr: Trajectory, times: np.ndarray, breakpoints: np.ndarray) -> np.ndarray:
    """*tr*'s joint rates at *times*: a cubic spline through its own points on each interval
    between the forces' *breakpoints*, where the rates are smooth.

    A spline's error is O(h⁴) of the step, far under the O(h²) error of the trapezoidal rule
    it measures; across a breakpoint the rates have a corner, which no spline spans.

    Parameters
    ----------
    tr : Trajectory
        A successful trajectory on its own points.
    times : ndarray
        Times within its span.
    breakpoints : ndarray
        The forces' breakpoints (t_stop among them or not).
    """
    t, y = tr.time, tr.rates
    span = float(t[-1]) if t.size else 0.0
    keep = np.append(np.diff(t) > 1e-12 * span, True)       # of two coinciding points, the later one
    t, y = t[keep], y[keep]
    edges = np.unique(np.concatenate([[0.0], np.asarray(breakpoints, float), [span]]))
    edges = edges[(edges >= 0.0) & (edges <= span)]
    out = np.empty((len(times), y.shape[1]))
    for a, b in zip(edges[:-1], edges[1:]):
        inside = (times >= a) & (times <= b)
        if not inside.any():
            continue
        src = (t >= a) & (t <= b)
        if np.count_nonzero(src) < 2:
            out[inside] = np.column_stack([np.interp(times[inside], t, y[:, j]) for j in range(y.shape[1])])
            continue
        out[inside] = CubicSpline(t[src], y[src], axis=0)(times[inside])
    return out


def _estimate(coarse: np.ndarray, fine: np.ndarray, factor: float, names: Sequence[str]) -> OutputErrors:
    err, rel = output_errors(coarse, fine)
    err, rel = err * factor, rel * factor
    worst = int(np.argmax(np.where(np.isnan(rel), -np.inf, rel)))
    top = float(np.max(np.abs(fine))) if fine.size else np.nan
    whole = float(np.max(err)) / top if top > 0 else np.nan
    return OutputErrors(float(np.max(err)), float(rel[worst]), names[worst], dict(zip(names, rel.tolist())), whole)


def unresolved_outputs(system, time: np.ndarray, rates: np.ndarray, bound: float) -> dict[str, str]:
    """Outputs of a SPICE run that move on a decay its steps do not resolve, and why.

    A preset's step cap leaves a decay to ngspice's truncation check, and ignores one under
    ten times the bound of the largest peak (:meth:`~analogy.circuit.scales.Scales.fastest`).
    An output whose own peak is as small as such a decay's share can still be all of it;
    stepped at β·h > 1 the trapezoidal rule turns the decay into a ringing that a run with
    twice shorter steps repeats, so Richardson's difference cannot see it. Such an output
    has no estimate: where a decay's share of the peak exceeds the bound of that output's
    own peak, every step while it lasts must keep β·h ≤ 1.

    Parameters
    ----------
    system : NodeDynamics
        The system (its :class:`~analogy.circuit.scales.Scales` give the decays and their shares).
    time : ndarray
        The run's own time points.
    rates : ndarray, shape (N, n)
        Its joint rates (their peaks, relative to the largest).
    bound : float
        The preset's bound.
    """
    scales = system_scales(system)
    own = np.max(np.abs(rates), axis=0)
    top = float(np.max(own)) if own.size else 0.0
    if not top > 0 or time.size < 2:
        return {}
    out: dict[str, str] = {}
    steps = np.diff(time)
    for beta, share in zip(scales.decays, scales.shares):
        for j, peak in enumerate(own / top):
            allowed = bound * max(float(peak), PEAK_FLOOR)
            if not (beta > 0 and share > allowed) or f"r{j + 1}" in out:
                continue
            lasts = math.log(share / allowed) / beta         # until the decay is under the allowance
            reach = int(np.searchsorted(time, lasts)) + 1
            h = float(np.max(steps[:max(reach, 1)]))
            if beta * h > 1:
                out[f"r{j + 1}"] = (f"r{j + 1} moves on a decay of {beta:.3g}/s ({share:.2g} of the peak velocity) "
                                    f"that steps of {h:.3g} s do not resolve (β·h = {beta * h:.3g})")
    return out


def estimated_errors(systems: Sequence, runs: dict[str, Sequence[Trajectory]], preset: Preset) -> \
        tuple[list[dict[str, OutputErrors]], dict[str, str]]:
    """Per system and solver, the estimated error of its joint rates, each against its own peak.

    Each solver with a :meth:`~analogy.solvers.registry.Solver.refinement` runs again under
    it; the difference of the two runs on the first run's own points, times the refinement's
    factor, is the estimate (Richardson's). A solver with its own points (SPICE) is read
    between the second run's points by :func:`on_points`.

    Parameters
    ----------
    systems : sequence of NodeDynamics
        The systems.
    runs : dict of str to sequence of Trajectory
        Each solver's trajectories, one per system, on the solver's own points.
    preset : Preset
        The settings they ran with.

    Returns
    -------
    estimates : list of dict of str to OutputErrors
        One dict per system.
    missing : dict of str to str
        Solvers with no estimate, and why (a closed form; the refined run failed).
    """
    out: list[dict] = [{} for _ in systems]
    missing: dict[str, str] = {}
    names = tuple(f"r{j + 1}" for j in range(systems[0].dof)) if len(systems) else ()
    for name, trs in runs.items():
        s = solver(name)
        refinement = s.refinement(preset)
        if refinement is None:
            continue
        finer, factor = refinement
        ok = [k for k, tr in enumerate(trs) if tr.success]
        if not ok:
            continue
        if s.own_grid:
            fines = run_many(name, [systems[k] for k in ok], None, finer)
        else:
            fines = [run(name, systems[k], trs[k].time, finer) for k in ok]
        for k, fine in zip(ok, fines):
            if not fine.success:
                missing[name] = f"its refined run failed: {fine.message}"
                continue
            coarse = trs[k]
            values = on_points(fine, coarse.time, systems[k].breakpoints()) if s.own_grid else fine.rates
            est = _estimate(coarse.rates, values, factor, names)
            blind = unresolved_outputs(systems[k], coarse.time, values, preset.bound) if s.own_grid else {}
            if blind:               # no claim at all: the worst output is among those it cannot see
                missing[name] = "; ".join(blind.values())
                est = est._replace(relative=math.nan, worst=next(iter(blind)),
                                   per_output={o: (math.nan if o in blind else e) for o, e in est.per_output.items()})
            out[k][name] = est
    return out, missing


_SUFFIX = {"t": 1e12, "g": 1e9, "meg": 1e6, "k": 1e3, "m": 1e-3, "u": 1e-6, "n": 1e-9, "p": 1e-12, "f": 1e-15}
_NUMBER = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?)(meg|[tgkmunpf])?[a-z]*$", re.IGNORECASE)


def spice_number(text: str) -> float:
    """A SPICE number: ``1e-3``, ``1m``, ``10meg`` (a unit after the suffix is ignored, as SPICE does).

    Parameters
    ----------
    text : str
        The number as written in a netlist.
    """
    match = _NUMBER.match(text.strip())
    if match is None:
        raise InputError(f"{text!r} is not a SPICE number")
    return float(match.group(1)) * _SUFFIX.get((match.group(2) or "").lower(), 1.0)


def refined_netlist(text: str) -> str:
    """*text* with every step of ngspice :data:`~analogy.solvers.transient.REFINE` times shorter:
    the ``.tran`` step cap and the :data:`~analogy.solvers.transient.STEP_TOLERANCES` that its
    ``.options`` set (REFINE³ times tighter), as :func:`~analogy.solvers.transient.refined` does
    for a preset. ``.control`` blocks and ``.print`` lines are left out: they change what is
    shown, not the steps.

    Parameters
    ----------
    text : str
        A netlist with one ``.tran``.
    """
    out, trans = [], 0
    for line in _as_written(text).splitlines():
        word = line.split()[0].lower() if line.split() else ""
        if word == ".options":
            parts = [line.split()[0]]
            for token in line.split()[1:]:
                key, eq, value = token.partition("=")
                if eq and key.lower() in STEP_TOLERANCES:
                    token = f"{key}={spice_number(value) / REFINE ** 3:.6g}"
                parts.append(token)
            line = " ".join(parts)
        elif word == ".tran":
            trans += 1
            tokens = line.split()
            flags = [t for t in tokens[1:] if not _NUMBER.match(t)]
            values = [spice_number(t) for t in tokens[1:] if _NUMBER.match(t)]
            if len(values) < 2:
                raise InputError(f"the netlist's .tran line needs TSTEP and TSTOP: {line.strip()!r}")
            step, stop = values[:2]
            start = values[2] if len(values) > 2 else 0.0
            cap = values[3] if len(values) > 3 else min(step, (stop - start) / 50)   # ngspice's default TMAX
            line = " ".join([tokens[0]] + [f"{x!r}" for x in (step, stop, start, cap / REFINE)] + flags)
        out.append(line)
    if trans != 1:
        raise InputError(f"analogy check judges a netlist with one .tran line, this one has {trans}")
    return "\n".join(out) + "\n"


def _saved(text: str) -> list[str]:
    names = [t for line in text.splitlines() if line.split()[:1] and line.split()[0].lower() == ".save"
             for t in line.split()[1:]]
    if not names:
        raise InputError("the netlist saves no vectors (.save): analogy check judges the saved vectors")
    return names


@dataclass(eq=False)
class NetlistEstimate(Tabular):
    """A netlist's saved vectors, each with its error estimated against its own peak.

    Attributes
    ----------
    time : ndarray
        The run's own time points.
    values : dict of str to ndarray
        The saved vectors as the netlist ran.
    estimates : dict of str to float
        Per vector, Richardson's estimate of max |error| over its own peak.
    steps : tuple of int
        Time points of the run and of its refined run.
    """

    time: np.ndarray
    values: dict
    estimates: dict
    steps: tuple = (0, 0)

    @property
    def worst(self) -> tuple[str, float]:
        """The vector with the largest estimate, and that estimate."""
        name = max(self.estimates, key=lambda k: self.estimates[k])
        return name, self.estimates[name]

    def __repr__(self) -> str:
        name, est = self.worst
        return f"<NetlistEstimate: {len(self.estimates)} vectors on {self.steps[0]} points, worst {name} {est:.2e}>"

    def table(self) -> str:
        """One line per saved vector: its peak and its estimated error over that peak."""
        lines = [f"{self.steps[0]} time points (refined run: {self.steps[1]}); errors estimated by the refined run, "
                 "each vector against its own peak", f"{'vector':<20}{'peak':>14}{'estimated':>12}"]
        for name, est in self.estimates.items():
            lines.append(f"{name:<20}{float(np.max(np.abs(self.values[name]))):>14.4e}{est:>12.2e}")
        return "\n".join(lines)

    def columns(self) -> dict[str, np.ndarray]:
        """``time`` and every saved vector."""
        return {"time": self.time, **self.values}

    def plot(self, path=None) -> "Figure":
        """The saved vectors against time, each labelled with its estimated error.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7.5, 4), constrained_layout=True)
        for name, y in self.values.items():
            ax.plot(self.time, y, label=f"{name}: estimated error {self.estimates[name]:.1e} of its peak")
        ax.set(xlabel="time [s]", ylabel="saved vector (V for a node, A for a current)", title="the netlist as it ran")
        ax.legend(fontsize=8)
        if path is not None:
            fig.savefig(path, dpi=120)
        return fig


def netlist_estimate(text: str, timeout: float | None = None) -> NetlistEstimate:
    """Run a transient netlist in ngspice as written and again with every step halved
    (:func:`refined_netlist`); Richardson's factor on their difference estimates each saved
    vector's error over its own peak.

    Both runs step onto every source corner, so the times they share bound the intervals
    on which the refined run is read between its points (:func:`on_points`).

    Parameters
    ----------
    text : str
        The netlist (what ``ngspice -b`` runs).
    timeout : float, optional
        Wall-time limit of each run [s].
    """
    from ..solvers.spice import session
    names = _saved(text)
    sess = session()
    first = sess.run(_as_written(text), names, timeout=timeout)
    second = sess.run(refined_netlist(text), names, timeout=timeout)
    t1, t2 = first["time"], second["time"]
    shared = np.intersect1d(t1, t2)
    factor = REFINE ** 2 / (REFINE ** 2 - 1)
    values, estimates = {}, {}
    for name in names:
        y1, y2 = np.asarray(first[name], float), np.asarray(second[name], float)
        fine = Trajectory("spice", t2, y2[:, None], y2[:, None])
        there = on_points(fine, t1, shared)[:, 0]
        top = float(np.max(np.abs(y2)))
        values[name] = y1
        estimates[name] = factor * float(np.max(np.abs(y1 - there))) / top if top > 0 else 0.0
    return NetlistEstimate(t1, values, estimates, (int(t1.size), int(t2.size)))


def _as_written(text: str) -> str:
    """*text* without its ``.control`` blocks and ``.print`` lines: the same steps, no printing."""
    out, control = [], False
    for line in text.splitlines():
        word = line.split()[0].lower() if line.split() else ""
        if word == ".control":
            control = True
        if control or word == ".print":
            control = control and word != ".endc"
            continue
        out.append(line)
    return "\n".join(out) + "\n"
