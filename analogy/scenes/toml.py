"""Scene files (TOML): parsed into :class:`~analogy.scenes.scene.Scene` data, nothing run.

A scene file describes one simulation job: a model, a configuration, the inputs,
the outputs wanted and the solvers that produce them. Example::

    name = "default"
    description = "2-DOF serial arm at q2 = 0.3 rad, step torques"

    [model]
    robot = "serial2"              # a built-in robot, or urdf = "arm.urdf", or mass = [[...]]

    [configuration]
    q = [0.0, 0.3]                 # joint coordinates q1 … qn
    topology = "serial"            # "serial", "parallel", "modal" or a matrix T, v = T·r

    [inputs]
    forces = [1.0, "sine(0, 0.5, 2)"]
    initial_rates = [0.0, 0.0]
    t_stop = 10.0

Every table and key (``[parameters]``, ``[outputs]``, ``[solvers]`` …) is described in
``docs/scenes.md``. Every key is checked: an
unknown key is an error, and a malformed scene raises
:class:`~analogy.errors.InputError` with one line naming the file, the key and the
problem, e.g. ``scene.toml: [configuration] q: expected 2 numbers, got 3``. Entries
are numbers or expression strings parsed by the restricted grammar of
:mod:`analogy.model.expressions`; nothing is evaluated as Python. Parsing builds
nothing; :func:`load_scene` then builds the system once to check the outputs' names.
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError, located, rendered
from ..model.conventions import CONVENTIONS
from ..model.urdf_file import read_urdf
from ..model.expressions import parse_number
from ..model.quantities import ANY, COORDINATE, RATE
from ..model.motors import motor_spec
from ..presets import DEFAULT_SOLVERS
from ..results.output import check_plot_path
from ..solvers.registry import SOLVER_NAMES
from .paths import check_relative_name
from .scene import OUTPUTS, Scene
from .build import TOML_KEYS
from .rules import MATRICES
from .spec import ModelSpec, freeze
from .validate import validated

__all__ = ["load_scene", "parse_scene", "parse_toml", "read_text", "scene_from_table", "toml_table", "validated"]

_TABLES = {
    "model": ("robot", "mass", "damping", "stiffness", "gravity", *CONVENTIONS, "urdf", "joints", "base", "contacts"),
    "parameters": None,         # free names
    "configuration": ("q", "topology", "equilibrium"),
    "inputs": ("forces", "voltages", "initial_rates", "t_stop"),
    "outputs": ("joint_rates", "node_voltages", "element_currents", "netlist", "csv", "plot"),
    "solvers": ("use", "preset", "errors", "estimate", "refine", "step"),
    "motors": None,             # [motors.default] and a table per joint (name or number)
}
_TOP = ("name", "description", "dynamics") + tuple(_TABLES)
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _label(key) -> str:
    key = str(key)
    return key if _BARE.match(key) else repr(key)


def _one_line(text) -> str:
    return " ".join(str(text).split())


class _Context:
    """Names the file and key in every error: a key it reads, or the field a scene rule names."""

    def __init__(self, source: str):
        self.source = source

    def error(self, key: str | None, message: str) -> InputError:
        where = f"{self.source}: {key}: " if key else f"{self.source}: "
        exc = InputError(where + _one_line(message))
        exc.located = True
        return exc

    def key(self, key: str):
        """Errors raised inside are at *key* of this file."""
        return located(f"{self.source}: {key}")

    @contextmanager
    def fields(self):
        """Errors of the scene's rules (:mod:`~analogy.scenes.rules`) raised inside are at their field's key."""
        with located(self.source), rendered(TOML_KEYS):
            yield

    def table(self, data: dict, name: str):
        value = data.get(name)
        if value is None:
            return None
        if not isinstance(value, dict):
            raise self.error(f"[{name}]", f"expected a table, got {_kind(value)}")
        allowed = _TABLES[name]
        if allowed is not None:
            for key in value:
                if key not in allowed:
                    raise self.error(None, f"unknown key [{name}] {_label(key)} "
                                           f"(known: {', '.join(allowed)})")
        return value


def _kind(value) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a table"
    return type(value).__name__


# ---------------------------------------------------------------- values

def _number(value, dimension=None) -> float:
    """A finite float from a TOML number or a constant expression string (its unit of *dimension*)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(f"expected a number, got {_kind(value)}")
    if isinstance(value, str):
        return parse_number(value, dimension)
    try:
        x = float(value)
    except OverflowError:                   # a TOML integer past 1.8e308
        x = math.inf
    if not math.isfinite(x):
        raise InputError(f"expected a finite number, got {_kind(value)} outside the floating-point range")
    return x


def _numbers(value, n: int | None = None, dimension=None) -> list[float]:
    if not isinstance(value, list):
        raise InputError(f"expected a list of numbers, got {_kind(value)}")
    if n is not None and len(value) != n:
        raise InputError(f"expected {n} numbers, got {len(value)}")
    out = []
    for k, item in enumerate(value):
        try:
            out.append(_number(item, dimension))
        except InputError as exc:
            raise InputError(f"entry {k + 1}: {exc}") from None
    return out


def load_scene(path) -> Scene:
    """Read, parse and validate the scene file *path* (its system is built to check it).

    Parameters
    ----------
    path : str or Path
        A TOML scene file.

    Raises
    ------
    InputError
        One line naming the file, the key and the problem.
    """
    path = Path(path)
    return parse_scene(read_text(path), source=path)


def read_text(path: Path, what: str = "scene file") -> str:
    """The UTF-8 text of *path*, or one sentence naming the file and what went wrong.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        What the file is, for messages.
    """
    try:
        return path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: the {what} is not UTF-8 text") from None


def parse_scene(text: str, source="scene.toml") -> Scene:
    """:func:`parse_toml`, then :func:`validated`.

    Parameters
    ----------
    text : str
        TOML text.
    source : str or Path
        The file the text came from; it names the file in errors, and relative
        output files are resolved against its folder.
    """
    return validated(parse_toml(text, source))


def parse_toml(text: str, source="scene.toml") -> Scene:
    """Parse scene TOML *text* into a :class:`Scene`, checking its structure; nothing is built or run.

    Parameters
    ----------
    text : str
        TOML text.
    source : str or Path
        The file the text came from, named in errors.
    """
    return scene_from_table(toml_table(text, source), source)


def toml_table(text: str, source="scene.toml") -> dict:
    """The TOML *text* as a dict; a syntax error is one line naming the file and the line.

    Parameters
    ----------
    text : str
        TOML text.
    source : str or Path
        The file the text came from, named in errors.
    """
    try:
        return tomllib.loads(text)
    except ValueError as exc:              # a TOMLDecodeError, or an integer past Python's 4300 digits
        message = str(exc) if isinstance(exc, tomllib.TOMLDecodeError) else "a number has too many digits"
        if "(at end of document)" in message:
            last = max(len(text.splitlines()), 1)
            message = message.replace("(at end of document)", f"(at line {last}, the end of the document)")
        raise _Context(str(source)).error(None, f"TOML syntax error: {message}") from None


def scene_from_table(data: dict, source="scene.toml") -> Scene:
    """A :class:`Scene` from a parsed scene table (see :func:`parse_toml`).

    Parameters
    ----------
    data : dict
        The parsed TOML.
    source : str or Path
        The file it came from, named in errors.
    """
    ctx = _Context(str(source))
    if "sweep" in data:
        raise ctx.error("[sweep]", "makes this file a sweep of many scenes: run it with analogy batch")
    for key in data:
        if key not in _TOP:
            kind = "table" if isinstance(data[key], dict) else "key"
            shown = f"[{_label(key)}]" if kind == "table" else _label(key)
            raise ctx.error(None, f"unknown {kind} {shown} (known: {', '.join(_TOP)})")
    path = Path(source)
    name = data.get("name", path.stem or "scene")
    description = data.get("description", "")
    dynamics = data.get("dynamics", "linear")
    for key, value in (("name", name), ("description", description), ("dynamics", dynamics)):
        if not isinstance(value, str):
            raise ctx.error(key, f"expected a string, got {_kind(value)}")
    if not name.strip():
        raise ctx.error("name", "must not be empty")
    for table in _TABLES:                  # unknown keys first, before anything else
        if isinstance(data.get(table), dict):
            ctx.table(data, table)
    outputs = _outputs(ctx, data)
    solvers = _solvers(ctx, data)
    fields = _model_fields(ctx, data)
    needs = bool(outputs["joint_rates"] or outputs["node_voltages"] or outputs["element_currents"])
    use = solvers["use"]
    if use is None:
        use = DEFAULT_SOLVERS if needs else ()
    if needs and not use:
        raise ctx.error("[solvers] use", "the outputs need a solver: choose spice, ode or exact")
    if use and not needs:
        raise ctx.error("[solvers] use", "no output needs a solver: ask for joint_rates, "
                                         "node_voltages or element_currents in [outputs]")
    for key in ("csv", "plot"):
        if outputs[key] is not None and not needs:
            raise ctx.error(f"[outputs] {key}", "needs joint_rates, node_voltages or element_currents")
    nv, ec = outputs["node_voltages"], outputs["element_currents"]
    with ctx.fields():
        return Scene.of(name, fields.pop("model"), description=description, source=str(path),
                        dynamics=dynamics, joint_rates=outputs["joint_rates"],
                        node_voltages=nv if nv is True else tuple(nv or ()),
                        element_currents=ec if ec is True else tuple(ec or ()),
                        netlist=outputs["netlist"], netlist_file=outputs["netlist_file"],
                        csv_file=outputs["csv"], plot_file=outputs["plot"], solvers=tuple(use),
                        preset=solvers["preset"], errors=solvers["errors"], estimate=solvers["estimate"],
                        refine=solvers["refine"], step=solvers["step"], **fields)


def _urdf_parts(ctx: _Context, model: dict) -> dict:
    """A URDF robot's text: the file relative to the scene file's folder, or anywhere (read, never written)."""
    name = model["urdf"]
    if not isinstance(name, str):
        raise ctx.error("[model] urdf", f"expected a file name, got {_kind(name)}")
    with ctx.key("[model] urdf"):
        return {"urdf": read_urdf(Path(str(ctx.source)).parent / name)}


def _model_spec(ctx: _Context, model: dict) -> ModelSpec:
    """The [model] table's spec: each value checked for its type here, and how they go together by
    the scene's rules (:func:`~analogy.scenes.rules.check_model_spec`)."""
    if not any(k in model for k in ("robot", "urdf", "mass")):
        raise ctx.error("[model]", "give robot = \"serial2\" (a built-in robot), urdf = \"arm.urdf\" or mass = [[...]]")
    if "robot" in model and not isinstance(model["robot"], str):
        raise ctx.error("[model] robot", f"expected a robot name, got {_kind(model['robot'])}")
    chosen = {k: model[k] for k in CONVENTIONS if k in model}
    for key, value in chosen.items():       # 1 == True: a choice must have the choices' type too
        if value not in CONVENTIONS[key] or type(value) is not type(CONVENTIONS[key][0]):
            shown = json.dumps(value) if isinstance(value, (str, bool)) else _kind(value)
            raise ctx.error(f"[model] {key}", f"expected {' or '.join(map(json.dumps, CONVENTIONS[key]))}, "
                                              f"got {shown}")
    for key in ("joints", "contacts"):      # lists of a URDF's joint or link names
        names = model.get(key)
        if names is not None and not (isinstance(names, list) and names and all(isinstance(j, str) for j in names)):
            raise ctx.error(f"[model] {key}", f"expected a list of {key[:-1] if key == 'joints' else 'link'} names")
    parts = _urdf_parts(ctx, model) if "urdf" in model else {}
    for key in MATRICES:
        if key in model:
            with ctx.key(f"[model] {key}"):
                parts[key] = _entries(model[key], key)
    with ctx.fields():
        return ModelSpec.of(model.get("robot"), base=model.get("base"), **chosen, **parts,
                            **{k: tuple(model[k]) for k in ("joints", "contacts") if k in model})


def _model_fields(ctx: _Context, data: dict) -> dict:
    """The model, configuration and inputs as Scene fields (values checked for their type only)."""
    model = ctx.table(data, "model")
    if model is None:
        raise ctx.error("[model]", "missing: give robot = \"serial2\" (a built-in robot) or mass = [[...]]")
    params_raw = ctx.table(data, "parameters") or {}
    config = ctx.table(data, "configuration") or {}
    inputs = ctx.table(data, "inputs")
    if inputs is None:
        raise ctx.error("[inputs]", "missing: give at least forces = [...] (one per joint)")
    out = {}
    params = {}
    for key, value in params_raw.items():
        with ctx.key(f"[parameters] {_label(key)}"):
            params[key] = _number(value, ANY)      # the model judges the unit's dimension
    out["parameters"] = params
    out["model"] = _model_spec(ctx, model)
    if "q" in config:
        with ctx.key("[configuration] q"):
            out["q"] = tuple(_numbers(config["q"], dimension=COORDINATE))
    if "equilibrium" in config:
        if not isinstance(config["equilibrium"], bool):
            raise ctx.error("[configuration] equilibrium", f"expected true or false, got {_kind(config['equilibrium'])}")
        out["equilibrium"] = config["equilibrium"]
    if "topology" in config:
        spec = config["topology"]
        with ctx.key("[configuration] topology"):
            if isinstance(spec, list):
                out["topology"] = tuple(tuple(_numbers(r)) if isinstance(r, list) else _bad_row()
                                        for r in spec)
            elif isinstance(spec, str):
                out["topology"] = spec
            else:
                raise InputError(f"expected \"serial\", \"parallel\", \"modal\" or a matrix, got {_kind(spec)}")
    if "motors" in data:        # a drive: each motor takes a voltage, and no applied force is left out in silence
        with ctx.key("[motors]"):
            out["motors"] = motor_spec(data["motors"], "[motors]")
        if "forces" in inputs:
            raise ctx.error("[inputs] forces", "the motors drive the joints: give voltages = [...], one per motor")
        inputs = {**inputs, "forces": inputs.get("voltages", [])}
    elif "voltages" in inputs:
        raise ctx.error("[inputs] voltages", "voltages drive motors: give them in [motors]")
    with ctx.key("[inputs] voltages" if "motors" in data else "[inputs] forces"):
        if "forces" not in inputs:
            raise InputError("missing: give one force per joint, e.g. forces = [1.0, \"sine(0, 1, 2)\"]")
        raw = inputs["forces"]
        if not isinstance(raw, list):
            raise InputError(f"expected a list with one entry per joint, got {_kind(raw)}")
    for k, item in enumerate(raw):
        with ctx.key(f"[inputs] {'voltages' if 'motors' in out else 'forces'}[{k + 1}]"):
            for w in (item if isinstance(item, list) else [item]):
                if isinstance(w, bool) or not isinstance(w, (int, float, str)):
                    raise InputError(f"expected a number or a waveform string such as \"step(1)\", "
                                     f"got {_kind(w)}")
    out["voltages" if "motors" in out else "forces"] = freeze(raw)
    if "initial_rates" in inputs:
        with ctx.key("[inputs] initial_rates"):
            out["initial_rates"] = tuple(_numbers(inputs["initial_rates"], dimension=RATE))
    if "t_stop" in inputs:
        with ctx.key("[inputs] t_stop"):
            out["t_stop"] = _number(inputs["t_stop"], "time")
    return out


def _bad_row():
    raise InputError("expected a matrix as a list of rows")


def _entries(value, key: str):
    """Matrix or vector entries, type-checked; their meaning is read when the model is built."""
    def entry(x, where):
        if isinstance(x, bool) or not isinstance(x, (int, float, str)):
            raise InputError(f"{where}: expected a number or an expression string, got {_kind(x)}")
        if isinstance(x, float) and not math.isfinite(x):
            raise InputError(f"{where}: expected a finite number, got {x!r}")
        return x
    if not isinstance(value, list) or not value:
        raise InputError(f"expected a list, got {_kind(value)}")
    if all(isinstance(r, list) for r in value):
        return [[entry(x, f"row {i + 1}, column {j + 1}") for j, x in enumerate(r)]
                for i, r in enumerate(value)]
    if any(isinstance(r, list) for r in value):
        raise InputError("mixes numbers and rows: give a diagonal [b1, b2] or a matrix [[...], [...]]")
    if key == "mass":
        raise InputError("expected a square matrix as a list of rows, got a list")
    return [entry(x, f"entry {k + 1}") for k, x in enumerate(value)]


def _outputs(ctx, data) -> dict:
    out = {"joint_rates": False, "node_voltages": None, "element_currents": None,
           "netlist": False, "netlist_file": None, "csv": None, "plot": None}
    raw = data.get("outputs")
    if raw is None:
        out["joint_rates"] = True
        return out
    if isinstance(raw, list):
        allowed = OUTPUTS + ("netlist",)
        for item in raw:
            if item not in allowed:
                raise ctx.error("outputs", f"unknown output {item!r} (use {', '.join(allowed)}, "
                                           "or an [outputs] table for files)")
            out[item] = True
        if not raw:
            raise ctx.error("outputs", "asks for nothing")
        return out
    table = ctx.table(data, "outputs")
    if not table:
        raise ctx.error("[outputs]", "asks for nothing: give joint_rates, node_voltages, "
                                     "element_currents or netlist")
    if "joint_rates" in table:
        if not isinstance(table["joint_rates"], bool):
            raise ctx.error("[outputs] joint_rates", f"expected true or false, got {_kind(table['joint_rates'])}")
        out["joint_rates"] = table["joint_rates"]
    for key in ("node_voltages", "element_currents"):
        if key in table:
            value = table[key]
            if value is True or value is False:
                out[key] = value or None
            elif isinstance(value, list) and all(isinstance(x, str) for x in value):
                if not value:
                    raise ctx.error(f"[outputs] {key}", "an empty list: name at least one, or write true")
                out[key] = value
            else:
                raise ctx.error(f"[outputs] {key}", f"expected true or a list of names, got {_kind(value)}")
    if "netlist" in table:
        value = table["netlist"]
        if isinstance(value, bool):
            out["netlist"] = value
        elif isinstance(value, str) and value.strip():
            out["netlist"], out["netlist_file"] = True, _relative_file(ctx, "netlist", value)
        else:
            raise ctx.error("[outputs] netlist", f"expected true or a file name, got {_kind(value)}")
    for key in ("csv", "plot"):
        if key in table:
            value = table[key]
            if not isinstance(value, str) or not value.strip():
                raise ctx.error(f"[outputs] {key}", f"expected a file name, got {_kind(value)}")
            out[key] = _relative_file(ctx, key, value)
    if out["plot"] is not None:
        try:
            check_plot_path(out["plot"])
        except InputError as exc:
            raise ctx.error("[outputs] plot", str(exc)) from None
    if not (out["joint_rates"] or out["node_voltages"] or out["element_currents"] or out["netlist"]):
        raise ctx.error("[outputs]", "asks for nothing: give joint_rates, node_voltages, "
                                     "element_currents or netlist")
    return out


def _relative_file(ctx, key: str, value: str) -> str:
    # A scene file may come from anyone: its outputs stay inside the output folder.
    with ctx.key(f"[outputs] {key}"):
        return check_relative_name(value)


def _solvers(ctx, data) -> dict:
    out = {"use": None, "preset": "accurate", "errors": True, "estimate": False, "refine": False, "step": None}
    raw = data.get("solvers")
    if raw is None:
        return out
    if isinstance(raw, list):
        table, key = {"use": raw}, "solvers"
    else:
        table, key = ctx.table(data, "solvers"), "[solvers] use"
    if "use" in table:
        use = table["use"]
        if not isinstance(use, list):
            raise ctx.error(key, f"expected a list of solver names, got {_kind(use)}")
        for s in use:
            if s not in SOLVER_NAMES:
                raise ctx.error(key, f"unknown solver {s!r}: use {', '.join(SOLVER_NAMES)}")
        out["use"] = list(dict.fromkeys(use))
    if "preset" in table:               # a name or a tolerance: the scene's rules judge it
        if isinstance(table["preset"], bool) or not isinstance(table["preset"], (str, int, float)):
            raise ctx.error("[solvers] preset", f"expected a preset name or a tolerance, got {_kind(table['preset'])}")
        out["preset"] = table["preset"]
    for flag in ("errors", "estimate", "refine"):
        if not isinstance(table.get(flag, False), bool):
            raise ctx.error(f"[solvers] {flag}", f"expected true or false, got {_kind(table[flag])}")
        out[flag] = table.get(flag, out[flag])
    if "step" in table:
        with ctx.key("[solvers] step"):
            out["step"] = _number(table["step"])
    return out
