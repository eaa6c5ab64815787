"""A nonlinear circuit's step from its motion's error: h²/12·∫|r'''|dt per joint rate bounds what the
trapezoidal rule errs, and the step it asks keeps each output within the bound."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.scenes.builtin import scene
from analogy.solvers.motion_step import motion_error, motion_step
from analogy.solvers.registry import solve
from analogy.solvers.spice import solve_spice
from analogy.solvers.transient import netlist

pytestmark = pytest.mark.ngspice


def _swing(force: float = 10.0):
    """The 2-DOF arm swung by steps 10 times the default scene's over 5 s: several radians."""
    return scene("default").replace(dynamics="nonlinear", forces=(force, 0.5 * force), t_stop=5.0).system()


@pytest.mark.parametrize("preset", ["fast", "accurate"])
def test_the_motion_error_bounds_what_each_joint_rate_errs_and_the_step_keeps_the_bound(preset):
    """Each step's truncation error is h³/12·r''' and the errors add at most: the run's error on
    every joint rate is under h²·C_j of its peak at the longest step it took, and so within the bound."""
    system = _swing()
    p = PRESETS[preset]
    run = solve_spice(system, preset=p)
    reference = solve(system, "reference", run.time, p)
    _, rel = output_errors(system.joint_rates(run.voltages), reference.rates)
    coefficient, peak = motion_error(system, p)
    h = run.settings.max_step
    assert np.all(np.asarray(rel) <= h ** 2 * coefficient / peak)
    assert np.max(rel) <= p.bound


def test_the_step_is_what_the_error_asks_and_what_the_netlist_writes():
    """h = min_j √(bound/SAFETY·peak_j/C_j), no longer than a fifth of the output step."""
    from analogy.solvers.error_constants import SAFETY
    system = _swing()
    p = PRESETS["accurate"]
    coefficient, peak = motion_error(system, p)
    want = min(float(np.min(np.sqrt(p.bound / SAFETY * peak / coefficient))), system.t_stop / (5 * p.steps))
    assert motion_step(system, p, 1.0) == pytest.approx(want, rel=1e-12)
    tran = next(line.split() for line in netlist(system, p).splitlines() if line.startswith(".tran"))
    assert float(tran[4]) == pytest.approx(want, rel=1e-12)


def test_a_motion_past_the_budget_keeps_the_fixed_cap_and_is_judged():
    system = _swing()
    p = PRESETS["accurate"]
    asked = system.t_stop / motion_step(system, p, 1.0)
    assert motion_step(system, replace(p, step_budget=int(asked / 2)), 1.0) is None
    assert motion_step(system, p, p.operation_budget / asked * 2) is None
    run = solve_spice(system, preset=replace(p, step_budget=int(asked / 2)))
    assert run.settings.max_step == pytest.approx(system.t_stop / p.behavioural_max_steps, rel=1e-12)


def test_a_motion_at_rest_takes_the_output_steps_alone():
    """No force on an arm at rest at g = 0: r''' = 0, so no step is asked beyond the output's."""
    system = scene("default").replace(dynamics="nonlinear", forces=(0.0, 0.0), t_stop=2.0).system()
    p = PRESETS["fast"]
    coefficient, _ = motion_error(system, p)
    assert np.all(coefficient == 0.0)
    assert motion_step(system, p, 1.0) == pytest.approx(system.t_stop / (5 * p.steps), rel=1e-12)
