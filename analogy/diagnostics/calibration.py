"""Measure ngspice's error constants again (``analogy bench --calibrate``): each reltol's error on the calibration set."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator

import numpy as np

from ..files import replaced
from .bench import bench_scenes
from ..errors import AnalogyError
from ..presets import PRESETS, Preset
from ..progress import Progress
from ..results.metrics import output_errors
from ..scenes.builtin import SCENES, scene
from ..scenes.scene import Scene
from ..scenes.spec import ModelSpec
from ..solvers.error_constants import CALIBRATED_MAX_STEPS, RINGING_LIMIT, ErrorConstant, calibrated_options
from ..solvers.exact import solve_exact
from ..solvers.spice import session
from ..solvers.transient import beyond_calibration, netlist
from ..circuit.scales import system_scales
from .stress.families import cases

__all__ = ["CalibrationRun", "CALIBRATION_RELTOLS", "SERIAL_CHAINS", "calibration_circuits", "calibration_runs",
           "error_constants_of", "write_runs"]

#: The rungs, a decade apart: from the fast preset's reltol to past what 1e-9 asks for.
CALIBRATION_RELTOLS = tuple(10.0 ** -k for k in range(5, 14))
#: Stress cases left out, and why: an undriven output's peak is itself rounding (cond 1), a cond(M)
#: past 1e4 sets a rounding floor over any reltol, and ratio 1e4 or 1e4 periods ask for 10^8 steps.
_LEFT_OUT = ("cond 1e+00", "cond 1e+06", "cond 1e+08", "cond 1e+1", "ratio 1e+04", "ratio 1e+06", "ratio 1e+08",
             "100 periods", "1000 periods", "10000 periods")
#: The serial chains measured, beside the built-in scenes (serial2, serial3).
SERIAL_CHAINS = (6, 12)
#: Φ is read at the accurate preset's bound: the modes that can reach 1e-6 of the peak.
_BOUND = PRESETS["accurate"].bound


@dataclass(frozen=True)
class CalibrationRun:
    """One circuit at one reltol: its ringing Φ, its worst error over each output's own peak, its time points."""

    circuit: str
    reltol: float
    ringing: float
    error: float
    points: int
    status: str = "ok"


def calibration_circuits() -> Iterator[tuple[str, object]]:
    """(name, linear node system): the bench's linear scenes (serial and modal), the built-in linear
    scenes, the serial chains :data:`SERIAL_CHAINS`, and the stress families a (conditioning), b (time
    scales) and c (undamped runs), each that does not ring (Φ ≤ :data:`~analogy.solvers.error_constants.RINGING_LIMIT`)."""
    seen = set()
    found = []
    for sc in bench_scenes()[:3] + [scene(name) for name in SCENES]:
        if sc.name in seen:
            continue
        seen.add(sc.name)
        system = sc.system()
        if system.kind != "linear":
            continue
        found.append((sc.name, system))
        if sc.name in ("default", "random10", "random50"):
            found.append((f"{sc.name} modal", sc.replace(topology="modal").system()))
    # serial chains up to the longest the constants speak for (SERIAL_NODE_LIMIT)
    for n in SERIAL_CHAINS:
        sc = Scene.of(f"serial{n}", ModelSpec(robot=f"serial{n}"), q=(0.0,) * n, forces=(1.0,) * n)
        found.append((sc.name, sc.system()))
    found += [(f"stress {case.family}: {case.label}", case.build()) for case in cases("abc")
              if not any(word in case.label for word in _LEFT_OUT)]
    for name, system in found:
        if system_scales(system).ringing(_BOUND) <= RINGING_LIMIT and not beyond_calibration(system):
            yield name, system


def _rung(reltol: float) -> Preset:
    # the accurate preset's print step and first step, whose abstol floor the runs share
    accurate = PRESETS["accurate"]
    return replace(accurate, name=f"reltol {reltol:g}", spice=replace(
        accurate.spice, options=calibrated_options(reltol), max_steps=CALIBRATED_MAX_STEPS, phase_step=math.inf,
        calibrated=False))


def calibration_runs(reltols=CALIBRATION_RELTOLS, progress: bool = True) -> list[CalibrationRun]:
    """Every calibration circuit at every reltol, each error against the exact solution.

    Parameters
    ----------
    reltols : sequence of float
        The rungs.
    progress : bool
        Show progress.
    """
    circuits = list(calibration_circuits())
    bar = Progress(len(circuits) * len(reltols), unit="run", enabled=progress)
    sess = session()
    runs = []
    for name, system in circuits:
        phi = system_scales(system).ringing(_BOUND)
        for r in reltols:
            try:
                data = sess.run(netlist(system, _rung(r), printing=False), system.nodes)
                t = data["time"]
                rates = system.joint_rates(np.column_stack([data[k] for k in system.nodes]))
                err = float(np.max(output_errors(rates, solve_exact(system, t).rates)[1]))
                runs.append(CalibrationRun(name, r, phi, err, int(t.size)))
            except AnalogyError as exc:       # a collapsed step: the solver's retries are another matter
                runs.append(CalibrationRun(name, r, phi, math.nan, 0, f"failed: {str(exc).splitlines()[0][:80]}"))
            bar.update(1)
    bar.close()
    return runs


def error_constants_of(runs) -> list[ErrorConstant]:
    """Per reltol, the smallest c0 with every run's error ≤ c0·reltol^(2/3).

    Parameters
    ----------
    runs : iterable of CalibrationRun
        :func:`calibration_runs`.
    """
    out = []
    for r in sorted({run.reltol for run in runs}):
        ok = [run for run in runs if run.reltol == r and run.status == "ok" and math.isfinite(run.error)]
        worst = max(ok, key=lambda run: run.error)
        out.append(ErrorConstant(r, worst.error / r ** (2 / 3), len(ok), worst.circuit))
    return out


def write_runs(runs, path) -> Path:
    """One row per circuit and reltol: Φ, error over the peak, points, status.

    Parameters
    ----------
    runs : iterable of CalibrationRun
        :func:`calibration_runs`.
    path : str or Path
        The CSV file.
    """
    path = Path(path)
    with replaced(path) as tmp, open(tmp, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["circuit", "reltol", "ringing", "error_over_peak", "points", "status"])
        for r in runs:
            out.writerow([r.circuit, f"{r.reltol:.3g}", f"{r.ringing:.4g}", f"{r.error:.3e}", r.points, r.status])
    return path
