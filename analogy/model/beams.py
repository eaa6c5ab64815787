"""Assumed modes of a flexible link: exact eigenfunctions of a clamped Euler–Bernoulli beam, bare or tip-loaded.

A link of length L, mass per length ρA and bending stiffness EI, clamped at its
joint, vibrates as w(x, t) = Σ φ_k(x)·δ_k(t). With ξ = x/L and λ⁴ = ρA·ω²·L⁴/EI,

    φ(ξ) = (cosh λξ − cos λξ) + b·(sinh λξ − sin λξ),

which is clamped at ξ = 0 for any b. A tip mass M and rotary inertia J (the next
joint's motor, or the payload) give, by Hamilton's principle, the natural conditions
EI·w''(L) = J·ω²·w'(L) and EI·w'''(L) = −M·ω²·w(L); in ξ, φ'' = j·λ⁴·φ' and
φ''' = −μ·λ⁴·φ at ξ = 1, with μ = M/(ρA·L) and j = J/(ρA·L³). The roots λ_k of their
determinant are the frequency equation; μ = j = 0 is the clamped-free cantilever,
1 + cos λ·cosh λ = 0.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np
from scipy.optimize import brentq

from ..errors import InputError

__all__ = ["MAX_BEAM_MODES", "Normalisation", "BeamModes", "frequency_equation", "frequency_roots", "beam_modes", "gauss_points"]

#: Most assumed modes per link: the 96-point quadrature of the modal matrices is tested to this many.
MAX_BEAM_MODES = 16
#: How mode shapes are scaled: ∫ρA·φ² dx + M·φ(L)² + J·φ'(L)² = 1 kg, or = ρA·L (the link's mass).
Normalisation = Literal["unit", "link-mass"]


def frequency_equation(lam: float, mass_ratio: float = 0.0, inertia_ratio: float = 0.0) -> float:
    """The frequency equation of a clamped link with a tip load, over cosh λ (zero at the modes' λ).

    The tip conditions (bending moment φ'' − jλ⁴φ' and shear φ''' + μλ⁴φ, both zero at the
    tip) on φ = (cosh − cos) + b·(sinh − sin) have the determinant 2λ·D(λ), with

        D = 1 + cos·cosh + μλ(cos·sinh − sin·cosh) − jλ³(sin·cosh + cos·sinh) + μjλ⁴(1 − cos·cosh)

    (``tests/test_beams.py`` derives it). D / cosh λ has terms of size 1, μλ, jλ³ and μjλ⁴
    only. The determinant's entries are of size cosh λ, and forming it first cancels
    cosh² λ down to 1, which costs e^λ·ε in the root.

    Parameters
    ----------
    lam : float
        λ = (ρA·ω²/EI)^(1/4)·L.
    mass_ratio : float
        μ = M_tip / (ρA·L).
    inertia_ratio : float
        j = J_tip / (ρA·L³).
    """
    c, s, th, sech = np.cos(lam), np.sin(lam), np.tanh(lam), 1.0 / np.cosh(lam)
    mu, j = mass_ratio, inertia_ratio
    return float(sech + c + mu * lam * (c * th - s) - j * lam ** 3 * (s + th * c)
                 + mu * j * lam ** 4 * (sech - c))


def frequency_roots(count: int, mass_ratio: float = 0.0, inertia_ratio: float = 0.0) -> np.ndarray:
    """The first *count* roots λ_k of the frequency equation, ascending.

    Parameters
    ----------
    count : int
        Number of modes.
    mass_ratio : float
        μ = M_tip / (ρA·L).
    inertia_ratio : float
        j = J_tip / (ρA·L³).
    """
    if count < 1 or mass_ratio < 0 or inertia_ratio < 0:
        raise InputError("a link needs at least one mode, and tip loads cannot be negative")
    roots, lo, step = [], 1e-3, 0.05

    def f(x):
        return frequency_equation(x, mass_ratio, inertia_ratio)
    flo = f(lo)
    while len(roots) < count:
        hi = lo + step
        fhi = f(hi)
        if np.sign(fhi) != np.sign(flo):
            roots.append(brentq(f, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps))
        lo, flo = hi, fhi
        if lo > 10 * (count + 2) * np.pi:
            raise InputError("the frequency equation has fewer roots than modes asked for")
    return np.array(roots)


def gauss_points(count: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre points and weights on [0, 1].

    Parameters
    ----------
    count : int
        Number of points.
    """
    x, w = np.polynomial.legendre.leggauss(count)
    return 0.5 * (x + 1.0), 0.5 * w


class BeamModes(NamedTuple):
    """The assumed modes of one link: shapes φ_k(x), their frequencies and their scale.

    ``shape(x, derivative)`` gives φ_k^(d)(x) for every mode k at positions x [m] (shape
    (len(x), modes)); ``omega`` are the natural frequencies [rad/s] of the link clamped
    at its joint with its tip load; ``scale`` multiplies the dimensionless shape so that
    the chosen normalisation holds.
    """

    length: float
    rho_a: float
    ei: float
    tip_mass: float
    tip_inertia: float
    lam: np.ndarray
    b: np.ndarray
    b_plus_one: np.ndarray
    scale: np.ndarray
    normalisation: str

    @property
    def omega(self) -> np.ndarray:
        """Natural frequencies ω_k = λ_k²·√(EI/(ρA·L⁴)) [rad/s]."""
        return self.lam ** 2 * np.sqrt(self.ei / (self.rho_a * self.length ** 4))

    def shape(self, x, derivative: int = 0) -> np.ndarray:
        """φ_k^(derivative)(x) [m^-derivative], shape (len(x), modes).

        Parameters
        ----------
        x : array_like
            Positions along the link, 0 ≤ x ≤ L.
        derivative : int
            0 to 3.
        """
        xi = np.atleast_1d(np.asarray(x, dtype=float))[:, None] / self.length
        z = self.lam[None, :] * xi
        # cosh z + b·sinh z = ½(1+b)eᶻ + ½(1−b)e⁻ᶻ, with 1 + b ~ e^(−λ) computed apart:
        # the usual form cancels eᶻ against eᶻ and loses digits in the higher modes
        grow = 0.5 * self.b_plus_one * np.exp(z)
        decay = 0.5 * (1.0 - self.b) * np.exp(-z)
        c, s = np.cos(z), np.sin(z)
        forms = [grow + decay - c - self.b * s, grow - decay + s - self.b * c,
                 grow + decay + c + self.b * s, grow - decay - s + self.b * c]
        factor = (self.lam / self.length) ** derivative
        return self.scale * factor * forms[derivative]


def beam_modes(count: int, length: float, rho_a: float, ei: float, tip_mass: float = 0.0,
               tip_inertia: float = 0.0, normalisation: Normalisation = "link-mass") -> BeamModes:
    """The first *count* modes of a clamped link with a tip mass and rotary inertia.

    Parameters
    ----------
    count : int
        Number of modes.
    length : float
        L [m].
    rho_a : float
        Mass per length ρA [kg/m].
    ei : float
        Bending stiffness EI [N·m²].
    tip_mass : float
        M at the tip [kg] (0: clamped-free).
    tip_inertia : float
        J at the tip [kg·m²].
    normalisation : {"link-mass", "unit"}
        Modal mass ∫ρA·φ² dx + M·φ(L)² + J·φ'(L)² equal to ρA·L, or to 1 kg.
    """
    if not 1 <= count <= MAX_BEAM_MODES:
        raise InputError(f"a link takes 1 to {MAX_BEAM_MODES} assumed modes, got {count}")
    if min(length, rho_a, ei) <= 0:
        raise InputError("a flexible link needs a positive length, mass per length and bending stiffness")
    if normalisation not in ("link-mass", "unit"):
        raise InputError(f"unknown normalisation {normalisation!r}: use link-mass or unit")
    mu, j = tip_mass / (rho_a * length), tip_inertia / (rho_a * length ** 3)
    lam = frequency_roots(count, mu, j)
    b, bp1 = np.empty(count), np.empty(count)
    for k, x in enumerate(lam):
        ch, sh, c, s, e = np.cosh(x), np.sinh(x), np.cos(x), np.sin(x), np.exp(-x)
        moment = ((ch + c) - j * x ** 3 * (sh + s), (sh + s) - j * x ** 3 * (ch - c))
        shear = (x * (sh - s) + mu * x ** 2 * (ch - c), x * (ch + c) + mu * x ** 2 * (sh - s))
        if abs(moment[1]) >= abs(shear[1]):     # b from the better conditioned tip condition
            b[k] = -moment[0] / moment[1]
            bp1[k] = (-e + s - c - j * x ** 3 * (e - c - s)) / moment[1]
        else:
            b[k] = -shear[0] / shear[1]
            bp1[k] = (x * (e + c + s) + mu * x ** 2 * (c - s - e)) / shear[1]
    raw = BeamModes(length, rho_a, ei, tip_mass, tip_inertia, lam, b, bp1, np.ones(count), normalisation)
    xg, wg = gauss_points(96)
    phi = raw.shape(xg * length)
    tip, slope = raw.shape([length])[0], raw.shape([length], 1)[0]
    modal = rho_a * length * (wg @ phi ** 2) + tip_mass * tip ** 2 + tip_inertia * slope ** 2
    target = rho_a * length if normalisation == "link-mass" else 1.0
    return raw._replace(scale=np.sqrt(target / modal))
