"""A URDF tree's dynamics by Pinocchio: q̈ by the articulated-body algorithm, M, c, G and U, where it is installed."""

from __future__ import annotations

import hashlib
import threading
from functools import lru_cache
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .dynamics import MechanicalFunctions
from .rigid_tree import RigidTree

__all__ = ["pinocchio_functions", "pinocchio_model", "pinocchio_places", "AGREEMENT_GUARD", "ROOT_JOINT"]

#: Pinocchio and the tree's recursions sum the same products in other orders: each entry of M
#: and c + G is a sum of about n² products no larger than its peak, so they agree to a few n²·ε
#: of it (1e-14 for n = 7). A file the two read differently differs by O(1); between the two,
#: this bound tells them apart with margin on both sides.
AGREEMENT_GUARD = 1e-8


def _library():
    """The pinocchio module, or None: optional, and a quarter of a second to import, so only when asked."""
    try:
        import pinocchio
    except ImportError:
        return None
    return pinocchio


#: Pinocchio's name for the joint a model is built on: the free base, where there is one.
ROOT_JOINT = "root_joint"


def _free_flyer(pin):
    """The free base of :data:`~analogy.model.urdf.FREE_FLYER` as one Pinocchio joint: x, y, z slides, then
    Z-Y-X rotations, in a composite whose coordinates are the six joints' own (q̇ = v)."""
    base = pin.JointModelComposite(pin.JointModelPX())
    for joint in (pin.JointModelPY(), pin.JointModelPZ(), pin.JointModelRZ(), pin.JointModelRY(), pin.JointModelRX()):
        base.addJoint(joint)
    return base


def pinocchio_model(text: str, joint_names: Sequence[str], pose: Mapping[str, float] | None = None,
                    gravity: Sequence[float] = (0.0, 0.0, -9.80665),
                    floating: bool = False) -> tuple[Any, np.ndarray] | None:
    """(Pinocchio model, velocity index per joint) of a URDF, or None where it does not read it alike.

    The joints not in *joint_names* are frozen at their *pose* (0 by default), as
    :class:`~analogy.model.urdf.UrdfModel` freezes them. The index
    maps analogy's joint k to Pinocchio's velocity coordinate, so the order need not agree.

    Parameters
    ----------
    text : str
        The URDF's text.
    joint_names : sequence of str
        The joints kept, in analogy's order.
    pose : mapping, optional
        The frozen joints' values.
    gravity : sequence of float
        The acceleration of gravity in the base frame [m/s²].
    floating : bool
        The first six of *joint_names* are a free base (:data:`~analogy.model.urdf.FREE_FLYER`),
        built as Pinocchio's root joint.
    """
    pin = _library()
    if pin is None:
        return None
    base, joint_names = (list(joint_names[:6]), list(joint_names[6:])) if floating else ([], list(joint_names))
    try:
        full = pin.buildModelFromXML(text, _free_flyer(pin)) if floating else pin.buildModelFromXML(text)
    except Exception:           # a file Pinocchio's parser refuses: the tree's own recursions serve
        return None
    kept = set(joint_names) | ({ROOT_JOINT} if floating else set())
    names = list(full.names)
    if not kept <= set(names) or full.nv != full.njoints - 1 + (5 if floating else 0):
        return None             # a joint it does not have, or one of more than one coordinate
    pose = dict(pose or {})
    held = np.zeros(full.nv)
    locked = []
    for j in range(1, full.njoints):
        if names[j] not in kept:
            locked.append(j)
            held[full.joints[j].idx_v] = float(pose.get(names[j], 0.0))
    # integrate from the neutral pose: exact for a 1-DOF joint, (cos, sin) for a continuous one
    model = pin.buildReducedModel(full, locked, pin.integrate(full, pin.neutral(full), held)) if locked else full
    model.gravity.linear = np.array(gravity, dtype=float)
    start = [model.joints[model.getJointId(ROOT_JOINT)].idx_v + k for k in range(len(base))]
    index = np.array(start + [model.joints[model.getJointId(name)].idx_v for name in joint_names])
    return model, index


class _Pinocchio:
    """Pinocchio's algorithms on analogy's coordinates: one Data per thread (Data is scratch space)."""

    def __init__(self, pin, model, index: np.ndarray):
        self.pin, self.model, self.index = pin, model, index
        self.still = pin.Model(model)
        self.still.gravity.linear = np.zeros(3)
        self.identity = bool(np.array_equal(index, np.arange(len(index))))
        self.angles = model.nq != model.nv          # continuous joints: q enters as (cos, sin)
        self.neutral = pin.neutral(model)
        self.local = threading.local()
        self.agreed: dict[str, bool] = {}

    def _data(self):
        local = self.local
        if not hasattr(local, "data"):
            local.data, local.still = self.model.createData(), self.still.createData()
        return local.data

    def _coordinates(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if not self.identity:
            moved = np.empty_like(q)
            moved[self.index] = q
            q = moved
        return self.pin.integrate(self.model, self.neutral, q) if self.angles else q

    def _rates(self, r) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        if self.identity:
            return r
        moved = np.empty_like(r)
        moved[self.index] = r
        return moved

    def _back(self, a: np.ndarray) -> np.ndarray:
        return a if self.identity else a[self.index]

    def forward(self, q, r, tau) -> np.ndarray:
        return self._back(self.pin.aba(self.model, self._data(), self._coordinates(q), self._rates(r),
                                       self._rates(tau)))

    def mass(self, q) -> np.ndarray:
        m = self.pin.crba(self.model, self._data(), self._coordinates(q))
        m = np.triu(m) + np.triu(m, 1).T        # crba fills the upper triangle
        return m if self.identity else m[np.ix_(self.index, self.index)]

    def velocity(self, q, r) -> np.ndarray:
        self._data()
        zero = np.zeros(self.model.nv)          # rnea without gravity: c alone, not (c + G) − G
        return self._back(self.pin.rnea(self.still, self.local.still, self._coordinates(q), self._rates(r), zero))

    def gravity(self, q) -> np.ndarray:
        return self._back(self.pin.computeGeneralizedGravity(self.model, self._data(), self._coordinates(q)))

    def masses(self, qs) -> np.ndarray:
        return np.stack([self.mass(q) for q in np.atleast_2d(qs)])

    def gravities(self, qs) -> np.ndarray:
        return np.stack([self.gravity(q) for q in np.atleast_2d(qs)])

    def places(self, q, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The origins (k, 3) of the frames *frames* in the world and their Jacobians ∂P/∂q (k, 3, n), in
        analogy's order."""
        pin, data = self.pin, self._data()
        state = self._coordinates(q)
        pin.computeJointJacobians(self.model, data, state)
        pin.updateFramePlacements(self.model, data)
        at = np.array([data.oMf[int(f)].translation for f in frames])
        jac = np.array([pin.getFrameJacobian(self.model, data, int(f), pin.LOCAL_WORLD_ALIGNED)[:3] for f in frames])
        return at, jac if self.identity else jac[:, :, self.index]

    def potential(self, qs) -> np.ndarray:
        data = self._data()
        return np.array([self.pin.computePotentialEnergy(self.model, data, self._coordinates(q))
                         for q in np.atleast_2d(qs)])


def _agrees(p: _Pinocchio, tree: RigidTree) -> bool:
    """Whether Pinocchio's M and c + G are the tree's at a few states (see :data:`AGREEMENT_GUARD`)."""
    rng = np.random.default_rng(0)
    n = tree.dof
    for _ in range(3):
        q, r = rng.uniform(-np.pi, np.pi, n), rng.normal(size=n)
        m, bias = tree.mass_matrix(q), tree.inverse_dynamics(q, r, np.zeros(n))
        theirs = p.mass(q), p.velocity(q, r) + p.gravity(q)
        for mine, other in zip((m, bias), theirs):
            if not np.abs(mine - other).max() <= AGREEMENT_GUARD * max(np.abs(mine).max(), np.finfo(float).tiny):
                return False
    return True


@lru_cache(maxsize=16)
def _cached(text: str, joint_names: tuple, pose: tuple, gravity: tuple, floating: bool) -> _Pinocchio | None:
    built = pinocchio_model(text, joint_names, dict(pose), gravity, floating)
    return None if built is None else _Pinocchio(_library(), *built)


def pinocchio_functions(text: str, tree: RigidTree, joint_names: Sequence[str], damping: np.ndarray,
                        pose: Mapping[str, float] | None = None, floating: bool = False) -> MechanicalFunctions | None:
    """The tree's M, c, G, forward dynamics (``pinocchio.aba``) and U by Pinocchio, or None.

    None where Pinocchio is not installed, or reads the file otherwise than *tree* was
    read (its M or c + G differ past :data:`AGREEMENT_GUARD`): the tree's own recursions
    then serve (:meth:`~analogy.model.rigid_tree.RigidTree.functions`).

    Parameters
    ----------
    text : str
        The URDF's text.
    tree : RigidTree
        The same tree as analogy read it.
    joint_names : sequence of str
        Its joints, in its order.
    damping : ndarray, shape (n, n)
        B.
    pose : mapping, optional
        The frozen joints' values.
    floating : bool
        The tree's first six joints are a free base.
    """
    p = _agreeing(text, tree, joint_names, pose, floating)
    if p is None:
        return None
    gravity: Callable | None = p.gravity if np.any(tree.gravity) else None
    return MechanicalFunctions(p.mass, p.velocity, gravity, damping, None, masses=p.masses,
                               gravities=None if gravity is None else p.gravities, forward=p.forward,
                               potential=None if gravity is None else p.potential)


def pinocchio_places(text: str, tree: RigidTree, joint_names: Sequence[str], links: Sequence[str],
                      pose: Mapping[str, float] | None = None, floating: bool = False) -> Callable | None:
    """``places(q)``: the origins of *links* and their Jacobians ∂P/∂q by Pinocchio's frame kinematics, as
    :meth:`~analogy.model.rigid_tree.RigidTree.points` gives them at one pose; None where Pinocchio is not
    installed or does not read the file as *tree*.

    Parameters
    ----------
    text : str
        The URDF's text.
    tree : RigidTree
        The same tree as analogy read it.
    joint_names : sequence of str
        Its joints, in its order.
    links : sequence of str
        The links whose origins are asked for.
    pose : mapping, optional
        The frozen joints' values.
    floating : bool
        The tree's first six joints are a free base.
    """
    p = _agreeing(text, tree, joint_names, pose, floating)
    if p is None or not all(p.model.existFrame(name) for name in links):
        return None
    frames = np.array([p.model.getFrameId(name) for name in links])
    return lambda q: p.places(q, frames)


def _agreeing(text: str, tree: RigidTree, joint_names: Sequence[str], pose: Mapping[str, float] | None,
              floating: bool) -> _Pinocchio | None:
    """The URDF's Pinocchio model where it is installed and reads the file as *tree*, else None."""
    p = _cached(text, tuple(joint_names), tuple(sorted((pose or {}).items())), tuple(map(float, tree.gravity)),
                floating)
    return p if p is not None and _agreed(p, tree) else None


def _agreed(p: _Pinocchio, tree: RigidTree) -> bool:
    """:func:`_agrees`, once per Pinocchio model and tree."""
    key = hashlib.sha256(repr((tree.parents, tree.kinds)).encode())
    for a in (tree.axes, tree.placements, tree.inertias, tree.gravity):
        key.update(np.ascontiguousarray(a, dtype=float).tobytes())
    digest = key.hexdigest()
    if digest not in p.agreed:
        p.agreed[digest] = _agrees(p, tree)
    return p.agreed[digest]
