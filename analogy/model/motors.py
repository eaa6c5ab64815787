"""DC motors and gearboxes on a robot's joints: a winding's R and L, a torque constant, a rotor reflected through its gear."""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import InputError, located
from .expressions import parse_number
from .quantities import Dimension

__all__ = ["Motor", "MOTOR_FIELDS", "motor_spec", "motor_table", "motors_from_table", "load_motors", "read_motor_file",
           "reflected"]


@dataclass(frozen=True)
class Motor:
    """A DC motor behind a gearbox of ratio N: the motor turns N times for each turn of its joint.

    In the analogy the motor is an ideal transformer of ratio n = N·k between its winding and its
    joint: the winding sees the back-EMF n·q̇ (a voltage source following the joint's rate) and the
    joint the torque n·i (a current source following the winding's current). The gear reflects the
    rotor's inertia and viscous friction to the joint as N²·J and N²·b.

    Attributes
    ----------
    resistance : float
        The winding's resistance R [Ω].
    inductance : float
        Its inductance L [H] (0: a winding whose current follows its voltage at once).
    torque_constant : float
        k [N·m/A], equal to the back-EMF constant [V·s/rad] in SI.
    rotor_inertia : float
        J [kg·m²], about the motor's shaft.
    gear_ratio : float
        N, motor turns per joint turn (1: direct drive).
    viscous : float
        The rotor's viscous friction b [N·m·s/rad], on the motor's side.
    coulomb : float
        Its Coulomb friction [N·m], on the motor's side (not linear: a linear drive refuses it).
    voltage_limit, current_limit : float
        The largest |voltage| the drive may apply [V] and |current| the winding may carry [A]
        (inf: none); a run past them is flagged.
    """

    resistance: float
    torque_constant: float
    inductance: float = 0.0
    rotor_inertia: float = 0.0
    gear_ratio: float = 1.0
    viscous: float = 0.0
    coulomb: float = 0.0
    voltage_limit: float = math.inf
    current_limit: float = math.inf

    @property
    def ratio(self) -> float:
        """n = N·k: the joint's torque per ampere and the back-EMF per unit joint rate."""
        return self.gear_ratio * self.torque_constant

    @property
    def armature(self) -> float:
        """N²·J: the rotor's inertia as the joint feels it (Pinocchio's ``model.armature``)."""
        return self.gear_ratio ** 2 * self.rotor_inertia

    @property
    def reflected_viscous(self) -> float:
        """N²·b: the rotor's viscous friction as the joint feels it."""
        return self.gear_ratio ** 2 * self.viscous


#: Each field of a motor file and what it measures (a bare number is SI).
MOTOR_FIELDS: dict[str, Dimension | None] = {
    "resistance": "resistance", "inductance": "inductance", "torque_constant": "torque constant",
    "rotor_inertia": "inertia", "gear_ratio": None, "viscous": "rotary damping", "coulomb": "torque",
    "voltage_limit": "voltage", "current_limit": "current"}
_POSITIVE = ("resistance", "torque_constant", "gear_ratio", "voltage_limit", "current_limit")


def _fields(entry: Mapping, where: str) -> dict[str, float]:
    """A motor table's fields as SI numbers, each checked (names, units, signs)."""
    if not isinstance(entry, Mapping):
        raise InputError(f"{where}: expected a table of a motor's fields")
    values = {}
    for key, value in entry.items():
        if key not in MOTOR_FIELDS:
            raise InputError(f"{where}: unknown field {key!r} (known: {', '.join(MOTOR_FIELDS)})")
        with located(f"{where} {key}"):
            if isinstance(value, bool) or not isinstance(value, (int, float, str)):
                raise InputError("expected a number, or a number with its unit such as \"0.5 ohm\"")
            dimension = MOTOR_FIELDS[key]
            x = parse_number(value, dimension) if isinstance(value, str) else float(value)
            if not (math.isfinite(x) or key.endswith("_limit")) or x < 0 or (key in _POSITIVE and x == 0):
                raise InputError(f"must be {'positive' if key in _POSITIVE else 'zero or positive'}, got {value!r}")
            values[key] = x
    return values


def _motor(entry: Mapping, where: str) -> Motor:
    """One motor from a table of field values (numbers, or strings with units)."""
    values = _fields(entry, where)
    missing = [k for k in ("resistance", "torque_constant") if k not in values]
    if missing:
        raise InputError(f"{where}: a motor needs its {' and '.join(missing)}")
    return Motor(**values)


def motor_spec(table: Mapping, where: str = "motors") -> tuple:
    """A motor table (a motor file's, or a scene file's ``[motors]``) as a hashable value, every field
    checked: ``((joint name or number, or "default", ((field, value), …)), …)``, sorted.

    Which joint each table names is judged when the robot is known (:func:`motors_from_table`).

    Parameters
    ----------
    table : mapping
        ``{default: {...}, <joint name or number>: {...}}``.
    where : str
        The source, named in errors.
    """
    if not isinstance(table, Mapping) or not table:
        raise InputError(f"{where}: expected [default] or a table per joint (its name or number), each of a "
                         "motor's fields")
    for key, entry in table.items():
        _fields(entry, f"{where}: [{key}]")
    return tuple(sorted((str(key), tuple(sorted(entry.items()))) for key, entry in table.items()))


def motor_table(spec: tuple) -> dict:
    """The mapping a :func:`motor_spec` value stands for.

    Parameters
    ----------
    spec : tuple
        A :func:`motor_spec` value.
    """
    return {key: dict(entry) for key, entry in spec}


def motors_from_table(table: Mapping, joints: Sequence[str], where: str = "motors",
                      reductions: Mapping[str, float] | None = None) -> tuple[Motor | None, ...]:
    """Each joint's motor from a table ``{default: {...}, <joint name or number>: {...}}``: a joint's own
    fields over the default's, and over a URDF's gear ratio for it (*reductions*); None for a joint
    with neither table.

    Parameters
    ----------
    table : mapping
        The motor file's tables.
    joints : sequence of str
        The robot's joint names, in order (``q1`` … for the built-in arms).
    where : str
        The source, named in errors.
    reductions : mapping of str to float, optional
        Gear ratios by joint name, from a URDF's transmissions (:func:`~analogy.model.urdf_file.transmissions`):
        a motor table without ``gear_ratio`` takes its joint's.
    """
    default = table.get("default", {})
    own: dict[int, Mapping] = {}
    for key, entry in table.items():
        if key == "default":
            continue
        k = joints.index(key) if key in joints else int(key) - 1 if str(key).isdigit() else -1
        if not 0 <= k < len(joints):
            raise InputError(f"{where}: [{key}] is not a joint (the joints are {', '.join(joints)}, or 1 to "
                             f"{len(joints)})")
        if k in own:
            raise InputError(f"{where}: joint {joints[k]} has two motor tables")
        own[k] = entry
    if not isinstance(default, Mapping):
        raise InputError(f"{where}: [default] must be a table of a motor's fields")
    out = []
    for k, name in enumerate(joints):
        if k not in own and not default:
            out.append(None)
            continue
        urdf = {"gear_ratio": (reductions or {})[name]} if name in (reductions or {}) else {}
        entry = {**urdf, **default, **own.get(k, {})} if isinstance(own.get(k, {}), Mapping) else own[k]
        out.append(_motor(entry, f"{where}: [{name if k in own else 'default'}]"))
    if not any(out):
        raise InputError(f"{where}: no joint has a motor (give [default] or a table per joint)")
    return tuple(out)


def load_motors(path: str | Path, joints: Sequence[str],
                reductions: Mapping[str, float] | None = None) -> tuple[Motor | None, ...]:
    """The motors of a motor file (TOML, see :func:`motors_from_table`).

    Parameters
    ----------
    path : str or Path
        The file.
    joints : sequence of str
        The robot's joint names.
    reductions : mapping of str to float, optional
        A URDF's gear ratios by joint name.
    """
    return motors_from_table(read_motor_file(path), list(joints), str(path), reductions)


def read_motor_file(path: str | Path) -> dict:
    """A motor file's tables (TOML), every field checked (:func:`motor_spec`).

    Parameters
    ----------
    path : str or Path
        The file.
    """
    p = Path(path)
    try:
        table = tomllib.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read the motor file {p}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: not a TOML motor file ({exc})") from None
    motor_spec(table, str(p))
    return table


def reflected(motors: Sequence[Motor | None]) -> tuple[np.ndarray, np.ndarray]:
    """The joints' added inertia N²·J and viscous friction N²·b, one entry per joint (0 without a motor).

    Parameters
    ----------
    motors : sequence of Motor or None
        One per joint.
    """
    return (np.array([m.armature if m else 0.0 for m in motors]),
            np.array([m.reflected_viscous if m else 0.0 for m in motors]))
