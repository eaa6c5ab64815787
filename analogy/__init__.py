"""analogy: robot dynamics as electric circuits (masses as capacitors, MP models as floating ones)."""

from importlib import import_module

__version__ = "0.1.0"

# Public names and the module that defines each. Modules load on first use, so a
# netlist-only job never imports SPICE, the ODE integrators or matplotlib.
_EXPORTS = {
    "Comparison": "compare", "compare": "compare",
    "Element": "elements", "elements": "elements", "mp_capacitance": "elements",
    "AnalogyError": "errors", "InputError": "errors", "SimulationError": "errors",
    "SpiceError": "errors",
    "solve_exact": "exact",
    "JointSpace": "model", "Model": "model",
    "netlist": "netlist",
    "solve_ode": "ode",
    "PRESETS": "presets", "Preset": "presets",
    "ROBOTS": "robots", "planar_serial": "robots", "point_mass_matrix": "robots", "robot": "robots",
    "SCENES": "scenes", "Scene": "scenes", "scene": "scenes",
    "solve_spice": "spice",
    "NodeSystem": "system", "node_system": "system", "node_systems": "system",
    "Topology": "topology", "parallel": "topology", "serial": "topology",
    "Trajectory": "trajectory",
    "PWL": "waveforms", "Pulse": "waveforms", "Sine": "waveforms", "Step": "waveforms",
}

__all__ = sorted(_EXPORTS)


# Functions named like their modules are bound now: importing the submodule later
# must not replace the function by the module.
from .compare import compare  # noqa: E402
from .elements import elements  # noqa: E402
from .netlist import netlist  # noqa: E402


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'analogy' has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + __all__)
