"""Exact solver against 40-digit mpmath, ODE against exact, on every built-in scene."""

import mpmath
import numpy as np
import pytest

from analogy import node_system, solve_exact, solve_ode
from analogy.model.joint import JointSpace
from analogy.model.robots import random_spd_model
from analogy.scenes.builtin import SCENES, scene
from analogy.solvers.exact import phi1, phi2
from analogy.solvers.ode import ODE_METHODS
from analogy.solvers.reference import solve_reference

#: The built-in scenes the exact solution and the 40-digit reference speak for (not the hopper's contact).
LINEAR = [n for n in SCENES if SCENES[n].dynamics == "linear"]


def rel_err(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("x", [0, 1e-12, -3e-9 + 2e-9j, 0.3 - 0.7j, -2.5, 4 + 1j, -50 + 20j, 1j * 1e-6])
def test_phi_functions_to_rounding(x):
    with mpmath.workdps(40):
        xm = mpmath.mpc(x)
        p1 = complex(mpmath.expm1(xm) / xm) if x != 0 else 1.0
        p2 = complex((mpmath.exp(xm) - 1 - xm) / xm ** 2) if x != 0 else 0.5
    assert abs(complex(phi1(np.array([x]))[0]) - p1) <= 4e-16 * abs(p1)
    assert abs(complex(phi2(np.array([x]))[0]) - p2) <= 4e-16 * abs(p2)


@pytest.mark.parametrize("name", LINEAR)
def test_exact_matches_40_digit_reference(name):
    """Eigen-decomposition of the pencil vs mpmath.expm of the augmented system: ≤ 1e-12."""
    s = scene(name).system()
    t = np.linspace(0.0, s.t_stop, 7)
    ref = solve_reference(s, t).voltages
    assert rel_err(solve_exact(s, t).voltages, ref) <= 1e-12


def test_exact_keeps_its_digits_on_a_free_body_held_by_a_spring_elsewhere():
    """The hopper in the air, linearised: a free body on a leg spring. Its free direction is a Jordan chain
    at λ = 0 that eig splits into modes ε·cond(V) = 4e6·ε apart; on the springs' state alone the exact
    solution keeps 1e-12 of the peak, and the leg, which gravity does not stretch, stays at rest."""
    s = scene("hopper").replace(dynamics="linear").system()
    t = np.linspace(0.0, s.t_stop, 7)
    ref = solve_reference(s, t)
    exact = solve_exact(s, t)
    assert rel_err(exact.voltages, ref.voltages) <= 1e-12
    assert np.max(np.abs(exact.rates[:, 1])) <= 1e-12 * np.max(np.abs(ref.rates))


def test_exact_with_springs_and_every_waveform_matches_reference():
    model = random_spd_model(4, seed=3, stiffness=True)
    forces = ["step(1, 0.5, 0.01)", "pulse(0, 1, 0.2, 0.01, 0.02, 0.5, 1.5)",
              "pwl(0, 0, 1, 1, 2, -1)", ["sine(0.2, 1, 0.8, 0.3, 0.4, 30)", "step(-0.5)"]]
    s = node_system(model, forces=forces, initial_rates=[0.3, -0.2, 0.1, 0.0], t_stop=4.0)
    t = np.linspace(0.0, 4.0, 9)
    assert rel_err(solve_exact(s, t).voltages, solve_reference(s, t).voltages) <= 1e-12


def test_exact_satisfies_the_differential_equation():
    """M'·dv/dt + B'·v + K'·∫v = i(t), checked by finite differences of the exact solution."""
    model = random_spd_model(3, seed=5, stiffness=True)
    s = node_system(model, forces=["sine(0, 1, 0.5)", 1.0, "pwl(0, 0, 3, 1)"], t_stop=3.0)
    h = 1e-4
    t = np.array([1.0 - 2 * h, 1.0 - h, 1.0, 1.0 + h, 1.0 + 2 * h])
    v = solve_exact(s, t).voltages
    dv = (v[0] - 8 * v[1] + 8 * v[3] - v[4]) / (12 * h)
    # ∫v from the exact solver on a fine grid (Simpson)
    tt = np.linspace(0.0, 1.0, 2001)
    vv = solve_exact(s, tt).voltages
    w = np.ones(tt.size); w[1:-1:2] = 4; w[2:-1:2] = 2
    x = (tt[1] - tt[0]) / 3 * (w @ vv)
    residual = s.mass @ dv + s.damping @ v[2] + s.stiffness @ x - s.current_map @ s.force([1.0])[0]
    assert np.max(np.abs(residual)) < 1e-8


@pytest.mark.parametrize("name", LINEAR)
def test_ode_accurate_preset_within_1e9_of_exact(name):
    s = scene(name).system()
    t = np.linspace(0.0, s.t_stop, 501)
    from analogy.presets import PRESETS
    p = PRESETS["accurate"]
    ode = solve_ode(s, t, p.ode.method, p.ode.rtol)
    assert rel_err(ode.rates, solve_exact(s, t).rates) <= 1e-9


@pytest.mark.parametrize("method", ODE_METHODS)
def test_every_ode_method_converges(method):
    s = scene("serial2").system()
    t = np.linspace(0.0, s.t_stop, 101)
    ode = solve_ode(s, t, method, rtol=1e-8)
    assert rel_err(ode.rates, solve_exact(s, t).rates) <= 1e-5


def test_serial_and_parallel_topologies_give_the_same_joint_rates():
    """The topology changes the circuit, never the mechanics: R(t) is independent of T."""
    m = random_spd_model(5, seed=11)
    kw = dict(forces=[1.0, "sine(0, 1, 1)", 0.0, -0.5, 0.2], initial_rates=[0.1, 0, 0, 0, -0.1], t_stop=3.0)
    t = np.linspace(0.0, 3.0, 31)
    rs = solve_exact(node_system(m, topology="serial", **kw), t).rates
    rp = solve_exact(node_system(m, topology="parallel", **kw), t).rates
    assert rel_err(rs, rp) <= 1e-12


def test_undamped_single_mass_is_a_ramp():
    """M·dR/dt = F with B = 0: R(t) = F·t/M exactly (a zero eigenvalue of the pencil)."""
    s = node_system(JointSpace([[2.0]], [[0.0]]), forces=[3.0], t_stop=2.0)
    t = np.linspace(0, 2, 5)
    np.testing.assert_allclose(solve_exact(s, t).rates[:, 0], 1.5 * t, rtol=1e-15, atol=1e-15)


WAVES = ["step(0.7)", "step(1, 0.3, 0.01)", "pwl(0, 0, 1, 1, 1.5, -0.5, 2, 0)",
         "pulse(0, 1, 0.2, 0.05, 0.1, 0.3, 1)", "pulse(0, 1, 0, 0.1, 0.1, 0)",
         "sine(0.2, 1, 0.3, 0.5, 0.2, 40)", "sine(0, 1, 2)"]


@pytest.mark.parametrize("text", WAVES)
def test_waveform_closed_form_pieces_equal_the_waveform(text):
    """On every segment, a + b·τ + Σ c·exp(sτ) reproduces f(t) (what SPICE sees)."""
    from analogy.waveforms import parse_waveform
    w = parse_waveform(text)
    t_stop = 4.0
    edges = [0.0] + sorted(b for b in w.breakpoints(t_stop) if 0 < b < t_stop) + [t_stop]
    for t0, t1 in zip(edges[:-1], edges[1:]):
        p = w.piece(t0, t1)
        tau = np.linspace(0.0, t1 - t0, 9)[1:-1]
        closed = p.a + p.b * tau + sum((c * np.exp(s * tau) for c, s in zip(p.c, p.s)), 0 * tau)
        np.testing.assert_allclose(np.real(closed), w(t0 + tau), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("text", WAVES)
def test_ode_and_exact_agree_for_every_waveform(text):
    """The ODE solver samples f(t) directly, independently of the closed forms."""
    s = node_system(random_spd_model(3, seed=6, stiffness=True), forces=[text, 0.5, text],
                    initial_rates=[0.1, 0.0, -0.1], t_stop=4.0)
    t = np.linspace(0.0, 4.0, 201)
    assert rel_err(solve_ode(s, t, "DOP853", 1e-12).rates, solve_exact(s, t).rates) <= 1e-9


def test_times_a_rounding_past_t_stop_are_t_stop():
    s = scene("default").system()
    t = [0.0, 5.0, 10.0, 10.0 * (1 + 5e-13)]
    ex = solve_exact(s, t).rates
    np.testing.assert_array_equal(ex[-1], ex[-2])
    np.testing.assert_array_equal(solve_ode(s, t).rates[-1], solve_ode(s, t).rates[-2])


def test_the_exact_solution_of_a_stiff_pencil_keeps_its_slow_rate():
    """m = 1e-9, b = 1e6, k = 1e9: rates 1e3 and 1e15 in one mode pair. eig loses the slow one's
    digits (4.3e-7 of the peak against the 40-digit solution without refinement); refined on
    λ²m + λb + k it is within 1e-9 (measured 8.8e-11, the rest is cancellation in the modal sum)."""
    from analogy.circuit.node_system import node_system
    from analogy.model.joint import JointSpace
    from analogy.solvers.reference import solve_reference
    s = node_system(JointSpace([[1e-9, 0], [0, 1.0]], damping=[[1e6, 0], [0, 1.0]],
                               stiffness=[[1e9, 0], [0, 1.0]]), forces=[1, 1], t_stop=10.0)
    t = np.array([0, 1e-15, 1e-9, 1e-6, 1e-4, 1e-3, 1e-2, 0.1, 1, 10])
    ref = solve_reference(s, t).voltages
    assert np.max(np.abs(solve_exact(s, t).voltages - ref)) <= 1e-9 * np.max(np.abs(ref))


def stiff_example(t_stop=10.0):
    return node_system(JointSpace([[1e-9, 0], [0, 1.0]], damping=[[1e6, 0], [0, 1.0]],
                                  stiffness=[[1e9, 0], [0, 1.0]]), forces=[1, 1], t_stop=t_stop)


def test_an_explicit_method_steps_within_its_stability_reach_of_a_fast_decay():
    """serial3 with a light third link decays at |λ| = 38/s beside 0.39/s. DOP853 at rtol 1e-12
    stepped to h·|λ| = 15, past its reach of 4 on the real axis; the decayed mode regrew to the
    tolerance and the dense output between steps amplified it to 3e-6 of r3's peak. Within the
    reach each output holds the accurate bound against the exact solution."""
    s = scene("serial3").replace(q=(0, 1.0574863396007563, 0.42414333723504694),
                                 parameters=(("d3", 0.10153329160667103),), forces=(1, 0.5, 0.2),
                                 t_stop=5.0).system()
    exact = solve_exact(s).rates
    tr = solve_ode(s, method="DOP853", rtol=1e-12)
    assert np.all(np.max(np.abs(tr.rates - exact), axis=0) <= 1e-6 * np.max(np.abs(exact), axis=0))


def test_an_explicit_method_on_a_stiff_system_is_replaced_and_says_so():
    """|λ|max = 1e15 against an oscillation of 0.87 rad/s: DOP853 would need 2.5e15 steps;
    Radau with the analytic Jacobian takes thousands, within the accurate bound."""
    from analogy.solvers.ode import stiff_method, state_matrices
    s = stiff_example()
    a, _ = state_matrices(s)
    assert stiff_method(s, "DOP853", a, np.zeros(4))[0] == "Radau"
    assert stiff_method(scene("random10").system(), "DOP853", state_matrices(scene("random10").system())[0],
                        np.zeros(20))[:2] == ("DOP853", "")
    t = np.linspace(0, 10, 101)
    tr = solve_ode(s, t, "DOP853", 1e-12)
    ref = solve_reference(s, t).voltages
    assert "Radau" in tr.message and tr.stats.steps < 100_000
    assert np.max(np.abs(tr.voltages - ref)) <= 1e-6 * np.max(np.abs(ref))


def test_an_integration_past_its_time_limit_stops_with_a_sentence():
    from analogy.errors import SimulationError
    s = scene("random10").system()
    with pytest.raises(SimulationError, match="time limit of 1e-06 s"):
        solve_ode(s, None, "DOP853", 1e-12, timeout=1e-6)


def test_a_critically_damped_stiff_mode_keeps_a_solvable_modal_basis():
    """ω = 1 and 1e6 with ζ = 1: the stiff pair is a double rate, refinement would merge its two
    modes; eig's own are kept, and the closed form stays within 1e-9 (measured 1.5e-10)."""
    from analogy.results.metrics import relative_error
    w = np.array([1.0, 1e6])
    s = node_system(JointSpace(np.array([[1.0, 0.2], [0.2, 1.0]]), np.diag(2 * w), np.diag(w ** 2)),
                    forces=[1.0, 1.0], t_stop=10.0)
    t = 10 * np.sort(np.concatenate([[0, 1], np.modf(np.arange(1, 8) * 0.6180339887498949)[0]]))
    assert relative_error(solve_exact(s, t).voltages, solve_reference(s, t).voltages) <= 1e-9


@pytest.mark.ngspice
def test_one_solve_shaped_like_solve_ivp_times_resamples_and_checks_every_solver():
    """analogy.solve(system, method, t_eval): every registered solver returns a Trajectory on
    t_eval, from t = 0, timed by the base class; a solver may not bypass that contract."""
    import analogy
    from analogy.solvers.registry import SOLVER_NAMES, Solver
    s = analogy.scene("default").system()
    t = np.linspace(0.0, s.t_stop, 51)
    exact = analogy.solve(s, "exact", t)
    for name in SOLVER_NAMES:
        tr = analogy.solve(s, name, t, "accurate")
        assert tr.success and tr.solver == name and np.array_equal(tr.time, t)
        assert tr.stats.wall_time > 0 and tr.rates.shape == (t.size, s.dof)
        assert analogy.relative_error(tr.rates, exact.rates) <= 1e-6     # the accurate bound
    with pytest.raises(TypeError, match="implement _solve"):
        type("Rogue", (Solver,), {"solve": lambda self, *a, **k: None})
    with pytest.raises(analogy.InputError, match="sorted"):      # bad input raises; a failure does not
        analogy.solve(s, "exact", [2.0, 1.0])


def test_what_a_solver_loads_once_is_ready_before_its_run_is_timed():
    """Solver.ready (a library's load) runs before the timer starts, once per solve, and the run's own
    hook after it: the time a solve reports is its own work (SPICE's ngspice load, about 50 ms, is not)."""
    import analogy
    from analogy.solvers.exact import SOLVER as exact

    calls = []

    class Traced(type(exact)):
        def ready(self):
            calls.append("ready")

        def _solve(self, *args, **kwargs):
            calls.append("run")
            return super()._solve(*args, **kwargs)

    s = analogy.scene("default").system()
    traced = Traced()
    tr = traced.solve(s, np.linspace(0.0, s.t_stop, 11), analogy.PRESETS["fast"])
    assert calls == ["ready", "run"] and tr.success


def test_every_keyword_the_force_help_shows_is_one_the_parser_takes():
    """The --force help and the waveform parser name the same arguments (sine's frequency and phase)."""
    import re as _re
    from analogy.cli.parser import build_parser
    from analogy.errors import InputError
    from analogy.waveforms import parse_waveform
    text = next(a.help for a in build_parser()._subparsers._group_actions[0].choices["netlist"]._actions
                if "--force" in a.option_strings)
    sine = _re.search(r"sine\(([^)]*)\)", text).group(1)
    names = [p.split("=")[0].strip() for p in sine.split(",")]
    assert names == ["offset", "amplitude", "frequency", "delay", "damping", "phase"]
    w = parse_waveform("sine(0, 1, frequency=2, delay=0, damping=0, phase=90)")
    assert w.frequency == 2.0 and w.phase == 90.0
    with pytest.raises(InputError, match="no argument 'freq'; its arguments are offset, amplitude, frequency"):
        parse_waveform("sine(0, 1, freq=3)")


def test_the_ode_s_segment_forces_are_the_waveforms_themselves():
    """On each segment between breakpoints, the closed form a + b·τ + Σ c·e^{sτ} the ODE's
    right-hand side evaluates is every waveform's own sum, to rounding (a few ε of the peak)."""
    from analogy.circuit.joint_forces import waveforms
    from analogy.solvers.ode import _SegmentForces
    forces = waveforms(["sine(0.5, 2, 3, delay=0.1, damping=0.7, phase=30)",
                        ["pulse(0, 1, 0.05, 1e-3, 1e-3, 0.2, 0.5)", "pwl(0, 0, 0.3, 1, 0.6, -2)"],
                        "step(1.5)"], 3)
    edges = sorted({0.0, 1.0} | {b for ws in forces for w in ws for b in w.breakpoints(1.0)})
    segment = _SegmentForces(forces)
    worst = 0.0
    for t0, t1 in zip(edges[:-1], edges[1:]):
        segment.segment(t0, t1)
        for tt in np.linspace(t0, t1, 7)[1:-1]:
            direct = np.array([sum(float(w(tt)) for w in ws) for ws in forces])
            worst = max(worst, float(np.max(np.abs(segment(tt) - direct))))
    # rounding: the sine's phase ω·τ over a segment of at most 0.9 s, ε·ω·τ·A = ε·(6π·0.9)·2 ≈ 34ε,
    # and a few ε of the constant and linear parts (peak |force| ≤ 3)
    eps = np.finfo(float).eps
    assert worst <= eps * (6 * np.pi * 0.9 * 2 + 4 * 3.0)
