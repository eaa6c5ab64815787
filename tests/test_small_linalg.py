"""Stacked small-matrix algebra: the entry-by-entry loops agree with LAPACK to rounding."""

import numpy as np
import pytest

from analogy import small_linalg as sl
from analogy.solvers.exact import _decay_minus_one

EPS = np.finfo(float).eps


def _spd(rng, count, n):
    a = rng.standard_normal((count, n, n))
    return a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6])
def test_cholesky_and_substitutions_are_lapacks_to_rounding(n):
    rng = np.random.default_rng(n)
    m, b = _spd(rng, 200, n), rng.standard_normal((200, n, 3))
    low = sl.cholesky(m)
    # backward stable: L·Lᵀ reproduces M to a few n·ε·‖M‖
    scale = np.abs(m).max(axis=(1, 2))[:, None, None]
    assert np.all(np.abs(low @ np.swapaxes(low, 1, 2) - m) <= 4 * n * EPS * scale)
    assert np.all(np.triu(low, 1) == 0)
    cond = np.linalg.cond(low)[:, None, None]
    for got, want in ((sl.solve_lower(low, b), np.linalg.solve(low, b)),
                      (sl.solve_lower(low, b, transposed=True), np.linalg.solve(np.swapaxes(low, 1, 2), b))):
        # two backward-stable solves differ by up to n·ε·cond(L) of the solution
        assert np.all(np.abs(got - want) <= 4 * n * EPS * cond * np.abs(want).max(axis=(1, 2))[:, None, None])


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_products_sums_and_maxima_are_numpys(n):
    rng = np.random.default_rng(10 + n)
    a, b, shared = rng.standard_normal((50, n, n)), rng.standard_normal((50, n, 2)), rng.standard_normal((n, 2))
    for right in (b, shared):
        # the same n products summed in another order: each within n·ε/2 of Σ|a||b| (γ_n), so n·ε apart
        assert np.all(np.abs(sl.matmul(a, right) - a @ right) <= n * EPS * (np.abs(a) @ np.abs(right)))
    assert np.array_equal(sl.axis_max(a, 1), a.max(axis=1))
    assert np.allclose(sl.axis_sum(a, 2), a.sum(axis=2), rtol=n * EPS, atol=0)
    # like numpy's, a reduction is a new array, even over an axis of one entry
    assert not np.shares_memory(sl.axis_sum(a, 2), a) and not np.shares_memory(sl.axis_max(a, 1), a)


def test_a_matrix_that_is_not_positive_definite_is_refused_as_lapack_refuses_it():
    m = np.array([[[1.0, 0.0], [0.0, 1.0]], [[1.0, 2.0], [2.0, 1.0]]])
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(m)
    with pytest.raises(np.linalg.LinAlgError):
        sl.cholesky(m)
    with pytest.raises(np.linalg.LinAlgError):
        sl.cholesky(np.array([[[np.nan, 0.0], [0.0, 1.0]]]))


def test_two_by_two_eigenpairs_hold_the_eigen_equation_to_rounding():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((2000, 2, 2)) * 10.0 ** rng.uniform(-8, 8, (2000, 1, 1))
    a = a + np.swapaxes(a, 1, 2)
    edge = np.array([[[1.0, 0.0], [0.0, 2.0]], [[2.0, 0.0], [0.0, 1.0]], [[3.0, 1.0], [1.0, 3.0]],
                     [[1.0, 1e-300], [1e-300, 1.0]], [[1e300, 1.0], [1.0, -1e300]], [[0.0, 0.0], [0.0, 0.0]],
                     [[-1e308, 1e308], [1e308, 1e308]], [[1.0, 1e-309], [1e-309, 2.0]]])
    a = np.concatenate([a, edge])
    values, vectors = sl.eigh(a)
    norm = np.abs(a).max(axis=(1, 2))[:, None, None]
    assert np.all(values[:, 0] <= values[:, 1])
    # one Jacobi rotation: residual and orthonormality at a few ε·‖A‖ and ε, as LAPACK's
    assert np.all(np.abs(a @ vectors - vectors * values[:, None, :]) <= 8 * EPS * norm)
    assert np.all(np.abs(np.swapaxes(vectors, 1, 2) @ vectors - np.eye(2)) <= 8 * EPS)
    assert np.all(np.abs(values - np.linalg.eigvalsh(a)) <= 8 * EPS * norm[:, :, 0])
    assert np.array_equal(sl.eigvalsh(a), values)


def test_a_fast_modes_decay_is_expm1_to_an_absolute_few_eps_and_a_slow_ones_is_expm1():
    lam = np.array([[-50.0, -0.01], [-2.0, -1e-9]])
    tau = np.linspace(0.0, 1.0, 301)
    x = lam[:, :, None] * tau
    got = _decay_minus_one(x.copy(), lam * 1.0)
    want = np.expm1(x)
    fast = np.abs(lam) >= 1
    # fl(eˣ) − 1 errs by 1.5·ε at most where x ≤ 0 (its value lies in [−1, 0])
    assert np.all(np.abs(got[fast] - want[fast]) <= 1.5 * EPS)
    assert np.array_equal(got[~fast], want[~fast])      # the slow modes keep their relative accuracy
