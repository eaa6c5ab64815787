"""Motion of a run: node positions integrated from its voltages, the pose and the capacitances at each frame."""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np
from scipy.integrate import cumulative_trapezoid

from ..circuit.currents import element_currents
from ..circuit.description import circuit
from ..circuit.diagram import schematic, schematic_fits
from ..errors import InputError
from ..model.dynamics import NodeDynamics
from ..model.base import RobotModel
from ..model.mechanism import mechanism_outline, tree_outline
from ..results.animation import VIEW, Motion
from ..results.trajectory import Trajectory
from .measure import contact_outputs

__all__ = ["motion", "DEFLECTION_SHOWN"]

#: A flexible arm's largest deflection is drawn as at least this share of its reach.
DEFLECTION_SHOWN = 0.15


def _nice(factor: float) -> float:
    """The 1-2-5 number at or below *factor* (≥ 1): a readable exaggeration."""
    if factor <= 1.0:
        return 1.0
    decade = 10.0 ** math.floor(math.log10(factor))
    return max(m * decade for m in (1.0, 2.0, 5.0) if m * decade <= factor)


def motion(system: NodeDynamics, trajectory: Trajectory, frames: int = 60, *,
           conventions: Mapping[str, Any] | None = None, model: RobotModel | None = None) -> Motion:
    """The run *trajectory* of *system* as frames: the pose q = q0 + T⁻¹·∫v dt and, where M' varies, M'(x).

    Positions are integrated from the solver's own voltages by the trapezoidal rule,
    between its points (a linear circuit's drawn motion is the one it predicts about q0).

    Parameters
    ----------
    system : NodeDynamics
        The system that was solved.
    trajectory : Trajectory
        A successful run of it.
    frames : int
        Frames, evenly spread over the run.
    conventions : mapping, optional
        A flexible arm's conventions as its model was built (``link_modes``,
        ``joint_frame``; see :attr:`analogy.scenes.spec.ModelSpec.conventions`).
    model : RobotModel, optional
        The system's model, where it is drawn from its own kinematics (a URDF's tree, in space;
        default: a nonlinear system's own model). The built-in arms are drawn from their parameters.
    """
    if not trajectory.success:
        raise InputError(f"the {trajectory.solver} run failed, so there is no motion to draw: "
                         f"{trajectory.message}")
    if not 2 <= frames <= 2000:
        raise InputError(f"an animation takes 2 to 2000 frames, got {frames}")
    t, v = trajectory.time, trajectory.voltages
    x = trajectory.positions if trajectory.positions is not None else cumulative_trapezoid(v, t, axis=0,
                                                                                           initial=0.0)
    shown = np.linspace(0.0, t[-1], frames)
    x_shown = np.column_stack([np.interp(shown, t, x[:, j]) for j in range(x.shape[1])])
    provenance = system.provenance
    if system.kind == "nonlinear":
        q0 = np.asarray(system.q0, dtype=float)
    else:
        at = list(provenance.configuration.values())        # in the model's coordinate order
        q0 = np.array(at, dtype=float) if len(at) == system.dof else np.zeros(system.dof)
    q = q0 + system.joint_rates(x_shown)
    outline, note, joint_axes = None, "", None
    drawn = dict(conventions or {})
    parameters = dict(provenance.parameters)
    if model is None and system.kind == "nonlinear":
        model = system.model
    if isinstance(model, RobotModel) and model.rigid_tree:
        outline, joint_axes = tree_outline(model.tree, q)
        note = f"from its joint frames, seen from azimuth {VIEW[0]:g}°, elevation {VIEW[1]:g}°"
    elif parameters:
        outline = mechanism_outline(provenance.robot, q, parameters, **drawn)
    if outline is not None and provenance.robot.startswith("flex"):
        stiff = mechanism_outline(provenance.robot, q, parameters, **drawn, exaggeration=0.0)
        bend = max(float(np.max(np.linalg.norm(a - b, axis=1))) for fa, fb in zip(outline, stiff)
                   for a, b in zip(fa, fb))
        reach = sum(float(np.linalg.norm(p[-1] - p[0])) for p in stiff[0])
        factor = _nice(DEFLECTION_SHOWN * reach / bend) if bend > 0 else 1.0
        if factor > 1.0:
            outline = mechanism_outline(provenance.robot, q, parameters, **drawn,
                                        exaggeration=factor)
        note = f"deflections drawn x{factor:g} (largest {bend * 1e3:.3g} mm)"
    elif outline is not None and system.kind == "linear":
        note = "the motion the linear circuit predicts about q0" + (f"; {note}" if note else "")
    capacitances = np.array([system.node_mass(row) for row in x_shown]) if system.kind == "nonlinear" else None
    drawn_circuit, currents, peaks = _circuit_in_motion(system, t, v, x, shown)
    branches = _branches_in_motion(system, t, v, x, shown) if system.kind == "linear" and drawn_circuit is None else None
    title = f"{provenance.robot} {system.kind}, {trajectory.solver}"
    nodes = list(system.nodes)
    if provenance.joints and np.array_equal(system.topology.matrix, np.eye(system.dof)):
        nodes = [f"{node}: {name}" for node, name in zip(nodes, provenance.joints)]     # node k is joint k
    contacts = {name: trajectory.currents[name] for name in contact_outputs(system)
                if name in trajectory.currents and trajectory.currents[name].shape == t.shape}
    return Motion(title, t, v, nodes, shown, outline, x_shown, capacitances, note, joint_axes, drawn_circuit,
                  currents, peaks, branches, contacts or None)


def _branches_in_motion(system: NodeDynamics, t: np.ndarray, v: np.ndarray, x: np.ndarray,
                        shown: np.ndarray) -> np.ndarray:
    """A circuit too large for a schematic, as a map of its currents at the frames, shape (F, n, n): entry
    (i, j) the current from node i to node j through the elements between them, (i, i) node i's to ground."""
    flows = element_currents(system, t, v, x)
    out = np.zeros((len(shown), system.dof, system.dof))
    for e in circuit(system).parts:
        i = np.interp(shown, t, flows[e.name])
        a, b = e.a - 1, (e.b - 1 if e.b else e.a - 1)
        out[:, a, b] += i
        if e.b:
            out[:, b, a] -= i
    return out


def _circuit_in_motion(system: NodeDynamics, t: np.ndarray, v: np.ndarray, x: np.ndarray,
                       shown: np.ndarray) -> tuple:
    """A linear circuit small enough to draw: its schematic, each part's current at the frames (the
    elements' from the node voltages, the sources' their forces) and its peak on the run's points; else
    Nones. A nonlinear circuit's capacitances change: its panel is M'(x)."""
    if system.kind != "linear" or not schematic_fits(system):
        return None, None, None
    drawn = schematic(system, title=" ", caption="node: its voltage over its peak; circle: a part's current "
                                                  "over its peak (red +, blue −)")
    flows = element_currents(system, t, v, x)
    for src in circuit(system).sources:
        flows[src.name] = src.scale * np.broadcast_to(src.waveform(t), t.shape)
    names = list(drawn.parts)
    peaks = np.array([np.max(np.abs(flows[name])) for name in names])
    return drawn, np.column_stack([np.interp(shown, t, flows[name]) for name in names]), peaks
