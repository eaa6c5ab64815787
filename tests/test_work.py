"""Work estimates: a run past the budget is refused in one sentence before it starts, and the budget can be raised."""

import os
from dataclasses import replace

import numpy as np

import pytest

import analogy
from analogy import InputError
from analogy.cli import main
from analogy.model.joint import JointSpace
from analogy.presets import PRESETS
from analogy.scenes.builtin import SCENES
from analogy.study.work import check_work, estimate_work
from hang_guard import finishes


@pytest.mark.parametrize("args, fragment", [
    (["--t-stop", "1e9"], "about 3.83e+09 time points"),   # the 1.91/s decay at β·h = 0.5
    (["--force", "sine(0, 1, 1e9)", "--force", "1"], "the fastest rate, 6.28e+09 rad/s"),
    (["--force", "pulse(0, 1, 0, 1e-6, 1e-6, 5e-5, 1e-4)", "--force", "1"], "400,001 segments"),
    (["--mass", "[[1, 0], [0, 1]]", "--stiffness", "[1e15, 1]", "--preset", "fast"], "budget of 1e+07"),
])
def test_runs_past_the_budget_are_refused_before_they_start(capsys, args, fragment):
    assert main(["compare", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0] and "--budget" in err[0], err


@pytest.mark.parametrize("args, fragment", [
    # a joint turning at 1e5 rad/s for 10 s: 6.25e7 points at the accurate phase step of 0.016 rad
    (["--dynamics", "nonlinear", "--r0", "1e5, 0"], "6.25e+07 time points"),
    (["--dynamics", "nonlinear", "--r0", "1e5, 0", "--solvers", "ode,exact"], "for a nonlinear run"),
])
def test_a_nonlinear_run_past_the_budget_is_refused_before_it_starts(capsys, args, fragment):
    """A nonlinear point costs NONLINEAR_POINT_COST·n³ of SPICE's operations and as many of the
    points budget (M(q), c and G evaluated where a linear point multiplies): the run that went on
    past 90 s is one sentence now."""
    assert finishes(lambda: main(["compare", *args])) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0], err


def test_an_animation_has_the_work_guard_of_a_comparison(capsys, tmp_path):
    assert finishes(lambda: main(["animate", "--t-stop", "1e8", "--frames", "10", "-o", str(tmp_path / "a.gif")])) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "time points" in err[0] and not (tmp_path / "a.gif").exists(), err


def test_every_named_robot_runs_nonlinear_inside_the_budget():
    from analogy.model.urdf_robots import URDF_ROBOTS
    for name in ("serial2", "serial3", "parallel2", "flexpar", *URDF_ROBOTS):
        system = analogy.scene(name).replace(dynamics="nonlinear").system()
        for p in PRESETS.values():
            check_work(system, p)


def test_every_built_in_scene_is_far_inside_the_budget():
    for sc in SCENES.values():
        for p in PRESETS.values():
            assert estimate_work(sc.system(), p).points < 1e-3 * p.budget.points


def test_the_budget_is_raised_deliberately():
    system = analogy.node_system(JointSpace([[1.0]], [[1.0]]), forces=["sine(0, 1, 1e6)"], t_stop=10.0)
    with pytest.raises(InputError, match="time points"):
        check_work(system, PRESETS["fast"])
    assert check_work(system, replace(PRESETS["fast"], budget=replace(PRESETS["fast"].budget, points=1e10))).points > 1e7


def test_the_cli_budget_must_be_a_count(capsys):
    assert main(["compare", "--budget", "0"]) == 2
    assert "--budget must be at least 1" in capsys.readouterr().err


def test_the_guard_holds_on_the_batch_path_too():
    """compare_many refuses what compare refuses, for the fastest system of a stack: the
    error concerns the budget, and names no command-line flag (the front end adds it)."""
    from analogy.study.comparison import compare_many
    sc = SCENES["default"].replace(t_stop=1e8)
    systems = sc.systems([[0.0, q] for q in (0.1, 0.3, 0.5)])
    with pytest.raises(InputError, match="time points") as caught:
        compare_many(systems, "fast", ["spice", "exact"])
    assert caught.value.field == "budget" and "--" not in str(caught.value)


def test_a_sweep_past_the_budget_stores_each_scene_as_refused(tmp_path):
    """analogy batch: every scene refused by the guard is stored as refused with its sentence."""
    import pandas as pd
    sweep = tmp_path / "long.toml"
    sweep.write_text('name = "long"\n[model]\nrobot = "serial2"\n[inputs]\nforces = ["step(1)", "step(0.5)"]\n'
                     't_stop = 1e8\n[solvers]\nuse = ["spice", "exact"]\npreset = "fast"\n[sweep]\n'
                     'method = "grid"\n[sweep.axes]\nq2 = { low = 0.1, high = 0.5, count = 3 }\n')
    main(["batch", str(sweep), "-o", str(tmp_path / "store"), "--no-progress", "--workers", "1"])
    frame = pd.read_parquet(tmp_path / "store")
    assert frame["status"].tolist() == ["refused"] * 3
    assert all("time points" in m and "work budget" in m for m in frame["message"])


@pytest.mark.parametrize("pattern, operations", [
    ("dense", lambda n: n ** 3),                            # every node coupled to all n
    ("diagonal", lambda n: n),                              # each node alone
    ("tridiagonal", lambda n: 2 * 2 ** 2 + (n - 2) * 3 ** 2),   # end rows couple 2, inner rows 3
])
def test_a_spice_point_costs_the_sum_of_squared_couplings(pattern, operations):
    """Σᵢ cᵢ², the work of a sparse LU whose fill stays in the pattern of M', B' and K'."""
    from analogy.circuit.elements import point_operations
    n = 12
    mass = {"dense": np.full((n, n), 0.1) + np.eye(n), "diagonal": np.eye(n),
            "tridiagonal": np.eye(n) + 0.3 * (np.eye(n, k=1) + np.eye(n, k=-1))}[pattern]
    system = analogy.node_system(JointSpace(mass, np.eye(n)), t_stop=1.0)
    assert point_operations(system) == operations(n)


def test_a_circuit_too_large_for_spice_is_refused_and_runs_without_it():
    """A dense 400-node circuit at accurate takes at least 2,000 points whatever its t_stop (two per print
    step t_stop/1000): 400³·2004 = 1.3e11 operations, past the budget of 5e10; the ODE and exact solvers
    still take it."""
    n = 400
    mass = np.full((n, n), 0.5) + np.eye(n)
    system = analogy.node_system(JointSpace(mass, np.eye(n)), topology="parallel", t_stop=0.01)     # dense
    p = PRESETS["accurate"]
    with pytest.raises(InputError, match=r"400 nodes\) would need about 1.28e\+11 operations") as caught:
        check_work(system, p)
    assert "shorten t_stop" not in str(caught.value) and caught.value.field == "budget"
    assert check_work(system, p, spice=False).points == 2 * p.steps + 4     # 4 points for its one force segment
    assert check_work(system, replace(p, budget=replace(p.budget, operations=2e11))).operations == pytest.approx(n ** 3 * 2004, rel=1e-3)


def test_every_built_in_scene_is_far_inside_the_operation_budget():
    for sc in SCENES.values():
        for p in PRESETS.values():
            assert estimate_work(sc.system(), p).operations < 1e-2 * p.budget.operations


@pytest.mark.ngspice
@pytest.mark.slow
def test_sigterm_stops_a_long_spice_run_at_once():
    """serial200's serial circuit over ngspice's 20,000 points is 200³·2e4 = 1.6e11 operations (a quarter of an
    hour at the 1.7e8 a second measured here, minutes on any machine): SIGTERM in the middle ends
    the command with exit 130. The only bound on time is the hang guard of communicate, which
    only a run that went on to its end could reach."""
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path
    proc = subprocess.Popen([sys.executable, "-m", "analogy", "compare", "--robot", "serial200", "--topology",
                             "serial", "--solvers", "spice", "--no-plot", "--budget", "1e9"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        ticks = os.sysconf("SC_CLK_TCK")
        end = time.monotonic() + 300    # a hang guard only
        while proc.poll() is None and time.monotonic() < end:      # 3 s of CPU: built, inside ngspice
            if int(Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()[11]) > 3 * ticks:
                break
            time.sleep(0.1)
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 130 and "interrupted" in err, err
    finally:
        proc.kill()
        proc.wait()


def test_a_take_refused_past_the_operation_budget_is_worded_from_its_own_first_row():
    """A take of a stack is checked on the inputs its rows share, but a refusal is said of the take's
    first row: whether a shorter t_stop would help reads that row's own scales. parallel3 with a soft
    first spring is calibrated at accurate where the stiffer rows ring, so the stack's first row and
    the take's would word it differently."""
    from analogy.circuit.scales import run_scales
    from analogy.scenes.builtin import scene
    from analogy.study.work import _fewest, check_works
    p3 = scene("parallel3")
    k = np.array([0.01, 0.1, 0.1, 0.1])
    stack = p3.systems(np.tile(p3.q, (4, 1)), parameters={"k1": k, "k2": k, "k3": k})
    assert stack.shares_inputs
    take, acc = stack.take([1, 2, 3]), PRESETS["accurate"]
    assert _fewest(take[0], acc) != _fewest(stack[0], acc)     # the hint would differ
    tight = replace(acc, budget=replace(acc.budget, operations=1e6))
    with pytest.raises(InputError) as refused:
        check_works(take, tight)
    with pytest.raises(InputError) as alone:        # the same rows as a stack of their own
        check_work(take[0], tight, run_scales(take), stacked=3)
    assert str(refused.value) == str(alone.value)
