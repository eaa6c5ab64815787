"""Pictures: units from the model on every axis, legends beside the data, colour the joint, style the solver."""

import numpy as np
import pytest

from analogy.diagnostics.bench import bench
from analogy.cli import main
from analogy.presets import PRESETS
from analogy.study.comparison import compare
from analogy.results.plots import error_envelope, shown_joints, solver_style
from analogy.scenes.builtin import scene


def _legends_clear_of_axes(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    boxes = [ax.get_window_extent(renderer) for ax in fig.axes]
    legends = [leg for ax in fig.axes for leg in [ax.get_legend()] if leg is not None] + list(fig.legends)
    assert legends
    for leg in legends:
        box = leg.get_window_extent(renderer)
        assert not any(box.overlaps(b) for b in boxes), "a legend lies over an axes"


@pytest.mark.ngspice
@pytest.mark.parametrize("name", ["default", "redundant", "random10"])
def test_a_comparison_plot_labels_units_keeps_legends_off_the_data_and_one_colour_per_joint(name):
    c = compare(scene(name).replace(t_stop=1.0).system(), "fast")
    fig = c.plot()
    top, bottom = fig.axes[:2]
    units = c.system.provenance.units
    expected = {("rad",) * 2: "[rad/s]", ("m",) * 2: "[m/s]"}.get(units, "[rad/s or m/s]")
    assert top.get_ylabel().endswith(expected) and bottom.get_ylabel().endswith("[1]")
    assert top.get_xlabel() == "" and bottom.get_xlabel() == "time [s]"
    _legends_clear_of_axes(fig)
    joints = shown_joints(c.results["exact"].rates)
    assert len(joints) == (4 if c.system.dof > 6 else c.system.dof)
    for name_, tr in c.results.items():          # each solver draws every shown joint in its joint's colour
        style = solver_style(name_)["ls"]
        lines = [ln for ln in top.lines if ln.get_linestyle() == {"-": "-", "--": "--", ":": ":"}[style]]
        assert {ln.get_color() for ln in lines} >= {f"C{j % 10}" for j in joints}
    for line in bottom.lines[:-1] if bottom.lines else []:
        assert line.get_color() in ("k", "tab:red")


def test_the_error_envelope_is_the_largest_error_of_each_window_and_hides_nothing():
    t = np.linspace(0.0, 10.0, 100_001)
    ringing = 1e-6 * (1 + np.sin(2 * np.pi * 5000 * t)) * (1 + t)
    te, env = error_envelope(t, ringing, bins=50)
    assert env.max() == ringing.max()
    edges = np.linspace(0.0, 10.0, 51)
    for k in range(50):
        inside = (t >= edges[k]) & (t < edges[k + 1]) if k < 49 else (t >= edges[k])
        assert env[2 * k] == ringing[inside].max()


@pytest.mark.ngspice
def test_bench_quick_keeps_each_preset_within_its_bound_and_tighter_ode_tolerances_do_better():
    result = bench(repeats=1, quick=True, scenes=[scene("default")], progress=False)
    rows = {r.setting: r for r in result.rows}
    for name, p in PRESETS.items():
        assert rows[f"tol={p.bound:g}"].error <= p.bound, name
    for method in ("DOP853", "Radau"):
        errs = [rows[f"{method} rtol={tol:g}"].error for tol in (1e-3, 1e-6, 1e-9)]
        assert errs[0] > errs[1] > errs[2], method
    _legends_clear_of_axes(result.plot())


def test_drawing_a_large_system_says_why_in_one_line_and_draws_the_map(tmp_path, capsys):
    assert main(["draw", "--scene", "random10", "-o", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "element values are drawn as a map" in captured.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["random10_elements.png", "random10_elements.svg"]


def test_rates_of_different_units_never_share_an_axis_and_the_titles_say_what_is_drawn():
    """A flexible arm's joints (rad/s) and modal rates (m/s) get a panel each; the error panel
    is the largest error of each window (not a running maximum), its bound label inside the axes."""
    from analogy.cli import scene_from_args, build_parser
    args = build_parser().parse_args(["compare", "--robot", "flex1", "--t-stop", "0.05"])
    c = compare(scene_from_args(args).system(), "fast", ["ode", "exact"])
    fig = c.plot()
    rates = [ax.get_ylabel() for ax in fig.axes[:-1]]
    assert rates == ["joint rate [rad/s]", "joint rate [m/s]"]
    title = fig.axes[-1].get_title()
    assert "largest in each time window" in title and "running maximum" not in title
    (label,) = [t for t in fig.axes[-1].texts if "bound" in t.get_text()]
    assert label.get_position()[0] < 1.0


def test_a_one_joint_comparison_names_its_joint_not_all_one_of_them():
    c = compare(_one_joint(), "fast", ["ode", "exact"])
    assert "worst of" not in c.plot().axes[-1].get_title()


def _one_joint():
    from analogy.cli import scene_from_args, build_parser
    return scene_from_args(build_parser().parse_args(["compare", "--mass", "[2]", "--damping", "[1]",
                                                      "--force", "1", "--t-stop", "1"])).system()


def test_a_bode_plot_without_resonances_does_not_promise_their_lines():
    from analogy.results.plots import plot_bode
    from analogy.solvers.exact import exact_mobility
    response = exact_mobility(scene("default").system(), np.logspace(-2, 2, 81))
    title = plot_bode(response).axes[0].get_title()
    assert len(response.resonances()) == 0 and "no resonance in the band" in title


def test_the_element_map_names_the_conductance_it_draws():
    from analogy.circuit.element_map import draw_element_map
    titles = [ax.get_title() for ax in draw_element_map(scene("default").system()).axes]
    assert "1/Ri_j between nodes (i < j)" in titles and not any(t.startswith("Ri_j") for t in titles)
