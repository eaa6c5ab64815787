"""Every lab in examples/ is a notebook: it runs headless in a Jupyter kernel, passes its own
assertions, writes its plots and tables and shows each plot. It still runs as a plain script, and
the helpers its plots share keep legends off the data."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Seconds one cell may take; the longest cell of any lab takes well under a minute.
CELL_TIMEOUT = 300


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
                         "nonlinear_linear.png", "pendulum.png", "nonlinear_motion.gif",
                         "nonlinear_motion_sheet.png"],
    "lab_mp_model.py": ["mp_loading.png", "mp_current.png", "mp_grounded_mass.csv", "mp_open.csv",
                        "mp_unloaded.csv", "mp_driven.csv"],
    "lab_flexible_arm.py": ["flexible_modes.png", "flexible_mass_matrix.png", "flexible_step.png",
                            "flexible_step.csv", "flexible_step_motion.gif", "flexible_step_motion_sheet.png", "flexible_bode.png", "flexible_convergence.png",
                            "flexible_clamp.png",
                            "flex2_elements.png"],
    "lab_closed_chains.py": ["closed_chain_forces.png", "closed_chain_singular.png"],
    "lab_modes.py": ["modes_serial.png", "modes_serial.csv", "modes_modal.png", "modes_modal.csv",
                     "modes_velocities.png", *_diagrams("modes_modal")],
    "lab_motor.py": ["motor_gear.png", "motor_step.png", "motor_pwm.png", "motor_pwm.csv"],
    "lab_contact.py": ["contact_drop.png", "contact_drop.csv", "contact_closed_form.png", "contact_diode.png",
                       "contact_settling.png", "contact_motion.gif", "contact_motion_sheet.png"],
    "lab_real_arm.py": ["real_arm_potential.png", "real_arm_panda.png", "real_arm_panda.csv", "real_arm_forces.csv"],
    "lab_your_robot.py": ["ur5_elbow_sweep.png", "ur5_elements.png", "ur5.png", "ur5.csv", "ur5_wrist.png",
                          "ur5_singular.png", "ur5_singular.csv"],
}

LABS = sorted(p.name for p in EXAMPLES.glob("lab_*.py"))


def _check_outputs(lab, out):
    for name in OUTPUTS[lab]:
        path = out / name
        assert path.exists(), f"{lab} did not write {name}"
        data = path.read_bytes()
        if name.endswith(".png"):
            assert data[:8] == PNG_SIGNATURE, f"{name} is not a PNG"
        elif name.endswith(".gif"):
            assert data[:6] == b"GIF89a", f"{name} is not a GIF"
        else:
            assert data.count(b"\n") > 10, f"{name} has too few rows"


@pytest.fixture
def lab_module(monkeypatch):
    """examples/_lab.py, imported as the labs import it."""
    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.delenv("ANALOGY_LAB_OUTPUT", raising=False)
    import _lab
    return _lab


@pytest.mark.parametrize("lab", LABS)
def test_a_lab_opened_as_a_notebook_names_its_kernel(lab):
    jupytext = pytest.importorskip("jupytext")
    kernel = jupytext.read(EXAMPLES / lab).metadata.get("kernelspec", {})
    assert kernel.get("name") == "python3" and kernel.get("language") == "python"


def test_every_lab_is_listed():
    assert set(LABS) == set(OUTPUTS), "add the new lab and its outputs to OUTPUTS"


@pytest.mark.parametrize("lab", LABS)
def test_every_lab_is_a_percent_notebook_that_opens_with_its_explanation(lab):
    jupytext = pytest.importorskip("jupytext")
    text = (EXAMPLES / lab).read_text()
    assert jupytext.formats.guess_format(text, ".py")[0] == "percent"
    notebook = jupytext.reads(text, fmt="py:percent")
    kinds = [cell.cell_type for cell in notebook.cells]
    assert kinds[0] == "markdown" and notebook.cells[0].source.startswith("# Lab: "), "a titled explanation first"
    assert kinds.count("markdown") >= 3 and kinds.count("code") >= 3, "prose between the steps"


def test_the_output_folder_is_the_first_argument_of_a_script(lab_module, tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["lab_x.py", str(tmp_path / "mine")])
    assert lab_module.output_folder() == tmp_path / "mine"
    assert (tmp_path / "mine").is_dir()


def test_the_environment_variable_names_the_output_folder_first(lab_module, tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["lab_x.py", str(tmp_path / "argument")])
    monkeypatch.setenv("ANALOGY_LAB_OUTPUT", str(tmp_path / "env"))
    assert lab_module.output_folder() == tmp_path / "env"
    assert not (tmp_path / "argument").exists()


def test_a_kernels_own_arguments_are_not_an_output_folder(lab_module, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", ["ipykernel_launcher.py", "-f", str(tmp_path / "kernel.json")])
    monkeypatch.setitem(sys.modules, "ipykernel", sys.modules.get("ipykernel", object()))
    assert lab_module.output_folder() == Path("lab-output")
    assert (tmp_path / "lab-output").is_dir() and not (tmp_path / "-f").exists()


def test_a_sweeps_legend_sits_outside_its_axes_and_unassembled_poses_are_shaded_not_plotted(lab_module):
    np = pytest.importorskip("numpy")
    x = np.linspace(0.0, 2.0, 21)
    skipped = [2.1, 2.2, 2.3]
    fig, axes = lab_module.figure()
    ax = axes[0, 0]
    lab_module.plot_sweep(ax, x, {"m'1": (np.cos(x), {}), "p'12": (np.sin(x), {})}, xlabel="q [rad]",
                          here=1.0, skipped=skipped)
    fig.draw_without_rendering()
    legend, frame = ax.get_legend().get_window_extent(), ax.get_window_extent()
    assert legend.x0 >= frame.x1, "the legend is right of the axes, over no data"
    assert not [line for line in ax.get_lines() if line.get_marker() not in ("None", None, "")], \
        "no markers: a pose without values is no data point"
    (span,) = [patch for patch in ax.patches]
    left, right = span.get_x(), span.get_x() + span.get_width()
    assert left < min(skipped) and right > max(skipped), "the shading covers the skipped poses"


def test_the_envelope_of_an_alternating_error_is_its_largest_value_in_each_window(lab_module):
    np = pytest.importorskip("numpy")
    # Uneven steps, as a simulator takes them; none falls on a window's edge k/10.
    time = np.concatenate([[0.0], np.sort(np.random.default_rng(1).uniform(0.001, 0.999, 999)), [1.0]])
    error = 1e-7 * (1.0 + time) * (1 + (-1) ** np.arange(time.size)) / 2     # 0 at every other step
    centre, top = lab_module.envelope(time, error, windows=10)
    assert np.allclose(centre, np.arange(10) / 10 + 0.05)
    for k in range(10):
        inside = (time >= k / 10) & (time <= (k + 1) / 10)
        assert top[k] == error[inside].max()
    assert np.all(np.diff(top) > 0), "the envelope follows the growth the band hides"


# Each lab runs as a notebook (a kernel per lab, 5 to 30 s each; the flexible arm's a minute or
# more) in CI's deep pass; the default pass keeps two: the default scene's, and serial2's with its
# widget. The labs' own helpers are tested in the default pass above.
_NOTEBOOKS_KEPT = ("lab_default_scene.py", "lab_serial2.py")


@pytest.mark.ngspice
@pytest.mark.slow
@pytest.mark.parametrize("lab", [lab if lab in _NOTEBOOKS_KEPT else pytest.param(lab, marks=pytest.mark.deep)
                                 for lab in LABS])
def test_lab_runs_as_a_notebook(lab, tmp_path, monkeypatch):
    jupytext = pytest.importorskip("jupytext")
    nbclient = pytest.importorskip("nbclient")
    out = tmp_path / "out"
    # The kernel inherits this environment; it runs in examples/ so that `import _lab` works.
    monkeypatch.setenv("ANALOGY_LAB_OUTPUT", str(out))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    notebook = jupytext.read(EXAMPLES / lab)
    client = nbclient.NotebookClient(notebook, timeout=CELL_TIMEOUT, kernel_name="python3",
                                     resources={"metadata": {"path": str(EXAMPLES)}})
    client.execute()
    _check_outputs(lab, out)
    pictures = sorted(out.glob("*.png"))
    shown = [o for cell in notebook.cells if cell.cell_type == "code"
             for o in cell.outputs if "image/png" in o.get("data", {})]
    assert len(shown) == len(pictures), "the notebook shows every picture it writes, once"
    players = [o for cell in notebook.cells if cell.cell_type == "code"
               for o in cell.outputs if 'aria-label="Play"' in "".join(o.get("data", {}).get("text/html", ""))]
    assert len(players) == len(list(out.glob("*.gif"))), "every animation plays in the notebook"
    results = [o["data"].get("text/plain", "") for cell in notebook.cells if cell.cell_type == "code"
               for o in cell.outputs if o.get("output_type") == "execute_result"]
    assert not [r for r in results if r.startswith(("PosixPath(", "["))], "a cell ends on a path or list"
    state = notebook.metadata.get("widgets", {}).get("application/vnd.jupyter.widget-state+json", {})
    for widget in state.get("state", {}).values():
        if widget["model_name"] == "OutputModel":
            drawn = [o for o in widget["state"].get("outputs", []) if "image/png" in o.get("data", {})]
            assert len(drawn) == 1, "a widget's output is the picture of its current value"


@pytest.mark.ngspice
def test_a_lab_still_runs_as_a_script_into_the_folder_it_is_given(tmp_path):
    lab = "lab_default_scene.py"        # the quickest lab: the notebook test covers the physics
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if k != "ANALOGY_LAB_OUTPUT"} | {"MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, str(EXAMPLES / lab), str(out)], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path, env=env)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    _check_outputs(lab, out)
    assert not (tmp_path / "lab-output").exists(), "the output folder argument was ignored"
