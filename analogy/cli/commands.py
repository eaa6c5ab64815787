"""The commands of the command line: each one's work over the analogy API, its printing and its exit code.

Each command imports the modules it uses when it runs, so that ``analogy netlist``
starts without the solvers, the batch machinery or the benchmarks.
"""

from __future__ import annotations

import signal
import sys
import threading
import warnings
from concurrent.futures import BrokenExecutor
from dataclasses import replace
from pathlib import Path

from ..circuit.description import circuit
from ..circuit.netlist import coupled_nodes, gnucap_size_note
from ..circuit.topology import DENSE_NODE_LIMIT
from ..files import write_text
from ..solvers.transient import netlist, subcircuit_netlist
from ..heap import retain_freed_memory
from ..errors import EXIT_ACCURACY, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE
from ..errors import AccuracyError, AnalogyError, InputError, SimulationError, one_line
from ..model.expressions import (
    parse_number,
)
from ..processes import stop_requests
from ..progress import Heartbeat
from ..results.output import check_plot_path
from .diagnostics import bench_command, memory_command, stress_command, throughput_command
from .outputs import accuracy_exit, check_writable, write_outputs
from .parser import build_parser
from .scene_options import built_system, scene_from_args, solver_list
from ..model.catalog import URDF_NAMES
from ..scenes.builtin import SCENES, scene
from ..scenes.scene import Scene

__all__ = ["EXIT_ACCURACY", "EXIT_FAILED", "EXIT_OK", "EXIT_USAGE", "build_parser", "main", "scene_from_args"]


def _title(sc: Scene) -> str:
    return f"analogy {sc.name}: {sc.description}" if sc.description else f"analogy {sc.name}"


def _say_pose(system, sc: Scene) -> None:
    """One line before a linear run at an unstable pose (:func:`unstable_note`), and the pose's own notes."""
    for note in system.provenance.notes:
        print(f"analogy: warning: {note}", file=sys.stderr)
    if sc.topology is None and system.topology.name == "modal":
        print(f"analogy: note: written on the modal map, one node per mode: past {DENSE_NODE_LIMIT} joints a "
              "dense circuit costs SPICE more than its modes (--topology names another)", file=sys.stderr)
    if not getattr(getattr(system, "joint", None), "unstable", False):
        return                  # the usual case, without importing scipy for the note
    from ..scenes.robot_defaults import unstable_note
    if (note := unstable_note(system, sc)) is not None:
        print(f"analogy: warning: {note}", file=sys.stderr)


def _cmd_netlist(args) -> int:
    sc = scene_from_args(args)
    if args.realizable and sc.dynamics != "linear":
        raise InputError("--realizable applies to the linear circuit, not to --dynamics nonlinear")
    check_writable(args.output)
    if args.format == "ltspice" and args.output:
        if Path(args.output).suffix.lower() == ".asc":
            raise InputError("-o names the LTspice netlist (.cir, .net); its schematic is written beside it as .asc")
        check_writable(str(Path(args.output).with_suffix(".asc")))
    save = None if args.save is None else [s.strip() for s in args.save.split(",") if s.strip()]
    system = built_system(sc, args.realizable)      # as compare --realizable does
    _say_pose(system, sc)
    if args.subckt is not None:
        if args.format != "ngspice" or save is not None:
            raise InputError(f"--subckt writes a subcircuit for ngspice that saves nothing: "
                             f"{'--save' if save is not None else '--format ' + args.format} does not apply to it")
        text = subcircuit_netlist(system, args.preset, name=args.subckt or None, title=_title(sc))
    else:
        dialect = "ngspice" if args.format == "kicad" else args.format
        text = netlist(system, args.preset, save=save, title=_title(sc), dialect=dialect)
        if dialect == "gnucap" and (note := gnucap_size_note(system.dof, coupled_nodes(circuit(system)))):
            print(f"analogy: warning: {note}", file=sys.stderr)
    files = {args.output: text} if args.output else {}
    if args.format == "kicad":
        from ..circuit.kicad import kicad_schematic
        text = kicad_schematic(text, Path(args.output).stem if args.output else sc.name)
        files = {args.output: text} if args.output else {}
    elif args.format == "ltspice" and args.output:
        from ..circuit.ltspice import ltspice_schematic
        files[str(Path(args.output).with_suffix(".asc"))] = ltspice_schematic(text)
    for path, content in files.items():
        try:
            write_text(path, content)
        except OSError as exc:
            raise InputError(f"cannot write {path}: {exc.strerror}") from None
    if not files:
        sys.stdout.write(text)
    return EXIT_OK


def _cmd_compare(args) -> int:
    from ..study.comparison import compare
    if args.motors or args.voltage:
        if not args.motors:
            raise InputError("--voltage drives motors: give them with --motors FILE")
        from .show import drive_command
        return drive_command(args)
    sc = scene_from_args(args)
    solvers = [s.strip() for s in args.solvers.split(",") if s.strip()]
    if not solvers:
        raise InputError("--solvers names no solver: use spice, gnucap, ode, exact and/or reference")
    if args.no_plot and args.plot:
        raise InputError("--plot and --no-plot contradict each other")
    if getattr(args, "csv_all", False) and not args.csv:
        raise InputError("--csv-all says how much of the CSV to write: give the file with --csv FILE")
    # Output paths are checked before any work, so nothing computed is lost to a typo.
    if args.plot:
        check_plot_path(args.plot)
    for path in (args.csv, args.plot):
        check_writable(path)
    step = None if args.step is None else parse_number(args.step, "time")
    preset = args.preset
    if args.timeout is not None:
        if not (limit := parse_number(args.timeout, "time")) > 0:
            raise InputError(f"--timeout must be positive, got {args.timeout}")
        preset = replace(preset, budget=replace(preset.budget, timeout=limit))
    if args.budget is not None:
        if not (budget := parse_number(args.budget)) >= 1:
            raise InputError(f"--budget must be at least 1, got {args.budget}")
        # one knob: the operation budget scales with the points'
        preset = replace(preset, budget=replace(preset.budget, points=budget, segments=int(min(budget, 2 ** 62)),
                                                operations=preset.budget.operations * budget / preset.budget.points))
    if args.realizable and (args.dynamics == "both" or sc.dynamics != "linear"):
        raise InputError("--realizable applies to the linear circuit, not to --dynamics nonlinear or both")
    if args.dynamics == "both":
        if args.estimate or args.refine or args.no_reference:
            raise InputError("--dynamics both measures the linear circuit against the nonlinear reference: "
                             "--estimate, --refine and --no-reference apply to one dynamics")
        return _compare_both(sc, args, solvers, step)
    system = built_system(sc, args.realizable)
    _say_pose(system, sc)
    reference = None if args.no_reference else "auto"
    result = compare(system, preset, solvers, step=step, progress=Heartbeat(), reference=reference,
                     estimate=args.estimate, refine=args.refine)
    print(result.table())
    if system.kind == "nonlinear":
        from ..study.predictability import predictability
        if (sensitivity := predictability(system, preset, result.results.get("ode"))).chaotic:
            print(f"analogy: {sensitivity.line()}", file=sys.stderr)
    return _written_and_judged(result, result, args)


def _compare_both(sc, args, solvers, step) -> int:
    """The nonlinear motion against the circuit linearised at q0: how long the linear one holds."""
    from ..study.horizon import linear_horizon
    horizon = linear_horizon(sc, args.preset, solvers, step)
    if horizon is None:
        print("analogy: simulation failed: the reference of the nonlinear motion did not run", file=sys.stderr)
        return EXIT_FAILED
    print(horizon.nonlinear.table())
    print("\n".join(horizon.lines()))
    return _written_and_judged(horizon, horizon.nonlinear, args)


#: Rows of a CSV past which the command says how many, and how large, before writing.
CSV_ROWS = 100_000


def _written_and_judged(output, result, args) -> int:
    """Write --csv and --plot of *output* (even when a solver failed), then the exit code of *result*."""
    every = 1
    if args.csv:
        cols = output.columns()
        rows = len(next(iter(cols.values())))
        if rows > CSV_ROWS:         # said before the time and disk go, with the other way
            size = f"about {rows * len(cols) * 20 / 1e6:,.0f} MB"
            if getattr(args, "step", None) is None and not getattr(args, "csv_all", False):
                every = -(-rows // CSV_ROWS)
                print(f"analogy: {args.csv} holds one in every {every} of the {rows:,} time points, as computed "
                      f"({-(-rows // every) + 1:,} rows at most); --csv-all writes them all ({size})",
                      file=sys.stderr)
            else:
                span = float(output.time[-1]) if getattr(output, "time", None) is not None else 0.0
                print(f"analogy: writing {rows:,} rows to {args.csv} ({size}); --step {span / 10_000:.3g} "
                      "writes 10,001", file=sys.stderr)
    write_outputs([(args.csv, lambda: output.to_csv(args.csv, every=every)),
                   (args.plot, lambda: output.plot(args.plot))])
    return EXIT_FAILED if result.failures else accuracy_exit(result.outside_bound(), result.preset, result.bound,
                                                                 result)


def _cmd_modes(args) -> int:
    from ..results.modes import natural_modes
    sc = scene_from_args(args)
    check_writable(args.csv)
    locked = [item.strip() for item in (args.locked or "").split(",") if item.strip()]
    if bad := [item for item in locked if not item.isdigit()]:
        raise InputError(f"--locked needs joint numbers like 1,2, got {bad[0]!r}")
    system = built_system(sc)
    result = natural_modes(system.joint, [int(x) for x in locked], system.provenance.joints)
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

    from ..study.comparison import compare
    from ..results.metrics import relative_error
    from ..solvers.exact import solve_exact
    from ..solvers.reference import solve_reference
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
        mp_err = relative_error(solve_exact(system, probe).voltages, solve_reference(system, probe).voltages)
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
    return accuracy_exit(flags, args.preset.name, args.preset.bound)


def _cmd_draw(args) -> int:
    from ..circuit.diagram import draw
    sc = scene_from_args(args)
    out = Path(args.output_dir)
    built_in = SCENES.get(sc.name)
    stem = args.stem or (sc.name if built_in is not None and built_in.key == sc.key
                         else f"{sc.name}-{sc.key[:8]}")
    if Path(stem).name != stem or stem in (".", ".."):
        raise InputError(f"--stem {stem!r} must be a plain file name (the folder is -o)")
    system = built_system(sc)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {out}: {exc.strerror}") from None
    check_writable(out / stem)
    from ..circuit.description import circuit
    from ..circuit.diagram import MAX_SCHEMATIC_FLOATING, MAX_SCHEMATIC_NODES, schematic_fits
    if not args.schematic and not schematic_fits(system):
        floating = sum(1 for e in circuit(system).elements if e.b)
        # name only the limits this system passes
        past = [f"{count} {what} (more than {limit})" for count, what, limit in
                ((system.dof, "nodes", MAX_SCHEMATIC_NODES), (floating, "floating elements", MAX_SCHEMATIC_FLOATING))
                if count > limit]
        print(f"analogy: note: {' and '.join(past)} are past what a schematic keeps readable, so the element "
              "values are drawn as a map by node pair (--schematic draws it anyway)", file=sys.stderr)
    for path in draw(system, out, stem, schematic=True if args.schematic else None):
        print(f"wrote {path}")
    return EXIT_OK


def _cmd_run(args) -> int:
    from ..scenes.run import run_scene
    from ..scenes.toml import load_scene, validated
    solvers = solver_list(args.solvers)
    jobs = []
    for path in args.scene_files:           # every file is read and checked before any work
        job = load_scene(path)
        changes = {k: v for k, v in (("dynamics", args.dynamics), ("preset", args.preset and args.preset.name),
                                      ("solvers", solvers)) if v is not None and v != getattr(job, k)}
        if changes:
            job = validated(job.replace(**changes))
        jobs.append(job.replace(plot_file=None) if args.no_plot else job)
    codes = []
    for job in jobs:
        if len(jobs) > 1:
            print(f"== {job.source}")
        result = run_scene(job, args.output_dir, progress=Heartbeat())
        print(result.table())
        if job.netlist and not job.netlist_file:
            sys.stdout.write(result.netlist)
        for written in result.written:
            print(f"wrote {written}")
        if result.failures:
            codes.append(EXIT_FAILED)
        elif result.drive is not None:
            from .show import drive_exit
            codes.append(drive_exit(result.drive, job.preset, job.settings.bound))
        elif result.comparison is not None:
            codes.append(accuracy_exit(result.comparison.outside_bound(), job.preset, job.settings.bound,
                                        result.comparison))
    return EXIT_FAILED if EXIT_FAILED in codes else max(codes, default=EXIT_OK)


def _cmd_animate(args) -> int:
    from .show import animate_command
    return animate_command(args)


def _cmd_report(args) -> int:
    from .show import report_command
    return report_command(args)


def _cmd_drive(args) -> int:
    from .show import drive_command
    return drive_command(args)


def _cmd_lab(args) -> int:
    from .show import lab_command
    return lab_command(args)


def _cmd_batch(args) -> int:
    from .batch import batch_command
    return batch_command(args)


def _cmd_check(args) -> int:
    from ..study.netlist_check import netlist_estimate
    try:
        text = Path(args.netlist).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the netlist {args.netlist}: {exc}") from None
    if args.plot:
        check_plot_path(args.plot)
    check_writable(args.csv)
    result = netlist_estimate(text)
    print(result.table())
    write_outputs([(args.csv, lambda: result.to_csv(args.csv)), (args.plot, lambda: result.plot(args.plot))])
    bound = args.preset.bound
    name, worst = result.worst
    return accuracy_exit({f"the netlist's {name}": worst} if worst > bound else {}, args.preset.name, bound)


def _cmd_ac(args) -> int:
    from ..study.mobility import mobility_check
    sc = scene_from_args(args)
    check_writable(args.csv)
    plot = check_plot_path(args.plot) if args.plot else None
    check = mobility_check(built_system(sc), args.f_start, args.f_stop, args.points)
    print(check.report)
    if args.csv:
        print(f"wrote {check.spice.to_csv(args.csv)}")
    if plot is not None:
        check.spice.plot(plot, check.exact)
        print(f"wrote {plot}")
    bound = args.preset.bound
    return accuracy_exit({"spice mobility": check.error} if check.error > bound else {}, args.preset.name, bound)


def _cmd_scenes(args) -> int:
    for name, sc in SCENES.items():
        print(f"{name:<16} {sc.description}")
    for name in URDF_NAMES:            # derived from the file when run: not loaded to be listed
        print(f"{name:<16} {name} from example-robot-data: hanging (or g = 0 where it cannot hang within its "
              "joint limits), steps sized to the robot, a horizon from its modes")
    return EXIT_OK


_COMMANDS = {"netlist": _cmd_netlist, "compare": _cmd_compare, "verify": _cmd_verify, "modes": _cmd_modes, "ac": _cmd_ac,
             "scenes": _cmd_scenes, "draw": _cmd_draw, "run": _cmd_run, "bench": bench_command,
             "throughput": throughput_command, "stress": stress_command, "batch": _cmd_batch,
             "memory": memory_command,
             "check": _cmd_check,
             "animate": _cmd_animate, "report": _cmd_report, "lab": _cmd_lab,
             "drive": _cmd_drive}


#: How the command line changes what an input error concerns, where a flag does.
_HINTS = {"budget": " (--budget N raises it)", "trajectories": " (analogy batch --trajectories N keeps them)"}


def main(argv=None) -> int:
    """Entry point of the ``analogy`` command; returns the exit code.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default ``sys.argv[1:]``).
    """
    parser = build_parser()
    args = None
    caught: dict[str, int] = {}
    # SIGTERM ends a command as Ctrl-C does: every clean-up runs (workers, scratch folders, stores)
    stop_requests.clear()               # before the handler: a request from here on is this command's
    old_term = signal.signal(signal.SIGTERM, _terminate) \
        if threading.current_thread() is threading.main_thread() else None
    try:
        with warnings.catch_warnings():
            # numpy's and scipy's warnings are counted here, and said in one sentence below
            warnings.simplefilter("default")
            warnings.showwarning = lambda message, category, *rest, **kw: caught.__setitem__(
                f"{category.__name__}: {message}", caught.get(f"{category.__name__}: {message}", 0) + 1)
            args = parser.parse_args(argv)
            if args.command is None:
                args = parser.parse_args(["compare"])
            if args.command != "memory":     # which measures what the allocator keeps per run
                retain_freed_memory()        # the command's own process: no host to change it for
            code = _COMMANDS[args.command](args)
        if stop_requests.asked():       # SIGTERM's exception was swallowed (a finalizer, say) and nothing acted on it
            raise KeyboardInterrupt
        if caught:
            first = " ".join(next(iter(caught)).split())
            print(f"analogy: warning: the numerics gave {sum(caught.values())} warning(s) during the run, "
                  f"first {first!r}: check the result", file=sys.stderr)
        return code
    except InputError as exc:
        # --budget is named only where the command has it
        hint = _HINTS.get(exc.field, "") if exc.field != "budget" or hasattr(args, "budget") else ""
        print(f"analogy: error: {one_line(exc)}{hint}", file=sys.stderr)
        return EXIT_USAGE
    except AccuracyError as exc:
        print(f"analogy: accuracy: {one_line(exc)}", file=sys.stderr)
        return EXIT_ACCURACY
    except SimulationError as exc:
        print(f"analogy: simulation failed: {one_line(exc)}", file=sys.stderr)
        return EXIT_FAILED
    except AnalogyError as exc:
        print(f"analogy: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("analogy: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenExecutor as exc:       # a worker process died (killed, or out of memory)
        print(f"analogy: simulation failed: a worker process died ({exc or type(exc).__name__})", file=sys.stderr)
        return EXIT_FAILED
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
        stop_requests.clear()           # answered (exit 130) or never asked: nothing for a later caller


def _terminate(signum, frame):
    stop_requests.ask()
    raise KeyboardInterrupt


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
