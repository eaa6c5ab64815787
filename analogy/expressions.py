"""Safe parsing of user expressions into sympy, by a restricted grammar (no eval)."""

from __future__ import annotations

import ast
import math
from typing import Iterable, Mapping

import sympy as sp

from .errors import InputError

__all__ = ["parse_expression", "parse_matrix", "parse_vector", "parse_number",
           "parse_call", "FUNCTIONS", "MAX_LENGTH"]

#: Longest expression accepted; bounds parser work on hostile input.
MAX_LENGTH = 20_000

#: Functions an expression may call, by name.
FUNCTIONS = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan,
    "asin": sp.asin, "acos": sp.acos, "atan": sp.atan, "atan2": sp.atan2,
    "sinh": sp.sinh, "cosh": sp.cosh, "tanh": sp.tanh,
    "exp": sp.exp, "log": sp.log, "sqrt": sp.sqrt, "abs": sp.Abs,
}
_CONSTANTS = {"pi": sp.pi, "e": sp.E}
_BINOPS = {
    ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a ** b,
}


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
        # ast.parse only builds a syntax tree; nothing is evaluated.
        return ast.parse(source, mode="eval").body
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        raise InputError(f"cannot parse expression {text!r}") from None


class _Converter:
    """Walks a syntax tree, accepting only arithmetic on numbers, names and whitelisted calls."""

    def __init__(self, text: str, symbols: Mapping[str, sp.Symbol] | None,
                 allow_lists: bool):
        self.text = text
        self.symbols = symbols
        self.allow_lists = allow_lists

    def reject(self, what: str):
        raise InputError(f"expression {self.text!r} is not allowed: {what}")

    def convert(self, node: ast.AST):
        try:
            return self._convert(node)
        except RecursionError:
            raise InputError(f"expression {self.text!r} is nested too deeply") from None

    def _convert(self, node: ast.AST):
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self.reject(f"constant {node.value!r} is not a real number")
            if isinstance(node.value, float) and not math.isfinite(node.value):
                self.reject("numbers must be finite")
            return sp.Float(node.value, 17) if isinstance(node.value, float) else sp.Integer(node.value)
        if isinstance(node, ast.Name):
            name = node.id
            if name.startswith("_"):
                self.reject(f"name {name!r}")
            if name.lower() in ("nan", "inf", "infinity"):
                self.reject(f"numbers must be finite, got {name}")
            if self.symbols is not None and name in self.symbols:
                return self.symbols[name]
            if name in _CONSTANTS:
                return _CONSTANTS[name]
            if self.symbols is None:
                return sp.Symbol(name, real=True)
            self.reject(f"unknown name {name!r} (known: {', '.join(sorted(self.symbols)) or 'none'})")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            value = self._convert(node.operand)
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            return _BINOPS[type(node.op)](self._convert(node.left), self._convert(node.right))
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
                self.reject(f"only the functions {', '.join(sorted(FUNCTIONS))} may be called")
            if node.keywords:
                self.reject("keyword arguments")
            return FUNCTIONS[node.func.id](*[self._convert(a) for a in node.args])
        if isinstance(node, (ast.List, ast.Tuple)) and self.allow_lists:
            return [self._convert(e) for e in node.elts]
        self.reject(f"syntax {type(node).__name__}")


def parse_expression(text: str, symbols: Mapping[str, sp.Symbol] | None = None) -> sp.Expr:
    """Parse an arithmetic expression into sympy without evaluating any Python.

    Parameters
    ----------
    text : str
        Numbers, names, ``+ - * / ** ^``, parentheses and calls to :data:`FUNCTIONS`.
    symbols : mapping, optional
        Allowed names. If omitted, any identifier not starting with ``_``
        becomes a real sympy symbol.
    """
    tree = _syntax_tree(text)
    return _Converter(text, symbols, allow_lists=False).convert(tree)


def parse_number(text: str) -> float:
    """Parse a constant expression such as ``pi/4`` or ``1e-3`` to a finite float."""
    value = parse_expression(text, symbols={})
    try:
        number = float(value)
    except TypeError:
        raise InputError(f"{text!r} is not a real number") from None
    if not math.isfinite(number):
        raise InputError(f"{text!r} is not finite")
    return number


def _nested(text: str, symbols, depth: int):
    tree = _syntax_tree(text)
    value = _Converter(text, symbols, allow_lists=True).convert(tree)

    def level(v):
        return 1 + level(v[0]) if isinstance(v, list) and v else (1 if isinstance(v, list) else 0)

    if level(value) != depth:
        kind = "matrix like [[a, b], [c, d]]" if depth == 2 else "vector like [a, b]"
        raise InputError(f"{text!r} is not a {kind}")
    return value


def parse_matrix(text: str, symbols: Mapping[str, sp.Symbol] | None = None) -> sp.Matrix:
    """Parse ``[[a, b], [c, d]]`` (rows of expressions) into a sympy Matrix."""
    rows = _nested(text, symbols, 2)
    if any(not isinstance(r, list) or any(isinstance(e, list) for e in r) for r in rows):
        raise InputError(f"{text!r} is not a matrix like [[a, b], [c, d]]")
    lengths = {len(r) for r in rows}
    if len(lengths) != 1:
        raise InputError(f"matrix {text!r} has rows of different lengths {sorted(lengths)}")
    return sp.Matrix(rows)


def parse_vector(text: str, symbols: Mapping[str, sp.Symbol] | None = None) -> list:
    """Parse ``[a, b, c]`` or ``a, b, c`` into a list of sympy expressions."""
    stripped = text.strip()
    if not stripped.startswith("["):
        stripped = f"[{stripped}]"
    items = _nested(stripped, symbols, 1)
    return items


def parse_call(text: str, names: Iterable[str]) -> tuple[str, list[float], dict[str, float]]:
    """Parse ``name(1, 2, key=3)`` with numeric arguments; ``name`` must be in *names*."""
    tree = _syntax_tree(text)
    allowed = set(names)
    if isinstance(tree, ast.Call) and isinstance(tree.func, ast.Name) and tree.func.id in allowed:
        conv = _Converter(text, {}, allow_lists=False)

        def number(node):
            value = conv.convert(node)
            try:
                result = float(value)
            except TypeError:
                raise InputError(f"{text!r}: arguments must be numbers") from None
            if not math.isfinite(result):
                raise InputError(f"{text!r}: arguments must be finite")
            return result

        args = [number(a) for a in tree.args]
        kwargs = {}
        for kw in tree.keywords:
            if kw.arg is None:
                raise InputError(f"{text!r}: '**' is not allowed")
            kwargs[kw.arg] = number(kw.value)
        return tree.func.id, args, kwargs
    raise InputError(f"{text!r} is not one of {', '.join(f'{n}(...)' for n in sorted(allowed))}")
