"""Scenes: one simulation job as pure, hashable data, with a content key stable across machines."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, fields
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

from ..errors import InputError
from ..model.dynamics import DynamicsKind
from ..model.motors import motor_spec
from ..presets import DEFAULT_SOLVERS, DEFAULT_T_STOP, Preset, PresetName
from ..presets import preset as get_preset
from .build import scene_model, scene_system, scene_systems, symbolic_model
from .paths import inside_folder
from .rules import check_scene
from .spec import ModelSpec, freeze

if TYPE_CHECKING:
    from ..solvers.registry import SolverName

__all__ = ["Scene", "OUTPUTS", "SCENE_SCHEMA", "content_key"]

#: The quantities a scene may ask for.
OUTPUTS = ("joint_rates", "node_voltages", "element_currents")

#: Version of what a content key covers; bumped when the meaning of a field changes.
SCENE_SCHEMA = "analogy-scene-2"

# Fields that name, describe or locate a scene but do not change its result.
# Where results are written changes no result: a renamed output file or folder re-solves nothing.
_NOT_CONTENT = ("name", "description", "source", "netlist_file", "csv_file", "plot_file")
_WHEN_SET = ("urdf", "joints", "joint_frame", "geometric_stiffness", "base", "contacts")
#: Scene fields added after SCENE_SCHEMA, in its key only when not at these defaults: earlier keys stand.
_SCENE_WHEN_SET = {"estimate": False, "refine": False, "motors": (), "voltages": ()}


@dataclass(frozen=True)
class Scene:
    """One simulation job: model, configuration, inputs, outputs and solvers, as plain data.

    Built-in scenes (:data:`analogy.scenes.builtin.SCENES`) and TOML files
    (:func:`analogy.scenes.toml.load_scene`) give scenes; :meth:`system` builds the
    node system; :func:`analogy.scenes.run.run_scene` computes what the outputs ask for.
    Two scenes with the same :attr:`key` give the same result.

    Attributes
    ----------
    name, description : str
        Labels (not part of the key).
    model : ModelSpec
        The model.
    q : tuple of float
        Configuration.
    parameters : tuple of (str, float)
        Parameter values, sorted by name.
    topology : str, tuple of tuple of float, or None
        ``"serial"``, ``"parallel"``, ``"modal"`` (one node per mode), a matrix T, or None for the model's own
        (the modal map for a linear system past 12 joints whose own circuit is dense:
        :func:`~analogy.circuit.topology.default_topology`).
    forces : tuple
        One entry per joint: a number (a step at t = 0), a waveform string, or a tuple of these.
    initial_rates : tuple of float or None
        Joint rates at t = 0 (None: zero).
    t_stop : float
        End of the simulated interval [s].
    equilibrium : bool
        Move q's elastic coordinates (a flexible link's modes) to the static equilibrium
        under gravity first, the joints held where q puts them
        (:func:`~analogy.model.equilibrium.static_equilibrium`).
    dynamics : {"linear", "nonlinear"}
        The circuit at q (linear) or the full configuration-dependent motion.
    joint_rates : bool
        Report joint rates.
    node_voltages, element_currents : tuple of str or bool
        Names to report, or True for all.
    netlist : bool
        Produce the netlist text.
    netlist_file, csv_file, plot_file : str or None
        Files to write, relative to the output folder.
    solvers : tuple of str
        Registered solvers to run.
    preset : str
        Accuracy preset.
    errors : bool
        Report errors against the reference (running it if need be).
    estimate : bool
        Also estimate each solver's error without the reference, by a refined second run
        (:func:`~analogy.study.estimate.estimated_errors`); with *errors* off it alone judges the bound.
    refine : bool
        Estimate, and refine a run whose estimate exceeds the bound until it meets it
        (``compare(..., refine=True)``).
    step : float or None
        Output step; None keeps SPICE's own points.
    source : str or None
        The scene file it came from (not part of the key).
    motors : tuple
        DC motors and gearboxes on the joints (:func:`~analogy.model.motors.motor_spec` of a
        ``[motors]`` table); empty for the joint forces' current sources. With motors the
        scene is a drive: its applied forces are left out and each motor takes a voltage.
    voltages : tuple
        One waveform per motor, in joint order (a number for a constant voltage).
    """

    name: str
    model: ModelSpec
    q: tuple = ()
    parameters: tuple = ()
    topology: object = None
    forces: tuple = ()
    initial_rates: tuple | None = None
    t_stop: float = DEFAULT_T_STOP
    equilibrium: bool = False
    dynamics: DynamicsKind = "linear"
    joint_rates: bool = True
    node_voltages: object = ()
    element_currents: object = ()
    netlist: bool = False
    netlist_file: str | None = None
    csv_file: str | None = None
    plot_file: str | None = None
    solvers: tuple[SolverName, ...] = DEFAULT_SOLVERS  # type: ignore[assignment]
    preset: PresetName = "accurate"
    errors: bool = True
    estimate: bool = False
    refine: bool = False
    step: float | None = None
    description: str = ""
    source: str | None = None
    motors: tuple = ()
    voltages: tuple = ()

    def __repr__(self) -> str:
        m = self.model
        what = m.robot or ("a URDF model" if m.urdf is not None else "a model given by its matrices")
        q = f" at q={tuple(float(x) for x in self.q)!r}" if self.q and all(
            isinstance(x, (int, float)) for x in self.q) else ""
        return (f"<Scene {self.name}: {what}{q}, {self.dynamics}, t_stop={self.t_stop:g} s, "
                f"{'+'.join(self.solvers) or 'no solver'} at {self.preset}, key {self.key[:12]}>")

    def __post_init__(self):
        if not isinstance(self.model, ModelSpec):
            raise InputError(f"scene {self.name!r}: model must be a ModelSpec")
        object.__setattr__(self, "preset", check_scene(self))
        try:
            hash(self)
        except TypeError:
            raise InputError(f"scene {self.name!r} holds a list or table where a tuple is "
                             "needed: build it with Scene.of") from None

    @classmethod
    def of(cls, name: str, model: ModelSpec | str, **fields_) -> "Scene":
        """A scene from friendlier values: a robot name for *model*, lists, a parameter dict.

        Parameters
        ----------
        name : str
            The scene's name.
        model : ModelSpec or str
            A spec, or a built-in robot name.
        **fields_
            Any other :class:`Scene` field.
        """
        spec = model if isinstance(model, ModelSpec) else ModelSpec(robot=model)
        if isinstance(fields_.get("parameters"), Mapping):
            fields_["parameters"] = tuple(sorted(fields_["parameters"].items()))
        if isinstance(fields_.get("motors"), Mapping):
            fields_["motors"] = motor_spec(fields_["motors"])
        for key in ("q", "forces", "initial_rates", "topology", "node_voltages", "element_currents",
                    "solvers", "parameters", "voltages"):
            if key in fields_ and fields_[key] is not None and not isinstance(fields_[key], (str, bool)):
                fields_[key] = freeze(fields_[key])
        return cls(name, spec, **fields_)

    def replace(self, **changes) -> "Scene":
        """A copy with *changes*; lists and a parameter dict are accepted as in :meth:`of`.

        Parameters
        ----------
        **changes
            New field values.
        """
        current = {f.name: getattr(self, f.name) for f in fields(self)}
        current.update(changes)
        name, model = current.pop("name"), current.pop("model")
        return Scene.of(name, model, **current)

    @property
    def settings(self) -> Preset:
        """The settings of :attr:`preset`, the scene's accuracy (its bound, and what each solver receives)."""
        return get_preset(self.preset)

    @property
    def parameter_values(self) -> dict[str, float]:
        """The parameters as a dict."""
        return dict(self.parameters)

    @property
    def key(self) -> str:
        """Content key: a SHA-256 of everything that determines the result (see :func:`content_key`)."""
        return content_key(self)

    @property
    def reference(self) -> bool:
        """True if a reference solution runs: asked for, or the yardstick of the others."""
        return "exact" in self.solvers or (self.errors and bool(self.solvers))

    @property
    def needs_solver(self) -> bool:
        """True if any output is a solver result."""
        return bool(self.joint_rates or self.node_voltages or self.element_currents)

    def path(self, name: str, output_dir=None) -> Path:
        """Where an output file named *name* goes.

        Parameters
        ----------
        name : str
            A relative file name from the scene.
        output_dir : str or Path, optional
            The output folder; default the scene file's folder, else the working folder.
        """
        folder = Path(output_dir) if output_dir is not None else \
            (Path(self.source).parent if self.source is not None else Path.cwd())
        return inside_folder(folder, name)

    def build_model(self) -> object:
        """The scene's symbolic model (sympy): a robot's derivation, or the parsed matrices."""
        return symbolic_model(self)

    def numeric_model(self) -> object:
        """The model the scene evaluates: compiled from the on-disk cache where it can be."""
        return scene_model(self)

    def system(self, model=None) -> object:
        """The scene's node system (see :func:`analogy.scenes.build.scene_system`).

        Parameters
        ----------
        model : object, optional
            An already built model to evaluate instead of building the scene's own.
        """
        return scene_system(self, model)

    def systems(self, qs, model=None, parameters=None) -> list:
        """The scene's node systems at every configuration in *qs*, built as one stack.

        Parameters
        ----------
        qs : array_like, shape (count, n)
            Configurations.
        model : object, optional
            An already built model.
        parameters : mapping of str to array_like, optional
            Parameter values per row, replacing the scene's own.
        """
        return scene_systems(self, qs, model, parameters)

    def family(self) -> tuple | None:
        """What the scene shares with scenes that differ only in q, parameter values and t_stop, as a hashable key.

        Such scenes are built as one stack (:meth:`systems`), each over its own horizon; only a built-in robot's
        parameters vary along a stack, since other models are derived with theirs. None
        when the scene is not built that way: nonlinear dynamics, a static equilibrium
        first, or a q that is not a flat tuple of real numbers.
        """
        if self.dynamics != "linear" or self.equilibrium or not (set(map(type, self.q)) <= _PLAIN_REALS or all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in self.q)):
            return None
        shared = tuple(k for k, _ in self.parameters) if self.model.robot is not None else self.parameters
        return (self.model, shared, self.topology, self.forces, self.initial_rates, len(self.q))


#: The types of a q whose values are plainly real numbers (their subclasses, bool excepted, are checked one by one).
_PLAIN_REALS = frozenset((int, float))


def _canonical(value):
    """A form whose repr is the same in every process; numbers and strings stay distinct."""
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, (int, float)):     # 0 and 0.0 give the same result, so the same key
        return f"f:{float(value)!r}"
    if isinstance(value, str):
        return f"s:{value}"
    if isinstance(value, tuple):
        return [_canonical(v) for v in value]
    if isinstance(value, ModelSpec):      # fields added later only when set: other scenes keep their keys
        return {f.name: _canonical(getattr(value, f.name)) for f in fields(value)
                if f.name not in _WHEN_SET or getattr(value, f.name) is not None}
    return repr(value)


def content_key(scene: Scene) -> str:
    """A hex SHA-256 of every field that determines *scene*'s result, in a canonical form.

    Names, descriptions, the source file and the output file names are left out (what is
    computed, and with which settings, is in); numbers are written with
    ``repr`` (exact for floats), so the key is the same in every process and on
    every machine. :data:`SCENE_SCHEMA` is part of it.

    Parameters
    ----------
    scene : Scene
        The scene.
    """
    # The text hashed is repr([SCENE_SCHEMA, sorted (name, canonical value) pairs]), built
    # field by field so that a model shared by many scenes is written out once.
    parts = ", ".join(f"({name!r}, {_model_text(value) if name == 'model' else repr(_canonical(value))})"
                      for name, value in sorted((n, getattr(scene, n)) for n in _CONTENT)
                      if name not in _SCENE_WHEN_SET or value != _SCENE_WHEN_SET[name])
    return hashlib.sha256(f"[{SCENE_SCHEMA!r}, [{parts}]]".encode()).hexdigest()


_CONTENT = tuple(f.name for f in fields(Scene) if f.name not in _NOT_CONTENT)


@lru_cache(maxsize=256)
def _model_text(spec: ModelSpec) -> str:
    return repr(_canonical(spec))
