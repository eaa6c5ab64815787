"""The circuit of a node system as typed elements, read by the netlist writer, the diagrams and the benchmarks."""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from ..errors import InputError
from ..waveforms import Waveform
from .elements import ZERO_TOL, Element, element_table, laplacian_split, spice_value
from .node_system import stacked

__all__ = ["CurrentSource", "Coupling", "ChargeCapacitor", "BehaviouralCurrent", "Circuit",
           "circuit", "circuits", "current_sources", "describe_forces"]


class CurrentSource(NamedTuple):
    """A joint force as a current source: *scale*·f(t) flows into node *a* and out of node *b*."""

    name: str
    a: int
    b: int
    waveform: Waveform
    scale: float
    joint: int

    def __repr__(self) -> str:
        scale = "" if self.scale == 1.0 else f"{self.scale:g}*"
        where = f"into n{self.a}" + (f", out of n{self.b}" if self.b else "")
        return f"<{self.name} = {scale}{self.waveform.label()} A: force on joint {self.joint}, {where}>"


class Coupling(NamedTuple):
    """A negative element built from its positive magnitude behind an ideal 1:−1 coupling.

    A VCVS makes v_x = v_b − v_a, a zero-volt source senses the current of the positive
    element on x, and a CCCS drives that current from a to b: the terminals see the
    negative element (mechanically, a reversing pulley).
    """

    element: Element

    @property
    def name(self) -> str:
        """The name of the element it realizes."""
        return self.element.name

    @property
    def auxiliary_nodes(self) -> tuple[str, str]:
        """The coupling's own nodes: the VCVS output x and the sensed side y."""
        low = self.element.name.lower()
        return f"{low}_x", f"{low}_y"


class ChargeCapacitor(NamedTuple):
    """A behavioural capacitor between *a* and *b* whose charge is the SPICE expression *charge*."""

    name: str
    a: int
    b: int
    charge: str


class BehaviouralCurrent(NamedTuple):
    """A behavioural source driving the SPICE expression *current* into node *a*, out of node *b*."""

    name: str
    a: int
    b: int
    current: str


class Circuit(NamedTuple):
    """Every part of a node system's circuit, typed: the one description all writers read.

    Attributes
    ----------
    nodes : int
        Node count n; nodes are n1 … nN, and 0 is ground.
    elements : tuple of Element
        Elements written as they are (negative values included).
    couplings : tuple of Coupling
        Negative elements realized behind 1:−1 couplings (realizable circuits only).
    sources : tuple of CurrentSource
        The joint forces.
    behavioural : tuple
        Charge-defined capacitors and behavioural currents (nonlinear circuits).
    initial : tuple of (str, float)
        Node voltages at t = 0, auxiliary nodes included.
    t_stop : float
        End of the transient.
    comments : tuple of str
        What was built: robot, parameters, configuration, topology, forces.
    """

    nodes: int
    elements: tuple
    sources: tuple
    initial: tuple
    t_stop: float
    couplings: tuple = ()
    behavioural: tuple = ()
    comments: tuple = ()

    def __repr__(self) -> str:
        kinds = ", ".join(f"{sum(e.kind == k for e in self.parts)} {k}" for k in "CRL"
                          if any(e.kind == k for e in self.parts))
        extra = f", {len(self.couplings)} couplings" if self.couplings else ""
        return f"Circuit({self.nodes} nodes: {kinds}, {len(self.sources)} sources{extra})"

    @property
    def parts(self) -> tuple:
        """Every element, those behind couplings included, in netlist order."""
        return self.elements + tuple(c.element for c in self.couplings)

    @property
    def node_names(self) -> list[str]:
        """n1 … nN."""
        return [f"n{k + 1}" for k in range(self.nodes)]

    def element(self, name: str) -> Element | None:
        """The element called *name* (any case), or None.

        Parameters
        ----------
        name : str
            An element name such as ``C1_2``.
        """
        low = name.lower()
        return next((e for e in self.parts if e.name.lower() == low), None)


def describe_forces(forces: Sequence) -> str:
    """``F1 = step(1), F2 = sine(0, 0.5, 2) + step(-0.1)``: the joint forces as written.

    Parameters
    ----------
    forces : sequence of tuple of Waveform
        Per joint, the waveforms whose sum is its force.
    """
    terms = []
    for j, ws in enumerate(forces):
        text = " + ".join(w.label() for w in ws) if ws else "0"
        terms.append(f"F{j + 1} = {text}")
    return ", ".join(terms) or "none"


def _comments(system) -> tuple[str, ...]:
    info = system.info
    params = ", ".join(f"{k}={v!r}" for k, v in dict(info.get("parameters", {})).items())
    config = ", ".join(f"{k}={v!r}" for k, v in dict(info.get("configuration", {})).items())
    top = system.topology
    matrix = "[" + ", ".join("[" + ", ".join(f"{x:.6g}" for x in row) + "]" for row in top.matrix) + "]"
    r0 = system.initial_rates
    return (f"robot: {info.get('robot', 'custom')}",
            f"parameters: {params or 'none'}",
            f"configuration: {config or 'none'}",
            f"topology: {top.describe()}, T = {matrix}",
            f"forces: {describe_forces(system.forces)}",
            "initial rates: " + (", ".join(f"{x:g}" for x in r0) if np.any(r0) else "zero")
            + f"; t_stop = {system.t_stop:g} s")


def current_sources(system, zero_tol: float = ZERO_TOL) -> tuple[CurrentSource, ...]:
    """The joint forces as sources of node currents i = T⁻ᵀ·F.

    A joint whose column of T⁻ᵀ is +1 at one node and −1 at another (or nothing else)
    is one source between the two, as an actuator acting across two links; otherwise
    it is one grounded source per node, scaled by the column entry.

    Parameters
    ----------
    system : NodeSystem
        Its forces and current map T⁻ᵀ.
    zero_tol : float
        Relative tolerance under which a column entry counts as zero.
    """
    c = system.current_map
    out = []
    for j, waves in enumerate(system.forces):
        if not waves:
            continue
        col = c[:, j].tolist()
        floor = zero_tol * max(abs(x) for x in col)
        col = [0.0 if abs(x) <= floor else x for x in col]
        plus = [k for k, x in enumerate(col) if abs(x - 1.0) <= zero_tol]
        minus = [k for k, x in enumerate(col) if abs(x + 1.0) <= zero_tol]
        nz = [k for k, x in enumerate(col) if x != 0.0]
        two_terminal = len(plus) == 1 and len(minus) <= 1 and len(nz) == len(plus) + len(minus)
        for w_index, wave in enumerate(waves):
            suffix = "" if len(waves) == 1 else f"_{w_index + 1}"
            if two_terminal:
                b = minus[0] + 1 if minus else 0
                out.append(CurrentSource(f"I{j + 1}{suffix}", plus[0] + 1, b, wave, 1.0, j + 1))
            else:
                out += [CurrentSource(f"I{j + 1}{suffix}_n{k + 1}", k + 1, 0, wave, float(col[k]), j + 1)
                        for k in nz]
    return tuple(out)


def _check_dropped(mass: np.ndarray, kept: list[Element], zero_tol: float):
    """Refuse a circuit whose capacitors, without those under the tolerance, are singular."""
    grounded, floating = laplacian_split(mass, 0.0)
    n = mass.shape[0]
    rebuilt = np.zeros((n, n))
    for e in kept:
        if e.kind != "C":
            continue
        i, j = e.a - 1, e.b - 1
        rebuilt[i, i] += e.value
        if e.b:
            rebuilt[j, j] += e.value
            rebuilt[i, j] -= e.value
            rebuilt[j, i] -= e.value
    try:
        np.linalg.cholesky(rebuilt)
        return
    except np.linalg.LinAlgError:
        pass
    present = {(e.a, e.b) for e in kept if e.kind == "C"}
    scale = float(np.abs(mass).max())
    dropped = [(abs(grounded[i]), f"C{i + 1}", grounded[i]) for i in range(n)
               if grounded[i] != 0 and (i + 1, 0) not in present]
    dropped += [(abs(floating[i, j]), f"C{i + 1}_{j + 1}", floating[i, j]) for i in range(n)
                for j in range(i + 1, n) if floating[i, j] != 0 and (i + 1, j + 1) not in present]
    _, name, value = max(dropped) if dropped else (0, "a capacitor", 0.0)
    raise InputError(f"element {name} = {value:.3g} F is below the zero tolerance "
                     f"({zero_tol:g} of the largest node mass, {scale:.3g}) and the circuit "
                     "without it is singular: rescale the masses or lower zero_tol")


def circuit(system, zero_tol: float = ZERO_TOL, realizable: bool = False, describe: bool = True) -> Circuit:
    """The circuit of a linear node system.

    Parameters
    ----------
    system : NodeSystem
        The node matrices, forces, initial voltages and time span.
    zero_tol : float
        Relative tolerance under which an element is left out.
    realizable : bool
        Put each negative element behind a 1:−1 :class:`Coupling`.
    describe : bool
        Fill :attr:`Circuit.comments` (what was built), for netlist headers.

    Raises
    ------
    InputError
        If leaving out the capacitors under the tolerance makes the circuit singular.
    """
    if getattr(system, "kind", "linear") != "linear":
        raise InputError("only a linear node system has a circuit of constant elements")
    k = None if system.stiffness is None else system.stiffness[None]
    table, dropped = element_table(system.mass[None], system.damping[None], k, zero_tol, report=True)
    parts = [Element(kind, a, b, float(spice_value(kind, c[0])), float(c[0]))
             for kind, a, b, c in table if c[0] != 0.0]
    if dropped[0]:
        _check_dropped(system.mass, parts, zero_tol)
    v0 = system.initial_voltages
    initial = [(f"n{i + 1}", float(x)) for i, x in enumerate(v0)]
    couplings = ()
    if realizable:
        couplings = tuple(Coupling(e) for e in parts if e.value < 0)
        parts = [e for e in parts if e.value >= 0]
        for c in couplings:
            e = c.element
            across = (v0[e.b - 1] if e.b else 0.0) - v0[e.a - 1]
            initial += [(node, float(across)) for node in c.auxiliary_nodes]
    return Circuit(system.dof, tuple(parts), current_sources(system, zero_tol), tuple(initial),
                   system.t_stop, couplings, (), _comments(system) if describe else ())


def circuits(systems: Sequence, zero_tol: float = ZERO_TOL) -> list[Circuit]:
    """The circuits of many linear systems, their elements split as one stack per size.

    Systems that share forces and topology share their sources, derived once.

    Parameters
    ----------
    systems : sequence of NodeSystem
        Systems to describe.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    out: list = [None] * len(systems)
    kinds: dict = {}
    for k, s in enumerate(systems):
        kinds.setdefault((s.dof, s.stiffness is None), []).append(k)
    sources: dict = {}
    for (_, no_springs), idx in kinds.items():
        group = [systems[k] for k in idx]
        table, dropped = element_table(stacked(group, "mass"), stacked(group, "damping"),
                                       None if no_springs else stacked(group, "stiffness"), zero_tol,
                                       report=True)
        columns = [(kind, a, b, spice_value(kind, c).tolist(), c.tolist()) for kind, a, b, c in table]
        names = [f"n{i + 1}" for i in range(systems[idx[0]].dof)]
        for j, k in enumerate(idx):
            s = systems[k]
            parts = tuple([Element(kind, a, b, values[j], coef[j])
                           for kind, a, b, values, coef in columns if coef[j] != 0.0])
            key = (id(s.forces), id(s.topology))
            src = sources.get(key)
            if src is None:
                src = sources[key] = current_sources(s, zero_tol)
            if dropped[j]:                  # a capacitor under the tolerance: is the rest singular?
                _check_dropped(s.mass, list(parts), zero_tol)
            out[k] = Circuit(s.dof, parts, src, tuple(zip(names, s.initial_voltages.tolist())), s.t_stop)
    return out
