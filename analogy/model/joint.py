"""Numeric joint-space dynamics at one configuration, and the checks every model's values pass."""

from __future__ import annotations

from typing import Mapping, NamedTuple, Sequence

import numpy as np

from ..errors import InputError, concerning
from ..small_linalg import axis_max, cholesky, eigvalsh

__all__ = ["JointSpace", "unstable_stiffness", "JointStack", "check_square_symmetric", "check_node_form",
           "check_vector", "evaluation_arguments", "stack_arguments", "configuration_stack", "evaluate_entries",
           "part_shapes",
           "stack_fault"]


#: The smallest normal float: a mass eigenvalue below it has no finite inverse.
_TINY = float(np.finfo(float).tiny)

def check_square_symmetric(name: str, matrix, *, n: int | None = None,
                           definite: bool = False, semidefinite: bool = False,
                           rtol: float = 1e-10) -> np.ndarray:
    """Return *matrix* as a float array after checking shape, finiteness and symmetry.

    Raises :class:`InputError` with one sentence naming what is wrong.

    Parameters
    ----------
    name : str
        What the matrix is, for messages.
    matrix : array_like
        The matrix.
    n : int, optional
        The size it must have.
    definite : bool
        Require positive definiteness.
    semidefinite : bool
        Require positive semidefiniteness.
    rtol : float
        Relative tolerance of the symmetry check.
    """
    try:
        a = np.array(matrix, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a numeric matrix") from None
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise InputError(f"{name} must be square, got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise InputError(f"{name} must be {n}x{n} to match the mass matrix, got {a.shape[0]}x{a.shape[1]}")
    if not np.all(np.isfinite(a)):
        bad = tuple(int(i) + 1 for i in np.argwhere(~np.isfinite(a))[0])
        raise InputError(f"{name} has a non-finite entry at row {bad[0]}, column {bad[1]}")
    scale = float(np.max(np.abs(a))) if a.size else 0.0
    if not np.array_equal(a, a.T):          # exact symmetry, the usual case, needs no more
        asym = np.abs(0.5 * a - 0.5 * a.T)    # halves first: a - aᵀ may overflow near 1e308
        if asym.max() > 0.5 * rtol * max(scale, np.finfo(float).tiny):
            i, j = (int(k) + 1 for k in np.unravel_index(np.argmax(asym), asym.shape))
            raise InputError(f"{name} is not symmetric: entry ({i},{j}) = {a[i-1, j-1]:.6g} "
                             f"but ({j},{i}) = {a[j-1, i-1]:.6g}")
        a = np.where(a == a.T, a, 0.5 * a + 0.5 * a.T)
    if definite or semidefinite:
        floor = 0.0 if definite else -1e-12 * max(scale, 1.0)
        if definite:
            try:        # Cholesky is the cheap test; eigenvalues only to explain a failure
                factor = np.linalg.cholesky(a)
                if np.min(np.diagonal(factor)) ** 2 >= _TINY:
                    return a
            except np.linalg.LinAlgError:
                pass
        elif not np.any(a - np.diag(np.diagonal(a))) and np.all(np.diagonal(a) >= floor):
            return a
        w = np.linalg.eigvalsh(a)
        bad = np.flatnonzero(w <= floor) if definite else np.flatnonzero(w < floor)
        if definite and not bad.size and w[0] < _TINY:
            raise InputError(f"{name} is too close to singular: eigenvalue 1 of {len(w)} is {w[0]:.3g}, "
                             f"below {_TINY:.3g}, so its inverse leaves the floating-point range")
        if bad.size or definite:
            k = int(bad[0]) if bad.size else 0
            kind = "positive definite" if definite else "positive semidefinite"
            raise InputError(f"{name} is not {kind}: eigenvalue {k + 1} of {len(w)} "
                             f"(ascending) is {w[k]:.6g}")
    return a


def check_node_form(name: str, matrix) -> None:
    """Refuse a matrix whose node form T⁻ᵀ·X·T⁻¹ (or T⁻ᵀ itself) left the floating-point range.

    Parameters
    ----------
    name : str
        What the matrix is, for messages (``node damping matrix B'``).
    matrix : ndarray or None
        The node-coordinate matrix; None is skipped.
    """
    if matrix is None or np.all(np.isfinite(matrix)):
        return
    i, j = (int(k) + 1 for k in np.argwhere(~np.isfinite(matrix))[0])
    raise InputError(f"{name} leaves the floating-point range at row {i}, column {j}: the joint-space "
                     "values are too large for this topology")


def check_vector(name: str, values, n: int) -> np.ndarray:
    """Return *values* as a finite float vector of length *n*.

    Parameters
    ----------
    name : str
        What the vector is, for messages.
    values : array_like
        The entries.
    n : int
        The length it must have.
    """
    try:
        v = np.array(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a list of numbers") from None
    if v.size != n:
        raise InputError(f"{name} must have {n} entries (one per joint), got {v.size}")
    if not np.all(np.isfinite(v)):
        raise InputError(f"{name} has a non-finite entry at position {int(np.argmin(np.isfinite(v))) + 1}")
    return v


def evaluation_arguments(name: str, coordinates, defaults: Mapping[str, float], q=None,
                         overrides: Mapping[str, float] | None = None) -> list[float]:
    """Checked numeric arguments (q…, parameters…) for a model's compiled functions.

    Parameters
    ----------
    name : str
        The model's name, for messages.
    coordinates : sequence of str
        The model's coordinates.
    defaults : mapping
        The model's parameter values.
    q : sequence of float, optional
        Configuration.
    overrides : mapping, optional
        Parameter overrides.
    """
    q = [] if q is None else list(q)
    if len(q) != len(coordinates):
        raise InputError(f"model {name!r} needs {len(coordinates)} joint coordinates "
                         f"({', '.join(coordinates) or 'none'}), got {len(q)}")
    values = dict(defaults)
    for key, value in (overrides or {}).items():
        if key not in values:
            raise InputError(f"model {name!r} has no parameter {key!r} "
                             f"(it has: {', '.join(values) or 'none'})")
        values[key] = value
    args = list(check_vector("configuration q", q, len(q))) if q else []
    return args + (list(check_vector("parameters", list(values.values()), len(values))) if values else [])


def stack_arguments(name: str, defaults: Mapping[str, float], overrides: Mapping | None,
                    count: int) -> list:
    """Checked parameter arguments for a stack of *count* rows: a float, or an array per row.

    An override may be one number for every row or a sequence of *count* numbers, so
    that scenes differing in their parameters are evaluated as one stack.

    Parameters
    ----------
    name : str
        The model's name, for messages.
    defaults : mapping
        The model's parameter values.
    overrides : mapping, optional
        Parameter overrides: numbers or sequences of *count* numbers.
    count : int
        Rows of the stack.
    """
    values: dict = dict(defaults)
    for key, value in (overrides or {}).items():
        if key not in values:
            raise InputError(f"model {name!r} has no parameter {key!r} "
                             f"(it has: {', '.join(values) or 'none'})")
        values[key] = value
    out = []
    for key, value in values.items():
        v = np.asarray(value, dtype=float)
        if v.ndim == 0:
            v = float(v)
        elif v.shape != (count,):
            raise InputError(f"parameter {key!r} needs one value or {count} (one per row), got shape {v.shape}")
        if not np.all(np.isfinite(v)):
            raise InputError(f"parameter {key!r} has a non-finite value")
        out.append(v)
    return out


def configuration_stack(name: str, coordinates, qs) -> np.ndarray:
    """*qs* as a finite float array of shape (count, len(coordinates)).

    Parameters
    ----------
    name : str
        The model's name, for messages.
    coordinates : sequence of str
        The model's coordinates.
    qs : array_like
        Configurations, one per row.
    """
    try:
        q = np.array(qs, dtype=float)
    except (TypeError, ValueError):
        raise InputError("configurations must be numbers, one row per configuration") from None
    if q.ndim >= 1 and not len(q):
        raise InputError("at least one configuration is needed")
    q = q.reshape(len(q), 1) if q.ndim == 1 and len(coordinates) == 1 else q
    if q.ndim != 2 or q.shape[1] != len(coordinates):
        raise InputError(f"model {name!r} needs rows of {len(coordinates)} joint coordinates, "
                         f"got an array of shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise InputError(f"configuration {int(np.argwhere(~np.isfinite(q))[0, 0]) + 1} "
                         "has a non-finite entry")
    return q


def part_shapes(n: int) -> tuple:
    """Shapes of M, B, K and G for *n* joints.

    Parameters
    ----------
    n : int
        Number of joints.
    """
    return ((n, n), (n, n), (n, n), (n,))


def evaluate_entries(name: str, fn, args, shape, count: int | None = None) -> np.ndarray | None:
    """A compiled part (a function returning its entries flat) at *args*, as a float array.

    With *count*, the arguments may be arrays of that length and the result has shape
    (count, *shape); constant entries are broadcast.

    Parameters
    ----------
    name : str
        The model's name, for messages.
    fn : callable or None
        A compiled part.
    args : sequence
        Its arguments.
    shape : tuple of int
        The part's shape.
    count : int, optional
        Number of configurations when the arguments are arrays.
    """
    if fn is None:
        return None
    # Overflow or a domain error gives inf or NaN, which the callers' finiteness checks name.
    with np.errstate(all="ignore"):
        entries = fn(*args)
    if count is None:
        value = np.asarray(entries)
    else:
        kind = complex if any(np.iscomplexobj(e) for e in entries) else float
        value = np.empty((count, len(entries)), dtype=kind)
        for i, e in enumerate(entries):
            value[:, i] = e
    if np.iscomplexobj(value):
        if np.any(value.imag != 0):
            raise InputError(f"model {name!r} evaluates to complex numbers at this "
                             "configuration (e.g. the square root of a negative number)")
        value = value.real
    return np.array(value, dtype=float).reshape(shape if count is None else (count, *shape))


class JointStack(NamedTuple):
    """Joint-space M, B, K, G at many configurations, stacked on a leading axis (unchecked)."""

    mass_matrix: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray | None
    gravity: np.ndarray | None

    @classmethod
    def of(cls, spaces: Sequence["JointSpace"]) -> "JointStack":
        """Stack joint spaces evaluated one by one (absent K or G as zeros, if any has one).

        Parameters
        ----------
        spaces : sequence of JointSpace
            Joint spaces of one size.
        """
        def stack(parts, shape):
            if all(p is None for p in parts):
                return None
            return np.stack([np.zeros(shape) if p is None else p for p in parts])
        n = spaces[0].dof
        return cls(np.stack([s.mass_matrix for s in spaces]), np.stack([s.damping for s in spaces]),
                   stack([s.stiffness for s in spaces], (n, n)), stack([s.gravity for s in spaces], (n,)))


def _frozen(a: np.ndarray | None) -> np.ndarray | None:
    if a is not None:
        a.setflags(write=False)
    return a


class JointSpace:
    """Numeric joint-space dynamics at one configuration: M·dR/dt + B·R + K·∫R = F − G.

    Parameters
    ----------
    mass_matrix : array_like, shape (n, n)
        Symmetric positive definite M.
    damping : array_like, shape (n, n), optional
        Symmetric positive semidefinite B (default zero).
    stiffness : array_like, shape (n, n), optional
        Symmetric K; all zeros is stored as None. It may be indefinite: gravity's
        stiffness is negative about a pose above the horizontal, an unstable equilibrium
        whose modes grow (see :attr:`unstable`).
    gravity : array_like, shape (n,), optional
        Gravity load G; all zeros is stored as None.
    """

    __slots__ = ("mass_matrix", "damping", "stiffness", "gravity")

    def __init__(self, mass_matrix, damping=None, stiffness=None, gravity=None):
        with concerning("mass"):
            m = check_square_symmetric("mass matrix M", mass_matrix, definite=True)
        n = m.shape[0]
        with concerning("damping"):
            b = np.zeros((n, n)) if damping is None else \
                check_square_symmetric("damping matrix B", damping, n=n, semidefinite=True)
        with concerning("stiffness"):
            k = None if stiffness is None else check_square_symmetric("stiffness matrix K", stiffness, n=n)
        with concerning("gravity"):
            g = None if gravity is None else check_vector("gravity vector G", gravity, n)
        self._store(m, b, k, g)

    def _store(self, m, b, k, g):
        self.mass_matrix, self.damping = _frozen(m), _frozen(b)
        self.stiffness = _frozen(k) if k is not None and np.any(k) else None
        self.gravity = _frozen(g) if g is not None and np.any(g) else None

    @classmethod
    def from_checked(cls, mass_matrix, damping, stiffness=None, gravity=None) -> "JointSpace":
        """A joint space from values that already passed :func:`stack_fault` (one row of a stack).

        Parameters
        ----------
        mass_matrix : ndarray
            M.
        damping : ndarray
            B.
        stiffness : ndarray, optional
            K.
        gravity : ndarray, optional
            G.
        """
        obj = cls.__new__(cls)
        obj._store(mass_matrix, damping, stiffness, gravity)
        return obj

    @property
    def dof(self) -> int:
        """Number of joints n."""
        return self.mass_matrix.shape[0]

    @property
    def unstable(self) -> bool:
        """True when K has a negative eigenvalue: the pose is an unstable equilibrium."""
        return unstable_stiffness(self.stiffness)

    def __repr__(self) -> str:
        parts = ["M", "B"] + (["K"] if self.stiffness is not None else []) + \
            (["G"] if self.gravity is not None else [])
        return f"JointSpace({self.dof} joints: {', '.join(parts)})"


def unstable_stiffness(stiffness: np.ndarray | None) -> bool:
    """True when the symmetric *stiffness* has an eigenvalue below −1e-12 of its largest entry.

    Parameters
    ----------
    stiffness : ndarray or None
        K (or K').
    """
    if stiffness is None:
        return False
    return bool(np.linalg.eigvalsh(stiffness)[0] < -1e-12 * max(np.abs(stiffness).max(), 1e-300))


def stack_fault(stack: JointStack, node_mass: np.ndarray | None = None) -> bool:
    """True unless every row of *stack* (and of *node_mass*) passes :class:`JointSpace`'s checks.

    Parameters
    ----------
    stack : JointStack
        M, B, K, G at many configurations.
    node_mass : ndarray, shape (count, n, n), optional
        The node mass matrices M' of the rows, which must be positive definite too.
    """
    m, b, k, g = stack
    parts = [x for x in (m, b, k, g, node_mass) if x is not None]
    if not all(np.all(np.isfinite(x)) for x in parts):
        return True
    for x in (m, b, k):
        if x is not None and not np.array_equal(x, np.swapaxes(x, 1, 2)):
            return True         # rare (rounding in a model's own expressions): checked one by one
    try:
        cholesky(m)
        if node_mass is not None:
            cholesky(node_mass)
    except np.linalg.LinAlgError:
        return True
    for x in (b,):
        if x is not None:
            floor = -1e-12 * np.maximum(axis_max(np.abs(x).reshape(len(x), -1), 1), 1.0)
            if np.any(eigvalsh(x)[:, 0] < floor):
                return True
    return False
