"""A drive run: the motors' netlist in ngspice beside the exact solution of the whole, per output, with its power balance."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import InputError, SimulationError, concerning
from ..model.motors import motor_table, motors_from_table
from ..model.urdf_file import transmissions
from ..files import write_figure
from ..presets import Preset
from ..results.metrics import output_errors
from ..results.output import Tabular
from ..solvers.drive import (COULOMB_SPEED, Drive, drive, drive_flow, drive_netlist, drive_settings, drive_state,
                             exact_drive, node_matrices, power_balance)
from ..solvers.ngspice import collapsed, session
from ..solvers.ode import stiff_method

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["DriveRun", "DriveTrace", "run_drive", "scene_drive"]


class DriveTrace(NamedTuple):
    """One solver's joint rates and winding currents on the run's points, and its power balance."""

    time: np.ndarray
    rates: np.ndarray
    currents: np.ndarray
    balance: np.ndarray
    seconds: float


@dataclass(frozen=True, eq=False)
class DriveRun(Tabular):
    """A drive's joint rates and winding currents by each solver on ngspice's points: ``spice`` (its
    netlist as ngspice ran it), ``ode`` (scipy on the whole state space, at the preset's method and
    tolerance) and ``exact`` (where the voltages are piecewise linear), with each output's error
    over its own peak against the exact solution and each run's power balance.

    Attributes
    ----------
    drive : Drive
        What ran.
    netlist : str
        The netlist ngspice ran (what ``analogy drive -o`` writes).
    traces : dict of str to DriveTrace
        Each solver's run on ngspice's points (t = 0 added).
    errors : dict of str to dict of str to float
        Per solver, each output's largest error over its own peak (``r1``, ``i1`` …); empty without
        the exact solution.
    bound : float
        The preset's bound.
    note : str
        How ngspice's run was retried after its step collapsed, if it was.
    reference : str
        The trace the errors are measured against: ``exact``, or where there is no exact
        solution (Coulomb friction, voltages that are not piecewise linear) ``reference``,
        scipy's integration at a hundredth of the preset's tolerance (1e-13 at least).
    """

    drive: Drive
    netlist: str
    traces: dict
    errors: dict
    bound: float
    note: str = ""
    reference: str = "exact"

    @property
    def system(self):
        """The robot's circuit."""
        return self.drive.system

    @property
    def time(self) -> np.ndarray:
        """ngspice's points, t = 0 added."""
        return self.traces["spice"].time

    def __repr__(self) -> str:
        worst = max((e for errs in self.errors.values() for e in errs.values()), default=None)
        shown = f", worst {worst:.2g} of its peak" if worst is not None else ""
        return (f"<DriveRun {self.system.provenance.robot}: {len(self.drive.driven)} motors, "
                f"{'+'.join(self.traces)}, {len(self.time)} points{shown}>")

    def power_in(self, solver: str = "spice") -> np.ndarray:
        """Σ V·i, the power the drives put in on *solver*'s run [W].

        Parameters
        ----------
        solver : str
            A solver that ran.
        """
        trace = self.traces[solver]
        volts = np.column_stack([w(trace.time) if w is not None else np.zeros_like(trace.time)
                                 for w in self.drive.voltages])
        return np.sum(volts * trace.currents, axis=1)

    def balance_error(self, solver: str = "spice") -> float:
        """*solver*'s power balance: its largest residual over the largest power put in.

        Parameters
        ----------
        solver : str
            A solver that ran.
        """
        peak = float(np.max(np.abs(self.power_in(solver))))
        # NaN where its differences reach a voltage's corner (see power_balance)
        return float(np.nanmax(np.abs(self.traces[solver].balance))) / peak if peak > 0 else 0.0

    def over_limits(self) -> dict[str, str]:
        """Each motor whose winding carried more than its current limit in ngspice's run, and by how much."""
        out = {}
        for j in self.drive.driven:
            limit, peak = self.drive.motors[j].current_limit, float(np.max(np.abs(self.traces["spice"].currents[:, j])))
            if peak > limit:
                out[f"i{j + 1}"] = f"{peak:.3g} A, past its limit of {limit:g} A"
        return out

    def outside_bound(self) -> dict[str, float]:
        """The solvers' outputs past the preset's bound (``spice i1``), with their errors."""
        return {f"{name} {k}": e for name, errs in self.errors.items() for k, e in errs.items() if e > self.bound}

    def outputs(self) -> list[tuple[str, str]]:
        """Each output's key and what it is: every joint's rate, each driven winding's current."""
        joints = self.system.provenance.joints or [f"q{j + 1}" for j in range(self.system.dof)]
        out = []
        for j in range(self.system.dof):
            out.append((f"r{j + 1}", f"{joints[j]} rate"))
            if j in self.drive.driven:
                out.append((f"i{j + 1}", f"{joints[j]} winding"))
        return out

    def table(self) -> str:
        """Each output's peak and each solver's error over it; the power balance's residual of each run."""
        solvers = [s for s in self.traces if s != self.reference]
        lines = [f"{'output':<30}{'peak':>11}" + "".join(f"{s + ' error':>14}" for s in solvers)]
        reference = self.traces.get(self.reference, self.traces["spice"])
        for key, what in self.outputs():
            j = int(key[1:]) - 1
            values = reference.rates[:, j] if key[0] == "r" else reference.currents[:, j]
            errs = "".join(f"{self.errors[s][key]:>14.2e}" if key in self.errors.get(s, {}) else f"{'-':>14}"
                           for s in solvers)
            lines.append(f"{key + ' (' + what + ')':<30}{np.max(np.abs(values)):>11.4g}{errs}")
        lines.append(f"{'power balance residual / peak':<41}" + "".join(f"{self.balance_error(s):>14.2e}"
                                                                          for s in solvers))
        lines.append(f"(largest power put in {np.max(np.abs(self.power_in())):.4g} W; "
                     + ", ".join(f"{s} {t.seconds:.3g} s" for s, t in self.traces.items()) + ")")
        return "\n".join(lines)

    def columns(self) -> dict[str, np.ndarray]:
        """``time``, then each joint's rate ``r<j>_<solver>`` and each winding's current ``i<j>_<solver>``."""
        cols: dict[str, np.ndarray] = {"time": self.time}
        for key, _ in self.outputs():
            j = int(key[1:]) - 1
            for name, trace in self.traces.items():
                cols[f"{key}_{name}"] = trace.rates[:, j] if key[0] == "r" else trace.currents[:, j]
        return cols

    def plot(self, path=None) -> "Figure":
        """Joint rates and winding currents, each solver over the exact solution.

        Parameters
        ----------
        path : str or Path, optional
            Write it as PNG or SVG.
        """
        from matplotlib.figure import Figure
        fig = Figure(figsize=(10.0, 6.0), layout="constrained")
        rates, currents = fig.subplots(2, 1, sharex=True)
        for ax, kind, label, which in ((rates, "rates", "joint rate", range(self.system.dof)),
                                       (currents, "currents", "winding current [A]", self.drive.driven)):
            for j in which:
                colour = f"C{j}"
                for name, trace in self.traces.items():
                    wide = name == self.reference        # the yardstick, drawn wide
                    ax.plot(trace.time, getattr(trace, kind)[:, j], lw=4.0 if wide else 1.0, alpha=0.3 if wide else 1.0,
                            color=colour, ls="--" if name == "ode" else "-", label=f"{j + 1}: {name}")
            ax.set_ylabel(label)
            ax.legend(fontsize=7, ncol=6)
        currents.set_xlabel("t [s]")
        fig.suptitle(f"{self.system.provenance.robot} driven by its motors", fontsize=10)
        if path is not None:
            write_figure(fig, path)
        return fig


def _spice(d: Drive, preset: Preset) -> tuple[str, str, DriveTrace]:
    """ngspice's run of the drive's netlist (retried where its step collapses): the netlist, the note, the run."""
    n = d.system.dof
    names = ["time"] + [f"v(p{j + 1})" for j in range(n)] + [f"vs{j + 1}#branch" for j in d.driven]
    ladder, note = drive_settings(d, preset).retries(), ""
    start = time.perf_counter()
    for k, settings in enumerate(ladder):       # a collapsed step: the next settings, said in the note
        text = drive_netlist(d, preset, settings=settings)
        try:
            # a wall-time limit: ngspice 39 was seen to stall at a PWM's corners without failing
            data = session().run(text, names, timeout=preset.budget.timeout)
            break
        except SimulationError as exc:
            if not collapsed(exc) or k == len(ladder) - 1:
                raise
            note = f"retried with {'gear' if ladder[k + 1].method != settings.method else 'looser abstol and vntol'} ({exc})"
    seconds = time.perf_counter() - start
    r0 = d.system.joint_rates(d.system.initial_voltages)
    t = np.concatenate([[0.0], data["time"]]) if data["time"][0] > 0 else data["time"]
    first = len(t) - len(data["time"])         # t = 0 added where ngspice's points start after it
    rates = np.column_stack([np.concatenate([r0[j:j + 1]] * first + [data[f"v(p{j + 1})"]]) for j in range(n)])
    currents = np.zeros_like(rates)
    for j in d.driven:
        m = d.motors[j]
        at_start = 0.0 if m.inductance else (float(d.voltages[j](0.0)) - m.ratio * r0[j]) / m.resistance
        currents[:, j] = np.concatenate([[at_start]] * first + [data[f"vs{j + 1}#branch"]])
    return text, note, DriveTrace(t, rates, currents, power_balance(d, t, rates, currents), seconds)


def _ode(d: Drive, preset: Preset, t: np.ndarray, scale: np.ndarray) -> DriveTrace:
    """scipy's integration of the drive's state space at the preset's method and rtol (atol that of each
    state's *scale*), between the voltages' corners, read on the points *t*."""
    if d.system.kind != "linear":
        return _nonlinear_ode(d, preset, t)
    a, u, load, first = drive_state(d)
    n = d.system.dof
    mass, _, _, cmap = node_matrices(d)
    pushed = np.linalg.solve(mass, cmap)                # M''⁻¹·T⁻ᵀ: a joint torque's node acceleration
    tinv = np.asarray(d.system.topology.inverse, float)
    rough = bool(np.any(d.coulomb))
    corners = np.unique(np.concatenate([np.asarray(w.breakpoints(t[-1]), float) for w in d.voltages if w is not None]
                                       + [[0.0, t[-1]]]))
    corners = corners[(corners >= 0) & (corners <= t[-1])]
    def rhs(s, y):
        dy = a @ y + u @ np.array([w(s) if w is not None else 0.0 for w in d.voltages], float) + load
        if rough:               # Coulomb friction: a load on each joint against its rate
            dy[first:first + n] -= pushed @ d.friction(tinv @ y[first:first + n])
        return dy

    def jac(s, y):
        if not rough:
            return a
        r = tinv @ y[first:first + n]
        slope = d.coulomb / COULOMB_SPEED / np.cosh(np.clip(r / COULOMB_SPEED, -300, 300)) ** 2
        out = a.copy()
        out[first:first + n, first:first + n] -= pushed @ (slope[:, None] * tinv)
        return out
    y = np.zeros(len(a))
    y[first:first + n] = d.system.initial_voltages
    states = np.empty((t.size, len(a)))
    start = time.perf_counter()
    atol = preset.ode.rtol * np.maximum(scale, np.finfo(float).tiny)
    # an explicit method within its stability reach of the windings' fast decay, or Radau where that is stiff
    method, _, longest = stiff_method(d.system, preset.ode.method, jac, y)
    extra = {"jac": jac} if method == "Radau" else {"max_step": longest} if np.isfinite(longest) else {}
    for lo, hi in zip(corners[:-1], corners[1:]):
        sol = solve_ivp(rhs, (lo, hi), y, method=method, rtol=preset.ode.rtol, atol=atol, dense_output=True,
                        **extra)
        if not sol.success:
            raise SimulationError(f"the ODE of the drive failed: {sol.message}")
        inside = slice(np.searchsorted(t, lo, "left"), np.searchsorted(t, hi, "right"))
        if inside.stop > inside.start:      # a jump's ramp may hold no output point
            states[inside] = sol.sol(t[inside]).T
        y = sol.y[:, -1]
    seconds = time.perf_counter() - start
    rates = d.system.joint_rates(states[:, first:first + n])
    currents = np.zeros((t.size, n))
    for i, j in enumerate(d.windings):
        currents[:, j] = states[:, first + n + i]
    for j in d.driven:
        m = d.motors[j]
        if m.inductance == 0:
            currents[:, j] = (d.voltages[j](t) - m.ratio * rates[:, j]) / m.resistance
    return DriveTrace(t, rates, currents, power_balance(d, t, rates, currents), seconds)


def _nonlinear_ode(d: Drive, preset: Preset, t: np.ndarray) -> DriveTrace:
    """scipy's integration of the drive with the robot's full dynamics (:func:`drive_flow`), between the
    voltages' corners, on the points *t*; its step within the explicit method's stability reach of the
    drive's fastest rate at the start pose."""
    n, flow = d.system.dof, drive_flow(d)
    y = np.zeros(2 * n + len(d.windings))
    y[n:2 * n] = d.system.initial_voltages
    corners = np.unique(np.concatenate([np.asarray(w.breakpoints(t[-1]), float) for w in d.voltages if w is not None]
                                       + [[0.0, t[-1]]]))
    corners = corners[(corners >= 0) & (corners <= t[-1])]
    a = drive_state(d, at_rest=True)[0]
    method, _, longest = stiff_method(d.system, preset.ode.method, a, np.zeros(len(a)))
    extra = {"max_step": longest} if method != "Radau" and np.isfinite(longest) else {}
    states = np.empty((t.size, len(y)))
    start = time.perf_counter()
    for lo, hi in zip(corners[:-1], corners[1:]):
        sol = solve_ivp(flow, (lo, hi), y, method=method, rtol=preset.ode.rtol, atol=preset.ode.rtol,
                        dense_output=True, **extra)
        if not sol.success:
            raise SimulationError(f"the ODE of the drive failed: {sol.message}")
        inside = slice(np.searchsorted(t, lo, "left"), np.searchsorted(t, hi, "right"))
        if inside.stop > inside.start:
            states[inside] = sol.sol(t[inside]).T
        y = sol.y[:, -1]
    seconds = time.perf_counter() - start
    rates = d.system.joint_rates(states[:, n:2 * n])
    currents = np.zeros((t.size, n))
    for i, j in enumerate(d.windings):
        currents[:, j] = states[:, 2 * n + i]
    for j in d.driven:
        m = d.motors[j]
        if m.inductance == 0:
            currents[:, j] = (d.voltages[j](t) - m.ratio * rates[:, j]) / m.resistance
    return DriveTrace(t, rates, currents, power_balance(d, t, rates, currents), seconds)


def scene_drive(scene, where: str = "[motors]") -> Drive:
    """A scene's drive: its linear circuit, each joint's motor from the scene's motor table (a URDF's
    transmissions giving the gear ratios the table leaves out) and each motor's voltage.

    Parameters
    ----------
    scene : Scene
        A scene with motors and voltages.
    where : str
        Where the motor table came from, named in errors (a motor file, or a scene file's ``[motors]``).
    """
    if not scene.motors:
        raise InputError("the scene has no motors to drive it: give a [motors] table (--motors FILE)")
    system = scene.system()
    joints = list(system.provenance.joints or [f"q{j + 1}" for j in range(system.dof)])
    model = scene.numeric_model()
    motors = motors_from_table(motor_table(scene.motors), joints, where,
                               transmissions(model.text) if model.rigid_tree else None)
    driven = [j for j, m in enumerate(motors) if m is not None]
    if len(scene.voltages) != len(driven):
        raise InputError(f"give one per motor, in joint order ({', '.join(joints[j] for j in driven)}): "
                         f"got {len(scene.voltages)}", field="voltages")
    voltages: list = [None] * system.dof
    for j, v in zip(driven, scene.voltages):
        voltages[j] = v
    with concerning("voltages"):
        return drive(system, motors, voltages)


def run_drive(d: Drive, preset: Preset, solvers: tuple[str, ...] = ("spice", "ode", "exact")) -> DriveRun:
    """Run *d* in ngspice and (where its voltages are piecewise linear) exactly and by scipy's ODE solver,
    on ngspice's points, and measure each against the exact solution.

    Parameters
    ----------
    d : Drive
        The drive.
    preset : Preset
        The accuracy preset.
    solvers : tuple of str
        Those to run beside ``spice``: ``ode`` and ``exact``.
    """
    text, note, spice = _spice(d, preset)
    traces = {"spice": spice}
    t = spice.time
    try:
        start = time.perf_counter()
        rates, currents = exact_drive(d, t)
        exact = DriveTrace(t, rates, currents, power_balance(d, t, rates, currents), time.perf_counter() - start)
    except InputError:                      # voltages that are not piecewise linear: no exact solution
        exact = None
    if "ode" in solvers:
        a, _, _, first = drive_state(d)
        scale = np.full(len(a), 1.0)
        if exact is not None:               # each state's size, from the exact run
            n = d.system.dof
            v = exact.rates @ np.asarray(d.system.topology.matrix, float).T
            scale[first:first + n] = np.max(np.abs(v), axis=0)
            for i, j in enumerate(d.windings):
                scale[first + n + i] = np.max(np.abs(exact.currents[:, j]))
        traces["ode"] = _ode(d, preset, t, scale)
    if exact is not None and "exact" in solvers:
        traces["exact"] = exact
    reference = "exact"
    if exact is None:       # no exact solution (Coulomb friction, smooth voltages): scipy, tighter, judges
        reference = "reference"
        tight = replace(preset, ode=replace(preset.ode, rtol=max(preset.ode.rtol / 100, 1e-13)))  # scipy's floor
        exact = traces["reference"] = _ode(d, tight, t, np.full(len(drive_state(d)[0]), 1.0))
    errors: dict = {}
    if exact is not None:
        for name, trace in traces.items():
            if name == reference:
                continue
            # the rates together, the currents together: a joint the drive does not move, its peak at
            # rounding, is judged against its group's floor, as every comparison judges it
            rates = output_errors(trace.rates, exact.rates, preset.bound)[1]
            currents = output_errors(trace.currents[:, d.driven], exact.currents[:, d.driven], preset.bound)[1]
            errors[name] = {**{f"r{j + 1}": float(e) for j, e in enumerate(rates)},
                            **{f"i{j + 1}": float(e) for j, e in zip(d.driven, currents)}}
    return DriveRun(d, text, traces, errors, preset.bound, note, reference)
