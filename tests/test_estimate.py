"""Error estimates without a reference: Richardson's estimate from a refined run, on its own and on a netlist."""

import math
import subprocess
import sys

import numpy as np
import pytest

from dataclasses import replace

from analogy.presets import PRESETS
from analogy.results.trajectory import Trajectory
from analogy.scenes.builtin import scene
from analogy.scenes.scene import Scene
from analogy.scenes.spec import ModelSpec
from analogy.solvers.transient import REFINE, refined
from analogy.diagnostics.stress.estimates import AGREEMENT, validate_estimates
from analogy.diagnostics.stress.families import cases
from analogy.study.comparison import compare
from analogy.study.estimate import on_points
from analogy.study.netlist_check import netlist_estimate, refined_netlist, spice_number
from analogy.solvers.transient import netlist

#: Every check here runs SPICE: the engine pass (ngspice 46) runs them too.
pytestmark = pytest.mark.ngspice


def cli(*args):
    return subprocess.run([sys.executable, "-m", "analogy", *args], capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("preset", ["fast", "accurate"])
def test_the_trapezoidal_error_falls_as_the_square_of_the_step_so_the_refined_run_errs_a_quarter(preset):
    # Richardson's premise on the default arm: with every step halved, SPICE's error falls 4 times
    # (h² of the trapezoidal rule); the measured ratio must lie within the factor the estimate allows.
    system = scene("default").system()
    first = compare(system, preset, ("spice",)).max_relative_error("spice")
    second = compare(system, refined(PRESETS[preset]), ("spice",)).max_relative_error("spice")
    assert REFINE ** 2 / AGREEMENT < first / second < REFINE ** 2 * AGREEMENT


@pytest.mark.parametrize("preset", ["fast", "accurate"])
def test_the_estimate_lies_within_a_factor_of_three_of_the_true_error(preset):
    c = compare(scene("default").system(), preset, estimate=True)
    for solver in ("spice", "ode"):
        true, est = c.measured[solver].relative, c.estimated[solver].relative
        assert 1 / AGREEMENT <= est / true <= AGREEMENT, (solver, true, est)
    assert "exact" not in c.estimated          # a closed form has no refinement
    assert c.results["spice"].estimated is c.estimated["spice"]           # every trajectory carries its own
    assert "estimated error" in repr(c.results["ode"]) and c.results["exact"].estimated is None
    assert "estimated" in c.table()


#: fast with a step budget under what the phase cap asks of the circuits below (23,351 points for
#: ten undamped periods, 79,085 for the stiff light pair): the cap is not bought, so the first run
#: keeps the calibrated step and misses the bound, as a circuit past its budget does.
# fast's own settings (not the reltol a circuit's truncation model would choose, which keeps the bound),
# with a step budget the phase cap cannot be paid from: a run that misses its bound
FAST_PAST_BUDGET = replace(PRESETS["fast"], budget=replace(PRESETS["fast"].budget, steps=10_000),
                           spice=replace(PRESETS["fast"].spice, calibrated=False))


def test_without_a_reference_the_estimate_alone_judges_the_bound():
    # ten undamped periods, the phase cap past the budget: SPICE's phase error reaches 7e-2 of the peak
    case = next(cases("c", quick=True))
    c = compare(case.build(), FAST_PAST_BUDGET, ("spice",), reference=None, estimate=True)
    assert c.reference is None and not c.measured
    est = c.estimated["spice"].relative
    assert est > 1e-3
    assert c.outside_bound() == {"spice": est}
    assert "no reference: errors estimated by refined runs" in c.table()


def test_a_spline_between_breakpoints_reads_a_piecewise_cubic_exactly():
    # a corner at t = 1 (a force's step): the spline must not span it
    t = np.concatenate([np.linspace(0, 1, 7), np.linspace(1, 2, 9)[1:]])
    f = np.where(t < 1, t ** 3, 1 + 3 * (t - 1) - (t - 1) ** 2)
    tr = Trajectory("spice", t, f[:, None], f[:, None])
    at = np.linspace(0, 2, 101)
    want = np.where(at < 1, at ** 3, 1 + 3 * (at - 1) - (at - 1) ** 2)
    got = on_points(tr, at, np.array([1.0]))[:, 0]
    assert np.max(np.abs(got - want)) < 1e-14 * 16     # rounding of a 16-point spline solve
    across = on_points(tr, at, np.array([]))[:, 0]      # spanning the corner: an O(h) error near it
    assert np.max(np.abs(across - want)) > 1e-3


def test_spice_numbers_take_their_suffixes():
    assert spice_number("1m") == 1e-3
    assert spice_number("10meg") == 1e7
    assert spice_number("2.5uF") == pytest.approx(2.5e-6, rel=2.3e-16)     # one rounding of the product
    assert spice_number("-1e-3") == -1e-3
    with pytest.raises(Exception, match="not a SPICE number"):
        spice_number("x1")


def test_the_refined_netlist_halves_the_cap_and_tightens_the_step_control_eightfold():
    text = netlist(scene("default").system(), "fast")
    fine = refined_netlist(text)
    opts = dict(t.partition("=")[::2] for line in text.splitlines() if line.startswith(".options")
                for t in line.split()[1:])
    finer = dict(t.partition("=")[::2] for line in fine.splitlines() if line.startswith(".options")
                 for t in line.split()[1:])
    assert finer.get("klu") == opts.get("klu") == ""          # a flag, kept as written
    for key in ("reltol", "vntol", "chgtol"):
        assert float(finer[key]) == pytest.approx(float(opts[key]) / REFINE ** 3, rel=1e-5)
    # abstol stays: where it binds it is the rounding floor, under which the step collapses
    assert finer["abstol"] == opts["abstol"]
    assert finer["trtol"] == opts["trtol"] and finer["method"] == opts["method"]
    tran = [line.split() for line in text.splitlines() if line.startswith(".tran")][0]
    tran2 = [line.split() for line in fine.splitlines() if line.startswith(".tran")][0]
    assert float(tran2[4]) == pytest.approx(float(tran[4]) / REFINE)
    assert ".control" not in fine and ".print" not in fine
    # without TMAX, ngspice's own cap min(TSTEP, TSTOP/50) is halved
    bare = refined_netlist("* t\nR1 n1 0 1\nC1 n1 0 1 ; a comment\n.option\n+ method=trap\n.tran 1m 1\n"
                           ".save v(n1)\n.end\n")
    assert ".tran 0.001 1.0 0.0 0.0005" in bare
    # ngspice's own reltol, vntol and chgtol, 8 times tighter, where the netlist leaves them out
    assert ".options reltol=0.000125 vntol=1.25e-07 chgtol=1.25e-15" in bare
    assert ".option method=trap" in bare and "comment" not in bare


def test_a_netlist_s_estimate_agrees_with_its_true_error_on_the_node_voltages():
    system = scene("default").system()
    text = netlist(system, "fast")
    est = netlist_estimate(text)
    # in process, ngspice's output starts after its first step: the exact solver needs t = 0 too
    exact = compare(system, "fast", ("exact",), times=np.concatenate([[0.0], est.time]),
                    reference=None).results["exact"].voltages[1:]
    for j, name in enumerate(("v(n1)", "v(n2)")):
        true = np.max(np.abs(est.values[name] - exact[:, j])) / np.max(np.abs(exact[:, j]))
        assert 1 / AGREEMENT <= est.estimates[name] / true <= AGREEMENT, (name, true, est.estimates[name])


def test_check_flags_a_fast_netlist_against_the_accurate_bound(tmp_path):
    fast, accurate = tmp_path / "fast.cir", tmp_path / "accurate.cir"
    assert cli("netlist", "--preset", "fast", "-o", str(fast)).returncode == 0
    assert cli("netlist", "-o", str(accurate)).returncode == 0
    res = cli("check", str(accurate))
    assert res.returncode == 0, res.stderr
    assert "v(n2)" in res.stdout
    res = cli("check", str(fast))
    assert res.returncode == 3
    assert "above the accurate preset's bound 1e-06" in res.stderr
    assert cli("check", str(fast), "--preset", "fast").returncode == 0
    res = cli("check", str(tmp_path / "missing.cir"))
    assert res.returncode == 2 and "Traceback" not in res.stderr


def test_the_estimates_agree_within_a_factor_of_three_and_never_claim_a_broken_bound_is_kept():
    # the quick bench scenes (2 and 10 joints) at both presets; every stress family in the deep pass
    report = validate_estimates(quick=True, families="", progress=False)
    assert len(report.rows) == 8
    assert not any(r.unsafe for r in report.rows)
    resolved = [r for r in report.rows if r.verdict != "unresolved"]
    assert resolved and all(r.verdict == "agrees" for r in resolved), report.table()


#: Runs whose estimate may miss the factor of three, and why (docs/estimates.md). On another processor
#: they may agree; they may never be unsafe.
ROUNDING_RUNS = {
    # rounding accumulates as n·ε·cond(M)·√steps (6 · 2.2e-16 · 1e8 · √20000 ≈ 2e-5), and grows as the
    # step shrinks: the estimate is 4 to 5 times the truth, on the safe side
    ("a: serial cond 1e+08", "spice", "accurate"): "rounding past the truncation error",
    ("a: parallel cond 1e+10", "spice", "accurate"): "rounding past the truncation error",
    # SPICE integrates these step responses to 1e-11 of the peak at fast: rounding again
    ("h: UR5 elbow, q3 = 1", "spice", "fast"): "rounding",
    ("h: UR5 wrist, q5 = 1", "spice", "fast"): "rounding",
    # the ODE within 6e-8 of a 1e6 to 1e8 separation of rates, where a 100 times tighter rtol repeats it
    ("b: ratio 1e+06 zeta 1", "ode", "accurate"): "an error the tighter tolerance repeats",
    ("b: ratio 1e+08 zeta 1", "ode", "accurate"): "an error the tighter tolerance repeats",
}


#: The stress families whose estimates are validated. Family i (the named robots at their
#: defaults) is not yet: the Z1's SPICE estimate at fast is 0.33 of its true error (1.85e-4),
#: under, on its 7th joint beside its fast decays.
VALIDATED_FAMILIES = "abcdefgh"


@pytest.mark.deep
def test_on_every_quick_bench_and_stress_scene_the_estimates_agree_but_where_rounding_rules():
    report = validate_estimates(quick=True, families=VALIDATED_FAMILIES, progress=False)
    assert not any(r.unsafe for r in report.rows), report.table()
    assert not any(r.verdict == "failed" for r in report.rows), report.table()
    misses = [r for r in report.rows if r.verdict in ("over", "under")
              and (r.scene, r.solver, r.preset) not in ROUNDING_RUNS]
    assert not misses, report.table()


def test_the_sufficient_subset_s_maximum_is_within_bernstein_s_factor_of_the_maximum_over_all_points():
    from analogy.study.grid import SUFFICIENT_PHASE, SUBSET_FROM, sufficient_points
    rng = np.random.default_rng(1)
    t = np.sort(np.concatenate([[0.0, 10.0], rng.uniform(0, 10, 3 * SUBSET_FROM)]))
    omega = 40.0
    rows = sufficient_points(t, omega, breakpoints=[2.5, 7.0])
    assert rows is not None and rows[0] == 0 and rows[-1] == t.size - 1
    assert np.any(t[rows] == t[np.searchsorted(t, 2.5) - 1])        # each corner's last point before it
    own = float(np.max(np.diff(t)))
    assert np.max(np.diff(t[rows])) <= SUFFICIENT_PHASE / omega + own
    reach = omega * float(np.max(np.diff(t[rows])))
    for phase in rng.uniform(0, 2 * np.pi, 20):        # content at rates up to ω: the worst case of the inequality
        e = np.sin(omega * t + phase) + 0.5 * np.sin(0.3 * omega * t)
        assert np.max(np.abs(e[rows])) >= (1 - reach / 2) * np.max(np.abs(e))
    assert sufficient_points(t[:SUBSET_FROM], omega) is None          # a short run keeps every point
    assert sufficient_points(t, 1e9) is None                          # no fewer points: kept whole


def test_a_long_run_is_measured_on_its_sufficient_subset_within_bernstein_s_factor_of_all_its_points():
    from dataclasses import replace
    from analogy.circuit.scales import system_scales
    from analogy.presets import PRESETS
    from analogy.results.metrics import output_errors
    from analogy.solvers.exact import solve_exact
    from analogy.solvers.spice import solve_spice
    from analogy.study.grid import SUBSET_FROM
    # the default arm over 100 s with a step cap of 5e-4 s: 2·10⁵ SPICE points, the subset a tenth of them
    system = scene("default").system().driven(None, 100.0)
    p = replace(PRESETS["fast"], spice=replace(PRESETS["fast"].spice, max_steps=200_000, calibrated=False))     # the cap as given
    c = compare(system, p, ("spice", "exact"))
    spice = c.results["spice"]
    assert spice.stats.steps > SUBSET_FROM and spice.time.size < spice.stats.steps / 2
    assert "measured on" in spice.message
    whole = solve_spice(system, preset=p)
    _, rel = output_errors(whole.rates, solve_exact(system, whole.time).rates)
    reach = system_scales(system).fastest(p.bound) * float(np.max(np.diff(spice.time)))
    sub = c.max_relative_error("spice")
    assert (1 - reach / 2) * np.max(rel) <= sub <= np.max(rel) * (1 + 1e-12)


def test_an_output_on_a_decay_the_steps_do_not_resolve_gets_no_estimate_and_no_claim():
    # a critically damped mode 10⁴ times faster than the slow one, 1.2e-4 of the peak velocity: fast's
    # step cap leaves it to ngspice (under 10·bound), yet it is all of r2, whose own error is 130 times its
    # peak; halving the steps repeats the same ringing, so Richardson's difference would say 4e-4
    case = next(c for c in cases("b") if c.label == "ratio 1e+04 zeta 1")
    c = compare(case.build(), "fast", ("spice",), reference=None, estimate=True)
    assert math.isnan(c.estimated["spice"].relative)
    assert "r2 may move on a decay" in c.unestimated["spice"]
    assert c.outside_bound() == {"spice": math.inf}
    resolved = compare(scene("default").system(), "fast", ("spice",), reference=None, estimate=True)
    assert resolved.unestimated == {} and resolved.outside_bound() == {}


def test_a_scene_asks_for_estimates_and_keeps_its_key_when_it_does_not(tmp_path):
    from analogy.batch.run import run_batch
    from analogy.scenes.run import run_scene
    from analogy.scenes.toml import load_scene
    base = scene("default")
    assert base.replace(estimate=False).key == base.key != base.replace(estimate=True).key
    path = tmp_path / "s.toml"
    path.write_text('name = "e"\n[model]\nrobot = "serial2"\n[configuration]\nq = [0.0, 0.3]\n'
                    '[inputs]\nforces = ["step(1)", "step(0.5)"]\n'
                    '[solvers]\nuse = ["spice"]\npreset = "fast"\nerrors = false\nestimate = true\n')
    sc = load_scene(path)
    assert sc.estimate and not sc.errors
    result = run_scene(sc)
    assert result.comparison.reference is None and "spice" in result.comparison.estimated
    with pytest.raises(Exception, match="does not estimate"):
        run_batch([sc], "fast")
    # refine = true: a key of its own, run by itself, refused by a batch
    assert base.replace(refine=False).key == base.key != base.replace(refine=True).key
    path.write_text(path.read_text().replace("estimate = true", "refine = true"))
    sc = load_scene(path)
    assert sc.refine and not sc.estimate
    assert "spice" in run_scene(sc).comparison.estimated
    with pytest.raises(Exception, match="does not estimate"):
        run_batch([sc], "fast")


def _stiff_light_pair():
    # two modes 100 times apart, ζ = 0.01: at fast the first run errs 2.3e-2 of r2's peak, 23 times the bound
    return next(c for c in cases() if c.label == "ratio 1e+02 zeta 0.01").build()


@pytest.mark.deep                   # 11 s: in CI's deep pass
def test_a_run_past_its_bound_is_refined_until_its_estimate_meets_it_and_the_truth_agrees():
    """refine: the run reported is the first whose estimated error meets the bound; its true error
    against the exact solution meets the bound too, and lies within the estimate's factor of 3."""
    system = _stiff_light_pair()
    plain = compare(system, FAST_PAST_BUDGET, ("spice",))
    assert plain.max_relative_error("spice") > plain.bound           # the premise: the first run misses
    c = compare(system, FAST_PAST_BUDGET, ("spice",), refine=True, save=("C1",), positions=True)
    true, est = c.max_relative_error("spice"), c.estimated["spice"].relative
    tr = c.results["spice"]     # the refined run keeps what the first was asked for
    assert tr.currents["C1"].shape == tr.time.shape
    assert est <= c.bound and true <= c.bound
    assert true / AGREEMENT <= est <= true * AGREEMENT
    assert "to meet the bound" in tr.message and tr.stats.steps > REFINE * plain.results["spice"].stats.steps
    assert not c.outside_bound()


def test_refine_leaves_a_run_within_its_bound_as_it_was():
    """A run whose estimate already meets the bound is not run again beyond its estimate."""
    system = scene("default").system()
    a = compare(system, "fast", ("spice",), estimate=True)
    b = compare(system, "fast", ("spice",), refine=True)
    assert b.results["spice"].stats.steps == a.results["spice"].stats.steps
    assert b.estimated["spice"].relative == a.estimated["spice"].relative
    assert "refined" not in b.results["spice"].message


def test_refine_applies_to_one_dynamics_only():
    r = cli("compare", "--dynamics", "both", "--refine", "--no-plot")
    assert r.returncode == 2 and "Traceback" not in r.stderr and "--refine" in r.stderr


def _large_motions():
    """serial2 and serial3 under gravity, step and sine torques at three poses, and three joints spun
    by a constant torque without gravity (18.8 to 32 rad): 15 motions of 10 s at `accurate`."""
    poses = {"serial2": [(0.0, 0.0), (0.5, -0.8), (1.5708, 0.0)],
             "serial3": [(0.0, 0.0, 0.0), (0.5, -0.8, 0.3), (1.5708, 0.0, 0.0)]}
    torques = {"serial2": {"step": ("step(3)", "step(1)"), "sine": ("sine(0, 3, 0.5)", "sine(0, 1, 0.3)")},
               "serial3": {"step": ("step(3)", "step(1)", "step(0.3)"),
                           "sine": ("sine(0, 3, 0.5)", "sine(0, 1, 0.3)", "sine(0, 0.3, 0.7)")}}
    out = [(f"{r} {kind} q={q}", Scene.of(r, ModelSpec(robot=r), q=q, forces=f, dynamics="nonlinear",
                                          parameters={"g": 9.81}))
           for r in poses for kind, f in torques[r].items() for q in poses[r]]
    spins = [("serial2", (0.0, 0.0), ("step(0)", "step(2)")), ("serial2", (0.5, -0.8), ("step(0)", "step(2)")),
             ("serial3", (0.0, 0.0, 0.0), ("step(0)", "step(0)", "step(1)"))]
    return out + [(f"{r} spin q={q}", Scene.of(r, ModelSpec(robot=r), q=q, forces=f, dynamics="nonlinear"))
                  for r, q, f in spins]


@pytest.mark.deep
@pytest.mark.parametrize("label, sc", _large_motions(), ids=[label for label, _ in _large_motions()])
def test_a_large_motion_holds_the_bound_once_refined_or_its_estimate_says_it_does_not(label, sc):
    """At `accurate` these miss 1e-6 against the DOP853 reference (measured: 2.2e-6 to 1.8e-5). Refined,
    it meets the bound, or its estimate (which the nonlinear circuit's error floor stops from falling
    as h²) still exceeds it and says so; the estimate never claims the bound where the truth is 3 times it."""
    c = compare(sc.system(), "accurate", ("spice",), reference="reference", refine=True)
    true, est = c.max_relative_error("spice"), c.estimated["spice"].relative
    assert true <= c.bound or (est > c.bound and "still exceeds the bound" in c.results["spice"].message)
    assert not (est <= c.bound and true > AGREEMENT * c.bound)
    assert true / AGREEMENT <= est        # on the safe side of the factor


@pytest.mark.deep                   # 12 s: in CI's deep pass
def test_a_scene_s_netlist_file_is_the_refined_run_it_reports(tmp_path, monkeypatch):
    """With refine = true the written netlist is the run reported: its step cap, not the preset's."""
    from analogy.scenes.run import run_scene
    from analogy.scenes.toml import load_scene
    monkeypatch.setitem(PRESETS, "fast", FAST_PAST_BUDGET)      # a first run that misses (see above)
    path = tmp_path / "pair.toml"        # the stiff, lightly damped pair above, as a scene file
    path.write_text('name = "pair"\n[model]\nmass = [[1.0, 0.2], [0.2, 1.0]]\ndamping = [0.02, 2.0]\n'
                    'stiffness = [1.0, 10000.0]\n[configuration]\ntopology = "parallel"\n'
                    '[inputs]\nforces = [1.0, 1.0]\nt_stop = 10\n[outputs]\njoint_rates = true\nnetlist = "pair.cir"\n'
                    '[solvers]\nuse = ["spice", "exact"]\npreset = "fast"\nrefine = true\n')
    result = run_scene(load_scene(path), output_dir=tmp_path)
    tr = result.comparison.results["spice"]
    assert "refined" in tr.message
    tran = next(line.split() for line in (tmp_path / "pair.cir").read_text().splitlines() if line.startswith(".tran"))
    assert float(tran[4]) == pytest.approx(tr.settings.max_step, rel=1e-12)
    assert tr.settings.max_step < netlist_cap(load_scene(path).system(), "fast")


def netlist_cap(system, preset):
    return float(next(line.split() for line in netlist(system, preset).splitlines() if line.startswith(".tran"))[4])
