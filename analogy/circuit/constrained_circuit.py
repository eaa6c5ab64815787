"""A closed chain's nonlinear circuit: a node per joint of the cut-open tree, the loop closure as constraint branches.

Cut open, the chain is a tree over θ = (q, p), the active joints first: its nonlinear
circuit (charge-defined capacitors M_θ(x), behavioural velocity terms, integrators)
has a node per joint, the joint forces at the active nodes only. Each loop-closure
equation Φ_c(θ) = 0 adds a node λ_c, whose voltage is its Lagrange multiplier:

- a behavioural current J_ck(x)·v(λ_c) into every joint node k (J = ∂Φ/∂θ), the
  constraint force Jᵀλ;
- a behavioural current J_c(x)·v + α·Φ_c(x) into node λ_c and nothing else. Kirchhoff's
  current law at that node is the constraint itself, held at velocity level with a
  Baumgarte term: Φ̇ = −α·Φ pulls the drift of the integrated positions back.

The nodal equations are then the constrained Lagrange equations
M_θ·θ̈ + c_θ = E·τ + Jᵀλ, J·θ̇ = −α·Φ: an index-2 system of differential-algebraic
equations, which ngspice integrates as it does any circuit. α = 100/t_stop relaxes the
drift in a hundredth of the run, and keeps α·h ≤ 0.1 at the presets' step caps, where
the trapezoidal rule damps it without ringing.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from ..errors import InputError
from .elements import ZERO_TOL
from .nonlinear import NonlinearNodeSystem
from .nonlinear_circuit import node_lagrangian, nonlinear_circuit, spice_text
from .parts import BehaviouralCurrent, Circuit, ConstraintCurrent, Integrator, comments
from .topology import topology as make_topology

__all__ = ["BAUMGARTE_RUNS", "open_system", "constrained_circuit"]

#: α·t_stop: how many times over the run the constraint drift relaxes by e.
BAUMGARTE_RUNS = 100.0


def open_system(system) -> NonlinearNodeSystem:
    """The closed chain *system* cut open: every joint a node (active first), at its assembled start.

    Parameters
    ----------
    system : NonlinearNodeSystem
        A closed chain's nonlinear system (its model has passive joints).
    """
    model = system.model
    p0, rates = model.assemble(system.q0, system.parameters)
    n, m = system.dof, len(p0)
    tree = model.open_tree()
    theta0 = np.concatenate([system.q0, p0])
    thetad0 = np.concatenate([system.initial_rates, rates @ system.initial_rates])
    return NonlinearNodeSystem(tree.mechanical_functions(system.parameters), theta0,
                               make_topology("parallel", n + m), tuple(system.forces) + ((),) * m,
                               thetad0, system.t_stop, {"robot": system.provenance.robot,
                                                        "parameters": dict(system.parameters)},
                               tree, system.parameters)


def constrained_circuit(system, zero_tol: float = ZERO_TOL, describe: bool = True) -> Circuit:
    """The circuit of a closed chain's full nonlinear dynamics (see the module).

    Nodes n1 … n_dof are the active joints (the system's nodes), then the passive joints,
    then one node λ_c per constraint; the passive joints' integrators are kept but not
    reported as the system's positions (:attr:`Circuit.monitors`).

    Parameters
    ----------
    system : NonlinearNodeSystem
        A closed chain's nonlinear system.
    zero_tol : float
        Relative tolerance under which a damper or spring is left out.
    describe : bool
        Fill :attr:`Circuit.comments`, for netlist headers.
    """
    model = system.model
    tree = open_system(system)
    base = nonlinear_circuit(tree, zero_tol, describe)
    lag = node_lagrangian(tree)
    n, total = system.dof, tree.dof
    theta = list(model.coordinates) + list(model.passive)
    subs = {sym: system.parameters[name] for name, sym in model.symbols.items()}
    at = {t: float(t0) + x for t, t0, x in zip(theta, tree.q0, lag.x)}
    phi = model.constraints.subs(subs)
    jac = phi.jacobian(theta)
    phi, jac = phi.subs(at), jac.subs(at)
    m = phi.rows
    lam = list(sp.symbols(f"lambda1:{m + 1}", real=True))
    alpha = BAUMGARTE_RUNS / system.t_stop
    # the multipliers are node voltages v(n_{total + c}), printed as the rates of nodes past the joints
    wide = lag._replace(v=list(lag.v) + lam)
    parts = []
    for c in range(m):
        closure = sum((jac[c, k] * lag.v[k] for k in range(total)), sp.S.Zero) + alpha * phi[c]
        parts.append(ConstraintCurrent(f"loop{c + 1}", total + c + 1, 0, spice_text(closure, wide)))
    for k in range(total):
        force = sum((jac[c, k] * lam[c] for c in range(m)), sp.S.Zero)
        if force != 0:
            parts.append(BehaviouralCurrent(f"lam{k + 1}", k + 1, 0, spice_text(force, wide)))
    behavioural = tuple(Integrator(p.node, p.node <= n) if isinstance(p, Integrator) else p
                        for p in base.behavioural) + tuple(parts)
    if not np.all(np.isfinite(np.asarray(jac.subs({x: 0.0 for x in lag.x}), dtype=float))):
        raise InputError(f"{model.name}'s loop closure is not finite at the start")
    notes = ()
    if describe:
        passive = ", ".join(f"n{n + k + 1} = d{s}/dt" for k, s in enumerate(model.passive))
        notes = comments(system) + (
            f"loop closure: the chain cut open, a node per joint ({passive}); nodes "
            f"{', '.join(f'n{total + c + 1}' for c in range(m))} carry the multipliers lambda, Bloop* hold "
            f"J(x)*v + alpha*Phi(x) = 0 (alpha = {alpha:g} 1/s), Blam* inject the constraint forces J^T*lambda",)
    return base._replace(nodes=total + m, behavioural=behavioural, comments=notes)
