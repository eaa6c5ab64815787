"""Planar chains of flexible links by assumed modes: M(q) = Σ∫ρA·JᵀJ dx + the hubs, motors and payload.

Link i turns by θ_i from link i−1's undeformed axis, so its axis points along
α_i = θ_1 + … + θ_i (the flexible-robot paper's eqs. 20–21, ``joint_frame="axis"``). A point at x along it
sits at r_i(x) = o_i + x·e_i + u_i(x)·n_i, with e_i = (cos α_i, sin α_i), n_i ⊥ e_i and
the deflection u_i(x) = Σ_k ψ_ik(x)·δ_ik; the next link starts at its tip,
o_{i+1} = r_i(l_i). The coordinates are (θ_1 … θ_n, δ_11 …, δ_21 …, …) unless an
order is given.

The Jacobians J_i = ∂r_i/∂q are taken by sympy with x and each ψ_ik(x) as symbols;
the entries of JᵀJ are polynomials in them, and each monomial x^a·ψ_ik·ψ_jl is
replaced by its integral ∫ρA·x^a·ψ_ik·ψ_jl dx, computed by Gauss–Legendre quadrature
(converged below 1e-14, see tests/test_beams.py). G_i = g·Σ∫ρA·J[y, i] dx (the
y row, gravity along −y), and K is the modal bending stiffness ∫EI·ψ''ψ'' dx.

In the tip frame (``joint_frame="tip"``) joint i + 1 is measured from link i's deformed
tip, θ'_{i+1} = θ_{i+1} − Σ_k ψ'_ik(l_i)·δ_ik, as a clamped joint or an elbow motor
sees it. The positions are the same, so the model is the axis frame's under the
constant map q = A·q': M' = Aᵀ·M(A·q')·A and G' = Aᵀ·G(A·q'); joint torques, joint
dampers and locks then act on the relative angle at the tip.

Gravity's geometric stiffness: an inextensible link's points move in by ½∫₀ˣ u'² along
its axis, which the assumed modes leave out. Over the mass m_i(x) beyond x (the link's
rest and everything it carries) this adds V = −½·g·sin α_i·∫ m_i(x)·u_i'(x)² dx, whose
gradient joins G: an axial tension stiffens a hanging link, a compression softens an
upright one.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from typing import NamedTuple, Sequence

import numpy as np
import sympy as sp

from ..errors import InputError
from .beams import BeamModes, Normalisation, beam_modes, gauss_points
from .conventions import JOINT_FRAMES, LINK_MODES, JointFrame, LinkModes, link_modes_for
from .symbolic import Model

__all__ = ["FlexibleLink", "ChainKinematics", "chain_kinematics", "flexible_chain", "FLEXIBLE_DEFAULTS",
           "flexible_arm"]

_QUADRATURE_POINTS = 96


class FlexibleLink(NamedTuple):
    """One link: length [m], ρA [kg/m], EI [N·m²] and its number of assumed modes (0: rigid).

    *tip_mass* [kg] and *tip_inertia* [kg·m²] are what the link carries at its tip (the
    next joint's motor, or the payload of the last link); *hub_inertia* [kg·m²] turns
    with the link's joint; *modal_damping* is the damping ratio of each of its modes.
    """

    length: float
    rho_a: float
    ei: float
    modes: int = 2
    hub_inertia: float = 0.0
    tip_mass: float = 0.0
    tip_inertia: float = 0.0
    modal_damping: float = 0.0


class ChainKinematics(NamedTuple):
    """Positions of a deformed planar chain, with the mode shapes as symbols.

    ``points[i]`` is r_i(x) in terms of ``x`` and the shape symbols ``shapes[i][k]`` =
    ψ_ik(x); ``tips[i]`` is r_i(l_i), written with ``tip_shapes[i][k]`` = ψ_ik(l_i);
    ``tip_angles[i]`` is the direction of link i's tip, α_i + Σ ψ'_ik(l_i)·δ_ik, with
    ``tip_slopes[i][k]`` = ψ'_ik(l_i).
    """

    coordinates: list
    angles: list
    modal: list
    x: sp.Symbol
    shapes: list
    tip_shapes: list
    tip_slopes: list
    points: list
    tips: list
    tip_angles: list

    def jacobians(self) -> list:
        """J_i = ∂r_i(x)/∂q, one 2 × dof matrix per link."""
        return [p.jacobian(self.coordinates) for p in self.points]


def _rot(v, angle):
    return sp.Matrix([v[0] * sp.cos(angle) - v[1] * sp.sin(angle), v[0] * sp.sin(angle) + v[1] * sp.cos(angle)])


def chain_kinematics(lengths: Sequence, modes: Sequence[int], order: Sequence[int] | None = None) -> ChainKinematics:
    """The deformed positions of a planar chain (eqs. 20–21 for two links), symbolically.

    Parameters
    ----------
    lengths : sequence
        l_i [m], numbers or sympy symbols.
    modes : sequence of int
        Assumed modes per link (0: a rigid link).
    order : sequence of int, optional
        A permutation of the default coordinates (θ…, δ_1…, δ_2…): coordinate k of the
        model is default coordinate ``order[k]``.
    """
    n = len(lengths)
    if n == 0 or len(modes) != n:
        raise InputError("a flexible chain needs one mode count per link")
    theta = list(sp.symbols(f"theta1:{n + 1}", real=True))
    modal = [list(sp.symbols(f"delta{i + 1}_1:{m + 1}", real=True)) if m else [] for i, m in enumerate(modes)]
    q = theta + [d for ds in modal for d in ds]
    if order is not None:
        if sorted(order) != list(range(len(q))):
            raise InputError(f"the coordinate order must be a permutation of 0 … {len(q) - 1}")
        q = [q[k] for k in order]
    x = sp.Symbol("x", real=True)

    def named(stem, i, m):
        return list(sp.symbols(f"{stem}{i + 1}_1:{m + 1}", real=True)) if m else []

    shapes = [named("psi", i, m) for i, m in enumerate(modes)]
    tip_shapes = [named("psie", i, m) for i, m in enumerate(modes)]
    tip_slopes = [named("dpsie", i, m) for i, m in enumerate(modes)]
    points, tips, tip_angles = [], [], []
    origin, alpha = sp.Matrix([0, 0]), sp.S.Zero
    for i, length in enumerate(lengths):
        alpha = alpha + theta[i]
        u = sum((p * d for p, d in zip(shapes[i], modal[i])), sp.S.Zero)
        points.append(origin + _rot([x, u], alpha))
        u_tip = sum((p * d for p, d in zip(tip_shapes[i], modal[i])), sp.S.Zero)
        origin = origin + _rot([length, u_tip], alpha)
        tips.append(origin)
        tip_angles.append(alpha + sum((p * d for p, d in zip(tip_slopes[i], modal[i])), sp.S.Zero))
    return ChainKinematics(q, theta, modal, x, shapes, tip_shapes, tip_slopes, points, tips, tip_angles)


def flexible_chain(links: Sequence[FlexibleLink], *, gravity: float = 0.0, link_modes: LinkModes | None = None,
                   normalisation: Normalisation = "link-mass", damping: Sequence[float] | None = None,
                   order: Sequence[int] | None = None, name: str = "flexible", joint_frame: JointFrame = "axis",
                   geometric_stiffness: bool | None = None) -> Model:
    """The assumed-modes model of a planar chain of flexible links on revolute joints.

    Parameters
    ----------
    links : sequence of FlexibleLink
        The links from the base out.
    gravity : float
        g [m/s²] along −y (0: a horizontal plane).
    link_modes : {"clamped-free", "clamped-mass"}, optional
        Each link's mode shapes: those of a cantilever (the paper's setting), or of a
        link clamped at its joint and loaded by its tip mass and inertia. None: the
        joint frame's (see `link_modes_for`).
    normalisation : {"link-mass", "unit"}
        Each mode's modal mass: the link's mass ρA·l, or 1 kg (see `beam_modes`).
    damping : sequence of float, optional
        Joint dampers [N·m·s/rad], one per link.
    order : sequence of int, optional
        A permutation of the default coordinates (see `chain_kinematics`).
    name : str
        The model's name.
    joint_frame : {"axis", "tip"}
        Joint i + 1 measured from link i's undeformed axis (the paper's) or from its
        deformed tip (a physical clamp or elbow motor).
    geometric_stiffness : bool, optional
        Gravity's axial-load stiffness of the links; None: on in the tip frame, off in the
        axis frame, whose equations are the paper's.
    """
    if not links:
        raise InputError("a flexible chain needs at least one link")
    link_modes = link_modes_for(joint_frame, link_modes)
    if link_modes not in LINK_MODES:
        raise InputError(f"unknown link modes {link_modes!r}: use {' or '.join(LINK_MODES)}")
    if joint_frame not in JOINT_FRAMES:
        raise InputError(f"unknown joint frame {joint_frame!r}: use {' or '.join(JOINT_FRAMES)}")
    if geometric_stiffness is None:
        geometric_stiffness = joint_frame == "tip"
    n = len(links)
    kin = chain_kinematics([ln.length for ln in links], [ln.modes for ln in links], order)
    q = kin.coordinates
    modes: list[BeamModes | None] = []
    for ln in links:
        tip = (ln.tip_mass, ln.tip_inertia) if link_modes == "clamped-mass" else (0.0, 0.0)
        modes.append(beam_modes(ln.modes, ln.length, ln.rho_a, ln.ei, *tip, normalisation=normalisation)
                     if ln.modes else None)
    tip_values = {}
    for i, md in enumerate(modes):
        if md is not None:
            tip_values |= dict(zip(kin.tip_shapes[i], md.shape([links[i].length])[0].tolist()))
            tip_values |= dict(zip(kin.tip_slopes[i], md.shape([links[i].length], 1)[0].tolist()))
    dof = len(q)
    mass = sp.zeros(dof, dof)
    grav = sp.zeros(1, dof)
    mass[q.index(kin.angles[0]), q.index(kin.angles[0])] += links[0].hub_inertia
    for i, (ln, md, jac) in enumerate(zip(links, modes, kin.jacobians())):
        mass += _integrate(jac.T * jac, kin.x, kin.shapes[i], ln, md)
        grav += gravity * _integrate(jac[1, :], kin.x, kin.shapes[i], ln, md)
        tip_jac = kin.tips[i].jacobian(q)
        turn = sp.Matrix([kin.tip_angles[i]]).jacobian(q)
        mass += ln.tip_mass * tip_jac.T * tip_jac + ln.tip_inertia * turn.T * turn
        grav += gravity * ln.tip_mass * tip_jac[1, :]
        if i > 0:
            mass += ln.hub_inertia * _turn(kin, i, q).T * _turn(kin, i, q)
    if geometric_stiffness and gravity:
        grav += _axial_load(kin, links, modes, gravity)
    mass = _trig_reduced(mass.subs(tip_values), kin.angles)
    grav = _trig_reduced(grav.subs(tip_values), kin.angles)
    if joint_frame == "tip":
        mass, grav = _in_tip_frame(kin, modes, links, mass, grav)
    mass = sp.Matrix(dof, dof, lambda a, b: mass[min(a, b), max(a, b)])    # exactly symmetric
    stiffness = np.zeros((dof, dof))
    modal_damping = np.zeros((dof, dof))
    for i, (ln, md) in enumerate(zip(links, modes)):
        if md is None:
            continue
        xg, wg = gauss_points(_QUADRATURE_POINTS)
        d2 = md.shape(xg * ln.length, 2)
        block = ln.ei * ln.length * (d2.T * wg) @ d2
        at = [q.index(d) for d in kin.modal[i]]
        stiffness[np.ix_(at, at)] = 0.5 * (block + block.T)
        # ratio ζ per mode of the clamped link: b_k = 2ζ·ω_k·(its modal mass)
        modal_mass = ln.rho_a * ln.length if normalisation == "link-mass" else 1.0
        modal_damping[at, at] = 2.0 * ln.modal_damping * md.omega * modal_mass
    joint = np.zeros(n) if damping is None else np.asarray(damping, dtype=float)
    if joint.shape != (n,):
        raise InputError(f"damping needs one value per joint ({n})")
    for k, th in enumerate(kin.angles):
        modal_damping[q.index(th), q.index(th)] += joint[k]
    damp = np.diag(modal_damping).tolist() if not np.any(modal_damping - np.diag(np.diag(modal_damping))) \
        else sp.Matrix(modal_damping.tolist())
    g = list(grav)
    modal = {c for ds in kin.modal for c in ds}
    return Model(name, mass, damping=damp, stiffness=sp.Matrix(stiffness.tolist()),
                 gravity=g if any(v != 0 for v in g) else None, coordinates=q, topology="parallel",
                 joints=tuple("modal" if c in modal else "revolute" for c in q),
                 description=f"planar chain of {n} flexible links, assumed modes")


def _axial_load(kin: ChainKinematics, links: Sequence[FlexibleLink], modes, gravity: float) -> sp.Matrix:
    """∂V/∂q of the links' foreshortening under gravity, V = −½·g·Σ sin α_i·δ_iᵀ·(∫ m_i·ψ_i'ψ_i'ᵀ dx)·δ_i."""
    potential = sp.S.Zero
    xg, wg = gauss_points(_QUADRATURE_POINTS)
    alpha = sp.S.Zero
    for i, (ln, md) in enumerate(zip(links, modes)):
        alpha = alpha + kin.angles[i]
        if md is None:
            continue
        beyond = ln.tip_mass + sum(nx.rho_a * nx.length + nx.tip_mass for nx in links[i + 1:])
        xs = xg * ln.length
        slope = md.shape(xs, 1)
        carried = ln.rho_a * (ln.length - xs) + beyond
        block = ln.length * (slope.T * (wg * carried)) @ slope
        delta = sp.Matrix(kin.modal[i])
        potential += -sp.Rational(1, 2) * gravity * sp.sin(alpha) * (delta.T * sp.Matrix(block.tolist()) * delta)[0]
    return sp.Matrix([potential]).jacobian(kin.coordinates)


def _in_tip_frame(kin: ChainKinematics, modes, links, mass: sp.Matrix, grav: sp.Matrix):
    """M and G in tip-frame coordinates q': q = A·q' with θ_{i+1} = θ'_{i+1} + Σ_k ψ'_ik(l_i)·δ_ik."""
    q = kin.coordinates
    a = sp.eye(len(q))
    shift = {}
    for i in range(len(links) - 1):
        if modes[i] is None:
            continue
        slopes = modes[i].shape([links[i].length], 1)[0]
        nxt = kin.angles[i + 1]
        for s, d in zip(slopes, kin.modal[i]):
            a[q.index(nxt), q.index(d)] = float(s)
        shift[nxt] = nxt + sum((float(s) * d for s, d in zip(slopes, kin.modal[i])), sp.S.Zero)
    if not shift:
        return mass, grav
    mass = a.T * mass.subs(shift, simultaneous=True) * a
    grav = grav.subs(shift, simultaneous=True) * a
    return mass.applyfunc(sp.expand), grav.applyfunc(sp.expand)


def _trig_reduced(matrix: sp.MatrixBase, angles) -> sp.MatrixBase:
    """Entries as polynomials in sin θ_i and cos θ_i with cos² θ_i = 1 − sin² θ_i, so that
    M shows that it depends on the relative angles only."""
    square = {sp.cos(a) ** 2: 1 - sp.sin(a) ** 2 for a in angles}
    return matrix.applyfunc(lambda e: sp.expand(sp.expand(sp.expand_trig(e)).subs(square)))


def _turn(kin: ChainKinematics, i: int, q) -> sp.Matrix:
    """∂α_i/∂q: how link i's joint rotor turns (θ_1 + … + θ_i)."""
    return sp.Matrix([sum(kin.angles[:i + 1], sp.S.Zero)]).jacobian(q)


def _integrate(matrix: sp.MatrixBase, x, shapes, link: FlexibleLink, modes: BeamModes | None):
    """∫ρA·matrix dx over the link, the shape symbols standing for the mode shapes ψ_k(x)."""
    xg, wg = gauss_points(_QUADRATURE_POINTS)
    xs = xg * link.length
    psi = modes.shape(xs) if modes is not None else np.zeros((xs.size, 0))
    cache: dict = {}

    def integral(powers):
        if powers not in cache:
            values = xs ** powers[0]
            for k, p in enumerate(powers[1:]):
                if p:
                    values = values * psi[:, k] ** p
            cache[powers] = float(link.rho_a * link.length * (wg @ values))
        return cache[powers]

    def entry(expr):
        expr = sp.expand(expr)
        if expr == 0:
            return sp.S.Zero
        poly = sp.Poly(expr, x, *shapes)
        return sum((c * integral(p) for p, c in poly.terms()), sp.S.Zero)

    return matrix.applyfunc(entry)


#: The built-in flexible arms' parameters and their defaults: aluminium strips
#: (E = 70 GPa, ρ = 2700 kg/m³) 50 mm × 4 mm in section, bending in the arm's plane,
#: so ρA = 0.54 kg/m and EI = 18.67 N·m²; 0.5 m links; a 0.5 kg motor at the elbow.
FLEXIBLE_DEFAULTS = {
    "l1": 0.5, "l2": 0.5,                  # link lengths [m]
    "rhoA1": 0.54, "rhoA2": 0.54,          # mass per length [kg/m]
    "EI1": 18.67, "EI2": 18.67,            # bending stiffness [N·m²]
    "Jh1": 0.01,                           # hub of joint 1 [kg·m²]
    "mh2": 0.5, "Jh2": 5e-4,               # motor of joint 2 at link 1's tip [kg], [kg·m²]
    "mp": 0.1, "Jp": 5e-5,                 # payload at the last tip [kg], [kg·m²]
    "g": 9.81,                             # gravity along −y [m/s²]; 0 turns it off
    "modes1": 2.0, "modes2": 2.0,          # assumed modes per link (0: rigid)
    "zeta1": 0.0, "zeta2": 0.0,            # damping ratio of each link's modes
    "b1": 0.0, "b2": 0.0,                  # joint dampers [N·m·s/rad]
}
MAX_MODES = 8


def flexible_arm(links: int = 2, link_modes: LinkModes | None = None, normalisation: Normalisation = "link-mass",
                 joint_frame: JointFrame = "axis", geometric_stiffness: bool | None = None,
                 **parameters: float) -> Model:
    """The built-in arm ``flex1`` (one flexible link on a hub) or ``flex2`` (the paper's two-link arm).

    Parameters
    ----------
    links : {1, 2}
        Number of links.
    link_modes : {"clamped-free", "clamped-mass"}, optional
        Mode shapes (see :func:`flexible_chain`; None: the joint frame's).
    normalisation : {"link-mass", "unit"}
        Modal mass of each mode.
    joint_frame : {"axis", "tip"}
        Where joint 2 is measured from (see :func:`flexible_chain`).
    geometric_stiffness : bool, optional
        Gravity's axial-load stiffness (None: on in the tip frame only).
    **parameters : float
        Overrides of :data:`FLEXIBLE_DEFAULTS` (for ``flex1``, those of link 1, the hub,
        the payload, g, modes1, zeta1 and b1).
    """
    if links not in (1, 2):
        raise InputError("the built-in flexible arms have 1 or 2 links")
    names = [k for k in FLEXIBLE_DEFAULTS if links == 2 or not k.endswith("2")]
    values = {k: FLEXIBLE_DEFAULTS[k] for k in names}
    for key, value in parameters.items():
        if key not in values:
            raise InputError(f"flex{links} has no parameter {key!r} (it has: {', '.join(names)})")
        values[key] = float(value)
    for k in range(1, links + 1):
        m = values[f"modes{k}"]
        if m != int(m) or not 0 <= m <= MAX_MODES:
            raise InputError(f"modes{k} must be a whole number of modes from 0 to {MAX_MODES}, got {m:g}")
        if min(values[f"l{k}"], values[f"rhoA{k}"], values[f"EI{k}"]) <= 0:
            raise InputError(f"l{k}, rhoA{k} and EI{k} must be positive")
    masses = [values["Jh1"], values["mp"], values["Jp"]] + ([values["mh2"], values["Jh2"]] if links == 2 else [])
    if min(masses) < 0 or min(values[f"zeta{k}"] for k in range(1, links + 1)) < 0:
        raise InputError("masses, inertias and damping ratios cannot be negative")
    tips = [(values["mh2"], values["Jh2"]), (values["mp"], values["Jp"])] if links == 2 \
        else [(values["mp"], values["Jp"])]
    chain = [FlexibleLink(values[f"l{k}"], values[f"rhoA{k}"], values[f"EI{k}"], int(values[f"modes{k}"]),
                          values["Jh1"] if k == 1 else 0.0, *tips[k - 1], values[f"zeta{k}"])
             for k in range(1, links + 1)]
    model = flexible_chain(chain, gravity=values["g"], link_modes=link_modes, normalisation=normalisation,
                           damping=[values[f"b{k}"] for k in range(1, links + 1)], name=f"flex{links}",
                           joint_frame=joint_frame, geometric_stiffness=geometric_stiffness)
    counts = "+".join(str(int(values[f"modes{k}"])) for k in range(1, links + 1))
    link_modes = link_modes_for(joint_frame, link_modes)
    axial = geometric_stiffness if geometric_stiffness is not None else joint_frame == "tip"
    conventions = (", joints from the tip" if joint_frame == "tip" and links > 1 else "") \
        + (", geometric stiffness" if axial and values["g"] else "")
    return replace(model, parameters=values, spring_rest=(0.0,) * model.dof,
                   builder=partial(flexible_arm, links, link_modes, normalisation, joint_frame, geometric_stiffness),
                   description=f"{'two' if links == 2 else 'one'}-link flexible arm, {counts} {link_modes} modes"
                               f"{conventions}")
