"""Contacts on a rigid tree's links: each point's height, its rate and the ground's generalised force, numerically."""

from __future__ import annotations

from typing import Callable, NamedTuple, Sequence

import numpy as np

from .contact import contact_force
from .dynamics import ContactFunctions
from .rigid_tree import RigidTree

__all__ = ["TreeContact", "tree_contact_functions", "CONTACT_PARAMETERS"]

#: The ground's parameters a URDF robot with contacts takes, and their units.
CONTACT_PARAMETERS = {"kc": "N/m", "cc": "N*s/m", "delta": "m", "kp": "N*m", "kd": "N*m*s"}


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
                           smoothing: float, kinematics: Callable | None = None) -> ContactFunctions:
    """The contacts' forces on *tree*: p = −P_z, ṗ = −(J·q̇)_z, f by :func:`~analogy.model.contact.contact_force`
    and τ = Σ J_zᵀ·f, with the ground's *stiffness*, *damping* and *smoothing* at every contact.

    Parameters
    ----------
    tree : RigidTree
        The tree.
    contacts : sequence of TreeContact
        The contact points.
    stiffness, damping, smoothing : float
        kc [N/m], cc [N·s/m] and δ [m].
    kinematics : callable, optional
        ``kinematics(q)`` → the points' heights (k,) and their gradients (k, n) at one pose, where a
        faster implementation of the tree's kinematics has them (Pinocchio's frames); by default
        :meth:`~analogy.model.rigid_tree.RigidTree.points`.
    """
    bodies = [c.body for c in contacts]
    offsets = np.array([c.offset for c in contacts], dtype=float)
    n = tree.dof

    def heights(q):
        at, jac = tree.points(np.atleast_2d(q), bodies, offsets)
        return at[..., 2], jac[..., 2, :]               # (poses, k), (poses, k, n)

    def one(q):
        if kinematics is not None:
            return kinematics(q)
        z, jz = heights(q)
        return z[0], jz[0]

    def forces(q, r):
        z, jz = one(q)
        return contact_force(-z, -(jz @ r), stiffness, damping, smoothing, np.tanh), jz

    def generalised(q, r):
        f, jz = forces(np.asarray(q, float), np.asarray(r, float))
        return jz.T @ f

    def derivatives(q, r):
        q, r = np.asarray(q, float), np.asarray(r, float)
        z, jz = one(q)
        switch = (1 + np.tanh(-z / (2 * smoothing))) / 2
        d_rate = -damping * (jz.T * switch) @ jz                # ∂τ/∂q̇ = −Σ cc·s·J_zᵀJ_z
        d_q = np.zeros((n, n))                                   # ∂τ/∂q by central differences: an
        for k in range(n):                                       # implicit method's Newton matrix
            h = 1e-7 * max(1.0, abs(q[k]))
            up, down = q.copy(), q.copy()
            up[k] += h
            down[k] -= h
            d_q[:, k] = (generalised(up, r) - generalised(down, r)) / (2 * h)
        return d_q, d_rate

    def normal(q, r):
        q, r = np.asarray(q, float), np.asarray(r, float)
        if q.ndim == 1:
            return forces(q, r)[0]
        z, jz = heights(q.T)
        return contact_force(-z, -np.einsum("pkn,pn->pk", jz, r.T), stiffness, damping, smoothing, np.tanh).T

    def depths(q):
        return -heights(np.asarray(q, float).T)[0].T

    return ContactFunctions(generalised, derivatives, normal, depths, tuple(c.name for c in contacts),
                            tuple(smoothing for _ in contacts))
