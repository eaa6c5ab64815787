"""Work estimates before a run: time points and force segments, refused past the preset's budget."""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from ..circuit.elements import NONLINEAR_POINT_COST, first_point_operations, point_operations
from ..circuit.node_stack import NodeStack
from ..circuit.scales import run_scales, system_scales
from ..errors import InputError
from ..presets import Preset
from ..solvers.error_constants import CALIBRATED_MAX_STEPS, step_phase
from ..solvers.transient import beyond_calibration, spice_run_reltol

__all__ = ["WorkEstimate", "check_work", "check_works", "estimate_work"]

#: Time points per force segment: each breakpoint restarts an integrator's step control.
_POINTS_PER_SEGMENT = 4


class WorkEstimate(NamedTuple):
    """What a run of a linear system will cost: time points to step and force segments to walk."""

    points: float
    segments: int
    fastest: float      # the rate [rad/s] that sets the points: a mode, a decay or a sine
    operations: float = 0.0     # of the SPICE circuit: points × point_operations, summed over a stack


def estimate_work(system, preset: Preset, scales=None, stacked: int = 1, operations: float | None = None) -> WorkEstimate:
    """The time points and force segments a solver run of *system* needs at *preset*.

    The points follow the fastest rate the preset resolves (one step per
    ``preset.spice.phase_step`` radians of it, the SPICE step cap and the ODE's step size
    alike) and no fewer than the preset's ``max_steps``, plus a few per force breakpoint. A linear
    system at a calibrated preset takes the steps of its reltol on its fastest oscillation
    (:func:`~analogy.solvers.error_constants.step_phase`) or of the decay cap, whichever are more.
    The SPICE circuit's operations are the points times :func:`point_operations`.

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    preset : Preset
        The accuracy preset.
    scales : Scales, optional
        The system's scales, or the combined scales of a stack it stands for.
    stacked : int
        How many systems like it one SPICE circuit holds.
    operations : float, optional
        One time point's operations of one system's circuit, where known (default :func:`point_operations`).
    """
    segments = len(system.breakpoints())
    scales = system_scales(system) if scales is None else scales
    rate = scales.fastest(preset.bound)      # a nonlinear system's includes the rates its joints turn at
    reltol = _reltol(system, preset, scales)
    if reltol is not None:      # the steps the truncation check takes on the fastest oscillation, the decay cap
        points = max(system.t_stop * scales.omega_max / step_phase(reltol),
                     system.t_stop / scales.decay_limit(preset.spice.decay_step, preset.bound))
    else:
        # as the step policy caps them: a decay over well before t_stop sets no steps after it
        phase = preset.spice.phase_step if math.isfinite(preset.spice.phase_step) else 1.0
        points = system.t_stop * scales.lasting(preset.bound, system.t_stop) / phase
    points = max(points, _fewest(system, preset, reltol is not None)) + _POINTS_PER_SEGMENT * segments
    points = points if math.isfinite(points) else math.inf
    each = point_operations(system) if operations is None else operations
    return WorkEstimate(points, segments, rate, points * stacked * each)


def _reltol(system, preset: Preset, scales) -> float | None:
    """The calibrated reltol the SPICE run takes, or None where the preset's own settings run."""
    other = system.kind != "linear" or getattr(system, "realizable", False) or beyond_calibration(system)
    return spice_run_reltol(preset, scales, behavioural=other)


def _fewest(system, preset: Preset, calibrated: bool | None = None) -> int:
    """The points any t_stop takes: the SPICE step cap's (t_stop/50 where calibrated, else t_stop/max_steps),
    and at least two per print step (the truncation check's own steps: the calibrated built-in scenes took
    1,500 to 23,000 at accurate, ``analogy/solvers/calibration_runs.csv``)."""
    if calibrated is None:
        calibrated = _reltol(system, preset, system_scales(system)) is not None
    return max(CALIBRATED_MAX_STEPS if calibrated else preset.spice.max_steps, 2 * preset.steps)


def check_work(system, preset: Preset, scales=None, *, stacked: int = 1, spice: bool = True,
               operations: float | None = None) -> WorkEstimate:
    """:func:`estimate_work`, refused in one sentence past ``preset.budget.points``, ``preset.budget.segments``
    or, where SPICE runs, ``preset.budget.operations``.

    Parameters
    ----------
    system : NodeSystem or NonlinearNodeSystem
        A node system; a nonlinear one is estimated from its start (x = 0 and r0).
    preset : Preset
        The accuracy preset; ``dataclasses.replace(preset, budget=preset.budget.scaled(…))`` raises the budget.
    scales : Scales, optional
        The system's scales, or the combined scales of a stack sharing its forces and t_stop.
    stacked : int
        How many systems like it one SPICE circuit holds.
    spice : bool
        Whether SPICE is among the solvers, so that the circuit's operations count.
    operations : float, optional
        One time point's operations of one system's circuit, where known (default :func:`point_operations`).
    """
    work = estimate_work(system, preset, scales, stacked, operations)
    if work.segments > preset.budget.segments:
        raise InputError(f"the forces have {work.segments:,} segments between breakpoints (pwl points, pulse "
                         f"edges), more than the budget of {preset.budget.segments:,}: use fewer, or raise "
                         "the preset's segment budget", field="budget")
    # a nonlinear point evaluates M(q), c and G (and SPICE its expressions) where a linear one multiplies
    nonlinear = system.kind != "linear"
    budget = preset.budget.points / (NONLINEAR_POINT_COST if nonlinear else 1.0)
    if work.points > budget:
        each = f" for a nonlinear run (a point of it counts {NONLINEAR_POINT_COST:g})" if nonlinear else ""
        raise InputError(f"the run would need about {work.points:.3g} time points (the fastest rate, "
                         f"{work.fastest:.3g} rad/s, over t_stop = {system.t_stop:g} s), more than the budget "
                         f"of {budget:.3g}{each}: shorten t_stop, or raise the preset's work budget",
                         field="budget")
    if spice and work.operations > preset.budget.operations:
        size = f"{stacked} circuits of {system.dof} nodes" if stacked > 1 else f"{system.dof} nodes"
        shorter = ", shorten t_stop" if work.points > _fewest(system, preset) + _POINTS_PER_SEGMENT * work.segments \
            else ""
        raise InputError(f"the SPICE circuit ({size}) would need about {work.operations:.3g} operations "
                         f"({work.points:.3g} time points of {work.operations / work.points:.3g}), more than "
                         f"the budget of {preset.budget.operations:.3g}: solve it without spice{shorter}, "
                         "or raise the preset's operation budget", field="budget")
    return work


def check_works(systems: Sequence, preset: Preset, *, spice: bool = True) -> None:
    """:func:`check_work` on many systems: one estimate per stack sharing forces, t_stop and size,
    from the stack's combined scales (its fastest rate); nonlinear systems one by one.

    Parameters
    ----------
    systems : sequence of node systems
        What one batched run would solve.
    preset : Preset
        The accuracy preset.
    spice : bool
        Whether SPICE is among the solvers (one circuit per stack).
    """
    if isinstance(systems, NodeStack) and len(systems) > 1 and systems.shares_inputs:
        if systems.checked is None or systems.checked[0] is not preset or systems.checked[1] != spice:
            # the inputs' row answers for the inputs, the first row for the circuit's pattern
            scales, operations = run_scales(systems), first_point_operations(systems)
            try:
                check_work(systems.inputs_row, preset, scales, stacked=len(systems), spice=spice, operations=operations)
            except InputError:      # refused: said of the first row, whose own scales word the sentence
                check_work(systems[0], preset, scales, stacked=len(systems), spice=spice, operations=operations)
                raise
            systems.checked = (preset, spice)
        return
    groups: dict = {}
    for s in systems:
        if s.kind == "linear":
            groups.setdefault((float(s.t_stop), id(s.forces), s.dof, id(s.topology)), []).append(s)
        else:
            check_work(s, preset, spice=spice)
    for group in groups.values():
        scales = None if len(group) == 1 else run_scales(group)
        check_work(group[0], preset, scales, stacked=len(group), spice=spice)
