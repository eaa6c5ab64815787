"""A batch netlist of a node stack, written from its element columns with no circuit object per row."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .description import current_sources, element_arrays
from .elements import ZERO_TOL
from .netlist import _node, _summed_comment, analysis_lines
from .node_stack import NodeStack
from .source_values import source_values
from .spice_numbers import spice_text as _num
from .step_sources import first_step_lines

__all__ = ["write_stack"]

#: Stands for a row's number in :func:`write_stack`'s templates: no netlist text holds it.
_ROW = "\x00"


def write_stack(stack: NodeStack, settings, zero_tol: float = ZERO_TOL) -> str:
    """:func:`write_batch` of a stack's :func:`~analogy.circuit.description.circuits`, written
    from its element columns: the same text, with no object per row (a batch writes one per group).

    Each row's lines are one template per pattern of kept elements, split where the row's number
    goes, joined with it and filled with ``%`` (``%r`` of a float is its repr, as everywhere else).
    Where every row keeps every element, the rows' templates are one format, kept for the next
    circuit of the shape, filled once.

    Parameters
    ----------
    stack : NodeStack
        Systems sharing their inputs and springs (one part of :meth:`NodeStack.partition`).
    settings : TransientSettings
        Their shared transient settings.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    if len(stack.partition()) != 1:
        raise ValueError("write_stack needs systems that share their inputs and springs: use write_batch")
    places, values, coefs = element_arrays(stack, zero_tol)
    count, dof, x = len(stack), stack.dof, f"x{_ROW}_"
    # the rows' inputs are one: their sources' text is made once for the stack a take was taken from
    sources, = stack.rowwise(f"source lines at {zero_tol!r}", lambda s: (_source_lines(s.inputs_row, zero_tol),))
    kept = coefs != 0.0
    used = kept.any(axis=0)         # a position no row keeps (a joint with no damper) is in no template
    places, values, kept = [p for p, u in zip(places, used.tolist()) if u], values[:, used], kept[:, used]
    # a value every row shares (a damper, a start at rest) is written into the template once
    fixed = _shared_columns(values)
    devices = [(f"{kind}{x}{a} {x}n{a} 0 " if b == 0 else f"{kind}{x}{a}_{b} {x}n{a} {x}n{b} ")
               + (repr(float(values[0, j])) if same else "%r") for j, ((kind, a, b), same) in enumerate(zip(places, fixed))]
    varying = values[:, [not same for same in fixed]]
    lines = [f"* analogy batch of {count} independent circuits"]
    template = "\n".join(devices + list(sources)).split(_ROW)
    if kept.all():                  # every row keeps every element: one format for all the rows
        if template != [""]:
            lines.append(_numbered(tuple(template), count, "\n") % tuple(varying.ravel().tolist()))
    else:
        templates: dict = {}
        for k, (row, mask) in enumerate(zip(varying.tolist(), map(tuple, kept.tolist()))):
            pieces = templates.get(mask)
            if pieces is None:
                pieces = templates[mask] = "\n".join([d for d, m in zip(devices, mask) if m] + list(sources)).split(_ROW)
            row = tuple(v for v, m in zip(row, (m for m, same in zip(mask, fixed) if not same)) if m)
            if pieces != [""]:
                lines.append(str(k).join(pieces) % row)
    v0 = stack.initial_voltages
    if not np.all(np.isfinite(v0)):
        _num(v0[~np.isfinite(v0)][0])           # its one sentence
    fixed = _shared_columns(v0)
    per_row = " ".join(f"v({x}n{i + 1})=" + (repr(float(v0[0, i])) if same else "%r") for i, same in enumerate(fixed))
    ic = _numbered(tuple(per_row.split(_ROW)), count, " ") % tuple(v0[:, [not same for same in fixed]].ravel().tolist())
    lines += first_step_lines(settings, "x0_n1")
    return "\n".join(lines + analysis_lines(settings, ic_text=ic, save_text=_saved(count, dof)) + [".end"]) + "\n"


@lru_cache(maxsize=64)
def _numbered(pieces: tuple[str, ...], count: int, between: str) -> str:
    """*pieces* joined with each row's number, 0 to *count* − 1, the rows joined by *between*: one
    format for a whole stack's rows (the same for every circuit of a family)."""
    return between.join([str(k).join(pieces) for k in range(count)])


def _source_lines(first, zero_tol: float) -> tuple[str, ...]:
    """The current sources of *first*'s inputs as template lines of :func:`write_stack` (no ``%`` of their own)."""
    lines, x = [], f"x{_ROW}_"
    for name, a, b, v, terms in source_values(current_sources(first, zero_tol), first.t_stop, None):
        if terms:
            lines.append(_summed_comment(f"I{x}{name[1:]}", a, terms))
        lines.append(f"I{x}{name[1:]} {_node(b, x)} {_node(a, x)} {v}")
    return tuple(line.replace("%", "%%") for line in lines)


@lru_cache(maxsize=64)
def _saved(count: int, dof: int) -> str:
    """The ``.save`` text of *count* sub-circuits of *dof* nodes (the same for every batch of that shape)."""
    return " ".join(f"v(x{k}_n{i + 1})" for k in range(count) for i in range(dof))


def _shared_columns(values: np.ndarray) -> list[bool]:
    """Per column of *values* (rows, columns), whether every row's value is the first's, bit for bit
    (so its text is too)."""
    bits = np.ascontiguousarray(values, dtype=float).view(np.int64)
    return (bits == bits[:1]).all(axis=0).tolist()
