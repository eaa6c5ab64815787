"""The scene's rules hold in one place: the API, a scene file and the command line refuse the same
scene for the same reason, each naming the part in its own words."""

import subprocess
import sys

import pytest

from analogy.errors import InputError
from analogy.scenes.scene import Scene
from analogy.scenes.spec import ModelSpec
from analogy.scenes.toml import parse_toml

#: Each rule, broken three ways: the spec or scene the API builds (and the field it names), the
#: scene file (and its key), the command line (and its flag), and a word of the one reason.
BROKEN = [
    (lambda: ModelSpec.of("serial2", mass=[[1.0]]), "mass",
     '[model]\nrobot = "serial2"\nmass = [[1.0]]', "[model] mass",
     None, None, "has its own"),
    (lambda: ModelSpec(robot="serial2", link_modes="clamped-free"), "link_modes",
     '[model]\nrobot = "serial2"\nlink_modes = "clamped-free"', "[model] link_modes",
     ["--mass", "[[1, 0], [0, 1]]", "--link-modes", "clamped-free"], "--link-modes", "flexible arms"),
    (lambda: ModelSpec(robot="panda", joints=("panda_joint1",)), "joints",
     '[model]\nrobot = "serial2"\njoints = ["a"]', "[model] joints",
     ["--robot", "panda", "--joints", "panda_joint1"], "--joints", "selects the joints"),
    (lambda: ModelSpec(robot="serial9x"), "robot",
     '[model]\nrobot = "serial9x"', "[model] robot",
     ["--robot", "serial9x"], "--robot", "unknown robot"),
    (lambda: Scene.of("s", "serial2", q=(0.0, 0.3), forces=(1.0, 0.0), t_stop=-1.0), "t_stop",
     "[inputs]\nforces = [1.0, 0.0]\nt_stop = -1", "[inputs] t_stop",
     ["--t-stop", "-1"], "--t-stop", "positive time"),
    (lambda: Scene.of("s", "serial2", q=(0.0, 0.3), forces=(1.0, 0.0), preset="slow"), "preset",
     '[solvers]\npreset = "slow"', "[solvers] preset",
     None, None, "unknown accuracy preset"),
]


def _scene_file(snippet: str) -> str:
    """A valid serial2 scene with the snippet's tables in place of its own."""
    tables = {"[model]": 'robot = "serial2"', "[configuration]": "q = [0.0, 0.3]",
              "[inputs]": "forces = [1.0, 0.0]"}
    for block in snippet.split("\n["):
        head, _, body = ("[" + block.lstrip("[")).partition("\n")
        tables[head] = body
    return "\n".join(f"{head}\n{body}" for head, body in tables.items()) + "\n"


@pytest.mark.parametrize("build, field, toml, key, argv, flag, reason", BROKEN,
                         ids=[row[1] for row in BROKEN])
def test_a_rule_is_one_refusal_that_each_front_end_places_in_its_words(build, field, toml, key, argv, flag,
                                                                         reason, tmp_path):
    with pytest.raises(InputError) as api:
        build()
    assert api.value.field == field
    said = str(api.value)
    if reason is not None:
        assert reason in said
    with pytest.raises(InputError) as from_file:
        parse_toml(_scene_file(toml), "scene.toml")
    assert str(from_file.value).startswith(f"scene.toml: {key}: "), str(from_file.value)
    if reason is not None:
        assert reason in str(from_file.value)
    if argv is None:                    # no flag for it: --preset is checked as it is parsed, and a
        return                          # robot's matrices are flags of --mass alone
    res = subprocess.run([sys.executable, "-m", "analogy", "netlist", *argv], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert res.returncode == 2 and res.stdout == "", res.stderr
    line = res.stderr.strip()
    assert "\n" not in line and line.startswith(f"analogy: error: {flag}: "), line
    if reason is not None:
        assert reason in line


def test_a_built_in_robot_with_matrices_of_its_own_is_refused_for_the_matrix_named():
    """The first matrix given is the one named, whichever front end."""
    with pytest.raises(InputError) as info:
        ModelSpec.of("serial3", damping=[1.0, 1.0, 1.0], gravity=[0.0, 0.0, 0.0])
    assert info.value.field == "damping" and "has its own" in str(info.value)
