"""Symbolic models: M(q), B, K, G(q) and the velocity terms c(q, q̇) from M's Christoffel symbols."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from ..units import joint_units
from ..errors import InputError
from .base import RobotModel
from .contact import Contact, check_contact_values, generalised_contact_forces
from .dynamics import ContactFunctions, MechanicalFunctions
from .joint import (
    JointStack,
    configuration_stack,
    evaluate_entries,
    stack_arguments,
    part_shapes,
)

__all__ = ["MAX_EXPANDED_TERMS", "Model", "christoffel_symbols", "velocity_terms"]


def christoffel_symbols(mass_matrix: sp.MatrixBase, coordinates: Sequence[sp.Symbol]) -> list:
    """Christoffel symbols of the first kind, Γ[i][j][k] = ½(∂M_ij/∂q_k + ∂M_ik/∂q_j − ∂M_jk/∂q_i).

    Parameters
    ----------
    mass_matrix : sympy Matrix
        Symmetric M(q).
    coordinates : sequence of sympy Symbol
        The joint coordinates q.

    Returns
    -------
    list of list of list of sympy expressions
        Γ[i][j][k], symmetric in j and k, so that c_i = Σ_jk Γ_ijk·q̇_j·q̇_k.
    """
    q = list(coordinates)
    n = mass_matrix.rows
    if len(q) != n:
        raise InputError(f"Christoffel symbols need {n} coordinates, one per row of M, got {len(q)}")
    d = [[[sp.diff(mass_matrix[i, j], q[k]) for k in range(n)] for j in range(n)] for i in range(n)]
    return [[[sp.Rational(1, 2) * (d[i][j][k] + d[i][k][j] - d[j][k][i]) for k in range(n)]
             for j in range(n)] for i in range(n)]


def velocity_terms(mass_matrix: sp.MatrixBase, coordinates: Sequence[sp.Symbol],
                   rates: Sequence[sp.Symbol]) -> sp.Matrix:
    """Centrifugal and Coriolis forces c(q, q̇) = Σ_jk Γ_ijk·q̇_j·q̇_k of the Lagrange equations.

    Parameters
    ----------
    mass_matrix : sympy Matrix
        Symmetric M(q) whose entries depend on *coordinates*.
    coordinates : sequence of sympy Symbol
        Joint coordinates q (one per row of M).
    rates : sequence of sympy Symbol
        Joint rates q̇, in the same order.

    Returns
    -------
    sympy Matrix, shape (n, 1)
        c, so that M(q)·q̈ + c(q, q̇) + G(q) = τ.
    """
    n = mass_matrix.rows
    if len(coordinates) != n or len(rates) != n:
        raise InputError(f"velocity terms need {n} coordinates and {n} rates, one per row of M")
    terms = max((_expanded_terms(e) for e in mass_matrix), default=0)
    if terms > MAX_EXPANDED_TERMS:
        raise InputError(f"the mass matrix expands to about {terms:.3g} terms in an entry, more than the "
                         f"{MAX_EXPANDED_TERMS} the nonlinear dynamics derive: give smaller powers of sums")
    gamma = christoffel_symbols(mass_matrix, coordinates)
    return sp.Matrix([sp.expand(sum(gamma[i][j][k] * rates[j] * rates[k]
                                    for j in range(n) for k in range(n))) for i in range(n)])


#: Most terms one expanded mass-matrix entry may have before the velocity terms are derived.
MAX_EXPANDED_TERMS = 2_000


def _expanded_terms(expr) -> float:
    """An upper estimate of the terms *expr* has once expanded (a float: it may be huge)."""
    if expr.is_Add:
        return sum(_expanded_terms(a) for a in expr.args)
    if expr.is_Mul:
        return math.prod(_expanded_terms(a) for a in expr.args)
    if expr.is_Pow and expr.exp.is_Integer and expr.exp > 1:
        k = _expanded_terms(expr.base)
        if k >= 1e3 or expr.exp > 10_000:
            return math.inf
        try:
            return float(math.comb(int(expr.exp) + int(k) - 1, int(k) - 1))
        except OverflowError:
            return math.inf
    return 1.0


def _lambdify(*args, **kwargs):
    """``sympy.lambdify``, with expressions too large to compile refused in one sentence."""
    try:
        return sp.lambdify(*args, **kwargs)
    except (RecursionError, MemoryError, SyntaxError, ValueError, OverflowError):
        # Python's compiler and its integer-to-text limit bound what generated code can hold.
        raise InputError("the model's expressions are too large to compile: "
                         "give smaller powers or fewer terms") from None


def _as_matrix(value, n, name):
    if value is None:
        return None
    if isinstance(value, sp.MatrixBase):
        return value
    a = np.asarray(value, dtype=object)
    if a.ndim == 1:
        if a.size != n:
            raise InputError(f"{name} must have {n} diagonal entries, got {a.size}")
        return sp.diag(*[sp.sympify(x) if not isinstance(x, str) else _bad_string(name) for x in a])
    return sp.Matrix(a.tolist())


def _bad_string(name):
    raise InputError(f"{name}: parse strings with analogy.model.expressions first")


@dataclass
class Model(RobotModel):
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
    description : str
        One line for reports.
    spring_rest : sequence of float, optional
        The configuration at which K is unstretched (the flexible links' modal
        coordinates rest at 0); by default the springs rest at the pose linearised at.
    builder : callable, optional
        ``builder(**parameters)`` rebuilds the model for other parameter values, for
        models whose matrices are numbers computed from them (mode shapes of flexible
        links, whose count sets the coordinates).
    joints : sequence of {"revolute", "prismatic", "modal"}, optional
        What each coordinate is, which sets its unit (rad or m) and whether a joint force
        drives it by default (a modal amplitude is not driven); None: not declared.
    contacts : sequence of Contact, optional
        Points that touch the ground plane (:mod:`analogy.model.contact`): their one-sided forces
        join the nonlinear dynamics, and their linearisation at q0 the linear circuit.

    Notes
    -----
    Linearised at q0, the model gives M(q0), B, K + ∂G/∂q(q0) (gravity's stiffness,
    negative where the pose is unstable) and the constant load G(q0) + K·(q0 − rest).
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
    spring_rest: Sequence[float] | None = None
    builder: Callable[..., "Model"] | None = None
    joints: Sequence[str] | None = None
    contacts: Sequence[Contact] = ()

    @property
    def units(self) -> tuple[str, ...] | None:
        """Per coordinate, ``"rad"`` or ``"m"``, from :attr:`joints` (None where not declared)."""
        return joint_units(self.joints)

    def __repr__(self) -> str:
        coords = ", ".join(str(c) for c in self.coordinates) or "none"
        return f"<Model {self.name}: coordinates {coords}; {len(self.parameters)} parameters>"

    def _repr_latex_(self) -> str:
        """M(q), and B, K and G(q) where the model has them, as LaTeX: a notebook renders the maths."""
        parts = (("M(q)", self.mass_matrix), ("B", self.damping), ("K", self.stiffness), ("G(q)", self.gravity))
        shown = [f"{label} = {sp.latex(m)}" for label, m in parts if m is not None and m.is_zero_matrix is not True]
        return "$\\displaystyle " + ",\\quad ".join(shown) + "$"

    def __post_init__(self):
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
        self.contacts = tuple(self.contacts)
        if self.contacts and len(self.coordinates) != n:
            raise InputError(f"model {self.name!r}: contacts need one coordinate per joint")
        if len({c.name for c in self.contacts}) != len(self.contacts):
            raise InputError(f"model {self.name!r}: two contacts share a name")
        if self.joints is not None:
            self.joints = tuple(self.joints)
            if len(self.joints) != n:
                raise InputError(f"joints must name the kind of each of the {n} coordinates, got {len(self.joints)}")
            joint_units(self.joints)        # one sentence for an unknown kind
        if self.spring_rest is not None:
            self.spring_rest = tuple(float(x) for x in self.spring_rest)
            if len(self.spring_rest) != n or len(self.coordinates) != n:
                raise InputError(f"spring_rest needs {n} entries and the model {n} coordinates")
        self._compiled = None
        self._rebuilt: dict = {}

    def with_parameters(self, parameters: Mapping[str, float] | None = None) -> "Model":
        """The model at other parameter values: rebuilt by its builder, else itself.

        Parameters
        ----------
        parameters : mapping, optional
            Overrides of :attr:`parameters` by name.
        """
        if self.builder is None or not parameters:
            return self
        values = dict(self.parameters)
        for key, value in parameters.items():
            if key not in values:
                raise InputError(f"model {self.name!r} has no parameter {key!r} "
                                 f"(it has: {', '.join(values)})")
            values[key] = float(value)
        if values == self.parameters:
            return self
        key = tuple(sorted(values.items()))
        if key not in self._rebuilt:
            self._rebuilt[key] = self.builder(**values)
        return self._rebuilt[key]

    def linear_parts(self) -> tuple:
        """M, B, the linearised stiffness K + ∂G/∂q and the static load G + K·(q − rest), symbolically."""
        stiffness, load = self.stiffness, self.gravity
        q = sp.Matrix(self.coordinates)
        if load is not None and self.coordinates and load.free_symbols & set(self.coordinates):
            hessian = load.jacobian(q)
            stiffness = hessian if stiffness is None else stiffness + hessian
        elastic = self.spring_load()
        if elastic is not None:
            load = elastic if load is None else load + elastic
        damping = self.damping
        if self.contacts:        # −τ_c(q, q̇) at rest, and its slopes: the ground's share of G, K and B
            rates = sp.symbols(f"qd1:{self.dof + 1}", real=True)
            tau = generalised_contact_forces(self.contacts, q, [c.force(q, rates) for c in self.contacts])
            at_rest = dict.fromkeys(rates, 0)
            static = (-tau).xreplace(at_rest)
            load = static if load is None else load + static
            stiffness = static.jacobian(q) if stiffness is None else stiffness + static.jacobian(q)
            damping = damping - tau.jacobian(sp.Matrix(rates)).xreplace(at_rest)
        return self.mass_matrix, damping, stiffness, load

    def spring_load(self) -> "sp.Matrix | None":
        """The springs' static load K·(q − rest), symbolically; None without springs or a rest pose."""
        if self.spring_rest is None or self.stiffness is None or not any(self.stiffness):
            return None
        return self.stiffness * (sp.Matrix(self.coordinates) - sp.Matrix(self.spring_rest))

    nonlinear = True

    @property
    def dof(self) -> int:
        return self.mass_matrix.rows

    @property
    def elastic(self) -> tuple[int, ...]:
        """The coordinates (0-based) that carry a spring of the model's own: the rows of K that are not zero."""
        k = self.stiffness
        if k is None:
            return ()
        return tuple(i for i in range(k.rows) if any(not entry.is_zero for entry in k.row(i)))

    @property
    def symbols(self):
        """Parameter symbols, by name, that the matrices may contain."""
        return {name: sp.Symbol(name, real=True) for name in self.parameters}

    def _compile(self):
        # Lambdify once per model; evaluation at many configurations reuses it.
        params = list(self.symbols.values())
        args = list(self.coordinates) + params
        free = set()
        parts = list(self.linear_parts())
        for p in parts:
            if p is not None:
                free |= p.free_symbols
        unknown = sorted(str(s) for s in free - set(args))
        if unknown:
            raise InputError(f"model {self.name!r} uses symbols with no value: {', '.join(unknown)}")
        # Common-subexpression elimination pays off for large matrices only; it costs
        # ~0.1 s even on a 2x2 one.
        # Each part returns its entries flat, so that arrays of configurations broadcast.
        fns = [None if p is None else _lambdify(args, list(p), modules="numpy",
                                                  cse=sp.count_ops(p) > 400)
               for p in parts]
        self._compiled = (fns, [str(s) for s in self.coordinates], list(self.parameters))
        return self._compiled

    def _shapes(self):
        return part_shapes(self.dof)

    def joint_stack(self, qs, parameters: Mapping[str, float] | None = None) -> JointStack:
        """Evaluate at every row of *qs* at once (vectorised over configurations).

        The values are not checked; :func:`analogy.circuit.node_system.node_systems` checks the stack.

        Parameters
        ----------
        qs : array_like, shape (count, n)
            Configurations.
        parameters : mapping, optional
            Parameter overrides.
        """
        if self.builder is not None and parameters:
            if any(np.ndim(v) for v in parameters.values()):
                raise InputError(f"model {self.name!r} is rebuilt for new parameter values, "
                                 "so its parameters cannot vary along a stack")
            rebuilt = self.with_parameters(parameters)
            if rebuilt is not self:
                return rebuilt.joint_stack(qs)
        check_contact_values(self.contacts, {**self.parameters, **(parameters or {})})
        fns, qnames, _ = self._compiled or self._compile()
        q = configuration_stack(self.name, qnames, qs)
        args = list(q.T) + stack_arguments(self.name, self.parameters, parameters, len(q))
        return JointStack(*(evaluate_entries(self.name, f, args, shape, len(q))
                            for f, shape in zip(fns, self._shapes())))


    def mechanical_functions(self, parameters: Mapping[str, float] | None = None) -> MechanicalFunctions:
        """M(q), c(q, q̇) and G(q) compiled at fixed parameter values, for nonlinear dynamics.

        Parameters
        ----------
        parameters : mapping, optional
            Overrides of :attr:`parameters` by name.

        Raises
        ------
        InputError
            If B or K depend on q (the nonlinear node dynamics take them constant), or
            the model's coordinates do not match its joints.
        """
        if self.builder is not None and parameters:
            rebuilt = self.with_parameters(parameters)
            if rebuilt is not self:
                return rebuilt.mechanical_functions()
        values = dict(self.parameters)
        for key, value in (parameters or {}).items():
            if key not in values:
                raise InputError(f"model {self.name!r} has no parameter {key!r} "
                                 f"(it has: {', '.join(values) or 'none'})")
            values[key] = float(value)
        check_contact_values(self.contacts, values)
        cache = self.__dict__.setdefault("_mechanical", {})
        key = tuple(sorted(values.items()))
        if key not in cache:        # derived and compiled once per parameter set
            cache[key] = self._mechanical_functions(values)
        return cache[key]

    def _mechanical_functions(self, values: dict) -> MechanicalFunctions:
        subs = {sym: values[name] for name, sym in self.symbols.items()}
        n = self.dof
        q = list(self.coordinates)
        if q and len(q) != n:
            raise InputError(f"model {self.name!r} has {len(q)} coordinates for {n} joints: "
                             "nonlinear dynamics need one coordinate per joint")
        if not q:
            q = list(sp.symbols(f"q1:{n + 1}", real=True))
        rates = list(sp.symbols(f"qd1:{n + 1}", real=True))
        mass = self.mass_matrix.subs(subs)
        constant = {}
        for label, mat in (("damping", self.damping), ("stiffness", self.stiffness)):
            if mat is None:
                constant[label] = None
                continue
            mat = mat.subs(subs)
            if mat.free_symbols:
                raise InputError(f"model {self.name!r}: its {label} depends on "
                                 f"{', '.join(sorted(map(str, mat.free_symbols)))}; nonlinear "
                                 "dynamics take B and K constant")
            constant[label] = np.array(mat.tolist(), dtype=float)
        c = velocity_terms(mass, q, rates)
        gravity = None if self.gravity is None else self.gravity.subs(subs)
        unknown = (mass.free_symbols | c.free_symbols |
                   (gravity.free_symbols if gravity is not None else set())) - set(q) - set(rates)
        if unknown:
            raise InputError(f"model {self.name!r} uses symbols with no value: "
                             f"{', '.join(sorted(map(str, unknown)))}")
        cse = sp.count_ops(c) > 400
        m_fn = _lambdify([q], mass, modules="numpy", cse=cse)
        c_fn = _lambdify([q, rates], list(c), modules="numpy", cse=cse)
        g_fn = None if gravity is None or not any(gravity) else \
            _lambdify([q], list(gravity), modules="numpy")

        def mass_at(x):
            return np.asarray(m_fn(x), dtype=float)

        def velocity_at(x, r):
            return np.asarray(c_fn(x, r), dtype=float).reshape(n)

        def gravity_at(x):
            return np.asarray(g_fn(x), dtype=float).reshape(n)

        def stacked(entries, shape):
            """The flat *entries* of a stack of poses (m, n) at once, compiled on first use: numpy
            broadcasts each entry over the stack, a constant one too."""
            compiled: list = []

            def at(qs):
                if not compiled:
                    compiled.append(_lambdify([q], entries, modules="numpy", cse=cse))
                qs = np.asarray(qs, dtype=float)
                values = compiled[0](qs.T)
                out = np.stack([np.broadcast_to(np.asarray(e, dtype=float), qs.shape[:1]) for e in values], axis=-1)
                return out.reshape(qs.shape[:1] + shape)
            return at

        # Derivatives for the analytic Jacobian of the implicit integrators.
        qm, rm = sp.Matrix(q), sp.Matrix(rates)
        g_vec = gravity if gravity is not None and any(gravity) else sp.zeros(n, 1)
        parts = [[mass.diff(qk) for qk in q], c.jacobian(qm), c.jacobian(rm), g_vec.jacobian(qm)]
        d_fn = _lambdify([q, rates], parts, modules="numpy", cse=cse)

        def derivatives_at(x, r):
            dm, dcq, dcr, dg = d_fn(x, r)
            return (np.array(dm, dtype=float).reshape(n, n, n), np.array(dcq, dtype=float).reshape(n, n),
                    np.array(dcr, dtype=float).reshape(n, n), np.array(dg, dtype=float).reshape(n, n))

        return MechanicalFunctions(mass_at, velocity_at, None if g_fn is None else gravity_at,
                                   constant["damping"] if constant["damping"] is not None
                                   else np.zeros((n, n)), constant["stiffness"], derivatives_at,
                                   masses=stacked(list(mass), (n, n)),
                                   gravities=None if g_fn is None else stacked(list(gravity), (n,)),
                                   contacts=self._contact_functions(subs, q, rates))

    def _contact_functions(self, subs: dict, q: list, rates: list) -> ContactFunctions | None:
        """The contacts' forces compiled at parameter values *subs*: τ_c, its derivatives, each f_c."""
        if not self.contacts:
            return None
        n = self.dof
        at = dict(zip(self.coordinates, q))
        forces = [c.force(self.coordinates, rates).xreplace(subs).xreplace(at) for c in self.contacts]
        unknown = set().union(*(f.free_symbols for f in forces)) - set(q) - set(rates)
        if unknown:
            raise InputError(f"model {self.name!r}: its contacts use symbols with no value: "
                             f"{', '.join(sorted(map(str, unknown)))}")
        tau = generalised_contact_forces(self.contacts, self.coordinates, forces).xreplace(subs).xreplace(at)
        tau_fn = _lambdify([q, rates], list(tau), modules="numpy")
        d_fn = _lambdify([q, rates], [tau.jacobian(sp.Matrix(q)), tau.jacobian(sp.Matrix(rates))], modules="numpy")
        f_fn = _lambdify([q, rates], forces, modules="numpy")
        heights = [sp.sympify(c.height).xreplace(subs).xreplace(at) for c in self.contacts]
        p_fn = _lambdify([q], [-h for h in heights], modules="numpy")
        smoothing = tuple(float(sp.sympify(c.smoothing).xreplace(subs)) for c in self.contacts)

        def generalised(x, r):
            x, r = np.asarray(x, dtype=float), np.asarray(r, dtype=float)
            return np.stack([np.broadcast_to(np.asarray(v, dtype=float), x.shape[1:]) for v in tau_fn(x, r)])

        def derivatives(x, r):
            dq, dr = d_fn(x, r)
            return np.array(dq, dtype=float).reshape(n, n), np.array(dr, dtype=float).reshape(n, n)

        def normal(x, r):
            x, r = np.asarray(x, dtype=float), np.asarray(r, dtype=float)
            values = f_fn(x, r)
            return np.stack([np.broadcast_to(np.asarray(v, dtype=float), x.shape[1:]) for v in values])

        def depths(x):
            x = np.asarray(x, dtype=float)
            return np.stack([np.broadcast_to(np.asarray(v, dtype=float), x.shape[1:]) for v in p_fn(x)])

        return ContactFunctions(generalised, derivatives, normal, depths, tuple(c.name for c in self.contacts),
                                smoothing)
