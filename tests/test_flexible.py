"""Flexible links by assumed modes: the chain's M(q), K and G, checked against beam theory and energy."""

import numpy as np
import pytest
import scipy.linalg as la
import sympy as sp

from analogy.circuit.nonlinear import nonlinear_system
from analogy.model.flexible import FlexibleLink, flexible_chain
from analogy.model.symbolic import velocity_terms
from analogy.solvers.ode import solve_ode

L, RHO_A, EI = 0.5, 0.4, 2.0


def lam(omega2):
    return (np.asarray(omega2) * RHO_A * L ** 4 / EI) ** 0.25


def test_a_link_with_its_hub_clamped_has_the_cantilevers_frequencies():
    """Locking θ leaves the modal block: βL = 1.8751, 4.6941, 7.8548."""
    js = flexible_chain([FlexibleLink(L, RHO_A, EI, modes=3)]).joint_space([0.0] * 4)
    w2 = la.eigh(js.stiffness[1:, 1:], js.mass_matrix[1:, 1:], eigvals_only=True)
    np.testing.assert_allclose(lam(w2), [1.875104069, 4.694091133, 7.854757438], rtol=1e-9)


def test_a_link_on_a_free_hub_converges_to_the_pinned_free_beam():
    """With a hub of zero inertia the first flexible mode tends to βL = 3.9266 as modes are added
    (measured: 1 mode 4.5317, 2: 3.92876, 3: 3.926754, 5: 3.926607, 8: 3.9266025)."""
    seen = []
    for modes in (1, 2, 3, 5, 8):
        js = flexible_chain([FlexibleLink(L, RHO_A, EI, modes=modes)]).joint_space([0.0] * (modes + 1))
        w2 = np.sort(np.abs(la.eigh(js.stiffness, js.mass_matrix, eigvals_only=True)))
        seen.append(float(lam(w2[1])))      # w2[0] is the rigid rotation
    assert all(a > b for a, b in zip(seen, seen[1:]))
    assert seen[-1] == pytest.approx(3.9266023, abs=1e-5)


def arm(gravity=9.81):
    links = [FlexibleLink(0.5, 0.4, 2.0, modes=2, hub_inertia=0.01, tip_mass=0.2, tip_inertia=1e-4),
             FlexibleLink(0.4, 0.3, 1.0, modes=2, tip_mass=0.1, tip_inertia=5e-5)]
    return flexible_chain(links, gravity=gravity)


def test_the_two_link_mass_matrix_is_symmetric_positive_definite_and_its_velocity_terms_do_no_work():
    """M(q) is SPD at random poses, and q̇ᵀ(½Ṁ − C)q̇ = 0 (checked numerically at random states)."""
    model = arm()
    rng = np.random.default_rng(2)
    q = list(model.coordinates)
    r = list(sp.symbols(f"r1:{len(q) + 1}", real=True))
    c = velocity_terms(model.mass_matrix, q, r)
    mdot = sum((model.mass_matrix.diff(qk) * r[k] for k, qk in enumerate(q)), sp.zeros(len(q), len(q)))
    for _ in range(3):
        point = dict(zip(q, rng.uniform(-0.3, 0.3, len(q)))) | dict(zip(r, rng.uniform(-1, 1, len(q))))
        m = np.array(model.mass_matrix.subs(point).tolist(), dtype=float)
        np.linalg.cholesky(m)
        rv = np.array([point[s] for s in r])
        work = rv @ np.array(c.subs(point).tolist(), dtype=float).ravel()
        half = 0.5 * rv @ np.array(mdot.subs(point).tolist(), dtype=float) @ rv
        assert work == pytest.approx(half, rel=1e-10)


@pytest.mark.deep                   # 10 s: in CI's deep pass
def test_the_free_flexible_arm_conserves_energy():
    """No damping, no input, gravity on: T + U stays constant to 1e-9 of the energy over 2 s."""
    s = nonlinear_system(arm(), [0.3, 0.5, 0, 0, 0, 0], forces=[0.0] * 6,
                         initial_rates=[1.0, -1.0, 0, 0, 0, 0], t_stop=2.0)
    tr = solve_ode(s, np.linspace(0, 2, 201), "DOP853", 1e-12, positions=True)
    residual, scale = s.energy_residual(tr)
    assert np.max(np.abs(residual)) <= 1e-9 * scale


def test_the_built_in_arm_is_rebuilt_when_a_parameter_changes():
    """modes2 = 3 adds a coordinate; doubling l1 and l2 (with their loads scaled away) divides the
    cantilever frequencies by 4, as ω ∝ l⁻²."""
    from analogy.model.flexible import flexible_arm
    arm2 = flexible_arm(2)
    assert arm2.joint_space([0.0] * 7, {"modes2": 3}).dof == 7
    bare = {"Jh1": 0.0, "mp": 0.0, "Jp": 0.0, "g": 0.0}
    short = flexible_arm(1, **bare).joint_space([0.0] * 3)
    long_ = flexible_arm(1, **bare).joint_space([0.0] * 3, {"l1": 1.0})
    w_short = la.eigh(short.stiffness[1:, 1:], short.mass_matrix[1:, 1:], eigvals_only=True)
    w_long = la.eigh(long_.stiffness[1:, 1:], long_.mass_matrix[1:, 1:], eigvals_only=True)
    np.testing.assert_allclose(np.sqrt(w_long), np.sqrt(w_short) / 4, rtol=1e-10)


def test_gravity_stiffness_is_the_hessian_of_the_potential_and_negative_above_the_horizontal():
    """A rigid link (modes1 = 0) of mass m, length l with payload mp: K = ∂G/∂θ = −g(m·l/2 + mp·l)·sin θ."""
    from analogy.model.flexible import flexible_arm
    arm1 = flexible_arm(1, modes1=0)
    m, l, mp, g = 0.54 * 0.5, 0.5, 0.1, 9.81
    for theta in (-0.5, 0.4):
        js = arm1.joint_space([theta])
        assert js.stiffness[0, 0] == pytest.approx(-g * (m * l / 2 + mp * l) * np.sin(theta), rel=1e-12)
        assert js.gravity[0] == pytest.approx(g * (m * l / 2 + mp * l) * np.cos(theta), rel=1e-12)
        assert js.unstable == (theta > 0)


def test_a_bent_link_carries_its_spring_force_in_the_static_load():
    """Modal coordinates rest at 0: linearised at δ0 the load is G(q0) + K·δ0."""
    from analogy.model.flexible import flexible_arm
    arm1 = flexible_arm(1, g=0.0)
    q0 = [0.2, 0.01, -0.002]
    js = arm1.joint_space(q0)
    k = np.array(arm1.stiffness.tolist(), dtype=float)
    np.testing.assert_allclose(js.gravity, k @ q0, rtol=1e-12)


def hanging_arm(g, t_stop):
    """flex2 at a hanging pose, joint dampers on."""
    from analogy.scenes.scene import Scene
    from analogy.scenes.spec import ModelSpec
    sc = Scene.of("arm", ModelSpec(robot="flex2"), q=[-0.6, 0.3, 0, 0, 0, 0], forces=[1, 1, 0, 0, 0, 0],
                  parameters={"g": g, "b1": 0.05, "b2": 0.05}, t_stop=t_stop)
    return sc.system()


@pytest.mark.parametrize("g", [9.81, 0.0])
def test_the_linearised_arm_integrated_by_the_ode_solver_matches_the_exact_solution(g):
    """DOP853 at accurate within 1e-9 of the peak over 2 s (measured 8.0e-12, and 1.6e-12 with
    g = 0): its atol follows each node's own scale, the small modal velocities too."""
    from analogy.presets import PRESETS
    from analogy.solvers.registry import run
    s = hanging_arm(g, 2.0)
    t = np.linspace(0, 2.0, 2001)
    exact, ode = (run(name, s, t, PRESETS["accurate"]) for name in ("exact", "ode"))
    assert np.max(np.abs(ode.rates - exact.rates)) <= 1e-9 * np.max(np.abs(exact.rates))


@pytest.mark.ngspice
@pytest.mark.deep       # about 40 s each: the step the 252 Hz mode's phase error asks over 2 s
@pytest.mark.parametrize("g", [9.81, 0.0])
def test_the_arm_as_a_circuit_keeps_the_accurate_bound_in_spice(g):
    """ngspice within 1e-6 of each output's own peak over 2 s of a 252 Hz mode: the step
    cap, first step and abstol follow the system's own scales, and the step its modes' phase
    error asks (the modal coordinates missed, 2.4e-5 of their own peak, at the fixed caps)."""
    from analogy.study.comparison import compare
    result = compare(hanging_arm(g, 2.0), "accurate", ["spice", "exact"])
    assert not result.failures
    assert result.errors()["spice"][1] <= 1e-6


@pytest.mark.ngspice
@pytest.mark.deep       # the same run as above
def test_the_arm_that_misses_its_bound_is_flagged_with_the_output_that_misses_it():
    """The promise is kept or flagged: the worst output is named, and outside_bound (exit 3) has it."""
    from analogy.study.comparison import compare
    result = compare(hanging_arm(9.81, 2.0), "accurate", ["spice", "exact"])
    name, worst = result.worst_output("spice")
    assert worst == max(result.errors()["spice"].per_output.values())
    assert (worst > 1e-6) == ("spice" in result.outside_bound())
    assert name in result.table()


def test_a_comparison_above_the_horizontal_says_the_equilibrium_is_unstable():
    """θ1 = 0.3 rad up: gravity's stiffness is negative; the exact solution grows and the report says so."""
    from analogy.study.comparison import compare
    from analogy.scenes.scene import Scene
    from analogy.scenes.spec import ModelSpec
    sc = Scene.of("up", ModelSpec(robot="flex1"), q=[0.3, 0, 0], forces=[0, 0, 0], t_stop=0.5)
    result = compare(sc.system(), "accurate", ["ode", "exact"])
    assert "unstable equilibrium" in result.table()
    rates = result.results["exact"].rates
    assert abs(rates[-1, 0]) > abs(rates[len(rates) // 2, 0]) > 0     # it falls, faster and faster
    assert result.errors()["ode"][1] <= 1e-9


def test_the_static_equilibrium_under_gravity_leaves_no_load_on_the_modes():
    """flex2 held at a pose: Newton on the modal rows of G + K·δ makes them vanish to rounding,
    the joints keep the holding torque; hanging straight down, nothing bends."""
    from analogy.model.equilibrium import elastic_coordinates, static_equilibrium
    from analogy.model.robots import robot
    arm2 = robot("flex2")
    assert elastic_coordinates(arm2) == [2, 3, 4, 5]
    q = static_equilibrium(arm2, [-0.6, 0.3, 0, 0, 0, 0])
    load = arm2.joint_space(q).gravity
    assert q[:2].tolist() == [-0.6, 0.3] and np.max(np.abs(q[2:])) > 1e-3       # the links sag
    assert np.max(np.abs(load[2:])) <= 1e-12 * np.max(np.abs(load[:2]))
    hanging = static_equilibrium(robot("flex1"), [-np.pi / 2, 0, 0])
    assert np.max(np.abs(hanging[1:])) <= 1e-15


def test_the_exact_solution_of_the_undamped_arm_with_free_joints_matches_the_ode():
    """flex1 horizontal, no damping: gravity's stiffness vanishes there, so the hub angle is a free
    (rigid) mode and x, v form a Jordan chain; on the spring extensions w = U_rᵀx the modes are
    plain, and the closed form agrees with DOP853 (measured 5.1e-13 of the peak over 0.5 s)."""
    from analogy.presets import PRESETS
    from analogy.scenes.scene import Scene
    from analogy.scenes.spec import ModelSpec
    from analogy.solvers.registry import run
    s = Scene.of("free", ModelSpec(robot="flex1"), q=[0, 0, 0], forces=[1, 0, 0], t_stop=0.5).system()
    t = np.linspace(0, 0.5, 501)
    exact, ode = (run(name, s, t, PRESETS["accurate"]) for name in ("exact", "ode"))
    assert np.max(np.abs(ode.rates - exact.rates)) <= 1e-9 * np.max(np.abs(exact.rates))
    assert abs(exact.rates[-1, 0]) > 1.0     # the arm falls from the horizontal: a rigid motion
