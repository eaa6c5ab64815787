"""Safe parsing of user expressions by a restricted grammar: nothing is evaluated as Python."""

from __future__ import annotations

import ast
import builtins
import keyword
import math
import operator
import re
import warnings
from typing import Iterable, Mapping

import numpy

from ..errors import InputError
from .quantities import Dimension, Measured, check_dimension, split_unit, unit_dimension, unit_factor

__all__ = ["parse_expression", "parse_matrix", "parse_vector", "parse_number",
           "parse_call", "split_entries", "reserved_name", "FUNCTION_NAMES", "MAX_LENGTH", "MAX_DEPTH",
           "MAX_EXPONENT"]

#: Longest expression accepted; bounds parser work on hostile input.
MAX_LENGTH = 20_000
#: Deepest nesting of operations accepted (``-(-(-(…)))``, ``2^2^2^…``).
MAX_DEPTH = 100
#: Largest |exponent| of a power whose base has symbols: keeps derivatives and expansions small.
MAX_EXPONENT = 100
#: Integers up to this magnitude stay exact in symbolic results; larger ones become floats.
_EXACT_INTEGER = 2 ** 53
#: Numerators and denominators of exact fractions stay below this many bits (floats reach 2^1024).
_FRACTION_BITS = 1024

#: Functions an expression may call.
FUNCTION_NAMES = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
                  "exp", "log", "sqrt", "abs")
_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
        ast.Div: operator.truediv, ast.Pow: operator.pow}


class _Numeric:
    """Backend that computes plain floats with the math module (no sympy import)."""

    constants = {"pi": math.pi, "e": math.e}
    functions = {name: getattr(math, "fabs" if name == "abs" else name) for name in FUNCTION_NAMES}

    @staticmethod
    def number(value):
        try:
            return float(value)
        except OverflowError:
            raise InputError(f"the number {_short(value)} is outside the floating-point range") from None

    @staticmethod
    def symbol(name):
        return None


class _Symbolic:
    """Backend that builds sympy expressions."""

    def __init__(self):
        import sympy as sp
        self.sp = sp
        self.constants = {"pi": sp.pi, "e": sp.E}
        self.functions = {name: getattr(sp, {"abs": "Abs"}.get(name, name)) for name in FUNCTION_NAMES}

    def symbol(self, name):
        return self.sp.Symbol(name, real=True)


def _short(value) -> str:
    text = str(value) if not isinstance(value, int) or value.bit_length() < 4000 else "with over 1000 digits"
    return text if len(text) <= 40 else f"{text[:12]}...{text[-6:]} ({len(text)} digits)"


def _too_deep(tree: ast.AST) -> bool:
    # Iterative, so that the check itself cannot overflow the stack. A chain such as
    # a + b + c is flat once built, so its left operands add no depth.
    stack = [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_DEPTH:
            return True
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.expr):
                chained = (isinstance(node, ast.BinOp) and child is node.left and isinstance(child, ast.BinOp)
                           and _CHAIN.get(type(child.op)) == _CHAIN.get(type(node.op), -1))
                stack.append((child, depth if chained else depth + 1))
    return False


_CHAIN = {ast.Add: 0, ast.Sub: 0, ast.Mult: 1, ast.Div: 1}


_CSE_NAME = re.compile(r"^x[0-9]+$")


def reserved_name(name: str) -> bool:
    """Whether *name* cannot be a parameter: a function, constant or any name the generated code uses.

    Parameters
    ----------
    name : str
        A proposed parameter name.
    """
    return (not name.isidentifier() or name.startswith("_") or keyword.iskeyword(name)
            or name in FUNCTION_NAMES or name in ("pi", "e", "numpy", "math", "mpmath", "sympy")
            or hasattr(builtins, name) or hasattr(numpy, name) or hasattr(math, name)
            or _CSE_NAME.match(name) is not None)


def _syntax_tree(text: str) -> ast.expr:
    if not isinstance(text, str):
        raise InputError(f"expected an expression string, got {type(text).__name__}")
    if len(text) > MAX_LENGTH:
        raise InputError(f"expression is longer than {MAX_LENGTH} characters")
    # '^' is the usual power sign in formulas; Python's parser reads it as xor.
    source = text.strip().replace("^", "**")
    if not source:
        raise InputError("empty expression")
    try:
        # ast.parse only builds a syntax tree; nothing is evaluated. Its SyntaxWarnings
        # (such as "invalid decimal literal") would be a second line after our sentence.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tree = ast.parse(source, mode="eval").body
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        raise InputError(f"cannot parse expression {_clip(text)!r}") from None
    if _too_deep(tree):
        raise InputError(f"expression {_clip(text)!r} nests more than {MAX_DEPTH} operations deep")
    return tree


def _clip(text: str) -> str:
    return text if len(text) <= 80 else f"{text[:60]}...{text[-12:]}"


class _Converter:
    """Walks a syntax tree, accepting only arithmetic on numbers, names and whitelisted calls.

    Every step is bounded: numeric work is done in floats and checked for overflow, and a
    symbolic result is built only where a name needs it, so no step can grow without limit.
    """

    def __init__(self, text: str, backend, symbols: Mapping | None, allow_lists: bool):
        self.text = text
        self.backend = backend
        self.symbols = symbols
        self.allow_lists = allow_lists
        self._pure: dict[int, bool] = {}

    def reject(self, what: str):
        raise InputError(f"expression {_clip(self.text)!r} is not allowed: {what}")

    def convert(self, node: ast.AST):
        try:
            value = self._convert(node)
            if self.backend is not _Numeric:
                for entry in (value if isinstance(value, list) else [value]):
                    if not isinstance(entry, list):
                        self._bounded(entry)
            return value
        except InputError:
            raise
        except RecursionError:
            raise InputError(f"expression {_clip(self.text)!r} is nested too deeply") from None
        except ZeroDivisionError:
            raise InputError(f"expression {_clip(self.text)!r} divides by zero") from None
        except OverflowError:
            raise InputError(f"expression {_clip(self.text)!r} leaves the floating-point range") from None
        except MemoryError:
            raise InputError(f"expression {_clip(self.text)!r} is too large to evaluate") from None
        except (ArithmeticError, ValueError, TypeError) as exc:
            # e.g. atan2(1) or sin(1, 2): wrong arguments; acos(2): outside the function's domain
            raise InputError(f"expression {_clip(self.text)!r} cannot be evaluated: {exc}") from None

    def _is_pure(self, node: ast.AST) -> bool:
        """Whether *node* names no symbol, so that it is a number computed in floats."""
        if id(node) not in self._pure:
            # Post-order without recursion: a long sum must not exhaust the stack here.
            order, stack = [], [node]
            while stack:
                current = stack.pop()
                order.append(current)
                stack.extend(ast.iter_child_nodes(current))
            for current in reversed(order):
                if isinstance(current, ast.Name):
                    named = self.symbols is not None and current.id in self.symbols
                    pure = current.id in self.backend.constants and not named
                else:
                    children = current.args if isinstance(current, ast.Call) else ast.iter_child_nodes(current)
                    pure = (not isinstance(current, (ast.List, ast.Tuple))
                            and all(self._pure[id(c)] for c in children))
                self._pure[id(current)] = pure
        return self._pure[id(node)]

    def _fold(self, node: ast.AST):
        """A symbol-free subtree as a sympy number, computed (bounded) in floats."""
        import sympy as sp
        if isinstance(node, ast.Constant) and isinstance(node.value, int) and not isinstance(node.value, bool):
            if abs(node.value) <= _EXACT_INTEGER:
                return sp.Integer(node.value)
        value = _Converter(self.text, _Numeric, {}, allow_lists=False)._convert(node)
        integers = all(isinstance(c.value, int) for c in ast.walk(node) if isinstance(c, ast.Constant))
        if integers and value.is_integer() and abs(value) <= _EXACT_INTEGER:
            return sp.Integer(int(value))
        return sp.Float(value, 17)

    def _number(self, value):
        """A numeric backend's result, checked: real and finite."""
        if isinstance(value, complex):
            raise InputError(f"expression {_clip(self.text)!r} cannot be evaluated: "
                             "a fractional power of a negative number gives complex numbers")
        if isinstance(value, float) and not math.isfinite(value):
            raise OverflowError
        return value

    def _bounded(self, expr) -> None:
        """Refuse a symbolic result whose numbers leave the float range or whose powers are too high."""
        import sympy as sp
        if not isinstance(expr, sp.Basic):
            return
        if expr.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
            self.reject("it divides by zero or is infinite")
        for atom in expr.atoms(sp.Number):
            if isinstance(atom, sp.Rational):
                if max(abs(atom.p).bit_length(), atom.q.bit_length()) > _FRACTION_BITS:
                    raise OverflowError
            elif not math.isfinite(float(atom)):
                raise OverflowError
        for power in expr.atoms(sp.Pow):
            if power.exp.is_Number and abs(power.exp) > MAX_EXPONENT:
                self.reject(f"an exponent of a symbolic base exceeds {MAX_EXPONENT} in magnitude")

    def _convert(self, node: ast.AST):
        b = self.backend
        numeric = b is _Numeric
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self.reject(f"constant {node.value!r} is not a real number")
            if isinstance(node.value, float) and not math.isfinite(node.value):
                self.reject("numbers must be finite")
            return b.number(node.value) if numeric else self._fold(node)
        if isinstance(node, ast.Name):
            name = node.id
            if name.startswith("_"):
                self.reject(f"name {name!r}")
            if name.lower() in ("nan", "inf", "infinity"):
                self.reject(f"numbers must be finite, got {name}")
            if self.symbols is not None and name in self.symbols:
                return self.symbols[name]
            if name in b.constants:
                return b.constants[name]
            if self.symbols is None and b.symbol(name) is not None:
                if reserved_name(name):
                    self.reject(f"{name!r} is the name of a function or constant")
                return b.symbol(name)
            known = ", ".join(sorted(self.symbols or {})) or "none"
            self.reject(f"unknown name {name!r} (known: {known})")
        if not numeric and not isinstance(node, (ast.List, ast.Tuple)) and self._is_pure(node):
            if isinstance(node, ast.Call):
                self._check_call(node)
            return self._fold(node)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            value = self._convert(node.operand)
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            left, right = self._convert(node.left), self._convert(node.right)
            if not numeric and isinstance(node.op, ast.Pow) and getattr(right, "is_Number", False) \
                    and abs(right) > MAX_EXPONENT:
                self.reject(f"an exponent of a symbolic base exceeds {MAX_EXPONENT} in magnitude")
            result = _OPS[type(node.op)](left, right)
            return self._number(result) if numeric else result
        if isinstance(node, ast.Call):
            self._check_call(node)
            args = [self._convert(a) for a in node.args]
            if not numeric:
                return b.functions[node.func.id](*args)
            try:
                return self._number(b.functions[node.func.id](*args))
            except ValueError:
                raise InputError(f"expression {_clip(self.text)!r} cannot be evaluated: {node.func.id}() "
                                 "is given an argument outside its domain") from None
        if isinstance(node, (ast.List, ast.Tuple)) and self.allow_lists:
            return [self._convert(e) for e in node.elts]
        self.reject(f"syntax {type(node).__name__}")

    def _check_call(self, node: ast.Call) -> None:
        if not isinstance(node.func, ast.Name) or node.func.id not in self.backend.functions:
            self.reject(f"only the functions {', '.join(FUNCTION_NAMES)} may be called")
        if node.keywords:
            self.reject("keyword arguments")


def parse_expression(text: str, symbols: Mapping | None = None) -> object:
    """Parse an arithmetic expression into sympy without evaluating any Python.

    Parameters
    ----------
    text : str
        Numbers, names, ``+ - * / ** ^``, parentheses and calls to :data:`FUNCTION_NAMES`.
    symbols : mapping, optional
        Allowed names. If omitted, any identifier not starting with ``_``
        becomes a real sympy symbol.
    """
    return _Converter(text, _Symbolic(), symbols, allow_lists=False).convert(_syntax_tree(text))


def _finite(value, text: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{text!r} is not a real number") from None
    if not math.isfinite(number):
        raise InputError(f"{text!r} is not finite")
    return number


def parse_number(text: str, dimension: Dimension | tuple[Dimension, ...] | None = None) -> float:
    """Parse a constant expression such as ``pi/4``, ``1e-3`` or ``250 ms`` to a finite float in SI.

    Parameters
    ----------
    text : str
        A constant expression, perhaps with a unit (``100 mm``, ``30 deg``).
    dimension : Dimension or tuple of Dimension, optional
        What the value measures: a unit of another dimension is refused in one sentence
        (``"10 kg"`` for a time). A bare number is taken as SI. A tuple (of several, or
        none: any dimension) returns a :class:`Measured` that keeps the unit's dimension
        for the model to judge.
    """
    try:
        return _finite(_Converter(text, _Numeric, {}, allow_lists=False).convert(_syntax_tree(text)), text)
    except InputError:
        split = split_unit(text) if isinstance(text, str) else None
        if split is None:
            raise
    number, unit = split        # a number with a unit, e.g. "100 mm": converted to SI
    if dimension:
        check_dimension(unit, dimension)
    value = _finite(parse_number(number) * unit_factor(unit), text)
    # Of several dimensions (an angle or a length), which one is for the model to judge.
    return Measured(value, unit_dimension(unit), unit) if isinstance(dimension, tuple) else value


def _depth(v) -> int:
    return 1 + _depth(v[0]) if isinstance(v, list) and v else (1 if isinstance(v, list) else 0)


def _nested(text: str, symbols, depth: int, numeric: bool):
    backend = _Numeric if numeric else _Symbolic()
    value = _Converter(text, backend, {} if numeric else symbols, allow_lists=True).convert(_syntax_tree(text))
    if _depth(value) != depth:
        kind = "matrix like [[a, b], [c, d]]" if depth == 2 else "vector like [a, b]"
        raise InputError(f"{text!r} is not a {kind}")
    return value


def parse_matrix(text: str, symbols: Mapping | None = None, numeric: bool = False) -> object:
    """Parse ``[[a, b], [c, d]]`` into a sympy Matrix (or, with *numeric*, a list of float rows).

    Parameters
    ----------
    text : str
        A matrix such as ``[[a, b], [c, d]]``.
    symbols : mapping of str to sympy Symbol, optional
        The names the entries may use.
    numeric : bool
        Return floats (constant entries only) instead of a sympy Matrix.
    """
    rows = _nested(text, symbols, 2, numeric)
    if any(not isinstance(r, list) or any(isinstance(e, list) for e in r) for r in rows):
        raise InputError(f"{text!r} is not a matrix like [[a, b], [c, d]]")
    lengths = {len(r) for r in rows}
    if len(lengths) != 1:
        raise InputError(f"matrix {text!r} has rows of different lengths {sorted(lengths)}")
    if numeric:
        return [[_finite(x, text) for x in r] for r in rows]
    import sympy as sp
    return sp.Matrix(rows)


def parse_vector(text: str, symbols: Mapping | None = None, numeric: bool = False,
                 dimension: Dimension | tuple[Dimension, ...] | None = None) -> list:
    """Parse ``[a, b, c]`` or ``a, b, c`` into a list of sympy expressions (or floats).

    Parameters
    ----------
    text : str
        A vector such as ``[a, b]`` or ``a, b``.
    symbols : mapping of str to sympy Symbol, optional
        The names the entries may use.
    numeric : bool
        Return floats (constant entries only).
    dimension : Dimension or tuple of Dimension, optional
        What the entries measure, when they carry units (see :func:`parse_number`).
    """
    stripped = text.strip()
    if not stripped.startswith("["):
        stripped = f"[{stripped}]"
    try:
        items = _nested(stripped, symbols, 1, numeric)
    except InputError:
        if not numeric or not any(split_unit(e) for e in _flat(stripped)):
            raise
        return [parse_number(e, dimension) for e in _flat(stripped)]        # entries with units
    return [_finite(x, text) for x in items] if numeric else items


def _flat(text: str) -> list[str]:
    """The entries of a one-level ``[a, b]`` split at its top-level commas (units are not Python syntax)."""
    inner = text.strip()
    if not (inner.startswith("[") and inner.endswith("]")):
        return []
    out, depth, start = [], 0, 1
    for k, ch in enumerate(inner[1:-1], 1):
        depth += ch in "([" and 1 or (-1 if ch in ")]" else 0)
        if depth < 0 or ch in "[]" and depth:
            return []
        if ch == "," and depth == 0:
            out.append(inner[start:k])
            start = k + 1
    out.append(inner[start:-1])
    return [e.strip() for e in out]


def split_entries(text: str) -> list:
    """The entries of ``[[a, b], [c, d]]`` or ``[a, b]`` (or ``a, b``) as nested lists of entry texts.

    Only the list structure is read here; each entry is left as its own text for
    :func:`parse_expression` or :func:`parse_number`, so a matrix given on the command
    line and one given in a scene file go through the same parser.

    Parameters
    ----------
    text : str
        A bracketed list of expressions, or of such lists.
    """
    stripped = text.strip() if isinstance(text, str) else text
    if isinstance(stripped, str) and not stripped.startswith("["):
        stripped = f"[{stripped}]"
    tree = _syntax_tree(stripped)
    source = stripped.replace("^", "**")

    def entries(node, depth):
        if isinstance(node, (ast.List, ast.Tuple)):
            if depth > 1:
                raise InputError(f"{text!r} nests lists too deeply: give a vector or a matrix")
            return [entries(e, depth + 1) for e in node.elts]
        return ast.get_source_segment(source, node)
    value = entries(tree, 0)
    if not isinstance(value, list):
        parse_expression(text)          # the grammar's own sentence if it rejects the text
        raise InputError(f"{text!r} is not a list like [a, b] or [[a, b], [c, d]]")
    return value


def parse_call(text: str, names: Iterable[str]) -> tuple[str, list[float], dict[str, float]]:
    """Parse ``name(1, 2, key=3)`` with numeric arguments; ``name`` must be in *names*.

    Parameters
    ----------
    text : str
        A call such as ``step(1, 0.5, 0.01)``.
    names : iterable of str
        The names that may be called.
    """
    tree = _syntax_tree(text)
    allowed = set(names)
    if isinstance(tree, ast.Call) and isinstance(tree.func, ast.Name) and tree.func.id in allowed:
        conv = _Converter(text, _Numeric, {}, allow_lists=False)

        def number(node):
            return _finite(conv.convert(node), text)

        args = [number(a) for a in tree.args]
        kwargs = {}
        for kw in tree.keywords:
            if kw.arg is None:
                raise InputError(f"{text!r}: '**' is not allowed")
            kwargs[kw.arg] = number(kw.value)
        return tree.func.id, args, kwargs
    raise InputError(f"{text!r} is not one of {', '.join(f'{n}(...)' for n in sorted(allowed))}")
