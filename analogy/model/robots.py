"""Robot models whose mass matrices are derived from kinematics: M(q) = Σ m·Jᵀ·J + I·J_ωᵀ·J_ω."""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache, partial
from typing import Sequence

import numpy as np
import sympy as sp

from ..errors import InputError
from .catalog import FAMILIES, ROBOT_NAMES, family_builder, robot_family
from .constant import ConstantModel
from .joint import JointSpace
from .linkages import ClosedChainModel, link_mass_matrix
from .symbolic import Model

__all__ = ["point_mass_matrix", "redundant_actuators", "planar_serial", "serial_2dof",
           "serial_3dof", "five_bar", "planar_3rrr", "parallel_3dof", "numeric_model", "random_spd_model",
           "ROBOTS", "robot"]


def point_mass_matrix(masses: Sequence, positions: Sequence, q: Sequence) -> sp.Matrix:
    """Mass matrix of point masses: M(q) = Σ_k m_k·J_kᵀ·J_k with J_k = ∂p_k/∂q.

    Parameters
    ----------
    masses : sequence of sympy expressions
    positions : sequence of sympy column vectors p_k(q), any dimension
    q : sequence of sympy symbols
    """
    return link_mass_matrix([(m, 0, p, None) for m, p in zip(masses, positions)], q)


def _symbols(prefix: str, n: int):
    return [sp.Symbol(f"{prefix}{k + 1}", real=True) for k in range(n)]


def redundant_actuators(d1: float = 1.5, d2: float = 1.0, b1: float = 1.0,
                        b2: float = 0.5) -> Model:
    """Two stacked actuators on one axis (paper Fig. 8): stage 1 moves d1 and d2, stage 2 moves d2.

    Parameters
    ----------
    d1 : float
        Mass of stage 1 [kg].
    d2 : float
        Mass of stage 2 [kg].
    b1 : float
        Damping of actuator 1 [N s/m].
    b2 : float
        Damping of actuator 2 [N s/m].
    """
    q = _symbols("q", 2)
    d, b = _symbols("d", 2), _symbols("b", 2)
    positions = [sp.Matrix([q[0]]), sp.Matrix([q[0] + q[1]])]
    return Model("redundant", point_mass_matrix(d, positions, q), damping=b,
                 parameters={"d1": d1, "d2": d2, "b1": b1, "b2": b2}, coordinates=q,
                 topology="serial", joints=("prismatic", "prismatic"),
                 description="redundant actuators on one axis: point masses d1 (stage 1) and d2 (stage 2)")


@lru_cache(maxsize=None)
def _planar_serial_parts(n: int) -> tuple[sp.ImmutableMatrix, sp.ImmutableMatrix]:
    # Depends on n only (lengths and masses stay symbolic): derived once per process.
    q, l, d = _symbols("q", n), _symbols("l", n), _symbols("d", n)
    g = sp.Symbol("g", real=True)
    positions, x, y, angle = [], 0, 0, 0
    for k in range(n):
        angle += q[k]
        x += l[k] * sp.cos(angle)
        y += l[k] * sp.sin(angle)
        positions.append(sp.Matrix([x, y]))
    # Gravity g along −y (the arm moves in a vertical plane when g > 0): G = ∂U/∂q, U = Σ d_k·g·y_k.
    potential = g * sum(d[k] * positions[k][1] for k in range(n))
    gravity = sp.Matrix([sp.diff(potential, qk) for qk in q])
    return sp.ImmutableMatrix(point_mass_matrix(d, positions, q)), sp.ImmutableMatrix(gravity)


def planar_serial(n: int, lengths: Sequence[float] | None = None,
                  masses: Sequence[float] | None = None,
                  dampings: Sequence[float] | None = None,
                  stiffnesses: Sequence[float] | None = None, gravity: float = 0.0) -> Model:
    """Planar nR arm with a point mass d_k at the distal end of link k, joint dampers b_k.

    The parameter ``g`` (default *gravity* = 0: a horizontal plane) turns on gravity
    along −y, G(q) = ∂U/∂q with U = Σ d_k·g·y_k.

    Parameters
    ----------
    n : int
        Number of joints.
    lengths : sequence of float, optional
        Link lengths [m].
    masses : sequence of float, optional
        Point masses at the link ends [kg].
    dampings : sequence of float, optional
        Joint dampers [N m s/rad].
    stiffnesses : sequence of float, optional
        Joint springs [N m/rad].
    gravity : float
        Default value of the parameter g [m/s²].
    """
    if n < 1:
        raise InputError("a serial arm needs at least one joint")
    q, l, d, b = _symbols("q", n), _symbols("l", n), _symbols("d", n), _symbols("b", n)
    lengths = list(lengths) if lengths is not None else [1.0 - 0.2 * k / max(n - 1, 1) for k in range(n)]
    masses = list(masses) if masses is not None else [2.0 / (k + 1) for k in range(n)]
    dampings = list(dampings) if dampings is not None else [1.0 / (k + 1) for k in range(n)]
    for label, vals in (("lengths", lengths), ("masses", masses), ("dampings", dampings)):
        if len(vals) != n:
            raise InputError(f"{label} must have {n} entries, got {len(vals)}")
    params = {}
    for syms, vals in ((l, lengths), (d, masses), (b, dampings)):
        params.update({str(s): float(v) for s, v in zip(syms, vals)})
    stiffness = None
    if stiffnesses is not None:
        k_syms = _symbols("k", n)
        params.update({str(s): float(v) for s, v in zip(k_syms, stiffnesses)})
        stiffness = k_syms
    params["g"] = float(gravity)
    mass, load = _planar_serial_parts(n)
    return Model(f"serial{n}" if n != 2 else "serial2", mass, gravity=list(load),
                 damping=b, stiffness=stiffness, parameters=params, coordinates=q,
                 topology="serial", joints=("revolute",) * n,
                 description=f"planar {n}R serial arm, point masses d_k at the end of link k")


def serial_2dof(**kw) -> Model:
    """The 2-DOF serial arm of the MP-model paper (eqs. 17–20): l1 = 1, l2 = 0.8, d1 = 2, d2 = 1.

    Parameters
    ----------
    **kw
        Passed to :func:`planar_serial` (e.g. ``stiffnesses``).
    """
    return planar_serial(2, lengths=(1.0, 0.8), masses=(2.0, 1.0), dampings=(1.0, 0.5), **kw)


def serial_3dof(**kw) -> Model:
    """A planar 3R arm: l = (0.6, 0.5, 0.4) m, d = (2, 1.5, 1) kg.

    Parameters
    ----------
    **kw
        Passed to :func:`planar_serial` (e.g. ``stiffnesses``).
    """
    return planar_serial(3, lengths=(0.6, 0.5, 0.4), masses=(2.0, 1.5, 1.0),
                         dampings=(1.0, 0.8, 0.5), **kw)


def numeric_model(name: str, mass_matrix, damping=None, stiffness=None,
                  topology: str = "parallel", description: str = "") -> ConstantModel:
    """A model with constant numeric matrices (no configuration dependence).

    Parameters
    ----------
    name : str
        The model's name.
    mass_matrix : array_like
        Constant M.
    damping : array_like, optional
        A diagonal or a matrix.
    stiffness : array_like, optional
        A diagonal or a matrix.
    topology : str
        Default topology.
    description : str
        A few words.
    """
    def square(a):
        return None if a is None else (np.asarray(a, dtype=float) if np.ndim(a) == 2 else np.diag(np.asarray(a, dtype=float)))
    joint = JointSpace(np.asarray(mass_matrix, dtype=float), square(damping), square(stiffness))
    return ConstantModel(name, joint, topology=topology, description=description)


def random_spd_model(n: int, seed: int = 0, topology: str = "serial",
                     stiffness: bool = False) -> ConstantModel:
    """A random well-conditioned SPD mass matrix with positive diagonal damping.

    Parameters
    ----------
    n : int
        Number of joints.
    seed : int
        Random seed.
    topology : str
        Default topology.
    stiffness : bool
        Add random joint springs.
    """
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    m = a @ a.T / n + np.eye(n)
    b = rng.uniform(0.5, 2.0, size=n)
    k = rng.uniform(1.0, 4.0, size=n) if stiffness else None
    return numeric_model(f"random{n}", m, b, k, topology=topology,
                         description=f"random SPD {n}-DOF (seed {seed})")


def _unit(angle):
    return sp.Matrix([sp.cos(angle), sp.sin(angle)])


def _two_link_ik(base, target, proximal: float, distal: float, elbow: int):
    """Absolute angles (proximal, distal) of a two-link leg from *base* to *target*.

    ``elbow = +1`` turns the proximal link counterclockwise from the base-target
    line, ``-1`` clockwise.
    """
    base, target = np.asarray(base, dtype=float), np.asarray(target, dtype=float)
    dx, dy = target - base
    r = float(np.hypot(dx, dy))
    c = (proximal ** 2 + r ** 2 - distal ** 2) / (2.0 * proximal * r)
    if not -1.0 < c < 1.0:
        raise ValueError("target out of reach")
    q = np.arctan2(dy, dx) + elbow * np.arccos(c)
    elbow_point = base + proximal * np.array([np.cos(q), np.sin(q)])
    ex, ey = target - elbow_point
    return float(q), float(np.arctan2(ey, ex))


def _leg_links(base, q, psi, la, lb, ma, mb, ja, jb):
    """Proximal and distal links of an RR leg (COM at mid-length), and the leg's tip."""
    base = sp.Matrix(base)
    elbow = base + la * _unit(q)
    return [(ma, ja, base + la / 2 * _unit(q), q),
            (mb, jb, elbow + lb / 2 * _unit(psi), psi)], elbow + lb * _unit(psi)


def _with_values(template: ClosedChainModel, names, values, dampings, stiffnesses):
    """A copy of *template* with parameter values, joint dampers b_k and optional springs k_k."""
    n = template.dof
    for label, vals in (("dampings", dampings), ("stiffnesses", stiffnesses)):
        if vals is not None and len(vals) != n:
            raise InputError(f"{label} must have {n} entries, got {len(vals)}")
    params = {k: float(v) for k, v in zip(names, values)}
    b = _symbols("b", n)
    params.update({str(s): float(v) for s, v in zip(b, dampings)})
    k = None
    if stiffnesses is not None:
        k = _symbols("k", n)
        params.update({str(s): float(v) for s, v in zip(k, stiffnesses)})
    return replace(template, parameters=params, damping=b, stiffness=k)


_FIVE_BAR = ("d", "la", "lb", "ma", "mb", "ja", "jb", "me")


@lru_cache(maxsize=None)
def _five_bar_chain() -> ClosedChainModel:
    q = _symbols("q", 2)
    psi = _symbols("psi", 2)
    s = {k: sp.Symbol(k, real=True) for k in _FIVE_BAR}
    bases = ([-s["d"] / 2, 0], [s["d"] / 2, 0])
    links, tips = [], []
    for i in range(2):
        leg, tip = _leg_links(bases[i], q[i], psi[i], s["la"], s["lb"], s["ma"], s["mb"],
                              s["ja"], s["jb"])
        links += leg
        tips.append(tip)
    links.append((s["me"], 0, tips[0], None))

    def reference(v):
        # End effector on the symmetry axis with both elbows at a right angle.
        h = np.sqrt(v["la"] ** 2 + v["lb"] ** 2 - v["d"] ** 2 / 4)
        legs = [_two_link_ik((side * v["d"] / 2, 0.0), (0.0, h), v["la"], v["lb"], -side)
                for side in (-1, 1)]
        return [a for a, _ in legs], [p for _, p in legs]

    return ClosedChainModel.from_links(
        "parallel2", links, q, psi, tips[0] - tips[1], reference,
        parameters=dict.fromkeys(_FIVE_BAR, 1.0), topology="parallel", joints=("revolute", "revolute"),
        description="2-DOF parallel five-bar (haptic pantograph), elbows out, M(q) from kinematics")


def five_bar(d: float = 0.06, la: float = 0.12, lb: float = 0.15, ma: float = 0.10,
             mb: float = 0.08, ja: float = 1.2e-4, jb: float = 1.5e-4,
             me: float = 0.02, dampings: Sequence[float] = (4e-3, 4e-3),
             stiffnesses: Sequence[float] | None = None) -> ClosedChainModel:
    """Planar five-bar (haptic pantograph of Hayward et al. 1994), actuated at both base joints.

    Base joints A1 = (−d/2, 0) and A2 = (d/2, 0); q1, q2 are the absolute angles
    of the proximal links (length la, mass ma) from the x axis; the distal links
    (lb, mb) have absolute angles psi1, psi2 and meet at the end effector P,
    which carries a point mass me. Links have their COM at mid-length and
    centroidal inertias ja, jb (defaults m·l²/12: uniform bars).

    Assembly mode: P to the left of E1→E2, beyond the elbows seen from the base,
    which is sin(psi1 − psi2) < 0; it is reached from the elbows-out reference
    P = (0, √(la² + lb² − d²/4)) (E1 left of A1→P, E2 right of A2→P, both
    elbows right angles). The scene and the tests stay in the elbows-out region.
    Units: m, kg, kg·m², N·m·s/rad (b1, b2), N·m/rad (k1, k2).

    Parameters
    ----------
    d : float
        Distance between the base joints [m].
    la : float
        Proximal link length [m].
    lb : float
        Distal link length [m].
    ma : float
        Proximal link mass [kg].
    mb : float
        Distal link mass [kg].
    ja : float
        Proximal centroidal inertia [kg m^2].
    jb : float
        Distal centroidal inertia [kg m^2].
    me : float
        End-effector point mass [kg].
    dampings : sequence of float
        Joint dampers [N m s/rad].
    stiffnesses : sequence of float, optional
        Joint springs [N m/rad].
    """
    return _with_values(_five_bar_chain(), _FIVE_BAR, (d, la, lb, ma, mb, ja, jb, me),
                        dampings, stiffnesses)


_THREE_RRR = ("rb", "rp", "la", "lb", "ma", "mb", "mp", "ja", "jb", "jp")
#: Directions of the base joints (and of the platform joints at phi = 0) of the 3-RRR.
_ALPHAS = (-sp.pi / 2, sp.pi / 6, 5 * sp.pi / 6)


@lru_cache(maxsize=None)
def _three_rrr_chain() -> ClosedChainModel:
    q = _symbols("q", 3)
    psi = _symbols("psi", 3)
    x, y, phi = (sp.Symbol(n, real=True) for n in ("x", "y", "phi"))
    s = {k: sp.Symbol(k, real=True) for k in _THREE_RRR}
    centre = sp.Matrix([x, y])
    links, residual = [], []
    for i, alpha in enumerate(_ALPHAS):
        leg, tip = _leg_links(s["rb"] * _unit(alpha), q[i], psi[i], s["la"], s["lb"], s["ma"],
                              s["mb"], s["ja"], s["jb"])
        links += leg
        residual += list(tip - centre - s["rp"] * _unit(alpha + phi))
    links.append((s["mp"], s["jp"], centre, phi))

    def reference(v):
        legs = []
        for alpha in (float(a) for a in _ALPHAS):
            u = np.array([np.cos(alpha), np.sin(alpha)])
            legs.append(_two_link_ik(v["rb"] * u, v["rp"] * u, v["la"], v["lb"], 1))
        return [a for a, _ in legs], [p for _, p in legs] + [0.0, 0.0, 0.0]

    return ClosedChainModel.from_links(
        "parallel3", links, q, psi + [x, y, phi], residual, reference,
        parameters=dict.fromkeys(_THREE_RRR, 1.0), topology="parallel", joints=("revolute",) * 3,
        description="3-DOF planar 3-RRR parallel mechanism, M(q) from kinematics")


def planar_3rrr(rb: float = 0.20, rp: float = 0.05, la: float = 0.12, lb: float = 0.12,
                ma: float = 0.15, mb: float = 0.10, mp: float = 0.20, ja: float = 1.8e-4,
                jb: float = 1.2e-4, jp: float = 1.25e-4,
                dampings: Sequence[float] = (7e-3, 7e-3, 7e-3),
                stiffnesses: Sequence[float] | None = None) -> ClosedChainModel:
    """Planar 3-RRR parallel mechanism, actuated at the three base joints.

    Base joints A_i = rb·(cos α_i, sin α_i) with α_i = −90°, 30°, 150°; the
    platform is an equilateral triangle (mass mp, centroidal inertia jp,
    default mp·rp²/4: uniform plate) with COM at its centre (x, y),
    orientation phi and joints C_i = (x, y) + rp·(cos(α_i + phi), sin(α_i + phi)).
    Leg i: proximal link (la, ma) at absolute angle q_i, distal link (lb, mb) at
    absolute angle psi_i; COM at mid-length, centroidal inertias ja, jb
    (defaults m·l²/12: uniform bars).

    Working mode: every elbow turned counterclockwise from its line A_i→C_i;
    the assembly mode is the one reached from the home pose x = y = phi = 0.
    Units: m, kg, kg·m², N·m·s/rad (b_i), N·m/rad (k_i).

    Parameters
    ----------
    rb : float
        Base radius [m].
    rp : float
        Platform radius [m].
    la : float
        Proximal link length [m].
    lb : float
        Distal link length [m].
    ma : float
        Proximal link mass [kg].
    mb : float
        Distal link mass [kg].
    mp : float
        Platform mass [kg].
    ja : float
        Proximal centroidal inertia [kg m^2].
    jb : float
        Distal centroidal inertia [kg m^2].
    jp : float
        Platform centroidal inertia [kg m^2].
    dampings : sequence of float
        Joint dampers [N m s/rad].
    stiffnesses : sequence of float, optional
        Joint springs [N m/rad].
    """
    return _with_values(_three_rrr_chain(), _THREE_RRR, (rb, rp, la, lb, ma, mb, mp, ja, jb, jp),
                        dampings, stiffnesses)


def parallel_3dof() -> ClosedChainModel:
    # Return springs at the base joints, so that the paper's 3-DOF example has inductors.
    return planar_3rrr(stiffnesses=(0.01, 0.01, 0.01))


def robot(name: str, link_modes: str | None = None, joint_frame: str | None = None,
          geometric_stiffness: bool | None = None) -> Model:
    """The symbolic model of a built-in robot (see :data:`~analogy.model.catalog.FAMILIES`).

    Parameters
    ----------
    name : str
        A built-in robot (see :func:`analogy.model.catalog.robot_family`).
    link_modes : {"clamped-free", "clamped-mass"}, optional
        The flexible arms' mode shapes (see :func:`analogy.model.flexible.flexible_chain`).
    joint_frame : {"axis", "tip"}, optional
        The flexible arms' joint frame.
    geometric_stiffness : bool, optional
        The flexible arms' axial-load stiffness under gravity.
    """
    family, size = robot_family(name)
    conventions = {k: v for k, v in (("link_modes", link_modes), ("joint_frame", joint_frame),
                                     ("geometric_stiffness", geometric_stiffness)) if v is not None}
    if conventions and not family.flexible:
        flexible = " and ".join(f.name for f in FAMILIES if f.flexible)
        shown = ", ".join(k.replace("_", " ") for k in conventions)
        raise InputError(f"{shown} apply to the flexible arms {flexible}, not to {name}")
    if family.symbolic is None:
        raise InputError(f"{name} is given by its numbers: it has no symbolic model (its linear dynamics "
                         "are built numerically)")
    build = family_builder(family.symbolic)
    if size is None:
        return build(*family.args, **conventions)
    if size > family.symbolic_sizes:
        raise InputError(f"{name}'s symbolic model (needed for its nonlinear dynamics) is built up to "
                         f"{family.symbolic_sizes} joints, as its derivation grows as n^4.8 (serial12's took "
                         f"minutes); its linear dynamics are numeric at any size ({family.numeric.replace(':', '.')})")
    return build(size)


#: The single built-in robots by name, each a builder of its symbolic model.
ROBOTS = {name: partial(robot, name) for name in ROBOT_NAMES}
