"""Joint forces as waveforms: one tuple per joint from a specification, their sums over time and their breakpoints."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import InputError
from ..waveforms import Step, Waveform, parse_waveform

__all__ = ["waveforms", "joint_forces", "force_breakpoints"]


def joint_forces(forces: tuple, t) -> np.ndarray:
    """The summed waveforms of every joint at times *t*, shape (len(t), n).

    Parameters
    ----------
    forces : tuple of tuple of Waveform
        Per joint, its waveforms.
    t : float or array_like
        Times.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    return np.stack([sum((w(t) for w in ws), np.zeros_like(t)) for ws in forces], axis=-1)


def force_breakpoints(forces: tuple, t_stop: float) -> np.ndarray:
    """Sorted segment ends in (0, t_stop] between which every force is smooth.

    Parameters
    ----------
    forces : tuple of tuple of Waveform
        Per joint, its waveforms.
    t_stop : float
        End time.
    """
    parts = [np.asarray(w.breakpoints(t_stop), dtype=float).ravel() for ws in forces for w in ws]
    pts = np.concatenate(parts + [np.array([t_stop])])
    return np.unique(pts[(pts > 0) & (pts <= t_stop)])


@lru_cache(maxsize=1024)
def _step(value: float) -> Step:
    # Waveforms are immutable; a batch of scenes shares its constant forces.
    return Step(value)


def waveforms(spec, n: int) -> tuple:
    """Per joint, the tuple of waveforms a force specification sums (see :func:`node_system`).

    Parameters
    ----------
    spec : sequence or None
        One entry per joint: a number, a waveform, a waveform string or a list of these.
    n : int
        Number of joints.
    """
    if spec is None:
        return tuple(() for _ in range(n))
    if isinstance(spec, (str, Waveform)) or np.isscalar(spec):
        raise InputError(f"forces must be a list with one entry per joint ({n})")
    spec = list(spec)
    if len(spec) != n:
        raise InputError(f"forces must have {n} entries (one per joint), got {len(spec)}")
    out = []
    for item in spec:
        items = item if isinstance(item, (list, tuple)) else [item]
        ws = []
        for w in items:
            if isinstance(w, Waveform):
                ws.append(w)
            elif isinstance(w, str):
                ws.append(parse_waveform(w))
            else:
                try:
                    value = float(w)
                except (TypeError, ValueError):
                    raise InputError(f"cannot use {w!r} as a force") from None
                except OverflowError:
                    raise InputError("forces must be finite: a number is outside the floating-point range") from None
                if not np.isfinite(value):
                    raise InputError("forces must be finite")
                ws.append(_step(value))
        out.append(tuple(ws))
    return tuple(out)
