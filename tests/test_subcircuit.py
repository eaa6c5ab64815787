"""The robot as a subcircuit: a netlist of the user's own includes it, drives its ports, and runs in plain ngspice.

Each port's voltage is its joint's rate and the current driven into it is the joint's force, so a
wrapper that drives the ports with the scene's forces, under the settings the subcircuit's comment
recommends, must reproduce the scene's joint rates: against the exact solution (linear circuits)
or the DOP853 reference (nonlinear ones), each rate within the accurate bound of its own peak.
"""

import re
import shutil
import subprocess

import numpy as np
import pytest

from analogy.circuit.subcircuit import joint_ports
from analogy.cli import build_parser, main, scene_from_args
from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.solvers.rawfile import read_printed
from analogy.solvers.registry import solver
from analogy.circuit.joint_forces import waveforms

CASES = [
    "--robot serial2",                                  # serial: joint 2's port follows v2 − v1 (an E source)
    "--robot serial3 --param g=9.81 --q=0.3,0.2,-0.1",  # gravity's load stays inside, the ports see the rest
    "--robot serial4 --topology modal",                 # one node per mode: every port sums every node (B)
    "--robot parallel2",                                # a closed chain (five-bar), linear at its pose
    "--robot serial2 --realizable",                     # the 1:-1 couplings inside
    "--robot serial2 --r0=0.5,-0.3",                    # initial rates: the subcircuit's own .ic
    "--robot serial2 --dynamics nonlinear",             # charges, behavioural forces and integrators inside
    "--robot panda",                                    # a URDF arm, its joint names beside its ports
    "--robot parallel2 --dynamics nonlinear --t-stop 4 --force sine(0,0.02,0.5) --force sine(0,0.02,0.5,0,0,90)",
]


def _wrapper(sc, system, name: str, lib: str) -> str:
    """A user's netlist: the subcircuit included, each port driven by its joint's applied force."""
    n = system.dof
    recommended = [line[2:] for line in lib.splitlines() if line.startswith(("* .options", "* .tran"))]
    assert len(recommended) == 2
    ports = " ".join(f"p{j}" for j in range(1, n + 1))
    lines = ["* a circuit of the user's own, the robot its load", ".include robot.lib", f"X1 {ports} {name}"]
    for j, waves in enumerate(waveforms(sc.forces, n), start=1):
        lines += [f"Iu{j}_{k} 0 p{j} {w.spice(1.0, system.t_stop)}" for k, w in enumerate(waves)]
    return "\n".join(lines + recommended + [f".print tran {' '.join(f'v(p{j})' for j in range(1, n + 1))}",
                                           ".control", "set numdgt=15", ".endc", ".end"]) + "\n"


@pytest.mark.ngspice
@pytest.mark.parametrize("args", CASES)
def test_a_wrapper_driving_the_ports_reproduces_the_joint_rates_in_plain_ngspice(args, tmp_path):
    words = args.split()
    lib = tmp_path / "robot.lib"
    assert main(["netlist", *words, "--subckt", "arm", "-o", str(lib)]) == 0
    text = lib.read_text()
    assert ".subckt arm p" in text and text.rstrip().endswith(".ends arm")
    assert not any(line.startswith((".tran", ".options", ".end ", ".control")) or line == ".end"
                   for line in text.splitlines())      # a library: the analysis is the user's
    sc = scene_from_args(build_parser().parse_args(["netlist", *words]))
    system = sc.system()
    (tmp_path / "wrap.cir").write_text(_wrapper(sc, system, "arm", text))
    res = subprocess.run([shutil.which("ngspice") or "ngspice", "-b", "wrap.cir"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    printed = read_printed(res.stdout)
    t = printed["time"]
    assert t[-1] == pytest.approx(system.t_stop, rel=1e-12)     # ngspice -b prints from its first step on
    rates = np.column_stack([printed[f"p{j}"] for j in range(1, system.dof + 1)])
    name = "exact" if system.kind == "linear" else "reference"
    ref = solver(name).solve(system, np.concatenate([[0.0], t]), PRESETS["accurate"])
    _, rel = output_errors(rates, ref.rates[1:])
    assert np.max(rel) <= PRESETS["accurate"].bound, f"joint {int(np.argmax(rel)) + 1}: {np.max(rel):.3g}"


def _written(lines: list[str], n: int) -> tuple[np.ndarray, np.ndarray]:
    """From a port's device lines: the rate it follows (row of coefficients on v(n1) … v(nn)) and
    the currents it drives into the nodes per unit force (the gains of its F sources, or a wire)."""
    follows, drives = np.zeros(n), np.zeros(n)
    for line in lines:
        words = line.split()
        if words[0][0] == "V" and words[2].startswith("n"):         # a wire: r_j = v(n_k), F_j into n_k
            k = int(words[2][1:]) - 1
            follows[k] = drives[k] = 1.0
        elif words[0][0] == "E":
            follows[int(words[3][1:]) - 1] += 1.0
            follows[int(words[4][1:]) - 1] -= 1.0
        elif words[0][0] == "B":
            for c, k in re.findall(r"\(([^)]*)\)\*v\(n(\d+)\)", line):
                follows[int(k) - 1] += float(c)
        elif words[0][0] == "F":
            drives[int(words[2][1:]) - 1] += float(words[4])
    return follows, drives


def test_each_port_is_a_row_of_the_inverse_topology_and_its_power_is_the_circuits():
    """Port j, as written, follows r_j = Σ_k (T⁻¹)_jk v_k and drives (T⁻ᵀ)_kj F_j into node k: the
    same numbers, so that r_j F_j = v·(T⁻ᵀ F) for every force, the power balance of an ideal transformer."""
    from analogy.scenes.builtin import scene
    for topology in ("serial", "parallel", "modal"):
        system = scene("default").replace(topology=topology).system()
        inverse = np.linalg.inv(system.topology.matrix)
        follows, drives = (np.array(m) for m in zip(*(_written(p.lines(), system.dof) for p in joint_ports(system))))
        assert np.allclose(follows, inverse, rtol=0, atol=1e-12 * np.max(np.abs(inverse)))
        assert np.array_equal(drives, follows)          # the very numbers: no power made or lost
    serial = joint_ports(scene("default").system())
    assert [p.direct for p in serial] == [True, False]      # r1 = v1 is a wire, r2 = v2 − v1 is not


def test_a_subcircuit_refuses_what_does_not_apply_to_it_in_one_sentence(capsys):
    assert main(["netlist", "--subckt", "--dialect", "gnucap"]) == 2
    assert main(["netlist", "--subckt", "--save", "n1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("--subckt writes a subcircuit for ngspice that saves nothing" in e for e in err)


def test_the_subcircuit_name_is_a_spice_name_whatever_the_robot_is_called():
    from analogy.circuit.subcircuit import subcircuit_name
    assert subcircuit_name("serial2") == "serial2"
    assert subcircuit_name("ur5 arm\n.control") == "ur5_arm__control"      # no control line smuggled in
    assert subcircuit_name("2dof") == "robot_2dof"
