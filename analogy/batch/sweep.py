"""Sweeps: a base scene and axes over its configuration, parameters and inputs, streamed scene by scene."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Literal

import numpy as np

from ..circuit.joint_forces import waveforms
from ..circuit.topology import TOPOLOGY_NAMES
from ..errors import InputError
from ..model.catalog import robot_family
from ..model.dynamics import DYNAMICS
from ..model.expressions import parse_number
from ..model.quantities import ANY, COORDINATE, RATE, Measured, check_joint_dimensions, check_parameter_units
from ..presets import preset as get_preset
from .store import RESERVED_COLUMNS
from ..scenes.build import scene_model
from ..scenes.scene import Scene
from .designs import DESIGNS, design_points

__all__ = ["Axis", "Sweep", "SWEEP_SCHEMA", "axis_kind", "load_sweep", "sweep_from"]

#: Version of what a sweep's key covers.
SWEEP_SCHEMA = "analogy-sweep-1"

AxisKind = Literal["q", "rate", "force", "parameter", "topology", "preset", "dynamics", "t_stop"]
_WHOLE = {"topology": "topology", "preset": "preset", "dynamics": "dynamics", "t_stop": "t_stop"}


def axis_kind(name: str) -> tuple[AxisKind, int]:
    """What the axis *name* varies, and the joint (from 0) for per-joint axes.

    ``q2`` is joint 2's coordinate, ``rate2`` its initial rate, ``force2`` its force;
    ``topology``, ``preset``, ``dynamics`` and ``t_stop`` are the scene's own fields;
    any other name is a model parameter.

    Parameters
    ----------
    name : str
        The axis name.
    """
    for prefix, kind in (("q", "q"), ("rate", "rate"), ("force", "force")):
        rest = name[len(prefix):]
        if name.startswith(prefix) and rest.isdigit() and rest[0] != "0":
            return kind, int(rest) - 1      # type: ignore[return-value]
    return _WHOLE.get(name, "parameter"), -1    # type: ignore[return-value]


@dataclass(frozen=True)
class Axis:
    """One swept variable: *values* to choose among, or a range [low, high] (linear or log).

    Attributes
    ----------
    name : str
        ``q<k>``, ``rate<k>``, ``force<k>``, ``topology``, ``preset``, ``dynamics``,
        ``t_stop``, or a parameter name (see :func:`axis_kind`).
    values : tuple or None
        The values of a grid, or the choices of a sampled design.
    low, high : float or None
        A range for sampled designs.
    log : bool
        Sample the range uniformly in log scale.
    """

    name: str
    values: tuple | None = None
    low: float | None = None
    high: float | None = None
    log: bool = False

    def __post_init__(self):
        if self.values is not None:
            if not self.values:
                raise InputError(f"axis {self.name}: needs at least one value")
            return
        if self.low is None or self.high is None:
            raise InputError(f"axis {self.name}: give a list of values or a range [low, high]")
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low <= self.high):
            raise InputError(f"axis {self.name}: the range needs finite low <= high, got [{self.low}, {self.high}]")
        if self.log and self.low <= 0:
            raise InputError(f"axis {self.name}: a log range needs low > 0, got {self.low}")

    @property
    def numeric(self) -> bool:
        """True when every value is a number (the axis's column holds floats)."""
        return self.values is None or all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                          for v in self.values)

    def pick(self, u: np.ndarray, grid: bool) -> np.ndarray:
        """The axis's values at design points *u* (grid indices, or numbers in [0, 1)).

        Parameters
        ----------
        u : ndarray
            One design coordinate per scene.
        grid : bool
            *u* holds indices into :attr:`values`.
        """
        if self.values is not None:
            idx = u.astype(int) if grid else np.minimum((u * len(self.values)).astype(int), len(self.values) - 1)
            table = np.array(self.values, dtype=float if self.numeric else object)
            return table[idx]
        if self.log:
            return np.exp(np.log(self.low) + u * (np.log(self.high) - np.log(self.low)))
        return self.low + u * (self.high - self.low)

    def canonical(self) -> str:
        return repr((self.name, None if self.values is None else [repr(v) for v in self.values],
                     repr(self.low), repr(self.high), self.log))


#: Most scenes in one sweep.
MAX_SCENES = 100_000_000
#: Most values of one grid axis: they are listed (and written into the sweep's key) one by one.
MAX_AXIS_VALUES = 100_000


def _parameters(base: Scene) -> tuple[str, ...]:
    """The parameter names the base scene's model takes (built once; an error there is the scene's)."""
    try:
        return tuple(getattr(scene_model(base), "parameters", None) or ())
    except InputError:
        return tuple(dict(base.parameters))         # the scenes themselves will say what is wrong


@dataclass(frozen=True)
class Sweep:
    """A base scene and axes: the scenes of a design, by index, never all held at once.

    Attributes
    ----------
    base : Scene
        What every scene shares; its q holds every joint coordinate.
    axes : tuple of Axis
        The swept variables.
    method : {"grid", "random", "lhs", "sobol"}
        The design (:func:`analogy.batch.designs.design_points`).
    count : int or None
        Scenes of a sampled design; a grid has one per combination of values.
    seed : int
        Seed of the sampled designs.
    group_size : int
        Scenes per group: solved together in one ngspice run, stored together.
    """

    base: Scene
    axes: tuple[Axis, ...]
    method: str = "grid"
    count: int | None = None
    seed: int = 0
    group_size: int = 100
    _kinds: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.method not in DESIGNS:
            raise InputError(f"unknown sweep method {self.method!r}: use {', '.join(DESIGNS)}")
        if not self.axes:
            raise InputError("a sweep needs at least one axis")
        names = [a.name for a in self.axes]
        if len(set(names)) != len(names):
            raise InputError(f"axis {next(n for n in names if names.count(n) > 1)} is given twice")
        if clash := [n for n in names if n in RESERVED_COLUMNS or n.startswith(("error_", "seconds_"))]:
            raise InputError(f"axis {clash[0]}: the results store has a column of that name (key, scene, "
                             "status, message, error_<solver>, seconds_<solver>): sweep a model parameter, "
                             "q<k>, rate<k>, force<k>, topology, preset, dynamics or t_stop")
        if not (isinstance(self.seed, int) and 0 <= self.seed < 2 ** 63):
            raise InputError(f"seed must be a whole number from 0 to 2^63 - 1, got {self.seed!r}")
        if self.method == "grid":
            if bad := [a.name for a in self.axes if a.values is None]:
                raise InputError(f"axis {bad[0]}: a grid needs a list of values (a range needs "
                                 "method = \"random\", \"lhs\" or \"sobol\")")
            if self.count is not None and self.count != self.size:
                raise InputError(f"a grid of these axes has {self.size} scenes, not count = {self.count}")
        elif self.count is None or self.count < 1:
            raise InputError(f"method {self.method!r} needs count, the number of scenes (at least 1)")
        if self.size > MAX_SCENES:
            raise InputError(f"a sweep of {self.size:,} scenes is more than {MAX_SCENES:,} (a store holds a "
                             "done-flag per scene, and a run of that size takes days): split it into sweeps")
        if not 1 <= self.group_size <= 100_000:
            raise InputError(f"group_size must be between 1 and 100000, got {self.group_size}")
        kinds = tuple(axis_kind(a.name) for a in self.axes)
        if params := [a.name for a, (kind, _) in zip(self.axes, kinds) if kind == "parameter"]:
            known = _parameters(self.base)
            if bad := [name for name in params if name not in known]:
                raise InputError(f"axis {bad[0]}: not something a sweep can vary; the model's parameters "
                                 f"are {', '.join(known) or 'none'}, and the scene's own axes are q<k>, "
                                 "rate<k>, force<k>, topology, preset, dynamics and t_stop")
        n = len(self.base.q)
        for axis, (kind, joint) in zip(self.axes, kinds):
            if kind in ("q", "rate", "force") and joint >= n:
                raise InputError(f"axis {axis.name}: the model has {n} joints")
            if kind in ("q", "rate", "t_stop") and not axis.numeric:
                raise InputError(f"axis {axis.name}: needs numbers")
            if kind == "preset":
                for v in axis.values or (None,):
                    try:
                        get_preset(v)       # a name or a tolerance
                    except InputError as exc:
                        raise InputError(f"axis preset: {exc}") from None
            if measured := [v for v in (axis.values or (axis.low, axis.high)) if isinstance(v, Measured)]:
                _check_units(self.base, axis.name, kind, joint, measured)
            # every choice read here, before any scene runs: a typo is one sentence, not stored rows
            for v in axis.values or ():
                try:
                    if kind == "force":
                        waveforms([v], 1)
                    elif kind == "dynamics" and v not in DYNAMICS:
                        raise InputError(f"{v!r} is not one of {', '.join(DYNAMICS)}")
                    elif kind == "topology" and isinstance(v, str) and v not in TOPOLOGY_NAMES:
                        raise InputError(f"{v!r} is not one of {', '.join(TOPOLOGY_NAMES)}")
                except InputError as exc:
                    raise InputError(f"axis {axis.name}: {exc}") from None
        object.__setattr__(self, "_kinds", kinds)

    @property
    def size(self) -> int:
        """Number of scenes."""
        return math.prod(len(a.values) for a in self.axes) if self.method == "grid" else int(self.count)

    def __len__(self) -> int:
        return self.size

    @property
    def groups(self) -> int:
        """Number of groups of :attr:`group_size` scenes."""
        return -(-self.size // self.group_size)

    @property
    def key(self) -> str:
        """A hex SHA-256 of the base scene's key, the axes and the design."""
        text = repr([SWEEP_SCHEMA, self.base.key, [a.canonical() for a in self.axes], self.method,
                     self.size, self.seed, self.group_size])
        return hashlib.sha256(text.encode()).hexdigest()

    def points(self, start: int, stop: int) -> np.ndarray:
        """Design points of scenes *start* to *stop* − 1 (see :func:`design_points`).

        Parameters
        ----------
        start, stop : int
            Range of scene indices.
        """
        shape = [len(a.values) if a.values is not None else 0 for a in self.axes]
        return design_points(self.method, start, stop, count=self.size, seed=self.seed, shape=shape)

    def chunks(self, start_group: int = 0) -> Iterator[tuple[int, int, np.ndarray]]:
        """(start, stop, points) of every group from *start_group* on, drawing points in large blocks.

        Parameters
        ----------
        start_group : int
            First group.
        """
        block = max(self.group_size, 65536 // self.group_size * self.group_size)
        for lo in range(start_group * self.group_size, self.size, block):
            hi = min(lo + block, self.size)
            pts = self.points(lo, hi)
            for a in range(lo, hi, self.group_size):
                b = min(a + self.group_size, hi)
                yield a, b, pts[a - lo:b - lo]

    def values(self, points: np.ndarray) -> dict[str, np.ndarray]:
        """Per axis, its values at design *points* (one row per scene).

        Parameters
        ----------
        points : ndarray, shape (count, axes)
            From :meth:`points`.
        """
        grid = self.method == "grid"
        return {a.name: a.pick(points[:, j], grid) for j, a in enumerate(self.axes)}

    def scenes(self, start: int = 0, stop: int | None = None) -> list[Scene]:
        """The scenes *start* to *stop* − 1.

        Parameters
        ----------
        start, stop : int
            Range of scene indices (default: all; mind the size).
        """
        stop = self.size if stop is None else stop
        return self.scenes_at(self.values(self.points(start, stop)))

    def scenes_at(self, values: dict[str, np.ndarray]) -> list[Scene]:
        """The scenes with these axis values (as :meth:`values` gives them).

        Parameters
        ----------
        values : dict of str to ndarray
            Per axis, one value per scene.
        """
        count = len(next(iter(values.values())))
        base = self.base
        out = []
        for k in range(count):
            q, rates, forces = list(base.q), None, None
            changes: dict = {}
            params = None
            for axis, (kind, joint) in zip(self.axes, self._kinds):
                v = values[axis.name][k]
                v = float(v) if axis.numeric else v
                if kind == "q":
                    q[joint] = v
                elif kind == "rate":
                    rates = rates or list(base.initial_rates or [0.0] * len(q))
                    rates[joint] = v
                elif kind == "force":
                    forces = forces or list(base.forces)
                    forces[joint] = v
                elif kind == "parameter":
                    params = params if params is not None else dict(base.parameters)
                    params[axis.name] = v
                else:
                    changes[kind] = v
            changes["q"] = tuple(q)
            if rates is not None:
                changes["initial_rates"] = tuple(rates)
            if forces is not None:
                changes["forces"] = tuple(forces)
            if params is not None:
                changes["parameters"] = params
            out.append(base.replace(**changes))
        return out

    def describe(self) -> dict:
        """The sweep as plain data, for a results store's manifest."""
        return {"schema": SWEEP_SCHEMA, "key": self.key, "scene": self.base.name, "base_key": self.base.key,
                "method": self.method, "count": self.size, "seed": self.seed, "group_size": self.group_size,
                "axes": [{"name": a.name, "values": None if a.values is None else list(a.values),
                          "low": a.low, "high": a.high, "log": a.log} for a in self.axes],
                "solvers": list(self.base.solvers), "preset": self.base.preset, "source": self.base.source,
                "joint_units": list(self.base.system().provenance.units or ())}


def _check_units(base: Scene, name: str, kind: str, joint: int, values: list) -> None:
    """One sentence if a swept value's unit does not measure what it sets (as a scene file's would)."""
    try:
        if kind in ("q", "rate"):
            joints = getattr(scene_model(base), "joints", None)
            for v in values:
                vector = [0.0] * len(base.q)
                vector[joint] = v
                check_joint_dimensions(vector, joints, rates=kind == "rate", name="q" if kind == "q" else "r")
        elif kind == "parameter":
            spec = base.model
            urdf = spec.from_urdf
            # a model given by its matrices declares no units: its parameters are not judged
            units = {"g": "m/s^2"} if urdf else robot_family(spec.robot)[0].parameter_units(
                [name]) if spec.robot is not None else {}
            for v in values:
                check_parameter_units({name: v}, units)
    except InputError as exc:
        raise InputError(f"axis {name}: {exc}") from None


def sweep_from(base: Scene, axes: dict, **design) -> Sweep:
    """A :class:`Sweep` from a base scene and a mapping of axis name to values, range or table.

    Parameters
    ----------
    base : Scene
        The base scene; an empty q becomes zeros.
    axes : dict
        Name to a list of values, a pair [low, high] for sampled designs, or a table
        with ``values``, or ``low``, ``high`` and ``scale = "log"``.
    **design
        ``method``, ``count``, ``seed``, ``group_size``.
    """
    method = design.get("method", "grid")
    built = []
    for name, spec in axes.items():
        built.append(_axis(str(name), spec, method))
    if not base.q:
        base = base.replace(q=(0.0,) * base.numeric_model().dof)
    return Sweep(base, tuple(built), **design)


#: What a swept value measures, by axis kind: a string with a unit is read as in a scene file.
_DIMENSIONS = {"q": COORDINATE, "rate": RATE, "t_stop": "time", "parameter": ANY}


def _axis(name: str, spec, method: str) -> Axis:
    dimension = _DIMENSIONS.get(axis_kind(name)[0])
    if dimension is not None:
        spec = _measured(name, spec, dimension)
    if isinstance(spec, dict):
        unknown = set(spec) - {"values", "low", "high", "scale", "count"}
        if unknown:
            raise InputError(f"axis {name}: unknown key {sorted(unknown)[0]} (known: values, low, high, scale, count)")
        scale = spec.get("scale", "linear")
        if scale not in ("linear", "log"):
            raise InputError(f"axis {name}: scale must be \"linear\" or \"log\", got {scale!r}")
        if "values" in spec:
            return Axis(name, values=tuple(_list(name, spec["values"])))
        low, high = _num(name, spec.get("low")), _num(name, spec.get("high"))
        if method == "grid":
            n = spec.get("count")
            if not isinstance(n, int) or isinstance(n, bool) or n < 1:
                raise InputError(f"axis {name}: a grid over a range needs count, the number of values")
            if n > MAX_AXIS_VALUES:
                raise InputError(f"axis {name}: count {n:,} is more than the {MAX_AXIS_VALUES:,} values a grid axis "
                                 "may list: for finer sampling use method = \"random\", \"lhs\" or \"sobol\"")
            if scale == "log" and not 0 < min(low, high):
                raise InputError(f"axis {name}: a log scale needs low and high above 0, got {low:g} and {high:g}")
            pts = np.geomspace(low, high, n) if scale == "log" else np.linspace(low, high, n)
            return Axis(name, values=tuple(float(x) for x in pts))
        if scale == "log" and not 0 < min(low, high):
            raise InputError(f"axis {name}: a log scale needs low and high above 0, got {low:g} and {high:g}")
        return Axis(name, low=low, high=high, log=scale == "log")
    items = _list(name, spec)
    pair = len(items) == 2 and all(isinstance(x, float) for x in items)
    if method != "grid" and pair:
        return Axis(name, low=items[0], high=items[1])
    return Axis(name, values=tuple(items))


def _measured(name: str, spec, dimension):
    """*spec* with each string read as a number with its unit (``"30 deg"``, ``"2 kg"``)."""
    def read(v):
        if not isinstance(v, str):
            return v
        try:
            return parse_number(v, dimension)
        except InputError as exc:
            raise InputError(f"axis {name}: {exc}") from None
    if isinstance(spec, dict):
        return {k: ([read(x) for x in v] if k == "values" and isinstance(v, list) else
                    read(v) if k in ("low", "high") else v) for k, v in spec.items()}
    return [read(x) for x in spec] if isinstance(spec, list) else spec


def _num(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"axis {name}: low and high must be numbers")
    return value if isinstance(value, Measured) else float(value)


def _list(name: str, value) -> list:
    if not isinstance(value, list) or not value:
        raise InputError(f"axis {name}: expected a list of values, a range [low, high] or a table")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            raise InputError(f"axis {name}: values must be numbers or strings")
        out.append(v if isinstance(v, Measured) else float(v) if isinstance(v, (int, float)) else v)
    if not all(math.isfinite(v) for v in out if isinstance(v, float)):
        raise InputError(f"axis {name}: values must be finite")
    return out


def load_sweep(path) -> Sweep:
    """Read a scene file with a ``[sweep]`` table (see docs/scenes.md).

    Parameters
    ----------
    path : str or Path
        The TOML file.
    """
    from ..scenes.toml import read_text, scene_from_table, toml_table, validated
    path = Path(path)
    data = toml_table(read_text(path, "sweep file"), path)
    table = data.pop("sweep", None)
    if not isinstance(table, dict):
        raise InputError(f"{path}: [sweep]: missing: a sweep file needs a [sweep] table with axes")
    base = scene_from_table(data, path)
    if not base.q:          # axes over q need every coordinate: the rest start at 0
        base = base.replace(q=(0.0,) * base.numeric_model().dof)
    base = validated(base)
    for key in ("netlist_file", "csv_file", "plot_file"):
        if getattr(base, key):
            raise InputError(f"{path}: [outputs]: a sweep stores its results with analogy batch -o DIR; "
                             "remove csv, plot and netlist files")
    unknown = set(table) - {"method", "count", "seed", "group_size", "axes"}
    if unknown:
        raise InputError(f"{path}: unknown key [sweep] {sorted(unknown)[0]} "
                         "(known: method, count, seed, group_size, axes)")
    axes = table.get("axes")
    if not isinstance(axes, dict) or not axes:
        raise InputError(f"{path}: [sweep.axes]: missing: map each swept name to values or a range")
    design = {k: table[k] for k in ("method", "count", "seed", "group_size") if k in table}
    for k in ("count", "seed", "group_size"):
        if k in design and (isinstance(design[k], bool) or not isinstance(design[k], int)):
            raise InputError(f"{path}: [sweep] {k}: expected a whole number")
    if "method" in design and not isinstance(design["method"], str):
        raise InputError(f"{path}: [sweep] method: expected a string")
    try:
        return sweep_from(base, axes, **design)
    except InputError as exc:
        raise InputError(f"{path}: [sweep] {exc}") from None

