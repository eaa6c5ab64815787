"""The flexible arms' conventions by name: mode shapes, the frame joints are measured in, gravity's axial stiffness."""

from __future__ import annotations

from typing import Literal

__all__ = ["LinkModes", "JointFrame", "LINK_MODES", "JOINT_FRAMES", "CONVENTIONS", "link_modes_for"]

#: Mode shapes: each link clamped-free (the paper's), or clamped and loaded by what its tip carries.
LinkModes = Literal["clamped-free", "clamped-mass"]
#: Where joint i + 1 is measured from: link i's undeformed axis (the paper's), or its deformed tip.
JointFrame = Literal["axis", "tip"]
LINK_MODES: tuple[str, ...] = ("clamped-free", "clamped-mass")
JOINT_FRAMES: tuple[str, ...] = ("axis", "tip")
#: Every convention a flexible arm takes, with its choices (None, the default, leaves it to the frame).
CONVENTIONS: dict[str, tuple] = {"link_modes": LINK_MODES, "joint_frame": JOINT_FRAMES,
                                 "geometric_stiffness": (True, False)}


def link_modes_for(joint_frame: str | None, link_modes: str | None = None) -> str:
    """The mode shapes a frame takes unless told: clamped-free in the axis frame (the paper's),
    clamped-mass in the tip frame.

    A clamp at the elbow carries a bending moment, and cantilever shapes have none at their
    tip: against a finite-element frame at 4 modes a link, they leave the first locked
    frequency of flex2 1.1 % high, the loaded link's own shapes 4e-5
    (``tests/test_flexible_frames.py``).

    Parameters
    ----------
    joint_frame : {"axis", "tip"} or None
        Where each joint is measured from (None: the axis).
    link_modes : {"clamped-free", "clamped-mass"}, optional
        The shapes asked for; None takes the frame's.
    """
    if link_modes is not None:
        return link_modes
    return "clamped-mass" if joint_frame == "tip" else "clamped-free"
