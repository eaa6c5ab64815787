"""What model a scene uses, as plain data: a built-in robot, or matrices of numbers and expressions."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Mapping, Protocol

from ..model.catalog import URDF_NAMES
from .rules import check_model_spec

__all__ = ["ModelSpec", "SceneData", "freeze"]

#: A URDF's robot name, read without parsing the file; kept to what a file name may hold.
_ROBOT_NAME = re.compile(r"<robot\b[^>]*?\bname\s*=\s*[\"']([^\"']*)[\"']")
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def freeze(value) -> object:
    """Lists to tuples, recursively, so that specs from TOML or the CLI are hashable.

    Parameters
    ----------
    value : object
        A value, or a list or tuple of values.
    """
    if isinstance(value, (list, tuple)):
        items = [freeze(v) for v in value]
        if type(value) is tuple and all(a is b for a, b in zip(items, value)):
            return value        # frozen already: the same object, so scenes made by replace share it
        return tuple(items)
    return value


@dataclass(frozen=True)
class ModelSpec:
    """What model a scene uses: a built-in robot, or matrices of numbers and expressions.

    Attributes
    ----------
    robot : str or None
        A built-in robot (``serial2``, ``serial<N>``, ``random<N>`` …).
    mass : tuple of tuple or None
        Rows of the mass matrix: numbers or expression strings in q1 … qn and the
        parameter names.
    damping, stiffness : tuple or None
        A tuple of entries (a diagonal) or of rows (a matrix).
    gravity : tuple or None
        One entry per joint.
    seed : int
        Random robots only: the seed of their mass matrix.
    link_modes : str or None
        Flexible arms only: ``"clamped-free"`` or ``"clamped-mass"`` mode shapes (None: the
        joint frame's, see :func:`analogy.model.conventions.link_modes_for`).
    urdf : str or None
        A URDF robot: the file's text (its content, not its path, is part of the scene).
    joints : tuple of str or None
        A URDF robot's movable joints kept (None: all); the others are frozen at 0.
    joint_frame : str or None
        Flexible arms only: joints measured from the previous link's undeformed ``"axis"``
        (None, the paper's) or its deformed ``"tip"``.
    geometric_stiffness : bool or None
        Flexible arms only: gravity's axial-load stiffness (None: on in the tip frame).
    base : str or None
        URDF robots only: ``"floating"`` frees the root link (six more coordinates, the
        base's slides and Z-Y-X angles first); None or ``"fixed"`` holds it to the world.
    contacts : tuple of str or None
        URDF robots only: the links whose origins meet the ground (feet), with the ground's
        kc, cc and delta among the parameters.
    """

    robot: str | None = None
    mass: tuple | None = None
    damping: tuple | None = None
    stiffness: tuple | None = None
    gravity: tuple | None = None
    seed: int = 0
    link_modes: str | None = None
    urdf: str | None = None
    joints: tuple | None = None
    joint_frame: str | None = None
    geometric_stiffness: bool | None = None
    base: str | None = None
    contacts: tuple | None = None

    def __post_init__(self):
        check_model_spec(self)

    @classmethod
    def of(cls, robot: str | None = None, **parts) -> "ModelSpec":
        """A spec whose matrix parts may be given as lists (they are stored as tuples).

        Parameters
        ----------
        robot : str, optional
            A built-in robot name.
        **parts
            ``mass``, ``damping``, ``stiffness``, ``gravity``, ``seed`` and ``link_modes``.
        """
        return cls(robot, **{k: freeze(v) for k, v in parts.items()})

    @property
    def conventions(self) -> dict[str, Any]:
        """The flexible-arm conventions set (link_modes, joint_frame, geometric_stiffness), by name."""
        return {k: getattr(self, k) for k in ("link_modes", "joint_frame", "geometric_stiffness")
                if getattr(self, k) is not None}

    @property
    def from_urdf(self) -> bool:
        """Whether the robot is read from a URDF: given as its text, or named in the registry with its file."""
        return self.urdf is not None or (isinstance(self.robot, str) and self.robot in URDF_NAMES)

    @property
    def label(self) -> str:
        """The robot's name (a URDF's own ``<robot name>``, as a file name keeps it), or ``custom``."""
        if self.robot:
            return self.robot
        if self.urdf is None:
            return "custom"
        found = _ROBOT_NAME.search(self.urdf)
        name = _UNSAFE.sub("_", found.group(1)).strip("._-")[:60] if found else ""
        return name or "urdf"


class SceneData(Protocol):
    """What building a scene reads of it (:class:`~analogy.scenes.scene.Scene` has it all)."""

    name: str
    model: ModelSpec
    q: tuple
    parameters: tuple
    topology: Any
    forces: tuple
    motors: tuple
    initial_rates: tuple | None
    t_stop: float
    dynamics: str
    node_voltages: Any
    element_currents: Any
    source: str | None

    @property
    def parameter_values(self) -> Mapping[str, float]: ...

    def replace(self, **changes) -> "SceneData":
        """A copy with *changes*.

        Parameters
        ----------
        **changes
            New field values.
        """

    def system(self, model=None) -> object:
        """The scene's node system.

        Parameters
        ----------
        model : object, optional
            An already built model.
        """
