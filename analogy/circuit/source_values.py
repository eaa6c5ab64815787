"""Current sources as device values: the grounded PWL sources into one node written as one device, their sum."""

from __future__ import annotations

import numpy as np

from ..waveforms import PWL, pwl_corners

__all__ = ["source_values"]


def source_values(sources, t_stop: float, memo: dict | None) -> list[tuple[str, int, int, str, tuple]]:
    """(name, a, b, value, terms) of each source device: the grounded piecewise-linear sources into one
    node are one device ``In<k>`` whose PWL is their sum (under a custom map T⁻ᵀ every joint
    drives every node, and ngspice evaluates n² sources at every step otherwise), with the sources
    it sums as *terms*; the rest as given.

    Parameters
    ----------
    sources : sequence of CurrentSource
        A circuit's sources (:func:`~analogy.circuit.parts.current_sources`).
    t_stop : float
        The run's end [s], where each waveform's text ends.
    memo : dict, optional
        Source values already written, for circuits that share their sources.
    """
    merged: dict[int, list] = {}
    for s in sources:
        if s.b == 0 and isinstance(s.waveform, PWL):
            merged.setdefault(s.a, []).append(s)
    merged = {k: group for k, group in merged.items() if len(group) > 1}
    summed = {id(s) for group in merged.values() for s in group}
    corners: dict = {}
    out, written = [], set()
    for s in sources:
        if id(s) not in summed:
            key = (s.scale, t_stop)
            value = None if memo is None else memo.setdefault(s.waveform, {}).get(key)
            if value is None:
                value = s.waveform.spice(s.scale, t_stop)
                if memo is not None:        # one waveform drives many circuits of a batch: its text is made once
                    memo[s.waveform][key] = value
            out.append((s.name, s.a, s.b, value, ()))
        elif s.a not in written:
            written.add(s.a)
            group = merged[s.a]
            times, columns = _shared_corners([g.waveform for g in group], corners)
            scales = np.array([float(g.scale) for g in group])[:, None]
            # a running sum adds row after row (a reduction may pair them): pwl_sum's order, the same digits
            # (+ 0.0: pwl_sum starts from +0.0, so a sum of −0.0 terms is written 0.0, as there)
            summed_values = np.cumsum(scales * np.array([columns[id(g.waveform)] for g in group]), axis=0)[-1] + 0.0
            out.append((f"In{s.a}", s.a, 0, PWL(np.column_stack([times, summed_values])).spice(1.0, t_stop),
                        tuple(group)))
    return out


def _shared_corners(waveforms: list, corners: dict) -> tuple[np.ndarray, dict]:
    """The corners of *waveforms* summed (:func:`~analogy.waveforms.pwl_corners`) and each
    one's values there, by id, kept in *corners* for the next group of the same waveforms: a modal
    map's n sources each sum the same n forces, interpolated once instead of n times."""
    key = frozenset(id(w) for w in waveforms)
    if key not in corners:
        distinct = list({id(w): w for w in waveforms}.values())
        times = pwl_corners(distinct)
        corners[key] = times, {id(w): np.interp(times, w.times, w.values) for w in distinct}
    return corners[key]
