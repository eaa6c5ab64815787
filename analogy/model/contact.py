"""Compliant unilateral contact with the ground plane: a one-sided spring and damper, smoothed over a stated length.

A contact point at height y(q) above the ground penetrates it by p = −y. The ground pushes
it up with the Kelvin–Voigt force k·p + c·ṗ while it penetrates, and not at all in flight.
That switch is smoothed over the length δ so that Newton's iteration in SPICE and the ODE's
step control see a force with continuous derivatives:

    f(p, ṗ) = (k·p + c·ṗ)·s(p),     s(p) = (1 + tanh(p/(2δ)))/2,

the logistic function of p/δ. For p ≫ δ the force is the linear spring and damper (a
stance phase is a damped oscillator); for p ≪ −δ it is zero to rounding (tanh saturates to
−1 past 19 of its argument, 38·δ of height); across the switch it departs from the sharp
law by at most (k·δ + c·|ṗ|)·O(1) over a height of a few δ, so the motion converges to the
piecewise linear one at first order in δ. Like any Kelvin–Voigt contact it can pull briefly
at the end of a stance, while p is still positive and ṗ strongly negative: that is the law's,
and the closed form of its stance phase has it too.

The force acts along the ground's normal at the contact point: its generalised force is
τ = (∂y/∂q)ᵀ·f, the same expression in the circuit's behavioural sources and in the ODE.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError

if TYPE_CHECKING:
    import sympy as sp

__all__ = ["Contact", "contact_force", "friction_force", "smoothed_switch", "generalised_contact_forces",
           "check_contact_values", "SLIP_SPEED"]

#: The sliding speed over which Coulomb friction's direction is smoothed [m/s]: below it friction
#: grows as a steep damper (μ·f/SLIP_SPEED), so a foot that sticks creeps at about SLIP_SPEED times
#: the share of μ·f its tangential load takes.
SLIP_SPEED = 1e-3


def _sympy():
    import sympy        # the expressions' algebra: only where a model is derived, not where a tree is run
    return sympy


def smoothed_switch(p, smoothing, tanh=None) -> Any:
    """s(p) = (1 + tanh(p/(2δ)))/2, the contact's on-switch smoothed over δ: an expression, or numbers
    with ``tanh=numpy.tanh``.

    Parameters
    ----------
    p : sympy expression or array_like
        Penetration [m].
    smoothing : sympy expression or float
        The smoothing length δ [m].
    tanh : callable, optional
        The hyperbolic tangent of the arithmetic at hand (default sympy's; numpy's for numbers).
    """
    tanh = tanh or _sympy().tanh
    return (1 + tanh(p / (2 * smoothing))) / 2


def contact_force(p, rate, stiffness, damping, smoothing, tanh=None) -> Any:
    """The normal force f = (k·p + c·ṗ)·s(p) the ground exerts at penetration *p* and its rate: the one law,
    written once, for the circuit's expressions (sympy) and the ODE's numbers (``tanh=numpy.tanh``).

    Parameters
    ----------
    p, rate : sympy expression or array_like
        Penetration [m] and its rate [m/s].
    stiffness, damping, smoothing : sympy expression or float
        k [N/m], c [N·s/m] and δ [m].
    tanh : callable, optional
        sympy's tanh (expressions, the default) or numpy's (numbers).
    """
    return (stiffness * p + damping * rate) * smoothed_switch(p, smoothing, tanh)


def friction_force(normal, vx, vy, mu, sqrt=None) -> tuple:
    """Regularised Coulomb friction (fx, fy) = −μ·f·(vx, vy)/√(vx² + vy² + :data:`SLIP_SPEED`²) against the
    contact's sliding velocity, under its normal force *normal*: the one law for expressions and numbers.

    Parameters
    ----------
    normal : sympy expression or array_like
        The normal force f [N].
    vx, vy : sympy expression or array_like
        The sliding velocity's components along the ground [m/s].
    mu : float
        The friction coefficient.
    sqrt : callable, optional
        sympy's square root (expressions, the default) or numpy's (numbers).
    """
    sqrt = sqrt or _sympy().sqrt
    scale = -mu * normal / sqrt(vx * vx + vy * vy + SLIP_SPEED ** 2)
    return scale * vx, scale * vy


@dataclass(frozen=True)
class Contact:
    """A point of the robot that touches the ground plane y = 0 from above.

    Attributes
    ----------
    name : str
        The point's name (a link's: ``foot``); the force's output is ``f_<name>``.
    height : sympy expression
        Its height y(q) above the ground [m], in the model's coordinates and parameters.
    stiffness, damping, smoothing : sympy expression
        k [N/m], c [N·s/m] and δ [m]: numbers or the model's parameters.
    """

    name: str
    height: sp.Expr
    stiffness: sp.Expr
    damping: sp.Expr
    smoothing: sp.Expr

    def __post_init__(self):
        if not self.name.isidentifier():
            raise InputError(f"a contact's name must be an identifier, got {self.name!r}")

    def force(self, coordinates: Sequence[sp.Symbol], rates: Sequence[sp.Symbol]) -> sp.Expr:
        """The normal force f(q, q̇) [N], as an expression.

        Parameters
        ----------
        coordinates, rates : sequence of sympy Symbol
            q and q̇.
        """
        sp = _sympy()
        q = list(coordinates)
        depth = -sp.sympify(self.height)
        rate = sum(sp.diff(depth, qk) * rk for qk, rk in zip(q, rates))
        return contact_force(depth, rate, self.stiffness, self.damping, self.smoothing)

    def normal(self, coordinates: Sequence[sp.Symbol]) -> sp.Matrix:
        """J = ∂y/∂q, the height's gradient: the force's generalised direction.

        Parameters
        ----------
        coordinates : sequence of sympy Symbol
            q.
        """
        sp = _sympy()
        return sp.Matrix([sp.diff(sp.sympify(self.height), qk) for qk in coordinates])


def generalised_contact_forces(contacts: Sequence[Contact], coordinates: Sequence[sp.Symbol],
                               forces: Sequence[sp.Expr]) -> sp.Matrix:
    """τ = Σ_c J_cᵀ·f_c: the contacts' normal forces *forces* as joint forces.

    Parameters
    ----------
    contacts : sequence of Contact
        The contacts.
    coordinates : sequence of sympy Symbol
        q.
    forces : sequence of sympy expression
        Each contact's normal force (its expression, or a symbol standing for it).
    """
    n = len(coordinates)
    total = _sympy().zeros(n, 1)
    for contact, f in zip(contacts, forces):
        total += contact.normal(coordinates) * f
    return total


def check_contact_values(contacts: Sequence[Contact], values: Mapping[str, object]) -> None:
    """Refuse, in one sentence, a contact whose stiffness or damping is negative or whose smoothing length is
    not positive at parameter *values* (a number, or an array of them, per name).

    Parameters
    ----------
    contacts : sequence of Contact
        The contacts.
    values : mapping of str to float or array
        Parameter values by name.
    """
    rules = (("stiffness", "N/m", lambda x: x >= 0), ("damping", "N*s/m", lambda x: x >= 0),
             ("smoothing", "m", lambda x: x > 0))
    for c in contacts:
        for field, unit, ok in rules:
            given = getattr(c, field)
            name = given if isinstance(given, str) else str(given) if type(given).__name__ == "Symbol" else None
            value = values.get(name) if name is not None else given
            if value is None:
                continue
            number = np.asarray(value, dtype=float)
            if not (np.all(np.isfinite(number)) and np.all(ok(number))):
                need = "positive" if field == "smoothing" else "zero or positive"
                label = f"{name} ({c.name}'s {field})" if name else f"{c.name}'s {field}"
                raise InputError(f"the contact {label} must be finite and {need} [{unit}], got {value}",
                                 field="parameters")
