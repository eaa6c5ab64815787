"""The circuit of a node system as typed parts, read by the netlist writer, the diagrams and the benchmarks."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import InputError
from .elements import ZERO_TOL, Element, element_table, laplacian_split, spice_value
from .node_stack import NodeStack
from .parts import (
    BehaviouralCurrent,
    BehaviouralVoltage,
    ChargeCapacitor,
    Circuit,
    Coupling,
    CurrentSource,
    Integrator,
    comments,
    current_sources,
    describe_forces,
)

__all__ = ["CurrentSource", "Coupling", "ChargeCapacitor", "BehaviouralCurrent", "BehaviouralVoltage", "Integrator",
           "Circuit", "circuit", "circuits", "element_columns", "element_arrays", "row_elements", "current_sources", "describe_forces",
           "comments"]


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
                     f"({zero_tol:g} of the node masses it is summed from; the largest is {scale:.3g}) "
                     "and the circuit without it is singular: rescale the masses or lower zero_tol")


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
    if realizable and system.kind != "linear":
        raise InputError("a realizable circuit (negative elements behind 1:-1 couplings) is the linear circuit's: "
                         "the nonlinear circuit's capacitances are expressions of the pose")
    if system.kind != "linear" and system.model is not None and system.model.closed_chain:
        from .constrained_circuit import constrained_circuit  # sympy: only for nonlinear circuits
        return constrained_circuit(system, zero_tol, describe)
    if system.kind != "linear":
        from .nonlinear_circuit import (
            nonlinear_circuit,  # sympy: only for nonlinear circuits
        )
        return nonlinear_circuit(system, zero_tol, describe)
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
            # the VCVS output x holds its value by itself; KLU (ngspice 46) refuses an .ic on a
            # node with no diagonal entry in its matrix, and x has none
            initial.append((c.auxiliary_nodes[1], float(across)))
    return Circuit(system.dof, tuple(parts), current_sources(system, zero_tol), tuple(initial),
                   system.t_stop, couplings, (), comments(system) if describe else (),
                   system.provenance.robot, system.provenance.joints or ())


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
        group = NodeStack.of(systems) if len(idx) == len(systems) else NodeStack([systems[k] for k in idx])
        columns = element_columns(group, zero_tol)
        names = [f"n{i + 1}" for i in range(group.dof)]
        shared = group.shares_inputs
        for j, k in enumerate(idx):
            s = systems[k]
            key = (group.dof, no_springs) if shared else s.inputs_key[:2]
            src = sources.get(key)
            if src is None:
                src = sources[key] = current_sources(s, zero_tol)
            out[k] = Circuit(s.dof, row_elements(columns, j), src, tuple(zip(names, s.initial_voltages.tolist())),
                             s.t_stop)
    return out


def element_columns(stack: NodeStack, zero_tol: float = ZERO_TOL) -> list[tuple]:
    """A stack's elements as columns, one per element position in netlist order: (kind, a, b, SPICE
    values, coefficients), the last two one per row (coefficient exactly 0 where the row has no such
    element). A row whose capacitors, without those under the tolerance, are singular is refused.

    Parameters
    ----------
    stack : NodeStack
        Systems of one size, all with springs or none.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    places, values, coefs = element_arrays(stack, zero_tol)
    return [(kind, a, b, v, c) for (kind, a, b), v, c in zip(places, values.T.tolist(), coefs.T.tolist())]


def element_arrays(stack: NodeStack, zero_tol: float = ZERO_TOL) -> tuple[tuple, np.ndarray, np.ndarray]:
    """:func:`element_columns` as arrays: the positions (kind, a, b) in netlist order, and each row's
    SPICE values and coefficients, shape (count, positions). A row whose capacitors, without those
    under the tolerance, are singular is refused.

    Parameters
    ----------
    stack : NodeStack
        Systems of one size, all with springs or none.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    places, values, coefs, dropped = stack.rowwise(f"elements at {zero_tol!r}", lambda s: _element_rows(s, zero_tol))
    for j in np.flatnonzero(dropped).tolist():      # a capacitor under the tolerance: is the rest singular?
        kept = [Element(kind, a, b, v, c) for (kind, a, b), v, c in zip(places, values[j].tolist(), coefs[j].tolist())
                if c != 0.0]
        _check_dropped(stack[j].mass, kept, zero_tol)
    return places, values, coefs


def _element_rows(stack: NodeStack, zero_tol: float) -> tuple:
    """:func:`element_table` of *stack*: positions, SPICE values and coefficients (one row per system)."""
    table, dropped = element_table(stack.mass, stack.damping, None if stack.springless else stack.stiffness,
                                   zero_tol, report=True)
    places = tuple((kind, a, b) for kind, a, b, _ in table)
    coefs = np.stack([c for *_, c in table], axis=1) if table else np.zeros((len(stack), 0))
    values = np.stack([spice_value(kind, c) for kind, _, _, c in table], axis=1) if table else coefs
    return places, values, coefs, dropped


def row_elements(columns: list[tuple], row: int) -> tuple[Element, ...]:
    """Row *row*'s elements from :func:`element_columns`.

    Parameters
    ----------
    columns : list of tuple
        The stack's element columns.
    row : int
        The row.
    """
    return tuple([Element(kind, a, b, values[row], coef[row]) for kind, a, b, values, coef in columns
                  if coef[row] != 0.0])
