"""Ringing circuits: the trapezoidal rule's phase error, carried by the circuit's own modes, sets the steps.

Each step of ngspice's trapezoidal rule errs (ω·h)³/12 of an undamped mode's amplitude in phase, so
the error grows with every step the mode takes. The truncation model foretells ngspice's steps at a
reltol and their summed error, carrying the circuit's modes (the UR arms hang with zero joint damping:
three rigid-body modes beside three undamped oscillations, a double root carried by dense
exponentials). Where no model is made (past its samples, or for another engine) the step cap holds
Σ(ω·h)³/12 to bound/SAFETY over the run."""

import math
import shutil
import subprocess

import numpy as np
import pytest

from analogy.circuit.node_system import node_system
from analogy.circuit.scales import Scales, system_scales
from analogy.model.joint import JointSpace
from analogy.presets import PRESETS
from analogy.solvers.error_constants import SAFETY
from analogy.solvers.exact import solve_exact
from analogy.solvers.rawfile import read_printed
from analogy.solvers.spice import solve_spice
from analogy.solvers.transient import _phase_cap, netlist, transient_settings
from analogy.solvers.truncation import MODEL_SHARE, truncation_model
from analogy.study.comparison import compare

pytestmark = pytest.mark.ngspice

ACCURATE, FAST = PRESETS["accurate"], PRESETS["fast"]


def _scales(phases, turns, shares):
    n = len(phases)
    return Scales(0.0, np.ones(2), np.ones(2), 1.0, 1.0, np.zeros(n), np.asarray(shares, float),
                  np.asarray(phases, float), frequencies=np.asarray(turns, float))


def test_the_phase_error_sums_each_mode_s_radians_times_its_error_per_radian():
    sc = _scales([20.0, 100.0], [2.0, 10.0], [1.0, 1.0])
    h = 1e-3
    assert sc.phase_error(h, 1e-6) == pytest.approx((20 * (2 * h) ** 2 + 100 * (10 * h) ** 2) / 12, rel=1e-15)
    step = sc.phase_limit(5e-7, 1e-6)
    assert sc.phase_error(step, 1e-6) == pytest.approx(5e-7, rel=1e-14)
    # a mode under the bound cannot break it, and counts for nothing
    assert _scales([20.0, 100.0], [2.0, 10.0], [1.0, 1e-7]).phase_error(h, 1e-6) == \
        pytest.approx(20 * (2 * h) ** 2 / 12, rel=1e-15)
    assert _scales([], [], []).phase_limit(1e-6, 1e-6) == math.inf


def test_an_undamped_mode_turns_omega_t_stop_radians_and_a_growing_one_sigma_t_stop():
    undamped = node_system(JointSpace(np.eye(1), np.zeros((1, 1)), np.array([[4.0]])), forces=[1.0], t_stop=10.0)
    sc = system_scales(undamped)
    assert sc.frequencies == pytest.approx([2.0], rel=1e-14)
    assert sc.phase_error(1e-3, 1e-6) == pytest.approx(20.0 * (2e-3) ** 2 / 12, rel=1e-13)
    growing = node_system(JointSpace(np.eye(1), np.zeros((1, 1)), np.array([[-4.0]])), forces=[1.0], t_stop=1.0)
    assert system_scales(growing).frequencies == pytest.approx([2.0], rel=1e-14)


def test_a_phase_cap_the_step_budget_cannot_pay_for_is_not_taken():
    # 1000 undamped radians at 1 rad/s: bound/2 at fast asks ω·h = 0.077, 12,900 steps; 100 times
    # the radians ask 1000^1.5 times the steps
    sc = _scales([1000.0], [1.0], [1.0])
    step = _phase_cap(FAST, 1000.0, sc)
    assert step == pytest.approx(math.sqrt(12 * FAST.bound / SAFETY / 1000.0), rel=1e-14)
    assert _phase_cap(FAST, 1000.0, _scales([1e5], [100.0], [1.0])) == math.inf
    # nor one whose operations pass the budget
    assert _phase_cap(FAST, 1000.0, sc, operations=FAST.budget.operations) == math.inf


def test_a_calibrated_circuit_keeps_the_calibrated_cap():
    """Φ ≤ 1: the error constants speak for the circuit, and their cap t_stop/50 stays."""
    from analogy.scenes.builtin import scene
    s = scene("parallel3").system()
    assert 0 < system_scales(s).ringing(1e-6) <= 1
    settings = transient_settings(PRESETS["accurate"], s.t_stop, system_scales(s), breakpoints=s.breakpoints())
    assert settings.max_step == pytest.approx(s.t_stop / 50, rel=1e-14)


def _oscillators():
    # two undamped modes (1 and 4 rad/s) over 10 s: Φ = 40, far past the calibration's 1
    return node_system(JointSpace(np.eye(2), np.zeros((2, 2)), np.diag([1.0, 16.0])), forces=[1.0, 1.0],
                       t_stop=10.0)


def test_each_mode_errs_its_summed_phase_error_over_the_steps_taken_and_the_truncation_model_foretells_both():
    """The mechanism: each mode's error over its amplitude is Σ(ω·h)³/12 over ngspice's steps. The
    circuit's truncation model foretells those steps from ngspice's own check and carries their phase
    errors, so its reltol lands every output between the model's share of the bound and the bound."""
    s = _oscillators()
    tr = solve_spice(s, preset="accurate")
    exact = solve_exact(s, tr.time)
    h = np.diff(tr.time)
    errors = []
    for k, omega in enumerate((1.0, 4.0)):
        error = np.max(np.abs(tr.rates[:, k] - exact.rates[:, k])) / np.max(np.abs(exact.rates[:, k]))
        drift = np.sum((omega * h) ** 3) / 12
        # the next terms of the phase and of ngspice's unchecked first step, each under 5 % here
        assert drift / 1.1 <= error <= drift * 1.1, (k, error, drift)
        errors.append(error)
    opts = {k: float(v) for k, v in tr.settings.options if k in ("reltol", "abstol", "chgtol")}
    model = truncation_model(s)
    steps = model.steps(opts["reltol"], opts["abstol"], opts["chgtol"], tr.settings.max_step)
    # the model's samples (six a radian) give q‴ and the carried phase to about 1 %; 5 % leaves room for
    # ngspice's start, where its step doubles from the first one
    assert tr.stats.steps == pytest.approx(model.points(steps), rel=0.05)
    assert model.errors(steps) == pytest.approx(errors, rel=0.05)
    assert 0.5 * ACCURATE.bound <= max(errors) <= ACCURATE.bound


def test_the_written_netlist_runs_the_in_process_steps_in_plain_ngspice(tmp_path):
    s = _oscillators()
    text = netlist(s, "accurate")
    tran = next(line.split() for line in text.splitlines() if line.startswith(".tran"))
    assert float(tran[4]) == pytest.approx(solve_spice(s, preset="accurate").settings.max_step, rel=1e-12)
    exe = shutil.which("ngspice")
    if exe is None:
        pytest.skip("no ngspice executable")
    path = tmp_path / "ring.cir"
    path.write_text(text)
    res = subprocess.run([exe, "-b", str(path)], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0 and "too small" not in (res.stdout + res.stderr).lower()
    printed = read_printed(res.stdout)
    t, v = printed["time"], np.column_stack([printed[n] for n in s.nodes])
    exact = solve_exact(s, t)
    peak = np.max(np.abs(exact.rates), axis=0)
    # printed on the print step, interpolated linearly between steps of ω·h ≈ 5e-4: (ω·h)²/8 ≈ 3e-8 more
    assert np.all(np.max(np.abs(s.joint_rates(v) - exact.rates), axis=0) / peak <= ACCURATE.bound)


def _robot(name):
    from analogy.scenes.robot_defaults import robot_scene
    return robot_scene(name).system()


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ur3", "ur5", "ur10"])
def test_every_output_of_a_hanging_ur_arm_keeps_the_accurate_bound(name):
    s = _robot(name)
    c = compare(s, "accurate", ("spice",))
    assert not c.failures and not c.outside_bound(), c.table()
    tr = c.results["spice"]
    # the steps the truncation model foretells at the settings it chose (3 %: its samples and ngspice's start),
    # and the worst output within 3 % of the model's share of the bound (its search's stop and its foretelling)
    opts = {k: float(v) for k, v in tr.settings.options if k in ("reltol", "abstol", "chgtol")}
    model = truncation_model(s)
    steps = model.steps(opts["reltol"], opts["abstol"], opts["chgtol"], tr.settings.max_step)
    assert tr.stats.steps == pytest.approx(model.points(steps), rel=0.03)
    assert c.max_relative_error("spice") >= MODEL_SHARE / 1.03 ** 2 * ACCURATE.bound


@pytest.mark.slow
def test_a_hanging_ur5_keeps_the_fast_bound_and_a_tolerance_between():
    s = _robot("ur5")
    for preset in ("fast", "1e-5"):
        c = compare(s, preset, ("spice",))
        assert not c.failures and not c.outside_bound(), c.table()
