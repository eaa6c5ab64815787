"""The step a nonlinear motion asks of the trapezoidal rule: its error h²/12·∫|r'''|dt, from the ODE's motion."""

from __future__ import annotations

import math

import numpy as np

from ..circuit.scales import system_scales
from ..errors import SimulationError
from ..presets import Preset
from ..results.metrics import PEAK_FLOOR
from .error_constants import SAFETY
from .ode import solve_ode

__all__ = ["motion_error", "motion_step", "circuit_motion_step", "SAMPLES_PER_PERIOD", "MIN_SAMPLES"]

#: Samples of the motion per period of the fastest rate of its linearisation at q0, for r''':
#: its second difference of the acceleration errs (2π/64)²/12 ≈ 1e-3 of itself there.
SAMPLES_PER_PERIOD = 64
#: Samples at least, over the run.
MIN_SAMPLES = 4001


def motion_error(system, preset: Preset) -> tuple[np.ndarray, np.ndarray]:
    """Per joint rate j, (C_j, peak_j): the trapezoidal rule at a uniform step h errs about h²·C_j on r_j.

    Each step's truncation error is h³/12·r''' (the rule's, and ngspice's, order 2), and they add
    up over the run: C_j = (1/12)·∫|r_j'''|dt, an upper bound where errors cancel or decay. r''' is
    the second derivative in time of the accelerations the system's own flow gives along the
    ODE's motion (at the preset's ODE settings), taken within each stretch between force corners.
    Measured on the Panda and the UR5 swung by sine torques over 2 s, the bound was 1.2 to 6
    times the ngspice run's error per joint.

    Parameters
    ----------
    system : NonlinearNodeSystem
        The motion.
    preset : Preset
        The ODE's settings.
    """
    t_stop = system.t_stop
    rate = system_scales(system).omega_max
    samples = int(min(max(MIN_SAMPLES, SAMPLES_PER_PERIOD * rate * t_stop / (2 * math.pi) + 1), 200_001))
    times = np.union1d(np.linspace(0.0, t_stop, samples), system.breakpoints())
    run = solve_ode(system, times, method=preset.ode_method, rtol=preset.ode_rtol, positions=True,
                    timeout=preset.timeout)
    if not run.success:
        raise SimulationError(f"the motion's ODE run failed: {run.message}")
    drive = system.node_currents(run.time)
    accel = np.array([system.flow(x, v, i)[0] for x, v, i in zip(run.positions, run.voltages, drive)])
    accel = accel @ system.topology.inverse.T          # joint accelerations r̈ = T⁻¹·v̇
    total = np.zeros(system.dof)
    for a, b in system.segments():
        inside = np.flatnonzero((run.time > a) & (run.time < b))    # a corner's sides differ
        if inside.size < 5:
            continue
        t, r2 = run.time[inside], accel[inside]
        third = np.gradient(np.gradient(r2, t, axis=0), t, axis=0)      # r''' from r̈: d/dt twice
        total += np.sum(0.5 * (np.abs(third[1:]) + np.abs(third[:-1])) * np.diff(t)[:, None], axis=0)
    peak = np.max(np.abs(run.rates), axis=0)
    return total / 12.0, np.maximum(peak, PEAK_FLOOR * peak.max(initial=0.0))


def motion_step(system, preset: Preset, operations: float) -> float | None:
    """The longest uniform step that keeps every joint rate's estimated error (:func:`motion_error`)
    within bound/:data:`~analogy.solvers.error_constants.SAFETY` of its own peak, or None where
    its steps would pass the preset's step or operation budget (the fixed cap runs then, and the
    run is judged and flagged).

    Parameters
    ----------
    system : NonlinearNodeSystem
        The motion.
    preset : Preset
        Its bound, budgets and ODE settings.
    operations : float
        The circuit's operations a step: its node count squared, behavioural nodes included (the
        UR5's 281 nodes give 79,000, 0.46 ms at 1.7e8 a second; it steps in about 0.5 ms).
    """
    coefficient, peak = motion_error(system, preset)
    moving = coefficient > 0
    step = float(np.min(np.sqrt(preset.bound / SAFETY * peak[moving] / coefficient[moving]))) if moving.any() \
        else math.inf
    # at least five steps an output step: a run's points resolve what it prints (ngspice's own
    # table of a written netlist then matches the in-process run to rounding)
    step = min(step, system.t_stop / (5 * preset.steps))
    steps = system.t_stop / step
    return step if steps <= preset.step_budget and steps * operations <= preset.operation_budget else None


def circuit_motion_step(system, circuit, preset: Preset) -> float | None:
    """:func:`motion_step` of a nonlinear *system* whose *circuit* is behavioural (not a closed
    chain's), made once per system and preset; None for any other circuit.

    Parameters
    ----------
    system : NodeDynamics
        The system.
    circuit : Circuit
        Its circuit description.
    preset : Preset
        The accuracy preset.
    """
    if not circuit.behavioural or circuit.constraints or not hasattr(system, "flow"):
        return None
    key = (preset.bound, preset.steps, preset.step_budget, preset.operation_budget, preset.ode_method,
           preset.ode_rtol)
    kept = system.__dict__.get("_motion_step")          # its ODE run is made once per system
    if kept is None or kept[0] != key:
        nodes = circuit.nodes + len(circuit.behavioural)     # a behavioural part holds a node of its own or two
        kept = system.__dict__["_motion_step"] = (key, motion_step(system, preset, float(nodes) ** 2))
    return kept[1]
