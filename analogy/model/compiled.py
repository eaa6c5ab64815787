"""Models compiled to numpy source and kept on disk, so a known model evaluates without sympy."""

from __future__ import annotations

import hashlib
import importlib.util
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import joint_units
from .base import RobotModel
from .joint import (
    JointStack,
    configuration_stack,
    evaluate_entries,
    stack_arguments,
    part_shapes,
)

__all__ = ["CompiledModel", "cache_dir", "compile_model", "load_compiled"]

_SOURCES = ("joint.py", "symbolic.py", "robots.py", "linkages.py", "compiled.py", "codegen.py", "flexible.py",
            "beams.py", "equilibrium.py", "catalog.py")


def cache_dir() -> Path | None:
    """``$ANALOGY_CACHE_DIR``, else ``$XDG_CACHE_HOME/analogy`` or ``~/.cache/analogy``.

    Setting ``ANALOGY_CACHE_DIR`` to an empty string turns the cache off.
    """
    env = os.environ.get("ANALOGY_CACHE_DIR")
    if env is not None:
        return Path(env) if env else None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "analogy"


def _key(name: str) -> str:
    # The derivation code is part of the key: editing it invalidates the cache.
    h = hashlib.sha256(name.encode())
    here = Path(__file__).parent
    for src in _SOURCES:
        p = here / src
        if p.exists():
            h.update(p.read_bytes())
    return h.hexdigest()[:24]


class CompiledModel(RobotModel):
    """A model's numeric functions, loaded from generated source: M, B, K, G at (q, parameters)."""

    def __init__(self, module):
        self._m = module
        self.name = module.NAME
        self.parameters = dict(module.PARAMETERS)
        self.coordinates = tuple(module.COORDINATES)
        self.topology = module.TOPOLOGY
        self.description = module.DESCRIPTION
        self.joints = module.JOINTS
        self.baked = bool(getattr(module, "BAKED", False))
        self._elastic = tuple(getattr(module, "ELASTIC", ()))

    @property
    def units(self) -> tuple[str, ...] | None:
        """Per coordinate, ``"rad"`` or ``"m"``, from :attr:`joints`."""
        return joint_units(self.joints)

    @property
    def dof(self) -> int:
        return self._m.DOF

    @property
    def elastic(self) -> tuple[int, ...]:
        """The coordinates with a spring of the model's own, found when its source was generated."""
        return self._elastic

    def joint_stack(self, qs, parameters=None) -> JointStack:
        """Evaluate at every row of *qs* at once (:meth:`~analogy.model.base.RobotModel.joint_stack`).

        Parameters
        ----------
        qs : array_like, shape (count, n)
            Configurations.
        parameters : mapping, optional
            Parameter overrides.
        """
        self._same_parameters(parameters)
        q = configuration_stack(self.name, self.coordinates, qs)
        args = list(q.T) + stack_arguments(self.name, self.parameters, parameters, len(q))
        return JointStack(*(evaluate_entries(self.name, f, args, shape, len(q)) for f, shape in self._parts()))

    def _same_parameters(self, parameters) -> None:
        # A baked model's numbers are its parameters: other values would be silently ignored.
        if not (self.baked and parameters):
            return
        if any(np.ndim(v) for v in parameters.values()):
            raise InputError(f"model {self.name!r} is rebuilt for new parameter values, "
                             "so its parameters cannot vary along a stack")
        if any(self.parameters.get(k) != float(v) for k, v in parameters.items()):
            raise InputError(f"{self.name} was compiled for one parameter set: build it for the others")

    def _parts(self):
        m = self._m
        return zip((m.mass_matrix, m.damping, m.stiffness, m.gravity), part_shapes(self.dof))


def compile_model(model, name: str, baked: bool = False) -> CompiledModel | None:
    """Write *model*'s numeric source to the cache under *name*; return it loaded (or None).

    Parameters
    ----------
    model : Model
        A symbolic model.
    name : str
        The cache entry's name.
    baked : bool
        The model's parameters are numbers in its expressions (see
        :func:`~analogy.model.codegen.module_source`); *name* must then name them.
    """
    from .codegen import module_source
    from .symbolic import Model
    folder = cache_dir()
    if folder is None or type(model) is not Model:     # closed chains solve numerically per call
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"model-{_key(name)}.py"
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(module_source(model, baked))
        os.replace(tmp, path)                           # atomic: readers never see half a file
    except OSError:
        return None
    return load_compiled(name)


def load_compiled(name: str) -> CompiledModel | None:
    """The cached compiled model *name*, or None if absent or unreadable.

    Parameters
    ----------
    name : str
        The cache entry's name.
    """
    folder = cache_dir()
    if folder is None:
        return None
    path = folder / f"model-{_key(name)}.py"
    if not path.is_file():
        return None
    spec = importlib.util.spec_from_file_location(f"analogy_compiled_{path.stem[6:]}", path)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
        return CompiledModel(module)
    except Exception:           # a damaged cache file is rebuilt, never trusted
        return None
