"""Units: inputs may carry them (converted to SI by pint), and every output names its own."""

import math
import re
import subprocess
import sys

import numpy as np
import pytest

from hang_guard import finishes

from analogy.cli import main
from analogy.errors import InputError
from analogy.model.expressions import parse_number, parse_vector
from analogy.model.quantities import split_unit, unit_factor
from analogy.results.output import column_unit
from analogy.scenes.builtin import scene
from analogy.units import joint_units, mechanical_units, rate_label


@pytest.mark.parametrize("text, si", [
    ("100 mm", 0.1), ("30 deg", math.pi / 6), ("2 kg", 2.0), ("500 g", 0.5), ("pi/6 rad", math.pi / 6),
    ("9.81 m/s^2", 9.81), ("5km", 5000.0), ("1.5 N·m", 1.5), ("250 ms", 0.25), ("2 kg*m^2", 2.0),
    ("1e-3", 1e-3), ("2*pi", 2 * math.pi),
])
def test_a_number_with_a_unit_is_its_si_value(text, si):
    assert parse_number(text) == pytest.approx(si, rel=1e-15)


def test_a_degree_is_pi_over_180_radians_and_a_millimetre_a_thousandth_of_a_metre():
    assert unit_factor("deg") == pytest.approx(math.pi / 180, rel=1e-15)
    assert unit_factor("mm") == pytest.approx(1e-3, rel=1e-15)
    assert unit_factor("N*m") == unit_factor("J") == 1.0


@pytest.mark.parametrize("text, message", [
    ("20 degC", "offset unit"), ("3 blorbs", "unknown unit"), ("2 e", "cannot parse"),
    ("1 __import__('os')", "cannot parse"), ("1 m; rm", "cannot parse"),
])
def test_what_is_not_a_unit_is_refused_in_one_sentence(text, message):
    with pytest.raises(InputError, match=message):
        parse_number(text)


def test_the_grammar_s_own_names_are_never_read_as_units():
    assert split_unit("2 e") is None and split_unit("3 pi") is None
    assert split_unit("1e5") is None


def test_a_vector_may_mix_numbers_and_units():
    assert parse_vector("0, 30 deg", numeric=True) == [0.0, pytest.approx(math.pi / 6, rel=1e-15)]


def test_units_give_the_netlist_of_their_si_numbers(capsys):
    assert main(["netlist", "--param", "l1=100 mm", "--q", "0, 30 deg"]) == 0
    with_units = capsys.readouterr().out
    assert main(["netlist", "--param", "l1=0.1", "--q", "0, 0.5235987755982988"]) == 0
    assert capsys.readouterr().out == with_units


def test_a_scene_file_may_give_units(tmp_path, capsys):
    body = ('[model]\nrobot = "serial2"\n[parameters]\nl1 = {l1}\nd2 = {d2}\n[configuration]\n'
            'q = [0, {q}]\n[inputs]\nforces = [1, 0]\nt_stop = {t}\n[outputs]\nnetlist = true\n')
    (tmp_path / "u.toml").write_text(body.format(l1='"100 mm"', d2='"500 g"', q='"30 deg"', t='"2 s"'))
    (tmp_path / "n.toml").write_text(body.format(l1=0.1, d2=0.5, q=0.5235987755982988, t=2))
    outputs = []
    for name in ("u", "n"):
        assert main(["run", str(tmp_path / f"{name}.toml")]) == 0
        outputs.append(capsys.readouterr().out.replace(f"scene {name}", "scene X"))
    assert outputs[0] == outputs[1]


def test_pint_is_imported_only_when_an_input_carries_a_unit():
    code = ("import sys; from analogy.cli import main; main(['netlist', '--q', '0, 0.3']); "
            "print('pint' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().endswith("False")


def test_joint_units_follow_the_joint_kinds_each_model_declares():
    """Units come from what a model says its coordinates are, not from its name."""
    from analogy.model.robots import robot
    assert scene("default").system().provenance.units == ("rad", "rad")
    assert scene("redundant").system().provenance.units == ("m", "m")
    flex = robot("flex2")
    assert flex.joints == ("revolute", "revolute") + ("modal",) * (flex.dof - 2)
    assert flex.units == ("rad", "rad") + ("m",) * (flex.dof - 2)
    assert scene("random10").system().provenance.units is None          # a matrix declares no joints
    assert joint_units(["revolute", "prismatic", "modal"]) == ("rad", "m", "m")
    with pytest.raises(InputError, match="unknown joint kind 'spherical'"):
        joint_units(["spherical"])
    assert rate_label(("rad", "rad")) == "joint rate [rad/s]"
    assert rate_label(("rad", "m")) == "joint rate [rad/s or m/s]"
    assert mechanical_units(("m", "m"))["C"] == "kg" and mechanical_units(("rad",))["C"] == "kg\u00b7m\u00b2"


def test_csv_headers_name_their_units():
    assert column_unit("time") == "s"
    assert column_unit("r2_spice", ("rad", "m")) == "m/s"
    assert column_unit("v_n1_exact") == "V" and column_unit("i_C1_2_spice") == "A"
    assert column_unit("mode") == ""


@pytest.mark.parametrize("unit", ["m^2^2^2^2^2^2^2^2", "m^2^2^2^2^2^2^2^2^2^2", "deg**1000", "m^1e300",
                                  "kg/0", "µ)s", "k·", "m^(2^3)", "(m", "m^", "s^-99", "m^2.5"])
def test_a_unit_is_read_by_a_bounded_grammar_and_refused_in_one_sentence(unit):
    """Exponents are whole numbers up to ±12, written once: a tower of them never reaches pint."""
    with pytest.raises(InputError) as caught:
        finishes(lambda: parse_number(f"1 {unit}"))
    assert "\n" not in str(caught.value) and unit in str(caught.value)


@pytest.mark.parametrize("text, si", [("1 m^-3", 1.0), ("1 s^-1", 1.0), ("2 N m", 2.0), ("3 km^2", 3e6),
                                      ("1 (mm/s)^2", 1e-6), ("1 m2", 1.0), ("1 kg*m^2/s^2", 1.0)])
def test_products_quotients_and_whole_powers_of_units(text, si):
    assert parse_number(text) == pytest.approx(si, rel=4 * np.finfo(float).eps)


@pytest.mark.parametrize("text, dimension, message", [
    ("10 kg", "time", "expected a time, got a unit of [mass]"),
    ("100 kg", ("angle", "length"), "expected an angle or length"),
    ("1 m", ("angular rate", "velocity"), "expected an angular rate or velocity, got a unit of [length]"),
])
def test_a_unit_of_the_wrong_dimension_is_refused(text, dimension, message):
    with pytest.raises(InputError, match=re.escape(message)):
        parse_number(text, dimension)


@pytest.mark.parametrize("text, dimension", [("500 ms", "time"), ("30 deg", ("angle", "length")),
                                             ("100 mm", ("angle", "length")), ("2 rad/s", ("angular rate", "velocity")),
                                             ("5", "time")])
def test_a_unit_of_the_field_s_dimension_is_converted(text, dimension):
    assert parse_number(text, dimension) == parse_number(text)


@pytest.mark.parametrize("argv, flag", [(["--t-stop", "10 kg"], "--t-stop: expected a time"),
                                        (["--q=0, 100 kg"], "--q: expected an angle or length"),
                                        (["--r0=0, 1 m"], "--r0: expected an angular rate or velocity"),
                                        (["--t-stop", "0 m^2^2^2^2^2^2^2"], "--t-stop: 'm^2^2^2^2^2^2^2' is not a unit")])
def test_the_command_line_names_the_option_whose_unit_is_wrong(argv, flag, capsys):
    assert main(["netlist", *argv]) == 2
    err = capsys.readouterr().err
    assert flag in err and err.count("\n") == 1


@pytest.mark.parametrize("argv, message", [
    (["--q=0, 100 mm"], "--q: q2 is an angle (a revolute joint), got a length ('mm')"),
    (["--r0=1 m/s, 0"], "--r0: r1 is an angular rate (a revolute joint), got a velocity ('m/s')"),
    (["--robot", "redundant", "--q=30 deg, 0"], "--q: q1 is a length (a prismatic joint), got an angle ('deg')"),
])
def test_a_coordinate_s_unit_is_judged_by_its_joint_kind(argv, message, capsys):
    """An angle where the joint turns, a length where it slides: the model decides, once it is known."""
    assert main(["netlist", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_a_coordinate_of_its_joint_s_dimension_is_its_si_value(capsys):
    assert main(["netlist", "--q=0, 30 deg"]) == 0
    assert f"q2={math.pi / 6!r}" in capsys.readouterr().out
    assert main(["netlist", "--robot", "redundant", "--q=100 mm, 0.2 m"]) == 0
    assert "q1=0.1, q2=0.2" in capsys.readouterr().out


def test_a_scene_file_s_coordinate_is_judged_by_its_joint_kind(tmp_path, capsys):
    path = tmp_path / "u.toml"
    path.write_text('name = "u"\n[model]\nrobot = "serial2"\n[configuration]\nq = [0, "100 mm"]\n'
                    '[inputs]\nforces = [1, 0]\n')
    assert main(["run", str(path)]) == 2
    assert "[configuration] q: q2 is an angle (a revolute joint), got a length ('mm')" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--param", "l1=30 deg"], "--param l1 is a length (m), got an angle ('deg')"),
    (["--param", "l1=2 s"], "--param l1 is a length (m), got a time ('s')"),
    (["--param", "d2=1 m"], "--param d2 is a mass (kg), got a length ('m')"),
    (["--param", "g=3 kg"], "--param g is measured in m/s^2, got a mass ('kg')"),
    (["--robot", "flex1", "--param", "modes1=2 m"], "--param modes1 is a pure number, got a length ('m')"),
    (["--robot", "parallel2", "--param", "d=1 kg"], "--param d is a length (m), got a mass ('kg')"),
    (["--robot", "parallel2", "--param", "ma=1 m"], "--param ma is a mass (kg), got a length ('m')"),
])
def test_a_parameter_s_unit_is_judged_by_the_dimension_its_model_declares(argv, message, capsys):
    """The five-bar's d is a length where the serial arm's d1 is a mass: each model declares its own."""
    assert main(["netlist", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_a_parameter_of_its_declared_dimension_is_its_si_value(capsys):
    assert main(["netlist", "--param", "l1=500 mm", "--param", "b1=1 N*m*s/rad", "--param", "d1=2000 g"]) == 0
    assert "l1=0.5, l2=0.8, d1=2.0" in capsys.readouterr().out


def test_every_built_in_parameter_declares_its_unit():
    """No parameter of a built-in robot escapes the check: each has an SI unit in the catalogue."""
    from analogy.model.catalog import robot_family
    from analogy.scenes.build import scene_model
    for robot in ("serial2", "serial3", "serial7", "parallel2", "parallel3", "redundant", "flex1", "flex2"):
        sc = scene("default").replace(model=scene("default").model.__class__(robot=robot))
        names = list(scene_model(sc).parameters)
        assert set(robot_family(robot)[0].parameter_units(names)) == set(names), robot


@pytest.mark.parametrize("argv, message", [
    (["--force", "1 N", "--force", "1 N*m"], "--force: F1 is a torque (a revolute joint), got a force ('N')"),
    (["--robot", "redundant", "--force", "1 N", "--force", "1 N*m"],
     "--force: F2 is a force (a prismatic joint), got a torque ('N*m')"),
    (["--force", "2 m", "--force", "1"], "--force: expected a torque or force, got a unit of [length] ('m')"),
])
def test_a_force_s_unit_is_judged_by_its_joint_kind(argv, message, capsys):
    assert main(["netlist", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_a_result_frame_carries_its_columns_units():
    """Plain column names to index by, and the units the CSV header gives, in frame.attrs."""
    from analogy.study.comparison import compare
    frame = compare(scene("redundant").replace(t_stop=0.5).system(), "fast", ["ode", "exact"]).to_frame()
    units = frame.attrs["units"]
    assert "r1_ode" in frame.columns and units["r1_ode"] == "m/s" and units["time"] == "s"
