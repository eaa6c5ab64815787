"""SI units of joint coordinates, rates and forces, and of their circuit twins, for labels and headers."""

from __future__ import annotations

from typing import Literal, Sequence

from .errors import InputError

__all__ = ["JointKind", "JOINT_KINDS", "joint_units", "mechanical_units", "rate_unit", "force_unit", "rate_label", "force_label", "quantity_label"]

#: The kinds of joint coordinate a model declares, and the SI unit of each: a revolute joint's
#: angle, a prismatic joint's travel, a flexible link's modal amplitude (a deflection).
JointKind = Literal["revolute", "prismatic", "modal"]
JOINT_KINDS: dict[str, str] = {"revolute": "rad", "prismatic": "m", "modal": "m"}


def joint_units(joints: Sequence[str] | None) -> tuple[str, ...] | None:
    """Per joint coordinate, ``"rad"`` or ``"m"``, from the kinds its model declares; None without them.

    A model given by its matrices (``custom``) or a random one declares none: its
    coordinates have no units beyond SI.

    Parameters
    ----------
    joints : sequence of JointKind or None
        The model's :attr:`joints`.
    """
    if joints is None:
        return None
    unknown = [k for k in joints if k not in JOINT_KINDS]
    if unknown:
        raise InputError(f"unknown joint kind {unknown[0]!r}: use {', '.join(JOINT_KINDS)}")
    return tuple(JOINT_KINDS[k] for k in joints)


def rate_unit(unit: str | None) -> str:
    """The unit of a coordinate's rate: rad/s, m/s, or both when unknown.

    Parameters
    ----------
    unit : str or None
        The coordinate's unit.
    """
    return {"rad": "rad/s", "m": "m/s"}.get(unit or "", "rad/s or m/s")


def force_unit(unit: str | None) -> str:
    """The unit of the generalised force on a coordinate: N·m on an angle, N on a length.

    Parameters
    ----------
    unit : str or None
        The coordinate's unit.
    """
    return {"rad": "N·m", "m": "N"}.get(unit or "", "N·m or N")


def _shared(units: Sequence[str] | None, convert) -> str:
    if not units:
        return convert(None)
    found = list(dict.fromkeys(convert(u) for u in units))
    return found[0] if len(found) == 1 else " or ".join(found)


def rate_label(units: Sequence[str] | None) -> str:
    """Axis label of joint rates, e.g. ``joint rate [rad/s]``.

    Parameters
    ----------
    units : sequence of str or None
        :func:`joint_units`.
    """
    return f"joint rate [{_shared(units, rate_unit)}]"


def force_label(units: Sequence[str] | None) -> str:
    """Axis label of joint forces, e.g. ``joint torque [N·m]``.

    Parameters
    ----------
    units : sequence of str or None
        :func:`joint_units`.
    """
    unit = _shared(units, force_unit)
    return f"joint {'torque' if unit == 'N·m' else 'force'} [{unit}]"


def quantity_label(quantity: str, units: Sequence[str] | None = None) -> str:
    """Axis label of a scene's quantity, with the circuit's unit and its mechanical meaning.

    Parameters
    ----------
    quantity : str
        ``"joint rates"``, ``"node voltages"`` or ``"<kind> currents"``.
    units : sequence of str or None
        :func:`joint_units` of the system.
    """
    rate = _shared(units, rate_unit)
    force = _shared(units, force_unit)
    if quantity == "joint rates":
        return rate_label(units)
    if quantity == "node voltages":
        return f"node voltage [V] = velocity [{rate}]"
    if quantity.endswith("currents"):
        kind = quantity[:-len("currents")].strip()
        return f"{kind} current [A] = force [{force}]".strip()
    return quantity


def mechanical_units(joint_units) -> dict[str, str]:
    """Units of mass, damping, stiffness and force values on nodes whose coordinates have *joint_units*.

    Parameters
    ----------
    joint_units : sequence of str or None
        ``"rad"`` or ``"m"`` per joint (:func:`analogy.units.joint_units`); mixed or
        unknown units leave the values in SI without a name.
    """
    kinds = set(joint_units or ())
    if kinds == {"rad"}:
        return {"C": "kg·m²", "R": "N·m·s/rad", "L": "N·m/rad", "I": "N·m"}
    if kinds == {"m"}:
        return {"C": "kg", "R": "N·s/m", "L": "N/m", "I": "N"}
    return {"C": "(SI)", "R": "(SI)", "L": "(SI)", "I": "(SI)"}
