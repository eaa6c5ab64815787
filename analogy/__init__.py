"""analogy: robot dynamics as electric circuits (masses as capacitors, MP models as floating ones)."""

from .compare import Comparison, compare
from .elements import Element, elements, mp_capacitance
from .errors import AnalogyError, InputError, SimulationError, SpiceError
from .exact import solve_exact
from .model import JointSpace, Model
from .netlist import netlist
from .ode import solve_ode
from .presets import PRESETS, Preset
from .robots import ROBOTS, planar_serial, point_mass_matrix, robot
from .scenes import SCENES, Scene, scene
from .system import NodeSystem, node_system
from .topology import Topology, parallel, serial
from .trajectory import Trajectory
from .waveforms import PWL, Pulse, Sine, Step

__version__ = "0.1.0"

__all__ = [
    "Comparison", "compare", "Element", "elements", "mp_capacitance",
    "AnalogyError", "InputError", "SimulationError", "SpiceError", "solve_exact",
    "JointSpace", "Model", "netlist", "solve_ode", "PRESETS", "Preset",
    "ROBOTS", "planar_serial", "point_mass_matrix", "robot", "SCENES", "Scene", "scene",
    "NodeSystem", "node_system", "Topology", "parallel", "serial", "Trajectory",
    "PWL", "Pulse", "Sine", "Step", "solve_spice",
]


def solve_spice(system, preset="accurate", save=None):
    """Simulate *system* in ngspice (imported on first use); see :func:`analogy.spice.solve_spice`."""
    from .spice import solve_spice as _solve
    return _solve(system, preset, save)
