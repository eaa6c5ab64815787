"""Resident memory grown per in-process solver run: the leak check behind ``analogy memory``."""

from __future__ import annotations

import gc
import os
import resource
import time as _time
from dataclasses import dataclass

from ..errors import InputError
from ..presets import preset as get_preset
from ..scenes.builtin import scene
from ..solvers.registry import solver as registered
from ..solvers.spice import session

__all__ = ["MemoryResult", "memory_per_run"]


@dataclass(frozen=True)
class MemoryResult:
    """Resident memory growth over many in-process runs of one solver on one system."""

    runs: int
    preset: str
    scene: str
    grown_kb: float
    seconds: float
    buffered_lines: int
    solver: str = "spice"

    @property
    def kb_per_run(self) -> float:
        return self.grown_kb / self.runs

    def __str__(self) -> str:
        lines = f"; ngspice lines buffered after the runs: {self.buffered_lines}" if self.solver == "spice" else ""
        return (f"memory: {self.runs} in-process {self.solver} runs of scene {self.scene} at preset "
                f"{self.preset}: resident memory grew {self.grown_kb:.0f} kB, {self.kb_per_run:.3f} kB per run "
                f"({self.seconds:.1f} s{lines})")


def _resident_kb() -> float:
    try:
        with open("/proc/self/statm") as f:         # current, not peak, resident size
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1024
    except OSError:
        return float(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def memory_per_run(runs: int = 10_000, preset: str = "accurate", scene_name: str = "default",
                   warmup: int = 200, solver: str = "spice") -> MemoryResult:
    """Resident memory grown per in-process solver run (for SPICE: netlist, ngspice run, vectors read, freed).

    The first *warmup* runs are not counted: they fill caches and the allocator's pools.

    Parameters
    ----------
    runs : int
        Counted runs.
    preset : str
        Accuracy preset.
    scene_name : str
        A built-in scene.
    warmup : int
        Runs before the count starts.
    solver : str
        A registered solver: ``spice``, ``ode``, ``exact`` or ``reference``.
    """
    if runs < 1 or warmup < 0:
        raise InputError("runs must be at least 1 and warmup at least 0")
    method, p = registered(solver), get_preset(preset)
    system = scene(scene_name).system()
    for _ in range(warmup):
        method.solve(system, None, p)
    gc.collect()
    before, start = _resident_kb(), _time.perf_counter()
    for _ in range(runs):
        method.solve(system, None, p)
    gc.collect()
    lines = len(session()._ng.lines) if solver == "spice" else 0
    return MemoryResult(runs, p.name, scene_name, _resident_kb() - before,
                        _time.perf_counter() - start, lines, solver)
