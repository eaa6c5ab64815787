"""A free-flying base: six coordinates before a URDF's joints, checked against Pinocchio's free-flyer and by
the conservation of momentum."""

import subprocess
import tempfile
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
#: Settled: the landing's remainder under a thousandth (of the weight, or a radian of tilt) by the horizon.
SETTLED = 1e-3


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


def free_arm():
    """The UR5 floating in zero gravity, in its default scene: a step sized to each joint's inertia with the base
    free (the Schur complement of M over the base)."""
    from analogy.scenes.robot_defaults import robot_defaults
    probe = Scene.of("ur5", ModelSpec(robot="ur5", base="floating"), dynamics="nonlinear")
    d = robot_defaults(probe.numeric_model())
    return probe.replace(q=d.q, forces=d.forces, t_stop=d.t_stop, parameters={"g": d.g}).system()


def momenta(system, tr, text=None):
    """The centroidal momentum (linear, then angular about the centre of mass, world axes) at every point,
    by Pinocchio's free-flyer model, and the scale of the joints' own generalised momenta M·q̇."""
    model = pin.buildModelFromXML(text or solo_text(), pin.JointModelFreeFlyer())
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


@pytest.mark.parametrize("solver, preset", [("ode", "accurate"), pytest.param("spice", "fast", marks=pytest.mark.ngspice)])
def test_a_free_floating_arm_turns_its_base_as_momentum_demands(solver, preset):
    """The UR5 in space: its joints driven from rest, its base turns the other way, and the momentum stays zero
    to the run's bound of the joints' momenta."""
    system = free_arm()
    tr = analogy.solve(system, solver, None, preset, positions=True)
    h, scale, qs = momenta(system, tr, urdf_robot("ur5")[0])
    assert np.max(np.abs(h)) <= analogy.PRESETS[preset].bound * scale
    assert np.ptp(qs[:, 3:6], axis=0).max() > 0.05


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


def standing(**parameters):
    """Solo12 free on its four feet, in its default standing scene (the base lowered until the feet touch)."""
    from analogy.scenes.robot_defaults import robot_defaults
    spec = ModelSpec(urdf=solo_text(), base="floating", contacts=("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"))
    probe = Scene.of("solo", spec, dynamics="nonlinear", parameters=parameters)
    d = robot_defaults(probe.numeric_model())
    return probe.replace(q=d.q, forces=d.forces, t_stop=d.t_stop, parameters={**parameters, "g": d.g}).system()


def weight() -> float:
    return sum(i.mass for i in pin.buildModelFromXML(solo_text()).inertias) * 9.80665


@pytest.mark.parametrize("solver, preset", [("ode", "fast"), pytest.param("ode", "accurate", marks=pytest.mark.deep),
                                            pytest.param("spice", "fast", marks=[pytest.mark.ngspice, pytest.mark.deep])])
def test_a_quadruped_settles_on_its_feet_with_their_forces_summing_to_its_weight(solver, preset):
    """Dropped onto its feet at rest, Solo12 settles by 0.5 s: the four contact forces sum to its weight within
    SETTLED of it (what is left of the landing, not a solver's error: measured 8.5e-7 by the ODE at accurate,
    the friction's creep still ringing out; 1.8e-12 without friction), each foot carries a share, and the base
    stays level within SETTLED rad (the robot is near symmetric)."""
    system = standing()
    tr = analogy.solve(system, solver, None, preset, positions=True)
    forces = np.array([tr.currents[f"f_{foot}"] for foot in ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")])
    total = forces.sum(axis=0)
    assert abs(total[-1] - weight()) <= SETTLED * weight()
    assert np.all(forces[:, -1] > 0.1 * weight() / 4)
    q = system.q0 + tr.positions @ system.topology.inverse.T
    assert np.max(np.abs(q[-1, 4:6])) <= SETTLED


def test_contacts_are_named_links_and_act_in_the_nonlinear_dynamics_only(tmp_path):
    path = tmp_path / "solo12.urdf"
    path.write_text(solo_text())
    out = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--robot", "ur5", "--contacts", "feet"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "ur5 has no link named like a foot" in out.stderr
    out = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--urdf", str(path), "--base", "floating",
                          "--contacts", "FL_FOOT,nose"], capture_output=True, text=True)
    assert out.returncode == 2 and "has no link 'nose'" in out.stderr
    out = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--urdf", str(path), "--base", "floating",
                          "--contacts", "feet", "--dynamics", "linear"], capture_output=True, text=True)
    assert out.returncode == 2 and "one-sided" in out.stderr and "Traceback" not in out.stderr
    out = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--urdf", str(path), "--base", "floating",
                          "--contacts", "feet", "--dynamics", "nonlinear", "--param", "kc=3 kg"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "kc is measured in N/m, got a mass" in out.stderr


@pytest.mark.deep
def test_each_foot_is_a_behavioural_node_of_the_netlist(tmp_path):
    """The netlist of the standing quadruped (its step sized from the ODE's motion: seconds) holds each foot's force."""
    path = tmp_path / "solo12.urdf"
    path.write_text(solo_text())
    out = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--urdf", str(path), "--base", "floating",
                          "--contacts", "feet", "--dynamics", "nonlinear"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    for foot in ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"):
        assert f"Bf_{foot} f_{foot} 0 V=" in out.stdout


def mujoco_standing(kp: float, kd: float, t_stop: float, base_height: float):
    """The same Solo12 in MuJoCo: its URDF's links without meshes, a free joint, a 1 mm sphere at each foot's
    origin on a plane, and a position servo kp, kv = kd on every joint. Returns the times, the base's height
    and the normal contact forces' sum, every millisecond."""
    import xml.etree.ElementTree as ET
    mujoco = pytest.importorskip("mujoco")
    urdf = ET.fromstring(solo_text())
    for link in urdf.findall("link"):
        for tag in ("visual", "collision"):
            for e in link.findall(tag):
                link.remove(e)
    ET.SubElement(ET.SubElement(urdf, "mujoco"), "compiler", {"discardvisual": "true", "fusestatic": "false"})
    model = mujoco.MjModel.from_xml_string(ET.tostring(urdf, encoding="unicode"))
    with tempfile.TemporaryDirectory() as folder:
        path = f"{folder}/solo.xml"
        mujoco.mj_saveLastXML(path, model)
        mjcf = ET.parse(path).getroot()
    world = mjcf.find("worldbody")
    base = world.find("body")
    base.set("pos", f"0 0 {base_height + 1e-3}")
    base.insert(0, ET.Element("freejoint", {"name": "root"}))
    ET.SubElement(world, "geom", {"type": "plane", "size": "2 2 0.1"})
    for body in mjcf.iter("body"):
        if body.get("name", "").endswith("_FOOT"):
            ET.SubElement(body, "geom", {"type": "sphere", "size": "0.001", "mass": "0"})
    servos = ET.SubElement(mjcf, "actuator")
    for joint in mjcf.iter("joint"):
        ET.SubElement(servos, "position", {"joint": joint.get("name"), "kp": repr(kp), "kv": repr(kd)})
    ET.SubElement(mjcf, "option", {"timestep": "1e-4", "integrator": "implicitfast", "gravity": "0 0 -9.80665"})
    model = mujoco.MjModel.from_xml_string(ET.tostring(mjcf, encoding="unicode"))
    data = mujoco.MjData(model)
    rows = []
    for k in range(int(round(t_stop / 1e-4))):
        mujoco.mj_step(model, data)
        if k % 10 == 9:
            force = np.zeros(6)
            total = 0.0
            for i in range(data.ncon):
                mujoco.mj_contactForce(model, data, i, force)
                total += force[0]
            rows.append((data.time, data.qpos[2] - 1e-3, total))
    return np.array(rows).T


def settled(time, total, w, share=0.01):
    """The time after which the contact forces' sum stays within *share* of the weight."""
    off = np.flatnonzero(np.abs(total - w) > share * w)
    return float(time[off[-1] + 1]) if off.size else 0.0


@pytest.mark.deep
def test_mujoco_anchors_the_quadrupeds_settling_and_its_contact_model_explains_the_rest():
    """MuJoCo, given the same robot, servos and start, lands it on the same weight. Both grounds are critically
    damped, so each settles in a few of its contact's time constants: ours 1/√(4·kc/m) = 5 ms (the whole
    mass on four feet), MuJoCo's solref default 20 ms. The settling times' ratio is that of the time
    constants within a factor 2, and MuJoCo's softer contact rests the base lower."""
    system = standing()
    tr = analogy.solve(system, "ode", np.linspace(0, system.t_stop, 501), "accurate", positions=True)
    ours = sum(tr.currents[f"f_{foot}"] for foot in ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"))
    height = system.q0[2] + tr.positions[:, 2]
    p = system.parameters
    time, theirs_height, theirs = mujoco_standing(p["kp"], p["kd"], system.t_stop, system.q0[2])
    w = weight()
    assert abs(ours[-1] - w) <= 1e-6 * w and abs(theirs[-1] - w) <= 1e-3 * w
    ours_settle, theirs_settle = settled(tr.time, ours, w), settled(time, theirs, w)
    assert 0 < ours_settle < system.t_stop and 0 < theirs_settle < system.t_stop
    mass = w / 9.80665
    expected = np.sqrt(mass / (4 * p["kc"])) / 0.02           # our contact's time constant over MuJoCo's
    assert 0.5 <= (ours_settle / theirs_settle) / expected <= 2
    sink_ours, sink_theirs = system.q0[2] - height[-1], system.q0[2] - theirs_height[-1]
    assert 0 < sink_ours < sink_theirs          # MuJoCo's default contact is the softer


@pytest.mark.parametrize("mu", [0.8, 0.0])
def test_friction_holds_a_push_under_mu_times_the_weight_and_nothing_holds_it_without(mu):
    """A push of a tenth of the weight on the standing base from t = 0.1 s: without friction the robot slides
    off as a free mass, x = F·(t − 0.1)²/(2m); with μ = 0.8 (the push under μ·weight) the feet stick. The base
    then moves by the legs' give, F over four hips' kp/L² (L the base's height), and a creep at the
    regularisation's speed, SLIP_SPEED·F/(μ·weight): within twice their sum (the push's step rings)."""
    from analogy.model.contact import SLIP_SPEED
    w = weight()
    system = standing(mu=mu)
    push = 0.1 * w
    system = system.driven([f"step({push!r}, 0.1, 0.001)"] + [0.0] * 17)
    tr = analogy.solve(system, "ode", None, "fast", positions=True)
    x = tr.positions[:, 0]
    slide = push * (system.t_stop - 0.1005) ** 2 / (2 * w / 9.80665)
    if mu == 0.0:
        assert x[-1] == pytest.approx(slide, rel=0.05)        # the feet's drag-free slide: a free mass
    else:
        creep = SLIP_SPEED * push / (mu * w) * (system.t_stop - 0.1)
        give = push / (4 * system.parameters["kp"] / system.q0[2] ** 2)
        assert 0 < x[-1] < 2 * (give + creep) and x[-1] < slide / 100


def test_a_scene_file_frees_the_base_and_names_the_feet(tmp_path):
    from analogy.scenes.toml import load_scene
    (tmp_path / "solo12.urdf").write_text(solo_text())
    (tmp_path / "stand.toml").write_text('dynamics = "nonlinear"\n[model]\nurdf = "solo12.urdf"\nbase = "floating"\n'
                                         'contacts = ["FL_FOOT", "HR_FOOT"]\n[parameters]\nmu = 0.5\n'
                                         '[configuration]\nq = [' + ', '.join(['0'] * 18) + ']\n'
                                         '[inputs]\nforces = [' + ', '.join(['0'] * 18) + ']\n')
    sc = load_scene(tmp_path / "stand.toml")
    assert sc.model.base == "floating" and sc.model.contacts == ("FL_FOOT", "HR_FOOT")
    model = sc.numeric_model()
    assert model.dof == 18 and model.parameters["mu"] == 0.5 and [c.name for c in model.contacts] == ["FL_FOOT", "HR_FOOT"]
