"""The time-grid policy: uniform output times of a study, SPICE's own points aside."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

__all__ = ["output_grid"]


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
