"""Ground contact: a one-sided spring and damper smoothed over δ, and the hopper that drops onto it."""

import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

import analogy
from analogy.errors import InputError
from analogy.model.legged import HOPPER, hopper
from analogy.solvers.ode import solve_ode

#: The ODE's tolerance for the closed-form checks: far under the smoothing's own effect.
RTOL = 1e-12


def drop(**values):
    """The hopper's drop scene's system at parameter *values*."""
    return analogy.scene("hopper").replace(parameters=values).system() if values else analogy.scene("hopper").system()


def stance_flow(p):
    """ẏ = A·y + b of the hopper with its foot in the ground under the sharp law f = kc·p + cc·ṗ, y = (q, q̇)."""
    mass = np.array([[p["mb"] + p["mf"], p["mf"]], [p["mf"], p["mf"]]])
    # the ground's spring and damper act on the foot's height q1 + q2, the leg's on q2
    k = np.array([[p["kc"], p["kc"]], [p["kc"], p["kc"] + p["kl"]]])
    c = np.array([[p["cc"], p["cc"]], [p["cc"], p["cc"] + p["bl"]]])
    load = -np.array([p["g"] * (p["mb"] + p["mf"]), p["g"] * p["mf"] + p["kl"] * p["l0"]])
    inv = np.linalg.inv(mass)
    a = np.block([[np.zeros((2, 2)), np.eye(2)], [-inv @ k, -inv @ c]])
    return a, np.concatenate([np.zeros(2), inv @ load])


def sharp_drop(p, z0=0.4, d0=-0.3):
    """The drop under the sharp law in closed form: a parabola to touchdown, then the stance's damped
    oscillation y(s) = e^{As}(y0 + A⁻¹b) − A⁻¹b. Returns the touchdown time, the stance's length and y(s)."""
    height = z0 + d0
    touchdown = math.sqrt(2 * height / p["g"])
    a, b = stance_flow(p)
    shift = np.linalg.solve(a, b)
    start = np.array([z0 - height, d0, -p["g"] * touchdown, 0.0])

    def stance(s):
        return expm(a * s) @ (start + shift) - shift

    s = np.linspace(1e-6, 0.5, 2001)
    foot = np.array([stance(x)[0] + stance(x)[1] for x in s])
    k = np.flatnonzero(foot >= 0)[0]
    lasts = brentq(lambda x: stance(x)[0] + stance(x)[1], s[k - 1], s[k], xtol=1e-15)
    return touchdown, lasts, stance


def joint_state(system, times):
    tr = solve_ode(system, np.asarray(times), "DOP853", rtol=RTOL, positions=True)
    return np.hstack([system.q0 + tr.positions @ system.topology.inverse.T, tr.rates]), tr


def test_the_ground_pushes_only_when_penetrated_and_then_as_a_linear_spring_and_damper():
    """f = 0 exactly once the foot is 38·δ above the ground (tanh saturates), f = kc·p + cc·ṗ to rounding
    once it is 38·δ below, and half of that at the surface."""
    p = HOPPER
    f = hopper().mechanical_functions().contacts
    delta = p["delta"]
    for depth in (-40 * delta, -1.0, -1e3):
        q = np.array([0.5, -0.5 - depth])            # the foot's height q1 + q2 = −depth
        assert f.normal(q, np.array([0.0, -2.0]))[0] == 0.0
    for depth, rate in ((40 * delta, 0.3), (1e-2, -0.2), (0.05, 1.5)):
        q = np.array([0.5, -0.5 - depth])
        sharp = p["kc"] * depth + p["cc"] * rate
        assert f.normal(q, np.array([0.0, -rate]))[0] == pytest.approx(sharp, rel=4e-16, abs=4e-16 * p["cc"])
    at_surface = f.normal(np.array([0.5, -0.5]), np.array([0.0, -1.0]))[0]
    assert at_surface == pytest.approx(0.5 * p["cc"], rel=1e-15)


def test_the_contact_is_a_one_port_at_the_foot_node():
    """τ = Jᵀ·f with J = ∂y/∂q = (1, 1): as node currents, the ground feeds the foot's node and not the body's."""
    system = drop()
    x = np.array([-0.1, -0.1 - 0.003])          # the foot 3 mm in the ground
    v = np.array([0.2, -0.4])
    into = system.node_contact(x, v)
    force = system.contact_forces(x[None], v[None])["f_foot"][0]
    assert into[0] == 0.0 and into[1] == pytest.approx(force, rel=1e-15) and force > 0
    text = analogy.netlist(system)
    lines = {line.split()[0]: line for line in text.splitlines() if line[:1] in "BC"}
    assert "v(f_foot)" in lines["Bh2"] and "f_foot" not in lines["Bh1"]
    assert lines["Bf_foot"].startswith("Bf_foot f_foot 0 V=") and "tanh(" in lines["Bf_foot"]


def test_flight_is_a_parabola_to_the_odes_tolerance():
    """Before touchdown nothing but gravity acts (the leg's spring rests, the ground's force is 0 exactly)."""
    touchdown = math.sqrt(2 * 0.1 / HOPPER["g"])
    t = np.linspace(0, 0.98 * touchdown, 7)
    y, _ = joint_state(drop(), t)
    assert np.max(np.abs(y[:, 0] - (0.4 - HOPPER["g"] * t ** 2 / 2))) <= 100 * RTOL * 0.4
    assert np.max(np.abs(y[:, 1] + 0.3)) <= 100 * RTOL * 0.3


def test_the_stance_converges_to_the_sharp_damped_oscillator_at_second_order_in_the_smoothing():
    """Mid-stance, the smooth law's motion departs from the sharp law's closed form as δ²: the switch's
    departure s(p) − H(p) is odd about p = 0, so its first-order impulse cancels. Ten times smaller δ, a
    hundred times smaller departure; the next term is O(δ/p̄), p̄ = (mb + mf)·g/kc = 5.4 mm the static
    penetration, 2 % at δ = 1e-4: within 5 % of 100."""
    touchdown, lasts, stance = sharp_drop(HOPPER)
    t = touchdown + 0.5 * lasts
    departures = []
    for delta in (1e-4, 1e-5):
        y, _ = joint_state(drop(delta=delta), [0.0, t])
        departures.append(np.max(np.abs(y[1] - stance(0.5 * lasts)) / np.array([0.4, 0.3, 1.4, 1.4])))
    assert 95 <= departures[0] / departures[1] <= 105


def test_energy_balances_with_the_grounds_work_and_each_impact_loses_some():
    """T + U − T(0) − W = 0 to the ODE's tolerance, W holding the leg's damper and the ground's work;
    the ground's work over the run is negative (its damper), and the hopper ends lower than it started."""
    system = drop()
    _, tr = joint_state(system, np.linspace(0, system.t_stop, 801))
    residual, scale = system.energy_residual(tr)
    assert np.max(np.abs(residual)) <= 1e3 * RTOL * scale
    force = tr.currents["f_foot"]
    foot_rate = tr.voltages[:, 1]                        # node 2 is the foot's velocity
    power = force * foot_rate
    ground_work = np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(tr.time))
    assert ground_work < 0 and np.min(force) < np.max(force)


@pytest.mark.ngspice
def test_spice_and_the_ode_agree_on_the_drop_and_on_the_contact_force():
    """At fast, every output (the joint rates and f_foot) within the bound of its own peak."""
    c = analogy.compare(drop(), solvers=("spice", "ode", "reference"), preset="fast")
    assert not c.outside_bound()
    for solver in ("spice", "ode"):
        rel = c.errors()[solver].per_output
        assert set(rel) == {"r1", "r2", "f_foot"} and max(rel.values()) <= c.bound


def test_contact_parameters_of_the_wrong_dimension_or_sign_are_refused():
    with pytest.raises(InputError, match=r"smoothing\) must be finite and positive \[m\]"):
        drop(delta=0.0)
    with pytest.raises(InputError, match=r"kc \(foot's stiffness\) must be finite and zero or positive"):
        hopper().mechanical_functions({"kc": -1.0})
    out = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--robot", "hopper", "--param", "kc=2 kg"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "kc is measured in N/m, got a mass" in out.stderr
    assert "Traceback" not in out.stderr


def test_the_hoppers_schematic_draws_its_masses_and_its_loads():
    """A nonlinear circuit's charge-defined capacitors are drawn at their start, c(0) = M'(0)'s split (the body's
    1 kg and the foot's 0.1 kg as C1 and C2), and each node's load h_k(x, v) as a source."""
    from analogy.circuit.diagram import schematic
    drawn = schematic(drop())
    assert {"C1", "C2", "R1_2", "Bh1", "Bh2"} <= set(drawn.parts)


@pytest.mark.ngspice
def test_the_written_netlist_runs_in_plain_ngspice_and_prints_the_contact_force(tmp_path):
    """`analogy netlist --robot hopper` saves and prints f_foot beside the nodes; plain `ngspice -b` runs it to
    the in-process run's values, printed with 15 digits and interpolated alike (1e-12 of the peak)."""
    import shutil

    from analogy.cli import main
    from analogy.solvers.rawfile import read_printed
    path = tmp_path / "hopper.cir"
    assert main(["netlist", "--robot", "hopper", "--preset", "fast", "-o", str(path)]) == 0
    text = path.read_text()
    assert ".save v(n1) v(n2) v(f_foot)" in text
    res = subprocess.run([shutil.which("ngspice") or "ngspice", "-b", str(path)], capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    printed = read_printed(res.stdout)
    run = analogy.solve(drop(), "spice", None, "fast")
    force = np.interp(printed["time"], run.time, run.currents["f_foot"])
    assert np.max(np.abs(printed["f_foot"] - force)) <= 1e-12 * np.max(np.abs(force))
