"""A URDF robot's defaults: a stable pose, forces sized to the robot, a horizon from its modes, its
joints named in every output, and its base said to be held fixed."""

from __future__ import annotations

import csv
import importlib.metadata
import math

import numpy as np
import pytest

from analogy.cli import main
from analogy.model.urdf import UrdfModel, urdf_model
from analogy.results.modes import system_poles
from analogy.scenes.robot_defaults import HORIZON_RANGE, MOTION, growth_rate, hanging_pose, robot_defaults
from analogy.scenes.spec import ModelSpec
from test_urdf import BENCH, random_tree_urdf

EPS = np.finfo(float).eps


def _installed(dist: str) -> bool:
    try:
        importlib.metadata.distribution(dist)
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


needs_robots = pytest.mark.skipif(not _installed("example-robot-data"),
                                  reason="the named robots come from example-robot-data (the test extras)")


def _named(name: str) -> UrdfModel:
    from analogy.model.urdf_robots import urdf_robot
    text, joints = urdf_robot(name)
    return urdf_model(text, joints, None, 9.80665, name)


@pytest.mark.parametrize("seed", range(4))
def test_the_potential_energy_is_what_gravity_loads_derive_from(seed):
    """G = ∂U/∂q, by central differences: truncation h²·U'''/6 and rounding ε·U/h, both under
    1e-8 of g·Σm·reach at h = 1e-5."""
    m = UrdfModel(random_tree_urdf(seed))
    q = np.random.default_rng(seed).uniform(-2, 2, m.dof)
    h = 1e-5
    fd = np.array([(m.tree.potential_energy(q + h * e) - m.tree.potential_energy(q - h * e)) / (2 * h)
                   for e in np.eye(m.dof)])
    assert np.abs(fd - m.tree.gravity_load(q)).max() <= 1e-8 * m.gravity_scale


def test_the_potential_energy_changes_as_pinocchio_says(tmp_path):
    """U(q) − U(q0) against Pinocchio's computePotentialEnergy: sums of n terms of at most
    g·Σm·reach, so they agree to n·ε of it (1e-12 allowed)."""
    pin = pytest.importorskip("pinocchio")
    path = tmp_path / "tree.urdf"
    path.write_text(random_tree_urdf(3))
    ours = UrdfModel(path.read_text())
    pm = pin.buildModelFromUrdf(str(path))
    pd = pm.createData()
    pm.gravity.linear = np.array([0.0, 0.0, -ours.parameters["g"]])
    rng = np.random.default_rng(0)
    qs = rng.uniform(-np.pi, np.pi, (10, ours.dof))
    theirs = np.array([pin.computePotentialEnergy(pm, pd, pin.integrate(pm, pin.neutral(pm), q)) for q in qs])
    mine = ours.tree.potential_energy(qs)
    assert np.abs((mine - mine[0]) - (theirs - theirs[0])).max() <= 1e-12 * ours.gravity_scale


def test_a_hanging_pose_is_a_minimum_of_the_potential_energy():
    """G = 0 to rounding, K = ∂G/∂q positive semidefinite, and no nearby pose lies lower."""
    m = UrdfModel(BENCH.read_text())
    q = hanging_pose(m)
    if q is None:
        pytest.skip("the bench robot cannot hang within its limits")
    rounding = 100 * m.dof * EPS * m.gravity_scale
    assert np.abs(m.tree.gravity_load(q)).max() <= rounding
    assert np.linalg.eigvalsh(m.tree.gravity_stiffness(q))[0] >= -rounding
    near = q + np.random.default_rng(0).normal(scale=0.05, size=(50, m.dof))
    assert m.tree.potential_energy(near).min() >= m.tree.potential_energy(q) - rounding
    assert m.limits.contain(q)


@needs_robots
@pytest.mark.parametrize("name, hangs", [("ur5", True), ("ur10", True), ("double_pendulum", True),
                                          ("panda", False), ("xarm7", False)])
def test_each_named_robot_hangs_or_has_gravity_turned_off(name, hangs):
    """Where the least potential energy lies outside the joint limits, g = 0 at the ranges' middle:
    never an unstable pose (no pole with a positive real part)."""
    model = _named(name)
    d = robot_defaults(model, label=name)
    assert (d.g > 0) == hangs and d.note.startswith(f"{name}: ")
    joint = model.with_parameters({"g": d.g}).joint_space(d.q)
    assert model.limits.contain(d.q)
    assert not joint.unstable
    scale = max(float(np.abs(system_poles(joint.mass_matrix, joint.damping,
                                          joint.stiffness if joint.stiffness is not None else
                                          np.zeros_like(joint.mass_matrix))).max()), 1.0)
    assert growth_rate(joint.mass_matrix, joint.damping, joint.stiffness) <= 1e3 * EPS * scale
    if not hangs:
        assert np.allclose(d.q, model.limits.middle())


@needs_robots
@pytest.mark.parametrize("name", ["ur5", "panda", "z1"])
def test_default_steps_move_each_joint_alone_by_the_stated_motion(name):
    """F_k over the joint's own impedance K_kk + B_kk/T + 2·M_kk/T² is MOTION, to the two digits
    the step is written with (or the step is the effort limit); T is three times the slowest
    time scale of the modes, within HORIZON_RANGE."""
    model = _named(name)
    d = robot_defaults(model, label=name)
    joint = model.with_parameters({"g": d.g}).joint_space(d.q)
    m, b, k = joint.mass_matrix, joint.damping, joint.stiffness
    t = d.t_stop
    impedance = (np.zeros(model.dof) if k is None else np.clip(np.diag(k), 0, None)) + np.diag(b) / t \
        + 2 * np.diag(m) / t ** 2
    forces = np.array([float(f[len("step("):-1]) for f in d.forces])
    motion = np.array([MOTION[kind] for kind in model.joints])
    capped = np.isclose(forces, model.limits.effort)
    assert np.all(capped | (np.abs(forces / impedance / motion - 1) <= 0.05))
    s = system_poles(m, b, np.zeros_like(m) if k is None else k)
    s = s[np.abs(s) > 0]
    slowest = max(2 * math.pi / abs(x.imag) if x.imag else 1 / abs(x.real) for x in s)
    assert HORIZON_RANGE[0] <= t <= HORIZON_RANGE[1]
    if HORIZON_RANGE[0] < 3 * slowest < HORIZON_RANGE[1]:
        assert t == pytest.approx(3 * slowest, rel=0.5)       # written with one digit


@needs_robots
@pytest.mark.parametrize("name", ["panda", "kinova", "z1", "double_pendulum"])
def test_a_named_robots_default_compare_keeps_accurate_for_the_ode_and_exact(name, capsys):
    """The first command a robotics user types: the default experiment exits 0."""
    assert main(["compare", "--robot", name, "--solvers", "ode,exact", "--no-plot"]) == 0
    err = capsys.readouterr().err
    assert f"analogy: note: {name}: " in err and "unstable" not in err


def test_a_linearisation_at_an_unstable_pose_says_so_with_its_growth_rate(capsys):
    """The pose and max Re(s) of det(M·s² + B·s + K) = 0, said before anything runs."""
    assert main(["netlist", "--robot", "serial2", "--param", "g=9.81", "--q", "1.57, 0"]) == 0
    err = capsys.readouterr().err
    assert "q = (1.57, 0) is an unstable equilibrium" in err
    from analogy import scene
    joint = scene("default").replace(q=(1.57, 0.0), parameters={"g": 9.81}).system().joint
    rate = growth_rate(joint.mass_matrix, joint.damping, joint.stiffness)
    assert rate > 0 and f"e^({rate:.4g}·t)" in err


def test_a_stable_pose_says_nothing_of_stability(capsys):
    assert main(["netlist"]) == 0
    assert "unstable" not in capsys.readouterr().err


@needs_robots
def test_urdf_outputs_carry_the_joint_names(tmp_path, capsys):
    """Netlist comments beside the sources, the table, CSV columns and the DataFrame name the joints."""
    out = tmp_path / "z1.csv"
    assert main(["compare", "--robot", "z1", "--solvers", "ode,exact", "--csv", str(out), "--no-plot"]) == 0
    printed = capsys.readouterr().out
    names = _named("z1").joint_names
    header = next(csv.reader(out.open()))
    assert header[1:1 + len(names)] == [f"{n}_rate_ode [rad/s]" for n in names]
    assert "_rate" in printed.splitlines()[2] and printed.startswith("robot z1,")
    assert main(["netlist", "--robot", "z1"]) == 0
    text = capsys.readouterr().out
    assert "* joints: " + ", ".join(f"q{k + 1} = {n}" for k, n in enumerate(names)) in text
    for k, n in enumerate(names):
        assert f"* I{k + 1}: the force on joint {k + 1}, {n}\nI{k + 1} " in text


@needs_robots
def test_the_dataframe_names_joints_and_keeps_the_r_form_readable():
    from analogy import compare, scene
    result = compare(scene("z1").system(), "fast", ["ode", "exact"])
    frame = result.to_frame()
    names = _named("z1").joint_names
    assert f"{names[0]}_rate_ode" in frame.columns
    assert frame.attrs["outputs"][f"{names[0]}_rate_ode"] == "r1_ode"
    np.testing.assert_array_equal(frame[f"{names[0]}_rate_ode"].to_numpy(), result.results["ode"].rates[:, 0])


def test_built_in_arms_keep_r1_to_rn(tmp_path):
    out = tmp_path / "d.csv"
    assert main(["compare", "--solvers", "ode,exact", "--csv", str(out), "--no-plot"]) == 0
    assert next(csv.reader(out.open()))[1] == "r1_ode [rad/s]"


def test_a_joint_name_cannot_smuggle_a_control_line_into_a_netlist(tmp_path, capsys):
    text = BENCH.read_text()
    first = UrdfModel(text).joint_names[0]
    evil = text.replace(f'"{first}"', '"j&#10;.control&#10;shell touch x&#10;.endc"')
    path = tmp_path / "evil.urdf"
    path.write_text(evil)
    assert main(["netlist", "--urdf", str(path)]) == 0
    lines = [line.lstrip().lower() for line in capsys.readouterr().out.splitlines()]
    assert not any(line.startswith("shell") for line in lines)
    assert sum(line.startswith(".control") for line in lines) == 1         # the netlist's own block


def test_a_urdf_scene_is_named_after_its_robot():
    assert ModelSpec(urdf=BENCH.read_text()).label == UrdfModel(BENCH.read_text()).name


@needs_robots
def test_a_root_link_that_is_not_the_world_is_said_to_be_held_fixed(capsys):
    assert main(["netlist", "--robot", "panda"]) == 0
    err = capsys.readouterr().err
    assert "root link panda_link0 is held fixed to the world (--base fixed, the default" in err
    assert main(["netlist", "--robot", "ur5"]) == 0
    assert "root link" not in capsys.readouterr().err          # its root is the world
    assert main(["netlist", "--robot", "panda", "--base", "fixed"]) == 0
    assert "root link" not in capsys.readouterr().err          # chosen, so not said


def test_a_floating_base_whose_joint_moves_what_the_base_moves_is_refused_in_one_sentence(capsys):
    """The bench's root link (the floor) is massless: freed, its slide moves exactly what the base's x does."""
    assert main(["netlist", "--urdf", str(BENCH), "--base", "floating"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "with its root link floor free, the robot's mass matrix is singular" in err[0]
    assert "Traceback" not in err[0]
