"""Direct integration of M'(x)·dv/dt = i(t) − B'·v − K'·x − h with scipy's ODE solvers."""

from __future__ import annotations

import threading
import time as _time
import warnings
from dataclasses import replace

import numpy as np
import scipy.linalg as la
from scipy import integrate

from ..circuit.scales import system_scales
from ..errors import InputError, SimulationError
from ..presets import Preset
from ..results.trajectory import SolverStats, Trajectory
from .registry import Solver

__all__ = ["solve_ode", "REFINE_RTOL", "ODE_METHODS", "STIFF_STEPS", "stiff_method", "state_matrices", "OdeSolver", "SOLVER"]

#: scipy.integrate methods; the implicit ones receive the constant analytic Jacobian of a linear system.
ODE_METHODS = ("LSODA", "Radau", "BDF", "RK45", "RK23", "DOP853")
_IMPLICIT = {"LSODA", "Radau", "BDF"}
#: How far each explicit method's stability region reaches along the negative real axis, |h·λ|.
_REACH = {"RK45": 3.3, "RK23": 2.5, "DOP853": 4.0}
#: An explicit method that would need more steps than this for stability alone is replaced.
STIFF_STEPS = 100_000


def stiff_method(system, method: str, jac, y0: np.ndarray, scales=None) -> tuple[str, str, float]:
    """(the method to use, why, its longest step): Radau where stability, not accuracy, would set
    an explicit method's steps.

    A system is stiff here when its largest rate |λ| would hold an explicit method to more
    than :data:`STIFF_STEPS` steps over t_stop, and |λ| is more than 100 times its fastest
    oscillation (which needs short steps anyway) and 1/t_stop. An explicit method kept on a
    system with a fast decay takes steps within its stability reach, h·|λ| ≤ reach: past it the
    step controller lets the decayed mode regrow to the tolerance and the dense output between
    steps amplifies it (DOP853 at h·|λ| = 15 erred 3e-6 at rtol 1e-12; within reach, 3e-12).

    Parameters
    ----------
    system : NodeDynamics
        The system.
    method : str
        The method asked for.
    jac : ndarray or callable or None
        The Jacobian of the first-order form (callable: evaluated at t = 0, *y0*).
    y0 : ndarray
        The initial state.
    scales : Scales, optional
        The system's scales, if already computed.
    """
    reach = _REACH.get(method)
    if reach is None or jac is None:
        return method, "", np.inf
    a = jac(0.0, y0) if callable(jac) else jac
    rho = float(np.max(np.abs(np.linalg.eigvals(a)))) if a.size else 0.0
    t_stop = float(system.t_stop)
    longest = reach / rho if rho > 0 else np.inf
    if rho * t_stop / reach <= STIFF_STEPS:
        return method, "", longest
    if rho <= 100 * max((scales or system_scales(system)).omega_max, 1 / t_stop):
        return method, "", longest
    return "Radau", f"stiff, |λ|·t_stop = {rho * t_stop:.2g}: Radau with the analytic Jacobian, not {method}", np.inf


def state_matrices(system) -> tuple[np.ndarray, np.ndarray]:
    """First-order form y' = A·y + G·F(t) of a linear system on y = [x, v] (or y = v without springs).

    M'⁻¹ is never formed: M'⁻¹B', M'⁻¹K' and M'⁻¹T⁻ᵀ come from one Cholesky factor.

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    """
    n = system.dof
    chol = la.cho_factor(system.mass)
    mb = la.cho_solve(chol, system.damping)
    mc = la.cho_solve(chol, system.current_map)
    if system.stiffness is None:
        return -mb, mc
    mk = la.cho_solve(chol, system.stiffness)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-mk, -mb]])
    g = np.vstack([np.zeros((n, mc.shape[1])), mc])
    return a, g


class _SegmentForces:
    """The joint forces on one segment between breakpoints, in the closed form the exact solver
    uses, u(t0 + τ) = a + b·τ + Σ c·e^{s·τ} (:class:`~analogy.waveforms.Piece`): a few array
    operations per call instead of every waveform's own evaluation."""

    def __init__(self, forces):
        self.forces = forces
        self.segment(0.0, 0.0)

    def segment(self, t0: float, t1: float) -> None:
        pieces = [[w.piece(t0, t1) for w in ws] for ws in self.forces]
        self.t0 = t0
        self.a = np.array([sum(p.a for p in ps) for ps in pieces], dtype=float)
        self.b = np.array([sum(p.b for p in ps) for ps in pieces], dtype=float)
        terms = [(j, c, e) for j, ps in enumerate(pieces) for p in ps for c, e in zip(p.c, p.s)]
        self.rows = np.array([j for j, _, _ in terms], dtype=int)
        self.c = np.array([c for _, c, _ in terms], dtype=complex)
        self.s = np.array([e for _, _, e in terms], dtype=complex)
        #: No ramp or exponential on this segment: the forces are a.
        self.constant = not self.rows.size and not np.any(self.b)

    def __call__(self, tt: float) -> np.ndarray:
        tau = tt - self.t0
        f = self.a + self.b * tau
        if self.rows.size:
            f = f + np.bincount(self.rows, (self.c * np.exp(self.s * tau)).real, minlength=f.size)
        return f


def _linear(system, force):
    """(rhs, jacobian, initial state, whether x is in the state)."""
    a, g = state_matrices(system)
    springs = system.stiffness is not None
    v0 = system.initial_voltages
    y0 = np.concatenate([np.zeros(system.dof), v0]) if springs else v0.copy()

    held = [None, None]         # (the segment's a, g·a) on a segment of constant forces: most of a run's steps

    def rhs(tt, yy):
        if force.constant:
            if held[0] is not force.a:
                held[:] = force.a, g @ force.a
            return a @ yy + held[1]
        return a @ yy + g @ force(tt)
    return rhs, a, y0, springs


def _nonlinear(system, force):
    """State [x, v, W]: W = ∫(iᵀv − vᵀB'v) dt, with − G'ᵀv in it where the model has no potential
    (:meth:`~analogy.circuit.nonlinear.NonlinearNodeSystem.flow`): the work of the forces that
    are not in the kinetic and spring energies, so that the energy balance can be checked."""
    n = system.dof
    cmap = system.current_map
    flow = system.flow

    def rhs(tt, yy):
        v = yy[n:2 * n]
        accel, power = flow(yy[:n], v, cmap @ force(tt))
        return np.concatenate([v, accel, [power]])
    y0 = np.concatenate([np.zeros(n), system.initial_voltages, [0.0]])
    jac = None
    if system.functions.derivatives is not None:
        def jac(tt, yy):
            return system.jacobian(yy[:n], yy[n:2 * n], cmap @ force(tt))
    return rhs, jac, y0, True


class _Outputs:
    """Where states go at output points: the joint rates' node velocities, the positions, the work."""

    __slots__ = ("out", "pos", "work", "vs", "n")

    def __init__(self, out: np.ndarray, pos: np.ndarray | None, work: np.ndarray | None, vs: slice, n: int) -> None:
        self.out, self.pos, self.work, self.vs, self.n = out, pos, work, vs, n

    def __call__(self, at: np.ndarray, states: np.ndarray) -> None:
        """States (one row per output point *at*) into the outputs."""
        self.out[at] = states[:, self.vs]
        if self.pos is not None:
            self.pos[at] = states[:, :self.n]
        if self.work is not None:
            self.work[at] = states[:, -1]


def _stepped(sol, method: str, t: np.ndarray, idx: np.ndarray, keep: _Outputs, start: float,
             timeout: float | None, t_stop: float) -> int:
    """Step scipy's solver *sol* to the segment's end, each step's output points (*idx*, ascending)
    read from its dense output; the number of steps. A failure or the time limit is one sentence."""
    wanted, k, steps = t[idx], 0, 0
    while sol.status == "running":
        message = _guarded(method, sol.t, sol.step)
        if sol.status == "failed":
            raise SimulationError(f"the ODE solver {method} could not continue at t = {sol.t:.6g} s "
                                  f"({_plain(message)}): try the other preset or the exact solver")
        if timeout is not None and _time.perf_counter() - start > timeout:
            raise SimulationError(f"the ODE solver {method} passed its time limit of {timeout:g} s at "
                                  f"t = {sol.t:.6g} of {t_stop:g} s: raise the preset's timeout or "
                                  "use the fast preset")
        steps += 1
        stop = int(np.searchsorted(wanted, sol.t, side="right"))     # bisection: the points are ascending
        if stop > k:
            keep(idx[k:stop], sol.dense_output()(t[idx[k:stop]]).T)
            k = stop
    return steps


def solve_ode(system, times=None, method: str = "DOP853", rtol: float = 1e-10,
              atol: float | None = None, positions: bool = False, timeout: float | None = None) -> Trajectory:
    """Integrate *system* with a scipy ODE solver, restarting at every force breakpoint.

    An explicit *method* on a stiff system is replaced by Radau (:func:`stiff_method`),
    and the trajectory's :attr:`~Trajectory.message` says so.

    Parameters
    ----------
    system : NodeDynamics
        A linear or nonlinear node system.
    times : array_like, optional
        Output times in [0, t_stop]; default 1001 uniform points.
    method : str
        One of :data:`ODE_METHODS`.
    rtol, atol : float
        Tolerances; *atol* defaults to ``rtol * 1e-2`` times each state's scale
        (:func:`~analogy.circuit.scales.system_scales`).
    positions : bool
        Also return the node positions x = ∫v (:attr:`Trajectory.positions`) when the
        system has springs or is nonlinear (they are then part of the integrated state).
        A nonlinear system's trajectory also carries :attr:`Trajectory.work`.
    timeout : float, optional
        Wall-time limit [s]; past it the integration stops with :class:`SimulationError`.
    """
    if method not in ODE_METHODS:
        raise InputError(f"unknown ODE method {method!r}: use {', '.join(ODE_METHODS)}")
    start = _time.perf_counter()
    t = system.time_points(times)
    n = system.dof
    linear = system.kind == "linear"
    force = _SegmentForces(system.forces)
    rhs, jac, y, has_x = _linear(system, force) if linear else _nonlinear(system, force)
    sc = None
    if atol is None:
        # Per state component, relative to the motion it can have (small modal nodes too).
        sc = system_scales(system)
        parts = ([sc.position] if has_x else []) + [sc.velocity]
        if not linear:
            parts.append([sc.current * sc.peak_velocity * system.t_stop])
        atol = rtol * 1e-2 * np.concatenate(parts)
    method, note, longest = stiff_method(system, method, jac, y, sc)
    extra = {"max_step": longest} if np.isfinite(longest) else {}
    if jac is not None and method in _IMPLICIT:     # LSODA takes the Jacobian as a callable only
        extra["jac"] = (lambda tt, yy: jac) if method == "LSODA" and not callable(jac) else jac
    cls = getattr(integrate, method)
    out = np.empty((t.size, n))
    # a nonlinear system's x at every point: gravity's work U(q0) − U(q) is added to W from it
    pos = np.empty((t.size, n)) if (positions or not linear) and has_x else None
    vs = slice(n, 2 * n) if not linear else slice(y.size - n, y.size)     # where v sits in the state
    work = np.empty(t.size) if not linear else None
    keep = _Outputs(out, pos, work, vs, n)
    steps = nfev = njev = 0
    for t0, t1 in system.segments():
        force.segment(t0, t1)
        last = t1 >= system.t_stop
        idx = np.flatnonzero((t >= t0) & ((t <= t1) if last else (t < t1)))
        at_start = idx[t[idx] == t0]
        keep(at_start, np.broadcast_to(y, (at_start.size, y.size)))
        idx = idx[t[idx] > t0]
        if t1 > t0 and method == "LSODA":
            values, counts = _lsoda(rhs, jac, y, t0, t1, t[idx], rtol, atol, start, timeout, system.t_stop)
            keep(idx, values[1:1 + idx.size])
            y = values[-1]
            steps, nfev, njev = steps + counts[0], nfev + counts[1], njev + counts[2]
        elif t1 > t0:
            sol = _guarded(method, t0, cls, rhs, t0, y, t1, rtol=rtol, atol=atol, **extra)
            steps += _stepped(sol, method, t, idx, keep, start, timeout, system.t_stop)
            nfev, njev = nfev + sol.nfev, njev + sol.njev
            y = sol.y
    if work is not None and (lifted := system.gravity_work(pos)) is not None:
        work = work + lifted
    elapsed = _time.perf_counter() - start
    stats = SolverStats(elapsed, steps, None, nfev, njev)
    forces = system.contact_forces(pos, out) if not linear and pos is not None else {}
    return Trajectory("ode", t, out, system.joint_rates(out), pos if positions else None, forces, stats=stats,
                      work=work, message=note)


#: odeint's failure messages, in the words of the solver's other failures.
_ODEPACK_REASONS = (
    ("Excess work done", "it took 1e8 steps in one output interval"),
    ("Excess accuracy requested", "the tolerances are below what rounding allows"),
    ("Illegal input", "the state left the floating-point range"),
    ("Repeated convergence failures", "its corrector iterations did not converge"),
    ("Error weight became zero", "a state's absolute tolerance fell to zero"),
)


class _PastLimit(Exception):
    """Raised from the right-hand side when the wall-time limit has passed."""


def _lsoda(rhs, jac, y0, t0: float, t1: float, times: np.ndarray, rtol, atol, start: float,
           timeout: float | None, t_stop: float):
    """One force segment [t0, t1] with ODEPACK's LSODA (``odeint``): the state at t0, *times*
    and t1, and (steps, f and Jacobian evaluations). Not scipy's ``LSODA`` class, which keeps
    0.8 kB per call (scipy 1.17), so that a loop of runs grows without bound; ``tcrit`` stops
    the steps at t1, so none reaches into the next segment's forces."""
    grid = np.concatenate([[t0], times, [t1]] if not times.size or times[-1] < t1 else [[t0], times])
    deadline = None if timeout is None else start + timeout

    def f(tt, yy):
        if deadline is not None and _time.perf_counter() > deadline:
            raise _PastLimit(tt)
        return rhs(tt, yy)
    dfun = None if jac is None else (jac if callable(jac) else (lambda tt, yy: jac))
    try:
        values, info = _guarded("LSODA", t0, integrate.odeint, f, y0, grid, Dfun=dfun, tfirst=True,
                                rtol=rtol, atol=atol, tcrit=[t1], mxstep=100_000_000, full_output=True,
                                printmessg=False)
    except _PastLimit as exc:
        raise SimulationError(f"the ODE solver LSODA passed its time limit of {timeout:g} s at t = "
                              f"{exc.args[0]:.6g} of {t_stop:g} s: raise the preset's timeout or use the fast "
                              "preset") from None
    if info["message"] != "Integration successful.":
        reached = float(np.max(info["tcur"], initial=t0))
        reason = next((why for start_, why in _ODEPACK_REASONS if info["message"].startswith(start_)),
                      "its step size fell to rounding")
        raise SimulationError(f"the ODE solver LSODA could not continue at t = {reached:.6g} s "
                              f"({reason}): try the other preset or the exact solver")
    return values, (int(info["nst"][-1]), int(info["nfe"][-1]), int(info["nje"][-1]))


_WARNINGS = threading.Lock()


def _guarded(method: str, at: float, fn, *args, **kwargs):
    """*fn* with scipy's warnings silenced and its numeric errors turned into one sentence."""
    try:
        # warnings' filters are the process's: two threads entering and leaving catch_warnings
        # interleaved would leave "ignore" behind (a batch in this process runs two groups at once)
        with _WARNINGS, warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")     # scipy's notes become the sentences here and above
            return fn(*args, **kwargs)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        # e.g. "array must not contain infs or NaNs" from an overflowing step
        raise SimulationError(f"the ODE solver {method} met values outside the floating-point range "
                              f"at t = {at:.6g} s: rescale the masses, dampers, springs or forces") from None


def _plain(message) -> str:
    """scipy's failure text without its codes (LSODA's "istate")."""
    text = str(message or "").strip().rstrip(".")
    return "its step size fell to rounding" if "istate" in text.lower() or not text else text


#: The second run of an error estimate asks for this many times less error.
REFINE_RTOL = 100.0


class OdeSolver(Solver):
    """scipy's integrators with the preset's method and tolerance."""

    name = "ode"
    label = "scipy.integrate"

    def refinements(self, preset: Preset) -> list[tuple[Preset, float]]:
        """The same method at a tolerance :data:`REFINE_RTOL` times tighter (an error about that
        much smaller; scipy holds rtol above 100·ε, so at least 45 times at ``accurate``).

        Parameters
        ----------
        preset : Preset
            The settings of the run to be judged.
        """
        return [(replace(preset, ode=replace(preset.ode, rtol=preset.ode.rtol / REFINE_RTOL)), REFINE_RTOL / (REFINE_RTOL - 1))]

    def _solve(self, system, times, preset: Preset, *, save=(), positions=False) -> Trajectory:
        """Integrate with ``preset.ode.method`` at ``preset.ode.rtol``; see :meth:`Solver.solve`.

        Parameters
        ----------
        system : NodeDynamics
            The system.
        times : ndarray
            Checked output times.
        preset : Preset
            Accuracy settings.
        save : sequence of str
            Unused: element currents follow from the trajectory.
        positions : bool
            Also return node positions where the system has springs.
        """
        return solve_ode(system, times, preset.ode.method, preset.ode.rtol, positions=positions,
                         timeout=preset.budget.timeout)


SOLVER = OdeSolver()
