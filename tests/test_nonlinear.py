"""Configuration-dependent dynamics inside SPICE: the nonlinear circuit is the Lagrange equations."""

import re
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp

import analogy
from analogy.circuit.description import (
    BehaviouralCurrent,
    ChargeCapacitor,
    Integrator,
    circuit,
)
from analogy.errors import InputError
from analogy.presets import PRESETS
from analogy.model.expressions import parse_expression
from analogy.study.comparison import compare
from analogy.results.metrics import relative_error
from analogy.scenes.builtin import scene
from analogy.scenes.spec import ModelSpec
from analogy.scenes.toml import parse_toml
from analogy.solvers.ode import solve_ode
from analogy.solvers.reference import NONLINEAR_RTOL

GRAVITY_ARM = """
dynamics = "nonlinear"
[model]
mass = [["a + b*cos(q2)", "c + 0.5*b*cos(q2)"], ["c + 0.5*b*cos(q2)", "c"]]
damping = [0.2, 0.1]
stiffness = [0.5, 0.3]
gravity = ["9.81*(m1*cos(q1) + m2*cos(q1 + q2))", "9.81*m2*cos(q1 + q2)"]
[parameters]
a = 3.0
b = 1.0
c = 0.5
m1 = 0.3
m2 = 0.1
[configuration]
q = [0.2, 0.3]
topology = {topology}
[inputs]
forces = [1.0, 0.5]
t_stop = 5.0
"""


def gravity_arm(topology='"parallel"'):
    return parse_toml(GRAVITY_ARM.replace("{topology}", topology)).system()


def nonlinear(name, **changes):
    return scene(name).replace(dynamics="nonlinear", **changes).system()


def test_nodal_equations_of_the_written_circuit_are_the_lagrange_equations():
    """KCL of the netlist's own expressions, parsed back, equals T⁻ᵀ·(M q̈ + Ṁq̇ − ½∂(q̇ᵀMq̇)/∂q
    + G + Bq̇ + K(q − q0) − F), derived here in joint space, at random states (to rounding)."""
    for system in (nonlinear("default"), gravity_arm("[[1, 0], [1, 1]]")):
        n = system.dof
        x, v, a = (list(sp.symbols(f"{s}1:{n + 1}", real=True)) for s in ("x", "v", "a"))
        f = list(sp.symbols(f"F1:{n + 1}", real=True))
        names = {f"x{k + 1}": x[k] for k in range(n)} | {f"v{k + 1}": v[k] for k in range(n)}

        def read(text):           # the SPICE expression back as sympy, by the restricted parser
            text = re.sub(r"v\((x|n)(\d+)\)", lambda m: ("x" if m.group(1) == "x" else "v") + m.group(2), text)
            return parse_expression(text, names)
        out = [sp.S.Zero] * n     # current leaving each node through the circuit's parts
        c = circuit(system)
        for p in c.behavioural:
            if isinstance(p, ChargeCapacitor):
                q = read(p.charge)
                i = sum(sp.diff(q, v[k]) * a[k] + sp.diff(q, x[k]) * v[k] for k in range(n))
                out[p.a - 1] += i
                if p.b:
                    out[p.b - 1] -= i
            elif isinstance(p, BehaviouralCurrent):
                out[p.b - 1] += read(p.current)
                if p.a:
                    out[p.a - 1] -= read(p.current)
            else:
                assert isinstance(p, Integrator)
        for e in c.elements:
            across = (v if e.kind == "R" else x)[e.a - 1] - ((v if e.kind == "R" else x)[e.b - 1] if e.b else 0)
            i = across / e.value
            out[e.a - 1] += i
            if e.b:
                out[e.b - 1] -= i
        for src in c.sources:
            out[src.a - 1] -= src.scale * f[src.joint - 1]
            if src.b:
                out[src.b - 1] += src.scale * f[src.joint - 1]
        # the Lagrange equations, in joint space
        model = system.model
        subs = {sym: system.parameters[k] for k, sym in model.symbols.items()}
        qs = list(model.coordinates)
        mass = model.mass_matrix.subs(subs)
        qd = sp.Matrix(sp.symbols(f"qd1:{n + 1}", real=True))
        qdd = sp.Matrix(sp.symbols(f"qdd1:{n + 1}", real=True))
        mdot = sum((mass.diff(qk) * qd[k] for k, qk in enumerate(qs)), sp.zeros(n, n))
        lagrange = mass * qdd + mdot * qd - sp.Matrix([(qd.T * mass.diff(qk) * qd)[0] / 2 for qk in qs])
        if model.gravity is not None:
            lagrange += model.gravity.subs(subs)
        lagrange += sp.Matrix(system.functions.damping) * qd - sp.Matrix(f)
        if system.functions.stiffness is not None:
            lagrange += sp.Matrix(system.functions.stiffness) * (sp.Matrix(qs) - sp.Matrix(system.q0))
        tinv = sp.Matrix(system.topology.inverse.tolist())
        mapping = {qd[k]: (tinv * sp.Matrix(v))[k] for k in range(n)}
        mapping |= {qdd[k]: (tinv * sp.Matrix(a))[k] for k in range(n)}
        mapping |= {qk: float(system.q0[k]) + (tinv * sp.Matrix(x))[k] for k, qk in enumerate(qs)}
        nodal_lagrange = tinv.T * lagrange.subs(mapping)
        rng = np.random.default_rng(3)
        for _ in range(5):
            point = {s: float(rng.uniform(-1, 1)) for s in x + v + a + f}
            got = np.array([float(e.subs(point)) for e in out])
            want = np.array([float(e.subs(point)) for e in nodal_lagrange])
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


@pytest.mark.ngspice
def test_the_charge_form_of_a_behavioural_capacitor_gives_d_cv_dt(tmp_path):
    """With C = 1 + x and v = 2t: Q = {(1+x)·v} carries d(Cv)/dt = 2 + 4t; C = {1+x} only C·dv/dt."""
    deck = tmp_path / "q.cir"
    deck.write_text("* charge form against capacitance form\nVx x 0 PWL(0 0 1 1)\n"
                    "Vq a 0 PWL(0 0 1 2)\nCq a 0 Q={(1+v(x))*v(a)}\n"
                    "Vc b 0 PWL(0 0 1 2)\nCc b 0 C={1+v(x)}\n"
                    ".tran 1e-3 1 0 1e-3\n.print tran i(Vq) i(Vc)\n.end\n")
    res = subprocess.run([shutil.which("ngspice"), "-b", str(deck)], capture_output=True, text=True, timeout=60)
    rows = np.array([[float(x) for x in ln.split()[1:]] for ln in res.stdout.splitlines()
                     if len(ln.split()) == 4 and ln.split()[0].isdigit()])
    # The trapezoidal rule makes a derivative ring from step to step, so compare the charge
    # each form has passed, ∫i dt, on the ramp: Q form (1+t)·2t, C form ∫C·dv = 2t + t².
    t, iq, ic = rows[:, 0], -rows[:, 1], -rows[:, 2]
    ramp = t <= 1.0

    def passed(i):
        return np.concatenate([[0.0], np.cumsum(0.5 * (i[1:] + i[:-1]) * np.diff(t))])[ramp]
    tr = t[ramp]
    assert np.max(np.abs(passed(iq) - 2 * tr * (1 + tr))) <= 1e-4
    assert np.max(np.abs(passed(ic) - (2 * tr + tr ** 2))) <= 1e-3
    assert passed(iq)[-1] - passed(ic)[-1] >= 0.99          # they differ by ∫dC/dt·v dt = t²


@pytest.mark.ngspice
@pytest.mark.parametrize("make", [lambda: nonlinear("default"), lambda: nonlinear("serial3"), gravity_arm,
                                  lambda: nonlinear("default", initial_rates=(0.5, -0.2)),
                                  lambda: nonlinear("redundant")],
                         ids=["serial2", "serial3", "gravity", "serial2-moving", "redundant"])
def test_nonlinear_spice_and_ode_keep_the_preset_bounds_against_the_reference(make):
    """SPICE ≤ 1e-3 (fast) and ≤ 1e-6 (accurate) of the peak rate, the ODE ≤ 1e-9 (accurate)."""
    system = make()
    for preset, spice_bound in (("fast", 1e-3), ("accurate", 1e-6)):
        c = compare(system, preset, ["spice", "ode"])
        assert c.reference == "reference" and not c.failures, c.failures
        assert c.errors()["spice"][1] <= spice_bound
        assert c.energy["reference"] <= 1e-9
        if preset == "accurate":
            assert c.errors()["ode"][1] <= 1e-9
            assert c.energy["spice"] <= 1e-6
        assert c.results["spice"].positions is not None


def test_the_nonlinear_reference_is_converged():
    """DOP853 at rtol 1e-13 agrees with rtol 2.5e-14 to 1e-10 of the peak: its own error is below that."""
    for system in (nonlinear("default"), gravity_arm()):
        t = np.linspace(0.0, system.t_stop, 201)
        a = solve_ode(system, t, "DOP853", NONLINEAR_RTOL).rates
        b = solve_ode(system, t, "DOP853", NONLINEAR_RTOL / 4).rates
        assert relative_error(a, b) <= 1e-10


def test_a_closed_chain_s_nonlinear_circuit_takes_the_parallel_topology_only():
    """Its circuit has a node per joint of the loop, v = r; another T is refused in one sentence."""
    with pytest.raises(InputError, match="parallel2 is a closed chain: its nonlinear circuit takes the parallel"):
        scene("parallel2").replace(dynamics="nonlinear", topology="serial").system()


@pytest.mark.parametrize("make", [lambda: nonlinear("default"), lambda: nonlinear("serial3"),
                                  lambda: gravity_arm("[[1, 0], [1, 1]]")], ids=["serial2", "serial3", "gravity"])
def test_the_analytic_jacobian_is_the_derivative_of_the_dynamics(make):
    """∂f/∂y of y = [x, v, W] equals central differences of f to 1e-7 at random states."""
    from analogy.solvers import ode
    system = make()
    force = ode._SegmentForces(system.forces)
    force.segment(*next((t0, t1) for t0, t1 in system.segments() if t0 <= 0.3 <= t1))
    rhs, jac, _, _ = ode._nonlinear(system, force)
    n = system.dof
    rng = np.random.default_rng(5)
    for _ in range(3):
        y = np.concatenate([rng.uniform(-1, 1, 2 * n), [0.0]])
        h = 1e-6
        fd = np.column_stack([(rhs(0.3, y + h * e) - rhs(0.3, y - h * e)) / (2 * h) for e in np.eye(2 * n + 1)])
        assert np.max(np.abs(jac(0.3, y) - fd)) <= 1e-7 * np.max(np.abs(fd))


def test_implicit_integrators_take_the_analytic_jacobian_and_converge():
    system = nonlinear("default")
    t = np.linspace(0, 10, 201)
    ref = solve_ode(system, t, "DOP853", NONLINEAR_RTOL).rates
    for method in ("Radau", "BDF"):
        tr = solve_ode(system, t, method, 1e-9)
        assert tr.stats.jacobians >= 1 and relative_error(tr.rates, ref) <= 1e-6


@pytest.mark.ngspice
def test_a_symbolic_command_line_model_with_gravity_keeps_the_bounds(capsys):
    from analogy.cli import main
    code = main(["compare", "--mass", "[[a + b*cos(q2), c + 0.5*b*cos(q2)], [c + 0.5*b*cos(q2), c]]",
                 "--param", "a=3", "--param", "b=1", "--param", "c=0.5", "--param", "m=0.2",
                 "--gravity", "[9.81*m*cos(q1), 0]", "--damping", "[0.2, 0.1]", "--q", "0.2, 0.3",
                 "--dynamics", "nonlinear", "--t-stop", "5"])
    out = capsys.readouterr().out
    assert code == 0, out
    rows = {ln.split()[0]: ln.split() for ln in out.splitlines()[2:] if ln.split()}
    assert float(rows["spice"][4]) <= 1e-6 and float(rows["ode"][4]) <= 1e-9      # worst output over its peak
    assert "does not apply" in out


@pytest.mark.ngspice
def test_a_scene_file_runs_nonlinear_on_request(tmp_path, capsys):
    from pathlib import Path

    from analogy.cli import main
    scene_file = Path(__file__).resolve().parent.parent / "examples" / "scenes" / "default.toml"
    assert main(["run", str(scene_file), "--dynamics", "nonlinear", "--no-plot",
                 "--output-dir", str(tmp_path)]) == 0
    assert "reference" in capsys.readouterr().out


@pytest.mark.ngspice
def test_the_charge_form_forgets_the_initial_condition_so_the_circuit_uses_a_follower(tmp_path):
    """An RC discharge from v(0) = 1: a linear C follows e^(−t/2); ngspice's Q = {2·v} starts at 0
    whatever .ic says, which is why charges are written as followers on a linear 1 F capacitor."""
    deck = tmp_path / "ic.cir"
    deck.write_text("* initial charge\nCq a 0 Q={2*v(a)}\nR1 a 0 1\nCl b 0 2\nR2 b 0 1\n"
                    ".ic v(a)=1 v(b)=1\n.tran 0.01 1 0 0.01 uic\n.print tran v(a) v(b)\n.end\n")
    res = subprocess.run([shutil.which("ngspice"), "-b", str(deck)], capture_output=True, text=True, timeout=60)
    rows = np.array([[float(x) for x in ln.split()[1:]] for ln in res.stdout.splitlines()
                     if len(ln.split()) == 4 and ln.split()[0].isdigit()])
    t, va, vb = rows.T
    assert np.max(np.abs(vb - np.exp(-t / 2))) <= 1e-3
    assert np.max(np.abs(va)) <= 1e-12
    moving = nonlinear("default", initial_rates=(0.5, -0.2))
    text = analogy.netlist(moving)
    for k in (1, 2):                # each follower says what its four devices do, beside them
        at = text.index(f"* C{k} as a follower")
        said = text[at:].splitlines()[0]
        assert all(re.search(rf"\b{device}\b", said) for device in (f"Bmq{k}", f"Cmc{k}", f"Vms{k}", f"Fm{k}"))
        assert text.splitlines()[text[:at].count("\n") + 1].startswith(f"Bmq{k} mq{k} 0 V=")
    tr = analogy.solve_spice(moving, preset="accurate")
    np.testing.assert_allclose(tr.rates[1], [0.5, -0.2], atol=1e-3)     # its first step keeps r(0)


def test_the_step_ladder_ends_in_gear_for_a_trapezoidal_run():
    """A collapsed step is retried with looser absolute tolerances, then with gear, for linear and
    behavioural circuits alike (both carry abstol and vntol); options without absolute tolerances
    (a bench's) run last at reltol RETRY_TIGHTEN times tighter; a gear run has nothing further to try."""
    from analogy.solvers.transient import RETRY_LOOSEN, RETRY_TIGHTEN, TransientSettings, transient_settings
    for behavioural in (False, True):
        first = transient_settings(PRESETS["accurate"], 1.0, None, behavioural=behavioural)
        ladder = first.retries()
        assert [s.loosen for s in ladder] == [*RETRY_LOOSEN, 1.0]
        assert [s.method for s in ladder] == ["trap"] * len(RETRY_LOOSEN) + ["gear"]
        assert len({s.reltol for s in ladder}) == 1
        assert [s.method for s in ladder[-1].retries()] == ["gear"] * len(RETRY_LOOSEN)
    bare = TransientSettings((("method", "trap"),), 0.01, 1.0, 1e-3, 1e-5)
    rungs = bare.retries()
    assert [s.method for s in rungs] == ["trap", "gear", "trap"]
    assert bare.reltol == 1e-3 == rungs[1].reltol            # ngspice's default, which it keeps
    assert rungs[2].reltol == pytest.approx(1e-3 / RETRY_TIGHTEN)
    assert ("reltol", f"{1e-3 / RETRY_TIGHTEN:.3g}") in rungs[2].options


@pytest.mark.ngspice
@pytest.mark.deep                   # 20 to 37 s: one run, or two where the first collapses
def test_flex2s_nonlinear_circuit_at_fast_runs_to_its_end_on_any_processor():
    """flex2's nonlinear circuit under its motor steps at fast sits on ngspice's rounding floor:
    on one processor its step collapsed at t = 3.91 s (rounding read as a failed Newton step), on
    another it ran through, because glibc picks its sin, cos and exp per processor (FMA or not).
    Either way it must reach t_stop under the trapezoidal rule, and a retry, where one was taken,
    is said with the factor that ran. (Its undamped modes, up to 1588 rad/s over 10 s, leave it
    far past fast's bound, as they leave the ODE at fast: the comparison flags both.) The retry
    itself is forced and checked on every machine by the collapsed-step test in test_spice."""
    from analogy.cli import build_parser, scene_from_args
    args = build_parser().parse_args(["compare", "--robot", "flex2", "--dynamics", "nonlinear"])
    tr = analogy.solve_spice(scene_from_args(args).system(), preset="fast")
    assert tr.success and tr.time[-1] == pytest.approx(10.0, rel=1e-12)
    loosen = tr.settings.loosen
    if loosen == 1.0:
        assert "retried" not in tr.message
    else:
        assert f"retried with abstol and vntol × {loosen:g} (" in tr.message
    assert dict(tr.settings.options)["method"] == "trap"


@pytest.mark.ngspice
def test_a_swing_that_collapsed_at_stale_pivots_runs_trapezoidal_within_its_bound():
    """serial4 swinging under gravity (q2 turning several radians a second): at pivrel = 0.1 the
    trapezoidal step collapsed at t = 1.05 s whatever the tolerances, and only gear finished. At
    pivrel = 0.9, with the step from its motion's error coefficients, the trapezoidal run goes
    through without a retry and keeps the accurate bound on every joint rate."""
    from analogy.cli import build_parser, scene_from_args
    args = build_parser().parse_args([
        "compare", "--robot", "serial4", "--dynamics", "nonlinear", "--param", "g=9.81", "--t-stop", "4",
        "--q=0.3,-0.5,0.8,0.2", "--r0=0,1,-1,0.5", "--force", "step(3)", "--force", "step(1)",
        "--force", "step(0.5)", "--force", "step(0.2)"])
    c = compare(scene_from_args(args).system(), "accurate", solvers=("spice", "reference"))
    assert not c.failures
    assert "retried" not in c.results["spice"].message
    assert dict(c.results["spice"].settings.options)["method"] == "trap"
    assert c.max_relative_error("spice") <= 1e-6


@pytest.mark.parametrize("robot", ["serial2", "serial3"])
def test_a_symbolic_model_evaluates_a_stack_of_poses_as_it_does_each_pose(robot):
    """M(q) and G(q) over 200 random poses at once (what the energy residual takes along a run of
    hundreds of thousands of points) equal the pose-by-pose values: the same expressions, numpy's
    vector and scalar paths of sin and cos agreeing to a few units in the last place."""
    n = int(robot[-1])
    system = scene("default").replace(model=ModelSpec(robot=robot), q=(0.0,) * n, forces=("step(1)",) * n,
                                      dynamics="nonlinear", parameters={"g": 9.81}).system()
    f = system.functions
    poses = np.random.default_rng(7).uniform(-np.pi, np.pi, (200, system.dof))
    masses = np.stack([f.mass(q) for q in poses])
    gravities = np.stack([f.gravity(q) for q in poses])
    np.testing.assert_allclose(f.masses(poses), masses, rtol=0, atol=8 * np.finfo(float).eps * np.abs(masses).max())
    np.testing.assert_allclose(f.gravities(poses), gravities, rtol=0,
                               atol=8 * np.finfo(float).eps * np.abs(gravities).max())
