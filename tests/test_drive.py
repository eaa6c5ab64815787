"""Motors and gearboxes: the robot as a load in its drives' circuit. The winding loops around its
subcircuit agree with the exact solution of the whole, the rotors reflect as Pinocchio's armature,
and the power the drives put in is what the windings, the dampers and the stored energy take."""

import shutil
import subprocess
import sys

import numpy as np
import pytest

import analogy
from analogy.errors import InputError
from analogy.model.motors import Motor, motors_from_table
from analogy.presets import PRESETS
from analogy.solvers.drive import drive, drive_netlist, exact_drive, node_matrices, power_balance
from analogy.study.drive_run import run_drive

EPS = np.finfo(float).eps
#: A motor with a winding inductance (its current a state) and one without (its current follows its voltage).
WOUND = Motor(resistance=0.6, torque_constant=0.07, inductance=5e-4, rotor_inertia=1e-5, gear_ratio=50, viscous=1e-5)
QUICK = Motor(resistance=1.2, torque_constant=0.05, rotor_inertia=2e-5, gear_ratio=30)

pytestmark = pytest.mark.ngspice


def test_the_rotor_reflects_through_its_gear_as_pinocchios_armature():
    """M + N²·J on the diagonal is Pinocchio's CRBA with ``model.armature`` = N²·J, at random poses of the
    UR5, to the rounding of the CRBA (64·n·ε of M's largest entry)."""
    pin = pytest.importorskip("pinocchio")
    from analogy.model.urdf_robots import URDF_ROBOTS, _robots_folder
    sc = analogy.scene("ur5")
    system = sc.system()
    rng = np.random.default_rng(5)
    motors = [Motor(resistance=1.0, torque_constant=0.1, rotor_inertia=float(j), gear_ratio=float(n))
              for j, n in zip(rng.uniform(1e-6, 1e-4, 6), rng.uniform(20, 160, 6))]
    pm = pin.buildModelFromUrdf(str(_robots_folder() / URDF_ROBOTS["ur5"][0]))
    pm.armature = np.array([m.armature for m in motors])
    data = pm.createData()
    model = sc.numeric_model()
    for q in [np.array(sc.q)] + list(rng.uniform(-np.pi, np.pi, (5, 6))):
        ours = model.joint_space(q).mass_matrix + np.diag([m.armature for m in motors])
        theirs = pin.crba(pm, data, q)
        theirs = np.triu(theirs) + np.triu(theirs, 1).T
        assert np.allclose(ours, theirs, rtol=0, atol=64 * 6 * EPS * np.max(np.abs(theirs)))
    # the drive's node mass is the same, mapped to the nodes (the UR5's parallel circuit: T = I)
    mass, _, _, _ = node_matrices(drive(system, motors, ["step(1)"] * 6))
    at = model.joint_space(sc.q).mass_matrix + np.diag([m.armature for m in motors])
    assert np.allclose(mass, at, rtol=0, atol=64 * 6 * EPS * np.max(np.abs(at)))


@pytest.mark.parametrize("name", ["default", "double_pendulum"])
def test_the_drives_circuit_holds_the_bound_against_the_exact_solution_of_the_whole(name):
    """Every joint rate and winding current within the accurate bound of its own peak; the hanging
    double pendulum brings gravity's stiffness (inductors) into the robot."""
    system = analogy.scene(name).system()
    run = run_drive(drive(system, [WOUND, QUICK], ["step(2)", "step(-1)"]), PRESETS["accurate"])
    assert set(run.errors) == {"spice", "ode"} and set(run.errors["spice"]) == {"r1", "r2", "i1", "i2"}
    assert max(run.errors["spice"].values()) <= PRESETS["accurate"].bound, run.errors
    assert max(run.errors["ode"].values()) <= PRESETS["accurate"].bound, run.errors
    # a step of voltage into a wound winding starts its current from zero; without L at once
    spice = run.traces["spice"]
    assert spice.currents[0, 0] == 0.0 and spice.currents[0, 1] == pytest.approx(-1.0 / QUICK.resistance, rel=1e-12)


def test_the_power_put_in_is_what_the_windings_dampers_and_stored_energy_take():
    """The balance is exact up to its time derivative's second-order differences: on the exact solution
    its residual falls four times as the grid's step halves, where the grid resolves the winding's
    L/R = 0.83 ms (20 µs to 5 µs over its first 20 ms, where the inrush makes the residual largest)."""
    d = drive(analogy.scene("default").system(), [WOUND, QUICK], ["step(2)", "step(-1)"])
    peaks = []
    for steps in (1000, 2000, 4000):
        t = np.linspace(0.0, 0.02, steps + 1)
        rates, currents = exact_drive(d, t)
        given = 2.0 * currents[:, 0] - 1.0 * currents[:, 1]
        residual = power_balance(d, t, rates, currents)
        peaks.append(float(np.max(np.abs(residual[1:-1]))) / float(np.max(np.abs(given))))
    assert 3.5 < peaks[0] / peaks[1] < 4.5 and 3.5 < peaks[1] / peaks[2] < 4.5, peaks


@pytest.mark.skipif(shutil.which("ngspice") is None, reason="ngspice's executable is not installed")
def test_the_drive_netlist_runs_in_plain_ngspice_as_it_ran_in_process(tmp_path):
    d = drive(analogy.scene("default").system(), [WOUND, QUICK], ["step(2)", "step(-1)"])
    run = run_drive(d, PRESETS["accurate"])
    text = run.netlist.replace(".end\n", ".print tran v(p1) v(p2)\n.control\nset numdgt=15\n.endc\n.end\n")
    (tmp_path / "drive.cir").write_text(text)
    out = subprocess.run(["ngspice", "-b", str(tmp_path / "drive.cir")], capture_output=True, text=True,
                         timeout=300).stdout
    rows = [ln.split() for ln in out.splitlines() if ln.split()[:1] and ln.split()[0].isdigit()]
    last = [float(x) for x in rows[-1][2:4]]
    # the same run, printed: its last row is t_stop's, as the run's own last point
    assert np.allclose(last, run.traces["spice"].rates[-1], rtol=1e-12, atol=0)


def test_a_motor_file_names_each_field_and_joint_or_is_refused_in_one_sentence():
    table = {"default": {"resistance": "0.6 ohm", "torque_constant": "70 mN*m/A", "inductance": "0.5 mH",
                         "rotor_inertia": "10 kg*cm^2", "gear_ratio": 50},
             "elbow": {"gear_ratio": 30}}
    first, second = motors_from_table(table, ["shoulder", "elbow"])
    assert first.torque_constant == pytest.approx(0.07) and first.rotor_inertia == pytest.approx(1e-3)
    assert second.gear_ratio == 30 and second.resistance == 0.6 and second.armature == pytest.approx(0.9)
    for broken, said in (({"default": {"resistance": 1}}, "needs its torque_constant"),
                         ({"default": {"resistance": "1 kg", "torque_constant": 1}}, "expected a resistance"),
                         ({"default": {"resistance": -1, "torque_constant": 1}}, "must be positive"),
                         ({"default": {"resistance": 1, "torque_constant": 1, "colour": 1}}, "unknown field"),
                         ({"wrist": {"resistance": 1, "torque_constant": 1}}, "not a joint")):
        with pytest.raises(InputError, match=said):
            motors_from_table(broken, ["shoulder", "elbow"])
    with pytest.raises(InputError, match="past its motor's limit"):
        drive(analogy.scene("default").system(), [Motor(1.0, 0.1, voltage_limit=12), None], ["step(24)", None])


def test_the_command_line_drives_a_robot_and_flags_a_winding_past_its_current_limit(tmp_path):
    motors = tmp_path / "motors.toml"
    motors.write_text('[default]\nresistance = "0.6 ohm"\ninductance = "0.5 mH"\ntorque_constant = 0.07\n'
                      'rotor_inertia = "1e-5 kg*m^2"\ngear_ratio = 50\ncurrent_limit = "10 A"\n')

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "analogy", "drive", "--motors", str(motors), *args],
                              capture_output=True, text=True, timeout=300, cwd=tmp_path)
    ok = cli("--voltage", "step(2)", "--voltage", "step(-1)", "-o", "drive.cir", "--csv", str(tmp_path / "d.csv"))
    assert ok.returncode == 0, ok.stderr
    assert "power balance" in ok.stdout and (tmp_path / "drive.cir").read_text().startswith("* analogy drive")
    assert (tmp_path / "d.csv").read_text().startswith("time")     # the command line's files may be anywhere
    hot = cli("--voltage", "step(12)", "--voltage", "step(-1)")
    assert hot.returncode == 3 and "past its limit of 10 A" in hot.stderr
    few = cli("--voltage", "step(2)")
    assert few.returncode == 2 and "one per motor" in few.stderr and "Traceback" not in few.stderr


def test_a_urdfs_transmissions_give_the_gear_ratios_a_motor_file_leaves_out():
    from analogy.model.urdf_file import transmissions
    from analogy.model.urdf_robots import urdf_robot
    reductions = transmissions(urdf_robot("xarm7")[0])
    assert reductions == {f"joint{k}": 100.0 for k in range(1, 8)}
    assert transmissions(urdf_robot("panda")[0]) == {}
    joints = [f"joint{k}" for k in range(1, 8)]
    table = {"default": {"resistance": 1.0, "torque_constant": 0.05}, "joint7": {"gear_ratio": 50}}
    motors = motors_from_table(table, joints, "m.toml", reductions)
    assert [m.gear_ratio for m in motors] == [100.0] * 6 + [50.0]      # the file's own ratio wins


def test_a_pwm_drive_holds_the_bound_against_the_exact_solution_with_the_same_switching_instants():
    """An H-bridge's ±12 V at 2 kHz and 60% duty (edges of 0.1% of a period) on the shoulder: ngspice's
    run of the winding loop against the exact solution carried across every switching corner."""
    system = analogy.scene("default").system().driven(None, 0.02)
    run = run_drive(drive(system, [WOUND, None], ["pwm(12, 0.6, 2000)", None]), PRESETS["accurate"], ("spice", "exact"))
    assert set(run.errors["spice"]) == {"r1", "r2", "i1"}
    assert max(run.errors["spice"].values()) <= PRESETS["accurate"].bound, run.errors
    # the winding's current ripples at the carrier: it rises while +12 V is on and falls while −12 V is
    late, i = run.time > 0.01, run.traces["spice"].currents[:, 0]
    assert np.ptp(i[late]) > 0.1 * np.max(np.abs(i))


def test_an_h_bridge_of_ngspice_switches_holds_the_bound_against_its_own_switching_instants():
    """Four sw switches between a 12 V supply, the shoulder winding's ends and ground, turned by two
    complementary 2 kHz control pulses (60% duty, edges of 1e-7 of the period): each switch turns where
    its control ends its edge, a breakpoint ngspice lands on, so the exact solution of the square wave
    with those instants (and the two closed switches' on-resistance in the loop) judges the run."""
    system = analogy.scene("default").system().driven(None, 0.02)
    d = drive(system, [WOUND, None], ["hbridge(12, 0.6, 2000)", None])
    assert d.motors[0].resistance == WOUND.resistance + 2 * 1e-3          # two closed switches in the loop
    run = run_drive(d, PRESETS["accurate"], ("spice", "exact"))
    switches = [line for line in run.netlist.splitlines() if line.startswith("S1")]
    assert len(switches) == 4 and ".model bridge1 sw" in run.netlist and "Vd1" not in run.netlist
    assert max(run.errors["spice"].values()) <= PRESETS["accurate"].bound, run.errors
    late, i = run.time > 0.01, run.traces["spice"].currents[:, 0]
    assert np.ptp(i[late]) > 0.1 * np.max(np.abs(i))                        # it ripples at the carrier
    # between the voltage's jumps the balance holds as well as the exact run's differences let it
    assert run.balance_error("spice") <= 2 * run.balance_error("exact") + PRESETS["accurate"].bound


def test_coulomb_friction_brakes_the_joint_to_its_steady_rate_with_no_exact_solution_left_silent():
    """One joint (M = 2, B = 1) driven at 2 V through a motor with n = N·k = 1 and R = 1, its rotor's
    Coulomb friction N·c = 0.2 N·m: in steady state (n/R)·(V − n·r) = B·r + N·c·tanh(r/ε), so
    r = (2 − 0.2)/2 = 0.9 rad/s (tanh = 1 to rounding at r/ε = 900). No exact solution exists, so
    scipy at a hundredth of the tolerance is the reference every output is judged against."""
    from analogy.scenes.scene import Scene
    from analogy.solvers.drive import COULOMB_SPEED, exact_drive
    system = Scene.of("one", "serial1", q=(0.0,), forces=(0.0,), t_stop=20.0).system()
    motor = Motor(resistance=1.0, torque_constant=0.1, gear_ratio=10.0, coulomb=0.02)
    d = drive(system, [motor], ["step(2)"])
    with pytest.raises(InputError, match="Coulomb friction has no exact solution"):
        exact_drive(d, [0.0, 1.0])
    run = run_drive(d, PRESETS["accurate"])
    assert run.reference == "reference" and set(run.errors) == {"spice", "ode"}
    assert max(e for errs in run.errors.values() for e in errs.values()) <= PRESETS["accurate"].bound, run.errors
    assert f"I={{0.2*tanh(v(p1)/{COULOMB_SPEED!r})}}" in run.netlist
    r = run.traces["spice"].rates[-1, 0]      # e^(−t/τ), τ = M/(B + n²/R) = 1 s: settled to 2e-9
    assert abs(r - 0.9) <= PRESETS["accurate"].bound * 0.9
    assert run.balance_error("spice") <= 1e-4           # the friction's loss is in the balance


def test_the_nonlinear_drive_tends_to_the_exact_linear_drive_as_the_voltage_goes_to_zero():
    """The full dynamics under motors (M''(x), the velocity terms, the windings) linearise to the linear
    drive's state space: driven by V and −V/2 from rest, the nonlinear motion departs from the exact
    linear one in proportion to V (the velocity terms are second order in the motion, so their share
    is first order), the same share per volt at 1 mV and at 0.1 mV to within 1%."""
    from dataclasses import replace
    from analogy.solvers.drive import exact_drive
    from analogy.study.drive_run import _ode
    sc, t = analogy.scene("default"), np.linspace(0.0, 1.0, 2001)
    tight = replace(PRESETS["accurate"], ode=replace(PRESETS["accurate"].ode, rtol=1e-12))
    shares = []
    for volts in (1e-3, 1e-4):
        waves = [f"step({volts})", f"step({-volts / 2})"]
        rates, currents = exact_drive(drive(sc.system().driven(None, 1.0), [WOUND, QUICK], waves), t)
        full = _ode(drive(replace(sc, dynamics="nonlinear").system().driven(None, 1.0), [WOUND, QUICK], waves),
                    tight, t, None)
        shares.append(np.concatenate([np.max(np.abs(full.rates - rates), axis=0) / np.max(np.abs(rates), axis=0),
                                      np.max(np.abs(full.currents - currents), axis=0)
                                      / np.max(np.abs(currents), axis=0)]))
    np.testing.assert_allclose(shares[0] / shares[1], 10.0, rtol=0.01)
    assert np.max(shares[1]) < 2e-6


def test_ngspice_drives_the_full_nonlinear_circuit_judged_against_scipy_tighter():
    """The robot's nonlinear subcircuit inside the windings' loops: no exact solution, so scipy at a
    hundredth of the tolerance judges; the joint rates hold the bound (the windings' currents are
    flagged where ngspice's Newton tolerance of 1e-6 leaves them past it)."""
    from dataclasses import replace
    system = replace(analogy.scene("default"), dynamics="nonlinear").system().driven(None, 0.5)
    run = run_drive(drive(system, [WOUND, QUICK], ["step(2)", "step(-1)"]), PRESETS["accurate"])
    assert run.reference == "reference" and "Bh1" in run.netlist          # the velocity terms are in the circuit
    assert max(e for k, e in run.errors["spice"].items() if k[0] == "r") <= PRESETS["accurate"].bound, run.errors
    assert max(run.errors["ode"].values()) <= PRESETS["accurate"].bound


@pytest.mark.deep
def test_a_drive_whose_ngspice_run_stalls_is_halted_early_and_retried_within_the_bound():
    """ngspice 39 crawls without end on this drive (both motors, one under a 2 kHz PWM, 20 ms) at the
    accurate settings, never saying "timestep too small". The run is halted once its progress stays
    put for a twentieth of its time limit (15 s of 300), not at the limit, and the retry's looser
    abstol and vntol hold the bound on every output."""
    system = analogy.scene("default").system().driven(None, 0.02)
    run = run_drive(drive(system, [WOUND, QUICK], ["pwm(12, 0.6, 2000)", 0.0]), PRESETS["accurate"],
                    ("spice", "exact"))
    assert max(run.errors["spice"].values()) <= PRESETS["accurate"].bound, run.errors
    if run.note:                    # the stall (ngspice 39), said with the retry
        assert "stalled" in run.note or "time step too small" in run.note, run.note


def test_the_exact_drive_is_an_integration_of_the_whole_state_space():
    """Under a ramp and a pulse the exact drive agrees with scipy's Radau integration of the same state
    space at rtol 1e-11 (its own error about that of the peak)."""
    from scipy.integrate import solve_ivp
    from analogy.solvers.drive import drive_state
    d = drive(analogy.scene("default").system().driven(None, 0.2), [WOUND, QUICK],
              ["pwl(0, 0, 0.1, 3, 0.2, 3)", "pulse(0, -1, 0.05, 0.001, 0.001, 0.02, 0.04)"])
    a, u, load, first = drive_state(d)
    t = np.linspace(0.0, 0.2, 401)
    volts = lambda s: np.array([w(s) if w is not None else 0.0 for w in d.voltages], float)
    corners = sorted({0.0, 0.2, *(float(c) for w in d.voltages for c in w.breakpoints(0.2))})
    y, pieces = np.zeros(len(a)), []
    for lo, hi in zip(corners[:-1], corners[1:]):           # across each corner: no step over a kink
        sol = solve_ivp(lambda s, x: a @ x + u @ volts(s) + load, (lo, hi), y, method="Radau", rtol=1e-11,
                        atol=1e-14, dense_output=True)
        pieces.append((lo, hi, sol.sol))
        y = sol.y[:, -1]
    reference = np.array([next(p for lo, hi, p in pieces if lo <= s <= hi)(s) for s in t])
    rates, _ = exact_drive(d, t)
    want = d.system.joint_rates(reference[:, first:first + 2])
    assert np.max(np.abs(rates - want)) <= 1e-9 * np.max(np.abs(want))


DRIVE_SCENE = '''name = "arm-drive"
[model]
robot = "serial2"
[configuration]
q = [0.0, 0.3]
[inputs]
voltages = ["step(2)", "step(-1)"]
t_stop = 5.0
[motors.default]
resistance = "0.6 ohm"
inductance = "0.5 mH"
torque_constant = "0.07 N*m/A"
rotor_inertia = "1e-5 kg*m^2"
gear_ratio = 50
[motors.2]
resistance = "1.2 ohm"
gear_ratio = 30
[outputs]
joint_rates = true
netlist = "drive.cir"
'''


def test_a_scene_file_s_motors_make_it_a_drive_run_as_the_command_line_runs_one(tmp_path):
    """[motors] and [inputs] voltages: the drive of analogy drive --motors, the same netlist, each output in bound."""
    from analogy.scenes.run import run_scene
    from analogy.scenes.toml import load_scene
    path = tmp_path / "drive.toml"
    path.write_text(DRIVE_SCENE)
    sc = load_scene(path)
    assert sc.motors and sc.voltages == ("step(2)", "step(-1)") and sc.key != sc.replace(motors=(), voltages=(),
                                                                                        forces=(0.0, 0.0)).key
    result = run_scene(sc)
    run = result.drive
    assert set(run.errors) == {"spice", "ode"} and not run.outside_bound()
    assert all(e <= sc.settings.bound for errs in run.errors.values() for e in errs.values())
    assert "power balance" in result.table() and (tmp_path / "drive.cir").read_text() == run.netlist
    motors = tmp_path / "motors.toml"
    motors.write_text(DRIVE_SCENE.split("t_stop = 5.0\n")[1].split("[outputs]")[0].replace("[motors.", "["))
    cli = subprocess.run([sys.executable, "-m", "analogy", "drive", "--motors", str(motors), "--q", "0, 0.3",
                          "--t-stop", "5", "--voltage", "step(2)", "--voltage", "step(-1)", "-o", "cli.cir"],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert cli.returncode == 0, cli.stderr
    body = [line for line in run.netlist.splitlines() if not line.startswith("*")]
    assert [line for line in (tmp_path / "cli.cir").read_text().splitlines() if not line.startswith("*")] == body


@pytest.mark.parametrize("edit, said", [
    (("[inputs]\n", "[inputs]\nforces = [1.0, 0.5]\n"), "[inputs] forces: the motors drive the joints"),
    (("[motors.2]", "[motors.wrist]"), "[motors]: [wrist] is not a joint"),
    (('resistance = "1.2 ohm"', 'resistance = "1.2 kg"'), "expected a resistance"),
    (('voltages = ["step(2)", "step(-1)"]', 'voltages = ["step(2)"]'), "[inputs] voltages: give one per motor"),
    (("dynamics", "dynamics"), None),
])
def test_a_broken_drive_scene_is_refused_in_one_sentence_naming_its_key(tmp_path, edit, said):
    path = tmp_path / "drive.toml"
    text = DRIVE_SCENE.replace(*edit)
    if said is None:                # voltages without motors
        text = text.split("[motors.default]")[0] + "[outputs]\njoint_rates = true\n"
        said = "[inputs] voltages: voltages drive motors"
    path.write_text(text)
    out = subprocess.run([sys.executable, "-m", "analogy", "run", str(path)], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert out.returncode == 2 and said in out.stderr and "Traceback" not in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
