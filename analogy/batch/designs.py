"""Sweep designs: points of the unit cube by index (grid, seeded random, Latin hypercube, Sobol), streamed."""

from __future__ import annotations

import warnings
from typing import Literal, Sequence

import numpy as np

from ..errors import InputError

__all__ = ["DESIGNS", "DesignName", "design_points", "index_permutation"]

DesignName = Literal["grid", "random", "lhs", "sobol"]
DESIGNS: tuple[str, ...] = ("grid", "random", "lhs", "sobol")

# Random and LHS draws come in fixed blocks, so that point i never depends on how a run is cut up.
_BLOCK = 4096
_ROUNDS = 6


def _mix(x: np.ndarray, key: np.ndarray) -> np.ndarray:
    """A keyed mixing of 64-bit words (splitmix64's finaliser on x XOR key)."""
    z = x ^ key
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def index_permutation(indices, count: int, seed: int, stream: int = 0) -> np.ndarray:
    """A seeded permutation π of range(*count*), evaluated at *indices* without holding it.

    A balanced Feistel network permutes the smallest power of 4 at or above *count*;
    values at or past *count* walk on (cycle walking), so π is a bijection of
    range(*count*) and costs O(1) memory whatever *count* is.

    Parameters
    ----------
    indices : array_like of int
        Points of range(*count*).
    count : int
        Size of the permuted range.
    seed : int
        Seed of the permutation.
    stream : int
        Which of the seed's permutations (one per sweep axis).
    """
    half = max(1, int(np.ceil(np.log2(max(count, 2)) / 2)))
    mask = np.uint64((1 << half) - 1)
    keys = np.random.default_rng([seed, stream, 0x5EED]).integers(0, 2**63, _ROUNDS, dtype=np.uint64)
    x = np.asarray(indices, dtype=np.uint64).copy()
    todo = np.ones(x.shape, dtype=bool)
    with np.errstate(over="ignore"):
        while todo.any():
            left, right = x[todo] >> np.uint64(half), x[todo] & mask
            for key in keys:
                left, right = right, left ^ (_mix(right, key) & mask)
            x[todo] = (left << np.uint64(half)) | right
            todo[todo] = x[todo] >= np.uint64(count)
    return x.astype(np.int64)


def _random_block(seed: int, block: int, dims: int) -> np.ndarray:
    return np.random.default_rng([seed, block]).random((_BLOCK, dims))


def _blocked(start: int, stop: int, seed: int, dims: int) -> np.ndarray:
    """Uniform draws for points start..stop-1, each block of points from its own seeded stream."""
    out = np.empty((stop - start, dims))
    for block in range(start // _BLOCK, (stop - 1) // _BLOCK + 1):
        lo, hi = max(start, block * _BLOCK), min(stop, (block + 1) * _BLOCK)
        out[lo - start:hi - start] = _random_block(seed, block, dims)[lo - block * _BLOCK:hi - block * _BLOCK]
    return out


def design_points(method: str, start: int, stop: int, *, count: int, seed: int = 0,
                  shape: Sequence[int] = ()) -> np.ndarray:
    """Points *start* to *stop* − 1 of a design with *count* points in all.

    For ``"grid"`` the result holds integer indices into each axis's values (the last
    axis fastest, as :func:`numpy.unravel_index`); otherwise numbers in [0, 1) per axis,
    and the same index gives the same point however the run is divided.

    Parameters
    ----------
    method : {"grid", "random", "lhs", "sobol"}
        The design: the full grid of *shape*; independent uniform draws; a Latin
        hypercube (each axis cut into *count* strata, each stratum hit once); or a
        scrambled Sobol' sequence (:class:`scipy.stats.qmc.Sobol`).
    start, stop : int
        Range of point indices.
    count : int
        Points in the whole design.
    seed : int
        Seed of the random designs.
    shape : sequence of int
        Number of values per axis (its length is the number of axes).
    """
    dims = len(shape)
    if not 0 <= start <= stop <= count:
        raise InputError(f"points {start}..{stop} are outside a design of {count}")
    if stop == start:
        return np.empty((0, dims), dtype=int if method == "grid" else float)
    if method == "grid":
        return np.stack(np.unravel_index(np.arange(start, stop), tuple(shape)), axis=1)
    if method == "random":
        return _blocked(start, stop, seed, dims)
    if method == "lhs":
        jitter = _blocked(start, stop, seed, dims)
        idx = np.arange(start, stop)
        strata = np.stack([index_permutation(idx, count, seed, axis) for axis in range(dims)], axis=1)
        return (strata + jitter) / count
    if method == "sobol":
        from scipy.stats import qmc
        engine = qmc.Sobol(dims, scramble=True, seed=seed)
        if start:
            engine.fast_forward(start)
        with warnings.catch_warnings():         # balance needs 2^k points; the docs say so
            warnings.simplefilter("ignore", UserWarning)
            return engine.random(stop - start)
    raise InputError(f"unknown sweep method {method!r}: use {', '.join(DESIGNS)}")
