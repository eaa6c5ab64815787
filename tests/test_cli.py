"""The command line: default scene, outputs, exit codes."""

import csv
import subprocess
import sys

import pytest


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "analogy", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd)


def test_netlist_default_scene_to_stdout():
    res = cli("netlist")
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("* analogy default")
    assert "* configuration: q1=0.0, q2=0.3" in res.stdout
    assert res.stdout.rstrip().endswith(".end")


def test_netlist_custom_symbolic_mass_and_topology(tmp_path):
    out = tmp_path / "m.cir"
    res = cli("netlist", "--mass", "[[a + b*cos(q2), b], [b, b]]", "--param", "a=3", "--param", "b=1",
              "--q", "0, 0.5", "--damping", "[1, 2]", "--topology", "[[1, 0], [1, 1]]",
              "--force", "sine(0, 1, 2)", "--force", "pulse(0, 1, 0.1, 1e-3, 1e-3, 0.2, 1)",
              "--save", "n2", "-o", str(out))
    assert res.returncode == 0, res.stderr
    text = out.read_text()
    assert "SIN(" in text and "PULSE(" in text and ".save v(n2)\n" in text
    assert "topology: custom" in text


@pytest.mark.ngspice
def test_compare_writes_table_csv_and_plot(tmp_path):
    res = cli("compare", "--preset", "fast", "--csv", str(tmp_path / "c.csv"),
              "--plot", str(tmp_path / "c.png"))
    assert res.returncode == 0, res.stderr
    assert "spice" in res.stdout and "ode" in res.stdout and "exact" in res.stdout
    with open(tmp_path / "c.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time", "r1_spice", "r2_spice", "r1_ode", "r2_ode", "r1_exact", "r2_exact"]
    assert len(rows) > 10
    assert (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_compare_without_spice_and_help():
    res = cli("compare", "--solvers", "ode,exact", "--no-plot")
    assert res.returncode == 0, res.stderr
    assert "ode" in res.stdout
    for sub in ("netlist", "compare", "verify", "scenes"):
        assert cli(sub, "--help").returncode == 0
    assert cli("--help").returncode == 0


@pytest.mark.parametrize("args, absent", [
    (["netlist"], ["PySpice", "scipy.integrate", "matplotlib"]),
    (["netlist", "--mass", "[[2, 0.5], [0.5, 1]]", "--damping", "[1, 1]"],
     ["PySpice", "scipy", "matplotlib", "sympy"]),
    (["compare", "--solvers", "ode,exact", "--no-plot"], ["PySpice", "matplotlib"]),
])
def test_jobs_import_only_what_they_need(args, absent):
    code = ("import sys\nfrom analogy.cli import main\nrc = main(%r)\n"
            "print(sorted(m for m in %r if m in sys.modules))\nsys.exit(rc)" % (args, absent))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines()[-1] == "[]"
