"""Golden ngspice outputs of the paper's five netlists (made by tests/golden/make_golden.py)."""

from pathlib import Path

import numpy as np
import pytest

from analogy.results.metrics import relative_error
from analogy.scenes.builtin import PAPER_EXAMPLES, scene
from analogy.solvers.exact import solve_exact
from analogy.solvers.rawfile import read_raw
from analogy.solvers.spice import session, solve_spice

GOLDEN = Path(__file__).resolve().parent / "golden"
NETLISTS = GOLDEN.parent.parent / "netlists"


def golden(name):
    data = read_raw(GOLDEN / f"{name}.raw")
    system = scene(name).system()
    return system, data["time"], np.column_stack([data[n] for n in system.nodes])


@pytest.mark.parametrize("name", PAPER_EXAMPLES)
def test_golden_output_is_the_exact_solution_within_the_accurate_bound(name):
    """ngspice's stored output, on the print step, is within 1e-6 of the exact solution."""
    system, t, v = golden(name)
    tran = next(ln for ln in (NETLISTS / f"{name}.cir").read_text().splitlines() if ln.startswith(".tran"))
    per_preset_step = round(float(tran.split()[2]) / float(tran.split()[1]) / 1000)   # a divisor of t_stop/1000
    assert t[0] == 0.0 and t.size == 1000 * per_preset_step + 1
    assert abs(t[-1] - system.t_stop) <= 1e-9 * system.t_stop
    assert relative_error(v, solve_exact(system, t).voltages) <= 1e-6


@pytest.mark.ngspice
@pytest.mark.parametrize("name", PAPER_EXAMPLES)
def test_in_process_run_reproduces_the_golden_output(name):
    """The committed netlist run in process gives the stored output: to 1e-8 with the
    ngspice version that made it (measured 6e-10 at worst; the rest is the interpolation
    onto the print step), and within the accurate bound with any other."""
    system, t, v = golden(name)
    assert (NETLISTS / f"{name}.cir").read_text().count(".tran") == 1
    tr = solve_spice(system, "accurate")
    here = np.column_stack([np.interp(t, tr.time, tr.voltages[:, j]) for j in range(system.dof)])
    made_by = (GOLDEN / f"{name}.txt").read_text()
    same = f"ngspice-{session().version} " in made_by
    assert relative_error(here, v) <= (1e-8 if same else 1e-6)
