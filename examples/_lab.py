"""Helpers shared by the labs: output folder, printing, the solver check, sweeps and plots.

The labs import this module as ``_lab`` (Python puts the script's own folder,
examples/, first on the import path). Everything here is plain bookkeeping; the
physics is in the labs themselves.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import analogy
from analogy.circuit.topology import congruence
from analogy.errors import InputError

#: Tolerances every paper lab asserts, relative to the peak exact joint rate.
SPICE_TOL = 1e-6
ODE_TOL = 1e-9

#: Label for mass-like quantities: a capacitance in the circuit is a mass (or
#: a rotational inertia, for revolute joints) in the mechanism.
MASS_AXIS = "capacitance [F] = inertia [kg·m²]"


#: Environment variable naming the output folder; it wins over the command line, so a
#: lab run as a notebook (whose kernel has its own command-line arguments) can be told too.
OUTPUT_ENV = "ANALOGY_LAB_OUTPUT"


def output_folder(default: str = "lab-output") -> Path:
    """The folder to write into, created: $ANALOGY_LAB_OUTPUT, else the script's first argument, else *default*.

    Inside a Jupyter kernel sys.argv holds the kernel's own arguments (``-f connection.json``),
    so there the command line is ignored.
    """
    if os.environ.get(OUTPUT_ENV):
        folder = os.environ[OUTPUT_ENV]
    elif len(sys.argv) > 1 and not _in_kernel():
        folder = sys.argv[1]
    else:
        folder = default
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    return out


def _in_kernel() -> bool:
    return "ipykernel" in sys.modules


def display_figure(fig) -> None:
    """Show *fig* as a PNG below the cell (or in a widget's output), with no file written."""
    import io

    from IPython.display import Image, display
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90)
    display(Image(data=buffer.getvalue()))


def in_notebook() -> bool:
    """True when the lab runs as a notebook (a Jupyter kernel), where widgets can be shown."""
    return _in_kernel()


def section(title: str) -> None:
    print(f"\n=== {title} ===")


def print_matrix(name: str, matrix) -> None:
    """A numeric matrix, one row per line."""
    rows = np.atleast_2d(np.asarray(matrix, dtype=float))
    print(f"{name} =")
    for row in rows:
        print("   [" + "  ".join(f"{x:+.6e}" for x in row) + "]")


def print_symbolic(name: str, matrix: sp.Matrix) -> None:
    """A symmetric sympy matrix, one upper-triangle entry per line (long entries stay readable)."""
    print(f"{name} (symmetric; upper triangle):")
    for i in range(matrix.rows):
        for j in range(i, matrix.cols):
            print(f"   {name}[{i + 1},{j + 1}] = {matrix[i, j]}")


def symbolic_node_matrix(mass_matrix: sp.Matrix, system) -> sp.Matrix:
    """M' = T^-T M T^-1 for a symbolic M, with the topology T of *system*."""
    t = sp.Matrix(np.rint(system.topology.matrix).astype(int).tolist())
    assert np.array_equal(np.asarray(t, dtype=float), system.topology.matrix), "T must be an integer matrix"
    return congruence(mass_matrix, t)


def paper_mass_matrix(n: int) -> sp.Matrix:
    """A general symmetric mass matrix in the paper's labels: m1 ... mn on the diagonal, then
    the upper off-diagonal entries row by row (n = 2: m3 = M12; n = 3: m4 = M12, m5 = M13, m6 = M23)."""
    m = sp.symbols(f"m1:{n * (n + 1) // 2 + 1}", real=True)
    matrix = sp.diag(*m[:n])
    k = n
    for i in range(n):
        for j in range(i + 1, n):
            matrix[i, j] = matrix[j, i] = m[k]
            k += 1
    return matrix


def symbolic_split(node_mass: sp.Matrix):
    """The element split done by hand: grounded m'_i = sum_j M'_ij, floating p'_ij = -M'_ij.

    Returns ({"m'1": expr, ...}, {"p'1_2": expr, ...}), every expression simplified; the
    names are those of the diagrams (the paper writes p'12).
    """
    n = node_mass.rows
    grounded = {f"m'{i + 1}": sp.simplify(sum(node_mass.row(i))) for i in range(n)}
    floating = {f"p'{i + 1}_{j + 1}": sp.simplify(-node_mass[i, j])
                for i in range(n) for j in range(i + 1, n)}
    return grounded, floating


def print_elements(system) -> None:
    """Every circuit element: netlist name, what it is mechanically, SPICE value and unit."""
    mech = {"C": "m'", "R": "b'", "L": "k'"}
    print(f"  {'name':<7}{'meaning':<10}{'value':>15}  {'unit':<5} mechanical coefficient")
    for e in analogy.elements(system):
        symbol = "p'" if e.meaning == "MP model" else mech[e.kind]
        print(f"  {e.name:<7}{e.meaning:<10}{e.value:>+15.6e}  {e.unit:<5} "
              f"{symbol}{e.name[1:]} = {e.coefficient:+.6g}")


def check_solvers(system, out: Path, stem: str):
    """Run SPICE, ODE and exact with the accurate preset, write <stem>.csv/.png and assert the errors."""
    result = analogy.compare(system, "accurate")
    print(result.table())
    assert not result.failures, result.failures
    result.to_csv(out / f"{stem}.csv")
    result.plot(out / f"{stem}.png")
    show(out / f"{stem}.png")
    spice, ode = result.max_relative_error("spice"), result.max_relative_error("ode")
    print(f"SPICE error / peak = {spice:.2e} (limit {SPICE_TOL:g}), ODE error / peak = {ode:.2e} "
          f"(limit {ODE_TOL:g})")
    assert spice <= SPICE_TOL, f"SPICE error {spice:.3e} of the peak exceeds {SPICE_TOL:g}"
    assert ode <= ODE_TOL, f"ODE error {ode:.3e} of the peak exceeds {ODE_TOL:g}"
    return result


def draw_diagrams(system, out: Path, stem: str) -> None:
    """Circuit and mechanism diagrams (SVG and PNG) of *system*, listed and shown."""
    from analogy.circuit.diagram import draw
    paths = draw(system, out, stem)
    print("diagrams:", ", ".join(p.name for p in paths))
    for path in paths:
        if path.suffix == ".png":
            show(path)


def sweep(scene, model, joint: int, values):
    """Node mass matrices M'(q) with joint *joint* (0-based) set to each of *values*.

    A closed chain does not assemble everywhere: a pose that does not assemble
    (or is singular) raises InputError and is skipped.

    Returns
    -------
    x : ndarray, the values that assembled
    node_mass : ndarray, shape (len(x), n, n)
    skipped : list of float
    """
    x, mats, skipped, reasons = [], [], [], []
    for value in values:
        q = list(scene.q)
        q[joint] = float(value)
        try:
            mats.append(scene.replace(q=tuple(q)).system(model).mass)
            x.append(float(value))
        except InputError as exc:
            skipped.append(float(value))
            reasons.append(str(exc))
    print(f"swept q{joint + 1} over [{min(values):.4g}, {max(values):.4g}] rad: {len(x)} poses assembled, "
          f"{len(skipped)} skipped" + (f"; the first skipped one: {reasons[0]}" if reasons else ""))
    return np.array(x), np.array(mats), skipped


def split(node_mass: np.ndarray):
    """Numeric element split of a stack of node mass matrices, shape (..., n, n).

    Returns grounded (..., n) and floating {(i, j): (...,)} with p'_ij = -M'_ij.
    """
    n = node_mass.shape[-1]
    grounded = node_mass.sum(axis=-1)
    floating = {(i, j): -node_mass[..., i, j] for i in range(n) for j in range(i + 1, n)}
    return grounded, floating


def figure(rows: int = 1, cols: int = 1, size=(7, 4)):
    """A matplotlib Figure outside pyplot (works headless, keeps no global state) and its axes."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.subplots(rows, cols, squeeze=False)


def plot_sweep(ax, x, curves: dict, *, xlabel: str, ylabel: str = MASS_AXIS, title: str = "",
               here: float | None = None, skipped=(), scale: float = 1.0) -> None:
    """Curves over a swept joint angle, with zero line, the scene's pose and skipped poses marked.

    *curves* maps a legend label to (values, style dict). Values are multiplied by *scale*
    (say so in *ylabel*). Poses that do not assemble are shaded, not drawn as points: they
    have no values. The legend goes outside the axes, right of them.
    """
    for label, (y, style) in curves.items():
        ax.plot(x, np.asarray(y) * scale, label=label, **style)
    ax.axhline(0.0, color="k", lw=0.6)
    if here is not None:
        ax.axvline(here, color="gray", ls="--", lw=0.8, label="scene pose")
    for k, (lo, hi) in enumerate(_runs(sorted(skipped), np.diff(x).min() if len(x) > 1 else 0.0)):
        ax.axvspan(lo, hi, color="0.85", lw=0, label=None if k else "does not assemble (no values)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.grid(alpha=0.3)
    legend_outside(ax)


def _runs(values, step: float):
    """Contiguous runs [lo, hi] of sorted *values*, each widened by half a step on both sides."""
    runs = []
    for v in values:
        if runs and v - runs[-1][1] <= 1.5 * step:
            runs[-1][1] = v
        else:
            runs.append([v, v])
    return [(lo - step / 2, hi + step / 2) for lo, hi in runs]


def legend_outside(ax, **kwargs) -> None:
    """The legend right of the axes, where it cannot cover data (constrained layout makes room)."""
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kwargs)


def envelope(time, values, windows: int = 100):
    """The largest of *values* in each of *windows* equal time windows: (window centres, maxima).

    An error that alternates from step to step draws as a solid band; its envelope shows
    how large it gets and how that changes over time.
    """
    time, values = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
    edges = np.linspace(time[0], time[-1], windows + 1)
    index = np.clip(np.searchsorted(edges, time, side="right") - 1, 0, windows - 1)
    top = np.full(windows, np.nan)
    np.fmax.at(top, index, values)
    keep = ~np.isnan(top)
    return ((edges[:-1] + edges[1:]) / 2)[keep], top[keep]


def save(fig, path: Path) -> None:
    """Write *fig* to *path*; in a notebook, show it as well (and nothing else: a cell that ends
    with it shows the picture, not a PosixPath)."""
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    show(path)


def animate(shown, path: Path) -> None:
    """Write the motion *shown* as a GIF at *path* and its contact sheet beside it; in a notebook,
    play it below the cell (its own HTML player)."""
    shown.save(path)
    sheet = path.with_name(path.stem + "_sheet.png")
    shown.sheet(sheet)
    print(f"wrote {path} ({shown.frames} frames) and {sheet.name}")
    if _in_kernel():
        from IPython.display import HTML, display
        display(HTML(shown.to_jshtml()))
    show(sheet)


def show(path: Path) -> None:
    """Show the picture at *path* below the cell when the lab runs as a notebook (a script only
    writes files). The file, not the figure: that needs no matplotlib backend in the kernel."""
    if _in_kernel():
        from IPython.display import Image, display
        display(Image(filename=str(path)))


def check_loop_closure_rates(model, q, step: float = 1e-6, tol: float = 1e-7) -> float:
    """Compare the closed chain's rates G = dp/dq with central differences of its assembly p(q).

    M(q) = S^T M_theta S uses G, so this checks the kinematics the mass matrix is built on.
    Returns the largest difference relative to max |G|.
    """
    q = np.asarray(q, dtype=float)
    _, rates = model.assemble(q)
    fd = np.empty_like(rates)
    for j in range(q.size):
        dq = np.zeros_like(q)
        dq[j] = step
        fd[:, j] = (model.assemble(q + dq)[0] - model.assemble(q - dq)[0]) / (2 * step)
    err = float(np.max(np.abs(fd - rates)) / np.max(np.abs(rates)))
    print(f"loop-closure rates dp/dq vs central differences: max difference / max |dp/dq| = {err:.1e}")
    assert err <= tol, f"rates disagree with finite differences by {err:.2e}"
    return err
