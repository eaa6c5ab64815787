"""Natural frequencies and damping ratios of a linear system at its configuration."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg as la

from ..errors import InputError
from .output import Tabular, html_table

__all__ = ["Modes", "natural_modes"]


@dataclass(eq=False)
class Modes(Tabular):
    """The modes of K·φ = ω²·M·φ, with each mode's damping ratio.

    Attributes
    ----------
    omega : ndarray
        Undamped natural frequencies [rad/s], ascending; 0 for a rigid-body mode and the
        growth rate √|ω²| for an unstable one.
    omega_squared : ndarray
        The generalised eigenvalues ω² (negative: unstable).
    damping_ratio : ndarray
        Modal damping φᵀBφ / (2ω) of M-normalised shapes (exact when B is a combination
        of M and K; NaN for a rigid-body mode).
    shapes : ndarray, shape (n, modes)
        M-normalised mode shapes in the free joints' coordinates.
    free : tuple of int
        The joints (1-based) that move; the others are locked.
    """

    omega: np.ndarray
    omega_squared: np.ndarray
    damping_ratio: np.ndarray
    shapes: np.ndarray
    free: tuple

    @property
    def unstable(self) -> np.ndarray:
        """True for modes with ω² < 0: the configuration is not a stable equilibrium."""
        return self.omega_squared < 0

    def columns(self) -> dict[str, np.ndarray]:
        """``mode``, ``omega_rad_s``, ``f_hz`` and ``damping_ratio``, one row per mode."""
        return {"mode": np.arange(1, self.omega.size + 1), "omega_rad_s": self.omega,
                "f_hz": self.omega / (2 * math.pi), "damping_ratio": self.damping_ratio}

    def table(self) -> str:
        """A plain-text table of the modes, unstable ones marked."""
        lines = [f"free joints {', '.join(map(str, self.free))}",
                 f"{'mode':>4}{'omega [rad/s]':>16}{'f [Hz]':>14}{'damping ratio':>15}"]
        for k, (w, z, bad) in enumerate(zip(self.omega, self.damping_ratio, self.unstable)):
            note = "  unstable (growth rate)" if bad else ("  rigid body" if w == 0 else "")
            lines.append(f"{k + 1:>4}{w:>16.8g}{w / (2 * math.pi):>14.6g}{z:>15.6g}{note}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def __repr__(self) -> str:
        marks = f", {int(self.unstable.sum())} unstable" if self.unstable.any() else ""
        return f"<Modes {self.omega.size}: omega {np.array2string(self.omega, precision=4)} rad/s{marks}>"

    def _repr_html_(self) -> str:
        return html_table(["mode", "omega [rad/s]", "f [Hz]", "damping ratio"],
                          [[k + 1, float(w), float(w / (2 * math.pi)), float(z)]
                           for k, (w, z) in enumerate(zip(self.omega, self.damping_ratio))])


def natural_modes(joint, locked: Sequence[int] = ()) -> Modes:
    """The natural modes of a joint space (M, B, K) with some joints held clamped.

    Parameters
    ----------
    joint : JointSpace
        M, B and K at the configuration.
    locked : sequence of int
        Joints (1-based) held fixed.
    """
    n = joint.dof
    bad = [j for j in locked if not 1 <= j <= n]
    if bad:
        raise InputError(f"cannot lock joint {bad[0]}: the system has joints 1 to {n}")
    free = tuple(j for j in range(1, n + 1) if j not in set(locked))
    if not free:
        raise InputError("every joint is locked: nothing can move")
    idx = [j - 1 for j in free]
    m = joint.mass_matrix[np.ix_(idx, idx)]
    k = np.zeros_like(m) if joint.stiffness is None else joint.stiffness[np.ix_(idx, idx)]
    b = joint.damping[np.ix_(idx, idx)]
    w2, shapes = la.eigh(k, m)              # M-normalised: shapesᵀ·M·shapes = I
    scale = max(float(np.max(np.abs(w2))), 1e-300)
    w2 = np.where(np.abs(w2) <= 1e-12 * scale, 0.0, w2)
    omega = np.sqrt(np.abs(w2))
    modal_b = np.einsum("ik,ij,jk->k", shapes, b, shapes)
    with np.errstate(divide="ignore", invalid="ignore"):
        zeta = np.where(omega > 0, modal_b / (2 * omega), np.nan)
    return Modes(omega, w2, zeta, shapes, free)
