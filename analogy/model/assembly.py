"""A closed chain's passive joints from its active ones: continuation from a reference assembly, then Newton."""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["AssemblySolver", "SINGULAR_CONDITION"]

#: Equilibrated cond(Φ_p) past which a closed chain's pose counts as near a singular one: the
#: passive joints' solution is then twenty times more sensitive to the motors than its best.
#: Measured on the five-bar: 9.1 on a 2 rad swing that keeps 1e-6 at accurate, 108 on the
#: built-in scene's 10 s, which misses it by 300 times (``examples/lab_closed_chains.py``).
SINGULAR_CONDITION = 20.0


#: A pose this close (rad, or m) to the last one solved continues from it, not from the reference.
_NEAR = 0.05
#: Continuation steps from the reference assembly to the asked configuration (each a few Newton
#: iterations); a pose many turns away would otherwise take minutes.
_MAX_CONTINUATION_STEPS = 2000


class AssemblySolver:
    """Numeric loop closure by continuation from the reference assembly; remembers the last answer.

    Called with (q, parameter values) it returns the passive coordinates p and their rates ∂p/∂q.

    Parameters
    ----------
    model : ClosedChainModel
        The chain (its reference assembly, branch, correction and condition limits).
    kin : tuple of callable
        Φ, Φ_p and Φ_q, each of (q, p, parameter values).
    n : int
        Number of active joints.
    pnames : list of str
        The model's parameter names, in its order.
    """

    def __init__(self, model, kin, n: int, pnames: list[str]):
        self.model, self.n, self.pnames = model, n, pnames
        self.residual, self.jac_p, self.jac_q = kin
        self.last = (None, None)
        self.references = {}

    def __call__(self, args):
        key = tuple(float(a) for a in args)
        if self.last[0] == key:
            return self.last[1]
        q, params = np.array(key[:self.n]), key[self.n:]
        if self.model.branch is not None:
            q0, p0 = (np.asarray(a, dtype=float).reshape(-1)
                      for a in self.model.branch(q, dict(zip(self.pnames, params))))
        else:
            q0, p0 = self._reference(params)
        near = self.last[0]
        if near is not None and near[self.n:] == params and np.max(np.abs(q - near[:self.n]), initial=0) <= _NEAR:
            q0, p0 = np.array(near[:self.n]), self.last[1][0]     # along a trajectory: from the last pose
        p = self._continue(q0, p0, q, params)
        if (cond := self.condition(q, p, params)) > self.model.max_condition:
            raise InputError(f"model {self.model.name!r} is at a singular pose at q = {_fmt(q)}: the active "
                             "joints do not determine the passive ones' rates there (equilibrated cond(Φ_p) = "
                             f"{cond:.3g}; links in line, a parallelogram folded flat); choose a pose away from it",
                             field="q")
        rates = -np.linalg.solve(self._jp(q, p, params), self._jq(q, p, params))
        self.last = (key, (p, rates))
        return p, rates

    def condition(self, q, p, params) -> float:
        """cond(Φ_p) at (q, p), its rows and columns scaled as at the reference assembly.

        Parameters
        ----------
        q, p : ndarray
            Active and passive joint coordinates.
        params : tuple of float
            The model's parameter values, in its order.
        """
        q0, p0 = self._reference(params)
        start = self._jp(q0, p0, params)
        columns = np.linalg.norm(start, axis=0)
        lines = np.linalg.norm(start / columns, axis=1)
        return float(np.linalg.cond(self._jp(q, p, params) / columns / lines[:, None]))

    def _r(self, q, p, params):
        return np.asarray(self.residual(*q, *p, *params), dtype=float).reshape(-1)

    def _jp(self, q, p, params):
        return np.asarray(self.jac_p(*q, *p, *params), dtype=float)

    def _jq(self, q, p, params):
        return np.asarray(self.jac_q(*q, *p, *params), dtype=float)

    def _reference(self, params):
        if params not in self.references:
            values = dict(zip(self.pnames, params))
            try:
                q0, p0 = (np.asarray(a, dtype=float).reshape(-1) for a in self.model.reference(values))
                p0 = self._newton(q0, p0, params)
            except (ValueError, ZeroDivisionError, FloatingPointError, np.linalg.LinAlgError):
                p0 = None
            if p0 is None:
                raise InputError(f"model {self.model.name!r} has no reference assembly "
                                 f"with these parameters")
            self.references[params] = (q0, p0)
        return self.references[params]

    def _newton(self, q, p, params):
        # Quadratic convergence is required: a slow or growing correction means the
        # predictor was too far from this branch, and the caller shortens the step.
        p = np.array(p, dtype=float)
        previous = np.inf
        for k in range(30):
            if not np.all(np.isfinite(p)):
                return None
            delta = np.linalg.solve(self._jp(q, p, params), self._r(q, p, params))
            size = float(np.max(np.abs(delta))) if delta.size else 0.0
            if not np.isfinite(size) or (k == 0 and size > self.model.max_correction):
                return None
            p -= delta
            if size <= 1e-12:
                p -= np.linalg.solve(self._jp(q, p, params), self._r(q, p, params))
                return p
            if size > 0.5 * previous:
                return None
            previous = size
        return None

    def _continue(self, q0, p0, q1, params):
        dq = q1 - q0

        def at(s):
            return q1 if s == 1.0 else q0 + s * dq

        sign = np.sign(np.linalg.det(self._jp(q0, p0, params)))
        s, h, p = 0.0, 1.0, p0
        for _ in range(_MAX_CONTINUATION_STEPS):
            if s >= 1.0:
                break
            # s and h stay dyadic, so the last step lands on s = 1 exactly.
            h = min(h, 1.0 - s)
            qs = at(s)
            try:
                tangent = -np.linalg.solve(self._jp(qs, p, params), self._jq(qs, p, params) @ dq)
                trial = self._newton(at(s + h), p + h * tangent, params)
            except np.linalg.LinAlgError:
                trial = None
            if trial is not None and np.sign(np.linalg.det(self._jp(at(s + h), trial, params))) == sign:
                p, s, h = trial, s + h, 2.0 * h
                continue
            h *= 0.5
            if h < 1e-6:
                why = (f": the loop meets a singular pose near q = {_fmt(qs)}, where the active joints do not "
                       "determine the passive ones (links in line, a parallelogram folded flat); choose a pose "
                       "away from it") if np.linalg.cond(self._jp(qs, p, params)) > self.model.max_condition else \
                    f" (continuation from q = {_fmt(q0)} fails near q = {_fmt(qs)})"
                raise InputError(f"model {self.model.name!r} does not assemble at q = {_fmt(q1)} "
                                 f"in its working mode{why}", field="q")
        if s < 1.0:
            raise InputError(f"model {self.model.name!r}: q = {_fmt(q1)} is too far from its reference assembly "
                             f"q = {_fmt(q0)} to follow the loop there in {_MAX_CONTINUATION_STEPS:,} steps: give "
                             "joint angles within a few turns of it", field="q")
        return p


def _fmt(q) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in q) + ")"
