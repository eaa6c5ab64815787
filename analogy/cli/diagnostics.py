"""The diagnostic commands: ``bench`` (run time against error), ``stress``, ``throughput`` and ``memory``."""

from __future__ import annotations

from pathlib import Path

from ..errors import EXIT_OK, InputError
from ..files import write_text
from ..results.output import check_plot_path
from ..scenes.builtin import scene
from .outputs import check_folder, check_writable, write_outputs

__all__ = ["bench_command", "stress_command", "throughput_command", "memory_command"]


def _positive(value: int, what: str) -> int:
    if value < 1:
        raise InputError(f"{what} must be at least 1")
    return value


def bench_command(args) -> int:
    """``analogy bench``: run time against error, or the error constants measured again.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from ..diagnostics.bench import bench
    if args.calibrate is not None:
        return _calibrate(args)
    check_plot_path(args.plot)
    check_writable(args.csv)
    check_writable(args.plot)
    result = bench(repeats=_positive(args.repeats, "--repeats"), full=args.full,
                   progress=not args.no_progress, quick=args.quick)
    print(result.table())
    write_outputs([(args.csv, lambda: result.to_csv(args.csv)), (args.plot, lambda: result.plot(args.plot))])
    return EXIT_OK


def _calibrate(args) -> int:
    from ..diagnostics.calibration import calibration_runs, error_constants_of, write_runs
    from ..solvers.error_constants import CALIBRATION, write_constants
    path = Path(args.calibrate or CALIBRATION)
    beside = path.with_name(f"{path.stem}_runs.csv")
    check_writable(path)
    check_writable(beside)
    runs = calibration_runs(progress=not args.no_progress)
    rungs = error_constants_of(runs)
    for r in rungs:
        print(f"reltol {r.reltol:.0e}: error ≤ {r.c0:.3g}·reltol^(2/3) = {r.error:.2e} over {r.circuits} circuits "
              f"(worst: {r.worst})")
    write_constants(rungs, path)
    write_runs(runs, beside)
    print(f"wrote {path} and {beside}")
    return EXIT_OK


def stress_command(args) -> int:
    """``analogy stress``: the families of hard cases, or the error estimates against true errors.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from ..diagnostics.stress import stress, write_report
    out = Path(args.output)
    check_folder(out)
    if not args.timeout > 0:
        raise InputError(f"--timeout must be positive, got {args.timeout:g}")
    families = args.families.strip().lower()
    if args.estimates:
        return _estimates(args, out, families)
    report = stress(families, quick=args.quick, timeout=args.timeout,
                    progress=not args.no_progress)
    print(report.summary())             # said before any file, which a full disk could refuse
    try:
        out.mkdir(parents=True, exist_ok=True)
        written = write_report(report, out)
    except OSError as exc:
        raise InputError(f"cannot write the stress report: {exc}") from None
    print("wrote " + ", ".join(str(p) for p in written))
    return EXIT_OK


def _estimates(args, out: Path, families: str) -> int:
    from ..diagnostics.stress.estimates import validate_estimates
    from ..diagnostics.stress.families import FAMILY_TITLES
    bad = sorted(set(families) - set(FAMILY_TITLES))
    if bad:
        raise InputError(f"unknown stress families {''.join(bad)}: use letters of {''.join(FAMILY_TITLES)}")
    report = validate_estimates(args.quick, families, args.timeout, progress=not args.no_progress)
    print(report.summary())
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {out}: {exc.strerror or exc}") from None
    write_outputs([(out / "estimates.csv", lambda: report.to_csv(out / "estimates.csv")),
                   (out / "estimates.md", lambda: write_text(out / "estimates.md", "# Error estimates against true "
                                                             "errors\n\n" + report.summary() + "\n\n"
                                                             + report.table() + "\n")),
                   (out / "estimates.png", lambda: report.plot(out / "estimates.png"))])
    return EXIT_OK


def throughput_command(args) -> int:
    """``analogy throughput``: scenes per second, batched against per-scene loops, or a sweep's store.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    if args.sweep is not None:
        from ..diagnostics.store_throughput import store_throughput
        from ..batch.sweep import load_sweep
        if args.output is None:
            raise InputError("--sweep needs the results folder -o DIR")
        print(store_throughput(load_sweep(args.sweep), args.output, sample=_positive(args.baseline, "--baseline"),
                               workers=_positive(args.workers, "--workers")))
        return EXIT_OK
    from ..diagnostics.throughput import throughput
    print(throughput(n=_positive(args.n, "-n"), preset=args.preset.name,
                     group_size=_positive(args.group_size, "--group-size"),
                     workers=_positive(args.workers, "--workers"),
                     baseline_n=_positive(args.baseline, "--baseline"),
                     repeats=_positive(args.repeats, "--repeats"), progress=not args.no_progress))
    return EXIT_OK


def memory_command(args) -> int:
    """``analogy memory``: resident memory grown per in-process solver run.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from ..diagnostics.memory import memory_per_run
    scene(args.scene)                   # an unknown name is refused before any run
    print(memory_per_run(_positive(args.runs, "--runs"), args.preset.name, args.scene, solver=args.solver))
    return EXIT_OK
