"""The built-in robots: one registry entry per robot family, read without deriving anything (no sympy)."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import Callable

from ..errors import InputError

__all__ = ["RobotFamily", "FAMILIES", "ROBOT_NAMES", "robot_family", "family_builder",
           "MAX_SERIAL", "MAX_SYMBOLIC_SERIAL", "MAX_RANDOM"]

MAX_SERIAL = 500
#: serial<N> beyond this is numeric only (its linear dynamics): sympy's nonlinear derivation grows as
#: n^4.8, measured at 1.4 s for serial4, 27 s for serial8, 98 s for serial10 and 277 s for serial12,
#: which passed the five minutes of the work budget with its run.
MAX_SYMBOLIC_SERIAL = 10
MAX_RANDOM = 2000


@dataclass(frozen=True)
class RobotFamily:
    """One robot, or a family ``name<N>`` of sizes, and the builders that make it.

    Attributes
    ----------
    name : str
        The robot's name, or the family's prefix when *sizes* is set.
    symbolic : str or None
        ``"module:function"`` of the symbolic model (its nonlinear dynamics too); a sized
        family's is called with N. None: the family has no symbolic model.
    numeric : str or None
        ``"module:function"`` of a numeric model of the linear dynamics at any size, used
        instead of compiling the symbolic one (called with N, or with N and the seed).
    sizes : int
        The largest N of a family ``name<N>`` (0: a single robot).
    symbolic_sizes : int
        The largest N with a symbolic model.
    flexible : bool
        Its link mode shapes can be chosen (``link_modes``); rebuilt per parameter set.
    seeded : bool
        Its numeric builder takes the scene's seed.
    args : tuple
        Fixed arguments of the symbolic builder.
    outline : str or None
        ``"module:function"`` that draws the links at each configuration
        (:mod:`analogy.model.mechanism`); None: drawn as its circuit's nodes.
    units : tuple of (str, str)
        The SI unit of each parameter, as (name, unit) with a trailing ``#`` for the
        numbered ones (``("l#", "m")`` covers l1, l2 …); ``"1"`` is a pure number. A value
        given with a unit of another dimension is refused.
    description : str
        A few words for listings.
    """

    name: str
    symbolic: str | None = None
    numeric: str | None = None
    sizes: int = 0
    symbolic_sizes: int = 0
    flexible: bool = False
    seeded: bool = False
    args: tuple = ()
    outline: str | None = None
    units: tuple[tuple[str, str], ...] = ()
    description: str = ""

    def parameter_units(self, names) -> dict[str, str]:
        """The SI unit of each of *names* that :attr:`units` declares.

        Parameters
        ----------
        names : iterable of str
            The model's parameter names.
        """
        out = {}
        for name in names:
            for pattern, unit in self.units:
                stem = pattern.rstrip("#")
                if name == pattern or (pattern.endswith("#") and name.startswith(stem) and name[len(stem):].isdigit()):
                    out[name] = unit
                    break
        return out


_DRAWN = "analogy.model.mechanism:"
# Joint dampers and springs of revolute joints: N·m·s/rad and N·m/rad (rad is a pure number).
_SERIAL = (("l#", "m"), ("d#", "kg"), ("b#", "N*m*s"), ("k#", "N*m"), ("g", "m/s^2"))
_LINKS = (("la", "m"), ("lb", "m"), ("ma", "kg"), ("mb", "kg"), ("ja", "kg*m^2"), ("jb", "kg*m^2"),
          ("b#", "N*m*s"), ("k#", "N*m"))
_FLEXIBLE = (("l#", "m"), ("rhoA#", "kg/m"), ("EI#", "N*m^2"), ("Jh#", "kg*m^2"), ("mh#", "kg"), ("mp", "kg"),
             ("Jp", "kg*m^2"), ("g", "m/s^2"), ("modes#", "1"), ("zeta#", "1"), ("b#", "N*m*s"))

#: Every built-in robot: a fixed name resolves before a sized family of the same prefix.
FAMILIES: tuple[RobotFamily, ...] = (
    RobotFamily("redundant", "analogy.model.robots:redundant_actuators",
                units=(("d#", "kg"), ("b#", "N*s/m")),
                description="redundant rotary and prismatic actuators on one axis"),
    RobotFamily("serial2", "analogy.model.robots:serial_2dof", outline=_DRAWN + "planar_chain_outline",
                units=_SERIAL, description="the papers' 2-DOF serial arm"),
    RobotFamily("parallel2", "analogy.model.robots:five_bar", outline=_DRAWN + "five_bar_outline",
                units=_LINKS + (("d", "m"), ("me", "kg")), description="the five-bar parallel robot"),
    RobotFamily("serial3", "analogy.model.robots:serial_3dof", outline=_DRAWN + "planar_chain_outline",
                units=_SERIAL, description="the papers' 3-DOF serial arm"),
    RobotFamily("parallel3", "analogy.model.robots:parallel_3dof",
                units=_LINKS + (("rb", "m"), ("rp", "m"), ("mp", "kg"), ("jp", "kg*m^2")),
                description="the 3-RRR parallel robot"),
    RobotFamily("flex1", "analogy.model.flexible:flexible_arm", flexible=True, args=(1,),
                outline=_DRAWN + "flexible_arm_outline", units=_FLEXIBLE,
                description="one flexible link on a hub"),
    RobotFamily("flex2", "analogy.model.flexible:flexible_arm", flexible=True, args=(2,),
                outline=_DRAWN + "flexible_arm_outline", units=_FLEXIBLE,
                description="two flexible links, serial"),
    RobotFamily("flexpar", "analogy.model.flexible_parallel:flexible_parallel_arm", flexible=True,
                outline=_DRAWN + "flexible_parallel_outline",
                units=_FLEXIBLE + (("lc", "m"), ("mc", "kg"), ("md", "kg")),
                description="two flexible links, the upper one held by a parallelogram (Fig. 1.b)"),
    RobotFamily("serial", "analogy.model.robots:planar_serial", "analogy.model.serial_chain:SerialChain",
                sizes=MAX_SERIAL, symbolic_sizes=MAX_SYMBOLIC_SERIAL,
                outline=_DRAWN + "planar_chain_outline", units=_SERIAL, description="a planar N-joint arm"),
    RobotFamily("random", None, "analogy.model.robots:random_spd_model", sizes=MAX_RANDOM, seeded=True,
                description="a random SPD N-joint system"),
)

#: Names of the single built-in robots (the families are ``serial<N>`` and ``random<N>``).
ROBOT_NAMES: tuple[str, ...] = tuple(f.name for f in FAMILIES if not f.sizes)


def robot_family(name) -> tuple[RobotFamily, int | None]:
    """The family *name* belongs to and its size N (None for a single robot); one sentence if none.

    Parameters
    ----------
    name : str
        A robot name: ``redundant``, ``serial2`` …, ``serial<N>`` or ``random<N>``.
    """
    if isinstance(name, str):
        for family in FAMILIES:
            if not family.sizes and name == family.name:
                return family, None
        for family in FAMILIES:
            tail = name[len(family.name):]
            if family.sizes and name.startswith(family.name) and tail.isdigit() and 1 <= int(tail) <= family.sizes:
                return family, int(tail)
    sized = ", ".join(f"{f.name}<N> ({f.description}, N = 1 to {f.sizes})" for f in FAMILIES if f.sizes)
    raise InputError(f"unknown robot {name!r}: use {', '.join(ROBOT_NAMES)} or {sized}")


def family_builder(path: str) -> Callable:
    """The builder ``"module:function"``, imported on first use (sympy only where it is needed).

    Parameters
    ----------
    path : str
        ``"package.module:function"``.
    """
    module, _, function = path.partition(":")
    return getattr(import_module(module), function)
