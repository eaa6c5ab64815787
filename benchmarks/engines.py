"""Each engine's worst error per output against the exact solution, on the paper's five robots.

    python benchmarks/engines.py [PRESET]

Rows: the system's ngspice in process, ngspice 46 in process (.engines/ngspice-46, from
``bash setup.sh engine``), the WebAssembly ngspice under node (.engines/wasm) and gnucap.
Each figure is max over outputs of max |r - r_exact| / peak |r_exact|, on the engine's own
points (the WebAssembly build without the printing block's ``interp``). A missing engine is
a dash.
"""

import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.scenes.builtin import PAPER_EXAMPLES, scene
from analogy.solvers.exact import solve_exact
from analogy.solvers.transient import netlist
from analogy.study.comparison import compare

ROOT = Path(__file__).resolve().parent.parent
WASM = ROOT / ".engines/wasm/node_modules/eecircuit-engine/dist/eecircuit-engine.mjs"
PROBE = ("import sys\nfrom analogy.scenes.builtin import scene\nfrom analogy.study.comparison import compare\n"
         "from analogy.solvers.spice import session\n"
         "c = compare(scene(sys.argv[1]).system(), sys.argv[2], ['spice', 'exact'])\n"
         "print(session().version, c.errors()['spice'].relative)")


def in_process(name, preset, env=None):
    res = subprocess.run([sys.executable, "-c", PROBE, name, preset], capture_output=True, text=True,
                         env=env, timeout=600)
    if res.returncode:
        return None, None
    version, error = res.stdout.split()
    return int(version), float(error)


def wasm(name, preset):
    if shutil.which("node") is None or not WASM.exists():
        return None
    system = scene(name).system()
    text = "\n".join(line for line in netlist(system, preset).splitlines() if line != "option interp")
    with tempfile.NamedTemporaryFile("w", suffix=".cir") as fh:
        fh.write(text + "\n")
        fh.flush()
        res = subprocess.run(["node", str(ROOT / "tests/engines/wasm_ngspice.mjs"), str(WASM), fh.name],
                             capture_output=True, text=True, timeout=600)
    data = json.loads(res.stdout)["data"]
    t = np.concatenate([[0.0], data["time"]])
    v = np.vstack([system.initial_voltages, np.column_stack([data[f"v({n})"] for n in system.nodes])])
    return float(np.max(output_errors(system.joint_rates(v), solve_exact(system, t).rates)[1]))


def main(preset="accurate"):
    lib46 = glob.glob(str(ROOT / ".engines/ngspice-46/usr/lib/*/libngspice.so.0"))
    env46 = dict(os.environ, NGSPICE_LIBRARY_PATH=lib46[0],
                 SPICE_SCRIPTS=str(ROOT / ".engines/ngspice-46/usr/share/ngspice/scripts")) if lib46 else None
    print(f"preset {preset} (bound {PRESETS[preset].bound:g}): worst error / own peak against exact")
    print(f"{'robot':<10} {'system ngspice':>16} {'ngspice 46':>12} {'wasm 45.2':>12} {'gnucap':>12}")
    for name in PAPER_EXAMPLES:
        v0, e0 = in_process(name, preset)
        v46, e46 = in_process(name, preset, env46) if env46 else (None, None)
        ew = wasm(name, preset)
        c = compare(scene(name).system(), preset, ["gnucap", "exact"]) if shutil.which("gnucap") else None
        eg = c.errors()["gnucap"].relative if c is not None and c.results["gnucap"].success else None
        cells = [f"{x:.4g}" if x is not None else "-" for x in (e0, e46 if v46 == 46 else None, ew, eg)]
        print(f"{name:<10} {cells[0] + f' ({v0})':>16} {cells[1]:>12} {cells[2]:>12} {cells[3]:>12}")


if __name__ == "__main__":
    main(*sys.argv[1:])
