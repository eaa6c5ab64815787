"""Node coordinates: M' = T⁻ᵀ·M·T⁻¹, i = T⁻ᵀ·F, and the element decomposition."""

import numpy as np
import pytest
import sympy as sp

from analogy import elements, mp_capacitance, node_system, robot
from analogy.circuit.elements import laplacian_split
from analogy.circuit.topology import congruence, custom, serial
from analogy.model.joint import JointSpace
from analogy.model.robots import random_spd_model

RNG = np.random.default_rng(7)


def random_spd(n):
    a = RNG.normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 3, 7, 12])
@pytest.mark.parametrize("kind", ["serial", "parallel", "custom"])
def test_energy_and_power_are_invariant(n, kind):
    """½rᵀMr = ½vᵀM'v, rᵀBr = vᵀB'v and Fᵀr = iᵀv for v = T·r, i = T⁻ᵀ·F."""
    m, b = random_spd(n), np.diag(RNG.uniform(0.1, 2, n))
    top = custom(RNG.normal(size=(n, n)) + 3 * np.eye(n)) if kind == "custom" else kind
    s = node_system(JointSpace(m, b), topology=top, forces=[1.0] * n)
    r, f = RNG.normal(size=n), RNG.normal(size=n)
    v, i = s.topology.matrix @ r, s.current_map @ f
    assert v @ s.mass @ v == pytest.approx(r @ m @ r, rel=1e-12)
    assert v @ s.damping @ v == pytest.approx(r @ b @ r, rel=1e-12)
    assert i @ v == pytest.approx(f @ r, rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(s.joint_rates(v), r, rtol=1e-12, atol=1e-12)


def test_serial_nodes_carry_cumulative_rates():
    """Serial topology: v_k = r_1 + … + r_k (eqs. 13, 31) and i_k = f_k − f_{k+1}."""
    t = serial(4).matrix
    r = np.array([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(t @ r, np.cumsum(r))
    f = np.array([5.0, 3.0, 2.0, 1.0])
    np.testing.assert_array_equal(serial(4).current_map @ f, [2.0, 1.0, 1.0, 1.0])


def test_parallel_node_system_is_the_joint_system():
    m = random_spd(3)
    s = node_system(JointSpace(m, np.eye(3)), topology="parallel", forces=[0, 0, 0])
    np.testing.assert_allclose(s.mass, m, rtol=1e-15)


def test_symbolic_congruence_matches_numeric():
    """The symbolic 2-DOF serial M' is T⁻ᵀMT⁻¹ with entries m1 − 2m3 + m2, m3 − m2, m2."""
    m1, m2, m3 = sp.symbols("m1 m2 m3")
    mm = sp.Matrix([[m1, m3], [m3, m2]])
    mp_ = congruence(mm, sp.Matrix(serial(2).matrix.astype(int)))
    assert sp.simplify(mp_ - sp.Matrix([[m1 - 2 * m3 + m2, m3 - m2], [m3 - m2, m2]])) == sp.zeros(2)


@pytest.mark.parametrize("n", [2, 5, 10])
def test_elements_rebuild_the_node_matrices(n):
    """X_ii = x_i + Σ_j x_ij and X_ij = −x_ij: the circuit's nodal matrix is M' (and B', K')."""
    model = random_spd_model(n, seed=n, stiffness=True)
    s = node_system(model, forces=[1.0] * n)
    for kind, mat in (("C", s.mass), ("R", s.damping), ("L", s.stiffness)):
        rebuilt = np.zeros((n, n))
        for e in elements(s):
            if e.kind != kind:
                continue
            a = e.a - 1
            if e.floating:
                b = e.b - 1
                rebuilt[a, a] += e.coefficient
                rebuilt[b, b] += e.coefficient
                rebuilt[a, b] -= e.coefficient
                rebuilt[b, a] -= e.coefficient
            else:
                rebuilt[a, a] += e.coefficient
            expect = e.coefficient if kind == "C" else 1.0 / e.coefficient
            assert e.value == pytest.approx(expect, rel=1e-15)
        np.testing.assert_allclose(rebuilt, mat, rtol=1e-12, atol=1e-12 * np.abs(mat).max())


def test_zero_elements_are_left_out_with_explicit_tolerance():
    x = np.array([[2.0, -1.0, 1e-17], [-1.0, 1.0, 0.0], [1e-17, 0.0, 3.0]])
    grounded, floating = laplacian_split(x, zero_tol=1e-12)
    assert grounded[1] == 0.0 and floating[0, 2] == 0.0 and floating[0, 1] == 1.0
    _, kept = laplacian_split(x, zero_tol=0.0)
    assert kept[0, 2] == -1e-17


def test_serial_2dof_mp_capacitance_is_negative_between_minus_and_plus_half_pi():
    """p'12 = m2 − m3 = −l1·l2·d2·cos(q2): negative for |q2| < π/2, zero at ±π/2."""
    model = robot("serial2")
    p = model.parameters
    for q2 in np.linspace(-np.pi, np.pi, 41):
        s = node_system(model, [0.0, q2], forces=[0, 0])
        c12 = mp_capacitance(s.mass)[0, 1]
        expect = -p["l1"] * p["l2"] * p["d2"] * np.cos(q2)
        assert c12 == pytest.approx(expect, abs=1e-12)
    s = node_system(model, [0.0, np.pi / 2], forces=[0, 0])
    assert mp_capacitance(s.mass)[0, 1] == 0.0


def test_redundant_actuators_decouple_in_node_coordinates():
    """Two stages on one axis: M' = diag(d1, d2), so no MP model is needed (Fig. 9)."""
    model = robot("redundant")
    s = node_system(model, [0.0, 0.0], forces=[0, 0])
    np.testing.assert_allclose(s.mass, np.diag([model.parameters["d1"], model.parameters["d2"]]),
                               atol=1e-15)
    assert not any(e.kind == "C" and e.floating for e in elements(s))


def test_gravity_enters_as_a_constant_force():
    m = random_spd(2)
    s = node_system(JointSpace(m, np.eye(2), gravity=[0.5, -0.25]), forces=[1.0, 0.0])
    np.testing.assert_allclose(s.force([0.0, 3.0]), [[0.5, 0.25], [0.5, 0.25]])


def test_the_horizon_and_forces_are_the_solves_own_inputs_and_gravity_stays():
    """solve(system, t_stop=T, forces=F) is the solve of the system built with T and F: the
    same matrices, gravity's constant −G still on the forces, and the system itself untouched."""
    from analogy import solve
    model = robot("serial2")
    q, params = [0.3, -0.7], {"g": 9.81}
    system = node_system(model, q, parameters=params, forces=["step(1)", 0], t_stop=2.0)
    built = node_system(model, q, parameters=params, forces=["sine(0, 2, 1.5)", "pulse(0, 1, 0.5)"], t_stop=3.0)
    t = np.linspace(0.0, 3.0, 301)
    given = solve(system, "exact", t, t_stop=3.0, forces=["sine(0, 2, 1.5)", "pulse(0, 1, 0.5)"])
    assert np.array_equal(given.rates, solve(built, "exact", t).rates)      # one computation, the same inputs
    assert system.t_stop == 2.0 and system.forces[0][0].label() == "step(1)"
    assert len(system.driven(t_stop=5.0).forces[1]) == len(system.forces[1])     # −G is kept once, not again


def test_a_driven_stack_responds_linearly_to_its_forces():
    """Superposition: from rest and without gravity, twice the forces give twice the rates on
    every row of a stack, to rounding: each exact solve is within n·ε·cond(M')·peak, so
    |R₂ − 2R₁| ≤ (1 + 2)·n·ε·cond(M')·peak."""
    from analogy import compare_many, node_systems
    model = robot("serial2")
    qs = np.column_stack([np.zeros(4), np.linspace(-2.0, 2.0, 4)])
    stack = node_systems(model, qs, forces=["step(1)", "sine(0, 1, 2)"], t_stop=2.0)
    one = compare_many(stack, "fast", ("exact",), reference=None)
    two = compare_many(stack, "fast", ("exact",), reference=None, t_stop=2.0,
                       forces=["step(2)", "sine(0, 2, 2)"])
    for a, b, s in zip(one, two, stack):
        bound = 3 * s.dof * np.finfo(float).eps * np.linalg.cond(s.mass) * np.max(np.abs(b.results["exact"].rates))
        assert np.max(np.abs(b.results["exact"].rates - 2 * a.results["exact"].rates)) <= bound
        assert b.system.forces[0][0].label() == "step(2)"


@pytest.mark.parametrize("t_stop", [0.0, -1.0, float("nan"), 1e12, "soon"])
def test_a_horizon_out_of_range_is_one_sentence_about_t_stop(t_stop):
    from analogy import InputError
    with pytest.raises(InputError, match="^t_stop must be a time between") as info:
        node_system(robot("serial2"), [0.0, 0.0]).driven(t_stop=t_stop)
    assert info.value.field == "t_stop"
