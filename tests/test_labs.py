"""Every lab in examples/ runs headless, passes its own assertions and writes its plots and tables."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _diagrams(stem):
    return [f"{stem}_circuit.png", f"{stem}_mechanism.png"]


#: Files each lab must write into its output folder.
OUTPUTS = {
    "lab_default_scene.py": ["default.png", "default.csv", "mp_capacitance_sweep.png"],
    "lab_redundant.py": ["redundant.png", "redundant.csv", "redundant_parallel.png", "redundant_parallel.csv",
                         "redundant_topologies.png", *_diagrams("redundant"), *_diagrams("redundant_parallel")],
    "lab_serial2.py": ["serial2.png", "serial2.csv", "serial2_sweep.png", *_diagrams("serial2")],
    "lab_parallel2.py": ["parallel2.png", "parallel2.csv", "parallel2_sweep.png", *_diagrams("parallel2")],
    "lab_serial3.py": ["serial3.png", "serial3.csv", "serial3_sweep.png", *_diagrams("serial3")],
    "lab_parallel3.py": ["parallel3.png", "parallel3.csv", "parallel3_sweep.png", *_diagrams("parallel3")],
    "lab_many_poses.py": ["many_poses.png", "many_poses.csv"],
    "lab_nonlinear.py": ["nonlinear.png", "nonlinear.csv", "nonlinear_mp.png", "nonlinear_energy.png",
                         "nonlinear_linear.png", "pendulum.png"],
    "lab_mp_model.py": ["mp_loading.png", "mp_current.png", "mp_grounded_mass.csv", "mp_open.csv",
                        "mp_unloaded.csv", "mp_driven.csv"],
    "lab_flexible_arm.py": ["flexible_modes.png", "flexible_mass_matrix.png", "flexible_step.png",
                            "flexible_step.csv", "flexible_bode.png", "flexible_convergence.png",
                            *_diagrams("flex2")],
}

LABS = sorted(p.name for p in EXAMPLES.glob("lab_*.py"))


def test_every_lab_is_listed():
    assert set(LABS) == set(OUTPUTS), "add the new lab and its outputs to OUTPUTS"


@pytest.mark.ngspice
@pytest.mark.parametrize("lab", LABS)
def test_lab_runs_headless(lab, tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, MPLBACKEND="Agg")
    res = subprocess.run([sys.executable, str(EXAMPLES / lab), str(out)], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path, env=env)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    for name in OUTPUTS[lab]:
        path = out / name
        assert path.exists(), f"{lab} did not write {name}"
        data = path.read_bytes()
        if name.endswith(".png"):
            assert data[:8] == PNG_SIGNATURE, f"{name} is not a PNG"
        else:
            assert data.count(b"\n") > 10, f"{name} has too few rows"
    assert not (tmp_path / "lab-output").exists(), "the output folder argument was ignored"
