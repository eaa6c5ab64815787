"""A node system's scales, read before it is solved: they bound its motion and set SPICE's steps."""

import numpy as np
import pytest

from analogy.solvers.transient import netlist, transient_settings
from analogy.circuit.node_system import node_system
from analogy.circuit.scales import combined_scales, system_scales
from analogy.model.joint import JointSpace
from analogy.presets import PRESETS
from analogy.scenes.builtin import SCENES, scene
from analogy.solvers.exact import solve_exact


def tran_line(text):
    line = next(ln for ln in text.splitlines() if ln.startswith(".tran"))
    tstep, t_stop, _, tmax = map(float, line.split()[1:5])
    return tstep, t_stop, tmax


def options(text):
    line = next(ln for ln in text.splitlines() if ln.startswith(".options"))
    return dict(item.partition("=")[::2] for item in line.split()[1:])     # a flag (klu) maps to ""


@pytest.mark.parametrize("name", [n for n in SCENES if SCENES[n].dynamics == "linear"])
def test_the_velocity_scale_is_each_nodes_peak_within_a_modest_factor(name):
    """The modal estimate is within a factor 2.5 below and 10 above each node's exact peak
    (measured 0.48 to 6.1): damping that couples the modes lets some nodes pass it."""
    s = scene(name).system()
    peak = np.max(np.abs(solve_exact(s, np.linspace(0, s.t_stop, 2001)).voltages), axis=0)
    ratio = system_scales(s).velocity / peak
    assert np.all(ratio >= 0.4) and np.all(ratio <= 10)


def test_the_fastest_oscillation_is_the_largest_damped_natural_frequency():
    """M = 1, K = ω²: ω_max = ω; damping b lowers it to √(ω² − b²/4); an overdamped mode
    (the stiff example: ζ = 5e5) only decays and sets no step; a sine force does."""
    springs = node_system(JointSpace([[1.0, 0], [0, 1.0]], stiffness=[[4e6, 0], [0, 1.0]]), forces=[1, 0])
    assert system_scales(springs).omega_max == pytest.approx(2e3, rel=1e-12)
    damped = JointSpace([[1.0, 0], [0, 1.0]], damping=[[2400.0, 0], [0, 0.0]], stiffness=[[4e6, 0], [0, 1.0]])
    assert system_scales(node_system(damped, forces=[1, 0])).omega_max == pytest.approx(1.6e3, rel=1e-12)
    stiff = JointSpace([[1e-9, 0], [0, 1.0]], damping=[[1e6, 0], [0, 1.0]], stiffness=[[1e9, 0], [0, 1.0]])
    assert system_scales(node_system(stiff, forces=[1, 1])).omega_max == pytest.approx(np.sqrt(0.75), rel=1e-9)
    shaken = node_system(JointSpace([[1.0]], damping=[[1.0]]), forces=["sine(0, 1, 50)"])
    assert system_scales(shaken).omega_max == pytest.approx(2 * np.pi * 50, rel=1e-12)


def test_a_fast_mode_caps_the_step_and_shortens_the_first_step_not_the_print_step():
    """ω = 2000 rad/s over 1 s: under the preset's own settings (no truncation model) tmax = 0.016/ω at
    accurate, not t_stop/20000; the print step stays t_stop/1000, and a zero source's corner at t_b
    makes ngspice's first step t_b/100 = 3e-4/ω, which its own (a hundredth of the print step) is not."""
    s = node_system(JointSpace([[1.0, 0], [0, 1.0]], stiffness=[[4e6, 0], [0, 1.0]]), forces=[1, 0],
                    t_stop=1.0)
    own = transient_settings(PRESETS["accurate"], s.t_stop, system_scales(s), breakpoints=s.breakpoints())
    assert own.max_step == pytest.approx(0.016 / 2e3, rel=1e-12)
    text = netlist(s, "accurate")
    tstep, t_stop, tmax = tran_line(text)
    assert tstep == pytest.approx(t_stop / 1000, rel=1e-12) and tstep / 100 > 3e-4 / 2e3
    corner = next(ln for ln in text.splitlines() if ln.startswith("Ifirst_step"))
    assert corner.startswith("Ifirst_step 0 n1 PWL(0 0 ") and corner.endswith(" 0)")
    assert float(corner.split()[5]) / 100 == pytest.approx(3e-4 / 2e3, rel=1e-12)


def test_absolute_tolerances_follow_the_units_of_the_system():
    """The same system with forces 1e6 times larger: abstol and vntol 1e6 times larger too."""
    js = JointSpace([[2.0, 0.3], [0.3, 1.0]], damping=[[1.0, 0], [0, 0.5]])
    small, large = (options(netlist(node_system(js, forces=[f, 0.5 * f]), "accurate")) for f in (1.0, 1e6))
    for key in ("abstol", "vntol"):
        assert float(large[key]) == pytest.approx(1e6 * float(small[key]), rel=1e-2)


def test_abstol_stays_above_the_rounding_of_a_capacitor_current():
    """A stiff, heavy circuit: abstol ≥ 4·n·ε·q/h at the first step h = 3e-4/ω_max, or
    rounding reads as truncation error (written to 3 digits, hence 0.999)."""
    from analogy.solvers.transient import ROUNDING_STEPS
    s = node_system(JointSpace([[50.0, 0], [0, 1.0]], stiffness=[[5e7, 0], [0, 1.0]]), forces=[1, 0])
    sc = system_scales(s)
    first = 3e-4 / sc.omega_max
    assert sc.rounding_current(first) == pytest.approx(2 * np.finfo(float).eps * sc.charge / first, rel=1e-12)
    floor = ROUNDING_STEPS * sc.rounding_current(first)
    assert float(options(netlist(s, "accurate"))["abstol"]) >= 0.999 * floor > 1e-15 * sc.current


def test_a_step_budget_bounds_the_work_of_a_long_run():
    """10^6 s of a 2000 rad/s mode at fast: the cap is t_stop/10^6, not 0.5/ω (4·10^9 steps)."""
    s = node_system(JointSpace([[1.0, 0], [0, 1.0]], stiffness=[[4e6, 0], [0, 1.0]]), forces=[1, 0],
                    t_stop=1e6)
    assert tran_line(netlist(s, "fast"))[2] == pytest.approx(1e6 / PRESETS["fast"].budget.steps, rel=1e-12)


def test_circuits_run_together_share_the_fastest_rate_and_the_largest_scales():
    a = system_scales(node_system(JointSpace([[1.0]], stiffness=[[100.0]]), forces=[2.0]))
    b = system_scales(node_system(JointSpace([[1.0]], stiffness=[[1e4]]), forces=[1.0]))
    both = combined_scales([a, b])
    assert both.omega_max == b.omega_max == pytest.approx(100)
    assert both.current == a.current == 2.0 and both.peak_velocity == max(a.peak_velocity, b.peak_velocity)


@pytest.mark.parametrize("name", ["default", "random10", "flexpar", "serial3"])
def test_a_stack_combines_its_scales_straight_from_its_arrays_as_from_its_rows(name):
    """run_scales of a fresh stack builds no Scales per row, and gives, field for field and to
    the bit, the combined scales of its rows' own (stack_scales of the same systems, one by one)."""
    from analogy.circuit.scales import run_scales, stack_scales
    base = scene(name)
    qs = np.tile(np.array(base.q, dtype=float), (5, 1))
    qs[:, :2] += 0.3 * np.random.default_rng(7).uniform(-1, 1, qs[:, :2].shape)
    stack = base.systems(qs)
    together = run_scales(stack)
    assert all(getattr(s, "_scales", None) is None for s in stack)     # no row was given its own
    rows = combined_scales(stack_scales(list(base.systems(qs))))      # fresh systems, scales per row
    for field in ("omega_max", "current", "charge", "nodes", "top_velocity", "top_position"):
        assert getattr(together, field) == getattr(rows, field), field
    for field in ("velocity", "position", "decays", "shares", "phases"):
        assert np.array_equal(getattr(together, field), getattr(rows, field), equal_nan=True), field


@pytest.mark.parametrize("name", ["default", "random10", "serial3"])
def test_springless_scales_are_those_of_zero_springs_to_the_bit(name):
    """Without springs the scales take K' = 0's eigenproblem as solved, (μ, ψ) = (0, I): the same
    numbers, to the bit, as solving it (LAPACK returns exactly that for a zero matrix)."""
    from analogy.circuit.scales import _scale_arrays
    base = scene(name)
    qs = np.tile(np.array(base.q, dtype=float), (4, 1))
    qs[:, :2] += 0.3 * np.random.default_rng(5).uniform(-1, 1, qs[:, :2].shape)
    stack = base.systems(qs)
    assert stack.springless
    m, b, v0 = stack.mass, stack.damping, stack.initial_voltages
    skipped, solved = _scale_arrays(stack[0], m, b, None, v0), _scale_arrays(stack[0], m, b, np.zeros_like(m), v0)
    for a, c in zip(skipped, solved):
        assert np.array_equal(np.asarray(a), np.asarray(c), equal_nan=True)
