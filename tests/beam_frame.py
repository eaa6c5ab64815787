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


class Frame:
    """A planar frame of Hermite beams and rigid bars on shared nodes, for closed chains.

    Every node has X and Y; a beam's nodes have a rotation each, and a beam may start on
    another's rotation (a clamp) or on its own (a pin). Rigid bars are inextensible
    two-node members with a uniform bar's mass, m/6·(v1² + v1·v2 + v2²) per direction.
    Extra linear constraints tie a bracket's turn to a beam's root. Gravity's axial forces
    come from the frame's statics (the inextensibility multipliers), so no load path is
    assumed; each member's geometric stiffness is then N·∫v'² (beams) or N/L·(Δv)² (bars).
    """

    def __init__(self):
        self.xy, self.size = [], 0
        self.masses, self.inertias, self.rows, self.locks = [], [], [], []
        self.beams, self.bars, self.rotors, self.ys = [], [], [], set()

    def _dofs(self, count):
        self.size += count
        return list(range(self.size - count, self.size))

    def node(self, xy):
        """A new node at *xy*: its (X, Y) dofs."""
        self.xy.append(np.asarray(xy, dtype=float))
        x, y = self._dofs(2)
        self.ys.add(y)
        return x, y, len(self.xy) - 1

    def rotation(self):
        return self._dofs(1)[0]

    def beam(self, start, rotation, angle, length, rho_a, ei, elements):
        """A beam from node *start* on rotation dof *rotation* along *angle*: its end node and end rotation."""
        h = length / elements
        e = np.array([np.cos(angle), np.sin(angle)])
        node, rot = start, rotation
        for k in range(elements):
            nxt, nrot = self.node(self.xy[start[2]] + (k + 1) * h * e), self.rotation()
            self.beams.append((node, rot, nxt, nrot, angle, h, rho_a, ei))
            node, rot = nxt, nrot
        return node, rot

    def bar(self, a, b, mass):
        self.bars.append((a, b, mass))

    def point(self, node, mass):
        self.masses += [(node[0], mass), (node[1], mass)]

    def inertia(self, dof, value):
        self.inertias.append((dof, value))

    def rotor(self, node, normal, radius, value):
        """A rotor of inertia *value* turning with a bar: node's velocity along *normal* over *radius*."""
        self.rotors.append(([node[0], node[1]], value / radius ** 2 * np.outer(normal, normal)))

    def constrain(self, row):
        """A linear constraint Σ c_k·u_k = 0, given as {dof: c}."""
        self.rows.append(row)

    def hold(self, *dofs):
        """Supports: these dofs are zero."""
        self.rows += [{d: 1.0} for d in dofs]

    def lock(self, row):
        """A motor's lock, {dof: c}: held in the statics, let go by ``frequencies(release=…)``; its index."""
        self.locks.append(row)
        return len(self.locks) - 1

    def _direction(self, a, b):
        d = self.xy[b[2]] - self.xy[a[2]]
        length = np.linalg.norm(d)
        return d / length, length

    def assemble(self):
        n = self.size
        mass, stiff = np.zeros((n, n)), np.zeros((n, n))
        rows = []
        for a, ra, b, rb, angle, h, rho_a, ei in self.beams:
            c, s = np.cos(angle), np.sin(angle)
            rot = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]])
            t = la.block_diag(rot, rot)
            index = [a[0], a[1], ra, b[0], b[1], rb]
            m, k, _ = _element(h, rho_a, ei, 0.0, 0.0)
            mass[np.ix_(index, index)] += t.T @ m @ t
            stiff[np.ix_(index, index)] += t.T @ k @ t
            rows.append({a[0]: -c, a[1]: -s, b[0]: c, b[1]: s})
        for a, b, m in self.bars:
            e, _ = self._direction(a, b)
            for axis in (0, 1):
                i, j = a[axis], b[axis]
                mass[np.ix_([i, j], [i, j])] += m / 6 * np.array([[2.0, 1.0], [1.0, 2.0]])
            rows.append({a[0]: -e[0], a[1]: -e[1], b[0]: e[0], b[1]: e[1]})
        for dof, m in self.masses + self.inertias:
            mass[dof, dof] += m
        for index, block in self.rotors:
            mass[np.ix_(index, index)] += block
        members = len(rows)
        rows += self.rows + self.locks
        constraints = np.zeros((len(rows), n))
        for r, row in enumerate(rows):
            for d, c in row.items():
                constraints[r, d] += c
        return mass, stiff, constraints, members

    def geometric_stiffness(self, tension):
        """Σ N_e·(second variation of each member's length), members in the order of :meth:`assemble`."""
        kg = np.zeros((self.size, self.size))
        for (a, ra, b, rb, angle, h, rho_a, ei), force in zip(self.beams, tension):
            c, s = np.cos(angle), np.sin(angle)
            rot = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]])
            t = la.block_diag(rot, rot)
            index = [a[0], a[1], ra, b[0], b[1], rb]
            _, _, g = _element(h, rho_a, 0.0, force, force)
            kg[np.ix_(index, index)] += t.T @ g @ t
        for (a, b, _), force in zip(self.bars, tension[len(self.beams):]):
            e, length = self._direction(a, b)
            normal = np.array([-e[1], e[0]])
            index = [a[0], a[1], b[0], b[1]]
            kg[np.ix_(index, index)] += force / length * np.kron(np.array([[1.0, -1.0], [-1.0, 1.0]]),
                                                                  np.outer(normal, normal))
        return kg

    def frequencies(self, gravity=0.0, release=()):
        """Natural frequencies [Hz], signed, ascending: the statics under gravity with every
        motor locked (its holding torque then a dead load), the vibration with the locks in
        *release* let go."""
        mass, stiff, constraints, members = self.assemble()
        if gravity:
            load = mass @ np.array([-gravity if d in self.ys else 0.0 for d in range(self.size)])
            rank = constraints.shape[0]
            saddle = np.block([[stiff, constraints.T], [constraints, np.zeros((rank, rank))]])
            solution = np.linalg.solve(saddle, np.concatenate([load, np.zeros(rank)]))
            stiff = stiff + self.geometric_stiffness(solution[self.size:self.size + members])
        first = members + len(self.rows)
        free = [r for r in range(constraints.shape[0]) if r < first or r - first not in release]
        z = la.null_space(constraints[free])
        k, m = z.T @ stiff @ z, z.T @ mass @ z
        rough = la.eigh(k, m, eigvals_only=True, subset_by_index=[0, min(5, k.shape[0] - 1)])
        shift = 1.0 + 2.0 * float(np.max(np.abs(rough)))
        w2 = np.sort(1.0 / la.eigh(m, k + shift * m, eigvals_only=True) - shift)
        return np.sign(w2) * np.sqrt(np.abs(w2)) / (2 * np.pi)
