"""The robot library as physics: SPD mass matrices, a rigid-body library, kinetic energy, compile once.

Closed chains are sampled by their output pose, not by joint angles: a pose in a
box is mapped by inverse kinematics (written here, in the documented working
mode) to q, and kept only if both kinds of singularity are far away. Type 1
(a leg stretched or folded): |sin(psi_i − q_i)| ≥ sin 20°. Type 2 (the distal
links lose control of the output): five-bar |sin(psi1 − psi2)| ≥ sin 20°;
3-RRR smallest singular value of the rows (u_i, r_i × u_i / rp) ≥ 0.5, where u_i
is the distal direction and r_i the platform joint from the platform centre
(1.22 at the home pose).

The kinetic-energy checks solve each closed chain here, independently of the
package: the five-bar by intersecting two circles, the 3-RRR by Newton on
|C_i − E_i|² = lb² in the platform pose. Velocities come from complex-step
differentiation along q(t) = q0 + t·q̇ (no subtraction, so exact to rounding:
measured ~1e-15, asserted ≤ 1e-12), and from an 8th-order central difference
with h = 3e-4 (truncation ~(h·|q̇|/ρ)⁸ with ρ the distance to a singularity,
rounding ~eps·|x|/(h·|ẋ|): measured ~1e-11, asserted ≤ 1e-9).
"""

import numpy as np
import pytest
import sympy

from analogy.errors import InputError
from analogy.model.linkages import ClosedChainModel
from analogy.model.robots import ROBOTS, five_bar, planar_3rrr, planar_serial, robot
from analogy.model.symbolic import Model

N_SPD = 1000
N_ENERGY = 50
SIN20 = np.sin(np.radians(20.0))


def unit(a):
    return np.array([np.cos(a), np.sin(a)])


def cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def leg_ik(base, target, la, lb, elbow):
    """(q, psi) of an RR leg from *base* to *target*; elbow +1 turns the proximal link counterclockwise."""
    d = target - base
    r = np.hypot(*d)
    c = (la ** 2 + r ** 2 - lb ** 2) / (2 * la * r)
    if abs(c) >= 1:
        return None
    q = np.arctan2(d[1], d[0]) + elbow * np.arccos(c)
    e = target - (base + la * unit(q))
    return q, np.arctan2(e[1], e[0])


# --- five-bar: A_i = (∓d/2, 0), elbows out, end effector P left of E1 -> E2 -----------------------

def five_bar_ik(v, p):
    legs = [leg_ik(np.array([side * v["d"] / 2, 0.0]), p, v["la"], v["lb"], -side) for side in (-1, 1)]
    if None in legs:
        return None
    (q1, psi1), (q2, psi2) = legs
    margins = [abs(np.sin(psi1 - q1)), abs(np.sin(psi2 - q2)), abs(np.sin(psi1 - psi2))]
    return (np.array([q1, q2]), np.array([psi1, psi2])) if min(margins) >= SIN20 else None


def five_bar_bodies(q, v, _guess=None):
    """(mass, inertia, COM, link vector) of every body; works for complex q."""
    la, lb = v["la"], v["lb"]
    a1, a2 = np.array([-v["d"] / 2, 0.0]), np.array([v["d"] / 2, 0.0])
    e1, e2 = a1 + la * unit(q[0]), a2 + la * unit(q[1])
    dd = e2 - e1
    dist = np.sqrt(dd @ dd)                     # no conjugate: analytic for complex steps
    p = e1 + dd / 2 + np.sqrt(lb ** 2 - dist ** 2 / 4) * np.array([-dd[1], dd[0]]) / dist
    return [(v["ma"], v["ja"], (a1 + e1) / 2, e1 - a1), (v["ma"], v["ja"], (a2 + e2) / 2, e2 - a2),
            (v["mb"], v["jb"], (e1 + p) / 2, p - e1), (v["mb"], v["jb"], (e2 + p) / 2, p - e2),
            (v["me"], 0.0, p, None)]


# --- 3-RRR: A_i = rb·u(α_i), C_i = X + rp·u(α_i + phi), elbows counterclockwise -------------------

ALPHAS = np.array([-np.pi / 2, np.pi / 6, 5 * np.pi / 6])


def rrr_joints(pose, v):
    x, y, phi = pose
    return [np.array([x, y]) + v["rp"] * unit(a + phi) for a in ALPHAS]


def rrr_ik(v, pose):
    legs = [leg_ik(v["rb"] * unit(a), c, v["la"], v["lb"], 1) for a, c in zip(ALPHAS, rrr_joints(pose, v))]
    if None in legs:
        return None
    q, psi = np.array([l[0] for l in legs]), np.array([l[1] for l in legs])
    rows = [[np.cos(s), np.sin(s), cross(c - pose[:2], unit(s)) / v["rp"]]
            for s, c in zip(psi, rrr_joints(pose, v))]
    type2 = np.linalg.svd(rows, compute_uv=False)[-1]
    if min(np.abs(np.sin(psi - q))) < SIN20 or type2 < 0.5:
        return None
    return q, psi


def rrr_bodies(q, v, guess):
    """Bodies of the 3-RRR at q (real or complex), platform pose by Newton from *guess*."""
    elbows = [v["rb"] * unit(a) + v["la"] * unit(qi) for a, qi in zip(ALPHAS, q)]
    pose = np.array(guess, dtype=complex if np.iscomplexobj(q) else float)
    for _ in range(12):
        res, jac = [], []
        for a, e, c in zip(ALPHAS, elbows, rrr_joints(pose, v)):
            w = c - e
            res.append(w @ w - v["lb"] ** 2)
            jac.append([2 * w[0], 2 * w[1], 2 * w @ (v["rp"] * np.array([-np.sin(a + pose[2]),
                                                                          np.cos(a + pose[2])]))])
        pose = pose - np.linalg.solve(np.array(jac), np.array(res))
    bodies = []
    for a, e, c in zip(ALPHAS, elbows, rrr_joints(pose, v)):
        base = v["rb"] * unit(a)
        bodies += [(v["ma"], v["ja"], (base + e) / 2, e - base), (v["mb"], v["jb"], (e + c) / 2, c - e)]
    centre = pose[:2]
    bodies.append((v["mp"], v["jp"], centre, rrr_joints(pose, v)[0] - centre))
    return bodies


def kinetic_energy(bodies_at, q0, qdot, v, guess, method):
    """T = ½ Σ (m|v_com|² + I·ω²) along q0 + t·q̇ at t = 0, with ω = (e × ė)/|e|²."""
    if method == "complex":
        h = 1e-30
        moving = bodies_at(q0 + 1j * h * qdot, v, guess)
        rates = [(np.imag(c) / h, None if e is None else np.imag(e) / h) for _, _, c, e in moving]
        still = [(m, j, np.real(c), None if e is None else np.real(e)) for m, j, c, e in moving]
    else:
        h, weights = 3e-4, (4 / 5, -1 / 5, 4 / 105, -1 / 280)
        still = bodies_at(q0, v, guess)
        rates = [(0.0, 0.0)] * len(still)
        for k, w in enumerate(weights, start=1):
            plus, minus = bodies_at(q0 + k * h * qdot, v, guess), bodies_at(q0 - k * h * qdot, v, guess)
            rates = [(r[0] + w * (b[2] - c[2]) / h, None if b[3] is None else r[1] + w * (b[3] - c[3]) / h)
                     for r, b, c in zip(rates, plus, minus)]
    t = 0.0
    for (m, j, _, e), (vc, ve) in zip(still, rates):
        t += 0.5 * m * vc @ vc
        if e is not None:
            t += 0.5 * j * (cross(e, ve) / (e @ e)) ** 2
    return t


# --- samples ---------------------------------------------------------------------------------------

def sample(ik, low, high, n, v, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        pose = rng.uniform(low, high)
        found = ik(v, pose)
        if found is not None:
            out.append((pose, *found))
    return out


@pytest.fixture(scope="module")
def five_bar_model():
    return five_bar()


@pytest.fixture(scope="module")
def rrr_model():
    return planar_3rrr()


@pytest.fixture(scope="module")
def five_bar_samples(five_bar_model):
    # End effector in a 16 x 16 cm box in front of the base.
    return sample(five_bar_ik, [-0.08, 0.10], [0.08, 0.26], N_SPD, five_bar_model.parameters, 1)


@pytest.fixture(scope="module")
def rrr_samples(rrr_model):
    # Platform within ±4 cm and ±0.4 rad of the home pose.
    return sample(rrr_ik, [-0.04, -0.04, -0.4], [0.04, 0.04, 0.4], N_SPD, rrr_model.parameters, 2)


# --- SPD --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", [*ROBOTS, "serial5"])
def test_mass_matrix_is_exactly_symmetric(name):
    m = robot(name).mass_matrix
    assert (m - m.T).applyfunc(sympy.expand) == sympy.zeros(m.rows)


@pytest.mark.parametrize("name", ["redundant", "serial2", "serial3", "serial5"])
def test_open_chain_mass_matrix_is_spd_everywhere(name):
    """Tip masses on every link: T = 0 forces every joint rate to zero, at any q."""
    model = robot(name)
    rng = np.random.default_rng(3)
    lowest = np.inf
    for q in rng.uniform(-np.pi, np.pi, size=(N_SPD, model.dof)):
        m = model.joint_space(q).mass_matrix
        w = np.linalg.eigvalsh(m)
        lowest = min(lowest, w[0] / w[-1])
    assert lowest > 0


def check_closed_chain_spd(model, samples, passive_angles, proximal):
    """Positive definite, and never lighter than the proximal links alone: M − diag(ja + ma·la²/4) ⪰ 0."""
    floor = np.eye(model.dof) * proximal
    for pose, q, psi in samples:
        p, _ = model.assemble(q)
        turn = np.angle(np.exp(1j * (p[:passive_angles] - psi)))
        assert np.max(np.abs(turn)) <= 1e-12                                  # the documented mode
        m = model.joint_space(q).mass_matrix
        assert np.linalg.eigvalsh(m)[0] > 0
        assert np.linalg.eigvalsh(m - floor)[0] >= -1e-15 * np.max(np.abs(m))


def test_five_bar_mass_matrix_is_spd_on_its_workspace(five_bar_model, five_bar_samples):
    v = five_bar_model.parameters
    check_closed_chain_spd(five_bar_model, five_bar_samples, 2, v["ja"] + v["ma"] * v["la"] ** 2 / 4)
    for _, _, psi in five_bar_samples:
        assert np.sin(psi[0] - psi[1]) < 0


def test_3rrr_mass_matrix_is_spd_on_its_workspace(rrr_model, rrr_samples):
    v = rrr_model.parameters
    check_closed_chain_spd(rrr_model, rrr_samples, 3, v["ja"] + v["ma"] * v["la"] ** 2 / 4)
    for pose, q, _ in rrr_samples[:50]:
        np.testing.assert_allclose(rrr_model.assemble(q)[0][3:], pose, atol=1e-12)


# --- rigid-body library -----------------------------------------------------------------------------

def pinocchio_arm(pin, lengths, masses):
    """Planar nR arm: revolute z joints, joint k at the tip of link k − 1, point mass at each tip."""
    model = pin.Model()
    parent, placement = 0, pin.SE3.Identity()
    for k, (length, mass) in enumerate(zip(lengths, masses)):
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{k + 1}")
        model.appendBodyToJoint(parent, pin.Inertia(mass, np.array([length, 0.0, 0.0]), np.zeros((3, 3))),
                                pin.SE3.Identity())
        placement = pin.SE3(np.eye(3), np.array([length, 0.0, 0.0]))
    return model


def crba(pin, model, q):
    m = pin.crba(model, model.createData(), np.asarray(q, dtype=float))
    return np.triu(m) + np.triu(m, 1).T


@pytest.mark.parametrize("name", ["serial2", "serial3", "serial1", "serial4", "serial5", "serial6"])
def test_serial_arms_match_pinocchio(name):
    pin = pytest.importorskip("pinocchio")
    n = int(name[6:])
    rng = np.random.default_rng(n)
    ours = robot(name) if name in ROBOTS else planar_serial(
        n, lengths=rng.uniform(0.2, 1.5, n), masses=rng.uniform(0.1, 3.0, n))
    v = ours.parameters
    arm = pinocchio_arm(pin, [v[f"l{k + 1}"] for k in range(n)], [v[f"d{k + 1}"] for k in range(n)])
    worst = 0.0
    for q in rng.uniform(-np.pi, np.pi, size=(20, n)):
        expected = crba(pin, arm, q)
        got = ours.joint_space(q).mass_matrix
        assert np.linalg.norm(expected - np.diag(np.diag(expected))) > 0 or n == 1
        worst = max(worst, np.max(np.abs(got - expected)) / np.max(np.abs(expected)))
    assert worst <= 1e-12


def test_redundant_actuators_match_pinocchio():
    pin = pytest.importorskip("pinocchio")
    ours = robot("redundant")
    v = ours.parameters
    model = pin.Model()
    parent = 0
    for k, mass in enumerate((v["d1"], v["d2"])):
        parent = model.addJoint(parent, pin.JointModelPX(), pin.SE3.Identity(), f"stage{k + 1}")
        model.appendBodyToJoint(parent, pin.Inertia(mass, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
    np.testing.assert_allclose(ours.joint_space([0.3, -0.2]).mass_matrix, crba(pin, model, [0.3, -0.2]),
                               rtol=1e-12, atol=0)


# --- kinetic energy of the closed chains -------------------------------------------------------------

def energy_errors(model, samples, bodies_at, guess_of, method, parameters=None):
    v = dict(model.parameters, **(parameters or {}))
    rng = np.random.default_rng(5)
    worst = 0.0
    for pose, q, _ in samples[:N_ENERGY]:
        m = model.joint_space(q, parameters).mass_matrix
        for qdot in rng.normal(size=(3, model.dof)):
            t = kinetic_energy(bodies_at, q, qdot, v, guess_of(pose), method)
            worst = max(worst, abs(0.5 * qdot @ m @ qdot - t) / t)
    return worst


@pytest.mark.parametrize("method, bound", [("complex", 1e-12), ("central", 1e-9)])
def test_five_bar_mass_matrix_is_its_kinetic_energy(five_bar_model, five_bar_samples, method, bound):
    assert energy_errors(five_bar_model, five_bar_samples, five_bar_bodies, lambda pose: None,
                         method) <= bound


@pytest.mark.parametrize("method, bound", [("complex", 1e-12), ("central", 1e-9)])
def test_3rrr_mass_matrix_is_its_kinetic_energy(rrr_model, rrr_samples, method, bound):
    assert energy_errors(rrr_model, rrr_samples, rrr_bodies, lambda pose: pose, method) <= bound


def test_overridden_parameters_change_geometry_and_masses():
    """Asymmetric-looking overrides: new lengths move the reference assembly, new masses the energy."""
    model = five_bar()
    override = {"d": 0.08, "la": 0.11, "lb": 0.16, "me": 0.05, "jb": 2e-4}
    v = dict(model.parameters, **override)
    samples = sample(five_bar_ik, [-0.06, 0.12], [0.06, 0.24], 20, v, 7)
    assert energy_errors(model, samples, five_bar_bodies, lambda pose: None, "complex", override) <= 1e-12


def test_configuration_outside_the_workspace_is_an_input_error():
    with pytest.raises(InputError, match="does not assemble"):
        five_bar().joint_space([np.pi + 0.3, -0.3])


# --- compile once -----------------------------------------------------------------------------------

@pytest.mark.parametrize("build, q0, spread", [
    (lambda: robot("serial3"), [0.0, 0.4, -0.7], 1.0),
    (five_bar, [2.1, 0.9], 0.1),
    (planar_3rrr, [2.6, -1.7, 0.35], 0.05),
])
def test_evaluation_does_not_call_sympy_again(monkeypatch, build, q0, spread):
    calls = {"lambdify": 0, "compile": 0}
    lambdify = sympy.lambdify
    compile_open, compile_closed = Model._compile, ClosedChainModel._compile

    def counting_lambdify(*args, **kw):
        calls["lambdify"] += 1
        return lambdify(*args, **kw)

    def counting(original):
        def run(self):
            calls["compile"] += 1
            return original(self)
        return run

    monkeypatch.setattr(sympy, "lambdify", counting_lambdify)
    monkeypatch.setattr(Model, "_compile", counting(compile_open))
    monkeypatch.setattr(ClosedChainModel, "_compile", counting(compile_closed))
    model = build()
    model.joint_space(q0)
    first = dict(calls)
    assert first["compile"] == 1 and first["lambdify"] >= 1
    rng = np.random.default_rng(9)
    masses = [model.joint_space(np.array(q0) + rng.uniform(-spread, spread, len(q0))).mass_matrix
              for _ in range(200)]
    assert calls == first
    assert len({m.tobytes() for m in masses}) == 200


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_the_numeric_serial_chain_is_the_symbolic_arm(n):
    """M = Σ d_k J_kᵀJ_k, G = ∂U/∂q and K = ∂G/∂q by cumulative sums equal sympy's derivation
    to 1e-13, with gravity on and off, at random poses."""
    from analogy.model.robots import planar_serial
    from analogy.model.serial_chain import SerialChain
    symbolic, numeric = planar_serial(n), SerialChain(n)
    assert dict(symbolic.parameters) == numeric.parameters
    rng = np.random.default_rng(n)
    for g in (0.0, 9.81):
        q = rng.uniform(-2, 2, n)
        a, b = symbolic.joint_space(q, {"g": g}), numeric.joint_space(q, {"g": g})
        scale = np.max(np.abs(a.mass_matrix))
        np.testing.assert_allclose(b.mass_matrix, a.mass_matrix, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(b.damping, a.damping, rtol=0, atol=0)
        if g:
            np.testing.assert_allclose(b.stiffness, a.stiffness, rtol=0, atol=1e-13 * g * scale)
            np.testing.assert_allclose(b.gravity, a.gravity, rtol=0, atol=1e-13 * g * scale)


def test_long_serial_arms_are_numeric_and_their_symbolic_model_is_refused_with_a_reason():
    from analogy.errors import InputError
    from analogy.model.robots import robot
    from analogy.model.serial_chain import SerialChain
    from analogy.scenes.build import scene_model
    from analogy.scenes.scene import Scene
    from analogy.scenes.spec import ModelSpec
    model = scene_model(Scene.of("long", ModelSpec(robot="serial200"), q=[0.1] * 200))
    assert isinstance(model, SerialChain) and model.joint_space([0.1] * 200).mass_matrix.shape == (200, 200)
    with pytest.raises(InputError, match="symbolic model .* up to 10 joints"):
        robot("serial11")


def test_every_robot_family_is_one_registry_entry_that_builds():
    """A name resolves to exactly one family, built-in or read from a URDF; each family builds its
    linear system from its entry alone, and an unknown name lists every family in one sentence."""
    from analogy.errors import InputError
    from analogy.model.base import RobotModel
    from analogy.model.catalog import FAMILIES, robot_family
    from analogy.scenes.builtin import SCENES
    from analogy.scenes.scene import Scene
    from analogy.scenes.spec import ModelSpec
    for family in FAMILIES:
        name = f"{family.name}4" if family.sizes else family.name
        assert robot_family(name) == (family, 4 if family.sizes else None)
        if family.flexible:
            continue                        # seconds of sympy each: tests/test_flexible.py builds them
        model = Scene.of(name, ModelSpec(robot=name)).numeric_model()
        assert isinstance(model, RobotModel) and model.closed_chain == name.startswith("parallel")
        if family.urdf is not None:         # its file's joints, each named
            assert model.rigid_tree and len(model.joint_names) == model.dof == len(family.joints or model.joints)
            continue                        # the named robots' scenes: tests/test_robot_defaults.py
        # a robot's own scene where it has one (a closed chain assembles only near its pose)
        sc = SCENES.get(name) or Scene.of(name, ModelSpec(robot=name), q=(0.1,) * len(model.coordinates),
                                          forces=(1.0,) * model.dof)
        system = sc.system()
        assert system.provenance.robot == name and system.dof == model.dof
    assert robot_family("serial2")[0].name == "serial2"       # a fixed name before its family
    with pytest.raises(InputError, match=r"unknown robot 'ur6': use redundant, .*serial<N>.*random<N>.*ur5, ur10, panda"):
        robot_family("ur6")


def test_a_symbolic_model_shows_itself_briefly_and_as_rendered_maths():
    """A short repr, and LaTeX for a notebook: M(q) of the 2R arm has its cos(q2) coupling term."""
    from analogy.model.robots import robot
    model = robot("serial2")
    assert repr(model) == "<Model serial2: coordinates q1, q2; 7 parameters>"
    latex = model._repr_latex_()
    assert latex.startswith("$\\displaystyle M(q) = ") and latex.endswith("$")
    assert "2 d_{2} l_{1} l_{2} \\cos{\\left(q_{2} \\right)}" in latex and "B = " in latex
