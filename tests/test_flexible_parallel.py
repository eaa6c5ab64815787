"""The parallel-link flexible arm (the flexible-robot paper's Fig. 1.b): its loop, its frequencies against a
finite-element frame, and its circuit.

The finite-element frame (``beam_frame.Frame``) shares only the beams' data with the
assumed modes: 50 Hermite elements a flexible link, the crank, bracket and closing link
as rigid bars, pins and the bracket's clamp as constraints, and gravity's axial forces
from the frame's own statics (the inextensibility multipliers), with no load path assumed.
"""

from dataclasses import replace

import numpy as np
import pytest

from beam_frame import Frame
from analogy.cli import main
from analogy.model.flexible_parallel import FLEXPAR_DEFAULTS as P, flexible_parallel_arm
from analogy.model.mechanism import mechanism_outline
from analogy.presets import preset
from analogy.results.modes import natural_modes
from analogy.scenes.build import scene_system
from analogy.scenes.builtin import scene
from analogy.study.comparison import compare

ELEMENTS = 50
POSES = {"oblique": (0.3, 0.8), "hanging": (-np.pi / 2, 0.0), "upright": (np.pi / 2, 0.0)}
# 4 assumed modes a link against the finite elements on the two lowest elastic frequencies:
# the bound (measured 1.3e-4 to 7.1e-4).
BOUND = 1e-3
# The finite elements' rounding, as in test_flexible_frames: ε·12·n⁴/β⁴ of ω².
FE_FLOOR = 12 * np.finfo(float).eps * ELEMENTS ** 4 / 1.875 ** 4


def _unit(a):
    return np.array([np.cos(a), np.sin(a)])


def frame(pose):
    """flexpar's frame at motor angles *pose*, undeformed; returns it and its two motor locks."""
    t1, t3 = pose
    lc = P["lc"]
    f = Frame()
    a = f.node([0.0, 0.0])
    f.hold(a[0], a[1])
    hub = f.rotation()
    f.inertia(hub, P["Jh1"])
    lock1 = f.lock({hub: 1.0})
    b, _ = f.beam(a, hub, t1, P["l1"], P["rhoA1"], P["EI1"], ELEMENTS)      # AB, pinned at B
    f.point(b, P["mh2"])
    root = f.rotation()
    e, tip = f.beam(b, root, t3, P["l2"], P["rhoA2"], P["EI2"], ELEMENTS)   # the forearm
    f.point(e, P["mp"])
    f.inertia(tip, P["Jp"])
    back = -lc * _unit(t3)
    normal = np.array([-back[1], back[0]]) / lc
    c = f.node(f.xy[b[2]] + back)
    f.bar(b, c, P["mc"])                                                        # bracket BC, clamped to the root
    f.constrain({c[0]: normal[0] / lc, c[1]: normal[1] / lc, b[0]: -normal[0] / lc, b[1]: -normal[1] / lc,
                 root: -1.0})
    d = f.node(back)
    f.bar(a, d, P["mc"])                                                        # crank AD
    f.rotor(d, normal, lc, P["Jh2"])
    lock2 = f.lock({d[0]: normal[0], d[1]: normal[1]})
    f.bar(d, c, P["md"])                                                        # closing link DC
    return f, (lock1, lock2)


def fe_frequencies(pose, locked, gravity=P["g"]):
    f, locks = frame(pose)
    return f.frequencies(gravity, release=[k for j, k in zip((1, 2), locks) if j not in locked])


def am_frequencies(model, pose, locked):
    m = natural_modes(model.joint_space(list(pose) + [0.0] * (model.dof - 2)), locked)
    return np.sign(m.omega_squared) * m.omega / (2 * np.pi)


def elastic(frequencies, locked):
    """The two lowest elastic frequencies: past one rigid-body (or pendulum) mode per free motor."""
    free = 2 - len(locked)
    return frequencies[free:free + 2]


@pytest.fixture(scope="module")
def flexpar4():
    return flexible_parallel_arm(modes1=4, modes2=4)


@pytest.mark.parametrize("pose", POSES, ids=list(POSES))
@pytest.mark.parametrize("locked", [[1, 2], []], ids=["locked", "free"])
def test_the_assumed_modes_converge_from_above_to_the_finite_element_frame(flexpar4, pose, locked):
    """At 4 modes a link, flexpar's lowest two elastic frequencies (gravity on, its geometric
    stiffness with it) lie above the frame's and within 1e-3 of them, motors locked or free,
    hanging, upright and oblique; with the motors free the pendulum frequencies agree too."""
    fe = fe_frequencies(POSES[pose], locked)
    am = am_frequencies(flexpar4, POSES[pose], locked)
    rel = elastic(am, locked) / elastic(fe, locked) - 1
    assert np.all(rel >= -FE_FLOOR) and np.all(rel < BOUND), rel
    if not locked and pose == "oblique":     # two pendulum modes, unstable there: ω² < 0 in both
        assert np.allclose(am[:2], fe[:2], rtol=BOUND)


def test_gravity_s_geometric_stiffness_needs_the_loop_s_foreshortening(flexpar4):
    """Motors locked, the first elastic frequency is 4.288 Hz without gravity; gravity lifts it
    2.2 % hanging and lowers it 2.2 % upright in the frame. The model follows (within 1e-3);
    without the links' foreshortening the loop's curvature under the multipliers that hold
    gravity turns both shifts the wrong way."""
    plain = flexible_parallel_arm(modes1=4, modes2=4, geometric_stiffness=False)
    rest = fe_frequencies(POSES["hanging"], [1, 2], gravity=0.0)[0]
    assert rest == pytest.approx(4.2884, abs=1e-4)
    for pose, sign in (("hanging", 1), ("upright", -1)):
        fe = fe_frequencies(POSES[pose], [1, 2])[0]
        assert sign * (fe / rest - 1) > 0.02
        assert abs(am_frequencies(flexpar4, POSES[pose], [1, 2])[0] / fe - 1) < BOUND
        assert sign * (am_frequencies(plain, POSES[pose], [1, 2])[0] / rest - 1) < 0


def test_gravity_s_stiffness_is_the_derivative_of_its_load_along_the_loop():
    """K_g = Sᵀ·∂G_θ/∂θ·S − Σ μ_c·Sᵀ∇²Φ_c·S (the closed chain's formula) against central
    differences of gravity's load G(q), each G from its own loop closure: h = 1e-6 leaves truncation h²·|G'''|
    and rounding ε·|G|/h, both under 1e-8 of |K_g|."""
    model = flexible_parallel_arm()
    bare = flexible_parallel_arm(g=0.0)
    q = np.array([0.3, 0.8, 0.01, -0.002, 0.005, 0.001])
    kg = model.joint_space(q).stiffness - bare.joint_space(q).stiffness
    h = 1e-6
    def load(x):        # gravity's part of the static load (the links' bending K·δ is in both)
        return model.joint_space(x).gravity - bare.joint_space(x).gravity
    fd = np.column_stack([(load(q + h * e) - load(q - h * e)) / (2 * h) for e in np.eye(q.size)])
    assert np.max(np.abs(kg - fd)) <= 1e-8 * np.max(np.abs(kg))


def test_the_parallelogram_holds_the_forearm_whatever_link_ab_s_end_slope():
    """The paper's motive for Fig. 1.b. In flexpar the forearm's direction θ1 + θ2 is motor 2's
    angle θ3 to first order in the deflections (∂θ2/∂δ = 0, and the error shrinks as δ²); in the
    serial arm, clamped at the elbow (tip frame), it turns with AB's end slope Σψ'(l1)·δ."""
    model = flexible_parallel_arm()
    q = np.array([0.3, 0.8, 0.0, 0.0, 0.0, 0.0])
    (theta2, theta4), rates = model.assemble(q)
    assert theta2 == pytest.approx(0.5, abs=1e-15) and theta4 == pytest.approx(0.3, abs=1e-15)
    assert np.max(np.abs(rates[0, 2:])) <= 1e-14       # forearm: no first-order turn with δ
    assert np.max(np.abs(rates[1, 2:4])) > 1             # the closing link follows AB's tip
    gaps = []
    for size in (1e-3, 5e-4):
        p, _ = model.assemble(q + np.array([0, 0, size, size / 4, 0, 0]))
        gaps.append(abs(p[0] - 0.5))
    # second order: the next adds u_tip/lc of it, 2 % at δ = 1e-3 (u_tip = 2.5e-3 m, lc = 0.1 m)
    assert gaps[0] / gaps[1] == pytest.approx(4.0, rel=0.03)
    tip = {**P, "mh2": 0.5, "Jh2": 5e-4}            # flex2's elbow motor, clamped at the tip frame
    direction = []
    for delta in (0.0, 1e-3):
        _, forearm = mechanism_outline("flex2", np.array([[0.3, 0.5, delta, 0, 0, 0]]), tip, joint_frame="tip")[0]
        direction.append(np.arctan2(*(forearm[1] - forearm[0])[::-1]))
    assert abs(direction[1] - direction[0]) > 1e-3      # ψ'(l1)·δ: the serial forearm follows the slope


def test_the_outline_draws_the_loop_to_first_order_in_the_deflections():
    """The drawing puts the forearm along θ3 from AB's bent tip and closes DC from there: to
    first order in δ it is the assembled loop. The closing link's drawn direction and length
    and the forearm's direction miss the model's θ4, l1 and θ1 + θ2 by O(δ²): each gap falls
    4 times as δ halves (within 10 %, the next order being δ³)."""
    model = flexible_parallel_arm()
    gaps = []
    for size in (1e-3, 5e-4):
        q = np.array([0.3, 0.8, size, size / 4, 0.0, 0.0])
        (lower, upper, loop), = mechanism_outline("flexpar", q[None], P)
        a, d, c, b = loop
        assert np.allclose(b, lower[-1]) and np.allclose(upper[0], b)
        (theta2, theta4), _ = model.assemble(q)
        gaps.append([abs(np.arctan2(*(c - d)[::-1]) - theta4), abs(np.linalg.norm(c - d) - P["l1"]),
                     abs(np.arctan2(*(upper[1] - upper[0])[::-1]) - (q[0] + theta2))])
    np.testing.assert_allclose(np.divide(*gaps), 4.0, rtol=0.1)


def test_modes_from_the_command_line_are_the_model_s(capsys):
    """`analogy modes --robot flexpar --locked 1,2` prints the first locked frequency the model
    gives with its scene's parameters (a horizontal plane)."""
    assert main(["modes", "--robot", "flexpar", "--q=0.3,0.8,0,0,0,0", "--locked", "1,2"]) == 0
    first = am_frequencies(flexible_parallel_arm(**dict(scene("flexpar").parameters)), (0.3, 0.8), [1, 2])[0]
    assert f"{first:g}" in capsys.readouterr().out


@pytest.mark.ngspice
@pytest.mark.deep
def test_the_nonlinear_circuit_converges_as_the_trapezoidal_rule():
    """flexpar's constrained circuit (every joint of the loop a node, the loop held by multiplier
    nodes) against the reduced reference over 0.05 s at the fast preset, at its step cap and at
    half of it: the error falls as h² (a ratio of 4 within a third), so what remains is the
    integration, not the circuit; the loop holds to 1e-8 rad."""
    system = scene_system(scene("flexpar").replace(dynamics="nonlinear", t_stop=0.05))
    errors = []
    for factor in (1, 2):
        p = preset("fast")
        p = replace(p, spice=replace(p.spice, behavioural_max_steps=p.spice.behavioural_max_steps * factor))
        c = compare(system, p, solvers=("spice", "reference"))
        errors.append(c.errors()["spice"].relative)
        assert c.loop["spice"][0] <= 1e-8 and not c.singular
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=1 / 3)


def test_a_flat_parallelogram_is_refused_as_a_singular_pose(capsys):
    """θ3 = θ1 folds the parallelogram flat: the loop's Jacobian in the passive joints is
    singular there, and the command says so in one sentence (exit 2)."""
    assert main(["modes", "--robot", "flexpar", "--q=0.3,0.3,0,0,0,0"]) == 2
    err = capsys.readouterr().err
    # one sentence; a loaded machine may add the model build's progress lines before it
    said = [line for line in err.strip().splitlines() if not line.startswith("analogy: model build")]
    assert "singular pose" in err and "Traceback" not in err and len(said) == 1, err
