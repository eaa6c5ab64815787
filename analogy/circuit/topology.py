"""Joint-to-node maps v = T·r: serial, parallel, modal (one node per mode) or any invertible T."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from ..errors import InputError
from ..small_linalg import matmul

__all__ = ["Topology", "serial", "parallel", "custom", "modal", "topology", "default_topology", "TOPOLOGIES",
           "TOPOLOGY_NAMES", "DENSE_NODE_LIMIT", "congruence", "symmetric_part"]


@dataclass(frozen=True)
class Topology:
    """Node velocities v = T·r and node currents i = T⁻ᵀ·F.

    Attributes
    ----------
    name : str
        ``"serial"``, ``"parallel"``, ``"modal"`` or ``"custom"``.
    matrix : ndarray, shape (n, n)
        The invertible map T from joint rates to node velocities.
    """

    name: str
    matrix: np.ndarray

    def __post_init__(self):
        t = np.array(self.matrix, dtype=float)
        if t.ndim != 2 or t.shape[0] != t.shape[1]:
            raise InputError(f"topology matrix T must be square, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise InputError("topology matrix T has a non-finite entry")
        if t.size and np.linalg.cond(t) > 1e12:
            raise InputError("topology matrix T is singular (or nearly so): it must be invertible")
        t.setflags(write=False)
        object.__setattr__(self, "matrix", t)

    @property
    def dof(self) -> int:
        return self.matrix.shape[0]

    @cached_property
    def key(self) -> tuple:
        """The map's value as a hashable tuple, for grouping systems that share it."""
        return (self.name, self.matrix.shape, self.matrix.tobytes())

    @cached_property
    def inverse(self) -> np.ndarray:
        """T⁻¹, mapping node velocities back to joint rates."""
        inv = np.linalg.inv(self.matrix)
        inv.setflags(write=False)
        return inv

    @cached_property
    def exact_inverse(self) -> bool:
        """True when T·T⁻¹ = I holds exactly in floating point (serial, parallel, integer maps)."""
        return bool(np.array_equal(self.matrix @ self.inverse, np.eye(self.dof)))

    @property
    def current_map(self) -> np.ndarray:
        """T⁻ᵀ, mapping joint forces F to node currents i (power is conserved: Fᵀr = iᵀv)."""
        return self.inverse.T

    def node_matrix(self, joint_matrix: np.ndarray) -> np.ndarray:
        """The node-coordinate form T⁻ᵀ·X·T⁻¹ of a joint-space matrix X, or of a stack (..., n, n).

        Parameters
        ----------
        joint_matrix : ndarray, shape (..., n, n)
            A joint-space matrix, or a stack of them.
        """
        if self.exact_inverse:      # products with an exact inverse: no solves, same numbers
            with np.errstate(over="ignore", invalid="ignore"):   # overflow is named by the callers
                z = matmul(matmul(self.inverse.T, np.asarray(joint_matrix, dtype=float)), self.inverse)
            return symmetric_part(z)
        z = congruence(joint_matrix, self.matrix)
        return _without_rounding(z, self.rounding) if self.name == "modal" and isinstance(z, np.ndarray) else z

    @cached_property
    def condition(self) -> float:
        """cond(T): the congruence's solves err about n·ε·cond(T) of its largest entry."""
        return float(np.linalg.cond(self.matrix)) if self.dof else 1.0

    @cached_property
    def rounding(self) -> float:
        """How far the map's rounding can move the joint rates, as a fraction of the largest: 4·n·ε·cond(T),
        or 0 where T⁻¹ is exact (serial, parallel). Both the node matrices (T⁻ᵀ·X·T⁻¹) and the rates read
        back (T⁻¹·v) carry it: on serial100's modal circuit (cond(T) = 1.4e4) the exact solutions of it and
        of the serial circuit differ by 1.4e-11 of the largest rate, under this 1.3e-9."""
        return 0.0 if self.exact_inverse else 4 * self.dof * float(np.finfo(float).eps) * self.condition

    def joint_rates(self, node_voltages) -> np.ndarray:
        """R = T⁻¹·v for node voltages of shape (..., n).

        Parameters
        ----------
        node_voltages : ndarray, shape (..., n)
            Node velocities v.
        """
        v = np.asarray(node_voltages, dtype=float)
        if v.shape[-1:] != (self.dof,):
            raise ValueError(f"node voltages of shape {v.shape} for a map of {self.dof} nodes")
        if self.exact_inverse:
            terms = self._rate_terms
            return v @ self.inverse.T if terms is None else _sparse_rows(v, terms)
        return np.linalg.solve(self.matrix, v.reshape(-1, self.dof).T).T.reshape(v.shape)

    @cached_property
    def _rate_terms(self) -> tuple | None:
        """Per joint, the (node, coefficient) of T⁻¹'s nonzero entries in its row, for a few joints
        (serial and parallel maps have one or two, each ±1); None past 8 joints, where one product is cheaper."""
        if self.dof > 8:
            return None
        # a +1 term first: copied, then the others added or subtracted in place
        return tuple(tuple(sorted(((k, float(c)) for k, c in enumerate(row) if c != 0), key=lambda t: t[1] != 1.0))
                     for row in self.inverse.tolist())

    def describe(self) -> str:
        if self.name == "serial":
            return "serial (v_k = r_1 + ... + r_k)"
        if self.name == "parallel":
            return "parallel (v = r)"
        if self.name == "modal":
            return "modal (v = T r: one node per mode, T = Phi^T M with Phi^T M Phi = I)"
        return "custom (v = T r)"


def congruence(x, t) -> np.ndarray:
    """Return T⁻ᵀ·X·T⁻¹ for numeric arrays (or stacks of them) or sympy matrices, without
    forming T⁻¹ for numbers.

    Parameters
    ----------
    x : ndarray or sympy Matrix
        The joint-space matrix (or a stack of them).
    t : ndarray or sympy Matrix
        The map T.
    """
    if not (isinstance(x, np.ndarray) and isinstance(t, np.ndarray)):
        import sympy as sp  # symbolic congruence; numbers never import sympy
        if isinstance(x, sp.MatrixBase) or isinstance(t, sp.MatrixBase):
            ti = sp.Matrix(t).inv()
            return sp.simplify(ti.T * sp.Matrix(x) * ti)
    t = np.asarray(t, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):       # overflow is named by the callers
        y = np.linalg.solve(t.T, np.asarray(x, dtype=float))     # T⁻ᵀ X
        z = np.swapaxes(np.linalg.solve(t.T, np.swapaxes(y, -1, -2)), -1, -2)   # T⁻ᵀ X T⁻¹
    return symmetric_part(z)


def _without_rounding(z: np.ndarray, rounding: float) -> np.ndarray:
    """*z* (or a stack) with each off-diagonal entry under *rounding*·max|z| (4·n·ε·cond(T),
    :attr:`Topology.rounding`) set to zero: the rounding of a congruence by the modal map, which
    diagonalises M and B (or K) exactly. Kept, it wrote serial100's
    modal circuit (cond(T) = 1.4e4) with floating capacitors and resistors of 2.6e-10 of the largest, whose
    charges crossing zero cut ngspice's steps; the genuine off-diagonal B' of a modal circuit with springs
    stands far above it."""
    n = z.shape[-1]
    floor = rounding * np.max(np.abs(z), axis=(-2, -1), keepdims=True)
    off = (np.abs(z) <= floor) & ~np.eye(n, dtype=bool)
    return np.where(off, 0.0, z)


def symmetric_part(z) -> np.ndarray:
    """½(Z + Zᵀ) for a matrix or a stack (..., n, n), computed so that it cannot overflow.

    Entries that already equal their mirror are kept exactly (halving a subnormal
    number would round it to zero); the others are halved before they are added.

    Parameters
    ----------
    z : ndarray, shape (..., n, n)
        A nearly symmetric matrix, or a stack of them.
    """
    z = np.asarray(z, dtype=float)
    zt = np.swapaxes(z, -1, -2)
    with np.errstate(invalid="ignore"):         # inf - inf in a matrix the callers refuse anyway
        return np.where(z == zt, z, 0.5 * z + 0.5 * zt)


@lru_cache(maxsize=64)
def serial(n: int) -> Topology:
    """Serial chain: node k carries the absolute rate v_k = r_1 + … + r_k."""
    return Topology("serial", np.tril(np.ones((n, n))))


@lru_cache(maxsize=64)
def parallel(n: int) -> Topology:
    """Parallel mechanism: every actuator is grounded, v = r."""
    return Topology("parallel", np.eye(n))


def custom(matrix) -> Topology:
    """Any invertible joint-to-node map T.

    Parameters
    ----------
    matrix : array_like, shape (n, n)
        The invertible map T.
    """
    return Topology("custom", matrix)


def modal(mass, damping, stiffness=None) -> Topology:
    """One node per mode: T = Φᵀ·M, where Φᵀ·M·Φ = I and Φᵀ·A·Φ = Λ for A = K (the undamped
    modes) or, without springs, A = B.

    Then M' = I, one 1 F capacitor per mode, and A' = Λ: the circuit's n(n−1)/2 floating
    capacitors become n grounded ones. B' (with springs) is diagonal only for proportional
    damping; otherwise its off-diagonal terms stay as floating resistors, so the circuit is
    exact either way. Each mode's sign makes its largest entry of Φ positive, which fixes
    T where the eigenvalues are distinct.

    Parameters
    ----------
    mass : array_like, shape (n, n)
        The joint mass matrix M (symmetric positive definite).
    damping : array_like, shape (n, n)
        The joint damping B.
    stiffness : array_like, shape (n, n), optional
        The joint stiffness K.
    """
    m = np.asarray(mass, dtype=float)
    springs = stiffness is not None and np.any(np.asarray(stiffness) != 0)
    a = np.asarray(stiffness if springs else damping, dtype=float)
    try:        # M = L·Lᵀ; the symmetric L⁻¹·A·L⁻ᵀ = V·Λ·Vᵀ; Φ = L⁻ᵀ·V
        low = np.linalg.cholesky(symmetric_part(m))
        c = np.linalg.solve(low, np.linalg.solve(low, symmetric_part(a)).T)
        _, vectors = np.linalg.eigh(symmetric_part(c))
        phi = np.linalg.solve(low.T, vectors)
    except np.linalg.LinAlgError:
        raise InputError("the modal topology needs a positive definite mass matrix") from None
    pivot = np.argmax(np.abs(phi), axis=0)
    phi = phi * np.sign(phi[pivot, np.arange(phi.shape[1])])
    return Topology("modal", phi.T @ m)


TOPOLOGIES = {"serial": serial, "parallel": parallel}
#: The topologies a scene names: ``modal`` is built from the system's own M, B and K.
TOPOLOGY_NAMES = (*TOPOLOGIES, "modal")
#: Past this many joints a linear system whose own circuit is dense is written on the modal map
#: (:func:`default_topology`). SPICE at ``accurate``, serial then modal (a fresh process each, loading
#: the library counted in both): serial10 105 and 113 ms, serial16 455 and 203 ms, serial50 7.4 s and
#: 0.41 s; at ``fast`` the serial circuits of serial32 and serial50 missed the bound (3.3e-3), the
#: modal ones kept it (4.2e-4, 4.4e-5).
DENSE_NODE_LIMIT = 12


def default_topology(own: str, mass, damping, stiffness=None) -> "str | Topology":
    """The map a linear system is written on when none is named: a name, or the modal map built.

    A system of more than :data:`DENSE_NODE_LIMIT` joints whose circuit on its own map would have
    more floating elements than twice its nodes (n(n−1)/2 capacitors for a dense mass matrix) takes the
    modal map where that has fewer: n grounded capacitors, and floating resistors only where springs
    meet damping that is not proportional. A sparse chain keeps its own map.

    Parameters
    ----------
    own : str
        The model's own map (``"serial"`` or ``"parallel"``).
    mass, damping : array_like, shape (n, n)
        The joint M and B.
    stiffness : array_like, shape (n, n), optional
        The joint K.
    """
    n = len(mass)
    if n <= DENSE_NODE_LIMIT or own not in TOPOLOGIES:
        return own
    matrices = [np.asarray(x, dtype=float) for x in (mass, damping, stiffness) if x is not None]
    upper = np.triu(np.ones((n, n), dtype=bool), 1)

    def floating(top: Topology) -> int:
        return sum(int(np.count_nonzero(top.node_matrix(x)[upper])) for x in matrices)
    mine = floating(TOPOLOGIES[own](n))
    if mine <= 2 * n:
        return own
    modes = modal(mass, damping, stiffness)
    return modes if floating(modes) < mine else own


def topology(spec, n: int, matrices: tuple | None = None) -> Topology:
    """Build a topology from a name (``serial``, ``parallel``, ``modal``), a Topology or a matrix.

    Parameters
    ----------
    spec : str, Topology or array_like
        ``"serial"``, ``"parallel"``, ``"modal"``, a Topology or a matrix T.
    n : int
        Number of joints.
    matrices : tuple, optional
        The joint (M, B, K) the modal topology is built from (K may be None).
    """
    if isinstance(spec, Topology):
        top = spec
    elif isinstance(spec, str):
        if spec == "modal":
            if matrices is None:
                raise InputError("the modal topology is built from a linear system's M, B and K: "
                                 "it needs the dynamics at one configuration")
            top = modal(*matrices)
        elif spec not in TOPOLOGIES:
            raise InputError(f"unknown topology {spec!r}: use serial, parallel, modal or a matrix T")
        else:
            top = TOPOLOGIES[spec](n)
    else:
        top = custom(spec)
    if top.dof != n:
        raise InputError(f"topology is {top.dof}x{top.dof} but the robot has {n} joints")
    return top


def _sparse_rows(v: np.ndarray, terms: tuple) -> np.ndarray:
    """``v @ Aᵀ`` for A given by its rows' nonzero (column, coefficient) *terms*: one pass over the
    times per term, not a product with every zero (the same numbers: unit coefficients are exact)."""
    # in v's own memory order (A is square): rates of (rows, nodes, times) memory stay time-contiguous
    out = np.empty_like(v)
    for i, row in enumerate(terms):
        at = out[..., i]
        if not row:
            at[...] = 0.0
        for j, (k, c) in enumerate(row):
            x = v[..., k]
            if c == 1.0:
                np.add(at, x, out=at) if j else np.copyto(at, x)
            elif c == -1.0:
                np.subtract(at, x, out=at) if j else np.negative(x, out=at)
            else:
                np.add(at, c * x, out=at) if j else np.multiply(x, c, out=at)
    return out
