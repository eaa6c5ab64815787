"""A baseline checkout against this tree, in one run, taking turns: batched throughput, warm SPICE
solve time and ``analogy netlist`` whole-process time; medians and ratios are printed.

    git worktree add /tmp/baseline <commit>
    .venv/bin/python benchmarks/side_by_side.py /tmp/baseline [turns]

Both trees run with the same interpreter and packages (PYTHONPATH selects the tree).
BYTECODE=0 measures with bytecode caching off, as in an environment that sets
PYTHONDONTWRITEBYTECODE.
"""
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

PY = sys.executable
TREES = {"old": str(Path(sys.argv[1]).resolve()), "new": str(Path(__file__).resolve().parent.parent)}
BATCH = r'''
import json, time, numpy as np, analogy
from analogy.batch import run_batch
base = analogy.scene("default")
q2 = np.random.default_rng(0).uniform(-np.pi, np.pi, 10000)
items = [base.replace(q=(0.0, float(x))) for x in q2]
res = run_batch(items, "fast", group_size=100, workers=2)
ok = res.errors[np.isfinite(res.errors)]
assert analogy.__file__.startswith(__import__("os").environ["PYTHONPATH"])
print(json.dumps([res.throughput, float(ok.max()), len(res.failures)]))
'''
SOLVE = r'''
import json, time, statistics, analogy
try:
    from analogy.spice import solve_spice           # the old layout
except ImportError:
    from analogy.solvers.spice import solve_spice
s = analogy.scene("default").system()
for _ in range(50): solve_spice(s, preset="fast")
ts = []
for _ in range(400):
    t0 = time.perf_counter(); solve_spice(s, preset="fast"); ts.append(time.perf_counter() - t0)
print(json.dumps(statistics.median(ts)))
'''
BYTECODE = os.environ.get("BYTECODE", "1") == "1"


def environment(tree):
    env = dict(os.environ, PYTHONPATH=tree)
    if BYTECODE:                        # as users run: compiled modules cached on disk
        env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def run(tree, code):
    env = environment(tree)
    out = subprocess.run([PY, "-c", code], capture_output=True, text=True, env=env, cwd="/tmp")
    if out.returncode:
        raise SystemExit(out.stderr)
    return json.loads(out.stdout.splitlines()[-1])
def netlist_time(tree):
    env = environment(tree)
    t0 = time.perf_counter()
    subprocess.run([PY, "-m", "analogy", "netlist"], capture_output=True, env=env, cwd="/tmp", check=True)
    return time.perf_counter() - t0
turns = int(sys.argv[2]) if len(sys.argv) > 2 else 3
res = {k: {"batch": [], "solve": [], "netlist": []} for k in TREES}
for k in TREES: netlist_time(TREES[k])      # warm the compiled-model cache of both
for turn in range(turns):
    for k, tree in (TREES.items() if turn % 2 == 0 else reversed(TREES.items())):
        thr, worst, failed = run(tree, BATCH)
        res[k]["batch"].append(thr)
        res[k]["solve"].append(run(tree, SOLVE))
        res[k]["netlist"].append(statistics.median(netlist_time(tree) for _ in range(7)))
        print(k, turn, f"{thr:,.0f} scenes/s (worst {worst:.2e}, {failed} failed)",
              f"solve {res[k]['solve'][-1]*1e3:.3f} ms", f"netlist {res[k]['netlist'][-1]*1e3:.0f} ms", flush=True)
med = {k: {m: statistics.median(v) for m, v in d.items()} for k, d in res.items()}
print(json.dumps(med, indent=1))
print("ratios new/old (higher is better):",
      f"throughput {med['new']['batch'] / med['old']['batch']:.3f},",
      f"solve speed {med['old']['solve'] / med['new']['solve']:.3f},",
      f"netlist speed {med['old']['netlist'] / med['new']['netlist']:.3f}")
