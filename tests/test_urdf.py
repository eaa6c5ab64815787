"""URDF robots: M(q), G(q), c(q, q̇) and ∂G/∂q from the kinematic tree, against Pinocchio, and their circuits."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from analogy import InputError
from analogy.cli import main
from analogy.model.urdf import UrdfModel

BENCH = Path(__file__).parent / "urdf" / "bench.urdf"

#: The two sum the same products in other orders: each entry is a sum of about n² terms no
#: larger than the quantity's peak over the poses, so they agree to about n²·ε of that peak
#: (2e-14 for n = 10); 1e-12 of the peak is the promise.
AGREEMENT = 1e-12


def random_tree_urdf(seed: int, movable: int = 6) -> str:
    """A random kinematic tree: branches, revolute, continuous and prismatic joints on unnormalised
    axes, fixed joints carrying links, rotated joint and inertial frames, and massless links; its
    joints are named out of file order."""
    rng = np.random.default_rng(seed)
    links = ['<link name="base"/>']
    joints = []
    names = ["base"]

    def inertial():
        a = rng.normal(size=(3, 3))
        moments = np.sort(rng.uniform(0.01, 0.1, 3))
        moments[2] = min(moments[2], moments[0] + moments[1])
        xyz, rpy = rng.uniform(-0.2, 0.2, 3), rng.uniform(-np.pi, np.pi, 3)
        del a
        return (f'<inertial><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>'
                f'<mass value="{rng.uniform(0.2, 3.0)}"/><inertia ixx="{moments[0]}" ixy="0" ixz="0" '
                f'iyy="{moments[1]}" iyz="0" izz="{moments[2]}"/></inertial>')

    def joint(name, kind, parent, child):
        xyz, rpy, axis = rng.uniform(-0.4, 0.4, 3), rng.uniform(-np.pi, np.pi, 3), rng.normal(size=3)
        return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
                f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>'
                f'<axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>'
                f'<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>')
    label = rng.permutation(movable)        # joint names out of file order: q follows Pinocchio's order
    for k in range(movable):
        parent = names[rng.integers(len(names))]
        kind = rng.choice(["revolute", "continuous", "prismatic"])
        links.append(f'<link name="l{k}">{inertial()}</link>')
        joints.append(joint(f"j{label[k]}", kind, parent, f"l{k}"))
        names.append(f"l{k}")
        if rng.random() < 0.4:          # a part on a fixed joint, with or without mass
            links.append(f'<link name="f{k}">{inertial() if rng.random() < 0.7 else ""}</link>')
            joints.append(joint(f"fixed{k}", "fixed", f"l{k}", f"f{k}"))
            names.append(f"f{k}")
    return f'<robot name="tree{seed}">' + "".join(links + joints) + "</robot>"


def _pinocchio_differences(path: Path, poses: int = 100, seed: int = 0, joints=None) -> dict:
    pin = pytest.importorskip("pinocchio")
    ours = UrdfModel(path.read_text(), joints)
    pm = pin.buildModelFromUrdf(str(path))
    if joints is not None:              # the others frozen at 0, as the model freezes them
        frozen = [pm.getJointId(name) for name in pm.names[1:] if name not in joints]
        pm = pin.buildReducedModel(pm, frozen, pin.neutral(pm))
    pd = pm.createData()
    pm.gravity.linear = np.array([0.0, 0.0, -ours.parameters["g"]])
    rng = np.random.default_rng(seed)
    diff: dict = {k: 0.0 for k in ("M", "G", "c", "dG/dq")}
    peak = dict(diff)
    tree = ours.tree
    for _ in range(poses):
        q, qd = rng.uniform(-np.pi, np.pi, ours.dof), rng.normal(size=ours.dof)
        qp = pin.integrate(pm, pin.neutral(pm), q)      # continuous joints are (cos, sin) in Pinocchio
        m = pin.crba(pm, pd, qp)
        m = np.triu(m) + np.triu(m, 1).T
        g = pin.computeGeneralizedGravity(pm, pd, qp).copy()
        c = pin.rnea(pm, pd, qp, qd, np.zeros(ours.dof)) - g
        dg = pin.computeGeneralizedGravityDerivatives(pm, pd, qp)
        for key, mine, theirs in (("M", tree.mass_matrix(q), m), ("G", tree.gravity_load(q), g),
                                  ("c", tree.velocity_load(q, qd), c), ("dG/dq", tree.gravity_stiffness(q), dg)):
            diff[key] = max(diff[key], float(np.abs(mine - theirs).max()))
            peak[key] = max(peak[key], float(np.abs(theirs).max()))
    return {k: diff[k] / peak[k] for k in diff}


def test_the_bench_urdf_matches_pinocchio_at_100_poses():
    """A prismatic joint, a continuous one, a fixed joint and a rotated inertial frame."""
    rel = _pinocchio_differences(BENCH)
    assert max(rel.values()) <= AGREEMENT, rel


@pytest.mark.parametrize("seed", range(8))
def test_random_trees_match_pinocchio(tmp_path, seed):
    path = tmp_path / "tree.urdf"
    path.write_text(random_tree_urdf(seed))
    rel = _pinocchio_differences(path, poses=20, seed=seed)
    assert max(rel.values()) <= AGREEMENT, rel
    import pinocchio as pin
    assert list(UrdfModel(path.read_text()).joint_names) == list(pin.buildModelFromUrdf(str(path)).names[1:])


def test_the_mass_matrix_is_symmetric_positive_definite_and_gravity_stiffness_symmetric():
    m = UrdfModel(BENCH.read_text())
    for q in np.random.default_rng(1).uniform(-3, 3, (20, 3)):
        mq = m.tree.mass_matrix(q)
        assert np.array_equal(mq, mq.T) and np.linalg.eigvalsh(mq).min() > 0
        k = m.tree.gravity_stiffness(q)
        assert np.array_equal(k, k.T)


def test_the_slide_along_x_feels_no_gravity_and_its_damper_is_a_resistor():
    """The slide is horizontal: G and ∂G/∂q vanish on its row; <dynamics damping> is B's diagonal."""
    m = UrdfModel(BENCH.read_text())
    j = m.joint_space([0.3, 0.5, -0.3])
    weight = 9.80665 * (4.0 + 1.5 + 0.5 + 0.8)         # its terms are this large: zero to rounding of them
    assert abs(j.gravity[0]) <= 10 * np.finfo(float).eps * weight
    assert np.abs(j.stiffness[0]).max() <= 10 * np.finfo(float).eps * weight
    np.testing.assert_array_equal(np.diag(j.damping), [2.0, 0.05, 0.0])
    assert m.units == ("m", "rad", "rad")


def test_a_urdf_scene_key_follows_the_file_content_not_its_path(tmp_path, capsys):
    from analogy.cli.parser import build_parser
    from analogy.cli.scene_options import scene_from_args
    a, b = tmp_path / "a.urdf", tmp_path / "sub" / "b.urdf"
    b.parent.mkdir()
    a.write_text(BENCH.read_text())
    b.write_text(BENCH.read_text())

    def key(path):
        return scene_from_args(build_parser().parse_args(["compare", "--urdf", str(path)])).key
    assert key(a) == key(b)
    b.write_text(BENCH.read_text().replace('value="4.0"', 'value="4.5"'))
    assert key(a) != key(b)


@pytest.mark.ngspice
def test_the_bench_circuit_keeps_the_accurate_bound_on_every_joint(capsys):
    assert main(["compare", "--urdf", str(BENCH), "--q", "0.1, 0.5, -0.3", "--t-stop", "2", "--no-plot"]) == 0
    out = capsys.readouterr().out
    assert "robot bench" in out


@pytest.mark.ngspice
def test_the_written_netlist_runs_in_plain_ngspice(tmp_path):
    cir = tmp_path / "bench.cir"
    assert main(["netlist", "--urdf", str(BENCH), "--q", "0.1, 0.5, -0.3", "--t-stop", "1", "-o", str(cir)]) == 0
    run = subprocess.run(["ngspice", "-b", str(cir)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "Timestep too small" not in run.stdout + run.stderr


_GOOD = BENCH.read_text()


@pytest.mark.parametrize("text, said", [
    (None, "no URDF file"),
    ("<robot name='x'><link name='a'>", "not a readable URDF"),
    (_GOOD.replace('value="4.0"', 'value="-4.0"'), "link carriage: mass -4 is negative"),
    (_GOOD.replace('ixx="0.02"', 'ixx="-0.02"'), "link carriage: its inertia is not positive semidefinite"),
    (_GOOD.replace('izz="0.04"', ''), "its <inertia> has no izz"),
    (_GOOD.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 1"/>'), "joint turn: axis must be three finite numbers"),
    (_GOOD.replace('<origin xyz="0.1 0 0.1"/>', '<origin xyz="1e400 0 0.1"/>'), "joint turn: origin xyz must be"),
    (_GOOD.replace('<link name="table">', '<link name="carriage"/><link name="table">'), "two links are named"),
    (_GOOD.replace('value="4.0"', 'value="0"').replace('value="1.5"', 'value="0"').replace(
        'value="0.5"', 'value="0"').replace('value="0.8"', 'value="0"'), "joint slide moves no mass or inertia"),
    (_GOOD.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), "joint turn has no axis"),
    (_GOOD.replace('type="continuous"', 'type="floating"'), "joint turn is floating"),
    (_GOOD.replace('<dynamics damping="0.05"/>', '<mimic joint="slide"/>'), "joint turn mimics slide"),
    (_GOOD.replace('<link name="floor"/>', '<link name="floor"/><link name="stray"/>'), "2 root links"),
    (_GOOD.replace('damping="2.0"', 'damping="-2.0"'), "joint slide: damping -2 is negative"),
])
def test_bad_urdf_input_is_one_sentence_and_exit_2(tmp_path, capsys, text, said):
    path = tmp_path / "robot.urdf"
    if text is not None:
        path.write_text(text)
    assert main(["netlist", "--urdf", str(path)]) == 2
    err = capsys.readouterr().err
    assert said in err and err.count("\n") == 1 and err.startswith("analogy: error: --urdf: "), err


def test_a_selection_freezes_the_other_joints(capsys):
    """Keeping the turntable and the arm, the slide frozen at 0: the same M as the full tree's
    lower-right block, since the slide's coordinate does not enter M."""
    full = UrdfModel(_GOOD)
    kept = UrdfModel(_GOOD, ["turn", "tilt"])
    q = [0.0, 0.5, -0.3]
    np.testing.assert_array_equal(kept.tree.mass_matrix(q[1:]), full.tree.mass_matrix(q)[1:, 1:])
    with pytest.raises(InputError, match="no movable joint 'mount'"):
        UrdfModel(_GOOD, ["mount"])


def test_a_scene_file_names_its_urdf_relative_to_itself(tmp_path):
    from analogy.scenes.toml import load_scene
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "bench.urdf").write_text(_GOOD)
    scene_file = tmp_path / "bench.toml"
    scene_file.write_text('name = "bench"\n[model]\nurdf = "arms/bench.urdf"\njoints = ["turn", "tilt"]\n'
                          '[configuration]\nq = [0.5, -0.3]\n[inputs]\nforces = [1, 0.5]\nt_stop = 2\n')
    sc = load_scene(scene_file)
    assert sc.model.urdf == _GOOD and sc.model.joints == ("turn", "tilt") and sc.system().dof == 2
    # an input is read, never written: a URDF beside the scene's folder, or anywhere, is the user's to name
    (tmp_path / "scenes").mkdir()
    beside = tmp_path / "scenes" / "bench.toml"
    beside.write_text(scene_file.read_text().replace("arms/bench.urdf", "../arms/bench.urdf"))
    assert load_scene(beside).model == sc.model
    beside.write_text(scene_file.read_text().replace("arms/bench.urdf", str(tmp_path / "arms" / "bench.urdf")))
    assert load_scene(beside).model == sc.model
    beside.write_text(scene_file.read_text().replace("arms/bench.urdf", "../arms/missing.urdf"))
    with pytest.raises(InputError, match=r"\[model\] urdf: .*missing.urdf"):
        load_scene(beside)


@pytest.mark.deep                   # 7 s: in CI's deep pass
def test_a_chain_of_two_thousand_links_loads_without_recursion():
    links = "".join(f'<link name="l{k}"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" '
                    f'iyy="0.01" iyz="0" izz="0.01"/></inertial></link>' for k in range(2001))
    joints = "".join(f'<joint name="j{k:04d}" type="revolute"><parent link="l{k}"/><child link="l{k + 1}"/>'
                     f'<origin xyz="0.01 0 0"/><axis xyz="0 0 1"/></joint>' for k in range(2000))
    assert UrdfModel(f'<robot name="long">{links}{joints}</robot>').dof == 2000


def test_gravity_terms_at_rounding_are_zero_not_huge_inductors():
    """At q = 0 the bench's tilt axis is level and its load is rounding: below 16·n·ε·g·Σm·reach
    the entries are zero, so no inductor of 1e30 H of either sign appears."""
    m = UrdfModel(_GOOD)
    j = m.joint_space([0.0, 0.0, 0.0])
    floor = 16 * m.dof * np.finfo(float).eps * m.gravity_scale
    for part in (j.gravity, j.stiffness):
        if part is not None:
            assert np.all((part == 0) | (np.abs(part) >= floor))


def test_a_stack_of_poses_gives_each_pose_its_joint_space():
    m = UrdfModel(_GOOD)
    qs = np.random.default_rng(2).uniform(-2, 2, (5, 3))
    stack = m.joint_stack(qs)
    for k, q in enumerate(qs):                  # a numpy row is a pose as a list is
        j = m.joint_space(q)
        np.testing.assert_array_equal(stack.mass_matrix[k], j.mass_matrix)
        np.testing.assert_array_equal(stack.gravity[k], j.gravity)


@pytest.mark.parametrize("name", ["ur3", "ur5", "ur10", "panda", "kinova", "xarm7", "z1", "double_pendulum"])
def test_the_named_robots_match_pinocchio_at_100_poses(name):
    from analogy.model.urdf_robots import URDF_ROBOTS, _robots_folder
    relative, joints = URDF_ROBOTS[name]
    rel = _pinocchio_differences(_robots_folder() / relative, joints=joints)
    assert max(rel.values()) <= AGREEMENT, rel


def test_a_named_robot_without_its_package_is_one_sentence(monkeypatch, capsys):
    from importlib import metadata

    def missing(name):
        raise metadata.PackageNotFoundError(name)
    monkeypatch.setattr(metadata, "distribution", missing)
    assert main(["netlist", "--robot", "ur5"]) == 2
    err = capsys.readouterr().err
    assert "pip install 'analogy[robots]'" in err and err.count("\n") == 1


@pytest.mark.ngspice
def test_the_ur5_and_the_panda_keep_the_accurate_bound_on_every_joint(capsys):
    """Without gravity (with it, a pose held by no torque is unstable and the linear motion grows)."""
    for args in (["--robot", "ur5", "--q", "0, -1, 1, 0, 1, 0"],
                 ["--robot", "panda", "--q", "0, 0.3, 0, -1.5, 0, 1.8, 0.7"]):
        assert main(["compare", *args, "--param", "g=0", "--t-stop", "2", "--no-plot"]) == 0, capsys.readouterr()


def test_a_urdf_read_before_comes_from_the_cache_without_its_parser(tmp_path, monkeypatch):
    """Keyed by the file's text, the selection and the code; a damaged entry is rebuilt."""
    import analogy.model.urdf as urdf
    monkeypatch.setenv("ANALOGY_CACHE_DIR", str(tmp_path))
    first = UrdfModel(_GOOD, ["turn", "tilt"])
    (entry,) = tmp_path.glob("urdf-*.npz")

    def no_parser(text):
        raise AssertionError("parsed again")
    monkeypatch.setattr(urdf, "parse_urdf", no_parser)
    again = UrdfModel(_GOOD, ["turn", "tilt"])
    q = [0.4, -0.2]
    assert again.joint_names == first.joint_names and again.name == "bench"
    np.testing.assert_array_equal(again.tree.mass_matrix(q), first.tree.mass_matrix(q))
    np.testing.assert_array_equal(again.joint_space(q).gravity, first.joint_space(q).gravity)
    monkeypatch.undo()
    monkeypatch.setenv("ANALOGY_CACHE_DIR", str(tmp_path))
    entry.write_bytes(b"PK\x03\x04 not an archive")
    rebuilt = UrdfModel(_GOOD, ["turn", "tilt"])
    np.testing.assert_array_equal(rebuilt.tree.mass_matrix(q), first.tree.mass_matrix(q))
