"""Numbers with units (``100 mm``, ``30 deg``, ``2 kg``): split off the unit and convert it to SI with pint."""

from __future__ import annotations

import re
from functools import lru_cache

from ..errors import InputError

__all__ = ["split_unit", "unit_factor", "MAX_UNIT_LENGTH"]

#: Longest unit text accepted.
MAX_UNIT_LENGTH = 40
# A unit: letters (µ, °, Ω too), digits as exponents, and * / ^ · ( ) between them; nothing else reaches pint.
_UNIT = re.compile(r"^[A-Za-zµμ°Ω][A-Za-z0-9µμ°Ω_·*/^() ]*$")
# Names the grammar already gives a meaning (Euler's e, pi): never read as units (e is also a charge).
_NOT_UNITS = frozenset({"e", "E", "pi"})
_EXPONENT = re.compile(r"^[eE][+-]?[0-9]")       # 1e5 is a number, not 1 of a unit "e5"
_GLUED = re.compile(r"^(.*[0-9.])([A-Za-zµμ°Ω][A-Za-z0-9µμ°Ω_·*/^() ]*)$")


def split_unit(text: str) -> tuple[str, str] | None:
    """*text* as (number, unit) when it ends with something shaped like a unit, else None.

    ``"100 mm"`` gives ``("100", "mm")``, ``"pi/6 rad"`` gives ``("pi/6", "rad")`` and
    ``"9.81m/s^2"`` gives ``("9.81", "m/s^2")``. The number part is left to the
    restricted grammar; nothing here evaluates anything.

    Parameters
    ----------
    text : str
        A number, perhaps followed by a unit.
    """
    stripped = text.strip()
    parts = stripped.split(None, 1)
    if len(parts) == 2 and _UNIT.match(parts[1].strip()):
        number, unit = parts[0], parts[1].strip()
    elif (m := _GLUED.match(stripped)) is not None and not m.group(1).rstrip().endswith(("e", "E")):
        number, unit = m.group(1), m.group(2).strip()
    else:
        return None
    if len(unit) > MAX_UNIT_LENGTH or not number.strip() or unit in _NOT_UNITS or _EXPONENT.match(unit):
        return None
    return number, unit


@lru_cache(maxsize=1)
def _registry():
    import pint
    return pint.UnitRegistry(autoconvert_offset_to_baseunit=False)


@lru_cache(maxsize=256)
def unit_factor(unit: str) -> float:
    """How many SI units (m, kg, s, rad, A, K, …) one *unit* is: ``unit_factor("mm") == 1e-3``.

    pint is imported only here, when an input carries a unit. Offset units (°C, °F)
    are refused: a temperature difference or an absolute one would be ambiguous.

    Parameters
    ----------
    unit : str
        A unit such as ``mm``, ``deg``, ``kg*m^2`` or ``N·m``.
    """
    if not _UNIT.match(unit) or len(unit) > MAX_UNIT_LENGTH:
        raise InputError(f"{unit!r} is not a unit")
    import pint
    ureg = _registry()
    try:
        parsed = ureg.parse_units(unit.replace("·", "*").replace("^", "**"))
        quantity = ureg.Quantity(1.0, parsed)
        if not quantity._is_multiplicative:
            raise InputError(f"offset unit {unit!r} is ambiguous: give kelvin")
        factor = float(quantity.to_base_units().magnitude)
    except InputError:
        raise
    except (pint.errors.PintError, AttributeError, TypeError, ValueError, SyntaxError, KeyError):
        raise InputError(f"unknown unit {unit!r} (e.g. mm, deg, kg, N*m, rad/s)") from None
    return factor
