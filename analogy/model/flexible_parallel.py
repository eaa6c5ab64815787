"""The flexible-robot paper's parallel-link arm (its Fig. 1.b): two flexible links whose upper one a parallelogram holds.

Link AB (length l1, flexible) turns on motor 1 at the base A, at θ1 from the x axis.
The upper link is pinned at the elbow B: a flexible forearm from B to the tip (l2, as
in the paper's eq. 21, at θ1 + θ2 from the x axis) and a rigid bracket BC of length lc
behind the elbow. Motor 2, also at the base, turns the rigid crank AD (length lc) at
θ3 + π, and the rigid closing link DC (length l1) joins D to C, so that ABCD is a
parallelogram: in the undeformed arm the forearm points along θ3 and θ1 + θ2 = θ3 (the
paper's "θ2 = θ3", AD measured from AB's axis as BC is).

Cut open at C, the arm is a tree over θ = (θ1, θ3, δ_1…, δ_2…, θ2, θ4), θ4 the closing
link's direction; the loop closure D + l1·e(θ4) = C (two equations) fixes the passive θ2
and θ4 (:class:`~analogy.model.linkages.ClosedChainModel`). The flexible links are the
serial arm's (:func:`~analogy.model.flexible.flexible_chain`: AB carries the elbow's
mass mh2 and no rotary inertia, for a pin passes no moment; the forearm the payload),
the crank, bracket and closing link are uniform rigid bars (the choice: they are short
or stiff beside the links they guide), and both motors' reactions act on the base, so
each torque drives its own coordinate.

What the parallelogram changes: to first order in the deflections, the loop gives
θ2 = θ3 − θ1 whatever link AB's tip deflection and slope, so the forearm's direction is
motor 2's angle. A base encoder measures it, where the serial arm's forearm turns with
AB's end slope, which is hard to measure (the paper's motive). The paper's axis frame
(joint 2 measured from AB's undeformed axis) is this arm's linearisation.

Gravity's geometric stiffness (on by default): an inextensible link's tip moves in by
½·δᵀ·(∫ψ'ψ'ᵀ dx)·δ along its axis. The serial arm's axial load takes it into gravity's
potential (:func:`~analogy.model.flexible.flexible_chain`); here the elbow moves in too, so
the loop closure and the bracket's weight take it as well. Without it, the assumed modes
lengthen AB's chord by u²/2l1 where an inextensible link shortens it, and the loop's
curvature under the multipliers that hold gravity gives a stiffness of the wrong sign.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial

import sympy as sp

from ..errors import InputError

from .beams import Normalisation, beam_modes, gauss_points
from .conventions import LinkModes, link_modes_for
from .flexible import FLEXIBLE_DEFAULTS, MAX_MODES, FlexibleLink, chain_kinematics, flexible_chain
from .linkages import ClosedChainModel, link_mass_matrix

__all__ = ["FLEXPAR_DEFAULTS", "flexible_parallel_arm"]

#: flexpar's parameters: flex2's links, hub and payload, with the elbow a bearing (its
#: motor moved to the base, where Jh2 is its rotor), and the parallelogram's rigid bars.
FLEXPAR_DEFAULTS = {
    **{k: v for k, v in FLEXIBLE_DEFAULTS.items() if k not in ("mh2", "Jh2")},
    "mh2": 0.1,                            # elbow bearing at link 1's tip [kg]
    "Jh2": 5e-4,                           # rotor of motor 2, at the base, on the crank [kg·m²]
    "lc": 0.1,                             # crank AD and bracket BC [m]
    "mc": 0.05,                            # mass of the crank, and of the bracket [kg]
    "md": 0.1,                             # mass of the closing link DC (length l1) [kg]
}


def _unit(angle) -> sp.Matrix:
    return sp.Matrix([sp.cos(angle), sp.sin(angle)])


def _flexpar_values(parameters: dict) -> dict:
    """:data:`FLEXPAR_DEFAULTS` with *parameters*, each a known name and a value the arm can have."""
    values = dict(FLEXPAR_DEFAULTS)
    for key, value in parameters.items():
        if key not in values:
            raise InputError(f"flexpar has no parameter {key!r} (it has: {', '.join(values)})")
        values[key] = float(value)
    for k in (1, 2):
        m = values[f"modes{k}"]
        if m != int(m) or not 0 <= m <= MAX_MODES:
            raise InputError(f"modes{k} must be a whole number of modes from 0 to {MAX_MODES}, got {m:g}")
    if min(values[k] for k in ("l1", "l2", "rhoA1", "rhoA2", "EI1", "EI2", "lc")) <= 0:
        raise InputError("l1, l2, rhoA1, rhoA2, EI1, EI2 and lc must be positive")
    if min(values[k] for k in ("Jh1", "Jh2", "mh2", "mp", "Jp", "mc", "md", "zeta1", "zeta2")) < 0:
        raise InputError("masses, inertias and damping ratios cannot be negative")
    return values


def _elbow(kin, links: list, v: dict, link_modes: str, normalisation: str, axial: bool) -> tuple:
    """The elbow B, link AB's deformed tip, with its mode shapes' tip values; and B moved inward by the
    link's foreshortening where the geometric stiffness is on (the point the closing loop meets)."""
    theta1 = kin.angles[0]
    elbow = moved = kin.tips[0]
    if links[0].modes:
        tip = (v["mh2"], 0.0) if link_modes == "clamped-mass" else (0.0, 0.0)
        modes = beam_modes(links[0].modes, v["l1"], v["rhoA1"], v["EI1"], *tip, normalisation=normalisation)
        elbow = moved = elbow.subs(dict(zip(kin.tip_shapes[0], modes.shape([v["l1"]])[0].tolist())))
        if axial:
            xg, wg = gauss_points(96)
            slope = modes.shape(xg * v["l1"], 1)
            delta = sp.Matrix(kin.modal[0])
            inward = (delta.T * sp.Matrix((v["l1"] * (slope.T * wg) @ slope).tolist()) * delta)[0] / 2
            moved = elbow - inward * _unit(theta1)
    return elbow, moved


def flexible_parallel_arm(link_modes: LinkModes | None = None, normalisation: Normalisation = "link-mass",
                          geometric_stiffness: bool | None = None, joint_frame: str | None = None,
                          **parameters: float) -> ClosedChainModel:
    """The built-in arm ``flexpar``: the paper's parallel-link flexible robot (see the module).

    Active coordinates (θ1, θ3, δ11 …, δ21 …): the motors' angles from the x axis and
    the links' modal amplitudes; passive (θ2, θ4).

    Parameters
    ----------
    link_modes : {"clamped-free", "clamped-mass"}, optional
        Each flexible link's mode shapes (None: clamped-free, the paper's).
    normalisation : {"link-mass", "unit"}
        Modal mass of each mode.
    geometric_stiffness : bool, optional
        The links' foreshortening under gravity and in the loop (None: on).
    joint_frame : None
        Refused: the parallelogram, not a joint frame, sets the forearm's direction.
    **parameters : float
        Overrides of :data:`FLEXPAR_DEFAULTS`.
    """
    if joint_frame is not None:
        raise InputError("flexpar has no joint frame to choose: its parallelogram holds the forearm along "
                         "motor 2's angle whatever link AB's tip slope")
    axial = geometric_stiffness is None or bool(geometric_stiffness)
    values = _flexpar_values(parameters)
    link_modes = link_modes_for("axis", link_modes)
    v = values
    links = [FlexibleLink(v["l1"], v["rhoA1"], v["EI1"], int(v["modes1"]), v["Jh1"], v["mh2"], 0.0, v["zeta1"]),
             FlexibleLink(v["l2"], v["rhoA2"], v["EI2"], int(v["modes2"]), 0.0, v["mp"], v["Jp"], v["zeta2"])]
    chain = flexible_chain(links, gravity=v["g"], link_modes=link_modes, normalisation=normalisation,
                           damping=[v["b1"], 0.0], geometric_stiffness=axial)
    kin = chain_kinematics([v["l1"], v["l2"]], [links[0].modes, links[1].modes])
    theta1, theta2 = kin.angles
    theta3, theta4 = sp.symbols("theta3 theta4", real=True)
    modal = [d for ds in kin.modal for d in ds]
    active, passive = [theta1, theta3, *modal], [theta2, theta4]
    tree = active + passive
    at = [tree.index(c) for c in kin.coordinates]

    elbow, moved = _elbow(kin, links, v, link_modes, normalisation, axial)
    lc, l1 = v["lc"], v["l1"]
    crank_end = -lc * _unit(theta3)
    upper = theta1 + theta2
    bars = [(0.0, v["Jh2"], sp.zeros(2, 1), theta3),                                   # motor 2's rotor
            (v["mc"], v["mc"] * lc ** 2 / 12, crank_end / 2, theta3),                 # crank AD
            (v["md"], v["md"] * l1 ** 2 / 12, crank_end + l1 / 2 * _unit(theta4), theta4),   # closing link DC
            (v["mc"], v["mc"] * lc ** 2 / 12, elbow - lc / 2 * _unit(upper), upper)]  # bracket BC
    tree_mass = link_mass_matrix(bars, tree)
    tree_gravity = sp.zeros(1, len(tree))
    heights = [0, crank_end[1] / 2, crank_end[1] + l1 / 2 * sp.sin(theta4), moved[1] - lc / 2 * sp.sin(upper)]
    for (mass, *_), height in zip(bars, heights):
        tree_gravity += v["g"] * mass * sp.Matrix([height]).jacobian(tree)
    for a, ca in enumerate(at):
        tree_gravity[ca] += chain.gravity[a] if chain.gravity is not None else 0
        for b, cb in enumerate(at):
            tree_mass[ca, cb] += chain.mass_matrix[a, b]
    tree_mass = sp.Matrix(len(tree), len(tree), lambda i, j: sp.expand(tree_mass[min(i, j), max(i, j)]))

    n = len(active)
    rates = sp.Matrix(2, n, lambda i, j: sp.Symbol(f"d{passive[i]}_d{active[j]}", real=True))
    s = sp.eye(n).col_join(rates)
    mass = sp.ImmutableMatrix((s.T * tree_mass * s).applyfunc(sp.expand))
    gravity = list(tree_gravity * s) if v["g"] else None
    closure = crank_end + l1 * _unit(theta4) - (moved - lc * _unit(upper))

    chain_damping = chain.damping if isinstance(chain.damping, sp.MatrixBase) else sp.diag(*chain.damping)
    damping = sp.zeros(n)
    stiffness = sp.zeros(n)
    for a, ca in enumerate(at):
        for b, cb in enumerate(at):
            if ca < n and cb < n:
                damping[ca, cb] = chain_damping[a, b]
                stiffness[ca, cb] = chain.stiffness[a, b]
    damping[1, 1] += v["b2"]

    def reference(_values):
        # the parallelogram undeformed, away from its flat (singular) poses θ3 − θ1 = 0, π
        return [0.0, 1.0] + [0.0] * len(modal), [1.0, 0.0]

    def branch(q, _values):
        # the undeformed arm at q's motor angles is a parallelogram: θ2 = θ3 − θ1, θ4 = θ1
        return [q[0], q[1]] + [0.0] * len(modal), [q[1] - q[0], q[0]]

    counts = f"{links[0].modes}+{links[1].modes}"
    model = ClosedChainModel(
        "flexpar", mass, damping=damping, stiffness=stiffness, gravity=gravity, parameters=values,
        coordinates=active, passive=passive, rates=rates, constraints=closure, reference=reference, branch=branch,
        tree_mass=sp.ImmutableMatrix(tree_mass), tree_gravity=sp.ImmutableMatrix(tree_gravity) if v["g"] else None,
        topology="parallel", joints=("revolute", "revolute") + ("modal",) * len(modal),
        description=f"parallel-link flexible arm (Fig. 1.b), {counts} {link_modes} modes"
                    f"{', geometric stiffness' if axial and v['g'] else ''}")
    return replace(model, spring_rest=(0.0,) * n,
                   builder=partial(flexible_parallel_arm, link_modes, normalisation, geometric_stiffness))
