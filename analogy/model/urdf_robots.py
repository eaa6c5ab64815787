"""Named robots from URDF files of the example-robot-data package: ur5, panda and other arms."""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

from ..errors import InputError
from .urdf_file import read_urdf

__all__ = ["URDF_ROBOTS", "urdf_robot"]

#: Name: (the file under example-robot-data's robots folder, the joints kept or None for all).
URDF_ROBOTS: dict[str, tuple[str, tuple | None]] = {
    "ur3": ("ur_description/urdf/ur3_robot.urdf", None),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", None),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", None),
    # the fingers are mimic joints: the arm's seven are kept and the fingers frozen
    "panda": ("panda_description/urdf/panda.urdf", tuple(f"panda_joint{k}" for k in range(1, 8))),
    "kinova": ("kinova_description/robots/kinova.urdf", None),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", None),
    "z1": ("z1_description/urdf/z1.urdf", None),
    "double_pendulum": ("double_pendulum_description/urdf/double_pendulum.urdf", None),
}


def _robots_folder() -> Path:
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        raise InputError("the named URDF robots come from the example-robot-data package: "
                         "pip install 'analogy[robots]' (or give the file with --urdf)", field="robot") from None
    for folder in ("cmeel.prefix/share/example-robot-data/robots", "share/example-robot-data/robots"):
        path = Path(str(dist.locate_file(folder)))
        if path.is_dir():
            return path
    raise InputError("example-robot-data is installed but its robots folder is not found: reinstall it",
                     field="robot")


def urdf_robot(name: str) -> tuple[str, tuple | None]:
    """The URDF text of the named robot and the joints it keeps.

    Parameters
    ----------
    name : str
        One of :data:`URDF_ROBOTS`.
    """
    relative, joints = URDF_ROBOTS[name]
    return read_urdf(_robots_folder() / relative), joints
