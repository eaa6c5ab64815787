"""Planar serial arms of any length, evaluated numerically: M = Σ d_k·J_kᵀJ_k and G = ∂U/∂q without sympy."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .base import RobotModel
from .joint import JointStack, configuration_stack, evaluation_arguments

__all__ = ["SerialChain", "serial_defaults"]


def serial_defaults(n: int) -> dict[str, float]:
    """The parameters of ``serial<n>``: l_k = 1 − 0.2·(k−1)/(n−1) m, d_k = 2/k kg, b_k = 1/k N·m·s/rad, g = 0.

    Parameters
    ----------
    n : int
        Number of joints.
    """
    out = {f"l{k + 1}": 1.0 - 0.2 * k / max(n - 1, 1) for k in range(n)}
    out.update({f"d{k + 1}": 2.0 / (k + 1) for k in range(n)})
    out.update({f"b{k + 1}": 1.0 / (k + 1) for k in range(n)})
    out["g"] = 0.0
    return out


class SerialChain(RobotModel):
    """The planar nR arm of :func:`~analogy.model.robots.planar_serial`, numerically.

    Point mass d_k at the end of link k, at p_k = Σ_{i≤k} l_i·(cos θ_i, sin θ_i) with
    θ_i = q_1 + … + q_i. Column j of its Jacobian is Σ_{j≤i≤k} l_i·(−sin θ_i, cos θ_i),
    so with the suffix sums S_j = Σ_{k≥j} d_k and u_i = l_i·(−sin θ_i, cos θ_i),

        M_jm = Σ_{i,i'} S_{max(i,i',j,m)} · u_i·u_i'   (i ≥ j, i' ≥ m),

    evaluated with cumulative sums in O(n²) per configuration. Gravity along −y gives
    G_j = g·Σ_{i≥j} S_i·l_i·cos θ_i and the linearised stiffness ∂G_j/∂q_m =
    −g·Σ_{i≥max(j,m)} S_i·l_i·sin θ_i. Its linear parts only (:class:`~analogy.model.base.RobotModel`).

    Parameters
    ----------
    n : int
        Number of joints.
    """

    topology = "serial"

    def __init__(self, n: int):
        self.n = int(n)
        self.name = f"serial{self.n}"
        self.parameters = serial_defaults(self.n)
        self.coordinates = tuple(f"q{k + 1}" for k in range(self.n))
        self.description = f"planar {self.n}R serial arm, point masses d_k at the end of link k"
        self.joints = ("revolute",) * self.n
        self.units = ("rad",) * self.n

    def __repr__(self) -> str:
        return f"SerialChain({self.n} joints, numeric)"

    @property
    def dof(self) -> int:
        return self.n

    def _values(self, parameters):
        args = evaluation_arguments(self.name, (), self.parameters, None, parameters)
        p = dict(zip(self.parameters, args))
        n = self.n
        return (np.array([p[f"l{k + 1}"] for k in range(n)]), np.array([p[f"d{k + 1}"] for k in range(n)]),
                np.array([p[f"b{k + 1}"] for k in range(n)]), p["g"])

    def joint_stack(self, qs, parameters: Mapping[str, float] | None = None) -> JointStack:
        """M, B, K, G at every row of *qs*.

        Parameters
        ----------
        qs : array_like, shape (count, n)
            Configurations.
        parameters : mapping, optional
            Parameter overrides.
        """
        q = configuration_stack(self.name, self.coordinates, qs)
        lengths, masses, damping, g = self._values(parameters)
        theta = np.cumsum(q, axis=1)
        ux, uy = -lengths * np.sin(theta), lengths * np.cos(theta)     # (count, n)
        suffix = np.cumsum(masses[::-1])[::-1]                          # S_i = Σ_{k≥i} d_k
        # M_jm = Σ_{i≥j, i'≥m} S_max(i,i') (u_i·u_i'): the pair term summed over its upper block
        pair = suffix[np.maximum.outer(np.arange(self.n), np.arange(self.n))]
        w = pair * (ux[:, :, None] * ux[:, None, :] + uy[:, :, None] * uy[:, None, :])
        mass = np.cumsum(np.cumsum(w[:, ::-1, ::-1], axis=1), axis=2)[:, ::-1, ::-1]
        mass = 0.5 * (mass + np.swapaxes(mass, 1, 2))
        count = q.shape[0]
        b = np.broadcast_to(np.diag(damping), (count, self.n, self.n)).copy()
        if g == 0.0:
            return JointStack(mass, b, None, None)
        gravity = g * np.cumsum((suffix * uy)[:, ::-1], axis=1)[:, ::-1]
        bend = g * np.cumsum((suffix * ux)[:, ::-1], axis=1)[:, ::-1]   # −g·Σ_{i≥j} S_i l_i sin θ_i
        stiffness = bend[:, np.maximum.outer(np.arange(self.n), np.arange(self.n))]
        return JointStack(mass, b, stiffness.reshape(count, self.n, self.n), gravity)
