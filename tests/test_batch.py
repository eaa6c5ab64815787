"""Batched runs: many sub-circuits in one ngspice run give each scene its own solution."""

import numpy as np
import pytest

import analogy
from analogy.batch import run_batch
from analogy.solvers.transient import batch_netlist
from analogy.presets import TOLERANCES, preset
from analogy.scenes.builtin import SCENES, scene
from analogy.solvers.exact import solve_exact, solve_exact_many
from analogy.solvers.spice import SOLVER as SPICE


def test_vectorised_exact_equals_the_single_system_solver():
    systems = [scene(n).system() for n in SCENES if scene(n).t_stop == 10.0]
    model = analogy.robot("serial2")
    systems += [scene("default").replace(q=(0.0, q)).system(model) for q in np.linspace(-3, 3, 7)]
    t = np.linspace(0.0, 10.0, 37)
    for s, v in zip(systems, solve_exact_many(systems, t)):
        ref = solve_exact(s, t).voltages
        assert np.max(np.abs(v - ref)) <= 1e-13 * np.max(np.abs(ref))


def test_batch_netlist_keeps_circuits_independent():
    systems = [scene("default").system(), scene("serial2").system()]
    text = batch_netlist(systems)
    assert "Cx0_1_2 x0_n1 x0_n2" in text and "Cx1_1_2 x1_n1 x1_n2" in text
    assert text.count(".tran") == 1


def test_a_batch_of_horizons_runs_to_the_longest_and_steps_onto_each():
    """One .tran to the longest horizon; each shorter one is a corner of a zero current source."""
    text = batch_netlist([scene("default").system(), scene("redundant").system()])       # 10 s and 8 s
    tran = next(ln for ln in text.splitlines() if ln.startswith(".tran")).split()
    assert float(tran[2]) == 10.0
    corners = next(ln for ln in text.splitlines() if ln.startswith("Ifirst_step"))
    assert " 8 0" in corners or " 8.0 0" in corners


@pytest.mark.ngspice
def test_systems_of_different_horizons_share_one_run_each_ending_at_its_own(monkeypatch):
    """Horizons in [1, 2] s in one ngspice run: every output ends at its system's own t_stop and
    keeps the preset's bound against the exact solution, per joint against its own peak."""
    from analogy.solvers import quiet_ngspice, spice
    runs = []
    real = spice.session()

    class Counting:
        def run(self, text, vectors=None, stats=None, timeout=None, until=None):
            runs.append(text)
            return real.run(text, vectors, stats, timeout=timeout, until=until)

    monkeypatch.setattr(spice, "session", Counting)
    quietly = spice.run_quietly

    def counted(text, t_stop, stats=None):      # a short stack runs in the quiet library
        runs.append(text)
        return quietly(text, t_stop, stats)
    monkeypatch.setattr(spice, "run_quietly", counted)
    quiet_ngspice.quiet_session()       # loaded before the talking session is watched for fallbacks
    monkeypatch.setattr(quiet_ngspice, "session", Counting)
    rng = np.random.default_rng(5)
    stack = analogy.node_systems(analogy.robot("serial2"), rng.uniform(-2, 2, (8, 2)),
                                 forces=["step(1)", "sine(0, 1, 2)"])
    ends = rng.uniform(1.0, 2.0, len(stack))
    systems = stack.driven(None, ends)
    trajectories = SPICE.solve_many(systems, None, preset("accurate"))
    assert len(runs) == 1               # one quiet run, and no run again in the talking library
    for s, tr in zip(systems, trajectories):
        assert abs(tr.time[-1] - s.t_stop) <= 4 * np.finfo(float).eps * s.t_stop    # a breakpoint: landed on
        exact = solve_exact(s, tr.time).rates
        per_joint = np.max(np.abs(tr.rates - exact), axis=0) / np.max(np.abs(exact), axis=0)
        assert np.all(per_joint <= preset("accurate").bound)


@pytest.mark.ngspice
def test_grouped_run_matches_one_run_per_scene():
    """Each scene's joint rates agree with the exact solution whichever path ran it."""
    model = analogy.robot("serial2")
    systems = [scene("default").replace(q=(0.0, q)).system(model) for q in np.linspace(-3, 3, 12)]
    trajectories = SPICE.solve_many(systems, None, preset("accurate"))
    assert len({id(tr.time) for tr in trajectories}) == 1          # one run, one time grid
    for s, tr in zip(systems, trajectories):
        grouped = analogy.relative_error(tr.rates, solve_exact(s, tr.time).rates)
        solo = analogy.compare(s, "accurate", ["spice"]).max_relative_error("spice")
        assert grouped <= 1e-6 and solo <= 1e-6


@pytest.mark.ngspice
def test_run_batch_over_workers_and_groups():
    items = [scene("default").replace(q=(0.0, q)) for q in np.linspace(-np.pi, np.pi, 60)]
    one = run_batch(items, "fast", group_size=25, workers=1)
    two = run_batch(items, "fast", group_size=20, workers=2)
    assert not one.failures and not two.failures
    assert np.all(one.errors <= 1e-3) and np.all(two.errors <= 1e-3)
    assert one.throughput > 0


@pytest.mark.ngspice
def test_any_executor_runs_the_groups_with_the_same_results():
    from concurrent.futures import ThreadPoolExecutor
    items = [scene("default").replace(q=(0.0, q), t_stop=3.0) for q in np.linspace(-2, 2, 9)]
    plain = run_batch(items, "fast", group_size=4, workers=1)
    with ThreadPoolExecutor(2) as ex:       # the session's lock serialises ngspice
        pooled = run_batch(items, "fast", group_size=4, executor=ex)
    np.testing.assert_array_equal(pooled.errors, plain.errors)
    assert not pooled.failures and np.all(pooled.errors <= 1e-3)


@pytest.mark.ngspice
def test_a_batch_result_is_a_short_repr_a_table_and_a_frame():
    items = [scene("default").replace(q=(0.0, q), t_stop=2.0) for q in np.linspace(-1, 1, 6)]
    res = run_batch(items, "fast", solvers=("spice", "ode"), workers=1)
    text = repr(res)
    assert text.startswith("<BatchResult 6 scenes") and "\n" not in text and len(text) < 200
    frame = res.to_frame()
    assert list(frame.columns) == ["error_spice", "error_ode", "failure"] and len(frame) == 6
    assert (frame["error_spice"] <= 1e-3).all() and (frame["error_ode"] <= 1e-3).all()
    assert res._repr_html_().startswith("<table>")


def _stiff_system():
    from analogy import node_system
    from analogy.model.joint import JointSpace
    # √(k/m) ≈ 2.4e7 rad/s over 10 s: about 5e8 time points, past the fast preset's budget
    return node_system(JointSpace(np.array([[2.0, 0.5], [0.5, 1.0]]), np.eye(2), np.diag([1e15, 1.0])), t_stop=10)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_scene_past_the_work_budget_is_refused_alone_and_the_rest_run(workers):
    base = scene("default")
    items = [base.replace(q=(0.0, 0.01 * k)) for k in range(40)]
    res = run_batch(items[:20] + [_stiff_system()] + items[20:], "fast", workers=workers, group_size=15)
    assert list(res.failures) == [20] and "more than the budget" in res.failures[20]
    assert np.isnan(res.errors[20]) and np.isfinite(np.delete(res.errors, 20)).all()
    assert (np.delete(res.errors, 20) <= preset("fast").bound).all()


def test_a_scene_whose_build_raises_anything_fails_alone(monkeypatch):
    """An unexpected exception in one scene (a bug) is that scene's failure, not the batch's."""
    import analogy.batch.plan as plan
    base = scene("default")
    items = [base.replace(q=(0.0, 0.01 * k)) for k in range(30)]
    build = plan.as_system

    def faulty(item):
        if tuple(item.q) == items[7].q:
            raise RuntimeError("a bug in one scene")
        return build(item)
    monkeypatch.setattr(plan, "as_system", faulty)
    monkeypatch.setattr(type(base), "systems", lambda self, *a, **k: (_ for _ in ()).throw(
        analogy.InputError("built one by one")))
    res = run_batch(items, "fast", workers=1, group_size=10)
    assert list(res.failures) == [7] and "RuntimeError: a bug in one scene" in res.failures[7]
    assert np.isfinite(np.delete(res.errors, 7)).all()



@pytest.mark.ngspice
def test_a_group_whose_worker_dies_is_run_again_circuit_by_circuit(monkeypatch):
    """A circuit that kills its worker on every attempt (ngspice crashing on it, say; the loop's retries
    are tests/test_executor.py's) loses its own scenes alone: the group of several circuits it came in is
    run again one circuit a group, and the others are solved."""
    import analogy.batch.run as run
    passes = []

    def dying(groups, payload, work, done, died, **kwargs):     # the loop, with the culprit's worker dying
        passes.append([len(g.runs) for g in groups])
        for g in groups:
            died(g) if 77 in g.rows else done(g, work(payload(g)))
        return False
    monkeypatch.setattr(run, "execute", dying)
    items = [scene("default").replace(q=(0.0, float(x)), t_stop=1.0) for x in np.linspace(-3.0, 0.5, 80)]
    res = run_batch(items, "fast", group_size=5, workers=1)
    assert passes == [[4] * 4, [0] * 4]         # four groups of four circuits, then the dead one's four
    assert sorted(res.failures) == list(range(75, 80))
    assert all("the worker process died" in why for why in res.failures.values())
    assert np.all(res.errors[:75] <= preset("fast").bound)


def test_groups_hold_horizons_within_the_spread_and_families_span_them():
    """The planner sorts horizons into runs whose longest is at most HORIZON_SPREAD times the shortest."""
    from analogy.batch.plan import HORIZON_SPREAD, plan_groups
    base = scene("default")
    ends = [10.0, 1.0, 2.5, 1.5, 4.1, 1.9]
    groups = plan_groups([base.replace(t_stop=t, q=(0.0, 0.1 * k)) for k, t in enumerate(ends)], 100)
    assert sorted(g.rows for g in groups) == [(0,), (1, 3, 5), (2, 4)]
    for g in groups:
        spans = [m.t_stop for m in g.members()]
        assert max(spans) <= HORIZON_SPREAD * min(spans)
        assert spans == [ends[k] for k in g.rows]           # each member keeps its own horizon
        assert [s.t_stop for s in g.build()[0]] == spans


def test_scenes_sharing_their_parts_plan_as_scenes_rebuilt_from_scratch():
    """A scene made from the last by replace(q=…) is planned by the identity of its parts, with no family key
    made: the groups are those of the same scenes each rebuilt from plain values, interleaved with another
    family, a subclass of float in q (checked value by value) and a nonlinear scene (a single)."""
    from dataclasses import fields
    from analogy.batch.plan import plan_groups
    from analogy.scenes.scene import Scene
    base, other = scene("default"), scene("serial2")
    made = [base.replace(q=(0.0, 0.1 * k)) for k in range(7)] + [other.replace(q=(0.2, 0.1 * k)) for k in range(3)]
    made += [base.replace(q=(0.0, np.float64(0.9))), base.replace(dynamics="nonlinear"), base.replace(q=(0.0, 1.1))]
    thawed = ("q", "forces", "initial_rates", "parameters", "solvers")        # what Scene.of freezes
    rebuilt = [Scene.of(s.name, s.model.robot, **{f.name: _thawed(getattr(s, f.name)) if f.name in thawed
                                                  else getattr(s, f.name) for f in fields(s)[2:]}) for s in made]
    assert made[1].forces is made[0].forces and rebuilt[1].forces is not rebuilt[0].forces
    assert rebuilt == made
    for size, circuits in ((3, 1), (4, 2), (100, 1)):
        assert [(g.rows, g.runs) for g in plan_groups(made, size, circuits)] == \
            [(g.rows, g.runs) for g in plan_groups(rebuilt, size, circuits)]


def _thawed(value):
    """*value* with its tuples as new lists: equal content, no object shared."""
    return [_thawed(v) for v in value] if isinstance(value, tuple) else value


@pytest.mark.ngspice
def test_a_sweep_over_horizons_keeps_each_scenes_bound():
    """Scenes of one family with different t_stop run together, each judged over its own horizon."""
    base = scene("default")
    items = [base.replace(q=(0.0, q), t_stop=t) for q, t in zip(np.linspace(-2, 2, 6), np.linspace(3, 5, 6))]
    res = run_batch(items, "fast", workers=1)
    assert not res.failures and np.all(res.errors <= preset("fast").bound)


@pytest.mark.ngspice
def test_throughput_reports_the_ngspice_floor_beside_the_batched_path():
    """The floor is ngspice alone on the very batch netlists the batched path runs: every
    path's worst error stays within the fast bound, and the share of the floor is printed."""
    import re
    from analogy.diagnostics.throughput import throughput
    text = throughput(n=200, baseline_n=20, repeats=1, workers=2, group_size=50, progress=False)
    assert "ngspice alone on the same batch netlists (1 process, 200 scenes" in text
    share = re.search(r"reaches (\d+\.\d+) of the ngspice floor, batched on 2 workers (\d+\.\d+) of the floor "
                      r"on 2 processes \(the batched figure includes starting its workers\); 0 scenes failed", text)
    assert share is not None and min(float(share.group(1)), float(share.group(2))) > 0
    # the floor on two processes at once, as a multiple of the one-process floor (how much two busy
    # cores give depends on the machine and its load, so no bound on it is asserted)
    gain = re.search(r"ngspice alone on 2 processes at once \(the netlists dealt out in turn\): .*, "
                     r"(\d+\.\d+)x one process", text)
    assert gain is not None and 0 < float(gain.group(1))
    worst = [float(x) for x in re.findall(r"worst error/peak (\S+?),?\s", text + " ")]
    assert len(worst) == 5 and max(worst) <= 1e-3
    # one process with threads, one group at a time, the floor
    cpu = [int(x) for x in re.findall(r"CPU (\d+) ms per 1,000 scenes", text)]
    assert len(cpu) == 3 and min(cpu) > 0
    # each share is that path's CPU beyond the floor's: ms per 1,000 scenes are us a scene, each of
    # the three printed to the nearest one, so they agree within 1.5
    shares = [int(x) for x in re.findall(r"CPU \d+ ms per 1,000 scenes: (-?\d+) us a scene beyond the floor's", text)]
    assert len(shares) == 2 and all(abs(s - (c - cpu[2])) <= 1.5 for s, c in zip(shares, cpu))
    assert "(Python's share)" in text


def test_a_process_not_ready_at_the_common_start_marks_the_floor_on_several_processes_late():
    """The processes' timed parts start together only if each is set up by then: a fresh
    process takes far longer than 1 ms to start, so with that lead the figure is marked."""
    from analogy.scenes.builtin import scene
    from analogy.diagnostics.throughput import _floor_together
    items = [scene("default").replace(q=(0.0, 0.01 * k)) for k in range(60)]
    together = _floor_together(items, "fast", 20, 2, lead=0.001, attempts=1)
    assert together.late and together.processes == 2 and together.rate > 0


def test_a_halt_request_halts_a_circuit_running_in_another_thread():
    """The in-process batch runs groups on threads, so its stop reaches a running circuit through
    the process's halt record: ngspice is halted, the run raises KeyboardInterrupt (no result),
    and the session runs the next circuit soundly."""
    import threading

    from analogy.processes import halt_requests as stop_requests
    from analogy.solvers.ngspice import session

    # an undamped LC over 1e4 s at steps of at most 1e-5 s: 1e9 steps, far longer than the test
    endless = "* endless\nL1 n1 0 1\nC1 n1 0 1\nI1 0 n1 DC 1\n.tran 1e-3 1e4 0 1e-5 uic\n.end\n"
    raised: list = []

    def run():
        try:
            session().run(endless, None, None, timeout=600.0)
        except BaseException as exc:    # noqa: BLE001 - the test reads which
            raised.append(type(exc))
    worker = threading.Thread(target=run)
    worker.start()
    try:
        worker.join(0.5)
        assert worker.is_alive()        # still running: the stop below is what ends it
        stop_requests.ask()
        worker.join(60.0)
    finally:
        stop_requests.clear()
    assert not worker.is_alive() and raised == [KeyboardInterrupt]
    data = session().run("* after\nR1 n1 0 1\nC1 n1 0 1\nI1 0 n1 DC 1\n.tran 0.01 1 uic\n.end\n", ["n1"])
    # v = 1 − e^(−t) on ngspice's points, within its default reltol (1e-3) of the peak, 1 V
    assert np.allclose(data["n1"], 1 - np.exp(-data["time"]), rtol=0, atol=1e-3)


def test_a_batch_of_scenes_runs_each_at_its_own_preset():
    """A scene's preset is part of the job: the batch holds each scene to its own bound
    (the accurate one at 1e-6, not at the fast preset's 1e-3), and an explicit preset
    applies to every member."""
    sc = scene("default")
    own = run_batch([sc.replace(preset="fast"), sc, sc.replace(q=(0.1, 0.2))], workers=1)
    assert own.errors[0] <= TOLERANCES["fast"] and own.errors[0] > TOLERANCES["accurate"]
    assert np.all(own.errors[1:] <= TOLERANCES["accurate"])
    fixed = run_batch([sc], "fast", workers=1)
    assert fixed.errors[0] == own.errors[0]
