"""Scenes per second: batched ngspice runs against one run per scene, a plain PySpice loop and ngspice alone."""

from __future__ import annotations

import logging
import os
import statistics
import time as _time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..batch.executor import PIPELINE
from ..batch.plan import as_system
from ..batch.run import run_batch
from ..circuit.description import circuit
from ..errors import InputError
from ..processes import worker_pool
from ..presets import preset as get_preset
from ..progress import Progress
from ..results.metrics import relative_error
from ..scenes.builtin import scene
from ..solvers.exact import solve_exact
from ..circuit.scales import run_scales
from ..solvers.quiet_ngspice import quiet_session
from ..solvers.spice import library_path, session, solve_spice
from ..solvers.transient import batch_netlist

__all__ = ["throughput"]


def _pyspice_loop(payload):
    """A plain PySpice loop: build a Circuit and call simulator().transient() per scene."""
    os.environ.setdefault("NGSPICE_LIBRARY_PATH", library_path())
    logging.getLogger("PySpice").setLevel(logging.CRITICAL)
    from PySpice.Spice.Netlist import Circuit

    items, preset_name = payload
    p = get_preset(preset_name)
    worst = 0.0
    start = None
    for k, item in enumerate([items[0]] + list(items)):
        if k == 1:      # the first pass is a warm-up: model, library and imports are ready
            start = _time.perf_counter()
        s = as_system(item)
        c = Circuit("scene")
        desc = circuit(s)
        for e in desc.elements:
            getattr(c, e.kind)(e.name[1:], f"n{e.a}", c.gnd if e.b == 0 else f"n{e.b}", e.value)
        for src in desc.sources:        # constant forces: 'I n+ n- value' drives current into n-
            c.I(src.name[1:], c.gnd if src.b == 0 else f"n{src.b}", f"n{src.a}",
                src.scale * float(src.waveform.values[0]))
        sim = c.simulator(simulator="ngspice-shared")
        sim.initial_condition(**{n: float(v) for n, v in zip(s.nodes, s.initial_voltages)})
        sim.options(**p.spice.options)
        analysis = sim.transient(step_time=s.t_stop / p.steps, end_time=s.t_stop,
                                 max_time=s.t_stop / p.spice.max_steps, use_initial_condition=True)
        t = np.array(analysis.time)
        v = np.column_stack([np.array(analysis[n]) for n in s.nodes])
        ex = solve_exact(s, t).rates
        worst = max(worst, relative_error(s.joint_rates(v), ex))
    return _time.perf_counter() - start, worst


def _solo_loop(payload):
    """One ngspice run per scene through the wrapped session, with the same comparison."""
    items, preset_name = payload
    worst, solves = 0.0, []
    start = None
    for k, item in enumerate([items[0]] + list(items)):
        if k == 1:      # the first pass is a warm-up, as in the PySpice loop
            start = _time.perf_counter()
            solves = []
        s = as_system(item)
        tr = solve_spice(s, preset=preset_name)
        solves.append(tr.run_time)
        ex = solve_exact(s, tr.time).rates
        worst = max(worst, relative_error(tr.rates, ex))
    return _time.perf_counter() - start, worst, statistics.median(solves)


def _floor_loop(payload):
    """ngspice alone: the batch netlists of the batched path (groups of *group_size*), written
    first and then loaded and run in the quiet session the batched path runs them in, only that
    timed: what the batched path cannot beat. With *start_at* (a wall-clock time), the timed part
    waits for it, so that workers started together run together. Returns (ready, start, end, CPU
    seconds), wall-clock times."""
    items, preset_name, group_size, start_at = payload
    systems = [as_system(item) for item in items]
    groups = [systems[k:k + group_size] for k in range(0, len(systems), group_size)]
    texts = [batch_netlist(g, preset_name, run_scales(g)) for g in groups]
    sess = quiet_session() or session()     # the batched path's own library: nothing printed
    sess.run(texts[0], None, {})            # warm-up, as on the other paths
    ready = _time.time()
    if start_at is not None:
        _time.sleep(max(start_at - ready, 0.0))
    start, cpu = _time.time(), _time.process_time()
    for text in texts:
        sess.run(text, None, {})
    return ready, start, _time.time(), _time.process_time() - cpu


class _Together(NamedTuple):
    """The floor on several processes at once."""

    rate: float             # scenes per second, from the first start to the last end
    processes: int          # how many had netlists to run
    late: bool              # a process was still setting up at the common start: the span counts its wait


def _floor_together(items, preset_name: str, group_size: int, workers: int, lead: float,
                    attempts: int = 3) -> _Together:
    """The floor on *workers* fresh processes at once, each with every *workers*-th group, timed
    from the first start to the last end. Their timed parts start together, *lead* seconds after
    they are asked; if one is not ready by then, the measurement is made again with twice the lead,
    *attempts* times in all, and the last one is marked late."""
    groups = [items[k:k + group_size] for k in range(0, len(items), group_size)]
    parts = [[m for g in groups[i::workers] for m in g] for i in range(workers)]
    parts = [part for part in parts if part]
    while True:
        with worker_pool(len(parts), fresh=True) as ex:
            start_at = _time.time() + lead
            times = [f.result() for f in [ex.submit(_floor_loop, (part, preset_name, group_size, start_at))
                                          for part in parts]]
        late = max(t[0] for t in times) > start_at
        attempts -= 1
        if not late or attempts < 1:
            return _Together(len(items) / (max(t[2] for t in times) - min(t[1] for t in times)), len(parts), late)
        lead *= 2


#: Most scenes of one throughput measurement (all held in memory at once).
MAX_SCENES = 1_000_000


@dataclass
class _Turns:
    """What the turns of every path measured: scenes per second, CPU seconds, worst errors."""

    processes: int
    rates: dict = field(default_factory=lambda: {k: [] for k in ("batched", "one", "sequential", "solo", "pyspice",
                                                                  "floor", "floors")})
    cpus: dict = field(default_factory=lambda: {"one": [], "sequential": [], "floor": []})
    worst: dict = field(default_factory=lambda: dict.fromkeys(("batched", "one", "sequential", "solo", "pyspice",
                                                              "floor", "floors"), 0.0))
    solves: list = field(default_factory=list)
    failed: int = 0
    late: int = 0


def _take_turns(turns: _Turns, n: int, preset: str, group_size: int, workers: int, baseline_n: int, seed: int,
                repeats: int, progress: bool) -> None:
    """Every path, *repeats* times in turn, into *turns*."""
    base = scene("default")
    q2 = np.random.default_rng(seed).uniform(-np.pi, np.pi, n)
    items = [base.replace(q=(0.0, float(x))) for x in q2]
    rates, cpus, worst = turns.rates, turns.cpus, turns.worst
    bar = Progress((6 + (workers > 1)) * repeats, unit="path run", enabled=progress, every=0.0)

    def batch(key: str, pool: int, threads: int = PIPELINE) -> None:
        cpu = _time.process_time()
        res = run_batch(items, preset, group_size=group_size, workers=pool, threads=threads)
        if key in cpus:            # this process's CPU, its threads and ngspice's included
            cpus[key].append(_time.process_time() - cpu)
        rates[key].append(res.throughput)
        # a run with no finite error (all failed) makes the worst error NaN, not hidden
        ok = res.errors[np.isfinite(res.errors)]
        worst[key] = max(worst[key], float(ok.max())) if ok.size else float("nan")
        turns.failed += len(res.failures)
        bar.update(1)

    # a warm-up group here, as the floor and the loops have theirs: the library loaded and the
    # model compiled in this process (about 60 ms, an eighth of a run of 5,000 scenes) are not timed
    run_batch(items[:group_size], preset, group_size=group_size, workers=1)
    for _ in range(repeats):
        with worker_pool(1, fresh=True) as ex:
            sec, err, med = ex.submit(_solo_loop, (items[:baseline_n], preset)).result()
        rates["solo"].append(baseline_n / sec)
        worst["solo"] = max(worst["solo"], err)
        turns.solves.append(med)
        bar.update(1)
        with worker_pool(1, fresh=True) as ex:
            sec, err = ex.submit(_pyspice_loop, (items[:baseline_n], preset)).result()
        rates["pyspice"].append(baseline_n / sec)
        worst["pyspice"] = max(worst["pyspice"], err)
        bar.update(1)
        # each share's two paths run one after the other, so that both meet the machine as it is then
        asked = _time.time()
        with worker_pool(1, fresh=True) as ex:
            ready, start, end, cpu = ex.submit(_floor_loop, (items, preset, group_size, None)).result()
        rates["floor"].append(n / (end - start))
        cpus["floor"].append(cpu)
        bar.update(1)
        batch("one", 1)
        batch("sequential", 1, threads=1)
        if workers > 1:         # a fresh worker was ready after (ready - asked): twice that is lead enough
            together = _floor_together(items, preset, group_size, workers, 2 * (ready - asked) + 0.5)
            rates["floors"].append(together.rate)
            turns.late += together.late
            turns.processes = together.processes
            bar.update(1)
        batch("batched", workers)
    bar.close()


def _summary(turns: _Turns, n: int, preset: str, group_size: int, workers: int, baseline_n: int,
             repeats: int) -> str:
    """The figures of *turns*: medians, spreads, shares of the ngspice floor, speed-ups."""
    rates, cpus, worst = turns.rates, turns.cpus, turns.worst
    solves, failed, late, processes = turns.solves, turns.failed, turns.late, turns.processes
    med = {k: statistics.median(v) for k, v in rates.items() if v}
    ratio = statistics.median(b / p for b, p in zip(rates["batched"], rates["pyspice"]))
    per_core = statistics.median(b / p for b, p in zip(rates["one"], rates["pyspice"]))
    of_floor = statistics.median(b / f for b, f in zip(rates["one"], rates["floor"]))

    def cpu_per(key):
        return f"CPU {statistics.median(cpus[key]) / n * 1e6:.0f} ms per 1,000 scenes"

    def share(key):         # per turn, this process's CPU beyond the floor's on the same netlists, a scene
        return statistics.median(o - f for o, f in zip(cpus[key], cpus["floor"])) / n * 1e6

    def spread(key):
        return f"{med[key]:,.0f} scenes/s (runs {', '.join(f'{r:,.0f}' for r in rates[key])})"

    lines = [
        f"throughput: default 2-DOF serial arm, random q2 in [-pi, pi], preset {preset}, "
        f"SPICE + comparison with the exact solution; medians of {repeats} turns",
        f"  batched, {workers} workers, {group_size} scenes per ngspice run, {n} scenes: "
        f"{spread('batched')}, worst error/peak {worst['batched']:.2e}",
        f"  batched, 1 process ({PIPELINE} groups in flight on threads): {spread('one')}, "
        f"{cpu_per('one')}: {share('one'):.0f} us a scene beyond the floor's (Python's, and the two cores "
        f"slowing each other), worst error/peak {worst['one']:.2e}",
        f"  batched, 1 process, one group at a time: {spread('sequential')}, {cpu_per('sequential')}: "
        f"{share('sequential'):.0f} us a scene beyond the floor's (Python's share), "
        f"worst error/peak {worst['sequential']:.2e}",
        f"  one ngspice run per scene (1 process, {baseline_n} scenes): {spread('solo')}, "
        f"worst error/peak {worst['solo']:.2e}, median SPICE solve {statistics.median(solves) * 1e3:.3f} ms",
        f"  plain PySpice loop (Circuit + simulator().transient(), 1 process, {baseline_n} scenes): "
        f"{spread('pyspice')}, worst error/peak {worst['pyspice']:.2e}",
        f"  ngspice alone on the same batch netlists (1 process, {n} scenes, loading and running only): "
        f"{spread('floor')}, {cpu_per('floor')}",
    ]
    shares = f"batched on 1 process reaches {of_floor:.2f} of the ngspice floor"
    if workers > 1:
        gain = statistics.median(f / o for f, o in zip(rates["floors"], rates["floor"]))
        lines.append(f"  ngspice alone on {processes} processes at once (the netlists dealt out in turn): "
                     f"{spread('floors')}, {gain:.2f}x one process: what {processes} busy cores give here"
                     + (f" ({late} of {repeats} turns had a process start late, its wait counted)" if late else ""))
        shares += (f", batched on {workers} workers "
                   f"{statistics.median(b / f for b, f in zip(rates['batched'], rates['floors'])):.2f} "
                   f"of the floor on {processes} processes (the batched figure includes starting its workers)")
    lines.append(f"  speed-up over the PySpice loop (median of per-turn ratios): batched {ratio:.1f}x, "
                 f"batched on 1 process {per_core:.1f}x; {shares}; {failed} scenes failed")
    return "\n".join(lines)


def throughput(n: int = 10_000, preset: str = "fast", group_size: int = 100, workers: int = 2,
               baseline_n: int = 500, seed: int = 0, repeats: int = 3, progress: bool = True) -> str:
    """Scenes per second: batched (grouped runs on *workers* processes) against per-scene paths.

    The scenes are the default 2-DOF serial arm at random q2 in [−π, π]. Each path builds
    its systems, runs SPICE and compares with the exact solution. The per-scene paths
    run on *baseline_n* scenes in a fresh worker process each (timed after a warm-up
    pass); the batched path is timed whole, worker start-up included, on *workers*
    processes, and on one, this one, after a warm-up group (whose threads keep a group's
    Python going while ngspice runs another: its CPU time is printed beside the floor's), and on
    this one again with one group at a time: its CPU beyond the floor's is Python's share alone,
    where with threads it also holds what the two busy cores cost each other. The
    floor is ngspice alone loading and running the same batch netlists in one process, written
    beforehand: the batched path on one process is reported as a share of it. With more than one worker the floor also runs on
    that many processes at once, each with every other netlist (their timed parts started together),
    and the batched path on *workers* processes is reported as a share of that. The paths take
    turns, *repeats* times, each share's two paths one right after the other, and the figures
    are medians.

    Parameters
    ----------
    n : int
        Scenes on the batched path.
    preset : str
        Accuracy preset.
    group_size : int
        Scenes per ngspice run.
    workers : int
        Worker processes of the batched path.
    baseline_n : int
        Scenes on each per-scene path.
    seed : int
        Seed of the random configurations.
    repeats : int
        Turns of every path; medians are reported.
    progress : bool
        Show progress by path run: a bar on a terminal, plain lines otherwise.
    """
    if min(n, baseline_n, repeats, workers, group_size) < 1:
        raise InputError("n, baseline_n, repeats, workers and group_size must be at least 1")
    if n > MAX_SCENES or baseline_n > MAX_SCENES or repeats > 1000 or workers > 256:
        raise InputError(f"throughput runs at most {MAX_SCENES:,} scenes (-n, --baseline), 1000 repeats and "
                         "256 workers: each scene is held in memory; use analogy batch for more")
    turns = _Turns(workers)
    _take_turns(turns, n, preset, group_size, workers, baseline_n, seed, repeats, progress)
    return _summary(turns, n, preset, group_size, workers, baseline_n, repeats)
