"""The one error metric: per output, max |x − x_ref| over time relative to that output's own peak."""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

__all__ = ["relative_error", "absolute_error", "peak", "errors", "output_errors", "stack_errors", "OutputErrors", "PEAK_FLOOR",
           "REFERENCE_ROUNDING", "judged_peaks"]

#: An output whose own peak is under this fraction of the largest output's is judged against
#: this fraction instead: below it the reference itself is rounding (the exact and reference
#: solvers reach about 1e-12 of the largest peak, n·ε·cond(M')), so no relative figure exists.
PEAK_FLOOR = 1e-10
#: How close the references come to the truth, as a fraction of the largest output's peak: the exact
#: solver agrees with mpmath's matrix exponential and with the reference to 1e-12 of it
#: (tests/test_solvers.py). Judged against a bound, an output's peak is floored at
#: REFERENCE_ROUNDING / bound of the largest, so that no bound asks a solver to come closer to the
#: reference than the reference is to the truth (at 1e-6: 1e-12 of the largest peak, absolute).
REFERENCE_ROUNDING = 1e-12


def judged_peaks(own: np.ndarray, top: np.ndarray, bound: float | None = None, rounding=0.0) -> np.ndarray:
    """The peak each output's error is divided by: its own, floored at :data:`PEAK_FLOOR` of the
    largest output's peak *top* and, under a *bound*, at max(:data:`REFERENCE_ROUNDING`, *rounding*) /
    *bound* of it (at most all of it): no bound asks for an output closer than the circuit's own
    rounding allows.

    Parameters
    ----------
    own : ndarray
        Each output's own peak.
    top : ndarray
        The largest output's peak, broadcast against *own*.
    bound : float, optional
        The error bound the outputs are judged against (a preset's).
    rounding : float or ndarray
        How far the circuit's node map can move the outputs, as a fraction of the largest
        (:attr:`~analogy.circuit.topology.Topology.rounding`), broadcast against *top*.
    """
    if bound is None or not bound > 0:
        return np.maximum(own, PEAK_FLOOR * top)
    # at most the largest peak: a map rounding past the bound judges every output against the largest
    floor = np.minimum(np.maximum(PEAK_FLOOR, np.maximum(REFERENCE_ROUNDING, rounding) / bound), 1.0)
    return np.maximum(own, floor * top)


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


def output_errors(values: np.ndarray, reference: np.ndarray, bound: float | None = None,
                  rounding: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Per output (the last axis): max over time |x − x_ref| and that over the output's own peak.

    The peak of an output is max |x_ref| over time, floored as :func:`judged_peaks` says;
    an all-zero reference gives 0 where the values are zero too, inf elsewhere (as
    :func:`relative_error`).

    Parameters
    ----------
    values : array_like, shape (..., N, m)
        Values of the solver under test: N times, m outputs (a leading stack axis is kept).
    reference : array_like
        Reference values, of the same shape.
    bound : float, optional
        The bound the errors are judged against (see :data:`REFERENCE_ROUNDING`).
    rounding : float
        The node map's rounding (see :func:`judged_peaks`).
    """
    x, ref = np.asarray(values, dtype=float), np.asarray(reference, dtype=float)
    if x.shape != ref.shape:
        raise ValueError(f"values of shape {x.shape} cannot be compared with a reference of shape {ref.shape}")
    if x.shape[-2] == 0:
        nan = np.full(x.shape[:-2] + x.shape[-1:], np.nan)
        return nan, nan
    err = _time_max(np.abs(x - ref))
    own = _time_max(np.abs(ref))
    top = np.max(own, axis=-1, keepdims=True) if own.shape[-1] else own
    return err, _over(err, judged_peaks(own, top, bound, rounding))


def stack_errors(values: np.ndarray, reference: np.ndarray, bound: float | None = None,
                 rounding=0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`output_errors` of a stack (count, N, m) and, per row, the largest error over the largest
    output's peak (:func:`relative_error` over each row's times and outputs), from one pass.

    Parameters
    ----------
    values : array_like, shape (count, N, m)
        Values of the solver under test.
    reference : array_like
        Reference values, of the same shape.
    bound : float, optional
        The bound the errors are judged against (see :data:`REFERENCE_ROUNDING`).
    rounding : float or ndarray, shape (count,)
        Each row's node-map rounding (see :func:`judged_peaks`).
    """
    x, ref = np.asarray(values, dtype=float), np.asarray(reference, dtype=float)
    if x.shape != ref.shape:
        raise ValueError(f"values of shape {x.shape} cannot be compared with a reference of shape {ref.shape}")
    if x.shape[-2] == 0 or x.shape[-1] == 0:
        err, rel = output_errors(x, ref, bound)
        return err, rel, np.full(x.shape[0], np.nan)
    err, own = _time_max(np.abs(x - ref)), _time_max(np.abs(ref))
    top = np.max(own, axis=-1)
    # the maxima over times, then over outputs, are the maxima over both
    rows = np.reshape(np.asarray(rounding, dtype=float), (-1, 1))
    return err, _over(err, judged_peaks(own, top[:, None], bound, rows)), _over(np.max(err, axis=-1), top)


def _time_max(a: np.ndarray) -> np.ndarray:
    """max over the time axis (−2) of (..., N, m), NaN kept: reduced along contiguous memory, which
    for a few outputs is ten times faster than numpy's strided reduction."""
    return np.ascontiguousarray(np.swapaxes(a, -1, -2)).max(axis=-1)


def _over(err: np.ndarray, peak_: np.ndarray) -> np.ndarray:
    """err / peak; where the peak is 0, 0 for no error and inf otherwise; NaN where err is NaN."""
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(peak_ > 0, err / np.where(peak_ > 0, peak_, 1.0), np.where(err == 0, 0.0, np.inf))
    return np.where(np.isnan(err), np.nan, rel)


class OutputErrors(NamedTuple):
    """One solver's errors, each output against its own peak (joint rates ``r1`` …, currents ``i_C1_2`` …).

    Indexed as a pair, it is (largest absolute error, worst relative error of any output).
    """

    absolute: float
    relative: float
    worst: str
    per_output: dict
    whole: float            # max |error| over every output over the largest output's peak

    @classmethod
    def zero(cls, names: Sequence[str]) -> "OutputErrors":
        """The reference against itself.

        Parameters
        ----------
        names : sequence of str
            The outputs.
        """
        return cls(0.0, 0.0, names[0] if names else "", dict.fromkeys(names, 0.0), 0.0)
