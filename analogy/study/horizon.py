"""How long the circuit linearised at q0 follows the full nonlinear motion."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from .comparison import Comparison, compare
from ..results.metrics import peak
from ..results.output import Tabular

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["LinearHorizon", "linear_horizon", "TOLERANCES"]

#: Relative deviations at which the linear circuit's horizon is reported.
TOLERANCES = (1e-3, 1e-2, 1e-1)


@dataclass(eq=False)
class LinearHorizon(Tabular):
    """The nonlinear comparison, the linear circuit's rates on its points, and where they part.

    Attributes
    ----------
    nonlinear : Comparison
        Every solver on the full motion, with its reference.
    linear : ndarray, shape (N, n)
        Joint rates of the exact solution of the circuit linearised at q0.
    deviation : ndarray, shape (N,)
        max over joints of |R_linear − R_reference| / peak.
    held : dict of float to float
        Tolerance → the first time the deviation exceeds it (inf: never).
    """

    nonlinear: Comparison
    linear: np.ndarray
    deviation: np.ndarray
    held: dict

    def lines(self) -> list[str]:
        """One sentence per tolerance."""
        return [f"the circuit linearised at q0 stays within {tol:g} of the peak rate "
                + (f"until t = {t:.4g} s" if np.isfinite(t) else "over the whole run")
                for tol, t in self.held.items()]

    def columns(self) -> dict[str, np.ndarray]:
        """The nonlinear solvers' joint rates, then the linear circuit's ``r1_linear`` …"""
        cols = self.nonlinear.columns()
        cols.update((f"r{j + 1}_linear", self.linear[:, j]) for j in range(self.linear.shape[1]))
        return cols

    def plot(self, path=None) -> "Figure":
        """Both motions and their deviation against time; saved to *path* if given.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from ..results.plots import plot_linear_horizon
        ref = self.nonlinear.results[self.nonlinear.reference]
        robot = self.nonlinear.system.provenance.robot
        return plot_linear_horizon(self.nonlinear.time, ref.rates, self.linear, self.deviation, self.held,
                                   f"{robot}: nonlinear motion against the circuit at q0", path,
                                   units=self.nonlinear.system.provenance.units,
                                   names=self.nonlinear.system.provenance.joints)


def linear_horizon(scene, preset="accurate", solvers: Sequence[str] = ("spice", "ode"),
                   step: float | None = None) -> LinearHorizon | None:
    """Compare the scene's full motion with its circuit linearised at q0.

    Parameters
    ----------
    scene : Scene
        The scene (its dynamics is set here).
    preset : str or Preset
        Accuracy preset.
    solvers : sequence of str
        Solvers of the nonlinear motion (the reference runs too).
    step : float, optional
        Output step.

    Returns
    -------
    LinearHorizon or None
        None if no reference applies to the nonlinear motion.
    """
    result = compare(scene.replace(dynamics="nonlinear").system(), preset, solvers, step=step)
    ref = result.results.get(result.reference) if result.reference else None
    if ref is None:
        return None
    linear = compare(scene.replace(dynamics="linear").system(), preset, ["exact"], times=result.time)
    lin = linear.results["exact"].rates
    deviation = np.max(np.abs(lin - ref.rates), axis=1) / peak(ref.rates)
    held = {}
    for tol in TOLERANCES:
        past = np.flatnonzero(deviation > tol)
        held[tol] = float(result.time[past[0]]) if past.size else float("inf")
    return LinearHorizon(result, lin, deviation, held)
