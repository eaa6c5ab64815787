"""Force waveforms (step, pulse, sine, piecewise linear) shared by SPICE and the solvers."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .errors import InputError
from .model.expressions import parse_call, parse_number
from .model.quantities import FORCE

__all__ = ["Waveform", "Step", "PWL", "Pulse", "PWM", "HBridge", "Sine", "Piece", "parse_waveform", "pwl_sum",
           "pwl_corners"]


def _num(x: float) -> str:
    """Full double precision, in a form every SPICE reads; a value past the float range is refused."""
    x = float(x)
    if not math.isfinite(x):
        raise InputError("a force's value at a node (the force times T^-T) leaves the floating-point range: "
                         "rescale the forces")
    return repr(float(x))


@dataclass(frozen=True)
class Piece:
    """On [t0, t0 + h]: u(t0 + τ) = a + b·τ + Σ c_k·exp(s_k·τ)."""

    a: float
    b: float = 0.0
    c: tuple = ()
    s: tuple = ()


#: Most pulse periods expanded within one simulation (bounds memory for tiny periods).
_MAX_PERIODS = 100_000


class Waveform:
    """A force waveform f(t), t ≥ 0."""

    def spice(self, scale: float, t_stop: float) -> str:
        """The SPICE source value (``DC …``, ``PWL(…)``, ``SIN(…)``) of scale·f.

        Parameters
        ----------
        scale : float
            Factor on the waveform (a column entry of T⁻ᵀ).
        t_stop : float
            End of the simulation.
        """
        raise NotImplementedError

    def breakpoints(self, t_stop: float) -> list[float]:
        """Times in (0, t_stop) where f or its derivative jumps.

        Parameters
        ----------
        t_stop : float
            End of the simulation.
        """
        raise NotImplementedError

    def piece(self, t0: float, t1: float) -> Piece:
        """Closed form of f on a segment that contains no breakpoint.

        Parameters
        ----------
        t0 : float
            Segment start.
        t1 : float
            Segment end.
        """
        raise NotImplementedError

    def __call__(self, t):
        raise NotImplementedError

    def label(self) -> str:
        """The waveform as the user writes it, e.g. ``step(1)`` or ``sine(0, 0.5, 2)``."""
        raise NotImplementedError

    def key(self) -> tuple:
        """The waveform's value as a hashable tuple: equal keys, equal waveforms (caches left out)."""
        key = self.__dict__.get("_key")
        if key is None:         # a waveform does not change once built (its arrays are read-only)
            key = self._key = (type(self).__name__,) + tuple(
                (v.shape, v.tobytes()) if isinstance(v, np.ndarray) else v
                for k, v in sorted(vars(self).items()) if not k.startswith("_"))
        return key


def _call(name: str, values, keep: int) -> str:
    """``name(v1, v2, …)`` with trailing defaults beyond the first *keep* values dropped."""
    vals = list(values)
    while len(vals) > keep and vals[-1] in (0.0, None):
        vals.pop()
    return f"{name}(" + ", ".join(f"{float(v):g}" for v in vals) + ")"


class PWL(Waveform):
    """Piecewise linear through (t_k, f_k); constant before the first and after the last point."""

    def __init__(self, points: Sequence[tuple[float, float]]):
        pts = np.array(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 1:
            raise InputError("pwl needs pairs of time and value")
        if not np.all(np.isfinite(pts)):
            raise InputError("pwl points must be finite")
        if pts[0, 0] < 0 or np.any(np.diff(pts[:, 0]) <= 0):
            raise InputError("pwl times must start at 0 or later and strictly increase")
        pts.setflags(write=False)
        self.times = pts[:, 0]
        self.values = pts[:, 1]

    def __repr__(self):
        return f"PWL({list(zip(self.times.tolist(), self.values.tolist()))})"

    def spice(self, scale, t_stop) -> str:
        if len(self.times) == 1 or np.all(self.values == self.values[0]):
            return f"DC {_num(float(scale) * float(self.values[0]))}"
        times, values = self.times, self.values
        if times[0] > 0:  # SPICE holds the first value before the first point; make it explicit
            times, values = np.r_[0.0, times], np.r_[values[0], values]
        body = " ".join(f"{_num(t)} {_num(float(scale) * float(v))}" for t, v in zip(times, values))
        return f"PWL({body})"

    def breakpoints(self, t_stop) -> np.ndarray:
        return self.times[(self.times > 0) & (self.times < t_stop)]

    def label(self) -> str:
        pairs = np.column_stack([self.times, self.values]).ravel()
        text = _call("pwl", pairs, len(pairs))
        # a long table is cut where a reader stops, and says how long it is; a short one is whole
        return text if len(text) <= 48 else f"{text[:40]}... ({len(self.times)} points)"

    def __call__(self, t):
        return np.interp(t, self.times, self.values)

    def piece(self, t0, t1) -> Piece:
        mid = 0.5 * (t0 + t1)
        k = np.searchsorted(self.times, mid)
        if k == 0 or k == len(self.times):
            return Piece(float(self.values[min(k, len(self.values) - 1)]))
        ta, tb = self.times[k - 1], self.times[k]
        slope = (self.values[k] - self.values[k - 1]) / (tb - ta)
        return Piece(float(self.values[k - 1] + slope * (t0 - ta)), float(slope))


class Step(PWL):
    """A step of *amplitude* at *delay*, rising linearly over *rise* (needed when delay > 0)."""

    def __init__(self, amplitude: float, delay: float = 0.0, rise: float = 0.0):
        self.amplitude, self.delay, self.rise = float(amplitude), float(delay), float(rise)
        if delay < 0 or rise < 0:
            raise InputError("step delay and rise must not be negative")
        if delay == 0 and rise == 0:
            super().__init__([(0.0, amplitude)])
        elif rise == 0:
            raise InputError("a delayed step needs a rise time > 0: SPICE sources cannot jump")
        else:
            super().__init__([(0.0, 0.0), (delay, 0.0), (delay + rise, amplitude)]
                             if delay > 0 else [(0.0, 0.0), (rise, amplitude)])

    def __repr__(self):
        return f"Step({self.amplitude!r}, delay={self.delay!r}, rise={self.rise!r})"

    def label(self) -> str:
        return _call("step", (self.amplitude, self.delay, self.rise), 1)


def pwl_corners(waveforms: Sequence["PWL"]) -> np.ndarray:
    """The union of piecewise-linear waveforms' times, where their sum has its corners.

    Parameters
    ----------
    waveforms : sequence of PWL
        The waveforms.
    """
    times = np.unique(np.concatenate([w.times for w in waveforms]))
    # one corner written by two waveforms a few ulps apart (0.2 + 0.1 against 0.3) is one time:
    # ngspice reads such a pair as a time that does not increase
    return times[np.append(True, np.diff(times) > 1e-14 * times[-1])]


def pwl_sum(terms: Sequence[tuple["PWL", float]]) -> PWL:
    """Σ scale·f of piecewise-linear waveforms, itself piecewise linear through the union of their times.

    Parameters
    ----------
    terms : sequence of (PWL, float)
        Each waveform with its factor.
    """
    times = pwl_corners([w for w, _ in terms])
    values = np.zeros_like(times)
    for w, scale in terms:
        values += float(scale) * np.interp(times, w.times, w.values)
    return PWL(np.column_stack([times, values]))


class Pulse(Waveform):
    """SPICE PULSE(v1 v2 delay rise fall width period); rise and fall must be > 0."""

    def __init__(self, v1, v2, delay=0.0, rise=1e-6, fall=1e-6, width=1.0, period=None):
        self.v1, self.v2 = float(v1), float(v2)
        self.delay, self.rise, self.fall, self.width = map(float, (delay, rise, fall, width))
        if self.rise <= 0 or self.fall <= 0:
            # SPICE silently replaces a zero edge by the print step; make it explicit instead.
            raise InputError("pulse rise and fall times must be > 0")
        if self.delay < 0 or self.width < 0:
            raise InputError("pulse delay and width must not be negative")
        self.period = None if period is None else float(period)
        if self.period is not None and self.period < self.rise + self.width + self.fall:
            raise InputError("pulse period must be at least rise + width + fall")

    def __repr__(self):
        return (f"Pulse({self.v1!r}, {self.v2!r}, {self.delay!r}, {self.rise!r}, "
                f"{self.fall!r}, {self.width!r}, {self.period!r})")

    def label(self) -> str:
        return _call("pulse", (self.v1, self.v2, self.delay, self.rise, self.fall, self.width, self.period), 6)

    def _period(self, t_stop):
        one = self.rise + self.width + self.fall
        return self.period if self.period is not None else max(2 * (one + self.delay), 2 * t_stop)

    def _check(self, t_stop: float):
        per = self._period(t_stop)
        if (t_stop - self.delay) / per > _MAX_PERIODS:
            raise InputError(f"pulse period {per:g} s is too short for t_stop = {t_stop:g} s "
                             f"(more than {_MAX_PERIODS} periods)")

    def as_pwl(self, t_stop: float) -> PWL:
        """as_pwl.

        Parameters
        ----------
        t_stop : float
            Expand periods up to this time.
        """
        per = self._period(t_stop)
        pts = [(0.0, self.v1)] if self.delay > 0 else []
        start = self.delay
        while start < t_stop:
            for dt, v in ((0.0, self.v1), (self.rise, self.v2),
                          (self.rise + self.width, self.v2), (self.rise + self.width + self.fall, self.v1)):
                pts.append((start + dt, v))
            start += per
        # drop a zero-width plateau duplicate (width == 0)
        clean = []
        for t, v in pts:
            if clean and t <= clean[-1][0]:
                continue
            clean.append((t, v))
        return PWL(clean)

    def spice(self, scale, t_stop) -> str:
        self._check(t_stop)
        if self.width == 0:     # SPICE reads a zero width as t_stop: write the corners instead
            pwl = self.as_pwl(t_stop)
            return PWL(list(zip(pwl.times, pwl.values))).spice(scale, t_stop)
        vals = (scale * self.v1, scale * self.v2, self.delay, self.rise, self.fall,
                self.width, self._period(t_stop))
        return "PULSE(" + " ".join(_num(v) for v in vals) + ")"

    def breakpoints(self, t_stop) -> list[float]:
        self._check(t_stop)
        return self.as_pwl(t_stop).breakpoints(t_stop)

    def piece(self, t0, t1) -> Piece:
        return self._pwl_cache(t1).piece(t0, t1)

    def _pwl_cache(self, t_stop):
        cache = getattr(self, "_cache", None)
        if cache is None or cache[0] < t_stop:
            # doubling the horizon keeps re-expansion rare as segments advance
            horizon = 2.0 * max(t_stop, self.delay + self.rise + self.width + self.fall)
            cache = (horizon, self.as_pwl(horizon))
            self._cache = cache
        return cache[1]

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        return self._pwl_cache(float(np.max(t)) if t.size else 1.0)(t)


class PWM(Pulse):
    """An H-bridge's output: +*supply* for the share *duty* of each period of 1/*frequency*, −*supply* for the
    rest, each switching edge a share *edge* of the period long (SPICE sources cannot jump)."""

    def __init__(self, supply, duty, frequency, edge=1e-3):
        supply, duty, frequency, edge = float(supply), float(duty), float(frequency), float(edge)
        if not (0.0 < frequency < math.inf and 0.0 < edge < 0.05):
            raise InputError("pwm needs a positive, finite frequency and an edge under 5% of the period")
        period = 1.0 / frequency
        if not edge <= duty <= 1.0 - edge:
            raise InputError(f"pwm duty must be from {edge:g} to {1 - edge:g} (its edges take {edge:g} of the period)")
        self.supply, self.duty, self.frequency, self.edge = supply, duty, frequency, edge
        super().__init__(-supply, supply, 0.0, edge * period, edge * period, (duty - edge) * period, period)

    def __repr__(self):
        return f"PWM({self.supply!r}, {self.duty!r}, {self.frequency!r}, {self.edge!r})"

    def label(self) -> str:
        return _call("pwm", (self.supply, self.duty, self.frequency, self.edge), 3)


class HBridge(Pulse):
    """An H-bridge of four ngspice switches around a winding: +*supply* for the share *duty* of each
    period of 1/*frequency*, −*supply* for the rest, each switch *on_resistance* when on.

    Two complementary control pulses turn the switches, each edge a share *edge* of the period; a
    switch turns where its control ends its edge, a breakpoint on which ngspice lands a time point,
    so the bridge switches at known instants: up at edge·T, down at (duty + edge)·T. As a waveform
    (the exact solution's, the ODE's) it is that square wave, each jump a ramp of 1e-6 of the edge
    ending at the instant. The netlist writes the switches (:func:`~analogy.solvers.drive.drive_netlist`).
    """

    def __init__(self, supply, duty, frequency, edge=1e-7, on_resistance=1e-3):
        supply, duty, frequency = float(supply), float(duty), float(frequency)
        edge, on_resistance = float(edge), float(on_resistance)
        if not (0.0 < frequency < math.inf and 0.0 < edge < 0.05 and 0.0 < on_resistance < math.inf):
            raise InputError("hbridge needs a positive, finite frequency, an edge under 5% of the period and a "
                             "positive on-resistance")
        if not edge <= duty <= 1.0 - 2.0 * edge:
            raise InputError(f"hbridge duty must be from {edge:g} to {1 - 2 * edge:g} (its controls' edges take "
                             f"{edge:g} of the period)")
        period = 1.0 / frequency
        self.supply, self.duty, self.frequency, self.edge = supply, duty, frequency, edge
        self.on_resistance = on_resistance
        jump = 1e-6 * edge * period
        super().__init__(-supply, supply, edge * period - jump, jump, jump, duty * period - jump, period)

    def __repr__(self):
        return f"HBridge({self.supply!r}, {self.duty!r}, {self.frequency!r}, {self.edge!r}, {self.on_resistance!r})"

    def label(self) -> str:
        return _call("hbridge", (self.supply, self.duty, self.frequency, self.edge, self.on_resistance), 3)

    def breakpoints(self, t_stop) -> list[float]:
        # the controls' corners too: ngspice steps there, and the switches' jumps lie between them
        period = 1.0 / self.frequency
        starts = np.arange(0.0, t_stop, period)
        edges = np.concatenate([starts, starts + self.duty * period])
        own = np.asarray(super().breakpoints(t_stop), float)
        return sorted(set(own.tolist()) | {float(x) for x in edges if 0.0 < x < t_stop})

    def controls(self) -> tuple[str, str]:
        """The SPICE sources of the two control pulses (0 to 1 V): the first turns the switches that put
        +supply on the winding, the second the others."""
        period = 1.0 / self.frequency
        rise, width = self.edge * period, (self.duty - self.edge) * period
        times = " ".join(_num(x) for x in (0.0, rise, rise, width, period))
        return f"PULSE(0 1 {times})", f"PULSE(1 0 {times})"


class Sine(Waveform):
    """SPICE SIN: offset + amplitude·exp(−damping·τ)·sin(2π·frequency·τ + phase), τ = t − delay ≥ 0.

    Before *delay* the value is offset + amplitude·sin(phase); *phase* is in degrees, as in SPICE.
    """

    def __init__(self, offset, amplitude, frequency, delay=0.0, damping=0.0, phase=0.0):
        self.offset, self.amplitude, self.frequency = float(offset), float(amplitude), float(frequency)
        self.delay, self.damping, self.phase = float(delay), float(damping), float(phase)
        if self.frequency <= 0 or self.delay < 0:
            # SPICE reads a zero frequency as 1/t_stop; a constant force is a step.
            raise InputError("sine frequency must be > 0 (use step() for a constant) "
                             "and its delay must not be negative")

    def __repr__(self):
        return (f"Sine({self.offset!r}, {self.amplitude!r}, {self.frequency!r}, "
                f"delay={self.delay!r}, damping={self.damping!r}, phase={self.phase!r})")

    def label(self) -> str:
        return _call("sine", (self.offset, self.amplitude, self.frequency, self.delay, self.damping,
                              self.phase), 3)

    def spice(self, scale, t_stop) -> str:
        vals = (scale * self.offset, scale * self.amplitude, self.frequency, self.delay,
                self.damping, self.phase)
        return "SIN(" + " ".join(_num(v) for v in vals) + ")"

    def breakpoints(self, t_stop) -> list[float]:
        return [self.delay] if 0 < self.delay < t_stop else []

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        phi = math.radians(self.phase)
        tau = np.maximum(t - self.delay, 0.0)
        return self.offset + self.amplitude * np.exp(-self.damping * tau) * \
            np.sin(2 * math.pi * self.frequency * tau + phi)

    def piece(self, t0, t1) -> Piece:
        phi = math.radians(self.phase)
        if t1 <= self.delay:
            return Piece(self.offset + self.amplitude * math.sin(phi))
        w = 2 * math.pi * self.frequency
        d = t0 - self.delay
        s_plus, s_minus = complex(-self.damping, w), complex(-self.damping, -w)
        # A e^{-θτ} sin(ωτ + φ) = A/(2i)·(e^{s+ τ + iφ} − e^{s− τ − iφ}), shifted to the segment start.
        c_plus = self.amplitude / 2j * np.exp(s_plus * d + 1j * phi)
        c_minus = -self.amplitude / 2j * np.exp(s_minus * d - 1j * phi)
        return Piece(self.offset, 0.0, (complex(c_plus), complex(c_minus)), (s_plus, s_minus))


_WAVEFORMS = {
    "step": Step,
    "pulse": Pulse,
    "pwm": PWM, "hbridge": HBridge,
    "sine": Sine, "sin": Sine,
    "pwl": None,
}


def parse_waveform(text: str) -> Waveform:
    """Parse ``step(1)``, ``pulse(0, 1, 0.1, 1e-3, 1e-3, 0.5, 2)``, ``sine(0, 1, 2)``,
    ``pwl(0, 0, 1, 1)`` or a bare number (a step at t = 0), without evaluating code.

    Parameters
    ----------
    text : str
        The waveform as written.
    """
    stripped = text.strip()
    if "(" not in stripped:
        return Step(parse_number(stripped, FORCE))
    name, args, kwargs = parse_call(stripped, _WAVEFORMS)
    try:
        if name == "pwl":
            if kwargs or len(args) < 2 or len(args) % 2:
                raise InputError(f"{text!r}: pwl needs time, value pairs")
            return PWL(list(zip(args[0::2], args[1::2])))
        cls = _WAVEFORMS[name]
        code = cls.__init__.__code__
        params = code.co_varnames[1:code.co_argcount]
        need = len(params) - len(cls.__init__.__defaults__ or ())
        if unknown := [k for k in kwargs if k not in params]:
            raise InputError(f"{text!r}: {name} has no argument {unknown[0]!r}; its arguments are "
                             f"{', '.join(params)}")
        if not need <= len(args) + len(kwargs) <= len(params):
            raise InputError(f"{text!r}: {name} takes {need} to {len(params)} arguments "
                             f"({', '.join(params)}), got {len(args) + len(kwargs)}")
        return cls(*args, **kwargs)
    except TypeError:
        raise InputError(f"{text!r}: wrong arguments for {name}") from None
