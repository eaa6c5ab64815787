"""Robot models whose mass matrices are derived from kinematics: M(q) = Σ m·Jᵀ·J."""

from __future__ import annotations

from typing import Sequence

import numpy as np
import sympy as sp

from .errors import InputError
from .model import Model

__all__ = ["point_mass_matrix", "redundant_actuators", "planar_serial", "serial_2dof",
           "serial_3dof", "numeric_model", "random_spd_model", "ROBOTS", "robot"]


def point_mass_matrix(masses: Sequence, positions: Sequence, q: Sequence) -> sp.Matrix:
    """Mass matrix of point masses: M(q) = Σ_k m_k·J_kᵀ·J_k with J_k = ∂p_k/∂q.

    Parameters
    ----------
    masses : sequence of sympy expressions
    positions : sequence of sympy column vectors p_k(q), any dimension
    q : sequence of sympy symbols
    """
    q = sp.Matrix(list(q))
    m = sp.zeros(len(q))
    for mass, p in zip(masses, positions):
        j = sp.Matrix(p).jacobian(q)
        m += mass * (j.T * j)
    return m.applyfunc(lambda e: sp.trigsimp(sp.expand(e)))


def _symbols(prefix: str, n: int):
    return [sp.Symbol(f"{prefix}{k + 1}", real=True) for k in range(n)]


def redundant_actuators(d1: float = 1.5, d2: float = 1.0, b1: float = 1.0,
                        b2: float = 0.5) -> Model:
    """Two stacked actuators on one axis (paper Fig. 8): stage 1 moves d1 and d2, stage 2 moves d2."""
    q = _symbols("q", 2)
    d, b = _symbols("d", 2), _symbols("b", 2)
    positions = [sp.Matrix([q[0]]), sp.Matrix([q[0] + q[1]])]
    return Model("redundant", point_mass_matrix(d, positions, q), damping=b,
                 parameters={"d1": d1, "d2": d2, "b1": b1, "b2": b2}, coordinates=q,
                 topology="serial",
                 description="redundant actuators on one axis: point masses d1 (stage 1) and d2 (stage 2)")


def planar_serial(n: int, lengths: Sequence[float] | None = None,
                  masses: Sequence[float] | None = None,
                  dampings: Sequence[float] | None = None,
                  stiffnesses: Sequence[float] | None = None) -> Model:
    """Planar nR arm with a point mass d_k at the distal end of link k, joint dampers b_k."""
    if n < 1:
        raise InputError("a serial arm needs at least one joint")
    q, l, d, b = _symbols("q", n), _symbols("l", n), _symbols("d", n), _symbols("b", n)
    positions, x, y, angle = [], 0, 0, 0
    for k in range(n):
        angle += q[k]
        x += l[k] * sp.cos(angle)
        y += l[k] * sp.sin(angle)
        positions.append(sp.Matrix([x, y]))
    lengths = list(lengths) if lengths is not None else [1.0 - 0.2 * k / max(n - 1, 1) for k in range(n)]
    masses = list(masses) if masses is not None else [2.0 / (k + 1) for k in range(n)]
    dampings = list(dampings) if dampings is not None else [1.0 / (k + 1) for k in range(n)]
    for label, vals in (("lengths", lengths), ("masses", masses), ("dampings", dampings)):
        if len(vals) != n:
            raise InputError(f"{label} must have {n} entries, got {len(vals)}")
    params = {}
    for syms, vals in ((l, lengths), (d, masses), (b, dampings)):
        params.update({str(s): float(v) for s, v in zip(syms, vals)})
    stiffness = None
    if stiffnesses is not None:
        k_syms = _symbols("k", n)
        params.update({str(s): float(v) for s, v in zip(k_syms, stiffnesses)})
        stiffness = k_syms
    return Model(f"serial{n}" if n != 2 else "serial2", point_mass_matrix(d, positions, q),
                 damping=b, stiffness=stiffness, parameters=params, coordinates=q,
                 topology="serial",
                 description=f"planar {n}R serial arm, point masses d_k at the end of link k")


def serial_2dof(**kw) -> Model:
    """The 2-DOF serial arm of the MP-model paper (eqs. 17–20): l1 = 1, l2 = 0.8, d1 = 2, d2 = 1."""
    return planar_serial(2, lengths=(1.0, 0.8), masses=(2.0, 1.0), dampings=(1.0, 0.5), **kw)


def serial_3dof(**kw) -> Model:
    """A planar 3R arm: l = (0.6, 0.5, 0.4) m, d = (2, 1.5, 1) kg."""
    return planar_serial(3, lengths=(0.6, 0.5, 0.4), masses=(2.0, 1.5, 1.0),
                         dampings=(1.0, 0.8, 0.5), **kw)


def numeric_model(name: str, mass_matrix, damping=None, stiffness=None,
                  topology: str = "parallel", description: str = "") -> Model:
    """A model with constant numeric matrices (no configuration dependence)."""
    return Model(name, sp.Matrix(np.asarray(mass_matrix, dtype=float).tolist()),
                 damping=None if damping is None else sp.Matrix(np.asarray(damping, dtype=float).tolist())
                 if np.ndim(damping) == 2 else list(map(float, damping)),
                 stiffness=None if stiffness is None else sp.Matrix(np.asarray(stiffness, dtype=float).tolist())
                 if np.ndim(stiffness) == 2 else list(map(float, stiffness)),
                 topology=topology, description=description)


def random_spd_model(n: int, seed: int = 0, topology: str = "serial",
                     stiffness: bool = False) -> Model:
    """A random well-conditioned SPD mass matrix with positive diagonal damping."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    m = a @ a.T / n + np.eye(n)
    b = rng.uniform(0.5, 2.0, size=n)
    k = rng.uniform(1.0, 4.0, size=n) if stiffness else None
    return numeric_model(f"random{n}", m, b, k, topology=topology,
                         description=f"random SPD {n}-DOF (seed {seed})")


def _parallel_2dof() -> Model:
    # Stated numbers for a five-bar at one pose; deriving M(q) from its kinematics is separate work.
    return numeric_model("parallel2", [[0.30, 0.08], [0.08, 0.25]], [0.1, 0.1],
                         description="2-DOF parallel five-bar, stated numeric M at one pose")


def _parallel_3dof() -> Model:
    return numeric_model("parallel3", [[1.2, 0.3, -0.2], [0.3, 0.9, 0.25], [-0.2, 0.25, 0.8]],
                         [0.6, 0.5, 0.4], [2.0, 1.5, 1.0],
                         description="3-DOF parallel mechanism, stated numeric M, with joint springs")


#: Built-in models by name.
ROBOTS = {
    "redundant": redundant_actuators,
    "serial2": serial_2dof,
    "parallel2": _parallel_2dof,
    "serial3": serial_3dof,
    "parallel3": _parallel_3dof,
}


def robot(name: str) -> Model:
    """A built-in model by name (see :data:`ROBOTS`); ``serialN`` gives a planar N-joint arm."""
    if name in ROBOTS:
        return ROBOTS[name]()
    if name.startswith("serial") and name[6:].isdigit() and 1 <= int(name[6:]) <= 50:
        return planar_serial(int(name[6:]))
    raise InputError(f"unknown robot {name!r}: use {', '.join(ROBOTS)} or serialN")
