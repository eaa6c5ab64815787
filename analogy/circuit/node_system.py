"""Linear node systems M'·dv/dt + B'·v + K'·∫v = i(t): one configuration, or many built as one stack."""

from __future__ import annotations

import copy
from typing import Mapping, Protocol, Sequence

import numpy as np

from ..errors import InputError, concerning
from ..presets import DEFAULT_T_STOP
from ..model.base import RobotModel
from ..model.dynamics import DynamicsKind
from ..model.provenance import Provenance
from ..model.joint import (
    JointSpace,
    check_node_form,
    check_square_symmetric,
    check_vector,
    configuration_stack,
    stack_fault,
)
from ..waveforms import Step
from .joint_forces import waveforms
from .node_coordinates import NodeCoordinates, check_t_stop, output_times
from .node_stack import NodeStack
from .topology import Topology, default_topology, symmetric_part
from .topology import topology as make_topology


class Evaluable(Protocol):
    """What node systems need of a model: a name, its coordinates and parameters, and M, B, K, G."""

    name: str
    coordinates: Sequence
    parameters: Mapping[str, float]
    topology: str

    def joint_space(self, q=None, parameters=None) -> JointSpace:
        """M, B, K and G at configuration *q*.

        Parameters
        ----------
        q : sequence of float, optional
            Configuration.
        parameters : mapping, optional
            Parameter overrides.
        """

__all__ = ["Evaluable", "NodeSystem", "node_system", "node_systems"]


class NodeSystem(NodeCoordinates):
    """Linear dynamics in node coordinates v = T·r, driven by joint forces F(t).

    ``M'·dv/dt = i(t) − B'·v − K'·x`` with constant M' = T⁻ᵀ·M·T⁻¹ (B', K' likewise)
    and i = T⁻ᵀ·F: the :class:`~analogy.model.dynamics.NodeDynamics` special case that
    every solver, the exact one included, applies to.

    Parameters
    ----------
    joint : JointSpace
        Joint-space M, B, K, G at the chosen configuration.
    topology : Topology
        The map T.
    forces : tuple of tuple of Waveform
        Per joint, the waveforms whose sum is F_j(t) (gravity included as a constant −G).
    initial_rates : array_like
        Joint rates R(0).
    t_stop : float
        End of the simulated interval [s].
    info : Provenance or mapping, optional
        What the system was built from (robot, scene, parameters, configuration, units),
        kept as :attr:`provenance` for netlist headers and reports.
    """

    kind: DynamicsKind = "linear"
    #: Its circuit puts each negative element behind a 1:−1 coupling (see :meth:`realized`).
    realizable: bool = False

    def realized(self, realizable: bool = True) -> "NodeSystem":
        """This system, to be simulated as its realizable circuit: the same dynamics, no
        negative element (each behind a 1:−1 coupling). The circuit solvers (spice, gnucap)
        build that circuit; the ODE and exact solvers solve the same equations.

        Parameters
        ----------
        realizable : bool
            False gives back the signed circuit.
        """
        return self._replaced(realizable=bool(realizable))

    def __init__(self, joint: JointSpace, topology: Topology, forces: tuple, initial_rates,
                 t_stop: float, info: Mapping | None = None):
        n = joint.dof
        if topology.dof != n:
            raise InputError(f"topology is {topology.dof}x{topology.dof} but the robot has {n} joints",
                             field="topology")
        t_stop = check_t_stop(t_stop)
        if len(forces) != n:
            raise InputError(f"forces must have {n} entries (one per joint), got {len(forces)}", field="forces")
        with concerning("initial_rates"):
            r0 = check_vector("initial rates r0", initial_rates, n)
        mass = topology.node_matrix(joint.mass_matrix)
        damping = topology.node_matrix(joint.damping)
        stiffness = None if joint.stiffness is None else topology.node_matrix(joint.stiffness)
        # T can be well conditioned yet scale M', B' or K' out of floating-point range. The
        # joint matrices passed their own checks, so a node form that fails concerns a T
        # given as a matrix, and otherwise the joint matrices it was made from.
        custom = topology.name not in ("serial", "parallel", "modal")
        for field, label, part in (("mass", "node mass matrix M'", mass), ("damping", "node damping matrix B'", damping),
                                   ("stiffness", "node stiffness matrix K'", stiffness),
                                   ("topology", "current map T^-T", topology.current_map)):
            with concerning("topology" if custom else field):
                check_node_form(label, part)
        with concerning("topology" if custom else "mass"):
            check_square_symmetric("node mass matrix M'", mass, definite=True)
        self._store(joint, topology, tuple(forces), r0, float(t_stop), info, mass, damping, stiffness)
        with concerning("forces"):
            self.breakpoints()      # checks every waveform against t_stop before any solver runs
        self._seal()

    def _store(self, joint, topology, forces, r0, t_stop, info, mass, damping, stiffness):
        self.joint, self.topology, self.forces = joint, topology, forces
        self.dof = joint.dof                                # number of nodes (and joints) n
        self.initial_rates, self.t_stop, self.provenance = r0, t_stop, Provenance.of(info)
        self.initial_voltages = topology.matrix @ r0        # node velocities v(0) = T·R(0)
        self.mass, self.damping, self.stiffness = mass, damping, stiffness
        self.current_map = topology.current_map

    @classmethod
    def from_checked(cls, joint: JointSpace, topology: Topology, forces: tuple, initial_rates: np.ndarray,
                     t_stop: float, info: Mapping, mass: np.ndarray, damping: np.ndarray,
                     stiffness: np.ndarray | None) -> "NodeSystem":
        """A system whose parts were checked as one row of a stack (see :func:`node_systems`).

        Parameters
        ----------
        joint : JointSpace
            Joint-space matrices.
        topology : Topology
            The map T.
        forces : tuple
            Per joint, its waveforms.
        initial_rates : ndarray
            Joint rates at t = 0.
        t_stop : float
            End time.
        info : Provenance
            What the system was built from.
        mass : ndarray
            M'.
        damping : ndarray
            B'.
        stiffness : ndarray or None
            K'.
        """
        obj = cls.__new__(cls)
        obj._store(joint, topology, forces, initial_rates, t_stop, info, mass, damping, stiffness)
        obj._seal()
        return obj

    def _with_gravity(self, ws: tuple) -> tuple:
        """Joint waveforms *ws* with gravity's constant −G added, as :func:`node_system` adds it."""
        gravity = self.joint.gravity
        return ws if gravity is None else tuple(w + (Step(-g),) if g else w for w, g in zip(ws, gravity))

    def __repr__(self) -> str:
        springs = ", springs" if self.stiffness is not None else ""
        return (f"NodeSystem({self.provenance.robot}, {self.dof} nodes, "
                f"{self.topology.name} topology{springs}, t_stop={self.t_stop:g} s)")

    def node_mass(self, x: np.ndarray) -> np.ndarray:
        """M', the same at every x.

        Parameters
        ----------
        x : ndarray
            Node positions (unused: M' is constant).
        """
        return self.mass

    def node_load(self, x: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """h = 0: a linear system has no velocity or configuration terms.

        Parameters
        ----------
        x : ndarray
            Node positions.
        v : ndarray
            Node velocities.
        t : float
            Time.
        """
        return np.zeros(self.dof)


def node_system(model: Evaluable | JointSpace, q: Sequence[float] | None = None, *,
                parameters: Mapping[str, float] | None = None,
                topology: str | Topology | np.ndarray | None = None,
                forces=None, initial_rates=None, t_stop: float = DEFAULT_T_STOP,
                info: Mapping | None = None) -> NodeSystem:
    """Evaluate *model* at *q* and map it to node coordinates.

    Parameters
    ----------
    model : Model, CompiledModel or JointSpace
        Symbolic, compiled or numeric dynamics.
    q : sequence of float, optional
        Configuration, for models that depend on it.
    parameters : mapping, optional
        Parameter overrides.
    topology : {"serial", "parallel", "modal"}, Topology or array_like, optional
        Joint-to-node map T; defaults to the model's own, or the modal one past 12 dense joints
        (:func:`~analogy.circuit.topology.default_topology`).
    forces : sequence, optional
        One entry per joint: a number (step at t = 0), a waveform, a waveform
        string such as ``"sine(0, 1, 2)"`` or a list of these to be summed.
    initial_rates : sequence of float, optional
        Joint rates at t = 0 (default zero).
    t_stop : float
        End of the simulated interval.
    info : Provenance or mapping, optional
        Provenance fields beyond the model's own (the scene's name, a robot name for a JointSpace).
    """
    return _mapped(*_evaluated(model, q, parameters, topology), forces, initial_rates, t_stop, info)


def _evaluated(model, q, parameters, topology):
    """The joint space of *model* at *q*, the topology to use and the report fields."""
    if isinstance(model, RobotModel):
        joint = model.joint_space(q, parameters)
        own = model.topology
        values = dict(model.parameters, **(parameters or {}))
        base_info = {"robot": model.name, "parameters": values,
                     "configuration": dict(zip((str(c) for c in model.coordinates), q or [])),
                     "units": model.units, "joints": model.joint_names}
        if q is not None and (note := model.pose_note(q, parameters)) is not None:
            base_info["notes"] = (note,)
    elif isinstance(model, JointSpace):
        joint, own, base_info = model, "parallel", {}
    else:
        raise InputError("model must be an analogy Model or JointSpace")
    top_spec = topology if topology is not None else default_topology(own, joint.mass_matrix, joint.damping,
                                                                       joint.stiffness)
    return joint, top_spec, base_info


def _mapped(joint, top_spec, base_info, forces, initial_rates, t_stop, info) -> NodeSystem:
    """A joint space mapped to node coordinates, with its forces and initial rates."""
    n = joint.dof
    with concerning("topology"):
        top = make_topology(top_spec, n, (joint.mass_matrix, joint.damping, joint.stiffness))
    with concerning("forces"):
        ws = waveforms(forces, n)
    if joint.gravity is not None:
        ws = tuple(w + (Step(-g),) if g else w for w, g in zip(ws, joint.gravity))
    r0 = np.zeros(n) if initial_rates is None else initial_rates
    return NodeSystem(joint, top, ws, r0, check_t_stop(t_stop), Provenance.of(info, **base_info))


def node_systems(model, qs, *, parameters: Mapping[str, float] | None = None,
                 topology=None, forces=None, initial_rates=None, t_stop: float = DEFAULT_T_STOP,
                 info: Mapping | None = None) -> NodeStack:
    """:func:`node_system` at every row of *qs*, evaluated and checked as one :class:`NodeStack`.

    The configurations share everything else (topology, forces, initial rates, t_stop,
    and the parameters that are not given per row), so those are checked once, and M(q), B(q), K(q), G(q) are evaluated
    vectorised over the rows and checked with stacked factorizations. The systems are
    the ones :func:`node_system` builds, to rounding (the same numbers on the platforms
    tested); a configuration that fails a check raises the error :func:`node_system`
    gives for it, naming its row. The systems' matrices are read-only views of the stack.

    Parameters
    ----------
    model : Model or CompiledModel
        A model that evaluates stacks of configurations.
    qs : array_like, shape (count, n)
        Configurations.
    parameters : mapping, optional
        Parameter overrides: one number for every row, or a sequence of one per row.
    topology : str, Topology or array_like, optional
        Joint-to-node map T.
    forces : sequence, optional
        One entry per joint (see :func:`node_system`).
    initial_rates : sequence of float, optional
        Joint rates at t = 0.
    t_stop : float
        End of the simulated interval.
    info : mapping, optional
        Extra report fields.
    """
    if not isinstance(model, RobotModel):
        raise InputError(f"node_systems needs a robot model, not a {type(model).__name__}")
    q = configuration_stack(model.name, [str(c) for c in model.coordinates], qs)
    kw = dict(topology=topology, forces=forces, initial_rates=initial_rates, t_stop=t_stop, info=info)
    # copies: rows made later read them, whatever the caller does with its own meanwhile
    parameters = None if parameters is None else dict(parameters)
    varying = {k: np.array(v, dtype=float) for k, v in (parameters or {}).items() if np.ndim(v)}
    for name, v in varying.items():
        if v.shape != (len(q),):
            raise InputError(f"parameter {name!r} needs one value or {len(q)} (one per configuration), "
                             f"got shape {v.shape}")

    def row(k: int) -> dict | None:
        return None if parameters is None else {
            name: float(varying[name][k]) if name in varying else v for name, v in parameters.items()}
    try:
        evaluated = _evaluated(model, q[0].tolist(), row(0), topology)
    except InputError as exc:
        raise InputError(f"configuration 1: {exc}") from None
    first = _mapped(*evaluated, forces, initial_rates, t_stop, info)    # checks what the rows share
    try:
        if first.topology.name == "modal":      # each row has its own modes
            raise InputError("modal")
        stack = model.joint_stack(q, parameters)
        top = first.topology
        m, b, kk = (None if x is None else symmetric_part(x) for x in stack[:3])
        node_mass = top.node_matrix(m)
        node_damping = top.node_matrix(b)
        node_stiffness = None if kk is None else top.node_matrix(kk)
        fault = stack_fault(stack, node_mass) or not all(
            np.all(np.isfinite(x)) for x in (node_damping, node_stiffness) if x is not None)
    except InputError:
        fault = True
    if fault:               # one at a time: a bad row raises its own error, with its number
        out = []
        for k, qk in enumerate(q):
            try:
                out.append(node_system(model, qk.tolist(), parameters=row(k), **kw))
            except InputError as exc:
                raise InputError(f"configuration {k + 1}: {exc}") from None
        return NodeStack(out)
    for x in (m, b, kk, node_mass, node_damping, node_stiffness):
        if x is not None:
            x.setflags(write=False)     # rows are views: no system may change another
    shared_forces = first.forces if stack.gravity is None else waveforms(forces, first.dof)
    coords = [str(c) for c in model.coordinates]
    r0, t_end = first.initial_rates, first.t_stop
    # per row: any spring, any gravity load (rows without keep the shared forces)
    springy = np.zeros(len(q), bool) if kk is None else np.any(kk, axis=(1, 2))
    loaded = np.zeros(len(q), bool) if stack.gravity is None else np.any(stack.gravity, axis=1)
    v0 = np.broadcast_to(first.initial_voltages, (len(q), first.dof))
    arrays = {"mass": node_mass, "damping": node_damping, "initial_voltages": v0}
    if springy.all():
        arrays["stiffness"] = node_stiffness

    def system(k: int) -> NodeSystem:     # made when the row is asked for: a batch reads the arrays
        stiff = kk[k] if springy[k] else None
        grav = stack.gravity[k] if loaded[k] else None
        ws = shared_forces if grav is None else \
            tuple(w + (Step(-x),) if x else w for w, x in zip(shared_forces, grav))
        joint = JointSpace.from_checked(m[k], b[k], stiff, grav)
        item_info = first.provenance.at(dict(zip(coords, q[k].tolist())), row(k) if varying else None)
        return NodeSystem.from_checked(joint, top, ws, r0.copy(), t_end, item_info, node_mass[k],
                                       node_damping[k], None if stiff is None else node_stiffness[k])
    return NodeStack.lazy(system, arrays, springy, shared_inputs=not loaded.any())
