"""The spice solver: a node system's circuit simulated by ngspice in process, retried where its step collapses."""

from __future__ import annotations

import math
import time as _time
from dataclasses import replace
from functools import lru_cache

import numpy as np

from ..circuit.currents import element_currents
from ..circuit.description import circuit
from ..circuit.elements import point_operations
from ..circuit.netlist import save_vectors, write_netlist
from ..circuit.node_stack import NodeStack
from ..circuit.scales import run_scales, system_scales
from ..errors import SimulationError
from ..presets import Preset
from ..presets import preset as get_preset
from ..results.trajectory import SolverStats, Trajectory
from ..results.trajectory_stack import TrajectoryStack
from .ngspice import NgspiceSession, collapsed, library_path, run_netlist, session, vector_key
from .quiet_ngspice import run_quietly
from .registry import Solver, stacked_trajectories
from .transient import REFINE, RETRY_LOOSEN, batch_netlist, circuit_settings, refined

__all__ = ["NgspiceSession", "session", "run_netlist", "solve_spice", "library_path", "vector_key",
           "SpiceSolver", "SOLVER", "RETRY_LOOSEN"]     # the session's names, re-exported


def _from_start(time: np.ndarray) -> tuple[np.ndarray, bool]:
    """SPICE's time points with t = 0 first (ngspice's first output point is its first step)."""
    if time.size and time[0] > 0:
        return np.concatenate([[0.0], time]), True
    return time, False


def _trajectory(system, time, prepended: bool, volts, currents, stats, elapsed,
                positions=None) -> Trajectory:
    """A SPICE result on *time*; with *prepended*, its first row is the initial state."""
    if prepended:
        v0 = system.initial_voltages
        volts = np.vstack([v0, volts])
        if positions is not None:
            positions = np.vstack([np.zeros(system.dof), positions])
        if currents:
            first = element_currents(system, np.zeros(1), v0[None], np.zeros((1, system.dof)),
                                     list(currents))
            currents = {k: np.concatenate([first[k], x]) for k, x in currents.items()}
    info = SolverStats(elapsed, max(int(time.size) - 1, 0), stats.get("rejected"), stats.get("iterations"))
    return Trajectory("spice", time, volts, system.joint_rates(volts), positions, currents=currents,
                      stats=info)


def _limit(scales, t_stop: float, preset: Preset, size: float) -> float | None:
    """The preset's wall-time limit where the run may be long: its fastest rate times t_stop
    past 10^4, or its step cap's points times *size* past 10^8 (about half a second at 5 ns a
    unit); None runs in the foreground, which costs a quarter millisecond less, and less waiting
    for the GIL where other threads run Python (no background thread to hand back to). *size* is
    :func:`run_size` of the run's independent circuits."""
    if scales is None or preset.budget.timeout is None or not math.isfinite(preset.budget.timeout):
        return None
    short = scales.fastest(preset.bound) * t_stop <= 1e4 and preset.spice.max_steps * size <= 1e8
    return None if short else preset.budget.timeout


def run_size(dofs) -> float:
    """A run's work per step in :func:`_limit`'s units: Σ (n³ + 16·n) over its independent circuits
    of n nodes each (a stack's are blocks of its matrix). A dense circuit's factorisation goes as
    n³; each node's own work counts 16 of those units: 600 2-DOF circuits (1,200 nodes) took 1.6 s
    for 20,000 steps, 67 ns a node and step, against about 5 ns a unit of n³.

    Parameters
    ----------
    dofs : iterable of int
        The circuits' node counts.
    """
    return sum(float(n) ** 3 + 16.0 * n for n in dofs)


def solve_spice(system, times=None, *, preset="accurate", save=None) -> Trajectory:
    """Simulate *system*'s netlist in ngspice and recover joint rates from node voltages.

    A run whose step collapses ("time step too small") is run again as
    :meth:`~analogy.solvers.transient.TransientSettings.retries` says (abstol and vntol
    :data:`RETRY_LOOSEN` times larger, then gear instead of the trapezoidal rule); the
    trajectory's :attr:`~Trajectory.message` says so, and the bound judges the result.

    Parameters
    ----------
    system : NodeSystem or NonlinearNodeSystem
        A linear system, or a nonlinear one with a symbolic model (its circuit has
        charge-defined capacitors, behavioural currents and integrators).
    times : array_like, optional
        Output times, interpolated onto from SPICE's own points (default: those points, t = 0 added).
    preset : str or Preset
        Accuracy preset.
    save : sequence of str, optional
        Element names whose currents to return in :attr:`Trajectory.currents`.
    """
    preset = get_preset(preset)
    circ = circuit(system, realizable=getattr(system, "realizable", False), describe=False)
    names = [e for e in (save or []) if e not in system.nodes] + circ.state_nodes + circ.monitors + list(circ.outputs)
    vectors = save_vectors(circ, list(system.nodes) + names)
    scales = system_scales(system)
    settings = circuit_settings(system, circ, preset)
    sess = session()
    start = _time.perf_counter()
    note = ""
    ladder = settings.retries()
    waited = 0.0
    for k, settings in enumerate(ladder):
        stats: dict = {}
        text = write_netlist(circ, settings, list(system.nodes) + names, printing=False)
        try:
            size = run_size([system.dof]) if system.kind == "linear" else point_operations(system)
            data = sess.run(text, vectors, stats, timeout=_limit(scales, system.t_stop, preset, size))
            break
        except SimulationError as exc:
            waited += stats.get("waited", 0.0)
            # a collapsed step: the next settings of the ladder, said in the message; the bound judges the result
            if not collapsed(exc) or k == len(ladder) - 1:
                raise
            after = ladder[k + 1]
            note = (f"retried without the clock's short steps, at the cap {after.max_step:.3g} s ({exc})"
                    if after.clock != settings.clock else
                    f"retried with reltol {after.reltol:g} ({exc})" if after.reltol != settings.reltol else
                    f"retried with gear integration ({exc})" if after.method != settings.method else
                    f"retried with abstol and vntol × {after.loosen:g} ({exc})")
    elapsed = _time.perf_counter() - start - waited - stats.get("waited", 0.0)
    v = np.column_stack([data[f"v({n})"] for n in system.nodes])
    x = np.column_stack([data[f"v({n})"] for n in circ.state_nodes]) if circ.state_nodes else None
    # node voltages past the system's own (a closed chain's passive positions and multipliers) are kept
    # beside the element currents: a position starts at 0, a multiplier's node is not known at t = 0
    outputs = circ.outputs
    nodes = {name: 0.0 if name in circ.monitors else outputs[name] if name in outputs else math.nan for name in names
             if name in circ.monitors or name in circ.node_names or name in outputs}
    currents = {name: data[vec] for name, vec in zip(names, vectors[system.dof:])
                if name not in circ.state_nodes and name not in nodes}
    tr = _trajectory(system, *_from_start(data["time"]), v, currents, stats, elapsed, x)
    if nodes:
        start = int(tr.time.size) - int(data["time"].size)
        tr = replace(tr, currents={**tr.currents, **{name: np.concatenate([np.full(start, nodes[name]), data[vec]])
                                                     for name, vec in zip(names, vectors[system.dof:]) if name in nodes}})
    tr = replace(tr, message=note, settings=settings) if note else replace(tr, settings=settings)
    return tr if times is None else tr.resampled(system.time_points(times), system.joint_rates, system.breakpoints())


class SpiceSolver(Solver):
    """ngspice in process: the equivalent circuit, simulated on its own time points."""

    name = "spice"
    own_grid = True
    label = "ngspice (shared library)"

    def ready(self) -> None:
        """Load ngspice's library into the process (about 50 ms, once)."""
        session()

    def supports(self, system) -> str | None:
        """Linear systems, and nonlinear ones with a symbolic model to write as a circuit.

        Parameters
        ----------
        system : NodeDynamics
            The system to be solved.
        """
        if system.kind != "linear" and getattr(system, "model", None) is None:
            return "the spice solver needs the symbolic model of a nonlinear system"
        return None

    def _solve(self, system, times, preset: Preset, *, save=(), positions=False) -> Trajectory:
        """Simulate on SPICE's own points (t = 0 added); :meth:`Solver.solve` interpolates onto given times.

        Parameters
        ----------
        system : NodeSystem
            A linear system, or a nonlinear one with a symbolic model.
        times : None
            SPICE chooses its points.
        preset : Preset
            Accuracy settings (``.options`` and ``.tran``).
        save : sequence of str
            Element names whose device currents to return.
        positions : bool
            Unused: the circuit's states are node voltages.
        """
        return solve_spice(system, preset=preset, save=save)

    def refinements(self, preset: Preset) -> list[tuple[Preset, float]]:
        """Every step :data:`~analogy.solvers.transient.REFINE` times shorter
        (:func:`~analogy.solvers.transient.refined`), an error REFINE² times smaller; then, where
        the tighter tolerances collapse the step (reltol under rounding: serial12 at 1.25e-11),
        the step cap alone, which refines a run whose steps the cap sets.

        Parameters
        ----------
        preset : Preset
            The settings of the run to be judged.
        """
        factor = REFINE ** 2 / (REFINE ** 2 - 1)
        return [(refined(preset), factor), (refined(preset, tolerances=False), factor)]

    def _solve_many(self, systems, times, preset: Preset, *, save=(), positions=False) -> list[Trajectory]:
        """One ngspice run for all systems, to the longest horizon; if it fails, one run each.

        Each system's output ends at its own t_stop, a breakpoint of the run (see
        :func:`~analogy.solvers.transient.batch_netlist`).

        Parameters
        ----------
        systems : sequence of NodeSystem
            Linear systems.
        times : array_like or None
            Must be None: a shared run has SPICE's own points.
        preset : Preset
            Accuracy settings.
        save : sequence of str
            Element currents to return (then each system runs alone).
        positions : bool
            Unused.
        """
        stack = systems if isinstance(systems, NodeStack) else None
        if len(systems) == 1 or save or times is not None or (
                stack.realizable if stack is not None else any(getattr(s, "realizable", False) for s in systems)):
            return super()._solve_many(systems, times, preset, save=save)
        scales = run_scales(systems)
        text = batch_netlist(systems, preset, scales)
        stats: dict = {}
        ends = stack.t_stops if stack is not None else np.array([s.t_stop for s in systems])
        start = _time.perf_counter()
        dofs = None if stack is not None else [x.dof for x in systems]       # a stack's rows are of one size
        n = stack.dof if stack is not None else dofs[0]
        mixed = dofs is not None and any(d != n for d in dofs)
        limit = _limit(scales, float(ends.max()), preset, run_size(dofs) if mixed else len(systems) * run_size([n]))
        try:
            # a short run in the quiet library: no line printed, so no callback waits for the GIL
            data = run_quietly(text, float(ends.max()), stats) if limit is None else \
                session().run(text, None, stats, timeout=limit, until=float(ends.max()))
        except SimulationError:
            return super()._solve_many(systems, times, preset)
        elapsed = (_time.perf_counter() - start - stats.get("waited", 0.0)) / len(systems)
        time, prepended = _from_start(data["time"])
        try:
            # each shorter horizon's points (none where the rows share one, as a family's circuit does)
            cut = {} if ends.min() == ends.max() else \
                {float(end): _until(time, float(end)) for end in np.unique(ends[ends < ends.max()])}
        except SimulationError:
            return super()._solve_many(systems, times, preset)
        if mixed:
            out = []
            for k, s in enumerate(systems):
                t, last = cut.get(s.t_stop, (time, time.size))
                v = np.column_stack([data[f"x{k}_{m}"] for m in s.nodes])[:last - prepended]
                out.append(_trajectory(s, t, prepended, v, {}, stats, elapsed))
            return out
        count = len(systems)
        # (rows, nodes, times) in memory, read as (rows, times, nodes): each output's times stay contiguous
        parts = [data[key] for key in _node_keys(count, n)]
        if prepended:           # each node's start before its points: still one copy
            parts, points = [None] * (2 * len(parts)), parts
            parts[::2], parts[1::2] = list(NodeStack.of(systems).initial_voltages.reshape(-1, 1)), points
        volts = np.concatenate(parts).reshape(count, n, -1).transpose(0, 2, 1)
        if not cut:
            info = SolverStats(elapsed, time.size - 1, stats.get("rejected"), stats.get("iterations"))
            return stacked_trajectories(self.name, systems, time, volts, info)
        stack, rows = NodeStack.of(systems), [None] * count
        for end in np.unique(ends):
            idx = np.flatnonzero(ends == end).tolist()
            t, last = cut.get(float(end), (time, time.size))
            info = SolverStats(elapsed, t.size - 1, stats.get("rejected"), stats.get("iterations"))
            for k, tr in zip(idx, stacked_trajectories(self.name, stack.take(idx), t, volts[idx, :last], info)):
                rows[k] = tr
        return TrajectoryStack(rows)


@lru_cache(maxsize=64)
def _node_keys(count: int, dof: int) -> tuple[str, ...]:
    """The vectors of a batch's node voltages, sub-circuit by sub-circuit, as :meth:`NgspiceSession.run` keys them."""
    return tuple(f"x{k}_n{i + 1}" for k in range(count) for i in range(dof))


def _until(time: np.ndarray, t_stop: float) -> tuple[np.ndarray, int]:
    """SPICE's points up to *t_stop*, a breakpoint of the run, and how many of them there are.

    ngspice lands on a breakpoint to within its own time rounding; that point is taken
    as t_stop itself.
    """
    last = int(np.searchsorted(time, t_stop * (1 + 1e-9), side="right"))
    if last == 0 or abs(time[last - 1] - t_stop) > 1e-9 * t_stop:
        raise SimulationError(f"ngspice did not step onto t = {t_stop:.6g} s, where a system of its run ends")
    return np.concatenate([time[:last - 1], [t_stop]]), last


SOLVER = SpiceSolver()
