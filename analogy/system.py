"""The node system: one linear system M'·dv/dt + B'·v + K'·∫v = i(t) read by every consumer."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Mapping, Sequence

import numpy as np

from .errors import InputError
from .model import JointSpace, JointStack, Model, check_square_symmetric, check_vector, configuration_stack
from .topology import Topology, topology as make_topology
from .waveforms import Step, Waveform, parse_waveform

__all__ = ["NodeSystem", "node_system", "node_systems"]


@dataclass(frozen=True, eq=False)
class NodeSystem:
    """Linear dynamics in node coordinates v = T·r, driven by joint forces F(t).

    Attributes
    ----------
    joint : JointSpace
        Joint-space M, B, K, G at the chosen configuration.
    topology : Topology
        The map T.
    forces : tuple of tuple of Waveform
        Per joint, the waveforms whose sum is F_j(t) (gravity included as a constant −G).
    initial_rates : ndarray
        Joint rates R(0).
    t_stop : float
        End of the simulated interval [s].
    info : dict
        Robot name, parameters and configuration, for netlist headers and reports.
    """

    joint: JointSpace
    topology: Topology
    forces: tuple
    initial_rates: np.ndarray
    t_stop: float
    info: Mapping = field(default_factory=dict)

    def __post_init__(self):
        n = self.joint.dof
        if self.topology.dof != n:
            raise InputError(f"topology is {self.topology.dof}x{self.topology.dof} "
                             f"but the robot has {n} joints")
        if not (np.isfinite(self.t_stop) and 1e-9 <= self.t_stop <= 1e9):
            raise InputError("t_stop must be a time between 1e-9 s and 1e9 s")
        if len(self.forces) != n:
            raise InputError(f"forces must have {n} entries (one per joint), got {len(self.forces)}")
        object.__setattr__(self, "initial_rates", check_vector("initial rates r0", self.initial_rates, n))
        t = self.topology
        object.__setattr__(self, "mass", t.node_matrix(self.joint.mass_matrix))
        object.__setattr__(self, "damping", t.node_matrix(self.joint.damping))
        object.__setattr__(self, "stiffness", None if self.joint.stiffness is None
                           else t.node_matrix(self.joint.stiffness))
        object.__setattr__(self, "current_map", t.current_map)
        # T can be well conditioned yet scale M' out of floating-point range.
        check_square_symmetric("node mass matrix M'", self.mass, definite=True)
        self.breakpoints()          # checks every waveform against t_stop before any solver runs

    # M', B', K' and T⁻ᵀ are set in __post_init__ so that every consumer reads the same numbers.
    mass: np.ndarray = field(init=False, repr=False)
    damping: np.ndarray = field(init=False, repr=False)
    stiffness: np.ndarray | None = field(init=False, repr=False)
    current_map: np.ndarray = field(init=False, repr=False)

    @property
    def dof(self) -> int:
        return self.joint.dof

    @property
    def nodes(self) -> list[str]:
        """SPICE node names, n1 … nN."""
        return [f"n{k + 1}" for k in range(self.dof)]

    @property
    def initial_voltages(self) -> np.ndarray:
        """Node velocities v(0) = T·R(0)."""
        return self.topology.matrix @ self.initial_rates

    def joint_rates(self, node_voltages: np.ndarray) -> np.ndarray:
        """R = T⁻¹·v for node voltages of shape (..., n)."""
        return self.topology.joint_rates(node_voltages)

    def time_points(self, times=None, default: int = 1001) -> np.ndarray:
        """Sorted output times in [0, t_stop] (default: uniform); a time a rounding past
        t_stop, as SPICE's last point can be, is taken as t_stop."""
        if times is None:
            return np.linspace(0.0, self.t_stop, default)
        t = np.asarray(times, dtype=float).reshape(-1)
        if t.size and (np.any(np.diff(t) < 0) or t[0] < 0 or t[-1] > self.t_stop * (1 + 1e-9)
                       or not np.all(np.isfinite(t))):
            raise InputError("output times must be sorted and within [0, t_stop]")
        return np.minimum(t, self.t_stop)

    def force(self, t) -> np.ndarray:
        """Joint forces F(t), shape (len(t), n) for an array of times."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.stack([sum((w(t) for w in ws), np.zeros_like(t)) for ws in self.forces], axis=-1)

    def breakpoints(self) -> np.ndarray:
        """Segment ends 0 < t_1 < … < t_stop between which every force is smooth."""
        pts = {self.t_stop}
        for ws in self.forces:
            for w in ws:
                pts.update(b for b in w.breakpoints(self.t_stop) if 0 < b < self.t_stop)
        return np.array(sorted(pts))

    def segments(self):
        """Yield (t0, t1) intervals on which all forces are given by one closed form."""
        t0 = 0.0
        for t1 in self.breakpoints():
            yield t0, float(t1)
            t0 = float(t1)


@lru_cache(maxsize=1024)
def _step(value: float) -> Step:
    # Waveforms are immutable; a batch of scenes shares its constant forces.
    return Step(value)


def _waveforms(spec, n) -> tuple:
    if spec is None:
        return tuple(() for _ in range(n))
    if isinstance(spec, (str, Waveform)) or np.isscalar(spec):
        raise InputError(f"forces must be a list with one entry per joint ({n})")
    spec = list(spec)
    if len(spec) != n:
        raise InputError(f"forces must have {n} entries (one per joint), got {len(spec)}")
    out = []
    for item in spec:
        items = item if isinstance(item, (list, tuple)) else [item]
        ws = []
        for w in items:
            if isinstance(w, Waveform):
                ws.append(w)
            elif isinstance(w, str):
                ws.append(parse_waveform(w))
            else:
                try:
                    value = float(w)
                except (TypeError, ValueError):
                    raise InputError(f"cannot use {w!r} as a force") from None
                if not np.isfinite(value):
                    raise InputError("forces must be finite")
                ws.append(_step(value))
        out.append(tuple(ws))
    return tuple(out)


def node_system(model: Model | JointSpace, q: Sequence[float] | None = None, *,
                parameters: Mapping[str, float] | None = None,
                topology: str | Topology | np.ndarray | None = None,
                forces=None, initial_rates=None, t_stop: float = 1.0,
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
    topology : {"serial", "parallel"}, Topology or array_like, optional
        Joint-to-node map T; defaults to the model's own.
    forces : sequence, optional
        One entry per joint: a number (step at t = 0), a waveform, a waveform
        string such as ``"sine(0, 1, 2)"`` or a list of these to be summed.
    initial_rates : sequence of float, optional
        Joint rates at t = 0 (default zero).
    t_stop : float
        End of the simulated interval.
    """
    return _mapped(*_evaluated(model, q, parameters, topology), forces, initial_rates, t_stop, info)


def _evaluated(model, q, parameters, topology):
    """The joint space of *model* at *q*, the topology to use and the report fields."""
    if isinstance(model, Model) or hasattr(model, "joint_space"):   # Model or CompiledModel
        joint = model.joint_space(q, parameters)
        top_spec = topology if topology is not None else model.topology
        values = dict(model.parameters, **(parameters or {}))
        base_info = {"robot": model.name, "parameters": values,
                     "configuration": dict(zip((str(c) for c in model.coordinates), q or []))}
    elif isinstance(model, JointSpace):
        joint = model
        top_spec = topology if topology is not None else "parallel"
        base_info = {"robot": "custom", "parameters": {}, "configuration": {}}
    else:
        raise InputError("model must be an analogy Model or JointSpace")
    return joint, top_spec, base_info


def _mapped(joint, top_spec, base_info, forces, initial_rates, t_stop, info) -> NodeSystem:
    """A joint space mapped to node coordinates, with its forces and initial rates."""
    n = joint.dof
    top = make_topology(top_spec, n)
    ws = _waveforms(forces, n)
    if joint.gravity is not None:
        ws = tuple(w + (Step(-g),) if g else w for w, g in zip(ws, joint.gravity))
    r0 = np.zeros(n) if initial_rates is None else initial_rates
    base_info.update(info or {})
    return NodeSystem(joint, top, ws, r0, float(t_stop), base_info)


def _assembled(cls, **values):
    """An instance of a frozen dataclass whose values were already checked as part of a stack."""
    obj = object.__new__(cls)
    for name, value in values.items():
        object.__setattr__(obj, name, value)
    return obj


def _stack_fault(stack: JointStack, node_mass: np.ndarray) -> bool:
    """True unless every configuration passes the checks of JointSpace and NodeSystem."""
    m, b, k, g = stack
    parts = [x for x in (m, b, k, g, node_mass) if x is not None]
    if not all(np.all(np.isfinite(x)) for x in parts):
        return True
    for x in (m, b, k):
        if x is not None and not np.array_equal(x, np.swapaxes(x, 1, 2)):
            return True         # rare (rounding in a model's own expressions): checked one by one
    try:
        np.linalg.cholesky(m)
        np.linalg.cholesky(node_mass)
    except np.linalg.LinAlgError:
        return True
    for x in (b, k):
        if x is not None:
            floor = -1e-12 * np.maximum(np.abs(x).max(axis=(1, 2)), 1.0)
            if np.any(np.linalg.eigvalsh(x)[:, 0] < floor):
                return True
    return False


def node_systems(model, qs, *, parameters: Mapping[str, float] | None = None,
                 topology=None, forces=None, initial_rates=None, t_stop: float = 1.0,
                 info: Mapping | None = None) -> list[NodeSystem]:
    """:func:`node_system` at every row of *qs*, evaluated and checked as one stack.

    The configurations share everything else (parameters, topology, forces, initial
    rates, t_stop), so those are checked once, and M(q), B(q), K(q), G(q) are evaluated
    vectorised over the rows and checked with stacked factorizations. The systems are
    the ones :func:`node_system` builds, to rounding (the same numbers on the platforms
    tested); a configuration that fails a check raises the error :func:`node_system`
    gives for it, naming its row. The systems' matrices are read-only views of the stack.
    """
    if not hasattr(model, "joint_stack"):
        raise InputError("node_systems needs a Model or CompiledModel, not a JointSpace")
    q = configuration_stack(model.name, [str(c) for c in model.coordinates], qs)
    kw = dict(parameters=parameters, topology=topology, forces=forces,
              initial_rates=initial_rates, t_stop=t_stop, info=info)
    try:
        evaluated = _evaluated(model, q[0].tolist(), parameters, topology)
    except InputError as exc:
        raise InputError(f"configuration 1: {exc}") from None
    first = _mapped(*evaluated, forces, initial_rates, t_stop, info)    # checks what the rows share
    try:
        stack = model.joint_stack(q, parameters)
        top = first.topology
        m, b, kk = (None if x is None else 0.5 * (x + np.swapaxes(x, 1, 2)) for x in stack[:3])
        node_mass = top.node_matrix(m)
        fault = _stack_fault(stack, node_mass)
    except InputError:
        fault = True
    if fault:               # one at a time: a bad row raises its own error, with its number
        out = []
        for k, row in enumerate(q):
            try:
                out.append(node_system(model, row.tolist(), **kw))
            except InputError as exc:
                raise InputError(f"configuration {k + 1}: {exc}") from None
        return out
    node_damping = top.node_matrix(b)
    node_stiffness = None if kk is None else top.node_matrix(kk)
    for x in (m, b, kk, node_mass, node_damping, node_stiffness):
        if x is not None:
            x.setflags(write=False)     # rows are views: no system may change another
    shared_forces = first.forces if stack.gravity is None else _waveforms(forces, first.dof)
    coords = [str(c) for c in model.coordinates]
    r0, cmap, t_end = first.initial_rates, top.current_map, first.t_stop
    out = []
    for k, row in enumerate(q):
        stiff = None if kk is None or not np.any(kk[k]) else kk[k]
        grav = None if stack.gravity is None or not np.any(stack.gravity[k]) else stack.gravity[k]
        ws = shared_forces if grav is None else \
            tuple(w + (Step(-x),) if x else w for w, x in zip(shared_forces, grav))
        joint = _assembled(JointSpace, mass_matrix=m[k], damping=b[k],
                           stiffness=stiff, gravity=grav)
        item_info = {**first.info, "parameters": dict(first.info["parameters"]),
                     "configuration": dict(zip(coords, row.tolist()))}
        out.append(_assembled(NodeSystem, joint=joint, topology=top, forces=ws, initial_rates=r0.copy(),
                              t_stop=t_end, info=item_info, mass=node_mass[k], damping=node_damping[k],
                              stiffness=None if stiff is None else node_stiffness[k], current_map=cmap))
    return out
