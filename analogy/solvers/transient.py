"""The spice solver's transient settings (tolerances, step cap, print and first steps) and the netlist it runs."""

from __future__ import annotations

import math
from dataclasses import replace
from functools import lru_cache
from typing import Iterable, Sequence

import numpy as np

from ..circuit.description import Circuit, circuits
from ..circuit.description import circuit as describe
from ..circuit.elements import ZERO_TOL, first_point_operations, point_operations
from ..circuit.netlist import Dialect, write_batch, write_netlist
from ..circuit.node_stack import NodeStack
from ..circuit.scales import Scales, run_scales, system_scales
from ..circuit.stack_netlist import write_stack
from ..circuit.subcircuit import joint_ports, subcircuit_name, write_subcircuit
from ..errors import InputError, SimulationError
from .error_constants import (CALIBRATED_MAX_STEPS, CALIBRATED_TOPOLOGIES, FLOOR_LIMIT, SAFETY, SERIAL_NODE_LIMIT,
                              calibrated_options, calibrated_reltol)
from .motion_step import MotionSchedule, motion_schedule
from .truncation import MODEL_SHARE, Tolerances, TruncationModel, truncation_model
from .run_settings import (NGSPICE_FIRST_STEP, NGSPICE_RELTOL, RETRY_LOOSEN, RETRY_TIGHTEN, TransientSettings,
                           checked_options)
from ..presets import Preset
from ..presets import preset as get_preset

__all__ = ["TransientSettings", "transient_settings", "netlist", "batch_netlist", "ROUNDING_STEPS",
           "NGSPICE_FIRST_STEP", "RETRY_LOOSEN", "RETRY_TIGHTEN", "REFINE", "refined", "STEP_TOLERANCES",
           "beyond_calibration", "spice_run_reltol", "NGSPICE_STEP_TOLERANCES",
           "circuit_settings", "subcircuit_netlist"]

#: abstol is kept above this many n·ε·q/h: the rounding of a capacitor current Δq/h at the
#: shortest step h ngspice is made to take, summed over the n nodes of a row. Under it,
#: rounding reads as truncation error and the step collapses ("timestep too small").
#: Measured in ngspice 39 at accurate, in ε·q/h: collapse below 2.1 on serial6, below about
#: 25 on serial12, between 1.5 and 10 on two coupled oscillators, and below 0.6 on flex2 at
#: its first step; 4·n leaves a factor of 1.9 to 11 over them. cond(M') does not predict them
#: (98, 441, 1.5 and 79,000).
ROUNDING_STEPS = 4.0

#: The second run of an error estimate shortens the step cap and the first step this many times.
REFINE = 2.0
#: The options of ngspice's step control tightened by a refinement: its truncation error per step
#: grows as h³ (trapezoidal rule and gear-2), so these REFINE³ times tighter halve the steps it
#: chooses. abstol is tightened too, but in process only down to the rounding floor of the first
#: step (:data:`ROUNDING_STEPS`), under which the step collapses; a netlist does not say where
#: that floor is, so :mod:`analogy.study.netlist_check` keeps abstol.
STEP_TOLERANCES = ("reltol", "vntol", "chgtol")
#: ngspice's own values of those options (its manual), tightened where a netlist leaves them out.
NGSPICE_STEP_TOLERANCES = {"reltol": 1e-3, "vntol": 1e-6, "chgtol": 1e-14}

_SCALE_NAMES = {"abstol": "current scale [A]", "vntol": "velocity scale [V]", "chgtol": "charge C·v [C]"}


def _shortest_gap(breakpoints: np.ndarray, t_stop: float) -> float:
    """The shortest interval between force breakpoints (ngspice cuts its step to a tenth of it)."""
    return _gap(tuple(np.asarray(breakpoints, float).tolist()), float(t_stop))


@lru_cache(maxsize=256)
def _gap(breakpoints: tuple, t_stop: float) -> float:
    """:func:`_shortest_gap`, kept: a batch's circuits share their breakpoints."""
    t = np.unique(np.concatenate([[0.0], breakpoints, [t_stop]]))
    gaps = np.diff(t)
    gaps = gaps[gaps > 1e-12 * t_stop]
    return float(np.min(gaps)) if gaps.size else t_stop


def _phase_cap(p: Preset, t_stop: float, scales: Scales, operations: float | None = None) -> float:
    """The step that holds the trapezoidal rule's phase error over each mode's amplitude, summed over the
    modes that turn within *t_stop* (:meth:`~analogy.circuit.scales.Scales.phase_error`), to
    bound/:data:`~analogy.solvers.error_constants.SAFETY`; inf where its steps pass the preset's step
    budget or, at *operations* a step (default n³, a dense circuit's), its operation budget: steps that
    cannot buy the bound are not spent, and the run is judged and flagged.

    ngspice's check holds each step's error to reltol, so the error grows with the steps: the UR5
    hanging (0.88 to 9.5 rad/s over 10 s) erred 7.7e-6 in 101,723 steps, each mode its Σ(ω·h)³/12, to 1 %.
    """
    return _bought(p, t_stop, scales.phase_limit(p.bound / SAFETY, p.bound), scales, operations)


def _bought(p: Preset, t_stop: float, step: float, scales: Scales | None, operations: float | None) -> float:
    """*step*, or inf where it is not representable or passes the step or (at *operations* a step, default n³)
    operation budget: steps that cannot buy the bound are not spent, and the run is judged and flagged."""
    if not step > 0:
        return math.inf
    points = t_stop / step
    each = operations if operations is not None else float(scales.size) ** 3 if scales is not None else 0.0
    return step if points <= p.budget.steps and points * each <= p.budget.operations else math.inf


def _step_limits(p: Preset, t_stop: float, scales: Scales, first: float, tmax: float, calibrated: bool,
                 trapezoidal: bool, operations: float | None) -> tuple[float, float]:
    """The first step and the step cap the circuit's *scales* ask, within *first* and *tmax*: the first
    step holds the fastest rate's phase, the cap each lasting rate's phase and decay and, on a linear
    *trapezoidal* circuit under the preset's own caps, its modes' phase error over t_stop."""
    need = scales.step_limit(p.spice.first_phase_step, p.bound / 10)
    if not need > 0:                   # zero or NaN: a rate past the float range
        raise InputError(f"the circuit's fastest rate ({scales.omega_max:.3g} rad/s) leaves the range "
                         "ngspice can step: rescale the masses, dampers or springs")
    first = min(first, need)
    # Where the preset's own caps run, a decay that falls under the bound before t_stop sets no cap: the
    # first step above and ngspice's truncation check cover it while it lasts. A calibrated run (and
    # the calibration, phase_step = inf) keeps the decay cap its constants were measured at: without
    # it, at t_stop/50 steps, the slow root of an overdamped pair (stress b, ratio 1e2, ζ = 1e3) erred
    # 2.5e-6 at reltol 1e-10 against the 3e-7 promised, as ngspice's check judges it against a node it
    # shares with a mode a hundred times larger.
    horizon = t_stop if not calibrated and math.isfinite(p.spice.phase_step) else math.inf
    rate = scales.lasting(p.bound, horizon)
    phase = math.inf if calibrated else p.spice.phase_step
    cap = min(phase / rate if rate > 0 else math.inf, scales.decay_limit(p.spice.decay_step, p.bound, horizon))
    if not calibrated and math.isfinite(p.spice.phase_step) and trapezoidal:
        # the preset's own caps (not the calibration's or the bench's fixed settings) on a linear
        # trapezoidal circuit: the phase error of its own modes over t_stop sets the step
        cap = min(cap, _phase_cap(p, t_stop, scales, operations))
    tmax = min(tmax, max(cap, t_stop / p.budget.steps))
    return first, tmax


def transient_settings(preset: Preset, t_stop: float, scales: Scales | None, *,
                       behavioural: bool = False, coupled: bool = False, constrained: bool = False,
                       breakpoints: np.ndarray | None = None, loosen: float = 1.0,
                       custom: bool = False, operations: float | None = None,
                       motion: MotionSchedule | None = None,
                       truncation: TruncationModel | None = None) -> TransientSettings:
    """The transient settings of a circuit with *scales* over *t_stop* at *preset*.

    The absolute tolerances are the preset's relative ones times the circuit's current,
    velocity and charge scales; abstol stays above :data:`ROUNDING_STEPS` roundings of a
    capacitor current at the shortest step the run takes (its first step, or a tenth of the
    shortest interval between force breakpoints). The step cap is ``preset.spice.phase_step``
    of the fastest rate (within ``preset.budget.steps``); the first step meets
    ``preset.spice.first_phase_step``; the print step is t_stop/``preset.steps``.

    Parameters
    ----------
    preset : Preset
        The accuracy preset.
    t_stop : float
        End of the transient [s].
    scales : Scales or None
        The circuit's scales (None: t_stop alone sets the steps, the options stay as the preset's).
    behavioural : bool
        The circuit has behavioural parts: the preset's behavioural options and step cap.
    coupled : bool
        The circuit has 1:−1 couplings (ideal sources across capacitors): gear, as the trapezoidal rule rings there.
    constrained : bool
        The circuit has loop-closure nodes (a closed chain): reltol at most 10× the preset's bound. Newton
        stops once each node moves less than reltol of its value, and a multiplier's node has no capacitor
        to smooth what is left: at ngspice's 1e-3 the 3-RRR's constraint forces missed 1e-6 by 16 times, at
        1e-5 the run converges as h² (``tests/test_closed_chains.py``).
    breakpoints : ndarray, optional
        The forces' breakpoints.
    loosen : float
        Factor on abstol and vntol (a retry).
    custom : bool
        The circuit is beyond the calibration (:func:`beyond_calibration`): the preset's own settings, as for
        every circuit the error constants do not speak for (:data:`~analogy.presets.SpiceSettings.calibrated`;
        also one whose abstol's rounding floor passes :data:`~analogy.solvers.error_constants.FLOOR_LIMIT`
        times its current scale, or whose model's steps pass the budget).
    operations : float, optional
        The circuit's operations a time point (:func:`analogy.circuit.elements.point_operations`; default n³):
        the phase cap is not taken past the preset's operation budget.
    motion : MotionSchedule, optional
        The steps a behavioural circuit's motion asks (:func:`~analogy.solvers.motion_step.motion_schedule`):
        its cap, and the clock's corners where it must step shorter.
    truncation : TruncationModel, optional
        A linear trapezoidal circuit's truncation model at a calibrated preset (:func:`circuit_settings` makes one
        where it runs): its reltol, charge floor and cap (:func:`_modelled`).
    """
    opts = dict(preset.spice.behavioural_options if behavioural else preset.spice.options)
    reltol = spice_run_reltol(preset, scales, behavioural=behavioural or coupled or constrained or custom)
    modelled = truncation is not None and scales is not None     # circuit_settings gives one only where it runs
    calibrated = reltol is not None or modelled
    if reltol is not None:
        opts.update(calibrated_options(reltol))
    if not behavioural:     # a flag: KLU where ngspice has it (46; 39 ignores it). ngspice 46 aborts a
        opts["klu"] = ""    # behavioural circuit under KLU ("out of memory": an .ic on a node with no diagonal entry)
    if coupled:
        opts["method"] = "gear"
    if constrained:
        opts["reltol"] = f"{min(float(opts.get('reltol', NGSPICE_RELTOL)), 10 * preset.bound):.3g}"
    tmax = t_stop / (preset.spice.behavioural_max_steps if behavioural else
                     CALIBRATED_MAX_STEPS if calibrated else preset.spice.max_steps)
    clock: tuple = ()
    unclocked = tmax
    if behavioural and motion is not None and math.isfinite(_bought(preset, t_stop, t_stop / motion.points, scales,
                                                                    operations)):
        # at most half the print step: where a step spans about one, ngspice's interpolated printing
        # is not the run (the UR5 at fast: 8.0e-3 printed against 1.1e-4 at its points; equal at half)
        tmax = min(motion.step, 0.5 * t_stop / preset.steps)
        clock = tuple(float(c) for c in motion.finer(REFINE ** preset.spice.refine).corners)
    tstep = t_stop / preset.steps
    first = NGSPICE_FIRST_STEP * tstep
    if scales is not None:
        first, tmax = _step_limits(preset, t_stop, scales, first, tmax, calibrated, not (behavioural or coupled),
                                   operations)
        unclocked = _step_limits(preset, t_stop, scales, first, unclocked, calibrated, not (behavioural or coupled),
                                 operations)[1] if clock else unclocked       # the cap a clock does not set
        shortest = min(first, 0.1 * _shortest_gap(np.zeros(0) if breakpoints is None else breakpoints, t_stop))
        if clock:       # after a near corner ngspice steps a tenth of a last step about a quarter of its gap
            shortest = min(shortest, 0.025 * float(np.min(np.diff(np.concatenate([[0.0], clock])))))
        rounding = ROUNDING_STEPS * scales.rounding_current(shortest)
        floored = calibrated and rounding > FLOOR_LIMIT * scales.current
        if floored or modelled and (chosen := _modelled(truncation, preset, scales, rounding, tmax, operations)) is None:
            # a rounding floor past the calibration's may judge each step, not reltol: the Panda's (3.2e-7)
            # left its small r3 at 1.7e-6 at the accurate reltol, in 731 steps whatever the reltol; and a
            # model's steps past the budget are not bought (the preset's own settings run, judged)
            return transient_settings(preset, t_stop, scales, behavioural=behavioural, coupled=coupled,
                                      constrained=constrained, breakpoints=breakpoints, loosen=loosen, custom=True,
                                      operations=operations, motion=motion)
        tmax = _written_tolerances(opts, preset, scales, rounding, loosen, chosen if modelled else None) or tmax
    else:
        _refine_tolerances(opts, preset)
    tmax, unclocked = (step / REFINE ** preset.spice.refine for step in (tmax, unclocked))   # an estimate's second run
    impedance = None if scales is None else _impedance(scales)
    return TransientSettings(tuple((k, str(v)) for k, v in checked_options(opts).items()), tstep, t_stop, tmax,
                             first, loosen, clock=clock, unclocked=unclocked if clock else None,
                             impedance=impedance, interpolate=not calibrated)


def _impedance(scales: Scales) -> float | None:
    """The circuit's velocity over current scale [Ω], or None where it has none."""
    ratio = scales.peak_velocity / scales.current if scales.current > 0 else math.inf
    return ratio if math.isfinite(ratio) else None


def _written_tolerances(opts: dict, preset: Preset, scales: Scales, rounding: float, loosen: float,
                        chosen: Tolerances | None) -> float | None:
    """*opts*' tolerances as written: a truncation model's reltol and charge floor where *chosen*, refined
    (:func:`_refine_tolerances`), times the circuit's scales (:func:`_scale_tolerances`); the model's cap."""
    if chosen:
        opts.update(calibrated_options(chosen.reltol))
    _refine_tolerances(opts, preset)
    if chosen:          # a charge floor, not a tolerance: a refinement's steps halve with reltol alone
        opts["chgtol"] = f"{chosen.chgtol / scales.charge:.6g}"
    _scale_tolerances(opts, scales, rounding, loosen)
    return chosen.max_step if chosen else None


def _refine_tolerances(opts: dict, preset: Preset) -> None:
    """The step tolerances in *opts* REFINE³ times tighter per refinement of *preset* (abstol too: the
    rounding floor keeps it where it binds)."""
    if preset.spice.refine and preset.spice.refine_tolerances:
        opts.update({k: f"{float(opts[k]) / REFINE ** (3 * preset.spice.refine):.3g}"
                     for k in (*STEP_TOLERANCES, "abstol") if k in opts})


def _modelled(truncation: TruncationModel, preset: Preset, scales: Scales, rounding: float, tmax: float,
              operations: float | None) -> Tolerances | None:
    """The settings whose foretold error is :data:`~analogy.solvers.truncation.MODEL_SHARE` of the bound
    (:meth:`~analogy.solvers.truncation.TruncationModel.tolerances`); None where the points foretold pass
    the preset's step or operation budget, or where no settings hold it."""
    chosen = truncation.tolerances(MODEL_SHARE * preset.bound, lambda r: _modelled_abstol(r, scales, rounding),
                                   scales.charge, tmax)
    t_stop = truncation.time[-1]
    if chosen is None or not math.isfinite(_bought(preset, t_stop, t_stop / chosen.points, scales, operations)):
        return None
    return chosen


def _modelled_abstol(reltol: float, scales: Scales, rounding: float) -> float:
    """abstol as a run at *reltol* writes it (:func:`calibrated_options` on *scales*, the rounding floor)."""
    opts = {"abstol": calibrated_options(reltol)["abstol"]}
    _scale_tolerances(opts, scales, rounding, 1.0)
    return float(opts["abstol"])


def _scale_tolerances(opts: dict, scales: Scales, rounding: float, loosen: float) -> None:
    """abstol, vntol, chgtol in *opts* times the current, velocity, charge scales (abstol ≥ *rounding*; ×loosen)."""
    for key, size in (("abstol", scales.current), ("vntol", scales.peak_velocity), ("chgtol", scales.charge)):
        if key not in opts:
            continue
        value = max(float(opts[key]) * size, rounding if key == "abstol" else 0.0)
        value *= loosen if key in ("abstol", "vntol") else 1.0     # Python floats overflow to inf
        if not math.isfinite(value):
            raise SimulationError(f"SPICE cannot run this circuit: its {key} scale is past the floating-point "
                                  f"range ({_SCALE_NAMES[key]} = {size:.3g}); the ODE and exact solvers can")
        opts[key] = f"{value:.3g}"


def refined(preset: Preset, tolerances: bool = True) -> Preset:
    """*preset* with every step of ngspice :data:`REFINE` times shorter: the step cap, and the
    steps its truncation check chooses (:data:`STEP_TOLERANCES` REFINE³ times tighter), applied by
    :func:`transient_settings` on top of what the preset gives the circuit (:attr:`SpiceSettings.refine`).
    The trapezoidal rule's error falls REFINE² times, so the difference of the two runs is
    (1 − 1/REFINE²) of the first run's error: Richardson's estimate of it.

    abstol is REFINE³ times tighter down to the rounding floor of the first step, and the first
    step is kept: a shorter first step would raise that floor, and a floor looser than the
    first run's abstol let the refined run step longer (a stiff oscillator took 60,910 points
    against 82,776 when both were halved). The first step's error is kept under 5 % of the
    bound (:attr:`SpiceSettings.first_phase_step`), so the estimate leaves that much out. The
    behavioural circuits keep ngspice's default tolerances (see :class:`~analogy.presets.Preset`),
    so only their cap is shortened.

    Parameters
    ----------
    preset : Preset
        The preset of the run to be judged.
    tolerances : bool
        Tighten the step tolerances too (False: the step cap alone).
    """
    more = int(REFINE)
    return replace(preset, spice=replace(preset.spice, refine=preset.spice.refine + 1, refine_tolerances=tolerances),
                   budget=preset.budget.scaled(more))


def spice_run_reltol(preset: Preset, scales: Scales | None, *, behavioural: bool = False) -> float | None:
    """The reltol the error constants give a circuit with *scales* at *preset*, or None where the preset's
    own settings run: a preset that is not calibrated, no scales, a circuit that rings or is *behavioural*
    (nonlinear, coupled, constrained or beyond the calibration: the constants measured plain linear circuits
    under the trapezoidal rule).

    Parameters
    ----------
    preset : Preset
        The accuracy preset.
    scales : Scales or None
        The circuit's scales.
    behavioural : bool
        The circuit is of a kind the constants do not speak for.
    """
    if not preset.spice.calibrated or scales is None or behavioural:
        return None
    return calibrated_reltol(preset.bound, scales.ringing(preset.bound))


def beyond_calibration(system) -> bool:
    """Whether *system*'s circuit is of a kind the error constants were not measured on: a custom node
    map T, or a serial chain of more than :data:`~analogy.solvers.error_constants.SERIAL_NODE_LIMIT` nodes.

    Parameters
    ----------
    system : NodeDynamics
        The system.
    """
    name = getattr(getattr(system, "topology", None), "name", "serial")
    return name not in CALIBRATED_TOPOLOGIES or (name == "serial" and system.dof > SERIAL_NODE_LIMIT)


def circuit_settings(system, c: Circuit, preset: Preset, loosen: float = 1.0, engine: Dialect = "ngspice",
                     whole: bool = True) -> TransientSettings:
    """The transient settings of *system*'s circuit *c* at *preset*: what a run and its netlist share.

    Parameters
    ----------
    system : NodeDynamics
        The system.
    c : Circuit
        Its circuit.
    preset : Preset
        The accuracy preset.
    loosen : float
        Factor on abstol and vntol (the retries after a collapsed step).
    engine : {"ngspice", "gnucap", "ltspice"}
        The engine that runs it: the truncation model follows ngspice's check, not the others'.
    whole : bool
        *c* is the whole circuit that runs (False: a part of one, as a drive's robot beside its windings,
        which its truncation model does not see).
    """
    motion = truncation = None
    custom = beyond_calibration(system)
    if c.behavioural and not c.constraints and getattr(system, "kind", None) == "nonlinear":
        motion = motion_schedule(system, preset.bound, SAFETY, timeout=preset.budget.timeout)
    elif whole and engine == "ngspice" and preset.spice.calibrated and not (c.behavioural or c.couplings
                                                                             or c.constraints or custom):
        truncation = truncation_model(system)
    return transient_settings(preset, system.t_stop, system_scales(system), behavioural=bool(c.behavioural),
                              coupled=bool(c.couplings), constrained=bool(c.constraints),
                              breakpoints=system.breakpoints(), loosen=loosen, custom=custom,
                              operations=point_operations(system), motion=motion, truncation=truncation)


def netlist(system, preset: str | Preset = "accurate", save: Iterable[str] | None = None,
            zero_tol: float = ZERO_TOL, title: str | None = None, realizable: bool | None = None,
            printing: bool = True, loosen: float = 1.0, dialect: Dialect = "ngspice",
            settings: TransientSettings | None = None) -> str:
    """The netlist the spice solver runs for *system*; ``ngspice -b`` runs and prints it unchanged.

    Parameters
    ----------
    system : NodeSystem, NonlinearNodeSystem or Circuit
        The system (a bare circuit description gets the preset's settings over its t_stop).
    preset : str or Preset
        Accuracy preset.
    save : iterable of str, optional
        Node names (``n1`` …) and element names (``C1_2``, ``R1`` …) to save; default all nodes.
    zero_tol : float
        Relative tolerance under which an element is left out.
    title : str, optional
        First line of the netlist.
    realizable : bool, optional
        Build negative elements from positive ones behind inverting couplings (default:
        as the system says, :meth:`~analogy.circuit.node_system.NodeSystem.realized`).
    printing : bool
        Print the saved vectors at ngspice's own points (``.print tran`` and 15 digits),
        which ``ngspice -b`` shows; the steps taken are the same without it.
    loosen : float
        Factor on abstol and vntol (see :class:`TransientSettings`).
    dialect : {"ngspice", "gnucap", "ltspice"}
        The engine that reads it: ngspice's language, gnucap's for a linear circuit
        (:func:`~analogy.circuit.netlist.gnucap_lines`), or LTspice's
        (:func:`~analogy.circuit.ltspice.ltspice_netlist`).
    settings : TransientSettings, optional
        The settings a run took (:attr:`Trajectory.settings`: a retry's, a refined run's),
        instead of those *preset* gives.
    """
    preset = get_preset(preset)
    if isinstance(system, Circuit):
        settings = transient_settings(preset, system.t_stop, None, behavioural=bool(system.behavioural),
                                      coupled=bool(system.couplings), constrained=bool(system.constraints),
                                      loosen=loosen)
        return write_netlist(system, settings, save, title, printing, dialect)
    c = describe(system, zero_tol, getattr(system, "realizable", False) if realizable is None else realizable)
    try:
        settings = settings or circuit_settings(system, c, preset, loosen, dialect)
    except SimulationError as exc:      # no netlist can be written for it: the input's scale
        raise InputError(str(exc)) from None
    return write_netlist(c, settings, save, title, printing, dialect)


def subcircuit_netlist(system, preset: str | Preset = "accurate", name: str | None = None, title: str | None = None,
                       realizable: bool | None = None) -> str:
    """*system* as a subcircuit a user's netlist ``.include``s: one port per joint, the applied forces
    left outside (:func:`~analogy.circuit.subcircuit.write_subcircuit`).

    Parameters
    ----------
    system : NodeSystem or NonlinearNodeSystem
        The system; its own forces set the settings written beside it, and are not in it.
    preset : str or Preset
        Accuracy preset of those settings.
    name : str, optional
        The subcircuit's name (default: the robot's).
    title : str, optional
        First comment line.
    realizable : bool, optional
        Negative elements behind inverting couplings (default: as the system says).
    """
    preset, real = get_preset(preset), getattr(system, "realizable", False) if realizable is None else realizable
    unforced = system.driven([0.0] * system.dof, None)
    c = describe(unforced, ZERO_TOL, real)
    try:
        settings = circuit_settings(system, describe(system, ZERO_TOL, real), preset)
    except SimulationError as exc:
        raise InputError(str(exc)) from None
    return write_subcircuit(c, joint_ports(system), subcircuit_name(name or c.robot), settings, title)


def batch_netlist(systems: Sequence, preset: str | Preset = "fast", scales: Scales | None = None) -> str:
    """One netlist holding every system as an independent sub-circuit (prefix ``x<k>_``).

    One ``.tran`` runs to the longest horizon; each shorter one is a breakpoint
    (:attr:`TransientSettings.horizons`), and the step cap and print step are those of the
    shortest, so that no system is stepped more coarsely than in a run of its own.

    Parameters
    ----------
    systems : sequence of NodeSystem
        The systems.
    preset : str or Preset
        Accuracy preset.
    scales : Scales, optional
        Their combined scales, if already known (else computed here).
    """
    if not systems:
        raise InputError("a batch needs at least one system")
    preset = get_preset(preset)
    shared = isinstance(systems, NodeStack) and systems.shares_inputs       # one row answers for all
    first = systems.inputs_row if shared else systems[0]
    alike = [first] if shared else systems
    ends = sorted({s.t_stop for s in alike})
    scales = scales or run_scales(systems)
    points = [s.breakpoints() for s in alike if s.forces is not first.forces] + [first.breakpoints()]
    settings = transient_settings(preset, ends[0], scales, breakpoints=np.concatenate(points),
                                  custom=any(beyond_calibration(s) for s in alike),
                                  operations=first_point_operations(systems) * len(systems))
    if len(ends) > 1:
        settings = replace(settings, stop=ends[-1], horizons=tuple(ends[:-1]))
    if isinstance(systems, NodeStack) and len(systems.partition()) == 1:
        return write_stack(systems, settings)
    return write_batch(circuits(systems), settings)
