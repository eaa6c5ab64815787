"""A netlist's error estimated without a reference: run as written and with every step halved (Richardson)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..circuit.spice_numbers import SPICE_NUMBER, spice_number
from ..errors import InputError, SimulationError
from ..results.output import Tabular
from ..results.trajectory import Trajectory
from ..solvers.transient import NGSPICE_STEP_TOLERANCES, REFINE, STEP_TOLERANCES
from .estimate import REFINED_STEPS, on_points

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["netlist_estimate", "NetlistEstimate", "refined_netlist", "spice_number", "Netlist"]

_OPTIONS = (".options", ".option", ".opt")


@dataclass(frozen=True)
class Netlist:
    """A transient netlist as ngspice reads it: its title, then its logical lines (a ``+`` line
    joined to the one before, comments and ``.control`` blocks left out, ``.print`` too: they
    change what is shown, not the steps).

    Attributes
    ----------
    title : str
        The first line (ngspice's title, whatever it says).
    lines : tuple of str
        The logical lines after it, ``.end`` included.
    """

    title: str
    lines: tuple

    @classmethod
    def parse(cls, text: str) -> "Netlist":
        """Read *text*; one sentence if it has no transient analysis ngspice can run as written.

        Parameters
        ----------
        text : str
            The netlist.
        """
        raw = text.splitlines()
        if not raw:
            raise InputError("the netlist is empty")
        lines: list[str] = []
        control = False
        for number, line in enumerate(raw[1:], start=2):
            body = re.split(r"(?:^|\s)[$;]", line.strip(), maxsplit=1)[0].strip()    # an inline comment
            word = body.split()[0].lower() if body else ""
            if word == ".control" or control:
                control = word != ".endc"
                continue
            if not body or body.startswith("*") or word == ".print":
                continue
            if not body.isascii():
                raise InputError(f"line {number} of the netlist has characters ngspice does not read: {line.strip()!r}")
            if body.startswith("+"):
                if not lines:
                    raise InputError(f"line {number} continues no line: {line.strip()!r}")
                lines[-1] += " " + body[1:].strip()
                continue
            lines.append(body)
        title = raw[0].encode("ascii", "replace").decode()
        return cls(title, tuple(lines))

    def words(self, *names: str) -> list[list[str]]:
        """The lines whose first word is one of *names* (lower case), split into words.

        Parameters
        ----------
        *names : str
            Dot commands such as ``.tran``.
        """
        return [line.split() for line in self.lines if line.split()[0].lower() in names]

    def tran(self) -> tuple[float, float, float, float | None, list[str]]:
        """(TSTEP, TSTOP, TSTART, TMAX or None, flags) of the one ``.tran`` line."""
        trans = self.words(".tran")
        if len(trans) != 1:
            raise InputError(f"analogy check judges a netlist with one .tran line (outside .control), "
                             f"this one has {len(trans)}")
        tokens = trans[0][1:]
        values = [spice_number(t) for t in tokens if SPICE_NUMBER.match(t)]
        flags = [t for t in tokens if not SPICE_NUMBER.match(t)]
        if len(values) < 2 or not values[0] > 0 or not values[1] > (values[2] if len(values) > 2 else 0.0):
            raise InputError(f"the .tran line needs TSTEP > 0 and TSTOP past TSTART: {' '.join(trans[0])!r}")
        start = values[2] if len(values) > 2 else 0.0
        return values[0], values[1], start, values[3] if len(values) > 3 else None, flags

    def saved(self) -> list[str]:
        """The vectors its ``.save`` lines name (``i(V1)`` as ngspice keeps it, ``v1#branch``)."""
        names = [t for words in self.words(".save") for t in words[1:]]
        if not names:
            raise InputError("the netlist saves no vectors (.save): analogy check judges the saved vectors")
        if any(n.lower() == "all" for n in names):
            raise InputError("analogy check judges named vectors, and '.save all' names none: list them "
                             "(v(n1) i(V1) @C1[i] …)")
        out = []
        for n in names:
            branch = re.fullmatch(r"i\((\w+)\)", n, re.IGNORECASE)
            out.append(f"{branch.group(1).lower()}#branch" if branch else n)
        return out

    def text(self, lines=None) -> str:
        """The netlist ngspice is given: the title and *lines* (default its own).

        Parameters
        ----------
        lines : sequence of str, optional
            Logical lines to write after the title instead of its own.
        """
        return "\n".join([self.title, *(self.lines if lines is None else lines)]) + "\n"


def refined_netlist(text: str, tolerances: bool = True) -> str:
    """*text* with every step of ngspice :data:`~analogy.solvers.transient.REFINE` times shorter,
    as :func:`~analogy.solvers.transient.refined` does for a preset: the ``.tran`` step cap
    (ngspice's own, min(TSTEP, (TSTOP − TSTART)/50), where it has none) and the
    :data:`~analogy.solvers.transient.STEP_TOLERANCES`, REFINE³ times tighter, ngspice's own
    values where ``.options`` (or ``.option``, ``.opt``) leaves them out. abstol is kept, as in
    process: where it binds it sits at the rounding floor, under which the step collapses.

    Parameters
    ----------
    text : str
        A netlist with one ``.tran``.
    tolerances : bool
        Tighten the step tolerances too (False: the step cap alone).
    """
    net = Netlist.parse(text)
    step, stop, start, cap, flags = net.tran()
    cap = min(step, (stop - start) / 50) if cap is None else cap
    lines, given = [], set()
    for line in net.lines:
        words = re.sub(r"\s*=\s*", "=", line).split()
        head = words[0].lower()
        if head in _OPTIONS:
            parts = [words[0]]
            for token in words[1:]:
                key, eq, value = token.partition("=")
                if eq and tolerances and key.lower() in STEP_TOLERANCES:
                    given.add(key.lower())
                    token = f"{key}={spice_number(value) / REFINE ** 3:.6g}"
                parts.append(token)
            line = " ".join(parts)
        elif head == ".tran":
            line = " ".join([words[0]] + [f"{x!r}" for x in (step, stop, start, cap / REFINE)] + flags)
        lines.append(line)
    missing = [f"{k}={v / REFINE ** 3:.6g}" for k, v in NGSPICE_STEP_TOLERANCES.items()
               if k not in given and tolerances]
    if missing:
        at = next(k for k, line in enumerate(lines) if line.split()[0].lower() == ".tran")
        lines.insert(at, ".options " + " ".join(missing))
    return net.text(lines)


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
        from matplotlib.figure import Figure
        from ..results.plots import save_figure
        fig = Figure(figsize=(7.5, 4), layout="constrained")
        ax = fig.subplots()
        for name, y in self.values.items():
            ax.plot(self.time, y, label=f"{name}: estimated error {self.estimates[name]:.1e} of its peak")
        ax.set(xlabel="time [s]", ylabel="saved vector (V for a node, A for a current)", title="the netlist as it ran")
        ax.legend(fontsize=8)
        return save_figure(fig, path)


def netlist_estimate(text: str, timeout: float | None = None) -> NetlistEstimate:
    """Run a transient netlist in ngspice as written and again with every step halved
    (:func:`refined_netlist`); Richardson's factor on their difference estimates each saved
    vector's error over its own peak.

    Both runs step onto every source corner, so the times they share bound the intervals
    on which the refined run is read between its points
    (:func:`~analogy.study.estimate.on_points`).

    Parameters
    ----------
    text : str
        The netlist (what ``ngspice -b`` runs).
    timeout : float, optional
        Wall-time limit of each run [s].
    """
    from ..solvers.spice import session
    net = Netlist.parse(text)
    net.tran()
    names = net.saved()
    sess = session()
    first = sess.run(net.text(), names, timeout=timeout)
    try:
        second = sess.run(refined_netlist(text), names, timeout=timeout)
    except SimulationError:         # tighter tolerances under rounding collapse the step: the cap alone
        try:
            second = sess.run(refined_netlist(text, tolerances=False), names, timeout=timeout)
        except SimulationError as exc:
            raise SimulationError(f"the netlist ran, but its refined run (every step halved) did not: {exc}") from None
    t1, t2 = first["time"], second["time"]
    if t2.size < REFINED_STEPS * REFINE * t1.size:
        raise SimulationError(f"the netlist ran, but its refined run took {t2.size:,} points against {t1.size:,}, "
                              f"not about {REFINE:g} times as many: its steps are not set by the step cap, and "
                              "the tolerances that set them collapse when tightened")
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
