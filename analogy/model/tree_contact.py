"""Contacts on a rigid tree's links: each point's place and velocity, and the ground's generalised force, numerically."""

from __future__ import annotations

from typing import Callable, NamedTuple, Sequence

import numpy as np

from .contact import contact_force, friction_force
from .dynamics import ContactFunctions
from .rigid_tree import RigidTree

__all__ = ["TreeContact", "tree_contact_functions", "CONTACT_PARAMETERS"]

#: The ground's parameters a URDF robot with contacts takes, and their units.
CONTACT_PARAMETERS = {"kc": "N/m", "cc": "N*s/m", "delta": "m", "mu": "1", "kp": "N*m", "kd": "N*m*s"}


class TreeContact(NamedTuple):
    """A point of a tree's link that meets the ground plane z = 0 (the URDF's base frame).

    Attributes
    ----------
    name : str
        The link's name; the force's output is ``f_<name>``.
    body : int
        The tree's body the link is welded to.
    offset : tuple of float
        The link's origin in that body's frame [m].
    """

    name: str
    body: int
    offset: tuple


def tree_contact_functions(tree: RigidTree, contacts: Sequence[TreeContact], stiffness: float, damping: float,
                           smoothing: float, friction: float = 0.0, kinematics: Callable | None = None
                           ) -> ContactFunctions:
    """The contacts' forces on *tree*: the normal force f of p = −P_z and ṗ = −(J·q̇)_z by
    :func:`~analogy.model.contact.contact_force`, friction along the ground by
    :func:`~analogy.model.contact.friction_force`, and τ = Σ Jᵀ·(fx, fy, f).

    Parameters
    ----------
    tree : RigidTree
        The tree.
    contacts : sequence of TreeContact
        The contact points.
    stiffness, damping, smoothing : float
        kc [N/m], cc [N·s/m] and δ [m].
    friction : float
        μ (0: the feet slide freely).
    kinematics : callable, optional
        ``kinematics(q)`` → the points (k, 3) and their Jacobians ∂P/∂q (k, 3, n) at one pose, where a
        faster implementation of the tree's kinematics has them (Pinocchio's frames); by default
        :meth:`~analogy.model.rigid_tree.RigidTree.points`.
    """
    bodies = [c.body for c in contacts]
    offsets = np.array([c.offset for c in contacts], dtype=float)
    n = tree.dof

    def place(q):
        if kinematics is not None:
            return kinematics(q)
        at, jac = tree.points(np.atleast_2d(q), bodies, offsets)
        return at[0], jac[0]

    def wrench(q, r):
        at, jac = place(q)
        velocity = jac @ r                                           # (k, 3)
        f = contact_force(-at[:, 2], -velocity[:, 2], stiffness, damping, smoothing, np.tanh)
        fx, fy = friction_force(f, velocity[:, 0], velocity[:, 1], friction, np.sqrt)
        return np.stack([fx, fy, f], axis=1), jac, f

    def generalised(q, r):
        q, r = np.asarray(q, float), np.asarray(r, float)
        if q.ndim == 2:                                 # a stack of states, one per column
            return np.stack([generalised(a, b) for a, b in zip(q.T, r.T)], axis=1)
        force, jac, _ = wrench(q, r)
        return np.einsum("kin,ki->n", jac, force)

    def derivatives(q, r):
        q, r = np.asarray(q, float), np.asarray(r, float)
        out = []
        for y, other, first in ((q, r, True), (r, q, False)):       # central differences: an implicit
            d = np.zeros((n, n))                                      # method's Newton matrix
            for k in range(n):
                h = 1e-7 * max(1.0, abs(y[k]))
                up, down = y.copy(), y.copy()
                up[k] += h
                down[k] -= h
                pair = ((up, other), (down, other)) if first else ((other, up), (other, down))
                d[:, k] = (generalised(*pair[0]) - generalised(*pair[1])) / (2 * h)
            out.append(d)
        return tuple(out)

    def normal(q, r):
        q, r = np.asarray(q, float), np.asarray(r, float)
        if q.ndim == 1:
            return wrench(q, r)[2]
        at, jac = tree.points(q.T, bodies, offsets)
        rise = np.einsum("pkn,pn->pk", jac[..., 2, :], r.T)
        return contact_force(-at[..., 2], -rise, stiffness, damping, smoothing, np.tanh).T

    def depths(q):
        return -tree.points(np.asarray(q, float).T, bodies, offsets)[0][..., 2].T

    return ContactFunctions(generalised, derivatives, normal, depths, tuple(c.name for c in contacts),
                            tuple(smoothing for _ in contacts))
