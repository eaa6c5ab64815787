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
    positions : ndarray, shape (N, n), or None
        Node positions x = ∫v (the inductor fluxes), when the solver was asked for
        them and the system has springs; None otherwise.
    """

    solver: str
    time: np.ndarray
    voltages: np.ndarray
    rates: np.ndarray
    run_time: float = float("nan")
    positions: np.ndarray | None = None
