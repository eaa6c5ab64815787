"""The tree's forward dynamics for the ODE: Pinocchio's and the vectorised numpy pass against the recursions."""

from __future__ import annotations

import numpy as np
import pytest

from analogy.circuit.nonlinear import NonlinearNodeSystem, nonlinear_system
from analogy.circuit.topology import topology as make_topology
from analogy.errors import InputError
from analogy.model.urdf import UrdfModel
from analogy.solvers.ode import solve_ode
from analogy.waveforms import Sine

from test_urdf import BENCH, random_tree_urdf

EPS = np.finfo(float).eps
STATES = 20


def _named(name: str, joints=None, pose=None) -> UrdfModel:
    from analogy.model.urdf_robots import urdf_robot
    try:
        text, kept = urdf_robot(name)
    except InputError as exc:       # example-robot-data is not installed
        pytest.skip(str(exc))
    return UrdfModel(text, joints or kept, pose)


MODELS = {
    "ur5": lambda: _named("ur5"),
    "panda": lambda: _named("panda"),
    # two wrist joints frozen away from 0: the pose reaches Pinocchio's reduced model
    "ur5 frozen wrist": lambda: _named("ur5", ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                               "wrist_1_joint"), {"wrist_2_joint": 0.7, "wrist_3_joint": -0.4}),
    "bench": lambda: UrdfModel(BENCH.read_text()),
    # continuous joints (Pinocchio's (cos, sin) coordinates), prismatic ones, branches
    **{f"random tree {s}": (lambda s=s: UrdfModel(random_tree_urdf(s))) for s in range(4)},
}


def _states(model: UrdfModel, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = model.dof
    return rng.uniform(-np.pi, np.pi, (STATES, n)), rng.normal(size=(STATES, n)), rng.normal(size=(STATES, n))


def _scales(model: UrdfModel, qs, rates) -> tuple[float, float]:
    """(M's, c + G's) scale of terms: each entry sums about n² products no larger than these, so
    one computation is within n²·ε of them and two within twice that. M's terms are no larger
    than its peak over the states, c's than its peak, G's than g·Σm·reach (the model's
    gravity_scale, the scale its own rounding floor uses)."""
    t = model.tree
    return float(np.abs(t.mass_matrices(qs)).max()), \
        float(np.abs(t.velocity_load(qs, rates)).max() + model.gravity_scale)


def _solve_bound(n: int, m: np.ndarray, accel: np.ndarray, mass_scale: float, load_scale: float) -> float:
    """|δq̈| ≤ ‖M⁻¹‖·(‖δM‖·‖q̈‖ + ‖δb‖), with each of the two sides' ‖δM‖ ≤ n·n²·ε·(M's scale)
    and ‖δb‖ ≤ √n·n²·ε·(c + G's scale) (see :func:`_scales`), and the solve's own backward
    error of the same order: twice that for two computations."""
    inverse = np.linalg.norm(np.linalg.inv(m), 2)
    return 2 * 2 * n * n * EPS * inverse * (n * mass_scale * np.linalg.norm(accel) + np.sqrt(n) * load_scale)


@pytest.mark.parametrize("name", list(MODELS))
def test_pinocchio_s_forward_dynamics_mass_and_loads_are_the_tree_recursions(name):
    pytest.importorskip("pinocchio")
    from analogy.model.articulated_body import pinocchio_functions
    model = MODELS[name]()
    n = model.dof
    f = pinocchio_functions(model.text, model.tree, model.joint_names, np.diag(model.joint_damping), model._pose)
    assert f is not None and f.forward is not None
    assert model.mechanical_functions().forward.__self__ is f.forward.__self__    # the model takes it
    qs, rates, taus = _states(model)
    mass_scale, load_scale = _scales(model, qs, rates)
    t = model.tree
    for q, r, tau in zip(qs, rates, taus):
        m, bias = t.mass_matrix(q), t.inverse_dynamics(q, r, np.zeros(n))
        accel = np.linalg.solve(m, tau - bias)
        assert np.abs(f.mass(q) - m).max() <= 2 * n * n * EPS * mass_scale
        assert np.abs(f.velocity(q, r) + f.gravity(q) - bias).max() <= 2 * n * n * EPS * load_scale
        assert np.abs(f.forward(q, r, tau) - accel).max() <= _solve_bound(n, m, accel, mass_scale, load_scale)
    # U sums n bodies' m·g·height, each from a chain of up to n transforms: n²·ε of g·Σm·reach each side
    np.testing.assert_allclose(f.potential(qs), t.potential_energy(qs), rtol=0,
                               atol=2 * n * n * EPS * model.gravity_scale)


@pytest.mark.parametrize("name", list(MODELS))
def test_the_vectorised_numpy_pass_is_the_one_state_recursions(name):
    """One kinematics pass for M, c and G over a stack of states, against the recursions
    (composite rigid body, Newton–Euler) run state by state."""
    model = MODELS[name]()
    n = model.dof
    t = model.tree
    qs, rates, taus = _states(model, seed=1)
    mass_scale, load_scale = _scales(model, qs, rates)
    masses, biases = t.dynamics(qs, rates)
    stacked = t.forward_dynamics(qs, rates, taus)
    for k, (q, r, tau) in enumerate(zip(qs, rates, taus)):
        m, bias = t.mass_matrix(q), t.inverse_dynamics(q, r, np.zeros(n))
        accel = np.linalg.solve(m, tau - bias)
        assert np.abs(masses[k] - m).max() <= 2 * n * n * EPS * mass_scale
        assert np.abs(biases[k] - bias).max() <= 2 * n * n * EPS * load_scale
        bound = _solve_bound(n, m, accel, mass_scale, load_scale)
        assert np.abs(stacked[k] - accel).max() <= bound
        # one state alone is the stack's row: the same operations (batched products may sum in
        # another order, a rounding per term)
        assert np.abs(t.forward_dynamics(q, r, tau) - stacked[k]).max() <= bound
    assert np.allclose(t.dynamics(qs, 0.0)[1], t.gravity_load(qs), rtol=0, atol=2 * n * n * EPS * load_scale)


def _functions(model: UrdfModel):
    out = {"numpy": model.tree.functions(np.diag(model.joint_damping))}
    try:
        import pinocchio  # noqa: F401
        from analogy.model.articulated_body import pinocchio_functions
        out["pinocchio"] = pinocchio_functions(model.text, model.tree, model.joint_names,
                                               np.diag(model.joint_damping), model._pose)
    except ImportError:
        pass
    return out


@pytest.mark.parametrize("spec", ["parallel", "serial"])
def test_the_node_system_s_flow_by_forward_dynamics_is_its_solve_of_m_prime(spec):
    """dv/dt = T·q̈(q, r, Tᵀ·(i − B'v − K'x)) is M'⁻¹·(i − B'v − K'x − h) for a constant T."""
    model = MODELS["bench"]()
    n = model.dof
    q0 = np.array([0.1, 0.5, -0.3])
    top = make_topology(spec, n)
    rng = np.random.default_rng(2)
    for label, f in _functions(model).items():
        fast = NonlinearNodeSystem(f, q0, top, ((),) * n, np.zeros(n), 1.0)
        slow = NonlinearNodeSystem(f._replace(forward=None), q0, top, ((),) * n, np.zeros(n), 1.0)
        qs, rates, _ = _states(model, seed=3)
        mass_scale, load_scale = _scales(model, q0 + qs, rates)
        for x, v in zip(qs, rates):
            drive = rng.normal(size=n)
            a, p = fast.flow(x, v, drive)
            b, p2 = slow.flow(x, v, drive)
            q, r = fast.configuration(x), fast.joint_rates(v)
            m = model.tree.mass_matrix(q)
            accel = top.joint_rates(b)
            # T and T⁻¹ here hold 0 and ±1: each map adds at most n roundings of the largest term
            bound = n * _solve_bound(n, m, accel, mass_scale, load_scale + np.abs(drive).max())
            assert np.abs(a - b).max() <= bound, label
            assert p == p2


def _swing(name: str):
    model = MODELS[name]()
    q0 = np.array([0.0, np.pi / 2, 0.0, 0.0, 0.0, 0.0])
    hold = model.tree.gravity_load(q0)
    forces = [[Sine(float(h), a, 0.5)] for h, a in zip(hold, [5.0, 10.0, 5.0, 1.0, 0.5, 0.1])]
    return model, nonlinear_system(model, q0, forces=forces, t_stop=1.0)


def test_the_energy_balance_holds_with_gravity_s_work_from_its_potential():
    """T − T(0) = W, with gravity's part U(q0) − U(q): what the run integrates and the potential
    agree, on either implementation. DOP853 at rtol 1e-10 holds each step's error to about rtol
    of the state, and the run takes under a hundred steps: their sum is below 100·rtol of the energy."""
    model, system = _swing("ur5")
    rtol = 1e-10
    for label, f in _functions(model).items():
        s = NonlinearNodeSystem(f, system.q0, system.topology, system.forces, system.initial_rates, system.t_stop)
        assert s.gravity_work(np.zeros((1, s.dof)))[0] == 0.0
        run = solve_ode(s, None, "DOP853", rtol, positions=True)
        residual, scale = s.energy_residual(run)
        assert np.max(np.abs(residual)) <= 100 * rtol * scale, label
        # gravity's power integrated with the rest, as without a potential: the same work
        integrated = NonlinearNodeSystem(f._replace(potential=None), system.q0, system.topology, system.forces,
                                         system.initial_rates, system.t_stop)
        other = solve_ode(integrated, None, "DOP853", rtol, positions=True)
        assert integrated.gravity_work(run.positions) is None
        assert np.max(np.abs(other.work - run.work)) <= 100 * rtol * scale, label
        assert np.ptp(run.positions, axis=0).max() > 0.5          # it swung: gravity did work


def test_without_pinocchio_or_where_it_reads_the_file_otherwise_the_tree_s_own_pass_serves(monkeypatch):
    model = MODELS["bench"]()
    pytest.importorskip("pinocchio")
    from dataclasses import replace
    from analogy.model import articulated_body
    # a tree that is not what Pinocchio reads from the file (twice the inertias): refused
    other = replace(model.tree, inertias=model.tree.inertias * 2)
    assert articulated_body.pinocchio_functions(model.text, other, model.joint_names,
                                                np.diag(model.joint_damping)) is None
    monkeypatch.setitem(__import__("sys").modules, "pinocchio", None)     # import pinocchio fails
    articulated_body._cached.cache_clear()
    try:
        f = model.mechanical_functions()
        assert f.forward == model.tree.forward_dynamics and f.potential == model.tree.potential_energy
    finally:
        articulated_body._cached.cache_clear()
