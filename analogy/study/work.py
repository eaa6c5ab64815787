"""Work estimates before a run: time points and force segments, refused past the preset's budget."""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

from ..circuit.scales import combined_scales, stack_scales, system_scales
from ..errors import InputError
from ..presets import Preset

__all__ = ["WorkEstimate", "check_work", "check_works", "estimate_work"]

#: Time points per force segment: each breakpoint restarts an integrator's step control.
_POINTS_PER_SEGMENT = 4


class WorkEstimate(NamedTuple):
    """What a run of a linear system will cost: time points to step and force segments to walk."""

    points: float
    segments: int
    fastest: float      # the rate [rad/s] that sets the points: a mode, a decay or a sine


def estimate_work(system, preset: Preset, scales=None) -> WorkEstimate:
    """The time points and force segments a solver run of *system* needs at *preset*.

    The points follow the fastest rate the preset resolves (one step per
    ``preset.phase_step`` radians of it, the SPICE step cap and the ODE's step size
    alike), plus a few per force breakpoint.

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    preset : Preset
        The accuracy preset.
    scales : Scales, optional
        The system's scales, or the combined scales of a stack it stands for.
    """
    segments = len(system.breakpoints())
    scales = system_scales(system) if scales is None else scales
    rate = scales.fastest(preset.bound)
    if system.kind != "linear":
        # the configuration turns at the joint rates, and M'(x) with it: at least the start's
        units = getattr(getattr(system, "provenance", None), "units", None) or ("rad",) * system.dof
        turning = [abs(float(r)) for r, u in zip(system.initial_rates, units) if u == "rad"]
        rate = max([rate, *turning])
    phase = preset.phase_step if math.isfinite(preset.phase_step) else 1.0
    points = system.t_stop * rate / phase + _POINTS_PER_SEGMENT * segments
    return WorkEstimate(points if math.isfinite(points) else math.inf, segments, rate)


def check_work(system, preset: Preset, scales=None) -> WorkEstimate:
    """:func:`estimate_work`, refused in one sentence past ``preset.work_budget`` or ``preset.segment_budget``.

    Parameters
    ----------
    system : NodeSystem or NonlinearNodeSystem
        A node system; a nonlinear one is estimated from its start (x = 0 and r0).
    preset : Preset
        The accuracy preset; ``dataclasses.replace(preset, work_budget=…)`` raises the budget.
    scales : Scales, optional
        The system's scales, or the combined scales of a stack sharing its forces and t_stop.
    """
    work = estimate_work(system, preset, scales)
    if work.segments > preset.segment_budget:
        raise InputError(f"the forces have {work.segments:,} segments between breakpoints (pwl points, pulse "
                         f"edges), more than the budget of {preset.segment_budget:,}: use fewer, or raise "
                         "the preset's segment budget", field="budget")
    if work.points > preset.work_budget:
        raise InputError(f"the run would need about {work.points:.3g} time points (the fastest rate, "
                         f"{work.fastest:.3g} rad/s, over t_stop = {system.t_stop:g} s), more than the budget "
                         f"of {preset.work_budget:.3g}: shorten t_stop, or raise the preset's work budget",
                         field="budget")
    return work


def check_works(systems: Sequence, preset: Preset) -> None:
    """:func:`check_work` on many systems: one estimate per stack sharing forces, t_stop and size,
    from the stack's combined scales (its fastest rate); nonlinear systems one by one.

    Parameters
    ----------
    systems : sequence of node systems
        What one batched run would solve.
    preset : Preset
        The accuracy preset.
    """
    groups: dict = {}
    for s in systems:
        if s.kind == "linear":
            groups.setdefault((float(s.t_stop), id(s.forces), s.dof, id(s.topology)), []).append(s)
        else:
            check_work(s, preset)
    for group in groups.values():
        check_work(group[0], preset, None if len(group) == 1 else combined_scales(stack_scales(group)))
