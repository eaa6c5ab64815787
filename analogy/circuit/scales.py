"""Time, velocity and current scales of a node system, from its pencil: what SPICE's steps and the tolerances follow."""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numpy as np

from ..errors import InputError
from ..small_linalg import axis_max, axis_sum, cholesky, eigh, matmul, solve_lower, whiten
from .joint_forces import joint_forces
from .node_stack import NodeStack
from .topology import symmetric_part

__all__ = ["Scales", "system_scales", "stack_scales", "combined_scales", "run_scales", "whitened_damping"]

#: Each system's scales, for as long as the system lives (a copy under other forces has its own).
_KEPT: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class Scales:
    """How fast and how large a node system's motion can be, before it is solved.

    From the undamped modes K'·φ = ω²·M'·φ (M'-normalised) and the forces' peaks F̂:
    a mode driven by f_k = Σ_j |φ_kᵀ·T⁻ᵀ·e_j|·F̂_j moves at most at f_k·t_k, with
    t_k = min(t_stop, 1/ω_k, 1/β_k) and β_k = φ_kᵀB'φ_k its damping rate (times
    e^{σ·t_stop} for a mode that grows at σ), plus its share of the initial velocity; it
    moves at most f_k·min(t_stop², 1/ω_k², t_stop/β_k).
    Node i's scale sums |φ_ik| times these: a bound on an undamped step response, and an
    estimate otherwise (damping that couples the modes, or a sine near resonance, can pass
    it: 0.48 to 6.1 times the exact peak on the built-in scenes). A nonlinear system is
    measured at x = 0.

    Attributes
    ----------
    omega_max : float
        Fastest oscillation [rad/s]: the largest damped frequency ω_k·√(1 − ζ_k²) of an
        underdamped mode (ζ_k = β_k/2ω_k), or of the forces' sines. A decay, however fast,
        is left to ngspice's truncation check: it dies out, while an oscillation keeps
        its phase error. Zero for a system that has none (then t_stop alone sets the steps).
        A nonlinear system's is at least the rate its fastest revolute joint turns at the start.
    velocity : ndarray, shape (n,)
        Per node, the velocity scale [V, i.e. m/s or rad/s].
    position : ndarray, shape (n,)
        Per node, the displacement scale ∫v [V·s].
    current : float
        Largest node current of the forces [A].
    charge : float
        Largest capacitor charge scale: max_i M'_ii times the largest velocity [C].
    decays, shares : ndarray
        Per overdamped or free mode: its decay rate β_k [1/s], and its velocity over the
        peak velocity (see :meth:`fastest`).
    phases : ndarray
        Per mode, the radians it rings through, weighted by what is left of it: the largest
        ω_dk·t·e^(-β_k·t/2) for t ≤ t_stop (at t = 2/β_k, or t_stop if sooner) for an underdamped
        mode, σ_k·t_stop for one that grows at σ_k, zero otherwise (see :meth:`ringing`).
    nodes : int or None
        The node count n (None: the length of *velocity*).
    top_velocity, top_position : float
        max of *velocity* and of *position*, where the builder has them at hand (NaN: derived).
    frequencies : ndarray
        Per mode, aligned with *phases*: the rate its phase turns at, ω_dk for an underdamped mode and
        σ_k for one that grows, zero otherwise [rad/s] (see :meth:`phase_error`).
    row_capacitors : int or None
        The most capacitors meeting at one node, the nonzero entries of a row of M' (None: every
        node's, n): a linear modal circuit's is 1 (see :meth:`rounding_current`).
    """

    omega_max: float
    velocity: np.ndarray
    position: np.ndarray
    current: float
    charge: float
    decays: np.ndarray = field(default_factory=lambda: np.zeros(0))
    shares: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phases: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nodes: int | None = None
    top_velocity: float = math.nan
    top_position: float = math.nan
    frequencies: np.ndarray = field(default_factory=lambda: np.zeros(0))
    row_capacitors: int | None = None

    def __repr__(self) -> str:
        return (f"Scales(omega_max={self.omega_max:.4g} rad/s, velocity={float(np.max(self.velocity)):.3g}, "
                f"current={self.current:.3g}, charge={self.charge:.3g})")

    @property
    def size(self) -> int:
        """The number of nodes (the largest, for combined scales)."""
        return int(np.size(self.velocity)) if self.nodes is None else self.nodes

    @property
    def peak_velocity(self) -> float:
        """The largest node velocity scale."""
        return float(np.max(self.velocity)) if math.isnan(self.top_velocity) else self.top_velocity

    @property
    def peak_position(self) -> float:
        """The largest node displacement scale."""
        return float(np.max(self.position)) if math.isnan(self.top_position) else self.top_position

    def rounding_current(self, step: float) -> float:
        """c·ε·charge/h [A]: the rounding in a capacitor current Δq/h at steps *step*, summed
        over the c capacitors of a row (:attr:`row_capacitors`, n where not known). An abstol
        under a few of these lets rounding read as truncation error, and ngspice then cuts the
        step until it stops with "timestep too small" (see
        :data:`analogy.solvers.transient.ROUNDING_STEPS`).

        Parameters
        ----------
        step : float
            The shortest step the run takes [s].
        """
        count = self.size if self.row_capacitors is None else self.row_capacitors
        return count * float(np.finfo(float).eps) * self.charge / step

    def fastest(self, bound: float) -> float:
        """ω_max, or the fastest decay of a mode larger than 10·*bound* of the peak if that is faster.

        A decay seen at steps much longer than 1/β rings from step to step under the
        trapezoidal rule (its factor (1 − hβ/2)/(1 + hβ/2) tends to −1), and ngspice's
        check misses it on a mass-damper circuit: the default scene over 10^4 s gave
        1.8e-3 at accurate without it. A decay under ten times the bound cannot break it.

        Parameters
        ----------
        bound : float
            The preset's promised error over the peak.
        """
        big = self.decays[self.shares > 10 * bound]
        return max(self.omega_max, float(np.max(big)) if big.size else 0.0)

    def lasting(self, bound: float, horizon: float) -> float:
        """ω_max, or the fastest decay still larger than 10·*bound* of the peak at *horizon* if that is faster:
        the rates a step cap must follow over the whole run.

        A decay that falls under 10·*bound* before *horizon* (s·e^(-β·t) < 10·bound) needs short steps
        only while it lasts, and ngspice's truncation check shortens them there: it checks each step's
        error against the device's own charge, which such a decay dominates while it can break the
        bound. Only its first step goes unchecked (see :meth:`fastest`, which still sets it). A cap
        from it would step the whole run as if it were alive: the xArm7's 68 µs decay, over within
        1 ms, took 9.1 million steps over 10 s.

        Parameters
        ----------
        bound : float
            The preset's promised error over the peak.
        horizon : float
            The end of the run [s].
        """
        alive = self.decays[self._larger(bound, horizon)]
        return max(self.omega_max, float(np.max(alive)) if alive.size else 0.0)

    def _larger(self, bound: float, horizon: float) -> np.ndarray:
        """Which decays are still larger than 10·*bound* of the peak at *horizon*: s·e^(-β·t) > 10·bound."""
        shares = self.shares[:self.decays.size]
        big = shares > 10 * bound
        if math.isinf(horizon):
            return big
        with np.errstate(divide="ignore"):
            return big & (self.decays * horizon < np.log(shares / (10 * bound)))

    def ringing(self, bound: float) -> float:
        """Φ: the most radians a mode larger than *bound* of the peak rings through within t_stop.

        The trapezoidal rule's phase error grows with each radian a mode turns, and counts as much as
        the mode has left (its amplitude falls as e^(-β·t/2)), so the error of a run at a set reltol
        grows with Φ (:mod:`analogy.solvers.error_constants`).

        Parameters
        ----------
        bound : float
            The preset's promised error over the peak: a smaller mode cannot break it.
        """
        alive = self.phases[self.shares[:self.phases.size] > bound] if self.phases.size else self.phases
        return float(np.max(alive)) if alive.size else 0.0

    def phase_error(self, step: float, bound: float) -> float:
        """The trapezoidal rule's phase error at steps *step*, summed over the modes larger than *bound*
        of the peak: each turns Φ_k radians and errs (ω_k·h)²/12 of its amplitude per radian.

        At steps h the rule turns an oscillation at 2·atan(ω·h/2)/h instead of ω, and a growth at σ by
        (1 + σh/2)/(1 − σh/2) = e^(σh·(1 + (σh)²/12 + …)): both are (ω·h)²/12 of each radian, held to
        the amplitude, whatever reltol. The sum bounds an output to which every mode brings up to its
        own peak.

        Parameters
        ----------
        step : float
            The step h [s].
        bound : float
            The preset's bound: a smaller mode cannot break it.
        """
        phases, turns = self._turning(bound)
        return float(np.sum(phases * (turns * step) ** 2)) / 12

    def phase_limit(self, error: float, bound: float) -> float:
        """The step at which :meth:`phase_error` is *error* (inf where no mode larger than *bound* turns).

        Parameters
        ----------
        error : float
            The phase error allowed, over each mode's amplitude.
        bound : float
            The preset's bound.
        """
        phases, turns = self._turning(bound)
        with np.errstate(over="ignore"):        # a rate past the float range: no step holds it (0)
            weight = float(np.sum(phases * turns ** 2))
        return math.sqrt(12 * error / weight) if weight > 0 else math.inf

    def _turning(self, bound: float) -> tuple[np.ndarray, np.ndarray]:
        """Φ_k and ω_k of the modes larger than *bound* of the peak (none where the rates are unknown)."""
        n = min(self.phases.size, self.frequencies.size)
        if not n:
            return np.zeros(0), np.zeros(0)
        alive = self.shares[:n] > bound
        return self.phases[:n][alive], self.frequencies[:n][alive]

    def decay_limit(self, product: float, bound: float, horizon: float = math.inf) -> float:
        """The step at which the fastest decay larger than 10·*bound* of the peak reaches β·h = *product*
        (inf without one).

        Parameters
        ----------
        product : float
            β·h.
        bound : float
            The preset's bound.
        horizon : float
            Only decays still that large at this time count (see :meth:`lasting`); inf: every one.
        """
        big = self.decays[self._larger(bound, horizon)]
        rate = float(np.max(big)) if big.size else 0.0
        return product / rate if rate > 0 else math.inf

    def step_limit(self, phase: float, bound: float = math.inf) -> float:
        """The step at which the fastest rate advances by *phase* radians (inf without one).

        Parameters
        ----------
        phase : float
            ω_max·h.
        bound : float
            The preset's bound: decays that can matter count too (:meth:`fastest`).
        """
        rate = self.fastest(bound)
        return phase / rate if rate > 0 else math.inf


def _force_peaks(system) -> tuple[np.ndarray, float]:
    """Per joint max |F(t)| (sampled and at every breakpoint), and the largest sine frequency."""
    key = (system.forces, float(system.t_stop))     # systems of one family share their forces
    hit = _PEAKS.get(key)
    if hit is None:
        t = np.union1d(system.time_points(), np.concatenate([[0.0], system.breakpoints()]))
        peaks = np.max(np.abs(joint_forces(system.forces, t)), axis=0) if t.size else np.zeros(system.dof)
        freq = max((float(getattr(w, "frequency", 0.0)) for ws in system.forces for w in ws), default=0.0)
        hit = (peaks, 2 * math.pi * freq)
        with _PEAKS_LOCK:           # a batch in this process runs groups on two threads
            if len(_PEAKS) >= 64:
                _PEAKS.pop(next(iter(_PEAKS)))
            _PEAKS[key] = hit
    return hit


_PEAKS: dict = {}
_PEAKS_LOCK = threading.Lock()


def system_scales(system) -> Scales:
    """The :class:`Scales` of a linear or nonlinear node system.

    Systems are not changed once built, so the scales are kept for the system (here, for as
    long as it lives): the work guard, the SPICE settings and the ODE tolerances read them
    from one computation.

    Parameters
    ----------
    system : NodeDynamics
        The system; a nonlinear one is evaluated at x = 0.
    """
    cached = _kept(system)
    if cached is not None:
        return cached
    m = np.asarray(system.node_mass(np.zeros(system.dof)), dtype=float)[None]
    k = None if system.stiffness is None else np.asarray(system.stiffness, dtype=float)[None]
    out = _stack_scales(system, m, np.asarray(system.damping, dtype=float)[None], k,
                        np.asarray(system.initial_voltages, dtype=float)[None])[0]
    if system.kind != "linear":
        # the configuration turns at the joint rates, and M'(x) with it: at least the start's
        units = getattr(getattr(system, "provenance", None), "units", None) or ("rad",) * system.dof
        turning = [abs(float(r)) for r, u in zip(system.initial_rates, units) if u == "rad"]
        if max(turning, default=0.0) > out.omega_max:
            out = replace(out, omega_max=max(turning))
    _keep(system, out)
    return out


def _kept(system) -> Scales | None:
    try:
        return _KEPT.get(system)
    except TypeError:               # a system that cannot be weakly referred to: computed each time
        return None


def _keep(system, scales: Scales) -> None:
    try:
        _KEPT[system] = scales
    except TypeError:
        pass


def stack_scales(systems: Sequence) -> list[Scales]:
    """:func:`system_scales` of linear systems, vectorised over each family (same size, forces, topology).

    Parameters
    ----------
    systems : sequence of NodeSystem
        Linear systems.
    """
    out: list = [_kept(s) for s in systems]
    todo = [i for i, s in enumerate(systems) if out[i] is None]
    if not todo:
        return out
    by_size: dict = {}
    for i in todo:
        by_size.setdefault(systems[i].dof, []).append(i)
    for idx in by_size.values():
        stack = NodeStack.of(systems) if len(idx) == len(systems) else NodeStack([systems[i] for i in idx])
        for rows, part in stack.partition():
            for i, sc in zip((idx[r] for r in rows), _stack_scales(part[0], part.mass, part.damping, part.stiffness,
                                                                  part.initial_voltages)):
                out[i] = sc
                _keep(systems[i], sc)
    return out


def _stack_scales(first, m, b, k, v0) -> list[Scales]:
    """Scales of a stack sharing *first*'s forces, topology and t_stop (arrays with a leading axis)."""
    fastest, velocity, position, current, charge, decays, share, phases, tops, reaches, turns = \
        _scale_arrays(first, m, b, k, v0)
    row = _row_capacitors(first, m)
    return [Scales(float(fastest[j]), velocity[j], position[j], current, float(charge[j]), decays[j], share[j],
                   phases[j], None, tops[j], reaches[j], turns[j], row) for j in range(m.shape[0])]


def _row_capacitors(first, m: np.ndarray) -> int | None:
    """The most nonzero entries in a row of a linear stack's M' (None for a nonlinear system: M'(x) at
    x = 0 may have zeros that other poses fill)."""
    if first.kind != "linear" or not m.size:
        return None
    return int(np.max(axis_sum((m != 0).view(np.int8), -1)))      # counts (numpy widens a long axis's sum)


def _scale_arrays(first, m, b, k, v0, whitened: Callable[[], tuple] | None = None) -> tuple:
    """The fields of :func:`_stack_scales`, one row per system: arrays, and *current* (shared); *whitened*
    gives :func:`whitened_damping` of the same rows where they are kept."""
    # Estimates only: a scale past 1e308 is inf, which the solvers' own checks then meet.
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            return _estimated_scales(first, m, b, k, v0, whitened)
    except np.linalg.LinAlgError:       # K' against M' past 1e308, or eigh cannot converge
        raise InputError("the system's rates (K' and B' against M') leave the floating-point range: "
                         "rescale the masses, dampers or springs") from None


def _starting_load(system) -> np.ndarray | None:
    """|h(0, v0)| of a nonlinear system, its gravity, velocity and contact terms at the start as node
    currents; None for a linear one or where they are zero."""
    if getattr(system, "kind", "linear") == "linear":
        return None
    with np.errstate(all="ignore"):
        load = np.abs(np.asarray(system.node_load(np.zeros(system.dof), system.initial_voltages, 0.0), dtype=float))
    return load if np.all(np.isfinite(load)) and np.any(load > 0) else None


def whitened_damping(stack: NodeStack) -> tuple[np.ndarray, np.ndarray]:
    """L and L⁻¹·B'·L⁻ᵀ of each row, with M' = L·Lᵀ its Cholesky factor, made once for the stack
    (:meth:`~analogy.circuit.node_stack.NodeStack.rowwise`): its scales and its modal solution both read them.

    Parameters
    ----------
    stack : NodeStack
        Systems of one size.
    """
    return stack.rowwise("whitened damping", lambda s: _whitened(s.mass, s.damping))


def _whitened(m: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`whitened_damping` of stacked M' and B'."""
    chol = cholesky(m)
    return chol, whiten(chol, b)


def _estimated_scales(first, m, b, k, v0, whitened: Callable[[], tuple] | None = None) -> tuple:
    count, n = m.shape[0], m.shape[1]
    chol, wb = _whitened(m, b) if whitened is None else whitened()
    if k is None:       # no springs: eigh of zeros, which is (0, I) exactly
        mu, psi = np.zeros((count, n)), np.broadcast_to(np.eye(n), (count, n, n))
    else:
        whitened_k = whiten(chol, k)
        if not np.all(np.isfinite(whitened_k)):
            raise np.linalg.LinAlgError("K' against M' leaves the floating-point range")
        mu, psi = eigh(symmetric_part(whitened_k))
    phi = solve_lower(chol, psi, transposed=True)                       # M'-orthonormal mode shapes
    beta = axis_sum(psi * matmul(wb, psi), 1)                      # modal damping rates
    omega = np.sqrt(np.abs(mu))
    peaks, sine = _force_peaks(first)
    phi_t = np.swapaxes(phi, 1, 2)
    drive = matmul(np.abs(matmul(phi_t, first.current_map)), peaks[:, None])[..., 0]
    load = _starting_load(first)
    if load is not None:            # gravity and contacts drive a nonlinear motion as its forces do
        drive = drive + matmul(np.abs(phi_t), load[..., None])[..., 0]
    start = np.abs(matmul(phi_t, matmul(m, v0[..., None]))[..., 0])
    t_stop = float(first.t_stop)
    with np.errstate(divide="ignore"):
        span = np.minimum.reduce([np.full(mu.shape, t_stop), np.where(mu > 0, 1 / omega, np.inf),
                                  np.where(beta > 0, 1 / np.abs(beta), np.inf)])
        # displacement: f·t² while free, f/ω² against a spring, f·t/β drifting through a damper
        reach = np.minimum.reduce([np.full(mu.shape, t_stop ** 2), np.where(mu > 0, 1 / np.abs(mu), np.inf),
                                   np.where(beta > 0, t_stop / np.abs(beta), np.inf)])
    growth = np.exp(np.minimum(np.where(mu < 0, omega, 0.0) * t_stop, 700.0))
    size = np.abs(phi)
    velocity = matmul(size, ((drive * span + start) * growth)[..., None])[..., 0]
    position = matmul(size, ((drive * reach + start * span) * growth)[..., None])[..., 0]
    with np.errstate(invalid="ignore", over="ignore"):      # (β/2)² past 1e308 only means overdamped
        damped = np.where(mu > 0, np.sqrt(np.maximum(mu - (beta / 2) ** 2, 0.0)), 0.0)
    current = float(np.max(np.abs(first.current_map) @ peaks)) if peaks.size else 0.0
    if load is not None:
        current = max(current, float(np.max(load, initial=0.0)))
    top = axis_max(velocity, 1) if n else np.zeros(count)
    still = ~(np.isfinite(top) & (top > 0))               # nothing moves: any unit scale serves
    velocity[still], position[still] = 1.0, t_stop
    velocity = np.maximum(velocity, 1e-12 * axis_max(velocity, 1)[:, None])
    position = np.maximum(position, 1e-12 * axis_max(position, 1)[:, None])
    fastest = np.maximum(axis_max(damped, 1) if n else np.zeros(count), sine)
    top = axis_max(velocity, 1) if n else np.ones(count)
    charge = axis_max(np.diagonal(m, axis1=1, axis2=2), 1) * top
    current = current if current > 0 else 1.0
    # overdamped or free modes decay at up to β_k; their share of the peak velocity
    share = axis_max(size, 1) * (drive * span + start) * growth / top[:, None]
    decays = np.where((beta > 0) & (beta >= 2 * np.sqrt(np.maximum(mu, 0.0))), beta, 0.0)
    # a mode's phase error grows as t while its amplitude falls as e^(-β·t/2): their product peaks at 2/β
    lives = np.minimum(t_stop, np.where(beta > 0, 2 / np.maximum(np.abs(beta), 1e-300), np.inf))
    phases = damped * lives * np.exp(-np.abs(beta) * lives / 2)
    # a mode that grows at σ (an unstable equilibrium) carries its relative error as a phase does: σ·t_stop
    phases = np.where(mu < 0, omega * t_stop, phases)
    turns = np.where(mu < 0, omega, damped)
    tops = top.tolist() if n else [1.0] * count
    reaches = axis_max(position, 1).tolist() if n else [t_stop] * count
    return fastest, velocity, position, current, charge, decays, share, phases, tops, reaches, turns


def combined_scales(scales: Sequence[Scales]) -> Scales:
    """One set of scales for circuits that run together: the fastest rate, the largest sizes.

    :func:`_combined_rows` makes the same from a stack's arrays: a change here is made there too.

    Parameters
    ----------
    scales : sequence of Scales
        The circuits' scales (velocity vectors may differ in length).
    """
    top, reach = max(s.peak_velocity for s in scales), max(s.peak_position for s in scales)
    return Scales(max(s.omega_max for s in scales), np.array([top]), np.array([reach]),
                  max(s.current for s in scales), max(s.charge for s in scales),
                  np.concatenate([s.decays for s in scales]), np.concatenate([s.shares for s in scales]),
                  np.concatenate([s.phases for s in scales]), max(s.size for s in scales), top, reach,
                  np.concatenate([s.frequencies for s in scales]),
                  None if any(s.row_capacitors is None for s in scales) else max(s.row_capacitors for s in scales))


def run_scales(systems: Sequence) -> Scales:
    """The scales of one circuit running *systems* together: :func:`combined_scales` of their
    :func:`stack_scales`, kept on a :class:`NodeStack` as each system keeps its own.

    Parameters
    ----------
    systems : sequence of NodeSystem
        Linear systems.
    """
    stack = systems if isinstance(systems, NodeStack) else None
    kept = None if stack is None else stack._scales
    if kept is None:
        # a row not yet made has no scales kept of its own
        made = None if stack is None else stack.first_made
        parts = None if stack is None or made is not None and _kept(made) is not None else stack.partition()
        if parts is not None and len(parts) == 1:       # straight from the stack's arrays: no Scales per row
            def rows_of(s, first):
                return _scale_arrays(first, s.mass, s.damping, s.stiffness, s.initial_voltages,
                                     lambda: whitened_damping(s))
            # a linear row's scales are its own and its inputs'; a nonlinear one's read the first row's start
            first = stack.inputs_row
            rows = stack.rowwise("scales", lambda s: rows_of(s, s.inputs_row)) if first.kind == "linear" else \
                rows_of(stack, stack[0])
            kept = _combined_rows(*rows, _row_capacitors(first, stack.mass))
        else:
            kept = combined_scales(stack_scales(systems))
        if stack is not None:
            stack._scales = kept
    return kept


def _combined_rows(fastest, velocity, position, current, charge, decays, share, phases, tops, reaches,
                   turns, row_capacitors: int | None = None) -> Scales:
    """:func:`combined_scales` of the rows of :func:`_scale_arrays`, taken in the same order."""
    top, reach = max(tops), max(reaches)
    return Scales(max(fastest.tolist()), np.array([top]), np.array([reach]), current, max(charge.tolist()),
                  decays.reshape(-1), share.reshape(-1), phases.reshape(-1), velocity.shape[1], top, reach,
                  turns.reshape(-1), row_capacitors)
