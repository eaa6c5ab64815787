"""From scene data to models and node systems: the one path for scene files, the CLI and the API."""

from __future__ import annotations

import re
from contextlib import contextmanager
from typing import Iterator, Mapping

import numpy as np

from ..circuit.joint_forces import waveforms
from ..circuit.node_system import node_system, node_systems
from ..circuit.nonlinear import nonlinear_system
from ..errors import InputError, located, rendered
from ..model.base import RobotModel
from ..model.catalog import family_builder, robot_family
from ..model.compiled import compile_model, load_compiled
from ..model.equilibrium import static_equilibrium
from ..model.urdf import STANDARD_GRAVITY, urdf_model
from ..model.tree_contact import CONTACT_PARAMETERS
from ..model.urdf_robots import urdf_robot
from ..model.expressions import parse_expression, parse_number, reserved_name
from ..model.joint import JointSpace
from ..model.quantities import FORCE, check_joint_dimensions, check_parameter_units
from .spec import ModelSpec, SceneData

__all__ = ["scene_model", "symbolic_model", "scene_system", "scene_systems", "entry_value", "placed", "TOML_KEYS",
           "LABELS", "COMMAND_LINE", "CLI_KEYS"]

#: How errors name each part of a scene: in a scene file, and on the command line.
TOML_KEYS = {"robot": "[model] robot", "mass": "[model] mass", "damping": "[model] damping",
             "stiffness": "[model] stiffness", "gravity": "[model] gravity", "q": "[configuration] q",
             "topology": "[configuration] topology", "forces": "[inputs] forces",
             "initial_rates": "[inputs] initial_rates", "t_stop": "[inputs] t_stop",
             "parameters": "[parameters]", "model": "[model]", "inputs": "[inputs]",
             "dynamics": "dynamics", "link_modes": "[model] link_modes",
             "joint_frame": "[model] joint_frame", "geometric_stiffness": "[model] geometric_stiffness", "urdf": "[model] urdf",
             "joints": "[model] joints", "preset": "[solvers] preset", "step": "[solvers] step",
             "motors": "[motors]", "voltages": "[inputs] voltages"}

#: The source of a scene made from command-line flags.
COMMAND_LINE = "command line"

#: The flag that sets each part of a scene, for input errors (forces are one repeated flag,
#: so they are not numbered).
CLI_KEYS = {"robot": "--robot", "mass": "--mass", "damping": "--damping", "stiffness": "--stiffness",
            "gravity": "--gravity", "q": "--q", "topology": "--topology", "forces": "--force",
            "initial_rates": "--r0", "t_stop": "--t-stop", "parameters": "--param", "model": "--mass",
            "inputs": "--force", "dynamics": "--dynamics", "link_modes": "--link-modes", "urdf": "--urdf",
            "joint_frame": "--joint-frame", "geometric_stiffness": "--geometric-stiffness",
            "joints": "--joints", "preset": "--preset", "step": "--step", "motors": "--motors",
            "voltages": "--voltage", "numbered": False}

#: How errors name each part of a scene, by the scene's source: the command line by its flags;
#: any other source (a scene file, the API) by the scene-file keys.
LABELS: dict[str, dict] = {COMMAND_LINE: CLI_KEYS}
_QNAME = re.compile(r"^q[0-9]+$")
_MODELS: dict = {}


def _keys(scene: SceneData) -> dict:
    return LABELS.get(scene.source, TOML_KEYS)


def _where(scene: SceneData):
    """Prefix errors with the scene file, when the scene came from one."""
    src = scene.source
    return located(src if src not in (None, COMMAND_LINE) else None)


@contextmanager
def placed(scene: SceneData) -> Iterator[None]:
    """Errors raised inside name their field as the scene's front end does (a scene-file key, an option),
    after the scene's file.

    Parameters
    ----------
    scene : SceneData
        The scene the enclosed work is for.
    """
    with _where(scene), rendered(_keys(scene)):
        yield


def entry_value(value, where: str = "") -> float | str:
    """A number from a number or a constant expression; the text itself if it has names.

    Parameters
    ----------
    value : float or str
        A matrix or vector entry.
    where : str
        Position for error messages (``row 1, column 2``).
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(f"{where + ': ' if where else ''}expected a number or an expression")
    if isinstance(value, str):
        try:
            return parse_number(value)
        except InputError:
            return value            # names (or a bad expression): the symbolic parser decides
    try:
        x = float(value)
    except OverflowError:                   # an integer past 1.8e308
        x = float("inf")
    if not np.isfinite(x):
        shown = f"{value!r}" if len(repr(value)) < 40 else "a number outside the floating-point range"
        raise InputError(f"{where + ': ' if where else ''}expected a finite number, got {shown}")
    return x


def _square(rows, n: int | None, what: str) -> list[list]:
    if not isinstance(rows, tuple) or not rows or not all(isinstance(r, tuple) for r in rows):
        raise InputError(f"expected a {what} as a list of rows")
    for k, r in enumerate(rows):
        if len(r) != len(rows):
            raise InputError(f"the matrix must be square: row {k + 1} has {len(r)} entries, "
                             f"but there are {len(rows)} rows")
    if n is not None and len(rows) != n:
        raise InputError(f"expected a {n}x{n} matrix to match the mass matrix, got {len(rows)}x{len(rows)}")
    return [[entry_value(x, f"row {i + 1}, column {j + 1}") for j, x in enumerate(r)]
            for i, r in enumerate(rows)]


def _matrix_or_diagonal(value, n: int) -> list[list]:
    if isinstance(value, tuple) and value and all(isinstance(r, tuple) for r in value):
        return _square(value, n, "matrix")
    if not isinstance(value, tuple) or any(isinstance(r, tuple) for r in value):
        raise InputError("give a diagonal [b1, b2] or a matrix [[...], [...]]")
    if len(value) != n:
        raise InputError(f"expected {n} diagonal entries or a {n}x{n} matrix, got {len(value)} entries")
    diag = [entry_value(x, f"entry {k + 1}") for k, x in enumerate(value)]
    return [[diag[i] if i == j else 0.0 for j in range(n)] for i in range(n)]


def _vector(value, n: int) -> list:
    if not isinstance(value, tuple) or len(value) != n:
        raise InputError(f"expected {n} entries (one per joint)")
    return [entry_value(x, f"entry {k + 1}") for k, x in enumerate(value)]


def _matrices(spec: ModelSpec, keys: dict) -> tuple[dict, bool]:
    parts = {}
    with located(keys["mass"]):
        parts["mass"] = _square(spec.mass, None, "square matrix")
    n = len(parts["mass"])
    for label in ("damping", "stiffness"):
        if getattr(spec, label) is not None:
            with located(keys[label]):
                parts[label] = _matrix_or_diagonal(getattr(spec, label), n)
    if spec.gravity is not None:
        with located(keys["gravity"]):
            parts["gravity"] = _vector(spec.gravity, n)
    symbolic = any(isinstance(x, str) for p in parts.values() for row in p
                   for x in (row if isinstance(row, list) else [row]))
    return parts, symbolic


def _symbolic(parts: dict, params: Mapping[str, float], keys: dict):
    import sympy as sp

    from ..model.symbolic import Model
    n = len(parts["mass"])
    qnames = [f"q{k + 1}" for k in range(n)]
    qs = [sp.Symbol(name, real=True) for name in qnames]
    symbols = {k: sp.Symbol(k, real=True) for k in params}
    symbols.update(zip(qnames, qs))

    def convert(label, value, where):
        if isinstance(value, str):
            with located(keys[label]):
                try:
                    return parse_expression(value, symbols)
                except InputError as exc:
                    hint = "" if params or "unknown name" not in str(exc) else f"; give its value with {keys['parameters']}"
                    raise InputError(f"{where}: {exc}{hint}") from None
        return sp.Float(value, 17)

    mats = {}
    for label, value in parts.items():
        if label == "gravity":
            mats[label] = sp.Matrix([convert(label, x, f"entry {k + 1}") for k, x in enumerate(value)])
        else:
            mats[label] = sp.Matrix([[convert(label, x, f"row {i + 1}, column {j + 1}")
                                      for j, x in enumerate(r)] for i, r in enumerate(value)])
    free = set().union(*(m.free_symbols for m in mats.values()))
    for key in params:
        if symbols[key] not in free:
            raise InputError(f"{keys['parameters']} {key} is not used by the model's entries")
    used_q = [s for s in qs if s in free]
    with located(keys["model"]):
        return Model("custom", mats["mass"], damping=mats.get("damping"), stiffness=mats.get("stiffness"),
                     gravity=None if "gravity" not in mats else list(mats["gravity"]),
                     parameters=dict(params), coordinates=qs if used_q else (), topology="parallel")


def _check_names(params: Mapping[str, float], model, robot: str, keys: dict) -> None:
    for key in params:
        if key not in model.parameters:
            raise InputError(f"{keys['parameters']} {key}: robot {robot} has no such "
                             f"parameter (it has: {', '.join(model.parameters) or 'none'})")


def scene_model(scene: SceneData) -> object:
    """The model a scene evaluates: a compiled or symbolic robot, a symbolic model or a JointSpace.

    Built-in robots are derived once per process (and kept compiled on disk); the
    nonlinear dynamics use the symbolic model, whose Christoffel symbols they need.

    Parameters
    ----------
    scene : SceneData
        The scene.
    """
    spec, keys = scene.model, _keys(scene)
    params = scene.parameter_values
    with _where(scene):
        if spec.urdf is not None:
            return _urdf(spec, params, keys)
        if spec.robot is not None:
            with located(keys["robot"]):
                family = robot_family(spec.robot)[0]
            if family.urdf is not None:         # read from its file: the registry entry says which
                with located(keys["robot"]):
                    text, joints = urdf_robot(spec.robot)
                return _urdf(ModelSpec(urdf=text, joints=joints, base=spec.base, contacts=spec.contacts), params, keys,
                             spec.robot)
            try:
                check_parameter_units(params, family.parameter_units(params))
            except InputError as exc:
                raise InputError(f"{keys['parameters']} {exc}") from None
            flexible = family.flexible or bool(spec.conventions)
            cache = (spec, scene.dynamics) + ((tuple(sorted(params.items())),) if flexible else ())
            model = _MODELS.get(cache)
            if model is None:
                # a flexible arm is built for its parameters: its builder names an unknown one
                with located(keys["parameters"] if flexible and params else keys["robot"]):
                    model = _MODELS[cache] = _robot(spec, scene.dynamics, params if flexible else None)
            _check_names(params, model, spec.robot, keys)
            if params:
                with located(keys["parameters"]):
                    return model.with_parameters(params)    # a flexible arm's mode shapes follow them
            return model
        if spec.mass is None:
            raise InputError(f"{keys['model']}: give a built-in robot or a mass matrix")
        for key in params:
            if _QNAME.match(key) or reserved_name(key):
                raise InputError(f"{keys['parameters']} {key}: not a usable name (q1 ... qn are the "
                                 "joint coordinates; pi and e are constants; function names such as "
                                 "sin, arcsin or exp are taken by the code the model compiles to)")
        parts, symbolic = _matrices(spec, keys)
        if not symbolic and scene.dynamics == "linear":
            if params:
                raise InputError(f"{keys['parameters']} {next(iter(params))}: not used: the model's "
                                 "entries are all numbers")
            n = len(parts["mass"])
            try:
                return JointSpace(np.array(parts["mass"]), np.array(parts.get("damping", np.zeros((n, n)))),
                                  None if "stiffness" not in parts else np.array(parts["stiffness"]),
                                  None if "gravity" not in parts else np.array(parts["gravity"]))
            except InputError as exc:
                raise InputError(f"{keys.get(exc.field, keys['mass'])}: {exc}", field=exc.field) from None
        cache = (spec, scene.parameters)
        model = _MODELS.get(cache)
        if model is None:
            model = _MODELS[cache] = _symbolic(parts, params, keys)
        return model


def _urdf(spec: ModelSpec, params: Mapping[str, float], keys: dict, name: str | None = None):
    """A URDF robot's model (parsed once per process), at the scene's g."""
    for label in ("mass", "damping", "stiffness", "gravity"):
        if getattr(spec, label) is not None:
            raise InputError(f"{keys[label]}: a URDF robot has its own")
    units = {"g": "m/s^2", **(CONTACT_PARAMETERS if spec.contacts else {})}
    if unknown := [k for k in params if k not in units]:
        raise InputError(f"{keys['parameters']} {unknown[0]}: a URDF robot has no such parameter (it has: "
                         f"{', '.join(units)}{'' if spec.contacts else '; kc, cc, delta, kp and kd come with contacts'})")
    try:
        check_parameter_units(params, units)
    except InputError as exc:
        raise InputError(f"{keys['parameters']} {exc}") from None
    with located(keys.get("urdf", keys["robot"])):
        model = urdf_model(spec.urdf, spec.joints, None, float(params.get("g", STANDARD_GRAVITY)), name,
                           spec.base or "fixed", tuple(spec.contacts or ()))
    ground = {k: v for k, v in params.items() if k in CONTACT_PARAMETERS}
    with located(keys["parameters"]):
        return model.with_parameters(ground) if ground else model


def symbolic_model(scene: SceneData) -> object:
    """The scene's model as sympy expressions (a built-in robot is derived, not loaded compiled).

    Parameters
    ----------
    scene : SceneData
        The scene.
    """
    if scene.model.robot is not None and not scene.model.from_urdf:
        with _where(scene), located(_keys(scene)["robot"]):
            return _robot(scene.model, "nonlinear")
    model = scene_model(scene.replace(dynamics="nonlinear"))
    return model


def _robot(spec: ModelSpec, dynamics: str, parameters: Mapping[str, float] | None = None):
    """A built-in robot's model, as its family's registry entry says to build it (a flexible
    arm's for its *parameters*; the others take theirs when evaluated)."""
    family, size = robot_family(spec.robot)
    if family.seeded:                           # numbers only, drawn from the scene's seed
        return family_builder(family.numeric)(size, seed=spec.seed)
    if family.flexible or spec.conventions:
        # Mode shapes follow the parameters: compiled per parameter set, those numbers baked in.
        name = f"{spec.robot} {sorted(spec.conventions.items())} " \
               f"{sorted((k, float(v)) for k, v in (parameters or {}).items())}"
        cached = load_compiled(name) if dynamics == "linear" else None
        if cached is not None:
            return cached
        model = family_builder("analogy.model.robots:robot")(spec.robot, **spec.conventions)
        model = model.with_parameters(parameters) if parameters else model
        return (compile_model(model, name, baked=True) or model) if dynamics == "linear" else model
    if dynamics == "linear" and family.numeric is not None:
        return family_builder(family.numeric)(size)   # numeric at any size: no sympy
    if dynamics == "linear":
        cached = load_compiled(spec.robot)           # compiled once: no sympy either
        if cached is not None:
            return cached
    model = family_builder("analogy.model.robots:robot")(spec.robot)
    return (compile_model(model, spec.robot) or model) if dynamics == "linear" else model


def _configuration(scene: SceneData, model, keys: dict) -> list[float] | None:
    with located(keys["q"]):
        if not isinstance(model, RobotModel) or not model.coordinates:
            return None                 # a JointSpace, or a model of constant matrices
        coords = [str(c) for c in model.coordinates]
        what = f"robot {scene.model.robot}" if scene.model.robot else "the model"
        if not scene.q:
            raise InputError(f"missing: {what} needs {len(coords)} joint coordinates ({', '.join(coords)})")
        if len(scene.q) != len(coords):
            raise InputError(f"expected {len(coords)} numbers, got {len(scene.q)}: {what} needs "
                             f"{len(coords)} joint coordinates ({', '.join(coords)})")
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in scene.q):
            raise InputError("configuration q must be a list of numbers")
        check_joint_dimensions(scene.q, model.joints)
        return [float(x) for x in scene.q]


def _topology(scene: SceneData):
    t = scene.topology
    if isinstance(t, tuple):
        return np.array(t, dtype=float)
    return t


def _inputs(scene: SceneData, n: int, keys: dict, joints=None) -> dict:
    # a drive leaves the applied forces out (its motors drive the joints): its circuit carries none
    forces = scene.forces or (tuple([0.0] * n) if scene.motors else ())
    with located(keys["forces"]):
        if not forces:
            raise InputError("missing: give one force per joint, e.g. [1.0, \"sine(0, 1, 2)\"]")
        if len(forces) != n:
            raise InputError(f"expected {n} entries (one per joint), got {len(forces)}")
    out = []
    for k, item in enumerate(forces):
        with located(f"{keys['forces']}[{k + 1}]" if keys.get("numbered", True) else keys["forces"]):
            if isinstance(item, tuple) and not item:
                raise InputError("an empty list: give a number or a waveform such as \"step(1)\"")
            out.append(waveforms([item], 1)[0])
    with located(keys["forces"]):
        # a force written with a unit: a torque on a revolute joint, a force on a sliding one
        check_joint_dimensions([parse_number(f, FORCE) if isinstance(f, str) and "(" not in f else 0.0
                                for f in forces], joints, quantity="force", name="F")
    r0 = None
    if scene.initial_rates is not None:
        with located(keys["initial_rates"]):
            r0 = [entry_value(x) for x in scene.initial_rates]
            if len(r0) != n or any(isinstance(x, str) for x in r0):
                raise InputError(f"expected {n} numbers, got {len(r0)}")
            check_joint_dimensions(scene.initial_rates, joints, rates=True, name="r")
    return {"forces": out, "initial_rates": r0}


def scene_system(scene: SceneData, model=None) -> object:
    """The node system of *scene*: linear at q, or its full nonlinear dynamics from q.

    Parameters
    ----------
    scene : SceneData
        The scene.
    model : object, optional
        An already built model (from :func:`scene_model`).
    """
    keys = _keys(scene)
    m = scene_model(scene) if model is None else model
    with _where(scene):
        q = _configuration(scene, m, keys)
        n = m.dof
        inputs = _inputs(scene, n, keys, getattr(m, "joints", None))
        info = {"scene": scene.name}
        top = _topology(scene)
        params = scene.parameter_values if scene.model.robot is not None else None
        if scene.equilibrium and q is not None:
            q = [float(x) for x in static_equilibrium(m, q, params)]
        try:
            if getattr(m, "rigid_tree", False) and m.contacts and scene.dynamics != "nonlinear":
                raise InputError(f"{m.name}'s contacts with the ground are one-sided: they act in its nonlinear "
                                 "dynamics (--dynamics nonlinear), not in a circuit linearised at one pose",
                                 field="dynamics")
            if scene.dynamics == "nonlinear":
                return nonlinear_system(m, q or [0.0] * n, parameters=params, topology=top,
                                        t_stop=scene.t_stop, info=info, **inputs)
            return node_system(m, q, parameters=params, topology=top, t_stop=scene.t_stop, info=info,
                               **inputs)
        except InputError as exc:
            if exc.field is None and scene.dynamics == "nonlinear":
                exc.field = "dynamics"      # what the nonlinear build alone refuses
            raise InputError(f"{_blamed(exc, scene, keys)}: {exc}", field=exc.field) from None


_MATRICES = ("mass", "damping", "stiffness", "gravity")


def _blamed(exc: InputError, scene: SceneData, keys: dict) -> str:
    """The key of the part of *scene* that *exc* concerns: a built-in robot's matrices come
    from its parameters, and what no raiser placed is blamed on the inputs."""
    field = exc.field
    if field in _MATRICES and scene.model.robot is not None:
        return keys["parameters"]
    return keys.get(field, keys["inputs"]) if field is not None else keys["inputs"]


def scene_systems(scene: SceneData, qs, model=None, parameters=None) -> list:
    """The linear node systems of *scene* at every row of *qs*, built as one stack.

    Parameters
    ----------
    scene : SceneData
        The scene (its q is replaced by each row).
    qs : array_like, shape (count, n)
        Configurations.
    model : object, optional
        An already built model.
    parameters : mapping of str to array_like, optional
        A built-in robot's parameter values per row, replacing the scene's own.
    """
    m = scene_model(scene) if model is None else model
    keys = _keys(scene)
    with _where(scene):
        inputs = _inputs(scene, m.dof, keys, getattr(m, "joints", None))
        params = scene.parameter_values if scene.model.robot is not None else None
        if parameters:
            if params is None:
                raise InputError(f"{keys['parameters']}: only a built-in robot's parameters vary along a stack")
            params = {**params, **parameters}
        return node_systems(m, qs, parameters=params, topology=_topology(scene), t_stop=scene.t_stop,
                            info={"scene": scene.name}, **inputs)
