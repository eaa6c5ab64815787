"""Other engines than the in-process ngspice: gnucap (its own dialect), and ngspice compiled to
WebAssembly (the npm package eecircuit-engine under node). Each is judged against the exact
solution (linear circuits) or the DOP853 reference (nonlinear ones) at the preset's bound, each
output against its own peak: never against another engine's bits.

``bash setup.sh test`` installs gnucap and, where npm exists, the WebAssembly build (in
.engines/wasm); elsewhere these tests skip and say why. ngspice 46 runs the whole SPICE suite
in CI's engine pass (``bash setup.sh engine``).
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from test_plain_ngspice import QUICK

from analogy.cli import build_parser, main, scene_from_args
from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.scenes.builtin import PAPER_EXAMPLES, scene
from analogy.solvers.gnucap import read_gnucap
from analogy.solvers.registry import solver
from analogy.study.comparison import compare

ROOT = Path(__file__).resolve().parent.parent
WASM = Path(os.environ.get("ANALOGY_WASM_ENGINE") or
            ROOT / ".engines/wasm/node_modules/eecircuit-engine/dist/eecircuit-engine.mjs")
# In CI setup.sh installs gnucap, so a missing one there is a failure, not a skip.
needs_gnucap = pytest.mark.skipif(shutil.which("gnucap") is None and not os.environ.get("CI"),
                                  reason="gnucap is not installed (bash setup.sh test installs it)")
needs_wasm = pytest.mark.skipif(shutil.which("node") is None or not WASM.exists(),
                                reason="node or the WebAssembly ngspice (npm eecircuit-engine) is not installed: "
                                       "bash setup.sh test installs it where npm exists")


def test_gnucap_s_table_is_read_with_its_scale_letters():
    """gnucap prints 4.4e-4 as -440.98u and 0 as 0.: each scale letter is its power of ten."""
    text = ("Gnucap banner\n#Time                   v(n1)                  v(n2)\n"
            " 0.                     0.                     0.\n"
            " 0.010000000000000002  -440.98139710800001u    0.0083048305350230009\n"
            " 0.02                   1.5K                   2.5Meg\n")
    data = read_gnucap(text)
    assert data["time"].tolist() == [0.0, 0.010000000000000002, 0.02]
    assert data["v(n1)"][1] == pytest.approx(-440.98139710800001e-6, rel=1e-15)
    assert data["v(n1)"][2] == 1500.0 and data["v(n2)"][2] == 2.5e6


@needs_gnucap
@pytest.mark.parametrize("name", PAPER_EXAMPLES)
@pytest.mark.parametrize("preset", ["accurate", "fast"])
def test_gnucap_keeps_the_preset_s_bound_on_the_paper_s_robots(name, preset):
    c = compare(scene(name).system(), preset, ["gnucap", "exact"])
    assert c.results["gnucap"].success, c.failures
    per_output = c.errors()["gnucap"].relative
    assert per_output <= PRESETS[preset].bound


def test_gnucap_s_dialect_writes_initial_voltages_on_capacitors_and_prints_before_the_run(capsys):
    assert main(["netlist", "--dialect", "gnucap", "--r0=0.5, -0.25"]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    assert not any(line.startswith((".ic", ".save", ".control")) for line in lines)
    # serial topology, v_k = r_1 + ... + r_k: v1 = r1 = 0.5, v2 = r1 + r2 = 0.25, v1 - v2 = -r2
    assert "C1 n1 0 3.7642691913004844 IC=0.5" in lines
    assert "C2 n2 0 1.404269191300485 IC=0.25" in lines
    assert "C1_2 n1 n2 -0.7642691913004849 IC=0.25" in lines
    assert [k for k, line in enumerate(lines) if line.startswith((".print", ".tran"))] == \
        [len(lines) - 3, len(lines) - 2]


@pytest.mark.parametrize("argv, message", [
    (["--dynamics", "nonlinear"], "gnucap has no charge-defined capacitors (Q={...}) or behavioural sources (B)"),
    (["--force", "sine(0, 1, 2, phase=90)", "--force", "0"], "gnucap's SIN has no phase"),
])
def test_what_gnucap_cannot_read_is_refused_in_one_sentence(argv, message, capsys):
    assert main(["netlist", "--dialect", "gnucap", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_the_gnucap_solver_declines_a_nonlinear_system_naming_what_gnucap_lacks():
    system = scene("default").replace(dynamics="nonlinear").system()
    assert "no charge-defined capacitors or behavioural sources" in solver("gnucap").supports(system)


@pytest.mark.ngspice
@pytest.mark.deep       # node starts the engine for each netlist: half a minute in all, in CI's deep pass
@needs_wasm
@pytest.mark.parametrize("args", QUICK)
def test_the_webassembly_ngspice_keeps_the_bound_on_every_written_netlist(args, tmp_path):
    """The netlist as `analogy netlist` writes it, without the printing block's ``interp`` where it has
    one (so that the engine's own points come back), keeps the accurate bound per output."""
    words = args.split()
    path = tmp_path / "robot.cir"
    assert main(["netlist", *words, "-o", str(path)]) == 0
    path.write_text("\n".join(line for line in path.read_text().splitlines() if line != "option interp") + "\n")
    res = subprocess.run(["node", str(ROOT / "tests/engines/wasm_ngspice.mjs"), str(WASM), str(path)],
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    out = json.loads(res.stdout)
    assert "ngspice-4" in out["header"]
    system = scene_from_args(build_parser().parse_args(["netlist", *words])).system()
    own = np.array(out["data"]["time"])
    volts = np.column_stack([out["data"][f"v({n})"] for n in system.nodes])
    if own[0] > 0:                                    # ngspice's output starts at its first step
        own, volts = np.concatenate([[0.0], own]), np.vstack([system.initial_voltages, volts])
    assert own[-1] == pytest.approx(system.t_stop, rel=1e-12)
    name = "exact" if system.kind == "linear" else "reference"
    ref = solver(name).solve(system, own, PRESETS["accurate"])
    _, rel = output_errors(system.joint_rates(volts), ref.rates)
    assert np.max(rel) <= PRESETS["accurate"].bound


@pytest.mark.ngspice
@pytest.mark.skipif(not os.environ.get("ANALOGY_EXPECT_NGSPICE"), reason="no engine pass asked for a version")
def test_the_engine_pass_runs_the_ngspice_it_names():
    """CI's engine pass (bash setup.sh engine) asks for ngspice 46: the library in process and
    the executable on PATH must both be it, or the pass would test ngspice 39 twice."""
    from analogy.solvers.spice import session
    wanted = int(os.environ["ANALOGY_EXPECT_NGSPICE"])
    assert session().version == wanted
    printed = subprocess.run(["ngspice", "-v"], capture_output=True, text=True, timeout=60).stdout
    assert f"ngspice-{wanted} " in printed


@needs_gnucap
@pytest.mark.ngspice
@pytest.mark.parametrize("name", ["serial2", "serial3", "parallel2"])
def test_the_realizable_circuit_keeps_the_accurate_bound_in_both_engines(name):
    """compare --realizable: each negative element behind a 1:-1 coupling, in ngspice and in
    gnucap. gnucap's voltage sources carry its series resistance 'short'; at its default
    (10 µΩ) serial2 measured 7.4e-5, so the dialect sets it from the circuit's impedance."""
    c = compare(scene(name).system().realized(), "accurate", ["spice", "gnucap", "exact"])
    assert "realizable circuit" in c.caption
    errors = c.errors()
    for engine in ("spice", "gnucap"):
        assert c.results[engine].success, c.failures
        assert errors[engine].relative <= PRESETS["accurate"].bound, engine


def test_the_gnucap_dialect_sets_its_source_resistance_where_couplings_need_it(capsys):
    """short = √ε × the circuit's impedance scale (velocity scale / current scale): the balance of
    its series error (∝ short) against rounding in its 1/short conductance (∝ 1/short)."""
    import math
    from analogy.circuit.scales import system_scales
    assert main(["netlist", "--dialect", "gnucap", "--realizable"]) == 0
    options = next(line for line in capsys.readouterr().out.splitlines() if line.startswith(".options"))
    assert "method=trap" in options
    scales = system_scales(scene("default").system())
    short = float(options.split(" short=")[1].split()[0])
    assert short == pytest.approx(math.sqrt(2.0 ** -52) * scales.peak_velocity / scales.current, rel=1e-15)
    assert main(["netlist", "--dialect", "gnucap"]) == 0                       # no coupling: gnucap's own
    assert " short=" not in capsys.readouterr().out


def test_a_gnucap_netlist_past_five_nodes_warns_that_gnucap_may_not_finish_it(capsys):
    """gnucap 0.36 ran serial5 at accurate in 0.4 s and serial6 in 14 s; serial7, serial8 and flex1 not at all."""
    assert main(["netlist", "--format", "gnucap", "--robot", "serial5"]) == 0
    out, err = capsys.readouterr()
    assert "warning" not in err and "* warning" not in out
    assert main(["netlist", "--format", "gnucap", "--robot", "serial6"]) == 0
    out, err = capsys.readouterr()
    assert "gnucap may not finish this 6-node netlist" in err
    assert "* warning: gnucap may not finish this 6-node netlist" in out      # the file says it too
    # serial20's modal circuit joins no node to another: gnucap ran it in 0.3 s, and nothing is said
    assert main(["netlist", "--format", "gnucap", "--robot", "serial20"]) == 0
    out, err = capsys.readouterr()
    assert "gnucap may not finish" not in err + out and "modal map" in err
    # a tridiagonal chain of 8 nodes (each joined to two) ran past 100 s: it is warned about
    chain = "[" + ", ".join("[" + ", ".join("2" if i == j else "-0.5" if abs(i - j) == 1 else "0"
                                            for j in range(8)) + "]" for i in range(8)) + "]"
    assert main(["netlist", "--format", "gnucap", "--mass", chain]) == 0
    assert "gnucap may not finish this 8-node netlist" in capsys.readouterr().err


def test_realizable_is_refused_for_the_nonlinear_circuit(capsys):
    assert main(["compare", "--realizable", "--dynamics", "nonlinear", "--no-plot"]) == 2
    assert "--realizable applies to the linear circuit" in capsys.readouterr().err
