"""Planar chains of flexible links by assumed modes: M(q) = Σ∫ρA·JᵀJ dx + the hubs, motors and payload.

Link i turns by θ_i from link i−1's undeformed axis, so its axis points along
α_i = θ_1 + … + θ_i (the flexible-robot paper's eqs. 20–21). A point at x along it
sits at p_i(x) = o_i + x·e_i + w_i(x)·n_i, with e_i = (cos α_i, sin α_i), n_i ⊥ e_i and
the deflection w_i(x) = Σ_k φ_ik(x)·δ_ik; the next link starts at its tip,
o_{i+1} = p_i(L_i). The coordinates are (θ_1 … θ_n, δ_11 …, δ_21 …, …).

The kinetic energy is written with x and each φ_ik(x) as placeholders; the integrand
is a polynomial in them, and each monomial x^a·φ_ik·φ_jl is replaced by its integral
∫ρA·x^a·φ_ik·φ_jl dx, computed by Gauss–Legendre quadrature (converged below 1e-14,
see tests/test_flexible.py). M is the Hessian of T in the rates, K the modal bending
stiffness ∫EI·φ''φ'' dx, and G = ∂U/∂q with U the potential of gravity along −y.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np
import sympy as sp

from ..errors import InputError
from .beams import BeamModes, beam_modes, gauss_points
from .symbolic import Model

__all__ = ["FlexibleLink", "flexible_chain"]


class FlexibleLink(NamedTuple):
    """One link: length [m], ρA [kg/m], EI [N·m²] and its number of assumed modes (0: rigid).

    *tip_mass* and *tip_inertia* are what the link carries at its tip (the next
    joint's motor, or the payload of the last link); *hub_inertia* is at its joint.
    """

    length: float
    rho_a: float
    ei: float
    modes: int = 2
    hub_inertia: float = 0.0
    tip_mass: float = 0.0
    tip_inertia: float = 0.0


def _rot(v, angle):
    return sp.Matrix([v[0] * sp.cos(angle) - v[1] * sp.sin(angle), v[0] * sp.sin(angle) + v[1] * sp.cos(angle)])


def flexible_chain(links: Sequence[FlexibleLink], *, gravity: float = 0.0, clamped_mass: bool = False,
                   damping: Sequence[float] | None = None, name: str = "flexible") -> Model:
    """The assumed-modes model of a planar chain of flexible links on revolute joints.

    Parameters
    ----------
    links : sequence of FlexibleLink
        The links from the base out.
    gravity : float
        g [m/s²] along −y (0: a horizontal plane).
    clamped_mass : bool
        Mode shapes of each link clamped at its joint and loaded by its tip mass and
        inertia; else clamped-free shapes (the paper's setting).
    damping : sequence of float, optional
        Joint dampers [N·m·s/rad], one per link.
    name : str
        The model's name.
    """
    if not links:
        raise InputError("a flexible chain needs at least one link")
    n = len(links)
    theta = list(sp.symbols(f"theta1:{n + 1}", real=True))
    deltas = [list(sp.symbols(f"delta{i + 1}_1:{ln.modes + 1}", real=True)) if ln.modes else []
              for i, ln in enumerate(links)]
    q = theta + [d for ds in deltas for d in ds]
    qd = list(sp.symbols(f"qd1:{len(q) + 1}", real=True))
    rate = dict(zip(q, qd))
    X = sp.Symbol("X", real=True)
    modes: list[BeamModes | None] = []
    for ln in links:
        if ln.modes:
            tip = (ln.tip_mass, ln.tip_inertia) if clamped_mass else (0.0, 0.0)
            modes.append(beam_modes(ln.modes, ln.length, ln.rho_a, ln.ei, *tip))
        else:
            modes.append(None)

    def d_dt(expr):
        return sum(sp.diff(expr, c) * rate[c] for c in q)

    kinetic, potential = sp.S.Zero, sp.S.Zero
    origin, alpha = sp.Matrix([0, 0]), sp.S.Zero
    for i, (ln, md) in enumerate(zip(links, modes)):
        alpha = alpha + theta[i]
        if i == 0:
            kinetic += ln.hub_inertia * rate[theta[0]] ** 2 / 2
        placeholders = list(sp.symbols(f"P{i + 1}_1:{ln.modes + 1}", real=True)) if ln.modes else []
        w = sum((p * d for p, d in zip(placeholders, deltas[i])), sp.S.Zero)
        point = origin + _rot([X, w], alpha)
        velocity = sp.Matrix([d_dt(point[0]), d_dt(point[1])])
        density = sp.expand(velocity.dot(velocity) / 2)
        kinetic += _integrate(density, X, placeholders, ln, md)
        potential += gravity * _integrate(sp.expand(point[1]), X, placeholders, ln, md)
        # the tip: its deflection and slope, then what it carries
        tip_w = sum((float(md.shape([ln.length])[0][k]) * d for k, d in enumerate(deltas[i])), sp.S.Zero) \
            if md is not None else sp.S.Zero
        tip_slope = sum((float(md.shape([ln.length], 1)[0][k]) * d for k, d in enumerate(deltas[i])), sp.S.Zero) \
            if md is not None else sp.S.Zero
        origin = origin + _rot([ln.length, tip_w], alpha)
        tip_velocity = sp.Matrix([d_dt(origin[0]), d_dt(origin[1])])
        kinetic += ln.tip_mass * tip_velocity.dot(tip_velocity) / 2
        kinetic += ln.tip_inertia * d_dt(alpha + tip_slope) ** 2 / 2
        potential += gravity * ln.tip_mass * origin[1]
    mass = sp.Matrix(len(q), len(q), lambda a, b: sp.expand(sp.diff(kinetic, qd[a], qd[b])))
    stiffness = np.zeros((len(q), len(q)))
    k = n
    for ln, md in zip(links, modes):
        if md is None:
            continue
        xg, wg = gauss_points(96)
        d2 = md.shape(xg * ln.length, 2)
        block = ln.ei * ln.length * (d2.T * wg) @ d2
        stiffness[k:k + ln.modes, k:k + ln.modes] = 0.5 * (block + block.T)
        k += ln.modes
    grav = [sp.expand(sp.diff(potential, c)) for c in q]
    damp = [0.0] * len(q) if damping is None else list(damping) + [0.0] * (len(q) - n)
    if len(damp) != len(q):
        raise InputError(f"damping needs one value per joint ({n})")
    return Model(name, mass, damping=damp, stiffness=sp.Matrix(stiffness.tolist()),
                 gravity=grav if any(g != 0 for g in grav) else None, coordinates=q, topology="parallel",
                 description=f"planar chain of {n} flexible links, assumed modes")


def _integrate(density, x, placeholders, link: FlexibleLink, modes: BeamModes | None):
    """∫ρA·density dx over the link, the placeholders standing for the mode shapes φ_k(x)."""
    xg, wg = gauss_points(96)
    xs = xg * link.length
    phi = modes.shape(xs) if modes is not None else np.zeros((xs.size, 0))
    poly = sp.Poly(density, x, *placeholders)
    total = sp.S.Zero
    for powers, coefficient in poly.terms():
        values = xs ** powers[0]
        for k, p in enumerate(powers[1:]):
            if p:
                values = values * phi[:, k] ** p
        total += coefficient * float(link.rho_a * link.length * (wg @ values))
    return total
