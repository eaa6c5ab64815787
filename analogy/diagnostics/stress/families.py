"""The stress families: systems that each push one numerical difficulty to its edge."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Iterator

import numpy as np

from ...circuit.elements import ZERO_TOL
from ...circuit.node_system import node_system
from ...errors import InputError
from ...model.joint import JointSpace
from ...model.urdf import urdf_model
from ...model.urdf_robots import URDF_ROBOTS, urdf_robot
from ...presets import DEFAULT_SOLVERS, PRESETS, Preset

__all__ = ["StressCase", "FAMILIES", "FAMILY_TITLES", "ALL_FAMILIES", "cases", "singular_q1", "spd_with_spectrum"]

#: The families, by letter, with what each sweeps.
FAMILY_TITLES = {
    "a": "conditioning: cond(M) from 1 to 1e14",
    "b": "time-scale separation: ω_max/ω_min from 1 to 1e8, damping ratio from 0 to 1e3",
    "c": "long undamped runs: 10 to 10,000 periods",
    "d": "size: n = 2 to 200, dense, serial topology",
    "e": "units and scale: mass, time and velocity scales",
    "f": "near-singular: MP capacitances through zero, elements at the zero tolerance, the 3-RRR near its "
         "singular pose",
    "g": "nonlinear: fast motions and a chaotic double pendulum",
    "h": "a real arm at its singular poses: the UR5's elbow straightening (q3 → 0) and its wrist "
         "(q5 → 0), from its URDF, g = 0",
    "i": "real arms at their defaults: each named URDF robot hanging (or at g = 0 where it cannot hang "
         "within its limits), under steps sized to it, over a horizon from its modes",
}
#: Every family, the default of :func:`cases`.
ALL_FAMILIES = "".join(FAMILY_TITLES)


@dataclass(frozen=True)
class StressCase:
    """One system of a family, with the solver runs it gets.

    Attributes
    ----------
    family : str
        Its letter (see :data:`FAMILY_TITLES`).
    axis : str
        The swept quantity.
    value : float
        Its value in this case.
    label : str
        A short name of the case.
    build : callable
        Makes the node system (deferred, so that a case that cannot be built is a row).
    runs : tuple of (str, Preset)
        (label, preset) per run: the label names the solver and its setting, e.g.
        ``spice`` or ``spice/gear``.
    horizon : bool
        Report the predictability horizon (chaotic motion) rather than the error alone.
    reference_points : int
        Points at which the exact solution is checked against the 40-digit one.
    """

    family: str
    axis: str
    value: float
    label: str
    build: Callable[[], object]
    runs: tuple = ()
    horizon: bool = False
    reference_points: int = 9


def _timed(p: Preset, seconds: float) -> Preset:
    # bounded work per run: ODE wall time, and at most 10^6 SPICE steps (then flagged)
    return replace(p, budget=replace(p.budget, timeout=seconds, steps=min(p.budget.steps, 1_000_000)))


def spd_with_spectrum(eigenvalues, seed: int = 0) -> np.ndarray:
    """Q·diag(eigenvalues)·Qᵀ with a random orthogonal Q: an SPD matrix of a set condition number.

    Parameters
    ----------
    eigenvalues : array_like
        Positive eigenvalues.
    seed : int
        Random seed of Q.
    """
    lam = np.asarray(eigenvalues, dtype=float)
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(lam.size, lam.size)))
    m = (q * lam) @ q.T
    return 0.5 * (m + m.T)


def _runs(preset: Preset, solvers=DEFAULT_SOLVERS) -> tuple:
    return tuple((name, preset) for name in solvers)


def _conditioning(quick: bool, p: Preset) -> Iterator[StressCase]:
    conds = (1.0, 1e8) if quick else (1.0, 1e2, 1e4, 1e6, 1e8, 1e10, 1e12, 1e14)
    for topology in ("serial",) if quick else ("serial", "parallel"):
        for c in conds:
            def build(c=c, topology=topology):
                m = spd_with_spectrum(np.logspace(0, math.log10(c), 6), seed=1)
                js = JointSpace(m, np.diag(np.linspace(0.5, 2.0, 6)), np.diag(np.linspace(1.0, 4.0, 6)))
                return node_system(js, topology=topology, forces=[1.0, -0.5, 0.3, 0, 0.2, 0.7], t_stop=10.0)
            yield StressCase("a", "cond(M)", c, f"{topology} cond {c:.0e}", build, _runs(p))


def _time_scales(quick: bool, p: Preset) -> Iterator[StressCase]:
    ratios = (1.0, 1e2) if quick else (1.0, 1e2, 1e4, 1e6, 1e8)
    zetas = (0.01,) if quick else (0.0, 0.01, 1.0, 1e3)
    for r in ratios:
        for z in zetas:
            def build(r=r, z=z):
                w = np.array([1.0, r])
                m = np.array([[1.0, 0.2], [0.2, 1.0]])
                return node_system(JointSpace(m, np.diag(2 * z * w), np.diag(w ** 2)), forces=[1.0, 1.0],
                                   t_stop=10.0)
            yield StressCase("b", "omega ratio", r, f"ratio {r:.0e} zeta {z:g}", build, _runs(p))


def _long_runs(quick: bool, p: Preset) -> Iterator[StressCase]:
    periods = (10, 30) if quick else (10, 100, 1000, 10000)
    gear = replace(p, spice=replace(p.spice, options=dict(p.spice.options, method="gear")))
    lsoda = replace(p, ode=replace(p.ode, method="LSODA"))
    runs = (("spice", p), ("spice/gear", gear), ("ode", p), ("ode/LSODA", lsoda), ("exact", p))
    for k in periods:
        def build(k=k):
            js = JointSpace(np.eye(2), np.zeros((2, 2)), np.diag([1.0, 2.3 ** 2]))
            return node_system(js, forces=[1.0, 0.5], t_stop=2 * math.pi * k)
        yield StressCase("c", "periods", float(k), f"{k} periods", build, runs)


def _size(quick: bool, p: Preset) -> Iterator[StressCase]:
    from ...model.robots import random_spd_model
    sizes = (2, 10, 20) if quick else (2, 5, 10, 20, 50, 100, 200)
    for n in sizes:
        def build(n=n):
            return node_system(random_spd_model(n, seed=n), topology="serial", forces=[1.0] * n, t_stop=5.0)
        yield StressCase("d", "n", float(n), f"n = {n}", build, _runs(PRESETS["fast"]))


def _units(quick: bool, p: Preset) -> Iterator[StressCase]:
    m = np.array([[2.0, 0.4], [0.4, 1.0]])
    b, k, f = np.diag([1.0, 0.5]), np.diag([3.0, 1.0]), np.array([1.0, 0.5])
    scales = {"mass": (1e-9, 1e6) if quick else (1e-9, 1e-3, 1.0, 1e3, 1e6),
              "time": (1e-6, 1e4) if quick else (1e-6, 1e-3, 1.0, 1e2, 1e4),
              "velocity": (1e-9, 1e3) if quick else (1e-9, 1e-3, 1.0, 1e3)}
    yield StressCase("e", "unit", 1.0, "unit scale",
                     lambda: node_system(JointSpace(m, b, k), forces=list(f), t_stop=10.0), _runs(p))
    for kind, values in scales.items():
        for s in values:
            # mass: every element and force by s (same velocities); time: t → s·t keeps the
            # velocities if M and F scale by s and K by 1/s; velocity: forces by s.
            sm, sb, sk, sf, st = {"mass": (s, s, s, s, 1.0), "time": (s, 1.0, 1 / s, 1.0, s),
                                  "velocity": (1.0, 1.0, 1.0, s, 1.0)}[kind]
            def build(sm=sm, sb=sb, sk=sk, sf=sf, st=st):
                return node_system(JointSpace(sm * m, sb * b, sk * k), forces=list(sf * f), t_stop=10.0 * st)
            yield StressCase("e", f"{kind} scale", s, f"{kind} × {s:g}", build, _runs(p))


def _singular(quick: bool, p: Preset) -> Iterator[StressCase]:
    couplings = (1e-3, 0.0) if quick else (1e-3, 1e-6, 1e-9, 1e-13, 0.0, -1e-13, -1e-9, -1e-6, -1e-3)
    for c in couplings:
        def build(c=c):
            return node_system(JointSpace([[2.0, c], [c, 1.0]], np.diag([1.0, 0.5])), topology="parallel",
                               forces=[1.0, 0.5], t_stop=10.0)
        yield StressCase("f", "MP capacitance", c, f"m12 = {c:g}", build, _runs(p))
    for factor in (0.5, 2.0) if quick else (0.5, 0.99, 1.01, 2.0):
        c = factor * ZERO_TOL * math.sqrt(2.0 * 1.0)     # the floor: tol·√(row scales), to first order
        def build(c=c):
            return node_system(JointSpace([[2.0, c], [c, 1.0]], np.diag([1.0, 0.5])), topology="parallel",
                               forces=[1.0, 0.5], t_stop=10.0)
        yield StressCase("f", "m12 / zero tolerance", factor, f"m12 = {factor:g}·zero_tol", build, _runs(p))
    yield from _singular_pose(quick, p)


def singular_q1(q2: float = -1.7, q3: float = 0.35, low: float = 2.7, high: float = 2.9) -> float:
    """The 3-RRR's last assembling q1 before its singular pose, by bisection to rounding.

    Parameters
    ----------
    q2, q3 : float
        The other actuated angles [rad].
    low, high : float
        A q1 that assembles and one that does not [rad].
    """
    from ...scenes.builtin import scene
    base = scene("parallel3")

    def assembles(q1: float) -> bool:
        try:
            base.replace(q=(q1, q2, q3)).system()
            return True
        except InputError:
            return False
    if not assembles(low) or assembles(high):
        raise InputError(f"3-RRR: q1 = {low} must assemble and q1 = {high} must not")
    while high - low > 4 * np.spacing(high):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if assembles(mid) else (low, mid)
    return low


def _singular_pose(quick: bool, p: Preset) -> Iterator[StressCase]:
    """The 3-RRR approaching its singular pose: M' grows as 1/δ (cond 8 at δ = 1e-2, 8e4 at 1e-6)."""
    from ...scenes.builtin import scene
    q1 = singular_q1()
    for delta in (1e-1, 1e-4) if quick else (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
        def build(delta=delta):
            return scene("parallel3").replace(q=(q1 - delta, -1.7, 0.35)).system()
        yield StressCase("f", "distance to the singular pose", delta, f"3-RRR, q1* − {delta:g} rad", build,
                         _runs(p))


def _nonlinear(quick: bool, p: Preset) -> Iterator[StressCase]:
    from ...scenes.builtin import scene
    base = scene("default")
    for amp in (1.0, 10.0) if quick else (1.0, 10.0, 100.0):
        def build(amp=amp):
            return base.replace(dynamics="nonlinear", forces=(amp, 0.5 * amp), t_stop=5.0).system()
        yield StressCase("g", "force", amp, f"force × {amp:g}", build, _runs(p, ("spice", "ode")))
    def pendulum():
        return base.replace(dynamics="nonlinear", parameters={"g": 9.81, "b1": 0.0, "b2": 0.0}, forces=(0.0, 0.0),
                            q=(2.0, 1.5), t_stop=5.0 if quick else 20.0).system()
    yield StressCase("g", "chaotic pendulum", 0.0, "double pendulum, g = 9.81", pendulum,
                     _runs(p, ("spice", "ode")), horizon=True)


def _real_arm(quick: bool, p: Preset) -> Iterator[StressCase]:
    """The UR5's kinematic singularities: the Jacobian of its hand loses rank, its M(q) does not.

    Held at a pose by no torque, gravity would topple it, so g = 0; each joint is driven by a
    unit step. Without ``example-robot-data`` each case is a row saying how to get it.
    """
    for joint, name in ((3, "elbow"), (5, "wrist")):
        for delta in (1.0, 1e-3) if quick else (1.0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 0.0):
            def build(joint=joint, delta=delta):
                text, joints = urdf_robot("ur5")
                q = [0.0, -1.0, 1.0, 0.0, 1.0, 0.0]
                q[joint - 1] = delta
                return node_system(urdf_model(text, joints), q, parameters={"g": 0.0}, forces=[1.0] * 6,
                                   t_stop=2.0)
            yield StressCase("h", f"UR5 {name}: q{joint}", delta, f"UR5 {name}, q{joint} = {delta:g}", build,
                             _runs(p))


def _real_arm_defaults(quick: bool, p: Preset) -> Iterator[StressCase]:
    """Every named URDF robot's default experiment, linear (:func:`~analogy.scenes.builtin.scene`):
    fast decays beside slow ones (the xArm7's 68 µs), undamped arms hanging (the URs), arms at
    g = 0 whose only time scale is a damper's (the Panda's 890 s)."""
    from ...scenes.builtin import scene
    for k, name in enumerate(("panda", "z1") if quick else URDF_ROBOTS):
        def build(name=name):
            return scene(name).system()
        yield StressCase("i", "robot", float(k), f"{name} at its defaults", build, _runs(p))


FAMILIES = {"a": _conditioning, "b": _time_scales, "c": _long_runs, "d": _size, "e": _units,
            "f": _singular, "g": _nonlinear, "h": _real_arm, "i": _real_arm_defaults}


def cases(families: str = ALL_FAMILIES, quick: bool = False, timeout: float = 10.0) -> Iterator[StressCase]:
    """Every case of the chosen *families*, built lazily.

    Parameters
    ----------
    families : str
        Letters of :data:`FAMILY_TITLES`.
    quick : bool
        A subset: the ends of each sweep.
    timeout : float
        Wall-time limit of each ODE run [s].
    """
    p = _timed(PRESETS["accurate"], timeout)
    for letter in families:
        for case in FAMILIES[letter](quick, p):
            # quick: the 40-digit check on 4 points (its cost is mpmath's, not the solvers')
            yield replace(case, runs=tuple((label, _timed(pr, timeout)) for label, pr in case.runs),
                          reference_points=4 if quick else case.reference_points)
