"""A robot driven by DC motors: each winding's loop around the robot's subcircuit, and the exact solution of the whole."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.linalg import expm

from ..circuit.description import circuit as describe
from ..circuit.elements import ZERO_TOL
from ..circuit.netlist import comment_text
from ..circuit.step_sources import first_step_lines
from ..errors import InputError
from ..model.motors import Motor, reflected
from ..presets import Preset
from ..waveforms import HBridge, Waveform, parse_waveform
from .exact import phi1, phi2
from .run_settings import TransientSettings
from .transient import circuit_settings, subcircuit_netlist

__all__ = ["COULOMB_SPEED", "drive_flow", "Drive", "drive", "drive_settings", "drive_netlist", "drive_state", "exact_drive", "node_matrices",
           "power_balance"]


#: The joint rate [rad/s] over which Coulomb friction's sign is smoothed (tanh(r/COULOMB_SPEED)): well
#: under the rates a drive is about, and wide enough for ngspice's Newton iteration to follow.
COULOMB_SPEED = 1e-3


@dataclass(frozen=True, eq=False)
class Drive:
    """A linear robot circuit with a DC motor on some joints, each driven by a voltage.

    Attributes
    ----------
    system : NodeSystem
        The robot's linear circuit; its own applied forces are left out (the motors drive it),
        gravity's load at the pose stays.
    motors : tuple of Motor or None
        One per joint (None: the joint is undriven).
    voltages : tuple of Waveform or None
        The voltage across each motor's winding terminals.
    """

    system: object
    motors: tuple
    voltages: tuple

    @property
    def driven(self) -> list[int]:
        """The joints (0-based) with a motor."""
        return [j for j, m in enumerate(self.motors) if m is not None]

    @property
    def windings(self) -> list[int]:
        """The driven joints whose winding has an inductance: its current is a state."""
        return [j for j in self.driven if self.motors[j].inductance > 0]

    @property
    def coulomb(self) -> np.ndarray:
        """Each joint's Coulomb friction torque N·c, as the joint feels it [N·m] (0 without a motor)."""
        return np.array([m.gear_ratio * m.coulomb if m is not None else 0.0 for m in self.motors])

    def friction(self, rates: np.ndarray) -> np.ndarray:
        """The Coulomb friction torques N·c·tanh(r/COULOMB_SPEED) at joint *rates* (..., n): the sign of
        the rate, smoothed over :data:`COULOMB_SPEED`.

        Parameters
        ----------
        rates : ndarray, shape (..., n)
            Joint rates.
        """
        return self.coulomb * np.tanh(np.asarray(rates, float) / COULOMB_SPEED)


def drive(system, motors: Sequence[Motor | None], voltages: Sequence[str | float | Waveform | None]) -> Drive:
    """*system* driven by *motors* at *voltages*, checked.

    Parameters
    ----------
    system : NodeSystem
        A linear robot circuit.
    motors : sequence of Motor or None
        One per joint.
    voltages : sequence
        One per joint: a waveform (``"step(12)"``, a number for a constant, ``"pwm(24, 0.6, 20e3)"``),
        None where the joint has no motor.
    """
    n = system.dof
    if len(motors) != n or len(voltages) != n:
        raise InputError(f"a drive needs a motor (or None) and a voltage for each of the {n} joints")
    waves = []
    for j, (m, v) in enumerate(zip(motors, voltages)):
        if m is None:
            if v is not None:
                raise InputError(f"joint {j + 1} has no motor to take the voltage {v!r}")
            waves.append(None)
            continue
        w = v if isinstance(v, Waveform) else parse_waveform(str(v if v is not None else 0.0))
        peak = float(np.max(np.abs(w(np.linspace(0.0, system.t_stop, 2001)))))
        if peak > m.voltage_limit:
            raise InputError(f"joint {j + 1}'s voltage reaches {peak:g} V, past its motor's limit of "
                             f"{m.voltage_limit:g} V")
        waves.append(w)
    # a bridge's two closed switches sit in the winding's loop: the whole's resistance is theirs too
    motors = [replace(m, resistance=m.resistance + 2.0 * w.on_resistance) if isinstance(w, HBridge) else m
              for m, w in zip(motors, waves)]
    unforced = system.driven([0.0] * n)
    return Drive(unforced, tuple(motors), tuple(waves))


def node_matrices(d: Drive, at_rest: bool = False) -> tuple:
    """M'', B'' (the robot's with the rotors reflected and, for windings without inductance, the
    back-EMF's damping n²/R) and K', in node coordinates; and the current map C = T⁻ᵀ. A nonlinear
    robot's M'(x) is taken at its start pose.

    Parameters
    ----------
    d : Drive
        The drive.
    at_rest : bool
        Add Coulomb friction's slope at rest, N·c/COULOMB_SPEED, to B'': the steepest damping its
        smoothed sign gives (the step's settings see it).
    """
    s = d.system
    c = np.asarray(s.current_map, float)
    armature, viscous = reflected(d.motors)
    quick = np.array([m.ratio ** 2 / m.resistance if m is not None and m.inductance == 0 else 0.0
                      for j, m in enumerate(d.motors)])
    own = s.mass if s.kind == "linear" else s.node_mass(np.zeros(s.dof))      # a nonlinear robot's at its start
    mass = own + c @ np.diag(armature) @ c.T
    slope = d.coulomb / COULOMB_SPEED if at_rest else 0.0
    damping = s.damping + c @ np.diag(viscous + quick + slope) @ c.T
    return mass, damping, s.stiffness, c


def drive_state(d: Drive, at_rest: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The drive's linear state space y' = A·y + U·V(t) + load, y = [x (with springs), v, i (windings with L)]:
    A, U, the constant load (gravity's), and the index where v starts in y.

    Parameters
    ----------
    d : Drive
        The drive.
    at_rest : bool
        Linearise Coulomb friction at rest (see :func:`node_matrices`); otherwise it is left out.
    """
    mass, damping, stiffness, c = node_matrices(d, at_rest)
    n, w = d.system.dof, d.windings
    springs = stiffness is not None
    first = n if springs else 0
    size = first + n + len(w)
    a, u, load = np.zeros((size, size)), np.zeros((size, n)), np.zeros(size)
    inv = np.linalg.inv(mass)
    if springs:
        a[:n, first:first + n] = np.eye(n)
        a[first:first + n, :n] = -inv @ stiffness
    a[first:first + n, first:first + n] = -inv @ damping
    load[first:first + n] = inv @ d.system.node_currents(np.zeros(1))[0]
    for k, j in enumerate(w):               # L·i' = V − R·i − n·r_j, and n·i onto joint j
        m, row = d.motors[j], first + n + k
        a[first:first + n, row] = inv @ c[:, j] * m.ratio
        a[row, first:first + n] = -m.ratio * c[:, j] / m.inductance
        a[row, row] = -m.resistance / m.inductance
        u[row, j] = 1.0 / m.inductance
    for j in d.driven:                      # without L: the current (V − n·r)/R, its torque n·V/R
        m = d.motors[j]
        if m.inductance == 0:
            u[first:first + n, j] = inv @ c[:, j] * m.ratio / m.resistance
    return a, u, load, first


class _Stepper:
    """y' = A·y + U·(a + b·σ) + load carried exactly over a step h from σ = 0.

    Through A's modes where they are well conditioned: each mode w = V⁻¹·y moves as
    e^{λh}·w + h·φ₁(λh)·V⁻¹·(U·a + load) + h²·φ₂(λh)·V⁻¹·U·b. Otherwise by one matrix exponential
    of y with the input as states, z = [y; a; p; b; 1] with p = b·σ (p' = b), cached per step length.
    """

    def __init__(self, d: Drive):
        self.a, self.u, self.load, self.first = drive_state(d)
        self.size, self.n = len(self.a), d.system.dof
        lam, vec = np.linalg.eig(self.a) if self.size else (np.zeros(0), np.zeros((0, 0)))
        self.modal = self.size > 0 and np.linalg.cond(vec) < 1e8
        if self.modal:
            self.lam, self.vec, self.inv = lam, vec, np.linalg.inv(vec)
            self.inv_u, self.inv_load = self.inv @ self.u, self.inv @ self.load
        else:
            size, n = self.size, self.n
            z = np.zeros((size + 3 * n + 1, size + 3 * n + 1))
            z[:size, :size], z[:size, size:size + n], z[:size, size + n:size + 2 * n] = self.a, self.u, self.u
            z[size + n:size + 2 * n, size + 2 * n:size + 3 * n] = np.eye(n)
            z[:size, -1] = self.load
            self.z, self.cache = z, {}

    def __call__(self, y: np.ndarray, h: np.ndarray, level: np.ndarray, slope: np.ndarray) -> np.ndarray:
        """The states after each step of *h* (shape (k,)) from *y*, shape (k, size)."""
        h = np.asarray(h, float)
        if self.modal:
            x = self.lam[None, :] * h[:, None]
            w = (np.exp(x) * (self.inv @ y) + h[:, None] * phi1(x) * (self.inv_u @ level + self.inv_load)
                 + (h * h)[:, None] * phi2(x) * (self.inv_u @ slope))
            return (w @ self.vec.T).real
        n, out = self.n, []
        for step in h:
            key = round(float(step), 15)
            if key not in self.cache:
                self.cache[key] = expm(self.z * step)
            out.append((self.cache[key] @ np.concatenate([y, level, np.zeros(n), slope, [1.0]]))[:self.size])
        return np.array(out).reshape(len(h), self.size)


def exact_drive(d: Drive, times) -> tuple[np.ndarray, np.ndarray]:
    """The joint rates and the windings' currents at *times*, exactly, under piecewise-linear voltages
    (steps, ramps, PWL, pulse trains such as a PWM drive's): between the voltages' corners the state and
    the voltages' pieces are carried together exactly (:class:`_Stepper`).

    Parameters
    ----------
    d : Drive
        The drive.
    times : array_like
        Increasing times from 0 to the system's t_stop [s].
    """
    if np.any(d.coulomb):
        raise InputError("the exact drive is linear: Coulomb friction has no exact solution")
    if d.system.kind != "linear":
        raise InputError("the exact drive is linear: the robot's nonlinear motion has no exact solution")
    t = np.asarray(times, float)
    n, stop = d.system.dof, max(float(t[-1]) if t.size else 0.0, d.system.t_stop)
    waves = [(j, w) for j, w in enumerate(d.voltages) if w is not None]
    corners = np.unique(np.concatenate([np.asarray(w.breakpoints(stop), float) for _, w in waves] + [[0.0]]))
    step = _Stepper(d)
    size, first = step.size, step.first
    y = np.zeros(size)
    y[first:first + n] = d.system.initial_voltages
    edges = np.concatenate([[0.0], corners[(corners > 0) & (corners < stop)], [stop]])
    states = np.empty((t.size, size))
    for start, end in zip(edges[:-1], edges[1:]):
        level, slope = np.zeros(n), np.zeros(n)
        for j, w in waves:
            piece = w.piece(start, end)
            if piece.c:
                raise InputError("the exact drive takes piecewise-linear voltages (steps, ramps, pulses); "
                                 f"joint {j + 1}'s is {w.label()}")
            level[j], slope[j] = piece.a, piece.b
        inside = slice(np.searchsorted(t, start, "left"), np.searchsorted(t, end, "right"))
        states[inside] = step(y, t[inside] - start, level, slope)       # each point from the segment's start
        y = step(y, np.array([end - start]), level, slope)[0]
    v = states[:, first:first + n]
    rates = d.system.joint_rates(v)
    currents = np.zeros((len(t), n))
    for i, j in enumerate(d.windings):
        currents[:, j] = states[:, first + n + i]
    for j, w in waves:
        m = d.motors[j]
        if m.inductance == 0:
            currents[:, j] = (w(t) - m.ratio * rates[:, j]) / m.resistance
    return rates, currents


def drive_flow(d: Drive) -> Callable[[float, np.ndarray], np.ndarray]:
    """The drive's equations with the robot's full dynamics, y' = f(t, y) on y = [x, v, i (windings with
    L)]: M''(x)·v' = C·τ − B''·v − K'·x − h(x, v) with M''(x) = M'(x) + C·diag(N²J)·Cᵀ, the joint torques
    τ = n·i (or n·(V − n·r)/R without L) less Coulomb friction, and L·i' = V − R·i − n·r.

    Parameters
    ----------
    d : Drive
        A drive of a nonlinear robot.
    """
    s, n = d.system, d.system.dof
    c = np.asarray(s.current_map, float)
    tinv = np.asarray(s.topology.inverse, float)
    armature, viscous = reflected(d.motors)
    rotors = c @ np.diag(armature) @ c.T
    damping = s.damping + c @ np.diag(viscous) @ c.T
    winding = {j: k for k, j in enumerate(d.windings)}

    def f(t: float, y: np.ndarray) -> np.ndarray:
        x, v, i = y[:n], y[n:2 * n], y[2 * n:]
        r = tinv @ v
        torque = -d.friction(r)
        di = np.zeros(len(i))
        for j in d.driven:
            m, volts = d.motors[j], float(d.voltages[j](t))
            if j in winding:
                torque[j] += m.ratio * i[winding[j]]
                di[winding[j]] = (volts - m.resistance * i[winding[j]] - m.ratio * r[j]) / m.inductance
            else:
                torque[j] += m.ratio * (volts - m.ratio * r[j]) / m.resistance
        net = c @ torque - damping @ v - s.node_load(x, v, t)
        if s.stiffness is not None:
            net = net - s.stiffness @ x
        return np.concatenate([v, np.linalg.solve(s.node_mass(x) + rotors, net), di])
    return f


def drive_settings(d: Drive, preset: Preset) -> TransientSettings:
    """The robot circuit's transient settings at *preset*, its step cap made short enough for the fastest
    lasting rate of the whole (a winding's decay that is over before t_stop sets the first step only).

    Parameters
    ----------
    d : Drive
        The drive.
    preset : Preset
        The accuracy preset.
    """
    s = d.system
    settings = circuit_settings(s, describe(s, ZERO_TOL, False), preset, whole=False)
    rates = np.linalg.eigvals(drive_state(d, at_rest=True)[0])     # friction's steepest slope seen too
    # a mode that decays under the bound before t_stop (a winding's L/R) sets the first step, not the cap
    lasting = rates[rates.real * s.t_stop > math.log(preset.bound)]
    fastest, cap = float(np.max(np.abs(rates), initial=0.0)), float(np.max(np.abs(lasting), initial=0.0))
    if s.kind != "linear":      # a nonlinear circuit's step has no truncation check: the cap must see every rate
        cap = fastest
    if cap > 0 and math.isfinite(preset.spice.phase_step):
        settings = replace(settings, max_step=min(settings.max_step, preset.spice.phase_step / cap))
    if fastest > 0 and math.isfinite(preset.spice.first_phase_step):
        settings = replace(settings, first_step=min(settings.first_step, preset.spice.first_phase_step / fastest))
    return settings


def drive_netlist(d: Drive, preset: Preset, title: str | None = None, settings=None) -> str:
    """The robot's subcircuit with each motor's winding loop on its port, as ``ngspice -b`` runs it.

    Winding j is a loop: its voltage source, R, L, a zero-volt source sensing its current i, and the
    back-EMF n·v(p_j) (an E source on the joint's port); an F source drives n·i into the port. The
    rotor's N²·J is a capacitor and its N²·b a conductance on the port. The port voltages (the
    joint rates) and the winding currents are saved.

    Parameters
    ----------
    d : Drive
        The drive.
    preset : Preset
        The accuracy preset: its ``.options``, with the step cap made short enough for the fastest
        rate of the whole (the windings' L/R, the back-EMF's damping).
    title : str, optional
        First line.
    settings : TransientSettings, optional
        The settings to write (a retry's), instead of :func:`drive_settings`.
    """
    s = d.system
    name = "robot"
    inner = subcircuit_netlist(s, preset, name=name)
    settings = settings or drive_settings(d, preset)
    ports = " ".join(f"p{j + 1}" for j in range(s.dof))
    joints = s.provenance.joints or [f"q{j + 1}" for j in range(s.dof)]
    lines = [f"* {comment_text(title or 'analogy drive: ' + s.provenance.robot + ' driven by its motors')}",
             "* each motor: its voltage, R and L in a loop with the back-EMF n*r (an E source on the joint's",
             "* port) and a zero-volt source sensing its current i; an F source drives the torque n*i into",
             "* the port; the rotor's N^2*J is a capacitor, its N^2*b a conductance on the port",
             inner.rstrip("\n"), f"X1 {ports} {name}"]
    save = [f"v(p{j + 1})" for j in range(s.dof)]
    for j in d.driven:
        m, k = d.motors[j], j + 1
        lines.append("* " + comment_text(f"motor on joint {k} ({joints[j]}): R = {m.resistance:g} ohm, L = {m.inductance:g} H, "
                                         f"n = N·k = {m.gear_ratio:g}·{m.torque_constant:g} = {m.ratio:g}"))
        w, ret, winding = d.voltages[j], "0", m.resistance
        if isinstance(w, HBridge):          # four switches between the supply, the winding's ends and ground
            on, off = w.controls()
            ret, winding = f"e{k}", m.resistance - 2.0 * w.on_resistance
            lines += [f"* joint {k}'s H-bridge: S{k}a and S{k}d put +{w.supply:g} V on d{k} - e{k} while c{k}a is "
                      f"1 V, S{k}b and S{k}c -{w.supply:g} V while c{k}b is (a switch turns where its control "
                      f"ends its edge)", f"Vbus{k} bus{k} 0 DC {w.supply!r}",
                      f"Vc{k}a c{k}a 0 {on}", f"Vc{k}b c{k}b 0 {off}",
                      f"S{k}a bus{k} d{k} c{k}a 0 bridge{k}", f"S{k}b d{k} 0 c{k}b 0 bridge{k}",
                      f"S{k}c bus{k} e{k} c{k}b 0 bridge{k}", f"S{k}d e{k} 0 c{k}a 0 bridge{k}",
                      f".model bridge{k} sw vt=0.5 vh=0.4999 ron={w.on_resistance!r} roff=1e12"]
        else:
            lines.append(f"Vd{k} d{k} 0 {w.spice(1.0, s.t_stop)}")
        lines.append(f"Rw{k} d{k} w{k}a {winding!r}" if m.inductance else f"Rw{k} d{k} w{k}b {winding!r}")
        if m.inductance:
            lines.append(f"Lw{k} w{k}a w{k}b {m.inductance!r}")
        lines += [f"Vs{k} w{k}b w{k}c DC 0", f"Eb{k} w{k}c {ret} p{k} 0 {m.ratio!r}",
                  f"Fm{k} 0 p{k} Vs{k} {m.ratio!r}"]
        if m.armature:
            lines.append(f"Ca{k} p{k} 0 {m.armature!r}")
        if m.reflected_viscous:
            lines.append(f"Rv{k} p{k} 0 {1.0 / m.reflected_viscous!r}")
        if m.coulomb:           # the sign of the rate, smoothed: a behavioural load on the port
            lines += [f"* joint {k}'s Coulomb friction N*c = {m.gear_ratio * m.coulomb:g} N m, its sign smoothed "
                      f"over {COULOMB_SPEED:g} rad/s", f"Bc{k} p{k} 0 I={{{m.gear_ratio * m.coulomb!r}*"
                      f"tanh(v(p{k})/{COULOMB_SPEED!r})}}"]
        save.append(f"i(vs{k})")
    lines += first_step_lines(settings, "p1")      # the winding's fast decay: a short first step
    options = " ".join(f"{k}={v}" if v != "" else k for k, v in settings.options)
    # a port's rate starts where the subcircuit's own .ic puts it; a rotor's capacitor on the port is set
    # too. A port without one has no matrix entry of its own, and ngspice 46 under KLU aborts the run
    # on an .ic there ("KLU mode cannot create a new element")
    rates = s.joint_rates(s.initial_voltages)
    ic = " ".join(f"v(p{j + 1})={float(rates[j])!r}" for j in d.driven if d.motors[j].armature)
    lines += ([f".ic {ic}"] if ic else []) + [f".options {options}",
              f".tran {settings.print_step!r} {settings.stop!r} 0 {settings.max_step!r} uic",
              f".save {' '.join(save)}", ".end"]
    return "\n".join(lines) + "\n"


def power_balance(d: Drive, t: np.ndarray, rates: np.ndarray, currents: np.ndarray) -> np.ndarray:
    """The power the drives put in, less what the windings' R and L, the robot's dampers and rotors, its
    springs and its kinetic energy take, at each of *t* [W]: zero but for the error of the run.

    Σ V·i = Σ R·i² + d/dt Σ ½·L·i² + vᵀ·B''·v + d/dt(½·vᵀ·M''·v + ½·xᵀ·K'·x) − i₀ᵀ·v, with v = T·r, x = ∫v
    and i₀ gravity's constant load; the time derivatives by second-order differences, so NaN at
    the points whose differences reach a corner of a voltage.

    Parameters
    ----------
    d : Drive
        The drive.
    t : ndarray, shape (N,)
        Times of a run.
    rates, currents : ndarray, shape (N, n)
        Its joint rates and winding currents (zero where a joint has no motor).
    """
    mass, damping, stiffness, _ = node_matrices(d)
    s = d.system
    v = rates @ np.asarray(s.topology.matrix, float).T
    x = cumulative_trapezoid(v, t, axis=0, initial=0.0)
    volts = np.column_stack([w(t) if w is not None else np.zeros_like(t) for w in d.voltages])
    r_w = np.array([m.resistance if m else 0.0 for m in d.motors])
    l_w = np.array([m.inductance if m else 0.0 for m in d.motors])
    # a winding without L: its R's loss is in B'' as the back-EMF's damping's share; count it once
    r_loss = np.where(l_w > 0, r_w, 0.0)
    if s.kind == "linear":
        kinetic = 0.5 * np.einsum("ti,ij,tj->t", v, mass, v)
    else:                   # M''(x) along the motion; the velocity terms do no work (M's Christoffel form)
        rotors = mass - s.node_mass(np.zeros(s.dof))
        kinetic = 0.5 * np.einsum("ti,tij,tj->t", v, s.node_masses(x) + rotors, v)
    stored = kinetic + 0.5 * np.sum(l_w * currents ** 2, axis=1)
    if stiffness is not None:
        stored = stored + 0.5 * np.einsum("ti,ij,tj->t", x, stiffness, x)
    quick_in = np.where(l_w == 0, 1.0, 0.0) * np.array([m.ratio / m.resistance if m else 0.0 for m in d.motors])
    # without L the drive's power into the joint is n·V/R·r (its own R's loss n²r²/R is in B'')
    given = np.sum(np.where(l_w > 0, volts * currents, volts * quick_in * rates), axis=1)
    if s.kind == "linear":      # gravity's constant load at the pose
        given = given + v @ s.node_currents(np.zeros(1))[0]
    else:                       # gravity's power along the motion, G(q)·r
        given = given - np.einsum("ti,ti->t", v, np.stack([s.node_gravity(p) for p in x]))
    lost = np.sum(r_loss * currents ** 2, axis=1) + np.einsum("ti,ij,tj->t", v, damping, v) \
        + np.sum(d.friction(rates) * rates, axis=1)
    residual = given - lost - np.gradient(stored, t, edge_order=2)
    # the derivative's differences are only good between the voltages' corners (a PWM's edges, a
    # bridge's jumps): points at a corner, or inside a cluster of corners closer than a typical step
    # (where steps of picoseconds turn the run's tolerance-level noise into large differences), and
    # their neighbours are no check, so they are left out (NaN)
    corners = np.unique([float(c) for w in d.voltages if w is not None for c in w.breakpoints(t[-1])])
    if corners.size and t.size > 2:
        first = np.r_[True, np.diff(corners) > np.median(np.diff(t))]      # where a cluster begins
        ends = np.r_[first[1:], True]
        for lo, hi in zip(np.searchsorted(t, corners[first], "left") - 1, np.searchsorted(t, corners[ends], "right")):
            residual[max(lo, 0):hi + 1] = np.nan
    return residual
