"""The predictability horizon of a nonlinear motion: how soon two motions 1e-12 apart part by the bound."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..presets import Preset
from ..results.trajectory import Trajectory
from ..solvers.registry import solve

__all__ = ["Predictability", "predictability", "PERTURBATION"]

#: The relative change of the initial joint rates whose growth is followed: near rounding, so
#: that any solver's own error of the same size grows as fast.
PERTURBATION = 1e-12


@dataclass(frozen=True)
class Predictability:
    """How two ODE motions from initial rates :data:`PERTURBATION` apart part.

    Attributes
    ----------
    horizon : float or None
        The first time they differ by *bound* of some joint rate's own peak [s]; None when
        they never do over the run.
    bound : float
        The preset's bound.
    rate : float
        The mean growth rate ln(bound / PERTURBATION) / horizon [1/s] (nan without a horizon).
    t_stop : float
        The run's horizon [s].
    """

    horizon: float | None
    bound: float
    rate: float
    t_stop: float

    @property
    def chaotic(self) -> bool:
        """True when the motion cannot be predicted to the bound over the whole run."""
        return self.horizon is not None

    def line(self) -> str:
        """One sentence: the horizon, or that the motion stays predictable."""
        if self.horizon is None:
            return (f"predictable: two motions {PERTURBATION:g} apart stay within {self.bound:g} of each rate's "
                    f"peak over t_stop = {self.t_stop:g} s")
        return (f"chaotic: two motions {PERTURBATION:g} apart in their initial rates part by {self.bound:g} of a "
                f"rate's peak at t = {self.horizon:.3g} s (growth about e^({self.rate:.3g}·t)): errors past that "
                "predictability horizon measure the motion's sensitivity, not a solver's")


def predictability(system, preset: Preset, nominal: Trajectory | None = None) -> Predictability:
    """The predictability horizon of a nonlinear *system*'s motion, from the ODE's divergence.

    The initial joint rates are moved by :data:`PERTURBATION` of each rate's peak (of its
    initial rate where larger) and the ODE integrates both motions at the preset's settings.

    Parameters
    ----------
    system : NonlinearNodeSystem
        The motion.
    preset : Preset
        Its settings and bound.
    nominal : Trajectory, optional
        The ODE's motion already computed at those settings (run here otherwise).
    """
    if nominal is None or not nominal.success:
        nominal = solve(system, "ode", None, preset)
    if not nominal.success:
        return Predictability(None, preset.bound, math.nan, system.t_stop)
    peak = np.max(np.abs(nominal.rates), axis=0)
    scale = np.maximum(np.maximum(peak, np.abs(system.initial_rates)), np.finfo(float).tiny)
    moved = system.driven(initial_rates=system.initial_rates + PERTURBATION * scale)
    other = solve(moved, "ode", nominal.time, preset)
    if not other.success:
        return Predictability(None, preset.bound, math.nan, system.t_stop)
    part = np.max(np.abs(other.rates - nominal.rates) / np.where(peak > 0, peak, scale), axis=1)
    past = np.flatnonzero(part > preset.bound)
    if not past.size:
        return Predictability(None, preset.bound, math.nan, system.t_stop)
    t = float(nominal.time[past[0]])
    return Predictability(t, preset.bound, math.log(preset.bound / PERTURBATION) / t if t > 0 else math.inf, system.t_stop)
