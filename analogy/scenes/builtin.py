"""The built-in scenes: the MP-model paper's examples, the default arm and a random system."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from ..files import write_text
from ..solvers.transient import netlist
from ..errors import InputError
from ..model.catalog import URDF_NAMES
from .scene import Scene
from .spec import ModelSpec

__all__ = ["SCENES", "PAPER_EXAMPLES", "scene", "write_netlists"]


SCENES = {
    "default": Scene.of(
        "default", "serial2", q=(0.0, 0.3), forces=(1.0, 0.5), t_stop=10.0,
        description="2-DOF serial arm (eqs. 17-20), l = (1, 0.8) m, d = (2, 1) kg, "
                    "b = (1, 0.5) N m s, at q2 = 0.3 rad, step torques (1, 0.5) N m"),
    "redundant": Scene.of(
        "redundant", "redundant", q=(0.0, 0.0),
        forces=("pwl(0, 0, 1, 1, 3, 1, 4, 0)", "step(0.5)"), initial_rates=(0.1, 0.0), t_stop=8.0,
        description="redundant rotary and prismatic actuators on one axis (Fig. 8, eq. 11)"),
    "serial2": Scene.of(
        "serial2", "serial2", q=(0.0, 0.3), forces=("step(1)", "sine(0, 0.5, 0.5)"),
        initial_rates=(0.0, 0.2), t_stop=10.0,
        description="2-DOF serial arm (eqs. 17-20) at q2 = 0.3 rad: negative MP capacitance"),
    "parallel2": Scene.of(
        "parallel2", "parallel2", q=(2.1, 0.9),
        forces=("pulse(0, 0.01, 0.5, 0.01, 0.01, 2, 5)", "step(-0.005)"), t_stop=10.0,
        description="2-DOF parallel five-bar (eq. 24), M(q) from its kinematics, at "
                    "q = (2.1, 0.9) rad (end effector at (12.6, 212.5) mm, elbows out), "
                    "b = 4e-3 N m s, M/B about 0.5-0.6 s"),
    "serial3": Scene.of(
        "serial3", "serial3", q=(0.0, 0.4, -0.7),
        forces=("step(1)", "step(0.5)", "sine(0, 0.3, 1)"), t_stop=8.0,
        description="3-DOF planar serial arm (eqs. 29-34)"),
    "parallel3": Scene.of(
        "parallel3", "parallel3", q=(2.6, -1.7, 0.35),
        forces=("step(0.005)", "sine(0, 0.0025, 0.5)", "pwl(0, 0, 2, 0.005)"), t_stop=10.0,
        description="3-DOF planar 3-RRR with joint springs (eq. 35), M(q) from its kinematics, "
                    "at q = (2.6, -1.7, 0.35) rad (platform at (-5.5, -9.1) mm, -0.152 rad), "
                    "b = 7e-3 N m s, k = 0.01 N m/rad, M/B about 0.5-0.7 s"),
    "flexpar": Scene.of(
        "flexpar", "flexpar", q=(0.3, 1.9, 0.0, 0.0, 0.0, 0.0), parameters={"g": 0.0},
        forces=("step(0.2)", "step(0.1)", 0.0, 0.0, 0.0, 0.0), t_stop=1.0,
        description="the flexible-robot paper's parallel-link arm (Fig. 1.b) in a horizontal plane: "
                    "links AB and BC flexible (2 modes each), the forearm held along motor 2's angle "
                    "by a parallelogram near a right angle (θ3 − θ1 stays 1.6 to 2.0 rad, far from "
                    "the flat singular poses); a step on each motor"),
    "hopper": Scene.of(
        "hopper", "hopper", q=(0.4, -0.3), forces=(0.0, 0.0), t_stop=1.0, dynamics="nonlinear",
        description="a one-legged hopper dropped from rest, its foot 0.1 m above the ground: flight, "
                    "impact, bounces on the leg's spring, and rest on the ground's contact"),
    "random10": Scene.of(
        "random10", ModelSpec(robot="random10", seed=1), topology="serial", forces=tuple(
            ["sine(0, 1, 0.7)"] + [f"step({1.0 / (k + 1)!r})" for k in range(1, 10)]),
        t_stop=5.0, description="random SPD 10-DOF mass matrix (seed 1), serial topology"),
}

#: The five examples of the MP-model paper.
PAPER_EXAMPLES = ("redundant", "serial2", "parallel2", "serial3", "parallel3")


def scene(name: str) -> Scene:
    """A built-in scene by name.

    Parameters
    ----------
    name : str
        One of :data:`SCENES`, or a named URDF robot (its default experiment:
        :func:`~analogy.scenes.robot_defaults.robot_scene`).
    """
    if name in SCENES:
        return SCENES[name]
    if name in URDF_NAMES:        # derived from the robot's file when first asked for
        from .robot_defaults import robot_scene
        return robot_scene(name)
    raise InputError(f"unknown scene {name!r}: use {', '.join(SCENES)} or a named robot "
                     f"({', '.join(URDF_NAMES)})")


def write_netlists(directory, names: Sequence[str] = PAPER_EXAMPLES, preset: str = "accurate") -> list[Path]:
    """Write ``<name>.cir`` for each named scene into *directory*.

    Parameters
    ----------
    directory : str or Path
        Folder to write into (created if need be).
    names : sequence of str
        Built-in scene names.
    preset : str
        Accuracy preset of the netlists.
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        sc = scene(name)
        path = out / f"{name}.cir"
        write_text(path, netlist(sc.system(), preset, title=f"analogy example {name}: {sc.description}"))
        paths.append(path)
    return paths
