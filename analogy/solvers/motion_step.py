"""The step a nonlinear circuit's motion asks: the trapezoidal rule's global error h²·E(t) within each output's bound.

ngspice integrates the node charges p = M'(x)·v and the positions x by the trapezoidal rule,
which errs −h³/12 times their third derivatives a step. Carried along the motion by the
linearised node dynamics, those local errors sum to the global error h²·E(t) (the
asymptotic expansion of a one-step method of order 2), where

    E' = J(t)·E − (x‴, v̂‴)/12,     E(0) = 0,

J is the Jacobian of y = (x, v) and v̂''' the change of v that p''' and x''' make through
v = M'(x)⁻¹·p. E takes in what one joint's error does to another's and what the motion
does to its errors (a swing under gravity, a chaotic motion). The motion comes from the ODE
at :data:`MOTION_RTOL`, its third derivatives from its samples by differences within each
force segment (ngspice restarts its step at every breakpoint).

This holds where ngspice's Newton solve and its pivots are not the larger error: the
nonlinear circuits therefore run with pivrel = 0.9 and reltol at the bound
(:data:`~analogy.presets.PRESETS`); under ngspice's defaults the error stopped falling with
the step and a tight reltol collapsed the step (README, "Nonlinear dynamics inside SPICE").
"""

from __future__ import annotations

import math
import weakref
from typing import NamedTuple

import numpy as np

from ..circuit.scales import system_scales
from ..errors import SimulationError

__all__ = ["MOTION_LIMIT", "MOTION_POINTS", "MOTION_RTOL", "MotionErrors", "error_coefficients", "motion_step"]

#: Points the motion is sampled at, at least; more where its fastest rate asks.
MOTION_POINTS = 1000
#: The ODE's rtol for the motion: three differences at about a third of a radian raise its error
#: 27 times, to 3e-4 of r‴.
MOTION_RTOL = 1e-5
#: Samples the motion may take, at most: past it (over about 2,000 radians of the fastest rate) the
#: estimate is not made, and the preset's cap t_stop/behavioural_max_steps runs, judged as ever. Each
#: sample costs an ODE stretch and a Jacobian: about 0.3 ms for a one-joint symbolic model.
MOTION_LIMIT = 6000
#: Samples per radian of the fastest rate (about 19 a period: the error coefficients agree with 31 a
#: period to 1 % on serial2 and the Panda).
_PER_RADIAN = 3.0

_cache: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _third(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """d³y/dt³ on samples *t* of one smooth segment (zero where it has too few)."""
    if t.size < 5:
        return np.zeros_like(y)
    for _ in range(3):
        y = np.gradient(y, t, axis=0, edge_order=2)
    return y


def _decay_samples(scales, t_stop: float) -> np.ndarray:
    """Samples that follow the fastest decay from the start: spaced 2 % of t apart from a third of its
    time constant on (a decay of rate β needs about 13/β to fall from the peak to 1e-6), where the
    uniform samples are too sparse for it (Talos' arm: a 2 ms decay, 4 ms samples, an error 8 times
    the estimate)."""
    rate = float(np.max(scales.decays, initial=0.0))
    first = 1.0 / (_PER_RADIAN * rate) if rate > 0 else math.inf
    if not first < t_stop / MOTION_POINTS:
        return np.zeros(0)
    return np.geomspace(first, t_stop, int(math.ceil(math.log(t_stop / first) / math.log(1.02))) + 1)


def _samples(system) -> tuple[np.ndarray, np.ndarray]:
    """The motion's sample times and its force breakpoints inside (0, t_stop)."""
    scales = system_scales(system)
    points = max(MOTION_POINTS, _PER_RADIAN * scales.omega_max * system.t_stop)
    if not points <= MOTION_LIMIT:
        raise SimulationError(f"the motion turns through {scales.omega_max * system.t_stop:.3g} rad, past what "
                              "its error coefficients are sampled for")
    edges = np.array([t1 for _, t1 in system.segments()][:-1], dtype=float)
    uniform = np.linspace(0.0, system.t_stop, int(points))
    return np.unique(np.concatenate([uniform, edges, _decay_samples(scales, system.t_stop)])), edges


#: A contact's switch is sampled wherever its penetration comes within this many smoothing lengths
#: of zero (its force is on to 1e-9 of the linear law's past 2·ln(1e9) ≈ 41 of them, off likewise).
SWITCH_BAND = 45.0
#: Samples per smoothing length crossed there: the switch lasts δ/|ṗ|, far shorter than the motion's
#: other time scales, and the third differences must follow it.
_PER_SMOOTHING = 3.0


def _switch_samples(system, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Extra sample times that follow each contact's switch (:mod:`analogy.model.contact`): between two
    samples where the penetration p is within :data:`SWITCH_BAND`·δ of zero or crosses it, spaced
    δ/(:data:`_PER_SMOOTHING`·|Δp/Δt|). Empty without contacts."""
    contacts = system.functions.contacts
    if contacts is None:
        return np.zeros(0)
    depth = contacts.depths((system.q0 + x @ system.topology.inverse.T).T)
    extra = []
    for p, delta in zip(depth, contacts.smoothing):
        near = np.abs(p) <= SWITCH_BAND * delta
        span = (near[:-1] | near[1:]) | (np.sign(p[:-1]) != np.sign(p[1:]))
        for k in np.flatnonzero(span):
            count = int(min(np.ceil(abs(p[k + 1] - p[k]) * _PER_SMOOTHING / delta), MOTION_LIMIT))
            if count > 1:
                extra.append(np.linspace(t[k], t[k + 1], count + 1)[1:-1])
    return np.concatenate(extra) if extra else np.zeros(0)


def _local_errors(system, x, v, masses, x3, p3) -> np.ndarray:
    """Each sample's local error density in (x, v): the rule's −(x‴, p‴)/12 with δv = M'⁻¹(δp − (∂M'/∂x·δx)·v)."""
    n = system.dof
    source = np.zeros((len(x), 2 * n))
    for k in range(len(x)):
        dx, dp = -x3[k] / 12.0, -p3[k] / 12.0
        size = np.max(np.abs(dx))
        if size > 0:
            s = 1e-6 * max(1.0, np.max(np.abs(x[k]))) / size
            dp = dp - (system.node_mass(x[k] + s * dx) - masses[k]) / s @ v[k]
        source[k, :n] = dx
        source[k, n:] = np.linalg.solve(masses[k], dp)
    return source


def _carried(system, t, x, v, source) -> np.ndarray:
    """E' = J·E + source from E(0) = 0, by the trapezoidal rule on the samples (J is smooth on them)."""
    drive = system.node_currents(t)
    error = np.zeros_like(source)
    eye = np.eye(source.shape[1])
    jac = _jacobian(system, x[0], v[0], drive[0])
    for k in range(1, t.size):
        h = t[k] - t[k - 1]
        nxt = _jacobian(system, x[k], v[k], drive[k])
        rhs = (eye + 0.5 * h * jac) @ error[k - 1] + 0.5 * h * (source[k - 1] + source[k])
        error[k] = np.linalg.solve(eye - 0.5 * h * nxt, rhs)
        jac = nxt
    return error


def _jacobian(system, x, v, drive) -> np.ndarray:
    """∂(x', v')/∂(x, v): the model's own where it has derivatives, else central differences of the flow."""
    n = system.dof
    jac = system.jacobian(x, v, drive)
    if jac is not None:
        return jac[:2 * n, :2 * n]
    out = np.zeros((2 * n, 2 * n))
    out[:n, n:] = np.eye(n)
    y = np.concatenate([x, v])
    for k in range(2 * n):
        d = 1e-6 * max(1.0, abs(y[k]))
        up, down = y.copy(), y.copy()
        up[k] += d
        down[k] -= d
        out[n:, k] = (system.flow(up[:n], up[n:], drive)[0] - system.flow(down[:n], down[n:], drive)[0]) / (2 * d)
    return out


class MotionErrors(NamedTuple):
    """The trapezoidal rule's global error over h² along a motion, per joint rate and over its own peak."""

    time: np.ndarray          # (m,) the samples [s]
    relative: np.ndarray      # (m, n) |E_r(t)|/max|r|
    curvature: np.ndarray     # (n,) max|r''|/max|r| [1/s²]: linear interpolation between steps errs h²/8 of it


def error_coefficients(system, timeout: float | None = None) -> MotionErrors:
    """The trapezoidal rule's global error over h² in each joint rate along *system*'s motion, over the
    rate's peak, and the rates' curvature.

    Parameters
    ----------
    system : NonlinearNodeSystem
        The system; its motion is integrated by the ODE at :data:`MOTION_RTOL`.
    timeout : float, optional
        Wall-time limit of that integration [s].
    """
    from .ode import solve_ode      # scipy: only where a nonlinear circuit is written

    cached = _cache.get(system)
    if cached is not None:
        return cached
    n = system.dof
    t, edges = _samples(system)
    motion = solve_ode(system, t, "DOP853", rtol=MOTION_RTOL, positions=True, timeout=timeout)
    switching = _switch_samples(system, t, motion.positions)
    if switching.size:          # again, on samples that follow each contact's switch
        if t.size + switching.size > 4 * MOTION_LIMIT:
            raise SimulationError("the contacts switch over more samples than their error coefficients are taken on")
        t = np.unique(np.concatenate([t, switching]))
        motion = solve_ode(system, t, "DOP853", rtol=MOTION_RTOL, positions=True, timeout=timeout)
    x, v = motion.positions, motion.voltages
    masses = system.node_masses(x)
    accel, x3, p3 = np.zeros_like(x), np.zeros_like(x), np.zeros_like(v)
    bounds = np.concatenate([[0.0], edges, [system.t_stop]])
    for t0, t1 in zip(bounds[:-1], bounds[1:]):
        i = np.flatnonzero((t >= t0) & (t <= t1))
        x3[i], p3[i] = _third(t[i], x[i]), _third(t[i], np.einsum("kab,kb->ka", masses[i], v[i]))
        if i.size >= 3:
            accel[i] = np.gradient(v[i], t[i], axis=0, edge_order=2)
    error = _carried(system, t, x, v, _local_errors(system, x, v, masses, x3, p3))
    peak = np.max(np.abs(motion.rates), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        result = MotionErrors(t, np.abs(system.joint_rates(error[:, n:])) / peak,
                              np.max(np.abs(system.joint_rates(accel)), axis=0) / peak)
    _cache[system] = result
    return result


def motion_step(system, bound: float, safety: float, timeout: float | None = None) -> float:
    """The step h with every joint rate's global error h²·|E_r(t)| within bound/*safety* of its own peak,
    and the linear interpolation onto the print points (h²/8·max|r''|) too; inf where nothing
    errs (a motion the rule follows exactly); NaN where the motion could not be integrated (the
    caller keeps its cap then, and the run is judged).

    Parameters
    ----------
    system : NonlinearNodeSystem
        The system.
    bound : float
        The preset's bound on each output's error over its own peak.
    safety : float
        The factor held in hand (the steps ngspice shortens at the start and at breakpoints).
    timeout : float, optional
        Wall-time limit of the motion's integration [s].
    """
    try:
        errors = error_coefficients(system, timeout)
    except SimulationError:
        return math.nan          # no motion to size the step from: the caller keeps its cap
    relative = np.where(np.isfinite(errors.relative), errors.relative, 0.0)
    worst = float(np.max(relative)) if relative.size else 0.0
    curvature = float(np.max(np.where(np.isfinite(errors.curvature), errors.curvature, 0.0), initial=0.0))
    with np.errstate(divide="ignore"):
        step = min(math.sqrt(bound / safety / worst) if worst > 0 else math.inf,
                   math.sqrt(8.0 * bound / safety / curvature) if curvature > 0 else math.inf)
    return step
