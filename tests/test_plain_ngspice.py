"""Every built-in robot's netlist, as `analogy netlist` writes it, runs in plain `ngspice -b`.

Two claims per robot. (1) What is written is what runs in process: the printed table is the
in-process run of the same text, to the 15 printed digits: at its own points (a calibrated
circuit), or linearly interpolated onto the print step (``option interp``, the preset's own
settings). (2) That
run keeps the preset's bound on every output against the exact solution (linear circuits) or
the DOP853 reference (nonlinear ones), each output against its own peak.
"""

import shutil
import subprocess

import numpy as np
import pytest

from analogy.cli import build_parser, main, scene_from_args
from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.solvers.rawfile import read_printed
from analogy.solvers.registry import solver
from analogy.solvers.spice import session

QUICK = [f"--robot serial{n}" for n in range(2, 13)] + [
    "--robot parallel2", "--robot parallel3", "--robot redundant",
    "--robot serial2 --realizable", "--robot serial3 --realizable", "--robot parallel2 --realizable",
    "--robot serial2 --dynamics nonlinear", "--robot serial3 --dynamics nonlinear",
    "--robot serial2 --dynamics nonlinear --topology parallel",
    # one node per mode; the sources into one node written as their sum
    "--robot random10 --topology modal", "--robot serial4 --topology modal",
    "--robot serial2 --dynamics nonlinear --topology modal",
    # closed chains' constrained circuits, swinging far from their singular poses
    "--robot parallel2 --dynamics nonlinear --t-stop 4 --force sine(0,0.02,0.5) --force sine(0,0.02,0.5,0,0,90)",
    "--robot parallel3 --dynamics nonlinear --t-stop 4 --force sine(0,0.005,0.5) --force sine(0,0.005,0.5,0,0,120) "
    "--force sine(0,0.005,0.5,0,0,240)",
]

class BoundMissed(AssertionError):
    """Claim (2) failed: the run is outside the preset's bound (``compare`` flags it, exit 3)."""


# Judged per output, the flexible arms at their defaults (10 s, a 252 Hz mode) miss the
# accurate bound on their modal coordinates: measured 2.3e-3 (flex1), 1.2e-2 (flex2; 1.4e-4
# of the largest peak) and 1.9e-2 (flex2 realizable). Only that claim may fail for them.
_FLEX = pytest.mark.xfail(strict=True, raises=BoundMissed,
                          reason="modal coordinates miss the accurate bound per output (flagged, exit 3)")
# minutes in plain ngspice at accurate: run in CI's deep pass (pytest -m deep)
DEEP = [f"--robot serial{n}" for n in range(13, 21)] + [
    pytest.param(args, marks=_FLEX) for args in ("--robot flex1", "--robot flex2", "--robot flex2 --realizable")]

#: Printed with 15 significant digits, interpolated alike: agreement to 1e-12 of the peak
#: leaves a factor of 1000 over the printing and n·ε of the interpolation.
PRINTED = 1e-12


def _plain_run(args: str, tmp_path):
    words = args.split()
    path = tmp_path / "robot.cir"
    assert main(["netlist", *words, "-o", str(path)]) == 0
    res = subprocess.run([shutil.which("ngspice") or "ngspice", "-b", str(path)], capture_output=True,
                         text=True, timeout=1800)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "too small" not in (res.stdout + res.stderr).lower()
    sc = scene_from_args(build_parser().parse_args(["netlist", *words]))
    return sc, sc.system(), path.read_text(), read_printed(res.stdout)


def _check(args: str, tmp_path):
    sc, system, text, printed = _plain_run(args, tmp_path)
    preset = PRESETS["accurate"]          # the netlist command's default
    t = printed["time"]
    assert t.size < 100_000 and t[-1] == pytest.approx(system.t_stop, rel=1e-12)
    # (1) the printed table is the in-process run of this very text, at its own points
    data = session().run(text, list(system.nodes))
    own = data["time"]
    here = np.column_stack([np.interp(t, own, data[n]) for n in system.nodes])     # at own points: themselves
    there = np.column_stack([printed[n] for n in system.nodes])
    scale = np.max(np.abs(there))
    assert np.max(np.abs(here - there)) <= PRINTED * scale
    # (2) that run keeps the bound on every joint rate, each against its own peak
    times = np.concatenate([[0.0], own]) if own[0] > 0 else own
    volts = np.column_stack([np.concatenate([[v0], data[n]])[-times.size:]
                             for n, v0 in zip(system.nodes, system.initial_voltages)])
    name = "exact" if system.kind == "linear" else "reference"
    ref = solver(name).solve(system, times, PRESETS["accurate"])
    _, rel = output_errors(system.joint_rates(volts), ref.rates)
    if not np.max(rel) <= preset.bound:
        raise BoundMissed(f"joint {int(np.argmax(rel)) + 1}: {np.max(rel):.3g} of its own peak")


@pytest.mark.ngspice
@pytest.mark.parametrize("args", QUICK)
def test_the_written_netlist_runs_in_plain_ngspice_and_keeps_the_bound(args, tmp_path):
    _check(args, tmp_path)


@pytest.mark.ngspice
@pytest.mark.deep
@pytest.mark.parametrize("args", DEEP)
def test_the_large_and_flexible_netlists_run_in_plain_ngspice_and_keep_the_bound(args, tmp_path):
    _check(args, tmp_path)


@pytest.mark.ngspice
def test_gear_integrates_at_order_two_whatever_maxord_asks(tmp_path):
    """ngspice raises the integration order from 1 to 2 only (dctran.c), so gear's maxord past 2
    changes no step: a damped LC at reltol 1e-6 and 1e-9 takes the same accepted points at
    maxord 2, 3 and 6. An order-p rule's local error goes as h^(p+1), so its steps grow as
    reltol^(-1/(p+1)) per 1000: 10 at order 2, 5.6 at order 3 and 2.7 at order 6 (measured 8.8;
    the bracket leaves a factor of 2 for the steps onto the breakpoints)."""
    deck = ("* damped LC\nL1 a 0 1\nC1 a 0 1\nR1 a 0 100\nI1 0 a PWL(0 0 0.1 1)\n"
            ".options method=gear maxord={order} reltol={tol}\n.tran 1e-3 20 0 0.5 uic\n"
            ".control\nrun\nrusage accept\n.endc\n.end\n")
    steps = {}
    for tol in (1e-6, 1e-9):
        for order in (2, 3, 6):
            path = tmp_path / f"lc{order}.cir"
            path.write_text(deck.format(order=order, tol=tol))
            out = subprocess.run([shutil.which("ngspice") or "ngspice", "-b", str(path)], capture_output=True,
                                 text=True, timeout=60).stdout
            steps[tol, order] = int(out.split("Accepted timepoints = ")[1].split()[0])
        assert steps[tol, 2] == steps[tol, 3] == steps[tol, 6]
    assert 5 <= steps[1e-9, 2] / steps[1e-6, 2] <= 20
