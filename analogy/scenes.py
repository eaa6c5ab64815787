"""Scenes: one simulation job (robot, configuration, topology, forces, time span); built-in examples."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from .errors import InputError
from .model import Model
from .system import NodeSystem, node_system

__all__ = ["Scene", "SCENES", "PAPER_EXAMPLES", "scene", "write_netlists"]


@dataclass(frozen=True)
class Scene:
    """One simulation job.

    Attributes
    ----------
    name : str
    model : str or callable
        A built-in robot name, or a function returning a :class:`Model`.
    q : tuple of float
        Configuration.
    forces : tuple
        One force entry per joint (see :func:`analogy.system.node_system`).
    """

    name: str
    model: str | Callable[[], Model]
    q: tuple = ()
    parameters: Mapping[str, float] = field(default_factory=dict)
    topology: object = None
    forces: tuple = ()
    initial_rates: tuple | None = None
    t_stop: float = 10.0
    description: str = ""

    def build_model(self) -> Model:
        if isinstance(self.model, str):
            from .robots import robot    # sympy loads only when a robot is built
            return robot(self.model)
        return self.model()

    def numeric_model(self):
        """The scene's model for evaluation: a built-in robot comes compiled from the
        on-disk cache when it is there (no sympy import), and is compiled into it otherwise."""
        if not isinstance(self.model, str):
            return self.model()
        from .compiled import compile_model, load_compiled
        cached = load_compiled(self.model)
        if cached is not None:
            return cached
        model = self.build_model()
        return compile_model(model, self.model) or model

    def system(self, model=None) -> NodeSystem:
        """The scene's node system (evaluating *model*, or the scene's own)."""
        m = model if model is not None else self.numeric_model()
        return node_system(m, list(self.q) if self.q else None, parameters=dict(self.parameters),
                           topology=self.topology, forces=list(self.forces),
                           initial_rates=self.initial_rates, t_stop=self.t_stop)

    def systems(self, qs, model=None) -> list[NodeSystem]:
        """The scene's node systems at every configuration in *qs*, built as one stack."""
        from .system import node_systems
        m = model if model is not None else self.numeric_model()
        return node_systems(m, qs, parameters=dict(self.parameters), topology=self.topology,
                            forces=list(self.forces), initial_rates=self.initial_rates,
                            t_stop=self.t_stop)

    def family(self):
        """What the scene shares with scenes that differ only in q, as a hashable key.

        None when the scene cannot join a stack: q is not a flat tuple of real numbers,
        or a field (a matrix topology, say) is unhashable.
        """
        if not all(isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)
                   for x in self.q):
            return None
        try:
            key = (self.model, tuple(sorted(self.parameters.items())), self.topology, self.forces,
                   self.initial_rates, self.t_stop, len(self.q))
            hash(key)
        except (TypeError, AttributeError):
            return None
        return key

    def replace(self, **changes) -> "Scene":
        return replace(self, **changes)


def _random_spd_model(n: int, seed: int) -> Model:
    from .robots import random_spd_model
    return random_spd_model(n, seed=seed)


SCENES = {
    "default": Scene(
        "default", "serial2", q=(0.0, 0.3), forces=(1.0, 0.5), t_stop=10.0,
        description="2-DOF serial arm (eqs. 17-20), l = (1, 0.8) m, d = (2, 1) kg, "
                    "b = (1, 0.5) N m s, at q2 = 0.3 rad, step torques (1, 0.5) N m"),
    "redundant": Scene(
        "redundant", "redundant", q=(0.0, 0.0),
        forces=("pwl(0, 0, 1, 1, 3, 1, 4, 0)", "step(0.5)"), initial_rates=(0.1, 0.0), t_stop=8.0,
        description="redundant rotary and prismatic actuators on one axis (Fig. 8, eq. 11)"),
    "serial2": Scene(
        "serial2", "serial2", q=(0.0, 0.3), forces=("step(1)", "sine(0, 0.5, 0.5)"),
        initial_rates=(0.0, 0.2), t_stop=10.0,
        description="2-DOF serial arm (eqs. 17-20) at q2 = 0.3 rad: negative MP capacitance"),
    "parallel2": Scene(
        "parallel2", "parallel2", q=(2.1, 0.9),
        forces=("pulse(0, 0.01, 0.5, 0.01, 0.01, 2, 5)", "step(-0.005)"), t_stop=10.0,
        description="2-DOF parallel five-bar (eq. 24), M(q) from its kinematics, at "
                    "q = (2.1, 0.9) rad (end effector at (12.6, 212.5) mm, elbows out), "
                    "b = 4e-3 N m s, M/B about 0.5-0.6 s"),
    "serial3": Scene(
        "serial3", "serial3", q=(0.0, 0.4, -0.7),
        forces=("step(1)", "step(0.5)", "sine(0, 0.3, 1)"), t_stop=8.0,
        description="3-DOF planar serial arm (eqs. 29-34)"),
    "parallel3": Scene(
        "parallel3", "parallel3", q=(2.6, -1.7, 0.35),
        forces=("step(0.005)", "sine(0, 0.0025, 0.5)", "pwl(0, 0, 2, 0.005)"), t_stop=10.0,
        description="3-DOF planar 3-RRR with joint springs (eq. 35), M(q) from its kinematics, "
                    "at q = (2.6, -1.7, 0.35) rad (platform at (-5.5, -9.1) mm, -0.152 rad), "
                    "b = 7e-3 N m s, k = 0.01 N m/rad, M/B about 0.5-0.7 s"),
    "random10": Scene(
        "random10", lambda: _random_spd_model(10, seed=1), forces=tuple(
            ["sine(0, 1, 0.7)"] + [f"step({1.0 / (k + 1)!r})" for k in range(1, 10)]),
        t_stop=5.0, description="random SPD 10-DOF mass matrix (seed 1), serial topology"),
}

#: The five examples of the MP-model paper.
PAPER_EXAMPLES = ("redundant", "serial2", "parallel2", "serial3", "parallel3")


def scene(name: str) -> Scene:
    """A built-in scene by name."""
    try:
        return SCENES[name]
    except KeyError:
        raise InputError(f"unknown scene {name!r}: use {', '.join(SCENES)}") from None


def write_netlists(directory, names: Sequence[str] = PAPER_EXAMPLES, preset: str = "accurate") -> list[Path]:
    """Write ``<name>.cir`` for each named scene into *directory*."""
    from .netlist import netlist
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        sc = scene(name)
        path = out / f"{name}.cir"
        path.write_text(netlist(sc.system(), preset, title=f"analogy example {name}: {sc.description}"))
        paths.append(path)
    return paths
