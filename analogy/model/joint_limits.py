"""A URDF joint's limits: its range of motion and the largest force it may exert."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["JointLimits", "joint_limits"]


@dataclass(frozen=True)
class JointLimits:
    """Per joint, the range of motion and the largest force a URDF's ``<limit>`` gives.

    Attributes
    ----------
    lower, upper : ndarray
        The range [rad or m]; ±inf where the joint has none (continuous, or an empty range).
    effort : ndarray
        The largest force [N·m or N]; nan where the file gives none.
    """

    lower: np.ndarray
    upper: np.ndarray
    effort: np.ndarray

    def contain(self, q) -> bool:
        """True when every coordinate of *q* lies in its range.

        Parameters
        ----------
        q : array_like
            Joint coordinates [rad or m].
        """
        q = np.asarray(q, dtype=float)
        return bool(np.all((q >= self.lower) & (q <= self.upper)))

    def middle(self) -> np.ndarray:
        """The middle of each range, 0 where a joint has none or 0 lies inside it."""
        bounded = np.isfinite(self.lower) & np.isfinite(self.upper)
        mid = np.where(bounded, 0.5 * (np.where(bounded, self.lower, 0.0) + np.where(bounded, self.upper, 0.0)), 0.0)
        return np.where((self.lower <= 0.0) & (self.upper >= 0.0), 0.0, mid)


def joint_limits(continuous: bool, lower: float | None, upper: float | None,
                 effort: float | None) -> tuple[float, float, float]:
    """(lower, upper, effort) of one joint as a URDF's <limit> gives them: ±inf for a continuous
    joint, a missing bound or an empty range (files write lower = upper = 0 for none), nan for
    an effort that is missing or not positive.

    Parameters
    ----------
    continuous : bool
        The joint turns without end.
    lower, upper, effort : float or None
        The <limit> attributes, None where absent.
    """
    low = -np.inf if lower is None else lower
    high = np.inf if upper is None else upper
    if continuous or not low < high:
        low, high = -np.inf, np.inf
    return low, high, effort if effort is not None and effort > 0 else np.nan
