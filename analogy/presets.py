"""Named accuracy presets: SPICE step and tolerance options, ODE method and tolerances."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from .errors import InputError

__all__ = ["Preset", "PRESETS", "PresetName", "preset"]

#: Names of the built-in presets.
PresetName = Literal["fast", "accurate"]


@dataclass(frozen=True)
class Preset:
    """Solver settings that trade run time for error.

    Attributes
    ----------
    spice_options : dict
        ``.options`` for ngspice (integration method, tolerances).
    steps : int
        ``.tran`` print step is t_stop/steps.
    max_steps : int
        ``.tran`` maximum internal step is t_stop/max_steps.
    ode_method, ode_rtol :
        ``scipy.integrate`` settings; atol follows from rtol and the response scale.
    bound : float
        The promised worst error / peak of SPICE and the ODE against the exact solution,
        measured on the built-in scenes (``analogy verify``); a result above it is flagged.
    behavioural_options, behavioural_max_steps :
        ``.options`` and step cap t_stop/behavioural_max_steps for circuits with
        behavioural parts (the nonlinear circuits). Tight reltol with trtol = 1 makes
        ngspice 39 stop these with "timestep too small" at the first steps, so they keep
        ngspice's default tolerances and take their accuracy from the step cap.
    """

    name: str
    spice_options: dict = field(default_factory=dict)
    steps: int = 100
    max_steps: int = 100
    ode_method: str = "LSODA"
    ode_rtol: float = 1e-6
    description: str = ""
    bound: float = 1e-3
    behavioural_options: dict = field(default_factory=lambda: {"method": "trap"})
    behavioural_max_steps: int = 200


PRESETS = {
    "fast": Preset(
        "fast",
        # Worst 3.4e-4 of the peak over the built-in scenes and 9.3e-4 over every output
        # (element currents included) of examples/scenes; reltol 3e-5 misses the latter
        # (1.8e-3). trtol=1 (default 7) matters more than reltol, and a larger step cap
        # costs time without gaining accuracy.
        spice_options={"method": "trap", "reltol": 1e-5, "abstol": 1e-12, "vntol": 1e-9,
                       "chgtol": 1e-16, "trtol": 1},
        steps=100, max_steps=50, ode_method="LSODA", ode_rtol=1e-6,
        description="better than 1e-3 of the peak, lowest run time", bound=1e-3,
        behavioural_options={"method": "trap"}, behavioural_max_steps=500),
    "accurate": Preset(
        "accurate",
        # Measured against the exact solution on every built-in scene: worst 2.1e-7 of the
        # peak. The step cap t_stop/20000 dominates; gear-2 at the same cap gives 7.6e-7.
        spice_options={"method": "trap", "reltol": 1e-9, "abstol": 1e-15,
                       "vntol": 1e-13, "chgtol": 1e-20, "trtol": 1},
        steps=1000, max_steps=20000, ode_method="DOP853", ode_rtol=1e-12,
        description="better than 1e-6 of the peak", bound=1e-6,
        behavioural_options={"method": "trap"}, behavioural_max_steps=20000),
}


def preset(name: str | Preset) -> Preset:
    """Look up a preset by name.

    Parameters
    ----------
    name : str or Preset
        ``"fast"`` or ``"accurate"`` (a Preset is returned as it is).
    """
    if isinstance(name, Preset):
        return name
    try:
        return PRESETS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown accuracy preset {name!r}: use {', '.join(PRESETS)}") from None
