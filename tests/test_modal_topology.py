"""The modal topology: one node per mode, T = Φᵀ·M, and the sources into one node written as their sum."""

import numpy as np
import pytest

from analogy import node_system, robot
from analogy.circuit.node_system import node_systems
from analogy.circuit.topology import modal
from analogy.model.joint import JointSpace
from analogy.presets import PRESETS
from analogy.results.metrics import output_errors
from analogy.scenes.builtin import scene
from analogy.solvers.exact import solve_exact
from analogy.solvers.registry import solver
from analogy.solvers.transient import netlist
from analogy.waveforms import PWL, Sine, Step, pwl_sum

EPS = np.finfo(float).eps
RNG = np.random.default_rng(11)


def _spd(n, spread=1.0):
    a = RNG.normal(size=(n, n))
    return a @ a.T + spread * n * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 5, 12])
@pytest.mark.parametrize("springs", [False, True])
def test_the_modal_map_makes_the_mass_the_identity_and_its_pair_diagonal(n, springs):
    """Φᵀ·M·Φ = I and Φᵀ·A·Φ = Λ (A = K with springs, else B), so M' = I and A' = diag(Λ)."""
    m, b = _spd(n), _spd(n, 0.5)
    k = _spd(n, 2.0) if springs else None
    s = node_system(JointSpace(m, b, k), topology="modal", forces=[1.0] * n)
    a = s.stiffness if springs else s.damping
    # the eigenproblem is solved through M's Cholesky factor: rounding n·ε·cond(M) on M',
    # and n·ε·cond(M)·‖A‖ on A' (its eigenvalues' own scale)
    cond = np.linalg.cond(m)
    np.testing.assert_allclose(s.mass, np.eye(n), atol=10 * n * EPS * cond)
    off = a - np.diag(np.diag(a))
    assert np.max(np.abs(off)) <= 10 * n * EPS * cond * np.max(np.abs(np.diag(a)))
    assert np.all(np.diff(np.diag(a)) >= -10 * n * EPS * cond * np.max(np.abs(np.diag(a))))   # slowest first
    assert s.topology.name == "modal"


def test_each_mode_s_sign_is_fixed_by_its_largest_entry():
    """Eigenvectors are defined up to sign: the largest |Φ_jk| of each mode is made positive, so
    T follows from the matrices alone. Renumbering the joints (P·M·Pᵀ, P·B·Pᵀ) renumbers T's
    columns and nothing else, although LAPACK meets a different matrix (n·ε·cond(M) apart)."""
    m, b = _spd(4), _spd(4, 0.5)
    top = modal(m, b)
    phi = np.linalg.solve(top.matrix, np.eye(4))        # T = Φᵀ·M = Φ⁻¹
    pivots = phi[np.argmax(np.abs(phi), axis=0), np.arange(4)]
    assert np.all(pivots > 0)
    order = [2, 0, 3, 1]
    renumbered = modal(m[np.ix_(order, order)], b[np.ix_(order, order)])
    np.testing.assert_allclose(renumbered.matrix, top.matrix[:, order], rtol=0,
                               atol=100 * 4 * EPS * np.linalg.cond(m) * np.max(np.abs(top.matrix)))


@pytest.mark.parametrize("name", ["default", "random10"])
def test_the_modal_circuit_is_the_same_physics(name):
    """Changing the node coordinates leaves the joint rates alone: the exact solutions of the
    serial and modal systems agree to rounding (n·ε·cond(T), with a factor of 100 for the
    modal solve's own sums)."""
    sc = scene(name)
    serial_, modal_ = sc.system(), sc.replace(topology="modal").system()
    t = np.linspace(0.0, serial_.t_stop, 301)
    a, b = solve_exact(serial_, t).rates, solve_exact(modal_, t).rates
    cond = np.linalg.cond(modal_.topology.matrix) * np.linalg.cond(serial_.topology.matrix)
    _, rel = output_errors(b, a)
    assert np.max(rel) <= 100 * serial_.dof * EPS * cond


def test_a_modal_circuit_has_one_grounded_capacitor_per_node_and_no_floating_one():
    """n(n−1)/2 floating capacitors of the serial circuit become n grounded 1 F capacitors."""
    sc = scene("random10").replace(topology="modal")
    system = sc.system()
    n = system.dof
    text = netlist(system, "fast", printing=False)
    caps = [line.split() for line in text.splitlines() if line.startswith("C")]
    assert len(caps) == system.dof and all(c[2] == "0" for c in caps)
    np.testing.assert_allclose([float(c[3]) for c in caps], 1.0, atol=10 * n * EPS * np.linalg.cond(
        system.joint.mass_matrix))


def test_a_large_modal_circuit_keeps_no_floating_element_of_its_congruence_s_rounding():
    """serial100's modal map (cond(T) = 1.4e4): its solves leave off-diagonal terms about n·ε·cond(T)
    of the largest (2.6e-10), which, written, were 4,950 floating capacitors and resistors whose
    charges crossing zero cut ngspice's steps. Under 4·n·ε·cond(T)·max they are rounding, and zero."""
    from analogy.cli.parser import build_parser
    from analogy.cli.scene_options import built_system, scene_from_args
    system = built_system(scene_from_args(build_parser().parse_args(
        ["compare", "--robot", "serial100", "--topology", "modal", "--preset", "fast"])))
    for matrix in (system.mass, system.damping):
        assert np.count_nonzero(matrix - np.diag(np.diag(matrix))) == 0
    text = netlist(system, "fast", printing=False)
    parts = [line.split() for line in text.splitlines() if line[:1] in ("C", "R")]
    assert len(parts) == 2 * system.dof and all(p[2] == "0" for p in parts)


def test_the_piecewise_linear_sources_into_one_node_are_one_device():
    """Under a dense T⁻ᵀ every force drives every node: the PWL terms of one node are written
    as one PWL source (their sum), the others (a sine) as they are."""
    sc = scene("random10").replace(topology="modal")
    system = sc.system()
    text = netlist(system, "fast", printing=False)
    sources = [line.split()[0] for line in text.splitlines() if line.startswith("I")
               and not line.startswith("Ifirst")]
    kinds = {type(w).__name__ for ws in system.forces for w in ws}
    sines = sum(isinstance(w, Sine) for ws in system.forces for w in ws)
    assert "Sine" in kinds and len(sources) == system.dof * (1 + sines)
    assert all(f"In{k}" in sources for k in range(1, system.dof + 1))
    # each summed source injects Σ_j (T⁻ᵀ)_kj·F_j of the PWL forces: here steps at t = 0, so DC
    steps = np.array([sum(w.values[-1] for w in ws if isinstance(w, PWL)) for ws in system.forces])
    want = system.current_map @ steps
    dc = {line.split()[0]: float(line.split()[4]) for line in text.splitlines() if line.startswith("In")}
    assert all(len(w.times) == 1 for ws in system.forces for w in ws if isinstance(w, PWL))
    np.testing.assert_allclose([dc[f"In{k + 1}"] for k in range(system.dof)], want, rtol=0,
                               atol=4 * system.dof * EPS * float(np.max(np.abs(system.current_map) @ np.abs(steps))))


def test_a_sum_of_piecewise_linear_waveforms_is_their_pointwise_sum():
    """Σ cₖ·fₖ(t) of PWL waveforms is PWL through the union of their times: equal everywhere,
    corners and the ends included, to the rounding of the sum (ε·Σ|cₖ·fₖ|)."""
    terms = [(Step(2.0), 0.5), (Step(-1.0, delay=0.3, rise=0.1), -3.0),
             (PWL([(0.0, 1.0), (0.2, -1.0), (0.7, 4.0)]), 0.25), (PWL([(0.5, 2.0)]), 1.0)]
    total = pwl_sum(terms)
    t = np.unique(np.concatenate([np.linspace(0.0, 1.0, 1001), [0.2, 0.3, 0.4, 0.5, 0.7]]))
    want = sum(c * w(t) for w, c in terms)
    scale = sum(abs(c) * np.max(np.abs(w.values)) for w, c in terms)
    np.testing.assert_allclose(total(t), want, rtol=0, atol=4 * EPS * scale)
    assert total.spice(1.0, 1.0).startswith("PWL(")
    assert pwl_sum([(Step(1.0), 2.0), (Step(3.0), -1.0)]).spice(1.0, 1.0) == "DC -1.0"
    # a corner two waveforms write a few ulps apart (0.2 + 0.1 and 0.3) is one point, not two
    near = pwl_sum([(Step(0.5, 0.2, 0.1), 1.0), (PWL([(0.3, 1.0), (0.6, 2.0)]), 1.0)])
    assert np.all(np.diff(near.times) > 1e-14) and np.count_nonzero(np.isclose(near.times, 0.3, rtol=1e-14)) == 1


def test_a_modal_circuit_s_work_counts_one_node_per_row():
    """The work estimate counts the floating elements the circuit keeps: M' = I to rounding has
    none, so a point costs Σᵢ 1² = n operations, against n³ for the dense serial circuit."""
    from analogy.circuit.elements import point_operations
    sc = scene("random10")
    assert point_operations(sc.replace(topology="modal").system()) == 10
    assert point_operations(sc.system()) == 10 ** 3


def test_a_stack_of_configurations_gets_each_row_s_own_modes():
    """node_systems at many q gives each row the modes of its own M(q), as node_system does."""
    model = robot("serial3")
    qs = [[0.0, 0.3, 0.2], [0.4, -0.2, 1.0]]
    stack = node_systems(model, qs, topology="modal", forces=[1.0, 0.0, 0.5])
    assert not np.allclose(stack[0].topology.matrix, stack[1].topology.matrix)
    for k, q in enumerate(qs):
        one = node_system(model, q, topology="modal", forces=[1.0, 0.0, 0.5])
        np.testing.assert_array_equal(stack[k].topology.matrix, one.topology.matrix)


@pytest.mark.ngspice
@pytest.mark.parametrize("name", ["default", "random10"])
@pytest.mark.parametrize("preset", ["fast", "accurate"])
def test_the_modal_circuit_in_ngspice_keeps_the_preset_s_bound(name, preset):
    """The modal circuit's joint rates against the exact solution, each against its own peak."""
    system = scene(name).replace(topology="modal").system()
    p = PRESETS[preset]
    tr = solver("spice").solve(system, None, p)
    ref = solve_exact(system, tr.time).rates
    _, rel = output_errors(tr.rates, ref)
    assert np.max(rel) <= p.bound


def _serial100(*extra):
    from analogy.cli.parser import build_parser
    from analogy.cli.scene_options import built_system, scene_from_args
    return built_system(scene_from_args(build_parser().parse_args(
        ["compare", "--robot", "serial100", "--preset", "fast", *extra])))


def test_a_large_dense_robot_is_written_on_its_modes_and_a_small_or_sparse_one_on_its_own_map():
    """Past DENSE_NODE_LIMIT joints a circuit with more floating elements than 2n takes the modal map
    (serial100's serial circuit: n(n−1)/2 = 4,950 floating capacitors and 99 resistors); 12 joints, or
    a chain whose M, B and K couple only neighbours (n − 1 floating elements each), keep their own."""
    from analogy.circuit.topology import DENSE_NODE_LIMIT, default_topology

    def name(top):
        return getattr(top, "name", top)
    assert _serial100().topology.name == "modal"
    assert _serial100("--topology", "serial").topology.name == "serial"
    for n in (DENSE_NODE_LIMIT, DENSE_NODE_LIMIT + 1):
        assert name(default_topology("serial", _spd(n), np.eye(n))) == ("modal" if n > DENSE_NODE_LIMIT else "serial")
    n = 3 * DENSE_NODE_LIMIT
    chain = 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1) + 0.1 * np.eye(n)
    assert default_topology("parallel", chain, np.eye(n), chain) == "parallel"      # 2(n − 1) ≤ 2n floating
    assert name(default_topology("parallel", _spd(n), np.eye(n))) == "modal"
    # springs beside damping that is not proportional: B' on the modes is as dense as M on the joints
    uneven = np.diag(np.linspace(0.5, 3.0, n))
    assert default_topology("parallel", _spd(n), uneven, 4 * np.eye(n)) == "parallel"


def test_the_node_map_s_rounding_bounds_how_far_two_maps_of_one_robot_part():
    """Topology.rounding is 0 where T⁻¹ is exact (serial, parallel) and 4·n·ε·cond(T) otherwise: the
    exact solutions of serial100 on its serial and its modal circuit part by no more than that of the
    largest rate (measured 1.4e-11 of it, against 1.3e-9)."""
    from analogy.circuit.topology import parallel, serial
    assert serial(7).rounding == 0.0 and parallel(7).rounding == 0.0
    on_modes, on_chain = _serial100(), _serial100("--topology", "serial")
    top = on_modes.topology
    assert top.rounding == pytest.approx(4 * top.dof * EPS * np.linalg.cond(top.matrix))
    t = np.linspace(0.0, on_modes.t_stop, 201)
    a, b = solve_exact(on_modes, t).rates, solve_exact(on_chain, t).rates
    assert np.max(np.abs(a - b)) <= top.rounding * np.max(np.abs(b))


def test_no_output_is_judged_closer_than_the_node_map_s_rounding_allows():
    """An output under rounding/bound of the largest is judged against that share of it, not its own peak."""
    from analogy.results.metrics import judged_peaks
    own, top, bound = np.array([1.0, 1e-10, 1e-3]), np.array([1.0]), 1e-3
    np.testing.assert_allclose(judged_peaks(own, top, bound), [1.0, 1e-9, 1e-3], rtol=EPS)     # 1e-12 / 1e-3
    np.testing.assert_allclose(judged_peaks(own, top, bound, 1e-9), [1.0, 1e-6, 1e-3], rtol=EPS)
    # never above the largest peak: a rounding past the bound judges every output against it
    np.testing.assert_allclose(judged_peaks(own, top, bound, 5e-3), [1.0, 1.0, 1.0], rtol=EPS)
    err = np.zeros((2, 3))
    err[1] = [0.0, 5e-10, 0.0]
    ref = np.vstack([np.zeros(3), own])
    assert output_errors(err + ref, ref, bound, 1e-9)[1][1] == pytest.approx(5e-4)


@pytest.mark.ngspice
def test_serial100_at_fast_keeps_the_bound_on_its_modes():
    """`compare --robot serial100 --preset fast` exits 0: on its modes, SPICE and the ODE within 1e-3 of
    each output's own peak (floored at the map's rounding over the bound)."""
    from analogy.cli.commands import main
    assert main(["compare", "--robot", "serial100", "--preset", "fast", "--no-plot"]) == 0


def test_a_node_s_current_rounds_over_the_capacitors_that_meet_there():
    """The rounding floor of abstol, c·ε·charge/h, counts the capacitors at a node: one on a modal
    circuit, n on a dense one. Counted as n, serial500's modal floor passed 1e-8 of its current scale, and
    its run fell back to the preset's own settings, which missed `fast` (2.8e-3)."""
    from analogy.circuit.scales import system_scales
    modes, chain = system_scales(_serial100()), system_scales(_serial100("--topology", "serial"))
    assert modes.row_capacitors == 1 and chain.row_capacitors == 100
    h = 1e-3
    assert modes.rounding_current(h) == pytest.approx(EPS * modes.charge / h, rel=1e-15)
    assert chain.rounding_current(h) == pytest.approx(100 * EPS * chain.charge / h, rel=1e-15)


@pytest.mark.deep
@pytest.mark.ngspice
@pytest.mark.parametrize("robot", ["serial200", "serial500"])
def test_hundreds_of_joints_keep_fast_on_their_modes(robot):
    """serial200 and serial500 at `fast`, as typed: on their modes, every output within 1e-3 of its own
    peak (their serial circuits missed it: 6.6e-3 for serial200, in 41 s under ngspice 39)."""
    from analogy.cli.commands import main
    assert main(["compare", "--robot", robot, "--preset", "fast", "--no-plot"]) == 0
