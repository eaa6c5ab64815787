"""Finite in, finite out: node forms that would leave the float range are refused by name, never passed on."""

import numpy as np
import pytest

import analogy
from analogy import InputError
from analogy.solvers.transient import netlist
from analogy.circuit.topology import serial, symmetric_part
from analogy.cli import main
from analogy.model.joint import JointSpace
from analogy.solvers.exact import solve_exact


def test_symmetrisation_cannot_overflow_and_keeps_subnormals():
    z = np.array([[1e308, 1.5e308], [1.5e308, 5e-324]])
    s = symmetric_part(z)
    assert np.all(np.isfinite(s)) and s[0, 1] == 1.5e308 and s[1, 1] == 5e-324
    skew = np.array([[1.0, 1e308], [-1e308, 1.0]])
    assert symmetric_part(skew)[0, 1] == 0.0


def test_huge_but_finite_dampers_give_their_resistors():
    s = analogy.node_system(JointSpace([[2, 0.3], [0.3, 1]], np.diag([1e308, 1e308])), forces=[1, 1])
    lines = [line for line in netlist(s).splitlines() if line.startswith("R")]
    assert lines == ["R1 n1 0 1e-308", "R2 n2 0 1e-308"]


def test_a_node_form_that_overflows_is_refused_by_name(capsys):
    code = main(["netlist", "--mass", "[[2, 0.3], [0.3, 1]]", "--damping", "[1e308, 1e308]",
                 "--topology", "serial"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "--damping: node damping matrix B' leaves the floating-point range at row 1, column 1" in err[0]


def test_node_stiffness_and_current_map_are_checked_too():
    with pytest.raises(InputError, match="node stiffness matrix K' leaves the floating-point range"):
        analogy.node_system(JointSpace(np.eye(2), np.zeros((2, 2)), np.diag([1e308, 1e308])),
                            forces=[1, 1], topology=serial(2))
    with pytest.raises(InputError, match="leaves the floating-point range"):
        analogy.node_system(JointSpace(np.eye(2)), forces=[1, 1], topology=np.diag([1e-200, 1e-200]))


def test_a_subnormal_mass_is_refused_before_its_inverse_overflows(capsys):
    assert main(["netlist", "--mass", "[[5e-324]]", "--force", "1"]) == 2
    assert "too close to singular" in capsys.readouterr().err


def test_the_exact_solution_fails_rather_than_return_inf():
    s = analogy.node_system(JointSpace([[1e-300]]), forces=[1e300], t_stop=1e9)
    with pytest.raises(analogy.SimulationError, match="leaves the floating-point range"):
        solve_exact(s)
    c = analogy.compare(s, "fast", ["exact"], reference="exact")
    assert "floating-point range" in c.failures["exact"]


def test_rates_past_the_float_range_are_refused_not_left_to_eigh():
    s = analogy.node_system(JointSpace(np.eye(4) * 1e-300, np.eye(4), np.diag([1, 1, 1, 2.4e8])),
                            forces=[0, 1, 11, 23], t_stop=1.0)
    with pytest.raises(InputError, match="rates .* leave the floating-point range"):
        netlist(s, "fast")
