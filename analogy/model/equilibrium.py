"""Static equilibria: a model's elastic coordinates settled under gravity and preload, its joints held where they are."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..errors import InputError

__all__ = ["elastic_coordinates", "static_equilibrium"]


def elastic_coordinates(model) -> list[int]:
    """The coordinates (0-based) that carry a spring of the model's own: the rows of K that are not zero.

    Parameters
    ----------
    model : Model or CompiledModel
        A symbolic model, or one compiled from it.
    """
    return list(model.elastic)


def static_equilibrium(model, q: Sequence[float], parameters: Mapping[str, float] | None = None, *,
                       free: Sequence[int] | None = None, max_iter: int = 50) -> np.ndarray:
    """*q* with its *free* coordinates moved to where the static load G + K·(q − rest) vanishes on them.

    The other coordinates (the joints) stay where they are, held by the load that remains
    on them. Newton's method with the tangent stiffness K + ∂G/∂q, which the linearised
    model gives, converges quadratically from the undeformed pose.

    Parameters
    ----------
    model : Model
        A symbolic model (a flexible arm's modal coordinates are its elastic ones).
    q : sequence of float
        The pose; its free entries are the first guess.
    parameters : mapping, optional
        Parameter overrides.
    free : sequence of int, optional
        0-based coordinates to solve for; default :func:`elastic_coordinates`.
    max_iter : int
        Newton iterations before giving up.

    Raises
    ------
    InputError
        If nothing is free, or no equilibrium is found (the elastic coordinates alone
        unstable, or the load too large for the linearised springs to settle).
    """
    idx = np.asarray(elastic_coordinates(model) if free is None else list(free), dtype=int)
    if idx.size == 0:
        raise InputError("the model has no elastic coordinates to settle: a static equilibrium "
                         "needs springs of its own (a flexible link's modes)")
    x = np.array(q, dtype=float)
    for _ in range(max_iter):
        js = model.joint_space(x, parameters)
        if js.gravity is None or js.stiffness is None:
            return x
        residual = js.gravity[idx]
        tangent = js.stiffness[np.ix_(idx, idx)]
        try:
            step = np.linalg.solve(tangent, residual)
        except np.linalg.LinAlgError:
            break
        x[idx] -= step
        if np.max(np.abs(step)) <= 1e-14 * max(1.0, float(np.max(np.abs(x[idx])))):
            return x
    raise InputError("no static equilibrium found near the given pose: its elastic coordinates "
                     "do not settle (the springs are too weak for the load)")
