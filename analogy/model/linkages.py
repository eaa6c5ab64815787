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
from .assembly import SINGULAR_CONDITION, AssemblySolver
from .dynamics import MechanicalFunctions
from .joint import JointSpace, JointStack, configuration_stack, evaluate_entries, evaluation_arguments
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

    closed_chain = True
    #: Largest first Newton correction (rad, or m) accepted in one continuation step.
    max_correction = 0.2
    #: Equilibrated condition number of Φ_p (see :meth:`pose_condition`) above which q is singular:
    #: 1/√ε, where the passive rates ∂p/∂q have lost half their digits (the five-bar stretched
    #: straight lands there about 1e-8 off the singular set, at 2e8).
    max_condition = 1.0 / np.sqrt(np.finfo(float).eps)

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

    def pose_condition(self, q: Sequence[float], parameters: Mapping[str, float] | None = None) -> float:
        """The equilibrated condition number of Φ_p at *q*: its rows and columns scaled by the
        lengths they have at the reference assembly, as :meth:`loop_closure` scales by a run's start.

        Parameters
        ----------
        q : sequence of float
            Actuated joint angles.
        parameters : mapping, optional
            Parameter overrides.
        """
        p, _ = self.assemble(q, parameters)
        values = {**self.parameters, **(parameters or {})}
        return self._assembly.condition(np.asarray(q, dtype=float).reshape(-1), p,
                                        tuple(float(values[k]) for k in self.parameters))

    def pose_note(self, q: Sequence[float], parameters: Mapping[str, float] | None = None) -> str | None:
        """The sentence said of a linear circuit at *q* near a singular pose of the loop; None away from one.

        Parameters
        ----------
        q : sequence of float
            Actuated joint angles.
        parameters : mapping, optional
            Parameter overrides.
        """
        cond = self.pose_condition(q, parameters)
        if cond < SINGULAR_CONDITION:
            return None
        pose = ", ".join(f"{x:.6g}" for x in np.asarray(q, dtype=float).reshape(-1))
        return (f"q = ({pose}) is near a singular pose of the loop (equilibrated cond(Φ_p) = {cond:.3g}, past "
                f"{SINGULAR_CONDITION:g}): the passive joints' rates, and the capacitances built from them, change "
                "fast with q here, so the linear circuit holds for small motions only")

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
        if self.builder is not None and parameters:
            rebuilt = self.with_parameters(parameters)
            if rebuilt is not self:
                return rebuilt.joint_stack(qs)
        fns, qnames, _ = self._compiled or self._compile()
        spaces = []
        for row in configuration_stack(self.name, qnames, qs):
            args = evaluation_arguments(self.name, qnames, self.parameters, row, parameters)
            spaces.append(JointSpace(*(evaluate_entries(self.name, f, args, shape)
                                       for f, shape in zip(fns, self._shapes()))))
        return JointStack.of(spaces)

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
        solve = AssemblySolver(self, kin, n, pnames)

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
