"""Scenes as TOML files: load, validate, run exactly what the scene asks for.

A scene file describes one simulation job: a model, a configuration, the inputs,
the outputs wanted and the solvers that produce them. Example::

    name = "default"
    description = "2-DOF serial arm at q2 = 0.3 rad, step torques"

    [model]
    robot = "serial2"              # a built-in robot (analogy.robots.robot) ...

    [parameters]                   # ... with parameter overrides
    d2 = 1.0

    [configuration]
    q = [0.0, 0.3]                 # joint coordinates q1 … qn
    topology = "serial"            # "serial", "parallel" or a matrix T, v = T·r

    [inputs]
    forces = [1.0, "sine(0, 0.5, 2)"]
    initial_rates = [0.0, 0.0]
    t_stop = 10.0

    [outputs]
    joint_rates = true
    node_voltages = ["n1"]         # or true: every node
    element_currents = ["C1_2"]    # or true: every element
    netlist = "default.cir"        # or true: netlist text only, no file
    csv = "default.csv"
    plot = "default.png"

    [solvers]
    use = ["spice", "ode", "exact"]
    preset = "accurate"
    errors = true

Top level
    ``name`` (string, default the file's stem), ``description`` (string) and the
    tables below. Every key is checked: an unknown key is an error.
``[model]``
    Either ``robot`` (a built-in name: redundant, serial2, parallel2, serial3,
    parallel3, serialN) or ``mass``, a square matrix (a list of rows) with optional
    ``damping`` and ``stiffness`` (a list is a diagonal, a list of rows a matrix) and
    ``gravity`` (a list, entering as a constant force −G). Entries are numbers or
    expression strings (``"3 + cos(q2)"``, ``"pi/4"``), parsed by the restricted
    grammar of :mod:`analogy.expressions`; nothing is evaluated as Python. Names in
    expressions are the joint coordinates q1 … qn and the names of ``[parameters]``.
    A matrix of plain numbers is used as is, without any symbolic algebra.
``[parameters]``
    ``name = value`` (a number or a constant expression such as ``"pi/4"``): values
    of a robot's parameters (overrides of its defaults), or the symbolic names that
    the mass, damping, stiffness and gravity entries use. Each must be used.
``[configuration]``
    ``q``: the joint coordinates, required when the model depends on them.
    ``topology``: ``"serial"``, ``"parallel"`` or an invertible matrix; default the
    robot's own, ``"parallel"`` for a ``mass`` model.
``[inputs]``
    ``forces`` (required): one entry per joint, a number (a step at t = 0), a
    waveform string (``"step(1)"``, ``"step(a, delay, rise)"``,
    ``"pulse(v1, v2, delay, rise, fall, width, period)"``,
    ``"sine(offset, amplitude, freq, delay, damping, phase_deg)"``,
    ``"pwl(t1, v1, t2, v2, ...)"``) or a list of these, summed.
    ``initial_rates``: joint rates at t = 0 (default zero). ``t_stop``: end time
    (default 10).
``[outputs]``
    ``joint_rates`` (bool), ``node_voltages`` and ``element_currents`` (true for
    all, or a list of node names ``n1`` … / element names ``C1``, ``C1_2``, ``R1``,
    ``L2_3`` …), ``netlist`` (true, or a file to write), ``csv`` and ``plot`` (files
    to write; they need at least one of the three quantities). Instead of a table,
    ``outputs`` may be a list of ``"joint_rates"``, ``"node_voltages"``,
    ``"element_currents"`` and ``"netlist"``. Without ``outputs`` a scene asks for
    the joint rates. Relative file names are resolved against the scene file's
    folder, or the output directory given to :func:`run_scene`.
``[solvers]``
    ``use``: any of ``"spice"``, ``"ode"``, ``"exact"`` (default all three when an
    output needs a solver, none otherwise); ``preset``: ``"fast"`` or
    ``"accurate"`` (default), which also sets the netlist's ``.options`` and
    ``.tran``; ``errors`` (default true): report every solver's error against the
    exact solution, running the exact solver for that if ``use`` does not name it.
    Instead of a table, ``solvers`` may be the list ``use``.

Element currents flow from an element's first terminal to its second, as SPICE
reports a device ``name a b value``: a capacitor carries c·d(v_a − v_b)/dt, a
resistor (v_a − v_b)/R and an inductor (x_a − x_b)/L with x = ∫v.

Only what the outputs need is computed: the netlist's ``.save`` names only the
vectors asked for (every node when joint rates are, since R = T⁻¹·v needs them
all); ngspice is loaded only when ``spice`` is a solver, scipy's integrators only
for ``ode``, matplotlib only for a plot, and sympy only for a robot or a mass
matrix with names in it.

A malformed scene raises :class:`~analogy.errors.InputError` with one line naming
the file, the key and the problem, e.g. ``scene.toml: [configuration] q: expected
2 numbers, got 3``.
"""

from __future__ import annotations

import csv
import math
import re
import time as _time
import tomllib
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from .elements import ZERO_TOL, elements
from .errors import AnalogyError, InputError
from .model import JointSpace
from .presets import preset as get_preset
from .topology import topology as make_topology
from .trajectory import Trajectory

__all__ = ["SceneJob", "SceneResult", "load_scene", "parse_scene", "run_scene", "main_run",
           "element_currents", "OUTPUTS", "SOLVERS"]

#: The quantities a scene may ask for.
OUTPUTS = ("joint_rates", "node_voltages", "element_currents")
#: Solvers, in the order they run.
SOLVERS = ("spice", "ode", "exact")


_TABLES = {
    "model": ("robot", "mass", "damping", "stiffness", "gravity"),
    "parameters": None,         # free names
    "configuration": ("q", "topology"),
    "inputs": ("forces", "initial_rates", "t_stop"),
    "outputs": ("joint_rates", "node_voltages", "element_currents", "netlist", "csv", "plot"),
    "solvers": ("use", "preset", "errors"),
}
_TOP = ("name", "description") + tuple(_TABLES)
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")
_QNAME = re.compile(r"^q[0-9]+$")


def _label(key) -> str:
    key = str(key)
    return key if _BARE.match(key) else repr(key)


def _one_line(text) -> str:
    return " ".join(str(text).split())


class _Context:
    """Names the file and key in every error."""

    def __init__(self, source: str):
        self.source = source

    def error(self, key: str | None, message: str) -> InputError:
        where = f"{self.source}: {key}: " if key else f"{self.source}: "
        return InputError(where + _one_line(message))

    @contextmanager
    def key(self, key: str):
        try:
            yield
        except InputError as exc:
            raise self.error(key, str(exc)) from None

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

def _number(value) -> float:
    """A finite float from a TOML number or a constant expression string."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(f"expected a number, got {_kind(value)}")
    if isinstance(value, str):
        from .expressions import parse_number
        return parse_number(value)
    x = float(value)
    if not math.isfinite(x):
        raise InputError(f"expected a finite number, got {value!r}")
    return x


def _numbers(value, n: int | None = None) -> list[float]:
    if not isinstance(value, list):
        raise InputError(f"expected a list of numbers, got {_kind(value)}")
    if n is not None and len(value) != n:
        raise InputError(f"expected {n} numbers, got {len(value)}")
    out = []
    for k, item in enumerate(value):
        try:
            out.append(_number(item))
        except InputError as exc:
            raise InputError(f"entry {k + 1}: {exc}") from None
    return out


def _matrix_shape(value, n: int | None, what: str) -> list[list]:
    if not isinstance(value, list) or not value or not all(isinstance(r, list) for r in value):
        raise InputError(f"expected a {what} as a list of rows, got {_kind(value)}")
    rows = len(value)
    for k, r in enumerate(value):
        if len(r) != rows:
            raise InputError(f"expected a square matrix: row {k + 1} has {len(r)} entries, "
                             f"but there are {rows} rows")
    if n is not None and rows != n:
        raise InputError(f"expected a {n}x{n} matrix to match the mass matrix, got {rows}x{rows}")
    return value


class _Entries:
    """Matrix and vector entries: numbers at once, names kept for the symbolic path."""

    def __init__(self):
        self.symbolic = False

    def entry(self, value, where: str):
        if isinstance(value, str):
            from .expressions import parse_number
            try:
                return parse_number(value)
            except InputError:
                # Names (or a bad expression): the symbolic parser decides, with its own message.
                self.symbolic = True
                return value
        try:
            return _number(value)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None

    def matrix(self, value, n, what="matrix"):
        rows = _matrix_shape(value, n, what)
        return [[self.entry(x, f"row {i + 1}, column {j + 1}") for j, x in enumerate(r)]
                for i, r in enumerate(rows)]

    def vector(self, value, n):
        if not isinstance(value, list):
            raise InputError(f"expected a list, got {_kind(value)}")
        if len(value) != n:
            raise InputError(f"expected {n} entries (one per joint), got {len(value)}")
        return [self.entry(x, f"entry {k + 1}") for k, x in enumerate(value)]

    def matrix_or_diagonal(self, value, n):
        if isinstance(value, list) and value and all(isinstance(r, list) for r in value):
            return self.matrix(value, n)
        if isinstance(value, list) and any(isinstance(r, list) for r in value):
            raise InputError("mixes numbers and rows: give a diagonal [b1, b2] or a matrix [[...], [...]]")
        if not isinstance(value, list):
            raise InputError(f"expected a diagonal (a list) or a matrix (a list of rows), got {_kind(value)}")
        if len(value) != n:
            raise InputError(f"expected {n} diagonal entries or a {n}x{n} matrix, got {len(value)} entries")
        return self.vector(value, n)


def _joint_error_key(message: str) -> str:
    """The [model] key a JointSpace check refers to."""
    for prefix, key in (("damping", "damping"), ("stiffness", "stiffness"), ("gravity", "gravity")):
        if message.startswith(prefix):
            return f"[model] {key}"
    return "[model] mass"


# ---------------------------------------------------------------- the job

def _check_nodes(system, names) -> tuple[str, ...]:
    nodes = system.nodes
    out = []
    for name in names:
        if not isinstance(name, str) or name not in nodes:
            raise InputError(f"unknown node {name!r}: nodes are {', '.join(nodes)}")
        out.append(name)
    if not out:
        raise InputError("name at least one node (or write true for all)")
    return tuple(dict.fromkeys(out))


def _check_elements(system, names) -> tuple[str, ...]:
    found = {e.name.lower(): e.name for e in elements(system)}
    out = []
    for name in names:
        canonical = found.get(name.lower()) if isinstance(name, str) else None
        if canonical is None:
            raise InputError(f"unknown element {name!r}: elements are {', '.join(found.values())}")
        out.append(canonical)
    if not out:
        raise InputError("name at least one element (or write true for all)")
    return tuple(dict.fromkeys(out))


@dataclass(frozen=True)
class SceneJob:
    """One simulation job, as read from a scene file.

    Attributes
    ----------
    name, description : str
    system : NodeSystem
        The evaluated model in node coordinates, with forces and time span.
    source : Path or None
        The scene file; relative output files are resolved against its folder.
    joint_rates : bool
        Report joint rates R = T⁻¹·v (as a :class:`~analogy.compare.Comparison`).
    node_voltages, element_currents : tuple of str
        Node names and element names whose voltages and currents to report.
    netlist : bool
        Produce the netlist text.
    netlist_file, csv_file, plot_file : str or None
        Files to write.
    solvers : tuple of str
        Solvers to run, a subset of :data:`SOLVERS`.
    preset : str
        Accuracy preset.
    errors : bool
        Report errors against the exact solution (running it if need be).
    """

    name: str
    system: object
    description: str = ""
    source: Path | None = None
    joint_rates: bool = True
    node_voltages: tuple = ()
    element_currents: tuple = ()
    netlist: bool = False
    netlist_file: str | None = None
    csv_file: str | None = None
    plot_file: str | None = None
    solvers: tuple = ("spice", "ode", "exact")
    preset: str = "accurate"
    errors: bool = True

    def __post_init__(self):
        solvers = tuple(dict.fromkeys(self.solvers))
        unknown = [s for s in solvers if s not in SOLVERS]
        if unknown:
            raise InputError(f"unknown solver {unknown[0]!r}: use {', '.join(SOLVERS)}")
        object.__setattr__(self, "solvers", tuple(s for s in SOLVERS if s in solvers))
        get_preset(self.preset)
        object.__setattr__(self, "joint_rates", bool(self.joint_rates))
        if self.node_voltages:
            object.__setattr__(self, "node_voltages", _check_nodes(self.system, self.node_voltages))
        if self.element_currents:
            object.__setattr__(self, "element_currents",
                               _check_elements(self.system, self.element_currents))
        if self.netlist_file is not None:
            object.__setattr__(self, "netlist", True)
        if self.solvers and not self.needs_solver:
            raise InputError("solvers are chosen but no output needs them: ask for joint_rates, "
                             "node_voltages or element_currents")
        if self.needs_solver and not self.solvers:
            raise InputError("the outputs need a solver: choose spice, ode or exact")
        for label, value in (("csv", self.csv_file), ("plot", self.plot_file)):
            if value is not None and not self.needs_solver:
                raise InputError(f"a {label} file needs joint_rates, node_voltages or element_currents")

    @property
    def needs_solver(self) -> bool:
        """True if any output is a solver result."""
        return bool(self.joint_rates or self.node_voltages or self.element_currents)

    @property
    def reference(self) -> bool:
        """True if the exact solver runs: asked for, or the yardstick of the others."""
        return "exact" in self.solvers or (self.errors and bool(self.solvers))

    def save(self) -> list[str]:
        """Node and element names for the netlist's ``.save``: exactly what the outputs need."""
        if not self.needs_solver:
            return list(self.system.nodes)
        nodes = list(self.system.nodes) if self.joint_rates else list(self.node_voltages)
        return nodes + list(self.element_currents)

    def replace(self, **changes) -> "SceneJob":
        """A copy with *changes* (e.g. other solvers, or no plot file)."""
        return replace(self, **changes)

    def path(self, name: str, output_dir=None) -> Path:
        """Where an output file named *name* goes."""
        p = Path(name)
        if output_dir is not None:
            return Path(output_dir) / p
        return (self.source.parent if self.source is not None else Path.cwd()) / p


def load_scene(path) -> SceneJob:
    """Read, validate and evaluate the scene file *path*.

    Raises
    ------
    InputError
        One line naming the file, the key and the problem.
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read the scene file: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: the scene file is not UTF-8 text") from None
    return parse_scene(text, source=path)


def parse_scene(text: str, source="scene.toml") -> SceneJob:
    """Parse scene TOML *text*.

    *source*, the file the text came from, names it in errors; relative output
    files are resolved against its folder.
    """
    label = str(source)
    ctx = _Context(label)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        if "(at end of document)" in message:
            last = max(len(text.splitlines()), 1)
            message = message.replace("(at end of document)", f"(at line {last}, the end of the document)")
        raise ctx.error(None, f"TOML syntax error: {message}") from None
    for key in data:
        if key not in _TOP:
            kind = "table" if isinstance(data[key], dict) else "key"
            shown = f"[{_label(key)}]" if kind == "table" else _label(key)
            raise ctx.error(None, f"unknown {kind} {shown} (known: {', '.join(_TOP)})")
    path = Path(source)
    name = data.get("name", path.stem or "scene")
    description = data.get("description", "")
    for key, value in (("name", name), ("description", description)):
        if not isinstance(value, str):
            raise ctx.error(key, f"expected a string, got {_kind(value)}")
    if not name.strip():
        raise ctx.error("name", "must not be empty")

    for table in _TABLES:                  # unknown keys first, before any model work
        if isinstance(data.get(table), dict):
            ctx.table(data, table)
    outputs = _outputs(ctx, data)
    solvers = _solvers(ctx, data)
    system = _system(ctx, data, name)

    with ctx.key("[outputs] node_voltages"):
        nv = outputs["node_voltages"]
        nv = tuple(system.nodes) if nv is True else (_check_nodes(system, nv) if nv else ())
    with ctx.key("[outputs] element_currents"):
        ec = outputs["element_currents"]
        ec = tuple(e.name for e in elements(system)) if ec is True else \
            (_check_elements(system, ec) if ec else ())
    needs = bool(outputs["joint_rates"] or nv or ec)
    use = solvers["use"]
    if use is None:
        use = SOLVERS if needs else ()
    if needs and not use:
        raise ctx.error("[solvers] use", "the outputs need a solver: choose spice, ode or exact")
    if use and not needs:
        raise ctx.error("[solvers] use", "no output needs a solver: ask for joint_rates, "
                                         "node_voltages or element_currents in [outputs]")
    for key in ("csv", "plot"):
        if outputs[key] is not None and not needs:
            raise ctx.error(f"[outputs] {key}", "needs joint_rates, node_voltages or element_currents")
    with ctx.key("[solvers]"):
        return SceneJob(name=name, system=system, description=description, source=path,
                        joint_rates=outputs["joint_rates"], node_voltages=nv, element_currents=ec,
                        netlist=outputs["netlist"], netlist_file=outputs["netlist_file"],
                        csv_file=outputs["csv"], plot_file=outputs["plot"], solvers=tuple(use),
                        preset=solvers["preset"], errors=solvers["errors"])


def _system(ctx: _Context, data: dict, name: str):
    from .system import node_system
    model = ctx.table(data, "model")
    if model is None:
        raise ctx.error("[model]", "missing: give robot = \"serial2\" (a built-in robot) or mass = [[...]]")
    params_raw = ctx.table(data, "parameters") or {}
    config = ctx.table(data, "configuration") or {}
    inputs = ctx.table(data, "inputs")
    if inputs is None:
        raise ctx.error("[inputs]", "missing: give at least forces = [...] (one per joint)")

    params = {}
    for key, value in params_raw.items():
        with ctx.key(f"[parameters] {_label(key)}"):
            params[key] = _number(value)

    q = None
    if "q" in config:
        with ctx.key("[configuration] q"):
            q = _numbers(config["q"])

    if "robot" in model:
        joint, info, default_top = _robot(ctx, model, params, q)
    elif "mass" in model:
        joint, info = _custom(ctx, model, params, q)
        default_top = "parallel"
    else:
        raise ctx.error("[model]", "give robot = \"serial2\" (a built-in robot) or mass = [[...]]")
    n = joint.dof

    with ctx.key("[configuration] topology"):
        spec = config.get("topology", default_top)
        if isinstance(spec, str):
            top = make_topology(spec, n)
        elif isinstance(spec, list):
            top = make_topology(_numeric_matrix(spec, n), n)
        else:
            raise InputError(f"expected \"serial\", \"parallel\" or a matrix, got {_kind(spec)}")

    with ctx.key("[inputs] forces"):
        if "forces" not in inputs:
            raise InputError("missing: give one force per joint, e.g. forces = [1.0, \"sine(0, 1, 2)\"]")
        raw = inputs["forces"]
        if not isinstance(raw, list):
            raise InputError(f"expected a list with one entry per joint, got {_kind(raw)}")
        if len(raw) != n:
            raise InputError(f"expected {n} entries (one per joint), got {len(raw)}")
    forces = []
    for k, item in enumerate(raw):
        with ctx.key(f"[inputs] forces[{k + 1}]"):
            forces.append(_force(item))
    r0 = None
    if "initial_rates" in inputs:
        with ctx.key("[inputs] initial_rates"):
            r0 = _numbers(inputs["initial_rates"], n)
    t_stop = 10.0
    if "t_stop" in inputs:
        with ctx.key("[inputs] t_stop"):
            t_stop = _number(inputs["t_stop"])
            if t_stop <= 0:
                raise InputError(f"must be a positive time, got {t_stop!r}")
    with ctx.key("[inputs]"):
        info = dict(info, scene=name)
        return node_system(joint, topology=top, forces=forces, initial_rates=r0,
                           t_stop=t_stop, info=info)


def _numeric_matrix(value, n):
    out = []
    for i, row in enumerate(_matrix_shape(value, n, "matrix")):
        try:
            out.append(_numbers(row))
        except InputError as exc:
            raise InputError(f"row {i + 1}, {exc}") from None
    return out


def _force(item):
    from .waveforms import Step, parse_waveform
    items = item if isinstance(item, list) else [item]
    if not items:
        raise InputError("an empty list: give a number or a waveform such as \"step(1)\"")
    out = []
    for w in items:
        if isinstance(w, str):
            out.append(parse_waveform(w))
        elif isinstance(w, (int, float)) and not isinstance(w, bool):
            out.append(Step(_number(w)))
        else:
            raise InputError(f"expected a number or a waveform string such as \"step(1)\", got {_kind(w)}")
    return out


def _robot(ctx, model, params, q):
    for key in ("mass", "damping", "stiffness", "gravity"):
        if key in model:
            raise ctx.error(f"[model] {key}", "a built-in robot has its own; set its [parameters] "
                                              "instead, or give mass = [[...]] without robot")
    name = model["robot"]
    with ctx.key("[model] robot"):
        if not isinstance(name, str):
            raise InputError(f"expected a robot name, got {_kind(name)}")
        from .robots import robot
        m = robot(name)
    for key in params:
        if key not in m.parameters:
            raise ctx.error(f"[parameters] {_label(key)}",
                            f"robot {name} has no such parameter (it has: {', '.join(m.parameters) or 'none'})")
    coords = [str(c) for c in m.coordinates]
    with ctx.key("[configuration] q"):
        if q is None and coords:
            raise InputError(f"missing: robot {name} needs {len(coords)} joint coordinates "
                             f"({', '.join(coords)})")
        q = q or []
        if len(q) != len(coords):
            raise InputError(f"expected {len(coords)} numbers, got {len(q)}")
    with ctx.key("[model]"):
        try:
            joint = m.joint_space(q, params)
        except InputError as exc:
            raise ctx.error(_joint_error_key(str(exc)), str(exc)) from None
    values = dict(m.parameters, **params)
    info = {"robot": m.name, "parameters": values, "configuration": dict(zip(coords, q))}
    return joint, info, m.topology


def _custom(ctx, model, params, q):
    entries = _Entries()
    with ctx.key("[model] mass"):
        mass = entries.matrix(model["mass"], None, "square matrix")
    n = len(mass)
    parts = {"mass": mass}
    for key in ("damping", "stiffness"):
        if key in model:
            with ctx.key(f"[model] {key}"):
                parts[key] = entries.matrix_or_diagonal(model[key], n)
    if "gravity" in model:
        with ctx.key("[model] gravity"):
            parts["gravity"] = entries.vector(model["gravity"], n)
    qnames = [f"q{k + 1}" for k in range(n)]
    for key in params:
        bad = (not key.isidentifier() or key.startswith("_") or _QNAME.match(key)
               or key in ("pi", "e"))
        if bad:
            raise ctx.error(f"[parameters] {_label(key)}",
                            "not a usable name (q1 … qn are the joint coordinates; pi and e are constants)")
    if q is not None and len(q) != n:
        raise ctx.error("[configuration] q", f"expected {n} numbers, got {len(q)}")
    if not entries.symbolic:
        if params:
            key = next(iter(params))
            raise ctx.error(f"[parameters] {_label(key)}", "not used: the model's entries are all numbers")
        joint = _joint_space(ctx, parts, n)
        config = dict(zip(qnames, q)) if q is not None else {}
        return joint, {"robot": "custom", "parameters": {}, "configuration": config}
    return _symbolic(ctx, parts, params, q, n, qnames)


def _diag(v, n):
    if isinstance(v[0], list):
        return v
    return [[v[i] if i == j else 0.0 for j in range(n)] for i in range(n)]


def _joint_space(ctx, parts, n):
    mass = np.array(parts["mass"], dtype=float)
    damping = np.array(_diag(parts["damping"], n), dtype=float) if "damping" in parts else np.zeros((n, n))
    stiffness = np.array(_diag(parts["stiffness"], n), dtype=float) if "stiffness" in parts else None
    gravity = np.array(parts["gravity"], dtype=float) if "gravity" in parts else None
    try:
        return JointSpace(mass, damping, stiffness, gravity)
    except InputError as exc:
        raise ctx.error(_joint_error_key(str(exc)), str(exc)) from None


def _symbolic(ctx, parts, params, q, n, qnames):
    import sympy as sp

    from .expressions import parse_expression
    from .model import Model
    qs = [sp.Symbol(name, real=True) for name in qnames]
    symbols = {k: sp.Symbol(k, real=True) for k in params}
    symbols.update(zip(qnames, qs))

    def convert(key, value, where):
        if isinstance(value, str):
            with ctx.key(f"[model] {key}"):
                try:
                    return parse_expression(value, symbols)
                except InputError as exc:
                    hint = "" if params else "; declare names in [parameters]"
                    raise InputError(f"{where}: {exc}{hint}") from None
        return sp.Float(value, 17)

    mats = {}
    for key, value in parts.items():
        if key == "gravity":
            mats[key] = sp.Matrix([convert(key, x, f"entry {k + 1}") for k, x in enumerate(value)])
        else:
            rows = _diag(value, n)
            mats[key] = sp.Matrix([[convert(key, x, f"row {i + 1}, column {j + 1}")
                                    for j, x in enumerate(r)] for i, r in enumerate(rows)])
    free = set()
    for mat in mats.values():
        free |= mat.free_symbols
    for key in params:
        if symbols[key] not in free:
            raise ctx.error(f"[parameters] {_label(key)}", "not used by the model's entries")
    used_q = [s for s in qs if s in free]
    if used_q and q is None:
        raise ctx.error("[configuration] q", f"missing: the model uses {', '.join(map(str, used_q))}; "
                                             f"give {n} joint coordinates")
    with ctx.key("[model]"):
        model = Model("custom", mats["mass"], damping=mats.get("damping"), stiffness=mats.get("stiffness"),
                      gravity=None if "gravity" not in mats else list(mats["gravity"]),
                      parameters=params, coordinates=qs if used_q else (), topology="parallel")
    try:
        joint = model.joint_space(q if used_q else None, None)
    except InputError as exc:
        raise ctx.error(_joint_error_key(str(exc)), str(exc)) from None
    config = dict(zip(qnames, q)) if q is not None else {}
    return joint, {"robot": "custom", "parameters": dict(params), "configuration": config}


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
            if item == "netlist":
                out["netlist"] = True
            elif item == "joint_rates":
                out["joint_rates"] = True
            else:
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
        from .compare import check_plot_path
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
    p = Path(value)
    if p.is_absolute() or ".." in p.parts:
        raise ctx.error(f"[outputs] {key}", f"{value!r} must be a relative path inside the "
                                            "output folder (no absolute path, no '..')")
    return value


def _solvers(ctx, data) -> dict:
    out = {"use": None, "preset": "accurate", "errors": True}
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
            if s not in SOLVERS:
                raise ctx.error(key, f"unknown solver {s!r}: use {', '.join(SOLVERS)}")
        out["use"] = list(dict.fromkeys(use))
    if "preset" in table:
        with ctx.key("[solvers] preset"):
            if not isinstance(table["preset"], str):
                raise InputError(f"expected a preset name, got {_kind(table['preset'])}")
            out["preset"] = get_preset(table["preset"]).name
    if "errors" in table:
        if not isinstance(table["errors"], bool):
            raise ctx.error("[solvers] errors", f"expected true or false, got {_kind(table['errors'])}")
        out["errors"] = table["errors"]
    return out


# ---------------------------------------------------------------- running

def element_currents(system, trajectory: Trajectory, names: Sequence[str] | None = None,
                     zero_tol: float = ZERO_TOL) -> dict[str, np.ndarray]:
    """Element currents from a solver's node voltages v (and positions x, with springs).

    A capacitor carries c·d(v_a − v_b)/dt with dv/dt = M'⁻¹·(i(t) − B'·v − K'·x), a
    resistor (v_a − v_b)/R and an inductor (x_a − x_b)/L: the current from terminal a
    to terminal b, as SPICE reports it for a device ``name a b value``.

    Parameters
    ----------
    system : NodeSystem
    trajectory : Trajectory
        Node voltages on its time points; with springs, :attr:`Trajectory.positions`
        too (``solve_exact(..., positions=True)``, ``solve_ode(..., positions=True)``).
    names : sequence of str, optional
        Element names (default all).
    """
    by_name = {e.name: e for e in elements(system, zero_tol)}
    wanted = list(by_name) if names is None else list(_check_elements(system, names))
    chosen = [by_name[name] for name in wanted]
    t, v, x = trajectory.time, trajectory.voltages, trajectory.positions
    needs_x = system.stiffness is not None and any(e.kind in "CL" for e in chosen)
    if needs_x and x is None:
        raise InputError("capacitor and inductor currents of a system with springs need the "
                         "positions x = ∫v: solve with positions=True")
    dv = None
    if any(e.kind == "C" for e in chosen):
        rhs = system.force(t) @ system.current_map.T - v @ system.damping.T
        if system.stiffness is not None:
            rhs = rhs - x @ system.stiffness.T
        dv = np.linalg.solve(system.mass, rhs.T).T

    def across(arr, e):
        return arr[:, e.a - 1] - (arr[:, e.b - 1] if e.b else 0.0)

    out = {}
    for e in chosen:
        if e.kind == "C":
            out[e.name] = e.value * across(dv, e)
        elif e.kind == "R":
            out[e.name] = across(v, e) / e.value
        else:
            out[e.name] = across(x, e) / e.value
    return out


def run_scene(job: SceneJob, output_dir=None) -> SceneResult:
    """Compute exactly what *job*'s outputs require and write its files.

    Relative file names go to *output_dir* if given, else next to the scene file.
    A failing solver is recorded in :attr:`SceneResult.failures`; the others still run.
    """
    from .netlist import netlist as make_netlist, save_vectors
    p = get_preset(job.preset)
    system = job.system
    result = SceneResult(job)
    save = job.save()
    text = None
    if job.netlist or "spice" in job.solvers:
        title = f"analogy scene {job.name}" + (f": {job.description}" if job.description else "")
        text = make_netlist(system, p, save=save, title=title)
    if job.netlist:
        result.netlist = text
        if job.netlist_file:
            result.written.append(_write_text(job.path(job.netlist_file, output_dir), text))
    if not job.solvers:
        return result

    run = list(job.solvers)
    if job.reference and "exact" not in run:
        run.append("exact")
    positions = system.stiffness is not None and any(
        name[0] in "CL" for name in job.element_currents)
    trajectories, grid = {}, None
    if "spice" in run:
        from .spice import run_netlist
        by_name = {name: save_vectors(system, [name])[0] for name in save}
        try:
            start = _time.perf_counter()
            data = run_netlist(text, list(by_name.values()))
            elapsed = _time.perf_counter() - start
            grid = data["time"]
            result.run_times["spice"] = elapsed
            if job.joint_rates:
                v = np.column_stack([data[by_name[n]] for n in system.nodes])
                trajectories["spice"] = Trajectory("spice", grid, v, system.joint_rates(v), elapsed)
            if job.node_voltages:
                result.node_voltages["spice"] = {n: data[by_name[n]] for n in job.node_voltages}
            if job.element_currents:
                result.element_currents["spice"] = {e: data[by_name[e]] for e in job.element_currents}
        except AnalogyError as exc:
            result.failures["spice"] = str(exc)
    if grid is None:
        grid = np.linspace(0.0, system.t_stop, p.steps + 1)
    result.time = grid
    for solver in ("ode", "exact"):
        if solver not in run:
            continue
        try:
            if solver == "ode":
                from .ode import solve_ode
                tr = solve_ode(system, grid, p.ode_method, p.ode_rtol, positions=positions)
            else:
                from .exact import solve_exact
                tr = solve_exact(system, grid, positions=positions)
        except AnalogyError as exc:
            result.failures[solver] = str(exc)
            continue
        result.run_times[solver] = tr.run_time
        trajectories[solver] = tr
        if job.node_voltages:
            result.node_voltages[solver] = {n: tr.voltages[:, int(n[1:]) - 1] for n in job.node_voltages}
        if job.element_currents:
            result.element_currents[solver] = element_currents(system, tr, job.element_currents)
    if job.joint_rates:
        from .compare import Comparison
        ordered = {s: trajectories[s] for s in SOLVERS if s in trajectories}
        result.comparison = Comparison(system, p.name, grid, ordered, dict(result.failures))
    try:
        if job.csv_file:
            result.written.append(result.to_csv(job.path(job.csv_file, output_dir)))
        if job.plot_file:
            path = job.path(job.plot_file, output_dir)
            path.parent.mkdir(parents=True, exist_ok=True)
            result.plot(path)
            result.written.append(path)
    except OSError as exc:
        raise InputError(f"cannot write output: {exc}") from None
    return result


def _write_text(path: Path, text: str) -> Path:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


@dataclass(eq=False)
class SceneResult:
    """What a scene asked for, computed.

    Attributes
    ----------
    job : SceneJob
    time : ndarray or None
        Shared time points of every solver (SPICE's own when it ran).
    comparison : Comparison or None
        Joint rates of every solver, when the scene asks for them.
    netlist : str or None
        The netlist text, when asked for.
    node_voltages, element_currents : dict
        ``{solver: {name: values}}`` for the requested nodes and elements.
    run_times : dict
        Seconds per solver.
    failures : dict
        Solvers that failed, with the reason.
    written : list of Path
        Files written.
    """

    job: SceneJob
    time: np.ndarray | None = None
    comparison: object = None
    netlist: str | None = None
    node_voltages: dict = field(default_factory=dict)
    element_currents: dict = field(default_factory=dict)
    run_times: dict = field(default_factory=dict)
    failures: dict = field(default_factory=dict)
    written: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.failures

    @property
    def solvers(self) -> list[str]:
        """Solvers that produced results, in :data:`SOLVERS` order."""
        return [s for s in SOLVERS if s in self.run_times]

    def _groups(self) -> list[tuple[str, dict]]:
        """(quantity, {solver: {name: values}}) for every requested quantity."""
        groups = []
        if self.comparison is not None:
            rates = {s: {f"r{j + 1}": tr.rates[:, j] for j in range(self.job.system.dof)}
                     for s, tr in self.comparison.results.items()}
            groups.append(("joint rates", rates))
        if self.job.node_voltages:
            groups.append(("node voltages", self.node_voltages))
        for kind, label in (("C", "C currents"), ("R", "R currents"), ("L", "L currents")):
            names = [e for e in self.job.element_currents if e[0] == kind]
            if names:
                groups.append((label, {s: {e: vals[e] for e in names}
                                       for s, vals in self.element_currents.items()}))
        return groups

    def errors(self) -> dict:
        """``{quantity: {solver: (max |x − x_exact|, that / peak |x_exact|)}}``.

        Quantities are joint rates, node voltages and element currents by kind (C, R, L).
        Empty when the exact solution did not run.
        """
        out = {}
        for quantity, by_solver in self._groups():
            ref = by_solver.get("exact")
            if ref is None:
                continue
            peak = max(float(np.max(np.abs(x))) for x in ref.values())
            out[quantity] = {}
            for solver, vals in by_solver.items():
                err = max(float(np.max(np.abs(vals[k] - ref[k]))) for k in ref)
                out[quantity][solver] = (err, err / peak if peak > 0 else float("nan"))
        return out

    def max_relative_error(self, solver: str) -> float:
        """Worst error / peak of *solver* over every requested quantity."""
        vals = [by[solver][1] for by in self.errors().values() if solver in by]
        return max(vals) if vals else float("nan")

    def table(self) -> str:
        """Plain-text summary: solvers, run times, errors against the exact solution, files."""
        job = self.job
        system = job.system
        head = f"scene {job.name}" + (f": {job.description}" if job.description else "")
        lines = [head]
        referenced = self.comparison is not None and "exact" in self.comparison.results
        if referenced:
            lines.append(self.comparison.table())
        elif job.solvers:
            n = 0 if self.time is None else self.time.size
            lines.append(f"robot {system.info.get('robot', 'custom')}, topology {system.topology.name}, "
                         f"preset {job.preset}, {n} time points, no exact reference")
            lines.append(f"{'solver':<8}{'run time [ms]':>15}")
            for s in SOLVERS:
                if s in self.run_times:
                    lines.append(f"{s:<8}{self.run_times[s] * 1e3:>15.3f}")
                elif s in self.failures:
                    lines.append(f"{s:<8}  failed: {self.failures[s]}")
        groups = [g for g in self._groups() if not (referenced and g[0] == "joint rates")]
        if groups:
            errs = self.errors()
            if job.node_voltages:
                lines.append("node voltages: " + ", ".join(job.node_voltages))
            if job.element_currents:
                lines.append("element currents (a to b): " + ", ".join(job.element_currents))
            lines.append(f"{'quantity':<16}{'solver':<8}{'peak':>12}{'max |error|':>14}{'error / peak':>14}")
            for quantity, by_solver in groups:
                for s in SOLVERS:
                    vals = by_solver.get(s)
                    if vals is None:
                        continue
                    peak = max(float(np.max(np.abs(x))) for x in vals.values())
                    if quantity in errs and s in errs[quantity]:
                        e, r = errs[quantity][s]
                        tail = f"{e:>14.3e}{r:>14.3e}" + ("  (reference)" if s == "exact" else "")
                    else:
                        tail = f"{'-':>14}{'-':>14}"
                    lines.append(f"{quantity:<16}{s:<8}{peak:>12.6g}{tail}")
        if job.netlist:
            count = len(self.netlist.splitlines()) if self.netlist else 0
            lines.append(f"netlist: {count} lines" + (f", saves {', '.join(job.save())}"))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def _columns(self) -> list[tuple[str, np.ndarray]]:
        cols = []
        groups = self._groups()
        for s in SOLVERS:
            for quantity, by_solver in groups:
                prefix = {"joint rates": "", "node voltages": "v_"}.get(quantity, "i_")
                for name, vals in (by_solver.get(s) or {}).items():
                    cols.append((f"{prefix}{name}_{s}", vals))
        return cols

    def to_csv(self, path) -> Path:
        """Write time, then per solver its joint rates ``r1_spice`` …, node voltages
        ``v_n1_spice`` … and element currents ``i_C1_2_spice`` …, one row per time point."""
        if self.time is None:
            raise InputError("no solver ran: nothing to write to CSV")
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        cols = self._columns()
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["time"] + [name for name, _ in cols])
            for row in zip(self.time, *(vals for _, vals in cols)):
                w.writerow([repr(float(x)) for x in row])
        return path

    def plot(self, path=None):
        """One panel per requested quantity (solvers overlaid) and, with a reference, the
        error / peak of each solver; save a PNG if *path*."""
        from matplotlib.figure import Figure   # no pyplot: works headless, no global state
        groups = self._groups()
        if not groups:
            raise InputError("no solver ran: nothing to plot")
        errs = self.errors()
        panels = len(groups) + (1 if errs else 0)
        fig = Figure(figsize=(8, 2.6 * panels + 0.6), layout="constrained")
        axes = fig.subplots(panels, 1, sharex=True, squeeze=False)[:, 0]
        styles = {"exact": dict(ls="-", lw=2.0, alpha=0.5), "spice": dict(ls="--", lw=1.2),
                  "ode": dict(ls=":", lw=1.2)}
        for ax, (quantity, by_solver) in zip(axes, groups):
            for s in SOLVERS:
                for k, (name, vals) in enumerate((by_solver.get(s) or {}).items()):
                    ax.plot(self.time, vals, color=f"C{k % 10}", label=f"{name} {s}", **styles[s])
            ax.set_ylabel(quantity)
            ax.legend(ncol=3, fontsize="x-small")
        axes[0].set_title(f"scene {self.job.name}: preset {self.job.preset}")
        if errs:
            ax = axes[-1]
            for s in ("spice", "ode"):
                curves = []
                for quantity, by_solver in groups:
                    ref, vals = by_solver.get("exact"), by_solver.get(s)
                    if ref is None or vals is None:
                        continue
                    peak = max(float(np.max(np.abs(x))) for x in ref.values()) or 1.0
                    curves += [np.abs(vals[k] - ref[k]) / peak for k in ref]
                if curves:
                    ax.semilogy(self.time, np.maximum(np.max(curves, axis=0), 1e-18), label=s, **styles[s])
            ax.set_ylabel("max |error| / peak")
            ax.legend(fontsize="small")
        axes[-1].set_xlabel("time [s]")
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def main_run(path, output_dir=None, no_plot: bool = False) -> int:
    """Run the scene file *path* as ``analogy run`` does: print the result, return the exit code.

    0: success; 1: a solver failed (the other results are still printed and written);
    2: bad input (one line on stderr). *no_plot* skips a plot the scene asks for, so the
    plotting library is never imported.
    """
    from .cli import main
    args = ["run", str(path)] + (["--output-dir", str(output_dir)] if output_dir is not None else [])
    return main(args + (["--no-plot"] if no_plot else []))
