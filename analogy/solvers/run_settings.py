"""What one ngspice transient run is told: its options, checked before they are written, its steps, its retries."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..circuit.spice_numbers import spice_number
from ..errors import InputError

__all__ = ["TransientSettings", "checked_options", "RETRY_LOOSEN", "RETRY_TIGHTEN", "NGSPICE_FIRST_STEP",
           "NGSPICE_RELTOL"]

#: Factors on abstol and vntol of the first run and of the retries after "time step too small".
RETRY_LOOSEN = (1.0, 1e3, 1e6)
#: The last retry of a nonlinear circuit whose step collapsed under both methods: reltol this many times tighter.
RETRY_TIGHTEN = 100.0

#: ngspice's own first step is this fraction of the print step (ngspice 39 and later, measured);
#: it takes it by backward Euler and never checks its truncation error.
NGSPICE_FIRST_STEP = 1e-2
#: ngspice's default reltol (its manual, the .options section).
NGSPICE_RELTOL = 1e-3

#: The ``.options`` that take a word, and their words; the flags (no value); every other option is a number.
_OPTION_WORDS = {"method": ("trap", "trapezoidal", "gear")}
_OPTION_FLAGS = ("klu", "sparse", "interp", "noopiter", "noinit", "nopage", "savecurrents")


def checked_options(opts: dict) -> dict:
    """*opts*, each a flag with no value, one of its words or a finite SPICE number: ngspice runs on
    after an option it cannot read (reltol=nan, maxord=abc, trtol=), saying so only in print.

    Parameters
    ----------
    opts : dict
        ``.options`` names and values.
    """
    for key, value in opts.items():
        text = str(value).strip()
        if not (key.isascii() and key.isidentifier()):
            raise InputError(f"{key!r} is not a SPICE option name")
        if key.lower() in _OPTION_FLAGS:
            ok = str(value) == ""
        elif key.lower() in _OPTION_WORDS:
            ok = text.lower() in _OPTION_WORDS[key.lower()]
        elif type(value) is float:      # its str is a SPICE number where it is finite
            ok = math.isfinite(value)
        else:
            try:
                ok = math.isfinite(spice_number(text))
            except InputError:
                ok = False
        if not ok:
            what = ("a flag, with no value" if key.lower() in _OPTION_FLAGS else
                    " or ".join(_OPTION_WORDS.get(key.lower(), ())) or "a finite number")
            raise InputError(f"the SPICE option {key}={value!r} must be {what}")
    return opts


@dataclass(frozen=True)
class TransientSettings:
    """What one ngspice transient run is told: the netlist writer formats these and nothing else.

    Attributes
    ----------
    options : tuple of (str, str)
        ``.options`` in order, values formatted.
    print_step : float
        ``.tran`` TSTEP: t_stop/``preset.steps``, the grid ``ngspice -b`` prints on.
    stop : float
        ``.tran`` TSTOP.
    max_step : float
        ``.tran`` TMAX, the step cap.
    first_step : float
        The first (backward Euler, unchecked) step the run needs; where ngspice's own,
        :data:`NGSPICE_FIRST_STEP` of the print step, is longer, :attr:`breakpoint` makes it shorter.
    loosen : float
        Factor on abstol and vntol (1 on the first run; a retry after a collapsed step raises it).
    horizons : tuple of float
        Ends of shorter systems in the same run, before :attr:`stop`: each is a breakpoint,
        so that ngspice steps onto it and each system's output ends at its own horizon.
    clock : tuple of float
        Corners where ngspice must step short (:class:`~analogy.solvers.motion_step.MotionSchedule`):
        a nonlinear circuit's fast decays and contact switches, which its truncation check does not follow.
    unclocked : float or None
        The step cap a clocked run falls back to when its step collapses under every retry: a clock
        may ask steps shorter than a circuit takes (the xArm7's under a clock of 2,601 pairs).
    impedance : float or None
        The circuit's impedance scale [Ω]: its velocity scale over its current scale
        (gnucap's dialect sizes the resistance of its voltage sources from it).
    interpolate : bool
        ``ngspice -b`` prints on the print step, linearly interpolated (``option interp``):
        where the step cap is far under the print step (the preset's own settings). A
        calibrated run's steps grow as its truncation check allows, so it prints its own
        points: interpolated, serial2's rows erred 7.6e-6 where its points held 2.7e-7.
    """

    options: tuple
    print_step: float
    stop: float
    max_step: float
    first_step: float
    loosen: float = 1.0
    horizons: tuple = ()
    clock: tuple = ()
    unclocked: float | None = None
    impedance: float | None = None
    interpolate: bool = True

    def with_method(self, method: str) -> "TransientSettings":
        """These settings with the integration method *method* (``trap`` or ``gear``).

        Parameters
        ----------
        method : str
            ngspice's ``method`` option.
        """
        opts = tuple((k, method if k == "method" else v) for k, v in self.options)
        return replace(self, options=opts if any(k == "method" for k, _ in opts) else opts + (("method", method),))

    @property
    def method(self) -> str:
        """The integration method the options ask for (ngspice's default: trap)."""
        return next((v for k, v in self.options if k == "method"), "trap")

    def retries(self) -> list["TransientSettings"]:
        """The settings a run tries in turn while its step collapses ("time step too small").

        First these, then abstol and vntol ``RETRY_LOOSEN`` times larger (rounding read as
        truncation error), when the options have them; last, for a trapezoidal run, gear at
        the first tolerances. A clocked run then tries all of that again without its clock, at
        its :attr:`unclocked` cap. flex2's nonlinear circuit under its motor steps at ``fast``
        collapses at t = 3.91 s and runs to its end at abstol and vntol 1000 times larger.
        Options without absolute tolerances (a bench's) run last at reltol
        :data:`RETRY_TIGHTEN` times tighter.
        """
        absolute = any(k in ("abstol", "vntol") for k, _ in self.options)
        ladder = [self.loosened(f) for f in RETRY_LOOSEN] if absolute else [self.loosened(1.0)]
        if self.method == "trap":
            ladder.append(self.loosened(1.0).with_method("gear"))
        if not absolute:
            ladder.append(self.loosened(1.0).tightened(RETRY_TIGHTEN))
        if self.clock and self.unclocked is not None:
            ladder += replace(self.loosened(1.0), clock=(), max_step=self.unclocked, unclocked=None).retries()
        return ladder

    @property
    def reltol(self) -> float:
        """ngspice's reltol: the options' or its default, 1e-3."""
        return float(next((v for k, v in self.options if k == "reltol"), 1e-3))

    def tightened(self, factor: float) -> "TransientSettings":
        """These settings with reltol *factor* times smaller: Newton's tolerance and the truncation check.

        Parameters
        ----------
        factor : float
            The divisor.
        """
        reltol = f"{self.reltol / factor:.3g}"
        opts = tuple((k, reltol if k == "reltol" else v) for k, v in self.options)
        return replace(self, options=opts if any(k == "reltol" for k, _ in opts) else opts + (("reltol", reltol),))

    @property
    def breakpoint(self) -> float | None:
        """A time at which a zero current source has a corner, so that ngspice's first step is
        a hundredth of it; None when ngspice's own first step is short enough."""
        own = NGSPICE_FIRST_STEP * self.print_step
        return None if self.first_step >= own else self.first_step / NGSPICE_FIRST_STEP

    def loosened(self, factor: float) -> "TransientSettings":
        """These settings with abstol and vntol *factor* times larger than the preset's.

        Parameters
        ----------
        factor : float
            The retry's factor (1: the preset's own).
        """
        opts = []
        for k, v in self.options:
            if k in ("abstol", "vntol") and self.loosen != factor:
                v = f"{float(v) / self.loosen * factor:.3g}"
            opts.append((k, v))
        return replace(self, options=tuple(opts), loosen=factor)
