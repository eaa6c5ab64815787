"""Exact response of a node system by eigen-decomposition of its matrix pencil."""

from __future__ import annotations

import time as _time
from typing import Sequence

import numpy as np

from ..circuit.node_stack import NodeStack, shared_row
from ..circuit.scales import whitened_damping
from ..circuit.topology import symmetric_part
from ..errors import InputError, SimulationError
from ..presets import Preset
from ..results.frequency import FrequencyResponse
from ..results.trajectory import SolverStats, Trajectory
from ..small_linalg import eigh, matmul, solve_lower
from .registry import Solver, stacked_trajectories

__all__ = ["solve_exact", "solve_exact_many", "exact_mobility", "phi1", "phi2", "ExactSolver", "SOLVER"]


def _expm1(x: np.ndarray) -> np.ndarray:
    """exp(x) − 1 without cancellation, for real or complex x."""
    if not np.iscomplexobj(x):
        return np.expm1(x)
    a, b = x.real, x.imag
    real = np.expm1(a) * np.cos(b) - 2.0 * np.sin(0.5 * b) ** 2
    imag = np.exp(a) * np.sin(b)
    return real + 1j * imag


def _decay_minus_one(x: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """eˣ − 1 of real *x* (rows, modes, times), written over it; *reach* is each mode's λ·(t1 − t0).

    Where a mode changes by a factor e or more over the segment (|reach| ≥ 1), eˣ − 1 is taken as
    fl(eˣ) − 1, which errs by at most 1.5·ε·max(1, eˣ) absolutely. The term it multiplies, z + d/λ, is
    then within 1/(1 − 1/e) of the mode's own largest excursion, so the states err by a few ε of that
    mode's peak, as forming z + d/λ already makes them. A slower mode keeps ``expm1``, whose relative
    accuracy its small excursion needs (there d/λ far exceeds what the mode reaches). ``exp`` costs
    about half of ``expm1``.
    """
    slow = np.abs(reach) < 1
    if slow.all():
        return np.expm1(x, out=x)
    kept = np.expm1(x[slow]) if slow.any() else None
    np.exp(x, out=x)
    x -= 1.0
    if kept is not None:
        x[slow] = kept
    return x


def phi1(x: np.ndarray) -> np.ndarray:
    """φ₁(x) = (eˣ − 1)/x, with φ₁(0) = 1; real in, real out.

    Parameters
    ----------
    x : array_like
        Real or complex arguments.
    """
    x = np.asarray(x)
    x = x.astype(complex if np.iscomplexobj(x) else float, copy=False)
    out = np.ones_like(x)
    nz = x != 0
    np.divide(_expm1(x), x, out=out, where=nz)
    return out


def phi2(x: np.ndarray) -> np.ndarray:
    """φ₂(x) = (eˣ − 1 − x)/x², with φ₂(0) = 1/2; a Taylor series near 0 avoids cancellation.

    Parameters
    ----------
    x : array_like
        Real or complex arguments.
    """
    x = np.asarray(x)
    x = x.astype(complex if np.iscomplexobj(x) else float, copy=False)
    out = np.empty_like(x)
    small = np.abs(x) < 1.0
    xs = x[small]
    term = np.full_like(xs, 0.5)
    acc = term.copy()
    for k in range(3, 30):      # Σ x^(k−2)/k!; |x| < 1 makes 30 terms exact to rounding
        term = term * xs / k
        acc = acc + term
    out[small] = acc
    xl = x[~small]
    out[~small] = (_expm1(xl) - xl) / xl ** 2
    return out


def _tau_phi1(lam, tau, em1):
    """τ·φ₁(λτ) = (e^{λτ} − 1)/λ from *em1* = e^{λτ} − 1, and τ where λ = 0 (broadcast)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out = em1 / lam
    zero = lam == 0
    return np.where(zero, tau, out) if zero.any() else out


def _forced(lam, s, tau):
    """∫₀^τ e^{λ(τ−σ)}·e^{sσ} dσ, broadcast over λ and τ."""
    w = (s - lam) * tau
    near = np.abs(w) < 1.0
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        far = (np.exp(s * tau) - np.exp(lam * tau)) / np.where(near, 1.0, s - lam)
    return np.where(near, np.exp(lam * tau) * tau * phi1(np.where(near, w, 0)), far)


def _modes(systems, n: int, springs: bool):
    """Stacked modal decomposition: rates λ, modes V, modal state z(0) and force map β.

    Without springs, M'·v' = −B'·v + i is a symmetric-definite pencil; through the
    Cholesky factor of M' it becomes a stack of symmetric eigenproblems with real rates
    and M'-orthonormal modes, so the transform is perfectly conditioned. With springs
    the first-order system on y = [x, v] is decomposed by ``eig``.
    """
    m, b, cmap, v0 = systems.mass, systems.damping, systems.current_map, systems.initial_voltages
    if not springs:
        chol, sym = whitened_damping(systems)
        mu, psi = eigh(symmetric_part(sym))
        vec = solve_lower(chol, psi, transposed=True)
        vec_t = np.swapaxes(vec, 1, 2)
        z = matmul(vec_t, matmul(m, v0[..., None]))[..., 0]
        beta = matmul(vec_t, cmap)
        return -mu, vec, z, beta          # real: real arithmetic unless a sine forces
    k = systems.stiffness
    mk, mb, mc = (np.linalg.solve(m, x) for x in (k, b, cmap))
    eye, zero = np.broadcast_to(np.eye(n), mk.shape), np.zeros_like(mk)
    a = np.concatenate([np.concatenate([zero, eye], 2), np.concatenate([-mk, -mb], 2)], 1)
    lam, vec = np.linalg.eig(a)
    if not np.all(np.isfinite(lam)):
        raise SimulationError("the system has infinite or undefined modal rates")
    cond = np.linalg.cond(vec)
    kappa = np.abs(np.linalg.eigvalsh(symmetric_part(k)))
    # a free direction: a stiffness at K's rounding (16·n·ε of its largest), not a soft spring beside a stiff one
    free = np.any(kappa <= 16 * n * np.finfo(float).eps * np.max(kappa, axis=1, keepdims=True), axis=1)
    if (np.any(cond > 1e10) or np.any(free)) and len(systems) == 1:
        # Free (rigid) directions of K' make x and v a Jordan chain at λ = 0: keep only
        # w = U_rᵀ·x, the extensions the springs feel, so each λ = 0 mode is a plain rate.
        # eig splits the chain into ±√ε·|λ| with modes ε·cond apart: the hopper's (a free body
        # on a leg spring) had cond 4e6 and erred 6.5e-11 of the peak, past the 1e-12 promised.
        a, lam, vec = _spring_state(m[0], k[0], mb[0])
        cond = np.array([np.linalg.cond(vec[0])])
    if np.any(cond > 1e10):
        raise SimulationError(f"the modes are nearly defective (condition number {cond.max():.2g}); "
                              "the exact solver cannot resolve them accurately")
    r = vec.shape[1] - n                    # state y = [x or w, v]
    if r == n:
        lam, vec = _refined(m, b, k, lam, vec)
    y0 = np.concatenate([np.zeros((v0.shape[0], r)), v0], 1).astype(complex)
    z = np.linalg.solve(vec, y0[..., None])[..., 0]
    beta = np.linalg.solve(vec, np.concatenate([np.zeros((mc.shape[0], r, mc.shape[2])), mc], 1).astype(complex))
    return lam, vec, z, beta


def _refined(m, b, k, lam, vec, spread: float = 1e6):
    """Rates and modes of stacks whose rates span more than *spread*, refined on Q(λ) = λ²M + λB + K.

    ``eig`` of the first-order matrix gets each rate to about ε·max|λ| absolutely: a slow
    rate beside a stiff one (1e3 beside 1e15) loses most of its digits. Each mode φ is
    refined by the two-sided Rayleigh quotient of the symmetric Q (the root of
    φᵀQ(λ)φ = 0 nearest λ, taken without cancellation) and one step of inverse iteration,
    which restores full relative accuracy.
    """
    size = np.abs(lam)
    live = size > 0
    low = np.where(live, size, np.inf).min(axis=1)
    wide = np.flatnonzero(size.max(axis=1) > spread * low)
    if wide.size == 0:
        return lam, vec
    lam, vec = lam.astype(complex), vec.astype(complex)
    before = (lam.copy(), vec.copy())
    n = m.shape[1]
    for s in wide:
        for i in np.flatnonzero(live[s]):
            l0 = lam[s, i]
            phi = vec[s, n:, i] if abs(l0) >= 1 else vec[s, :n, i]     # the larger half: v = λ·x
            for _ in range(3):
                qm, qb, qk = (phi @ x @ phi for x in (m[s], b[s], k[s]))
                disc = np.sqrt(complex(qb * qb - 4 * qm * qk))
                if (np.conj(qb) * disc).real < 0:
                    disc = -disc
                q = -0.5 * (qb + disc)
                roots = [q / qm, qk / q] if q != 0 else [l0]
                l0 = min(roots, key=lambda x: abs(x - l0))
                try:
                    step = np.linalg.solve(l0 * l0 * m[s] + l0 * b[s] + k[s], (2 * l0 * m[s] + b[s]) @ phi)
                except np.linalg.LinAlgError:       # Q(λ) exactly singular: λ is exact
                    break
                if not np.all(np.isfinite(step)):
                    break
                phi = step / np.linalg.norm(step)
            col = np.concatenate([phi, l0 * phi])
            lam[s, i], vec[s, :, i] = l0, col / np.linalg.norm(col)
        # two modes refined onto one (a double rate): keep eig's own for this system
        if not np.isfinite(np.linalg.cond(vec[s])) or np.linalg.cond(vec[s]) > 10 * np.linalg.cond(before[1][s]):
            lam[s], vec[s] = before[0][s], before[1][s]
    return lam, vec


def _spring_state(m, k, mb):
    """The first-order matrix on y = [w, v], w = U_rᵀ·x over the range of K' = U_r·κ·U_rᵀ, and its modes."""
    kappa, u = np.linalg.eigh(symmetric_part(k))
    live = np.abs(kappa) > 1e-12 * np.max(np.abs(kappa))
    ur = u[:, live]
    r = ur.shape[1]
    a = np.block([[np.zeros((r, r)), ur.T], [-np.linalg.solve(m, ur * kappa[live]), -mb]])
    lam, vec = np.linalg.eig(a)
    return a[None], lam[None], vec[None]


def _states(systems: NodeStack, t, n: int, springs: bool) -> np.ndarray:
    """States y(t) (x and v with springs, else v) of a stack sharing springs and breakpoints."""
    # without springs each row's modes are its own: made once for the stack a group's circuits are taken from
    lam, vec, z, beta = _modes(systems, n, springs) if springs else \
        systems.rowwise("springless modes", lambda s: _modes(s, n, False))
    count, joints = len(systems), beta.shape[2]
    states = np.empty((count, vec.shape[1], t.size)).transpose(0, 2, 1)     # times contiguous, as SPICE's
    first = systems.inputs_row if systems.shares_inputs else systems[0]
    lam_ = lam[:, :, None]          # time runs along the last axis: long inner loops
    shared: dict = {}               # the pieces of equal forces are derived once
    drives: dict = {}               # and, for rows sharing their inputs, once for every take of their stack
    if systems.shares_inputs:
        shared[None] = (first.forces, slice(None))        # every row
        drives, = systems.rowwise("segment drives", lambda s: ({},))
    else:
        for i, s in enumerate(systems):
            shared.setdefault(s.inputs_key[1], (s.forces, []))[1].append(i)
    for t0, t1 in first.segments():
        last = t1 >= first.t_stop
        mask = (t >= t0) & ((t <= t1) if last else (t < t1))
        whole = bool(mask.all())
        tau = np.concatenate([(t if whole else t[mask]) - t0, [t1 - t0]])
        a_coef, b_coef, exps = np.zeros((count, joints)), np.zeros((count, joints)), []
        for key, (forces, idx) in shared.items():
            # rows sharing their inputs (key None) keep their stack's; rows of other forces derive their own
            got = drives.get((t0, t1)) if key is None else None
            if got is None:
                got = _segment_drive(forces, t0, t1)
                if key is None:
                    drives[(t0, t1)] = got
            a, b, terms = got
            a_coef[idx], b_coef[idx] = a, b
            exps += [(idx, j, c, sv) for j, c, sv in terms]
        x = lam_ * tau
        ramp = b_coef.any()             # φ₂(x) reads x: otherwise e^x − 1 is written over it
        em1 = _decay_minus_one(x, lam * (t1 - t0)) if not ramp and not np.iscomplexobj(x) else _expm1(x)
        # u(t0 + τ) = a + b·τ + Σ c·e^{sτ}, each term integrated exactly against e^{λτ}
        drive = np.einsum("smj,sj->sm", beta, a_coef) if a_coef.any() else None
        if np.all(lam != 0):
            # z·e^x + d·(e^x − 1)/λ = z + (e^x − 1)·(z + d/λ): one pass over the times, in e^x − 1's place
            zt = np.multiply(em1, (z if drive is None else z + drive / lam)[:, :, None],
                             out=em1 if em1.dtype == np.result_type(em1, z, lam) else None)
            zt += z[:, :, None]
        else:
            zt = z[:, :, None] + em1 * z[:, :, None]
            if drive is not None:
                zt = zt + drive[:, :, None] * _tau_phi1(lam_, tau, em1)
        if ramp:
            zt = zt + np.einsum("smj,sj->sm", beta, b_coef)[:, :, None] * tau ** 2 * phi2(x)
        if exps and not np.iscomplexobj(zt):
            zt = zt.astype(complex)
        for idx, j, c, sv in exps:
            zt[idx] += (c * beta[idx, :, j])[:, :, None] * _forced(lam_[idx], sv, tau)
        y = np.swapaxes((vec @ zt).real[:, :, :-1], 1, 2)
        if whole:
            states = y          # one segment: the states are a view, not a copy
        else:
            states[:, mask] = y
        z = zt[:, :, -1]
    return states


def _segment_drive(forces, t0: float, t1: float) -> tuple[list[float], list[float], list[tuple]]:
    """The joint forces' closed forms on [t0, t1]: per joint, a and b of a + b·τ, and the terms (joint, c, s) of c·e^{sτ}."""
    pieces = [[w.piece(t0, t1) for w in ws] for ws in forces]
    return ([sum(p.a for p in ps) for ps in pieces], [sum(p.b for p in ps) for ps in pieces],
            [(j, c, sv) for j, ps in enumerate(pieces) for p in ps for c, sv in zip(p.c, p.s)])


def _solve(systems, t) -> np.ndarray | list[np.ndarray]:
    # Overflow shows as inf or NaN in the states, which _finite turns into one sentence.
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return _solve_parts(systems, t)
    except np.linalg.LinAlgError:           # an overflowed modal matrix: eig and cholesky refuse it
        raise SimulationError("the modal decomposition failed: the system's rates leave the "
                              "floating-point range") from None


def _solve_parts(systems, t) -> np.ndarray | list[np.ndarray]:
    if isinstance(systems, NodeStack) and len(systems.partition()) == 1:     # one stack: returned whole
        return _finite(_states(systems, t, systems.dof, not systems.springless))
    groups: dict = {}
    breaks: dict = {}
    for k, s in enumerate(systems):
        b = breaks.get(s.inputs_key)
        if b is None:
            b = breaks[s.inputs_key] = tuple(s.breakpoints().tolist())
        groups.setdefault((s.dof, s.stiffness is not None, b), []).append(k)
    if len(groups) == 1:
        (n, springs, _), = groups
        return _finite(_states(NodeStack.of(systems), t, n, springs))
    out: list = [None] * len(systems)
    for (n, springs, _), idx in groups.items():
        for k, y in zip(idx, _finite(_states(NodeStack([systems[k] for k in idx]), t, n, springs))):
            out[k] = y
    return out


def _finite(states: np.ndarray) -> np.ndarray:
    """*states*, unless a value left the floating-point range: then a failure, never inf or NaN."""
    if not np.all(np.isfinite(states)):
        raise SimulationError("the exact solution leaves the floating-point range (the rates or positions "
                              "pass 1.8e308): rescale the masses, forces or time")
    return states


def solve_exact_many(systems: Sequence, times) -> list[np.ndarray]:
    """Exact node voltages of many systems at the same *times*, vectorised over the systems.

    Systems are split by size, springs and force breakpoints, and each part is solved
    at once with numpy's stacked linear algebra.

    Parameters
    ----------
    systems : sequence of NodeSystem
        Linear systems sharing t_stop.
    times : array_like
        Output times.
    """
    if not systems:
        return []
    t = systems[0].time_points(times)
    return [y[:, -s.dof:] for s, y in zip(systems, _solve(systems, t))]


def solve_exact(system, times=None, positions: bool = False) -> Trajectory:
    """Exact node voltages and joint rates of *system* at *times*.

    Forces are piecewise closed forms (constant, ramp, damped sine) between the
    system's breakpoints; each segment is integrated exactly in modal coordinates.

    Parameters
    ----------
    system : NodeSystem
    times : array_like, optional
        Sorted times in [0, t_stop]; default 1001 uniform points.
    positions : bool
        Also return the node positions x = ∫v (:attr:`Trajectory.positions`) when the
        system has springs; they are part of its state, so this costs nothing extra.
    """
    start = _time.perf_counter()
    t = system.time_points(times)
    y = _solve([system], t)[0]
    n = system.dof
    voltages = y[:, -n:]
    if positions and system.stiffness is not None and y.shape[1] != 2 * n:
        raise SimulationError("the exact solver keeps only the spring extensions of a system with "
                              "free (rigid) modes, not its positions: use the ode solver for them")
    pos = y[:, :n] if positions and system.stiffness is not None else None
    with np.errstate(over="ignore", invalid="ignore"):
        rates = _finite(system.joint_rates(voltages))        # R = T⁻¹·v may overflow where v did not
    elapsed = _time.perf_counter() - start
    return Trajectory("exact", t, voltages, rates, pos, stats=SolverStats(elapsed))


class ExactSolver(Solver):
    """The modal closed form of a linear system, segment by segment."""

    name = "exact"
    yardstick = True
    linear_only = True
    label = "modal closed form"

    def _solve(self, system, times, preset: Preset, *, save=(), positions=False) -> Trajectory:
        """The exact solution at *times*; see :meth:`Solver.solve`.

        Parameters
        ----------
        system : NodeSystem
            A linear system.
        times : ndarray
            Checked output times.
        preset : Preset
            Sets the default grid only.
        save : sequence of str
            Unused: element currents follow from the trajectory.
        positions : bool
            Also return node positions where the system has springs.
        """
        return solve_exact(system, times, positions)

    def _solve_many(self, systems, times, preset: Preset, *, save=(), positions=False) -> list[Trajectory]:
        """All systems at once with stacked linear algebra; if that fails, one by one.

        Parameters
        ----------
        systems : sequence of NodeSystem
            Linear systems.
        times : array_like or None
            Shared output times.
        preset : Preset
            Sets the default grid only.
        save : sequence of str
            Unused: element currents follow from the trajectory.
        positions : bool
            Also return node positions where the systems have springs (one by one).
        """
        linear = systems.linear if isinstance(systems, NodeStack) else not any(self.supports(s) for s in systems)
        if positions or len(systems) == 1 or not linear:
            return super()._solve_many(systems, times, preset, positions=positions)
        start = _time.perf_counter()
        first = shared_row(systems)
        t = self.grid(first, times, preset)
        try:
            states = _solve(systems, t)
        except SimulationError:             # one by one, so that only a system it cannot take fails
            return [self._one(s, t) for s in systems]
        each = SolverStats((_time.perf_counter() - start) / len(systems))
        if isinstance(states, np.ndarray):  # one stack: voltages are a view of it
            return stacked_trajectories(self.name, systems, t, states[:, :, -first.dof:], each)
        return [Trajectory("exact", t, y[:, -s.dof:], s.joint_rates(y[:, -s.dof:]), stats=each)
                for s, y in zip(systems, states)]

    def _one(self, system, t) -> Trajectory:
        start = _time.perf_counter()
        try:
            v = solve_exact_many([system], t)[0]
        except SimulationError as exc:
            return Trajectory.failed(self.name, str(exc), _time.perf_counter() - start)
        return Trajectory("exact", t, v, system.joint_rates(v), stats=SolverStats(_time.perf_counter() - start))


SOLVER = ExactSolver()


def exact_mobility(system, frequencies) -> FrequencyResponse:
    """Y(s)·T⁻ᵀ with Y = (M'·s + B' + K'/s)⁻¹ at s = 2πj·f: node velocity per unit joint force.

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    frequencies : array_like
        Frequencies [Hz], positive.
    """
    f = np.asarray(frequencies, dtype=float)
    if f.ndim != 1 or not np.all(f > 0):
        raise InputError("frequencies must be a 1-D array of positive values [Hz]")
    s = 2j * np.pi * f[:, None, None]
    k = np.zeros_like(system.mass) if system.stiffness is None else system.stiffness
    impedance = system.mass * s + system.damping + k / s
    mobility = np.linalg.solve(impedance, np.broadcast_to(system.current_map, impedance.shape).astype(complex))
    return FrequencyResponse(f, mobility, "exact", np.linalg.inv(system.topology.matrix),
                             system.provenance.units, tuple(system.provenance.configuration) or None)
