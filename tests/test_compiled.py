"""Compiled models on disk: the same numbers as the symbolic model, without sympy."""

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
