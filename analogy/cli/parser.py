"""The command line's parser: every subcommand and its options, with one-line errors."""

from __future__ import annotations

import argparse

from .. import __version__
from ..circuit.netlist import NETLIST_FORMATS
from ..errors import InputError
from .batch import batch_options
from .scene_options import preset_option, scene_options

__all__ = ["build_parser"]


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit 2) instead of a usage dump."""

    def error(self, message):
        if "expected one argument" in message:      # argparse reads "-0.6,0.3" as a flag
            message += "; a value starting with '-' goes after '=', e.g. --q=-0.6,0.3"
        raise InputError(f"{message} (see {self.prog} --help)")


def _netlist(sub) -> None:
    """``analogy netlist``: the equivalent circuit's netlist."""
    p = sub.add_parser("netlist", help="write the equivalent-circuit SPICE netlist")
    scene_options(p)
    p.add_argument("-o", "--output", help="file to write (default: stdout)")
    p.add_argument("--save", metavar="NAMES", help="nodes or elements to save, e.g. 'n1, C1_2' (default: all nodes)")
    p.add_argument("--realizable", action="store_true",
                   help="no negative values: negative elements behind 1:-1 couplings")
    p.add_argument("--format", "--dialect", dest="format", default="ngspice", choices=list(NETLIST_FORMATS),
                   help="what to write: ngspice's netlist (default, any circuit); gnucap's (linear circuits: IC= on "
                        "each capacitor instead of .ic, .print before .tran); ltspice, LTspice's netlist, and with "
                        "-o FILE its schematic FILE.asc beside it; or kicad, a KiCad 9 schematic (.kicad_sch) whose "
                        "parts carry the ngspice lines")
    p.add_argument("--dynamics", choices=["linear", "nonlinear"],
                   help="the circuit at q (linear), or the robot's full nonlinear circuit: "
                        "charge-defined capacitors, behavioural forces and integrators (default: the scene's own, "
                        "linear but for the hopper's)")
    p.add_argument("--subckt", nargs="?", const="", metavar="NAME",
                   help="write the robot as a subcircuit '.subckt NAME p1 ... pn' for a netlist of your own: "
                        "one port per joint, the current into it the joint's force and its voltage the joint's "
                        "rate; the applied forces are left to your circuit (default NAME: the robot's)")


def _compare(sub) -> None:
    """``analogy compare``: solvers run and compared on one scene."""
    p = sub.add_parser("compare", help="run SPICE, ODE and exact solvers and compare them")
    scene_options(p)
    p.add_argument("--solvers", default="spice,ode,exact",
                   help="comma-separated registered solvers: spice, gnucap (linear circuits, where installed), "
                        "ode, exact, reference")
    p.add_argument("--dynamics", choices=["linear", "nonlinear", "both"],
                   help="the circuit at q (linear), the full configuration-dependent motion, or both: "
                        "how long the linear circuit holds (default: the scene's own, linear but for the hopper's)")
    p.add_argument("--estimate", action="store_true", help="also estimate each solver's error without a "
                   "reference: each runs again with every step halved (SPICE) or a 100 times tighter tolerance "
                   "(ODE), and the difference, times Richardson's factor, is the estimate")
    p.add_argument("--refine", action="store_true", help="estimate (as --estimate), and where a solver's "
                   "estimate exceeds the bound, take its refined run and refine that in turn, at most 3 times "
                   "(SPICE: every step halved; ODE: rtol 100 times tighter), until its estimated error meets the bound")
    p.add_argument("--no-reference", action="store_true", help="run no reference solution: with --estimate, "
                   "the estimate alone judges the bound")
    p.add_argument("--realizable", action="store_true", help="the circuit solvers (spice, gnucap) run the "
                   "realizable circuit: no negative values, negative elements behind 1:-1 couplings")
    p.add_argument("--step", metavar="SECONDS", help="output step of the shared time grid "
                   "(default: SPICE's own points); errors are measured on each solver's own points")
    p.add_argument("--timeout", metavar="SECONDS", help="wall-time limit of each ODE integration and of each "
                   "long ngspice run (default: the preset's, 300 s); past it the solver fails with one sentence")
    p.add_argument("--budget", metavar="POINTS", help="most time points (and force segments) a run may "
                   "need, estimated before it starts (default: the preset's, 1e8 at accurate, 1e7 at fast); "
                   "the SPICE circuit's operation budget scales with it")
    p.add_argument("--csv", metavar="FILE", help="write joint rates of every solver to CSV (past 100,000 "
                   "time points, every k-th of them as computed, unless --step or --csv-all)")
    p.add_argument("--csv-all", action="store_true", help="write every time point to the CSV, however many")
    _motor_options(p, required=False)
    p.add_argument("--plot", metavar="FILE.png", help="write a plot of rates and errors")
    p.add_argument("--no-plot", action="store_true", help="never import the plotting library")


def _modes(sub) -> None:
    """``analogy modes``: natural frequencies and damping ratios."""
    p = sub.add_parser("modes", help="natural frequencies and damping ratios of the linear system at q")
    scene_options(p)
    p.add_argument("--locked", metavar="JOINTS", help="joints held clamped, e.g. '1' or '1,2'")
    p.add_argument("--csv", metavar="FILE", help="write mode, omega_rad_s, f_hz, damping_ratio, kind "
                   "(oscillating, rigid body or unstable)")


def _ac(sub) -> None:
    """``analogy ac``: the AC sweep against the exact mobility."""
    p = sub.add_parser("ac", help="ngspice's .ac sweep against the exact mobility (M's + B' + K'/s)^-1")
    scene_options(p)
    for flag, what in (("--f-start", "first frequency (default: modes / 10)"), ("--f-stop", "last (modes x 10)")):
        p.add_argument(flag, type=float, metavar="HZ", help=what)
    p.add_argument("--points", type=int, default=500, help="points per decade (default 500)")
    for flag, what in (("--csv", "|Y| and phase of SPICE's mobilities"), ("--plot", "a Bode plot")):
        p.add_argument(flag, metavar="FILE", help=f"write {what}")


def _verify(sub) -> None:
    """``analogy verify`` and ``analogy scenes``: every built-in example checked, and the list of scenes."""
    p = sub.add_parser("verify", help="check every built-in example: SPICE and ODE against exact, "
                                      "exact against a 40-digit mpmath solution")
    preset_option(p)
    p.add_argument("--scenes", default=None, help="comma-separated scene names (default: all)")
    sub.add_parser("scenes", help="list the built-in scenes")


def _draw(sub) -> None:
    """``analogy draw``: drawings of the circuit and the mechanism."""
    p = sub.add_parser("draw", help="draw the equivalent circuit and the mechanical system (SVG and PNG)")
    scene_options(p)
    p.add_argument("-o", "--output-dir", default=".", help="folder for the drawings (default: .)")
    p.add_argument("--stem", help="file name stem (default: the scene's name, with its content "
                                  "key when changed from a built-in scene)")
    p.add_argument("--schematic", action="store_true", help="draw schematics even past 6 nodes "
                   "(default there: a map of the element values by node pair)")


def _animate(sub) -> None:
    """``analogy animate``: the mechanism moving beside its circuit."""
    p = sub.add_parser("animate", help="the mechanism moving beside its node voltages (and, nonlinear, its "
                                       "MP capacitances): GIF, MP4 or an HTML page")
    scene_options(p)
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="FILE.gif (pillow), FILE.mp4 (needs ffmpeg) or FILE.html (its own player)")
    p.add_argument("--dynamics", choices=["linear", "nonlinear"],
                   help="the circuit linearised at q (default) or the full nonlinear one, whose "
                        "capacitances change with the pose")
    p.add_argument("--solver", default="spice", choices=("spice", "ode", "exact", "reference"),
                   help="whose run is drawn (default spice: the circuit's own)")
    p.add_argument("--frames", type=int, default=60, help="frames, evenly spread over the run (default 60)")
    p.add_argument("--fps", type=float, default=15.0, help="frames per second (default 15)")
    p.add_argument("--sheet", metavar="FILE.png", help="also write a contact sheet of three frames")


def _report(sub) -> None:
    """``analogy report``: one scene on one HTML page."""
    p = sub.add_parser("report", help="one scene's run on one self-contained HTML page: verdict, table, "
                                      "circuit, plots, motion, netlist and provenance")
    p.add_argument("scene_file", nargs="?", metavar="SCENE.toml",
                   help="a scene file (default: the scene the flags below describe)")
    scene_options(p, preset=None)
    p.add_argument("-o", "--output-dir", required=True, metavar="DIR", help="folder for index.html")
    p.add_argument("--dynamics", choices=["linear", "nonlinear"], help="the circuit at q (linear, the "
                   "default) or the full nonlinear one")
    p.add_argument("--solvers", help="comma-separated solvers (default spice,ode,exact)")
    p.add_argument("--frames", type=int, default=48, help="frames of the animation (default 48)")
    p.add_argument("--no-animation", action="store_true", help="leave the animation out (a smaller page)")


def _lab(sub) -> None:
    """``analogy lab``: a scene as a lab page in the browser."""
    p = sub.add_parser("lab", help="a scene as one offline page: sliders re-write its netlist, ngspice compiled "
                                   "to WebAssembly runs it, and the exact solution is set beside it")
    scene_options(p)
    p.add_argument("-o", "--output-dir", required=True, metavar="DIR", help="folder for index.html")
    p.add_argument("--engine", metavar="FILE.mjs", help="eecircuit-engine's dist/eecircuit-engine.mjs (npm "
                   "eecircuit-engine; default $ANALOGY_WASM_ENGINE, else the copy bash setup.sh test installs)")


def _drive(sub) -> None:
    """``analogy drive``: the robot driven by its motors."""
    p = sub.add_parser("drive", help="the robot driven by DC motors through gearboxes: the windings' loops "
                                     "around its subcircuit run in ngspice, against the exact solution")
    scene_options(p)
    _motor_options(p, required=True)
    p.add_argument("--dynamics", choices=["linear", "nonlinear"],
                   help="the robot's circuit at q (linear, default: ngspice against the exact solution) or its "
                        "full nonlinear circuit (ngspice against scipy's integration of the whole, 100 times tighter)")
    p.add_argument("-o", "--output", metavar="FILE.cir", help="write the netlist that ran (it runs in ngspice -b)")
    p.add_argument("--csv", metavar="FILE", help="write the joint rates and winding currents of every solver")
    p.add_argument("--plot", metavar="FILE.png", help="write a plot of them")


def _motor_options(p, required: bool) -> None:
    """``--motors`` and ``--voltage``."""
    p.add_argument("--motors", required=required, metavar="FILE.toml",
                   help="motor file: [default] and/or a table per joint (its name or number) with resistance, "
                        "inductance, torque_constant, rotor_inertia, gear_ratio, viscous, coulomb, voltage_limit, "
                        "current_limit (numbers in SI, or strings with units such as \"0.5 mH\")")
    p.add_argument("--voltage", action="append", default=[], metavar="WAVEFORM",
                   help="the voltage on each motor, in joint order, once per motor: a number or a waveform such "
                        "as step(12) or pwm(24, 0.6, 20e3) (the exact solution needs piecewise-linear voltages)")


def _run(sub) -> None:
    """``analogy run``: scene files run."""
    p = sub.add_parser("run", help="run scene files (TOML): exactly what each asks for")
    p.add_argument("scene_files", nargs="+", metavar="SCENE.toml", help="one or more .toml scenes")
    preset_option(p, None, "override each scene's accuracy preset (a name or a tolerance)")
    p.add_argument("--solvers", help="override each scene's solvers, e.g. spice,exact")
    p.add_argument("--output-dir", help="folder for the scene's output files (default: next to it)")
    p.add_argument("--no-plot", action="store_true", help="skip plots even if the scene asks for one")
    p.add_argument("--dynamics", choices=["linear", "nonlinear"], help="override the scene's dynamics")


def _bench(sub) -> None:
    """``analogy bench``: run time against error."""
    p = sub.add_parser("bench", help="run time against error: ngspice settings, ODE methods, exact solver")
    p.add_argument("--repeats", type=int, default=5, help="timed runs per setting (median; default 5)")
    p.add_argument("--quick", action="store_true", help="a small grid on the 2- and 10-DOF scenes "
                   "(seconds), for a first look")
    p.add_argument("--full", action="store_true", help="the full ngspice grid (method x reltol x trtol x max step)")
    p.add_argument("--csv", default="bench.csv", help="CSV output (default: bench.csv)")
    p.add_argument("--plot", default="bench.png", help="work-precision plot (default: bench.png)")
    p.add_argument("--calibrate", nargs="?", const="", metavar="FILE", help="instead, measure ngspice's error "
                   "constants again (every calibration circuit at reltol 1e-5 to 1e-13, minutes) and write them to "
                   "FILE (default: the package's own, which --tol and the presets read), the runs beside it")
    p.add_argument("--no-progress", action="store_true", help="no progress (a bar on a terminal, "
                   "plain lines otherwise)")


def _stress(sub) -> None:
    """``analogy stress``: families of hard cases."""
    p = sub.add_parser("stress", help="stress-test numerical stability: families of hard cases, each run by "
                                      "every solver that applies (CSV, a plot per family, a summary)")
    p.add_argument("--quick", action="store_true", help="only the ends of each sweep (under a minute)")
    p.add_argument("--families", default="abcdefghi", help="family letters (default abcdefghi): "
                   "a conditioning, b time scales, c long runs, d size, e units, f near-singular, g nonlinear, "
                   "h a real arm's singular poses, i the named robots at their defaults")
    p.add_argument("-o", "--output", default="stress", help="folder for stress.csv, stress.md and "
                   "stress_<family>.png (made if missing; default: stress)")
    p.add_argument("--timeout", type=float, default=10.0, help="wall-time limit of each ODE run [s] (default 10)")
    p.add_argument("--estimates", action="store_true", help="validate the error estimates instead: each solver "
                   "at both presets on the bench scenes and these families' cases, its estimate against its true "
                   "error (estimates.csv, estimates.md, estimates.png)")
    p.add_argument("--no-progress", action="store_true", help="no progress (a bar on a terminal, "
                   "plain lines otherwise)")


def _check(sub) -> None:
    """``analogy check``: a netlist's error estimated without a reference."""
    p = sub.add_parser("check", help="estimate the error of a netlist's saved vectors without a reference: "
                       "it runs as written and again with every step halved (Richardson)")
    p.add_argument("netlist", metavar="NETLIST", help="a transient netlist, e.g. one analogy netlist wrote")
    preset_option(p, "accurate", "the preset (or tolerance) whose bound judges the estimate "
                  "(default accurate, 1e-6 of each vector's peak)")
    p.add_argument("--csv", metavar="FILE", help="write the saved vectors as they ran")
    p.add_argument("--plot", metavar="FILE.png", help="write a plot of the saved vectors and their estimates")


def _memory(sub) -> None:
    """``analogy memory``: resident memory per run."""
    p = sub.add_parser("memory", help="resident memory grown per in-process solver run (kB/run)")
    p.add_argument("--runs", type=int, default=10_000, help="counted runs (default 10000)")
    p.add_argument("--solver", default="spice", help="registered solver: spice, ode, exact or reference "
                   "(default spice)")
    preset_option(p)
    p.add_argument("--scene", default="default", help="built-in scene (default: default)")


def _throughput(sub) -> None:
    """``analogy throughput``: scenes per second."""
    p = sub.add_parser("throughput", help="scenes per second: batched ngspice runs against per-scene loops")
    p.add_argument("-n", type=int, default=10_000, help="number of 2-DOF scenes (default 10000)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--group-size", type=int, default=100, help="scenes per ngspice run (default 100)")
    p.add_argument("--baseline", type=int, default=500, help="scenes for the per-scene loops (default 500)")
    p.add_argument("--repeats", type=int, default=3, help="turns of every path; medians are reported (default 3)")
    preset_option(p, "fast")
    p.add_argument("--no-progress", action="store_true", help="no progress lines")
    p.add_argument("--sweep", metavar="SWEEP.toml", help="instead: this sweep into the store -o DIR, "
                   "beside the in-memory batched path on its first --baseline scenes, with peak memory")
    p.add_argument("-o", "--output", metavar="DIR", help="the store of --sweep")


#: Each adds its subcommand, in the order ``analogy --help`` lists them.
_SUBCOMMANDS = (_netlist, _compare, _modes, _ac, _verify, _draw, _animate, _report, _lab, _drive, _run,
                batch_options,
                _bench, _stress, _check, _memory, _throughput)


def build_parser() -> argparse.ArgumentParser:
    """The ``analogy`` argument parser, with one subcommand per task."""
    parser = _Parser(prog="analogy",
                     description="Robot dynamics as electric circuits: netlists, SPICE and checks.")
    parser.add_argument("--version", action="version", version=f"analogy {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in _SUBCOMMANDS:
        add(sub)
    return parser
