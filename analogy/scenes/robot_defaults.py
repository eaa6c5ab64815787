"""A URDF robot's default experiment: a stable pose, forces sized to the robot, a horizon from its modes."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from ..model.urdf import FREE_FLYER, UrdfModel
from ..results.modes import system_poles
from .scene import Scene

__all__ = ["RobotDefaults", "robot_defaults", "robot_scene", "base_note", "unstable_note", "hanging_pose", "growth_rate", "MOTION", "HORIZON_RANGE"]

#: How far a default step moves a joint alone over the horizon: small, so that the nonlinear
#: motion stays near the pose the linear circuit is taken at [rad for revolute joints, m for prismatic].
MOTION = {"revolute": 0.1, "prismatic": 0.01}
#: The horizon is three times the slowest time scale of the modes, kept within this range [s].
HORIZON_RANGE = (0.5, 10.0)
#: The horizon when no mode has a time scale (no springs, no dampers): free masses under steps [s].
FREE_HORIZON = 2.0
#: The horizon of a free robot standing on its contacts: it lands and settles [s].
STANDING_HORIZON = 0.5


@dataclass(frozen=True)
class RobotDefaults:
    """What a URDF robot is simulated with when the user gives nothing else.

    Attributes
    ----------
    q : tuple of float
        The pose, in the model's joint order.
    g : float
        Gravity's magnitude [m/s²] (0 where no hanging pose lies within the joint limits).
    forces : tuple of str
        One step per joint, ``step(F)``.
    t_stop : float
        The horizon [s].
    note : str
        One line saying how each was chosen.
    """

    q: tuple
    g: float
    forces: tuple
    t_stop: float
    note: str


def _wrapped(q: np.ndarray, model: UrdfModel) -> np.ndarray:
    """Each revolute angle turned by whole turns into its range where one fits, nearest its middle."""
    lo, hi = model.limits.lower, model.limits.upper
    mid = model.limits.middle()
    out = q.copy()
    for k, kind in enumerate(model.joints):
        if kind != "revolute" or not (np.isfinite(lo[k]) and np.isfinite(hi[k])):
            out[k] = math.remainder(q[k], 2 * math.pi) if kind == "revolute" else q[k]
            continue
        turns = np.arange(-3, 4)
        tries = q[k] + 2 * math.pi * turns
        inside = tries[(tries >= lo[k]) & (tries <= hi[k])]
        if inside.size:
            out[k] = inside[np.argmin(np.abs(inside - mid[k]))]
    return out


def hanging_pose(model: UrdfModel) -> np.ndarray | None:
    """The pose of least potential energy reached from the middle of the joint ranges, or None.

    None when it lies outside the joint limits (the arm would hang through them), when a
    prismatic joint slides without bound, or when the minimum is not reached. Joints whose
    axis gravity does not load (a vertical axis) stay at their middle.

    Parameters
    ----------
    model : UrdfModel
        The robot, with gravity on.
    """
    tree = model.tree
    scale = model.gravity_scale
    if not scale > 0:
        return None
    start = model.limits.middle()
    # G = ∂U/∂q and ∂G/∂q = U's Hessian are exact, so a trust region with that Hessian leaves a
    # saddle (q = 0 upright is one) along its negative curvature
    res = minimize(tree.potential_energy, start, jac=tree.gravity_load, hess=tree.gravity_stiffness,
                   method="trust-exact", options={"gtol": 1e-12 * scale, "maxiter": 500})
    # U's own rounding (ε·scale) stops the trust region while G is still ~1e-11 of scale:
    # Newton on G = 0 with K, in the loaded directions only, takes G down to its rounding
    q = np.asarray(res.x, dtype=float)
    for _ in range(3):
        q = q - np.linalg.lstsq(tree.gravity_stiffness(q), tree.gravity_load(q), rcond=1e-10)[0]
    # a joint gravity does not load (a vertical axis) may have drifted: back to its middle
    for k in range(tree.dof):
        moved = q.copy()
        moved[k] = start[k]
        if np.abs(tree.gravity_load(moved)).max() <= np.abs(tree.gravity_load(q)).max() + _rounding(tree, scale):
            q = moved
    q = _wrapped(q, model)
    # rounding of G is n·ε·scale; a minimum has G at that level and K positive semidefinite
    tol = _rounding(tree, scale)
    stiffness = tree.gravity_stiffness(q)
    if not (np.abs(tree.gravity_load(q)).max() <= tol and np.linalg.eigvalsh(stiffness)[0] >= -tol):
        return None
    return q if model.limits.contain(q) else None


def _rounding(tree, scale: float) -> float:
    """How large rounding leaves G or K at a pose: 100·n·ε of g·Σm·reach."""
    return 100 * tree.dof * np.finfo(float).eps * scale


def growth_rate(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray | None) -> float:
    """The fastest growth rate max Re(s) of det(M·s² + B·s + K) = 0 [1/s]: positive at an unstable pose.

    Parameters
    ----------
    mass, damping : ndarray
        M and B.
    stiffness : ndarray or None
        K (None: no springs).
    """
    k = np.zeros_like(mass) if stiffness is None else stiffness
    return float(np.max(system_poles(mass, damping, k).real))


def unstable_note(system, scene: Scene) -> str | None:
    """The sentence said before a linear run at an unstable pose: the pose, the fastest growth and
    the ways out; None at a stable one (or for a nonlinear system).

    Parameters
    ----------
    system : NodeSystem
        The linear circuit's system.
    scene : Scene
        The scene it was built from (its pose and robot).
    """
    joint = getattr(system, "joint", None)
    if joint is None or not joint.unstable:
        return None
    rate = growth_rate(joint.mass_matrix, joint.damping, joint.stiffness)
    pose = ", ".join(f"{x:.4g}" for x in scene.q)
    urdf = scene.model.from_urdf
    way = "leave out --q for the hanging pose, or --param g=0" if urdf else \
        "--param g=0 turns gravity off; --equilibrium settles a flexible arm's elastic coordinates"
    return (f"q = ({pose}) is an unstable equilibrium: the fastest mode grows as e^({rate:.4g}·t), "
            f"{math.exp(min(rate * system.t_stop, 700)):.3g} times over t_stop = {system.t_stop:g} s; the linear "
            f"circuit is exact but leaves the pose at once ({way})")


def _time_scales(poles: np.ndarray) -> np.ndarray:
    """Per pole, its period 2π/|ω| (oscillating) or time constant 1/|σ| (real); rigid-body poles left out."""
    s = poles[np.abs(poles) > 0]
    return np.array([2 * math.pi / abs(x.imag) if x.imag != 0 else 1 / abs(x.real) for x in s])


def _rounded(x: float, digits: int = 2) -> float:
    return float(f"{x:.{digits}g}")


def robot_defaults(model: UrdfModel, g: float | None = None, q=None, label: str | None = None) -> RobotDefaults:
    """The default experiment of *model*: pose, gravity, forces and horizon, with a note on each.

    The pose hangs (the least potential energy within the joint limits); where no hanging
    pose lies within them, gravity is turned off and the joints sit at the middle of their
    ranges. Each joint gets a step sized to move it alone by :data:`MOTION` over the horizon
    against its own impedance K_kk + B_kk/T + 2·M_kk/T² (capped at its effort limit), and the
    horizon is three times the slowest period or time constant of the modes at the pose.

    Parameters
    ----------
    model : UrdfModel
        The robot.
    g : float, optional
        Gravity's magnitude, when the user chose it (0 turns it off; None: the model's, kept
        only where the robot can hang).
    q : sequence of float, optional
        The pose, when the user chose it.
    label : str, optional
        The robot's name in the note (default: the URDF's).
    """
    names = model.joint_names
    chosen_g = g is not None
    g = model.parameters["g"] if g is None else float(g)
    limits = model.limits
    free = getattr(model, "base", "fixed") == "floating"
    contacts = getattr(model, "contacts", ())
    if free and contacts:
        return _standing(model, g, q, label)
    if free and not chosen_g:       # nothing to stand on: it would fall for ever
        g = 0.0
    if q is not None:
        pose, why = np.asarray(q, dtype=float), "the pose given"
    elif free:
        pose, why = limits.middle(), (f"a free-flying base at the origin, g = {g:g}" + (" (nothing holds it up)"
                                      if not chosen_g else "") + ", the joints at the middle of their ranges")
    elif g == 0.0:
        pose, why = limits.middle(), "g = 0, the joints at the middle of their ranges"
    else:
        hanging = hanging_pose(model.with_parameters({"g": g}))
        if hanging is not None:
            pose, why = hanging, "hanging, the least potential energy within the joint limits"
        elif chosen_g:
            pose, why = limits.middle(), (f"g = {g:g} as asked, the joints at the middle of their ranges "
                                          "(no hanging pose within the joint limits)")
        else:
            g = 0.0
            pose, why = limits.middle(), ("g = 0 (no hanging pose lies within the joint limits), the joints at "
                                          "the middle of their ranges")
    joint = model.with_parameters({"g": g}).joint_space(pose)
    m, b, k = joint.mass_matrix, joint.damping, joint.stiffness
    scales = _time_scales(system_poles(m, b, np.zeros_like(m) if k is None else k))
    slowest = float(scales.max()) if scales.size else None
    t_stop = FREE_HORIZON if slowest is None else min(max(_rounded(3 * slowest, 1), HORIZON_RANGE[0]),
                                                          HORIZON_RANGE[1])
    stiff = np.zeros(model.dof) if k is None else np.clip(np.diag(k), 0.0, None)
    inertia = np.diag(m).copy()
    if free:            # a joint of a free robot moves the base too: the inertia it meets is M's Schur complement
        base = len(FREE_FLYER)
        inertia[base:] = np.diag(m[base:, base:] - m[base:, :base] @ np.linalg.solve(m[:base, :base], m[:base, base:]))
    impedance = stiff + np.diag(b) / t_stop + 2 * inertia / t_stop ** 2
    motion = np.array([MOTION[kind] for kind in model.joints])
    force = motion * impedance
    force = np.where(np.isfinite(limits.effort), np.minimum(force, limits.effort), force)
    if free:
        force[:len(FREE_FLYER)] = 0.0       # nothing drives a free base: the joints move it by reaction
    forces = tuple(f"step({_rounded(f)!r})" if f else "0" for f in force)
    if slowest is None:
        horizon = "no mode has a time scale"
    else:
        capped = "" if HORIZON_RANGE[0] < 3 * slowest < HORIZON_RANGE[1] else \
            f", within {HORIZON_RANGE[0]:g} to {HORIZON_RANGE[1]:g} s"
        horizon = f"three times the slowest mode's {slowest:.3g} s{capped}"
    unit = "rad" if all(kind == "revolute" for kind in model.joints) else "rad or 10 mm"
    moved = [f"{n}={x:.4g}" for n, x in zip(names, pose) if abs(x) > 5e-13]
    shown = (", ".join(moved) + (", the others 0" if len(moved) < len(names) else "")) if moved else "every joint 0"
    driven = "each joint but the free base's" if free else "each joint"
    note = (f"{label or model.name}: {why}: {shown}; steps moving {driven} alone about 0.1 {unit} over "
            f"t_stop = {t_stop:g} s ({horizon})")
    return RobotDefaults(tuple(float(x) for x in pose), g, forces, float(t_stop), note)


def _standing(model: UrdfModel, g: float, q, label: str | None) -> RobotDefaults:
    """A free robot on its contacts: the joints at the middle of their ranges, the base lowered until the
    lowest contact just touches the ground, no force, and STANDING_HORIZON to settle under gravity."""
    if q is not None:
        pose, why = np.asarray(q, dtype=float), "the pose given"
    else:
        pose = model.limits.middle()
        bodies = [c.body for c in model.contacts]
        heights = model.tree.points(pose[None], bodies, [c.offset for c in model.contacts])[0][0, :, 2]
        pose[2] = -float(np.min(heights))
        why = (f"standing: the base at {pose[2]:.4g} m, so that its lowest contact just touches the ground, "
               f"g = {g:g}, the joints at the middle of their ranges held by their servos")
    names = ", ".join(c.name for c in model.contacts)
    note = (f"{label or model.name}: {why}; no force: it settles on {names} over t_stop = {STANDING_HORIZON:g} s")
    return RobotDefaults(tuple(float(x) for x in pose), g, ("0",) * model.dof, STANDING_HORIZON, note)


def base_note(model: UrdfModel) -> str | None:
    """The sentence that says a URDF's root link is held to the world, or None when it is the world.

    Parameters
    ----------
    model : UrdfModel
        The robot.
    """
    if model.root_link == "world":
        return None
    if getattr(model, "base", "fixed") == "floating":
        return (f"{model.name}'s root link {model.root_link} flies free (--base floating): six more coordinates "
                "first, its origin's x, y, z and its Z-Y-X angles (singular at pitch ±π/2)")
    return (f"{model.name}'s root link {model.root_link} is held fixed to the world (--base fixed, the default; "
            "--base floating frees it)")


def robot_scene(name: str) -> Scene:
    """The default scene of a named URDF robot (:data:`~analogy.model.catalog.URDF_NAMES`).

    Parameters
    ----------
    name : str
        The robot, e.g. ``"ur5"``.
    """
    probe = Scene.of(name, name)
    model = probe.numeric_model()
    d = robot_defaults(model, label=name)
    return probe.replace(q=d.q, parameters={"g": d.g}, forces=d.forces, t_stop=d.t_stop,
                         description=d.note.partition(": ")[2])
