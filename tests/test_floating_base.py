"""A free-flying base: six coordinates before a URDF's joints, checked against Pinocchio's free-flyer and by
the conservation of momentum."""

import subprocess
import sys

import numpy as np
import pytest

import analogy
from analogy.errors import InputError
from analogy.model.urdf import FREE_FLYER, urdf_model
from analogy.model.urdf_robots import urdf_robot
from analogy.scenes.scene import Scene
from analogy.scenes.spec import ModelSpec

pin = pytest.importorskip("pinocchio")
SOLO = "solo_description/robots/solo12.urdf"


def solo_text() -> str:
    from analogy.model.urdf_robots import _robots_folder
    return (_robots_folder() / SOLO).read_text()


def _rotation(axis: str, angle):
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    rows = {"x": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
            "y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
            "z": [[c, -s, zero], [s, c, zero], [zero, zero, one]]}[axis]
    return np.array(rows)


def free_flyer_map(q, n):
    """(R, S): the base's rotation Rz(ψ)·Ry(θ)·Rx(φ) and the map S(q) of our rates q̇ to Pinocchio's
    free-flyer velocity (the origin's velocity and the angular velocity, both in the base's frame)."""
    yaw, pitch, roll = q[3:6]
    rx, ry = _rotation("x", roll), _rotation("y", pitch)
    rotation = _rotation("z", yaw) @ ry @ rx
    euler = np.column_stack([rx.T @ ry.T @ np.array([0, 0, 1.0]), rx.T @ np.array([0, 1.0, 0]),
                             np.array([1.0, 0, 0])])
    s = np.zeros((n, n), dtype=np.result_type(q))
    s[:3, :3], s[3:6, 3:6], s[6:, 6:] = rotation.T, euler, np.eye(n - 6)
    return rotation, s


def pinocchio_state(q, rates):
    rotation, s = free_flyer_map(q, len(q))
    quaternion = pin.Quaternion(rotation)
    quaternion.normalize()
    return np.concatenate([q[:3], quaternion.coeffs(), q[6:]]), s @ rates


def test_the_free_base_is_pinocchios_free_flyer_seen_through_its_euler_angles():
    """With v_ff = S(q)·q̇: M = Sᵀ·M_ff·S, G = Sᵀ·G_ff and M·q̈ + c + G = Sᵀ·RNEA_ff(q, S·q̇, S·q̈ + Ṡ·q̇), to
    rounding: each a sum of about n² products, n²·ε·cond(S)² of its largest entry (n = 18). Ṡ·q̇ by the
    complex step, exact to rounding."""
    text = solo_text()
    tree = urdf_model(text, g=9.81, base="floating").tree
    model = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    data = model.createData()
    n = tree.dof
    rng = np.random.default_rng(7)
    for _ in range(6):
        q, rates, accelerations = rng.uniform(-1.2, 1.2, n), rng.normal(size=n), rng.normal(size=n)
        _, s = free_flyer_map(q, n)
        step = 1e-30
        s_dot = np.imag(free_flyer_map(q + 1j * step * rates, n)[1]) / step
        state, v = pinocchio_state(q, rates)
        mass = pin.crba(model, data, state)
        mass = np.triu(mass) + np.triu(mass, 1).T
        theirs = (s.T @ mass @ s, s.T @ pin.computeGeneralizedGravity(model, data, state),
                  s.T @ pin.rnea(model, data, state, v, s @ accelerations + s_dot @ rates))
        mine = (tree.mass_matrix(q), tree.gravity_load(q[None])[0], tree.inverse_dynamics(q, rates, accelerations))
        tol = n * n * np.finfo(float).eps * np.linalg.cond(s) ** 2
        for a, b in zip(mine, theirs):
            assert np.max(np.abs(a - b)) <= tol * np.max(np.abs(b))


def test_the_base_is_the_root_links_and_gets_no_force():
    model = urdf_model(solo_text(), g=9.81, base="floating")
    assert model.joint_names[:6] == tuple(name for name, _, _ in FREE_FLYER) and model.dof == 18
    total = model.tree.mass_matrix(np.zeros(18))[:3, :3]
    masses = [pin_mass for pin_mass in pin.buildModelFromXML(solo_text()).inertias]
    assert np.allclose(total, sum(i.mass for i in masses) * np.eye(3), rtol=1e-14, atol=0)
    sc = Scene.of("solo", ModelSpec(urdf=solo_text(), base="floating"))
    from analogy.scenes.robot_defaults import robot_defaults
    d = robot_defaults(sc.numeric_model())
    assert d.g == 0.0 and d.forces[:6] == ("0",) * 6 and all(f.startswith("step(") for f in d.forces[6:])


def free_swing(t_stop=0.4):
    """Solo12 floating in zero gravity, its twelve joints pushed by small steps from rest."""
    sc = Scene.of("solo", ModelSpec(urdf=solo_text(), base="floating"), q=(0.0,) * 18, parameters={"g": 0.0},
                  forces=(0,) * 6 + ("step(0.02)",) * 12, t_stop=t_stop, dynamics="nonlinear")
    return sc.system()


def momenta(system, tr):
    """The centroidal momentum (linear, then angular about the centre of mass, world axes) at every point,
    by Pinocchio's free-flyer model, and the scale of the joints' own generalised momenta M·q̇."""
    model = pin.buildModelFromXML(solo_text(), pin.JointModelFreeFlyer())
    data = model.createData()
    qs = system.q0 + tr.positions @ system.topology.inverse.T
    h = np.array([np.array(pin.computeCentroidalMomentum(model, data, *pinocchio_state(q, r)))
                  for q, r in zip(qs, tr.rates)])
    scale = max(float(np.max(np.abs(system.functions.mass(q) @ r)[6:])) for q, r in zip(qs, tr.rates))
    return h, scale, qs


@pytest.mark.parametrize("solver, preset", [("ode", "accurate"), pytest.param("spice", "fast", marks=pytest.mark.ngspice)])
def test_a_free_robot_keeps_its_momentum_and_turns_its_base_by_moving_its_legs(solver, preset):
    """From rest with no external force, linear and angular momentum stay zero, to the run's bound of the
    joints' momenta (measured: ODE 3e-11, SPICE at fast 1.3e-5); yet the base turns, as its legs swing."""
    system = free_swing()
    tr = analogy.solve(system, solver, None, preset, positions=True)
    h, scale, qs = momenta(system, tr)
    assert np.max(np.abs(h)) <= analogy.PRESETS[preset].bound * scale
    assert np.ptp(qs[:, 3:6], axis=0).max() > 0.1          # the base's angles moved by a tenth of a radian
    residual, energy = system.energy_residual(tr)
    assert np.max(np.abs(residual)) <= analogy.PRESETS[preset].bound * energy


@pytest.mark.ngspice
def test_the_issues_command_runs_a_floating_quadruped_within_its_bound(tmp_path):
    path = tmp_path / "solo12.urdf"
    path.write_text(solo_text())
    out = subprocess.run([sys.executable, "-m", "analogy", "compare", "--urdf", str(path), "--base", "floating",
                          "--dynamics", "nonlinear", "--param", "g=0", "--t-stop", "0.2", "--preset", "fast"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "flies free (--base floating)" in out.stderr
    rows = {line.split()[0]: line.split() for line in out.stdout.splitlines() if line.split()}
    assert float(rows["spice"][4]) <= 1e-3 and float(rows["ode"][4]) <= 1e-3       # error / peak, each solver


def test_a_base_applies_to_urdf_robots_only():
    out = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--robot", "serial2", "--base", "floating"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "the built-in robots have no base to free" in out.stderr
    with pytest.raises(InputError, match="applies to a URDF robot"):
        ModelSpec(robot="serial2", base="floating")
    with pytest.raises(InputError, match="base must be fixed or floating"):
        ModelSpec(urdf=urdf_robot("ur5")[0], base="loose")
