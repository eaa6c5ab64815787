"""Command-line interface: argument parsing and printing over the analogy API.

Each command imports the modules it uses when it runs, so that ``analogy netlist``
starts without the solvers, the batch machinery or the benchmarks.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from concurrent.futures import BrokenExecutor
from dataclasses import replace
from pathlib import Path

from . import __version__
from .solvers.transient import netlist
from .errors import EXIT_ACCURACY, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE
from .errors import AccuracyError, AnalogyError, InputError, SimulationError
from .model.expressions import (
    parse_number,
)
from .presets import PRESETS
from .presets import preset as get_preset
from .results.output import check_plot_path
from .batch.cli import batch_options
from .scenes.arguments import PRESET_HELP, scene_from_args, scene_options
from .scenes.builtin import SCENES, scene
from .scenes.scene import Scene

__all__ = [
    "EXIT_ACCURACY",
    "EXIT_FAILED",
    "EXIT_OK",
    "EXIT_USAGE",
    "build_parser",
    "main",
    "scene_from_args",
]

class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit 2) instead of a usage dump."""

    def error(self, message):
        raise InputError(f"{message} (see {self.prog} --help)")


def build_parser() -> argparse.ArgumentParser:
    """The ``analogy`` argument parser, with one subcommand per task."""
    parser = _Parser(prog="analogy",
                     description="Robot dynamics as electric circuits: netlists, SPICE and checks.")
    parser.add_argument("--version", action="version", version=f"analogy {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    p = sub.add_parser("netlist", help="write the equivalent-circuit SPICE netlist")
    scene_options(p)
    p.add_argument("-o", "--output", help="file to write (default: stdout)")
    p.add_argument("--save", metavar="NAMES", help="nodes or elements to save, e.g. 'n1, C1_2' (default: all nodes)")
    p.add_argument("--realizable", action="store_true",
                   help="no negative values: negative elements behind 1:-1 couplings")
    p.add_argument("--dynamics", default="linear", choices=["linear", "nonlinear"],
                   help="the circuit at q (linear), or the robot's full nonlinear circuit: "
                        "charge-defined capacitors, behavioural forces and integrators")
    p = sub.add_parser("compare", help="run SPICE, ODE and exact solvers and compare them")
    scene_options(p)
    p.add_argument("--solvers", default="spice,ode,exact",
                   help="comma-separated registered solvers: spice, ode, exact, reference")
    p.add_argument("--dynamics", default="linear", choices=["linear", "nonlinear", "both"],
                   help="the circuit at q (linear), the full configuration-dependent motion, or both: "
                        "how long the linear circuit holds")
    p.add_argument("--step", metavar="SECONDS", help="output step of the shared time grid "
                   "(default: SPICE's own points); errors are measured on each solver's own points")
    p.add_argument("--timeout", metavar="SECONDS", help="wall-time limit of each ODE integration "
                   "(default: the preset's, 300 s); past it the solver fails with one sentence")
    p.add_argument("--budget", metavar="POINTS", help="most time points (and force segments) a run may "
                   "need, estimated before it starts (default: the preset's, 1e8 at accurate, 1e7 at fast)")
    p.add_argument("--csv", metavar="FILE", help="write joint rates of every solver to CSV")
    p.add_argument("--plot", metavar="FILE.png", help="write a plot of rates and errors")
    p.add_argument("--no-plot", action="store_true", help="never import the plotting library")
    p = sub.add_parser("modes", help="natural frequencies and damping ratios of the linear system at q")
    scene_options(p)
    p.add_argument("--locked", metavar="JOINTS", help="joints held clamped, e.g. '1' or '1,2'")
    p.add_argument("--csv", metavar="FILE", help="write mode, omega_rad_s, f_hz, damping_ratio")
    p = sub.add_parser("ac", help="ngspice's .ac sweep against the exact mobility (M's + B' + K'/s)^-1")
    scene_options(p)
    for flag, what in (("--f-start", "first frequency (default: modes / 10)"), ("--f-stop", "last (modes x 10)")):
        p.add_argument(flag, type=float, metavar="HZ", help=what)
    p.add_argument("--points", type=int, default=500, help="points per decade (default 500)")
    for flag, what in (("--csv", "|Y| and phase of SPICE's mobilities"), ("--plot", "a Bode plot")):
        p.add_argument(flag, metavar="FILE", help=f"write {what}")
    p = sub.add_parser("verify", help="check every built-in example: SPICE and ODE against exact, "
                                      "exact against a 40-digit mpmath solution")
    p.add_argument("--preset", default="accurate", choices=list(PRESETS), help=PRESET_HELP)
    p.add_argument("--scenes", default=None, help="comma-separated scene names (default: all)")
    sub.add_parser("scenes", help="list the built-in scenes")
    p = sub.add_parser("draw", help="draw the equivalent circuit and the mechanical system (SVG and PNG)")
    scene_options(p)
    p.add_argument("-o", "--output-dir", default=".", help="folder for the drawings (default: .)")
    p.add_argument("--stem", help="file name stem (default: the scene's name, with its content "
                                  "key when changed from a built-in scene)")
    p.add_argument("--schematic", action="store_true", help="draw schematics even past 6 nodes "
                   "(default there: a map of the element values by node pair)")
    p = sub.add_parser("run", help="run scene files (TOML): exactly what each asks for")
    p.add_argument("scene_files", nargs="+", metavar="SCENE.toml", help="one or more .toml scenes")
    p.add_argument("--preset", choices=list(PRESETS), help="override each scene's accuracy preset")
    p.add_argument("--solvers", help="override each scene's solvers, e.g. spice,exact")
    p.add_argument("--output-dir", help="folder for the scene's output files (default: next to it)")
    p.add_argument("--no-plot", action="store_true", help="skip plots even if the scene asks for one")
    p.add_argument("--dynamics", choices=["linear", "nonlinear"], help="override the scene's dynamics")
    batch_options(sub)
    p = sub.add_parser("bench", help="run time against error: ngspice settings, ODE methods, exact solver")
    p.add_argument("--repeats", type=int, default=5, help="timed runs per setting (median; default 5)")
    p.add_argument("--quick", action="store_true", help="a small grid on the 2- and 10-DOF scenes "
                   "(seconds), for a first look")
    p.add_argument("--full", action="store_true", help="the full ngspice grid (method x reltol x trtol x max step)")
    p.add_argument("--csv", default="bench.csv", help="CSV output (default: bench.csv)")
    p.add_argument("--plot", default="bench.png", help="work-precision plot (default: bench.png)")
    p.add_argument("--no-progress", action="store_true", help="no progress (a bar on a terminal, "
                   "plain lines otherwise)")
    p = sub.add_parser("stress", help="stress-test numerical stability: families of hard cases, each run by "
                                      "every solver that applies (CSV, a plot per family, a summary)")
    p.add_argument("--quick", action="store_true", help="only the ends of each sweep (under a minute)")
    p.add_argument("--families", default="abcdefg", help="family letters (default abcdefg): a conditioning, "
                   "b time scales, c long runs, d size, e units, f near-singular, g nonlinear")
    p.add_argument("-o", "--output", default="stress", help="folder for stress.csv, stress.md and "
                   "stress_<family>.png (made if missing; default: stress)")
    p.add_argument("--timeout", type=float, default=10.0, help="wall-time limit of each ODE run [s] (default 10)")
    p.add_argument("--no-progress", action="store_true", help="no progress (a bar on a terminal, "
                   "plain lines otherwise)")
    p = sub.add_parser("memory", help="resident memory grown per in-process SPICE run (kB/run)")
    p.add_argument("--runs", type=int, default=10_000, help="counted runs (default 10000)")
    p.add_argument("--preset", default="accurate", choices=list(PRESETS), help=PRESET_HELP)
    p.add_argument("--scene", default="default", help="built-in scene (default: default)")
    p = sub.add_parser("throughput", help="scenes per second: batched ngspice runs against per-scene loops")
    p.add_argument("-n", type=int, default=10_000, help="number of 2-DOF scenes (default 10000)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--group-size", type=int, default=100, help="scenes per ngspice run (default 100)")
    p.add_argument("--baseline", type=int, default=500, help="scenes for the per-scene loops (default 500)")
    p.add_argument("--repeats", type=int, default=3, help="turns of every path; medians are reported (default 3)")
    p.add_argument("--preset", default="fast", choices=list(PRESETS), help=PRESET_HELP)
    p.add_argument("--no-progress", action="store_true", help="no progress lines")
    p.add_argument("--sweep", metavar="SWEEP.toml", help="instead: this sweep into the store -o DIR, "
                   "beside the in-memory batched path on its first --baseline scenes, with peak memory")
    p.add_argument("-o", "--output", metavar="DIR", help="the store of --sweep")
    return parser


def _title(sc: Scene) -> str:
    return f"analogy {sc.name}: {sc.description}" if sc.description else f"analogy {sc.name}"


def _check_writable(path):
    if path is None:
        return
    if Path(path).is_dir():
        raise InputError(f"cannot write {path}: it is a folder")
    folder = Path(path).resolve().parent
    if not folder.is_dir():
        raise InputError(f"cannot write {path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK) or (Path(path).exists() and not os.access(path, os.W_OK)):
        raise InputError(f"cannot write {path}: permission denied")


def _cmd_netlist(args) -> int:
    sc = scene_from_args(args)
    if args.realizable and sc.dynamics != "linear":
        raise InputError("--realizable applies to the linear circuit, not to --dynamics nonlinear")
    _check_writable(args.output)
    save = None if args.save is None else [s.strip() for s in args.save.split(",") if s.strip()]
    text = netlist(sc.system(), args.preset, save=save, realizable=args.realizable, title=_title(sc))
    if args.output:
        try:
            Path(args.output).write_text(text)
        except OSError as exc:
            raise InputError(f"cannot write {args.output}: {exc.strerror}") from None
    else:
        sys.stdout.write(text)
    return EXIT_OK


def _accuracy_exit(flags: dict, preset: str, bound: float, result=None) -> int:
    for solver, err in flags.items():
        worst = getattr(result, "worst_output", None)
        which = f" on {worst(solver)[0]}" if worst is not None and solver in result.results else ""
        print(f"analogy: accuracy: {solver} error{which} {err:.3g} of its own peak is above the {preset} "
              f"preset's bound {bound:g}", file=sys.stderr)
    return EXIT_ACCURACY if flags else EXIT_OK


def _cmd_compare(args) -> int:
    from .study.comparison import compare
    sc = scene_from_args(args)
    solvers = [s.strip() for s in args.solvers.split(",") if s.strip()]
    if not solvers:
        raise InputError("--solvers names no solver: use spice, ode, exact and/or reference")
    if args.no_plot and args.plot:
        raise InputError("--plot and --no-plot contradict each other")
    # Output paths are checked before any work, so nothing computed is lost to a typo.
    if args.plot:
        check_plot_path(args.plot)
    for path in (args.csv, args.plot):
        _check_writable(path)
    step = None if args.step is None else parse_number(args.step)
    preset = get_preset(args.preset)
    if args.timeout is not None:
        if not (limit := parse_number(args.timeout)) > 0:
            raise InputError(f"--timeout must be positive, got {args.timeout}")
        preset = replace(preset, timeout=limit)
    if args.budget is not None:
        if not (budget := parse_number(args.budget)) >= 1:
            raise InputError(f"--budget must be at least 1, got {args.budget}")
        preset = replace(preset, work_budget=budget, segment_budget=int(min(budget, 2 ** 62)))
    if args.dynamics == "both":
        return _compare_both(sc, args, solvers, step)
    result = compare(sc.system(), preset, solvers, step=step)
    print(result.table())
    return _written_and_judged(result, result, args)


def _compare_both(sc, args, solvers, step) -> int:
    """The nonlinear motion against the circuit linearised at q0: how long the linear one holds."""
    from .study.horizon import linear_horizon
    horizon = linear_horizon(sc, args.preset, solvers, step)
    if horizon is None:
        print("analogy: simulation failed: the reference of the nonlinear motion did not run", file=sys.stderr)
        return EXIT_FAILED
    print(horizon.nonlinear.table())
    print("\n".join(horizon.lines()))
    return _written_and_judged(horizon, horizon.nonlinear, args)


def _written_and_judged(output, result, args) -> int:
    """Write --csv and --plot of *output* (even when a solver failed), then the exit code of *result*."""
    try:
        if args.csv:
            output.to_csv(args.csv)
            print(f"wrote {args.csv}")
        if args.plot:
            output.plot(args.plot)
            print(f"wrote {args.plot}")
    except OSError as exc:
        raise InputError(f"cannot write output: {exc}") from None
    return EXIT_FAILED if result.failures else _accuracy_exit(result.outside_bound(), result.preset, result.bound,
                                                                 result)


def _cmd_modes(args) -> int:
    from .results.modes import natural_modes
    sc = scene_from_args(args)
    _check_writable(args.csv)
    locked = [item.strip() for item in (args.locked or "").split(",") if item.strip()]
    if bad := [item for item in locked if not item.isdigit()]:
        raise InputError(f"--locked needs joint numbers like 1,2, got {bad[0]!r}")
    result = natural_modes(sc.system().joint, [int(x) for x in locked])
    print(result.table())
    if args.csv:
        try:
            result.to_csv(args.csv)
        except OSError as exc:
            raise InputError(f"cannot write {args.csv}: {exc.strerror}") from None
        print(f"wrote {args.csv}")
    return EXIT_OK


def _cmd_verify(args) -> int:
    import numpy as np

    from .study.comparison import compare
    from .results.metrics import relative_error
    from .solvers.exact import solve_exact
    from .solvers.reference import solve_reference
    names = list(SCENES) if args.scenes is None else [s.strip() for s in args.scenes.split(",") if s.strip()]
    systems = {name: scene(name).system() for name in names}      # every name checked before any work
    if not names:
        raise InputError("--scenes names no scene: see 'analogy scenes'")
    print(f"{'scene':<10}{'dof':>4}{'spice/peak':>13}{'ode/peak':>11}{'exact vs mpmath':>17}"
          f"{'spice [ms]':>12}")
    code, flags = EXIT_OK, {}
    for name in names:
        system = systems[name]
        c = compare(system, args.preset)
        probe = np.linspace(0, system.t_stop, 9)
        mp_err = relative_error(solve_exact(system, probe).voltages, solve_reference(system, probe))
        errs = c.errors()
        sp_err = errs.get("spice", (np.nan, np.nan))[1]
        od_err = errs.get("ode", (np.nan, np.nan))[1]
        sp_ms = c.results["spice"].run_time * 1e3 if "spice" in c.results else np.nan
        print(f"{name:<10}{system.dof:>4}{sp_err:>13.2e}{od_err:>11.2e}{mp_err:>17.2e}{sp_ms:>12.1f}",
              flush=True)       # each scene's row as it is done, in a log too
        for solver, reason in c.failures.items():
            print(f"  {solver} failed: {reason}")
        if c.failures:
            code = EXIT_FAILED
        flags.update({f"{name} {k}": v for k, v in c.outside_bound().items()})
    if code:
        return code
    return _accuracy_exit(flags, args.preset, PRESETS[args.preset].bound)


def _cmd_draw(args) -> int:
    from .circuit.diagram import draw
    sc = scene_from_args(args)
    out = Path(args.output_dir)
    built_in = SCENES.get(sc.name)
    stem = args.stem or (sc.name if built_in is not None and built_in.key == sc.key
                         else f"{sc.name}-{sc.key[:8]}")
    if Path(stem).name != stem or stem in (".", ".."):
        raise InputError(f"--stem {stem!r} must be a plain file name (the folder is -o)")
    system = sc.system()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {out}: {exc.strerror}") from None
    _check_writable(out / stem)
    from .circuit.description import circuit
    from .circuit.diagram import MAX_SCHEMATIC_FLOATING, MAX_SCHEMATIC_NODES, schematic_fits
    if not args.schematic and not schematic_fits(system):
        floating = sum(1 for e in circuit(system).elements if e.b)
        print(f"analogy: note: {system.dof} nodes and {floating} floating elements are past what a schematic "
              f"keeps readable ({MAX_SCHEMATIC_NODES} nodes, {MAX_SCHEMATIC_FLOATING} floating elements), so "
              "the element values are drawn as a map by node pair (--schematic draws it anyway)", file=sys.stderr)
    for path in draw(system, out, stem, schematic=True if args.schematic else None):
        print(f"wrote {path}")
    return EXIT_OK


def _solver_list(text: str | None) -> tuple[str, ...] | None:
    if text is None:
        return None
    from .solvers.registry import SOLVER_NAMES
    names = tuple(dict.fromkeys(s.strip() for s in text.split(",") if s.strip()))
    if not names or (bad := [s for s in names if s not in SOLVER_NAMES]):
        raise InputError(f"--solvers: unknown solver {bad[0]!r}" if names else "--solvers names no solver")
    return names


def _cmd_run(args) -> int:
    from .scenes.run import run_scene
    from .scenes.toml import load_scene, validated
    solvers = _solver_list(args.solvers)
    jobs = []
    for path in args.scene_files:           # every file is read and checked before any work
        job = load_scene(path)
        changes = {k: v for k, v in (("dynamics", args.dynamics), ("preset", args.preset),
                                      ("solvers", solvers)) if v is not None and v != getattr(job, k)}
        if changes:
            job = validated(job.replace(**changes))
        jobs.append(job.replace(plot_file=None) if args.no_plot else job)
    codes = []
    for job in jobs:
        if len(jobs) > 1:
            print(f"== {job.source}")
        result = run_scene(job, args.output_dir)
        print(result.table())
        if job.netlist and not job.netlist_file:
            sys.stdout.write(result.netlist)
        for written in result.written:
            print(f"wrote {written}")
        if result.failures:
            codes.append(EXIT_FAILED)
        elif result.comparison is not None:
            codes.append(_accuracy_exit(result.comparison.outside_bound(), job.preset,
                                        PRESETS[job.preset].bound))
    return EXIT_FAILED if EXIT_FAILED in codes else max(codes, default=EXIT_OK)


def _cmd_batch(args) -> int:
    from .batch.cli import batch_command
    return batch_command(args)


def _positive(value: int, what: str) -> int:
    if value < 1:
        raise InputError(f"{what} must be at least 1")
    return value


def _cmd_bench(args) -> int:
    from .bench import bench
    check_plot_path(args.plot)
    _check_writable(args.csv)
    _check_writable(args.plot)
    result = bench(repeats=_positive(args.repeats, "--repeats"), full=args.full,
                   progress=not args.no_progress, quick=args.quick)
    print(result.table())
    result.to_csv(args.csv)
    result.plot(args.plot)
    print(f"wrote {args.csv} and {args.plot}")
    return EXIT_OK


def _cmd_stress(args) -> int:
    from .stress import stress, write_report
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError(f"cannot write into {out}: it is a file")
    if not args.timeout > 0:
        raise InputError(f"--timeout must be positive, got {args.timeout:g}")
    families = args.families.strip().lower()
    report = stress(families, quick=args.quick, timeout=args.timeout,
                    progress=not args.no_progress)
    try:
        out.mkdir(parents=True, exist_ok=True)
        written = write_report(report, out)
    except OSError as exc:
        raise InputError(f"cannot write the stress report: {exc}") from None
    print(report.summary())
    print("wrote " + ", ".join(str(p) for p in written))
    return EXIT_OK


def _cmd_throughput(args) -> int:
    if args.sweep is not None:
        from .batch.benchmark import store_throughput
        from .batch.sweep import load_sweep
        if args.output is None:
            raise InputError("--sweep needs the results folder -o DIR")
        print(store_throughput(load_sweep(args.sweep), args.output, sample=_positive(args.baseline, "--baseline"),
                               workers=_positive(args.workers, "--workers")))
        return EXIT_OK
    from .throughput import throughput
    print(throughput(n=_positive(args.n, "-n"), preset=args.preset,
                     group_size=_positive(args.group_size, "--group-size"),
                     workers=_positive(args.workers, "--workers"),
                     baseline_n=_positive(args.baseline, "--baseline"),
                     repeats=_positive(args.repeats, "--repeats"), progress=not args.no_progress))
    return EXIT_OK


def _cmd_memory(args) -> int:
    from .memory import memory_per_run
    scene(args.scene)                   # an unknown name is refused before any run
    print(memory_per_run(_positive(args.runs, "--runs"), args.preset, args.scene))
    return EXIT_OK


def _cmd_ac(args) -> int:
    from .study.mobility import mobility_check
    sc = scene_from_args(args)
    _check_writable(args.csv)
    plot = check_plot_path(args.plot) if args.plot else None
    check = mobility_check(sc.system(), args.f_start, args.f_stop, args.points)
    print(check.report)
    if args.csv:
        print(f"wrote {check.spice.to_csv(args.csv)}")
    if plot is not None:
        check.spice.plot(plot, check.exact)
        print(f"wrote {plot}")
    bound = PRESETS[args.preset].bound
    return _accuracy_exit({"spice mobility": check.error} if check.error > bound else {}, args.preset, bound)


def _cmd_scenes(args) -> int:
    for name, sc in SCENES.items():
        print(f"{name:<10} {sc.description}")
    return EXIT_OK


_COMMANDS = {"netlist": _cmd_netlist, "compare": _cmd_compare, "verify": _cmd_verify, "modes": _cmd_modes, "ac": _cmd_ac,
             "scenes": _cmd_scenes, "draw": _cmd_draw, "run": _cmd_run, "bench": _cmd_bench,
             "throughput": _cmd_throughput, "stress": _cmd_stress, "batch": _cmd_batch, "memory": _cmd_memory}


def main(argv=None) -> int:
    """Entry point of the ``analogy`` command; returns the exit code.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default ``sys.argv[1:]``).
    """
    parser = build_parser()
    caught: dict[str, int] = {}
    try:
        with warnings.catch_warnings():
            # numpy's and scipy's warnings are counted here, and said in one sentence below
            warnings.simplefilter("default")
            warnings.showwarning = lambda message, category, *rest, **kw: caught.__setitem__(
                f"{category.__name__}: {message}", caught.get(f"{category.__name__}: {message}", 0) + 1)
            args = parser.parse_args(argv)
            if args.command is None:
                args = parser.parse_args(["compare"])
            code = _COMMANDS[args.command](args)
        if caught:
            first = " ".join(next(iter(caught)).split())
            print(f"analogy: warning: the numerics gave {sum(caught.values())} warning(s) during the run, "
                  f"first {first!r}: check the result", file=sys.stderr)
        return code
    except InputError as exc:
        print(f"analogy: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except AccuracyError as exc:
        print(f"analogy: accuracy: {exc}", file=sys.stderr)
        return EXIT_ACCURACY
    except SimulationError as exc:
        print(f"analogy: simulation failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except AnalogyError as exc:
        print(f"analogy: error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("analogy: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenExecutor as exc:       # a worker process died (killed, or out of memory)
        print(f"analogy: simulation failed: a worker process died ({exc or type(exc).__name__})", file=sys.stderr)
        return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
