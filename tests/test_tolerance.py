"""A tolerance instead of a preset: the named presets are tolerances, and the settings between them keep theirs."""

import dataclasses
import math
import subprocess
import sys

import pytest

from analogy.errors import InputError
from analogy.presets import PRESETS, TOLERANCE_RANGE, preset, tolerance_preset
from analogy.scenes.builtin import scene
from analogy.circuit.scales import system_scales
from analogy.solvers.transient import REFINE, refined, transient_settings
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
    exponent = math.log(accurate.spice.phase_step / fast.spice.phase_step) / math.log(1e-3)
    assert exponent == pytest.approx(0.5, abs=0.01)        # the two calibrated presets agree with h²
    assert a.spice.phase_step / b.spice.phase_step == pytest.approx(10 ** exponent, rel=1e-12)
    assert accurate.spice.phase_step < b.spice.phase_step < a.spice.phase_step < fast.spice.phase_step
    assert fast.spice.max_steps < a.spice.max_steps < b.spice.max_steps < accurate.spice.max_steps
    assert float(b.spice.options["reltol"]) < float(a.spice.options["reltol"])
    assert a.ode.method == "LSODA" and b.ode.method == "DOP853"


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
    from analogy.diagnostics.bench import bench
    result = bench(repeats=1, quick=True, scenes=[scene("default")], progress=False)
    rows = {r.setting: r for r in result.rows if r.solver == "spice"}
    for tol in (1e-3, 1e-6):
        row = rows[f"tol={tol:g}"]
        assert row.status == "ok" and row.error <= tol
    lines = "\n".join(result.cost_lines())
    assert "default at 0.001: cheapest SPICE" in lines and "--tol 1e-06:" in lines and "(kept)" in lines


def test_a_sweep_runs_at_a_tolerance_and_an_axis_may_sweep_tolerances(tmp_path):
    import numpy as np
    from analogy.batch import read
    from analogy.cli import main
    from sweep_text import HEAD
    path = tmp_path / "sweep.toml"
    path.write_text(HEAD + '[sweep]\nmethod = "grid"\ncount = 4\ngroup_size = 4\n[sweep.axes]\n'
                    'q2 = [0.3, 1.0]\npreset = ["1e-4", "1e-5"]\n')
    assert main(["batch", str(path), "-o", str(tmp_path / "store"), "--no-progress"]) == 0
    frame = read(tmp_path / "store")
    assert sorted(set(frame["preset"].astype(float))) == [1e-5, 1e-4]
    assert np.all(frame["error_spice"] <= frame["preset"].astype(float))      # each kept its own tolerance
    path.write_text(HEAD + '[sweep]\nmethod = "grid"\ncount = 2\ngroup_size = 2\n[sweep.axes]\nq2 = [0.3, 1.0]\n')
    assert main(["batch", str(path), "-o", str(tmp_path / "store2"), "--tol", "1e-5", "--no-progress"]) == 0
    errors = read(tmp_path / "store2")["error_spice"]
    assert errors.max() <= 1e-5          # the sweep's own preset, fast, errs about 1e-4 here


def test_a_refined_run_keeps_its_first_step_and_halves_the_cap_so_it_is_never_coarser():
    s = scene("default").system()
    for name in PRESETS.values():
        base = transient_settings(name, s.t_stop, system_scales(s), breakpoints=s.breakpoints())
        fine = transient_settings(refined(name), s.t_stop, system_scales(s), breakpoints=s.breakpoints())
        a, b = dict(base.options), dict(fine.options)
        # abstol REFINE³ times tighter down to the rounding floor of the first step, which is kept
        tighter = float(a["abstol"]) / float(b["abstol"])
        assert (tighter == pytest.approx(1.0, rel=1e-2) or tighter == pytest.approx(REFINE ** 3, rel=1e-2))
        assert fine.first_step == base.first_step
        assert fine.max_step == pytest.approx(base.max_step / REFINE)
        assert float(b["reltol"]) == pytest.approx(float(a["reltol"]) / REFINE ** 3, rel=1e-2)
        cap_only = transient_settings(refined(name, tolerances=False), s.t_stop, system_scales(s),
                                      breakpoints=s.breakpoints())
        assert dict(cap_only.options) == a and cap_only.max_step == fine.max_step


@pytest.mark.parametrize("option", [{"reltol": "nan"}, {"abstol": float("inf")}, {"maxord": "abc"},
                                    {"method": "euler"}, {"reltol; .control": "1e-6"}, {"reltol": ""},
                                    {"trtol": " "}, {"method": ""}, {"interp": "1"}, {"reltol": "1_000"}])
def test_an_option_ngspice_cannot_read_is_refused_before_it_is_written(option):
    # ngspice runs on after reltol=nan or maxord=abc, saying so only in print, with its default instead
    custom = dataclasses.replace(preset("fast"), spice=dataclasses.replace(preset("fast").spice, options={**preset("fast").spice.options, **option}))
    with pytest.raises(InputError, match="SPICE option"):
        transient_settings(custom, 1.0, None)           # no scales: the preset's options as they are


def test_flags_words_and_finite_numbers_pass_as_written():
    custom = dataclasses.replace(preset("fast"), spice=dataclasses.replace(preset("fast").spice, options={"method": "gear", "maxord": "2", "reltol": 1e-4}))
    options = dict(transient_settings(custom, 1.0, None).options)
    assert options["method"] == "gear" and options["maxord"] == "2" and options["klu"] == ""
