"""Hostile and huge input: a one-sentence refusal with exit 2 within milliseconds, never a traceback."""

import os
import subprocess
import sys
import numpy as np
import pytest
import sympy as sp

from analogy import InputError
from analogy.cli import main
from analogy.model.expressions import MAX_EXPONENT, parse_expression, parse_number
from analogy.scenes.paths import inside_folder
from hang_guard import finishes

SYMBOLS = {name: sp.Symbol(name, real=True) for name in ("a", "q1", "q2")}


def refused(capsys, *args) -> str:
    """Run the CLI in process; return its one stderr line after checking exit code 2."""
    code = main(list(args))
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert len(err) == 1 and err[0].startswith("analogy: error: "), err
    return err[0]


@pytest.mark.parametrize("text, fragment", [
    ("9**9**9", "floating-point range"),
    ("exp(exp(539609.85))", "floating-point range"),
    ("pi^(pi^(pi^pi))", "floating-point range"),
    ("a*10**400", "floating-point range"),
    ("a + 10**5000", "floating-point range"),
    ("a*1e300*1e300", "floating-point range"),
    ("2 + q1 + 0**-1", "divides by zero"),
    ("q1/0", "divides by zero"),
    ("q1**1000", f"exceeds {MAX_EXPONENT}"),
    ("q1" + "*q1" * 150, f"exceeds {MAX_EXPONENT}"),
    ("-" * 150 + "q1", "nests more than"),
    ("sin(" * 120 + "q1" + ")" * 120, "nests more than"),
    ("acos(2) + q1", "acos() is given an argument outside its domain"),
    ("(-8)**(1/3) + q1", "complex numbers"),
])
def test_exploding_expressions_are_refused_without_evaluating_them(text, fragment):
    with pytest.raises(InputError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        finishes(lambda: parse_expression(text, SYMBOLS))


def test_underflow_is_an_answer_not_a_memory_explosion():
    assert finishes(lambda: parse_number("2^-(10^30)")) == 0.0
    assert finishes(lambda: parse_expression("2^-(10^30) + a", SYMBOLS)) == SYMBOLS["a"]


def test_constant_parts_of_formulas_keep_their_value():
    names = {**SYMBOLS, "l": sp.Symbol("l", real=True)}
    m = parse_expression("a*l**2/3 + 2*cos(q1) + 2^10", names)
    assert m.subs({names["a"]: 3, names["l"]: 1, names["q1"]: 0}) == 1 + 2 + 1024
    assert parse_expression("q1**2", SYMBOLS).exp == 2          # exponents stay exact integers


@pytest.mark.parametrize("args, fragment", [
    (["--mass", "[[a*10**400, 0], [0, 1]]", "--param", "a=1"], "floating-point range"),
    (["--mass", "[[pi^(pi^(pi^pi)), 0], [0, 1]]"], "floating-point range"),
    (["--mass", "[[a + 10**5000, 0], [0, 1]]", "--param", "a=1"], "floating-point range"),
    (["--mass", "[[2 + q1 + 0**-1, 0], [0, 1]]"], "divides by zero"),
    (["--mass", "[[9**9**9, 0], [0, 1]]"], "floating-point range"),
    (["--mass", "[[exp(exp(539609.85)), 0], [0, 1]]"], "floating-point range"),
    (["--mass", "[[3 + sin(q1) + sin, 0], [0, 1]]", "--param", "sin=2"], "--param sin: not a usable name"),
    (["--mass", "[[3 + arcsin, 0], [0, 1]]", "--param", "arcsin=2"], "--param arcsin: not a usable name"),
    (["--mass", "[[3 + x0, 0], [0, 1]]", "--param", "x0=2"], "--param x0: not a usable name"),
    (["--mass", "[[3 + numpy, 0], [0, 1]]", "--param", "numpy=2"], "--param numpy: not a usable name"),
    (["--mass", "[[3 + (q1+q2+1)**100, 0], [0, 1]]", "--dynamics", "nonlinear"], "expands to about 5.15e+03 terms"),
])
def test_symbolic_path_failures_are_one_sentence(capsys, args, fragment):
    assert fragment in finishes(lambda: refused(capsys, "netlist", *args))


def scene_file(folder, outputs="", inputs="forces = [1, 1]", parameters=""):
    path = folder / "s.toml"
    path.write_text(f'[model]\nmass = [["2 + a", 0.3], [0.3, 1]]\n[parameters]\na = 0\n{parameters}\n'
                    f'[inputs]\n{inputs}\nt_stop = 1\n'
                    f'[outputs]\njoint_rates = true\n{outputs}\n[solvers]\nuse = ["exact"]\n')
    return str(path)


@pytest.mark.parametrize("kwargs, fragment", [
    ({"inputs": "forces = [1, 1]\nt_stop = 1" + "0" * 400}, "TOML syntax error"),
    ({"inputs": "forces = [1" + "0" * 400 + ", 1]"}, "outside the floating-point range"),
    ({"parameters": "b = 1" + "0" * 400}, "[parameters] b: expected a finite number"),
    ({"parameters": "sin = 2"}, "[parameters] sin: not a usable name"),
    ({"outputs": 'csv = "x\\u0000y.csv"'}, "contains a NUL byte"),
])
def test_scene_reader_failures_are_one_sentence(capsys, tmp_path, kwargs, fragment):
    assert fragment in refused(capsys, "run", scene_file(tmp_path, **kwargs))


def test_a_huge_t_stop_is_refused_by_value(capsys, tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[model]\nmass = [[2, 0.3], [0.3, 1]]\n[inputs]\nforces = [1, 1]\n'
                    f't_stop = 1{"0" * 400}\n')
    assert "t_stop: expected a finite number" in refused(capsys, "run", str(path))


def test_an_output_through_a_linked_folder_is_refused(capsys, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    (tmp_path / "scene").mkdir()
    elsewhere.mkdir()
    os.symlink(elsewhere, tmp_path / "scene" / "link")
    message = refused(capsys, "run", scene_file(tmp_path / "scene", 'csv = "link/escaped.csv"'))
    assert "[outputs] csv" in message and "symbolic link" in message
    assert list(elsewhere.iterdir()) == []


def test_an_output_file_linked_elsewhere_is_not_overwritten(capsys, tmp_path):
    victim = tmp_path / "victim.csv"
    victim.write_text("precious")
    (tmp_path / "scene").mkdir()
    os.symlink(victim, tmp_path / "scene" / "victim.csv")
    assert "symbolic link" in refused(capsys, "run", scene_file(tmp_path / "scene", 'csv = "victim.csv"'))
    assert victim.read_text() == "precious"


def test_outputs_in_plain_subfolders_are_written(capsys, tmp_path):
    assert main(["run", scene_file(tmp_path, 'csv = "sub/rates.csv"')]) == 0
    assert (tmp_path / "sub" / "rates.csv").is_file()


@pytest.mark.parametrize("name, fragment", [
    ("x\x00y.csv", "NUL byte"), ("/etc/passwd", "relative path"), ("a/../../b.csv", "relative path"),
    (".", "names no file"),
])
def test_output_names_that_leave_the_folder_are_refused(tmp_path, name, fragment):
    with pytest.raises(InputError, match=fragment):
        inside_folder(tmp_path, name)


def test_the_output_folder_itself_may_be_reached_through_a_link(tmp_path):
    (tmp_path / "real").mkdir()
    os.symlink(tmp_path / "real", tmp_path / "alias")
    assert inside_folder(tmp_path / "alias", "out.csv") == tmp_path / "real" / "out.csv"


def test_numeric_warnings_never_add_lines_to_a_refusal():
    res = subprocess.run([sys.executable, "-m", "analogy", "compare", "--mass", "[[2 + acos(2 + q1), 0], [0, 1]]"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert "non-finite entry" in res.stderr


def test_numeric_warnings_on_success_become_one_sentence(capsys, monkeypatch):
    import numpy as np

    from analogy.cli import commands as cli

    def noisy(args):
        np.ones(3) / np.zeros(3)
        np.exp(np.full(2, 1e4))
        return cli.EXIT_OK
    monkeypatch.setitem(cli._COMMANDS, "scenes", noisy)
    assert main(["scenes"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("analogy: warning: the numerics gave 2 warning(s)"), err


@pytest.mark.parametrize("argv, said", [
    (["throughput", "-n", "1000000000"], "throughput runs at most 1,000,000 scenes"),
    (["ac", "--f-start", "1e-300", "--f-stop", "1e300"], "more than 200,000 frequencies"),
    (["compare", "--param", "g=1e308", "--dynamics", "nonlinear", "--preset", "fast"],
     "--param: the gravity and velocity terms h(x, v) are not finite at the start"),
    # a negative damper feeds energy in without bound: refused as it is for the linear circuit
    (["compare", "--param", "b1=-5", "--dynamics", "nonlinear", "--t-stop", "100"],
     "--param: damping matrix B is not positive semidefinite"),
    # its serial circuit, dense (its default, the modal one, is sparse and runs)
    (["compare", "--robot", "serial500", "--topology", "serial"], "500 nodes) would need about 2.5e+12 operations"),
])
def test_options_that_ask_too_much_get_one_sentence(argv, said, capsys):
    assert finishes(lambda: main(argv)) in (1, 2)
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err


def test_ngspice_points_past_f_stop_are_dropped_and_every_asked_point_kept():
    """Past about 2,000 points a decade ngspice's accumulated step lets a few points beyond f_stop through."""
    from analogy.results.frequency import frequency_grid
    from analogy.solvers.ac import spice_mobility
    from analogy.scenes.builtin import scene
    s = scene("default").system()
    r = spice_mobility(s, 1e-2, 1e2, 10_000)
    np.testing.assert_array_equal(r.frequency, frequency_grid(1e-2, 1e2, 10_000))


def test_a_million_point_pwl_force_is_refused_by_its_segment_count():
    from analogy.scenes.builtin import scene
    from analogy.study.comparison import compare
    from analogy.waveforms import PWL
    t = np.linspace(0.0, 10.0, 10 ** 6)
    sc = scene("default").replace(forces=(PWL(list(zip(t.tolist(), np.sin(t).tolist()))), 0.0))
    with pytest.raises(InputError, match="999,999 segments"):
        finishes(lambda: compare(sc.system(), "fast"))


def test_a_closed_chain_many_turns_from_its_reference_is_refused_not_followed_for_minutes(capsys):
    assert finishes(lambda: main(["netlist", "--robot", "parallel2", "--q", "1e5,0.9"])) == 2
    assert "too far from its reference assembly" in capsys.readouterr().err
