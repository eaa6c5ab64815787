"""analogy: robot dynamics as electric circuits (masses as capacitors, MP models as floating ones)."""

from importlib import import_module as _import_module

__version__ = "0.1.0"

# Public names and the module that defines each. Modules load on first use, so a
# netlist-only job never imports SPICE, the ODE integrators or matplotlib.
_EXPORTS = {
    "Comparison": "study.comparison", "compare": "study.comparison",
    "compare_many": "study.comparison",
    "Trajectory": "results.trajectory", "SolverStats": "results.trajectory",
    "relative_error": "results.metrics",
    "Element": "circuit.elements", "elements": "circuit.elements", "mp_capacitance": "circuit.elements",
    "Circuit": "circuit.description",
    "AnalogyError": "errors", "InputError": "errors", "SimulationError": "errors",
    "SpiceError": "errors", "AccuracyError": "errors",
    "solve_exact": "solvers.exact", "solve_ode": "solvers.ode", "solve_spice": "solvers.spice",
    "solve_reference": "solvers.reference", "solver": "solvers.registry", "SOLVER_NAMES": "solvers.registry", "solve": "solvers.registry",
    "JointSpace": "model.joint", "Model": "model.symbolic", "NodeDynamics": "model.dynamics",
    "christoffel_symbols": "model.symbolic", "velocity_terms": "model.symbolic",
    "netlist": "solvers.transient", "kicad_schematic": "circuit.kicad",
    "ltspice_netlist": "circuit.ltspice", "ltspice_schematic": "circuit.ltspice",
    "PRESETS": "presets", "Preset": "presets",
    "ROBOTS": "model.robots", "planar_serial": "model.robots", "point_mass_matrix": "model.robots",
    "robot": "model.robots",
    "SCENES": "scenes.builtin", "Scene": "scenes.scene", "scene": "scenes.builtin",
    "load_scene": "scenes.toml", "run_scene": "scenes.run",
    "NodeSystem": "circuit.node_system", "node_system": "circuit.node_system",
    "node_systems": "circuit.node_system",
    "NonlinearNodeSystem": "circuit.nonlinear", "nonlinear_system": "circuit.nonlinear",
    "Topology": "circuit.topology", "parallel": "circuit.topology", "serial": "circuit.topology",
    "PWL": "waveforms", "Pulse": "waveforms", "Sine": "waveforms", "Step": "waveforms",
    "run_batch": "batch.run", "draw_circuit": "circuit.diagram",
    "motion": "study.motion", "Motion": "results.animation", "scene_report": "scenes.report",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'analogy' has no attribute {name!r}")
    value = getattr(_import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(__all__) | {k for k in globals() if not k.startswith("_")})
