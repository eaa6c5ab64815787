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
    assert rows[0] == ["time [s]"] + [f"r{j}_{s} [rad/s]" for s in ("spice", "ode", "exact") for j in (1, 2)]
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


# ---------------------------------------------------------------- what was built, and how it runs

def test_headers_and_file_names_describe_what_was_built(tmp_path):
    res = cli("netlist", "--robot", "serial4")
    assert res.returncode == 0, res.stderr
    assert "2-DOF" not in res.stdout and "* robot: serial4" in res.stdout
    assert "* forces: F1 = step(1), F2 = step(1), F3 = step(1), F4 = step(1)" in res.stdout
    for mass in ("[[2, 0.5], [0.5, 1]]", "[[3, 0.5], [0.5, 1]]"):
        assert cli("draw", "--mass", mass, "-o", str(tmp_path)).returncode == 0
    assert cli("draw", "-o", str(tmp_path)).returncode == 0
    circuits = sorted(p.name for p in tmp_path.glob("*_circuit.png"))
    assert len(circuits) == 3 and "default_circuit.png" in circuits
    assert all(name.startswith("custom-") for name in circuits if name != "default_circuit.png")


@pytest.mark.ngspice
def test_a_written_netlist_gives_its_results_in_plain_ngspice_batch_mode(tmp_path):
    """`analogy netlist -o d.cir; ngspice -b d.cir` prints the node voltages, within the bound."""
    import shutil

    import numpy as np

    import analogy
    assert cli("netlist", "-o", str(tmp_path / "d.cir")).returncode == 0
    res = subprocess.run([shutil.which("ngspice"), "-b", "d.cir"], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    from analogy.solvers.rawfile import read_printed
    data = read_printed(res.stdout)
    t = data["time"]
    assert np.all(np.diff(t) > 0) and t[-1] == pytest.approx(10.0, rel=1e-12)     # ngspice's own points
    system = analogy.scene("default").system()
    exact = analogy.solve_exact(system, t).voltages
    # the values ngspice computed, with 15 digits: within the accurate bound
    assert analogy.relative_error(np.column_stack([data["n1"], data["n2"]]), exact) <= 1e-6


def test_results_start_at_t0_and_an_output_step_sets_the_rows(tmp_path):
    out = tmp_path / "r.csv"
    res = cli("compare", "--solvers", "ode,exact", "--step", "0.5", "--csv", str(out))
    assert res.returncode == 0, res.stderr
    rows = list(csv.reader(out.open()))
    assert rows[0][0] == "time [s]" and [float(r[0]) for r in rows[1:]] == [0.5 * k for k in range(21)]


@pytest.mark.ngspice
def test_spice_results_include_the_initial_state():
    import analogy
    tr = analogy.solve_spice(analogy.scene("serial2").system(), preset="fast")
    assert tr.time[0] == 0.0 and tr.time[1] > 0
    assert tr.voltages[0].tolist() == analogy.scene("serial2").system().initial_voltages.tolist()


def test_help_says_what_the_tool_does():
    assert cli("--version").stdout.strip() == "analogy 0.1.0"
    assert "serial<N>" in cli("compare", "--help").stdout
    for command in ("compare", "verify", "throughput"):
        text = " ".join(cli(command, "--help").stdout.split())
        assert "fast (better than 1e-3" in text and "accurate (better than 1e-6" in text
    res = cli("netlist", "--param", "q2=pi/4")
    assert res.returncode == 0 and "q2=0.7853981633974483" in res.stdout


@pytest.mark.parametrize("args, fragment", [
    (["--force", "stp(1)", "--force", "1"], "'stp(1)' is not one of hbridge(...), pulse(...), pwl(...)"),
    (["--force", "step(1,2,3,4)", "--force", "1"], "step takes 1 to 3 arguments (amplitude, delay, rise), got 4"),
    (["--robot", "serialN"], "serial<N> (a planar N-joint arm"),
    (["--mass", "[[1, -1], [-1, 1.0000000000001]]"], "F is below the zero tolerance (1e-12"),
    (["--csv", "/nonexistent-folder/x.csv"], "cannot write /nonexistent-folder/x.csv"),
    (["--csv", "/tmp"], "cannot write /tmp: it is a folder"),
    (["--mass", "[]"], "--mass must be a matrix like [[m1, m3], [m3, m2]], not empty"),
    (["--q", "0, 0.5", "--param", "q2=1"], "--q and --param q2 both set the configuration"),
    (["--t-stop", "1e-12"], "--t-stop: t_stop must be a time between 1e-9 s and 1e9 s"),
    (["--param", "d2=0"], "--param: mass matrix M is not positive definite"),
])
def test_bad_input_is_refused_before_any_work(args, fragment):
    res = cli("compare", *args)
    assert res.returncode == 2 and res.stdout == ""
    assert fragment in res.stderr and res.stderr.count("\n") == 1, res.stderr
    assert "Error" not in res.stderr and "positional" not in res.stderr


@pytest.mark.ngspice
def test_a_broken_accuracy_promise_exits_3_after_writing_its_results(tmp_path):
    """An undamped oscillator over 3,200 periods at fast: past the truncation model's samples (320 periods
    it holds within the bound), the step budget cannot pay for the phase cap, and the trapezoidal phase
    drift (ω·h)²·ω·t/12 passes the 1e-3 bound (2.0 measured): flagged, not hidden."""
    out = tmp_path / "long.csv"
    res = cli("compare", "--mass", "[[1,0],[0,1]]", "--damping", "[0,0]", "--stiffness", "[1,4]",
              "--t-stop", "10000", "--preset", "fast", "--csv", str(out))
    assert res.returncode == 3 and out.exists()
    assert "spice error" in res.stderr and "above the fast preset's bound 0.001" in res.stderr


def test_a_slow_unit_is_counted_per_second_not_rounded_to_zero():
    import io
    from analogy.progress import Progress
    p = Progress(12, unit="path run", bar=False, stream=io.StringIO())
    p._start -= 10.0            # three path runs in ten seconds
    p.done = 3
    assert "0.3 path runs/s" in p.line()


def test_batch_report_help_shows_the_report_form(capsys):
    from analogy.cli import main
    with pytest.raises(SystemExit):
        main(["batch", "report", "--help"])
    assert "analogy batch report DIR [-o FOLDER]" in capsys.readouterr().out


def test_a_negative_value_after_a_flag_gets_the_equals_hint():
    out = cli("compare", "--q", "-0.6,0.3")
    assert out.returncode == 2 and "goes after '=', e.g. --q=-0.6,0.3" in out.stderr


def test_a_mass_vector_is_the_diagonal_of_the_mass_matrix():
    out = cli("netlist", "--mass", "[1, 2]", "--damping", "[0.5, 0.25]")
    assert out.returncode == 0, out.stderr
    assert "C1 n1 0 1.0" in out.stdout and "C2 n2 0 2.0" in out.stdout and "C1_2" not in out.stdout


def test_the_draw_note_names_only_the_limit_the_system_passes(tmp_path):
    # serial6: 6 nodes (the limit, not past it) and 20 floating MP models and dampers (past 12)
    out = cli("draw", "--robot", "serial6", "-o", str(tmp_path))
    assert out.returncode == 0, out.stderr
    assert "floating elements (more than 12) are past" in out.stderr and "nodes (more than" not in out.stderr


def test_a_long_solver_run_says_so_and_a_short_one_stays_quiet():
    """The heartbeat speaks only past its quiet time, then says how long the run took."""
    import io
    import time
    from analogy.progress import Heartbeat
    out = io.StringIO()
    beat = Heartbeat(out, quiet=0.05, every=0.05)
    beat("spice")
    deadline = time.monotonic() + 60
    while "running" not in out.getvalue() and time.monotonic() < deadline:
        time.sleep(0.01)
    beat.quiet = 60.0
    beat("ode")                 # ends spice, starts ode
    beat(None)                  # ode ended within its quiet time: nothing said of it
    lines = out.getvalue().splitlines()
    assert lines[0] == "analogy: spice running, 0 s so far" and lines[-1].startswith("analogy: spice finished in")
    assert not any("ode" in line for line in lines)


def test_the_robot_option_says_that_a_robot_with_a_scene_starts_from_it():
    """--robot serial3 takes the serial3 scene's pose, forces and initial rates: the help says so."""
    text = " ".join(cli("compare", "--help").stdout.split())
    assert "A robot with a built-in scene of its name" in text and "forces and initial rates included" in text


def test_a_csv_of_many_rows_holds_every_kth_computed_point_unless_all_are_asked(tmp_path, monkeypatch, capsys):
    """Past CSV_ROWS time points the CSV holds every k-th of them and the last, as computed
    (none interpolated), and says so; --csv-all writes them all, announced with its size."""
    import numpy as np
    from analogy.cli import commands, main
    monkeypatch.setattr(commands, "CSV_ROWS", 50)
    every, full = tmp_path / "every.csv", tmp_path / "all.csv"
    assert main(["compare", "--solvers", "ode,exact", "--no-plot", "--csv", str(full), "--csv-all"]) == 0
    err = capsys.readouterr().err
    rows = np.loadtxt(full, delimiter=",", skiprows=1)
    assert f"writing {len(rows):,} rows to {full}" in err and "--step 0.001 writes 10,001" in err
    assert main(["compare", "--solvers", "ode,exact", "--no-plot", "--csv", str(every)]) == 0
    err = capsys.readouterr().err
    k = -(-len(rows) // 50)
    assert f"holds one in every {k} of the {len(rows):,} time points" in err and "--csv-all" in err
    thinned = np.loadtxt(every, delimiter=",", skiprows=1)
    assert len(thinned) <= 51
    np.testing.assert_array_equal(thinned, rows[np.unique(np.append(np.arange(0, len(rows), k), len(rows) - 1))])


@pytest.mark.deep
def test_the_flexible_arm_s_joint_frame_from_the_command_line():
    """--joint-frame tip --locked 1,2 prints the clamped arm's modes, as the API gives them;
    on a rigid robot the flag is one sentence and exit 2."""
    import numpy as np
    from analogy.model.flexible import flexible_arm
    from analogy.results.modes import natural_modes
    res = cli("modes", "--robot", "flex2", "--joint-frame", "tip", "--q=0.3,0.5,0,0,0,0", "--locked", "1,2")
    assert res.returncode == 0, res.stderr
    first = float(next(line for line in res.stdout.splitlines() if line.split()[:1] == ["1"]).split()[2])
    expected = natural_modes(flexible_arm(2, joint_frame="tip").joint_space([0.3, 0.5, 0, 0, 0, 0]), [1, 2])
    assert first == pytest.approx(expected.omega[0] / (2 * np.pi), rel=1e-5)      # 6 printed digits
    bad = cli("modes", "--robot", "serial2", "--joint-frame", "tip")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "flexible arms" in bad.stderr


@pytest.mark.ngspice
def test_the_readme_symbolic_mass_example_exits_as_the_readme_says(capsys):
    """README: the serial example keeps the accurate bound on r2 (v2 − v1, six times smaller than the node
    voltages whose charges SPICE's step control holds: the truncation model judges r2 itself), and
    with --refine too."""
    from analogy.cli import main
    args = ["compare", "--mass", "[[a + b*cos(q2), b], [b, b]]", "--param", "a=3", "--param", "b=1",
            "--q", "0, 0.5", "--damping", "[1, 2]", "--topology", "serial", "--force", "step(1)",
            "--force", "sine(0, 0.5, 2)", "--solvers", "spice,exact"]
    assert main(args) == 0
    assert "above the accurate preset's bound" not in capsys.readouterr().err
    assert main(args + ["--refine"]) == 0
