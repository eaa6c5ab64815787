"""The dynamics protocol every node system follows: M'(x)·dv/dt = i(t) − B'·v − K'·x − h(x, v, t)."""

from __future__ import annotations

from typing import (
    Any,
    Callable,
    Iterator,
    Literal,
    NamedTuple,
    Protocol,
    runtime_checkable,
)

import numpy as np

__all__ = ["DynamicsKind", "DYNAMICS", "NodeDynamics", "MechanicalFunctions", "ContactFunctions"]

#: The kinds of node dynamics: constant M', B', K' with h = 0, or configuration-dependent.
DynamicsKind = Literal["linear", "nonlinear"]
DYNAMICS: tuple[DynamicsKind, ...] = ("linear", "nonlinear")


@runtime_checkable
class NodeDynamics(Protocol):
    """Dynamics in node coordinates v = T·r, x = ∫v, read by every solver.

    ``M'(x)·dv/dt = i(t) − B'·v − K'·x − h(x, v, t)``, with node currents
    i = T⁻ᵀ·F(t). A linear system has constant M' and h = 0; a nonlinear one gives
    M'(x) and h (velocity terms, gravity) from its model. x is measured from the
    configuration the system was built at, so x(0) = 0.
    """

    kind: DynamicsKind
    topology: Any
    forces: tuple
    t_stop: float
    provenance: Any
    damping: np.ndarray
    stiffness: np.ndarray | None

    @property
    def dof(self) -> int: ...

    @property
    def nodes(self) -> list[str]: ...

    @property
    def initial_voltages(self) -> np.ndarray: ...

    def node_mass(self, x: np.ndarray) -> np.ndarray:
        """M'(x), shape (n, n).

        Parameters
        ----------
        x : ndarray
            Node positions.
        """

    def node_load(self, x: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """h(x, v, t), shape (n,): zero for a linear system.

        Parameters
        ----------
        x : ndarray
            Node positions.
        v : ndarray
            Node velocities.
        t : float
            Time.
        """

    def node_currents(self, t) -> np.ndarray:
        """i(t) = T⁻ᵀ·F(t), shape (len(t), n).

        Parameters
        ----------
        t : float or array_like
            Times.
        """

    def joint_rates(self, node_voltages: np.ndarray) -> np.ndarray:
        """R = T⁻¹·v for node voltages of shape (..., n).

        Parameters
        ----------
        node_voltages : ndarray, shape (..., n)
            Node velocities v.
        """

    def time_points(self, times=None, default: int = 1001) -> np.ndarray:
        """Sorted output times in [0, t_stop].

        Parameters
        ----------
        times : array_like, optional
            Requested times.
        default : int
            Number of uniform points without *times*.
        """

    def segments(self) -> Iterator[tuple[float, float]]:
        """Intervals on which every force is one closed form."""


class ContactFunctions(NamedTuple):
    """Compiled contact forces of a model (:mod:`analogy.model.contact`), at fixed parameters.

    *generalised* (q, q̇) gives τ_c = Σ J_cᵀ·f_c, shape (n,), or (n, m) for states stacked as columns
    (n, m); *derivatives* (q, q̇) gives
    (∂τ_c/∂q, ∂τ_c/∂q̇), each (n, n); *normal* takes q and q̇ of shape (n,) or (n, m) and gives
    each contact's normal force f_c, shape (k,) or (k, m); *depths* takes q of shape (n, m) and
    gives each contact's penetration p = −y, (k, m); *names* are the contacts', *smoothing*
    their switch lengths δ [m].
    """

    generalised: Callable[[np.ndarray, np.ndarray], np.ndarray]
    derivatives: Callable[[np.ndarray, np.ndarray], tuple]
    normal: Callable[[np.ndarray, np.ndarray], np.ndarray]
    depths: Callable[[np.ndarray], np.ndarray]
    names: tuple
    smoothing: tuple


class MechanicalFunctions(NamedTuple):
    """Compiled functions of a configuration-dependent model, at fixed parameters.

    Each takes numeric q (and q̇) of shape (n,) and returns an array: M(q) (n, n),
    c(q, q̇) (n,), G(q) (n,) or None, and the constant B and K (None without springs).
    *derivatives* (q, q̇) gives (∂M/∂q_k stacked on the first axis, ∂c/∂q, ∂c/∂q̇, ∂G/∂q),
    for analytic Jacobians; None where the model does not provide them. *masses* and
    *gravities* take a stack of poses (p, n) at once, where the model has them (energy
    residuals along a trajectory of many points).

    *forward* (q, q̇, τ) gives q̈ = M(q)⁻¹·(τ − c(q, q̇) − G(q)) in one call, where the model
    has a forward dynamics cheaper than forming M and solving (an articulated-body algorithm,
    or one kinematics pass shared by M, c and G); B and K are not in it. *potential* takes a
    stack of poses (p, n) and gives gravity's potential energy U with G = ∂U/∂q, so that
    gravity's work is U(q0) − U(q) rather than an integral of G. *contacts* are the ground's
    forces on the model's contact points (None without contacts): not in c, G or *forward*.
    """

    mass: Callable[[np.ndarray], np.ndarray]
    velocity: Callable[[np.ndarray, np.ndarray], np.ndarray]
    gravity: Callable[[np.ndarray], np.ndarray] | None
    damping: np.ndarray
    stiffness: np.ndarray | None
    derivatives: Callable | None = None
    masses: Callable[[np.ndarray], np.ndarray] | None = None
    gravities: Callable[[np.ndarray], np.ndarray] | None = None
    forward: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None
    potential: Callable[[np.ndarray], np.ndarray] | None = None
    contacts: ContactFunctions | None = None
