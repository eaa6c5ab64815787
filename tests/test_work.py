"""Work estimates: a run past the budget is refused in one sentence before it starts, and the budget can be raised."""

from dataclasses import replace

import pytest

import analogy
from analogy import InputError
from analogy.cli import main
from analogy.model.joint import JointSpace
from analogy.presets import PRESETS
from analogy.scenes.builtin import SCENES
from analogy.study.work import check_work, estimate_work


@pytest.mark.parametrize("args, fragment", [
    (["--t-stop", "1e9"], "about 1.2e+11 time points"),
    (["--force", "sine(0, 1, 1e9)", "--force", "1"], "the fastest rate, 6.28e+09 rad/s"),
    (["--force", "pulse(0, 1, 0, 1e-6, 1e-6, 5e-5, 1e-4)", "--force", "1"], "400,001 segments"),
    (["--mass", "[[1, 0], [0, 1]]", "--stiffness", "[1e15, 1]", "--preset", "fast"], "budget of 1e+07"),
])
def test_runs_past_the_budget_are_refused_before_they_start(capsys, args, fragment):
    assert main(["compare", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0] and "--budget" in err[0], err


def test_every_built_in_scene_is_far_inside_the_budget():
    for sc in SCENES.values():
        for p in PRESETS.values():
            assert estimate_work(sc.system(), p).points < 1e-3 * p.work_budget


def test_the_budget_is_raised_deliberately():
    system = analogy.node_system(JointSpace([[1.0]], [[1.0]]), forces=["sine(0, 1, 1e6)"], t_stop=10.0)
    with pytest.raises(InputError, match="time points"):
        check_work(system, PRESETS["fast"])
    assert check_work(system, replace(PRESETS["fast"], work_budget=1e9)).points > 1e7


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
