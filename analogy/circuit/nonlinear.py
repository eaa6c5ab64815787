"""Configuration-dependent node dynamics: M'(x)·dv/dt = i(t) − B'·v − K'·x − h(x, v)."""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ..model.provenance import Provenance
from ..errors import InputError, concerning
from ..presets import DEFAULT_T_STOP
from ..model.base import RobotModel
from ..model.dynamics import DynamicsKind, MechanicalFunctions
from ..model.joint import check_square_symmetric, check_vector
from .joint_forces import waveforms
from .node_coordinates import NodeCoordinates, check_t_stop
from .topology import Topology
from .topology import topology as make_topology

__all__ = ["NonlinearNodeSystem", "nonlinear_system"]


class NonlinearNodeSystem(NodeCoordinates):
    """A robot's full dynamics in node coordinates, about the configuration q0 it starts at.

    With q = q0 + T⁻¹·x and r = T⁻¹·v, the Lagrange equations
    M(q)·ṙ + c(q, r) + G(q) + K·(q − q0) + B·r = F become
    ``M'(x)·dv/dt = i − B'·v − K'·x − h`` with M'(x) = T⁻ᵀ·M(q)·T⁻¹ and
    h = T⁻ᵀ·(c(q, r) + G(q)). Only solvers that integrate M'(x) apply (not the exact one).

    Parameters
    ----------
    functions : MechanicalFunctions
        Compiled M(q), c(q, q̇), G(q) and constant B, K of the model.
    q0 : array_like
        Configuration at t = 0.
    topology : Topology
        The constant map T.
    forces : tuple of tuple of Waveform
        Per joint, the waveforms whose sum is F_j(t) (gravity is part of h, not of F).
    initial_rates : array_like
        Joint rates at t = 0.
    t_stop : float
        End of the simulated interval [s].
    info : mapping, optional
        Robot name, parameters and configuration, for reports.
    model : Model, optional
        The symbolic model the functions were compiled from (the nonlinear circuit
        writes its expressions).
    parameters : mapping, optional
        The parameter values the functions were compiled with.
    """

    kind: DynamicsKind = "nonlinear"

    def __init__(self, functions: MechanicalFunctions, q0, topology: Topology, forces: tuple,
                 initial_rates, t_stop: float, info: Mapping | None = None, model=None,
                 parameters: Mapping[str, float] | None = None):
        n = topology.dof
        self.functions, self.model = functions, model
        self.parameters = dict(parameters or {})
        self.q0 = check_vector("configuration q", q0, n)
        self.topology, self.forces, self.t_stop = topology, tuple(forces), check_t_stop(t_stop)
        if len(self.forces) != n:
            raise InputError(f"forces must have {n} entries (one per joint), got {len(self.forces)}")
        self.initial_rates = check_vector("initial rates r0", initial_rates, n)
        self.provenance = Provenance.of(info)
        # as for the linear circuit: a negative damper feeds energy in without bound
        with concerning("damping"):
            check_square_symmetric("damping matrix B", functions.damping, n=n, semidefinite=True)
        self.damping = topology.node_matrix(functions.damping)
        self.stiffness = None if functions.stiffness is None or not np.any(functions.stiffness) \
            else topology.node_matrix(functions.stiffness)
        self.current_map = topology.current_map
        self.initial_voltages = topology.matrix @ self.initial_rates       # v(0) = T·R(0)
        with concerning("mass"):
            check_square_symmetric("node mass matrix M'(0)", self.node_mass(np.zeros(n)), definite=True)
        with np.errstate(all="ignore"):         # past the float range is said below, once
            load = self.node_load(np.zeros(n), self.initial_voltages, 0.0)
        if not np.all(np.isfinite(load)):
            raise InputError("the gravity and velocity terms h(x, v) are not finite at the start (a parameter "
                             "such as g past the floating-point range?)", field="gravity")
        self.breakpoints()
        self._seal()

    def __repr__(self) -> str:
        return (f"NonlinearNodeSystem({self.provenance.robot}, {self.dof} nodes, "
                f"{self.topology.name} topology, t_stop={self.t_stop:g} s)")

    @property
    def dof(self) -> int:
        """Number of nodes (and joints) n."""
        return self.topology.dof

    def configuration(self, x: np.ndarray) -> np.ndarray:
        """Joint coordinates q = q0 + T⁻¹·x at node positions *x*.

        Parameters
        ----------
        x : ndarray
            Node positions.
        """
        return self.q0 + self.topology.joint_rates(x)

    def node_mass(self, x: np.ndarray) -> np.ndarray:
        """M'(x) = T⁻ᵀ·M(q0 + T⁻¹·x)·T⁻¹.

        Parameters
        ----------
        x : ndarray
            Node positions.
        """
        return self.topology.node_matrix(self.functions.mass(self.configuration(x)))

    def node_masses(self, x: np.ndarray) -> np.ndarray:
        """M'(x) at every row of node positions *x* (m, n): the model's stack of poses at once where it
        has one, else pose by pose.

        Parameters
        ----------
        x : ndarray, shape (m, n)
            Node positions.
        """
        if self.functions.masses is not None:
            return self.topology.node_matrix(self.functions.masses(self.q0 + x @ self.topology.inverse.T))
        return np.stack([self.node_mass(p) for p in x])

    def node_load(self, x: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """h = T⁻ᵀ·(c(q, r) + G(q)): velocity terms and gravity, as node currents.

        Parameters
        ----------
        x : ndarray
            Node positions.
        v : ndarray
            Node velocities.
        t : float
            Time (the load does not depend on it).
        """
        q, r = self.configuration(x), self.joint_rates(v)
        load = self.functions.velocity(q, r)
        if self.functions.gravity is not None:
            load = load + self.functions.gravity(q)
        if self.functions.contacts is not None:
            load = load - self.functions.contacts.generalised(q, r)
        return self.current_map @ load

    def node_contact(self, x: np.ndarray, v: np.ndarray) -> np.ndarray | None:
        """T⁻ᵀ·τ_c: the ground's contact forces as node currents into the nodes; None without contacts.

        Parameters
        ----------
        x, v : ndarray
            Node positions and velocities.
        """
        contacts = self.functions.contacts
        if contacts is None:
            return None
        return self.current_map @ contacts.generalised(self.configuration(x), self.joint_rates(v))

    def contact_forces(self, x: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
        """Each contact's normal force f_c [N] at every row of node positions *x* and velocities *v*
        (m, n), by the output name ``f_<contact>``; empty without contacts.

        Parameters
        ----------
        x, v : ndarray, shape (m, n)
            Node positions and velocities.
        """
        contacts = self.functions.contacts
        if contacts is None:
            return {}
        q = self.q0 + np.atleast_2d(x) @ self.topology.inverse.T
        r = np.atleast_2d(v) @ self.topology.inverse.T
        forces = contacts.normal(q.T, r.T)
        return {f"f_{name}": forces[k] for k, name in enumerate(contacts.names)}

    def node_gravity(self, x: np.ndarray) -> np.ndarray:
        """T⁻ᵀ·G(q): gravity as node currents (zero without gravity).

        Parameters
        ----------
        x : ndarray
            Node positions.
        """
        if self.functions.gravity is None:
            return np.zeros(self.dof)
        return self.current_map @ self.functions.gravity(self.configuration(x))

    def flow(self, x: np.ndarray, v: np.ndarray, drive: np.ndarray) -> tuple[np.ndarray, float]:
        """(dv/dt, dW/dt) at node positions *x*, velocities *v* and node currents *drive*.

        dv/dt = M'(x)⁻¹·(i − B'·v − K'·x − h). Where the model gives its forward dynamics, that
        is T·q̈ with q̈ from it at the joint forces F = Tᵀ·(i − B'·v − K'·x) (T is constant,
        so v̇ = T·ṙ): one call, no M' formed. W is the work of the drive and dampers, and of
        gravity only where the model has no potential (:meth:`gravity_work` gives it then).

        Parameters
        ----------
        x, v : ndarray
            Node positions and velocities.
        drive : ndarray
            Node currents i(t).
        """
        net = drive - self.damping @ v
        power = v @ net
        f = self.functions
        if f.potential is None and f.gravity is not None:
            power = power - v @ self.node_gravity(x)
        contact = self.node_contact(x, v)
        if contact is not None:          # the ground's work, and its force where h does not hold it
            power = power + v @ contact
        if self.stiffness is not None:
            net = net - self.stiffness @ x
        if f.forward is not None:
            t = self.topology.matrix
            if contact is not None:
                net = net + contact
            return t @ f.forward(self.configuration(x), self.joint_rates(v), net @ t), power
        return np.linalg.solve(self.node_mass(x), net - self.node_load(x, v, 0.0)), power

    def gravity_work(self, x: np.ndarray) -> np.ndarray | None:
        """U(q0) − U(q), gravity's work at every row of node positions *x*, from the model's
        potential; None where it has none (the integral in :meth:`flow` then holds it) or no gravity.

        Parameters
        ----------
        x : ndarray, shape (N, n)
            Node positions.
        """
        potential = self.functions.potential
        if potential is None or self.functions.gravity is None:
            return None
        u = potential(np.vstack([self.q0, self.q0 + np.atleast_2d(x) @ self.topology.inverse.T]))
        return u[0] - u[1:]

    def energy_residual(self, trajectory) -> tuple[np.ndarray, float]:
        """T + U_K − T(0) − W along *trajectory*, and the energy scale it is relative to.

        T = ½·vᵀM'(x)v, U_K = ½·xᵀK'x, and W is the work of the drive, damping and
        gravity: the trajectory's own integral where it has one, else the trapezoidal
        rule on its time points, gravity's part U(q0) − U(q) where the model has a potential
        U. The scale is the largest of T + U_K and |W| over time.

        Parameters
        ----------
        trajectory : Trajectory
            A solution with positions.
        """
        x, v, t = trajectory.positions, trajectory.voltages, trajectory.time
        f = self.functions
        qs = self.q0 + x @ self.topology.inverse.T       # q at every point
        masses = self.node_masses(x)
        kinetic = 0.5 * np.einsum("ti,tij,tj->t", v, masses, v)
        spring = np.zeros_like(kinetic) if self.stiffness is None else \
            0.5 * np.einsum("ti,ij,tj->t", x, self.stiffness, x)
        work = trajectory.work
        if work is None:
            drive = self.node_currents(t)
            lifted = self.gravity_work(x)
            if f.gravity is None or lifted is not None:
                gravity = np.zeros_like(v)
            elif f.gravities is not None:
                gravity = f.gravities(qs) @ self.current_map.T
            else:
                gravity = np.stack([self.node_gravity(p) for p in x])
            power = np.einsum("ti,ti->t", v, drive - v @ self.damping.T - gravity)
            if f.contacts is not None:
                rates = v @ self.topology.inverse.T
                power = power + np.einsum("ti,ti->t", rates,
                                          f.contacts.generalised(qs.T, rates.T).T)
            work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
            if lifted is not None:
                work = work + lifted
        energy = kinetic + spring
        residual = energy - energy[0] - work
        return residual, float(max(np.max(np.abs(energy)), np.max(np.abs(work)), np.finfo(float).tiny))

    def loop_residual(self, trajectory) -> tuple[float, float] | None:
        """A closed chain's largest |Φ| along *trajectory*, and the largest equilibrated cond(Φ_p) it met.

        The passive joints are the circuit's own (saved as ``x<k>``) where the solver
        integrated them, else solved from the loop closure at up to 400 of its points.
        None for a tree, or a run without positions.

        Parameters
        ----------
        trajectory : Trajectory
            A solution with positions.
        """
        model = self.model
        if not model.closed_chain or trajectory.positions is None:
            return None
        q = self.configuration(trajectory.positions)
        names = [f"x{self.dof + k + 1}" for k in range(len(model.passive))]
        p0, _ = model.assemble(self.q0, self.parameters)
        if all(n in trajectory.currents for n in names):
            p = p0 + np.column_stack([trajectory.currents[n] for n in names])
        else:
            q = q[np.unique(np.linspace(0, len(q) - 1, min(len(q), 400)).astype(int))]
            try:
                p = np.array([model.assemble(row, self.parameters)[0] for row in q])
            except InputError:          # the run reached a pose where the loop does not close
                return math.nan, math.inf
        size, cond = model.loop_closure(np.column_stack([q, p]), self.parameters)
        return float(np.max(size)), float(np.max(cond))

    def jacobian(self, x: np.ndarray, v: np.ndarray, drive: np.ndarray) -> np.ndarray | None:
        """∂f/∂y of the first-order form y = [x, v, W], y' = f (see :func:`~analogy.solvers.ode.solve_ode`).

        With q = q0 + T⁻¹x and r = T⁻¹v: ∂M'/∂x_k = T⁻ᵀ(Σ_j ∂M/∂q_j·T⁻¹_jk)T⁻¹,
        ∂h/∂x = T⁻ᵀ(∂c/∂q + ∂G/∂q)T⁻¹ and ∂h/∂v = T⁻ᵀ(∂c/∂r)T⁻¹; then
        ∂(M'⁻¹ρ)/∂x_k = M'⁻¹(∂ρ/∂x_k − ∂M'/∂x_k·M'⁻¹ρ). None without model derivatives.

        Parameters
        ----------
        x, v : ndarray
            Node positions and rates.
        drive : ndarray
            Node currents i(t) at the time of evaluation.
        """
        if self.functions.derivatives is None:
            return None
        n = self.dof
        ti = self.topology.inverse
        q, r = self.configuration(x), self.joint_rates(v)
        dm, dcq, dcr, dg = self.functions.derivatives(q, r)
        mass = self.node_mass(x)
        rho = drive - self.damping @ v - self.node_load(x, v, 0.0)
        if self.stiffness is not None:
            rho = rho - self.stiffness @ x
        accel = np.linalg.solve(mass, rho)
        dm_node = np.einsum("ai,jab,bk,jl->ikl", ti, dm, ti, ti)  # (i, k, l): ∂M'_ik/∂x_l
        dh_dx = ti.T @ (dcq + dg) @ ti
        dh_dv = ti.T @ dcr @ ti
        drho_dx = -dh_dx - (self.stiffness if self.stiffness is not None else 0.0)
        drho_dv = -dh_dv - self.damping
        dpv = drive - 2.0 * self.damping @ v
        dpx = np.zeros(n)
        if self.functions.contacts is not None:    # h holds −T⁻ᵀτ_c; the ground's power is r·τ_c
            tau = self.functions.contacts.generalised(q, r)
            dtq, dtr = self.functions.contacts.derivatives(q, r)
            drho_dx = drho_dx + ti.T @ dtq @ ti
            drho_dv = drho_dv + ti.T @ dtr @ ti
            rates = self.joint_rates(v)
            dpv = dpv + ti.T @ (tau + dtr.T @ rates)
            dpx = dpx + ti.T @ (dtq.T @ rates)
        dfx = np.linalg.solve(mass, drho_dx - np.einsum("ikl,k->il", dm_node, accel))
        dfv = np.linalg.solve(mass, drho_dv)
        if self.functions.potential is None:        # else gravity's work is U(q0) − U(q), not in W's rate
            dpv = dpv - self.node_gravity(x)
            dpx = dpx - v @ (ti.T @ dg @ ti)
        jac = np.zeros((2 * n + 1, 2 * n + 1))
        jac[:n, n:2 * n] = np.eye(n)
        jac[n:2 * n, :n], jac[n:2 * n, n:2 * n] = dfx, dfv
        jac[2 * n, :n], jac[2 * n, n:2 * n] = dpx, dpv
        return jac


def nonlinear_system(model, q: Sequence[float], *, parameters: Mapping[str, float] | None = None,
                     topology=None, forces=None, initial_rates=None, t_stop: float = DEFAULT_T_STOP,
                     info: Mapping | None = None) -> NonlinearNodeSystem:
    """The full nonlinear dynamics of a symbolic *model*, starting at configuration *q*.

    Parameters
    ----------
    model : Model
        A symbolic model (its Christoffel symbols are derived from M(q)).
    q : sequence of float
        Configuration at t = 0.
    parameters : mapping, optional
        Parameter overrides.
    topology : {"serial", "parallel", "modal"}, Topology or array_like, optional
        Joint-to-node map T; defaults to the model's own. ``"modal"``: the modes of the
        dynamics linearised at *q*, so that M'(x) is the identity at the start.
    forces : sequence, optional
        One entry per joint, as for :func:`~analogy.circuit.node_system.node_system`.
    initial_rates : sequence of float, optional
        Joint rates at t = 0 (default zero).
    t_stop : float
        End of the simulated interval.
    info : mapping, optional
        Extra report fields.
    """
    if not isinstance(model, RobotModel):
        raise InputError("nonlinear dynamics need a robot model (a Model, a URDF or a built-in robot), "
                         f"not a {type(model).__name__}")
    functions = model.mechanical_functions(parameters)
    n = model.dof
    spec = model.topology if topology is None else topology
    at_start = None
    if isinstance(spec, str) and spec == "modal":     # the modes of the dynamics linearised at q
        j = model.joint_space(list(q), parameters)
        at_start = (j.mass_matrix, j.damping, j.stiffness)
    top = make_topology(spec, n, at_start)
    if model.closed_chain and not np.array_equal(top.matrix, np.eye(n)):
        # its circuit has a node per joint of the loop, the active ones first: v = r
        raise InputError(f"{model.name} is a closed chain: its nonlinear circuit takes the parallel "
                         "topology (a node per joint)", field="topology")
    values = dict(model.parameters, **(parameters or {}))
    base = Provenance.of(info, robot=model.name, parameters=values,
                         configuration=dict(zip((str(c) for c in model.coordinates), list(q))),
                         units=model.units, joints=model.joint_names)
    return NonlinearNodeSystem(functions, q, top, waveforms(forces, n),
                               np.zeros(n) if initial_rates is None else initial_rates, t_stop, base,
                               model, values)
