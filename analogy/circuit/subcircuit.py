"""The robot as a subcircuit: one port per joint, its voltage the joint's rate and the current into it the force."""

from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..waveforms import PWL
from .elements import ZERO_TOL
from .netlist import analysis_lines, circuit_lines, comment_text
from .step_sources import first_step_lines
from .parts import Circuit

__all__ = ["JointPort", "joint_ports", "write_subcircuit", "subcircuit_name"]


class JointPort(NamedTuple):
    """Joint *joint*'s port *name*: its voltage is r_j = Σ c_k·v(n_k) over *terms* (row j of T⁻¹),
    and the current a user's circuit drives into it is the force F_j, which enters each node k as
    c_k·F_j (column j of T⁻ᵀ: the same numbers), so that the port's power r_j·F_j is the circuit's."""

    joint: int
    name: str
    terms: tuple[tuple[int, float], ...]

    @property
    def direct(self) -> bool:
        """True when the joint's rate is one node's voltage: the port is wired to that node."""
        return len(self.terms) == 1 and self.terms[0][1] == 1.0

    def lines(self) -> list[str]:
        """The port's devices: a wire to its node, or a rate-following source whose current,
        sensed by a zero-volt source, is driven into the nodes by current-controlled sources."""
        p = self.name
        if self.direct:
            return [f"V{p} {p} n{self.terms[0][0]} DC 0"]
        (a, ca), *rest = self.terms
        if len(self.terms) == 2 and ca == 1.0 and rest[0][1] == -1.0:
            follow = f"E{p} {p}s 0 n{a} n{rest[0][0]} 1"
        elif len(self.terms) == 2 and ca == -1.0 and rest[0][1] == 1.0:
            follow = f"E{p} {p}s 0 n{rest[0][0]} n{a} 1"
        else:
            follow = f"B{p} {p}s 0 V={{" + " + ".join(f"({c!r})*v(n{k})" for k, c in self.terms) + "}"
        # 'F n+ n- V gain' drives gain·I(V) out of n+ and into n-: into node k
        return [follow, f"V{p} {p} {p}s DC 0"] + [f"F{p}_{k} 0 n{k} V{p} {c!r}" for k, c in self.terms]


def joint_ports(system, zero_tol: float = ZERO_TOL) -> tuple[JointPort, ...]:
    """One port per joint, from the system's current map T⁻ᵀ (its columns are the rows of T⁻¹).

    Parameters
    ----------
    system : NodeDynamics
        The system.
    zero_tol : float
        Relative tolerance under which an entry counts as zero.
    """
    inverse = np.asarray(system.current_map, float).T
    out = []
    for j, row in enumerate(inverse):
        floor = zero_tol * float(np.max(np.abs(row)))
        terms = tuple((k + 1, float(c)) for k, c in enumerate(row) if abs(c) > floor)
        out.append(JointPort(j + 1, f"p{j + 1}", terms))
    return tuple(out)


def subcircuit_name(text: str) -> str:
    """*text* as a SPICE subcircuit name: letters, digits and underscores, starting with a letter.

    Parameters
    ----------
    text : str
        A robot's or scene's name.
    """
    name = re.sub(r"[^A-Za-z0-9_]", "_", text.strip())
    if not name or not name[0].isalpha():
        name = "robot_" + name
    return name[:64]


def _is_zero(wave) -> bool:
    return isinstance(wave, PWL) and not np.any(wave.values)


def write_subcircuit(c: Circuit, ports: tuple[JointPort, ...], name: str, settings,
                     title: str | None = None) -> str:
    """Circuit *c*, its applied forces left to the user's circuit, as ``.subckt NAME p1 … pn``.

    The forces the robot makes itself (gravity's constant load at the pose) stay inside; each
    port takes the force of its joint from outside (a current into it) and shows its rate (its
    voltage). The initial node voltages are the subcircuit's own ``.ic``, which ngspice applies
    under ``uic``. Nothing in it runs an analysis: a user's netlist ``.include``s it.

    Parameters
    ----------
    c : Circuit
        The circuit of the system under its own loads only (every applied force zero).
    ports : tuple of JointPort
        One per joint (:func:`joint_ports`).
    name : str
        The subcircuit's name (:func:`subcircuit_name`).
    settings : TransientSettings
        The spice solver's settings for the robot under its forces: their ``.options`` and ``.tran``
        are written as a comment for the user's netlist, and their first step is made inside
        (a zero current source with a corner, as in :func:`~analogy.circuit.netlist.first_step_lines`).
    title : str, optional
        First comment line.
    """
    inside = c._replace(sources=tuple(s for s in c.sources if not _is_zero(s.waveform)))
    body = circuit_lines(inside) + first_step_lines(settings, c.node_names[0])
    ic, options, tran = analysis_lines(settings, c.initial)[:3]
    taken = {w for line in body for w in line.split()[:3]}
    clash = [p.name for p in ports if p.name in taken or f"{p.name}s" in taken]
    if clash:
        raise InputError(f"the circuit already has a node or device named {clash[0]!r}: no port can take that name")
    joints = c.joints or tuple(f"q{j}" for j in range(1, len(ports) + 1))
    head = [f"* {comment_text(title or 'analogy subcircuit: ' + c.robot)}"]
    head += [f"* {comment_text(line)}" for line in c.comments if not line.startswith("forces:")]
    head += ["* analogy: force = current [A], velocity = voltage [V], mass = capacitance [F],",
             "* damping = conductance [S], stiffness = 1/inductance [1/H]; floating C = MP model",
             f"* ports: {' '.join(p.name for p in ports)}, one per joint; the current a circuit drives into",
             "* port j is the force on joint j (N or N m) and v(port j) is its rate (m/s or rad/s)"]
    head += [f"* {comment_text(f'{p.name}: joint {p.joint}, {joints[p.joint - 1]}')}" for p in ports]
    head += ["* use: .include this file, then an instance such as", f"*   X1 {' '.join(p.name for p in ports)} {name}",
             "* drive each port (current sources are forces, voltage sources impose rates) and run .tran with uic"]
    head += ["* the settings that hold the preset's bound on this robot under its own forces:",
             f"* {options}", f"* {tran}"]
    ports_lines = ["* each port: a wire to its node, or a source that follows the rate (E or B), a zero-volt",
                   "* source sensing the force, and current-controlled sources driving it into the nodes (F)"]
    for p in ports:
        ports_lines += p.lines()
    return "\n".join(head + [f".subckt {name} {' '.join(p.name for p in ports)}"] + body + ports_lines
                     + ([ic] if c.initial else []) + [f".ends {name}"]) + "\n"
