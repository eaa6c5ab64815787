"""SPICE's steps and time against its error on a few defaults: a baseline tree beside this one, per ngspice.

    git worktree add /tmp/analogy-before <commit>
    .venv/bin/python benchmarks/work_precision.py /tmp/analogy-before [--repeats 3] [--engines 39,46]

Each scene is `analogy compare …` as a user types it, run as a process in each tree (PYTHONPATH
selects it; same interpreter and packages) with each engine: "39" is the one on the machine,
"46" the one `bash setup.sh engine` fetches into `.engines/` (KLU). Printed per scene, tree and
engine: the exit code, SPICE's worst error over its own peak, its steps and the median of its run
time [ms] over the repeats, the ODE's, and the ratio of the two medians; beside them the ideal
trapezoidal count at 0.8 of the bound (the equidistributed schedule of this tree's truncation model, a linear circuit's only).
"""
import argparse
import glob
import os
import statistics
import sys
from pathlib import Path

HERE = str(Path(__file__).resolve().parent.parent)
sys.path.insert(0, str(Path(__file__).resolve().parent))
from named_robots import _run  # noqa: E402  (the same process runner and table parser)

SCENES = (
    ("default 2-DOF", ["compare"], 1e-6),
    ("serial10", ["compare", "--robot", "serial10"], 1e-6),
    ("parallel3 (springs)", ["compare", "--robot", "parallel3"], 1e-6),
    ("ur5 hanging", ["compare", "--robot", "ur5"], 1e-6),
    ("serial100 modal, fast", ["compare", "--robot", "serial100", "--topology", "modal", "--preset", "fast"], 1e-3),
    ("serial100, fast", ["compare", "--robot", "serial100", "--preset", "fast"], 1e-3),
    ("serial200, fast", ["compare", "--robot", "serial200", "--preset", "fast"], 1e-3),
    ("nonlinear 2-DOF", ["compare", "--dynamics", "nonlinear"], 1e-6),
)


def _engine(version: str) -> dict:
    """The environment that selects ngspice *version* ("39": the machine's own)."""
    if version == "39":
        return {}
    root = Path(HERE) / ".engines" / f"ngspice-{version}"
    libs = glob.glob(str(root / "usr" / "lib" / "*" / "libngspice.so.0"))
    if not libs:
        raise SystemExit(f"no ngspice {version} under {root}: run bash setup.sh engine")
    return {"NGSPICE_LIBRARY_PATH": libs[0], "SPICE_SCRIPTS": str(root / "usr" / "share" / "ngspice" / "scripts"),
            "PATH": f"{root / 'bin'}:{os.environ['PATH']}"}


def _ideal(words: list, bound: float) -> str:
    """This tree's equidistributed trapezoidal count at 0.8 of *bound* (a linear circuit's)."""
    if "--dynamics" in words:
        return "-"
    sys.path.insert(0, HERE)
    from analogy.cli.parser import build_parser
    from analogy.cli.scene_options import built_system, scene_from_args
    from analogy.solvers.truncation import MODEL_SHARE, truncation_model
    system = built_system(scene_from_args(build_parser().parse_args(words)))
    model = truncation_model(system)
    return "-" if model is None else f"{model.ideal_points(MODEL_SHARE * bound):,.0f}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", help="the baseline tree (a git worktree)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--engines", default="39,46")
    p.add_argument("--timeout", type=float, default=600.0)
    p.add_argument("--only", default="", help="the scenes whose name contains this text")
    args = p.parse_args()
    trees = (("before", str(Path(args.before).resolve())), ("this", HERE))
    print(f"{'scene':<24}{'ideal':>8}{'tree':>8}{'ngspice':>8}{'exit':>6}"
          f"{'spice err':>11}{'steps':>9}{'ms':>9}{'ode err':>11}{'ode ms':>8}{'spice/ode':>10}")
    for name, words, bound in SCENES:
        if args.only not in name:
            continue
        ideal = _ideal(words, bound)
        for engine in args.engines.split(","):
            extra = _engine(engine)
            for label, tree in trees:
                runs = []
                for _ in range(args.repeats):
                    saved = dict(os.environ)
                    os.environ.update(extra)
                    try:
                        runs.append(_run(tree, [*words, "--no-plot"], args.timeout))
                    finally:
                        os.environ.clear()
                        os.environ.update(saved)
                last = runs[-1]
                spice, ode = last["rows"].get("spice"), last["rows"].get("ode")
                ms = [r["rows"]["spice"][0] for r in runs if "spice" in r["rows"]]
                ode_ms = [r["rows"]["ode"][0] for r in runs if "ode" in r["rows"]]
                cells = (f"{spice[2]:>11.2e}{spice[3]:>9}{statistics.median(ms):>9.0f}" if spice else f"{'-':>29}")
                cells += (f"{ode[2]:>11.2e}{statistics.median(ode_ms):>8.1f}" if ode else f"{'-':>19}")
                # the ratio of the medians: SPICE's time over the ODE's in the same runs
                cells += f"{statistics.median(ms) / statistics.median(ode_ms):>10.1f}" if ms and ode_ms else f"{'-':>10}"
                print(f"{name:<24}{ideal:>8}{label:>8}{engine:>8}{last['exit']!s:>6}{cells}")
                sys.stdout.flush()


if __name__ == "__main__":
    main()
