"""Symbolic nodal analysis of an element list: J = G·v + C·s·v + Γ·v/s, for any number of nodes."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ..errors import InputError

__all__ = ["Nodal", "nodal_analysis", "KINDS"]

#: Element kinds: what the value of each is, and which nodal matrix it enters.
KINDS = {
    "G": "conductance [S], enters G",
    "R": "resistance [Ω], enters G as 1/R",
    "C": "capacitance [F], enters C",
    "L": "inductance [H], enters Γ as 1/L",
    "I": "current source [A], driven into node a and drawn from node b, enters J",
}


@dataclass(frozen=True)
class Nodal:
    """Nodal matrices of a circuit with nodes 1..n (0 is ground).

    The nodal equations are J = G·v + C·s·v + Γ·v/s, where v holds the node voltages,
    J the current injected into each node by the sources and s is the Laplace operator.
    """

    G: sp.Matrix
    C: sp.Matrix
    Gamma: sp.Matrix
    J: sp.Matrix

    def currents(self, v, s) -> sp.Matrix:
        """The element currents leaving each node, G·v + C·s·v + Γ·v/s (equal to J).

        Parameters
        ----------
        v : sympy Matrix
            Node voltages.
        s : sympy Symbol
            The Laplace variable.
        """
        v = sp.Matrix(v)
        return self.G * v + self.C * s * v + self.Gamma * v / s


def _fields(element):
    if hasattr(element, "kind"):            # an Element (itself a named tuple)
        return element.kind, element.a, element.b, element.value
    if isinstance(element, (tuple, list)):
        if len(element) != 4:
            raise InputError(f"an element is (kind, node_a, node_b, value), got {element!r}")
        return tuple(element)
    try:
        return element.kind, element.a, element.b, element.value
    except AttributeError:
        raise InputError(f"an element is (kind, node_a, node_b, value), got {element!r}") from None


def nodal_analysis(elements, n: int | None = None) -> Nodal:
    """Stamp every (kind, node_a, node_b, value) element into G, C, Γ and J.

    A two-terminal admittance y between nodes a and b adds y to the (a, a) and (b, b)
    entries and −y to (a, b) and (b, a); node 0 (ground) has no row. A current source
    ("I", a, b, i) adds i to J_a and −i to J_b. *n* defaults to the highest node used.
    Objects with ``kind``, ``a``, ``b`` and ``value`` attributes (such as
    :class:`analogy.circuit.elements.Element`) are accepted too.

    Parameters
    ----------
    elements : iterable
        Elements, or (kind, node_a, node_b, value) tuples.
    n : int, optional
        Node count (default: the highest node named).
    """
    items = [_fields(e) for e in elements]
    for kind, a, b, _ in items:
        if kind not in KINDS:
            raise InputError(f"unknown element kind {kind!r}: use one of {', '.join(KINDS)}")
        if not (isinstance(a, int) and isinstance(b, int)) or a < 0 or b < 0:
            raise InputError(f"element nodes must be integers >= 0, got ({a!r}, {b!r})")
        if a == b:
            raise InputError(f"element {kind} connects node {a} to itself")
    used = max((max(a, b) for _, a, b, _ in items), default=0)
    n = used if n is None else n
    if used > n:
        raise InputError(f"an element uses node {used} but the circuit has {n} nodes")
    mats = {"G": sp.zeros(n, n), "C": sp.zeros(n, n), "Gamma": sp.zeros(n, n)}
    injected = sp.zeros(n, 1)
    for kind, a, b, value in items:
        value = sp.sympify(value)
        if kind == "I":
            if a:
                injected[a - 1] += value
            if b:
                injected[b - 1] -= value
            continue
        target, y = {"G": ("G", value), "R": ("G", 1 / value), "C": ("C", value),
                     "L": ("Gamma", 1 / value)}[kind]
        m = mats[target]
        for p in (a, b):
            if p:
                m[p - 1, p - 1] += y
        if a and b:
            m[a - 1, b - 1] -= y
            m[b - 1, a - 1] -= y
    return Nodal(mats["G"], mats["C"], mats["Gamma"], injected)
