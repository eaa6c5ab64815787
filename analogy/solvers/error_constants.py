"""ngspice's error constants: the reltol a tolerance asks for on a linear circuit that does not ring."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ..files import replaced

__all__ = ["ErrorConstant", "CALIBRATION", "CALIBRATED_MAX_STEPS", "CALIBRATED_TOPOLOGIES", "SERIAL_NODE_LIMIT",
           "RELTOL_LIMITS",
           "RINGING_LIMIT", "FLOOR_LIMIT", "SAFETY", "calibrated_options",
           "calibrated_reltol", "error_constants", "predicted_error", "spice_reltol", "read_constants",
           "step_phase", "write_constants"]

#: The calibration the package ships; ``analogy bench --calibrate`` measures it again and writes it.
CALIBRATION = Path(__file__).with_name("calibration.csv")
#: reltol stays within these: under 1e-14 Newton's test compares rounding; over 1e-3 the trapezoidal
#: rule's truncation check no longer follows h² (ngspice's own default).
RELTOL_LIMITS = (1e-14, 1e-3)
#: The most radians Φ a calibrated circuit may ring through. Past it the phase error adds up
#: with Φ, and how much of it reaches each output depends on that output's share of the mode: at
#: reltol 1e-9, 5.3e-4 on flexpar (Φ = 516) and 1.4e-4 on 10 undamped periods (Φ = 145). The
#: preset's own settings, with their phase cap, run those and are judged.
RINGING_LIMIT = 1.0
#: The room a chosen reltol leaves under the bound: its calibrated error is at most tol/SAFETY. Each
#: constant is the worst of its calibration circuits, which that reltol would leave just on the bound,
#: and a circuit outside them can err more: serial4's modal circuit erred 1.3 times its calibrated
#: error. 2 costs 41 % more steps than none (steps go as error^-1/2).
SAFETY = 2.0
#: The largest rounding floor of abstol (4·n·ε·charge over the first step), over the current scale, that
#: the constants speak for: up to 6.3e-9 on the calibration circuits (serial12). Past it the floor, not
#: reltol, may judge each step: the Panda's 3.2e-7 left its small r3 at 1.7e-6 at the accurate reltol.
FLOOR_LIMIT = 1e-8
#: The node maps the constants were measured on (a custom T erred 3e-6 at the accurate reltol).
CALIBRATED_TOPOLOGIES = ("serial", "parallel", "modal")
#: The longest serial chain the constants speak for. A serial circuit's joint rates are differences of
#: node velocities, so a node's error reaches a small joint rate magnified: serial13 to serial20 erred
#: 1.1e-6 to 2.3e-6 of their first joint rate's peak (1.4 % of the largest) at the accurate reltol, and
#: serial20 collapsed from reltol 1e-11 on.
SERIAL_NODE_LIMIT = 12
#: The step cap t_stop/50 (ngspice's own default) the constants are measured at and hold for.
CALIBRATED_MAX_STEPS = 50
#: abstol, vntol and chgtol over reltol (each then times the circuit's current, velocity and charge
#: scale): the ratios of the accurate preset's options, so that reltol alone sets the error.
_ABSOLUTE = {"abstol": 1e-5, "vntol": 0.1, "chgtol": 1e-10}


def calibrated_options(reltol: float) -> dict:
    """ngspice's options of a calibrated run at *reltol*: trap, trtol = 1, absolute tolerances in proportion.

    Parameters
    ----------
    reltol : float
        ngspice's reltol.
    """
    return {"method": "trap", "reltol": f"{reltol:.3g}", **{k: f"{f * reltol:.3g}" for k, f in _ABSOLUTE.items()},
            "trtol": "1"}


@dataclass(frozen=True)
class ErrorConstant:
    """What ngspice's trapezoidal rule (trtol = 1) erred at one reltol over the calibration circuits.

    The worst error over each output's own peak was at most c0·reltol^(2/3) on the calibration
    circuits that do not ring (Φ ≤ :data:`RINGING_LIMIT`): the truncation check holds each step's
    error to about reltol, and a step of h = (12·reltol)^(1/3)/ω errs as h³, so over a run the
    error goes as reltol^(2/3).

    Attributes
    ----------
    reltol : float
        The rung.
    c0 : float
        The constant: the largest error / reltol^(2/3) over the calibration circuits.
    circuits : int
        How many circuits measured it.
    worst : str
        The circuit that set it.
    """

    reltol: float
    c0: float
    circuits: int = 0
    worst: str = ""

    @property
    def error(self) -> float:
        """The error a run at this reltol may have: c0·reltol^(2/3)."""
        return self.c0 * self.reltol ** (2 / 3)


def read_constants(path) -> tuple[ErrorConstant, ...]:
    """The rungs a calibration file holds, loosest reltol last.

    Parameters
    ----------
    path : str or Path
        A file that :func:`write_constants` wrote.
    """
    with open(path, newline="") as fh:
        rows = [ErrorConstant(float(r["reltol"]), float(r["c0"]), int(r["circuits"]), r["worst"])
                for r in csv.DictReader(fh)]
    if not rows:
        raise ValueError(f"{path} holds no error constants")
    return tuple(sorted(rows, key=lambda r: r.reltol))


def write_constants(rows, path) -> Path:
    """Write the rungs *rows* where :func:`read_constants` reads them.

    Parameters
    ----------
    rows : iterable of ErrorConstant
        The measured rungs.
    path : str or Path
        The file.
    """
    path = Path(path)
    with replaced(path) as tmp, open(tmp, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["reltol", "c0", "circuits", "worst"])
        for r in sorted(rows, key=lambda r: r.reltol):
            out.writerow([f"{r.reltol:.3g}", f"{r.c0:.4g}", r.circuits, r.worst])
    error_constants.cache_clear()
    _shipped_reltol.cache_clear()
    _shipped_calibrated.cache_clear()
    return path


@lru_cache(maxsize=1)
def error_constants() -> tuple[ErrorConstant, ...]:
    """The shipped calibration (:data:`CALIBRATION`)."""
    return read_constants(CALIBRATION)


def predicted_error(reltol: float, rungs=None) -> float:
    """The calibrated error of a run at *reltol*: each rung's error c0·reltol^(2/3), made
    non-decreasing in reltol (a tighter rung that erred more is an error floor, which holds for the
    looser ones too), interpolated linearly in log-log between rungs; past the loosest rung it grows as
    reltol^(2/3), and under the tightest it stays at that rung's: nothing better was measured.

    Parameters
    ----------
    reltol : float
        ngspice's reltol.
    rungs : sequence of ErrorConstant, optional
        The calibration (default :func:`error_constants`).
    """
    rungs = error_constants() if rungs is None else rungs
    logs = [math.log(r.reltol) for r in rungs]
    errors = [math.log(max(r.error, 1e-300)) for r in rungs]
    errors = [max(errors[: i + 1]) for i in range(len(errors))]
    x = math.log(reltol)
    if x <= logs[0]:
        return math.exp(errors[0])
    if x >= logs[-1]:
        return math.exp(errors[-1] + (x - logs[-1]) * 2 / 3)
    i = next(j for j in range(1, len(logs)) if x <= logs[j])
    w = (x - logs[i - 1]) / (logs[i] - logs[i - 1])
    return math.exp((1 - w) * errors[i - 1] + w * errors[i])


def spice_reltol(tol: float, rungs=None) -> float:
    """The loosest reltol whose calibrated error (:func:`predicted_error`) is at most *tol*/:data:`SAFETY`.

    Parameters
    ----------
    tol : float
        The bound on each output's error over its own peak.
    rungs : sequence of ErrorConstant, optional
        The calibration (default :func:`error_constants`).
    """
    if rungs is None:
        return _shipped_reltol(float(tol))
    return _bisected_reltol(tol, rungs)


@lru_cache(maxsize=64)
def _shipped_reltol(tol: float) -> float:
    """:func:`spice_reltol` on the shipped calibration: a batch asks it once per group."""
    return _bisected_reltol(tol, error_constants())


def _bisected_reltol(tol: float, rungs) -> float:
    low, high = (math.log(v) for v in RELTOL_LIMITS)
    tol = tol / SAFETY
    if predicted_error(math.exp(high), rungs) <= tol:
        return RELTOL_LIMITS[1]
    if predicted_error(math.exp(low), rungs) > tol:
        return RELTOL_LIMITS[0]         # the bound may fail: the result is judged and flagged
    for _ in range(60):                 # bisection in log reltol to 1e-3 of a decade
        mid = 0.5 * (low + high)
        low, high = (mid, high) if predicted_error(math.exp(mid), rungs) <= tol else (low, mid)
        if high - low < 2e-3:
            break
    return math.exp(low)


def calibrated_reltol(tol: float, ringing: float, rungs=None) -> float | None:
    """:func:`spice_reltol`, or None where the constants do not speak for the circuit: it rings
    (Φ past :data:`RINGING_LIMIT`), or even the tightest reltol's calibrated error passes *tol*. Then
    the preset's own settings run, and are judged.

    Parameters
    ----------
    tol : float
        The bound.
    ringing : float
        Φ of the circuit.
    rungs : sequence of ErrorConstant, optional
        The calibration (default :func:`error_constants`).
    """
    if ringing > RINGING_LIMIT:
        return None
    return _shipped_calibrated(float(tol)) if rungs is None else _calibrated(tol, rungs)


def _calibrated(tol: float, rungs) -> float | None:
    """:func:`calibrated_reltol` of a circuit that does not ring."""
    r = spice_reltol(tol, rungs)
    return r if predicted_error(r, rungs) <= tol / SAFETY else None


@lru_cache(maxsize=64)
def _shipped_calibrated(tol: float) -> float | None:
    """:func:`_calibrated` on the shipped calibration, kept: a batch asks it twice per circuit."""
    return _calibrated(tol, None)


def step_phase(reltol: float) -> float:
    """ω·h of the steps ngspice's truncation check takes on an oscillation at *reltol* (trtol = 1): the
    trapezoidal rule errs (ω·h)³/12 of the amplitude per step, held to reltol of it.

    Parameters
    ----------
    reltol : float
        ngspice's reltol.
    """
    return (12.0 * reltol) ** (1 / 3)
