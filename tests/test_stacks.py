"""Many configurations at once: a stack of node systems holds the numbers of one-at-a-time evaluation."""

import numpy as np
import pytest
import sympy as sp

import analogy
from analogy.batch import run_batch
from analogy.circuit.description import circuit
from analogy.circuit.elements import element_table, elements
from analogy.circuit.description import circuits
from analogy.circuit.netlist import circuit_lines, write_batch
from analogy.circuit.stack_netlist import write_stack
from analogy.circuit.scales import combined_scales, stack_scales
from analogy.presets import PRESETS
from analogy.solvers.transient import transient_settings
from analogy.solvers.transient import batch_netlist
from analogy.circuit.node_system import node_system, node_systems
from analogy.model.robots import robot
from analogy.model.symbolic import Model
from analogy.scenes.builtin import scene

EPS = np.finfo(float).eps


def assert_rounding_equal(a, b):
    """Equal up to a few roundings of the largest entry."""
    np.testing.assert_allclose(a, b, rtol=0, atol=4 * EPS * np.abs(b).max())


def sprung_model(skew: float = 0.0) -> Model:
    """A symbolic 2-DOF model whose M, K and G depend on q; K, G and ∂G/∂q vanish at q1 = 0.

    *skew* makes M symmetric only to within a relative *skew*, as rounding in a
    model's own expressions can.
    """
    q1, q2, k, g = sp.symbols("q1 q2 k g", real=True)
    m12 = 0.5 * sp.cos(q2)
    mass = sp.Matrix([[3 + sp.cos(q2), m12], [m12 * (1 + skew), 1]])
    spring = k * sp.sin(q1) ** 2
    return Model("sprung", mass, damping=[1, 0.5], stiffness=sp.Matrix([[spring, 0], [0, 2 * spring]]),
                 gravity=[g * sp.sin(q1) ** 2, 0], parameters={"k": 2.0, "g": 9.81}, coordinates=(q1, q2),
                 topology="serial")


CASES = {
    "serial2": (lambda: scene("default").numeric_model(), 2, dict(forces=(1.0, 0.5), t_stop=10.0)),
    "serial3": (lambda: robot("serial3"), 3, dict(forces=(1.0, "sine(0, 1, 2)", 0.0), t_stop=5.0)),
    "parallel2": (lambda: robot("parallel2"), 2, dict(forces=(0.01, -0.005), t_stop=5.0)),
    "sprung": (sprung_model, 2, dict(forces=(1.0, 0.0), initial_rates=(0.1, 0.0), t_stop=4.0)),
}


@pytest.mark.parametrize("name", CASES)
def test_stack_equals_one_at_a_time(name):
    """M', B', K', T⁻ᵀ, forces and R(0) of every row equal node_system's at that q."""
    make, n, kw = CASES[name]
    model = make()
    centre = {"parallel2": [2.1, 0.9]}.get(name, np.zeros(n))
    qs = centre + np.random.default_rng(5).uniform(-0.3, 0.3, (12, n))
    for s, q in zip(node_systems(model, qs, **kw), qs):
        ref = node_system(model, list(q), **kw)
        for attr in ("mass", "damping", "current_map", "initial_rates"):
            assert_rounding_equal(getattr(s, attr), getattr(ref, attr))
        assert (s.stiffness is None) == (ref.stiffness is None)
        if ref.stiffness is not None:
            assert_rounding_equal(s.stiffness, ref.stiffness)
        assert_rounding_equal(s.joint.mass_matrix, ref.joint.mass_matrix)
        assert repr(s.forces) == repr(ref.forces) and s.t_stop == ref.t_stop and s.provenance == ref.provenance


def test_gravity_and_springs_follow_each_row_and_vanish_where_they_vanish():
    qs = np.array([[0.0, 0.2], [np.pi / 3, 0.2], [np.pi / 2, 0.2]])
    systems = node_systems(sprung_model(), qs, forces=(1.0, 0.0))
    # F_1 = 1 − g·sin² q1: the step of −G sums with the applied step
    for s, q in zip(systems, qs):
        assert s.force([0.5])[0, 0] == pytest.approx(1.0 - 9.81 * np.sin(q[0]) ** 2, abs=1e-12)
    assert systems[0].joint.gravity is None and systems[0].stiffness is None
    assert systems[1].stiffness is not None and [e.kind for e in elements(systems[1])].count("L") == 2
    assert elements(systems[0]) == elements(node_system(sprung_model(), [0.0, 0.2], forces=(1.0, 0.0)))


def test_nearly_symmetric_stack_is_built_one_at_a_time_with_the_same_result():
    model, qs = sprung_model(skew=1e-13), [[0.1, 0.2], [0.3, -1.0]]
    for s, q in zip(node_systems(model, qs, forces=(1.0, 0.0)), qs):
        ref = node_system(model, q, forces=(1.0, 0.0))
        np.testing.assert_array_equal(s.mass, ref.mass)
        assert s.provenance.configuration == {"q1": q[0], "q2": q[1]}
        assert all(type(v) is float for v in s.provenance.configuration.values())


def test_stack_shapes_for_one_joint_and_for_no_coordinates():
    q = sp.Symbol("q", real=True)
    pendulum = Model("pendulum", sp.Matrix([[2 + sp.cos(q)]]), damping=[1], coordinates=(q,))
    systems = node_systems(pendulum, [0.0, 1.0, 2.0], forces=(1.0,))      # a flat list of q
    assert [float(s.mass[0, 0]) for s in systems] == [2 + np.cos(x) for x in (0.0, 1.0, 2.0)]
    fixed = Model("fixed", [[2.0, 0.5], [0.5, 1.0]], damping=[1, 1])
    assert len(node_systems(fixed, np.zeros((3, 0)), forces=(1.0, 0.0))) == 3
    with pytest.raises(analogy.InputError, match="at least one configuration"):
        node_systems(pendulum, [], forces=(1.0,))


def test_rows_of_a_stack_cannot_change_each_other():
    systems = scene("default").systems([[0.0, 0.1], [0.0, 0.2]])
    for array in (systems[0].mass, systems[0].initial_rates, systems[0].initial_voltages):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 5.0
    with pytest.raises(AttributeError, match="immutable"):
        systems[0].t_stop = 1.0
    systems[0].provenance.parameters["l1"] = 7.0
    assert systems[1].initial_rates[0] == 0.0 and systems[1].provenance.parameters["l1"] == 1.0


def test_a_driven_system_is_a_new_one_whose_cached_inputs_follow_its_own():
    """driven() leaves the system alone; the new one's segments and inputs key are of its own forces."""
    system = scene("default").system()
    before = (system.inputs_key, system.breakpoints().copy())
    other = system.driven(forces=("pulse(0, 1, 0.5, 0.1, 0.1, 1)", 0.0), t_stop=4.0)
    assert system.inputs_key == before[0] and np.array_equal(system.breakpoints(), before[1])
    assert other.inputs_key != system.inputs_key and other.t_stop == 4.0
    assert 0.5 in other.breakpoints() and other.breakpoints()[-1] == 4.0
    assert other.mass is system.mass            # the matrices are shared, never copied


def test_joint_stack_of_symbolic_and_compiled_models_agree():
    qs = np.random.default_rng(2).uniform(-np.pi, np.pi, (50, 3))
    symbolic, compiled = robot("serial3"), scene("serial3").numeric_model()
    a, b = symbolic.joint_stack(qs), compiled.joint_stack(qs)
    assert a.mass_matrix.shape == (50, 3, 3) and a.damping.shape == (50, 3, 3)
    assert_rounding_equal(a.mass_matrix, b.mass_matrix)
    # constant entries (damping) broadcast over the rows
    np.testing.assert_array_equal(b.damping, np.broadcast_to(compiled.joint_space(qs[0]).damping, (50, 3, 3)))


def test_bad_row_is_named():
    qs = [[2.1, 0.9], [2.0, 1.0], [0.0, np.pi]]       # the last cannot assemble
    with pytest.raises(analogy.InputError, match=r"^configuration 3: model 'parallel2' does not assemble"):
        node_systems(robot("parallel2"), qs, forces=(0.0, 0.0))
    with pytest.raises(analogy.InputError, match=r"^configuration 1: model 'parallel2' does not assemble"):
        node_systems(robot("parallel2"), qs[::-1], forces=(0.0, 0.0))
    with pytest.raises(analogy.InputError, match=r"^forces must have 2 entries"):    # shared: no row
        node_systems(robot("parallel2"), qs[:2], forces=(0.0,))
    with pytest.raises(analogy.InputError, match="rows of 2 joint coordinates"):
        node_systems(robot("serial2"), [[0.0, 0.1, 0.2]], forces=(0.0, 0.0))


def test_element_table_of_a_stack_lists_each_systems_elements():
    systems = scene("serial3").systems(np.random.default_rng(1).uniform(-2, 2, (6, 3)))
    table = element_table(np.stack([s.mass for s in systems]), np.stack([s.damping for s in systems]))
    for k, s in enumerate(systems):
        listed = [(kind, a, b, c[k]) for kind, a, b, c in table if c[k] != 0]
        assert listed == [(e.kind, e.a, e.b, e.coefficient) for e in elements(s)]


def test_batch_netlist_is_each_systems_own_circuit_under_a_prefix():
    """The stacked writer gives, line for line, what the one-system writer gives."""
    systems = list(scene("serial2").systems(np.column_stack([np.zeros(5), np.linspace(-3, 3, 5)])))
    systems.append(scene("serial3").replace(t_stop=10.0).system())
    text = batch_netlist(systems)
    expected = []
    for k, s in enumerate(systems):
        expected += circuit_lines(circuit(s), prefix=f"x{k}_")
    body = [ln for ln in text.splitlines()[1:] if not ln.startswith(".")]
    assert body == expected


@pytest.mark.parametrize("name, topology, forces", [
    ("default", None, None),
    ("random10", None, None),
    ("flexpar", None, None),                                # springs: L lines
    ("serial2", [[1.0, 0.5], [-0.3, 1.0]], ("pwl(0, 0, 1, 2, 3, -1)", "step(1)")),    # summed PWL sources
])
def test_a_shared_stack_is_written_from_its_columns_as_from_its_circuits(name, topology, forces):
    """write_stack, which a batch uses for a stack sharing its inputs, writes the text that
    write_batch writes from each row's circuit: the same netlist, character for character."""
    base = scene(name)
    q0 = np.array(base.q, dtype=float)
    qs = np.tile(q0, (6, 1))
    qs[:, :2] += 0.3 * np.random.default_rng(3).uniform(-1, 1, qs[:, :2].shape)     # the motors: flexpar's links stay straight
    systems = base.systems(qs) if topology is None else node_systems(
        base.numeric_model(), qs, topology=topology, forces=forces, t_stop=4.0)
    assert len(systems.partition()) == 1
    settings = transient_settings(PRESETS["fast"], systems[0].t_stop, combined_scales(stack_scales(systems)),
                                  breakpoints=systems[0].breakpoints())
    text = write_stack(systems, settings)
    assert text == write_batch(circuits(systems), settings)
    if topology is None:                # (a custom T is beyond the calibration: other settings)
        assert batch_netlist(systems, "fast") == text       # what a batch writes
    assert ("sums the forces into" in text) == (topology is not None)
    assert (" x5_n1 0 " in text) and (name != "flexpar" or "\nLx0_" in text)


def test_values_every_row_shares_are_written_as_each_circuit_writes_them():
    """write_stack writes a value every row shares (the dampers, and v(0) = T·r0, as a serial T is
    the same in every row) into its template once: the text is still write_batch's."""
    base = scene("default")
    qs = np.column_stack([np.zeros(5), np.linspace(-2.0, 2.0, 5)])
    systems = node_systems(base.numeric_model(), qs, initial_rates=(0.3, -0.2), t_stop=2.0)
    v0 = systems.initial_voltages
    assert np.all(v0 == v0[0]) and np.all(v0 != 0)
    settings = transient_settings(PRESETS["fast"], 2.0, combined_scales(stack_scales(systems)),
                                  breakpoints=systems[0].breakpoints())
    text = write_stack(systems, settings)
    assert text == write_batch(circuits(systems), settings)
    assert "v(x4_n1)=0.3 v(x4_n2)=0.09999999999999998" in text


def test_rows_that_keep_different_elements_are_written_as_their_circuits():
    """Where M12 = 0 (q2 at its root) the floating capacitor is left out of that row alone:
    write_stack fills another template for it, and still writes write_batch's text."""
    from scipy.optimize import brentq
    base = scene("default")
    m12 = lambda q2: base.systems(np.array([[0.0, q2]]))[0].mass[0, 1]
    root = brentq(m12, 1.2, 2.0, xtol=1e-15)
    qs = np.array([[0.0, 0.3], [0.0, root], [0.0, 2.0], [0.0, root], [0.0, 1.0]])
    systems = base.systems(qs)
    settings = transient_settings(PRESETS["fast"], systems[0].t_stop, combined_scales(stack_scales(systems)),
                                  breakpoints=systems[0].breakpoints())
    text = write_stack(systems, settings)
    assert text == write_batch(circuits(systems), settings)
    assert [f"Cx{k}_1_2 " in text for k in range(5)] == [True, False, True, False, True]
    # each row's point operations, made for the whole stack, are its own (the damper R12 still couples
    # the nodes where C12 is left out)
    from analogy.circuit.elements import first_point_operations, point_operations
    assert [first_point_operations(systems.take([k])) for k in range(5)] == [point_operations(systems[k]) for k in range(5)]


@pytest.mark.ngspice
def test_one_bad_configuration_fails_alone():
    base = scene("parallel2").replace(t_stop=2.0)
    qs = [(2.1, 0.9), (2.0, 1.0), (0.0, np.pi), (2.2, 0.8)]
    res = run_batch([base.replace(q=q) for q in qs], "fast", workers=1)
    assert list(res.failures) == [2] and "does not assemble" in res.failures[2]
    assert np.all(res.errors[[0, 1, 3]] <= 1e-3) and np.isnan(res.errors[2])


@pytest.mark.ngspice
def test_a_malformed_configuration_fails_alone():
    items = [scene("default").replace(q=q, t_stop=2.0) for q in ((0.0, 0.1), ("x", 0.2), ((0.0, 0.1),))]
    res = run_batch(items, "fast", workers=1)
    assert sorted(res.failures) == [1, 2] and "list of numbers" in res.failures[1]
    assert "needs 2 joint coordinates" in res.failures[2]
    assert res.errors[0] <= 1e-3


@pytest.mark.ngspice
def test_a_system_the_exact_solver_cannot_take_fails_alone(monkeypatch):
    from analogy.solvers import exact
    solve = exact._solve

    def refusing(systems, t):
        if any(s.provenance.configuration["q2"] == 0.7 for s in systems):
            raise analogy.SimulationError("the modes are nearly defective")
        return solve(systems, t)

    monkeypatch.setattr(exact, "_solve", refusing)
    items = [scene("default").replace(q=(0.0, q), t_stop=2.0) for q in (0.1, 0.7, 1.3)]
    res = run_batch(items, "fast", workers=1)
    assert list(res.failures) == [1] and "nearly defective" in res.failures[1]
    assert np.all(res.errors[[0, 2]] <= 1e-3) and np.isnan(res.errors[1])


@pytest.mark.ngspice
def test_a_failing_ngspice_run_is_retried_scene_by_scene(monkeypatch):
    """If the shared run fails, each scene runs alone and only the culprit is a failure."""
    from analogy.solvers import spice
    culprit = 0.7
    c12 = next(e for e in elements(scene("default").replace(q=(0.0, culprit), t_stop=2.0).system())
               if e.name == "C1_2")
    real = spice.session()

    class Failing:                  # ngspice that fails on any netlist holding the culprit
        def run(self, text, vectors=None, stats=None, timeout=None):
            if repr(c12.value) in text:
                raise analogy.SpiceError("ngspice transient analysis failed: time step too small")
            return real.run(text, vectors, stats, timeout=timeout)

    monkeypatch.setattr(spice, "session", Failing)
    quietly = spice.run_quietly

    def failing_quietly(text, t_stop, stats=None):     # the stack's own run, in the quiet library
        if repr(c12.value) in text:
            raise analogy.SpiceError("ngspice transient analysis failed: time step too small")
        return quietly(text, t_stop, stats)
    monkeypatch.setattr(spice, "run_quietly", failing_quietly)
    items = [scene("default").replace(q=(0.0, q), t_stop=2.0) for q in (0.1, culprit, 1.3)]
    res = run_batch(items, "fast", workers=1)
    assert list(res.failures) == [1] and "time step too small" in res.failures[1]
    assert np.all(res.errors[[0, 2]] <= 1e-3)


def test_parameters_per_row_build_the_systems_each_scene_builds_alone():
    """A family of scenes differing in q and a robot's parameters is one stack, row by row exact."""
    base = scene("default")
    rng = np.random.default_rng(3)
    items = [base.replace(q=(0.0, float(x)), parameters={"d1": float(a), "d2": float(b)})
             for x, a, b in zip(rng.uniform(-3, 3, 6), rng.uniform(0.5, 3, 6), rng.uniform(0.5, 2, 6))]
    assert len({s.family() for s in items}) == 1
    qs = np.array([s.q for s in items])
    per_row = {k: np.array([s.parameter_values[k] for s in items]) for k in ("d1", "d2")}
    for alone, stacked in zip((s.system() for s in items), items[0].systems(qs, parameters=per_row)):
        np.testing.assert_array_equal(stacked.mass, alone.mass)
        np.testing.assert_array_equal(stacked.damping, alone.damping)
        assert stacked.provenance.parameters == alone.provenance.parameters


def test_nonlinear_and_equilibrium_scenes_form_no_stack():
    """Stacks are linear systems at q: a scene whose system is built otherwise has no family."""
    base = scene("default")
    assert base.family() is not None
    assert base.replace(dynamics="nonlinear").family() is None
    assert base.replace(equilibrium=True).family() is None


def test_the_batched_path_keeps_the_contract_of_solve(monkeypatch):
    """Solver.solve_many checks each row as Solver.solve checks one run: a row that is not finite
    fails alone, in solve's words, and numbers that break down for the stack as a whole send each
    system alone, so that only the one that breaks down fails. A solver cannot bypass this."""
    from analogy.presets import preset
    from analogy.solvers import exact
    from analogy.solvers.registry import Solver, run_many
    solve = exact._solve
    items = [scene("default").replace(q=(0.0, q), t_stop=2.0).system() for q in (0.1, 0.7, 1.3)]
    t = np.linspace(0.0, 2.0, 41)

    def culprit(systems):
        return [s.provenance.configuration["q2"] == 0.7 for s in systems]

    def poisoned(systems, times):           # a NaN the solver's own check would have missed
        states = solve(systems, times)
        for k in np.flatnonzero(culprit(systems)):      # one stack, or one array per part
            states[k][times.size // 2:] = np.nan
        return states

    monkeypatch.setattr(exact, "_solve", poisoned)
    rows = run_many("exact", items, t, preset("fast"))
    assert [tr.success for tr in rows] == [True, False, True]
    assert rows[1].message == "its result is not finite from t = 1 s on"

    def breaking(systems, times):
        if any(culprit(systems)):
            raise np.linalg.LinAlgError("Eigenvalues did not converge")
        return solve(systems, times)

    monkeypatch.setattr(exact, "_solve", breaking)
    rows = run_many("exact", items, t, preset("fast"))
    assert [tr.success for tr in rows] == [True, False, True]
    assert "numerics broke down: Eigenvalues did not converge" in rows[1].message
    with pytest.raises(TypeError, match="implement _solve_many"):
        type("Rogue", (Solver,), {"solve_many": lambda self, *a, **k: []})


@pytest.mark.ngspice
def test_comparisons_read_as_columns_are_the_records_of_each_comparison():
    """compare_many's figures read as arrays are, system by system, those of its Comparison: the
    same floats, not recomputed; the reference has no error of its own; nothing failed."""
    from analogy.study.comparison import compare_many
    qs = np.column_stack([np.zeros(6), np.linspace(-2.5, 2.5, 6)])
    stack = scene("default").systems(qs)
    found = compare_many(stack, "fast", ["spice", "ode", "exact"])
    assert len(found) == 6 and found.reference == "exact" and set(found.solvers) == {"spice", "ode", "exact"}
    for name in found.solvers:
        errors, seconds = found.errors(name), found.seconds(name)
        assert found.failures(name) == {}
        for k, c in enumerate(found):
            record = c.records[name]
            assert seconds[k] == record.trajectory.run_time
            if name == "exact":
                assert np.isnan(errors[k])
            else:
                assert errors[k] == record.errors.relative <= found.bound
    import pickle
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(found)).errors("spice"), found.errors("spice"))
    frame = found.to_frame()
    assert list(frame.columns) == [f"{kind}_{n}" for n in found.solvers for kind in ("error", "seconds")]
    assert repr(found).startswith("<Comparisons of 6 systems at fast: worst error/peak spice ")
    # a histogram per solver with an error (the reference has none), the bound beside them
    legend = [t.get_text() for t in found.plot().axes[0].get_legend().get_texts()]
    assert legend == [n for n in found.solvers if n != "exact"] + ["fast bound"]


@pytest.mark.ngspice
def test_a_batch_group_makes_no_system_or_trajectory_per_scene(monkeypatch):
    """A family's group reads its stack's arrays and its solvers' stacks: of its hundred rows it makes
    the first's system alone (its shared inputs), and no row's Trajectory or Comparison."""
    from analogy.batch.plan import plan_groups, solve_group
    from analogy.circuit.node_system import NodeSystem
    from analogy.presets import preset
    from analogy.results.trajectory import Trajectory
    made = {"systems": 0, "trajectories": 0}
    checked = NodeSystem.from_checked.__func__

    def counted(cls, *args, **kwargs):
        made["systems"] += 1
        return checked(cls, *args, **kwargs)
    monkeypatch.setattr(NodeSystem, "from_checked", classmethod(counted))
    init = Trajectory.__init__

    def counted_init(self, *args, **kwargs):
        made["trajectories"] += 1
        init(self, *args, **kwargs)
    monkeypatch.setattr(Trajectory, "__init__", counted_init)
    base = scene("default")
    group, = plan_groups([base.replace(q=(0.0, x)) for x in np.linspace(-3.0, 3.0, 100)], 100)
    result = solve_group(group, preset("fast"), ["spice"], "auto")
    assert not result.failures and np.all(result.errors["spice"] <= preset("fast").bound)
    assert made == {"systems": 1, "trajectories": 0}


@pytest.mark.ngspice
def test_a_group_of_several_circuits_solves_each_as_a_group_of_its_own_would():
    """Consecutive circuits of one family in one group (built and checked once): every scene's error and
    failure is what it is when each circuit is a group of its own, as the same netlists run."""
    from analogy.batch.plan import plan_groups, solve_group
    from analogy.presets import preset
    base = scene("default")
    items = [base.replace(q=(0.0, x)) for x in np.linspace(-3.0, 3.0, 25)]
    fast = preset("fast")
    block, = plan_groups(items, 10, circuits=3)
    alone = plan_groups(items, 10)
    assert block.runs == tuple(len(g.rows) for g in alone) and block.rows == sum((g.rows for g in alone), ())
    together = solve_group(block, fast, ["spice", "ode"], "auto")
    apart = [solve_group(g, fast, ["spice", "ode"], "auto") for g in alone]
    for name in ("spice", "ode"):
        np.testing.assert_array_equal(together.errors[name], np.concatenate([r.errors[name] for r in apart]))
    assert not together.failures and np.all(together.errors["spice"] <= fast.bound)


@pytest.mark.ngspice
def test_a_bug_met_in_one_circuit_of_a_group_is_that_circuits_alone(monkeypatch):
    """An exception in one circuit's comparison sends only that circuit's members to be solved one by one:
    the group's other circuits keep the errors of their shared runs."""
    import analogy.batch.plan as plan
    from analogy.batch.plan import plan_groups, solve_group_isolated
    from analogy.presets import preset
    real = plan.compare_many

    def buggy(systems, *args, **kwargs):
        if len(systems) > 1 and any(s.provenance.configuration["q2"] == 2.5 for s in systems):
            raise RuntimeError("a bug met by the circuit holding q2 = 2.5")
        return real(systems, *args, **kwargs)
    monkeypatch.setattr(plan, "compare_many", buggy)
    base = scene("default").replace(t_stop=2.0)
    items = [base.replace(q=(0.0, float(x))) for x in np.linspace(-3.0, 2.5, 30)]
    fast = preset("fast")
    block, = plan_groups(items, 10, circuits=3)
    together = solve_group_isolated(block, fast, ["spice"], "auto")
    apart = [solve_group_isolated(g, fast, ["spice"], "auto") for g in plan_groups(items, 10)]
    np.testing.assert_array_equal(together.errors["spice"], np.concatenate([r.errors["spice"] for r in apart]))
    assert not together.failures and np.all(together.errors["spice"] <= fast.bound)


@pytest.mark.ngspice
def test_a_row_that_does_not_build_makes_only_its_circuit_build_row_by_row(monkeypatch):
    """A configuration of a closed chain that does not assemble fails the group's stack: each circuit is then
    built as a stack of its own, and only the one holding it is built row by row; every other scene's error
    is what a group of one circuit gives."""
    import analogy.batch.plan as plan
    from analogy.batch.plan import plan_groups, solve_group
    from analogy.presets import preset
    base = scene("parallel2").replace(t_stop=2.0)
    qs = [(2.1 + a, 0.9 + b) for a, b in np.random.default_rng(0).uniform(-0.2, 0.2, (30, 2))]
    qs[25] = (0.0, np.pi)
    items = [base.replace(q=q) for q in qs]
    fast = preset("fast")
    block, = plan_groups(items, 10, circuits=3)
    alone = plan_groups(items, 10)
    one_by_one = []
    build = plan.as_system
    monkeypatch.setattr(plan, "as_system", lambda item: one_by_one.append(item.q) or build(item))
    together = solve_group(block, fast, ["spice"], "auto")
    assert sorted(one_by_one) == sorted(qs[20:30])          # the third circuit's, and only once
    apart = [solve_group(g, fast, ["spice"], "auto") for g in alone]
    np.testing.assert_array_equal(together.errors["spice"], np.concatenate([r.errors["spice"] for r in apart]))
    assert list(together.failures) == [25] and together.invalid == {25} and "does not assemble" in together.failures[25]


def test_circuits_of_different_horizons_are_not_one_group():
    """A stack over several horizons makes every row's system, so a group holds circuits of one horizon."""
    from analogy.batch.plan import plan_groups
    base = scene("default")
    items = [base.replace(q=(0.0, 0.01 * k), t_stop=1.0 if k < 20 else 1.5) for k in range(40)]
    groups = plan_groups(items, 10, circuits=4)
    assert [(len(g.rows), g.runs, g.horizons is None) for g in groups] == [(20, (10, 10), True)] * 2


def test_a_take_of_a_stack_reads_its_rows_scales_as_made_for_the_whole_stack():
    """run_scales of a sub-stack is made from the whole stack's row scales (made once), and equals the
    scales of those rows as a stack of their own."""
    from analogy.circuit.scales import run_scales
    base = scene("default")
    qs = np.column_stack([np.zeros(12), np.linspace(-3.0, 3.0, 12)])
    whole = base.systems(qs)
    part = whole.take([3, 1, 8])
    own = base.systems(qs[[3, 1, 8]])
    assert "scales" not in whole._rowwise
    a, b = run_scales(part), run_scales(own)
    assert "scales" in whole._rowwise        # made for the whole stack, for its other takes
    assert (a.omega_max, a.peak_velocity, a.peak_position, a.charge) == (b.omega_max, b.peak_velocity,
                                                                         b.peak_position, b.charge)
    for x, y in ((a.decays, b.decays), (a.shares, b.shares), (a.phases, b.phases), (a.frequencies, b.frequencies)):
        np.testing.assert_array_equal(x, y)


def test_a_take_reads_no_row_values_from_a_stack_whose_rows_differ_in_springs():
    """K(q) vanishes at q1 = 0: a stack sharing its inputs (no gravity) holds rows with and without
    springs, whose element table and scales leave K' out. Its sprung rows' take makes its own, with
    their inductors, as a stack of those rows alone does."""
    from analogy.circuit.description import element_columns
    from analogy.circuit.scales import run_scales
    qs = np.array([[0.0, 0.2], [0.5, 0.2], [0.0, 0.4], [0.7, 0.1]])
    mixed = node_systems(sprung_model(), qs, forces=(1.0, 0.0), parameters={"g": 0.0})
    assert mixed.shares_inputs and mixed.springs.tolist() == [False, True, False, True]
    run_scales(mixed.take([0, 2]))          # the springless rows: made for themselves too
    sprung, alone = mixed.take([1, 3]), node_systems(sprung_model(), qs[[1, 3]], forces=(1.0, 0.0),
                                                     parameters={"g": 0.0})
    assert [c[0] for c in element_columns(sprung)] == [c[0] for c in element_columns(alone)]
    assert "L" in [c[0] for c in element_columns(sprung)] and not mixed._rowwise
    assert run_scales(sprung).omega_max == run_scales(alone).omega_max > 0


def test_takes_of_a_stack_share_what_their_inputs_derive_and_write_their_circuits_text():
    """The takes of a stack sharing its inputs read them from one system (the stack's first row), and
    each row's point operations and elements from the whole stack's, made once: a take's netlist is
    still write_batch's of its own circuits, and its first row's operations are point_operations'."""
    from analogy.circuit.elements import first_point_operations, point_operations
    base = scene("default")
    qs = np.column_stack([np.zeros(12), np.linspace(-3.0, 3.0, 12)])
    whole = base.systems(qs)
    parts = [whole.take([3, 1, 8]), whole.take([11, 0]), whole.take([5])]
    assert all(part.inputs_row is whole[0] for part in parts)
    assert "point operations" not in whole._rowwise
    assert [first_point_operations(part) for part in parts] == [point_operations(part[0]) for part in parts]
    assert "point operations" in whole._rowwise
    for part in parts:
        settings = transient_settings(PRESETS["fast"], part[0].t_stop, combined_scales(stack_scales(part)),
                                      breakpoints=part[0].breakpoints())
        assert write_stack(part, settings) == write_batch(circuits(part), settings)


def test_a_take_of_consecutive_rows_reads_the_stacks_values_without_copying_and_cannot_write_them():
    """A batch's circuits are consecutive rows of its group's stack: their take's matrices and row values
    are views of the stack's, read-only, and equal to a take of the same rows in another order's."""
    from analogy.circuit.scales import whitened_damping
    base = scene("default")
    whole = base.systems(np.column_stack([np.zeros(12), np.linspace(-3.0, 3.0, 12)]))
    part, picked = whole.take(range(4, 9)), whole.take([4, 5, 6, 8, 7])
    chol, wb = whitened_damping(part)
    assert np.shares_memory(part.mass, whole.mass) and np.shares_memory(chol, whitened_damping(whole)[0])
    with pytest.raises(ValueError):
        part.mass[0, 0, 0] = 1.0
    with pytest.raises(ValueError):
        wb[0] = 0.0
    order = [0, 1, 2, 4, 3]
    np.testing.assert_array_equal(part.mass[order], picked.mass)
    np.testing.assert_array_equal(wb[order], whitened_damping(picked)[1])
    # rows counted from the end, or past it, are taken as numpy takes them, never as an empty slice
    np.testing.assert_array_equal(whole.take([-1]).mass, whole.mass[[-1]])
    np.testing.assert_array_equal(whole.take([-1, 0]).mass, whole.mass[[-1, 0]])
    with pytest.raises(IndexError):
        whole.take([11, 12])


@pytest.mark.ngspice
def test_a_circuit_taken_from_a_group_stack_is_compared_with_no_row_of_it_made():
    """What a circuit's rows share (kind, size, topology, inputs, horizon) is read from its group stack's
    inputs row: comparing a take makes none of its rows, and its errors are those of its rows built alone."""
    from analogy.study.comparison import compare_many
    base = scene("default")
    qs = np.column_stack([np.zeros(30), np.linspace(-3.0, 3.0, 30)])
    whole = base.systems(qs)
    part = whole.take(range(10, 20))
    found = compare_many(part, "fast", ["spice"], reference="exact")
    assert [k for k, row in enumerate(whole._rows) if row is not None] == [0]
    alone = compare_many(base.systems(qs[10:20]), "fast", ["spice"], reference="exact")
    np.testing.assert_array_equal(found.errors("spice"), alone.errors("spice"))


def test_joint_rates_are_the_inverse_maps_product_bit_for_bit():
    """R = T⁻¹·v, taken from T⁻¹'s nonzero entries (serial and parallel maps: ±1), is the full product's."""
    rng = np.random.default_rng(5)
    for name in ("serial2", "parallel3", "serial3", "parallel2"):
        item = scene(name)
        topology = item.systems([item.q])[0].topology
        v = rng.standard_normal((7, 33, topology.dof))
        assert topology.exact_inverse and topology._rate_terms is not None
        np.testing.assert_array_equal(topology.joint_rates(v), v @ topology.inverse.T)
        with pytest.raises(ValueError):
            topology.joint_rates(np.ones((3, topology.dof + 1)))


def test_a_lazy_stack_keeps_what_its_rows_were_built_from_and_pickles_with_them():
    """Rows made after the caller changed its own parameter arrays still report the values the stack was
    built with; a pickled stack is the same systems; a sub-stack's rows are its parent's objects."""
    import pickle
    from analogy.results.trajectory_stack import TrajectoryStack
    from analogy.results.trajectory import SolverStats
    b1 = np.array([0.5, 1.0, 2.0])
    stack = node_systems(robot("serial2"), [[0.1, 0.2]] * 3, parameters={"b1": b1})
    b1[:] = 99.0
    assert [s.provenance.parameters["b1"] for s in stack] == [0.5, 1.0, 2.0]
    again = pickle.loads(pickle.dumps(stack))
    assert [s.provenance.parameters["b1"] for s in again] == [0.5, 1.0, 2.0]
    np.testing.assert_array_equal(again.damping, stack.damping)
    volts = np.zeros((3, 4, 2))
    solved = TrajectoryStack.solved_as_one("exact", np.arange(4.0), volts, volts, SolverStats(0.0))
    assert solved.take([2, 0])[0] is solved[2]


def test_the_exact_solver_fails_only_the_nonlinear_row_of_a_stack():
    """A stack of a linear and a nonlinear system: the exact solver takes the first and says why not the second."""
    from analogy.circuit.node_stack import NodeStack
    from analogy.presets import preset
    from analogy.solvers.registry import run_many
    linear = scene("default").system()
    nonlinear = scene("default").replace(dynamics="nonlinear").system()
    first, second = run_many("exact", NodeStack([linear, nonlinear]), None, preset("fast"))
    assert first.success and not second.success and "applies only to linear systems" in second.message
