"""A tolerance instead of a preset: the named presets are tolerances, and the settings between them keep theirs."""

import math
import subprocess
import sys

import pytest

from analogy.presets import PRESETS, TOLERANCE_RANGE, preset, tolerance_preset
from analogy.scenes.builtin import scene
from analogy.study.comparison import compare

#: Every check here runs SPICE: the engine pass (ngspice 46) runs them too.
pytestmark = pytest.mark.ngspice


def test_the_named_presets_are_the_tolerances_1e_3_and_1e_6():
    assert preset("1e-3") is PRESETS["fast"] and preset(1e-3) is PRESETS["fast"]
    assert preset("1e-6") is PRESETS["accurate"] and tolerance_preset(1e-6) is PRESETS["accurate"]
    assert preset("1e-5").bound == 1e-5 and preset("1e-5").name == "1e-05"


def test_the_step_cap_follows_the_square_root_of_the_tolerance():
    # the trapezoidal rule's error grows as (ω·h)²: ten times the tolerance, √10 times the cap
    a, b = tolerance_preset(1e-4), tolerance_preset(1e-5)
    fast, accurate = PRESETS["fast"], PRESETS["accurate"]
    exponent = math.log(accurate.phase_step / fast.phase_step) / math.log(1e-3)
    assert exponent == pytest.approx(0.5, abs=0.01)        # the two calibrated presets agree with h²
    assert a.phase_step / b.phase_step == pytest.approx(10 ** exponent, rel=1e-12)
    assert accurate.phase_step < b.phase_step < a.phase_step < fast.phase_step
    assert fast.max_steps < a.max_steps < b.max_steps < accurate.max_steps
    assert float(b.spice_options["reltol"]) < float(a.spice_options["reltol"])
    assert a.ode_method == "LSODA" and b.ode_method == "DOP853"


@pytest.mark.parametrize("tol", [1e-2, 1e-4, 1e-5, 1e-7])
def test_each_solver_keeps_the_tolerance_asked_for_on_the_default_arm(tol):
    c = compare(scene("default").system(), tol)
    assert c.bound == tol
    assert c.outside_bound() == {}, c.table()


def test_a_tolerance_outside_the_range_is_one_sentence():
    low, high = TOLERANCE_RANGE
    with pytest.raises(Exception, match="the tolerance must be a number from 1e-09 to 0.01"):
        tolerance_preset(high * 10)
    res = subprocess.run([sys.executable, "-m", "analogy", "compare", "--tol", "1e-12", "--no-plot"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_a_scene_takes_a_tolerance_as_its_preset():
    sc = scene("default").replace(preset="1e-05")
    assert sc.key != scene("default").replace(preset="accurate").key
    with pytest.raises(Exception, match="unknown accuracy preset"):
        scene("default").replace(preset="slow")


def test_the_bench_times_what_tol_chooses_and_says_whether_it_kept_the_tolerance():
    from analogy.bench import bench
    result = bench(repeats=1, quick=True, scenes=[scene("default")], progress=False)
    rows = {r.setting: r for r in result.rows if r.solver == "spice"}
    for tol in (1e-3, 1e-6):
        row = rows[f"tol={tol:g}"]
        assert row.status == "ok" and row.error <= tol
    lines = "\n".join(result.cost_lines())
    assert "default at 0.001: cheapest SPICE" in lines and "--tol 1e-06:" in lines and "(kept)" in lines
