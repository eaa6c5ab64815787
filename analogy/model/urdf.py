"""Robots from URDF files: the kinematic tree parsed by yourdfpy, its dynamics as a model of analogy."""

from __future__ import annotations

import hashlib
import io
from functools import lru_cache
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import InputError
from .joint import JointSpace, JointStack, configuration_stack
from .rigid_tree import RigidTree, plucker, spatial_inertia

__all__ = ["UrdfModel", "urdf_model", "read_urdf", "MAX_URDF_BYTES", "STANDARD_GRAVITY"]

#: A URDF larger than this is refused before it is parsed (the Panda's is 20 kB).
MAX_URDF_BYTES = 10_000_000
STANDARD_GRAVITY = 9.80665
_MOVING = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}


def read_urdf(path) -> str:
    """The text of the URDF file at *path*, or one sentence.

    Parameters
    ----------
    path : str or Path
        The file.
    """
    p = Path(path)
    try:
        if p.stat().st_size > MAX_URDF_BYTES:
            raise InputError(f"{p} is larger than {MAX_URDF_BYTES:,} bytes: not a URDF this reads", field="robot")
        return p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"no URDF file {p}", field="robot") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {p}: {getattr(exc, 'strerror', None) or exc}", field="robot") from None


def _parse(text: str):
    # no DTD: entities could expand without bound or read other files into the names
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise InputError("the URDF has a DTD (<!DOCTYPE or <!ENTITY>): URDF files need none", field="robot")
    from xml.etree import ElementTree
    try:
        ElementTree.fromstring(text.encode("utf-8"))        # well-formed, before a recovering parser
    except ElementTree.ParseError as exc:
        raise InputError(f"not a readable URDF (malformed XML: {exc})", field="robot") from None
    try:
        import yourdfpy
    except ImportError:
        raise InputError("URDF robots need yourdfpy: pip install yourdfpy", field="robot") from None
    import warnings
    import logging
    logging.getLogger("yourdfpy").setLevel(logging.CRITICAL)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return yourdfpy.URDF.load(io.BytesIO(text.encode("utf-8")), build_scene_graph=False, load_meshes=False,
                                      build_collision_scene_graph=False, load_collision_meshes=False).robot
    except Exception as exc:        # lxml's and yourdfpy's own errors: the file is not a URDF
        detail = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise InputError(f"not a readable URDF ({detail})", field="robot") from None


def _number(value, what: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not a number: {value!r}", field="robot") from None
    if not np.isfinite(x):
        raise InputError(f"{what} is not finite", field="robot")
    return x


def _inertia(link) -> np.ndarray:
    """The link's spatial inertia about its own frame (zero for a link without <inertial>)."""
    inertial = link.inertial
    if inertial is None:
        return np.zeros((6, 6))
    mass = _number(inertial.mass, f"link {link.name}: mass")
    frame = np.asarray(inertial.origin if inertial.origin is not None else np.eye(4), dtype=float)
    rot = np.asarray(inertial.inertia if inertial.inertia is not None else np.zeros((3, 3)), dtype=float)
    if mass < 0:
        raise InputError(f"link {link.name}: mass {mass:g} is negative", field="robot")
    if not (np.all(np.isfinite(frame)) and np.all(np.isfinite(rot))):
        raise InputError(f"link {link.name}: its inertial origin or inertia is not finite", field="robot")
    eig = np.linalg.eigvalsh(0.5 * (rot + rot.T))
    scale = max(abs(eig).max(initial=0.0), 1e-300)
    if eig.min(initial=0.0) < -1e-12 * scale:
        raise InputError(f"link {link.name}: its inertia is not positive semidefinite (eigenvalue "
                         f"{eig.min():.3g})", field="robot")
    # principal moments obey the triangle inequality, within rounding of the largest
    if mass > 0 and eig.size == 3 and eig[0] + eig[1] < eig[2] * (1 - 1e-9):
        raise InputError(f"link {link.name}: its principal moments {eig[0]:.3g}, {eig[1]:.3g}, {eig[2]:.3g} "
                         "break the triangle inequality (no body has them)", field="robot")
    r = frame[:3, :3]
    return spatial_inertia(mass, frame[:3, 3], r @ rot @ r.T)


def _tree(robot, gravity: float, joints: Sequence[str] | None = None, pose: Mapping[str, float] | None = None):
    """(RigidTree, joint names, kinds, damping per joint) of a parsed URDF."""
    links = {link.name: link for link in robot.links}
    by_child: dict = {}
    children: dict = {}
    for j in robot.joints:
        if j.type not in (*_MOVING, "fixed"):
            raise InputError(f"joint {j.name} is {j.type}: only revolute, continuous, prismatic and fixed "
                             "joints are modelled (a floating base can come later)", field="robot")
        if j.child in by_child:
            raise InputError(f"link {j.child} has two parent joints ({by_child[j.child].name}, {j.name}): "
                             "closed loops are not modelled", field="robot")
        if j.parent not in links or j.child not in links:
            raise InputError(f"joint {j.name} joins a link that is not defined", field="robot")
        by_child[j.child] = j
        children.setdefault(j.parent, []).append(j)
    roots = [name for name in links if name not in by_child]
    if len(roots) != 1:
        raise InputError(f"the URDF has {len(roots)} root links ({', '.join(roots[:4])}): a tree has one",
                         field="robot")
    movable = [j.name for j in robot.joints if j.type in _MOVING]
    kept = set(movable if joints is None else joints)
    if unknown := [name for name in kept if name not in movable]:
        raise InputError(f"no movable joint {unknown[0]!r} (the URDF's are {', '.join(movable)})", field="robot")
    for j in robot.joints:
        if j.mimic is not None and (j.name in kept or j.mimic.joint in kept):
            raise InputError(f"joint {j.name} mimics {j.mimic.joint}: mimic joints are not modelled; keep "
                             "both out of the joints selected (they are then frozen)", field="robot")
    pose = dict(pose or {})
    parents, kinds, axes, placements, inertias, names, damping = [], [], [], [], [], [], []

    def visit(link_name, body: int, frame: np.ndarray, seen: set):
        if link_name in seen:
            raise InputError(f"link {link_name} is reached twice: closed loops are not modelled", field="robot")
        seen.add(link_name)
        inertia = _inertia(links[link_name])
        x = plucker(frame[:3, :3], frame[:3, 3])           # the link's frame from its body's
        if body >= 0:
            inertias[body] = inertias[body] + x.T @ inertia @ x
        for j in children.get(link_name, []):
            origin = frame @ np.asarray(j.origin if j.origin is not None else np.eye(4), dtype=float)
            if j.type == "fixed" or j.name not in kept:
                if j.type != "fixed":       # frozen at its pose: a fixed joint there
                    origin = origin @ _joint_motion(j, _number(pose.get(j.name, 0.0), f"joint {j.name}: pose"))
                visit(j.child, body, origin, seen)
                continue
            axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
            norm = np.linalg.norm(axis)
            if not np.isfinite(norm) or norm < 1e-12:
                raise InputError(f"joint {j.name} has no axis (its axis is zero)", field="robot")
            parents.append(body)
            kinds.append(_MOVING[j.type])
            axes.append(axis / norm)
            placements.append(plucker(origin[:3, :3], origin[:3, 3]))
            inertias.append(np.zeros((6, 6)))
            names.append(j.name)
            d = getattr(j.dynamics, "damping", None) if j.dynamics is not None else None
            d = 0.0 if d is None else _number(d, f"joint {j.name}: damping")
            if d < 0:
                raise InputError(f"joint {j.name}: damping {d:g} is negative", field="robot")
            damping.append(d)
            visit(j.child, len(names) - 1, np.eye(4), seen)

    visit(roots[0], -1, np.eye(4), set())
    if not names:
        raise InputError("the URDF has no movable joint", field="robot")
    tree = RigidTree(tuple(parents), tuple(kinds), np.array(axes), np.array(placements), np.array(inertias),
                     np.array([0.0, 0.0, -gravity]))
    return tree, tuple(names), tuple(kinds), np.array(damping)


def _joint_motion(joint, value: float) -> np.ndarray:
    """The 4×4 motion of a joint held at *value*."""
    axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float)
    axis = axis / np.linalg.norm(axis)
    t = np.eye(4)
    if _MOVING[joint.type] == "revolute":
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        t[:3, :3] = np.eye(3) + np.sin(value) * k + (1 - np.cos(value)) * k @ k
    else:
        t[:3, 3] = axis * value
    return t


class UrdfModel:
    """A URDF robot: M(q) and G(q) from its tree, numeric at every pose (no sympy).

    Joint damping from ``<dynamics damping>`` is a resistor per joint; ``friction``
    (Coulomb, not linear in the rate) is left out. Gravity acts along the base frame's −z
    (URDF's convention) with magnitude parameter ``g``.

    Parameters
    ----------
    text : str
        The URDF file's text.
    joints : sequence of str, optional
        The movable joints kept; the others are frozen at *pose*.
    pose : mapping of str to float, optional
        The frozen joints' values.
    g : float
        Gravity's magnitude [m/s²].
    """

    topology = "parallel"
    description = ""

    def __init__(self, text: str, joints: Sequence[str] | None = None, pose: Mapping[str, float] | None = None,
                 g: float = STANDARD_GRAVITY):
        self.text = text
        robot = _parse(text)
        self.name = str(robot.name or "urdf")
        self._robot, self._selection, self._pose = robot, joints, pose
        self.tree, self.joint_names, kinds, self.joint_damping = _tree(robot, g, joints, pose)
        self.joints = kinds
        self.parameters = {"g": float(g)}
        self.coordinates = tuple(f"q{i + 1}" for i in range(len(kinds)))
        self.description = f"URDF {self.name}: {len(kinds)} joints ({', '.join(self.joint_names)})"
        self.key = hashlib.sha256(text.encode()).hexdigest()[:16]

    def __repr__(self) -> str:
        return f"UrdfModel({self.name!r}, {self.dof} joints)"

    @property
    def dof(self) -> int:
        return self.tree.dof

    @property
    def units(self) -> tuple[str, ...]:
        return tuple("rad" if k == "revolute" else "m" for k in self.joints)

    def _at(self, parameters: Mapping[str, float] | None) -> "UrdfModel":
        if not parameters:
            return self
        if unknown := [k for k in parameters if k != "g"]:
            raise InputError(f"URDF robot {self.name} has no parameter {unknown[0]!r} (it has: g)",
                             field="parameters")
        g = float(parameters["g"])
        if not np.isfinite(g):
            raise InputError("g must be finite", field="parameters")
        if g == self.parameters["g"]:
            return self
        return urdf_model(self.text, None if self._selection is None else tuple(self._selection),
                          None if not self._pose else tuple(sorted(self._pose.items())), g)

    def joint_space(self, q: Sequence[float] | None = None,
                    parameters: Mapping[str, float] | None = None) -> JointSpace:
        """M(q), the joint dampers, gravity's stiffness ∂G/∂q and the load G(q), at *q*.

        Parameters
        ----------
        q : sequence of float
            Joint coordinates [rad, m].
        parameters : mapping, optional
            ``g``.
        """
        model = self._at(parameters)
        q = configuration_stack(self.name, self.coordinates, [list(q or [])])[0]
        tree = model.tree
        k = tree.gravity_stiffness(q) if np.any(tree.gravity) else None
        return JointSpace(tree.mass_matrix(q), np.diag(self.joint_damping), k, tree.gravity_load(q))

    def joint_stack(self, qs, parameters: Mapping[str, float] | None = None) -> JointStack:
        """:meth:`joint_space` at every row of *qs*.

        Parameters
        ----------
        qs : array_like, shape (count, n)
            Configurations.
        parameters : mapping, optional
            ``g`` (one value for the stack).
        """
        if parameters and any(np.ndim(v) for v in parameters.values()):
            raise InputError(f"URDF robot {self.name}'s g cannot vary along a stack", field="parameters")
        q = configuration_stack(self.name, self.coordinates, qs)
        return JointStack.of([self.joint_space(row, parameters) for row in q])


@lru_cache(maxsize=16)
def urdf_model(text: str, joints: tuple | None = None, pose: tuple | None = None,
               g: float = STANDARD_GRAVITY) -> UrdfModel:
    """The :class:`UrdfModel` of a URDF's text, parsed once per process.

    Parameters
    ----------
    text : str
        The URDF.
    joints : tuple of str, optional
        Movable joints kept (the rest frozen).
    pose : tuple of (str, float) pairs, optional
        The frozen joints' values.
    g : float
        Gravity's magnitude.
    """
    return UrdfModel(text, joints, dict(pose) if pose is not None else None, g)
