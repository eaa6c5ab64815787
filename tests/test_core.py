"""The core: one dynamics protocol, the solver contract, one error metric, the circuit description, scenes as data."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

import analogy
from analogy.circuit.description import (
    BehaviouralCurrent,
    ChargeCapacitor,
    Circuit,
    circuit,
)
from analogy.solvers.transient import netlist
from analogy.circuit.nonlinear import nonlinear_system
from analogy.errors import InputError, SimulationError
from analogy.model.dynamics import NodeDynamics
from analogy.model.joint import JointSpace
from analogy.model.robots import planar_serial, robot
from analogy.model.symbolic import christoffel_symbols, velocity_terms
from analogy.presets import preset
from analogy.study.comparison import compare
from analogy.results.metrics import PEAK_FLOOR, REFERENCE_ROUNDING, output_errors, relative_error, stack_errors
from analogy.scenes.builtin import scene
from analogy.scenes.toml import parse_toml
from analogy.solvers.ode import solve_ode
from analogy.solvers.registry import SOLVER_NAMES, run, solver


def undamped_serial2(**kw):
    return nonlinear_system(robot("serial2"), [0.0, 0.3], parameters={"b1": 0.0, "b2": 0.0},
                            forces=[0.0, 0.0], initial_rates=[1.0, -0.5], t_stop=5.0, **kw)


# ---------------------------------------------------------------- dynamics

def test_christoffel_terms_of_the_two_link_arm_are_the_textbook_ones():
    """c = h·(−2q̇1q̇2 − q̇2², q̇1²) with h = l1·l2·d2·sin q2, for point masses at the link ends."""
    m = robot("serial2")
    q1, q2 = m.coordinates
    r1, r2 = sp.symbols("r1 r2", real=True)
    c = velocity_terms(m.mass_matrix, m.coordinates, [r1, r2])
    l1, l2, d2 = (m.symbols[k] for k in ("l1", "l2", "d2"))
    h = l1 * l2 * d2 * sp.sin(q2)
    assert sp.simplify(c[0] - h * (-2 * r1 * r2 - r2 ** 2)) == 0
    assert sp.simplify(c[1] - h * r1 ** 2) == 0


def test_velocity_terms_do_no_work_beyond_half_the_mass_rate():
    """q̇ᵀ·c = ½·q̇ᵀ·Ṁ·q̇ (Ṁ − 2C skew-symmetric) for a 3R arm, symbolically."""
    m = planar_serial(3)
    q = list(m.coordinates)
    r = sp.symbols("r1:4", real=True)
    c = velocity_terms(m.mass_matrix, q, r)
    mdot = sp.Matrix(3, 3, lambda i, j: sum(sp.diff(m.mass_matrix[i, j], q[k]) * r[k] for k in range(3)))
    rv = sp.Matrix(r)
    assert sp.simplify((rv.T * c)[0] - (rv.T * mdot * rv)[0] / 2) == 0
    gamma = christoffel_symbols(m.mass_matrix, q)
    assert all(sp.simplify(gamma[i][j][k] - gamma[i][k][j]) == 0
               for i in range(3) for j in range(3) for k in range(3))


def test_undamped_free_motion_conserves_kinetic_energy():
    """½·ṙᵀM(q)ṙ stays constant to 1e-11 along the nonlinear ODE solution (measured 1.6e-13)."""
    s = undamped_serial2()
    tr = solve_ode(s, np.linspace(0, 5, 501), "DOP853", 1e-12, positions=True)
    q = s.q0 + s.topology.joint_rates(tr.positions)
    energy = 0.5 * np.einsum("ti,tij,tj->t", tr.rates, np.stack([s.functions.mass(x) for x in q]), tr.rates)
    assert np.max(np.abs(energy - energy[0])) <= 1e-11 * energy[0]
    assert tr.stats.steps > 0 and tr.stats.evaluations > tr.stats.steps


def test_small_motions_of_the_nonlinear_system_follow_the_linear_circuit():
    """For forces of size ε, nonlinear and linearised motions differ by O(ε²) of the motion."""
    base = scene("default").replace(t_stop=2.0)
    gaps = []
    for eps in (1e-2, 1e-3):
        sc = base.replace(forces=(eps, -0.5 * eps))
        t = np.linspace(0, 2, 201)
        lin = solve_ode(sc.system(), t, "DOP853", 1e-12).rates
        non = solve_ode(sc.replace(dynamics="nonlinear").system(), t, "DOP853", 1e-12).rates
        gaps.append(relative_error(non, lin))
    assert gaps[1] < gaps[0] / 5 and gaps[1] < 1e-3


def test_every_node_system_follows_the_protocol_and_says_which_solvers_apply():
    linear, nonlinear = scene("default").system(), undamped_serial2()
    for s in (linear, nonlinear):
        assert isinstance(s, NodeDynamics)
    assert linear.kind == "linear" and nonlinear.kind == "nonlinear"
    np.testing.assert_array_equal(linear.node_mass(np.ones(2)), linear.mass)
    assert not np.any(linear.node_load(np.ones(2), np.ones(2), 0.0))
    np.testing.assert_allclose(nonlinear.node_mass(np.zeros(2)),
                               scene("default").replace(parameters={"b1": 0.0, "b2": 0.0}).system().mass,
                               rtol=1e-14)
    for name in SOLVER_NAMES:
        assert solver(name).supports(linear) is None
    assert solver("ode").supports(nonlinear) is None
    assert "only to linear" in solver("exact").supports(nonlinear)


def test_a_nonlinear_comparison_runs_what_applies_and_reports_the_rest():
    """The exact solver does not apply; the tight ODE reference is the yardstick instead."""
    c = compare(undamped_serial2(), "fast", ["ode", "exact"])
    assert list(c.results) == ["ode", "reference"] and c.reference == "reference"
    assert not c.failures and "only to linear" in c.skipped["exact"]
    assert c.errors()["ode"][1] <= 1e-3
    assert c.energy["reference"] <= 1e-9


# ---------------------------------------------------------------- solver contract

@pytest.mark.ngspice
@pytest.mark.parametrize("name", SOLVER_NAMES)
def test_every_registered_solver_keeps_the_contract(name):
    """A Trajectory from t = 0 with statistics; the reference agrees with exact to 1e-12."""
    s = scene("default").system()
    times = None if name == "spice" else np.linspace(0.0, s.t_stop, 11)
    tr = run(name, s, times, preset("fast"))
    assert tr.success and tr.solver == name and tr.time[0] == 0.0
    np.testing.assert_allclose(tr.voltages[0], s.initial_voltages, atol=1e-15)
    assert tr.stats.wall_time > 0 and tr.rates.shape == tr.voltages.shape
    exact = analogy.solve_exact(s, tr.time).rates
    assert relative_error(tr.rates, exact) <= (1e-12 if name in ("exact", "reference") else 1e-3)


def test_a_failing_solver_is_a_failed_trajectory_and_the_others_still_run(monkeypatch):
    import analogy.solvers.ode as ode

    def broken(*args, **kwargs):
        raise SimulationError("ODE solver DOP853 failed at t = 0.5: test")
    monkeypatch.setattr(ode, "solve_ode", broken)
    c = compare(scene("default").system(), "fast", ["ode", "exact"])
    assert list(c.results) == ["exact"] and "t = 0.5" in c.failures["ode"]
    with pytest.raises(InputError, match="unknown solver 'rk4'"):
        compare(scene("default").system(), "fast", ["rk4"])


def test_errors_are_measured_on_each_solvers_own_points_whatever_the_output_step():
    s = scene("default").replace(t_stop=2.0).system()
    own = compare(s, "fast", ["ode", "exact"], times=np.linspace(0, 2, 101))
    stepped = compare(s, "fast", ["ode", "exact"], step=0.25)
    assert stepped.time.tolist() == [0.25 * k for k in range(9)]
    np.testing.assert_array_equal(stepped.results["ode"].time, stepped.time)
    assert own.errors()["ode"][1] <= 1e-3 and stepped.errors()["ode"][1] <= 1e-3
    with pytest.raises(InputError, match="output step"):
        compare(s, "fast", ["exact"], step=5.0)


# ---------------------------------------------------------------- one metric

def test_the_error_metric_is_max_error_over_peak_with_an_explicit_zero_peak():
    ref = np.array([[0.0, 2.0], [1.0, -4.0]])
    assert relative_error(ref + [[0.0, 0.1], [0.0, 0.0]], ref) == pytest.approx(0.1 / 4.0)
    assert relative_error(np.zeros(3), np.zeros(3)) == 0.0
    assert relative_error(np.ones(3), np.zeros(3)) == math.inf
    assert math.isnan(relative_error(np.empty((0, 2)), np.empty((0, 2))))
    stack = np.random.default_rng(1).normal(size=(5, 7, 3))
    noisy = stack + 1e-3 * np.random.default_rng(2).normal(size=stack.shape)
    np.testing.assert_allclose(relative_error(noisy, stack, axis=(1, 2)),
                               [relative_error(a, b) for a, b in zip(noisy, stack)], rtol=1e-15)


def test_a_stack_s_errors_per_output_and_over_the_largest_peak_are_those_of_each_row():
    """stack_errors is output_errors per row and, per row, relative_error over all its outputs:
    the same divisions of the same maxima, so equal exactly; zero and empty rows as there."""
    stack = np.random.default_rng(1).normal(size=(5, 7, 3))
    noisy = stack + 1e-3 * np.random.default_rng(2).normal(size=stack.shape)
    stack[3], noisy[3] = 0.0, 0.0           # a still reference, matched: 0
    noisy[4] = stack[4] = 0.0
    noisy[4, 2, 1] = 1.0                    # a still reference, missed: inf
    err, rel, whole = stack_errors(noisy, stack)
    for k in range(5):
        e, r = output_errors(noisy[k], stack[k])
        np.testing.assert_array_equal(err[k], e)
        np.testing.assert_array_equal(rel[k], r)
        assert whole[k] == relative_error(noisy[k], stack[k])
    assert whole[3] == 0.0 and whole[4] == math.inf
    assert np.isnan(stack_errors(np.empty((2, 0, 3)), np.empty((2, 0, 3)))[2]).all()


def test_an_output_at_rounding_is_judged_no_closer_than_the_reference_reaches():
    """Judged against a bound, an output's peak is floored at REFERENCE_ROUNDING / bound of the largest:
    a still joint whose reference is rounding (peak 1e-14 of the largest) is judged in absolute terms
    at 1e-12 of the largest peak, never at 1e-6 of its own rounding; large outputs keep their own peak."""
    t = np.linspace(0.0, 1.0, 11)
    ref = np.column_stack([np.sin(t), 1e-14 * np.cos(t), 1e-3 * t, 1e-14 * t])
    off = ref + np.column_stack([1e-7 * t, 5e-13 * t, 2e-10 * t, 2e-12 * t])
    err, loose = output_errors(off, ref)                 # no bound: PEAK_FLOOR of the largest
    assert loose[1] == pytest.approx(5e-13 / (PEAK_FLOOR * np.sin(1.0)), rel=1e-12)
    err, judged = output_errors(off, ref, 1e-6)
    top = np.sin(1.0)
    assert judged[1] == pytest.approx(5e-13 / (REFERENCE_ROUNDING / 1e-6 * top), rel=1e-12) and judged[1] < 1e-6
    assert judged[0] == pytest.approx(1e-7 / top, rel=1e-12) and judged[2] == pytest.approx(2e-10 / 1e-3, rel=1e-12)
    assert judged[3] > 1e-6             # past the reference's reach of the largest peak: flagged
    np.testing.assert_array_equal(stack_errors(off[None], ref[None], 1e-6)[1][0], judged)


# ---------------------------------------------------------------- circuit description

def test_the_circuit_reassembles_the_node_matrices_and_injects_the_node_currents():
    """Stamping the elements gives M', B', K'; the sources inject i = T⁻ᵀ·F at every node."""
    for name in ("default", "parallel3", "redundant"):
        s = scene(name).system()
        c = circuit(s)
        n = s.dof
        stamped = {k: np.zeros((n, n)) for k in "CRL"}
        for e in c.elements:
            x = e.coefficient
            i, j = e.a - 1, e.b - 1
            stamped[e.kind][i, i] += x
            if e.b:
                stamped[e.kind][j, j] += x
                stamped[e.kind][i, j] -= x
                stamped[e.kind][j, i] -= x
        scale = np.abs(s.mass).max()
        np.testing.assert_allclose(stamped["C"], s.mass, atol=1e-12 * scale)
        np.testing.assert_allclose(stamped["R"], s.damping, atol=1e-12 * np.abs(s.damping).max())
        if s.stiffness is not None:
            np.testing.assert_allclose(stamped["L"], s.stiffness, atol=1e-12 * np.abs(s.stiffness).max())
        t = np.linspace(0, s.t_stop, 7)
        injected = np.zeros((t.size, n))
        for src in c.sources:
            f = src.scale * src.waveform(t)
            injected[:, src.a - 1] += f
            if src.b:
                injected[:, src.b - 1] -= f
        np.testing.assert_allclose(injected, s.node_currents(t), atol=1e-12)


def test_behavioural_parts_are_written_and_cannot_smuggle_control_lines():
    s = scene("default").system()
    base = circuit(s)
    q = ChargeCapacitor("q1_2", 1, 2, "0.5*(v(n1)-v(n2))*(1+v(x1)^2)", 0.3)
    b = BehaviouralCurrent("h1", 1, 0, "0.1*v(n1)*v(n2)")
    rest = ChargeCapacitor("q1", 1, 0, "2*v(n1)")
    c = Circuit(base.nodes, base.elements, base.sources, base.initial, base.t_stop, behavioural=(q, b, rest))
    text = netlist(c, "fast")
    assert "Cq1 n1 0 Q={2*v(n1)}" in text               # Q(0) = 0: ngspice's own charge form
    # Q(0) ≠ 0: a charge follower, a node held at Q, 1 F on it, its current mirrored from n1 to n2
    assert "Bmqq1_2 mqq1_2 0 V={0.5*(v(n1)-v(n2))*(1+v(x1)^2)}" in text
    assert "Vmsq1_2 mqq1_2 mcq1_2 DC 0" in text and "Cmcq1_2 mcq1_2 0 1" in text
    assert "Fmq1_2 n1 n2 Vmsq1_2 1" in text
    assert "Bh1 0 n1 I={0.1*v(n1)*v(n2)}" in text
    for evil in ("1\n.control", "v(n1)}\n.endc", "'x'", "{1}"):
        bad = Circuit(base.nodes, base.elements, base.sources, base.initial, base.t_stop,
                      behavioural=(BehaviouralCurrent("h1", 1, 0, evil),))
        with pytest.raises(InputError, match="must not read"):
            netlist(bad)


def test_an_element_under_the_zero_tolerance_that_leaves_the_circuit_singular_is_refused():
    """C2 = 1e-13 F is a rounding residue of its row [−1, 1 + 1e-13]; without it no capacitor grounds."""
    m = np.array([[1.0, -1.0], [-1.0, 1.0 + 1e-13]])
    s = analogy.node_system(JointSpace(m), forces=[1.0, 1.0], t_stop=1.0)
    with pytest.raises(InputError, match=r"C2 = (1e-13|9.99e-14) F is below the zero tolerance \(1e-12"):
        circuit(s)
    c = compare(s, "fast", ["ode", "exact"])          # the other solvers need no circuit
    assert c.errors()["ode"][1] <= 1e-3


@pytest.mark.ngspice
def test_a_node_far_below_the_largest_keeps_its_elements():
    """The zero tolerance is relative to each element's own row: a 1 N/m spring beside a 1e12 N/m one
    stays in the netlist (dropped, the soft node's decay vanished and SPICE drifted to 5e-3 of the peak)."""
    w = np.array([1.0, 1e6])
    s = analogy.node_system(JointSpace([[1.0, 0.2], [0.2, 1.0]], np.diag(2e3 * w), np.diag(w ** 2)),
                            forces=[1.0, 1.0], t_stop=10.0)
    assert {e.name for e in analogy.elements(s) if e.kind == "L"} == {"L1", "L2"}
    assert compare(s, "fast", ["spice", "exact"]).errors()["spice"][1] <= 1e-3
    tiny = analogy.node_system(JointSpace(np.diag([1e-30, 1.0])), forces=[1.0, 1.0])
    assert [e.value for e in analogy.elements(tiny) if e.name == "C1"] == [1e-30]


# ---------------------------------------------------------------- scenes as data

def test_a_scene_is_hashable_data_with_a_content_key():
    a = scene("default")
    assert hash(a) == hash(a.replace())
    assert a.key == a.replace(name="other", description="renamed").key
    assert a.key == a.replace(q=(0, 0.3)).key               # 0 and 0.0 give the same result
    assert a.key != a.replace(q=(0.0, 0.31)).key
    assert a.key != a.replace(preset="fast").key
    # where the results go is no part of them; what is computed is
    assert a.key == a.replace(plot_file="elsewhere/x.png", csv_file="y.csv", netlist_file="z.cir").key
    assert a.key != a.replace(netlist=not a.netlist).key
    assert len(a.key) == 64 and int(a.key, 16) >= 0


def test_content_keys_are_the_same_in_every_process():
    code = ("import analogy; print(analogy.scene('default').key, "
            "analogy.scene('random10').replace(t_stop=3.0).key)")
    keys = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env=dict(os.environ, PYTHONHASHSEED=seed)).stdout for seed in ("1", "2")}
    assert len(keys) == 1
    assert keys.pop().split() == [scene("default").key, scene("random10").replace(t_stop=3.0).key]


def test_parsing_a_scene_file_builds_nothing():
    code = """
import json, sys
from analogy.scenes.toml import parse_toml
sc = parse_toml('[model]\\nrobot = "serial3"\\n[configuration]\\nq = [0, 1, 2]\\n'
                '[inputs]\\nforces = [1, 1, 1]\\n', 'x.toml')
print(json.dumps([sc.model.robot, [m for m in ("sympy", "scipy", "analogy.model.robots",
                                              "analogy.model.compiled") if m in sys.modules]]))
"""
    out = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                    check=True).stdout)
    assert out[0] == "serial3" and out[1] in ([], ["analogy.model.compiled"])


def test_the_command_line_and_a_scene_file_build_a_model_the_same_way():
    from analogy.cli import build_parser, scene_from_args
    args = build_parser().parse_args(["compare", "--mass", "[[a + b*cos(q2), b], [b, b]]",
                                      "--param", "a=3", "--param", "b=1", "--q", "0, 0.5",
                                      "--damping", "[1, 2]"])
    from_cli = scene_from_args(args).system()
    from_file = parse_toml('[model]\nmass = [["a + b*cos(q2)", "b"], ["b", "b"]]\ndamping = [1, 2]\n'
                           '[parameters]\na = 3\nb = 1\n[configuration]\nq = [0, 0.5]\n'
                           '[inputs]\nforces = [1, 1]\n').system()
    np.testing.assert_array_equal(from_cli.mass, from_file.mass)
    np.testing.assert_array_equal(from_cli.damping, from_file.damping)
    assert from_cli.mass[0, 0] == pytest.approx(3 + math.cos(0.5))


def test_short_reprs_for_the_repl():
    s = scene("default").system()
    c = compare(s, "fast", ["ode", "exact"])
    for obj in (c, s, circuit(s), c.results["ode"], c.results["ode"].stats, scene("default").model):
        text = repr(obj)
        assert "\n" not in text and len(text) < 300, text
    e = analogy.elements(s)[2]
    assert repr(e) == "<C1_2 -0.764269 F: MP model, n1-n2>"
    assert c._repr_html_().startswith("<table>") and "ode" in c._repr_html_()
    # no estimate ran: no column of NaN for one (issue of the report and the notebook)
    assert "estimated" not in c._repr_html_() and "nan" not in c._repr_html_()
    estimated = compare(s, "fast", ["ode", "exact"], estimate=True)
    assert "estimated error / its peak" in estimated._repr_html_()


def test_results_are_tables_and_pictures_for_notebooks():
    """DataFrames with one column per quantity and solver; diagrams show as SVG in notebooks."""
    s = scene("default").replace(t_stop=2.0).system()
    c = compare(s, "fast", ["ode", "exact"], step=0.5)
    frame = c.to_frame()
    assert list(frame.columns) == ["r1_ode", "r2_ode", "r1_exact", "r2_exact"]
    assert frame.index.tolist() == [0.0, 0.5, 1.0, 1.5, 2.0]
    np.testing.assert_array_equal(frame["r2_exact"].to_numpy(), c.results["exact"].rates[:, 1])
    assert list(c.results["ode"].to_frame().columns) == ["r1", "r2", "v_n1", "v_n2"]
    from analogy.circuit.diagram import draw_circuit
    svg = draw_circuit(s)._repr_svg_()
    assert "<svg" in svg and "C1_2" in svg


def test_a_system_records_what_it_was_built_from_in_a_typed_record():
    """Provenance: robot, scene, parameters, configuration and units as fields, not a dict to guess from."""
    from analogy.model.provenance import Provenance
    s = scene("default").system()
    made = s.provenance
    assert isinstance(made, Provenance) and made.robot == "serial2" and made.scene == "default"
    assert made.configuration == {"q1": 0.0, "q2": 0.3} and made.units == ("rad", "rad")
    custom = analogy.node_system(JointSpace(np.eye(2)), forces=[1, 0], info={"robot": "my arm"})
    assert custom.provenance.robot == "my arm" and custom.provenance.units is None
    with pytest.raises(InputError, match="unknown provenance field 'robto'"):
        analogy.node_system(JointSpace(np.eye(2)), forces=[1, 0], info={"robto": "typo"})
