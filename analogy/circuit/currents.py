"""Element currents from node voltages: what each capacitor, resistor and inductor carries."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import InputError
from .description import circuit
from .elements import ZERO_TOL

__all__ = ["element_currents", "trajectory_currents", "check_element_names"]


def check_element_names(system, names: Sequence[str], zero_tol: float = ZERO_TOL) -> tuple[str, ...]:
    """*names* in their canonical spelling, checked against the circuit of *system*.

    Parameters
    ----------
    system : NodeSystem
        The system whose circuit's elements may be named.
    names : sequence of str
        Element names, in any case.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    found = {e.name.lower(): e.name for e in circuit(system, zero_tol).parts}
    out = []
    for name in names:
        canonical = found.get(name.lower()) if isinstance(name, str) else None
        if canonical is None:
            raise InputError(f"unknown element {name!r}: elements are {', '.join(found.values())}")
        out.append(canonical)
    if not out:
        raise InputError("name at least one element (or write true for all)")
    return tuple(dict.fromkeys(out))


def element_currents(system, time: np.ndarray, voltages: np.ndarray, positions: np.ndarray | None,
                     names: Sequence[str] | None = None, zero_tol: float = ZERO_TOL) -> dict[str, np.ndarray]:
    """Element currents from node voltages v (and positions x, with springs).

    A capacitor carries c·d(v_a − v_b)/dt with dv/dt = M'⁻¹·(i(t) − B'·v − K'·x), a
    resistor (v_a − v_b)/R and an inductor (x_a − x_b)/L: the current from terminal a
    to terminal b, as SPICE reports it for a device ``name a b value``.

    Parameters
    ----------
    system : NodeSystem
        A linear system.
    time : ndarray, shape (N,)
        Time points.
    voltages : ndarray, shape (N, n)
        Node voltages v.
    positions : ndarray, shape (N, n), or None
        Node positions x = ∫v; needed for capacitor and inductor currents with springs.
    names : sequence of str, optional
        Element names (default all).
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    by_name = {e.name: e for e in circuit(system, zero_tol).parts}
    wanted = list(by_name) if names is None else list(check_element_names(system, names, zero_tol))
    chosen = [by_name[name] for name in wanted]
    t, v, x = time, voltages, positions
    needs_x = system.stiffness is not None and any(e.kind in "CL" for e in chosen)
    if needs_x and x is None:
        raise InputError("capacitor and inductor currents of a system with springs need the "
                         "positions x = ∫v: solve with positions=True")
    dv = None
    if any(e.kind == "C" for e in chosen):
        rhs = system.node_currents(t) - v @ system.damping.T
        if system.stiffness is not None:
            rhs = rhs - x @ system.stiffness.T
        dv = np.linalg.solve(system.mass, rhs.T).T

    def across(arr, e):
        return arr[:, e.a - 1] - (arr[:, e.b - 1] if e.b else 0.0)

    out = {}
    for e in chosen:
        if e.kind == "C":
            out[e.name] = e.value * across(dv, e)
        elif e.kind == "R":
            out[e.name] = across(v, e) / e.value
        else:
            out[e.name] = across(x, e) / e.value
    return out


def trajectory_currents(system, trajectory, names: Sequence[str] | None = None,
                        zero_tol: float = ZERO_TOL) -> dict[str, np.ndarray]:
    """:func:`element_currents` on a solver's trajectory (positions needed with springs).

    Parameters
    ----------
    system : NodeSystem
        A linear system.
    trajectory : Trajectory
        Node voltages on its time points; with springs, :attr:`Trajectory.positions` too.
    names : sequence of str, optional
        Element names (default all).
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    return element_currents(system, trajectory.time, trajectory.voltages, trajectory.positions,
                            names, zero_tol)
