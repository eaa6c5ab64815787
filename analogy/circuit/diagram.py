"""Circuit and mechanical-system diagrams of a node system, drawn with schemdraw.

Both diagrams share one automatic layout, so they are topologically identical and
can be read side by side. Nodes n1 … nN are horizontal bars from left to right.
Grounded elements (and grounded force sources) hang from their node down to
ground. Floating elements join two nodes: the first element of each adjacent
pair sits on the rail between the two bars; every other one is a bridge above
the bars, on stacked levels so that no two bridges overlap, with its symbol in a
gap between bars where no riser passes. A connection is marked by a dot; crossing wires without a dot are
not connected.

In the circuit a mass is a grounded capacitor, an off-diagonal mass a floating
capacitor, a damper a resistor (R = 1/b), a spring an inductor (L = 1/k) and a
joint force a current source. In the mechanism each node is a link moving with
velocity v_k, a mass is a block tied to the ground reference (dotted), a
floating capacitor is an MP (mass/pulley) model, dampers are dashpots, springs
are springs and joint forces are arrows. Negative values are printed in red:
they are legitimate physics (an MP model whose mass opposes the relative
acceleration of its terminals).
"""

from __future__ import annotations

import textwrap

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np
import schemdraw
import schemdraw.elements as elm

from ..files import write_figure
from ..errors import InputError
from ..units import mechanical_units
from .description import circuit
from .elements import ZERO_TOL, element_table, spice_value
from .mechanical_symbols import Dashpot, Force, LinkGround, MassBlock, MPModel, Spring

if TYPE_CHECKING:
    from .node_system import NodeSystem

__all__ = ["Schematic", "schematic", "draw_circuit", "draw_mechanism", "draw", "schematic_fits", "FORMATS",
           "MAX_SCHEMATIC_NODES", "MAX_SCHEMATIC_FLOATING"]

#: File formats written when a path has no suffix.
FORMATS = (".svg", ".png")
#: Largest node count drawn as schematics by :func:`draw`; larger systems get an element map.
MAX_SCHEMATIC_NODES = 6
#: Most floating elements drawn as schematics (the 6-node flexible arm has 22, on a 4,559 px page).
MAX_SCHEMATIC_FLOATING = 12

_XY = tuple[float, float]

# Layout, in drawing units.
_NODE_MARGIN = 1.0     # bar start to first hanging element (room for the node label)
_DOWN_STEP = 2.7       # between hanging elements (room for their labels)
_UP_STEP = 0.55        # between bridge risers on one bar
_GAP_WIDTH = 3.6       # between two bars (room for one symbol and its label)
_DROP = 3.0            # bar to ground
_FIRST_LEVEL = 2.4     # height of the lowest bridge
_LEVEL_STEP = 2.1      # between bridge levels

_FONT = 11
_INCHES_PER_UNIT = 0.5
_NEGATIVE = "#c00000"
_ORDER = {"I": 0, "C": 1, "R": 2, "L": 3}
_UNITS = {"C": "F", "R": "\u03a9", "L": "H"}


@dataclass(frozen=True)
class _Part:
    """One labelled two-terminal part: an element of :func:`analogy.elements` or a force source."""

    name: str              # netlist name: C1, R1_2, I2, I1_n2
    kind: str              # "C", "R", "L" or "I"
    a: int                 # node, 1-based
    b: int                 # second node (> a), or 0 for ground
    value: float           # SPICE value (F, Ohm, H) or, for a source, the scale of its joint force
    coefficient: float     # mass, damping or stiffness, or the source scale
    joint: int = 0         # sources: the joint whose force drives it, 1-based
    into_a: bool = True    # sources: current (force) flows into node a, else into node b
    waveform: str = ""     # sources: its term of the joint force as written, e.g. step(1)
    terms: int = 1         # sources: how many terms the joint's force has (a source each)
    unit: str = ""         # the mechanical value's unit, e.g. kg·m² (empty when the model has none)


@dataclass
class _Placed:
    part: _Part
    start: _XY                       # symbol end points, drawn start -> end
    end: _XY
    wires: list[list[_XY]] = field(default_factory=list)
    dots: list[_XY] = field(default_factory=list)
    ground: _XY | None = None
    hanging: bool = False


@dataclass
class _Layout:
    bars: list[tuple[float, float]]  # (x start, x end) of each node bar, at y = 0
    placed: list[_Placed]
    top: float


def _parts(system: NodeSystem, zero_tol: float) -> list[_Part]:
    """Elements then force sources, read from the circuit description. A nonlinear circuit's charge-defined
    capacitors are drawn at their start, c(0), and each node's behavioural load h_k(x, v) as a source."""
    c = circuit(system, zero_tol)
    units = mechanical_units(system.provenance.units)
    parts = [_Part(e.name, e.kind, e.a, e.b, e.value, e.coefficient, unit=units[e.kind]) for e in c.elements]
    if system.kind != "linear":
        table = element_table(np.asarray(system.node_mass(np.zeros(system.dof)))[None], np.zeros((1, system.dof,
                              system.dof)), None, zero_tol)
        parts = [_Part(f"C{a}" if b == 0 else f"C{a}_{b}", kind, a, b, float(spice_value(kind, v[0])), float(v[0]),
                       unit=units[kind]) for kind, a, b, v in table if kind == "C" and v[0] != 0.0] + parts
        parts += [_Part(f"B{p.name}", "I", p.b, 0, 1.0, 1.0, 0, into_a=True, waveform=f"\u2212{p.name}(x, v)",
                        unit=units["I"]) for p in c.behavioural if type(p).__name__ == "BehaviouralCurrent"]
    for src in c.sources:
        if src.b == 0 or src.scale != 1.0:
            a, b, into_a = src.a, src.b, True
        else:
            a, b = min(src.a, src.b), max(src.a, src.b)
            into_a = src.a == a
        wave = src.waveform.label()         # its own term: with gravity a joint has a source per term
        parts.append(_Part(src.name, "I", a, b, src.scale, src.scale, src.joint, into_a=into_a,
                           waveform=wave, terms=len(system.forces[src.joint - 1]), unit=units["I"]))
    return parts


def _layout(parts: Sequence[_Part], n: int) -> _Layout:
    """Place every part: bars left to right, hanging parts below, bridges on stacked levels above."""
    rank = {p.name: i for i, p in enumerate(sorted(parts, key=lambda p: _ORDER[p.kind]))}
    hanging = {k: sorted((p for p in parts if p.b == 0 and p.a == k), key=lambda p: rank[p.name])
               for k in range(1, n + 1)}
    floating = sorted((p for p in parts if p.b != 0), key=lambda p: rank[p.name])
    inline: dict[int, _Part] = {}
    for p in floating:
        if p.b == p.a + 1 and p.a not in inline:
            inline[p.a] = p
    bridges = [p for p in floating if inline.get(p.a) is not p]

    # Risers on each bar, ordered so that bridges nest: inner (short) ones sit
    # next to the gap they cross, outer (long) ones further in.
    taps: dict[int, list[tuple[_Part, str]]] = {}
    for k in range(1, n + 1):
        left = sorted((p for p in bridges if p.b == k), key=lambda p: (p.b - p.a, rank[p.name]))
        right = sorted((p for p in bridges if p.a == k), key=lambda p: (p.b - p.a, rank[p.name]), reverse=True)
        taps[k] = [(p, "b") for p in left] + [(p, "a") for p in right]

    # Bars: hanging parts spaced by their label widths, risers on a finer grid that keeps clear of them.
    gap_width = max([_GAP_WIDTH] + [_label_width(p) + 0.8 for p in floating])
    bars: list[tuple[float, float]] = []
    riser: dict[tuple[str, str], float] = {}
    placed: list[_Placed] = []
    x = 0.0
    for k in range(1, n + 1):
        down, xk = [], x + _NODE_MARGIN
        for p in hanging[k]:
            down.append(xk)
            xk += max(_DOWN_STEP, _label_width(p) + 1.4)
        # The last label may reach under the gap, but not the next bar's first symbol.
        width = max(down[-1] - x + 0.9 if down else 1.6, xk - x - gap_width - 0.3, 1.6)
        while True:
            slots = [s for s in np.arange(x + 0.35, x + width - 0.3, _UP_STEP)
                     if all(abs(s - h) > 0.45 for h in down)]
            if len(slots) >= len(taps[k]):
                break
            width += _UP_STEP
        pick = np.round(np.linspace(0, len(slots) - 1, len(taps[k]))).astype(int) if taps[k] else []
        for (p, end), i in zip(taps[k], pick):
            riser[p.name, end] = float(slots[i])
        for p, xh in zip(hanging[k], down):
            top, bottom = (xh, 0.0), (xh, -_DROP)
            start, end = (bottom, top) if p.kind == "I" else (top, bottom)
            placed.append(_Placed(p, start, end, dots=[top], ground=bottom, hanging=True))
        bars.append((x, x + width))
        x += width + gap_width

    for k, p in inline.items():
        start, end = (bars[k - 1][1], 0.0), (bars[k][0], 0.0)
        placed.append(_Placed(p, *((end, start) if p.kind == "I" and p.into_a else (start, end))))

    levels: list[list[tuple[float, float]]] = []
    in_gap = [0] * n
    top = 1.5
    for p in sorted(bridges, key=lambda p: (p.b - p.a, riser[p.name, "b"] - riser[p.name, "a"], rank[p.name])):
        xa, xb = riser[p.name, "a"], riser[p.name, "b"]
        level = next((i for i, spans in enumerate(levels)
                      if all(xb < s0 - 0.3 or xa > s1 + 0.3 for s0, s1 in spans)), len(levels))
        if level == len(levels):
            levels.append([])
        levels[level].append((xa, xb))
        y = _FIRST_LEVEL + level * _LEVEL_STEP
        top = max(top, y + 1.5)
        mid = (p.a + p.b - 1) / 2
        gap = min(range(p.a, p.b), key=lambda m: (in_gap[m], abs(m - mid), m))
        in_gap[gap] += 1
        g0, g1 = bars[gap - 1][1], bars[gap][0]
        start, end = ((g1, y), (g0, y)) if p.kind == "I" and p.into_a else ((g0, y), (g1, y))
        wires = [[(xa, 0.0), (xa, y), (g0, y)], [(g1, y), (xb, y), (xb, 0.0)]]
        placed.append(_Placed(p, start, end, wires, dots=[(xa, 0.0), (xb, 0.0)]))
    return _Layout(bars, placed, top)


def _number(x: float) -> str:
    return f"{x:.3g}".replace("-", "\u2212")


def _label_width(p: _Part) -> float:
    """Generous width of the wider of the part's two labels (circuit and mechanism), in drawing units."""
    chars = max(len(line) for text in (_circuit_label(p), _mechanism_label(p)) for line in text.split("\n"))
    return chars * _FONT * 0.62 / 72 / _INCHES_PER_UNIT


def _wave(p: _Part) -> str:
    """The waveform whole, wrapped after its commas into lines of about 28 characters."""
    return "\n".join(textwrap.wrap(p.waveform, 28, break_long_words=False, break_on_hyphens=False))


def _source_label(name: str, p: _Part, unit: str) -> str:
    """A force source: f_k itself, or (with gravity, a sum) its own term of f_k; two lines either way."""
    if p.joint == 0:                        # a nonlinear node's load: gravity, velocity terms, contacts
        return f"{name}\n= {p.waveform}"
    scaled = _wave(p) if p.value == 1.0 else f"{_number(p.value)}\u00b7{_wave(p)}"
    if p.terms > 1:
        return f"{name}\n= {scaled} {unit}, a term of f{p.joint}"
    if p.value == 1.0:
        return f"{name}\n= {scaled} {unit}" if name == f"f{p.joint}" else f"{name}\n= f{p.joint} = {scaled} {unit}"
    return f"{name}\n= {_number(p.value)}\u00b7f{p.joint},\nf{p.joint} = {_wave(p)} {unit}"


def _circuit_label(p: _Part) -> str:
    return _source_label(p.name, p, "A") if p.kind == "I" else f"{p.name}\n= {_number(p.value)} {_UNITS[p.kind]}"


def _mechanism_label(p: _Part) -> str:
    suffix = p.name[1:]
    if p.kind == "I":
        return _source_label(f"f{suffix}", p, p.unit)
    prefix = {"C": "MP p\u2032" if p.b else "m\u2032", "R": "b\u2032", "L": "k\u2032"}[p.kind]
    return f"{prefix}{suffix}\n= {_number(p.coefficient)} {p.unit}"


_CIRCUIT = {"C": elm.Capacitor, "R": elm.Resistor, "L": elm.Inductor, "I": elm.SourceI}


def _circuit_symbol(p: _Part) -> elm.Element2Term:
    return _CIRCUIT[p.kind]()


def _mechanism_symbol(p: _Part) -> elm.Element2Term:
    if p.kind == "C":
        return MPModel() if p.b else MassBlock(_DROP)
    return {"R": Dashpot, "L": Spring, "I": Force}[p.kind]()


def _render(layout: _Layout, symbol: Callable[[_Part], elm.Element2Term],
            label: Callable[[_Part], str], *, node: str, bar_lw: float,
            ground: Callable[[], elm.Element], title: str, caption: str) -> schemdraw.Drawing:
    d = schemdraw.Drawing(show=False)
    d.config(fontsize=_FONT, margin=0.4, inches_per_unit=_INCHES_PER_UNIT)
    for k, (xs, xe) in enumerate(layout.bars, start=1):
        d.add(elm.Line(lw=bar_lw).endpoints((xs, 0.0), (xe, 0.0)))
        d.add(elm.Label().at((xs + 0.1, -0.2)).label(f"{node}{k}", halign="left", valign="top",
                                                      fontsize=_FONT + 2))
    for item in layout.placed:
        p = item.part
        for path in item.wires:
            for s, e in zip(path, path[1:]):
                d.add(elm.Line().endpoints(s, e))
        sym = d.add(symbol(p).endpoints(item.start, item.end))
        box = sym.get_bbox(transform=True, includetext=False)
        # One text per line: the name (as in the netlist) above its value.
        lines = label(p).split("\n")[::-1]
        color = _NEGATIVE if p.value < 0 else None
        if item.hanging:
            x, y = max(box.xmax, item.start[0] + 0.35) + 0.2, (item.start[1] + item.end[1]) / 2
            y -= 0.25 * (len(lines) - 1)
            halign = "left"
        else:
            x, y, halign = (item.start[0] + item.end[0]) / 2, box.ymax + 0.15, "center"
        for i, text in enumerate(lines):
            d.add(elm.Label().at((x, y + 0.42 * i)).label(text, halign=halign, valign="bottom", color=color))
        for xy in item.dots:
            d.add(elm.Dot(radius=0.1).at(xy))
        if item.ground is not None:
            d.add(ground().at(item.ground))
    d.add(elm.Label().at((layout.bars[0][0], layout.top + 0.6))
          .label(title, halign="left", valign="bottom", fontsize=_FONT + 3))
    d.add(elm.Label().at((layout.bars[0][0], -_DROP - 1.3))
          .label(caption, halign="left", valign="top", fontsize=_FONT - 1))
    return d


def _title(system: NodeSystem, what: str) -> str:
    start = "" if system.kind == "linear" else ", nonlinear: capacitances c(x) at the start, loads h(x, v) as sources"
    return f"{system.provenance.robot} ({system.topology.name} topology): {what}{start}"


@dataclass(frozen=True)
class Schematic:
    """A circuit's schematic and where each node and part of it is drawn, to show values on them.

    Attributes
    ----------
    drawing : schemdraw.Drawing
        The schematic (:func:`draw_circuit` draws it).
    bars : tuple of (float, float)
        Node k's bar, from x to x at y = 0, in drawing units.
    parts : dict of str to ((float, float), (float, float))
        Each part's symbol, from one end to the other: the elements and the force sources, by their
        netlist names.
    """

    drawing: schemdraw.Drawing
    bars: tuple
    parts: dict


def schematic(system: NodeSystem, zero_tol: float = ZERO_TOL, title: str | None = None,
              caption: str = "force = current, velocity = node voltage, mass = C, damper = R (1/b), "
                             "spring = L (1/k); red values are negative") -> Schematic:
    """The equivalent circuit of *system* as a schematic, with where it draws each node and part.

    Parameters
    ----------
    system : NodeSystem
        The linear system.
    zero_tol : float
        Relative tolerance under which an element is left out (as in the netlist).
    title : str, optional
        Heading; default names the robot and topology.
    caption : str
        The line under it.
    """
    layout = _layout(_parts(system, zero_tol), system.dof)
    d = _render(layout, _circuit_symbol, _circuit_label, node="n", bar_lw=3.5, ground=lambda: elm.Ground(lead=False),
                title=title or _title(system, "equivalent circuit"), caption=caption)
    return Schematic(d, tuple(layout.bars), {item.part.name: (item.start, item.end) for item in layout.placed})


def draw_circuit(system: NodeSystem, path: str | Path | None = None, *, zero_tol: float = ZERO_TOL,
                 title: str | None = None) -> schemdraw.Drawing:
    """Draw the equivalent circuit of *system*.

    Parameters
    ----------
    system : NodeSystem
    path : str or Path, optional
        Where to save: ``.svg`` or ``.png``; without a suffix both are written.
    zero_tol : float
        Relative tolerance under which an element is left out (as in the netlist).
    title : str, optional
        Heading; default names the robot and topology.

    Returns
    -------
    schemdraw.Drawing
        One labelled symbol per element of :func:`analogy.elements` and per
        current source of the netlist; each label is the netlist name (``C1_2``,
        ``I2``) above its value (``= −0.764 F``, ``= f2``).
    """
    d = schematic(system, zero_tol, title).drawing
    if path is not None:
        _save(d, path)
    return d


def draw_mechanism(system: NodeSystem, path: str | Path | None = None, *, zero_tol: float = ZERO_TOL,
                   title: str | None = None) -> schemdraw.Drawing:
    """Draw the mechanical system diagram of *system*, laid out as :func:`draw_circuit`.

    Parameters
    ----------
    system : NodeSystem
    path : str or Path, optional
        Where to save: ``.svg`` or ``.png``; without a suffix both are written.
    zero_tol : float
        Relative tolerance under which an element is left out.
    title : str, optional
        Heading; default names the robot and topology.

    Returns
    -------
    schemdraw.Drawing
        Links v1 … vN; one labelled symbol per element and force: masses ``m′k``,
        MP models ``MP p′i_j``, dampers ``b′…``, springs ``k′…`` and forces ``f…``.
    """
    parts = _parts(system, zero_tol)
    d = _render(_layout(parts, system.dof), _mechanism_symbol, _mechanism_label,
                node="v", bar_lw=6, ground=LinkGround,
                title=title or _title(system, "mechanical model"),
                caption="links move with velocities v_k; masses are referred to ground (dotted), "
                        "MP = mass/pulley model; red values are negative")
    if path is not None:
        _save(d, path)
    return d


def schematic_fits(system: NodeSystem, zero_tol: float = ZERO_TOL) -> bool:
    """True when the schematics stay readable: at most :data:`MAX_SCHEMATIC_NODES` nodes and
    :data:`MAX_SCHEMATIC_FLOATING` floating elements (each floating element past the first
    between adjacent nodes is a bridge).

    Parameters
    ----------
    system : NodeSystem
        The system.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    if system.dof > MAX_SCHEMATIC_NODES:
        return False
    return sum(1 for e in circuit(system, zero_tol).elements if e.b) <= MAX_SCHEMATIC_FLOATING


def draw(system: NodeSystem, directory: str | Path, stem: str = "system", *,
         zero_tol: float = ZERO_TOL, schematic: bool | None = None) -> list[Path]:
    """Write ``<stem>_circuit`` and ``<stem>_mechanism`` as SVG and PNG into *directory*.

    Past :data:`MAX_SCHEMATIC_NODES` nodes or :data:`MAX_SCHEMATIC_FLOATING` floating
    elements a schematic's bridges pile up past reading (10 nodes: 45 nested bridges on
    a 5,863 × 3,589 px page), so ``<stem>_elements``
    (:func:`analogy.circuit.element_map.draw_element_map`) is drawn instead, unless
    *schematic* is True.

    Parameters
    ----------
    system : NodeSystem
        The system to draw.
    directory : str or Path
        Folder to write into (created if need be).
    stem : str
        File name stem.
    zero_tol : float
        Relative tolerance under which an element is left out.
    schematic : bool, optional
        Draw the schematics (True), the element map (False), or whichever fits (None).

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    if schematic is False or (schematic is None and not schematic_fits(system, zero_tol)):
        from .element_map import draw_element_map
        paths = [out / f"{stem}_elements{s}" for s in FORMATS]
        import matplotlib
        fig = draw_element_map(system, zero_tol=zero_tol)
        with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "analogy"}):
            for p in paths:      # SVG text stays text: searchable, and the same on every run
                write_figure(fig, p, dpi=110, metadata={"Date": None} if p.suffix == ".svg" else None)
        return paths
    circuit = _write(draw_circuit(system, zero_tol=zero_tol), [out / f"{stem}_circuit{s}" for s in FORMATS])
    return circuit + _write(draw_mechanism(system, zero_tol=zero_tol),
                            [out / f"{stem}_mechanism{s}" for s in FORMATS])


def _save(drawing: schemdraw.Drawing, path: str | Path) -> list[Path]:
    """Write *drawing* to *path* (``.svg`` or ``.png``), or to both formats when it has no suffix."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix and suffix not in FORMATS:
        raise InputError(f"cannot write a diagram as {path.suffix!r}: use .svg or .png (or no suffix for both)")
    return _write(drawing, [path] if suffix else [path.with_name(path.name + s) for s in FORMATS])


def _write(drawing: schemdraw.Drawing, targets: list[Path]) -> list[Path]:
    """Render *drawing* on a matplotlib figure outside pyplot (no display needed) and save it."""
    import matplotlib
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_axis_off()
    ax.set_aspect("equal")
    drawing.draw(show=False, canvas=ax)
    box = drawing.get_bbox()
    ax.set_xlim(box.xmin - 0.3, box.xmax + 0.3)
    ax.set_ylim(box.ymin - 0.3, box.ymax + 0.3)
    inches = drawing.dwgparams.get("inches_per_unit", 0.5)
    fig.set_size_inches(inches * (box.xmax - box.xmin + 0.6), inches * (box.ymax - box.ymin + 0.6))
    # A large drawing keeps its scale but is capped at about 9000 pixels on its longer side.
    dpi = min(110.0, 9000.0 / max(fig.get_size_inches()))
    try:
        for target in targets:
            target.parent.mkdir(parents=True, exist_ok=True)
            svg = target.suffix.lower() == ".svg"
            with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "analogy"}):
                write_figure(fig, target, dpi=dpi, bbox_inches="tight", pad_inches=0.15, facecolor="white",
                             metadata={"Date": None} if svg else None)
    finally:
        drawing.fig = None
    return targets
