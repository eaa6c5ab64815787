"""A URDF arm's full nonlinear dynamics as a circuit: the tree's recursions as shared nodes, against Pinocchio."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp

from analogy.circuit.nonlinear import nonlinear_system
from analogy.circuit.nonlinear_circuit import node_lagrangian
from analogy.cli import main
from analogy.model.urdf import UrdfModel, urdf_model
from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.solvers.rawfile import read_printed
from analogy.solvers.spice import session, solve_spice
from analogy.solvers.transient import netlist, refined
from analogy.waveforms import Sine

from test_urdf import AGREEMENT, BENCH, random_tree_urdf

pin = pytest.importorskip("pinocchio")

#: The UR5 hanging (q2 = π/2, a stable pose), driven by 0.5 Hz sine torques from rest: the
#: shoulder pan and wrist 1 swing through 4.7 and 3.9 rad in 2 s, with gravity on.
UR5_SWING = ([0.0, np.pi / 2, 0.0, 0.0, 0.0, 0.0], [5.0, 10.0, 5.0, 1.0, 0.5, 0.1])
#: The Panda at a pose where gravity's stiffness has no negative eigenvalue, held there by
#: G(q0) and driven at its four proximal joints: joints 3 and 4 turn through 3.6 and 2.7 rad.
PANDA_SWING = ([-2.58, -2.18, 0.11, 0.41, 1.8, 1.41, -2.67], [0.75, 1.5, 0.75, 0.75, 0.0, 0.0, 0.0])


def _robot(name: str):
    from analogy.model.urdf_robots import URDF_ROBOTS, _robots_folder, urdf_robot
    text, joints = urdf_robot(name)
    path = _robots_folder() / URDF_ROBOTS[name][0]
    return urdf_model(text, joints), _pinocchio(path, joints)


def _pinocchio(path, joints=None, g: float = 9.80665):
    pm = pin.buildModelFromUrdf(str(path))
    if joints is not None:              # the others frozen at 0, as the model freezes them
        frozen = [pm.getJointId(name) for name in pm.names[1:] if name not in joints]
        pm = pin.buildReducedModel(pm, frozen, pin.neutral(pm))
    pm.gravity.linear = np.array([0.0, 0.0, -g])
    return pm


def _lagrangian_differences(model: UrdfModel, pm, states: int = 20, seed: int = 0) -> dict:
    """Largest difference over the peak of M'(x) and of the node load h against Pinocchio.

    h = G − ∂T/∂q, and Pinocchio's Coriolis matrix C has Ṁ = C + Cᵀ (Ṁ − 2C is skew), so
    ∂T/∂q = Ṁ·q̇ − c = Cᵀ·q̇.
    """
    pd = pm.createData()
    n = model.dof
    rng = np.random.default_rng(seed)
    q0 = rng.uniform(-np.pi, np.pi, n)
    system = nonlinear_system(model, q0, t_stop=1.0)
    lag = node_lagrangian(system)
    diff = {"M": 0.0, "h": 0.0}
    peak = dict(diff)
    for _ in range(states):
        x, v = rng.uniform(-1, 1, n), rng.normal(size=n)
        values = lag.values(x, v)
        mass = np.array(lag.mass.xreplace(values).tolist(), dtype=float)
        load = np.array(lag.load.xreplace(values).tolist(), dtype=float).ravel()
        qp = pin.integrate(pm, pin.neutral(pm), q0 + x)
        m = pin.crba(pm, pd, qp)
        m = np.triu(m) + np.triu(m, 1).T
        coriolis = pin.computeCoriolisMatrix(pm, pd, qp, v)
        h = pin.computeGeneralizedGravity(pm, pd, qp) - coriolis.T @ v
        for key, mine, theirs in (("M", mass, m), ("h", load, h)):
            diff[key] = max(diff[key], float(np.abs(mine - theirs).max()))
            peak[key] = max(peak[key], float(np.abs(theirs).max()))
    return {k: diff[k] / peak[k] for k in diff}


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_the_circuit_s_capacitances_and_load_are_the_tree_s_mass_matrix_and_lagrange_terms(name):
    """M'(x) and h(x, v) read off the shared nodes equal Pinocchio's crba, gravity and Coriolis."""
    rel = _lagrangian_differences(*_robot(name))
    assert max(rel.values()) <= AGREEMENT, rel


@pytest.mark.parametrize("seed", [1, 2])
def test_the_same_holds_for_random_trees_and_the_hand_written_bench(tmp_path, seed):
    """Prismatic joints, fixed joints and rotated inertial frames (the bench), branching trees."""
    path = tmp_path / "tree.urdf"
    path.write_text(random_tree_urdf(seed))
    for p in (path, BENCH):
        rel = _lagrangian_differences(UrdfModel(p.read_text()), _pinocchio(p))
        assert max(rel.values()) <= AGREEMENT, (p.name, rel)


def test_a_placement_and_a_body_inertia_read_back_the_frame_and_body_they_were_made_from():
    """placement_frame inverts plucker and body_inertia inverts spatial_inertia, to a few roundings."""
    from scipy.spatial.transform import Rotation
    from analogy.model.rigid_tree import body_inertia, placement_frame, plucker, spatial_inertia
    rng = np.random.default_rng(3)
    for _ in range(20):
        rotation, position = Rotation.random(random_state=rng).as_matrix(), rng.normal(size=3)
        e, p = placement_frame(plucker(rotation, position))
        np.testing.assert_allclose(e, rotation, rtol=0, atol=8 * np.finfo(float).eps)
        np.testing.assert_allclose(p, position, rtol=0, atol=8 * np.finfo(float).eps * np.abs(position).max())
        a = rng.normal(size=(3, 3))
        m, com, at_com = rng.uniform(0.1, 5.0), rng.normal(size=3), a @ a.T
        m2, c2, i2 = body_inertia(spatial_inertia(m, com, at_com))
        # Ī comes back from Ī + m·c×c×ᵀ less the same product: roundings of m·|c|² and of Ī
        scale = np.abs(at_com).max() + m * (com @ com)
        assert m2 == m
        np.testing.assert_allclose(c2, com, rtol=8 * np.finfo(float).eps)
        np.testing.assert_allclose(i2, at_com, rtol=0, atol=16 * np.finfo(float).eps * scale)


def test_the_circuit_takes_the_system_s_gravity_as_its_functions_do():
    """g set on the system (not on the model) reaches the circuit: at rest, g = 0 leaves no load."""
    model = UrdfModel(BENCH.read_text())
    q0 = [0.1, 0.5, -0.3]
    for g in (0.0, 2.5):
        system = nonlinear_system(model, q0, parameters={"g": g}, t_stop=1.0)
        lag = node_lagrangian(system)
        load = np.array(lag.load.xreplace(lag.values(np.zeros(3), np.zeros(3))).tolist(), dtype=float).ravel()
        expected = system.node_gravity(np.zeros(3))
        assert np.abs(load - expected).max() <= AGREEMENT * max(np.abs(expected).max(), 1.0), (g, load, expected)
    assert not np.any(nonlinear_system(model, q0, parameters={"g": 0.0}, t_stop=1.0).node_gravity(np.zeros(3)))


def test_every_node_is_a_few_products_of_the_ones_before():
    """The netlist grows as n, not n³: the Panda's is 439 lines and tens of kB, no expression long."""
    model, _ = _robot("panda")
    system = nonlinear_system(model, PANDA_SWING[0], t_stop=2.0)
    lag = node_lagrangian(system)
    assert 300 < len(lag.shared) < 80 * model.dof
    assert max(sp.count_ops(e) for _, e in lag.shared) < 40
    text = netlist(system, "accurate")
    assert len(text) < 100_000
    assert all(f"Bm{a}_{b} m{a}_{b} 0 V=" in text for a in range(1, 8) for b in range(a, 8))


def _swing(name: str, t_stop: float = 2.0):
    model, pm = _robot(name)
    q0, amplitudes = PANDA_SWING if name == "panda" else UR5_SWING
    q0 = np.array(q0)
    hold = model.tree.gravity_load(q0)
    forces = [[Sine(float(h), a, 0.5)] for h, a in zip(hold, amplitudes)]
    system = nonlinear_system(model, q0, forces=forces, t_stop=t_stop)
    return system, pm, hold, np.array(amplitudes)


def _pinocchio_rates(system, pm, hold, amplitudes, times):
    """Pinocchio's articulated-body accelerations, integrated by DOP853 at rtol 1e-12."""
    from scipy.integrate import solve_ivp
    pd = pm.createData()
    n = system.dof
    damping = np.diag(system.functions.damping)

    def rhs(t, y):
        tau = hold + amplitudes * np.sin(np.pi * t) - damping * y[n:]
        return np.concatenate([y[n:], pin.aba(pm, pd, y[:n], y[n:], tau)])
    sol = solve_ivp(rhs, (0.0, system.t_stop), np.concatenate([system.q0, np.zeros(n)]), method="DOP853",
                    rtol=1e-12, atol=1e-14, dense_output=True)
    return sol.sol(times)[n:].T, sol.sol(times)[:n].T


@pytest.mark.ngspice
@pytest.mark.deep
def test_the_ur5_s_nonlinear_circuit_keeps_the_accurate_bound_against_pinocchio():
    system, pm, hold, amplitudes = _swing("ur5")
    run = solve_spice(system, preset="accurate")
    rates, angles = _pinocchio_rates(system, pm, hold, amplitudes, run.time)
    assert np.ptp(angles, axis=0).max() > 3.0          # several radians of motion
    _, rel = output_errors(system.joint_rates(run.voltages), rates)
    assert np.max(rel) <= PRESETS["accurate"].bound, rel


@pytest.mark.ngspice
@pytest.mark.deep
def test_the_panda_s_nonlinear_circuit_converges_as_the_trapezoidal_rule_to_pinocchio():
    """At the step from its motion's error coefficients the Panda's swing keeps 1e-6 of each joint's
    own peak against Pinocchio (at the old cap t_stop/20000 its wrist missed: 2.8e-6); the error
    is the trapezoidal rule's h², not the circuit's: half the step gives a quarter of it."""
    system, pm, hold, amplitudes = _swing("panda")
    accurate = PRESETS["accurate"]
    errors = []
    for p in (accurate, refined(accurate, tolerances=False)):
        run = solve_spice(system, preset=p)
        rates, angles = _pinocchio_rates(system, pm, hold, amplitudes, run.time)
        assert np.ptp(angles, axis=0).max() > 3.0
        errors.append(np.max(output_errors(system.joint_rates(run.voltages), rates)[1]))
    # h² halved: 4 within a third either way (the step binds over the whole run)
    assert 4 / 1.33 <= errors[0] / errors[1] <= 4 * 1.33, errors
    assert errors[0] <= accurate.bound, errors


@pytest.mark.ngspice
def test_the_nonlinear_netlist_runs_in_plain_ngspice_as_in_process(tmp_path):
    """What `analogy netlist` writes runs in `ngspice -b`: its printed table is the in-process run."""
    system, *_ = _swing("ur5", t_stop=0.5)
    text = netlist(system, "fast", printing=True)
    path = tmp_path / "ur5.cir"
    path.write_text(text)
    res = subprocess.run([shutil.which("ngspice") or "ngspice", "-b", str(path)], capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0 and "too small" not in (res.stdout + res.stderr).lower(), res.stderr[-2000:]
    printed = read_printed(res.stdout)
    data = session().run(netlist(system, "fast"), list(system.nodes))
    here = np.column_stack([np.interp(printed["time"], data["time"], data[n]) for n in system.nodes])
    there = np.column_stack([printed[n] for n in system.nodes])
    # 15 printed digits, interpolated alike: 1e-12 of the peak leaves 1000 over the printing
    assert np.max(np.abs(here - there)) <= 1e-12 * np.max(np.abs(there))


@pytest.mark.ngspice
def test_compare_runs_a_urdf_arm_s_nonlinear_dynamics_from_the_command_line(capsys):
    code = main(["compare", "--robot", "ur5", "--dynamics", "nonlinear", "--q=0,1.5707963267948966,0,0,0,0",
                 "--force", "sine(0,5,0.5)", "--force", "sine(0,10,0.5)", "--force", "0", "--force", "0",
                 "--force", "0", "--force", "0", "--t-stop", "0.5", "--preset", "fast", "--no-plot"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "spice" in out and "ode" in out
