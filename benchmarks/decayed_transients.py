"""SPICE steps, run time and worst per-output error of the named robots at g = 0, a baseline tree
beside this one, in one run: a decay that is over early should not set the step for the whole run.

    git worktree add /tmp/analogy-before <commit>
    .venv/bin/python benchmarks/decayed_transients.py /tmp/analogy-before [preset] [robots…]

Each tree runs in its own process (PYTHONPATH selects it) with the same interpreter and packages.
Both build the robot with their own code at g = 0, then run the same inputs: a unit step on every
joint over 10 s (pinned, so that changed scene defaults do not change the circuit). The fastest
decay each tree sees is printed beside its figures, so that a different model shows. Last, this
tree's own scene for each robot (its defaults) runs as well. Errors are each output's max |x − x_exact|
over its own peak, on SPICE's own points; the run time is the in-process ngspice solve.
"""
import json
import subprocess
import sys
from pathlib import Path

PY = sys.executable
HERE = str(Path(__file__).resolve().parent.parent)
RUN = r'''
import json, sys, time, numpy as np, analogy
assert analogy.__file__.startswith(sys.argv[1])
from analogy.cli import build_parser, scene_from_args
from analogy.circuit.scales import system_scales
from analogy.results.metrics import output_errors
from analogy.solvers.exact import solve_exact
from analogy.solvers.spice import solve_spice
robot, preset, pinned = sys.argv[2], sys.argv[3], sys.argv[4] == "1"
words = ["compare", "--robot", robot, "--param", "g=0"] + (["--t-stop", "10"] if pinned else [])
sc = scene_from_args(build_parser().parse_args(words))
if pinned:
    sc = sc.replace(forces=(1.0,) * len(sc.q))
system = sc.system()
scales = system_scales(system)
start = time.perf_counter()
tr = solve_spice(system, preset=preset)
wall = time.perf_counter() - start
_, rel = output_errors(tr.rates, solve_exact(system, tr.time).rates)
print(json.dumps({"steps": tr.stats.steps, "wall": wall, "worst": float(np.max(rel)),
                  "output": f"r{int(np.argmax(rel)) + 1}", "t_stop": float(system.t_stop),
                  "decay": float(np.max(scales.decays, initial=0.0)), "cap": tr.settings.max_step}))
'''


def run(tree: str, robot: str, preset: str, pinned: bool) -> dict:
    out = subprocess.run([PY, "-c", RUN, tree, robot, preset, "1" if pinned else "0"], capture_output=True,
                         text=True, env={"PYTHONPATH": tree, "PATH": "/usr/bin:/bin"}, cwd="/tmp")
    if out.returncode:
        return {"error": out.stderr.strip().splitlines()[-1]}
    return json.loads(out.stdout.splitlines()[-1])


def line(label: str, r: dict) -> str:
    if "error" in r:
        return f"  {label:22s} failed: {r['error']}"
    return (f"  {label:22s} t_stop {r['t_stop']:>5g} s  steps {r['steps']:>10,d}  spice {r['wall']:7.2f} s  "
            f"worst {r['worst']:.2e} ({r['output']})  cap {r['cap']:.3g} s  fastest decay {r['decay']:.4g}/s")


def main() -> None:
    before = str(Path(sys.argv[1]).resolve())
    preset = sys.argv[2] if len(sys.argv) > 2 else "accurate"
    robots = sys.argv[3:] or ["xarm7", "z1", "ur5", "panda", "kinova"]
    print(f"preset {preset}; baseline {before}, this tree {HERE}")
    for robot in robots:
        print(f"{robot} --param g=0")
        print(line("before, 10 s unit steps", run(before, robot, preset, True)), flush=True)
        print(line("after, 10 s unit steps", run(HERE, robot, preset, True)), flush=True)
        print(line("after, its own scene", run(HERE, robot, preset, False)), flush=True)


if __name__ == "__main__":
    main()
