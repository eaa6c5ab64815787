"""SPICE text of circuit descriptions and the spice solver's settings, which only formats (a stack's: stack_netlist)."""

from __future__ import annotations

import math
import re
import unicodedata
from typing import Iterable, Literal, Sequence

from ..errors import InputError
from .description import (
    BehaviouralCurrent,
    BehaviouralVoltage,
    ChargeCapacitor,
    Circuit,
    Integrator,
)
from .description import circuit as describe
from .elements import ZERO_TOL
from .ltspice import ltspice_netlist
from .source_values import source_values
from .spice_numbers import spice_text as _num
from .step_sources import first_step_lines

__all__ = ["Dialect", "DIALECTS", "NETLIST_FORMATS", "write_netlist", "write_batch", "ac_netlist", "circuit_lines",
           "analysis_lines", "save_vectors", "comment_text", "spice_expression", "gnucap_lines",
           "gnucap_size_note", "coupled_nodes", "GNUCAP_NODES"]

#: The SPICE engines a netlist is written for: ngspice's language, and gnucap's (linear circuits).
Dialect = Literal["ngspice", "gnucap", "ltspice"]
DIALECTS: tuple[str, ...] = ("ngspice", "gnucap", "ltspice")
#: What ``analogy netlist`` writes: a dialect's netlist, or a KiCad schematic of ngspice's.
NETLIST_FORMATS: tuple[str, ...] = DIALECTS + ("kicad",)
#: ``.options`` gnucap reads as ngspice does; the others are ngspice's own.
_GNUCAP_OPTIONS = ("method", "reltol", "abstol", "vntol", "chgtol", "trtol")
_EPS = 2.0 ** -52

#: Symbols the package writes (and joint names may hold) spelled in ASCII for a comment; accents
#: are dropped by NFKD (é → e), superscripts become digits; anything else left becomes "?".
_ASCII_NAMES = str.maketrans({"Φ": "Phi", "φ": "phi", "ε": "eps", "λ": "lambda", "ω": "omega", "β": "beta",
                              "σ": "sigma", "ζ": "zeta", "π": "pi", "µ": "u", "μ": "u", "θ": "theta",
                              "·": "*", "×": "x", "−": "-", "–": "-", "—": "-", "≤": "<=", "≥": ">=",
                              "≈": "~", "→": "->", "…": "...", "ᵀ": "^T", "⁻": "^-", "′": "'", "’": "'"})
_SAFE_COMMENT = re.compile(r"[^A-Za-z0-9 _.,:;=+\-*/()\[\]{}<>'#%@!?|~^&$]")
_SAFE_EXPRESSION = re.compile(r"^[A-Za-z0-9_.+\-*/()^ ,<>=!&|?:]+$")


def comment_text(text) -> str:
    """Make *text* safe inside a ``*`` comment: one line, printable ASCII only.

    Parameters
    ----------
    text : object
        Anything; its ``str`` is cleaned.
    """
    text = str(text)
    if not text.isascii():      # Greek letters and operators spelled out, accents dropped
        text = unicodedata.normalize("NFKD", text.translate(_ASCII_NAMES))
        text = "".join(c for c in text if not unicodedata.combining(c))
    return _SAFE_COMMENT.sub("?", text)


def spice_expression(text: str) -> str:
    """*text* if it is a plain arithmetic SPICE expression, else :class:`InputError`.

    Only names, numbers, operators, parentheses and commas pass: no quotes, braces,
    newlines or dots that start a control line, so nothing can leave the expression.

    Parameters
    ----------
    text : str
        A behavioural expression such as ``v(n1)*v(n2)``.
    """
    if not isinstance(text, str) or not _SAFE_EXPRESSION.match(text) or text.lstrip().startswith("."):
        raise InputError(f"behavioural expression {text!r} contains characters SPICE must not read")
    return text


_NODE_REFERENCE = re.compile(r"\bv\(([nxe]\d+|m\d+_\d+)\)")


def _prefixed(expression: str, prefix: str) -> str:
    """*expression* with its node references v(n1), v(x1) given the sub-circuit's prefix."""
    return _NODE_REFERENCE.sub(lambda m: f"v({prefix}{m.group(1)})", expression) if prefix else expression


def _node(k: int, prefix: str = "") -> str:
    return "0" if k == 0 else f"{prefix}n{k}"


def circuit_lines(c: Circuit, prefix: str = "", memo: dict | None = None) -> list[str]:
    """Device lines of circuit *c*: elements, 1:−1 couplings, behavioural parts, sources.

    Parameters
    ----------
    c : Circuit
        The description to write.
    prefix : str
        Prepended to every device and node name (independent circuits in one run).
    memo : dict, optional
        Source values already written, for circuits that share their sources.
    """
    lines = [f"{kind}{prefix}{a} {prefix}n{a} 0 {value!r}" if b == 0 else
             f"{kind}{prefix}{a}_{b} {prefix}n{a} {prefix}n{b} {value!r}"
             for kind, a, b, value, _ in c.elements]       # values are floats: repr is exact
    for cp in c.couplings:
        e = cp.element
        name = f"{prefix}{e.name}"
        a, b = _node(e.a, prefix), _node(e.b, prefix)
        x, y = (f"{prefix}{n}" for n in cp.auxiliary_nodes)
        lines += [f"E{name} {x} 0 {b} {a} 1", f"V{name} {x} {y} DC 0",
                  f"{name} {y} 0 {_num(-e.value)}", f"F{name} {a} {b} V{name} 1"]
    for p in c.behavioural:
        if isinstance(p, Integrator):           # x_k = ∫ v(n_k): 1 F charged by a current v(n_k)
            x, n = f"{prefix}{p.name}", f"{prefix}n{p.node}"
            lines += [f"C{x} {x} 0 1", f"B{x} 0 {x} I={{v({n})}}"]
            continue
        if isinstance(p, BehaviouralVoltage):   # a shared quantity: a node held at its expression
            lines.append(f"B{prefix}{p.name} {prefix}{p.name} 0 V={{{_prefixed(spice_expression(p.voltage), prefix)}}}")
            continue
        a, b = _node(p.a, prefix), _node(p.b, prefix)
        if isinstance(p, ChargeCapacitor) and p.initial == 0.0:    # ngspice's Q form starts at Q = 0
            lines.append(f"C{prefix}{p.name} {a} {b} Q={{{_prefixed(spice_expression(p.charge), prefix)}}}")
        elif isinstance(p, ChargeCapacitor):        # Q on a node, dQ/dt through 1 F, mirrored from a to b
            qn, cn = (f"{prefix}{node}" for node in p.follower_nodes)
            lines += [f"* C{prefix}{p.name} as a follower, since ngspice's Q form starts at Q = 0 whatever .ic says: "
                      f"B{qn} holds {qn} at Q, C{cn}'s 1 F carries dQ/dt, V{prefix}ms{p.name} senses it and "
                      f"F{prefix}m{p.name} drives it from {a} to {b}",
                      f"B{qn} {qn} 0 V={{{_prefixed(spice_expression(p.charge), prefix)}}}",
                      f"V{prefix}ms{p.name} {qn} {cn} DC 0", f"C{cn} {cn} 0 1",
                      f"F{prefix}m{p.name} {a} {b} V{prefix}ms{p.name} 1"]
        elif isinstance(p, BehaviouralCurrent):
            lines.append(f"B{prefix}{p.name} {b} {a} I={{{_prefixed(spice_expression(p.current), prefix)}}}")
    # 'I n+ n- value' drives current out of n+ and into n-: into a, out of b.
    joint_of = {s.name: s.joint for s in c.sources}
    for name, a, b, v, terms in source_values(c.sources, c.t_stop, memo):
        if terms:       # the description's sources it stands for
            lines.append(_summed_comment(f"I{prefix}{name[1:]}", a, terms))
        elif c.joints and name in joint_of:       # beside its source, the joint it drives
            joint = joint_of[name]
            lines.append("* " + comment_text(f"I{prefix}{name[1:]}: the force on joint {joint}, {c.joints[joint - 1]}"))
        lines.append(f"I{prefix}{name[1:]} {_node(b, prefix)} {_node(a, prefix)} {v}")
    return lines


#: A summed source's comment names its terms up to this many; past it, how many (a modal map's n per node).
_LISTED_TERMS = 8


def _summed_comment(device: str, node: int, terms: Sequence) -> str:
    """The comment line above a summed source: its terms by waveform and joint, or, past
    :data:`_LISTED_TERMS` of them, their number."""
    if len(terms) > _LISTED_TERMS:
        return f"* {device} sums {len(terms)} force terms into n{node}, each times its joint's entry of T^-T"
    named = (f"{'' if g.scale == 1.0 else f'{g.scale:g}*'}{g.waveform.label()} (joint {g.joint})" for g in terms)
    return f"* {device} " + comment_text(f"sums the forces into n{node}: " + " + ".join(named))


def analysis_lines(settings, ic: Iterable[tuple[str, float]] = (), save: Iterable[str] = (),
                   printing: bool = False, *, ic_text: str | None = None, save_text: str | None = None) -> list[str]:
    """``.ic``, ``.options``, ``.tran`` (uic), ``.save`` and, with *printing*, ``.print``: *settings* formatted.

    Parameters
    ----------
    settings : TransientSettings
        The spice solver's settings (:class:`~analogy.solvers.transient.TransientSettings`):
        ``options``, ``print_step``, ``stop``, ``max_step`` and ``breakpoint``.
    ic : iterable of (str, float)
        Node voltages at t = 0.
    save : iterable of str
        Vectors to save (``v(n1)``, ``@c1_2[i]``).
    printing : bool
        Add ``.print tran`` of the saved vectors with 15 significant digits, so that
        ``ngspice -b`` prints them: on the print step (``option interp``) where
        ``settings.interpolate``, else at its own time points.
    ic_text : str, optional
        The ``.ic`` line's text, written already (instead of *ic*).
    save_text : str, optional
        The ``.save`` line's text, written already (instead of *save*).
    """
    if ic_text is None:
        ic_text = " ".join(f"v({n})={_num(v)}" for n, v in ic)
    if save_text is None:
        save_text = " ".join(save)
    options = " ".join(f"{k}={v}" if v != "" else k for k, v in settings.options)      # "": a flag
    lines = [
        ".ic " + ic_text,
        ".options " + options,
        f".tran {_num(settings.print_step)} {_num(settings.stop)} 0 {_num(settings.max_step)} uic",
        ".save " + save_text,
    ]
    if printing:
        # in a .control block, which a run in process leaves out (see analogy.solvers.ngspice)
        interp = ["option interp"] if getattr(settings, "interpolate", True) else []
        lines += [".print tran " + save_text, ".control", "set numdgt=15", *interp, ".endc"]
    return lines


def save_vectors(c: Circuit, save: Iterable[str] | None = None) -> list[str]:
    """The ``.save`` vectors for node and element names of circuit *c*.

    A node name (``n1`` …) gives its voltage ``v(n1)``; an element name (``C1``,
    ``C1_2``, ``R1``, ``L2_3`` …) gives its current ``@c1_2[i]``, flowing from its
    first terminal through it to its second, as SPICE reports a device ``name a b
    value``. An element behind a coupling reports the current of the coupling's
    source ``F<name>``, which carries it from a to b. Names are checked against the
    circuit, so nothing else can reach the netlist.

    Parameters
    ----------
    c : Circuit
        The circuit whose nodes and elements may be named.
    save : iterable of str, optional
        Names; default every node and every output node (a contact's force).
    """
    nodes = c.node_names + c.state_nodes + c.monitors + list(c.outputs)
    wanted = list(c.node_names) + list(c.outputs) if save is None else list(save)
    if not wanted:
        raise InputError("nothing to save: name at least one node")
    coupled = {cp.name.lower() for cp in c.couplings}
    out = []
    for item in wanted:
        if isinstance(item, str) and item in nodes:
            out.append(f"v({item})")
            continue
        e = c.element(item) if isinstance(item, str) else None
        if e is None:
            names = ", ".join(p.name for p in c.parts) or "none"
            raise InputError(f"cannot save unknown node or element {item!r}: nodes are "
                             f"{', '.join(nodes)}; elements are {names}")
        device = f"F{e.name}" if e.name.lower() in coupled else e.name
        out.append(f"@{device.lower()}[i]")
    return list(dict.fromkeys(out))


def _header(c: Circuit, title: str | None, realizable: bool) -> list[str]:
    lines = [f"* {comment_text(title or 'analogy equivalent circuit: ' + c.robot)}"]
    lines += [f"* {comment_text(line)}" for line in c.comments]
    lines += ["* analogy: force = current [A], velocity = voltage [V], mass = capacitance [F],",
              "* damping = conductance [S], stiffness = 1/inductance [1/H]; floating C = MP model"]
    if realizable:
        lines.append("* realizable: negative elements sit behind 1:-1 couplings (E, V, F sources)")
    return lines


def write_netlist(c: Circuit, settings, save: Iterable[str] | None = None, title: str | None = None,
                  printing: bool = True, dialect: Dialect = "ngspice") -> str:
    """Circuit *c* with the spice solver's *settings* as a SPICE netlist that ``ngspice -b`` runs unchanged.

    Parameters
    ----------
    c : Circuit
        The circuit description.
    settings : TransientSettings
        The spice solver's transient settings (:func:`~analogy.solvers.transient.transient_settings`).
    save : iterable of str, optional
        Node names (``n1`` …) whose voltages to save and element names (``C1_2``,
        ``R1`` …) whose currents to save (see :func:`save_vectors`); default all nodes.
    title : str, optional
        First line of the netlist.
    printing : bool
        End with ``.print tran`` of the saved vectors (see :func:`analysis_lines`).
    dialect : {"ngspice", "gnucap", "ltspice"}
        The engine that reads it (see :func:`gnucap_lines` for what gnucap needs, and
        :func:`~analogy.circuit.ltspice.ltspice_netlist` for LTspice).
    """
    if dialect == "gnucap":
        note = gnucap_size_note(len(c.node_names), coupled_nodes(c))
        warning = [f"* warning: {note}"] if note else []
        return "\n".join(_header(c, title, bool(c.couplings)) + warning + gnucap_lines(c, settings, save)) + "\n"
    if dialect not in DIALECTS:
        raise InputError(f"unknown netlist dialect {dialect!r}: use {', '.join(DIALECTS)}")
    vectors = save_vectors(c, save)
    body = circuit_lines(c) + first_step_lines(settings, c.node_names[0])
    tail = analysis_lines(settings, c.initial, vectors, printing) + [".end"]
    text = "\n".join(_header(c, title, bool(c.couplings)) + body + tail) + "\n"
    if dialect == "ltspice":
        return ltspice_netlist(text)
    return text


#: Above this many nodes joined by floating elements gnucap 0.36 was seen to run past minutes on our
#: netlists, with no error: dense serial circuits, and tridiagonal chains of 6 to 20 nodes alike;
#: serial20's modal circuit, no node joined to another, took 0.3 s.
GNUCAP_NODES = 5


def coupled_nodes(c: Circuit) -> int:
    """The most nodes one node's floating elements and couplings join, itself included: n for a dense
    circuit, 1 for a modal one.

    Parameters
    ----------
    c : Circuit
        A circuit description.
    """
    joined: dict[int, set] = {}
    pairs = [(a, b) for _, a, b, _, _ in c.elements] + [(cp.element.a, cp.element.b) for cp in c.couplings]
    for a, b in pairs:
        if a and b:
            joined.setdefault(a, set()).add(b)
            joined.setdefault(b, set()).add(a)
    return 1 + max((len(v) for v in joined.values()), default=0)


def gnucap_size_note(nodes: int, coupled: int) -> str | None:
    """A sentence for a gnucap netlist of *nodes* nodes past :data:`GNUCAP_NODES` where a floating element
    joins two of them (*coupled* > 1, :func:`coupled_nodes`), or None.

    Parameters
    ----------
    nodes : int
        The circuit's node count.
    coupled : int
        The most nodes one node's floating elements join, itself included.
    """
    if nodes <= GNUCAP_NODES or coupled <= 1:
        return None
    return (f"gnucap may not finish this {nodes}-node netlist: at the accurate preset it ran the 5-node serial5 "
            "in 0.4 s, serial6 in 14 s, and neither serial7 nor serial8 within 15 s nor flex1 within 300 s, with no "
            "error (gnucap 0.36); ngspice runs them")


def gnucap_lines(c: Circuit, settings, save: Iterable[str] | None = None) -> list[str]:
    """Circuit *c* in gnucap's dialect: the device and analysis lines after the header.

    gnucap reads ngspice's element and source lines, but not ``.ic`` (each capacitor gets
    ``IC=`` its initial voltage instead), ``.save``, a SIN phase, a ``.print`` after ``.tran``
    (it runs ``.tran`` as soon as it reads it) or behavioural parts (``Q={…}``, ``B``).
    ``numdgt=17`` prints every digit; ``noincmode`` solves each step in full, since the
    incremental mode's error (1e-6 to 1e-4 measured) is above the accurate bound.

    gnucap's voltage sources (the couplings' E and V) have a series resistance, its option
    ``short`` (10 µΩ by default): in series with a coupling's capacitor it gave an error
    proportional to it (4.4e-5 on serial2, 4.4e-7 at 1e-7 Ω). Below ~1e-8 Ω its 1/short
    conductance loses the other currents to rounding instead. The dialect takes the balance,
    ``short`` = √ε times the circuit's impedance scale, with the trapezoidal rule
    (gear measured 16 times slower in gnucap, and no more accurate).

    Parameters
    ----------
    c : Circuit
        A linear circuit (its couplings too).
    settings : TransientSettings
        The spice solver's settings.
    save : iterable of str, optional
        Node names to print (gnucap prints node voltages here); default every node.
    """
    if c.behavioural:
        raise InputError("gnucap has no charge-defined capacitors (Q={...}) or behavioural sources (B): "
                         "a nonlinear circuit runs in ngspice only")
    wanted = list(c.node_names) + list(c.outputs) if save is None else list(save)
    if bad := [n for n in wanted if n not in c.node_names]:
        raise InputError(f"gnucap prints node voltages here: {bad[0]!r} is not one of {', '.join(c.node_names)}")
    start = {"0": 0.0, **{name: value for name, value in c.initial}}
    lines = []
    for line in circuit_lines(c) + first_step_lines(settings, c.node_names[0]):
        words = line.split()
        if words[0][0] == "C":              # the run starts from each capacitor's initial voltage
            line += f" IC={_num(start.get(words[1], 0.0) - start.get(words[2], 0.0))}"
        elif words[0][0] == "I" and words[3].startswith("SIN("):
            args = line[line.index("SIN(") + 4:-1].split()
            if len(args) == 6 and float(args[5]) != 0.0:
                raise InputError(f"gnucap's SIN has no phase: source {words[0]} starts at phase {args[5]} deg")
            line = line[:line.index("SIN(")] + "SIN(" + " ".join(args[:5]) + ")"
        lines.append(line)
    known = dict((k, v) for k, v in settings.options if k in _GNUCAP_OPTIONS)
    if c.couplings and getattr(settings, "impedance", None):
        known.update(method="trap", short=_num(math.sqrt(_EPS) * settings.impedance))
    options = " ".join(f"{k}={v}" for k, v in known.items())
    return lines + [f".options {options} numdgt=17 noincmode",
                    ".print tran " + " ".join(f"v({n})" for n in wanted),
                    f".tran {_num(settings.print_step)} {_num(settings.stop)} 0 {_num(settings.max_step)} uic",
                    ".end"]


def write_batch(described: Sequence[Circuit], settings) -> str:
    """Circuits as independent sub-circuits (prefix ``x<k>_``) of one netlist under one ``.tran``.

    Parameters
    ----------
    described : sequence of Circuit
        The circuits, sharing t_stop (:func:`~analogy.circuit.description.circuits`).
    settings : TransientSettings
        Their shared transient settings.
    """
    lines, ic, save = [f"* analogy batch of {len(described)} independent circuits"], [], []
    memo: dict = {}         # per waveform, its source text at each scale and t_stop
    for k, c in enumerate(described):
        prefix = f"x{k}_"
        lines += circuit_lines(c, prefix, memo)
        ic += [(prefix + n, v) for n, v in c.initial]
        save += [f"v({prefix}{n})" for n in c.node_names]
    lines += first_step_lines(settings, "x0_n1")
    return "\n".join(lines + analysis_lines(settings, ic, save) + [".end"]) + "\n"


def ac_netlist(system, joint: int, f_start: float, f_stop: float, per_decade: int,
               zero_tol: float = ZERO_TOL) -> str:
    """An ``.ac`` sweep of *system*'s circuit driven by a unit force on *joint* alone.

    The sources of the other joints are left out (zero); every node has a 1e12 Ω
    shunt (``rshunt``) so that the operating point exists where only capacitors reach
    ground: a damper of 1e-12 N·s/m, below double precision against any real one.

    Parameters
    ----------
    system : NodeSystem
        A linear node system.
    joint : int
        The driven joint (1-based).
    f_start, f_stop : float
        The sweep [Hz].
    per_decade : int
        Points per decade.
    zero_tol : float
        Relative tolerance under which an element is left out.
    """
    c = describe(system, zero_tol, False)
    if c.behavioural:
        raise InputError("an AC sweep needs a linear circuit: linearise the model at a configuration")
    # one source per terminal pair: a joint's force may be written as several terms
    driven = list({(s.a, s.b, s.scale): s for s in reversed(c.sources) if s.joint == joint}.values())[::-1]
    if not driven:
        raise InputError(f"joint {joint} drives no source: the circuit has joints 1 to {system.dof}")
    nodes = [f"v({n})" for n in c.node_names]
    lines = _header(c, f"analogy AC sweep of {c.robot}: unit force on joint {joint}", False)
    lines += circuit_lines(c._replace(sources=()))
    lines += [f"I{s.name[1:]} {_node(s.b)} {_node(s.a)} DC 0 AC {_num(s.scale)}" for s in driven]
    lines += [".options rshunt=1e12", f".ac dec {int(per_decade)} {_num(f_start)} {_num(f_stop)}",
              ".save " + " ".join(nodes), ".print ac " + " ".join(f"vr({n}) vi({n})" for n in c.node_names),
              ".end"]
    return "\n".join(lines) + "\n"
