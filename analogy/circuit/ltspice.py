"""A netlist in LTspice's dialect, and its schematic (``.asc``) of LTspice's stock symbols with the nets by flag."""

from __future__ import annotations

import math
import re

from .netlist_lines import NetlistLine, netlist_lines

__all__ = ["ltspice_netlist", "ltspice_schematic"]

#: Digits LTspice keeps: past 6 its waveform data are double precision (``.options numdgt``).
NUMDGT = 15
_BRACED = re.compile(r"^([IVQ])=\{(.*)\}$", re.S)
#: A charge c·v_own as written for ngspice: the own voltage is LTspice's x.
_OWN_GROUNDED = r"\*v\({a}\)$"
_OWN_FLOATING = r"\*\(v\({a}\)-v\({b}\)\)$"
#: LTspice's stock symbols: each kind's symbol and its pins (SpiceOrder) relative to the origin at R0.
_SYMBOLS = {
    "R": ("res", ((16, 16), (16, 96))), "L": ("ind", ((16, 16), (16, 96))), "C": ("cap", ((16, 0), (16, 64))),
    "V": ("voltage", ((0, 16), (0, 96))), "I": ("current", ((0, 0), (0, 80))),
    "BI": ("bi", ((0, 0), (0, 80))), "BV": ("bv", ((0, 16), (0, 96))), "F": ("f", ((0, 0), (0, 80))),
    "H": ("h", ((0, 16), (0, 96))), "E": ("e", ((0, 16), (0, 96), (-48, 32), (-48, 80))),
    "G": ("g", ((0, 96), (0, 16), (-48, 32), (-48, 80))),
}


def _conditionals(text: str) -> str:
    """``c ? a : b`` (ngspice) as ``if(c,a,b)`` (LTspice), at every depth of parentheses."""
    depth, question = 0, -1
    for k, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0 and ch == "?" and question < 0:
            question = k
        elif depth == 0 and ch == ":" and question >= 0:
            return (f"if({_conditionals(text[:question])},{_conditionals(text[question + 1:k])},"
                    f"{_conditionals(text[k + 1:])})")
    out, start, depth = [], 0, 0
    for k, ch in enumerate(text):           # no top-level conditional: look inside each parenthesis
        if ch == "(":
            if depth == 0:
                out.append(text[start:k + 1])
                start = k + 1
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth == 0:
                out.append(_conditionals(text[start:k]) + ")")
                start = k + 1
    return "".join(out) + text[start:]


def _expression(text: str) -> str:
    """An ngspice behavioural expression in LTspice's words: ``**`` for powers (``^`` is XOR there),
    ``if()`` for conditionals, no spaces (a ``Q=`` with spaces is not one word)."""
    return _conditionals(text.replace(" ", "").replace("^", "**"))


def _element(line: NetlistLine) -> str:
    match = _BRACED.match(line.model)
    if match is None:
        return " ".join((line.name, *line.nodes, line.model))
    kind, body = match.group(1), _expression(match.group(2))
    if kind == "Q":                 # the charge's own-voltage factor is LTspice's x
        a, b = (re.escape(n) for n in line.nodes)
        pattern = _OWN_GROUNDED.format(a=a) if line.nodes[1] == "0" else _OWN_FLOATING.format(a=a, b=b)
        body = re.sub(pattern, "*x", body)
    return " ".join((line.name, *line.nodes, f"{kind}={body}"))


def _directive(block: str) -> str | None:
    """An analysis line as LTspice reads it, or None for what is ngspice's alone."""
    words = block.split()
    head = words[0].lower()
    if head in (".control", ".print"):
        return None
    if head == ".options":
        kept = [w for w in words[1:] if w.lower() not in ("klu", "interp")]
        return " ".join([".options", *kept, f"numdgt={NUMDGT}"])
    return block


def ltspice_netlist(netlist: str) -> str:
    """The ngspice netlist *netlist* in LTspice's dialect.

    Behavioural expressions lose their braces (LTspice evaluates ``{…}`` once, as a
    parameter), take ``**`` for powers and ``if(c, a, b)`` for ``c ? a : b``; a charge
    ``Q={c·v(a)}`` becomes ``Q=c*x``, x being the capacitor's own voltage in LTspice.
    ``.options`` lose ngspice's ``klu`` and ``interp`` and gain ``numdgt=15`` (double
    precision waveforms); ``.control`` blocks and ``.print`` are left out. A linear
    circuit's netlist is also plain SPICE that ngspice runs to the same result (a test).

    Parameters
    ----------
    netlist : str
        A netlist as :func:`~analogy.solvers.transient.netlist` writes it.
    """
    parts = netlist_lines(netlist)
    lines = [f"* {c}" for c in parts.comments] or ["* analogy"]
    lines += [_element(e) for e in parts.elements]
    lines += [d for d in map(_directive, parts.directives) if d is not None]
    return "\n".join(lines + [".end"]) + "\n"


def ltspice_schematic(netlist: str) -> str:
    """An LTspice netlist (:func:`ltspice_netlist`) as an LTspice schematic (``.asc``).

    Each element is LTspice's stock symbol of its kind (res, cap, ind, current, voltage,
    bi, bv, e, f, g, h) with its line's value; each pin gets a net flag of its node's name,
    0 being ground; the analysis lines are directives and the comment header a comment.

    Parameters
    ----------
    netlist : str
        A netlist in LTspice's dialect.
    """
    parts = netlist_lines(netlist)
    columns = max(4, math.ceil(math.sqrt(len(parts.elements) * 1.6)))
    top = 64 + 32 * len(parts.comments)         # below the comment header
    out = []
    for k, e in enumerate(parts.elements):
        x, y = 160 * (k % columns), top + 192 * (k // columns)
        kind = e.name[0].upper()
        if kind == "B":
            kind += e.model[0].upper()
        symbol, pins = _SYMBOLS[kind]
        out += [f"SYMBOL {symbol} {x} {y} R0", f"SYMATTR InstName {e.name}", f"SYMATTR Value {e.model}"]
        out += [f"FLAG {x + px} {y + py} {node}" for node, (px, py) in zip(e.nodes, pins)]
    rows = math.ceil(len(parts.elements) / columns)
    below = top + 192 * rows
    texts = [f"TEXT 0 {below + 48 * k} Left 2 !{d}" for k, d in enumerate(parts.directives)]
    if parts.comments:
        texts.append("TEXT 0 0 Left 2 ;" + "\\n".join(parts.comments))    # LTspice's line break in a text
    width, height = 160 * columns + 160, below + 48 * len(parts.directives) + 96
    return "\n".join(["Version 4", f"SHEET 1 {width} {height}", *out, *texts]) + "\n"
