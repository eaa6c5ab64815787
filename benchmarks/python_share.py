"""Python's share of a batch group beside ngspice's own work: this tree against another, in turns.

    python benchmarks/python_share.py [--baseline TREE] [--turns 4] [--repeats 15] [--replay]

A batch group of ten circuits of 100 default 2-DOF scenes at random q2 (``solve_group``, one
group at a time on one thread, as ``run_batch(threads=1)`` runs it) costs ngspice's runs of its
ten netlists and the Python around them: planning, building the stack, its scales, the netlists,
the exact solution and the errors. Each turn runs, in a fresh process, the group and then ngspice
alone on the same ten netlists in the same quiet library, REPEATS times each, and takes the CPU
time of each; Python's share is the group's CPU beyond ngspice's, a scene, from the minima over
the repeats (the machine's noise only adds) and from the medians. With ``--baseline``, a tree
(a checkout of another commit) takes every other turn, so that both meet the machine alike; the
last lines are the medians over the turns and their ratio.

With ``--replay``, ngspice runs each netlist once and its results are handed back for every later
run of the same text, so a repeat of the group is its Python alone, timed directly rather than as
a difference of two noisy times (the floor is then not measured).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

SCENES, CIRCUITS = 1000, 10


def measure(repeats: int, replay: bool = False) -> dict:
    """One turn in this process: CPU seconds a scene of the group and of ngspice alone, each repeat
    (with *replay*, of the group with ngspice's results replayed, and no floor)."""
    import numpy as np

    if replay:
        _replay_ngspice()

    from analogy.batch.plan import as_system, plan_groups, solve_group
    from analogy.circuit.scales import run_scales
    from analogy.heap import retain_freed_memory
    from analogy.presets import preset
    from analogy.scenes.builtin import scene
    from analogy.solvers.quiet_ngspice import quiet_session
    from analogy.solvers.transient import batch_netlist

    retain_freed_memory()       # as the analogy command does for its own process
    base = scene("default")
    items = [base.replace(q=(0.0, float(x))) for x in np.random.default_rng(0).uniform(-np.pi, np.pi, SCENES)]
    fast, size = preset("fast"), SCENES // CIRCUITS
    systems = [as_system(item) for item in items]
    texts = [batch_netlist(systems[k:k + size], "fast", run_scales(systems[k:k + size])) for k in range(0, SCENES, size)]
    session = quiet_session()
    session.run(texts[0], None, {})
    solve_group(plan_groups(items, size, CIRCUITS)[0], fast, ["spice"], "auto")     # a warm-up
    group, floor = [], []
    for _ in range(repeats):
        start = time.process_time()
        for text in texts if not replay else ():
            session.run(text, None, {})
        floor.append((time.process_time() - start) / SCENES)
        start = time.process_time()
        solve_group(plan_groups(items, size, CIRCUITS)[0], fast, ["spice"], "auto")
        group.append((time.process_time() - start) / SCENES)
    return {"group": group, "floor": floor}


def _replay_ngspice() -> None:
    """The SPICE solver's quiet runs answered from the first run of each netlist text."""
    import analogy.solvers.spice as spice

    kept: dict = {}
    first_run = spice.run_quietly

    def replayed(text, t_stop, stats=None):
        if text not in kept:
            ran: dict = {}
            kept[text] = (first_run(text, t_stop, ran), ran)
        if stats is not None:
            stats.update(kept[text][1])
        return kept[text][0]
    spice.run_quietly = replayed


def _turn(tree: str, repeats: int, replay: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=tree, OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, __file__, "--measure", "--repeats", str(repeats)] + ["--replay"] * replay,
                         env=env, cwd=tree, capture_output=True, text=True, check=True).stdout
    return json.loads(out.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="another tree (a checkout) to take turns with")
    parser.add_argument("--turns", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--replay", action="store_true", help="time the group's Python alone, ngspice's results replayed")
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure(args.repeats, args.replay)))
        return
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    trees = {"this tree": here} | ({"baseline": os.path.abspath(args.baseline)} if args.baseline else {})
    shares: dict = {name: [] for name in trees}
    what = "the group's own CPU, ngspice's results replayed" if args.replay else \
        "CPU beyond ngspice alone on the same netlists"
    print(f"Python's share of a group of {CIRCUITS} circuits of {SCENES // CIRCUITS} default scenes, one group at a time, "
          f"us a scene: {what} (minima, then medians, of {args.repeats} repeats)")
    for turn in range(args.turns):
        for name, tree in trees.items():
            got = _turn(tree, args.repeats, args.replay)
            group, floor = (1e6 * min(got[k]) for k in ("group", "floor"))
            median = 1e6 * (statistics.median(got["group"]) - statistics.median(got["floor"]))
            shares[name].append(group - floor)
            print(f"  turn {turn + 1}, {name}: group {group:.1f}, ngspice alone {floor:.1f}, share {group - floor:.1f} "
                  f"(medians: {median:.1f})")
    for name, values in shares.items():
        print(f"{name}: median share {statistics.median(values):.1f} us a scene over {len(values)} turns")
    if args.baseline:
        ratios = [a / b for a, b in zip(shares["this tree"], shares["baseline"])]
        print(f"this tree / baseline, turn by turn: {', '.join(f'{r:.2f}' for r in ratios)}; "
              f"median {statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main()
