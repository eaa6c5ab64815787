"""The named robots' URDF files, read from the example-robot-data package: ur5, panda and other arms."""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

from ..errors import InputError
from .catalog import FAMILIES, robot_family
from .urdf_file import read_urdf

__all__ = ["URDF_ROBOTS", "urdf_robot"]

#: Name: (the file under example-robot-data's robots folder, the joints kept or None for all): the
#: registry's URDF entries (:data:`~analogy.model.catalog.FAMILIES`), seen by name.
URDF_ROBOTS: dict[str, tuple[str, tuple | None]] = {f.name: (f.urdf, f.joints) for f in FAMILIES if f.urdf}


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
    family = robot_family(name)[0]
    if family.urdf is None:
        raise InputError(f"robot {name!r} is built in, not read from a URDF file", field="robot")
    return read_urdf(_robots_folder() / family.urdf), family.joints
