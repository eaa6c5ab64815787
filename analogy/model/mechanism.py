"""Mechanism: where a robot's links are at each configuration, as polylines in its plane or in space, for drawings."""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np

from ..errors import InputError
from .beams import beam_modes
from .conventions import link_modes_for
from .catalog import family_builder, robot_family

__all__ = ["Outline", "planar_chain_outline", "five_bar_outline", "flexible_arm_outline",
           "flexible_parallel_outline", "hopper_outline", "tree_outline", "mechanism_outline"]

#: Links at each of F configurations: a list of link polylines per frame, each (k, 2) in metres
#: (a planar robot) or (k, 3) (a URDF's tree, in its base frame).
Outline = list[list[np.ndarray]]

#: Points drawn along a flexible link: enough for its fourth mode's three nodes to show.
_BEAM_POINTS = 41


def _cumulative_chain(angles: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Joint and tip points (F, n + 1, 2) of a planar chain from its relative joint angles (F, n)."""
    absolute = np.cumsum(angles, axis=1)
    steps = lengths * np.stack([np.cos(absolute), np.sin(absolute)], axis=-1).transpose(2, 0, 1)
    points = np.cumsum(steps.transpose(1, 2, 0), axis=1)
    return np.concatenate([np.zeros((len(angles), 1, 2)), points], axis=1)


def planar_chain_outline(q: np.ndarray, parameters: Mapping[str, float]) -> Outline:
    """The planar serial arm: q_k is link k's angle from link k − 1, l_k its length.

    Parameters
    ----------
    q : ndarray, shape (F, n)
        Joint angles [rad], one row per frame.
    parameters : mapping
        l1 … ln [m].
    """
    q = np.atleast_2d(q)
    lengths = np.array([parameters[f"l{k + 1}"] for k in range(q.shape[1])])
    points = _cumulative_chain(q, lengths)
    return [[frame] for frame in points]


def five_bar_outline(q: np.ndarray, parameters: Mapping[str, float]) -> Outline:
    """The five-bar: base joints at (∓d/2, 0), proximal links at absolute angles q1, q2, distal ones
    meeting at P to the left of E1→E2 (the model's elbows-out assembly mode).

    Parameters
    ----------
    q : ndarray, shape (F, 2)
        Proximal link angles [rad].
    parameters : mapping
        d, la, lb [m].
    """
    q = np.atleast_2d(q)
    d, la, lb = (parameters[k] for k in ("d", "la", "lb"))
    bases = np.array([[-d / 2, 0.0], [d / 2, 0.0]])
    frames = []
    for q1, q2 in q:
        e1 = bases[0] + la * np.array([np.cos(q1), np.sin(q1)])
        e2 = bases[1] + la * np.array([np.cos(q2), np.sin(q2)])
        chord = e2 - e1
        half = np.linalg.norm(chord) / 2
        rise = np.sqrt(max(lb ** 2 - half ** 2, 0.0))       # 0 where the loop cannot close: drawn flat
        normal = np.array([-chord[1], chord[0]]) / (2 * half)
        p = (e1 + e2) / 2 + rise * normal
        frames.append([np.array([bases[0], e1, p, e2, bases[1]]), bases.copy()])
    return frames


def flexible_arm_outline(q: np.ndarray, parameters: Mapping[str, float], *, links: int = 2,
                         link_modes: str | None = None, joint_frame: str | None = None,
                         geometric_stiffness: bool | None = None, exaggeration: float = 1.0) -> Outline:
    """The flexible arm bent by its modes: link i's point at x is r_i(x) = o_i + R(α_i)·(x, Σ_k φ_ik(x)·δ_ik).

    α_i is θ_i plus link i − 1's direction: its undeformed axis's (the axis frame, the
    paper's kinematics) or its deformed tip's (the tip frame); o_i is link i − 1's deformed
    tip.

    Parameters
    ----------
    q : ndarray, shape (F, dof)
        θ_1 … θ_links, then every link's modal coordinates δ_ik, one row per frame.
    parameters : mapping
        l_i, rhoA_i, EI_i, modes_i and the tip loads (see ``FLEXIBLE_DEFAULTS``).
    links : int
        Number of links.
    link_modes : {"clamped-free", "clamped-mass"}, optional
        The model's mode shapes (None: the joint frame's).
    joint_frame : {"axis", "tip"}, optional
        Where each joint is measured from (None: the axis).
    geometric_stiffness : bool, optional
        Not drawn; taken so that a scene's conventions pass as they are.
    exaggeration : float
        Deflections are drawn this many times their size.
    """
    q = np.atleast_2d(q)
    tips = [(parameters.get("mh2", 0.0), parameters.get("Jh2", 0.0)), (parameters["mp"], parameters["Jp"])] \
        if links == 2 else [(parameters["mp"], parameters["Jp"])]
    at, shapes = links, []
    for i in range(links):
        count, length = int(parameters[f"modes{i + 1}"]), parameters[f"l{i + 1}"]
        x = np.linspace(0.0, length, _BEAM_POINTS)
        if count:
            load = tips[i] if link_modes_for(joint_frame, link_modes) == "clamped-mass" else (0.0, 0.0)
            modes = beam_modes(count, length, parameters[f"rhoA{i + 1}"], parameters[f"EI{i + 1}"], *load)
            slope = modes.shape([length], 1)[0] if joint_frame == "tip" else np.zeros(count)
            shapes.append((x, modes.shape(x), slice(at, at + count), slope))
        else:
            shapes.append((x, np.zeros((x.size, 0)), slice(at, at), np.zeros(0)))
        at += count
    frames = []
    for row in q:
        origin, alpha, frame = np.zeros(2), 0.0, []
        for i, (x, phi, cols, slope) in enumerate(shapes):
            alpha += row[i]
            u = exaggeration * phi @ row[cols]
            c, s = np.cos(alpha), np.sin(alpha)
            points = origin + np.stack([c * x - s * u, s * x + c * u], axis=1)
            frame.append(points)
            origin = points[-1]
            alpha += exaggeration * slope @ row[cols]       # the tip frame: the next joint turns with the tip
        frames.append(frame)
    return frames


def flexible_parallel_outline(q: np.ndarray, parameters: Mapping[str, float], *, link_modes: str | None = None,
                              exaggeration: float = 1.0, **conventions) -> Outline:
    """The parallel-link flexible arm: its two flexible links bent by their modes, the crank AD,
    the bracket BC behind the elbow and the closing link DC.

    The forearm is drawn along θ3 from link AB's deformed tip, the loop's solution to first
    order in the deflections (see :mod:`analogy.model.flexible_parallel`).

    Parameters
    ----------
    q : ndarray, shape (F, dof)
        θ1, θ3, then each link's modal coordinates, one row per frame.
    parameters : mapping
        flexpar's parameters (``FLEXPAR_DEFAULTS``).
    link_modes : {"clamped-free", "clamped-mass"}, optional
        The model's mode shapes.
    exaggeration : float
        Deflections are drawn this many times their size.
    **conventions
        The other conventions of a scene, not drawn.
    """
    q = np.atleast_2d(q)
    serial = q.copy()
    serial[:, 1] = q[:, 1] - q[:, 0]
    arms = flexible_arm_outline(serial, {**parameters, "Jh2": 0.0}, links=2, link_modes=link_modes,
                                exaggeration=exaggeration)
    lc = parameters["lc"]
    frames = []
    for row, (lower, upper) in zip(q, arms):
        back = -lc * np.array([np.cos(row[1]), np.sin(row[1])])
        elbow = lower[-1]
        frames.append([lower, upper, np.array([np.zeros(2), back, elbow + back, elbow])])
    return frames


def tree_outline(tree, q: np.ndarray) -> tuple[Outline, np.ndarray]:
    """A rigid tree drawn from its joint frames: per frame one polyline from the base's origin through
    each joint's origin to each leaf body's centre of mass; and each joint's axis, shape (F, n, 2, 3),
    a segment through its origin a twentieth of the reach long.

    Parameters
    ----------
    tree : RigidTree
        The robot's kinematic tree (:attr:`analogy.model.urdf.UrdfModel.tree`).
    q : ndarray, shape (F, n)
        Joint coordinates, one row per frame.
    """
    origin, axis, centre = tree.joint_frames(np.atleast_2d(np.asarray(q, dtype=float)))
    parents = list(tree.parents)
    leaves = [i for i in range(len(parents)) if i not in parents]
    chains = []
    for leaf in leaves:
        chain, j = [], leaf
        while j >= 0:
            chain.append(j)
            j = parents[j]
        chains.append(chain[::-1])
    base = np.zeros((len(origin), 1, 3))
    lines = [np.concatenate([base, origin[:, chain], centre[:, chain[-1:]]], axis=1) for chain in chains]
    reach = max(float(np.max(np.linalg.norm(line - line[:, :1], axis=2))) for line in lines) or 1.0
    half = 0.05 * reach * axis
    axes = np.stack([origin - half, origin + half], axis=2)
    return [[line[k] for line in lines] for k in range(len(origin))], axes


def hopper_outline(q: np.ndarray, parameters: Mapping[str, float]) -> Outline:
    """The hopper in its vertical plane: the ground line, the leg from the body at height q1 to the foot
    q2 below it, and the body (last, so that its trail shows the bounces).

    Parameters
    ----------
    q : ndarray, shape (F, 2)
        Body height and the foot's height relative to it [m], one row per frame.
    parameters : mapping
        l0 [m], which sets the drawing's width.
    """
    q = np.atleast_2d(q)
    half = 0.4 * parameters["l0"]
    ground = np.array([[-half, 0.0], [half, 0.0]])
    return [[ground, np.array([[0.0, z], [0.0, z + d]]), np.array([[0.0, z]])] for z, d in q]


def mechanism_outline(robot: str, q: np.ndarray, parameters: Mapping[str, float],
                      **options) -> Outline | None:
    """The outline of built-in robot *robot* at each row of *q*, or None where it has no drawing.

    Parameters
    ----------
    robot : str
        A built-in robot's name.
    q : ndarray, shape (F, n)
        Joint coordinates, one row per frame.
    parameters : mapping
        The model's parameter values.
    **options
        A flexible arm's conventions (``link_modes``, ``joint_frame``) and ``exaggeration``
        (ignored for rigid robots).
    """
    try:
        family, _ = robot_family(robot)
    except InputError:                  # a URDF robot, or a model given by its matrices
        return None
    if family.outline is None:
        return None
    outline: Callable = family_builder(family.outline)
    # only a flexible arm's drawing has options: its mode shapes and how much its bending is enlarged
    options = ({**options, "links": family.args[0]} if family.args else options) if family.flexible else {}
    return outline(np.atleast_2d(np.asarray(q, dtype=float)), parameters, **options)
