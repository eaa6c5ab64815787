"""Natural frequencies and damping ratios of a linear system at its configuration."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg as la

from ..errors import InputError
from .output import Tabular, html_table

__all__ = ["Modes", "natural_modes", "system_poles"]


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
    poles : ndarray of complex
        The 2n roots s of det(M·s² + B·s + K) = 0, as python-control's ``damp`` lists
        them: a pair per oscillating mode, real ones where damping wins or no spring holds
        (s = 0 for a free rigid body).
    joints : tuple of str or None
        Every joint's own name (a URDF robot's), for the table and the shape columns; None: 1 … n.
    """

    omega: np.ndarray
    omega_squared: np.ndarray
    damping_ratio: np.ndarray
    shapes: np.ndarray
    free: tuple
    poles: np.ndarray = None
    joints: tuple | None = None

    @property
    def unstable(self) -> np.ndarray:
        """True for modes with ω² < 0: the configuration is not a stable equilibrium."""
        return self.omega_squared < 0

    def columns(self) -> dict[str, np.ndarray]:
        """``mode``, ``omega_rad_s``, ``f_hz``, ``damping_ratio``, ``kind``, then each free joint's
        share of the M-normalised shape (``shape_<joint>``), one row per mode."""
        cols = {"mode": np.arange(1, self.omega.size + 1), "omega_rad_s": self.omega,
                "f_hz": self.omega / (2 * math.pi), "damping_ratio": self.damping_ratio,
                "kind": np.array(["unstable" if bad else "rigid body" if w == 0 else "oscillating"
                                  for w, bad in zip(self.omega, self.unstable)])}
        cols.update((f"shape_{name}", self.shapes[k]) for k, name in enumerate(self._free_names()))
        return cols

    def _free_names(self) -> list[str]:
        """The free joints' names: their own, or q1 … by number."""
        return [self.joints[j - 1] if self.joints else f"q{j}" for j in self.free]

    def table(self) -> str:
        """A plain-text table of the modes, unstable ones marked."""
        named = "" if not self.joints else " (" + ", ".join(self._free_names()) + ")"
        lines = [f"free joints {', '.join(map(str, self.free))}{named}",
                 f"{'mode':>4}{'omega [rad/s]':>16}{'f [Hz]':>14}{'damping ratio':>15}"]
        for k, (w, z, bad) in enumerate(zip(self.omega, self.damping_ratio, self.unstable)):
            note = "  unstable (growth rate)" if bad else ("  rigid body" if w == 0 else "")
            zeta = f"{z:>15.6g}" if np.isfinite(z) else f"{'-':>15}"
            lines.append(f"{k + 1:>4}{w:>16.8g}{w / (2 * math.pi):>14.6g}{zeta}{note}")
        if self.poles is not None:
            lines += ["poles s of det(M s^2 + B s + K) = 0 (as python-control's damp):",
                      f"{'pole s [1/s]':>30}{'|s| [rad/s]':>14}{'damping':>11}   what it does"]
            for s in self.poles:
                lines.append(f"{_pole_text(s):>30}{abs(s):>14.6g}{_pole_damping(s):>11}   {_pole_kind(s)}")
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


def _pole_text(s: complex) -> str:
    return f"{s.real:.6g}" if s.imag == 0 else f"{s.real:.6g} {'+' if s.imag > 0 else '-'} {abs(s.imag):.6g}j"


def _pole_damping(s: complex) -> str:
    return "-" if s == 0 else f"{-s.real / abs(s) + 0.0:.4g}"      # + 0.0: no "-0"


def _pole_kind(s: complex) -> str:
    if s == 0:
        return "rigid body: no spring holds it"
    if s.real > 0:
        return f"unstable: grows as e^({s.real:.4g} t)"
    if s.imag == 0:
        return f"real: decays with time constant {-1 / s.real:.4g} s"
    return f"oscillates at {abs(s.imag) / (2 * math.pi):.4g} Hz, decays with time constant {-1 / s.real:.4g} s" \
        if s.real < 0 else f"oscillates at {abs(s.imag) / (2 * math.pi):.4g} Hz, undamped"


def system_poles(m: np.ndarray, b: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The 2n roots of det(M·s² + B·s + K) = 0: eigenvalues of the first-order form, sorted by |s|.

    Parameters
    ----------
    m, b, k : ndarray, shape (n, n)
        Mass, damping and stiffness (M positive definite).
    """
    n = m.shape[0]
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-la.solve(m, k), -la.solve(m, b)]])
    s = la.eigvals(a)
    scale = max(float(np.max(np.abs(s))), 1e-300)
    # rounding of a real pole leaves an imaginary part of order ε·|A|; a zero pole the same
    tiny = 1e3 * np.finfo(float).eps * scale
    s = np.where(np.abs(s.imag) <= tiny, s.real + 0j, s)
    s = np.where(np.abs(s.real) <= tiny, 0.0 + 1j * s.imag + 0.0, s)
    return s[np.lexsort((s.imag, np.abs(s)))]


def natural_modes(joint, locked: Sequence[int] = (), joints: Sequence[str] | None = None) -> Modes:
    """The natural modes of a joint space (M, B, K) with some joints held clamped.

    Parameters
    ----------
    joint : JointSpace
        M, B and K at the configuration.
    locked : sequence of int
        Joints (1-based) held fixed.
    joints : sequence of str, optional
        Every joint's own name.
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
    return Modes(omega, w2, zeta, shapes, free, system_poles(m, b, k), None if joints is None else tuple(joints))
