"""Closed kinematic chains: M(q) = Sᵀ·M_θ(q, p)·S with passive coordinates p(q) from loop closure.

Cut open, the chain is a tree over θ = (q, p) with mass matrix M_θ(θ), velocity terms
c_θ(θ, θ̇) and the loop closure Φ(θ) = 0 as constraints: M_θ·θ̈ + c_θ = E·τ + Φ_θᵀ·λ.
On the constraint θ̇ = S·q̇ with S = [I; G], so θ̈ = S·q̈ + (0, p̈₀), where
p̈₀ = −Φ_p⁻¹·(∂(Φ_θ·θ̇)/∂θ)·θ̇ is the passive acceleration at q̈ = 0. SᵀΦ_θᵀ = 0 and SᵀE = I
leave M(q)·q̈ + Sᵀ·(M_θ·(0, p̈₀) + c_θ) = τ: the velocity terms of the active joints
(:meth:`ClosedChainModel.mechanical_functions`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
import sympy as sp
from sympy.simplify.fu import TR8

from ..errors import InputError
from .dynamics import MechanicalFunctions
from .joint import JointStack, configuration_stack
from .symbolic import Model

__all__ = ["link_mass_matrix", "ClosedChainModel"]


def link_mass_matrix(links: Sequence, coordinates: Sequence) -> sp.Matrix:
    """Mass matrix of planar links: Σ m·J_cᵀ·J_c + I·J_φᵀ·J_φ.

    Parameters
    ----------
    links : sequence of (mass, inertia, position, angle)
        Mass, rotational inertia about the centre of mass, centre-of-mass
        position (sympy column vector, any dimension) and absolute angle of
        each link; a point mass has inertia 0 and angle None.
    coordinates : sequence of sympy Symbol
        The coordinates θ the positions and angles depend on.
    """
    theta = sp.Matrix(list(coordinates))
    m = sp.zeros(len(theta))
    for mass, inertia, position, angle in links:
        jc = sp.Matrix(position).jacobian(theta)
        m += mass * (jc.T * jc)
        if angle is not None and inertia != 0:
            jw = sp.Matrix([angle]).jacobian(theta)
            m += inertia * (jw.T * jw)
    # Product-to-sum turns l²·(sin²θ + cos²θ) into l² and cross terms into cos(θi − θj),
    # exactly and far faster than trigsimp (which takes minutes for a 4R arm); pulling
    # out common factors, d3·l3·(…), saves roundings when the entry is evaluated.
    return m.applyfunc(lambda e: sp.factor_terms(sp.expand(TR8(sp.expand(e)))))


@dataclass
class ClosedChainModel(Model):
    """A mechanism whose passive coordinates p are fixed by loop-closure constraints Φ(q, p) = 0.

    :attr:`mass_matrix` is M = Sᵀ·M_θ·S with S = [I; G], where M_θ is the mass
    matrix in all coordinates (q, p) and G = ∂p/∂q = −Φ_p⁻¹·Φ_q is held by the
    symbols :attr:`rates`. Evaluating at q solves Φ = 0 for p, computes G from
    the symbolic Jacobians Φ_p, Φ_q, and evaluates M; everything is compiled
    once per model.

    The assembly mode is the one reached from ``reference(parameters)``, a valid
    assembly (q_ref, p_ref), by continuation along the segment from q_ref to q
    (predictor ∂p/∂q, Newton corrector). A segment that crosses a singular
    configuration (det Φ_p changes sign) or leaves the workspace is an error.

    Parameters
    ----------
    passive : sequence of sympy Symbol
        Passive coordinates p.
    rates : sympy Matrix
        Symbols standing for ∂p_i/∂q_j, shape (len(p), len(q)).
    constraints : sympy Matrix
        Loop-closure residual Φ(q, p), one entry per passive coordinate.
    reference : callable
        Maps a dict of parameter values to (q_ref, p_ref) in the working mode.
    tree_mass : sympy Matrix, optional
        M_θ over (q, p), the chain cut open (needed for its nonlinear dynamics).
    tree_gravity : sympy Matrix, optional
        G_θ over (q, p), the cut-open chain's gravity load; :attr:`gravity` is then Sᵀ·G_θ.
    branch : callable, optional
        Maps (q, parameter values) to an exact assembly (q_b, p_b) of the working mode near
        q, to continue from instead of the reference: for a mode known in closed form on
        both sides of a singular pose (a parallelogram folding flat).

    Notes
    -----
    Linearised at q, gravity's stiffness is the second derivative of U(θ(q)) along the
    loop: ∂(Sᵀ·G_θ)/∂q = Sᵀ·(∂G_θ/∂θ)·S − Σ_c μ_c·Sᵀ·∇²Φ_c·S, with μ = Φ_p⁻ᵀ·G_p the
    multipliers that hold gravity (from Φ_θ·S = 0 differentiated along the loop). It is
    added to :attr:`stiffness` when the model is evaluated.
    """

    passive: Sequence = ()
    rates: object = None
    constraints: object = None
    reference: Callable | None = None
    tree_mass: object = None
    tree_gravity: object = None
    branch: Callable | None = None

    #: Largest first Newton correction (rad, or m) accepted in one continuation step.
    max_correction = 0.2
    #: Condition number of Φ_p above which q counts as singular.
    max_condition = 1e10

    def __post_init__(self):
        super().__post_init__()
        self.passive = tuple(self.passive)
        self.constraints = sp.ImmutableMatrix(self.constraints)
        self.rates = sp.ImmutableMatrix(self.rates)
        m, n = len(self.passive), len(self.coordinates)
        if self.constraints.shape != (m, 1) or self.rates.shape != (m, n) or self.dof != n:
            raise InputError(f"closed chain {self.name!r}: need {m} constraints, {m}x{n} rates "
                             f"and an {n}x{n} mass matrix")
        if self.reference is None:
            raise InputError(f"closed chain {self.name!r} needs a reference assembly")

    @classmethod
    def from_links(cls, name: str, links: Sequence, coordinates: Sequence, passive: Sequence,
                   constraints, reference: Callable, **kw) -> "ClosedChainModel":
        """Build M = Sᵀ·M_θ·S from planar links over (q, p); see :func:`link_mass_matrix`.

        Parameters
        ----------
        name : str
            The model's name.
        links : sequence
            Planar links (see :func:`link_mass_matrix`).
        coordinates : sequence of sympy Symbol
            Actuated joint angles q.
        passive : sequence of sympy Symbol
            Passive joint angles p.
        constraints : sequence of sympy expressions
            Loop-closure equations in q and p.
        reference : callable
            Assembly at a reference configuration, for continuation.
        **kw
            Further :class:`ClosedChainModel` fields.
        """
        q, p = list(coordinates), list(passive)
        rates = sp.Matrix(len(p), len(q), lambda i, j: sp.Symbol(f"d{p[i]}_d{q[j]}", real=True))
        s = sp.eye(len(q)).col_join(rates)
        full = link_mass_matrix(links, q + p)
        mass = sp.ImmutableMatrix((s.T * full * s).applyfunc(sp.expand))
        return cls(name, mass, coordinates=q, passive=p, rates=rates,
                   constraints=sp.Matrix(constraints), reference=reference, tree_mass=sp.ImmutableMatrix(full), **kw)

    def open_tree(self) -> Model:
        """The chain cut open: M_θ over all its joints (q, p), the joint dampers and springs on q.

        Its own dynamics are the chain's without the loop closure; the constraint forces
        Φ_θᵀ·λ are what hold it closed (see :mod:`analogy.circuit.constrained_circuit`).
        """
        if self.tree_mass is None:
            raise InputError(f"closed chain {self.name!r} keeps no tree mass matrix: its nonlinear "
                             "dynamics are not built")
        m = len(self.passive)

        def padded(matrix):
            if matrix is None:
                return None
            full = sp.zeros(self.dof + m)
            full[:self.dof, :self.dof] = matrix
            return full
        return Model(f"{self.name} (cut open)", self.tree_mass, damping=padded(self.damping),
                     stiffness=padded(self.stiffness), gravity=self.tree_gravity, parameters=self.parameters,
                     coordinates=tuple(self.coordinates) + self.passive, topology="parallel")

    def loop_closure(self, thetas, parameters: Mapping[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """|Φ(θ)| and the equilibrated condition number of Φ_p at each row of *thetas* = (q, p).

        Φ_p's rows and columns are scaled by the lengths they have at the first row (the
        run's start), so that the condition number does not depend on units (metres
        against radians); scaled at each pose instead, a row that vanishes at a singular
        pose would be blown up and hide it. It grows without bound at a singular pose,
        where the passive joints lose their solution and the constraint forces grow as
        its inverse.

        Parameters
        ----------
        thetas : array_like, shape (count, dof + passive)
            Poses of every joint, active first.
        parameters : mapping, optional
            Parameter overrides.
        """
        values = {**self.parameters, **(parameters or {})}
        theta = list(self.coordinates) + list(self.passive)
        subs = {sym: values[name] for name, sym in self.symbols.items()}
        phi = self.constraints.subs(subs)
        residual = sp.lambdify([theta], list(phi), cse=True)
        jac = sp.lambdify([theta], phi.jacobian(list(self.passive)), cse=True)
        rows = np.atleast_2d(np.asarray(thetas, dtype=float))
        size = np.array([np.max(np.abs(np.asarray(residual(r), dtype=float))) for r in rows])
        start = np.asarray(jac(rows[0]), dtype=float)
        columns = np.linalg.norm(start, axis=0)
        lines = np.linalg.norm(start / columns, axis=1)
        conds = [np.linalg.cond(np.asarray(jac(r), dtype=float) / columns / lines[:, None]) for r in rows]
        return size, np.array(conds)

    def mechanical_functions(self, parameters: Mapping[str, float] | None = None) -> MechanicalFunctions:
        """M(q) = SᵀM_θS and c(q, q̇) = Sᵀ·(M_θ·(0, p̈₀) + c_θ(θ, S·q̇)) at fixed parameters (see the module).

        Parameters
        ----------
        parameters : mapping, optional
            Overrides of :attr:`parameters` by name.
        """
        values = dict(self.parameters)
        for key, value in (parameters or {}).items():
            if key not in values:
                raise InputError(f"model {self.name!r} has no parameter {key!r} (it has: {', '.join(values)})")
            values[key] = float(value)
        cache = self.__dict__.setdefault("_mechanical", {})
        key = tuple(sorted(values.items()))
        if key not in cache:
            cache[key] = self._constrained_functions(values)
        return cache[key]

    def _constrained_functions(self, values: dict) -> MechanicalFunctions:
        tree = self.open_tree().mechanical_functions(values)
        n, m = self.dof, len(self.passive)
        theta = list(self.coordinates) + list(self.passive)
        rates = sp.symbols(f"thetad1:{n + m + 1}", real=True)
        subs = {sym: values[name] for name, sym in self.symbols.items()}
        phi = self.constraints.subs(subs)
        drift = phi.jacobian(theta) * sp.Matrix(rates)          # Φ_θ·θ̇
        quadratic = sp.lambdify([theta, rates], list(drift.jacobian(theta) * sp.Matrix(rates)), cse=True)
        jac_p = sp.lambdify([theta], phi.jacobian(list(self.passive)), cse=True)

        def state(q, r=None):
            p, g = self.assemble(q, values)
            s = np.vstack([np.eye(n), g])
            return np.concatenate([q, p]), s

        def mass(q):
            th, s = state(np.asarray(q, dtype=float))
            return s.T @ tree.mass(th) @ s

        def velocity(q, r):
            th, s = state(np.asarray(q, dtype=float))
            thd = s @ np.asarray(r, dtype=float)
            passive = -np.linalg.solve(np.asarray(jac_p(th), dtype=float),
                                       np.asarray(quadratic(th, thd), dtype=float).reshape(m))
            return s.T @ (tree.mass(th) @ np.concatenate([np.zeros(n), passive]) + tree.velocity(th, thd))

        gravity = None
        if tree.gravity is not None:
            def gravity(q):
                th, s = state(np.asarray(q, dtype=float))
                return s.T @ tree.gravity(th)
        return MechanicalFunctions(mass, velocity, gravity, tree.damping[:n, :n],
                                   None if tree.stiffness is None else tree.stiffness[:n, :n])

    def joint_stack(self, qs, parameters=None) -> JointStack:
        """Evaluate configuration by configuration: each needs its own assembly solve.

        Parameters
        ----------
        qs : array_like, shape (count, n)
            Configurations.
        parameters : mapping, optional
            Parameter overrides.
        """
        q = configuration_stack(self.name, [str(c) for c in self.coordinates], qs)
        return JointStack.of([self.joint_space(row, parameters) for row in q])

    def _compile(self):
        # Lambdify once per model; every evaluation reuses these functions.
        q, p = list(self.coordinates), list(self.passive)
        g = list(self.rates)
        params = list(self.symbols.values())
        full_args = q + p + g + params
        phi = self.constraints
        unknown = set(phi.free_symbols) - set(q + p + params)
        load, elastic = self.gravity, self.spring_load()
        if elastic is not None:
            load = elastic if load is None else load + elastic
        parts = [self.mass_matrix, self.damping, self.stiffness, load]
        for part in parts:
            if part is not None:
                unknown |= part.free_symbols - set(full_args)
        if unknown:
            raise InputError(f"model {self.name!r} uses symbols with no value: "
                             f"{', '.join(sorted(map(str, unknown)))}")

        def lam(expr, args):
            return sp.lambdify(args, expr, modules="numpy", cse=True)

        kin_args = q + p + params
        kin = (lam(phi, kin_args), lam(phi.jacobian(p), kin_args), lam(phi.jacobian(q), kin_args))
        fns = [None if part is None else lam(part, full_args) for part in parts]
        if self.tree_gravity is not None:
            fns[2] = _with_gravity_stiffness(fns[2], self, lam, len(q), len(p))
        n, pnames = len(q), list(self.parameters)
        solve = _AssemblySolver(self, kin, n, pnames)

        def wrap(fn):
            if fn is None:
                return None

            def evaluate(*args):
                pv, gv = solve(args)
                return fn(*args[:n], *pv, *gv.reshape(-1), *args[n:])
            return evaluate

        self._assembly = solve
        self._compiled = ([wrap(f) for f in fns], [str(s) for s in q], pnames)
        return self._compiled

    def assemble(self, q: Sequence[float], parameters: Mapping[str, float] | None = None) -> np.ndarray:
        """Passive coordinates p(q) and rates G = ∂p/∂q in the model's assembly mode.

        Parameters
        ----------
        q : sequence of float
            Actuated joint angles.
        parameters : mapping, optional
            Parameter overrides.

        Returns
        -------
        p : ndarray, shape (m,)
        rates : ndarray, shape (m, n)
        """
        if self._compiled is None:
            self._compile()
        values = dict(self.parameters)
        for key, value in (parameters or {}).items():
            if key not in values:
                raise InputError(f"model {self.name!r} has no parameter {key!r}")
            values[key] = value
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.size != self.dof:
            raise InputError(f"model {self.name!r} needs {self.dof} joint coordinates, got {q.size}")
        p, rates = self._assembly(tuple(q) + tuple(float(values[k]) for k in self.parameters))
        return p.copy(), rates.copy()


#: A pose this close (rad, or m) to the last one solved continues from it, not from the reference.
_NEAR = 0.05
#: Continuation steps from the reference assembly to the asked configuration (each a few Newton
#: iterations); a pose many turns away would otherwise take minutes.
_MAX_CONTINUATION_STEPS = 2000


class _AssemblySolver:
    """Numeric loop closure by continuation from the reference assembly; remembers the last answer."""

    def __init__(self, model: ClosedChainModel, kin, n: int, pnames: list[str]):
        self.model, self.n, self.pnames = model, n, pnames
        self.residual, self.jac_p, self.jac_q = kin
        self.last = (None, None)
        self.references = {}

    def __call__(self, args):
        key = tuple(float(a) for a in args)
        if self.last[0] == key:
            return self.last[1]
        q, params = np.array(key[:self.n]), key[self.n:]
        if self.model.branch is not None:
            q0, p0 = (np.asarray(a, dtype=float).reshape(-1)
                      for a in self.model.branch(q, dict(zip(self.pnames, params))))
        else:
            q0, p0 = self._reference(params)
        near = self.last[0]
        if near is not None and near[self.n:] == params and np.max(np.abs(q - near[:self.n]), initial=0) <= _NEAR:
            q0, p0 = np.array(near[:self.n]), self.last[1][0]     # along a trajectory: from the last pose
        p = self._continue(q0, p0, q, params)
        jp = self._jp(q, p, params)
        if np.linalg.cond(jp) > self.model.max_condition:
            raise InputError(f"model {self.model.name!r} is singular at q = {_fmt(q)}")
        rates = -np.linalg.solve(jp, self._jq(q, p, params))
        self.last = (key, (p, rates))
        return p, rates

    def _r(self, q, p, params):
        return np.asarray(self.residual(*q, *p, *params), dtype=float).reshape(-1)

    def _jp(self, q, p, params):
        return np.asarray(self.jac_p(*q, *p, *params), dtype=float)

    def _jq(self, q, p, params):
        return np.asarray(self.jac_q(*q, *p, *params), dtype=float)

    def _reference(self, params):
        if params not in self.references:
            values = dict(zip(self.pnames, params))
            try:
                q0, p0 = (np.asarray(a, dtype=float).reshape(-1) for a in self.model.reference(values))
                p0 = self._newton(q0, p0, params)
            except (ValueError, ZeroDivisionError, FloatingPointError, np.linalg.LinAlgError):
                p0 = None
            if p0 is None:
                raise InputError(f"model {self.model.name!r} has no reference assembly "
                                 f"with these parameters")
            self.references[params] = (q0, p0)
        return self.references[params]

    def _newton(self, q, p, params):
        # Quadratic convergence is required: a slow or growing correction means the
        # predictor was too far from this branch, and the caller shortens the step.
        p = np.array(p, dtype=float)
        previous = np.inf
        for k in range(30):
            if not np.all(np.isfinite(p)):
                return None
            delta = np.linalg.solve(self._jp(q, p, params), self._r(q, p, params))
            size = float(np.max(np.abs(delta))) if delta.size else 0.0
            if not np.isfinite(size) or (k == 0 and size > self.model.max_correction):
                return None
            p -= delta
            if size <= 1e-12:
                p -= np.linalg.solve(self._jp(q, p, params), self._r(q, p, params))
                return p
            if size > 0.5 * previous:
                return None
            previous = size
        return None

    def _continue(self, q0, p0, q1, params):
        dq = q1 - q0

        def at(s):
            return q1 if s == 1.0 else q0 + s * dq

        sign = np.sign(np.linalg.det(self._jp(q0, p0, params)))
        s, h, p = 0.0, 1.0, p0
        for _ in range(_MAX_CONTINUATION_STEPS):
            if s >= 1.0:
                break
            # s and h stay dyadic, so the last step lands on s = 1 exactly.
            h = min(h, 1.0 - s)
            qs = at(s)
            try:
                tangent = -np.linalg.solve(self._jp(qs, p, params), self._jq(qs, p, params) @ dq)
                trial = self._newton(at(s + h), p + h * tangent, params)
            except np.linalg.LinAlgError:
                trial = None
            if trial is not None and np.sign(np.linalg.det(self._jp(at(s + h), trial, params))) == sign:
                p, s, h = trial, s + h, 2.0 * h
                continue
            h *= 0.5
            if h < 1e-6:
                why = (f": the loop meets a singular pose near q = {_fmt(qs)}, where the active joints do not "
                       "determine the passive ones (links in line, a parallelogram folded flat); choose a pose "
                       "away from it") if np.linalg.cond(self._jp(qs, p, params)) > _SINGULAR else \
                    f" (continuation from q = {_fmt(q0)} fails near q = {_fmt(qs)})"
                raise InputError(f"model {self.model.name!r} does not assemble at q = {_fmt(q1)} "
                                 f"in its working mode{why}", field="q")
        if s < 1.0:
            raise InputError(f"model {self.model.name!r}: q = {_fmt(q1)} is too far from its reference assembly "
                             f"q = {_fmt(q0)} to follow the loop there in {_MAX_CONTINUATION_STEPS:,} steps: give "
                             "joint angles within a few turns of it", field="q")
        return p


#: cond(Φ_p) past which a failed continuation is reported as a singular pose (1/√ε: the passive
#: joints' solve has lost half its digits there).
_SINGULAR = 1.0 / np.sqrt(np.finfo(float).eps)


def _with_gravity_stiffness(stiffness, model: ClosedChainModel, lam, n: int, m: int):
    """K(q) + ∂(Sᵀ·G_θ)/∂q along the loop (see :class:`ClosedChainModel`), on the compiled arguments."""
    theta = list(model.coordinates) + list(model.passive)
    args = theta + list(model.symbols.values())
    load = sp.Matrix(list(model.tree_gravity))
    hessian = lam(load.jacobian(theta), args)
    phi = model.constraints
    curvature = lam([phi[c].diff(a, b) for c in range(m) for a in theta for b in theta], args)
    jac_p = lam(phi.jacobian(list(model.passive)), args)
    gravity = lam(load, args)

    def evaluate(*values):
        th, rates, params = values[:n + m], values[n + m:n + m + m * n], values[n + m + m * n:]
        s = np.vstack([np.eye(n), np.asarray(rates, dtype=float).reshape(m, n)])
        g = np.asarray(gravity(*th, *params), dtype=float).reshape(-1)
        mu = np.linalg.solve(np.asarray(jac_p(*th, *params), dtype=float).T, g[n:])
        curv = np.asarray(curvature(*th, *params), dtype=float).reshape(m, n + m, n + m)
        k = s.T @ (np.asarray(hessian(*th, *params), dtype=float) - np.tensordot(mu, curv, 1)) @ s
        if stiffness is not None:
            k = k + np.asarray(stiffness(*values), dtype=float).reshape(n, n)
        return list(k.reshape(-1))
    return evaluate


def _fmt(q) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in q) + ")"
