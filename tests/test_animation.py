"""Animations: the drawn mechanism is the model's kinematics at the pose ∫v dt, beside its circuit's values."""

import subprocess
import sys

import numpy as np
import pytest

import analogy
from analogy.model.beams import beam_modes
from analogy.model.flexible import FLEXIBLE_DEFAULTS
from analogy.model.mechanism import five_bar_outline, flexible_arm_outline, mechanism_outline, planar_chain_outline
from analogy.results.animation import Motion
from analogy.study.motion import motion

EPS = np.finfo(float).eps


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "analogy", *args], capture_output=True, text=True,
                          timeout=600, cwd=cwd)


def test_a_planar_chain_keeps_every_link_length_and_reaches_its_forward_kinematics():
    rng = np.random.default_rng(1)
    q = rng.uniform(-np.pi, np.pi, (50, 3))
    lengths = {"l1": 1.0, "l2": 0.8, "l3": 0.6}
    for row, (points,) in zip(q, planar_chain_outline(q, lengths)):
        # |p_k − p_(k−1)| = l_k: cos² + sin² = 1 to a few ε, scaled by the length
        assert np.allclose(np.linalg.norm(np.diff(points, axis=0), axis=1), [1.0, 0.8, 0.6], rtol=0, atol=8 * EPS)
        absolute = np.cumsum(row)
        tip = sum(l * np.array([np.cos(a), np.sin(a)]) for l, a in zip((1.0, 0.8, 0.6), absolute))
        assert np.allclose(points[-1], tip, rtol=0, atol=16 * EPS)
    (right_angle,) = planar_chain_outline(np.array([[0.0, np.pi / 2, 0.0]]), lengths)[0]
    assert np.allclose(right_angle[-1], [1.0, 1.4], atol=16 * EPS)


def test_the_five_bar_closes_its_loop_in_the_models_assembly_mode():
    parameters = analogy.robot("parallel2").parameters
    model = analogy.robot("parallel2")
    for q in ([2.0, 1.1], [1.8, 0.9], [2.3, 1.4]):
        polyline, bases = five_bar_outline(np.array([q]), parameters)[0]
        a1, e1, p, e2, a2 = polyline
        # each link keeps its length; the distal pair meets at P (rounding of a sqrt: a few ε·l)
        for start, end, length in ((a1, e1, parameters["la"]), (a2, e2, parameters["la"]),
                                   (e1, p, parameters["lb"]), (e2, p, parameters["lb"])):
            assert np.linalg.norm(end - start) == pytest.approx(length, rel=0, abs=32 * EPS)
        # the model's own assembly (continuation from its reference) puts P at the same place
        psi, _ = model.assemble(q)
        p_model = e1 + parameters["lb"] * np.array([np.cos(psi[0]), np.sin(psi[0])])
        # its Newton solve takes one more step after a correction of 1e-12: ψ to rounding, P to a few ε·lb
        assert np.allclose(p, p_model, rtol=0, atol=32 * EPS)


def test_a_flexible_link_bends_by_its_mode_shapes_and_the_drawing_scales_only_the_bending():
    parameters = dict(FLEXIBLE_DEFAULTS)
    theta, deltas = 0.4, np.array([0.02, -0.005])
    q = np.array([[theta, *deltas]])
    (link,) = flexible_arm_outline(q, parameters, links=1)[0]
    length = parameters["l1"]
    modes = beam_modes(2, length, parameters["rhoA1"], parameters["EI1"])
    tip_deflection = modes.shape([length])[0] @ deltas
    c, s = np.cos(theta), np.sin(theta)
    # r(l) = R(θ)·(l, Σ φ_k(l)·δ_k)
    assert np.allclose(link[-1], [c * length - s * tip_deflection, s * length + c * tip_deflection],
                       rtol=0, atol=64 * EPS)
    straight = flexible_arm_outline(q, parameters, links=1, exaggeration=0.0)[0][0]
    bent5 = flexible_arm_outline(q, parameters, links=1, exaggeration=5.0)[0][0]
    assert np.allclose(np.linalg.norm(np.diff(straight, axis=0), axis=1).sum(), length, rtol=1e-14)
    assert np.allclose(bent5 - straight, 5.0 * (link - straight), rtol=0, atol=64 * EPS)


def test_the_drawn_pose_is_the_integral_of_the_node_voltages():
    # One mass m on a damper b pushed by a step F: v = F/b·(1 − e^(−bt/m)),
    # x = F/b·(t − m/b·(1 − e^(−bt/m))).
    m, b, force, t_stop, points = 2.0, 0.5, 1.5, 10.0, 2001
    system = analogy.node_system(analogy.JointSpace(np.array([[m]]), np.array([[b]])), forces=[force],
                                 t_stop=t_stop)
    run = analogy.solve(system, "exact", t_eval=np.linspace(0, t_stop, points))
    shown = motion(system, run, frames=41)          # every frame on a point of the run
    t = shown.frame_times
    exact = force / b * (t - m / b * (1 - np.exp(-b * t / m)))
    # the trapezoidal rule's error: T·h²/12·max|v''|, with v'' = −F·b/m²·e^(−bt/m)
    h = t_stop / (points - 1)
    bound = t_stop * h ** 2 / 12 * force * b / m ** 2
    assert np.max(np.abs(shown.displacements[:, 0] - exact)) <= bound
    assert shown.outline is None and shown.capacitances is None   # no mechanism: drawn as its node on a rail


def test_a_nonlinear_run_draws_the_capacitances_of_each_pose():
    sc = analogy.scene("default").replace(dynamics="nonlinear", t_stop=4.0)
    system = sc.system()
    run = analogy.solve(system, "ode", preset="fast")
    shown = motion(system, run, frames=9)
    p = system.provenance.parameters
    t_inv = np.linalg.inv(system.topology.matrix)
    for x, caps, (points,) in zip(shown.displacements, shown.capacitances, shown.outline):
        q = system.q0 + t_inv @ x
        # point masses d1 at the elbow, d2 at the tip: M(q) in closed form
        m12 = p["d2"] * (p["l2"] ** 2 + p["l1"] * p["l2"] * np.cos(q[1]))
        m11 = p["d1"] * p["l1"] ** 2 + p["d2"] * (p["l1"] ** 2 + p["l2"] ** 2
                                                   + 2 * p["l1"] * p["l2"] * np.cos(q[1]))
        mass = np.array([[m11, m12], [m12, p["d2"] * p["l2"] ** 2]])
        node_mass = t_inv.T @ mass @ t_inv
        assert np.allclose(caps, node_mass, rtol=0, atol=64 * EPS * np.abs(mass).max())
        elbow = p["l1"] * np.array([np.cos(q[0]), np.sin(q[0])])
        assert np.allclose(points[1], elbow, rtol=0, atol=16 * EPS)
    # the floating capacitor C1_2 = −M'_12 of the linear circuit at q0 is frame 0's
    linear = analogy.scene("default").system()
    assert -shown.capacitances[0][0, 1] == pytest.approx(-linear.node_mass(np.zeros(2))[0, 1], rel=1e-12)


def test_every_drawn_robot_family_has_an_outline_and_the_others_are_drawn_as_nodes():
    q = np.zeros((2, 2))
    assert mechanism_outline("serial2", q, analogy.robot("serial2").parameters) is not None
    assert mechanism_outline("random2", q, {}) is None
    assert mechanism_outline("ur5", np.zeros((2, 6)), {}) is None


@pytest.fixture(scope="module")
def small_motion() -> Motion:
    system = analogy.scene("default").replace(dynamics="nonlinear", t_stop=2.0).system()
    return motion(system, analogy.solve(system, "ode", preset="fast"), frames=5)


def test_an_animation_is_a_gif_of_every_frame_or_a_page_with_no_outside_address(small_motion, tmp_path):
    from PIL import Image
    small_motion.save(tmp_path / "arm.gif", fps=5)
    with Image.open(tmp_path / "arm.gif") as gif:
        assert gif.n_frames == small_motion.frames
    page = small_motion.save(tmp_path / "arm.html").read_text()
    assert "<img" in page and "http://" not in page and "https://" not in page
    assert "&#9654;" in page                    # the play button, as a character
    assert repr(small_motion).startswith("<Motion serial2 nonlinear, ode: 5 frames")


def test_a_contact_sheet_shows_the_first_middle_and_last_frame(small_motion, tmp_path):
    sheet = small_motion.sheet(tmp_path / "sheet.png")
    titles = [ax.get_title() for ax in sheet.axes]
    assert [t.split(",")[0] for t in titles] == ["frame 1 of 5", "frame 3 of 5", "frame 5 of 5"]
    assert (tmp_path / "sheet.png").stat().st_size > 0


@pytest.mark.ngspice
def test_animate_writes_the_circuits_own_run(tmp_path):
    out = cli("animate", "--dynamics", "nonlinear", "--t-stop", "2", "--frames", "6", "-o", "arm.gif",
              "--sheet", "sheet.png", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "6 frames" in out.stdout and "wrote arm.gif" in out.stdout and (tmp_path / "sheet.png").exists()


@pytest.mark.parametrize("args, sentence", [
    (["-o", "arm.txt"], "end the name in .gif, .mp4, .html"),
    (["-o", "arm.gif", "--frames", "1"], "2 to 2000 frames"),
    (["-o", "arm.gif", "--fps", "0"], "--fps must be positive"),
    (["-o", "no/such/arm.gif"], "does not exist"),
])
def test_animate_refuses_what_it_cannot_write_in_one_sentence(tmp_path, args, sentence):
    out = cli("animate", "--solver", "exact", *args, cwd=tmp_path)
    assert out.returncode == 2 and sentence in out.stderr
    assert "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_an_mp4_without_ffmpeg_says_how_to_get_it(monkeypatch):
    import shutil
    from analogy.results.animation import check_animation_path
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(analogy.InputError, match="needs ffmpeg"):
        check_animation_path("arm.mp4")


def test_a_urdf_arm_is_drawn_from_the_joint_frames_pinocchio_places():
    """Each joint's origin and axis in the base frame, and the last body's centre of mass, as
    Pinocchio's forward kinematics gives them at random poses: to rounding of a few products of
    rotations along the chain (16·n·ε of the reach)."""
    pin = pytest.importorskip("pinocchio")
    from analogy.model.mechanism import tree_outline
    from analogy.model.urdf import urdf_model
    from analogy.model.urdf_robots import URDF_ROBOTS, _robots_folder, urdf_robot
    rng = np.random.default_rng(3)
    for name in ("ur5", "double_pendulum"):
        text, joints = urdf_robot(name)
        model = urdf_model(text, joints)
        pm = pin.buildModelFromUrdf(str(_robots_folder() / URDF_ROBOTS[name][0]))
        data = pm.createData()
        qs = rng.uniform(-np.pi, np.pi, (20, model.dof))
        origin, axis, _ = model.tree.joint_frames(qs)
        outline, axes = tree_outline(model.tree, qs)
        n = model.dof
        for k, q in enumerate(qs):
            pin.forwardKinematics(pm, data, q)
            pin.computeJointJacobians(pm, data, q)
            reach = max(np.linalg.norm(data.oMi[j].translation) for j in range(1, n + 1))
            tol = 16 * n * EPS * reach
            for j in range(n):
                assert np.allclose(origin[k, j], data.oMi[j + 1].translation, rtol=0, atol=tol)
                spin = pin.getJointJacobian(pm, data, j + 1, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[3:, j]
                assert np.allclose(axis[k, j], spin, rtol=0, atol=16 * n * EPS)
            (chain,) = outline[k]          # a serial arm: one polyline, base → joints → last body's centre
            assert np.array_equal(chain[0], np.zeros(3)) and np.allclose(chain[1:-1], origin[k], rtol=0, atol=0)
            centre = data.oMi[n].act(pm.inertias[n].lever)
            assert np.allclose(chain[-1], centre, rtol=0, atol=tol)
            # each axis segment is centred on its joint, along its axis
            assert np.allclose(axes[k].mean(axis=1), origin[k], rtol=0, atol=tol)
            assert np.allclose(np.cross(axes[k, :, 1] - axes[k, :, 0], axis[k]), 0.0, rtol=0, atol=tol)


def test_a_urdf_scene_moves_in_space_from_its_own_pose():
    """The drawn robot starts at the scene's pose and follows q0 + T⁻¹·∫v dt: frame 0 is the pose,
    the last frame the pose the run's voltages integrate to."""
    from analogy.model.mechanism import tree_outline
    sc = analogy.scene("double_pendulum")
    system = sc.system()
    model = sc.numeric_model()
    run = analogy.solve(system, "exact", np.linspace(0.0, system.t_stop, 2001))
    shown = motion(system, run, frames=5, model=model)
    assert shown.spatial and shown.joint_axes.shape == (5, model.dof, 2, 3)
    start, _ = tree_outline(model.tree, np.array([sc.q]))
    assert all(np.array_equal(a, b) for a, b in zip(shown.outline[0], start[0]))
    moved = np.array(sc.q) + system.joint_rates(shown.displacements[-1])
    end, _ = tree_outline(model.tree, moved[None])
    assert all(np.array_equal(a, b) for a, b in zip(shown.outline[-1], end[0]))
    assert "azimuth" in shown.note and "linear circuit" in shown.note
    png = shown.frame_png(-1, dpi=40)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name", ["default", "springs3.toml"])
def test_the_circuit_in_motion_keeps_kirchhoffs_current_law_at_every_node_and_frame(name):
    """The currents drawn on the schematic are the circuit's: at every frame the sources' currents into
    each node equal its elements' currents out of it, to rounding of the sum of their sizes."""
    from pathlib import Path
    from analogy.circuit.description import circuit
    from analogy.scenes.toml import load_scene
    sc = load_scene(Path(__file__).parent.parent / "examples" / "scenes" / name) if name.endswith(".toml") \
        else analogy.scene(name)
    system = sc.system()
    run = analogy.solve(system, "exact", np.linspace(0.0, system.t_stop, 1001), positions=True)
    shown = motion(system, run, frames=11)
    c = circuit(system)
    assert set(shown.schematic.parts) == {p.name for p in c.parts} | {s.name for s in c.sources}
    index = {name: k for k, name in enumerate(shown.schematic.parts)}
    balance = np.zeros((shown.frames, system.dof))
    size = np.zeros((shown.frames, system.dof))
    for s in c.sources:                              # scale·f(t) into a, out of b
        for node, sign in ((s.a, 1.0), (s.b, -1.0)):
            if node:
                balance[:, node - 1] += sign * shown.currents[:, index[s.name]]
                size[:, node - 1] += np.abs(shown.currents[:, index[s.name]])
    for e in c.parts:                                # from a through the part to b
        for node, sign in ((e.a, -1.0), (e.b, 1.0)):
            if node:
                balance[:, node - 1] += sign * shown.currents[:, index[e.name]]
                size[:, node - 1] += np.abs(shown.currents[:, index[e.name]])
    # each capacitor's current is c·dv/dt from M'⁻¹ of the same sum: rounding of cond(M')·ε of it
    assert np.all(np.abs(balance) <= 64 * np.linalg.cond(system.mass) * EPS * size)
    assert np.all(shown.current_peaks > 0) and np.max(np.abs(shown.currents)) <= np.max(shown.current_peaks)
    assert shown.frame_png(5, dpi=40)[:4] == b"\x89PNG"


def test_a_circuit_past_a_schematic_moves_as_a_map_of_its_branch_currents():
    """Past the schematic's size the currents are drawn by node pair: antisymmetric off the diagonal,
    and each row sums to the node's injected current T⁻ᵀ·F(t) (Kirchhoff), to rounding of cond(M')·ε."""
    sc = analogy.scene("random10")
    system = sc.system()
    run = analogy.solve(system, "exact", np.linspace(0.0, system.t_stop, 1001))
    shown = motion(system, run, frames=11)         # every frame on a point of the run
    assert shown.schematic is None and shown.branches.shape == (11, system.dof, system.dof)
    b = shown.branches
    off = b - np.einsum("fii->fi", b)[:, :, None] * np.eye(system.dof)
    assert np.array_equal(off, -off.transpose(0, 2, 1))
    injected = system.node_currents(shown.frame_times)
    size = np.abs(b).sum(axis=2) + np.abs(injected)
    assert np.all(np.abs(b.sum(axis=2) - injected) <= 64 * np.linalg.cond(system.mass) * EPS * size)
    assert shown.frame_png(3, dpi=40)[:4] == b"\x89PNG"


def test_a_wide_schematic_in_the_middle_panel_keeps_its_labels_apart():
    """The five-bar's circuit is wide and flat: drawn into the animation's middle column at under 0.7 of
    its own size, its labels shrink with it, so no two of them overlap in the rendered frame."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from analogy.results.animation import _figure
    system = analogy.scene("parallel2").system()
    run = analogy.solve(system, "exact", np.linspace(0.0, system.t_stop, 501), positions=True)
    fig, _ = _figure(motion(system, run, frames=3))
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    middle = max(fig.axes, key=lambda ax: len(ax.texts))          # the schematic's panel
    boxes = [t.get_window_extent(canvas.get_renderer()) for t in middle.texts if t.get_text().strip()]
    assert len(boxes) >= 8
    # a text's box holds its line's leading: two lines of one label touch by a pixel or two, so each
    # box is taken without a fifth of its height; a collision of two labels is far larger than that
    inner = [b.shrunk(1.0, 0.8) for b in boxes]
    crossing = [(a, b) for k, a in enumerate(inner) for b in inner[k + 1:] if a.overlaps(b)]
    assert not crossing, crossing[:3]
