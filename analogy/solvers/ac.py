"""Frequency response of a node system's circuit by ngspice's ``.ac`` sweep, one driven joint at a time."""

from __future__ import annotations

import numpy as np

from ..circuit.netlist import ac_netlist
from ..circuit.node_system import NodeSystem
from ..errors import InputError, SimulationError, SpiceError
from ..results.frequency import FrequencyResponse, frequency_grid

__all__ = ["spice_mobility"]


def spice_mobility(system, f_start: float, f_stop: float, per_decade: int = 500) -> FrequencyResponse:
    """Mobilities Y[f, node, joint] of *system*'s circuit from one ngspice AC run per joint.

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    f_start, f_stop : float
        The sweep [Hz].
    per_decade : int
        Points per decade (the grid of :func:`~analogy.results.frequency.frequency_grid`).

    Raises
    ------
    SimulationError
        If ngspice fails, with its sentence.
    """
    from .spice import session
    grid = frequency_grid(f_start, f_stop, per_decade)       # checks the sweep before any run
    if not isinstance(system, NodeSystem):
        raise InputError("an AC sweep needs a linear node system")
    n = system.dof
    out = np.zeros((grid.size, n, n), dtype=complex)
    for j in range(n):
        text = ac_netlist(system, j + 1, f_start, f_stop, per_decade)
        try:
            data = session().run(text, [f"v(n{k + 1})" for k in range(n)], analysis="ac")
        except SpiceError as exc:
            raise SimulationError(str(exc)) from None
        f = data["frequency"]
        # past about 2,000 points a decade ngspice's stop test lets a few points beyond f_stop through
        # (its factor is accumulated): those are dropped, every asked-for point must be there
        beyond = f.size - grid.size
        if beyond < 0 or not np.allclose(f[:grid.size], grid, rtol=1e-9) or \
                not np.all(f[grid.size:] > f_stop * (1 - 1e-9)):
            raise SimulationError("ngspice swept other frequencies than asked for")
        for k in range(n):
            out[:, k, j] = data[f"v(n{k + 1})"][:grid.size]
    return FrequencyResponse(grid, out, "spice", np.linalg.inv(system.topology.matrix), system.provenance.units,
                             tuple(system.provenance.configuration) or None)
