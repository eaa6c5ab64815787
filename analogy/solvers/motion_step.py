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

__all__ = ["MOTION_LIMIT", "MOTION_POINTS", "MOTION_RTOL", "CORNER_GAP", "CORNER_STEPS", "CORNER_LIMIT", "PAIR_COST", "MotionErrors",
           "MotionSchedule", "error_coefficients", "motion_step", "motion_schedule"]

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
_schedules: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
#: Candidate schedules carried together.
_BATCH = 16


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


def _local_errors(system, x, v, masses, x3, p3, factor: float = -1.0 / 12.0) -> np.ndarray:
    """Each sample's local error density in (x, v): the rule's −(x‴, p‴)/12 (or *factor* times other
    derivatives) with δv = M'⁻¹(δp − (∂M'/∂x·δx)·v)."""
    n = system.dof
    source = np.zeros((len(x), 2 * n))
    for k in range(len(x)):
        dx, dp = factor * x3[k], factor * p3[k]
        size = np.max(np.abs(dx))
        if size > 0:
            s = 1e-6 * max(1.0, np.max(np.abs(x[k]))) / size
            dp = dp - (system.node_mass(x[k] + s * dx) - masses[k]) / s @ v[k]
        source[k, :n] = dx
        source[k, n:] = np.linalg.solve(masses[k], dp)
    return source


def _propagators(system, t, x, v) -> tuple[np.ndarray, np.ndarray]:
    """The trapezoidal rule's propagators of E' = J·E + s between samples: E_k = A_k·E_(k−1) + B_k·(s_(k−1) + s_k)."""
    drive = system.node_currents(t)
    size = 2 * system.dof
    eye = np.eye(size)
    step, carry = np.zeros((t.size, size, size)), np.zeros((t.size, size, size))
    jac = _jacobian(system, x[0], v[0], drive[0])
    for k in range(1, t.size):
        h = t[k] - t[k - 1]
        nxt = _jacobian(system, x[k], v[k], drive[k])
        inverse = np.linalg.inv(eye - 0.5 * h * nxt)
        step[k], carry[k] = inverse @ (eye + 0.5 * h * jac), 0.5 * h * inverse
        jac = nxt
    return step, carry


def _carried(propagators, source) -> np.ndarray:
    """E' = J·E + source from E(0) = 0 on the samples (J is smooth on them)."""
    step, carry = propagators
    error = np.zeros_like(source)
    for k in range(1, source.shape[0]):
        error[k] = step[k] @ error[k - 1] + carry[k] @ (source[k - 1] + source[k])
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
    relative: np.ndarray      # (m, n + k) |E_r(t)|/max|r|, then each of k contact forces' error over its peak
    curvature: np.ndarray     # (n,) max|r''|/max|r| [1/s²]: linear interpolation between steps errs h²/8 of it


class _Motion(NamedTuple):
    """A motion's samples and what its error coefficients are made of."""

    time: np.ndarray          # (m,) the samples [s]
    peak: np.ndarray          # (n,) each joint rate's peak
    trapezoidal: np.ndarray   # (m, 2n) the rule's local error density over h²: −(x‴, p‴)/12 in (x, v)
    euler: np.ndarray         # (m, 2n) backward Euler's local error over h²: −(x″, p″)/2 in (x, v)
    propagators: tuple        # the linearised dynamics between samples (:func:`_propagators`)
    curvature: np.ndarray     # (n,) max|r''|/max|r|
    outputs: np.ndarray       # (m, k, 2n) each contact force's derivative in (x, v) over its peak (k = 0 without)


def _derivatives(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """dy/dt, d²y/dt² and d³y/dt³ on samples *t* of one smooth segment (zero where it has too few)."""
    if t.size < 5:
        return np.zeros_like(y), np.zeros_like(y), np.zeros_like(y)
    first = np.gradient(y, t, axis=0, edge_order=2)
    second = np.gradient(first, t, axis=0, edge_order=2)
    return first, second, np.gradient(second, t, axis=0, edge_order=2)


def _motion(system, timeout: float | None) -> _Motion:
    """*system*'s motion from the ODE at :data:`MOTION_RTOL` on its samples, and its local error densities."""
    from .ode import solve_ode      # scipy: only where a nonlinear circuit is written

    cached = _cache.get(system)
    if cached is not None:
        return cached
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
    p = np.einsum("kab,kb->ka", masses, v)
    accel, x2, x3, p2, p3 = (np.zeros_like(x) for _ in range(5))
    bounds = np.concatenate([[0.0], edges, [system.t_stop]])
    for t0, t1 in zip(bounds[:-1], bounds[1:]):
        i = np.flatnonzero((t >= t0) & (t <= t1))
        _, x2[i], x3[i] = _derivatives(t[i], x[i])
        _, p2[i], p3[i] = _derivatives(t[i], p[i])
        if i.size >= 3:
            accel[i] = np.gradient(v[i], t[i], axis=0, edge_order=2)
    peak = np.max(np.abs(motion.rates), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        curvature = np.max(np.abs(system.joint_rates(accel)), axis=0) / peak
    result = _Motion(t, peak, _local_errors(system, x, v, masses, x3, p3),
                     _local_errors(system, x, v, masses, x2, p2, factor=-0.5),
                     _propagators(system, t, x, v), curvature, _output_derivatives(system, x, v))
    _cache[system] = result
    return result


def _output_derivatives(system, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Each contact force's derivative in (x, v) at every sample over the force's peak, by central
    differences (steps 1e-6 of each coordinate's size, a hundredth of a contact's smoothing length and
    less): the outputs a circuit judges beside its rates; (m, 0, 2n) without contacts."""
    n = system.dof
    y = np.hstack([x, v])
    forces = system.contact_forces(x, v)
    if not forces:
        return np.zeros((len(y), 0, 2 * n))
    with np.errstate(divide="ignore"):
        scale = 1.0 / np.max(np.abs(np.column_stack(list(forces.values()))), axis=0)
    scale = np.where(np.isfinite(scale), scale, 0.0)
    out = np.zeros((len(y), len(forces), 2 * n))
    for j in range(2 * n):
        d = 1e-6 * max(1.0, float(np.max(np.abs(y[:, j]))))
        up, down = y.copy(), y.copy()
        up[:, j] += d
        down[:, j] -= d
        high = np.column_stack(list(system.contact_forces(up[:, :n], up[:, n:]).values()))
        low = np.column_stack(list(system.contact_forces(down[:, :n], down[:, n:]).values()))
        out[:, :, j] = (high - low) / (2 * d) * scale
    return out


def _relative(system, motion: _Motion, error: np.ndarray) -> np.ndarray:
    """|E_r|/max|r| per sample and joint rate of a carried error *error* in (x, v), and each contact
    force's error over its peak beside them."""
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.abs(system.joint_rates(error[:, system.dof:])) / motion.peak
        relative = np.hstack([relative, np.abs(np.einsum("mkj,mj->mk", motion.outputs, error))])
    return np.where(np.isfinite(relative), relative, 0.0)


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
    motion = _motion(system, timeout)
    return MotionErrors(motion.time, _relative(system, motion, _carried(motion.propagators, motion.trapezoidal)),
                        motion.curvature)


def _interpolation_step(motion: _Motion, allowed: float) -> float:
    """The step whose linear interpolation onto the print points, h²/8·max|r''|, is within *allowed*."""
    curvature = float(np.max(np.where(np.isfinite(motion.curvature), motion.curvature, 0.0), initial=0.0))
    return math.sqrt(8.0 * allowed / curvature) if curvature > 0 else math.inf


def motion_step(system, bound: float, safety: float, timeout: float | None = None) -> float:
    """The uniform step h with every joint rate's (and contact force's) global error h²·|E_r(t)| within
    bound/*safety* of its own peak, and the linear interpolation onto the print points
    (h²/8·max|r''|) too; inf where nothing errs (a motion the rule follows exactly); NaN where the
    motion could not be integrated (the caller keeps its cap then, and the run is judged).

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
        motion = _motion(system, timeout)
    except SimulationError:
        return math.nan          # no motion to size the step from: the caller keeps its cap
    uniform = np.ones((motion.time.size, 1))
    trapezoidal, euler = _carried_shares(motion, uniform)
    return _schedule(system, motion, uniform[:, 0], (trapezoidal[:, :, 0], euler[:, :, 0]), bound / safety).step


#: A clock's corners stand this many times the step they allow apart. After a corner ngspice steps a
#: tenth of its last step or of the gap, whichever is shorter, and doubles each step after (its
#: truncation check off), so its longest step between two corners is about half the gap (0.46 to
#: 0.52 of it, measured on the xArm7's decay).
CORNER_GAP = 1.9
#: Each corner comes with a second one this share of the gap before it. The first step after a
#: corner is backward Euler's, whose local error h²/2·y″ is not the rule's h³/12·y‴; after the near
#: corner it is a tenth of that short gap, and its error a ten-thousandth of what it would be.
CORNER_PAIR = 0.1
#: The Euler steps' h² after the corners a gap g holds, over g²: a tenth of a last step of at most half
#: the gap after a lone corner, (0.05·g)²; after a pair a tenth of the near gap and a tenth of a last
#: step of at most half of it, (0.1² + 0.05²)·(CORNER_PAIR·g)².
_EULER = 0.0125 * CORNER_PAIR ** 2 if CORNER_PAIR else 0.0025
#: The steps ngspice takes from one pair of corners to the next (measured: 10.9 on the hopper, 11.0 on the
#: double pendulum).
CORNER_STEPS = 11
#: What a pair of corners costs beside its steps, in steps of the same run (measured: 47 on the double
#: pendulum's 479 pairs; 100 in process and 120 in plain ngspice on 3,293 of the hopper's, whose steps
#: are cheap and whose evaluations took three times as long), so a clock is taken where it saves more.
PAIR_COST = 60.0
#: The pairs of corners a schedule may place: past them the step does not follow the motion.
CORNER_LIMIT = 10000
#: The levels of the rule's local error density, under its largest, past which the step follows it.
_LEVELS = tuple(10.0 ** (-k / 2) for k in range(1, 17))
#: The shares under which a step is clocked: a pair of corners costs CORNER_STEPS steps for a gap of
#: CORNER_GAP free ones, so a share above about CORNER_GAP/CORNER_STEPS is cheaper left free.
_WORTH = (0.06, 0.13, 0.3, 1.0)


class MotionSchedule(NamedTuple):
    """The steps a nonlinear circuit's motion asks: a cap, and shorter steps where the motion is fast.

    Where the motion's local error density σ(t) passes a level σ*, the step is the cap times
    ρ(t) = (σ*/σ(t))^(1/3), the share that spreads the rule's error evenly over time (h³·σ constant
    per unit of t/h); there a clock's corners stand :data:`CORNER_GAP`·ρ·cap apart, since ngspice's
    own truncation check does not follow these circuits (a fast decay, a contact's switch)."""

    step: float               # the step cap [s]
    corners: np.ndarray       # the clock's corners [s]: ngspice steps at most about ρ·step between them
    points: float             # the time points foretold
    cost: float               # the points and the corners' cost (:data:`PAIR_COST`), in points
    time: np.ndarray          # the motion's samples [s]
    share: np.ndarray         # ρ at each sample

    def finer(self, factor: float) -> "MotionSchedule":
        """This schedule with every step *factor* times shorter (an error estimate's second run).

        Parameters
        ----------
        factor : float
            The divisor of the cap and of every clocked step.
        """
        if factor == 1.0 or not self.corners.size:
            return self._replace(step=self.step / factor, points=self.points * factor, cost=self.cost * factor)
        corners = _clock(self.time, self.share, self.step / factor)
        return self._replace(step=self.step / factor, points=self.points * factor, cost=self.cost * factor,
                             corners=self.corners if corners is None else corners)


def _shares(density: np.ndarray, level: float, worth: float) -> np.ndarray:
    """ρ ≤ 1 at each sample: the step's share of the cap where the local error *density* passes *level* of
    its largest and the share is under *worth* (a clocked step costs more than a free one)."""
    ref = level * float(np.max(density, initial=0.0))
    if not ref > 0:
        return np.ones_like(density)
    with np.errstate(divide="ignore"):
        share = np.cbrt(ref / density)
    return np.where(share < worth, share, 1.0)


def _clock(t: np.ndarray, share: np.ndarray, step: float) -> np.ndarray | None:
    """Corners :data:`CORNER_GAP`·ρ·*step* apart over the intervals where ρ < 1 (the shorter of an
    interval's two ends); None past :data:`CORNER_LIMIT`."""
    inner = np.minimum(share[:-1], share[1:])
    rate = np.where(inner < 1.0, 1.0 / (CORNER_GAP * step * inner), 0.0)
    count = np.concatenate([[0.0], np.cumsum(rate * np.diff(t))])
    if not count[-1] <= CORNER_LIMIT:
        return None
    far = np.interp(np.arange(1.0, math.floor(count[-1]) + 1.0), count, t)
    near = far - CORNER_PAIR * CORNER_GAP * step * np.interp(far, t, share) if CORNER_PAIR else far[:0]
    corners = np.unique(np.concatenate([near, far]))
    return corners[(corners > 0) & (corners < t[-1])]


def _carried_shares(motion: _Motion, shares: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """E_ρ and E_Euler in (x, v), (m, 2n, K), for K columns of shares ρ (m, K): ρ²·σ and the Euler
    steps after the corners, carried at once."""
    clocked = shares < 1.0
    trapezoidal = _carried(motion.propagators, shares[:, None, :] ** 2 * motion.trapezoidal[:, :, None])
    weight = np.where(clocked, _EULER * CORNER_GAP * shares, 0.0)
    return trapezoidal, _carried(motion.propagators, weight[:, None, :] * motion.euler[:, :, None])


def _schedule(system, motion: _Motion, share: np.ndarray, carried: tuple, allowed: float) -> MotionSchedule | None:
    """The cap under which every joint rate's error h²·|E_ρ| + h·|E_Euler| stays within *allowed* of its
    peak (*carried*: E_ρ and E_Euler for this *share*); None past the corners' limit."""
    clocked = share < 1.0
    trapezoidal, euler = (_relative(system, motion, error) for error in carried)
    with np.errstate(divide="ignore", invalid="ignore"):
        steps = 2.0 * allowed / (euler + np.sqrt(euler ** 2 + 4.0 * trapezoidal * allowed))
    step = min(float(np.min(steps, initial=math.inf)), _interpolation_step(motion, allowed))
    if not math.isfinite(step):
        return MotionSchedule(step, np.zeros(0), 1.0, 1.0, motion.time, share)
    if not clocked.any():
        return MotionSchedule(step, np.zeros(0), motion.time[-1] / step, motion.time[-1] / step, motion.time, share)
    corners = _clock(motion.time, share, step)
    if corners is None:
        return None
    inner = np.minimum(share[:-1], share[1:]) < 1.0
    free = float(np.sum(np.diff(motion.time)[~inner]))
    pairs = corners.size / (2 if CORNER_PAIR else 1)
    points = free / step + CORNER_STEPS * pairs
    return MotionSchedule(step, corners, points, points + PAIR_COST * pairs, motion.time, share)


def motion_schedule(system, bound: float, safety: float, timeout: float | None = None) -> MotionSchedule | None:
    """The schedule of least foretold cost that holds every joint rate's and contact force's error
    within bound/*safety* of its own peak: the uniform step (:func:`motion_step`), or a cap with a
    clock where the motion's local error density passes one of :data:`_LEVELS` of its largest; None
    where the motion could not be integrated (the caller keeps its cap then, and the run is judged).

    Parameters
    ----------
    system : NonlinearNodeSystem
        The system.
    bound : float
        The preset's bound on each output's error over its own peak.
    safety : float
        The factor held in hand.
    timeout : float, optional
        Wall-time limit of the motion's integration [s].
    """
    try:
        motion = _motion(system, timeout)
    except SimulationError:
        return None
    known = _schedules.setdefault(system, {})
    if (bound, safety) not in known:
        density = np.max(_relative(system, motion, motion.trapezoidal), axis=1)
        shares = np.unique(np.column_stack([np.ones(motion.time.size)] + [
            _shares(density, level, worth) for level in _LEVELS for worth in _WORTH]), axis=1)
        candidates = []
        for k in range(0, shares.shape[1], _BATCH):        # a few at a time: each holds (m, 2n) errors
            part = shares[:, k:k + _BATCH]
            trapezoidal, euler = _carried_shares(motion, part)
            candidates += [_schedule(system, motion, part[:, j], (trapezoidal[:, :, j], euler[:, :, j]),
                                     bound / safety) for j in range(part.shape[1])]
        known[(bound, safety)] = min((c for c in candidates if c is not None), key=lambda c: c.cost)
    return known[(bound, safety)]
