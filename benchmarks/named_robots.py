"""Every named robot's default `analogy compare`, linear and nonlinear, a baseline tree beside this one.

    git worktree add /tmp/analogy-before <commit>
    .venv/bin/python benchmarks/named_robots.py /tmp/analogy-before [--timeout S] [robots…]

What a user types first: `analogy compare --robot NAME [--dynamics nonlinear]`, with nothing else,
run as a process in each tree (PYTHONPATH selects it; same interpreter and packages). The two
trees may choose different scenes: that is the point, as the defaults are what changed. Printed
per robot and tree: the pose, gravity, forces and horizon each tree chose (from its netlist
header), and per solver its error over its own peak, steps and run time as the table gives them,
with the exit code (0 kept, 3 flagged, 1 failed; "timeout" past --timeout seconds).
"""
import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

HERE = str(Path(__file__).resolve().parent.parent)
ROBOTS = ("ur3", "ur5", "ur10", "panda", "kinova", "xarm7", "z1", "double_pendulum", "hopper")
_ROW = re.compile(r"^(spice|ode|reference|exact)\s+([0-9.]+)\s+\S+\s+(\S+)\s+([0-9.e+-]+)\s+\S+\s+(\d*)")


def _run(tree: str, args: list, timeout: float) -> dict:
    env = dict(os.environ, PYTHONPATH=tree)
    start = time.perf_counter()
    try:
        res = subprocess.run([sys.executable, "-m", "analogy", *args], capture_output=True, text=True,
                             timeout=timeout, env=env, cwd="/tmp")
    except subprocess.TimeoutExpired:
        return {"exit": "timeout", "wall": timeout, "rows": {}, "err": ""}
    rows = {}
    for line in res.stdout.splitlines():
        if (m := _ROW.match(line)) is not None:
            rows[m.group(1)] = (float(m.group(2)), m.group(3), float(m.group(4)), m.group(5))
    return {"exit": res.returncode, "wall": time.perf_counter() - start, "rows": rows, "err": res.stderr}


def _chosen(tree: str, robot: str) -> str:
    env = dict(os.environ, PYTHONPATH=tree)
    res = subprocess.run([sys.executable, "-m", "analogy", "netlist", "--robot", robot], capture_output=True,
                         text=True, timeout=120, env=env, cwd="/tmp")
    head = {line[2:].split(":")[0]: line[2:].split(": ", 1)[-1] for line in res.stdout.splitlines()
            if line.startswith("* ") and ": " in line}
    q = head.get("configuration", "?")
    q = ", ".join(f"{float(v):.3g}" for v in re.findall(r"=([-0-9.e+]+)", q))
    return (f"g = {head.get('parameters', '?').replace('g=', '')}; q = ({q}); "
            f"{head.get('forces', '?')}; {head.get('initial rates', '?').split('; ')[-1]}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", help="the baseline tree (a git worktree)")
    p.add_argument("robots", nargs="*", default=list(ROBOTS))
    p.add_argument("--timeout", type=float, default=300.0, help="seconds per compare (default 300)")
    args = p.parse_args()
    trees = (("before", args.before), ("this", HERE))
    for robot in args.robots:
        print(f"\n## {robot}")
        for label, tree in trees:
            print(f"{label:>6} chose: {_chosen(tree, robot)}")
        print(f"{'dynamics':<10}{'tree':>7}{'exit':>8}{'wall s':>8}   " + "   ".join(
            f"{s:>26}" for s in ("spice err/peak steps ms", "ode err/peak steps ms")))
        for dynamics in ("linear", "nonlinear"):
            for label, tree in trees:
                words = ["compare", "--robot", robot, "--no-plot", "--dynamics", dynamics]
                r = _run(tree, words, args.timeout)
                cells = []
                for solver in ("spice", "ode"):
                    if solver in r["rows"]:
                        ms, _, rel, steps = r["rows"][solver]
                        cells.append(f"{rel:>10.2e} {steps:>8} {ms:>7.0f}")
                    else:
                        cells.append(f"{'-':>26}")
                print(f"{dynamics:<10}{label:>7}{r['exit']!s:>8}{r['wall']:>8.1f}   " + "   ".join(cells))
                sys.stdout.flush()


if __name__ == "__main__":
    main()
