"""Compiled models on disk: the same numbers as the symbolic model, without sympy."""

import os
import subprocess
import sys

import numpy as np
import pytest

from analogy.model.compiled import cache_dir, compile_model, load_compiled
from analogy.model.robots import robot


@pytest.mark.parametrize("name", ["serial2", "serial3", "redundant"])
def test_compiled_model_equals_symbolic(name):
    model = robot(name)
    compiled = compile_model(model, name)
    assert compiled is not None
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, model.dof)
        a, b = model.joint_space(q), compiled.joint_space(q)
        np.testing.assert_array_equal(a.mass_matrix, b.mass_matrix)
        np.testing.assert_array_equal(a.damping, b.damping)


def test_damaged_cache_file_is_not_trusted():
    model = robot("serial2")
    compile_model(model, "serial2")
    for path in cache_dir().glob("model-*.py"):
        path.write_text("raise RuntimeError('damaged')\n")
    assert load_compiled("serial2") is None
    assert compile_model(model, "serial2") is not None


def test_cached_netlist_job_runs_without_sympy():
    code = ("import sys\nfrom analogy.cli import main\nmain(['netlist', '-o', '/dev/null'])\n"
            "main(['netlist', '-o', '/dev/null'])\nprint('sympy' in sys.modules)")
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    again = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert again.stdout.strip() == "False"      # the second process finds the compiled model


@pytest.mark.parametrize("args", [["--robot", "flex2"], ["--robot", "flex1", "--param", "l1=0.4"]])
def test_a_flexible_arm_is_compiled_per_parameter_set_and_a_later_process_needs_no_sympy(args, tmp_path):
    """Its mode shapes follow the parameters, so each set is compiled with its numbers in:
    the second process writes the same netlist from the cache, without sympy."""
    code = ("import sys\nfrom analogy.cli import main\n"
            f"main(['netlist', *{args!r}, '-o', sys.argv[1]])\nprint('sympy' in sys.modules)")
    env = dict(os.environ, ANALOGY_CACHE_DIR=str(tmp_path / "cache"))      # empty at first, whatever ran before
    runs = [subprocess.run([sys.executable, "-c", code, str(tmp_path / f"{k}.cir")], capture_output=True,
                           text=True, timeout=300, env=env) for k in range(2)]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr
    assert [r.stdout.strip() for r in runs] == ["True", "False"]
    assert (tmp_path / "0.cir").read_text() == (tmp_path / "1.cir").read_text()


def test_a_model_compiled_for_one_parameter_set_refuses_another():
    from analogy.errors import InputError
    from analogy.model.flexible import flexible_arm
    compiled = compile_model(flexible_arm(1), "flex1 test", baked=True)
    assert compiled.joint_space([0.0] * compiled.dof, {"l1": 0.5}) is not None      # its own values
    with pytest.raises(InputError, match="compiled for one parameter set"):
        compiled.joint_space([0.0] * compiled.dof, {"l1": 0.4})


def test_a_baked_model_refuses_parameters_that_vary_along_a_stack():
    """A sweep over a flexible arm's parameter is built scene by scene: one sentence, not a crash."""
    from analogy.errors import InputError
    from analogy.model.flexible import flexible_arm
    compiled = compile_model(flexible_arm(1), "flex1 stack test", baked=True)
    qs = np.zeros((2, compiled.dof))
    with pytest.raises(InputError, match="cannot vary along a stack"):
        compiled.joint_stack(qs, {"l1": np.array([0.5, 0.4])})


@pytest.mark.ngspice
def test_a_sweep_over_a_flexible_arm_s_parameter_runs(tmp_path, capsys):
    from analogy.cli import main
    sweep = tmp_path / "flex.toml"
    sweep.write_text('name = "flex"\n[model]\nrobot = "flex1"\n[configuration]\nq = [0, 0, 0]\n'
                     '[inputs]\nforces = [1, 0, 0]\nt_stop = 0.05\n[solvers]\nuse = ["ode", "exact"]\n'
                     '[sweep]\nmethod = "grid"\n[sweep.axes]\nl1 = [0.4, 0.5]\n')
    assert main(["batch", str(sweep), "-o", str(tmp_path / "store"), "--no-progress"]) == 0, capsys.readouterr()
    from analogy.batch.store import read
    rows = read(tmp_path / "store")
    assert list(rows["status"]) == ["ok", "ok"] and rows["l1"].tolist() == [0.4, 0.5]
    assert (rows["error_ode"] <= 1e-6).all()            # each arm, its own mode shapes, within the bound


def test_an_unknown_parameter_of_a_flexible_arm_is_named_in_one_sentence(capsys):
    """Its builder, which takes the parameters, names the ones it has; nothing else is derived first."""
    from analogy.cli import main
    assert main(["netlist", "--robot", "flex1", "--param", "zz=1"]) == 2
    err = capsys.readouterr().err
    assert "--param: model 'flex1' has no parameter 'zz' (it has: l1, rhoA1, EI1" in err and err.count("\n") == 1
