"""Accuracy presets, each a tolerance: one bound, and the SPICE, ODE and budget settings each solver receives."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Literal

import numpy as np

from .errors import InputError

__all__ = ["DEFAULT_SOLVERS", "DEFAULT_T_STOP", "Budget", "OdeSettings", "Preset", "PRESETS", "PresetName",
           "SpiceSettings", "preset", "tolerance_preset", "TOLERANCES", "TOLERANCE_RANGE"]

#: End of the simulated interval [s] when none is given: the same for scenes, systems and the CLI.
DEFAULT_T_STOP = 10.0
#: The solvers a scene or a comparison runs unless told otherwise.
DEFAULT_SOLVERS: tuple[str, ...] = ("spice", "ode", "exact")

#: About 5 minutes of ngspice 39 on one 2 GHz core, which steps Σᵢ cᵢ² operations at about
#: 1.7e8 per second (serial20 to serial100 over 20,000 points: 1.0 s and 118 s).
OPERATION_BUDGET = 5e10

#: Names of the built-in presets.
PresetName = Literal["fast", "accurate"]


@dataclass(frozen=True)
class SpiceSettings:
    """What ngspice receives of a preset: its ``.options``, its step caps, and how a run is refined.

    Attributes
    ----------
    options : dict
        ``.options`` for ngspice (integration method, tolerances). The absolute tolerances
        (``abstol``, ``vntol``, ``chgtol``) are relative to the circuit's own current, velocity
        and charge scales, so the netlist of a system in any units gets the same relative accuracy.
    max_steps : int
        ``.tran`` maximum internal step is t_stop/max_steps.
    phase_step : float
        Largest ω_max·h: the step cap from the system's fastest rate (see
        :class:`~analogy.circuit.scales.Scales`), where t_stop/max_steps is longer.
        Trapezoidal phase error grows as (ω·h)², and ngspice's per-device truncation
        check misses it when M' couples fast and slow modes.
    first_phase_step : float
        Largest ω_max·h of ngspice's first step, a backward-Euler step it never checks
        (a hundredth of the print step, made shorter where needed by a source's corner,
        see :mod:`analogy.solvers.transient`): on flex2 its error is 0.13·(ω·h)² of the
        peak, so this keeps it under 5% of the bound.
    decay_step : float
        Largest β·h of a decay larger than 10·*bound* of the peak, on a calibrated circuit. Past
        h·β = 2 the trapezoidal rule flips such a decay's sign at every step, which ngspice's check
        misses: the stress pair ω ratio 1e2, ζ = 1e3 erred 2.5e-6 at every reltol without this cap,
        and the pair ω ratio 1e6, ζ = 1e3 erred 6.1e-4 at fast with 1.0 and 3.7e-4 with 0.5 (its
        error goes as the cap: at accurate it misses at any cap, 7.7e-6 at 0.016, and is flagged).
    calibrated : bool
        A linear trapezoidal circuit takes its reltol (and chgtol and cap) from its own truncation
        model where ngspice runs it alone (:mod:`analogy.solvers.truncation`), else from the shipped
        error constants, for this bound and the circuit's ringing Φ
        (:func:`~analogy.solvers.error_constants.spice_reltol`), its absolute tolerances in proportion,
        the cap t_stop/50 the constants were measured at, and no phase cap on its oscillations (the
        reltol already pays for their phase error). False (the bench's fixed settings): the options
        and caps as given.
    behavioural_options, behavioural_max_steps :
        ``.options`` for circuits with behavioural parts (the nonlinear circuits), and their step cap
        t_stop/behavioural_max_steps where the motion gives no step (closed chains, a motion the ODE
        could not integrate). An open chain's step comes from its motion's error coefficients
        (:mod:`analogy.solvers.motion_step`); its options make ngspice's error fall as h² there:
        pivrel = 0.9, reltol at the bound, the truncation check off (trtol).
    refine : int
        How many times every step of ngspice is halved against these settings (the second
        run of an error estimate, :func:`~analogy.solvers.transient.refined`): the step cap
        REFINE^refine times shorter and reltol, vntol and chgtol REFINE^(3·refine) times tighter.
    refine_tolerances : bool
        False: a refinement shortens the step cap alone (where tighter tolerances collapse the step).
    """

    options: dict = field(default_factory=dict)
    max_steps: int = 100
    phase_step: float = math.inf
    first_phase_step: float = math.inf
    decay_step: float = math.inf
    calibrated: bool = False
    behavioural_options: dict = field(default_factory=lambda: {"method": "trap"})
    behavioural_max_steps: int = 200
    refine: int = 0
    refine_tolerances: bool = True


@dataclass(frozen=True)
class OdeSettings:
    """What the ODE solver receives of a preset.

    Attributes
    ----------
    method : str
        The ``scipy.integrate.solve_ivp`` method.
    rtol : float
        Its relative tolerance; atol follows from rtol and the response scale.
    """

    method: str = "LSODA"
    rtol: float = 1e-6


@dataclass(frozen=True)
class Budget:
    """The most work a run may take: past it a run is refused before it starts, or stopped and flagged.

    Attributes
    ----------
    timeout : float
        Wall-time limit [s] of the ODE integration (SPICE's work is bounded by *steps*,
        the exact solver's by its time points).
    steps : int
        The most steps the time-scale cap may ask for: over a t_stop that would need
        more, the cap is t_stop/steps and the bound may fail (then it is flagged
        against the exact solution), rather than the run taking without end.
    points : float
        The most time points a run may need (:func:`analogy.study.work.check_work`
        estimates them from the fastest rate and t_stop before any solver starts).
    segments : int
        The most force segments (between pwl points, pulse edges) a run may walk.
    operations : float
        The most operations a SPICE circuit may need: its time points times the
        work of one point, Σᵢ cᵢ² over its nodes' couplings
        (:func:`analogy.circuit.elements.point_operations`).
    """

    timeout: float = 300.0
    steps: int = 10_000_000
    points: float = 1e8
    segments: int = 100_000
    operations: float = OPERATION_BUDGET

    def scaled(self, factor: float) -> "Budget":
        """This budget with *factor* times the steps, points and operations.

        Parameters
        ----------
        factor : float
            The factor (an integer keeps the step count exact).
        """
        return replace(self, steps=int(self.steps * factor), points=self.points * factor,
                       operations=self.operations * factor)


@dataclass(frozen=True)
class Preset:
    """Solver settings that trade run time for error: one bound, and what each solver receives.

    Attributes
    ----------
    name : str
        ``fast``, ``accurate``, or the tolerance it was made for.
    bound : float
        The promised worst error / peak of SPICE and the ODE against the exact solution,
        measured on the built-in scenes (``analogy verify``); a result above it is flagged.
    steps : int
        The uniform output grid has t_stop/steps between points (:meth:`grid`); it is also
        ngspice's print step.
    description : str
        A few words for listings.
    spice : SpiceSettings
        ngspice's options and step caps.
    ode : OdeSettings
        The ODE's method and tolerance.
    budget : Budget
        The most work a run may take.
    """

    name: str
    bound: float = 1e-3
    steps: int = 100
    description: str = ""
    spice: SpiceSettings = SpiceSettings()
    ode: OdeSettings = OdeSettings()
    budget: Budget = Budget()

    def grid(self, t_stop: float) -> np.ndarray:
        """The uniform output times 0 … *t_stop*, *steps* intervals: the points every solver
        is compared on where none is asked for.

        Parameters
        ----------
        t_stop : float
            The horizon [s].
        """
        return np.linspace(0.0, t_stop, self.steps + 1)


PRESETS = {
    "fast": Preset(
        "fast", bound=1e-3, steps=100, description="better than 1e-3 of the peak, lowest run time",
        # Worst 3.4e-4 of the peak over the built-in scenes and 9.3e-4 over every output
        # (element currents included) of examples/scenes; reltol 3e-5 misses the latter
        # (1.8e-3). trtol=1 (default 7) matters more than reltol, and a larger step cap
        # costs time without gaining accuracy.
        spice=SpiceSettings(
            {"method": "trap", "reltol": 1e-5, "abstol": 1e-12, "vntol": 1e-9, "chgtol": 1e-16, "trtol": 1},
            max_steps=50, phase_step=0.5, first_phase_step=0.02, calibrated=True, decay_step=0.5,
            behavioural_options={"method": "trap", "pivrel": 0.9, "trtol": 1e6, "reltol": 1e-3, "abstol": 1e-5,
                                 "vntol": 1e-5}, behavioural_max_steps=500),
        # LSODA at rtol 1e-6 erred 8.9e-4 on an output at 1e-6 of the largest rate (serial100, whose
        # error control weighs every state against its own size, and the rate sums 100 of them); 1e-7 has
        # 1.4e-4 there, for 23 % more steps.
        ode=OdeSettings("LSODA", 1e-7), budget=Budget(steps=1_000_000, points=1e7)),
    "accurate": Preset(
        "accurate", bound=1e-6, steps=1000, description="better than 1e-6 of the peak",
        # Measured against the exact solution on every built-in scene: worst 2.1e-7 of the
        # peak. The step cap t_stop/20000 dominates; gear-2 at the same cap gives 7.6e-7.
        spice=SpiceSettings(
            {"method": "trap", "reltol": 1e-10, "abstol": 1e-15, "vntol": 1e-11, "chgtol": 1e-20, "trtol": 1},
            max_steps=20000, phase_step=0.016, first_phase_step=3e-4, calibrated=True, decay_step=0.5,
            # Circuits with behavioural parts take their step from their motion (solvers/motion_step.py), and
            # ngspice's truncation check is off (trtol): at a tight reltol it collapsed the step at the first
            # steps. pivrel = 0.9: at 0.1 or ngspice's 1e-3 the charges' auxiliary rows (no diagonal) kept
            # stale pivots, the step collapsed mid-run at reltol ≤ 1e-4 and the error stopped falling with h;
            # at 0.5 serial3 swung under gravity still collapsed at t = 0.504 s on the pivots' rounding.
            # reltol at the bound: Newton's remainder stays out of the error (2-DOF, steps (10, 5) from rest:
            # 2.9e-7, 7.4e-8, 1.8e-8, 4.5e-9 as the step halves from 2.5e-4 s, the same at reltol 1e-9; at
            # 1e-3, 4.0e-7 to 9.3e-9). vntol 1e-7 of the velocity scale: at 1e-9 the hanging double
            # pendulum's step collapsed at t = 0.066 s on rounding.
            behavioural_options={"method": "trap", "pivrel": 0.9, "trtol": 1e6, "reltol": 1e-6, "abstol": 1e-7,
                                 "vntol": 1e-7}, behavioural_max_steps=20000),
        ode=OdeSettings("DOP853", 1e-12), budget=Budget(steps=20_000_000)),
}


#: The tolerance each named preset stands for: its bound on every output's error over its own peak.
TOLERANCES = {name: p.bound for name, p in PRESETS.items()}
#: The tolerances a preset can be asked for: past 1e-2 the step cap no longer resolves a period,
#: and under 1e-9 ngspice's reltol would have to go under 1e-15, where double precision ends.
TOLERANCE_RANGE = (1e-9, 1e-2)
#: reltol is kept above this: Newton's convergence test compares rounding with it.
_RELTOL_FLOOR = 1e-14
#: The ODE's rtol is kept above this (scipy's floor is 100·ε; DOP853 here errs about 1e-11 of the peak).
_ODE_RTOL_FLOOR = 1e-13


#: Beyond the calibrated presets each setting goes as tol to the power of its order: the
#: trapezoidal rule's error grows as h², so a step as tol^½ and a step count as tol^-½; ngspice's
#: truncation error per step as h³, so its tolerances as tol^{3/2}; the ODE's error as its rtol.
_ORDERS = {"phase_step": 0.5, "first_phase_step": 0.5, "rtol": 1.0, "steps": -0.5, "max_steps": -0.5,
           "behavioural_max_steps": -0.5, "points": -0.5, "operations": -0.5,
           "reltol": 1.5, "abstol": 1.5, "vntol": 1.5, "chgtol": 1.5}


def _setting(name: str, low, high, tol: float):
    """Setting *name* at *tol*, from its fast (*low*) and accurate (*high*) values."""
    fast, accurate = TOLERANCES["fast"], TOLERANCES["accurate"]
    share = math.log(tol / fast) / math.log(accurate / fast)
    if isinstance(low, str) or low == high:
        return low if share < 0.5 else high
    if share < 0:
        value = low * (tol / fast) ** _ORDERS[name]
    elif share > 1:
        value = high * (tol / accurate) ** _ORDERS[name]
    else:
        value = low * (high / low) ** share
    return round(value) if isinstance(low, int) and isinstance(high, int) else float(value)


def _options(a: dict, b: dict, tol: float) -> dict:
    """The ``.options`` at *tol* from fast's (*a*) and accurate's (*b*), as ngspice's text."""
    out = {k: _setting(k, float(a[k]) if k != "method" and _number(a[k]) else a[k],
                       float(b[k]) if k != "method" and _number(b[k]) else b[k], tol) for k in a if k in b}
    if "reltol" in out:
        out["reltol"] = max(out["reltol"], _RELTOL_FLOOR)
    return {k: (f"{v:.3g}" if isinstance(v, float) else v) for k, v in out.items()}


def _group(low, high, tol: float):
    """The settings group (SpiceSettings, OdeSettings, Budget) at *tol*, each field from *low* and *high*."""
    values = {}
    for f in fields(low):
        a, b = getattr(low, f.name), getattr(high, f.name)
        values[f.name] = _options(a, b, tol) if isinstance(a, dict) else _setting(f.name, a, b, tol)
    return type(low)(**values)


def tolerance_preset(tol: float) -> Preset:
    """The settings asked for by the tolerance *tol* on each output's error over its own peak.

    ``fast`` and ``accurate`` are the tolerances 1e-3 and 1e-6, calibrated on the built-in
    scenes (their settings above). Between them each setting follows the power law through
    the two (the step cap as tol^0.50: the trapezoidal rule's error grows as (ω·h)²). Beyond
    them each goes from the nearer preset as tol to its order (:data:`_ORDERS`). The ODE
    method switches at the geometric middle (LSODA above 3.2e-5, DOP853 under). reltol stays
    above 1e-14 and the ODE's rtol above 1e-13.

    Parameters
    ----------
    tol : float
        The bound, within :data:`TOLERANCE_RANGE`.
    """
    low, high = TOLERANCE_RANGE
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and low <= tol <= high):
        raise InputError(f"the tolerance must be a number from {low:g} to {high:g}, got {tol!r}")
    for name, bound in TOLERANCES.items():
        if tol == bound:
            return PRESETS[name]
    fast, accurate = PRESETS["fast"], PRESETS["accurate"]
    ode = _group(fast.ode, accurate.ode, tol)
    return Preset(f"{tol:g}", bound=float(tol), steps=int(_setting("steps", fast.steps, accurate.steps, tol)),
                  description=f"better than {tol:g} of the peak (settings from the power laws of fast and accurate)",
                  spice=_group(fast.spice, accurate.spice, tol), ode=replace(ode, rtol=max(ode.rtol, _ODE_RTOL_FLOOR)),
                  budget=_group(fast.budget, accurate.budget, tol))


def _number(text) -> bool:
    try:
        float(text)
        return True
    except (TypeError, ValueError):
        return False


def preset(name: str | float | Preset) -> Preset:
    """Look up a preset by name, or make the one of a tolerance.

    Parameters
    ----------
    name : str, float or Preset
        ``"fast"`` or ``"accurate"``, or a tolerance such as ``1e-5`` or ``"1e-5"``
        (:func:`tolerance_preset`; ``1e-3`` is ``fast`` and ``1e-6`` ``accurate``). A Preset is
        returned as it is.
    """
    if isinstance(name, Preset):
        return name
    if isinstance(name, str) and name in PRESETS:
        return PRESETS[name]
    if isinstance(name, (int, float)) and not isinstance(name, bool):
        return tolerance_preset(float(name))
    if isinstance(name, str) and _number(name.strip()):
        return tolerance_preset(float(name.strip()))
    raise InputError(f"unknown accuracy preset {name!r}: use {', '.join(PRESETS)} or a tolerance such as 1e-5")
