"""Linear algebra on stacks of small matrices, entry by entry over the stack rather than one LAPACK call per matrix."""

from __future__ import annotations

import numpy as np

__all__ = ["SMALL", "matmul", "cholesky", "solve_lower", "whiten", "eigh", "eigvalsh", "axis_sum", "axis_max"]

#: Up to this size, a stack's products, Cholesky factors and triangular solves are loops over the
#: entries, each one numpy pass over the stack. numpy's stacked ``linalg`` calls LAPACK once per
#: matrix (about 0.2 to 0.6 µs each) and reduces a short axis row by row (55 ns a row); for a
#: stack of 1,000 2×2 matrices a pass is about 2 µs, and (measured on a loaded 2-core machine) a
#: Cholesky factor took 47 to 56 µs against 170, a solve 26 against 300, and ``eigh`` 118 to 125
#: against 580. Past it the loops' passes (about n³/3) cost more than the calls.
SMALL = 4


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` over broadcast leading axes, entry by entry where the matrices are small.

    Parameters
    ----------
    a : ndarray, shape (..., n, k)
        Left factors.
    b : ndarray, shape (..., k, m)
        Right factors.
    """
    (n, k), m = a.shape[-2:], b.shape[-1]
    if max(n, k, m) > SMALL or k == 0:     # long rows (a state over time): numpy's own loop is faster
        return a @ b
    out = np.empty(np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + (n, m), dtype=np.result_type(a, b))
    for i in range(n):
        for j in range(m):
            entry = a[..., i, 0] * b[..., 0, j]
            for h in range(1, k):
                entry = entry + a[..., i, h] * b[..., h, j]
            out[..., i, j] = entry
    return out


def axis_sum(x: np.ndarray, axis: int) -> np.ndarray:
    """``x.sum(axis)``, added slice by slice where that axis is short (of numbers: booleans would add as
    logical or, and small integers keep their type, so count in a wide enough one).

    Parameters
    ----------
    x : ndarray
        Values.
    axis : int
        The axis summed over.
    """
    return _by_slices(x, axis, np.add) if 0 < x.shape[axis] <= SMALL else x.sum(axis=axis)


def axis_max(x: np.ndarray, axis: int) -> np.ndarray:
    """``x.max(axis)``, taken slice by slice where that axis is short (NaN wins, as there).

    Parameters
    ----------
    x : ndarray
        Values.
    axis : int
        The axis maximised over.
    """
    return _by_slices(x, axis, np.maximum) if 0 < x.shape[axis] <= SMALL else x.max(axis=axis)


def _by_slices(x: np.ndarray, axis: int, ufunc: np.ufunc) -> np.ndarray:
    """*ufunc* folded over the slices of *x* along *axis*: always a new array, never a view of x."""
    index = (slice(None),) * (axis % x.ndim)
    out = x[index + (0,)]
    for j in range(1, x.shape[axis]):
        out = ufunc(out, x[index + (j,)])
    return out if x.shape[axis] > 1 else out.copy()


def cholesky(a: np.ndarray) -> np.ndarray:
    """The lower Cholesky factors of a stack of symmetric positive-definite matrices (lower triangles read).

    Raises :class:`numpy.linalg.LinAlgError` as :func:`numpy.linalg.cholesky` does when a pivot is
    not positive (or NaN).

    Parameters
    ----------
    a : ndarray, shape (..., n, n)
        The matrices.
    """
    n = a.shape[-1]
    if n > SMALL:
        return np.linalg.cholesky(a)
    a = np.asarray(a, dtype=float)
    low = np.zeros_like(a)
    for j in range(n):
        pivot = a[..., j, j]
        for k in range(j):
            pivot = pivot - low[..., j, k] * low[..., j, k]
        if not np.all(pivot > 0):
            raise np.linalg.LinAlgError("Matrix is not positive definite")
        root = low[..., j, j] = np.sqrt(pivot)
        for i in range(j + 1, n):
            entry = a[..., i, j]
            for k in range(j):
                entry = entry - low[..., i, k] * low[..., j, k]
            low[..., i, j] = entry / root
    return low


def solve_lower(low: np.ndarray, b: np.ndarray, transposed: bool = False) -> np.ndarray:
    """X with L·X = B by forward substitution, or with Lᵀ·X = B by back substitution, for lower-triangular L.

    Parameters
    ----------
    low : ndarray, shape (..., n, n)
        Lower-triangular factors with nonzero diagonals.
    b : ndarray, shape (..., n, m)
        Right-hand sides.
    transposed : bool
        Solve with Lᵀ.
    """
    n, m = low.shape[-1], b.shape[-1]
    if max(n, m) > SMALL:
        return np.linalg.solve(np.swapaxes(low, -1, -2) if transposed else low, b)
    out = np.empty(np.broadcast_shapes(low.shape[:-2], b.shape[:-2]) + (n, m), dtype=np.result_type(low, b))
    order = range(n - 1, -1, -1) if transposed else range(n)
    for j in range(m):
        for i in order:
            entry = b[..., i, j]
            for k in (range(i + 1, n) if transposed else range(i)):
                entry = entry - (low[..., k, i] if transposed else low[..., i, k]) * out[..., k, j]
            out[..., i, j] = entry / low[..., i, i]
    return out


def whiten(low: np.ndarray, a: np.ndarray) -> np.ndarray:
    """L⁻¹·A·L⁻ᵀ of a stack of symmetric A: A in the frame where L·Lᵀ is the identity (M' whitened).

    Parameters
    ----------
    low : ndarray, shape (..., n, n)
        Lower-triangular factors with nonzero diagonals.
    a : ndarray, shape (..., n, n)
        Symmetric matrices.
    """
    return solve_lower(low, np.swapaxes(solve_lower(low, a), -1, -2))


def eigh(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (ascending) and orthonormal eigenvectors (columns) of a stack of symmetric matrices,
    lower triangles read, as :func:`numpy.linalg.eigh`.

    A 2×2 matrix is diagonalised by one Jacobi rotation (Golub and Van Loan's ``sym.schur2``),
    whose eigenvalues are within a few ε·‖A‖ of the true ones, as LAPACK's are; other sizes go to
    numpy. An eigenvector's sign is not that of LAPACK's.

    Parameters
    ----------
    a : ndarray, shape (..., n, n)
        The matrices.
    """
    n = a.shape[-1]
    if n == 1:
        return np.array(a[..., 0], dtype=float), np.ones_like(a, dtype=float)
    if n != 2:
        return np.linalg.eigh(a)
    p, q, r = a[..., 0, 0], a[..., 1, 0], a[..., 1, 1]
    coupled = q != 0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        tau = (0.5 * r - 0.5 * p) / np.where(coupled, q, 1.0)         # halves first: r − p may overflow
        # the smaller root of t² + 2τ·t − 1 = 0; hypot, since τ² may overflow
        t = np.where(coupled, np.where(tau >= 0, 1.0, -1.0) / (np.abs(tau) + np.hypot(1.0, tau)), 0.0)
    c = 1 / np.hypot(1.0, t)
    s = t * c
    first, second = p - t * q, r + t * q        # for the columns (c, −s) and (s, c)
    swap = first > second
    values = np.stack([np.where(swap, second, first), np.where(swap, first, second)], axis=-1)
    vectors = np.empty(a.shape, dtype=float)
    vectors[..., 0, 0] = vectors[..., 1, 1] = np.where(swap, s, c)
    vectors[..., 1, 0] = np.where(swap, c, -s)
    vectors[..., 0, 1] = np.where(swap, -c, s)
    return values, vectors


def eigvalsh(a: np.ndarray) -> np.ndarray:
    """The eigenvalues (ascending) of a stack of symmetric matrices, lower triangles read: :func:`eigh`'s
    for 2×2, :func:`numpy.linalg.eigvalsh`'s otherwise.

    Parameters
    ----------
    a : ndarray, shape (..., n, n)
        The matrices.
    """
    return eigh(a)[0] if a.shape[-1] <= 2 else np.linalg.eigvalsh(a)
