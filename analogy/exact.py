"""Exact response of a node system by eigen-decomposition of its matrix pencil."""

from __future__ import annotations

import time as _time

import numpy as np
import scipy.linalg as la

from .errors import SimulationError
from .trajectory import Trajectory

__all__ = ["solve_exact", "modal_form", "phi1", "phi2"]


def _expm1(x: np.ndarray) -> np.ndarray:
    """exp(x) − 1 without cancellation, for real or complex x."""
    if not np.iscomplexobj(x):
        return np.expm1(x)
    a, b = x.real, x.imag
    real = np.expm1(a) * np.cos(b) - 2.0 * np.sin(0.5 * b) ** 2
    imag = np.exp(a) * np.sin(b)
    return real + 1j * imag


def phi1(x: np.ndarray) -> np.ndarray:
    """φ₁(x) = (eˣ − 1)/x, with φ₁(0) = 1; real in, real out."""
    x = np.asarray(x)
    x = x.astype(complex if np.iscomplexobj(x) else float, copy=False)
    out = np.ones_like(x)
    nz = x != 0
    out[nz] = _expm1(x[nz]) / x[nz]
    return out


def phi2(x: np.ndarray) -> np.ndarray:
    """φ₂(x) = (eˣ − 1 − x)/x², with φ₂(0) = 1/2; a Taylor series near 0 avoids cancellation."""
    x = np.asarray(x)
    x = x.astype(complex if np.iscomplexobj(x) else float, copy=False)
    out = np.empty_like(x)
    small = np.abs(x) < 1.0
    xs = x[small]
    term = np.full_like(xs, 0.5)
    acc = term.copy()
    for k in range(3, 30):      # Σ x^(k−2)/k!; |x| < 1 makes 30 terms exact to rounding
        term = term * xs / k
        acc = acc + term
    out[small] = acc
    xl = x[~small]
    out[~small] = (_expm1(xl) - xl) / xl ** 2
    return out


def _forced(lam: np.ndarray, s: complex, tau: np.ndarray) -> np.ndarray:
    """∫₀^τ e^{λ(τ−σ)}·e^{sσ} dσ for every λ (columns) and τ (rows)."""
    lam = lam[None, :]
    tau = tau[:, None]
    w = (s - lam) * tau
    near = np.abs(w) < 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        far = (np.exp(s * tau) - np.exp(lam * tau)) / np.where(near, 1.0, s - lam)
    return np.where(near, np.exp(lam * tau) * tau * phi1(np.where(near, w, 0)), far)


class _Modes:
    """State y = V·z with decoupled modes z' = λ·z + β·F(t)."""

    def __init__(self, lam, vectors, to_modal, force_map, n, has_position):
        self.lam = lam                  # (m,)
        self.vectors = vectors          # (state, m)
        self.to_modal = to_modal        # callable y -> z
        self.force_map = force_map      # (m, joints)
        self.n = n
        self.has_position = has_position


def modal_form(system) -> _Modes:
    """Eigen-decomposition of the pencil of *system*.

    Without springs, M'·v' = −B'·v + i is a symmetric-definite pencil: ``eigh(B', M')``
    gives real rates and M'-orthonormal modes, so the transform is perfectly conditioned.
    With springs, the first-order pencil (A, E) on y = [x, v] is decomposed by ``eig``.
    """
    m, b, k, c = system.mass, system.damping, system.stiffness, system.current_map
    n = system.dof
    if k is None:
        mu, phi = la.eigh(b, m)
        return _Modes((-mu).astype(complex), phi.astype(complex),
                      lambda y: phi.T @ (m @ y), (phi.T @ c).astype(complex), n, False)
    e = la.block_diag(np.eye(n), m)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-k, -b]])
    lam, vec = la.eig(a, e)
    if not np.all(np.isfinite(lam)):
        raise SimulationError("the system pencil has infinite eigenvalues")
    ev = e @ vec
    lu = la.lu_factor(ev)
    cond = np.linalg.cond(vec)
    if cond > 1e10:
        raise SimulationError(f"the modes are nearly defective (condition number {cond:.2g}); "
                              "the exact solver cannot resolve them accurately")
    force_map = la.lu_solve(lu, np.vstack([np.zeros((n, c.shape[1])), c]))
    vec_lu = la.lu_factor(vec)
    return _Modes(lam, vec, lambda y: la.lu_solve(vec_lu, y.astype(complex)), force_map, n, True)


def solve_exact(system, times=None, positions: bool = False) -> Trajectory:
    """Exact node voltages and joint rates of *system* at *times*.

    Forces are piecewise closed forms (constant, linear, damped sine) between the
    system's breakpoints; each segment is integrated exactly in modal coordinates.

    Parameters
    ----------
    system : NodeSystem
    times : array_like, optional
        Sorted times in [0, t_stop]; default 1001 uniform points.
    positions : bool
        Also return the node positions x = ∫v (:attr:`Trajectory.positions`) when the
        system has springs; they are part of its state, so this costs nothing extra.
    """
    start = _time.perf_counter()
    t = system.time_points(times)
    modes = modal_form(system)
    n = system.dof
    v0 = system.initial_voltages
    y0 = np.concatenate([np.zeros(n), v0]) if modes.has_position else v0
    z = modes.to_modal(y0.astype(complex))
    lam = modes.lam
    out = np.empty((t.size, n))
    pos = np.empty((t.size, n)) if positions and modes.has_position else None
    seg_start = 0.0
    for t0, t1 in system.segments():
        last = t1 >= system.t_stop
        mask = (t >= t0) & ((t <= t1) if last else (t < t1))
        taus = np.concatenate([t[mask] - t0, [t1 - t0]])
        zt = np.exp(np.outer(taus, lam)) * z[None, :]
        for j, waves in enumerate(system.forces):
            beta = modes.force_map[:, j]
            if not np.any(beta) or not waves:
                continue
            for w in waves:
                p = w.piece(t0, t1)
                x = np.outer(taus, lam)
                if p.a:
                    zt += p.a * beta[None, :] * taus[:, None] * phi1(x)
                if p.b:
                    zt += p.b * beta[None, :] * taus[:, None] ** 2 * phi2(x)
                for c, s in zip(p.c, p.s):
                    zt += c * beta[None, :] * _forced(lam, s, taus)
        y = (zt @ modes.vectors.T).real
        out[mask] = y[:-1, n:] if modes.has_position else y[:-1]
        if pos is not None:
            pos[mask] = y[:-1, :n]
        z = zt[-1]
        seg_start = t1
    del seg_start
    voltages = out
    elapsed = _time.perf_counter() - start
    return Trajectory("exact", t, voltages, system.joint_rates(voltages), elapsed, pos)
