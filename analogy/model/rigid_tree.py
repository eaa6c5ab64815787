"""A kinematic tree of rigid bodies: M(q), G(q) and the velocity terms by spatial algebra (numpy)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal, Sequence

import numpy as np

from .dynamics import MechanicalFunctions

__all__ = ["JointKind", "RigidTree", "axis_rotation", "spatial_inertia", "plucker", "placement_frame", "body_inertia"]

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


def placement_frame(transform: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, position) of the frame a motion transform :func:`plucker` made: its inverse.

    Parameters
    ----------
    transform : ndarray, shape (6, 6)
        ᴮX_A = [[Eᵀ, 0], [−Eᵀ·p×, Eᵀ]].
    """
    rotation = transform[:3, :3].T
    px = -rotation @ transform[3:, :3]
    return rotation, np.array([px[2, 1], px[0, 2], px[1, 0]])


def axis_rotation(axis: np.ndarray, angles) -> np.ndarray:
    """Rodrigues' rotations by each of *angles* about the unit *axis*, shape (len(angles), 3, 3).

    Parameters
    ----------
    axis : ndarray, shape (3,)
        Unit axis.
    angles : array_like
        Angles [rad] (complex ones too, for the complex step).
    """
    k = _skew(np.asarray(axis, dtype=float))
    a = np.atleast_1d(angles)
    c, s = np.cos(a)[:, None, None], np.sin(a)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


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


def body_inertia(inertia: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(m, c, Ī) of a spatial inertia :func:`spatial_inertia` made: its inverse (c = 0 when m = 0).

    Parameters
    ----------
    inertia : ndarray, shape (6, 6)
        A body's spatial inertia about its frame's origin.
    """
    m = float(inertia[5, 5])
    first = np.array([inertia[2, 4], inertia[0, 5], inertia[1, 3]])     # m·c from the m·c× block
    com = first / m if m > 0 else np.zeros(3)
    cx = _skew(com)
    return m, com, inertia[:3, :3] - m * cx @ cx.T


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

    def _links(self, qs: np.ndarray) -> np.ndarray:
        """ⁱX_λ(q) per pose and joint, shape (poses, n, 6, 6): each body's frame from its parent's."""
        p, n = qs.shape
        x = np.zeros((p, n, 6, 6), dtype=qs.dtype)
        for i, (kind, axis) in enumerate(zip(self.kinds, self.axes)):
            if kind == "revolute":          # the child's axes turned by q about the axis
                et = axis_rotation(axis, qs[:, i]).transpose(0, 2, 1)
                x[:, i, :3, :3] = et
                x[:, i, 3:, 3:] = et
            else:                           # a slide by q along the axis: [[1, 0], [−p×, 1]]
                x[:, i, :3, :3] = x[:, i, 3:, 3:] = np.eye(3)
                x[:, i, 3:, :3] = -qs[:, i, None, None] * _skew(axis)
        return x @ self.placements

    def mass_matrices(self, qs) -> np.ndarray:
        """M(q) at every row of *qs* by the composite-rigid-body algorithm, shape (poses, n, n).

        Parameters
        ----------
        qs : array_like, shape (poses, n)
            Joint coordinates [rad or m].
        """
        qs = np.atleast_2d(np.asarray(qs, dtype=float))
        x = self._links(qs)
        s = self._subspaces()
        composite = np.broadcast_to(self.inertias, (len(qs),) + self.inertias.shape).copy()
        for i in range(self.dof - 1, -1, -1):
            if self.parents[i] >= 0:
                composite[:, self.parents[i]] += x[:, i].transpose(0, 2, 1) @ composite[:, i] @ x[:, i]
        m = np.zeros((len(qs), self.dof, self.dof))
        for i in range(self.dof):
            f = composite[:, i] @ s[i]
            m[:, i, i] = f @ s[i]
            j = i
            while self.parents[j] >= 0:
                f = (f[:, None, :] @ x[:, j])[:, 0]
                j = self.parents[j]
                m[:, i, j] = m[:, j, i] = f @ s[j]
        return m

    def mass_matrix(self, q: Sequence[float]) -> np.ndarray:
        """M(q) at one pose (:meth:`mass_matrices`).

        Parameters
        ----------
        q : sequence of float
            Joint coordinates [rad or m].
        """
        return self.mass_matrices(np.asarray(q, dtype=float)[None])[0]

    def inverse_dynamics(self, qs, rates, accelerations, gravity: bool = True) -> np.ndarray:
        """τ = M(q)·q̈ + c(q, q̇) + G(q) at every row, by recursive Newton–Euler (complex q allowed).

        Parameters
        ----------
        qs, rates, accelerations : array_like, shape (poses, n) or (n,)
            q, q̇ and q̈; one pose gives one row back as a vector.
        gravity : bool
            Include G(q).
        """
        single = np.ndim(qs) == 1
        qs = np.atleast_2d(np.asarray(qs))
        dtype = np.result_type(qs, float)
        qs = qs.astype(dtype)
        p = len(qs)
        x = self._links(qs)
        s = self._subspaces()
        qd = np.broadcast_to(np.asarray(rates, dtype=dtype), qs.shape)
        qdd = np.broadcast_to(np.asarray(accelerations, dtype=dtype), qs.shape)
        base = np.zeros((p, 6), dtype=dtype)
        if gravity:
            base[:, 3:] = -self.gravity     # the base accelerates up: gravity on every body at once
        v = np.zeros((p, self.dof, 6), dtype=dtype)
        a = np.zeros((p, self.dof, 6), dtype=dtype)
        f = np.zeros((p, self.dof, 6), dtype=dtype)
        for i in range(self.dof):
            parent = self.parents[i]
            vp, ap = (np.zeros((p, 6), dtype=dtype), base) if parent < 0 else (v[:, parent], a[:, parent])
            sqd = s[i] * qd[:, i, None]
            v[:, i] = np.einsum("pij,pj->pi", x[:, i], vp) + sqd
            a[:, i] = np.einsum("pij,pj->pi", x[:, i], ap) + s[i] * qdd[:, i, None] + _cross_motion(v[:, i], sqd)
            iv = v[:, i] @ self.inertias[i].T
            f[:, i] = a[:, i] @ self.inertias[i].T + _cross_force(v[:, i], iv)
        tau = np.zeros((p, self.dof), dtype=dtype)
        for i in range(self.dof - 1, -1, -1):
            tau[:, i] = f[:, i] @ s[i]
            if self.parents[i] >= 0:
                f[:, self.parents[i]] += np.einsum("pji,pj->pi", x[:, i], f[:, i])
        return tau[0] if single else tau

    def potential_energy(self, q) -> np.ndarray:
        """U(q) = −Σ mᵢ·g·cᵢ, gravity's potential energy with the base origin at zero [J]; G = ∂U/∂q.

        Parameters
        ----------
        q : array_like, shape (n,) or (poses, n)
            Joint coordinates.
        """
        single = np.ndim(q) == 1
        qs = np.atleast_2d(np.asarray(q, dtype=float))
        x = self._links(qs)
        world = np.empty_like(x)            # ⁱX_0, each body's frame from the base's
        u = np.zeros(len(qs))
        for i in range(self.dof):
            world[:, i] = x[:, i] if self.parents[i] < 0 else x[:, i] @ world[:, self.parents[i]]
            m, c, _ = body_inertia(self.inertias[i])
            if m == 0.0:
                continue
            rotation = world[:, i, :3, :3].transpose(0, 2, 1)
            px = -rotation @ world[:, i, 3:, :3]
            origin = np.stack([px[:, 2, 1], px[:, 0, 2], px[:, 1, 0]], axis=1)
            u -= m * ((origin + rotation @ c) @ self.gravity)
        return u[0] if single else u

    def gravity_load(self, q) -> np.ndarray:
        """G(q), the joint forces that hold the tree still against gravity (rows of poses too).

        Parameters
        ----------
        q : array_like, shape (n,) or (poses, n)
            Joint coordinates.
        """
        return self.inverse_dynamics(q, 0.0, 0.0).real

    def velocity_load(self, q, rates) -> np.ndarray:
        """c(q, q̇) = C(q, q̇)·q̇, the Coriolis and centrifugal joint forces.

        Parameters
        ----------
        q, rates : array_like, shape (n,) or (poses, n)
            q and q̇.
        """
        return self.inverse_dynamics(q, rates, 0.0, gravity=False).real

    def gravity_stiffness(self, q) -> np.ndarray:
        """∂G/∂q, the stiffness gravity adds about q, by the complex step (exact to rounding).

        G = ∂U/∂q for the potential U, so ∂G/∂q is U's Hessian and symmetric.

        Parameters
        ----------
        q : array_like, shape (n,) or (poses, n)
            Joint coordinates.
        """
        single = np.ndim(q) == 1
        qs = np.atleast_2d(np.asarray(q, dtype=float))
        h = 1e-30                   # no subtraction: the step may be far below rounding
        n = self.dof
        # every pose once per coordinate stepped, in one batch
        stepped = np.repeat(qs.astype(complex), n, axis=0)
        stepped[np.arange(len(stepped)), np.tile(np.arange(n), len(qs))] += 1j * h
        k = (self.inverse_dynamics(stepped, 0.0, 0.0).imag / h).reshape(len(qs), n, n).transpose(0, 2, 1)
        k = 0.5 * (k + k.transpose(0, 2, 1))
        return k[0] if single else k

    @cached_property
    def _shape(self) -> tuple:
        """What the vectorised pass reads of the tree: masks, skews, ancestry and depth levels."""
        n = self.dof
        revolute = np.array([k == "revolute" for k in self.kinds], dtype=float)
        skews = np.array([_skew(np.asarray(a, dtype=float)) for a in self.axes]).reshape(n, 3, 3)
        above = np.eye(n)               # above[i, j]: body i is body j or one of its ancestors
        depth = np.zeros(n, dtype=int)
        for j in range(n):
            if self.parents[j] >= 0:
                above[:, j] += above[:, self.parents[j]]
                depth[j] = depth[self.parents[j]] + 1
        levels = [(np.flatnonzero(depth == d), np.array([self.parents[j] for j in np.flatnonzero(depth == d)]))
                  for d in range(1, depth.max(initial=0) + 1)]
        swapped = self._subspaces()[:, _SWAP]
        return revolute, 1.0 - revolute, skews, skews @ skews, above, levels, swapped

    def _world(self, qs: np.ndarray) -> np.ndarray:
        """ⁱX_0 per pose and body, shape (poses, n, 6, 6): every joint at once, one product per depth."""
        revolute, prismatic, skews, squares, _, levels, _ = self._shape
        angles = qs * revolute
        s, c = np.sin(angles)[..., None, None], np.cos(angles)[..., None, None]
        et = np.eye(3) - s * skews + (1.0 - c) * squares     # Eᵀ: the child's axes turned by q
        x = np.zeros(qs.shape + (6, 6), dtype=et.dtype)
        x[..., :3, :3] = et
        x[..., 3:, 3:] = et
        x[..., 3:, :3] = -(qs * prismatic)[..., None, None] * skews     # a slide: [[1, 0], [−p×, 1]]
        x = x @ self.placements
        for children, parents in levels:        # parents are a level up: already from the base
            x[:, children] = x[:, children] @ x[:, parents]
        return x

    def joint_frames(self, qs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where each joint is at every row of *qs*, in the base frame: its origin, its unit axis and
        its body's centre of mass, each of shape (poses, n, 3) [m].

        Parameters
        ----------
        qs : array_like, shape (poses, n)
            Joint coordinates [rad or m].
        """
        world = self._world(np.atleast_2d(np.asarray(qs, dtype=float)))
        rotation = world[..., :3, :3].transpose(0, 1, 3, 2)        # each body's axes in the base frame
        px = -rotation @ world[..., 3:, :3]
        origin = np.stack([px[..., 2, 1], px[..., 0, 2], px[..., 1, 0]], axis=-1)
        centres = np.array([body_inertia(i)[1] for i in self.inertias])
        return (origin, np.einsum("pnij,nj->pni", rotation, np.asarray(self.axes, dtype=float)),
                origin + np.einsum("pnij,nj->pni", rotation, centres))

    def points(self, qs, bodies, offsets) -> tuple[np.ndarray, np.ndarray]:
        """Points fixed on bodies, in the base frame at every row of *qs*: their positions (poses, k, 3) and
        Jacobians ∂P/∂q (poses, k, 3, n), whose column a is z_a × (P − o_a) for a revolute ancestor a,
        z_a for a prismatic one, and zero for a joint that does not carry the point.

        Parameters
        ----------
        qs : array_like, shape (poses, n)
            Joint coordinates [rad or m].
        bodies : sequence of int
            The body each point is on.
        offsets : array_like, shape (k, 3)
            Each point in its body's frame [m].
        """
        qs = np.atleast_2d(np.asarray(qs, dtype=float))
        world = self._world(qs)
        rotation = world[..., :3, :3].transpose(0, 1, 3, 2)
        px = -rotation @ world[..., 3:, :3]
        origin = np.stack([px[..., 2, 1], px[..., 0, 2], px[..., 1, 0]], axis=-1)
        axes = np.einsum("pnij,nj->pni", rotation, np.asarray(self.axes, dtype=float))
        bodies = list(bodies)
        at = origin[:, bodies] + np.einsum("pkij,kj->pki", rotation[:, bodies], np.asarray(offsets, dtype=float))
        above = self._shape[4]
        jac = np.zeros(at.shape + (self.dof,))
        for c, b in enumerate(bodies):
            for a in np.flatnonzero(above[:, b]):
                jac[:, c, :, a] = np.cross(axes[:, a], at[:, c] - origin[:, a]) if self.kinds[a] == "revolute"                     else axes[:, a]
        return at, jac

    def dynamics(self, qs, rates) -> tuple[np.ndarray, np.ndarray]:
        """(M(q), c(q, q̇) + G(q)) at every row from one kinematics pass, shape ((p, n, n), (p, n)).

        The recursions of :meth:`mass_matrices` and :meth:`inverse_dynamics` written in the
        base frame, where each is a sum over ancestors or descendants: a product with the
        tree's ancestry matrix for all joints and poses at once.

        Parameters
        ----------
        qs, rates : array_like, shape (poses, n)
            q and q̇.
        """
        qs = np.atleast_2d(np.asarray(qs))
        qs = qs.astype(np.result_type(qs, float))
        p, n = qs.shape
        qd = np.broadcast_to(np.asarray(rates, dtype=qs.dtype), qs.shape)
        *_, above, _, swapped = self._shape
        w = self._world(qs)
        wt = w.swapaxes(-1, -2)
        # ⁰X_i = (ⁱX_0)⁻¹ = P·(ⁱX_0)ᵀ·P with P swapping the halves, so S_i in the base is P·(ⁱX_0)ᵀ·P·s_i
        s0 = (wt @ swapped[:, :, None])[..., _SWAP, 0]
        i0 = wt @ self.inertias @ w                                     # inertias about the base origin
        composite = (above @ i0.reshape(p, n, 36)).reshape(p, n, 6, 6)  # each body and its descendants
        f = (composite @ s0[..., None])[..., 0]
        upper = above * (s0 @ f.swapaxes(-1, -2))           # M_ij = S_i·Ic_j·S_j for i at or above j
        m = upper + upper.swapaxes(-1, -2) - upper * np.eye(n)
        sq = s0 * qd[..., None]
        v = above.T @ sq                                    # each body's velocity: its joints' sum
        crm = (v @ _CRM).reshape(p, n, 6, 6)                # v×, the motion cross product as a matrix
        acc = above.T @ (crm @ sq[..., None])[..., 0]       # Ṡ_k = v_k × S_k: the bias accelerations
        acc[..., 3:] -= self.gravity                        # the base accelerates up
        both = i0 @ np.stack([acc, v], axis=-1)
        force = both[..., 0] - (both[..., None, :, 1] @ crm)[..., 0, :]     # I·a + v ×* I·v
        bias = np.einsum("pni,pni->pn", s0, above @ force)
        return m, bias

    def forward_dynamics(self, q, rates, forces) -> np.ndarray:
        """q̈ = M(q)⁻¹·(τ − c(q, q̇) − G(q)) from :meth:`dynamics` (rows of poses too).

        Parameters
        ----------
        q, rates, forces : array_like, shape (n,) or (poses, n)
            q, q̇ and the joint forces τ.
        """
        single = np.ndim(q) == 1
        m, bias = self.dynamics(q, rates)
        accel = np.linalg.solve(m, (np.asarray(forces) - bias)[..., None])[..., 0]
        return accel[0] if single else accel

    def functions(self, damping: np.ndarray) -> MechanicalFunctions:
        """The tree's M, c, G, forward dynamics and potential by these recursions, with dampers *damping*.

        Parameters
        ----------
        damping : ndarray, shape (n, n)
            B.
        """
        gravity = self.gravity_load if np.any(self.gravity) else None
        return MechanicalFunctions(self.mass_matrix, self.velocity_load, gravity, damping, None,
                                   masses=self.mass_matrices, gravities=gravity, forward=self.forward_dynamics,
                                   potential=None if gravity is None else self.potential_energy)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rows of a × b (numpy's cross costs a hundred times more on short rows)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.result_type(a, b))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _cross_motion(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    """v × m for rows of motion vectors [ω; u]: [ω×m_ω; u×m_ω + ω×m_u]."""
    w, u = v[:, :3], v[:, 3:]
    return np.concatenate([_cross(w, m[:, :3]), _cross(u, m[:, :3]) + _cross(w, m[:, 3:])], axis=1)


def _cross_force(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """v ×* f for rows, the force cross product: [ω×f_n + u×f_l; ω×f_l]."""
    w, u = v[:, :3], v[:, 3:]
    return np.concatenate([_cross(w, f[:, :3]) + _cross(u, f[:, 3:]), _cross(w, f[:, 3:])], axis=1)


#: Halves swapped: [ω; v] ↔ [v; ω].
_SWAP = np.array([3, 4, 5, 0, 1, 2])


def _motion_cross_tensor() -> np.ndarray:
    """(6, 36): a motion vector v times it, reshaped (6, 6), is v× = [[ω×, 0], [u×, ω×]]."""
    out = np.zeros((6, 6, 6))
    for b in range(6):
        e = np.zeros(6)
        e[b] = 1.0
        out[b, :3, :3] = out[b, 3:, 3:] = _skew(e[:3])
        out[b, 3:, :3] = _skew(e[3:])
    return out.reshape(6, 36)


_CRM = _motion_cross_tensor()
