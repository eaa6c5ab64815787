"""Every named robot: one registry entry per robot or family, built-in or from a URDF, read without deriving anything."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import Callable, Literal

from ..errors import InputError

__all__ = ["Base", "BASES", "RobotFamily", "FAMILIES", "ROBOT_NAMES", "URDF_NAMES", "robot_family", "family_builder",
           "MAX_SERIAL", "MAX_SYMBOLIC_SERIAL", "MAX_RANDOM"]

#: How a URDF robot's root link is held: to the world, or free-flying.
Base = Literal["fixed", "floating"]
BASES: tuple[str, ...] = ("fixed", "floating")

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
    urdf : str or None
        The robot's URDF file under example-robot-data's robots folder
        (:func:`~analogy.model.urdf_robots.urdf_robot`); None: a built-in model.
    joints : tuple of str or None
        The URDF's joints kept (the others frozen); None: every movable joint.
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
    urdf: str | None = None
    joints: tuple[str, ...] | None = None
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
    RobotFamily("hopper", "analogy.model.legged:hopper", outline=_DRAWN + "hopper_outline",
                units=(("mb", "kg"), ("mf", "kg"), ("l0", "m"), ("kl", "N/m"), ("bl", "N*s/m"), ("kc", "N/m"),
                       ("cc", "N*s/m"), ("delta", "m"), ("g", "m/s^2")),
                description="a one-legged hopper on a one-sided ground contact"),
    RobotFamily("random", None, "analogy.model.robots:random_spd_model", sizes=MAX_RANDOM, seeded=True,
                description="a random SPD N-joint system"),
    # Real arms from example-robot-data's URDF files, derived when first asked for (their default
    # scenes: analogy.scenes.robot_defaults)
    RobotFamily("ur3", urdf="ur_description/urdf/ur3_robot.urdf", description="Universal Robots UR3, 6 joints"),
    RobotFamily("ur5", urdf="ur_description/urdf/ur5_robot.urdf", description="Universal Robots UR5, 6 joints"),
    RobotFamily("ur10", urdf="ur_description/urdf/ur10_robot.urdf", description="Universal Robots UR10, 6 joints"),
    # the fingers are mimic joints: the arm's seven are kept and the fingers frozen
    RobotFamily("panda", urdf="panda_description/urdf/panda.urdf",
                joints=tuple(f"panda_joint{k}" for k in range(1, 8)), description="Franka Emika Panda, 7 joints"),
    RobotFamily("kinova", urdf="kinova_description/robots/kinova.urdf", description="Kinova Jaco2 (j2s6s200), 6 joints"),
    RobotFamily("xarm7", urdf="xarm_description/urdf/xarm7.urdf", description="UFACTORY xArm7, 7 joints"),
    RobotFamily("z1", urdf="z1_description/urdf/z1.urdf", description="Unitree Z1, 6 joints and its gripper"),
    RobotFamily("double_pendulum", urdf="double_pendulum_description/urdf/double_pendulum.urdf",
                description="a planar double pendulum, 2 joints"),
)

#: Names of the single built-in models (the families are ``serial<N>`` and ``random<N>``).
ROBOT_NAMES: tuple[str, ...] = tuple(f.name for f in FAMILIES if not f.sizes and f.urdf is None)
#: Names of the robots loaded from example-robot-data's URDF files.
URDF_NAMES: tuple[str, ...] = tuple(f.name for f in FAMILIES if f.urdf is not None)


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
    raise InputError(f"unknown robot {name!r}: use {', '.join(ROBOT_NAMES)}, {sized}, "
                     f"or a URDF robot ({', '.join(URDF_NAMES)})")


def family_builder(path: str) -> Callable:
    """The builder ``"module:function"``, imported on first use (sympy only where it is needed).

    Parameters
    ----------
    path : str
        ``"package.module:function"``.
    """
    module, _, function = path.partition(":")
    return getattr(import_module(module), function)
