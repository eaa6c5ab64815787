"""A kinematic tree of rigid bodies: M(q), G(q) and the velocity terms by spatial algebra (numpy)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

__all__ = ["JointKind", "RigidTree", "spatial_inertia", "plucker"]

#: The joints a tree moves by: a rotation about an axis, or a slide along it.
JointKind = Literal["revolute", "prismatic"]


def _skew(p: np.ndarray) -> np.ndarray:
    x, y, z = p
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]], dtype=p.dtype)


def plucker(rotation: np.ndarray, position: np.ndarray) -> np.ndarray:
    """ᴮX_A, the motion transform into frame B located at *position* with axes *rotation* in A.

    Motion vectors are [ω; v] (Featherstone's order): ᴮX_A = [[Eᵀ, 0], [−Eᵀ·p×, Eᵀ]].

    Parameters
    ----------
    rotation : ndarray, shape (3, 3)
        B's axes in A's coordinates (columns).
    position : ndarray, shape (3,)
        B's origin in A.
    """
    et = rotation.T
    x = np.zeros((6, 6), dtype=np.result_type(rotation, position))
    x[:3, :3] = et
    x[3:, 3:] = et
    x[3:, :3] = -et @ _skew(position)
    return x


def spatial_inertia(mass: float, com: np.ndarray, inertia_at_com: np.ndarray) -> np.ndarray:
    """A body's 6×6 spatial inertia about its frame's origin.

    [[Ī + m·c×·c×ᵀ, m·c×], [m·c×ᵀ, m·1]], with Ī its rotational inertia about the centre
    of mass c, both in the body's axes.

    Parameters
    ----------
    mass : float
        m.
    com : ndarray, shape (3,)
        c.
    inertia_at_com : ndarray, shape (3, 3)
        Ī.
    """
    cx = _skew(np.asarray(com, dtype=float))
    i = np.zeros((6, 6))
    i[:3, :3] = inertia_at_com + mass * cx @ cx.T
    i[:3, 3:] = mass * cx
    i[3:, :3] = mass * cx.T
    i[3:, 3:] = mass * np.eye(3)
    return i


def _rotation(axis: np.ndarray, angle):
    """Rodrigues: the axes of a frame turned by *angle* about the unit *axis* (complex angles too)."""
    k = _skew(axis.astype(np.result_type(axis, angle)))
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def _crm(v: np.ndarray) -> np.ndarray:
    """v×, the spatial cross product of motion vectors."""
    out = np.zeros((6, 6), dtype=v.dtype)
    w, u = _skew(v[:3]), _skew(v[3:])
    out[:3, :3] = w
    out[3:, 3:] = w
    out[3:, :3] = u
    return out


@dataclass(frozen=True)
class RigidTree:
    """Bodies on joints, each joint on its parent body (−1: the fixed base).

    Parameters
    ----------
    parents : tuple of int
        Per joint, the index of its parent body, lower than its own.
    kinds : tuple of JointKind
        Per joint, revolute or prismatic.
    axes : ndarray, shape (n, 3)
        Per joint, its unit axis in its own frame.
    placements : ndarray, shape (n, 6, 6)
        Per joint, the motion transform from its parent body's frame to the joint's frame at q = 0.
    inertias : ndarray, shape (n, 6, 6)
        Per body, its spatial inertia about its frame (bodies on fixed joints merged in).
    gravity : ndarray, shape (3,)
        The acceleration of gravity in the base frame [m/s²].
    """

    parents: tuple
    kinds: tuple
    axes: np.ndarray
    placements: np.ndarray
    inertias: np.ndarray
    gravity: np.ndarray

    @property
    def dof(self) -> int:
        return len(self.parents)

    def _subspaces(self) -> np.ndarray:
        s = np.zeros((self.dof, 6))
        for i, (kind, axis) in enumerate(zip(self.kinds, self.axes)):
            s[i, slice(0, 3) if kind == "revolute" else slice(3, 6)] = axis
        return s

    def _links(self, q) -> list[np.ndarray]:
        """Per joint, ⁱX_λ(q): its body's frame from its parent's."""
        out = []
        for kind, axis, placement, qi in zip(self.kinds, self.axes, self.placements, q):
            if kind == "revolute":
                joint = plucker(_rotation(axis, qi), np.zeros(3))
            else:
                joint = plucker(np.eye(3), axis * qi)
            out.append(joint @ placement)
        return out

    def mass_matrix(self, q: Sequence[float]) -> np.ndarray:
        """M(q) by the composite-rigid-body algorithm.

        Parameters
        ----------
        q : sequence of float
            Joint coordinates [rad or m].
        """
        x = self._links(np.asarray(q, dtype=float))
        s = self._subspaces()
        composite = self.inertias.copy()
        for i in range(self.dof - 1, -1, -1):
            if self.parents[i] >= 0:
                composite[self.parents[i]] += x[i].T @ composite[i] @ x[i]
        m = np.zeros((self.dof, self.dof))
        for i in range(self.dof):
            f = composite[i] @ s[i]
            m[i, i] = s[i] @ f
            j = i
            while self.parents[j] >= 0:
                f = x[j].T @ f
                j = self.parents[j]
                m[i, j] = m[j, i] = s[j] @ f
        return m

    def inverse_dynamics(self, q, rates, accelerations, gravity: bool = True) -> np.ndarray:
        """τ = M(q)·q̈ + c(q, q̇) + G(q) by recursive Newton–Euler (complex q allowed).

        Parameters
        ----------
        q, rates, accelerations : sequence of float
            q, q̇ and q̈.
        gravity : bool
            Include G(q).
        """
        q = np.asarray(q)
        dtype = np.result_type(q, float)
        x = self._links(q)
        s = self._subspaces()
        qd = np.asarray(rates, dtype=dtype)
        qdd = np.asarray(accelerations, dtype=dtype)
        base = np.zeros(6, dtype=dtype)
        if gravity:
            base[3:] = -self.gravity        # the base accelerates up: gravity on every body at once
        v = np.zeros((self.dof, 6), dtype=dtype)
        a = np.zeros((self.dof, 6), dtype=dtype)
        f = np.zeros((self.dof, 6), dtype=dtype)
        for i in range(self.dof):
            p = self.parents[i]
            vp, ap = (np.zeros(6, dtype=dtype), base) if p < 0 else (v[p], a[p])
            v[i] = x[i] @ vp + s[i] * qd[i]
            a[i] = x[i] @ ap + s[i] * qdd[i] + _crm(v[i]) @ (s[i] * qd[i])
            f[i] = self.inertias[i] @ a[i] - _crm(v[i]).T @ (self.inertias[i] @ v[i])
        tau = np.zeros(self.dof, dtype=dtype)
        for i in range(self.dof - 1, -1, -1):
            tau[i] = s[i] @ f[i]
            if self.parents[i] >= 0:
                f[self.parents[i]] += x[i].T @ f[i]
        return tau

    def gravity_load(self, q: Sequence[float]) -> np.ndarray:
        """G(q), the joint forces that hold the tree still against gravity.

        Parameters
        ----------
        q : sequence of float
            Joint coordinates.
        """
        zero = np.zeros(self.dof)
        return self.inverse_dynamics(q, zero, zero).real

    def velocity_load(self, q: Sequence[float], rates: Sequence[float]) -> np.ndarray:
        """c(q, q̇) = C(q, q̇)·q̇, the Coriolis and centrifugal joint forces.

        Parameters
        ----------
        q, rates : sequence of float
            q and q̇.
        """
        return self.inverse_dynamics(q, rates, np.zeros(self.dof), gravity=False).real

    def gravity_stiffness(self, q: Sequence[float]) -> np.ndarray:
        """∂G/∂q, the stiffness gravity adds about q, by the complex step (exact to rounding).

        G = ∂U/∂q for the potential U, so ∂G/∂q is U's Hessian and symmetric.

        Parameters
        ----------
        q : sequence of float
            Joint coordinates.
        """
        q = np.asarray(q, dtype=float)
        h = 1e-30                   # no subtraction: the step may be far below rounding
        zero = np.zeros(self.dof)
        k = np.empty((self.dof, self.dof))
        for j in range(self.dof):
            qc = q.astype(complex)
            qc[j] += 1j * h
            k[:, j] = self.inverse_dynamics(qc, zero, zero).imag / h
        return 0.5 * (k + k.T)
