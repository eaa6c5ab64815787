"""A written netlist read back into its parts: comments, element lines (name, nodes, the rest) and analysis blocks."""

from __future__ import annotations

from typing import NamedTuple

from ..errors import InputError

__all__ = ["NetlistLine", "NetlistParts", "netlist_lines"]

#: Nodes an element line names, by its first letter (F and H name their controlling source after them).
NODE_COUNTS = {"R": 2, "C": 2, "L": 2, "I": 2, "V": 2, "B": 2, "F": 2, "H": 2, "E": 4, "G": 4}


class NetlistLine(NamedTuple):
    """One element: its name, the nodes it joins and the rest of its line (value, source or expression)."""

    name: str
    nodes: tuple[str, ...]
    model: str


class NetlistParts(NamedTuple):
    """A netlist's comment lines (without ``*``), element lines and analysis blocks (``.control`` … ``.endc`` one)."""

    comments: list[str]
    elements: list[NetlistLine]
    directives: list[str]


def netlist_lines(text: str) -> NetlistParts:
    """The parts of a netlist as analogy writes it (continuation lines joined, ``.end`` dropped).

    Parameters
    ----------
    text : str
        The netlist.
    """
    lines: list[str] = []
    for raw in text.splitlines():
        if raw.startswith("+") and lines:
            lines[-1] += " " + raw[1:].strip()
        elif raw.strip():
            lines.append(raw.rstrip())
    comments, elements, directives, control = [], [], [], None
    for line in lines:
        low = line.strip().lower()
        if control is not None:
            control.append(line)
            if low == ".endc":
                directives.append("\n".join(control))
                control = None
        elif low == ".control":
            control = [line]
        elif low == ".end":
            break
        elif line.startswith("*"):
            comments.append(line[1:].strip())
        elif line.startswith("."):
            directives.append(line)
        else:
            words = line.split()
            count = NODE_COUNTS.get(words[0][0].upper())
            if count is None or len(words) < count + 2:
                raise InputError(f"element {words[0]} cannot be drawn as a part: only R, C, L, I, V, B, E, F, G and "
                                 "H lines are (a subcircuit is not)")
            elements.append(NetlistLine(words[0], tuple(words[1:count + 1]), " ".join(words[count + 1:])))
    return NetlistParts(comments, elements, directives)
