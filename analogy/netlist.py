"""SPICE netlist of a node system: plain text that runs unchanged in ``ngspice -b``."""

from __future__ import annotations

import re
from typing import Iterable

import numpy as np

from .elements import ZERO_TOL, elements
from .errors import InputError
from .presets import Preset, preset as get_preset

__all__ = ["netlist", "source_lines", "comment_text"]

_SAFE_COMMENT = re.compile(r"[^A-Za-z0-9 _.,:;=+\-*/()\[\]{}<>'#%@!?|~^&$]")


def comment_text(text) -> str:
    """Make *text* safe inside a ``*`` comment: one line, printable ASCII only."""
    return _SAFE_COMMENT.sub("?", str(text))


def _num(x: float) -> str:
    return repr(float(x))


def _node(k: int) -> str:
    return "0" if k == 0 else f"n{k}"


def source_lines(system, zero_tol: float = ZERO_TOL) -> list[str]:
    """Current sources for the joint forces: node currents i = T⁻ᵀ·F.

    A joint whose column of T⁻ᵀ is +1 at one node and −1 at another (or at ground)
    is one source between the two, as an actuator acting across two links;
    otherwise it is one grounded source per node, scaled by the column entry.
    """
    c = system.current_map
    lines = []
    for j, waves in enumerate(system.forces):
        if not waves:
            continue
        col = c[:, j].copy()
        col[np.abs(col) <= zero_tol * np.max(np.abs(col))] = 0.0
        plus = np.flatnonzero(np.isclose(col, 1.0, rtol=0, atol=zero_tol))
        minus = np.flatnonzero(np.isclose(col, -1.0, rtol=0, atol=zero_tol))
        nz = np.flatnonzero(col)
        two_terminal = len(plus) == 1 and len(minus) <= 1 and len(nz) == len(plus) + len(minus)
        for w_index, wave in enumerate(waves):
            suffix = "" if len(waves) == 1 else f"_{w_index + 1}"
            if two_terminal:
                a = int(plus[0]) + 1
                b = int(minus[0]) + 1 if len(minus) else 0
                # 'I n+ n- value' drives current out of n+ and into n-.
                lines.append(f"I{j + 1}{suffix} {_node(b)} {_node(a)} {wave.spice(1.0, system.t_stop)}")
            else:
                for k in nz:
                    lines.append(f"I{j + 1}{suffix}_n{k + 1} 0 {_node(k + 1)} "
                                 f"{wave.spice(float(col[k]), system.t_stop)}")
    return lines


def _matrix_text(m: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{x:.6g}" for x in row) + "]" for row in m) + "]"


def netlist(system, preset: str | Preset = "accurate", save: Iterable[str] | None = None,
            zero_tol: float = ZERO_TOL, title: str | None = None) -> str:
    """Write *system* as a SPICE netlist.

    Parameters
    ----------
    system : NodeSystem
    preset : str or Preset
        Accuracy preset for ``.options`` and ``.tran``.
    save : iterable of str, optional
        Node names (``n1`` …) to save; default all nodes.
    zero_tol : float
        Relative tolerance under which an element is left out.
    title : str, optional
        First line of the netlist.
    """
    p = get_preset(preset)
    nodes = system.nodes
    wanted = list(nodes) if save is None else list(save)
    unknown = [s for s in wanted if s not in nodes]
    if unknown:
        raise InputError(f"cannot save unknown node {unknown[0]!r}: nodes are {', '.join(nodes)}")
    if not wanted:
        raise InputError("nothing to save: name at least one node")
    info = system.info
    params = ", ".join(f"{k}={v!r}" for k, v in dict(info.get("parameters", {})).items())
    config = ", ".join(f"{k}={v!r}" for k, v in dict(info.get("configuration", {})).items())
    head = [
        f"* {comment_text(title or 'analogy equivalent circuit: ' + str(info.get('robot', 'custom')))}",
        f"* robot: {comment_text(info.get('robot', 'custom'))}",
        f"* parameters: {comment_text(params or 'none')}",
        f"* configuration: {comment_text(config or 'none')}",
        f"* topology: {comment_text(system.topology.describe())}, T = {_matrix_text(system.topology.matrix)}",
        "* analogy: force = current [A], velocity = voltage [V], mass = capacitance [F],",
        "* damping = conductance [S], stiffness = 1/inductance [1/H]; floating C = MP model",
    ]
    body = []
    for e in elements(system, zero_tol):
        body.append(f"{e.name} {_node(e.a)} {_node(e.b)} {_num(e.value)}")
    body += source_lines(system, zero_tol)
    v0 = system.initial_voltages
    tail = [
        ".ic " + " ".join(f"v({n})={_num(v)}" for n, v in zip(nodes, v0)),
        ".options " + " ".join(f"{k}={v}" for k, v in p.spice_options.items()),
        f".tran {_num(system.t_stop / p.steps)} {_num(system.t_stop)} 0 "
        f"{_num(system.t_stop / p.max_steps)} uic",
        ".save " + " ".join(f"v({n})" for n in wanted),
        ".end",
    ]
    return "\n".join(head + body + tail) + "\n"
