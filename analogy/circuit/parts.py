"""Typed parts of a circuit (elements' companions: sources, couplings, behavioural parts) and the rules that place them."""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from ..waveforms import Waveform
from .elements import ZERO_TOL, Element

__all__ = ["CurrentSource", "Coupling", "ChargeCapacitor", "BehaviouralCurrent", "ConstraintCurrent", "BehaviouralVoltage",
           "Integrator",
           "Circuit", "current_sources", "describe_forces", "comments"]


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
    """A capacitor between *a* and *b* holding the charge *charge* (a SPICE expression), Q(0) = *initial*.

    Its current, from a to b, is dQ/dt: for Q = c(x)·(v_a − v_b), c·d(v_a − v_b)/dt + (dc/dt)·(v_a − v_b).
    ngspice's ``C … Q={…}`` form carries that current but starts from zero charge
    whatever ``.ic`` says, so it is written when Q(0) = 0. Otherwise the charge is
    written as a follower: a behavioural voltage source sets a node to Q, a linear 1 F
    capacitor on that node, starting at Q(0), carries dQ/dt, and a current-controlled
    source mirrors that current between a and b.
    """

    name: str
    a: int
    b: int
    charge: str
    initial: float = 0.0

    @property
    def follower_nodes(self) -> tuple[str, str]:
        """The node held at Q by the behavioural source, and the node of the 1 F capacitor."""
        return f"mq{self.name}", f"mc{self.name}"


class BehaviouralCurrent(NamedTuple):
    """A behavioural source driving the SPICE expression *current* into node *a*, out of node *b*."""

    name: str
    a: int
    b: int
    current: str


class ConstraintCurrent(BehaviouralCurrent):
    """A loop-closure branch: J(x)·v + α·Φ(x) into a multiplier's node, which nothing else
    touches, so that Kirchhoff's current law there is the constraint (closed chains)."""


class BehaviouralVoltage(NamedTuple):
    """A node *name* held at the SPICE expression *voltage* (a quantity others share), *initial* at t = 0;
    *output*: the quantity is one of the run's outputs (a contact's force), saved and reported."""

    name: str
    voltage: str
    initial: float = 0.0
    output: bool = False


class Integrator(NamedTuple):
    """A state node x_k = ∫ v(n_k) dt: a 1 F capacitor charged by a current equal to the node's rate.

    *reported*: the node is one of the system's positions; a closed chain's passive joints
    are integrated too, and saved apart (:attr:`Circuit.monitors`).
    """

    node: int
    reported: bool = True

    @property
    def name(self) -> str:
        """The state node's name, ``x1`` …"""
        return f"x{self.node}"


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
        Charge-defined capacitors, behavioural currents and integrators (nonlinear circuits).
    initial : tuple of (str, float)
        Node voltages at t = 0, auxiliary nodes included.
    t_stop : float
        End of the transient.
    comments : tuple of str
        What was built: robot, parameters, configuration, topology, forces.
    robot : str
        The robot's name, for titles.
    joints : tuple of str
        Per joint, its own name (a URDF's), for comments beside the sources; empty: q1 … qn.

    A circuit is what is built, not how it is simulated: the spice solver derives its
    settings from the system (:mod:`analogy.solvers.transient`).
    """

    nodes: int
    elements: tuple
    sources: tuple
    initial: tuple
    t_stop: float
    couplings: tuple = ()
    behavioural: tuple = ()
    comments: tuple = ()
    robot: str = "custom"
    joints: tuple = ()

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

    @property
    def state_nodes(self) -> list[str]:
        """The integrators' nodes x1 … (the system's positions), in a nonlinear circuit."""
        return [p.name for p in self.behavioural if isinstance(p, Integrator) and p.reported]

    @property
    def constraints(self) -> int:
        """Loop-closure equations: nodes whose only branch is a :class:`ConstraintCurrent`."""
        return sum(isinstance(p, ConstraintCurrent) for p in self.behavioural)

    @property
    def monitors(self) -> list[str]:
        """Integrator nodes that are not the system's positions: a closed chain's passive joints."""
        return [p.name for p in self.behavioural if isinstance(p, Integrator) and not p.reported]

    @property
    def outputs(self) -> dict[str, float]:
        """Behavioural nodes that are outputs of the run (contact forces ``f_<contact>``), with their values at t = 0."""
        return {p.name: p.initial for p in self.behavioural if isinstance(p, BehaviouralVoltage) and p.output}

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


def comments(system) -> tuple[str, ...]:
    """What was built, for netlist headers: robot, parameters, configuration, topology, inputs.

    Parameters
    ----------
    system : NodeDynamics
        A node system.
    """
    made = system.provenance
    params = ", ".join(f"{k}={v!r}" for k, v in made.parameters.items())
    config = ", ".join(f"{k}={v!r}" for k, v in made.configuration.items())
    top = system.topology
    matrix = "[" + ", ".join("[" + ", ".join(f"{x:.6g}" for x in row) + "]" for row in top.matrix) + "]"
    r0 = system.initial_rates
    kind = system.kind
    dynamics = ("dynamics: linear, the circuit at the configuration above" if kind == "linear" else
                "dynamics: nonlinear: M'(x) as charge-defined capacitors Q = c(x)*(v_a - v_b), "
                "velocity terms and gravity as behavioural currents, x = integral of v on nodes x1...")
    named = () if not made.joints else \
        ("joints: " + ", ".join(f"q{k + 1} = {name}" for k, name in enumerate(made.joints))
         + "; F_k and r_k are joint k's force and rate",)
    return (f"robot: {made.robot}",) + named + (
            f"parameters: {params or 'none'}",
            f"configuration: {config or 'none'}",
            f"topology: {top.describe()}, T = {matrix}",
            f"forces: {describe_forces(system.forces)}",
            "initial rates: " + (", ".join(f"{x:g}" for x in r0) if np.any(r0) else "zero")
            + f"; t_stop = {system.t_stop:g} s", dynamics) + tuple(f"warning: {note}" for note in made.notes)


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
    c = np.asarray(system.current_map, dtype=float)
    c = np.where(np.abs(c) <= zero_tol * np.max(np.abs(c), axis=0), 0.0, c)     # each column's own floor
    plus, minus, nonzero = np.abs(c - 1.0) <= zero_tol, np.abs(c + 1.0) <= zero_tol, c != 0.0
    out = []
    for j, waves in enumerate(system.forces):
        if not waves:
            continue
        ups, downs, nz = (np.flatnonzero(x[:, j]).tolist() for x in (plus, minus, nonzero))
        two_terminal = len(ups) == 1 and len(downs) <= 1 and len(nz) == len(ups) + len(downs)
        entries = c[nz, j].tolist()
        for w_index, wave in enumerate(waves):
            suffix = "" if len(waves) == 1 else f"_{w_index + 1}"
            if two_terminal:
                b = downs[0] + 1 if downs else 0
                out.append(CurrentSource(f"I{j + 1}{suffix}", ups[0] + 1, b, wave, 1.0, j + 1))
            else:
                out += [CurrentSource(f"I{j + 1}{suffix}_n{k + 1}", k + 1, 0, wave, x, j + 1)
                        for k, x in zip(nz, entries)]
    return tuple(out)
