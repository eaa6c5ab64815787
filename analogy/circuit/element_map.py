"""A circuit too large for a schematic, as maps of its element values by node pair beside its grounded ones."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..files import write_figure
from ..units import mechanical_units
from .description import circuit
from .elements import ZERO_TOL

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .node_system import NodeSystem

__all__ = ["draw_element_map"]

_KINDS = (("C", "C [F] = mass m′, p′"), ("R", "1/R [S] = damping b′"), ("L", "1/L [1/H] = stiffness k′"))


def draw_element_map(system: "NodeSystem", path: str | Path | None = None, *,
                     zero_tol: float = ZERO_TOL) -> "Figure":
    """One panel per element kind: floating values by node pair (i < j), grounded values beside them.

    Colour is the signed value on a symmetric log scale (red negative, blue positive),
    so a negative MP capacitance stands out however small; an element left out of the
    netlist is blank. Capacitances are masses; resistors and inductors are shown as
    their conductance 1/R = b′ and inverse inductance 1/L = k′. Cells carry their values
    up to 16 nodes.

    Parameters
    ----------
    system : NodeSystem
        The linear system.
    path : str or Path, optional
        ``.png`` or ``.svg`` to write.
    zero_tol : float
        Relative tolerance under which an element is left out (as in the netlist).
    """
    from matplotlib.colors import SymLogNorm
    from matplotlib.figure import Figure

    c = circuit(system, zero_tol)
    n = c.nodes
    units = mechanical_units(system.provenance.units)
    present = [(k, label) for k, label in _KINDS if any(e.kind == k for e in c.elements)]
    fig = Figure(figsize=(5.4 * len(present) + 0.4, 4.8 + 0.12 * n), layout="constrained")
    grid = fig.add_gridspec(1, 2 * len(present), width_ratios=[n, 1.6] * len(present))
    annotate = n <= 16
    for col, (kind, label) in enumerate(present):
        floating = np.full((n, n), np.nan)
        grounded = np.full((n, 1), np.nan)
        for e in c.elements:
            if e.kind != kind:
                continue
            if e.b:
                floating[e.a - 1, e.b - 1] = e.coefficient
            else:
                grounded[e.a - 1, 0] = e.coefficient
        values = np.concatenate([floating[np.isfinite(floating)], grounded[np.isfinite(grounded)]])
        top = float(np.max(np.abs(values))) if values.size else 1.0
        norm = SymLogNorm(linthresh=max(top * 1e-3, np.finfo(float).tiny), vmin=-top, vmax=top)
        ax, axg = fig.add_subplot(grid[0, 2 * col]), fig.add_subplot(grid[0, 2 * col + 1])
        image = ax.imshow(floating, cmap="RdBu", norm=norm)
        axg.imshow(grounded, cmap="RdBu", norm=norm, aspect="auto")
        ticks = np.arange(n)
        names = [f"n{k + 1}" for k in ticks]
        ax.set_xticks(ticks, names, rotation=90 if n > 10 else 0, fontsize="small")
        ax.set_yticks(ticks, names, fontsize="small")
        # what is drawn is the coefficient (1/R for a resistor), named as the colour bar names it
        shown = {"C": "C", "R": "1/R", "L": "1/L"}[kind]
        ax.set_title(f"{shown}i_j between nodes (i < j)", fontsize="medium")
        axg.set_xticks([0], ["to ground"], fontsize="small")
        axg.set_yticks(ticks, names, fontsize="small")
        axg.yaxis.tick_right()
        axg.set_title(f"{shown}k", fontsize="medium")
        if annotate:
            for (i, j), v in np.ndenumerate(floating):
                if np.isfinite(v):
                    ax.text(j, i, f"{v:.2g}", ha="center", va="center", fontsize=7,
                            color="white" if abs(norm(v) - 0.5) > 0.35 else "black")
            for i, v in enumerate(grounded[:, 0]):
                if np.isfinite(v):
                    axg.text(0, i, f"{v:.3g}", ha="center", va="center", fontsize=7,
                             color="white" if abs(norm(v) - 0.5) > 0.35 else "black")
        bar = fig.colorbar(image, ax=[ax, axg], location="bottom", shrink=0.9,
                           label=f"{label} [{units[kind]}]".replace(" [(SI)]", " (SI)"))
        ticks = [s * top * f for s in (-1, 1) for f in (1.0, 0.01)] + [0.0]
        bar.set_ticks(sorted(ticks), labels=[f"{t:.2g}" for t in sorted(ticks)])
    count = len(c.elements)
    title = (f"{system.provenance.robot} ({system.topology.name} topology): {count} elements on {n} nodes, "
             "by node pair; red is negative, blank is left out")
    # wrapped to the figure's width (about 11 characters an inch at this size): one panel is narrow
    fig.suptitle(textwrap.fill(title, max(30, int(11 * fig.get_size_inches()[0]))), fontsize="medium")
    if path is not None:
        write_figure(fig, path, dpi=110)
    return fig
