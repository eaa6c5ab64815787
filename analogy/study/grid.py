"""The time-grid policy: uniform output times of a study, SPICE's own points aside, and their sufficient subset."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

__all__ = ["output_grid", "sufficient_points", "SUFFICIENT_PHASE", "SUBSET_FROM"]

#: Largest ω·H between the points on which a long run is measured. The error's content is at the
#: system's rates (its modes, the forces' frequencies, ω ≤ ω_max), so by Bernstein's inequality
#: |ė| ≤ ω_max·max|e|, and the maximum over points H apart falls short of the true one by at
#: most a factor 1 − ω_max·H/2: 2.5 % here, at 126 points a period of the fastest rate.
SUFFICIENT_PHASE = 0.05
#: A run with more own points than this is measured on its sufficient subset, where that is
#: at least twice fewer points.
SUBSET_FROM = 100_000


def output_grid(t_stop: float, step: float | None, default: int) -> np.ndarray:
    """Uniform output times 0, step, 2·step, … with t_stop last (or *default* + 1 points).

    Parameters
    ----------
    t_stop : float
        End time.
    step : float or None
        Output step; None gives *default* intervals.
    default : int
        Number of intervals without a step.
    """
    if step is None:
        return np.linspace(0.0, t_stop, default + 1)
    if not (math.isfinite(step) and 0 < step <= t_stop):
        raise InputError(f"the output step must be a time in (0, t_stop = {t_stop:g} s], got {step!r}")
    count = int(math.floor(t_stop / step * (1 + 1e-12)))
    if count > 10_000_000:
        raise InputError(f"the output step {step:g} s gives more than 10 million points")
    t = np.arange(count + 1) * step
    return t if t[-1] >= t_stop * (1 - 1e-12) else np.append(t, t_stop)


def sufficient_points(time: np.ndarray, omega: float, breakpoints=()) -> np.ndarray | None:
    """Indices of a subset of *time*, each gap at most :data:`SUFFICIENT_PHASE`/*omega* plus
    one own step, every breakpoint's first point and the last point included; None where
    the subset would not be at least twice smaller, or the run is short (:data:`SUBSET_FROM`).

    Parameters
    ----------
    time : ndarray
        A solver's own, increasing time points.
    omega : float
        The fastest rate in the error [rad/s] (:meth:`~analogy.circuit.scales.Scales.fastest`).
    breakpoints : array_like
        The forces' corners, where the error's derivative jumps.
    """
    n = int(time.size)
    if n <= SUBSET_FROM or not (math.isfinite(omega) and omega > 0):
        return None
    span = float(time[-1] - time[0])
    step = SUFFICIENT_PHASE / omega
    if span / step > n / 2:
        return None
    targets = np.concatenate([time[0] + np.arange(int(span / step) + 1) * step, np.asarray(breakpoints, float)])
    idx = np.searchsorted(time, targets, side="right") - 1          # the last own point at or before each
    return np.unique(np.concatenate([[0], np.clip(idx, 0, n - 1), [n - 1]]))
