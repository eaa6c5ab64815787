"""The nonlinear circuit of a robot: charge-defined capacitors d(c(x)·Δv)/dt, behavioural forces, integrators.

In node coordinates the Lagrangian is L = ½·vᵀM'(x)v − U(x), and the Lagrange
equations read

    d/dt(M'(x)·v) − ½·vᵀ(∂M'/∂x_a)v + ∂U/∂x_a + (K'x)_a + (B'v)_a = i_a.

Split as M' is split into elements (grounded c_a = Σ_j M'_aj, floating
c_ab = −M'_ab), the first term is the sum of the currents d(c·(v_a − v_b))/dt of
charge-defined capacitors, Q = c(x)·(v_a − v_b). ngspice's ``Q=`` form gives exactly
that current (its ``C=`` form gives c(x)·dv/dt and misses dc/dt·Δv) but starts from
zero charge whatever ``.ic`` says; so a charge with Q(0) ≠ 0 (the arm moving at t = 0)
is written as a follower whose 1 F capacitor starts at Q(0) (see
:class:`~analogy.circuit.parts.ChargeCapacitor`). The second and
third terms are one behavioural current per node, h_a(x, v), drawn out of the node;
springs stay inductors and dampers resistors; x_a = ∫v_a comes from an integrator
node per joint.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import sympy as sp
from sympy.printing.str import StrPrinter

from ..errors import InputError
from .elements import ZERO_TOL, Element, element_table, spice_value
from .parts import (
    BehaviouralCurrent,
    BehaviouralVoltage,
    ChargeCapacitor,
    Circuit,
    Integrator,
    comments,
    current_sources,
)
from .tree_lagrangian import tree_lagrangian

__all__ = ["NodeLagrangian", "node_lagrangian", "nonlinear_circuit", "spice_text"]


class NodeLagrangian(NamedTuple):
    """The nonlinear node dynamics as sympy expressions in node positions x and rates v."""

    x: list
    v: list
    mass: sp.Matrix          # M'(x)
    load: sp.Matrix          # h(x, v) = −½·vᵀ(∂M'/∂x_a)v + (T⁻ᵀG)_a
    shared: tuple = ()       # (symbol, expression) pairs the others use, in evaluation order

    def values(self, x, v) -> dict:
        """Every symbol's value at node positions *x* and rates *v*, the shared ones evaluated in order.

        Parameters
        ----------
        x, v : sequence of float
            Node positions and rates.
        """
        values = {**dict(zip(self.x, map(float, x))), **dict(zip(self.v, map(float, v)))}
        for symbol, e in self.shared:
            values[symbol] = float(e.xreplace(values))
        return values


def node_lagrangian(system) -> NodeLagrangian:
    """M'(x) and h(x, v) of a nonlinear node system, derived from its symbolic model.

    A symbolic model's M(q) is written out; a rigid tree's (URDF robots) comes from
    :func:`~analogy.circuit.tree_lagrangian.tree_lagrangian`, in shared subexpressions.

    Parameters
    ----------
    system : NonlinearNodeSystem
        A system built from a symbolic model or a rigid tree.
    """
    model = system.model
    if model is None:
        raise InputError("this nonlinear system has no symbolic model to write as a circuit")
    n = system.dof
    x = list(sp.symbols(f"x1:{n + 1}", real=True))
    v = list(sp.symbols(f"v1:{n + 1}", real=True))
    if model.rigid_tree:          # its recursions, one shared expression per quantity
        at = model.with_parameters(system.parameters)               # at the system's g, as its functions are
        return NodeLagrangian(x, v, *tree_lagrangian(at.tree, system.q0, system.topology.inverse, x, v,
                                                     at.contacts, at.parameters))
    subs = {sym: system.parameters[name] for name, sym in model.symbols.items()}
    tinv = sp.Matrix(np.asarray(system.topology.inverse).tolist())
    q = list(model.coordinates) or list(sp.symbols(f"q1:{n + 1}", real=True))
    at = {qk: float(q0) + sum(tinv[k, j] * x[j] for j in range(n)) for k, (qk, q0) in enumerate(zip(q, system.q0))}
    # xreplace: every key is a symbol, and subs' own matching costs 10 times more on a long chain
    mass = (tinv.T * model.mass_matrix.xreplace(subs) * tinv).xreplace(at)
    vv = sp.Matrix(v)
    load = sp.Matrix([-(vv.T * mass.diff(x[a]) * vv)[0] / 2 for a in range(n)])
    if model.gravity is not None:
        load += tinv.T * model.gravity.xreplace(subs).xreplace(at)
    shared = []
    if model.contacts:      # each normal force a node of its own (an output), drawn out through Jᵀ
        rates = {rk: sum(tinv[k, j] * v[j] for j in range(n)) for k, rk in enumerate(sp.symbols(f"qd1:{n + 1}"))}
        for c in model.contacts:
            force = sp.Symbol(f"f_{c.name}", real=True)
            shared.append((force, c.force(q, list(rates)).xreplace(subs).xreplace(at).xreplace(rates)))
            load -= tinv.T * c.normal(q).xreplace(subs).xreplace(at) * force
    return NodeLagrangian(x, v, mass, load, tuple(shared))


class _SpicePrinter(StrPrinter):
    """sympy to ngspice expressions: x_k as v(xk), v_k as v(nk), numbers at full precision."""

    _FUNCTIONS = {"sin": "sin", "cos": "cos", "tan": "tan", "asin": "asin", "acos": "acos",
                  "atan": "atan", "sinh": "sinh", "cosh": "cosh", "tanh": "tanh", "exp": "exp",
                  "log": "ln", "sqrt": "sqrt", "Abs": "abs"}

    def __init__(self, names):
        super().__init__({"full_prec": True})
        self.names = names

    def _print_Symbol(self, expr):
        if expr in self.names:
            return self.names[expr]
        raise InputError(f"symbol {expr} has no value in the circuit")

    def _print_Float(self, expr):
        return repr(float(expr))

    def _print_Rational(self, expr):
        return repr(float(expr))

    def _print_Integer(self, expr):
        return repr(float(expr))

    def _print_Pow(self, expr, rational=False):
        base, exp = expr.as_base_exp()
        if exp == sp.Rational(1, 2):
            return f"sqrt({self._print(base)})"
        if exp.is_Integer and 0 < abs(int(exp)) <= 8:
            product = "*".join([f"({self._print(base)})"] * abs(int(exp)))
            return f"(1.0/({product}))" if exp < 0 else f"({product})"
        return f"pow({self._print(base)}, {self._print(exp)})"

    def _print_Function(self, expr):
        name = self._FUNCTIONS.get(type(expr).__name__)
        if name is None:
            raise InputError(f"function {type(expr).__name__} has no ngspice equivalent")
        return f"{name}({', '.join(self._print(a) for a in expr.args)})"

    _print_Abs = _print_Function

    def _print_Pi(self, expr):
        return repr(float(sp.pi))

    def _print_Exp1(self, expr):
        return repr(float(sp.E))


def spice_text(expr, lagrangian: NodeLagrangian) -> str:
    """*expr* (in x and v) as an ngspice expression of the node voltages v(x1)…, v(n1)….

    Parameters
    ----------
    expr : sympy expression
        An expression in the system's node positions and rates.
    lagrangian : NodeLagrangian
        The system's symbols.
    """
    names = {s: f"v(x{k + 1})" for k, s in enumerate(lagrangian.x)}
    names.update({s: f"v(n{k + 1})" for k, s in enumerate(lagrangian.v)})
    names.update({s: f"v({s.name})" for s, _ in lagrangian.shared})
    return _SpicePrinter(names).doprint(expr)


def nonlinear_circuit(system, zero_tol: float = ZERO_TOL, describe: bool = True) -> Circuit:
    """The circuit whose nodal equations are the system's Lagrange equations.

    Parameters
    ----------
    system : NonlinearNodeSystem
        A system built from a symbolic model.
    zero_tol : float
        Relative tolerance under which a damper or spring is left out.
    describe : bool
        Fill :attr:`Circuit.comments`, for netlist headers.
    """
    lag = node_lagrangian(system)
    n = system.dof
    v0 = system.initial_voltages
    at_start = lag.values(np.zeros(n), v0)

    def charge(c, a, b):
        """Q = c(x)·(v_a − v_b) as text, and its value at t = 0."""
        across = f"v(n{a})" if b == 0 else f"(v(n{a})-v(n{b}))"
        q0 = float(c.xreplace(at_start)) * (v0[a - 1] - (v0[b - 1] if b else 0.0))
        name = f"{a}" if b == 0 else f"{a}_{b}"
        return ChargeCapacitor(name, a, b, f"({spice_text(c, lag)})*{across}", q0)

    contacts = {f"f_{c.name}" for c in getattr(system.model, "contacts", ()) or ()}
    parts = [BehaviouralVoltage(str(symbol), spice_text(e, lag), at_start[symbol], str(symbol) in contacts)
             for symbol, e in lag.shared]
    for a in range(n):                  # grounded c_a = Σ_j M'_aj, floating c_ab = −M'_ab
        c = sp.expand(sum(lag.mass[a, j] for j in range(n)))
        if c != 0:
            parts.append(charge(c, a + 1, 0))
    for a in range(n):
        for b in range(a + 1, n):
            c = sp.expand(-lag.mass[a, b])
            if c != 0:
                parts.append(charge(c, a + 1, b + 1))
    for a in range(n):                  # h_a is drawn out of node a: driven from a to ground
        h = lag.load[a]
        if h != 0:
            parts.append(BehaviouralCurrent(f"h{a + 1}", 0, a + 1, spice_text(h, lag)))
    parts += [Integrator(a + 1) for a in range(n)]
    k = None if system.stiffness is None else system.stiffness[None]
    table = element_table(np.zeros((1, n, n)), system.damping[None], k, zero_tol)
    elements = tuple(Element(kind, a, b, float(spice_value(kind, c[0])), float(c[0]))
                     for kind, a, b, c in table if kind != "C" and c[0] != 0.0)
    initial = tuple([(f"n{i + 1}", float(x)) for i, x in enumerate(v0)] + [(f"x{i + 1}", 0.0) for i in range(n)]
                    + [(node, p.initial) for p in parts if isinstance(p, ChargeCapacitor) and p.initial != 0.0
                       for node in p.follower_nodes]
                    + [(p.name, p.initial) for p in parts if isinstance(p, BehaviouralVoltage)])
    return Circuit(n, elements, current_sources(system, zero_tol), initial, system.t_stop, (),
                   tuple(parts), comments(system) if describe else (),
                   system.provenance.robot)
