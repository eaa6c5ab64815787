"""A planar frame of Hermite beam elements: a finite-element model of the flexible arms, independent of assumed modes.

Each link is cut into equal Euler–Bernoulli elements with three degrees of freedom per
node (X, Y and the section's rotation φ), cubic Hermite bending, linear axial motion and
consistent mass. The links are inextensible, as the assumed modes take them: each
element's two ends keep their distance (a constraint, eliminated by its null space). A link's first node shares X and Y with the previous
link's last node (the joint is a pin); a locked joint also shares φ (a clamp: the slope
is continuous), a free one gives each side its own φ. The first joint's base is pinned
to the ground, or clamped when locked.

Gravity's geometric stiffness is the second variation of its potential over an
inextensible link: ½∫N(x)·v'(x)² dx, with the axial force N(x) = −g·m(x)·sin α, where
m(x) is the mass beyond x and α the link's direction.
"""

from typing import Sequence

import numpy as np
import scipy.linalg as la

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(4)
_GAUSS_X, _GAUSS_W = 0.5 * (_GAUSS_X + 1.0), 0.5 * _GAUSS_W


def _hermite(xi, h):
    """Values and first and second x-derivatives of the four Hermite functions at ξ = x/h."""
    n = np.array([1 - 3 * xi ** 2 + 2 * xi ** 3, h * (xi - 2 * xi ** 2 + xi ** 3), 3 * xi ** 2 - 2 * xi ** 3,
                  h * (-xi ** 2 + xi ** 3)])
    d1 = np.array([(-6 * xi + 6 * xi ** 2) / h, 1 - 4 * xi + 3 * xi ** 2, (6 * xi - 6 * xi ** 2) / h,
                   -2 * xi + 3 * xi ** 2])
    d2 = np.array([(-6 + 12 * xi) / h ** 2, (-4 + 6 * xi) / h, (6 - 12 * xi) / h ** 2, (-2 + 6 * xi) / h])
    return n, d1, d2


def _element(h, rho_a, ei, axial_start, axial_end):
    """Local mass, stiffness and geometric stiffness (u1, v1, φ1, u2, v2, φ2) of one element.

    The axial force runs linearly from *axial_start* to *axial_end*; four Gauss points
    integrate every product exactly.
    """
    m, k, kg = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros((6, 6))
    bend = [1, 2, 4, 5]
    for xi, w in zip(_GAUSS_X, _GAUSS_W):
        n, d1, d2 = _hermite(xi, h)
        lin = np.array([1 - xi, xi])
        force = axial_start + (axial_end - axial_start) * xi
        m[np.ix_(bend, bend)] += w * h * rho_a * np.outer(n, n)
        m[np.ix_([0, 3], [0, 3])] += w * h * rho_a * np.outer(lin, lin)
        k[np.ix_(bend, bend)] += w * h * ei * np.outer(d2, d2)
        kg[np.ix_(bend, bend)] += w * h * force * np.outer(d1, d1)
    return m, k, kg


def frame_frequencies(links: Sequence, angles: Sequence[float], *, gravity: float = 0.0,
                      locked: Sequence[int] = (), elements: int = 50) -> np.ndarray:
    """The natural frequencies [Hz] of a planar chain of flexible links, ascending, rigid-body modes (0) included.

    *links* are ``FlexibleLink``s (length, rho_a, ei, hub_inertia, tip_mass, tip_inertia
    are read); *angles* are the joint angles, link k pointing along θ_1 + … + θ_k in the
    undeformed pose; *locked* lists the clamped joints (1-based); gravity acts along −y.
    """
    alphas = np.cumsum(angles)
    nodes = len(links) * elements + 1
    # φ columns: one per node, plus one for each free joint's far side (k > 1)
    dof = 3 * nodes + sum(1 for k in range(2, len(links) + 1) if k not in locked)
    mass, stiff = np.zeros((dof, dof)), np.zeros((dof, dof))
    stretch = np.zeros((len(links) * elements, dof))
    extra = 3 * nodes
    beyond = [sum(ln.rho_a * ln.length + ln.tip_mass for ln in links[i + 1:]) for i in range(len(links))]
    for i, (ln, alpha) in enumerate(zip(links, alphas)):
        h = ln.length / elements
        c, s = np.cos(alpha), np.sin(alpha)
        rot = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]])
        t = la.block_diag(rot, rot)
        first = i * elements
        base_phi = 3 * first + 2
        if i > 0 and (i + 1) not in locked:
            base_phi, extra = extra, extra + 1
        mass[base_phi, base_phi] += ln.hub_inertia
        for e in range(elements):
            a, b = first + e, first + e + 1
            index = [3 * a, 3 * a + 1, base_phi if e == 0 else 3 * a + 2, 3 * b, 3 * b + 1, 3 * b + 2]
            load = [-gravity * np.sin(alpha) * (ln.rho_a * (ln.length - x) + ln.tip_mass + beyond[i])
                    for x in (e * h, (e + 1) * h)]
            m, k, kg = _element(h, ln.rho_a, ln.ei, *load)
            mass[np.ix_(index, index)] += t.T @ m @ t
            stretch[first + e, index] = (t[3] - t[0])         # u2 − u1 in the global X, Y
            stiff[np.ix_(index, index)] += t.T @ (k + kg) @ t
        tip = first + elements
        mass[3 * tip, 3 * tip] += ln.tip_mass
        mass[3 * tip + 1, 3 * tip + 1] += ln.tip_mass
        mass[3 * tip + 2, 3 * tip + 2] += ln.tip_inertia
    held = [0, 1] + ([2] if 1 in locked else [])
    keep = [d for d in range(dof) if d not in held]
    z = la.null_space(stretch[:, keep])
    k, m = z.T @ stiff[np.ix_(keep, keep)] @ z, z.T @ mass[np.ix_(keep, keep)] @ z
    # eigh(K, M) resolves ω² only to ε·ω²_max, about 1e-4 of the lowest modes' ω² at 50
    # elements a link. Shifted and inverted, 1/(ω² + σ) of the lowest modes are the largest
    # eigenvalues and come out to ε relative to themselves.
    rough = la.eigh(k, m, eigvals_only=True, subset_by_index=[0, min(5, k.shape[0] - 1)])
    shift = 1.0 + 2.0 * float(np.max(np.abs(rough)))
    w2 = np.sort(1.0 / la.eigh(m, k + shift * m, eigvals_only=True) - shift)
    return np.sign(w2) * np.sqrt(np.abs(w2)) / (2 * np.pi)
