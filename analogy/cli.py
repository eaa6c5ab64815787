"""Command-line interface: a thin layer over the analogy API."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import AnalogyError, InputError, SimulationError

__all__ = ["main", "build_parser"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit 2) instead of a usage dump."""

    def error(self, message):
        raise InputError(f"{message} (see {self.prog} --help)")


def _scene_options(p: argparse.ArgumentParser):
    g = p.add_argument_group("scene (defaults: the built-in default scene)")
    g.add_argument("--scene", default="default", help="built-in scene to start from (see 'analogy scenes')")
    g.add_argument("--robot", help="built-in robot: redundant, serial2, parallel2, serial3, parallel3, serialN")
    g.add_argument("--mass", metavar="MATRIX", help="mass matrix, e.g. '[[m1, m3], [m3, m2]]'; "
                   "may use --param names and q1..qn")
    g.add_argument("--damping", metavar="VECTOR|MATRIX", help="damping: diagonal '[b1, b2]' or a matrix")
    g.add_argument("--stiffness", metavar="VECTOR|MATRIX", help="stiffness: diagonal or a matrix")
    g.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="parameter value (repeatable), e.g. l1=0.5 or q2=pi/4")
    g.add_argument("--q", metavar="VALUES", help="configuration, e.g. '0, 0.3'")
    g.add_argument("--topology", metavar="serial|parallel|MATRIX",
                   help="joint-to-node map: serial, parallel or a matrix T with v = T r")
    g.add_argument("--force", action="append", metavar="SPEC",
                   help="force on the next joint (repeat once per joint): a number, step(a), "
                        "step(a, delay, rise), pulse(v1, v2, delay, rise, fall, width, period), "
                        "sine(offset, amplitude, freq), pwl(t1, v1, t2, v2, ...)")
    g.add_argument("--r0", metavar="VALUES", help="initial joint rates, e.g. '0, 0'")
    g.add_argument("--t-stop", metavar="SECONDS", help="end time of the simulation")
    p.add_argument("--preset", default="accurate", help="accuracy preset: fast or accurate (default)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="analogy",
                     description="Robot dynamics as electric circuits: netlists, SPICE and checks.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    p = sub.add_parser("netlist", help="write the equivalent-circuit SPICE netlist")
    _scene_options(p)
    p.add_argument("-o", "--output", help="file to write (default: stdout)")
    p.add_argument("--save", metavar="NODES", help="nodes to save, e.g. 'n1, n2' (default: all)")
    p.add_argument("--realizable", action="store_true",
                   help="no negative values: negative elements behind 1:-1 couplings")
    p = sub.add_parser("compare", help="run SPICE, ODE and exact solvers and compare them")
    _scene_options(p)
    p.add_argument("--solvers", default="spice,ode,exact", help="comma-separated: spice, ode, exact")
    p.add_argument("--csv", metavar="FILE", help="write joint rates of every solver to CSV")
    p.add_argument("--plot", metavar="FILE.png", help="write a plot of rates and errors")
    p.add_argument("--no-plot", action="store_true", help="never import the plotting library")
    p = sub.add_parser("verify", help="check every built-in example: SPICE and ODE against exact, "
                                      "exact against a 40-digit mpmath solution")
    p.add_argument("--preset", default="accurate")
    p.add_argument("--scenes", default=None, help="comma-separated scene names (default: all)")
    sub.add_parser("scenes", help="list the built-in scenes")
    p = sub.add_parser("draw", help="draw the equivalent circuit and the mechanical system (SVG and PNG)")
    _scene_options(p)
    p.add_argument("-o", "--output-dir", default=".", help="folder for the drawings (default: .)")
    p.add_argument("--stem", help="file name stem (default: the scene name)")
    p = sub.add_parser("run", help="run a scene file (TOML): exactly what it asks for")
    p.add_argument("scene_file", help="path to a .toml scene")
    p.add_argument("--output-dir", help="folder for the scene's output files (default: next to it)")
    p.add_argument("--no-plot", action="store_true", help="skip plots even if the scene asks for one")
    p = sub.add_parser("bench", help="run time against error: ngspice settings, ODE methods, exact solver")
    p.add_argument("--repeats", type=int, default=5, help="timed runs per setting (median; default 5)")
    p.add_argument("--full", action="store_true", help="the full ngspice grid (method x reltol x trtol x max step)")
    p.add_argument("--csv", default="bench.csv", help="CSV output (default: bench.csv)")
    p.add_argument("--plot", default="bench.png", help="work-precision plot (default: bench.png)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p = sub.add_parser("throughput", help="scenes per second: batched ngspice runs against per-scene loops")
    p.add_argument("-n", type=int, default=10_000, help="number of 2-DOF scenes (default 10000)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--group-size", type=int, default=100, help="scenes per ngspice run (default 100)")
    p.add_argument("--baseline", type=int, default=500, help="scenes for the per-scene loops (default 500)")
    p.add_argument("--repeats", type=int, default=3, help="turns of every path; medians are reported (default 3)")
    p.add_argument("--preset", default="fast")
    return parser


def _split_param(text: str):
    name, sep, value = text.partition("=")
    if not sep or not name.strip().isidentifier():
        raise InputError(f"--param needs NAME=VALUE, got {text!r}")
    from .expressions import parse_number
    return name.strip(), parse_number(value)


def _numbers(text: str, what: str) -> list[float]:
    from .expressions import parse_vector
    return parse_vector(text, numeric=True)


def _numeric_matrix(text: str | None, n: int, what: str, diagonal: bool = True):
    """A numeric matrix, or (if *diagonal*) a diagonal from a vector; None if *text* uses names."""
    import numpy as np

    from .expressions import parse_matrix, parse_vector
    if text is None:
        return None
    try:
        if text.strip().startswith("[[") or not diagonal:
            return np.array(parse_matrix(text, numeric=True))
        return np.diag(parse_vector(text, numeric=True))
    except InputError as exc:
        if "unknown name" in str(exc):
            return None
        raise


def _matrix_or_diagonal(text: str, symbols, what: str):
    from .expressions import parse_matrix, parse_vector
    if text.strip().startswith("[["):
        return parse_matrix(text, symbols)
    return parse_vector(text, symbols)


def scene_from_args(args):
    """Build (model, scene) from the CLI options; model None means the scene's own."""
    from .scenes import scene
    from .topology import TOPOLOGIES

    from .scenes import SCENES
    # A robot with a scene of its own starts from that scene (a configuration that assembles).
    start = args.robot if args.robot in SCENES and args.scene == "default" else args.scene
    sc = scene(start)
    params = dict(_split_param(p) for p in args.param)
    changes = {}
    if args.mass is not None:
        import numpy as np

        from .expressions import parse_matrix
        from .model import JointSpace
        mass = _numeric_matrix(args.mass, 0, "--mass", diagonal=False)
        if mass is not None and not params:
            # A numeric matrix needs no symbolic work at all.
            n = mass.shape[0] if mass.ndim == 2 else 0
            damping = _numeric_matrix(args.damping, n, "--damping")
            stiffness = _numeric_matrix(args.stiffness, n, "--stiffness")
            if (args.damping and damping is None) or (args.stiffness and stiffness is None):
                raise InputError("--damping and --stiffness may use names only with a symbolic --mass and --param")
            model = JointSpace(mass, np.zeros_like(mass) if damping is None else damping, stiffness)
            changes.update(parameters={}, q=(), initial_rates=None)
            if not args.force:
                changes["forces"] = tuple(1.0 for _ in range(n))
        else:
            import sympy as sp

            from .model import Model
            probe = parse_matrix(args.mass, None)   # names only; checked again below
            n = probe.rows
            qs = [sp.Symbol(f"q{k + 1}", real=True) for k in range(n)]
            names = {str(x) for x in probe.free_symbols} - {str(q) for q in qs}
            missing = sorted(names - set(params))
            if missing:
                raise InputError(f"--mass uses {', '.join(missing)} with no value: add --param NAME=VALUE")
            used = set(names)
            for text in (args.damping, args.stiffness):
                if text:
                    value = _matrix_or_diagonal(text, None, "")
                    items = value if isinstance(value, list) else [value]
                    used |= {str(x) for item in items for x in getattr(item, "free_symbols", ())}
            unused = sorted(set(params) - used)
            if unused:
                raise InputError(f"--param {unused[0]} is not used by --mass, --damping or --stiffness")
            symbols = {k: sp.Symbol(k, real=True) for k in params}
            symbols.update({str(q): q for q in qs})
            mass = parse_matrix(args.mass, symbols)
            damping = _matrix_or_diagonal(args.damping, symbols, "--damping") if args.damping else None
            stiffness = _matrix_or_diagonal(args.stiffness, symbols, "--stiffness") if args.stiffness else None
            used_q = [q for q in qs if q in mass.free_symbols]
            model = Model("custom", mass, damping=damping, stiffness=stiffness,
                          parameters=params, coordinates=qs if used_q else (), topology="parallel")
            changes.update(parameters={}, q=tuple(0.0 for _ in qs) if used_q else ())
            if not args.force:
                changes["forces"] = tuple(1.0 for _ in range(n))
            changes["initial_rates"] = None
    else:
        if args.damping or args.stiffness:
            raise InputError("--damping and --stiffness need --mass (built-in robots have their own)")
        model = None                 # the scene's own, compiled once and cached on disk
        if args.robot is not None and args.robot != sc.model:
            from .robots import robot
            robot(args.robot)        # fails early, with one line, on an unknown name
            changes["model"] = args.robot
            m = sc.replace(model=args.robot).numeric_model()
            n = m.dof
            changes.update(q=tuple(0.0 for _ in m.coordinates), parameters={},
                           forces=tuple(1.0 for _ in range(n)), initial_rates=None)
        if params:
            changes["parameters"] = params
    if args.q is not None:
        changes["q"] = tuple(_numbers(args.q, "--q"))
    if args.topology is not None:
        t = args.topology.strip()
        if t in TOPOLOGIES:
            changes["topology"] = t
        elif t.startswith("["):
            from .expressions import parse_matrix
            changes["topology"] = parse_matrix(t, numeric=True)
        else:
            raise InputError(f"unknown topology {t!r}: use serial, parallel or a matrix like [[1, 0], [1, 1]]")
    if args.force:
        changes["forces"] = tuple(args.force)
    if args.r0 is not None:
        changes["initial_rates"] = tuple(_numbers(args.r0, "--r0"))
    if args.t_stop is not None:
        from .expressions import parse_number
        changes["t_stop"] = parse_number(args.t_stop)
    sc = sc.replace(**changes)
    return model, sc


def _cmd_netlist(args) -> int:
    from .netlist import netlist
    model, sc = scene_from_args(args)
    system = sc.system(model)
    save = None if args.save is None else [s.strip() for s in args.save.split(",") if s.strip()]
    text = netlist(system, args.preset, save=save, realizable=args.realizable,
                   title=f"analogy {sc.name}: {sc.description}" if sc.description else None)
    if args.output:
        try:
            Path(args.output).write_text(text)
        except OSError as exc:
            raise InputError(f"cannot write {args.output}: {exc.strerror}") from None
    else:
        sys.stdout.write(text)
    return EXIT_OK


def _cmd_compare(args) -> int:
    from .compare import compare
    model, sc = scene_from_args(args)
    system = sc.system(model)
    solvers = [s.strip() for s in args.solvers.split(",") if s.strip()]
    if not solvers:
        raise InputError("--solvers names no solver: use spice, ode and/or exact")
    if args.no_plot and args.plot:
        raise InputError("--plot and --no-plot contradict each other")
    # Output paths are checked before any work, so nothing computed is lost to a typo.
    if args.plot:
        from .compare import check_plot_path
        check_plot_path(args.plot)
    for path in (args.csv, args.plot):
        _check_writable(path)
    result = compare(system, args.preset, solvers)
    print(result.table())
    # Results already computed are written even when a solver failed.
    try:
        if args.csv:
            result.to_csv(args.csv)
            print(f"wrote {args.csv}")
        if args.plot:
            result.plot(args.plot)
            print(f"wrote {args.plot}")
    except OSError as exc:
        raise InputError(f"cannot write output: {exc}") from None
    return EXIT_FAILED if result.failures else EXIT_OK


def _cmd_verify(args) -> int:
    import numpy as np

    from .compare import compare
    from .reference import solve_reference
    from .scenes import SCENES, scene

    names = list(SCENES) if args.scenes is None else [s.strip() for s in args.scenes.split(",")]
    print(f"{'scene':<10}{'dof':>4}{'spice/peak':>13}{'ode/peak':>11}{'exact vs mpmath':>17}"
          f"{'spice [ms]':>12}")
    worst = 0
    for name in names:
        sc = scene(name)
        system = sc.system()
        c = compare(system, args.preset)
        probe = np.linspace(0, system.t_stop, 9)
        from .exact import solve_exact
        ref = solve_reference(system, probe)
        ex = solve_exact(system, probe).voltages
        mp_err = float(np.max(np.abs(ex - ref)) / np.max(np.abs(ref)))
        errs = c.errors()
        sp_err = errs.get("spice", (np.nan, np.nan))[1]
        od_err = errs.get("ode", (np.nan, np.nan))[1]
        sp_ms = c.results["spice"].run_time * 1e3 if "spice" in c.results else np.nan
        print(f"{name:<10}{system.dof:>4}{sp_err:>13.2e}{od_err:>11.2e}{mp_err:>17.2e}{sp_ms:>12.1f}")
        for solver, reason in c.failures.items():
            print(f"  {solver} failed: {reason}")
        if c.failures:
            worst = EXIT_FAILED
    return worst


def _cmd_draw(args) -> int:
    from .diagram import draw
    model, sc = scene_from_args(args)
    system = sc.system(model)
    out = Path(args.output_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {out}: {exc.strerror}") from None
    stem = args.stem or sc.name
    if Path(stem).name != stem or stem in (".", ".."):
        raise InputError(f"--stem {stem!r} must be a plain file name (the folder is -o)")
    for path in draw(system, out, stem):
        print(f"wrote {path}")
    return EXIT_OK


def _cmd_run(args) -> int:
    from .scenefile import load_scene, run_scene
    job = load_scene(args.scene_file)
    if args.no_plot:
        job = job.replace(plot_file=None)
    result = run_scene(job, args.output_dir)
    print(result.table())
    if job.netlist and not job.netlist_file:
        sys.stdout.write(result.netlist)
    for written in result.written:
        print(f"wrote {written}")
    return EXIT_FAILED if result.failures else EXIT_OK


def _positive(value: int, what: str) -> int:
    if value < 1:
        raise InputError(f"{what} must be at least 1")
    return value


def _check_writable(path):
    import os
    if path is None:
        return
    folder = Path(path).resolve().parent
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise InputError(f"cannot write {path}: folder {folder} does not exist or is not writable")


def _cmd_bench(args) -> int:
    from .bench import bench
    from .compare import check_plot_path
    check_plot_path(args.plot)
    _check_writable(args.csv)
    _check_writable(args.plot)
    result = bench(repeats=_positive(args.repeats, "--repeats"), full=args.full,
                   progress=not args.no_progress)
    print(result.table())
    result.to_csv(args.csv)
    result.plot(args.plot)
    print(f"wrote {args.csv} and {args.plot}")
    return EXIT_OK


def _cmd_throughput(args) -> int:
    from .bench import throughput
    print(throughput(n=_positive(args.n, "-n"), preset=args.preset,
                     group_size=_positive(args.group_size, "--group-size"),
                     workers=_positive(args.workers, "--workers"),
                     baseline_n=_positive(args.baseline, "--baseline"),
                     repeats=_positive(args.repeats, "--repeats")))
    return EXIT_OK


def _cmd_scenes(args) -> int:
    from .scenes import SCENES
    for name, sc in SCENES.items():
        print(f"{name:<10} {sc.description}")
    return EXIT_OK


def main(argv=None) -> int:
    """Entry point of the ``analogy`` command; returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        command = args.command or "compare"
        if args.command is None:
            args = parser.parse_args(["compare"])
        handler = {"netlist": _cmd_netlist, "compare": _cmd_compare, "verify": _cmd_verify,
                   "scenes": _cmd_scenes, "draw": _cmd_draw, "run": _cmd_run, "bench": _cmd_bench,
                   "throughput": _cmd_throughput}[command]
        return handler(args)
    except InputError as exc:
        print(f"analogy: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except SimulationError as exc:
        print(f"analogy: simulation failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except AnalogyError as exc:
        print(f"analogy: error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("analogy: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
