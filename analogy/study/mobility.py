"""The frequency-domain check: SPICE's swept mobilities against (M's + B' + K'/s)^-1 and the natural frequencies."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..results.frequency import FrequencyResponse, resonance_report, sweep_range
from ..solvers.exact import exact_mobility
from ..results.modes import natural_modes
from ..solvers.ac import spice_mobility

__all__ = ["MobilityCheck", "mobility_check"]


class MobilityCheck(NamedTuple):
    """SPICE's swept mobilities against the exact ones: the two responses, the report and the error."""

    spice: FrequencyResponse
    exact: FrequencyResponse
    report: str
    worst_resonance: float
    error: float


def mobility_check(system, f_start: float | None = None, f_stop: float | None = None,
                   per_decade: int = 500) -> MobilityCheck:
    """Sweep *system*'s circuit in ngspice and compare with (M's + B' + K'/s)⁻¹ and the natural frequencies.

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    f_start, f_stop : float, optional
        The sweep [Hz]; by default a decade beyond the natural frequencies each way.
    per_decade : int
        Points per decade.
    """
    modes = natural_modes(system.joint)
    natural = modes.omega / (2 * np.pi)
    lo, hi = sweep_range(natural)
    spice = spice_mobility(system, f_start or lo, f_stop or hi, per_decade)
    exact = exact_mobility(system, spice.frequency)
    return MobilityCheck(spice, exact, *resonance_report(natural, modes.unstable, spice, exact))
