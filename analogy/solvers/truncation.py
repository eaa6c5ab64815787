"""ngspice's steps and error on a linear circuit at a reltol: its truncation check followed along the exact motion.

ngspice's trapezoidal rule (``cktterr.c``) takes, at each reactive element of charge q (a
capacitor's C·ΔV, an inductor's flux L·I = Δx), the longest step h with

    h²·max(abstol, |q‴|/72) ≤ trtol·max(abstol + reltol·|q′|, reltol·max(|q|, chgtol)/h),

the third divided difference of q being q‴/6 and the rule's coefficient 1/12; over the elements
it takes the shortest, within the step cap. Along the exact motion that gives the step h(t) a
run at *reltol* will take, and the rule's local errors −h³·y‴/12, carried by the circuit's own
dynamics, give its global error per output: the error constant of the circuit at hand (its modes,
its scales and where its charges cross zero), where :mod:`~analogy.solvers.error_constants` has
the worst of a calibration set. Measured on serial2, serial3, serial10 and random10 at the
accurate reltol, the foretold steps were within 1 % of ngspice's at the median and the foretold
error of the worst output within 0.5 % of the measured one.
"""

from __future__ import annotations

import math
import weakref
from typing import Callable, NamedTuple

import numpy as np

from ..circuit.elements import laplacian_split
from ..circuit.scales import system_scales
from ..errors import SimulationError
from .error_constants import RELTOL_LIMITS, spice_reltol

__all__ = ["MODEL_POINTS", "MODEL_LIMIT", "MODEL_SHARE", "CHARGE_FLOORS", "SEARCH_POINTS", "Tolerances", "TruncationModel", "truncation_model"]

#: Samples the motion is taken at, at least; more where the fastest rate asks six a radian.
MODEL_POINTS = 500
#: Samples past which no model is made (the preset's own settings run, judged as ever).
MODEL_LIMIT = 20000
#: The share of the bound the chosen settings' foretold error is held to: the foretold errors were
#: within 3 % of the measured ones (README); the rest is room for what the model leaves out (the
#: backward-Euler first steps after each breakpoint, Newton's residue).
MODEL_SHARE = 0.8
#: chgtol over the circuit's charge scale, tried beside a chgtol under every charge (the check then
#: relative to each charge at hand): a floor holds each step's error to reltol of the scale, as the
#: bound judges each output against its own peak, where the relative check cuts the step at every
#: charge's zero crossing. Foretold at 8e-7: the default 2-DOF in 1,389 points relative, 694 at
#: 1; parallel3 in 17,865, 15,441 at 1e-3 and 18,505 at 1; the xArm7 21,531, 23,818 at 1.
CHARGE_FLOORS = (1e-3, 1.0)
#: Foretold points under which the first settings tried (the charge scale's floor, the most often the
#: fewest) are kept: another search, about a millisecond, costs more than such a run could save.
SEARCH_POINTS = 2000
#: Samples per radian of the fastest rate: the steps' ∫dt/h and the errors' carriage between samples.
_PER_RADIAN = 6.0
#: Samples in a force segment, at least: a pulse's 10 ms edge needs its own q‴.
_SEGMENT_POINTS = 9
#: ngspice's trapezoidal coefficient times the third divided difference's 1/3!: |q‴|/72.
_DIVIDED = 72.0
#: Eigenvector conditioning past which the modal propagation is not trusted.
_CONDITION = 1e8
#: The most states (2n with springs) carried by dense exponentials where the modes are not.
_DENSE_LIMIT = 48

_models: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _samples(system) -> np.ndarray | None:
    """Sample times: uniform in each force segment (at least :data:`_SEGMENT_POINTS`), denser on a fast decay."""
    scales = system_scales(system)
    spacing = min(system.t_stop / MODEL_POINTS, 1.0 / (_PER_RADIAN * scales.omega_max)
                  if scales.omega_max > 0 else math.inf)
    if not (spacing > 0 and system.t_stop / spacing <= MODEL_LIMIT):
        return None
    parts = [np.linspace(t0, t1, max(_SEGMENT_POINTS, int(math.ceil((t1 - t0) / spacing)) + 1))
             for t0, t1 in system.segments()]
    rate = float(np.max(scales.decays, initial=0.0))
    first = 1.0 / (_PER_RADIAN * rate) if rate > 0 else math.inf
    if not first > 0:           # a rate past the float range: no samples follow it
        return None
    if first < spacing:         # a decay faster than the samples: 2 % of t apart from a sixth of its time constant
        parts.append(np.geomspace(first, system.t_stop, int(math.ceil(math.log(system.t_stop / first) / 0.02)) + 1))
    t = np.unique(np.concatenate(parts))
    return t if t.size <= MODEL_LIMIT else None


def _force_derivatives(system, t: np.ndarray) -> np.ndarray:
    """The joint forces and their first two derivatives at *t*, (3, m, n), from each segment's closed form
    (:class:`~analogy.waveforms.Piece`); a sample on a breakpoint takes the later segment's, where
    ngspice restarts its step."""
    out = np.zeros((3, t.size, system.dof))
    for t0, t1 in system.segments():
        inside = (t >= t0) & (t <= t1)
        tau = t[inside] - t0
        for j, waves in enumerate(system.forces):
            for w in waves:
                p = w.piece(t0, t1)
                out[0, inside, j] += p.a + p.b * tau
                out[1, inside, j] += p.b
                for c, rate in zip(p.c, p.s):
                    term = c * np.exp(rate * tau)
                    out[:, inside, j] += np.real([term, rate * term, rate ** 2 * term])
    return out


def _motion_derivatives(system, t: np.ndarray, v: np.ndarray, x: np.ndarray) -> list[np.ndarray]:
    """v′, v″ and v‴ on the samples from the node dynamics M′·v′ = i − B′·v − K′·x and its derivatives
    (exact where x is: differences of sampled v missed a fast decay's v‴ by 60 % at its first samples)."""
    currents = _force_derivatives(system, t) @ system.current_map.T
    inverse = np.linalg.inv(system.mass)
    damping, stiffness = system.damping, system.stiffness
    spring = (lambda y: y @ stiffness.T) if stiffness is not None else (lambda y: 0.0)
    v1 = (currents[0] - v @ damping.T - spring(x)) @ inverse.T
    v2 = (currents[1] - v1 @ damping.T - spring(v)) @ inverse.T
    v3 = (currents[2] - v2 @ damping.T - spring(v1)) @ inverse.T
    return [v1, v2, v3]


def _incidence(matrix: np.ndarray | None, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The reactive elements of a node matrix (grounded, then floating): their incidence rows and |values|."""
    if matrix is None:
        return np.zeros((0, n)), np.zeros(0)
    grounded, floating = laplacian_split(matrix)
    ground = np.flatnonzero(grounded)
    i, j = np.nonzero(np.triu(floating, 1))
    rows = np.zeros((ground.size + i.size, n))
    rows[np.arange(ground.size), ground] = 1.0
    rows[ground.size + np.arange(i.size), i] = 1.0
    rows[ground.size + np.arange(i.size), j] = -1.0
    return rows, np.abs(np.concatenate([grounded[ground], floating[i, j]]))


class Tolerances(NamedTuple):
    """ngspice's settings a truncation model chose, and the time points it foretells for them."""

    reltol: float
    chgtol: float           # [C]
    max_step: float         # [s]
    points: float
    error: float            # the worst output's, over its own peak


class TruncationModel:
    """A linear circuit's reactive elements and local errors along its exact motion.

    Parameters
    ----------
    system : NodeSystem
        The linear system.
    """

    def __init__(self, system):
        from .exact import phi1, phi2, solve_exact      # the exact solution: only where a linear circuit is written

        t = _samples(system)
        if t is None:
            raise SimulationError("the motion turns too fast for the truncation model's samples")
        n = system.dof
        exact = solve_exact(system, t)
        v = exact.voltages
        x = np.concatenate([np.zeros((1, n)), np.cumsum(0.5 * np.diff(t)[:, None] * (v[1:] + v[:-1]), axis=0)])
        with np.errstate(all="ignore"):
            v1, v2, v3 = _motion_derivatives(system, t, v, x)
        if not all(np.all(np.isfinite(a)) for a in (x, v1, v2, v3)):
            raise SimulationError("the motion's derivatives leave the floating-point range")
        springs = system.stiffness is not None
        caps, c_values = _incidence(system.mass, n)
        coils, _ = _incidence(system.stiffness, n)
        # per element, in units of its own value: |q|, |q'| and |q'''| over |C| (a coil's flux L·I is Δx)
        self.weight = np.concatenate([c_values, np.ones(coils.shape[0])])
        self.level = np.abs(np.hstack([v @ caps.T, x @ coils.T]))
        self.level = np.maximum(self.level, np.vstack([self.level[:1], self.level[:-1]]))  # max(|q_now|, |q_prev|)
        self.slope = np.abs(np.hstack([v1 @ caps.T, v @ coils.T]))
        self.third = np.abs(np.hstack([v3 @ caps.T, v2 @ coils.T]))
        self.time, self.dof = t, n
        self._chosen: dict = {}
        self.peak = np.max(np.abs(exact.rates), axis=0)
        # the rule's local error density over h²: −(x‴, v‴)/12, x‴ = v″ (x only where springs feed it back)
        density = -np.hstack([v2, v3]) / 12.0 if springs else -v3 / 12.0
        inverse_mass = np.linalg.inv(system.mass)
        flow = -inverse_mass @ system.damping
        if springs:
            flow = np.block([[np.zeros((n, n)), np.eye(n)], [-inverse_mass @ system.stiffness, flow]])
        lam, vectors = np.linalg.eig(flow)
        h = np.diff(t)
        if np.linalg.cond(vectors) < _CONDITION:
            velocities = vectors[-n:]                          # the modes' node velocities
            self._density = density @ np.linalg.inv(vectors).T  # in modal coordinates
            z = lam[None, :] * h[:, None]
            self._decay = np.exp(z)
            self._before = h[:, None] * (phi1(z) - phi2(z))   # exact for a source linear between samples
            self._after = h[:, None] * phi2(z)
            self._dense = None
        elif flow.shape[0] <= _DENSE_LIMIT:     # a double root (a free mode beside springs): the flow itself
            velocities, self._density = np.eye(flow.shape[0])[-n:], density
            self._dense = _dense_propagators(flow, h)
        else:
            raise SimulationError("the circuit's modes are too near a double root for the truncation model")
        # each mode's (or state's) joint rates, R = T⁻¹·v, once: the errors are read through it at every sample
        self._rates = system.joint_rates(velocities.T.real) + 1j * system.joint_rates(velocities.T.imag) \
            if np.iscomplexobj(velocities) else system.joint_rates(velocities.T)

    def steps(self, reltol: float, abstol: float, chgtol: float, max_step: float, trtol: float = 1.0) -> np.ndarray:
        """The step ngspice's truncation check takes at each sample (see the module's note).

        Parameters
        ----------
        reltol, abstol, chgtol : float
            ngspice's options, as the netlist writes them.
        max_step : float
            The step cap [s].
        trtol : float
            ngspice's trtol.
        """
        inverse = 1.0 / self.weight
        floor = np.maximum(abstol * inverse, self.third * (1.0 / _DIVIDED))
        volt = trtol * (abstol * inverse + reltol * self.slope) / floor
        charge = trtol * reltol * np.maximum(self.level, chgtol * inverse) / floor
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            cubed = np.maximum(volt * np.sqrt(volt), charge)          # h³ of each element: the longer of the two
        return np.minimum(np.cbrt(np.min(cubed, axis=1, initial=math.inf)), max_step)

    def points(self, steps: np.ndarray) -> float:
        """The time points foretold for *steps* (from :meth:`steps`): ∫dt/h.

        Parameters
        ----------
        steps : ndarray
            The step at each sample [s].
        """
        return float(np.sum(np.diff(self.time) * 0.5 * (1.0 / steps[1:] + 1.0 / steps[:-1])))

    def errors(self, steps: np.ndarray) -> np.ndarray:
        """Each joint rate's global error over its own peak for *steps*: the local errors h²·(−y‴/12)
        carried by the circuit's modes from zero.

        Parameters
        ----------
        steps : ndarray
            The step at each sample [s].
        """
        source = self._density * (steps ** 2)[:, None]
        if self._dense is None:
            carried = _carried(self._decay, self._before * source[:-1] + self._after * source[1:])
        else:
            carried = _carried_dense(self._dense, source)
        worst = np.max(np.abs((carried @ self._rates).real), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            share = worst / self.peak
        return np.where(np.isfinite(share), share, 0.0)

    def ideal_points(self, target: float) -> float:
        """The time points of the equidistributed schedule h = c·σ^(−1/3) whose worst error is *target*: σ(t)
        the rule's local error density at the worst-placed output (each joint rate's over its own peak),
        the step a free trapezoidal rule would take with nothing but this circuit's error to hold.

        Parameters
        ----------
        target : float
            The error allowed each output, over its own peak.
        """
        local = np.abs((self._density @ self._rates).real) / self.peak
        sigma = np.max(np.where(np.isfinite(local), local, 0.0), axis=1)
        shape = np.cbrt(np.max(sigma) / np.maximum(sigma, 1e-300 * np.max(sigma)))    # 1 where σ is largest
        scale = 1.0
        for _ in range(6):          # the error goes as c²
            e = float(np.max(self.errors(scale * shape), initial=0.0))
            if not e > 0:
                return 1.0
            scale *= math.sqrt(target / e)
        return self.points(scale * shape)

    def tolerances(self, target: float, abstol: Callable[[float], float], charge: float,
                   max_step: float) -> "Tolerances | None":
        """The settings of the fewest foretold points whose worst error is at most *target*: at the cap
        *max_step*, the reltol for chgtol at each of :data:`CHARGE_FLOORS` of the charge scale or under
        every charge (1e-10·reltol of the scale); or, ngspice's check loose (reltol 1e-3), the cap that
        holds the error alone (an undamped oscillation's error grows with every step, so its best steps
        are about uniform: the UR5 hanging, 277,373 points by the check, 254,000 by the cap). The search
        stops at the first that foretells fewer than :data:`SEARCH_POINTS`; None where none holds *target*
        (reltol at its floor, the steps held by abstol).

        Parameters
        ----------
        target : float
            The error allowed each output, over its own peak.
        abstol : callable
            reltol → abstol as the netlist writes it.
        charge : float
            The circuit's charge scale [C].
        max_step : float
            The step cap [s].
        """
        key = (target, charge, max_step, abstol(1e-12), abstol(1e-6))
        if key in self._chosen:
            return self._chosen[key]
        candidates: list = []
        for floor in (*CHARGE_FLOORS[::-1], None, "cap"):
            if candidates and candidates[0].points < SEARCH_POINTS:
                break
            if floor == "cap":
                loose = RELTOL_LIMITS[1]
                candidates.append(self._settled(loose, abstol(loose), charge,
                                                self._cap(target, (loose, abstol(loose), charge), max_step)))
                continue

            def options(r: float, floor=floor) -> tuple[float, float]:
                return abstol(r), float(f"{(1e-10 * r if floor is None else floor) * charge:.3g}")
            r = self.reltol(target, options, max_step, start=spice_reltol(target / MODEL_SHARE))
            candidates.append(self._settled(r, *options(r), max_step))
        kept = [c for c in candidates if c.error <= target]
        self._chosen[key] = min(kept, key=lambda c: c.points) if kept else None
        return self._chosen[key]

    def _settled(self, reltol: float, abstol: float, chgtol: float, max_step: float) -> "Tolerances":
        """The settings and what they foretell: points and the worst output's error."""
        steps = self.steps(reltol, abstol, chgtol, max_step)
        return Tolerances(reltol, chgtol, max_step, self.points(steps), float(np.max(self.errors(steps), initial=0.0)))

    def _cap(self, target: float, options: tuple[float, float, float], max_step: float) -> float:
        """The longest cap within *max_step* whose foretold worst error, at *options*, is at most *target*."""
        def error(cap: float) -> float:
            return float(np.max(self.errors(self.steps(*options, cap)), initial=0.0))

        cap, best = max_step, 0.0
        for _ in range(8):              # the error goes as cap² where the cap sets the steps
            e = error(cap)
            if e <= target:
                best = max(best, cap)
                if e > target / 1.03 or cap >= max_step:
                    break
            cap = min(max_step, cap * math.sqrt(target / 1.015 / e)) if e > 0 else max_step
        return best if best > 0 else cap

    def reltol(self, target: float, tolerances: Callable[[float], tuple[float, float]], max_step: float,
               start: float) -> float:
        """The loosest reltol whose foretold worst error is at most *target*: a secant in log-log, bracketed
        (the error grows as reltol^(2/3) where the charge term sets the steps).

        Parameters
        ----------
        target : float
            The error allowed each output, over its own peak.
        tolerances : callable
            reltol → (abstol, chgtol) as the netlist writes them.
        max_step : float
            The step cap [s].
        start : float
            The first reltol tried.
        """
        def error(r: float) -> float:
            return float(np.max(self.errors(self.steps(r, *tolerances(r), max_step)), initial=0.0))

        low, high = RELTOL_LIMITS
        aim, slope = target / 1.015, 2.0 / 3.0
        r = min(max(start, low), high)
        e = error(r)
        below, above = (low, 0.0), (high, math.inf)
        for _ in range(30):
            if e <= target:
                below = max(below, (r, e))
            else:
                above = min(above, (r, e))
            if target / 1.03 < e <= target or above[0] / below[0] < 1.001:
                break
            guess = r * math.exp(max(-50.0, min(50.0, math.log(aim / e) / slope))) if e > 0 else high
            if not below[0] < guess < above[0]:
                guess = math.sqrt(below[0] * above[0])
            last, r, e = (r, e), guess, error(guess)
            if e > 0 and last[1] > 0 and r != last[0]:      # the secant's slope, within reason
                slope = min(2.0, max(0.05, math.log(e / last[1]) / math.log(r / last[0])))
        return r if e <= target else below[0]


def _dense_propagators(flow: np.ndarray, steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e^(A·h), h·(φ₁ − φ₂)(A·h) and h·φ₂(A·h) for each step *h* (one exponential per distinct step): the
    exact propagation of y′ = A·y + s with s linear between samples."""
    from scipy.linalg import expm

    d = flow.shape[0]
    distinct, which = np.unique(steps, return_inverse=True)
    parts = np.zeros((3, distinct.size, d, d))
    augmented = np.zeros((3 * d, 3 * d))
    augmented[d:2 * d, 2 * d:] = np.eye(d)
    for k, h in enumerate(distinct):
        augmented[:d, :d], augmented[:d, d:2 * d] = flow * h, np.eye(d) * h
        block = expm(augmented)[:d]
        parts[0, k], parts[1, k], parts[2, k] = block[:, :d], block[:, d:2 * d] - block[:, 2 * d:], block[:, 2 * d:]
    return parts[0][which], parts[1][which], parts[2][which]


def _carried_dense(propagators: tuple, source: np.ndarray) -> np.ndarray:
    """y_k = E_k·y_(k−1) + B_k·s_(k−1) + C_k·s_k from y_0 = 0 (:func:`_dense_propagators`)."""
    decay, before, after = propagators
    out = np.zeros_like(source)
    pushed = np.einsum("kij,kj->ki", before, source[:-1]) + np.einsum("kij,kj->ki", after, source[1:])
    for k in range(1, source.shape[0]):
        out[k] = decay[k - 1] @ out[k - 1] + pushed[k - 1]
    return out


#: Nepers a block of :func:`_carried` spans at most: its products stay within e^±200 of one.
_BLOCK_NEPERS = 200.0


def _carried(decay: np.ndarray, increments: np.ndarray) -> np.ndarray:
    """z_k = a_k·z_(k−1) + u_k from z_0 = 0 for each mode, (m, d) from (m − 1, d) factors and increments: in
    blocks over which every mode's product Π a stays within e^±200, z = P·Σ u/P inside each; a step that
    alone decays (or grows) past e^200 is a block of its own, taken as it stands."""
    m, d = decay.shape[0] + 1, decay.shape[1]
    out = np.zeros((m, d), complex)
    with np.errstate(divide="ignore"):
        nepers = np.max(np.abs(np.log(np.abs(decay))), axis=1)
    steep = ~(nepers <= _BLOCK_NEPERS)           # NaN and inf too
    reach = np.concatenate([[0.0], np.cumsum(np.where(steep, 0.0, nepers))])
    marks = np.searchsorted(reach, np.arange(_BLOCK_NEPERS, reach[-1], _BLOCK_NEPERS), side="right") - 1
    alone = np.flatnonzero(steep)
    starts = np.unique(np.concatenate([[0], marks, alone, alone + 1]))
    starts = starts[starts < m - 1]
    ends = np.append(starts[1:], m - 1)
    z = np.zeros(d, complex)
    for s, e in zip(starts, ends):
        if e - s == 1:
            out[e] = decay[s] * z + increments[s]
        else:
            product = np.cumprod(decay[s:e], axis=0)
            out[s + 1:e + 1] = product * (z + np.cumsum(increments[s:e] / product, axis=0))
        z = out[e]
    return out


def truncation_model(system) -> TruncationModel | None:
    """*system*'s truncation model, kept while the system lives; None where none can be made (the
    motion turns past :data:`MODEL_LIMIT` samples, or its modes are too near a double root).

    Parameters
    ----------
    system : NodeSystem
        The linear system.
    """
    if system in _models:
        return _models[system]
    try:
        model = TruncationModel(system)
    except (SimulationError, np.linalg.LinAlgError):
        model = None
    _models[system] = model
    return model
