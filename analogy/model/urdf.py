"""Robots from URDF files: the kinematic tree parsed by yourdfpy, its dynamics as a model of analogy."""

from __future__ import annotations

import copy
import hashlib
import os
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import InputError
from . import joint_limits as joint_limits_module
from . import rigid_tree as rigid_tree_module
from . import urdf_file as urdf_file_module
from .articulated_body import pinocchio_functions, pinocchio_places
from .contact import Contact, check_contact_values
from .compiled import cache_dir
from .dynamics import MechanicalFunctions
from .base import RobotModel
from .catalog import BASES
from .joint import JointStack, configuration_stack
from .joint_limits import JointLimits, joint_limits
from .urdf_file import MOVING_JOINTS, parse_urdf, urdf_number
from .rigid_tree import RigidTree, axis_rotation, body_inertia, placement_frame, plucker, spatial_inertia
from .tree_contact import TreeContact, tree_contact_functions

__all__ = ["UrdfModel", "urdf_model", "STANDARD_GRAVITY", "FREE_FLYER", "GROUND_SINK", "ground_defaults"]

STANDARD_GRAVITY = 9.80665
#: How far the robot's whole weight sinks one contact into the ground by default [m].
GROUND_SINK = 1e-3
#: The ground's friction coefficient by default (rubber on a floor).
GROUND_FRICTION = 0.8
#: How far the robot's whole weight at its contacts' reach bends a servo-held joint by default [rad].
SERVO_SAG = 0.05
#: A free-flying base as six joints before the root link: its origin's slides along the world's x, y,
#: z, then Z-Y-X Euler angles (yaw, pitch, roll), each turning about the frame the last one left.
#: The circuit's node velocities must integrate to coordinates (x = ∫v); a body's twist does not,
#: so the nodes are these six rates, and the twist is their linear map. The angles are singular
#: at pitch ±π/2 (gimbal lock), a quarter turn from the URDF's own upright pose.
FREE_FLYER = (("base_x", "prismatic", (1.0, 0.0, 0.0)), ("base_y", "prismatic", (0.0, 1.0, 0.0)),
              ("base_z", "prismatic", (0.0, 0.0, 1.0)), ("base_yaw", "revolute", (0.0, 0.0, 1.0)),
              ("base_pitch", "revolute", (0.0, 1.0, 0.0)), ("base_roll", "revolute", (1.0, 0.0, 0.0)))
FREE_NAMES = tuple(name for name, _, _ in FREE_FLYER)


def _inertia(link, scale: float) -> np.ndarray:
    """The link's spatial inertia about its own frame (zero for a link without <inertial>).

    *scale* is the largest principal moment of any link: a moment that misses positivity
    by less than 1e-12 of it is rounding in the file.
    """
    inertial = link.inertial
    if inertial is None:
        return np.zeros((6, 6))
    mass = urdf_number(inertial.mass, f"link {link.name}: mass")
    frame = np.asarray(inertial.origin if inertial.origin is not None else np.eye(4), dtype=float)
    rot = np.asarray(inertial.inertia if inertial.inertia is not None else np.zeros((3, 3)), dtype=float)
    if mass < 0:
        raise InputError(f"link {link.name}: mass {mass:g} is negative", field="robot")
    eig = np.linalg.eigvalsh(0.5 * (rot + rot.T))
    floor = 1e-12 * scale
    if eig[0] < -floor:
        raise InputError(f"link {link.name}: its inertia is not positive semidefinite (principal moment "
                         f"{eig[0]:.3g})", field="robot")
    # moments that break the triangle inequality (no body has them, but real files carry such
    # placeholders, as Pinocchio accepts them) are kept: M(q) is checked positive definite
    r = frame[:3, :3]
    return spatial_inertia(mass, frame[:3, 3], r @ rot @ r.T)


def _largest_moment(robot) -> float:
    moments = [np.abs(np.linalg.eigvalsh(0.5 * (i + i.T))).max() for link in robot.links
               if link.inertial is not None and (i := np.asarray(link.inertial.inertia, dtype=float)).shape == (3, 3)]
    return max(moments, default=0.0)


def _check_moving(tree: RigidTree, names: list, free_root: str | None) -> None:
    """Refuse a joint that moves no mass (M singular), naming it; and, for a free base at *free_root*, a joint
    that moves what the base moves."""
    mass = tree.mass_matrix(np.zeros(tree.dof))
    resisted = np.diag(mass)
    if still := [names[k] for k in range(tree.dof) if not resisted[k] > 1e-12 * resisted.max(initial=0.0)]:
        raise InputError(f"joint {still[0]} moves no mass or inertia along its motion (every link it carries "
                         "is massless there)", field="robot")
    eig = np.linalg.eigvalsh(mass) if free_root is not None else None
    if eig is not None and not eig[0] > 1e-12 * eig[-1]:
        raise InputError(f"with its root link {free_root} free, the robot's mass matrix is singular: a joint "
                         "moves the same bodies as the free base does (a massless root link, or a slide or "
                         "turn of the whole robot); free a robot whose root link carries its body, or keep "
                         "--base fixed", field="robot")


def _check_mimics(robot, movable: list, kept: set) -> None:
    """Refuse a mimic joint that mimics no movable joint, or one kept (mimics are frozen, not modelled)."""
    for j in robot.joints:
        if j.mimic is not None and j.mimic.joint not in movable:
            raise InputError(f"joint {j.name} mimics {j.mimic.joint!r}, which is not a movable joint",
                             field="robot")
        if j.mimic is not None and (j.name in kept or j.mimic.joint in kept):
            raise InputError(f"joint {j.name} mimics {j.mimic.joint}: mimic joints are not modelled; keep "
                             "both out of the joints selected (they are then frozen)", field="robot")


def _tree(robot, gravity: float, joints: Sequence[str] | None = None, pose: Mapping[str, float] | None = None,
          base: str = "fixed"):
    """(RigidTree, joint names, kinds, damping per joint, JointLimits, root link, link frames) of a parsed URDF;
    a *base* ``"floating"`` puts the :data:`FREE_FLYER` joints between the world and the root link. The link
    frames map each link to its body (−1: welded to the world) and its frame in that body's (4×4)."""
    links = {link.name: link for link in robot.links}
    by_child: dict = {}
    children: dict = {}
    for j in robot.joints:
        if j.type not in (*MOVING_JOINTS, "fixed"):
            raise InputError(f"joint {j.name} is {j.type}: only revolute, continuous, prismatic and fixed "
                             "joints are modelled (a free root link is --base floating)", field="robot")
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
    movable = [j.name for j in robot.joints if j.type in MOVING_JOINTS]
    kept = set(movable if joints is None else joints)
    if unknown := [name for name in kept if name not in movable]:
        raise InputError(f"no movable joint {unknown[0]!r} (the URDF's are {', '.join(movable)})", field="robot")
    _check_mimics(robot, movable, kept)
    pose = dict(pose or {})
    parents, kinds, axes, placements, inertias, names, damping = [], [], [], [], [], [], []
    lower, upper, effort = [], [], []

    scale = _largest_moment(robot)
    if base == "floating":
        if any(name in movable for name in FREE_NAMES):
            raise InputError(f"the URDF has a joint named like the free base's ({', '.join(FREE_NAMES)})",
                             field="robot")
        for k, (name, kind, axis) in enumerate(FREE_FLYER):      # a chain of massless bodies to the root link
            for into, value in zip((parents, kinds, axes, placements, inertias, names, damping, lower, upper, effort),
                                   (k - 1, kind, np.array(axis), np.eye(6), np.zeros((6, 6)), name, 0.0,
                                    *joint_limits(True, None, None, None))):
                into.append(value)
    # depth first, each link's joints in name order, numbered when reached: Pinocchio's order
    stack: list = [("link", roots[0], len(names) - 1, np.eye(4))]
    seen: set = set()
    frames: dict = {}
    while stack:
        item = stack.pop()
        if item[0] == "link":
            _, link_name, body, frame = item
            if link_name in seen:
                raise InputError(f"link {link_name} is reached twice: closed loops are not modelled", field="robot")
            seen.add(link_name)
            frames[link_name] = (body, frame)
            if body >= 0:       # a link welded to the fixed base never moves: its inertia does not enter
                x = plucker(frame[:3, :3], frame[:3, 3])    # the link's frame from its body's
                inertias[body] = inertias[body] + x.T @ _inertia(links[link_name], scale) @ x
            for j in sorted(children.get(link_name, []), key=lambda j: j.name, reverse=True):
                stack.append(("joint", j, body, frame))
            continue
        _, j, body, frame = item
        origin = frame @ np.asarray(j.origin if j.origin is not None else np.eye(4), dtype=float)
        if j.type == "fixed" or j.name not in kept:
            if j.type != "fixed":       # frozen at its pose: a fixed joint there
                origin = origin @ _joint_motion(j, urdf_number(pose.get(j.name, 0.0), f"joint {j.name}: pose"))
            stack.append(("link", j.child, body, origin))
            continue
        axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
        norm = np.linalg.norm(axis)
        if norm < 1e-12:
            raise InputError(f"joint {j.name} has no axis (its axis is zero)", field="robot")
        parents.append(body)
        kinds.append(MOVING_JOINTS[j.type])
        axes.append(axis / norm)
        placements.append(plucker(origin[:3, :3], origin[:3, 3]))
        inertias.append(np.zeros((6, 6)))
        names.append(j.name)
        d = getattr(j.dynamics, "damping", None) if j.dynamics is not None else None
        d = 0.0 if d is None else urdf_number(d, f"joint {j.name}: damping")
        if d < 0:
            raise InputError(f"joint {j.name}: damping {d:g} is negative", field="robot")
        damping.append(d)
        given = [None if j.limit is None or getattr(j.limit, a) is None else
                 urdf_number(getattr(j.limit, a), f"joint {j.name}: {a} limit") for a in ("lower", "upper", "effort")]
        low, high, most = joint_limits(j.type == "continuous", *given)
        lower.append(low)
        upper.append(high)
        effort.append(most)
        stack.append(("link", j.child, len(names) - 1, np.eye(4)))

    tree = RigidTree(tuple(parents), tuple(kinds), np.array(axes), np.array(placements), np.array(inertias),
                     np.array([0.0, 0.0, -gravity]))
    _check_moving(tree, names, roots[0] if base == "floating" else None)
    return tree, tuple(names), tuple(kinds), np.array(damping), \
        JointLimits(np.array(lower), np.array(upper), np.array(effort)), roots[0], frames


def _joint_motion(joint, value: float) -> np.ndarray:
    """The 4×4 motion of a joint held at *value*."""
    axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float)
    axis = axis / np.linalg.norm(axis)
    t = np.eye(4)
    if MOVING_JOINTS[joint.type] == "revolute":
        t[:3, :3] = axis_rotation(axis, value)[0]
    else:
        t[:3, 3] = axis * value
    return t


def _cached_tree(text: str, g: float, joints, pose, base: str = "fixed") -> tuple:
    """(name, tree, joint names, kinds, dampers, limits, root link, link frames): from the cache when this file was
    read before.

    Parsing needs yourdfpy, whose import alone takes a second; the tree is a few arrays,
    kept under a key of the file's text, the selection and this code (``ANALOGY_CACHE_DIR=``
    turns the cache off, as for the compiled models).
    """
    folder = cache_dir()
    key = hashlib.sha256(repr((text, g, None if joints is None else tuple(joints),
                               None if pose is None else sorted(pose.items()), base)).encode())
    for source in (__file__, rigid_tree_module.__file__, urdf_file_module.__file__, joint_limits_module.__file__):
        key.update(Path(source).read_bytes())
    path = None if folder is None else folder / f"urdf-{key.hexdigest()[:24]}.npz"
    if path is not None and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as z:
                tree = RigidTree(tuple(int(p) for p in z["parents"]), tuple(str(k) for k in z["kinds"]), z["axes"],
                                 z["placements"], z["inertias"], z["gravity"])
                limits = JointLimits(z["lower"], z["upper"], z["effort"])
                frames = {str(k): (int(b), f) for k, b, f in zip(z["links"], z["link_bodies"], z["link_frames"])}
                return (str(z["name"]), tree, tuple(str(n) for n in z["names"]), tree.kinds, z["damping"], limits,
                        str(z["root"]), frames)
        except Exception:           # a damaged entry (not a zip, a missing array …) is rebuilt, never trusted
            pass
    robot = parse_urdf(text)
    tree, names, kinds, damping, limits, root, frames = _tree(robot, g, joints, pose, base)
    name = str(robot.name or "urdf")
    if path is not None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
            np.savez(tmp, name=name, parents=np.array(tree.parents), kinds=np.array(kinds), axes=tree.axes,
                     placements=tree.placements, inertias=tree.inertias, gravity=tree.gravity,
                     names=np.array(names), damping=damping, lower=limits.lower, upper=limits.upper,
                     effort=limits.effort, root=root, links=np.array(list(frames)),
                     link_bodies=np.array([b for b, _ in frames.values()]),
                     link_frames=np.array([f for _, f in frames.values()]).reshape(-1, 4, 4))
            os.replace(tmp, path)               # atomic: readers never see half a file
        except OSError:
            pass
    return name, tree, names, kinds, damping, limits, root, frames


class UrdfModel(RobotModel):
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
    name : str, optional
        The robot's name (default: the URDF's ``<robot name>``).
    base : {"fixed", "floating"}
        The root link held to the world, or free: six more coordinates before the URDF's
        joints (:data:`FREE_FLYER`).
    contacts : sequence of str, optional
        Links whose origins meet the ground plane z = 0 (:mod:`analogy.model.tree_contact`): the
        ground's kc, cc and delta join the parameters, by default :func:`ground_defaults`, and so do
        kp and kd, a servo that holds each joint (not a free base's) about the pose the run starts
        from: a spring and a damper per joint, an inductor and a resistor in the circuit.
    """

    topology = "parallel"
    description = ""
    nonlinear = True
    rigid_tree = True

    def __init__(self, text: str, joints: Sequence[str] | None = None, pose: Mapping[str, float] | None = None,
                 g: float = STANDARD_GRAVITY, name: str | None = None, base: str = "fixed",
                 contacts: Sequence[str] = ()):
        if base not in BASES:
            raise InputError(f"base must be one of {', '.join(BASES)}, got {base!r}", field="robot")
        self.text, self.base = text, base
        self._selection, self._pose, self._label = joints, pose, name
        (self.name, self.tree, self.joint_names, kinds, self.joint_damping, self.limits,
         self.root_link, self.link_frames) = _cached_tree(text, g, joints, pose, base)
        self.name = name or self.name
        self.joints = kinds
        self.contacts = self._contact_points(tuple(contacts))
        self.parameters = {"g": float(g), **(ground_defaults(self.tree, self.contacts,
                                                              [n in FREE_NAMES for n in self.joint_names])
                                              if self.contacts else {})}
        self.coordinates = tuple(f"q{i + 1}" for i in range(len(kinds)))
        self.description = f"URDF {self.name}: {len(kinds)} joints ({', '.join(self.joint_names)})"

    def __repr__(self) -> str:
        return f"UrdfModel({self.name!r}, {self.dof} joints)"

    def _contact_points(self, names: tuple) -> tuple:
        """The :class:`TreeContact` of each link named, each on a moving body; one sentence for any other."""
        points = []
        for name in names:
            if name not in self.link_frames:
                raise InputError(f"{self.name} has no link {name!r} to touch the ground with (its links: "
                                 f"{', '.join(sorted(self.link_frames))})", field="robot")
            body, frame = self.link_frames[name]
            if body < 0:
                raise InputError(f"link {name} is welded to the world: it cannot touch the ground", field="robot")
            points.append(TreeContact(name, body, tuple(float(x) for x in frame[:3, 3])))
        return tuple(points)

    @property
    def dof(self) -> int:
        return self.tree.dof

    @property
    def units(self) -> tuple[str, ...]:
        return tuple("rad" if k == "revolute" else "m" for k in self.joints)

    def with_parameters(self, parameters: Mapping[str, float] | None = None) -> "UrdfModel":
        """This robot at other parameter values (``g``): itself when they are its own.

        Parameters
        ----------
        parameters : mapping, optional
            ``g``.
        """
        if not parameters:
            return self
        if unknown := [k for k in parameters if k not in self.parameters]:
            raise InputError(f"URDF robot {self.name} has no parameter {unknown[0]!r} (it has: "
                             f"{', '.join(self.parameters)})", field="parameters")
        g = float(parameters.get("g", self.parameters["g"]))
        if not np.isfinite(g):
            raise InputError("g must be finite", field="parameters")
        values = {**self.parameters, **{k: float(v) for k, v in parameters.items()}}
        if values == self.parameters:
            return self
        model = self if g == self.parameters["g"] else urdf_model(
            self.text, None if self._selection is None else tuple(self._selection),
            None if not self._pose else tuple(sorted(self._pose.items())), g, self._label, self.base,
            tuple(c.name for c in self.contacts))
        if values != model.parameters:      # the ground's: the tree stays, the parameters change
            check_contact_values([Contact(c.name, 0, "kc", "cc", "delta") for c in model.contacts]
                                 + [Contact("servo", 0, "kp", "kd", "delta")], values)
            if not (np.isfinite(values["mu"]) and values["mu"] >= 0):
                raise InputError(f"the friction coefficient mu must be finite and zero or positive, got {values['mu']:g}",
                                 field="parameters")
            model = copy.copy(model)
            model.parameters = values
        return model

    def _parts(self, qs: np.ndarray, parameters) -> tuple:
        """M, B, ∂G/∂q and G at every row of *qs* (the last two None without gravity)."""
        model = self.with_parameters(parameters)
        tree = model.tree
        m = tree.mass_matrices(qs)
        b = np.broadcast_to(np.diag(self.joint_damping), m.shape)
        if not np.any(tree.gravity):
            return m, b, None, None
        # G and ∂G/∂q are sums of terms up to g·Σm·reach: below n·ε of that they are rounding,
        # which would become loads and inductors of random sign (1e38 H) in the circuit
        floor = 16 * self.dof * np.finfo(float).eps * model.gravity_scale
        k, g = tree.gravity_stiffness(qs), tree.gravity_load(qs)
        k[np.abs(k) < floor] = 0.0
        g[np.abs(g) < floor] = 0.0
        return m, b, k, g

    @cached_property
    def gravity_scale(self) -> float:
        """g·Σm·reach [N·m]: how large a gravity load or stiffness of the tree can be."""
        t = self.tree
        bodies = [body_inertia(i) for i in t.inertias]
        reach = sum(float(np.linalg.norm(placement_frame(x)[1])) for x in t.placements) \
            + max((float(np.linalg.norm(c)) for _, c, _ in bodies), default=0.0)
        return float(np.linalg.norm(t.gravity) * sum(m for m, _, _ in bodies) * reach)

    def mechanical_functions(self, parameters: Mapping[str, float] | None = None) -> MechanicalFunctions:
        """M(q), c(q, q̇), G(q), q̈ and U(q) of the tree (Pinocchio's where installed), for the nonlinear dynamics.

        Parameters
        ----------
        parameters : mapping, optional
            ``g``.
        """
        model = self.with_parameters(parameters)
        tree = model.tree
        damping = np.diag(self.joint_damping)
        # Pinocchio's where it is installed and reads the file as this tree, else the tree's own
        functions = pinocchio_functions(self.text, tree, self.joint_names, damping, self._pose,
                                        self.base == "floating") or tree.functions(damping)
        if not model.contacts:
            return functions
        ground = model.parameters
        servo = np.diag([0.0 if name in FREE_NAMES else 1.0 for name in self.joint_names])
        return functions._replace(damping=damping + ground["kd"] * servo,
                                  stiffness=ground["kp"] * servo if ground["kp"] > 0 else None,
                                  contacts=tree_contact_functions(
                                      tree, model.contacts, ground["kc"], ground["cc"], ground["delta"], ground["mu"],
                                      pinocchio_places(self.text, tree, self.joint_names,
                                                       [c.name for c in model.contacts], self._pose,
                                                       self.base == "floating")))

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
        return JointStack(*self._parts(configuration_stack(self.name, self.coordinates, qs), parameters))


@lru_cache(maxsize=16)
def urdf_model(text: str, joints: tuple | None = None, pose: tuple | None = None,
               g: float = STANDARD_GRAVITY, name: str | None = None, base: str = "fixed",
               contacts: tuple = ()) -> UrdfModel:
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
    name : str, optional
        The robot's name (default: the URDF's ``<robot name>``).
    base : {"fixed", "floating"}
        The root link held to the world, or free-flying.
    contacts : tuple of str
        Links that meet the ground.
    """
    return UrdfModel(text, joints, dict(pose) if pose is not None else None, g, name, base, contacts)


def ground_defaults(tree: RigidTree, contacts: Sequence[TreeContact], free: Sequence[bool]) -> dict[str, float]:
    """The ground's default kc, cc and delta for a robot of *tree*'s mass, and its joints' servo kp, kd: under
    standard gravity its whole weight sinks one contact by :data:`GROUND_SINK`, cc damps that mass on kc
    critically, and δ is a tenth of the sink (the stance is then the linear law's to 1e-4,
    :mod:`analogy.model.contact`); the whole weight at the contacts' reach from the root (at q = 0) bends
    a joint by :data:`SERVO_SAG`, and kd damps the median joint's own inertia on kp critically.

    Parameters
    ----------
    tree : RigidTree
        The robot's tree.
    contacts : sequence of TreeContact
        Its contact points.
    free : sequence of bool
        Per joint, whether it is a free base's (no servo).
    """
    mass = sum(body_inertia(i)[0] for i in tree.inertias)
    stiffness = mass * STANDARD_GRAVITY / GROUND_SINK
    at = tree.points(np.zeros((1, tree.dof)), [c.body for c in contacts], [c.offset for c in contacts])[0][0]
    servo = mass * STANDARD_GRAVITY * float(np.max(np.linalg.norm(at, axis=1))) / SERVO_SAG
    held = ~np.asarray(free, dtype=bool)
    inertia = float(np.median(np.diag(tree.mass_matrix(np.zeros(tree.dof)))[held])) if held.any() else 0.0
    return {"kc": float(f"{stiffness:.3g}"), "cc": float(f"{2 * np.sqrt(stiffness * mass):.3g}"),
            "delta": GROUND_SINK / 10, "mu": GROUND_FRICTION, "kp": float(f"{servo:.3g}"),
            "kd": float(f"{2 * np.sqrt(servo * inertia):.3g}")}
