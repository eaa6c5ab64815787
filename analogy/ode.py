"""Direct integration of M'·dv/dt = i(t) − B'·v − K'·∫v with scipy's solve_ivp."""

from __future__ import annotations

import time as _time

import numpy as np
import scipy.linalg as la

from .errors import InputError, SimulationError
from .trajectory import Trajectory

__all__ = ["solve_ode", "ODE_METHODS", "state_matrices"]

#: solve_ivp methods; the implicit ones receive the constant analytic Jacobian.
ODE_METHODS = ("LSODA", "Radau", "BDF", "RK45", "RK23", "DOP853")
_IMPLICIT = {"LSODA", "Radau", "BDF"}


def state_matrices(system):
    """First-order form y' = A·y + G·F(t) on y = [∫v, v] (or y = v without springs).

    M'⁻¹ is never formed: M'⁻¹B', M'⁻¹K' and M'⁻¹T⁻ᵀ come from one Cholesky factor.
    """
    n = system.dof
    chol = la.cho_factor(system.mass)
    mb = la.cho_solve(chol, system.damping)
    mc = la.cho_solve(chol, system.current_map)
    if system.stiffness is None:
        return -mb, mc
    mk = la.cho_solve(chol, system.stiffness)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-mk, -mb]])
    g = np.vstack([np.zeros((n, mc.shape[1])), mc])
    return a, g


def solve_ode(system, times=None, method: str = "DOP853", rtol: float = 1e-10,
              atol: float | None = None, positions: bool = False) -> Trajectory:
    """Integrate *system* with ``scipy.integrate.solve_ivp``, restarting at every force breakpoint.

    Parameters
    ----------
    system : NodeSystem
    times : array_like, optional
        Output times in [0, t_stop]; default 1001 uniform points.
    method : str
        One of :data:`ODE_METHODS`.
    rtol, atol : float
        Tolerances; *atol* defaults to ``rtol * 1e-3`` times the response scale.
    positions : bool
        Also return the node positions x = ∫v (:attr:`Trajectory.positions`) when the
        system has springs (they are then part of the integrated state).
    """
    from scipy.integrate import solve_ivp

    if method not in ODE_METHODS:
        raise InputError(f"unknown ODE method {method!r}: use {', '.join(ODE_METHODS)}")
    start = _time.perf_counter()
    t = system.time_points(times)
    a, g = state_matrices(system)
    n = system.dof
    v0 = system.initial_voltages
    y = np.concatenate([np.zeros(n), v0]) if system.stiffness is not None else v0.copy()
    if atol is None:
        # Scale from the steady response to the peak force, so atol is relative to the motion.
        fmax = max(float(np.max(np.abs(system.force(t)))) if t.size else 0.0, 1e-300)
        scale = max(float(np.max(np.abs(v0))), fmax * float(np.max(np.abs(g))) * system.t_stop)
        atol = rtol * 1e-3 * max(scale, 1e-300)
    # Radau and BDF take a constant Jacobian as an array; LSODA needs a callable.
    extra_args = {} if method not in _IMPLICIT else {"jac": (lambda tt, yy: a) if method == "LSODA" else a}
    forces = system.forces

    def rhs(tt, yy):
        f = np.array([sum(float(w(tt)) for w in ws) if ws else 0.0 for ws in forces])
        return a @ yy + g @ f

    out = np.empty((t.size, n))
    pos = np.empty((t.size, n)) if positions and system.stiffness is not None else None
    for t0, t1 in system.segments():
        last = t1 >= system.t_stop
        mask = (t >= t0) & ((t <= t1) if last else (t < t1))
        te, back = np.unique(t[mask], return_inverse=True)   # solve_ivp wants distinct times
        extra = not te.size or te[-1] < t1     # also evaluate at t1 to carry the state on
        sol = solve_ivp(rhs, (t0, t1), y, method=method, t_eval=np.append(te, t1) if extra else te,
                        rtol=rtol, atol=atol, **extra_args)
        if sol.status < 0:
            at = sol.t[-1] if len(sol.t) else t0
            raise SimulationError(f"ODE solver {method} failed at t = {at:.6g}: {sol.message}")
        if te.size:
            out[mask] = sol.y[-n:, back].T
            if pos is not None:
                pos[mask] = sol.y[:n, back].T
        y = sol.y[:, -1]
    elapsed = _time.perf_counter() - start
    return Trajectory("ode", t, out, system.joint_rates(out), elapsed, pos)
