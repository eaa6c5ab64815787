"""SPICE on ringing circuits, side by side with a previous tree in one run: steps, time, worst error/peak.

    git worktree add /tmp/analogy-before <commit>
    .venv/bin/python benchmarks/ringing_arms.py /tmp/analogy-before [preset ...]

The UR arms hang with zero joint damping: rigid-body modes and undamped oscillations whose
trapezoidal phase error grows with every radian they turn. Each case is made once, in this tree
(a URDF robot's default experiment: its pose, g, forces and t_stop), and handed to both trees as
explicit values, so both run the same circuit whatever either's scene defaults are. Each tree
runs in its own process (PYTHONPATH selects it), with the same interpreter and packages; the
time is SPICE's own (the solver's stats), the error each output's over its own peak against the
exact solution, on SPICE's own points.
"""
import json
import subprocess
import sys
from pathlib import Path

PY = sys.executable
TREES = {"before": str(Path(sys.argv[1]).resolve()), "now": str(Path(__file__).resolve().parent.parent)}
PRESETS = sys.argv[2:] or ["accurate"]
ROBOTS = ("ur3", "ur5", "ur10")
BUILTIN = ("default", "serial3", "parallel3", "random10")

CASES = r'''
import json, analogy
from analogy.scenes.robot_defaults import robot_scene
out = []
for name in %r:
    sc = robot_scene(name)
    out.append([name, name, list(sc.q), list(sc.forces), sc.t_stop, dict(sc.parameters)["g"]])
for name in %r:
    out.append([name, None, None, None, None, None])
out.append(["ur5, t_stop 2", "ur5", out[1][2], out[1][3], 2.0, out[1][5]])
print(json.dumps(out))
''' % (ROBOTS, BUILTIN)

RUN = r'''
import json, sys, analogy
from analogy.scenes.scene import Scene
name, robot, q, forces, t_stop, g = json.loads(sys.argv[1])
preset = sys.argv[2]
if robot is None:
    system = analogy.scene(name).system()
else:
    system = Scene.of(name, robot, q=q, forces=forces, t_stop=t_stop, parameters={"g": g}).system()
c = analogy.compare(system, preset, ["spice"])
tr = c.results["spice"]
print(json.dumps([tr.stats.steps, tr.stats.wall_time, c.max_relative_error("spice"), bool(c.outside_bound())]))
'''


def run(tree: str, code: str, *args: str):
    out = subprocess.run([PY, "-c", code, *args], capture_output=True, text=True, cwd="/tmp",
                         env={"PYTHONPATH": tree, "PATH": "/usr/bin:/bin"})
    if out.returncode:
        raise SystemExit(out.stderr[-2000:])
    return json.loads(out.stdout.splitlines()[-1])


cases = run(TREES["now"], CASES)
print(f"{'case':16s} {'preset':9s} | {'steps before':>12s} {'time [s]':>9s} {'err/peak':>9s} | "
      f"{'steps now':>10s} {'time [s]':>9s} {'err/peak':>9s} | steps now/before")
for preset in PRESETS:
    for case in cases:
        got = {k: run(tree, RUN, json.dumps(case), preset) for k, tree in TREES.items()}
        (sb, tb, eb, fb), (sn, tn, en, fn) = got["before"], got["now"]
        flag = lambda f: "!" if f else " "      # noqa: E731 - outside the preset's bound
        print(f"{case[0]:16s} {preset:9s} | {sb:12,d} {tb:9.3f} {eb:8.2e}{flag(fb)} | {sn:10,d} {tn:9.3f} "
              f"{en:8.2e}{flag(fn)} | {sn / sb:.2f}", flush=True)
print("! = outside the preset's bound (exit 3)")
