"""Command-line scene flags: the options every scene command shares, and the Scene they describe."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from ..circuit.topology import TOPOLOGY_NAMES
from ..errors import InputError, located, rendered
from ..model.catalog import MAX_SERIAL, ROBOT_NAMES, URDF_NAMES
from ..model.conventions import CONVENTIONS, JOINT_FRAMES, LINK_MODES
from ..model.expressions import (
    parse_expression,
    parse_matrix,
    parse_number,
    parse_vector,
    split_entries,
)
from ..model.quantities import ANY, COORDINATE, RATE
from ..model.tree_contact import CONTACT_PARAMETERS
from ..presets import PRESETS, Preset
from ..progress import Heartbeat
from ..presets import preset as get_preset
from ..scenes.build import CLI_KEYS, COMMAND_LINE, scene_model
from ..scenes.builtin import SCENES, scene
from ..scenes.scene import Scene
from ..scenes.spec import ModelSpec
from ..model.urdf_file import read_urdf

__all__ = ["CLI_KEYS", "PRESET_HELP", "built_system", "scene_from_args", "scene_options", "solver_list"]



#: The --preset help text: each preset and what it promises.
PRESET_HELP = ("accuracy preset: " + "; ".join(f"{k} ({p.description})" for k, p in PRESETS.items())
               + "; or a tolerance from 1e-9 to 1e-2 on each output's error over its own peak (--tol 1e-5)")


def preset_option(p: argparse.ArgumentParser, default: str | None = "accurate", help: str = PRESET_HELP) -> None:
    """``--preset`` (or ``--tol``): a preset's name or a tolerance, checked as it is parsed.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The subcommand's parser.
    default : str or None
        The preset when none is given (None: the scene's own).
    help : str
        What the option does for this command.
    """
    p.add_argument("--preset", "--tol", dest="preset", default=default, type=preset_setting, metavar="PRESET", help=help)


def preset_setting(text: str) -> Preset:
    """The preset *text* names (``fast``, ``accurate`` or a tolerance, as ``1e-05``): the one place
    the command line turns a preset's name into its settings."""
    try:
        return get_preset(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def scene_options(p: argparse.ArgumentParser, preset: str = "accurate") -> None:
    """Add the scene flags (model, configuration, inputs, t_stop) and ``--preset`` to *p*.

    Parameters
    ----------
    p : argparse.ArgumentParser
        A command's parser.
    preset : str
        The default preset.
    """
    g = p.add_argument_group("scene (defaults: the built-in default scene; numbers are SI: m, kg, s, rad, "
                             "N, N·m; a number may carry a unit instead, e.g. '100 mm', '30 deg')")
    g.add_argument("--scene", default="default", help="built-in scene to start from (see 'analogy scenes')")
    g.add_argument("--robot", help=f"built-in robot: {', '.join(ROBOT_NAMES)}, serial<N> (a planar "
                                   f"N-joint arm, e.g. serial4, N up to {MAX_SERIAL}) or random<N>; or from "
                                   f"example-robot-data (pip install 'analogy[robots]'): {', '.join(URDF_NAMES)}. "
                                   "A robot with a built-in scene of its name "
                                   f"({', '.join(s for s in SCENES if s != 'default')}) "
                                   "starts from that scene, its pose, forces and initial rates included; "
                                   "the other options change it")
    g.add_argument("--urdf", metavar="FILE", help="a robot from its URDF file (revolute, continuous, prismatic "
                   "and fixed joints; gravity along -z, --param g=0 turns it off); q1..qn follow its movable "
                   "joints depth first, each link's joints by name (Pinocchio's order)")
    g.add_argument("--base", choices=("fixed", "floating"), help="a URDF robot's root link: held fixed to the "
                   "world (fixed, the default, said in one line when the root is not the world) or free-flying "
                   "(floating: six more coordinates first, base_x, base_y, base_z and the Z-Y-X angles base_yaw, "
                   "base_pitch, base_roll)")
    g.add_argument("--contacts", metavar="LINKS", help="a URDF robot's links that meet the ground plane z = 0, "
                   "comma-separated, or 'feet' (every link named like a foot): a one-sided spring and damper at "
                   "each link's origin, the ground's kc, cc and delta among the --param (nonlinear dynamics)")
    g.add_argument("--joints", metavar="NAMES", help="with --urdf: the movable joints kept, e.g. "
                   "'shoulder_pan_joint,elbow_joint'; the others are frozen at 0")
    g.add_argument("--mass", metavar="VECTOR|MATRIX", help="mass matrix, e.g. '[[m1, m3], [m3, m2]]', or its "
                   "diagonal '[m1, m2]'; "
                   "may use --param names and q1..qn")
    g.add_argument("--damping", metavar="VECTOR|MATRIX", help="damping: diagonal '[b1, b2]' or a matrix")
    g.add_argument("--stiffness", metavar="VECTOR|MATRIX", help="stiffness: diagonal or a matrix")
    g.add_argument("--gravity", metavar="VECTOR", help="gravity load G(q), one entry per joint, "
                   "e.g. '[9.81*m*cos(q1), 0]'; with --mass")
    g.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="parameter value (repeatable), e.g. l1=0.5 or l1='500 mm'; qK=VALUE sets "
                        "joint coordinate K, e.g. q2=pi/4 or q2='45 deg'")
    g.add_argument("--link-modes", choices=LINK_MODES,
                   help="flexible arms: each link's mode shapes, a cantilever's or loaded by the tip mass "
                        "and inertia the link carries (default: clamped-free in the axis frame, "
                        "clamped-mass in the tip frame)")
    g.add_argument("--joint-frame", choices=JOINT_FRAMES,
                   help="flexible arms: joint 2 measured from link 1's undeformed axis (default, the "
                        "paper's equations) or from its deformed tip (a physical clamp: --locked 2 holds "
                        "the elbow's slope, and the elbow motor pushes back on link 1's tip)")
    g.add_argument("--geometric-stiffness", choices=("on", "off"),
                   help="flexible arms: gravity's axial-load stiffness of the links, which stiffens a "
                        "hanging link and softens an upright one (default: on in the tip frame, off in "
                        "the axis frame)")
    g.add_argument("--q", metavar="VALUES", help="configuration [rad or m], e.g. '0, 0.3' or '0, 30 deg'")
    g.add_argument("--topology", metavar="serial|parallel|modal|MATRIX",
                   help="joint-to-node map: serial, parallel, modal (one node per mode) or a matrix T with v = T r "
                        "(default: the robot's own; modal for a linear robot of more than 12 joints whose own "
                        "circuit is dense, where the modes' is not)")
    g.add_argument("--force", action="append", metavar="SPEC",
                   help="force on the next joint [N·m or N] (repeat once per joint): a number, step(a), "
                        "step(a, delay, rise), pulse(v1, v2, delay=0, rise=1e-6, fall=1e-6, width=1, "
                        "period=one pulse), sine(offset, amplitude, frequency, delay=0, damping=0, "
                        "phase=0 [deg]), pwl(t1, v1, t2, v2, ...)")
    g.add_argument("--r0", metavar="VALUES", help="initial joint rates [rad/s or m/s], e.g. '0, 0'")
    g.add_argument("--t-stop", metavar="SECONDS", help="end time of the simulation [s] (default 10, "
                   "or the scene's), e.g. 2 or '500 ms'")
    g.add_argument("--equilibrium", action="store_true", help="settle the elastic (modal) coordinates "
                   "at the static equilibrium under gravity first, the joints held at --q")
    preset_option(p, preset)


def _split_param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip().isidentifier():
        raise InputError(f"--param needs NAME=VALUE, got {text!r}")
    try:
        return name.strip(), parse_number(value, ANY)      # the model judges the unit's dimension
    except InputError as exc:
        raise InputError(f"--param {name.strip()}: {exc}") from None


def _option(flag: str, parse, *args, **kwargs):
    """*parse* of an option's text, its errors placed at the option."""
    with located(flag):
        return parse(*args, **kwargs)


def _entries(text: str | None, label: str):
    if text is None:
        return None
    try:
        return split_entries(text)
    except InputError as exc:
        raise InputError(f"{label}: {exc}") from None


def _fitted(sc: Scene, model) -> dict:
    """The scene's joint values on *model*, where a changed mode count gives it other coordinates:
    the joints' q, forces and rates kept (they come first), every modal coordinate at rest and undriven."""
    if model.dof == len(sc.q):
        return {}
    joints = sum(kind != "modal" for kind in (model.joints or ("revolute",) * model.dof))

    def fit(values):
        return tuple(values[:joints]) + (0.0,) * (model.dof - joints)
    out = {"q": fit(sc.q), "forces": fit(sc.forces)}
    if sc.initial_rates is not None:
        out["initial_rates"] = fit(sc.initial_rates)
    return out


def _with_contacts(spec: ModelSpec, args, label: str, params: dict) -> ModelSpec:
    """*spec* with the --contacts links: their names, or for ``feet`` every link named like a foot."""
    if not getattr(args, "contacts", None):
        return spec
    names = tuple(n.strip() for n in args.contacts.split(",") if n.strip())
    if names == ("feet",):
        links = scene_model(Scene.of(label, spec, parameters=params, source=COMMAND_LINE)).link_frames
        names = tuple(sorted(n for n in links if "foot" in n.lower() or "feet" in n.lower()))
        if not names:
            raise InputError(f"--contacts feet: {label} has no link named like a foot; name the links that touch "
                             f"the ground, e.g. --contacts {','.join(sorted(links)[-2:])}")
    return replace(spec, contacts=names)


def _base(args) -> str | None:
    """The --base a URDF robot's spec takes: None for the fixed default (the scene's key unchanged)."""
    return "floating" if getattr(args, "base", None) == "floating" else None


def _urdf_defaults(spec: ModelSpec, label: str, params: dict, args) -> dict:
    """A URDF robot's scene changes: its default pose, gravity, forces and horizon where the
    options leave them, said in one line (with the sentence on its base) on stderr."""
    from ..scenes.robot_defaults import base_note, robot_defaults     # scipy's optimizer: URDF robots only
    ground = {k: params.pop(k) for k in CONTACT_PARAMETERS if k in params}
    spec = _with_contacts(spec, args, label, params)
    params.update(ground)
    model = scene_model(Scene.of(label, spec, parameters=params, source=COMMAND_LINE))
    q = None if args.q is None else _option("--q", parse_vector, args.q, numeric=True, dimension=COORDINATE)
    if q is not None and len(q) != model.dof:
        raise InputError(f"--q: expected {model.dof} numbers, got {len(q)}: {label} has {model.dof} joints "
                         f"({', '.join(model.joint_names)})")
    d = robot_defaults(model, params.get("g"), q, label)
    if not (args.force and args.t_stop is not None and q is not None):
        print(f"analogy: note: {d.note}", file=sys.stderr)
    if getattr(args, "base", None) != "fixed" and (base := base_note(model)) is not None:
        print(f"analogy: note: {base}", file=sys.stderr)
    return {"model": spec, "q": d.q, "parameters": {**params, "g": d.g}, "forces": d.forces, "t_stop": d.t_stop,
            "initial_rates": None, "topology": None, "robot_note": d.note}


def _model_changes(args, sc: Scene, params: dict, chosen: dict, changes: dict) -> None:
    """The robot the options describe, into *changes*: a mass matrix, a URDF, a named robot, or the
    scene's own arm with other conventions or parameters; one sentence for options that do not go together."""
    if getattr(args, "base", None) is not None and args.urdf is None and args.robot not in URDF_NAMES:
        raise InputError("--base frees or holds a URDF robot's root link (--urdf FILE, or a named robot such as "
                         "ur5); the built-in robots have no base to free")
    if args.mass is not None:
        mass = _entries(args.mass, "--mass")
        if mass and not any(isinstance(r, list) for r in mass):
            # a vector is the diagonal, as for --damping and --stiffness
            mass = [[x if i == j else "0" for j in range(len(mass))] for i, x in enumerate(mass)]
        if not mass or not all(isinstance(r, list) and r for r in mass):
            if not mass or any(r == [] for r in mass):
                raise InputError("--mass must be a matrix like [[m1, m3], [m3, m2]], not empty")
            try:
                parse_expression(args.mass, {})       # the grammar's own sentence first
            except InputError as exc:
                if "unknown name" not in str(exc):
                    raise InputError(f"--mass: {exc}") from None
            raise InputError("--mass must be a matrix like [[m1, m3], [m3, m2]]")
        spec = ModelSpec.of(None, mass=mass, **chosen, **{k: _entries(getattr(args, k), f"--{k}")
                                                          for k in ("damping", "stiffness", "gravity")})
        n = len(mass)
        changes.update(model=spec, parameters=params, q=(0.0,) * n, initial_rates=None, topology=None,
                       forces=(1.0,) * n)
    elif args.urdf is not None:
        if args.robot is not None:
            raise InputError("--robot and --urdf both name the robot: give one")
        names = None if args.joints is None else tuple(n.strip() for n in args.joints.split(",") if n.strip())
        spec = ModelSpec(urdf=_option("--urdf", read_urdf, args.urdf), joints=names or None, base=_base(args),
                         **chosen)
        changes.update(_urdf_defaults(spec, spec.label, params, args))
    elif args.robot in URDF_NAMES:      # its joints are the registry's: a --joints is refused by the rules
        joints = None if args.joints is None else tuple(n.strip() for n in args.joints.split(","))
        changes.update(_urdf_defaults(ModelSpec(robot=args.robot, joints=joints, base=_base(args), **chosen),
                                      args.robot, params, args))
    elif args.joints is not None:
        raise InputError("--joints selects the joints of a --urdf robot")
    elif args.damping or args.stiffness or args.gravity:
        raise InputError("--damping, --stiffness and --gravity need --mass (built-in robots have their own; "
                         "the serial arms take --param g=9.81)")
    elif args.robot is not None and args.robot != sc.model.robot:
        spec = ModelSpec(robot=args.robot, **chosen)
        probe = Scene.of(args.robot, spec, parameters=params, source=COMMAND_LINE)
        model = scene_model(probe)          # one sentence on an unknown name or parameter
        # a unit step on every joint the model drives; a flexible link's modal amplitude is not driven
        joints = model.joints or ("revolute",) * model.dof
        forces = tuple(float(kind != "modal") for kind in joints)
        changes.update(model=spec, q=(0.0,) * len(model.coordinates), parameters=params,
                       forces=forces, initial_rates=None, topology=None)
    elif chosen or params:              # conventions on a model that is not a flexible arm: the rules refuse              # the scene's own arm, with these conventions and parameters
        if chosen:
            changes["model"] = replace(sc.model, **chosen)
        if params:
            changes["parameters"] = dict(sc.parameters, **params)
        if sc.model.robot is not None and (chosen or any(k.startswith("modes") for k in params)):
            changes.update(_fitted(sc, scene_model(sc.replace(**changes))))


def _motion_changes(args, sc: Scene, coords: dict, changes: dict) -> None:
    """The configuration, topology, forces, initial rates, horizon and dynamics the options set, into *changes*."""
    if args.q is not None:
        changes["q"] = tuple(_option("--q", parse_vector, args.q, numeric=True, dimension=COORDINATE))
    if coords:
        if args.q is not None:
            raise InputError(f"--q and --param {', '.join(coords)} both set the configuration: use one")
        q = list(changes.get("q", sc.q))
        for key, value in coords.items():
            if not 1 <= (k := int(key[1:])) <= len(q):
                raise InputError(f"--param {key}: the model has joint coordinates q1 to q{len(q)}")
            q[k - 1] = value
        changes["q"] = tuple(q)
    if args.topology is not None:
        t = args.topology.strip()
        if t.startswith("["):
            changes["topology"] = tuple(tuple(r) for r in parse_matrix(t, numeric=True))
        elif t in TOPOLOGY_NAMES:
            changes["topology"] = t
        else:
            raise InputError(f"unknown topology {t!r}: use serial, parallel, modal or a matrix like [[1, 0], [1, 1]]")
    if args.force:
        changes["forces"] = tuple(args.force)
    if args.r0 is not None:
        changes["initial_rates"] = tuple(_option("--r0", parse_vector, args.r0, numeric=True, dimension=RATE))
    if args.t_stop is not None:
        changes["t_stop"] = _option("--t-stop", parse_number, args.t_stop, "time")
    if args.equilibrium:
        changes["equilibrium"] = True
    if getattr(args, "dynamics", None) in ("linear", "nonlinear"):      # "both" is the command's
        changes["dynamics"] = args.dynamics


def scene_from_args(args) -> Scene:
    """The scene the CLI options describe: a built-in scene with the options' changes.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed scene options (see :func:`build_parser`).
    """
    # A robot with a scene of its own starts from that scene (a configuration that assembles).
    start = args.robot if args.robot in SCENES and args.scene == "default" else args.scene
    sc = scene(start)
    params = dict(_split_param(p) for p in args.param)
    coords = {k: params.pop(k) for k in list(params) if k[0] == "q" and k[1:].isdigit()}
    changes: dict = {"source": COMMAND_LINE}
    chosen = {k: getattr(args, k) for k in CONVENTIONS if getattr(args, k, None) is not None}
    if "geometric_stiffness" in chosen:
        chosen["geometric_stiffness"] = chosen["geometric_stiffness"] == "on"
    with rendered(CLI_KEYS):            # a scene rule's refusal, said at its option
        _model_changes(args, sc, params, chosen, changes)
        _motion_changes(args, sc, coords, changes)
        robot_note = changes.pop("robot_note", None)
        new = sc.replace(**changes)
    if robot_note is not None:      # a URDF robot: its own name, and how its defaults were chosen
        new = new.replace(name=new.model.label, description=robot_note.partition(": ")[2])
    elif new.key != sc.key:         # name and describe what was actually built
        label = new.model.label
        new = new.replace(name=label if label != sc.name else sc.name,
                          description=f"{label}, changed from the built-in scene {sc.name!r} on the "
                                      "command line")
    return new


def solver_list(text: str | None) -> tuple[str, ...] | None:
    """The registered solvers *text* names, comma-separated, each once (None stays None).

    Parameters
    ----------
    text : str or None
        ``--solvers``, e.g. ``"spice,exact"``.
    """
    if text is None:
        return None
    from ..solvers.registry import SOLVER_NAMES
    names = tuple(dict.fromkeys(s.strip() for s in text.split(",") if s.strip()))
    if not names or (bad := [s for s in names if s not in SOLVER_NAMES]):
        raise InputError(f"--solvers: unknown solver {bad[0]!r}" if names else "--solvers names no solver")
    return names


def built_system(sc: Scene, realizable: bool = False) -> object:
    """*sc*'s node system, with a line every 15 s while it is built past 3 s (a large arm's symbolic
    nonlinear derivation takes minutes: serial10's took 98 s, serial12's 277 s).

    Parameters
    ----------
    sc : Scene
        The scene.
    realizable : bool
        Its realizable circuit (negative elements behind 1:-1 couplings).
    """
    beat = Heartbeat()
    beat("model build")
    try:
        system = sc.system()
    finally:
        beat(None)
    return system.realized() if realizable else system
