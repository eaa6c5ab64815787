"""Frequency responses: mobilities (node velocity per unit joint force), their resonances and Bode plots."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from .output import Tabular

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FrequencyResponse", "frequency_grid", "sweep_range", "resonance_report", "MAX_FREQUENCIES"]


#: Most frequencies in one sweep (a mobility matrix each).
MAX_FREQUENCIES = 200_000


def frequency_grid(f_start: float, f_stop: float, per_decade: int) -> np.ndarray:
    """Log-spaced frequencies [Hz], *per_decade* points a decade, as ngspice's ``.ac dec`` makes them.

    Parameters
    ----------
    f_start, f_stop : float
        First and last frequency [Hz], 0 < f_start < f_stop.
    per_decade : int
        Points per decade.
    """
    if not (0 < f_start < f_stop and math.isfinite(f_stop)):
        raise InputError(f"frequencies must satisfy 0 < f_start < f_stop, got {f_start:g} and {f_stop:g}")
    if not 1 <= per_decade <= 100000:
        raise InputError(f"points per decade must be 1 to 100000, got {per_decade}")
    decades = math.log10(f_stop) - math.log10(f_start)
    if per_decade * decades > MAX_FREQUENCIES:
        raise InputError(f"{decades:.3g} decades at {per_decade} points each is more than {MAX_FREQUENCIES:,} "
                         "frequencies: narrow the range or take fewer points per decade")
    count = int(math.floor(per_decade * math.log10(f_stop / f_start) + 1e-9)) + 1
    return f_start * 10.0 ** (np.arange(count) / per_decade)


@dataclass(eq=False)
class FrequencyResponse(Tabular):
    """Mobilities Y[f, node, joint] [(m/s)/N or (rad/s)/(N·m); V/A in the circuit] at frequencies f [Hz].

    Attributes
    ----------
    frequency : ndarray
        Frequencies [Hz].
    mobility : ndarray, shape (frequencies, nodes, joints)
        Complex node velocity per unit force on each joint: driving-point entries on
        the diagonal, transfer mobilities off it.
    solver : str
        Who computed it (``spice``, ``exact``).
    joint_map : ndarray, shape (joints, nodes)
        T⁻¹, from node velocities to joint rates (identity for the parallel topology).
    units : tuple of str or None
        Joint units (:func:`analogy.units.joint_units`), for labels.
    coordinates : tuple of str or None
        The joints' coordinate names (``theta1``, ``delta1_1`` …), for labels.
    """

    frequency: np.ndarray
    mobility: np.ndarray
    solver: str
    joint_map: np.ndarray
    units: tuple | None = None
    coordinates: tuple | None = None

    def driving_point(self) -> np.ndarray:
        """R_j/F_j [f, joint]: each joint's rate per unit force on itself, whatever the topology."""
        return np.einsum("jk,fkj->fj", self.joint_map, self.mobility)

    def joint_mobility(self) -> np.ndarray:
        """R_i/F_j [f, joint i, joint j]: the joint mobility matrix, symmetric (reciprocal) for any
        topology, as (B + sM + K/s)⁻¹ is; the node voltages' own matrix is not, unless T = I."""
        return np.einsum("ik,fkj->fij", self.joint_map, self.mobility)

    def __repr__(self) -> str:
        f = self.frequency
        return (f"<FrequencyResponse {self.solver}: {self.mobility.shape[1]} nodes × {self.mobility.shape[2]} "
                f"joints, {f.size} frequencies {f[0]:.3g}–{f[-1]:.3g} Hz>")

    def columns(self) -> dict[str, np.ndarray]:
        """``f_hz``; the joint mobilities ``abs_Y<i>_<j>``, ``phase_deg_Y<i>_<j>`` (joint i's rate per unit
        force on joint j, what the Bode plot draws); then the node voltages per joint force
        ``abs_v<node>_F<j>``, ``phase_deg_v<node>_F<j>`` (the circuit's own, the same where T = I)."""
        cols: dict[str, np.ndarray] = {"f_hz": self.frequency}
        for name, values in (("Y{}_{}", self.joint_mobility()), ("v{}_F{}", self.mobility)):
            _, rows, joints = values.shape
            for i in range(rows):
                for j in range(joints):
                    y = values[:, i, j]
                    cols["abs_" + name.format(i + 1, j + 1)] = np.abs(y)
                    cols["phase_deg_" + name.format(i + 1, j + 1)] = np.degrees(np.angle(y))
        return cols

    def relative_error(self, reference: "FrequencyResponse") -> float:
        """max |Y − Y_ref| / max |Y_ref| over every frequency and entry (the same grid needed).

        Parameters
        ----------
        reference : FrequencyResponse
            The response to compare with.
        """
        if self.mobility.shape != reference.mobility.shape or \
                not np.allclose(self.frequency, reference.frequency, rtol=1e-12, atol=0):
            raise InputError("frequency responses on different grids cannot be compared")
        return float(np.max(np.abs(self.mobility - reference.mobility)) / np.max(np.abs(reference.mobility)))

    def resonances(self, joint: int | None = None) -> np.ndarray:
        """Frequencies [Hz] of the resonances in the driving-point mobility R_j/F_j of *joint* (default: each).

        In the circuit a driving-point mobility is an impedance, whose reactance rises with frequency
        (Foster): at a resonance Im Y falls through zero or jumps from +∞ to −∞, at an
        antiresonance it rises through zero. The resonance is placed where Im(1/Y)
        vanishes (for one mode exactly at √(k/m), whatever its damping), by linear
        interpolation in log f between grid points; those of the joints are merged.

        Parameters
        ----------
        joint : int, optional
            Joint (1-based) whose driving-point mobility is read.
        """
        return self._crossings(joint, resonance=True)

    def antiresonances(self, joint: int | None = None) -> np.ndarray:
        """Frequencies [Hz] where the driving-point mobility of *joint* has a zero (Im Y rises through 0).

        Parameters
        ----------
        joint : int, optional
            Joint (1-based).
        """
        return self._crossings(joint, resonance=False)

    def _crossings(self, joint, resonance: bool) -> np.ndarray:
        joints = range(self.mobility.shape[2]) if joint is None else [joint - 1]
        found: list[tuple[float, float]] = []
        logf = np.log(self.frequency)
        points = self.driving_point()
        for j in joints:
            y = points[:, j]
            rising = (y.imag[:-1] < 0) & (y.imag[1:] > 0)
            falling = (y.imag[:-1] > 0) & (y.imag[1:] < 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                g = (1.0 / y).imag if resonance else y.imag
            for k in np.nonzero(falling if resonance else rising)[0]:
                if not np.isfinite(g[k:k + 2]).all() or g[k] == g[k + 1]:
                    continue
                root = logf[k] - g[k] * (logf[k + 1] - logf[k]) / (g[k + 1] - g[k])
                # how clearly this joint sees it: a weakly excited mode sits next to a zero
                # closer than the grid, where the interpolation fails
                strength = float(np.abs(y[k:k + 2]).max() / np.abs(y[k:k + 2]).min())
                found.append((float(np.exp(root)), strength if resonance else 1.0 / strength))
        found.sort()
        merged: list[tuple[float, float]] = []
        for f, strength in found:       # one mode seen from several joints: the clearest view
            if merged and f / merged[-1][0] - 1 < 1e-3:
                if strength > merged[-1][1]:
                    merged[-1] = (f, strength)
                continue
            merged.append((f, strength))
        return np.array([f for f, _ in merged])

    def plot(self, path=None, reference: "FrequencyResponse | None" = None) -> "Figure":
        """Bode plot of the driving-point mobilities: magnitude and phase, *reference* overlaid.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        reference : FrequencyResponse, optional
            Another response (the exact one) drawn beneath.
        """
        from .plots import plot_bode
        return plot_bode(self, reference, path)


def sweep_range(natural_hz: np.ndarray) -> tuple[float, float]:
    """A sweep that shows every resonance: a decade below the lowest nonzero natural frequency to one above the highest.

    Parameters
    ----------
    natural_hz : ndarray
        Natural frequencies [Hz] (zeros, rigid-body modes, are skipped).
    """
    f = natural_hz[natural_hz > 0]
    if f.size == 0:
        return 0.01, 100.0
    return float(10 ** np.floor(np.log10(f.min()) - 1)), float(10 ** np.ceil(np.log10(f.max()) + 1))


def resonance_report(natural_hz: np.ndarray, unstable: np.ndarray, response: FrequencyResponse,
                     reference: FrequencyResponse) -> tuple[str, float, float]:
    """A table pairing each natural frequency with the nearest resonance *response* and *reference* locate.

    Returns the text, the worst relative distance of a located resonance from its
    natural frequency, and the mobility error of *response* against *reference*.

    Parameters
    ----------
    natural_hz : ndarray
        Undamped natural frequencies [Hz] of the modes.
    unstable : ndarray of bool
        Modes with ω² < 0 (no resonance: they grow).
    response, reference : FrequencyResponse
        The swept responses (SPICE, exact).
    """
    found = {r.solver: r.resonances() for r in (response, reference)}
    lines = [f"{'mode':>4}{'natural f [Hz]':>16}" + "".join(f"{name + ' peak [Hz]':>18}{'rel. diff':>11}"
                                                            for name in found)]
    worst = 0.0
    for k, (f, bad) in enumerate(zip(natural_hz, unstable)):
        row = f"{k + 1:>4}{f:>16.8g}"
        if f == 0 or bad:
            lines.append(row + ("  unstable: grows, no resonance" if bad else "  rigid body"))
            continue
        for peaks in found.values():
            if peaks.size == 0:
                row += f"{'none':>18}{'':>11}"
                continue
            near = float(peaks[np.argmin(np.abs(np.log(peaks / f)))])
            diff = abs(near / f - 1)
            worst = max(worst, diff)
            row += f"{near:>18.8g}{diff:>11.2e}"
        lines.append(row)
    error = response.relative_error(reference)
    f = response.frequency
    lines.append(f"mobility of {response.solver} against {reference.solver}: max |ΔY| / max |Y| = {error:.3e} "
                 f"over {f.size} frequencies, {f[0]:.4g}–{f[-1]:.4g} Hz")
    return "\n".join(lines), worst, error
