"""The commands that show a scene: ``animate``, ``report``, the browser ``lab`` and the motors' ``drive``."""

from __future__ import annotations

import sys

from ..errors import EXIT_ACCURACY, EXIT_FAILED, EXIT_OK, InputError, SimulationError
from ..results.animation import check_animation_path
from ..results.output import check_plot_path
from .outputs import accuracy_exit, check_folder, check_writable, write_outputs
from .scene_options import built_system, scene_from_args, solver_list

__all__ = ["animate_command", "report_command", "lab_command", "drive_command"]

#: The flags that describe a scene (beside a scene file they are refused, not ignored).
_SCENE_FLAGS = ("robot", "urdf", "joints", "mass", "damping", "stiffness", "gravity", "param", "link_modes",
                "joint_frame", "geometric_stiffness", "q",
                "topology", "force", "r0", "t_stop", "equilibrium")


def animate_command(args) -> int:
    """``analogy animate``: one solver's run drawn as the mechanism moving beside its node voltages.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from ..solvers.registry import solve
    from ..study.motion import motion
    from ..study.work import check_work
    sc = scene_from_args(args)
    check_animation_path(args.output)
    check_writable(args.output)
    if args.sheet:
        check_plot_path(args.sheet)
        check_writable(args.sheet)
    if not args.fps > 0:
        raise InputError(f"--fps must be positive, got {args.fps:g}")
    if not 2 <= args.frames <= 2000:
        raise InputError(f"--frames takes 2 to 2000 frames, got {args.frames}")
    system = built_system(sc)
    check_work(system, args.preset, spice=args.solver == "spice")    # refused before it runs
    run = solve(system, args.solver, preset=args.preset)
    if not run.success:
        raise SimulationError(f"{args.solver}: {run.message}")
    shown = motion(system, run, args.frames, conventions=sc.model.conventions, model=sc.numeric_model())
    print(f"{shown.frames} frames, {shown.frames / args.fps:.3g} s at {args.fps:g} fps"
          + (f": {shown.note}" if shown.note else ""))
    write_outputs([(args.output, lambda: shown.save(args.output, args.fps)),
                   (args.sheet, lambda: shown.sheet(args.sheet))])
    return EXIT_OK


def report_command(args) -> int:
    """``analogy report``: one scene's run on one self-contained HTML page, ``DIR/index.html``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from pathlib import Path

    from ..scenes.report import scene_report
    from ..scenes.toml import load_scene, validated
    if args.scene_file:
        given = [f"--{k.replace('_', '-')}" for k in _SCENE_FLAGS if getattr(args, k, None)]
        if given or args.scene != "default":
            raise InputError(f"give a scene file or scene flags, not both: {(given or ['--scene'])[0]} "
                             f"would change {args.scene_file}")
        sc = load_scene(args.scene_file)
    else:
        sc = scene_from_args(args).replace(preset=args.preset or "accurate")
    changes = {k: v for k, v in (("dynamics", args.dynamics), ("preset", args.preset and args.preset.name),
                                  ("solvers", solver_list(args.solvers))) if v is not None and v != getattr(sc, k)}
    sc = validated(sc.replace(**changes)) if changes else sc
    out = Path(args.output_dir)
    check_folder(out, "the report")
    if out.is_dir():
        check_writable(out / "index.html")
    if not 2 <= args.frames <= 2000:
        raise InputError(f"--frames takes 2 to 2000 frames, got {args.frames}")
    report = scene_report(sc, animation=not args.no_animation, frames=args.frames)
    print(report.comparison.table())            # said before the page, which a full disk could refuse
    path = report.save(out)
    print(f"wrote {path} ({len(report.html) / 1e6:.2f} MB)")
    c = report.comparison
    return EXIT_FAILED if c.failures else accuracy_exit(c.outside_bound(), c.preset, c.bound, c)


def lab_command(args) -> int:
    """``analogy lab``: the scene the flags describe as an offline page of sliders, ngspice and the exact solution.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from pathlib import Path

    from ..scenes.lab_page import write_lab
    sc = scene_from_args(args)
    out = Path(args.output_dir)
    check_folder(out, "the lab")
    if out.is_dir():
        check_writable(out / "index.html")
    path = write_lab(sc, out, args.engine)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB): open it in a browser, no network needed")
    return EXIT_OK


def drive_command(args) -> int:
    """``analogy drive``: the scene's robot driven by the motors of a motor file, in ngspice and exactly.

    The motor file and the voltages make the scene a drive, as a scene file's ``[motors]`` does;
    it runs as :func:`~analogy.scenes.run.run_scene` runs any scene.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from ..model.motors import read_motor_file
    from ..scenes.run import run_scene
    from ..files import write_text
    from ..scenes.validate import validated
    if args.force:
        raise InputError("--force: the motors drive the joints; give each motor its --voltage instead")
    for path in (args.csv, getattr(args, "output", None)):
        check_writable(path)
    if args.plot:
        check_plot_path(args.plot)
    sc = scene_from_args(args).replace(motors=read_motor_file(args.motors), voltages=tuple(args.voltage), forces=(),
                                       solvers=("spice", "ode", "exact"), description="")
    run = run_scene(validated(sc)).drive
    # the command line's own files, anywhere (a scene file's stay inside its folder); compare --motors has no -o
    print(run.table())
    write_outputs([(getattr(args, "output", None), lambda: write_text(args.output, run.netlist)),
                   (args.csv, lambda: run.to_csv(args.csv)), (args.plot, lambda: run.plot(args.plot))])
    return drive_exit(run, args.preset.name, args.preset.bound)


def drive_exit(run, preset: str, bound: float) -> int:
    """A drive's exit code, each broken promise said on stderr: an output past the bound, a winding past its
    current limit (3), else 0.

    Parameters
    ----------
    run : DriveRun
        The drive's run.
    preset : str
        The preset's name.
    bound : float
        Its bound.
    """
    if run.note:
        print(f"analogy: note: the run was {run.note}", file=sys.stderr)
    limits = run.over_limits()
    for name, why in limits.items():
        print(f"analogy: limit: {name}'s winding carried {why}", file=sys.stderr)
    code = accuracy_exit(run.outside_bound(), preset, bound)
    return code or (EXIT_ACCURACY if limits else EXIT_OK)
