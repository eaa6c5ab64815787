"""Provenance: what a system was built from (robot, scene, parameters, configuration, coordinate units)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field, fields, replace
from typing import Mapping

from ..errors import InputError

__all__ = ["Provenance"]

#: A joint rate's output name, with a solver's or a run's suffix: r2, r2_spice, r2_linear.
_RATE = re.compile(r"^r([0-9]+)(_[A-Za-z0-9_]+)?$")


@dataclass(frozen=True)
class Provenance:
    """What a node system was built from, for netlist headers, reports and labels.

    Attributes
    ----------
    robot : str
        The model's name (``"custom"`` for one given by its matrices).
    scene : str or None
        The scene it came from.
    parameters : dict of str to float
        The model's parameter values.
    configuration : dict of str to float
        The coordinates it was built at.
    units : tuple of str or None
        Per joint coordinate, ``"rad"`` or ``"m"``; None where the model does not say.
    joints : tuple of str or None
        Per joint coordinate, the joint's own name (a URDF's); None: the coordinates are q1 … qn.
    notes : tuple of str
        What a user must hear about the pose before trusting the circuit built at it
        (near a singular pose of a closed chain's loop), said by the CLI, the netlist and the comparison.
    """

    robot: str = "custom"
    scene: str | None = None
    parameters: dict = field(default_factory=dict)
    configuration: dict = field(default_factory=dict)
    units: tuple | None = None
    joints: tuple | None = None
    notes: tuple = ()

    def output_name(self, name: str) -> str:
        """*name* with a joint rate ``r<k>`` named after its joint: ``r2_spice`` → ``shoulder_lift_joint_rate_spice``.

        Other names, and every name of a model without joint names, are returned as they are.

        Parameters
        ----------
        name : str
            An output or column name (``r2``, ``r2_spice``, ``r2_linear``, ``v_n1`` …).
        """
        if not self.joints or (m := _RATE.match(name)) is None or not 1 <= int(m.group(1)) <= len(self.joints):
            return name
        return f"{self.joints[int(m.group(1)) - 1]}_rate{m.group(2) or ''}"

    @classmethod
    def of(cls, given: "Provenance | Mapping | None", **defaults) -> "Provenance":
        """A record from a Provenance or a mapping of its fields, over *defaults*.

        Parameters
        ----------
        given : Provenance, mapping or None
            The fields given (``{"robot": "arm", "scene": "lab"}``); unknown names are refused.
        **defaults
            Fields the builder knows (robot, parameters, configuration, units).
        """
        if isinstance(given, Provenance):
            return given
        base = cls(**defaults)
        if given is None:
            return base
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(given) - known)
        if unknown:
            raise InputError(f"unknown provenance field {unknown[0]!r}: use {', '.join(sorted(known))}")
        values = dict(given)
        for key in ("parameters", "configuration"):
            if key in values:
                values[key] = dict(values[key] or {})
        for key in ("units", "joints", "notes"):
            if values.get(key) is not None:
                values[key] = tuple(values[key])
        return replace(base, **values)

    def at(self, configuration: Mapping[str, float], parameters: Mapping[str, float] | None = None) -> "Provenance":
        """The same record at another configuration (and parameter values), with its own dicts.

        Parameters
        ----------
        configuration : mapping
            Coordinate values.
        parameters : mapping, optional
            Parameter values that change (the others are kept).
        """
        params = {**self.parameters, **(parameters or {})}
        # built directly, not by dataclasses.replace: a stack makes one record per row
        return type(self)(self.robot, self.scene, params, dict(configuration), self.units, self.joints)
