"""Parse once and ``alter``, against parsing each group afresh: what ngspice charges for each.

    python benchmarks/alter.py [GROUP] [REPEATS]

A batch runs groups of GROUP default 2-DOF scenes (100, as ``analogy batch`` does), one
netlist each. Parsing a group's netlist (``ngSpice_Circ``) is part of ngspice's floor. The
alternative keeps one group's circuit loaded and changes the next group's values in place
with ``alter``. This times, per scene, in the quiet library the batches run in:

- loading a group's netlist;
- altering only its capacitors and resistors, one ``alter`` command each.

A group also needs its current sources and initial conditions changed, and ``alter`` cannot
change ``.ic``. So the second figure is a lower bound on the alternative's cost. The figures
are medians of REPEATS.
"""

import statistics
import sys
import time

import numpy as np

from analogy.batch.plan import plan_groups
from analogy.scenes.builtin import scene
from analogy.solvers.ngspice import _Lines
from analogy.solvers.quiet_ngspice import quiet_session
from analogy.solvers.transient import batch_netlist


def main(group: int = 100, repeats: int = 7) -> None:
    base = scene("default")
    q2 = np.random.default_rng(0).uniform(-np.pi, np.pi, 2 * group)
    first, second = plan_groups([base.replace(q=(0.0, float(x))) for x in q2], group)[:2]
    loaded, other = (batch_netlist(g.build()[0], "fast") for g in (first, second))
    # every capacitor and resistor of the second group, as "alter NAME = VALUE"
    alters = [f"alter {words[0]} = {words[3]}" for words in (line.split() for line in other.splitlines())
              if len(words) == 4 and words[0][:1] in "CR"]
    sess = quiet_session()
    sess.run(loaded, None, {})          # a warm-up: the library and its first circuit
    # the session's own steps, timed apart: run() loads, runs, reads and frees in one call
    load, alter = [], []
    for _ in range(repeats):
        lines = _Lines(sess._ffi, loaded)
        start = time.perf_counter()
        sess._load(lines)
        load.append(time.perf_counter() - start)
        start = time.perf_counter()
        for command in alters:
            sess._command(command)
        alter.append(time.perf_counter() - start)
        sess._free()
    per = {k: statistics.median(v) / group * 1e6 for k, v in (("load", load), ("alter", alter))}
    print(f"groups of {group} default 2-DOF scenes, {len(alters) // group} alter commands a scene, "
          f"medians of {repeats}:")
    print(f"  parse a group's netlist: {per['load']:.1f} us a scene")
    print(f"  alter its C and R values only: {per['alter']:.1f} us a scene "
          f"({per['alter'] / per['load']:.2f}x the parse; sources and .ic not yet changed)")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
