"""The nonlinear circuit's step from its motion: the trapezoidal rule's global error h²·E(t), foretold and measured."""

import math

import numpy as np
import pytest

import analogy
from analogy.presets import PRESETS
from analogy.scenes.scene import ModelSpec
from analogy.solvers.error_constants import SAFETY
from analogy.solvers.motion_step import error_coefficients, motion_step
from analogy.study.comparison import compare


def _pendulum(rate: float, t_stop: float = 10.0):
    scene = analogy.scene("default").replace(
        model=ModelSpec("serial1"), q=(-math.pi / 2,), forces=("0",), initial_rates=(rate,),
        parameters={"g": 9.81, "b1": 0.0}, dynamics="nonlinear", t_stop=t_stop)
    return scene.system()


def test_a_small_swing_errs_as_the_trapezoidal_phase_drift_of_its_oscillation():
    """A hanging pendulum at 1e-3 rad/s is the oscillator r'' = −ω²x. The rule's phase drifts
    ω³h²t/12, so the rate errs h²·R·ω³t/12·|sin ωt|, largest at the last crest before t_stop.
    The coefficients (finite differences of the sampled motion, (h·ω)² ≈ 1e-3 off) give it to 1 %."""
    system = _pendulum(1e-3)
    jac = system.jacobian(np.zeros(1), np.zeros(1), np.zeros(1))
    omega = math.sqrt(-jac[1, 0])
    crest = (math.floor((omega * system.t_stop - math.pi / 2) / math.pi) * math.pi + math.pi / 2) / omega
    errors = error_coefficients(system)
    assert np.max(errors.relative[:, 0]) == pytest.approx(omega ** 3 * crest / 12, rel=0.01)
    assert errors.curvature[0] == pytest.approx(omega, rel=0.01)            # r'' = ω·R at its crest


def test_the_step_holds_every_rate_within_its_share_of_the_bound():
    """h = √(bound/SAFETY·peak/max|E|) per joint, the smallest taken; and the interpolation onto
    the print points (h²/8·max|r''|) is held alike."""
    system = _pendulum(1e-3)
    errors = error_coefficients(system)
    bound = PRESETS["accurate"].bound
    h = motion_step(system, bound, SAFETY)
    worst = max(h ** 2 * np.max(errors.relative), h ** 2 / 8 * errors.curvature[0])
    assert worst == pytest.approx(bound / SAFETY, rel=1e-12)     # the longest step that holds both


def test_a_uniform_step_past_the_operation_budget_is_not_bought():
    """The xArm7's default (g = 0) starts with a 68 µs decay. Followed by the samples from the start,
    the rule's error there asks 1.6 million uniform steps, 1.5e11 operations against the budget's
    5e10: the step is not bought, the preset's cap t_stop/behavioural_max_steps runs, and the run is
    judged (flagged at 2.6e-3)."""
    from analogy.circuit.description import circuit
    from analogy.circuit.elements import point_operations
    from analogy.solvers.transient import circuit_settings
    system = analogy.scene("xarm7").replace(dynamics="nonlinear").system()
    accurate = PRESETS["accurate"]
    h = motion_step(system, accurate.bound, SAFETY)
    assert system.t_stop / h * point_operations(system) > accurate.budget.operations
    settings = circuit_settings(system, circuit(system), PRESETS["accurate"])
    assert settings.max_step == pytest.approx(system.t_stop / accurate.spice.behavioural_max_steps)


@pytest.mark.ngspice
@pytest.mark.parametrize("rates, forces, t_stop", [((0.0, 0.0), ("step(1)", "step(0.5)"), 10.0),
                                                   ((0.5, -0.3), ("step(10)", "step(5)"), 5.0)])
def test_the_circuit_at_its_motion_step_keeps_the_bound_without_wasting_it(rates, forces, t_stop):
    """The 2-DOF arm at rest under the default steps, and thrown under forces ten times larger:
    at the step from its error coefficients SAFETY = 2 under the bound, ngspice lands at 0.20 and
    0.21 of it (measured), so the coefficients are within 2.5 times of what ngspice errs. Kept:
    at most the bound; not wasted: above a tenth of it (fewer steps would have done)."""
    system = analogy.scene("default").replace(dynamics="nonlinear", initial_rates=rates, forces=forces,
                                              t_stop=t_stop).system()
    c = compare(system, "accurate", solvers=("spice", "reference"))
    error = c.max_relative_error("spice")
    bound = PRESETS["accurate"].bound
    assert bound / 10 <= error <= bound, error
    assert "retried" not in c.results["spice"].message
