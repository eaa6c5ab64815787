"""Numbers with units (``100 mm``, ``30 deg``): the unit read by a bounded grammar, converted to SI by pint."""

from __future__ import annotations

import re
from functools import lru_cache
from typing import Literal

from ..errors import InputError

__all__ = ["split_unit", "unit_factor", "unit_dimension", "check_dimension", "Dimension", "DIMENSIONS", "COORDINATE",
           "RATE", "FORCE", "ANY", "MAX_UNIT_LENGTH", "MAX_UNIT_EXPONENT", "Measured", "check_joint_dimensions",
           "check_parameter_units"]

#: Longest unit text accepted.
MAX_UNIT_LENGTH = 40
#: Largest |exponent| on a unit (m^3, s^-2, ...): no physical input needs more, and a tower of
#: exponents (m^2^2^2...) would otherwise ask pint for an integer of astronomical size.
MAX_UNIT_EXPONENT = 12
# A unit: letters (µ, °, Ω too), digits as exponents, and * / ^ · ( ) between them; nothing else reaches pint.
_UNIT = re.compile(r"^[A-Za-zµμ°Ω(][A-Za-z0-9µμ°Ω_·*/^() -]*$")
# Names the grammar already gives a meaning (Euler's e, pi): never read as units (e is also a charge).
_NOT_UNITS = frozenset({"e", "E", "pi"})
_EXPONENT = re.compile(r"^[eE][+-]?[0-9]")       # 1e5 is a number, not 1 of a unit "e5"
_GLUED = re.compile(r"^(.*[0-9.])([A-Za-zµμ°Ω][A-Za-z0-9µμ°Ω_·*/^() -]*)$")
_TOKEN = re.compile(r"\s*(?:(?P<name>[A-Za-zµμ°Ω_]+)|(?P<int>[+-]?[0-9]+)|(?P<op>\*\*|[*/^·()]))")

#: The physical dimensions a field may ask of its unit, as pint dimensionalities. An angle is
#: dimensionless in SI (rad = m/m), so a bare number and rad, deg or turn all pass as one.
Dimension = Literal["time", "length", "angle", "mass", "frequency", "angular rate", "velocity", "force",
                    "torque", "resistance", "inductance", "voltage", "current", "torque constant", "inertia",
                    "rotary damping"]
DIMENSIONS: dict[str, str] = {"time": "[time]", "length": "[length]", "angle": "dimensionless",
                              "mass": "[mass]", "frequency": "1 / [time]", "angular rate": "1 / [time]",
                              "velocity": "[length] / [time]", "force": "[mass] * [length] / [time] ** 2",
                              "torque": "[mass] * [length] ** 2 / [time] ** 2",
                              # a motor's (analogy.model.motors)
                              "resistance": "[mass] * [length] ** 2 / [time] ** 3 / [current] ** 2",
                              "inductance": "[mass] * [length] ** 2 / [time] ** 2 / [current] ** 2",
                              "voltage": "[mass] * [length] ** 2 / [time] ** 3 / [current]",
                              "current": "[current]",
                              "torque constant": "[mass] * [length] ** 2 / [time] ** 2 / [current]",
                              "inertia": "[mass] * [length] ** 2",
                              "rotary damping": "[mass] * [length] ** 2 / [time]"}
#: A joint coordinate (an angle or a travel) and its rate, before the model says which joint is which.
COORDINATE: tuple[Dimension, ...] = ("angle", "length")
RATE: tuple[Dimension, ...] = ("angular rate", "velocity")
FORCE: tuple[Dimension, ...] = ("torque", "force")
#: Any dimension, kept with the value for the model to judge (a parameter's unit is the model's to declare).
ANY: tuple[Dimension, ...] = ()


class Measured(float):
    """A number read with a unit: its SI value, and the pint dimensionality the unit had.

    A joint coordinate is read before the model says whether its joint turns or slides;
    the dimension is kept so that :func:`check_joint_dimensions` can judge it then. It is a
    float in every other respect (and in a scene's key).
    """

    dimension: str
    unit: str

    def __new__(cls, value: float, dimension: str, unit: str = "") -> "Measured":
        number = super().__new__(cls, value)
        number.dimension, number.unit = dimension, unit
        return number

    def __reduce__(self):
        return (Measured, (float(self), self.dimension, self.unit))


#: What a coordinate and its rate measure, per joint kind.
_JOINT_DIMENSIONS: dict[str, tuple[Dimension, Dimension, Dimension]] = {
    "revolute": ("angle", "angular rate", "torque"), "prismatic": ("length", "velocity", "force"),
    "modal": ("length", "velocity", "force")}
_JOINT_NOUNS = {"revolute": "a revolute joint", "prismatic": "a prismatic joint", "modal": "a modal amplitude"}


def _noun(dimension: str) -> str:
    """``an angle``, ``a force`` …: the pint dimensionality in words, where it has a name."""
    found = next((d for d in _JOINT_DIMENSIONS["revolute"] + _JOINT_DIMENSIONS["prismatic"] + ("mass", "time")
                  if DIMENSIONS[d] == dimension), None)
    return f"a unit of {dimension}" if found is None else f"{'an' if found[0] in 'aeiou' else 'a'} {found}"


def check_joint_dimensions(values, joints, rates: bool = False, name: str = "q",
                           quantity: Literal["coordinate", "rate", "force"] | None = None) -> None:
    """One sentence if a value read with a unit does not measure what its joint's coordinate (rate, force) is.

    Parameters
    ----------
    values : sequence of float
        Coordinates (or their rates, or forces); :class:`Measured` entries are checked.
    joints : sequence of str or None
        The model's joint kinds (``"revolute"``, ``"prismatic"``, ``"modal"``); None checks nothing.
    rates : bool
        The values are rates (the same as *quantity* ``"rate"``).
    name : str
        The values' symbol in the sentence (``q1``, ``r1``, ``F1`` …).
    quantity : {"coordinate", "rate", "force"}, optional
        What the values are; default a coordinate, or a rate with *rates*.
    """
    if joints is None:
        return
    which = ("coordinate", "rate", "force").index(quantity or ("rate" if rates else "coordinate"))
    for k, (x, kind) in enumerate(zip(values, joints)):
        if not isinstance(x, Measured) or kind not in _JOINT_DIMENSIONS:
            continue
        wanted = _JOINT_DIMENSIONS[kind][which]
        if x.dimension != DIMENSIONS[wanted]:
            article = "an" if wanted[0] in "aeiou" else "a"
            raise InputError(f"{name}{k + 1} is {article} {wanted} ({_JOINT_NOUNS[kind]}), "
                             f"got {_noun(x.dimension)} ({x.unit!r})")


def check_parameter_units(values, units) -> None:
    """One sentence if a parameter read with a unit does not measure what its model declares.

    Parameters
    ----------
    values : mapping of str to float
        Parameter values; :class:`Measured` entries are checked.
    units : mapping of str to str
        The model's SI unit of each parameter (``"m"``, ``"kg*m^2"``; ``"1"`` for a pure
        number); a parameter it does not list is not judged.
    """
    for key, x in values.items():
        unit = units.get(key)
        if not isinstance(x, Measured) or unit is None:
            continue
        wanted = "dimensionless" if unit == "1" else unit_dimension(unit)
        if x.dimension != wanted:
            what = _noun(wanted)
            what = ("a pure number" if unit == "1" else f"measured in {unit}" if what.startswith("a unit of")
                    else f"{what} ({unit})")
            raise InputError(f"{key} is {what}, got {_noun(x.dimension)} ({x.unit!r})")


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


def _tokens(unit: str) -> list[tuple[str, str]]:
    out, pos = [], 0
    while pos < len(unit):
        if unit[pos:].strip() == "":
            break
        m = _TOKEN.match(unit, pos)
        if m is None:
            raise InputError(f"{unit!r} is not a unit: unexpected {unit[pos:].strip()[0]!r}")
        kind = m.lastgroup
        out.append((kind, m.group(kind)))
        pos = m.end()
    return out


class _UnitParser:
    """unit := power ((* | / | · | space) power)*;  power := (name | '(' unit ')') [^ int | int]."""

    def __init__(self, unit: str):
        self.unit, self.tokens, self.k = unit, _tokens(unit), 0
        self.ureg = _registry()

    def fail(self, why: str):
        raise InputError(f"{self.unit!r} is not a unit: {why}")

    def peek(self):
        return self.tokens[self.k] if self.k < len(self.tokens) else (None, None)

    def take(self):
        token = self.peek()
        self.k += 1
        return token

    def parse(self):
        value = self.product()
        if self.k != len(self.tokens):
            self.fail(f"unexpected {self.peek()[1]!r}")
        return value

    def product(self):
        value = self.power()
        while True:
            kind, text = self.peek()
            if kind == "op" and text in ("*", "·", "/"):
                self.take()
                right = self.power()
                value = value / right if text == "/" else value * right
            elif kind == "name" or (kind, text) == ("op", "("):
                value = value * self.power()        # "N m": a space multiplies
            else:
                return value

    def power(self):
        kind, text = self.take()
        if kind == "name":
            value = self.name(text)
        elif (kind, text) == ("op", "("):
            value = self.product()
            if self.take() != ("op", ")"):
                self.fail("a '(' is not closed")
        else:
            self.fail("expected a unit name" if kind is None else f"expected a unit name, got {text!r}")
        kind, text = self.peek()
        if kind == "op" and text in ("^", "**"):
            self.take()
            exponent = self.exponent()
        elif kind == "int":                  # m2 is m^2, as pint reads it
            exponent = self.exponent()
        else:
            return value
        if self.peek()[0] == "op" and self.peek()[1] in ("^", "**") or self.peek()[0] == "int":
            self.fail("an exponent of an exponent: write the power once, e.g. m^4")
        return value ** exponent

    def exponent(self) -> int:
        kind, text = self.take()
        paren = (kind, text) == ("op", "(")
        if paren:
            kind, text = self.take()
        if kind != "int":
            self.fail("an exponent must be a whole number, e.g. m^2 or s^-1")
        if paren and self.take() != ("op", ")"):
            self.fail("a '(' is not closed")
        n = int(text)
        if abs(n) > MAX_UNIT_EXPONENT:
            self.fail(f"exponent {n} is beyond ±{MAX_UNIT_EXPONENT}")
        return n

    def name(self, text: str):
        import pint
        try:
            unit = self.ureg.parse_units(text)
        except (pint.errors.PintError, AttributeError, TypeError, ValueError, SyntaxError, KeyError):
            raise InputError(f"unknown unit {text!r} (e.g. mm, deg, kg, N*m, rad/s)") from None
        quantity = self.ureg.Quantity(1.0, unit)
        if not quantity._is_multiplicative:
            raise InputError(f"offset unit {text!r} is ambiguous: give kelvin")
        return quantity


@lru_cache(maxsize=256)
def _si(unit: str) -> tuple[float, str]:
    if not _UNIT.match(unit) or len(unit) > MAX_UNIT_LENGTH:
        raise InputError(f"{unit!r} is not a unit")
    import pint
    try:
        quantity = _UnitParser(unit).parse().to_base_units()
        factor = float(quantity.magnitude)
    except InputError:
        raise
    except (pint.errors.PintError, ArithmeticError, ValueError, TypeError):
        raise InputError(f"{unit!r} is not a unit with a finite SI value") from None
    if not (factor > 0 and factor != float("inf")):
        raise InputError(f"{unit!r} is not a unit with a finite SI value")
    return factor, str(quantity.dimensionality)


def unit_factor(unit: str) -> float:
    """How many SI units (m, kg, s, rad, A, K, …) one *unit* is: ``unit_factor("mm") == 1e-3``.

    pint is imported only here, when an input carries a unit; it resolves each unit name,
    and the grammar above combines them (so no input reaches pint's own expression parser).
    Offset units (°C, °F) are refused: a temperature difference or an absolute one would be
    ambiguous.

    Parameters
    ----------
    unit : str
        A unit such as ``mm``, ``deg``, ``kg*m^2`` or ``N·m``.
    """
    return _si(unit)[0]


def unit_dimension(unit: str) -> str:
    """The pint dimensionality of *unit*, e.g. ``"[length]"`` for mm, ``"dimensionless"`` for deg.

    Parameters
    ----------
    unit : str
        A unit such as ``mm`` or ``N·m``.
    """
    return _si(unit)[1]


def check_dimension(unit: str, dimension: Dimension | tuple[Dimension, ...]) -> None:
    """One sentence unless *unit* measures *dimension* (or one of several).

    Parameters
    ----------
    unit : str
        The unit an input carries.
    dimension : Dimension or tuple of Dimension
        What the field measures.
    """
    wanted = (dimension,) if isinstance(dimension, str) else tuple(dimension)
    found = unit_dimension(unit)
    if found not in {DIMENSIONS[d] for d in wanted}:
        article = "an" if wanted[0][0] in "aeiou" else "a"
        raise InputError(f"expected {article} {' or '.join(wanted)}, got a unit of {found} ({unit!r})")
