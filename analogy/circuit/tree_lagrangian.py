"""A rigid tree's node Lagrangian as a chain of shared subexpressions: poses, velocities, momenta, M(q).

Writing M(q) and the Christoffel terms of a 6- or 7-joint arm out in full gives n³
terms of large expressions. Here every intermediate quantity of the spatial-algebra
recursions is one shared expression (in the circuit, one behavioural node), each a few
products of the ones before. All vectors are in the base frame, about its origin, as
motion [ω; u] and force [n; f] pairs:

- body k's rotation R_k, origin p_k, joint axis z_k and motion subspace
  S_k = [z_k; p_k × z_k] (revolute) or [0; z_k] (prismatic);
- its velocity V_k = V_λ(k) + S_k·r_k and momentum h_k = [Ī_k·ω + c_k × L_k; L_k],
  L_k = m_k·(u + ω × c_k);
- the subtree's momentum H_k = h_k + Σ H_children, and its composite inertia (m, first
  moment f, inertia J about the origin), whose force on a motion S is
  F = [J·ω + f × u; m·u + ω × f];
- M_ab = S_a·F_b for a on b's path to the base;
- ∂T/∂q_a = (V_λ(a) × S_a)·H_a: a change of q_a turns a's subtree rigidly by S_a,
  which changes each body's velocity by S_a × (V_k − V_λ(a)) and its kinetic energy by
  h_k·(V_λ(a) × S_a);
- G_a = ∂U/∂q_a = −g·(linear part of S_a's composite force).

So the node load is h' = T⁻ᵀ·(G − ∂T/∂q), the Lagrange form the charge-defined
capacitors Q = c(x)·Δv need.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from ..model.contact import contact_force, friction_force
from ..model.rigid_tree import body_inertia, placement_frame

__all__ = ["tree_lagrangian"]

#: Rotation and offset entries within this many roundings of zero are zero (an axis
#: cos(π/2) = 6e-17 would otherwise add a term to every expression it meets).
_ROUNDINGS = 4


class _Program:
    """Shared subexpressions in evaluation order: each a symbol e1, e2 … and its expression."""

    def __init__(self):
        self.shared: list = []

    def let(self, expr, name: str | None = None):
        expr = sp.sympify(expr)
        scaled = expr.is_Mul and len(expr.args) == 2 and expr.args[0].is_Number and expr.args[1].is_Symbol
        if name is None and (expr.is_Number or expr.is_Symbol or scaled):
            return expr                 # a number, a symbol or a scaled copy costs less inline than as a node
        symbol = sp.Symbol(name or f"e{len(self.shared) + 1}", real=True)
        self.shared.append((symbol, expr))
        return symbol

    def vector(self, entries) -> list:
        return [self.let(e) for e in entries]

    def symmetric(self, matrix) -> sp.Matrix:
        """A symmetric 3×3 matrix from its upper triangle, each entry shared once."""
        upper = {(i, j): self.let(matrix[i, j]) for i in range(3) for j in range(i, 3)}
        return sp.Matrix(3, 3, lambda i, j: upper[min(i, j), max(i, j)])


def _cross(a, b) -> list:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dot(a, b):
    return sum((x * y for x, y in zip(a, b)), sp.S.Zero)


def _matvec(m, v) -> list:
    return [_dot(row, v) for row in m]


def _clean(values: np.ndarray, scale: float) -> list:
    """Numbers as sympy Floats, those within rounding of zero as exact zeros."""
    floor = _ROUNDINGS * np.finfo(float).eps * scale
    return [sp.S.Zero if abs(x) <= floor else sp.Integer(int(x)) if x in (-1.0, 1.0) else sp.Float(float(x))
            for x in np.ravel(values)]


def _constants(tree):
    """Per joint: rotation E and offset p of its frame in its parent's, and the body's m, c, Ī."""
    frames = [placement_frame(x) for x in tree.placements]
    reach = max(1.0, *(np.abs(p).max() for _, p in frames))
    out = []
    for (e, offset), inertia in zip(frames, tree.inertias):
        m, com, at_com = body_inertia(inertia)
        out.append((np.array(_clean(e, 1.0)).reshape(3, 3), _clean(offset, reach), m,
                    _clean(com, reach), np.array(_clean(at_com, np.abs(at_com).max(initial=0.0))).reshape(3, 3)))
    return out


def _frames(tree, prog: _Program, consts: list, q: list, r: list) -> tuple[list, list, list, list, list]:
    """Each body's rotation and origin in the base, its angular and linear velocity, and its joint's
    motion subspace (angular, linear), root to leaves, as shared subexpressions of *prog*."""
    zero3 = [sp.S.Zero] * 3
    rot, pos, omega, u, subspace = [], [], [], [], []
    for k in range(tree.dof):
        e, offset, _, _, _ = consts[k]
        parent = tree.parents[k]
        if parent < 0:
            r_parent, p_parent, w_parent, u_parent = sp.eye(3), zero3, zero3, zero3
        else:
            r_parent, p_parent, w_parent, u_parent = rot[parent], pos[parent], omega[parent], u[parent]
        axis = _clean(tree.axes[k], 1.0)
        joint = r_parent * sp.Matrix(e)            # the joint frame's axes in the base
        z = prog.vector(_matvec(joint.tolist(), axis))
        p = prog.vector([a + b for a, b in zip(p_parent, _matvec(r_parent.tolist(), offset))])
        if tree.kinds[k] == "revolute":
            c, s = prog.let(sp.cos(q[k])), prog.let(sp.sin(q[k]))
            kx = sp.Matrix([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
            turn = sp.eye(3) + s * kx + (1 - c) * kx * kx
            body = sp.Matrix(3, 3, prog.vector(list(r_parent * (sp.Matrix(e) * turn).applyfunc(sp.expand))))
            s6 = (z, prog.vector(_cross(p, z)))
        else:
            body = sp.Matrix(3, 3, prog.vector(list(joint)))
            p = prog.vector([a + b * q[k] for a, b in zip(p, z)])
            s6 = (zero3, z)
        rot.append(body)
        pos.append(p)
        subspace.append(s6)
        omega.append(prog.vector([a + b * r[k] for a, b in zip(w_parent, s6[0])]))
        u.append(prog.vector([a + b * r[k] for a, b in zip(u_parent, s6[1])]))
    return rot, pos, omega, u, subspace


def tree_lagrangian(tree, q0, inverse: np.ndarray, x: list, v: list, contacts=(), ground=None) -> tuple:
    """(M'(x), h(x, v), shared) of a rigid tree in node coordinates q = q0 + T⁻¹x, r = T⁻¹v.

    A contact point P on body b (:class:`~analogy.model.tree_contact.TreeContact`) meets the ground
    z = 0: its normal force f (:func:`~analogy.model.contact.contact_force` of p = −P_z and ṗ = −Ṗ_z,
    Ṗ = u_b + ω_b × P) is the shared node ``f_<name>``, friction along the ground
    (:func:`~analogy.model.contact.friction_force`) opposes Ṗ_x, Ṗ_y, and each joint a that carries b
    feels S_a·[P × F; F] with F = (fx, fy, f).

    Parameters
    ----------
    tree : RigidTree
        The bodies, joints and gravity.
    q0 : array_like
        The configuration at x = 0.
    inverse : ndarray
        T⁻¹.
    x, v : list of sympy Symbol
        Node positions and rates.
    contacts : sequence of TreeContact
        Points that meet the ground.
    ground : mapping, optional
        The ground's ``kc``, ``cc``, ``delta`` and ``mu`` (with *contacts*).
    """
    n = tree.dof
    prog = _Program()
    tinv = [_clean(row, 0.0) for row in np.asarray(inverse)]
    q = [sp.Float(float(q0[j])) + _dot(tinv[j], x) for j in range(n)]
    r = [_dot(tinv[j], v) for j in range(n)]
    consts = _constants(tree)
    rot, pos, omega, u, subspace = _frames(tree, prog, consts, q, r)

    # bodies: centre of mass, inertia and momentum in the base frame
    com, inertia, momentum = [], [], []
    for k in range(n):
        _, _, m, c_local, at_com = consts[k]
        c = prog.vector([a + b for a, b in zip(pos[k], _matvec(rot[k].tolist(), c_local))])
        ibar = rot[k] * sp.Matrix(at_com) * rot[k].T
        ibar = prog.symmetric(ibar.applyfunc(sp.expand))
        linear = prog.vector([m * a for a in (sp.Matrix(u[k]) + sp.Matrix(_cross(omega[k], c)))])
        angular = prog.vector([a + b for a, b in zip(_matvec(ibar.tolist(), omega[k]), _cross(c, linear))])
        com.append(c)
        inertia.append((m, ibar))
        momentum.append(angular + linear)

    # subtrees, leaves first: composite inertia and momentum
    children = [[j for j in range(n) if tree.parents[j] == k] for k in range(n)]
    sub_mass, first, rotational, total = [0.0] * n, [None] * n, [None] * n, [None] * n
    for k in range(n - 1, -1, -1):
        m, ibar = inertia[k]
        c = sp.Matrix(com[k])
        own = ibar + m * ((c.T * c)[0] * sp.eye(3) - c * c.T)
        sub_mass[k] = m + sum(sub_mass[j] for j in children[k])
        first[k] = prog.vector([m * c[i] + sum(first[j][i] for j in children[k]) for i in range(3)])
        rotational[k] = prog.symmetric(own + sum((rotational[j] for j in children[k]), sp.zeros(3, 3)))
        total[k] = prog.vector([momentum[k][i] + sum(total[j][i] for j in children[k]) for i in range(6)])

    def composite_force(b, s6):
        w, uu = s6
        return (prog.vector([a + f for a, f in zip(_matvec(rotational[b].tolist(), w), _cross(first[b], uu))]),
                prog.vector([sub_mass[b] * a + f for a, f in zip(uu, _cross(w, first[b]))]))

    mass = sp.zeros(n, n)
    forces = [composite_force(b, subspace[b]) for b in range(n)]
    for b in range(n):
        a = b
        while a >= 0:
            mass[a, b] = mass[b, a] = prog.let(_dot(subspace[a][0], forces[b][0]) + _dot(subspace[a][1], forces[b][1]),
                                               f"m{a + 1}_{b + 1}")
            a = tree.parents[a]
    g = _clean(tree.gravity, 1.0)
    load = []
    for a in range(n):
        parent = tree.parents[a]
        w, uu = subspace[a]
        if parent < 0:
            dtdq = sp.S.Zero                # the whole tree turns: T does not change
        else:
            wp, up = omega[parent], u[parent]
            moved = (_cross(wp, w), [x + y for x, y in zip(_cross(wp, uu), _cross(up, w))])
            dtdq = _dot(moved[0], total[a][:3]) + _dot(moved[1], total[a][3:])
        load.append(-_dot(g, forces[a][1]) - dtdq)
    for contact in contacts:
        b = contact.body
        point = prog.vector([a + d for a, d in zip(pos[b], _matvec(rot[b].tolist(), _clean(contact.offset, 1.0)))])
        velocity = prog.vector([a + c for a, c in zip(u[b], _cross(omega[b], point))])
        normal = prog.let(contact_force(-point[2], -velocity[2], ground["kc"], ground["cc"], ground["delta"]),
                          f"f_{contact.name}")
        force = [*prog.vector(friction_force(normal, velocity[0], velocity[1], ground["mu"])), normal] \
            if ground["mu"] else [sp.S.Zero, sp.S.Zero, normal]
        moment = _cross(point, force)
        a = b
        while a >= 0:                       # S_a·[P × F; F]
            w, uu = subspace[a]
            load[a] = load[a] - _dot(w, moment) - _dot(uu, force)
            a = tree.parents[a]
    ti = sp.Matrix(tinv)
    return ti.T * mass * ti, ti.T * sp.Matrix(load), tuple(prog.shared)
