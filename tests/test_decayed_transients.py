"""A decay that is over before the run ends sets no step cap: its first step is short, ngspice's
truncation check follows it while it lasts, and the oscillations (and the decays that last) alone
cap the step for the rest of the run."""

import math
from importlib import metadata
from dataclasses import replace

import numpy as np
import pytest

from analogy.circuit.description import circuit
from analogy.circuit.scales import Scales, system_scales
from analogy.cli import build_parser, scene_from_args
from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.solvers.exact import solve_exact
from analogy.solvers.spice import solve_spice
from analogy.solvers.transient import circuit_settings, transient_settings

ACCURATE = PRESETS["accurate"]


def _scales(omega=0.0, decays=(), shares=()):
    return Scales(omega, np.ones(2), np.ones(2), 1.0, 1.0, np.asarray(decays, float), np.asarray(shares, float),
                  np.zeros(len(decays)))


def test_a_decay_counts_while_it_is_larger_than_ten_times_the_bound():
    # share 1 falls under 10·1e-6 at β·t = ln(1e5) = 11.5
    sc = _scales(3.0, decays=[1e4, 1.0], shares=[1.0, 1.0])
    assert sc.lasting(1e-6, 10.0) == 3.0                  # 1e4/s over by 1.2 ms, 1/s by 11.5 s
    assert sc.lasting(1e-6, 11.0) == 3.0
    assert sc.lasting(1e-6, 12.0) == 3.0
    assert _scales(0.0, [1e4, 1.0], [1.0, 1.0]).lasting(1e-6, 11.0) == 1.0     # 1/s still lasts at 11 s
    assert _scales(0.0, [1e4, 1.0], [1.0, 1.0]).lasting(1e-6, 12.0) == 0.0
    assert _scales(0.0, [1e4], [1.0]).lasting(1e-6, math.log(1e5) / 1e4 * 0.99) == 1e4
    # without a horizon every decay that can matter counts, as before
    assert sc.lasting(1e-6, math.inf) == sc.fastest(1e-6) == 1e4
    assert sc.decay_limit(0.5, 1e-6) == 0.5 / 1e4
    assert sc.decay_limit(0.5, 1e-6, 12.0) == math.inf
    # a decay under ten times the bound never counts
    assert _scales(0.0, [1e4], [5e-6]).lasting(1e-6, 0.0) == 0.0


def test_the_preset_cap_follows_the_decays_that_last_and_the_first_step_every_decay():
    sc = _scales(2.0, decays=[1e4], shares=[0.9])
    s = transient_settings(ACCURATE, 10.0, sc, custom=True)
    # the preset's own caps: t_stop/max_steps and phase_step/ω over the oscillation; the decay is over in 1.2 ms
    assert s.max_step == pytest.approx(min(10.0 / ACCURATE.spice.max_steps, ACCURATE.spice.phase_step / 2.0))
    # the first (unchecked, backward Euler) step still resolves the decay
    assert s.first_step * 1e4 <= ACCURATE.spice.first_phase_step * (1 + 1e-12)
    # a decay that lasts the run caps it as an oscillation does (under a cap t_stop/10 that leaves it room)
    loose = replace(ACCURATE, spice=replace(ACCURATE.spice, max_steps=10))
    assert transient_settings(loose, 10.0, _scales(0.0, [1.0], [0.9]), custom=True).max_step == pytest.approx(
        ACCURATE.spice.phase_step / 1.0)
    assert transient_settings(loose, 10.0, _scales(0.0, [3.0], [0.9]), custom=True).max_step == 1.0


def test_a_calibrated_run_keeps_the_decay_cap_its_constants_were_measured_at():
    # the calibration (phase_step = inf) and the calibrated runs step decays at β·h = decay_step
    sc = _scales(0.0, decays=[100.0], shares=[0.9])         # over within 0.12 s of 1e4 s
    s = transient_settings(ACCURATE, 1e4, sc)
    assert not s.interpolate                              # calibrated
    assert s.max_step == pytest.approx(ACCURATE.spice.decay_step / 100.0)


XARM7 = ("--robot xarm7 --param g=0 --t-stop 10 " + "--force 1 " * 7).split()


def _xarm7():
    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("the named URDF robots need example-robot-data (pip install 'analogy[robots]')")
    return scene_from_args(build_parser().parse_args(["compare", *XARM7])).system()


@pytest.mark.ngspice
def test_xarm7_at_g_0_steps_as_its_horizon_asks_and_keeps_the_bound():
    """No mode of the xArm7 at g = 0 oscillates; its fastest decay (1.5e4 /s) is over within 1 ms of 10 s.
    The step cap is then the preset's t_stop/max_steps, and the steps past it are the decays' while they
    last: ln(share/(10·bound))/phase_step each at most, about 700 per decay at accurate."""
    system = _xarm7()
    scales = system_scales(system)
    assert scales.omega_max == 0 and scales.lasting(ACCURATE.bound, system.t_stop) == 0
    settings = circuit_settings(system, circuit(system), ACCURATE)
    assert settings.max_step == pytest.approx(system.t_stop / ACCURATE.spice.max_steps)
    tr = solve_spice(system, preset=ACCURATE)
    decays = scales.decays[scales.shares > 10 * ACCURATE.bound]
    lasting = float(np.sum(np.log(scales.shares[scales.shares > 10 * ACCURATE.bound] / (10 * ACCURATE.bound))))
    assert decays.size
    assert tr.stats.steps <= ACCURATE.spice.max_steps + lasting / ACCURATE.spice.phase_step + ACCURATE.steps
    assert tr.stats.steps <= 200_000
    _, rel = output_errors(tr.rates, solve_exact(system, tr.time).rates)
    assert np.max(rel) <= ACCURATE.bound


@pytest.mark.ngspice
def test_the_written_xarm7_netlist_is_what_ran_and_runs_in_plain_ngspice(tmp_path):
    from test_plain_ngspice import _check
    system = _xarm7()
    tr = solve_spice(system, preset=ACCURATE)
    assert tr.settings == circuit_settings(system, circuit(system), ACCURATE)
    _check(" ".join(XARM7), tmp_path)
