"""The rules of a scene, in one place whatever wrote it: each refusal names its field, and each front end says where."""

from __future__ import annotations

import math

from ..errors import InputError, concerning
from ..model.catalog import BASES, robot_family
from ..model.conventions import CONVENTIONS
from ..model.dynamics import DYNAMICS
from ..presets import preset

__all__ = ["check_model_spec", "check_scene", "MATRICES"]

#: The parts of a model given by its matrices.
MATRICES = ("mass", "damping", "stiffness", "gravity")


def check_model_spec(spec) -> None:
    """Refuse a model spec whose parts do not go together, naming the part (:attr:`InputError.field`).

    A robot is named once: by a built-in name, or by a URDF. A named or URDF robot has its own
    matrices. The flexible arms' conventions apply to them alone, and a joint selection to a URDF
    given by its file (a named robot keeps its own).

    Parameters
    ----------
    spec : ModelSpec
        The spec.
    """
    if spec.robot is not None and spec.urdf is not None:
        raise InputError("a robot is named and a URDF given: give one", field="urdf")
    if spec.robot is not None:
        with concerning("robot"):
            family = robot_family(spec.robot)[0]
    else:
        family = None
    given = [k for k in MATRICES if getattr(spec, k) is not None]
    if given and (family is not None or spec.urdf is not None):
        whose = "a built-in robot" if family is not None and family.urdf is None else "a URDF robot"
        raise InputError(f"{whose} has its own; set its parameters instead, or give a mass matrix without a robot",
                         field=given[0])
    chosen = [k for k in CONVENTIONS if getattr(spec, k) is not None]
    if chosen and (family is None or not family.flexible):
        what = f"not to {spec.robot}" if spec.robot is not None else "not to a model given by its matrices or a URDF"
        raise InputError(f"applies to the flexible arms (flex1, flex2, flexpar), {what}", field=chosen[0])
    if spec.joints is not None and spec.urdf is None:
        raise InputError("selects the joints of a URDF given by its file (a named robot keeps its own)", field="joints")
    if spec.base is not None:
        if spec.base not in BASES:
            raise InputError(f"base must be {' or '.join(BASES)}, got {spec.base!r}", field="robot")
        if not spec.from_urdf:
            raise InputError(f"base {spec.base!r} applies to a URDF robot, whose root link may be held or free",
                             field="robot")
    if spec.contacts is not None and not spec.from_urdf:
        raise InputError("contacts name a URDF robot's links (the hopper has its own foot)", field="robot")


def check_scene(scene) -> str:
    """Refuse a scene's settings that no solver can take, naming the field; return its preset's name.

    Parameters
    ----------
    scene : Scene
        The scene.
    """
    if scene.dynamics not in DYNAMICS:
        raise InputError(f"unknown dynamics {scene.dynamics!r}: use {', '.join(DYNAMICS)}", field="dynamics")
    with concerning("preset"):
        # a name, or a tolerance written as its name ("1e-5", 1e-5 and "0.00001" are "1e-05": one key)
        name = preset(scene.preset).name
    t = scene.t_stop
    if isinstance(t, bool) or not (isinstance(t, (int, float)) and math.isfinite(t) and t > 0):
        raise InputError(f"t_stop must be a positive time, got {t!r}", field="t_stop")
    s = scene.step
    if s is not None and (isinstance(s, bool) or not (isinstance(s, (int, float)) and math.isfinite(s) and s > 0)):
        raise InputError(f"the output step must be a positive time, got {s!r}", field="step")
    if scene.voltages and not scene.motors:
        raise InputError("voltages drive motors: give them in [motors] (--motors FILE)", field="voltages")
    return name
