"""Bad input: one clear sentence, exit code 2, no traceback, and nothing executed."""

import subprocess
import sys

import numpy as np
import pytest

from analogy import InputError, node_system
from analogy.solvers.transient import netlist
from analogy.model.expressions import parse_expression, parse_matrix, parse_number
from analogy.model.joint import JointSpace


def cli(*args):
    return subprocess.run([sys.executable, "-m", "analogy", *args], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("mass, message", [
    ([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], "must be square"),
    ([[1.0, 0.2], [0.3, 1.0]], "not symmetric"),
    ([[1.0, 2.0], [2.0, 1.0]], "eigenvalue 1 of 2"),
    ([[1.0, np.nan], [np.nan, 1.0]], "non-finite"),
    ([[1.0, 0.0], [0.0, np.inf]], "non-finite"),
])
def test_bad_mass_matrices_are_named(mass, message):
    with pytest.raises(InputError, match=message):
        JointSpace(mass, np.eye(len(mass)))


def test_wrong_lengths_and_unknown_topology():
    js = JointSpace(np.eye(2), np.eye(2))
    with pytest.raises(InputError, match="2 entries"):
        node_system(js, forces=[1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="2 entries"):
        node_system(js, forces=[1.0, 2.0], initial_rates=[0.0])
    with pytest.raises(InputError, match="unknown topology"):
        node_system(js, forces=[1.0, 2.0], topology="ring")
    with pytest.raises(InputError, match="singular"):
        node_system(js, forces=[1.0, 2.0], topology=[[1, 1], [1, 1]])


@pytest.mark.parametrize("text", [
    "__import__('os').system('touch /tmp/x')",
    "().__class__.__bases__[0]",
    "open('/etc/passwd')",
    "lambda: 1",
    "[x for x in (1,)]",
    "a.b",
    "exec('1')",
])
def test_expressions_that_try_to_run_code_are_rejected(text):
    with pytest.raises(InputError):
        parse_expression(text)


def test_expression_grammar_accepts_formulas():
    assert parse_number("pi/2 + 2^3") == pytest.approx(np.pi / 2 + 8)
    m = parse_matrix("[[d1*l1**2, cos(q2)], [cos(q2), 1]]")
    assert m.shape == (2, 2)


@pytest.mark.parametrize("args, fragment", [
    (["--mass", "[[1, 2], [2, 1]]"], "not positive definite: eigenvalue 1 of 2"),
    (["--mass", "[[1, 0.2], [0.3, 1]]"], "not symmetric"),
    (["--mass", "[[1, 0, 0], [0, 1, 0]]"], "must be square"),
    (["--mass", "[[1, 0], [0, nan]]"], "must be finite"),
    (["--param", "l1=inf"], "must be finite"),
    (["--q", "0, 0.3, 1"], "2 joint coordinates"),
    (["--force", "1", "--force", "2", "--force", "3"], "2 entries"),
    (["--topology", "ring"], "unknown topology"),
    (["--r0", "1"], "expected 2 numbers"),
    (["--t-stop", "1e999"], "must be finite"),
    (["--mass", "__import__('os').system('touch /tmp/analogy-pwned')"], "not allowed"),
    (["--param", "l1=__import__('os').system('touch /tmp/analogy-pwned')"], "not allowed"),
    (["--force", "step(__import__('os'))", "--force", "1"], "not allowed"),
    (["--bogus"], "unrecognized arguments"),
    (["--t-stop", "atan2(1)"], "cannot be evaluated"),
    (["--t-stop", "sin((-8)**0.5)"], "cannot be evaluated"),
    (["--t-stop", "1e-300"], "between 1e-9 s and 1e9 s"),
    (["--topology", "[[1e308, 0], [0, 1e308]]"], "node mass matrix M' is not positive definite"),
    (["--mass", "[[a + 0*q1, 0], [0, (-1)**0.5 + a]]", "--param", "a=1"], "complex numbers"),
    (["--mass", "[[a, 0], [0, a]]", "--param", "a=1", "--param", "zz=2"], "--param zz is not used"),
    (["--force", "sine(1, 1, 0)", "--force", "1"], "frequency must be > 0"),
    (["--force", "pulse(0, 1, 0, 1e-6, 1e-6, 0, 3e-6)", "--force", "1"], "too short"),
    (["--robot", "serialN"], "unknown robot"),
])
def test_cli_bad_input_is_one_line_exit_2(args, fragment, tmp_path):
    marker = "/tmp/analogy-pwned"
    res = cli("netlist", *args)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], res.stderr
    assert "Traceback" not in res.stderr and res.stdout == ""
    import os
    assert not os.path.exists(marker)


def test_names_cannot_smuggle_spice_control_lines():
    js = JointSpace(np.eye(2), np.eye(2))
    s = node_system(js, forces=[1.0, 0.0], info={"robot": "evil\n.control\nshell rm -rf /\n.endc"})
    text = netlist(s, title="x\r\n.include /etc/passwd")
    directives = [ln.split()[0] for ln in text.splitlines() if ln.startswith(".")]
    # the one control block is the printing one: 15 digits, which a run in process leaves out
    assert directives == [".ic", ".options", ".tran", ".save", ".print", ".control", ".endc", ".end"]
    assert text.split(".control\n")[1].split(".endc")[0] == "set numdgt=15\n"
    with pytest.raises(InputError, match="unknown node"):
        netlist(s, save=["n1\n.control"])


@pytest.mark.parametrize("args, fragment", [
    (["compare", "--plot", "x.txt"], "cannot plot"),
    (["compare", "--solvers", ""], "names no solver"),
    (["compare", "--csv", "/nonexistent/c.csv"], "cannot write"),
    (["bench", "--csv", "/nonexistent/b.csv"], "cannot write"),
    (["bench", "--repeats", "0"], "at least 1"),
    (["throughput", "-n", "0"], "at least 1"),
    (["draw", "--stem", "../../x"], "plain file name"),
])
def test_other_commands_reject_bad_input_before_working(args, fragment):
    res = cli(*args)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and "Traceback" not in res.stderr
