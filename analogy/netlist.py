"""SPICE netlist of a node system: plain text that runs unchanged in ``ngspice -b``."""

from __future__ import annotations

import re
from typing import Iterable

import numpy as np

from .elements import ZERO_TOL, elements
from .errors import InputError
from .presets import Preset, preset as get_preset

__all__ = ["netlist", "element_lines", "circuit_lines", "source_lines", "source_terms",
           "analysis_lines", "header_lines",
           "comment_text", "save_vectors"]

_SAFE_COMMENT = re.compile(r"[^A-Za-z0-9 _.,:;=+\-*/()\[\]{}<>'#%@!?|~^&$]")


def comment_text(text) -> str:
    """Make *text* safe inside a ``*`` comment: one line, printable ASCII only."""
    return _SAFE_COMMENT.sub("?", str(text))


def _num(x: float) -> str:
    return repr(float(x))


def _node(k: int, prefix: str = "") -> str:
    return "0" if k == 0 else f"{prefix}n{k}"


def element_lines(system, zero_tol: float = ZERO_TOL, prefix: str = "",
                  realizable: bool = False) -> tuple[list[str], dict[str, float]]:
    """SPICE lines of the circuit elements, and initial voltages of any auxiliary nodes.

    With *realizable*, an element with a negative value is built from its positive
    magnitude behind an ideal inverting coupling (a 1:−1 transformer; mechanically a
    reversing pulley): a VCVS makes v_x = v_b − v_a, a zero-volt source senses the
    current of the positive element on x, and a CCCS drives that current from a to b.
    """
    return circuit_lines([(e.kind, e.a, e.b, e.value) for e in elements(system, zero_tol)],
                         prefix, system.initial_voltages if realizable else None)


def circuit_lines(parts, prefix: str = "", realizable_from=None) -> tuple[list[str], dict[str, float]]:
    """Lines of elements given as (kind, a, b, SPICE value); see :func:`element_lines`.

    *realizable_from* holds the node voltages at t = 0 when negative values are to be
    realized; None writes them as they are.
    """
    lines, ic = [], {}
    for kind, na, nb, value in parts:
        name = f"{kind}{prefix}{na}" if nb == 0 else f"{kind}{prefix}{na}_{nb}"
        a, b = _node(na, prefix), _node(nb, prefix)
        if realizable_from is None or value >= 0:
            lines.append(f"{name} {a} {b} {_num(value)}")
            continue
        x, y = f"{name.lower()}_x", f"{name.lower()}_y"
        lines += [f"E{name} {x} 0 {b} {a} 1",
                  f"V{name} {x} {y} DC 0",
                  f"{name} {y} 0 {_num(-value)}",
                  f"F{name} {a} {b} V{name} 1"]
        v0 = realizable_from
        ic[x] = ic[y] = (v0[nb - 1] if nb else 0.0) - v0[na - 1]
    return lines, ic


def analysis_lines(preset: Preset, t_stop: float, ic: dict, save: Iterable[str],
                   options: dict | None = None) -> list[str]:
    """``.ic``, ``.options`` (the preset's, updated by *options*), ``.tran`` (uic) and ``.save``."""
    p = get_preset(preset)
    opts = dict(p.spice_options, **(options or {}))
    return [
        ".ic " + " ".join(f"v({n})={_num(v)}" for n, v in ic.items()),
        ".options " + " ".join(f"{k}={v}" for k, v in opts.items()),
        f".tran {_num(t_stop / p.steps)} {_num(t_stop)} 0 {_num(t_stop / p.max_steps)} uic",
        ".save " + " ".join(save),
    ]


def source_lines(system, zero_tol: float = ZERO_TOL, prefix: str = "", terms=None) -> list[str]:
    """Current sources for the joint forces: node currents i = T⁻ᵀ·F.

    A joint whose column of T⁻ᵀ is +1 at one node and −1 at another (or at ground)
    is one source between the two, as an actuator acting across two links;
    otherwise it is one grounded source per node, scaled by the column entry.
    *terms*, if given, are the system's :func:`source_terms`, derived once for many.
    """
    terms = source_terms(system, zero_tol) if terms is None else terms
    return [f"I{prefix}{name} {_node(b, prefix)} {_node(a, prefix)} {spec}" for name, a, b, spec in terms]


def source_terms(system, zero_tol: float = ZERO_TOL) -> list[tuple[str, int, int, str]]:
    """The sources of :func:`source_lines` as (name, node a, node b, SPICE source text):
    each drives its current into node a and out of node b (0 is ground)."""
    c = system.current_map
    terms = []
    for j, waves in enumerate(system.forces):
        if not waves:
            continue
        col = c[:, j].tolist()
        floor = zero_tol * max(abs(x) for x in col)
        col = [0.0 if abs(x) <= floor else x for x in col]
        plus = [k for k, x in enumerate(col) if abs(x - 1.0) <= zero_tol]
        minus = [k for k, x in enumerate(col) if abs(x + 1.0) <= zero_tol]
        nz = [k for k, x in enumerate(col) if x != 0.0]
        two_terminal = len(plus) == 1 and len(minus) <= 1 and len(nz) == len(plus) + len(minus)
        for w_index, wave in enumerate(waves):
            suffix = "" if len(waves) == 1 else f"_{w_index + 1}"
            if two_terminal:
                # 'I n+ n- value' drives current out of n+ and into n-.
                b = int(minus[0]) + 1 if len(minus) else 0
                terms.append((f"{j + 1}{suffix}", int(plus[0]) + 1, b, wave.spice(1.0, system.t_stop)))
            else:
                terms += [(f"{j + 1}{suffix}_n{k + 1}", k + 1, 0, wave.spice(float(col[k]), system.t_stop))
                          for k in nz]
    return terms


def _matrix_text(m: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{x:.6g}" for x in row) + "]" for row in m) + "]"


def save_vectors(system, save: Iterable[str] | None = None, zero_tol: float = ZERO_TOL,
                 realizable: bool = False) -> list[str]:
    """The ``.save`` vectors for node and element names.

    A node name (``n1`` …) gives its voltage ``v(n1)``; an element name of
    :func:`analogy.elements.elements` (``C1``, ``C1_2``, ``R1``, ``L2_3`` …) gives its
    current ``@c1_2[i]``, flowing from its first terminal through it to its second, as
    SPICE reports a device ``name a b value``. With *realizable*, a negative element is
    built behind an inverting coupling and its current is that of the coupling's
    current source ``F<name>``, which carries it from a to b. Names are checked against
    the system's nodes and elements, so nothing else can reach the netlist.
    """
    nodes = system.nodes
    wanted = list(nodes) if save is None else list(save)
    if not wanted:
        raise InputError("nothing to save: name at least one node")
    found = {e.name.lower(): e for e in elements(system, zero_tol)}
    out = []
    for item in wanted:
        if isinstance(item, str) and item in nodes:
            out.append(f"v({item})")
            continue
        e = found.get(item.lower()) if isinstance(item, str) else None
        if e is None:
            names = ", ".join(e.name for e in found.values()) or "none"
            raise InputError(f"cannot save unknown node or element {item!r}: nodes are "
                             f"{', '.join(nodes)}; elements are {names}")
        device = f"F{e.name}" if realizable and e.value < 0 else e.name
        out.append(f"@{device.lower()}[i]")
    return list(dict.fromkeys(out))


def netlist(system, preset: str | Preset = "accurate", save: Iterable[str] | None = None,
            zero_tol: float = ZERO_TOL, title: str | None = None, realizable: bool = False) -> str:
    """Write *system* as a SPICE netlist.

    Parameters
    ----------
    system : NodeSystem
    preset : str or Preset
        Accuracy preset for ``.options`` and ``.tran``.
    save : iterable of str, optional
        Node names (``n1`` …) whose voltages to save and element names (``C1_2``,
        ``R1`` …) whose currents to save (see :func:`save_vectors`); default all nodes.
    zero_tol : float
        Relative tolerance under which an element is left out.
    title : str, optional
        First line of the netlist.
    realizable : bool
        Build negative elements from positive ones behind inverting couplings.
    """
    nodes = system.nodes
    vectors = save_vectors(system, save, zero_tol, realizable)
    body, aux_ic = element_lines(system, zero_tol, realizable=realizable)
    body += source_lines(system, zero_tol)
    ic = dict(zip(nodes, system.initial_voltages.tolist()))
    ic.update(aux_ic)
    # A capacitor driven by an ideal source makes the trapezoidal rule ring from step to
    # step, and tight step control then collapses; gear damps it.
    options = {"method": "gear"} if aux_ic else None
    tail = analysis_lines(preset, system.t_stop, ic, vectors, options) + [".end"]
    return "\n".join(header_lines(system, title, realizable) + body + tail) + "\n"


def header_lines(system, title: str | None = None, realizable: bool = False) -> list[str]:
    """Comment lines naming the robot, parameters, configuration and topology."""
    info = system.info
    params = ", ".join(f"{k}={v!r}" for k, v in dict(info.get("parameters", {})).items())
    config = ", ".join(f"{k}={v!r}" for k, v in dict(info.get("configuration", {})).items())
    lines = [
        f"* {comment_text(title or 'analogy equivalent circuit: ' + str(info.get('robot', 'custom')))}",
        f"* robot: {comment_text(info.get('robot', 'custom'))}",
        f"* parameters: {comment_text(params or 'none')}",
        f"* configuration: {comment_text(config or 'none')}",
        f"* topology: {comment_text(system.topology.describe())}, T = {_matrix_text(system.topology.matrix)}",
        "* analogy: force = current [A], velocity = voltage [V], mass = capacitance [F],",
        "* damping = conductance [S], stiffness = 1/inductance [1/H]; floating C = MP model",
    ]
    if realizable:
        lines.append("* realizable: negative elements sit behind 1:-1 couplings (E, V, F sources)")
    return lines
