"""Numbers in netlists: as ngspice reads them (``1e-3``, ``1m``, ``10meg``, a unit ignored) and as written."""

from __future__ import annotations

import math
import re

from ..errors import InputError

__all__ = ["spice_number", "spice_text", "SPICE_NUMBER"]

_SUFFIX = {"t": 1e12, "g": 1e9, "meg": 1e6, "k": 1e3, "m": 1e-3, "u": 1e-6, "n": 1e-9, "p": 1e-12, "f": 1e-15}
#: A SPICE number: mantissa, exponent, scale suffix and letters after it (a unit, which SPICE ignores).
SPICE_NUMBER = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?)(meg|[tgkmunpf])?[a-z]*$", re.IGNORECASE)


def spice_number(text: str) -> float:
    """A SPICE number: ``1e-3``, ``1m``, ``10meg`` (a unit after the suffix is ignored, as SPICE does).

    Parameters
    ----------
    text : str
        The number as written in a netlist.
    """
    match = SPICE_NUMBER.match(text.strip())
    if match is None:
        raise InputError(f"{text!r} is not a SPICE number")
    return float(match.group(1)) * _SUFFIX.get((match.group(2) or "").lower(), 1.0)


def spice_text(x: float) -> str:
    """*x* as a netlist writes it: every digit (``repr``), never inf or NaN.

    Parameters
    ----------
    x : float
        The value.
    """
    x = float(x)
    if not math.isfinite(x):            # inf or nan in a netlist would be read as a name or zero
        raise InputError(f"a netlist value ({float(x)!r}) leaves the floating-point range: rescale the "
                         "masses, dampers, springs or forces")
    return repr(float(x))
