"""Closed chains' full nonlinear dynamics: the five-bar and the 3-RRR, reduced onto their motors and as constrained circuits.

Two formulations meet here. The ODE and the reference integrate the active joints
(coordinate partitioning: the passive ones solved from the loop at every step). The
circuit keeps every joint of the chain cut open as a node and closes the loop with
multiplier nodes, J·v + α·Φ = 0 (``analogy.circuit.constrained_circuit``). A third,
written here, integrates the cut-open tree with its multipliers by DOP853.
"""

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from analogy.circuit.constrained_circuit import open_system
from analogy.circuit.description import circuit
from analogy.cli import main
from analogy.model.robots import robot
from analogy.scenes.build import scene_system
from analogy.scenes.builtin import scene
from analogy.solvers.ode import solve_ode
from analogy.study.comparison import SINGULAR_CONDITION, compare

SWING2 = ("sine(0, 0.02, 0.5)", "sine(0, 0.02, 0.5, 0, 0, 90)")            # the motors swing 2 rad
SWING3 = ("sine(0, 0.005, 0.5)", "sine(0, 0.005, 0.5, 0, 0, 120)", "sine(0, 0.005, 0.5, 0, 0, 240)")


def swing(name, forces, t_stop=4.0):
    return scene_system(scene(name).replace(dynamics="nonlinear", t_stop=t_stop, forces=forces))


@pytest.mark.parametrize("name", ["parallel2", "parallel3"])
def test_the_velocity_terms_are_the_christoffel_symbols_of_the_reduced_mass_matrix(name):
    """c(q, q̇) = Sᵀ·(M_θ·(0, p̈₀) + c_θ) is Σ (∂M_ij/∂q_k − ½∂M_jk/∂q_i)·q̇_j·q̇_k of M(q) = SᵀM_θS,
    whose derivatives are taken here by central differences (h = 1e-5: truncation h² and
    rounding ε·|M|/h, both below 1e-8 of |c|)."""
    model = robot(name)
    f = model.mechanical_functions()
    q0 = np.array(scene(name).q, dtype=float)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = q0 + rng.uniform(-0.05, 0.05, q0.size)
        r = rng.normal(size=q0.size)
        h = 1e-5
        dm = np.array([(f.mass(q + h * e) - f.mass(q - h * e)) / (2 * h) for e in np.eye(q.size)])
        christoffel = np.einsum("kij,j,k->i", dm, r, r) - 0.5 * np.einsum("ijk,j,k->i", dm, r, r)
        c = f.velocity(q, r)
        assert np.max(np.abs(c - christoffel)) <= 1e-8 * np.max(np.abs(c))


def test_the_reduced_dynamics_are_the_cut_open_tree_held_by_its_multipliers():
    """The five-bar swinging 2 rad: the cut-open tree with [M_θ, −Jᵀ; J, 0]·(θ̈, λ) = (τ − c_θ, −J̇θ̇),
    by DOP853 at rtol 1e-12, against the reduced ODE at rtol 1e-13: 1e-9 of the peak rate,
    both tolerances with a margin of a hundred."""
    system = swing("parallel2", SWING2, 2.0)
    ref = solve_ode(system, np.linspace(0, 2, 401), "DOP853", 1e-13)
    tree, model = open_system(system), system.model
    theta = list(model.coordinates) + list(model.passive)
    subs = {s: system.parameters[k] for k, s in model.symbols.items()}
    phi = model.constraints.subs(subs)
    jac = phi.jacobian(theta)
    rates = sp.symbols(f"w1:{len(theta) + 1}")
    quadratic = (jac * sp.Matrix(rates)).jacobian(theta) * sp.Matrix(rates)
    jf, qf = sp.lambdify([theta], jac), sp.lambdify([theta, rates], list(quadratic))
    f, n, m = tree.functions, len(theta), phi.rows

    def rhs(t, y):
        th, w = y[:n], y[n:]
        j = np.asarray(jf(th), dtype=float)
        kkt = np.block([[f.mass(th), -j.T], [j, np.zeros((m, m))]])
        load = tree.node_currents(np.array([t]))[0] - f.damping @ w - f.velocity(th, w)
        return np.concatenate([w, np.linalg.solve(kkt, np.concatenate([load, -np.asarray(qf(th, w), float)]))[:n]])

    out = solve_ivp(rhs, (0, 2), np.concatenate([tree.q0, tree.initial_voltages]), method="DOP853",
                    rtol=1e-12, atol=1e-12, t_eval=ref.time)
    peak = np.max(np.abs(ref.rates), axis=0)
    assert np.max(np.abs(out.y[n:n + system.dof].T - ref.rates) / peak) <= 1e-9


@pytest.mark.ngspice
@pytest.mark.parametrize("name, forces, span", [("parallel2", SWING2, 1.5), ("parallel3", SWING3, 0.2)])
# accurate takes 12 s and 20 s: in the deep pass, with fast's in the default one
@pytest.mark.parametrize("preset", ["fast", pytest.param("accurate", marks=pytest.mark.deep)])
def test_the_constrained_circuit_keeps_the_preset_s_bound_against_the_reduced_reference(name, forces, span, preset):
    """SPICE, every joint of the loop a node, against DOP853 on the active joints: within the
    preset's bound on each motor's rate, the loop held to the bound times the chain's reach
    (a position error of the size the rate bound allows), and away from singular poses
    (measured at accurate: five-bar 7.0e-8, 3-RRR 4.8e-8). The five-bar's motors swing
    1.8 to 2.0 rad; the 3-RRR's 0.25 to 0.4 rad, since wider swings from its pose reach a
    singular pose within a second."""
    system = swing(name, forces)
    c = compare(system, preset, solvers=("spice", "reference"))
    assert c.outside_bound() == {} and not c.singular
    reach = sum(system.parameters[k] for k in ("la", "lb"))
    residual, condition = c.loop["spice"]
    assert residual <= c.bound * reach and condition < SINGULAR_CONDITION
    moved = np.ptp(system.configuration(c.results["reference"].positions), axis=0)
    assert np.min(moved) >= span            # a large part of the workspace, not a small wobble


@pytest.mark.ngspice
@pytest.mark.deep                   # 14 s: in CI's deep pass
def test_a_motion_near_a_singular_pose_is_flagged_with_exit_3(capsys):
    """The five-bar's built-in scene, nonlinear over its 10 s, folds both legs flat at t = 1.42 s
    with the distal links in line (cond(Φ_p) 66 on the fast preset's points): the comparison says so, and the command exits 3."""
    c = compare(scene_system(scene("parallel2").replace(dynamics="nonlinear")), "fast", solvers=("spice",))
    assert "singular pose" in c.singular and c.loop["spice"][1] >= SINGULAR_CONDITION
    assert main(["compare", "--robot", "parallel2", "--dynamics", "nonlinear", "--preset", "fast",
                 "--solvers", "spice"]) == 3
    assert "singular pose of the loop" in capsys.readouterr().err


def test_the_linear_circuit_is_refused_at_a_singular_pose_and_warned_of_near_one(capsys):
    """The five-bar stretched straight, q = (π, 0): the distal links in line, Φ_p loses rank and
    the passive rates ∂p/∂q are undefined. Newton lands about 1e-8 off the singular set, where
    cond(Φ_p) passes 1/√ε and the rates have lost half their digits: refused in one sentence
    (exit 2). At 0.04 rad from it, cond is past 20: the netlist is written, with the warning in
    its header and on stderr. The default pose says nothing."""
    model = robot("parallel2")
    assert main(["netlist", "--robot", "parallel2", "--q", "3.141592653589793, 0"]) == 2
    err = capsys.readouterr().err
    # one sentence; a loaded machine may add the model build's progress lines before it
    said = [line for line in err.strip().splitlines() if not line.startswith("analogy: model build")]
    assert "singular pose" in err and "Traceback" not in err and len(said) == 1, err
    assert model.pose_condition((3.1, 0.0)) > SINGULAR_CONDITION > model.pose_condition((2.1, 0.9))
    assert main(["netlist", "--robot", "parallel2", "--q", "3.1, 0"]) == 0
    out, err = capsys.readouterr()
    assert "* warning: q = (3.1, 0) is near a singular pose" in out and "near a singular pose" in err
    assert main(["netlist", "--robot", "parallel2"]) == 0
    out, err = capsys.readouterr()
    assert "warning" not in out + err


def test_the_circuit_has_a_node_per_joint_and_one_per_constraint():
    """Five-bar: nodes n1, n2 (motors), n3, n4 (distal links), n5, n6 (λ); the passive positions
    are kept apart from the system's."""
    c = circuit(swing("parallel2", SWING2))
    assert c.nodes == 6 and c.constraints == 2
    assert c.state_nodes == ["x1", "x2"] and c.monitors == ["x3", "x4"]
