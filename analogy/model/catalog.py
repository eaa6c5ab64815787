"""Names of the built-in robots, checked without deriving anything (no sympy)."""

from __future__ import annotations

from ..errors import InputError

__all__ = ["ROBOT_NAMES", "check_robot_name", "MAX_SERIAL", "MAX_SYMBOLIC_SERIAL", "MAX_RANDOM"]

#: Fixed built-in robots; ``serial<N>`` and ``random<N>`` name families.
ROBOT_NAMES = ("redundant", "serial2", "parallel2", "serial3", "parallel3", "flex1", "flex2")
MAX_SERIAL = 500
#: serial<N> beyond this is numeric only (its linear dynamics): sympy takes minutes past it.
MAX_SYMBOLIC_SERIAL = 12
MAX_RANDOM = 2000


def check_robot_name(name) -> str:
    """*name* if it names a built-in robot, else one sentence listing the robots there are.

    Parameters
    ----------
    name : str
        ``redundant``, ``serial2``, ``serial3``, ``parallel2``, ``parallel3``, ``flex1``, ``flex2``,
        ``serial<N>`` (a planar N-joint arm) or ``random<N>`` (a random SPD N-joint system).
    """
    if isinstance(name, str):
        if name in ROBOT_NAMES:
            return name
        for family, top in (("serial", MAX_SERIAL), ("random", MAX_RANDOM)):
            tail = name[len(family):]
            if name.startswith(family) and tail.isdigit() and 1 <= int(tail) <= top:
                return name
    raise InputError(f"unknown robot {name!r}: use {', '.join(ROBOT_NAMES)}, serial<N> "
                     f"(a planar N-joint arm, N = 1 to {MAX_SERIAL}, e.g. serial4) or random<N> "
                     f"(a random N-joint system, N = 1 to {MAX_RANDOM})")
