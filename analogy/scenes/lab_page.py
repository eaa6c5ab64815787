"""The browser lab: an offline page whose sliders re-write a netlist, run it in WebAssembly ngspice, and solve it exactly."""

from __future__ import annotations

import json
import os
from importlib import resources
from pathlib import Path

import numpy as np
import sympy as sp
from sympy.printing.jscode import jscode

from ..circuit.description import circuit
from ..errors import InputError
from ..files import write_text
from ..solvers.transient import netlist
from ..waveforms import Step
from .scene import Scene

__all__ = ["lab_page", "write_lab", "engine_module", "ENGINE_VARIABLE"]

#: The environment variable naming the engine's ES module, ``eecircuit-engine.mjs``.
ENGINE_VARIABLE = "ANALOGY_WASM_ENGINE"
#: Where ``bash setup.sh test`` installs it, beside the package's source tree.
_BESIDE = Path(__file__).resolve().parents[2] / ".engines/wasm/node_modules/eecircuit-engine/dist/eecircuit-engine.mjs"
#: The most joints a lab has sliders for: the page plots every joint's rate.
MOST_JOINTS = 6


def engine_module(path: str | os.PathLike | None = None) -> Path:
    """The ES module of ngspice compiled to WebAssembly (npm ``eecircuit-engine``) that a lab inlines.

    Parameters
    ----------
    path : str or Path, optional
        Its ``dist/eecircuit-engine.mjs``; default :data:`ENGINE_VARIABLE`, else the copy
        ``bash setup.sh test`` installs beside the source tree.
    """
    chosen = path or os.environ.get(ENGINE_VARIABLE) or _BESIDE
    found = Path(chosen)
    if not found.is_file():
        raise InputError(f"the browser lab inlines ngspice compiled to WebAssembly, and {found} is not there: "
                         "npm install eecircuit-engine, then give --engine …/dist/eecircuit-engine.mjs "
                         f"(or set {ENGINE_VARIABLE})")
    return found


def _function(name: str, args: list[sp.Symbol], parts: dict) -> str:
    """A JavaScript function *name*(values) returning each sympy matrix of *parts* as nested arrays."""
    local = [sp.Symbol(f"a{k}") for k in range(len(args))]
    swap = dict(zip(args, local))
    lines = [f"function {name}(values) {{", f"  const [{', '.join(map(str, local))}] = values;", "  return {"]
    for key, matrix in parts.items():
        if matrix is None:
            lines.append(f"    {key}: null,")
            continue
        rows = [", ".join(jscode(sp.sympify(x).xreplace(swap)) for x in matrix.row(i)) for i in range(matrix.rows)]
        lines.append(f"    {key}: [{', '.join(f'[{r}]' for r in rows)}],")
    return "\n".join(lines + ["  };", "}"])


def _lab_data(scene: Scene) -> tuple[dict, str]:
    """The page's data (sliders, node map, sources, the analysis lines) and its model function's source."""
    if scene.dynamics != "linear":
        raise InputError(f"the browser lab runs the linear circuit, and scene {scene.name!r} is nonlinear (leave out "
                         "--dynamics nonlinear, or take a scene of a linear circuit)", field="dynamics")
    system = scene.system()
    if system.topology.name not in ("serial", "parallel"):
        raise InputError("the browser lab keeps the node map fixed as the sliders move: take --topology serial "
                         "or parallel", field="topology")
    if system.dof > MOST_JOINTS:
        raise InputError(f"the browser lab plots every joint: {system.dof} is more than {MOST_JOINTS}", field="robot")
    model = scene.build_model()
    mass, damping, stiffness, load = model.linear_parts()
    values = dict(model.parameters, **scene.parameter_values)
    q0 = [float(x) for x in scene.q] or []
    at = {**{sp.Symbol(k, real=True): v for k, v in values.items()}, **dict(zip(model.coordinates, q0))}
    if load is not None and any(abs(float(sp.sympify(x).xreplace(at))) > 0 for x in load):
        raise InputError("the browser lab's circuit carries no static load: take --param g=0 and no preload",
                         field="gravity")
    # a parameter at zero (g = 0) keeps its value: its terms drop out, and so do the sliders only they used
    fixed = {s: 0 for name, s in model.symbols.items() if values[name] == 0}
    mass, damping, stiffness = (None if m is None else m.xreplace(fixed) for m in (mass, damping, stiffness))
    used = set().union(*(m.free_symbols for m in (mass, damping, stiffness) if m is not None))
    coordinates = [c for c in model.coordinates if c in used]
    parameters = [s for s in model.symbols.values() if s in used]
    # a source per joint, as the circuit places one for a force on it (a slider may wake a joint at rest)
    sources = [{"name": s.name, "a": s.a, "b": s.b, "scale": s.scale, "joint": s.joint}
               for s in circuit(system.driven([1.0] * system.dof)).sources]
    steps = []
    for j, force in enumerate(system.forces):
        if len(force) > 1 or (force and (not isinstance(force[0], Step) or force[0].delay or force[0].rise)):
            raise InputError(f"the browser lab drives each joint with a step from t = 0; joint {j + 1}'s force "
                             f"is {' + '.join(w.label() for w in force)}", field="forces")
        steps.append(force[0].amplitude if force else 0.0)
    lines = netlist(system, scene.settings, printing=False).splitlines()
    analysis = [ln for ln in lines if ln.startswith((".ic", ".options", ".tran", ".save"))]
    t = np.asarray(system.topology.matrix, dtype=float)
    data = {
        "title": f"{system.provenance.robot} in the lab, starting from {scene.description or scene.name}",
        "n": system.dof,
        "joints": list(system.provenance.joints or [f"q{k + 1}" for k in range(system.dof)]),
        "T": t.tolist(), "Tinv": np.linalg.inv(t).tolist(),
        "coordinates": [{"name": str(c), "index": model.coordinates.index(c), "value": q0[model.coordinates.index(c)],
                         "min": q0[model.coordinates.index(c)] - np.pi, "max": q0[model.coordinates.index(c)] + np.pi}
                        for c in coordinates],
        "allCoordinates": q0,
        "parameters": [{"name": str(s), "value": values[str(s)], "min": values[str(s)] / 4, "max": values[str(s)] * 4}
                       for s in parameters if values[str(s)] > 0],     # a negative one keeps its value
        "allParameters": {str(s): values[str(s)] for s in parameters},
        "forces": [{"joint": j + 1, "value": f, "min": -2 * (abs(f) or 1.0), "max": 2 * (abs(f) or 1.0)}
                   for j, f in enumerate(steps)],
        "sources": sources, "analysis": analysis, "tStop": system.t_stop, "bound": scene.settings.bound,
        "zeroTol": 1e-12,
    }
    args = list(model.coordinates) + parameters
    code = _function("modelParts", args, {"M": mass, "B": damping,
                                          "K": stiffness if stiffness is not None and any(stiffness) else None})
    return data, code


def lab_page(scene: Scene, engine: str | os.PathLike | None = None) -> str:
    """The lab of *scene* as one self-contained HTML page, with no address outside it.

    Sliders set the joint coordinates and parameters the matrices depend on (a parameter from a
    quarter to four times its value) and each joint's step force. Each move writes the netlist
    again (elements from M′ = T⁻ᵀ·M·T⁻¹, B′ and K′ as the circuit description splits them), runs
    it in ngspice compiled to WebAssembly, and sets each joint rate beside the exact solution,
    computed in the page by the matrix exponential of the circuit's state at SPICE's own points,
    with each rate's error over its own peak. The ``.options`` and ``.tran`` are those analogy
    chose for the scene as given; a slider far from it may leave them short of the bound, and the
    page says so.

    Parameters
    ----------
    scene : Scene
        A linear scene of a symbolic model on the serial or parallel node map, at most
        :data:`MOST_JOINTS` joints, step forces from rest and no static load.
    engine : str or Path, optional
        The engine's ES module (:func:`engine_module`).
    """
    data, code = _lab_data(scene)
    if scene.initial_rates is not None and any(scene.initial_rates):
        raise InputError("the browser lab starts from rest: leave out the initial rates", field="initial_rates")
    source = engine_module(engine).read_text(encoding="utf-8")
    script = resources.files("analogy.scenes").joinpath("lab.js").read_text(encoding="utf-8")
    blob = json.dumps(data).replace("</", "<\\/")
    return ("<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>analogy lab</title>\n<style>"
            "body{font-family:sans-serif;margin:1.2em;max-width:1100px} label{display:inline-block;width:11em}"
            " input[type=range]{width:18em;vertical-align:middle} table{border-collapse:collapse}"
            " td,th{padding:2px 10px;border-bottom:1px solid #ccc;text-align:right} #status{color:#555}"
            " pre{background:#f6f6f6;padding:6px;max-height:16em;overflow:auto}</style></head><body>\n"
            "<h2 id='title'></h2><p id='status'>starting ngspice (WebAssembly)…</p>\n"
            "<div id='sliders'></div>\n<canvas id='plot' width='1000' height='360'></canvas>\n"
            "<table id='errors'></table>\n<details><summary>the netlist that ran</summary><pre id='netlist'></pre>"
            "</details>\n"
            f"<script type='application/json' id='lab-data'>{blob}</script>\n"
            f"<script type='text/plain' id='engine'>{source.replace('</script', '<' + chr(92) + '/script')}</script>\n"
            f"<script type='module'>\n{code}\n{script}\n</script>\n</body></html>\n")


def write_lab(scene: Scene, directory: str | os.PathLike, engine: str | os.PathLike | None = None) -> Path:
    """Write *scene*'s lab as ``index.html`` in *directory* (made if missing); return its path.

    Parameters
    ----------
    scene : Scene
        The scene (see :func:`lab_page`).
    directory : str or Path
        The folder.
    engine : str or Path, optional
        The engine's ES module (:func:`engine_module`).
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "index.html"
    write_text(path, lab_page(scene, engine))
    return path
