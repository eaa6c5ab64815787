"""Circuit elements of a node system: grounded and floating (MP) capacitors, resistors, inductors."""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np

from ..errors import InputError
from ..small_linalg import axis_max, axis_sum

__all__ = ["Element", "ElementKind", "ELEMENT_KINDS", "elements", "element_table", "spice_value", "mp_capacitance", "laplacian_split", "point_operations", "first_point_operations", "NONLINEAR_POINT_COST",
           "ZERO_TOL"]

#: Default relative tolerance below which an element value counts as zero.
ZERO_TOL = 1e-12

_UNITS = {"C": "F", "R": "Ohm", "L": "H"}
_MEANING = {"C": "mass", "R": "damper", "L": "spring"}


ElementKind = Literal["C", "R", "L"]
ELEMENT_KINDS: tuple[ElementKind, ...] = ("C", "R", "L")


class Element(NamedTuple):
    """One two-terminal element between node *a* and node *b* (0 is ground).

    *value* is the SPICE value: capacitance [F] = mass, resistance [Ω] = 1/damping,
    inductance [H] = 1/stiffness. *coefficient* is the mechanical value it came from.
    """

    kind: ElementKind
    a: int
    b: int
    value: float
    coefficient: float

    @property
    def name(self) -> str:
        """Netlist name: ``C1`` (grounded at node 1) or ``C1_2`` (between nodes 1 and 2)."""
        return f"{self.kind}{self.a}" if self.b == 0 else f"{self.kind}{self.a}_{self.b}"

    @property
    def floating(self) -> bool:
        """True for an element between two nodes: a capacitor here is an MP model."""
        return self.b != 0

    @property
    def unit(self) -> str:
        """SI unit of :attr:`value`."""
        return _UNITS[self.kind]

    @property
    def meaning(self) -> str:
        """The mechanical element it stands for: mass, MP model, damper or spring."""
        if self.kind == "C" and self.floating:
            return "MP model"
        return _MEANING[self.kind]

    def __repr__(self) -> str:
        where = f"n{self.a}-ground" if self.b == 0 else f"n{self.a}-n{self.b}"
        return f"<{self.name} {self.value:.6g} {self.unit}: {self.meaning}, {where}>"


def laplacian_split(matrix: np.ndarray, zero_tol: float = ZERO_TOL,
                    report: bool = False) -> tuple[np.ndarray, ...]:
    """Split a symmetric node matrix X into grounded x_i = Σ_j X_ij and floating x_ij = −X_ij.

    X is recovered as X_ii = x_i + Σ_{j≠i} x_ij and X_ij = −x_ij. A grounded value with
    |x_i| ≤ zero_tol·Σ_j|X_ij| (the scale of the row it is summed from), and a floating
    one with |x_ij| ≤ zero_tol·√(Σ_k|X_ik|·Σ_k|X_jk|), is rounding: an exact zero. A stack of matrices
    (..., n, n) is split matrix by matrix.

    Parameters
    ----------
    matrix : ndarray, shape (..., n, n)
        A symmetric node matrix, or a stack of them.
    zero_tol : float
        Relative tolerance under which a value counts as zero.
    report : bool
        Also return, per matrix, whether a nonzero value was set to zero.

    Returns
    -------
    grounded : ndarray, shape (..., n)
    floating : ndarray, shape (..., n, n), symmetric with zero diagonal
    dropped : ndarray of bool, shape (...), with *report* only
    """
    x = np.asarray(matrix, dtype=float)
    n = x.shape[-1]
    with np.errstate(over="ignore"):        # a row sum past 1.8e308 is refused by the circuit's checks
        grounded = axis_sum(x, -1)
    floating = -x
    floating[..., range(n), range(n)] = 0.0
    # Row-relative: a value is rounding only against the entries it was summed from, so a node
    # whose own scale is far below the largest (a soft spring beside a stiff one) keeps its elements.
    with np.errstate(over="ignore", invalid="ignore"):      # past the float range is refused later
        rows = axis_sum(np.abs(x), -1)
        root = np.sqrt(rows)                                  # √a·√b: no overflow where a·b would
        floor_g = zero_tol * rows
        floor_f = zero_tol * root[..., :, None] * root[..., None, :]
    small_g = np.abs(grounded) <= floor_g
    small_f = np.abs(floating) <= floor_f
    if report:
        dropped = axis_max(small_g & (grounded != 0), -1) | \
            axis_max((small_f & (floating != 0)).reshape(x.shape[:-2] + (n * n,)), -1)
    grounded[small_g] = 0.0
    floating[small_f] = 0.0
    return (grounded, floating, dropped) if report else (grounded, floating)


def mp_capacitance(node_mass: np.ndarray, zero_tol: float = ZERO_TOL) -> np.ndarray:
    """Floating capacitances c_ij = −M'_ij: the masses of the MP models between nodes.

    Parameters
    ----------
    node_mass : ndarray
        The node mass matrix M'.
    zero_tol : float
        Relative tolerance under which a value counts as zero.
    """
    return laplacian_split(node_mass, zero_tol)[1]


def element_table(mass, damping, stiffness=None, zero_tol: float = ZERO_TOL,
                  report: bool = False) -> list[tuple] | tuple[list[tuple], np.ndarray]:
    """Every element position of a stack of node matrices, in netlist order.

    Returns a list of (kind, a, b, coefficients): per node then per pair, C then R
    then L, with the mechanical coefficient of each system in the stack (shape (count,),
    exactly 0 where the element is absent).

    Parameters
    ----------
    mass : ndarray, shape (count, n, n)
        Node mass matrices M'.
    damping : ndarray, shape (count, n, n)
        Node damping matrices B'.
    stiffness : ndarray, shape (count, n, n), optional
        Node stiffness matrices K'.
    zero_tol : float
        Relative tolerance under which an element is left out.
    report : bool
        Also return, per system, whether a nonzero capacitor was left out.
    """
    table = []
    dropped = None
    for kind, mat in (("C", mass), ("R", damping), ("L", stiffness)):
        if mat is None:
            continue
        if kind == "C" and report:
            grounded, floating, dropped = laplacian_split(mat, zero_tol, report=True)
        else:
            grounded, floating = laplacian_split(mat, zero_tol)
        n = grounded.shape[-1]
        for values, what in ((grounded, "a row sum of its node matrix"), (spice_value(kind, grounded), "1/value"),
                             (spice_value(kind, floating), "1/value")):
            if not np.all(np.isfinite(values)):
                i = int(np.argwhere(~np.isfinite(values))[0][1]) + 1
                raise InputError(f"an element {kind} at node {i} ({what}) leaves the floating-point range: "
                                 "rescale the masses, dampers or springs")
        table += [(kind, i + 1, 0, grounded[:, i]) for i in range(n)]
        table += [(kind, i + 1, j + 1, floating[:, i, j]) for i in range(n) for j in range(i + 1, n)]
    return (table, dropped) if report else table


def spice_value(kind: str, coefficient) -> np.ndarray:
    """The SPICE value of a mechanical coefficient: C = mass, R = 1/damping, L = 1/stiffness.

    Works on arrays; a zero coefficient (no element) gives 0.

    Parameters
    ----------
    kind : {"C", "R", "L"}
        Element kind.
    coefficient : float or ndarray
        Mass, damping or stiffness.
    """
    c = np.asarray(coefficient, dtype=float)
    if kind == "C":
        return c
    with np.errstate(over="ignore"):            # 1/5e-324 is inf, which element_table refuses
        return np.divide(1.0, c, out=np.zeros_like(c), where=c != 0)


def elements(system, zero_tol: float = ZERO_TOL) -> list[Element]:
    """All non-zero elements of *system*: per node then per pair, C then R then L.

    Negative values are kept: a negative floating capacitor is legitimate physics
    (an MP model whose mass opposes the relative acceleration of its terminals).

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    k = None if system.stiffness is None else system.stiffness[None]
    return [Element(kind, a, b, float(spice_value(kind, c[0])), float(c[0]))
            for kind, a, b, c in element_table(system.mass[None], system.damping[None], k, zero_tol)
            if c[0] != 0.0]


#: What one time point of a nonlinear circuit costs, in units of a dense LU's n³: its charge-defined
#: capacitors and behavioural sources are evaluated with their derivatives at every Newton step.
#: Measured at accurate under ngspice 39 on the planar serial arms: 17 µs a point for serial2, 38 µs
#: for serial3, 0.11 ms for serial4 and 1.6 ms for serial10, about 1.6 µs·n³, or 270 units of 5.9 ns.
NONLINEAR_POINT_COST = 270.0


def point_operations(system) -> float:
    """The operations of one SPICE time point of *system*'s circuit: Σᵢ cᵢ².

    cᵢ counts the floating elements at node i, from M', B' and K' together, the nodes that node i's
    parts couple it to: a sparse LU whose fill stays inside that pattern costs Σᵢ cᵢ²
    (n³ for a dense M', n for a diagonal one), and it is refactored at every Newton
    step. A nonlinear circuit couples every node through M'(x), and its parts are expressions:
    :data:`NONLINEAR_POINT_COST`·n³.

    Parameters
    ----------
    system : NodeSystem or NonlinearNodeSystem
        A node system.
    """
    n = system.dof
    if system.kind != "linear":
        return NONLINEAR_POINT_COST * float(n) ** 3
    # the floating elements the circuit keeps (rounding is no coupling), of M', B' and K' split as one stack
    floating = laplacian_split(np.stack([x for x in (system.mass, system.damping, system.stiffness)
                                         if x is not None]))[1]
    couplings = (np.eye(n, dtype=bool) | np.any(floating != 0, axis=0)).sum(axis=1, dtype=float)
    return float(couplings @ couplings)


def first_point_operations(systems) -> float:
    """:func:`point_operations` of the first of *systems*; of a linear stack whose rows share springs
    (all or none), read from every row's, made at once for the stack it was taken from.

    Parameters
    ----------
    systems : sequence of node systems, or NodeStack
        The systems of one circuit.
    """
    springs = getattr(systems, "springs", None)
    if springs is None or systems.inputs_row.kind != "linear" or (springs.any() and not springs.all()):
        return point_operations(systems[0])
    return float(systems.rowwise("point operations", _row_operations)[0][0])


def _row_operations(stack) -> tuple[np.ndarray]:
    """:func:`point_operations` of each row of a linear stack whose rows share springs (all or none)."""
    floating = laplacian_split(np.stack([stack.mass, stack.damping] + ([] if stack.springless else [stack.stiffness])))[1]
    couplings = (np.eye(stack.dof, dtype=bool) | np.any(floating != 0, axis=0)).sum(axis=-1, dtype=float)
    return (np.einsum("si,si->s", couplings, couplings),)
