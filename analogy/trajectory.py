"""Trajectory: one solver's node voltages and joint rates on its time points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Trajectory"]


@dataclass(eq=False)
class Trajectory:
    """Result of one solver.

    Attributes
    ----------
    solver : str
        ``"spice"``, ``"ode"`` or ``"exact"``.
    time : ndarray, shape (N,)
    voltages : ndarray, shape (N, n)
        Node velocities v.
    rates : ndarray, shape (N, n)
        Joint rates R = T⁻¹·v.
    run_time : float
        Wall-clock seconds spent in the solver.
    """

    solver: str
    time: np.ndarray
    voltages: np.ndarray
    rates: np.ndarray
    run_time: float = float("nan")
