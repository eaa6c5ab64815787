"""The reltol a tolerance asks for: ngspice's calibrated error constants, and the ringing Φ that sets where they hold."""

import csv
import math

import numpy as np
import pytest

from analogy.circuit.node_system import node_system
from analogy.circuit.scales import system_scales
from analogy.model.joint import JointSpace
from analogy.presets import PRESETS, tolerance_preset
from analogy.solvers.error_constants import (CALIBRATED_MAX_STEPS, CALIBRATION, RELTOL_LIMITS, RINGING_LIMIT, SAFETY,
                                             ErrorConstant, calibrated_reltol, error_constants, predicted_error,
                                             read_constants, spice_reltol)
from analogy.solvers.transient import transient_settings

RUNS = CALIBRATION.with_name(f"{CALIBRATION.stem}_runs.csv")
#: The files hold c0 to 4 significant digits and errors to 4: each is off by at most 5e-4 of itself.
WRITTEN = 5e-4


def _runs():
    with open(RUNS, newline="") as fh:
        return [r for r in csv.DictReader(fh) if r["status"] == "ok"]


def test_each_rungs_constant_bounds_every_run_it_was_measured_on_and_is_reached():
    """error ≤ c0·reltol^(2/3) on every calibration run, and one run sits on it: the constants are the
    measured ones, neither looser nor hand-made, and every run is of a circuit that does not ring."""
    runs = _runs()
    for rung in error_constants():
        mine = [r for r in runs if math.isclose(float(r["reltol"]), rung.reltol, rel_tol=1e-9)]
        assert len(mine) == rung.circuits > 0
        worst = max(float(r["error_over_peak"]) for r in mine)
        assert worst == pytest.approx(rung.error, rel=2 * WRITTEN)
        assert all(float(r["ringing"]) <= RINGING_LIMIT for r in mine)


def test_the_chosen_reltol_meets_the_tolerance_by_the_constants_and_a_looser_one_would_not():
    for tol in (1e-2, 1e-3, 1e-4, 1e-6, 1e-7):
        r = spice_reltol(tol)
        assert RELTOL_LIMITS[0] <= r <= RELTOL_LIMITS[1]
        if r > RELTOL_LIMITS[0]:
            assert predicted_error(r) <= tol / SAFETY
        if RELTOL_LIMITS[0] < r < RELTOL_LIMITS[1]:
            assert predicted_error(r * 10 ** 0.005) > tol / SAFETY     # bisection to 1e-3 of a decade


def test_a_tighter_tolerance_never_asks_for_a_looser_reltol_and_a_ringing_circuit_is_not_spoken_for():
    tols = np.logspace(-9, -2, 29)
    assert np.all(np.diff([spice_reltol(t) for t in tols]) >= 0)
    assert calibrated_reltol(1e-6, 0.0) == spice_reltol(1e-6)
    assert calibrated_reltol(1e-6, 2 * RINGING_LIMIT) is None
    tightest = error_constants()[0]
    assert calibrated_reltol(0.5 * tightest.error, 0.0) is None      # under every measured error


def test_the_predicted_error_runs_through_each_rung_and_grows_as_reltol_to_two_thirds_past_the_loosest():
    rungs = (ErrorConstant(1e-9, 2.0), ErrorConstant(1e-7, 1.0))
    tight, loose = 2.0 * 1e-6, 1.0 * 1e-7 ** (2 / 3)
    assert predicted_error(1e-9, rungs) == pytest.approx(tight, rel=1e-12)
    assert predicted_error(1e-7, rungs) == pytest.approx(loose, rel=1e-12)
    assert predicted_error(1e-8, rungs) == pytest.approx(math.sqrt(tight * loose), rel=1e-12)   # log-log
    assert predicted_error(1e-5, rungs) == pytest.approx(loose * 100 ** (2 / 3), rel=1e-12)
    assert predicted_error(1e-12, rungs) == pytest.approx(tight, rel=1e-12)   # no better than measured
    # a tighter rung that erred more than a looser one is a floor: the looser one errs at least as much
    floor = (ErrorConstant(1e-11, 1e3), ErrorConstant(1e-9, 1.0))
    assert predicted_error(1e-9, floor) == pytest.approx(1e3 * 1e-11 ** (2 / 3), rel=1e-12)


def test_the_shipped_file_reads_back_sorted_from_the_tightest_rung():
    rungs = read_constants(CALIBRATION)
    assert [r.reltol for r in rungs] == sorted(r.reltol for r in rungs)
    assert all(r.c0 > 0 for r in rungs)


def test_ringing_is_the_radians_an_oscillation_turns_while_it_lives():
    """Φ = max over t ≤ t_stop of ω_d·t·e^(-β·t/2): an undamped mode turns ω·t_stop, a damped one's
    phase error times what is left of it peaks at t = 2/β, at ω_d·2/(e·β); a decay does not ring."""
    undamped = node_system(JointSpace(np.eye(1), np.zeros((1, 1)), np.array([[4.0]])), forces=[1.0], t_stop=10.0)
    assert system_scales(undamped).ringing(1e-6) == pytest.approx(2.0 * 10.0, rel=1e-12)
    beta = 0.4                         # ζ = β/2ω = 0.1
    damped = node_system(JointSpace(np.eye(1), np.array([[beta]]), np.array([[4.0]])), forces=[1.0], t_stop=10.0)
    omega_d = math.sqrt(4.0 - (beta / 2) ** 2)
    assert system_scales(damped).ringing(1e-6) == pytest.approx(omega_d * 2 / (math.e * beta), rel=1e-12)
    late = node_system(JointSpace(np.eye(1), np.array([[beta]]), np.array([[4.0]])), forces=[1.0], t_stop=2.0)
    assert system_scales(late).ringing(1e-6) == pytest.approx(omega_d * 2.0 * math.exp(-beta * 2.0 / 2), rel=1e-12)
    decay = node_system(JointSpace(np.eye(1), np.array([[3.0]])), forces=[1.0], t_stop=10.0)
    assert system_scales(decay).ringing(1e-6) == 0.0


def test_a_calibrated_preset_takes_its_reltol_from_the_constants_and_the_cap_they_were_measured_at():
    system = node_system(JointSpace(np.eye(2), np.diag([1.0, 2.0])), forces=[1.0, 0.5], t_stop=10.0)
    sc = system_scales(system)
    assert sc.ringing(1e-6) == 0.0
    for p in (PRESETS["accurate"], PRESETS["fast"], tolerance_preset(1e-5)):
        s = transient_settings(p, 10.0, sc)
        opts = dict(s.options)
        assert float(opts["reltol"]) == pytest.approx(spice_reltol(p.bound), rel=5e-3)
        assert opts["trtol"] == "1" and opts["method"] == "trap"
        assert s.max_step == pytest.approx(10.0 / CALIBRATED_MAX_STEPS)
    accurate = str(PRESETS["accurate"].spice.options["reltol"])
    for kind in ("coupled", "custom"):     # not measured: the preset's own options
        s = transient_settings(PRESETS["accurate"], 10.0, sc, **{kind: True})
        assert dict(s.options)["reltol"] == accurate
    ringing = node_system(JointSpace(np.eye(1), np.zeros((1, 1)), np.array([[4.0]])), forces=[1.0], t_stop=10.0)
    s = transient_settings(PRESETS["accurate"], 10.0, system_scales(ringing))
    assert dict(s.options)["reltol"] == accurate and s.max_step < 10.0 / PRESETS["accurate"].spice.max_steps * 1.0001


def test_a_rounding_floor_past_the_calibrations_leaves_the_preset_s_own_settings(monkeypatch):
    """Where abstol's rounding floor passes FLOOR_LIMIT of the current scale, the floor judges each
    step, not reltol: the constants do not speak for the circuit."""
    from analogy.solvers import transient
    system = node_system(JointSpace(np.eye(2), np.diag([1.0, 2.0])), forces=[1.0, 0.5], t_stop=10.0)
    p = PRESETS["accurate"]
    assert dict(transient_settings(p, 10.0, system_scales(system)).options)["reltol"] != "1e-10"
    monkeypatch.setattr(transient, "FLOOR_LIMIT", 0.0)
    s = transient_settings(p, 10.0, system_scales(system))
    assert dict(s.options)["reltol"] == "1e-10" and s.max_step <= 10.0 / p.spice.max_steps


@pytest.mark.deep
@pytest.mark.ngspice
@pytest.mark.parametrize("name", ["fast", "accurate", "1e-4"])
def test_every_calibration_circuit_keeps_the_bound_its_tolerance_chose_a_reltol_for(name):
    """Each circuit the constants were measured on holds the bound of the tolerance at the reltol the
    constants chose for it, per output: the settings a circuit runs where no truncation model is made
    (a stack of circuits in one netlist, a drive's robot). Through the solver as a user runs it, its
    truncation model's settings, it holds the bound too."""
    from analogy.circuit.description import circuit
    from analogy.circuit.netlist import write_netlist
    from analogy.diagnostics.calibration import calibration_circuits
    from analogy.presets import preset
    from analogy.results.metrics import output_errors
    from analogy.solvers.exact import solve_exact
    from analogy.solvers.spice import session
    from analogy.solvers.transient import circuit_settings
    from analogy.study.comparison import compare
    p = preset(name)
    for label, system in calibration_circuits():
        c = circuit(system)
        settings = circuit_settings(system, c, p, whole=False)
        assert dict(settings.options)["reltol"] == f"{spice_reltol(p.bound):.3g}", label
        data = session().run(write_netlist(c, settings, None, None, False, "ngspice"), list(system.nodes))
        rates = system.joint_rates(np.column_stack([data[n] for n in system.nodes]))
        assert np.max(output_errors(rates, solve_exact(system, data["time"]).rates, p.bound)[1]) <= p.bound, label
        assert compare(system, p, ["spice", "exact"]).errors()["spice"][1] <= p.bound, label

def test_a_recalibration_is_read_by_the_calibrated_reltol_at_once(tmp_path, monkeypatch):
    """write_constants clears every answer kept from the calibration it replaces: calibrated_reltol
    gives the new constants' reltol in the same process, as spice_reltol does."""
    import shutil
    import analogy.solvers.error_constants as ec
    path = tmp_path / "calibration.csv"
    shutil.copy(ec.CALIBRATION, path)
    monkeypatch.setattr(ec, "CALIBRATION", path)
    for cached in (ec.error_constants, ec._shipped_reltol, ec._shipped_calibrated):
        cached.cache_clear()
    before = ec.calibrated_reltol(1e-3, 0.0)
    ec.write_constants([ec.ErrorConstant(r.reltol, r.c0 * 50, r.circuits, r.worst) for r in ec.error_constants()], path)
    after = ec.calibrated_reltol(1e-3, 0.0)
    assert after == ec.spice_reltol(1e-3) == ec.calibrated_reltol(1e-3, 0.0, ec.error_constants()) != before
    monkeypatch.undo()
    for cached in (ec.error_constants, ec._shipped_reltol, ec._shipped_calibrated):
        cached.cache_clear()
