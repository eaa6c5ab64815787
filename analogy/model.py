"""Mechanical models: a mass matrix M(q) with damping B, stiffness K and gravity G."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from .errors import InputError

__all__ = ["Model", "JointSpace", "JointStack", "check_square_symmetric", "check_vector",
           "evaluation_arguments", "configuration_stack", "evaluate_entries", "part_shapes"]


def check_square_symmetric(name: str, matrix, *, n: int | None = None,
                           definite: bool = False, semidefinite: bool = False,
                           rtol: float = 1e-10) -> np.ndarray:
    """Return *matrix* as a float array after checking shape, finiteness and symmetry.

    Raises :class:`InputError` with one sentence naming what is wrong.
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
        asym = np.abs(a - a.T)
        if asym.max() > rtol * max(scale, np.finfo(float).tiny):
            i, j = (int(k) + 1 for k in np.unravel_index(np.argmax(asym), asym.shape))
            raise InputError(f"{name} is not symmetric: entry ({i},{j}) = {a[i-1, j-1]:.6g} "
                             f"but ({j},{i}) = {a[j-1, i-1]:.6g}")
        a = 0.5 * (a + a.T)
    if definite or semidefinite:
        floor = 0.0 if definite else -1e-12 * max(scale, 1.0)
        if definite:
            try:        # Cholesky is the cheap test; eigenvalues only to explain a failure
                np.linalg.cholesky(a)
                return a
            except np.linalg.LinAlgError:
                pass
        elif not np.any(a - np.diag(np.diagonal(a))) and np.all(np.diagonal(a) >= floor):
            return a
        w = np.linalg.eigvalsh(a)
        bad = np.flatnonzero(w <= floor) if definite else np.flatnonzero(w < floor)
        if bad.size or definite:
            k = int(bad[0]) if bad.size else 0
            kind = "positive definite" if definite else "positive semidefinite"
            raise InputError(f"{name} is not {kind}: eigenvalue {k + 1} of {len(w)} "
                             f"(ascending) is {w[k]:.6g}")
    return a


def check_vector(name: str, values, n: int) -> np.ndarray:
    """Return *values* as a finite float vector of length *n*."""
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
    """Checked numeric arguments (q…, parameters…) for a model's compiled functions."""
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


def configuration_stack(name: str, coordinates, qs) -> np.ndarray:
    """*qs* as a finite float array of shape (count, len(coordinates))."""
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
    """Shapes of M, B, K and G for *n* joints."""
    return ((n, n), (n, n), (n, n), (n,))


def evaluate_entries(name: str, fn, args, shape, count: int | None = None):
    """A compiled part (a function returning its entries flat) at *args*, as a float array.

    With *count*, the arguments may be arrays of that length and the result has shape
    (count, *shape); constant entries are broadcast.
    """
    if fn is None:
        return None
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
        """Stack joint spaces evaluated one by one (absent K or G as zeros, if any has one)."""
        def stack(parts, shape):
            if all(p is None for p in parts):
                return None
            return np.stack([np.zeros(shape) if p is None else p for p in parts])
        n = spaces[0].dof
        return cls(np.stack([s.mass_matrix for s in spaces]), np.stack([s.damping for s in spaces]),
                   stack([s.stiffness for s in spaces], (n, n)), stack([s.gravity for s in spaces], (n,)))


@dataclass(frozen=True)
class JointSpace:
    """Numeric joint-space dynamics at one configuration: M·dR/dt + B·R + K·∫R = F − G."""

    mass_matrix: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray | None = None
    gravity: np.ndarray | None = None

    def __post_init__(self):
        m = check_square_symmetric("mass matrix M", self.mass_matrix, definite=True)
        n = m.shape[0]
        object.__setattr__(self, "mass_matrix", m)
        object.__setattr__(self, "damping", check_square_symmetric(
            "damping matrix B", self.damping, n=n, semidefinite=True))
        if self.stiffness is not None:
            k = check_square_symmetric("stiffness matrix K", self.stiffness, n=n, semidefinite=True)
            object.__setattr__(self, "stiffness", None if not np.any(k) else k)
        if self.gravity is not None:
            g = check_vector("gravity vector G", self.gravity, n)
            object.__setattr__(self, "gravity", None if not np.any(g) else g)

    @property
    def dof(self) -> int:
        return self.mass_matrix.shape[0]


def _as_matrix(value, n, name):
    if value is None:
        return None
    import sympy as sp
    if isinstance(value, sp.MatrixBase):
        return value
    a = np.asarray(value, dtype=object)
    if a.ndim == 1:
        if a.size != n:
            raise InputError(f"{name} must have {n} diagonal entries, got {a.size}")
        return sp.diag(*[sp.sympify(x) if not isinstance(x, str) else _bad_string(name) for x in a])
    return sp.Matrix(a.tolist())


def _bad_string(name):
    raise InputError(f"{name}: parse strings with analogy.expressions first")


@dataclass
class Model:
    """A robot or mechanism: M(q), B(q), K(q), G(q), symbolic or numeric.

    Parameters
    ----------
    name : str
        Short identifier, written into netlist headers.
    mass_matrix : sympy Matrix or array_like
        Symmetric positive definite joint-space mass matrix.
    damping, stiffness : sympy Matrix, array_like or sequence, optional
        A 1-D sequence is a diagonal.
    gravity : sequence, optional
        Joint-space gravity load G(q); it enters as a constant force −G.
    parameters : mapping of str to float
        Default numeric values of the model's symbolic parameters.
    coordinates : sequence of sympy Symbol
        Joint coordinates q the matrices may depend on.
    topology : str
        Default joint-to-node map (``"serial"`` or ``"parallel"``).
    """

    name: str
    mass_matrix: object
    damping: object = None
    stiffness: object = None
    gravity: object = None
    parameters: Mapping[str, float] = field(default_factory=dict)
    coordinates: Sequence = ()
    topology: str = "parallel"
    description: str = ""

    def __post_init__(self):
        import sympy as sp
        if isinstance(self.mass_matrix, sp.MatrixBase):
            m = self.mass_matrix
        else:
            m = sp.Matrix(np.asarray(self.mass_matrix, dtype=object).tolist()) \
                if np.asarray(self.mass_matrix, dtype=object).ndim == 2 else None
            if m is None:
                raise InputError("mass matrix must be two-dimensional")
        if m.rows != m.cols:
            raise InputError(f"mass matrix must be square, got shape ({m.rows}, {m.cols})")
        self.mass_matrix = m
        n = m.rows
        self.damping = _as_matrix(self.damping, n, "damping") if self.damping is not None else sp.zeros(n)
        self.stiffness = _as_matrix(self.stiffness, n, "stiffness")
        if self.gravity is not None:
            g = sp.Matrix(list(self.gravity))
            if g.rows != n:
                raise InputError(f"gravity must have {n} entries, got {g.rows}")
            self.gravity = g
        for label, mat in (("damping", self.damping), ("stiffness", self.stiffness)):
            if mat is not None and mat.shape != (n, n):
                raise InputError(f"{label} matrix must be {n}x{n}, got {mat.shape[0]}x{mat.shape[1]}")
        self.coordinates = tuple(self.coordinates)
        self.parameters = dict(self.parameters)
        self._compiled = None

    @property
    def dof(self) -> int:
        return self.mass_matrix.rows

    @property
    def symbols(self):
        """Parameter symbols, by name, that the matrices may contain."""
        import sympy as sp
        return {name: sp.Symbol(name, real=True) for name in self.parameters}

    def _compile(self):
        # Lambdify once per model; evaluation at many configurations reuses it.
        import sympy as sp
        params = list(self.symbols.values())
        args = list(self.coordinates) + params
        free = set()
        parts = [self.mass_matrix, self.damping, self.stiffness, self.gravity]
        for p in parts:
            if p is not None:
                free |= p.free_symbols
        unknown = sorted(str(s) for s in free - set(args))
        if unknown:
            raise InputError(f"model {self.name!r} uses symbols with no value: {', '.join(unknown)}")
        # Common-subexpression elimination pays off for large matrices only; it costs
        # ~0.1 s even on a 2x2 one.
        # Each part returns its entries flat, so that arrays of configurations broadcast.
        fns = [None if p is None else sp.lambdify(args, list(p), modules="numpy",
                                                  cse=sp.count_ops(p) > 400)
               for p in parts]
        self._compiled = (fns, [str(s) for s in self.coordinates], list(self.parameters))
        return self._compiled

    def _shapes(self):
        return part_shapes(self.dof)

    def joint_space(self, q: Sequence[float] | None = None,
                    parameters: Mapping[str, float] | None = None) -> JointSpace:
        """Evaluate the model numerically at configuration *q*.

        Parameters
        ----------
        q : sequence of float, optional
            Joint coordinates, one per entry of :attr:`coordinates`.
        parameters : mapping, optional
            Overrides of :attr:`parameters` by name.
        """
        fns, qnames, pnames = self._compiled or self._compile()
        args = evaluation_arguments(self.name, qnames, self.parameters, q, parameters)
        m, b, k, g = (evaluate_entries(self.name, f, args, shape) for f, shape in zip(fns, self._shapes()))
        return JointSpace(m, b, k, g)

    def joint_stack(self, qs, parameters: Mapping[str, float] | None = None) -> JointStack:
        """Evaluate at every row of *qs* at once (vectorised over configurations).

        The values are not checked; :func:`analogy.system.node_systems` checks the stack.
        """
        fns, qnames, _ = self._compiled or self._compile()
        q = configuration_stack(self.name, qnames, qs)
        args = list(q.T) + evaluation_arguments(self.name, (), self.parameters, None, parameters)
        return JointStack(*(evaluate_entries(self.name, f, args, shape, len(q))
                            for f, shape in zip(fns, self._shapes())))

