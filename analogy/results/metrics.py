"""The one error metric: max |x − x_ref| over time and channels, relative to the reference's peak."""

from __future__ import annotations

import numpy as np

__all__ = ["relative_error", "absolute_error", "peak", "errors"]


def peak(reference: np.ndarray, axis=None) -> np.ndarray | float:
    """max |x_ref| over *axis* (default all).

    Parameters
    ----------
    reference : array_like
        Reference values.
    axis : int or tuple of int, optional
        Axes to reduce; the others are kept (a stack of trajectories).
    """
    ref = np.asarray(reference, dtype=float)
    if ref.size == 0:
        return np.nan if axis is None else np.full(np.max(ref, axis=axis, initial=0).shape, np.nan)
    return np.max(np.abs(ref), axis=axis) if axis is not None else float(np.max(np.abs(ref)))


def absolute_error(values: np.ndarray, reference: np.ndarray, axis=None) -> np.ndarray | float:
    """max |x − x_ref| over *axis* (default all); NaN if there are no values.

    Parameters
    ----------
    values : array_like
        Values of the solver under test.
    reference : array_like
        Reference values, of the same shape.
    axis : int or tuple of int, optional
        Axes to reduce.
    """
    x, ref = np.asarray(values, dtype=float), np.asarray(reference, dtype=float)
    if x.shape != ref.shape:
        raise ValueError(f"values of shape {x.shape} cannot be compared with a reference of shape {ref.shape}")
    if x.size == 0:
        return np.nan
    err = np.abs(x - ref)
    return np.max(err, axis=axis) if axis is not None else float(np.max(err))


def errors(values: np.ndarray, reference: np.ndarray, axis=None) -> tuple:
    """(max |x − x_ref|, that / max |x_ref|) in one pass: :func:`relative_error` and its numerator.

    Parameters
    ----------
    values : array_like
        Values of the solver under test.
    reference : array_like
        Reference values, of the same shape.
    axis : int or tuple of int, optional
        Axes to reduce; default all.
    """
    err = absolute_error(values, reference, axis)
    top = peak(reference, axis)
    err_a, top_a = np.asarray(err, dtype=float), np.asarray(top, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(top_a > 0, err_a / np.where(top_a > 0, top_a, 1.0), np.where(err_a == 0, 0.0, np.inf))
    rel = np.where(np.isnan(err_a), np.nan, rel)
    return (err, float(rel)) if rel.ndim == 0 else (err_a, rel)


def relative_error(values: np.ndarray, reference: np.ndarray, axis=None) -> np.ndarray | float:
    """max |x − x_ref| / max |x_ref|: the error every report and test uses.

    A zero peak (the reference is identically zero) is handled explicitly: the
    relative error is 0 where the values are exactly zero too, and inf otherwise,
    since no relative bound can hold against a zero reference.

    Parameters
    ----------
    values : array_like
        Values of the solver under test.
    reference : array_like
        Reference values, of the same shape.
    axis : int or tuple of int, optional
        Axes to reduce (e.g. ``(1, 2)`` for a stack of (time, joint) arrays); default all.
    """
    return errors(values, reference, axis)[1]
